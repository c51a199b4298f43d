//! One time step of the nearly-implicit two-fluid scheme.
//!
//! The step follows the RELAP5-3D nearly-implicit method as the paper describes it (Sec.
//! "Algorithm"), in two steps:
//!
//! **Step 1.**
//! (a) *Provisional velocities*: the phasic momentum equations at every junction with implicit
//! convection (donor-cell v ∂v/∂x, linearised about the old velocity), implicit wall friction,
//! interphase drag (Newton-linearised in the relative velocity where it grows faster than
//! linearly), virtual mass (its time-derivative term) and form losses, with the old
//! pressure gradient: a block-tridiagonal system with 2×2 blocks over the junctions.
//! (b) *Velocity–pressure coupling*: the new velocity of a junction is its provisional velocity
//! plus a correction linear in the change of the pressure difference across it, through the
//! inverse of the junction's own 2×2 block: v = ṽ + w (δp_L − δp_R).
//! (c) *Pressure*: each cell's expanded (linearised) gas mass, liquid mass, gas energy and liquid
//! energy equations in the unknowns (δp, δα, δT_g, δT_l) — with interphase heat and mass
//! transfer and the wall heat linearised implicitly in pressure and phasic temperatures, and the
//! lumped wall temperature eliminated locally, and the donor-cell fluxes with the donors'
//! contents at the new time (linear in the donor cell's unknowns, as step 2 takes them) — form
//! a block-tridiagonal system with 4×4 blocks over the cells.
//! (d) Its solve gives the new pressures and velocities, provisional void fraction and
//! temperatures, and provisional interphase and wall heat and mass transfer.
//!
//! **Step 2.** The unexpanded (conservative) phasic mass and energy equations with the new
//! velocities, new-time donor-cell fluxes and the provisional sources: four independent
//! tridiagonal systems. Mass is conserved to round-off. The wall energy changes by exactly the
//! heat the fluid received. The state then follows from the conserved masses and energies at the
//! new pressure; the mismatch between the two phases' volumes and the cell volume (the volume
//! error) is carried into the next step's pressure equation, which drives it back to zero.
//!
//! Primary thermodynamic variables are pressure and phasic temperatures (see
//! [`crate::fluids`]); the primary conserved variables are the phasic masses and internal
//! energies per unit volume.
//!
//! # Phases
//!
//! [`Scheme::step`] runs these methods in order, each reading and writing the scheme's reusable
//! work arrays (`Work`); the first that fails rejects the step:
//!
//! | phase | file | what it does |
//! | --- | --- | --- |
//! | `old_time_sources` | `sources.rs` | linearised interphase and wall sources at the old state |
//! | `momentum_predictor` | `momentum.rs` | step 1a: the 2×2 block-tridiagonal momentum system |
//! | `pressure_weights` | `momentum.rs` | step 1b: each junction's velocity–pressure weights |
//! | `provisional_velocities` | `momentum.rs` | the momentum solve; the heat estimate of the step |
//! | `pressure_equation` | `pressure.rs` | step 1c: per-cell rows of the 4×4 block-tridiagonal pressure system |
//! | `pressure_solve` | `pressure.rs` | step 1d: its solve for every cell's unknowns |
//! | `velocity_update` | `pressure.rs` | the new velocities |
//! | `exit_choke` | `choking.rs` | a choked exit: step 1 again with the exit's resistance |
//! | `provisional_sources` | `sources.rs` | sources at the provisional state |
//! | `mass_update` | `conservative.rs` | step 2: conservative phasic masses |
//! | `mark_limited` | `sources.rs` | cells whose phase change took nearly all of a phase: their sources limited, the masses solved again |
//! | `dissipated_heat` | `conservative.rs` | the momentum forces' heat with the new velocities |
//! | `phase_volume_changes` | `conservative.rs` | each phase's volume change (its p dV work) |
//! | `work_consistency` | `conservative.rs` | pressure work the flow work did not book |
//! | `energy_update` | `conservative.rs` | step 2: conservative phasic energies |
//! | `wall_update` | `conservative.rs` | the wall's energy and temperature, the heat budgets |
//! | `state_recovery` | `recovery.rs`, `refill.rs`, `mixture.rs` | pressure, temperatures and void fraction from the conserved variables |
//! | `total_energy_flux` | `balance.rs` | the boundary total-energy flux of the budget |
//! | `all_finite`, `change_control`, `volume_error_check` | `acceptance.rs` | the acceptance checks |

