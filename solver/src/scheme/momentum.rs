//! Step 1a–b: the junctions' momentum equations — their coefficients from the closures, the
//! block-tridiagonal momentum system, the velocity–pressure weights, the provisional velocities
//! — and the heat the momentum forces book ([`booked_heat`]).

use nalgebra::{Matrix2, Vector2};

use super::sources::Sources;
use super::{BLEND_RELAXATION_S, Rejection, Scheme, StepInput, Work, liquid_share};
use crate::case::BoundaryKind;
use crate::closures::presence;
use crate::cryo;
use crate::linalg;
use crate::model::{BoundaryState, GRAVITY, State};

/// Velocity, m/s, over which the cell a phase comes from at a junction goes over from one side
/// to the other ([`Scheme::junction_presence_fractions`]).
const PRESENCE_DONOR_VELOCITY_M_S: f64 = 0.1;

/// Relative change of the relative velocity in the difference that gives the drag's Newton slope.
const NEWTON_DRAG_STEP: f64 = 0.01;

impl Scheme<'_> {
    /// Step 1a, the momentum predictor: the phasic momentum equations of every junction as a
    /// block-tridiagonal system of 2×2 blocks (`w.lower`, `w.diag`, `w.upper`, `w.rhs2`) with
    /// implicit friction, drag, virtual mass, phase-change momentum and donor-cell convection and
    /// the old pressure gradient; a junction whose velocities a boundary prescribes gets an
    /// identity row. Keeps each junction's work-doing coefficients (`w.mech`) and the phase
    /// fractions of its pressure force (`w.alpha_mom`) for step 2.
    pub(super) fn momentum_predictor(&self, st: &StepInput, w: &mut Work) {
        let grav = if self.physics.gravity { GRAVITY } else { 0.0 };
        for j in 0..st.n + 1 {
            w.lower[j] = Matrix2::zeros();
            w.upper[j] = Matrix2::zeros();
            if let Some((vg, vl)) = st.prescribed(j) {
                w.mech[j] = JunctionWork::default();
                w.alpha_mom[j] = None;
                w.diag[j] = Matrix2::identity();
                w.rhs2[j] = Vector2::new(vg, vl);
                continue;
            }
            let s = st.s;
            let jc = match w.old_junctions.get(j) {
                Some(jc) => jc,
                None => {
                    let jc = self.junction_coefficients(st, j, grav);
                    // the step's length and a choked exit's resistance enter only the
                    // boundary junctions' coefficients
                    if j > 0 && j < st.n {
                        w.old_junctions.keep(j, jc);
                    }
                    jc
                }
            };
            let (mut diag, mut rhs) = jc.momentum_block(s.v_g[j], s.v_l[j], st.dt, self.grid.dx_junction(j));
            let gamma = self.phase_change_momentum(st, &w.sources, j, &mut diag, &mut rhs);
            w.mech[j] = self.implicit_convection(st, w, j, &jc, &mut diag);
            w.mech[j].gamma = gamma;
            w.alpha_mom[j] = Some((jc.a_g, jc.a_l));
            w.diag[j] = diag;
            w.rhs2[j] = rhs;
        }
    }

    /// Momentum of the mass that changes phase at junction `j`, added to its block and
    /// right-hand side; returns the junction's Γ, kg/(m³ s) (0 without phase change), whose
    /// kinetic energy `dissipated_heat` reconciles with the continuity equations'.
    ///
    /// The paper's A Γ_g u_i in the vapour's conservative momentum equation and −A Γ_g u_i in the
    /// liquid's are, in the non-conservative form here, Γ_g (v_I − v_g) and −Γ_g (v_I − v_l). With
    /// the interface velocity v_I = (v_g + v_l)/2 (RELAP5's choice) both are −(Γ/2)(v_g − v_l),
    /// the same force on both phases: evaporating liquid leaves at v_I > v_l, so the liquid that
    /// stays slows down, and the vapour that forms at v_I < v_g slows the vapour.
    fn phase_change_momentum(
        &self,
        st: &StepInput,
        sources: &[Sources],
        j: usize,
        diag: &mut Matrix2<f64>,
        rhs: &mut Vector2<f64>,
    ) -> f64 {
        let n = st.n;
        let (vg, vl) = (st.s.v_g[j], st.s.v_l[j]);
        // Decision: v_I the mean, because then the kinetic energy of the two phases changes
        // only by the work of the other forces (−(Γ/2)(v_g² − v_l²) of work against the
        // ½ Γ (v_g² − v_l²) the transferred mass carries); any other v_I dissipates or creates
        // kinetic energy that the energy equations do not see. Γ is the old-time rate of
        // the junction's cells (the mean of the two; a boundary junction's one cell), with
        // an evaporating interface's part depleted over the step (`Sources::momentum_gamma`). Each
        // part is implicit where it damps its own phase's velocity and explicit where it
        // drives it (for evaporation the liquid's own −(Γ/2)(−v_l), for condensation the
        // vapour's). Before, the liquid's term had the drag's sign (+(Γ/2)(v_g − v_l)),
        // which created Γ (v_g − v_l) v_l of kinetic energy.
        let gamma_j = {
            let cell_gamma = |i: usize| sources[i].momentum_gamma;
            match (j == 0, j == n) {
                (true, _) => cell_gamma(0),
                (_, true) => cell_gamma(n - 1),
                _ => 0.5 * (cell_gamma(j - 1) + cell_gamma(j)),
            }
        };
        let mt = if self.physics.phase_change && gamma_j.is_finite() { 0.5 * gamma_j } else { 0.0 };
        // both phases feel −(Γ/2)(v_g − v_l): each part implicit where it damps its own
        // phase's velocity, explicit where it would drive it
        if mt > 0.0 {
            diag[(0, 0)] += mt;
            diag[(0, 1)] -= mt;
            diag[(1, 0)] += mt;
            rhs[1] += mt * vl;
        } else if mt < 0.0 {
            let c = -mt;
            diag[(1, 1)] += c;
            diag[(1, 0)] -= c;
            diag[(0, 1)] += c;
            rhs[0] += c * vg;
        }
        2.0 * mt
    }

    /// Implicit donor-cell convection v^n (v_j − v_up)^{n+1} / dx of junction `j`, added to its
    /// block `diag` and to the off-diagonal blocks `w.lower`, `w.upper`; returns the junction's
    /// work-doing coefficients (friction, drag, and the convection terms whose heat
    /// [`booked_heat`] books).
    ///
    /// Out of a reservoir the fluid starts from rest, and the jump from 0 to v is given its
    /// Bernoulli value ½ ρ v² (the donor-cell form would give ρ v²). Where the flow area changes
    /// between two junctions, the velocity jump is the area ratio and ½ (v_j + v_up) (v_j − v_up)
    /// is the Bernoulli ½ Δ(v²) exactly. (the standard donor-cell terms are kept for the heat
    /// they dissipate, see [`booked_heat`]; the Bernoulli forms dissipate nothing)
    fn implicit_convection(
        &self,
        st: &StepInput,
        w: &mut Work,
        j: usize,
        jc: &JunctionCoefficients,
        diag: &mut Matrix2<f64>,
    ) -> JunctionWork {
        let (g, s, n) = (&self.grid, st.s, st.n);
        let (vg, vl) = (s.v_g[j], s.v_l[j]);
        let dxj = g.dx_junction(j);
        let mut work = JunctionWork {
            inertia: [jc.ar_g, jc.ar_l, jc.vm],
            fric: [jc.fric_g, jc.fric_l],
            boundary_loss: [jc.loss_g, jc.loss_l],
            drag: jc.drag,
            drag_explicit: jc.drag_explicit,
            conv: [None; 2],
            gravity: (j > 0 && j < n).then_some(jc.gx),
            gamma: 0.0,
        };
        for (k, (v, ar)) in [(vg, jc.ar_g), (vl, jc.ar_l)].into_iter().enumerate() {
            let old_v = |jj: usize| if k == 0 { s.v_g[jj] } else { s.v_l[jj] };
            let upstream = if v >= 0.0 { j.checked_sub(1) } else { (j < n).then_some(j + 1) };
            match upstream {
                Some(up) => {
                    let c = if g.area_junction[up] != g.area_junction[j] {
                        ar * (0.5 * (v + old_v(up))).abs() / dxj
                    } else {
                        let c = ar * v.abs() / dxj;
                        // (a phase at rest carries no kinetic energy through the term)
                        work.conv[k] = (c > 0.0).then_some((c, up));
                        c
                    };
                    diag[(k, k)] += c;
                    if up < j {
                        w.lower[j][(k, k)] -= c;
                    } else {
                        w.upper[j][(k, k)] -= c;
                    }
                }
                // out of a reservoir; other boundaries carry the junction's own velocity
                // (no convective acceleration)
                None => {
                    let b = if v >= 0.0 { st.inlet0 } else { st.outlet0 };
                    if b.kind == BoundaryKind::Reservoir {
                        diag[(k, k)] += 0.5 * ar * v.abs() / dxj;
                    }
                }
            }
        }
        work
    }

    /// Step 1b, the velocity–pressure coupling: the new velocity of a junction is its
    /// provisional velocity plus a correction linear in the change of the pressure difference
    /// across it, v = ṽ + w (δp_L − δp_R), the weights `w.w_g`, `w.w_l` through the inverse of
    /// the junction's own 2×2 block (taken before the solve overwrites the right-hand sides);
    /// zero where a boundary prescribes the velocities.
    pub(super) fn pressure_weights(&self, st: &StepInput, w: &mut Work) -> Result<(), Rejection> {
        let g = &self.grid;
        for j in 0..st.n + 1 {
            if st.prescribed(j).is_some() {
                w.w_g[j] = 0.0;
                w.w_l[j] = 0.0;
                continue;
            }
            let (a_g, a_l) = self.junction_alpha(st.s, j, st.inlet0, st.outlet0);
            let dxj = g.dx_junction(j);
            let Some(inv) = w.diag[j].try_inverse() else {
                return Err(Rejection {
                    cell: j,
                    variable: "momentum",
                    value: st.dt,
                    reason: "singular junction block",
                });
            };
            let wv = inv * Vector2::new(a_g / dxj, a_l / dxj);
            w.w_g[j] = wv[0];
            w.w_l[j] = wv[1];
        }
        Ok(())
    }

    /// Solves the momentum system for the provisional velocities `w.vt_g`, `w.vt_l`, and
    /// estimates the heat of the step for the pressure equation (`w.junction_heat`): the work of
    /// the momentum forces with the provisional velocities and the old masses (step 2 books it
    /// with the new ones; the closer the two, the smaller the volume error the difference
    /// leaves).
    pub(super) fn provisional_velocities(&self, st: &StepInput, w: &mut Work) -> Result<(), Rejection> {
        let (g, s) = (&self.grid, st.s);
        if !linalg::block_tridiagonal(&w.lower, &w.diag, &w.upper, &mut w.rhs2, &mut w.scratch2) {
            return Err(Rejection { cell: 0, variable: "velocity", value: st.dt, reason: "momentum system singular" });
        }
        for j in 0..st.n + 1 {
            w.vt_g[j] = w.rhs2[j][0];
            w.vt_l[j] = w.rhs2[j][1];
        }
        let mass = [s.m_g.as_slice(), s.m_l.as_slice()];
        let v0 = [s.v_g.as_slice(), s.v_l.as_slice()];
        for j in 0..st.n + 1 {
            let vt = [w.vt_g.as_slice(), w.vt_l.as_slice()];
            w.junction_heat[j] = booked_heat(&w.mech[j], j, vt, vt, mass, g.dx_junction(j))
                + time_step_loss(&w.mech[j], j, v0, vt, st.dt)
                - exported_heat(&w.mech[j], j, st.n, vt);
            let (dg, dl) = heat_slope(&w.mech[j], j, st.n, vt, v0, mass, g.dx_junction(j), st.dt);
            w.heat_slope[j] = dg * w.w_g[j] + dl * w.w_l[j];
        }
        Ok(())
    }

    /// Junction `j`'s momentum coefficients at the old state (a choked exit's resistance
    /// `st.choke` included).
    fn junction_coefficients(&self, st: &StepInput, j: usize, grav: f64) -> JunctionCoefficients {
        let (s, inlet, outlet, dt) = (st.s, st.inlet0, st.outlet0, st.dt);
        let choke = if j == st.n { st.choke } else { 0.0 };
        let g = &self.grid;
        let ph = &self.physics;
        let n = g.n;
        let js = self.junction_state(s, j, inlet, outlet);
        let (a_g, a_l) = (js.alpha, 1.0 - js.alpha);
        let ar_g = a_g * js.rho_g;
        let ar_l = a_l * js.rho_l;
        let (vg, vl) = (s.v_g[j], s.v_l[j]);
        // the closures see the junction through its donor cell, with the junction's velocities
        let donor = if j == 0 {
            0
        } else if j == n {
            n - 1
        } else if a_g * vg + a_l * vl >= 0.0 {
            j - 1
        } else {
            j
        };
        let mut local = self.local(s, donor);
        local.v_g = vg;
        local.v_l = vl;
        local.alpha = a_g;
        local.d_h = g.d_h_junction(j);
        let cp = &ph.cryo;
        // the map and the closures again at the drag slope's shifted slip below reuse what does
        // not depend on the velocities (bit for bit the same numbers)
        let mut basis = cryo::RegimeBasis::default();
        let slip_free = cryo::SlipFree::new(&local);
        let regime = cryo::flow_regime_cached(&local, cp, s.wall_heat_flux[donor], &mut basis);
        let rough = 0.5 * (g.relative_roughness[j.saturating_sub(1)] + g.relative_roughness[j.min(n - 1)]);
        let (f_g, f_l) = if ph.wall_friction {
            cryo::wall_friction_with(&local, cp, &regime, rough, &slip_free)
        } else {
            (0.0, 0.0)
        };
        let fric = |f: f64, a: f64| if a > 0.0 { f } else { 0.0 };
        let mut fric_g = fric(f_g, a_g);
        let mut fric_l = fric(f_l, a_l);
        // form loss (valve / entrance) at a boundary junction
        let bnd = if j == 0 {
            Some(inlet)
        } else if j == n {
            Some(outlet)
        } else {
            None
        };
        let (p_l, p_r) = (if j == 0 { inlet.p } else { s.p[j - 1] }, if j == n { outlet.p } else { s.p[j] });
        let gx = -grav * g.sin_junction[j];
        let (mut loss_g, mut loss_l) = (0.0, 0.0);
        if let Some(b) = bnd {
            let loss = FormLoss { b, dx: g.dx_junction(j), dt, dp_old: p_r - p_l, gx };
            loss_g = loss.coefficient(ar_g, a_g, vg, fric_g);
            loss_l = loss.coefficient(ar_l, a_l, vl, fric_l);
        }
        // a choked exit's resistance (`choking.rs`), acting like the valve's loss
        loss_g += choke * ar_g;
        loss_l += choke * ar_l;
        fric_g += loss_g;
        fric_l += loss_l;
        let rho_m = a_g * js.rho_g + a_l * js.rho_l;
        let drag_physical =
            if ph.interphase_drag { cryo::interfacial_drag_with(&local, cp, &regime, &slip_free) } else { 0.0 };
        // Newton linearisation of the drag force G(v_r) = F(v_r) v_r about the old relative
        // velocity: G(v_r^{n+1}) ≈ G' v_r^{n+1} + (F − G') v_r^n. The Picard form F(v_r^n) v_r^{n+1}
        // maps v_r^n to v_r^{n+1} with slope −(dlnF/dlnv_r) at equilibrium once the step is long
        // against the drag's relaxation time: the mist's Weber drops (d ∝ v_r⁻², F ∝ v_r³) then
        // oscillate from step to step with growing amplitude, and held the NBS runs to
        // millisecond steps wherever mist left the line. With the Newton form the slope is 0 and
        // the steady state (G = driving force) is unchanged. G' is a one-sided
        // difference in v_r (1 %), used only where the drag grows faster than linearly (G' > F:
        // a weaker growth is stable in the Picard form).
        //
        // Decision: the slope is not bounded above. Where a regime's weight jumps with v_r (mist
        // bordering on annular flow) G' is the drag's growth across that jump, tens of F, and
        // the Newton step holds v_r at the jump as the drag itself does. Bounded at 8 F, the
        // step overshot it: behind the saturated front of the NBS nitrogen run at 2.5 atm the
        // liquid velocity at a junction flickered between 5 and 7.5 m/s from step to step
        // (160–200 s), the front cell held 4.5 kg/m³ of liquid where 5 ms steps leave 2.6, and
        // its first 300 s took 7 022 steps (5 382 without the bound). Without it the station-4
        // chilldown is 301.32 s, and 301.07 and 301.09 s with steps of at most 10 and 5 ms. A
        // bound is a step factor the results moved with (`solver/tests/envelope_regressions.rs`
        // holds the step count).
        //
        // Decision: the shifted drag takes the flow regime at the shifted velocities too. The
        // regime weights follow the slip through the regime quality (the gas's share of the
        // mass flux) and the dryout boundary depends on that quality, so F grows with v_r
        // through them as well: where annular flow borders on mist, a few per cent of mist
        // weight with its 10 µm drops is 45 times the film's drag. With the regime held at
        // the old velocities the slope missed that growth, and the exit junction of
        // para-hydrogen saturated at 11 atm (calibrated-six.toml) flipped between the two drags on
        // alternate steps after its chilldown (quality 0.47 ↔ 0.51, gas velocity 207 ↔ 227
        // m/s): 540 000 steps for 300 s, and an energy residual of −50 W that those steps
        // added up to 3.4e-3 of the wall's heat. With it, 121 000 steps and 3.8e-4; the
        // station-4 chilldown the same to 3 ms.
        let (drag_newton, drag_explicit) = {
            let vr = vg - vl;
            if drag_physical > 0.0 && vr.abs() > 1e-3 {
                let mut shifted = local;
                shifted.v_g = vl + vr * (1.0 + NEWTON_DRAG_STEP);
                let shifted_regime = cryo::flow_regime_cached(&shifted, cp, s.wall_heat_flux[donor], &mut basis);
                let f2 = cryo::interfacial_drag_with(&shifted, cp, &shifted_regime, &slip_free);
                let slope = drag_physical + (f2 - drag_physical) / NEWTON_DRAG_STEP;
                let k = if slope.is_finite() { slope.max(drag_physical) } else { drag_physical };
                (k, (k - drag_physical) * vr)
            } else {
                (drag_physical, 0.0)
            }
        };
        let mut drag = drag_newton;
        // A disappearing phase is tied to the continuous one (phase blending, paper eq.
        // "smoother"). At a junction a phase counts as disappearing when the cell it comes from
        // (nearly) lacks it ([`Scheme::junction_presence_fractions`]): its velocity there is
        // otherwise undetermined by anything physical, and through the convective term it
        // would drag the neighbouring junctions.
        // (the junction's own fractions count too: fluid drawn from a liquid reservoir has no gas)
        let (side_g, side_l) = self.junction_presence_fractions(s, j, &js, (p_r - p_l) / g.dx_junction(j), gx);
        let share_l = if ar_g + ar_l > 0.0 { ar_l / (ar_g + ar_l) } else { a_l };
        let pres = presence(side_g.min(side_l).min(a_g).min(share_l), ph.cryo.blend_min, ph.cryo.blend_max);
        drag += (1.0 - pres) * rho_m / BLEND_RELAXATION_S;
        let vm = if ph.virtual_mass { cryo::virtual_mass_coefficient(&local, cp) * a_g * a_l * rho_m } else { 0.0 };
        JunctionCoefficients {
            a_g,
            a_l,
            ar_g: ar_g.max(1e-9 * rho_m),
            ar_l: ar_l.max(1e-9 * rho_m),
            fric_g,
            fric_l,
            loss_g,
            loss_l,
            drag,
            drag_explicit,
            vm,
            dp_old: p_r - p_l,
            gx,
        }
    }

    fn junction_state(&self, s: &State, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> JunctionState {
        let n = self.grid.n;
        let cell = |i: usize| JunctionState { alpha: s.alpha[i], rho_g: s.gas[i].rho, rho_l: s.liquid[i].rho };
        let bnd = |b: &BoundaryState| JunctionState { alpha: b.alpha, rho_g: b.gas.rho, rho_l: b.liquid.rho };
        if j > 0 && j < n {
            let (l, r) = (cell(j - 1), cell(j));
            let (wl, wr) = (self.grid.dx[j - 1], self.grid.dx[j]);
            let f = wl / (wl + wr);
            return JunctionState {
                alpha: f * l.alpha + (1.0 - f) * r.alpha,
                rho_g: f * l.rho_g + (1.0 - f) * r.rho_g,
                rho_l: f * l.rho_l + (1.0 - f) * r.rho_l,
            };
        }
        // boundary junction: the donor side by the way the mass crosses it (each phase from
        // its own upwind side, as the continuity equations move it), or by the pressure
        // difference when nothing crosses
        let (b, c, inflow_sign) = if j == 0 { (inlet, cell(0), 1.0) } else { (outlet, cell(n - 1), -1.0) };
        let p_cell = s.p[if j == 0 { 0 } else { n - 1 }];
        let flux = boundary_mass_flux(&bnd(b), &c, s.v_g[j], s.v_l[j], inflow_sign);
        let inflow = if flux.abs() > 1e-9 * (c.rho_g + c.rho_l) {
            flux > 0.0
        } else {
            inflow_sign * (if j == 0 { b.p - p_cell } else { p_cell - b.p }) > 0.0
        };
        if inflow && !matches!(b.kind, BoundaryKind::Closed) { bnd(b) } else { c }
    }

    /// Junction gas fraction and phase densities (α, ρ_g, ρ_l), as the momentum equations use
    /// them.
    pub(super) fn junction_densities(
        &self,
        s: &State,
        j: usize,
        inlet: &BoundaryState,
        outlet: &BoundaryState,
    ) -> (f64, f64, f64) {
        let js = self.junction_state(s, j, inlet, outlet);
        (js.alpha, js.rho_g, js.rho_l)
    }

    /// Junction phase fractions for the pressure-gradient term.
    pub(super) fn junction_alpha(
        &self,
        s: &State,
        j: usize,
        inlet: &BoundaryState,
        outlet: &BoundaryState,
    ) -> (f64, f64) {
        let a = self.junction_state(s, j, inlet, outlet).alpha;
        (a, 1.0 - a)
    }

    /// The gas volume fraction and the liquid mass share ([`liquid_share`]) that junction `j`'s
    /// presence weight takes for each phase: those of the cell the phase comes from. That cell is
    /// the upwind one of the phase's old velocity v, blended over `PRESENCE_DONOR_VELOCITY_M_S`
    /// (weights ½ (1 ± tanh(v / PRESENCE_DONOR_VELOCITY_M_S))); what the blend leaves to a
    /// phase at rest goes to the cell the phase's old driving force (the pressure gradient and
    /// gravity on its density) pushes it from, and to the larger of the two where that force is
    /// zero too. A boundary junction's cell decides alone ([`Scheme::junction_min_fractions`]).
    ///
    /// Decision: a phase is tied to the other at a junction where it comes from a cell that
    /// nearly lacks it: there nothing of it crosses, and its velocity is undetermined. The
    /// smaller of the two cells' fractions, taken before, also tied a phase that leaves a cell
    /// holding it: a gas pocket of 1.3 % under a cell with 0.1 % of gas stayed there, its gas
    /// tied to the resting liquid at the junction above (`phases_separate_in_a_closed_tube`,
    /// with the step control set in proportion to the change ratio). The upwind cell alone
    /// switches with the sign of a velocity near zero, and a calibration's cost with it (the
    /// twin experiment of `cli/tests/calibrate.rs` found Gwsc at 0.43 for a truth of 0.6: the
    /// cost near the truth rough, 536 to 1 034 within 2 % of it). The velocity-weighted mean
    /// of both cells at rest, without the force, left the gas at the junction between the
    /// separated liquid (no gas) and the gas above it untied in every other step, flying up at
    /// 9.6 m/s and tied back in the next (a two-step cycle; the liquid column 3.6 % off its
    /// hydrostatic pressure gradient). The blending velocity is numerics: at 0.05 and 0.2 m/s
    /// against 0.1 the six NBS runs' station-4 chilldowns move by at most 0.4 s but for
    /// hydrogen subcooled at 4.2 atm, whose two branches (68.8 and 70.4 s) it lands on by turns.
    ///
    /// `js` is the junction's state, `dpdx` its old pressure gradient and `gx` gravity's
    /// component along it, as its momentum equations take them ([`Scheme::junction_coefficients`]).
    fn junction_presence_fractions(&self, s: &State, j: usize, js: &JunctionState, dpdx: f64, gx: f64) -> (f64, f64) {
        let n = self.grid.n;
        if j == 0 || j == n {
            return self.junction_min_fractions(s, j);
        }
        // the fraction a phase with old velocity v and density rho takes from the left cell
        // (f_l) and the right one (f_r)
        let from_donor = |f_l: f64, f_r: f64, v: f64, rho: f64| {
            let t = (v / PRESENCE_DONOR_VELOCITY_M_S).tanh();
            let force = rho * gx - dpdx;
            if t == 0.0 && force == 0.0 {
                return f_l.max(f_r);
            }
            let pushed = if force == 0.0 { 0.0 } else { force.signum() };
            let d = t + (1.0 - t.abs()) * pushed;
            0.5 * (1.0 + d) * f_l + 0.5 * (1.0 - d) * f_r
        };
        (
            from_donor(s.alpha[j - 1], s.alpha[j], s.v_g[j], js.rho_g),
            from_donor(liquid_share(s, j - 1), liquid_share(s, j), s.v_l[j], js.rho_l),
        )
    }

    /// Smallest gas volume fraction and smallest liquid mass share ([`liquid_share`]) of the two
    /// cells at junction `j` (a boundary junction's one cell): what the step control's velocity
    /// gating takes, and a boundary junction's presence weights.
    pub(super) fn junction_min_fractions(&self, s: &State, j: usize) -> (f64, f64) {
        let n = self.grid.n;
        // at a boundary junction the cell decides: the boundary's composition only describes
        // fluid that would enter
        let (l, r) = match (j == 0, j == n) {
            (true, _) => (0, 0),
            (_, true) => (n - 1, n - 1),
            _ => (j - 1, j),
        };
        (s.alpha[l].min(s.alpha[r]), liquid_share(s, l).min(liquid_share(s, r)))
    }
}

