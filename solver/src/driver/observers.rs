//! What a run records besides its final state, as observers that see every time level and every
//! accepted step: the probes at the stations, the whole-line profiles, the chilldown and
//! quench-front arrival times, and the mass and energy budgets.

use std::collections::BTreeMap;

use super::{
    CHILLDOWN_MARGIN_K, Observation, PROBE_QUANTITIES, ProfilePoint, QUENCH_TEMPERATURE_K, fluid_temperature,
    total_mass,
};
use crate::model::{GRAVITY, Grid, State};
use crate::scheme::{StepBudget, StepReport};

/// Something that watches a run. The driver calls every observer in turn: with the state at
/// each time level the run reaches (the initial one included, the final one last) and the state
/// before it (none for the initial one), and with each accepted step.
pub(super) trait RunObserver {
    /// Sees the state `s` at a time level the run has reached, and the one before it.
    fn on_state(&mut self, _before: Option<&State>, _s: &State) {}

    /// Sees an accepted step: its size `h`, s, and the scheme's report of it.
    fn on_step(&mut self, _h: f64, _report: &StepReport) {}
}

/// Output times every `interval` from t = 0; an output is due once the run is within `eps` of
/// its time.
///
/// The k-th output time is `k × interval` written with as many decimals as the interval has
/// (every 0.1 s: 0.6, not 0.6000000000000001 nor a running sum of intervals that drifts by
/// rounding over thousands of outputs): the times a user wrote in the case and in their data.
#[derive(Debug, Clone)]
pub(super) struct OutputClock {
    next: f64,
    count: u64,
    interval: f64,
    /// Decimals of the interval's shortest decimal form.
    decimals: usize,
    eps: f64,
}

impl OutputClock {
    /// Outputs every `interval` seconds from 0, each due `eps` seconds early.
    pub(super) fn new(interval: f64, eps: f64) -> Self {
        // `Display` of an f64 is its shortest round-trip decimal, never in exponent form
        let decimals = format!("{interval}").split_once('.').map_or(0, |(_, d)| d.len());
        Self { next: 0.0, count: 0, interval, decimals, eps }
    }

    /// The next output time if it is due at `time` (reached to within `eps`), moving the clock
    /// on to the one after it; `None` if it is not due yet.
    fn take_due(&mut self, time: f64) -> Option<f64> {
        if time >= self.next - self.eps {
            let due = self.next;
            self.count += 1;
            let exact = self.count as f64 * self.interval;
            self.next = format!("{exact:.*}", self.decimals).parse().unwrap_or(exact);
            Some(due)
        } else {
            None
        }
    }
}

/// Where output time `t` falls between the state `before` and the state `s` the run has just
/// reached: the weight of `s` in a linear interpolation, 1 where `t` is `s`'s own time (to within
/// `eps`) or there is no state before.
///
/// Decision: the outputs are interpolated, the steps do not land on them. Landing on every
/// output time cut a step short whenever one fell due, and so made the step sequence, and with
/// it every result, depend on the output intervals the case asks for — a setting of what to
/// write, not of the physics (the subcooled NBS run's station-4 chilldown moved by 0.9 s between
/// probes every 1 s and every 1000 s; after the chilldown, steps held at 0.4994 s by the Courant
/// limit took three steps a second to land on each probe time instead of two). Interpolated
/// linearly between the two accepted states that bracket it, an output is accurate to the
/// scheme's own first order in time, and the run is the same whatever is written.
fn weight_at(t: f64, before: Option<&State>, s: &State, eps: f64) -> f64 {
    match before {
        Some(b) if t < s.time - eps && s.time > b.time => ((t - b.time) / (s.time - b.time)).clamp(0.0, 1.0),
        _ => 1.0,
    }
}

