//! `cryofit calibrate CALIBRATION.toml [--workers N | --coordinator URL] [--out DIR]`: fits parameters to
//! measured time series.
//!
//! The calibration runs through an embedded coordinator — the service's code path, with its SQLite
//! database at `<out>/calibration.sqlite` — and in-process workers (`--workers` simulation slots).
//! Re-running into a folder that holds an unfinished run of the same calibration (the same spec,
//! cases and data) resumes it where it stopped: nothing counted is evaluated again, and a
//! generation-synchronous calibration ends bit-identical to an uninterrupted one. A finished run is
//! reported again; a folder holding another calibration is refused.
//!
//! With `--coordinator URL` the calibration runs on a remote coordinator's workers instead: it is
//! submitted there (its id noted in `<out>/coordinator.json`, so that a re-run waits for it rather
//! than submitting another) and the outputs are made, as above, from what the REST API returns.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_api as api;
use cryofit_calib::Space;
use cryofit_calib::config::{AlgorithmName, CalibrationSpec, StageSpec};
use cryofit_calib::cost;
use cryofit_calib::inference::InferenceSummary;
use cryofit_calib::pipeline::{Pipeline, StageReport};
use cryofit_calib::problem::{Experiment, Fixed, Problem, default_start, experiment_from_texts};
use cryofit_worker::{Client, WorkerSettings};
use serde_json::json;

use crate::csv_text::CsvText;
use crate::fluid_source;
use crate::output::{chilldown_pairs, fmt_num, fmt_sig, probes_csv, write_outputs};

/// Arguments of `cryofit calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// The calibration file (TOML).
    pub(crate) file: PathBuf,
    /// Simulations run at once (in-process worker slots) [default: the number of cores].
    #[arg(long, value_name = "N")]
    pub(crate) workers: Option<usize>,
    /// Output directory, also holding the run's database (calibration.sqlite): re-running into it
    /// resumes an unfinished run [default: out/<calibration file stem>].
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
    /// Run the calibration on this coordinator's workers instead of in-process ones (token from
    /// CRYOFIT_TOKEN): the file and its experiments are submitted, the command waits for the end
    /// and writes the same outputs; the folder notes the calibration (coordinator.json), so that
    /// re-running into it waits for that calibration again instead of submitting another.
    #[arg(long, value_name = "URL", conflicts_with = "workers")]
    pub(crate) coordinator: Option<String>,
}

/// A calibration read from disk: its spec, its problem and its (not yet started) pipeline.
pub struct Loaded {
    pub spec: CalibrationSpec,
    pub problem: Problem,
    pub pipeline: Pipeline,
}

/// Reads a calibration file and every case and data file it names (relative to its folder).
pub fn load(file: &Path) -> Result<Loaded> {
    let label = file.display().to_string();
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {label}"))?;
    let spec = CalibrationSpec::from_toml(&text, &label)?;
    // sizes first (the pipeline below allocates every stage up front: a stage of 10¹⁴ Morris
    // trajectories must be refused before that), with the ceilings a coordinator has by default
    cryofit_server::limits::check_calibration_sizes(&spec, &cryofit_server::limits::Limits::default())
        .map_err(|e| anyhow!("{label}: {e}"))?;
    // stages and bounds next: they need no other file (the start is set once the cases are read)
    let space = spec.space().map_err(|e| anyhow!("{label}: {e}"))?;
    let mid = vec![0.5; space.dim()];
    Pipeline::new(space.clone(), spec.stages.clone(), mid, spec.seed).map_err(|e| anyhow!("{label}: {e}"))?;
    let dir = file.parent().unwrap_or(Path::new("."));
    let fixed = Fixed::new(&spec.fixed).map_err(|e| anyhow!("{label}: {e}"))?;
    let mut experiments = Vec::new();
    for (k, e) in spec.experiments.iter().enumerate() {
        let case_path = dir.join(&e.case);
        let data_path = dir.join(&e.data);
        let read = |p: &Path, field: &str| {
            std::fs::read_to_string(p)
                .with_context(|| format!("{label}: experiments[{k}].{field}: cannot read {}", p.display()))
        };
        let case_text = read(&case_path, "case")?;
        let data_text = read(&data_path, "data")?;
        let name = e.label(k);
        if experiments.iter().any(|x: &Experiment| x.name == name) {
            bail!("{label}: experiments[{k}]: the name `{name}` is used twice; give each experiment its own `name`");
        }
        let fluid = |n: &str| fluid_source::load(n).map(|t| Arc::new(t.into_owned())).map_err(|e| format!("{e:#}"));
        let exp = experiment_from_texts(
            &name,
            &case_text,
            &case_path.display().to_string(),
            &data_text,
            &data_path.display().to_string(),
            fluid,
            &fixed,
            Some(spec.max_evaluation_s),
        )
        .map_err(|e| anyhow!("{label}: experiments[{k}]: {e}"))?;
        let model = solver_of(&exp)?;
        spec.check_case_fields(&name, model.case(), &case_path.display().to_string())
            .map_err(|e| anyhow!("{label}: {e}"))?;
        experiments.push(exp);
    }
    let problem = Problem::new(experiments, spec.weights()).map_err(|e| anyhow!("{label}: {e}"))?;
    let start = default_start(&space, &problem.experiments, &spec.start_values());
    let pipeline = Pipeline::new(space, spec.stages.clone(), start, spec.seed).map_err(|e| anyhow!("{label}: {e}"))?;
    Ok(Loaded { spec, problem, pipeline })
}

/// File name of the embedded coordinator's database in the output folder.
pub(crate) const DATABASE: &str = "calibration.sqlite";

/// Most worker slots (the coordinator's limit of a worker's slots).
const MAX_WORKERS: usize = 4096;

