//! `/workers`: the workers with their last heartbeat and throughput.

use std::fmt::Write as _;

use axum::extract::State;
use axum::response::{Html, IntoResponse, Response};
use cryofit_plots::escape_html as esc;

use super::session::secured;
use super::{ago, db_error, num, page};
use crate::clock::{now_ms, utc};
use crate::db;
use crate::state::AppState;

/// Window of the throughput column, s.
const THROUGHPUT_WINDOW_S: i64 = 60;

pub(super) async fn workers_page(State(state): State<AppState>) -> Response {
    let pool = state.coordinator.db().reader();
    let now = now_ms();
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
