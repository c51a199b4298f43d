//! The optimiser driver: owns the ask/tell state of every running calibration, fans parameter sets
//! out to jobs, leases jobs to workers, collects results and tells the optimiser.
//!
//! # Consistency
//! Every change of a calibration's optimiser state is written in the same transaction as what
//! caused it: asking stores the new parameter sets and jobs with the new state; a parameter set's
//! last result, its summed cost and the tell are one transaction. A coordinator killed at any
//! instant restarts from a state in which every handed-out parameter set is stored (and is
//! re-queued, never asked again) and every counted result is told exactly once.
//!
//! Writers hold the pipelines lock and then the single writer connection, always in that order.
//! The in-memory pipelines are changed on clones and replaced only after the commit.
//!
//! # Leases
//! A claim leases jobs for [`CoordinatorSettings::lease`]; heartbeats extend it. The reaper puts
//! expired jobs back in the queue, or fails them once they were leased
//! [`CoordinatorSettings::max_attempts`] times. A result quoting anything but the current lease id
//! is recorded as `stale` and not counted. Leases survive a coordinator restart: a worker that
//! keeps running reports with a lease id that is still valid.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use cryofit_api as api;
use cryofit_calib::pipeline::Pipeline;
use cryofit_calib::{Evaluation, Outcome};
use rand::Rng;
use tokio::sync::Mutex;

use crate::clock::now_ms;
use crate::db::{self, Db, DbError, Tx};
use crate::metrics::Metrics;

/// Tunables of the driver and the leases.
#[derive(Debug, Clone)]
pub struct CoordinatorSettings {
    /// Lease length; heartbeats extend a lease by this much.
    pub lease: Duration,
    /// Leases a job may get before an expiry fails it.
    pub max_attempts: i64,
    /// Parameter sets kept queued per running calibration at least.
    pub min_queued: i64,
    /// A worker counts as active this long after its last claim or heartbeat.
    pub active_window: Duration,
}

impl Default for CoordinatorSettings {
    fn default() -> Self {
        Self { lease: Duration::from_secs(30), max_attempts: 3, min_queued: 8, active_window: Duration::from_secs(60) }
    }
}

/// Why a driver operation did not happen.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CoordError {
    /// Storage failed.
    #[error(transparent)]
    Db(#[from] DbError),
    /// The request conflicts with the current state (e.g. a lease that is not current).
    #[error("{0}")]
    Conflict(String),
    /// A field of the request is invalid.
    #[error("{field}: {message}")]
    Invalid {
        /// Field path.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// Internal inconsistency (a bug), with what was seen.
    #[error("internal error: {0}")]
    Internal(String),
}

impl From<sqlx::Error> for CoordError {
    fn from(e: sqlx::Error) -> Self {
        Self::Db(DbError::Sqlx(e))
    }
}

/// A running calibration in memory: its pipeline and what a claim checks and hands out.
#[derive(Debug, Clone)]
struct Running {
    pipeline: Pipeline,
    experiments: Vec<i64>,
    /// Evaluation settings sent with the calibration's jobs.
    context: api::JobContext,
    /// Solver version the calibration runs with.
    solver_version: String,
    /// Fluid-table hash per fluid.
    fluid_hashes: BTreeMap<String, String>,
}

/// The driver (see the module docs).
#[derive(Debug)]
pub struct Coordinator {
    db: Db,
    settings: CoordinatorSettings,
    running: Mutex<BTreeMap<i64, Running>>,
    metrics: Arc<Metrics>,
    /// Claims so far: rotates which calibration a claim serves first.
    turn: std::sync::atomic::AtomicUsize,
}

/// A validated calibration ready to store.
#[derive(Debug, Clone)]
pub struct NewCalibration {
    /// The request.
    pub request: api::CreateCalibration,
    /// A fresh pipeline.
    pub pipeline: Pipeline,
    /// Fluid hashes of the experiments' fluids.
    pub fluid_hashes: BTreeMap<String, String>,
}

/// Outcome of one reaper pass.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Reaped {
    /// Jobs put back in the queue.
    pub requeued: usize,
    /// Jobs failed after too many expired leases.
    pub failed: usize,
}

