//! The boiling curve: its anchors (onset of nucleate boiling, critical heat flux, minimum film
//! boiling), the film-boiling correlations and the curve between the anchors.

use std::f64::consts::PI;

use super::TINY;
use super::convection::Convection;
use super::parameters::{CorrelationSet, CryoParams};
use super::state::{
    Local, Vapour, boiling_gravity, diameter, mass_fluxes, prandtl, regime_quality, sat_delta_rho, void,
};
use crate::fastmath::{cbrt, fourth_root, pow_param};
use crate::fluids::{FluidTable, Phase};

/// Floor of Miropolskii's Y (not a parameter-scaled quantity: Y has no registry constant).
const MIROPOLSKII_Y_FLOOR: f64 = 0.05;
/// Bromley's constant for a horizontal cylinder (the scale is `qmfbsc`).
const BROMLEY_C: f64 = 0.62;
/// Bromley's latent-heat correction h̃_lg = h_lg + 0.4 c_pg ΔT.
const BROMLEY_SENSIBLE: f64 = 0.4;
/// Griffith-type CHF constants (paper, after Griffith 1957; water values).
const GRIFFITH_A: [f64; 3] = [0.0144, 1.0e-6, 0.5e-3];
/// Spiegler's thermodynamic limit of liquid contact, T/T_cr = 27/32: the leading factor of the
/// Darr–Hartwig rewet temperature.
const DARR_HARTWIG_TCR_FACTOR: f64 = 27.0 / 32.0;
/// Heat-transfer regime of the wall ([`WallHeat::regime`](super::WallHeat::regime)): the branch
/// of the boiling curve, or a dry wall.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WallRegime {
    /// Single-phase convection to the liquid (T_w ≤ T_onb).
    Convection,
    /// Nucleate boiling (T_onb < T_w ≤ T_chf).
    Nucleate,
    /// Transition boiling (T_chf < T_w ≤ T_mfb).
    Transition,
    /// Film boiling (T_w > T_mfb).
    Film,
    /// Dry wall: no liquid-covered perimeter (wetted fraction below 10⁻³); heat goes to the gas.
    Dry,
}

impl Local {
    /// The same state with the boiling correlations' property bases read from `fluid`:
    /// saturated vapour at T_s, the film vapour of the wall at (T_w + T_s)/2 and that of the
    /// minimum film boiling point at T_s + ΔT_mfb,0/2 (Berenson's superheat with saturated
    /// vapour, unscaled: the film temperature does not move with `Tmfbsc`). Film temperatures
    /// are held within the gas table; where the table holds no vapour at a temperature (above
    /// the critical pressure, say) the basis stays as it was.
    pub fn with_boiling_basis(mut self, fluid: &FluidTable) -> Self {
        // the gas table at the cell's pressure, located once for the three bases, which read
        // values only (no derivatives)
        let gas = fluid.isobar(Phase::Gas, self.p);
        let range = gas.temperature_range();
        let vapour_at = |t: f64| -> Option<Vapour> {
            let (lo, hi) = range?;
            let t = t.clamp(lo, hi);
            let g = gas.values(t).ok()?;
            Some(Vapour { rho: g.rho, mu: g.mu, k: g.k, cp: g.cp })
        };
        if let Some(v) = vapour_at(self.t_sat) {
            self.vap_sat = v;
        }
        if let Some(v) = vapour_at(0.5 * (self.t_w.max(self.t_sat) + self.t_sat)) {
            self.vap_film = v;
        }
        let dt_mfb0 = berenson_with(&self, &self.vap_sat);
        if let Some(v) = vapour_at(self.t_sat + 0.5 * dt_mfb0) {
            self.vap_mfb = v;
        }
        self
    }
}

/// Onset of nucleate boiling (eq:T_onb, eq:q_onb; Sato & Matsumura 1964 with the
/// Frost & Dzakowic 1967 Pr² for non-water fluids): returns (T_onb, q_onb).
///
/// B = ρ_g h_lg κ_l/(8 σ T_s), F = h_cb Pr_l²/(2B),
/// T_onb = T_s + Tonbsc · F (1 + √(1 + 2 ΔT_sub/F)), ΔT_sub = max(T_s − T_l, 0),
/// which is where the nucleation line (B/Pr²) ΔT_sat² meets convection h_cb (T_w − T_l).
/// h_cb is evaluated at a wall 1 K above max(T_s, T_l) (natural convection depends on the wall
/// temperature) and q_onb = h_cb(T_onb) (T_onb − T_l), so that the curve is continuous at T_onb.
/// Property basis: saturated vapour density, h_lg, σ and T_s (the nucleation criterion at the
/// saturation state), the liquid's conductivity, Prandtl number and convection at its own
/// temperature. A superheated liquid (T_l > T_s) takes the superheat from T_l.
pub fn onset_of_nucleate_boiling(s: &Local, p: &CryoParams) -> (f64, f64) {
    onb_with(s, p, &Convection::liquid(s, p))
}

