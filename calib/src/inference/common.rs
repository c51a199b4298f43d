//! Bookkeeping shared by every inference algorithm: candidate ids, the budget, the generation in
//! flight, result validation and the best point. The algorithms only decide *which* points form the
//! next generation and what to learn from a completed one.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::InferenceError;
use crate::api::{Best, Candidate, CandidateId, Evaluation, Outcome, StopReason, TellError};

/// A stored result: a cost, or the failure reason.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub(crate) enum Told {
    Cost(#[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))] f64),
    Failed(String),
}

impl Told {
    /// The cost, `+∞` when failed (the ranking every optimiser uses).
    pub(crate) fn rank(&self) -> f64 {
        match self {
            Told::Cost(c) => *c,
            Told::Failed(_) => f64::INFINITY,
        }
    }

    pub(crate) fn cost(&self) -> Option<f64> {
        match self {
            Told::Cost(c) => Some(*c),
            Told::Failed(_) => None,
        }
    }

    pub(crate) fn reason(&self) -> Option<&str> {
        match self {
            Told::Cost(_) => None,
            Told::Failed(r) => Some(r),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct BestPoint {
    id: CandidateId,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    unit: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    cost: f64,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Generation {
    first_id: CandidateId,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    points: Vec<Vec<f64>>,
    handed: usize,
    results: Vec<Option<Told>>,
    pending: usize,
}

/// A generation whose every result is in, in id order.
#[derive(Clone, Debug)]
pub(crate) struct Completed {
    pub(crate) first_id: CandidateId,
    pub(crate) points: Vec<Vec<f64>>,
    pub(crate) results: Vec<Told>,
}

/// Ids, budget, the generation in flight and the best point.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub(crate) struct Core {
    budget: usize,
    next_id: CandidateId,
    told: usize,
    best: Option<BestPoint>,
    generation: Option<Generation>,
    stop: Option<StopReason>,
}

impl Core {
    pub(crate) fn new(budget: usize) -> Self {
        Self { budget, next_id: 0, told: 0, best: None, generation: None, stop: None }
    }

    pub(crate) fn budget(&self) -> usize {
        self.budget
    }

    /// Candidates generated so far (every one of them is, or will be, handed out).
    pub(crate) fn used(&self) -> usize {
        self.next_id as usize
    }

    /// Evaluations the budget still allows.
    pub(crate) fn remaining(&self) -> usize {
        self.budget.saturating_sub(self.used())
    }

    /// Opens a generation. The caller guarantees `0 < points.len() ≤ remaining()`, no generation in
    /// flight and every point inside the unit box; points beyond the budget are dropped as a guard.
    pub(crate) fn start(&mut self, mut points: Vec<Vec<f64>>) {
        debug_assert!(self.generation.is_none() && self.stop.is_none());
        debug_assert!(!points.is_empty() && points.len() <= self.remaining());
        debug_assert!(points.iter().all(|p| p.iter().all(|v| (0.0..=1.0).contains(v))));
        points.truncate(self.remaining());
        if points.is_empty() {
            self.stop = Some(StopReason::Budget);
            return;
        }
        let n = points.len();
        self.generation =
            Some(Generation { first_id: self.next_id, points, handed: 0, results: vec![None; n], pending: n });
        self.next_id += n as CandidateId;
    }

    /// Declares the algorithm finished (nothing is in flight when this is called).
    pub(crate) fn finish(&mut self, reason: StopReason) {
        debug_assert!(self.generation.is_none());
        self.stop = Some(reason);
    }

    pub(crate) fn ask(&mut self, n: usize) -> Vec<Candidate> {
        let Some(g) = self.generation.as_mut() else { return Vec::new() };
        let take = n.min(g.points.len() - g.handed);
        let out = (g.handed..g.handed + take)
            .map(|k| Candidate { id: g.first_id + k as CandidateId, unit: g.points[k].clone() })
            .collect();
        g.handed += take;
        out
    }

    /// Validates every result first (nothing is stored if one is bad), stores them, and returns the
    /// generation once it is complete; the best point is updated then, in id order.
    pub(crate) fn tell(&mut self, results: &[Evaluation]) -> Result<Option<Completed>, TellError> {
        let mut slots = Vec::with_capacity(results.len());
        let mut seen = vec![false; self.generation.as_ref().map_or(0, |g| g.handed)];
        for e in results {
            let slot = match self.generation.as_ref() {
                Some(g) if e.id >= g.first_id && e.id < g.first_id + g.handed as CandidateId => {
                    let k = (e.id - g.first_id) as usize;
                    if g.results[k].is_some() || seen[k] {
                        return Err(TellError::Duplicate { id: e.id });
                    }
                    seen[k] = true;
                    k
                }
                Some(g) if e.id < g.first_id => return Err(TellError::Duplicate { id: e.id }),
                None if e.id < self.next_id => return Err(TellError::Duplicate { id: e.id }),
                _ => return Err(TellError::Unknown { id: e.id }),
            };
            if let Outcome::Ok { cost } = e.outcome
                && !(cost.is_finite() && cost >= 0.0)
            {
                return Err(TellError::BadCost { id: e.id, cost });
            }
            slots.push(slot);
        }
        let Some(g) = self.generation.as_mut() else { return Ok(None) };
        for (e, &k) in results.iter().zip(&slots) {
            g.results[k] = Some(match &e.outcome {
                Outcome::Ok { cost } => Told::Cost(*cost),
                Outcome::Failed { reason } => Told::Failed(reason.clone()),
            });
        }
        g.pending -= slots.len();
        self.told += slots.len();
        if g.pending > 0 {
            return Ok(None);
        }
        let g = self.generation.take().expect("generation present");
        let results: Vec<Told> = g.results.into_iter().map(|r| r.expect("complete generation")).collect();
        for (k, (p, r)) in g.points.iter().zip(&results).enumerate() {
            if let Told::Cost(c) = r
                && self.best.as_ref().is_none_or(|b| *c < b.cost)
            {
                self.best = Some(BestPoint { id: g.first_id + k as CandidateId, unit: p.clone(), cost: *c });
            }
        }
        Ok(Some(Completed { first_id: g.first_id, points: g.points, results }))
    }

    pub(crate) fn best(&self) -> Option<Best> {
        self.best.as_ref().map(|b| Best { id: b.id, unit: b.unit.clone(), cost: b.cost })
    }

    pub(crate) fn best_point(&self) -> Option<(&[f64], f64)> {
        self.best.as_ref().map(|b| (b.unit.as_slice(), b.cost))
    }

    pub(crate) fn told(&self) -> usize {
        self.told
    }

    pub(crate) fn finished(&self) -> Option<StopReason> {
        if self.generation.is_some() { None } else { self.stop.clone() }
    }
}

/// Checks an option value; `ok` is the condition it must meet.
pub(crate) fn check(
    algorithm: &'static str,
    option: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), InferenceError> {
    if ok { Ok(()) } else { Err(InferenceError::InvalidOption { algorithm, option, value, expected }) }
}

/// The start point in unit coordinates: the given one (checked) or the centre of the box.
pub(crate) fn resolve_start(
    algorithm: &'static str,
    dim: usize,
    start: Option<&[f64]>,
) -> Result<Vec<f64>, InferenceError> {
    if dim == 0 {
        return Err(InferenceError::NoParameters { algorithm });
    }
    match start {
        None => Ok(vec![0.5; dim]),
        Some(s) if s.len() != dim => Err(InferenceError::StartDimension { algorithm, expected: dim, got: s.len() }),
        Some(s) => {
            if let Some((index, &value)) = s.iter().enumerate().find(|(_, v)| !(0.0..=1.0).contains(*v)) {
                return Err(InferenceError::StartOutside { algorithm, index, value });
            }
            Ok(s.to_vec())
        }
    }
}

/// Clamps every coordinate into `[0, 1]`.
pub(crate) fn clamp_unit(mut x: Vec<f64>) -> Vec<f64> {
    for v in &mut x {
        *v = v.clamp(0.0, 1.0);
    }
    x
}

/// Euclidean distance.
pub(crate) fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}
