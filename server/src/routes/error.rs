//! The error answer of every route: a status and `{"error": {"code", "message", "field"?}}`.

use axum::Json;
use axum::extract::Request;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use cryofit_api as api;

use crate::coordinator::CoordError;
use crate::db::DbError;
use crate::invalid::Invalid;

/// An error response: status and `{"error": {"code", "message", "field"?}}`.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    code: &'static str,
    message: String,
    field: Option<String>,
}

impl ApiError {
    pub(crate) fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> Self {
        Self { status, code, message: message.into(), field: None }
    }

    /// The status and message (the dashboard shows them as a page).
    pub(crate) fn parts(&self) -> (StatusCode, &str) {
        (self.status, &self.message)
    }

    pub(crate) fn field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    pub(crate) fn maybe_field(mut self, field: Option<String>) -> Self {
        self.field = field;
        self
    }

    pub(crate) fn bad_request(message: impl Into<String>) -> Self {
        Self::new(StatusCode::BAD_REQUEST, "bad_request", message)
    }

    pub(crate) fn validation(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "validation", message).field(field)
    }

    pub(crate) fn internal(message: impl Into<String>) -> Self {
        Self::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", message)
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
        Self::new(StatusCode::UNPROCESSABLE_ENTITY, "validation", e.message).maybe_field(e.field)
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
                Self::internal(format!("storage error: {other}"))
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
                Self::internal(other.to_string())
            }
        }
    }
}

/// What a route answers.
pub(crate) type ApiResult<T> = Result<T, ApiError>;

/// The answer to a path no route serves.
pub(crate) async fn not_found(req: Request) -> ApiError {
    ApiError::new(StatusCode::NOT_FOUND, "not_found", format!("no route {} {}", req.method(), req.uri().path()))
}

/// The answer to a method the path's route does not serve.
pub(crate) async fn method_not_allowed(req: Request) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        format!("{} is not allowed on {}", req.method(), req.uri().path()),
    )
}
