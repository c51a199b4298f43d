//! The new thermodynamic state from the conserved variables: pressure, phase masses,
//! temperatures (with the trace resets booked in the budget), void fraction and volume error.

use super::mixture::{Mixture, NEAR_CRITICAL_FRACTION, NearCritical, table_edge};
use super::{
    EdgeMove, MAX_VOLUME_ERROR, PRESENT_MASS_FRACTION, Rejection, Scheme, StepBudget, StepInput, TRACE_RESET_FRACTION,
    Work, new_pressure, refill, saturation_or_none,
};
use crate::fluids::{FluidTable, Phase, PhaseProps};
use crate::model::{State, clamp_to_range};

impl Scheme<'_> {
    /// The new thermodynamic state from the conserved variables: each cell's new pressure
    /// (checked against the property table), its phase masses (a negative one rejects the step)
    /// and the phases' temperatures from their energies ([`Recovery::phase`]); returns the
    /// largest |volume error| over the cells.
    pub(super) fn state_recovery(
        &self,
        st: &StepInput,
        w: &mut Work,
        next: &mut State,
        budget: &mut StepBudget,
    ) -> Result<f64, Rejection> {
        for i in 0..st.n {
            w.refilled[i] = false;
            // only a retried step's cell that the rejected step found over its limit may be
            // refilled (`refill_wanted`), and a cell the step before recovered as one mixture
            // (`mixed_before`, `mixed_again_wanted`): only there is what it held before kept
            let before = (w.volume_retry.over_before(st.s.time, i) || mixed_before(st, i))
                .then(|| Before::take(next, budget, i));
            self.recover_or_mix(st, w, next, budget, i)?;
            if let Some(before) = before
                && (refill_wanted(st, w, next, i) || mixed_again_wanted(st, w, next, i))
            {
                self.refill(st, w, next, budget, i, &before)?;
            }
        }
        for c in self.outflow_work_correction(st, w, next, budget).into_iter().flatten() {
            let (merged, reset, reset_volume, edge) = (w.merged[c], w.reset[c], w.reset_volume[c], w.edge[c]);
            self.recover_or_mix(st, w, next, budget, c)?;
            w.merged[c] |= merged;
            w.reset[c] |= reset;
            // the first recovery's edge change already moved its mass: the volume it made is
            // still in the error, and its mass in the void fraction
            w.reset_volume[c] += reset_volume;
            w.edge[c] += edge;
        }
        for i in 0..st.n {
            if w.merged[i] && !w.mixture[i] && !w.refilled[i] && next.volume_error[i].abs() > MAX_VOLUME_ERROR {
                self.refill_merged(st, w, next, budget, i);
            }
        }
        next.mixture.clear();
        next.mixture.extend_from_slice(&w.mixture[..st.n]);
        Ok(next.volume_error.iter().fold(0.0, |m: f64, e| m.max(e.abs())))
    }

    /// The flow work of the fluid leaving through a boundary, at the volume it actually
    /// occupies: adds to the energies of a boundary cell's outflowing phases the difference
    /// between the flow work the energy equations booked (the boundary pressure times the
    /// provisional volume of step 2, `flux_volume`) and the boundary pressure times the volume
    /// of the mass that left at the phase's recovered density; returns the cells so corrected
    /// (the inlet's, the outlet's), which the caller recovers again.
    ///
    /// Decision: the provisional densities are the old state's linearised in the step's changes,
    /// exact only as the step vanishes. Inside the line the volume a junction moves is the same
    /// for the cells on either side (and the work-consistency term squares it with the momentum
    /// equations), so its error only shares the flow work out differently; at a boundary the
    /// fluid is gone and carries the flow work p_b m / ρ of its true volume. The nitrogen line
    /// saturated at 11 atm, where the front's flashing reaches the exit (25–65 s), booked 5.1 kJ
    /// more flow work out than left with the fluid: an energy balance error of 1.4e-3 that
    /// vanished with steps below 0.02 s.
    fn outflow_work_correction(
        &self,
        st: &StepInput,
        w: &Work,
        next: &mut State,
        budget: &mut StepBudget,
    ) -> [Option<usize>; 2] {
        let (g, s, dt, n) = (&self.grid, st.s, st.dt, st.n);
        let mut corrected = [None; 2];
        for (k, (j, c, b, sign)) in [(0, 0, st.inlet1, -1.0), (n, n - 1, st.outlet1, 1.0)].into_iter().enumerate() {
            let area = self.flow_area(j, st.inlet1, st.outlet1);
            let mut touched = false;
            for gas in [true, false] {
                let v = if gas { next.v_g[j] } else { next.v_l[j] };
                if sign * v <= 0.0 {
                    continue;
                }
                let dvol: &[f64] = if gas { &w.dvol_g } else { &w.dvol_l };
                let vel: &[f64] = if gas { &next.v_g } else { &next.v_l };
                let booked = sign * self.flux_volume(s, dvol, gas, vel, j, dt, st.inlet1, st.outlet1);
                let (m, rho) = if gas { (next.m_g[c], next.gas[c].rho) } else { (next.m_l[c], next.liquid[c].rho) };
                let actual = dt * v.abs() * area * m.max(0.0) / rho;
                let work = b.p * (booked - actual);
                if work != 0.0 && work.is_finite() {
                    // the work enters the cell's energy equation, whose donor-cell outflow
                    // carries part of it on: the diagonal of the conservative step's transport
                    // matrix (`transport_matrix`) shares it between the cell and its outflow
                    let out = self.cell_outflow(vel, c, dt, st.inlet1, st.outlet1);
                    let de = work / (g.volume[c] + out);
                    if gas {
                        next.e_g[c] += de;
                    } else {
                        next.e_l[c] += de;
                    }
                    budget.pressure_work += work;
                    budget.energy_flux -= de * out;
                    touched = true;
                }
            }
            // one cell line: its inlet and outlet are the same cell, recovered once
            if touched && !(k == 1 && corrected[0] == Some(c)) {
                corrected[k] = Some(c);
            }
        }
        corrected
    }

    /// Recovers cell `i` again at the pressure at which its phases fill it
    /// ([`refill::filling_pressure`]), from the masses and energies and the budget it had before
    /// its first recovery (`before`); where there is no such pressure nearby, or
    /// the recovery there resets a phase, the cell is recovered as one fluid near the critical
    /// point ([`Scheme::near_critical_mixture`], from 0.98 to 1.1 times the critical pressure),
    /// and elsewhere the first recovery stands.
    ///
    /// Decision: just above the critical pressure the refill can find no pressure: the
    /// para-hydrogen line subcooled at 11 atm (defaults, 20 cells, the drag's Newton slope
    /// unbounded) had a cell at 1.2966 MPa whose "liquid" (30.4 kg per m³ of cell at 249.4 kJ/kg)
    /// was at the critical density beside gas at 47 K, underfilled by 4.8e-3; it fills only
    /// below the critical pressure, where that energy lies above the liquid table's top at every
    /// pressure, so the volume balance has no value on that side, and the run ended at 7.98 s
    /// with its steps halved below 1e-9 s. Above the critical pressure the two are one fluid.
    ///
    /// Decision: this is for a retry whose volume error in the cell did not shrink with the
    /// step (`refill_wanted`), where the error is the linearised correction's nonlinearity and
    /// no step length removes it (the rule of [`acceptance::volume_error_check`] accepts such an
    /// error, and near the critical point the next correction made another as large, at any
    /// step length). Elsewhere the volume error is the step's accuracy control and stays so.
    /// The pressure so found is the cell's new pressure, as if the pressure solve had given it:
    /// the velocities of the step are those of the solve, and the following steps' pressure
    /// equations start from a cell without a volume error.
    fn refill(
        &self,
        st: &StepInput,
        w: &mut Work,
        next: &mut State,
        budget: &mut StepBudget,
        i: usize,
        before: &Before,
    ) -> Result<(), Rejection> {
        let x0 = w.x[i][0];
        if let Some(p) =
            refill::filling_pressure(self.fluid, &cell_contents(next, i), next.p[i], refill::MAX_RELATIVE_MOVE)
        {
            before.restore(next, budget, i);
            w.x[i][0] = p - st.s.p[i];
            let again = self.recover_or_mix(st, w, next, budget, i);
            if again.is_ok() && refillable(w, next, i) {
                w.refilled[i] = true;
                return Ok(());
            }
            before.restore(next, budget, i);
            w.x[i][0] = x0;
        } else {
            before.restore(next, budget, i);
        }
        // near the critical point the cell as one mixture, else the first recovery stands
        // (recovered again: it depends only on what is restored)
        if self.near_critical_mixture(st, w, next, i, NearCritical::EitherSide).is_some() {
            return Ok(());
        }
        self.recover_or_mix(st, w, next, budget, i)
    }

    /// Recovers cell `i`, whose recovery has just merged a phase into the other (`w.merged`)
    /// with a volume error above `MAX_VOLUME_ERROR`, again at the pressure at which its merged
    /// contents fill it ([`refill::filling_pressure`], within `refill::MAX_RELATIVE_MOVE` of
    /// the pressure solve's), or, near the critical point where the phases alone fill it at no
    /// pressure within reach, as one mixture at the pressure at which the mixture fills it
    /// ([`Mixture::filling_pressure`], [`Scheme::near_critical_mixture`]).
    /// The cell stays exempt from the volume-error check and the change control (the merge is
    /// not a function of the step). Where neither exists, or the recovery at the pressure
    /// found leaves a larger error (or, in the first case, is one mixture), the merged contents'
    /// filling pressure is sought farther off, within `refill::MERGED_MAX_RELATIVE_MOVE`; where
    /// that fails as well, the first recovery stands.
    ///
    /// Decision: the volume a merge leaves is not the step's linearisation error, and it was left
    /// to the following steps' pressure equations; near the critical point they do not remove it.
    /// Nitrogen at 3.4–3.5 MPa (just above its critical pressure) in the inlet cell of the
    /// subcooled 4.2 atm case (robustness sample 2 of seed 1, a first-contact surge with the
    /// drops' enhancement of the vapour's wall convection at gain 5.8) merged 93 % of the cell's
    /// volume, its "gas", into the liquid, and left the liquid filling 90 % of the cell. Every
    /// following correction, limited to 2 % of the pressure, moved the pressure up and down by
    /// 70 kPa in turn without shrinking the error; each step that grew it was rejected and its
    /// retry merged a new trace of gas (exempt, so accepted), so the steps halved every third
    /// attempt to below 1e-9 s at 1.67 s. That fluid (230.6 kg/m³ at 30.9 kJ/kg, 127.1 K) fills
    /// its cell at no pressure as one phase: at that energy the tables' density lies between 251
    /// and 265 kg/m³ from the critical pressure to 3.53 MPa, and below the critical pressure
    /// the energy lies between the phase tables. As saturated liquid and vapour it fills its
    /// cell at 3.27 MPa, 0.963 of the critical pressure. The filling pressure keeps mass and
    /// energy exactly.
    ///
    /// Where a merge leaves less than `MAX_VOLUME_ERROR` the error stays for the following
    /// pressure equations, as before: the NBS nitrogen runs, whose merges all do, are unchanged
    /// bit for bit. The NBS hydrogen runs refill 37–58 more cells, their largest volume error
    /// falls from 3.4–6.5e-3 to 2.0–3.3e-3, and their station-4 chilldown moves by 0.3 % at most.
    fn refill_merged(&self, st: &StepInput, w: &mut Work, next: &mut State, budget: &mut StepBudget, i: usize) {
        let merged = MergedCell::take(next, w, budget, i);
        let contents = cell_contents(next, i);
        let p0 = next.p[i];
        let improved = |w: &Work, next: &State, kept: bool| {
            kept && !w.mixture[i] && next.volume_error[i].abs() < merged.volume_error()
        };
        let near = match refill::filling_pressure(self.fluid, &contents, p0, refill::MAX_RELATIVE_MOVE) {
            Some(p) => {
                w.x[i][0] = p - st.s.p[i];
                let again = self.recover_or_mix(st, w, next, budget, i);
                improved(w, next, again.is_ok())
            }
            None => {
                let m = next.m_g[i] + next.m_l[i];
                let u = (next.e_g[i] + next.e_l[i]) / m;
                let guesses = (next.t_g[i], next.t_l[i]);
                Mixture::filling_pressure(self.fluid, m, u, p0, guesses).is_some_and(|p| {
                    w.x[i][0] = p - st.s.p[i];
                    self.near_critical_mixture(st, w, next, i, NearCritical::Filled).is_some()
                        && next.volume_error[i].abs() < merged.volume_error()
                })
            }
        };
        // where neither lies near, the merged contents' filling pressure farther off
        let kept = near || {
            merged.restore(next, w, budget, i);
            refill::filling_pressure(self.fluid, &contents, p0, refill::MERGED_MAX_RELATIVE_MOVE).is_some_and(|p| {
                w.x[i][0] = p - st.s.p[i];
                let again = self.recover_or_mix(st, w, next, budget, i);
                improved(w, next, again.is_ok())
            })
        };
        if kept {
            w.merged[i] = true;
            w.reset[i] = true;
            w.reset_volume[i] = next.volume_error[i];
            w.edge[i] += merged.edge;
            w.refilled[i] = true;
        } else {
            merged.restore(next, w, budget, i);
        }
    }

    /// Recovers cell `i` ([`Scheme::recover_cell`]), or, where that fails near the critical
    /// point, recovers its fluid as one mixture ([`Scheme::near_critical_mixture`]) from the
    /// conserved masses and energies it started from.
    fn recover_or_mix(
        &self,
        st: &StepInput,
        w: &mut Work,
        next: &mut State,
        budget: &mut StepBudget,
        i: usize,
    ) -> Result<(), Rejection> {
        let before = Before::take(next, budget, i);
        w.mixture[i] = false;
        match self.recover_cell(st, w, next, budget, i) {
            Ok(_) => Ok(()),
            Err(rejection) => {
                // near the critical point no shorter step helps: the cell as one mixture
                before.restore(next, budget, i);
                self.near_critical_mixture(st, w, next, i, NearCritical::Below).ok_or(rejection)
            }
        }
    }

    /// Cell `i`'s fluid as one mixture in equilibrium at its new pressure, where that pressure
    /// lies within the `window` around the critical pressure (from `NEAR_CRITICAL_FRACTION` of
    /// it: up to it where the phases could not be recovered one by one, up to
    /// `SUPERCRITICAL_FRACTION` of it where a volume error no step shrinks has no filling
    /// pressure): the cell's mass and internal energy are shared by the
    /// lever rule between saturated liquid and vapour where both phase tables hold them, else
    /// between the liquid table's top and the vapour table's bottom (all liquid or all vapour
    /// where the mixture's energy lies beyond that end; above the critical pressure the vapour
    /// table's bottom lies below the liquid table's top, and the fluid is all liquid up to that
    /// top and all "vapour", the supercritical fluid, beyond). Mass and energy are kept exactly; the
    /// volume the mixture then takes is the cell's volume error, which the following steps'
    /// pressure equations remove. `None` elsewhere or where the tables give no such state.
    ///
    /// Decision: near the critical point the phase tables end at their spinodal margins on
    /// either side of saturation (para-hydrogen at 1.2707 MPa, 0.988 of its critical pressure:
    /// liquid to 32.81 K, vapour from 32.88 K, saturation at 32.86 K), within 0.5 % of it the
    /// table gives no saturation, and the energies between the two tables' ends (10–25 kJ/kg
    /// there) belong to neither. The phase change at a table's edge moves mass at the other
    /// phase's saturated energy, which lies outside that phase's table there, and the pressure
    /// correction of a volume error does not shrink with the step: the subcooled para-hydrogen
    /// line at 11 atm (`examples/nbs/calibrated-six.toml`) ended with its steps halved below 1e-9 s,
    /// its inlet cells' liquid above its table's top and vapour below its table's bottom. The
    /// mixture has a state where its phases do not, and this close to the critical point the
    /// two phases' densities differ by a factor below 2, so the split moves little volume.
    fn near_critical_mixture(
        &self,
        st: &StepInput,
        w: &mut Work,
        next: &mut State,
        i: usize,
        window: NearCritical,
    ) -> Option<()> {
        let (fluid, s) = (self.fluid, st.s);
        let pc = fluid.constants().p_critical_pa;
        let p = new_pressure(s, w, i);
        let (bottom, top) = window.window();
        if !(p >= bottom * pc && p < top * pc) {
            return None;
        }
        let m = next.m_g[i] + next.m_l[i];
        let u = (next.e_g[i] + next.e_l[i]) / m;
        // a negative phase mass is the step's error, not the state's (`recover_cell`)
        if !(m > 0.0 && u.is_finite() && next.m_g[i].min(next.m_l[i]) >= -1e-12 * m) {
            return None;
        }
        let guesses = (s.t_g[i] + w.x[i][2], s.t_l[i] + w.x[i][3]);
        let Mixture { gas: (tg, gp, m_gas), liquid: (tl, lp, m_liq) } = Mixture::at(fluid, p, m, u, guesses)?;
        let (ag, al) = (m_gas / gp.rho, m_liq / lp.rho);
        next.p[i] = p;
        next.m_g[i] = m_gas;
        next.m_l[i] = m_liq;
        next.e_g[i] = m_gas * gp.u;
        next.e_l[i] = m_liq * lp.u;
        next.t_g[i] = tg;
        next.t_l[i] = tl;
        next.gas[i] = gp;
        next.liquid[i] = lp;
        next.alpha[i] = ag / (ag + al);
        next.volume_error[i] = ag + al - 1.0;
        next.sat[i] = saturation_or_none(fluid, p);
        // not a function of the step: exempt from the volume-error check and the change control
        w.merged[i] = true;
        w.reset[i] = true;
        w.reset_volume[i] = next.volume_error[i];
        w.edge[i] = EdgeMove::default();
        w.mixture[i] = true;
        Some(())
    }

    /// Recovers cell `i` of `next` (see [`Scheme::state_recovery`]), noting in `w.reset` whether
    /// a phase of it was reset or changed phase at its table's edge and in `w.reset_volume` the
    /// volume that made; returns its volume error.
    fn recover_cell(
        &self,
        st: &StepInput,
        w: &mut Work,
        next: &mut State,
        budget: &mut StepBudget,
        i: usize,
    ) -> Result<f64, Rejection> {
        let (s, fluid) = (st.s, self.fluid);
        let p = new_pressure(s, w, i);
        if !(p.is_finite() && p > 0.0) {
            return Err(Rejection { cell: i, variable: "pressure", value: p, reason: "non-physical pressure" });
        }
        let c = fluid.constants();
        if !(p >= c.p_min_pa && p <= c.p_max_pa) {
            return Err(Rejection {
                cell: i,
                variable: "pressure",
                value: p,
                reason: "outside the property table's pressure range",
            });
        }
        next.p[i] = p;
        let total = next.m_g[i] + next.m_l[i];
        for (gas, m) in [(true, next.m_g[i]), (false, next.m_l[i])] {
            if !m.is_finite() || m < -1e-12 * total {
                return Err(Rejection {
                    cell: i,
                    variable: if gas { "gas mass" } else { "liquid mass" },
                    value: m,
                    reason: "negative phase mass",
                });
            }
        }
        let tiny = PRESENT_MASS_FRACTION * total.max(1e-30);
        let (mg, ml) = (next.m_g[i].max(0.0), next.m_l[i].max(0.0));
        w.merged[i] = false;
        next.m_g[i] = mg;
        next.m_l[i] = ml;
        // gas
        let tg_guess = s.t_g[i] + w.x[i][2];
        let tl_guess = s.t_l[i] + w.x[i][3];
        let cell = Recovery {
            fluid,
            s,
            i,
            p,
            tiny,
            volume: self.grid.volume[i],
            blend_min: self.physics.cryo.blend_min,
            blend_max: self.physics.cryo.blend_max,
        };
        let (mut moved_to_g, mut moved_to_l) = (0.0, 0.0);
        // the change of the gas's volume that the liquid flashed into it made
        let mut flashed_volume = 0.0;
        // each phase from its own energy; one whose energy lies beyond its table's edge towards
        // the other phase changes phase there (`Recovery::edge_phase_change`)
        let (mut tg, mut gp, mut eg, reset_g) =
            match cell.phase(Phase::Gas, mg, next.e_g[i], tg_guess, tl_guess, ml, budget) {
                Ok(gas) => gas,
                Err(rejection) => match cell.edge_phase_change(Phase::Gas, mg, next.e_g[i]).ok_or(rejection)? {
                    EdgeChange::Whole => {
                        next.m_l[i] += mg;
                        next.e_l[i] += next.e_g[i];
                        next.m_g[i] = 0.0;
                        let (t, props, e, _) = cell.phase(Phase::Gas, 0.0, 0.0, tg_guess, tl_guess, 0.0, budget)?;
                        // not a function of the step: exempt from the volume-error check
                        // and from the change control (`w.merged`)
                        w.merged[i] = true;
                        (t, props, e, true)
                    }
                    EdgeChange::Part { mass, energy, t, props, at_any_step } => {
                        next.m_g[i] -= mass;
                        next.m_l[i] += mass;
                        next.e_l[i] += energy;
                        moved_to_l = mass;
                        w.merged[i] |= at_any_step;
                        (t, props, next.m_g[i] * props.u, true)
                    }
                },
            };
        let (tl, lp, el, reset_l) =
            match cell.phase(Phase::Liquid, next.m_l[i], next.e_l[i], tl_guess, tg, next.m_g[i], budget) {
                Ok(liquid) => liquid,
                Err(rejection) => {
                    let change = cell.edge_phase_change(Phase::Liquid, next.m_l[i], next.e_l[i]).ok_or(rejection)?;
                    let (mass, energy) = match change {
                        EdgeChange::Whole => (next.m_l[i], next.e_l[i]),
                        EdgeChange::Part { mass, energy, .. } => (mass, energy),
                    };
                    let gas_volume = next.m_g[i] / gp.rho;
                    next.m_l[i] -= mass;
                    next.m_g[i] += mass;
                    moved_to_g = mass;
                    // the gas with the vapour that joined it, from its temperature as recovered
                    (tg, gp, eg, _) = cell.phase(Phase::Gas, next.m_g[i], eg + energy, tg, tl_guess, 0.0, budget)?;
                    flashed_volume = next.m_g[i] / gp.rho - gas_volume;
                    match change {
                        EdgeChange::Whole => {
                            next.m_l[i] = 0.0;
                            let (t, props, e, _) = cell.phase(Phase::Liquid, 0.0, 0.0, tl_guess, tg, 0.0, budget)?;
                            w.merged[i] = true;
                            (t, props, e, true)
                        }
                        EdgeChange::Part { t, props, at_any_step, .. } => {
                            w.merged[i] |= at_any_step;
                            (t, props, next.m_l[i] * props.u, true)
                        }
                    }
                }
            };
        let (mg, ml) = (next.m_g[i], next.m_l[i]);
        next.e_g[i] = eg;
        next.e_l[i] = el;
        let ag = mg / gp.rho;
        let al = ml / lp.rho;
        let verr = ag + al - 1.0;
        // the volume a reset phase's new temperature gave it, and the volume the mass an edge
        // change moved takes in the phase it joined: not the step's linearisation error
        let provisional_g = s.alpha[i] + w.dvol_g[i];
        let provisional_l = 1.0 - s.alpha[i] + w.dvol_l[i];
        let mut reset_volume = moved_to_g / gp.rho + moved_to_l / lp.rho;
        if reset_g {
            reset_volume += ag - provisional_g;
        }
        if reset_l {
            reset_volume += al - provisional_l;
        }
        w.reset_volume[i] = reset_volume;
        w.edge[i] = EdgeMove { mass: moved_to_g - moved_to_l, gas_volume: flashed_volume - moved_to_l / gp.rho };
        w.reset[i] = reset_g || reset_l;
        next.alpha[i] = ag / (ag + al);
        next.t_g[i] = tg;
        next.t_l[i] = tl;
        next.gas[i] = gp;
        next.liquid[i] = lp;
        next.volume_error[i] = verr;
        next.sat[i] = saturation_or_none(fluid, p);
        Ok(verr)
    }
}

