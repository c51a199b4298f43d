//! Client commands of the service: `cryofit submit`, `status`, `results`, `cancel`. Each takes
//! `--coordinator URL` (or `CRYOFIT_COORDINATOR`) and the token from `CRYOFIT_TOKEN`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow};
use clap::{Args, ValueEnum};
use cryofit_api as api;
use cryofit_calib::config::CalibrationSpec;
use cryofit_worker::Client;
use cryofit_worker::client::Format;

/// The coordinator to talk to.
#[derive(Debug, Args)]
pub struct Remote {
    /// Coordinator base URL (token from CRYOFIT_TOKEN).
    #[arg(long, value_name = "URL", env = "CRYOFIT_COORDINATOR", default_value = "http://127.0.0.1:8700")]
    coordinator: String,
}

impl Remote {
    fn client(&self) -> Result<Client> {
        Client::new(&self.coordinator, crate::work::token())
            .map(|c| c.with_retry_for(std::time::Duration::from_secs(10)))
            .with_context(|| "--coordinator".to_string())
    }
}

fn block_on<F: std::future::Future>(f: F) -> Result<F::Output> {
    Ok(tokio::runtime::Builder::new_current_thread().enable_all().build().context("async runtime")?.block_on(f))
}

/// Arguments of `cryofit submit`.
#[derive(Debug, Args)]
pub struct SubmitArgs {
    /// The calibration file (TOML): its experiments are uploaded, then the calibration.
    file: PathBuf,
    #[command(flatten)]
    remote: Remote,
    /// Print `{"id": …}` as the last line.
    #[arg(long)]
    json: bool,
}

/// Reads the calibration file and its experiments' texts; returns the spec and, per experiment,
/// (name, case text, data text). The file is parsed, not checked: the coordinator checks the
/// calibration (with its own limits) and names the field it refuses.
pub fn read_calibration(file: &Path) -> Result<(CalibrationSpec, Vec<api::CreateExperiment>)> {
    let label = file.display().to_string();
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {label}"))?;
    let spec: CalibrationSpec =
        toml::from_str(&text).map_err(|e| anyhow!("{label}: {}", e.to_string().trim().replace('\n', " ")))?;
    let dir = file.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for (k, e) in spec.experiments.iter().enumerate() {
        let read = |p: &str, field: &str| {
            let path = dir.join(p);
            std::fs::read_to_string(&path)
                .with_context(|| format!("{label}: experiments[{k}].{field}: cannot read {}", path.display()))
        };
        let case = read(&e.case, "case")?;
        let data = read(&e.data, "data")?;
        let name = e.label(k);
        out.push(api::CreateExperiment { name, case, data });
    }
    Ok((spec, out))
}

/// `cryofit submit`.
pub fn submit(args: &SubmitArgs) -> Result<()> {
    let (spec, experiments) = read_calibration(&args.file)?;
    let client = args.remote.client()?;
    let label = args.file.display().to_string();
    let id = block_on(async {
        let mut ids = Vec::new();
        for (k, e) in experiments.iter().enumerate() {
            let created = client
                .create_experiment(e)
                .await
                .map_err(|err| anyhow!("{label}: experiments[{k}] ({}): {err}", e.name))?;
            ids.push(created.id);
        }
        let req = api::CreateCalibration {
            name: spec.name.clone(),
            description: spec.description.clone(),
            seed: spec.seed,
            experiments: ids,
            parameters: spec.with_experiment_names().parameters,
            fixed: spec.fixed.clone(),
            weights: spec.weights.clone(),
            stages: spec.stages.clone(),
            max_evaluation_s: Some(spec.max_evaluation_s),
        };
        let created = client.create_calibration(&req).await.map_err(|err| anyhow!("{label}: {err}"))?;
        Ok::<_, anyhow::Error>(created.id)
    })??;
    if args.json {
        println!("{}", serde_json::json!({ "id": id }));
    } else {
        println!("submitted calibration {id} to {}", client.base());
    }
    Ok(())
}

/// Arguments of `cryofit status`.
#[derive(Debug, Args)]
pub struct StatusArgs {
    /// Calibration id.
    id: i64,
    #[command(flatten)]
    remote: Remote,
    /// Print the calibration as JSON.
    #[arg(long)]
    json: bool,
}

/// `cryofit status`.
pub fn status(args: &StatusArgs) -> Result<()> {
    let client = args.remote.client()?;
    let c = block_on(client.calibration(args.id))?.map_err(|e| anyhow!("calibration {}: {e}", args.id))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&c)?);
        return Ok(());
    }
    let best = c.best_cost.map_or_else(|| "—".into(), |b| format!("{b:.6e}"));
    println!(
        "calibration {} \"{}\": {}; {}/{} evaluations ({} failed); stage {}; best cost {best}",
        c.id,
        c.name,
        c.status.as_str(),
        c.evaluations,
        c.budget,
        c.failed_evaluations,
        c.stage
    );
    if let Some(p) = &c.best_parameters {
        for (k, v) in p {
            println!("  {k} = {v}");
        }
    }
    if let Some(e) = &c.error {
        println!("  error: {e}");
    }
    Ok(())
}

/// Output format of `cryofit results`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ResultsFormat {
    /// One JSON array of result items.
    Json,
    /// CSV with a header line.
    Csv,
}

/// Arguments of `cryofit results`.
#[derive(Debug, Args)]
pub struct ResultsArgs {
    /// Calibration id.
    id: i64,
    #[command(flatten)]
    remote: Remote,
    /// Output format.
    #[arg(long, value_enum, default_value_t = ResultsFormat::Json)]
    format: ResultsFormat,
}

/// `cryofit results`: every result of a calibration.
pub fn results(args: &ResultsArgs) -> Result<()> {
    let client = args.remote.client()?;
    let id = args.id;
    match args.format {
        ResultsFormat::Json => {
            let items = block_on(client.results(id))?.map_err(|e| anyhow!("calibration {id}: {e}"))?;
            println!("{}", serde_json::to_string_pretty(&items)?);
        }
        ResultsFormat::Csv => {
            let mut offset = 0;
            let limit = api::MAX_PAGE;
            loop {
                let text = block_on(client.results_page(id, limit, offset, Format::Csv))?
                    .map_err(|e| anyhow!("calibration {id}: {e}"))?;
                let mut lines = text.lines();
                let header = lines.next().unwrap_or_default();
                if offset == 0 {
                    println!("{header}");
                }
                let rows: Vec<&str> = lines.collect();
                for r in &rows {
                    println!("{r}");
                }
                if (rows.len() as i64) < limit {
                    break;
                }
                offset += limit;
            }
        }
    }
    Ok(())
}

/// Arguments of `cryofit cancel`.
#[derive(Debug, Args)]
pub struct CancelArgs {
    /// Calibration id.
    id: i64,
    #[command(flatten)]
    remote: Remote,
}

/// `cryofit cancel`.
pub fn cancel(args: &CancelArgs) -> Result<()> {
    let client = args.remote.client()?;
    let c = block_on(client.cancel(args.id))?.map_err(|e| anyhow!("calibration {}: {e}", args.id))?;
    println!("calibration {}: {}", c.id, c.status.as_str());
    Ok(())
}
