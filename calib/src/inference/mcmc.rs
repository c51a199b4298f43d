//! Posterior sampling with the affine-invariant ensemble sampler of Goodman and Weare (2010,
//! Comm. Appl. Math. Comput. Sci. 5(1)), "stretch move", in the parallel form of Foreman-Mackey
//! et al. (2013, PASP 125, the emcee paper): the walkers are split into two halves and each half is
//! moved using the other, so one half's proposals are independent and form one generation.
//!
//! The posterior is the paper's Bayes rule for the parameters (section "Probabilistic framework",
//! eq. "bayes_param") with likelihood `exp(−S/2)` and a uniform prior on the unit box, or, at a
//! temperature `T` above 1, the tempered likelihood `exp(−S/(2T))` (see [`McmcOptions::temperature`]). Uniform in
//! unit coordinates means **uniform in the physical value for a linear parameter and log-uniform
//! (uniform in ln x) for a logarithmic one**. A failed evaluation has zero likelihood: the proposal
//! is rejected. Proposals outside the box have zero prior and are rejected without evaluation.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::InferenceError;
use super::common::{Completed, Core, Told, check, clamp_unit, resolve_start};
use crate::api::StopReason;
use crate::space::Space;

/// Options of [`EnsembleSampler`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default))]
pub struct McmcOptions {
    /// Number of walkers: even and at least `max(4, 2d)`. Default (`None`): `max(2d + 2, 16)`
    /// rounded up to even.
    pub walkers: Option<usize>,
    /// Stretch scale `a > 1` of the proposal `z ~ g(z) ∝ 1/√z` on `[1/a, a]`. Default 2 (Goodman
    /// and Weare's choice).
    pub stretch: f64,
    /// Standard deviation of the initial Gaussian ball around `start`, unit coordinates (points
    /// clamped into the box). Default 0.01.
    pub initial_spread: f64,
    /// Fraction of the iterations discarded as burn-in in the summary and in draws. Default 0.5.
    pub burn_in: f64,
    /// Window constant `c` of Sokal's automatic windowing for the autocorrelation time. Default 5.
    pub autocorr_window: f64,
    /// Temperature `T ≥ 1` of the likelihood `exp(−S/(2T))`. Default 1 (the plain likelihood).
    ///
    /// Decision: a simulated cost jitters by σ_ε between nearby parameter sets (adaptive time
    /// stepping and the two-phase flow's sensitivity to small perturbations; the variance
    /// stage measures σ_ε). Under the plain likelihood a point whose cost happens to lie 2σ_ε
    /// below its neighbours' — hundreds of cost units on the NBS runs — is `e^{σ_ε}` times as
    /// likely, and the walkers stick to such points: the chain samples the jitter, not the
    /// posterior. At `T = 1 + 2σ_ε`, the variance stage's noise inflation, a jitter of σ_ε
    /// changes the log-likelihood by less than ½ and the sampled spread is the one that stage
    /// reports: the smooth part of the cost must rise by about `2σ_ε` before a move is unlikely.
    pub temperature: f64,
}

impl Default for McmcOptions {
    fn default() -> Self {
        Self { walkers: None, stretch: 2.0, initial_spread: 0.01, burn_in: 0.5, autocorr_window: 5.0, temperature: 1.0 }
    }
}

/// Five posterior quantiles.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Quantiles {
    /// 2.5 %.
    pub q025: f64,
    /// 5 %.
    pub q05: f64,
    /// 50 % (median).
    pub q50: f64,
    /// 95 %.
    pub q95: f64,
    /// 97.5 %.
    pub q975: f64,
}

