//! The cryofit worker: claims jobs from a coordinator over HTTP, runs them on a rayon pool (never
//! on tokio's threads), heartbeats their leases and reports costs.
//!
//! The worker keeps up to twice its slots of jobs in hand (running plus prefetched) so slots never
//! wait for a claim round trip. Experiments are fetched once and kept by (calibration,
//! experiment) in a cache bounded in bytes (least recently used first out); fluid tables are
//! loaded once per process and shared by every experiment. A download that fails for a passing
//! reason (the coordinator away, 429, 5xx) is retried with backoff and never remembered: a job
//! fails only for its own reasons. When the coordinator is away, requests are retried with
//! backoff and jitter. On shutdown (SIGTERM) the worker stops claiming and starting jobs,
//! finishes and reports the evaluations running, and exits — after at most
//! [`WorkerSettings::drain_timeout`], abandoning an evaluation still running then (its lease
//! expires and the job is handed out again).

#![warn(missing_docs)]

pub mod client;

use std::collections::{BTreeMap, HashMap, HashSet, VecDeque};
use std::future::Future;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cryofit_api as api;
use cryofit_calib::cost::{Weight, Weights};
use cryofit_calib::problem::{Experiment, Fixed, evaluate_and_fit, experiment_from_texts};
use cryofit_solver::fluids::FluidTable;

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
    /// On shutdown, how long running evaluations may take to finish before the worker exits
    /// without them.
    pub drain_timeout: Duration,
    /// Bytes of prepared experiments kept (least recently used first out).
    pub cache_bytes: usize,
}

/// Default [`WorkerSettings::drain_timeout`]: 60 s.
pub const DEFAULT_DRAIN_TIMEOUT: Duration = Duration::from_secs(60);

/// Default [`WorkerSettings::cache_bytes`]: 64 MiB.
pub const DEFAULT_CACHE_BYTES: usize = 64 * 1024 * 1024;

impl WorkerSettings {
    /// `slots` slots, named after the host and process id.
    pub fn new(slots: usize) -> Self {
        let host = std::env::var("HOSTNAME").ok().filter(|h| !h.is_empty()).unwrap_or_else(|| "worker".into());
        Self {
            slots: slots.max(1),
            exit_when_idle: None,
            name: format!("{host}-{}", std::process::id()),
            drain_timeout: DEFAULT_DRAIN_TIMEOUT,
            cache_bytes: DEFAULT_CACHE_BYTES,
        }
    }
}

/// A loader that loads each fluid table once and hands out the same `Arc` afterwards, so that
/// every prepared experiment of a fluid shares one table.
pub fn shared_fluids(inner: FluidLoader) -> FluidLoader {
    let loaded: std::sync::Mutex<HashMap<String, (Arc<FluidTable>, String)>> = Default::default();
    Arc::new(move |name: &str| {
        let key = cryofit_solver::fluids::canonical_name(name).unwrap_or(name).to_string();
        let mut map = loaded.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((t, h)) = map.get(&key) {
            return Ok((t.clone(), h.clone()));
        }
        let (t, h) = inner(name)?;
        map.insert(key, (t.clone(), h.clone()));
        Ok((t, h))
    })
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
    /// Bytes it holds (its data; the fluid table is shared).
    bytes: usize,
}

/// Prepared experiments by (calibration, experiment), at most a number of bytes of them: the
/// least recently used go first. Jobs running hold their own reference, so an evicted entry lives
/// until they end.
#[derive(Debug)]
struct PreparedCache {
    entries: HashMap<(i64, i64), (Arc<Prepared>, u64)>,
    bytes: usize,
    limit: usize,
    clock: u64,
}

impl PreparedCache {
    fn new(limit: usize) -> Self {
        Self { entries: HashMap::new(), bytes: 0, limit, clock: 0 }
    }

    fn get(&mut self, key: &(i64, i64)) -> Option<Arc<Prepared>> {
        self.clock += 1;
        let clock = self.clock;
        self.entries.get_mut(key).map(|(p, used)| {
            *used = clock;
            p.clone()
        })
    }