// Index loops over cells and junctions mirror the discrete equations (i, j ± 1) one to one.
#![allow(clippy::needless_range_loop)]

mod acceptance;
mod balance;
mod choking;
mod conservative;
mod mixture;
mod momentum;
mod pressure;
mod recovery;
mod refill;
mod sources;

use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};

use crate::case::BoundaryKind;
use crate::cryo;
use crate::fluids::{FluidTable, Saturation};
use crate::model::{BoundaryState, Grid, State};

use acceptance::{RetryRecord, VelocityTrend, all_finite, volume_error_check};
pub use balance::StepBudget;
use choking::MAX_CHOKE_PASSES;
pub use choking::two_phase_critical_speed;
use momentum::JunctionWork;
use sources::Sources;

/// Physics switches and the constants of the basic closures.
#[derive(Debug, Clone, PartialEq)]
pub struct Physics {
    /// Interphase and wall mass transfer.
    pub phase_change: bool,
    /// Wall–fluid heat transfer.
    pub wall_heat_transfer: bool,
    /// Heat transfer between the phases.
    pub interphase_heat_transfer: bool,
    /// Interfacial drag.
    pub interphase_drag: bool,
    /// Wall friction.
    pub wall_friction: bool,
    /// Gravity.
    pub gravity: bool,
    /// Virtual mass.
    pub virtual_mass: bool,
    /// Fixed wall heat transfer coefficient, W/(m² K), instead of correlations.
    pub fixed_wall_htc: Option<f64>,
    /// Volumetric interphase heat transfer coefficient scale, W/(m³ K), times α(1 − α).
    pub interphase_htc_w_m3k: f64,
    /// Ambient temperature, K.
    pub ambient_temperature_k: f64,
    /// Ambient heat transfer coefficient on the outer wall, W/(m² K).
    pub ambient_htc_w_m2k: f64,
    /// The cryogenic closure constants (from the parameter registry).
    pub cryo: cryo::CryoParams,
    /// Which film-boiling / rewet correlation set.
    pub correlations: cryo::CorrelationSet,
}

impl Default for Physics {
    fn default() -> Self {
        Self {
            phase_change: true,
            wall_heat_transfer: true,
            interphase_heat_transfer: true,
            interphase_drag: true,
            wall_friction: true,
            gravity: true,
            virtual_mass: true,
            fixed_wall_htc: None,
            interphase_htc_w_m3k: 1.0e5,
            ambient_temperature_k: 290.0,
            ambient_htc_w_m2k: 0.0,
            cryo: cryo::CryoParams::default(),
            correlations: cryo::CorrelationSet::Paper,
        }
    }
}

/// Why a step was rejected (the driver halves the time step and retries).
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// Cell (or junction) index.
    pub cell: usize,
    /// Which variable.
    pub variable: &'static str,
    /// Its value.
    pub value: f64,
    /// Why.
    pub reason: &'static str,
}

/// What a step produced besides the new state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepReport {
    /// Largest change of a controlled variable, or volume error, as a fraction of its allowed
    /// change or its limit (≤ 1).
    pub change_ratio: f64,
    /// Largest |volume error| over the cells.
    pub max_volume_error: f64,
    /// The controlled variable that came closest to its limit (what holds the step down).
    pub limiting: &'static str,
    /// Cell (or junction, for a velocity) of [`StepReport::limiting`].
    pub limiting_index: usize,
    /// Whether the line's exit was choked in the step (`choking.rs`).
    pub exit_choked: bool,
    /// Cells recovered as one near-critical mixture in the step (`recovery.rs`).
    pub mixture_cells: u32,
    /// Cells recovered again at the pressure at which their phases fill them (`recovery.rs`).
    pub refilled_cells: u32,
    /// Budget terms.
    pub budget: StepBudget,
}

/// Largest allowed relative change per step (the paper's 25 %).
pub const MAX_RELATIVE_CHANGE: f64 = 0.25;

/// Scales below which a change is measured against the scale instead of the value, so that
/// quantities near zero do not stall the step control.
pub const SCALE_PRESSURE_PA: f64 = 2.0e4;

/// Void-fraction scale.
pub const SCALE_VOID: f64 = 0.2;

/// Temperature scale, K.
pub const SCALE_TEMPERATURE_K: f64 = 20.0;

