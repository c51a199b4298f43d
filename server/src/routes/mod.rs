//! The HTTP routes, by resource: [`experiments`], [`calibrations`] and [`jobs`] under `/api/v1`,
//! `/healthz` and `/metrics` ([`system`]); [`error`] is the error answer, [`extract`] the
//! extractors, [`csv`] the CSV answers, [`openapi`] the document's frame.
//!
//! Each route is declared once, by its handler's `#[utoipa::path]` (method and path): `routes!`
//! adds the route to the router and its entry to the OpenAPI document together. (Every operation
//! keeps the tag `routes` it has always had in the document.) Routes are
//! grouped by the role that may use them, and each group carries its role check
//! ([`auth`]); bearer tokens are checked for everything under `/api/v1` before a body is read.

mod auth;
mod calibrations;
pub(crate) mod csv;
pub(crate) mod error;
mod experiments;
mod extract;
mod jobs;
mod openapi;
mod system;

use std::sync::Arc;

use axum::routing::get;
use axum::{Json, Router, middleware};
use cryofit_api as api;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

pub(crate) use calibrations::calibration_view;

use crate::state::AppState;

/// The documented routes of `/api/v1` (paths relative to it), by role group.
fn api_routes() -> OpenApiRouter<AppState> {
    let client = OpenApiRouter::new()
        .routes(routes!(experiments::create_experiment, experiments::list_experiments))
        .routes(routes!(calibrations::create_calibration, calibrations::list_calibrations))
        .routes(routes!(calibrations::get_calibration))
        .routes(routes!(calibrations::cancel_calibration))
        .routes(routes!(calibrations::parameter_sets))
        .routes(routes!(calibrations::results))
        .route_layer(middleware::from_fn(auth::client));
    let worker = OpenApiRouter::new()
        .routes(routes!(jobs::claim))
        .routes(routes!(jobs::heartbeat))
        .routes(routes!(jobs::result))
        .routes(routes!(jobs::results_batch))
        .route_layer(middleware::from_fn(auth::worker));
    let both = OpenApiRouter::new()
        .routes(routes!(experiments::get_experiment))
        .route_layer(middleware::from_fn(auth::any_role));
    client.merge(worker).merge(both)
}

/// The OpenAPI document of a coordinator with these limits.
pub(crate) fn document(limits: &api::Limits) -> utoipa::openapi::OpenApi {
    let doc = OpenApiRouter::<AppState>::with_openapi(openapi::frame()).nest("/api/v1", api_routes()).into_openapi();
    openapi::with_limits(doc, limits)
}

/// `/healthz`, `/metrics` and everything under `/api/v1`: the documented routes and the document
/// itself (`/api/v1/openapi.json`, for both roles).
pub(crate) fn router(state: &AppState) -> Router<AppState> {
    let doc = Arc::new(document(&state.settings.limits));
    let document = Router::new()
        .route("/openapi.json", get(move || std::future::ready(Json(doc.as_ref().clone()))))
        .route_layer(middleware::from_fn(auth::any_role));
    let v1 = Router::from(api_routes())
        .merge(document)
        .layer(middleware::from_fn_with_state(state.clone(), auth::authenticate));
    Router::new().route("/healthz", get(system::healthz)).route("/metrics", get(system::metrics)).nest("/api/v1", v1)
}

#[cfg(test)]
mod tests;
