//! Step 1c–d: the pressure equation — each cell's linearised mass and energy equations, with
//! the donors' contents at the new time, one row of a block-tridiagonal system with 4×4
//! blocks — its solve and the new velocities.

use nalgebra::{Matrix4, Vector4};

use super::balance::gas_heat_fraction;
use super::{
    Rejection, SCALE_PRESSURE_PA, Scheme, StepInput, VOLUME_ERROR_PRESSURE_FRACTION, Work, boundary_conserved, present,
};
use crate::fluids::Phase;
use crate::linalg;
use crate::model::{BoundaryState, State, clamp_to_phase};

impl Scheme<'_> {
    /// Step 1c, the pressure equation: each cell's linearised gas mass, liquid mass, gas energy
    /// and liquid energy equations in its unknowns x = (δp, δα, δT_g, δT_l) and its neighbours'
    /// ([`Scheme::cell_system`]), one row of 4×4 blocks of a block-tridiagonal system (`w.blo`,
    /// `w.bdi`, `w.bup`, the right-hand sides in `w.x`, which the solve turns into the unknowns).
    ///
    /// Each cell's storage terms, residuals and corrected share come first
    /// ([`Scheme::storage`]): the donor-cell fluxes take the donors' contents at the new time,
    /// linear in the donor cell's unknowns ([`donor_contents`]). They are of the old state
    /// alone, and kept for the next attempt from it (`w.storage_kept`, as `Work::old_cells`).
    pub(super) fn pressure_equation(&self, st: &StepInput, w: &mut Work) {
        if !w.storage_kept {
            for i in 0..st.n {
                self.storage(st.s, w, i);
            }
            w.storage_kept = true;
        }
        for i in 0..st.n {
            self.cell_system(st, w, i);
        }
    }

    /// Cell `i`'s storage terms (the change of each phase's mass α_k ρ_k and of its energy
    /// α_k ρ_k u_k plus its flow work p δα_k, linear in the cell's unknowns), into `w.storage`;
    /// its residuals (the conserved masses and energies less what its state holds: the volume
    /// error of the last step), into `w.residual`; and the share of them the step corrects,
    /// into `w.corrected`.
    fn storage(&self, s: &State, w: &mut Work, i: usize) {
        let (gp, lp) = (&s.gas[i], &s.liquid[i]);
        let a = s.alpha[i];
        let b = 1.0 - a;
        let mut m = Matrix4::zeros();
        m[(0, 0)] = a * gp.drho_dp;
        m[(0, 1)] = gp.rho;
        m[(0, 2)] = a * gp.drho_dt;
        m[(1, 0)] = b * lp.drho_dp;
        m[(1, 1)] = -lp.rho;
        m[(1, 3)] = b * lp.drho_dt;
        m[(2, 0)] = a * (gp.u * gp.drho_dp + gp.rho * gp.du_dp);
        m[(2, 1)] = gp.rho * gp.h;
        m[(2, 2)] = a * (gp.u * gp.drho_dt + gp.rho * gp.du_dt);
        m[(3, 0)] = b * (lp.u * lp.drho_dp + lp.rho * lp.du_dp);
        m[(3, 1)] = -lp.rho * lp.h;
        m[(3, 3)] = b * (lp.u * lp.drho_dt + lp.rho * lp.du_dt);
        let residual = Vector4::new(
            s.m_g[i] - a * gp.rho,
            s.m_l[i] - b * lp.rho,
            s.e_g[i] - a * gp.rho * gp.u,
            s.e_l[i] - b * lp.rho * lp.u,
        );
        w.storage[i] = m;
        w.residual[i] = residual;
        w.corrected[i] = corrected_share(s, i, &m, &residual);
    }

    /// Cell `i`'s linearised mass and energy equations, its row of the block-tridiagonal
    /// system: storage terms, the volume-error correction, the dissipated heat (which it also
    /// keeps in `w.heat_g`, `w.heat_l`), the implicit sources, the donor-cell fluxes with the
    /// velocities linear in the pressure changes and the donors' contents linear in their
    /// cells' unknowns, and the rows of an absent phase.
    fn cell_system(&self, st: &StepInput, w: &mut Work, i: usize) {
        let (s, dt) = (st.s, st.dt);
        let v = self.grid.volume[i];
        let src = w.sources[i];
        let mut sys = CellSystem {
            lower: Matrix4::zeros(),
            diag: w.storage[i],
            upper: Matrix4::zeros(),
            rhs: w.corrected[i] * w.residual[i],
        };
        // frictional dissipation (from the old velocities; step 2 adds the same heat)
        let (heat_g, heat_l) = self.dissipation_split(st, &w.junction_heat, i);
        w.heat_g[i] = heat_g;
        w.heat_l[i] = heat_l;
        sys.rhs[2] += dt * heat_g / v;
        sys.rhs[3] += dt * heat_l / v;
        self.heat_rows(st, w, i, &mut sys);
        // sources: row += −dt * source (moved to the left)
        for (row, lin, sign) in [(0, src.gamma, 1.0), (1, src.gamma, -1.0), (2, src.s_g, 1.0), (3, src.s_l, 1.0)] {
            sys.rhs[row] += sign * dt * lin.c0;
            for k in 0..4 {
                sys.diag[(row, k)] -= sign * dt * lin.c[k];
            }
        }
        self.cell_fluxes(st, w, i, &mut sys);
        self.absent_phase_rows(s, i, &mut sys);
        w.blo[i] = sys.lower;
        w.bdi[i] = sys.diag;
        w.bup[i] = sys.upper;
        w.x[i] = sys.rhs;
    }

    /// The heat's change with the step's pressure changes, into cell `i`'s energy rows: each of
    /// its junctions' heat linear in the change of the junction's pressure difference
    /// (`w.heat_slope`, the heat's slope in the junction's velocities times their pressure
    /// weights), shared between the cell's phases as [`Scheme::dissipation_split`] shares the
    /// heat.
    ///
    /// Decision: step 2 books the heat of the momentum forces at the new velocities
    /// (`dissipated_heat`), the pressure equation estimated it at the provisional ones; the
    /// difference, first order in the step, went into the volume error. At the exit of the
    /// subcooled nitrogen run (mist at 175 m/s, 100 s) step 2 heated the exit cell's vapour by
    /// 3.2 kJ/m³ a step (of 60 ms) more than the equation had solved for, against 0.7 kJ/m³ less
    /// for the faces' flow work at the new pressure. With both linear in the pressure changes
    /// (the flow work in `cell_fluxes`), one step of 50 ms from the run's state at 100 s
    /// leaves a largest volume error of 2.5e-4, against 1.2e-3 before (each build from its own
    /// run's state; `driver` test `a_step_behind_the_front_leaves_a_small_volume_error`).
    fn heat_rows(&self, st: &StepInput, w: &Work, i: usize, sys: &mut CellSystem) {
        let (n, dt, v) = (st.n, st.dt, self.grid.volume[i]);
        let Some(fg) = gas_heat_fraction(st.s, i) else { return };
        for (row, f) in [(2, fg), (3, 1.0 - fg)] {
            for (j, side) in [(i, -1.0), (i + 1, 1.0)] {
                let inside = if j == 0 || j == n { 1.0 } else { 0.5 };
                let t = dt * f * inside * w.heat_slope[j] * self.junction_volume(j, st.inlet1, st.outlet1) / v;
                if t == 0.0 || !t.is_finite() {
                    continue;
                }
                // rhs += t (δp_L − δp_R), moved to the left
                sys.add_pressure_difference(st, i, side, row, -t);
            }
        }
    }

    /// The donor-cell fluxes through cell `i`'s left (j = i) and right (j = i + 1) junctions:
    /// each velocity its provisional value plus its pressure weight times the change of the
    /// pressure difference, each donor's contents its new-time estimate ([`donor_contents`]),
    /// the product of the two changes dropped.
    fn cell_fluxes(&self, st: &StepInput, w: &Work, i: usize, sys: &mut CellSystem) {
        let (g, s, n) = (&self.grid, st.s, st.n);
        let v = g.volume[i];
        for (j, side) in [(i, -1.0), (i + 1, 1.0)] {
            let area = self.flow_area(j, st.inlet1, st.outlet1);
            let f = st.dt * area / v;
            for (k, (vt, wj)) in [(w.vt_g[j], w.w_g[j]), (w.vt_l[j], w.w_l[j])].into_iter().enumerate() {
                // the donor: the cell upstream of the provisional velocity, or a boundary
                let donor_cell = if vt >= 0.0 { j.checked_sub(1) } else { (j < n).then_some(j) };
                let d = match donor_cell {
                    Some(c) => donor_contents(s, w, c, k),
                    None => {
                        let b = if j == 0 { st.inlet0 } else { st.outlet0 };
                        DonorContents::boundary(b, k == 0)
                    }
                };
                // the flow work p α̂_k of the volume that crosses the face, as step 2 charges it
                // (`Scheme::energy_update`): at the cell's new pressure p + δp_i and the donor's
                // new-time fraction α̂_k + δα̂_k, linear in both changes. Decision: the pressure
                // equation took p and α̂ at the old time, so the energy step 2 gave a phase
                // differed from the one the equation had solved its state for by the step's
                // pressure change times the volume that moved, and by p times the moved
                // fraction's change: a volume error in proportion to the step, not its square
                // (see `Scheme::heat_rows`; BENCHMARKS.md, "The pressure equation's energy as
                // step 2 books it"). Linearising the new pressure alone, without the fraction's
                // change and the heat's slope, took more steps (BENCHMARKS.md, "The flow work at
                // the new pressure").
                let p_work = s.p[i];
                let mut energy_slope = d.energy_slope;
                if donor_cell.is_some() {
                    energy_slope[1] += if k == 0 { p_work } else { -p_work };
                }
                let rows = [(k, d.mass, d.mass_slope), (2 + k, d.energy + p_work * d.fraction, energy_slope)];
                sys.diag[(2 + k, 0)] += side * f * d.fraction * vt;
                for (row, q, slope) in rows {
                    // side * f * (q + slope · x_donor) * (vt + wj (δp_L − δp_R)), the product of
                    // the changes dropped
                    sys.rhs[row] -= side * f * q * vt;
                    sys.add_pressure_difference(st, i, side, row, side * f * q * wj);
                    if let Some(c) = donor_cell {
                        let block = if c == i {
                            &mut sys.diag
                        } else if c < i {
                            &mut sys.lower
                        } else {
                            &mut sys.upper
                        };
                        for col in 0..4 {
                            block[(row, col)] += side * f * vt * slope[col];
                        }
                    }
                }
            }
        }
    }

    /// An absent phase has no energy equation: its temperature follows the other phase
    /// (within its own table), so that it enters well defined if it flows in.
    fn absent_phase_rows(&self, s: &State, i: usize, sys: &mut CellSystem) {
        let fluid = self.fluid;
        for (present, row, phase) in
            [(present(s.m_g[i], s.m_l[i]), 2usize, Phase::Gas), (present(s.m_l[i], s.m_g[i]), 3, Phase::Liquid)]
        {
            if !present {
                let target = match phase {
                    Phase::Gas => clamp_to_phase(fluid, Phase::Gas, s.p[i], s.t_l[i]) - s.t_g[i],
                    Phase::Liquid => clamp_to_phase(fluid, Phase::Liquid, s.p[i], s.t_g[i]) - s.t_l[i],
                };
                for k in 0..4 {
                    sys.diag[(row, k)] = 0.0;
                    sys.lower[(row, k)] = 0.0;
                    sys.upper[(row, k)] = 0.0;
                }
                sys.diag[(row, row)] = 1.0;
                sys.rhs[row] = target;
            }
        }
    }

    /// Step 1d: solves the block-tridiagonal pressure equation (the boundary pressure changes
    /// known) for every cell's unknowns (δp, δα, δT_g, δT_l), into `w.x`.
    pub(super) fn pressure_solve(&self, st: &StepInput, w: &mut Work) -> Result<(), Rejection> {
        let n = st.n;
        if !linalg::block_tridiagonal(&w.blo[..n], &w.bdi[..n], &w.bup[..n], &mut w.x[..n], &mut w.bscr[..n]) {
            return Err(Rejection { cell: 0, variable: "pressure", value: st.dt, reason: "pressure system singular" });
        }
        Ok(())
    }

    /// The new velocities from the provisional ones and the pressure changes (keeping the
    /// pressure changes in `w.dp`): the start of the new state, whose other fields step 2 fills.
    pub(super) fn velocity_update(&self, st: &StepInput, w: &mut Work) -> State {
        let mut next = st.s.clone();
        for (d, x) in w.dp.iter_mut().zip(&w.x) {
            *d = x[0];
        }
        let dps = &w.dp;
        for j in 0..st.n + 1 {
            let dpl = st.dp_at(j as isize - 1, dps);
            let dpr = st.dp_at(j as isize, dps);
            next.v_g[j] = w.vt_g[j] + w.w_g[j] * (dpl - dpr);
            next.v_l[j] = w.vt_l[j] + w.w_l[j] * (dpl - dpr);
        }
        next
    }
}

