//! The driver: initial state, time-step control, probes, profiles and the run summary.

use std::collections::BTreeMap;
use std::time::Instant;

use serde::Serialize;

use crate::case::{BoundaryKind, Case};
use crate::fluids::{FluidError, FluidTable, Phase};
use crate::model::{BoundaryState, GRAVITY, Grid, State, boundary_state, clamp_to_phase};
use crate::params::ParameterSet;
use crate::scheme::{Physics, Rejection, Scheme, StepBudget};

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
    /// Why steps were rejected: "variable: reason" and how often (to see what makes a run slow).
    pub rejection_causes: BTreeMap<String, u64>,
    /// Which controlled variable came closest to its limit in accepted steps, and how often.
    pub step_limited_by: BTreeMap<String, u64>,
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

/// Runs a case to its end time with parameter values `params` (defaults for the rest).
pub fn run(
    case: &Case,
    fluid: &FluidTable,
    params: &ParameterSet,
    progress: &mut dyn FnMut(Progress),
) -> Result<Output, SimError> {
    let grid = Grid::from_case(case);
    let state = initial_state(case, fluid, &grid)?;
    let physics = physics_of(case, params, fluid);
    let mut scheme = Scheme::new(fluid, grid.clone(), physics);
    let t = &case.time;
    let n = grid.n;
    let clock = Instant::now();
    let mut s = state;
    let mut dt = t.initial_dt_s.min(t.max_dt_s);
    let mut steps = 0u64;
    let mut rejected = 0u64;
    let (mut min_dt, mut max_dt) = (f64::INFINITY, 0.0f64);
    let mut probes = Vec::new();
    let mut profiles = Vec::new();
    let mut next_out = 0.0;
    let mut next_prof = 0.0;
    let mut cum = StepBudget::default();
    let mut max_verr: f64 = 0.0;
    let p_guess = s.p[0];
    let bstate = |time: f64| -> Result<[BoundaryState; 2], SimError> {
        Ok([
            boundary_state(&case.inlet, time, fluid, p_guess)?,
            boundary_state(&case.outlet, time, fluid, s_last_p(&case.outlet, p_guess))?,
        ])
    };
    let inlet_tl = boundary_state(&case.inlet, 0.0, fluid, p_guess)?.t_l;
    let stations: Vec<Station> = case.stations.iter().map(|st| Station::new(&grid, &st.name, st.x_m)).collect();
    let mut chill: BTreeMap<String, Option<f64>> = stations.iter().map(|s| (s.name.clone(), None)).collect();
    let mut quench: BTreeMap<String, Option<f64>> = stations.iter().map(|s| (s.name.clone(), None)).collect();
    let m0 = total_mass(&s, &grid);
    let e0_scheme = fluid_internal_energy(&s, &grid);
    let e0_total = total_energy(&s, &grid, case.physics.gravity);
    let e0_parts = energy_parts(&s, &grid, case.physics.gravity);
    let end = t.end_s;
    let eps = 1e-9 * end;
    let mut easy_steps = 0u32;
    let mut rejection_causes: BTreeMap<String, u64> = BTreeMap::new();
    let mut step_limited_by: BTreeMap<String, u64> = BTreeMap::new();
    loop {
        if s.time >= next_out - eps {
            record_probes(&mut probes, &s, &grid, &stations);
            next_out += t.output_interval_s;
        }
        if s.time >= next_prof - eps {
            record_profile(&mut profiles, &s, &grid);
            next_prof += t.profile_interval_s;
        }
        for st in &stations {
            let tw = st.cell_value(&s.t_w);
            if chill[&st.name].is_none() && tw < inlet_tl + CHILLDOWN_MARGIN_K {
                chill.insert(st.name.clone(), Some(s.time));
            }
            if quench[&st.name].is_none() && tw < QUENCH_TEMPERATURE_K {
                quench.insert(st.name.clone(), Some(s.time));
            }
        }
        if s.time >= end - eps {
            break;
        }
        if let Some(ms) = t.max_steps
            && steps >= ms
        {
            return Err(SimError::MaxSteps { steps, time_s: s.time });
        }
        if let Some(mw) = t.max_wall_s
            && clock.elapsed().as_secs_f64() > mw
        {
            return Err(SimError::MaxWall { wall_s: mw, time_s: s.time });
        }
        // Courant limit for accuracy, and landing exactly on output times
        let mut courant = f64::INFINITY;
        for j in 0..=n {
            let dxj = grid.dx_junction(j);
            let v = s.v_g[j].abs().max(s.v_l[j].abs());
            if v > 0.0 {
                courant = courant.min(t.max_courant * dxj / v);
            }
        }
        let target = next_out.min(next_prof).min(end);
        let mut h = dt.min(t.max_dt_s).min(courant).min(target - s.time);
        if h <= 0.0 {
            h = (target - s.time).max(t.min_dt_s);
        }
        let b0 = bstate(s.time)?;
        loop {
            let b1 = bstate(s.time + h)?;
            match scheme.step(&s, h, [&b0[0], &b0[1]], [&b1[0], &b1[1]]) {
                Ok((next, report)) => {
                    steps += 1;
                    min_dt = min_dt.min(h);
                    max_dt = max_dt.max(h);
                    max_verr = max_verr.max(report.max_volume_error);
                    add_budget(&mut cum, &report.budget);
                    if !report.limiting.is_empty() {
                        *step_limited_by.entry(report.limiting.to_string()).or_default() += 1;
                    }
                    if report.change_ratio < 0.5 {
                        easy_steps += 1;
                    } else {
                        easy_steps = 0;
                    }
                    // `dt` is the controller's step; `h` may have been shortened to land on an
                    // output time or by the Courant limit, which says nothing about difficulty.
                    // Grow after three easy steps in a row, shrink after a hard one.
                    if easy_steps >= 3 {
                        dt = (dt * 1.25).min(t.max_dt_s);
                        easy_steps = 0;
                    }
                    if report.change_ratio > 0.8 {
                        dt = dt.min(h * 0.8);
                    }
                    s = next;
                    break;
                }
                Err(Rejection { cell, variable, value, reason }) => {
                    rejected += 1;
                    *rejection_causes.entry(format!("{variable}: {reason}")).or_default() += 1;
                    h *= 0.5;
                    dt = h;
                    easy_steps = 0;
                    if h < t.min_dt_s {
                        return Err(SimError::StepTooSmall {
                            time_s: s.time,
                            min_dt_s: t.min_dt_s,
                            cell,
                            variable,
                            value,
                            reason,
                        });
                    }
                }
            }
        }
        if steps.is_multiple_of(64) {
            progress(Progress { time_s: s.time, end_s: end, steps });
        }
    }
    let wall_time_s = clock.elapsed().as_secs_f64();
    let m1 = total_mass(&s, &grid);
    let net_in = cum.mass_in - cum.mass_out;
    let mass_balance_error = (m1 - m0 - net_in).abs() / m0.max(cum.mass_in.abs() + cum.mass_out.abs()).max(1e-300);
    let e1_scheme = fluid_internal_energy(&s, &grid);
    let scheme_terms = cum.energy_flux + cum.pressure_work + cum.wall_heat + cum.adjustment + cum.dissipation;
    let scheme_scale = cum.energy_flux.abs()
        + cum.pressure_work.abs()
        + cum.wall_heat.abs()
        + cum.dissipation.abs()
        + e0_scheme.abs().max(1.0);
    let scheme_energy_error = (e1_scheme - e0_scheme - scheme_terms).abs() / scheme_scale;
    let e1_total = total_energy(&s, &grid, case.physics.gravity);
    let phys_terms = cum.total_energy_flux + cum.ambient_heat;
    let residual = e1_total - e0_total - phys_terms;
    // Decision: the residual is measured against the heat the wall gave up, the energy a
    // chilldown is about (3.35 MJ on the NBS line), not against the boundary enthalpy
    // throughput, whose size depends on the property tables' reference state and dwarfs any
    // defect. Where no heat moved (the adiabatic verification problems) the scale is the
    // mechanical energy that moved: kinetic and potential energy changes and the boundary
    // fluxes of both.
    let (ke0, pe0) = e0_parts;
    let (ke1, pe1) = energy_parts(&s, &grid, case.physics.gravity);
    let heat_scale = cum.wall_heat.abs() + cum.ambient_heat.abs();
    let scale =
        if heat_scale > 0.0 { heat_scale } else { (ke1 - ke0).abs() + (pe1 - pe0).abs() + cum.mechanical_flux_abs };
    let energy_balance_error = if scale > 0.0 { residual.abs() / scale } else { residual.abs() };
    Ok(Output {
        probes,
        profiles,
        summary: Summary {
            steps,
            rejected_steps: rejected,
            wall_time_s,
            simulated_time_s: s.time,
            min_dt_s: if min_dt.is_finite() { min_dt } else { 0.0 },
            max_dt_s: max_dt,
            mass_balance_error,
            energy_balance_error,
            energy_balance_residual_j: residual,
            wall_heat_j: cum.wall_heat,
            scheme_energy_error,
            max_volume_error: max_verr,
            trace_adjustment_j: cum.adjustment_abs,
            dissipation_j: cum.dissipation,
            rejection_causes,
            step_limited_by,
            chilldown_time_s: chill,
            quench_arrival_s: quench,
            inlet_liquid_temperature_k: inlet_tl,
        },
        final_state: s,
    })
}

