//! `cryofit bench envelope [--json] [--params FILE] [--fluids A,B] [--kinds K,K]
//! [--pressures-atm P,P] [--end-s S] [--cells N] [--jobs N] [--max-wall-s S]`: the solver's
//! operating envelope on the NBS line.
//!
//! Every run is the line of `examples/nbs/subcooled-4.2atm.toml` (built into the binary): 61 m
//! of vacuum-jacketed copper tube, 15.875 mm inner diameter, 30 cells, a reservoir behind a valve
//! that opens over 2 s with a loss coefficient of 10, discharge to the local atmosphere of
//! 83 087 Pa (0.82 atm), no heat from outside, the stations TS1–TS4 and every other modelling
//! choice of that case, except that the fluid is changed and the line and its gas start uniform
//! at 290 K. For each fluid, kind and drive pressure:
//!
//! - the drive pressure is a gauge pressure over the local atmosphere: the dewar holds
//!   83 087 Pa + p_atm × 101 325 Pa absolute. This is the envelope's own definition, fixed so that
//!   its results stay comparable from one version to the next (11 atm saturated hydrogen is then
//!   93 % of its critical pressure); the NBS case files themselves read the report's drive
//!   pressures as absolute (their comments give why), and their gauge twins are in
//!   `examples/nbs/gauge/`. The base case's own dewar pressure is replaced in every run;
//! - `saturated`: the liquid enters at T_sat of the dewar pressure (as in the NBS saturated
//!   cases; the reservoir clamps its liquid to T_sat, so T_sat itself is the saturated state);
//! - `subcooled`: the liquid enters at T_sat of the local atmosphere (saturated there, then
//!   pressurised), as in the NBS subcooled case.
//!
//! Saturation temperatures come from the fluid's table (`CRYOFIT_DATA_DIR` is honoured).
//!
//! Runs go in parallel on `--jobs` threads (all cores by default). Each run's wall time is the
//! elapsed time of the thread that ran it, from the start of the run to its end: with several
//! threads busy it includes their contention for memory bandwidth and caches and whatever else
//! the machine is running; `--jobs 1` gives clean per-run timings. A run still going after
//! `--max-wall-s` of computing is stopped and reported as failed (`time.max_wall_s`).
//!
//! A run that fails is a result, not an error: the report names its cause (time, cell, variable,
//! value, reason) and the command still exits 0. A solver panic is caught and reported as that
//! run's failure. Bad flags and unreadable files are errors naming them.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::panic::{self, AssertUnwindSafe, PanicHookInfo};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use clap::{Args, ValueEnum};
use cryofit_solver::case::{Case, Profile};
use cryofit_solver::driver::{self, SimError, Summary};
use cryofit_solver::fluids::{self, FluidTable};
use cryofit_solver::params::ParameterSet;
use rayon::prelude::*;
use serde::Serialize;

use crate::fluid_source;
use crate::param_values::{apply_case_fields, read_params_file};

/// The NBS subcooled case: the line, boundaries, numerics and stations every run starts from.
const BASE_CASE: &str = include_str!("../../../examples/nbs/subcooled-4.2atm.toml");
/// Where [`BASE_CASE`] comes from, for messages.
const BASE_CASE_NAME: &str = "examples/nbs/subcooled-4.2atm.toml";
/// One standard atmosphere, Pa.
const ATM_PA: f64 = 101_325.0;
/// Initial temperature of the line and of the gas in it, K.
const INITIAL_TEMPERATURE_K: f64 = 290.0;
/// The station whose chilldown time is reported.
const CHILLDOWN_STATION: &str = "TS4";
/// Target: trace adjustments of a run at most this, J.
const TARGET_TRACE_ADJUSTMENT_J: f64 = 3350.0;
/// Target: relative energy balance error of a run at most this.
const TARGET_ENERGY_BALANCE_ERROR: f64 = 1e-3;
/// Target: median speed of the completed runs, physical time over wall time.
const TARGET_MEDIAN_SPEED: f64 = 1000.0;
/// Target: the slowest completed run, physical time over wall time.
const TARGET_MIN_SPEED: f64 = 200.0;

