//! `cryofit predict CASE.toml --from DIR [--samples N] [--seed S] [--out DIR]`: runs a case that
//! was not in the calibration over the calibrated parameters' posterior (paper eq.
//! "bayes_forecast") and writes median and 5–95 % bands of every probe and the distribution of
//! each station's chilldown time.
//!
//! The calibration's case fields apply as in `cryofit simulate --params` (see
//! [`crate::param_values`]): its shared ones to any case, its per-experiment ones only when the case
//! is taken as that experiment (`--experiment`, by default the case file's stem); the others are
//! skipped and named on stderr.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_calib::apparatus;
use cryofit_calib::config::CalibrationSpec;
use cryofit_calib::draws::{gaussian_draws, space_draws};
use cryofit_solver::case::Case;
use cryofit_solver::driver::{self, Output};
use cryofit_solver::params::{self, ParameterSet};
use rayon::prelude::*;
use serde_json::json;

use crate::csv_text::CsvText;
use crate::fluid_source;
use crate::output::{fmt_num, read_result_json, write_outputs};

/// Arguments of `cryofit predict`.
#[derive(Debug, Args)]
pub struct PredictArgs {
    /// The case to predict (TOML).
    pub(crate) case: PathBuf,
    /// Output folder of a `cryofit calibrate` run (its result.json, and posterior.csv if an MCMC stage ran).
    #[arg(long, value_name = "DIR")]
    pub(crate) from: PathBuf,
    /// Parameter sets to run, drawn from the posterior.
    #[arg(long, value_name = "N", default_value_t = 100)]
    pub(crate) samples: usize,
    /// Seed of the draws.
    #[arg(long, value_name = "S", default_value_t = 0)]
    pub(crate) seed: u64,
    /// Output directory [default: out/predict-<case file stem>].
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
    /// The calibration experiment this case is: its per-experiment values (`case.<path>@NAME`)
    /// apply, other experiments' are skipped [default: the case file's stem].
    #[arg(long, value_name = "NAME")]
    pub(crate) experiment: Option<String>,
}

