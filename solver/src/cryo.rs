//! The paper's cryogenic closure set (Sec. "Constitutive relations", "Heat and mass transfer",
//! "Parametrization", "Pressure drop"): flow-regime map, wall heat transfer along the boiling
//! curve, interphase heat transfer, wall friction, interfacial drag and virtual mass.
//!
//! Every function here is small and pure: it reads the local state of one cell ([`Local`], old
//! time level, SI units) and the tunable constants ([`CryoParams`], filled once from a
//! [`ParameterSet`]) and returns numbers. No I/O, no global state.
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
//! | eq:churchill | 2.475 | Churchill's 2.457 (in [`churchill_darcy`]) |
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

use std::f64::consts::PI;
use std::fmt;
use std::str::FromStr;

use crate::closures::{churchill_darcy, smooth_step};
use crate::fastmath::{cbrt, fourth_root, pow_param};
use crate::fluids::{FluidConstants, FluidTable, Phase};
use crate::params::ParameterSet;

/// Denominator floor for properties and lengths.
const TINY: f64 = 1e-30;
/// Gravity floor of the pool-boiling correlations when gravity is off, m/s².
const GRAVITY_FLOOR: f64 = 1e-3;
/// Velocity regularisation of the friction and drag coefficients, m/s: |v| → √(v² + V_REG²),
/// so that the implicit coefficients are finite and continuous through v = 0 (they tend to the
/// laminar/Stokes values there).
const V_REG: f64 = 1e-4;
/// Reference mass flux of the regime quality, kg/(m² s): the flow quality G_g/G above it, the
/// static quality below (see [`regime_quality`]).
const G_REF_QUALITY: f64 = 1.0;
/// Width in quality of the smooth mist transition.
const QUALITY_WIDTH: f64 = 0.05;
/// Floor of the normalised wall heat flux q/q_DNB of the dryout boundary.
const Q_TILDE_MIN: f64 = 1e-3;
/// Lowest stratified boundary mass flux, kg/(m² s) (the polynomials can be driven negative).
const G_BOUNDARY_MIN: f64 = 1.0;
/// The wavy boundary is at least this factor above the stratified one.
const WAVY_OVER_STRAT_MIN: f64 = 1.5;
/// Floor of Miropolskii's Y (not a parameter-scaled quantity: Y has no registry constant).
const MIROPOLSKII_Y_FLOOR: f64 = 0.05;
/// Laminar fully developed Nusselt number of a pipe (constant wall temperature 3.66, constant
/// flux 4.36; the paper uses 4.36).
const NU_LAMINAR: f64 = 4.36;
/// Bromley's constant for a horizontal cylinder (the scale is `qmfbsc`).
const BROMLEY_C: f64 = 0.62;
/// Bromley's latent-heat correction h̃_lg = h_lg + 0.4 c_pg ΔT.
const BROMLEY_SENSIBLE: f64 = 0.4;
/// Theler's k_g = c_p/R of a diatomic ideal gas with its rotation excited: nitrogen's, the
/// default of [`CryoParams::ideal_cp_over_r`].
pub const DIATOMIC_CP_OVER_R: f64 = 3.5;
/// Griffith-type CHF constants (paper, after Griffith 1957; water values).
const GRIFFITH_A: [f64; 3] = [0.0144, 1.0e-6, 0.5e-3];
/// Spiegler's thermodynamic limit of liquid contact, T/T_cr = 27/32: the leading factor of the
/// Darr–Hartwig rewet temperature.
const DARR_HARTWIG_TCR_FACTOR: f64 = 27.0 / 32.0;
/// Critical Weber number of drops.
const WE_CRIT: f64 = 12.0;
/// Nusselt number of a drop interior: conduction 2π²/3 (Newman) up to Kronig & Brink's
/// circulating-drop limit 17.9.
const NU_DROP_INTERIOR: (f64, f64) = (2.0 * PI * PI / 3.0, 17.9);
/// Void fractions between which the bubbles of intermittent flow fade out of the drag.
const BUBBLY_VOID: (f64, f64) = (0.1, 0.4);
/// Smallest drop or bubble diameter, m.
const D_PARTICLE_MIN: f64 = 1e-5;
/// Wavy stratified interface: area over the flat chord.
const WAVY_AREA_FACTOR: f64 = 2.0;
/// Wavy interface Fanning friction factor floor (Cohen & Hanratty).
const WAVY_FRICTION: f64 = 0.0142;
/// Nitrogen's specific gas constant, J/(kg K): the default of [`CryoParams::gas_constant`].
pub const NITROGEN_GAS_CONSTANT: f64 = 296.8;
/// Nitrogen's critical temperature, K: the default of [`CryoParams::t_critical`].
pub const NITROGEN_T_CRITICAL: f64 = 126.192;

/// Boiling-curve branch in [`WallHeat::regime_code`]: single-phase convection to the liquid.
pub const REGIME_CONVECTION: u8 = 0;
/// Nucleate boiling (T_onb < T_w ≤ T_chf).
pub const REGIME_NUCLEATE: u8 = 1;
/// Transition boiling (T_chf < T_w ≤ T_mfb).
pub const REGIME_TRANSITION: u8 = 2;
/// Film boiling (T_w > T_mfb).
pub const REGIME_FILM: u8 = 3;
/// Dry wall: no liquid-covered perimeter (wetted fraction below 10⁻³); heat goes to the gas.
pub const REGIME_DRY: u8 = 4;

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
    /// The same state with the boiling correlations' property bases read from `fluid`:
    /// saturated vapour at T_s, the film vapour of the wall at (T_w + T_s)/2 and that of the
    /// minimum film boiling point at T_s + ΔT_mfb,0/2 (Berenson's superheat with saturated
    /// vapour, unscaled: the film temperature does not move with `Tmfbsc`). Film temperatures
    /// are held within the gas table; where the table holds no vapour at a temperature (above
    /// the critical pressure, say) the basis stays as it was.
    pub fn with_boiling_basis(mut self, fluid: &FluidTable) -> Self {
        let vapour_at = |t: f64| -> Option<Vapour> {
            let (lo, hi) = fluid.phase_temperature_range(Phase::Gas, self.p)?;
            let t = t.clamp(lo, hi);
            let g = fluid.phase_props(Phase::Gas, self.p, t).ok()?;
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

/// Which film-boiling / minimum-film-boiling pair the boiling curve uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum CorrelationSet {
    /// The paper's: Berenson ΔT_mfb with the Iloeje correction (eq:Tmfb, eq:Iloeje) and Bromley
    /// film boiling with the Iloeje correction (eq:Bromley, eq:Iloeje_hfb).
    #[default]
    Paper,
    /// The alternative: Miropolskii film boiling with its Y correction (never below pool
    /// Bromley) and a Darr–Hartwig-type rewet temperature in place of T_mfb.
    Miropolskii,
}

impl CorrelationSet {
    /// Every set, in order.
    pub const ALL: [CorrelationSet; 2] = [CorrelationSet::Paper, CorrelationSet::Miropolskii];

    /// The name used in case files: `paper` or `miropolskii`.
    pub fn name(self) -> &'static str {
        match self {
            CorrelationSet::Paper => "paper",
            CorrelationSet::Miropolskii => "miropolskii",
        }
    }
}

impl fmt::Display for CorrelationSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown correlation-set name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown correlation set '{0}' (expected 'paper' or 'miropolskii')")]
pub struct UnknownCorrelationSet(pub String);

impl FromStr for CorrelationSet {
    type Err = UnknownCorrelationSet;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        CorrelationSet::ALL
            .into_iter()
            .find(|c| c.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownCorrelationSet(s.to_string()))
    }
}

/// The registry names [`CryoParams::from_set`] reads, in the order of the struct fields.
pub const PARAMETER_NAMES: &[&str] = &[
    "Tonbsc",
    "nb_exp",
    "qchfsc",
    "chf_alpha_cr",
    "chf_void_exp",
    "chf_g_coeff",
    "chf_g_exp",
    "chf_griffith",
    "Tchfsc",
    "qmfbsc",
    "Xmfbsc",
    "Xemfbsc",
    "Gmfbsc",
    "Emfbsc",
    "Tmfbsc",
    "Gtmfbsc",
    "Etmfbsc",
    "Xetmfbsc",
    "Xtmfbsc",
    "hmirosc",
    "dh_we_coeff",
    "dh_we_exp",
    "hg0sc",
    "hg0esc",
    "hl0sc",
    "Gwsc",
    "tauw",
    "regime_strat_c0",
    "regime_strat_c1",
    "regime_strat_c2",
    "regime_wavy_c0",
    "regime_wavy_c1",
    "regime_wavy_c2",
    "kutateladze_k",
    "xmin",
    "regime_width",
    "fwsc",
    "chisholm_c",
    "Gisc",
    "hgisc",
    "hgi0esc",
    "hli0esc",
    "idrag_strat_sc",
    "idrag_disp_sc",
    "drop_d_max",
    "vm_coeff",
    "blend_xmin",
    "blend_xmax",
    "iloeje_x_floor",
    "boil_gap_chf",
    "boil_gap_mfb",
    "chf_over_mfb",
    "flash_void_min",
    "drop_contact_k",
];