/// Heat that the forces of junction `j`'s momentum equations put into the fluid over a step,
/// per unit volume of the junction's control volume, W/m³: the kinetic energy they took from
/// the flow at the velocities `v1` (gas, liquid), the upstream junctions at `vt` (the velocities
/// of the momentum solve before the pressure correction, which the convective term used), and
/// the donor masses `mass` of the continuity equation's fluxes.
///
/// Decision: every loss of kinetic energy in the discrete momentum equations is heat, booked
/// where it happens, so that the internal-energy equations keep the paper's total energy
/// (internal plus kinetic). With the velocity implicit, a force f changes the kinetic energy by
/// f v¹ Δt less the time-step loss ½ ρ (v¹ − v⁰)². Booked here: wall friction and form losses
/// F (v¹)², the interphase drag's work at v¹ (its Newton part and the blending tie included),
/// and the donor-cell convection c (v_j − v_up) v_j less the kinetic energy ½ m_up |v| Δx⁻¹
/// (v_j² − v_up²) that the continuity equation's mass flux carries (the momentum equation's
/// α ρ is the junction mean, the mass flux the donor cell's): that is its numerical viscosity
/// ½ c (v_j − v_up)² plus the kinetic energy the two disagree about. Friction heat F v⁰ v¹ and
/// the drag's physical part alone, booked before, left 4.2 kJ (saturated 3.4 atm) to 24 kJ
/// (para-hydrogen) of the run's energy unaccounted; a numerical viscosity dissipates like a
/// physical one. The time-step loss ½ ρ (v¹ − v⁰)² is booked beside it ([`time_step_loss`]).
///
/// The potential energy the two disagree about is booked the same way: at an interior
/// junction with gravity component g_x along it, gravity does work α ρ g_x v per unit volume on
/// the momentum equation's junction mean α ρ, while the continuity equation's donor-cell flux
/// m_up v lifts the potential energy by −m_up g_x v; the difference (m_up − α ρ) g_x v is heat.
/// Decision: where a smeared interface moves along gravity, the donor cell holds more of the
/// heavy phase than the junction mean whichever way it moves, so the donor-cell transport
/// lifts liquid for nothing: the frictionless manometer (`Reference::Manometer`) gained 284 J
/// of total energy over 15 s, eight times its initial kinetic energy, before this booking.
pub(super) fn booked_heat(
    m: &JunctionWork,
    j: usize,
    v1: [&[f64]; 2],
    vt: [&[f64]; 2],
    mass: [&[f64]; 2],
    dx_j: f64,
) -> f64 {
    let (g1, l1) = (v1[0][j], v1[1][j]);
    let r1 = g1 - l1;
    let mut heat = m.fric[0] * g1 * g1 + m.fric[1] * l1 * l1 + (m.drag * r1 - m.drag_explicit) * r1;
    for k in 0..2 {
        if let Some((c, up)) = m.conv[k] {
            let (v, v_up, vt_up) = (v1[k][j], v1[k][up], vt[k][up]);
            let cell = if up < j { j - 1 } else { j };
            let carried = mass[k][cell].max(0.0) * v.abs() / dx_j;
            heat += c * (v - vt_up) * v - 0.5 * carried * (v * v - v_up * v_up);
        }
    }
    if let Some(gx) = m.gravity {
        for k in 0..2 {
            let v = v1[k][j];
            let donor = if v >= 0.0 { j - 1 } else { j };
            heat += (mass[k][donor].max(0.0) - m.inertia[k]) * gx * v;
        }
    }
    heat
}