/// [`onset_of_nucleate_boiling`] with the liquid's convection already set up.
fn onb_with(s: &Local, p: &CryoParams, liquid: &Convection) -> (f64, f64) {
    let pr = liquid.pr;
    let b = s.vap_sat.rho.max(0.0) * s.h_lg.max(0.0) * s.k_l.max(0.0) / (8.0 * s.sigma.max(1e-9) * s.t_sat.max(1.0));
    let h_ref = liquid.htc(s.t_sat.max(s.t_l) + 1.0);
    let f = (h_ref * pr * pr / (2.0 * b.max(TINY))).max(1e-12);
    let dt_sub = (s.t_sat - s.t_l).max(0.0);
    let dt_onb = p.t_onb_scale * f * (1.0 + (1.0 + 2.0 * dt_sub / f).sqrt());
    // superheat measured from the liquid where it is above saturation (a superheated liquid
    // nucleates from its own temperature on), which keeps T_onb > T_l without a clamp
    let t_onb = s.t_sat.max(s.t_l) + dt_onb;
    (t_onb, liquid.htc(t_onb) * (t_onb - s.t_l))
}

/// Zuber's pool critical heat flux (eq:Zuber), W/m²:
/// q_chf,0 = (π/24) h_lg ρ_g^½ [σ g (ρ_l − ρ_g)]^¼ (1 + ρ_g/ρ_l)^½.
/// The last factor is Zuber's (1959) own; the paper prints its inverse (ρ_l/(ρ_l + ρ_g))^½.
/// About 1.6 × 10⁵ W/m² for nitrogen at 1 atm. Property basis: saturated liquid and vapour
/// (Zuber's hydrodynamic instability of saturated vapour columns in saturated liquid).
pub fn zuber_chf(s: &Local) -> f64 {
    let rho_g = s.vap_sat.rho.max(0.0);
    let rho_l = s.rho_l_sat.max(TINY);
    PI / 24.0
        * s.h_lg.max(0.0)
        * rho_g.sqrt()
        * fourth_root(s.sigma.max(0.0) * boiling_gravity(s) * sat_delta_rho(s))
        * (1.0 + rho_g / rho_l).sqrt()
}

/// Flow-boiling critical heat flux, W/m²: Zuber's pool value times a blend, weighted by
/// `chf_griffith` = w, of
/// the simplified Iloeje-type form (eq:Iloeje_chf) qchfsc (α_cr − α)^a2 (1 + a3 G^a4)
/// (the paper lists a4 = 0.2 but prints a5 in the exponent: the exponent is `chf_g_exp`) and
/// the Griffith-type form (eq:Griffith_chf) qchfsc (α_cr − α)(1 + a1 Ja + a2 Re_l + a3 (Re_l Ja)^½)
/// with Ja = ρ_l c_l ΔT_sub/(ρ_g,sat h_lg), Re_l = ρ_l |v_l| D/μ_l and Griffith's water constants
/// a1 = 0.0144, a2 = 10⁻⁶, a3 = 0.5 × 10⁻³.
/// (α_cr − α) is clamped to ≥ 0 before the power; G is the total mass flux.
pub fn critical_heat_flux(s: &Local, p: &CryoParams) -> f64 {
    let (gg, gl) = mass_fluxes(s);
    chf_with(s, p, gg + gl)
}

/// [`critical_heat_flux`] at the total mass flux `g`.
fn chf_with(s: &Local, p: &CryoParams, g: f64) -> f64 {
    let q0 = zuber_chf(s);
    let void_margin = (p.chf_alpha_cr - void(s)).max(0.0);
    let iloeje = pow_param(void_margin, p.chf_void_exponent) * (1.0 + p.chf_g_coeff * g.powf(p.chf_g_exponent));
    let w = p.chf_griffith_weight.clamp(0.0, 1.0);
    let griffith = if w > 0.0 {
        let ja = s.rho_l * s.cp_l * (s.t_sat - s.t_l).max(0.0) / (s.vap_sat.rho * s.h_lg).max(TINY);
        let re_l = s.rho_l * s.v_l.abs() * diameter(s) / s.mu_l.max(TINY);
        let [a1, a2, a3] = GRIFFITH_A;
        void_margin * (1.0 + a1 * ja + a2 * re_l + a3 * (re_l * ja).sqrt())
    } else {
        0.0
    };
    p.q_chf_scale * q0 * ((1.0 - w) * iloeje + w * griffith)
}