/// What a cell's recovery changes and a second recovery starts from again: the cell's
/// conserved masses and energies from step 2 and the step's budget.
struct Before {
    conserved: [f64; 4],
    budget: StepBudget,
}

impl Before {
    fn take(next: &State, budget: &StepBudget, i: usize) -> Self {
        Self { conserved: [next.m_g[i], next.m_l[i], next.e_g[i], next.e_l[i]], budget: *budget }
    }

    fn restore(&self, next: &mut State, budget: &mut StepBudget, i: usize) {
        [next.m_g[i], next.m_l[i], next.e_g[i], next.e_l[i]] = self.conserved;
        *budget = self.budget;
    }
}

/// What cell `i` of `next` holds, as [`refill::filling_pressure`] takes it: a phase whose mass
/// is a trace keeps the volume it was recovered with.
fn cell_contents(next: &State, i: usize) -> refill::Contents {
    let (mg, ml) = (next.m_g[i], next.m_l[i]);
    let tiny = PRESENT_MASS_FRACTION * (mg + ml).max(1e-30);
    let (gp, lp) = (&next.gas[i], &next.liquid[i]);
    refill::Contents {
        m_g: mg,
        u_g: (mg > tiny).then(|| next.e_g[i] / mg),
        m_l: ml,
        u_l: (ml > tiny).then(|| next.e_l[i] / ml),
        fixed_volume: if mg > tiny { 0.0 } else { mg / gp.rho } + if ml > tiny { 0.0 } else { ml / lp.rho },
        t_g: next.t_g[i],
        t_l: next.t_l[i],
    }
}

