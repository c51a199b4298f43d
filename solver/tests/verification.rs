//! The solver against problems with exact answers, and its conservation properties.
//!
//! Grid sizes and end times are the ones the done-criteria name where that is cheap; the
//! benchmark (`cargo bench -p cryofit-solver --bench scheme`) runs the larger versions.

use cryofit_solver::driver::{self, Output};
use cryofit_solver::exact::{self, Schumann};
use cryofit_solver::fluids::{self, Phase};
use cryofit_solver::model::{GRAVITY, Grid};
use cryofit_solver::reference::Reference;

fn run(case: &cryofit_solver::case::Case) -> Output {
    let fluid = fluids::embedded(&case.fluid.name).unwrap();
    let params = driver::case_parameters(case).unwrap();
    driver::run(case, fluid, &params, &mut |_| {}).unwrap_or_else(|e| panic!("{}: {e}", case.title))
}

/// Mean absolute error of the faucet void profile at the end time against the exact solution.
fn faucet_error(cells: usize) -> (f64, Output) {
    let case = Reference::Faucet.with_cells(cells);
    let out = run(&case);
    let g = Grid::from_case(&case);
    let s = &out.final_state;
    let mae = (0..g.n)
        .map(|i| (s.alpha[i] - exact::faucet_void_fraction(g.x_cell[i], s.time, 0.2, 10.0, GRAVITY)).abs())
        .sum::<f64>()
        / g.n as f64;
    (mae, out)
}

#[test]
fn faucet_void_profile_converges_to_the_exact_solution() {
    let mut errors = Vec::new();
    for cells in [25, 50, 100, 200] {
        let (mae, out) = faucet_error(cells);
        println!("faucet {cells} cells: mean |Δα| = {mae:.4}, steps {}", out.summary.steps);
        assert!((out.summary.simulated_time_s - 0.5).abs() < 1e-9);
        // open system: inflow − outflow − accumulation
        assert!(out.summary.mass_balance_error <= 1e-8, "mass balance {}", out.summary.mass_balance_error);
        assert!(out.summary.scheme_energy_error <= 1e-8, "scheme energy {}", out.summary.scheme_energy_error);
        errors.push((cells, mae));
    }
    let at100 = errors.iter().find(|e| e.0 == 100).unwrap().1;
    assert!(at100 <= 0.02, "faucet error on 100 cells {at100}");
    for w in errors.windows(2) {
        assert!(w[1].1 < w[0].1, "error does not fall from {} to {} cells: {:?}", w[0].0, w[1].0, errors);
    }
}

#[test]
fn manometer_oscillates_with_the_exact_period() {
    let case = Reference::Manometer.case();
    let out = run(&case);
    let v: Vec<(f64, f64)> = out
        .probes
        .iter()
        .filter(|o| o.station == "bottom" && o.quantity == "liquid_velocity_m_s")
        .map(|o| (o.time_s, o.value))
        .collect();
    // zero crossings of the liquid velocity at the bottom of the U
    let mut crossings = Vec::new();
    for w in v.windows(2) {
        let ((t0, v0), (t1, v1)) = (w[0], w[1]);
        if v0 != 0.0 && v0.signum() != v1.signum() {
            crossings.push(t0 + (t1 - t0) * v0 / (v0 - v1));
        }
    }
    assert!(crossings.len() >= 7, "only {} zero crossings: {crossings:?}", crossings.len());
    let exact_period = exact::manometer_period_s(10.0, GRAVITY);
    let periods = (crossings.len() - 1) / 2;
    let measured = (crossings[2 * periods] - crossings[0]) / periods as f64;
    // amplitude in each half period
    let mut amplitudes = Vec::new();
    for w in crossings.windows(2) {
        let a = v.iter().filter(|(t, _)| *t > w[0] && *t < w[1]).map(|(_, x)| x.abs()).fold(0.0, f64::max);
        amplitudes.push(a);
    }
    println!(
        "manometer: period {measured:.4} s over {periods} periods (exact {exact_period:.4} s, {:+.2} %), half-period amplitudes {:?}; total energy residual {:.3} J, mechanical energy moved {:.3} J, error {:.3e}",
        100.0 * (measured / exact_period - 1.0),
        amplitudes.iter().map(|a| format!("{a:.3}")).collect::<Vec<_>>(),
        out.summary.energy_balance_residual_j,
        out.summary.wall_heat_j,
        out.summary.energy_balance_error,
    );
    assert!(periods >= 3);
    assert!((measured / exact_period - 1.0).abs() <= 0.02, "period {measured} vs {exact_period}");
    // a frictionless manometer would keep its amplitude: what decays is numerical damping
    // (donor-cell smearing of the two interfaces), reported above; it must neither grow nor
    // swallow the oscillation
    assert!(amplitudes.iter().all(|&a| a > 0.4 && a < 1.05), "{amplitudes:?}");
    assert!(amplitudes.windows(2).all(|w| w[1] <= w[0] + 0.01), "amplitude grows: {amplitudes:?}");
    assert!(out.summary.mass_balance_error <= 1e-8, "mass balance {}", out.summary.mass_balance_error);
    assert!(out.summary.scheme_energy_error <= 1e-8);
    // the total energy (internal + kinetic + potential) is kept up to the residual reported
    // above: 38 J against 33 J of initial kinetic energy (284 J before the potential energy
    // that the donor-cell transport and the momentum equations disagree about was booked as
    // heat, `scheme::momentum::booked_heat`)
    let residual = out.summary.energy_balance_residual_j;
    assert!(residual.abs() <= 50.0, "total energy residual {residual} J");
}

