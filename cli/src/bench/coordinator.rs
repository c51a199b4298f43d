//! `cryofit bench coordinator --workers N --evaluations M [--batch B] [--per-job-results] [--json]`:
//! throughput of the coordinator's whole path with a null model.
//!
//! A real coordinator (the same routes, SQLite transactions and pipeline tell/persist as
//! `cryofit serve`) starts in-process on a loopback port with a temporary database. One experiment
//! (a small case that is validated but never simulated) and a 14-parameter annealing calibration
//! with a budget of M evaluations are submitted over HTTP. N tokio tasks then act as workers
//! through the worker crate's HTTP client: claim up to B jobs, evaluate a cheap analytic cost
//! instead of the solver (the null model), report the results — one `POST /jobs/results` per claim,
//! or one `POST /jobs/{id}/result` per job with `--per-job-results` — until the calibration is
//! complete. The clock runs from the first claim to the completion; the calibration's status, its
//! evaluation count and its history are checked at the end.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_api as api;
use cryofit_calib::config::{AlgorithmName, ParameterSpec, StageSpec, WeightSpec};
use cryofit_solver::params::REGISTRY;
use cryofit_worker::{Client, ClientError};
use serde::Serialize;

/// Arguments of `cryofit bench coordinator`.
#[derive(Debug, Args)]
pub struct CoordinatorArgs {
    /// Concurrent worker tasks.
    #[arg(long, value_name = "N", default_value_t = 2)]
    workers: usize,
    /// Evaluations: the calibration's budget.
    #[arg(long, value_name = "M", default_value_t = 20_000)]
    evaluations: usize,
    /// Jobs a worker task claims at once (1–1000).
    #[arg(long, value_name = "B", default_value_t = 64)]
    batch: usize,
    /// Report every result with its own `POST /jobs/{id}/result` instead of one batched
    /// `POST /jobs/results` per claim.
    #[arg(long)]
    per_job_results: bool,
    /// Print the summary as JSON (the last line).
    #[arg(long)]
    json: bool,
}

/// Free parameters of the benchmark calibration (the Optuna peer has 14 too).
const PARAMETERS: usize = 14;

/// A small case: validated when the experiment is stored, never simulated.
const CASE: &str = r#"title = "coordinator benchmark (never simulated)"
[fluid]
name = "nitrogen"
[pipe]
length_m = 10.0
inner_diameter_m = 0.015875
wall_thickness_m = 0.0015875
wall_material = "copper"
roughness_m = 1.5e-6
inclination_deg = 0.0
cells = 5
[inlet]
kind = "reservoir"
pressure_pa = 425565.0
temperature_k = 76.0
valve_opening_time_s = 2.0
loss_coefficient = 10.0
[outlet]
kind = "pressure"
pressure_pa = 83087.0
void_fraction = 1.0
gas_temperature_k = 290.0
[initial]
pressure_pa = 83087.0
void_fraction = 1.0
gas_temperature_k = 290.0
wall_temperature_k = 290.0
[ambient]
temperature_k = 290.0
heat_transfer_coefficient_w_m2k = 0.0
[time]
end_s = 2.0
output_interval_s = 1.0
profile_interval_s = 2.0
max_dt_s = 0.5
[[stations]]
name = "TS1"
x_m = 5.0
"#;

const DATA: &str = "time_s,station,x_m,quantity,value\n1,TS1,5.0,wall_temperature_k,289.0\n";

/// The null model: a shifted sphere in the parameters' relative values.
fn null_cost(parameters: &BTreeMap<String, f64>) -> f64 {
    parameters
        .iter()
        .map(|(name, v)| {
            let (lo, hi) = REGISTRY.iter().find(|p| p.name == name).map_or((0.0, 1.0), |p| (p.lower, p.upper));
            let u = (v - lo) / (hi - lo) - 0.3;
            u * u
        })
        .sum()
}

/// The calibration: the first 14 non-numerics registry parameters with bounds, annealing.
fn calibration(experiment: i64, evaluations: usize, generation: usize) -> api::CreateCalibration {
    let parameters = REGISTRY
        .iter()
        .filter(|p| p.group != "numerics" && p.upper > p.lower)
        .take(PARAMETERS)
        .map(|p| ParameterSpec {
            name: p.name.to_string(),
            lower: None,
            upper: None,
            scale: None,
            experiments: None,
            start: None,
        })
        .collect();
    let mut stage = StageSpec::new(AlgorithmName::Annealing, evaluations);
    stage.population = Some(generation);
    api::CreateCalibration {
        name: "coordinator benchmark".into(),
        description: Some("null model".into()),
        seed: 1,
        experiments: vec![experiment],
        parameters,
        fixed: BTreeMap::new(),
        weights: [("wall_temperature_k".to_string(), WeightSpec { weight: 1.0, sigma: 1.0 })].into(),
        stages: vec![stage],
        max_evaluation_s: None,
    }
}

