//! Momentum closures: wall friction, interfacial drag and virtual mass.

use std::f64::consts::PI;

use super::parameters::CryoParams;
use super::particles::{bubble_diameter, particle_diameter, relative_speed};
use super::regime::{Regime, wetted_fraction_at};
use super::state::{Local, diameter, stratified_half_angle, void};
use super::{BUBBLY_VOID, TINY, V_REG};
use crate::closures::{churchill_darcy, smooth_step};

/// Wavy interface Fanning friction factor floor (Cohen & Hanratty).
const WAVY_FRICTION: f64 = 0.0142;

/// Wall friction per phase as implicit coefficients (f_g, f_l): force per unit volume on phase
/// k is −f_k v_k (N s/m⁴).
///
/// Single-phase ("phase alone") pressure gradients (eq:taitel76 with Churchill's Darcy factor
/// λ, eq:churchill): dp_k = λ_k G_k²/(2 D ρ_k) = φ_k |v_k|, φ_k = (λ Re)_k α_k μ_k/(2 D²),
/// Re_k = α_k ρ_k |v_k| D/μ_k (λ Re → 64 in laminar flow, so φ_k stays finite at v = 0).
/// Two-phase gradient (Lockhart–Martinelli with Chisholm's C, `chisholm_c`):
/// dp_2φ = dp_l + C √(dp_l dp_g) + dp_g, i.e. φ_l² dp_l with φ_l² = 1 + C/X + 1/X².
/// RELAP5 partition (the Z² split): gas share α_g/(α_g + α_l Z²) = B_g/(B_g + B_l),
/// B_k = α_wk (λ Re)_k ρ_k v_k², with the wall contact fractions α_wl = [`wetted_fraction`],
/// α_wg = 1 − α_wl (stratified: both walls; annular: all on the liquid film; mist: all on the
/// gas). f_k = `fwsc` share_k dp_2φ/|v_k|. Velocities are regularised |v| → √(v² + (10⁻⁴)²).
pub fn wall_friction(s: &Local, p: &CryoParams, regime: &Regime, roughness_rel: f64) -> (f64, f64) {
    wall_friction_with(s, p, regime, roughness_rel, &SlipFree::new(s))
}

/// The parts of the momentum closures at a state that do not depend on its phase velocities
/// (the void fraction's geometry, the bubbles' size), computed once where the closures are
/// evaluated again at a shifted slip (the momentum step's drag slope). The closures with and
/// without it agree to the bit.
#[derive(Debug, Clone, Copy)]
pub struct SlipFree {
    d: f64,
    a: f64,
    beta: f64,
    /// The stratified layer's half-angle δ ([`stratified_half_angle`]).
    half_angle: f64,
    /// The stratified interface per volume, 4 sin δ/(π D).
    a_strat: f64,
    sqrt_a: f64,
    d_b: f64,
    /// The bubbles' weight of intermittent flow.
    bubbly: f64,
}

impl SlipFree {
    /// The velocity-free parts at `s`.
    pub fn new(s: &Local) -> Self {
        let d = diameter(s);
        let a = void(s);
        let beta = 1.0 - a;
        let half_angle = stratified_half_angle(beta);
        Self {
            d,
            a,
            beta,
            half_angle,
            a_strat: 4.0 * half_angle.sin() / (PI * d),
            sqrt_a: a.sqrt(),
            d_b: bubble_diameter(s),
            bubbly: 1.0 - smooth_step((a - BUBBLY_VOID.0) / (BUBBLY_VOID.1 - BUBBLY_VOID.0)),
        }
    }
}

/// [`wall_friction`] with the velocity-free parts from `g` (made at a state that differs from
/// `s` at most in its velocities).
pub fn wall_friction_with(s: &Local, p: &CryoParams, regime: &Regime, roughness_rel: f64, g: &SlipFree) -> (f64, f64) {
    let d = g.d;
    let a_g = g.a;
    let a_l = 1.0 - a_g;
    let w_l = wetted_fraction_at(regime, g.half_angle);
    let w_g = 1.0 - w_l;
    let rough = roughness_rel.max(0.0);
    let vg = (s.v_g * s.v_g + V_REG * V_REG).sqrt();
    let vl = (s.v_l * s.v_l + V_REG * V_REG).sqrt();
    let lambda_re = |a: f64, rho: f64, mu: f64, v: f64| {
        let re = (a * rho * v * d / mu.max(TINY)).max(1e-3);
        churchill_darcy(re, rough) * re
    };
    let lre_g = lambda_re(a_g, s.rho_g, s.mu_g, vg);
    let lre_l = lambda_re(a_l, s.rho_l, s.mu_l, vl);
    let phi_g = lre_g * a_g * s.mu_g.max(0.0) / (2.0 * d * d);
    let phi_l = lre_l * a_l * s.mu_l.max(0.0) / (2.0 * d * d);
    let (dp_g, dp_l) = (phi_g * vg, phi_l * vl);
    let dp = dp_g + dp_l + p.chisholm_c * (dp_g * dp_l).sqrt();
    let b_g = w_g * lre_g * s.rho_g.max(0.0) * vg * vg;
    let b_l = w_l * lre_l * s.rho_l.max(0.0) * vl * vl;
    let share_g = if b_g + b_l > 0.0 { b_g / (b_g + b_l) } else { w_g };
    let f_g = p.wall_friction_scale * share_g * dp / vg;
    let f_l = p.wall_friction_scale * (1.0 - share_g) * dp / vl;
    (if f_g.is_finite() { f_g } else { 0.0 }, if f_l.is_finite() { f_l } else { 0.0 })
}

