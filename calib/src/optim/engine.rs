//! The bookkeeping every generation-synchronous optimiser shares: ids, hand-out, tell validation,
//! budget, best point and the stop reason. An algorithm only implements [`Generational`]: propose a
//! whole generation, learn from it once every result is in.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use crate::api::{Best, Candidate, CandidateId, Evaluation, Outcome, StopReason, TellError};

/// Below this step (in unit coordinates) a search cannot tell points apart any more: the step, span
/// or spread based algorithms stop there even without a tolerance.
pub(crate) const RESOLUTION_FLOOR: f64 = 1e-12;

/// Largest generation-size option (population, swarm, batch, grid points) accepted.
pub(crate) const MAX_GENERATION: usize = 1_000_000;

/// One algorithm's generation logic.
pub(crate) trait Generational {
    /// Proposes the next generation: at least one and at most `max` points of the search dimension.
    /// Components outside `[0, 1]` are clamped by the caller (the algorithm keeps its own copy if it
    /// needs the unclamped point).
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>>;

    /// Learns from the completed generation: `points` as handed out, `costs` in the same order
    /// (`+∞` for failed evaluations). Returns a reason to stop early, if any.
    fn learn(&mut self, points: &[Vec<f64>], costs: &[f64]) -> Option<StopReason>;
}

/// Best point seen, kept with exact floats in the serialised state.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub(crate) struct BestPoint {
    id: CandidateId,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    unit: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    cost: f64,
}

/// Ids, hand-out and results of the current generation, the budget and the stop reason.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub(crate) struct Book {
    dim: usize,
    budget: usize,
    /// Ids generated so far (also the id of the next generation's first candidate).
    generated: u64,
    told: usize,
    /// Completed generations.
    generation: usize,
    /// Id of the current generation's first candidate.
    first_id: u64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    points: Vec<Vec<f64>>,
    handed: usize,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    costs: Vec<Option<f64>>,
    received: usize,
    best: Option<BestPoint>,
    stop: Option<StopReason>,
}

impl Book {
    /// A book for `budget` evaluations in `dim` dimensions, with the first generation proposed.
    pub(crate) fn start<G: Generational>(dim: usize, budget: usize, algo: &mut G) -> Self {
        let mut book = Self {
            dim,
            budget,
            generated: 0,
            told: 0,
            generation: 0,
            first_id: 0,
            points: Vec::new(),
            handed: 0,
            costs: Vec::new(),
            received: 0,
            best: None,
            stop: None,
        };
        book.begin(algo);
        book
    }

    /// Completed generations: the index of the generation being handed out or evaluated.
    pub(crate) fn generation(&self) -> usize {
        self.generation
    }

    fn remaining_budget(&self) -> usize {
        // `generated` never exceeds `budget`, which is a usize.
        self.budget.saturating_sub(usize::try_from(self.generated).unwrap_or(usize::MAX))
    }

    /// Starts the next generation, or sets the stop reason when the budget is handed out.
    fn begin<G: Generational>(&mut self, algo: &mut G) {
        if self.stop.is_some() {
            return;
        }
        let remaining = self.remaining_budget();
        if remaining == 0 {
            self.stop = Some(match &self.best {
                Some(_) => StopReason::Budget,
                None => {
                    StopReason::Exhausted { message: format!("all {} evaluations of the budget failed", self.told) }
                }
            });
            return;
        }
        let mut points = algo.propose(remaining);
        points.truncate(remaining);
        if points.is_empty() {
            self.stop = Some(StopReason::Exhausted { message: "the algorithm proposed no new point".into() });
            return;
        }
        for p in &mut points {
            debug_assert_eq!(p.len(), self.dim);
            p.resize(self.dim, 0.5);
            for v in p.iter_mut() {
                *v = if v.is_nan() { 0.5 } else { v.clamp(0.0, 1.0) };
            }
        }
        self.first_id = self.generated;
        self.generated += points.len() as u64;
        self.handed = 0;
        self.received = 0;
        self.costs = vec![None; points.len()];
        self.points = points;
    }

    /// Hands out up to `n` candidates of the current generation.
    pub(crate) fn ask(&mut self, n: usize) -> Vec<Candidate> {
        if self.stop.is_some() {
            return Vec::new();
        }
        let end = self.points.len().min(self.handed.saturating_add(n));
        let out = (self.handed..end)
            .map(|i| Candidate { id: self.first_id + i as u64, unit: self.points[i].clone() })
            .collect();
        self.handed = end;
        out
    }

    /// Index in the current generation of a handed-out, not yet told id.
    fn index_of(&self, id: CandidateId) -> Result<usize, TellError> {
        if id < self.first_id {
            // Every earlier generation is complete.
            return if id < self.generated { Err(TellError::Duplicate { id }) } else { Err(TellError::Unknown { id }) };
        }
        let i = usize::try_from(id - self.first_id).map_err(|_| TellError::Unknown { id })?;
        if i >= self.handed {
            return Err(TellError::Unknown { id });
        }
        if self.costs[i].is_some() {
            return Err(TellError::Duplicate { id });
        }
        Ok(i)
    }

