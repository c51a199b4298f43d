//! HTTP routes: extraction, authentication, validation, and the mapping of errors to statuses.
//!
//! Request bodies are read by [`JsonBody`] only after the authentication middleware accepted the
//! token and role, and never beyond the body limit.

use std::fmt::Write as _;

use axum::extract::{FromRequest, FromRequestParts, MatchedPath, Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header, request::Parts};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use cryofit_api as api;
use serde::de::DeserializeOwned;
use tower_http::set_header::SetResponseHeaderLayer;

use crate::AppState;
use crate::coordinator::{CoordError, NewCalibration, Report};
use crate::db::{self, DbError};
use crate::validate::{self, Invalid};

// ---------------------------------------------------------------------------------------------
// errors

/// An error response: status and `{"error": {"code", "message", "field"?}}`.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    code: &'static str,
    message: String,
    field: Option<String>,
}

impl ApiError {
    fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self { status, code, message: message.into(), field: None }
    }

    /// The status and message (the dashboard shows them as a page).
    pub(crate) fn parts(&self) -> (StatusCode, &str) {
        (self.status, &self.message)
    }

    fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    fn bad_request(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "bad_request", message)
    }

    fn validation(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "validation", message).field(field)
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = api::ErrorBody {
            error: api::ErrorDetail { code: self.code.to_string(), message: self.message, field: self.field },
        };
        (self.status, Json(body)).into_response()
    }
}

impl From<Invalid> for ApiError {
    fn from(e: Invalid) -> Self {
        let mut a = Self::new(StatusCode::UNPROCESSABLE_ENTITY, "validation", e.message);
        a.field = e.field;
        a
    }
}

impl From<DbError> for ApiError {
    fn from(e: DbError) -> Self {
        match e {
            DbError::NotFound { what, id } => {
                Self::new(StatusCode::NOT_FOUND, "not_found", format!("{what} {id} does not exist"))
            }
            other => {
                tracing::error!(error = %other, "storage error");
                Self::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", format!("storage error: {other}"))
            }
        }
    }
}

impl From<CoordError> for ApiError {
    fn from(e: CoordError) -> Self {
        match e {
            CoordError::Db(d) => d.into(),
            CoordError::Conflict(m) => Self::new(StatusCode::CONFLICT, "conflict", m),
            CoordError::Invalid { field, message } => Self::validation(field, message),
            other => {
                tracing::error!(error = %other, "coordinator error");
                Self::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", other.to_string())
            }
        }
    }
}

type ApiResult<T> = Result<T, ApiError>;

// ---------------------------------------------------------------------------------------------
// extractors

/// A JSON body read up to the body limit; errors name the field (`stages[0].budget`).
#[derive(Debug)]
pub struct JsonBody<T>(pub T);

impl<T: DeserializeOwned> FromRequest<AppState> for JsonBody<T> {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, ApiError> {
        let limit = state.settings.body_limit;
        if let Some(len) = req.headers().get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok())
            && let Ok(len) = len.parse::<u64>()
            && len > limit as u64
        {
            return Err(ApiError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                "payload_too_large",
                format!("the body ({len} bytes) exceeds the limit of {limit} bytes"),
            ));
        }
        let bytes = axum::body::to_bytes(req.into_body(), limit).await.map_err(|e| {
            let mut src: Option<&(dyn std::error::Error + 'static)> = Some(&e);
            while let Some(s) = src {
                if s.is::<http_body_util::LengthLimitError>() {
                    return ApiError::new(
                        StatusCode::PAYLOAD_TOO_LARGE,
                        "payload_too_large",
                        format!("the body exceeds the limit of {limit} bytes"),
                    );
                }
                src = s.source();
            }
            ApiError::bad_request(format!("cannot read the body: {e}"))
        })?;
        let mut de = serde_json::Deserializer::from_slice(&bytes);
        let value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            let field = (path != "." && !path.is_empty()).then_some(path);
            let status = if inner.is_data() { StatusCode::UNPROCESSABLE_ENTITY } else { StatusCode::BAD_REQUEST };
            let code = if inner.is_data() { "validation" } else { "invalid_json" };
            let message = match (&field, inner.is_data()) {
                (Some(f), true) => format!("{f}: {inner}"),
                (Some(f), false) => format!("malformed JSON (at {f}): {inner}"),
                (None, _) => format!("malformed JSON: {inner}"),
            };
            ApiError { status, code, message, field }
        })?;
        de.end().map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, "invalid_json", format!("malformed JSON: {e}")))?;
        Ok(Self(value))
    }
}

