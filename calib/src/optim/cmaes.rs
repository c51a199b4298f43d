//! CMA-ES: the covariance matrix adaptation evolution strategy, with optional IPOP restarts.
//!
//! Follows Hansen, "The CMA Evolution Strategy: A Tutorial" (arXiv:1604.00772, 2016): the
//! (μ/μ_w, λ) strategy with positive recombination weights, cumulative step-size adaptation (CSA),
//! rank-one and rank-μ covariance updates, the `h_σ` stall of the evolution path, the default
//! strategy parameters of its Table 1, its TolFun/TolX stopping rules, and lazy
//! eigendecomposition. Restarts with doubled population follow Auger and Hansen, "A restart CMA
//! evolution strategy with increasing population size" (CEC 2005).
//!
//! # Box constraints
//! The unit box is handled by evaluating the clamped point (so the cost is always computed inside
//! the box) and ranking by `cost + γ·‖x − clamp(x)‖²`, where `x` is the unclamped sample and
//! `γ = 2·δf / (σ²·mean(diag C))` with `δf` the inter-quartile range of the generation's finite
//! costs (its range if that is zero, 1 if both are): a penalty of the order of the generation's
//! cost differences for a sample one standard deviation outside, after the initial weights of
//! Hansen's `BoundPenalty` (Hansen et al., "A method for handling uncertainty in evolutionary
//! optimization…", IEEE TEC 2009, and `cma.py`). The update uses the unclamped samples. Failed
//! evaluations rank after every finite one and get no recombination weight; a generation that fails
//! entirely halves σ and keeps the mean.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use super::engine::{
    Book, Generational, MAX_GENERATION, RESOLUTION_FLOOR, check_common, check_tolerance, delegate_optimizer, ranking,
    require,
};
use crate::api::StopReason;

/// Largest condition number of `C` before the run is considered degenerate.
const MAX_CONDITION: f64 = 1e14;
/// Population factor of an IPOP restart.
const IPOP_FACTOR: usize = 2;

/// Options of [`Cmaes`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default, deny_unknown_fields))]
pub struct CmaesOptions {
    /// Offspring per generation λ (2 to 1 000 000). `None`: `4 + ⌊3 ln dim⌋`. Multimodal costs want more
    /// (for example 10·dim or more).
    pub population: Option<usize>,
    /// Initial step size σ₀ in unit coordinates (in `(0, 1]`).
    pub sigma: f64,
    /// TolFun: stop when the range of the best costs of the last `10 + ⌈30·dim/λ⌉` generations and
    /// of all costs of the current generation is below this.
    pub tolfun: Option<f64>,
    /// TolX: stop when `σ·√C_ii` and `σ·|p_c,i|` are below this for every coordinate.
    pub tolx: Option<f64>,
    /// Stall stop: with `tolfun`, also stop when the best cost of the run has fallen by less than
    /// `tolfun` over the last this many generations. TolFun asks the whole recent history and
    /// the current generation to agree to within `tolfun`, which a cost that jitters between
    /// nearby points (a chaotic simulation) never does; the stall rule asks only that the search
    /// has stopped finding anything better (the "objective improvement over a period" rule of
    /// common optimisation libraries).
    pub stall_generations: Option<usize>,
    /// IPOP restarts: when a stop criterion is met (tolerances, or the numerical floors: step below
    /// 1e-12 or condition of `C` above 1e14), start again from a uniform random mean with σ₀ and
    /// twice the population, this many times at most.
    pub restarts: usize,
}

impl Default for CmaesOptions {
    fn default() -> Self {
        Self { population: None, sigma: 0.3, tolfun: None, tolx: None, stall_generations: None, restarts: 0 }
    }
}

/// Strategy parameters of Hansen's tutorial, Table 1, for dimension `n` and population `lambda`.
struct Params {
    mu: usize,
    weights: Vec<f64>,
    cs: f64,
    ds: f64,
    cc: f64,
    c1: f64,
    cmu: f64,
    chi_n: f64,
}

