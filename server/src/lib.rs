//! The cryofit coordinator: REST routes (axum), SQLite storage (sqlx), the optimiser driver and
//! job leases (DESIGN.md §3.4–3.5), and the dashboard ([`dashboard`]) with a calibration's figures
//! ([`figures`]).
//!
//! [`launch`] serves on a bound listener until a shutdown future resolves, so tests bind
//! `127.0.0.1:0`; [`start_embedded`] runs a coordinator on a loopback port in the background of
//! the current tokio runtime (for `cryofit calibrate` and benchmarks).

#![warn(missing_docs)]

pub mod coordinator;
pub mod dashboard;
pub mod db;
pub mod figures;
pub mod metrics;
mod openapi;
mod routes;
mod validate;

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use cryofit_solver::fluids::FluidTable;

pub use coordinator::{Coordinator, CoordinatorSettings};
pub use routes::router;

/// Loads a fluid table by name and returns it with [`cryofit_api::fluid_hash`] of its bytes.
pub type FluidLoader = Arc<dyn Fn(&str) -> Result<(Arc<FluidTable>, String), String> + Send + Sync>;

/// The tables built into the binary, hashed.
pub fn embedded_fluids() -> FluidLoader {
    Arc::new(|name: &str| {
        let table = cryofit_solver::fluids::embedded(name).map_err(|e| e.to_string())?;
        let bytes = cryofit_solver::fluids::embedded_bytes(name).ok_or_else(|| format!("unknown fluid `{name}`"))?;
        Ok((Arc::new(table.clone()), cryofit_api::fluid_hash(bytes)))
    })
}

/// A secret that never shows in `Debug` output.
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(String);

impl Secret {
    /// Wraps a secret.
    pub fn new(s: impl Into<String>) -> Self {
        Self(s.into())
    }

    /// Compares in time independent of where the first difference is.
    pub fn matches(&self, other: &str) -> bool {
        let (a, b) = (self.0.as_bytes(), other.as_bytes());
        let mut diff = a.len() ^ b.len();
        for (i, x) in a.iter().enumerate() {
            diff |= usize::from(x ^ b.get(i).copied().unwrap_or(0));
        }
        diff == 0
    }
}

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(***)")
    }
}

/// The coordinator's settings.
#[derive(Clone)]
pub struct Settings {
    /// SQLite database: `sqlite://PATH` or a path; created if absent.
    pub database_url: String,
    /// Token of clients (submit, read, cancel).
    pub client_token: Option<Secret>,
    /// Token of workers (claim, heartbeat, result, read experiments).
    pub worker_token: Option<Secret>,
    /// Largest request body, bytes.
    pub body_limit: usize,
    /// Driver and lease settings.
    pub coordinator: CoordinatorSettings,
    /// How often the reaper looks for expired leases.
    pub reaper_interval: Duration,
    /// Fluid tables (for validating experiments and recording table hashes).
    pub fluids: FluidLoader,
}

impl std::fmt::Debug for Settings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Settings")
            .field("database_url", &self.database_url)
            .field("client_token", &self.client_token)
            .field("worker_token", &self.worker_token)
            .field("body_limit", &self.body_limit)
            .field("coordinator", &self.coordinator)
            .field("reaper_interval", &self.reaper_interval)
            .finish_non_exhaustive()
    }
}

/// Default body limit: 16 MiB.
pub const DEFAULT_BODY_LIMIT: usize = 16 * 1024 * 1024;

impl Settings {
    /// Defaults for a database, with the embedded fluid tables and no tokens.
    pub fn new(database_url: impl Into<String>) -> Self {
        Self {
            database_url: database_url.into(),
            client_token: None,
            worker_token: None,
            body_limit: DEFAULT_BODY_LIMIT,
            coordinator: CoordinatorSettings::default(),
            reaper_interval: Duration::from_secs(1),
            fluids: embedded_fluids(),
        }
    }

    /// Layers the environment over [`Settings::new`]: `CRYOFIT_CLIENT_TOKEN`,
    /// `CRYOFIT_WORKER_TOKEN`, `CRYOFIT_LEASE_S` (lease length, s), `CRYOFIT_MAX_ATTEMPTS`,
    /// `CRYOFIT_BODY_LIMIT` (bytes). Errors name the variable.
    pub fn from_env(database_url: impl Into<String>) -> Result<Self, ServerError> {
        let mut s = Self::new(database_url);
        let var = |name: &str| std::env::var(name).ok().filter(|v| !v.trim().is_empty());
        s.client_token = var("CRYOFIT_CLIENT_TOKEN").map(Secret::new);
        s.worker_token = var("CRYOFIT_WORKER_TOKEN").map(Secret::new);
        if let Some(v) = var("CRYOFIT_LEASE_S") {
            let secs: f64 = v
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite() && *x > 0.0 && *x < 86_400.0)
                .ok_or_else(|| ServerError::Config(format!("CRYOFIT_LEASE_S = {v}: give seconds in (0, 86400)")))?;
            s.coordinator.lease = Duration::from_secs_f64(secs);
            s.reaper_interval = Duration::from_secs_f64((secs / 4.0).clamp(0.05, 1.0));
        }
        if let Some(v) = var("CRYOFIT_MAX_ATTEMPTS") {
            s.coordinator.max_attempts = v
                .parse()
                .ok()
                .filter(|x| *x >= 1)
                .ok_or_else(|| ServerError::Config(format!("CRYOFIT_MAX_ATTEMPTS = {v}: give an integer ≥ 1")))?;
        }
        if let Some(v) = var("CRYOFIT_BODY_LIMIT") {
            s.body_limit = v
                .parse()
                .ok()
                .filter(|x| *x >= 1024)
                .ok_or_else(|| ServerError::Config(format!("CRYOFIT_BODY_LIMIT = {v}: give bytes ≥ 1024")))?;
        }
        Ok(s)
    }
}

