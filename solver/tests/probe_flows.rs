//! The probes' mass flow at the line's ends is the flow the scheme carried through its boundary
//! junctions: integrated over a run, the inflow at x = 0 less the outflow at x = L is the
//! change of the line's mass.

use cryofit_solver::case::{Case, Station};
use cryofit_solver::driver;
use cryofit_solver::fluids;
use cryofit_solver::model::{Grid, State};
use cryofit_solver::params::ParameterSet;

fn line_mass(s: &State, g: &Grid) -> f64 {
    (0..g.n).map(|i| (s.m_g[i] + s.m_l[i]) * g.volume[i]).sum()
}

/// The probe series of `quantity` at `station`, (time, value) in time order.
fn series(out: &driver::Output, station: &str, quantity: &str) -> Vec<(f64, f64)> {
    out.probes.iter().filter(|o| o.station == station && o.quantity == quantity).map(|o| (o.time_s, o.value)).collect()
}

fn trapezoid(xs: &[(f64, f64)]) -> f64 {
    xs.windows(2).map(|w| 0.5 * (w[0].1 + w[1].1) * (w[1].0 - w[0].0)).sum()
}

/// The first 20 s of the saturated NBS nitrogen run on 10 cells: liquid from the dewar enters a
/// line full of warm vapour, the inlet's flow reverses again and again (vapour pushed back into
/// the dewar), and the line fills. Probed every 5 ms at both ends, the inflow less the outflow
/// integrates to the line's mass change within 2 % of the mass that entered. (The probe took the
/// inlet cell's liquid density for the reservoir's liquid, and read a net backflow into the dewar
/// where the line was gaining mass.)
#[test]
fn end_probes_carry_the_boundary_flows() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs/saturated-2.5atm.toml");
    let mut case = Case::from_toml(&std::fs::read_to_string(path).unwrap(), path).unwrap();
    case.pipe.cells = 10;
    case.time.end_s = 20.0;
    case.time.output_interval_s = 0.005;
    case.stations =
        vec![Station { name: "in".into(), x_m: 0.0 }, Station { name: "out".into(), x_m: case.pipe.length_m }];
    let fluid = fluids::embedded(&case.fluid.name).unwrap();
    let grid = Grid::from_case(&case);
    let m0 = line_mass(&driver::initial_state(&case, fluid, &grid).unwrap(), &grid);
    let out = driver::run(&case, fluid, &ParameterSet::new(), &mut |_| {}).unwrap();
    let m1 = line_mass(&out.final_state, &grid);
    let inflow = series(&out, "in", "mass_flow_kg_s");
    let outflow = series(&out, "out", "mass_flow_kg_s");
    assert!(inflow.len() > 3000 && inflow.len() == outflow.len());
    let (mass_in, mass_out) = (trapezoid(&inflow), trapezoid(&outflow));
    let gross_in: f64 = inflow.windows(2).map(|w| 0.5 * (w[0].1.max(0.0) + w[1].1.max(0.0)) * (w[1].0 - w[0].0)).sum();
    assert!(m1 > m0 && mass_in > 0.0, "the line fills: {m0} → {m1} kg, net inflow {mass_in} kg");
    let defect = (m1 - m0) - (mass_in - mass_out);
    assert!(
        defect.abs() <= 0.02 * gross_in,
        "Δm {} kg against ∫in − ∫out {} kg (gross inflow {gross_in} kg)",
        m1 - m0,
        mass_in - mass_out
    );
}
