//! The acceptance checks of a step: every value finite, no controlled variable changed by more
//! than its limit, no volume error grown above its limit.

use super::{
    CONTROLLED_FRACTION, MAX_RELATIVE_CHANGE, MAX_VELOCITY_CHANGE, MAX_VOLUME_ERROR, Rejection, SCALE_PRESSURE_PA,
    SCALE_TEMPERATURE_K, SCALE_VELOCITY_M_S, SCALE_VOID, Scheme, StepInput, VELOCITY_ERROR_FRACTION,
    VOLUME_ERROR_PRESSURE_FRACTION, Work,
};
use crate::model::State;

impl Scheme<'_> {
    /// Step control: the largest change of a controlled variable over the step as a fraction
    /// of its allowed change (`MAX_RELATIVE_CHANGE` of the larger of its old value and its
    /// scale), and the variable; a step with a fraction above 1 is rejected, naming it.
    ///
    /// A cell where a whole phase went over to the other at its table's edge (`w.merged`: a
    /// near-critical "liquid" that the falling pressure makes vapour, merged into the gas) is
    /// exempt for its void fraction and temperatures: the merge mixes the two phases at once,
    /// whatever the step, so no shorter step makes its change smaller (para-hydrogen subcooled
    /// at 11 atm ended at 2.9 s with its steps halved below 1e-9 s on a gas temperature that fell
    /// 42 K in any step).
    ///
    /// A cell's change of pressure, void fraction or a phase's temperature that a step half as
    /// long does not at least halve is not the step's either ([`RetryRecord`], as the volume
    /// error's in [`volume_error_check`]): a retry from the same time whose change of such a
    /// variable in a cell is above half of the rejected step's there (`w.cell_retry`) is not
    /// rejected for it, and the cell enters the step control at its limit, so that the next
    /// step is shorter. Decision: such a change is the recovery of a state far from its
    /// equilibrium or a jump of the state's recovery, which any step length makes. With one
    /// parameter set of the robustness study (`tests/data/robustness-seed1-sample944.toml`)
    /// vapour collapse pulled the subcooled nitrogen line's inlet cell, nearly full of liquid
    /// (void fraction 2.9e-4), down to 30.9 kPa, its liquid at 79.2 K 13 K above saturation: the
    /// linearised flashing (7.5e4 kg/m³/s, falling by 1.49 per Pa) ends near 81 kPa within
    /// nanoseconds. A 29 µs step landed at 81.4 kPa, four halvings stayed within 0.3 % of it, the
    /// 25 % rule rejected every step length and the run ended at 66.9 s. On the subcooled
    /// para-hydrogen line at 11 atm on 25 cells (inlet at 19.619650779 K, defaults) a cell's
    /// near-critical gas fell to 34.3 K in any step that crossed 15.857062 s, and the steps were
    /// halved towards that instant until below 1e-9 s.
    ///
    /// A phase velocity is controlled by its step's local error where the step before is known
    /// (`w.trend`, [`VelocityTrend::error`]), within `VELOCITY_ERROR_FRACTION` of the 25 %
    /// rule's allowance and a change of at most `MAX_VELOCITY_CHANGE` of max(|v|,
    /// `SCALE_VELOCITY_M_S`); by the 25 % rule on a run's first step. Decision: the 25 % rule
    /// measures how far a velocity moves, not how well the step follows it. A velocity that
    /// swings steadily (the chugging at the inlet of the hydrogen runs: the gas there goes from
    /// 0 to −37 m/s and back within 25 ms, smooth over steps of 0.1 ms) was held to 2.5 m/s a
    /// step, and that held most of the operating envelope's steps (gas velocity: 24 633 of the
    /// 33 069 steps of para-hydrogen subcooled at 1.5 atm with `calibrated.toml`). The change
    /// of a velocity over a first-order step departs from the last step's trend (its change
    /// scaled to this step's length) by twice the step's local error to leading order, so the
    /// step is held where its velocities turn, not where they only move; a flicker from step to
    /// step is a departure of twice its size and is held as before. Measured on the operating
    /// envelope (BENCHMARKS.md, "A velocity's step held by its local error"): step attempts
    /// 149 118 → 122 886 with the defaults and 239 224 → 193 559 with `calibrated.toml`, the
    /// mean station-4 error against steps of at most 1 ms 0.51 → 0.55 % and 1.16 → 1.14 %; the
    /// slowest run (para-hydrogen subcooled at 1.5 atm) 35 422 → 21 856 attempts.
    pub(super) fn change_control(&self, st: &StepInput, w: &mut Work, next: &State) -> Result<ChangeRatio, Rejection> {
        let s = st.s;
        let mut change = ChangeRatio { ratio: 0.0, worst: Rejection { cell: 0, variable: "", value: 0.0, reason: "" } };
        for i in 0..st.n {
            for (k, c) in cell_changes(s, w, next, i).into_iter().enumerate() {
                if let Some(c) = c {
                    let held = w.cell_retry[k].not_halved(s.time, i, c.new - c.old);
                    change.check_held(i, CELL_VARIABLES[k], c.old, c.new, c.scale, held);
                }
            }
            change.check(i, "wall temperature", s.t_w[i], next.t_w[i], SCALE_TEMPERATURE_K);
        }
        // a phase's velocity is controlled only where it fills at least CONTROLLED_FRACTION of
        // the junction (as its temperature in a cell, `cell_changes`)
        let xmax = CONTROLLED_FRACTION;
        let trend = w.trend.before(s.time, st.dt, st.n + 1);
        for j in 0..st.n + 1 {
            if j == st.n && st.choke > 0.0 {
                // a choked exit's velocities follow the exit cell's state through the choking
                // condition (`choking.rs`); that state's changes are controlled above
                continue;
            }
            let (fg, fl) = self.junction_min_fractions(s, j);
            let (ag, al) = self.junction_alpha(s, j, st.inlet0, st.outlet0);
            let (fg, fl) = (fg.min(ag), fl.min(al));
            if fg > xmax {
                let last = trend.map(|r| (r, w.trend.dv_g[j]));
                change.check_velocity(j, "gas velocity", s.v_g[j], next.v_g[j], last);
            }
            if fl > xmax {
                let last = trend.map(|r| (r, w.trend.dv_l[j]));
                change.check_velocity(j, "liquid velocity", s.v_l[j], next.v_l[j], last);
            }
        }
        if change.ratio > 1.0 {
            let changes: Vec<_> = (0..st.n).map(|i| cell_changes(s, w, next, i)).collect();
            for (k, record) in w.cell_retry.iter_mut().enumerate() {
                record.record(s.time, |i| {
                    changes[i][k].filter(|c| relative_change(c.old, c.new, c.scale) > 1.0).map(|c| c.new - c.old)
                });
            }
            return Err(change.worst);
        }
        Ok(change)
    }
}

