//! A calibration problem: experiments (a model and its data each) and the cost weights.
//! Evaluating a parameter point runs every experiment and sums their costs.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::api::Outcome;
use crate::cost::{self, Fit, FitError, Weights};
use crate::data::{DataError, Dataset};
use crate::model::{Model, ModelError};

/// One experiment of a calibration.
#[derive(Clone)]
pub struct Experiment {
    /// Name used in reports and in the per-experiment output files.
    pub name: String,
    pub model: Arc<dyn Model>,
    pub data: Dataset,
}

impl std::fmt::Debug for Experiment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Experiment").field("name", &self.name).field("observations", &self.data.len()).finish()
    }
}

/// Experiments and weights.
#[derive(Debug, Clone)]
pub struct Problem {
    pub experiments: Vec<Experiment>,
    pub weights: Weights,
}

impl Problem {
    /// Checks that the weights select some data in every experiment and that every weighted
    /// quantity occurs in some experiment.
    pub fn new(experiments: Vec<Experiment>, weights: Weights) -> Result<Self, ProblemError> {
        for e in &experiments {
            if cost::counted_points(&e.data, &weights) == 0 {
                return Err(ProblemError::NoDataInCost {
                    experiment: e.name.clone(),
                    quantities: e.data.quantities(),
                    weighted: weights.0.keys().cloned().collect(),
                });
            }
        }
        for q in weights.0.keys() {
            if !experiments.iter().any(|e| e.data.quantities().contains(q)) {
                return Err(ProblemError::WeightWithoutData { quantity: q.clone() });
            }
        }
        Ok(Self { experiments, weights })
    }

    /// Cost of experiment `k` at `parameters`, with its parts.
    pub fn fit_experiment(&self, k: usize, parameters: &BTreeMap<String, f64>) -> Result<Fit, ExperimentError> {
        let e = &self.experiments[k];
        evaluate_and_fit(e, &self.weights, parameters)
            .map_err(|error| ExperimentError { experiment: e.name.clone(), error })
    }

    /// Cost of experiment `k` as an outcome.
    pub fn evaluate_experiment(&self, k: usize, parameters: &BTreeMap<String, f64>) -> Outcome {
        match self.fit_experiment(k, parameters) {
            Ok(f) => Outcome::Ok { cost: f.cost },
            Err(e) => Outcome::Failed { reason: e.to_string() },
        }
    }

    /// Sum over the experiments; the first failure fails the whole evaluation.
    pub fn evaluate(&self, parameters: &BTreeMap<String, f64>) -> Outcome {
        let mut total = 0.0;
        for k in 0..self.experiments.len() {
            match self.evaluate_experiment(k, parameters) {
                Outcome::Ok { cost } => total += cost,
                failed => return failed,
            }
        }
        Outcome::Ok { cost: total }
    }

    /// Number of data points in the cost, over all experiments.
    pub fn data_points(&self) -> usize {
        self.experiments.iter().map(|e| cost::counted_points(&e.data, &self.weights)).sum()
    }
}

/// Runs `experiment`'s model at `parameters` and compares the output with its data.
pub fn evaluate_and_fit(
    experiment: &Experiment,
    weights: &Weights,
    parameters: &BTreeMap<String, f64>,
) -> Result<Fit, EvaluationError> {
    let out = experiment.model.evaluate(parameters)?;
    Ok(cost::fit(&out, &experiment.data, weights)?)
}

/// Why a problem cannot be built from its experiments and weights.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ProblemError {
    /// No series of an experiment carries a weight.
    #[error(
        "experiment `{experiment}`: none of its data enters the cost (its quantities: {}; weighted: {})",
        quantities.join(", "),
        weighted.join(", ")
    )]
    NoDataInCost {
        /// The experiment's name.
        experiment: String,
        /// The quantities of its data.
        quantities: Vec<String>,
        /// The weighted quantities.
        weighted: Vec<String>,
    },
    /// A weighted quantity that no experiment has data of.
    #[error("weights.{quantity}: no experiment has data of this quantity")]
    WeightWithoutData {
        /// The quantity.
        quantity: String,
    },
}

