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
    /// Why the last write failed, `None` after a successful one.
    write_error: std::sync::Arc<std::sync::Mutex<Option<String>>>,
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
        // A write that failed (disk full, file size limit, I/O error) can leave the connection
        // inside a transaction that SQLite already ended, which sqlx still counts as open: every
        // later `BEGIN` would fail with "non-zero transaction depth". Such a connection is closed
        // when it is next taken from the pool, and a fresh one is opened.
        let write = SqlitePoolOptions::new()
            .max_connections(1)
            .before_acquire(|conn, _| {
                Box::pin(async move {
                    use sqlx::Connection as _;
                    if conn.is_in_transaction() {
                        tracing::warn!("the writer connection was left inside a failed transaction: reopening it");
                        return Ok(false);
                    }
                    Ok(true)
                })
            })
            .connect_with(options.clone())
            .await?;
        sqlx::migrate!("../migrations").run(&write).await?;
        let read = SqlitePoolOptions::new().max_connections(4).connect_with(options.read_only(true)).await?;
        Ok(Self { read, write, write_error: Default::default() })
    }

    /// Starts a write transaction (`BEGIN IMMEDIATE` on the writer connection).
    pub async fn begin(&self) -> Result<Tx, DbError> {
        let tx = self.write.begin_with("BEGIN IMMEDIATE").await;
        self.note(tx.as_ref().err());
        Ok(tx?)
    }

    /// Commits a write transaction, recording the outcome for [`Db::write_error`].
    pub async fn commit(&self, tx: Tx) -> Result<(), DbError> {
        let done = tx.commit().await;
        self.note(done.as_ref().err());
        Ok(done?)
    }

    fn note(&self, e: Option<&sqlx::Error>) {
        if let Ok(mut w) = self.write_error.lock() {
            *w = e.map(|e| e.to_string());
        }
    }

    /// Why the last write transaction failed to start or commit, if it did.
    pub fn write_error(&self) -> Option<String> {
        self.write_error.lock().ok().and_then(|w| w.clone())
    }

    /// The writer pool (for tests that need to reach the writer connection itself).
    #[doc(hidden)]
    pub fn writer(&self) -> &SqlitePool {
        &self.write
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

/// Rows per multi-row statement (SQLite allows 32 766 bound values; 11 per row at most here).
const ROWS_PER_STATEMENT: usize = 1000;

/// A parameter set to store: the pipeline's job id, its stage and the parameter values as JSON.
#[derive(Debug, Clone)]
pub struct NewParameterSet {
    /// The pipeline's job id.
    pub job: i64,
    /// Stage that asked for it.
    pub stage: i64,
    /// Parameter values JSON.
    pub parameters_json: String,
}

/// Stores parameter sets (pipeline jobs) in the order given, each with one queued job per
/// experiment (job ids follow the sets' order, then the experiments' order), in two statements
/// per thousand sets.
pub async fn insert_parameter_sets(
    tx: &mut SqliteConnection,
    calibration_id: i64,
    sets: &[NewParameterSet],
    experiments: &[i64],
) -> Result<(), DbError> {
    let now = now_ms();
    for chunk in sets.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
            "INSERT INTO parameter_sets (calibration_id, job, stage, parameters_json, status, created) ",
        );
        q.push_values(chunk, |mut b, s| {
            b.push_bind(calibration_id)
                .push_bind(s.job)
                .push_bind(s.stage)
                .push_bind(&s.parameters_json)
                .push_bind("pending")
                .push_bind(now);
        });
        q.push(" RETURNING id, job");
        let rows = q.build().persistent(false).fetch_all(&mut *tx).await?;
        let ids: std::collections::HashMap<i64, i64> = rows.iter().map(|r| (r.get(1), r.get(0))).collect();
        let mut jobs = Vec::with_capacity(chunk.len() * experiments.len());
        for s in chunk {
            let ps = *ids
                .get(&s.job)
                .ok_or_else(|| DbError::Corrupt(format!("parameter set of job {} was not stored", s.job)))?;
            jobs.extend(experiments.iter().map(|&e| (ps, e)));
        }
        for part in jobs.chunks(ROWS_PER_STATEMENT) {
            let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
                "INSERT INTO jobs (calibration_id, parameter_set_id, experiment_id, status, created) ",
            );
            q.push_values(part, |mut b, &(ps, e)| {
                b.push_bind(calibration_id).push_bind(ps).push_bind(e).push_bind("queued").push_bind(now);
            });
            q.build().persistent(false).execute(&mut *tx).await?;
        }
    }
    Ok(())
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