    /// Validates every result first (a rejected batch changes nothing), records them, and lets the
    /// algorithm learn once the generation is complete.
    pub(crate) fn tell<G: Generational>(&mut self, results: &[Evaluation], algo: &mut G) -> Result<(), TellError> {
        let mut seen = vec![false; self.points.len()];
        let mut indices = Vec::with_capacity(results.len());
        for e in results {
            let i = self.index_of(e.id)?;
            if seen[i] {
                return Err(TellError::Duplicate { id: e.id });
            }
            seen[i] = true;
            if let Outcome::Ok { cost } = e.outcome
                && !(cost.is_finite() && cost >= 0.0)
            {
                return Err(TellError::BadCost { id: e.id, cost });
            }
            indices.push(i);
        }
        for (e, &i) in results.iter().zip(&indices) {
            let cost = e.outcome.rank_cost();
            self.costs[i] = Some(cost);
            self.received += 1;
            self.told += 1;
            if cost.is_finite() {
                let better = match &self.best {
                    None => true,
                    Some(b) => cost < b.cost || (cost == b.cost && e.id < b.id),
                };
                if better {
                    self.best = Some(BestPoint { id: e.id, unit: self.points[i].clone(), cost });
                }
            }
        }
        if self.received == self.points.len() && !self.points.is_empty() {
            let costs: Vec<f64> = self.costs.iter().map(|c| c.unwrap_or(f64::INFINITY)).collect();
            let stop = algo.learn(&self.points, &costs);
            self.generation += 1;
            if let Some(stop) = stop {
                self.stop = Some(match (&self.best, stop) {
                    (None, StopReason::Converged { message }) => {
                        StopReason::Exhausted { message: format!("all {} evaluations failed ({message})", self.told) }
                    }
                    (_, stop) => stop,
                });
            } else {
                self.begin(algo);
            }
        }
        Ok(())
    }

    pub(crate) fn best(&self) -> Option<Best> {
        self.best.as_ref().map(|b| Best { id: b.id, unit: b.unit.clone(), cost: b.cost })
    }

    pub(crate) fn told(&self) -> usize {
        self.told
    }

    pub(crate) fn finished(&self) -> Option<StopReason> {
        // The stop reason is only set once a generation is complete, so nothing is outstanding.
        self.stop.clone()
    }
}

/// Implements [`crate::api::Optimizer`] for a struct with fields `core` (a [`Generational`]) and
/// `book` (a [`Book`]).
macro_rules! delegate_optimizer {
    ($ty:ty) => {
        impl $crate::api::Optimizer for $ty {
            fn ask(&mut self, n: usize) -> Vec<$crate::api::Candidate> {
                self.book.ask(n)
            }
            fn tell(&mut self, results: &[$crate::api::Evaluation]) -> Result<(), $crate::api::TellError> {
                self.book.tell(results, &mut self.core)
            }
            fn best(&self) -> Option<$crate::api::Best> {
                self.book.best()
            }
            fn told(&self) -> usize {
                self.book.told()
            }
            fn finished(&self) -> Option<$crate::api::StopReason> {
                self.book.finished()
            }
        }
    };
}
pub(crate) use delegate_optimizer;

/// Checks the dimension, budget and start point shared by every constructor; returns the start
/// (the centre of the box when none is given).
pub(crate) fn check_common(dim: usize, start: Option<&[f64]>, budget: usize) -> Result<Vec<f64>, OptimError> {
    if dim == 0 {
        return Err(OptimError::NoDimensions);
    }
    if budget == 0 {
        return Err(OptimError::ZeroBudget);
    }
    match start {
        None => Ok(vec![0.5; dim]),
        Some(s) => {
            if s.len() != dim {
                return Err(OptimError::StartLength { expected: dim, got: s.len() });
            }
            if let Some((index, &value)) = s.iter().enumerate().find(|(_, v)| !(0.0..=1.0).contains(*v)) {
                return Err(OptimError::StartOutside { index, value });
            }
            Ok(s.to_vec())
        }
    }
}

/// Fails with [`OptimError::BadOption`] unless `ok`.
pub(crate) fn require(ok: bool, option: &'static str, value: f64, requirement: &'static str) -> Result<(), OptimError> {
    if ok { Ok(()) } else { Err(OptimError::BadOption { option, value, requirement }) }
}

/// Checks an optional positive tolerance.
pub(crate) fn check_tolerance(option: &'static str, tol: Option<f64>) -> Result<(), OptimError> {
    match tol {
        Some(t) => require(t.is_finite() && t > 0.0, option, t, "a finite number > 0"),
        None => Ok(()),
    }
}

/// Mirrors `x` back into `[0, 1]` as often as needed (a non-finite value goes to the centre).
pub(crate) fn reflect(x: f64) -> f64 {
    if !x.is_finite() {
        return 0.5;
    }
    let m = x.rem_euclid(2.0);
    if m > 1.0 { 2.0 - m } else { m }
}

/// Index of the smallest cost, ties to the lowest index; `None` when every cost is `+∞`.
pub(crate) fn argmin(costs: &[f64]) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (i, &c) in costs.iter().enumerate() {
        if c.is_finite() && best.is_none_or(|b| c < costs[b]) {
            best = Some(i);
        }
    }
    best
}

/// Indices sorted by cost, ties (and `+∞`) in index order.
pub(crate) fn ranking(costs: &[f64]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..costs.len()).collect();
    idx.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)));
    idx
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect_folds_into_the_box() {
        assert_eq!(reflect(0.25), 0.25);
        assert!((reflect(1.25) - 0.75).abs() < 1e-15);
        assert!((reflect(-0.25) - 0.25).abs() < 1e-15);
        assert!((reflect(2.25) - 0.25).abs() < 1e-15);
        assert_eq!(reflect(f64::NAN), 0.5);
    }

    #[test]
    fn argmin_and_ranking_break_ties_by_index() {
        let c = [3.0, 1.0, f64::INFINITY, 1.0];
        assert_eq!(argmin(&c), Some(1));
        assert_eq!(ranking(&c), vec![1, 3, 0, 2]);
        assert_eq!(argmin(&[f64::INFINITY; 3]), None);
    }
}
