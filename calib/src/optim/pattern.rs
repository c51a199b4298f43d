//! Compass search, the simplest generalised pattern search.
//!
//! After Kolda, Lewis and Torczon, "Optimization by direct search: new perspectives on some classical
//! and modern methods" (SIAM Review, 2003), and the generalised pattern search with the `2n`
//! coordinate basis that MATLAB's `patternsearch` (used in the paper) polls by default: poll
//! `x ± step·e_i` for every coordinate, move to the best poll point if it improves on `x` and
//! expand the step, otherwise contract it. A rotating basis (random Householder reflections, after
//! OrthoMADS) is available for non-separable costs.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use super::engine::{
    Book, Generational, RESOLUTION_FLOOR, argmin, check_common, check_tolerance, delegate_optimizer, require,
};
use crate::api::StopReason;

/// Directions [`Pattern`] polls along.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum PollBasis {
    /// `±e_i`: the coordinate axes (compass search, MATLAB's "GPS positive basis 2N").
    #[default]
    Coordinate,
    /// `±h_i`: the columns of a random Householder reflection `H = I − 2vvᵀ` (`v` a uniform random
    /// unit vector), drawn anew each generation, as in OrthoMADS (Abramson, Audet, Dennis and Le
    /// Digabel, SIAM J. Optim., 2009). Polls off the axes, so it follows curved valleys better.
    Rotating,
}

/// Options of [`Pattern`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default, deny_unknown_fields))]
pub struct PatternOptions {
    /// First poll step in unit coordinates (in `(0, 1]`).
    pub initial_step: f64,
    /// Poll directions.
    pub basis: PollBasis,
    /// Step factor after a successful poll (≥ 1; MATLAB's default 2).
    pub expansion: f64,
    /// Step factor after an unsuccessful poll (in `(0, 1)`; MATLAB's default 0.5).
    pub contraction: f64,
    /// Stop when the step falls below this (unit coordinates). Without it the search stops at a
    /// step of 1e-12.
    pub tolerance: Option<f64>,
}

impl Default for PatternOptions {
    fn default() -> Self {
        Self { initial_step: 0.25, basis: PollBasis::Coordinate, expansion: 2.0, contraction: 0.5, tolerance: None }
    }
}

impl PatternOptions {
    fn check(&self) -> Result<(), OptimError> {
        require(self.initial_step > 0.0 && self.initial_step <= 1.0, "initial_step", self.initial_step, "in (0, 1]")?;
        require(self.expansion >= 1.0 && self.expansion.is_finite(), "expansion", self.expansion, "finite and ≥ 1")?;
        require(self.contraction > 0.0 && self.contraction < 1.0, "contraction", self.contraction, "in (0, 1)")?;
        check_tolerance("tolerance", self.tolerance)
    }
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Core {
    rng: ChaCha8Rng,
    basis: PollBasis,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    x: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    fx: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    step: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    expansion: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    contraction: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolerance: Option<f64>,
    /// Whether the current generation starts with the current point itself (the first one).
    with_centre: bool,
    successes: usize,
}

impl Generational for Core {
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>> {
        let mut out = Vec::with_capacity(2 * self.x.len() + 1);
        if self.with_centre {
            out.push(self.x.clone());
        }
        let n = self.x.len();
        // Unit vector of the Householder reflection (rotating basis only).
        let v: Vec<f64> = match self.basis {
            PollBasis::Coordinate => Vec::new(),
            PollBasis::Rotating => loop {
                let g: Vec<f64> = (0..n).map(|_| self.rng.sample(StandardNormal)).collect();
                let norm = g.iter().map(|a| a * a).sum::<f64>().sqrt();
                if norm > 1e-12 {
                    break g.into_iter().map(|a| a / norm).collect();
                }
            },
        };
        for i in 0..n {
            for sign in [1.0, -1.0] {
                let p: Vec<f64> = match self.basis {
                    PollBasis::Coordinate => {
                        let mut p = self.x.clone();
                        p[i] = (self.x[i] + sign * self.step).clamp(0.0, 1.0);
                        p
                    }
                    PollBasis::Rotating => (0..n)
                        .map(|k| {
                            let h = if k == i { 1.0 } else { 0.0 } - 2.0 * v[k] * v[i];
                            (self.x[k] + sign * self.step * h).clamp(0.0, 1.0)
                        })
                        .collect(),
                };
                // A poll point pushed back onto x by the box is not a new point.
                if p != self.x {
                    out.push(p);
                }
            }
        }
        out.truncate(max);
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
        let polls = &costs[first.min(costs.len())..];
        match argmin(polls) {
            Some(b) if polls[b] < self.fx => {
                self.x.clone_from(&points[first + b]);
                self.fx = polls[b];
                self.step = (self.step * self.expansion).min(1.0);
                self.successes += 1;
                None
            }
            _ => {
                self.step *= self.contraction;
                if let Some(tol) = self.tolerance
                    && self.step < tol
                {
                    return Some(StopReason::Converged {
                        message: format!("poll step {:.3e} < tolerance {tol:.3e}", self.step),
                    });
                }
                if self.step < RESOLUTION_FLOOR {
                    return Some(StopReason::Converged {
                        message: format!("poll step {:.3e} below the resolution floor {RESOLUTION_FLOOR:e}", self.step),
                    });
                }
                None
            }
        }
    }
}

/// Compass search (generalised pattern search on the `±e_i` basis with complete polling), after
/// Kolda, Lewis and Torczon (SIAM Review, 2003) and MATLAB's `patternsearch` defaults.
///
/// One generation is one complete poll: the `2·dim` points `x ± step·e_i` (points the box would push
/// back onto `x` are skipped; the first generation also evaluates `x`). The best poll point is taken
/// if it improves on `x` and the step grows by `expansion`; otherwise the step shrinks by
/// `contraction`. With [`PollBasis::Coordinate`] the method is deterministic and the seed unused;
/// [`PollBasis::Rotating`] draws its directions from the seeded RNG.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Pattern {
    core: Core,
    book: Book,
}

impl Pattern {
    /// A compass search in `dim` unit coordinates from `start` (the centre of the box if `None`),
    /// with at most `budget` evaluations. `seed` drives the rotating basis only.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: PatternOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        let x = check_common(dim, start, budget)?;
        options.check()?;
        let mut core = Core {
            rng: ChaCha8Rng::seed_from_u64(seed),
            basis: options.basis,
            x,
            fx: f64::INFINITY,
            step: options.initial_step,
            expansion: options.expansion,
            contraction: options.contraction,
            tolerance: options.tolerance,
            with_centre: true,
            successes: 0,
        };
        let book = Book::start(dim, budget, &mut core);
        Ok(Self { core, book })
    }

    /// Completed generations (polls).
    pub fn generation(&self) -> usize {
        self.book.generation()
    }

    /// The current poll step in unit coordinates.
    pub fn step(&self) -> f64 {
        self.core.step
    }

    /// The current poll centre (the best point found by completed polls).
    pub fn current(&self) -> &[f64] {
        &self.core.x
    }

    /// Polls that improved on the centre so far.
    pub fn successes(&self) -> usize {
        self.core.successes
    }
}

delegate_optimizer!(Pattern);
