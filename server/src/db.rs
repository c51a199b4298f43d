//! Every SQL statement of the coordinator.
//!
//! SQLite in WAL mode with `synchronous = NORMAL`. Reads go through a pool of reader connections;
//! writes go through a single writer connection and start with `BEGIN IMMEDIATE` ([`Db::begin`]),
//! so a write transaction never fails half-way with `SQLITE_BUSY`. Functions take a pool (reads) or
//! a connection inside a transaction (writes) and return [`DbError`], with a distinct
//! [`DbError::NotFound`]; the routes map errors to HTTP statuses.

use std::collections::BTreeMap;
use std::str::FromStr;
use std::time::Duration;

use sqlx::sqlite::{SqliteConnectOptions, SqliteJournalMode, SqlitePoolOptions, SqliteSynchronous};
use sqlx::{Row, SqliteConnection, SqlitePool};

/// A storage error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DbError {
    /// The row does not exist.
    #[error("{what} {id} does not exist")]
    NotFound {
        /// Kind of row (`experiment`, `calibration`, `job`).
        what: &'static str,
        /// Its id.
        id: i64,
    },
    /// A stored value cannot be read back.
    #[error("stored data is corrupt: {0}")]
    Corrupt(String),
    /// The database refused or failed.
    #[error("database: {0}")]
    Sqlx(#[from] sqlx::Error),
    /// A migration failed.
    #[error("database migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
}

/// A write transaction.
pub type Tx = sqlx::Transaction<'static, sqlx::Sqlite>;

/// The coordinator's database: reader pool and one writer connection.
#[derive(Debug, Clone)]
pub struct Db {
    read: SqlitePool,
    write: SqlitePool,
}

/// Current time, Unix milliseconds.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

impl Db {
    /// Opens (creating it if absent) the SQLite database at `url` (`sqlite://path` or a plain
    /// path) and runs the migrations.
    pub async fn open(url: &str) -> Result<Self, DbError> {
        let url = if url.starts_with("sqlite:") { url.to_string() } else { format!("sqlite://{url}") };
        let options = SqliteConnectOptions::from_str(&url)?
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Normal)
            .busy_timeout(Duration::from_secs(10))
            .foreign_keys(true);
        let write = SqlitePoolOptions::new().max_connections(1).connect_with(options.clone()).await?;
        sqlx::migrate!("../migrations").run(&write).await?;
        let read = SqlitePoolOptions::new().max_connections(4).connect_with(options.read_only(true)).await?;
        Ok(Self { read, write })
    }

    /// Starts a write transaction (`BEGIN IMMEDIATE` on the writer connection).
    pub async fn begin(&self) -> Result<Tx, DbError> {
        Ok(self.write.begin_with("BEGIN IMMEDIATE").await?)
    }

    /// The reader pool.
    pub fn reader(&self) -> &SqlitePool {
        &self.read
    }

    /// Closes both pools.
    pub async fn close(&self) {
        self.read.close().await;
        self.write.close().await;
    }
}

// ---------------------------------------------------------------------------------------------
// experiments

/// Stores an experiment; returns its id.
pub async fn insert_experiment(
    tx: &mut SqliteConnection,
    name: &str,
    fluid: &str,
    case_text: &str,
    data_text: &str,
) -> Result<i64, DbError> {
    let row = sqlx::query(
        "INSERT INTO experiments (name, fluid, case_text, data_text, created) VALUES (?, ?, ?, ?, ?) RETURNING id",
    )
    .bind(name)
    .bind(fluid)
    .bind(case_text)
    .bind(data_text)
    .bind(now_ms())
    .fetch_one(tx)
    .await?;
    Ok(row.get(0))
}

/// An experiment with its texts.
pub async fn experiment(pool: &SqlitePool, id: i64) -> Result<cryofit_api::Experiment, DbError> {
    let row = sqlx::query("SELECT id, name, fluid, case_text, data_text, created FROM experiments WHERE id = ?")
        .bind(id)
        .fetch_optional(pool)
        .await?
        .ok_or(DbError::NotFound { what: "experiment", id })?;
    Ok(cryofit_api::Experiment {
        id: row.get(0),
        name: row.get(1),
        fluid: row.get(2),
        case: row.get(3),
        data: row.get(4),
        created: row.get(5),
    })
}

