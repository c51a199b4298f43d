//! The fluid of a cell near the critical point as one mixture in equilibrium: the lever rule
//! between saturated liquid and vapour, or between the phase tables' edges where the table gives
//! no saturation (`Scheme::near_critical_mixture` in `recovery.rs`), and the pressure at which
//! such a mixture fills its cell.

use super::refill;
use crate::fluids::{FluidTable, Phase, PhaseProps};

/// Fraction of the critical pressure above which a cell whose phases cannot be recovered is
/// recovered as one mixture (`Scheme::near_critical_mixture`).
pub(super) const NEAR_CRITICAL_FRACTION: f64 = 0.98;

/// Fraction of the critical pressure below which a cell whose volume error no step shrinks,
/// and which no pressure nearby fills, is recovered as one fluid (`Scheme::refill`).
pub(super) const SUPERCRITICAL_FRACTION: f64 = 1.1;

/// Where `Scheme::near_critical_mixture` applies: below the critical pressure only (phases that
/// could not be recovered one by one), or on either side of it (a volume error that
/// neither a shorter step nor the filling pressure removes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum NearCritical {
    /// From `NEAR_CRITICAL_FRACTION` of the critical pressure up to it.
    Below,
    /// From `NEAR_CRITICAL_FRACTION` up to `SUPERCRITICAL_FRACTION` of the critical pressure.
    EitherSide,
    /// At the pressure at which the cell's fluid as one mixture fills it
    /// ([`Mixture::filling_pressure`], from a pressure in the `EitherSide` window):
    /// from `refill::MAX_RELATIVE_MOVE` below `NEAR_CRITICAL_FRACTION` of the critical pressure up
    /// to `SUPERCRITICAL_FRACTION` of it.
    Filled,
}

impl NearCritical {
    /// The window of pressures, as fractions of the critical pressure.
    pub(super) fn window(self) -> (f64, f64) {
        match self {
            Self::Below => (NEAR_CRITICAL_FRACTION, 1.0),
            Self::EitherSide => (NEAR_CRITICAL_FRACTION, SUPERCRITICAL_FRACTION),
            Self::Filled => ((1.0 - refill::MAX_RELATIVE_MOVE) * NEAR_CRITICAL_FRACTION, SUPERCRITICAL_FRACTION),
        }
    }
}

/// One fluid near the critical point in equilibrium at a pressure: each phase's temperature,
/// properties and mass per unit volume (`Scheme::near_critical_mixture`).
pub(super) struct Mixture {
    pub(super) gas: (f64, PhaseProps, f64),
    pub(super) liquid: (f64, PhaseProps, f64),
}

impl Mixture {
    /// Mass `m` per unit volume at specific internal energy `u` as one fluid at pressure `p`:
    /// shared by the lever rule between saturated liquid and vapour where both phase tables hold
    /// them, else between the liquid table's top and the vapour table's bottom (all liquid or
    /// all vapour where the energy lies beyond that end); `guesses` are the gas and liquid
    /// temperatures to start an inversion from. `None` where the tables give no such state.
    pub(super) fn at(fluid: &FluidTable, p: f64, m: f64, u: f64, guesses: (f64, f64)) -> Option<Self> {
        // the two-phase end states: saturated liquid and vapour where the table gives a
        // saturation that both phase tables hold, else the tables' edges towards each other
        let saturated = fluid.saturation(p).ok().filter(|sat| sat.h_lg > 0.0).and_then(|sat| {
            let liquid = fluid.phase_props(Phase::Liquid, p, sat.t_sat).ok()?;
            let vapour = fluid.phase_props(Phase::Gas, p, sat.t_sat).ok()?;
            (liquid.u < vapour.u).then_some(((sat.t_sat, liquid), (sat.t_sat, vapour)))
        });
        let ((t_top, top), (t_bottom, bottom)) = match saturated {
            Some(ends) => ends,
            None => (table_edge(fluid, Phase::Liquid, p)?, table_edge(fluid, Phase::Gas, p)?),
        };
        let (gas, liquid) = if u <= top.u {
            let (t, pr) = fluid.temperature_from_energy(Phase::Liquid, p, u, guesses.1).ok()?;
            ((t_bottom, bottom, 0.0), (t, pr, m))
        } else if u >= bottom.u {
            let (t, pr) = fluid.temperature_from_energy(Phase::Gas, p, u, guesses.0).ok()?;
            ((t, pr, m), (t_top, top, 0.0))
        } else {
            let x = (u - top.u) / (bottom.u - top.u);
            ((t_bottom, bottom, x * m), (t_top, top, (1.0 - x) * m))
        };
        Some(Self { gas, liquid })
    }

    /// The fraction of the cell the mixture's phases take, less one.
    pub(super) fn volume_error(&self) -> f64 {
        self.gas.2 / self.gas.1.rho + self.liquid.2 / self.liquid.1.rho - 1.0
    }

