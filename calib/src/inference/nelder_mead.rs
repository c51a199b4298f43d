//! Nelder–Mead simplex search in unit coordinates (Nelder and Mead 1965, with the acceptance rules
//! as stated by Lagarias, Reeds, Wright and Wright 1998, SIAM J. Optim. 9(1), and optionally the
//! dimension-adaptive coefficients of Gao and Han 2012, Comput. Optim. Appl. 51(1)).
//!
//! The paper uses the simplex method near the optimum ("local search with multiple restarts",
//! section "Variance of the model parameters"). The method is sequential: after the initial
//! simplex, each step asks for one point (reflection, then perhaps expansion or contraction) or, on
//! a shrink, for the d moved vertices at once. Points leaving the box are clamped into it.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::InferenceError;
use super::common::{Completed, Core, check, clamp_unit, resolve_start};
use crate::api::StopReason;

/// Options of [`NelderMead`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default))]
pub struct NelderMeadOptions {
    /// Edge of the initial simplex in unit coordinates: vertex `i` is the start moved by this much
    /// along coordinate `i` (backwards when forwards would leave the box). Default 0.1.
    pub initial_step: f64,
    /// Use the Gao–Han coefficients (expansion `1 + 2/d`, contraction `3/4 − 1/(2d)`, shrink
    /// `1 − 1/d`) when d > 2; the standard `1, 2, ½, ½` otherwise. Default true.
    pub adaptive: bool,
    /// Stop when every vertex is within this distance (max-norm, unit coordinates) of the best one…
    /// Default 1e-6.
    pub x_tol: f64,
    /// …and the cost spread over the simplex is at most this (absolute, in cost units). Default 1e-8.
    pub f_tol: f64,
}

impl Default for NelderMeadOptions {
    fn default() -> Self {
        Self { initial_step: 0.1, adaptive: true, x_tol: 1e-6, f_tol: 1e-8 }
    }
}

impl NelderMeadOptions {
    pub(crate) fn validate(&self, algorithm: &'static str) -> Result<(), InferenceError> {
        let s = self.initial_step;
        check(algorithm, "initial_step", s, s > 0.0 && s <= 0.5, "in (0, 0.5]")?;
        check(algorithm, "x_tol", self.x_tol, self.x_tol >= 0.0 && self.x_tol.is_finite(), "finite and ≥ 0")?;
        check(algorithm, "f_tol", self.f_tol, self.f_tol >= 0.0 && self.f_tol.is_finite(), "finite and ≥ 0")
    }
}

/// How often each kind of step was taken.
#[derive(Clone, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct StepCounts {
    /// Reflections accepted.
    pub reflections: usize,
    /// Expansions accepted.
    pub expansions: usize,
    /// Contractions accepted (inside and outside).
    pub contractions: usize,
    /// Shrinks.
    pub shrinks: usize,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
enum Phase {
    Init,
    Reflect {
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        centroid: Vec<f64>,
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        point: Vec<f64>,
    },
    Expand {
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        reflected: Vec<f64>,
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        reflected_cost: f64,
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        point: Vec<f64>,
    },
    Contract {
        outside: bool,
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        reflected_cost: f64,
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        point: Vec<f64>,
    },
    Shrink {
        count: usize,
    },
    Done,
}

/// What the simplex wants next.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Step {
    Evaluate(Vec<Vec<f64>>),
    Converged(String),
    Budget,
    Exhausted(String),
}

impl Step {
    /// The stop reason of a terminal step.
    pub(crate) fn stop_reason(&self) -> Option<StopReason> {
        match self {
            Step::Evaluate(_) => None,
            Step::Converged(m) => Some(StopReason::Converged { message: m.clone() }),
            Step::Budget => Some(StopReason::Budget),
            Step::Exhausted(m) => Some(StopReason::Exhausted { message: m.clone() }),
        }
    }
}

/// The simplex state machine without ids or budget bookkeeping, so that [`NelderMead`] and the
/// variance stage's restarts share it. Costs of failed points are `+∞`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub(crate) struct Simplex {
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    coefficients: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    x_tol: f64,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    f_tol: f64,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    vertices: Vec<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    costs: Vec<f64>,
    phase: Phase,
    iterations: usize,
    counts: StepCounts,
}

impl Simplex {
    /// The initial simplex around `start` (inside the box; options already validated).
    pub(crate) fn new(start: &[f64], options: &NelderMeadOptions) -> Self {
        let n = start.len();
        let nf = n as f64;
        let coefficients = if options.adaptive && n > 2 {
            vec![1.0, 1.0 + 2.0 / nf, 0.75 - 0.5 / nf, 1.0 - 1.0 / nf]
        } else {
            vec![1.0, 2.0, 0.5, 0.5]
        };
        let mut vertices = vec![start.to_vec()];
        for i in 0..n {
            let mut v = start.to_vec();
            let h = options.initial_step;
            v[i] = if v[i] + h <= 1.0 { v[i] + h } else { v[i] - h };
            vertices.push(clamp_unit(v));
        }
        Self {
            coefficients,
            x_tol: options.x_tol,
            f_tol: options.f_tol,
            costs: vec![f64::INFINITY; n + 1],
            vertices,
            phase: Phase::Init,
            iterations: 0,
            counts: StepCounts::default(),
        }
    }