#[test]
fn phases_separate_in_a_closed_tube() {
    let case = Reference::Separation.case();
    let out = run(&case);
    let g = Grid::from_case(&case);
    let s = &out.final_state;
    // void fraction never outside [0, 1], at any profile time
    for p in out.profiles.iter().filter(|p| p.quantity == "void_fraction") {
        assert!((0.0..=1.0).contains(&p.value), "void fraction {} at x = {} t = {}", p.value, p.x_m, p.time_s);
    }
    let level = 0.5 * case.pipe.length_m;
    for i in 0..g.n {
        let x = g.x_cell[i];
        if x < level - g.dx[i] {
            assert!(s.alpha[i] < 0.005, "gas left at x = {x}: {}", s.alpha[i]);
        } else if x > level + g.dx[i] {
            assert!(s.alpha[i] > 0.995, "liquid left at x = {x}: {}", 1.0 - s.alpha[i]);
        }
    }
    // hydrostatic pressure: ρ_l g in the liquid, ρ_g g in the gas
    let cell_at = |x: f64| g.cell_at(x);
    let (a, b) = (cell_at(0.2 * level), cell_at(0.9 * level));
    let grad_l = (s.p[a] - s.p[b]) / (g.x_cell[b] - g.x_cell[a]);
    let rho_l = s.liquid[a].rho;
    println!("separation: liquid pressure gradient {grad_l:.1} Pa/m, ρ_l g = {:.1}", rho_l * GRAVITY);
    assert!((grad_l / (rho_l * GRAVITY) - 1.0).abs() < 0.01, "liquid gradient {grad_l}");
    let (c, d) = (cell_at(1.2 * level), cell_at(1.9 * level));
    let grad_g = (s.p[c] - s.p[d]) / (g.x_cell[d] - g.x_cell[c]);
    let rho_g = s.gas[c].rho;
    assert!(grad_g > 0.0 && grad_g < 3.0 * rho_g * GRAVITY, "gas gradient {grad_g} vs ρ_g g {}", rho_g * GRAVITY);
    // at rest
    assert!(s.v_l.iter().chain(&s.v_g).all(|v| v.abs() < 0.05), "not at rest");
    // closed system: mass to round-off
    assert!(out.summary.mass_balance_error <= 1e-10, "mass {}", out.summary.mass_balance_error);
    assert!(out.summary.scheme_energy_error <= 1e-8);
}

