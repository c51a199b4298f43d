//! Bearer tokens and roles, decided before any body is read.
//!
//! [`authenticate`] runs on everything under `/api/v1`: 401 without a valid token, otherwise the
//! roles the token holds go with the request. Each role group of routes then carries its own
//! check ([`client`], [`worker`], [`any_role`]): 403 for a token of the wrong role. Without
//! configured tokens (loopback only) every request holds every role.

use axum::extract::{MatchedPath, Request, State};
use axum::http::{StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::error::ApiError;
use crate::state::AppState;

/// A role a token gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// Submits, reads and cancels.
    Client,
    /// Claims and runs jobs.
    Worker,
}

/// The roles the request's token holds, set by [`authenticate`].
#[derive(Debug, Clone, Copy, Default)]
struct Held {
    client: bool,
    worker: bool,
}

impl Held {
    fn has(self, role: Role) -> bool {
        match role {
            Role::Client => self.client,
            Role::Worker => self.worker,
        }
    }
}

fn unauthorized(message: &'static str) -> Response {
    ApiError::new(StatusCode::UNAUTHORIZED, "unauthorized", message).into_response()
}

/// Bearer-token check: 401 without a valid token; the roles it holds go with the request.
pub(crate) async fn authenticate(State(state): State<AppState>, mut req: Request, next: Next) -> Response {
    let s = &state.settings;
    if s.client_token.is_none() && s.worker_token.is_none() {
        req.extensions_mut().insert(Held { client: true, worker: true });
        return next.run(req).await;
    }
    let token = req
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer ").or_else(|| v.strip_prefix("bearer ")))
        .map(str::trim);
    let Some(token) = token else {
        return unauthorized("missing bearer token: send `Authorization: Bearer <token>` (CRYOFIT_TOKEN)");
    };
    let held = Held {
        client: s.client_token.as_ref().is_some_and(|t| t.matches(token)),
        worker: s.worker_token.as_ref().is_some_and(|t| t.matches(token)),
    };
    if !held.client && !held.worker {
        return unauthorized("the bearer token is not valid");
    }
    req.extensions_mut().insert(held);
    next.run(req).await
}

/// Lets the request through when its token holds one of `roles`: 403 otherwise, and 401 when
/// [`authenticate`] did not run (a route outside it: refused rather than open).
async fn require(roles: &[Role], req: Request, next: Next) -> Response {
    let Some(held) = req.extensions().get::<Held>().copied() else {
        return unauthorized("missing bearer token: send `Authorization: Bearer <token>` (CRYOFIT_TOKEN)");
    };
    if roles.iter().any(|r| held.has(*r)) {
        return next.run(req).await;
    }
    let path =
        req.extensions().get::<MatchedPath>().map_or_else(|| req.uri().path().to_string(), |m| m.as_str().into());
    let want = if roles.contains(&Role::Worker) { "a worker token" } else { "a client token" };
    ApiError::new(
        StatusCode::FORBIDDEN,
        "forbidden",
        format!("{} {path} needs {want}; this token's role may not use it", req.method()),
    )
    .into_response()
}

/// The check of the client routes.
pub(crate) async fn client(req: Request, next: Next) -> Response {
    require(&[Role::Client], req, next).await
}

/// The check of the worker routes.
pub(crate) async fn worker(req: Request, next: Next) -> Response {
    require(&[Role::Worker], req, next).await
}

/// The check of the routes both roles use.
pub(crate) async fn any_role(req: Request, next: Next) -> Response {
    require(&[Role::Client, Role::Worker], req, next).await
}
