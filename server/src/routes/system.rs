//! The operational routes outside `/api/v1`, open without a token: `/healthz` and `/metrics`.

use axum::Json;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use cryofit_api as api;

use super::error::ApiResult;
use crate::db;
use crate::state::AppState;

/// Healthy when the database can be written: the answer renews the coordinator's database lock,
/// a real write. 503 with the reason otherwise (a full disk, a file turned read-only, the lock
/// lost to another coordinator).
pub(crate) async fn healthz(State(state): State<AppState>) -> (StatusCode, Json<api::Health>) {
    let version = env!("CARGO_PKG_VERSION").to_string();
    match state.lock.renew(state.coordinator.db()).await {
        Ok(()) => (StatusCode::OK, Json(api::Health { status: "ok".into(), version, reason: None })),
        Err(reason) => {
            tracing::error!(%reason, "unhealthy");
            (
                StatusCode::SERVICE_UNAVAILABLE,
                Json(api::Health { status: "unhealthy".into(), version, reason: Some(reason) }),
            )
        }
    }
}

/// The Prometheus metrics, with the job counts of the database.
pub(crate) async fn metrics(State(state): State<AppState>) -> ApiResult<Response> {
    let counts = db::job_counts(state.coordinator.db().reader()).await?;
    let text = state.metrics.render(&counts);
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response())
}
