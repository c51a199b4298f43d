//! Flow regimes and wetting: the regime weights of the simplified Wojtan map, the dryout
//! boundary and the equilibrium wetted fraction of the wall.

use std::f64::consts::PI;

use super::TINY;
use super::parameters::CryoParams;
use super::state::{
    Local, boiling_gravity, diameter, mass_fluxes, regime_quality, sat_delta_rho, static_quality,
    stratified_half_angle, void,
};
use crate::closures::smooth_step;
use crate::fastmath::fourth_root;

/// Width in quality of the smooth mist transition.
const QUALITY_WIDTH: f64 = 0.05;
/// Width in quality of the smooth intermittent/annular bound of dryout.
const IA_WIDTH: f64 = 0.05;
/// Floor of the normalised wall heat flux q/q_DNB of the dryout boundary.
pub(super) const Q_TILDE_MIN: f64 = 1e-3;
/// Lowest stratified boundary mass flux, kg/(m² s) (the polynomials can be driven negative).
const G_BOUNDARY_MIN: f64 = 1.0;
/// The wavy boundary is at least this factor above the stratified one.
const WAVY_OVER_STRAT_MIN: f64 = 1.5;

/// Flow regime weights (sum 1), smooth in G and quality: stratified, stratified-wavy,
/// annular/intermittent, dryout/mist.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Regime {
    /// Stratified (smooth).
    pub stratified: f64,
    /// Stratified-wavy.
    pub wavy: f64,
    /// Annular or intermittent.
    pub annular: f64,
    /// Dryout or dispersed (mist).
    pub dryout: f64,
}

impl Regime {
    /// Sum of the weights (1 up to round-off).
    pub fn sum(&self) -> f64 {
        self.stratified + self.wavy + self.annular + self.dryout
    }
}

fn poly2(c: &[f64; 3], x: f64) -> f64 {
    c[0] + x * (c[1] + x * c[2])
}

/// The simplified Wojtan et al. (2005) boundaries at regime quality χ, kg/(m² s):
/// (G_strat, G_wavy), the quadratic polynomials of the `regime_strat_*` and `regime_wavy_*`
/// parameters. Their defaults are least-squares fits of Wojtan's ṁ_strat (χ ∈ [0.06, 0.98])
/// and ṁ_wavy (χ ∈ [0.06, 0.7], q = 10 kW/m²; above, dryout and mist take over) for nitrogen
/// at 1 atm in a 15.9 mm line. G_strat ≥ 1, G_wavy ≥ 1.5 G_strat.
pub fn stratification_boundaries(p: &CryoParams, chi: f64) -> (f64, f64) {
    let g_strat = poly2(&p.strat_poly(), chi).max(G_BOUNDARY_MIN);
    let g_wavy = poly2(&p.wavy_poly(), chi).max(WAVY_OVER_STRAT_MIN * g_strat);
    (g_strat, g_wavy)
}

/// Kutateladze's (1950) departure from nucleate boiling heat flux, W/m²:
/// q_DNB = K ρ_g^½ h_lg [σ g (ρ_l − ρ_g)]^¼, K = `kutateladze_k` (0.131), saturated properties.
pub fn kutateladze_q_dnb(s: &Local, p: &CryoParams) -> f64 {
    p.kutateladze_k
        * s.vap_sat.rho.max(0.0).sqrt()
        * s.h_lg.max(0.0)
        * fourth_root(s.sigma.max(0.0) * boiling_gravity(s) * sat_delta_rho(s))
}

/// Wojtan's dryout boundary ṁ_dry at regime quality `chi` and wall heat flux `q_wall` (W/m²),
/// kg/(m² s): the flow is in dryout above it.
/// ṁ_dry = [4.25 (ln(0.58/χ) + 0.52) (ρ_g σ/D)^0.17 (g D ρ_g Δρ)^0.37 (ρ_l/ρ_g)^0.25 q̃^−0.7]^0.93,
/// q̃ = q_wall/q_DNB ([`kutateladze_q_dnb`]), floored at 10⁻³ (no heat flux: no dryout below
/// χ = 0.58 e^0.52 = 0.976). Zero for χ ≥ 0.976. Saturated properties (Wojtan et al. 2005).
pub fn dryout_mass_flux(s: &Local, p: &CryoParams, chi: f64, q_wall: f64) -> f64 {
    ln_dryout_mass_flux(s, p, chi, q_wall).map_or(0.0, f64::exp)
}