/// The velocity changes of the last step the scheme accepted, for the local error of the step
/// after it ([`Scheme::change_control`]).
#[derive(Debug, Clone, Default)]
pub(super) struct VelocityTrend {
    /// The time at which that step ended, s (a step from another time has no trend).
    end: f64,
    /// Its length, s (0 before any).
    dt: f64,
    /// Per junction: its change of the gas velocity, m/s.
    dv_g: Vec<f64>,
    /// Per junction: its change of the liquid velocity, m/s.
    dv_l: Vec<f64>,
}

impl VelocityTrend {
    /// Records the accepted step of `dt` from `s` to `next`.
    pub(super) fn record(&mut self, s: &State, next: &State, dt: f64) {
        (self.end, self.dt) = (next.time, dt);
        self.dv_g.clear();
        self.dv_g.extend(next.v_g.iter().zip(&s.v_g).map(|(a, b)| a - b));
        self.dv_l.clear();
        self.dv_l.extend(next.v_l.iter().zip(&s.v_l).map(|(a, b)| a - b));
    }

    /// For a step of `h` from `time` on a line of `junctions` junctions: the ratio of its length
    /// to the last step's, where that step ended at `time`.
    fn before(&self, time: f64, h: f64, junctions: usize) -> Option<f64> {
        (self.dt > 0.0 && self.end == time && self.dv_g.len() == junctions).then(|| h / self.dt)
    }

    /// The local error of a step whose velocity changed by `dv`, the step before (`r` times
    /// shorter) by `last`: half the departure of `dv` from the trend `r · last`, weighted for
    /// unequal steps, r / (1 + r) |dv − r · last| (h² v''/2 to leading order for steps h and
    /// h / r).
    fn error(r: f64, dv: f64, last: f64) -> f64 {
        r / (1.0 + r) * (dv - r * last).abs()
    }
}

