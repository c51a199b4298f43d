//! A calibration's stage pipeline: sensitivity → direct search → CMA-ES → variance → posterior,
//! or any sequence of stages, each starting from the previous one's result.
//!
//! [`Pipeline`] is itself ask/tell: it hands out [`Job`]s (a candidate in the full free-parameter
//! space, with physical values by name) and takes costs back in any order. Candidate ids are
//! global across stages. A sensitivity or Morris stage narrows the free set of the stages after it
//! to its suggested parameters (the others stay at the values of the best point so far). The whole
//! state serialises with the crate feature `serde`, so a coordinator can persist it after every
//! tell and resume it bit-identically.

use std::collections::BTreeMap;

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::api::{Best, Evaluation, Optimizer, Outcome, StopReason, TellError};
use crate::config::{AlgorithmName, SpecError, StageSpec, Temperature};
use crate::inference::{
    self, EnsembleSampler, InferenceAlgorithm, InferenceSummary, McmcOptions, Morris, MorrisOptions, NelderMead,
    NelderMeadOptions, Sensitivity, SensitivityOptions, Variance, VarianceOptions,
};
use crate::optim::{
    AnnealingOptions, CmaesOptions, DirectSearchOptions, GeneticOptions, GlobalAlgorithm, GlobalOptions, OptimError,
    PatternOptions, SwarmOptions,
};
use crate::space::{Space, SpaceError};

/// Why a stage's algorithm cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum StageError {
    /// A global optimiser refused its options, budget or start point.
    #[error("{algorithm}: {error}")]
    Global {
        /// The stage's algorithm.
        algorithm: AlgorithmName,
        /// Why (its message is part of this error's).
        error: OptimError,
    },
    /// An inference algorithm refused its options, budget or start point.
    #[error(transparent)]
    Inference(#[from] inference::InferenceError),
    /// The stage's free parameters do not make a space.
    #[error(transparent)]
    Space(#[from] SpaceError),
}

/// Why a pipeline cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PipelineError {
    /// No stages.
    #[error("stages: at least one stage is needed")]
    NoStages,
    /// The start point does not fit the space.
    #[error("start point must have {dim} unit coordinates in [0, 1]")]
    StartPoint {
        /// The space's dimension.
        dim: usize,
    },
    /// A stage's settings are not valid.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// The free parameters do not make a space.
    #[error(transparent)]
    Space(#[from] SpaceError),
    /// MCMC stage `index` asks for the noise temperature without a variance stage before it.
    #[error(
        "stages[{index}].temperature = \"noise\" takes the cost's jitter from a variance stage before the \
         MCMC stage, and there is none: put a variance stage before it or give the temperature as a number ≥ 1"
    )]
    NoiseWithoutVariance {
        /// The MCMC stage's index.
        index: usize,
    },
    /// Stage `index` cannot be built.
    #[error("stages[{index}]: {error}")]
    Stage {
        /// The stage's index.
        index: usize,
        /// Why (its message is part of this error's).
        error: StageError,
    },
}

/// The algorithm of the running stage.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum StageAlgorithm {
    Global(Box<GlobalAlgorithm>),
    Inference(Box<InferenceAlgorithm>),
}

impl StageAlgorithm {
    fn inner(&self) -> &dyn Optimizer {
        match self {
            Self::Global(a) => a.as_ref(),
            Self::Inference(a) => a.as_ref(),
        }
    }

    fn inner_mut(&mut self) -> &mut dyn Optimizer {
        match self {
            Self::Global(a) => a.as_mut(),
            Self::Inference(a) => a.as_mut(),
        }
    }
}

