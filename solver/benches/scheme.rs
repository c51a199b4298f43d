//! Cost of the nearly-implicit scheme per cell-step on reference problems at several grid sizes.
//!
//! `cargo bench -p cryofit-solver --bench scheme` prints a Markdown table: for each problem and
//! grid, the steps taken, the integration wall time (median of repeated runs) and the time per
//! cell-step. Pass a number to change the repetitions (default 3).

use cryofit_solver::driver;
use cryofit_solver::fluids;
use cryofit_solver::reference::Reference;

fn main() {
    let reps: usize = std::env::args().skip(1).find_map(|a| a.parse().ok()).unwrap_or(3);
    println!("| problem | cells | steps | rejected | wall time (median of {reps}) | per cell-step |");
    println!("| --- | --- | --- | --- | --- | --- |");
    for (reference, label) in
        [(Reference::Faucet, "faucet, 0.5 s"), (Reference::GasCooldown, "gas cool-down of the 61 m line, 1000 s")]
    {
        for cells in [30usize, 100, 300] {
            let case = reference.with_cells(cells);
            let fluid = fluids::embedded(&case.fluid.name).expect("fluid");
            let params = driver::case_parameters(&case).expect("parameters");
            let mut times = Vec::new();
            let mut summary = None;
            for _ in 0..reps {
                let out = driver::run(&case, fluid, &params, &mut |_| {}).expect("reference run");
                times.push(out.summary.wall_time_s);
                summary = Some(out.summary);
            }
            times.sort_by(f64::total_cmp);
            let median = times[times.len() / 2];
            let s = summary.expect("ran");
            let per = median / (s.steps as f64 * cells as f64);
            println!(
                "| {label} | {cells} | {} | {} | {:.3} s | {:.2} µs |",
                s.steps,
                s.rejected_steps,
                median,
                per * 1e6
            );
        }
    }
}