/// A page of experiments, newest last.
pub async fn experiments(
    pool: &SqlitePool,
    limit: i64,
    offset: i64,
) -> Result<Vec<cryofit_api::ExperimentSummary>, DbError> {
    let rows = sqlx::query("SELECT id, name, fluid, created FROM experiments ORDER BY id LIMIT ? OFFSET ?")
        .bind(limit)
        .bind(offset)
        .fetch_all(pool)
        .await?;
    Ok(rows
        .into_iter()
        .map(|r| cryofit_api::ExperimentSummary { id: r.get(0), name: r.get(1), fluid: r.get(2), created: r.get(3) })
        .collect())
}

// ---------------------------------------------------------------------------------------------
// calibrations

/// A calibration to store.
#[derive(Debug, Clone)]
pub struct NewCalibration<'a> {
    /// Name.
    pub name: &'a str,
    /// The request as JSON.
    pub spec_json: &'a str,
    /// Experiment ids as JSON.
    pub experiment_ids_json: &'a str,
    /// Total budget.
    pub budget: i64,
    /// Serialised pipeline.
    pub state_json: &'a str,
    /// Solver version.
    pub solver_version: &'a str,
    /// Fluid hashes as JSON.
    pub fluid_hashes_json: &'a str,
}

/// Stores a running calibration; returns its id.
pub async fn insert_calibration(tx: &mut SqliteConnection, c: &NewCalibration<'_>) -> Result<i64, DbError> {
    let now = now_ms();
    let row = sqlx::query(
        "INSERT INTO calibrations (name, spec_json, experiment_ids_json, status, budget, pipeline_state_json,
                                   solver_version, fluid_hashes, created, updated)
         VALUES (?, ?, ?, 'running', ?, ?, ?, ?, ?, ?) RETURNING id",
    )
    .bind(c.name)
    .bind(c.spec_json)
    .bind(c.experiment_ids_json)
    .bind(c.budget)
    .bind(c.state_json)
    .bind(c.solver_version)
    .bind(c.fluid_hashes_json)
    .bind(now)
    .bind(now)
    .fetch_one(tx)
    .await?;
    Ok(row.get(0))
}

/// A stored calibration, columns as stored.
#[derive(Debug, Clone)]
pub struct CalibrationRow {
    /// Id.
    pub id: i64,
    /// Name.
    pub name: String,
    /// Request JSON.
    pub spec_json: String,
    /// Experiment ids JSON.
    pub experiment_ids_json: String,
    /// Status.
    pub status: String,
    /// Budget.
    pub budget: i64,
    /// Evaluations told.
    pub evaluations: i64,
    /// Failed evaluations told.
    pub failed_evaluations: i64,
    /// Running stage.
    pub stage: i64,
    /// Best cost.
    pub best_cost: Option<f64>,
    /// Best parameters JSON.
    pub best_parameters_json: Option<String>,
    /// Stage reports JSON.
    pub reports_json: String,
    /// Solver version.
    pub solver_version: String,
    /// Fluid hashes JSON.
    pub fluid_hashes: String,
    /// Error.
    pub error: Option<String>,
    /// Created, ms.
    pub created: i64,
    /// Updated, ms.
    pub updated: i64,
}

const CALIBRATION_COLUMNS: &str = "id, name, spec_json, experiment_ids_json, status, budget, evaluations, \
     failed_evaluations, stage, best_cost, best_parameters_json, reports_json, solver_version, fluid_hashes, error, \
     created, updated";

fn calibration_row(r: &sqlx::sqlite::SqliteRow) -> CalibrationRow {
    CalibrationRow {
        id: r.get(0),
        name: r.get(1),
        spec_json: r.get(2),
        experiment_ids_json: r.get(3),
        status: r.get(4),
        budget: r.get(5),
        evaluations: r.get(6),
        failed_evaluations: r.get(7),
        stage: r.get(8),
        best_cost: r.get(9),
        best_parameters_json: r.get(10),
        reports_json: r.get(11),
        solver_version: r.get(12),
        fluid_hashes: r.get(13),
        error: r.get(14),
        created: r.get(15),
        updated: r.get(16),
    }
}

