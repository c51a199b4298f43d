//! The driver: initial state, time-step control, probes, profiles and the run summary.
//!
//! [`run`] sets a case up, then loops: the run's observers see the state (`observers.rs`: probes,
//! profiles, chilldown and quench arrivals, budgets), the [`StepController`] proposes a step
//! (`control.rs`, its settings in [`StepControl`]), the scheme takes it, the controller accepts
//! or rejects it, and the observers see the accepted step; the output is assembled from them.

mod control;
mod observers;

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

use crate::case::{BoundaryKind, Case, TimeSection};
use crate::fluids::{FluidError, FluidTable, Phase};
use crate::model::{BoundaryState, Grid, State, boundary_state, clamp_to_phase};
use crate::params::ParameterSet;
use crate::scheme::{Physics, Rejection, Scheme, StepReport};

pub use control::{StepControl, StepController};
use observers::{EnergyBudget, FrontArrivals, OutputClock, ProbeRecorder, ProfileRecorder, RunObserver, Station};

/// Why a run ended without reaching its end time.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// The time step fell below the minimum.
    #[error(
        "time step fell below {min_dt_s:e} s at t = {time_s:.6} s: cell {cell}, {variable} = {value}: {reason} (try a smaller time.min_dt_s, a finer grid, or check the boundary conditions)"
    )]
    StepTooSmall {
        /// Simulated time, s.
        time_s: f64,
        /// The minimum step, s.
        min_dt_s: f64,
        /// Cell or junction index.
        cell: usize,
        /// Variable that failed.
        variable: &'static str,
        /// Its value.
        value: f64,
        /// Why.
        reason: &'static str,
    },
    /// `time.max_steps` reached.
    #[error("stopped after time.max_steps = {steps} steps at t = {time_s:.6} s")]
    MaxSteps {
        /// Steps taken.
        steps: u64,
        /// Simulated time, s.
        time_s: f64,
    },
    /// `time.max_wall_s` reached.
    #[error("stopped after time.max_wall_s = {wall_s} s of computing at t = {time_s:.6} s")]
    MaxWall {
        /// Limit, s.
        wall_s: f64,
        /// Simulated time, s.
        time_s: f64,
    },
    /// A property query failed while setting up.
    #[error("{0}")]
    Fluid(#[from] FluidError),
    /// A parameter name or value is not acceptable.
    #[error("{0}")]
    Parameter(String),
    /// The initial state cannot be built.
    #[error("initial state: {0}")]
    Initial(String),
}

/// One observation: `time_s,station,x_m,quantity,value` (DESIGN.md §3.2).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Observation {
    /// Time, s.
    pub time_s: f64,
    /// Station name.
    pub station: String,
    /// Station position, m.
    pub x_m: f64,
    /// Quantity name.
    pub quantity: &'static str,
    /// Value, SI.
    pub value: f64,
}

/// One profile value: `time_s,x_m,quantity,value`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProfilePoint {
    /// Time, s.
    pub time_s: f64,
    /// Position (cell centre, or junction for velocities), m.
    pub x_m: f64,
    /// Quantity name.
    pub quantity: &'static str,
    /// Value, SI.
    pub value: f64,
}

