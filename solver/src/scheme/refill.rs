//! The pressure at which a cell's phases, with their masses and energies, fill the cell: the
//! equation of state solved for the pressure where its linearisation in the step fails.
//!
//! The pressure equation corrects a volume error by one linearised step (the storage matrix's
//! pressure change, `pressure_equation`); the state recovery then finds each phase's density at
//! that pressure from its energy, and what the linearisation missed is the new volume error. As
//! the step vanishes that remainder is the correction's own nonlinearity, not the step's
//! truncation error. Near the critical point it does not shrink: in para-hydrogen at 1.30 MPa and
//! 32.99 K (1.009 of the critical pressure) ∂ρ/∂T|p is −180 to −270 kg/m³/K and ∂ρ/∂p|T changes
//! by a factor 2.5 over 2 kPa, so a correction of ±2 kPa leaves errors of 3–7e-3 at any step
//! length (the limit is 2e-3), and the run ended with its steps halved below 1e-9 s
//! (para-hydrogen subcooled at 11 atm, inlet at 19.619650779 K, `examples/nbs/calibrated-six.toml`:
//! 9.79 s). [`filling_pressure`] solves the cell's volume balance for the pressure instead, with
//! the phases' masses and energies held (so mass and energy are kept exactly), by a bracketed
//! secant on the equation of state itself.

use crate::fluids::{FluidTable, Phase};

/// Farthest the search moves the pressure, as a fraction of it.
pub(super) const MAX_RELATIVE_MOVE: f64 = 0.1;

/// Farthest the search moves the pressure of a cell where a whole phase went over to the other
/// (`Scheme::refill_merged`), as a fraction of it, where neither its filling pressure within
/// `MAX_RELATIVE_MOVE` nor a near-critical mixture's filling pressure holds.
///
/// Decision: the pressure equation linearised the cell with both phases in it, so the pressure it
/// gave a cell whose liquid then went over to the gas whole is that of a stiff cell, and it may
/// lie far from the pressure at which the gas alone fills the cell. With one parameter set of the
/// robustness study (`tests/data/robustness-seed1-sample315.toml`: wall friction ×3.9, wall
/// evaporation ×3.85) a step of 1.8 ms at 325.27 s took the nitrogen line's cell 28, where liquid
/// 4 K superheated filled 0.5 % of the volume, to 795 kPa (the same step twice and four times as
/// long: 472 and 341 kPa, both rejected) with its liquid merged into the gas, which then filled
/// 53 % of the cell; its filling pressure lay beyond the 10 % of `MAX_RELATIVE_MOVE`, the first
/// recovery stood, and the following corrections, limited to 2 % of the pressure a step, left a
/// nonlinear remainder of about 0.01 at any step length, until the steps were halved below 1e-9 s
/// at 325.27 s. With the farther search the run completes its 1000 s: 186 of its 17 988 merged
/// cells' refills go beyond 10 %, to 0.42–1.86 times the pressure solve's. The search within 10 %
/// comes first so that every cell it refilled is refilled as before: the six NBS runs are the
/// same bit for bit; of the operating envelope's 64 runs two take other steps, para-hydrogen
/// subcooled at 11 atm with the defaults and with `calibrated.toml` (station 4 at 27.49 → 27.43 s
/// and 33.54 → 33.78 s, against 28.10 and 33.85 s with steps of at most 1 ms).
pub(super) const MERGED_MAX_RELATIVE_MOVE: f64 = 0.9;

/// Volume error at which the search stops.
const TOLERANCE: f64 = 1e-9;
/// Most evaluations of the volume balance.
const MAX_EVALUATIONS: usize = 80;

/// What a cell holds per unit volume: each phase's mass, kg/m³, and specific internal energy,
/// J/kg (`None` for a phase whose mass is a trace, which keeps the volume `fixed_volume` it was
/// recovered with), and the temperatures to start each phase's inversion from.
#[derive(Debug, Clone, Copy)]
pub(super) struct Contents {
    pub m_g: f64,
    pub u_g: Option<f64>,
    pub m_l: f64,
    pub u_l: Option<f64>,
    pub fixed_volume: f64,
    pub t_g: f64,
    pub t_l: f64,
}