/// The controlled variables of a cell's state whose changes a retry may hold
/// ([`Scheme::change_control`], `w.cell_retry`), in the order of [`cell_changes`].
pub(super) const CELL_VARIABLES: [&str; 4] = ["pressure", "void fraction", "gas temperature", "liquid temperature"];

/// A controlled variable's change over a step: old and new value and the scale below which its
/// allowed change does not shrink.
#[derive(Debug, Clone, Copy)]
struct CellChange {
    old: f64,
    new: f64,
    scale: f64,
}

/// Cell `i`'s changes of the variables of [`CELL_VARIABLES`] over the step to `next`, `None`
/// where a variable is not controlled: the void fraction and temperatures of a cell where a
/// whole phase went over to the other (`w.merged`, [`Scheme::change_control`]), and a phase's
/// temperature where it fills less than `CONTROLLED_FRACTION` of the cell at either end of the
/// step (a fixed fraction, not `blend_xmax`: the step sizes, and through them the results,
/// would otherwise move with a blending threshold).
fn cell_changes(s: &State, w: &Work, next: &State, i: usize) -> [Option<CellChange>; 4] {
    let xmax = CONTROLLED_FRACTION;
    let merged = w.merged[i];
    let change = |old: f64, new: f64, scale: f64| CellChange { old, new, scale };
    [
        Some(change(s.p[i], next.p[i], SCALE_PRESSURE_PA)),
        (!merged).then(|| change(s.alpha[i], void_without_edge_change(w, next, i), SCALE_VOID)),
        (!merged && s.alpha[i].min(next.alpha[i]) > xmax).then(|| change(s.t_g[i], next.t_g[i], SCALE_TEMPERATURE_K)),
        (!merged && (1.0 - s.alpha[i]).min(1.0 - next.alpha[i]) > xmax)
            .then(|| change(s.t_l[i], next.t_l[i], SCALE_TEMPERATURE_K)),
    ]
}

/// What a rejected step changed in each cell, kept for its retries (shorter steps from the same
/// time): a change that a step half as long does not at least halve is not the step's, and no
/// shorter step makes it smaller. Such a change in a retry is not rejected; its cell enters the
/// step control at its limit instead ([`volume_error_check`], [`Scheme::change_control`]).
#[derive(Debug, Clone)]
pub(super) struct RetryRecord {
    /// The start time of the rejected step (NaN before any).
    time: f64,
    /// Per cell: the magnitude of the rejected step's change where it was above its limit, 0
    /// elsewhere.
    change: Vec<f64>,
}

impl Default for RetryRecord {
    fn default() -> Self {
        Self { time: f64::NAN, change: Vec::new() }
    }
}

impl RetryRecord {
    /// Sizes the record for `n` cells.
    pub(super) fn resize(&mut self, n: usize) {
        self.change.resize(n, 0.0);
    }

    /// Whether a step from `time` retries the recorded one and cell `i`'s change was above its
    /// limit in it.
    pub(super) fn over_before(&self, time: f64, i: usize) -> bool {
        self.time == time && self.change[i] > 0.0
    }

    /// Whether `change`, cell `i`'s in a step from `time`, is a retry's that kept more than
    /// half of the rejected step's change there.
    pub(super) fn not_halved(&self, time: f64, i: usize, change: f64) -> bool {
        self.over_before(time, i) && change.abs() > 0.5 * self.change[i]
    }

    /// Records a step from `time`, rejected: `over(i)` is cell `i`'s change where it was above
    /// its limit (of either sign), `None` elsewhere.
    fn record(&mut self, time: f64, over: impl Fn(usize) -> Option<f64>) {
        self.time = time;
        for (i, c) in self.change.iter_mut().enumerate() {
            *c = over(i).map_or(0.0, f64::abs);
        }
    }
}

