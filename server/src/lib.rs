//! The cryofit coordinator: REST routes (axum), SQLite storage (sqlx), the optimiser driver and
//! job leases (DESIGN.md §3.4–3.5), and the dashboard ([`dashboard`]) with a calibration's figures
//! ([`figures`]).
//!
//! [`launch`] serves on a bound listener until a shutdown future resolves, so tests bind
//! `127.0.0.1:0`; [`start_embedded`] runs a coordinator on a loopback port in the background of
//! the current tokio runtime (for `cryofit calibrate` and benchmarks).

#![warn(missing_docs)]

mod clock;
pub mod coordinator;
pub mod dashboard;
pub mod db;
pub mod figures;
pub mod limits;
pub mod lock;
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

/// The tables built into the binary, hashed; each copied out once and shared afterwards.
pub fn embedded_fluids() -> FluidLoader {
    let loaded: std::sync::Mutex<std::collections::HashMap<&'static str, (Arc<FluidTable>, String)>> =
        Default::default();
    Arc::new(move |name: &str| {
        let canon = cryofit_solver::fluids::canonical_name(name).ok_or_else(|| format!("unknown fluid `{name}`"))?;
        let mut map = loaded.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((t, h)) = map.get(canon) {
            return Ok((t.clone(), h.clone()));
        }
        let table = cryofit_solver::fluids::embedded(canon).map_err(|e| e.to_string())?;
        let bytes = cryofit_solver::fluids::embedded_bytes(canon).ok_or_else(|| format!("unknown fluid `{name}`"))?;
        let v = (Arc::new(table.clone()), cryofit_api::fluid_hash(bytes));
        map.insert(canon, v.clone());
        Ok(v)
    })
}

/// A secret that never shows in `Debug` output ([`secrecy::SecretString`]), compared in constant
/// time ([`subtle`]).
#[derive(Clone)]
pub struct Secret(secrecy::SecretString);

impl Secret {
    /// Wraps a secret.
    pub fn new(s: impl Into<String>) -> Self {
        Self(secrecy::SecretString::from(s.into()))
    }

    /// Compares in time independent of where the first difference is.
    pub fn matches(&self, other: &str) -> bool {
        use secrecy::ExposeSecret as _;
        use subtle::ConstantTimeEq as _;
        self.0.expose_secret().as_bytes().ct_eq(other.as_bytes()).into()
    }

    /// True when both hold the same secret.
    pub fn same_as(&self, other: &Secret) -> bool {
        use secrecy::ExposeSecret as _;
        self.matches(other.0.expose_secret())
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
    /// Ceilings on what one request can size.
    pub limits: limits::Limits,
    /// Mark the dashboard's session cookie `Secure` (served behind TLS).
    pub secure_cookies: bool,
    /// How long a dashboard session lasts after signing in.
    pub session_ttl: Duration,
    /// How long the database lock lasts without renewal (another coordinator may take over a
    /// lock older than this whose holder it cannot see).
    pub lock_ttl: Duration,
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
            .field("limits", &self.limits)
            .field("secure_cookies", &self.secure_cookies)
            .field("session_ttl", &self.session_ttl)
            .field("lock_ttl", &self.lock_ttl)
            .finish_non_exhaustive()
    }
}

/// Default body limit: 16 MiB.
pub const DEFAULT_BODY_LIMIT: usize = 16 * 1024 * 1024;

/// Default lifetime of a dashboard session: 12 hours.
pub const DEFAULT_SESSION_TTL: Duration = Duration::from_secs(12 * 3600);

