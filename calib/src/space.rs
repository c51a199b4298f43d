//! Free-parameter spaces: bounds, linear or logarithmic scale, and the map to unit coordinates.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// How a parameter is mapped to its unit coordinate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "lowercase"))]
pub enum Scale {
    /// `u = (x − lower)/(upper − lower)`.
    #[default]
    Linear,
    /// `u = ln(x/lower)/ln(upper/lower)`; needs `0 < lower`.
    Log,
}

/// One free parameter of a calibration.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct FreeParameter {
    pub name: String,
    pub lower: f64,
    pub upper: f64,
    pub scale: Scale,
}

/// Why a space could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpaceError {
    #[error("parameter `{name}`: bounds must be finite with lower < upper (got lower = {lower}, upper = {upper})")]
    Bounds { name: String, lower: f64, upper: f64 },
    #[error("parameter `{name}`: scale \"log\" needs lower > 0 (got lower = {lower}); use scale = \"linear\"")]
    LogNonPositive { name: String, lower: f64 },
    #[error("parameter `{name}` is listed twice")]
    Duplicate { name: String },
    #[error("no free parameters")]
    Empty,
}

/// An ordered set of free parameters.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Space {
    params: Vec<FreeParameter>,
}

impl Space {
    /// Checks bounds and scales.
    pub fn new(params: Vec<FreeParameter>) -> Result<Self, SpaceError> {
        if params.is_empty() {
            return Err(SpaceError::Empty);
        }
        for (i, p) in params.iter().enumerate() {
            if !(p.lower.is_finite() && p.upper.is_finite() && p.lower < p.upper) {
                return Err(SpaceError::Bounds { name: p.name.clone(), lower: p.lower, upper: p.upper });
            }
            if p.scale == Scale::Log && p.lower <= 0.0 {
                return Err(SpaceError::LogNonPositive { name: p.name.clone(), lower: p.lower });
            }
            if params[..i].iter().any(|q| q.name == p.name) {
                return Err(SpaceError::Duplicate { name: p.name.clone() });
            }
        }
        Ok(Self { params })
    }

    pub fn dim(&self) -> usize {
        self.params.len()
    }

    pub fn params(&self) -> &[FreeParameter] {
        &self.params
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.params.iter().map(|p| p.name.as_str())
    }

    /// The space of the parameters `names`, in that order (a stage's free set after a screening
    /// stage, say); `None` when a name is not in this space.
    pub fn select<S: AsRef<str>>(&self, names: &[S]) -> Option<Space> {
        let params: Option<Vec<FreeParameter>> =
            names.iter().map(|n| self.params.iter().find(|p| p.name == n.as_ref()).cloned()).collect();
        Space::new(params?).ok()
    }

    /// Physical value of parameter `i` at unit coordinate `u` (clamped to `[0, 1]`).
    pub fn value(&self, i: usize, u: f64) -> f64 {
        let p = &self.params[i];
        let u = u.clamp(0.0, 1.0);
        let x = match p.scale {
            Scale::Linear => p.lower + u * (p.upper - p.lower),
            Scale::Log => p.lower * (p.upper / p.lower).powf(u),
        };
        x.clamp(p.lower, p.upper)
    }

    /// Unit coordinate of parameter `i` at physical value `x` (clamped to the bounds).
    pub fn unit(&self, i: usize, x: f64) -> f64 {
        let p = &self.params[i];
        let x = x.clamp(p.lower, p.upper);
        let u = match p.scale {
            Scale::Linear => (x - p.lower) / (p.upper - p.lower),
            Scale::Log => (x / p.lower).ln() / (p.upper / p.lower).ln(),
        };
        u.clamp(0.0, 1.0)
    }

    /// `dx/du` of parameter `i` at unit coordinate `u`: converts unit-coordinate spreads to physical ones.
    pub fn jacobian(&self, i: usize, u: f64) -> f64 {
        let p = &self.params[i];
        match p.scale {
            Scale::Linear => p.upper - p.lower,
            Scale::Log => self.value(i, u) * (p.upper / p.lower).ln(),
        }
    }

    /// Physical values of a unit point.
    pub fn to_physical(&self, unit: &[f64]) -> Vec<f64> {
        unit.iter().enumerate().map(|(i, &u)| self.value(i, u)).collect()
    }

    /// Unit coordinates of a physical point.
    pub fn to_unit(&self, physical: &[f64]) -> Vec<f64> {
        physical.iter().enumerate().map(|(i, &x)| self.unit(i, x)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(name: &str, lower: f64, upper: f64, scale: Scale) -> FreeParameter {
        FreeParameter { name: name.into(), lower, upper, scale }
    }

    #[test]
    fn a_selection_keeps_the_named_parameters_in_the_given_order() {
        let s = Space::new(vec![p("a", -1.0, 3.0, Scale::Linear), p("b", 0.25, 4.0, Scale::Log)]).unwrap();
        let t = s.select(&["b", "a"]).unwrap();
        assert_eq!(t.params(), [s.params()[1].clone(), s.params()[0].clone()]);
        assert_eq!(s.select(&["b", "c"]), None);
        assert_eq!(s.select(&["a", "a"]), None);
    }

    #[test]
    fn round_trip_linear_and_log() {
        let s = Space::new(vec![p("a", -1.0, 3.0, Scale::Linear), p("b", 0.25, 4.0, Scale::Log)]).unwrap();
        assert_eq!(s.to_physical(&[0.5, 0.5]), vec![1.0, 1.0]);
        let u = s.to_unit(&[2.0, 2.0]);
        assert!((u[0] - 0.75).abs() < 1e-15 && (u[1] - 0.75).abs() < 1e-15);
        assert!((s.jacobian(1, 0.5) - 16f64.ln()).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_bounds() {
        assert!(matches!(Space::new(vec![p("a", 1.0, 1.0, Scale::Linear)]), Err(SpaceError::Bounds { .. })));
        assert!(matches!(Space::new(vec![p("a", 0.0, 1.0, Scale::Log)]), Err(SpaceError::LogNonPositive { .. })));
        assert!(matches!(Space::new(vec![p("a", f64::NAN, 1.0, Scale::Linear)]), Err(SpaceError::Bounds { .. })));
        let dup = vec![p("a", 0.0, 1.0, Scale::Linear), p("a", 0.0, 2.0, Scale::Linear)];
        assert!(matches!(Space::new(dup), Err(SpaceError::Duplicate { .. })));
    }
}