/// Velocity scale, m/s: a velocity may change by 25 % of max(|v|, 10 m/s) in a step. Decision:
/// near a quench front the slow phase velocities (a few m/s) flicker by tens of cm/s from step
/// to step while the vapour leaves the line at 100–200 m/s; a 2 m/s floor held the NBS runs to
/// millisecond steps for no change in the result (chilldown times within 3 s at 2 and 10 m/s).
pub const SCALE_VELOCITY_M_S: f64 = 10.0;

/// The local error a phase velocity's step may make, as a fraction of the change the 25 % rule
/// allows it (`MAX_RELATIVE_CHANGE` of max(|v|, `SCALE_VELOCITY_M_S`)): the step control
/// measures a velocity by its departure from the trend of the step before
/// ([`acceptance::VelocityTrend`]).
///
/// Decision: a half. The tolerance is an accuracy control like the others: with
/// `calibrated.toml` the saturated envelope runs' station-4 chilldowns move towards their values
/// with steps of at most 1 ms as it falls (nitrogen at 3 atm +2.28 / +2.10 / +1.31 % at 1, 0.5 and
/// 0.25; methane at 1.5 atm +3.81 / +1.54 / +0.96 %), and at a half the envelope's mean error is
/// that of the 25 % rule in a fifth fewer step attempts (BENCHMARKS.md, "A velocity's step held
/// by its local error").
pub const VELOCITY_ERROR_FRACTION: f64 = 0.5;

/// Largest change of a phase velocity in one step, as a fraction of max(|v|,
/// `SCALE_VELOCITY_M_S`), whatever its trend.
///
/// Decision: four times the 25 % rule's allowance. The trend is one step's change, so two
/// steps that jump alike (a drag or a loss whose linearisation about the old velocity holds
/// only near it) would pass its test; the bound keeps each step's change within the velocity's
/// own size. Of the 1 240 steps that the velocities rejected in the six NBS runs (defaults),
/// it rejected 25, all in the hydrogen runs; the local error rejected the rest (see
/// [`VELOCITY_ERROR_FRACTION`]).
pub const MAX_VELOCITY_CHANGE: f64 = 1.0;

/// Relaxation time with which a disappearing phase is pulled to the velocity and temperature of
/// the continuous one, s. A time constant rather than a multiple of 1/Δt, so that the pull does
/// not change abruptly with the step size (the step control measures changes per step).
pub const BLEND_RELAXATION_S: f64 = 1e-3;

/// Volume fraction below which a phase whose energy has left its property table is reset to
/// the other phase's temperature (see the state recovery in [`Scheme::step`]).
pub const TRACE_RESET_FRACTION: f64 = 0.1;

/// Largest pressure correction (as a fraction of the pressure) that a volume error left by a
/// step may imply for the next one.
pub const VOLUME_ERROR_PRESSURE_FRACTION: f64 = 0.02;

/// Volume fraction above which a phase's temperature and velocity enter the step control.
pub const CONTROLLED_FRACTION: f64 = 1e-2;

/// Largest volume error accepted after a step.
pub const MAX_VOLUME_ERROR: f64 = 2e-3;

/// Mass fraction below which a phase counts as absent in a cell: its energy equation is replaced
/// and it takes no heat. (Donor-cell fluxes spread vanishing amounts, down to denormal numbers,
/// which must not reach the closures.)
pub const PRESENT_MASS_FRACTION: f64 = 1e-12;

/// The nearly-implicit scheme bound to a fluid, a grid and physics.
#[derive(Debug, Clone)]
pub struct Scheme<'a> {
    /// Property table.
    pub fluid: &'a FluidTable,
    /// Geometry.
    pub grid: Grid,
    /// Switches and closure constants.
    pub physics: Physics,
    work: Work,
}

impl<'a> Scheme<'a> {
    /// A scheme for `grid` with the given fluid and physics.
    pub fn new(fluid: &'a FluidTable, grid: Grid, physics: Physics) -> Self {
        Self { fluid, grid, physics, work: Work::default() }
    }

    /// Advances `s` by `dt` with boundary states at the old (`b0`) and new (`b1`) time.
    /// Returns the new state, or the reason the step must be retried with a smaller `dt`.
    pub fn step(
        &mut self,
        s: &State,
        dt: f64,
        b0: [&BoundaryState; 2],
        b1: [&BoundaryState; 2],
    ) -> Result<(State, StepReport), Rejection> {
        let n = self.grid.n;
        let mut w = std::mem::take(&mut self.work);
        resize(&mut w, n);
        let input = StepInput {
            s,
            dt,
            n,
            inlet0: b0[0],
            outlet0: b0[1],
            inlet1: b1[0],
            outlet1: b1[1],
            dp_in: b1[0].p - b0[0].p,
            dp_out: b1[1].p - b0[1].p,
            choke: 0.0,
        };
        let result = self.phases(&input, &mut w);
        if let Ok((next, _)) = &result {
            w.trend.record(s, next, dt);
        }
        self.work = w;
        result
    }

