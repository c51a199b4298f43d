//! Sensitivity screening: which parameters deserve to be free.
//!
//! [`Sensitivity`] is the paper's one-at-a-time test (section "Sensitivity analysis"): perturb each
//! parameter by a relative step around a base point and report the relative change of the cost over
//! the relative change of the parameter ("12 % change in the parameter value results in 88 % change
//! in the cost function"). [`Morris`] is the elementary-effects screen of Morris (1991,
//! Technometrics 33(2)) with the `μ*` statistic of Campolongo, Cariboni and Saltelli (2007): random
//! one-at-a-time trajectories over a grid of the whole box, so it sees interactions and
//! nonlinearity that a single base point misses. Both give a [`Ranking`] and a suggested free set.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use rand::Rng;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use super::InferenceError;
use super::common::{Completed, Core, Told, check, resolve_start};
use crate::api::StopReason;
use crate::space::Space;

// ---------------------------------------------------------------------------------------------
// Ranking
// ---------------------------------------------------------------------------------------------

/// How to pick a free set from a [`Ranking`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum FreeSelection {
    /// The `k` highest-ranked parameters (those with a nonzero score).
    Top(usize),
    /// Parameters whose score is at least `fraction` of the largest score (and nonzero), at most
    /// `max_count` of them — the paper fixes the parameters "that have no effect on the output" and
    /// typically retained about 20.
    FractionOfMax {
        /// Smallest normalised score kept, in `[0, 1]`.
        fraction: f64,
        /// Largest number of parameters.
        max_count: usize,
    },
}

/// One parameter's place in a [`Ranking`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct RankedParameter {
    /// Index of the parameter in the space.
    pub index: usize,
    /// The score (|relative sensitivity| or Morris `μ*`); `None` when it could not be computed
    /// (every perturbation failed, for example).
    pub score: Option<f64>,
    /// The score divided by the largest score (0 when every score is 0).
    pub normalised: Option<f64>,
}

/// Parameters sorted by decreasing score; parameters without a score come last.
#[derive(Clone, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Ranking {
    /// Highest score first; ties in index order.
    pub entries: Vec<RankedParameter>,
}

impl Ranking {
    /// Ranks scores (non-negative; a score that is not finite counts as missing).
    pub fn from_scores(scores: &[Option<f64>]) -> Self {
        let scores: Vec<Option<f64>> = scores.iter().map(|s| s.filter(|v| v.is_finite()).map(f64::abs)).collect();
        let max = scores.iter().flatten().fold(0.0f64, |m, &v| m.max(v));
        let mut entries: Vec<RankedParameter> = scores
            .iter()
            .enumerate()
            .map(|(index, &score)| RankedParameter {
                index,
                score,
                normalised: score.map(|s| if max > 0.0 { s / max } else { 0.0 }),
            })
            .collect();
        entries.sort_by(|a, b| match (a.score, b.score) {
            (Some(x), Some(y)) => y.total_cmp(&x).then(a.index.cmp(&b.index)),
            (Some(_), None) => std::cmp::Ordering::Less,
            (None, Some(_)) => std::cmp::Ordering::Greater,
            (None, None) => a.index.cmp(&b.index),
        });
        Self { entries }
    }

    /// Parameter indices, highest score first.
    pub fn order(&self) -> Vec<usize> {
        self.entries.iter().map(|e| e.index).collect()
    }

    /// A suggested free set (indices in rank order); parameters without a score or with score 0
    /// are never suggested.
    pub fn suggested_free(&self, rule: FreeSelection) -> Vec<usize> {
        let scored = self.entries.iter().filter(|e| e.score.is_some_and(|s| s > 0.0));
        match rule {
            FreeSelection::Top(k) => scored.take(k).map(|e| e.index).collect(),
            FreeSelection::FractionOfMax { fraction, max_count } => scored
                .filter(|e| e.normalised.is_some_and(|n| n >= fraction))
                .take(max_count)
                .map(|e| e.index)
                .collect(),
        }
    }
}

fn check_selection(algorithm: &'static str, fraction: f64, max_free: usize) -> Result<(), InferenceError> {
    check(algorithm, "free_fraction", fraction, (0.0..=1.0).contains(&fraction), "in [0, 1]")?;
    check(algorithm, "max_free", max_free as f64, max_free >= 1, "at least 1")
}

// ---------------------------------------------------------------------------------------------
// One-at-a-time sensitivity
// ---------------------------------------------------------------------------------------------

