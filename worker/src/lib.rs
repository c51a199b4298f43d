//! The cryofit worker: claims jobs from a coordinator over HTTP, runs them on a rayon pool (never
//! on tokio's threads), heartbeats their leases and reports costs.
//!
//! The worker keeps up to twice its slots of jobs in hand (running plus prefetched) so slots never
//! wait for a claim round trip. Experiments are fetched once and cached by (calibration,
//! experiment). When the coordinator is away, requests are retried with backoff and jitter. On
//! shutdown (SIGTERM) the worker stops claiming, finishes the jobs it holds, reports them and
//! exits.

#![warn(missing_docs)]

pub mod client;

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::future::Future;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cryofit_api as api;
use cryofit_calib::cost::{self, Weight, Weights};
use cryofit_calib::problem::{Experiment, experiment_from_texts};
use cryofit_solver::fluids::FluidTable;
use cryofit_solver::params::ParameterSet;

pub use client::{Client, ClientError};

/// Loads a fluid table by name and returns it with [`cryofit_api::fluid_hash`] of its bytes.
pub type FluidLoader = Arc<dyn Fn(&str) -> Result<(Arc<FluidTable>, String), String> + Send + Sync>;

/// Worker settings.
#[derive(Debug, Clone)]
pub struct WorkerSettings {
    /// Simulations run at once.
    pub slots: usize,
    /// Exit after this long without jobs.
    pub exit_when_idle: Option<Duration>,
    /// Name reported to the coordinator (unique per process).
    pub name: String,
}

impl WorkerSettings {
    /// `slots` slots, named after the host and process id.
    pub fn new(slots: usize) -> Self {
        let host = std::env::var("HOSTNAME").ok().filter(|h| !h.is_empty()).unwrap_or_else(|| "worker".into());
        Self { slots: slots.max(1), exit_when_idle: None, name: format!("{host}-{}", std::process::id()) }
    }
}

/// Why the worker stopped with an error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WorkerError {
    /// The coordinator refused or could not be reached.
    #[error(transparent)]
    Client(#[from] ClientError),
    /// The thread pool could not start.
    #[error("cannot start {slots} worker threads: {message}")]
    Pool {
        /// Slots asked for.
        slots: usize,
        /// Why.
        message: String,
    },
}

/// What a worker did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Summary {
    /// Results reported and counted.
    pub counted: usize,
    /// Results reported but stale (the lease had expired).
    pub stale: usize,
    /// Evaluations that failed.
    pub failed: usize,
}

/// A prepared experiment with the cost weights of its calibration.
#[derive(Debug)]
struct Prepared {
    experiment: Experiment,
    weights: Weights,
}

/// Runs one job: the model at the job's parameters and the cost against the data. Panics in the
/// model become failed evaluations.
fn evaluate(p: &Prepared, parameters: &BTreeMap<String, f64>) -> (api::JobOutcome, Option<Vec<api::SeriesCost>>) {
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let out = p.experiment.model.evaluate(parameters)?;
        cost::fit(&out, &p.experiment.data, &p.weights)
    }));
    match run {
        Ok(Ok(fit)) => {
            let breakdown = fit
                .series
                .iter()
                .map(|((station, quantity), s)| api::SeriesCost {
                    station: station.clone(),
                    quantity: quantity.clone(),
                    cost: s.cost,
                    rms: s.rms,
                    points: s.points as u64,
                })
                .collect();
            if fit.cost.is_finite() && fit.cost >= 0.0 {
                (api::JobOutcome::Ok { cost: fit.cost }, Some(breakdown))
            } else {
                (api::JobOutcome::Failed { reason: format!("the cost is {} (not finite)", fit.cost) }, None)
            }
        }
        Ok(Err(reason)) => {
            (api::JobOutcome::Failed { reason: format!("experiment `{}`: {reason}", p.experiment.name) }, None)
        }
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            (api::JobOutcome::Failed { reason: format!("the model panicked: {msg}") }, None)
        }
    }
}

/// Fluid hashes of every fluid the loader knows.
pub fn fluid_hashes(fluids: &FluidLoader) -> BTreeMap<String, String> {
    cryofit_solver::fluids::EMBEDDED_FLUIDS
        .iter()
        .filter_map(|name| fluids(name).ok().map(|(_, h)| (name.to_string(), h)))
        .collect()
}

/// A job in hand.
#[derive(Debug)]
struct Held {
    job: api::LeasedJob,
    started: Option<Instant>,
}

/// Messages to the main loop.
enum Event {
    Done { job: i64, outcome: api::JobOutcome, breakdown: Option<Vec<api::SeriesCost>>, seconds: f64 },
    Reported { job: i64, response: Result<api::ResultResponse, ClientError>, failed: bool },
    Prepared { key: (i64, i64), result: Result<Arc<Prepared>, String> },
    Lost { job: i64 },
}

