//! Simulated annealing, made batch-parallel and deterministic.
//!
//! After Kirkpatrick, Gelatt and Vecchi, "Optimization by simulated annealing" (Science, 1983):
//! Metropolis acceptance of random moves at a slowly decreasing temperature. To use parallel
//! workers, each generation proposes `batch` Gaussian moves from the current state at once; when
//! all are evaluated, they are offered to the Metropolis test one after the other in id order, each
//! against the state as it stands then, with uniforms drawn when the moves were proposed. The
//! temperature falls geometrically per generation, starting from the spread of the first
//! generation's costs (White, "Concepts of scale in simulated annealing", 1984, relates the useful
//! starting temperature to the standard deviation of the cost); the move size adapts towards a
//! target acceptance rate.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use super::engine::{
    Book, Generational, MAX_GENERATION, RESOLUTION_FLOOR, check_common, check_tolerance, delegate_optimizer, reflect,
    require,
};
use crate::api::StopReason;

/// Ratio of the final to the initial temperature when `cooling` is chosen from the budget.
const AUTO_COOLING_RATIO: f64 = 1e-9;
/// Largest move standard deviation, in unit coordinates.
const MAX_STEP: f64 = 0.5;

/// Options of [`Annealing`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default, deny_unknown_fields))]
pub struct AnnealingOptions {
    /// Moves proposed per generation (1 to 1 000 000): set it to the number of parallel workers.
    pub batch: usize,
    /// Initial standard deviation of a move in every unit coordinate (in `(0, 0.5]`).
    pub initial_step: f64,
    /// Initial temperature (in cost units, > 0). `None`: the standard deviation of the finite costs
    /// of the first generation (the start and its first moves).
    pub initial_temperature: Option<f64>,
    /// Temperature factor per generation (in `(0, 1)`). `None`: chosen so that the temperature falls
    /// by a factor 1e-9 over the budget.
    pub cooling: Option<f64>,
    /// Acceptance rate the move size is steered to (in `(0, 1)`).
    pub target_acceptance: f64,
    /// Stop when the move size falls below this (unit coordinates). Without it the move size stays
    /// above 1e-12 and the budget is used.
    pub tolerance: Option<f64>,
}

impl Default for AnnealingOptions {
    fn default() -> Self {
        Self {
            batch: 8,
            initial_step: 0.2,
            initial_temperature: None,
            cooling: None,
            target_acceptance: 0.25,
            tolerance: None,
        }
    }
}