/// Options of [`Sensitivity`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default))]
pub struct SensitivityOptions {
    /// Perturbation as a fraction of the physical value (of the range when the value is 0); the
    /// perturbed value is clamped inside the bounds. Default 0.1 (the paper's example used 12 %).
    pub relative_step: f64,
    /// Suggested free set: parameters whose |sensitivity| is at least this fraction of the
    /// largest. Default 0.05.
    pub free_fraction: f64,
    /// Suggested free set: at most this many parameters. Default 20 (the paper's typical count).
    pub max_free: usize,
}

impl Default for SensitivityOptions {
    fn default() -> Self {
        Self { relative_step: 0.1, free_fraction: 0.05, max_free: 20 }
    }
}

/// Which side of the base value a perturbation went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "lowercase"))]
pub enum Side {
    /// Value decreased.
    Lower,
    /// Value increased.
    Upper,
}

/// The finite difference a sensitivity came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "lowercase"))]
pub enum Difference {
    /// Both sides: `(S₊ − S₋)/(p₊ − p₋)`.
    Central,
    /// Upper side only (lower bound, or the lower perturbation failed).
    Forward,
    /// Lower side only.
    Backward,
    /// No usable perturbation (or the base point failed).
    None,
}

/// A perturbation whose evaluation failed.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct PerturbationFailure {
    /// Which side.
    pub side: Side,
    /// The perturbed physical value.
    pub value: f64,
    /// The evaluation's failure reason.
    pub reason: String,
}

/// One parameter's one-at-a-time sensitivity.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ParameterSensitivity {
    /// Index in the space.
    pub index: usize,
    /// Parameter name.
    pub name: String,
    /// Physical value at the base point.
    pub value: f64,
    /// Perturbed physical values (`None` when the base sits on that bound).
    pub lower_value: Option<f64>,
    /// See `lower_value`.
    pub upper_value: Option<f64>,
    /// Costs at the perturbed values (`None` when not evaluated or failed).
    pub lower_cost: Option<f64>,
    /// See `lower_cost`.
    pub upper_cost: Option<f64>,
    /// True when the relative parameter change is taken against the range because the value is 0.
    pub relative_to_range: bool,
    /// `ΔS / (Δp/p)`: cost change per relative parameter change. Defined even when the base cost is
    /// 0; the ranking uses its magnitude (the same order as the relative sensitivity).
    pub scaled_effect: Option<f64>,
    /// The paper's relative sensitivity `(ΔS/S)/(Δp/p)` (`None` when the base cost is 0 or failed).
    pub relative_sensitivity: Option<f64>,
    /// How the difference was formed.
    pub difference: Difference,
    /// Perturbations that failed — often the most telling result of all: the model diverges when
    /// this parameter moves.
    pub failures: Vec<PerturbationFailure>,
}

/// Result of a [`Sensitivity`] run.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct SensitivitySummary {
    /// Base point in unit coordinates.
    pub base_unit: Vec<f64>,
    /// Base point in physical values.
    pub base_physical: Vec<f64>,
    /// Cost at the base point (`None` until evaluated or when it failed).
    pub base_cost: Option<f64>,
    /// Failure reason of the base point.
    pub base_failure: Option<String>,
    /// Per parameter, in space order (empty until the run is complete).
    pub parameters: Vec<ParameterSensitivity>,
    /// By decreasing |relative sensitivity|.
    pub ranking: Ranking,
    /// Indices of the suggested free set (options `free_fraction`, `max_free`).
    pub suggested_free: Vec<usize>,
    /// Evaluations the analysis needs (and uses): 1 + one per existing perturbation, ≤ 2d + 1.
    pub evaluations: usize,
    /// The budget it was given.
    pub budget: usize,
    /// True once every result is in.
    pub complete: bool,
}

/// Where each parameter's perturbations sit in the single generation.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Perturbation {
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    value: f64,
    /// Reference for the relative change: the value, or the range when the value is 0.
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    reference: f64,
    lower: Option<(usize, PhysicalValue)>,
    upper: Option<(usize, PhysicalValue)>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct PhysicalValue(#[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))] f64);

/// One-at-a-time relative sensitivity at a base point (paper, section "Sensitivity analysis").
///
/// The base point is `start` — the registry defaults mapped to unit coordinates, or the previous
/// stage's best — or the centre of the box. Each parameter is moved by `±relative_step` of its
/// physical value (of its range when the value is 0), clamped inside its bounds; a side that would
/// leave the bounds entirely is skipped. The sensitivity is `(ΔS/S)/(Δp/p)`, central where both
/// sides exist. All `1 + Σ sides ≤ 2d + 1` points form one generation; the run finishes as soon as
/// they are told, whatever budget is left.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Sensitivity {
    #[cfg_attr(feature = "serde", serde(with = "crate::exact::space"))]
    space: Space,
    options: SensitivityOptions,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    base: Vec<f64>,
    plan: Vec<Perturbation>,
    evaluations: usize,
    results: Option<Vec<Told>>,
    core: Core,
}