/// What one worker task measured.
#[derive(Debug, Default)]
struct Tally {
    claims: usize,
    empty_claims: usize,
    result_requests: usize,
    counted: usize,
    claim_ms: Vec<f64>,
    result_ms: Vec<f64>,
}

/// The summary (`--json` prints it as the last line).
#[derive(Debug, Serialize)]
struct Summary {
    evaluations_per_s: f64,
    evaluations: usize,
    workers: usize,
    wall_s: f64,
    claim_latency_ms_p50: f64,
    claim_latency_ms_p90: f64,
    claim_latency_ms_p99: f64,
    result_latency_ms_p50: f64,
    result_latency_ms_p90: f64,
    result_latency_ms_p99: f64,
    batch: usize,
    generation: usize,
    results_endpoint: &'static str,
    claims: usize,
    empty_claims: usize,
    result_requests: usize,
    parameters: usize,
}

/// The `q` quantile (nearest rank) of `v`, 0 when empty.
fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let k = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    v[k]
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// One worker task: claim, evaluate the null model, report, until the calibration is done.
async fn worker(
    client: Client,
    name: String,
    batch: usize,
    per_job: bool,
    hashes: BTreeMap<String, String>,
    done: Arc<AtomicBool>,
    calibration: i64,
) -> Result<Tally, ClientError> {
    let mut t = Tally::default();
    let req = api::ClaimRequest {
        worker: name.clone(),
        slots: batch as u32,
        max_jobs: batch as u32,
        solver_version: api::SOLVER_VERSION.to_string(),
        fluid_hashes: hashes,
    };
    let mut idle = Duration::from_micros(200);
    while !done.load(Ordering::Relaxed) {
        let started = Instant::now();
        let claimed = client.claim(&req).await?;
        t.claim_ms.push(ms(started));
        t.claims += 1;
        if claimed.jobs.is_empty() {
            t.empty_claims += 1;
            // a generation boundary (another task holds its last jobs) or the end
            if client.calibration(calibration).await?.status.is_final() {
                done.store(true, Ordering::Relaxed);
                break;
            }
            tokio::time::sleep(idle).await;
            idle = (idle * 2).min(Duration::from_millis(5));
            continue;
        }
        idle = Duration::from_micros(200);
        let results: Vec<api::JobResult> = claimed
            .jobs
            .iter()
            .map(|j| {
                let evaluated = Instant::now();
                let cost = null_cost(&j.parameters);
                api::JobResult {
                    job_id: j.id,
                    lease_id: j.lease_id.clone(),
                    outcome: api::JobOutcome::Ok { cost },
                    duration_s: Some(evaluated.elapsed().as_secs_f64()),
                    breakdown: None,
                    worker: Some(name.clone()),
                }
            })
            .collect();
        if per_job {
            for r in results {
                let started = Instant::now();
                let req = api::ResultRequest {
                    lease_id: r.lease_id,
                    outcome: r.outcome,
                    duration_s: r.duration_s,
                    breakdown: None,
                    worker: r.worker,
                };
                let resp = client.result(r.job_id, &req).await?;
                t.result_ms.push(ms(started));
                t.result_requests += 1;
                t.counted += usize::from(resp.counted);
            }
        } else {
            let started = Instant::now();
            let resp = client.report(&api::ResultBatch { results }).await?;
            t.result_ms.push(ms(started));
            t.result_requests += 1;
            t.counted += resp.results.iter().filter(|r| r.counted).count();
        }
    }
    Ok(t)
}