/// 0.34^(1/0.875), the Martinelli parameter of Kattan, Thome and Favrat's intermittent/annular
/// transition (checked by a test).
pub(super) const X_TT_IA_POW: f64 = 0.291_438_775_663_021_9;

/// The quality x_IA of the intermittent/annular transition of the Wojtan et al. (2005) map
/// (Kattan, Thome and Favrat 1998: the Martinelli parameter X_tt = 0.34):
/// x_IA = [0.34^(1/0.875) (ρ_g/ρ_l)^(−1/1.75) (μ_l/μ_g)^(−1/7) + 1]^(−1), saturated densities,
/// the saturated vapour's viscosity and the liquid's. 0.23 for saturated nitrogen at 1 atm (a
/// test), 0.42 for para-hydrogen at 2.2 bar (the NBS line's exit after a chilldown).
pub fn intermittent_annular_quality(s: &Local) -> f64 {
    let rho_ratio = s.vap_sat.rho.max(TINY) / s.rho_l_sat.max(TINY);
    let mu_ratio = s.mu_l.max(TINY) / s.vap_sat.mu.max(TINY);
    let x = 1.0 / (X_TT_IA_POW * rho_ratio.powf(-1.0 / 1.75) * mu_ratio.powf(-1.0 / 7.0) + 1.0);
    if x.is_finite() { x } else { 0.0 }
}

/// ln 4.25 (checked by a test).
pub(super) const LN_4_25: f64 = 1.446_918_982_936_325_4;
/// ln 10⁻³, the logarithm of [`Q_TILDE_MIN`] (checked by a test).
pub(super) const LN_Q_TILDE_MIN: f64 = -6.907_755_278_982_137;

/// The quality term ln(0.58/χ) + 0.52 of the dryout boundary (no dryout where it is ≤ 0).
fn dryout_quality_term(chi: f64) -> f64 {
    (0.58 / chi.max(TINY)).ln() + 0.52
}

/// ln ṁ_dry of [`dryout_mass_flux`], or `None` where that is 0 (χ ≥ 0.976, or a boundary that
/// is not a positive finite number).
fn ln_dryout_mass_flux(s: &Local, p: &CryoParams, chi: f64, q_wall: f64) -> Option<f64> {
    ln_dryout_cached(s, p, chi, q_wall, &mut RegimeBasis::default())
}

/// [`ln_dryout_mass_flux`] with the velocity-free part of the boundary taken from `basis`
/// (computed there on first use).
fn ln_dryout_cached(s: &Local, p: &CryoParams, chi: f64, q_wall: f64, basis: &mut RegimeBasis) -> Option<f64> {
    let quality_term = dryout_quality_term(chi);
    if quality_term <= 0.0 {
        return None;
    }
    let ln_m = basis.dryout.get_or_insert_with(|| DryoutBasis::new(s, p, q_wall)).ln_mass_flux(quality_term);
    // exp(ln_m) positive and finite (the form with powers gives 0 outside)
    (ln_m > -745.0 && ln_m < 709.0).then_some(ln_m)
}

/// The terms of ln ṁ_dry that do not depend on the phase velocities (only the regime quality
/// does), as a sum of logarithms (no powers):
/// 0.93 [ln 4.25 + 0.17 ln(ρ_g σ/D) + 0.37 ln(g D ρ_g Δρ) + ln((ρ_l/ρ_g)^¼ (ln(0.58/χ) + 0.52))
/// − 0.7 ln q̃].
#[derive(Debug, Clone, Copy)]
struct DryoutBasis {
    /// ln 4.25 + 0.17 ln(ρ_g σ/D) + 0.37 ln(g D ρ_g Δρ), summed in that order.
    head: f64,
    /// (ρ_l/ρ_g)^¼.
    density_root: f64,
    /// 0.7 ln q̃.
    tail: f64,
    /// The share of the flow past the intermittent/annular transition, S(½ + (x_s − x_IA)/w)
    /// with x_s the static quality, x_IA from [`intermittent_annular_quality`] and w =
    /// `IA_WIDTH`.
    annular: f64,
}

