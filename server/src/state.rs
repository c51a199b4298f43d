//! The state every route shares.

use std::sync::Arc;

use crate::config::Settings;
use crate::coordinator::Coordinator;
use crate::figure_cache::FigureCache;
use crate::lock::DbLock;
use crate::metrics::Metrics;

/// Shared state of the routes.
#[derive(Clone, Debug)]
pub struct AppState {
    pub(crate) coordinator: Arc<Coordinator>,
    pub(crate) settings: Arc<Settings>,
    pub(crate) metrics: Arc<Metrics>,
    pub(crate) figures: Arc<FigureCache>,
    pub(crate) lock: Arc<DbLock>,
}