/// Query parameters with JSON errors.
#[derive(Debug)]
pub struct QueryParams<T>(pub T);

impl<T: DeserializeOwned, S: Send + Sync> FromRequestParts<S> for QueryParams<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        axum::extract::Query::<T>::from_request_parts(parts, state)
            .await
            .map(|q| Self(q.0))
            .map_err(|e| ApiError::bad_request(format!("query: {}", e.body_text())).field("query"))
    }
}

/// An id in the path with a JSON error.
#[derive(Debug)]
pub struct Id(pub i64);

impl<S: Send + Sync> FromRequestParts<S> for Id {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        axum::extract::Path::<i64>::from_request_parts(parts, state)
            .await
            .map(|p| Self(p.0))
            .map_err(|e| ApiError::bad_request(format!("id: {}", e.body_text())).field("id"))
    }
}

// ---------------------------------------------------------------------------------------------
// auth

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Client,
    Worker,
}

/// The roles a route accepts (by matched path and method).
fn roles(method: &Method, path: &str) -> &'static [Role] {
    let path = path.strip_prefix("/api/v1").unwrap_or(path);
    if path.starts_with("/jobs") {
        &[Role::Worker]
    } else if (path == "/experiments/{id}" && method == Method::GET) || path == "/openapi.json" {
        &[Role::Client, Role::Worker]
    } else {
        &[Role::Client]
    }
}

/// Bearer-token check, before any body is read: 401 without a valid token, 403 with a token of
/// the wrong role. Without configured tokens (loopback only) everything is allowed.
async fn auth(State(state): State<AppState>, req: Request, next: Next) -> Response {
    let s = &state.settings;
    if s.client_token.is_none() && s.worker_token.is_none() {
        return next.run(req).await;
    }
    let token = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer ").or_else(|| v.strip_prefix("bearer ")))
        .map(str::trim);
    let Some(token) = token else {
        return ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "missing bearer token: send `Authorization: Bearer <token>` (CRYOFIT_TOKEN)",
        )
        .into_response();
    };
    let mut held = Vec::new();
    if s.client_token.as_ref().is_some_and(|t| t.matches(token)) {
        held.push(Role::Client);
    }
    if s.worker_token.as_ref().is_some_and(|t| t.matches(token)) {
        held.push(Role::Worker);
    }
    if held.is_empty() {
        return ApiError::new(StatusCode::UNAUTHORIZED, "unauthorized", "the bearer token is not valid")
            .into_response();
    }
    let path =
        req.extensions().get::<MatchedPath>().map_or_else(|| req.uri().path().to_string(), |m| m.as_str().into());
    let needed = roles(req.method(), &path);
    if !held.iter().any(|r| needed.contains(r)) {
        let want = if needed.contains(&Role::Worker) { "a worker token" } else { "a client token" };
        return ApiError::new(
            StatusCode::FORBIDDEN,
            "forbidden",
            format!("{} {path} needs {want}; this token's role may not use it", req.method()),
        )
        .into_response();
    }
    next.run(req).await
}

// ---------------------------------------------------------------------------------------------
// router

/// The full router: `/healthz`, `/metrics`, the dashboard (`/` and its pages) and everything under
/// `/api/v1`.
pub fn router(state: AppState) -> Router {
    let v1 = Router::new()
        .route("/experiments", post(create_experiment).get(list_experiments))
        .route("/experiments/{id}", get(get_experiment))
        .route("/calibrations", post(create_calibration).get(list_calibrations))
        .route("/calibrations/{id}", get(get_calibration))
        .route("/calibrations/{id}/cancel", post(cancel_calibration))
        .route("/calibrations/{id}/parameter-sets", get(parameter_sets))
        .route("/calibrations/{id}/results", get(results))
        .route("/jobs/claim", post(claim))
        .route("/jobs/{id}/heartbeat", post(heartbeat))
        .route("/jobs/{id}/result", post(result))
        .route("/jobs/results", post(results_batch))
        .route("/openapi.json", get(openapi))
        .layer(middleware::from_fn_with_state(state.clone(), auth));
    let app = Router::new()
        .route("/healthz", get(healthz))
        .route("/metrics", get(metrics))
        .nest("/api/v1", v1)
        .merge(crate::dashboard::router(state.clone()))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed);
    with_security_headers(app).layer(crate::telemetry::http_trace()).with_state(state)
}