/// One calibration.
pub async fn calibration(pool: &SqlitePool, id: i64) -> Result<CalibrationRow, DbError> {
    let row = sqlx::query(&format!("SELECT {CALIBRATION_COLUMNS} FROM calibrations WHERE id = ?"))
        .bind(id)
        .fetch_optional(pool)
        .await?
        .ok_or(DbError::NotFound { what: "calibration", id })?;
    Ok(calibration_row(&row))
}

/// A page of calibrations.
pub async fn calibrations(
    pool: &SqlitePool,
    status: Option<&str>,
    limit: i64,
    offset: i64,
) -> Result<Vec<CalibrationRow>, DbError> {
    let rows = sqlx::query(&format!(
        "SELECT {CALIBRATION_COLUMNS} FROM calibrations WHERE (?1 IS NULL OR status = ?1) ORDER BY id LIMIT ?2 OFFSET ?3"
    ))
    .bind(status)
    .bind(limit)
    .bind(offset)
    .fetch_all(pool)
    .await?;
    Ok(rows.iter().map(calibration_row).collect())
}

/// Running calibrations with their pipeline state, for a restart.
pub async fn running_states(pool: &SqlitePool) -> Result<Vec<(i64, String)>, DbError> {
    let rows = sqlx::query("SELECT id, pipeline_state_json FROM calibrations WHERE status = 'running' ORDER BY id")
        .fetch_all(pool)
        .await?;
    Ok(rows.into_iter().map(|r| (r.get(0), r.get(1))).collect())
}

/// What a worker is checked against, per running calibration: (id, spec JSON, solver version,
/// fluid hashes JSON).
pub async fn running_builds(tx: &mut SqliteConnection) -> Result<Vec<(i64, String, String, String)>, DbError> {
    let rows = sqlx::query(
        "SELECT id, spec_json, solver_version, fluid_hashes FROM calibrations WHERE status = 'running' ORDER BY id",
    )
    .fetch_all(tx)
    .await?;
    Ok(rows.into_iter().map(|r| (r.get(0), r.get(1), r.get(2), r.get(3))).collect())
}

/// A calibration's status inside a transaction.
pub async fn calibration_status(tx: &mut SqliteConnection, id: i64) -> Result<String, DbError> {
    let row = sqlx::query("SELECT status FROM calibrations WHERE id = ?")
        .bind(id)
        .fetch_optional(tx)
        .await?
        .ok_or(DbError::NotFound { what: "calibration", id })?;
    Ok(row.get(0))
}

/// A calibration's progress after a tell.
#[derive(Debug, Clone)]
pub struct Progress {
    /// New status.
    pub status: &'static str,
    /// Evaluations told.
    pub evaluations: i64,
    /// Failed evaluations told.
    pub failed_evaluations: i64,
    /// Running stage.
    pub stage: i64,
    /// Best cost.
    pub best_cost: Option<f64>,
    /// Best parameters as JSON.
    pub best_parameters_json: Option<String>,
    /// Stage reports as JSON.
    pub reports_json: String,
    /// Serialised pipeline.
    pub state_json: String,
    /// Error.
    pub error: Option<String>,
}

/// Writes a calibration's progress and optimiser state.
pub async fn update_progress(tx: &mut SqliteConnection, id: i64, p: &Progress) -> Result<(), DbError> {
    sqlx::query(
        "UPDATE calibrations SET status = ?, evaluations = ?, failed_evaluations = ?, stage = ?, best_cost = ?,
                best_parameters_json = ?, reports_json = ?, pipeline_state_json = ?, error = ?, updated = ?
         WHERE id = ?",
    )
    .bind(p.status)
    .bind(p.evaluations)
    .bind(p.failed_evaluations)
    .bind(p.stage)
    .bind(p.best_cost)
    .bind(&p.best_parameters_json)
    .bind(&p.reports_json)
    .bind(&p.state_json)
    .bind(&p.error)
    .bind(now_ms())
    .bind(id)
    .execute(tx)
    .await?;
    Ok(())
}