/// Why the coordinator could not start or stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServerError {
    /// A setting is wrong.
    #[error("{0}")]
    Config(String),
    /// The database could not be opened or migrated.
    #[error(transparent)]
    Db(#[from] db::DbError),
    /// Serving failed.
    #[error("serving: {0}")]
    Io(#[from] std::io::Error),
}

/// Shared state of the routes.
#[derive(Clone, Debug)]
pub struct AppState {
    coordinator: Arc<Coordinator>,
    settings: Arc<Settings>,
    metrics: Arc<metrics::Metrics>,
    figures: Arc<dashboard::FigureCache>,
}

/// Opens the database, resumes running calibrations and builds the state of the routes.
pub async fn build_state(settings: Settings) -> Result<AppState, ServerError> {
    let db = db::Db::open(&settings.database_url).await?;
    let metrics = Arc::new(metrics::Metrics::default());
    let coordinator = Arc::new(Coordinator::load(db, settings.coordinator.clone(), metrics.clone()).await?);
    Ok(AppState { coordinator, settings: Arc::new(settings), metrics, figures: Arc::default() })
}

/// Serves the coordinator on `listener` until `shutdown` resolves, with the reaper running.
///
/// Refuses to start on a non-loopback address without both tokens.
pub async fn launch(
    listener: tokio::net::TcpListener,
    settings: Settings,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServerError> {
    let addr = listener.local_addr()?;
    if !addr.ip().is_loopback() && (settings.client_token.is_none() || settings.worker_token.is_none()) {
        return Err(ServerError::Config(format!(
            "refusing to serve on {addr} without tokens: set CRYOFIT_CLIENT_TOKEN and CRYOFIT_WORKER_TOKEN, or bind \
             a loopback address (127.0.0.1)"
        )));
    }
    let interval = settings.reaper_interval;
    let state = build_state(settings).await?;
    let (stop_tx, mut stop_rx) = tokio::sync::watch::channel(false);
    let coordinator = state.coordinator.clone();
    let reaper = tokio::spawn(async move {
        let mut tick = tokio::time::interval(interval);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = tick.tick() => {
                    if let Err(e) = coordinator.reap().await {
                        tracing::error!(error = %e, "reaper");
                    }
                }
                _ = stop_rx.changed() => break,
            }
        }
    });
    tracing::info!(%addr, "coordinator listening");
    let app = router(state.clone());
    let served = axum::serve(listener, app).with_graceful_shutdown(shutdown).await;
    let _ = stop_tx.send(true);
    let _ = reaper.await;
    state.coordinator.db().close().await;
    served?;
    Ok(())
}

/// A coordinator running in the background on a loopback port.
#[derive(Debug)]
pub struct Embedded {
    /// Where it listens.
    pub addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    handle: tokio::task::JoinHandle<Result<(), ServerError>>,
}

impl Embedded {
    /// Base URL, `http://127.0.0.1:PORT`.
    pub fn url(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// Stops it and waits until it has closed the database.
    pub async fn stop(mut self) -> Result<(), ServerError> {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        self.handle.await.map_err(|e| ServerError::Config(format!("coordinator task: {e}")))?
    }
}

/// Starts a coordinator on `127.0.0.1` (a free port) with its SQLite database at `database`,
/// without tokens (loopback only), in the current tokio runtime.
///
/// The database is taken to be private to this process (the caller makes sure no other
/// coordinator serves it): jobs still leased by an earlier, ended process are put back in the
/// queue at once instead of waiting for their leases to expire.
pub async fn start_embedded(database: &std::path::Path, mut settings: Settings) -> Result<Embedded, ServerError> {
    settings.database_url = format!("sqlite://{}", database.display());
    settings.client_token = None;
    settings.worker_token = None;
    let listener = tokio::net::TcpListener::bind(("127.0.0.1", 0)).await?;
    let addr = listener.local_addr()?;
    // open once here so that errors (a bad path, a failed migration) surface before returning
    let db = db::Db::open(&settings.database_url).await?;
    let released = async {
        let mut tx = db.begin().await?;
        let n = db::release_leases(&mut tx).await?;
        tx.commit().await.map_err(db::DbError::from)?;
        Ok::<_, db::DbError>(n)
    }
    .await;
    db.close().await;
    let released = released?;
    if released > 0 {
        tracing::info!(jobs = released, "released the leases of an earlier process");
    }
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let handle = tokio::spawn(launch(listener, settings, async move {
        let _ = rx.await;
    }));
    Ok(Embedded { addr, stop: Some(tx), handle })
}