/// The probe quantity that is a step's flux, not a state: a step's mass flow is its value over
/// the whole step (what its mass equations moved), so an output time inside the step takes the
/// step's own flow, not one interpolated between two steps' flows.
///
/// Decision: interpolated like a state, each step's flow was read half a step late, and where
/// the step lengths change with the inlet's reversals the end probes' flows no longer integrate
/// to the mass the line gained (the saturated NBS run on 10 cells: inflow less outflow 0.0458 kg
/// against the line's gain of 0.0324 kg, 2.8 % of what entered; with the step's own flow
/// 0.0329 kg, 0.1 %; `solver/tests/probe_flows.rs`).
const STEP_FLUX: &str = "mass_flow_kg_s";

/// `a` and `b` blended with weight `w` on `b`.
fn blend(a: f64, b: f64, w: f64) -> f64 {
    if w == 1.0 { b } else { a + (b - a) * w }
}

/// The probes: every station's [`PROBE_QUANTITIES`] at the output times.
#[derive(Debug)]
pub(super) struct ProbeRecorder<'a> {
    grid: &'a Grid,
    stations: &'a [Station],
    clock: OutputClock,
    probes: Vec<Observation>,
}

impl<'a> ProbeRecorder<'a> {
    /// Probes at `stations` on `grid` at the times of `clock`.
    pub(super) fn new(grid: &'a Grid, stations: &'a [Station], clock: OutputClock) -> Self {
        Self { grid, stations, clock, probes: Vec::new() }
    }

    /// The recorded observations.
    pub(super) fn into_probes(self) -> Vec<Observation> {
        self.probes
    }
}

impl RunObserver for ProbeRecorder<'_> {
    fn on_state(&mut self, before: Option<&State>, s: &State) {
        // each state's values once, for every output time that falls due in this step
        let mut values: Option<Vec<(Option<ProbeValues>, ProbeValues)>> = None;
        while let Some(t) = self.clock.take_due(s.time) {
            let w = weight_at(t, before, s, self.clock.eps);
            let (grid, stations) = (self.grid, self.stations);
            let values = values.get_or_insert_with(|| {
                stations
                    .iter()
                    .map(|st| (before.map(|b| probe_values(b, grid, st)), probe_values(s, grid, st)))
                    .collect()
            });
            for (st, &(then, now)) in stations.iter().zip(values.iter()) {
                // without a state before (the initial one) the weight is 1: the state's own values
                for ((quantity, a), b) in PROBE_QUANTITIES.into_iter().zip(then.unwrap_or(now)).zip(now) {
                    let value = if quantity == STEP_FLUX { b } else { blend(a, b, w) };
                    self.probes.push(Observation { time_s: t, station: st.name.clone(), x_m: st.x_m, quantity, value });
                }
            }
        }
    }
}

/// The whole-line profiles at the profile times.
#[derive(Debug)]
pub(super) struct ProfileRecorder<'a> {
    grid: &'a Grid,
    clock: OutputClock,
    profiles: Vec<ProfilePoint>,
}

impl<'a> ProfileRecorder<'a> {
    /// Profiles of `grid` at the times of `clock`.
    pub(super) fn new(grid: &'a Grid, clock: OutputClock) -> Self {
        Self { grid, clock, profiles: Vec::new() }
    }

    /// The recorded profile values.
    pub(super) fn into_profiles(self) -> Vec<ProfilePoint> {
        self.profiles
    }
}

impl RunObserver for ProfileRecorder<'_> {
    fn on_state(&mut self, before: Option<&State>, s: &State) {
        // each state's profile once, for every profile time that falls due in this step
        let mut values: Option<(Profile, Profile)> = None;
        while let Some(t) = self.clock.take_due(s.time) {
            let w = weight_at(t, before, s, self.clock.eps);
            let grid = self.grid;
            let (then, now) = values.get_or_insert_with(|| {
                let now = profile_values(s, grid);
                (before.map_or_else(|| now.clone(), |b| profile_values(b, grid)), now)
            });
            for (&(x_m, quantity, a), &(_, _, b)) in then.iter().zip(now.iter()) {
                self.profiles.push(ProfilePoint { time_s: t, x_m, quantity, value: blend(a, b, w) });
            }
        }
    }
}

