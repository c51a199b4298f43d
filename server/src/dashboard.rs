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
//! A calibration's figures are drawn on the blocking pool, at most one drawing per calibration at
//! a time (later viewers wait for it and take its result), with model runs that stop at the end
//! of the data, and kept until the calibration changes.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::sync::{Arc, Mutex};

use axum::Form;
use axum::Router;
use axum::extract::{Path, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use axum_extra::extract::cookie::{Cookie, CookieJar, SameSite};
use cryofit_api as api;
use cryofit_plots::{Figure, Plot, escape_html as esc};

use crate::AppState;
use crate::clock::utc;
use crate::db::{self, DbError};
use crate::figures::{self, CalibrationData, FigureOptions};
use crate::routes::{ApiError, calibration_view, csv_response, parameter_sets_csv, results_csv};

/// Name of the session cookie (its value is a random session id, 64 hex digits).
pub const SESSION_COOKIE: &str = "cryofit_session";

/// Seconds between refreshes of a page that shows a running calibration.
const REFRESH_S: u32 = 5;

/// Posterior draws simulated for the bands of a finished calibration's page.
const DASHBOARD_BAND_DRAWS: usize = 8;

/// Figure drawings that run at once, over all calibrations (each uses every core for its
/// posterior-predictive runs).
static FIGURE_BUILDS: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(2);

/// Calibrations whose figures are kept.
const CACHED_CALIBRATIONS: usize = 16;

/// Figures drawn for a calibration at one state of it (status, evaluations, last update).
#[derive(Debug)]
struct Drawn {
    key: String,
    at: std::time::Instant,
    figures: Vec<(Figure, Result<String, String>)>,
}

/// The figures of recently viewed calibrations, redrawn when the calibration has changed, and
/// the drawings under way (one per calibration).
#[derive(Debug, Default)]
pub struct FigureCache {
    map: Mutex<HashMap<i64, Arc<Drawn>>>,
    building: Mutex<HashMap<i64, Arc<tokio::sync::Mutex<()>>>>,
}

pub(crate) fn router(state: AppState) -> Router<AppState> {
    let pages = Router::new()
        .route("/calibrations/{id}", get(calibration_page))
        .route("/calibrations/{id}/parameter-sets.csv", get(parameter_sets_download))
        .route("/calibrations/{id}/results.csv", get(results_download))
        .route("/calibrations/{id}/figures/{file}", get(figure_file))
        .route("/experiments", get(experiments_page))
        .route("/experiments/{id}", get(experiment_page))
        .route("/experiments/{id}/data.csv", get(experiment_data))
        .route("/experiments/{id}/case.toml", get(experiment_case))
        .route("/workers", get(workers_page))
        .layer(middleware::from_fn_with_state(state, require_session));
    Router::new()
        .route("/", get(home))
        .route("/signin", post(sign_in))
        .route("/signout", post(sign_out))
        .route("/dashboard.js", get(script))
        .merge(pages)
}

async fn script() -> Response {
    ([(header::CONTENT_TYPE, "text/javascript; charset=utf-8")], REFRESH_SCRIPT).into_response()
}

// ---------------------------------------------------------------------------------------------
// session

fn secured(state: &AppState) -> bool {
    state.settings.client_token.is_some() || state.settings.worker_token.is_some()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of a session id, hex: what the database holds.
fn digest(session: &str) -> String {
    use sha2::Digest as _;
    hex(&sha2::Sha256::digest(session.as_bytes()))
}

/// The session id of the cookie, if it is one that is stored and not expired.
async fn session(state: &AppState, headers: &HeaderMap) -> Option<String> {
    let id = CookieJar::from_headers(headers).get(SESSION_COOKIE)?.value().to_string();
    if id.len() != 64 || !id.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    match db::session_valid(state.coordinator.db().reader(), &digest(&id), db::now_ms()).await {
        Ok(true) => Some(id),
        Ok(false) => None,
        Err(e) => {
            tracing::error!(error = %e, "reading a session");
            None
        }
    }
}

async fn signed_in(state: &AppState, headers: &HeaderMap) -> bool {
    !secured(state) || session(state, headers).await.is_some()
}

async fn require_session(State(state): State<AppState>, req: Request, next: Next) -> Response {
    if signed_in(&state, req.headers()).await {
        return next.run(req).await;
    }
    let next_path = req.uri().path().to_string();
    let body = sign_in_form(Some("Sign in with the client token to see this page."), &next_path);
    (StatusCode::UNAUTHORIZED, Html(page("Sign in", &body, false, true))).into_response()
}

fn sign_in_form(note: Option<&str>, next_path: &str) -> String {
    let mut s = String::from("<h1>cryofit coordinator</h1>");
    if let Some(n) = note {
        let _ = write!(s, "<p class=\"note\">{}</p>", esc(n));
    }
    let _ = write!(
        s,
        "<form method=\"post\" action=\"/signin\" class=\"signin\"><input type=\"hidden\" name=\"next\" value=\"{}\">\
         <label>Client token <input name=\"token\" type=\"password\" autocomplete=\"current-password\" required></label> \
         <button type=\"submit\">Sign in</button></form>\
         <p>The REST API is under <code>/api/v1</code> (bearer token); its contract is \
         <code>/api/v1/openapi.json</code>.</p>",
        esc(next_path)
    );
    s
}

/// Where to go after signing in: a local path, `/` otherwise. Whitespace and control characters
/// are refused (browsers drop a TAB or a newline from a URL, which would turn `/\t/host` into
/// `//host`), as are backslashes and `//` (another host).
fn local_path(next: Option<&str>) -> String {
    match next {
        Some(p)
            if p.starts_with('/')
                && !p.starts_with("//")
                && !p.chars().any(|c| c.is_control() || c.is_whitespace() || c == '\\') =>
        {
            p.to_string()
        }
        _ => "/".into(),
    }
}

fn see_other(location: &str, jar: CookieJar) -> Response {
    let mut r = (jar, StatusCode::SEE_OTHER).into_response();
    if let Ok(v) = HeaderValue::from_str(location) {
        r.headers_mut().insert(header::LOCATION, v);
    }
    r
}

/// The sign-in form's fields.
#[derive(Debug, serde::Deserialize)]
struct SignIn {
    #[serde(default)]
    token: String,
    #[serde(default)]
    next: Option<String>,
}

fn session_cookie(state: &AppState, value: String, max_age: cookie::time::Duration) -> Cookie<'static> {
    Cookie::build((SESSION_COOKIE, value))
        .path("/")
        .http_only(true)
        .same_site(SameSite::Strict)
        .secure(state.settings.secure_cookies)
        .max_age(max_age)
        .build()
}

async fn sign_in(State(state): State<AppState>, jar: CookieJar, Form(form): Form<SignIn>) -> Response {
    let next = local_path(form.next.as_deref());
    if !secured(&state) {
        return see_other(&next, jar);
    }
    let token = form.token.trim();
    let valid = !token.is_empty() && state.settings.client_token.as_ref().is_some_and(|t| t.matches(token));
    if !valid {
        let body = sign_in_form(Some("That is not the client token (CRYOFIT_CLIENT_TOKEN)."), &next);
        return (StatusCode::UNAUTHORIZED, Html(page("Sign in", &body, false, true))).into_response();
    }
    let id = hex(&rand::random::<[u8; 32]>());
    let now = db::now_ms();
    let ttl = state.settings.session_ttl;
    let db = state.coordinator.db();
    let stored = async {
        let mut tx = db.begin().await?;
        db::delete_expired_sessions(&mut tx, now).await?;
        db::insert_session(&mut tx, &digest(&id), now, now + ttl.as_millis() as i64).await?;
        db.commit(tx).await
    };
    if let Err(e) = stored.await {
        return db_error(&state, e);
    }
    let max_age = cookie::time::Duration::seconds(i64::try_from(ttl.as_secs()).unwrap_or(i64::MAX));
    see_other(&next, jar.add(session_cookie(&state, id, max_age)))
}

async fn sign_out(State(state): State<AppState>, jar: CookieJar) -> Response {
    if let Some(id) = jar.get(SESSION_COOKIE).map(|c| c.value().to_string()) {
        let db = state.coordinator.db();
        let done = async {
            let mut tx = db.begin().await?;
            db::delete_session(&mut tx, &digest(&id)).await?;
            db.commit(tx).await
        };
        if let Err(e) = done.await {
            return db_error(&state, e);
        }
    }
    see_other("/", jar.remove(session_cookie(&state, String::new(), cookie::time::Duration::ZERO)))
}

// ---------------------------------------------------------------------------------------------
// page frame

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

fn ago(ms: i64) -> String {
    let s = (db::now_ms() - ms).max(0) / 1000;
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

// ---------------------------------------------------------------------------------------------
// calibrations

async fn home(State(state): State<AppState>, headers: HeaderMap) -> Response {
    if !signed_in(&state, &headers).await {
        return Html(page("Sign in", &sign_in_form(None, "/"), false, true)).into_response();
    }
    let pool = state.coordinator.db().reader();
    let mut rows = Vec::new();
    let mut offset = 0;
    loop {
        match db::calibrations(pool, None, api::MAX_PAGE, offset).await {
            Ok(page) => {
                let n = page.len() as i64;
                rows.extend(page);
                if n < api::MAX_PAGE {
                    break;
                }
                offset += n;
            }
            Err(e) => return db_error(&state, e),
        }
    }
    rows.reverse(); // newest first
    let running = rows.iter().any(|r| r.status == "running" || r.status == "queued");
    let mut s = String::from("<h1>Calibrations</h1>");
    if rows.is_empty() {
        s.push_str(
            "<p>No calibration yet: submit one with <code>cryofit submit FILE.toml --coordinator URL</code>.</p>",
        );
    } else {
        s.push_str(
            "<table><tr><th>id</th><th>name</th><th>status</th><th>progress</th><th>stage</th><th>best cost</th>\
             <th>updated</th></tr>",
        );
        for r in &rows {
            let stages = serde_json::from_str::<serde_json::Value>(&r.spec_json)
                .ok()
                .and_then(|v| {
                    v["stages"].as_array().map(|a| {
                        a.iter().map(|s| s["algorithm"].as_str().unwrap_or("?").to_string()).collect::<Vec<_>>()
                    })
                })
                .unwrap_or_default();
            let k = (r.stage.max(0) as usize).min(stages.len().saturating_sub(1));
            let stage = stages.get(k).map_or_else(String::new, |a| format!("{}/{} {a}", k + 1, stages.len()));
            let _ = write!(
                s,
                "<tr><td class=\"num\">{id}</td><td><a href=\"/calibrations/{id}\">{name}</a></td><td>{status}</td>\
                 <td><progress value=\"{ev}\" max=\"{budget}\"></progress> {ev}/{budget}{failed}</td><td>{stage}</td>\
                 <td class=\"num\">{best}</td><td>{updated}</td></tr>",
                id = r.id,
                name = esc(&r.name),
                status = status_badge(&r.status),
                ev = r.evaluations,
                budget = r.budget.max(1),
                failed = if r.failed_evaluations > 0 {
                    format!(" ({} failed)", r.failed_evaluations)
                } else {
                    String::new()
                },
                stage = esc(&stage),
                best = r.best_cost.map_or_else(|| "—".into(), num),
                updated = esc(&utc(r.updated)),
            );
        }
        s.push_str("</table>");
    }
    Html(page("Calibrations", &s, running, secured(&state))).into_response()
}

/// The calibration, its parameter sets and experiments, as the figures need them.
async fn calibration_data(state: &AppState, id: i64) -> Result<CalibrationData, Response> {
    let pool = state.coordinator.db().reader();
    let row = db::calibration(pool, id).await.map_err(|e| db_error(state, e))?;
    let calibration = calibration_view(row).map_err(|e| api_error(state, e))?;
    let sets = db::all_parameter_sets(pool, id).await.map_err(|e| db_error(state, e))?;
    let mut experiments = Vec::new();
    for &e in &calibration.experiments {
        experiments.push(db::experiment(pool, e).await.map_err(|x| db_error(state, x))?);
    }
    Ok(CalibrationData { calibration, sets, experiments })
}

/// The figures of a calibration, from the cache when it has not changed since they were drawn.
/// At most one drawing per calibration runs at a time (two over all calibrations): a viewer that
/// finds one under way waits for it and takes its figures.
async fn drawn(state: &AppState, data: CalibrationData) -> Result<Arc<Drawn>, Response> {
    let c = &data.calibration;
    let key = format!("{}:{}:{}:{}", c.status.as_str(), c.evaluations, c.failed_evaluations, c.updated);
    let id = c.id;
    let cache = state.figures.clone();
    let fresh = |since: Option<std::time::Instant>| {
        let map = cache.map.lock().ok()?;
        let d = map.get(&id)?;
        (d.key == key || since.is_some_and(|t| d.at >= t)).then(|| d.clone())
    };
    if let Some(d) = fresh(None) {
        return Ok(d);
    }
    let gate = {
        let mut b = cache.building.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        b.entry(id).or_default().clone()
    };
    let waiting_since = std::time::Instant::now();
    let _turn = gate.lock().await;
    // a drawing that finished while this viewer waited is as new as this viewer's data
    if let Some(d) = fresh(Some(waiting_since)) {
        return Ok(d);
    }
    let fluids = state.settings.fluids.clone();
    let opts = FigureOptions {
        band_draws: if c.status == api::CalibrationStatus::Completed { DASHBOARD_BAND_DRAWS } else { 0 },
        seed: 0,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        end_at_data: true,
    };
    // and at most two drawings at once over all calibrations
    let _slot = FIGURE_BUILDS
        .acquire()
        .await
        .map_err(|e| error_page(state, StatusCode::SERVICE_UNAVAILABLE, &e.to_string()))?;
    state.metrics.figures_built();
    let done = tokio::task::spawn_blocking(move || {
        let figures = figures::figures(&data, &fluids, &opts);
        let figures = figures
            .into_iter()
            .map(|f| {
                let svg = match &f.plot {
                    Ok(p) => p.svg().map_err(|e| e.to_string()),
                    Err(why) => Err(why.clone()),
                };
                (f, svg)
            })
            .collect();
        Drawn { key, at: std::time::Instant::now(), figures }
    })
    .await
    .map_err(|e| error_page(state, StatusCode::INTERNAL_SERVER_ERROR, &format!("drawing the figures: {e}")))?;
    let done = Arc::new(done);
    if let Ok(mut map) = cache.map.lock() {
        if map.len() >= CACHED_CALIBRATIONS && !map.contains_key(&id) {
            map.clear();
        }
        map.insert(id, done.clone());
    }
    Ok(done)
}

async fn calibration_page(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    let data = match calibration_data(&state, id).await {
        Ok(d) => d,
        Err(r) => return r,
    };
    let c = data.calibration.clone();
    let names: Vec<(i64, String)> = data.experiments.iter().map(|e| (e.id, e.name.clone())).collect();
    let reports = c.stages.clone();
    let stage_specs: Vec<String> = c.spec["stages"]
        .as_array()
        .map(|a| a.iter().map(|s| s["algorithm"].as_str().unwrap_or("?").to_string()).collect())
        .unwrap_or_default();
    let drawn = match drawn(&state, data).await {
        Ok(d) => d,
        Err(r) => return r,
    };
    let mut s = format!("<h1>{} <small>(calibration {id})</small></h1>", esc(&c.name));
    let _ = write!(
        s,
        "<p>{} <progress value=\"{ev}\" max=\"{b}\"></progress> {ev} of {b} evaluations ({f} failed); best cost {best}; \
         created {created}, updated {updated}</p>",
        status_badge(c.status.as_str()),
        ev = c.evaluations,
        b = c.budget.max(1),
        f = c.failed_evaluations,
        best = c.best_cost.map_or_else(|| "—".into(), num),
        created = esc(&utc(c.created)),
        updated = esc(&utc(c.updated)),
    );
    if let Some(e) = &c.error {
        let _ = write!(s, "<p class=\"note\">Error: {}</p>", esc(e));
    }
    s.push_str("<h2>Stages</h2><table><tr><th>stage</th><th>algorithm</th><th>evaluations</th><th>best cost</th><th>free parameters</th><th>state</th></tr>");
    for (k, alg) in stage_specs.iter().enumerate() {
        let r = reports.get(k);
        let field = |name: &str| r.map(|r| r[name].clone()).unwrap_or(serde_json::Value::Null);
        let free: Vec<String> = field("free")
            .as_array()
            .map(|a| a.iter().filter_map(|v| v.as_str().map(str::to_string)).collect())
            .unwrap_or_default();
        let state_text = match r {
            None if (k as i64) == c.stage && !c.status.is_final() => "running".to_string(),
            None => "not started".to_string(),
            Some(_) => field("stop").as_str().unwrap_or("").to_string(),
        };
        let _ = write!(
            s,
            "<tr><td class=\"num\">{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td>{}</td><td>{}</td></tr>",
            k + 1,
            esc(alg),
            field("evaluations").as_i64().map_or_else(String::new, |v| v.to_string()),
            field("best_cost").as_f64().map_or_else(|| "—".into(), num),
            esc(&free.join(", ")),
            esc(&state_text),
        );
    }
    s.push_str("</table>");
    if let Some(p) = &c.best_parameters {
        s.push_str("<h2>Best parameters</h2><table><tr><th>parameter</th><th>value</th><th>unit</th></tr>");
        for (k, v) in p {
            let unit =
                cryofit_solver::params::spec(k).map_or("", |s| if s.unit == "-" { "dimensionless" } else { s.unit });
            let _ = write!(s, "<tr><td>{}</td><td class=\"num\">{}</td><td>{}</td></tr>", esc(k), num(*v), esc(unit));
        }
        s.push_str("</table>");
    }
    s.push_str("<h2>Experiments and downloads</h2><ul>");
    for (eid, name) in &names {
        let _ = write!(s, "<li>experiment <a href=\"/experiments/{eid}\">{}</a></li>", esc(name));
    }
    let _ = write!(
        s,
        "<li><a href=\"/calibrations/{id}/parameter-sets.csv\" download>parameter-sets.csv</a> (every parameter set \
         and its cost)</li><li><a href=\"/calibrations/{id}/results.csv\" download>results.csv</a> (every result per \
         experiment, with worker and duration)</li></ul>"
    );
    s.push_str("<h2>Figures</h2>");
    for (f, svg) in &drawn.figures {
        let _ = write!(s, "<figure id=\"{}\"><h3>{}</h3>", esc(&f.name), esc(&f.title));
        match svg {
            Ok(svg) => {
                s.push_str(svg);
                let _ = write!(
                    s,
                    "<figcaption><a href=\"/calibrations/{id}/figures/{n}.svg\">SVG</a> · \
                     <a href=\"/calibrations/{id}/figures/{n}.png\">PNG</a></figcaption>",
                    n = esc(&f.name)
                );
            }
            Err(why) => {
                let _ = write!(s, "<p class=\"note\">Not drawn: {}</p>", esc(why));
            }
        }
        s.push_str("</figure>");
    }
    let running = !c.status.is_final();
    Html(page(&c.name, &s, running, secured(&state))).into_response()
}

async fn figure_file(State(state): State<AppState>, Path((id, file)): Path<(i64, String)>) -> Response {
    let Some((name, ext)) = file.rsplit_once('.') else {
        return error_page(&state, StatusCode::NOT_FOUND, &format!("no figure `{file}`: ask for NAME.svg or NAME.png"));
    };
    if ext != "svg" && ext != "png" {
        return error_page(&state, StatusCode::NOT_FOUND, &format!("no figure `{file}`: ask for NAME.svg or NAME.png"));
    }
    let data = match calibration_data(&state, id).await {
        Ok(d) => d,
        Err(r) => return r,
    };
    let drawn = match drawn(&state, data).await {
        Ok(d) => d,
        Err(r) => return r,
    };
    let Some((f, svg)) = drawn.figures.iter().find(|(f, _)| f.name == name) else {
        return error_page(&state, StatusCode::NOT_FOUND, &format!("calibration {id} has no figure `{name}`"));
    };
    let plot: &Plot = match &f.plot {
        Ok(p) => p,
        Err(why) => return error_page(&state, StatusCode::NOT_FOUND, &format!("figure `{name}` is not drawn: {why}")),
    };
    if ext == "svg" {
        return match svg {
            Ok(svg) => ([(header::CONTENT_TYPE, "image/svg+xml")], svg.clone()).into_response(),
            Err(e) => error_page(&state, StatusCode::INTERNAL_SERVER_ERROR, e),
        };
    }
    let plot = plot.clone();
    match tokio::task::spawn_blocking(move || plot.png()).await {
        Ok(Ok(png)) => ([(header::CONTENT_TYPE, "image/png")], png).into_response(),
        Ok(Err(e)) => error_page(&state, StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
        Err(e) => error_page(&state, StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    }
}

fn download(name: &str, r: Response) -> Response {
    let mut r = r;
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{name}\"")) {
        r.headers_mut().insert(header::CONTENT_DISPOSITION, v);
    }
    r
}

async fn parameter_sets_download(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    let pool = state.coordinator.db().reader();
    if let Err(e) = db::calibration(pool, id).await {
        return db_error(&state, e);
    }
    match db::all_parameter_sets(pool, id).await {
        Ok(items) => {
            download(&format!("calibration-{id}-parameter-sets.csv"), csv_response(parameter_sets_csv(&items)))
        }
        Err(e) => db_error(&state, e),
    }
}

async fn results_download(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    let pool = state.coordinator.db().reader();
    if let Err(e) = db::calibration(pool, id).await {
        return db_error(&state, e);
    }
    match db::all_results(pool, id).await {
        Ok(items) => download(&format!("calibration-{id}-results.csv"), csv_response(results_csv(&items))),
        Err(e) => db_error(&state, e),
    }
}

// ---------------------------------------------------------------------------------------------
// experiments

async fn experiments_page(State(state): State<AppState>) -> Response {
    let pool = state.coordinator.db().reader();
    let mut all = Vec::new();
    loop {
        match db::experiments(pool, api::MAX_PAGE, all.len() as i64).await {
            Ok(page) => {
                let n = page.len() as i64;
                all.extend(page);
                if n < api::MAX_PAGE {
                    break;
                }
            }
            Err(e) => return db_error(&state, e),
        }
    }
    let mut s = String::from("<h1>Experiments</h1>");
    if all.is_empty() {
        s.push_str("<p>No experiment stored yet.</p>");
    } else {
        s.push_str("<table><tr><th>id</th><th>name</th><th>fluid</th><th>stored</th></tr>");
        for e in &all {
            let _ = write!(
                s,
                "<tr><td class=\"num\">{id}</td><td><a href=\"/experiments/{id}\">{}</a></td><td>{}</td><td>{}</td></tr>",
                esc(&e.name),
                esc(&e.fluid),
                esc(&utc(e.created)),
                id = e.id
            );
        }
        s.push_str("</table>");
    }
    Html(page("Experiments", &s, false, secured(&state))).into_response()
}

/// A figure's heading and its SVG, or why it could not be drawn.
type DrawnSvg = (String, Result<String, String>);

/// Figures of an experiment's measured data: one per quantity, a panel per station.
fn data_figures(e: &api::Experiment) -> Result<Vec<DrawnSvg>, String> {
    let data = cryofit_calib::data::Dataset::from_csv(&e.data, &format!("experiment {} data", e.id))
        .map_err(|x| x.to_string())?;
    let mut quantities: Vec<&str> = data.series.keys().map(|(_, q)| q.as_str()).collect();
    quantities.dedup();
    quantities.sort_unstable();
    quantities.dedup();
    Ok(quantities
        .into_iter()
        .map(|q| {
            let (label, scale) = match q {
                "wall_temperature_k" => ("wall temperature (K)".to_string(), 1.0),
                "fluid_temperature_k" => ("fluid temperature (K)".to_string(), 1.0),
                "pressure_pa" => ("pressure (kPa)".to_string(), 1e-3),
                other => (other.replace('_', " "), 1.0),
            };
            let panels = data
                .series
                .iter()
                .filter(|((_, qq), _)| qq == q)
                .map(|((st, _), s)| cryofit_plots::StationPanel {
                    station: st.clone(),
                    x_m: Some(s.x_m),
                    data: s.times.iter().copied().zip(s.values.iter().copied()).collect(),
                    model: Vec::new(),
                    band: None,
                })
                .collect();
            let plot = Plot::Fit(cryofit_plots::FitPanels {
                title: format!("{}: measured {label}", e.name),
                value_label: label.clone(),
                value_scale: scale,
                band_label: String::new(),
                panels,
            });
            (label, plot.svg().map_err(|x| x.to_string()))
        })
        .collect())
}

async fn experiment_page(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    let e = match db::experiment(state.coordinator.db().reader(), id).await {
        Ok(e) => e,
        Err(x) => return db_error(&state, x),
    };
    let (e, figures) = match tokio::task::spawn_blocking(move || {
        let f = data_figures(&e);
        (e, f)
    })
    .await
    {
        Ok(v) => v,
        Err(x) => return error_page(&state, StatusCode::INTERNAL_SERVER_ERROR, &x.to_string()),
    };
    let mut s = format!(
        "<h1>{} <small>(experiment {id}, {})</small></h1><p>Stored {}. Downloads: \
         <a href=\"/experiments/{id}/case.toml\" download>case.toml</a> · \
         <a href=\"/experiments/{id}/data.csv\" download>data.csv</a></p><h2>Measured data</h2>",
        esc(&e.name),
        esc(&e.fluid),
        esc(&utc(e.created))
    );
    match figures {
        Ok(figs) => {
            for (label, svg) in figs {
                let _ = write!(s, "<figure><h3>{}</h3>", esc(&label));
                match svg {
                    Ok(svg) => s.push_str(&svg),
                    Err(why) => {
                        let _ = write!(s, "<p class=\"note\">Not drawn: {}</p>", esc(&why));
                    }
                }
                s.push_str("</figure>");
            }
        }
        Err(why) => {
            let _ = write!(s, "<p class=\"note\">The data cannot be read: {}</p>", esc(&why));
        }
    }
    let _ = write!(s, "<h2>Case</h2><pre>{}</pre>", esc(&e.case));
    Html(page(&e.name, &s, false, secured(&state))).into_response()
}

async fn experiment_data(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    match db::experiment(state.coordinator.db().reader(), id).await {
        Ok(e) => download(&format!("experiment-{id}-data.csv"), csv_response(e.data)),
        Err(x) => db_error(&state, x),
    }
}

async fn experiment_case(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    match db::experiment(state.coordinator.db().reader(), id).await {
        Ok(e) => download(
            &format!("experiment-{id}-case.toml"),
            ([(header::CONTENT_TYPE, "application/toml; charset=utf-8")], e.case).into_response(),
        ),
        Err(x) => db_error(&state, x),
    }
}

// ---------------------------------------------------------------------------------------------
// workers

/// Window of the throughput column, s.
const THROUGHPUT_WINDOW_S: i64 = 60;

async fn workers_page(State(state): State<AppState>) -> Response {
    let pool = state.coordinator.db().reader();
    let now = db::now_ms();
    let (workers, recent) =
        match (db::workers(pool).await, db::results_per_worker_since(pool, now - THROUGHPUT_WINDOW_S * 1000).await) {
            (Ok(w), Ok(r)) => (w, r),
            (Err(e), _) | (_, Err(e)) => return db_error(&state, e),
        };
    let mut s = String::from("<h1>Workers</h1>");
    if workers.is_empty() {
        s.push_str(
            "<p>No worker has claimed a job yet: start one with <code>cryofit work --coordinator URL</code>.</p>",
        );
    } else {
        let _ = write!(
            s,
            "<table><tr><th>worker</th><th>slots</th><th>last heartbeat</th><th>results reported</th>\
             <th>throughput (results/min, last {THROUGHPUT_WINDOW_S} s)</th></tr>"
        );
        for w in &workers {
            let n = recent.get(&w.name).copied().unwrap_or(0);
            let per_min = n as f64 * 60.0 / THROUGHPUT_WINDOW_S as f64;
            let _ = write!(
                s,
                "<tr><td>{}</td><td class=\"num\">{}</td><td>{} ({})</td><td class=\"num\">{}</td><td class=\"num\">{}</td></tr>",
                esc(&w.name),
                w.slots,
                esc(&utc(w.last_heartbeat)),
                esc(&ago(w.last_heartbeat)),
                w.evaluations,
                num(per_min)
            );
        }
        s.push_str("</table>");
    }
    let busy = workers.iter().any(|w| now - w.last_heartbeat < THROUGHPUT_WINDOW_S * 1000);
    Html(page("Workers", &s, busy, secured(&state))).into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_in_goes_only_to_local_paths() {
        assert_eq!(local_path(Some("//evil.example")), "/");
        assert_eq!(local_path(Some("/calibrations/3")), "/calibrations/3");
        assert_eq!(local_path(None), "/");
        // browsers drop TAB, CR and LF from URLs: `/\t/evil.example` would become `//evil.example`
        assert_eq!(local_path(Some("/\t/evil.example")), "/");
        assert_eq!(local_path(Some("/\n/evil.example")), "/");
        assert_eq!(local_path(Some("/ /evil.example")), "/");
        assert_eq!(local_path(Some("/\\evil.example")), "/");
        assert_eq!(local_path(Some("/\u{0}x")), "/");
    }

    #[test]
    fn session_ids_are_stored_as_digests() {
        let id = hex(&[0xab; 32]);
        assert_eq!(id.len(), 64);
        assert_eq!(digest(&id).len(), 64);
        assert_ne!(digest(&id), id);
        // SHA-256 of "abc"
        assert_eq!(digest("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }
}