/// The slope of junction `j`'s heat for the pressure equation ([`booked_heat`] plus
/// [`time_step_loss`] less [`exported_heat`], W/m³) in its own gas and liquid velocities at
/// `vt`, W s/m⁴: (∂H/∂v_g, ∂H/∂v_l), the upstream junctions' velocities held.
#[allow(clippy::too_many_arguments)]
pub(super) fn heat_slope(
    m: &JunctionWork,
    j: usize,
    n: usize,
    vt: [&[f64]; 2],
    v0: [&[f64]; 2],
    mass: [&[f64]; 2],
    dx_j: f64,
    dt: f64,
) -> (f64, f64) {
    let (g1, l1) = (vt[0][j], vt[1][j]);
    let r1 = g1 - l1;
    let drag = 2.0 * m.drag * r1 - m.drag_explicit;
    let mut d = [2.0 * m.fric[0] * g1 + drag, 2.0 * m.fric[1] * l1 - drag];
    for k in 0..2 {
        let v = vt[k][j];
        if let Some((c, up)) = m.conv[k] {
            // the upstream junction's velocity, which the estimate takes at `vt` in both places
            let v_up = vt[k][up];
            let cell = if up < j { j - 1 } else { j };
            let mk = mass[k][cell].max(0.0) / dx_j;
            d[k] += c * (2.0 * v - v_up) - 0.5 * mk * (v.signum() * (v * v - v_up * v_up) + 2.0 * v.abs() * v);
        }
        if let Some(gx) = m.gravity {
            let donor = if v >= 0.0 { j - 1 } else { j };
            d[k] += (mass[k][donor].max(0.0) - m.inertia[k]) * gx;
        }
    }
    let (dg, dl) = (vt[0][j] - v0[0][j], vt[1][j] - v0[1][j]);
    let dr = dg - dl;
    d[0] += (m.inertia[0] * dg + m.inertia[2] * dr) / dt;
    d[1] += (m.inertia[1] * dl - m.inertia[2] * dr) / dt;
    let outward = if j == 0 {
        -1.0
    } else if j == n {
        1.0
    } else {
        0.0
    };
    for k in 0..2 {
        let v = vt[k][j];
        if outward * v > 0.0 {
            d[k] -= 2.0 * m.boundary_loss[k] * v;
        }
    }
    (d[0], d[1])
}

