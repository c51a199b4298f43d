//! The paper's simplified direct search: one-coordinate grid scans in random orders.
//!
//! From the paper's section "Direct search": the cost is searched on a regular grid, scanning one
//! parameter at a time, and the search is repeated with randomly changing orders of the scanning
//! directions. Here each scan evaluates `points` values of one coordinate on a regular grid around
//! the current best point (the other coordinates held), moves there if a value is better, and every
//! complete sweep over the coordinates shrinks the grid's span. The grid is shifted by a random
//! fraction of its spacing at each scan, so that it cannot alias with periodic structure of the
//! cost. One scan is one generation.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use super::engine::{
    Book, Generational, MAX_GENERATION, RESOLUTION_FLOOR, argmin, check_common, check_tolerance, delegate_optimizer,
    require,
};
use crate::api::StopReason;

/// Options of [`DirectSearch`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default, deny_unknown_fields))]
pub struct DirectSearchOptions {
    /// Grid points per coordinate scan (2 to 1 000 000): one value in each of `points` equal cells of the span,
    /// all at the same random offset within their cell (drawn per scan, so that the grid does not
    /// alias with periodic structure of the cost). A value within a quarter cell of the current
    /// coordinate is skipped, as its cost is known.
    pub points: usize,
    /// Span of the first sweep's grid, as a fraction of the unit interval (in `(0, 1]`).
    pub initial_span: f64,
    /// Factor applied to the span after every sweep over all coordinates (in `(0, 1)`).
    pub shrink: f64,
    /// Stop when the span falls below this (unit coordinates). Without it the search stops at a span
    /// of 1e-12, where grid values can no longer be told apart.
    pub tolerance: Option<f64>,
}

impl Default for DirectSearchOptions {
    fn default() -> Self {
        Self { points: 20, initial_span: 1.0, shrink: 0.5, tolerance: None }
    }
}

impl DirectSearchOptions {
    fn check(&self) -> Result<(), OptimError> {
        require(
            (2..=MAX_GENERATION).contains(&self.points),
            "points",
            self.points as f64,
            "at least 2 and at most 1 000 000",
        )?;
        require(self.initial_span > 0.0 && self.initial_span <= 1.0, "initial_span", self.initial_span, "in (0, 1]")?;
        require(self.shrink > 0.0 && self.shrink < 1.0, "shrink", self.shrink, "in (0, 1)")?;
        check_tolerance("tolerance", self.tolerance)
    }
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Core {
    rng: ChaCha8Rng,
    points: usize,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    shrink: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolerance: Option<f64>,
    /// Current best point and its cost (`+∞` until known).
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    x: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    fx: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    span: f64,
    /// Scanning order of the current sweep and the position in it.
    order: Vec<usize>,
    pos: usize,
    sweep: usize,
    start_done: bool,
}

impl Generational for Core {
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>> {
        let k = self.order[self.pos];
        let span = self.span.min(1.0);
        let lo = (self.x[k] - 0.5 * span).clamp(0.0, 1.0 - span);
        let cell = span / self.points as f64;
        let mut out = Vec::with_capacity(self.points.min(max) + 1);
        if !self.start_done {
            // The first scan also evaluates the start, so that a good start is not lost.
            self.start_done = true;
            out.push(self.x.clone());
        }
        // A random phase shifts the whole grid within one cell, so that the grid does not alias with
        // periodic structure of the cost or always miss the same values.
        let phase: f64 = self.rng.r#gen();
        for j in 0..self.points {
            if out.len() >= max {
                break;
            }
            let v = lo + (j as f64 + phase) * cell;
            if self.fx.is_finite() && (v - self.x[k]).abs() < 0.25 * cell {
                continue;
            }
            let mut p = self.x.clone();
            p[k] = v;
            out.push(p);
        }
        out.truncate(max);
        out
    }