/// Wall temperature of the critical heat flux (eq:theler, Theler 2011), K:
/// T_chf,0 = T_s / (1 − (T_s R_g/h_lg) ln(2 k_g + 1)), k_g the fluid's ideal-gas c_p/R
/// ([`CryoParams::ideal_cp_over_r`]: 7/2 for nitrogen, the paper's diatomic value; 5/2 for
/// para-hydrogen, whose rotation is frozen near its boiling point; the logarithm is natural),
/// and T_chf = T_s + Tchfsc (T_chf,0 − T_s).
/// Tchfsc scales the superheat, not T_chf itself (a scale of T_chf could put it below T_s).
/// The group (T_s R_g/h_lg) ln(2k_g + 1) is capped at 0.8 (near the critical point it would
/// reach 1). About 101.7 K for nitrogen at 1 atm. Not yet ordered against T_onb (see
/// [`boiling_anchors`]).
pub fn theler_t_chf(s: &Local, p: &CryoParams) -> f64 {
    let u = (s.t_sat * p.gas_constant / s.h_lg.max(TINY) * (2.0 * p.ideal_cp_over_r + 1.0).ln()).clamp(0.0, 0.8);
    s.t_sat + p.t_chf_scale * s.t_sat * u / (1.0 - u)
}

/// Berenson's (1961) minimum film boiling superheat (eq:Tmfb), K:
/// ΔT_mfb,0 = 0.127 (ρ_g h_lg/κ_g) [g Δρ/(ρ_l + ρ_g)]^⅔ [σ/(g Δρ)]^½ [μ_g/(g Δρ)]^⅓.
/// The paper drops the g of the last bracket (dimensionally wrong); it is restored.
/// Property basis (Berenson 1961): the vapour of the film, ρ_g, κ_g and μ_g at the film
/// temperature (T_s + T_mfb)/2 ([`Local::vap_mfb`]); the Taylor-instability brackets with
/// saturated liquid and vapour densities. Not the cell's vapour: the cell average of a front
/// cell is a grid artefact (95 K or 200 K in the same flow), and ΔT_mfb followed it (121 K
/// against 33.5 K). About 69 K for nitrogen at 1 atm with saturated-vapour properties.
pub fn berenson_dt_mfb(s: &Local) -> f64 {
    berenson_with(s, &s.vap_mfb)
}

/// [`berenson_dt_mfb`] with the film vapour `v`.
pub fn berenson_with(s: &Local, v: &Vapour) -> f64 {
    let g = boiling_gravity(s);
    let gd = g * sat_delta_rho(s);
    let c = cbrt(gd / (s.rho_l_sat + s.vap_sat.rho).max(TINY));
    0.127 * v.rho.max(0.0) * s.h_lg.max(0.0) / v.k.max(TINY)
        * (c * c)
        * (s.sigma.max(0.0) / gd).sqrt()
        * cbrt(v.mu.max(0.0) / gd)
}

/// Iloeje's (1982) flow correction of the minimum film boiling superheat (eq:Iloeje), K:
/// ΔT_mfb = c1 ΔT_mfb,0 (1 − c2 X_e^c3)(1 + c4 G_l^c5) with the Table 1 parameters
/// c1 = Tmfbsc, c2 = Xtmfbsc, c3 = Xetmfbsc, c4 = Gtmfbsc, c5 = Etmfbsc (not the Griffith
/// constants the paper pasted; Xtmfbsc/Xetmfbsc taken as scale/exponent, the reverse of Table 1's
/// labels, matching the film-boiling set c2 = 1.04, c3 = 2.0). G_l is the liquid mass flux.
///
/// X is the **flow quality** G_g/G ([`regime_quality`]: smoothly the static quality where the
/// mixture stands), the quality of Iloeje's (1982) dispersed-flow data, in [0, 1]. Decision: not
/// the equilibrium quality — behind a quench front the vapour is superheated by 100 K and more
/// while a quarter of the mass is still liquid, so X_e clamps at 1 and both Iloeje factors sat
/// on their floor. The quality factor is floored at `iloeje_x_floor` (a registry parameter).
pub fn iloeje_dt_mfb(s: &Local, p: &CryoParams) -> f64 {
    let (_, gl) = mass_fluxes(s);
    iloeje_with(s, p, regime_quality(s), gl)
}

