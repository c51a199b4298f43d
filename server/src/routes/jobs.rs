//! `/api/v1/jobs` (worker): claim jobs, extend their leases, report results one by one or in
//! batches.

use axum::Json;
use axum::extract::State;
use cryofit_api as api;

use super::error::{ApiError, ApiResult};
use super::extract::{Id, JsonBody};
use crate::coordinator::Report;
use crate::state::AppState;

#[utoipa::path(post, tag = "routes", path = "/jobs/claim", request_body = api::ClaimRequest,
    responses((status = 200, body = api::ClaimResponse)))]
#[tracing::instrument(skip_all, fields(worker = %req.worker))]
pub(crate) async fn claim(
    State(state): State<AppState>,
    JsonBody(req): JsonBody<api::ClaimRequest>,
) -> ApiResult<Json<api::ClaimResponse>> {
    if req.worker.trim().is_empty() || req.worker.chars().count() > 200 {
        return Err(ApiError::validation("worker", "give a name of 1–200 characters"));
    }
    if req.slots == 0 || req.slots > 4096 {
        return Err(ApiError::validation("slots", format!("{}: must be in 1..=4096", req.slots)));
    }
    if req.max_jobs > 1000 {
        return Err(ApiError::validation("max_jobs", format!("{}: must be at most 1000", req.max_jobs)));
    }
    Ok(Json(state.coordinator.claim(&req).await?))
}

#[utoipa::path(post, tag = "routes", path = "/jobs/{id}/heartbeat", params(("id" = i64, Path)),
    request_body = api::HeartbeatRequest,
    responses((status = 200, body = api::HeartbeatResponse), (status = 409, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(job = id))]
pub(crate) async fn heartbeat(
    State(state): State<AppState>,
    Id(id): Id,
    JsonBody(req): JsonBody<api::HeartbeatRequest>,
) -> ApiResult<Json<api::HeartbeatResponse>> {
    Ok(Json(state.coordinator.heartbeat(id, &req.lease_id).await?))
}

#[utoipa::path(post, tag = "routes", path = "/jobs/{id}/result", params(("id" = i64, Path)),
    request_body = api::ResultRequest,
    responses((status = 200, body = api::ResultResponse), (status = 404, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(job = id))]
pub(crate) async fn result(
    State(state): State<AppState>,
    Id(id): Id,
    JsonBody(req): JsonBody<api::ResultRequest>,
) -> ApiResult<Json<api::ResultResponse>> {
    Ok(Json(state.coordinator.result(id, &req).await?))
}

#[utoipa::path(post, tag = "routes", path = "/jobs/results", request_body = api::ResultBatch,
    responses((status = 200, body = api::ResultBatchResponse), (status = 422, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(results = req.results.len()))]
pub(crate) async fn results_batch(
    State(state): State<AppState>,
    JsonBody(req): JsonBody<api::ResultBatch>,
) -> ApiResult<Json<api::ResultBatchResponse>> {
    let reports: Vec<Report<'_>> = req.results.iter().map(Report::batched).collect();
    Ok(Json(api::ResultBatchResponse { results: state.coordinator.results(&reports).await? }))
}