/// Marks a calibration failed with an error (e.g. a state that cannot be resumed).
pub async fn fail_calibration(tx: &mut SqliteConnection, id: i64, error: &str) -> Result<(), DbError> {
    sqlx::query("UPDATE calibrations SET status = 'failed', error = ?, updated = ? WHERE id = ?")
        .bind(error)
        .bind(now_ms())
        .bind(id)
        .execute(tx)
        .await?;
    Ok(())
}

/// Cancels a calibration: its queued and leased jobs fail with reason "calibration cancelled"
/// (a late result of one is recorded as stale). Returns the previous status.
pub async fn cancel_calibration(tx: &mut SqliteConnection, id: i64) -> Result<String, DbError> {
    let status = calibration_status(&mut *tx, id).await?;
    if matches!(status.as_str(), "completed" | "failed" | "cancelled") {
        return Ok(status);
    }
    sqlx::query("UPDATE calibrations SET status = 'cancelled', updated = ? WHERE id = ?")
        .bind(now_ms())
        .bind(id)
        .execute(&mut *tx)
        .await?;
    sqlx::query(
        "UPDATE jobs SET status = 'failed', reason = 'calibration cancelled', lease_id = NULL, lease_expires = NULL
         WHERE calibration_id = ? AND status IN ('queued', 'leased')",
    )
    .bind(id)
    .execute(&mut *tx)
    .await?;
    Ok(status)
}

// ---------------------------------------------------------------------------------------------
// parameter sets and jobs

/// Stores a parameter set (a pipeline job) and one queued job per experiment.
pub async fn insert_parameter_set(
    tx: &mut SqliteConnection,
    calibration_id: i64,
    job: i64,
    stage: i64,
    parameters_json: &str,
    experiments: &[i64],
) -> Result<i64, DbError> {
    let now = now_ms();
    let row = sqlx::query(
        "INSERT INTO parameter_sets (calibration_id, job, stage, parameters_json, status, created)
         VALUES (?, ?, ?, ?, 'pending', ?) RETURNING id",
    )
    .bind(calibration_id)
    .bind(job)
    .bind(stage)
    .bind(parameters_json)
    .bind(now)
    .fetch_one(&mut *tx)
    .await?;
    let ps: i64 = row.get(0);
    for &e in experiments {
        sqlx::query(
            "INSERT INTO jobs (calibration_id, parameter_set_id, experiment_id, status, created)
             VALUES (?, ?, ?, 'queued', ?)",
        )
        .bind(calibration_id)
        .bind(ps)
        .bind(e)
        .bind(now)
        .execute(&mut *tx)
        .await?;
    }
    Ok(ps)
}

/// Number of queued jobs of a calibration.
pub async fn queued_jobs(tx: &mut SqliteConnection, calibration_id: i64) -> Result<i64, DbError> {
    let row = sqlx::query("SELECT COUNT(*) FROM jobs WHERE calibration_id = ? AND status = 'queued'")
        .bind(calibration_id)
        .fetch_one(tx)
        .await?;
    Ok(row.get(0))
}

/// Records a worker's claim (name, slots, time).
pub async fn touch_worker(tx: &mut SqliteConnection, name: &str, slots: i64) -> Result<(), DbError> {
    sqlx::query(
        "INSERT INTO workers (name, slots, last_heartbeat) VALUES (?1, ?2, ?3)
         ON CONFLICT (name) DO UPDATE SET slots = ?2, last_heartbeat = ?3",
    )
    .bind(name)
    .bind(slots)
    .bind(now_ms())
    .execute(tx)
    .await?;
    Ok(())
}

/// Slots of the workers seen since `since_ms`.
pub async fn active_slots(tx: &mut SqliteConnection, since_ms: i64) -> Result<i64, DbError> {
    let row = sqlx::query("SELECT COALESCE(SUM(slots), 0) FROM workers WHERE last_heartbeat >= ?")
        .bind(since_ms)
        .fetch_one(tx)
        .await?;
    Ok(row.get(0))
}

