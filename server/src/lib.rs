//! The cryofit coordinator: REST routes (axum), SQLite storage (sqlx), the optimiser driver and
//! job leases (DESIGN.md §3.4–3.5), and the dashboard ([`dashboard`]) with a calibration's figures
//! ([`figures`]).
//!
//! [`launch`] serves on a bound listener until a shutdown future resolves, so tests bind
//! `127.0.0.1:0`; [`start_embedded`] runs a coordinator on a loopback port in the background of
//! the current tokio runtime (for `cryofit calibrate` and benchmarks). [`config`] turns the flags
//! and environment of `cryofit serve` into [`Settings`]; [`telemetry`] sets up logging.
//!
//! This file only declares the modules; no module depends on a module that depends on it.

#![warn(missing_docs)]

mod app;
mod clock;
pub mod config;
pub mod coordinator;
pub mod dashboard;
pub mod db;
mod figure_cache;
pub mod figures;
mod fluids;
mod invalid;
pub mod limits;
pub mod lock;
pub mod metrics;
mod routes;
mod state;
pub mod telemetry;
mod validate;

pub use app::{
    CONTENT_SECURITY_POLICY, Embedded, ServerError, build_state, launch, launch_with_ready, router, start_embedded,
};
pub use config::{DEFAULT_BODY_LIMIT, DEFAULT_LOCK_TTL, DEFAULT_SESSION_TTL, Secret, ServeArgs, Settings};
pub use coordinator::{Coordinator, CoordinatorSettings};
pub use fluids::{FluidLoader, embedded_fluids};
pub use state::AppState;