/// Why one evaluation of an experiment has no cost.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EvaluationError {
    /// The model gave no output.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The output cannot be compared with the data.
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// An evaluation of a named experiment that has no cost.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("experiment `{experiment}`: {error}")]
pub struct ExperimentError {
    /// The experiment's name.
    pub experiment: String,
    /// Why (its message is part of this error's).
    pub error: EvaluationError,
}

/// Why an experiment cannot be built from its case and data texts.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum BuildError {
    /// The case text is not a valid case.
    #[error(transparent)]
    Case(#[from] cryofit_solver::case::CaseError),
    /// The data text is not a valid data file.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The data name a station that the case does not have.
    #[error(
        "{data_label}: station `{station}` ({quantity}) is not a station of {case_label} (its stations: {})",
        case_stations.join(", ")
    )]
    UnknownStation {
        /// Names the data.
        data_label: String,
        /// Names the case.
        case_label: String,
        /// The station of the data.
        station: String,
        /// A quantity measured there.
        quantity: String,
        /// The case's stations.
        case_stations: Vec<String>,
    },
    /// The data run past the case's end time.
    #[error(
        "{data_label}: the data run to {data_end_s} s but {case_label} ends at time.end_s = {case_end_s} s; lengthen the case"
    )]
    DataPastCase {
        /// Names the data.
        data_label: String,
        /// Names the case.
        case_label: String,
        /// Last data time, s.
        data_end_s: f64,
        /// The case's `time.end_s`, s.
        case_end_s: f64,
    },
    /// The case's fluid table cannot be loaded.
    #[error("{case_label}: {message}")]
    Fluid {
        /// Names the case.
        case_label: String,
        /// The loader's reason.
        message: String,
    },
    /// A `[fixed]` case field that the case does not have or whose value it refuses.
    #[error("{case_label}: fixed.{name}: {error}")]
    FixedCaseField {
        /// Names the case.
        case_label: String,
        /// The fixed value's name (`case.<path>` or `case.<path>@<experiment>`).
        name: String,
        /// Why.
        error: cryofit_solver::case::FieldError,
    },
    /// The model cannot be built (for example the case's `[parameters]`).
    #[error("{case_label}: {error}")]
    Model {
        /// Names the case.
        case_label: String,
        /// Why (its message is part of this error's).
        error: ModelError,
    },
}

impl BuildError {
    /// True when the error lies in the data text (rather than in the case or its fluid).
    pub fn is_in_data(&self) -> bool {
        matches!(self, Self::Data(_) | Self::UnknownStation { .. } | Self::DataPastCase { .. })
    }
}

/// Unit coordinates where a calibration over `experiments` starts: a parameter at its value in
/// `given` (the calibration's `start` values, [`crate::config::CalibrationSpec::start_values`]),
/// else a registry parameter at its registry default, a case field at its value in the case of
/// the first experiment it applies to ([`Model::own_value`]), anything else at the middle of its
/// bounds; each clamped into its bounds.
pub fn default_start(
    space: &crate::space::Space,
    experiments: &[Experiment],
    given: &std::collections::BTreeMap<String, f64>,
) -> Vec<f64> {
    space
        .params()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let registry = || cryofit_solver::params::spec(&p.name).map(|s| s.default);
            let own = || experiments.iter().find_map(|e| e.model.own_value(&p.name));
            let value = given.get(&p.name).copied().or_else(registry).or_else(own);
            space.unit(i, value.unwrap_or(0.5 * (p.lower + p.upper)))
        })
        .collect()
}

/// The values a calibration holds fixed (its `[fixed]` table) as experiments are built with them:
/// the registry parameters as a parameter set, and the case fields (`case.<path>` for every
/// experiment, `case.<path>@<experiment>` for one), which are set in the cases before anything
/// else reads them, so that `"case.pipe.cells" = 120` makes every experiment run on 120 cells.
#[derive(Debug, Clone, Default)]
pub struct Fixed {
    params: cryofit_solver::params::ParameterSet,
    case_fields: BTreeMap<String, f64>,
}

