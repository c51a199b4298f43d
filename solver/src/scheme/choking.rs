//! Choked outflow: the line's exit junction cannot pass the fluid faster than its critical
//! speed, whatever the pressure beyond it.
//!
//! The criterion is RELAP5's (RELAP5/MOD3 code manual, vol. 1, choked flow): the exit's
//! velocity weighted as (α_g ρ_l v_g + α_l ρ_g v_l)/(α_g ρ_l + α_l ρ_g) may not exceed the
//! critical speed a of the fluid that leaves. Single-phase liquid is not checked: its speed of
//! sound (hundreds of m/s) is out of reach, and the subcooled-flashing critical flow (RELAP5's
//! Alamgir–Lienhard–Jones throat undershoot) is not modelled.
//!
//! Decision: a is the speed of sound of the exit cell's mixture without phase change
//! ([`frozen_mixture_sound_speed`], Wood's, each phase at its own state; the gas's own where it
//! is all gas), at the old time, where its phases are out of equilibrium; RELAP5 takes a
//! homogeneous-equilibrium speed from the saturation line instead. Where both phases are
//! saturated the mixture flashes as it expands, and a is the flashing speed
//! ([`two_phase_critical_speed`] below). The two fluids here are seldom in equilibrium at the
//! exit: on the NBS hydrogen runs a trace of drops travels in gas at 100–290 K, whose own speed is
//! 600–1300 m/s, while the equilibrium speed at saturation is 320 m/s; with it the exit choked
//! and unchoked as the trace came and went, and the runs took thirteen times the steps. Wood's
//! speed is continuous as either phase vanishes and follows each phase's temperature. Only the
//! exit junction is checked: the line has one flow area, and a flow that chokes does so where it
//! discharges. A flashing discharge at the NBS line's exit (methane saturated at 11 atm, after
//! its chilldown) left at 140 m/s where its mixture's speed of sound is under 90 m/s: without a
//! critical-flow limit the discrete flow there flickered from step to step, took half a million
//! steps and a per-step energy residual that added up to 1.6 % (`calibrated-six.toml`'s parameters;
//! 5 800 steps and 4e-4 with the limit).
//!
//! How it is imposed: an extra resistance λ α_k ρ_k v_k on each phase at the exit junction.
//! The step is first taken with the resistance that would have held the last step's exit
//! exactly at a ([`Scheme::exit_resistance`] of its last pass; 0 at the start and where the
//! flow stayed below a without one). If the exit's weighted velocity then exceeds a by more
//! than [`CHOKE_TOLERANCE`], or falls short of it by more than that while λ > 0, step 1 is
//! taken again with λ ≥ 0 chosen so that, with the previous pass's pressure changes, the
//! weighted velocity is a (λ = 0 where the flow stays below a without it); the exit cell's
//! pressure moves in the new pass, so the passes are repeated (at most [`MAX_CHOKE_PASSES`])
//! until the velocity holds within the tolerance.
//!
//! Decision: each step once started unchoked and found λ afresh. Where the velocity it left lay
//! within the tolerance, the next step took one pass fewer and left it higher in the band, and
//! the step after took the extra pass again: nitrogen saturated at 11 atm, choked at its exit
//! after its chilldown, alternated three and two passes (λ 9.97 and 6.14 1/s, 0.3 % and 0.9 %
//! above a) on every other step, its exit cell's volume error with them (1.4e-3 and 2e-4), which
//! held its steps to 35 ms for the rest of the run (10 450 steps for 300 s; 6 445 now). Started
//! from the last step's own λ, the velocity drifted to the band's edge and λ jumped back, a
//! kick to the exit cell's pressure each time (methane saturated at 3 atm with
//! `calibrated-six.toml`: 16 % more steps than without a warm start); started from the λ that would
//! have held the last step at a, λ follows the exit's state from step to step and a further
//! pass is rare. A resistance rather than a prescribed velocity, so that the work the pressure
//! drop across the exit does beyond what the choked flow's kinetic energy takes is booked as
//! heat like every other force's (the momentum equations' energy bookkeeping,
//! [`booked_heat`](super::momentum)): a prescribed exit velocity, tried first, left the
//! kinetic energy its junction's momentum equation books unpaid (an energy balance error of
//! 8 % on methane saturated at 11 atm). A choked exit's velocities are exempt from the step
//! control's velocity rule: they follow the exit cell's state, whose changes the control limits
//! (where liquid reaches the exit cell its critical speed drops from hundreds to tens of m/s,
//! and no step is short enough to make that a small change).

use nalgebra::{Matrix2, Vector2};