impl DryoutBasis {
    fn new(s: &Local, p: &CryoParams, q_wall: f64) -> Self {
        let d = diameter(s);
        let rho_g = s.vap_sat.rho.max(TINY);
        let q_t = (q_wall.max(0.0) / kutateladze_q_dnb(s, p).max(TINY)).max(Q_TILDE_MIN);
        let ln_q_t = if q_t == Q_TILDE_MIN { LN_Q_TILDE_MIN } else { q_t.ln() };
        Self {
            head: LN_4_25
                + 0.17 * (rho_g * s.sigma.max(0.0) / d).ln()
                + 0.37 * (boiling_gravity(s) * d * rho_g * sat_delta_rho(s)).ln(),
            density_root: fourth_root(s.rho_l_sat.max(0.0) / rho_g),
            tail: 0.7 * ln_q_t,
            annular: smooth_step(0.5 + (static_quality(s) - intermittent_annular_quality(s)) / IA_WIDTH),
        }
    }

    /// ln ṁ_dry at a positive `quality_term` (the same operations in the same order as the
    /// sum written out: the cached and the uncached boundary agree to the bit).
    fn ln_mass_flux(&self, quality_term: f64) -> f64 {
        0.93 * (self.head + (self.density_root * quality_term).ln() - self.tail)
    }
}

/// The part of the flow-regime map that does not depend on the phase velocities, kept between
/// evaluations of [`flow_regime_cached`] at states that differ only in `v_g` and `v_l` (and the
/// same wall heat flux): the momentum step's drag slope evaluates the map again at a shifted
/// slip. Start each state from `RegimeBasis::default()`.
#[derive(Debug, Clone, Copy, Default)]
pub struct RegimeBasis {
    dryout: Option<DryoutBasis>,
}

/// Flow regime weights at the state `s` with wall heat flux `q_wall` (W/m², for the dryout
/// boundary; the previous step's is fine).
///
/// With G the total mass flux and χ the [`regime_quality`]:
/// s_strat = S(½ + ln(G/G_strat)/w), s_wavy = S(½ + ln(G/G_wavy)/w),
/// s_dry = S(½ + ln(G/ṁ_dry)/w) S(½ + (x_s − x_IA)/0.05) (S the smooth step, w = `regime_width`,
/// ṁ_dry from [`dryout_mass_flux`], x_s the [`static_quality`], x_IA from
/// [`intermittent_annular_quality`]),
/// mist = S(½ + (χ − xmin)/0.05), dry = 1 − (1 − s_dry)(1 − mist);
/// stratified = (1 − dry)(1 − s_strat), wavy = (1 − dry) s_strat (1 − s_wavy),
/// annular = (1 − dry) s_strat s_wavy, dryout = dry.
///
/// Decision: Wojtan's dryout is the drying of an annular film, and his map has it only in the
/// annular zone, right of x_IA; below it a flow above the wavy boundary is intermittent however
/// fast it is. The boundary ṁ_dry alone, extrapolated to low qualities, put liquid at a void
/// fraction of 0.46 (χ ≈ 0.02) into dryout whenever a surge raised its mass flux, and took it
/// as drops: at the subcooled NBS inlet a dryout weight of 0.03–0.08 multiplied the liquid's
/// interface coefficient by 25, the vapour collapsed, the mass flux fell back and the cycle
/// repeated every 40 ms (BENCHMARKS.md, "The dryout regime's liquid as a stream"). The bound
/// reads the static quality, not χ: χ moves with the slip, and where a flow's quality sat at
/// x_IA (para-hydrogen's exit after its chilldown at 11 atm) the bound on χ fed back on the drag
/// (slip down, quality down, dryout down, drag down, slip up) from step to step.
pub fn flow_regime(s: &Local, p: &CryoParams, q_wall: f64) -> Regime {
    flow_regime_cached(s, p, q_wall, &mut RegimeBasis::default())
}