    /// The phases of a step in order (see the module documentation), passing their results on
    /// in the work arrays `w`. The first phase that fails rejects the step.
    fn phases(&self, st: &StepInput, w: &mut Work) -> Result<(State, StepReport), Rejection> {
        if !w.old_state.holds(st.s) {
            w.old_state.keep(st.s);
            w.old_cells.clear();
            w.old_junctions.clear(st.n + 1);
            w.storage_kept = false;
        }
        // step 1: provisional velocities, the pressure equation, the new velocities; a checked
        // exit starts from the resistance the last step left it (`choking.rs`)
        self.old_time_sources(st, w);
        let exit = self.exit_criterion(st);
        let mut choked = *st;
        choked.choke = if exit.is_some() { st.s.exit_resistance } else { 0.0 };
        let mut next = self.step_one(&choked, w)?;
        // a choked exit: step 1 again with the exit's resistance (`choking.rs`)
        if let Some(exit) = exit {
            for _ in 0..MAX_CHOKE_PASSES {
                let Some(choke) = self.exit_choke(&exit, &choked, w, &next) else { break };
                choked.choke = choke;
                next = self.step_one(&choked, w)?;
            }
        }
        next.exit_resistance = match exit {
            Some(exit) => self.exit_resistance(&exit, &choked, w, &next).unwrap_or(choked.choke),
            None => 0.0,
        };
        let st = &choked;
        // step 2: the conservative masses and energies with the new velocities
        let mut budget = StepBudget::default();
        w.limited.fill(false);
        self.provisional_sources(st, w);
        self.mass_update(st, w, &next, &mut budget)?;
        if self.mark_limited(st, w) {
            budget = StepBudget::default();
            self.provisional_sources(st, w);
            self.mass_update(st, w, &next, &mut budget)?;
        }
        next.boundary_mass_flow = [budget.mass_in / st.dt, budget.mass_out / st.dt];
        self.dissipated_heat(st, w, &next);
        self.phase_volume_changes(st, w);
        self.work_consistency(st, w, &next);
        self.energy_update(st, w, &mut next, &mut budget)?;
        self.wall_update(st, w, &mut next, &mut budget);
        // the new thermodynamic state, the boundary balance, acceptance
        let max_verr = self.state_recovery(st, w, &mut next, &mut budget)?;
        // total-energy boundary flux: enthalpy, kinetic and potential energy carried by the
        // boundary mass fluxes (donor properties)
        (budget.total_energy_flux, budget.mechanical_flux_abs) =
            self.total_energy_flux(&next, st.dt, st.inlet1, st.outlet1);
        // the heat the end throttles gave the outflow leaves with it
        budget.exported_heat = w.exported_heat * st.dt;
        budget.total_energy_flux -= budget.exported_heat;
        next.time = st.s.time + st.dt;
        all_finite(&next)?;
        let mut change = self.change_control(st, w, &next)?;
        // the volume error enters the step control like a controlled variable's change
        let volume = volume_error_check(st, w, &next)?;
        if volume.ratio > change.ratio {
            change = volume;
        }
        Ok((
            next,
            StepReport {
                change_ratio: change.ratio,
                max_volume_error: max_verr,
                limiting: change.worst.variable,
                limiting_index: change.worst.cell,
                exit_choked: st.choke > 0.0,
                mixture_cells: w.mixture.iter().filter(|&&m| m).count() as u32,
                refilled_cells: w.refilled.iter().filter(|&&r| r).count() as u32,
                budget,
            },
        ))
    }

    /// Step 1 after the old-time sources: the momentum system, the pressure equation, the new
    /// velocities.
    fn step_one(&self, st: &StepInput, w: &mut Work) -> Result<State, Rejection> {
        self.momentum_predictor(st, w);
        self.pressure_weights(st, w)?;
        self.provisional_velocities(st, w)?;
        self.pressure_equation(st, w);
        self.pressure_solve(st, w)?;
        Ok(self.velocity_update(st, w))
    }

