//! `cryofit report DIR|ID [--coordinator URL] --out DIR`: the figures of a calibration as SVG and
//! PNG files with an `index.html` that shows them.
//!
//! The calibration is either a `cryofit calibrate` output folder (its `calibration.sqlite` is
//! opened through an embedded coordinator, as `calibrate` itself does) or a calibration id on a
//! coordinator. Either way the figures are made from what the REST API returns, by
//! `cryofit_server::figures`; a figure whose inputs are missing is listed in the index with the
//! reason, and the command still succeeds.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_api as api;
use cryofit_plots::{IndexEntry, index_html};
use cryofit_server::figures::{self, CalibrationData, FigureOptions};
use cryofit_worker::Client;

use crate::calibrate::DATABASE;

/// Arguments of `cryofit report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// A `cryofit calibrate` output folder, or the id of a calibration on the coordinator (a
    /// path that exists is a folder).
    source: String,
    /// Coordinator base URL, for a calibration id (token from CRYOFIT_TOKEN).
    #[arg(long, value_name = "URL", env = "CRYOFIT_COORDINATOR", default_value = "http://127.0.0.1:8700")]
    coordinator: String,
    /// Folder to write the figures and index.html into (created if absent).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Simulations at posterior draws for the posterior-predictive bands (0: no bands).
    #[arg(long, value_name = "N", default_value_t = 40)]
    band_draws: usize,
    /// Seed of the posterior draws (Gaussian approximation of a variance stage).
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
}

/// Most posterior-predictive simulations.
const MAX_BAND_DRAWS: usize = 1000;

/// Runs `cryofit report`.
pub fn run(args: &ReportArgs) -> Result<()> {
    if args.band_draws > MAX_BAND_DRAWS {
        bail!("--band-draws {}: give at most {MAX_BAND_DRAWS}", args.band_draws);
    }
    if args.out.exists() && !args.out.is_dir() {
        bail!("--out {}: exists and is not a directory", args.out.display());
    }
    let rt =
        tokio::runtime::Builder::new_multi_thread().enable_all().build().context("cannot start the async runtime")?;
    let local = Path::new(&args.source);
    let data = if local.exists() {
        if !local.is_dir() {
            bail!("{}: not a folder; give a `cryofit calibrate` output folder or a calibration id", local.display());
        }
        // held while the database is open, so that no `cryofit calibrate` writes into it meanwhile
        let _lock = crate::calibrate::lock_folder(local, || {
            anyhow!(
                "{}: a cryofit calibrate is running into this folder; report it when it has finished",
                local.display()
            )
        })?;
        rt.block_on(from_folder(local))?
    } else {
        let id: i64 = args.source.parse().map_err(|_| {
            anyhow!("{}: neither an existing folder nor a calibration id (a whole number)", args.source)
        })?;
        let client = Client::new(&args.coordinator, crate::work::token())
            .map(|c| c.with_retry_for(Duration::from_secs(10)))
            .context("--coordinator")?;
        rt.block_on(fetch(&client, id)).with_context(|| format!("calibration {id} on {}", args.coordinator))?
    };
    let opts = FigureOptions {
        band_draws: args.band_draws,
        seed: args.seed,
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        end_at_data: false,
    };
    let fluids = crate::serve::fluid_loader();
    let figs = figures::figures(&data, &fluids, &opts);

    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut entries = Vec::new();
    for f in &figs {
        let skipped = match &f.plot {
            Err(why) => Some(why.clone()),
            Ok(p) => {
                let svg = p.svg().map_err(|e| anyhow!("{e}"))?;
                let png = p.png().map_err(|e| anyhow!("{e}"))?;
                files.push((format!("{}.svg", f.name), svg.into_bytes()));
                files.push((format!("{}.png", f.name), png));
                None
            }
        };
        entries.push(IndexEntry { name: f.name.clone(), title: f.title.clone(), skipped });
    }
    let c = &data.calibration;
    let html = index_html(&format!("{} — calibration report", c.name), &figures::facts(c), &entries);
    files.push(("index.html".into(), html.into_bytes()));
    crate::output::write_outputs(&args.out, &files)?;

    let drawn = entries.iter().filter(|e| e.skipped.is_none()).count();
    println!(
        "report of calibration {} \"{}\" ({}, {} evaluations): {drawn} figures in {}",
        c.id,
        c.name,
        c.status.as_str(),
        c.evaluations,
        args.out.join("index.html").display()
    );
    for e in &entries {
        match &e.skipped {
            None => println!("  {}.svg, {}.png: {}", e.name, e.name, e.title),
            Some(why) => println!("  skipped {}: {why}", e.name),
        }
    }
    Ok(())
}

/// The calibration of a `cryofit calibrate` output folder, read through an embedded coordinator.
async fn from_folder(dir: &Path) -> Result<CalibrationData> {
    let database = dir.join(DATABASE);
    if !database.is_file() {
        bail!(
            "{}: no {DATABASE} here; give the --out folder of a `cryofit calibrate` run, or a calibration id with \
             --coordinator",
            dir.display()
        );
    }
    let mut settings = cryofit_server::Settings::new(database.display().to_string());
    settings.fluids = crate::serve::fluid_loader();
    let server = cryofit_server::start_embedded(&database, settings)
        .await
        .map_err(|e| anyhow!("{}: cannot open the calibration database: {e}", database.display()))?;
    let outcome = async {
        let client = Client::new(&server.url(), None)?.with_retry_for(Duration::from_secs(10));
        let stored = client.calibrations().await.map_err(|e| anyhow!("{}: {e}", database.display()))?;
        let id = match stored.as_slice() {
            [one] => one.id,
            [] => bail!("{}: holds no calibration", database.display()),
            many => bail!("{}: holds {} calibrations; a calibrate folder holds one", database.display(), many.len()),
        };
        fetch(&client, id).await
    }
    .await;
    let stopped = server.stop().await;
    let data = outcome?;
    stopped.map_err(|e| anyhow!("{}: {e}", database.display()))?;
    Ok(data)
}

/// A calibration, its parameter sets and its experiments over the REST API.
async fn fetch(client: &Client, id: i64) -> Result<CalibrationData> {
    let calibration: api::Calibration = client.calibration(id).await.map_err(|e| anyhow!("{e}"))?;
    let sets = client.parameter_sets(id).await.map_err(|e| anyhow!("parameter sets: {e}"))?;
    let mut experiments = Vec::new();
    for &e in &calibration.experiments {
        experiments.push(client.experiment(e).await.map_err(|x| anyhow!("experiment {e}: {x}"))?);
    }
    Ok(CalibrationData { calibration, sets, experiments })
}
