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

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Duration;

use cryofit_api as api;
use cryofit_calib::pipeline::Pipeline;
use cryofit_calib::{Evaluation, Outcome};
use rand::Rng;
use tokio::sync::Mutex;

use crate::db::{self, Db, DbError, Tx, now_ms};
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

/// A running calibration in memory.
#[derive(Debug, Clone)]
struct Running {
    pipeline: Pipeline,
    experiments: Vec<i64>,
}

/// The driver (see the module docs).
#[derive(Debug)]
pub struct Coordinator {
    db: Db,
    settings: CoordinatorSettings,
    running: Mutex<HashMap<i64, Running>>,
    metrics: Arc<Metrics>,
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

impl Coordinator {
    /// Loads every running calibration's state. A state that cannot be read fails its calibration
    /// (with the reason) instead of stopping the coordinator.
    pub async fn load(db: Db, settings: CoordinatorSettings, metrics: Arc<Metrics>) -> Result<Self, DbError> {
        let mut running = HashMap::new();
        for (id, state) in db::running_states(db.reader()).await? {
            let row = db::calibration(db.reader(), id).await?;
            let parsed = serde_json::from_str::<Pipeline>(&state)
                .map_err(|e| format!("the stored optimiser state cannot be read ({e}); resubmit the calibration"))
                .and_then(|p| {
                    serde_json::from_str::<Vec<i64>>(&row.experiment_ids_json)
                        .map(|experiments| Running { pipeline: p, experiments })
                        .map_err(|e| format!("stored experiment ids: {e}"))
                });
            match parsed {
                Ok(r) => {
                    tracing::info!(calibration = id, evaluations = r.pipeline.evaluations().0, "resuming calibration");
                    running.insert(id, r);
                }
                Err(e) => {
                    tracing::error!(calibration = id, error = %e, "cannot resume calibration");
                    let mut tx = db.begin().await?;
                    db::fail_calibration(&mut tx, id, &e).await?;
                    tx.commit().await?;
                }
            }
        }
        Ok(Self { db, settings, running: Mutex::new(running), metrics })
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

    /// Asks the pipeline for parameter sets until `target` are queued; stores them.
    /// Returns true when the pipeline changed.
    async fn top_up(tx: &mut Tx, id: i64, r: &mut Running, target: i64) -> Result<bool, CoordError> {
        if r.pipeline.is_finished() {
            return Ok(false);
        }
        let per_set = r.experiments.len().max(1) as i64;
        let queued = db::queued_jobs(tx, id).await? / per_set;
        if queued >= target {
            return Ok(false);
        }
        let jobs = r.pipeline.ask((target - queued) as usize);
        for j in &jobs {
            db::insert_parameter_set(tx, id, j.id as i64, j.stage as i64, &json(&j.parameters)?, &r.experiments)
                .await?;
        }
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
                budget: c.pipeline.budget() as i64,
                state_json: &state_json,
                solver_version: api::SOLVER_VERSION,
                fluid_hashes_json: &hashes_json,
            },
        )
        .await?;
        let mut r = Running { pipeline: c.pipeline, experiments: c.request.experiments.clone() };
        let target = self.target(&mut tx).await?;
        Self::top_up(&mut tx, id, &mut r, target).await?;
        let (status, error) = Self::status_of(&r.pipeline);
        db::update_progress(&mut tx, id, &progress(&r.pipeline, status, error)?).await?;
        tx.commit().await?;
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
        let mut contexts = HashMap::new();
        for (id, spec_json, version, hashes_json) in db::running_builds(&mut tx).await? {
            let hashes: BTreeMap<String, String> = serde_json::from_str(&hashes_json)
                .map_err(|e| DbError::Corrupt(format!("calibration {id} fluid hashes: {e}")))?;
            match refusal(&version, &hashes, req) {
                Some(reason) => refused.push(api::Refusal { calibration_id: id, reason }),
                None => {
                    let spec: api::CreateCalibration = serde_json::from_str(&spec_json)
                        .map_err(|e| DbError::Corrupt(format!("calibration {id} spec: {e}")))?;
                    contexts.insert(
                        id,
                        api::JobContext {
                            calibration_id: id,
                            fixed: spec.fixed,
                            weights: spec.weights,
                            max_evaluation_s: spec
                                .max_evaluation_s
                                .unwrap_or(cryofit_calib::config::DEFAULT_MAX_EVALUATION_S),
                        },
                    );
                    eligible.push(id);
                }
            }
        }
        let mut changed = Vec::new();
        if !eligible.is_empty() && req.max_jobs > 0 {
            let target = self.target(&mut tx).await?;
            for &id in &eligible {
                let Some(r) = running.get(&id) else { continue };
                let mut r = r.clone();
                if Self::top_up(&mut tx, id, &mut r, target).await? {
                    db::update_progress(&mut tx, id, &progress(&r.pipeline, "running", None)?).await?;
                    changed.push((id, r));
                }
            }
        }
        let prefix = format!("{:016x}", rand::thread_rng().r#gen::<u64>());
        let lease_ms = self.settings.lease.as_millis() as i64;
        let claimed = if eligible.is_empty() || req.max_jobs == 0 {
            Vec::new()
        } else {
            db::claim(&mut tx, &eligible, i64::from(req.max_jobs.min(1000)), &prefix, &req.worker, now_ms() + lease_ms)
                .await?
        };
        tx.commit().await?;
        for (id, r) in changed {
            running.insert(id, r);
        }
        drop(running);
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
        let calibrations = used.into_iter().filter_map(|id| contexts.remove(&id)).collect();
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
        tx.commit().await?;
        out
    }