/// Kinetic energy that junction `j`'s implicit inertia loses over a step of `dt` from the
/// velocities `v0` to `v1`, as heat per unit volume of its control volume, W/m³: ½ α_k ρ_k
/// (v_k¹ − v_k⁰)² for each phase and ½ C_vm (v_r¹ − v_r⁰)² for the virtual mass of the relative
/// velocity, with the inertia coefficients of the junction's momentum block.
///
/// Decision: booked as heat, like the donor-cell convection's numerical viscosity. With the
/// velocity implicit a force f changes the kinetic energy by f v¹ Δt less this loss, which the
/// heat of the forces ([`booked_heat`]) does not contain. Where the velocities settle it is
/// small (0.03–0.2 kJ over the NBS runs), but where they swing from step to step it is not: the
/// flashing outflow of para-hydrogen saturated at 11 atm (`examples/nbs/calibrated-six.toml`,
/// liquid and vapour leaving at 100–190 m/s, their velocities changing at every step of a
/// fraction of a millisecond) lost about 120 W of it for the 270 s after its chilldown: the
/// run's residual was −44.8 kJ by 300 s (an energy balance error of 1.2e-2), with the loss
/// booked −12.4 kJ (3.4e-3).
pub(super) fn time_step_loss(m: &JunctionWork, j: usize, v0: [&[f64]; 2], v1: [&[f64]; 2], dt: f64) -> f64 {
    let dg = v1[0][j] - v0[0][j];
    let dl = v1[1][j] - v0[1][j];
    let dr = dg - dl;
    0.5 * (m.inertia[0] * dg * dg + m.inertia[1] * dl * dl + m.inertia[2] * dr * dr) / dt
}