    /// The open fraction of junction `j`'s flow area: a boundary valve's at the ends, 1 inside.
    fn open_fraction(&self, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> f64 {
        if j == 0 {
            inlet.open_fraction
        } else if j == self.grid.n {
            outlet.open_fraction
        } else {
            1.0
        }
    }

    /// Junction `j`'s flow area, m²: its area times the open fraction (a boundary valve's open
    /// part at the ends), the area its fluxes and its velocities go through.
    fn flow_area(&self, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> f64 {
        self.grid.area_junction[j] * self.open_fraction(j, inlet, outlet)
    }

    /// The volume of junction `j`'s momentum control volume in which the fluid moves at the
    /// junction's velocities, m³: its flow area (a boundary valve's open part) times its length.
    ///
    /// Decision: the heat the momentum equations' forces book at a junction is their power per
    /// unit volume times this volume. A boundary junction's velocities are those through its
    /// valve's open area (its fluxes take the area times the open fraction), so the volume is
    /// the open part's; on the whole area, a part-open valve's form loss booked 1/open times
    /// the work it did. Para-hydrogen entering the NBS line at 11 atm through the inlet valve's
    /// 2 s opening made 587 J of energy in its first second, 793 J in half a second with gas
    /// entering and every closure off (BENCHMARKS.md, "The heat of a part-open valve's loss").
    fn junction_volume(&self, j: usize, inlet: &BoundaryState, outlet: &BoundaryState) -> f64 {
        self.flow_area(j, inlet, outlet) * self.grid.dx_junction(j)
    }
}

/// The inputs of one step that its phases share: the old state, the step, the boundary states
/// at the old and the new time.
#[derive(Debug, Clone, Copy)]
struct StepInput<'s> {
    /// The state at the old time level.
    s: &'s State,
    /// The step, s.
    dt: f64,
    /// Number of cells (the junctions are `0..=n`).
    n: usize,
    /// Inlet boundary state at the old time.
    inlet0: &'s BoundaryState,
    /// Outlet boundary state at the old time.
    outlet0: &'s BoundaryState,
    /// Inlet boundary state at the new time.
    inlet1: &'s BoundaryState,
    /// Outlet boundary state at the new time.
    outlet1: &'s BoundaryState,
    /// The inlet boundary's pressure change over the step, Pa.
    dp_in: f64,
    /// The outlet boundary's pressure change over the step, Pa.
    dp_out: f64,
    /// The choked exit's resistance λ, 1/s: λ α_k ρ_k v_k on each phase at the exit junction
    /// (the last step's at the first pass, 0 where the exit is not checked; `choking.rs`).
    choke: f64,
}

impl StepInput<'_> {
    /// The velocities (gas, liquid) that a boundary prescribes at junction `j` (a velocity
    /// boundary's, zero at a closed end), or `None` where the momentum equations decide them.
    fn prescribed(&self, j: usize) -> Option<(f64, f64)> {
        let b = if j == 0 {
            Some(self.inlet1)
        } else if j == self.n {
            Some(self.outlet1)
        } else {
            None
        }?;
        match b.kind {
            BoundaryKind::Velocity => Some((b.v_g, b.v_l)),
            BoundaryKind::Closed => Some((0.0, 0.0)),
            _ => None,
        }
    }

    /// The pressure change of cell `i` in `d`, or of the boundary beyond the first or last cell.
    fn dp_at(&self, i: isize, d: &[f64]) -> f64 {
        if i < 0 {
            self.dp_in
        } else if i as usize >= self.n {
            self.dp_out
        } else {
            d[i as usize]
        }
    }
}

