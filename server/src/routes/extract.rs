//! Extractors whose rejections are [`ApiError`]s: a JSON body read up to the body limit, query
//! parameters, an id in the path; and the page bounds of the list routes.

use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::{StatusCode, header, request::Parts};
use cryofit_api as api;
use serde::de::DeserializeOwned;

use super::error::{ApiError, ApiResult};
use crate::state::AppState;

/// A JSON body read up to the body limit; errors name the field (`stages[0].budget`).
///
/// Bodies are read only after the authentication middleware accepted the token and role.
#[derive(Debug)]
pub struct JsonBody<T>(pub T);

fn too_large(message: String) -> ApiError {
    ApiError::new(StatusCode::PAYLOAD_TOO_LARGE, "payload_too_large", message)
}

impl<T: DeserializeOwned> FromRequest<AppState> for JsonBody<T> {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, ApiError> {
        let limit = state.settings.body_limit;
        if let Some(len) = req.headers().get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok())
            && let Ok(len) = len.parse::<u64>()
            && len > limit as u64
        {
            drain(req.into_body(), 0).await;
            return Err(too_large(format!("the body ({len} bytes) exceeds the limit of {limit} bytes")));
        }
        let bytes = read_limited(req.into_body(), limit).await?;
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
            ApiError::new(status, code, message).maybe_field(field)
        })?;
        de.end().map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, "invalid_json", format!("malformed JSON: {e}")))?;
        Ok(Self(value))
    }
}

/// How much of a body past the limit is read and dropped before the 413 goes out, bytes.
const DRAIN_BYTES: usize = 4 << 20;
/// How long that reading may take.
const DRAIN_TIME: std::time::Duration = std::time::Duration::from_secs(2);

/// Reads a body of up to `limit` bytes, refusing a longer one with a 413 (one without a
/// length, whose excess shows only while it is read).
async fn read_limited(mut body: axum::body::Body, limit: usize) -> Result<Vec<u8>, ApiError> {
    use http_body_util::BodyExt as _;
    let mut out = Vec::new();
    while let Some(frame) = body.frame().await {
        let frame = frame.map_err(|e| ApiError::bad_request(format!("cannot read the body: {e}")))?;
        let Ok(data) = frame.into_data() else { continue };
        if out.len() + data.len() <= limit {
            out.extend_from_slice(&data);
            continue;
        }
        drain(body, data.len()).await;
        return Err(too_large(format!("the body exceeds the limit of {limit} bytes")));
    }
    Ok(out)
}

/// Before a 413 goes out, reads and drops up to `DRAIN_BYTES` (counting `already` read) more
/// of a refused body, for at most `DRAIN_TIME`, so that a client still sending a moderately
/// oversized body receives the 413 instead of a connection closed under it.
async fn drain(mut body: axum::body::Body, already: usize) {
    use http_body_util::BodyExt as _;
    let read = async {
        let mut drained = already;
        while drained < DRAIN_BYTES {
            match body.frame().await {
                Some(Ok(f)) => drained += f.data_ref().map_or(0, |d| d.len()),
                _ => break,
            }
        }
    };
    let _ = tokio::time::timeout(DRAIN_TIME, read).await;
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

/// The limit and offset of a page request, checked.
pub(crate) fn page_bounds(q: &api::PageQuery) -> ApiResult<(i64, i64)> {
    let limit = q.limit.unwrap_or(api::DEFAULT_PAGE).clamp(1, api::MAX_PAGE);
    let offset = q.offset.unwrap_or(0);
    if offset < 0 {
        return Err(ApiError::bad_request(format!("offset = {offset}: must be ≥ 0")).field("offset"));
    }
    Ok((limit, offset))
}

/// A page of items: `next_offset` when the page is full.
pub(crate) fn page<T>(items: Vec<T>, limit: i64, offset: i64) -> api::Page<T> {
    let next_offset = (items.len() as i64 == limit).then_some(offset + limit);
    api::Page { items, next_offset }
}