/// Arguments of `cryofit bench envelope`.
#[derive(Debug, Args)]
pub struct EnvelopeArgs {
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// A TOML file of `name = number` parameter values applied to every run (as `cryofit simulate
    /// --params` takes; its shared case fields are set in the base case, per-experiment ones skipped).
    #[arg(long, value_name = "FILE.toml")]
    params: Option<PathBuf>,
    /// Fluids (table names), comma-separated.
    #[arg(
        long,
        value_name = "FLUID,...",
        value_delimiter = ',',
        default_values = ["nitrogen", "parahydrogen", "oxygen", "methane"]
    )]
    fluids: Vec<String>,
    /// Inlet liquid kinds, comma-separated: saturated (T_sat of the dewar) and/or subcooled
    /// (T_sat of the local atmosphere).
    #[arg(long, value_name = "KIND,...", value_delimiter = ',', default_values = ["saturated", "subcooled"])]
    kinds: Vec<Kind>,
    /// Drive pressures in atm, gauge over the local atmosphere of 83087 Pa, comma-separated.
    #[arg(
        long = "pressures-atm",
        value_name = "ATM,...",
        value_delimiter = ',',
        allow_negative_numbers = true,
        default_values_t = [1.5, 3.0, 6.0, 11.0]
    )]
    pressures_atm: Vec<f64>,
    /// Physical time of each run, s.
    #[arg(long = "end-s", value_name = "S", default_value_t = 300.0, allow_negative_numbers = true)]
    end_s: f64,
    /// Cells of the line.
    #[arg(long, value_name = "N", default_value_t = 30)]
    cells: usize,
    /// Runs at once [default: one per core]; `--jobs 1` for per-run timings without contention.
    #[arg(long, value_name = "N")]
    jobs: Option<usize>,
    /// Stop a run after this many seconds of computing and report it as failed.
    #[arg(long = "max-wall-s", value_name = "S", default_value_t = 300.0, allow_negative_numbers = true)]
    max_wall_s: f64,
}

/// What enters the line: liquid saturated at the dewar pressure, or saturated at the local
/// atmosphere and then pressurised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
enum Kind {
    /// T_sat of the dewar pressure.
    Saturated,
    /// T_sat of the local atmosphere.
    Subcooled,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Saturated => "saturated",
            Kind::Subcooled => "subcooled",
        }
    }
}

/// One run to make.
#[derive(Debug)]
struct Plan {
    fluid: &'static str,
    table: usize,
    kind: Kind,
    drive_pressure_atm: f64,
    dewar_pressure_pa: f64,
    inlet_temperature_k: f64,
    case: Case,
}

/// Why a run did not complete.
#[derive(Debug, Clone, Serialize)]
struct Failure {
    /// Short classification, for counting (as `bench robustness` counts).
    cause: String,
    /// Simulated time at which it stopped, s, where known.
    time_s: Option<f64>,
    /// Cell or junction where the step failed, where known.
    cell: Option<usize>,
    /// Variable that failed, where known.
    variable: Option<String>,
    /// Its value, where known.
    value: Option<f64>,
    /// Why the variable was refused, where known.
    reason: Option<String>,
    /// The whole error message.
    message: String,
}

/// One run's result.
#[derive(Debug, Clone, Serialize)]
struct RunReport {
    fluid: &'static str,
    kind: Kind,
    drive_pressure_atm: f64,
    dewar_pressure_pa: f64,
    inlet_temperature_k: f64,
    completed: bool,
    /// Why it did not complete (`None` when it did).
    failure: Option<Failure>,
    /// Physical time reached, s (where it stopped, for a failed run, where known).
    simulated_time_s: Option<f64>,
    steps: Option<u64>,
    rejected_steps: Option<u64>,
    /// Elapsed time of the thread that ran it, s.
    wall_time_s: f64,
    /// Physical time over wall time.
    speed: Option<f64>,
    /// Station-4 chilldown time (wall below the inlet liquid temperature + 15 K), s; `None` when
    /// not reached.
    chilldown_ts4_s: Option<f64>,
    trace_adjustment_j: Option<f64>,
    energy_balance_error: Option<f64>,
    energy_balance_residual_j: Option<f64>,
    wall_heat_j: Option<f64>,
    /// Simulated time during which the line's exit was choked, s.
    exit_choked_s: Option<f64>,
    /// Cell states recovered as one near-critical mixture.
    mixture_recoveries: Option<u64>,
    /// Cell states recovered at the pressure that fills them (a volume error no shorter step
    /// shrank).
    pressure_refills: Option<u64>,
    /// Which controlled variable came closest to its limit in accepted steps, and how often.
    step_limited_by: BTreeMap<String, u64>,
    /// Completed with trace adjustments and energy balance error within the targets.
    meets_targets: bool,
}