/// Cell `i`'s new void fraction without the volume its edge phase changes moved between the
/// phases (`w.edge`: the gas's change of volume, and the mass moved at the liquid's new
/// density); its new void fraction where there were none.
///
/// Decision: the void fraction's change control measures the step's change, not an edge phase
/// change's. The phase tables' edges near the critical point are steps in the pressure (the
/// para-hydrogen liquid table ends at 32.591 K up to 1 221 487 Pa and at 32.627 K from
/// 1 221 488 Pa), so liquid at 32.611 K whose pressure fell by a pascal flashed 3.7 % of its mass
/// at the edge: its void fraction rose from 0.173 to 0.224 at any step length, and the 25 %
/// rule rejected every step down to 1e-9 s (para-hydrogen subcooled at 11 atm, defaults, 5.3 s).
/// Such a change is a recovery of the state, not an effect of the step's length, as the volume
/// it leaves is not the step's volume error ([`volume_error_check`]).
///
/// Decision: the gas's part is the change of its volume that the flashed mass and energy made,
/// not the flashed mass at the gas's new density. The flash joins the gas at the saturated
/// vapour's energy and can cool it far: in para-hydrogen at 1.261 MPa (subcooled at 11 atm,
/// `calibrated-six-drops.toml`, 6.48 s) 2.25 kg/m³ of liquid flashed into gas at 45.8 K and cooled
/// it to 35.8 K; the void fraction rose from 0.293 to 0.362 at any step length, the flashed
/// mass at the new gas density put the step's own change at 0.293 → 0.207, and the 25 % rule
/// rejected every step down to 1e-9 s.
fn void_without_edge_change(w: &Work, next: &State, i: usize) -> f64 {
    let moved = w.edge[i].mass;
    if moved == 0.0 {
        return next.alpha[i];
    }
    let filled = 1.0 + next.volume_error[i];
    let gas = next.alpha[i] * filled - w.edge[i].gas_volume;
    let liquid = (1.0 - next.alpha[i]) * filled + moved / next.liquid[i].rho;
    let alpha = gas / (gas + liquid);
    if alpha.is_finite() { alpha.clamp(0.0, 1.0) } else { next.alpha[i] }
}

/// No NaN escapes a step: anything non-finite in the new state rejects it, naming where.
pub(super) fn all_finite(next: &State) -> Result<(), Rejection> {
    let finite = |v: &[f64]| v.iter().position(|x| !x.is_finite());
    for (name, values) in [
        ("gas velocity", &next.v_g),
        ("liquid velocity", &next.v_l),
        ("wall temperature", &next.t_w),
        ("gas energy", &next.e_g),
        ("liquid energy", &next.e_l),
        ("void fraction", &next.alpha),
    ] {
        if let Some(i) = finite(values) {
            return Err(Rejection { cell: i, variable: name, value: values[i], reason: "not a finite number" });
        }
    }
    Ok(())
}

