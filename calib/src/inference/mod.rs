//! Sensitivity analysis, local refinement, variance and posterior estimation, model comparison.
//!
//! The stages follow the inference procedure of the paper (section "Inference of the model
//! parameters"): a sensitivity study picks the parameters worth freeing ([`Sensitivity`], the
//! paper's one-at-a-time test, and [`Morris`] elementary effects as a global screen); after the
//! global optimisers (in [`crate::optim`]) a local simplex search refines the optimum
//! ([`NelderMead`]); the variance stage restarts the simplex near the optimum and fits the
//! Gaussian of the paper's dispersion equation through a finite-difference Hessian, reporting where
//! simulations diverge nearby ([`Variance`]); an ensemble sampler gives the full posterior
//! ([`EnsembleSampler`]); and [`compare`] ranks alternative correlation sets by AIC, BIC and Laplace
//! evidence (the model-comparison use of Bayes' rule in section "Probabilistic framework").
//!
//! Every algorithm here implements [`crate::Optimizer`] and follows the crate's conventions: unit
//! coordinates, seeded, budgeted, generation-synchronous (results processed in id order once a
//! generation is complete, so the outcome does not depend on batch sizes or arrival order), failed
//! evaluations treated as infeasible. Constructors share one shape,
//! `X::new(space or dim, start, options, budget, seed)`, and reject bad option values with an
//! [`InferenceError`] naming the option. Each has a `summary()` returning a serialisable summary.
//!
//! With the crate feature `serde`, the algorithms (RNG included) serialise and resume bit-identically.
//! Floats in *state* are written as decimal strings (see the private `exact` module: JSON has no
//! infinity and common JSON float parsers are not correctly rounded); summaries use plain numbers.
//!
//! The likelihood convention throughout: with the cost `S` a weighted sum of squares normalised by
//! the noise, `S/2` is the negative log-likelihood up to a constant, and the prior is uniform on the
//! unit box — uniform in the physical value for a linear parameter and log-uniform for a
//! logarithmic one.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::api::{Best, Candidate, Evaluation, Optimizer, StopReason, TellError};

mod common;
pub mod compare;
#[cfg(feature = "serde")]
use crate::exact;
pub mod mcmc;
pub mod nelder_mead;
pub mod sensitivity;
pub mod surface;
pub mod variance;

pub use compare::{ComparisonError, ComparisonRow, ModelComparison, ModelFit, aic, bic, laplace_log_evidence};
pub use mcmc::{EnsembleSampler, McmcOptions, McmcSummary, ParameterPosterior, PosteriorDraws, Quantiles};
pub use nelder_mead::{NelderMead, NelderMeadOptions, NelderMeadSummary, StepCounts};
pub use sensitivity::{
    Difference, ElementaryEffects, FreeSelection, Morris, MorrisOptions, MorrisSummary, ParameterSensitivity,
    PerturbationFailure, RankedParameter, Ranking, Sensitivity, SensitivityOptions, SensitivitySummary, Side,
};
pub use surface::{ResponseSurface, SurfaceEstimate};
pub use variance::{
    DivergentPoint, GaussianApproximation, Interval, Profile, ProfilePoint, RestartSummary, Variance, VarianceOptions,
    VarianceStage, VarianceSummary,
};

/// Why an inference algorithm could not be built. Every variant names the algorithm and the value
/// at fault, so the message says what to change.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum InferenceError {
    /// An option is out of its allowed range.
    #[error("{algorithm}: option `{option}` = {value} is invalid; it must be {expected}")]
    InvalidOption {
        /// The algorithm.
        algorithm: &'static str,
        /// The option's field name.
        option: &'static str,
        /// The value given (counts as `f64`).
        value: f64,
        /// The allowed range, in words.
        expected: &'static str,
    },
    /// The start point has the wrong number of coordinates.
    #[error("{algorithm}: the start point has {got} coordinates but there are {expected} free parameters")]
    StartDimension {
        /// The algorithm.
        algorithm: &'static str,
        /// Number of free parameters.
        expected: usize,
        /// Coordinates given.
        got: usize,
    },
    /// A start coordinate is not in `[0, 1]` (or is not a number).
    #[error("{algorithm}: start coordinate {index} = {value} is not in [0, 1]; pass unit coordinates")]
    StartOutside {
        /// The algorithm.
        algorithm: &'static str,
        /// The coordinate.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// The budget cannot hold what the algorithm needs.
    #[error("{algorithm}: budget {budget} is too small; at least {required} evaluations are needed ({needed_for})")]
    BudgetTooSmall {
        /// The algorithm.
        algorithm: &'static str,
        /// The budget given.
        budget: usize,
        /// The smallest budget that works.
        required: usize,
        /// What the required evaluations are for.
        needed_for: &'static str,
    },
    /// There is nothing to infer.
    #[error("{algorithm}: there are no free parameters")]
    NoParameters {
        /// The algorithm.
        algorithm: &'static str,
    },
}