/// Reusable work arrays of the scheme: the scratch space the phases of a step pass their
/// results on in (sized by `resize` at every step, allocated at the first). Each field names
/// the phase that writes it.
#[derive(Debug, Clone, Default)]
struct Work {
    /// Per junction: the coefficients of step 1's forces, for the work they do
    /// (`momentum_predictor`).
    mech: Vec<JunctionWork>,
    /// Per junction: the gas and liquid fractions of the momentum equations' pressure force
    /// (none where the velocities are prescribed; `momentum_predictor`).
    alpha_mom: Vec<Option<(f64, f64)>>,
    /// Per cell: the pressure work of the momentum equations that the energy equations' flow
    /// work did not book, J (taken from the cell's internal energy; `work_consistency`).
    work_fix: Vec<f64>,
    /// Per cell: the new wetted fraction of the wall (`old_time_sources`).
    wetted: Vec<f64>,
    /// Dissipated heat per cell going to the gas and the liquid, W (with the old velocities in
    /// step 1, `pressure_equation`; with the work of the implicit forces in step 2,
    /// `dissipated_heat`).
    heat_g: Vec<f64>,
    /// See `heat_g`.
    heat_l: Vec<f64>,
    /// Per cell: the pressure change of the step, Pa (`velocity_update`).
    dp: Vec<f64>,
    /// Per cell: the new gas and liquid masses per unit volume, kg/m³ (`mass_update`).
    mass_g: Vec<f64>,
    /// See `mass_g`.
    mass_l: Vec<f64>,
    /// Per cell: each phase's volume-fraction change over the step (`phase_volume_changes`).
    dvol_g: Vec<f64>,
    /// See `dvol_g`.
    dvol_l: Vec<f64>,
    /// Per cell: the vapour generation and the gas and liquid energy sources at the
    /// provisional state, the phase change of the cells in `limited` limited
    /// (`provisional_sources`).
    gamma_used: Vec<f64>,
    /// See `gamma_used`.
    sg_used: Vec<f64>,
    /// See `gamma_used`.
    sl_used: Vec<f64>,
    /// Per cell: whether its phase change is limited by the phase it held at the old time
    /// (`mark_limited`).
    limited: Vec<bool>,
    /// Per cell: whether a phase's temperature was reset or a phase changed at its table's
    /// edge (`state_recovery`).
    reset: Vec<bool>,
    /// Per cell: the part of the new volume error that the cell's resets and edge phase
    /// changes made (`state_recovery`; see [`acceptance::volume_error_check`]).
    reset_volume: Vec<f64>,
    /// Per cell: what the edge phase changes of its recovery moved between the phases
    /// (`state_recovery`; not the step's change of the void fraction, [`Scheme::change_control`]).
    edge: Vec<EdgeMove>,
    /// Per cell: the fraction of the old volume error the pressure solve corrects
    /// (`pressure_equation`).
    corrected: Vec<f64>,
    /// The volume errors of the last step rejected for them, for its retries
    /// ([`acceptance::volume_error_check`]).
    volume_retry: RetryRecord,
    /// The changes of each variable of [`acceptance::CELL_VARIABLES`] in the last step the
    /// change control rejected, for its retries ([`Scheme::change_control`]).
    cell_retry: [RetryRecord; 4],
    /// Per cell: whether it was recovered as one near-critical mixture (`state_recovery`).
    mixture: Vec<bool>,
    /// Per cell: whether it was recovered again at the pressure at which its phases fill it
    /// (`state_recovery`, [`Scheme::refill`]).
    refilled: Vec<bool>,
    /// Per cell: whether a whole phase went over to the other at its table's edge
    /// (`state_recovery`; exempt from the step's change control, [`Scheme::change_control`]).
    merged: Vec<bool>,
    /// Per junction: the heat its momentum forces put into the fluid, W/m³ ([`momentum::booked_heat`];
    /// estimated in `provisional_velocities`, booked in `dissipated_heat`).
    junction_heat: Vec<f64>,
    /// Per junction: the slope of `junction_heat` in the junction's pressure difference change
    /// δp_L − δp_R, W/(m³ Pa) (`provisional_velocities`; the pressure equation's heat).
    heat_slope: Vec<f64>,
    /// The power that the boundary junctions' form losses and a choked exit's resistance gave
    /// the fluid leaving the line, W (`dissipated_heat`; [`momentum::exported_heat`]): not
    /// booked in a cell, it leaves with the outflow.
    exported_heat: f64,
    /// The velocity changes of the last step the scheme accepted ([`Scheme::change_control`]).
    trend: VelocityTrend,
    /// Per junction: the provisional gas and liquid velocities (`provisional_velocities`).
    vt_g: Vec<f64>,
    /// See `vt_g`.
    vt_l: Vec<f64>,
    /// Per junction: the gas and liquid velocity–pressure weights (`pressure_weights`).
    w_g: Vec<f64>,
    /// See `w_g`.
    w_l: Vec<f64>,
    /// Per cell: a tridiagonal system — sub-diagonal `a`, diagonal `b`, super-diagonal `c`,
    /// right-hand side `d` (the solution after the solve), solver scratch `s` — of each
    /// conservative update.
    a: Vec<f64>,
    /// See `a`.
    b: Vec<f64>,
    /// See `a`.
    c: Vec<f64>,
    /// See `a`.
    d: Vec<f64>,
    /// See `a`.
    s: Vec<f64>,
    /// Per junction: the block-tridiagonal momentum system — sub-diagonal, diagonal and
    /// super-diagonal 2×2 blocks, right-hand sides (the provisional velocities after the solve),
    /// solver scratch (`momentum_predictor`, `provisional_velocities`).
    lower: Vec<Matrix2<f64>>,
    /// See `lower`.
    diag: Vec<Matrix2<f64>>,
    /// See `lower`.
    upper: Vec<Matrix2<f64>>,
    /// See `lower`.
    rhs2: Vec<Vector2<f64>>,
    /// See `lower`.
    scratch2: Vec<Matrix2<f64>>,
    /// Per cell: its storage terms and residuals (`pressure_equation`; the donors' contents at
    /// the new time are linear in them).
    storage: Vec<Matrix4<f64>>,
    /// See `storage`.
    residual: Vec<Vector4<f64>>,
    /// Per cell: the block-tridiagonal pressure system — sub-diagonal, diagonal and
    /// super-diagonal 4×4 blocks, solver scratch (`pressure_equation`, `pressure_solve`; the
    /// right-hand sides are in `x` until the solve).
    blo: Vec<Matrix4<f64>>,
    /// See `blo`.
    bdi: Vec<Matrix4<f64>>,
    /// See `blo`.
    bup: Vec<Matrix4<f64>>,
    /// See `blo`.
    bscr: Vec<Matrix4<f64>>,
    /// Per cell: the linearised sources at the old state (`old_time_sources`).
    sources: Vec<Sources>,
    /// The state the closures in `old_cells` and `old_junctions` were evaluated at (`phases`
    /// empties them for another).
    old_state: OldStateKey,
    /// Per cell: the closures at the old state that the step's length does not change
    /// (`old_time_sources`; kept from one attempt to the next from the same state).
    old_cells: Vec<sources::OldCell>,
    /// Per junction: its momentum coefficients at the old state where the step's length does
    /// not enter them (`momentum_predictor`; kept as `old_cells`).
    old_junctions: momentum::OldJunctions,
    /// Whether `storage`, `residual` and `corrected` hold the old state's (`pressure_equation`;
    /// kept as `old_cells`).
    storage_kept: bool,
    /// Per cell: the step-1 unknowns (δp, δα, δT_g, δT_l) (`pressure_solve`; before it, the
    /// pressure equation's right-hand sides, `pressure_equation`).
    x: Vec<Vector4<f64>>,
}

