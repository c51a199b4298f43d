//! `cryofit bench ...`: measurements too heavy for the test suite.
//!
//! `cryofit bench robustness --case CASE --samples N --seed S [--json]` draws N parameter sets
//! uniformly within the registry bounds (the `numerics` group stays at its defaults: those are
//! choices of the method, not uncertain physics) and runs the case with each, on all cores. No
//! run may panic; every failure is reported with its cause (time, cell, variable, reason).
//!
//! `cryofit bench coordinator --workers N --evaluations M [--json]` measures the coordinator's
//! throughput with a null model (see [`coordinator`]).
//!
//! `cryofit bench envelope [--json] [--params FILE]` runs the NBS line with four fluids, saturated
//! and subcooled, at four drive pressures and reports which runs complete, how fast and how well
//! they keep their energy balance (see [`envelope`]).
//!
//! `cryofit bench chaos --case CASE --param NAME [--ulps N]` measures how far a run's chilldown
//! moves when one parameter moves by a few units in the last place (see [`chaos`]).
//!
//! `cryofit bench speed --case CASE [--case CASE]... [--repeats N] [--json]` measures how many
//! times faster than physical time each case runs on one core (see [`speed`]).
//!
//! `cryofit bench grid (--case CASE [--case CASE]... [--data DATA]... | --calibration FILE)
//! [--cells N,N,...]` runs cases on refined grids and reports how their station chilldowns move
//! (see [`grid`]).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use cryofit_solver::case::Case;
use cryofit_solver::driver::{self, SimError};
use cryofit_solver::params::{ParameterSet, REGISTRY};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;

use crate::fluid_source;

mod chaos;
mod coordinator;
mod envelope;
mod grid;
mod speed;

/// `cryofit bench` subcommands.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Run a case with random parameter sets and report how many complete and why the others fail.
    Robustness(RobustnessArgs),
    /// Coordinator throughput: HTTP claim → null model → HTTP result → tell → persist.
    Coordinator(coordinator::CoordinatorArgs),
    /// Operating envelope: the NBS line with four fluids, saturated and subcooled, at four drive pressures.
    Envelope(envelope::EnvelopeArgs),
    /// Chaos: a case's chilldown with one parameter moved by a few units in the last place.
    Chaos(chaos::ChaosArgs),
    /// Speed: how many times faster than physical time cases run on one core.
    Speed(speed::SpeedArgs),
    /// Grid refinement: cases on finer and finer grids, their station chilldowns and fit.
    Grid(grid::GridArgs),
}

/// Arguments of `cryofit bench robustness`.
#[derive(Debug, Args)]
pub struct RobustnessArgs {
    /// The case file.
    #[arg(long, value_name = "CASE.toml")]
    case: PathBuf,
    /// Number of parameter sets.
    #[arg(long, value_name = "N", default_value_t = 100)]
    samples: usize,
    /// Seed of the sampler: the same seed draws the same parameter sets.
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// Runs a `cryofit bench` subcommand.
pub fn run(cmd: &BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Robustness(args) => robustness(args),
        BenchCommand::Coordinator(args) => coordinator::run(args),
        BenchCommand::Envelope(args) => envelope::run(args),
        BenchCommand::Chaos(args) => chaos::run(args),
        BenchCommand::Speed(args) => speed::run(args),
        BenchCommand::Grid(args) => grid::run(args),
    }
}

/// Prints a report: as JSON with `--json`, else as the command's text (`text`).
fn emit<R: Serialize>(report: &R, json: bool, text: impl FnOnce(&R)) -> Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
    } else {
        text(report);
    }
    Ok(())
}

/// The robustness report (`--json` prints it).
#[derive(Debug, Serialize)]
struct Report {
    case: String,
    samples: usize,
    seed: u64,
    completed: usize,
    completion_fraction: f64,
    wall_time_s: f64,
    /// Failure causes and how often each occurred.
    failure_causes: BTreeMap<String, usize>,
    /// Every failure: sample index, the parameter values drawn and the error.
    failures: Vec<Failure>,
}

#[derive(Debug, Serialize)]
struct Failure {
    sample: usize,
    error: String,
    parameters: BTreeMap<String, f64>,
}

/// The parameter set of sample `i`: every non-numerics registry parameter uniform in its bounds.
pub fn sample(seed: u64, i: usize) -> ParameterSet {
    let mut rng = StdRng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(i as u64));
    let mut set = ParameterSet::new();
    for p in REGISTRY.iter().filter(|p| p.group != "numerics") {
        let v = if p.upper > p.lower { rng.gen_range(p.lower..=p.upper) } else { p.lower };
        set.set(p.name, v).expect("a value within the registry bounds");
    }
    set
}

/// A short classification of a failure, for counting.
fn cause(e: &SimError) -> String {
    match e {
        SimError::StepTooSmall { variable, reason, .. } => format!("time step too small: {variable}: {reason}"),
        SimError::MaxSteps { .. } => "time.max_steps reached".into(),
        SimError::MaxWall { .. } => "time.max_wall_s reached".into(),
        other => other.to_string(),
    }
}

fn robustness(args: &RobustnessArgs) -> Result<()> {
    if args.samples == 0 {
        bail!("--samples 0: give at least one sample");
    }
    let path = args.case.display().to_string();
    let text = std::fs::read_to_string(&args.case).with_context(|| format!("cannot read {path}"))?;
    let case = Case::from_toml(&text, &path)?;
    let base = driver::case_parameters(&case).map_err(|e| anyhow::anyhow!("{path}: {e}"))?;
    let table = fluid_source::load(&case.fluid.name)?;
    let clock = Instant::now();
    let results: Vec<(usize, ParameterSet, Result<(), SimError>)> = (0..args.samples)
        .into_par_iter()
        .map(|i| {
            let mut params = base.clone();
            params.overlay(&sample(args.seed, i));
            let outcome = driver::run(&case, &table, &params, &mut |_| {}).map(|_| ());
            (i, params, outcome)
        })
        .collect();
    let mut report = Report {
        case: path.clone(),
        samples: args.samples,
        seed: args.seed,
        completed: 0,
        completion_fraction: 0.0,
        wall_time_s: clock.elapsed().as_secs_f64(),
        failure_causes: BTreeMap::new(),
        failures: Vec::new(),
    };
    for (i, params, outcome) in results {
        match outcome {
            Ok(()) => report.completed += 1,
            Err(e) => {
                *report.failure_causes.entry(cause(&e)).or_default() += 1;
                report.failures.push(Failure {
                    sample: i,
                    error: e.to_string(),
                    parameters: params.explicit().clone(),
                });
            }
        }
    }
    report.completion_fraction = report.completed as f64 / args.samples as f64;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{path}: {} of {} parameter sets completed ({:.1} %), seed {}, {:.1} s",
        report.completed,
        report.samples,
        100.0 * report.completion_fraction,
        report.seed,
        report.wall_time_s
    );
    for (cause, count) in &report.failure_causes {
        println!("  {count:>5}  {cause}");
    }
    for f in report.failures.iter().take(10) {
        println!("  sample {}: {}", f.sample, f.error);
    }
    Ok(())
}