/// The chilldown time (the wall below the inlet liquid temperature + [`CHILLDOWN_MARGIN_K`])
/// and the quench-front arrival (the wall below [`QUENCH_TEMPERATURE_K`]) at each station: the
/// time at which its wall temperature first falls below the threshold, interpolated linearly
/// within the step that crosses it.
///
/// Decision: the crossing is interpolated, not taken at the end of the step. The steps near a
/// station's chilldown are a third of a second to half a second long (the Courant and
/// largest-step limits), and the end of the crossing step moved the reported time by up to a
/// whole step whenever a perturbation shifted the step sequence: a jump no smaller
/// perturbation removes, which the one-ulp chaos measurement (VALIDATION.md) and a
/// calibration's chilldown errors inherited.
#[derive(Debug)]
pub(super) struct FrontArrivals<'a> {
    stations: &'a [Station],
    /// The inlet liquid temperature of the chilldown criterion, K.
    pub(super) inlet_liquid_temperature_k: f64,
    /// Chilldown time per station, s (`None`: not reached).
    pub(super) chilldown: BTreeMap<String, Option<f64>>,
    /// Quench-front arrival per station, s (`None`: not reached).
    pub(super) quench: BTreeMap<String, Option<f64>>,
    /// Per station, the time and wall temperature of the last state seen (`None` before the
    /// first).
    last: Vec<Option<(f64, f64)>>,
}

impl<'a> FrontArrivals<'a> {
    /// Arrivals at `stations`, the chilldown measured from the inlet liquid temperature
    /// `inlet_liquid_temperature_k`.
    pub(super) fn new(stations: &'a [Station], inlet_liquid_temperature_k: f64) -> Self {
        let none = || stations.iter().map(|s| (s.name.clone(), None)).collect();
        Self {
            stations,
            inlet_liquid_temperature_k,
            chilldown: none(),
            quench: none(),
            last: vec![None; stations.len()],
        }
    }
}

/// When a wall temperature going from `before` = (time, T) to `now` = (time, T) first falls
/// below `threshold`, linear in time within the step; `now`'s time where there is no step before
/// it (the first state) or the temperature did not change.
fn crossing(before: Option<(f64, f64)>, now: (f64, f64), threshold: f64) -> f64 {
    match before {
        Some((t0, w0)) if w0 >= threshold && w0 > now.1 => t0 + (now.0 - t0) * (w0 - threshold) / (w0 - now.1),
        _ => now.0,
    }
}

impl RunObserver for FrontArrivals<'_> {
    fn on_state(&mut self, _before: Option<&State>, s: &State) {
        for (st, last) in self.stations.iter().zip(self.last.iter_mut()) {
            let tw = st.cell_value(&s.t_w);
            let chilled = self.inlet_liquid_temperature_k + CHILLDOWN_MARGIN_K;
            if self.chilldown[&st.name].is_none() && tw < chilled {
                self.chilldown.insert(st.name.clone(), Some(crossing(*last, (s.time, tw), chilled)));
            }
            if self.quench[&st.name].is_none() && tw < QUENCH_TEMPERATURE_K {
                self.quench.insert(st.name.clone(), Some(crossing(*last, (s.time, tw), QUENCH_TEMPERATURE_K)));
            }
            *last = Some((s.time, tw));
        }
    }
}

/// The run's budgets: the steps' budget terms summed, the largest volume error, and the fluid's
/// mass and energies at the start, to close the balances at the end ([`EnergyBudget::finish`]).
#[derive(Debug)]
pub(super) struct EnergyBudget<'a> {
    grid: &'a Grid,
    gravity: bool,
    /// The steps' budget terms, summed.
    cum: StepBudget,
    max_verr: f64,
    m0: f64,
    e0_scheme: f64,
    e0_total: f64,
    /// Kinetic and potential energy at the start, J.
    e0_parts: (f64, f64),
}

/// The closed balances of a run (the [`super::Summary`] fields of the same names).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Balances {
    pub(super) mass_balance_error: f64,
    pub(super) energy_balance_error: f64,
    pub(super) energy_balance_residual_j: f64,
    pub(super) wall_heat_j: f64,
    pub(super) scheme_energy_error: f64,
    pub(super) max_volume_error: f64,
    pub(super) trace_adjustment_j: f64,
    pub(super) dissipation_j: f64,
    pub(super) exported_heat_j: f64,
}

