//! The `experiments` table: a case and its measured data, stored once and shared by calibrations.

use cryofit_api as api;
use sqlx::{SqliteConnection, SqlitePool};

use super::{DbError, now_ms};

/// An `experiments` row with its texts.
#[derive(Debug, sqlx::FromRow)]
struct ExperimentRow {
    id: i64,
    name: String,
    fluid: String,
    case_text: String,
    data_text: String,
    created: i64,
}

impl From<ExperimentRow> for api::Experiment {
    fn from(r: ExperimentRow) -> Self {
        Self { id: r.id, name: r.name, fluid: r.fluid, case: r.case_text, data: r.data_text, created: r.created }
    }
}

/// An `experiments` row without its texts.
#[derive(Debug, sqlx::FromRow)]
struct SummaryRow {
    id: i64,
    name: String,
    fluid: String,
    created: i64,
}

impl From<SummaryRow> for api::ExperimentSummary {
    fn from(r: SummaryRow) -> Self {
        Self { id: r.id, name: r.name, fluid: r.fluid, created: r.created }
    }
}

/// Stores an experiment; returns its id.
pub async fn insert_experiment(
    tx: &mut SqliteConnection,
    name: &str,
    fluid: &str,
    case_text: &str,
    data_text: &str,
) -> Result<i64, DbError> {
    let id = sqlx::query_scalar(
        "INSERT INTO experiments (name, fluid, case_text, data_text, created) VALUES (?, ?, ?, ?, ?) RETURNING id",
    )
    .bind(name)
    .bind(fluid)
    .bind(case_text)
    .bind(data_text)
    .bind(now_ms())
    .fetch_one(tx)
    .await?;
    Ok(id)
}

/// An experiment with its texts.
pub async fn experiment(pool: &SqlitePool, id: i64) -> Result<api::Experiment, DbError> {
    let row: ExperimentRow =
        sqlx::query_as("SELECT id, name, fluid, case_text, data_text, created FROM experiments WHERE id = ?")
            .bind(id)
            .fetch_optional(pool)
            .await?
            .ok_or(DbError::NotFound { what: "experiment", id })?;
    Ok(row.into())
}

/// A page of experiments, newest last.
pub async fn experiments(pool: &SqlitePool, limit: i64, offset: i64) -> Result<Vec<api::ExperimentSummary>, DbError> {
    let rows: Vec<SummaryRow> =
        sqlx::query_as("SELECT id, name, fluid, created FROM experiments ORDER BY id LIMIT ? OFFSET ?")
            .bind(limit)
            .bind(offset)
            .fetch_all(pool)
            .await?;
    Ok(rows.into_iter().map(Into::into).collect())
}