impl Params {
    fn new(n: usize, lambda: usize) -> Self {
        let nf = n as f64;
        let mu = (lambda / 2).max(1);
        let raw: Vec<f64> = (1..=mu).map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln()).collect();
        let sum: f64 = raw.iter().sum();
        let weights: Vec<f64> = raw.iter().map(|w| w / sum).collect();
        let mueff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let cs = (mueff + 2.0) / (nf + mueff + 5.0);
        let ds = 1.0 + 2.0 * (((mueff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + cs;
        let cc = (4.0 + mueff / nf) / (nf + 4.0 + 2.0 * mueff / nf);
        let c1 = 2.0 / ((nf + 1.3).powi(2) + mueff);
        let cmu = (1.0 - c1).min(2.0 * (mueff - 2.0 + 1.0 / mueff) / ((nf + 2.0).powi(2) + mueff));
        let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        Self { mu, weights, cs, ds, cc, c1, cmu, chi_n }
    }

    /// Generations between eigendecompositions (the tutorial's lazy update).
    fn eigen_gap(&self, n: usize) -> usize {
        let gap = 1.0 / (10.0 * n as f64 * (self.c1 + self.cmu));
        if gap.is_finite() && gap >= 1.0 { gap as usize } else { 1 }
    }
}

fn default_lambda(n: usize) -> usize {
    4 + (3.0 * (n as f64).ln()).floor() as usize
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Core {
    rng: ChaCha8Rng,
    n: usize,
    lambda: usize,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    sigma0: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolfun: Option<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolx: Option<f64>,
    restarts_left: usize,
    restarts_done: usize,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    mean: DVector<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    sigma: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    c: DMatrix<f64>,
    /// Eigenvectors (columns) and square roots of the eigenvalues of `C` at the last decomposition.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    b: DMatrix<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    d: DVector<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    ps: DVector<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    pc: DVector<f64>,
    /// Generations since the (re)start, and at the last eigendecomposition.
    gen_run: usize,
    gen_eigen: usize,
    /// Unclamped samples of the generation being evaluated.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    samples: Vec<Vec<f64>>,
    /// Best finite cost of each recent generation, for TolFun.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    history: Vec<f64>,
    /// Generations of the stall stop (with `tolfun`).
    #[cfg_attr(feature = "serde", serde(default))]
    stall_generations: Option<usize>,
    /// Best finite cost since the (re)start after each of the last `stall_generations + 1`
    /// generations.
    #[cfg_attr(feature = "serde", serde(default, with = "super::exact"))]
    best_path: Vec<f64>,
}

impl Core {
    fn reset(&mut self, mean: DVector<f64>) {
        let n = self.n;
        self.mean = mean;
        self.sigma = self.sigma0;
        self.c = DMatrix::identity(n, n);
        self.b = DMatrix::identity(n, n);
        self.d = DVector::from_element(n, 1.0);
        self.ps = DVector::zeros(n);
        self.pc = DVector::zeros(n);
        self.gen_run = 0;
        self.gen_eigen = 0;
        self.history.clear();
        self.best_path.clear();
    }

    /// `σ·max √C_ii`: the largest standard deviation of the sampling distribution along a coordinate.
    fn max_coordinate_sd(&self) -> f64 {
        self.sigma * self.c.diagonal().iter().fold(0.0_f64, |m, &v| m.max(v)).sqrt()
    }

    /// Refreshes `B` and `D` from `C`; `false` if `C` is not a usable covariance.
    fn decompose(&mut self) -> bool {
        let sym = (&self.c + self.c.transpose()) * 0.5;
        if sym.iter().any(|v| !v.is_finite()) {
            return false;
        }
        let Some(eig) = SymmetricEigen::try_new(sym.clone(), f64::EPSILON, 10_000) else {
            return false;
        };
        let top = eig.eigenvalues.iter().fold(0.0_f64, |m, &v| m.max(v));
        if !(top > 0.0 && top.is_finite()) {
            return false;
        }
        self.c = sym;
        self.b = eig.eigenvectors;
        self.d = eig.eigenvalues.map(|v| v.max(top * f64::EPSILON * f64::EPSILON).sqrt());
        self.gen_eigen = self.gen_run;
        true
    }

    /// Condition number of `C` from the last decomposition.
    fn condition(&self) -> f64 {
        let max = self.d.iter().fold(0.0_f64, |m, &v| m.max(v));
        let min = self.d.iter().fold(f64::INFINITY, |m, &v| m.min(v));
        (max / min).powi(2)
    }

    /// One CMA-ES update from a complete generation (only σ halves if nothing in it succeeded).
    fn update(&mut self, points: &[Vec<f64>], costs: &[f64]) {
        let n = self.n;
        let p = Params::new(n, self.lambda);
        let finite: Vec<f64> = costs.iter().copied().filter(|c| c.is_finite()).collect();
        if finite.is_empty() {
            self.sigma *= 0.5;
            self.gen_run += 1;
            return;
        }

        // Ranking cost: clamped cost plus the boundary penalty on the unclamped sample.
        let dist2: Vec<f64> =
            self.samples.iter().zip(points).map(|(x, q)| x.iter().zip(q).map(|(a, b)| (a - b).powi(2)).sum()).collect();
        let mut rank_cost = costs.to_vec();
        if dist2.iter().any(|&d| d > 0.0) {
            let mut sorted = finite.clone();
            sorted.sort_by(f64::total_cmp);
            let q = |f: f64| sorted[((sorted.len() - 1) as f64 * f).round() as usize];
            let mut df = q(0.75) - q(0.25);
            if df <= 0.0 {
                df = sorted[sorted.len() - 1] - sorted[0];
            }
            if df <= 0.0 || !df.is_finite() {
                df = 1.0;
            }
            let mean_var = self.c.diagonal().mean();
            let gamma = 2.0 * df / (self.sigma * self.sigma * mean_var);
            if gamma.is_finite() {
                for (r, d) in rank_cost.iter_mut().zip(&dist2) {
                    *r += gamma * d;
                }
            }
        }
        let order = ranking(&rank_cost);

        // Recombination weights, restricted to successful samples when fewer than μ succeeded.
        let mu = p.mu.min(finite.len());
        let wsum: f64 = p.weights[..mu].iter().sum();
        let w: Vec<f64> = p.weights[..mu].iter().map(|v| v / wsum).collect();
        let mueff = 1.0 / w.iter().map(|v| v * v).sum::<f64>();

        let ys: Vec<DVector<f64>> = order[..mu]
            .iter()
            .map(|&k| (DVector::from_column_slice(&self.samples[k]) - &self.mean) / self.sigma)
            .collect();
        let mut yw = DVector::zeros(n);
        for (wi, y) in w.iter().zip(&ys) {
            yw.axpy(*wi, y, 1.0);
        }
        self.mean.axpy(self.sigma, &yw, 1.0);

        // C^(-1/2)·y_w = B D⁻¹ Bᵀ y_w.
        let inv_sqrt_c_yw = &self.b * (self.b.tr_mul(&yw).component_div(&self.d));
        self.ps *= 1.0 - p.cs;
        self.ps.axpy((p.cs * (2.0 - p.cs) * mueff).sqrt(), &inv_sqrt_c_yw, 1.0);
        let ps_norm = self.ps.norm();
        let g = (self.gen_run + 1) as f64;
        let hsig = ps_norm / (1.0 - (1.0 - p.cs).powf(2.0 * g)).sqrt() < (1.4 + 2.0 / (n as f64 + 1.0)) * p.chi_n;
        let hsig_f = if hsig { 1.0 } else { 0.0 };
        self.pc *= 1.0 - p.cc;
        self.pc.axpy(hsig_f * (p.cc * (2.0 - p.cc) * mueff).sqrt(), &yw, 1.0);

        let delta = (1.0 - hsig_f) * p.cc * (2.0 - p.cc);
        let mut c_new = &self.c * (1.0 - p.c1 - p.cmu + p.c1 * delta);
        c_new.ger(p.c1, &self.pc, &self.pc, 1.0);
        for (wi, y) in w.iter().zip(&ys) {
            c_new.ger(p.cmu * wi, y, y, 1.0);
        }
        self.c = c_new;

        self.sigma *= ((p.cs / p.ds) * (ps_norm / p.chi_n - 1.0)).min(1.0).exp();
        // Flat fitness: the best and the ⌈0.7λ⌉-th ranks equal; widen the search (tutorial, §B.3).
        let k = ((0.7 * self.lambda as f64).ceil() as usize).saturating_sub(1).min(costs.len() - 1);
        if rank_cost[order[0]].is_finite() && rank_cost[order[0]] == rank_cost[order[k]] {
            self.sigma *= (0.2 + p.cs / p.ds).exp();
        }

        self.gen_run += 1;
        let cap = 10 + (30 * n).div_ceil(self.lambda);
        let generation_best = finite.iter().copied().fold(f64::INFINITY, f64::min);
        self.history.push(generation_best);
        if self.history.len() > cap {
            self.history.remove(0);
        }
        if let Some(w) = self.stall_generations {
            let so_far = self.best_path.last().copied().unwrap_or(f64::INFINITY).min(generation_best);
            self.best_path.push(so_far);
            if self.best_path.len() > w + 1 {
                self.best_path.remove(0);
            }
        }
    }

    /// Refreshes the eigendecomposition when due, then returns the first stop criterion met, if
    /// any, and whether it counts as convergence (rather than a numerical breakdown).
    fn stop_criterion(&mut self, costs: &[f64]) -> Option<(String, bool)> {
        if !(self.sigma.is_finite() && self.sigma > 0.0) || self.mean.iter().any(|v| !v.is_finite()) {
            return Some((format!("numerical breakdown (σ = {:e})", self.sigma), false));
        }
        let p = Params::new(self.n, self.lambda);
        if self.gen_run - self.gen_eigen >= p.eigen_gap(self.n) && !self.decompose() {
            return Some(("covariance matrix lost positive definiteness".into(), false));
        }
        let sd = self.max_coordinate_sd();
        if let Some(tol) = self.tolx {
            let pc_max = self.sigma * self.pc.amax();
            if sd < tol && pc_max < tol {
                return Some((format!("TolX: σ·max √C_ii = {sd:.3e} < {tol:.3e}"), true));
            }
        }
        if let Some(tol) = self.tolfun {
            let cap = 10 + (30 * self.n).div_ceil(self.lambda);
            if self.history.len() >= cap && costs.iter().all(|c| c.is_finite()) {
                let all = self.history.iter().chain(costs);
                let hi = all.clone().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
                let lo = all.fold(f64::INFINITY, |m, &v| m.min(v));
                if hi - lo < tol {
                    return Some((
                        format!("TolFun: cost range {:.3e} over {cap} generations < {tol:.3e}", hi - lo),
                        true,
                    ));
                }
            }
        }
        if let (Some(w), Some(tol)) = (self.stall_generations, self.tolfun)
            && self.best_path.len() > w
        {
            let (then, now) = (self.best_path[0], self.best_path[w]);
            if now.is_finite() && then - now < tol {
                return Some((
                    format!(
                        "stall: the best cost fell by {:.3e} over the last {w} generations < {tol:.3e}",
                        then - now
                    ),
                    true,
                ));
            }
        }
        if sd < RESOLUTION_FLOOR {
            return Some((format!("σ·max √C_ii = {sd:.3e} below the resolution floor {RESOLUTION_FLOOR:e}"), true));
        }
        let cond = self.condition();
        if cond > MAX_CONDITION {
            return Some((format!("condition number of C {cond:.3e} above {MAX_CONDITION:e}"), true));
        }
        None
    }
}

impl Generational for Core {
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>> {
        let k = self.lambda.min(max);
        self.samples.clear();
        for _ in 0..k {
            let z = DVector::from_fn(self.n, |_, _| self.rng.sample::<f64, _>(StandardNormal));
            let y = &self.b * z.component_mul(&self.d);
            let x = &self.mean + y * self.sigma;
            self.samples.push(x.iter().copied().collect());
        }
        // The book clamps the handed-out copies into the box.
        self.samples.clone()
    }

    fn learn(&mut self, points: &[Vec<f64>], costs: &[f64]) -> Option<StopReason> {
        if costs.len() < self.lambda {
            // Cut short by the budget: nothing more will be proposed.
            return None;
        }
        self.update(points, costs);
        let (why, converged) = self.stop_criterion(costs)?;
        if self.restarts_left > 0 {
            self.restarts_left -= 1;
            self.restarts_done += 1;
            self.lambda = self.lambda.saturating_mul(IPOP_FACTOR);
            let mean = DVector::from_fn(self.n, |_, _| self.rng.r#gen::<f64>());
            self.reset(mean);
            return None;
        }
        let message =
            if self.restarts_done > 0 { format!("{why} (after {} restarts)", self.restarts_done) } else { why };
        Some(if converged { StopReason::Converged { message } } else { StopReason::Exhausted { message } })
    }
}

/// CMA-ES after Hansen's tutorial (2016), optionally with IPOP restarts (Auger and Hansen, 2005): the
/// default global optimiser.
///
/// Samples `x = m + σ·B·D·z`, `z ~ N(0, I)`; one generation is λ samples. The mean starts at `start`
/// (the centre of the box if `None`) with `σ = sigma`, `C = I`. Candidates are the samples clamped
/// to the box; ranking adds a quadratic penalty on the distance of the unclamped sample to the box
/// (see the module documentation). The distribution `N(m, σ²C)` is available through [`mean`],
/// [`sigma`] and [`covariance`] for later stages.
///
/// [`mean`]: Cmaes::mean
/// [`sigma`]: Cmaes::sigma
/// [`covariance`]: Cmaes::covariance
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Cmaes {
    core: Core,
    book: Book,
}

impl Cmaes {
    /// CMA-ES in `dim` unit coordinates from `start` (the centre of the box if `None`), with at most
    /// `budget` evaluations.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: CmaesOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        let m = check_common(dim, start, budget)?;
        let lambda = options.population.unwrap_or_else(|| default_lambda(dim));
        require(
            (2..=MAX_GENERATION).contains(&lambda),
            "population",
            lambda as f64,
            "at least 2 and at most 1 000 000",
        )?;
        require(options.sigma > 0.0 && options.sigma <= 1.0, "sigma", options.sigma, "in (0, 1]")?;
        check_tolerance("tolfun", options.tolfun)?;
        check_tolerance("tolx", options.tolx)?;
        if let Some(w) = options.stall_generations {
            require(w >= 1, "stall_generations", w as f64, "at least 1")?;
        }
        // Restarts double the population; keep it far from overflowing.
        require(options.restarts <= 30, "restarts", options.restarts as f64, "at most 30")?;
        let mut core = Core {
            rng: ChaCha8Rng::seed_from_u64(seed),
            n: dim,
            lambda,
            sigma0: options.sigma,
            tolfun: options.tolfun,
            tolx: options.tolx,
            restarts_left: options.restarts,
            restarts_done: 0,
            mean: DVector::zeros(dim),
            sigma: options.sigma,
            c: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 0),
            d: DVector::zeros(0),
            ps: DVector::zeros(0),
            pc: DVector::zeros(0),
            gen_run: 0,
            gen_eigen: 0,
            samples: Vec::new(),
            history: Vec::new(),
            stall_generations: options.stall_generations,
            best_path: Vec::new(),
        };
        core.reset(DVector::from_vec(m));
        let book = Book::start(dim, budget, &mut core);
        Ok(Self { core, book })
    }

    /// Completed generations (over all restarts).
    pub fn generation(&self) -> usize {
        self.book.generation()
    }

    /// Current distribution mean in unit coordinates. It can lie slightly outside the box (the
    /// boundary penalty pulls it back); clamp it for a point to evaluate.
    pub fn mean(&self) -> &[f64] {
        self.core.mean.as_slice()
    }

    /// Current overall step size σ.
    pub fn sigma(&self) -> f64 {
        self.core.sigma
    }

    /// Current covariance of the sampling distribution, `σ²·C`, in unit coordinates.
    pub fn covariance(&self) -> DMatrix<f64> {
        &self.core.c * (self.core.sigma * self.core.sigma)
    }

    /// Current population size λ (doubled at every IPOP restart).
    pub fn population_size(&self) -> usize {
        self.core.lambda
    }

    /// IPOP restarts done so far.
    pub fn restarts(&self) -> usize {
        self.core.restarts_done
    }
}

delegate_optimizer!(Cmaes);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_population_follows_the_tutorial() {
        assert_eq!([1, 2, 3, 5, 10, 20, 100].map(default_lambda), [4, 6, 7, 8, 10, 12, 17]);
    }

    /// Table 1 of Hansen's tutorial evaluated by hand for n = 10, λ = 10.
    #[test]
    fn strategy_parameters_for_n10() {
        let p = Params::new(10, 10);
        assert_eq!(p.mu, 5);
        assert!((p.weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(p.weights.windows(2).all(|w| w[0] > w[1]));
        let mueff = 1.0 / p.weights.iter().map(|w| w * w).sum::<f64>();
        for (got, want) in [
            (mueff, 3.167_299_281_410_702),
            (p.cs, 0.284_428_587_946_367_4),
            (p.ds, 1.284_428_587_946_367_5),
            (p.cc, 0.294_990_383_035_622_25),
            (p.c1, 0.015_283_824_524_751_714),
            (p.cmu, 0.020_154_282_761_208_37),
        ] {
            assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        }
        assert!((p.chi_n - 3.084_726_2).abs() < 1e-6);
    }

    #[test]
    fn samples_outside_the_box_are_clamped_but_kept_for_the_update() {
        // Mean on a corner: about half of every coordinate's samples fall outside.
        let mut o = Cmaes::new(2, Some(&[1.0, 0.0]), CmaesOptions::default(), 60, 3).unwrap();
        let c = crate::api::Optimizer::ask(&mut o, 6);
        assert!(c.iter().all(|c| c.unit.iter().all(|v| (0.0..=1.0).contains(v))));
        assert!(o.core.samples.iter().any(|s| s[0] > 1.0 || s[1] < 0.0));
    }
}
