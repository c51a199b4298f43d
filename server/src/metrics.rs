//! Prometheus metrics, kept in atomics and rendered by hand in the text exposition format.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::Mutex;
use std::time::Duration;

/// A histogram with fixed bucket bounds (seconds).
#[derive(Debug)]
struct Histogram {
    bounds: &'static [f64],
    counts: Vec<u64>,
    sum: f64,
    count: u64,
}

impl Histogram {
    fn new(bounds: &'static [f64]) -> Self {
        Self { bounds, counts: vec![0; bounds.len()], sum: 0.0, count: 0 }
    }

    fn observe(&mut self, v: f64) {
        for (b, c) in self.bounds.iter().zip(self.counts.iter_mut()) {
            if v <= *b {
                *c += 1;
            }
        }
        self.sum += v;
        self.count += 1;
    }

    fn render(&self, out: &mut String, name: &str, help: &str) {
        let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} histogram");
        for (b, c) in self.bounds.iter().zip(&self.counts) {
            let _ = writeln!(out, "{name}_bucket{{le=\"{b}\"}} {c}");
        }
        let _ = writeln!(out, "{name}_bucket{{le=\"+Inf\"}} {}", self.count);
        let _ = writeln!(out, "{name}_sum {}", self.sum);
        let _ = writeln!(out, "{name}_count {}", self.count);
    }
}

#[derive(Debug)]
struct Inner {
    claims: u64,
    jobs_leased: u64,
    expired: u64,
    stale: u64,
    claim_latency: Histogram,
    evaluation: Histogram,
    figure_builds: u64,
}

/// The coordinator's counters and histograms.
#[derive(Debug)]
pub struct Metrics {
    inner: Mutex<Inner>,
}

const LATENCY: &[f64] = &[0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 1.0];
const DURATION: &[f64] = &[0.001, 0.01, 0.1, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0];

impl Default for Metrics {
    fn default() -> Self {
        Self {
            inner: Mutex::new(Inner {
                claims: 0,
                jobs_leased: 0,
                expired: 0,
                stale: 0,
                claim_latency: Histogram::new(LATENCY),
                evaluation: Histogram::new(DURATION),
                figure_builds: 0,
            }),
        }
    }
}

impl Metrics {
    fn with(&self, f: impl FnOnce(&mut Inner)) {
        let mut g = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        f(&mut g);
    }

    /// A claim that leased `jobs` jobs in `latency`.
    pub fn claimed(&self, jobs: usize, latency: Duration) {
        self.with(|m| {
            m.claims += 1;
            m.jobs_leased += jobs as u64;
            m.claim_latency.observe(latency.as_secs_f64());
        });
    }

    /// `n` leases expired.
    pub fn expired(&self, n: usize) {
        self.with(|m| m.expired += n as u64);
    }

    /// A stale result arrived.
    pub fn stale(&self) {
        self.with(|m| m.stale += 1);
    }

    /// An evaluation of `seconds` was counted.
    pub fn evaluated(&self, seconds: f64) {
        self.with(|m| m.evaluation.observe(seconds));
    }

    /// The dashboard drew a calibration's figures.
    pub fn figures_built(&self) {
        self.with(|m| m.figure_builds += 1);
    }

    /// The exposition text, with the job counts by status (queued, leased, done, failed).
    pub fn render(&self, jobs: &BTreeMap<String, i64>) -> String {
        let mut out = String::new();
        let _ = writeln!(out, "# HELP cryofit_jobs Jobs by status.\n# TYPE cryofit_jobs gauge");
        for status in ["queued", "leased", "done", "failed"] {
            let _ = writeln!(out, "cryofit_jobs{{status=\"{status}\"}} {}", jobs.get(status).copied().unwrap_or(0));
        }
        let _ = writeln!(
            out,
            "# HELP cryofit_queue_depth Jobs waiting for a worker.\n# TYPE cryofit_queue_depth gauge\n\
             cryofit_queue_depth {}",
            jobs.get("queued").copied().unwrap_or(0)
        );
        let _ = writeln!(
            out,
            "# HELP cryofit_leased_jobs Jobs leased to workers.\n# TYPE cryofit_leased_jobs gauge\n\
             cryofit_leased_jobs {}",
            jobs.get("leased").copied().unwrap_or(0)
        );
        let g = self.inner.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        for (name, help, v) in [
            ("cryofit_claims_total", "Claim requests served.", g.claims),
            ("cryofit_jobs_leased_total", "Jobs leased.", g.jobs_leased),
            ("cryofit_expired_leases_total", "Leases that expired without a result.", g.expired),
            ("cryofit_stale_results_total", "Results quoting a lease that was not current.", g.stale),
            ("cryofit_figure_builds_total", "Calibration figure sets the dashboard drew.", g.figure_builds),
        ] {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} counter\n{name} {v}");
        }
        g.claim_latency.render(&mut out, "cryofit_claim_latency_seconds", "Time to serve a claim.");
        g.evaluation.render(&mut out, "cryofit_evaluation_duration_seconds", "Wall time of counted evaluations.");
        out
    }
}