/// The part of a boundary junction's heat ([`booked_heat`], W/m³ of its control volume) that
/// the fluid leaving the line takes with it: the work of its form loss and of a choked exit's
/// resistance on each phase that flows out through it, F_loss v².
///
/// Decision: a valve, an entrance or a choked exit's expansion at the end of the line throttles
/// the fluid that passes it; the kinetic energy the throttle destroys heats the fluid downstream
/// of it, which keeps its stagnation enthalpy. Flowing in, that fluid is the first or last
/// cell's, where the heat stays booked. Flowing out, it is no longer in the line: the heat leaves
/// with it, through the boundary's total-energy flux (`Scheme::step`), instead of heating the
/// cell it came from. Before, an exit valve of 50 velocity heads at the end of the saturated
/// 3.4 atm NBS line heated the exit cell's vapour from 294 to 350 K by 96 s (the outflow's
/// K v²/2, 65 kJ/kg at 51 m/s, booked in the cell) and the wall under it to 341 K, and the run
/// ended with the vapour's energy above its table; the vapour venting back into the dewar
/// through the inlet valve heated the inlet cell the same way.
pub(super) fn exported_heat(m: &JunctionWork, j: usize, n: usize, v1: [&[f64]; 2]) -> f64 {
    let outward = if j == 0 {
        -1.0
    } else if j == n {
        1.0
    } else {
        return 0.0;
    };
    let mut heat = 0.0;
    for k in 0..2 {
        let v = v1[k][j];
        if outward * v > 0.0 {
            heat += m.boundary_loss[k] * v * v;
        }
    }
    heat
}