/// [`iloeje_dt_mfb`] at flow quality `x` and liquid mass flux `gl`.
fn iloeje_with(s: &Local, p: &CryoParams, x: f64, gl: f64) -> f64 {
    p.t_mfb_scale
        * berenson_dt_mfb(s)
        * (1.0 - p.t_mfb_x_scale * pow_param(x, p.t_mfb_x_exponent)).max(p.iloeje_x_floor)
        * (1.0 + p.t_mfb_g_scale * gl.powf(p.t_mfb_g_exponent))
}

/// Darr–Hartwig-type rewet (wetting) temperature, K, the [`CorrelationSet::Miropolskii`]
/// replacement of T_mfb: T_wet = (27/32) T_cr (1 + b We_D^e), We_D = G² D/(ρ_l σ), G the total
/// mass flux; 27/32 T_cr is Spiegler's thermodynamic limit of liquid contact. Capped at T_cr
/// (no liquid contact above it). About 118 K for nitrogen in a 5/8" line at G = 100 kg/(m² s).
pub fn darr_hartwig_t_wet(s: &Local, p: &CryoParams) -> f64 {
    let (gg, gl) = mass_fluxes(s);
    darr_hartwig_with(s, p, gg + gl)
}

/// [`darr_hartwig_t_wet`] at the total mass flux `g`.
fn darr_hartwig_with(s: &Local, p: &CryoParams, g: f64) -> f64 {
    let we = g * g * diameter(s) / (s.rho_l * s.sigma).max(TINY);
    (DARR_HARTWIG_TCR_FACTOR * p.t_critical * (1.0 + p.dh_we_coeff * we.powf(p.dh_we_exponent))).min(p.t_critical)
}

/// Bromley's (1950) film-boiling coefficient at wall temperature `t_w` (eq:Bromley), W/(m² K):
/// h_br = 0.62 [g ρ_g κ_g² (ρ_l − ρ_g) h̃_lg c_pg / (D (T_w − T_s) Pr_g)]^¼,
/// h̃_lg = h_lg + 0.4 c_pg (T_w − T_s). (T_w − T_s) is floored at 0.1 K.
/// Property basis (Bromley 1950): the vapour of the film at the film temperature (T_w + T_s)/2
/// ([`Local::vap_film`]; ρ_g, κ_g, c_pg, μ_g), the liquid density at saturation.
pub fn bromley_htc(s: &Local, t_w: f64) -> f64 {
    bromley_with(s, &s.vap_film, t_w)
}

/// [`bromley_htc`] with the film vapour `v`.
fn bromley_with(s: &Local, v: &Vapour, t_w: f64) -> f64 {
    let dt = (t_w - s.t_sat).max(0.1);
    let h_mod = s.h_lg.max(0.0) + BROMLEY_SENSIBLE * v.cp.max(0.0) * dt;
    let pr = prandtl(v.mu, v.cp, v.k).max(TINY);
    let drho = (s.rho_l_sat - v.rho).max(1e-6 * s.rho_l_sat.max(TINY));
    let group = boiling_gravity(s) * v.rho.max(0.0) * v.k.max(0.0).powi(2) * drho * h_mod * v.cp.max(0.0)
        / (diameter(s) * dt * pr);
    BROMLEY_C * fourth_root(group)
}

/// Miropolskii's (1963) film-boiling (post-dryout) coefficient, W/(m² K):
/// Nu = 0.023 [Re_g (X + (ρ_g/ρ_l)(1 − X))]^0.8 Pr_g^0.8 Y,
/// Y = 1 − 0.1 (ρ_l/ρ_g − 1)^0.4 (1 − X)^0.4, Re_g = G D/μ_g, X the flow quality, times
/// `hmirosc`. Y is floored at 0.05 (it goes negative for ρ_l/ρ_g ≳ 300). Property basis
/// (Miropolskii 1963): saturated vapour and liquid; the wall Prandtl number is taken at the film
/// temperature ([`Local::vap_film`]).
pub fn miropolskii_htc(s: &Local, p: &CryoParams) -> f64 {
    let (gg, gl) = mass_fluxes(s);
    miropolskii_with(s, p, regime_quality(s), gg + gl)
}