/// Default lifetime of the database lock without renewal: 15 s (renewed every 3 s).
pub const DEFAULT_LOCK_TTL: Duration = Duration::from_secs(15);

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
            limits: limits::Limits::default(),
            secure_cookies: false,
            session_ttl: DEFAULT_SESSION_TTL,
            lock_ttl: DEFAULT_LOCK_TTL,
        }
    }

    /// Checks settings that depend on each other: the two tokens must differ (a worker token
    /// that is also the client token would let every worker submit and cancel).
    pub fn check(&self) -> Result<(), ServerError> {
        if let (Some(c), Some(w)) = (&self.client_token, &self.worker_token)
            && c.same_as(w)
        {
            return Err(ServerError::Config(
                "CRYOFIT_CLIENT_TOKEN and CRYOFIT_WORKER_TOKEN are the same: give each role its own token \
                 (openssl rand -hex 32)"
                    .into(),
            ));
        }
        Ok(())
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
        s.check()?;
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
    /// The database is served by another coordinator or cannot be written.
    #[error("database: {0}")]
    Lock(#[from] lock::LockError),
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
    lock: Arc<lock::DbLock>,
}

/// Opens the database, takes its lock for a coordinator listening on `address` (refusing a
/// database that another coordinator serves or that cannot be written), resumes running
/// calibrations and builds the state of the routes.
pub async fn build_state(settings: Settings, address: &str) -> Result<AppState, ServerError> {
    settings.check()?;
    let db = db::Db::open(&settings.database_url).await?;
    let lock = match lock::DbLock::acquire(&db, address, settings.lock_ttl).await {
        Ok(l) => l,
        Err(e) => {
            db.close().await;
            return Err(ServerError::Lock(e));
        }
    };
    let metrics = Arc::new(metrics::Metrics::default());
    let coordinator = Arc::new(Coordinator::load(db, settings.coordinator.clone(), metrics.clone()).await?);
    Ok(AppState { coordinator, settings: Arc::new(settings), metrics, figures: Arc::default(), lock: Arc::new(lock) })
}

/// Serves the coordinator on `listener` until `shutdown` resolves, with the reaper running.
///
/// Refuses to start on a non-loopback address without both tokens, with two equal tokens, on a
/// database another coordinator serves, or on one it cannot write.
pub async fn launch(
    listener: tokio::net::TcpListener,
    settings: Settings,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServerError> {
    launch_with_ready(listener, settings, shutdown, |_| {}).await
}

/// [`launch`], calling `ready` with the address once the database is open and locked, just
/// before requests are answered.
pub async fn launch_with_ready(
    listener: tokio::net::TcpListener,
    settings: Settings,
    shutdown: impl Future<Output = ()> + Send + 'static,
    ready: impl FnOnce(SocketAddr) + Send,
) -> Result<(), ServerError> {
    let addr = listener.local_addr()?;
    if !addr.ip().is_loopback() && (settings.client_token.is_none() || settings.worker_token.is_none()) {
        return Err(ServerError::Config(format!(
            "refusing to serve on {addr} without tokens: set CRYOFIT_CLIENT_TOKEN and CRYOFIT_WORKER_TOKEN, or bind \
             a loopback address (127.0.0.1)"
        )));
    }
    let state = build_state(settings, &addr.to_string()).await?;
    ready(addr);
    serve(listener, state, shutdown).await
}

/// Serves `state` until `shutdown` resolves or the database lock is lost, with the reaper and
/// the lock's renewal running; then releases the lock and closes the database.
async fn serve(
    listener: tokio::net::TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> Result<(), ServerError> {
    let addr = listener.local_addr()?;
    let interval = state.settings.reaper_interval;
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
    // the lock's renewal; losing the lock to another coordinator stops this one
    let (lost_tx, lost_rx) = tokio::sync::oneshot::channel::<String>();
    let (lock, db) = (state.lock.clone(), state.coordinator.db().clone());
    let mut stop_renewal = stop_tx.subscribe();
    let renewal = tokio::spawn(async move {
        let mut tick = tokio::time::interval(lock.renew_every());
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = tick.tick() => match lock.renew(&db).await {
                    Ok(()) => {}
                    Err(e) if e.starts_with("another coordinator") => {
                        tracing::error!(error = %e, "stopping");
                        let _ = lost_tx.send(e);
                        break;
                    }
                    Err(e) => tracing::error!(error = %e, "renewing the database lock"),
                },
                _ = stop_renewal.changed() => break,
            }
        }
    });
    tracing::info!(%addr, "coordinator listening");
    let app = router(state.clone());
    let lost = Arc::new(std::sync::Mutex::new(None::<String>));
    let lost_reason = lost.clone();
    let stop = async move {
        tokio::select! {
            _ = shutdown => {}
            r = lost_rx => {
                if let Ok(r) = r && let Ok(mut l) = lost_reason.lock() {
                    *l = Some(r);
                }
            }
        }
    };
    let served = axum::serve(listener, app).with_graceful_shutdown(stop).await;
    let _ = stop_tx.send(true);
    let _ = reaper.await;
    let _ = renewal.await;
    let lost = lost.lock().ok().and_then(|mut l| l.take());
    if lost.is_none() {
        state.lock.release(state.coordinator.db()).await;
    }
    state.coordinator.db().close().await;
    served?;
    match lost {
        Some(reason) => Err(ServerError::Config(format!("stopped: {reason}"))),
        None => Ok(()),
    }
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
    // open and lock here so that errors (a bad path, a failed migration, a database another
    // coordinator serves) surface before returning
    let state = build_state(settings, &addr.to_string()).await?;
    let db = state.coordinator.db().clone();
    let released = async {
        let mut tx = db.begin().await?;
        let n = db::release_leases(&mut tx).await?;
        db.commit(tx).await?;
        Ok::<_, db::DbError>(n)
    }
    .await;
    let released = match released {
        Ok(n) => n,
        Err(e) => {
            state.lock.release(&db).await;
            db.close().await;
            return Err(e.into());
        }
    };
    if released > 0 {
        tracing::info!(jobs = released, "released the leases of an earlier process");
    }
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let handle = tokio::spawn(serve(listener, state, async move {
        let _ = rx.await;
    }));
    Ok(Embedded { addr, stop: Some(tx), handle })
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::body::Body;
    use axum::http::{Request, StatusCode};
    use tower::ServiceExt as _;

    fn scratch(tag: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("cryofit-lib-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    async fn health(app: &axum::Router) -> (StatusCode, String) {
        let r =
            app.clone().oneshot(Request::get("/healthz").body(Body::empty()).expect("request")).await.expect("answer");
        let status = r.status();
        let body = axum::body::to_bytes(r.into_body(), 1 << 20).await.expect("body");
        (status, String::from_utf8_lossy(&body).into_owned())
    }

    #[tokio::test]
    async fn healthz_answers_503_while_the_database_cannot_be_written() {
        let dir = scratch("health");
        let state = build_state(Settings::new(dir.join("c.db").display().to_string()), "test").await.expect("state");
        let app = router(state.clone());
        assert_eq!(health(&app).await.0, StatusCode::OK);
        let writer = state.coordinator.db().writer();
        sqlx::query("PRAGMA query_only = ON").execute(writer).await.expect("pragma");
        let (status, body) = health(&app).await;
        assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "{body}");
        assert!(body.contains("\"unhealthy\"") && body.contains("cannot be written"), "{body}");
        sqlx::query("PRAGMA query_only = OFF").execute(writer).await.expect("pragma");
        assert_eq!(health(&app).await.0, StatusCode::OK, "healthy again once writes work");
        state.coordinator.db().close().await;
        let _ = std::fs::remove_dir_all(dir);
    }

    #[tokio::test]
    async fn a_database_that_cannot_be_written_is_refused_at_start() {
        let dir = scratch("readonly");
        let path = dir.join("c.db");
        let state = build_state(Settings::new(path.display().to_string()), "first").await.expect("state");
        state.lock.release(state.coordinator.db()).await;
        state.coordinator.db().close().await;
        let e = build_state(Settings::new(format!("sqlite://{}?mode=ro", path.display())), "second")
            .await
            .expect_err("a read-only database is refused");
        assert!(e.to_string().contains("cannot be written"), "{e}");
        let _ = std::fs::remove_dir_all(dir);
    }

    #[test]
    fn identical_client_and_worker_tokens_are_refused() {
        let mut s = Settings::new("x.db");
        s.client_token = Some(Secret::new("same"));
        s.worker_token = Some(Secret::new("same"));
        assert!(s.check().unwrap_err().to_string().contains("are the same"));
        s.worker_token = Some(Secret::new("other"));
        assert!(s.check().is_ok());
        assert_eq!(format!("{:?}", s.client_token), "Some(Secret(***))");
    }
}