/// [`flow_regime`] with the velocity-free part of the dryout boundary kept in `basis`: valid
/// only across states that differ in their phase velocities alone, at the same `q_wall`. The
/// weights are the same to the bit as [`flow_regime`]'s.
pub fn flow_regime_cached(s: &Local, p: &CryoParams, q_wall: f64, basis: &mut RegimeBasis) -> Regime {
    let (gg, gl) = mass_fluxes(s);
    let chi = regime_quality(s);
    let mist = smooth_step(0.5 + (chi - p.x_mist) / QUALITY_WIDTH);
    if mist == 1.0 {
        // dryout = 1 − (1 − dry)·0 = 1 whatever the dryout boundary
        return Regime { stratified: 0.0, wavy: 0.0, annular: 0.0, dryout: 1.0 };
    }
    let ln_g = (gg + gl).max(1e-9).ln();
    let w = p.regime_width.max(1e-6);
    let dry_hf = match ln_dryout_cached(s, p, chi, q_wall, basis) {
        Some(ln_m) => smooth_step(0.5 + (ln_g - ln_m) / w),
        None => 1.0,
    };
    // dryout is the drying of an annular film: none below the intermittent/annular transition
    let annular = basis.dryout.get_or_insert_with(|| DryoutBasis::new(s, p, q_wall)).annular;
    let dry_hf = dry_hf * annular;
    let dryout = 1.0 - (1.0 - dry_hf) * (1.0 - mist);
    let wet = 1.0 - dryout;
    if wet == 0.0 {
        // all dryout/mist: the stratification steps (finite, in [0, 1]) would be multiplied by 0
        return Regime { stratified: 0.0, wavy: 0.0, annular: 0.0, dryout };
    }
    let (g_strat, g_wavy) = stratification_boundaries(p, chi);
    let s_strat = smooth_step(0.5 + (ln_g - g_strat.ln()) / w);
    let s_wavy = smooth_step(0.5 + (ln_g - g_wavy.ln()) / w);
    Regime {
        stratified: wet * (1.0 - s_strat),
        wavy: wet * s_strat * (1.0 - s_wavy),
        annular: wet * s_strat * s_wavy,
        dryout,
    }
}

/// Equilibrium fraction of the wall perimeter covered by liquid:
/// stratified δ/π (the liquid level of a circle at void fraction α, [`stratified_half_angle`]);
/// stratified-wavy 1 − 0.5^0.61 (1 − δ/π) (Wojtan's dry angle θ_strat ((G_wavy − G)/(G_wavy −
/// G_strat))^0.61 at mid-band); annular/intermittent 1; dryout/mist 0; blended with the regime
/// weights.
///
/// Decision: the fraction is not multiplied by the liquid's presence weight (`blend_xmin`,
/// `blend_xmax`): those thresholds are numerics and may not carry physics. A vanishing liquid
/// leaves the wall through the regime map (its flow quality moves the cell into dryout/mist,
/// where the covered fraction is 0) and the stratified chord (δ/π → 0 with the liquid).
///
/// Decision: the fraction does **not** drop to 0 above T_mfb. "Covered" includes a wall under a
/// vapour film: the boiling curve already carries film boiling above T_mfb (eq:Bromley,
/// eq:Iloeje_hfb, heat flux to the liquid through the film, Fig. "Surface1"); zeroing the
/// covered fraction there would remove film boiling altogether. Above T_mfb the heat to the
/// liquid is the film-boiling flux, below it the nucleate/transition flux; the scheme relaxes
/// its wetted fraction towards this value with the time constant `tauw`.
pub fn wetted_fraction(s: &Local, regime: &Regime) -> f64 {
    wetted_fraction_at(regime, stratified_half_angle(1.0 - void(s)))
}

/// [`wetted_fraction`] with the stratified layer's half-angle δ given.
pub(super) fn wetted_fraction_at(regime: &Regime, half_angle: f64) -> f64 {
    let w_strat = half_angle / PI;
    let w_wavy = 1.0 - 0.5f64.powf(0.61) * (1.0 - w_strat);
    let w = regime.stratified * w_strat + regime.wavy * w_wavy + regime.annular;
    w.clamp(0.0, 1.0)
}
