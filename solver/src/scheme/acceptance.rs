//! The acceptance checks of a step: every value finite, no controlled variable changed by more
//! than its limit, no volume error grown above its limit.

use super::{
    CONTROLLED_FRACTION, MAX_RELATIVE_CHANGE, MAX_VOLUME_ERROR, Rejection, SCALE_PRESSURE_PA, SCALE_TEMPERATURE_K,
    SCALE_VELOCITY_M_S, SCALE_VOID, Scheme, StepInput, VOLUME_ERROR_PRESSURE_FRACTION, Work,
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
    pub(super) fn change_control(&self, st: &StepInput, w: &Work, next: &State) -> Result<ChangeRatio, Rejection> {
        let s = st.s;
        let mut change = ChangeRatio { ratio: 0.0, worst: Rejection { cell: 0, variable: "", value: 0.0, reason: "" } };
        // a phase's temperature and velocity are controlled only where it fills at least
        // CONTROLLED_FRACTION of the volume (a fixed fraction, not `blend_xmax`: the step sizes,
        // and through them the results, would otherwise move with a blending threshold)
        let xmax = CONTROLLED_FRACTION;
        for i in 0..st.n {
            change.check(i, "pressure", s.p[i], next.p[i], SCALE_PRESSURE_PA);
            if !w.merged[i] {
                change.check(i, "void fraction", s.alpha[i], next.alpha[i], SCALE_VOID);
                if s.alpha[i].min(next.alpha[i]) > xmax {
                    change.check(i, "gas temperature", s.t_g[i], next.t_g[i], SCALE_TEMPERATURE_K);
                }
                if (1.0 - s.alpha[i]).min(1.0 - next.alpha[i]) > xmax {
                    change.check(i, "liquid temperature", s.t_l[i], next.t_l[i], SCALE_TEMPERATURE_K);
                }
            }
            change.check(i, "wall temperature", s.t_w[i], next.t_w[i], SCALE_TEMPERATURE_K);
        }
        for j in 0..st.n + 1 {
            let (fg, fl) = self.junction_min_fractions(s, j);
            let (ag, al) = self.junction_alpha(s, j, st.inlet0, st.outlet0);
            let (fg, fl) = (fg.min(ag), fl.min(al));
            if fg > xmax {
                change.check(j, "gas velocity", s.v_g[j], next.v_g[j], SCALE_VELOCITY_M_S);
            }
            if fl > xmax {
                change.check(j, "liquid velocity", s.v_l[j], next.v_l[j], SCALE_VELOCITY_M_S);
            }
        }
        if change.ratio > 1.0 {
            return Err(change.worst);
        }
        Ok(change)
    }
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
/// step cannot remove it), naming the cell with the largest such error; not one that a trace
/// reset made (the reset is not a function of the step size).
///
/// In a cell full of liquid even a small volume error is a large pressure correction in the
/// next step (liquid is stiff): the error is also limited by the pressure change it implies,
/// |e| / κ with κ the cell's volume compressibility.
///
/// Otherwise returns the volume error's share of the step control: the largest ratio of a
/// grown error to its cell's limit, and where. The error a step leaves grows with the step (the
/// linearised equations of state are exact only as it vanishes), so the controller treats it as
/// it treats a controlled variable's change ([`Scheme::change_control`]): a step that comes
/// near the limit makes the next one shorter instead of the run growing its steps into a
/// rejection. (Without it, volume errors were nearly all the rejected steps of the NBS runs —
/// 1 389 of 1 395 on the saturated 2.5 atm run — each a whole step wasted and the next halved.)
pub(super) fn volume_error_check(st: &StepInput, w: &Work, next: &State) -> Result<ChangeRatio, Rejection> {
    let s = st.s;
    let ratio = |i: usize| {
        let (gp, lp, a) = (&next.gas[i], &next.liquid[i], next.alpha[i]);
        let kappa = a * gp.drho_dp / gp.rho + (1.0 - a) * lp.drho_dp / lp.rho;
        let limit = MAX_VOLUME_ERROR.min(VOLUME_ERROR_PRESSURE_FRACTION * next.p[i].max(SCALE_PRESSURE_PA) * kappa);
        next.volume_error[i].abs() / limit
    };
    let grew = |i: usize| !w.reset[i] && next.volume_error[i].abs() > s.volume_error[i].abs();
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
    for i in (0..st.n).filter(|&i| grew(i)) {
        let r = ratio(i);
        let e = next.volume_error[i];
        if r > 1.0 && rejected.is_none_or(|k| e.abs() > next.volume_error[k].abs()) {
            rejected = Some(i);
        }
        if r > control.ratio {
            control.ratio = r;
            control.worst.cell = i;
            control.worst.value = e;
        }
    }
    match rejected {
        Some(i) => Err(Rejection { cell: i, value: next.volume_error[i], ..control.worst }),
        None => Ok(control),
    }
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
        let r = (new - old).abs() / (MAX_RELATIVE_CHANGE * old.abs().max(scale));
        if r.is_nan() || r > self.ratio {
            self.ratio = if r.is_finite() { r } else { f64::INFINITY };
            self.worst = Rejection { cell, variable, value: new, reason: "changed by more than 25 %" };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::BoundaryKind;
    use crate::fluids::PhaseProps;
    use crate::model::BoundaryState;

    /// Two gas-filled cells at 1 bar (κ = 1/p, so the absolute limit `MAX_VOLUME_ERROR` binds)
    /// whose volume errors grow from zero to `errors` over a step.
    fn check(errors: [f64; 2], reset: [bool; 2]) -> Result<ChangeRatio, Rejection> {
        let gas = PhaseProps { rho: 1.0, drho_dp: 1.0e-5, ..PhaseProps::default() };
        let liquid = PhaseProps { rho: 800.0, drho_dp: 1.0e-6, ..PhaseProps::default() };
        let old = State {
            p: vec![1.0e5; 2],
            alpha: vec![1.0; 2],
            volume_error: vec![0.0; 2],
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
        };
        let w = Work { reset: reset.to_vec(), ..Work::default() };
        volume_error_check(&st, &w, &next)
    }

    #[test]
    fn a_volume_error_below_its_limit_is_a_share_of_the_step_control() {
        let c = check([0.5 * MAX_VOLUME_ERROR, -0.75 * MAX_VOLUME_ERROR], [false; 2]).unwrap();
        assert!((c.ratio - 0.75).abs() < 1e-12, "{}", c.ratio);
        assert_eq!((c.worst.cell, c.worst.variable), (1, "volume error"));
        // an error a trace reset made is not the step's
        let c = check([0.5 * MAX_VOLUME_ERROR, -0.75 * MAX_VOLUME_ERROR], [false, true]).unwrap();
        assert!((c.ratio - 0.5).abs() < 1e-12 && c.worst.cell == 0, "{c:?}");
    }

    #[test]
    fn a_volume_error_above_its_limit_rejects_the_step_naming_the_largest() {
        let r = check([1.5 * MAX_VOLUME_ERROR, -2.5 * MAX_VOLUME_ERROR], [false; 2]).unwrap_err();
        assert_eq!((r.cell, r.variable, r.value), (1, "volume error", -2.5 * MAX_VOLUME_ERROR));
        assert!(check([1.5 * MAX_VOLUME_ERROR, 0.0], [true, false]).is_ok());
    }
}
