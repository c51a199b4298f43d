//! The local state of one cell ([`Local`], [`Vapour`]) and the small helpers that read it:
//! void fraction, diameter, mass fluxes, qualities and the stratified half-angle.

use std::f64::consts::PI;

use super::TINY;
use crate::fastmath::cbrt;

/// Gravity floor of the pool-boiling correlations when gravity is off, m/s².
const GRAVITY_FLOOR: f64 = 1e-3;
/// Reference mass flux of the regime quality, kg/(m² s): the flow quality G_g/G above it, the
/// static quality below (see [`regime_quality`]).
const G_REF_QUALITY: f64 = 1.0;

/// Local state of one cell, old time level, SI units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Local {
    /// Pressure, Pa.
    pub p: f64,
    /// Wall temperature, K.
    pub t_w: f64,
    /// Gas temperature, K.
    pub t_g: f64,
    /// Liquid temperature, K.
    pub t_l: f64,
    /// Saturation temperature at `p`, K.
    pub t_sat: f64,
    /// Gas volume fraction α.
    pub alpha: f64,
    /// Gas density, kg/m³.
    pub rho_g: f64,
    /// Liquid density, kg/m³.
    pub rho_l: f64,
    /// Gas viscosity, Pa s.
    pub mu_g: f64,
    /// Liquid viscosity, Pa s.
    pub mu_l: f64,
    /// Gas thermal conductivity, W/(m K).
    pub k_g: f64,
    /// Liquid thermal conductivity, W/(m K).
    pub k_l: f64,
    /// Gas isobaric heat capacity, J/(kg K).
    pub cp_g: f64,
    /// Liquid isobaric heat capacity, J/(kg K).
    pub cp_l: f64,
    /// Latent heat h_g,sat − h_l,sat, J/kg.
    pub h_lg: f64,
    /// Surface tension, N/m.
    pub sigma: f64,
    /// Liquid specific enthalpy, J/kg.
    pub h_l: f64,
    /// Gas specific enthalpy, J/kg.
    pub h_g: f64,
    /// Saturated liquid enthalpy, J/kg.
    pub h_l_sat: f64,
    /// Saturated vapour enthalpy, J/kg.
    pub h_g_sat: f64,
    /// Cell-centred gas velocity, m/s.
    pub v_g: f64,
    /// Cell-centred liquid velocity, m/s.
    pub v_l: f64,
    /// Hydraulic (inner) diameter, m.
    pub d_h: f64,
    /// Gravity magnitude, m/s² (0 when gravity is off).
    pub gravity: f64,
    /// Gas thermal expansion coefficient −(1/ρ) ∂ρ/∂T|_p, 1/K.
    pub beta_g: f64,
    /// Liquid thermal expansion coefficient −(1/ρ) ∂ρ/∂T|_p, 1/K.
    pub beta_l: f64,
    /// Saturated liquid density at `p`, kg/m³ (the pool-boiling correlations' ρ_l).
    pub rho_l_sat: f64,
    /// Saturated vapour at `p`: the property basis of ONB, Zuber's and Kutateladze's heat fluxes,
    /// the Griffith CHF, Wojtan's dryout boundary and Miropolskii's Reynolds number.
    pub vap_sat: Vapour,
    /// Vapour at the film temperature (T_w + T_s)/2 of the cell's wall: Bromley's film-boiling
    /// coefficient at the wall.
    pub vap_film: Vapour,
    /// Vapour at the film temperature T_s + ΔT_mfb,0/2 of the minimum film boiling point
    /// (Berenson's ΔT_mfb,0 with saturated vapour): Berenson's ΔT_mfb and q_mfb.
    pub vap_mfb: Vapour,
}

/// Vapour properties of a boiling correlation's basis (saturation or a film temperature).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Vapour {
    /// Density, kg/m³.
    pub rho: f64,
    /// Viscosity, Pa s.
    pub mu: f64,
    /// Thermal conductivity, W/(m K).
    pub k: f64,
    /// Isobaric heat capacity, J/(kg K).
    pub cp: f64,
}

impl Local {
    /// The same state with every vapour basis (saturation and both film temperatures) taken
    /// from the cell's own vapour and saturated densities from the cell's phases: for states
    /// without a saturation line, tests and callers that have no property table at hand.
    pub fn with_cell_vapour_basis(mut self) -> Self {
        let v = Vapour { rho: self.rho_g, mu: self.mu_g, k: self.k_g, cp: self.cp_g };
        self.vap_sat = v;
        self.vap_film = v;
        self.vap_mfb = v;
        self.rho_l_sat = self.rho_l;
        self
    }
}

