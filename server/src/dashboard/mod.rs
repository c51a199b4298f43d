//! The dashboard: server-rendered HTML at `/` and a few pages beside it, outside `/api/v1`.
//!
//! - `/`: the calibrations with status, progress and best cost (or, when tokens are configured
//!   and the browser has not signed in, the sign-in form: `POST /signin` takes the client token
//!   and sets an HttpOnly cookie holding a random session id (never the token) that expires
//!   after [`crate::Settings::session_ttl`] and is stored server-side as its SHA-256;
//!   `POST /signout` revokes the session and clears the cookie);
//! - `/calibrations/{id}`: one calibration, its stages and its figures as inline SVG (the
//!   [`crate::figures`] set), refreshed every few seconds while it runs, with CSV downloads and
//!   each figure as SVG or PNG;
//! - `/experiments`, `/experiments/{id}`: the stored experiments, their case and measured data;
//! - `/workers`: the workers with their last heartbeat and throughput.
//!
//! Every page but `/` needs the cookie when tokens are configured (401 with the sign-in form
//! otherwise, never a redirect). Every text that comes from storage is escaped. The only script
//! (`/dashboard.js`, a few lines that fetch the page again and swap its live part while a
//! calibration runs) is served as a file, so the Content-Security-Policy allows no inline script.
//!
//! The pages live by resource: `session` (signing in and out), `calibrations`, `experiments`,
//! `workers`; this module holds the router and the page frame. A calibration's figures are drawn
//! and kept by [`crate::figure_cache`], with model runs that stop at the end of the data.

mod calibrations;
mod experiments;
mod session;
mod workers;

use std::fmt::Write as _;

use axum::Router;
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware;
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use cryofit_plots::escape_html as esc;

use crate::clock::now_ms;
use crate::db::DbError;
use crate::routes::error::ApiError;
use crate::state::AppState;
use session::secured;

/// Name of the session cookie (its value is a random session id, 64 hex digits).
pub const SESSION_COOKIE: &str = "cryofit_session";

/// Seconds between refreshes of a page that shows a running calibration.
const REFRESH_S: u32 = 5;

/// The dashboard's routes; every page but `/`, `/signin`, `/signout` and the script needs a
/// session when tokens are configured.
pub(crate) fn router(state: AppState) -> Router<AppState> {
    let pages = Router::new()
        .route("/calibrations/{id}", get(calibrations::calibration_page))
        .route("/calibrations/{id}/parameter-sets.csv", get(calibrations::parameter_sets_download))
        .route("/calibrations/{id}/results.csv", get(calibrations::results_download))
        .route("/calibrations/{id}/figures/{file}", get(calibrations::figure_file))
        .route("/experiments", get(experiments::experiments_page))
        .route("/experiments/{id}", get(experiments::experiment_page))
        .route("/experiments/{id}/data.csv", get(experiments::experiment_data))
        .route("/experiments/{id}/case.toml", get(experiments::experiment_case))
        .route("/workers", get(workers::workers_page))
        .layer(middleware::from_fn_with_state(state, session::require_session));
    Router::new()
        .route("/", get(calibrations::home))
        .route("/signin", post(session::sign_in))
        .route("/signout", post(session::sign_out))
        .route("/dashboard.js", get(script))
        .merge(pages)
}

async fn script() -> Response {
    ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], REFRESH_SCRIPT).into_response()
}

const STYLE: &str = "body{font-family:'DejaVu Sans',Verdana,sans-serif;margin:0;color:#222;background:#fafafa}\
header{background:#1d3557;color:#fff;padding:.6em 1.5em;display:flex;gap:1.5em;align-items:center}\
header a{color:#fff;text-decoration:none}header form{margin-left:auto}\
main{padding:1em 1.5em;max-width:1400px}table{border-collapse:collapse;margin:.5em 0 1.5em}\
td,th{border:1px solid #ccc;padding:.3em .6em;text-align:left;vertical-align:top}th{background:#eee}\
td.num{text-align:right;font-variant-numeric:tabular-nums}\
.status{padding:.1em .5em;border-radius:.3em;background:#ddd}.running,.queued{background:#ffe08a}\
.completed{background:#b7e4c7}.failed,.cancelled{background:#f4a6a6}\
figure{margin:1.5em 0;background:#fff;border:1px solid #ddd;padding:.5em}figure svg{max-width:100%;height:auto}\
.note{color:#8a5a00}pre{background:#fff;border:1px solid #ddd;padding:.6em;overflow:auto;max-height:30em}";

/// `/dashboard.js`: fetches the page again every few seconds and swaps in its live part while it
/// asks for it.
const REFRESH_SCRIPT: &str = "(function tick(){var l=document.getElementById('live');\
if(!l||!l.dataset.refresh)return;setTimeout(function(){fetch(location.href,{credentials:'same-origin'})\
.then(function(r){return r.ok?r.text():null}).then(function(t){if(!t){tick();return}\
var n=new DOMParser().parseFromString(t,'text/html').getElementById('live');if(n){l.replaceWith(n)}tick()})\
.catch(function(){tick()})},1000*Number(l.dataset.refresh))})();\n";

fn page(title: &str, body: &str, refresh: bool, secured: bool) -> String {
    let mut s = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{} — cryofit</title>\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\"><style>{STYLE}</style></head>\n<body>\
         <header><strong>cryofit</strong><a href=\"/\">Calibrations</a><a href=\"/experiments\">Experiments</a>\
         <a href=\"/workers\">Workers</a>",
        esc(title)
    );
    if secured {
        s.push_str("<form method=\"post\" action=\"/signout\"><button type=\"submit\">Sign out</button></form>");
    }
    let live = if refresh { format!(" data-refresh=\"{REFRESH_S}\"") } else { String::new() };
    let _ = write!(
        s,
        "</header>\n<main id=\"live\"{live}>\n{body}\n</main>\n<script src=\"/dashboard.js\"></script>\n</body></html>\n"
    );
    s
}

fn error_page(state: &AppState, status: StatusCode, message: &str) -> Response {
    let body = format!("<h1>{}</h1><p>{}</p>", status.as_u16(), esc(message));
    (status, Html(page("Error", &body, false, secured(state)))).into_response()
}

fn db_error(state: &AppState, e: DbError) -> Response {
    api_error(state, ApiError::from(e))
}

fn api_error(state: &AppState, e: ApiError) -> Response {
    let (status, message) = e.parts();
    error_page(state, status, message)
}

fn download(name: &str, r: Response) -> Response {
    let mut r = r;
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{name}\"")) {
        r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
    }
    r
}

fn ago(ms: i64) -> String {
    let s = (now_ms() - ms).max(0) / 1000;
    match s {
        0..=119 => format!("{s} s ago"),
        120..=7199 => format!("{} min ago", s / 60),
        _ => format!("{} h ago", s / 3600),
    }
}

fn num(v: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) { format!("{v:.4e}") } else { format!("{}", (v * 1e4).round() / 1e4) }
}

fn status_badge(s: &str) -> String {
    format!("<span class=\"status {0}\">{0}</span>", esc(s))
}
