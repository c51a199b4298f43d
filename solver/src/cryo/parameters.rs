//! The closure set's constants: [`CryoParams`], read once from the parameter registry, the
//! registry names it reads ([`PARAMETER_NAMES`]) and the choice of film-boiling pair
//! ([`CorrelationSet`]).

use std::fmt;
use std::str::FromStr;

use crate::fluids::FluidConstants;
use crate::params::ParameterSet;

/// Theler's k_g = c_p/R of a diatomic ideal gas with its rotation excited: nitrogen's, the
/// default of [`CryoParams::ideal_cp_over_r`].
pub const DIATOMIC_CP_OVER_R: f64 = 3.5;
/// Nitrogen's specific gas constant, J/(kg K): the default of [`CryoParams::gas_constant`].
pub const NITROGEN_GAS_CONSTANT: f64 = 296.8;
/// Nitrogen's critical temperature, K: the default of [`CryoParams::t_critical`].
pub const NITROGEN_T_CRITICAL: f64 = 126.192;

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
    /// wetted fraction towards [`wetted_fraction`](super::wetted_fraction) with this time
    /// constant**.
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
