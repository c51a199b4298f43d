//! The paper's cryogenic closure set (Sec. "Constitutive relations", "Heat and mass transfer",
//! "Parametrization", "Pressure drop"): flow-regime map, wall heat transfer along the boiling
//! curve, interphase heat transfer, wall friction, interfacial drag and virtual mass.
//!
//! Every function here is small and pure: it reads the local state of one cell ([`Local`], old
//! time level, SI units) and the tunable constants ([`CryoParams`], filled once from a
//! [`ParameterSet`](crate::params::ParameterSet)) and returns numbers. No I/O, no global state.
//!
//! # Conventions
//!
//! * Heat fluxes are W/m² of the **whole** inner wall; heat transfer coefficients W/(m² K).
//! * Mass fluxes G are kg/(m² s) of the pipe cross-section: G_g = α ρ_g |v_g|,
//!   G_l = (1 − α) ρ_l |v_l|, G = G_g + G_l.
//! * X_e is the equilibrium quality from the static (mass-weighted) mixture enthalpy,
//!   X_e = (h_m − h_l,sat)/(h_g,sat − h_l,sat), clamped to [0, 1] before any fractional power
//!   (DESIGN.md §4).
//! * The pool-boiling correlations (Zuber, Berenson, Bromley, Kutateladze) need gravity; with
//!   gravity switched off they use a floor of 10⁻³ m/s² so that nothing divides by zero.
//!   Natural convection uses the true gravity (none without it).
//!
//! # Paper slips and the decisions taken (DESIGN.md §4)
//!
//! | Where | Paper | Here |
//! |---|---|---|
//! | eq:Zuber | factor (ρ_l/(ρ_l+ρ_g))^½ | Zuber's own (1 + ρ_g/ρ_l)^½ |
//! | eq:Iloeje_chf | lists a4 = 0.2, exponent printed a5 | the G exponent is the parameter `chf_g_exp` (= a4) |
//! | eq:theler | k_g "isentropic expansion factor", "log" | k_g = 7/2 = c_p/R of a diatomic ideal gas, natural log |
//! | eq:Tmfb | last bracket [μ_g/(ρ_l − ρ_g)]^⅓ | Berenson's [μ_g/(g(ρ_l − ρ_g))]^⅓ (dimensionally right) |
//! | eq:Iloeje | constants a1 = 0.0144 … pasted from Griffith | Table 1: c1 = Tmfbsc, c2 = Xtmfbsc, c3 = Xetmfbsc, c4 = Gtmfbsc, c5 = Etmfbsc |
//! | Table 1 | Xetmfbsc = 2.0 "scaling", Xtmfbsc = 1.04 "exponent" | swapped: Xtmfbsc = 1.04 is the scale c2, Xetmfbsc = 2.0 the exponent c3 |
//! | eq:convection_Nu | 0.1 (Gr Pr)^⅓ "N-L", 0.59 (Gr Pr)^¼ "N-T" | 0.59 (Gr Pr)^¼ laminar, 0.1 (Gr Pr)^⅓ turbulent (max of all four is unchanged) |
//! | eq:churchill | 2.475 | Churchill's 2.457 (in [`churchill_darcy`](crate::closures::churchill_darcy)) |
//! | eq:q_nb_int | y^n q_onb + (1 − y^n) q_chf | reversed as printed (gives q_chf at T_onb): q_onb + (q_chf − q_onb) y^n |
//! | eq:transition_boiling | f_tb = ((T_w − T_mfb)/(T_chf − T_mfb))² | correct as printed: f_tb(T_chf) = 1 gives q_chf, f_tb(T_mfb) = 0 gives q_mfb; kept |
//! | Sec. "Direct search" | Gmfbsc, Emfbsc called c2, c3 of eq:Iloeje_hfb | by their names (G scale, G exponent, as Gtmfbsc/Etmfbsc): c4, c5 |
//! | Table 1 | "void fraction" in the comments | eq:Iloeje uses X_e; X_e it is |
//!
//! Further decisions where the paper is silent:
//!
//! * CHF form: a continuous weight `chf_griffith` ∈ [0, 1] between the simplified Iloeje-type
//!   form (default, weight 0: "in practice we often used") and the Griffith-type form, not a
//!   switch on [`CorrelationSet`] (an optimiser can move through it). Griffith's a1..a3 are his
//!   water constants, fixed.
//! * `Tchfsc` and `Tmfbsc` scale superheats (T − T_s), not absolute temperatures.
//! * G: total mass flux for the CHF, the regime map and Darr–Hartwig; the liquid mass flux for
//!   the Iloeje T_mfb and film-boiling corrections (the paper: "G is liquid mass flux").
//! * Theler needs R_g and Darr–Hartwig T_cr: fluid constants in [`CryoParams`], nitrogen by
//!   default, set with [`CryoParams::with_fluid`].
//! * The wetted fraction does not vanish above T_mfb (see [`wetted_fraction`]): film boiling is
//!   the liquid-side branch of the boiling curve there.
//! * Exponent scales (`hg0esc`, `hgi0esc`, `hli0esc`) multiply the Dittus–Boelter exponent 0.8
//!   literally; at the top of their (required ≥ 4×) range the coefficients are very large but
//!   finite.
//!
//! The anchors of the boiling curve are kept in order, T_onb < T_chf < T_mfb (gaps of at least
//! `boil_gap_chf` and `boil_gap_mfb`), and q_chf ≥ `chf_over_mfb` max(q_onb, q_mfb), so that the curve is
//! continuous, rises to its maximum at T_chf, falls to its minimum at T_mfb and rises again,
//! whatever the parameter values within their bounds.
//!
//! # Layout
//!
//! The closures live in private submodules, one per topic; everything public is re-exported
//! here, so callers name it `cryo::…`:
//!
//! | Module | Contents |
//! |---|---|
//! | `state` | [`Local`], [`Vapour`], the small helpers of the local state (void fraction, mass fluxes, qualities, the stratified half-angle) |
//! | `parameters` | [`CryoParams`], [`PARAMETER_NAMES`], [`CorrelationSet`], the fluid constants' defaults |
//! | `convection` | single-phase convection to the wall, Dittus–Boelter, the recovery temperature |
//! | `boiling` | the boiling curve: its anchors, the film-boiling correlations, the boiling property bases of [`Local`], [`WallRegime`] |
//! | `regime` | the flow-regime map ([`Regime`], [`flow_regime`], and [`flow_regime_cached`] with its velocity-free part kept in a [`RegimeBasis`]), the dryout boundary, the wetted fraction |
//! | `wall_heat` | [`WallHeat`], [`wall_heat`], the drop–wall contact of dispersed flow |
//! | `particles` | drop and bubble diameters and the regularised slip velocity |
//! | `interphase` | interphase heat transfer ([`Interphase`], [`interphase_heat`]) and flashing |
//! | `momentum` | wall friction, interfacial drag (each also with its velocity-free parts given, [`SlipFree`]), virtual mass |
//!
//! Dependencies run one way: `state` and `parameters` first, then `convection`, `boiling`,
//! `regime` and `particles`, then `wall_heat`, `interphase` and `momentum`. Of the crate's other
//! closures the set uses [`crate::closures`] (Churchill's friction factor, the smooth step), which
//! does not depend on it.