/// Run statistics and derived results (`summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Accepted steps.
    pub steps: u64,
    /// Rejected (retried) steps.
    pub rejected_steps: u64,
    /// Wall-clock seconds of the integration itself.
    pub wall_time_s: f64,
    /// Simulated time reached, s.
    pub simulated_time_s: f64,
    /// Smallest accepted step, s.
    pub min_dt_s: f64,
    /// Largest accepted step, s.
    pub max_dt_s: f64,
    /// |Δ mass − (in − out)| / max(initial mass, throughput).
    pub mass_balance_error: f64,
    /// Physical total-energy balance (fluid internal + kinetic + potential energy and the wall's
    /// energy against the boundary fluxes and the ambient heat), relative: |residual| divided by
    /// the heat the wall gave up to the fluid (by the mechanical energy that moved where no
    /// heat did, in cases without wall heat). Every adjustment the step makes outside the
    /// balance equations is part of the residual.
    pub energy_balance_error: f64,
    /// The physical total-energy residual itself, J (signed: energy created is positive).
    pub energy_balance_residual_j: f64,
    /// Heat the wall gave up to the fluid over the run, J (the denominator of
    /// `energy_balance_error`).
    pub wall_heat_j: f64,
    /// The scheme's own discrete energy budget residual, relative.
    pub scheme_energy_error: f64,
    /// Largest |volume error| seen.
    pub max_volume_error: f64,
    /// Energy added or removed by state adjustments outside the balance equations over the
    /// run (trace-phase resets and clamps), J: the sum of their magnitudes, so that additions
    /// and removals do not cancel. The net of them is part of `energy_balance_residual_j`.
    pub trace_adjustment_j: f64,
    /// Kinetic energy the momentum equations turned into heat over the run, J: wall friction, form
    /// losses, interphase drag and the donor-cell convection's numerical dissipation
    /// (`scheme::booked_heat`).
    pub dissipation_j: f64,
    /// Heat that the throttles at the line's ends (a boundary's valve or entrance loss, a choked
    /// exit's expansion) gave the fluid leaving the line over the run, J: it left with that
    /// fluid, as part of the boundaries' total-energy flux (`scheme::exported_heat`).
    pub exported_heat_j: f64,
    /// Why steps were rejected: "variable: reason" and how often (to see what makes a run slow).
    pub rejection_causes: BTreeMap<String, u64>,
    /// What held the accepted steps, and how often: the cap that set a step where one did (the
    /// case's largest step, the Courant limit, the end of the interval), else the controlled
    /// variable that came closest to its limit.
    pub step_limited_by: BTreeMap<String, u64>,
    /// Simulated time during which the line's exit was choked (the fluid leaving at the speed
    /// of sound of its mixture, whatever the pressure beyond), s.
    pub exit_choked_s: f64,
    /// Cell states recovered as one near-critical mixture because their phases could not be
    /// recovered one by one, or because a volume error that no step shrinks had no filling
    /// pressure (mass and energy kept exactly; `scheme/recovery.rs`), summed over the accepted
    /// steps.
    pub mixture_recoveries: u64,
    /// Cell states recovered again at the pressure at which their phases fill the cell, where a
    /// retried step's volume error did not shrink with the step or a phase's merge into the
    /// other left a volume error above its limit (the equation of state solved for the
    /// pressure, mass and energy kept exactly; `scheme/refill.rs`, `scheme/recovery.rs`), summed
    /// over the accepted steps.
    pub pressure_refills: u64,
    /// First time the wall falls below the inlet liquid temperature + 15 K, per station.
    pub chilldown_time_s: BTreeMap<String, Option<f64>>,
    /// First time the wall falls below 150 K, per station.
    pub quench_arrival_s: BTreeMap<String, Option<f64>>,
    /// Inlet liquid temperature used for the chilldown criterion, K.
    pub inlet_liquid_temperature_k: f64,
}

/// Everything a run produces.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// Probe time series.
    pub probes: Vec<Observation>,
    /// Whole-line profiles.
    pub profiles: Vec<ProfilePoint>,
    /// Statistics and derived results.
    pub summary: Summary,
    /// The final state.
    pub final_state: State,
}

/// One attempt at a step, accepted or rejected, as [`run_logged`] reports it: what held the run's
/// steps down, and when (the summary's `step_limited_by` and `rejection_causes` count the same
/// over the whole run).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepAttempt {
    /// Time at the start of the step, s.
    pub time_s: f64,
    /// The step tried, s.
    pub dt_s: f64,
    /// Whether the scheme accepted the step (a rejected one is retried shorter from `time_s`).
    pub accepted: bool,
    /// Accepted: the cap that set the step where one did (the case's largest step, the Courant
    /// limit, the end of the interval; [`StepController::proposal`]), else the controlled variable
    /// that came closest to its limit. Rejected: the variable that rejected the step.
    pub variable: &'static str,
    /// The cell of `variable` (the junction, for a velocity).
    pub index: usize,
    /// Accepted: the step's change ratio (the largest change of a controlled variable, or volume
    /// error, as a fraction of its limit; ≤ 1). Rejected: the value that rejected it.
    pub value: f64,
    /// Rejected: why; accepted: empty.
    pub reason: &'static str,
}