/// The share of cell `i`'s residuals (`residual`, with its storage terms `storage`) that the
/// step corrects.
///
/// In a cell nearly full of liquid a small volume error is a large pressure change (liquid is
/// stiff), so at most the part of the error worth VOLUME_ERROR_PRESSURE_FRACTION of the pressure
/// is corrected per step; the rest is corrected over the following steps.
///
/// Decision: the pressure change the correction implies is the one the storage terms give it,
/// the first component of M⁻¹ r (what the step converges to as Δt → 0), not |e|/κ with the
/// isothermal compressibility κ: the residuals also hold each phase's energy, and at constant
/// energy a phase can be far stiffer. Near the critical point the two part completely: in
/// nitrogen subcooled at 11 atm a trace of vapour (0.09 % of a liquid-full cell at 3.39 MPa,
/// 126 K) has (∂ρ/∂p)_u = ρ κ_T c_v/(∂u/∂T)_p, a small difference of two large terms that the
/// tables' derivatives get even the sign of wrong; its volume error of 2e-4 implied 25 kPa by κ
/// and was 2.8 MPa by the system, at any step length, so the step control rejected every step to
/// 1e-9 s.
///
/// An absent phase's energy row is the one the solve gives it (`absent_phase_rows`: its
/// temperature follows the other phase, no part of the correction), so that the implied change
/// is the present phase's own at constant energy. Decision: before, the storage matrix of a cell
/// without liquid was singular and |e|/κ stood in; for near-critical vapour alone in a cell
/// (para-hydrogen at 1.282 MPa, 32.95 K, after a near-critical mixture's recovery left a volume
/// error of −0.18) κ put the correction at 25 kPa and the solve made it 1.9 MPa at any step
/// length, and the run ended with its steps halved below 1e-9 s (para-hydrogen subcooled at
/// 11 atm on 120 cells, `calibrated-six.toml`, 2.9 s). Where the matrix is singular even so, κ
/// stands in.
fn corrected_share(s: &State, i: usize, storage: &Matrix4<f64>, residual: &Vector4<f64>) -> f64 {
    let (gp, lp) = (&s.gas[i], &s.liquid[i]);
    let (a, b) = (s.alpha[i], 1.0 - s.alpha[i]);
    let kappa = a * gp.drho_dp / gp.rho + b * lp.drho_dp / lp.rho;
    let mut m = *storage;
    let mut r = *residual;
    for (present, row) in [(present(s.m_g[i], s.m_l[i]), 2usize), (present(s.m_l[i], s.m_g[i]), 3)] {
        if !present {
            for k in 0..4 {
                m[(row, k)] = 0.0;
            }
            m[(row, row)] = 1.0;
            r[row] = 0.0;
        }
    }
    let implied = match m.lu().solve(&r) {
        Some(x) if x[0].is_finite() => x[0].abs(),
        _ => s.volume_error[i].abs() / kappa.max(1e-300),
    };
    let limit = VOLUME_ERROR_PRESSURE_FRACTION * s.p[i].max(SCALE_PRESSURE_PA);
    if implied > limit { limit / implied } else { 1.0 }
}