impl RunReport {
    fn label(&self) -> String {
        format!("{} {} {} atm", self.fluid, self.kind.name(), self.drive_pressure_atm)
    }
}

/// A run and its value, for the worst and slowest of the totals.
#[derive(Debug, Clone, Serialize)]
struct Extreme {
    run: String,
    value: f64,
}

/// Which targets the measurement meets.
#[derive(Debug, Clone, Serialize)]
struct TargetsMet {
    all_completed: bool,
    all_within_balances: bool,
    median_speed: bool,
    min_speed: bool,
}

/// Totals over the runs.
#[derive(Debug, Clone, Serialize)]
struct Totals {
    runs: usize,
    completed: usize,
    /// Median speed of the completed runs.
    median_speed: Option<f64>,
    /// The slowest completed run.
    min_speed: Option<Extreme>,
    /// Completed runs with trace adjustments and energy balance error within the targets.
    meeting_balance_targets: usize,
    /// The completed run with the largest trace adjustments, J.
    worst_trace_adjustment_j: Option<Extreme>,
    /// The completed run with the largest energy balance error.
    worst_energy_balance_error: Option<Extreme>,
    /// Failure causes and how often each occurred.
    failure_causes: BTreeMap<String, usize>,
    targets_met: TargetsMet,
}

/// The targets the totals are held against.
#[derive(Debug, Clone, Serialize)]
struct Targets {
    trace_adjustment_j: f64,
    energy_balance_error: f64,
    median_speed: f64,
    min_speed: f64,
}

/// The whole report (`--json` prints it).
#[derive(Debug, Serialize)]
struct Report {
    base_case: &'static str,
    params_file: Option<String>,
    parameters: BTreeMap<String, f64>,
    end_s: f64,
    cells: usize,
    jobs: usize,
    max_wall_s: f64,
    local_atmosphere_pa: f64,
    initial_temperature_k: f64,
    /// Wall time of the whole measurement, s.
    wall_time_s: f64,
    targets: Targets,
    runs: Vec<RunReport>,
    totals: Totals,
}

/// Runs `cryofit bench envelope`.
pub fn run(args: &EnvelopeArgs) -> Result<()> {
    check_args(args)?;
    let mut base = Case::from_toml(BASE_CASE, BASE_CASE_NAME)?;
    let mut params = driver::case_parameters(&base).map_err(|e| anyhow!("{BASE_CASE_NAME}: {e}"))?;
    if let Some(file) = &args.params {
        // registry values, and the shared case fields (the apparatus) on the base case; the
        // envelope's cases are no calibration's experiments, so per-experiment values are skipped
        let values = read_params_file(file)?;
        params.overlay(&values.registry()?);
        let applied = apply_case_fields(&base, BASE_CASE_NAME, "", &[&values])?;
        if !applied.skipped.is_empty() {
            eprintln!("note: skipped {} (per-experiment values)", applied.skipped.join(", "));
        }
        base = applied.case;
    }
    let atmosphere_pa = match &base.outlet.pressure_pa {
        Some(p) => p.at(0.0),
        None => bail!("{BASE_CASE_NAME}: the outlet has no pressure_pa"),
    };
    let fluids = fluid_names(&args.fluids)?;
    let tables = fluids.iter().map(|f| fluid_source::load(f)).collect::<Result<Vec<_>>>()?;
    let plans = plans(args, &base, atmosphere_pa, &fluids, &tables)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .context("cannot start the threads of the runs")?;
    let jobs = pool.current_num_threads();
    let clock = Instant::now();
    let runs: Vec<RunReport> = {
        let _hook = PanicCapture::install();
        pool.install(|| plans.par_iter().map(|plan| run_one(plan, &tables[plan.table], &params)).collect())
    };
    let wall_time_s = clock.elapsed().as_secs_f64();
    let report = Report {
        base_case: BASE_CASE_NAME,
        params_file: args.params.as_ref().map(|p| p.display().to_string()),
        parameters: params.explicit().clone(),
        end_s: args.end_s,
        cells: args.cells,
        jobs,
        max_wall_s: args.max_wall_s,
        local_atmosphere_pa: atmosphere_pa,
        initial_temperature_k: INITIAL_TEMPERATURE_K,
        wall_time_s,
        targets: Targets {
            trace_adjustment_j: TARGET_TRACE_ADJUSTMENT_J,
            energy_balance_error: TARGET_ENERGY_BALANCE_ERROR,
            median_speed: TARGET_MEDIAN_SPEED,
            min_speed: TARGET_MIN_SPEED,
        },
        totals: totals(&runs),
        runs,
    };
    super::emit(&report, args.json, print_table)
}

