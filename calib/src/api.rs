//! The ask/tell contract every algorithm implements.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// Sequential id of a candidate within one algorithm instance (0, 1, 2, … in generation order).
pub type CandidateId = u64;

/// A point to evaluate, in unit coordinates (every component in `[0, 1]`).
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Candidate {
    pub id: CandidateId,
    pub unit: Vec<f64>,
}

/// The result of evaluating one candidate.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(tag = "status", rename_all = "lowercase"))]
pub enum Outcome {
    /// A finite cost `S ≥ 0`.
    Ok { cost: f64 },
    /// The simulation failed (diverged, timed out, …); the reason is kept for reports.
    Failed { reason: String },
}

impl Outcome {
    /// The cost, or `+∞` for a failed evaluation: the ordering every optimiser uses.
    pub fn rank_cost(&self) -> f64 {
        match self {
            Outcome::Ok { cost } if cost.is_finite() => *cost,
            _ => f64::INFINITY,
        }
    }

    pub fn is_ok(&self) -> bool {
        matches!(self, Outcome::Ok { cost } if cost.is_finite())
    }
}

/// A told result.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Evaluation {
    pub id: CandidateId,
    pub outcome: Outcome,
}

/// The best point seen so far.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Best {
    pub id: CandidateId,
    pub unit: Vec<f64>,
    pub cost: f64,
}

/// Why an algorithm stopped.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(tag = "kind", rename_all = "snake_case"))]
pub enum StopReason {
    /// Every evaluation of the budget was told.
    Budget,
    /// A stop tolerance was met; the message says which and at what value.
    Converged { message: String },
    /// The algorithm cannot go on (for example every evaluation failed); the message says why.
    Exhausted { message: String },
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Budget => write!(f, "budget used"),
            StopReason::Converged { message } => write!(f, "converged: {message}"),
            StopReason::Exhausted { message } => write!(f, "stopped: {message}"),
        }
    }
}

/// A result that does not fit the algorithm's state.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TellError {
    #[error("candidate {id} was never handed out")]
    Unknown { id: CandidateId },
    #[error("candidate {id} was already told")]
    Duplicate { id: CandidateId },
    #[error("candidate {id}: cost {cost} is not a finite number ≥ 0; report the evaluation as failed instead")]
    BadCost { id: CandidateId, cost: f64 },
}

/// The ask/tell interface.
///
/// `ask(n)` returns at most `n` new candidates, possibly fewer (none while a generation-synchronous
/// algorithm waits for the rest of its generation, none once the budget is handed out). `tell` takes
/// results of handed-out candidates in any order and any grouping; each id exactly once.
pub trait Optimizer {
    fn ask(&mut self, n: usize) -> Vec<Candidate>;
    fn tell(&mut self, results: &[Evaluation]) -> Result<(), TellError>;
    /// Best successful evaluation so far.
    fn best(&self) -> Option<Best>;
    /// Number of results told so far.
    fn told(&self) -> usize;
    /// `Some` once the algorithm will hand out nothing more and every handed-out candidate is told.
    fn finished(&self) -> Option<StopReason>;
}

/// Runs an optimiser to the end on an in-process function, `batch` candidates at a time — the
/// reference driver used by tests and by callers that evaluate in-process.
///
/// Panics if the optimiser rejects a result of its own, which would be a bug in the optimiser.
pub fn minimize<O: Optimizer + ?Sized>(opt: &mut O, batch: usize, mut f: impl FnMut(&[f64]) -> Outcome) {
    let batch = batch.max(1);
    while opt.finished().is_none() {
        let asked = opt.ask(batch);
        if asked.is_empty() {
            // Nothing outstanding (this driver tells everything it asks), so an empty ask with
            // no finish would loop forever: that is an optimiser bug.
            panic!("optimiser handed out nothing but did not finish");
        }
        let results: Vec<Evaluation> = asked.iter().map(|c| Evaluation { id: c.id, outcome: f(&c.unit) }).collect();
        opt.tell(&results).expect("optimiser rejected its own candidates");
    }
}
