//! Global and local optimisers (ask/tell): direct search, pattern search, annealing, genetic, swarm, CMA-ES.
//!
//! The paper's inference procedure (section "Inference of the model parameters") first runs a
//! simplified direct search — one-parameter-at-a-time grid scans in random orders — to locate the
//! global minimum roughly, then refines it with a global optimiser; the paper used MATLAB's pattern
//! search, genetic algorithm, simulated annealing and particle swarm. This module has all of them,
//! plus CMA-ES (the default global optimiser), as ask/tell [`Optimizer`]s.
//!
//! # Shared behaviour
//! - Every algorithm is **generation-synchronous**: a generation is drawn from the seeded RNG when it
//!   starts, handed out in any batch sizes (`ask` returns nothing while results are outstanding),
//!   and learnt from only once every result is in, in id order. Results are therefore bit-identical
//!   for any number of workers and any order in which results arrive.
//! - The **budget** is exact: never more evaluations are handed out; the last generation is cut
//!   short when the budget ends inside it.
//! - Failed evaluations rank as `+∞`. A result batch with an unknown id, a repeated id or an `Ok`
//!   cost that is not a finite number ≥ 0 is rejected whole.
//! - Every constructor has the shape `Algo::new(dim, start, options, budget, seed)`, where `start` is
//!   an optional point in unit coordinates (where the previous stage ended) and bad options are
//!   reported as [`OptimError`].
//! - With the `serde` feature the whole state, RNG included, serialises; floats of the state are
//!   written as exact decimal strings so that a resumed run is bit-identical (see `exact.rs`).

use thiserror::Error;

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::api::{Best, Candidate, Evaluation, Optimizer, StopReason, TellError};

mod annealing;
mod cmaes;
mod direct_search;
mod engine;
#[cfg(feature = "serde")]
use crate::exact;
mod genetic;
mod pattern;
mod swarm;

pub use annealing::{Annealing, AnnealingOptions};
pub use cmaes::{Cmaes, CmaesOptions};
pub use direct_search::{DirectSearch, DirectSearchOptions};
pub use genetic::{Crossover, Genetic, GeneticOptions, Mutation};
pub use pattern::{Pattern, PatternOptions, PollBasis};
pub use swarm::{Boundary, Swarm, SwarmOptions};

/// Why an optimiser could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum OptimError {
    /// The space has no free parameters.
    #[error("the search space has no dimensions; an optimiser needs at least one free parameter")]
    NoDimensions,
    /// A budget of zero evaluations.
    #[error("the budget is 0 evaluations; give at least 1")]
    ZeroBudget,
    /// The start point has the wrong number of coordinates.
    #[error("the start point has {got} coordinates but the space has {expected}")]
    StartLength {
        /// Dimension of the space.
        expected: usize,
        /// Length of the given start point.
        got: usize,
    },
    /// A start coordinate is not a number in `[0, 1]`.
    #[error("start point coordinate {index} is {value}; unit coordinates must lie in [0, 1]")]
    StartOutside {
        /// Index of the coordinate.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// An option is out of its range.
    #[error("option `{option}` = {value} is invalid: it must be {requirement}")]
    BadOption {
        /// Name of the option field.
        option: &'static str,
        /// The value given (counts converted to `f64`).
        value: f64,
        /// What the value must be.
        requirement: &'static str,
    },
}

/// Options of one global algorithm: which algorithm, and how it is set up.
///
/// With the `serde` feature this is a tagged table, e.g. `{"algorithm": "cmaes", "sigma": 0.2}`;
/// omitted fields take their defaults.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(tag = "algorithm", rename_all = "snake_case"))]
pub enum GlobalOptions {
    /// The paper's simplified direct search.
    DirectSearch(DirectSearchOptions),
    /// Compass (generalised pattern) search.
    Pattern(PatternOptions),
    /// Batch-parallel simulated annealing.
    Annealing(AnnealingOptions),
    /// Real-coded genetic algorithm.
    Genetic(GeneticOptions),
    /// Particle swarm.
    Swarm(SwarmOptions),
    /// CMA-ES (the default).
    Cmaes(CmaesOptions),
}