    /// The points of the initial simplex (d + 1 of them), to evaluate first.
    pub(crate) fn initial_points(&self) -> Vec<Vec<f64>> {
        self.vertices.clone()
    }

    /// The best vertex and its cost.
    pub(crate) fn best(&self) -> (&[f64], f64) {
        let k = (0..self.costs.len()).min_by(|&a, &b| self.costs[a].total_cmp(&self.costs[b])).unwrap_or(0);
        (&self.vertices[k], self.costs[k])
    }

    pub(crate) fn iterations(&self) -> usize {
        self.iterations
    }

    fn size(&self) -> f64 {
        let (b, _) = self.best();
        self.vertices
            .iter()
            .map(|v| v.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max)
    }

    fn spread(&self) -> f64 {
        let lo = self.costs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self.costs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if hi.is_finite() { hi - lo } else { f64::INFINITY }
    }

    /// Takes the costs of the points last requested (in request order) and says what comes next;
    /// `remaining` is the evaluations still allowed.
    pub(crate) fn absorb(&mut self, costs: &[f64], remaining: usize) -> Step {
        let n = self.vertices.len() - 1;
        let [_, beta, gamma, _] =
            [self.coefficients[0], self.coefficients[1], self.coefficients[2], self.coefficients[3]];
        match std::mem::replace(&mut self.phase, Phase::Done) {
            Phase::Init => self.costs.copy_from_slice(costs),
            Phase::Reflect { centroid, point } => {
                let fr = costs[0];
                let (f0, fsw, fw) = (self.costs[0], self.costs[n - 1], self.costs[n]);
                if fr < f0 {
                    if remaining == 0 {
                        self.replace_worst(point, fr);
                        self.counts.reflections += 1;
                        return Step::Budget;
                    }
                    let xe = self.along(&centroid, beta);
                    self.phase = Phase::Expand { reflected: point, reflected_cost: fr, point: xe.clone() };
                    return Step::Evaluate(vec![xe]);
                } else if fr < fsw {
                    self.replace_worst(point, fr);
                    self.counts.reflections += 1;
                } else {
                    if remaining == 0 {
                        return Step::Budget;
                    }
                    let outside = fr < fw;
                    let xc = if outside { self.along(&centroid, gamma) } else { self.along(&centroid, -gamma) };
                    self.phase = Phase::Contract { outside, reflected_cost: fr, point: xc.clone() };
                    return Step::Evaluate(vec![xc]);
                }
            }
            Phase::Expand { reflected, reflected_cost, point } => {
                if costs[0] < reflected_cost {
                    self.replace_worst(point, costs[0]);
                    self.counts.expansions += 1;
                } else {
                    self.replace_worst(reflected, reflected_cost);
                    self.counts.reflections += 1;
                }
            }
            Phase::Contract { outside, reflected_cost, point } => {
                let fc = costs[0];
                let accept = if outside { fc <= reflected_cost } else { fc < self.costs[n] };
                if accept {
                    self.replace_worst(point, fc);
                    self.counts.contractions += 1;
                } else {
                    return self.shrink(remaining);
                }
            }
            Phase::Shrink { count } => self.costs[1..=count].copy_from_slice(costs),
            Phase::Done => return Step::Exhausted("the simplex was asked to continue after it stopped".into()),
        }
        self.iterate(remaining)
    }

    /// `c + t (c − x_worst)`, clamped into the box: reflection (t = α), expansion (t = β), outside
    /// contraction (t = γα with α = 1) and inside contraction (t = −γ).
    fn along(&self, centroid: &[f64], t: f64) -> Vec<f64> {
        let worst = &self.vertices[self.vertices.len() - 1];
        clamp_unit(centroid.iter().zip(worst).map(|(c, w)| c + t * (c - w)).collect())
    }

    fn replace_worst(&mut self, x: Vec<f64>, f: f64) {
        let n = self.vertices.len() - 1;
        self.vertices[n] = x;
        self.costs[n] = f;
    }

    fn shrink(&mut self, remaining: usize) -> Step {
        let n = self.vertices.len() - 1;
        let count = n.min(remaining);
        if count == 0 {
            return Step::Budget;
        }
        let delta = self.coefficients[3];
        let best = self.vertices[0].clone();
        for v in &mut self.vertices[1..=count] {
            for (x, b) in v.iter_mut().zip(&best) {
                *x = b + delta * (*x - b);
            }
        }
        self.counts.shrinks += 1;
        self.phase = Phase::Shrink { count };
        Step::Evaluate(self.vertices[1..=count].to_vec())
    }