/// Rejects a step that leaves a cell with a volume error above the limit and larger than it
/// had (an error inherited from earlier steps shrinks under the next pressure solves; a smaller
/// step cannot remove it), naming the cell with the largest such error; otherwise returns the
/// volume error's share of the step control: the largest ratio of a grown error to its cell's
/// limit, and where.
///
/// In a cell where a phase was reset or changed phase at its table's edge (`w.reset`) the
/// error checked is the one the step made: the new error less what the resets and edge changes
/// made (`w.reset_volume`: the volume a reset phase's new temperature gave it, the volume the
/// mass an edge change moved takes in the phase it joined) and less what the pressure solve
/// left of the old error (it corrects at most the part worth `VOLUME_ERROR_PRESSURE_FRACTION`
/// of the pressure per step). A cell where a whole phase went over to the other (`w.merged`)
/// is exempt: the merge is all of its error.
///
/// Decision: before, a cell with a reset or an edge change was exempt from the check
/// altogether, and any error the step made beside the reset went unchecked and was inherited.
/// In the exit cell of para-hydrogen saturated at 1.5 atm, where a trace of liquid flashes at
/// its table's top in nearly every step after the front arrives, the error grew to 0.128 of
/// the cell (its phases filling 113 % of it), and the flow work of the fluid leaving at the
/// recovered density then missed energy. (Measuring every cell by the error its step made, not
/// only those with a reset, changes the steps of runs without resets too; in the closed-tube
/// separation it left a pocket of 2.5 % gas trapped under a cell with a trace of gas, whose
/// presence weight ties the pocket's gas to the resting liquid: the measure stays for the cells
/// it was made for.)
///
/// An error that a step half as long does not at least halve is not the step's either (the
/// correction of a large inherited error near the critical point leaves a nonlinear remainder
/// of its own: para-hydrogen saturated at 11 atm, −0.025 at any step length down to 1e-9 s;
/// with `examples/nbs/calibrated-six.toml` the run ended there at 8.7 s while the rule covered only
/// the reset cells): a retry from the same time whose error in a cell is above half of the
/// rejected step's there (`w.volume_retry`) is not rejected for that cell, which enters the
/// step control at its limit instead, so that the next step is shorter.
///
/// In a cell full of liquid even a small volume error is a large pressure correction in the
/// next step (liquid is stiff): the limit is also the error worth
/// `VOLUME_ERROR_PRESSURE_FRACTION` of the pressure, |e| / κ with κ the cell's volume
/// compressibility.
///
/// The error a step makes grows with the step (the linearised equations of state are exact
/// only as it vanishes), so the controller treats it as it treats a controlled variable's
/// change ([`Scheme::change_control`]): a step that comes near the limit makes the next one
/// shorter instead of the run growing its steps into a rejection. (Without it, volume errors
/// were nearly all the rejected steps of the NBS runs — 1 389 of 1 395 on the saturated
/// 2.5 atm run — each a whole step wasted and the next halved.) The limit is an accuracy
/// control: the station-4 chilldown of nitrogen saturated at 11 atm is 84.2 s as the steps
/// vanish and 85.2 s at the default control (VALIDATION.md, "Time-step refinement").
pub(super) fn volume_error_check(st: &StepInput, w: &mut Work, next: &State) -> Result<ChangeRatio, Rejection> {
    let s = st.s;
    let err = |i: usize| {
        if w.reset[i] {
            next.volume_error[i] - w.reset_volume[i] - (1.0 - w.corrected[i]) * s.volume_error[i]
        } else {
            next.volume_error[i]
        }
    };
    let checked = |i: usize| !w.merged[i] && (w.reset[i] || next.volume_error[i].abs() > s.volume_error[i].abs());
    let ratio = |i: usize| {
        let (gp, lp, a) = (&next.gas[i], &next.liquid[i], next.alpha[i]);
        let kappa = a * gp.drho_dp / gp.rho + (1.0 - a) * lp.drho_dp / lp.rho;
        let limit = MAX_VOLUME_ERROR.min(VOLUME_ERROR_PRESSURE_FRACTION * next.p[i].max(SCALE_PRESSURE_PA) * kappa);
        err(i).abs() / limit
    };
    let mut control = ChangeRatio {
        ratio: 0.0,
        worst: Rejection {
            cell: 0,
            variable: "volume error",
            value: 0.0,
            reason: "phase volumes do not fill the cell",
        },
    };
    // the cell with the largest error among those above their limit
    let mut rejected: Option<usize> = None;
    for i in (0..st.n).filter(|&i| checked(i)) {
        let e = err(i);
        let mut r = ratio(i);
        if w.volume_retry.not_halved(s.time, i, e) {
            r = r.min(1.0);
        }
        if r > 1.0 && rejected.is_none_or(|k| e.abs() > err(k).abs()) {
            rejected = Some(i);
        }
        if r > control.ratio {
            control.ratio = r;
            control.worst.cell = i;
            control.worst.value = e;
        }
    }
    let Some(i) = rejected else { return Ok(control) };
    w.volume_retry.record(s.time, |k| (checked(k) && ratio(k) > 1.0).then(|| err(k)));
    Err(Rejection { cell: i, value: err(i), ..control.worst })
}

/// The largest change of a controlled variable over a step as a fraction of its allowed
/// change, and the variable ([`Scheme::change_control`]).
#[derive(Debug, Clone)]
pub(super) struct ChangeRatio {
    /// The largest fraction so far (infinite for a change that is not a number).
    pub(super) ratio: f64,
    /// Where it is, as the rejection it makes when above 1.
    pub(super) worst: Rejection,
}

impl ChangeRatio {
    /// Takes in the change of `variable` at `cell` from `old` to `new`, measured against
    /// `MAX_RELATIVE_CHANGE` of the larger of |old| and `scale`.
    fn check(&mut self, cell: usize, variable: &'static str, old: f64, new: f64, scale: f64) {
        self.check_held(cell, variable, old, new, scale, false);
    }

