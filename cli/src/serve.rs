//! `cryofit serve [--bind ADDR] [--database URL]`: runs the coordinator.

use std::sync::Arc;

use anyhow::{Context, Result};
use clap::Args;
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
}

/// The binary's fluid tables (built in, or `CRYOFIT_DATA_DIR`), with the hash of their bytes.
pub fn fluid_loader() -> FluidLoader {
    Arc::new(|name: &str| {
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
    })
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
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    rt.block_on(async {
        let listener = tokio::net::TcpListener::bind(&args.bind)
            .await
            .with_context(|| format!("--bind {}: cannot listen", args.bind))?;
        let addr = listener.local_addr()?;
        println!("listening on http://{addr}");
        use std::io::Write as _;
        let _ = std::io::stdout().flush();
        cryofit_server::launch(listener, settings, cryofit_worker::shutdown_signal()).await?;
        Ok(())
    })
}