/// The constants of the closure set, read once from a [`ParameterSet`] (each field's doc starts
/// with its registry name), plus two fluid constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CryoParams {
    /// `Tonbsc`: scale of the ONB wall superheat T_onb − T_s.
    pub t_onb_scale: f64,
    /// `nb_exp`: exponent n of the nucleate-boiling interpolation (eq:q_nb_int).
    pub nb_exponent: f64,
    /// `qchfsc`: overall CHF scale (a1 of eq:Iloeje_chf).
    pub q_chf_scale: f64,
    /// `chf_alpha_cr`: critical void fraction α_cr.
    pub chf_alpha_cr: f64,
    /// `chf_void_exp`: exponent a2 of (α_cr − α) in eq:Iloeje_chf.
    pub chf_void_exponent: f64,
    /// `chf_g_coeff`: mass-flux coefficient a3 of eq:Iloeje_chf.
    pub chf_g_coeff: f64,
    /// `chf_g_exp`: mass-flux exponent a4 of eq:Iloeje_chf (printed a5).
    pub chf_g_exponent: f64,
    /// `chf_griffith`: weight of the Griffith-type form (eq:Griffith_chf) against the simplified
    /// Iloeje-type form: 0 simplified only, 1 Griffith only.
    pub chf_griffith_weight: f64,
    /// `Tchfsc`: scale of the CHF wall superheat T_chf − T_s (eq:theler).
    pub t_chf_scale: f64,
    /// `qmfbsc`: c1 of eq:Iloeje_hfb: film-boiling heat transfer scale.
    pub fb_scale: f64,
    /// `Xmfbsc`: c2 of eq:Iloeje_hfb: quality coefficient.
    pub fb_x_scale: f64,
    /// `Xemfbsc`: c3 of eq:Iloeje_hfb: quality exponent.
    pub fb_x_exponent: f64,
    /// `Gmfbsc`: c4 of eq:Iloeje_hfb: mass-flux coefficient.
    pub fb_g_scale: f64,
    /// `Emfbsc`: c5 of eq:Iloeje_hfb: mass-flux exponent.
    pub fb_g_exponent: f64,
    /// `Tmfbsc`: c1 of eq:Iloeje: scale of ΔT_mfb.
    pub t_mfb_scale: f64,
    /// `Gtmfbsc`: c4 of eq:Iloeje: mass-flux coefficient.
    pub t_mfb_g_scale: f64,
    /// `Etmfbsc`: c5 of eq:Iloeje: mass-flux exponent.
    pub t_mfb_g_exponent: f64,
    /// `Xetmfbsc`: c3 of eq:Iloeje: quality exponent (Table 1 says "scaling": swapped).
    pub t_mfb_x_exponent: f64,
    /// `Xtmfbsc`: c2 of eq:Iloeje: quality coefficient (Table 1 says "exponent": swapped).
    pub t_mfb_x_scale: f64,
    /// `hmirosc`: scale of the Miropolskii film-boiling coefficient.
    pub miropolskii_scale: f64,
    /// `dh_we_coeff`: Weber coefficient b of the Darr–Hartwig rewet temperature.
    pub dh_we_coeff: f64,
    /// `dh_we_exp`: Weber exponent e of the Darr–Hartwig rewet temperature.
    pub dh_we_exponent: f64,
    /// `hg0sc`: scale of the gas heat transfer to the dry wall.
    pub gas_wall_scale: f64,
    /// `hg0esc`: scale of the Dittus–Boelter Reynolds exponent (0.8) of the gas at the dry wall.
    pub gas_wall_exponent_scale: f64,
    /// `hl0sc`: scale of the single-phase liquid convection to the wetted wall.
    pub liquid_wall_scale: f64,
    /// `Gwsc`: scale of the wall mass transfer Γ_wg: **the scheme multiplies Γ_wg by it**.
    pub wall_mass_transfer_scale: f64,
    /// `tauw`: characteristic time of the heat transfer to the wall, s: **the scheme relaxes the
    /// wetted fraction towards [`wetted_fraction`] with this time constant**.
    pub wetting_time_constant: f64,
    /// `regime_strat_c0..c2`: stratified → stratified-wavy boundary G_strat(χ) = c0 + c1 χ + c2 χ².
    pub strat_poly: [f64; 3],
    /// `regime_wavy_c0..c2`: stratified-wavy → annular/intermittent boundary G_wavy(χ).
    pub wavy_poly: [f64; 3],
    /// `kutateladze_k`: Kutateladze constant K of q_DNB in the dryout boundary.
    pub kutateladze_k: f64,
    /// `xmin`: quality above which the flow is dispersed (mist).
    pub x_mist: f64,
    /// `regime_width`: width, in ln G, of the smooth transitions across G_strat and G_wavy.
    pub regime_width: f64,
    /// `fwsc`: scale of the two-phase wall friction.
    pub wall_friction_scale: f64,
    /// `chisholm_c`: Chisholm's C of the Lockhart–Martinelli multiplier.
    pub chisholm_c: f64,
    /// `Gisc`: scale of the interface mass transfer Γ_ig: **the scheme multiplies Γ_ig by it**.
    pub interface_mass_transfer_scale: f64,
    /// `hgisc`: scale of the gas-side interphase heat transfer.
    pub gas_interface_scale: f64,
    /// `hgi0esc`: scale of the Dittus–Boelter Reynolds exponent on the gas side of the interface.
    pub gas_interface_exponent_scale: f64,
    /// `hli0esc`: scale of the Dittus–Boelter Reynolds exponent on the liquid side of the interface.
    pub liquid_interface_exponent_scale: f64,
    /// `idrag_strat_sc`: scale of the stratified and stratified-wavy interfacial drag.
    pub drag_stratified_scale: f64,
    /// `idrag_disp_sc`: scale of the annular/intermittent and dispersed interfacial drag.
    pub drag_dispersed_scale: f64,
    /// `drop_d_max`: largest drop diameter of dispersed (mist) flow, m.
    pub drop_diameter_max: f64,
    /// `vm_coeff`: virtual-mass coefficient C.
    pub virtual_mass: f64,
    /// `blend_xmin`: a phase below this volume fraction is absent (no wetting, no interface).
    pub blend_min: f64,
    /// `blend_xmax`: a phase above this volume fraction is fully present.
    pub blend_max: f64,
    /// `iloeje_x_floor`: floor of the Iloeje quality factors (1 − c2 X^c3) of T_mfb and film
    /// boiling (Table 1's 1 − 1.04 X² is negative for X > 0.98).
    pub iloeje_x_floor: f64,
    /// `boil_gap_chf`: smallest T_chf − T_onb, K.
    pub boil_gap_chf: f64,
    /// `boil_gap_mfb`: smallest T_mfb − T_chf, K.
    pub boil_gap_mfb: f64,
    /// `chf_over_mfb`: smallest q_chf / max(q_onb, q_mfb).
    pub chf_over_mfb: f64,
    /// `flash_void_min`: smallest void fraction of the bubbles on which superheated liquid
    /// flashes.
    pub flash_void_min: f64,
    /// `drop_contact_k`: constant of the Forslund–Rohsenow drop–wall contact coefficient.
    pub drop_contact_k: f64,
    /// Specific gas constant R_g of the fluid, J/(kg K) (Theler's T_chf). Nitrogen unless set
    /// with [`CryoParams::with_fluid`].
    pub gas_constant: f64,
    /// Critical temperature of the fluid, K (Darr–Hartwig rewet temperature). Nitrogen unless
    /// set with [`CryoParams::with_fluid`].
    pub t_critical: f64,
    /// Ideal-gas c_p/R of the fluid's vapour near its normal boiling point (Theler's k_g):
    /// 3.5 for nitrogen and oxygen, about 4 for methane, 2.5 for para-hydrogen (rotation
    /// frozen). Nitrogen's unless set with [`CryoParams::with_ideal_cp_over_r`].
    pub ideal_cp_over_r: f64,
}

impl CryoParams {
    /// Reads every closure constant from `set` (registry defaults for the rest). The fluid
    /// constants are nitrogen's: call [`CryoParams::with_fluid`] for another fluid.
    pub fn from_set(set: &ParameterSet) -> Self {
        let g = |n: &str| set.get(n);
        Self {
            t_onb_scale: g("Tonbsc"),
            nb_exponent: g("nb_exp"),
            q_chf_scale: g("qchfsc"),
            chf_alpha_cr: g("chf_alpha_cr"),
            chf_void_exponent: g("chf_void_exp"),
            chf_g_coeff: g("chf_g_coeff"),
            chf_g_exponent: g("chf_g_exp"),
            chf_griffith_weight: g("chf_griffith"),
            t_chf_scale: g("Tchfsc"),
            fb_scale: g("qmfbsc"),
            fb_x_scale: g("Xmfbsc"),
            fb_x_exponent: g("Xemfbsc"),
            fb_g_scale: g("Gmfbsc"),
            fb_g_exponent: g("Emfbsc"),
            t_mfb_scale: g("Tmfbsc"),
            t_mfb_g_scale: g("Gtmfbsc"),
            t_mfb_g_exponent: g("Etmfbsc"),
            t_mfb_x_exponent: g("Xetmfbsc"),
            t_mfb_x_scale: g("Xtmfbsc"),
            miropolskii_scale: g("hmirosc"),
            dh_we_coeff: g("dh_we_coeff"),
            dh_we_exponent: g("dh_we_exp"),
            gas_wall_scale: g("hg0sc"),
            gas_wall_exponent_scale: g("hg0esc"),
            liquid_wall_scale: g("hl0sc"),
            wall_mass_transfer_scale: g("Gwsc"),
            wetting_time_constant: g("tauw"),
            strat_poly: [g("regime_strat_c0"), g("regime_strat_c1"), g("regime_strat_c2")],
            wavy_poly: [g("regime_wavy_c0"), g("regime_wavy_c1"), g("regime_wavy_c2")],
            kutateladze_k: g("kutateladze_k"),
            x_mist: g("xmin"),
            regime_width: g("regime_width"),
            wall_friction_scale: g("fwsc"),
            chisholm_c: g("chisholm_c"),
            interface_mass_transfer_scale: g("Gisc"),
            gas_interface_scale: g("hgisc"),
            gas_interface_exponent_scale: g("hgi0esc"),
            liquid_interface_exponent_scale: g("hli0esc"),
            drag_stratified_scale: g("idrag_strat_sc"),
            drag_dispersed_scale: g("idrag_disp_sc"),
            drop_diameter_max: g("drop_d_max"),
            virtual_mass: g("vm_coeff"),
            blend_min: g("blend_xmin"),
            blend_max: g("blend_xmax"),
            iloeje_x_floor: g("iloeje_x_floor"),
            boil_gap_chf: g("boil_gap_chf"),
            boil_gap_mfb: g("boil_gap_mfb"),
            chf_over_mfb: g("chf_over_mfb"),
            flash_void_min: g("flash_void_min"),
            drop_contact_k: g("drop_contact_k"),
            gas_constant: NITROGEN_GAS_CONSTANT,
            t_critical: NITROGEN_T_CRITICAL,
            ideal_cp_over_r: DIATOMIC_CP_OVER_R,
        }
    }

    /// The same constants with the fluid's ideal-gas c_p/R (Theler's k_g).
    pub fn with_ideal_cp_over_r(mut self, cp_over_r: f64) -> Self {
        if cp_over_r.is_finite() && cp_over_r > 1.0 {
            self.ideal_cp_over_r = cp_over_r;
        }
        self
    }

    /// The same constants with the fluid's gas constant and critical temperature.
    pub fn with_fluid(mut self, fluid: &FluidConstants) -> Self {
        self.gas_constant = fluid.gas_constant_j_kg_k;
        self.t_critical = fluid.t_critical_k;
        self
    }
}

impl Default for CryoParams {
    /// Registry defaults, nitrogen.
    fn default() -> Self {
        Self::from_set(&ParameterSet::new())
    }
}

// ---------------------------------------------------------------------------------------------
// Small helpers of the local state
// ---------------------------------------------------------------------------------------------

fn void(s: &Local) -> f64 {
    if s.alpha.is_finite() { s.alpha.clamp(0.0, 1.0) } else { 0.0 }
}

fn diameter(s: &Local) -> f64 {
    s.d_h.max(1e-9)
}

/// Gravity of the pool-boiling correlations (floored, see the module docs), m/s².
fn boiling_gravity(s: &Local) -> f64 {
    s.gravity.abs().max(GRAVITY_FLOOR)
}

fn delta_rho(s: &Local) -> f64 {
    (s.rho_l - s.rho_g).max(1e-6 * s.rho_l.max(TINY))
}

/// ρ_l,sat − ρ_g,sat: the density difference of the pool-boiling correlations (buoyancy of
/// saturated vapour in saturated liquid).
fn sat_delta_rho(s: &Local) -> f64 {
    (s.rho_l_sat - s.vap_sat.rho).max(1e-6 * s.rho_l_sat.max(TINY))
}