    /// Takes in a phase velocity's change at junction `j` from `old` to `new`: with `last` (the
    /// ratio of this step's length to the last one's and the last one's change) its local error
    /// against `VELOCITY_ERROR_FRACTION` of the 25 % allowance, and its change against
    /// `MAX_VELOCITY_CHANGE` of max(|old|, `SCALE_VELOCITY_M_S`), the larger of the two;
    /// without, the 25 % rule ([`ChangeRatio::check`]).
    fn check_velocity(&mut self, j: usize, variable: &'static str, old: f64, new: f64, last: Option<(f64, f64)>) {
        let Some((r, last)) = last else {
            return self.check(j, variable, old, new, SCALE_VELOCITY_M_S);
        };
        let scale = old.abs().max(SCALE_VELOCITY_M_S);
        let error = VelocityTrend::error(r, new - old, last) / (VELOCITY_ERROR_FRACTION * MAX_RELATIVE_CHANGE * scale);
        let jump = (new - old).abs() / (MAX_VELOCITY_CHANGE * scale);
        let (ratio, reason) = if jump >= error || jump.is_nan() {
            (jump, "changed by more than its size (10 m/s at least)")
        } else {
            (error, "left its trend by more than its local error allows")
        };
        self.take(ratio, Rejection { cell: j, variable, value: new, reason });
    }

    /// Takes in a change's `ratio` with the rejection it makes above 1: it becomes the step's
    /// where it is the largest so far or not a number (entered as infinite).
    fn take(&mut self, ratio: f64, why: Rejection) {
        if ratio.is_nan() || ratio > self.ratio {
            self.ratio = if ratio.is_finite() { ratio } else { f64::INFINITY };
            self.worst = why;
        }
    }

    /// As [`ChangeRatio::check`], a change that is `held` taken in at most at its limit.
    fn check_held(&mut self, cell: usize, variable: &'static str, old: f64, new: f64, scale: f64, held: bool) {
        let mut r = relative_change(old, new, scale);
        if held && r.is_finite() {
            r = r.min(1.0);
        }
        self.take(r, Rejection { cell, variable, value: new, reason: "changed by more than 25 %" });
    }
}