pub(super) fn void(s: &Local) -> f64 {
    if s.alpha.is_finite() { s.alpha.clamp(0.0, 1.0) } else { 0.0 }
}

pub(super) fn diameter(s: &Local) -> f64 {
    s.d_h.max(1e-9)
}

/// Gravity of the pool-boiling correlations (floored, see the module docs), m/s².
pub(super) fn boiling_gravity(s: &Local) -> f64 {
    s.gravity.abs().max(GRAVITY_FLOOR)
}

pub(super) fn delta_rho(s: &Local) -> f64 {
    (s.rho_l - s.rho_g).max(1e-6 * s.rho_l.max(TINY))
}

/// ρ_l,sat − ρ_g,sat: the density difference of the pool-boiling correlations (buoyancy of
/// saturated vapour in saturated liquid).
pub(super) fn sat_delta_rho(s: &Local) -> f64 {
    (s.rho_l_sat - s.vap_sat.rho).max(1e-6 * s.rho_l_sat.max(TINY))
}

pub(super) fn prandtl(mu: f64, cp: f64, k: f64) -> f64 {
    (mu * cp / k.max(TINY)).max(0.0)
}

/// Superficial mass fluxes (G_g, G_l) = (α ρ_g |v_g|, (1 − α) ρ_l |v_l|), kg/(m² s).
pub fn mass_fluxes(s: &Local) -> (f64, f64) {
    let a = void(s);
    (a * s.rho_g.max(0.0) * s.v_g.abs(), (1.0 - a) * s.rho_l.max(0.0) * s.v_l.abs())
}

/// Static quality α ρ_g / (α ρ_g + (1 − α) ρ_l).
pub fn static_quality(s: &Local) -> f64 {
    let a = void(s);
    let mg = a * s.rho_g.max(0.0);
    let ml = (1.0 - a) * s.rho_l.max(0.0);
    if mg + ml > 0.0 { mg / (mg + ml) } else { 0.0 }
}

/// Equilibrium quality X_e = (h_m − h_l,sat)/(h_g,sat − h_l,sat) of the static mixture enthalpy
/// h_m = (α ρ_g h_g + (1 − α) ρ_l h_l)/(α ρ_g + (1 − α) ρ_l), clamped to [0, 1] (DESIGN.md §4:
/// clamp before fractional powers).
pub fn equilibrium_quality(s: &Local) -> f64 {
    let a = void(s);
    let mg = a * s.rho_g.max(0.0);
    let ml = (1.0 - a) * s.rho_l.max(0.0);
    let dh = s.h_g_sat - s.h_l_sat;
    if mg + ml <= 0.0 || dh.abs() <= TINY {
        return static_quality(s);
    }
    let h_m = (mg * s.h_g + ml * s.h_l) / (mg + ml);
    let x = (h_m - s.h_l_sat) / dh;
    if x.is_finite() { x.clamp(0.0, 1.0) } else { static_quality(s) }
}

/// Quality χ of the flow-regime map: (G_g + G_ref x_s)/(G + G_ref) with G_ref = 1 kg/(m² s),
/// i.e. the flow quality G_g/G of a moving mixture, smoothly the static quality x_s of a
/// standing one (the flow quality is 0/0 there). In [0, 1].
pub fn regime_quality(s: &Local) -> f64 {
    let (gg, gl) = mass_fluxes(s);
    ((gg + G_REF_QUALITY * static_quality(s)) / (gg + gl + G_REF_QUALITY)).clamp(0.0, 1.0)
}

/// (3π/2)^(1/3), written out (cbrt is not evaluated at compile time; checked by a test).
pub(super) const CBRT_3PI_2: f64 = 1.676_539_193_219_743_5;

/// Half-angle δ (rad) subtended at the pipe axis by the liquid of a stratified layer of liquid
/// fraction `beta` (Biberg's explicit approximation, error below 0.002 rad; it is the θ_strat of
/// Wojtan et al.: θ_dry = 2π − 2δ). The wetted perimeter fraction is δ/π and the interface chord
/// D sin δ.
pub fn stratified_half_angle(beta: f64) -> f64 {
    let b = if beta.is_finite() { beta.clamp(0.0, 1.0) } else { 0.0 };
    let d = PI * b + CBRT_3PI_2 * (1.0 - 2.0 * b + cbrt(b) - cbrt(1.0 - b))
        - b * (1.0 - b) * (1.0 - 2.0 * b) * (1.0 + 4.0 * (b * b + (1.0 - b) * (1.0 - b))) / 200.0;
    d.clamp(0.0, PI)
}