#[test]
fn gas_cools_the_wall_as_schumann_predicts() {
    let mut case = Reference::Schumann.case();
    case.time.end_s = 150.0;
    let out = run(&case);
    let fluid = fluids::embedded("nitrogen").unwrap();
    let g = Grid::from_case(&case);
    let gas = fluid.phase_props(Phase::Gas, 1.0e5, 201.0).unwrap();
    let c_w = g.wall_mass[0] / g.dx[0] * g.material.specific_heat_j_kg_k(201.0);
    let h = case.physics.wall_htc_w_m2k.unwrap() * g.perimeter[0];
    let ex = Schumann::new(gas.rho * gas.cp * g.area_cell[0], c_w, h, 1.0, 200.0, 202.0);
    let mut worst: f64 = 0.0;
    for p in out.profiles.iter().filter(|p| p.time_s > 0.0) {
        let (tf, tw) = ex.temperatures(p.x_m, p.time_s);
        let err = match p.quantity {
            "gas_temperature_k" => (p.value - tf).abs(),
            "wall_temperature_k" => (p.value - tw).abs(),
            _ => continue,
        };
        worst = worst.max(err / 2.0);
    }
    println!("schumann: worst error {:.2} % of the initial difference", 100.0 * worst);
    assert!(worst <= 0.02, "worst error {worst} of the initial difference");
    assert!(out.summary.mass_balance_error <= 1e-8);
    assert!(out.summary.scheme_energy_error <= 1e-8);
    assert!(out.summary.energy_balance_error <= 1e-3, "energy balance {}", out.summary.energy_balance_error);
}

#[test]
fn reservoir_flow_reaches_bernoulli_with_losses() {
    let case = Reference::LiquidReservoir.case();
    let out = run(&case);
    let s = &out.final_state;
    let g = Grid::from_case(&case);
    let rho = s.liquid[g.n / 2].rho;
    let mu = s.liquid[g.n / 2].mu;
    let v = s.v_l[g.n / 2];
    // p_res − p_out = ρ v²/2 (1 + K + f L/D), f from Churchill at the flow's Reynolds number
    let re = rho * v * g.d_h[0] / mu;
    let f = cryofit_solver::closures::churchill_darcy(re, 0.0);
    let predicted = 0.5 * rho * v * v * (1.0 + 2.0 + f * case.pipe.length_m / g.d_h[0]);
    println!("reservoir: v = {v:.4} m/s, Re = {re:.0}, f = {f:.5}, Δp predicted {predicted:.0} Pa of 50000");
    assert!((predicted / 5.0e4 - 1.0).abs() < 0.02, "steady flow {v} m/s implies Δp {predicted}");
    // steady: the same velocity everywhere, liquid only
    assert!(s.v_l.iter().all(|x| (x - v).abs() < 1e-3 * v));
    assert!(s.alpha.iter().all(|&a| a == 0.0));
    assert!(out.summary.mass_balance_error <= 1e-8);
    assert!(out.summary.scheme_energy_error <= 1e-8);
}

#[test]
fn gas_cooldown_closes_the_energy_balance() {
    let case = Reference::GasCooldown.case();
    let out = run(&case);
    println!(
        "gas cool-down: steps {}, energy balance {:.2e}, scheme budget {:.2e}, mass {:.2e}",
        out.summary.steps,
        out.summary.energy_balance_error,
        out.summary.scheme_energy_error,
        out.summary.mass_balance_error
    );
    assert!(out.summary.mass_balance_error <= 1e-8);
    assert!(out.summary.scheme_energy_error <= 1e-8);
    assert!(out.summary.energy_balance_error <= 1e-3);
    // the wall cools from the inlet on
    let s = &out.final_state;
    assert!(s.t_w[0] < 100.0 && s.t_w[s.t_w.len() - 1] > 250.0, "{:?}", s.t_w);
    assert!(s.t_w.windows(2).all(|w| w[0] <= w[1] + 0.05));
}

#[test]
fn run_limits_end_runs_with_errors() {
    let mut case = Reference::Faucet.case();
    case.time.max_steps = Some(5);
    let fluid = fluids::embedded("nitrogen").unwrap();
    let params = driver::case_parameters(&case).unwrap();
    let err = driver::run(&case, fluid, &params, &mut |_| {}).unwrap_err();
    assert!(matches!(err, driver::SimError::MaxSteps { steps: 5, .. }), "{err}");
    let mut case = Reference::Faucet.case();
    case.time.max_wall_s = Some(1e-9);
    let err = driver::run(&case, fluid, &params, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("max_wall_s"), "{err}");
    // a minimum step that cannot be met names time, cell, variable and value
    let mut case = Reference::Faucet.case();
    case.time.initial_dt_s = 0.2;
    case.time.max_dt_s = 0.2;
    case.time.max_courant = 100.0;
    case.time.min_dt_s = 0.1;
    let err = driver::run(&case, fluid, &params, &mut |_| {}).unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, driver::SimError::StepTooSmall { .. }), "{msg}");
    assert!(msg.contains("cell") && msg.contains("t = "), "{msg}");
}

