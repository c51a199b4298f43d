//! Logs and request traces: [`init`] installs the process's subscriber (for `cryofit serve` and
//! `cryofit work`), [`http_trace`] is the layer that gives every request a span named by its route.

use axum::body::Body;
use axum::extract::MatchedPath;
use axum::http::Request;
use tower_http::trace::{HttpMakeClassifier, TraceLayer};

/// Logs to stderr, filtered by `RUST_LOG` (default `info`). A second call changes nothing.
pub fn init() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}

/// The span of a request: its method and matched route (never the path with its ids).
fn request_span(req: &Request<Body>) -> tracing::Span {
    let route = req.extensions().get::<MatchedPath>().map_or("unmatched", |m| m.as_str());
    tracing::info_span!("request", method = %req.method(), route = %route)
}

/// The trace layer of the router.
pub(crate) fn http_trace() -> TraceLayer<HttpMakeClassifier, fn(&Request<Body>) -> tracing::Span> {
    TraceLayer::new_for_http().make_span_with(request_span as fn(&Request<Body>) -> tracing::Span)
}