/// One worker result to record (of `POST /jobs/{id}/result` or an item of `POST /jobs/results`).
#[derive(Debug, Clone, Copy)]
pub struct Report<'a> {
    /// The job.
    pub job: i64,
    /// The lease the worker quotes.
    pub lease_id: &'a str,
    /// The outcome.
    pub outcome: &'a api::JobOutcome,
    /// Evaluation wall time, s.
    pub duration_s: Option<f64>,
    /// Per-series breakdown.
    pub breakdown: Option<&'a [api::SeriesCost]>,
    /// The reporting worker.
    pub worker: Option<&'a str>,
}

impl<'a> Report<'a> {
    /// The report of a single-result request.
    pub fn single(job: i64, r: &'a api::ResultRequest) -> Self {
        Self {
            job,
            lease_id: &r.lease_id,
            outcome: &r.outcome,
            duration_s: r.duration_s,
            breakdown: r.breakdown.as_deref(),
            worker: r.worker.as_deref(),
        }
    }

    /// The report of a batch item.
    pub fn batched(r: &'a api::JobResult) -> Self {
        Self {
            job: r.job_id,
            lease_id: &r.lease_id,
            outcome: &r.outcome,
            duration_s: r.duration_s,
            breakdown: r.breakdown.as_deref(),
            worker: r.worker.as_deref(),
        }
    }
}

fn json<T: serde::Serialize + ?Sized>(v: &T) -> Result<String, CoordError> {
    serde_json::to_string(v).map_err(|e| CoordError::Internal(format!("serialising: {e}")))
}

fn progress(p: &Pipeline, status: &'static str, error: Option<String>) -> Result<db::Progress, CoordError> {
    let (evaluations, failed) = p.evaluations();
    Ok(db::Progress {
        status,
        evaluations: evaluations as i64,
        failed_evaluations: failed as i64,
        stage: p.stage() as i64,
        best_cost: p.best().map(|b| b.cost),
        best_parameters_json: p.best().map(|b| json(&p.parameters(&b.unit))).transpose()?,
        reports_json: json(p.reports())?,
        state_json: json(p)?,
        error,
    })
}

/// The evaluation settings of a calibration's jobs.
fn context(id: i64, spec: &api::CreateCalibration) -> api::JobContext {
    api::JobContext {
        calibration_id: id,
        fixed: spec.fixed.clone(),
        weights: spec.weights.clone(),
        max_evaluation_s: spec.max_evaluation_s.unwrap_or(cryofit_calib::config::DEFAULT_MAX_EVALUATION_S),
    }
}

/// Rebuilds a running calibration from its stored row and optimiser state.
fn resume(row: &db::CalibrationRow, state: &str) -> Result<Running, String> {
    let pipeline = serde_json::from_str::<Pipeline>(state)
        .map_err(|e| format!("the stored optimiser state cannot be read ({e}); resubmit the calibration"))?;
    let experiments: Vec<i64> =
        serde_json::from_str(&row.experiment_ids_json).map_err(|e| format!("stored experiment ids: {e}"))?;
    let spec: api::CreateCalibration =
        serde_json::from_str(&row.spec_json).map_err(|e| format!("stored calibration spec: {e}"))?;
    let fluid_hashes: BTreeMap<String, String> =
        serde_json::from_str(&row.fluid_hashes).map_err(|e| format!("stored fluid hashes: {e}"))?;
    Ok(Running {
        pipeline,
        experiments,
        context: context(row.id, &spec),
        solver_version: row.solver_version.clone(),
        fluid_hashes,
    })
}

/// Results of one transaction, per calibration: the evaluations to tell, in arrival order.
type Told = BTreeMap<i64, Vec<Evaluation>>;

impl Coordinator {
    /// Loads every running calibration's state. A state that cannot be read fails its calibration
    /// (with the reason) instead of stopping the coordinator.
    pub async fn load(db: Db, settings: CoordinatorSettings, metrics: Arc<Metrics>) -> Result<Self, DbError> {
        let mut running = BTreeMap::new();
        for db::RunningState { id, pipeline_state_json } in db::running_states(db.reader()).await? {
            let row = db::calibration(db.reader(), id).await?;
            match resume(&row, &pipeline_state_json) {
                Ok(r) => {
                    tracing::info!(calibration = id, evaluations = r.pipeline.evaluations().0, "resuming calibration");
                    running.insert(id, r);
                }
                Err(e) => {
                    tracing::error!(calibration = id, error = %e, "cannot resume calibration");
                    let mut tx = db.begin().await?;
                    db::fail_calibration(&mut tx, id, &e).await?;
                    db.commit(tx).await?;
                }
            }
        }
        Ok(Self { db, settings, running: Mutex::new(running), metrics, turn: Default::default() })
    }