/// A leased job as the claim returns it.
#[derive(Debug, Clone)]
pub struct Claimed {
    /// Job id.
    pub id: i64,
    /// Lease id.
    pub lease_id: String,
    /// Calibration.
    pub calibration_id: i64,
    /// Parameter set.
    pub parameter_set_id: i64,
    /// Experiment.
    pub experiment_id: i64,
    /// Parameter values JSON.
    pub parameters_json: String,
}

/// Leases up to `n` queued jobs of the given calibrations, oldest first, in one statement.
pub async fn claim(
    tx: &mut SqliteConnection,
    calibrations: &[i64],
    n: i64,
    lease_prefix: &str,
    owner: &str,
    expires_ms: i64,
) -> Result<Vec<Claimed>, DbError> {
    let ids = serde_json::to_string(calibrations).map_err(|e| DbError::Corrupt(e.to_string()))?;
    let rows = sqlx::query(
        "UPDATE jobs SET status = 'leased', lease_id = ?1 || '-' || id, lease_owner = ?2, lease_expires = ?3,
                attempts = attempts + 1
         WHERE id IN (SELECT id FROM jobs WHERE status = 'queued'
                      AND calibration_id IN (SELECT value FROM json_each(?4)) ORDER BY id LIMIT ?5)
         RETURNING id, lease_id, calibration_id, parameter_set_id, experiment_id,
                   (SELECT parameters_json FROM parameter_sets p WHERE p.id = parameter_set_id)",
    )
    .bind(lease_prefix)
    .bind(owner)
    .bind(expires_ms)
    .bind(ids)
    .bind(n)
    .fetch_all(tx)
    .await?;
    let mut v: Vec<Claimed> = rows
        .into_iter()
        .map(|r| Claimed {
            id: r.get(0),
            lease_id: r.get(1),
            calibration_id: r.get(2),
            parameter_set_id: r.get(3),
            experiment_id: r.get(4),
            parameters_json: r.get(5),
        })
        .collect();
    v.sort_by_key(|c| c.id);
    Ok(v)
}

/// Extends a lease; `None` when the job is not leased under `lease_id` any more.
pub async fn heartbeat(
    tx: &mut SqliteConnection,
    job: i64,
    lease_id: &str,
    expires_ms: i64,
) -> Result<Option<String>, DbError> {
    let row = sqlx::query(
        "UPDATE jobs SET lease_expires = ? WHERE id = ? AND status = 'leased' AND lease_id = ? RETURNING lease_owner",
    )
    .bind(expires_ms)
    .bind(job)
    .bind(lease_id)
    .fetch_optional(&mut *tx)
    .await?;
    let Some(row) = row else { return Ok(None) };
    let owner: Option<String> = row.get(0);
    if let Some(owner) = &owner {
        sqlx::query("UPDATE workers SET last_heartbeat = ? WHERE name = ?")
            .bind(now_ms())
            .bind(owner)
            .execute(&mut *tx)
            .await?;
    }
    Ok(Some(owner.unwrap_or_default()))
}

/// A job's state.
#[derive(Debug, Clone)]
pub struct JobRow {
    /// Id.
    pub id: i64,
    /// Calibration.
    pub calibration_id: i64,
    /// Parameter set.
    pub parameter_set_id: i64,
    /// Experiment.
    pub experiment_id: i64,
    /// `queued`, `leased`, `done` or `failed`.
    pub status: String,
    /// Current lease.
    pub lease_id: Option<String>,
    /// Leases given so far.
    pub attempts: i64,
}

fn job_row(r: &sqlx::sqlite::SqliteRow) -> JobRow {
    JobRow {
        id: r.get(0),
        calibration_id: r.get(1),
        parameter_set_id: r.get(2),
        experiment_id: r.get(3),
        status: r.get(4),
        lease_id: r.get(5),
        attempts: r.get(6),
    }
}

const JOB_COLUMNS: &str = "id, calibration_id, parameter_set_id, experiment_id, status, lease_id, attempts";