impl<'a> EnergyBudget<'a> {
    /// Budgets from the initial state `s0` on `grid`, with or without gravity.
    pub(super) fn new(s0: &State, grid: &'a Grid, gravity: bool) -> Self {
        Self {
            grid,
            gravity,
            cum: StepBudget::default(),
            max_verr: 0.0,
            m0: total_mass(s0, grid),
            e0_scheme: fluid_internal_energy(s0, grid),
            e0_total: total_energy(s0, grid, gravity),
            e0_parts: energy_parts(s0, grid, gravity),
        }
    }

    /// The balances with the final state `s`.
    pub(super) fn finish(&self, s: &State) -> Balances {
        let (grid, cum) = (self.grid, &self.cum);
        let (m0, e0_scheme, e0_total) = (self.m0, self.e0_scheme, self.e0_total);
        let m1 = total_mass(s, grid);
        let net_in = cum.mass_in - cum.mass_out;
        let mass_balance_error = (m1 - m0 - net_in).abs() / m0.max(cum.mass_in.abs() + cum.mass_out.abs()).max(1e-300);
        let e1_scheme = fluid_internal_energy(s, grid);
        let scheme_terms = cum.energy_flux + cum.pressure_work + cum.wall_heat + cum.adjustment + cum.dissipation;
        let scheme_scale = cum.energy_flux.abs()
            + cum.pressure_work.abs()
            + cum.wall_heat.abs()
            + cum.dissipation.abs()
            + e0_scheme.abs().max(1.0);
        let scheme_energy_error = (e1_scheme - e0_scheme - scheme_terms).abs() / scheme_scale;
        let e1_total = total_energy(s, grid, self.gravity);
        let phys_terms = cum.total_energy_flux + cum.ambient_heat;
        let residual = e1_total - e0_total - phys_terms;
        // Decision: the residual is measured against the heat the wall gave up, the energy a
        // chilldown is about (3.35 MJ on the NBS line), not against the boundary enthalpy
        // throughput, whose size depends on the property tables' reference state and dwarfs any
        // defect. Where no heat moved (the adiabatic verification problems) the scale is the
        // mechanical energy that moved: kinetic and potential energy changes and the boundary
        // fluxes of both.
        let (ke0, pe0) = self.e0_parts;
        let (ke1, pe1) = energy_parts(s, grid, self.gravity);
        let heat_scale = cum.wall_heat.abs() + cum.ambient_heat.abs();
        let scale =
            if heat_scale > 0.0 { heat_scale } else { (ke1 - ke0).abs() + (pe1 - pe0).abs() + cum.mechanical_flux_abs };
        let energy_balance_error = if scale > 0.0 { residual.abs() / scale } else { residual.abs() };
        Balances {
            mass_balance_error,
            energy_balance_error,
            energy_balance_residual_j: residual,
            wall_heat_j: cum.wall_heat,
            scheme_energy_error,
            max_volume_error: self.max_verr,
            trace_adjustment_j: cum.adjustment_abs,
            dissipation_j: cum.dissipation,
            exported_heat_j: cum.exported_heat,
        }
    }
}