impl StepAttempt {
    /// The accepted step of `dt_s` from `time_s` with the scheme's `report` of it.
    fn accepted(time_s: f64, dt_s: f64, report: &StepReport) -> Self {
        let (variable, index, value) = (report.limiting, report.limiting_index, report.change_ratio);
        Self { time_s, dt_s, accepted: true, variable, index, value, reason: "" }
    }

    /// The step of `dt_s` from `time_s` that the scheme rejected with `rejection`.
    fn rejected(time_s: f64, dt_s: f64, rejection: &Rejection) -> Self {
        let Rejection { cell, variable, value, reason } = *rejection;
        Self { time_s, dt_s, accepted: false, variable, index: cell, value, reason }
    }
}

/// Progress of a run, for a progress bar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Simulated time, s.
    pub time_s: f64,
    /// End time, s.
    pub end_s: f64,
    /// Steps so far.
    pub steps: u64,
}

/// The vapour's c_p/R near the ideal-gas limit, at the normal boiling temperature and the
/// table's lowest pressure (Theler's k_g; 3.5 for nitrogen), or NaN where the table holds no
/// such state.
pub fn ideal_cp_over_r(fluid: &FluidTable) -> f64 {
    let c = fluid.constants();
    let Ok(sat) = fluid.saturation(101_325.0) else { return f64::NAN };
    fluid.phase_props(Phase::Gas, c.p_min_pa, sat.t_sat).map(|g| g.cp / c.gas_constant_j_kg_k).unwrap_or(f64::NAN)
}

/// Physics settings of a case with the given parameter values (already merged with the case's
/// `[parameters]` by the caller, see [`case_parameters`]).
pub fn physics_of(case: &Case, params: &ParameterSet, fluid: &FluidTable) -> Physics {
    let p = &case.physics;
    Physics {
        cryo: crate::cryo::CryoParams::from_set(params)
            .with_fluid(fluid.constants())
            .with_ideal_cp_over_r(ideal_cp_over_r(fluid)),
        correlations: p.correlations.parse().unwrap_or(crate::cryo::CorrelationSet::Paper),
        interphase_htc_w_m3k: params.get("hi_vol"),
        phase_change: p.phase_change,
        wall_heat_transfer: p.wall_heat_transfer,
        interphase_heat_transfer: p.interphase_heat_transfer,
        interphase_drag: p.interphase_drag,
        wall_friction: p.wall_friction,
        gravity: p.gravity,
        virtual_mass: p.virtual_mass,
        fixed_wall_htc: p.wall_htc_w_m2k,
        ambient_temperature_k: case.ambient.temperature_k,
        ambient_htc_w_m2k: case.ambient.heat_transfer_coefficient_w_m2k,
    }
}

/// The case's `[parameters]` as a checked parameter set (errors name the case's field).
pub fn case_parameters(case: &Case) -> Result<ParameterSet, SimError> {
    let mut set = ParameterSet::new();
    for (name, value) in &case.parameters {
        set.set(name, *value).map_err(|e| SimError::Parameter(format!("parameters.{name}: {e}")))?;
    }
    Ok(set)
}

