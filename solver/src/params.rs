//! The parameter registry: every tunable constant of the closures and numerics is a named,
//! bounded parameter with a unit, a group and a one-line meaning.
//!
//! A [`ParameterSet`] holds values for any subset of the registry; everything it does not name
//! takes the registry default. Names are checked: an unknown name or a value outside the bounds
//! is an error that says which name, which value and what is allowed.

use std::collections::BTreeMap;

use serde::Serialize;

/// One registry entry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ParamSpec {
    /// Name (as in case files, `--set` and calibrations).
    pub name: &'static str,
    /// Group: onb, chf, film_boiling, transition_boiling, convection, flow_regime, friction,
    /// interface, numerics.
    pub group: &'static str,
    /// Default value.
    pub default: f64,
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
    /// Unit (`-` for dimensionless).
    pub unit: &'static str,
    /// One-line meaning.
    pub description: &'static str,
}

/// The parameter table: every registry parameter once, in registry order, with its entry
/// (group, default, bounds, unit, meaning) and the field of the cryogenic closure set's
/// [`CryoParams`](crate::cryo::CryoParams) it fills, with that field's doc (`_`: read elsewhere, by
/// name). [`REGISTRY`] is generated from it here, and `PARAMETER_NAMES`, the `CryoParams` fields
/// and `CryoParams::from_set` in `cryo`: a parameter is added in this table and nowhere else.
macro_rules! parameter_table {
    ($then:ident) => {
        $then! {
            "vm_coeff" {
                group: "interface",
                default: 0.5,
                lower: 0.0,
                upper: 5.0,
                unit: "-",
                description: "virtual-mass coefficient C in C α β ρ_m ∂(u_g − u_l)/∂t",
                /// `vm_coeff`: virtual-mass coefficient C.
                field: virtual_mass,
            }
            "hi_vol" {
                group: "interface",
                default: 1.0e5,
                lower: 0.0,
                upper: 1.0e9,
                unit: "W/(m3 K)",
                description: "volumetric interphase heat transfer coefficient scale, times α β",
                field: _,
            }
            "blend_xmin" {
                group: "numerics",
                default: 1.0e-7,
                lower: 1.0e-12,
                upper: 1.0e-4,
                unit: "-",
                description: "phase blending: below this fraction a phase is treated as absent",
                /// `blend_xmin`: a phase below this volume fraction is absent (no wetting, no interface).
                field: blend_min,
            }
            "blend_xmax" {
                group: "numerics",
                default: 1.0e-2,
                lower: 1.0e-4,
                upper: 0.2,
                unit: "-",
                description: "phase blending: above this fraction a phase is fully present",
                /// `blend_xmax`: a phase above this volume fraction is fully present.
                field: blend_max,
            }
            "Tonbsc" {
                group: "onb",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "scale of the ONB wall superheat T_onb − T_s (eq:T_onb, Sato–Matsumura/Frost–Dzakowic)",
                /// `Tonbsc`: scale of the ONB wall superheat T_onb − T_s.
                field: t_onb_scale,
            }
            "nb_exp" {
                group: "onb",
                default: 2.0,
                lower: 1.0,
                upper: 5.0,
                unit: "-",
                description: "exponent n of the nucleate-boiling interpolation q_onb + (q_chf − q_onb) y^n (eq:q_nb_int)",
                /// `nb_exp`: exponent n of the nucleate-boiling interpolation (eq:q_nb_int).
                field: nb_exponent,
            }
            "qchfsc" {
                group: "chf",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "overall scale of the critical heat flux (a1 of eq:Iloeje_chf, also applied to the Griffith form)",
                /// `qchfsc`: overall CHF scale (a1 of eq:Iloeje_chf).
                field: q_chf_scale,
            }
            "chf_alpha_cr" {
                group: "chf",
                default: 0.96,
                lower: 0.5,
                upper: 1.0,
                unit: "-",
                description: "critical void fraction α_cr of the CHF void factor (α_cr − α)",
                /// `chf_alpha_cr`: critical void fraction α_cr.
                field: chf_alpha_cr,
            }
            "chf_void_exp" {
                group: "chf",
                default: 2.0,
                lower: 0.5,
                upper: 4.0,
                unit: "-",
                description: "exponent a2 of (α_cr − α) in the simplified CHF (eq:Iloeje_chf)",
                /// `chf_void_exp`: exponent a2 of (α_cr − α) in eq:Iloeje_chf.
                field: chf_void_exponent,
            }
            "chf_g_coeff" {
                group: "chf",
                default: 0.16,
                lower: 0.0,
                upper: 1.0,
                unit: "-",
                description: "mass-flux coefficient a3 of the simplified CHF (1 + a3 G^a4), G in kg/(m2 s)",
                /// `chf_g_coeff`: mass-flux coefficient a3 of eq:Iloeje_chf.
                field: chf_g_coeff,
            }
            "chf_g_exp" {
                group: "chf",
                default: 0.2,
                lower: 0.0,
                upper: 0.6,
                unit: "-",
                description: "mass-flux exponent a4 of the simplified CHF (the paper prints a5 in the exponent)",
                /// `chf_g_exp`: mass-flux exponent a4 of eq:Iloeje_chf (printed a5).
                field: chf_g_exponent,
            }
            "chf_griffith" {
                group: "chf",
                default: 0.0,
                lower: 0.0,
                upper: 1.0,
                unit: "-",
                description: "weight of the Griffith-type CHF (eq:Griffith_chf) against the simplified Iloeje-type form",
                /// `chf_griffith`: weight of the Griffith-type form (eq:Griffith_chf) against the simplified
                /// Iloeje-type form: 0 simplified only, 1 Griffith only.
                field: chf_griffith_weight,
            }
            "Tchfsc" {
                group: "chf",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "scale of the CHF wall superheat T_chf − T_s from Theler's T_chf (eq:theler)",
                /// `Tchfsc`: scale of the CHF wall superheat T_chf − T_s (eq:theler).
                field: t_chf_scale,
            }
            "qmfbsc" {
                group: "film_boiling",
                default: 2.0,
                lower: 0.5,
                upper: 8.0,
                unit: "-",
                description: "c1 of eq:Iloeje_hfb: scaling coefficient of the film-boiling heat transfer (Bromley)",
                /// `qmfbsc`: c1 of eq:Iloeje_hfb: film-boiling heat transfer scale.
                field: fb_scale,
            }
            "Xmfbsc" {
                group: "film_boiling",
                default: 1.04,
                lower: 0.26,
                upper: 4.16,
                unit: "-",
                description: "c2 of eq:Iloeje_hfb: coefficient of the quality term (1 − c2 X_e^c3)",
                /// `Xmfbsc`: c2 of eq:Iloeje_hfb: quality coefficient.
                field: fb_x_scale,
            }
            "Xemfbsc" {
                group: "film_boiling",
                default: 2.0,
                lower: 0.5,
                upper: 8.0,
                unit: "-",
                description: "c3 of eq:Iloeje_hfb: exponent of the equilibrium quality X_e",
                /// `Xemfbsc`: c3 of eq:Iloeje_hfb: quality exponent.
                field: fb_x_exponent,
            }
            "Gmfbsc" {
                group: "film_boiling",
                default: 0.2,
                lower: 0.05,
                upper: 0.8,
                unit: "-",
                description: "c4 of eq:Iloeje_hfb: scaling of the liquid mass flux term (1 + c4 G^c5)",
                /// `Gmfbsc`: c4 of eq:Iloeje_hfb: mass-flux coefficient.
                field: fb_g_scale,
            }
            "Emfbsc" {
                group: "film_boiling",
                default: 0.1,
                lower: 0.025,
                upper: 0.4,
                unit: "-",
                description: "c5 of eq:Iloeje_hfb: exponent of the liquid mass flux",
                /// `Emfbsc`: c5 of eq:Iloeje_hfb: mass-flux exponent.
                field: fb_g_exponent,
            }
            "Tmfbsc" {
                group: "film_boiling",
                default: 1.25,
                lower: 0.3125,
                upper: 5.0,
                unit: "-",
                description: "c1 of eq:Iloeje: overall scaling of the minimum film boiling superheat (Berenson)",
                /// `Tmfbsc`: c1 of eq:Iloeje: scale of ΔT_mfb.
                field: t_mfb_scale,
            }
            "Gtmfbsc" {
                group: "film_boiling",
                default: 0.2,
                lower: 0.05,
                upper: 0.8,
                unit: "-",
                description: "c4 of eq:Iloeje: scaling of the liquid mass flux term of T_mfb",
                /// `Gtmfbsc`: c4 of eq:Iloeje: mass-flux coefficient.
                field: t_mfb_g_scale,
            }
            "Etmfbsc" {
                group: "film_boiling",
                default: 0.165,
                lower: 0.04125,
                upper: 0.66,
                unit: "-",
                description: "c5 of eq:Iloeje: exponent of the liquid mass flux of T_mfb",
                /// `Etmfbsc`: c5 of eq:Iloeje: mass-flux exponent.
                field: t_mfb_g_exponent,
            }
            "Xetmfbsc" {
                group: "film_boiling",
                default: 2.0,
                lower: 0.5,
                upper: 8.0,
                unit: "-",
                description: "c3 of eq:Iloeje: exponent of the quality X_e of T_mfb (Table 1 labels it scaling: swapped)",
                /// `Xetmfbsc`: c3 of eq:Iloeje: quality exponent (Table 1 says "scaling": swapped).
                field: t_mfb_x_exponent,
            }
            "Xtmfbsc" {
                group: "film_boiling",
                default: 1.04,
                lower: 0.26,
                upper: 4.16,
                unit: "-",
                description: "c2 of eq:Iloeje: scaling of the quality term of T_mfb (Table 1 labels it exponent: swapped)",
                /// `Xtmfbsc`: c2 of eq:Iloeje: quality coefficient (Table 1 says "exponent": swapped).
                field: t_mfb_x_scale,
            }
            "hmirosc" {
                group: "film_boiling",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "scale of the Miropolskii film-boiling coefficient (correlation set miropolskii)",
                /// `hmirosc`: scale of the Miropolskii film-boiling coefficient.
                field: miropolskii_scale,
            }
            "dh_we_coeff" {
                group: "film_boiling",
                default: 0.06,
                lower: 0.0,
                upper: 0.3,
                unit: "-",
                description: "Darr–Hartwig rewet temperature (27/32) T_cr (1 + b We_D^e): Weber coefficient b (set miropolskii)",
                /// `dh_we_coeff`: Weber coefficient b of the Darr–Hartwig rewet temperature.
                field: dh_we_coeff,
            }
            "dh_we_exp" {
                group: "film_boiling",
                default: 0.208,
                lower: 0.05,
                upper: 0.5,
                unit: "-",
                description: "Darr–Hartwig rewet temperature: Weber exponent e, We_D = G^2 D/(ρ_l σ) (set miropolskii)",
                /// `dh_we_exp`: Weber exponent e of the Darr–Hartwig rewet temperature.
                field: dh_we_exponent,
            }
            "hg0sc" {
                group: "convection",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "overall scaling of the gas heat transfer to the dry wall (also after dryout)",
                /// `hg0sc`: scale of the gas heat transfer to the dry wall.
                field: gas_wall_scale,
            }
            "hg0esc" {
                group: "convection",
                default: 1.0,
                lower: 0.75,
                upper: 1.25,
                unit: "-",
                description: "scaling of the Dittus–Boelter Reynolds exponent 0.8 of the gas at the dry wall (bounds: exponents 0.6–1.0)",
                /// `hg0esc`: scale of the Dittus–Boelter Reynolds exponent (0.8) of the gas at the dry wall.
                field: gas_wall_exponent_scale,
            }
            "hl0sc" {
                group: "convection",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "scaling of the single-phase liquid convection to the wetted wall (eq:convection_Nu)",
                /// `hl0sc`: scale of the single-phase liquid convection to the wetted wall.
                field: liquid_wall_scale,
            }
            "Gwsc" {
                group: "convection",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "overall scaling of the mass transfer at the wetted wall Γ_wg (above 1: on superheated liquid only)",
                /// `Gwsc`: scale of the wall mass transfer Γ_wg: **the scheme multiplies Γ_wg by it**; the
                /// part above 1 acts only on superheated liquid (see the scheme's `wall_evaporation_scale`).
                field: wall_mass_transfer_scale,
            }
            "tauw" {
                group: "convection",
                default: 1.0,
                lower: 0.01,
                upper: 100.0,
                unit: "s",
                description: "characteristic time of the heat transfer to the wall: relaxation time of the wetted fraction",
                /// `tauw`: characteristic time of the heat transfer to the wall, s: **the scheme relaxes the
                /// wetted fraction towards [`wetted_fraction`](super::wetted_fraction) with this time
                /// constant**.
                field: wetting_time_constant,
            }
            "regime_strat_c0" {
                group: "flow_regime",
                default: 50.0,
                lower: 0.0,
                upper: 200.0,
                unit: "kg/(m2 s)",
                description: "stratified/wavy boundary G_strat(χ) = c0 + c1 χ + c2 χ^2 (simplified Wojtan): c0",
                /// `regime_strat_c0`: constant term c0 of the stratified → stratified-wavy boundary
                /// G_strat(χ) = c0 + c1 χ + c2 χ², kg/(m² s) ([`CryoParams::strat_poly`]).
                field: strat_c0,
            }
            "regime_strat_c1" {
                group: "flow_regime",
                default: -95.0,
                lower: -400.0,
                upper: 100.0,
                unit: "kg/(m2 s)",
                description: "stratified/wavy boundary G_strat(χ): c1",
                /// `regime_strat_c1`: linear coefficient c1 of G_strat(χ).
                field: strat_c1,
            }
            "regime_strat_c2" {
                group: "flow_regime",
                default: 80.0,
                lower: -100.0,
                upper: 400.0,
                unit: "kg/(m2 s)",
                description: "stratified/wavy boundary G_strat(χ): c2",
                /// `regime_strat_c2`: quadratic coefficient c2 of G_strat(χ).
                field: strat_c2,
            }
            "regime_wavy_c0" {
                group: "flow_regime",
                default: 300.0,
                lower: 0.0,
                upper: 1200.0,
                unit: "kg/(m2 s)",
                description: "wavy/annular-intermittent boundary G_wavy(χ) = c0 + c1 χ + c2 χ^2 (simplified Wojtan): c0",
                /// `regime_wavy_c0`: constant term c0 of the stratified-wavy → annular/intermittent boundary
                /// G_wavy(χ) = c0 + c1 χ + c2 χ², kg/(m² s) ([`CryoParams::wavy_poly`]).
                field: wavy_c0,
            }
            "regime_wavy_c1" {
                group: "flow_regime",
                default: -830.0,
                lower: -3000.0,
                upper: 500.0,
                unit: "kg/(m2 s)",
                description: "wavy/annular-intermittent boundary G_wavy(χ): c1",
                /// `regime_wavy_c1`: linear coefficient c1 of G_wavy(χ).
                field: wavy_c1,
            }
            "regime_wavy_c2" {
                group: "flow_regime",
                default: 800.0,
                lower: -500.0,
                upper: 3000.0,
                unit: "kg/(m2 s)",
                description: "wavy/annular-intermittent boundary G_wavy(χ): c2",
                /// `regime_wavy_c2`: quadratic coefficient c2 of G_wavy(χ).
                field: wavy_c2,
            }
            "kutateladze_k" {
                group: "flow_regime",
                default: 0.131,
                lower: 0.05,
                upper: 0.3,
                unit: "-",
                description: "Kutateladze constant K of q_DNB normalising the wall heat flux of the dryout boundary",
                /// `kutateladze_k`: Kutateladze constant K of q_DNB in the dryout boundary.
                field: kutateladze_k,
            }
            "xmin" {
                group: "flow_regime",
                default: 0.9,
                lower: 0.5,
                upper: 0.999,
                unit: "-",
                description: "boundary quality of the dispersed-flow (mist) regime",
                /// `xmin`: quality above which the flow is dispersed (mist).
                field: x_mist,
            }
            "regime_width" {
                group: "flow_regime",
                default: 0.3,
                lower: 0.05,
                upper: 2.0,
                unit: "-",
                description: "width in ln G of the smooth transitions across the stratified and wavy boundaries",
                /// `regime_width`: width, in ln G, of the smooth transitions across G_strat and G_wavy.
                field: regime_width,
            }
            "fwsc" {
                group: "friction",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "overall scaling of the wall friction (Lockhart–Martinelli with RELAP5 partition; it scales a phase alone too, below 1 under Churchill's tube friction)",
                /// `fwsc`: scale of the wall friction. It multiplies the whole partitioned
                /// Lockhart–Martinelli gradient, so a phase alone (the gradient's limit as the other
                /// phase vanishes) is scaled too: below 1 that is less than Churchill's friction of
                /// the tube, and every run whose flow the friction limits speeds up (VALIDATION.md,
                /// "Both readings against the line's throughput").
                field: wall_friction_scale,
            }
            "chisholm_c" {
                group: "friction",
                default: 20.0,
                lower: 0.0,
                upper: 40.0,
                unit: "-",
                description: "Chisholm's C of the Lockhart–Martinelli two-phase multiplier",
                /// `chisholm_c`: Chisholm's C of the Lockhart–Martinelli multiplier.
                field: chisholm_c,
            }
            "Gisc" {
                group: "interface",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "overall scaling of the mass transfer at the interface Γ_ig",
                /// `Gisc`: scale of the interface mass transfer Γ_ig: **the scheme multiplies Γ_ig by it**.
                field: interface_mass_transfer_scale,
            }
            "hgisc" {
                group: "interface",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "overall scaling of the interphase heat transfer on the gas side",
                /// `hgisc`: scale of the gas-side interphase heat transfer.
                field: gas_interface_scale,
            }
            "hgi0esc" {
                group: "interface",
                default: 1.0,
                lower: 0.75,
                upper: 1.25,
                unit: "-",
                description: "scaling of the Dittus–Boelter Reynolds exponent on the gas side of the interface",
                /// `hgi0esc`: scale of the Dittus–Boelter Reynolds exponent on the gas side of the interface.
                field: gas_interface_exponent_scale,
            }
            "hli0esc" {
                group: "interface",
                default: 1.0,
                lower: 0.75,
                upper: 1.25,
                unit: "-",
                description: "scaling of the Dittus–Boelter Reynolds exponent on the liquid side of the interface",
                /// `hli0esc`: scale of the Dittus–Boelter Reynolds exponent on the liquid side of the interface.
                field: liquid_interface_exponent_scale,
            }
            "idrag_strat_sc" {
                group: "interface",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "scaling of the stratified and stratified-wavy interfacial drag",
                /// `idrag_strat_sc`: scale of the stratified and stratified-wavy interfacial drag.
                field: drag_stratified_scale,
            }
            "idrag_disp_sc" {
                group: "interface",
                default: 1.0,
                lower: 0.25,
                upper: 4.0,
                unit: "-",
                description: "scaling of the annular/intermittent and dispersed interfacial drag",
                /// `idrag_disp_sc`: scale of the annular/intermittent and dispersed interfacial drag.
                field: drag_dispersed_scale,
            }
            "drop_d_max" {
                group: "interface",
                default: 1.0e-3,
                lower: 2.5e-4,
                upper: 8.0e-3,
                unit: "m",
                description: "largest drop diameter of dispersed (mist) flow: bounds the Weber diameter 12 σ/(ρ_g v_r²)",
                /// `drop_d_max`: largest drop diameter of dispersed (mist) flow, m.
                field: drop_diameter_max,
            }
            "iloeje_x_floor" {
                group: "film_boiling",
                default: 0.05,
                lower: 0.01,
                upper: 0.5,
                unit: "-",
                description: "floor of the Iloeje quality factors 1 − c2 X^c3 of T_mfb and film boiling; where it binds, Xmfbsc, Xemfbsc, Xtmfbsc and Xetmfbsc have no effect",
                /// `iloeje_x_floor`: floor of the Iloeje quality factors (1 − c2 X^c3) of T_mfb and film
                /// boiling (Table 1's 1 − 1.04 X² is negative for X > 0.98).
                field: iloeje_x_floor,
            }
            "boil_gap_chf" {
                group: "transition_boiling",
                default: 0.5,
                lower: 0.1,
                upper: 5.0,
                unit: "K",
                description: "smallest T_chf − T_onb of the boiling curve; where it binds, Tchfsc has no effect",
                /// `boil_gap_chf`: smallest T_chf − T_onb, K.
                field: boil_gap_chf,
            }
            "boil_gap_mfb" {
                group: "transition_boiling",
                default: 1.0,
                lower: 0.1,
                upper: 10.0,
                unit: "K",
                description: "smallest T_mfb − T_chf of the boiling curve; where it binds, Tmfbsc (or the rewet temperature) has no effect",
                /// `boil_gap_mfb`: smallest T_mfb − T_chf, K.
                field: boil_gap_mfb,
            }
            "chf_over_mfb" {
                group: "chf",
                default: 1.0,
                lower: 1.0,
                upper: 3.0,
                unit: "-",
                description: "smallest q_chf / max(q_onb, q_mfb) of the boiling curve; where it binds, qchfsc and the CHF shape have no effect",
                /// `chf_over_mfb`: smallest q_chf / max(q_onb, q_mfb).
                field: chf_over_mfb,
            }
            "flash_void_min" {
                group: "interface",
                default: 1.0e-5,
                lower: 1.0e-7,
                upper: 1.0e-3,
                unit: "-",
                description: "smallest void fraction of the bubbles on which superheated liquid flashes (nuclei of a liquid-filled cell; RELAP5's 10⁻⁵)",
                /// `flash_void_min`: smallest void fraction of the bubbles on which superheated liquid
                /// flashes.
                field: flash_void_min,
            }
            "drop_contact_k" {
                group: "film_boiling",
                default: 0.2552,
                lower: 0.0,
                upper: 1.0,
                unit: "-",
                description: "constant of the drop–wall contact heat transfer of dispersed-flow film boiling (Forslund–Rohsenow; 0 turns it off)",
                /// `drop_contact_k`: constant of the Forslund–Rohsenow drop–wall contact coefficient.
                field: drop_contact_k,
            }
            "hg_drop_gain" {
                group: "film_boiling",
                default: 0.0,
                lower: 0.0,
                upper: 10.0,
                unit: "-",
                description: "enhancement of the vapour's wall convection by the drops of a dispersed flow: the factor 1 + hg_drop_gain w_dry ε/(ε + hg_drop_eps), ε the liquid fraction (0 turns it off)",
                /// `hg_drop_gain`: largest enhancement of the vapour's wall convection by the drops of a
                /// dispersed flow (0: none).
                field: gas_wall_drop_gain,
            }
            "hg_drop_eps" {
                group: "film_boiling",
                default: 1.0e-3,
                lower: 1.0e-5,
                upper: 0.1,
                unit: "-",
                description: "liquid fraction at which the drops' enhancement of the vapour's wall convection is half of hg_drop_gain",
                /// `hg_drop_eps`: liquid fraction of half the drops' enhancement.
                field: gas_wall_drop_fraction,
            }
        }
    };
}
pub(crate) use parameter_table;

