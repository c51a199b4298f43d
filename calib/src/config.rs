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
//! start = 1.2                # optional: where it starts (default: registry default, case value)
//! [[parameters]]             # a case field (apparatus parameter): bounds required
//! name = "case.inlet.loss_coefficient"
//! lower = 2.0
//! upper = 30.0
//! experiments = ["subcooled-4.2atm"]   # optional: one copy per experiment listed
//! [fixed]                    # other parameters held at given values (default: registry)
//! tauw = 2.0
//! "case.pipe.cells" = 120    # a case field, in every experiment's case
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
//!
//! A parameter named `case.<path>` is a numeric field of the experiments' cases (an apparatus
//! parameter, see [`crate::apparatus`]): it has no registry box, so `lower` and `upper` are
//! required. Without `experiments` it is one value shared by every experiment; with
//! `experiments = [...]` (each entry an experiment's name, or its `case` as written in the file)
//! each listed experiment gets its own copy, named `case.<path>@<experiment name>` in results,
//! and the experiments not listed keep their case's value. Whether the field exists and accepts
//! the bounds is checked against each case it applies to
//! ([`CalibrationSpec::check_case_fields`]) once the cases are read.
//!
//! `[fixed]` may hold case fields too, by the same names: `"case.pipe.cells" = 120` sets the
//! field in every experiment's case (the grid a fit is made on), `"case.inlet.loss_coefficient@a"
//! = 7.9` in experiment `a`'s case only (`a` its name), over the case files' values. A fixed field
//! cannot also be free.

use std::collections::BTreeMap;

use cryofit_solver::case::{Case, FieldError};
use cryofit_solver::params;
use serde::{Deserialize, Serialize};

use crate::apparatus;

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

impl ExperimentRef {
    /// The experiment's name: `name`, or else the stem of the case file's name (`experiment-<k>`
    /// for a case path without one); `k` is its index in the file.
    pub fn label(&self, k: usize) -> String {
        self.name.clone().unwrap_or_else(|| {
            std::path::Path::new(&self.case)
                .file_stem()
                .map_or_else(|| format!("experiment-{k}"), |s| s.to_string_lossy().into_owned())
        })
    }
}

/// One free parameter as written in the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    /// A registry name, or a case field `case.<path>`.
    pub name: String,
    /// Lower bound (default: the registry's; required for a case field).
    #[serde(default)]
    pub lower: Option<f64>,
    /// Upper bound (default: the registry's; required for a case field).
    #[serde(default)]
    pub upper: Option<f64>,
    /// How the parameter maps to its unit coordinate (default linear).
    #[serde(default)]
    pub scale: Option<ScaleName>,
    /// Case fields only: one independent copy per listed experiment (its name, or its `case` as
    /// written in the file), named `case.<path>@<experiment name>`; absent: one value shared by
    /// every experiment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub experiments: Option<Vec<String>>,
    /// Where the calibration starts, within the bounds (default: the registry default, or a case
    /// field's value in its case); every copy of a per-experiment case field starts there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
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
            AlgorithmName::Mcmc => &["walkers", "burn_in", "spread", "temperature"],
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
    /// MCMC: temperature of the likelihood `exp(−S/(2T))`: a number ≥ 1, or `"noise"` for the
    /// noise inflation `1 + 2σ_ε` that the last variance stage before it measured
    /// (`McmcOptions::temperature` says why).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<Temperature>,
}

/// An MCMC stage's likelihood temperature ([`StageSpec::temperature`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Temperature {
    /// This temperature.
    Value(f64),
    /// The noise inflation of the last variance stage before the MCMC stage.
    Noise,
}

impl Serialize for Temperature {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Temperature::Value(t) => s.serialize_f64(*t),
            Temperature::Noise => s.serialize_str("noise"),
        }
    }
}

