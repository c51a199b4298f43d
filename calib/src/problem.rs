//! A calibration problem: experiments (a model and its data each) and the cost weights.
//! Evaluating a parameter point runs every experiment and sums their costs.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::api::Outcome;
use crate::cost::{self, Fit, Weights};
use crate::data::Dataset;
use crate::model::Model;

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
    pub fn new(experiments: Vec<Experiment>, weights: Weights) -> Result<Self, String> {
        for e in &experiments {
            if cost::counted_points(&e.data, &weights) == 0 {
                return Err(format!(
                    "experiment `{}`: none of its data enters the cost (its quantities: {}; weighted: {})",
                    e.name,
                    e.data.quantities().join(", "),
                    weights.0.keys().cloned().collect::<Vec<_>>().join(", ")
                ));
            }
        }
        for q in weights.0.keys() {
            if !experiments.iter().any(|e| e.data.quantities().contains(q)) {
                return Err(format!("weights.{q}: no experiment has data of this quantity"));
            }
        }
        Ok(Self { experiments, weights })
    }

    /// Cost of experiment `k` at `parameters`, with its parts.
    pub fn fit_experiment(&self, k: usize, parameters: &BTreeMap<String, f64>) -> Result<Fit, String> {
        let e = &self.experiments[k];
        let out = e.model.evaluate(parameters).map_err(|m| format!("experiment `{}`: {m}", e.name))?;
        cost::fit(&out, &e.data, &self.weights).map_err(|m| format!("experiment `{}`: {m}", e.name))
    }

    /// Cost of experiment `k` as an outcome.
    pub fn evaluate_experiment(&self, k: usize, parameters: &BTreeMap<String, f64>) -> Outcome {
        match self.fit_experiment(k, parameters) {
            Ok(f) => Outcome::Ok { cost: f.cost },
            Err(reason) => Outcome::Failed { reason },
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

/// Builds one experiment from the texts of its case and data files (`*_label` name them in
/// errors): checks that every measured station exists in the case, under the same name, and that
/// the case runs at least as long as the data. The experiment's model runs only to the end of
/// the data ([`SolverModel::with_end_at`](crate::model::SolverModel::with_end_at)).
///
/// `fixed` holds parameter values that are not free; `max_evaluation_s` bounds each run's
/// computing time (a longer run is a failed evaluation).
#[allow(clippy::too_many_arguments)]
pub fn experiment_from_texts(
    name: &str,
    case_text: &str,
    case_label: &str,
    data_text: &str,
    data_label: &str,
    fluid: impl FnOnce(&str) -> Result<Arc<cryofit_solver::fluids::FluidTable>, String>,
    fixed: &cryofit_solver::params::ParameterSet,
    max_evaluation_s: Option<f64>,
) -> Result<Experiment, String> {
    let case = cryofit_solver::case::Case::from_toml(case_text, case_label).map_err(|e| e.to_string())?;
    let data = Dataset::from_csv(data_text, data_label).map_err(|e| e.to_string())?;
    for (station, quantity) in data.series.keys() {
        if !case.stations.iter().any(|s| &s.name == station) {
            let known: Vec<&str> = case.stations.iter().map(|s| s.name.as_str()).collect();
            return Err(format!(
                "{data_label}: station `{station}` ({quantity}) is not a station of {case_label} (its stations: {})",
                known.join(", ")
            ));
        }
    }
    if data.end_time() > case.time.end_s {
        return Err(format!(
            "{data_label}: the data run to {} s but {case_label} ends at time.end_s = {} s; lengthen the case",
            data.end_time(),
            case.time.end_s
        ));
    }
    let table = fluid(&case.fluid.name).map_err(|e| format!("{case_label}: {e}"))?;
    let model = crate::model::SolverModel::new(case, table, fixed)
        .map_err(|e| format!("{case_label}: {e}"))?
        .with_wall_limit(max_evaluation_s)
        .with_end_at(data.end_time());
    Ok(Experiment { name: name.to_string(), model: Arc::new(model), data })
}