impl Fixed {
    /// The fixed values `values` by name; an error names the value that is no registry parameter
    /// or lies outside its bounds. Case fields are checked where they are applied
    /// ([`Fixed::apply`]).
    pub fn new(values: &BTreeMap<String, f64>) -> Result<Self, FixedError> {
        let mut fixed = Self::default();
        for (name, &value) in values {
            if crate::apparatus::is_case_name(name) {
                fixed.case_fields.insert(name.clone(), value);
            } else {
                fixed.params.set(name, value).map_err(|error| FixedError { name: name.clone(), error })?;
            }
        }
        Ok(fixed)
    }

    /// The fixed registry parameters.
    pub fn params(&self) -> &cryofit_solver::params::ParameterSet {
        &self.params
    }

    /// `case` with the fixed case fields of experiment `experiment` set (a per-experiment value
    /// over a shared one), or the name of the first one it refuses and why.
    pub fn apply(
        &self,
        case: cryofit_solver::case::Case,
        experiment: &str,
    ) -> Result<cryofit_solver::case::Case, (String, cryofit_solver::case::FieldError)> {
        if self.case_fields.is_empty() {
            return Ok(case);
        }
        crate::apparatus::set_fields(&self.case_fields, &case, experiment)
    }
}

/// A `[fixed]` registry value that the registry refuses.
#[derive(Debug, thiserror::Error)]
#[error("fixed.{name}: {error}")]
pub struct FixedError {
    /// The value's name.
    pub name: String,
    /// Why.
    pub error: cryofit_solver::params::ParamError,
}

/// Builds one experiment from the texts of its case and data files (`*_label` name them in
/// errors): checks that every measured station exists in the case, under the same name, and that
/// the case runs at least as long as the data. The experiment's model runs only to the end of
/// the data ([`SolverModel::with_end_at`](crate::model::SolverModel::with_end_at)), and the
/// per-experiment case fields named `name` apply to it
/// ([`SolverModel::with_experiment`](crate::model::SolverModel::with_experiment)).
///
/// `fixed` holds the values that are not free, its case fields set in the case first;
/// `max_evaluation_s` bounds each run's computing time (a longer run is a failed evaluation).
#[allow(clippy::too_many_arguments)]
pub fn experiment_from_texts(
    name: &str,
    case_text: &str,
    case_label: &str,
    data_text: &str,
    data_label: &str,
    fluid: impl FnOnce(&str) -> Result<Arc<cryofit_solver::fluids::FluidTable>, String>,
    fixed: &Fixed,
    max_evaluation_s: Option<f64>,
) -> Result<Experiment, BuildError> {
    let case = cryofit_solver::case::Case::from_toml(case_text, case_label)?;
    let case = fixed.apply(case, name).map_err(|(name, error)| BuildError::FixedCaseField {
        case_label: case_label.to_string(),
        name,
        error,
    })?;
    let data = Dataset::from_csv(data_text, data_label)?;
    for (station, quantity) in data.series.keys() {
        if !case.stations.iter().any(|s| &s.name == station) {
            return Err(BuildError::UnknownStation {
                data_label: data_label.to_string(),
                case_label: case_label.to_string(),
                station: station.clone(),
                quantity: quantity.clone(),
                case_stations: case.stations.iter().map(|s| s.name.clone()).collect(),
            });
        }
    }
    if data.end_time() > case.time.end_s {
        return Err(BuildError::DataPastCase {
            data_label: data_label.to_string(),
            case_label: case_label.to_string(),
            data_end_s: data.end_time(),
            case_end_s: case.time.end_s,
        });
    }
    let table =
        fluid(&case.fluid.name).map_err(|message| BuildError::Fluid { case_label: case_label.to_string(), message })?;
    let model = crate::model::SolverModel::new(case, table, fixed.params())
        .map_err(|error| BuildError::Model { case_label: case_label.to_string(), error })?
        .with_experiment(name)
        .with_wall_limit(max_evaluation_s)
        .with_end_at(data.end_time());
    Ok(Experiment { name: name.to_string(), model: Arc::new(model), data })
}