impl<'de> Deserialize<'de> for Temperature {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = Temperature;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number ≥ 1 or \"noise\" (the last variance stage's noise inflation)")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Temperature, E> {
                Ok(Temperature::Value(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Temperature, E> {
                Ok(Temperature::Value(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Temperature, E> {
                Ok(Temperature::Value(v as f64))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Temperature, E> {
                match v {
                    "noise" => Ok(Temperature::Noise),
                    other => Err(E::invalid_value(serde::de::Unexpected::Str(other), &self)),
                }
            }
        }
        d.deserialize_any(V)
    }
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
            temperature: None,
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
        push("temperature", self.temperature.is_some());
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
        if let Some(Temperature::Value(value)) = self.temperature
            && !(value.is_finite() && value >= 1.0)
        {
            return Err(SpecError::OutOfRange {
                field: field("temperature"),
                value,
                need: "must be a finite number ≥ 1 (or \"noise\")",
            });
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
    /// Cross-validation (`cryofit crossval`): the stages of each refit without one experiment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crossval: Option<CrossvalSpec>,
}

/// `[crossval]`: how `cryofit crossval` refits the calibration without each experiment in turn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrossvalSpec {
    /// The refit's stages, in order (warm-started from the joint optimum): typically a local or
    /// global optimiser with a small budget, then a variance or MCMC stage for the prediction's
    /// posterior-predictive band.
    pub stages: Vec<StageSpec>,
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
            if apparatus::is_case_name(name) {
                self.check_fixed_case_field(&field, name, value)?;
                continue;
            }
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
        if let Some(cv) = &self.crossval {
            if cv.stages.is_empty() {
                return invalid("crossval.stages", "at least one stage is needed for the refits");
            }
            for (k, s) in cv.stages.iter().enumerate() {
                s.validate(&format!("crossval.stages[{k}]"))?;
            }
            if cv.stages.iter().try_fold(0usize, |t, s| t.checked_add(s.budget)).is_none() {
                return Err(SpecError::BudgetOverflow);
            }
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

    /// The free-parameter space, in file order (a per-experiment case field gives one parameter
    /// per listed experiment, in the list's order). Registry bounds default to the registry's and
    /// must lie within them; a case field's are required.
    pub fn space(&self) -> Result<Space, SpecError> {
        let mut free = Vec::new();
        for (k, p) in self.parameters.iter().enumerate() {
            let (lower, upper) = self.bounds(k, p)?;
            let scale = match p.scale.unwrap_or(ScaleName::Linear) {
                ScaleName::Linear => Scale::Linear,
                ScaleName::Log => Scale::Log,
            };
            if let Some(start) = p.start
                && !(start.is_finite() && lower <= start && start <= upper)
            {
                return Err(SpecError::OutOfRange {
                    field: format!("parameters[{k}].start"),
                    value: start,
                    need: "must lie within the parameter's bounds",
                });
            }
            match self.copies(k)? {
                None => free.push(FreeParameter { name: p.name.clone(), lower, upper, scale }),
                Some(experiments) => free.extend(experiments.into_iter().map(|e| FreeParameter {
                    name: apparatus::copy_name(&p.name, &self.experiments[e].label(e)),
                    lower,
                    upper,
                    scale,
                })),
            }
        }
        self.check_case_field_overlap()?;
        Ok(Space::new(free)?)
    }

    /// The given starting values (`parameters[k].start`) by free-parameter name: a per-experiment
    /// case field's under each copy's name. Call after [`Self::validate`].
    pub fn start_values(&self) -> BTreeMap<String, f64> {
        let mut m = BTreeMap::new();
        for (k, p) in self.parameters.iter().enumerate() {
            let Some(v) = p.start else { continue };
            match self.copies(k).ok().flatten() {
                None => {
                    m.insert(p.name.clone(), v);
                }
                Some(experiments) => m.extend(
                    experiments.into_iter().map(|e| (apparatus::copy_name(&p.name, &self.experiments[e].label(e)), v)),
                ),
            }
        }
        m
    }

    /// The bounds of `parameters[k]` (`p`): checked against the registry's, or required for a
    /// case field.
    fn bounds(&self, k: usize, p: &ParameterSpec) -> Result<(f64, f64), SpecError> {
        let field = format!("parameters[{k}]");
        let registry = if apparatus::is_case_name(&p.name) {
            check_case_name(&format!("{field}.name"), &p.name)?;
            if p.lower.is_none() || p.upper.is_none() {
                return Err(SpecError::CaseParameter {
                    field,
                    value: p.name.clone(),
                    need: "a case field has no registry bounds: give both `lower` and `upper`".into(),
                });
            }
            None
        } else {
            Some(registry_spec(&format!("{field}.name"), &p.name)?)
        };
        let lower = p.lower.or(registry.map(|s| s.lower)).unwrap_or(f64::NAN);
        let upper = p.upper.or(registry.map(|s| s.upper)).unwrap_or(f64::NAN);
        let bounds = |registry: Option<(f64, f64)>| SpecError::Bounds {
            field: field.clone(),
            name: p.name.clone(),
            lower,
            upper,
            registry,
        };
        if !(lower.is_finite() && upper.is_finite() && lower < upper) {
            return Err(bounds(None));
        }
        if let Some(spec) = registry
            && (lower < spec.lower || upper > spec.upper)
        {
            return Err(bounds(Some((spec.lower, spec.upper))));
        }
        Ok((lower, upper))
    }

    /// The experiments (indices) that get a copy of `parameters[k]`, in the list's order; `None`
    /// for a parameter shared by all.
    fn copies(&self, k: usize) -> Result<Option<Vec<usize>>, SpecError> {
        let p = &self.parameters[k];
        let Some(list) = &p.experiments else { return Ok(None) };
        let field = format!("parameters[{k}].experiments");
        let refuse = |field: String, value: &str, need: String| SpecError::CaseParameter {
            field,
            value: value.to_string(),
            need,
        };
        if !apparatus::is_case_name(&p.name) {
            let need = "a registry parameter is one value for every experiment; `experiments` applies to case \
                        fields (`case.<path>`) only";
            return Err(refuse(field, &p.name, need.into()));
        }
        if list.is_empty() {
            let need = "lists no experiment: name at least one, or leave `experiments` out for one value shared \
                        by all";
            return Err(refuse(field, &p.name, need.into()));
        }
        let mut picked = Vec::new();
        for (j, entry) in list.iter().enumerate() {
            let e = self.experiment_named(&format!("{field}[{j}]"), entry)?;
            if picked.contains(&e) {
                let need = format!("names experiment `{}` a second time", self.experiments[e].label(e));
                return Err(refuse(format!("{field}[{j}]"), entry, need));
            }
            picked.push(e);
        }
        Ok(Some(picked))
    }

    /// The experiment an `experiments` entry names: by its name first, else by its `case` as
    /// written in the file.
    fn experiment_named(&self, field: &str, entry: &str) -> Result<usize, SpecError> {
        let labels: Vec<String> = self.experiments.iter().enumerate().map(|(k, e)| e.label(k)).collect();
        let by_name: Vec<usize> = (0..labels.len()).filter(|&k| labels[k] == entry).collect();
        let by_case: Vec<usize> = (0..labels.len()).filter(|&k| self.experiments[k].case == entry).collect();
        let refuse = |need: String| SpecError::CaseParameter { field: field.to_string(), value: entry.into(), need };
        match (by_name.as_slice(), by_case.as_slice()) {
            ([k], _) | ([], [k]) => Ok(*k),
            ([a, b, ..], _) => Err(refuse(format!(
                "experiments[{a}] and experiments[{b}] are both named `{entry}`; give each experiment its own `name`"
            ))),
            ([], [a, b, ..]) => Err(refuse(format!(
                "experiments[{a}] and experiments[{b}] share this case file; name the experiment by its `name`"
            ))),
            ([], []) => Err(refuse(format!(
                "not an experiment of this calibration (its experiments: {}); give an experiment's name or its case \
                 file",
                labels.join(", ")
            ))),
        }
    }

    /// Checks `[fixed]` case field `name` (at `field`, value `value`): a well-formed field name,
    /// its experiment (after `@`) one of this calibration's by name, a finite value, and the field
    /// not also free. Whether the cases have the field and accept the value is checked once they
    /// are read ([`CalibrationSpec::check_case_fields`]).
    fn check_fixed_case_field(&self, field: &str, name: &str, value: f64) -> Result<(), SpecError> {
        let refuse = |need: String| SpecError::CaseParameter { field: field.into(), value: name.into(), need };
        let Some(case) = apparatus::case_name(name) else { return Ok(()) };
        let shared = format!("{}{}", apparatus::CASE_PREFIX, case.path);
        check_case_name(field, &shared)?;
        if let Some(experiment) = case.experiment {
            let labels: Vec<String> = self.experiments.iter().enumerate().map(|(k, e)| e.label(k)).collect();
            if !labels.iter().any(|l| l == experiment) {
                return Err(refuse(format!(
                    "`{experiment}` after `@` is not an experiment of this calibration (its experiments: {}); give \
                     an experiment's name",
                    labels.join(", ")
                )));
            }
        }
        if !value.is_finite() {
            return Err(refuse(format!("the value {value} is not a finite number")));
        }
        if let Some(k) = self.parameters.iter().position(|p| p.name == shared) {
            return Err(refuse(format!("`{shared}` is also a free parameter (parameters[{k}]); list it in one place")));
        }
        Ok(())
    }

    /// Refuses a case field that is free both for every experiment and for some experiments.
    fn check_case_field_overlap(&self) -> Result<(), SpecError> {
        for (k, p) in self.parameters.iter().enumerate() {
            let shared = |q: &ParameterSpec| q.name == p.name && q.experiments.is_none();
            if let Some(j) = self.parameters.iter().position(shared)
                && j != k
                && apparatus::is_case_name(&p.name)
            {
                return Err(SpecError::CaseParameter {
                    field: format!("parameters[{k}]"),
                    value: p.name.clone(),
                    need: format!(
                        "is already free for every experiment in parameters[{j}]; list a case field once, shared \
                         or per experiment"
                    ),
                });
            }
        }
        Ok(())
    }

    /// Number of free parameters (each per-experiment copy counted), without checking them.
    pub fn dimension(&self) -> usize {
        self.parameters.iter().map(|p| p.experiments.as_ref().map_or(1, |e| e.len().max(1))).sum()
    }

    /// The calibration with every `experiments` entry of a parameter given as the experiment's
    /// name (an entry that names a case file replaced), as a coordinator needs it: it knows
    /// experiments by name only. Entries that name no experiment are left for
    /// [`CalibrationSpec::validate`] to refuse.
    pub fn with_experiment_names(&self) -> CalibrationSpec {
        let mut spec = self.clone();
        for p in &mut spec.parameters {
            for entry in p.experiments.iter_mut().flatten() {
                if let Ok(k) = self.experiment_named("", entry) {
                    *entry = self.experiments[k].label(k);
                }
            }
        }
        spec
    }

    /// Checks every case field fixed or free in experiment `experiment` (its name) against its
    /// `case` (`case_label` names the file): the field exists, holds a number, and the case accepts
    /// the fixed value or both bounds. Errors name the parameter, the experiment, the case, the bound and the field.
    pub fn check_case_fields(&self, experiment: &str, case: &Case, case_label: &str) -> Result<(), SpecError> {
        // the fixed case fields that apply here
        if let Err((name, error)) = apparatus::set_fields(&self.fixed, case, experiment) {
            return Err(SpecError::CaseField {
                field: format!("fixed.{name}"),
                name,
                experiment: experiment.to_string(),
                case_label: case_label.to_string(),
                bound: None,
                error: Box::new(error),
            });
        }
        for (k, p) in self.parameters.iter().enumerate() {
            let Some(name) = apparatus::case_name(&p.name) else { continue };
            let applies = match self.copies(k)? {
                None => true,
                Some(list) => list.iter().any(|&e| self.experiments[e].label(e) == experiment),
            };
            if !applies {
                continue;
            }
            let (lower, upper) = self.bounds(k, p)?;
            for (bound, value) in [("lower", lower), ("upper", upper)] {
                if let Err(error) = case.with_fields(&[(name.path, value)]) {
                    let bound = matches!(error, FieldError::Invalid { .. }).then_some(bound);
                    return Err(SpecError::CaseField {
                        field: format!("parameters[{k}]"),
                        name: p.name.clone(),
                        experiment: experiment.to_string(),
                        case_label: case_label.to_string(),
                        bound,
                        error: Box::new(error),
                    });
                }
            }
        }
        Ok(())
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

/// Checks the form of a case field's name given at `field`: `case.<path>`, the path not through
/// the case's `[parameters]` and without the `@` of a per-experiment copy's name.
fn check_case_name(field: &str, name: &str) -> Result<(), SpecError> {
    let refuse = |need: &str| SpecError::CaseParameter { field: field.into(), value: name.into(), need: need.into() };
    let path = name.strip_prefix(apparatus::CASE_PREFIX).unwrap_or(name);
    if path.contains(apparatus::EXPERIMENT_MARK) {
        return Err(refuse(
            "`@` marks the per-experiment copies a calibration names itself: give the field's name and list the \
             experiments in `experiments = [...]`",
        ));
    }
    if path.split('.').any(|s| s.trim().is_empty() || s.trim() != s) {
        return Err(refuse("not a case field: give `case.` and the field's TOML path (case.inlet.loss_coefficient)"));
    }
    if let Some(registry) = path.strip_prefix("parameters.") {
        return Err(refuse(&format!(
            "the case's [parameters] are registry parameters: name the parameter `{registry}` itself"
        )));
    }
    Ok(())
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
    /// A case-field parameter (or its `experiments`) that cannot be used as written.
    #[error("{field} (`{value}`): {need}")]
    CaseParameter {
        /// The field path (`parameters[k]`, `parameters[k].experiments[j]`, `fixed.<name>`).
        field: String,
        /// The name or entry given.
        value: String,
        /// What is wrong and what to do, in words.
        need: String,
    },
    /// A free case field that an experiment's case does not have, or whose bounds it refuses; a
    /// fixed one that it does not have or whose value it refuses.
    #[error(
        "{field} ({name}), experiment `{experiment}` ({case_label}){}: {error}{}",
        bound.map(|b| format!(", at the {b} bound")).unwrap_or_default(),
        if bound.is_some() { "; keep the bounds within the values the case accepts" } else { "" }
    )]
    CaseField {
        /// The field path (`parameters[k]`, `fixed.<name>`).
        field: String,
        /// The parameter.
        name: String,
        /// The experiment.
        experiment: String,
        /// Names its case.
        case_label: String,
        /// The bound the case refuses (`None`: the field itself is not usable).
        bound: Option<&'static str>,
        /// Why (boxed: the other errors are small).
        error: Box<FieldError>,
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
            | Self::CaseParameter { field, .. }
            | Self::CaseField { field, .. }
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
    fn an_mcmc_temperature_is_a_number_of_at_least_one_or_noise() {
        let mcmc = |t: &str| {
            GOOD.replace(
                "algorithm = \"cmaes\"\nbudget = 50\npopulation = 8",
                &format!("algorithm = \"mcmc\"\nbudget = 400\n{t}"),
            )
        };
        let c = CalibrationSpec::from_toml(&mcmc("temperature = \"noise\""), "c.toml").unwrap();
        assert_eq!(c.stages[0].temperature, Some(Temperature::Noise));
        let c = CalibrationSpec::from_toml(&mcmc("temperature = 40"), "c.toml").unwrap();
        assert_eq!(c.stages[0].temperature, Some(Temperature::Value(40.0)));
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<CalibrationSpec>(&json).unwrap(), c);
        let e = CalibrationSpec::from_toml(&mcmc("temperature = 0.5"), "c.toml").unwrap_err().to_string();
        assert!(e.contains("stages[0].temperature") && e.contains("≥ 1"), "{e}");
        let e = CalibrationSpec::from_toml(&mcmc("temperature = \"hot\""), "c.toml").unwrap_err().to_string();
        assert!(e.contains("\"noise\"") && e.contains("hot"), "{e}");
        let e = CalibrationSpec::from_toml(&GOOD.replace("population = 8", "temperature = 2.0"), "c.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("stages[0].temperature: does not apply to algorithm \"cmaes\""), "{e}");
    }

    const APPARATUS: &str = r#"
name = "apparatus"
[[experiments]]
case = "runs/a.toml"
data = "a.csv"
[[experiments]]
case = "runs/b.toml"
data = "b.csv"
name = "run-b"
[[parameters]]
name = "case.inlet.loss_coefficient"
lower = 2.0
upper = 20.0
scale = "log"
experiments = ["a", "runs/b.toml"]
[[parameters]]
name = "case.inlet.valve_opening_time_s"
lower = 0.5
upper = 4.0
[[parameters]]
name = "Gwsc"
[[stages]]
algorithm = "cmaes"
budget = 50
"#;

    #[test]
    fn case_fields_are_free_parameters_shared_or_copied_per_experiment() {
        let c = CalibrationSpec::from_toml(APPARATUS, "c.toml").unwrap();
        let s = c.space().unwrap();
        let names: Vec<&str> = s.names().collect();
        assert_eq!(
            names,
            [
                "case.inlet.loss_coefficient@a",
                "case.inlet.loss_coefficient@run-b",
                "case.inlet.valve_opening_time_s",
                "Gwsc"
            ]
        );
        assert_eq!(c.dimension(), 4);
        assert_eq!((s.params()[1].lower, s.params()[1].upper, s.params()[1].scale), (2.0, 20.0, Scale::Log));
        // the coordinator's form names experiments by name, and its JSON reads back
        let named = c.with_experiment_names();
        assert_eq!(named.parameters[0].experiments, Some(vec!["a".to_string(), "run-b".to_string()]));
        let back: CalibrationSpec = serde_json::from_str(&serde_json::to_string(&named).unwrap()).unwrap();
        assert_eq!(back, named);
        assert_eq!(back.space().unwrap(), s);
        // a registry parameter's JSON has no `experiments` key (stored calibrations compare equal)
        assert!(!serde_json::to_string(&c.parameters[2]).unwrap().contains("experiments"));
    }

    #[test]
    fn start_values_lie_within_the_bounds_and_reach_every_copy() {
        let text = APPARATUS
            .replace("experiments = [\"a\", \"runs/b.toml\"]", "experiments = [\"a\", \"runs/b.toml\"]\nstart = 7.5")
            .replace("name = \"Gwsc\"", "name = \"Gwsc\"\nstart = 1.25");
        let c = CalibrationSpec::from_toml(&text, "c.toml").unwrap();
        let starts = c.start_values();
        assert_eq!(
            starts,
            BTreeMap::from([
                ("Gwsc".to_string(), 1.25),
                ("case.inlet.loss_coefficient@a".to_string(), 7.5),
                ("case.inlet.loss_coefficient@run-b".to_string(), 7.5),
            ])
        );
        // the JSON twin keeps it; a parameter without one has no `start` key
        let back: CalibrationSpec = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
        assert_eq!(back.start_values(), starts);
        assert!(!serde_json::to_string(&c.parameters[1]).unwrap().contains("start"));
        let e = CalibrationSpec::from_toml(&text.replace("start = 7.5", "start = 25.0"), "c.toml").unwrap_err();
        assert!(e.to_string().contains("parameters[0].start = 25: must lie within the parameter's bounds"), "{e}");
    }

    #[test]
    fn case_field_parameters_that_cannot_be_used_are_refused_naming_the_field() {
        let bad = |from: &str, to: &str| {
            let text = APPARATUS.replace(from, to);
            assert_ne!(text, APPARATUS, "{from}");
            CalibrationSpec::from_toml(&text, "c.toml").unwrap_err().to_string()
        };
        let e = bad("lower = 0.5\nupper = 4.0", "upper = 4.0");
        assert!(
            e.contains("parameters[1] (`case.inlet.valve_opening_time_s`): a case field has no registry bounds"),
            "{e}"
        );
        let e = bad("lower = 0.5", "lower = 5.0");
        assert!(
            e.contains("parameters[1] (case.inlet.valve_opening_time_s): bounds must be finite with lower < upper"),
            "{e}"
        );
        let e = bad("name = \"Gwsc\"", "name = \"Gwsc\"\nexperiments = [\"a\"]");
        assert!(e.contains("parameters[2].experiments (`Gwsc`): a registry parameter is one value"), "{e}");
        let e = bad("[\"a\", \"runs/b.toml\"]", "[\"a\", \"c\"]");
        assert!(
            e.contains(
                "parameters[0].experiments[1] (`c`): not an experiment of this calibration (its experiments: a, run-b)"
            ),
            "{e}"
        );
        let e = bad("[\"a\", \"runs/b.toml\"]", "[\"a\", \"runs/a.toml\"]");
        assert!(e.contains("parameters[0].experiments[1] (`runs/a.toml`): names experiment `a` a second time"), "{e}");
        let e = bad("[\"a\", \"runs/b.toml\"]", "[]");
        assert!(e.contains("parameters[0].experiments (`case.inlet.loss_coefficient`): lists no experiment"), "{e}");
        let e = bad("name = \"run-b\"", "name = \"a\"");
        assert!(e.contains("experiments[0] and experiments[1] are both named `a`"), "{e}");
        let e = bad("name = \"case.inlet.valve_opening_time_s\"", "name = \"case.inlet.valve_opening_time_s@a\"");
        assert!(e.contains("`@` marks the per-experiment copies"), "{e}");
        let e = bad("name = \"case.inlet.valve_opening_time_s\"", "name = \"case.inlet..x\"");
        assert!(e.contains("parameters[1].name (`case.inlet..x`): not a case field"), "{e}");
        let e = bad("name = \"case.inlet.valve_opening_time_s\"", "name = \"case.parameters.Gwsc\"");
        assert!(e.contains("name the parameter `Gwsc` itself"), "{e}");
        let e = bad("name = \"case.inlet.valve_opening_time_s\"", "name = \"case.inlet.loss_coefficient\"");
        assert!(
            e.contains(
                "parameters[0] (`case.inlet.loss_coefficient`): is already free for every experiment in parameters[1]"
            ),
            "{e}"
        );
        let e = bad("[[stages]]", "[fixed]\n\"case.inlet.loss_coefficient\" = 3.0\n[[stages]]");
        assert!(
            e.contains(
                "fixed.case.inlet.loss_coefficient (`case.inlet.loss_coefficient`): `case.inlet.loss_coefficient` is \
                 also a free parameter (parameters[0]); list it in one place"
            ),
            "{e}"
        );
        assert!(e.starts_with("c.toml: "), "{e}");
        let e = bad("[[stages]]", "[fixed]\n\"case.pipe.cells@c\" = 10\n[[stages]]");
        assert!(e.contains("fixed.case.pipe.cells@c (`case.pipe.cells@c`): `c` after `@` is not an experiment"), "{e}");
        assert!(e.contains("its experiments: a, run-b"), "{e}");
        let e = bad("[[stages]]", "[fixed]\n\"case.pipe..cells\" = 10\n[[stages]]");
        assert!(e.contains("fixed.case.pipe..cells (`case.pipe..cells`): not a case field"), "{e}");
    }

    #[test]
    fn fixed_case_fields_apply_to_every_case_or_to_their_experiment() {
        let text = APPARATUS.replace(
            "[[stages]]",
            "[fixed]\n\"case.pipe.cells\" = 12\n\"case.inlet.pressure_pa@run-b\" = 3.0e5\nGwsc = 1.5\n[[stages]]",
        );
        let text = text.replace("name = \"Gwsc\"", "name = \"Gisc\"");
        let c = CalibrationSpec::from_toml(&text, "c.toml").unwrap();
        let case = Case::from_toml(include_str!("../../tests/fixtures/tiny.toml"), "runs/a.toml").unwrap();
        c.check_case_fields("a", &case, "runs/a.toml").unwrap();
        c.check_case_fields("run-b", &case, "runs/b.toml").unwrap();
        // the JSON twin (a coordinator's request) keeps them
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<CalibrationSpec>(&json).unwrap(), c);
        // a value the case refuses, named with the experiment and the case
        let refused = text.replace("\"case.pipe.cells\" = 12", "\"case.pipe.cells\" = 0");
        let c = CalibrationSpec::from_toml(&refused, "c.toml").unwrap();
        let e = c.check_case_fields("a", &case, "runs/a.toml").unwrap_err();
        assert_eq!(e.field(), "fixed.case.pipe.cells");
        assert!(
            e.to_string().starts_with("fixed.case.pipe.cells (case.pipe.cells), experiment `a` (runs/a.toml): "),
            "{e}"
        );
        let unknown = text.replace("case.inlet.pressure_pa@run-b", "case.inlet.presure_pa@run-b");
        let c = CalibrationSpec::from_toml(&unknown, "c.toml").unwrap();
        c.check_case_fields("a", &case, "runs/a.toml").unwrap();
        let e = c.check_case_fields("run-b", &case, "runs/b.toml").unwrap_err();
        assert_eq!(e.field(), "fixed.case.inlet.presure_pa@run-b");
        assert!(e.to_string().contains("`inlet.presure_pa` is not a field"), "{e}");
    }

    #[test]
    fn case_fields_are_checked_against_each_case_they_apply_to() {
        let c = CalibrationSpec::from_toml(APPARATUS, "c.toml").unwrap();
        let case = Case::from_toml(include_str!("../../tests/fixtures/tiny.toml"), "runs/a.toml").unwrap();
        c.check_case_fields("a", &case, "runs/a.toml").unwrap();
        let refused = |text: String, experiment: &str| {
            let c = CalibrationSpec::from_toml(&text, "c.toml").unwrap();
            c.check_case_fields(experiment, &case, "runs/a.toml").unwrap_err()
        };
        let e = refused(APPARATUS.replace("lower = 0.5", "lower = -0.5"), "a");
        assert_eq!(e.field(), "parameters[1]");
        let e = e.to_string();
        assert!(
            e.starts_with(
                "parameters[1] (case.inlet.valve_opening_time_s), experiment `a` (runs/a.toml), at the lower bound: \
                 inlet.valve_opening_time_s = -0.5 makes the case invalid"
            ),
            "{e}"
        );
        assert!(e.contains("must be ≥ 0") && e.contains("keep the bounds within"), "{e}");
        let e = refused(APPARATUS.replace("case.inlet.valve_opening_time_s", "case.inlet.valve_time_s"), "run-b");
        assert!(e.to_string().contains("experiment `run-b` (runs/a.toml): `inlet.valve_time_s` is not a field"), "{e}");
        // a per-experiment field is checked only against its experiments' cases
        let text = APPARATUS
            .replace("[\"a\", \"runs/b.toml\"]", "[\"a\"]")
            .replace("lower = 2.0", "lower = -2.0")
            .replace("scale = \"log\"\n", "");
        let c = CalibrationSpec::from_toml(&text, "c.toml").unwrap();
        c.check_case_fields("run-b", &case, "runs/b.toml").unwrap();
        assert!(c.check_case_fields("a", &case, "runs/a.toml").is_err());
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