fn check_args(args: &EnvelopeArgs) -> Result<()> {
    if !(args.end_s.is_finite() && args.end_s > 0.0) {
        bail!("--end-s {}: must be a positive number of seconds", args.end_s);
    }
    if !(2..=100_000).contains(&args.cells) {
        bail!("--cells {}: must be between 2 and 100000", args.cells);
    }
    if args.jobs == Some(0) {
        bail!("--jobs 0: give at least one");
    }
    if !(args.max_wall_s.is_finite() && args.max_wall_s > 0.0) {
        bail!("--max-wall-s {}: must be a positive number of seconds", args.max_wall_s);
    }
    for (k, kind) in args.kinds.iter().enumerate() {
        if args.kinds[..k].contains(kind) {
            bail!("--kinds: {} is given twice", kind.name());
        }
    }
    for (k, &p) in args.pressures_atm.iter().enumerate() {
        if !(p.is_finite() && p > 0.0) {
            bail!("--pressures-atm {p}: must be a positive gauge pressure in atm");
        }
        if args.pressures_atm[..k].contains(&p) {
            bail!("--pressures-atm: {p} is given twice");
        }
    }
    Ok(())
}

/// The canonical table names of `--fluids`, each once.
fn fluid_names(names: &[String]) -> Result<Vec<&'static str>> {
    let mut out: Vec<&'static str> = Vec::new();
    for name in names {
        let Some(canon) = fluids::canonical_name(name) else {
            bail!("--fluids: unknown fluid '{name}'; use one of {}", fluids::EMBEDDED_FLUIDS.join(", "));
        };
        if out.contains(&canon) {
            bail!("--fluids: {canon} is given twice");
        }
        out.push(canon);
    }
    Ok(out)
}