    /// Adds an entry, then evicts the least recently used others while over the limit (the new
    /// one stays even when it alone is larger).
    fn insert(&mut self, key: (i64, i64), p: Arc<Prepared>) {
        self.clock += 1;
        self.bytes += p.bytes;
        if let Some((old, _)) = self.entries.insert(key, (p, self.clock)) {
            self.bytes -= old.bytes;
        }
        while self.bytes > self.limit && self.entries.len() > 1 {
            let Some(oldest) =
                self.entries.iter().filter(|(k, _)| **k != key).min_by_key(|(_, (_, used))| *used).map(|(k, _)| *k)
            else {
                break;
            };
            if let Some((gone, _)) = self.entries.remove(&oldest) {
                self.bytes -= gone.bytes;
                tracing::debug!(calibration = oldest.0, experiment = oldest.1, "evicted a prepared experiment");
            }
        }
    }
}

/// Runs one job: the model at the job's parameters and the cost against the data. Panics in the
/// model become failed evaluations.
fn evaluate(p: &Prepared, parameters: &BTreeMap<String, f64>) -> (api::JobOutcome, Option<Vec<api::SeriesCost>>) {
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        evaluate_and_fit(&p.experiment, &p.weights, parameters)
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
///
/// Each turn of the loop goes through the same phases: [`Worker::drain`] (once shutting down:
/// drop the jobs not started, stop at the drain deadline), [`Worker::dispatch`] (start the jobs
/// whose experiment is prepared on free slots), [`Worker::should_exit`] (idle or drained),
/// [`Worker::claim`] (lease more jobs while fewer than twice the slots are in hand), then
/// [`Worker::wait`] for the next thing to happen: an evaluation done, a result reported, an
/// experiment prepared, a lease lost ([`Worker::handle`]), a heartbeat due
/// ([`Worker::heartbeat`]) or the shutdown signal.
pub async fn run(
    client: Client,
    settings: WorkerSettings,
    fluids: FluidLoader,
    shutdown: impl Future<Output = ()> + Send,
) -> Result<Summary, WorkerError> {
    let (mut worker, mut rx) = Worker::new(client, settings, fluids)?;
    tokio::pin!(shutdown);
    loop {
        if worker.drain() == Flow::Stop {
            break;
        }
        worker.dispatch();
        let in_hand = worker.held.len();
        if worker.should_exit() {
            break;
        }
        if worker.claim(in_hand, &mut shutdown).await? == Flow::Continue {
            continue;
        }
        match worker.wait(&mut rx, &mut shutdown).await {
            Wake::Event(Some(ev)) => worker.handle(ev),
            Wake::Event(None) => break,
            Wake::Heartbeat => worker.heartbeat(),
            Wake::Shutdown => {
                tracing::info!(
                    running = worker.running,
                    drain_timeout_s = worker.settings.drain_timeout.as_secs_f64(),
                    "shutdown: finishing the evaluations running, starting no more"
                );
                worker.begin_drain();
            }
            Wake::Timeout => {}
        }
    }
    Ok(worker.summary)
}

/// Whether the worker's loop goes on with the current turn, starts the next one, or stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Flow {
    /// Go on with this turn's next phase.
    Next,
    /// Start the next turn at once (jobs were claimed).
    Continue,
    /// Leave the loop.
    Stop,
}

/// What ended a wait of the worker's loop.
enum Wake {
    /// A message from a job, a report or a preparation (`None`: every sender is gone).
    Event(Option<Event>),
    /// Heartbeats are due.
    Heartbeat,
    /// The shutdown signal.
    Shutdown,
    /// Time to look again (claim, drain deadline).
    Timeout,
}

/// The worker's loop state: the jobs in hand, the slots in use, the prepared experiments, and
/// the timers of claims, heartbeats and the drain.
struct Worker {
    client: Client,
    settings: WorkerSettings,
    slots: usize,
    fluids: FluidLoader,
    pool: Arc<rayon::ThreadPool>,
    hashes: BTreeMap<String, String>,
    tx: tokio::sync::mpsc::UnboundedSender<Event>,
    summary: Summary,
    held: HashMap<i64, Held>,
    waiting: VecDeque<i64>,
    running: usize,
    reporting: usize,
    contexts: HashMap<i64, api::JobContext>,
    prepared: PreparedCache,
    preparing: HashSet<(i64, i64)>,
    refused_logged: HashSet<i64>,
    draining: bool,
    drain_deadline: Option<Instant>,
    idle_since: Instant,
    next_claim: Instant,
    claim_delay: Duration,
    heartbeat: tokio::time::Interval,
    lease_s: f64,
}

