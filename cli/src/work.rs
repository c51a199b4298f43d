//! `cryofit work --coordinator URL [--slots N] [--exit-when-idle SECS] [--drain-timeout SECS]
//! [--cache-mb MIB]`: runs a worker.

use std::time::Duration;

use anyhow::{Context, Result, bail};
use clap::Args;
use cryofit_worker::{Client, WorkerSettings};

/// Arguments of `cryofit work`.
#[derive(Debug, Args)]
pub struct WorkArgs {
    /// Coordinator base URL (token from CRYOFIT_TOKEN).
    #[arg(long, value_name = "URL", env = "CRYOFIT_COORDINATOR")]
    coordinator: String,
    /// Simulations run at once [default: the number of cores].
    #[arg(long, value_name = "N")]
    slots: Option<usize>,
    /// Exit after this many seconds without jobs.
    #[arg(long, value_name = "SECS")]
    exit_when_idle: Option<f64>,
    /// On SIGTERM, seconds the running simulations may take to finish before the worker exits
    /// without them (their leases expire and the jobs are handed out again).
    #[arg(long, value_name = "SECS", env = "CRYOFIT_DRAIN_TIMEOUT_S", default_value_t = 60.0)]
    drain_timeout: f64,
    /// Memory for prepared experiments, MiB (least recently used first out).
    #[arg(long, value_name = "MIB", default_value_t = 64)]
    cache_mb: usize,
}

/// The token of `CRYOFIT_TOKEN`, if set.
pub fn token() -> Option<String> {
    std::env::var("CRYOFIT_TOKEN").ok().filter(|t| !t.trim().is_empty())
}

/// Runs the worker until SIGTERM (then drains) or until idle.
pub fn run(args: &WorkArgs) -> Result<()> {
    crate::serve::init_tracing();
    let slots = match args.slots {
        Some(0) => bail!("--slots 0: give at least 1"),
        Some(n) if n > 4096 => bail!("--slots {n}: give at most 4096 (the coordinator's limit)"),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let mut settings = WorkerSettings::new(slots);
    if let Some(s) = args.exit_when_idle {
        if !(s.is_finite() && s >= 0.0) {
            bail!("--exit-when-idle {s}: give seconds ≥ 0");
        }
        settings.exit_when_idle = Some(Duration::from_secs_f64(s));
    }
    let d = args.drain_timeout;
    if !(d.is_finite() && (0.0..=86_400.0).contains(&d)) {
        bail!("--drain-timeout {d}: give seconds in [0, 86400]");
    }
    settings.drain_timeout = Duration::from_secs_f64(d);
    settings.cache_bytes = args.cache_mb.saturating_mul(1024 * 1024);
    let client = Client::new(&args.coordinator, token()).with_context(|| "--coordinator".to_string())?;
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    let summary = rt.block_on(cryofit_worker::run(
        client,
        settings,
        crate::serve::fluid_loader(),
        cryofit_worker::shutdown_signal(),
    ));
    // an evaluation abandoned at the drain timeout keeps its thread busy: do not wait for it
    rt.shutdown_timeout(Duration::from_millis(500));
    let summary = summary?;
    eprintln!(
        "worker done: {} results counted ({} failed evaluations), {} stale",
        summary.counted, summary.failed, summary.stale
    );
    Ok(())
}
