//! Time-step control: the step a run tries next, and what an accepted or a rejected step does
//! to the steps after it (the paper's control: reject and halve a step that changes a variable
//! too much, end the run below a minimum step; each accepted step sizes the next for the change
//! it made).

use std::collections::BTreeMap;

use super::SimError;
use crate::case::TimeSection;
use crate::model::{Grid, State};
use crate::scheme::{Rejection, StepReport};

/// Settings of the [`StepController`]. A step's difficulty is its change ratio
/// ([`StepReport::change_ratio`]): the largest change of a controlled variable as a fraction of
/// the change allowed in one step. The default is the control every run uses.
///
/// Decision: each accepted step sets the next from its own change ratio, in proportion
/// (`target_ratio` / ratio, within `max_shrink` and `max_growth`), as the change of a variable
/// over a short step is nearly in proportion to its length. The control before grew the step by
/// 1.25 after three steps in a row with a ratio below 0.5 and cut it to 0.8 of a step above 0.8,
/// so the steps climbed and fell in a saw-tooth through a band of ratios, most of them well below
/// the limit. Measured on the operating envelope (`cryofit bench envelope --jobs 2 --json [--params
/// examples/nbs/calibrated.toml]`, with the junction presence of
/// `Scheme::junction_presence_fractions` that came with it): step attempts 172 059 → 149 118 and
/// 294 119 → 239 224, the mean station-4 error against steps of at most 1 ms 0.46 → 0.51 % and
/// 0.85 → 1.16 % (methane subcooled at 3 atm, a run with two branches, −4.3 %); the six NBS
/// runs 4 094 / 2 923 / 2 439 / 7 031 / 19 670 / 11 943 → 3 704 / 2 774 / 2 105 / 5 122 / 13 419
/// / 8 544 attempts. Targets of 0.5 and 0.65 took more steps or moved station 4 further
/// (BENCHMARKS.md, "The step set in proportion to its change ratio").
#[derive(Debug, Clone, PartialEq)]
pub struct StepControl {
    /// Factor on the size of a rejected step before it is tried again (0.5: halved).
    pub rejection_factor: f64,
    /// The change ratio the next step is sized for.
    pub target_ratio: f64,
    /// The largest factor by which the step grows from one accepted step to the next (up to
    /// the case's `time.max_dt_s`).
    pub max_growth: f64,
    /// The smallest factor by which an accepted step's successor is cut from it.
    pub max_shrink: f64,
}

impl Default for StepControl {
    fn default() -> Self {
        Self { rejection_factor: 0.5, target_ratio: 0.6, max_growth: 1.25, max_shrink: 0.5 }
    }
}

/// The step control of one run: proposes each step from its own step size, the case's largest
/// step, the Courant limit and the next time the run must land on; adjusts its step size by the
/// outcome; counts the accepted and rejected steps and what limited or rejected them.
///
/// Its step size `dt` is what the steps are allowed to be; a step actually taken may be shorter
/// (cut to land on an output time or by the Courant limit), which says nothing about its
/// difficulty: growing and shrinking act on `dt`, rejections on the step taken.
#[derive(Debug, Clone)]
pub struct StepController {
    control: StepControl,
    /// The case's largest step, s.
    max_dt: f64,
    /// The case's smallest step, s: a rejected step below it ends the run.
    min_dt: f64,
    /// The case's largest material Courant number.
    max_courant: f64,
    /// The controller's step size, s.
    dt: f64,
    statistics: StepStatistics,
}

/// What held an accepted step at the case's largest step (`time.max_dt_s`).
pub const LARGEST_STEP: &str = "largest step";

/// What held an accepted step at the material Courant limit (`time.max_courant`).
pub const COURANT_LIMIT: &str = "Courant number";

/// What held an accepted step that ended at the end of the interval it was to reach.
pub const END_OF_INTERVAL: &str = "end of interval";

