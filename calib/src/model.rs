//! Models: parameters in, time series out. The two-fluid solver is the main one; analytic
//! models implement the same trait for tests and service benchmarks.

use std::collections::BTreeMap;
use std::sync::Arc;

use cryofit_solver::case::Case;
use cryofit_solver::driver;
use cryofit_solver::fluids::FluidTable;
use cryofit_solver::params::ParameterSet;

use crate::data::{Dataset, Series};

/// A model evaluated at named parameter values (registry names, physical units).
pub trait Model: Send + Sync + 'static {
    /// The model's time series, or why the run failed (for example where the solver diverged).
    fn evaluate(&self, parameters: &BTreeMap<String, f64>) -> Result<Dataset, String>;

    /// The model as `Any`, so that callers can reach a concrete model's own methods (for
    /// example the solver's full output for reports).
    fn as_any(&self) -> &dyn std::any::Any;
}

/// The two-fluid solver on one case.
#[derive(Debug, Clone)]
pub struct SolverModel {
    case: Case,
    fluid: Arc<FluidTable>,
    base: ParameterSet,
}

impl SolverModel {
    /// `base` holds the values of parameters that are not free (the case's own `[parameters]`
    /// are applied first, `base` over them, the free values over both).
    pub fn new(case: Case, fluid: Arc<FluidTable>, base: &ParameterSet) -> Result<Self, String> {
        let mut set = driver::case_parameters(&case).map_err(|e| e.to_string())?;
        set.overlay(base);
        Ok(Self { case, fluid, base: set })
    }

    /// Sets the per-run wall-clock limit, s (a longer run ends as a failed evaluation).
    pub fn with_wall_limit(mut self, seconds: Option<f64>) -> Self {
        if let Some(s) = seconds {
            self.case.time.max_wall_s = Some(self.case.time.max_wall_s.map_or(s, |w| w.min(s)));
        }
        self
    }

    pub fn case(&self) -> &Case {
        &self.case
    }

    /// The full parameter set of a run at `parameters`.
    pub fn parameter_set(&self, parameters: &BTreeMap<String, f64>) -> Result<ParameterSet, String> {
        let mut set = self.base.clone();
        for (name, &value) in parameters {
            set.set(name, value).map_err(|e| e.to_string())?;
        }
        Ok(set)
    }

    /// Runs the solver and returns its whole output.
    pub fn run(&self, parameters: &BTreeMap<String, f64>) -> Result<driver::Output, String> {
        let set = self.parameter_set(parameters)?;
        driver::run(&self.case, &self.fluid, &set, &mut |_| {}).map_err(|e| e.to_string())
    }
}

/// Probes of a solver run as a dataset.
pub fn probes_dataset(probes: &[driver::Observation]) -> Dataset {
    let mut d = Dataset::default();
    for o in probes {
        let s = d.series.entry((o.station.clone(), o.quantity.to_string())).or_insert_with(|| Series {
            x_m: o.x_m,
            times: Vec::new(),
            values: Vec::new(),
        });
        // probes are recorded in time order; a repeated time (an output landing twice) keeps the last
        if s.times.last() == Some(&o.time_s) {
            if let Some(v) = s.values.last_mut() {
                *v = o.value;
            }
        } else {
            s.times.push(o.time_s);
            s.values.push(o.value);
        }
    }
    d
}

impl Model for SolverModel {
    fn evaluate(&self, parameters: &BTreeMap<String, f64>) -> Result<Dataset, String> {
        self.run(parameters).map(|out| probes_dataset(&out.probes))
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}
