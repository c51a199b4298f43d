//! `cryofit bench chaos --case CASE --param NAME [--ulps N] [--station NAME] [--params FILE]
//! [--set NAME=VALUE]... [--experiment NAME] [--json]`: how far a run's chilldown moves when one parameter moves by a few units in the last
//! place.
//!
//! The value of `NAME` in the case (its `[parameters]` entry, the `--params` file's or a `--set`
//! of it, or the registry default) is set to each of the 2N + 1 doubles from N below it to N above
//! it, and the case is run with each (all cores). `--params` and `--set` take registry parameters
//! and case fields as `cryofit simulate` does (`--params examples/nbs/calibrated.toml` measures the
//! spread at a calibrated point, `--set case.time.max_dt_s=0.002` at shorter steps). The report gives
//! every run's chilldown time at the station and its steps, the range, mean and standard deviation
//! of the chilldowns and the largest move from the unperturbed run, held against the target of 1 s
//! (the operating envelope's smoothness target: ten one-ulp perturbations of one closure value
//! move the subcooled station-4 chilldown by at most 1 s). A perturbation that leaves the registry
//! bounds, or a run that fails or never reaches the chilldown, is reported as such and counts as
//! not meeting it.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_solver::case::Case;
use cryofit_solver::driver;
use rayon::prelude::*;
use serde::Serialize;

use crate::fluid_source;
use crate::param_values::{case_parameters, experiment_of};

/// Largest move of the chilldown, s, that the target allows.
const TARGET_S: f64 = 1.0;

/// Most units in the last place either side.
const MAX_ULPS: u32 = 50;