/// A cell as its recovery left it after a merge, everything a second recovery writes
/// ([`Scheme::refill_merged`] restores it where the second recovery is not kept).
struct MergedCell {
    p: f64,
    conserved: [f64; 4],
    t: [f64; 2],
    props: [PhaseProps; 2],
    alpha: f64,
    volume_error: f64,
    sat: crate::fluids::Saturation,
    budget: StepBudget,
    x0: f64,
    reset: bool,
    reset_volume: f64,
    edge: EdgeMove,
    merged: bool,
    mixture: bool,
}

impl MergedCell {
    fn take(next: &State, w: &Work, budget: &StepBudget, i: usize) -> Self {
        Self {
            p: next.p[i],
            conserved: [next.m_g[i], next.m_l[i], next.e_g[i], next.e_l[i]],
            t: [next.t_g[i], next.t_l[i]],
            props: [next.gas[i], next.liquid[i]],
            alpha: next.alpha[i],
            volume_error: next.volume_error[i],
            sat: next.sat[i],
            budget: *budget,
            x0: w.x[i][0],
            reset: w.reset[i],
            reset_volume: w.reset_volume[i],
            edge: w.edge[i],
            merged: w.merged[i],
            mixture: w.mixture[i],
        }
    }

    fn volume_error(&self) -> f64 {
        self.volume_error.abs()
    }

