//! `/api/v1/calibrations` (client): submit, list, read and cancel a calibration, and page
//! through its parameter sets and results (JSON, or CSV with `Accept: text/csv`).

use axum::Json;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use cryofit_api as api;

use super::csv;
use super::error::{ApiError, ApiResult};
use super::extract::{Id, JsonBody, QueryParams, page, page_bounds};
use crate::coordinator::NewCalibration;
use crate::db::{self, DbError};
use crate::state::AppState;
use crate::validate;

#[utoipa::path(post, tag = "routes", path = "/calibrations", request_body = api::CreateCalibration,
    responses((status = 201, body = api::Created), (status = 422, body = api::ErrorBody)))]
pub(crate) async fn create_calibration(
    State(state): State<AppState>,
    JsonBody(req): JsonBody<api::CreateCalibration>,
) -> ApiResult<(StatusCode, Json<api::Created>)> {
    if req.experiments.is_empty() {
        return Err(ApiError::validation("experiments", "at least one experiment id is needed"));
    }
    let mut rows = Vec::with_capacity(req.experiments.len());
    for (k, &id) in req.experiments.iter().enumerate() {
        if req.experiments[..k].contains(&id) {
            return Err(ApiError::validation(format!("experiments[{k}]"), format!("experiment {id} is listed twice")));
        }
        match db::experiment(state.coordinator.db().reader(), id).await {
            Ok(e) => rows.push(e),
            Err(DbError::NotFound { .. }) => {
                return Err(ApiError::validation(
                    format!("experiments[{k}]"),
                    format!("experiment {id} does not exist; store it with POST /api/v1/experiments first"),
                ));
            }
            Err(e) => return Err(e.into()),
        }
    }
    let fluids = state.settings.fluids.clone();
    let limits = state.settings.limits;
    let (req, prepared) = tokio::task::spawn_blocking(move || {
        let p = validate::calibration(&req, &rows, &fluids, &limits);
        (req, p)
    })
    .await
    .map_err(|e| ApiError::internal(format!("validation task: {e}")))?;
    let prepared = prepared?;
    let id = state
        .coordinator
        .create(NewCalibration { request: req, pipeline: prepared.pipeline, fluid_hashes: prepared.fluid_hashes })
        .await?;
    Ok((StatusCode::CREATED, Json(api::Created { id })))
}

pub(crate) fn calibration_view(r: db::CalibrationRow) -> ApiResult<api::Calibration> {
    let corrupt =
        |what: &str, e: serde_json::Error| ApiError::from(DbError::Corrupt(format!("calibration {what}: {e}")));
    let status = api::CalibrationStatus::parse(&r.status)
        .ok_or_else(|| ApiError::from(DbError::Corrupt(format!("calibration status `{}`", r.status))))?;
    Ok(api::Calibration {
        id: r.id,
        name: r.name,
        status,
        evaluations: r.evaluations,
        failed_evaluations: r.failed_evaluations,
        budget: r.budget,
        stage: r.stage,
        best_cost: r.best_cost,
        best_parameters: r
            .best_parameters_json
            .map(|b| serde_json::from_str(&b))
            .transpose()
            .map_err(|e| corrupt("best parameters", e))?,
        experiments: serde_json::from_str(&r.experiment_ids_json).map_err(|e| corrupt("experiments", e))?,
        solver_version: r.solver_version,
        fluid_hashes: serde_json::from_str(&r.fluid_hashes).map_err(|e| corrupt("fluid hashes", e))?,
        error: r.error,
        spec: serde_json::from_str(&r.spec_json).map_err(|e| corrupt("spec", e))?,
        stages: serde_json::from_str(&r.reports_json).map_err(|e| corrupt("reports", e))?,
        created: r.created,
        updated: r.updated,
    })
}

#[utoipa::path(get, tag = "routes", path = "/calibrations", params(api::PageQuery),
    responses((status = 200, body = api::Page<api::Calibration>)))]
pub(crate) async fn list_calibrations(
    State(state): State<AppState>,
    QueryParams(q): QueryParams<api::PageQuery>,
) -> ApiResult<Json<api::Page<api::Calibration>>> {
    let (limit, offset) = page_bounds(&q)?;
    let rows = db::calibrations(state.coordinator.db().reader(), q.status.as_deref(), limit, offset).await?;
    let items = rows.into_iter().map(calibration_view).collect::<ApiResult<Vec<_>>>()?;
    Ok(Json(page(items, limit, offset)))
}

#[utoipa::path(get, tag = "routes", path = "/calibrations/{id}", params(("id" = i64, Path)),
    responses((status = 200, body = api::Calibration), (status = 404, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(calibration = id))]
pub(crate) async fn get_calibration(State(state): State<AppState>, Id(id): Id) -> ApiResult<Json<api::Calibration>> {
    Ok(Json(calibration_view(db::calibration(state.coordinator.db().reader(), id).await?)?))
}

#[utoipa::path(post, tag = "routes", path = "/calibrations/{id}/cancel", params(("id" = i64, Path)),
    responses((status = 200, body = api::Calibration), (status = 404, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(calibration = id))]
pub(crate) async fn cancel_calibration(State(state): State<AppState>, Id(id): Id) -> ApiResult<Json<api::Calibration>> {
    state.coordinator.cancel(id).await?;
    Ok(Json(calibration_view(db::calibration(state.coordinator.db().reader(), id).await?)?))
}

#[utoipa::path(get, tag = "routes", path = "/calibrations/{id}/parameter-sets", params(("id" = i64, Path), api::PageQuery),
    responses((status = 200, body = api::Page<api::ParameterSetItem>)))]
#[tracing::instrument(skip_all, fields(calibration = id))]
pub(crate) async fn parameter_sets(
    State(state): State<AppState>,
    Id(id): Id,
    headers: HeaderMap,
    QueryParams(q): QueryParams<api::PageQuery>,
) -> ApiResult<Response> {
    let (limit, offset) = page_bounds(&q)?;
    let pool = state.coordinator.db().reader();
    db::calibration(pool, id).await?;
    let items = db::parameter_sets_page(pool, id, q.status.as_deref(), q.stage, limit, offset).await?;
    if csv::wanted(&headers) {
        return Ok(csv::response(csv::parameter_sets(&items)?));
    }
    Ok(Json(page(items, limit, offset)).into_response())
}

#[utoipa::path(get, tag = "routes", path = "/calibrations/{id}/results", params(("id" = i64, Path), api::PageQuery),
    responses((status = 200, body = api::Page<api::ResultItem>)))]
#[tracing::instrument(skip_all, fields(calibration = id))]
pub(crate) async fn results(
    State(state): State<AppState>,
    Id(id): Id,
    headers: HeaderMap,
    QueryParams(q): QueryParams<api::PageQuery>,
) -> ApiResult<Response> {
    let (limit, offset) = page_bounds(&q)?;
    let pool = state.coordinator.db().reader();
    db::calibration(pool, id).await?;
    let items = db::results_page(pool, id, q.status.as_deref(), q.experiment_id, limit, offset).await?;
    if csv::wanted(&headers) {
        return Ok(csv::response(csv::results(&items)?));
    }
    Ok(Json(page(items, limit, offset)).into_response())
}

// ---------------------------------------------------------------------------------------------
