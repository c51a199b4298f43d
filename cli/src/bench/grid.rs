//! `cryofit bench grid (--case CASE [--case CASE]... [--data DATA.csv]... | --calibration FILE)
//! [--cells N,N,...] [--params FILE] [--set NAME=VALUE]... [--json]`: how a run's station
//! chilldowns move as its grid is refined.
//!
//! Each case is run on every grid of `--cells` (its `pipe.cells` replaced; everything else as
//! `cryofit simulate` takes it, `--params` and `--set` included), all runs on all cores, the
//! finest first. The report gives per run the steps, the wall time, the energy balance error and
//! every station's chilldown time, and per case how far each station's chilldown moves between the
//! two finest grids and how far the coarsest grid lies from the finest, held against the
//! operating envelope's grid target (the last station's chilldown changes by at most 2 % from
//! 240 to 480 cells; here: between the two finest grids given). With `--data` (one file per case,
//! in the order of the cases) each run is also compared with its measurements: every station's
//! chilldown error and the wall-temperature RMS (the quadratic mean of the stations' RMS), so that a calibrated point's
//! fit can be read on the grid it was fitted on and on finer ones; `--calibration` takes the cases,
//! their data and their experiment names (for per-experiment values of `--params`) from a
//! calibration file, with its `[fixed]` values (its case fields too, all but `pipe.cells`, which
//! `--cells` sets).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_calib::apparatus;
use cryofit_calib::config::CalibrationSpec;
use cryofit_calib::cost::Weights;
use cryofit_calib::data::Dataset;
use cryofit_calib::model::probes_dataset;
use cryofit_solver::case::Case;
use cryofit_solver::driver;
use cryofit_solver::fluids::FluidTable;
use cryofit_solver::params::ParameterSet;
use rayon::prelude::*;
use serde::Serialize;

use crate::fluid_source;
use crate::output::chilldown_pairs;
use crate::param_values::{apply_case_fields, case_parameters, experiment_of, parse_set};
use crate::simulate::read_case_data;

/// Largest change of the last station's chilldown between the two finest grids that the target
/// allows, as a fraction.
const TARGET_CHANGE: f64 = 0.02;

/// The case field that sets the grid.
const CELLS_FIELD: &str = "case.pipe.cells";

