//! The calibration file (TOML) and its JSON twin (the body of `POST /calibrations`).
//!
//! ```toml
//! name = "NBS subcooled"
//! seed = 11
//! [[experiments]]            # one or more; paths relative to this file or absolute
//! case = "subcooled-4.2atm.toml"
//! data = "subcooled-4.2atm-data.csv"
//! [[parameters]]             # the free parameters; bounds default to the registry's
//! name = "Gwsc"
//! lower = 0.3
//! upper = 3.0
//! scale = "log"              # or "linear" (default)
//! [fixed]                    # other parameters held at given values (default: registry)
//! tauw = 2.0
//! [weights]                  # per quantity: η and σ
//! wall_temperature_k = { weight = 1.0, sigma = 1.0 }
//! [[stages]]                 # in order
//! algorithm = "cmaes"
//! budget = 500
//! ```
//!
//! Parsing checks everything that can be checked without reading other files: unknown fields,
//! parameter names (with the closest registry name suggested), bounds inside the registry's,
//! stage options that apply to the stage's algorithm. Errors name the file and the field.

use std::collections::BTreeMap;

use cryofit_solver::params;
use serde::{Deserialize, Serialize};

use crate::cost::Weight;
use crate::space::{FreeParameter, Scale, Space};

/// One experiment: a case and its measured data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentRef {
    /// Case file path (relative to the calibration file or absolute).
    pub case: String,
    /// Data file path (long-format CSV).
    pub data: String,
    /// Name used in reports; defaults to the case file's stem.
    #[serde(default)]
    pub name: Option<String>,
}

/// One free parameter as written in the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    pub name: String,
    #[serde(default)]
    pub lower: Option<f64>,
    #[serde(default)]
    pub upper: Option<f64>,
    #[serde(default)]
    pub scale: Option<ScaleName>,
}

/// `scale = "linear" | "log"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScaleName {
    Linear,
    Log,
}

/// The algorithms a stage can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, PartialOrd, Ord, Hash)]
#[serde(rename_all = "kebab-case")]
pub enum AlgorithmName {
    Sensitivity,
    Morris,
    DirectSearch,
    Pattern,
    Annealing,
    Genetic,
    Swarm,
    Cmaes,
    NelderMead,
    Variance,
    Mcmc,
}

impl AlgorithmName {
    pub fn as_str(self) -> &'static str {
        match self {
            AlgorithmName::Sensitivity => "sensitivity",
            AlgorithmName::Morris => "morris",
            AlgorithmName::DirectSearch => "direct-search",
            AlgorithmName::Pattern => "pattern",
            AlgorithmName::Annealing => "annealing",
            AlgorithmName::Genetic => "genetic",
            AlgorithmName::Swarm => "swarm",
            AlgorithmName::Cmaes => "cmaes",
            AlgorithmName::NelderMead => "nelder-mead",
            AlgorithmName::Variance => "variance",
            AlgorithmName::Mcmc => "mcmc",
        }
    }

    /// The stage options that apply to this algorithm (besides `algorithm`, `budget`, `tolerance`).
    pub fn options(self) -> &'static [&'static str] {
        match self {
            AlgorithmName::Sensitivity => &["step", "keep", "threshold"],
            AlgorithmName::Morris => &["trajectories", "levels", "keep", "threshold"],
            AlgorithmName::DirectSearch => &["points", "span"],
            AlgorithmName::Pattern => &["step"],
            AlgorithmName::Annealing => &["step", "population"],
            AlgorithmName::Genetic => &["population", "mutation"],
            AlgorithmName::Swarm => &["population"],
            AlgorithmName::Cmaes => &["population", "sigma", "stall_generations"],
            AlgorithmName::NelderMead => &["step"],
            AlgorithmName::Variance => &["restarts", "step"],
            AlgorithmName::Mcmc => &["walkers", "burn_in", "spread"],
        }
    }
}

