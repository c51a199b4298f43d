//! `cryofit serve [--bind ADDR] [--database URL] [--max-… LIMIT]… [--secure-cookies]`: runs the
//! coordinator. The flags and the environment are read by [`cryofit_server::config`]; this
//! command only binds the address and serves.

use std::sync::Arc;

use anyhow::{Context, Result};
use cryofit_server::FluidLoader;
pub use cryofit_server::ServeArgs;

use crate::fluid_source;

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

/// Logging for the commands that serve or work ([`cryofit_server::telemetry::init`]).
pub use cryofit_server::telemetry::init as init_tracing;

/// Runs the coordinator until SIGTERM or Ctrl-C.
pub fn run(args: &ServeArgs) -> Result<()> {
    init_tracing();
    let mut settings = args.settings()?;
    settings.fluids = fluid_loader();
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