/// What a cell's edge phase changes moved between its phases in a step (`state_recovery`).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct EdgeMove {
    /// The mass moved to the gas (negative: to the liquid), kg/m³.
    mass: f64,
    /// The change of the gas's volume fraction it made: for liquid flashed into the gas, the
    /// change of the gas's volume that the flashed mass and energy made (the flash cools the
    /// gas, [`acceptance::void_without_edge_change`]).
    gas_volume: f64,
}

impl std::ops::AddAssign for EdgeMove {
    fn add_assign(&mut self, other: Self) {
        self.mass += other.mass;
        self.gas_volume += other.gas_volume;
    }
}

/// Cell `i`'s new pressure as step 1 solved it (the old pressure plus its change `w.x[i][0]`):
/// the pressure the new velocities were solved with, and the one step 2 charges the faces' flow
/// work at.
fn new_pressure(s: &State, w: &Work, i: usize) -> f64 {
    s.p[i] + w.x[i][0]
}

/// The old state of the closures kept in the work arrays from one attempt at a step to the next
/// (`Work::old_cells`, `Work::old_junctions`): a step tried again from the same state (after a
/// rejection, at a shorter length) takes them as they are.
///
/// Decision: the state is recognised by its contents (every field equal), not by its time, so
/// that no caller reaches closures kept for another state at the same time. The comparison and
/// the copy cost about what one copy of the state does, against about a third of an attempt's
/// work that a retry is spared (the subcooled NBS run: 112 M instructions over its 414 retries
/// and 70 repeated passes of step 1 at its choked exit, of 650 k per attempt).
#[derive(Debug, Clone, Default)]
struct OldStateKey {
    state: Option<State>,
}

impl OldStateKey {
    /// Whether the kept closures are those of `s`.
    fn holds(&self, s: &State) -> bool {
        self.state.as_ref().is_some_and(|k| k == s)
    }

    /// Records `s` as the state of the kept closures.
    fn keep(&mut self, s: &State) {
        match &mut self.state {
            Some(k) => k.copy_from(s),
            None => self.state = Some(s.clone()),
        }
    }
}