/// One job.
pub async fn job(tx: &mut SqliteConnection, id: i64) -> Result<JobRow, DbError> {
    let row = sqlx::query(&format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?"))
        .bind(id)
        .fetch_optional(tx)
        .await?
        .ok_or(DbError::NotFound { what: "job", id })?;
    Ok(job_row(&row))
}

/// Leased jobs whose lease expired before `now_ms`.
pub async fn expired_jobs(tx: &mut SqliteConnection, now_ms: i64) -> Result<Vec<JobRow>, DbError> {
    let rows = sqlx::query(&format!(
        "SELECT {JOB_COLUMNS} FROM jobs WHERE status = 'leased' AND lease_expires < ? ORDER BY id"
    ))
    .bind(now_ms)
    .fetch_all(tx)
    .await?;
    Ok(rows.iter().map(job_row).collect())
}

/// Puts a job back in the queue (its lease is void).
pub async fn requeue(tx: &mut SqliteConnection, id: i64) -> Result<(), DbError> {
    sqlx::query(
        "UPDATE jobs SET status = 'queued', lease_id = NULL, lease_owner = NULL, lease_expires = NULL WHERE id = ?",
    )
    .bind(id)
    .execute(tx)
    .await?;
    Ok(())
}

/// A result to record.
#[derive(Debug, Clone)]
pub struct NewResult<'a> {
    /// The job.
    pub job: &'a JobRow,
    /// `ok`, `failed` or `stale`.
    pub status: &'static str,
    /// Cost.
    pub cost: Option<f64>,
    /// Failure reason.
    pub reason: Option<&'a str>,
    /// Worker name.
    pub worker: Option<&'a str>,
    /// Duration, s.
    pub duration: Option<f64>,
    /// Breakdown JSON.
    pub breakdown_json: Option<String>,
}

/// Records a result; unless stale, also finishes the job (`done` or `failed`) and counts it for
/// the worker.
pub async fn record_result(tx: &mut SqliteConnection, r: &NewResult<'_>) -> Result<(), DbError> {
    sqlx::query(
        "INSERT INTO cost_results (calibration_id, job_id, parameter_set_id, experiment_id, status, cost, reason,
                                   worker, duration, breakdown_json, created)
         VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
    )
    .bind(r.job.calibration_id)
    .bind(r.job.id)
    .bind(r.job.parameter_set_id)
    .bind(r.job.experiment_id)
    .bind(r.status)
    .bind(r.cost)
    .bind(r.reason)
    .bind(r.worker)
    .bind(r.duration)
    .bind(&r.breakdown_json)
    .bind(now_ms())
    .execute(&mut *tx)
    .await?;
    if r.status == "stale" {
        return Ok(());
    }
    let status = if r.status == "ok" { "done" } else { "failed" };
    sqlx::query(
        "UPDATE jobs SET status = ?, cost = ?, reason = ?, duration = ?, lease_id = NULL, lease_expires = NULL
         WHERE id = ?",
    )
    .bind(status)
    .bind(r.cost)
    .bind(r.reason)
    .bind(r.duration)
    .bind(r.job.id)
    .execute(&mut *tx)
    .await?;
    if let Some(w) = r.worker {
        sqlx::query("UPDATE workers SET evaluations = evaluations + 1, last_heartbeat = ? WHERE name = ?")
            .bind(now_ms())
            .bind(w)
            .execute(&mut *tx)
            .await?;
    }
    Ok(())
}

/// The jobs of a parameter set in id (= experiment) order: (status, cost, reason).
pub async fn parameter_set_jobs(
    tx: &mut SqliteConnection,
    parameter_set_id: i64,
) -> Result<Vec<(String, Option<f64>, Option<String>)>, DbError> {
    let rows = sqlx::query("SELECT status, cost, reason FROM jobs WHERE parameter_set_id = ? ORDER BY id")
        .bind(parameter_set_id)
        .fetch_all(tx)
        .await?;
    Ok(rows.into_iter().map(|r| (r.get(0), r.get(1), r.get(2))).collect())
}

