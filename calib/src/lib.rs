//! Inference engine of cryofit: parameter spaces, the cost, and ask/tell algorithms.
//!
//! Everything here is pure computation: no files, no network, no threads of its own. Callers (the
//! local `cryofit calibrate`, the coordinator) own evaluation, persistence and scheduling; an
//! algorithm only proposes points ([`Optimizer::ask`]) and learns from costs ([`Optimizer::tell`]).
//!
//! # Conventions shared by every algorithm
//! - Algorithms work in **unit coordinates**: each free parameter mapped to `[0, 1]` by
//!   [`Space`] (linearly or logarithmically). Points handed out are always inside the unit box.
//! - The **cost** is the weighted sum of squares `S = Σ η ((y_model − y_data)/σ)²`. With σ the
//!   measurement noise and η = 1, `S/2` is the negative log-likelihood (up to a constant); the
//!   variance and posterior algorithms rely on that.
//! - A **failed** evaluation ([`Outcome::Failed`]) is infeasible: optimisers rank it worse than any
//!   finite cost; it is never turned into a silent large number.
//! - **Determinism**: every algorithm is seeded. Candidates get sequential ids in the order they are
//!   generated. Generation-synchronous algorithms generate a whole generation at once, hand it out
//!   in any batch sizes, and only update once every result of the generation is in, processing
//!   results by id, so the outcome is bit-identical whatever the number of workers or the order in
//!   which results arrive.
//! - **Budget**: an algorithm never hands out more than its budget of evaluations; it finishes when
//!   the budget is used, or earlier when a stop tolerance is met (and then says why).

pub mod api;
pub mod apparatus;
pub mod config;
pub mod cost;
pub mod data;
pub mod draws;
#[cfg(feature = "serde")]
mod exact;
pub mod heat;
pub mod inference;
pub mod model;
pub mod optim;
pub mod pipeline;
pub mod problem;
pub mod space;
pub mod testfns;

pub use api::{Best, Candidate, CandidateId, Evaluation, Optimizer, Outcome, StopReason, TellError, minimize};
pub use space::{FreeParameter, Scale, Space, SpaceError};
