//! The `jobs` table: one evaluation of a parameter set on one experiment, its lease, and the
//! results workers report for it (`cost_results`).

use std::collections::BTreeMap;

use sqlx::{SqliteConnection, SqlitePool};

use super::{DbError, ROWS_PER_STATEMENT, id_list, now_ms};

/// Number of queued jobs of a calibration.
pub async fn queued_jobs(tx: &mut SqliteConnection, calibration_id: i64) -> Result<i64, DbError> {
    let n = sqlx::query_scalar("SELECT COUNT(*) FROM jobs WHERE calibration_id = ? AND status = 'queued'")
        .bind(calibration_id)
        .fetch_one(tx)
        .await?;
    Ok(n)
}

/// A leased job as the claim returns it.
#[derive(Debug, Clone, sqlx::FromRow)]
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
    let ids = id_list(calibrations)?;
    let mut claimed: Vec<Claimed> = sqlx::query_as(
        "WITH turn AS (SELECT value AS calibration_id, key AS position FROM json_each(?4)),
              ranked AS (SELECT j.id AS id, t.position AS position,
                                ROW_NUMBER() OVER (PARTITION BY j.calibration_id ORDER BY j.id) AS rank
                         FROM jobs j JOIN turn t ON t.calibration_id = j.calibration_id
                         WHERE j.status = 'queued')
         UPDATE jobs SET status = 'leased', lease_id = ?1 || '-' || id, lease_owner = ?2, lease_expires = ?3,
                attempts = attempts + 1
         WHERE id IN (SELECT id FROM ranked ORDER BY rank, position LIMIT ?5)
         RETURNING id, lease_id, calibration_id, parameter_set_id, experiment_id,
                   (SELECT parameters_json FROM parameter_sets p WHERE p.id = parameter_set_id) AS parameters_json",
    )
    .bind(lease_prefix)
    .bind(owner)
    .bind(expires_ms)
    .bind(ids)
    .bind(n)
    .fetch_all(tx)
    .await?;
    claimed.sort_by_key(|c| c.id);
    Ok(claimed)
}

/// Extends a lease; `None` when the job is not leased under `lease_id` any more.
pub async fn heartbeat(
    tx: &mut SqliteConnection,
    job: i64,
    lease_id: &str,
    expires_ms: i64,
) -> Result<Option<String>, DbError> {
    let row: Option<Option<String>> = sqlx::query_scalar(
        "UPDATE jobs SET lease_expires = ? WHERE id = ? AND status = 'leased' AND lease_id = ? RETURNING lease_owner",
    )
    .bind(expires_ms)
    .bind(job)
    .bind(lease_id)
    .fetch_optional(&mut *tx)
    .await?;
    let Some(owner) = row else { return Ok(None) };
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
#[derive(Debug, Clone, sqlx::FromRow)]
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

const JOB_COLUMNS: &str = "id, calibration_id, parameter_set_id, experiment_id, status, lease_id, attempts";

/// One job.
pub async fn job(tx: &mut SqliteConnection, id: i64) -> Result<JobRow, DbError> {
    let row = sqlx::query_as(&format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = ?"))
        .bind(id)
        .fetch_optional(tx)
        .await?
        .ok_or(DbError::NotFound { what: "job", id })?;
    Ok(row)
}

/// Jobs by id, in id order; ids that do not exist are left out.
pub async fn jobs(tx: &mut SqliteConnection, ids: &[i64]) -> Result<Vec<JobRow>, DbError> {
    let ids = id_list(ids)?;
    let rows = sqlx::query_as(&format!(
        "SELECT {JOB_COLUMNS} FROM jobs WHERE id IN (SELECT value FROM json_each(?)) ORDER BY id"
    ))
    .bind(ids)
    .fetch_all(tx)
    .await?;
    Ok(rows)
}

/// Leased jobs whose lease expired before `now_ms`.
pub async fn expired_jobs(tx: &mut SqliteConnection, now_ms: i64) -> Result<Vec<JobRow>, DbError> {
    let rows = sqlx::query_as(&format!(
        "SELECT {JOB_COLUMNS} FROM jobs WHERE status = 'leased' AND lease_expires < ? ORDER BY id"
    ))
    .bind(now_ms)
    .fetch_all(tx)
    .await?;
    Ok(rows)
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

/// A count of jobs with one status.
#[derive(Debug, sqlx::FromRow)]
struct StatusCount {
    status: String,
    n: i64,
}

/// Job counts by status.
pub async fn job_counts(pool: &SqlitePool) -> Result<BTreeMap<String, i64>, DbError> {
    let rows: Vec<StatusCount> =
        sqlx::query_as("SELECT status, COUNT(*) AS n FROM jobs GROUP BY status").fetch_all(pool).await?;
    Ok(rows.into_iter().map(|r| (r.status, r.n)).collect())
}
