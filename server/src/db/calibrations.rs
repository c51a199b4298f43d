//! The `calibrations` table: a calibration's request, status, progress and optimiser state.

use sqlx::{SqliteConnection, SqlitePool};

use super::{DbError, now_ms};

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
    let id = sqlx::query_scalar(
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
    Ok(id)
}

/// A stored calibration, columns as stored.
#[derive(Debug, Clone, sqlx::FromRow)]
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

/// One calibration.
pub async fn calibration(pool: &SqlitePool, id: i64) -> Result<CalibrationRow, DbError> {
    let row = sqlx::query_as(&format!("SELECT {CALIBRATION_COLUMNS} FROM calibrations WHERE id = ?"))
        .bind(id)
        .fetch_optional(pool)
        .await?
        .ok_or(DbError::NotFound { what: "calibration", id })?;
    Ok(row)
}

/// A page of calibrations.
pub async fn calibrations(
    pool: &SqlitePool,
    status: Option<&str>,
    limit: i64,
    offset: i64,
) -> Result<Vec<CalibrationRow>, DbError> {
    let rows = sqlx::query_as(&format!(
        "SELECT {CALIBRATION_COLUMNS} FROM calibrations WHERE (?1 IS NULL OR status = ?1) ORDER BY id LIMIT ?2 OFFSET ?3"
    ))
    .bind(status)
    .bind(limit)
    .bind(offset)
    .fetch_all(pool)
    .await?;
    Ok(rows)
}

/// A running calibration's id and optimiser state.
#[derive(Debug, Clone, sqlx::FromRow)]
pub struct RunningState {
    /// The calibration.
    pub id: i64,
    /// Its serialised pipeline.
    pub pipeline_state_json: String,
}

/// Running calibrations with their pipeline state, for a restart.
pub async fn running_states(pool: &SqlitePool) -> Result<Vec<RunningState>, DbError> {
    let rows = sqlx::query_as("SELECT id, pipeline_state_json FROM calibrations WHERE status = 'running' ORDER BY id")
        .fetch_all(pool)
        .await?;
    Ok(rows)
}

/// A calibration's status inside a transaction.
pub async fn calibration_status(tx: &mut SqliteConnection, id: i64) -> Result<String, DbError> {
    let status = sqlx::query_scalar("SELECT status FROM calibrations WHERE id = ?")
        .bind(id)
        .fetch_optional(tx)
        .await?
        .ok_or(DbError::NotFound { what: "calibration", id })?;
    Ok(status)
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