/// The state at t = 0 from the case's `[initial]` section.
pub fn initial_state(case: &Case, fluid: &FluidTable, grid: &Grid) -> Result<State, SimError> {
    let n = grid.n;
    let ini = &case.initial;
    let mut s = State {
        time: 0.0,
        p: vec![0.0; n],
        alpha: vec![0.0; n],
        t_g: vec![0.0; n],
        t_l: vec![0.0; n],
        m_g: vec![0.0; n],
        m_l: vec![0.0; n],
        e_g: vec![0.0; n],
        e_l: vec![0.0; n],
        gas: Vec::with_capacity(n),
        liquid: Vec::with_capacity(n),
        volume_error: vec![0.0; n],
        v_g: grid.x_junction.iter().map(|&x| ini.gas_velocity_m_s.at(x)).collect(),
        v_l: grid.x_junction.iter().map(|&x| ini.liquid_velocity_m_s.at(x)).collect(),
        t_w: vec![0.0; n],
        e_w: vec![0.0; n],
        wall_heat_flux: vec![0.0; n],
        wetted: vec![0.0; n],
        sat: Vec::with_capacity(n),
        boundary_mass_flow: [0.0; 2],
        exit_resistance: 0.0,
        mixture: vec![false; n],
    };
    for i in 0..n {
        let x = grid.x_cell[i];
        let p = ini.pressure_pa.at(x);
        let a = ini.void_fraction.at(x);
        let tg_req = ini.gas_temperature_k.at(x);
        let tl_req = ini.liquid_temperature_k.as_ref().map_or(tg_req, |t| t.at(x));
        // a phase that is present must be representable as given; an absent one takes the
        // nearest representable temperature
        let tg = if a > 0.0 { tg_req } else { clamp_to_phase(fluid, Phase::Gas, p, tg_req) };
        let tl = if a < 1.0 && ini.liquid_temperature_k.is_some() {
            tl_req
        } else {
            clamp_to_phase(fluid, Phase::Liquid, p, tl_req)
        };
        let gp = fluid.phase_props(Phase::Gas, p, tg).map_err(|e| SimError::Initial(format!("at x = {x} m: {e}")))?;
        let lp =
            fluid.phase_props(Phase::Liquid, p, tl).map_err(|e| SimError::Initial(format!("at x = {x} m: {e}")))?;
        s.p[i] = p;
        s.alpha[i] = a;
        s.t_g[i] = tg;
        s.t_l[i] = tl;
        s.m_g[i] = a * gp.rho;
        s.m_l[i] = (1.0 - a) * lp.rho;
        s.e_g[i] = s.m_g[i] * gp.u;
        s.e_l[i] = s.m_l[i] * lp.u;
        s.gas.push(gp);
        s.liquid.push(lp);
        let tw = ini.wall_temperature_k.at(x);
        s.t_w[i] = tw;
        s.e_w[i] = grid.material.table().energy(tw);
        s.sat.push(crate::scheme::saturation_or_none(fluid, p));
        // liquid present at the start wets the wall
        s.wetted[i] = if a < 1.0 { 1.0 } else { 0.0 };
    }
    Ok(s)
}

/// The temperature a thermocouple in the stream reads: the observation function g(x) of the
/// paper's state-space model. Defined as the phasic temperatures blended by volume fraction,
/// T_f = (1 − α) T_l + α T_g: a probe in liquid-filled flow reads the liquid, in vapour the
/// vapour, and in between the phase that wets it in proportion to its share of the section.
pub fn fluid_temperature(alpha: f64, t_g: f64, t_l: f64) -> f64 {
    (1.0 - alpha) * t_l + alpha * t_g
}

/// An output time (and the end time) counts as reached once the run is within this fraction of
/// the end time of it.
const OUTPUT_TIME_TOLERANCE: f64 = 1e-9;

/// [`run`] calls its progress callback after every this many accepted steps.
const PROGRESS_INTERVAL_STEPS: u64 = 64;

/// Runs a case to its end time with parameter values `params` (defaults for the rest).
///
/// Sets up the grid, the initial state, the scheme, a [`StepController`] with the default
/// [`StepControl`] and the run's observers (probes, profiles, chilldown and quench arrivals, the
/// budgets); then, until the end time: every observer sees the state, the controller proposes a
/// step, the scheme takes it (smaller after each rejection: `advance`) and every observer sees
/// the accepted step. The output is assembled from the observers and the controller's
/// statistics.
pub fn run(
    case: &Case,
    fluid: &FluidTable,
    params: &ParameterSet,
    progress: &mut dyn FnMut(Progress),
) -> Result<Output, SimError> {
    run_logged(case, fluid, params, progress, &mut |_| {})
}