/// The Content-Security-Policy of every answer: the dashboard's own script and style sheet
/// only, inline SVG figures, no framing, forms posting only to this origin.
pub const CONTENT_SECURITY_POLICY: &str = "default-src 'none'; script-src 'self'; style-src 'self' 'unsafe-inline'; \
     img-src 'self' data:; connect-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'";

/// Security headers on every answer (dashboard pages, API, errors): CSP, no framing, no MIME
/// sniffing, no referrer.
fn with_security_headers(r: Router<AppState>) -> Router<AppState> {
    let set = |name, value: &'static str| SetResponseHeaderLayer::overriding(name, HeaderValue::from_static(value));
    r.layer(set(header::CONTENT_SECURITY_POLICY, CONTENT_SECURITY_POLICY))
        .layer(set(header::X_FRAME_OPTIONS, "DENY"))
        .layer(set(header::X_CONTENT_TYPE_OPTIONS, "nosniff"))
        .layer(set(header::REFERRER_POLICY, "no-referrer"))
}

async fn not_found(req: Request) -> ApiError {
    ApiError::new(StatusCode::NOT_FOUND, "not_found", format!("no route {} {}", req.method(), req.uri().path()))
}

async fn method_not_allowed(req: Request) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        format!("{} is not allowed on {}", req.method(), req.uri().path()),
    )
}

/// Healthy when the database can be written: the answer renews the coordinator's database lock,
/// a real write. 503 with the reason otherwise (a full disk, a file turned read-only, the lock
/// lost to another coordinator).
#[utoipa::path(get, path = "/healthz",
    responses((status = 200, body = api::Health), (status = 503, body = api::Health)))]
async fn healthz(State(state): State<AppState>) -> (StatusCode, Json<api::Health>) {
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

async fn metrics(State(state): State<AppState>) -> ApiResult<Response> {
    let counts = db::job_counts(state.coordinator.db().reader()).await?;
    let text = state.metrics.render(&counts);
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response())
}

async fn openapi(State(state): State<AppState>) -> Response {
    Json(crate::openapi::document(&state.settings.limits)).into_response()
}

// ---------------------------------------------------------------------------------------------
// experiments

#[utoipa::path(post, path = "/api/v1/experiments", request_body = api::CreateExperiment,
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
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", format!("validation task: {e}")))?;
    let fluid = fluid?;
    let mut tx = state.coordinator.db().begin().await?;
    let id = db::insert_experiment(&mut tx, &req.name, &fluid, &req.case, &req.data).await?;
    state.coordinator.db().commit(tx).await?;
    tracing::info!(experiment = id, "experiment stored");
    Ok((StatusCode::CREATED, Json(api::Created { id })))
}

fn page_bounds(q: &api::PageQuery) -> ApiResult<(i64, i64)> {
    let limit = q.limit.unwrap_or(api::DEFAULT_PAGE).clamp(1, api::MAX_PAGE);
    let offset = q.offset.unwrap_or(0);
    if offset < 0 {
        return Err(ApiError::bad_request(format!("offset = {offset}: must be ≥ 0")).field("offset"));
    }
    Ok((limit, offset))
}

fn page<T>(items: Vec<T>, limit: i64, offset: i64) -> api::Page<T> {
    let next_offset = (items.len() as i64 == limit).then_some(offset + limit);
    api::Page { items, next_offset }
}

#[utoipa::path(get, path = "/api/v1/experiments", params(api::PageQuery),
    responses((status = 200, body = api::Page<api::ExperimentSummary>)))]
pub(crate) async fn list_experiments(
    State(state): State<AppState>,
    QueryParams(q): QueryParams<api::PageQuery>,
) -> ApiResult<Json<api::Page<api::ExperimentSummary>>> {
    let (limit, offset) = page_bounds(&q)?;
    let items = db::experiments(state.coordinator.db().reader(), limit, offset).await?;
    Ok(Json(page(items, limit, offset)))
}

#[utoipa::path(get, path = "/api/v1/experiments/{id}", params(("id" = i64, Path)),
    responses((status = 200, body = api::Experiment), (status = 404, body = api::ErrorBody)))]
pub(crate) async fn get_experiment(State(state): State<AppState>, Id(id): Id) -> ApiResult<Json<api::Experiment>> {
    Ok(Json(db::experiment(state.coordinator.db().reader(), id).await?))
}

// ---------------------------------------------------------------------------------------------
// calibrations