/// Finishes a parameter set; returns its pipeline job id.
pub async fn finish_parameter_set(
    tx: &mut SqliteConnection,
    id: i64,
    status: &'static str,
    cost: Option<f64>,
    reason: Option<&str>,
) -> Result<i64, DbError> {
    let row = sqlx::query("UPDATE parameter_sets SET status = ?, cost = ?, reason = ? WHERE id = ? RETURNING job")
        .bind(status)
        .bind(cost)
        .bind(reason)
        .bind(id)
        .fetch_optional(tx)
        .await?
        .ok_or(DbError::NotFound { what: "parameter set", id })?;
    Ok(row.get(0))
}

// ---------------------------------------------------------------------------------------------
// history

/// A page of a calibration's parameter sets, in the order they were asked.
pub async fn parameter_sets_page(
    pool: &SqlitePool,
    calibration_id: i64,
    status: Option<&str>,
    stage: Option<i64>,
    limit: i64,
    offset: i64,
) -> Result<Vec<cryofit_api::ParameterSetItem>, DbError> {
    let rows = sqlx::query(
        "SELECT id, calibration_id, job, stage, parameters_json, status, cost, reason, created FROM parameter_sets
         WHERE calibration_id = ?1 AND (?2 IS NULL OR status = ?2) AND (?3 IS NULL OR stage = ?3)
         ORDER BY id LIMIT ?4 OFFSET ?5",
    )
    .bind(calibration_id)
    .bind(status)
    .bind(stage)
    .bind(limit)
    .bind(offset)
    .fetch_all(pool)
    .await?;
    rows.into_iter()
        .map(|r| {
            let params: String = r.get(4);
            let parameters: BTreeMap<String, f64> = serde_json::from_str(&params)
                .map_err(|e| DbError::Corrupt(format!("parameter set parameters: {e}")))?;
            Ok(cryofit_api::ParameterSetItem {
                id: r.get(0),
                calibration_id: r.get(1),
                job: r.get(2),
                stage: r.get(3),
                parameters,
                status: r.get(5),
                cost: r.get(6),
                reason: r.get(7),
                created: r.get(8),
            })
        })
        .collect()
}

/// A page of a calibration's results, in the order they arrived.
pub async fn results_page(
    pool: &SqlitePool,
    calibration_id: i64,
    status: Option<&str>,
    experiment_id: Option<i64>,
    limit: i64,
    offset: i64,
) -> Result<Vec<cryofit_api::ResultItem>, DbError> {
    let rows = sqlx::query(
        "SELECT id, parameter_set_id, job_id, experiment_id, status, cost, reason, worker, duration, breakdown_json,
                created
         FROM cost_results
         WHERE calibration_id = ?1 AND (?2 IS NULL OR status = ?2) AND (?3 IS NULL OR experiment_id = ?3)
         ORDER BY id LIMIT ?4 OFFSET ?5",
    )
    .bind(calibration_id)
    .bind(status)
    .bind(experiment_id)
    .bind(limit)
    .bind(offset)
    .fetch_all(pool)
    .await?;
    rows.into_iter()
        .map(|r| {
            let breakdown: Option<String> = r.get(9);
            let breakdown = breakdown
                .map(|b| serde_json::from_str(&b))
                .transpose()
                .map_err(|e| DbError::Corrupt(format!("result breakdown: {e}")))?;
            Ok(cryofit_api::ResultItem {
                id: r.get(0),
                parameter_set_id: r.get(1),
                job_id: r.get(2),
                experiment_id: r.get(3),
                status: r.get(4),
                cost: r.get(5),
                reason: r.get(6),
                worker: r.get(7),
                duration_s: r.get(8),
                breakdown,
                created: r.get(10),
            })
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// metrics

/// Job counts by status.
pub async fn job_counts(pool: &SqlitePool) -> Result<BTreeMap<String, i64>, DbError> {
    let rows = sqlx::query("SELECT status, COUNT(*) FROM jobs GROUP BY status").fetch_all(pool).await?;
    Ok(rows.into_iter().map(|r| (r.get(0), r.get(1))).collect())
}