/// [`run`], reporting every attempt at a step, accepted or rejected, to `log` as it is made (so
/// that a run that fails has reported the steps that led to its failure).
pub fn run_logged(
    case: &Case,
    fluid: &FluidTable,
    params: &ParameterSet,
    progress: &mut dyn FnMut(Progress),
    log: &mut dyn FnMut(StepAttempt),
) -> Result<Output, SimError> {
    let grid = Grid::from_case(case);
    let mut s = initial_state(case, fluid, &grid)?;
    let physics = physics_of(case, params, fluid);
    let mut scheme = Scheme::new(fluid, grid.clone(), physics);
    let t = &case.time;
    let end = t.end_s;
    let clock = Instant::now();
    let mut boundaries = Boundaries { case, fluid, p_guess: s.p[0], last: None };
    let inlet_tl = boundary_state(&case.inlet, 0.0, fluid, boundaries.p_guess)?.t_l;
    let stations: Vec<Station> = case.stations.iter().map(|st| Station::new(&grid, &st.name, st.x_m)).collect();
    let eps = OUTPUT_TIME_TOLERANCE * end;
    let mut probes = ProbeRecorder::new(&grid, &stations, OutputClock::new(t.output_interval_s, eps));
    let mut profiles = ProfileRecorder::new(&grid, OutputClock::new(t.profile_interval_s, eps));
    let mut arrivals = FrontArrivals::new(&stations, inlet_tl);
    let mut budget = EnergyBudget::new(&s, &grid, case.physics.gravity);
    let mut controller = StepController::new(StepControl::default(), t);
    let mut observers: [&mut dyn RunObserver; 4] = [&mut probes, &mut profiles, &mut arrivals, &mut budget];
    let mut before: Option<State> = None;
    loop {
        observers.iter_mut().for_each(|o| o.on_state(before.as_ref(), &s));
        if s.time >= end - eps {
            break;
        }
        check_limits(t, controller.steps(), &clock, s.time)?;
        // the steps land on the end time only: the outputs between are interpolated
        // (`observers::weight_at` says why)
        let (mut next, h, report) = advance(&mut scheme, &mut controller, &s, end, &mut boundaries, log)?;
        observers.iter_mut().for_each(|o| o.on_step(h, &report));
        // a step that lands on the end to within rounding lands on it exactly
        if (next.time - end).abs() <= eps {
            next.time = end;
        }
        before = Some(std::mem::replace(&mut s, next));
        if controller.steps().is_multiple_of(PROGRESS_INTERVAL_STEPS) {
            progress(Progress { time_s: s.time, end_s: end, steps: controller.steps() });
        }
    }
    let wall_time_s = clock.elapsed().as_secs_f64();
    let steps = controller.into_statistics();
    let balances = budget.finish(&s);
    Ok(Output {
        probes: probes.into_probes(),
        profiles: profiles.into_profiles(),
        summary: Summary {
            steps: steps.steps,
            rejected_steps: steps.rejected,
            wall_time_s,
            simulated_time_s: s.time,
            min_dt_s: if steps.min_dt.is_finite() { steps.min_dt } else { 0.0 },
            max_dt_s: steps.max_dt,
            mass_balance_error: balances.mass_balance_error,
            energy_balance_error: balances.energy_balance_error,
            energy_balance_residual_j: balances.energy_balance_residual_j,
            wall_heat_j: balances.wall_heat_j,
            scheme_energy_error: balances.scheme_energy_error,
            max_volume_error: balances.max_volume_error,
            trace_adjustment_j: balances.trace_adjustment_j,
            dissipation_j: balances.dissipation_j,
            exported_heat_j: balances.exported_heat_j,
            rejection_causes: steps.rejection_causes,
            step_limited_by: steps.step_limited_by,
            exit_choked_s: steps.exit_choked_s,
            mixture_recoveries: steps.mixture_recoveries,
            pressure_refills: steps.pressure_refills,
            chilldown_time_s: arrivals.chilldown,
            quench_arrival_s: arrivals.quench,
            inlet_liquid_temperature_k: arrivals.inlet_liquid_temperature_k,
        },
        final_state: s,
    })
}