/// Arguments of `cryofit bench chaos`.
#[derive(Debug, Args)]
pub struct ChaosArgs {
    /// The case file.
    #[arg(long, value_name = "CASE.toml")]
    case: PathBuf,
    /// The registry parameter to perturb.
    #[arg(long, value_name = "NAME")]
    param: String,
    /// Units in the last place either side of the value (2N + 1 runs).
    #[arg(long, value_name = "N", default_value_t = 5)]
    ulps: u32,
    /// The station whose chilldown is measured [default: the case's last station].
    #[arg(long, value_name = "NAME")]
    station: Option<String>,
    /// A parameter file (`cryofit simulate --params`: a calibration's `best.toml`, say): its
    /// registry parameters and `case.` fields for every run (a value of the perturbed parameter
    /// moves its centre).
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Set a registry parameter, or a case field by its `case.` name (`case.time.max_dt_s=0.002`),
    /// for every run (repeatable; after `--params`; a `--set` of the perturbed parameter moves its
    /// centre).
    #[arg(long = "set", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    set: Vec<String>,
    /// The calibration experiment this case is: its per-experiment values (`case.<path>@NAME`)
    /// apply, other experiments' are skipped [default: the case file's stem].
    #[arg(long, value_name = "NAME")]
    experiment: Option<String>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// One perturbed run.
#[derive(Debug, Serialize)]
struct Run {
    /// Units in the last place from the case's value (negative: below).
    ulps: i64,
    value: f64,
    /// Chilldown time at the station, s; `None` when not reached or the run failed.
    chilldown_s: Option<f64>,
    steps: Option<u64>,
    /// Why there is no chilldown time, where there is none.
    error: Option<String>,
}

/// The report (`--json` prints it).
#[derive(Debug, Serialize)]
struct Report {
    case: String,
    parameter: String,
    value: f64,
    station: String,
    runs: Vec<Run>,
    /// The `--params` file, if one was given.
    params: Option<String>,
    /// The registry parameters and case fields set by `--params` and `--set`, by name (a
    /// `--set` over the file's value).
    set: std::collections::BTreeMap<String, f64>,
    /// Smallest and largest chilldown of the runs that reached it, s.
    range_s: Option<(f64, f64)>,
    /// Mean of the chilldowns of the runs that reached it, s.
    mean_s: Option<f64>,
    /// Their sample standard deviation, s (`None` below two runs).
    standard_deviation_s: Option<f64>,
    /// Largest |chilldown − unperturbed chilldown| over the perturbed runs, s.
    largest_move_s: Option<f64>,
    target_s: f64,
    /// Every run reached the chilldown and none moved it by more than the target.
    target_met: bool,
    wall_time_s: f64,
}

/// The double `k` units in the last place from `x` (towards +∞ for positive `k`), for finite
/// nonzero `x`; `None` where that crosses zero or leaves the finite numbers.
fn ulps_from(x: f64, k: i64) -> Option<f64> {
    if !(x.is_finite() && x != 0.0) {
        return None;
    }
    let bits = x.abs().to_bits() as i64;
    let step = if x > 0.0 { k } else { -k };
    let moved = bits.checked_add(step).filter(|&b| b > 0)?;
    let y = f64::from_bits(moved as u64);
    y.is_finite().then_some(if x > 0.0 { y } else { -y })
}

/// Runs `cryofit bench chaos`.
pub fn run(args: &ChaosArgs) -> Result<()> {
    if args.ulps == 0 || args.ulps > MAX_ULPS {
        bail!("--ulps {}: give 1 to {MAX_ULPS}", args.ulps);
    }
    let path = args.case.display().to_string();
    let text = std::fs::read_to_string(&args.case).with_context(|| format!("cannot read {path}"))?;
    let case = Case::from_toml(&text, &path)?;
    let experiment = experiment_of(&args.case, args.experiment.as_deref());
    let (applied, base, sets) = case_parameters(&case, &path, &experiment, args.params.as_deref(), &args.set)?;
    let case = applied.case;
    let value = base.try_get(&args.param).map_err(|e| anyhow!("--param: {e}"))?;
    if !(value.is_finite() && value != 0.0) {
        bail!("--param {}: its value in {path} is {value}; units in the last place need a nonzero value", args.param);
    }
    let station = match &args.station {
        Some(s) if case.stations.iter().any(|st| &st.name == s) => s.clone(),
        Some(s) => {
            let names: Vec<&str> = case.stations.iter().map(|st| st.name.as_str()).collect();
            bail!("--station {s}: {path} has the stations {}", names.join(", "));
        }
        None => case
            .stations
            .last()
            .map(|st| st.name.clone())
            .ok_or_else(|| anyhow!("{path}: the case has no stations, so no chilldown time to measure"))?,
    };
    let table = fluid_source::load(&case.fluid.name)?;
    let clock = Instant::now();
    let n = i64::from(args.ulps);
    let runs: Vec<Run> = (-n..=n)
        .into_par_iter()
        .map(|k| {
            let Some(v) = ulps_from(value, k) else {
                return Run {
                    ulps: k,
                    value: f64::NAN,
                    chilldown_s: None,
                    steps: None,
                    error: Some("no such double".into()),
                };
            };
            let mut params = base.clone();
            if let Err(e) = params.set(&args.param, v) {
                return Run { ulps: k, value: v, chilldown_s: None, steps: None, error: Some(e.to_string()) };
            }
            match driver::run(&case, &table, &params, &mut |_| {}) {
                Ok(out) => {
                    let chill = out.summary.chilldown_time_s.get(&station).copied().flatten();
                    let error = chill.is_none().then(|| format!("{station} does not reach its chilldown"));
                    Run { ulps: k, value: v, chilldown_s: chill, steps: Some(out.summary.steps), error }
                }
                Err(e) => Run { ulps: k, value: v, chilldown_s: None, steps: None, error: Some(e.to_string()) },
            }
        })
        .collect();
    let times: Vec<f64> = runs.iter().filter_map(|r| r.chilldown_s).collect();
    let range_s = (!times.is_empty()).then(|| {
        (times.iter().copied().fold(f64::INFINITY, f64::min), times.iter().copied().fold(f64::NEG_INFINITY, f64::max))
    });
    let centre = runs.iter().find(|r| r.ulps == 0).and_then(|r| r.chilldown_s);
    let largest_move_s = centre.map(|c| times.iter().map(|t| (t - c).abs()).fold(0.0, f64::max));
    let all_reached = runs.iter().all(|r| r.chilldown_s.is_some());
    let (mean_s, standard_deviation_s) = mean_and_deviation(&times);
    let report = Report {
        case: path.clone(),
        parameter: args.param.clone(),
        value,
        station: station.clone(),
        target_met: all_reached && largest_move_s.is_some_and(|m| m <= TARGET_S),
        runs,
        params: args.params.as_ref().map(|p| p.display().to_string()),
        set: sets.iter().flat_map(|s| s.values.clone()).collect(),
        range_s,
        mean_s,
        standard_deviation_s,
        largest_move_s,
        target_s: TARGET_S,
        wall_time_s: clock.elapsed().as_secs_f64(),
    };
    super::emit(&report, args.json, print_report)
}

/// Mean and sample standard deviation of `xs` (`None` for an empty slice; no deviation below two).
fn mean_and_deviation(xs: &[f64]) -> (Option<f64>, Option<f64>) {
    if xs.is_empty() {
        return (None, None);
    }
    let n = xs.len() as f64;
    let mean = xs.iter().sum::<f64>() / n;
    let sd = (xs.len() > 1).then(|| (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt());
    (Some(mean), sd)
}

fn print_report(r: &Report) {
    let mut with: Vec<String> = r.params.iter().cloned().collect();
    with.extend(r.set.iter().map(|(k, v)| format!("{k}={v}")));
    let set = if with.is_empty() { String::new() } else { format!(" (with {})", with.join(", ")) };
    println!(
        "{}{set}: {} = {} moved by up to {} units in the last place; {} chilldown, {:.1} s",
        r.case,
        r.parameter,
        r.value,
        r.runs.len() / 2,
        r.station,
        r.wall_time_s
    );
    println!("  {:>5}  {:>24}  {:>12}  {:>8}", "ulps", "value", "chilldown s", "steps");
    for run in &r.runs {
        let chill = run.chilldown_s.map_or_else(|| "-".into(), |c| format!("{c:.3}"));
        let steps = run.steps.map_or_else(|| "-".into(), |s| s.to_string());
        print!("  {:>5}  {:>24}  {chill:>12}  {steps:>8}", run.ulps, run.value);
        match &run.error {
            Some(e) => println!("  {e}"),
            None => println!(),
        }
    }
    match (r.range_s, r.largest_move_s) {
        (Some((lo, hi)), Some(m)) => println!(
            "Chilldowns {lo:.3}–{hi:.3} s (mean {}, standard deviation {}); largest move from the unperturbed \
             run {m:.3} s (target ≤ {} s: {})",
            r.mean_s.map_or_else(|| "-".into(), |v| format!("{v:.3} s")),
            r.standard_deviation_s.map_or_else(|| "-".into(), |v| format!("{v:.3} s")),
            r.target_s,
            if r.target_met { "met" } else { "not met" }
        ),
        _ => println!("The unperturbed run did not reach its chilldown (target ≤ {} s: not met)", r.target_s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ulps_step_through_neighbouring_doubles() {
        assert_eq!(ulps_from(1.0, 1), Some(1.0 + f64::EPSILON));
        assert_eq!(ulps_from(1.0, -1), Some(1.0 - f64::EPSILON / 2.0));
        assert_eq!(ulps_from(1.0, 0), Some(1.0));
        assert_eq!(ulps_from(-2.0, 1), Some(-2.0 + f64::EPSILON));
        assert_eq!(ulps_from(-2.0, -1), Some(-2.0 - 2.0 * f64::EPSILON));
        assert_eq!(ulps_from(f64::MIN_POSITIVE, -(f64::MIN_POSITIVE.to_bits() as i64)), None);
        assert_eq!(ulps_from(0.0, 1), None);
        assert_eq!(ulps_from(f64::MAX, 1), None);
    }

    #[test]
    fn mean_and_sample_deviation() {
        assert_eq!(mean_and_deviation(&[]), (None, None));
        assert_eq!(mean_and_deviation(&[3.0]), (Some(3.0), None));
        let (m, sd) = mean_and_deviation(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(m, Some(2.5));
        assert!((sd.unwrap() - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
    }
}