/// One cell's row of the block-tridiagonal pressure equation:
/// `lower x_{i−1} + diag x_i + upper x_{i+1} = rhs`, x = (δp, δα, δT_g, δT_l).
#[derive(Debug, Clone, Copy)]
struct CellSystem {
    /// Rows: gas mass, liquid mass, gas energy, liquid energy.
    lower: Matrix4<f64>,
    /// See `lower`.
    diag: Matrix4<f64>,
    /// See `lower`.
    upper: Matrix4<f64>,
    /// Right-hand side.
    rhs: Vector4<f64>,
}

impl CellSystem {
    /// Adds `c` (δp_L − δp_R) of cell `i`'s left (`side` −1) or right (+1) junction to the left
    /// side of row `row`: δp_L, δp_R the pressure changes of the junction's two sides, a
    /// boundary's known change (`st.dp_in`, `st.dp_out`) moved to the right-hand side.
    fn add_pressure_difference(&mut self, st: &StepInput, i: usize, side: f64, row: usize, c: f64) {
        if side > 0.0 {
            // right junction: δp_L = δp_i, δp_R = δp_{i+1}
            self.diag[(row, 0)] += c;
            if i + 1 < st.n {
                self.upper[(row, 0)] -= c;
            } else {
                self.rhs[row] += c * st.dp_out;
            }
        } else {
            // left junction: δp_L = δp_{i-1}, δp_R = δp_i
            self.diag[(row, 0)] -= c;
            if i > 0 {
                self.lower[(row, 0)] += c;
            } else {
                self.rhs[row] -= c * st.dp_in;
            }
        }
    }
}

