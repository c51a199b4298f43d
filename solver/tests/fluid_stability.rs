//! Every phase table's interpolant keeps the signs of a stable fluid everywhere it answers:
//! ∂ρ/∂p|T > 0, ∂u/∂T|p > 0, c_p > 0, sampled inside every interpolation cell on a pattern
//! other than the one the loader's repair uses.

use cryofit_solver::fluids::{self, EMBEDDED_FLUIDS};

#[test]
fn every_table_is_thermodynamically_stable_between_its_nodes() {
    let mut report = String::new();
    for name in EMBEDDED_FLUIDS {
        let table = fluids::embedded(name).expect("embedded table");
        let limiter = table.limiter_report();
        eprintln!("{name}: {limiter:?}");
        if limiter.cells_unrepaired > 0 {
            report.push_str(&format!("{name}: {} cells the loader could not repair\n", limiter.cells_unrepaired));
        }
        for samples in [5, 7, 16] {
            let bad = table.stability_violations(samples);
            if !bad.is_empty() {
                report.push_str(&format!("{name} ({samples}×{samples} per cell): {} samples\n", bad.len()));
                for v in bad.iter().take(12) {
                    report.push_str(&format!(
                        "  {} p = {:.0} Pa, T = {:.4} K: {} = {:.4e}\n",
                        v.phase, v.p, v.t, v.what, v.value
                    ));
                }
            }
        }
    }
    assert!(report.is_empty(), "interpolants with the wrong sign:\n{report}");
}