/// One accepted step from `s`: the step the controller proposes towards `target`, tried again
/// at the smaller size the controller gives after each rejection. Returns the new state, the
/// step taken and the scheme's report. Every attempt, accepted or rejected, goes to `log`.
fn advance(
    scheme: &mut Scheme,
    controller: &mut StepController,
    s: &State,
    target: f64,
    boundaries: &mut Boundaries,
    log: &mut dyn FnMut(StepAttempt),
) -> Result<(State, f64, StepReport), SimError> {
    let (mut h, mut cap) = controller.proposal(s, &scheme.grid, target);
    let b0 = boundaries.at(s.time)?;
    loop {
        let b1 = boundaries.at(s.time + h)?;
        match scheme.step(s, h, [&b0[0], &b0[1]], [&b1[0], &b1[1]]) {
            Ok((next, mut report)) => {
                // a step at a cap was held by the cap, not by a controlled variable
                if let Some((what, index)) = cap {
                    report.limiting = what;
                    report.limiting_index = index;
                }
                log(StepAttempt::accepted(s.time, h, &report));
                controller.accept(h, &report);
                return Ok((next, h, report));
            }
            Err(rejection) => {
                log(StepAttempt::rejected(s.time, h, &rejection));
                h = controller.reject(h, rejection, s.time)?;
                cap = None;
            }
        }
    }
}

/// The case's limits on the number of steps (`time.max_steps`) and on computing time
/// (`time.max_wall_s`): an error once one is reached.
fn check_limits(t: &TimeSection, steps: u64, clock: &Instant, time_s: f64) -> Result<(), SimError> {
    if let Some(ms) = t.max_steps
        && steps >= ms
    {
        return Err(SimError::MaxSteps { steps, time_s });
    }
    if let Some(mw) = t.max_wall_s
        && clock.elapsed().as_secs_f64() > mw
    {
        return Err(SimError::MaxWall { wall_s: mw, time_s });
    }
    Ok(())
}

/// A case's boundary states at any time; `p_guess` (the initial pressure of the first cell)
/// stands for a pressure the boundary does not set.
#[derive(Debug, Clone, Copy)]
struct Boundaries<'a> {
    case: &'a Case,
    fluid: &'a FluidTable,
    p_guess: f64,
    /// The states last asked for and their time: an accepted step's new time is the next
    /// step's old time, at which they are asked for again.
    last: Option<(f64, [BoundaryState; 2])>,
}

impl Boundaries<'_> {
    /// The inlet and outlet states at `time`.
    fn at(&mut self, time: f64) -> Result<[BoundaryState; 2], SimError> {
        if let Some((t, states)) = self.last
            && t == time
        {
            return Ok(states);
        }
        let (case, fluid, p_guess) = (self.case, self.fluid, self.p_guess);
        let states = [
            boundary_state(&case.inlet, time, fluid, p_guess)?,
            boundary_state(&case.outlet, time, fluid, s_last_p(&case.outlet, p_guess))?,
        ];
        self.last = Some((time, states));
        Ok(states)
    }
}

fn s_last_p(b: &crate::case::BoundarySection, fallback: f64) -> f64 {
    match (&b.kind, &b.pressure_pa) {
        (BoundaryKind::Pressure | BoundaryKind::Reservoir, Some(p)) => p.at(0.0),
        _ => fallback,
    }
}

/// Total fluid mass on the line, kg.
pub fn total_mass(s: &State, g: &Grid) -> f64 {
    (0..g.n).map(|i| (s.m_g[i] + s.m_l[i]) * g.volume[i]).sum()
}

/// Chilldown time at a station: the first time its wall falls below the inlet liquid temperature
/// plus this margin, K (DESIGN.md §5).
pub const CHILLDOWN_MARGIN_K: f64 = 15.0;

/// The quantities written for every station, in order (DESIGN.md §3.2).
pub const PROBE_QUANTITIES: [&str; 10] = [
    "wall_temperature_k",
    "fluid_temperature_k",
    "pressure_pa",
    "void_fraction",
    "gas_temperature_k",
    "liquid_temperature_k",
    "gas_velocity_m_s",
    "liquid_velocity_m_s",
    "wall_heat_flux_w_m2",
    "mass_flow_kg_s",
];