    /// The database.
    pub fn db(&self) -> &Db {
        &self.db
    }

    /// The settings.
    pub fn settings(&self) -> &CoordinatorSettings {
        &self.settings
    }

    /// Parameter sets to keep queued per calibration: twice the active workers' slots, at least
    /// [`CoordinatorSettings::min_queued`].
    async fn target(&self, tx: &mut Tx) -> Result<i64, CoordError> {
        let since = now_ms() - self.settings.active_window.as_millis() as i64;
        let slots = db::active_slots(tx, since).await?;
        Ok((2 * slots).max(self.settings.min_queued))
    }

    /// When fewer than `low` parameter sets are queued, asks the pipeline for enough to have
    /// `target` queued and stores them. Returns true when the pipeline changed (its state must
    /// then be persisted in the same transaction).
    async fn top_up(tx: &mut Tx, id: i64, r: &mut Running, low: i64, target: i64) -> Result<bool, CoordError> {
        if r.pipeline.is_finished() {
            return Ok(false);
        }
        let per_set = r.experiments.len().max(1) as i64;
        let queued = db::queued_jobs(tx, id).await? / per_set;
        if queued >= low.min(target) {
            return Ok(false);
        }
        let jobs = r.pipeline.ask((target - queued) as usize);
        let sets = jobs
            .iter()
            .map(|j| {
                Ok(db::NewParameterSet {
                    job: j.id as i64,
                    stage: j.stage as i64,
                    parameters_json: json(&j.parameters)?,
                })
            })
            .collect::<Result<Vec<_>, CoordError>>()?;
        db::insert_parameter_sets(tx, id, &sets, &r.experiments).await?;
        Ok(!jobs.is_empty())
    }

    /// The status a pipeline's calibration should have, with its error.
    fn status_of(p: &Pipeline) -> (&'static str, Option<String>) {
        if let Some(e) = p.error() {
            return ("failed", Some(e.to_string()));
        }
        if p.is_finished() {
            if p.best().is_none() {
                let (n, _) = p.evaluations();
                return ("failed", Some(format!("every one of the {n} evaluations failed")));
            }
            return ("completed", None);
        }
        if p.outstanding() == 0 {
            return ("failed", Some(format!("the optimiser stalled at stage {} with nothing to evaluate", p.stage())));
        }
        ("running", None)
    }

    /// Stores a validated calibration, asks its first parameter sets and starts handing them out.
    pub async fn create(&self, c: NewCalibration) -> Result<i64, CoordError> {
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        let spec_json = json(&c.request)?;
        let ids_json = json(&c.request.experiments)?;
        let hashes_json = json(&c.fluid_hashes)?;
        let state_json = json(&c.pipeline)?;
        let id = db::insert_calibration(
            &mut tx,
            &db::NewCalibration {
                name: &c.request.name,
                spec_json: &spec_json,
                experiment_ids_json: &ids_json,
                budget: i64::try_from(c.pipeline.budget()).unwrap_or(i64::MAX),
                state_json: &state_json,
                solver_version: api::SOLVER_VERSION,
                fluid_hashes_json: &hashes_json,
            },
        )
        .await?;
        let mut r = Running {
            pipeline: c.pipeline,
            experiments: c.request.experiments.clone(),
            context: context(id, &c.request),
            solver_version: api::SOLVER_VERSION.to_string(),
            fluid_hashes: c.fluid_hashes,
        };
        let target = self.target(&mut tx).await?;
        Self::top_up(&mut tx, id, &mut r, target, target).await?;
        let (status, error) = Self::status_of(&r.pipeline);
        db::update_progress(&mut tx, id, &progress(&r.pipeline, status, error)?).await?;
        self.db.commit(tx).await?;
        if status == "running" {
            running.insert(id, r);
        }
        tracing::info!(calibration = id, status, "calibration created");
        Ok(id)
    }