/// A junction's momentum coefficients that do work on the flow (per unit volume), kept from
/// step 1 to book that work as heat in step 2.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct JunctionWork {
    /// Inertia of the gas and the liquid (the junction's α ρ) and of the relative velocity (the
    /// virtual-mass coefficient), kg/m³.
    inertia: [f64; 3],
    /// Wall friction and form-loss coefficients, N s/m⁴.
    fric: [f64; 2],
    /// The part of `fric` that acts where the line ends: a boundary junction's form loss
    /// (valve, entrance) and a choked exit's resistance, N s/m⁴ ([`exported_heat`]).
    boundary_loss: [f64; 2],
    /// Implicit drag coefficient (physical slope and blending tie), N s/m⁴.
    drag: f64,
    /// Explicit part of the Newton-linearised drag, N/m³.
    drag_explicit: f64,
    /// Gas and liquid donor-cell convection: the coefficient α ρ |v| / Δx (junction mean α ρ),
    /// kg/(m³ s), and the upstream junction; `None` where the term has a Bernoulli form or there
    /// is no upstream junction.
    conv: [Option<(f64, usize)>; 2],
    /// The gravity component along an interior junction, m/s² (`None` at the boundaries).
    gravity: Option<f64>,
    /// The junction's Γ in the phase-change momentum, kg/(m³ s) (0 without phase change).
    pub(super) gamma: f64,
}