/// Pause before the next claim after jobs were claimed or a result was counted.
const CLAIM_DELAY_MIN: Duration = Duration::from_millis(50);

/// Longest pause between claims that found no job.
const CLAIM_DELAY_MAX: Duration = Duration::from_millis(500);

impl Worker {
    /// The loop state and the receiver of its events; starts the evaluation pool.
    fn new(
        client: Client,
        settings: WorkerSettings,
        fluids: FluidLoader,
    ) -> Result<(Self, tokio::sync::mpsc::UnboundedReceiver<Event>), WorkerError> {
        let slots = settings.slots.max(1);
        let fluids = shared_fluids(fluids);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(slots)
            .thread_name(|i| format!("cryofit-eval-{i}"))
            .build()
            .map_err(|e| WorkerError::Pool { slots, message: e.to_string() })?;
        let hashes = fluid_hashes(&fluids);
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel::<Event>();
        let mut heartbeat = tokio::time::interval(Duration::from_secs(5));
        heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let worker = Self {
            client,
            slots,
            fluids,
            pool: Arc::new(pool),
            hashes,
            tx,
            summary: Summary::default(),
            held: HashMap::new(),
            waiting: VecDeque::new(),
            running: 0,
            reporting: 0,
            contexts: HashMap::new(),
            prepared: PreparedCache::new(settings.cache_bytes),
            preparing: HashSet::new(),
            refused_logged: HashSet::new(),
            draining: false,
            drain_deadline: None,
            idle_since: Instant::now(),
            next_claim: Instant::now(),
            claim_delay: CLAIM_DELAY_MIN,
            heartbeat,
            lease_s: 30.0,
            settings,
        };
        Ok((worker, rx))
    }

    /// Stops claiming and starting jobs; running evaluations get the drain timeout to finish.
    fn begin_drain(&mut self) {
        self.draining = true;
        self.drain_deadline = Some(Instant::now() + self.settings.drain_timeout);
    }

    /// While draining: drops the jobs not started (they stay with the coordinator: their leases
    /// expire and they are handed out again), and stops once the drain deadline has passed.
    fn drain(&mut self) -> Flow {
        if !self.draining {
            return Flow::Next;
        }
        for id in self.waiting.drain(..) {
            self.held.remove(&id);
        }
        if let Some(deadline) = self.drain_deadline
            && Instant::now() >= deadline
        {
            tracing::warn!(
                running = self.running,
                drain_timeout_s = self.settings.drain_timeout.as_secs_f64(),
                "drain timeout: exiting without the evaluations still running (their leases expire)"
            );
            return Flow::Stop;
        }
        Flow::Next
    }

    /// Starts waiting jobs whose experiment is prepared on free slots; starts preparing the
    /// experiments of the others.
    fn dispatch(&mut self) {
        let mut k = 0;
        while self.running < self.slots && k < self.waiting.len() {
            let id = self.waiting[k];
            let Some(h) = self.held.get_mut(&id) else {
                self.waiting.remove(k);
                continue;
            };
            let key = (h.job.calibration_id, h.job.experiment_id);
            match self.prepared.get(&key) {
                Some(p) => {
                    self.waiting.remove(k);
                    self.running += 1;
                    h.started = Some(Instant::now());
                    let parameters = h.job.parameters.clone();
                    let tx = self.tx.clone();
                    let span = tracing::info_span!("job", job = id, calibration = key.0, experiment = key.1);
                    self.pool.spawn(move || {
                        let _g = span.enter();
                        let t = Instant::now();
                        let (outcome, breakdown) = evaluate(&p, &parameters);
                        let _ =
                            tx.send(Event::Done { job: id, outcome, breakdown, seconds: t.elapsed().as_secs_f64() });
                    });
                }
                None => {
                    if self.preparing.insert(key) {
                        let context = self.contexts.get(&key.0).cloned();
                        spawn_prepare(&self.client, &self.fluids, key, context, self.tx.clone());
                    }
                    k += 1;
                }
            }
        }
    }