/// [`miropolskii_htc`] at flow quality `x` and total mass flux `g`; a^0.8 b^0.8 as
/// (a b)^0.8, a^0.4 b^0.4 as (a b)^0.4.
fn miropolskii_with(s: &Local, p: &CryoParams, x: f64, g: f64) -> f64 {
    let d = diameter(s);
    let v = &s.vap_sat;
    let ratio = v.rho.max(0.0) / s.rho_l_sat.max(TINY);
    let re = g * d / v.mu.max(TINY) * (x + ratio * (1.0 - x));
    let pr = prandtl(s.vap_film.mu, s.vap_film.cp, s.vap_film.k);
    let y = (1.0 - 0.1 * ((1.0 / ratio.max(TINY) - 1.0).max(0.0) * (1.0 - x)).powf(0.4)).max(MIROPOLSKII_Y_FLOOR);
    p.miropolskii_scale * 0.023 * (re * pr).powf(0.8) * y * v.k.max(0.0) / d
}

/// Film-boiling coefficient at wall temperature `t_w`, W/(m² K), heat flux h_fb (T_w − T_s):
/// * [`CorrelationSet::Paper`]: Bromley with Iloeje's correction (eq:Iloeje_hfb)
///   h_fb = c1 h_br (1 − c2 X^c3)(1 + c4 G_l^c5), c1..c5 = qmfbsc, Xmfbsc, Xemfbsc, Gmfbsc,
///   Emfbsc (paper values 2.0, 1.04, 2.0, 0.2, 0.1), X the flow quality (see
///   [`iloeje_dt_mfb`]); the quality factor is floored at `iloeje_x_floor`.
/// * [`CorrelationSet::Miropolskii`]: max(Miropolskii, uncorrected Bromley), so that a standing
///   liquid still has pool film boiling.
pub fn film_boiling_htc(s: &Local, p: &CryoParams, set: CorrelationSet, t_w: f64) -> f64 {
    let (gg, gl) = mass_fluxes(s);
    FilmBoiling::new(s, p, set, regime_quality(s), gg, gl).htc(s, p, &s.vap_film, t_w)
}

/// The wall-temperature-independent factors of [`film_boiling_htc`].
enum FilmBoiling {
    /// Iloeje's quality and mass-flux factors (1 − c2 X^c3) (floored), (1 + c4 G_l^c5).
    Paper { quality: f64, flux: f64 },
    /// The Miropolskii coefficient.
    Miropolskii(f64),
}

impl FilmBoiling {
    /// At flow quality `x` and mass fluxes `gg`, `gl`.
    fn new(s: &Local, p: &CryoParams, set: CorrelationSet, x: f64, gg: f64, gl: f64) -> Self {
        match set {
            CorrelationSet::Paper => FilmBoiling::Paper {
                quality: (1.0 - p.fb_x_scale * pow_param(x, p.fb_x_exponent)).max(p.iloeje_x_floor),
                flux: 1.0 + p.fb_g_scale * gl.powf(p.fb_g_exponent),
            },
            CorrelationSet::Miropolskii => FilmBoiling::Miropolskii(miropolskii_with(s, p, x, gg + gl)),
        }
    }

    /// The coefficient at wall temperature `t_w` with film vapour `v`, W/(m² K).
    fn htc(&self, s: &Local, p: &CryoParams, v: &Vapour, t_w: f64) -> f64 {
        match *self {
            FilmBoiling::Paper { quality, flux } => p.fb_scale * bromley_with(s, v, t_w) * quality * flux,
            FilmBoiling::Miropolskii(h) => h.max(bromley_with(s, v, t_w)),
        }
    }
}

/// The characteristic points of the boiling curve at one state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchors {
    /// Onset of nucleate boiling, K.
    pub t_onb: f64,
    /// Heat flux at T_onb, W/m².
    pub q_onb: f64,
    /// Wall temperature of the critical heat flux, K.
    pub t_chf: f64,
    /// Critical heat flux, W/m² (at least max(q_onb, q_mfb)).
    pub q_chf: f64,
    /// Minimum film boiling temperature (or rewet temperature), K.
    pub t_mfb: f64,
    /// Heat flux at T_mfb, W/m² (eq:q_mfb).
    pub q_mfb: f64,
}

