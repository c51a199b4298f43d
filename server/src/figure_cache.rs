//! The dashboard's drawn figures: a calibration's figures are drawn on the blocking pool, at most
//! one drawing per calibration at a time (later viewers wait for it and take its result) and two
//! over all calibrations, and kept until the calibration changes.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use cryofit_plots::Figure;

use crate::figures::{self, CalibrationData, FigureOptions};
use crate::fluids::FluidLoader;
use crate::metrics::Metrics;

/// Figure drawings that run at once, over all calibrations (each uses every core for its
/// posterior-predictive runs).
static FIGURE_BUILDS: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(2);

/// Calibrations whose figures are kept.
const CACHED_CALIBRATIONS: usize = 16;

/// Figures drawn for a calibration at one state of it (status, evaluations, last update): each
/// figure with its SVG, or why it could not be drawn.
#[derive(Debug)]
pub struct Drawn {
    key: String,
    at: Instant,
    /// The figures.
    pub figures: Vec<(Figure, Result<String, String>)>,
}

/// The figures of recently viewed calibrations, redrawn when the calibration has changed, and
/// the drawings under way (one per calibration).
#[derive(Debug, Default)]
pub struct FigureCache {
    map: Mutex<HashMap<i64, Arc<Drawn>>>,
    building: Mutex<HashMap<i64, Arc<tokio::sync::Mutex<()>>>>,
}

/// Why the figures were not drawn.
#[derive(Debug, thiserror::Error)]
pub enum DrawError {
    /// No drawing slot can be had.
    #[error("{0}")]
    Unavailable(String),
    /// The drawing failed.
    #[error("drawing the figures: {0}")]
    Failed(String),
}

impl FigureCache {
    /// The figures of a calibration, from the cache when it has not changed since they were
    /// drawn. A viewer that finds a drawing of the same calibration under way waits for it and
    /// takes its figures.
    pub async fn drawn(
        &self,
        data: CalibrationData,
        fluids: &FluidLoader,
        opts: FigureOptions,
        metrics: &Metrics,
    ) -> Result<Arc<Drawn>, DrawError> {
        let c = &data.calibration;
        let key = format!("{}:{}:{}:{}", c.status.as_str(), c.evaluations, c.failed_evaluations, c.updated);
        let id = c.id;
        let fresh = |since: Option<Instant>| {
            let map = self.map.lock().ok()?;
            let d = map.get(&id)?;
            (d.key == key || since.is_some_and(|t| d.at >= t)).then(|| d.clone())
        };
        if let Some(d) = fresh(None) {
            return Ok(d);
        }
        let gate = {
            let mut b = self.building.lock().unwrap_or_else(PoisonError::into_inner);
            b.entry(id).or_default().clone()
        };
        let waiting_since = Instant::now();
        let _turn = gate.lock().await;
        // a drawing that finished while this viewer waited is as new as this viewer's data
        if let Some(d) = fresh(Some(waiting_since)) {
            return Ok(d);
        }
        // and at most two drawings at once over all calibrations
        let _slot = FIGURE_BUILDS.acquire().await.map_err(|e| DrawError::Unavailable(e.to_string()))?;
        metrics.figures_built();
        let fluids = fluids.clone();
        let done = tokio::task::spawn_blocking(move || {
            let figures = figures::figures(&data, &fluids, &opts)
                .into_iter()
                .map(|f| {
                    let svg = match &f.plot {
                        Ok(p) => p.svg().map_err(|e| e.to_string()),
                        Err(why) => Err(why.clone()),
                    };
                    (f, svg)
                })
                .collect();
            Drawn { key, at: Instant::now(), figures }
        })
        .await
        .map_err(|e| DrawError::Failed(e.to_string()))?;
        let done = Arc::new(done);
        if let Ok(mut map) = self.map.lock() {
            if map.len() >= CACHED_CALIBRATIONS && !map.contains_key(&id) {
                map.clear();
            }
            map.insert(id, done.clone());
        }
        Ok(done)
    }
}
