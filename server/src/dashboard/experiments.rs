//! The experiment pages: `/experiments`, `/experiments/{id}` with its measured data drawn, and
//! the case and data downloads.

use std::fmt::Write as _;

use axum::extract::{Path, State};
use axum::http::{StatusCode, header};
use axum::response::{Html, IntoResponse, Response};
use cryofit_api as api;
use cryofit_plots::{Plot, escape_html as esc};

use super::session::secured;
use super::{db_error, download, error_page, page};
use crate::clock::utc;
use crate::db;
use crate::routes::csv;
use crate::state::AppState;

pub(super) async fn experiments_page(State(state): State<AppState>) -> Response {
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

pub(super) async fn experiment_page(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
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

pub(super) async fn experiment_data(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    match db::experiment(state.coordinator.db().reader(), id).await {
        Ok(e) => download(&format!("experiment-{id}-data.csv"), csv::response(e.data)),
        Err(x) => db_error(&state, x),
    }
}

pub(super) async fn experiment_case(State(state): State<AppState>, Path(id): Path<i64>) -> Response {
    match db::experiment(state.coordinator.db().reader(), id).await {
        Ok(e) => download(
            &format!("experiment-{id}-case.toml"),
            ([(header::CONTENT_TYPE, "application/toml; charset=utf-8")], e.case).into_response(),
        ),
        Err(x) => db_error(&state, x),
    }
}