/// Where the outputs go: `--out`, or `out/<calibration file stem>`.
fn out_dir(args: &CalibrateArgs) -> PathBuf {
    match &args.out {
        Some(dir) => dir.clone(),
        None => {
            let stem = args.file.file_stem().map_or_else(|| "calibration".into(), |s| s.to_string_lossy().into_owned());
            Path::new("out").join(stem)
        }
    }
}

/// What the outputs are made from: the calibration as the coordinator reports it at the end, and
/// its history.
struct Run {
    evaluations: usize,
    failed: usize,
    budget: usize,
    stages: Vec<StageSpec>,
    reports: Vec<StageReport>,
    best_cost: f64,
    best_parameters: BTreeMap<String, f64>,
    /// Told parameter sets in the optimiser's order.
    rows: Vec<api::ParameterSetItem>,
    wall: f64,
}

/// Runs the calibration through an embedded coordinator whose database is `<out>/calibration.sqlite`
/// with in-process workers, resuming an unfinished run of the same calibration found there, and
/// writes the outputs.
pub fn run(args: &CalibrateArgs) -> Result<()> {
    let Loaded { spec, problem, pipeline } = load(&args.file)?;
    let spec = &spec;
    let label = args.file.display().to_string();
    let out_dir = out_dir(args);
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("--out {}: exists and is not a directory", out_dir.display());
    }
    let workers = match args.workers {
        Some(0) => bail!("--workers 0: give at least 1"),
        Some(n) if n > MAX_WORKERS => bail!("--workers {n}: give at most {MAX_WORKERS}"),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()).min(MAX_WORKERS),
    };
    let (_, experiments) = crate::client::read_calibration(&args.file)?;
    let _lock = open_folder(&out_dir)?;
    let space = pipeline.space().clone();
    let run = {
        let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
        match &args.coordinator {
            None if out_dir.join(COORDINATOR_FILE).exists() => bail!(
                "--out {}: the folder is a calibration on a coordinator ({COORDINATOR_FILE}); give the same \
                 --coordinator to wait for it, or pick another --out",
                out_dir.display()
            ),
            None => rt.block_on(drive(spec, &label, &experiments, &out_dir, workers))?,
            Some(url) => rt.block_on(remote(spec, &label, &experiments, &out_dir, url))?,
        }
    };

    // the best fit, once more, for its probes and per-series figures: over the whole case (the
    // evaluations stopped with the data), so that chilldown times after the data's end are known
    let mut fits = Vec::new();
    let mut files: Vec<(String, String)> = Vec::new();
    for (k, e) in problem.experiments.iter().enumerate() {
        let fit = problem.fit_experiment(k, &run.best_parameters).map_err(|m| anyhow!("best fit: {m}"))?;
        let model = solver_of(e)?;
        let out = match model.run_full(&run.best_parameters) {
            Ok(out) => out,
            Err(m) => {
                eprintln!(
                    "warning: the best fit of experiment `{}` failed after the end of its data ({m}); \
                     its probes end with the data",
                    e.name
                );
                model.run(&run.best_parameters).map_err(|m| anyhow!("best fit, experiment `{}`: {m}", e.name))?
            }
        };
        files.push((format!("fit-{}.csv", e.name), probes_csv(&out.probes)?));
        fits.push((e, fit, out));
    }

    let data_points = problem.data_points();
    let result = result_json(spec, &run, &fits, data_points)?;
    let best_toml = best_toml(spec, &run.best_parameters);
    let mut outputs: Vec<(String, String)> = vec![
        ("result.json".into(), result),
        ("best.toml".into(), best_toml),
        ("evaluations.csv".into(), evaluations_csv(&space, &run)?),
    ];
    if let Some(draws) = posterior_csv(&run.reports)? {
        outputs.push(("posterior.csv".into(), draws));
    }
    outputs.extend(files);
    let refs: Vec<(&str, String)> = outputs.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    write_outputs(&out_dir, &refs)?;
    print_report(spec, &run, &fits, &out_dir, &outputs);
    Ok(())
}

/// Creates the output folder and locks it for this run.
fn open_folder(out_dir: &Path) -> Result<Option<std::fs::File>> {
    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("--out {}: cannot create the directory", out_dir.display()))?;
    lock_folder(out_dir, || {
        anyhow!(
            "--out {}: another cryofit calibrate is running into this folder; wait for it to finish or pick another \
             --out",
            out_dir.display()
        )
    })
}

/// Submits the calibration file `args.file` to `args.coordinator` without waiting for it, noting
/// it in the output folder as `cryofit calibrate --coordinator` does (a calibration already noted
/// there is kept); returns its id. `cryofit calibrate --coordinator` into the same folder then
/// waits for it and writes the outputs.
pub(crate) fn submit_to_coordinator(args: &CalibrateArgs) -> Result<i64> {
    let url = args.coordinator.as_deref().ok_or_else(|| anyhow!("no --coordinator to submit to"))?;
    let Loaded { spec, .. } = load(&args.file)?;
    let label = args.file.display().to_string();
    let out_dir = out_dir(args);
    let (_, experiments) = crate::client::read_calibration(&args.file)?;
    let _lock = open_folder(&out_dir)?;
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    rt.block_on(async {
        let client = remote_client(url)?;
        attach_or_submit(&client, &spec, &label, &experiments, &out_dir, url).await
    })
}

/// File in a `--coordinator` calibration's output folder naming the coordinator and the
/// calibration id.
const COORDINATOR_FILE: &str = "coordinator.json";

fn remote_client(url: &str) -> Result<Client> {
    Client::new(url, crate::work::token())
        .map(|c| c.with_retry_for(Duration::from_secs(10)))
        .with_context(|| format!("--coordinator {url}"))
}