/// Every run: fluids × kinds × pressures, in that order.
fn plans(
    args: &EnvelopeArgs,
    base: &Case,
    atmosphere_pa: f64,
    fluids: &[&'static str],
    tables: &[impl AsRef<FluidTable>],
) -> Result<Vec<Plan>> {
    let mut plans = Vec::new();
    for (f, (&fluid, table)) in fluids.iter().zip(tables).enumerate() {
        let table = table.as_ref();
        let t_sat = |p: f64, what: &str| -> Result<f64> {
            table.saturation(p).map(|s| s.t_sat).map_err(|e| anyhow!("{what}: {fluid} has no saturation state: {e}"))
        };
        let t_atmosphere = t_sat(atmosphere_pa, &format!("the local atmosphere of {atmosphere_pa} Pa"))?;
        for &kind in &args.kinds {
            for &drive in &args.pressures_atm {
                let dewar_pa = atmosphere_pa + drive * ATM_PA;
                let inlet_k = match kind {
                    Kind::Saturated => t_sat(dewar_pa, &format!("--pressures-atm {drive}: dewar at {dewar_pa} Pa"))?,
                    Kind::Subcooled => {
                        // the reservoir needs its pressure on the saturation line too
                        t_sat(dewar_pa, &format!("--pressures-atm {drive}: dewar at {dewar_pa} Pa"))?;
                        t_atmosphere
                    }
                };
                let mut case = base.clone();
                case.title = format!("operating envelope: {fluid}, {}, {drive} atm", kind.name());
                case.fluid.name = fluid.to_string();
                case.pipe.cells = args.cells;
                case.inlet.pressure_pa = Some(Profile::Constant(dewar_pa));
                case.inlet.temperature_k = Some(Profile::Constant(inlet_k));
                case.initial.gas_temperature_k = Profile::Constant(INITIAL_TEMPERATURE_K);
                case.initial.wall_temperature_k = Profile::Constant(INITIAL_TEMPERATURE_K);
                case.time.end_s = args.end_s;
                case.time.max_wall_s = Some(args.max_wall_s);
                plans.push(Plan {
                    fluid,
                    table: f,
                    kind,
                    drive_pressure_atm: drive,
                    dewar_pressure_pa: dewar_pa,
                    inlet_temperature_k: inlet_k,
                    case,
                });
            }
        }
    }
    Ok(plans)
}

/// Runs one plan on the calling thread and measures it.
fn run_one(plan: &Plan, table: &FluidTable, params: &ParameterSet) -> RunReport {
    let clock = Instant::now();
    let outcome = panic::catch_unwind(AssertUnwindSafe(|| driver::run(&plan.case, table, params, &mut |_| {})));
    let wall_time_s = clock.elapsed().as_secs_f64();
    let mut report = RunReport {
        fluid: plan.fluid,
        kind: plan.kind,
        drive_pressure_atm: plan.drive_pressure_atm,
        dewar_pressure_pa: plan.dewar_pressure_pa,
        inlet_temperature_k: plan.inlet_temperature_k,
        completed: false,
        failure: None,
        simulated_time_s: None,
        steps: None,
        rejected_steps: None,
        wall_time_s,
        speed: None,
        chilldown_ts4_s: None,
        trace_adjustment_j: None,
        energy_balance_error: None,
        energy_balance_residual_j: None,
        wall_heat_j: None,
        exit_choked_s: None,
        mixture_recoveries: None,
        pressure_refills: None,
        step_limited_by: BTreeMap::new(),
        meets_targets: false,
    };
    match outcome {
        Ok(Ok(output)) => fill_completed(&mut report, output.summary),
        Ok(Err(e)) => {
            let failure = failure_of(&e);
            report.simulated_time_s = failure.time_s;
            report.failure = Some(failure);
        }
        Err(payload) => {
            let message = PanicCapture::take()
                .unwrap_or_else(|| payload_text(payload.as_ref()).unwrap_or("(no message)").to_string());
            report.failure = Some(Failure {
                cause: "panic".into(),
                time_s: None,
                cell: None,
                variable: None,
                value: None,
                reason: None,
                message: format!("the solver panicked: {message}"),
            });
        }
    }
    if let Some(t) = report.simulated_time_s
        && wall_time_s > 0.0
    {
        report.speed = Some(t / wall_time_s);
    }
    report
}

fn fill_completed(report: &mut RunReport, s: Summary) {
    report.completed = true;
    report.simulated_time_s = Some(s.simulated_time_s);
    report.steps = Some(s.steps);
    report.rejected_steps = Some(s.rejected_steps);
    report.chilldown_ts4_s = s.chilldown_time_s.get(CHILLDOWN_STATION).copied().flatten();
    report.trace_adjustment_j = Some(s.trace_adjustment_j);
    report.energy_balance_error = Some(s.energy_balance_error);
    report.energy_balance_residual_j = Some(s.energy_balance_residual_j);
    report.wall_heat_j = Some(s.wall_heat_j);
    report.exit_choked_s = Some(s.exit_choked_s);
    report.mixture_recoveries = Some(s.mixture_recoveries);
    report.pressure_refills = Some(s.pressure_refills);
    report.meets_targets =
        s.trace_adjustment_j <= TARGET_TRACE_ADJUSTMENT_J && s.energy_balance_error <= TARGET_ENERGY_BALANCE_ERROR;
    report.step_limited_by = s.step_limited_by;
}

/// The failure of a run that ended with an error: where and why, as far as the error says.
fn failure_of(e: &SimError) -> Failure {
    let mut f = Failure {
        cause: super::cause(e),
        time_s: None,
        cell: None,
        variable: None,
        value: None,
        reason: None,
        message: e.to_string(),
    };
    match e {
        SimError::StepTooSmall { time_s, cell, variable, value, reason, .. } => {
            f.time_s = Some(*time_s);
            f.cell = Some(*cell);
            f.variable = Some((*variable).to_string());
            f.value = Some(*value);
            f.reason = Some((*reason).to_string());
        }
        SimError::MaxSteps { time_s, .. } | SimError::MaxWall { time_s, .. } => f.time_s = Some(*time_s),
        _ => {}
    }
    f
}

fn payload_text(payload: &(dyn std::any::Any + Send)) -> Option<&str> {
    payload.downcast_ref::<&str>().copied().or_else(|| payload.downcast_ref::<String>().map(String::as_str))
}

thread_local! {
    /// The message and place of the last panic on this thread while a [`PanicCapture`] is installed.
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// While alive, panics are recorded per thread (message and place) for the report instead of
/// being printed; dropping it puts back the hook that was there before.
struct PanicCapture {
    previous: Arc<dyn Fn(&PanicHookInfo<'_>) + Send + Sync + 'static>,
}

impl std::fmt::Debug for PanicCapture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PanicCapture")
    }
}

impl PanicCapture {
    fn install() -> Self {
        let previous: Arc<dyn Fn(&PanicHookInfo<'_>) + Send + Sync + 'static> = Arc::from(panic::take_hook());
        panic::set_hook(Box::new(|info| {
            let message = info.payload_as_str().unwrap_or("(no message)");
            let text = match info.location() {
                Some(at) => format!("{message} at {}:{}", at.file(), at.line()),
                None => message.to_string(),
            };
            LAST_PANIC.with(|p| *p.borrow_mut() = Some(text));
        }));
        PanicCapture { previous }
    }

    /// The last panic recorded on this thread, if any.
    fn take() -> Option<String> {
        LAST_PANIC.with(|p| p.borrow_mut().take())
    }
}

impl Drop for PanicCapture {
    fn drop(&mut self) {
        let previous = Arc::clone(&self.previous);
        panic::set_hook(Box::new(move |info| previous(info)));
    }
}

fn totals(runs: &[RunReport]) -> Totals {
    let completed: Vec<&RunReport> = runs.iter().filter(|r| r.completed).collect();
    let mut speeds: Vec<f64> = completed.iter().filter_map(|r| r.speed).collect();
    speeds.sort_by(f64::total_cmp);
    let median_speed = match speeds.len() {
        0 => None,
        n if n % 2 == 1 => Some(speeds[n / 2]),
        n => Some(0.5 * (speeds[n / 2 - 1] + speeds[n / 2])),
    };
    // the first run with the largest (or smallest) value; NaN counts as the worst
    let extreme = |value: &dyn Fn(&RunReport) -> Option<f64>, largest: bool| -> Option<Extreme> {
        let key = |v: f64| {
            if v.is_nan() {
                f64::INFINITY
            } else if largest {
                v
            } else {
                -v
            }
        };
        completed
            .iter()
            .filter_map(|r| value(r).map(|v| (r, v)))
            .reduce(|a, b| if key(b.1) > key(a.1) { b } else { a })
            .map(|(r, v)| Extreme { run: r.label(), value: v })
    };
    let min_speed = extreme(&|r| r.speed, false);
    let worst_trace_adjustment_j = extreme(&|r| r.trace_adjustment_j, true);
    let worst_energy_balance_error = extreme(&|r| r.energy_balance_error, true);
    let meeting = completed.iter().filter(|r| r.meets_targets).count();
    let mut failure_causes = BTreeMap::new();
    for f in runs.iter().filter_map(|r| r.failure.as_ref()) {
        *failure_causes.entry(f.cause.clone()).or_default() += 1;
    }
    Totals {
        runs: runs.len(),
        completed: completed.len(),
        median_speed,
        meeting_balance_targets: meeting,
        targets_met: TargetsMet {
            all_completed: completed.len() == runs.len(),
            all_within_balances: meeting == runs.len(),
            median_speed: median_speed.is_some_and(|s| s >= TARGET_MEDIAN_SPEED),
            min_speed: min_speed.as_ref().is_some_and(|s| s.value >= TARGET_MIN_SPEED),
        },
        min_speed,
        worst_trace_adjustment_j,
        worst_energy_balance_error,
        failure_causes,
    }
}

/// The most frequent entry of `step_limited_by` and its share of the counted steps.
fn main_limit(limits: &BTreeMap<String, u64>) -> String {
    let total: u64 = limits.values().sum();
    match limits.iter().max_by_key(|(_, n)| **n) {
        Some((name, n)) if total > 0 => format!("{name} {:.0} %", 100.0 * *n as f64 / total as f64),
        _ => "-".into(),
    }
}

fn print_table(r: &Report) {
    let params = match &r.params_file {
        Some(file) => format!("parameters from {file}"),
        None => "default parameters".into(),
    };
    println!(
        "Operating envelope: the NBS line ({}), {} cells, {} s per run, {params}, {} threads, {:.1} s",
        r.base_case, r.cells, r.end_s, r.jobs, r.wall_time_s
    );
    let header = [
        "fluid",
        "kind",
        "p atm",
        "dewar Pa",
        "inlet K",
        "result",
        "steps",
        "rejected",
        "wall s",
        "speed",
        "TS4 chill s",
        "trace kJ",
        "energy err",
        "step limited by",
    ];
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or_else(|| "-".to_string(), f);
    let rows: Vec<Vec<String>> = r
        .runs
        .iter()
        .map(|run| {
            let result = match &run.failure {
                None => "completed".to_string(),
                Some(f) => match f.time_s {
                    Some(t) => format!("FAILED at {t:.2} s"),
                    None => "FAILED".to_string(),
                },
            };
            vec![
                run.fluid.to_string(),
                run.kind.name().to_string(),
                format!("{}", run.drive_pressure_atm),
                format!("{:.0}", run.dewar_pressure_pa),
                format!("{:.3}", run.inlet_temperature_k),
                result,
                run.steps.map_or_else(|| "-".into(), |s| s.to_string()),
                run.rejected_steps.map_or_else(|| "-".into(), |s| s.to_string()),
                format!("{:.2}", run.wall_time_s),
                opt(run.speed, &|s| format!("{s:.0}×")),
                if run.completed { opt(run.chilldown_ts4_s, &|t| format!("{t:.1}")) } else { "-".into() },
                opt(run.trace_adjustment_j, &|j| format!("{:.2}", j / 1000.0)),
                opt(run.energy_balance_error, &|e| format!("{e:.2e}")),
                if run.completed { main_limit(&run.step_limited_by) } else { "-".into() },
            ]
        })
        .collect();
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for row in &rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: &[String]| {
        let parts: Vec<String> = cells
            .iter()
            .zip(&widths)
            .enumerate()
            .map(|(k, (c, &w))| {
                let pad = w - c.chars().count();
                // text columns to the left, numbers to the right
                if k <= 1 || k == 5 || k == 13 {
                    format!("{c}{}", " ".repeat(pad))
                } else {
                    format!("{}{c}", " ".repeat(pad))
                }
            })
            .collect();
        println!("  {}", parts.join("  ").trim_end());
    };
    line(&header.iter().map(|h| h.to_string()).collect::<Vec<_>>());
    for row in &rows {
        line(row);
    }
    let failed: Vec<&RunReport> = r.runs.iter().filter(|run| !run.completed).collect();
    if !failed.is_empty() {
        println!("Failures:");
        for run in failed {
            if let Some(f) = &run.failure {
                println!("  {}: {}", run.label(), f.message);
            }
        }
    }
    let t = &r.totals;
    let yes_no = |b: bool| if b { "met" } else { "not met" };
    println!(
        "Completed {} of {} runs; {} within trace adjustments ≤ {} kJ and energy balance error ≤ {:e} ({})",
        t.completed,
        t.runs,
        t.meeting_balance_targets,
        TARGET_TRACE_ADJUSTMENT_J / 1000.0,
        TARGET_ENERGY_BALANCE_ERROR,
        yes_no(t.targets_met.all_completed && t.targets_met.all_within_balances)
    );
    match (&t.median_speed, &t.min_speed) {
        (Some(median), Some(min)) => println!(
            "Speed of the completed runs: median {median:.0}× (target ≥ {TARGET_MEDIAN_SPEED}×: {}), slowest {:.0}× \
             ({}; target ≥ {TARGET_MIN_SPEED}× for every run: {})",
            yes_no(t.targets_met.median_speed),
            min.value,
            min.run,
            yes_no(t.targets_met.min_speed)
        ),
        _ => println!("Speed: no run completed"),
    }
    if let Some(w) = &t.worst_trace_adjustment_j {
        println!("Largest trace adjustments: {:.2} kJ ({})", w.value / 1000.0, w.run);
    }
    if let Some(w) = &t.worst_energy_balance_error {
        println!("Largest energy balance error: {:.2e} ({})", w.value, w.run);
    }
    for (cause, n) in &t.failure_causes {
        println!("  {n:>3} failed: {cause}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn completed(fluid: &'static str, speed: f64, trace_j: f64, energy: f64) -> RunReport {
        RunReport {
            fluid,
            kind: Kind::Saturated,
            drive_pressure_atm: 3.0,
            dewar_pressure_pa: 387_062.0,
            inlet_temperature_k: 90.0,
            completed: true,
            failure: None,
            simulated_time_s: Some(300.0),
            steps: Some(1000),
            rejected_steps: Some(10),
            wall_time_s: 300.0 / speed,
            speed: Some(speed),
            chilldown_ts4_s: None,
            trace_adjustment_j: Some(trace_j),
            energy_balance_error: Some(energy),
            energy_balance_residual_j: Some(0.0),
            wall_heat_j: Some(1e6),
            exit_choked_s: Some(0.0),
            mixture_recoveries: Some(0),
            pressure_refills: Some(0),
            step_limited_by: BTreeMap::new(),
            meets_targets: trace_j <= TARGET_TRACE_ADJUSTMENT_J && energy <= TARGET_ENERGY_BALANCE_ERROR,
        }
    }

    #[test]
    fn totals_take_the_median_and_the_worst_of_the_completed_runs() {
        let mut failed = completed("methane", 5.0, 0.0, 0.0);
        failed.completed = false;
        failed.meets_targets = false;
        failed.failure = Some(failure_of(&SimError::MaxWall { wall_s: 1.0, time_s: 2.0 }));
        let runs = vec![
            completed("nitrogen", 400.0, 10.0, 5e-4),
            completed("oxygen", 100.0, 5000.0, 2e-3),
            completed("parahydrogen", 300.0, 20.0, 9e-3),
            completed("nitrogen", 2000.0, 0.0, 1e-4),
            failed,
        ];
        let t = totals(&runs);
        assert_eq!((t.runs, t.completed, t.meeting_balance_targets), (5, 4, 2));
        assert_eq!(t.median_speed, Some(350.0));
        let slowest = t.min_speed.unwrap();
        assert_eq!((slowest.run.as_str(), slowest.value), ("oxygen saturated 3 atm", 100.0));
        assert_eq!(t.worst_trace_adjustment_j.unwrap().value, 5000.0);
        assert_eq!(t.worst_energy_balance_error.unwrap().run, "parahydrogen saturated 3 atm");
        assert_eq!(t.failure_causes.get("time.max_wall_s reached"), Some(&1));
        assert!(!t.targets_met.all_completed && !t.targets_met.min_speed && !t.targets_met.median_speed);
    }

    #[test]
    fn a_panic_is_captured_with_its_place() {
        let capture = PanicCapture::install();
        let outcome = panic::catch_unwind(|| -> u32 { panic!("closure out of range: {}", 7) });
        let message = PanicCapture::take();
        drop(capture);
        assert!(outcome.is_err());
        let message = message.expect("the panic was recorded");
        assert!(message.contains("closure out of range: 7") && message.contains("envelope.rs:"), "{message}");
    }
}