/// Posterior statistics of one parameter (after burn-in, all walkers pooled).
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ParameterPosterior {
    /// Index in the space.
    pub index: usize,
    /// Name.
    pub name: String,
    /// Posterior mean, unit coordinates.
    pub mean_unit: f64,
    /// Posterior standard deviation, unit coordinates.
    pub sd_unit: f64,
    /// Posterior mean, physical units.
    pub mean: f64,
    /// Posterior standard deviation, physical units.
    pub sd: f64,
    /// Quantiles, physical units.
    pub quantiles: Quantiles,
    /// Quantiles, unit coordinates.
    pub quantiles_unit: Quantiles,
    /// Split R-hat over the walkers (Gelman et al., Bayesian Data Analysis, 3rd ed., §11.4);
    /// walkers of an ensemble are not independent chains, so read it as a consistency check.
    pub r_hat: Option<f64>,
    /// Integrated autocorrelation time in iterations (Sokal's windowed estimator on the
    /// walker-averaged autocorrelation function, as in emcee).
    pub autocorr_time: Option<f64>,
    /// True when the chain is longer than 50 autocorrelation times (emcee's reliability rule).
    pub autocorr_reliable: bool,
    /// Effective sample size: samples / autocorrelation time.
    pub ess: Option<f64>,
}

/// Result of an [`EnsembleSampler`] run.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct McmcSummary {
    /// Walkers.
    pub walkers: usize,
    /// Temperature of the likelihood, `exp(−S/(2T))` ([`McmcOptions::temperature`]).
    #[cfg_attr(feature = "serde", serde(default = "unit_temperature"))]
    pub temperature: f64,
    /// Completed iterations (both halves moved).
    pub iterations: usize,
    /// Iterations discarded as burn-in.
    pub burn_in: usize,
    /// Posterior samples kept: `(iterations − burn_in) × walkers`.
    pub samples: usize,
    /// Evaluations handed out.
    pub evaluations: usize,
    /// The budget.
    pub budget: usize,
    /// Accepted / proposed moves, all walkers (`None` before the first move).
    pub acceptance_fraction: Option<f64>,
    /// Accepted / proposed moves per walker.
    pub acceptance_per_walker: Vec<f64>,
    /// Proposals outside the box (rejected without evaluation).
    pub outside_box: usize,
    /// Proposals whose evaluation failed (rejected).
    pub failed_proposals: usize,
    /// Per parameter (empty until there are samples).
    pub parameters: Vec<ParameterPosterior>,
    /// Posterior covariance, unit coordinates.
    pub covariance_unit: Vec<Vec<f64>>,
    /// Posterior covariance, physical units.
    pub covariance_physical: Vec<Vec<f64>>,
    /// Posterior correlation (of the unit coordinates).
    pub correlation: Vec<Vec<f64>>,
    /// Largest R-hat over the parameters.
    pub max_r_hat: Option<f64>,
    /// Things the caller should know.
    pub warnings: Vec<String>,
    /// Why it stopped, once finished.
    pub stop: Option<StopReason>,
}

/// The temperature of a summary stored before temperatures existed: the plain likelihood.
#[cfg(feature = "serde")]
fn unit_temperature() -> f64 {
    1.0
}