/// Runs the calibration on the coordinator at `url`: the one noted in `out_dir` or a new
/// submission; waits for it to end and fetches what the outputs need.
async fn remote(
    spec: &CalibrationSpec,
    label: &str,
    experiments: &[api::CreateExperiment],
    out_dir: &Path,
    url: &str,
) -> Result<Run> {
    let client = remote_client(url)?;
    let id = attach_or_submit(&client, spec, label, experiments, out_dir, url).await?;
    let bar = CalibrationProgress::new();
    let clock = Instant::now();
    let mut done_before = None;
    let c = loop {
        let c = client.calibration(id).await.map_err(|e| anyhow!("calibration {id} on {url}: {e}"))?;
        let before = *done_before.get_or_insert(c.evaluations.max(0) as usize);
        bar.update(&c, before, clock.elapsed());
        if c.status.is_final() {
            break c;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    };
    bar.clear();
    // the coordinator's clock: from submission to the last change
    let wall = (c.updated - c.created).max(0) as f64 / 1e3;
    finished(&client, label, out_dir, c, wall).await
}

/// The id of this file's calibration on the coordinator at `url`: the one `out_dir` notes (which
/// must be this calibration there), or a new submission, then noted.
async fn attach_or_submit(
    client: &Client,
    spec: &CalibrationSpec,
    label: &str,
    experiments: &[api::CreateExperiment],
    out_dir: &Path,
    url: &str,
) -> Result<i64> {
    let noted = out_dir.join(COORDINATOR_FILE);
    let folder = out_dir.display();
    if out_dir.join(DATABASE).exists() {
        bail!("--out {folder}: the folder holds a local calibration ({DATABASE}); pick another --out");
    }
    if let Ok(text) = std::fs::read_to_string(&noted) {
        let v: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", noted.display()))?;
        let (Some(at), Some(id)) = (v["coordinator"].as_str(), v["id"].as_i64()) else {
            bail!(
                "{}: names no coordinator and calibration id; delete the folder or pick another --out",
                noted.display()
            );
        };
        if at != url {
            bail!("--out {folder}: the folder is calibration {id} on {at}, not on {url}; pick another --out");
        }
        let c =
            client.calibration(id).await.map_err(|e| anyhow!("{}: calibration {id} on {url}: {e}", noted.display()))?;
        if c.spec != serde_json::to_value(request(spec, c.experiments.clone()))? {
            bail!(
                "--out {folder}: the folder is calibration {id} on {url} (\"{}\"), not the one of {label}; pick another \
                 --out or delete the folder",
                c.name
            );
        }
        return Ok(id);
    }
    if std::fs::read_dir(out_dir).is_ok_and(|mut d| d.any(|e| e.is_ok_and(|e| e.file_name() == "result.json"))) {
        bail!("--out {folder}: the folder holds the outputs of another calibration; pick another --out");
    }
    let id = submit(client, spec, label, experiments).await?;
    let note = json!({ "coordinator": url, "id": id });
    write_outputs(out_dir, &[(COORDINATOR_FILE, format!("{note:#}\n"))])?;
    eprintln!("submitted calibration {id} to {url}");
    Ok(id)
}

/// An exclusive lock on a calibration output folder for as long as it is held, so that two runs
/// never drive the same database and nothing reads it while a run writes. Where folders cannot be
/// locked (not on Unix), there is no lock. `busy` is the error when another process holds it.
pub(crate) fn lock_folder(dir: &Path, busy: impl FnOnce() -> anyhow::Error) -> Result<Option<std::fs::File>> {
    let Ok(handle) = std::fs::File::open(dir) else { return Ok(None) };
    match handle.try_lock() {
        Ok(()) => Ok(Some(handle)),
        Err(std::fs::TryLockError::WouldBlock) => Err(busy()),
        Err(std::fs::TryLockError::Error(_)) => Ok(None),
    }
}

/// The calibration request for stored experiments `ids` (experiments named by their names).
fn request(spec: &CalibrationSpec, ids: Vec<i64>) -> api::CreateCalibration {
    api::CreateCalibration {
        name: spec.name.clone(),
        description: spec.description.clone(),
        seed: spec.seed,
        experiments: ids,
        parameters: spec.with_experiment_names().parameters,
        fixed: spec.fixed.clone(),
        weights: spec.weights.clone(),
        stages: spec.stages.clone(),
        max_evaluation_s: Some(spec.max_evaluation_s),
    }
}

/// Starts the embedded coordinator on `<out>/calibration.sqlite`, submits (or finds) the
/// calibration, runs the workers until it ends and fetches what the outputs need.
async fn drive(
    spec: &CalibrationSpec,
    label: &str,
    experiments: &[api::CreateExperiment],
    out_dir: &Path,
    workers: usize,
) -> Result<Run> {
    let database = out_dir.join(DATABASE);
    let fluids = crate::serve::fluid_loader();
    let mut settings = cryofit_server::Settings::new(database.display().to_string());
    settings.fluids = fluids.clone();
    let server = cryofit_server::start_embedded(&database, settings)
        .await
        .map_err(|e| anyhow!("{}: cannot open the calibration database: {e}", database.display()))?;
    let outcome = async {
        let client = Client::new(&server.url(), None)?.with_retry_for(Duration::from_secs(10));
        calibrate(&client, spec, label, experiments, out_dir, workers, fluids).await
    }
    .await;
    let stopped = server.stop().await;
    let run = outcome?;
    stopped.map_err(|e| anyhow!("{}: {e}", database.display()))?;
    Ok(run)
}

/// The calibration of this file in the database: submitted now, or found unfinished (resumed) or
/// finished (reported again).
async fn calibrate(
    client: &Client,
    spec: &CalibrationSpec,
    label: &str,
    experiments: &[api::CreateExperiment],
    out_dir: &Path,
    workers: usize,
    fluids: cryofit_server::FluidLoader,
) -> Result<Run> {
    let database = out_dir.join(DATABASE);
    let db_label = database.display().to_string();
    let stored = client.calibrations().await.map_err(|e| anyhow!("{db_label}: {e}"))?;
    let hashes = cryofit_worker::fluid_hashes(&fluids);
    let started = Instant::now();
    let (id, prior) = match stored.as_slice() {
        [] => (submit(client, spec, label, experiments).await?, 0.0),
        [c] => {
            let other = || {
                anyhow!(
                    "--out {}: the folder holds another calibration (\"{}\" in {DATABASE}), not the one of {label}; \
                     pick another --out or delete the folder",
                    out_dir.display(),
                    c.name
                )
            };
            let ids = c.experiments.clone();
            if c.spec != serde_json::to_value(request(spec, ids.clone()))? || ids.len() != experiments.len() {
                return Err(other());
            }
            for (&eid, mine) in ids.iter().zip(experiments) {
                let e = client.experiment(eid).await.map_err(|e| anyhow!("{db_label}: experiment {eid}: {e}"))?;
                if e.name != mine.name || e.case != mine.case || e.data != mine.data {
                    return Err(other());
                }
            }
            let prior = (c.updated - c.created).max(0) as f64 / 1e3;
            if !c.status.is_final() {
                if let Some(why) = build_difference(c, &hashes) {
                    bail!(
                        "--out {}: the unfinished calibration there {why}, so it cannot be resumed by this cryofit; pick \
                         another --out or delete the folder",
                        out_dir.display()
                    );
                }
                eprintln!(
                    "resuming the unfinished calibration in {}: {} of {} evaluations done",
                    out_dir.display(),
                    c.evaluations,
                    c.budget
                );
            }
            (c.id, prior)
        }
        many => bail!(
            "--out {}: {db_label} holds {} calibrations, not one run of cryofit calibrate; pick another --out",
            out_dir.display(),
            many.len()
        ),
    };
    let c = client.calibration(id).await.map_err(|e| anyhow!("{db_label}: calibration {id}: {e}"))?;
    if c.status.is_final() {
        // ended in an earlier run: report it again
        return finished(client, label, out_dir, c, prior).await.map_err(|e| {
            anyhow!("{e:#} (as stored in {db_label}; delete the folder or pick another --out to run it again)")
        });
    }
    let c = work(client, id, c, workers, fluids).await?;
    finished(client, label, out_dir, c, prior + started.elapsed().as_secs_f64()).await
}

/// Why a stored calibration cannot run on this build (solver version, fluid tables), if it cannot.
fn build_difference(c: &api::Calibration, hashes: &BTreeMap<String, String>) -> Option<String> {
    if c.solver_version != api::SOLVER_VERSION {
        return Some(format!("runs solver version {}, this is {}", c.solver_version, api::SOLVER_VERSION));
    }
    for (fluid, hash) in &c.fluid_hashes {
        if hashes.get(fluid) != Some(hash) {
            return Some(format!("was started with another `{fluid}` fluid table (CRYOFIT_DATA_DIR)"));
        }
    }
    None
}

/// Uploads the experiments (reusing identical ones already stored, as after an interrupted
/// upload) and the calibration; returns its id.
async fn submit(
    client: &Client,
    spec: &CalibrationSpec,
    label: &str,
    experiments: &[api::CreateExperiment],
) -> Result<i64> {
    let stored = client.experiments().await.map_err(|e| anyhow!("{label}: {e}"))?;
    let mut ids = Vec::new();
    for (k, e) in experiments.iter().enumerate() {
        let mut found = None;
        for s in &stored {
            if s.name == e.name && !ids.contains(&s.id) {
                let full = client.experiment(s.id).await.map_err(|err| anyhow!("{label}: {err}"))?;
                if full.case == e.case && full.data == e.data {
                    found = Some(s.id);
                    break;
                }
            }
        }
        let id = match found {
            Some(id) => id,
            None => {
                client
                    .create_experiment(e)
                    .await
                    .map_err(|err| anyhow!("{label}: experiments[{k}] ({}): {err}", e.name))?
                    .id
            }
        };
        ids.push(id);
    }
    let created = client.create_calibration(&request(spec, ids)).await.map_err(|err| anyhow!("{label}: {err}"))?;
    Ok(created.id)
}

/// Runs in-process workers (`workers` slots) until the calibration ends; returns its final state.
async fn work(
    client: &Client,
    id: i64,
    start: api::Calibration,
    workers: usize,
    fluids: cryofit_server::FluidLoader,
) -> Result<api::Calibration> {
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let mut worker = tokio::spawn(cryofit_worker::run(client.clone(), WorkerSettings::new(workers), fluids, async {
        let _ = stopped.await;
    }));
    let clock = Instant::now();
    let bar = CalibrationProgress::new();
    let done_before = start.evaluations.max(0) as usize;
    let mut c = start;
    let outcome = loop {
        bar.update(&c, done_before, clock.elapsed());
        if c.status.is_final() {
            break Ok(c);
        }
        tokio::select! {
            joined = &mut worker => {
                // the worker stops only when told to, or on an error
                bar.clear();
                return match joined {
                    Ok(Ok(_)) => Err(anyhow!("calibration {id}: the workers stopped before it finished")),
                    Ok(Err(e)) => Err(anyhow!("calibration {id}: worker: {e}")),
                    Err(e) => Err(anyhow!("calibration {id}: worker task: {e}")),
                };
            }
            _ = tokio::time::sleep(Duration::from_millis(100)) => {}
        }
        match client.calibration(id).await {
            Ok(next) => c = next,
            Err(e) => break Err(anyhow!("calibration {id}: {e}")),
        }
    };
    bar.clear();
    let _ = stop.send(());
    match worker.await {
        Ok(Ok(_)) => {}
        Ok(Err(e)) => return Err(anyhow!("calibration {id}: worker: {e}")),
        Err(e) => return Err(anyhow!("calibration {id}: worker task: {e}")),
    }
    outcome
}

/// Turns a calibration that has ended into what the outputs need, or into the error that ended it.
async fn finished(client: &Client, label: &str, out_dir: &Path, c: api::Calibration, wall: f64) -> Result<Run> {
    let id = c.id;
    match c.status {
        api::CalibrationStatus::Completed => {}
        api::CalibrationStatus::Cancelled => bail!(
            "{label}: the calibration in {} was cancelled; pick another --out or delete the folder to start again",
            out_dir.display()
        ),
        _ => {
            let error = c.error.clone().unwrap_or_else(|| format!("the calibration ended {}", c.status.as_str()));
            if error.starts_with("every one of") {
                let sets = client.parameter_sets(id).await.map_err(|e| anyhow!("calibration {id}: {e}"))?;
                let first = sets.iter().filter_map(|s| s.reason.clone()).min().unwrap_or_default();
                bail!("{label}: every one of the {} evaluations failed; first reason: {first}", c.evaluations);
            }
            bail!("{label}: {error}");
        }
    }
    let reports = c
        .stages
        .iter()
        .enumerate()
        .map(|(k, v)| {
            serde_json::from_value::<StageReport>(v.clone())
                .map_err(|e| anyhow!("calibration {id}: the report of stage {k} cannot be read: {e}"))
        })
        .collect::<Result<Vec<_>>>()?;
    let (Some(best_cost), Some(best_parameters)) = (c.best_cost, c.best_parameters) else {
        bail!("{label}: calibration {id} completed without a best point");
    };
    let mut rows = client.parameter_sets(id).await.map_err(|e| anyhow!("calibration {id}: {e}"))?;
    rows.retain(|r| r.status != "pending");
    rows.sort_by_key(|r| r.job);
    let stages: Vec<StageSpec> = serde_json::from_value(c.spec["stages"].clone())
        .map_err(|e| anyhow!("calibration {id}: the stored stages cannot be read: {e}"))?;
    Ok(Run {
        evaluations: c.evaluations.max(0) as usize,
        failed: c.failed_evaluations.max(0) as usize,
        budget: c.budget.max(0) as usize,
        stages,
        reports,
        best_cost,
        best_parameters,
        rows,
        wall,
    })
}

/// The solver model of an experiment (every experiment of a file-based calibration is one).
fn solver_of(e: &Experiment) -> Result<cryofit_calib::model::SolverModel> {
    let any: &dyn std::any::Any = e.model.as_any();
    any.downcast_ref::<cryofit_calib::model::SolverModel>()
        .cloned()
        .ok_or_else(|| anyhow!("experiment `{}` is not a solver model", e.name))
}

type FitRow<'a> = (&'a Experiment, cryofit_calib::cost::Fit, cryofit_solver::driver::Output);