impl Sensitivity {
    const NAME: &'static str = "sensitivity";

    /// Plans the perturbations. `seed` is unused (the design is deterministic) and accepted for the
    /// uniform constructor shape. Errors: bad options, a bad start, or a budget below the number of
    /// evaluations needed (named in the error).
    pub fn new(
        space: &Space,
        start: Option<&[f64]>,
        options: SensitivityOptions,
        budget: usize,
        _seed: u64,
    ) -> Result<Self, InferenceError> {
        let o = &options;
        check(
            Self::NAME,
            "relative_step",
            o.relative_step,
            o.relative_step > 0.0 && o.relative_step <= 1.0,
            "in (0, 1]",
        )?;
        check_selection(Self::NAME, o.free_fraction, o.max_free)?;
        let base = resolve_start(Self::NAME, space.dim(), start)?;
        let mut points = vec![base.clone()];
        let mut plan = Vec::with_capacity(space.dim());
        for (i, p) in space.params().iter().enumerate() {
            let value = space.value(i, base[i]);
            let range = p.upper - p.lower;
            let reference = if value != 0.0 { value } else { range };
            let step = o.relative_step * reference.abs();
            let mut side = |target: f64| -> Option<(usize, PhysicalValue)> {
                let u = space.unit(i, target);
                if u == base[i] {
                    return None;
                }
                let mut x = base.clone();
                x[i] = u;
                points.push(x);
                Some((points.len() - 1, PhysicalValue(space.value(i, u))))
            };
            let lower = if value > p.lower { side((value - step).max(p.lower)) } else { None };
            let upper = if value < p.upper { side((value + step).min(p.upper)) } else { None };
            plan.push(Perturbation { value, reference, lower, upper });
        }
        let evaluations = points.len();
        if budget < evaluations {
            return Err(InferenceError::BudgetTooSmall {
                algorithm: Self::NAME,
                budget,
                required: evaluations,
                needed_for: "the base point and every perturbation",
            });
        }
        let mut core = Core::new(budget);
        core.start(points);
        Ok(Self { space: space.clone(), options, base, plan, evaluations, results: None, core })
    }

    fn absorb(&mut self, done: Completed) {
        let reason = match &done.results[0] {
            Told::Failed(r) => StopReason::Exhausted { message: format!("the base point failed: {r}") },
            Told::Cost(_) => StopReason::Converged {
                message: format!(
                    "one-at-a-time analysis complete after {} evaluations (budget {})",
                    self.evaluations,
                    self.core.budget()
                ),
            },
        };
        self.results = Some(done.results);
        self.core.finish(reason);
    }

    /// The analysis so far (complete once the algorithm has finished).
    pub fn summary(&self) -> SensitivitySummary {
        let base_physical = self.space.to_physical(&self.base);
        let mut s = SensitivitySummary {
            base_unit: self.base.clone(),
            base_physical,
            base_cost: None,
            base_failure: None,
            parameters: Vec::new(),
            ranking: Ranking::default(),
            suggested_free: Vec::new(),
            evaluations: self.evaluations,
            budget: self.core.budget(),
            complete: false,
        };
        let Some(results) = &self.results else { return s };
        s.complete = true;
        let s0 = results[0].cost();
        s.base_cost = s0;
        s.base_failure = results[0].reason().map(str::to_owned);
        for (i, (pert, name)) in self.plan.iter().zip(self.space.names()).enumerate() {
            let side_cost = |side: Option<(usize, PhysicalValue)>| side.and_then(|(k, _)| results[k].cost());
            let (lc, uc) = (side_cost(pert.lower), side_cost(pert.upper));
            let (lv, uv) = (pert.lower.map(|(_, v)| v.0), pert.upper.map(|(_, v)| v.0));
            let mut failures = Vec::new();
            for (side, entry) in [(Side::Lower, pert.lower), (Side::Upper, pert.upper)] {
                if let Some((k, v)) = entry
                    && let Told::Failed(reason) = &results[k]
                {
                    failures.push(PerturbationFailure { side, value: v.0, reason: reason.clone() });
                }
            }
            let (difference, ds_dp) = match (s0, lc, uc, lv, uv) {
                (Some(_), Some(l), Some(u), Some(a), Some(b)) => (Difference::Central, Some((u - l) / (b - a))),
                (Some(c), None, Some(u), _, Some(b)) => (Difference::Forward, Some((u - c) / (b - pert.value))),
                (Some(c), Some(l), None, Some(a), _) => (Difference::Backward, Some((c - l) / (pert.value - a))),
                _ => (Difference::None, None),
            };
            // ΔS / (Δp / p) = p · ΔS/Δp.
            let scaled_effect = ds_dp.map(|g| g * pert.reference);
            let relative_sensitivity = match (scaled_effect, s0) {
                (Some(e), Some(c)) if c > 0.0 => Some(e / c),
                _ => None,
            };
            s.parameters.push(ParameterSensitivity {
                index: i,
                name: name.to_owned(),
                value: pert.value,
                lower_value: lv,
                upper_value: uv,
                lower_cost: lc,
                upper_cost: uc,
                relative_to_range: pert.value == 0.0,
                scaled_effect,
                relative_sensitivity,
                difference,
                failures,
            });
        }
        let scores: Vec<Option<f64>> = s.parameters.iter().map(|p| p.scaled_effect).collect();
        s.ranking = Ranking::from_scores(&scores);
        s.suggested_free = s.ranking.suggested_free(FreeSelection::FractionOfMax {
            fraction: self.options.free_fraction,
            max_count: self.options.max_free,
        });
        s
    }
}

