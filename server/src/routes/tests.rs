//! The router against its OpenAPI document, and the role groups.

use std::collections::BTreeSet;

use axum::body::Body;
use axum::http::{Method, Request, StatusCode};
use tower::ServiceExt as _;

use crate::app::{build_state, router};
use crate::config::{Secret, Settings};
use crate::state::AppState;

fn scratch(tag: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("cryofit-routes-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

async fn state(tag: &str, tokens: bool) -> (AppState, std::path::PathBuf) {
    let dir = scratch(tag);
    let mut settings = Settings::new(dir.join("c.db").display().to_string());
    if tokens {
        settings.client_token = Some(Secret::new("client"));
        settings.worker_token = Some(Secret::new("worker"));
    }
    (build_state(settings, "test").await.expect("state"), dir)
}

async fn close(state: AppState, dir: std::path::PathBuf) {
    state.lock.release(state.coordinator.db()).await;
    state.coordinator.db().close().await;
    let _ = std::fs::remove_dir_all(dir);
}

/// The paths a router serves, as its `Debug` output lists them (axum offers no other way to
/// enumerate them).
fn routed_paths(app: &axum::Router) -> BTreeSet<String> {
    let text = format!("{app:?}");
    text.split("RouteId(")
        .skip(1)
        .filter_map(|rest| {
            let digits = rest.find(|c: char| !c.is_ascii_digit())?;
            let tail = rest[digits..].strip_prefix("): \"")?;
            Some(tail[..tail.find('"')?].to_string())
        })
        .collect()
}

/// A request to a route path, its parameters filled in.
fn request(method: &Method, path: &str, token: Option<&str>) -> Request<Body> {
    let uri = path.replace("{id}", "1").replace("{file}", "x.svg");
    let mut r = Request::builder().method(method.clone()).uri(uri);
    if let Some(t) = token {
        r = r.header("authorization", format!("Bearer {t}"));
    }
    r.body(Body::empty()).expect("request")
}

const METHODS: [Method; 5] = [Method::GET, Method::POST, Method::PUT, Method::PATCH, Method::DELETE];

/// The (method, path) operations a router serves under `/api/v1` (a method counts when the
/// path's route does not answer 405), the document itself left out.
async fn served_operations(app: &axum::Router) -> BTreeSet<(String, String)> {
    let mut ops = BTreeSet::new();
    for path in routed_paths(app) {
        if !path.starts_with("/api/v1/") || path == "/api/v1/openapi.json" {
            continue;
        }
        for m in &METHODS {
            let r = app.clone().oneshot(request(m, &path, None)).await.expect("answer");
            if r.status() != StatusCode::METHOD_NOT_ALLOWED {
                ops.insert((m.to_string(), path.clone()));
            }
        }
    }
    ops
}

/// The (method, path) operations of an OpenAPI document.
fn documented_operations(doc: &utoipa::openapi::OpenApi) -> BTreeSet<(String, String)> {
    let doc = serde_json::to_value(doc).expect("document as JSON");
    let mut ops = BTreeSet::new();
    for (path, item) in doc["paths"].as_object().into_iter().flatten() {
        for m in &METHODS {
            if item.get(m.as_str().to_lowercase()).is_some() {
                ops.insert((m.to_string(), path.clone()));
            }
        }
    }
    ops
}

/// What the router serves and the document does not list, and the other way round.
async fn drift(app: &axum::Router, doc: &utoipa::openapi::OpenApi) -> Vec<String> {
    let (served, documented) = (served_operations(app).await, documented_operations(doc));
    let mut out: Vec<String> =
        served.difference(&documented).map(|(m, p)| format!("{m} {p} is served but not documented")).collect();
    out.extend(documented.difference(&served).map(|(m, p)| format!("{m} {p} is documented but not served")));
    out
}

#[tokio::test]
async fn every_route_is_in_the_openapi_document_and_every_entry_is_routed() {
    let (state, dir) = state("drift", false).await;
    let doc = super::document(&state.settings.limits);
    let app = router(state.clone());
    let paths = routed_paths(&app);
    assert!(
        paths.contains("/api/v1/jobs/{id}/heartbeat") && paths.contains("/healthz"),
        "the router's paths are read from its Debug output: {paths:?}"
    );
    assert_eq!(documented_operations(&doc).len(), 13, "{:?}", documented_operations(&doc));
    assert_eq!(drift(&app, &doc).await, Vec::<String>::new());
    // a route added beside the documented ones, without its document entry, is found
    let extra = router(state.clone()).route("/api/v1/jobs/{id}/cancel", axum::routing::post(|| async {}));
    assert_eq!(drift(&extra, &doc).await, ["POST /api/v1/jobs/{id}/cancel is served but not documented"]);
    // and a method added to a documented path
    let extra = router(state.clone()).route("/api/v1/experiments/{id}/x", axum::routing::delete(|| async {}));
    assert_eq!(drift(&extra, &doc).await, ["DELETE /api/v1/experiments/{id}/x is served but not documented"]);
    close(state, dir).await;
}

#[tokio::test]
async fn the_served_document_is_the_document_with_this_coordinators_limits() {
    let (state, dir) = state("document", false).await;
    let app = router(state.clone());
    let r = app.oneshot(request(&Method::GET, "/api/v1/openapi.json", None)).await.expect("answer");
    assert_eq!(r.status(), StatusCode::OK);
    let body = axum::body::to_bytes(r.into_body(), 1 << 22).await.expect("body");
    let served: serde_json::Value = serde_json::from_slice(&body).expect("JSON");
    let doc = serde_json::to_value(super::document(&state.settings.limits)).expect("JSON");
    assert_eq!(served, doc);
    assert!(served["openapi"].as_str().is_some_and(|v| v.starts_with("3.1")), "{}", served["openapi"]);
    assert_eq!(served["info"]["x-cryofit-limits"]["max_budget"], state.settings.limits.max_budget);
    assert!(served["components"]["securitySchemes"]["bearer"].is_object(), "{}", served["components"]);
    close(state, dir).await;
}

#[tokio::test]
async fn each_role_group_admits_its_roles_only() {
    let (state, dir) = state("roles", true).await;
    let app = router(state.clone());
    let doc = super::document(&state.settings.limits);
    let mut ops: Vec<(String, String)> = documented_operations(&doc).into_iter().collect();
    ops.push(("GET".into(), "/api/v1/openapi.json".into()));
    for (m, path) in ops {
        let method = Method::from_bytes(m.as_bytes()).expect("method");
        let status = |token| {
            let app = app.clone();
            let req = request(&method, &path, token);
            async move { app.oneshot(req).await.expect("answer").status() }
        };
        assert_eq!(status(None).await, StatusCode::UNAUTHORIZED, "{m} {path} without a token");
        assert_eq!(status(Some("nope")).await, StatusCode::UNAUTHORIZED, "{m} {path} with a wrong token");
        let worker_only = path.starts_with("/api/v1/jobs");
        let both = path == "/api/v1/openapi.json" || (m == "GET" && path == "/api/v1/experiments/{id}");
        let (client, worker) = (status(Some("client")).await, status(Some("worker")).await);
        assert_eq!(client == StatusCode::FORBIDDEN, worker_only, "{m} {path} with the client token: {client}");
        assert_eq!(
            worker == StatusCode::FORBIDDEN,
            !worker_only && !both,
            "{m} {path} with the worker token: {worker}"
        );
    }
    close(state, dir).await;
}