/// [`REGISTRY`] from [`parameter_table`].
macro_rules! registry_entries {
    ($(
        $name:literal {
            group: $group:literal,
            default: $default:expr,
            lower: $lower:expr,
            upper: $upper:expr,
            unit: $unit:literal,
            description: $description:literal,
            $(#[$doc:meta])*
            field: $field:tt,
        }
    )*) => {
        &[$(ParamSpec {
            name: $name,
            group: $group,
            default: $default,
            lower: $lower,
            upper: $upper,
            unit: $unit,
            description: $description,
        }),*]
    };
}

/// The registry.
pub const REGISTRY: &[ParamSpec] = parameter_table!(registry_entries);

/// The registry entry of `name`.
pub fn spec(name: &str) -> Option<&'static ParamSpec> {
    REGISTRY.iter().find(|p| p.name == name)
}

/// A bad parameter name or value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParamError {
    /// Not in the registry.
    #[error("unknown parameter '{name}'{}; `cryofit params` lists them", suggestion.map(|s| format!(" (did you mean '{s}'?)")).unwrap_or_default())]
    Unknown {
        /// The name given.
        name: String,
        /// The closest registry name, if any is close.
        suggestion: Option<&'static str>,
    },
    /// Outside the registry bounds.
    #[error("parameter {name} = {value} is outside its bounds [{lower}, {upper}] {unit}")]
    OutOfBounds {
        /// Name.
        name: String,
        /// Value given.
        value: f64,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
        /// Unit.
        unit: &'static str,
    },
}

