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
        name: "drag_coeff",
        group: "interface",
        default: 1.0,
        lower: 0.0,
        upper: 100.0,
        unit: "-",
        description: "interfacial drag scale: F_i = c α β ρ_m |u_g − u_l| / D_h",
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

    /// The value of `name`: set, or the registry default. Panics on a name not in the
    /// registry (a programming error: closures only ask for registered names).
    pub fn get(&self, name: &str) -> f64 {
        match self.values.get(name) {
            Some(v) => *v,
            None => spec(name).unwrap_or_else(|| panic!("parameter '{name}' is not in the registry")).default,
        }
    }

    /// The explicitly set values.
    pub fn explicit(&self) -> &BTreeMap<String, f64> {
        &self.values
    }
}

/// The registry name closest to `name` (edit distance ≤ 3), for error messages.
fn closest(name: &str) -> Option<&'static str> {
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
}