impl AnnealingOptions {
    fn check(&self) -> Result<(), OptimError> {
        require(
            (1..=MAX_GENERATION).contains(&self.batch),
            "batch",
            self.batch as f64,
            "at least 1 and at most 1 000 000",
        )?;
        require(
            self.initial_step > 0.0 && self.initial_step <= MAX_STEP,
            "initial_step",
            self.initial_step,
            "in (0, 0.5]",
        )?;
        if let Some(t) = self.initial_temperature {
            require(t.is_finite() && t > 0.0, "initial_temperature", t, "a finite number > 0")?;
        }
        if let Some(c) = self.cooling {
            require(c > 0.0 && c < 1.0, "cooling", c, "in (0, 1)")?;
        }
        require(
            self.target_acceptance > 0.0 && self.target_acceptance < 1.0,
            "target_acceptance",
            self.target_acceptance,
            "in (0, 1)",
        )?;
        check_tolerance("tolerance", self.tolerance)
    }
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Core {
    rng: ChaCha8Rng,
    batch: usize,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    cooling: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    target: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolerance: Option<f64>,
    /// Current state of the chain and its cost (`+∞` until known).
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    x: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    fx: f64,
    /// `None` until a generation shows a cost spread.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    temperature: Option<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    step: f64,
    /// Uniforms of the current generation's Metropolis tests, one per candidate.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    uniforms: Vec<f64>,
    /// Whether the current generation starts with the current state itself (the first one).
    with_centre: bool,
    accepted: usize,
}

/// Standard deviation of the finite values (`None` with fewer than two, or no spread).
fn spread(values: impl Iterator<Item = f64>) -> Option<f64> {
    let v: Vec<f64> = values.filter(|c| c.is_finite()).collect();
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let sd = var.sqrt();
    (sd.is_finite() && sd > 0.0).then_some(sd)
}

impl Generational for Core {
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>> {
        let n = self.batch.min(max);
        let mut out = Vec::with_capacity(n);
        self.uniforms.clear();
        for j in 0..n {
            if j == 0 && self.with_centre {
                out.push(self.x.clone());
            } else {
                let p: Vec<f64> = self
                    .x
                    .iter()
                    .map(|&v| reflect(v + self.step * self.rng.sample::<f64, _>(StandardNormal)))
                    .collect();
                out.push(p);
            }
            self.uniforms.push(self.rng.r#gen::<f64>());
        }
        out
    }

    fn learn(&mut self, points: &[Vec<f64>], costs: &[f64]) -> Option<StopReason> {
        let first = if self.with_centre {
            self.with_centre = false;
            self.fx = costs[0];
            1
        } else {
            0
        };
        if self.temperature.is_none() {
            // The state's cost joins the spread unless it is already among `costs` (first generation).
            let state = (first == 0).then_some(self.fx);
            self.temperature = spread(costs.iter().copied().chain(state));
        }
        let t = self.temperature.unwrap_or(0.0);
        let mut accepted = 0usize;
        for j in first..costs.len() {
            let c = costs[j];
            let delta = if c.is_infinite() && self.fx.is_infinite() { 0.0 } else { c - self.fx };
            let accept = delta <= 0.0 || (t > 0.0 && self.uniforms[j] < (-delta / t).exp());
            if accept {
                self.x.clone_from(&points[j]);
                self.fx = c;
                accepted += 1;
            }
        }
        self.accepted += accepted;
        let proposed = costs.len() - first.min(costs.len());
        if proposed > 0 {
            let rate = accepted as f64 / proposed as f64;
            self.step = (self.step * (2.0 * (rate - self.target)).exp()).clamp(RESOLUTION_FLOOR, MAX_STEP);
        }
        if let Some(t) = self.temperature.as_mut() {
            *t *= self.cooling;
        }
        if let Some(tol) = self.tolerance
            && self.step < tol
        {
            return Some(StopReason::Converged {
                message: format!("move size {:.3e} < tolerance {tol:.3e}", self.step),
            });
        }
        None
    }
}

/// Batch-parallel simulated annealing (Kirkpatrick, Gelatt and Vecchi, Science 1983) with
/// deterministic Metropolis tests.
///
/// Each generation proposes `batch` moves `x + step·N(0, I)` (mirrored into the box) from the current
/// state `x`, together with one uniform per move. Once all are evaluated, the moves are tested in id
/// order against the state as it then is: accepted if not worse, else with probability
/// `exp(−Δ/T)`. Failed evaluations are never accepted (unless the state itself failed). After each
/// generation the temperature is multiplied by `cooling` and the move size by
/// `exp(2 (acceptance − target))`, kept within `[1e-12, 0.5]`. The first generation also evaluates
/// the start; the initial temperature defaults to the standard deviation of that generation's
/// finite costs (White, 1984), or of the first generation that shows a spread.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Annealing {
    core: Core,
    book: Book,
}

impl Annealing {
    /// Simulated annealing in `dim` unit coordinates from `start` (the centre of the box if `None`),
    /// with at most `budget` evaluations.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: AnnealingOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        let x = check_common(dim, start, budget)?;
        options.check()?;
        let generations = budget.div_ceil(options.batch).max(1);
        let cooling = options.cooling.unwrap_or_else(|| AUTO_COOLING_RATIO.powf(1.0 / generations as f64));
        let mut core = Core {
            rng: ChaCha8Rng::seed_from_u64(seed),
            batch: options.batch,
            cooling,
            target: options.target_acceptance,
            tolerance: options.tolerance,
            x,
            fx: f64::INFINITY,
            temperature: options.initial_temperature,
            step: options.initial_step,
            uniforms: Vec::new(),
            with_centre: true,
            accepted: 0,
        };
        let book = Book::start(dim, budget, &mut core);
        Ok(Self { core, book })
    }

    /// Completed generations.
    pub fn generation(&self) -> usize {
        self.book.generation()
    }

    /// The current temperature (`None` until it could be set from a cost spread).
    pub fn temperature(&self) -> Option<f64> {
        self.core.temperature
    }

    /// The current move standard deviation in unit coordinates.
    pub fn step(&self) -> f64 {
        self.core.step
    }

    /// The current state of the chain.
    pub fn current(&self) -> &[f64] {
        &self.core.x
    }

    /// Moves accepted so far.
    pub fn accepted(&self) -> usize {
        self.core.accepted
    }
}

delegate_optimizer!(Annealing);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_ignores_failures_and_needs_two_values() {
        assert_eq!(spread([1.0, f64::INFINITY].into_iter()), None);
        assert_eq!(spread([2.0, 2.0].into_iter()), None);
        let sd = spread([1.0, 3.0, f64::INFINITY].into_iter()).unwrap();
        assert!((sd - 2f64.sqrt()).abs() < 1e-15);
    }

    #[test]
    fn cooling_from_the_budget_reaches_the_stated_ratio() {
        let o = Annealing::new(2, None, AnnealingOptions::default(), 800, 1).unwrap();
        assert!((o.core.cooling.powi(100) - AUTO_COOLING_RATIO).abs() < 1e-20);
    }
}