    /// Records a worker's result. A result quoting a lease that is not current is stored as
    /// `stale` and not counted.
    pub async fn result(&self, job_id: i64, req: &api::ResultRequest) -> Result<api::ResultResponse, CoordError> {
        if let api::JobOutcome::Ok { cost } = req.outcome
            && !(cost.is_finite() && cost >= 0.0)
        {
            return Err(CoordError::Invalid {
                field: "outcome.cost".into(),
                message: format!("{cost} is not a finite number ≥ 0; report the evaluation as failed instead"),
            });
        }
        if let Some(d) = req.duration_s
            && !(d.is_finite() && d >= 0.0)
        {
            return Err(CoordError::Invalid { field: "duration_s".into(), message: format!("{d}: must be ≥ 0") });
        }
        let breakdown = req.breakdown.as_ref().map(json).transpose()?;
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        let job = db::job(&mut tx, job_id).await?;
        let current = job.status == "leased" && job.lease_id.as_deref() == Some(req.lease_id.as_str());
        let (status, cost, reason) = match (&req.outcome, current) {
            (_, false) => ("stale", None, None),
            (api::JobOutcome::Ok { cost }, true) => ("ok", Some(*cost), None),
            (api::JobOutcome::Failed { reason }, true) => ("failed", None, Some(reason.as_str())),
        };
        let stale_cost = match (&req.outcome, current) {
            (api::JobOutcome::Ok { cost }, false) => Some(*cost),
            _ => cost,
        };
        let stale_reason = match (&req.outcome, current) {
            (api::JobOutcome::Failed { reason }, false) => Some(reason.as_str()),
            _ => reason,
        };
        db::record_result(
            &mut tx,
            &db::NewResult {
                job: &job,
                status,
                cost: stale_cost,
                reason: stale_reason,
                worker: req.worker.as_deref(),
                duration: req.duration_s,
                breakdown_json: breakdown,
            },
        )
        .await?;
        let mut changed = HashMap::new();
        if current {
            self.complete_if_done(&mut tx, &running, &mut changed, &job).await?;
        }
        tx.commit().await?;
        Self::apply(&mut running, changed);
        drop(running);
        if let Some(d) = req.duration_s
            && current
        {
            self.metrics.evaluated(d);
        }
        if !current {
            self.metrics.stale();
            tracing::info!(job = job_id, lease = %req.lease_id, "stale result recorded, not counted");
        }
        Ok(api::ResultResponse { status: status.to_string(), counted: current })
    }