/// Builds the algorithm of `spec` on `space` (the stage's free parameters), starting at `start`.
/// `noise_temperature` is what an MCMC stage's `temperature = "noise"` stands for (the last
/// variance stage's noise inflation; 1 when none was measured).
pub fn build_stage(
    spec: &StageSpec,
    space: &Space,
    start: Option<&[f64]>,
    seed: u64,
    noise_temperature: f64,
) -> Result<StageAlgorithm, StageError> {
    let d = space.dim();
    let b = spec.budget;
    let name = spec.algorithm;
    let global = |o: GlobalOptions| {
        GlobalAlgorithm::new(d, start, o, b, seed)
            .map(|a| StageAlgorithm::Global(Box::new(a)))
            .map_err(|error| StageError::Global { algorithm: name, error })
    };
    let inf = |r: Result<InferenceAlgorithm, inference::InferenceError>| {
        Ok(r.map(|a| StageAlgorithm::Inference(Box::new(a)))?)
    };
    match name {
        AlgorithmName::Sensitivity => {
            let mut o = SensitivityOptions::default();
            o.relative_step = spec.step.unwrap_or(o.relative_step);
            o.max_free = spec.keep.unwrap_or(o.max_free);
            o.free_fraction = spec.threshold.unwrap_or(o.free_fraction);
            inf(Sensitivity::new(space, start, o, b, seed).map(InferenceAlgorithm::Sensitivity))
        }
        AlgorithmName::Morris => {
            let mut o = MorrisOptions::default();
            o.trajectories = spec.trajectories.unwrap_or(o.trajectories);
            o.levels = spec.levels.unwrap_or(o.levels);
            o.max_free = spec.keep.unwrap_or(o.max_free);
            o.free_fraction = spec.threshold.unwrap_or(o.free_fraction);
            inf(Morris::new(d, start, o, b, seed).map(InferenceAlgorithm::Morris))
        }
        AlgorithmName::NelderMead => {
            let mut o = NelderMeadOptions::default();
            o.initial_step = spec.step.unwrap_or(o.initial_step);
            if let Some(t) = spec.tolerance {
                o.f_tol = t;
            }
            inf(NelderMead::new(d, start, o, b, seed).map(InferenceAlgorithm::NelderMead))
        }
        AlgorithmName::Variance => {
            let mut o = VarianceOptions::default();
            o.restarts = spec.restarts.unwrap_or(o.restarts);
            o.hessian_step = spec.step.unwrap_or(o.hessian_step);
            if let Some(t) = spec.tolerance {
                o.f_tol = t;
            }
            inf(Variance::new(space, start, o, b, seed).map(|v| InferenceAlgorithm::Variance(Box::new(v))))
        }
        AlgorithmName::Mcmc => {
            let mut o = McmcOptions::default();
            o.walkers = spec.walkers.or(o.walkers);
            o.burn_in = spec.burn_in.unwrap_or(o.burn_in);
            o.initial_spread = spec.spread.unwrap_or(o.initial_spread);
            o.temperature = match spec.temperature {
                Some(Temperature::Value(t)) => t,
                Some(Temperature::Noise) => noise_temperature,
                None => o.temperature,
            };
            inf(EnsembleSampler::new(space, start, o, b, seed).map(|m| InferenceAlgorithm::Mcmc(Box::new(m))))
        }
        AlgorithmName::DirectSearch => {
            let mut o = DirectSearchOptions::default();
            o.points = spec.points.unwrap_or(o.points);
            o.initial_span = spec.span.unwrap_or(o.initial_span);
            o.tolerance = spec.tolerance;
            global(GlobalOptions::DirectSearch(o))
        }
        AlgorithmName::Pattern => {
            let mut o = PatternOptions::default();
            o.initial_step = spec.step.unwrap_or(o.initial_step);
            o.tolerance = spec.tolerance;
            global(GlobalOptions::Pattern(o))
        }
        AlgorithmName::Annealing => {
            let mut o = AnnealingOptions::default();
            o.initial_step = spec.step.unwrap_or(o.initial_step);
            o.batch = spec.population.unwrap_or(o.batch);
            o.tolerance = spec.tolerance;
            global(GlobalOptions::Annealing(o))
        }
        AlgorithmName::Genetic => {
            let mut o = GeneticOptions::default();
            o.population = spec.population.or(o.population);
            o.mutation_rate = spec.mutation.or(o.mutation_rate);
            o.tolerance = spec.tolerance;
            global(GlobalOptions::Genetic(o))
        }
        AlgorithmName::Swarm => {
            let mut o = SwarmOptions::default();
            o.swarm = spec.population.or(o.swarm);
            o.tolerance = spec.tolerance;
            global(GlobalOptions::Swarm(o))
        }
        AlgorithmName::Cmaes => {
            let mut o = CmaesOptions::default();
            o.population = spec.population.or(o.population);
            o.sigma = spec.sigma.unwrap_or(o.sigma);
            o.tolfun = spec.tolerance;
            o.stall_generations = spec.stall_generations;
            global(GlobalOptions::Cmaes(o))
        }
    }
}