/// Drag coefficient of a sphere (Schiller–Naumann, Newton regime 0.44).
fn sphere_cd(re: f64) -> f64 {
    let re = re.max(1e-9);
    // 24/Re (1 + 0.15 Re^0.687) falls with Re and is 0.4388 < 0.44 at Re = 1000
    if re >= 1000.0 {
        return 0.44;
    }
    (24.0 / re * (1.0 + 0.15 * re.powf(0.687))).max(0.44)
}

/// Interfacial drag coefficient F_i (N s/m⁴): force per unit volume on the gas −F_i (v_g − v_l)
/// (and +F_i (v_g − v_l) on the liquid), by regime, with v_r = |v_g − v_l| (regularised):
/// * stratified: ½ f_i ρ_g v_r a_i, a_i = 4 sin δ/(π D), f_i the smooth-interface Fanning factor
///   λ(Re_r)/4, Re_r = ρ_g v_r D/μ_g (Taitel & Dukler);
/// * stratified-wavy: the same with f_i ≥ 0.0142 (Cohen & Hanratty);
/// * annular/intermittent: Wallis f_i = 0.005 (1 + 75 (1 − α)) on a_i = 4√α/D, plus the bubbles
///   of intermittent flow ¾ C_D ρ_l v_r α (1 − α)/d_b, d_b = 2 √(σ/(g Δρ)) (twice the capillary
///   length, ≈ 2 mm for nitrogen: terminal velocity ≈ 0.25 m/s), faded out between α = 0.1 and
///   0.4 (a Weber diameter from the phasic slip of annular flow gives 10 µm bubbles);
///   the fade is geometric, F_film (1 + F_bubbles/F_film)^b with b the bubbles' weight (1 below
///   α = 0.1, 0 above 0.4): the same values at both ends as the film plus b times the bubbles;
/// * dryout/mist: drops ¾ C_D ρ_g v_r (1 − α)/d_d, d_d = 12 σ/(ρ_g v_r²) ≤ `drop_d_max`, C_D Schiller–Naumann.
///
/// Stratified and wavy are scaled by `idrag_strat_sc`, the rest by `idrag_disp_sc`. All tend to
/// their laminar/Stokes values as v_r → 0.
pub fn interfacial_drag(s: &Local, p: &CryoParams, regime: &Regime) -> f64 {
    interfacial_drag_with(s, p, regime, &SlipFree::new(s))
}

/// [`interfacial_drag`] with the velocity-free parts from `g` (made at a state that differs
/// from `s` at most in its velocities).
pub fn interfacial_drag_with(s: &Local, p: &CryoParams, regime: &Regime, g: &SlipFree) -> f64 {
    let (d, a, beta) = (g.d, g.a, g.beta);
    let v_r = relative_speed(s);
    let re_r = (s.rho_g * v_r * d / s.mu_g.max(TINY)).max(1e-3);
    let f_smooth = churchill_darcy(re_r, 0.0) / 4.0;
    let a_strat = g.a_strat;
    let f_strat = 0.5 * f_smooth * s.rho_g * v_r * a_strat;
    let f_wavy = 0.5 * f_smooth.max(WAVY_FRICTION) * s.rho_g * v_r * a_strat;

    let f_wallis = (0.005 * (1.0 + 75.0 * beta)).max(f_smooth);
    let f_film = 0.5 * f_wallis * s.rho_g * v_r * 4.0 * g.sqrt_a / d;
    let d_b = g.d_b;
    let re_b = s.rho_l * v_r * d_b / s.mu_l.max(TINY);
    let bubbly = g.bubbly;
    let f_bubbles = 0.75 * sphere_cd(re_b) * s.rho_l * v_r * a * beta / d_b;
    // Decision: the bubbles' drag (∝ ρ_l) is hundreds of times the film's (∝ ρ_g), so faded
    // out linearly it still ruled the drag a few hundredths below α = 0.4: the drag fell
    // elevenfold between α = 0.37 and 0.40 (saturated nitrogen at 1 atm, 1 m/s slip; 1.2-fold
    // faded geometrically). The momentum step takes α from the start of the step, and a
    // cell near that edge oscillated (α 0.37–0.41 with a 1.5 s period, the gas velocity by
    // ±9 %) with an amplitude that grew with the step (saturated 2.5 atm, 500 s: α 0.387–0.389
    // at 15 ms steps, 0.371–0.408 at 0.12 s), its volume errors holding the steps down. Faded
    // geometrically the drag changes by a bounded factor per unit α (e^(ln(F_b/F_f)·Δb)) and
    // the oscillation is gone; the NBS nitrogen chilldowns moved by at most 0.4 s.
    let f_intermittent = if bubbly > 0.0 && f_film > 0.0 {
        f_film * (1.0 + f_bubbles / f_film).powf(bubbly)
    } else {
        f_film + bubbly * f_bubbles
    };

    let d_d = particle_diameter(s.sigma, s.rho_g, v_r, d, p.drop_diameter_max);
    let re_d = s.rho_g * v_r * d_d / s.mu_g.max(TINY);
    let f_drop = 0.75 * sphere_cd(re_d) * s.rho_g * v_r * beta / d_d;

    let f = p.drag_stratified_scale * (regime.stratified * f_strat + regime.wavy * f_wavy)
        + p.drag_dispersed_scale * (regime.annular * f_intermittent + regime.dryout * f_drop);
    if f.is_finite() { f.max(0.0) } else { 0.0 }
}

/// Virtual-mass coefficient C (dimensionless) of C α (1 − α) ρ_m ∂(v_g − v_l)/∂t: the registry
/// parameter `vm_coeff` (RELAP5 uses 0.5 for dispersed flow; the paper keeps only the time
/// derivative).
pub fn virtual_mass_coefficient(_s: &Local, p: &CryoParams) -> f64 {
    p.virtual_mass
}