    fn learn(&mut self, points: &[Vec<f64>], costs: &[f64]) -> Option<StopReason> {
        if let Some(b) = argmin(costs)
            && costs[b] < self.fx
        {
            self.x.clone_from(&points[b]);
            self.fx = costs[b];
        }
        self.pos += 1;
        if self.pos < self.order.len() {
            return None;
        }
        self.pos = 0;
        self.sweep += 1;
        self.span *= self.shrink;
        self.order.shuffle(&mut self.rng);
        if let Some(tol) = self.tolerance
            && self.span < tol
        {
            return Some(StopReason::Converged {
                message: format!("grid span {:.3e} < tolerance {tol:.3e} after {} sweeps", self.span, self.sweep),
            });
        }
        if self.span < RESOLUTION_FLOOR {
            return Some(StopReason::Converged {
                message: format!(
                    "grid span {:.3e} below the resolution floor {RESOLUTION_FLOOR:e} after {} sweeps",
                    self.span, self.sweep
                ),
            });
        }
        None
    }
}

/// The paper's simplified direct search (section "Direct search"): coordinate-wise grid scans around
/// the current best point, in a fresh random coordinate order each sweep, with the grid's span
/// shrinking geometrically from sweep to sweep.
///
/// One generation is one coordinate's scan (`points` candidates, plus the start point in the first
/// scan). Meant for the rough first stage of a calibration; the seed drives the scanning orders
/// and the grid offsets. Coordinate scans solve separable costs one coordinate at a time but crawl
/// along curved valleys (Rosenbrock), where the shrinking span stops them early.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct DirectSearch {
    core: Core,
    book: Book,
}

impl DirectSearch {
    /// A direct search in `dim` unit coordinates from `start` (the centre of the box if `None`),
    /// with at most `budget` evaluations.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: DirectSearchOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        let x = check_common(dim, start, budget)?;
        options.check()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut order: Vec<usize> = (0..dim).collect();
        order.shuffle(&mut rng);
        let mut core = Core {
            rng,
            points: options.points,
            shrink: options.shrink,
            tolerance: options.tolerance,
            x,
            fx: f64::INFINITY,
            span: options.initial_span,
            order,
            pos: 0,
            sweep: 0,
            start_done: false,
        };
        let book = Book::start(dim, budget, &mut core);
        Ok(Self { core, book })
    }

    /// Completed generations (coordinate scans).
    pub fn generation(&self) -> usize {
        self.book.generation()
    }

    /// Completed sweeps over all coordinates.
    pub fn sweep(&self) -> usize {
        self.core.sweep
    }

    /// The current grid span in unit coordinates.
    pub fn span(&self) -> f64 {
        self.core.span
    }

    /// The point the scans are centred on (the best found by completed scans).
    pub fn current(&self) -> &[f64] {
        &self.core.x
    }
}

delegate_optimizer!(DirectSearch);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::Optimizer;

    #[test]
    fn first_scan_is_the_start_and_a_shifted_grid_over_the_span() {
        let options = DirectSearchOptions { points: 4, initial_span: 0.4, ..Default::default() };
        let mut o = DirectSearch::new(2, Some(&[0.9, 0.5]), options, 100, 1).unwrap();
        let c = o.ask(100);
        assert_eq!(c.len(), 5);
        assert_eq!(c[0].unit, vec![0.9, 0.5]);
        let k = o.core.order[0];
        let values: Vec<f64> = c[1..].iter().map(|c| c.unit[k]).collect();
        // The window of width 0.4 around the coordinate, pushed inside the box; one value per cell.
        let lo = if k == 0 { 0.6 } else { 0.3 };
        for (j, v) in values.iter().enumerate() {
            let cell = lo + 0.1 * j as f64;
            assert!(*v >= cell - 1e-12 && *v <= cell + 0.1 + 1e-12, "{values:?}");
        }
        // Same offset in every cell.
        assert!(values.windows(2).all(|w| (w[1] - w[0] - 0.1).abs() < 1e-12));
    }
}