#[utoipa::path(post, path = "/api/v1/calibrations", request_body = api::CreateCalibration,
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
    .map_err(|e| ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", format!("validation task: {e}")))?;
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

#[utoipa::path(get, path = "/api/v1/calibrations", params(api::PageQuery),
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

#[utoipa::path(get, path = "/api/v1/calibrations/{id}", params(("id" = i64, Path)),
    responses((status = 200, body = api::Calibration), (status = 404, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(calibration = id))]
pub(crate) async fn get_calibration(State(state): State<AppState>, Id(id): Id) -> ApiResult<Json<api::Calibration>> {
    Ok(Json(calibration_view(db::calibration(state.coordinator.db().reader(), id).await?)?))
}

#[utoipa::path(post, path = "/api/v1/calibrations/{id}/cancel", params(("id" = i64, Path)),
    responses((status = 200, body = api::Calibration), (status = 404, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(calibration = id))]
pub(crate) async fn cancel_calibration(State(state): State<AppState>, Id(id): Id) -> ApiResult<Json<api::Calibration>> {
    state.coordinator.cancel(id).await?;
    Ok(Json(calibration_view(db::calibration(state.coordinator.db().reader(), id).await?)?))
}

fn wants_csv(headers: &HeaderMap) -> bool {
    headers.get(header::ACCEPT).and_then(|v| v.to_str().ok()).is_some_and(|v| v.contains("text/csv"))
}

pub(crate) fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() }
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(String::new, |x| x.to_string())
}

/// Parameter sets as CSV: `id,job,stage,status,cost,reason` and a column per parameter.
pub(crate) fn parameter_sets_csv(items: &[api::ParameterSetItem]) -> String {
    let names: Vec<String> = items
        .iter()
        .flat_map(|i| i.parameters.keys().cloned())
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let mut s = String::from("id,job,stage,status,cost,reason");
    for n in &names {
        let _ = write!(s, ",{}", csv_field(n));
    }
    s.push('\n');
    for i in items {
        let _ = write!(
            s,
            "{},{},{},{},{},{}",
            i.id,
            i.job,
            i.stage,
            i.status,
            opt(i.cost),
            csv_field(i.reason.as_deref().unwrap_or(""))
        );
        for n in &names {
            let _ = write!(s, ",{}", opt(i.parameters.get(n)));
        }
        s.push('\n');
    }
    s
}

/// Results as CSV.
pub(crate) fn results_csv(items: &[api::ResultItem]) -> String {
    let mut s = String::from("id,parameter_set_id,job_id,experiment_id,status,cost,reason,worker,duration_s\n");
    for i in items {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{}",
            i.id,
            i.parameter_set_id,
            i.job_id,
            i.experiment_id,
            i.status,
            opt(i.cost),
            csv_field(i.reason.as_deref().unwrap_or("")),
            csv_field(i.worker.as_deref().unwrap_or("")),
            opt(i.duration_s)
        );
    }
    s
}

pub(crate) fn csv_response(text: String) -> Response {
    ([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], text).into_response()
}

#[utoipa::path(get, path = "/api/v1/calibrations/{id}/parameter-sets", params(("id" = i64, Path), api::PageQuery),
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
    if wants_csv(&headers) {
        return Ok(csv_response(parameter_sets_csv(&items)));
    }
    Ok(Json(page(items, limit, offset)).into_response())
}

#[utoipa::path(get, path = "/api/v1/calibrations/{id}/results", params(("id" = i64, Path), api::PageQuery),
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
    if wants_csv(&headers) {
        return Ok(csv_response(results_csv(&items)));
    }
    Ok(Json(page(items, limit, offset)).into_response())
}

// ---------------------------------------------------------------------------------------------
// workers

#[utoipa::path(post, path = "/api/v1/jobs/claim", request_body = api::ClaimRequest,
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

#[utoipa::path(post, path = "/api/v1/jobs/{id}/heartbeat", params(("id" = i64, Path)),
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

#[utoipa::path(post, path = "/api/v1/jobs/{id}/result", params(("id" = i64, Path)),
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

#[utoipa::path(post, path = "/api/v1/jobs/results", request_body = api::ResultBatch,
    responses((status = 200, body = api::ResultBatchResponse), (status = 422, body = api::ErrorBody)))]
#[tracing::instrument(skip_all, fields(results = req.results.len()))]
pub(crate) async fn results_batch(
    State(state): State<AppState>,
    JsonBody(req): JsonBody<api::ResultBatch>,
) -> ApiResult<Json<api::ResultBatchResponse>> {
    let reports: Vec<Report<'_>> = req.results.iter().map(Report::batched).collect();
    Ok(Json(api::ResultBatchResponse { results: state.coordinator.results(&reports).await? }))
}