    fn restore(&self, next: &mut State, w: &mut Work, budget: &mut StepBudget, i: usize) {
        next.p[i] = self.p;
        [next.m_g[i], next.m_l[i], next.e_g[i], next.e_l[i]] = self.conserved;
        [next.t_g[i], next.t_l[i]] = self.t;
        [next.gas[i], next.liquid[i]] = self.props;
        next.alpha[i] = self.alpha;
        next.volume_error[i] = self.volume_error;
        next.sat[i] = self.sat;
        *budget = self.budget;
        w.x[i][0] = self.x0;
        w.reset[i] = self.reset;
        w.reset_volume[i] = self.reset_volume;
        w.edge[i] = self.edge;
        w.merged[i] = self.merged;
        w.mixture[i] = self.mixture;
    }
}

/// Whether cell `i` of a step just recovered is to be refilled ([`Scheme::refill`]): the step
/// is a retry of one rejected for its volume error, this cell's error then was above its limit
/// and the retry's is still above half of it (a shorter step did not shrink it), and the cell's
/// recovery reset no phase (a reset's volume is not the linearisation's).
fn refill_wanted(st: &StepInput, w: &Work, next: &State, i: usize) -> bool {
    w.volume_retry.not_halved(st.s.time, i, next.volume_error[i]) && refillable(w, next, i)
}