/// What a donor gives one phase's flux through a junction: its mass and internal energy per
/// unit volume at the new time, each its value plus a slope on the donor cell's unknowns, and
/// its volume fraction (for the flow work).
#[derive(Debug, Clone, Copy)]
struct DonorContents {
    mass: f64,
    mass_slope: [f64; 4],
    energy: f64,
    energy_slope: [f64; 4],
    fraction: f64,
}

impl DonorContents {
    /// A boundary's gas (`gas`) or liquid: its conserved quantities, fixed over the step.
    fn boundary(b: &BoundaryState, gas: bool) -> Self {
        let (mass, energy, fraction) = boundary_conserved(b, gas);
        Self { mass, mass_slope: [0.0; 4], energy, energy_slope: [0.0; 4], fraction }
    }
}

/// Cell `c`'s contents of phase `k` (0 gas, 1 liquid) as a donor at the new time: its old mass
/// and energy less the share of its residual the step corrects, plus the storage terms' change
/// with its unknowns — what its own linearised equations give it.
///
/// Decision: the energy a donor carries is α_k ρ_k u_k, its storage row with ρ_k u_k for the
/// change of the fraction (the cell's own equation has ρ_k h_k there, its flow work p δα_k
/// included); the flow work p α_k a flux carries, with its change, is the caller's
/// (`cell_fluxes`). An absent phase's contents are linear in its unknowns too (a trace carried
/// into a liquid-filled cell and on out of it in one step is in both cells' fluxes). With the donors at the old time the
/// volume error of a step was the donor lag of each flux (the donor's contents change over the
/// step while step 2 takes them at the new time), and that error held most of the steps of the
/// NBS runs (BENCHMARKS.md).
fn donor_contents(s: &State, w: &Work, c: usize, k: usize) -> DonorContents {
    let m = &w.storage[c];
    let lambda = w.corrected[c];
    let res = &w.residual[c];
    let row = |r: usize| [m[(r, 0)], m[(r, 1)], m[(r, 2)], m[(r, 3)]];
    if k == 0 {
        let mut energy_slope = row(2);
        energy_slope[1] = s.gas[c].rho * s.gas[c].u;
        DonorContents {
            mass: s.m_g[c] - lambda * res[0],
            mass_slope: row(0),
            energy: s.e_g[c] - lambda * res[2],
            energy_slope,
            fraction: s.alpha[c],
        }
    } else {
        let mut energy_slope = row(3);
        energy_slope[1] = -s.liquid[c].rho * s.liquid[c].u;
        DonorContents {
            mass: s.m_l[c] - lambda * res[1],
            mass_slope: row(1),
            energy: s.e_l[c] - lambda * res[3],
            energy_slope,
            fraction: 1.0 - s.alpha[c],
        }
    }
}
