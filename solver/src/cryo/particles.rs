//! Drop and bubble sizes and the regularised slip velocity, shared by the interphase heat
//! transfer, the interfacial drag and the drop–wall contact.

use super::state::{Local, boiling_gravity, delta_rho, diameter};
use super::{TINY, V_REG};

/// Critical Weber number of drops.
const WE_CRIT: f64 = 12.0;
/// Smallest drop or bubble diameter, m.
const D_PARTICLE_MIN: f64 = 1e-5;

/// Drop diameter from a critical Weber number, clamped to [10 µm, min(D/2, `drop_d_max`)], m.
///
/// Decision: the diameter is also bounded by `drop_d_max` (registry, 1 mm by default). The
/// Weber size follows the slip, and in the mist behind a quench front the drag has tied the drops
/// to the vapour (slip of cm/s): the formula then gives drops of half the tube diameter, whose
/// interface is a few W/(m³ K) — drops of liquid that cross 50 m of a 270 K line without
/// evaporating and leave with a sixth of the flow. Drops are made where the liquid is torn off at
/// the front, at the slip of that moment (0.1–1 mm for nitrogen at 5–20 m/s), and keep their size
/// afterwards; the bound stands for that. Smaller bounds make the subcooled NBS run's first
/// contact violent: 0.5 mm drops of 76 K liquid condense the vapour at the inlet so fast that
/// 27 of the 65 points of a ±0.2 sensitivity scan around the defaults end in a liquid hammer
/// beyond the tables (none at 1 mm, none without the bound).
pub(super) fn particle_diameter(sigma: f64, rho_continuous: f64, v_r: f64, d: f64, d_max: f64) -> f64 {
    (WE_CRIT * sigma.max(0.0) / (rho_continuous * v_r * v_r).max(TINY))
        .clamp(D_PARTICLE_MIN, (0.5 * d).min(d_max).max(D_PARTICLE_MIN))
}

/// Relative velocity, regularised: √((v_g − v_l)² + V_REG²).
pub(super) fn relative_speed(s: &Local) -> f64 {
    let dv = s.v_g - s.v_l;
    (dv * dv + V_REG * V_REG).sqrt()
}

/// Bubble diameter of intermittent flow: twice the capillary length √(σ/(g Δρ)), clamped to
/// [10 µm, D/2], m.
pub(super) fn bubble_diameter(s: &Local) -> f64 {
    let lc = (s.sigma.max(0.0) / (boiling_gravity(s) * delta_rho(s))).sqrt();
    (2.0 * lc).clamp(D_PARTICLE_MIN, (0.5 * diameter(s)).max(D_PARTICLE_MIN))
}