/// Runs the benchmark.
pub fn run(args: &CoordinatorArgs) -> Result<()> {
    if !(1..=1024).contains(&args.workers) {
        bail!("--workers {}: give 1 to 1024 worker tasks", args.workers);
    }
    if !(10..=10_000_000).contains(&args.evaluations) {
        bail!("--evaluations {}: give 10 to 10 000 000", args.evaluations);
    }
    if !(1..=1000).contains(&args.batch) {
        bail!("--batch {}: give 1 to 1000 jobs per claim", args.batch);
    }
    // a generation large enough that the tasks seldom wait for each other at its end
    let generation = (4 * args.workers * args.batch).clamp(8, args.evaluations);
    let dir = std::env::temp_dir().join(format!("cryofit-bench-coordinator-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let rt = tokio::runtime::Runtime::new().context("cannot start the async runtime")?;
    let outcome = rt.block_on(measure(args, generation, &dir.join("bench.sqlite")));
    std::fs::remove_dir_all(&dir).ok();
    let summary = outcome?;
    print(&summary, args.json)
}

async fn measure(args: &CoordinatorArgs, generation: usize, database: &std::path::Path) -> Result<Summary> {
    let fluids = crate::serve::fluid_loader();
    let mut settings = cryofit_server::Settings::new(database.display().to_string());
    settings.fluids = fluids.clone();
    let server = cryofit_server::start_embedded(database, settings).await?;
    let client = Client::new(&server.url(), None)?.with_retry_for(Duration::from_secs(10));
    let experiment = client
        .create_experiment(&api::CreateExperiment { name: "bench".into(), case: CASE.into(), data: DATA.into() })
        .await
        .map_err(|e| anyhow!("storing the benchmark experiment: {e}"))?;
    let id = client
        .create_calibration(&calibration(experiment.id, args.evaluations, generation))
        .await
        .map_err(|e| anyhow!("creating the benchmark calibration: {e}"))?
        .id;
    let hashes = cryofit_worker::fluid_hashes(&fluids);
    let done = Arc::new(AtomicBool::new(false));
    let started = Instant::now();
    let tasks: Vec<_> = (0..args.workers)
        .map(|k| {
            tokio::spawn(worker(
                client.clone(),
                format!("bench-{k}"),
                args.batch,
                args.per_job_results,
                hashes.clone(),
                done.clone(),
                id,
            ))
        })
        .collect();
    let mut tally = Tally::default();
    for t in tasks {
        let t = t.await.map_err(|e| anyhow!("worker task: {e}"))?.map_err(|e| anyhow!("worker task: {e}"))?;
        tally.claims += t.claims;
        tally.empty_claims += t.empty_claims;
        tally.result_requests += t.result_requests;
        tally.counted += t.counted;
        tally.claim_ms.extend(t.claim_ms);
        tally.result_ms.extend(t.result_ms);
    }
    let wall = started.elapsed().as_secs_f64();
    let c = client.calibration(id).await.map_err(|e| anyhow!("calibration {id}: {e}"))?;
    if c.status != api::CalibrationStatus::Completed || c.evaluations != args.evaluations as i64 {
        bail!(
            "the benchmark calibration ended {} with {} of {} evaluations: {}",
            c.status.as_str(),
            c.evaluations,
            args.evaluations,
            c.error.unwrap_or_default()
        );
    }
    let sets = client.parameter_sets(id).await.map_err(|e| anyhow!("calibration {id} history: {e}"))?;
    if sets.len() != args.evaluations || sets.iter().any(|s| s.status != "ok") || tally.counted != args.evaluations {
        bail!(
            "the history holds {} parameter sets ({} not ok) and {} results were counted; expected {} of each",
            sets.len(),
            sets.iter().filter(|s| s.status != "ok").count(),
            tally.counted,
            args.evaluations
        );
    }
    server.stop().await?;
    Ok(Summary {
        evaluations_per_s: args.evaluations as f64 / wall,
        evaluations: args.evaluations,
        workers: args.workers,
        wall_s: wall,
        claim_latency_ms_p50: quantile(&mut tally.claim_ms, 0.5),
        claim_latency_ms_p90: quantile(&mut tally.claim_ms, 0.9),
        claim_latency_ms_p99: quantile(&mut tally.claim_ms, 0.99),
        result_latency_ms_p50: quantile(&mut tally.result_ms, 0.5),
        result_latency_ms_p90: quantile(&mut tally.result_ms, 0.9),
        result_latency_ms_p99: quantile(&mut tally.result_ms, 0.99),
        batch: args.batch,
        generation,
        results_endpoint: if args.per_job_results { "POST /jobs/{id}/result" } else { "POST /jobs/results" },
        claims: tally.claims,
        empty_claims: tally.empty_claims,
        result_requests: tally.result_requests,
        parameters: PARAMETERS,
    })
}

fn print(s: &Summary, json: bool) -> Result<()> {
    println!(
        "coordinator throughput: {} evaluations of a {}-parameter annealing calibration (generation {}), null model",
        s.evaluations, s.parameters, s.generation
    );
    println!("  {} worker tasks, {} jobs per claim, results through {}", s.workers, s.batch, s.results_endpoint);
    println!("  {:<22} {:>10}", "wall time (s)", format!("{:.3}", s.wall_s));
    println!("  {:<22} {:>10}", "evaluations/s", format!("{:.0}", s.evaluations_per_s));
    println!("  {:<22} {:>10} {:>10} {:>10}", "latency (ms)", "p50", "p90", "p99");
    println!(
        "  {:<22} {:>10.3} {:>10.3} {:>10.3}",
        "claim", s.claim_latency_ms_p50, s.claim_latency_ms_p90, s.claim_latency_ms_p99
    );
    println!(
        "  {:<22} {:>10.3} {:>10.3} {:>10.3}",
        "result", s.result_latency_ms_p50, s.result_latency_ms_p90, s.result_latency_ms_p99
    );
    println!("  {:<22} {:>10}  ({} empty)", "claims", s.claims, s.empty_claims);
    println!("  {:<22} {:>10}", "result requests", s.result_requests);
    if json {
        println!("{}", serde_json::to_string(s)?);
    }
    Ok(())
}