    /// True when the worker is done: drained, or idle for [`WorkerSettings::exit_when_idle`].
    fn should_exit(&mut self) -> bool {
        if !(self.held.is_empty() && self.reporting == 0) {
            self.idle_since = Instant::now();
            return false;
        }
        if self.draining {
            return true;
        }
        if let Some(limit) = self.settings.exit_when_idle
            && self.idle_since.elapsed() >= limit
        {
            tracing::info!(idle_s = limit.as_secs_f64(), "idle: exiting");
            return true;
        }
        false
    }

    /// Claims more jobs when fewer than twice the slots are in hand (`in_hand`) and a claim is
    /// due; the shutdown signal interrupts the claim. [`Flow::Continue`] when jobs came; an error
    /// when the coordinator refuses the worker's token.
    async fn claim(
        &mut self,
        in_hand: usize,
        shutdown: &mut std::pin::Pin<&mut impl Future<Output = ()>>,
    ) -> Result<Flow, WorkerError> {
        if self.draining || in_hand >= 2 * self.slots || Instant::now() < self.next_claim {
            return Ok(Flow::Next);
        }
        let req = api::ClaimRequest {
            worker: self.settings.name.clone(),
            slots: self.slots as u32,
            max_jobs: (2 * self.slots - in_hand).min(1000) as u32,
            solver_version: api::SOLVER_VERSION.to_string(),
            fluid_hashes: self.hashes.clone(),
        };
        let claimed = tokio::select! {
            r = self.client.claim(&req) => Some(r),
            _ = shutdown => None,
        };
        match claimed {
            Some(Ok(resp)) => {
                self.claimed(resp);
                Ok(Flow::Continue)
            }
            Some(Err(e)) => {
                if matches!(e, ClientError::Api { status: 401 | 403, .. }) {
                    return Err(e.into());
                }
                tracing::warn!(error = %e, "claim failed");
                self.next_claim = Instant::now() + Duration::from_secs(1);
                Ok(Flow::Next)
            }
            None => {
                self.begin_drain();
                Ok(Flow::Next)
            }
        }
    }

    /// Takes in a claim's answer: refusals (logged once per calibration), calibration contexts,
    /// and the jobs; backs off while claims come back empty; follows the lease length with the
    /// heartbeat period.
    fn claimed(&mut self, resp: api::ClaimResponse) {
        for r in &resp.refused {
            if self.refused_logged.insert(r.calibration_id) {
                tracing::warn!(calibration = r.calibration_id, reason = %r.reason, "refused jobs of a calibration");
            }
        }
        for c in resp.calibrations {
            self.contexts.insert(c.calibration_id, c);
        }
        if resp.jobs.is_empty() {
            self.next_claim = Instant::now() + self.claim_delay;
            self.claim_delay = (self.claim_delay * 2).min(CLAIM_DELAY_MAX);
            return;
        }
        self.claim_delay = CLAIM_DELAY_MIN;
        for j in resp.jobs {
            self.lease_s = j.lease_s;
            self.waiting.push_back(j.id);
            self.held.insert(j.id, Held { job: j, started: None });
        }
        let period = Duration::from_secs_f64((self.lease_s / 3.0).clamp(0.05, 10.0));
        if self.heartbeat.period() != period {
            self.heartbeat = tokio::time::interval(period);
            self.heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        }
    }

    /// Waits for an event, a heartbeat, the shutdown signal (once) or the next claim or drain
    /// deadline, whichever comes first.
    async fn wait(
        &mut self,
        rx: &mut tokio::sync::mpsc::UnboundedReceiver<Event>,
        shutdown: &mut std::pin::Pin<&mut impl Future<Output = ()>>,
    ) -> Wake {
        let mut wait = self.next_claim.saturating_duration_since(Instant::now()).max(Duration::from_millis(5));
        if let Some(deadline) = self.drain_deadline {
            wait = wait.min(deadline.saturating_duration_since(Instant::now()).max(Duration::from_millis(5)));
        }
        tokio::select! {
            ev = rx.recv() => Wake::Event(ev),
            _ = self.heartbeat.tick() => Wake::Heartbeat,
            _ = shutdown, if !self.draining => Wake::Shutdown,
            _ = tokio::time::sleep(wait) => Wake::Timeout,
        }
    }