/// Sizes the work arrays for `n` cells (`n + 1` junctions).
fn resize(w: &mut Work, n: usize) {
    let nj = n + 1;
    let m = nj.max(n);
    w.mech.resize(nj, JunctionWork::default());
    for v in [&mut w.vt_g, &mut w.vt_l, &mut w.w_g, &mut w.w_l, &mut w.junction_heat, &mut w.heat_slope] {
        v.resize(nj, 0.0);
    }
    for v in [&mut w.a, &mut w.b, &mut w.c, &mut w.d, &mut w.s] {
        v.resize(n, 0.0);
    }
    w.lower.resize(m, Matrix2::zeros());
    w.diag.resize(m, Matrix2::zeros());
    w.upper.resize(m, Matrix2::zeros());
    w.rhs2.resize(m, Vector2::zeros());
    w.scratch2.resize(m, Matrix2::zeros());
    for v in [&mut w.storage, &mut w.blo, &mut w.bdi, &mut w.bup, &mut w.bscr] {
        v.resize(n, Matrix4::zeros());
    }
    w.residual.resize(n, Vector4::zeros());
    w.sources.resize(n, Sources::default());
    w.wetted.resize(n, 0.0);
    for v in [
        &mut w.heat_g,
        &mut w.heat_l,
        &mut w.dp,
        &mut w.mass_g,
        &mut w.mass_l,
        &mut w.dvol_g,
        &mut w.dvol_l,
        &mut w.gamma_used,
        &mut w.sg_used,
        &mut w.sl_used,
        &mut w.reset_volume,
        &mut w.corrected,
    ] {
        v.resize(n, 0.0);
    }
    w.edge.resize(n, EdgeMove::default());
    w.reset.resize(n, false);
    w.limited.resize(n, false);
    w.merged.resize(n, false);
    w.mixture.resize(n, false);
    w.refilled.resize(n, false);
    w.volume_retry.resize(n);
    for r in &mut w.cell_retry {
        r.resize(n);
    }
    w.alpha_mom.resize(nj, None);
    w.work_fix.resize(n, 0.0);
    w.x.resize(n, Vector4::zeros());
}

/// Conserved quantities per unit volume of the fluid entering through a boundary:
/// (mass, internal energy, phase fraction) of the gas or the liquid.
fn boundary_conserved(b: &BoundaryState, gas: bool) -> (f64, f64, f64) {
    if gas {
        (b.alpha * b.gas.rho, b.alpha * b.gas.rho * b.gas.u, b.alpha)
    } else {
        let a = 1.0 - b.alpha;
        (a * b.liquid.rho, a * b.liquid.rho * b.liquid.u, a)
    }
}

/// Saturation properties at `p`, or all zeros where there are none (above the critical pressure
/// or below the triple point): `h_lg = 0` then switches phase change off for the cell.
pub fn saturation_or_none(fluid: &FluidTable, p: f64) -> Saturation {
    fluid.saturation(p).unwrap_or(Saturation { pressure_pa: p, ..Saturation::default() })
}

/// The liquid's share of the mass in cell `i`, m_l/(m_g + m_l).
///
/// Decision: the liquid's presence weight (phase blending, `blend_xmin`/`blend_xmax`) is taken
/// on its mass share, the gas's on its volume fraction. Blending is numerics for a phase too
/// small to matter: liquid is that when it carries a negligible share of the mass, and a mist
/// behind a quench front at a volume fraction of 10⁻³ carries a fifth of it (ρ_l/ρ_g ≈ 200 for
/// nitrogen at 3 bar). Weighed by its volume fraction, that mist had its velocity tied to the
/// vapour's and its temperature relaxed to saturation, and the station-4 chilldowns moved by
/// 3–4 % between `blend_xmax` = 10⁻⁴ and 10⁻² (VALIDATION.md). Vapour in a liquid-filled cell
/// has a negligible mass share at any void fraction, so for the gas the volume fraction stays
/// the measure: below 1 % of the volume a vapour trace is bubbles that follow the liquid.
fn liquid_share(s: &State, i: usize) -> f64 {
    let (m_g, m_l) = (s.m_g[i].max(0.0), s.m_l[i].max(0.0));
    if m_g + m_l > 0.0 { m_l / (m_g + m_l) } else { 1.0 - s.alpha[i] }
}

/// Is a phase of mass `m` present next to the other phase's mass `other` (per unit volume)?
#[inline]
fn present(m: f64, other: f64) -> bool {
    m > PRESENT_MASS_FRACTION * (m + other)
}