/// Leases up to `n` queued jobs of the given calibrations in one statement, fairly: round-robin
/// over the calibrations in the order given (each calibration's oldest job first, then each
/// one's second, …), so that one calibration's queue cannot hold every worker. The caller rotates
/// the order between claims so that one-job claims take turns too.
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
        "WITH turn AS (SELECT value AS calibration_id, key AS position FROM json_each(?4)),
              ranked AS (SELECT j.id AS id, t.position AS position,
                                ROW_NUMBER() OVER (PARTITION BY j.calibration_id ORDER BY j.id) AS rank
                         FROM jobs j JOIN turn t ON t.calibration_id = j.calibration_id
                         WHERE j.status = 'queued')
         UPDATE jobs SET status = 'leased', lease_id = ?1 || '-' || id, lease_owner = ?2, lease_expires = ?3,
                attempts = attempts + 1
         WHERE id IN (SELECT id FROM ranked ORDER BY rank, position LIMIT ?5)
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

/// Jobs by id, in id order; ids that do not exist are left out.
pub async fn jobs(tx: &mut SqliteConnection, ids: &[i64]) -> Result<Vec<JobRow>, DbError> {
    let ids = serde_json::to_string(ids).map_err(|e| DbError::Corrupt(e.to_string()))?;
    let rows = sqlx::query(&format!(
        "SELECT {JOB_COLUMNS} FROM jobs WHERE id IN (SELECT value FROM json_each(?)) ORDER BY id"
    ))
    .bind(ids)
    .fetch_all(tx)
    .await?;
    Ok(rows.iter().map(job_row).collect())
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

/// Puts every leased job back in the queue, as if its lease had never been given (the attempt
/// is not counted). For a database whose previous coordinator and workers are known to be gone.
/// Returns the number of jobs released.
pub async fn release_leases(tx: &mut SqliteConnection) -> Result<u64, DbError> {
    let done = sqlx::query(
        "UPDATE jobs SET status = 'queued', lease_id = NULL, lease_owner = NULL, lease_expires = NULL,
                attempts = MAX(attempts - 1, 0)
         WHERE status = 'leased'",
    )
    .execute(tx)
    .await?;
    Ok(done.rows_affected())
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

/// Records results in the order given (one statement per thousand); the ones that are not stale
/// also finish their job (`done` or `failed`, one more statement). The worker's count is kept by
/// [`count_evaluations`].
pub async fn record_results(tx: &mut SqliteConnection, results: &[NewResult<'_>]) -> Result<(), DbError> {
    let now = now_ms();
    for chunk in results.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
            "INSERT INTO cost_results (calibration_id, job_id, parameter_set_id, experiment_id, status, cost, reason,
                                       worker, duration, breakdown_json, created) ",
        );
        q.push_values(chunk, |mut b, r| {
            b.push_bind(r.job.calibration_id)
                .push_bind(r.job.id)
                .push_bind(r.job.parameter_set_id)
                .push_bind(r.job.experiment_id)
                .push_bind(r.status)
                .push_bind(r.cost)
                .push_bind(r.reason)
                .push_bind(r.worker)
                .push_bind(r.duration)
                .push_bind(r.breakdown_json.as_deref())
                .push_bind(now);
        });
        q.build().persistent(false).execute(&mut *tx).await?;
        let finished: Vec<&NewResult<'_>> = chunk.iter().filter(|r| r.status != "stale").collect();
        if finished.is_empty() {
            continue;
        }
        let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
            "UPDATE jobs SET status = v.column2, cost = v.column3, reason = v.column4, duration = v.column5,
                             lease_id = NULL, lease_expires = NULL
             FROM (",
        );
        q.push_values(finished, |mut b, r| {
            b.push_bind(r.job.id)
                .push_bind(if r.status == "ok" { "done" } else { "failed" })
                .push_bind(r.cost)
                .push_bind(r.reason)
                .push_bind(r.duration);
        });
        q.push(") AS v WHERE jobs.id = v.column1");
        q.build().persistent(false).execute(&mut *tx).await?;
    }
    Ok(())
}

/// Counts `n` results for a worker and marks it seen.
pub async fn count_evaluations(tx: &mut SqliteConnection, worker: &str, n: i64) -> Result<(), DbError> {
    sqlx::query("UPDATE workers SET evaluations = evaluations + ?, last_heartbeat = ? WHERE name = ?")
        .bind(n)
        .bind(now_ms())
        .bind(worker)
        .execute(tx)
        .await?;
    Ok(())
}