    /// Handles one message from a job, a report or a preparation.
    fn handle(&mut self, ev: Event) {
        match ev {
            Event::Done { job, outcome, breakdown, seconds } => self.report(job, outcome, breakdown, seconds),
            Event::Reported { job, response, failed } => self.reported(job, response, failed),
            Event::Prepared { key, result } => self.prepared(key, result),
            Event::Lost { job } => {
                // a lease that is not current: drop the job if it has not started
                if self.held.get(&job).is_some_and(|h| h.started.is_none()) {
                    self.held.remove(&job);
                    self.waiting.retain(|&j| j != job);
                }
            }
        }
    }

    /// An evaluation ended: frees its slot and reports its outcome in the background.
    fn report(&mut self, job: i64, outcome: api::JobOutcome, breakdown: Option<Vec<api::SeriesCost>>, seconds: f64) {
        self.running = self.running.saturating_sub(1);
        let Some(h) = self.held.get(&job) else { return };
        let failed = matches!(outcome, api::JobOutcome::Failed { .. });
        let req = api::ResultRequest {
            lease_id: h.job.lease_id.clone(),
            outcome,
            duration_s: Some(seconds),
            breakdown,
            worker: Some(self.settings.name.clone()),
        };
        self.reporting += 1;
        let client = self.client.clone();
        let tx = self.tx.clone();
        tokio::spawn(async move {
            let response = client.result(job, &req).await;
            let _ = tx.send(Event::Reported { job, response, failed });
        });
    }

    /// A result was reported: the job leaves the hand and is counted.
    fn reported(&mut self, job: i64, response: Result<api::ResultResponse, ClientError>, failed: bool) {
        self.reporting -= 1;
        self.held.remove(&job);
        // a counted result may have completed a generation: claim again at once
        self.next_claim = Instant::now();
        self.claim_delay = CLAIM_DELAY_MIN;
        match response {
            Ok(r) if r.counted => {
                self.summary.counted += 1;
                if failed {
                    self.summary.failed += 1;
                }
            }
            Ok(_) => self.summary.stale += 1,
            Err(e) => tracing::error!(job, error = %e, "result could not be reported"),
        }
    }

    /// An experiment was prepared (cached), or could not be: then the jobs waiting for it fail
    /// with the reason. A failure is not remembered: a later job of the experiment prepares it
    /// again.
    fn prepared(&mut self, key: (i64, i64), result: Result<Arc<Prepared>, String>) {
        self.preparing.remove(&key);
        let e = match result {
            Ok(p) => {
                self.prepared.insert(key, p);
                return;
            }
            Err(e) => e,
        };
        tracing::error!(calibration = key.0, experiment = key.1, error = %e, "cannot prepare experiment");
        let held = &self.held;
        let failing: Vec<i64> = self
            .waiting
            .iter()
            .copied()
            .filter(|id| held.get(id).is_some_and(|h| (h.job.calibration_id, h.job.experiment_id) == key))
            .collect();
        self.waiting.retain(|id| !failing.contains(id));
        for id in failing {
            self.running += 1;
            let _ = self.tx.send(Event::Done {
                job: id,
                outcome: api::JobOutcome::Failed { reason: e.clone() },
                breakdown: None,
                seconds: 0.0,
            });
        }
    }

    /// Heartbeats every lease in hand in the background; a lease the coordinator no longer
    /// holds (cancelled, 404, 409) comes back as [`Event::Lost`].
    fn heartbeat(&self) {
        for h in self.held.values() {
            let (client, tx, id, lease) = (self.client.clone(), self.tx.clone(), h.job.id, h.job.lease_id.clone());
            tokio::spawn(async move {
                match client.heartbeat(id, &lease).await {
                    Ok(r) if r.cancelled => {
                        let _ = tx.send(Event::Lost { job: id });
                    }
                    Ok(_) => {}
                    Err(ClientError::Api { status: 404 | 409, .. }) => {
                        let _ = tx.send(Event::Lost { job: id });
                    }
                    Err(e) => tracing::warn!(job = id, error = %e, "heartbeat failed"),
                }
            });
        }
    }
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
            let text = download(&client, key.1).await?;
            tokio::task::spawn_blocking(move || build(&text, &ctx, &fluids))
                .await
                .map_err(|e| format!("preparing experiment {}: {e}", key.1))?
        }
        .await;
        let _ = tx.send(Event::Prepared { key, result });
    });
}