impl RunObserver for EnergyBudget<'_> {
    fn on_step(&mut self, _h: f64, report: &StepReport) {
        self.max_verr = self.max_verr.max(report.max_volume_error);
        add_budget(&mut self.cum, &report.budget);
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
    c.exported_heat += b.exported_heat;
    c.total_energy_flux += b.total_energy_flux;
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

/// A measuring station and how it reads the grid: cell quantities interpolate linearly between
/// the two cell centres around it, velocities and the mass flow between the two junctions
/// around it (flat beyond the first and last centre). Decision: the data are taken at the
/// thermocouple, not over the 2 m cell that holds it; reading the cell put TS1 and TS2 about
/// 1 m downstream of their thermocouples on the 30-cell NBS grid.
#[derive(Debug, Clone)]
pub(super) struct Station {
    name: String,
    x_m: f64,
    /// Left cell, right cell and the right one's weight.
    cells: (usize, usize, f64),
    /// Left junction, right junction and the right one's weight.
    junctions: (usize, usize, f64),
}

impl Station {
    /// The station `name` at `x_m` on `grid`.
    pub(super) fn new(grid: &Grid, name: &str, x_m: f64) -> Self {
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

/// Mass flow through junction `j`, kg/s: inside the line with donor-cell (upwind) densities, the
/// new-time donors of the step's mass equations; through a boundary junction the step's own
/// flow ([`State::boundary_mass_flow`]), whose donor is the boundary's fluid where it enters.
/// (Before, a boundary junction took its cell's densities both ways, which put the liquid an
/// inlet takes from a reservoir at the inlet cell's void fraction: in the first minute of the
/// saturated NBS nitrogen runs it read a net backflow into the dewar where the line was filling.)
fn junction_mass_flow(s: &State, g: &Grid, j: usize) -> f64 {
    let n = g.n;
    if j == 0 {
        return s.boundary_mass_flow[0];
    }
    if j == n {
        return s.boundary_mass_flow[1];
    }
    let donor = |v: f64| if v >= 0.0 { j - 1 } else { j };
    let (ig, il) = (donor(s.v_g[j]), donor(s.v_l[j]));
    g.area_junction[j] * (s.m_g[ig] * s.v_g[j] + s.m_l[il] * s.v_l[j])
}

/// One station's [`PROBE_QUANTITIES`] in one state.
type ProbeValues = [f64; 10];

/// The [`PROBE_QUANTITIES`] of station `st` in state `s`, in that order.
fn probe_values(s: &State, g: &Grid, st: &Station) -> ProbeValues {
    let (jl, jr, fj) = st.junctions;
    let mass_flow = (1.0 - fj) * junction_mass_flow(s, g, jl) + fj * junction_mass_flow(s, g, jr);
    [
        st.cell_value(&s.t_w),
        // the fluid temperature of the two cells, interpolated (each cell's own mixture)
        (1.0 - st.cells.2) * fluid_temperature(s.alpha[st.cells.0], s.t_g[st.cells.0], s.t_l[st.cells.0])
            + st.cells.2 * fluid_temperature(s.alpha[st.cells.1], s.t_g[st.cells.1], s.t_l[st.cells.1]),
        st.cell_value(&s.p),
        st.cell_value(&s.alpha),
        st.cell_value(&s.t_g),
        st.cell_value(&s.t_l),
        st.junction_value(&s.v_g),
        st.junction_value(&s.v_l),
        st.cell_value(&s.wall_heat_flux),
        mass_flow,
    ]
}

/// One state's whole-line profile: (x, quantity, value), cells then junctions.
type Profile = Vec<(f64, &'static str, f64)>;

/// The whole-line profile of state `s`, cells then junctions.
fn profile_values(s: &State, g: &Grid) -> Profile {
    let mut out = Vec::with_capacity(6 * g.n + 2 * (g.n + 1));
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
            out.push((x, quantity, value));
        }
    }
    for j in 0..=g.n {
        let x = g.x_junction[j];
        out.push((x, "gas_velocity_m_s", s.v_g[j]));
        out.push((x, "liquid_velocity_m_s", s.v_l[j]));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::crossing;

    #[test]
    fn a_crossing_is_interpolated_within_its_step() {
        // 100 K at 10 s to 80 K at 10.5 s: 90 K is crossed half-way
        assert_eq!(crossing(Some((10.0, 100.0)), (10.5, 80.0), 90.0), 10.25);
        // a quarter of the way down to 80 K
        assert_eq!(crossing(Some((10.0, 100.0)), (10.5, 80.0), 95.0), 10.125);
        // the first state already below: its own time
        assert_eq!(crossing(None, (0.0, 80.0), 90.0), 0.0);
        // a step that started below the threshold (a wall rewarmed and cooled again) keeps the
        // step's end
        assert_eq!(crossing(Some((10.0, 89.0)), (10.5, 80.0), 90.0), 10.5);
    }
}
