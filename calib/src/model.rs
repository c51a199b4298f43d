//! Models: parameters in, time series out. The two-fluid solver is the main one; analytic
//! models implement the same trait for tests and service benchmarks.

use std::collections::BTreeMap;
use std::sync::Arc;

use cryofit_solver::case::{Case, FieldError};
use cryofit_solver::driver;
use cryofit_solver::fluids::FluidTable;
use cryofit_solver::params::{ParamError, ParameterSet};

use crate::data::{Dataset, Series};

/// Why a model gave no time series.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A parameter name or value is not acceptable.
    #[error(transparent)]
    Parameter(#[from] ParamError),
    /// The solver stopped before the end of the run (its error carries the numbers).
    #[error(transparent)]
    Simulation(#[from] driver::SimError),
    /// The case fields of a point do not make a valid case.
    #[error("case fields: {0}")]
    CaseField(#[from] FieldError),
    /// A model other than the solver failed, for the reason given.
    #[error("{0}")]
    Failed(String),
}

/// A model evaluated at named parameter values (registry names and case fields, see
/// [`crate::apparatus`]; physical units).
pub trait Model: Send + Sync + 'static {
    /// The model's time series, or why the run failed (for example where the solver diverged).
    fn evaluate(&self, parameters: &BTreeMap<String, f64>) -> Result<Dataset, ModelError>;

    /// The value the model runs with for `name` when a point does not give it, where the model
    /// holds one of its own (the solver: a case field's value in its case); `None` otherwise.
    /// A calibration starts a case field there.
    fn own_value(&self, _name: &str) -> Option<f64> {
        None
    }

    /// The model as `Any`, so that callers can reach a concrete model's own methods (for
    /// example the solver's full output for reports).
    fn as_any(&self) -> &dyn std::any::Any;
}

/// The two-fluid solver on one case.
///
/// A point's registry names set closure parameters; its case fields (`case.<path>`, and
/// `case.<path>@<experiment>` for this model's experiment, see [`crate::apparatus`]) are set in a
/// copy of the case before each run; the per-experiment values of other experiments are ignored.
#[derive(Debug, Clone)]
pub struct SolverModel {
    case: Case,
    fluid: Arc<FluidTable>,
    base: ParameterSet,
    /// Where [`SolverModel::run`] ends, s (at most the case's `time.end_s`).
    stop_s: f64,
    /// The experiment whose case this is ([`SolverModel::with_experiment`]).
    experiment: Option<String>,
}

impl SolverModel {
    /// `base` holds the values of parameters that are not free (the case's own `[parameters]`
    /// are applied first, `base` over them, the free values over both).
    pub fn new(case: Case, fluid: Arc<FluidTable>, base: &ParameterSet) -> Result<Self, ModelError> {
        let mut set = driver::case_parameters(&case)?;
        set.overlay(base);
        let stop_s = case.time.end_s;
        Ok(Self { case, fluid, base: set, stop_s, experiment: None })
    }

    /// Names the experiment whose case this is: the per-experiment case fields of that name
    /// (`case.<path>@<experiment>`) apply to its runs.
    pub fn with_experiment(mut self, name: &str) -> Self {
        self.experiment = Some(name.to_string());
        self
    }

    /// The experiment whose case this is, if one was named.
    pub fn experiment(&self) -> Option<&str> {
        self.experiment.as_deref()
    }

    /// Sets the per-run wall-clock limit, s (a longer run ends as a failed evaluation).
    pub fn with_wall_limit(mut self, seconds: Option<f64>) -> Self {
        if let Some(s) = seconds {
            self.case.time.max_wall_s = Some(self.case.time.max_wall_s.map_or(s, |w| w.min(s)));
        }
        self
    }

    /// Ends each run at the first probe output time at or after `t_s` (never later than the
    /// case's own `time.end_s`).
    ///
    /// A calibration's cost reads the model only at the data's times, so simulating past the
    /// last of them changes no cost: it only spends time, and can turn a run whose fit is known
    /// into a failed evaluation. The NBS cases run 1000 s for their chilldown summaries while
    /// their data end at 132–250 s; ending there saves about 30 % of a default run's steps. The
    /// end is rounded up to an output time so that the data's last time is bracketed by probes
    /// (the driver records probes on its output grid, starting at time 0).
    /// [`SolverModel::run_full`] still runs the whole case (for the best fit's summaries).
    pub fn with_end_at(mut self, t_s: f64) -> Self {
        let t = &self.case.time;
        let interval = t.output_interval_s;
        if t_s.is_finite() && t_s >= 0.0 && interval > 0.0 {
            let k = (t_s / interval - 1e-9).ceil().max(0.0);
            self.stop_s = t.end_s.min(k * interval);
        }
        self
    }

    /// Where [`SolverModel::run`] ends, s.
    pub fn stop_s(&self) -> f64 {
        self.stop_s
    }

    /// The case as given (no case field of a point set).
    pub fn case(&self) -> &Case {
        &self.case
    }

    /// The full parameter set of a run at `parameters`: its registry names over the base values
    /// (its case fields are for [`SolverModel::case_at`]).
    pub fn parameter_set(&self, parameters: &BTreeMap<String, f64>) -> Result<ParameterSet, ModelError> {
        let mut set = self.base.clone();
        for (name, &value) in parameters.iter().filter(|(name, _)| !crate::apparatus::is_case_name(name)) {
            set.set(name, value)?;
        }
        Ok(set)
    }

    /// The case a run at `parameters` simulates: this model's case with the case fields of
    /// `parameters` that apply to its experiment set and validated.
    pub fn case_at(&self, parameters: &BTreeMap<String, f64>) -> Result<Case, ModelError> {
        let sorted = crate::apparatus::sort(parameters, self.experiment.as_deref());
        Ok(sorted.apply(&self.case)?)
    }

    /// Runs the solver to [`SolverModel::stop_s`] and returns its whole output.
    pub fn run(&self, parameters: &BTreeMap<String, f64>) -> Result<driver::Output, ModelError> {
        let mut case = self.case_at(parameters)?;
        case.time.end_s = case.time.end_s.min(self.stop_s);
        self.run_case(&case, parameters)
    }

    /// Runs the solver to the case's own `time.end_s`.
    pub fn run_full(&self, parameters: &BTreeMap<String, f64>) -> Result<driver::Output, ModelError> {
        let case = self.case_at(parameters)?;
        self.run_case(&case, parameters)
    }

    fn run_case(&self, case: &Case, parameters: &BTreeMap<String, f64>) -> Result<driver::Output, ModelError> {
        let set = self.parameter_set(parameters)?;
        Ok(driver::run(case, &self.fluid, &set, &mut |_| {})?)
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
    fn evaluate(&self, parameters: &BTreeMap<String, f64>) -> Result<Dataset, ModelError> {
        self.run(parameters).map(|out| probes_dataset(&out.probes))
    }

    fn own_value(&self, name: &str) -> Option<f64> {
        let field = crate::apparatus::case_name(name)?;
        if field.experiment.is_some_and(|e| Some(e) != self.experiment.as_deref()) {
            return None;
        }
        self.case.field(field.path).ok()
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}