    /// The pressure within `refill::MAX_RELATIVE_MOVE` of `p0`, itself in the near-critical
    /// window (`NearCritical::EitherSide`), and within the window of `NearCritical::Filled`, at
    /// which mass `m` per unit volume at energy `u` as one fluid fills its cell: the nearest to
    /// `p0` that a scan in each direction from `p0` brackets (first in the direction that
    /// shrinks the error: an underfull cell towards lower pressure), narrowed by bisection;
    /// `None` where there is none.
    ///
    /// Decision: bisection, not a secant: near the critical point the tables' densities at
    /// constant energy wobble by several per cent between neighbouring pressures (nitrogen at
    /// 30.9 kJ/kg: 251.6, 264.7, 261.9, 256.7 kg/m³ at 3.396, 3.402, 3.408, 3.414 MPa), and only
    /// a bracket is sure to hold a root.
    pub(super) fn filling_pressure(fluid: &FluidTable, m: f64, u: f64, p0: f64, guesses: (f64, f64)) -> Option<f64> {
        const SCAN: usize = 48;
        const BISECTIONS: usize = 50;
        let pc = fluid.constants().p_critical_pa;
        let (start, end) = NearCritical::EitherSide.window();
        if !(p0 >= start * pc && p0 < end * pc) {
            return None;
        }
        let (bottom, top) = NearCritical::Filled.window();
        let lo = (bottom * pc).max((1.0 - refill::MAX_RELATIVE_MOVE) * p0);
        let hi = (top * pc * (1.0 - 1e-9)).min((1.0 + refill::MAX_RELATIVE_MOVE) * p0);
        let error = |p: f64| Self::at(fluid, p, m, u, guesses).map(|mix| mix.volume_error()).filter(|e| e.is_finite());
        let f0 = error(p0)?;
        if f0 == 0.0 {
            return Some(p0);
        }
        let ends = if f0 < 0.0 { [lo, hi] } else { [hi, lo] };
        let bracket = ends.into_iter().find_map(|end| {
            let (mut a, mut fa) = (p0, f0);
            (1..=SCAN).find_map(|k| {
                let p = p0 + (end - p0) * k as f64 / SCAN as f64;
                let f = error(p)?;
                if f.signum() != fa.signum() {
                    return Some((a, fa, p));
                }
                (a, fa) = (p, f);
                None
            })
        });
        let (mut a, fa, mut b) = bracket?;
        for _ in 0..BISECTIONS {
            let mid = 0.5 * (a + b);
            let Some(f) = error(mid) else { break };
            if f.signum() == fa.signum() {
                a = mid;
            } else {
                b = mid;
            }
        }
        // the end of the bracket on the side of the filled cell's sign change, whose state exists
        [b, a].into_iter().find(|&p| error(p).is_some())
    }
}

/// The temperature and properties of `phase` at its table's edge towards the other phase at
/// pressure `p` (the liquid's top, the gas's bottom), a millionth of the table's range inside it.
pub(super) fn table_edge(fluid: &FluidTable, phase: Phase, p: f64) -> Option<(f64, PhaseProps)> {
    let (lo, hi) = fluid.phase_temperature_range(phase, p)?;
    let margin = 1e-6 * (hi - lo);
    let t = match phase {
        Phase::Liquid => hi - margin,
        Phase::Gas => lo + margin,
    };
    Some((t, fluid.phase_props(phase, p, t).ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fluids;

    /// Nitrogen as a merge left it in the inlet cell of a first-contact surge (robustness
    /// sample 2 of seed 1): 230.6 kg/m³ at 30.9 kJ/kg, underfilling its cell by 10 % at 3.44 MPa.
    const RHO: f64 = 230.6;
    const U: f64 = 30_900.0;

    #[test]
    fn no_single_phase_state_fills_the_cell_near_the_critical_point() {
        let n2 = fluids::embedded("nitrogen").unwrap();
        let pc = n2.constants().p_critical_pa;
        for k in 0..=20 {
            let p = pc * (1.0 + 0.002 * f64::from(k));
            if let Ok((_, props)) = n2.temperature_from_energy(Phase::Liquid, p, U, 127.0) {
                assert!(props.rho > 1.05 * RHO, "{p} Pa: {} kg/m³", props.rho);
            }
        }
    }

    #[test]
    fn the_mixture_fills_the_cell_below_the_critical_pressure() {
        let n2 = fluids::embedded("nitrogen").unwrap();
        let pc = n2.constants().p_critical_pa;
        let p0 = 3.44e6;
        let before = Mixture::at(n2, p0, RHO, U, (127.0, 127.0)).unwrap().volume_error();
        assert!(before < -0.05, "{before}");
        let p = Mixture::filling_pressure(n2, RHO, U, p0, (127.0, 127.0)).unwrap();
        assert!(p < pc && p > 0.9 * p0, "{p} Pa");
        let mix = Mixture::at(n2, p, RHO, U, (127.0, 127.0)).unwrap();
        assert!(mix.volume_error().abs() < 1e-6, "{}", mix.volume_error());
        // two phases, mass and energy kept
        assert!(mix.gas.2 > 0.0 && mix.liquid.2 > 0.0);
        assert!((mix.gas.2 + mix.liquid.2 - RHO).abs() < 1e-9 * RHO);
        let energy = mix.gas.2 * mix.gas.1.u + mix.liquid.2 * mix.liquid.1.u;
        assert!((energy / (RHO * U) - 1.0).abs() < 1e-9, "{energy}");
    }

    #[test]
    fn no_mixture_pressure_far_from_the_critical_point() {
        let n2 = fluids::embedded("nitrogen").unwrap();
        assert_eq!(Mixture::filling_pressure(n2, RHO, U, 1.0e6, (127.0, 127.0)), None);
    }
}