impl std::fmt::Display for AlgorithmName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One stage of the pipeline. Options that do not apply to the algorithm are errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    pub algorithm: AlgorithmName,
    /// Evaluations; the stage runs exactly this many unless a `tolerance` ends it earlier.
    pub budget: usize,
    /// Stop tolerance (meaning depends on the algorithm); absent: run the whole budget.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Population / swarm / generation size.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub population: Option<usize>,
    /// Initial step size in unit coordinates (CMA-ES).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// CMA-ES: also stop when the best cost has fallen by less than `tolerance` over this many
    /// generations (a stall stop, for costs that jitter between nearby points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stall_generations: Option<usize>,
    /// Step: relative perturbation (sensitivity), unit-coordinate step (pattern, annealing,
    /// Nelder–Mead simplex size), finite-difference step (variance).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step: Option<f64>,
    /// Sensitivity/Morris: keep at most this many parameters free for the following stages.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub keep: Option<usize>,
    /// Sensitivity/Morris: keep parameters whose sensitivity is at least this fraction of the largest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threshold: Option<f64>,
    /// Morris: number of trajectories.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trajectories: Option<usize>,
    /// Morris: grid levels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub levels: Option<usize>,
    /// Direct search: grid points per coordinate scan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub points: Option<usize>,
    /// Direct search: initial span of a scan in unit coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub span: Option<f64>,
    /// Genetic: mutation probability per gene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mutation: Option<f64>,
    /// Variance: Nelder–Mead restarts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restarts: Option<usize>,
    /// MCMC: walkers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub walkers: Option<usize>,
    /// MCMC: fraction of each chain discarded as burn-in.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub burn_in: Option<f64>,
    /// MCMC: initial spread of the walkers around the start, unit coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spread: Option<f64>,
}

impl StageSpec {
    /// A stage with only an algorithm and a budget.
    pub fn new(algorithm: AlgorithmName, budget: usize) -> Self {
        Self {
            algorithm,
            budget,
            tolerance: None,
            population: None,
            sigma: None,
            stall_generations: None,
            step: None,
            keep: None,
            threshold: None,
            trajectories: None,
            levels: None,
            points: None,
            span: None,
            mutation: None,
            restarts: None,
            walkers: None,
            burn_in: None,
            spread: None,
        }
    }

    /// Names of the options that are set.
    fn set_options(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        let mut push = |name: &'static str, set: bool| {
            if set {
                v.push(name)
            }
        };
        push("population", self.population.is_some());
        push("sigma", self.sigma.is_some());
        push("stall_generations", self.stall_generations.is_some());
        push("step", self.step.is_some());
        push("keep", self.keep.is_some());
        push("threshold", self.threshold.is_some());
        push("trajectories", self.trajectories.is_some());
        push("levels", self.levels.is_some());
        push("points", self.points.is_some());
        push("span", self.span.is_some());
        push("mutation", self.mutation.is_some());
        push("restarts", self.restarts.is_some());
        push("walkers", self.walkers.is_some());
        push("burn_in", self.burn_in.is_some());
        push("spread", self.spread.is_some());
        v
    }

    /// Checks option applicability and ranges; `at` is the field path for errors (`stages[2]`).
    pub fn validate(&self, at: &str) -> Result<(), SpecError> {
        let field = |name: &str| format!("{at}.{name}");
        if self.budget == 0 {
            return Err(SpecError::Invalid { field: field("budget"), need: "must be at least 1" });
        }
        for name in self.set_options() {
            if !self.algorithm.options().contains(&name) {
                return Err(SpecError::NotAnOption { field: field(name), algorithm: self.algorithm });
            }
        }
        let positive = |name: &str, v: Option<f64>| match v {
            Some(value) if !(value.is_finite() && value > 0.0) => {
                Err(SpecError::OutOfRange { field: field(name), value, need: "must be a finite number > 0" })
            }
            _ => Ok(()),
        };
        positive("tolerance", self.tolerance)?;
        positive("sigma", self.sigma)?;
        positive("step", self.step)?;
        positive("span", self.span)?;
        positive("spread", self.spread)?;
        for (name, v) in [("threshold", self.threshold), ("mutation", self.mutation), ("burn_in", self.burn_in)] {
            if let Some(value) = v
                && !(value.is_finite() && (0.0..1.0).contains(&value))
            {
                return Err(SpecError::OutOfRange { field: field(name), value, need: "must be in [0, 1)" });
            }
        }
        if self.keep == Some(0) {
            return Err(SpecError::Invalid { field: field("keep"), need: "must be at least 1" });
        }
        if let Some(generations) = self.stall_generations {
            if generations == 0 {
                return Err(SpecError::Invalid { field: field("stall_generations"), need: "must be at least 1" });
            }
            if self.tolerance.is_none() {
                return Err(SpecError::StallWithoutTolerance { field: field("stall_generations"), generations });
            }
        }
        Ok(())
    }
}

