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

/// The registry.
pub const REGISTRY: &[ParamSpec] = &[
    ParamSpec {
        name: "vm_coeff",
        group: "interface",
        default: 0.5,
        lower: 0.0,
        upper: 5.0,
        unit: "-",
        description: "virtual-mass coefficient C in C α β ρ_m ∂(u_g − u_l)/∂t",
    },
    ParamSpec {
        name: "hi_vol",
        group: "interface",
        default: 1.0e5,
        lower: 0.0,
        upper: 1.0e9,
        unit: "W/(m3 K)",
        description: "volumetric interphase heat transfer coefficient scale, times α β",
    },
    ParamSpec {
        name: "blend_xmin",
        group: "numerics",
        default: 1.0e-7,
        lower: 1.0e-12,
        upper: 1.0e-4,
        unit: "-",
        description: "phase blending: below this fraction a phase is treated as absent",
    },
    ParamSpec {
        name: "blend_xmax",
        group: "numerics",
        default: 1.0e-2,
        lower: 1.0e-4,
        upper: 0.2,
        unit: "-",
        description: "phase blending: above this fraction a phase is fully present",
    },
    ParamSpec {
        name: "Tonbsc",
        group: "onb",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "scale of the ONB wall superheat T_onb − T_s (eq:T_onb, Sato–Matsumura/Frost–Dzakowic)",
    },
    ParamSpec {
        name: "nb_exp",
        group: "onb",
        default: 2.0,
        lower: 1.0,
        upper: 5.0,
        unit: "-",
        description: "exponent n of the nucleate-boiling interpolation q_onb + (q_chf − q_onb) y^n (eq:q_nb_int)",
    },
    ParamSpec {
        name: "qchfsc",
        group: "chf",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "overall scale of the critical heat flux (a1 of eq:Iloeje_chf, also applied to the Griffith form)",
    },
    ParamSpec {
        name: "chf_alpha_cr",
        group: "chf",
        default: 0.96,
        lower: 0.5,
        upper: 1.0,
        unit: "-",
        description: "critical void fraction α_cr of the CHF void factor (α_cr − α)",
    },
    ParamSpec {
        name: "chf_void_exp",
        group: "chf",
        default: 2.0,
        lower: 0.5,
        upper: 4.0,
        unit: "-",
        description: "exponent a2 of (α_cr − α) in the simplified CHF (eq:Iloeje_chf)",
    },
    ParamSpec {
        name: "chf_g_coeff",
        group: "chf",
        default: 0.16,
        lower: 0.0,
        upper: 1.0,
        unit: "-",
        description: "mass-flux coefficient a3 of the simplified CHF (1 + a3 G^a4), G in kg/(m2 s)",
    },
    ParamSpec {
        name: "chf_g_exp",
        group: "chf",
        default: 0.2,
        lower: 0.0,
        upper: 0.6,
        unit: "-",
        description: "mass-flux exponent a4 of the simplified CHF (the paper prints a5 in the exponent)",
    },
    ParamSpec {
        name: "chf_griffith",
        group: "chf",
        default: 0.0,
        lower: 0.0,
        upper: 1.0,
        unit: "-",
        description: "weight of the Griffith-type CHF (eq:Griffith_chf) against the simplified Iloeje-type form",
    },
    ParamSpec {
        name: "Tchfsc",
        group: "chf",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "scale of the CHF wall superheat T_chf − T_s from Theler's T_chf (eq:theler)",
    },
    ParamSpec {
        name: "qmfbsc",
        group: "film_boiling",
        default: 2.0,
        lower: 0.5,
        upper: 8.0,
        unit: "-",
        description: "c1 of eq:Iloeje_hfb: scaling coefficient of the film-boiling heat transfer (Bromley)",
    },
    ParamSpec {
        name: "Xmfbsc",
        group: "film_boiling",
        default: 1.04,
        lower: 0.26,
        upper: 4.16,
        unit: "-",
        description: "c2 of eq:Iloeje_hfb: coefficient of the quality term (1 − c2 X_e^c3)",
    },
    ParamSpec {
        name: "Xemfbsc",
        group: "film_boiling",
        default: 2.0,
        lower: 0.5,
        upper: 8.0,
        unit: "-",
        description: "c3 of eq:Iloeje_hfb: exponent of the equilibrium quality X_e",
    },
    ParamSpec {
        name: "Gmfbsc",
        group: "film_boiling",
        default: 0.2,
        lower: 0.05,
        upper: 0.8,
        unit: "-",
        description: "c4 of eq:Iloeje_hfb: scaling of the liquid mass flux term (1 + c4 G^c5)",
    },
    ParamSpec {
        name: "Emfbsc",
        group: "film_boiling",
        default: 0.1,
        lower: 0.025,
        upper: 0.4,
        unit: "-",
        description: "c5 of eq:Iloeje_hfb: exponent of the liquid mass flux",
    },
    ParamSpec {
        name: "Tmfbsc",
        group: "film_boiling",
        default: 1.25,
        lower: 0.3125,
        upper: 5.0,
        unit: "-",
        description: "c1 of eq:Iloeje: overall scaling of the minimum film boiling superheat (Berenson)",
    },
    ParamSpec {
        name: "Gtmfbsc",
        group: "film_boiling",
        default: 0.2,
        lower: 0.05,
        upper: 0.8,
        unit: "-",
        description: "c4 of eq:Iloeje: scaling of the liquid mass flux term of T_mfb",
    },
    ParamSpec {
        name: "Etmfbsc",
        group: "film_boiling",
        default: 0.165,
        lower: 0.04125,
        upper: 0.66,
        unit: "-",
        description: "c5 of eq:Iloeje: exponent of the liquid mass flux of T_mfb",
    },
    ParamSpec {
        name: "Xetmfbsc",
        group: "film_boiling",
        default: 2.0,
        lower: 0.5,
        upper: 8.0,
        unit: "-",
        description: "c3 of eq:Iloeje: exponent of the quality X_e of T_mfb (Table 1 labels it scaling: swapped)",
    },
    ParamSpec {
        name: "Xtmfbsc",
        group: "film_boiling",
        default: 1.04,
        lower: 0.26,
        upper: 4.16,
        unit: "-",
        description: "c2 of eq:Iloeje: scaling of the quality term of T_mfb (Table 1 labels it exponent: swapped)",
    },
    ParamSpec {
        name: "hmirosc",
        group: "film_boiling",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "scale of the Miropolskii film-boiling coefficient (correlation set miropolskii)",
    },
    ParamSpec {
        name: "dh_we_coeff",
        group: "film_boiling",
        default: 0.06,
        lower: 0.0,
        upper: 0.3,
        unit: "-",
        description: "Darr–Hartwig rewet temperature (27/32) T_cr (1 + b We_D^e): Weber coefficient b (set miropolskii)",
    },
    ParamSpec {
        name: "dh_we_exp",
        group: "film_boiling",
        default: 0.208,
        lower: 0.05,
        upper: 0.5,
        unit: "-",
        description: "Darr–Hartwig rewet temperature: Weber exponent e, We_D = G^2 D/(ρ_l σ) (set miropolskii)",
    },
    ParamSpec {
        name: "hg0sc",
        group: "convection",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "overall scaling of the gas heat transfer to the dry wall (also after dryout)",
    },
    ParamSpec {
        name: "hg0esc",
        group: "convection",
        default: 1.0,
        lower: 0.75,
        upper: 1.25,
        unit: "-",
        description: "scaling of the Dittus–Boelter Reynolds exponent 0.8 of the gas at the dry wall (bounds: exponents 0.6–1.0)",
    },
    ParamSpec {
        name: "hl0sc",
        group: "convection",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "scaling of the single-phase liquid convection to the wetted wall (eq:convection_Nu)",
    },
    ParamSpec {
        name: "Gwsc",
        group: "convection",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "overall scaling of the mass transfer at the wetted wall Γ_wg",
    },
    ParamSpec {
        name: "tauw",
        group: "convection",
        default: 1.0,
        lower: 0.01,
        upper: 100.0,
        unit: "s",
        description: "characteristic time of the heat transfer to the wall: relaxation time of the wetted fraction",
    },
    ParamSpec {
        name: "regime_strat_c0",
        group: "flow_regime",
        default: 50.0,
        lower: 0.0,
        upper: 200.0,
        unit: "kg/(m2 s)",
        description: "stratified/wavy boundary G_strat(χ) = c0 + c1 χ + c2 χ^2 (simplified Wojtan): c0",
    },
    ParamSpec {
        name: "regime_strat_c1",
        group: "flow_regime",
        default: -95.0,
        lower: -400.0,
        upper: 100.0,
        unit: "kg/(m2 s)",
        description: "stratified/wavy boundary G_strat(χ): c1",
    },
    ParamSpec {
        name: "regime_strat_c2",
        group: "flow_regime",
        default: 80.0,
        lower: -100.0,
        upper: 400.0,
        unit: "kg/(m2 s)",
        description: "stratified/wavy boundary G_strat(χ): c2",
    },
    ParamSpec {
        name: "regime_wavy_c0",
        group: "flow_regime",
        default: 300.0,
        lower: 0.0,
        upper: 1200.0,
        unit: "kg/(m2 s)",
        description: "wavy/annular-intermittent boundary G_wavy(χ) = c0 + c1 χ + c2 χ^2 (simplified Wojtan): c0",
    },
    ParamSpec {
        name: "regime_wavy_c1",
        group: "flow_regime",
        default: -830.0,
        lower: -3000.0,
        upper: 500.0,
        unit: "kg/(m2 s)",
        description: "wavy/annular-intermittent boundary G_wavy(χ): c1",
    },
    ParamSpec {
        name: "regime_wavy_c2",
        group: "flow_regime",
        default: 800.0,
        lower: -500.0,
        upper: 3000.0,
        unit: "kg/(m2 s)",
        description: "wavy/annular-intermittent boundary G_wavy(χ): c2",
    },
    ParamSpec {
        name: "kutateladze_k",
        group: "flow_regime",
        default: 0.131,
        lower: 0.05,
        upper: 0.3,
        unit: "-",
        description: "Kutateladze constant K of q_DNB normalising the wall heat flux of the dryout boundary",
    },
    ParamSpec {
        name: "xmin",
        group: "flow_regime",
        default: 0.9,
        lower: 0.5,
        upper: 0.999,
        unit: "-",
        description: "boundary quality of the dispersed-flow (mist) regime",
    },
    ParamSpec {
        name: "regime_width",
        group: "flow_regime",
        default: 0.3,
        lower: 0.05,
        upper: 2.0,
        unit: "-",
        description: "width in ln G of the smooth transitions across the stratified and wavy boundaries",
    },
    ParamSpec {
        name: "fwsc",
        group: "friction",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "overall scaling of the two-phase wall friction (Lockhart–Martinelli with RELAP5 partition)",
    },
    ParamSpec {
        name: "chisholm_c",
        group: "friction",
        default: 20.0,
        lower: 0.0,
        upper: 40.0,
        unit: "-",
        description: "Chisholm's C of the Lockhart–Martinelli two-phase multiplier",
    },
    ParamSpec {
        name: "Gisc",
        group: "interface",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "overall scaling of the mass transfer at the interface Γ_ig",
    },
    ParamSpec {
        name: "hgisc",
        group: "interface",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "overall scaling of the interphase heat transfer on the gas side",
    },
    ParamSpec {
        name: "hgi0esc",
        group: "interface",
        default: 1.0,
        lower: 0.75,
        upper: 1.25,
        unit: "-",
        description: "scaling of the Dittus–Boelter Reynolds exponent on the gas side of the interface",
    },
    ParamSpec {
        name: "hli0esc",
        group: "interface",
        default: 1.0,
        lower: 0.75,
        upper: 1.25,
        unit: "-",
        description: "scaling of the Dittus–Boelter Reynolds exponent on the liquid side of the interface",
    },
    ParamSpec {
        name: "idrag_strat_sc",
        group: "interface",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "scaling of the stratified and stratified-wavy interfacial drag",
    },
    ParamSpec {
        name: "idrag_disp_sc",
        group: "interface",
        default: 1.0,
        lower: 0.25,
        upper: 4.0,
        unit: "-",
        description: "scaling of the annular/intermittent and dispersed interfacial drag",
    },
    ParamSpec {
        name: "drop_d_max",
        group: "interface",
        default: 1.0e-3,
        lower: 2.5e-4,
        upper: 8.0e-3,
        unit: "m",
        description: "largest drop diameter of dispersed (mist) flow: bounds the Weber diameter 12 σ/(ρ_g v_r²)",
    },
    ParamSpec {
        name: "iloeje_x_floor",
        group: "film_boiling",
        default: 0.05,
        lower: 0.01,
        upper: 0.5,
        unit: "-",
        description: "floor of the Iloeje quality factors 1 − c2 X^c3 of T_mfb and film boiling; where it binds, Xmfbsc, Xemfbsc, Xtmfbsc and Xetmfbsc have no effect",
    },
    ParamSpec {
        name: "boil_gap_chf",
        group: "transition_boiling",
        default: 0.5,
        lower: 0.1,
        upper: 5.0,
        unit: "K",
        description: "smallest T_chf − T_onb of the boiling curve; where it binds, Tchfsc has no effect",
    },
    ParamSpec {
        name: "boil_gap_mfb",
        group: "transition_boiling",
        default: 1.0,
        lower: 0.1,
        upper: 10.0,
        unit: "K",
        description: "smallest T_mfb − T_chf of the boiling curve; where it binds, Tmfbsc (or the rewet temperature) has no effect",
    },
    ParamSpec {
        name: "chf_over_mfb",
        group: "chf",
        default: 1.0,
        lower: 1.0,
        upper: 3.0,
        unit: "-",
        description: "smallest q_chf / max(q_onb, q_mfb) of the boiling curve; where it binds, qchfsc and the CHF shape have no effect",
    },
    ParamSpec {
        name: "flash_void_min",
        group: "interface",
        default: 1.0e-5,
        lower: 1.0e-7,
        upper: 1.0e-3,
        unit: "-",
        description: "smallest void fraction of the bubbles on which superheated liquid flashes (nuclei of a liquid-filled cell; RELAP5's 10⁻⁵)",
    },
    ParamSpec {
        name: "drop_contact_k",
        group: "film_boiling",
        default: 0.2552,
        lower: 0.0,
        upper: 1.0,
        unit: "-",
        description: "constant of the drop–wall contact heat transfer of dispersed-flow film boiling (Forslund–Rohsenow; 0 turns it off)",
    },
];

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

fn edit_distance(a: &str, b: &str) -> usize {
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