/// Runs the worker until `shutdown` resolves (then drains: finishes and reports the jobs in hand)
/// or, with [`WorkerSettings::exit_when_idle`], until it has had no job for that long.
pub async fn run(
    client: Client,
    settings: WorkerSettings,
    fluids: FluidLoader,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<Summary, WorkerError> {
    let slots = settings.slots.max(1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(slots)
        .thread_name(|i| format!("cryofit-eval-{i}"))
        .build()
        .map_err(|e| WorkerError::Pool { slots, message: e.to_string() })?;
    let pool = Arc::new(pool);
    let hashes = fluid_hashes(&fluids);
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Event>();
    let mut summary = Summary::default();
    let mut held: HashMap<i64, Held> = HashMap::new();
    let mut waiting: VecDeque<i64> = VecDeque::new();
    let mut running = 0usize;
    let mut reporting = 0usize;
    let mut contexts: HashMap<i64, api::JobContext> = HashMap::new();
    let mut prepared: HashMap<(i64, i64), Result<Arc<Prepared>, String>> = HashMap::new();
    let mut preparing: std::collections::HashSet<(i64, i64)> = Default::default();
    let mut refused_logged: std::collections::HashSet<i64> = Default::default();
    let mut draining = false;
    let mut idle_since = Instant::now();
    let mut next_claim = Instant::now();
    let mut claim_delay = Duration::from_millis(50);
    let mut heartbeat = tokio::time::interval(Duration::from_secs(5));
    heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut lease_s = 30.0f64;
    tokio::pin!(shutdown);

    loop {
        // dispatch waiting jobs whose experiment is ready onto free slots
        let mut k = 0;
        while running < slots && k < waiting.len() {
            let id = waiting[k];
            let Some(h) = held.get_mut(&id) else {
                waiting.remove(k);
                continue;
            };
            let key = (h.job.calibration_id, h.job.experiment_id);
            match prepared.get(&key) {
                Some(Ok(p)) => {
                    waiting.remove(k);
                    running += 1;
                    h.started = Some(Instant::now());
                    let p = p.clone();
                    let parameters = h.job.parameters.clone();
                    let tx = tx.clone();
                    let span = tracing::info_span!("job", job = id, calibration = key.0, experiment = key.1);
                    pool.spawn(move || {
                        let _g = span.enter();
                        let t = Instant::now();
                        let (outcome, breakdown) = evaluate(&p, &parameters);
                        let _ =
                            tx.send(Event::Done { job: id, outcome, breakdown, seconds: t.elapsed().as_secs_f64() });
                    });
                }
                Some(Err(reason)) => {
                    waiting.remove(k);
                    let _ = tx.send(Event::Done {
                        job: id,
                        outcome: api::JobOutcome::Failed { reason: reason.clone() },
                        breakdown: None,
                        seconds: 0.0,
                    });
                    running += 1;
                }
                None => {
                    if preparing.insert(key) {
                        spawn_prepare(&client, &fluids, key, contexts.get(&key.0).cloned(), tx.clone());
                    }
                    k += 1;
                }
            }
        }

        let in_hand = held.len();
        if held.is_empty() && reporting == 0 {
            if draining {
                break;
            }
            if let Some(limit) = settings.exit_when_idle
                && idle_since.elapsed() >= limit
            {
                tracing::info!(idle_s = limit.as_secs_f64(), "idle: exiting");
                break;
            }
        } else {
            idle_since = Instant::now();
        }

        // claim more when below twice the slots
        if !draining && in_hand < 2 * slots && Instant::now() >= next_claim {
            let req = api::ClaimRequest {
                worker: settings.name.clone(),
                slots: slots as u32,
                max_jobs: (2 * slots - in_hand).min(1000) as u32,
                solver_version: api::SOLVER_VERSION.to_string(),
                fluid_hashes: hashes.clone(),
            };
            let claimed = tokio::select! {
                r = client.claim(&req) => Some(r),
                _ = &mut shutdown => { draining = true; None }
            };
            match claimed {
                Some(Ok(resp)) => {
                    for r in &resp.refused {
                        if refused_logged.insert(r.calibration_id) {
                            tracing::warn!(calibration = r.calibration_id, reason = %r.reason, "refused jobs of a calibration");
                        }
                    }
                    for c in resp.calibrations {
                        contexts.insert(c.calibration_id, c);
                    }
                    if resp.jobs.is_empty() {
                        next_claim = Instant::now() + claim_delay;
                        claim_delay = (claim_delay * 2).min(Duration::from_millis(500));
                    } else {
                        claim_delay = Duration::from_millis(50);
                        for j in resp.jobs {
                            lease_s = j.lease_s;
                            waiting.push_back(j.id);
                            held.insert(j.id, Held { job: j, started: None });
                        }
                        let period = Duration::from_secs_f64((lease_s / 3.0).clamp(0.05, 10.0));
                        if heartbeat.period() != period {
                            heartbeat = tokio::time::interval(period);
                            heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
                        }
                    }
                    continue;
                }
                Some(Err(e)) => {
                    if matches!(e, ClientError::Api { status: 401 | 403, .. }) {
                        return Err(e.into());
                    }
                    tracing::warn!(error = %e, "claim failed");
                    next_claim = Instant::now() + Duration::from_secs(1);
                }
                None => {}
            }
        }

        let wait = next_claim.saturating_duration_since(Instant::now()).max(Duration::from_millis(5));
        tokio::select! {
            ev = rx.recv() => {
                let Some(ev) = ev else { break };
                match ev {
                    Event::Done { job, outcome, breakdown, seconds } => {
                        running = running.saturating_sub(1);
                        let Some(h) = held.get(&job) else { continue };
                        let failed = matches!(outcome, api::JobOutcome::Failed { .. });
                        let req = api::ResultRequest {
                            lease_id: h.job.lease_id.clone(),
                            outcome,
                            duration_s: Some(seconds),
                            breakdown,
                            worker: Some(settings.name.clone()),
                        };
                        reporting += 1;
                        let client = client.clone();
                        let tx = tx.clone();
                        tokio::spawn(async move {
                            let response = client.result(job, &req).await;
                            let _ = tx.send(Event::Reported { job, response, failed });
                        });
                    }
                    Event::Reported { job, response, failed } => {
                        reporting -= 1;
                        held.remove(&job);
                        // a counted result may have completed a generation: claim again at once
                        next_claim = Instant::now();
                        claim_delay = Duration::from_millis(50);
                        match response {
                            Ok(r) if r.counted => {
                                summary.counted += 1;
                                if failed { summary.failed += 1; }
                            }
                            Ok(_) => summary.stale += 1,
                            Err(e) => tracing::error!(job, error = %e, "result could not be reported"),
                        }
                    }
                    Event::Prepared { key, result } => {
                        preparing.remove(&key);
                        if let Err(e) = &result {
                            tracing::error!(calibration = key.0, experiment = key.1, error = %e, "cannot prepare experiment");
                        }
                        prepared.insert(key, result);
                    }
                    Event::Lost { job } => {
                        // a lease that is not current: drop the job if it has not started
                        if held.get(&job).is_some_and(|h| h.started.is_none()) {
                            held.remove(&job);
                            waiting.retain(|&j| j != job);
                        }
                    }
                }
            }
            _ = heartbeat.tick() => {
                for h in held.values() {
                    let (client, tx, id, lease) = (client.clone(), tx.clone(), h.job.id, h.job.lease_id.clone());
                    tokio::spawn(async move {
                        match client.heartbeat(id, &lease).await {
                            Ok(r) if r.cancelled => { let _ = tx.send(Event::Lost { job: id }); }
                            Ok(_) => {}
                            Err(ClientError::Api { status: 404 | 409, .. }) => { let _ = tx.send(Event::Lost { job: id }); }
                            Err(e) => tracing::warn!(job = id, error = %e, "heartbeat failed"),
                        }
                    });
                }
            }
            _ = &mut shutdown, if !draining => {
                tracing::info!(jobs = held.len(), "shutdown: finishing the jobs in hand");
                draining = true;
            }
            _ = tokio::time::sleep(wait) => {}
        }
    }
    Ok(summary)
}

/// Fetches an experiment and builds it for a calibration on a blocking thread.
fn spawn_prepare(
    client: &Client,
    fluids: &FluidLoader,
    key: (i64, i64),
    context: Option<api::JobContext>,
    tx: tokio::sync::mpsc::UnboundedSender<Event>,
) {
    let client = client.clone();
    let fluids = fluids.clone();
    tokio::spawn(async move {
        let result = async {
            let ctx = context.ok_or_else(|| format!("no settings for calibration {}", key.0))?;
            let text = client.experiment(key.1).await.map_err(|e| format!("experiment {}: {e}", key.1))?;
            tokio::task::spawn_blocking(move || build(&text, &ctx, &fluids))
                .await
                .map_err(|e| format!("preparing experiment {}: {e}", key.1))?
        }
        .await;
        let _ = tx.send(Event::Prepared { key, result });
    });
}

fn build(e: &api::Experiment, ctx: &api::JobContext, fluids: &FluidLoader) -> Result<Arc<Prepared>, String> {
    let mut fixed = ParameterSet::new();
    for (name, &v) in &ctx.fixed {
        fixed.set(name, v).map_err(|err| format!("fixed.{name}: {err}"))?;
    }
    let loader = |n: &str| fluids(n).map(|(t, _)| t);
    let experiment = experiment_from_texts(
        &e.name,
        &e.case,
        &format!("experiment {} case", e.id),
        &e.data,
        &format!("experiment {} data", e.id),
        loader,
        &fixed,
        Some(ctx.max_evaluation_s),
    )?;
    let weights =
        Weights(ctx.weights.iter().map(|(q, w)| (q.clone(), Weight { weight: w.weight, sigma: w.sigma })).collect());
    Ok(Arc::new(Prepared { experiment, weights }))
}

/// Resolves on SIGTERM or Ctrl-C.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = term => {}
    }
}