/// Whether cell `i` was recovered as one near-critical mixture by the step that ended at the
/// old state.
fn mixed_before(st: &StepInput, i: usize) -> bool {
    st.s.mixture.get(i).copied().unwrap_or(false)
}

/// Whether cell `i`, which the step before recovered as one near-critical mixture, is refilled
/// ([`Scheme::refill`]) at the first attempt: where its phases' recovery leaves a volume error
/// above the limit.
///
/// Decision: a cell at the critical point itself (para-hydrogen at 34.2 kg/m³, 32.98 K,
/// 1.296 MPa, the envelope's line subcooled at 11 atm) is filled by no pressure within reach:
/// every step from the mixture made a volume error of −2.5 to −3.6e-3 at any length and was
/// rejected, its retry recovered the cell as one mixture again (exempt, so accepted), and the
/// steps halved every second attempt to below 1e-9 s. Refilled at the first attempt it is
/// mixed again without the rejection.
fn mixed_again_wanted(st: &StepInput, w: &Work, next: &State, i: usize) -> bool {
    mixed_before(st, i) && next.volume_error[i].abs() > MAX_VOLUME_ERROR && refillable(w, next, i)
}

/// Whether cell `i`'s first recovery leaves it to be refilled: no phase merged into the other,
/// not one mixture, and no reset but of a trace ([`only_a_trace`]).
fn refillable(w: &Work, next: &State, i: usize) -> bool {
    !((w.reset[i] && !only_a_trace(next, i)) || w.merged[i] || w.mixture[i])
}