use super::{Scheme, StepInput, Work, present};
use crate::case::BoundaryKind;
use crate::closures::smooth_step;
use crate::fluids::{flashing_mixture_sound_speed, frozen_mixture_sound_speed};
use crate::model::State;

impl Scheme<'_> {
    /// The exit's choking criterion for the step, from the old state; `None` where the exit is
    /// not checked (no pressure-type outlet, a liquid-only exit cell, a speed the tables'
    /// derivatives do not give).
    pub(super) fn exit_criterion(&self, st: &StepInput) -> Option<ExitCriterion> {
        if !matches!(st.outlet1.kind, BoundaryKind::Pressure | BoundaryKind::Reservoir) {
            return None;
        }
        let s: &State = st.s;
        let c = st.n - 1;
        let gas = present(s.m_g[c], s.m_l[c]);
        let liquid = present(s.m_l[c], s.m_g[c]);
        let speed = match (gas, liquid) {
            (true, true) => two_phase_critical_speed(s, c)?,
            (true, false) => s.gas[c].sound_speed()?,
            _ => return None,
        };
        let (a_g, a_l) = (s.alpha[c], 1.0 - s.alpha[c]);
        let (rho_g, rho_l) = (s.gas[c].rho, s.liquid[c].rho);
        let den = a_g * rho_l + a_l * rho_g;
        if !(den > 0.0 && speed > 0.0) {
            return None;
        }
        let (a_j, rho_gj, rho_lj) = self.junction_densities(s, st.n, st.inlet0, st.outlet0);
        Some(ExitCriterion {
            speed,
            weights: (a_g * rho_l / den, a_l * rho_g / den),
            mass: Matrix2::new(a_j * rho_gj, 0.0, 0.0, (1.0 - a_j) * rho_lj),
        })
    }

    /// The resistance λ (1/s) for another pass, if the last pass's new exit velocities
    /// `next.v_g[n]`, `next.v_l[n]` exceed the critical speed by more than [`CHOKE_TOLERANCE`],
    /// or fall short of it by more than that with a resistance `st.choke` > 0: the
    /// [`Scheme::exit_resistance`] of that pass.
    pub(super) fn exit_choke(&self, exit: &ExitCriterion, st: &StepInput, w: &Work, next: &State) -> Option<f64> {
        let now = exit.velocity(next, st.n);
        let too_fast = now > exit.speed * (1.0 + CHOKE_TOLERANCE);
        let held_back = st.choke > 0.0 && now < exit.speed * (1.0 - CHOKE_TOLERANCE);
        if !(too_fast || held_back) {
            return None;
        }
        self.exit_resistance(exit, st, w, next)
    }

    /// The resistance λ ≥ 0 (1/s) with which the last pass's exit velocities would have been
    /// the critical speed (0 where they stay below it without one), or `None` where the
    /// junction's block does not give it.
    ///
    /// With the exit junction's momentum block D (`w.diag[n]`, which holds the last pass's
    /// resistance λ₀ M) and the forcing R = D v that gave its velocities v (its pressure changes
    /// included), the velocities with a resistance λ are (D + (λ − λ₀) M)⁻¹ R,
    /// M = diag(α_g ρ_g, α_l ρ_l) at the junction; λ is found by bisection so that their weighted
    /// velocity is the critical speed.
    pub(super) fn exit_resistance(&self, exit: &ExitCriterion, st: &StepInput, w: &Work, next: &State) -> Option<f64> {
        let n = st.n;
        let (speed, m) = (exit.speed, exit.mass);
        let v = Vector2::new(next.v_g[n], next.v_l[n]);
        let lambda0 = st.choke;
        let now = exit.velocity(next, n);
        if now.is_nan() {
            return None;
        }
        if lambda0 == 0.0 && now <= speed {
            return Some(0.0);
        }
        let d = w.diag[n];
        let r = d * v;
        let excess = |lambda: f64| -> Option<f64> {
            let v = (d + m * (lambda - lambda0)).try_inverse()? * r;
            Some(exit.weighted(v[0], v[1]) - speed)
        };
        let (mut lo, mut hi) = if now > speed {
            // bracket: from the block's own inertia per unit mass, quadrupled until the
            // resistance brings the flow below the critical speed
            let scale = (d[(0, 0)] + d[(1, 1)]) / (m[(0, 0)] + m[(1, 1)]).max(f64::MIN_POSITIVE);
            let lo = lambda0;
            let mut hi = lambda0 + if scale.is_finite() && scale > 0.0 { scale } else { 1.0 / st.dt };
            let mut tries = 0;
            while excess(hi)? > 0.0 {
                hi = lambda0 + 4.0 * (hi - lambda0);
                tries += 1;
                if tries > 60 {
                    return None;
                }
            }
            (lo, hi)
        } else {
            // the resistance holds the flow below the critical speed: less of it, none where
            // the flow stays below without
            if excess(0.0)? <= 0.0 {
                return Some(0.0);
            }
            (0.0, lambda0)
        };
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            if excess(mid)? > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Some(hi)
    }
}