/// The parameter sets to run: posterior draws completed with the best and fixed values.
fn draws(dir: &Path, n: usize, seed: u64) -> Result<(Vec<BTreeMap<String, f64>>, &'static str)> {
    let (result_path, result) = read_result_json(dir, "--from")?;
    let number_map = |v: &serde_json::Value, field: &str| -> Result<BTreeMap<String, f64>> {
        let obj =
            v.as_object().ok_or_else(|| anyhow!("{}: `{field}` is missing or not an object", result_path.display()))?;
        obj.iter()
            .map(|(k, x)| {
                x.as_f64()
                    .map(|f| (k.clone(), f))
                    .ok_or_else(|| anyhow!("{}: {field}.{k} is not a number", result_path.display()))
            })
            .collect()
    };
    let mut base = number_map(&result["fixed_parameters"], "fixed_parameters").unwrap_or_default();
    base.extend(number_map(&result["best_parameters"], "best_parameters")?);

    let posterior = dir.join("posterior.csv");
    let (names, rows, method): (Vec<String>, Vec<Vec<f64>>, &'static str) = if posterior.exists() {
        let text =
            std::fs::read_to_string(&posterior).with_context(|| format!("cannot read {}", posterior.display()))?;
        let (names, rows) = read_draws(&text, &posterior.display().to_string())?;
        if rows.is_empty() {
            bail!("{}: no draws", posterior.display());
        }
        // every n-th draw, spread over the file
        let step = (rows.len() as f64 / n.max(1) as f64).max(1.0);
        let picked =
            (0..n.min(rows.len())).map(|k| rows[((k as f64 * step) as usize).min(rows.len() - 1)].clone()).collect();
        (names, picked, "mcmc posterior draws")
    } else {
        let u = &result["uncertainty"];
        if u.is_null() {
            bail!(
                "--from {}: the calibration has no variance or mcmc stage, so there is no posterior to predict with; add one, or use `cryofit simulate --params {}`",
                dir.display(),
                dir.join("best.toml").display()
            );
        }
        let names: Vec<String> = serde_json::from_value(u["names"].clone())
            .with_context(|| format!("{}: uncertainty.names", result_path.display()))?;
        if u["positive_definite"] == false {
            bail!(
                "--from {}: the variance stage's Hessian is not positive definite (result.json: stages, warnings), so its \
                 Gaussian is not a posterior to draw from; add an mcmc stage to the calibration, or use `cryofit \
                 simulate --params {}`",
                dir.display(),
                dir.join("best.toml").display()
            );
        }
        // the calibration's own free parameters (bounds and scales), in the stage's order
        let space = serde_json::from_value::<CalibrationSpec>(result["calibration"].clone())
            .ok()
            .and_then(|s| s.space().ok())
            .and_then(|space| space.select(&names));
        let unit: Option<(Vec<f64>, Vec<Vec<f64>>)> = serde_json::from_value(u["centre_unit"].clone())
            .ok()
            .zip(serde_json::from_value(u["covariance_unit"].clone()).ok());
        let rows = match (space, unit) {
            (Some(space), Some((centre, cov))) => space_draws(&space, &centre, &cov, n, seed),
            // a result.json written before the unit-coordinate fields: the physical Gaussian
            (space, _) => {
                let cov: Vec<Vec<f64>> = serde_json::from_value(u["covariance"].clone())
                    .with_context(|| format!("{}: uncertainty.covariance", result_path.display()))?;
                let mean: Vec<f64> = names
                    .iter()
                    .map(|n| {
                        u["parameters"][n]["value"]
                            .as_f64()
                            .ok_or_else(|| anyhow!("{}: uncertainty value of {n}", result_path.display()))
                    })
                    .collect::<Result<_>>()?;
                let bounds: Vec<(f64, f64)> = names
                    .iter()
                    .map(|n| {
                        let own = space.as_ref().and_then(|s| s.params().iter().find(|p| &p.name == n));
                        own.map(|p| (p.lower, p.upper))
                            .or_else(|| params::spec(n).map(|s| (s.lower, s.upper)))
                            .ok_or_else(|| anyhow!("{}: no bounds for parameter {n}", result_path.display()))
                    })
                    .collect::<Result<_>>()?;
                gaussian_draws(&mean, &cov, &bounds, n, seed)
            }
        }
        .map_err(|e| anyhow!("{}: {e}", result_path.display()))?;
        (names, rows, "Gaussian approximation of the variance stage")
    };
    let sets = rows
        .into_iter()
        .map(|row| {
            let mut m = base.clone();
            for (name, v) in names.iter().zip(row) {
                m.insert(name.clone(), v);
            }
            m
        })
        .collect();
    Ok((sets, method))
}

/// The draws of a `posterior.csv` (`file` names it in errors): the parameter names of its header
/// and one row of numbers per draw.
fn read_draws(text: &str, file: &str) -> Result<(Vec<String>, Vec<Vec<f64>>)> {
    let mut reader = csv::ReaderBuilder::new().flexible(true).from_reader(text.as_bytes());
    let names: Vec<String> =
        reader.headers().map_err(|e| anyhow!("{file}: line 1: {e}"))?.iter().map(|s| s.trim().to_string()).collect();
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| anyhow!("{file}: {e}"))?;
        let line = record.position().map_or(0, csv::Position::line);
        let row: Result<Vec<f64>, _> = record.iter().map(|s| s.trim().parse::<f64>()).collect();
        let row = row.map_err(|_| anyhow!("{file}: line {line}: not a row of numbers"))?;
        if row.len() != names.len() {
            bail!("{file}: line {line}: {} values for {} columns", row.len(), names.len());
        }
        rows.push(row);
    }
    Ok((names, rows))
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let k = pos.floor() as usize;
    let w = pos - k as f64;
    if k + 1 < sorted.len() { sorted[k] * (1.0 - w) + sorted[k + 1] * w } else { sorted[k] }
}