/// Volume fraction below which a phase is a trace whose reset does not bar a refill.
const TRACE_VOLUME: f64 = 1e-3;

/// Whether one of cell `i`'s phases fills less than [`TRACE_VOLUME`] of it.
///
/// Decision: a trace's reset (its temperature taken to the other phase's) moves a volume of at
/// most its own and does not make the cell's error; near the critical point a liquid-filled cell
/// whose trace of gas was reset on every other step had its volume error swing between −3.5e-3
/// and −5.9e-3 at any step length, the refill barred by the reset, and the steps halved below
/// 1e-9 s (para-hydrogen subcooled at 11 atm on the envelope's line, 14.10 s).
fn only_a_trace(next: &State, i: usize) -> bool {
    next.alpha[i].min(1.0 - next.alpha[i]) < TRACE_VOLUME
}

/// Whether specific energy `u` of `phase` lies beyond `edge`, its properties at its table's edge
/// towards the other phase ([`Recovery::edge_towards_other`]).
fn beyond_edge(phase: Phase, u: f64, edge: &PhaseProps) -> bool {
    match phase {
        Phase::Liquid => u > edge.u,
        Phase::Gas => u < edge.u,
    }
}

/// A phase's recovered temperature, properties and conserved energy per unit volume, and
/// whether its temperature was reset.
type Recovered = (f64, PhaseProps, f64, bool);

/// What recovering the temperatures of cell `i`'s phases from their new masses and energies
/// needs ([`Recovery::phase`]).
#[derive(Debug, Clone, Copy)]
struct Recovery<'a> {
    fluid: &'a FluidTable,
    /// The old state (a phase's old density estimates its volume fraction).
    s: &'a State,
    /// The cell.
    i: usize,
    /// The cell's new pressure, Pa.
    p: f64,
    /// Mass per unit volume at or below which a phase is reset, kg/m³.
    tiny: f64,
    /// The cell's volume, m³.
    volume: f64,
    /// Phase-blending thresholds (`CryoParams::blend_min`, `blend_max`).
    blend_min: f64,
    /// See `blend_min`.
    blend_max: f64,
}

/// A phase change at a phase table's edge ([`Recovery::edge_phase_change`]).
#[derive(Debug, Clone, Copy)]
enum EdgeChange {
    /// The whole phase goes to the other phase, mass and energy (its energy is the other
    /// phase's: [`Recovery::beyond_other_phase`]).
    Whole,
    /// The mass and internal energy per unit volume that go to the other phase, the
    /// temperature and properties at the edge of the part that stays, and whether the phase
    /// lay beyond the edge in the old state already ([`Recovery::old_beyond_edge`]: then the
    /// change is not a function of the step, and the cell is exempt from the change control
    /// and the volume-error check as for a whole phase, `w.merged`).
    Part { mass: f64, energy: f64, t: f64, props: PhaseProps, at_any_step: bool },
}

