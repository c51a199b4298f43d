//! `cryofit serve [--bind ADDR] [--database URL] [--max-… LIMIT]… [--secure-cookies]`: runs the
//! coordinator.

use std::sync::Arc;

use anyhow::{Context, Result, bail};
use clap::Args;
use cryofit_server::limits::Limits;
use cryofit_server::{FluidLoader, Settings};

use crate::fluid_source;

/// Arguments of `cryofit serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0 picks a free port; the chosen address is printed).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8700")]
    bind: String,
    /// SQLite database (a path or sqlite://PATH); created if absent.
    #[arg(long, value_name = "URL", default_value = "cryofit.db")]
    database: String,
    /// Most evaluations of one calibration, all stages together.
    #[arg(long, value_name = "N", env = "CRYOFIT_MAX_BUDGET", default_value_t = Limits::DEFAULT_MAX_BUDGET)]
    max_budget: u64,
    /// Largest population, trajectories, walkers, points, levels, restarts or keep of a stage.
    #[arg(long, value_name = "N", env = "CRYOFIT_MAX_STAGE_SIZE", default_value_t = Limits::DEFAULT_MAX_STAGE_SIZE)]
    max_stage_size: u64,
    /// Largest estimated optimiser state of one calibration, bytes (it is written with every result).
    #[arg(long, value_name = "BYTES", env = "CRYOFIT_MAX_STATE_BYTES", default_value_t = Limits::DEFAULT_MAX_STATE_BYTES)]
    max_state_bytes: u64,
    /// Most values one evaluation records (probes and profiles up to the end of the data).
    #[arg(long, value_name = "N", env = "CRYOFIT_MAX_OUTPUT_POINTS", default_value_t = Limits::DEFAULT_MAX_OUTPUT_POINTS)]
    max_output_points: u64,
    /// Largest max_evaluation_s a calibration may ask for, s.
    #[arg(long, value_name = "SECS", env = "CRYOFIT_MAX_EVALUATION_S", default_value_t = Limits::DEFAULT_MAX_EVALUATION_S)]
    max_evaluation_s: f64,
    /// Mark the dashboard's session cookie Secure (set it when a TLS proxy serves the coordinator).
    #[arg(long, env = "CRYOFIT_SECURE_COOKIES")]
    secure_cookies: bool,
    /// Hours a dashboard session lasts after signing in.
    #[arg(long, value_name = "HOURS", env = "CRYOFIT_SESSION_HOURS", default_value_t = 12.0)]
    session_hours: f64,
}

impl ServeArgs {
    /// The limits of the flags, checked.
    fn limits(&self) -> Result<Limits> {
        for (flag, v) in [
            ("--max-budget", self.max_budget),
            ("--max-stage-size", self.max_stage_size),
            ("--max-state-bytes", self.max_state_bytes),
            ("--max-output-points", self.max_output_points),
        ] {
            if v == 0 {
                bail!("{flag} 0: give at least 1");
            }
        }
        let e = self.max_evaluation_s;
        if !(e.is_finite() && e > 0.0) {
            bail!("--max-evaluation-s {e}: give seconds > 0");
        }
        Ok(Limits {
            max_budget: self.max_budget,
            max_stage_size: self.max_stage_size,
            max_state_bytes: self.max_state_bytes,
            max_output_points: self.max_output_points,
            max_evaluation_s: e,
        })
    }
}

/// The binary's fluid tables (built in, or `CRYOFIT_DATA_DIR`), with the hash of their bytes.
pub fn fluid_loader() -> FluidLoader {
    let load: FluidLoader = Arc::new(|name: &str| {
        let table = fluid_source::load(name).map_err(|e| format!("{e:#}"))?;
        let canon = cryofit_solver::fluids::canonical_name(name).unwrap_or(name);
        let bytes: std::borrow::Cow<'static, [u8]> = match std::env::var_os(fluid_source::DATA_DIR_VAR) {
            Some(dir) if !dir.is_empty() => {
                let path = std::path::Path::new(&dir).join(format!("{canon}.cft"));
                std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?.into()
            }
            _ => cryofit_solver::fluids::embedded_bytes(canon).ok_or_else(|| format!("unknown fluid `{name}`"))?.into(),
        };
        Ok((Arc::new(table.into_owned()), cryofit_api::fluid_hash(&bytes)))
    });
    // each table loaded (and copied out of the binary) once, shared by every experiment
    cryofit_worker::shared_fluids(load)
}

/// Logs to stderr, filtered by `RUST_LOG` (default `info`).
pub fn init_tracing() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
}

/// Runs the coordinator until SIGTERM or Ctrl-C.
pub fn run(args: &ServeArgs) -> Result<()> {
    init_tracing();
    let mut settings = Settings::from_env(&args.database)?;
    settings.fluids = fluid_loader();
    settings.limits = args.limits()?;
    settings.secure_cookies = args.secure_cookies;
    let h = args.session_hours;
    if !(h.is_finite() && h > 0.0 && h <= 24.0 * 366.0) {
        bail!("--session-hours {h}: give hours in (0, 8784]");
    }
    settings.session_ttl = std::time::Duration::from_secs_f64(h * 3600.0);
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    rt.block_on(async {
        let listener = tokio::net::TcpListener::bind(&args.bind)
            .await
            .with_context(|| format!("--bind {}: cannot listen", args.bind))?;
        // "listening on" once the database is open and locked: a second coordinator on the
        // same database never prints it
        cryofit_server::launch_with_ready(listener, settings, cryofit_worker::shutdown_signal(), |addr| {
            println!("listening on http://{addr}");
            use std::io::Write as _;
            let _ = std::io::stdout().flush();
        })
        .await
        .with_context(|| format!("--database {}", args.database))?;
        Ok(())
    })
}