/// Wall temperature below which the quench front has reached a station, K (DESIGN.md §5).
pub const QUENCH_TEMPERATURE_K: f64 = 150.0;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::Case;
    use crate::scheme::MAX_VOLUME_ERROR;

    /// One step of `h` from `s` on a fresh scheme for `case`: the largest |volume error| it
    /// leaves, or the rejection.
    fn step_error(case: &Case, fluid: &FluidTable, s: &State, h: f64) -> Result<f64, Rejection> {
        let physics = physics_of(case, &case_parameters(case).unwrap(), fluid);
        let mut scheme = Scheme::new(fluid, Grid::from_case(case), physics);
        let mut boundaries = Boundaries { case, fluid, p_guess: s.p[0], last: None };
        let (b0, b1) = (boundaries.at(s.time).unwrap(), boundaries.at(s.time + h).unwrap());
        let (next, _) = scheme.step(s, h, [&b0[0], &b0[1]], [&b1[0], &b1[1]])?;
        Ok(next.volume_error.iter().fold(0.0, |m: f64, e| m.max(e.abs())))
    }

    /// The pressure equation's energy rows hold the heat and the faces' flow work as step 2
    /// books them, to first order in the step's changes (`Scheme::heat_rows`,
    /// `Scheme::cell_fluxes`), so that the volume error a step leaves is of second order. On
    /// the subcooled NBS run behind its front (vapour and mist at up to 175 m/s at the exit), one
    /// step of 50 ms from the run's state at 60 or 100 s left 1.1e-3 and 1.2e-3 when the
    /// equation took the heat at the provisional velocities and the flow work at the old
    /// pressure and fraction, and leaves 2.1e-4 and 2.5e-4 now (each build from its own run's
    /// state).
    #[test]
    fn a_step_behind_the_front_leaves_a_small_volume_error() {
        let path = format!("{}/../examples/nbs/subcooled-4.2atm.toml", env!("CARGO_MANIFEST_DIR"));
        let mut case = Case::from_toml(&std::fs::read_to_string(&path).unwrap(), &path).unwrap();
        let fluid = crate::fluids::embedded("nitrogen").unwrap();
        for end in [60.0, 100.0] {
            case.time.end_s = end;
            let out = run(&case, fluid, &case_parameters(&case).unwrap(), &mut |_| {}).unwrap();
            let error = step_error(&case, fluid, &out.final_state, 0.05);
            assert!(matches!(error, Ok(e) if e < 0.25 * MAX_VOLUME_ERROR), "a step of 50 ms from {end} s: {error:?}");
        }
    }

    /// A step tried again from the same state reuses the closures the scheme kept from the
    /// attempt before (`Work::old_cells`, `old_junctions`, the storage terms), which the step's
    /// length does not enter: it gives, to the bit, what a fresh scheme gives. A state of the
    /// same time but other contents is not taken for the kept one. On the subcooled NBS run's
    /// state at 30 s (boiling at the front, the exit's mist, the inlet's valve loss).
    #[test]
    fn a_retry_gives_what_a_fresh_scheme_gives() {
        let path = format!("{}/../examples/nbs/subcooled-4.2atm.toml", env!("CARGO_MANIFEST_DIR"));
        let mut case = Case::from_toml(&std::fs::read_to_string(&path).unwrap(), &path).unwrap();
        let fluid = crate::fluids::embedded("nitrogen").unwrap();
        case.time.end_s = 30.0;
        let s = run(&case, fluid, &case_parameters(&case).unwrap(), &mut |_| {}).unwrap().final_state;
        let physics = physics_of(&case, &case_parameters(&case).unwrap(), fluid);
        let at = |t: f64| Boundaries { case: &case, fluid, p_guess: s.p[0], last: None }.at(t).unwrap();
        let step = |scheme: &mut Scheme, s: &State, h: f64| {
            let (b0, b1) = (at(s.time), at(s.time + h));
            scheme.step(s, h, [&b0[0], &b0[1]], [&b1[0], &b1[1]])
        };
        let fresh = |s: &State, h: f64| step(&mut Scheme::new(fluid, Grid::from_case(&case), physics.clone()), s, h);
        let mut kept = Scheme::new(fluid, Grid::from_case(&case), physics.clone());
        // a first attempt, then shorter ones from the same state
        let _ = step(&mut kept, &s, 0.2);
        for h in [0.1, 0.05, 0.025] {
            assert_eq!(step(&mut kept, &s, h), fresh(&s, h), "a retry of {h} s");
        }
        // the same time, another state: a cell's pressure and a junction's velocity moved
        let mut other = s.clone();
        other.p[12] *= 1.0 + 1e-6;
        other.v_g[7] += 1e-3;
        assert_eq!(step(&mut kept, &other, 0.05), fresh(&other, 0.05));
    }
}