impl Default for GlobalOptions {
    fn default() -> Self {
        GlobalOptions::Cmaes(CmaesOptions::default())
    }
}

/// Any of the global optimisers, behind one type: implements [`Optimizer`] by delegation.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum GlobalAlgorithm {
    /// See [`DirectSearch`].
    DirectSearch(DirectSearch),
    /// See [`Pattern`].
    Pattern(Pattern),
    /// See [`Annealing`].
    Annealing(Annealing),
    /// See [`Genetic`].
    Genetic(Genetic),
    /// See [`Swarm`].
    Swarm(Swarm),
    /// See [`Cmaes`].
    Cmaes(Cmaes),
}

impl GlobalAlgorithm {
    /// Builds the algorithm `options` names, with the uniform constructor arguments.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: GlobalOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        Ok(match options {
            GlobalOptions::DirectSearch(o) => Self::DirectSearch(DirectSearch::new(dim, start, o, budget, seed)?),
            GlobalOptions::Pattern(o) => Self::Pattern(Pattern::new(dim, start, o, budget, seed)?),
            GlobalOptions::Annealing(o) => Self::Annealing(Annealing::new(dim, start, o, budget, seed)?),
            GlobalOptions::Genetic(o) => Self::Genetic(Genetic::new(dim, start, o, budget, seed)?),
            GlobalOptions::Swarm(o) => Self::Swarm(Swarm::new(dim, start, o, budget, seed)?),
            GlobalOptions::Cmaes(o) => Self::Cmaes(Cmaes::new(dim, start, o, budget, seed)?),
        })
    }

    fn inner(&self) -> &dyn Optimizer {
        match self {
            Self::DirectSearch(a) => a,
            Self::Pattern(a) => a,
            Self::Annealing(a) => a,
            Self::Genetic(a) => a,
            Self::Swarm(a) => a,
            Self::Cmaes(a) => a,
        }
    }

    fn inner_mut(&mut self) -> &mut dyn Optimizer {
        match self {
            Self::DirectSearch(a) => a,
            Self::Pattern(a) => a,
            Self::Annealing(a) => a,
            Self::Genetic(a) => a,
            Self::Swarm(a) => a,
            Self::Cmaes(a) => a,
        }
    }

    /// Short lower-case name of the algorithm, for reports.
    pub fn name(&self) -> &'static str {
        match self {
            Self::DirectSearch(_) => "direct_search",
            Self::Pattern(_) => "pattern",
            Self::Annealing(_) => "annealing",
            Self::Genetic(_) => "genetic",
            Self::Swarm(_) => "swarm",
            Self::Cmaes(_) => "cmaes",
        }
    }

    /// Completed generations of the wrapped algorithm.
    pub fn generation(&self) -> usize {
        match self {
            Self::DirectSearch(a) => a.generation(),
            Self::Pattern(a) => a.generation(),
            Self::Annealing(a) => a.generation(),
            Self::Genetic(a) => a.generation(),
            Self::Swarm(a) => a.generation(),
            Self::Cmaes(a) => a.generation(),
        }
    }
}

impl Optimizer for GlobalAlgorithm {
    fn ask(&mut self, n: usize) -> Vec<Candidate> {
        self.inner_mut().ask(n)
    }
    fn tell(&mut self, results: &[Evaluation]) -> Result<(), TellError> {
        self.inner_mut().tell(results)
    }
    fn best(&self) -> Option<Best> {
        self.inner().best()
    }
    fn told(&self) -> usize {
        self.inner().told()
    }
    fn finished(&self) -> Option<StopReason> {
        self.inner().finished()
    }
}

macro_rules! from_algorithm {
    ($($ty:ident),*) => {$(
        impl From<$ty> for GlobalAlgorithm {
            fn from(a: $ty) -> Self {
                GlobalAlgorithm::$ty(a)
            }
        }
    )*};
}
from_algorithm!(DirectSearch, Pattern, Annealing, Genetic, Swarm, Cmaes);