/// What the steps of a run were: their numbers, sizes and what held them down.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct StepStatistics {
    /// Accepted steps.
    pub(super) steps: u64,
    /// Rejected (retried) steps.
    pub(super) rejected: u64,
    /// Smallest accepted step, s (infinite before the first).
    pub(super) min_dt: f64,
    /// Largest accepted step, s.
    pub(super) max_dt: f64,
    /// Why steps were rejected ("variable: reason") and how often.
    pub(super) rejection_causes: BTreeMap<String, u64>,
    /// What held the accepted steps (a cap, else the controlled variable that came closest to its
    /// limit; [`StepController::proposal`]), and how often.
    pub(super) step_limited_by: BTreeMap<String, u64>,
    /// Simulated time of the accepted steps in which the line's exit was choked, s.
    pub(super) exit_choked_s: f64,
    /// Cells recovered as one near-critical mixture, summed over the accepted steps.
    pub(super) mixture_recoveries: u64,
    /// Cells recovered again at the pressure at which their phases fill them, summed over the
    /// accepted steps.
    pub(super) pressure_refills: u64,
}

impl StepController {
    /// A controller with the settings `control` for a case's `[time]` section; its first step is
    /// the case's `initial_dt_s` (at most `max_dt_s`).
    pub fn new(control: StepControl, time: &TimeSection) -> Self {
        Self {
            control,
            max_dt: time.max_dt_s,
            min_dt: time.min_dt_s,
            max_courant: time.max_courant,
            dt: time.initial_dt_s.min(time.max_dt_s),
            statistics: StepStatistics {
                steps: 0,
                rejected: 0,
                min_dt: f64::INFINITY,
                max_dt: 0.0,
                rejection_causes: BTreeMap::new(),
                step_limited_by: BTreeMap::new(),
                exit_choked_s: 0.0,
                mixture_recoveries: 0,
                pressure_refills: 0,
            },
        }
    }

    /// Accepted steps so far.
    pub fn steps(&self) -> u64 {
        self.statistics.steps
    }