fn prandtl(mu: f64, cp: f64, k: f64) -> f64 {
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
const CBRT_3PI_2: f64 = 1.676_539_193_219_743_5;

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

// ---------------------------------------------------------------------------------------------
// Convection
// ---------------------------------------------------------------------------------------------

/// Four-regime convective Nusselt number (eq:convection_Nu), the maximum of
/// forced laminar 4.36, forced turbulent 0.023 Re^(0.8 e) Pr^0.4 (Dittus–Boelter, `e` the
/// exponent scale, 1 for the classical value), natural laminar 0.59 (Gr Pr)^¼ and natural
/// turbulent 0.1 (Gr Pr)^⅓ (Holman). The paper swaps the two natural-convection labels; the
/// maximum is the same either way.
pub fn convection_nusselt(re: f64, pr: f64, gr_pr: f64, exponent_scale: f64) -> f64 {
    let forced = dittus_boelter(re.max(0.0), pr.max(0.0), exponent_scale);
    NU_LAMINAR.max(forced).max(natural_nusselt(gr_pr.max(0.0)))
}

/// Rayleigh number above which 0.1 Ra^⅓ exceeds 0.59 Ra^¼: Ra^(1/12) = 5.9.
const RA_NATURAL_TURBULENT: f64 = {
    let r4 = 5.9 * 5.9 * 5.9 * 5.9;
    r4 * r4 * r4
};

/// Natural convection max(0.59 Ra^¼, 0.1 Ra^⅓) for Ra ≥ 0, evaluating only the larger one
/// (they are equal, to round-off, at [`RA_NATURAL_TURBULENT`]).
fn natural_nusselt(ra: f64) -> f64 {
    if ra < RA_NATURAL_TURBULENT { 0.59 * fourth_root(ra) } else { 0.1 * cbrt(ra) }
}

/// Dittus–Boelter with the Reynolds exponent 0.8 scaled by `exponent_scale`.
///
/// Decision: the exponent scales (`hg0esc`, `hgi0esc`, `hli0esc`) are calibration knobs on an
/// empirical exponent. A factor 4 either side (as for every `sc` name) reaches Re^3.2, which at
/// Re = 1e5 is a Nusselt number of 1e14; a cap on the Nusselt number kept that finite but pinned
/// the fitted exponents where it bound, out of sight of the registry. Their registry bounds are
/// narrowed instead, to 0.75–1.25 (Reynolds exponents 0.6–1.0: at Re = 10⁶ a factor 0.03–16 on
/// Dittus–Boelter), and nothing else bounds them.
pub fn scaled_dittus_boelter(re: f64, pr: f64, exponent_scale: f64) -> f64 {
    dittus_boelter(re.max(0.0), pr.max(0.0), exponent_scale)
}

/// [`scaled_dittus_boelter`] for Re, Pr ≥ 0 without powers: unscaled, one logarithm,
/// 0.023 (Re² Pr)^0.4 = 0.023 exp(0.4 ln(Re² Pr)) (where Re² Pr is safely inside the range of
/// doubles), else [`dittus_boelter_ln`].
fn dittus_boelter(re: f64, pr: f64, exponent_scale: f64) -> f64 {
    let x = re * re * pr;
    if exponent_scale == 1.0 && x > 1e-280 && x < 1e280 {
        0.023 * (0.4 * x.ln()).exp()
    } else {
        dittus_boelter_ln(re.ln(), pr.ln(), exponent_scale)
    }
}

/// [`scaled_dittus_boelter`] from ln Re and ln Pr (Re, Pr ≥ 0; ln 0 = −∞ gives 0 as the powers
/// do): 0.023 exp(0.8 e ln Re + 0.4 ln Pr).
fn dittus_boelter_ln(ln_re: f64, ln_pr: f64, exponent_scale: f64) -> f64 {
    let v = 0.023 * (0.8 * exponent_scale * ln_re + 0.4 * ln_pr).exp();
    if v.is_nan() { 0.0 } else { v }
}

/// Single-phase convection of one phase to the wall, the parts that do not depend on the wall
/// temperature evaluated once: h(T_w) = scale · Nu(Re, Pr, Gr(T_w) Pr) · κ/D
/// (eq:convection_Nu), Gr = ρ² g β_T |T_w − T| D³/μ² (true gravity; 0 without it).
struct Convection {
    /// max(4.36, scaled Dittus–Boelter).
    forced: f64,
    /// Prandtl number.
    pr: f64,
    /// ρ² |g| |β_T| of the Grashof number.
    gr_head: f64,
    /// D³.
    d3: f64,
    /// max(μ², 10⁻³⁰).
    mu2: f64,
    /// Temperature of the phase, K.
    t: f64,
    /// The coefficient scale (`hl0sc` or `hg0sc`).
    scale: f64,
    /// max(κ, 0).
    k: f64,
    /// D.
    d: f64,
}

impl Convection {
    #[allow(clippy::too_many_arguments)]
    fn new(
        s: &Local,
        rho: f64,
        v: f64,
        mu: f64,
        cp: f64,
        k: f64,
        beta: f64,
        t: f64,
        scale: f64,
        exponent_scale: f64,
    ) -> Self {
        let d = diameter(s);
        let re = rho * v.abs() * d / mu.max(TINY);
        let pr = prandtl(mu, cp, k);
        let forced = NU_LAMINAR.max(dittus_boelter(re.max(0.0), pr, exponent_scale));
        Convection {
            forced,
            pr,
            gr_head: rho * rho * s.gravity.abs() * beta.abs(),
            d3: d.powi(3),
            mu2: (mu * mu).max(TINY),
            t,
            scale,
            k: k.max(0.0),
            d,
        }
    }

    /// The liquid's, scaled by `hl0sc`.
    fn liquid(s: &Local, p: &CryoParams) -> Self {
        Self::new(s, s.rho_l, s.v_l, s.mu_l, s.cp_l, s.k_l, s.beta_l, s.t_l, p.liquid_wall_scale, 1.0)
    }

    /// The gas's, scaled by `hg0sc`, Reynolds exponent scaled by `hg0esc`.
    fn gas(s: &Local, p: &CryoParams) -> Self {
        Self::new(
            s,
            s.rho_g,
            s.v_g,
            s.mu_g,
            s.cp_g,
            s.k_g,
            s.beta_g,
            s.t_g,
            p.gas_wall_scale,
            p.gas_wall_exponent_scale,
        )
    }

    /// Coefficient to a wall at `t_w`, W/(m² K).
    fn htc(&self, t_w: f64) -> f64 {
        let gr = self.gr_head * (t_w - self.t).abs() * self.d3 / self.mu2;
        let gr = if gr.is_finite() { gr } else { 0.0 };
        let nu = self.forced.max(natural_nusselt((gr * self.pr).max(0.0)));
        self.scale * nu * self.k / self.d
    }
}

/// Single-phase liquid convection coefficient to a wall at `t_w`, W/(m² K): h_cb of
/// eq:convection_Nu with the liquid's Re = ρ_l |v_l| D/μ_l, Pr and Gr, times `hl0sc`.
pub fn liquid_convection_htc(s: &Local, p: &CryoParams, t_w: f64) -> f64 {
    Convection::liquid(s, p).htc(t_w)
}

/// Gas convection coefficient to the dry wall at `t_w`, W/(m² K): eq:convection_Nu for the gas
/// ("with appropriately modified parameters"): the Dittus–Boelter exponent 0.8 scaled by
/// `hg0esc`, the whole coefficient by `hg0sc`. Used on the dry perimeter in every regime,
/// i.e. also after dryout.
pub fn gas_convection_htc(s: &Local, p: &CryoParams, t_w: f64) -> f64 {
    Convection::gas(s, p).htc(t_w)
}

/// Rise of the adiabatic-wall (recovery) temperature of the gas above its static temperature, K:
/// T_aw − T_g = r v_g²/(2 c_p,g), with the turbulent recovery factor r = Pr_g^(1/3) (about 0.9
/// for nitrogen vapour); the gas convects heat to the wall as h (T_w − T_aw).
///
/// Not in the paper. Decision: the vapour that leaves a chilling line runs at 100–200 m/s near
/// the discharge (Mach 0.3–0.5), where its static temperature lies v²/(2 c_p) ≈ 5–15 K below its
/// total temperature. Driving the wall heat flux by the static temperature cools the far,
/// still-dry end of the line at several hundred W/m² by the gas's own kinetic energy — the
/// steady pre-cooling of TS3/TS4 that the NBS traces do not show (their wall stays at its
/// initial temperature until the front is near). A convective boundary layer sees the recovery
/// temperature, which makes the fast dry flow nearly adiabatic to the wall, as it is.
pub fn recovery_temperature_rise(s: &Local) -> f64 {
    let cp = s.cp_g.max(TINY);
    let rise = cbrt(prandtl(s.mu_g, cp, s.k_g)) * s.v_g * s.v_g / (2.0 * cp);
    if rise.is_finite() { rise } else { 0.0 }
}

// ---------------------------------------------------------------------------------------------
// Boiling-curve anchors
// ---------------------------------------------------------------------------------------------

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
struct BoilingCurve<'a> {
    s: &'a Local,
    p: &'a CryoParams,
    liquid: Convection,
    film: FilmBoiling,
    anchors: Anchors,
}

