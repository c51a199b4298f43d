//! `cryofit bench speed --case CASE [--case CASE]... [--repeats N] [--params FILE]
//! [--set NAME=VALUE]... [--target X] [--json]`: how many times faster than physical time a
//! case runs on one core.
//!
//! Each case runs `N` times one after another on the calling thread (the solver uses one core per
//! run), and the report gives per case the simulated time, the steps and rejected steps, what held
//! the steps (`step_limited_by`), the integration's wall time of every repeat (the summary's
//! `wall_time_s`: reading the case and the tables and writing outputs are not in it) and the
//! median's ratio of simulated to wall time, held against the target (default 5 000×: issue
//! "operating envelope", the three NBS nitrogen cases at 30 cells, 1000 s, on one core). The
//! repeats are the same computation, so their step counts must agree; a run that does not
//! (which would make the timing meaningless) or that fails is reported and fails the target.
//! Timings move with whatever else the machine runs: BENCHMARKS.md records them with the
//! machine's state, and instruction counts (`valgrind --tool=callgrind`) where a change must
//! be measured free of noise.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use cryofit_solver::case::Case;
use cryofit_solver::driver;
use cryofit_solver::fluids::FluidTable;
use cryofit_solver::params::ParameterSet;
use serde::Serialize;

use crate::fluid_source;
use crate::param_values::{case_parameters, experiment_of};

/// Default target: simulated time over wall time.
const DEFAULT_TARGET: f64 = 5000.0;

/// Most repeats per case.
const MAX_REPEATS: usize = 100;

/// Arguments of `cryofit bench speed`.
#[derive(Debug, Args)]
pub struct SpeedArgs {
    /// A case file (repeatable: each is measured in turn).
    #[arg(long = "case", value_name = "CASE.toml", required = true)]
    cases: Vec<PathBuf>,
    /// Runs per case; the median's wall time counts.
    #[arg(long, value_name = "N", default_value_t = 3)]
    repeats: usize,
    /// A parameter file (`cryofit simulate --params`): registry parameters and `case.` fields.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Set a registry parameter, or a case field by its `case.` name, for every case
    /// (repeatable; after `--params`).
    #[arg(long = "set", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    set: Vec<String>,
    /// The speed the median run of every case must reach, simulated time over wall time.
    #[arg(long, value_name = "X", default_value_t = DEFAULT_TARGET)]
    target: f64,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// One case's measurement.
#[derive(Debug, Serialize)]
struct CaseSpeed {
    case: String,
    cells: usize,
    /// Physical time simulated, s.
    simulated_s: f64,
    steps: u64,
    rejected_steps: u64,
    /// What held the accepted steps, by the rule's name (the summary's `step_limited_by`).
    step_limited_by: BTreeMap<String, u64>,
    /// The integration's wall time of every repeat, s, in the order run.
    wall_times_s: Vec<f64>,
    /// Their median, s.
    median_wall_s: f64,
    /// Simulated time over the median wall time.
    speed: f64,
    /// Microseconds of the median run per cell and accepted step.
    per_cell_step_us: f64,
    /// `speed` ≥ the target.
    target_met: bool,
}

/// A case that could not be measured.
#[derive(Debug, Serialize)]
struct CaseFailure {
    case: String,
    error: String,
}

/// The report (`--json` prints it).
#[derive(Debug, Serialize)]
struct Report {
    repeats: usize,
    target: f64,
    /// The parameters and case fields set by `--params` and `--set`, by name.
    set: BTreeMap<String, f64>,
    cases: Vec<CaseSpeed>,
    failures: Vec<CaseFailure>,
    /// The slowest case's speed (`None` when no case was measured).
    slowest_speed: Option<f64>,
    /// Every case measured and every one at or above the target.
    target_met: bool,
}

/// Runs `cryofit bench speed`.
pub fn run(args: &SpeedArgs) -> Result<()> {
    if args.repeats == 0 || args.repeats > MAX_REPEATS {
        bail!("--repeats {}: give 1 to {MAX_REPEATS}", args.repeats);
    }
    if !(args.target.is_finite() && args.target > 0.0) {
        bail!("--target {}: give a positive number (simulated time over wall time, e.g. 5000)", args.target);
    }
    let mut cases = Vec::new();
    let mut failures = Vec::new();
    let mut set = BTreeMap::new();
    for path in &args.cases {
        let setup = Setup::read(path, args)?;
        set.extend(setup.values.clone());
        match time_runs(&setup, args.repeats) {
            Ok((summary, wall_times_s)) => cases.push(case_speed(setup, summary, wall_times_s, args.target)),
            Err(error) => failures.push(CaseFailure { case: setup.name, error }),
        }
    }
    let slowest_speed = cases.iter().map(|c| c.speed).min_by(f64::total_cmp);
    let report = Report {
        repeats: args.repeats,
        target: args.target,
        set,
        target_met: failures.is_empty() && cases.iter().all(|c| c.target_met),
        cases,
        failures,
        slowest_speed,
    };
    super::emit(&report, args.json, print_report)
}

/// One case ready to run: the case with its `--params` and `--set` case fields applied, its
/// fluid's table, its parameters, and the values those options gave.
struct Setup {
    name: String,
    case: Case,
    table: Cow<'static, FluidTable>,
    params: ParameterSet,
    values: BTreeMap<String, f64>,
}

impl Setup {
    /// Reads the case at `path` and applies the options; an error here (a file, a name or a value
    /// the command cannot use) ends the command.
    fn read(path: &Path, args: &SpeedArgs) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {name}"))?;
        let case = Case::from_toml(&text, &name)?;
        let experiment = experiment_of(path, None);
        let (applied, params, sources) = case_parameters(&case, &name, &experiment, args.params.as_deref(), &args.set)?;
        let values = sources.iter().flat_map(|s| s.values.clone()).collect();
        let table = fluid_source::load(&applied.case.fluid.name)?;
        Ok(Self { name, case: applied.case, table, params, values })
    }
}