mod boiling;
mod convection;
mod interphase;
mod momentum;
mod parameters;
mod particles;
mod regime;
mod state;
mod wall_heat;

pub use boiling::{
    Anchors, WallRegime, berenson_dt_mfb, berenson_with, boiling_anchors, boiling_curve, bromley_htc,
    critical_heat_flux, darr_hartwig_t_wet, film_boiling_htc, iloeje_dt_mfb, miropolskii_htc,
    onset_of_nucleate_boiling, theler_t_chf, zuber_chf,
};
pub use convection::{
    convection_nusselt, gas_convection_htc, liquid_convection_htc, recovery_temperature_rise, scaled_dittus_boelter,
};
pub use interphase::{Interphase, flashing_htc, interphase_heat};
pub use momentum::{
    SlipFree, interfacial_drag, interfacial_drag_with, virtual_mass_coefficient, wall_friction, wall_friction_with,
};
pub use parameters::{
    CorrelationSet, CryoParams, DIATOMIC_CP_OVER_R, NITROGEN_GAS_CONSTANT, NITROGEN_T_CRITICAL, PARAMETER_NAMES,
    UnknownCorrelationSet,
};
pub use regime::{
    Regime, RegimeBasis, dryout_mass_flux, flow_regime, flow_regime_cached, intermittent_annular_quality,
    kutateladze_q_dnb, stratification_boundaries, wetted_fraction,
};
pub use state::{
    Local, Vapour, equilibrium_quality, mass_fluxes, regime_quality, static_quality, stratified_half_angle,
};
pub use wall_heat::{WallHeat, WallHeatBasis, drop_contact_htc, drop_enhancement, wall_heat};

/// Denominator floor for properties and lengths.
const TINY: f64 = 1e-30;
/// Velocity regularisation of the friction and drag coefficients, m/s: |v| → √(v² + V_REG²),
/// so that the implicit coefficients are finite and continuous through v = 0 (they tend to the
/// laminar/Stokes values there).
const V_REG: f64 = 1e-4;
/// Laminar fully developed Nusselt number of a pipe (constant wall temperature 3.66, constant
/// flux 4.36; the paper uses 4.36).
const NU_LAMINAR: f64 = 4.36;
/// Void fractions between which the bubbles of intermittent flow fade out of the drag.
const BUBBLY_VOID: (f64, f64) = (0.1, 0.4);

#[cfg(test)]
mod tests;