/// The anchors (T_onb, q_onb), (T_chf, q_chf), (T_mfb, q_mfb) of the boiling curve, ordered:
/// T_chf ≥ T_onb + `boil_gap_chf`, T_mfb ≥ T_chf + `boil_gap_mfb`, q_mfb = h_fb(T_mfb) (T_mfb − T_s)
/// (eq:q_mfb, the film vapour of [`Local::vap_mfb`]), q_chf ≥ `chf_over_mfb` max(q_onb, q_mfb).
/// The three bounds are registry parameters: where one binds, the parameters it holds
/// (`Tchfsc`, `Tonbsc`; `Tmfbsc`; `qchfsc` and the CHF shape) have no effect, and `cryofit
/// params` says so.
pub fn boiling_anchors(s: &Local, p: &CryoParams, set: CorrelationSet) -> Anchors {
    BoilingCurve::new(s, p, set).anchors
}

/// The boiling curve of one state: its anchors and the wall-temperature-independent parts of
/// its convective and film-boiling branches, each evaluated once.
pub(super) struct BoilingCurve<'a> {
    s: &'a Local,
    p: &'a CryoParams,
    pub(super) liquid: Convection,
    film: FilmBoiling,
    pub(super) anchors: Anchors,
}

impl<'a> BoilingCurve<'a> {
    pub(super) fn new(s: &'a Local, p: &'a CryoParams, set: CorrelationSet) -> Self {
        let liquid = Convection::liquid(s, p);
        let (gg, gl) = mass_fluxes(s);
        let x = regime_quality(s);
        let film = FilmBoiling::new(s, p, set, x, gg, gl);
        let (t_onb, q_onb) = onb_with(s, p, &liquid);
        let t_chf = theler_t_chf(s, p).max(t_onb + p.boil_gap_chf);
        let t_mfb_raw = match set {
            CorrelationSet::Paper => s.t_sat + iloeje_with(s, p, x, gl),
            CorrelationSet::Miropolskii => darr_hartwig_with(s, p, gg + gl),
        };
        let t_mfb = t_mfb_raw.max(t_chf + p.boil_gap_mfb);
        let q_mfb = film.htc(s, p, &s.vap_mfb, t_mfb) * (t_mfb - s.t_sat);
        let q_chf = chf_with(s, p, gg + gl).max(p.chf_over_mfb * q_onb.max(q_mfb));
        let anchors = Anchors { t_onb, q_onb, t_chf, q_chf, t_mfb, q_mfb };
        BoilingCurve { s, p, liquid, film, anchors }
    }

    /// Heat flux wall → liquid at wall temperature `t_w`, W/m², and the branch.
    pub(super) fn at(&self, t_w: f64) -> (f64, WallRegime) {
        let (s, a) = (self.s, &self.anchors);
        if t_w <= a.t_onb {
            (self.liquid.htc(t_w) * (t_w - s.t_l), WallRegime::Convection)
        } else if t_w <= a.t_chf {
            // eq:q_nb_int, in the orientation that gives q_onb at T_onb and q_chf at T_chf
            let y = ((t_w - a.t_onb) / (a.t_chf - a.t_onb)).clamp(0.0, 1.0);
            (a.q_onb + (a.q_chf - a.q_onb) * pow_param(y, self.p.nb_exponent), WallRegime::Nucleate)
        } else if t_w <= a.t_mfb {
            // eq:transition_boiling as printed (TRACE): f_tb = 1 at T_chf, 0 at T_mfb
            let f = ((t_w - a.t_mfb) / (a.t_chf - a.t_mfb)).clamp(0.0, 1.0).powi(2);
            (f * a.q_chf + (1.0 - f) * a.q_mfb, WallRegime::Transition)
        } else {
            (self.film.htc(s, self.p, &s.vap_film, t_w) * (t_w - s.t_sat), WallRegime::Film)
        }
    }
}

/// The liquid-side boiling curve alone: heat flux q(T_w) from the wall at `s.t_w` to the
/// liquid, W/m² of liquid-covered wall. Convection h_cb (T_w − T_l) up to T_onb; nucleate
/// boiling q_onb + (q_chf − q_onb) y^n, y = (T_w − T_onb)/(T_chf − T_onb) up to T_chf
/// (eq:q_nb_int, re-oriented); transition boiling f q_chf + (1 − f) q_mfb,
/// f = ((T_w − T_mfb)/(T_chf − T_mfb))² up to T_mfb (eq:transition_boiling); film boiling
/// h_fb(T_w)(T_w − T_s) above. Continuous at every anchor.
pub fn boiling_curve(s: &Local, p: &CryoParams, set: CorrelationSet) -> f64 {
    BoilingCurve::new(s, p, set).at(s.t_w).0
}
