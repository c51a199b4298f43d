//! The calibration pages: `/` (the list, or the sign-in form), `/calibrations/{id}` with its
//! figures, each figure as SVG or PNG, and the CSV downloads.

use std::fmt::Write as _;
use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use cryofit_api as api;
use cryofit_plots::{Plot, escape_html as esc};

use super::session::{secured, sign_in_form, signed_in};
use super::{api_error, db_error, download, error_page, num, page, status_badge};
use crate::clock::utc;
use crate::db;
use crate::figure_cache::{DrawError, Drawn};
use crate::figures::{CalibrationData, FigureOptions};
use crate::routes::{calibration_view, csv};
use crate::state::AppState;

/// Posterior draws simulated for the bands of a finished calibration's page.
const DASHBOARD_BAND_DRAWS: usize = 8;

pub(super) async fn home(State(state): State<AppState>, headers: HeaderMap) -> Response {
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

/// The figures of a calibration, drawn or from the cache.
async fn drawn(state: &AppState, data: CalibrationData) -> Result<Arc<Drawn>, Response> {
    let opts = FigureOptions {
        band_draws: if data.calibration.status == api::CalibrationStatus::Completed { DASHBOARD_BAND_DRAWS } else { 0 },
        seed: 0,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        end_at_data: true,
    };
    state.figures.drawn(data, &state.settings.fluids, opts, &state.metrics).await.map_err(|e| match e {
        DrawError::Unavailable(m) => error_page(state, StatusCode::SERVICE_UNAVAILABLE, &m),
        e @ DrawError::Failed(_) => error_page(state, StatusCode::INTERNAL_SERVER_ERROR, &e.to_string()),
    })
}

pub(super) async fn calibration_page(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
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
            let unit = match cryofit_calib::apparatus::case_name(k) {
                Some(field) => Some(cryofit_solver::case::field_unit(field.path)),
                None => cryofit_solver::params::spec(k).map(|s| s.unit),
            };
            let unit = unit.map_or("", |u| if u == "-" { "dimensionless" } else { u });
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

pub(super) async fn figure_file(State(state): State<AppState>, Path((id, file)): Path<(i64, String)>) -> Response {
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

pub(super) async fn parameter_sets_download(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    let pool = state.coordinator.db().reader();
    if let Err(e) = db::calibration(pool, id).await {
        return db_error(&state, e);
    }
    match db::all_parameter_sets(pool, id).await {
        Ok(items) => match csv::parameter_sets(&items) {
            Ok(text) => download(&format!("calibration-{id}-parameter-sets.csv"), csv::response(text)),
            Err(e) => api_error(&state, e),
        },
        Err(e) => db_error(&state, e),
    }
}

pub(super) async fn results_download(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    let pool = state.coordinator.db().reader();
    if let Err(e) = db::calibration(pool, id).await {
        return db_error(&state, e);
    }
    match db::all_results(pool, id).await {
        Ok(items) => match csv::results(&items) {
            Ok(text) => download(&format!("calibration-{id}-results.csv"), csv::response(text)),
            Err(e) => api_error(&state, e),
        },
        Err(e) => db_error(&state, e),
    }
}