#[test]
fn boundary_time_tables_drive_the_run() {
    // the reservoir pressure ramps from 1.0 to 1.5 bar over 2 s: no flow at first, then flow
    let text =
        Reference::LiquidReservoir.text().replace("pressure_pa = 1.5e5", "pressure_pa = [[0.0, 1.0e5], [2.0, 1.5e5]]");
    let case = cryofit_solver::case::Case::from_toml(&text, "ramp.toml").unwrap();
    let out = run(&case);
    let v_at = |t: f64| {
        out.probes
            .iter()
            .filter(|o| o.quantity == "liquid_velocity_m_s" && (o.time_s - t).abs() < 1e-9)
            .map(|o| o.value)
            .next()
            .unwrap()
    };
    assert!(v_at(0.1).abs() < 0.2, "{}", v_at(0.1));
    assert!(v_at(1.0) > 0.5 && v_at(1.0) < v_at(5.0), "{} {}", v_at(1.0), v_at(5.0));
}

#[test]
fn contraction_follows_bernoulli() {
    // frictionless liquid from a 1.5 bar reservoir through a 20 mm pipe that narrows to 14 mm at
    // x = 5 m, into 1 bar: ½ ρ v_out² = Δp, v_in = v_out (A_out / A_in), and upstream of the
    // throat p = p_res − ½ ρ v_in²
    let text = Reference::LiquidReservoir
        .text()
        .replace("inner_diameter_m = 0.02", "inner_diameter_m = [[0.0, 0.02], [5.0, 0.014]]")
        .replace("loss_coefficient = 2.0", "loss_coefficient = 0.0")
        .replace("wall_friction = true", "")
        .replace("[physics]", "[physics]\nwall_friction = false");
    let case = cryofit_solver::case::Case::from_toml(&text, "contraction.toml").unwrap();
    let out = run(&case);
    let g = Grid::from_case(&case);
    let s = &out.final_state;
    let rho = s.liquid[g.n - 1].rho;
    let v_out = (2.0 * 5.0e4 / rho).sqrt();
    let v_in = v_out * (0.014f64 / 0.02).powi(2);
    let (j_in, j_out) = (g.n / 4, 3 * g.n / 4);
    let p_up = 1.5e5 - 0.5 * rho * v_in * v_in;
    println!(
        "contraction: v_in {:.3} (Bernoulli {v_in:.3}), v_out {:.3} ({v_out:.3}), p upstream {:.0} ({p_up:.0}) Pa",
        s.v_l[j_in],
        s.v_l[j_out],
        s.p[g.n / 4]
    );
    assert!((s.v_l[j_out] / v_out - 1.0).abs() < 0.03, "outlet velocity {}", s.v_l[j_out]);
    assert!((s.v_l[j_in] / v_in - 1.0).abs() < 0.03, "inlet velocity {}", s.v_l[j_in]);
    assert!(((s.p[g.n / 4] - 1.0e5) / (p_up - 1.0e5) - 1.0).abs() < 0.03, "upstream pressure {}", s.p[g.n / 4]);
    // mass flow is the same on both sides of the throat (steady state)
    let flow = |j: usize| s.liquid[j].rho * s.v_l[j] * g.area_junction[j];
    assert!((flow(j_in) / flow(j_out) - 1.0).abs() < 1e-4, "{} vs {}", flow(j_in), flow(j_out));
}