/// The critical speed (m/s) against which the exit's choking checks the outflow of cell `c` of
/// `s` where it holds both phases: its speed without phase change (Wood's) where either phase is
/// away from saturation, and with the part of the phase change a discharge completes
/// ([`flashing_mixture_sound_speed`]) as the gas's superheat and the liquid's subcooling fall
/// below [`EQUILIBRIUM_WIDTH_K`].
///
/// Decision: a discharge flashes as it expands only where its phases are at saturation; drops
/// in warm vapour or subcooled liquid under vapour leave at the frozen speed (the module's
/// first decision). Where both are saturated the frozen speed is too high: para-hydrogen
/// saturated at 11 atm on the NBS line (300 s, 30 cells), with the parameters of a six-run fit
/// on this solver (`hg_drop_gain` 4.28, `hg_drop_eps` 4.1e-5, `kutateladze_k` 0.238), reached a
/// saturated mixture at the exit after its chilldown (x = 0.32, 2.1 bar) leaving at 190–218 m/s
/// against the 83 kPa beyond, where Wood's speed is 227 m/s and the flashing one 175 m/s; the
/// flow flickered with a period of 5 ms for the rest of the run, 492 299 steps at 0.5 ms and an
/// energy balance error of 1.4e-3. With the flashing speed the exit chokes there from the
/// chilldown on: 14 043 steps, 2.8e-4. (On the NBS cases at the defaults the station-4
/// chilldowns moved by +0.26 / +0.32 / −0.55 s, nitrogen saturated 2.5 / 3.4 and subcooled
/// 4.2 atm; the hydrogen runs' exits never reach saturation and are unchanged.)
/// `None` where a phase's speed is not defined.
pub fn two_phase_critical_speed(s: &State, c: usize) -> Option<f64> {
    let frozen = frozen_mixture_sound_speed(s.alpha[c], &s.gas[c], &s.liquid[c])?;
    let sat = &s.sat[c];
    if sat.h_lg <= 0.0 {
        return Some(frozen);
    }
    let saturated = (1.0 - smooth_step((s.t_g[c] - sat.t_sat) / EQUILIBRIUM_WIDTH_K))
        * (1.0 - smooth_step((sat.t_sat - s.t_l[c]) / EQUILIBRIUM_WIDTH_K));
    if saturated == 0.0 {
        return Some(frozen);
    }
    let flashing = flashing_mixture_sound_speed(s.alpha[c], &s.gas[c], &s.liquid[c], sat, saturated);
    Some(flashing.map_or(frozen, |f| f.min(frozen)))
}

/// How far (K) the gas's superheat or the liquid's subcooling at the exit goes before its
/// critical speed is the frozen mixture's alone ([`two_phase_critical_speed`]).
pub const EQUILIBRIUM_WIDTH_K: f64 = 2.0;

/// The exit's choking criterion over a step, from the old state
/// ([`Scheme::exit_criterion`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct ExitCriterion {
    /// The critical speed a, m/s.
    speed: f64,
    /// The weights (w_g, w_l) of the criterion's velocity w_g v_g + w_l v_l.
    weights: (f64, f64),
    /// M = diag(α_g ρ_g, α_l ρ_l) of the exit junction: the resistance λ M of its momentum
    /// equations.
    mass: Matrix2<f64>,
}

impl ExitCriterion {
    /// The criterion's weighted velocity w_g v_g + w_l v_l of the phase velocities `v_g`, `v_l`.
    fn weighted(&self, v_g: f64, v_l: f64) -> f64 {
        self.weights.0 * v_g + self.weights.1 * v_l
    }

    /// The criterion's weighted velocity at the exit junction `n` of `next`.
    pub(super) fn velocity(&self, next: &State, n: usize) -> f64 {
        self.weighted(next.v_g[n], next.v_l[n])
    }
}

/// Bisection steps for the resistance λ.
const BISECTION_STEPS: usize = 60;

/// The passes of step 1 that a choked exit may take beyond the first.
pub(super) const MAX_CHOKE_PASSES: usize = 4;

/// How far, as a fraction of the critical speed, the exit's weighted velocity may exceed it
/// before another pass is taken.
pub const CHOKE_TOLERANCE: f64 = 0.01;