/// Runs the case `repeats` times: the first run's summary and every run's integration time, or
/// why the case has no speed (a run that fails, repeats whose step counts differ).
fn time_runs(setup: &Setup, repeats: usize) -> Result<(driver::Summary, Vec<f64>), String> {
    let run = |k: usize| {
        driver::run(&setup.case, &setup.table, &setup.params, &mut |_| {})
            .map(|out| out.summary)
            .map_err(|e| format!("run {k} of {repeats}: {e}"))
    };
    let first = run(1)?;
    let mut wall_times_s = vec![first.wall_time_s];
    for k in 2..=repeats {
        let s = run(k)?;
        if (s.steps, s.rejected_steps) != (first.steps, first.rejected_steps) {
            return Err(format!(
                "run {k} took {} steps ({} rejected) where run 1 took {} ({}): the repeats are not the same \
                 computation, so their times do not measure it",
                s.steps, s.rejected_steps, first.steps, first.rejected_steps
            ));
        }
        wall_times_s.push(s.wall_time_s);
    }
    Ok((first, wall_times_s))
}

/// The measurement of a case from its runs' summary and times.
fn case_speed(setup: Setup, s: driver::Summary, wall_times_s: Vec<f64>, target: f64) -> CaseSpeed {
    let median_wall_s = median(&wall_times_s);
    let speed = s.simulated_time_s / median_wall_s;
    let cells = setup.case.pipe.cells;
    CaseSpeed {
        case: setup.name,
        cells,
        simulated_s: s.simulated_time_s,
        steps: s.steps,
        rejected_steps: s.rejected_steps,
        step_limited_by: s.step_limited_by,
        per_cell_step_us: median_wall_s / (s.steps.max(1) as f64 * cells.max(1) as f64) * 1e6,
        wall_times_s,
        median_wall_s,
        speed,
        target_met: speed >= target,
    }
}

/// The median of a nonempty slice (the mean of the middle two for an even length).
fn median(xs: &[f64]) -> f64 {
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

fn print_report(r: &Report) {
    let set = if r.set.is_empty() {
        String::new()
    } else {
        let list: Vec<String> = r.set.iter().map(|(k, v)| format!("{k}={v}")).collect();
        format!(", with {}", list.join(", "))
    };
    println!("Speed on one core, median of {} run(s) per case{set}:", r.repeats);
    println!(
        "  {:<44} {:>5} {:>8} {:>8} {:>9} {:>10} {:>9} {:>9}  held by",
        "case", "cells", "sim s", "steps", "rejected", "median s", "speed", "µs/c-s"
    );
    for c in &r.cases {
        let held = c.step_limited_by.iter().max_by_key(|(_, n)| **n).map_or_else(
            || "-".into(),
            |(rule, n)| format!("{rule} ({:.0} %)", 100.0 * *n as f64 / c.steps.max(1) as f64),
        );
        println!(
            "  {:<44} {:>5} {:>8.0} {:>8} {:>9} {:>10.3} {:>8.0}× {:>9.2}  {held}",
            c.case, c.cells, c.simulated_s, c.steps, c.rejected_steps, c.median_wall_s, c.speed, c.per_cell_step_us
        );
    }
    for f in &r.failures {
        println!("  {}: not measured: {}", f.case, f.error);
    }
    match r.slowest_speed {
        Some(s) => println!(
            "Slowest {s:.0}× physical time (target ≥ {:.0}× for every case: {})",
            r.target,
            if r.target_met { "met" } else { "not met" }
        ),
        None => println!("No case was measured (target ≥ {:.0}×: not met)", r.target),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_lengths() {
        assert_eq!(median(&[3.0]), 3.0);
        assert_eq!(median(&[0.3, 0.1, 0.2]), 0.2);
        assert_eq!(median(&[0.4, 0.1, 0.3, 0.2]), 0.25);
    }
}