#[test]
fn an_exit_valve_does_not_heat_the_gas_that_leaves_through_it() {
    // nitrogen gas at 290 K from 2 bar through the 61 m line and a valve of 50 velocity heads at
    // its end into 1 bar, no heat from the wall: the flow is adiabatic, so each cell's gas keeps
    // the inlet's stagnation enthalpy; the valve's K v²/2 (tens of kJ/kg) heats the gas beyond
    // the valve, which has left the line, and leaves with it through the boundary's energy flux
    let text = Reference::GasCooldown
        .text()
        .replace(
            "pressure_pa = 1.2e5\nvoid_fraction = 1.0\ngas_temperature_k = 90.0",
            "pressure_pa = 2.0e5\nvoid_fraction = 1.0\ngas_temperature_k = 290.0",
        )
        .replace(
            "pressure_pa = 1.0e5\nvoid_fraction = 1.0\ngas_temperature_k = 290.0",
            "pressure_pa = 1.0e5\nvoid_fraction = 1.0\ngas_temperature_k = 290.0\nloss_coefficient = 50.0",
        )
        .replace("pressure_pa = [[0.0, 1.2e5], [61.0, 1.0e5]]", "pressure_pa = 2.0e5")
        .replace("end_s = 1000.0", "end_s = 60.0")
        .replace("gravity = false", "gravity = false\nwall_heat_transfer = false");
    let case = cryofit_solver::case::Case::from_toml(&text, "exit_valve.toml").unwrap();
    assert_eq!(case.outlet.loss_coefficient, 50.0, "the valve is in the case");
    let fluid = fluids::embedded("nitrogen").unwrap();
    let out = run(&case);
    let s = &out.final_state;
    let n = s.p.len();
    let h0_in = fluid.phase_props(Phase::Gas, 2.0e5, 290.0).unwrap().h + 0.5 * s.v_g[0] * s.v_g[0];
    let v_exit = s.v_g[n];
    for i in 0..n {
        let v = 0.5 * (s.v_g[i] + s.v_g[i + 1]);
        let h0 = s.gas[i].h + 0.5 * v * v;
        println!("exit valve: cell {i}: T_g {:.2} K, v {v:.1} m/s, h0 − h0_in {:.0} J/kg", s.t_g[i], h0 - h0_in);
        // (without wall heat the line's gas stays within a kelvin of the dewar's: 290.3 K
        // everywhere, where the valve's heat booked in the exit cell had taken it to 318 K)
        assert!((s.t_g[i] - 290.0).abs() < 1.0, "cell {i}: gas at {} K", s.t_g[i]);
    }
    // the valve's heat left with the outflow: about K v²/2 per kilogram of it
    let m_dot = s.gas[n - 1].rho * v_exit * Grid::from_case(&case).area_junction[n];
    let valve_w = m_dot * 0.5 * 50.0 * v_exit * v_exit;
    println!(
        "exit valve: {v_exit:.1} m/s, exported {:.0} J over 60 s, K v²/2 ṁ = {valve_w:.1} W",
        out.summary.exported_heat_j
    );
    assert!(v_exit > 5.0, "the line flows: {v_exit} m/s");
    assert!(out.summary.exported_heat_j > 0.5 * valve_w * 60.0, "{} J", out.summary.exported_heat_j);
    assert!(out.summary.mass_balance_error <= 1e-8);
    assert!(out.summary.scheme_energy_error <= 1e-8);
    // the books close on it (the residual is the adiabatic line's own few joules)
    let residual = out.summary.energy_balance_residual_j;
    assert!(residual.abs() <= 1e-3 * out.summary.exported_heat_j, "residual {residual} J");
}