/// One job of a parameter set, with the set's calibration and pipeline job id.
#[derive(Debug, Clone)]
pub struct SetPart {
    /// Parameter set.
    pub parameter_set_id: i64,
    /// Its calibration.
    pub calibration_id: i64,
    /// Its pipeline job id.
    pub pipeline_job: i64,
    /// The job's status.
    pub status: String,
    /// The job's cost.
    pub cost: Option<f64>,
    /// The job's failure reason.
    pub reason: Option<String>,
}

/// The jobs of pending parameter sets, by set and then job id (= experiment order).
pub async fn pending_set_parts(tx: &mut SqliteConnection, sets: &[i64]) -> Result<Vec<SetPart>, DbError> {
    let ids = serde_json::to_string(sets).map_err(|e| DbError::Corrupt(e.to_string()))?;
    let rows = sqlx::query(
        "SELECT j.parameter_set_id, p.calibration_id, p.job, j.status, j.cost, j.reason
         FROM jobs j JOIN parameter_sets p ON p.id = j.parameter_set_id
         WHERE j.parameter_set_id IN (SELECT value FROM json_each(?)) AND p.status = 'pending'
         ORDER BY j.parameter_set_id, j.id",
    )
    .bind(ids)
    .fetch_all(tx)
    .await?;
    Ok(rows
        .into_iter()
        .map(|r| SetPart {
            parameter_set_id: r.get(0),
            calibration_id: r.get(1),
            pipeline_job: r.get(2),
            status: r.get(3),
            cost: r.get(4),
            reason: r.get(5),
        })
        .collect())
}

/// A finished parameter set: (id, `ok` or `failed`, summed cost, reason).
pub type FinishedSet<'a> = (i64, &'static str, Option<f64>, Option<&'a str>);