/// Any of this module's algorithms behind one type, so a calibration pipeline (and its persisted
/// state) can hold whichever stage is running; every [`Optimizer`] call is delegated.
///
/// Serialised externally tagged (`{"mcmc": {…}}`): an internally tagged enum would buffer its
/// content through serde's generic value type, which cannot hold the RNG's 128-bit word position.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum InferenceAlgorithm {
    /// One-at-a-time relative sensitivity (paper, "Sensitivity analysis").
    Sensitivity(Sensitivity),
    /// Morris elementary-effects screening.
    Morris(Morris),
    /// Nelder–Mead simplex refinement.
    NelderMead(NelderMead),
    /// Simplex restarts, Hessian and divergence scan (paper, "Variance of the model parameters").
    Variance(Box<Variance>),
    /// Affine-invariant ensemble sampler of the posterior.
    Mcmc(Box<EnsembleSampler>),
}

/// The summary of whichever algorithm an [`InferenceAlgorithm`] holds.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum InferenceSummary {
    /// See [`SensitivitySummary`].
    Sensitivity(SensitivitySummary),
    /// See [`MorrisSummary`].
    Morris(MorrisSummary),
    /// See [`NelderMeadSummary`].
    NelderMead(NelderMeadSummary),
    /// See [`VarianceSummary`].
    Variance(Box<VarianceSummary>),
    /// See [`McmcSummary`].
    Mcmc(Box<McmcSummary>),
}

impl InferenceAlgorithm {
    fn inner(&self) -> &dyn Optimizer {
        match self {
            Self::Sensitivity(a) => a,
            Self::Morris(a) => a,
            Self::NelderMead(a) => a,
            Self::Variance(a) => a.as_ref(),
            Self::Mcmc(a) => a.as_ref(),
        }
    }

    fn inner_mut(&mut self) -> &mut dyn Optimizer {
        match self {
            Self::Sensitivity(a) => a,
            Self::Morris(a) => a,
            Self::NelderMead(a) => a,
            Self::Variance(a) => a.as_mut(),
            Self::Mcmc(a) => a.as_mut(),
        }
    }

    /// The held algorithm's summary.
    pub fn summary(&self) -> InferenceSummary {
        match self {
            Self::Sensitivity(a) => InferenceSummary::Sensitivity(a.summary()),
            Self::Morris(a) => InferenceSummary::Morris(a.summary()),
            Self::NelderMead(a) => InferenceSummary::NelderMead(a.summary()),
            Self::Variance(a) => InferenceSummary::Variance(Box::new(a.summary())),
            Self::Mcmc(a) => InferenceSummary::Mcmc(Box::new(a.summary())),
        }
    }
}

impl Optimizer for InferenceAlgorithm {
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

macro_rules! delegate_to_core {
    ($t:ty) => {
        impl crate::api::Optimizer for $t {
            fn ask(&mut self, n: usize) -> Vec<crate::api::Candidate> {
                self.core.ask(n)
            }

            fn tell(&mut self, results: &[crate::api::Evaluation]) -> Result<(), crate::api::TellError> {
                if let Some(done) = self.core.tell(results)? {
                    self.absorb(done);
                }
                Ok(())
            }

            fn best(&self) -> Option<crate::api::Best> {
                self.core.best()
            }

            fn told(&self) -> usize {
                self.core.told()
            }

            fn finished(&self) -> Option<crate::api::StopReason> {
                self.core.finished()
            }
        }
    };
}
pub(crate) use delegate_to_core;
