//! Starting and stopping a coordinator: [`build_state`] opens and locks the database and loads the
//! running calibrations, [`router`] assembles the routes and the dashboard with the security
//! headers and request traces, [`launch`] serves them with the reaper and the lock's renewal,
//! [`start_embedded`] runs one in the background.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;

use axum::Router;
use axum::http::{HeaderValue, header};
use tower_http::set_header::SetResponseHeaderLayer;

use crate::config::{ConfigError, Settings};
use crate::coordinator::Coordinator;
use crate::state::AppState;
use crate::{dashboard, db, lock, metrics, routes, telemetry};

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

impl From<ConfigError> for ServerError {
    fn from(e: ConfigError) -> Self {
        Self::Config(e.0)
    }
}

/// The full router: `/healthz`, `/metrics`, the dashboard (`/` and its pages) and everything under
/// `/api/v1`.
pub fn router(state: AppState) -> Router {
    let app = routes::router(&state)
        .merge(dashboard::router(state.clone()))
        .fallback(routes::error::not_found)
        .method_not_allowed_fallback(routes::error::method_not_allowed);
    with_security_headers(app).layer(telemetry::http_trace()).with_state(state)
}

/// The Content-Security-Policy of every answer: the dashboard's own script and style sheet
/// only, inline SVG figures, no framing, forms posting only to this origin.
pub const CONTENT_SECURITY_POLICY: &str = "default-src 'none'; script-src 'self'; style-src 'self' 'unsafe-inline'; \
     img-src 'self' data:; connect-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'";

/// Security headers on every answer (dashboard pages, API, errors): CSP, no framing, no MIME
/// sniffing, no referrer.
fn with_security_headers(r: Router<AppState>) -> Router<AppState> {
    let set = |name, value: &'static str| SetResponseHeaderLayer::overriding(name, HeaderValue::from_static(value));
    r.layer(set(header::CONTENT_SECURITY_POLICY, CONTENT_SECURITY_POLICY))
        .layer(set(header::X_FRAME_OPTIONS, "DENY"))
        .layer(set(header::X_CONTENT_TYPE_OPTIONS, "nosniff"))
        .layer(set(header::REFERRER_POLICY, "no-referrer"))
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
}