/// Posterior draws, for posterior-predictive runs (paper, eq. "bayes_forecast").
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct PosteriorDraws {
    /// Draws in unit coordinates.
    pub unit: Vec<Vec<f64>>,
    /// The same draws in physical values.
    pub physical: Vec<Vec<f64>>,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Proposal {
    walker: usize,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    point: Vec<f64>,
    /// `(d − 1) ln z`.
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    log_z_term: f64,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    uniform: f64,
    /// Position in the generation; `None` when outside the box.
    slot: Option<usize>,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
enum Phase {
    Init,
    Half { half: usize, proposals: Vec<Proposal> },
    Done,
}

/// Affine-invariant ensemble sampler (Goodman and Weare 2010 stretch move, parallel half-ensemble
/// updates as in emcee, Foreman-Mackey et al. 2013) of `p(u) ∝ exp(−S(u)/(2T))` on the unit box
/// (`T` = [`McmcOptions::temperature`], 1 unless the cost's jitter calls for more).
///
/// Budget = evaluations: the initial ensemble, then one generation per half-ensemble move (the
/// in-box proposals of that half). The sampler stops with [`StopReason::Budget`] when the next
/// generation no longer fits; the few evaluations left are not used.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct EnsembleSampler {
    #[cfg_attr(feature = "serde", serde(with = "crate::exact::space"))]
    space: Space,
    options: McmcOptions,
    walkers: usize,
    rng: ChaCha8Rng,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    positions: Vec<Vec<f64>>,
    /// Current costs, `+∞` for a walker whose position failed (initial ensemble only).
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    costs: Vec<f64>,
    phase: Phase,
    /// Positions after each iteration, flat `[iteration][walker][parameter]`.
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    chain: Vec<f64>,
    /// Costs after each iteration, flat `[iteration][walker]`.
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    chain_costs: Vec<f64>,
    iterations: usize,
    accepted: Vec<usize>,
    proposed: Vec<usize>,
    outside: usize,
    failed: usize,
    core: Core,
}

impl EnsembleSampler {
    const NAME: &'static str = "mcmc";
    /// Consecutive half-moves with every proposal outside the box before giving up.
    const MAX_EMPTY_HALVES: usize = 1000;

    /// The default number of walkers in dimension `d`: `max(2d + 2, 16)`, rounded up to even.
    pub fn default_walkers(d: usize) -> usize {
        let w = (2 * d + 2).max(16);
        w + w % 2
    }

    /// Draws the initial ensemble around `start` (or the centre). Errors: bad options or start,
    /// a budget below two ensembles (initial positions and one full move).
    pub fn new(
        space: &Space,
        start: Option<&[f64]>,
        options: McmcOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, InferenceError> {
        let n = Self::NAME;
        let o = &options;
        let d = space.dim();
        let start = resolve_start(n, d, start)?;
        let walkers = o.walkers.unwrap_or_else(|| Self::default_walkers(d));
        let min_walkers = (2 * d).max(4);
        check(
            n,
            "walkers",
            walkers as f64,
            walkers.is_multiple_of(2) && walkers >= min_walkers,
            "even and at least max(4, 2d)",
        )?;
        check(n, "stretch", o.stretch, o.stretch > 1.0 && o.stretch.is_finite(), "finite and > 1")?;
        check(n, "initial_spread", o.initial_spread, o.initial_spread > 0.0 && o.initial_spread <= 0.5, "in (0, 0.5]")?;
        check(n, "burn_in", o.burn_in, (0.0..1.0).contains(&o.burn_in), "in [0, 1)")?;
        check(
            n,
            "autocorr_window",
            o.autocorr_window,
            o.autocorr_window >= 1.0 && o.autocorr_window.is_finite(),
            "≥ 1",
        )?;
        check(n, "temperature", o.temperature, o.temperature >= 1.0 && o.temperature.is_finite(), "finite and ≥ 1")?;
        if budget < 2 * walkers {
            return Err(InferenceError::BudgetTooSmall {
                algorithm: n,
                budget,
                required: 2 * walkers,
                needed_for: "the initial ensemble and one move of every walker",
            });
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let initial: Vec<Vec<f64>> = (0..walkers)
            .map(|_| {
                clamp_unit(start.iter().map(|&s| s + o.initial_spread * rng.sample::<f64, _>(StandardNormal)).collect())
            })
            .collect();
        let mut core = Core::new(budget);
        core.start(initial);
        Ok(Self {
            space: space.clone(),
            options,
            walkers,
            rng,
            positions: Vec::new(),
            costs: Vec::new(),
            phase: Phase::Init,
            chain: Vec::new(),
            chain_costs: Vec::new(),
            iterations: 0,
            accepted: vec![0; walkers],
            proposed: vec![0; walkers],
            outside: 0,
            failed: 0,
            core,
        })
    }

    fn absorb(&mut self, done: Completed) {
        match std::mem::replace(&mut self.phase, Phase::Done) {
            Phase::Init => {
                self.costs = done.results.iter().map(Told::rank).collect();
                self.positions = done.points;
                if self.costs.iter().all(|c| c.is_infinite()) {
                    return self.core.finish(StopReason::Exhausted {
                        message: "every walker of the initial ensemble failed; start elsewhere or widen the ball"
                            .into(),
                    });
                }
                self.next_half(0);
            }
            Phase::Half { half, proposals } => {
                self.settle(&proposals, &done.results);
                self.after_half(half);
            }
            Phase::Done => {}
        }
    }

    /// Metropolis–Hastings acceptance of one half's proposals, in walker order.
    fn settle(&mut self, proposals: &[Proposal], results: &[Told]) {
        for p in proposals {
            self.proposed[p.walker] += 1;
            let Some(slot) = p.slot else {
                self.outside += 1;
                continue;
            };
            let new = results[slot].rank();
            if !new.is_finite() {
                self.failed += 1;
                continue;
            }
            let old = self.costs[p.walker];
            let log_q = p.log_z_term - 0.5 * (new - old) / self.options.temperature;
            if !old.is_finite() || p.uniform.ln() < log_q {
                self.positions[p.walker] = p.point.clone();
                self.costs[p.walker] = new;
                self.accepted[p.walker] += 1;
            }
        }
    }

    fn after_half(&mut self, half: usize) {
        if half == 1 {
            self.record();
        }
        self.next_half(1 - half);
    }

    /// Appends the ensemble to the chain: one iteration is complete.
    fn record(&mut self) {
        self.iterations += 1;
        for (x, &c) in self.positions.iter().zip(&self.costs) {
            self.chain.extend_from_slice(x);
            self.chain_costs.push(c);
        }
    }

    /// Draws the proposals of half `half` (walkers `[half·W/2, (half+1)·W/2)`, each stretched
    /// towards a random walker of the other half) and opens their generation.
    fn next_half(&mut self, mut half: usize) {
        let d = self.space.dim();
        let h = self.walkers / 2;
        let a = self.options.stretch;
        for _ in 0..Self::MAX_EMPTY_HALVES {
            let mut proposals = Vec::with_capacity(h);
            let mut points = Vec::with_capacity(h);
            for k in half * h..(half + 1) * h {
                let j = (1 - half) * h + self.rng.gen_range(0..h);
                let r: f64 = self.rng.r#gen();
                let z = ((a - 1.0) * r + 1.0).powi(2) / a;
                let uniform: f64 = 1.0 - self.rng.r#gen::<f64>();
                let (xk, xj) = (&self.positions[k], &self.positions[j]);
                let point: Vec<f64> = xj.iter().zip(xk).map(|(&b, &x)| b + z * (x - b)).collect();
                let inside = point.iter().all(|v| (0.0..=1.0).contains(v));
                let slot = inside.then(|| {
                    points.push(point.clone());
                    points.len() - 1
                });
                proposals.push(Proposal { walker: k, point, log_z_term: (d as f64 - 1.0) * z.ln(), uniform, slot });
            }
            if points.is_empty() {
                self.settle(&proposals, &[]);
                if half == 1 {
                    self.record();
                }
                half = 1 - half;
                continue;
            }
            if points.len() > self.core.remaining() {
                return self.core.finish(StopReason::Budget);
            }
            self.core.start(points);
            self.phase = Phase::Half { half, proposals };
            return;
        }
        self.core.finish(StopReason::Exhausted {
            message: format!("{} consecutive half-moves proposed only points outside the box", Self::MAX_EMPTY_HALVES),
        })
    }

    /// Number of walkers.
    pub fn walkers(&self) -> usize {
        self.walkers
    }

    /// Completed iterations.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// The chains, `[walker][iteration][parameter]`, unit coordinates, burn-in included.
    pub fn chains(&self) -> Vec<Vec<Vec<f64>>> {
        let (w, d) = (self.walkers, self.space.dim());
        (0..w).map(|k| (0..self.iterations).map(|t| self.chain[(t * w + k) * d..][..d].to_vec()).collect()).collect()
    }

    /// The cost of each walker after each iteration, `[walker][iteration]` (`+∞` for a walker that
    /// has not left a failed initial position).
    pub fn chain_costs(&self) -> Vec<Vec<f64>> {
        let w = self.walkers;
        (0..w).map(|k| (0..self.iterations).map(|t| self.chain_costs[t * w + k]).collect()).collect()
    }

    fn burn_in(&self) -> usize {
        (self.options.burn_in * self.iterations as f64).floor() as usize
    }

    /// Post-burn-in value of parameter `p` for walker `k` at kept iteration `t`.
    fn at(&self, t: usize, k: usize, p: usize) -> f64 {
        let (w, d) = (self.walkers, self.space.dim());
        self.chain[((self.burn_in() + t) * w + k) * d + p]
    }

    /// `n` posterior draws (after burn-in, uniformly with replacement from all walkers), seeded by
    /// `seed`; empty while there are no post-burn-in samples.
    pub fn samples(&self, n: usize, seed: u64) -> PosteriorDraws {
        let kept = self.iterations - self.burn_in();
        let total = kept * self.walkers;
        if total == 0 {
            return PosteriorDraws { unit: Vec::new(), physical: Vec::new() };
        }
        let d = self.space.dim();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let unit: Vec<Vec<f64>> = (0..n)
            .map(|_| {
                let s = rng.gen_range(0..total);
                (0..d).map(|p| self.at(s / self.walkers, s % self.walkers, p)).collect()
            })
            .collect();
        let physical = unit.iter().map(|u| self.space.to_physical(u)).collect();
        PosteriorDraws { unit, physical }
    }

    /// Posterior statistics and diagnostics so far.
    pub fn summary(&self) -> McmcSummary {
        let (w, d) = (self.walkers, self.space.dim());
        let proposed: usize = self.proposed.iter().sum();
        let accepted: usize = self.accepted.iter().sum();
        let burn_in = self.burn_in();
        let kept = self.iterations - burn_in;
        let mut s = McmcSummary {
            walkers: w,
            temperature: self.options.temperature,
            iterations: self.iterations,
            burn_in,
            samples: kept * w,
            evaluations: self.core.used(),
            budget: self.core.budget(),
            acceptance_fraction: (proposed > 0).then(|| accepted as f64 / proposed as f64),
            acceptance_per_walker: (0..w)
                .map(|k| if self.proposed[k] > 0 { self.accepted[k] as f64 / self.proposed[k] as f64 } else { 0.0 })
                .collect(),
            outside_box: self.outside,
            failed_proposals: self.failed,
            parameters: Vec::new(),
            covariance_unit: Vec::new(),
            covariance_physical: Vec::new(),
            correlation: Vec::new(),
            max_r_hat: None,
            warnings: Vec::new(),
            stop: self.core.finished(),
        };
        if kept == 0 {
            return s;
        }
        let n = (kept * w) as f64;
        let unit: Vec<Vec<f64>> = (0..d)
            .map(|p| (0..kept).flat_map(|t| (0..w).map(move |k| (t, k))).map(|(t, k)| self.at(t, k, p)).collect())
            .collect();
        let physical: Vec<Vec<f64>> =
            unit.iter().enumerate().map(|(p, v)| v.iter().map(|&u| self.space.value(p, u)).collect()).collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / n;
        let cov = |a: &[f64], b: &[f64], ma: f64, mb: f64| {
            a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum::<f64>() / (n - 1.0).max(1.0)
        };
        let mu: Vec<f64> = unit.iter().map(|v| mean(v)).collect();
        let mx: Vec<f64> = physical.iter().map(|v| mean(v)).collect();
        s.covariance_unit = (0..d).map(|i| (0..d).map(|j| cov(&unit[i], &unit[j], mu[i], mu[j])).collect()).collect();
        s.covariance_physical =
            (0..d).map(|i| (0..d).map(|j| cov(&physical[i], &physical[j], mx[i], mx[j])).collect()).collect();
        s.correlation = (0..d)
            .map(|i| {
                (0..d)
                    .map(|j| {
                        let den = (s.covariance_unit[i][i] * s.covariance_unit[j][j]).sqrt();
                        if i == j {
                            1.0
                        } else if den > 0.0 {
                            s.covariance_unit[i][j] / den
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let window = self.options.autocorr_window;
        for (p, name) in self.space.names().enumerate() {
            let r_hat = self.split_r_hat(p, kept);
            let tau = self.autocorr_time(p, kept, window);
            let reliable = tau.is_some_and(|t| kept as f64 > 50.0 * t);
            if !reliable {
                s.warnings.push(format!(
                    "parameter {name}: the kept chain ({kept} iterations) is not longer than 50 autocorrelation \
                     times ({}); run longer before trusting the error bars",
                    tau.map_or("unknown".to_owned(), |t| format!("{t:.1}"))
                ));
            }
            s.parameters.push(ParameterPosterior {
                index: p,
                name: name.to_owned(),
                mean_unit: mu[p],
                sd_unit: s.covariance_unit[p][p].sqrt(),
                mean: mx[p],
                sd: s.covariance_physical[p][p].sqrt(),
                quantiles: quantiles(&physical[p]),
                quantiles_unit: quantiles(&unit[p]),
                r_hat,
                autocorr_time: tau,
                autocorr_reliable: reliable,
                ess: tau.map(|t| n / t),
            });
        }
        s.max_r_hat = s.parameters.iter().filter_map(|p| p.r_hat).reduce(f64::max);
        if s.max_r_hat.is_some_and(|r| r > 1.05) {
            s.warnings.push(format!("max split R-hat {:.3} > 1.05: the walkers disagree", s.max_r_hat.unwrap_or(0.0)));
        }
        s
    }

    /// Split R-hat of parameter `p` over the `2W` half-chains of the kept iterations.
    fn split_r_hat(&self, p: usize, kept: usize) -> Option<f64> {
        let half = kept / 2;
        if half < 2 {
            return None;
        }
        let mut means = Vec::with_capacity(2 * self.walkers);
        let mut vars = Vec::with_capacity(2 * self.walkers);
        for k in 0..self.walkers {
            for start in [0, kept - half] {
                let xs: Vec<f64> = (start..start + half).map(|t| self.at(t, k, p)).collect();
                let m = xs.iter().sum::<f64>() / half as f64;
                means.push(m);
                vars.push(xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (half - 1) as f64);
            }
        }
        let (m, n) = (means.len() as f64, half as f64);
        let grand = means.iter().sum::<f64>() / m;
        let between = n / (m - 1.0) * means.iter().map(|x| (x - grand).powi(2)).sum::<f64>();
        let within = vars.iter().sum::<f64>() / m;
        if within <= 0.0 || !within.is_finite() {
            return None;
        }
        let var_plus = (n - 1.0) / n * within + between / n;
        Some((var_plus / within).sqrt())
    }

    /// Integrated autocorrelation time of parameter `p`: the walkers' normalised autocorrelation
    /// functions averaged, `τ(M) = 1 + 2 Σ_{t=1..M} ρ(t)`, with the smallest window `M ≥ c τ(M)`
    /// (Sokal 1997, "Monte Carlo methods in statistical mechanics"; emcee's estimator).
    fn autocorr_time(&self, p: usize, kept: usize, c: f64) -> Option<f64> {
        if kept < 4 {
            return None;
        }
        let series: Vec<Vec<f64>> = (0..self.walkers)
            .filter_map(|k| {
                let xs: Vec<f64> = (0..kept).map(|t| self.at(t, k, p)).collect();
                let m = xs.iter().sum::<f64>() / kept as f64;
                let f: Vec<f64> = xs.iter().map(|x| x - m).collect();
                let c0 = f.iter().map(|v| v * v).sum::<f64>();
                (c0 > 0.0).then(|| f.iter().map(|v| v / c0.sqrt()).collect())
            })
            .collect();
        if series.is_empty() {
            return None;
        }
        let mut tau = 1.0;
        for lag in 1..kept {
            let rho = series
                .iter()
                .map(|f| f[..kept - lag].iter().zip(&f[lag..]).map(|(a, b)| a * b).sum::<f64>())
                .sum::<f64>()
                / series.len() as f64;
            tau += 2.0 * rho;
            if lag as f64 >= c * tau {
                return Some(tau.max(1e-12));
            }
        }
        Some(tau.max(1e-12))
    }
}

super::delegate_to_core!(EnsembleSampler);

/// Quantiles by linear interpolation between order statistics (Hyndman and Fan's type 7).
fn quantiles(values: &[f64]) -> Quantiles {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let h = (v.len() - 1) as f64 * p;
        let lo = h.floor() as usize;
        let hi = (lo + 1).min(v.len() - 1);
        v[lo] + (h - lo as f64) * (v[hi] - v[lo])
    };
    Quantiles { q025: q(0.025), q05: q(0.05), q50: q(0.5), q95: q(0.95), q975: q(0.975) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_interpolate_between_order_statistics() {
        let q = quantiles(&[4.0, 0.0, 2.0, 1.0, 3.0]);
        assert_eq!((q.q025, q.q05, q.q50, q.q95, q.q975), (0.1, 0.2, 2.0, 3.8, 3.9));
        assert_eq!(EnsembleSampler::default_walkers(3), 16);
        assert_eq!(EnsembleSampler::default_walkers(10), 22);
    }
}