fn s_last_p(b: &crate::case::BoundarySection, fallback: f64) -> f64 {
    match (&b.kind, &b.pressure_pa) {
        (BoundaryKind::Pressure | BoundaryKind::Reservoir, Some(p)) => p.at(0.0),
        _ => fallback,
    }
}

fn add_budget(c: &mut StepBudget, b: &StepBudget) {
    c.mass_in += b.mass_in;
    c.mass_out += b.mass_out;
    c.energy_flux += b.energy_flux;
    c.pressure_work += b.pressure_work;
    c.wall_heat += b.wall_heat;
    c.ambient_heat += b.ambient_heat;
    c.adjustment += b.adjustment;
    c.adjustment_abs += b.adjustment_abs;
    c.mechanical_flux_abs += b.mechanical_flux_abs;
    c.dissipation += b.dissipation;
    c.total_energy_flux += b.total_energy_flux;
}

/// Total fluid mass on the line, kg.
pub fn total_mass(s: &State, g: &Grid) -> f64 {
    (0..g.n).map(|i| (s.m_g[i] + s.m_l[i]) * g.volume[i]).sum()
}

fn fluid_internal_energy(s: &State, g: &Grid) -> f64 {
    (0..g.n).map(|i| (s.e_g[i] + s.e_l[i]) * g.volume[i]).sum()
}