/// The cell's volume balance at pressure `p`: the phases' volumes less the cell's (a fraction of
/// it), with the slope d/dp at constant energies; `None` where a phase has no state at `p`.
/// The temperature guesses move to the temperatures found.
fn balance(fluid: &FluidTable, c: &mut Contents, p: f64) -> Option<(f64, f64)> {
    let mut volume = c.fixed_volume;
    let mut slope = 0.0;
    for (phase, m, u, t) in [(Phase::Gas, c.m_g, c.u_g, &mut c.t_g), (Phase::Liquid, c.m_l, c.u_l, &mut c.t_l)] {
        let Some(u) = u else { continue };
        let (temperature, pr) = fluid.temperature_from_energy(phase, p, u, *t).ok()?;
        *t = temperature;
        // dρ/dp at constant u: ρ_p − ρ_T u_p / u_T
        let drho = pr.drho_dp - pr.drho_dt * pr.du_dp / pr.du_dt;
        volume += m / pr.rho;
        slope -= m / (pr.rho * pr.rho) * drho;
    }
    Some((volume - 1.0, slope))
}

/// The pressure near `p0` at which the phases of `contents` fill their cell (volume error below
/// `TOLERANCE`), within `relative_reach` of `p0` (a fraction of it: `MAX_RELATIVE_MOVE`, or
/// `MERGED_MAX_RELATIVE_MOVE` for a merged cell); `None` where there is no such pressure there
/// (or no state of a phase on the way to it).
///
/// The first trial is the Newton step of the balance's slope at constant energies (or, where
/// that slope has the wrong sign, a move of the error's size relative to the pressure in the
/// direction that compresses an overfull cell); the trial moves double (up to the reach) until
/// the balance changes sign, first in that direction, then in the other; the Illinois variant
/// of the secant method then narrows the bracket.
pub(super) fn filling_pressure(fluid: &FluidTable, contents: &Contents, p0: f64, relative_reach: f64) -> Option<f64> {
    let mut c = *contents;
    let (f0, slope) = balance(fluid, &mut c, p0)?;
    if f0.abs() <= TOLERANCE {
        return Some(p0);
    }
    let reach = relative_reach * p0;
    // an overfull cell (f > 0) is compressed: the pressure rises where (∂ρ/∂p)_u > 0
    let first = if slope < 0.0 { -f0 / slope } else { f0.signum() * f0.abs().max(1e-6) * p0 };
    let first = first.clamp(-reach, reach);
    let mut evaluations = 1;
    let mut bracket = None;
    'search: for direction in [1.0, -1.0] {
        let mut c = *contents;
        let mut step = direction * first;
        while evaluations < MAX_EVALUATIONS {
            evaluations += 1;
            let p = p0 + step;
            let Some((f, _)) = balance(fluid, &mut c, p) else { break };
            if f.abs() <= TOLERANCE {
                return Some(p);
            }
            if f.signum() != f0.signum() {
                bracket = Some((p0, f0, p, f, c));
                break 'search;
            }
            if step.abs() >= reach {
                break;
            }
            step = (2.0 * step).clamp(-reach, reach);
        }
    }
    let (mut a, mut fa, mut b, mut fb, mut c) = bracket?;
    // Illinois: a secant within the bracket, halving the weight of an end kept twice
    let mut kept = 0i8;
    while evaluations < MAX_EVALUATIONS {
        evaluations += 1;
        let p = (a * fb - b * fa) / (fb - fa);
        if !(p > a.min(b) && p < a.max(b)) {
            return None;
        }
        let (f, _) = balance(fluid, &mut c, p)?;
        if f.abs() <= TOLERANCE || (b - a).abs() <= 1e-12 * p {
            return Some(p);
        }
        if f.signum() == fb.signum() {
            // the new point replaces b; a is kept
            (b, fb) = (p, f);
            if kept == -1 {
                fa *= 0.5;
            }
            kept = -1;
        } else {
            (a, fa) = (b, fb);
            (b, fb) = (p, f);
            kept = 1;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fluids;

    /// Contents of a cell holding the two phases at `(p, t_g)` and `(p, t_l)` with gas volume
    /// fraction `alpha`.
    fn contents(fluid: &FluidTable, p: f64, t_g: f64, t_l: f64, alpha: f64) -> Contents {
        let g = fluid.phase_props(Phase::Gas, p, t_g).unwrap();
        let l = fluid.phase_props(Phase::Liquid, p, t_l).unwrap();
        Contents {
            m_g: alpha * g.rho,
            u_g: Some(g.u),
            m_l: (1.0 - alpha) * l.rho,
            u_l: Some(l.u),
            fixed_volume: 0.0,
            t_g: t_g + 0.3,
            t_l: t_l - 0.3,
        }
    }

    #[test]
    fn finds_the_pressure_a_cell_was_filled_at() {
        let n2 = fluids::embedded("nitrogen").unwrap();
        let c = contents(n2, 3.0e5, 120.0, 85.0, 0.4);
        for p0 in [2.75e5, 2.99e5, 3.2e5] {
            let p = filling_pressure(n2, &c, p0, MAX_RELATIVE_MOVE).unwrap();
            assert!((p / 3.0e5 - 1.0).abs() < 1e-7, "from {p0}: {p}");
        }
    }

    #[test]
    fn finds_it_near_the_critical_point_where_the_linearisation_misses() {
        // para-hydrogen supercritical-side vapour beside liquid at 1.009 of the critical pressure
        let h2 = fluids::embedded("parahydrogen").unwrap();
        let pc = h2.constants().p_critical_pa;
        let p = 1.009 * pc;
        let (lo_g, _) = h2.phase_temperature_range(Phase::Gas, p).unwrap();
        let (_, hi_l) = h2.phase_temperature_range(Phase::Liquid, p).unwrap();
        let c = contents(h2, p, lo_g + 0.2, hi_l - 0.5, 0.005);
        let found = filling_pressure(h2, &c, p - 2.0e3, MAX_RELATIVE_MOVE).unwrap();
        assert!((found / p - 1.0).abs() < 1e-6, "{found} vs {p}");
        let mut at = c;
        let (f, _) = balance(h2, &mut at, found).unwrap();
        assert!(f.abs() <= TOLERANCE, "{f}");
    }

    #[test]
    fn a_merged_cell_is_filled_farther_off() {
        // the gas alone at 300 kPa, looked for from a pressure solve's 550 kPa (a merged cell's
        // linearisation with a stiff liquid in it)
        let n2 = fluids::embedded("nitrogen").unwrap();
        let mut c = contents(n2, 3.0e5, 110.0, 85.0, 1.0);
        c.m_l = 0.0;
        c.u_l = None;
        assert_eq!(filling_pressure(n2, &c, 5.5e5, MAX_RELATIVE_MOVE), None);
        let p = filling_pressure(n2, &c, 5.5e5, MERGED_MAX_RELATIVE_MOVE).unwrap();
        assert!((p / 3.0e5 - 1.0).abs() < 1e-7, "{p}");
    }

    #[test]
    fn no_pressure_within_reach_is_none() {
        let n2 = fluids::embedded("nitrogen").unwrap();
        let mut c = contents(n2, 3.0e5, 120.0, 85.0, 0.0);
        // twice the liquid that fills the cell: no pressure within 10 % compresses it so far
        c.m_l *= 2.0;
        assert_eq!(filling_pressure(n2, &c, 3.0e5, MAX_RELATIVE_MOVE), None);
    }
}