/// The change from `old` to `new` as a fraction of its allowed change: `MAX_RELATIVE_CHANGE`
/// of the larger of |old| and `scale`.
fn relative_change(old: f64, new: f64, scale: f64) -> f64 {
    (new - old).abs() / (MAX_RELATIVE_CHANGE * old.abs().max(scale))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::BoundaryKind;
    use crate::fluids::PhaseProps;
    use crate::model::BoundaryState;

    /// Two gas-filled cells at 1 bar (κ = 1/p, so the absolute limit `MAX_VOLUME_ERROR` binds)
    /// whose volume errors go from `old_errors` to `errors` over a step of the work `w` (its
    /// resets' volumes, the corrected fractions of the old errors and its retry record).
    fn check_with(old_errors: [f64; 2], errors: [f64; 2], w: &mut Work) -> Result<ChangeRatio, Rejection> {
        let gas = PhaseProps { rho: 1.0, drho_dp: 1.0e-5, ..PhaseProps::default() };
        let liquid = PhaseProps { rho: 800.0, drho_dp: 1.0e-6, ..PhaseProps::default() };
        let old = State {
            time: 2.0,
            p: vec![1.0e5; 2],
            alpha: vec![1.0; 2],
            volume_error: old_errors.to_vec(),
            gas: vec![gas; 2],
            liquid: vec![liquid; 2],
            ..State::default()
        };
        let next = State { volume_error: errors.to_vec(), ..old.clone() };
        let b = BoundaryState {
            kind: BoundaryKind::Closed,
            p: 1.0e5,
            alpha: 1.0,
            t_g: 300.0,
            t_l: 77.0,
            v_g: 0.0,
            v_l: 0.0,
            gas,
            liquid,
            open_fraction: 1.0,
            loss: 0.0,
        };
        let st = StepInput {
            s: &old,
            dt: 0.1,
            n: 2,
            inlet0: &b,
            outlet0: &b,
            inlet1: &b,
            outlet1: &b,
            dp_in: 0.0,
            dp_out: 0.0,
            choke: 0.0,
        };
        volume_error_check(&st, w, &next)
    }

    /// A step from no volume error, each cell's old error corrected in full, with the volume
    /// that resets and edge changes made in each cell (a cell with a nonzero one had a reset).
    fn work(reset_volume: [f64; 2]) -> Work {
        Work {
            reset: reset_volume.iter().map(|&v| v != 0.0).collect(),
            reset_volume: reset_volume.to_vec(),
            corrected: vec![1.0; 2],
            merged: vec![false; 2],
            volume_retry: RetryRecord { time: f64::NAN, change: vec![0.0; 2] },
            ..Work::default()
        }
    }

    fn check(errors: [f64; 2], reset_volume: [f64; 2]) -> Result<ChangeRatio, Rejection> {
        check_with([0.0; 2], errors, &mut work(reset_volume))
    }

    const E: f64 = MAX_VOLUME_ERROR;

    #[test]
    fn a_volume_error_below_its_limit_is_a_share_of_the_step_control() {
        let c = check([0.5 * E, -0.75 * E], [0.0; 2]).unwrap();
        assert!((c.ratio - 0.75).abs() < 1e-12, "{}", c.ratio);
        assert_eq!((c.worst.cell, c.worst.variable), (1, "volume error"));
        // the part a trace reset made is not the step's
        let c = check([0.5 * E, -0.75 * E], [0.0, -0.5 * E]).unwrap();
        assert!((c.ratio - 0.5).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn a_volume_error_above_its_limit_rejects_the_step_naming_the_largest() {
        let r = check([1.5 * E, -2.5 * E], [0.0; 2]).unwrap_err();
        assert_eq!((r.cell, r.variable, r.value), (1, "volume error", -2.5 * E));
        // a reset's volume is taken off; what the step made beside it is still checked
        assert!(check([1.5 * E, 0.0], [1.4 * E, 0.0]).is_ok());
        let r = check([1.5 * E, 0.0], [-E, 0.0]).unwrap_err();
        assert_eq!((r.cell, r.value), (0, 2.5 * E));
        // a cell whose whole phase went over to the other is exempt
        let mut w = work([0.0; 2]);
        w.merged[1] = true;
        assert!(check_with([0.0; 2], [0.5 * E, 30.0 * E], &mut w).is_ok());
    }

    #[test]
    fn an_error_that_did_not_grow_is_inherited() {
        // without a reset: an error above the limit that shrank is the old one's remainder
        let mut w = work([0.0; 2]);
        assert!(check_with([3.0 * E, 0.0], [2.5 * E, 0.5 * E], &mut w).is_ok());
        assert!(check_with([3.0 * E, 0.0], [3.5 * E, 0.5 * E], &mut w).is_err());
    }

    #[test]
    fn a_reset_cells_inherited_error_is_not_the_steps() {
        // the pressure solve corrected a fifth of an old error of 10 E: 8 E are inherited
        let mut w = work([0.0, 0.0]);
        w.reset[0] = true;
        w.corrected = vec![0.2, 1.0];
        let c = check_with([10.0 * E, 0.0], [8.5 * E, 0.0], &mut w).unwrap();
        assert!((c.ratio - 0.5).abs() < 1e-12, "{c:?}");
        assert!(check_with([10.0 * E, 0.0], [9.5 * E, 0.0], &mut w).is_err());
    }

    #[test]
    fn an_error_a_shorter_step_does_not_halve_is_not_the_steps() {
        let mut w = work([0.0; 2]);
        let r = check_with([0.0; 2], [3.0 * E, 2.0 * E], &mut w).unwrap_err();
        assert_eq!(r.cell, 0);
        assert_eq!(w.volume_retry.change, [3.0 * E, 2.0 * E]);
        // the retry (a shorter step from the same time) halved cell 1's error but not cell 0's
        let c = check_with([0.0; 2], [2.9 * E, 0.9 * E], &mut w).unwrap();
        assert_eq!((c.ratio, c.worst.cell), (1.0, 0));
        // a step from another time is judged afresh
        w.volume_retry.time = 1.0;
        assert!(check_with([0.0; 2], [2.9 * E, 0.9 * E], &mut w).is_err());
    }

    #[test]
    fn a_retry_record_keeps_the_rejected_steps_changes_above_their_limit() {
        let mut r = RetryRecord::default();
        r.resize(3);
        assert!(!r.over_before(0.0, 0), "no step rejected yet");
        r.record(2.0, |i| [Some(-4.0e4), None, Some(1.0e3)][i]);
        assert_eq!(r.change, [4.0e4, 0.0, 1.0e3]);
        // a retry: cell 0's change kept more than half of the rejected one (of either sign),
        // cell 2's was halved, cell 1's was within its limit
        assert!(r.not_halved(2.0, 0, 3.9e4) && r.not_halved(2.0, 0, -2.1e4));
        assert!(!r.not_halved(2.0, 2, 4.0e2) && !r.not_halved(2.0, 1, 5.0e4));
        // a step from another time is not a retry
        assert!(!r.not_halved(2.5, 0, 3.9e4));
        // a change that is not a number is never held
        assert!(!r.not_halved(2.0, 0, f64::NAN));
    }

    #[test]
    fn a_velocity_is_held_by_its_departure_from_the_last_steps_trend() {
        let fresh = || ChangeRatio { ratio: 0.0, worst: Rejection { cell: 0, variable: "", value: 0.0, reason: "" } };
        let allowed = VELOCITY_ERROR_FRACTION * MAX_RELATIVE_CHANGE * SCALE_VELOCITY_M_S;
        // a steady acceleration of 3 m/s per step: no departure, held only by the largest change
        let mut c = fresh();
        c.check_velocity(4, "gas velocity", 0.0, 3.0, Some((1.0, 3.0)));
        assert!((c.ratio - 3.0 / (MAX_VELOCITY_CHANGE * SCALE_VELOCITY_M_S)).abs() < 1e-15, "{c:?}");
        // a step twice as long as the last keeps the trend at twice its change
        let mut c = fresh();
        c.check_velocity(4, "gas velocity", 0.0, 6.0, Some((2.0, 3.0)));
        assert!((c.ratio - 0.6).abs() < 1e-12, "{c:?}");
        // a velocity that turns: half the departure, for equal steps
        let mut c = fresh();
        c.check_velocity(2, "liquid velocity", 10.0, 11.0, Some((1.0, -1.0)));
        assert!((c.ratio - 1.0 / allowed).abs() < 1e-12, "{c:?}");
        assert_eq!((c.worst.cell, c.worst.reason), (2, "left its trend by more than its local error allows"));
        // a flicker from step to step departs by twice its change
        let mut c = fresh();
        c.check_velocity(2, "liquid velocity", 0.0, 1.5, Some((1.0, -1.5)));
        assert!((c.ratio - 1.5 / allowed).abs() < 1e-12 && c.ratio > 1.0, "{c:?}");
        // the run's first step: the 25 % rule
        let mut c = fresh();
        c.check_velocity(0, "gas velocity", 20.0, 24.0, None);
        assert!((c.ratio - 4.0 / (MAX_RELATIVE_CHANGE * 20.0)).abs() < 1e-12, "{c:?}");
        assert_eq!(c.worst.reason, "changed by more than 25 %");
        // not a number rejects
        let mut c = fresh();
        c.check_velocity(0, "gas velocity", 20.0, f64::NAN, Some((1.0, 0.0)));
        assert!(c.ratio.is_infinite());
    }

    #[test]
    fn a_trend_is_the_last_accepted_steps_from_the_time_it_ended() {
        let old = State { time: 1.0, v_g: vec![0.0, 2.0], v_l: vec![1.0, 1.0], ..State::default() };
        let next = State { time: 1.5, v_g: vec![1.0, 1.0], v_l: vec![1.0, 3.0], ..State::default() };
        let mut t = VelocityTrend::default();
        assert_eq!(t.before(0.0, 0.1, 2), None, "no step accepted yet");
        t.record(&old, &next, 0.5);
        assert_eq!((t.dv_g.as_slice(), t.dv_l.as_slice()), ([1.0, -1.0].as_slice(), [0.0, 2.0].as_slice()));
        assert_eq!(t.before(1.5, 0.25, 2), Some(0.5));
        // a step from another time (or on another line) has none
        assert_eq!(t.before(1.0, 0.25, 2), None);
        assert_eq!(t.before(1.5, 0.25, 3), None);
    }

    #[test]
    fn a_held_change_enters_the_step_control_at_its_limit() {
        let mut c = ChangeRatio { ratio: 0.0, worst: Rejection { cell: 0, variable: "", value: 0.0, reason: "" } };
        c.check_held(3, "pressure", 4.0e4, 8.0e4, 1.0e5, true);
        assert_eq!((c.ratio, c.worst.cell), (1.0, 3));
        c.check_held(1, "pressure", 4.0e4, 8.0e4, 1.0e5, false);
        assert_eq!((c.ratio, c.worst.cell), (4.0e4 / (MAX_RELATIVE_CHANGE * 1.0e5), 1));
        // a change that is not a number rejects the step, held or not
        c.check_held(2, "pressure", 4.0e4, f64::NAN, 1.0e5, true);
        assert!(c.ratio.is_infinite() && c.worst.cell == 2);
    }
}
