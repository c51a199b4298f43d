//! `/api/v1/experiments`: store an experiment (client), list them (client), read one (client and
//! worker).

use axum::Json;
use axum::extract::State;
use axum::http::StatusCode;
use cryofit_api as api;

use super::error::{ApiError, ApiResult};
use super::extract::{Id, JsonBody, QueryParams, page, page_bounds};
use crate::db;
use crate::state::AppState;
use crate::validate;

#[utoipa::path(post, tag = "routes", path = "/experiments", request_body = api::CreateExperiment,
    responses((status = 201, body = api::Created), (status = 422, body = api::ErrorBody)))]
pub(crate) async fn create_experiment(
    State(state): State<AppState>,
    JsonBody(req): JsonBody<api::CreateExperiment>,
) -> ApiResult<(StatusCode, Json<api::Created>)> {
    let fluids = state.settings.fluids.clone();
    let limits = state.settings.limits;
    let (req, fluid) = tokio::task::spawn_blocking(move || {
        let f = validate::experiment(&req, &fluids, &limits);
        (req, f)
    })
    .await
    .map_err(|e| ApiError::internal(format!("validation task: {e}")))?;
    let fluid = fluid?;
    let mut tx = state.coordinator.db().begin().await?;
    let id = db::insert_experiment(&mut tx, &req.name, &fluid, &req.case, &req.data).await?;
    state.coordinator.db().commit(tx).await?;
    tracing::info!(experiment = id, "experiment stored");
    Ok((StatusCode::CREATED, Json(api::Created { id })))
}

#[utoipa::path(get, tag = "routes", path = "/experiments", params(api::PageQuery),
    responses((status = 200, body = api::Page<api::ExperimentSummary>)))]
pub(crate) async fn list_experiments(
    State(state): State<AppState>,
    QueryParams(q): QueryParams<api::PageQuery>,
) -> ApiResult<Json<api::Page<api::ExperimentSummary>>> {
    let (limit, offset) = page_bounds(&q)?;
    let items = db::experiments(state.coordinator.db().reader(), limit, offset).await?;
    Ok(Json(page(items, limit, offset)))
}

#[utoipa::path(get, tag = "routes", path = "/experiments/{id}", params(("id" = i64, Path)),
    responses((status = 200, body = api::Experiment), (status = 404, body = api::ErrorBody)))]
pub(crate) async fn get_experiment(State(state): State<AppState>, Id(id): Id) -> ApiResult<Json<api::Experiment>> {
    Ok(Json(db::experiment(state.coordinator.db().reader(), id).await?))
}