#[derive(Debug, Clone, Copy)]
struct JunctionState {
    alpha: f64,
    rho_g: f64,
    rho_l: f64,
}

/// The mass flux into the line through a boundary junction, kg/(m² s), with the phase
/// velocities `v_g`, `v_l` (positive along the line) and each phase taken from its own upwind
/// side: the boundary's `b` where that phase enters, the end cell's `c` where it leaves.
/// `inflow_sign` is +1 at the inlet, −1 at the outlet (where entering is against the line).
///
/// Decision: the side whose state the boundary junction's momentum equations take is the one
/// the mass comes from, as the continuity equations move it, not the side of the mixture
/// velocity weighted by the end cell's fractions. The two part in counter-current flow at a
/// liquid reservoir: in the chugging inlet of para-hydrogen saturated at 1.5 atm the few drops
/// left in the vapour-filled inlet cell drained back into the dewar while the vapour was pushed
/// into the line. By the mixture velocity (the vapour's) the junction took the dewar's pure
/// liquid, which tied the absent gas to the liquid's backflow; that reversed the mixture
/// velocity, the next step took the cell's vapour, which the pressure drove forward again — the
/// gas velocity flipped on alternate steps and the 25 % rule held the run to 0.1 ms steps for
/// seconds at a time. What crosses the junction there is the liquid going back (the dewar has
/// no vapour to send), so the cell is the donor whichever way the absent gas is pushed.
/// Measured (BENCHMARKS.md, "The inlet junction's donor by what crosses it"): that run takes
/// 44 084 steps instead of 57 285 at the defaults; the one-ulp spread of the NBS subcooled
/// nitrogen run is the same (largest moves of eight closure values 0.62–1.39 s against
/// 0.47–1.42 s), and that of the
/// NBS subcooled hydrogen 2.5 atm run at `calibrated-six.toml` falls from 1.80 to 0.16 s. On a
/// 10-cell copy of the subcooled nitrogen case the spread widens (standard deviation 0.43 s
/// against 0.07 s): its 6 m inlet cell geysers differently, which is why the twin calibration of
/// the test suite is made on a saturated run.
fn boundary_mass_flux(b: &JunctionState, c: &JunctionState, v_g: f64, v_l: f64, inflow_sign: f64) -> f64 {
    let (u_g, u_l) = (inflow_sign * v_g, inflow_sign * v_l);
    let gas = if u_g > 0.0 { b.alpha * b.rho_g } else { c.alpha * c.rho_g };
    let liquid = if u_l > 0.0 { (1.0 - b.alpha) * b.rho_l } else { (1.0 - c.alpha) * c.rho_l };
    gas * u_g + liquid * u_l
}

/// Per junction: its [`JunctionCoefficients`] at the old state where neither the step's length
/// nor a choked exit's resistance enters them (the junctions inside the line), kept from one
/// attempt at a step to the next from the same state (`Work::old_state`).
#[derive(Debug, Clone, Default)]
pub(super) struct OldJunctions {
    kept: Vec<Option<JunctionCoefficients>>,
}

impl OldJunctions {
    /// Forgets every junction's coefficients (another state), for `nj` junctions.
    pub(super) fn clear(&mut self, nj: usize) {
        self.kept.clear();
        self.kept.resize(nj, None);
    }

    fn get(&self, j: usize) -> Option<JunctionCoefficients> {
        self.kept.get(j).copied().flatten()
    }