/// The last cell's stagnation enthalpy above the inlet's, J/kg, and the mass flow through the
/// exit, kg/s, of nitrogen gas at 280 K driven from 4.26 bar through the 61 m line into 0.83 bar
/// (the NBS line at the drive of its subcooled runs) without wall heat, on `cells` cells graded
/// by `grading` (1: equal cells) after 10 s.
fn fast_adiabatic_exit(cells: usize, grading: f64) -> (f64, f64) {
    let text = Reference::GasCooldown
        .text()
        .replace(
            "pressure_pa = 1.2e5\nvoid_fraction = 1.0\ngas_temperature_k = 90.0",
            "pressure_pa = 4.26e5\nvoid_fraction = 1.0\ngas_temperature_k = 280.0",
        )
        .replace(
            "pressure_pa = 1.0e5\nvoid_fraction = 1.0\ngas_temperature_k = 290.0",
            "pressure_pa = 0.83e5\nvoid_fraction = 1.0\ngas_temperature_k = 280.0",
        )
        .replace("pressure_pa = [[0.0, 1.2e5], [61.0, 1.0e5]]", "pressure_pa = [[0.0, 4.26e5], [61.0, 0.83e5]]")
        .replace(
            "gas_temperature_k = 290.0\nwall_temperature_k = 290.0",
            "gas_temperature_k = 280.0\nwall_temperature_k = 280.0",
        )
        .replace("cells = 30", &format!("cells = {cells}\ngrading = {grading:?}"))
        .replace("end_s = 1000.0", "end_s = 10.0")
        .replace("gravity = false", "gravity = false\nwall_heat_transfer = false");
    let case = cryofit_solver::case::Case::from_toml(&text, "fast_exit.toml").unwrap();
    assert_eq!(case.pipe.grading, grading);
    let fluid = fluids::embedded("nitrogen").unwrap();
    let out = run(&case);
    let s = &out.final_state;
    let n = s.p.len();
    let h0_in = fluid.phase_props(Phase::Gas, 4.26e5, 280.0).unwrap().h + 0.5 * s.v_g[0] * s.v_g[0];
    let v = 0.5 * (s.v_g[n - 1] + s.v_g[n]);
    let excess = s.gas[n - 1].h + 0.5 * v * v - h0_in;
    let m_dot = s.gas[n - 1].rho * s.v_g[n] * Grid::from_case(&case).area_junction[n];
    println!(
        "fast adiabatic exit, {cells} cells graded {grading}: first cell {:.2} K, last cell {:.2} K, exit {:.0} m/s, h0 excess {excess:.0} J/kg, {m_dot:.5} kg/s",
        s.t_g[0],
        s.t_g[n - 1],
        s.v_g[n]
    );
    assert!(out.summary.scheme_energy_error <= 1e-8);
    (excess, m_dot)
}

#[test]
fn fast_adiabatic_gas_gains_stagnation_enthalpy_only_to_first_order_at_the_exit() {
    // an adiabatic frictional flow keeps its stagnation enthalpy: its gas leaves colder than it
    // came, by its kinetic energy (about 268 K at 160 m/s). The donor-cell scheme's pressure work
    // is first order in the cell, and at these exit speeds its error is the last cell's gas some
    // 15 K too warm on 30 cells (VALIDATION.md, "Each fluid alone on 120 cells"), where station 4
    // of the NBS line lies; it must shrink with the cell at least as fast as the cell
    let (e30, m30) = fast_adiabatic_exit(30, 1.0);
    let (e60, m60) = fast_adiabatic_exit(60, 1.0);
    let (e120, m120) = fast_adiabatic_exit(120, 1.0);
    assert!(e30 > 0.0 && e30 < 25e3, "30 cells: the last cell's h0 is {e30} J/kg above the inlet's");
    assert!(e60.abs() <= 0.65 * e30, "60 cells: {e60} J/kg against {e30} on 30");
    assert!(e120.abs() <= 0.65 * e60.abs(), "120 cells: {e120} J/kg against {e60} on 60");
    // the flow itself hardly moves with the grid
    for (cells, m) in [(30, m30), (60, m60)] {
        assert!((m / m120 - 1.0).abs() < 0.02, "{cells} cells: {m} kg/s against {m120} on 120");
    }
}

#[test]
fn cells_graded_towards_the_ends_give_the_exit_a_fine_grids_answer() {
    // the same flow on 30 cells graded by 8 (the end cells 0.59 m, the middle ones 4.7 m): the
    // last cell is as short as on 120 equal cells, and so is its error
    let (graded, m_graded) = fast_adiabatic_exit(30, 8.0);
    let (e60, _) = fast_adiabatic_exit(60, 1.0);
    let (_, m120) = fast_adiabatic_exit(120, 1.0);
    assert!(graded.abs() < e60.abs(), "graded 30 cells: {graded} J/kg against {e60} on 60 equal cells");
    assert!((m_graded / m120 - 1.0).abs() < 0.01, "graded: {m_graded} kg/s against {m120} on 120");
}