impl Recovery<'_> {
    /// A phase of mass `m` and energy `e` per unit volume whose specific energy lies beyond its
    /// table's edge on the side of the other phase (liquid above the top of the liquid table,
    /// gas below the bottom of the gas table): the excess changes phase. The phase stays at its
    /// table's edge (hundredths of a kelvin from saturation there) and the mass that carries
    /// the excess at the other phase's saturated internal energy goes to the other phase (which
    /// need not be present), so that the cell's internal energy is kept exactly; the volume that
    /// moves is a volume error that the next steps' pressure equations remove, as for a trace
    /// reset. A phase whose energy lies beyond even the other phase's saturated energy goes over
    /// whole, mass and energy (a "liquid" above the critical temperature when the pressure falls
    /// below the critical pressure is vapour). `None` where the energy is not beyond that edge,
    /// there is no saturation (above the critical pressure), or a partial change would take
    /// more than half the phase.
    ///
    /// Decision: near the critical point the phase tables end a few hundredths of a kelvin
    /// from saturation (`data/fluids/README.md`), and liquid the wall heats there (para-hydrogen
    /// at 1.2 MPa, 93 % of its critical pressure) crossed the liquid table's top at liquid
    /// fractions of 0.2 while the interface did not evaporate it fast enough (and gas cooled to
    /// saturation crossed the gas table's bottom); the pressure change of the volume-error
    /// correction does not vanish with the step, so no shorter step brought them back and the
    /// run ended. Holding the liquid at the top and booking the excess as an adjustment instead
    /// destroyed 136 kJ over that run.
    ///
    /// Decision: the other phase need not be present. Vapour past its table's bottom condenses
    /// and liquid past its table's top flashes whether or not the cell holds any of the other
    /// phase (the tables end at the metastable limits, beyond which the phase does not exist);
    /// the mass that changes phase enters the empty phase at its saturated energy. Before, a
    /// cell holding one phase only had no way out: para-hydrogen subcooled at 11 atm with the
    /// defaults and its inlet at 19.619650779 K ended at 5.58 s with its inlet cell all
    /// vapour at 0.9986 of the critical pressure, whose volume-error correction lowered the
    /// pressure below the near-critical mixture's window and left the vapour's energy below its
    /// table's bottom at any step length.
    fn edge_phase_change(&self, phase: Phase, m: f64, e: f64) -> Option<EdgeChange> {
        if m <= self.tiny {
            return None;
        }
        let u = e / m;
        let entering = self.entering_energy(phase);
        if self.beyond_other_phase_at(phase, u, entering) {
            return Some(EdgeChange::Whole);
        }
        let u_other = entering?;
        let (t, props) = self.edge_towards_other(phase)?;
        if !beyond_edge(phase, u, &props) {
            return None;
        }
        let mass = m * (u - props.u) / (u_other - props.u);
        let at_any_step = self.old_beyond_edge(phase, &props);
        if mass <= 0.5 * m || at_any_step {
            Some(EdgeChange::Part { mass, energy: mass * u_other, t, props, at_any_step })
        } else {
            // a trace goes over whole (its volume is a small volume error); more than half of a
            // phase present in bulk is not a table-edge correction
            (m / self.old_density(phase) < self.blend_max.max(TRACE_RESET_FRACTION)).then_some(EdgeChange::Whole)
        }
    }

    /// Whether the cell comes from where the table gives no saturation near the critical point
    /// (above the critical pressure, or within 0.5 % below it) with the phase's specific energy
    /// in the old state already beyond `edge` (its table's edge towards the other phase at the
    /// new pressure, where there is a saturation): fluid entering the two-phase region from
    /// where a phase is not bound to its side of the dome, where no shorter step brings the
    /// phase back and however much of it changes phase is the state, not the step's error.
    ///
    /// Decision: below the critical pressure a partial change of more than half a phase is
    /// left to a shorter step, which keeps the change control in charge of ordinary flashing
    /// and condensation (with the old state's energy beyond the edge at the new pressure
    /// allowed everywhere, a long step's pressure drop exempted the flashing it caused: the
    /// NBS nitrogen run saturated at 3.4 atm doubled its energy balance error). Above the
    /// critical pressure a phase is not bound to its side of the dome: dense fluid is one
    /// phase, the gas table's ("supercritical") at any energy, and "liquid" heated past the
    /// critical temperature stays in the liquid table. When the pressure falls below the
    /// critical pressure again, often by the correction of a volume error, which does not
    /// shrink with the step, such fluid lies inside the dome: para-hydrogen subcooled at
    /// 11 atm (15 and 25 cells, 19.619650779 K inlet) ended with its inlet cell's "gas" at
    /// 237–248 kJ/kg falling from 0.999 to 0.979 of the critical pressure, whose lever-rule
    /// split sends 70 % of it to the liquid, and (15 cells, the inlet at saturation) with a
    /// cell's "liquid" at 33.003 K falling from 1.292 to 1.266 MPa, 96 % of which flashed into
    /// its gas at 79 K, at any step length.
    fn old_beyond_edge(&self, phase: Phase, edge: &PhaseProps) -> bool {
        // the old state's saturation, as its recovery stored it (`saturation_or_none`)
        let unbound = self.s.p[self.i] >= NEAR_CRITICAL_FRACTION * self.fluid.constants().p_critical_pa
            && self.s.sat[self.i].h_lg <= 0.0;
        if !unbound {
            return false;
        }
        let (m, e) = match phase {
            Phase::Gas => (self.s.m_g[self.i], self.s.e_g[self.i]),
            Phase::Liquid => (self.s.m_l[self.i], self.s.e_l[self.i]),
        };
        m > self.tiny && beyond_edge(phase, e / m, edge)
    }

    /// The phase's density in the cell's old state, kg/m³ (estimates its volume fraction).
    fn old_density(&self, phase: Phase) -> f64 {
        match phase {
            Phase::Gas => self.s.gas[self.i].rho,
            Phase::Liquid => self.s.liquid[self.i].rho,
        }
    }

    /// Whether liquid of specific energy `u` lies above the top of its table at the cell's
    /// pressure (superheated beyond its metastable limit) where the table gives a saturation:
    /// such liquid flashes at the table's edge ([`Recovery::edge_phase_change`]), even a trace.
    ///
    /// Decision: a liquid trace used to be reset or clamped to the table's top instead, which
    /// destroyed the heat that the wall and the gas had given it: the exit cell of the nitrogen
    /// line saturated at 11 atm held a trace of liquid (volume fraction 10⁻⁵) that the hot gas
    /// heated past the top in every step, 1.6 kJ destroyed over the run. Flashing turns that
    /// heat into vapour and keeps the energy. (Vapour below the bottom of its table is still
    /// reset as a trace: condensing it would collapse its volume in a cell full of liquid.)
    fn liquid_above_top(&self, u: f64) -> bool {
        self.other_saturated_energy(Phase::Liquid).is_some()
            && self.edge_towards_other(Phase::Liquid).is_some_and(|(_, top)| beyond_edge(Phase::Liquid, u, &top))
    }

    /// The temperature and properties of `phase` at its table's edge towards the other phase
    /// at the cell's pressure (the liquid's top, the gas's bottom), a millionth of the table's
    /// range inside it.
    fn edge_towards_other(&self, phase: Phase) -> Option<(f64, PhaseProps)> {
        table_edge(self.fluid, phase, self.p)
    }

    /// Whether specific energy `u` of `phase` belongs to the other phase at the cell's pressure:
    /// beyond the other phase's saturated energy (liquid more energetic than saturated vapour,
    /// gas less than saturated liquid) or, where the table gives no saturation (within 0.5 %
    /// of the critical pressure), outside its own table and inside the other phase's. Such a
    /// phase goes over whole ([`Recovery::edge_phase_change`]); it is never a trace to be
    /// clamped into its own table.
    fn beyond_other_phase(&self, phase: Phase, u: f64) -> bool {
        self.beyond_other_phase_at(phase, u, self.entering_energy(phase))
    }

    /// [`Recovery::beyond_other_phase`] with the phase's [`Recovery::entering_energy`] known.
    fn beyond_other_phase_at(&self, phase: Phase, u: f64, entering: Option<f64>) -> bool {
        let (fluid, p) = (self.fluid, self.p);
        match entering {
            Some(u_other) => match phase {
                Phase::Liquid => u > u_other,
                Phase::Gas => u < u_other,
            },
            None => {
                let guess = fluid.constants().t_critical_k;
                fluid.temperature_from_energy(phase, p, u, guess).is_err()
                    && fluid.temperature_from_energy(phase.other(), p, u, guess).is_ok()
            }
        }
    }

    /// The specific internal energy, J/kg, at which mass of `phase` that changes phase enters
    /// the other phase: that phase saturated at the cell's pressure, or its table's edge where
    /// the edge lies beyond saturation; `None` where the table gives no saturation.
    ///
    /// Decision: near the critical point the phase tables end a few hundredths of a kelvin on
    /// their own side of saturation, so the saturated energies of the saturation table can lie
    /// outside the other phase's table: para-hydrogen at 1.2445 MPa (0.968 of the critical
    /// pressure), where saturated vapour has 296.8 kJ/kg and the vapour table starts at
    /// 301.9 kJ/kg (32.74 K). Liquid past its table's top flashed into vapour at 296.8 kJ/kg,
    /// the cell's vapour fell below its table with it at any step length, and the run ended
    /// (subcooled at 11 atm with `examples/nbs/calibrated-six.toml`, at 6.6 s with probes every
    /// 0.25 s or on the interpolated outputs, at 18.3 s with probes every 2 s). Entering at the
    /// table's edge, the mass that changes phase is a little smaller and carries the same
    /// excess energy: the cell's energy is kept exactly.
    fn entering_energy(&self, phase: Phase) -> Option<f64> {
        let u_sat = self.other_saturated_energy(phase)?;
        Some(match (phase, self.edge_towards_other(phase.other())) {
            (Phase::Liquid, Some((_, bottom))) => u_sat.max(bottom.u),
            (Phase::Gas, Some((_, top))) => u_sat.min(top.u),
            (_, None) => u_sat,
        })
    }

    /// The specific internal energy of the other phase than `phase` saturated at the cell's
    /// pressure, J/kg; `None` where the table gives no saturation there.
    fn other_saturated_energy(&self, phase: Phase) -> Option<f64> {
        let (sat, p) = (self.fluid.saturation(self.p).ok().filter(|s| s.h_lg > 0.0)?, self.p);
        Some(match phase {
            Phase::Liquid => sat.h_g - p / sat.rho_g,
            Phase::Gas => sat.h_l - p / sat.rho_l,
        })
    }

    /// The temperature of a phase of mass `m` and energy `e` per unit volume (`guess` to start
    /// the inversion from, `other_t` the other phase's temperature).
    ///
    /// A phase present in more than a trace keeps the temperature its conserved energy gives. A
    /// trace (volume fraction below blend_min, or below TRACE_RESET_FRACTION when its energy has
    /// left the table) takes the other phase's temperature, moved into its own table: its
    /// energy per unit mass is ill-conditioned (tiny mass, finite pressure work, compression by
    /// liquid hammer), and the reset moves at most a trace of energy, booked as an adjustment
    /// in the budget.
    #[allow(clippy::too_many_arguments)]
    fn phase(
        &self,
        phase: Phase,
        m: f64,
        e: f64,
        guess: f64,
        other_t: f64,
        m_other: f64,
        budget: &mut StepBudget,
    ) -> Result<Recovered, Rejection> {
        let (fluid, p, i, tiny) = (self.fluid, self.p, self.i, self.tiny);
        let (name, energy_name, what) = match phase {
            Phase::Gas => ("gas temperature", "gas specific energy (J/kg)", "gas energy outside the property table"),
            Phase::Liquid => {
                ("liquid temperature", "liquid specific energy (J/kg)", "liquid energy outside the property table")
            }
        };
        // the phase's table at the cell's pressure, located once for the evaluations below
        let table = fluid.isobar(phase, p);
        let range = table.temperature_range();
        let reset = |budget: &mut StepBudget| -> Result<Recovered, Rejection> {
            // the other phase's temperature moved into this phase's table (`clamp_to_phase`)
            let target = clamp_to_range(range, other_t);
            let pr = table.props(target).map_err(|_| Rejection {
                cell: i,
                variable: name,
                value: target,
                reason: "outside the property table",
            })?;
            budget.adjust((m * pr.u - e) * self.volume);
            Ok((target, pr, m * pr.u, m > tiny))
        };
        if m <= tiny {
            return reset(budget);
        }
        // the phase's volume fraction, estimated with its old density
        let trace_frac = m / self.old_density(phase);
        // liquid above its table's top flashes there (the caller's edge phase change)
        let flashes = || phase == Phase::Liquid && m_other > tiny && self.liquid_above_top(e / m);
        let beyond = || Rejection { cell: i, variable: energy_name, value: e / m, reason: what };
        if trace_frac < self.blend_min {
            if flashes() {
                return Err(beyond());
            }
            return reset(budget);
        }
        match table.temperature_from_energy(e / m, guess) {
            Ok((t, pr)) => Ok((t, pr, e, false)),
            Err(_)
                if trace_frac < self.blend_max.max(TRACE_RESET_FRACTION)
                    && !self.beyond_other_phase(phase, e / m)
                    && !flashes() =>
            {
                // the nearest temperature the table holds, which changes the trace's
                // density (and so the cell's volume balance) least
                let Some((lo, hi)) = range else {
                    return reset(budget);
                };
                let u_lo = table.props(lo).map(|pr| pr.u).unwrap_or(f64::NAN);
                let margin = 1e-6 * (hi - lo);
                let t = if e / m <= u_lo { lo + margin } else { hi - margin };
                let pr = table.props(t).map_err(|_| Rejection {
                    cell: i,
                    variable: name,
                    value: t,
                    reason: "outside the property table",
                })?;
                budget.adjust((m * pr.u - e) * self.volume);
                Ok((t, pr, m * pr.u, true))
            }
            // the value is the specific internal energy, J/kg (no temperature fits it)
            Err(_) => Err(beyond()),
        }
    }
}