/// Arguments of `cryofit bench grid`.
#[derive(Debug, Args)]
pub struct GridArgs {
    /// A case file (repeatable).
    #[arg(long = "case", value_name = "CASE.toml", required_unless_present = "calibration")]
    cases: Vec<PathBuf>,
    /// Measured data of each case, in the order of the cases (give one per case or none).
    #[arg(long = "data", value_name = "DATA.csv")]
    data: Vec<PathBuf>,
    /// A calibration file whose experiments (case and data, as experiments of that name) are
    /// the runs, in place of `--case` and `--data`, with its `[fixed]` values where `--params`
    /// and `--set` do not set them: `--params` its `best.toml` checks a fit on finer grids.
    #[arg(long, value_name = "CALIBRATION.toml", conflicts_with_all = ["cases", "data"])]
    calibration: Option<PathBuf>,
    /// The grids: numbers of cells, comma-separated (at least two different ones).
    #[arg(long, value_name = "N,N,...", value_delimiter = ',', default_values_t = [30, 60, 120, 240, 480])]
    cells: Vec<usize>,
    /// A parameter file (`cryofit simulate --params`: a calibration's `best.toml`, say): its
    /// registry parameters and `case.` fields for every run.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
    /// Set a registry parameter, or a case field by its `case.` name (`case.time.end_s=300`), for
    /// every run (repeatable; after `--params`; not `case.pipe.cells`, which `--cells` sets).
    #[arg(long = "set", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    set: Vec<String>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// One case on one grid.
#[derive(Debug, Serialize)]
struct Run {
    cells: usize,
    /// Why the run did not complete, where it did not.
    error: Option<String>,
    steps: Option<u64>,
    rejected_steps: Option<u64>,
    wall_time_s: Option<f64>,
    energy_balance_error: Option<f64>,
    /// Each station's chilldown time, s (`None`: not reached within the run).
    chilldown_s: BTreeMap<String, Option<f64>>,
    /// With data: each station's chilldown error against the data's, % (`None` where either
    /// side has none).
    chilldown_error_pct: BTreeMap<String, Option<f64>>,
    /// With data: the wall-temperature RMS of the run, K: the quadratic mean of the stations' RMS.
    wall_rms_k: Option<f64>,
    /// With data: why the run could not be compared with it, where it could not.
    data_error: Option<String>,
    /// With data: each station's chilldown in the data (the same on every grid).
    #[serde(skip)]
    data_chilldown_s: BTreeMap<String, Option<f64>>,
}

/// One case on every grid.
#[derive(Debug, Serialize)]
struct CaseReport {
    case: String,
    data: Option<String>,
    /// Each station's chilldown in the data, s.
    data_chilldown_s: BTreeMap<String, Option<f64>>,
    /// The runs, coarsest grid first.
    runs: Vec<Run>,
    /// The two finest grids (coarser, finer).
    finest: (usize, usize),
    /// Each station's relative change of chilldown from the second finest grid to the finest, %.
    finest_change_pct: BTreeMap<String, Option<f64>>,
    /// Each station's chilldown on the coarsest grid relative to the finest, %.
    coarsest_from_finest_pct: BTreeMap<String, Option<f64>>,
    /// The last station.
    station: String,
    /// Every run completed and the last station's chilldown moved by at most the target between
    /// the two finest grids.
    target_met: bool,
}

/// The report (`--json` prints it).
#[derive(Debug, Serialize)]
struct Report {
    cells: Vec<usize>,
    /// The `--calibration` file, if the runs are its experiments.
    calibration: Option<String>,
    params: Option<String>,
    /// The registry parameters and case fields set by `--params` and `--set`, by name.
    set: BTreeMap<String, f64>,
    cases: Vec<CaseReport>,
    target_change_pct: f64,
    target_met: bool,
    wall_time_s: f64,
}

/// The grids of `--cells`, ascending, without repeats; at least two, each of at least one cell.
fn grids(cells: &[usize]) -> Result<Vec<usize>> {
    if cells.contains(&0) {
        bail!("--cells {}: a grid needs at least one cell", join(cells));
    }
    let mut g = cells.to_vec();
    g.sort_unstable();
    g.dedup();
    if g.len() < 2 {
        bail!("--cells {}: give at least two different numbers of cells, e.g. --cells 30,60,120", join(cells));
    }
    Ok(g)
}

fn join(cells: &[usize]) -> String {
    cells.iter().map(usize::to_string).collect::<Vec<_>>().join(",")
}

/// Relative change from `from` to `to`, %.
fn change_pct(from: Option<f64>, to: Option<f64>) -> Option<f64> {
    match (from, to) {
        (Some(a), Some(b)) if a != 0.0 => Some((b / a - 1.0) * 100.0),
        _ => None,
    }
}

/// The quadratic mean of the stations' RMS values (each station weighted alike, as VALIDATION.md
/// states a run's wall RMS).
fn station_rms(rms: impl Iterator<Item = f64>) -> Option<f64> {
    let (sum, n) = rms.fold((0.0, 0usize), |(s, n), r| (s + r * r, n + 1));
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// A case read, with its data and every grid's case and parameters.
struct Prepared {
    path: String,
    data: Option<(String, Dataset)>,
    table: std::borrow::Cow<'static, FluidTable>,
    /// The parameters of every run.
    params: ParameterSet,
    /// (cells, case) per grid.
    grids: Vec<(usize, Case)>,
    station: String,
}

/// One case to run on every grid: its file, its data file and the experiment it is taken as.
struct Item {
    case: PathBuf,
    data: Option<PathBuf>,
    experiment: String,
    /// The calibration's `[fixed]` values, for the parameters `--params` and `--set` leave.
    fixed: BTreeMap<String, f64>,
}

/// The runs of `--case` and `--data`, or of `--calibration`'s experiments (their paths taken
/// from the calibration file's folder).
fn items(args: &GridArgs) -> Result<Vec<Item>> {
    let Some(file) = &args.calibration else {
        if !args.data.is_empty() && args.data.len() != args.cases.len() {
            bail!(
                "--data given {} times for {} cases: give one data file per case, in the order of the cases, or none",
                args.data.len(),
                args.cases.len()
            );
        }
        return Ok(args
            .cases
            .iter()
            .enumerate()
            .map(|(k, c)| Item {
                case: c.clone(),
                data: args.data.get(k).cloned(),
                experiment: experiment_of(c, None),
                fixed: BTreeMap::new(),
            })
            .collect());
    };
    let label = file.display().to_string();
    let text = std::fs::read_to_string(file).with_context(|| format!("--calibration: cannot read {label}"))?;
    let spec = CalibrationSpec::from_toml(&text, &label)?;
    let base = file.parent().unwrap_or_else(|| std::path::Path::new("."));
    Ok(spec
        .experiments
        .iter()
        .enumerate()
        .map(|(k, e)| Item {
            case: base.join(&e.case),
            data: Some(base.join(&e.data)),
            experiment: e.label(k),
            fixed: spec.fixed.clone(),
        })
        .collect())
}

fn prepare(args: &GridArgs, item: &Item, cells: &[usize]) -> Result<Prepared> {
    let file = &item.case;
    let path = file.display().to_string();
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {path}"))?;
    let case = Case::from_toml(&text, &path)?;
    let experiment = item.experiment.clone();
    // the calibration's fixed case fields over the case file's, but not its grid, which `--cells`
    // sets; `--params` and `--set` over both
    let fixed_fields: BTreeMap<String, f64> = item
        .fixed
        .iter()
        .filter(|(name, _)| apparatus::case_name(name).is_some_and(|c| format!("case.{}", c.path) != CELLS_FIELD))
        .map(|(name, &value)| (name.clone(), value))
        .collect();
    let case = apparatus::set_fields(&fixed_fields, &case, &experiment)
        .map_err(|(name, e)| anyhow!("{path}: [fixed] {name} of the calibration: {e}"))?;
    let (applied, mut params, sources) = case_parameters(&case, &path, &experiment, args.params.as_deref(), &args.set)?;
    for (name, &value) in &item.fixed {
        if !apparatus::is_case_name(name) && !sources.iter().any(|s| s.values.contains_key(name)) {
            params.set(name, value).map_err(|e| anyhow!("[fixed] {name} of the calibration: {e}"))?;
        }
    }
    let station = applied
        .case
        .stations
        .last()
        .map(|s| s.name.clone())
        .ok_or_else(|| anyhow!("{path}: the case has no stations, so no chilldown times to compare"))?;
    // read before the runs: a bad file is reported before minutes of simulation
    let data = item.data.as_deref().map(|d| read_case_data(d, &applied.case, &path)).transpose()?;
    let table = fluid_source::load(&applied.case.fluid.name)?;
    let mut runs = Vec::new();
    for &n in cells {
        let grid = parse_set(&format!("{CELLS_FIELD}={n}"))?;
        let on_grid = apply_case_fields(&applied.case, &path, &experiment, &[&grid])?;
        runs.push((n, on_grid.case));
    }
    Ok(Prepared { path, data, table, params, grids: runs, station })
}

fn run_one(p: &Prepared, cells: usize, case: &Case) -> Run {
    let mut run = Run {
        cells,
        error: None,
        steps: None,
        rejected_steps: None,
        wall_time_s: None,
        energy_balance_error: None,
        chilldown_s: case.stations.iter().map(|s| (s.name.clone(), None)).collect(),
        chilldown_error_pct: BTreeMap::new(),
        wall_rms_k: None,
        data_error: None,
        data_chilldown_s: BTreeMap::new(),
    };
    let out = match driver::run(case, &p.table, &p.params, &mut |_| {}) {
        Ok(out) => out,
        Err(e) => {
            run.error = Some(e.to_string());
            return run;
        }
    };
    let s = &out.summary;
    run.steps = Some(s.steps);
    run.rejected_steps = Some(s.rejected_steps);
    run.wall_time_s = Some(s.wall_time_s);
    run.energy_balance_error = Some(s.energy_balance_error);
    run.chilldown_s = s.chilldown_time_s.clone();
    if let Some((name, data)) = &p.data {
        for (station, (d, m)) in chilldown_pairs(data, &out) {
            run.chilldown_error_pct.insert(station.clone(), change_pct(d, m));
            run.data_chilldown_s.insert(station, d);
        }
        match cryofit_calib::cost::fit(&probes_dataset(&out.probes), data, &Weights::default()) {
            Ok(fit) => {
                let wall = fit.series.iter().filter(|((_, q), _)| q == "wall_temperature_k");
                run.wall_rms_k = station_rms(wall.map(|(_, s)| s.rms));
            }
            Err(e) => run.data_error = Some(format!("{name}: {e}")),
        }
    }
    run
}

/// Runs `cryofit bench grid`.
pub fn run(args: &GridArgs) -> Result<()> {
    let cells = grids(&args.cells)?;
    if let Some(s) = args.set.iter().find(|s| s.split('=').next().is_some_and(|n| n.trim().starts_with(CELLS_FIELD))) {
        bail!("--set {s}: the grids are given by --cells");
    }
    let clock = std::time::Instant::now();
    let prepared: Vec<Prepared> = items(args)?.iter().map(|item| prepare(args, item, &cells)).collect::<Result<_>>()?;
    // every (case, grid), the finest first so that the longest runs start first
    let mut jobs: Vec<(usize, usize)> =
        (0..prepared.len()).flat_map(|c| (0..cells.len()).map(move |g| (c, g))).collect();
    jobs.sort_by_key(|&(c, g)| (std::cmp::Reverse(cells[g]), c));
    let mut done: Vec<((usize, usize), Run)> = jobs
        .par_iter()
        .map(|&(c, g)| {
            let (n, case) = &prepared[c].grids[g];
            ((c, g), run_one(&prepared[c], *n, case))
        })
        .collect();
    done.sort_by_key(|(key, _)| *key);
    let mut by_case: Vec<Vec<Run>> = prepared.iter().map(|_| Vec::new()).collect();
    for ((c, _), run) in done {
        by_case[c].push(run);
    }
    let finest = (cells[cells.len() - 2], cells[cells.len() - 1]);
    let cases: Vec<CaseReport> = prepared
        .iter()
        .zip(by_case)
        .map(|(p, runs)| {
            let last = &runs[runs.len() - 1];
            let second = &runs[runs.len() - 2];
            let at = |r: &Run, st: &str| r.chilldown_s.get(st).copied().flatten();
            let stations: Vec<String> = last.chilldown_s.keys().cloned().collect();
            let finest_change_pct =
                stations.iter().map(|st| (st.clone(), change_pct(at(second, st), at(last, st)))).collect();
            let coarsest_from_finest_pct =
                stations.iter().map(|st| (st.clone(), change_pct(at(last, st), at(&runs[0], st)))).collect();
            let data_chilldown_s = runs
                .iter()
                .find(|r| !r.data_chilldown_s.is_empty())
                .map_or_else(BTreeMap::new, |r| r.data_chilldown_s.clone());
            let moved = change_pct(at(second, &p.station), at(last, &p.station));
            let target_met =
                runs.iter().all(|r| r.error.is_none()) && moved.is_some_and(|m| m.abs() <= TARGET_CHANGE * 100.0);
            CaseReport {
                case: p.path.clone(),
                data: p.data.as_ref().map(|(n, _)| n.clone()),
                data_chilldown_s,
                finest,
                finest_change_pct,
                coarsest_from_finest_pct,
                station: p.station.clone(),
                target_met,
                runs,
            }
        })
        .collect();
    let report = Report {
        target_met: cases.iter().all(|c| c.target_met),
        cells,
        calibration: args.calibration.as_ref().map(|p| p.display().to_string()),
        params: args.params.as_ref().map(|p| p.display().to_string()),
        set: args.set.iter().filter_map(|s| parse_set(s).ok()).flat_map(|v| v.values).collect(),
        cases,
        target_change_pct: TARGET_CHANGE * 100.0,
        wall_time_s: clock.elapsed().as_secs_f64(),
    };
    super::emit(&report, args.json, print_report)
}

fn print_report(r: &Report) {
    let mut with: Vec<String> = r.params.iter().cloned().collect();
    with.extend(r.set.iter().map(|(k, v)| format!("{k}={v}")));
    let set = if with.is_empty() { String::new() } else { format!(" (with {})", with.join(", ")) };
    let of = r.calibration.as_ref().map_or_else(String::new, |c| format!(" of the experiments of {c}"));
    println!("Grid refinement{of} on {} cells{set}, {:.1} s", join(&r.cells), r.wall_time_s);
    for c in &r.cases {
        println!("{}{}", c.case, c.data.as_ref().map_or_else(String::new, |d| format!(" against {d}")));
        let stations: Vec<&String> = c.runs.last().map(|r| r.chilldown_s.keys().collect()).unwrap_or_default();
        let mut head = format!("  {:>6}  {:>8}  {:>8}  {:>8}  {:>9}", "cells", "steps", "rejected", "wall s", "energy");
        for st in &stations {
            head.push_str(&format!("  {:>16}", format!("{st} s")));
        }
        if c.data.is_some() {
            head.push_str(&format!("  {:>8}", "RMS K"));
        }
        println!("{head}");
        for run in &c.runs {
            if let Some(e) = &run.error {
                println!("  {:>6}  failed: {e}", run.cells);
                continue;
            }
            let mut line = format!(
                "  {:>6}  {:>8}  {:>8}  {:>8.2}  {:>9.1e}",
                run.cells,
                run.steps.unwrap_or(0),
                run.rejected_steps.unwrap_or(0),
                run.wall_time_s.unwrap_or(f64::NAN),
                run.energy_balance_error.unwrap_or(f64::NAN)
            );
            for st in &stations {
                let t = run.chilldown_s.get(*st).copied().flatten();
                let e = run.chilldown_error_pct.get(*st).copied().flatten();
                let cell = match (t, e) {
                    (Some(t), Some(e)) => format!("{t:.1} ({e:+.1} %)"),
                    (Some(t), None) => format!("{t:.1}"),
                    (None, _) => "-".into(),
                };
                line.push_str(&format!("  {cell:>16}"));
            }
            if c.data.is_some() {
                line.push_str(&format!("  {:>8}", run.wall_rms_k.map_or_else(|| "-".into(), |v| format!("{v:.1}"))));
            }
            println!("{line}");
            if let Some(e) = &run.data_error {
                println!("          not compared with the data: {e}");
            }
        }
        if c.data.is_some() {
            let mut line = format!("  {:>6}  {:>8}  {:>8}  {:>8}  {:>9}", "data", "", "", "", "");
            for st in &stations {
                let t = c.data_chilldown_s.get(*st).copied().flatten();
                line.push_str(&format!("  {:>16}", t.map_or_else(|| "-".into(), |t| format!("{t:.1}"))));
            }
            println!("{line}");
        }
        let pct = |m: &BTreeMap<String, Option<f64>>| {
            stations
                .iter()
                .map(|st| {
                    format!(
                        "{st} {}",
                        m.get(*st).copied().flatten().map_or_else(|| "-".into(), |v| format!("{v:+.2} %"))
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        println!("  {} → {} cells: {}", c.finest.0, c.finest.1, pct(&c.finest_change_pct));
        println!("  {} cells against {}: {}", r.cells[0], c.finest.1, pct(&c.coarsest_from_finest_pct));
        println!(
            "  {} changes by at most {} % between the two finest grids: {}",
            c.station,
            r.target_change_pct,
            if c.target_met { "met" } else { "not met" }
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_are_sorted_distinct_and_at_least_two() {
        assert_eq!(grids(&[120, 30, 60, 30]).unwrap(), [30, 60, 120]);
        let e = grids(&[30, 30]).unwrap_err().to_string();
        assert!(e.contains("--cells 30,30") && e.contains("at least two"), "{e}");
        let e = grids(&[0, 30]).unwrap_err().to_string();
        assert!(e.contains("at least one cell"), "{e}");
    }

    #[test]
    fn changes_and_the_runs_rms() {
        assert_eq!(change_pct(Some(200.0), Some(204.0)), Some(2.0000000000000018));
        assert_eq!(change_pct(None, Some(1.0)), None);
        assert_eq!(change_pct(Some(0.0), Some(1.0)), None);
        // stations of 10 and 20 K RMS (whatever their readings): sqrt((100 + 400) / 2)
        let rms = station_rms([10.0, 20.0].into_iter()).unwrap();
        assert!((rms - 250f64.sqrt()).abs() < 1e-12);
        assert_eq!(station_rms(std::iter::empty()), None);
    }
}