impl<'a> BoilingCurve<'a> {
    fn new(s: &'a Local, p: &'a CryoParams, set: CorrelationSet) -> Self {
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
    fn at(&self, t_w: f64) -> (f64, u8) {
        let (s, a) = (self.s, &self.anchors);
        if t_w <= a.t_onb {
            (self.liquid.htc(t_w) * (t_w - s.t_l), REGIME_CONVECTION)
        } else if t_w <= a.t_chf {
            // eq:q_nb_int, in the orientation that gives q_onb at T_onb and q_chf at T_chf
            let y = ((t_w - a.t_onb) / (a.t_chf - a.t_onb)).clamp(0.0, 1.0);
            (a.q_onb + (a.q_chf - a.q_onb) * pow_param(y, self.p.nb_exponent), REGIME_NUCLEATE)
        } else if t_w <= a.t_mfb {
            // eq:transition_boiling as printed (TRACE): f_tb = 1 at T_chf, 0 at T_mfb
            let f = ((t_w - a.t_mfb) / (a.t_chf - a.t_mfb)).clamp(0.0, 1.0).powi(2);
            (f * a.q_chf + (1.0 - f) * a.q_mfb, REGIME_TRANSITION)
        } else {
            (self.film.htc(s, self.p, &s.vap_film, t_w) * (t_w - s.t_sat), REGIME_FILM)
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

// ---------------------------------------------------------------------------------------------
// Flow regimes and wetting
// ---------------------------------------------------------------------------------------------

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
    let g_strat = poly2(&p.strat_poly, chi).max(G_BOUNDARY_MIN);
    let g_wavy = poly2(&p.wavy_poly, chi).max(WAVY_OVER_STRAT_MIN * g_strat);
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

/// ln 4.25 (checked by a test).
const LN_4_25: f64 = 1.446_918_982_936_325_4;
/// ln 10⁻³, the logarithm of [`Q_TILDE_MIN`] (checked by a test).
const LN_Q_TILDE_MIN: f64 = -6.907_755_278_982_137;

/// The quality term ln(0.58/χ) + 0.52 of the dryout boundary (no dryout where it is ≤ 0).
fn dryout_quality_term(chi: f64) -> f64 {
    (0.58 / chi.max(TINY)).ln() + 0.52
}

/// ln ṁ_dry of [`dryout_mass_flux`], or `None` where that is 0 (χ ≥ 0.976, or a boundary that
/// is not a positive finite number).
fn ln_dryout_mass_flux(s: &Local, p: &CryoParams, chi: f64, q_wall: f64) -> Option<f64> {
    let quality_term = dryout_quality_term(chi);
    if quality_term <= 0.0 {
        return None;
    }
    let ln_m = ln_dryout_with(s, p, quality_term, q_wall);
    // exp(ln_m) positive and finite (the form with powers gives 0 outside)
    (ln_m > -745.0 && ln_m < 709.0).then_some(ln_m)
}

/// ln ṁ_dry at a positive `quality_term`, as a sum of logarithms (no powers):
/// 0.93 [ln 4.25 + 0.17 ln(ρ_g σ/D) + 0.37 ln(g D ρ_g Δρ) + ln((ρ_l/ρ_g)^¼ (ln(0.58/χ) + 0.52))
/// − 0.7 ln q̃].
fn ln_dryout_with(s: &Local, p: &CryoParams, quality_term: f64, q_wall: f64) -> f64 {
    let d = diameter(s);
    let rho_g = s.vap_sat.rho.max(TINY);
    let q_t = (q_wall.max(0.0) / kutateladze_q_dnb(s, p).max(TINY)).max(Q_TILDE_MIN);
    let ln_q_t = if q_t == Q_TILDE_MIN { LN_Q_TILDE_MIN } else { q_t.ln() };
    0.93 * (LN_4_25
        + 0.17 * (rho_g * s.sigma.max(0.0) / d).ln()
        + 0.37 * (boiling_gravity(s) * d * rho_g * sat_delta_rho(s)).ln()
        + (fourth_root(s.rho_l_sat.max(0.0) / rho_g) * quality_term).ln()
        - 0.7 * ln_q_t)
}

/// Flow regime weights at the state `s` with wall heat flux `q_wall` (W/m², for the dryout
/// boundary; the previous step's is fine).
///
/// With G the total mass flux and χ the [`regime_quality`]:
/// s_strat = S(½ + ln(G/G_strat)/w), s_wavy = S(½ + ln(G/G_wavy)/w),
/// s_dry = S(½ + ln(G/ṁ_dry)/w) (S the smooth step, w = `regime_width`, ṁ_dry from
/// [`dryout_mass_flux`]), mist = S(½ + (χ − xmin)/0.05), dry = 1 − (1 − s_dry)(1 − mist);
/// stratified = (1 − dry)(1 − s_strat), wavy = (1 − dry) s_strat (1 − s_wavy),
/// annular = (1 − dry) s_strat s_wavy, dryout = dry.
pub fn flow_regime(s: &Local, p: &CryoParams, q_wall: f64) -> Regime {
    let (gg, gl) = mass_fluxes(s);
    let chi = regime_quality(s);
    let mist = smooth_step(0.5 + (chi - p.x_mist) / QUALITY_WIDTH);
    if mist == 1.0 {
        // dryout = 1 − (1 − dry)·0 = 1 whatever the dryout boundary
        return Regime { stratified: 0.0, wavy: 0.0, annular: 0.0, dryout: 1.0 };
    }
    let ln_g = (gg + gl).max(1e-9).ln();
    let w = p.regime_width.max(1e-6);
    let dry_hf = match ln_dryout_mass_flux(s, p, chi, q_wall) {
        Some(ln_m) => smooth_step(0.5 + (ln_g - ln_m) / w),
        None => 1.0,
    };
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
    let beta = 1.0 - void(s);
    let w_strat = stratified_half_angle(beta) / PI;
    let w_wavy = 1.0 - 0.5f64.powf(0.61) * (1.0 - w_strat);
    let w = regime.stratified * w_strat + regime.wavy * w_wavy + regime.annular;
    w.clamp(0.0, 1.0)
}

// ---------------------------------------------------------------------------------------------
// Wall heat transfer
// ---------------------------------------------------------------------------------------------

/// Wall heat transfer at the old state: coefficients such that the heat flux from wall to gas is
/// h_wg (T_w − T_g) and to liquid h_wl (T_w − T_l), per unit of the WHOLE inner wall area (the
/// split of the perimeter between liquid-wetted and dry is already inside them, using `wetted`),
/// and the fraction of the liquid-side heat that generates vapour at the wall (0 in
/// single-phase convection, rising to 1 from onset of nucleate boiling on, smoothly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallHeat {
    /// Wall → gas coefficient, W/(m² K) of the whole wall: (1 − wetted) h_gas.
    pub h_wg: f64,
    /// Wall → liquid coefficient, W/(m² K) of the whole wall: wetted q(T_w)/(T_w − T_l).
    pub h_wl: f64,
    /// Fraction of the wall → liquid heat that evaporates liquid at the wall (Γ_wg).
    pub boiling_fraction: f64,
    /// Critical heat flux, W/m².
    pub q_chf: f64,
    /// Wall temperature of the critical heat flux, K.
    pub t_chf: f64,
    /// Minimum film boiling (or rewet) temperature, K.
    pub t_mfb: f64,
    /// Onset of nucleate boiling, K.
    pub t_onb: f64,
    /// Branch: [`REGIME_CONVECTION`], [`REGIME_NUCLEATE`], [`REGIME_TRANSITION`],
    /// [`REGIME_FILM`] or [`REGIME_DRY`].
    pub regime_code: u8,
}

/// Wall heat transfer at `s.t_w` with liquid-covered perimeter fraction `wetted`.
///
/// h_wl = wetted q(T_w)/(T_w − T_l) with q the [`boiling_curve`] (in the convective branch,
/// wetted h_cb(T_w), no division); h_wg = (1 − wetted) [`gas_convection_htc`]. The boiling
/// fraction is the smooth step of (T_w − T_s)/(T_onb − T_s): 0 with the wall at or below
/// saturation, 1 from T_onb on (nucleate, transition and film boiling all evaporate liquid).
pub fn wall_heat(s: &Local, p: &CryoParams, set: CorrelationSet, wetted: f64, regime: &Regime) -> WallHeat {
    let w = if wetted.is_finite() { wetted.clamp(0.0, 1.0) } else { 0.0 };
    // drops of a dispersed flow that reach the dry part of the wall
    let h_drops = if s.t_w > s.t_l { (1.0 - w) * regime.dryout * drop_contact_htc(s, p) } else { 0.0 };
    let curve = BoilingCurve::new(s, p, set);
    let a = curve.anchors;
    let (h_liquid, branch) = if s.t_w <= a.t_onb {
        (curve.liquid.htc(s.t_w), REGIME_CONVECTION)
    } else {
        // T_w > T_onb ≥ T_l + 0.1 K here
        let (q, branch) = curve.at(s.t_w);
        (q / (s.t_w - s.t_l), branch)
    };
    let boiling_fraction = smooth_step((s.t_w - s.t_sat) / (a.t_onb - s.t_sat).max(1e-6));
    WallHeat {
        h_wg: (1.0 - w) * gas_convection_htc(s, p, s.t_w),
        h_wl: w * h_liquid + h_drops,
        boiling_fraction,
        q_chf: a.q_chf,
        t_chf: a.t_chf,
        t_mfb: a.t_mfb,
        t_onb: a.t_onb,
        regime_code: if w < 1e-3 { REGIME_DRY } else { branch },
    }
}

/// Drop–wall contact heat transfer of dispersed-flow film boiling, W/(m² K) of wall, for the
/// flux h (T_w − T_sat) that the drops of a mist take from the dry wall and evaporate with:
/// Forslund and Rohsenow's coefficient as RELAP5 and TRACE use it above the critical heat flux,
/// h = K (1 − α)^(2/3) [g ρ_l,sat ρ_g h_lg κ_g³ / ((T_w − T_sat) μ_g d_d)]^(1/4), with K
/// `drop_contact_k` (0.2552 in the source form), the vapour properties at the film temperature
/// ([`Local::vap_film`]), d_d the drop diameter of the interface closure and g at least the
/// boiling correlations' floor. The scheme applies it on the dry share of the perimeter in the
/// dryout/mist regime; its heat goes to the liquid, which it evaporates. Decision: the heat is
/// driven by T_w − T_l, the liquid-side difference of the scheme's linearisation, rather than
/// the source's T_w − T_sat: the drops of a mist are at saturation to within a kelvin, and the
/// ratio (T_w − T_sat)/(T_w − T_l) that converts one into the other grows without bound where
/// a superheated liquid meets a wall at its own temperature (a 10-cell subcooled run failed on
/// it with a pressure of −10¹⁴ Pa).
pub fn drop_contact_htc(s: &Local, p: &CryoParams) -> f64 {
    let dt_w = s.t_w - s.t_sat;
    let beta = 1.0 - void(s);
    if !(dt_w > 0.0 && beta > 0.0 && s.h_lg > 0.0 && p.drop_contact_k > 0.0) {
        return 0.0;
    }
    let v = &s.vap_film;
    let d_d = particle_diameter(s.sigma, s.rho_g, relative_speed(s), diameter(s), p.drop_diameter_max);
    let group = boiling_gravity(s) * s.rho_l_sat * v.rho * s.h_lg * v.k.powi(3) / (dt_w * v.mu * d_d).max(TINY);
    let h = p.drop_contact_k * beta.powf(2.0 / 3.0) * group.max(0.0).powf(0.25);
    if h.is_finite() { h } else { 0.0 }
}

// ---------------------------------------------------------------------------------------------
// Interphase heat transfer
// ---------------------------------------------------------------------------------------------

/// Interphase heat transfer, volumetric coefficients W/(m³ K) for q_ig = H_ig (T_sat − T_g) and
/// q_il = H_il (T_sat − T_l).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interphase {
    /// Gas side, W/(m³ K).
    pub h_ig: f64,
    /// Liquid side, W/(m³ K).
    pub h_il: f64,
}

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
fn particle_diameter(sigma: f64, rho_continuous: f64, v_r: f64, d: f64, d_max: f64) -> f64 {
    (WE_CRIT * sigma.max(0.0) / (rho_continuous * v_r * v_r).max(TINY))
        .clamp(D_PARTICLE_MIN, (0.5 * d).min(d_max).max(D_PARTICLE_MIN))
}

/// Relative velocity, regularised: √((v_g − v_l)² + V_REG²).
fn relative_speed(s: &Local) -> f64 {
    let dv = s.v_g - s.v_l;
    (dv * dv + V_REG * V_REG).sqrt()
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

// ---------------------------------------------------------------------------------------------
// Momentum closures
// ---------------------------------------------------------------------------------------------

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
    let d = diameter(s);
    let a_g = void(s);
    let a_l = 1.0 - a_g;
    let w_l = wetted_fraction(s, regime);
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

/// Bubble diameter of intermittent flow: twice the capillary length √(σ/(g Δρ)), clamped to
/// [10 µm, D/2], m.
fn bubble_diameter(s: &Local) -> f64 {
    let lc = (s.sigma.max(0.0) / (boiling_gravity(s) * delta_rho(s))).sqrt();
    (2.0 * lc).clamp(D_PARTICLE_MIN, (0.5 * diameter(s)).max(D_PARTICLE_MIN))
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
/// * dryout/mist: drops ¾ C_D ρ_g v_r (1 − α)/d_d, d_d = 12 σ/(ρ_g v_r²) ≤ `drop_d_max`, C_D Schiller–Naumann.
///
/// Stratified and wavy are scaled by `idrag_strat_sc`, the rest by `idrag_disp_sc`. All tend to
/// their laminar/Stokes values as v_r → 0.
pub fn interfacial_drag(s: &Local, p: &CryoParams, regime: &Regime) -> f64 {
    let d = diameter(s);
    let a = void(s);
    let beta = 1.0 - a;
    let v_r = relative_speed(s);
    let re_r = (s.rho_g * v_r * d / s.mu_g.max(TINY)).max(1e-3);
    let f_smooth = churchill_darcy(re_r, 0.0) / 4.0;
    let a_strat = 4.0 * stratified_half_angle(beta).sin() / (PI * d);
    let f_strat = 0.5 * f_smooth * s.rho_g * v_r * a_strat;
    let f_wavy = 0.5 * f_smooth.max(WAVY_FRICTION) * s.rho_g * v_r * a_strat;

    let f_wallis = (0.005 * (1.0 + 75.0 * beta)).max(f_smooth);
    let f_film = 0.5 * f_wallis * s.rho_g * v_r * 4.0 * a.sqrt() / d;
    let d_b = bubble_diameter(s);
    let re_b = s.rho_l * v_r * d_b / s.mu_l.max(TINY);
    let bubbly = 1.0 - smooth_step((a - BUBBLY_VOID.0) / (BUBBLY_VOID.1 - BUBBLY_VOID.0));
    let f_bubble = bubbly * 0.75 * sphere_cd(re_b) * s.rho_l * v_r * a * beta / d_b;

    let d_d = particle_diameter(s.sigma, s.rho_g, v_r, d, p.drop_diameter_max);
    let re_d = s.rho_g * v_r * d_d / s.mu_g.max(TINY);
    let f_drop = 0.75 * sphere_cd(re_d) * s.rho_g * v_r * beta / d_d;

    let f = p.drag_stratified_scale * (regime.stratified * f_strat + regime.wavy * f_wavy)
        + p.drag_dispersed_scale * (regime.annular * (f_film + f_bubble) + regime.dryout * f_drop);
    if f.is_finite() { f.max(0.0) } else { 0.0 }
}

/// Virtual-mass coefficient C (dimensionless) of C α (1 − α) ρ_m ∂(v_g − v_l)/∂t: the registry
/// parameter `vm_coeff` (RELAP5 uses 0.5 for dispersed flow; the paper keeps only the time
/// derivative).
pub fn virtual_mass_coefficient(_s: &Local, p: &CryoParams) -> f64 {
    p.virtual_mass
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regime without dryout (no drop contact): the wall-heat tests of the wetted wall.
    const WET: Regime = Regime { stratified: 0.0, wavy: 0.0, annular: 1.0, dryout: 0.0 };

    #[test]
    fn cbrt_constant_is_exact() {
        assert!((CBRT_3PI_2 - (1.5 * PI).cbrt()).abs() < 1e-15);
    }
    use crate::params::{REGISTRY, spec};

    const T_SAT: f64 = 77.355;
    const H_L_SAT: f64 = -122_000.0;
    const H_LG: f64 = 199_176.0;
    const D: f64 = 0.015875;
    const G0: f64 = 9.80665;

    /// Liquid nitrogen at 1 atm (the brief's property values), saturated phases.
    fn ln2(alpha: f64, t_w: f64, v_g: f64, v_l: f64) -> Local {
        Local {
            p: 101_325.0,
            t_w,
            t_g: T_SAT,
            t_l: T_SAT,
            t_sat: T_SAT,
            alpha,
            rho_g: 4.612,
            rho_l: 806.08,
            mu_g: 5.44e-6,
            mu_l: 1.607e-4,
            k_g: 7.19e-3,
            k_l: 0.1448,
            cp_g: 1124.0,
            cp_l: 2041.0,
            h_lg: H_LG,
            sigma: 8.88e-3,
            h_l: H_L_SAT,
            h_g: H_L_SAT + H_LG,
            h_l_sat: H_L_SAT,
            h_g_sat: H_L_SAT + H_LG,
            v_g,
            v_l,
            d_h: D,
            gravity: G0,
            beta_g: 1.0 / T_SAT,
            beta_l: 5.7e-3,
            ..Local::default()
        }
        .with_cell_vapour_basis()
    }

    /// Pr = 5.44e-6 · 1124 / 7.19e-3 = 0.85043, r = Pr^(1/3) = 0.94743; at 100 m/s the rise is
    /// 0.94743 · 100² / (2 · 1124) = 4.2145 K; at rest it is zero, and it is even in v_g.
    #[test]
    fn recovery_temperature_at_a_hand_checked_point() {
        let rise = recovery_temperature_rise(&ln2(0.99, 290.0, 100.0, 0.0));
        assert!((rise - 4.2145).abs() < 1e-3, "{rise}");
        assert_eq!(recovery_temperature_rise(&ln2(0.99, 290.0, 0.0, 0.0)), 0.0);
        assert_eq!(recovery_temperature_rise(&ln2(0.99, 290.0, -100.0, 0.0)), rise);
    }

    fn defaults() -> CryoParams {
        CryoParams::default()
    }

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(1e-300)
    }

    /// A small deterministic generator (xorshift64*).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }
        /// Uniform in [a, b].
        fn in_range(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * self.unit()
        }
        /// Log-uniform in [a, b], a > 0.
        fn log_range(&mut self, a: f64, b: f64) -> f64 {
            a * (b / a).powf(self.unit())
        }
        fn pick(&mut self, xs: &[f64]) -> f64 {
            xs[(self.next() % xs.len() as u64) as usize]
        }
    }

    /// A random state: nitrogen-like properties scaled by up to a factor 3 either way (hot or
    /// superheated gas, subcooled or superheated liquid), every void fraction (pure phases
    /// included), velocities of either sign from rest to 30 m/s, gravity on or off.
    fn random_state(r: &mut Rng) -> Local {
        let alpha = match r.next() % 6 {
            0 => 0.0,
            1 => 1.0,
            2 => r.log_range(1e-9, 1e-2),
            3 => 1.0 - r.log_range(1e-9, 1e-2),
            _ => r.unit(),
        };
        let v = |r: &mut Rng| {
            let sign = if r.next().is_multiple_of(4) { -1.0 } else { 1.0 };
            match r.next() % 5 {
                0 => 0.0,
                _ => sign * r.log_range(1e-5, 30.0),
            }
        };
        let f = |r: &mut Rng| r.log_range(1.0 / 3.0, 3.0);
        let mut s = ln2(alpha, r.in_range(60.0, 500.0), v(r), v(r));
        s.t_sat = T_SAT * r.in_range(0.9, 1.25);
        s.t_l = s.t_sat + r.in_range(-20.0, 2.0);
        s.t_g = s.t_sat + {
            let v = r.in_range(0.0, 200.0);
            r.pick(&[0.0, v])
        };
        if r.next().is_multiple_of(3) {
            s.t_w = s.t_sat + r.in_range(-3.0, 40.0);
        }
        s.rho_g *= f(r);
        s.rho_l *= r.in_range(0.8, 1.1);
        s.mu_g *= f(r);
        s.mu_l *= f(r);
        s.k_g *= f(r);
        s.k_l *= f(r);
        s.cp_g *= f(r);
        s.cp_l *= f(r);
        s.h_lg *= r.in_range(0.5, 1.1);
        s.sigma *= f(r);
        s.h_g_sat = s.h_l_sat + s.h_lg;
        s.h_l = s.h_l_sat + s.cp_l * (s.t_l - s.t_sat);
        s.h_g = s.h_g_sat + s.cp_g * (s.t_g - s.t_sat);
        s.d_h = r.pick(&[D, 0.005, 0.05]);
        s.gravity = r.pick(&[G0, G0, 0.0]);
        s.beta_g = 1.0 / s.t_g;
        s.with_cell_vapour_basis()
    }

    /// Registry defaults, or every parameter uniform within its bounds.
    fn random_params(r: &mut Rng) -> CryoParams {
        if r.next().is_multiple_of(3) {
            return defaults();
        }
        let mut set = ParameterSet::new();
        for name in PARAMETER_NAMES {
            let sp = spec(name).unwrap();
            set.set(name, r.in_range(sp.lower, sp.upper)).unwrap();
        }
        CryoParams::from_set(&set)
    }

    /// No closure bounds a parameter-scaled quantity except through the registry: at random
    /// states and parameter sets, a 1 % change of a scale moves the quantity it scales unless a
    /// registry bound (or the regime maximum of eq:convection_Nu) is the active branch there.
    #[test]
    fn no_hidden_bound_pins_a_parameter() {
        let mut r = Rng(7);
        let bump = |p: &CryoParams, f: &dyn Fn(&mut CryoParams)| {
            let mut q = *p;
            f(&mut q);
            q
        };
        let (mut checked, mut bound) = (0usize, 0usize);
        for _ in 0..20_000 {
            let s = random_state(&mut r);
            if s.h_lg <= 0.0 {
                continue;
            }
            let p = random_params(&mut r);
            let set = CorrelationSet::Paper;
            let a = boiling_anchors(&s, &p, set);
            // Tchfsc moves T_chf unless boil_gap_chf holds it
            let q = bump(&p, &|q| q.t_chf_scale *= 1.01);
            let b = boiling_anchors(&s, &q, set);
            let held = (a.t_chf - (a.t_onb + p.boil_gap_chf)).abs() < 1e-9 * a.t_chf
                || (b.t_chf - (b.t_onb + q.boil_gap_chf)).abs() < 1e-9 * b.t_chf;
            if held {
                bound += 1;
            } else {
                assert!(b.t_chf != a.t_chf, "Tchfsc pinned at {s:?}");
                checked += 1;
            }
            // Tmfbsc moves T_mfb unless boil_gap_mfb holds it
            let q = bump(&p, &|q| q.t_mfb_scale *= 1.01);
            let b = boiling_anchors(&s, &q, set);
            let held = (a.t_mfb - (a.t_chf + p.boil_gap_mfb)).abs() < 1e-9 * a.t_mfb
                || (b.t_mfb - (b.t_chf + q.boil_gap_mfb)).abs() < 1e-9 * b.t_mfb;
            if !held {
                assert!(b.t_mfb != a.t_mfb, "Tmfbsc pinned at {s:?}");
            }
            // qchfsc moves q_chf unless chf_over_mfb holds it (or there is no CHF margin left)
            let q = bump(&p, &|q| q.q_chf_scale *= 1.01);
            let b = boiling_anchors(&s, &q, set);
            let floor = |p: &CryoParams, x: &Anchors| p.chf_over_mfb * x.q_onb.max(x.q_mfb);
            let held = (a.q_chf - floor(&p, &a)).abs() <= 1e-12 * a.q_chf
                || (b.q_chf - floor(&q, &b)).abs() <= 1e-12 * b.q_chf
                || critical_heat_flux(&s, &p) == 0.0;
            if !held {
                assert!(b.q_chf != a.q_chf, "qchfsc pinned at {s:?}");
            }
            // Xmfbsc moves film boiling unless the Iloeje floor holds it (or X = 0)
            let x = regime_quality(&s);
            let q = bump(&p, &|q| q.fb_x_scale *= 1.01);
            let factor = |p: &CryoParams| 1.0 - p.fb_x_scale * pow_param(x, p.fb_x_exponent);
            // (where X^c3 is resolvable next to 1)
            let resolvable = (factor(&p) - factor(&q)).abs() > 1e-12;
            if resolvable && factor(&p) > p.iloeje_x_floor && factor(&q) > q.iloeje_x_floor {
                assert!(
                    film_boiling_htc(&s, &q, set, s.t_w.max(s.t_sat + 5.0))
                        != film_boiling_htc(&s, &p, set, s.t_w.max(s.t_sat + 5.0)),
                    "Xmfbsc pinned at {s:?}"
                );
            }
            // the exponent scale moves the gas's forced convection wherever forced convection is
            // the largest of eq:convection_Nu's four branches (no cap on the Nusselt number)
            let q = bump(&p, &|q| q.gas_wall_exponent_scale *= 1.01);
            let re = s.rho_g * s.v_g.abs() * diameter(&s) / s.mu_g;
            let pr = prandtl(s.mu_g, s.cp_g, s.k_g);
            let forced = |p: &CryoParams| scaled_dittus_boelter(re, pr, p.gas_wall_exponent_scale);
            if re > 10.0 && forced(&p).min(forced(&q)) > NU_LAMINAR * 1.01 && s.gravity == 0.0 {
                assert!(
                    gas_convection_htc(&s, &q, s.t_w) != gas_convection_htc(&s, &p, s.t_w),
                    "hg0esc pinned at Re {re}"
                );
            }
        }
        assert!(checked > 1000 && bound > 0, "{checked} free, {bound} held by boil_gap_chf");
    }

    #[test]
    fn logarithm_constants_are_exact() {
        assert_eq!(LN_4_25, 4.25f64.ln());
        assert_eq!(LN_Q_TILDE_MIN, Q_TILDE_MIN.ln());
        let r4: f64 = 5.9 * 5.9 * 5.9 * 5.9;
        assert_eq!(RA_NATURAL_TURBULENT, r4 * r4 * r4);
        assert!(rel(0.59 * RA_NATURAL_TURBULENT.powf(0.25), 0.1 * RA_NATURAL_TURBULENT.cbrt()) < 1e-14);
    }

    // ---------------------------------------------------------------- hand-checked points

    #[test]
    fn zuber_hand_check() {
        let s = ln2(0.3, 100.0, 0.0, 0.0);
        let drho: f64 = 806.08 - 4.612;
        let expected = PI / 24.0
            * 199_176.0
            * 4.612f64.sqrt()
            * (8.88e-3 * G0 * drho).powf(0.25)
            * ((806.08 + 4.612) / 806.08f64).sqrt();
        assert!(rel(zuber_chf(&s), expected) < 1e-12);
        assert!((zuber_chf(&s) - 1.62e5).abs() < 0.02e5, "{}", zuber_chf(&s));
    }

    #[test]
    fn simplified_and_griffith_chf_hand_check() {
        let mut p = defaults();
        let s = ln2(0.3, 100.0, 2.0, 0.2);
        let g: f64 = 0.3 * 4.612 * 2.0 + 0.7 * 806.08 * 0.2;
        let q0 = zuber_chf(&s);
        let expected = q0 * 1.0 * (0.96f64 - 0.3).powf(2.0) * (1.0 + 0.16 * g.powf(0.2));
        assert!(rel(critical_heat_flux(&s, &p), expected) < 1e-12);
        // Griffith-type with subcooled liquid
        let mut s = s;
        s.t_l = 72.0;
        p.chf_griffith_weight = 1.0;
        let ja = 806.08 * 2041.0 * (T_SAT - 72.0) / (4.612 * 199_176.0);
        let re_l = 806.08 * 0.2 * D / 1.607e-4;
        let expected = q0 * (0.96 - 0.3) * (1.0 + 0.0144 * ja + 1e-6 * re_l + 0.5e-3 * (re_l * ja).sqrt());
        assert!(rel(critical_heat_flux(&s, &p), expected) < 1e-12);
        // α above α_cr: clamped to zero, no NaN
        let s = ln2(0.99, 100.0, 2.0, 0.2);
        assert_eq!(critical_heat_flux(&s, &defaults()), 0.0);
    }

    #[test]
    fn theler_hand_check() {
        let s = ln2(0.3, 100.0, 0.0, 0.0);
        let u = T_SAT * 296.8 / 199_176.0 * 8.0f64.ln();
        let expected = T_SAT / (1.0 - u);
        let t = theler_t_chf(&s, &defaults());
        assert!(rel(t, expected) < 1e-12, "{t} {expected}");
        assert!((t - 101.7).abs() < 0.1, "{t}");
        let mut p = defaults();
        p.t_chf_scale = 1.5;
        assert!(rel(theler_t_chf(&s, &p) - T_SAT, 1.5 * (expected - T_SAT)) < 1e-12);
    }

    #[test]
    fn berenson_and_iloeje_hand_check() {
        let s = ln2(0.3, 100.0, 1.0, 0.1);
        let drho: f64 = 806.08 - 4.612;
        let gd = G0 * drho;
        let expected = 0.127 * 4.612 * 199_176.0 / 7.19e-3
            * (gd / (806.08 + 4.612)).powf(2.0 / 3.0)
            * (8.88e-3 / gd).powf(0.5)
            * (5.44e-6 / gd).powf(1.0 / 3.0);
        let dt0 = berenson_dt_mfb(&s);
        assert!(rel(dt0, expected) < 1e-12);
        assert!((dt0 - 69.4).abs() < 0.5, "{dt0}");
        // Iloeje with Table 1 at the flow quality (G_g + x_s)/(G + 1), G in kg/(m² s)
        let gg: f64 = 0.3 * 4.612 * 1.0;
        let gl: f64 = 0.7 * 806.08 * 0.1;
        let x_s = 0.3 * 4.612 / (0.3 * 4.612 + 0.7 * 806.08);
        let x = (gg + x_s) / (gg + gl + 1.0);
        let expected = 1.25 * dt0 * (1.0 - 1.04 * x * x) * (1.0 + 0.2 * gl.powf(0.165));
        assert!(rel(iloeje_dt_mfb(&s, &defaults()), expected) < 1e-9);
    }

    #[test]
    fn bromley_and_film_boiling_hand_check() {
        let s = ln2(0.3, 200.0, 1.0, 0.1);
        let dt = 200.0 - T_SAT;
        let h_mod = 199_176.0 + 0.4 * 1124.0 * dt;
        let pr: f64 = 5.44e-6 * 1124.0 / 7.19e-3;
        let expected =
            0.62 * (G0 * 4.612 * 7.19e-3f64.powi(2) * (806.08 - 4.612) * h_mod * 1124.0 / (D * dt * pr)).powf(0.25);
        let h_br = bromley_htc(&s, 200.0);
        assert!(rel(h_br, expected) < 1e-12);
        assert!(h_br > 50.0 && h_br < 300.0, "{h_br}");
        let gg: f64 = 0.3 * 4.612 * 1.0;
        let gl: f64 = 0.7 * 806.08 * 0.1;
        let x_s = 0.3 * 4.612 / (0.3 * 4.612 + 0.7 * 806.08);
        let x = (gg + x_s) / (gg + gl + 1.0);
        let expected = 2.0 * h_br * (1.0 - 1.04 * x * x) * (1.0 + 0.2 * gl.powf(0.1));
        assert!(rel(film_boiling_htc(&s, &defaults(), CorrelationSet::Paper, 200.0), expected) < 1e-9);
    }

    #[test]
    fn miropolskii_and_darr_hartwig_hand_check() {
        let p = defaults();
        // a superheated-gas state with liquid: X_e from enthalpies
        let mut s = ln2(0.8, 200.0, 3.0, 0.3);
        s.h_g = H_L_SAT + H_LG + 1124.0 * 20.0;
        let mg: f64 = 0.8 * 4.612;
        let ml: f64 = 0.2 * 806.08;
        let xe = ((mg * s.h_g + ml * s.h_l) / (mg + ml) - H_L_SAT) / H_LG;
        assert!(rel(equilibrium_quality(&s), xe) < 1e-12);
        let g = mg * 3.0 + ml * 0.3;
        // the flow quality (G_g + x_s)/(G + 1), G in kg/(m² s)
        let x = (mg * 3.0 + mg / (mg + ml)) / (g + 1.0);
        let ratio: f64 = 4.612 / 806.08;
        let re = g * D / 5.44e-6 * (x + ratio * (1.0 - x));
        let pr: f64 = 5.44e-6 * 1124.0 / 7.19e-3;
        let y = 1.0 - 0.1 * (1.0 / ratio - 1.0).powf(0.4) * (1.0 - x).powf(0.4);
        let expected = 0.023 * re.powf(0.8) * pr.powf(0.8) * y * 7.19e-3 / D;
        assert!(rel(miropolskii_htc(&s, &p), expected) < 1e-12);
        // Darr–Hartwig: G = 100 kg/(m² s) of liquid alone
        let s = ln2(0.0, 200.0, 0.0, 100.0 / 806.08);
        let we = 100.0f64.powi(2) * D / (806.08 * 8.88e-3);
        let expected = 27.0 / 32.0 * 126.192 * (1.0 + 0.06 * we.powf(0.208));
        let t = darr_hartwig_t_wet(&s, &p);
        assert!(rel(t, expected) < 1e-12);
        assert!(t > 110.0 && t < 126.2, "{t}");
    }

    #[test]
    fn onb_hand_check() {
        let p = defaults();
        // subcooled liquid at 1 m/s: forced convection dominates, so h_cb is the same at the
        // reference wall and at T_onb and q_onb lies on the nucleation line B ΔT²/Pr²
        let mut s = ln2(0.0, 80.0, 0.0, 1.0);
        s.t_l = 74.0;
        let pr: f64 = 1.607e-4 * 2041.0 / 0.1448;
        let re: f64 = 806.08 * 1.0 * D / 1.607e-4;
        let h = 0.023 * re.powf(0.8) * pr.powf(0.4) * 0.1448 / D;
        assert!(rel(liquid_convection_htc(&s, &p, 80.0), h) < 1e-12);
        let b = 4.612 * 199_176.0 * 0.1448 / (8.0 * 8.88e-3 * T_SAT);
        let f = h * pr * pr / (2.0 * b);
        let dt_onb = f * (1.0 + (1.0 + 2.0 * (T_SAT - 74.0) / f).sqrt());
        let (t_onb, q_onb) = onset_of_nucleate_boiling(&s, &p);
        assert!(rel(t_onb - T_SAT, dt_onb) < 1e-12);
        assert!(rel(q_onb, b / (pr * pr) * dt_onb * dt_onb) < 1e-9);
        assert!(rel(q_onb, h * (t_onb - 74.0)) < 1e-12);
    }

    #[test]
    fn natural_convection_labels() {
        // laminar 0.59 Ra^1/4 dominates at Ra = 1e6, turbulent 0.1 Ra^1/3 at Ra = 1e12
        assert!(rel(convection_nusselt(0.0, 1.0, 1e6, 1.0), 0.59 * 1e6f64.powf(0.25)) < 1e-12);
        assert!(rel(convection_nusselt(0.0, 1.0, 1e12, 1.0), 0.1 * 1e4) < 1e-9);
        assert_eq!(convection_nusselt(0.0, 1.0, 0.0, 1.0), 4.36);
        assert!(rel(convection_nusselt(1e5, 2.0, 0.0, 1.0), 0.023 * 1e5f64.powf(0.8) * 2f64.powf(0.4)) < 1e-12);
        // the exponent scale scales the Reynolds exponent
        assert!(rel(convection_nusselt(1e5, 2.0, 0.0, 0.9), 0.023 * 1e5f64.powf(0.72) * 2f64.powf(0.4)) < 1e-12);
    }

    #[test]
    fn biberg_against_exact_geometry() {
        for i in 0..=100 {
            let beta = i as f64 / 100.0;
            let d = stratified_half_angle(beta);
            // exact liquid fraction of a circular segment of half-angle δ
            let exact = (d - d.sin() * d.cos()) / PI;
            assert!((exact - beta).abs() < 2e-3, "{beta} {exact}");
        }
        assert_eq!(stratified_half_angle(0.0), 0.0);
        assert!((stratified_half_angle(1.0) - PI).abs() < 1e-12);
        assert!((stratified_half_angle(0.5) - PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn dryout_boundary_hand_check() {
        let p = defaults();
        let s = ln2(0.9, 200.0, 5.0, 0.1);
        let q_dnb = 0.131 * 4.612f64.sqrt() * 199_176.0 * (8.88e-3 * G0 * (806.08 - 4.612)).powf(0.25);
        assert!(rel(kutateladze_q_dnb(&s, &p), q_dnb) < 1e-12);
        let q: f64 = 1e4;
        let group = 4.25
            * (4.612 * 8.88e-3 / D).powf(0.17)
            * (G0 * D * 4.612 * (806.08 - 4.612)).powf(0.37)
            * (806.08f64 / 4.612).powf(0.25);
        for chi in [0.1, 0.5, 0.9] {
            let m: f64 = (group * ((0.58f64 / chi).ln() + 0.52) * (q / q_dnb).powf(-0.7)).powf(0.93);
            assert!(rel(dryout_mass_flux(&s, &p, chi, q), m) < 1e-12);
        }
        // G = 100 kg/(m² s) at 10 kW/m² dries out near χ ≈ 0.88 (Wojtan's map for nitrogen)
        assert!(dryout_mass_flux(&s, &p, 0.85, q) > 100.0 && dryout_mass_flux(&s, &p, 0.91, q) < 100.0);
        // more heat flux: lower boundary; none above χ = 0.976
        assert!(dryout_mass_flux(&s, &p, 0.5, 1e5) < dryout_mass_flux(&s, &p, 0.5, 1e4));
        assert_eq!(dryout_mass_flux(&s, &p, 0.98, 1e4), 0.0);
        assert!(dryout_mass_flux(&s, &p, 0.5, 0.0).is_finite());
    }

    #[test]
    fn wall_friction_hand_check() {
        let p = defaults();
        // single-phase liquid, turbulent: f_l = λ ρ |v|/(2D)
        let s = ln2(0.0, 80.0, 0.0, 1.0);
        let r = flow_regime(&s, &p, 0.0);
        let (fg, fl) = wall_friction(&s, &p, &r, 1e-4);
        let v = (1.0f64 + 1e-8).sqrt();
        let lam = churchill_darcy(806.08 * v * D / 1.607e-4, 1e-4);
        assert!(rel(fl, lam * 806.08 * v / (2.0 * D)) < 1e-9, "{fl}");
        assert_eq!(fg, 0.0);
        // laminar single-phase gas at rest: Hagen–Poiseuille 32 μ/D²
        let s = ln2(1.0, 80.0, 0.0, 0.0);
        let r = flow_regime(&s, &p, 0.0);
        let (fg, fl) = wall_friction(&s, &p, &r, 0.0);
        assert!(rel(fg, 32.0 * 5.44e-6 / (D * D)) < 1e-6, "{fg}");
        assert_eq!(fl, 0.0);
        // two-phase stratified: written out
        let s = ln2(0.5, 80.0, 2.0, 0.2);
        let r = Regime { stratified: 1.0, wavy: 0.0, annular: 0.0, dryout: 0.0 };
        let (fg, fl) = wall_friction(&s, &p, &r, 0.0);
        let vg = (4.0f64 + 1e-8).sqrt();
        let vl = (0.04f64 + 1e-8).sqrt();
        let re_g = 0.5 * 4.612 * vg * D / 5.44e-6;
        let re_l = 0.5 * 806.08 * vl * D / 1.607e-4;
        let (lg, ll) = (churchill_darcy(re_g, 0.0), churchill_darcy(re_l, 0.0));
        let dp_g = lg * (0.5 * 4.612 * vg).powi(2) / (2.0 * D * 4.612);
        let dp_l = ll * (0.5 * 806.08 * vl).powi(2) / (2.0 * D * 806.08);
        let dp = dp_g + dp_l + 20.0 * (dp_g * dp_l).sqrt();
        let w_l = 0.5; // δ = π/2 at α = 0.5
        let bg = (1.0 - w_l) * lg * re_g * 4.612 * vg * vg;
        let bl = w_l * ll * re_l * 806.08 * vl * vl;
        let share_g = bg / (bg + bl);
        assert!(rel(fg, share_g * dp / vg) < 1e-9);
        assert!(rel(fl, (1.0 - share_g) * dp / vl) < 1e-9);
        // the forces add up to the two-phase gradient
        assert!(rel(fg * vg + fl * vl, dp) < 1e-9);
    }

    #[test]
    fn interfacial_drag_hand_check() {
        let p = defaults();
        let s = ln2(0.5, 80.0, 3.0, 0.5);
        let vr = (6.25f64 + 1e-8).sqrt();
        let f_fanning = churchill_darcy(4.612 * vr * D / 5.44e-6, 0.0) / 4.0;
        let a_i = 4.0 * 1.0 / (PI * D);
        let strat = Regime { stratified: 1.0, wavy: 0.0, annular: 0.0, dryout: 0.0 };
        assert!(rel(interfacial_drag(&s, &p, &strat), 0.5 * f_fanning * 4.612 * vr * a_i) < 1e-9);
        let wavy = Regime { stratified: 0.0, wavy: 1.0, annular: 0.0, dryout: 0.0 };
        assert!(rel(interfacial_drag(&s, &p, &wavy), 0.5 * f_fanning.max(0.0142) * 4.612 * vr * a_i) < 1e-9);
        // annular film (Wallis) + bubbles
        let ann = Regime { stratified: 0.0, wavy: 0.0, annular: 1.0, dryout: 0.0 };
        let film = 0.5 * 0.005 * (1.0 + 75.0 * 0.5) * 4.612 * vr * 4.0 * 0.5f64.sqrt() / D;
        // α = 0.5: the bubbles have faded out
        assert!(rel(interfacial_drag(&s, &p, &ann), film) < 1e-9);
        // α = 0.05: bubbles of twice the capillary length, plus the film
        let s = ln2(0.05, 80.0, 1.5, 0.5);
        let vr = (1.0f64 + 1e-8).sqrt();
        let d_b = 2.0 * (8.88e-3 / (G0 * (806.08 - 4.612))).sqrt();
        let re_b = 806.08 * vr * d_b / 1.607e-4;
        let cd = (24.0 / re_b * (1.0 + 0.15 * re_b.powf(0.687))).max(0.44);
        let bubble = 0.75 * cd * 806.08 * vr * 0.05 * 0.95 / d_b;
        let film = 0.5 * 0.005 * (1.0 + 75.0 * 0.95) * 4.612 * vr * 4.0 * 0.05f64.sqrt() / D;
        assert!(rel(interfacial_drag(&s, &p, &ann), film + bubble) < 1e-9);
        // terminal rise: drag balances buoyancy at ≈ 0.25 m/s
        let v_t = ((806.08 - 4.612) * G0 * d_b / (0.75 * 0.44 * 806.08)).sqrt();
        assert!((v_t - 0.25).abs() < 0.03, "{v_t}");
        let s = ln2(0.5, 80.0, 3.0, 0.5);
        let vr = (6.25f64 + 1e-8).sqrt();
        // drops
        let mist = Regime { stratified: 0.0, wavy: 0.0, annular: 0.0, dryout: 1.0 };
        // (the Weber size, 3.7 mm at this slip, is bounded by drop_d_max = 1 mm)
        let d_d = (12.0 * 8.88e-3 / (4.612 * vr * vr)).clamp(1e-5, (D / 2.0).min(1e-3));
        assert_eq!(d_d, 1e-3);
        let re_d = 4.612 * vr * d_d / 5.44e-6;
        let cd = (24.0 / re_d * (1.0 + 0.15 * re_d.powf(0.687))).max(0.44);
        assert!(rel(interfacial_drag(&s, &p, &mist), 0.75 * cd * 4.612 * vr * 0.5 / d_d) < 1e-9);
        assert_eq!(virtual_mass_coefficient(&s, &p), 0.5);
    }

    #[test]
    fn interphase_heat_hand_check() {
        let p = defaults();
        let s = ln2(0.5, 80.0, 3.0, 0.5);
        let strat = Regime { stratified: 1.0, wavy: 0.0, annular: 0.0, dryout: 0.0 };
        let got = interphase_heat(&s, &p, &strat);
        let vr = (6.25f64 + 1e-8).sqrt();
        let a_i = 4.0 / (PI * D);
        let pr_g: f64 = 5.44e-6 * 1124.0 / 7.19e-3;
        let pr_l: f64 = 1.607e-4 * 2041.0 / 0.1448;
        let re_g = 4.612 * vr * D / 5.44e-6;
        let re_l = 806.08 * 0.5 * D / 1.607e-4;
        let hg = 4.36f64.max(0.023 * re_g.powf(0.8) * pr_g.powf(0.4)) * 7.19e-3 / D;
        let hl = 4.36f64.max(0.023 * re_l.powf(0.8) * pr_l.powf(0.4)) * 0.1448 / D;
        assert!(rel(got.h_ig, a_i * hg) < 1e-9);
        assert!(rel(got.h_il, a_i * hl) < 1e-9);
    }

    // ---------------------------------------------------------------- boiling curve shape

    fn curve(s: &Local, p: &CryoParams, set: CorrelationSet, t_w: f64) -> f64 {
        boiling_curve(&Local { t_w, ..*s }, p, set)
    }

    fn curve_states() -> Vec<Local> {
        let mut v = vec![ln2(0.3, 100.0, 0.5, 0.05), ln2(0.05, 100.0, 0.0, 0.0), ln2(0.7, 100.0, 5.0, 0.5)];
        let mut sub = ln2(0.1, 100.0, 0.2, 1.0);
        sub.t_l = 70.0;
        v.push(sub);
        let mut hot_gas = ln2(0.9, 100.0, 3.0, 0.1);
        hot_gas.h_g += 1124.0 * 100.0;
        v.push(hot_gas);
        v
    }

    #[test]
    fn boiling_curve_is_continuous_at_every_anchor() {
        let p = defaults();
        for set in CorrelationSet::ALL {
            for s in curve_states() {
                let a = boiling_anchors(&s, &p, set);
                assert!(a.t_onb < a.t_chf && a.t_chf < a.t_mfb, "{set} {a:?}");
                for t in [a.t_onb, a.t_chf, a.t_mfb] {
                    let eps = 1e-9 * t;
                    let lo = curve(&s, &p, set, t - eps);
                    let hi = curve(&s, &p, set, t + eps);
                    assert!((hi - lo).abs() <= 0.01 * lo.abs().max(hi.abs()), "{set} at {t}: {lo} {hi} {a:?}");
                }
                let q = |t| curve(&s, &p, set, t);
                assert!(rel(q(a.t_onb), a.q_onb) < 1e-9);
                assert!(rel(q(a.t_chf), a.q_chf) < 1e-9);
                assert!(rel(q(a.t_mfb), a.q_mfb) < 1e-9);
            }
        }
    }

    #[test]
    fn boiling_curve_has_the_boiling_shape() {
        let p = defaults();
        for set in CorrelationSet::ALL {
            for s in curve_states() {
                let a = boiling_anchors(&s, &p, set);
                // segment of a wall temperature: 0 rising to q_chf, 1 falling to q_mfb, 2 rising
                let segment = |t: f64| {
                    if t <= a.t_chf {
                        0
                    } else if t <= a.t_mfb {
                        1
                    } else {
                        2
                    }
                };
                let t0 = s.t_l + 0.01;
                let (mut prev_t, mut prev) = (t0, curve(&s, &p, set, t0));
                let n = 4000;
                for i in 1..=n {
                    let t = t0 + (500.0 - t0) * i as f64 / n as f64;
                    let q = curve(&s, &p, set, t);
                    assert!(q.is_finite() && q > 0.0, "{set} {t} {q}");
                    if segment(t) == segment(prev_t) {
                        if segment(t) == 1 {
                            assert!(q <= prev * (1.0 + 1e-12), "{set}: not falling at {t}: {prev} → {q} {a:?}");
                        } else {
                            assert!(q >= prev * (1.0 - 1e-12), "{set}: not rising at {t}: {prev} → {q} {a:?}");
                        }
                    }
                    (prev_t, prev) = (t, q);
                }
                assert!(a.q_chf >= a.q_onb && a.q_chf >= a.q_mfb);
            }
        }
    }

    #[test]
    fn paper_anchors_for_ln2_are_plausible() {
        let p = defaults();
        let s = ln2(0.3, 100.0, 0.5, 0.05);
        let a = boiling_anchors(&s, &p, CorrelationSet::Paper);
        assert!(a.t_onb - T_SAT < 3.0, "{a:?}");
        assert!((a.t_chf - 101.7).abs() < 0.2, "{a:?}");
        assert!(a.t_mfb > 140.0 && a.t_mfb < 260.0, "{a:?}");
        assert!(a.q_chf > 3e4 && a.q_chf < 3e5, "{a:?}");
        assert!(a.q_mfb > 1e3 && a.q_mfb < a.q_chf, "{a:?}");
    }

    // ---------------------------------------------------------------- wall heat

    #[test]
    fn wall_heat_splits_and_boils() {
        let p = defaults();
        let s = ln2(0.5, 150.0, 1.0, 0.1);
        let q = boiling_curve(&s, &p, CorrelationSet::Paper);
        let wh = wall_heat(&s, &p, CorrelationSet::Paper, 0.4, &WET);
        assert!(rel(wh.h_wl * (150.0 - T_SAT), 0.4 * q) < 1e-12);
        assert!(rel(wh.h_wg, 0.6 * gas_convection_htc(&s, &p, 150.0)) < 1e-12);
        assert_eq!(wh.boiling_fraction, 1.0);
        assert!(wh.t_onb < wh.t_chf && wh.t_chf < wh.t_mfb);
        let dry = wall_heat(&s, &p, CorrelationSet::Paper, 0.0, &WET);
        assert_eq!(dry.regime_code, REGIME_DRY);
        assert_eq!(dry.h_wl, 0.0);
        // wall colder than saturation: convection, no boiling
        let mut cold = ln2(0.0, 75.0, 0.0, 0.5);
        cold.t_l = 76.0;
        let wh = wall_heat(&cold, &p, CorrelationSet::Paper, 1.0, &WET);
        assert_eq!(wh.regime_code, REGIME_CONVECTION);
        assert_eq!(wh.boiling_fraction, 0.0);
        assert!(rel(wh.h_wl, liquid_convection_htc(&cold, &p, 75.0)) < 1e-12);
        // the boiling fraction rises smoothly from T_s to T_onb
        let s = ln2(0.0, 0.0, 0.0, 0.0);
        let t_onb = onset_of_nucleate_boiling(&s, &p).0;
        let mid = wall_heat(&Local { t_w: 0.5 * (T_SAT + t_onb), ..s }, &p, CorrelationSet::Paper, 1.0, &WET);
        assert!((mid.boiling_fraction - 0.5).abs() < 1e-9);
        let codes: Vec<u8> = [T_SAT + 1e-3, 0.5 * (t_onb + 101.7), 110.0, 400.0]
            .iter()
            .map(|&t| wall_heat(&Local { t_w: t, ..s }, &p, CorrelationSet::Paper, 1.0, &WET).regime_code)
            .collect();
        assert_eq!(codes, [REGIME_CONVECTION, REGIME_NUCLEATE, REGIME_TRANSITION, REGIME_FILM]);
    }

    // ---------------------------------------------------------------- regimes

    #[test]
    fn regime_weights_sum_to_one_and_are_smooth() {
        let p = defaults();
        for alpha in [0.0, 0.05, 0.3, 0.6, 0.9, 0.99, 1.0] {
            for q in [0.0, 1e4, 1e5] {
                let mut prev: Option<Regime> = None;
                let n = 400;
                for i in 0..=n {
                    // velocities from 1 mm/s to 30 m/s in log steps of ~2.5 %
                    let v = 1e-3 * (3e4f64).powf(i as f64 / n as f64);
                    let s = ln2(alpha, 150.0, 3.0 * v, v);
                    let r = flow_regime(&s, &p, q);
                    assert!((r.sum() - 1.0).abs() < 1e-12, "{r:?}");
                    for w in [r.stratified, r.wavy, r.annular, r.dryout] {
                        assert!((0.0..=1.0).contains(&w), "{r:?}");
                    }
                    if let Some(pr) = prev {
                        let jump = (r.stratified - pr.stratified)
                            .abs()
                            .max((r.wavy - pr.wavy).abs())
                            .max((r.annular - pr.annular).abs())
                            .max((r.dryout - pr.dryout).abs());
                        assert!(jump < 0.2, "α {alpha} v {v}: {pr:?} → {r:?}");
                    }
                    prev = Some(r);
                }
            }
        }
    }

    #[test]
    fn regimes_where_expected() {
        let p = defaults();
        // standing liquid: stratified
        let r = flow_regime(&ln2(0.5, 150.0, 0.0, 0.0), &p, 0.0);
        assert_eq!(r.stratified, 1.0);
        // all gas: dryout/mist, nothing wetted
        let s = ln2(1.0, 150.0, 5.0, 0.0);
        let r = flow_regime(&s, &p, 0.0);
        assert_eq!(r.dryout, 1.0);
        assert_eq!(wetted_fraction(&s, &r), 0.0);
        // fast flow at moderate quality: annular
        let s = ln2(0.9, 150.0, 20.0, 2.0);
        let r = flow_regime(&s, &p, 0.0);
        assert!(r.annular > 0.99, "{r:?} χ {}", regime_quality(&s));
        assert!(wetted_fraction(&s, &r) > 0.99);
        // slow flow at moderate quality between the boundaries: wavy
        let s = ln2(0.9, 150.0, 6.0, 0.08);
        let chi = regime_quality(&s);
        let (gs, gw) = stratification_boundaries(&p, chi);
        let (gg, gl) = mass_fluxes(&s);
        assert!(gg + gl > gs && gg + gl < gw, "{gs} {} {gw}", gg + gl);
        // heat flux moves dryout to lower quality
        let s = ln2(0.98, 150.0, 15.0, 0.5);
        let r0 = flow_regime(&s, &p, 0.0);
        let r1 = flow_regime(&s, &p, 2e5);
        assert!(r1.dryout > r0.dryout, "{r0:?} {r1:?}");
        // liquid-full pipe is fully wetted
        let s = ln2(0.0, 150.0, 0.0, 0.0);
        assert_eq!(wetted_fraction(&s, &flow_regime(&s, &p, 0.0)), 1.0);
    }

    // ---------------------------------------------------------------- robustness

    #[test]
    fn no_nan_at_extremes() {
        let p = defaults();
        for set in CorrelationSet::ALL {
            for alpha in [0.0, 1e-9, 0.5, 1.0 - 1e-9, 1.0] {
                for t_w in [20.0, 70.0, T_SAT, T_SAT + 1e-9, 90.0, 150.0, 300.0, 1000.0] {
                    for (vg, vl) in [(0.0, 0.0), (1e-12, -1e-12), (50.0, 0.0), (-3.0, 2.0)] {
                        for gravity in [0.0, G0] {
                            for t_l in [60.0, T_SAT, 80.0] {
                                let mut s = ln2(alpha, t_w, vg, vl);
                                s.gravity = gravity;
                                s.t_l = t_l;
                                let r = flow_regime(&s, &p, 1e4);
                                assert!((r.sum() - 1.0).abs() < 1e-12);
                                let w = wetted_fraction(&s, &r);
                                assert!((0.0..=1.0).contains(&w));
                                let wh = wall_heat(&s, &p, set, w, &r);
                                let ih = interphase_heat(&s, &p, &r);
                                let (fg, fl) = wall_friction(&s, &p, &r, 1e-4);
                                let fi = interfacial_drag(&s, &p, &r);
                                let q = boiling_curve(&s, &p, set);
                                for (name, x) in [
                                    ("h_wg", wh.h_wg),
                                    ("h_wl", wh.h_wl),
                                    ("boiling", wh.boiling_fraction),
                                    ("q_chf", wh.q_chf),
                                    ("h_ig", ih.h_ig),
                                    ("h_il", ih.h_il),
                                    ("f_g", fg),
                                    ("f_l", fl),
                                    ("F_i", fi),
                                ] {
                                    assert!(x.is_finite() && x >= 0.0, "{name} = {x} at {s:?}");
                                }
                                assert!(q.is_finite(), "q = {q} at {s:?}");
                                assert!(wh.t_onb.is_finite() && wh.t_chf.is_finite() && wh.t_mfb.is_finite());
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn extreme_parameter_values_stay_finite() {
        // every parameter at its lower, then upper bound (one at a time)
        let s_list = [ln2(0.3, 150.0, 1.0, 0.1), ln2(0.95, 300.0, 20.0, 1.0), ln2(0.0, 78.0, 0.0, 0.0)];
        for name in PARAMETER_NAMES {
            let sp = spec(name).unwrap();
            for v in [sp.lower, sp.upper] {
                let mut set = ParameterSet::new();
                set.set(name, v).unwrap();
                let p = CryoParams::from_set(&set);
                for s in &s_list {
                    for set in CorrelationSet::ALL {
                        let r = flow_regime(s, &p, 2e4);
                        let w = wetted_fraction(s, &r);
                        let wh = wall_heat(s, &p, set, w, &r);
                        let ih = interphase_heat(s, &p, &r);
                        let (fg, fl) = wall_friction(s, &p, &r, 1e-4);
                        let fi = interfacial_drag(s, &p, &r);
                        for x in [wh.h_wg, wh.h_wl, wh.q_chf, ih.h_ig, ih.h_il, fg, fl, fi, r.sum()] {
                            assert!(x.is_finite() && x >= 0.0, "{name} = {v}: {x}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn correlation_set_names() {
        for c in CorrelationSet::ALL {
            assert_eq!(c.name().parse::<CorrelationSet>().unwrap(), c);
            assert_eq!(c.to_string(), c.name());
        }
        assert_eq!("Miropolskii".parse::<CorrelationSet>().unwrap(), CorrelationSet::Miropolskii);
        let e = "bromley".parse::<CorrelationSet>().unwrap_err().to_string();
        assert!(e.contains("bromley") && e.contains("paper"), "{e}");
        assert_eq!(CorrelationSet::default(), CorrelationSet::Paper);
    }

    #[test]
    fn parameters_are_read_from_the_set() {
        let mut set = ParameterSet::new();
        set.set("Gwsc", 2.0).unwrap();
        set.set("Gisc", 0.5).unwrap();
        set.set("tauw", 3.0).unwrap();
        let p = CryoParams::from_set(&set);
        assert_eq!(p.wall_mass_transfer_scale, 2.0);
        assert_eq!(p.interface_mass_transfer_scale, 0.5);
        assert_eq!(p.wetting_time_constant, 3.0);
        let d = defaults();
        assert_eq!(d.t_mfb_scale, 1.25);
        assert_eq!((d.t_mfb_g_scale, d.t_mfb_g_exponent, d.t_mfb_x_scale, d.t_mfb_x_exponent), (0.2, 0.165, 1.04, 2.0));
        assert_eq!(
            (d.fb_scale, d.fb_x_scale, d.fb_x_exponent, d.fb_g_scale, d.fb_g_exponent),
            (2.0, 1.04, 2.0, 0.2, 0.1)
        );
        assert_eq!(
            (d.q_chf_scale, d.chf_alpha_cr, d.chf_void_exponent, d.chf_g_coeff, d.chf_g_exponent),
            (1.0, 0.96, 2.0, 0.16, 0.2)
        );
        // every name is in the registry, once
        let mut seen = std::collections::HashSet::new();
        for n in PARAMETER_NAMES {
            assert!(spec(n).is_some(), "{n} not registered");
            assert!(seen.insert(*n), "{n} twice");
        }
        // every registry parameter is read here, except the basic closures' own two
        for r in REGISTRY {
            assert!(
                PARAMETER_NAMES.contains(&r.name) || ["hi_vol"].contains(&r.name),
                "{} is registered but not read",
                r.name
            );
        }
    }

    #[test]
    fn flashing_acts_on_superheated_liquid_only() {
        let p = CryoParams::from_set(&ParameterSet::new());
        // a liquid-filled cell: no other interface is left
        let mut s = ln2(0.0, T_SAT, 0.0, 0.0);
        assert_eq!(flashing_htc(&s, &p), 0.0, "saturated liquid does not flash");
        s.t_l = T_SAT - 5.0;
        assert_eq!(flashing_htc(&s, &p), 0.0, "subcooled liquid does not flash");
        s.t_l = T_SAT + 5.0;
        let h = flashing_htc(&s, &p);
        // Plesset–Zwick on 6 α_min / d_b of bubbles: Ja = 806 · 2041 · 5 / (4.6 · 2e5) ≈ 9
        let d_b = bubble_diameter(&s);
        let ja = s.rho_l * s.cp_l * 5.0 / (s.vap_sat.rho * s.h_lg);
        let expected = 6.0 * p.flash_void_min / d_b * (12.0 / PI * ja) * s.k_l / d_b;
        assert!((h - expected).abs() < 1e-9 * expected, "{h} vs {expected}");
        // it is part of the liquid-side interphase coefficient, with no presence weight
        let ih = interphase_heat(&s, &p, &flow_regime(&s, &p, 0.0));
        assert!(ih.h_il >= h);
        // and it fades out with the bubbly regime
        s.alpha = 0.6;
        assert_eq!(flashing_htc(&s, &p), 0.0);
    }

    #[test]
    fn drop_contact_follows_forslund_rohsenow() {
        let p = CryoParams::from_set(&ParameterSet::new());
        let s = ln2(0.99, 250.0, 10.0, 8.0);
        let h = drop_contact_htc(&s, &p);
        assert!(h > 0.0);
        // h ∝ (1 − α)^(2/3) and ∝ K
        let s2 = Local { alpha: 0.999, ..s };
        let ratio = drop_contact_htc(&s2, &p) / h;
        assert!((ratio - (0.001f64 / 0.01).powf(2.0 / 3.0)).abs() < 1e-9, "{ratio}");
        let mut off = p;
        off.drop_contact_k = 0.0;
        assert_eq!(drop_contact_htc(&s, &off), 0.0);
        // no contact heat below saturation, and none on a wetted wall or outside dryout
        assert_eq!(drop_contact_htc(&Local { t_w: T_SAT - 1.0, ..s }, &p), 0.0);
        let mist = Regime { stratified: 0.0, wavy: 0.0, annular: 0.0, dryout: 1.0 };
        let dry = wall_heat(&s, &p, CorrelationSet::Paper, 0.0, &mist);
        let no_drops = wall_heat(&s, &off, CorrelationSet::Paper, 0.0, &mist);
        assert!((dry.h_wl - no_drops.h_wl - h).abs() < 1e-9 * h);
        let wet = wall_heat(&s, &p, CorrelationSet::Paper, 0.0, &WET);
        assert_eq!(wet.h_wl, wall_heat(&s, &off, CorrelationSet::Paper, 0.0, &WET).h_wl);
    }

    // ---------------------------------------------------------------- liveness

    /// Every closure output at a set of states covering the regimes and the boiling curve.
    fn fingerprint(p: &CryoParams) -> Vec<f64> {
        let mut states = vec![
            ln2(0.3, 78.0, 0.2, 0.02),
            ln2(0.3, 90.0, 0.5, 0.05),
            ln2(0.3, 105.0, 0.5, 0.05),
            ln2(0.3, 180.0, 0.5, 0.05),
            ln2(0.3, 400.0, 0.5, 0.05),
            ln2(0.6, 150.0, 2.0, 0.2),
            ln2(0.85, 150.0, 4.0, 0.3),
            ln2(0.9, 150.0, 8.0, 0.8),
            ln2(0.97, 200.0, 10.0, 0.5),
            ln2(0.995, 300.0, 10.0, 0.3),
            ln2(0.999, 300.0, 10.0, 0.3),
            ln2(0.9995, 300.0, 10.0, 0.3),
            // mist whose drops move with the vapour: the Weber size is bounded by drop_d_max
            ln2(0.999, 300.0, 10.0, 9.5),
            ln2(0.0, 100.0, 0.0, 0.3),
            ln2(0.003, 100.0, 0.3, 0.3),
        ];
        let mut sub = ln2(0.1, 95.0, 0.5, 1.0);
        sub.t_l = 70.0;
        states.push(sub);
        // strongly subcooled, fast liquid: T_onb above Theler's T_chf, so the boiling curve
        // holds T_chf at T_onb + boil_gap_chf
        let mut fast = ln2(0.05, 120.0, 0.5, 6.0);
        fast.t_l = 64.0;
        states.push(fast);
        // liquid 3 K above saturation in a nearly liquid-filled cell: it flashes
        let mut flashing = ln2(1e-4, 90.0, 0.5, 0.5);
        flashing.t_l = T_SAT + 3.0;
        states.push(flashing);
        let mut hot = ln2(0.7, 250.0, 3.0, 0.3);
        hot.h_g += 1124.0 * 60.0;
        states.push(hot);
        let mut out = Vec::new();
        for s in &states {
            for q_wall in [0.0, 3e4] {
                let r = flow_regime(s, p, q_wall);
                out.extend([r.stratified, r.wavy, r.annular, r.dryout]);
                let w = wetted_fraction(s, &r);
                out.push(w);
                for set in CorrelationSet::ALL {
                    let wh = wall_heat(s, p, set, w.max(0.5), &r);
                    out.extend([wh.h_wg, wh.h_wl, wh.boiling_fraction, wh.q_chf, wh.t_chf, wh.t_mfb, wh.t_onb]);
                    out.push(boiling_curve(s, p, set));
                }
                let ih = interphase_heat(s, p, &r);
                out.extend([ih.h_ig, ih.h_il]);
                let (fg, fl) = wall_friction(s, p, &r, 1e-4);
                out.extend([fg, fl, interfacial_drag(s, p, &r), virtual_mass_coefficient(s, p)]);
            }
        }
        // the three scales the scheme applies itself, and the phase-blending thresholds (numerics
        // of the scheme: no closure reads them)
        out.extend([
            p.wall_mass_transfer_scale,
            p.interface_mass_transfer_scale,
            p.wetting_time_constant,
            p.blend_min,
            p.blend_max,
        ]);
        out
    }

    /// The bounds of the boiling curve's ordering and the parameters each one holds: they act
    /// where those are at a bound (`Tonbsc` at its upper, the others at their lower bound).
    const ORDERING_BOUNDS: [(&str, &[&str]); 3] =
        [("boil_gap_chf", &["Tchfsc", "Tonbsc"]), ("boil_gap_mfb", &["Tmfbsc"]), ("chf_over_mfb", &["qchfsc"])];

    #[test]
    fn every_parameter_is_live() {
        for name in PARAMETER_NAMES {
            let sp = spec(name).unwrap();
            let mut base_set = ParameterSet::new();
            if let Some((_, held)) = ORDERING_BOUNDS.iter().find(|(b, _)| b == name) {
                for h in held.iter() {
                    let sp = spec(h).unwrap();
                    // the scale of T_onb goes up, every other held scale down
                    base_set.set(h, if *h == "Tonbsc" { sp.upper } else { sp.lower }).unwrap();
                }
            }
            let base = fingerprint(&CryoParams::from_set(&base_set));
            assert!(base.iter().all(|x| x.is_finite()));
            let live = [sp.lower, sp.upper, 0.5 * (sp.lower + sp.default), 0.5 * (sp.upper + sp.default)]
                .into_iter()
                .filter(|v| *v != sp.default)
                .any(|v| {
                    let mut set = base_set.clone();
                    set.set(name, v).unwrap();
                    let fp = fingerprint(&CryoParams::from_set(&set));
                    fp.iter().zip(&base).any(|(a, b)| rel(*a, *b) > 1e-9)
                });
            assert!(live, "parameter {name} changes no closure output");
        }
    }
}
