//! A calibration's history as the API pages it: its parameter sets and its results.

use std::collections::BTreeMap;

use cryofit_api as api;
use sqlx::SqlitePool;

use super::DbError;

/// A `parameter_sets` row.
#[derive(Debug, sqlx::FromRow)]
struct ParameterSetRow {
    id: i64,
    calibration_id: i64,
    job: i64,
    stage: i64,
    parameters_json: String,
    status: String,
    cost: Option<f64>,
    reason: Option<String>,
    created: i64,
}

impl ParameterSetRow {
    fn into_item(self) -> Result<api::ParameterSetItem, DbError> {
        let parameters: BTreeMap<String, f64> = serde_json::from_str(&self.parameters_json)
            .map_err(|e| DbError::Corrupt(format!("parameter set parameters: {e}")))?;
        Ok(api::ParameterSetItem {
            id: self.id,
            calibration_id: self.calibration_id,
            job: self.job,
            stage: self.stage,
            parameters,
            status: self.status,
            cost: self.cost,
            reason: self.reason,
            created: self.created,
        })
    }
}

/// A `cost_results` row.
#[derive(Debug, sqlx::FromRow)]
struct ResultRow {
    id: i64,
    parameter_set_id: i64,
    job_id: i64,
    experiment_id: i64,
    status: String,
    cost: Option<f64>,
    reason: Option<String>,
    worker: Option<String>,
    duration: Option<f64>,
    breakdown_json: Option<String>,
    created: i64,
}

impl ResultRow {
    fn into_item(self) -> Result<api::ResultItem, DbError> {
        let breakdown = self
            .breakdown_json
            .map(|b| serde_json::from_str(&b))
            .transpose()
            .map_err(|e| DbError::Corrupt(format!("result breakdown: {e}")))?;
        Ok(api::ResultItem {
            id: self.id,
            parameter_set_id: self.parameter_set_id,
            job_id: self.job_id,
            experiment_id: self.experiment_id,
            status: self.status,
            cost: self.cost,
            reason: self.reason,
            worker: self.worker,
            duration_s: self.duration,
            breakdown,
            created: self.created,
        })
    }
}

/// A page of a calibration's parameter sets, in the order they were asked.
pub async fn parameter_sets_page(
    pool: &SqlitePool,
    calibration_id: i64,
    status: Option<&str>,
    stage: Option<i64>,
    limit: i64,
    offset: i64,
) -> Result<Vec<api::ParameterSetItem>, DbError> {
    let rows: Vec<ParameterSetRow> = sqlx::query_as(
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
    rows.into_iter().map(ParameterSetRow::into_item).collect()
}

/// A page of a calibration's results, in the order they arrived.
pub async fn results_page(
    pool: &SqlitePool,
    calibration_id: i64,
    status: Option<&str>,
    experiment_id: Option<i64>,
    limit: i64,
    offset: i64,
) -> Result<Vec<api::ResultItem>, DbError> {
    let rows: Vec<ResultRow> = sqlx::query_as(
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
    rows.into_iter().map(ResultRow::into_item).collect()
}

/// Every parameter set of a calibration, in the order they were asked (page by page).
pub async fn all_parameter_sets(pool: &SqlitePool, calibration_id: i64) -> Result<Vec<api::ParameterSetItem>, DbError> {
    let mut all = Vec::new();
    loop {
        let page = parameter_sets_page(pool, calibration_id, None, None, api::MAX_PAGE, all.len() as i64).await?;
        let n = page.len();
        all.extend(page);
        if (n as i64) < api::MAX_PAGE {
            return Ok(all);
        }
    }
}

/// Every result of a calibration, in the order they arrived (page by page).
pub async fn all_results(pool: &SqlitePool, calibration_id: i64) -> Result<Vec<api::ResultItem>, DbError> {
    let mut all = Vec::new();
    loop {
        let page = results_page(pool, calibration_id, None, None, api::MAX_PAGE, all.len() as i64).await?;
        let n = page.len();
        all.extend(page);
        if (n as i64) < api::MAX_PAGE {
            return Ok(all);
        }
    }
}