    /// Replaces in-memory pipelines after a commit (dropping finished ones).
    fn apply(running: &mut HashMap<i64, Running>, changed: HashMap<i64, Running>) {
        for (id, r) in changed {
            if Self::status_of(&r.pipeline).0 == "running" {
                running.insert(id, r);
            } else {
                running.remove(&id);
            }
        }
    }

    /// When every job of `job`'s parameter set is in: sums the costs (any failure fails the set),
    /// tells the optimiser, asks for more and persists the state, all in `tx`.
    async fn complete_if_done(
        &self,
        tx: &mut Tx,
        running: &HashMap<i64, Running>,
        changed: &mut HashMap<i64, Running>,
        job: &db::JobRow,
    ) -> Result<(), CoordError> {
        let parts = db::parameter_set_jobs(tx, job.parameter_set_id).await?;
        if parts.iter().any(|(s, _, _)| s == "queued" || s == "leased") {
            return Ok(());
        }
        let mut outcome = Outcome::Ok { cost: 0.0 };
        for (status, cost, reason) in &parts {
            match (status.as_str(), &mut outcome) {
                ("done", Outcome::Ok { cost: total }) => *total += cost.unwrap_or(f64::NAN),
                ("failed", Outcome::Ok { .. }) => {
                    outcome = Outcome::Failed { reason: reason.clone().unwrap_or_else(|| "failed".into()) };
                }
                _ => {}
            }
        }
        let (status, cost, reason) = match &outcome {
            Outcome::Ok { cost } => ("ok", Some(*cost), None),
            Outcome::Failed { reason } => ("failed", None, Some(reason.as_str())),
        };
        let pipeline_job = db::finish_parameter_set(tx, job.parameter_set_id, status, cost, reason).await?;
        let id = job.calibration_id;
        if db::calibration_status(tx, id).await? != "running" {
            return Ok(());
        }
        let mut r = match changed.remove(&id) {
            Some(r) => r,
            None => match running.get(&id) {
                Some(r) => r.clone(),
                None => return Ok(()),
            },
        };
        r.pipeline
            .tell(&[Evaluation { id: pipeline_job as u64, outcome }])
            .map_err(|e| CoordError::Internal(format!("calibration {id}: the optimiser rejected a result: {e}")))?;
        let target = self.target(tx).await?;
        Self::top_up(tx, id, &mut r, target).await?;
        let (status, error) = Self::status_of(&r.pipeline);
        db::update_progress(tx, id, &progress(&r.pipeline, status, error)?).await?;
        if status != "running" {
            tracing::info!(calibration = id, status, "calibration finished");
        }
        changed.insert(id, r);
        Ok(())
    }

    /// Re-queues jobs whose lease expired, or fails them after too many attempts.
    pub async fn reap(&self) -> Result<Reaped, CoordError> {
        let mut running = self.running.lock().await;
        let mut tx = self.db.begin().await?;
        let expired = db::expired_jobs(&mut tx, now_ms()).await?;
        let mut out = Reaped::default();
        let mut changed = HashMap::new();
        for j in &expired {
            if j.attempts >= self.settings.max_attempts {
                let reason = format!(
                    "the lease expired {} times without a result (worker lost or evaluation stuck)",
                    j.attempts
                );
                db::record_result(
                    &mut tx,
                    &db::NewResult {
                        job: j,
                        status: "failed",
                        cost: None,
                        reason: Some(&reason),
                        worker: None,
                        duration: None,
                        breakdown_json: None,
                    },
                )
                .await?;
                self.complete_if_done(&mut tx, &running, &mut changed, j).await?;
                out.failed += 1;
            } else {
                db::requeue(&mut tx, j.id).await?;
                out.requeued += 1;
            }
        }
        tx.commit().await?;
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
        tx.commit().await?;
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