    /// The step to try from `s` on `grid`: the controller's step size within the case's largest
    /// step and the Courant limit (for accuracy), ending at most at `target` (landing exactly on
    /// it); at least the case's smallest step where `target` is already reached. With it, what
    /// set it where that was a cap, not the controller's own step size: the case's largest step
    /// ([`LARGEST_STEP`]), the Courant limit ([`COURANT_LIMIT`], with its junction) or the end of
    /// the interval ([`END_OF_INTERVAL`]).
    ///
    /// Decision: an accepted step is counted as held by what capped it (the summary's
    /// `step_limited_by`, the step log), not by the controlled variable nearest its limit: after
    /// the saturated NBS runs' chilldown every step sat at the case's largest step of 0.5 s and
    /// was counted as held by the volume error (1 301 of 1 360 on the 2.5 atm run), which made
    /// the volume error look as if it held three quarters of the run's steps.
    pub fn proposal(&self, s: &State, grid: &Grid, target: f64) -> (f64, Option<(&'static str, usize)>) {
        let mut courant = (f64::INFINITY, 0);
        for j in 0..=grid.n {
            for v in [s.v_g[j], s.v_l[j]] {
                if v != 0.0 {
                    let limit = self.max_courant * donor_length(grid, j, v) / v.abs();
                    if limit < courant.0 {
                        courant = (limit, j);
                    }
                }
            }
        }
        let own = self.dt.min(self.max_dt);
        let limited = own.min(courant.0);
        let h = limited.min(target - s.time);
        if h <= 0.0 {
            return ((target - s.time).max(self.min_dt), Some((END_OF_INTERVAL, 0)));
        }
        let cap = if h == target - s.time && h < limited {
            Some((END_OF_INTERVAL, 0))
        } else if h == courant.0 && courant.0 < own {
            Some((COURANT_LIMIT, courant.1))
        } else if h == self.max_dt {
            Some((LARGEST_STEP, 0))
        } else {
            None
        };
        (h, cap)
    }

    /// Books an accepted step of size `h` with its `report` and sizes the next: `h` times
    /// `target_ratio` over the step's change ratio, within `max_shrink` and `max_growth`. A
    /// step that would grow never makes the step size smaller (a step cut short by a cap says
    /// nothing about how long a step may be); one that would shrink sets it from `h`.
    pub fn accept(&mut self, h: f64, report: &StepReport) {
        let c = &self.control;
        let stats = &mut self.statistics;
        stats.steps += 1;
        stats.min_dt = stats.min_dt.min(h);
        stats.max_dt = stats.max_dt.max(h);
        if !report.limiting.is_empty() {
            *stats.step_limited_by.entry(report.limiting.to_string()).or_default() += 1;
        }
        if report.exit_choked {
            stats.exit_choked_s += h;
        }
        stats.mixture_recoveries += u64::from(report.mixture_cells);
        stats.pressure_refills += u64::from(report.refilled_cells);
        let factor = (c.target_ratio / report.change_ratio.max(f64::MIN_POSITIVE)).clamp(c.max_shrink, c.max_growth);
        self.dt = if factor >= 1.0 { self.dt.max(h * factor) } else { h * factor }.min(self.max_dt);
    }

    /// Books a step of size `h` from time `time_s` that the scheme rejected, and returns the
    /// smaller step to try instead (which also becomes the step size), or
    /// [`SimError::StepTooSmall`] when that is below the case's smallest step.
    pub fn reject(&mut self, h: f64, rejection: Rejection, time_s: f64) -> Result<f64, SimError> {
        let Rejection { cell, variable, value, reason } = rejection;
        self.statistics.rejected += 1;
        *self.statistics.rejection_causes.entry(format!("{variable}: {reason}")).or_default() += 1;
        let h = h * self.control.rejection_factor;
        self.dt = h;
        if h < self.min_dt {
            return Err(SimError::StepTooSmall { time_s, min_dt_s: self.min_dt, cell, variable, value, reason });
        }
        Ok(h)
    }

    /// The statistics of the steps taken.
    pub(super) fn into_statistics(self) -> StepStatistics {
        self.statistics
    }
}

/// The length of the cell whose contents a velocity `v` at junction `j` carries across it: the
/// upwind cell, or at a boundary junction whose upwind side is outside the line, the end cell the
/// flow enters.
///
/// Decision: the material Courant number measures the fraction of a cell's contents that crosses
/// one of its faces in a step, |v| Δt / Δx of the cell the donor-cell fluxes empty (or, at an
/// inflow boundary, fill), as RELAP5 takes it on its volumes. Before, it was measured on the
/// junction's momentum control volume, half a cell at the two boundary junctions: the exit's
/// vapour, the fastest flow of the line, then held the steps at half of what the limit allows in
/// the exit cell itself (after the chilldown of the saturated NBS runs nearly every step, at
/// 0.5 s with the exit's 20 m/s; BENCHMARKS.md "The Courant number on the donor cell").
fn donor_length(grid: &Grid, j: usize, v: f64) -> f64 {
    let (left, right) = (j.checked_sub(1), (j < grid.n).then_some(j));
    let (upwind, downwind) = if v > 0.0 { (left, right) } else { (right, left) };
    // an upwind side outside the line: the end cell the flow enters
    upwind.or(downwind).map_or(0.0, |i| grid.dx[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn time() -> TimeSection {
        TimeSection {
            end_s: 10.0,
            output_interval_s: 1.0,
            profile_interval_s: 5.0,
            initial_dt_s: 0.01,
            max_dt_s: 0.1,
            min_dt_s: 1e-4,
            max_courant: 1.0,
            max_steps: None,
            max_wall_s: None,
        }
    }

    fn report(change_ratio: f64) -> StepReport {
        StepReport { change_ratio, limiting: "pressure", ..StepReport::default() }
    }

    #[test]
    fn sizes_the_next_step_for_the_target_ratio() {
        let mut c = StepController::new(StepControl::default(), &time());
        // a step at the target keeps its size; half the target grows it, by at most 1.25
        c.accept(0.01, &report(0.6));
        assert_eq!(c.dt, 0.01);
        c.accept(0.01, &report(0.4));
        assert!((c.dt - 0.0125).abs() < 1e-15, "{}", c.dt);
        // up to the case's largest step
        for _ in 0..20 {
            c.accept(c.dt, &report(0.0));
        }
        assert_eq!(c.dt, 0.1);
        // a hard step sets the next from its own size, cut by at most half
        c.accept(0.004, &report(0.8));
        assert!((c.dt - 0.003).abs() < 1e-15, "{}", c.dt);
        c.accept(0.004, &report(3.0));
        assert_eq!(c.dt, 0.002);
        // an easy step cut short by a cap does not make the step size smaller
        c.dt = 0.05;
        c.accept(0.001, &report(0.3));
        assert_eq!(c.dt, 0.05);
        assert_eq!(c.steps(), 25);
        let stats = c.into_statistics();
        assert_eq!((stats.min_dt, stats.max_dt), (0.001, 0.1));
        assert_eq!(stats.step_limited_by["pressure"], 25);
    }

    /// A line of four equal cells, its cell length and time settings with the largest step
    /// `max_dt` and a Courant limit of 2.
    fn four_cells(max_dt: f64) -> (Grid, f64, TimeSection) {
        let grid = Grid::from_case(&crate::reference::Reference::GasCooldown.with_cells(4));
        let dx = grid.dx[0];
        let mut t = time();
        (t.max_dt_s, t.max_courant) = (max_dt, 2.0);
        (grid, dx, t)
    }

    #[test]
    fn the_courant_limit_is_measured_on_the_cell_the_flow_empties_or_fills() {
        let (grid, dx, t) = four_cells(1e3);
        let c = StepController { dt: 1e3, ..StepController::new(StepControl::default(), &t) };
        let propose = |s: &State, target: f64| c.proposal(s, &grid, target).0;
        let state = |j: usize, v_g: f64, v_l: f64| {
            let mut s = State { v_g: vec![0.0; grid.n + 1], v_l: vec![0.0; grid.n + 1], ..State::default() };
            (s.v_g[j], s.v_l[j]) = (v_g, v_l);
            s
        };
        // the exit's outflow empties the last cell, a whole cell, not the half of the junction's
        // momentum volume
        assert_eq!(propose(&state(grid.n, 10.0, 0.0), 1e9), 2.0 * dx / 10.0);
        // an inflow fills the first cell; a backflow at the exit fills the last one
        assert_eq!(propose(&state(0, 0.0, 5.0), 1e9), 2.0 * dx / 5.0);
        assert_eq!(propose(&state(grid.n, -4.0, 1.0), 1e9), 2.0 * dx / 4.0);
        // inside the line the faster phase sets it
        assert_eq!(propose(&state(2, 3.0, -8.0), 1e9), 2.0 * dx / 8.0);
        // at rest only the controller's step and the target
        assert_eq!(propose(&state(2, 0.0, 0.0), 7.0), 7.0);
    }

    #[test]
    fn a_capped_step_names_its_cap() {
        let (grid, dx, t) = four_cells(0.5);
        let mut s = State { v_g: vec![0.0; grid.n + 1], v_l: vec![0.0; grid.n + 1], ..State::default() };
        // the controller's own step, below every cap: no cap
        let c = StepController { dt: 0.1, ..StepController::new(StepControl::default(), &t) };
        assert_eq!(c.proposal(&s, &grid, 1e9), (0.1, None));
        // grown to the case's largest step
        let c = StepController { dt: 0.5, ..StepController::new(StepControl::default(), &t) };
        assert_eq!(c.proposal(&s, &grid, 1e9), (0.5, Some((LARGEST_STEP, 0))));
        // the Courant limit below it, at the junction of the fastest flow
        s.v_g[2] = 8.0 * dx;
        assert_eq!(c.proposal(&s, &grid, 1e9), (2.0 * dx / s.v_g[2], Some((COURANT_LIMIT, 2))));
        // the end of the interval below both
        s.v_g[2] = 0.0;
        assert_eq!(c.proposal(&s, &grid, 0.2), (0.2, Some((END_OF_INTERVAL, 0))));
    }

    #[test]
    fn halves_a_rejected_step_until_the_minimum() {
        let mut c = StepController::new(StepControl::default(), &time());
        let why = Rejection { cell: 3, variable: "pressure", value: 1.0, reason: "changed by more than 25 %" };
        assert_eq!(c.reject(0.01, why.clone(), 2.0), Ok(0.005));
        assert_eq!(c.dt, 0.005);
        let err = c.reject(1.5e-4, why, 2.0).unwrap_err();
        assert!(matches!(err, SimError::StepTooSmall { cell: 3, time_s: 2.0, .. }), "{err}");
        assert_eq!(c.into_statistics().rejection_causes["pressure: changed by more than 25 %"], 2);
    }
}
