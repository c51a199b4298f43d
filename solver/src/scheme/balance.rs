//! The step's budget: its terms ([`StepBudget`]), the total-energy flux through the boundaries,
//! and the sharing of the junctions' dissipated heat among the cells and phases.

use super::{Scheme, StepInput, boundary_conserved};
use crate::case::BoundaryKind;
use crate::model::{BoundaryState, GRAVITY, State};

/// Budget terms of one step (SI, integrated over the step and the line).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepBudget {
    /// Mass entering through the inlet junction, kg (negative: leaving).
    pub mass_in: f64,
    /// Mass leaving through the outlet junction, kg (negative: entering).
    pub mass_out: f64,
    /// Internal-energy flux in at the inlet minus out at the outlet, J.
    pub energy_flux: f64,
    /// Pressure work terms of the phasic energy equations, J.
    pub pressure_work: f64,
    /// Heat from the wall into the fluid, J.
    pub wall_heat: f64,
    /// Heat from the ambient into the wall, J.
    pub ambient_heat: f64,
    /// Kinetic energy the momentum equations turned into heat (friction, form losses, drag and
    /// the donor-cell convection's numerical dissipation), J.
    pub dissipation: f64,
    /// Heat that the boundary junctions' form losses and a choked exit's resistance gave the
    /// fluid leaving the line, J: it leaves with that fluid (part of `total_energy_flux`'s
    /// outflow, not of `dissipation`).
    pub exported_heat: f64,
    /// Energy added by state adjustments outside the balance equations (vanishing-phase
    /// resets and clamps), J, net.
    pub adjustment: f64,
    /// The same adjustments' magnitudes, summed, J.
    pub adjustment_abs: f64,
    /// Magnitude of the kinetic and potential energy carried through the boundaries, J (the
    /// scale of the energy balance where no heat moves).
    pub mechanical_flux_abs: f64,
    /// Total-energy (h + v²/2 + g z) inflow minus outflow through the boundaries, J.
    pub total_energy_flux: f64,
}

impl StepBudget {
    /// Books an adjustment of `joules` made outside the balance equations.
    pub(super) fn adjust(&mut self, joules: f64) {
        self.adjustment += joules;
        self.adjustment_abs += joules.abs();
    }
}

impl Scheme<'_> {
    /// Total energy (h + v²/2 + g z) carried in minus out through the boundaries over the
    /// step, J, and the magnitude of its kinetic and potential parts, J.
    pub(super) fn total_energy_flux(
        &self,
        next: &State,
        dt: f64,
        inlet: &BoundaryState,
        outlet: &BoundaryState,
    ) -> (f64, f64) {
        let g = &self.grid;
        let n = g.n;
        let z_in = 0.0;
        let z_out: f64 = (0..n).map(|i| g.dx[i] * g.sin_cell[i]).sum();
        let grav = if self.physics.gravity { GRAVITY } else { 0.0 };
        let mut total = 0.0;
        let mut mechanical = 0.0;
        for (j, b, z, sign) in [(0usize, inlet, z_in, 1.0), (n, outlet, z_out, -1.0)] {
            let area = g.area_junction[j] * b.open_fraction;
            for gas in [true, false] {
                let v = if gas { next.v_g[j] } else { next.v_l[j] };
                let inflow = sign * v > 0.0;
                let c = if j == 0 { 0 } else { n - 1 };
                let (m, h) = if inflow {
                    let (m, _, _) = boundary_conserved(b, gas);
                    (m, if gas { b.gas.h } else { b.liquid.h })
                } else {
                    // leaving: the cell's new internal energy (the scheme's donor) plus the flow
                    // work against the boundary pressure
                    let (m, e, rho) = if gas {
                        (next.m_g[c], next.e_g[c], next.gas[c].rho)
                    } else {
                        (next.m_l[c], next.e_l[c], next.liquid[c].rho)
                    };
                    (m, if m > 0.0 { e / m } else { 0.0 } + b.p / rho)
                };
                // fluid drawn from a reservoir brings its stagnation enthalpy (it was at rest)
                let ke = if inflow && b.kind == BoundaryKind::Reservoir { 0.0 } else { 0.5 * v * v };
                let mass = dt * v * area * m;
                total += sign * mass * (h + ke + grav * z);
                mechanical += (mass * (ke + grav * z)).abs();
            }
        }
        (total, mechanical)
    }

    /// Cell `i`'s dissipation (W) split between gas and liquid in proportion to their heat
    /// capacities m_k c_p,k.
    pub(super) fn dissipation_split(&self, st: &StepInput, diss: &[f64], i: usize) -> (f64, f64) {
        let total = self.dissipation_share(st, diss, i);
        let Some(fg) = gas_heat_fraction(st.s, i) else { return (0.0, 0.0) };
        (total * fg, total * (1.0 - fg))
    }

    /// Dissipated power (W) that cell `i` receives from its two junctions: each junction's
    /// power per volume times its control volume, shared by the cells it lies in (a boundary
    /// junction's control volume lies wholly in its one cell; [`Scheme::junction_volume`]).
    fn dissipation_share(&self, st: &StepInput, diss: &[f64], i: usize) -> f64 {
        let g = &self.grid;
        let share = |j: usize| -> f64 {
            let vol = self.junction_volume(j, st.inlet1, st.outlet1);
            let inside = if j == 0 || j == g.n { 1.0 } else { 0.5 };
            inside * diss[j] * vol
        };
        share(i) + share(i + 1)
    }
}

/// The gas's share of cell `i`'s heat capacity m_g c_p,g / (m_g c_p,g + m_l c_p,l), by which a
/// cell's dissipation is split between its phases ([`Scheme::dissipation_split`], and its slope
/// in the pressure equation); `None` where the cell holds no heat capacity.
pub(super) fn gas_heat_fraction(s: &State, i: usize) -> Option<f64> {
    let cg = s.m_g[i].max(0.0) * s.gas[i].cp;
    let cl = s.m_l[i].max(0.0) * s.liquid[i].cp;
    (cg + cl > 0.0).then(|| cg / (cg + cl))
}