super::delegate_to_core!(Sensitivity);

// ---------------------------------------------------------------------------------------------
// Morris elementary effects
// ---------------------------------------------------------------------------------------------

/// Options of [`Morris`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default))]
pub struct MorrisOptions {
    /// Number of trajectories `r` (each costs d + 1 evaluations). Default 10.
    pub trajectories: usize,
    /// Number of grid levels `p` per unit coordinate (even, ≥ 2); the step is `Δ = p/(2(p − 1))`,
    /// Morris's recommended choice. Default 4.
    pub levels: usize,
    /// Suggested free set: `μ*` at least this fraction of the largest. Default 0.05.
    pub free_fraction: f64,
    /// Suggested free set: at most this many parameters. Default 20.
    pub max_free: usize,
}

impl Default for MorrisOptions {
    fn default() -> Self {
        Self { trajectories: 10, levels: 4, free_fraction: 0.05, max_free: 20 }
    }
}

/// Elementary-effect statistics of one parameter.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ElementaryEffects {
    /// Index in the space.
    pub index: usize,
    /// Mean elementary effect `μ` (cost per unit coordinate); cancels for non-monotonic effects.
    pub mu: Option<f64>,
    /// Mean absolute elementary effect `μ*` (Campolongo et al. 2007): the importance measure.
    pub mu_star: Option<f64>,
    /// Standard deviation of the effects: nonlinearity or interactions.
    pub sigma: Option<f64>,
    /// Effects computed.
    pub effects: usize,
    /// Effects lost because one of their two evaluations failed.
    pub failed: usize,
}

/// Result of a [`Morris`] run.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct MorrisSummary {
    /// Per parameter, in space order (empty until complete).
    pub parameters: Vec<ElementaryEffects>,
    /// By decreasing `μ*`.
    pub ranking: Ranking,
    /// Indices of the suggested free set.
    pub suggested_free: Vec<usize>,
    /// The step `Δ` in unit coordinates.
    pub delta: f64,
    /// Evaluations used: `r (d + 1)`.
    pub evaluations: usize,
    /// Failed evaluations.
    pub failed_evaluations: usize,
    /// The budget it was given.
    pub budget: usize,
    /// True once every result is in.
    pub complete: bool,
}

/// Morris elementary-effects screening in unit coordinates (Morris 1991; `μ*` after Campolongo,
/// Cariboni and Saltelli 2007).
///
/// Each trajectory starts at a random grid point and moves every coordinate once, in random order,
/// by `±Δ` (the direction that stays in the box). The elementary effect of parameter `i` is the
/// cost change over the coordinate change. All `r (d + 1)` points form one generation. `start` is
/// accepted for the uniform constructor shape and only checked: the screen covers the whole box.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Morris {
    dim: usize,
    options: MorrisOptions,
    /// For each trajectory step (trajectory-major): the parameter moved.
    moved: Vec<usize>,
    results: Option<Vec<Told>>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    points: Vec<Vec<f64>>,
    core: Core,
}

impl Morris {
    const NAME: &'static str = "morris";