/// A calibration as written by the user.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationSpec {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    #[serde(default)]
    pub seed: u64,
    pub experiments: Vec<ExperimentRef>,
    pub parameters: Vec<ParameterSpec>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub fixed: BTreeMap<String, f64>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub weights: BTreeMap<String, WeightSpec>,
    pub stages: Vec<StageSpec>,
    /// Wall-clock limit of one simulation, s: a longer run is a failed evaluation.
    #[serde(default = "default_max_evaluation_s")]
    pub max_evaluation_s: f64,
}

/// Default per-evaluation wall-clock limit, s.
pub const DEFAULT_MAX_EVALUATION_S: f64 = 120.0;

fn default_max_evaluation_s() -> f64 {
    DEFAULT_MAX_EVALUATION_S
}

/// `{ weight = η, sigma = σ }`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightSpec {
    #[serde(default = "one")]
    pub weight: f64,
    pub sigma: f64,
}

fn one() -> f64 {
    1.0
}

/// Why a calibration file is not usable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {message}")]
pub struct ConfigError {
    pub file: String,
    pub message: String,
}

impl CalibrationSpec {
    /// Parses and validates TOML text; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, ConfigError> {
        let spec: Self = toml::from_str(text)
            .map_err(|e| ConfigError { file: file.to_string(), message: e.to_string().trim().replace('\n', " ") })?;
        spec.validate().map_err(|e| ConfigError { file: file.to_string(), message: e.to_string() })?;
        Ok(spec)
    }

    /// Checks names, bounds, weights and stages. Errors name the field.
    pub fn validate(&self) -> Result<(), SpecError> {
        let invalid = |field: &str, need: &'static str| Err(SpecError::Invalid { field: field.to_string(), need });
        if self.name.trim().is_empty() {
            return invalid("name", "must not be empty");
        }
        if self.experiments.is_empty() {
            return invalid("experiments", "at least one [[experiments]] entry is needed");
        }
        for (k, e) in self.experiments.iter().enumerate() {
            if e.case.trim().is_empty() || e.data.trim().is_empty() {
                return invalid(&format!("experiments[{k}]"), "case and data must name files");
            }
        }
        if self.parameters.is_empty() {
            return invalid("parameters", "at least one free parameter ([[parameters]]) is needed");
        }
        self.space()?;
        for (name, &value) in &self.fixed {
            let field = format!("fixed.{name}");
            let spec = registry_spec(&field, name)?;
            if !(value.is_finite() && value >= spec.lower && value <= spec.upper) {
                return Err(SpecError::OutsideRegistry { field, value, lower: spec.lower, upper: spec.upper });
            }
            if self.parameters.iter().any(|p| &p.name == name) {
                return invalid(&field, "is also a free parameter; list it in one place");
            }
        }
        for q in self.weights.keys() {
            if !crate::data::QUANTITIES.contains(&q.as_str()) {
                return Err(SpecError::UnknownQuantity { field: format!("weights.{q}") });
            }
        }
        self.weights().validate()?;
        if self.stages.is_empty() {
            return invalid("stages", "at least one [[stages]] entry is needed");
        }
        for (k, s) in self.stages.iter().enumerate() {
            s.validate(&format!("stages[{k}]"))?;
        }
        if self.stages.iter().try_fold(0usize, |t, s| t.checked_add(s.budget)).is_none() {
            return Err(SpecError::BudgetOverflow);
        }
        if !(self.max_evaluation_s.is_finite() && self.max_evaluation_s > 0.0) {
            return Err(SpecError::OutOfRange {
                field: "max_evaluation_s".into(),
                value: self.max_evaluation_s,
                need: "must be a finite number > 0",
            });
        }
        Ok(())
    }

    /// The free-parameter space: bounds default to the registry's and must lie within them.
    pub fn space(&self) -> Result<Space, SpecError> {
        let mut free = Vec::new();
        for (k, p) in self.parameters.iter().enumerate() {
            let spec = registry_spec(&format!("parameters[{k}].name"), &p.name)?;
            let lower = p.lower.unwrap_or(spec.lower);
            let upper = p.upper.unwrap_or(spec.upper);
            let bounds = |registry: Option<(f64, f64)>| SpecError::Bounds {
                field: format!("parameters[{k}]"),
                name: p.name.clone(),
                lower,
                upper,
                registry,
            };
            if !(lower.is_finite() && upper.is_finite() && lower < upper) {
                return Err(bounds(None));
            }
            if lower < spec.lower || upper > spec.upper {
                return Err(bounds(Some((spec.lower, spec.upper))));
            }
            let scale = match p.scale.unwrap_or(ScaleName::Linear) {
                ScaleName::Linear => Scale::Linear,
                ScaleName::Log => Scale::Log,
            };
            free.push(FreeParameter { name: p.name.clone(), lower, upper, scale });
        }
        Ok(Space::new(free)?)
    }

    /// The weights as the cost uses them.
    pub fn weights(&self) -> crate::cost::Weights {
        crate::cost::Weights(
            self.weights.iter().map(|(q, w)| (q.clone(), Weight { weight: w.weight, sigma: w.sigma })).collect(),
        )
    }

    /// Total evaluation budget of all stages (each evaluation runs every experiment; saturates
    /// where [`CalibrationSpec::validate`] refuses the sum).
    pub fn budget(&self) -> usize {
        self.stages.iter().fold(0usize, |t, s| t.saturating_add(s.budget))
    }
}

