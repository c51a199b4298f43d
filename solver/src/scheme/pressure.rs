//! Step 1c–d: the pressure equation — each cell's 4×4 linearised mass and energy system
//! eliminated to one tridiagonal row — its solve, the back-substitution and the new velocities.

use nalgebra::{Matrix4, Vector4};

use super::{
    Rejection, SCALE_PRESSURE_PA, Scheme, StepInput, VOLUME_ERROR_PRESSURE_FRACTION, Work, boundary_conserved, present,
};
use crate::case::BoundaryKind;
use crate::fluids::Phase;
use crate::linalg;
use crate::model::{BoundaryState, State, clamp_to_phase};

impl Scheme<'_> {
    /// Step 1c, the pressure equation: each cell's linearised gas mass, liquid mass, gas energy
    /// and liquid energy equations as a 4×4 system in (δp, δα, δT_g, δT_l) and the neighbouring
    /// pressure changes ([`Scheme::cell_system`]); the first row of its inverse gives the cell's
    /// row of a tridiagonal pressure equation (`w.a`, `w.b`, `w.c`, `w.d`).
    pub(super) fn pressure_equation(&self, st: &StepInput, w: &mut Work) -> Result<(), Rejection> {
        for i in 0..st.n {
            let sys = self.cell_system(st, w, i);
            let Some(minv) = sys.m.try_inverse() else {
                return Err(Rejection {
                    cell: i,
                    variable: "cell",
                    value: st.s.alpha[i],
                    reason: "singular cell system",
                });
            };
            w.minv[i] = minv;
            w.r4[i] = sys.r;
            w.cl[i] = sys.cl;
            w.cr[i] = sys.cr;
            let sol_r = minv * sys.r;
            let sol_l = minv * sys.cl;
            let sol_rr = minv * sys.cr;
            w.a[i] = sol_l[0];
            w.b[i] = 1.0;
            w.c[i] = sol_rr[0];
            w.d[i] = sol_r[0];
        }
        Ok(())
    }

    /// Cell `i`'s linearised mass and energy equations (see [`CellSystem`]): storage terms, the
    /// volume-error correction, the dissipated heat (which it also keeps in `w.heat_g`,
    /// `w.heat_l`), the implicit sources, the donor-cell fluxes with the velocities linear in the
    /// pressure changes, and the rows of an absent phase.
    fn cell_system(&self, st: &StepInput, w: &mut Work, i: usize) -> CellSystem {
        let (g, s, dt) = (&self.grid, st.s, st.dt);
        let v = g.volume[i];
        let (gp, lp) = (&s.gas[i], &s.liquid[i]);
        let a = s.alpha[i];
        let b = 1.0 - a;
        let src = w.sources[i];
        let mut m = Matrix4::zeros();
        // storage terms
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
        // Old-time residuals: the volume-error correction. In a cell nearly full of liquid a
        // small volume error is a large pressure change (liquid is stiff), so at most the
        // part of the error worth VOLUME_ERROR_PRESSURE_FRACTION of the pressure is corrected
        // per step; the rest is corrected over the following steps.
        //
        // Decision: the pressure change the correction implies is the one the storage terms
        // give it, the first component of M⁻¹ r (what the step converges to as Δt → 0), not
        // |e|/κ with the isothermal compressibility κ: the residuals also hold each phase's
        // energy, and at constant energy a phase can be far stiffer. Near the critical point
        // the two part completely: in nitrogen subcooled at 11 atm a trace of vapour (0.09 %
        // of a liquid-full cell at 3.39 MPa, 126 K) has (∂ρ/∂p)_u = ρ κ_T c_v/(∂u/∂T)_p, a
        // small difference of two large terms that the tables' derivatives get even the sign
        // of wrong; its volume error of 2e-4 implied 25 kPa by κ and was 2.8 MPa by the
        // system, at any step length, so the step control rejected every step to 1e-9 s.
        //
        // An absent phase's energy row is the one the solve gives it (`absent_phase_rows`: its
        // temperature follows the other phase, no part of the correction), so that the implied
        // change is the present phase's own at constant energy. Decision: before, the storage
        // matrix of a cell without liquid was singular and |e|/κ stood in; for near-critical
        // vapour alone in a cell (para-hydrogen at 1.282 MPa, 32.95 K, after a near-critical
        // mixture's recovery left a volume error of −0.18) κ put the correction at 25 kPa and the
        // solve made it 1.9 MPa at any step length, and the run ended with its steps halved below
        // 1e-9 s (para-hydrogen subcooled at 11 atm on 120 cells, `calibrated-six.toml`, 2.9 s).
        // Where the matrix is singular even so, κ stands in.
        let kappa = a * gp.drho_dp / gp.rho + b * lp.drho_dp / lp.rho;
        let residual = Vector4::new(
            s.m_g[i] - a * gp.rho,
            s.m_l[i] - b * lp.rho,
            s.e_g[i] - a * gp.rho * gp.u,
            s.e_l[i] - b * lp.rho * lp.u,
        );
        let mut storage = m;
        let mut implied_residual = residual;
        for (present, row) in [(present(s.m_g[i], s.m_l[i]), 2usize), (present(s.m_l[i], s.m_g[i]), 3)] {
            if !present {
                for k in 0..4 {
                    storage[(row, k)] = 0.0;
                }
                storage[(row, row)] = 1.0;
                implied_residual[row] = 0.0;
            }
        }
        let implied = match storage.lu().solve(&implied_residual) {
            Some(x) if x[0].is_finite() => x[0].abs(),
            _ => s.volume_error[i].abs() / kappa.max(1e-300),
        };
        let limit = VOLUME_ERROR_PRESSURE_FRACTION * s.p[i].max(SCALE_PRESSURE_PA);
        let lambda = if implied > limit { limit / implied } else { 1.0 };
        w.corrected[i] = lambda;
        let mut r = lambda * residual;
        // frictional dissipation (from the old velocities; step 2 adds the same heat)
        let (heat_g, heat_l) = self.dissipation_split(s, &w.junction_heat, i);
        w.heat_g[i] = heat_g;
        w.heat_l[i] = heat_l;
        r[2] += dt * heat_g / v;
        r[3] += dt * heat_l / v;
        // sources: row += −dt * source (moved to the left)
        for (row, lin, sign) in [(0, src.gamma, 1.0), (1, src.gamma, -1.0), (2, src.s_g, 1.0), (3, src.s_l, 1.0)] {
            r[row] += sign * dt * lin.c0;
            for k in 0..4 {
                m[(row, k)] -= sign * dt * lin.c[k];
            }
        }
        let mut sys = CellSystem { m, r, cl: Vector4::zeros(), cr: Vector4::zeros() };
        self.cell_fluxes(st, w, i, &mut sys);
        self.absent_phase_rows(s, i, &mut sys);
        sys
    }

    /// The donor-cell fluxes through cell `i`'s left (j = i) and right (j = i + 1) junctions,
    /// each velocity its provisional value plus its pressure weight times the change of the
    /// pressure difference.
    fn cell_fluxes(&self, st: &StepInput, w: &Work, i: usize, sys: &mut CellSystem) {
        let (g, s) = (&self.grid, st.s);
        let v = g.volume[i];
        let CellSystem { m, r, cl, cr } = sys;
        for (j, side) in [(i, -1.0), (i + 1, 1.0)] {
            let area = g.area_junction[j] * self.open_fraction(j, st.inlet1, st.outlet1);
            let f = st.dt * area / v;
            let (ml, mr) = self.donor_pair(s, j, st.inlet0, st.outlet0);
            for (k, (vt, wj)) in [(w.vt_g[j], w.w_g[j]), (w.vt_l[j], w.w_l[j])].into_iter().enumerate() {
                let d = upwind(vt, ml, mr);
                let (mass, energy, frac) = if k == 0 { (d.m_g, d.e_g, d.a_g) } else { (d.m_l, d.e_l, d.a_l) };
                let p_work = s.p[i];
                // rows: mass k, energy k (2 + k)
                for (row, q) in [(k, mass), (2 + k, energy + p_work * frac)] {
                    // side * f * q * (vt + wj (δp_L − δp_R))
                    r[row] -= side * f * q * vt;
                    let c = side * f * q * wj;
                    if side > 0.0 {
                        // right junction: δp_L = δp_i, δp_R = δp_{i+1}
                        m[(row, 0)] += c;
                        cr[row] -= c;
                    } else {
                        // left junction: δp_L = δp_{i-1}, δp_R = δp_i
                        m[(row, 0)] -= c;
                        cl[row] += c;
                    }
                }
            }
        }
    }

    /// An absent phase has no energy equation: its temperature follows the other phase
    /// (within its own table), so that it enters well defined if it flows in.
    fn absent_phase_rows(&self, s: &State, i: usize, sys: &mut CellSystem) {
        let fluid = self.fluid;
        for (present, row, col, phase) in [
            (present(s.m_g[i], s.m_l[i]), 2usize, 2usize, Phase::Gas),
            (present(s.m_l[i], s.m_g[i]), 3, 3, Phase::Liquid),
        ] {
            if !present {
                let target = match phase {
                    Phase::Gas => clamp_to_phase(fluid, Phase::Gas, s.p[i], s.t_l[i]) - s.t_g[i],
                    Phase::Liquid => clamp_to_phase(fluid, Phase::Liquid, s.p[i], s.t_g[i]) - s.t_l[i],
                };
                for k in 0..4 {
                    sys.m[(row, k)] = 0.0;
                }
                sys.m[(row, col)] = 1.0;
                sys.r[row] = target;
                sys.cl[row] = 0.0;
                sys.cr[row] = 0.0;
            }
        }
    }

    /// Step 1d: solves the tridiagonal pressure equation (the boundary pressure changes known)
    /// and back-substitutes each cell's unknowns (δp, δα, δT_g, δT_l) into `w.x`.
    pub(super) fn pressure_solve(&self, st: &StepInput, w: &mut Work) -> Result<(), Rejection> {
        let n = st.n;
        // boundary pressure changes are known
        if !matches!(st.inlet1.kind, BoundaryKind::Velocity | BoundaryKind::Closed) {
            w.d[0] -= w.a[0] * st.dp_in;
        }
        if !matches!(st.outlet1.kind, BoundaryKind::Velocity | BoundaryKind::Closed) {
            w.d[n - 1] -= w.c[n - 1] * st.dp_out;
        }
        if !linalg::tridiagonal(&w.a, &w.b, &w.c, &mut w.d, &mut w.s) {
            return Err(Rejection { cell: 0, variable: "pressure", value: st.dt, reason: "pressure system singular" });
        }
        for i in 0..n {
            let dpl = st.dp_at(i as isize - 1, &w.d);
            let dpr = st.dp_at(i as isize + 1, &w.d);
            w.x[i] = w.minv[i] * (w.r4[i] - w.cl[i] * dpl - w.cr[i] * dpr);
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

    /// Donor quantities on the two sides of junction `j` (boundary states at the ends).
    fn donor_pair(&self, s: &State, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> (Donor, Donor) {
        let n = self.grid.n;
        let cell = |i: usize| Donor {
            m_g: s.m_g[i],
            m_l: s.m_l[i],
            e_g: s.e_g[i],
            e_l: s.e_l[i],
            a_g: s.alpha[i],
            a_l: 1.0 - s.alpha[i],
        };
        let left = if j == 0 { Donor::from_boundary(inlet) } else { cell(j - 1) };
        let right = if j == n { Donor::from_boundary(outlet) } else { cell(j) };
        (left, right)
    }
}

/// One cell's linearised mass and energy equations in its unknowns x = (δp, δα, δT_g, δT_l)
/// and the pressure changes of its neighbours: `m x = r − cl δp_left − cr δp_right`.
#[derive(Debug, Clone, Copy)]
struct CellSystem {
    /// Rows: gas mass, liquid mass, gas energy, liquid energy.
    m: Matrix4<f64>,
    /// Right-hand side.
    r: Vector4<f64>,
    /// Coefficients of the left neighbour's pressure change.
    cl: Vector4<f64>,
    /// Coefficients of the right neighbour's pressure change.
    cr: Vector4<f64>,
}

#[derive(Debug, Clone, Copy)]
struct Donor {
    m_g: f64,
    m_l: f64,
    e_g: f64,
    e_l: f64,
    a_g: f64,
    a_l: f64,
}

impl Donor {
    fn from_boundary(b: &BoundaryState) -> Self {
        let (m_g, e_g, a_g) = boundary_conserved(b, true);
        let (m_l, e_l, a_l) = boundary_conserved(b, false);
        Self { m_g, m_l, e_g, e_l, a_g, a_l }
    }
}

/// The donor (upwind) side of a junction for a given velocity.
#[inline]
fn upwind<T: Copy>(v: f64, left: T, right: T) -> T {
    if v >= 0.0 { left } else { right }
}
