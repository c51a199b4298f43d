//! Every registry parameter is live: changing it changes the output of a case in which its
//! regime occurs.
//!
//! The cases: the first 90 s of the NBS subcooled chilldown on 10 cells (convection, nucleate,
//! transition and film boiling, stratified and wavy flow, interphase transfer, friction), the same
//! with the `miropolskii` correlation set (its own film-boiling and rewet parameters) at the
//! case's flow and, for 300 s, throttled to a low mass flux (where the rewet temperature's
//! Weber-number terms act), the blowdown of a liquid-filled line (flashing), and the
//! phase-separation problem (heat exchange without phase change, `hi_vol`).

use cryofit_solver::case::Case;
use cryofit_solver::driver::{self, Output};
use cryofit_solver::fluids;
use cryofit_solver::params::{ParameterSet, REGISTRY};
use cryofit_solver::reference::Reference;

fn nbs(correlations: &str, loss: f64) -> Case {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs/subcooled-4.2atm.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let mut case = Case::from_toml(&text, path).unwrap();
    case.pipe.cells = 10;
    case.time.end_s = 90.0;
    case.time.output_interval_s = 2.0;
    case.physics.correlations = correlations.to_string();
    case.inlet.loss_coefficient = loss;
    case
}

/// 10 m of line full of liquid nitrogen at 85 K and 3.4 bar (a void fraction of 10⁻⁶), closed at
/// the inlet and opened to 0.82 atm at the outlet, for 5 s: the liquid, 9 K above its saturation
/// temperature at the outlet pressure, flashes.
fn blowdown() -> Case {
    let text = r#"
        title = "blowdown of a liquid-filled line"
        [fluid]
        name = "nitrogen"
        [pipe]
        length_m = 10.0
        inner_diameter_m = 0.015875
        wall_thickness_m = 0.0015875
        wall_material = "copper"
        roughness_m = 1.5e-6
        inclination_deg = 0.0
        cells = 10
        [inlet]
        kind = "closed"
        [outlet]
        kind = "pressure"
        pressure_pa = 83087.0
        void_fraction = 1.0
        gas_temperature_k = 290.0
        [initial]
        pressure_pa = 336399.0
        void_fraction = 1e-6
        gas_temperature_k = 85.0
        liquid_temperature_k = 85.0
        wall_temperature_k = 85.0
        [ambient]
        temperature_k = 290.0
        heat_transfer_coefficient_w_m2k = 0.0
        [time]
        end_s = 5.0
        output_interval_s = 0.1
        profile_interval_s = 1.0
        max_dt_s = 0.01
        max_courant = 10.0
        [[stations]]
        name = "mid"
        x_m = 5.0
    "#;
    Case::from_toml(text, "blowdown").unwrap()
}

fn run(case: &Case, params: &ParameterSet) -> Output {
    let fluid = fluids::embedded(&case.fluid.name).unwrap();
    driver::run(case, fluid, params, &mut |_| {}).unwrap_or_else(|e| panic!("{}: {e}", case.title))
}

/// Largest relative difference between two runs' probe values.
fn difference(a: &Output, b: &Output) -> f64 {
    if a.probes.len() != b.probes.len() {
        return f64::INFINITY;
    }
    a.probes
        .iter()
        .zip(&b.probes)
        .map(|(x, y)| (x.value - y.value).abs() / x.value.abs().max(y.value.abs()).max(1e-9))
        .fold(0.0, f64::max)
}

/// The bounds of the boiling curve's ordering (registry parameters) and the parameters each
/// holds (acting with `Tonbsc` at its upper bound, the others at their lower bound).
const ORDERING_BOUNDS: [(&str, &[&str]); 3] =
    [("boil_gap_chf", &["Tchfsc", "Tonbsc"]), ("boil_gap_mfb", &["Tmfbsc"]), ("chf_over_mfb", &["qchfsc"])];

fn registry_spec(name: &str) -> &'static cryofit_solver::params::ParamSpec {
    REGISTRY.iter().find(|p| p.name == name).unwrap()
}

/// Parameters that act only where another is switched on, and the value that switches it on.
const ENABLED_BY: [(&str, &str, f64); 1] = [("hg_drop_eps", "hg_drop_gain", 1.0)];

/// A value inside the bounds, clearly different from the default.
fn perturbed(default: f64, lower: f64, upper: f64) -> f64 {
    if upper > default { default + 0.5 * (upper - default) } else { default - 0.5 * (default - lower) }
}

#[test]
fn every_parameter_changes_some_output() {
    let cases = [
        ("nbs subcooled, paper set", nbs("paper", 10.0)),
        ("nbs subcooled, miropolskii set", nbs("miropolskii", 10.0)),
        // a throttled inlet: low mass flux, where the Darr–Hartwig rewet temperature is below
        // its cap at the critical temperature
        ("nbs subcooled, miropolskii set, throttled", {
            let mut c = nbs("miropolskii", 1000.0);
            c.time.end_s = 300.0;
            c
        }),
        // a liquid-filled line opened to the atmosphere: liquid flashing where it holds no vapour
        // (the bubble nuclei of `flash_void_min`)
        ("blowdown", blowdown()),
    ];
    let separation = Reference::Separation.with_cells(10);
    let baselines: Vec<Output> = cases.iter().map(|(_, c)| run(c, &ParameterSet::new())).collect();
    let sep_base = run(&separation, &driver::case_parameters(&separation).unwrap());
    let mut dead = Vec::new();
    for p in REGISTRY {
        let value = perturbed(p.default, p.lower, p.upper);
        let mut live = None;
        // a bound of the boiling curve's ordering acts where the parameter it holds is at its
        // lower bound: both runs take that value
        let held = ORDERING_BOUNDS.iter().find(|(b, _)| *b == p.name).map(|(_, h)| *h);
        let mut base_set = ParameterSet::new();
        for h in held.unwrap_or(&[]) {
            let sp = registry_spec(h);
            // the scale of T_onb goes up, every other held scale down
            base_set.set(h, if *h == "Tonbsc" { sp.upper } else { sp.lower }).unwrap();
        }
        // a parameter that acts only where another is switched on: both runs switch it on
        let enabled = ENABLED_BY.iter().find(|(n, _, _)| *n == p.name);
        if let Some((_, on, v)) = enabled {
            base_set.set(on, *v).unwrap();
        }
        for ((label, case), base) in cases.iter().zip(&baselines) {
            let held_base = (held.is_some() || enabled.is_some()).then(|| run(case, &base_set));
            let base = held_base.as_ref().unwrap_or(base);
            let mut set = base_set.clone();
            set.set(p.name, value).unwrap();
            let d = match driver::run(case, fluids::embedded("nitrogen").unwrap(), &set, &mut |_| {}) {
                Ok(out) => difference(base, &out),
                // a run the change makes fail is a change too
                Err(_) => f64::INFINITY,
            };
            if d > 1e-9 {
                live = Some((label.to_string(), d));
                break;
            }
        }
        if live.is_none() {
            let mut set = driver::case_parameters(&separation).unwrap();
            set.set(p.name, value).unwrap();
            let out = run(&separation, &set);
            let d = difference(&sep_base, &out);
            if d > 1e-9 {
                live = Some(("separation".into(), d));
            }
        }
        match live {
            Some((label, d)) => println!("{:<16} {} = {value}: changes {label} by {d:.2e}", p.name, p.name),
            None => dead.push(p.name),
        }
    }
    assert!(dead.is_empty(), "parameters without effect on any case: {dead:?}");
}