/// Runs the prediction.
pub fn run(args: &PredictArgs) -> Result<()> {
    if args.samples == 0 {
        bail!("--samples 0: give at least 1");
    }
    let case_path = args.case.display().to_string();
    let text = std::fs::read_to_string(&args.case).with_context(|| format!("cannot read {case_path}"))?;
    let case = Case::from_toml(&text, &case_path)?;
    let base = driver::case_parameters(&case).map_err(|e| anyhow!("{case_path}: {e}"))?;
    let (sets, method) = draws(&args.from, args.samples, args.seed)?;
    let experiment = crate::param_values::experiment_of(&args.case, args.experiment.as_deref());
    if let Some(first) = sets.first() {
        crate::param_values::report_skipped(&apparatus::sort(first, Some(&experiment)).skipped, &experiment);
    }
    let table = fluid_source::load(&case.fluid.name)?;
    let runs: Vec<Result<Output, String>> = sets
        .par_iter()
        .map(|values| {
            let sorted = apparatus::sort(values, Some(&experiment));
            let mut set: ParameterSet = base.clone();
            for (k, &v) in &sorted.registry {
                set.set(k, v).map_err(|e| e.to_string())?;
            }
            let case = sorted.apply(&case).map_err(|e| format!("case fields: {e}"))?;
            driver::run(&case, &table, &set, &mut |_| {}).map_err(|e| e.to_string())
        })
        .collect();
    let ok: Vec<&Output> = runs.iter().filter_map(|r| r.as_ref().ok()).collect();
    let failures: Vec<&String> = runs.iter().filter_map(|r| r.as_ref().err()).collect();
    if ok.is_empty() {
        bail!("{case_path}: all {} runs failed; first: {}", runs.len(), failures.first().map_or("", |s| s.as_str()));
    }
    // bands: every run records the same probe rows in the same order
    let n_rows = ok[0].probes.len();
    if ok.iter().any(|o| o.probes.len() != n_rows) {
        bail!("internal error: runs recorded different numbers of probe values");
    }
    let mut bands = CsvText::new(["time_s", "station", "x_m", "quantity", "q05", "q50", "q95"])?;
    let mut values = Vec::with_capacity(ok.len());
    for k in 0..n_rows {
        let o = &ok[0].probes[k];
        values.clear();
        values.extend(ok.iter().map(|r| r.probes[k].value));
        values.sort_by(f64::total_cmp);
        bands.row([
            &fmt_num(o.time_s),
            o.station.as_str(),
            &fmt_num(o.x_m),
            o.quantity,
            &fmt_num(quantile(&values, 0.05)),
            &fmt_num(quantile(&values, 0.5)),
            &fmt_num(quantile(&values, 0.95)),
        ])?;
    }
    let bands = bands.finish()?;
    let mut chill = serde_json::Map::new();
    let stations: Vec<String> = case.stations.iter().map(|s| s.name.clone()).collect();
    for st in &stations {
        let mut t: Vec<f64> = ok.iter().filter_map(|o| o.summary.chilldown_time_s.get(st).copied().flatten()).collect();
        t.sort_by(f64::total_cmp);
        chill.insert(
            st.clone(),
            json!({
                "q05": (!t.is_empty()).then(|| quantile(&t, 0.05)),
                "median": (!t.is_empty()).then(|| quantile(&t, 0.5)),
                "q95": (!t.is_empty()).then(|| quantile(&t, 0.95)),
                "not_reached": ok.len() - t.len(),
                "values_s": t,
            }),
        );
    }
    let summary = json!({
        "case": case_path,
        "from": args.from.display().to_string(),
        "method": method,
        "samples": sets.len(),
        "completed": ok.len(),
        "failed": failures.len(),
        "failures": failures,
        "chilldown_time_s": chill,
    });
    let out_dir = args.out.clone().unwrap_or_else(|| {
        let stem = args.case.file_stem().map_or_else(|| "case".into(), |s| s.to_string_lossy().into_owned());
        Path::new("out").join(format!("predict-{stem}"))
    });
    let mut text = serde_json::to_string_pretty(&summary)?;
    text.push('\n');
    write_outputs(&out_dir, &[("bands.csv", bands), ("prediction.json", text)])?;
    println!("{case_path}: {} of {} runs ({method}) completed", ok.len(), sets.len());
    for st in &stations {
        let c = &summary["chilldown_time_s"][st];
        match (c["q05"].as_f64(), c["median"].as_f64(), c["q95"].as_f64()) {
            (Some(a), Some(m), Some(b)) => println!("  {st} chilldown: median {m:.1} s, 90 % band {a:.1} – {b:.1} s"),
            _ => println!("  {st} chilldown: not reached within the case"),
        }
    }
    println!("  wrote bands.csv, prediction.json to {}", out_dir.display());
    Ok(())
}