/// Values for some registry parameters; the rest take their defaults.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ParameterSet {
    values: BTreeMap<String, f64>,
}

impl ParameterSet {
    /// An empty set: every parameter at its default.
    pub fn new() -> Self {
        Self::default()
    }

    /// Sets `name` to `value` after checking the name and the bounds.
    pub fn set(&mut self, name: &str, value: f64) -> Result<(), ParamError> {
        let Some(p) = spec(name) else {
            return Err(ParamError::Unknown { name: name.to_string(), suggestion: closest(name) });
        };
        if !(value.is_finite() && value >= p.lower && value <= p.upper) {
            return Err(ParamError::OutOfBounds {
                name: name.to_string(),
                value,
                lower: p.lower,
                upper: p.upper,
                unit: p.unit,
            });
        }
        self.values.insert(name.to_string(), value);
        Ok(())
    }

    /// Applies every value of `other` on top of this set.
    pub fn overlay(&mut self, other: &ParameterSet) {
        for (k, v) in &other.values {
            self.values.insert(k.clone(), *v);
        }
    }

    /// The value of `name`: set, or the registry default; a name not in the registry is an
    /// error that suggests the closest name.
    pub fn try_get(&self, name: &str) -> Result<f64, ParamError> {
        match self.values.get(name) {
            Some(v) => Ok(*v),
            None => spec(name)
                .map(|p| p.default)
                .ok_or_else(|| ParamError::Unknown { name: name.to_string(), suggestion: closest(name) }),
        }
    }