    fn keep(&mut self, j: usize, jc: JunctionCoefficients) {
        if let Some(k) = self.kept.get_mut(j) {
            *k = Some(jc);
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct JunctionCoefficients {
    a_g: f64,
    a_l: f64,
    ar_g: f64,
    ar_l: f64,
    fric_g: f64,
    fric_l: f64,
    /// The part of `fric_g`, `fric_l` that acts where the line ends (a boundary junction's
    /// valve or entrance loss and a choked exit's resistance), N s/m⁴.
    loss_g: f64,
    loss_l: f64,
    /// Implicit interphase drag coefficient (the Newton slope of the physical drag plus the
    /// phase-blending tie), N s/m⁴.
    drag: f64,
    /// Explicit part of the Newton-linearised drag on the gas, (G' − F) v_r^n, N/m³ (the liquid
    /// gets its negative).
    drag_explicit: f64,
    vm: f64,
    dp_old: f64,
    gx: f64,
}

impl JunctionCoefficients {
    /// The junction's 2×2 momentum block and right-hand side before the phase-change momentum
    /// and the convection terms: inertia, friction, drag (its Newton part explicit), virtual mass
    /// (its time-derivative term), the old pressure gradient and gravity, for the old velocities
    /// `vg`, `vl`, the step `dt` and the junction's length `dxj`.
    fn momentum_block(&self, vg: f64, vl: f64, dt: f64, dxj: f64) -> (Matrix2<f64>, Vector2<f64>) {
        let jc = self;
        let drag = jc.drag;
        let diag = Matrix2::new(
            jc.ar_g / dt + jc.fric_g + drag + jc.vm / dt,
            -drag - jc.vm / dt,
            -drag - jc.vm / dt,
            jc.ar_l / dt + jc.fric_l + drag + jc.vm / dt,
        );
        let rhs = Vector2::new(
            jc.ar_g * vg / dt + jc.vm / dt * (vg - vl) - jc.a_g * jc.dp_old / dxj + jc.ar_g * jc.gx + jc.drag_explicit,
            jc.ar_l * vl / dt - jc.vm / dt * (vg - vl) - jc.a_l * jc.dp_old / dxj + jc.ar_l * jc.gx - jc.drag_explicit,
        );
        (diag, rhs)
    }
}

/// The form loss of a boundary junction (valve, entrance): K ρ v|v| / (2 dx), the valve closing
/// the area scaling K with 1/open² (plus the sudden-contraction term (1/open − 1)²).
struct FormLoss<'b> {
    b: &'b BoundaryState,
    /// The junction's length, m.
    dx: f64,
    dt: f64,
    /// Old pressure difference across the junction (right − left), Pa.
    dp_old: f64,
    /// Gravity along the junction, m/s².
    gx: f64,
}

impl FormLoss<'_> {
    /// The loss coefficient of one phase, N s/m⁴ per unit volume (the coefficient of v^{n+1}
    /// in its momentum equation), for the phase's `ar` = αρ, volume fraction `a`, old velocity
    /// `v` and the friction coefficient `fric` it already has.
    ///
    /// Decision: the loss is linearised about the speed v* that solves the junction's own
    /// momentum balance with the loss implicit,
    ///   (αρ/Δt + F) v* + c v*|v*| = |αρ vⁿ/Δt − α Δpⁿ/dx + αρ g_x|,   c = K αρ / (2 dx),
    /// rather than about the old speed |vⁿ|. About |vⁿ| the loss vanishes where the fluid is at
    /// rest: the first step through a valve 0.05 % open accelerated the liquid to 7 m/s, which
    /// the next step, now seeing K ≈ 10⁷, threw back to rest (on 480 cells the 25 % rule then
    /// rejected every step length); and on long steps the old-speed form maps v to
    /// (Δp/dx)/(c v), a two-step oscillation. v* tends to |vⁿ| as Δt → 0, so the scheme's
    /// consistency is unchanged; where the loss dominates, the step gives the quasi-steady
    /// speed √(2 Δp / (K ρ)).
    fn coefficient(&self, ar: f64, a: f64, v: f64, fric: f64) -> f64 {
        let open = self.b.open_fraction.max(1e-6);
        let k = self.b.loss / (open * open) + if open < 1.0 { (1.0 / open - 1.0).powi(2) } else { 0.0 };
        let c = k * ar / (2.0 * self.dx);
        let inertia = ar / self.dt + fric;
        let drive = (ar * v / self.dt - a * self.dp_old / self.dx + ar * self.gx).abs();
        let speed = 2.0 * drive / (inertia + (inertia * inertia + 4.0 * c * drive).sqrt());
        c * if speed.is_finite() { speed } else { v.abs() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The heat's slope is the derivative of the heat the pressure equation estimates
    /// (`provisional_velocities`): central differences in each phase's velocity, at an interior
    /// junction with convection and gravity and at an exit with its form loss.
    #[test]
    fn the_heat_slope_is_the_heats_derivative() {
        let m = JunctionWork {
            inertia: [1.3, 640.0, 12.0],
            fric: [4.0, 90.0],
            boundary_loss: [1.5, 30.0],
            drag: 250.0,
            drag_explicit: 40.0,
            conv: [Some((55.0, 1)), Some((210.0, 1))],
            gravity: Some(-3.2),
            gamma: 0.0,
        };
        let (dt, dx) = (0.04, 2.0);
        let mass = [vec![1.1, 1.4, 1.2], vec![300.0, 420.0, 380.0]];
        let mass = [mass[0].as_slice(), mass[1].as_slice()];
        let v0 = [vec![8.0, 9.5, 11.0, 11.8], vec![2.0, 2.4, 3.1, 3.2]];
        let v0 = [v0[0].as_slice(), v0[1].as_slice()];
        for (j, n, m) in [(2, 3, m), (3, 3, JunctionWork { conv: [None, None], gravity: None, ..m })] {
            let base = [vec![8.3, 9.9, 11.6, 12.0], vec![2.2, 2.6, 3.3, 3.5]];
            let heat = |vt: [&[f64]; 2]| {
                booked_heat(&m, j, vt, vt, mass, dx) + time_step_loss(&m, j, v0, vt, dt) - exported_heat(&m, j, n, vt)
            };
            let vt = [base[0].as_slice(), base[1].as_slice()];
            let slope = heat_slope(&m, j, n, vt, v0, mass, dx, dt);
            for k in 0..2 {
                let h = 1e-4;
                let at = |d: f64| {
                    let mut v = base.clone();
                    v[k][j] += d;
                    heat([v[0].as_slice(), v[1].as_slice()])
                };
                let numeric = (at(h) - at(-h)) / (2.0 * h);
                let analytic = if k == 0 { slope.0 } else { slope.1 };
                assert!(
                    (numeric - analytic).abs() <= 1e-6 * numeric.abs().max(1.0),
                    "junction {j}, phase {k}: {analytic} against {numeric}"
                );
            }
        }
    }
}