/// One evaluation to run: every experiment at these parameter values.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Job {
    /// Global id, unique within the calibration.
    pub id: u64,
    /// Index of the stage that asked for it.
    pub stage: usize,
    /// Unit coordinates in the full free space.
    pub unit: Vec<f64>,
    /// Physical values of the free parameters, by name.
    pub parameters: BTreeMap<String, f64>,
}

/// What a finished stage did.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct StageReport {
    pub index: usize,
    pub algorithm: AlgorithmName,
    pub budget: usize,
    /// Evaluations the stage ran.
    pub evaluations: usize,
    pub failed_evaluations: usize,
    /// Parameters free during the stage.
    pub free: Vec<String>,
    /// The stage's estimate's cost: its lowest evaluation's, or a variance stage's accepted
    /// response-surface minimum's (`None` when every evaluation failed).
    pub best_cost: Option<f64>,
    /// The stage's lowest evaluated cost (differs from `best_cost` when a response surface's
    /// minimum is the estimate).
    #[cfg_attr(feature = "serde", serde(default))]
    pub lowest_cost: Option<f64>,
    /// Its parameters (all free parameters of the calibration, by name).
    pub best_parameters: BTreeMap<String, f64>,
    /// Why it stopped.
    pub stop: String,
    /// Sensitivity, variance and posterior details.
    pub details: Option<InferenceSummary>,
    /// Posterior draws of an MCMC stage: physical values of the stage's free parameters
    /// ([`StageReport::free`] order), [`POSTERIOR_DRAWS`] of them.
    pub posterior_draws: Option<Vec<Vec<f64>>>,
}

/// Whether stage `k` of `stages` asks for `temperature = "noise"` with no variance stage before it
/// to measure the noise.
pub fn noise_unmeasured(stages: &[StageSpec], k: usize) -> bool {
    stages[k].temperature == Some(Temperature::Noise)
        && !stages[..k].iter().any(|p| p.algorithm == AlgorithmName::Variance)
}

/// The noise inflation `1 + 2σ_ε` the last variance stage among `reports` measured (1 when it
/// measured no noise), or `None` when none of them is a variance stage.
pub fn measured_noise_temperature(reports: &[StageReport]) -> Option<f64> {
    reports.iter().rev().find_map(|r| match &r.details {
        Some(InferenceSummary::Variance(v)) => Some(v.gaussian.as_ref().map_or(1.0, |g| g.noise_inflation)),
        _ => None,
    })
}

/// Number of posterior draws an MCMC stage keeps for predictions.
pub const POSTERIOR_DRAWS: usize = 1000;

/// The stage that is running.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Running {
    index: usize,
    /// Indices (into the full space) of the free parameters of this stage.
    active: Vec<usize>,
    algorithm: StageAlgorithm,
    /// local candidate id → global job id, for handed-out candidates not yet told.
    outstanding: BTreeMap<u64, u64>,
    evaluations: usize,
    failed: usize,
    /// Best (cost, job id, full unit point) of this stage.
    best: Option<(f64, u64, Vec<f64>)>,
    /// A variance stage's response-surface minimum, once evaluated and accepted: the stage's
    /// estimate (full unit point, global id) and the surface's prediction and residual RMS there.
    #[cfg_attr(feature = "serde", serde(default))]
    estimate: Option<(Best, Smoothed)>,
}

/// A smoothed estimate's standing: the response surface's prediction at it and the surface's
/// residual RMS. A later evaluation replaces the estimate only when its cost is below the
/// prediction by more than three residual RMS, so that a lucky draw of a jittering cost does not.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Smoothed {
    #[cfg_attr(feature = "serde", serde(with = "crate::exact"))]
    predicted: f64,
    #[cfg_attr(feature = "serde", serde(with = "crate::exact"))]
    residual_rms: f64,
}

impl Smoothed {
    fn beaten_by(&self, cost: f64) -> bool {
        cost < self.predicted - 3.0 * self.residual_rms
    }
}

/// A handed-out job: the stage algorithm's candidate id and the job's full unit point.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Pending {
    local: u64,
    unit: Vec<f64>,
}

