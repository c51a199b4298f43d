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