/// True for a failure that says nothing about the request: the coordinator away or busy
/// (transport errors, 408, 429, 5xx).
pub fn is_transient(e: &ClientError) -> bool {
    match e {
        ClientError::Transport { .. } => true,
        ClientError::Api { status, .. } => matches!(status, 408 | 429 | 500..=599),
    }
}

/// Longest pause between two downloads of an experiment that failed for a passing reason.
const DOWNLOAD_BACKOFF_MAX: Duration = Duration::from_secs(30);

/// Fetches an experiment, retrying failures that pass (see [`is_transient`]) with backoff and
/// jitter for as long as it takes; other failures are returned with the reason.
async fn download(client: &Client, id: i64) -> Result<api::Experiment, String> {
    let mut delay = Duration::from_millis(200);
    loop {
        match client.experiment(id).await {
            Ok(e) => return Ok(e),
            Err(e) if is_transient(&e) => {
                tracing::warn!(experiment = id, error = %e, retry_in_ms = delay.as_millis() as u64, "experiment download failed; retrying");
                let jitter = rand::Rng::gen_range(&mut rand::thread_rng(), 0.5..1.5);
                tokio::time::sleep(delay.mul_f64(jitter)).await;
                delay = (delay * 2).min(DOWNLOAD_BACKOFF_MAX);
            }
            Err(e) => return Err(format!("experiment {id}: {e}")),
        }
    }
}