    /// Leases up to `req.max_jobs` jobs to a worker, topping up the queues of the calibrations it
    /// may run first. Calibrations built with another solver version or other fluid tables are
    /// listed as refused, with the reason.
    pub async fn claim(&self, req: &api::ClaimRequest) -> Result<api::ClaimResponse, CoordError> {
        let started = std::time::Instant::now();
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        db::touch_worker(&mut tx, &req.worker, i64::from(req.slots.max(1))).await?;
        let mut eligible = Vec::new();
        let mut refused = Vec::new();
        for (&id, r) in running.iter() {
            match refusal(&r.solver_version, &r.fluid_hashes, req) {
                Some(reason) => refused.push(api::Refusal { calibration_id: id, reason }),
                None => eligible.push(id),
            }
        }
        // Results keep the queues topped up (their transaction persists the optimiser state
        // anyway); a claim asks the optimiser only when a queue cannot serve it.
        let mut changed = Vec::new();
        if !eligible.is_empty() && req.max_jobs > 0 {
            let target = self.target(&mut tx).await?;
            for &id in &eligible {
                let Some(r) = running.get(&id) else { continue };
                let low = i64::from(req.max_jobs).div_euclid(r.experiments.len().max(1) as i64).max(1);
                let mut r = r.clone();
                if Self::top_up(&mut tx, id, &mut r, low, target).await? {
                    db::update_progress(&mut tx, id, &progress(&r.pipeline, "running", None)?).await?;
                    changed.push((id, r));
                }
            }
        }
        let prefix = format!("{:016x}", rand::thread_rng().r#gen::<u64>());
        let lease_ms = self.settings.lease.as_millis() as i64;
        if !eligible.is_empty() {
            let turn = self.turn.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let n = eligible.len();
            eligible.rotate_left(turn % n);
        }
        let claimed = if eligible.is_empty() || req.max_jobs == 0 {
            Vec::new()
        } else {
            db::claim(&mut tx, &eligible, i64::from(req.max_jobs.min(1000)), &prefix, &req.worker, now_ms() + lease_ms)
                .await?
        };
        self.db.commit(tx).await?;
        for (id, r) in changed {
            running.insert(id, r);
        }
        let mut jobs = Vec::with_capacity(claimed.len());
        let mut used = std::collections::BTreeSet::new();
        for c in claimed {
            let parameters: BTreeMap<String, f64> = serde_json::from_str(&c.parameters_json)
                .map_err(|e| DbError::Corrupt(format!("parameter set {}: {e}", c.parameter_set_id)))?;
            used.insert(c.calibration_id);
            jobs.push(api::LeasedJob {
                id: c.id,
                lease_id: c.lease_id,
                lease_s: self.settings.lease.as_secs_f64(),
                calibration_id: c.calibration_id,
                parameter_set_id: c.parameter_set_id,
                experiment_id: c.experiment_id,
                parameters,
            });
        }
        let calibrations = used.into_iter().filter_map(|id| running.get(&id).map(|r| r.context.clone())).collect();
        drop(running);
        self.metrics.claimed(jobs.len(), started.elapsed());
        Ok(api::ClaimResponse { jobs, calibrations, refused })
    }

    /// Extends a job's lease.
    pub async fn heartbeat(&self, job: i64, lease_id: &str) -> Result<api::HeartbeatResponse, CoordError> {
        let mut tx = self.db.begin().await?;
        let expires = now_ms() + self.settings.lease.as_millis() as i64;
        let ok = db::heartbeat(&mut tx, job, lease_id, expires).await?;
        let out = match ok {
            Some(_) => Ok(api::HeartbeatResponse { lease_s: self.settings.lease.as_secs_f64(), cancelled: false }),
            None => {
                let j = db::job(&mut tx, job).await?;
                let status = db::calibration_status(&mut tx, j.calibration_id).await?;
                if status == "cancelled" {
                    Ok(api::HeartbeatResponse { lease_s: 0.0, cancelled: true })
                } else {
                    Err(CoordError::Conflict(format!(
                        "lease `{lease_id}` of job {job} is not current (job is {}): it expired or the job was \
                         leased again; drop the job",
                        j.status
                    )))
                }
            }
        };
        self.db.commit(tx).await?;
        out
    }

    /// Records a worker's result. A result quoting a lease that is not current is stored as
    /// `stale` and not counted.
    pub async fn result(&self, job_id: i64, req: &api::ResultRequest) -> Result<api::ResultResponse, CoordError> {
        let mut out = self.record(&[Report::single(job_id, req)], false).await?;
        out.pop().ok_or_else(|| CoordError::Internal("a result without an answer".into()))
    }

    /// Records several results in one transaction, in order, and tells each calibration's
    /// optimiser the parameter sets they complete at once (its state is persisted once). Either
    /// every result is recorded or none is. Errors name the field as `results[k].…`.
    pub async fn results(&self, reports: &[Report<'_>]) -> Result<Vec<api::ResultResponse>, CoordError> {
        self.record(reports, true).await
    }

    /// Checks what can be checked without the database: costs, durations, repeated jobs.
    fn check_reports(reports: &[Report<'_>], batch: bool) -> Result<(), CoordError> {
        let field = |k: usize, f: &str| if batch { format!("results[{k}].{f}") } else { f.to_string() };
        if batch && reports.is_empty() {
            return Err(CoordError::Invalid { field: "results".into(), message: "give at least one result".into() });
        }
        if reports.len() > api::MAX_RESULT_BATCH {
            return Err(CoordError::Invalid {
                field: "results".into(),
                message: format!("{} results: at most {} per request", reports.len(), api::MAX_RESULT_BATCH),
            });
        }
        let mut seen = std::collections::HashSet::with_capacity(reports.len());
        for (k, r) in reports.iter().enumerate() {
            if let api::JobOutcome::Ok { cost } = r.outcome
                && !(cost.is_finite() && *cost >= 0.0)
            {
                return Err(CoordError::Invalid {
                    field: field(k, "outcome.cost"),
                    message: format!("{cost} is not a finite number ≥ 0; report the evaluation as failed instead"),
                });
            }
            if let Some(d) = r.duration_s
                && !(d.is_finite() && d >= 0.0)
            {
                return Err(CoordError::Invalid {
                    field: field(k, "duration_s"),
                    message: format!("{d}: must be ≥ 0"),
                });
            }
            if !seen.insert(r.job) {
                return Err(CoordError::Invalid {
                    field: field(k, "job_id"),
                    message: format!("job {} is listed twice; report each job once", r.job),
                });
            }
        }
        Ok(())
    }

    async fn record(&self, reports: &[Report<'_>], batch: bool) -> Result<Vec<api::ResultResponse>, CoordError> {
        Self::check_reports(reports, batch)?;
        let breakdowns = reports.iter().map(|r| r.breakdown.map(json).transpose()).collect::<Result<Vec<_>, _>>()?;
        let ids: Vec<i64> = reports.iter().map(|r| r.job).collect();
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        let rows: std::collections::HashMap<i64, db::JobRow> =
            db::jobs(&mut tx, &ids).await?.into_iter().map(|j| (j.id, j)).collect();
        let mut out = Vec::with_capacity(reports.len());
        let mut results = Vec::with_capacity(reports.len());
        let mut sets = Vec::new();
        let mut per_worker: BTreeMap<&str, i64> = BTreeMap::new();
        for (k, (r, breakdown)) in reports.iter().zip(breakdowns).enumerate() {
            let Some(job) = rows.get(&r.job) else {
                return Err(if batch {
                    CoordError::Invalid {
                        field: format!("results[{k}].job_id"),
                        message: format!("job {} does not exist", r.job),
                    }
                } else {
                    DbError::NotFound { what: "job", id: r.job }.into()
                });
            };
            let current = job.status == "leased" && job.lease_id.as_deref() == Some(r.lease_id);
            let (status, cost, reason) = match r.outcome {
                api::JobOutcome::Ok { cost } => (if current { "ok" } else { "stale" }, Some(*cost), None),
                api::JobOutcome::Failed { reason } => {
                    (if current { "failed" } else { "stale" }, None, Some(reason.as_str()))
                }
            };
            results.push(db::NewResult {
                job,
                status,
                cost,
                reason,
                worker: r.worker,
                duration: r.duration_s,
                breakdown_json: breakdown,
            });
            if current {
                if let Some(w) = r.worker {
                    *per_worker.entry(w).or_default() += 1;
                }
                if !sets.contains(&job.parameter_set_id) {
                    sets.push(job.parameter_set_id);
                }
            }
            out.push(api::ResultResponse { status: status.to_string(), counted: current });
        }
        db::record_results(&mut tx, &results).await?;
        for (worker, n) in per_worker {
            db::count_evaluations(&mut tx, worker, n).await?;
        }
        let told = Self::finish_sets(&mut tx, &sets).await?;
        let changed = self.tell(&mut tx, &running, told).await?;
        self.db.commit(tx).await?;
        Self::apply(&mut running, changed);
        drop(running);
        for (r, o) in reports.iter().zip(&out) {
            if o.counted {
                if let Some(d) = r.duration_s {
                    self.metrics.evaluated(d);
                }
            } else {
                self.metrics.stale();
                tracing::info!(job = r.job, lease = %r.lease_id, "stale result recorded, not counted");
            }
        }
        Ok(out)
    }

    /// Replaces in-memory pipelines after a commit (dropping finished ones).
    fn apply(running: &mut BTreeMap<i64, Running>, changed: BTreeMap<i64, Running>) {
        for (id, r) in changed {
            if Self::status_of(&r.pipeline).0 == "running" {
                running.insert(id, r);
            } else {
                running.remove(&id);
            }
        }
    }

    /// Finishes the parameter sets (of `sets`, in that order) whose jobs are all in: sums their
    /// costs in experiment order (any failure fails the set) and returns, per calibration, the
    /// evaluations to tell.
    async fn finish_sets(tx: &mut Tx, sets: &[i64]) -> Result<Told, CoordError> {
        let mut told = Told::new();
        if sets.is_empty() {
            return Ok(told);
        }
        let parts = db::pending_set_parts(tx, sets).await?;
        let mut by_set: std::collections::HashMap<i64, Vec<&db::SetPart>> = std::collections::HashMap::new();
        for p in &parts {
            by_set.entry(p.parameter_set_id).or_default().push(p);
        }
        let mut finished = Vec::new();
        for id in sets {
            let Some(parts) = by_set.get(id) else { continue };
            if parts.iter().any(|p| p.status == "queued" || p.status == "leased") {
                continue;
            }
            let mut outcome = Outcome::Ok { cost: 0.0 };
            for p in parts {
                match (p.status.as_str(), &mut outcome) {
                    ("done", Outcome::Ok { cost: total }) => *total += p.cost.unwrap_or(f64::NAN),
                    ("failed", Outcome::Ok { .. }) => {
                        outcome = Outcome::Failed { reason: p.reason.clone().unwrap_or_else(|| "failed".into()) };
                    }
                    _ => {}
                }
            }
            // two finite costs can still sum to infinity: that set fails, it is not told as a cost
            if let Outcome::Ok { cost } = outcome
                && !cost.is_finite()
            {
                outcome = Outcome::Failed {
                    reason: format!(
                        "the experiments' costs sum to {cost} (not a finite number); check the weights and sigmas"
                    ),
                };
            }
            let first = parts[0];
            told.entry(first.calibration_id)
                .or_default()
                .push(Evaluation { id: first.pipeline_job as u64, outcome: outcome.clone() });
            finished.push((*id, outcome));
        }
        let rows: Vec<db::FinishedSet<'_>> = finished
            .iter()
            .map(|(id, o)| match o {
                Outcome::Ok { cost } => (*id, "ok", Some(*cost), None),
                Outcome::Failed { reason } => (*id, "failed", None, Some(reason.as_str())),
            })
            .collect();
        db::finish_parameter_sets(tx, &rows).await?;
        Ok(told)
    }

    /// Tells each running calibration its completed parameter sets, asks for more and persists
    /// its state, all in `tx`. Returns the changed pipelines, to apply after the commit.
    async fn tell(
        &self,
        tx: &mut Tx,
        running: &BTreeMap<i64, Running>,
        told: Told,
    ) -> Result<BTreeMap<i64, Running>, CoordError> {
        let mut changed = BTreeMap::new();
        if told.is_empty() {
            return Ok(changed);
        }
        let target = self.target(tx).await?;
        for (id, evaluations) in told {
            let Some(r) = running.get(&id) else { continue };
            if db::calibration_status(tx, id).await? != "running" {
                continue;
            }
            let mut r = r.clone();
            r.pipeline
                .tell(&evaluations)
                .map_err(|e| CoordError::Internal(format!("calibration {id}: the optimiser rejected a result: {e}")))?;
            Self::top_up(tx, id, &mut r, target, target).await?;
            let (status, error) = Self::status_of(&r.pipeline);
            db::update_progress(tx, id, &progress(&r.pipeline, status, error)?).await?;
            if status != "running" {
                tracing::info!(calibration = id, status, "calibration finished");
            }
            changed.insert(id, r);
        }
        Ok(changed)
    }

    /// Re-queues jobs whose lease expired, or fails them after too many attempts.
    pub async fn reap(&self) -> Result<Reaped, CoordError> {
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        let expired = db::expired_jobs(&mut tx, now_ms()).await?;
        let mut out = Reaped::default();
        let reasons: Vec<String> = expired
            .iter()
            .map(|j| {
                format!("the lease expired {} times without a result (worker lost or evaluation stuck)", j.attempts)
            })
            .collect();
        let mut failed = Vec::new();
        let mut sets = Vec::new();
        for (j, reason) in expired.iter().zip(&reasons) {
            if j.attempts >= self.settings.max_attempts {
                failed.push(db::NewResult {
                    job: j,
                    status: "failed",
                    cost: None,
                    reason: Some(reason),
                    worker: None,
                    duration: None,
                    breakdown_json: None,
                });
                if !sets.contains(&j.parameter_set_id) {
                    sets.push(j.parameter_set_id);
                }
                out.failed += 1;
            } else {
                db::requeue(&mut tx, j.id).await?;
                out.requeued += 1;
            }
        }
        db::record_results(&mut tx, &failed).await?;
        let told = Self::finish_sets(&mut tx, &sets).await?;
        let changed = self.tell(&mut tx, &running, told).await?;
        self.db.commit(tx).await?;
        Self::apply(&mut running, changed);
        if !expired.is_empty() {
            self.metrics.expired(expired.len());
            tracing::warn!(requeued = out.requeued, failed = out.failed, "expired leases");
        }
        Ok(out)
    }

    /// Cancels a calibration; returns its status before.
    pub async fn cancel(&self, id: i64) -> Result<String, CoordError> {
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        let before = db::cancel_calibration(&mut tx, id).await?;
        self.db.commit(tx).await?;
        running.remove(&id);
        Ok(before)
    }
}

/// Why a worker may not run a calibration's jobs, if it may not.
fn refusal(version: &str, hashes: &BTreeMap<String, String>, req: &api::ClaimRequest) -> Option<String> {
    if version != req.solver_version {
        return Some(format!(
            "the calibration runs solver version {version}, this worker has {}: results must not mix model \
             versions; run a worker built from version {version}",
            req.solver_version
        ));
    }
    for (fluid, hash) in hashes {
        match req.fluid_hashes.get(fluid) {
            None => return Some(format!("this worker has no `{fluid}` fluid table, which the calibration uses")),
            Some(h) if h != hash => {
                return Some(format!(
                    "fluid table `{fluid}` differs (calibration: {hash}, worker: {h}); give coordinator and \
                     workers the same tables (CRYOFIT_DATA_DIR)"
                ));
            }
            Some(_) => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    const CASE: &str = include_str!("../../tests/fixtures/tiny.toml");
    const DATA: &str = include_str!("../../tests/fixtures/tiny-data.csv");

    async fn coordinator(tag: &str) -> (Coordinator, std::path::PathBuf) {
        let dir = std::env::temp_dir().join(format!("cryofit-coord-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        let db = Db::open(&dir.join("c.db").display().to_string()).await.expect("open");
        let c = Coordinator::load(db, CoordinatorSettings::default(), Arc::default()).await.expect("load");
        (c, dir)
    }

    async fn experiment(c: &Coordinator) -> i64 {
        let mut tx = c.db.begin().await.expect("begin");
        let id = db::insert_experiment(&mut tx, "tiny", "nitrogen", CASE, DATA).await.expect("insert");
        c.db.commit(tx).await.expect("commit");
        id
    }

    async fn calibration(c: &Coordinator, experiments: &[i64]) -> i64 {
        let req: api::CreateCalibration = serde_json::from_value(json!({
            "name": "t",
            "seed": 3,
            "experiments": experiments,
            "parameters": [{"name": "Gwsc", "lower": 0.5, "upper": 2.0}],
            "weights": {"wall_temperature_k": {"weight": 1.0, "sigma": 1.0}},
            "stages": [{"algorithm": "cmaes", "budget": 60, "population": 6}]
        }))
        .expect("request");
        let mut rows = Vec::new();
        for &e in experiments {
            rows.push(db::experiment(c.db.reader(), e).await.expect("experiment"));
        }
        let p = crate::validate::calibration(&req, &rows, &crate::fluids::embedded_fluids(), &api::Limits::default())
            .expect("valid");
        c.create(NewCalibration { request: req, pipeline: p.pipeline, fluid_hashes: p.fluid_hashes })
            .await
            .expect("created")
    }

    fn claim(max_jobs: u32) -> api::ClaimRequest {
        let (_, hash) = crate::fluids::embedded_fluids()("nitrogen").expect("nitrogen");
        api::ClaimRequest {
            worker: "w".into(),
            slots: 1,
            max_jobs,
            solver_version: api::SOLVER_VERSION.into(),
            fluid_hashes: [("nitrogen".to_string(), hash)].into(),
        }
    }

    #[tokio::test]
    async fn claims_take_turns_across_running_calibrations() {
        let (c, dir) = coordinator("fair").await;
        let e = experiment(&c).await;
        let first = calibration(&c, &[e]).await;
        let second = calibration(&c, &[e]).await;
        let mut got: BTreeMap<i64, usize> = BTreeMap::new();
        // a one-slot worker claiming one job at a time, holding them all: before, the oldest
        // calibration's six queued jobs all went first
        for _ in 0..6 {
            for j in c.claim(&claim(1)).await.expect("claim").jobs {
                *got.entry(j.calibration_id).or_default() += 1;
            }
        }
        assert_eq!((got.get(&first), got.get(&second)), (Some(&3), Some(&3)), "{got:?}");
        // a larger claim interleaves: the second job of each comes after the first of each
        let jobs = c.claim(&claim(2)).await.expect("claim").jobs;
        let ids: Vec<i64> = jobs.iter().map(|j| j.calibration_id).collect();
        assert!(ids.contains(&first) && ids.contains(&second), "{ids:?}");
        c.db.close().await;
        let _ = std::fs::remove_dir_all(dir);
    }

    #[tokio::test]
    async fn costs_that_sum_to_infinity_fail_their_parameter_set() {
        let (c, dir) = coordinator("infinite").await;
        let (e1, e2) = (experiment(&c).await, experiment(&c).await);
        let id = calibration(&c, &[e1, e2]).await;
        let jobs = c.claim(&claim(2)).await.expect("claim").jobs;
        assert_eq!(jobs.len(), 2);
        assert_eq!(jobs[0].parameter_set_id, jobs[1].parameter_set_id, "both experiments of one set");
        let outcome = api::JobOutcome::Ok { cost: 1e308 };
        let items: Vec<api::JobResult> = jobs
            .iter()
            .map(|j| api::JobResult {
                job_id: j.id,
                lease_id: j.lease_id.clone(),
                outcome: outcome.clone(),
                duration_s: Some(0.1),
                breakdown: None,
                worker: Some("w".into()),
            })
            .collect();
        let reports: Vec<Report<'_>> = items.iter().map(Report::batched).collect();
        let out = c.results(&reports).await.expect("recorded, not an internal error");
        assert!(out.iter().all(|r| r.counted), "{out:?}");
        let sets = db::parameter_sets_page(c.db.reader(), id, None, None, 100, 0).await.expect("sets");
        let set = sets.iter().find(|s| s.id == jobs[0].parameter_set_id).expect("the set");
        assert_eq!(set.status, "failed", "{set:?}");
        assert!(set.reason.as_deref().is_some_and(|r| r.contains("sum to inf")), "{set:?}");
        let row = db::calibration(c.db.reader(), id).await.expect("calibration");
        assert_eq!((row.status.as_str(), row.evaluations, row.failed_evaluations), ("running", 1, 1));
        c.db.close().await;
        let _ = std::fs::remove_dir_all(dir);
    }
}