fn result_json(spec: &CalibrationSpec, run: &Run, fits: &[FitRow<'_>], data_points: usize) -> Result<String> {
    let mut fit = serde_json::Map::new();
    for (e, f, out) in fits {
        let model = cryofit_calib::model::probes_dataset(&out.probes);
        let series: Vec<_> = f
            .series
            .iter()
            .map(|(key, s)| {
                // the clock factor that best aligns the model with the data, and the misfit left
                let aligned =
                    model.series.get(key).zip(e.data.series.get(key)).and_then(|(m, d)| cost::best_time_scale(m, d));
                json!({"station": key.0, "quantity": key.1, "rms": s.rms, "points": s.points, "cost": s.cost,
                       "time_scale": aligned.map(|a| a.0), "time_scaled_rms": aligned.map(|a| a.1)})
            })
            .collect();
        let chill: BTreeMap<String, serde_json::Value> = chilldown_pairs(&e.data, out)
            .into_iter()
            .map(|(st, (d, m))| (st, json!({"data_s": d, "model_s": m})))
            .collect();
        fit.insert(e.name.clone(), json!({"cost": f.cost, "series": series, "chilldown_time_s": chill}));
    }
    let value = json!({
        "name": spec.name,
        "seed": spec.seed,
        "best_cost": run.best_cost,
        "best_parameters": run.best_parameters,
        "fixed_parameters": spec.fixed,
        "evaluations": run.evaluations,
        "failed_evaluations": run.failed,
        "budget": run.budget,
        "data_points": data_points,
        "wall_time_s": run.wall,
        "solver_version": env!("CARGO_PKG_VERSION"),
        "stages": run.reports,
        "uncertainty": uncertainty(&run.reports),
        "fit": fit,
        "calibration": spec,
    });
    let mut text = serde_json::to_string_pretty(&value)?;
    text.push('\n');
    Ok(text)
}

/// What the ± above rest on, where it needs saying: for a Gaussian approximation whose Hessian
/// was not positive definite, that along the regularised directions its covariance is a
/// placeholder, not an estimate; for an MCMC stage, the chain behind its quantiles (its size,
/// its temperature, whether it converged). `unc` is what [`uncertainty`] chose; the note concerns
/// that stage only (an MCMC stage's ± after a variance stage need no Hessian caveat).
fn uncertainty_caveat(reports: &[StageReport], unc: &serde_json::Value) -> Option<String> {
    let stage = unc["stage"].as_u64()?;
    let r = reports.iter().find(|r| r.index as u64 == stage)?;
    if let Some(InferenceSummary::Mcmc(m)) = &r.details {
        let tempered = if m.temperature > 1.0 {
            format!(
                "; likelihood tempered at T = {} for the cost's jitter between nearby parameter sets",
                fmt_sig(m.temperature)
            )
        } else {
            String::new()
        };
        let short = m.parameters.iter().filter(|p| !p.autocorr_reliable).count();
        let disagree = m.max_r_hat.filter(|&r| r > 1.05);
        let convergence = if short == 0 && disagree.is_none() {
            "the chain is longer than 50 autocorrelation times and its walkers agree".to_string()
        } else {
            let mut why = Vec::new();
            if let Some(r) = disagree {
                why.push(format!("max split R-hat {r:.2} > 1.05"));
            }
            if short > 0 {
                why.push(format!(
                    "kept chain not longer than 50 autocorrelation times for {short} of {} parameters",
                    m.parameters.len()
                ));
            }
            format!(
                "the chain has not converged ({}): read the intervals as a first look and raise the stage's \
                 budget for estimates",
                why.join(", ")
            )
        };
        return Some(format!(
            "± and 95 % from the MCMC stage's {} samples ({} walkers × {} iterations after {} of burn-in{tempered}); \
             {convergence}",
            m.samples,
            m.walkers,
            m.iterations - m.burn_in,
            m.burn_in
        ));
    }
    let Some(InferenceSummary::Variance(v)) = &r.details else { return None };
    let g = v.gaussian.as_ref().filter(|g| !g.positive_definite)?;
    Some(format!(
        "the Hessian at the best point is not positive definite ({} of {} directions regularised): the best \
         point is not a minimum along every direction, and the ± above are placeholders along those directions, \
         not estimates (eigenvalues and warnings in result.json)",
        g.regularised,
        g.eigenvalues.len()
    ))
}

/// Why a variance stage that ran gave no Gaussian approximation (its first warning and how many
/// there are), or `None` where no variance stage ran.
fn missing_uncertainty(reports: &[StageReport]) -> Option<String> {
    reports.iter().rev().find_map(|r| match &r.details {
        Some(InferenceSummary::Variance(v)) if v.gaussian.is_none() => Some(match v.warnings.first() {
            Some(first) => format!(
                "the variance stage's Hessian could not be used ({first}; {} warning(s) in result.json)",
                v.warnings.len()
            ),
            None => "the variance stage's Hessian could not be used".to_string(),
        }),
        _ => None,
    })
}

/// Standard deviations and 95 % intervals from the last variance or MCMC stage.
fn uncertainty(reports: &[StageReport]) -> serde_json::Value {
    for r in reports.iter().rev() {
        match &r.details {
            Some(InferenceSummary::Mcmc(m)) => {
                let params: BTreeMap<&str, serde_json::Value> = m
                    .parameters
                    .iter()
                    .map(|q| {
                        (
                            r.free.get(q.index).map_or("?", String::as_str),
                            json!({"value": q.mean, "sd": q.sd, "lower95": q.quantiles.q025, "upper95": q.quantiles.q975,
                                   "median": q.quantiles.q50, "r_hat": q.r_hat}),
                        )
                    })
                    .collect();
                return json!({"method": "mcmc", "stage": r.index, "parameters": params,
                              "names": r.free, "covariance": m.covariance_physical, "correlation": m.correlation,
                              "temperature": m.temperature, "samples": m.samples, "max_r_hat": m.max_r_hat,
                              "acceptance_fraction": m.acceptance_fraction});
            }
            Some(InferenceSummary::Variance(v)) => {
                let Some(g) = &v.gaussian else { continue };
                let params: BTreeMap<&str, serde_json::Value> = r
                    .free
                    .iter()
                    .enumerate()
                    .map(|(i, name)| {
                        (
                            name.as_str(),
                            json!({"value": g.centre_physical[i], "sd": g.sd_physical[i],
                                   "lower95": g.interval95[i].lower, "upper95": g.interval95[i].upper}),
                        )
                    })
                    .collect();
                return json!({"method": "variance", "stage": r.index, "parameters": params,
                              "names": r.free, "covariance": g.covariance_physical, "correlation": g.correlation,
                              "centre_unit": g.centre_unit, "covariance_unit": g.covariance_unit,
                              "positive_definite": g.positive_definite,
                              "divergent_nearby": v.divergent.len()});
            }
            _ => {}
        }
    }
    serde_json::Value::Null
}

/// `best.toml`: the fixed and the best free values, a flat table for `cryofit simulate --params`;
/// case fields by their quoted `case.` names (`"case.inlet.loss_coefficient@run-2" = 7.9`).
fn best_toml(spec: &CalibrationSpec, best: &BTreeMap<String, f64>) -> String {
    let mut s = format!("# best parameters of calibration \"{}\" (cryofit calibrate)\n", spec.name.replace('"', "'"));
    let mut all: BTreeMap<&str, f64> = spec.fixed.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    all.extend(best.iter().map(|(k, v)| (k.as_str(), *v)));
    for (k, v) in all {
        let _ = writeln!(s, "{} = {}", crate::param_values::toml_key(k), toml_num(v));
    }
    s
}

/// A TOML float that reads back to the same value.
fn toml_num(v: f64) -> String {
    let s = fmt_num(v);
    if s.contains(['.', 'e', 'E']) || s.contains("inf") || s.contains("NaN") { s } else { format!("{s}.0") }
}

/// `evaluations.csv`: every told evaluation in the optimiser's order, its cost or failure reason
/// and the free parameters' values.
fn evaluations_csv(space: &Space, run: &Run) -> Result<String> {
    let mut t = CsvText::new(
        ["id", "stage", "algorithm", "status", "cost"].into_iter().chain(space.names()).chain(["reason"]),
    )?;
    for r in &run.rows {
        let algorithm =
            usize::try_from(r.stage).ok().and_then(|k| run.stages.get(k)).map_or("?", |st| st.algorithm.as_str());
        let (status, cost, reason) = match (r.status.as_str(), r.cost) {
            ("ok", Some(cost)) => ("ok", fmt_num(cost), String::new()),
            _ => ("failed", String::new(), r.reason.clone().unwrap_or_default()),
        };
        let mut row = vec![r.job.to_string(), r.stage.to_string(), algorithm.to_string(), status.to_string(), cost];
        row.extend(space.names().map(|name| r.parameters.get(name).map_or_else(String::new, |v| fmt_num(*v))));
        row.push(reason);
        t.row(row)?;
    }
    t.finish()
}

/// `posterior.csv`: the draws of the last stage that made some (an MCMC stage), one a row.
fn posterior_csv(reports: &[StageReport]) -> Result<Option<String>> {
    let Some(r) = reports.iter().rev().find(|r| r.posterior_draws.is_some()) else { return Ok(None) };
    let Some(draws) = r.posterior_draws.as_ref() else { return Ok(None) };
    let mut t = CsvText::new(&r.free)?;
    for d in draws {
        t.row(d.iter().map(|v| fmt_num(*v)))?;
    }
    t.finish().map(Some)
}

fn print_report(spec: &CalibrationSpec, run: &Run, fits: &[FitRow<'_>], out_dir: &Path, outputs: &[(String, String)]) {
    let (n, failed, wall) = (run.evaluations, run.failed, run.wall);
    println!(
        "calibration \"{}\": {n} evaluations ({failed} failed) in {wall:.1} s; best cost {}",
        spec.name,
        fmt_sig(run.best_cost)
    );
    for r in &run.reports {
        let best = match (r.best_cost, r.lowest_cost) {
            (None, _) => "no successful evaluation".into(),
            (Some(c), Some(low)) if low < c => {
                format!("estimate {} (its response surface's minimum; lowest evaluation {})", fmt_sig(c), fmt_sig(low))
            }
            (Some(c), _) => format!("best {}", fmt_sig(c)),
        };
        println!(
            "  stage {} {}: {} evaluations ({} failed), {best}, {} free; {}",
            r.index,
            r.algorithm,
            r.evaluations,
            r.failed_evaluations,
            r.free.len(),
            r.stop
        );
        if let (AlgorithmName::Sensitivity | AlgorithmName::Morris, Some(d)) = (r.algorithm, &r.details) {
            let ranking = match d {
                InferenceSummary::Sensitivity(s) => &s.ranking,
                InferenceSummary::Morris(m) => &m.ranking,
                _ => continue,
            };
            let top: Vec<String> = ranking
                .entries
                .iter()
                .take(8)
                .map(|e| {
                    let name = r.free.get(e.index).map_or("?", String::as_str);
                    format!("{name} {:.2}", e.normalised.unwrap_or(0.0))
                })
                .collect();
            println!("    ranking (normalised): {}", top.join(", "));
        }
    }
    let unc = uncertainty(&run.reports);
    println!("  best parameters:");
    for (name, v) in &run.best_parameters {
        let pm = unc["parameters"][name.as_str()].as_object().map(|u| {
            format!(
                "  ± {} (95 %: {} – {})",
                fmt_sig(u["sd"].as_f64().unwrap_or(f64::NAN)),
                fmt_sig(u["lower95"].as_f64().unwrap_or(f64::NAN)),
                fmt_sig(u["upper95"].as_f64().unwrap_or(f64::NAN))
            )
        });
        println!("    {name} = {}{}", fmt_sig(*v), pm.unwrap_or_default());
    }
    if unc.is_null()
        && let Some(why) = missing_uncertainty(&run.reports)
    {
        println!("  uncertainty: not estimated: {why}");
    }
    if let Some(caveat) = uncertainty_caveat(&run.reports, &unc) {
        println!("  uncertainty: {caveat}");
    }
    println!("  fit:");
    for (e, f, out) in fits {
        let rms: Vec<String> =
            f.series.iter().map(|((st, q), s)| format!("{st} {} {}", short_quantity(q), fmt_sig(s.rms))).collect();
        println!("    {}: cost {}; RMS {}", e.name, fmt_sig(f.cost), rms.join(", "));
        for (st, (d, m)) in chilldown_pairs(&e.data, out) {
            if let (Some(d), Some(m)) = (d, m) {
                println!("      {st} chilldown: model {m:.1} s, data {d:.1} s ({:+.1} %)", (m / d - 1.0) * 100.0);
            }
        }
    }
    let names: Vec<&str> = outputs.iter().map(|(n, _)| n.as_str()).collect();
    println!("  wrote {} to {}", names.join(", "), out_dir.display());
}

fn short_quantity(q: &str) -> &str {
    match q {
        "wall_temperature_k" => "wall T (K)",
        "fluid_temperature_k" => "fluid T (K)",
        "pressure_pa" => "p (Pa)",
        other => other,
    }
}

/// The progress of a calibration on stderr: stage, evaluations, best cost and ETA, redrawn at
/// most five times a second; nothing when stderr is not a terminal.
struct CalibrationProgress {
    bar: indicatif::ProgressBar,
}

impl CalibrationProgress {
    const TEMPLATE: &str = "{prefix}  [{bar:20}] evaluations {pos}/{len} {msg}";

    fn new() -> Self {
        Self { bar: crate::progress::bar(1, Self::TEMPLATE, 5) }
    }

    /// Shows the progress of `c`; `done_before` evaluations were done before this run (`elapsed`
    /// ago) started, and do not count for the ETA.
    fn update(&self, c: &api::Calibration, done_before: usize, elapsed: Duration) {
        if self.bar.is_hidden() {
            return;
        }
        let (n, failed) = (c.evaluations.max(0) as usize, c.failed_evaluations.max(0) as usize);
        let budget = (c.budget.max(0) as usize).max(1);
        let stages: Vec<&str> = c.spec["stages"]
            .as_array()
            .map(|s| s.iter().map(|st| st["algorithm"].as_str().unwrap_or("")).collect())
            .unwrap_or_default();
        let stage = (c.stage.max(0) as usize).min(stages.len().saturating_sub(1));
        let algorithm = stages.get(stage).copied().unwrap_or("");
        let here = n.saturating_sub(done_before);
        let eta = if here > 0 {
            let per = elapsed.as_secs_f64() / here as f64;
            format!("{:.0} s", per * budget.saturating_sub(n) as f64)
        } else {
            "…".into()
        };
        let best = c.best_cost.map_or_else(|| "—".into(), fmt_sig);
        self.bar.set_length(budget as u64);
        self.bar.set_position(n as u64);
        self.bar.set_prefix(format!("stage {}/{} {algorithm}", stage + 1, stages.len()));
        self.bar.set_message(format!("({failed} failed)  best cost {best}  ETA ≤ {eta}"));
    }

    fn clear(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A variance stage (as `result.json` stores it) whose Hessian could not be computed.
    fn variance_stage(warnings: &[&str], gaussian_missing: bool) -> StageReport {
        let mut stage = json!({
            "algorithm": "variance", "best_cost": 2.0, "best_parameters": {"qmfbsc": 0.5}, "budget": 8,
            "evaluations": 8, "failed_evaluations": 3, "free": ["qmfbsc"], "index": 1,
            "posterior_draws": null, "stop": "converged",
            "details": {"variance": {
                "budget": 8, "divergent": [], "evaluations": 8, "gaussian": null, "hessian_evaluations": 3,
                "optimum_cost": 2.0, "optimum_physical": [0.5], "optimum_unit": [0.0], "profiles": [],
                "restart_spread_unit": null, "restarts": [], "stage": null,
                "stop": {"kind": "converged", "message": "done"}, "warnings": warnings,
            }},
        });
        if !gaussian_missing {
            stage["details"] = serde_json::Value::Null;
        }
        serde_json::from_value(stage).unwrap()
    }

    #[test]
    fn a_gaussian_from_an_indefinite_hessian_is_flagged() {
        let gaussian = |positive_definite: bool| {
            let mut v = serde_json::to_value(variance_stage(&[], true)).unwrap();
            v["details"]["variance"]["gaussian"] = json!({
                "centre_physical": [0.5], "centre_unit": [0.5], "correlation": [[1.0]], "cost": 2.0,
                "cost_noise": null, "covariance_physical": [[1e6]], "covariance_unit": [[1e6]],
                "eigenvalues": [-3.0], "hessian_unit": [[-3.0]],
                "interval95": [{"clamped": true, "lower": 0.25, "upper": 4.0}], "log_det_half_hessian": 0.0,
                "noise_inflation": 1.0, "positive_definite": positive_definite,
                "regularised": if positive_definite { 0 } else { 1 }, "sd_physical": [1e3], "sd_unit": [1e3],
            });
            serde_json::from_value::<StageReport>(v).unwrap()
        };
        let caveat_of = |reports: &[StageReport]| uncertainty_caveat(reports, &uncertainty(reports));
        let caveat = caveat_of(&[gaussian(false)]).unwrap();
        assert!(caveat.contains("not positive definite (1 of 1 directions regularised)"), "{caveat}");
        assert_eq!(caveat_of(&[gaussian(true)]), None);
        assert_eq!(caveat_of(&[variance_stage(&[], true)]), None);
    }

    /// The reports of a one-parameter MCMC stage of `budget` evaluations at `temperature` on
    /// the cost `((x − 0.5)/0.05)²`.
    fn mcmc_reports(budget: usize, temperature: f64) -> Vec<StageReport> {
        use cryofit_calib::config::Temperature;
        use cryofit_calib::{Evaluation, FreeParameter, Outcome, Scale};
        let space =
            Space::new(vec![FreeParameter { name: "a".into(), lower: 0.0, upper: 1.0, scale: Scale::Linear }]).unwrap();
        let mut stage = StageSpec::new(AlgorithmName::Mcmc, budget);
        stage.temperature = Some(Temperature::Value(temperature));
        let mut p = Pipeline::new(space, vec![stage], vec![0.5], 3).unwrap();
        while !p.is_finished() {
            let told: Vec<Evaluation> = p
                .ask(64)
                .iter()
                .map(|j| Evaluation {
                    id: j.id,
                    outcome: Outcome::Ok { cost: ((j.parameters["a"] - 0.5) / 0.05).powi(2) },
                })
                .collect();
            p.tell(&told).unwrap();
        }
        p.reports().to_vec()
    }

    #[test]
    fn an_mcmc_stage_says_what_its_intervals_rest_on() {
        let caveat_of = |reports: &[StageReport]| uncertainty_caveat(reports, &uncertainty(reports)).unwrap();
        let short = caveat_of(&mcmc_reports(16 * 12, 40.0));
        assert!(short.contains("16 walkers × 6 iterations after 5 of burn-in"), "{short}");
        assert!(short.contains("tempered at T = 40"), "{short}");
        assert!(short.contains("has not converged") && short.contains("raise the stage's budget"), "{short}");
        let long = caveat_of(&mcmc_reports(16 * 6000, 1.0));
        assert!(!long.contains("tempered"), "{long}");
        assert!(long.contains("longer than 50 autocorrelation times and its walkers agree"), "{long}");
    }

    #[test]
    fn the_progress_template_parses() {
        assert!(indicatif::ProgressStyle::with_template(CalibrationProgress::TEMPLATE).is_ok());
    }

    #[test]
    fn a_variance_stage_without_a_gaussian_says_why() {
        let why =
            missing_uncertainty(&[variance_stage(&["Hessian diagonal 0 (qmfbsc) could not be computed", "x"], true)])
                .unwrap();
        assert!(why.contains("Hessian diagonal 0 (qmfbsc) could not be computed"), "{why}");
        assert!(why.contains("2 warning(s) in result.json"), "{why}");
        assert!(missing_uncertainty(&[variance_stage(&[], true)]).unwrap().contains("could not be used"));
        // no variance stage, nothing to explain
        assert_eq!(missing_uncertainty(&[variance_stage(&[], false)]), None);
        assert!(uncertainty(&[variance_stage(&[], true)]).is_null());
    }
}