    /// Orders the vertices, tests convergence and asks for the next reflection.
    fn iterate(&mut self, remaining: usize) -> Step {
        let n = self.vertices.len() - 1;
        let mut order: Vec<usize> = (0..=n).collect();
        order.sort_by(|&a, &b| self.costs[a].total_cmp(&self.costs[b]).then(a.cmp(&b)));
        self.vertices = order.iter().map(|&k| self.vertices[k].clone()).collect();
        self.costs = order.iter().map(|&k| self.costs[k]).collect();
        if !self.costs[0].is_finite() {
            return Step::Exhausted("every vertex of the simplex failed".into());
        }
        let (size, spread) = (self.size(), self.spread());
        if size <= self.x_tol && spread <= self.f_tol {
            return Step::Converged(format!(
                "simplex size {size:.3e} ≤ x_tol {:.1e} and cost spread {spread:.3e} ≤ f_tol {:.1e}",
                self.x_tol, self.f_tol
            ));
        }
        if size <= 1e-13 {
            return Step::Converged(format!(
                "simplex collapsed (size {size:.3e}) with cost spread {spread:.3e} above f_tol {:.1e}",
                self.f_tol
            ));
        }
        if remaining == 0 {
            return Step::Budget;
        }
        self.iterations += 1;
        let centroid: Vec<f64> = (0..self.vertices[0].len())
            .map(|k| self.vertices[..n].iter().map(|v| v[k]).sum::<f64>() / n as f64)
            .collect();
        let point = self.along(&centroid, self.coefficients[0]);
        self.phase = Phase::Reflect { centroid, point: point.clone() };
        Step::Evaluate(vec![point])
    }

    fn counts(&self) -> &StepCounts {
        &self.counts
    }
}

/// Result of a [`NelderMead`] run.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct NelderMeadSummary {
    /// Best point found (unit coordinates).
    pub best_unit: Option<Vec<f64>>,
    /// Its cost.
    pub best_cost: Option<f64>,
    /// Iterations (reflections attempted).
    pub iterations: usize,
    /// Accepted steps by kind.
    pub steps: StepCounts,
    /// Current simplex size: max-norm distance of the vertices from the best one.
    pub simplex_size: f64,
    /// Current cost spread over the simplex (`None` while a vertex has failed).
    pub cost_spread: Option<f64>,
    /// Coefficients used: reflection, expansion, contraction, shrink.
    pub coefficients: Vec<f64>,
    /// Evaluations handed out.
    pub evaluations: usize,
    /// The budget.
    pub budget: usize,
    /// Why it stopped, once finished.
    pub stop: Option<StopReason>,
}

/// Nelder–Mead simplex search as an ask/tell optimiser (Nelder and Mead 1965; Lagarias et al. 1998
/// rules; Gao–Han 2012 adaptive coefficients optional).
///
/// Inherently sequential: one point per step (d on a shrink), so parallel workers idle — use it for
/// local refinement. Deterministic; `seed` is accepted for the uniform constructor shape.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct NelderMead {
    options: NelderMeadOptions,
    simplex: Simplex,
    core: Core,
}

impl NelderMead {
    const NAME: &'static str = "nelder_mead";

    /// Builds the initial simplex at `start` (or the centre). Errors: bad options or start, budget
    /// below d + 1 (the initial simplex).
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: NelderMeadOptions,
        budget: usize,
        _seed: u64,
    ) -> Result<Self, InferenceError> {
        options.validate(Self::NAME)?;
        let start = resolve_start(Self::NAME, dim, start)?;
        if budget < dim + 1 {
            return Err(InferenceError::BudgetTooSmall {
                algorithm: Self::NAME,
                budget,
                required: dim + 1,
                needed_for: "the initial simplex",
            });
        }
        let simplex = Simplex::new(&start, &options);
        let mut core = Core::new(budget);
        core.start(simplex.initial_points());
        Ok(Self { options, simplex, core })
    }

    fn absorb(&mut self, done: Completed) {
        let costs: Vec<f64> = done.results.iter().map(|r| r.rank()).collect();
        match self.simplex.absorb(&costs, self.core.remaining()) {
            Step::Evaluate(points) => self.core.start(points),
            terminal => self.core.finish(terminal.stop_reason().unwrap_or(StopReason::Budget)),
        }
    }

    /// The options in use.
    pub fn options(&self) -> &NelderMeadOptions {
        &self.options
    }

    /// The search so far.
    pub fn summary(&self) -> NelderMeadSummary {
        let best = self.core.best_point();
        let spread = self.simplex.spread();
        NelderMeadSummary {
            best_unit: best.map(|b| b.0.to_vec()),
            best_cost: best.map(|b| b.1),
            iterations: self.simplex.iterations(),
            steps: self.simplex.counts().clone(),
            simplex_size: self.simplex.size(),
            cost_spread: spread.is_finite().then_some(spread),
            coefficients: self.simplex.coefficients.clone(),
            evaluations: self.core.used(),
            budget: self.core.budget(),
            stop: self.core.finished(),
        }
    }
}

super::delegate_to_core!(NelderMead);