/// Finishes parameter sets (one statement per thousand).
pub async fn finish_parameter_sets(tx: &mut SqliteConnection, sets: &[FinishedSet<'_>]) -> Result<(), DbError> {
    for chunk in sets.chunks(ROWS_PER_STATEMENT) {
        let mut q = sqlx::QueryBuilder::<sqlx::Sqlite>::new(
            "UPDATE parameter_sets SET status = v.column2, cost = v.column3, reason = v.column4 FROM (",
        );
        q.push_values(chunk, |mut b, &(id, status, cost, reason)| {
            b.push_bind(id).push_bind(status).push_bind(cost).push_bind(reason);
        });
        q.push(") AS v WHERE parameter_sets.id = v.column1");
        q.build().persistent(false).execute(&mut *tx).await?;
    }
    Ok(())
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
// dashboard

/// A worker as the coordinator last saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct WorkerRow {
    /// Its name.
    pub name: String,
    /// Simulation slots it claimed with.
    pub slots: i64,
    /// Last claim, heartbeat or result, Unix ms.
    pub last_heartbeat: i64,
    /// Results it reported.
    pub evaluations: i64,
}

/// Every worker, most recently seen first.
pub async fn workers(pool: &SqlitePool) -> Result<Vec<WorkerRow>, DbError> {
    let rows =
        sqlx::query("SELECT name, slots, last_heartbeat, evaluations FROM workers ORDER BY last_heartbeat DESC, name")
            .fetch_all(pool)
            .await?;
    Ok(rows
        .into_iter()
        .map(|r| WorkerRow { name: r.get(0), slots: r.get(1), last_heartbeat: r.get(2), evaluations: r.get(3) })
        .collect())
}

/// Results recorded since `since_ms`, per worker name.
pub async fn results_per_worker_since(pool: &SqlitePool, since_ms: i64) -> Result<BTreeMap<String, i64>, DbError> {
    let rows = sqlx::query(
        "SELECT worker, COUNT(*) FROM cost_results WHERE created >= ? AND worker IS NOT NULL GROUP BY worker",
    )
    .bind(since_ms)
    .fetch_all(pool)
    .await?;
    Ok(rows.into_iter().map(|r| (r.get(0), r.get(1))).collect())
}

/// Every parameter set of a calibration, in the order they were asked (page by page).
pub async fn all_parameter_sets(
    pool: &SqlitePool,
    calibration_id: i64,
) -> Result<Vec<cryofit_api::ParameterSetItem>, DbError> {
    let mut all = Vec::new();
    loop {
        let page =
            parameter_sets_page(pool, calibration_id, None, None, cryofit_api::MAX_PAGE, all.len() as i64).await?;
        let n = page.len();
        all.extend(page);
        if (n as i64) < cryofit_api::MAX_PAGE {
            return Ok(all);
        }
    }
}

/// Every result of a calibration, in the order they arrived (page by page).
pub async fn all_results(pool: &SqlitePool, calibration_id: i64) -> Result<Vec<cryofit_api::ResultItem>, DbError> {
    let mut all = Vec::new();
    loop {
        let page = results_page(pool, calibration_id, None, None, cryofit_api::MAX_PAGE, all.len() as i64).await?;
        let n = page.len();
        all.extend(page);
        if (n as i64) < cryofit_api::MAX_PAGE {
            return Ok(all);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// metrics

/// Job counts by status.
pub async fn job_counts(pool: &SqlitePool) -> Result<BTreeMap<String, i64>, DbError> {
    let rows = sqlx::query("SELECT status, COUNT(*) FROM jobs GROUP BY status").fetch_all(pool).await?;
    Ok(rows.into_iter().map(|r| (r.get(0), r.get(1))).collect())
}

// ---------------------------------------------------------------------------------------------
// dashboard sessions

/// Stores a session by the digest of its id.
pub async fn insert_session(
    tx: &mut SqliteConnection,
    digest: &str,
    created: i64,
    expires: i64,
) -> Result<(), DbError> {
    sqlx::query("INSERT INTO sessions (digest, created, expires) VALUES (?, ?, ?)")
        .bind(digest)
        .bind(created)
        .bind(expires)
        .execute(tx)
        .await?;
    Ok(())
}

/// True when a session with this digest is stored and has not expired at `now_ms`.
pub async fn session_valid(pool: &SqlitePool, digest: &str, now_ms: i64) -> Result<bool, DbError> {
    let row = sqlx::query("SELECT 1 FROM sessions WHERE digest = ? AND expires > ?")
        .bind(digest)
        .bind(now_ms)
        .fetch_optional(pool)
        .await?;
    Ok(row.is_some())
}

/// Revokes a session.
pub async fn delete_session(tx: &mut SqliteConnection, digest: &str) -> Result<(), DbError> {
    sqlx::query("DELETE FROM sessions WHERE digest = ?").bind(digest).execute(tx).await?;
    Ok(())
}

/// Forgets sessions that expired before `now_ms`.
pub async fn delete_expired_sessions(tx: &mut SqliteConnection, now_ms: i64) -> Result<(), DbError> {
    sqlx::query("DELETE FROM sessions WHERE expires <= ?").bind(now_ms).execute(tx).await?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    async fn scratch_db(tag: &str) -> (Db, std::path::PathBuf) {
        let dir = std::env::temp_dir().join(format!("cryofit-db-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        let db = Db::open(&dir.join("c.db").display().to_string()).await.expect("open");
        (db, dir)
    }

    async fn store(db: &Db, data: &str) -> Result<i64, DbError> {
        let mut tx = db.begin().await?;
        let id = insert_experiment(&mut tx, "e", "nitrogen", "case", data).await?;
        db.commit(tx).await?;
        Ok(id)
    }

    #[tokio::test]
    async fn a_transaction_that_failed_under_sqlx_does_not_wedge_later_writes() {
        let (db, dir) = scratch_db("wedge").await;
        // SQLite ends the transaction behind sqlx's back, as an I/O error during COMMIT does: the
        // COMMIT fails and sqlx still counts the transaction as open
        let mut tx = db.begin().await.expect("begin");
        sqlx::query("ROLLBACK").execute(&mut *tx).await.expect("rollback");
        let e = db.commit(tx).await.expect_err("nothing to commit");
        assert!(e.to_string().contains("no transaction is active"), "{e}");
        assert!(db.write_error().is_some());
        // before: "attempted to call begin_with at non-zero transaction depth", for every write
        for k in 0..3 {
            store(&db, "x").await.unwrap_or_else(|e| panic!("write {k} after the failure: {e}"));
        }
        assert_eq!(db.write_error(), None);
        db.close().await;
        let _ = std::fs::remove_dir_all(dir);
    }

    #[tokio::test]
    async fn a_full_database_fails_one_write_and_the_next_ones_work_again() {
        let (db, dir) = scratch_db("full").await;
        store(&db, "small").await.expect("first write");
        // the file may not grow: the disk is full as far as SQLite can tell
        let pages: i64 = sqlx::query_scalar("PRAGMA page_count").fetch_one(db.writer()).await.expect("page count");
        sqlx::query(&format!("PRAGMA max_page_count = {}", pages + 1)).execute(db.writer()).await.expect("limit");
        let big = "x".repeat(1 << 20);
        let e = store(&db, &big).await.expect_err("a megabyte does not fit");
        assert!(e.to_string().contains("full"), "{e}");
        store(&db, "small again").await.expect("a small write after the failed one");
        db.close().await;
        let _ = std::fs::remove_dir_all(dir);
    }
}