    /// Draws the trajectories. Errors: bad options or start, budget below `r (d + 1)`.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: MorrisOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, InferenceError> {
        let o = &options;
        resolve_start(Self::NAME, dim, start)?;
        check(Self::NAME, "trajectories", o.trajectories as f64, o.trajectories >= 1, "at least 1")?;
        check(
            Self::NAME,
            "levels",
            o.levels as f64,
            o.levels >= 2 && o.levels.is_multiple_of(2),
            "even and at least 2",
        )?;
        check_selection(Self::NAME, o.free_fraction, o.max_free)?;
        let required = o.trajectories * (dim + 1);
        if budget < required {
            return Err(InferenceError::BudgetTooSmall {
                algorithm: Self::NAME,
                budget,
                required,
                needed_for: "trajectories × (parameters + 1)",
            });
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p = o.levels;
        let half = p / 2;
        let level = |l: usize| l as f64 / (p - 1) as f64;
        let mut points = Vec::with_capacity(required);
        let mut moved = Vec::with_capacity(o.trajectories * dim);
        for _ in 0..o.trajectories {
            let mut levels: Vec<usize> = (0..dim).map(|_| rng.gen_range(0..p)).collect();
            let mut order: Vec<usize> = (0..dim).collect();
            order.shuffle(&mut rng);
            points.push(levels.iter().map(|&l| level(l)).collect());
            for &i in &order {
                levels[i] = if levels[i] + half < p { levels[i] + half } else { levels[i] - half };
                points.push(levels.iter().map(|&l| level(l)).collect());
                moved.push(i);
            }
        }
        let mut core = Core::new(budget);
        core.start(points.clone());
        Ok(Self { dim, options, moved, results: None, points, core })
    }

    fn absorb(&mut self, done: Completed) {
        let failed = done.results.iter().filter(|r| r.cost().is_none()).count();
        let reason = if failed == done.results.len() {
            StopReason::Exhausted { message: "every evaluation failed".into() }
        } else {
            StopReason::Converged {
                message: format!(
                    "{} trajectories complete after {} evaluations (budget {})",
                    self.options.trajectories,
                    done.results.len(),
                    self.core.budget()
                ),
            }
        };
        self.results = Some(done.results);
        self.core.finish(reason);
    }

    /// The screening so far (complete once the algorithm has finished).
    pub fn summary(&self) -> MorrisSummary {
        let p = self.options.levels as f64;
        let mut s = MorrisSummary {
            parameters: Vec::new(),
            ranking: Ranking::default(),
            suggested_free: Vec::new(),
            delta: p / (2.0 * (p - 1.0)),
            evaluations: self.points.len(),
            failed_evaluations: 0,
            budget: self.core.budget(),
            complete: false,
        };
        let Some(results) = &self.results else { return s };
        s.complete = true;
        s.failed_evaluations = results.iter().filter(|r| r.cost().is_none()).count();
        let d = self.dim;
        let mut effects = vec![Vec::new(); d];
        let mut failed = vec![0usize; d];
        for t in 0..self.options.trajectories {
            for step in 0..d {
                let k = t * (d + 1) + step;
                let i = self.moved[t * d + step];
                match (results[k].cost(), results[k + 1].cost()) {
                    (Some(a), Some(b)) => effects[i].push((b - a) / (self.points[k + 1][i] - self.points[k][i])),
                    _ => failed[i] += 1,
                }
            }
        }
        for (index, e) in effects.iter().enumerate() {
            let n = e.len() as f64;
            let mu = (!e.is_empty()).then(|| e.iter().sum::<f64>() / n);
            let mu_star = (!e.is_empty()).then(|| e.iter().map(|v| v.abs()).sum::<f64>() / n);
            let sigma = mu
                .filter(|_| e.len() >= 2)
                .map(|m| (e.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt());
            s.parameters.push(ElementaryEffects { index, mu, mu_star, sigma, effects: e.len(), failed: failed[index] });
        }
        let scores: Vec<Option<f64>> = s.parameters.iter().map(|p| p.mu_star).collect();
        s.ranking = Ranking::from_scores(&scores);
        s.suggested_free = s.ranking.suggested_free(FreeSelection::FractionOfMax {
            fraction: self.options.free_fraction,
            max_count: self.options.max_free,
        });
        s
    }
}

super::delegate_to_core!(Morris);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranking_orders_by_score_then_index_with_missing_last() {
        let r = Ranking::from_scores(&[Some(1.0), None, Some(-4.0), Some(1.0), Some(0.0), Some(f64::NAN)]);
        assert_eq!(r.order(), vec![2, 0, 3, 4, 1, 5]);
        assert_eq!(r.entries[1].normalised, Some(0.25));
        assert_eq!(r.suggested_free(FreeSelection::FractionOfMax { fraction: 0.2, max_count: 2 }), vec![2, 0]);
        assert_eq!(r.suggested_free(FreeSelection::Top(10)), vec![2, 0, 3], "zero and missing scores never suggested");
    }
}