fn build(e: &api::Experiment, ctx: &api::JobContext, fluids: &FluidLoader) -> Result<Arc<Prepared>, String> {
    let fixed = Fixed::new(&ctx.fixed).map_err(|e| e.to_string())?;
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
    )
    .map_err(|e| e.to_string())?;
    let weights =
        Weights(ctx.weights.iter().map(|(q, w)| (q.clone(), Weight { weight: w.weight, sigma: w.sigma })).collect());
    let bytes = 4096 + 16 * experiment.data.len() + e.case.len();
    Ok(Arc::new(Prepared { experiment, weights, bytes }))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn prepared(bytes: usize) -> Arc<Prepared> {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures/tiny.toml"))
            .expect("tiny case");
        let data = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures/tiny-data.csv"))
            .expect("tiny data");
        let loader =
            |n: &str| cryofit_solver::fluids::embedded(n).map(|t| Arc::new(t.clone())).map_err(|e| e.to_string());
        let experiment = experiment_from_texts("tiny", &text, "case", &data, "data", loader, &Fixed::default(), None)
            .expect("experiment");
        Arc::new(Prepared { experiment, weights: Weights(BTreeMap::new()), bytes })
    }

    #[test]
    fn the_cache_of_prepared_experiments_is_bounded_in_bytes_least_recently_used_first_out() {
        let mut c = PreparedCache::new(250);
        let p = prepared(100);
        c.insert(
            (1, 1),
            Arc::new(Prepared { experiment: p.experiment.clone(), weights: Weights(BTreeMap::new()), bytes: 100 }),
        );
        c.insert(
            (1, 2),
            Arc::new(Prepared { experiment: p.experiment.clone(), weights: Weights(BTreeMap::new()), bytes: 100 }),
        );
        assert!(c.get(&(1, 1)).is_some(), "(1, 1) is now the most recently used");
        c.insert(
            (2, 1),
            Arc::new(Prepared { experiment: p.experiment.clone(), weights: Weights(BTreeMap::new()), bytes: 100 }),
        );
        assert!(c.bytes <= 250, "{} bytes kept", c.bytes);
        assert!(c.get(&(1, 2)).is_none(), "the least recently used went first");
        assert!(c.get(&(1, 1)).is_some() && c.get(&(2, 1)).is_some());
        // one entry larger than the limit stays alone
        c.insert(
            (3, 1),
            Arc::new(Prepared { experiment: p.experiment.clone(), weights: Weights(BTreeMap::new()), bytes: 1000 }),
        );
        assert_eq!(c.entries.len(), 1);
        assert_eq!(c.bytes, 1000);
        // 41 calibrations' experiments in a 250-byte cache: never more than the limit (plus the newest)
        for k in 0..41 {
            c.insert(
                (10 + k, 1),
                Arc::new(Prepared { experiment: p.experiment.clone(), weights: Weights(BTreeMap::new()), bytes: 100 }),
            );
            assert!(c.bytes <= 250, "{} bytes kept after {k}", c.bytes);
        }
    }

    #[test]
    fn every_experiment_of_a_fluid_shares_one_table() {
        let copies = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let counted = copies.clone();
        // a loader that makes a private copy each time, like reading a table from a file
        let inner: FluidLoader = Arc::new(move |n: &str| {
            counted.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let t = cryofit_solver::fluids::embedded(n).map_err(|e| e.to_string())?;
            Ok((Arc::new(t.clone()), "hash".into()))
        });
        let shared = shared_fluids(inner);
        let (a, _) = shared("nitrogen").expect("nitrogen");
        let (b, _) = shared("N2").expect("nitrogen by another name");
        let (c, _) = shared("nitrogen").expect("nitrogen");
        assert!(Arc::ptr_eq(&a, &b) && Arc::ptr_eq(&a, &c), "one table for every experiment");
        assert_eq!(copies.load(std::sync::atomic::Ordering::Relaxed), 1);
        assert!(shared("unobtainium").is_err());
    }

    fn job(id: i64, lease_s: f64) -> api::LeasedJob {
        api::LeasedJob {
            id,
            lease_id: format!("lease-{id}"),
            lease_s,
            calibration_id: 1,
            parameter_set_id: id,
            experiment_id: 1,
            parameters: BTreeMap::new(),
        }
    }

    #[tokio::test]
    async fn the_loop_phases_back_off_take_jobs_in_and_drain() {
        let client = Client::new("http://127.0.0.1:9", None).expect("client");
        let fluids: FluidLoader = Arc::new(|n: &str| Err(format!("no table {n}")));
        let (mut w, mut rx) = Worker::new(client, WorkerSettings::new(2), fluids).expect("worker");
        let empty = || api::ClaimResponse { jobs: vec![], calibrations: vec![], refused: vec![] };
        // empty claims back off, doubling up to the longest pause
        for want in [100, 200, 400, 500, 500] {
            w.claimed(empty());
            assert_eq!(w.claim_delay, Duration::from_millis(want));
        }
        // jobs come in: held and waiting, the backoff reset, heartbeats at a third of the lease
        w.claimed(api::ClaimResponse { jobs: vec![job(7, 3.0), job(8, 3.0)], ..empty() });
        assert_eq!((w.held.len(), w.waiting.len()), (2, 2));
        assert_eq!(w.claim_delay, CLAIM_DELAY_MIN);
        assert_eq!(w.heartbeat.period(), Duration::from_secs(1));
        assert!(!w.should_exit(), "jobs in hand");
        // a lost lease of a job not started drops it
        w.handle(Event::Lost { job: 8 });
        assert_eq!((w.held.len(), w.waiting.len()), (1, 1));
        // an experiment that cannot be prepared fails the jobs waiting for it
        w.handle(Event::Prepared { key: (1, 1), result: Err("no such experiment".into()) });
        assert!(w.waiting.is_empty());
        match rx.try_recv() {
            Ok(Event::Done { job: 7, outcome: api::JobOutcome::Failed { reason }, .. }) => {
                assert_eq!(reason, "no such experiment")
            }
            _ => panic!("job 7 should have failed"),
        }
        // draining drops the jobs not started and exits once nothing is in hand
        w.claimed(api::ClaimResponse { jobs: vec![job(9, 3.0)], ..empty() });
        w.held.remove(&7);
        w.running = 0;
        w.begin_drain();
        assert_eq!(w.drain(), Flow::Next);
        assert!(w.held.is_empty() && w.waiting.is_empty());
        assert!(w.should_exit());
        w.drain_deadline = Some(Instant::now());
        assert_eq!(w.drain(), Flow::Stop, "the drain deadline has passed");
    }

    #[test]
    fn only_passing_failures_are_retried() {
        let api = |status| ClientError::Api { status, code: "x".into(), message: "x".into(), field: None };
        assert!(is_transient(&api(429)));
        assert!(is_transient(&api(503)));
        assert!(is_transient(&ClientError::Transport { url: "u".into(), message: "refused".into() }));
        assert!(!is_transient(&api(404)));
        assert!(!is_transient(&api(422)));
    }
}