    /// The value of a registered `name`, for this crate's closures, which read the registry by
    /// literal names (`cryo::CryoParams::from_set`, `driver::physics_of`); a test reads every one
    /// of them. Panics on a name not in the registry: outside this crate, use
    /// [`ParameterSet::try_get`].
    pub(crate) fn get(&self, name: &str) -> f64 {
        match self.try_get(name) {
            Ok(v) => v,
            Err(e) => panic!("{e}"),
        }
    }

    /// The explicitly set values.
    pub fn explicit(&self) -> &BTreeMap<String, f64> {
        &self.values
    }
}

/// The registry name closest to `name` (edit distance ≤ 3), for error messages.
pub fn closest(name: &str) -> Option<&'static str> {
    let lower = name.to_ascii_lowercase();
    REGISTRY
        .iter()
        .map(|p| (edit_distance(&lower, &p.name.to_ascii_lowercase()), p.name))
        .filter(|(d, _)| *d <= 3)
        .min()
        .map(|(_, n)| n)
}

/// Levenshtein distance between `a` and `b`, in characters.
pub(crate) fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j + 1] + 1).min(cur[j] + 1).min(prev[j] + usize::from(ca != *cb));
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registry_is_consistent() {
        let mut names = std::collections::HashSet::new();
        for p in REGISTRY {
            assert!(names.insert(p.name), "duplicate {}", p.name);
            assert!(p.lower <= p.default && p.default <= p.upper, "{} default outside bounds", p.name);
            assert!(!p.description.is_empty() && !p.unit.is_empty());
        }
    }

    #[test]
    fn multiplicative_scales_span_a_factor_four() {
        // (the exponent scales, `…esc`, are bounded by the Reynolds numbers of the line instead:
        // see `cryo::scaled_dittus_boelter`)
        let scales: Vec<&ParamSpec> =
            REGISTRY.iter().filter(|p| p.name.ends_with("sc") && !p.name.ends_with("esc")).collect();
        assert!(scales.len() >= 20, "{}", scales.len());
        for p in scales {
            assert!(p.default > 0.0, "{}", p.name);
            assert!(p.lower <= p.default / 4.0 * (1.0 + 1e-12), "{}: lower {} > default/4", p.name, p.lower);
            assert!(p.upper >= p.default * 4.0 * (1.0 - 1e-12), "{}: upper {} < 4 default", p.name, p.upper);
            assert!(p.lower > 0.0, "{}: a scale stays positive", p.name);
        }
    }

    #[test]
    fn temperature_scales_cover_the_calibration_range() {
        for name in ["Tchfsc", "Tmfbsc"] {
            let p = spec(name).unwrap();
            assert!(p.lower <= 0.7 && p.upper >= 1.7, "{name} [{}, {}]", p.lower, p.upper);
        }
        assert!(spec("Tmfbsc").unwrap().upper >= 2.2);
    }

    #[test]
    fn paper_parameters_are_registered_with_table_1_defaults() {
        let want = [
            ("Tmfbsc", 1.25),
            ("Gtmfbsc", 0.2),
            ("Etmfbsc", 0.165),
            ("Xetmfbsc", 2.0),
            ("Xtmfbsc", 1.04),
            ("qmfbsc", 2.0),
            ("Xmfbsc", 1.04),
            ("Xemfbsc", 2.0),
            ("Gmfbsc", 0.2),
            ("Emfbsc", 0.1),
            ("qchfsc", 1.0),
            ("chf_alpha_cr", 0.96),
            ("chf_void_exp", 2.0),
            ("chf_g_coeff", 0.16),
            ("chf_g_exp", 0.2),
        ];
        for (name, default) in want {
            assert_eq!(spec(name).unwrap_or_else(|| panic!("{name}")).default, default, "{name}");
        }
        for name in ["Gwsc", "Gisc", "tauw", "hgi0esc", "hli0esc", "hg0esc", "hg0sc", "hgisc", "Tchfsc", "xmin"] {
            assert!(spec(name).is_some(), "{name}");
        }
        // the five basic entries are kept
        for (name, default) in [("vm_coeff", 0.5), ("hi_vol", 1.0e5), ("blend_xmin", 1.0e-7), ("blend_xmax", 1.0e-2)] {
            assert_eq!(spec(name).unwrap().default, default, "{name}");
        }
        let groups = [
            "onb",
            "chf",
            "film_boiling",
            "transition_boiling",
            "convection",
            "flow_regime",
            "friction",
            "interface",
            "numerics",
        ];
        for p in REGISTRY {
            assert!(groups.contains(&p.group), "{}: group {}", p.name, p.group);
            assert!(!p.description.contains('\n'), "{}", p.name);
        }
        assert!((45..=60).contains(&REGISTRY.len()), "{}", REGISTRY.len());
    }

    #[test]
    fn set_checks_names_and_bounds() {
        let mut s = ParameterSet::new();
        assert_eq!(s.get("vm_coeff"), 0.5);
        s.set("vm_coeff", 1.0).unwrap();
        assert_eq!(s.get("vm_coeff"), 1.0);
        let e = s.set("vm_coef", 1.0).unwrap_err().to_string();
        assert!(e.contains("vm_coef") && e.contains("did you mean 'vm_coeff'"), "{e}");
        let e = s.set("vm_coeff", 50.0).unwrap_err().to_string();
        assert!(e.contains("outside its bounds"), "{e}");
        assert!(s.set("vm_coeff", f64::NAN).is_err());
    }

    #[test]
    fn try_get_reads_set_values_and_defaults_and_refuses_unknown_names() {
        let mut s = ParameterSet::new();
        assert_eq!(s.try_get("vm_coeff"), Ok(0.5));
        s.set("vm_coeff", 1.0).unwrap();
        assert_eq!(s.try_get("vm_coeff"), Ok(1.0));
        assert_eq!(
            s.try_get("vm_coef"),
            Err(ParamError::Unknown { name: "vm_coef".into(), suggestion: Some("vm_coeff") })
        );
        // every name the crate's closures read with `get` is registered (these would panic)
        let _ = crate::cryo::CryoParams::from_set(&s);
        assert_eq!(s.get("hi_vol"), 1.0e5);
    }
}