/// The whole calibration: stages in order, the best point so far, progress counts.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Pipeline {
    space: Space,
    stages: Vec<StageSpec>,
    seed: u64,
    /// Full unit point that inactive parameters are held at (the best so far, or the start).
    anchor: Vec<f64>,
    /// Free parameters of the next stage.
    active: Vec<usize>,
    running: Option<Running>,
    next_stage: usize,
    next_id: u64,
    /// Outstanding jobs by id.
    jobs: BTreeMap<u64, Pending>,
    /// The calibration's estimate: the lowest-cost evaluation, or a variance stage's smoothed
    /// minimum (then `smoothed` is set) until an evaluation beats it beyond the cost's jitter.
    best: Option<Best>,
    #[cfg_attr(feature = "serde", serde(default))]
    smoothed: Option<Smoothed>,
    evaluations: usize,
    failed: usize,
    reports: Vec<StageReport>,
    error: Option<String>,
}

/// Seed of stage `k`: distinct, reproducible streams per stage.
fn stage_seed(seed: u64, k: usize) -> u64 {
    seed ^ (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

impl Pipeline {
    /// A pipeline over `space` starting at `start` (full unit coordinates, e.g. the registry
    /// defaults). Every stage is built once up front, on as many parameters as it can have free
    /// (all of them, or at most a preceding screen's `keep`), so that bad options or a budget too
    /// small for an algorithm are reported before anything runs.
    pub fn new(space: Space, stages: Vec<StageSpec>, start: Vec<f64>, seed: u64) -> Result<Self, PipelineError> {
        if stages.is_empty() {
            return Err(PipelineError::NoStages);
        }
        if start.len() != space.dim() || start.iter().any(|u| !(0.0..=1.0).contains(u)) {
            return Err(PipelineError::StartPoint { dim: space.dim() });
        }
        // the largest free set each stage can see: a screen keeps at most `keep` (default 20)
        let mut dim = space.dim();
        for (k, s) in stages.iter().enumerate() {
            s.validate(&format!("stages[{k}]"))?;
            if noise_unmeasured(&stages, k) {
                return Err(PipelineError::NoiseWithoutVariance { index: k });
            }
            let sub = Space::new(space.params()[..dim].to_vec())?;
            build_stage(s, &sub, Some(&start[..dim]), stage_seed(seed, k), 1.0)
                .map_err(|error| PipelineError::Stage { index: k, error })?;
            if matches!(s.algorithm, AlgorithmName::Sensitivity | AlgorithmName::Morris) {
                dim = dim.min(s.keep.unwrap_or(SensitivityOptions::default().max_free));
            }
        }
        let active = (0..space.dim()).collect();
        Ok(Self {
            space,
            stages,
            seed,
            anchor: start,
            active,
            running: None,
            next_stage: 0,
            next_id: 0,
            jobs: BTreeMap::new(),
            best: None,
            smoothed: None,
            evaluations: 0,
            failed: 0,
            reports: Vec::new(),
            error: None,
        })
    }

    pub fn space(&self) -> &Space {
        &self.space
    }

    pub fn stages(&self) -> &[StageSpec] {
        &self.stages
    }

    /// Reports of the finished stages.
    pub fn reports(&self) -> &[StageReport] {
        &self.reports
    }

    /// Index of the running stage (or of the next one to start).
    pub fn stage(&self) -> usize {
        self.running.as_ref().map_or(self.next_stage, |r| r.index)
    }

    /// Evaluations told so far, and how many of them failed.
    pub fn evaluations(&self) -> (usize, usize) {
        (self.evaluations, self.failed)
    }

    /// Total budget of all stages (saturating: a sum past `usize::MAX` reads as `usize::MAX`).
    pub fn budget(&self) -> usize {
        self.stages.iter().fold(0usize, |t, s| t.saturating_add(s.budget))
    }

    /// The calibration's estimate so far (full unit coordinates): the lowest-cost evaluation, or,
    /// after a variance stage whose response surface gave an accepted minimum, that minimum's
    /// evaluation, until a later evaluation is lower than the surface's prediction by more than
    /// three residual RMS (see [`crate::inference::ResponseSurface`]).
    pub fn best(&self) -> Option<&Best> {
        self.best.as_ref()
    }

    /// Physical values by name of a full unit point.
    pub fn parameters(&self, unit: &[f64]) -> BTreeMap<String, f64> {
        self.space.names().map(str::to_string).zip(self.space.to_physical(unit)).collect()
    }

    /// The error that stopped the pipeline, if one did (a stage that could not be built).
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// Number of jobs handed out and not yet told.
    pub fn outstanding(&self) -> usize {
        self.jobs.len()
    }

    /// True once every stage has finished (or the pipeline stopped on an error).
    pub fn is_finished(&self) -> bool {
        self.error.is_some() || (self.running.is_none() && self.next_stage >= self.stages.len())
    }

    /// The noise inflation `1 + 2σ_ε` the last finished variance stage measured (1 when it
    /// measured no noise, or there was none): an MCMC stage's `temperature = "noise"`.
    pub fn noise_temperature(&self) -> f64 {
        measured_noise_temperature(&self.reports).unwrap_or(1.0)
    }

    fn start_stage(&mut self) -> Result<(), StageError> {
        let k = self.next_stage;
        let spec = &self.stages[k];
        let params: Vec<_> = self.active.iter().map(|&i| self.space.params()[i].clone()).collect();
        let sub = Space::new(params)?;
        let start: Vec<f64> = self.active.iter().map(|&i| self.anchor[i]).collect();
        let algorithm = build_stage(spec, &sub, Some(&start), stage_seed(self.seed, k), self.noise_temperature())?;
        self.running = Some(Running {
            index: k,
            active: self.active.clone(),
            algorithm,
            outstanding: BTreeMap::new(),
            evaluations: 0,
            failed: 0,
            best: None,
            estimate: None,
        });
        self.next_stage += 1;
        Ok(())
    }

    fn finish_stage(&mut self, stop: StopReason) {
        let Some(r) = self.running.take() else { return };
        let spec = &self.stages[r.index];
        let details = match &r.algorithm {
            StageAlgorithm::Inference(a) => Some(a.summary()),
            StageAlgorithm::Global(_) => None,
        };
        let posterior_draws = match &r.algorithm {
            StageAlgorithm::Inference(a) => match a.as_ref() {
                InferenceAlgorithm::Mcmc(m) => {
                    Some(m.samples(POSTERIOR_DRAWS, stage_seed(self.seed, r.index)).physical)
                }
                _ => None,
            },
            StageAlgorithm::Global(_) => None,
        };
        // a sensitivity screen narrows the free set of the stages after it
        let suggested = match &details {
            Some(InferenceSummary::Sensitivity(s)) => Some(s.suggested_free.clone()),
            Some(InferenceSummary::Morris(m)) => Some(m.suggested_free.clone()),
            _ => None,
        };
        if let Some(sel) = suggested
            && !sel.is_empty()
        {
            let mut next: Vec<usize> = sel.iter().filter_map(|&j| r.active.get(j).copied()).collect();
            next.sort_unstable();
            self.active = next;
        }
        let names = |idx: &[usize]| idx.iter().map(|&i| self.space.params()[i].name.clone()).collect::<Vec<_>>();
        // a variance stage's accepted response-surface minimum is its estimate, and the calibration's
        if let Some((best, smoothed)) = &r.estimate {
            self.best = Some(best.clone());
            self.smoothed = Some(*smoothed);
        }
        let (best_cost, best_parameters) = match (&r.estimate, &r.best) {
            (Some((b, _)), _) => (Some(b.cost), self.parameters(&b.unit)),
            (None, Some((c, _, u))) => (Some(*c), self.parameters(u)),
            (None, None) => (None, BTreeMap::new()),
        };
        // the next stage starts from the best point so far
        if let Some(b) = &self.best {
            self.anchor = b.unit.clone();
        }
        self.reports.push(StageReport {
            index: r.index,
            algorithm: spec.algorithm,
            budget: spec.budget,
            evaluations: r.evaluations,
            failed_evaluations: r.failed,
            free: names(&r.active),
            best_cost,
            lowest_cost: r.best.as_ref().map(|(c, _, _)| *c),
            best_parameters,
            stop: stop.to_string(),
            details,
            posterior_draws,
        });
    }

    /// Up to `n` jobs. Fewer (or none) while a generation-synchronous stage waits for results;
    /// none once the pipeline is finished.
    pub fn ask(&mut self, n: usize) -> Vec<Job> {
        loop {
            if self.is_finished() || n == 0 {
                return Vec::new();
            }
            if self.running.is_none()
                && let Err(e) = self.start_stage()
            {
                self.error = Some(format!("stages[{}]: {e}", self.next_stage));
                return Vec::new();
            }
            let r = self.running.as_mut().expect("a stage is running");
            let asked = r.algorithm.inner_mut().ask(n);
            if !asked.is_empty() {
                let mut jobs = Vec::with_capacity(asked.len());
                for c in asked {
                    let id = self.next_id;
                    self.next_id += 1;
                    let mut unit = self.anchor.clone();
                    for (&i, &u) in r.active.iter().zip(&c.unit) {
                        unit[i] = u;
                    }
                    r.outstanding.insert(c.id, id);
                    self.jobs.insert(id, Pending { local: c.id, unit: unit.clone() });
                    let parameters =
                        self.space.names().map(str::to_string).zip(self.space.to_physical(&unit)).collect();
                    jobs.push(Job { id, stage: r.index, unit, parameters });
                }
                return jobs;
            }
            match r.algorithm.inner().finished() {
                Some(stop) if r.outstanding.is_empty() => self.finish_stage(stop),
                _ => return Vec::new(),
            }
        }
    }

    /// Takes results of handed-out jobs, in any order. Rejects unknown or repeated ids and
    /// invalid costs without changing anything.
    pub fn tell(&mut self, results: &[Evaluation]) -> Result<(), TellError> {
        let mut seen = std::collections::BTreeSet::new();
        for e in results {
            if !self.jobs.contains_key(&e.id) {
                return Err(TellError::Unknown { id: e.id });
            }
            if !seen.insert(e.id) {
                return Err(TellError::Duplicate { id: e.id });
            }
            if let Outcome::Ok { cost } = e.outcome
                && (!cost.is_finite() || cost < 0.0)
            {
                return Err(TellError::BadCost { id: e.id, cost });
            }
        }
        let Some(r) = self.running.as_mut() else {
            return match results.first() {
                Some(e) => Err(TellError::Unknown { id: e.id }),
                None => Ok(()),
            };
        };
        let mut local = Vec::with_capacity(results.len());
        for e in results {
            local.push(Evaluation { id: self.jobs[&e.id].local, outcome: e.outcome.clone() });
        }
        r.algorithm.inner_mut().tell(&local).map_err(|err| match err {
            TellError::Unknown { id } => TellError::Unknown { id: r.outstanding.get(&id).copied().unwrap_or(id) },
            TellError::Duplicate { id } => TellError::Duplicate { id: r.outstanding.get(&id).copied().unwrap_or(id) },
            other => other,
        })?;
        let surface = match &r.algorithm {
            StageAlgorithm::Inference(a) => match a.as_ref() {
                InferenceAlgorithm::Variance(v) => v.surface_estimate(),
                _ => None,
            },
            StageAlgorithm::Global(_) => None,
        };
        for e in results {
            let job = self.jobs.remove(&e.id).expect("checked above");
            r.outstanding.remove(&job.local);
            r.evaluations += 1;
            self.evaluations += 1;
            match e.outcome {
                Outcome::Ok { cost } => {
                    // ties go to the lower id, so the best does not depend on the telling order
                    let better = |c: f64, id: u64, bc: f64, bid: u64| c < bc || (c == bc && id < bid);
                    if r.best.as_ref().is_none_or(|(bc, bid, _)| better(cost, e.id, *bc, *bid)) {
                        r.best = Some((cost, e.id, job.unit.clone()));
                    }
                    if let Some(s) = surface.as_ref().filter(|s| s.id == job.local) {
                        let smoothed = Smoothed { predicted: s.predicted_cost, residual_rms: s.residual_rms };
                        r.estimate = Some((Best { id: e.id, unit: job.unit.clone(), cost }, smoothed));
                    }
                    let beats = |b: &Best| match &self.smoothed {
                        Some(s) => s.beaten_by(cost),
                        None => better(cost, e.id, b.cost, b.id),
                    };
                    if self.best.as_ref().is_none_or(beats) {
                        self.best = Some(Best { id: e.id, unit: job.unit, cost });
                        self.smoothed = None;
                    }
                }
                Outcome::Failed { .. } => {
                    r.failed += 1;
                    self.failed += 1;
                }
            }
        }
        if r.outstanding.is_empty()
            && let Some(stop) = r.algorithm.inner().finished()
        {
            self.finish_stage(stop);
        }
        Ok(())
    }
}