/// The registry entry of parameter `name`, given at `field`.
fn registry_spec(field: &str, name: &str) -> Result<&'static params::ParamSpec, SpecError> {
    params::spec(name).ok_or_else(|| SpecError::UnknownParameter {
        field: field.to_string(),
        name: name.to_string(),
        suggestion: params::closest(name),
    })
}

/// What is wrong with a calibration, at which field. The message names the field first
/// (`stages[0].budget: must be at least 1`) and says what to change.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpecError {
    /// A field that is empty, zero or in conflict with another.
    #[error("{field}: {need}")]
    Invalid {
        /// The field path.
        field: String,
        /// What it needs.
        need: &'static str,
    },
    /// A number outside its range.
    #[error("{field} = {value}: {need}")]
    OutOfRange {
        /// The field path.
        field: String,
        /// The value given.
        value: f64,
        /// The range, in words.
        need: &'static str,
    },
    /// A stage option that the stage's algorithm does not have.
    #[error("{field}: does not apply to algorithm \"{algorithm}\" (its options: {})", algorithm.options().join(", "))]
    NotAnOption {
        /// The field path (`stages[k].<option>`).
        field: String,
        /// The stage's algorithm.
        algorithm: AlgorithmName,
    },
    /// A stall criterion without the tolerance it compares with.
    #[error(
        "{field} = {generations}: needs a `tolerance` (the least improvement of the best cost over that many \
         generations)"
    )]
    StallWithoutTolerance {
        /// The field path (`stages[k].stall_generations`).
        field: String,
        /// The generations given.
        generations: usize,
    },
    /// A name that is not in the parameter registry.
    #[error(
        "{field}: unknown parameter `{name}`{} (`cryofit params` lists them)",
        suggestion.map(|s| format!("; did you mean `{s}`?")).unwrap_or_default()
    )]
    UnknownParameter {
        /// The field path.
        field: String,
        /// The name given.
        name: String,
        /// The closest registry name, if one is close.
        suggestion: Option<&'static str>,
    },
    /// A fixed value outside the registry's bounds.
    #[error("{field} = {value}: outside the registry bounds [{lower}, {upper}]")]
    OutsideRegistry {
        /// The field path (`fixed.<name>`).
        field: String,
        /// The value given.
        value: f64,
        /// The registry's lower bound.
        lower: f64,
        /// The registry's upper bound.
        upper: f64,
    },
    /// Bounds of a free parameter that are not finite and increasing (`registry: None`), or that
    /// leave the registry's bounds.
    #[error("{field} ({name}): {}", match registry {
        None => format!("bounds must be finite with lower < upper (got lower = {lower}, upper = {upper})"),
        Some((lo, hi)) => format!("bounds [{lower}, {upper}] leave the registry's [{lo}, {hi}]"),
    })]
    Bounds {
        /// The field path (`parameters[k]`).
        field: String,
        /// The parameter.
        name: String,
        /// Lower bound given (or the registry's).
        lower: f64,
        /// Upper bound given (or the registry's).
        upper: f64,
        /// The registry's bounds, when the given ones leave them.
        registry: Option<(f64, f64)>,
    },
    /// A weight for a quantity that no time series holds.
    #[error("{field}: unknown quantity (known: {})", crate::data::QUANTITIES.join(", "))]
    UnknownQuantity {
        /// The field path (`weights.<quantity>`).
        field: String,
    },
    /// A weight that cannot be used.
    #[error(transparent)]
    Weight(#[from] crate::cost::WeightError),
    /// The free parameters do not make a space.
    #[error("parameters: {0}")]
    Space(#[from] crate::space::SpaceError),
    /// The stages' budgets add up past the integer range.
    #[error("stages: the budgets add up to more than {} evaluations; lower them", usize::MAX)]
    BudgetOverflow,
}

impl SpecError {
    /// The path of the field at fault (`stages[0].budget`, `weights.pressure_pa.sigma`, …).
    pub fn field(&self) -> String {
        match self {
            Self::Invalid { field, .. }
            | Self::OutOfRange { field, .. }
            | Self::NotAnOption { field, .. }
            | Self::StallWithoutTolerance { field, .. }
            | Self::UnknownParameter { field, .. }
            | Self::OutsideRegistry { field, .. }
            | Self::Bounds { field, .. }
            | Self::UnknownQuantity { field } => field.clone(),
            Self::Weight(e) => e.field(),
            Self::Space(_) => "parameters".into(),
            Self::BudgetOverflow => "stages".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "t"
seed = 3
[[experiments]]
case = "a.toml"
data = "a.csv"
[[parameters]]
name = "Gwsc"
lower = 0.3
upper = 3.0
scale = "log"
[[parameters]]
name = "tauw"
[fixed]
Gisc = 2.0
[weights]
wall_temperature_k = { weight = 1.0, sigma = 2.0 }
[[stages]]
algorithm = "cmaes"
budget = 50
population = 8
"#;

    #[test]
    fn parses_a_good_file() {
        let c = CalibrationSpec::from_toml(GOOD, "c.toml").unwrap();
        assert_eq!(c.seed, 3);
        let s = c.space().unwrap();
        assert_eq!(s.dim(), 2);
        assert_eq!(s.params()[0].scale, Scale::Log);
        let reg = params::spec("tauw").unwrap();
        assert_eq!((s.params()[1].lower, s.params()[1].upper), (reg.lower, reg.upper));
        assert_eq!(c.budget(), 50);
        assert_eq!(c.max_evaluation_s, DEFAULT_MAX_EVALUATION_S);
        // JSON round trip (the REST body)
        let json = serde_json::to_string(&c).unwrap();
        let back: CalibrationSpec = serde_json::from_str(&json).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn errors_name_the_field() {
        let bad = |from: &str, to: &str| CalibrationSpec::from_toml(&GOOD.replace(from, to), "c.toml").unwrap_err();
        let e = bad("name = \"Gwsc\"", "name = \"Gwscc\"");
        assert!(e.to_string().contains("parameters[0].name: unknown parameter `Gwscc`; did you mean `Gwsc`?"), "{e}");
        let e = bad("upper = 3.0", "upper = 0.2");
        assert!(e.to_string().contains("lower < upper"), "{e}");
        let e = bad("upper = 3.0", "upper = 300.0");
        assert!(e.to_string().contains("leave the registry"), "{e}");
        let e = bad("population = 8", "walkers = 8");
        assert!(e.to_string().contains("stages[0].walkers: does not apply to algorithm \"cmaes\""), "{e}");
        let e = bad("budget = 50", "budget = 50\nfoo = 1");
        assert!(e.to_string().contains("unknown field `foo`"), "{e}");
        let e = bad("Gisc = 2.0", "Gwsc = 2.0");
        assert!(e.to_string().contains("fixed.Gwsc: is also a free parameter"), "{e}");
        let e = bad("sigma = 2.0", "sigma = 0.0");
        assert!(e.to_string().contains("weights.wall_temperature_k.sigma"), "{e}");
        let e = bad("algorithm = \"cmaes\"", "algorithm = \"cma\"");
        assert!(e.to_string().starts_with("c.toml: "), "{e}");
        let e = bad("population = 8", "stall_generations = 20");
        assert!(e.to_string().contains("stages[0].stall_generations = 20: needs a `tolerance`"), "{e}");
        let e = bad("population = 8", "stall_generations = 0\ntolerance = 1.0");
        assert!(e.to_string().contains("stages[0].stall_generations: must be at least 1"), "{e}");
        let e = bad(
            "algorithm = \"cmaes\"\nbudget = 50\npopulation = 8",
            "algorithm = \"swarm\"\nbudget = 50\nstall_generations = 3",
        );
        assert!(e.to_string().contains("stages[0].stall_generations: does not apply to algorithm \"swarm\""), "{e}");
        let c = CalibrationSpec::from_toml(
            &GOOD.replace("population = 8", "stall_generations = 20\ntolerance = 5.0"),
            "c.toml",
        )
        .unwrap();
        assert_eq!(c.stages[0].stall_generations, Some(20));
    }

    #[test]
    fn budgets_that_sum_past_the_integer_range_are_refused() {
        let stage = "[[stages]]\nalgorithm = \"cmaes\"\nbudget = 9000000000000000000\n";
        let text = GOOD.replace("[[stages]]", &format!("{stage}\n{stage}\n{stage}\n[[stages]]"));
        let e = CalibrationSpec::from_toml(&text, "c.toml").unwrap_err();
        assert!(e.to_string().contains("stages: the budgets add up to more than"), "{e}");
        let mut c = CalibrationSpec::from_toml(GOOD, "c.toml").unwrap();
        c.stages = vec![StageSpec::new(AlgorithmName::Cmaes, usize::MAX), StageSpec::new(AlgorithmName::Cmaes, 5)];
        assert_eq!(c.budget(), usize::MAX, "the sum saturates");
    }
}
