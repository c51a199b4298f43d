//! Interphase heat transfer: interfacial areas and coefficients by regime, and flashing of
//! superheated liquid.

use std::f64::consts::PI;

use super::convection::dittus_boelter;
use super::parameters::CryoParams;
use super::particles::{bubble_diameter, particle_diameter, relative_speed};
use super::regime::Regime;
use super::state::{Local, diameter, prandtl, stratified_half_angle, void};
use super::{BUBBLY_VOID, NU_LAMINAR, TINY};
use crate::closures::smooth_step;

/// Nusselt number of a drop interior: conduction 2π²/3 (Newman) up to Kronig & Brink's
/// circulating-drop limit 17.9.
const NU_DROP_INTERIOR: (f64, f64) = (2.0 * PI * PI / 3.0, 17.9);
/// Wavy stratified interface: area over the flat chord.
const WAVY_AREA_FACTOR: f64 = 2.0;

/// Interphase heat transfer, volumetric coefficients W/(m³ K) for q_ig = H_ig (T_sat − T_g) and
/// q_il = H_il (T_sat − T_l).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interphase {
    /// Gas side, W/(m³ K).
    pub h_ig: f64,
    /// Liquid side, W/(m³ K).
    pub h_il: f64,
}

/// Interphase heat transfer by regime: interfacial area density a_i times a Dittus–Boelter-type
/// coefficient on each side, h = (κ/L) max(Nu_0, 0.023 Re^(0.8 e) Pr^0.4), blended with the
/// regime weights.
///
/// | regime | a_i, 1/m | L | gas Re | liquid Re, Nu_0 |
/// |---|---|---|---|---|
/// | stratified | 4 sin δ/(π D) (interface chord) | D | ρ_g |v_g − v_l| D/μ_g | ρ_l |v_l| D/μ_l, 4.36 |
/// | wavy | 2 × stratified | D | as stratified | as stratified |
/// | annular/intermittent | 4 √α / D (film surface) | D | as stratified | as stratified |
/// | dryout/mist | 6 (1 − α)/d, d = 12 σ/(ρ_g v_r²) ≤ `drop_d_max` | d | ρ_g v_r d/μ_g, Nu_0 = 2 | ρ_l v_r d/μ_l, 6.58 (2π²/3), Nu ≤ 17.9 (Kronig–Brink) |
///
/// e = `hgi0esc` on the gas side and `hli0esc` on the liquid side; the gas side is scaled by
/// `hgisc`. Every area vanishes with the phase that bounds it (the stratified chord as either
/// phase fills the tube, the film surface 4√α/D with the gas, the drops' 6β/d with the liquid),
/// so no presence weight multiplies them: the blending thresholds are numerics and a mist that
/// carries a real share of the mass at a small volume fraction keeps its whole interface.
/// `Gisc` scales the resulting interface mass transfer in the scheme
/// ([`CryoParams::interface_mass_transfer_scale`]).
pub fn interphase_heat(s: &Local, p: &CryoParams, regime: &Regime) -> Interphase {
    let d = diameter(s);
    let a = void(s);
    let beta = 1.0 - a;
    let v_r = relative_speed(s);
    let pr_g = prandtl(s.mu_g, s.cp_g, s.k_g);
    let pr_l = prandtl(s.mu_l, s.cp_l, s.k_l);
    let (eg, el) = (p.gas_interface_exponent_scale, p.liquid_interface_exponent_scale);
    let db = |re: f64, pr: f64, e: f64, nu0: f64| nu0.max(dittus_boelter(re.max(0.0), pr, e));

    // pipe-scale interfaces (stratified, wavy, annular)
    let re_g = s.rho_g * v_r * d / s.mu_g.max(TINY);
    let re_l = s.rho_l * s.v_l.abs() * d / s.mu_l.max(TINY);
    let hg_pipe = db(re_g, pr_g, eg, NU_LAMINAR) * s.k_g.max(0.0) / d;
    let hl_pipe = db(re_l, pr_l, el, NU_LAMINAR) * s.k_l.max(0.0) / d;
    let a_strat = 4.0 * stratified_half_angle(beta).sin() / (PI * d);
    let a_pipe =
        regime.stratified * a_strat + regime.wavy * WAVY_AREA_FACTOR * a_strat + regime.annular * 4.0 * a.sqrt() / d;

    // drops
    let d_drop = particle_diameter(s.sigma, s.rho_g, v_r, d, p.drop_diameter_max);
    let a_drop = regime.dryout * 6.0 * beta / d_drop;
    let re_gd = s.rho_g * v_r * d_drop / s.mu_g.max(TINY);
    let re_ld = s.rho_l * v_r * d_drop / s.mu_l.max(TINY);
    let hg_drop = db(re_gd, pr_g, eg, 2.0) * s.k_g.max(0.0) / d_drop;
    let hl_drop = db(re_ld, pr_l, el, NU_DROP_INTERIOR.0).min(NU_DROP_INTERIOR.1) * s.k_l.max(0.0) / d_drop;

    // flashing: superheated liquid boils on the bubbles it holds
    let hl_flash = flashing_htc(s, p);

    Interphase {
        h_ig: p.gas_interface_scale * (a_pipe * hg_pipe + a_drop * hg_drop),
        h_il: a_pipe * hl_pipe + a_drop * hl_drop + hl_flash,
    }
}

/// Liquid-side interphase coefficient of flashing, W/(m³ K): liquid above its saturation
/// temperature boils on bubbles, a_b = 6 max(α, `flash_void_min`)/d_b with d_b the bubble
/// diameter of [`bubble_diameter`], and the Plesset–Zwick coefficient of a growing bubble,
/// h = (k_l/d_b)(12/π) Ja, Ja = ρ_l c_p,l (T_l − T_sat)/(ρ_g,sat h_lg) (RELAP5's bubbly-flow
/// coefficient for superheated liquid, with its minimum void 10⁻⁵), at least the conduction
/// limit Nu = 2; faded in over the first kelvin of superheat and out with the bubbly regime
/// (void fractions 0.1–0.4, as the bubble drag).
///
/// Decision: without it a cell filled with liquid has no interface (every other area vanishes
/// with the vapour), and liquid stretched by an outflow larger than its inflow (vapour collapse
/// behind a surge) fell to the property table's 1 kPa at 81 K with no vapour forming.
pub fn flashing_htc(s: &Local, p: &CryoParams) -> f64 {
    let superheat = s.t_l - s.t_sat;
    if !(superheat > 0.0 && s.h_lg > 0.0) {
        return 0.0;
    }
    let a = void(s);
    let bubbly = 1.0 - smooth_step((a - BUBBLY_VOID.0) / (BUBBLY_VOID.1 - BUBBLY_VOID.0));
    let d_b = bubble_diameter(s);
    let area = 6.0 * a.max(p.flash_void_min) / d_b;
    let ja = s.rho_l * s.cp_l * superheat / (s.vap_sat.rho * s.h_lg).max(TINY);
    let nu = (12.0 / PI * ja).max(2.0);
    let h = smooth_step(superheat) * bubbly * area * nu * s.k_l.max(0.0) / d_b;
    if h.is_finite() { h } else { 0.0 }
}