/// (kinetic, potential) energy of the fluid, J.
fn energy_parts(s: &State, g: &Grid, gravity: bool) -> (f64, f64) {
    let grav = if gravity { GRAVITY } else { 0.0 };
    let (mut z, mut ke, mut pe) = (0.0, 0.0, 0.0);
    for i in 0..g.n {
        let zc = z + 0.5 * g.dx[i] * g.sin_cell[i];
        z += g.dx[i] * g.sin_cell[i];
        let vg = 0.5 * (s.v_g[i] + s.v_g[i + 1]);
        let vl = 0.5 * (s.v_l[i] + s.v_l[i + 1]);
        ke += g.volume[i] * 0.5 * (s.m_g[i] * vg * vg + s.m_l[i] * vl * vl);
        pe += g.volume[i] * (s.m_g[i] + s.m_l[i]) * grav * zc;
    }
    (ke, pe)
}

/// Fluid internal + kinetic + potential energy plus wall internal energy, J.
fn total_energy(s: &State, g: &Grid, gravity: bool) -> f64 {
    let grav = if gravity { GRAVITY } else { 0.0 };
    let mut z = 0.0;
    let mut total = 0.0;
    for i in 0..g.n {
        let zc = z + 0.5 * g.dx[i] * g.sin_cell[i];
        z += g.dx[i] * g.sin_cell[i];
        let vg = 0.5 * (s.v_g[i] + s.v_g[i + 1]);
        let vl = 0.5 * (s.v_l[i] + s.v_l[i + 1]);
        let m = s.m_g[i] + s.m_l[i];
        total += g.volume[i] * (s.e_g[i] + s.e_l[i] + 0.5 * (s.m_g[i] * vg * vg + s.m_l[i] * vl * vl) + m * grav * zc);
        total += g.wall_mass[i] * s.e_w[i];
    }
    total
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

/// A measuring station and how it reads the grid: cell quantities interpolate linearly between
/// the two cell centres around it, velocities and the mass flow between the two junctions
/// around it (flat beyond the first and last centre). Decision: the data are taken at the
/// thermocouple, not over the 2 m cell that holds it; reading the cell put TS1 and TS2 about
/// 1 m downstream of their thermocouples on the 30-cell NBS grid.
#[derive(Debug, Clone)]
struct Station {
    name: String,
    x_m: f64,
    /// Left cell, right cell and the right one's weight.
    cells: (usize, usize, f64),
    /// Left junction, right junction and the right one's weight.
    junctions: (usize, usize, f64),
}

impl Station {
    fn new(grid: &Grid, name: &str, x_m: f64) -> Self {
        Station {
            name: name.to_string(),
            x_m,
            cells: bracket(&grid.x_cell, x_m),
            junctions: bracket(&grid.x_junction, x_m),
        }
    }

    fn cell_value(&self, v: &[f64]) -> f64 {
        let (l, r, f) = self.cells;
        (1.0 - f) * v[l] + f * v[r]
    }

    fn junction_value(&self, v: &[f64]) -> f64 {
        let (l, r, f) = self.junctions;
        (1.0 - f) * v[l] + f * v[r]
    }
}

/// The two nodes of the ascending `nodes` around `x` and the weight of the right one (the
/// nearest node twice, weight 0, outside them).
fn bracket(nodes: &[f64], x: f64) -> (usize, usize, f64) {
    let last = nodes.len() - 1;
    if x.is_nan() || x <= nodes[0] {
        return (0, 0, 0.0);
    }
    if x >= nodes[last] {
        return (last, last, 0.0);
    }
    let r = nodes.partition_point(|&xn| xn <= x).min(last);
    let l = r - 1;
    let width = nodes[r] - nodes[l];
    let f = if width > 0.0 { (x - nodes[l]) / width } else { 0.0 };
    (l, r, f.clamp(0.0, 1.0))
}

/// Mass flow through junction `j` with donor-cell (upwind) densities, kg/s; the boundary
/// junctions take their cell's densities.
fn junction_mass_flow(s: &State, g: &Grid, j: usize) -> f64 {
    let n = g.n;
    let donor = |v: f64| -> usize {
        if j == 0 {
            0
        } else if j == n {
            n - 1
        } else if v >= 0.0 {
            j - 1
        } else {
            j
        }
    };
    let (ig, il) = (donor(s.v_g[j]), donor(s.v_l[j]));
    g.area_junction[j] * (s.m_g[ig] * s.v_g[j] + s.m_l[il] * s.v_l[j])
}

fn record_probes(out: &mut Vec<Observation>, s: &State, g: &Grid, stations: &[Station]) {
    for st in stations {
        let a = st.cell_value(&s.alpha);
        let t_g = st.cell_value(&s.t_g);
        let t_l = st.cell_value(&s.t_l);
        let (jl, jr, fj) = st.junctions;
        let mass_flow = (1.0 - fj) * junction_mass_flow(s, g, jl) + fj * junction_mass_flow(s, g, jr);
        let values: [f64; 10] = [
            st.cell_value(&s.t_w),
            // the fluid temperature of the two cells, interpolated (each cell's own mixture)
            (1.0 - st.cells.2) * fluid_temperature(s.alpha[st.cells.0], s.t_g[st.cells.0], s.t_l[st.cells.0])
                + st.cells.2 * fluid_temperature(s.alpha[st.cells.1], s.t_g[st.cells.1], s.t_l[st.cells.1]),
            st.cell_value(&s.p),
            a,
            t_g,
            t_l,
            st.junction_value(&s.v_g),
            st.junction_value(&s.v_l),
            st.cell_value(&s.wall_heat_flux),
            mass_flow,
        ];
        for (quantity, value) in PROBE_QUANTITIES.into_iter().zip(values) {
            out.push(Observation { time_s: s.time, station: st.name.clone(), x_m: st.x_m, quantity, value });
        }
    }
}

fn record_profile(out: &mut Vec<ProfilePoint>, s: &State, g: &Grid) {
    for i in 0..g.n {
        let x = g.x_cell[i];
        let a = s.alpha[i];
        for (quantity, value) in [
            ("wall_temperature_k", s.t_w[i]),
            ("fluid_temperature_k", fluid_temperature(a, s.t_g[i], s.t_l[i])),
            ("pressure_pa", s.p[i]),
            ("void_fraction", a),
            ("gas_temperature_k", s.t_g[i]),
            ("liquid_temperature_k", s.t_l[i]),
        ] {
            out.push(ProfilePoint { time_s: s.time, x_m: x, quantity, value });
        }
    }
    for j in 0..=g.n {
        let x = g.x_junction[j];
        out.push(ProfilePoint { time_s: s.time, x_m: x, quantity: "gas_velocity_m_s", value: s.v_g[j] });
        out.push(ProfilePoint { time_s: s.time, x_m: x, quantity: "liquid_velocity_m_s", value: s.v_l[j] });
    }
}
