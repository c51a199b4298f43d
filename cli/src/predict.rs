//! `cryofit predict CASE.toml --from DIR [--samples N] [--seed S] [--out DIR]`: runs a case that
//! was not in the calibration over the calibrated parameters' posterior (paper eq.
//! "bayes_forecast") and writes median and 5–95 % bands of every probe and the distribution of
//! each station's chilldown time.
//!
//! The calibration's case fields apply as in `cryofit simulate --params` (see
//! [`crate::param_values`]): its shared ones to any case, its per-experiment ones only when the case
//! is taken as that experiment (`--experiment`, by default the case file's stem); the others are
//! skipped and named on stderr.
//!
//! `bands.csv` holds two bands per probe row: `q05`–`q95`, the model's spread over the posterior
//! draws (the parameters' uncertainty alone), and `p05`–`p95`, the posterior-predictive band of a
//! measurement, the paper's eq. "bayes_forecast" `P(d_n | d) = ∫ P(d_n | θ) P(θ | d) dθ`.
//!
//! Decision: `P(d_n | θ)` is the model at θ with its clock in error, plus a Gaussian error, both
//! measured on the calibration's own fit at its best point (`result.json`, `fit`):
//! - the clock: a measurement at `t` is the model at `r·t`, `ln r ~ N(0, s²)`, with `s` the RMS of
//!   ln r over the station's fitted series in every experiment of the calibration (over every
//!   series where the station has fewer than two: near the inlet the front's timing errs by
//!   more than at the far end — 0.95–1.62 at station 1 of the six NBS runs against 0.80–1.10 at
//!   station 4 — and one σ for all would widen the far stations' bands for the near one's), r the factor that best aligns the model with that series' data (`time_scale`, from
//!   [`cryofit_calib::cost::best_time_scale`]; the maximum-likelihood σ given the best point,
//!   about zero, not about the mean factor, so a calibration that is late on every run widens
//!   the band rather than shifting it off the model's curve: one bias estimated from a few runs
//!   is no correction to trust for a run under other conditions). The fitted model's error is
//!   mostly one of timing — its front arrives early or late, the curves before and after it
//!   agree — and an additive error of constant width cannot say so: it must be as wide as the
//!   front's misplacement everywhere, so a band that covers the front is ±50 K on a line that has
//!   long settled at 77 K and reaches below 0 K. Scaling the clock keeps every centre on the
//!   model's own curve (a temperature stays a temperature the model reached) and puts the width
//!   where the front is uncertain.
//! - the Gaussian: per station and quantity, the RMS of model − data left at that best alignment
//!   (`time_scaled_rms`), pooled over the experiments by points; a station the calibration did
//!   not fit takes the quantity's RMS pooled over all its stations. This is the error of the
//!   curve's shape; the weights' σ (the instruments' noise) would claim the model is as good as
//!   the thermocouples.
//!
//! A calibration whose fit has fewer than two aligned series (or a `result.json` written before
//! `time_scale`) has no clock error: the Gaussian is then the plain residual RMS, as wide as it
//! must be. A quantity the calibration did not fit has no `p05`/`p95` (empty cells). The band of a
//! row is the equal-weight mixture of N(model at each draw at each of 16 equal-probability clock
//! factors, σ²), its 5 and 95 % points found by bisection; the clock factors are clamped to the
//! run's time range (the model's first or last value).
//!
//! Decision: each Gaussian of the mixture is truncated to the quantity's physical range
//! ([`physical_range`]) and renormalised — the measurement given that it is possible. A
//! temperature is at least the fluid's triple point: no wall in the line is colder than the
//! coldest fluid in it, and liquid colder than that would be solid. A pressure is positive, a void
//! fraction between 0 and 1. Without it the σ pooled over the calibration's runs (8–24 K on the
//! NBS fits, which hold the front's misfits) puts the band's lower edge of a hydrogen line that
//! has settled at 20 K below 0 K. Readings below the triple point exist — the NBS hydrogen
//! figures' low-temperature crossings, which the report calls thermocouple error (48 of the 1 590
//! points of the subcooled 2.5 atm run, down to 10 K) — and the band does not claim them: it is
//! the band of a measurement that can be true.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_calib::apparatus;
use cryofit_calib::config::CalibrationSpec;
use cryofit_calib::data::Dataset;
use cryofit_calib::draws::{gaussian_draws, space_draws};
use cryofit_calib::model::probes_dataset;
use cryofit_solver::case::Case;
use cryofit_solver::driver::{self, Output};
use cryofit_solver::fluids::FluidConstants;
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

/// The parameter sets to run: posterior draws completed with the best and fixed values
/// (`result` is the calibration's `result.json`, read from `result_path` in `dir`).
fn draws(
    dir: &Path,
    result_path: &Path,
    result: &serde_json::Value,
    n: usize,
    seed: u64,
) -> Result<(Vec<BTreeMap<String, f64>>, &'static str)> {
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

/// The error of a measurement about the model (see the module's decision), from a calibration's
/// `result.json`: the σ of its Gaussian part per (station, quantity) and, for stations the
/// calibration did not fit, per quantity; and the σ of the log of the model's clock error, per
/// station and over all, when the calibration's fit has aligned series to measure it from.
#[derive(Debug, Default, PartialEq)]
struct ErrorModel {
    series: BTreeMap<(String, String), f64>,
    quantity: BTreeMap<String, f64>,
    /// σ of ln(best clock factor) over all the calibration's aligned series (at least two).
    timing: Option<f64>,
    /// The same per station, for stations with at least two aligned series.
    station_timing: BTreeMap<String, f64>,
}

/// Equal-probability points of the clock error's distribution in the band's mixture.
const TIMING_NODES: usize = 16;

impl ErrorModel {
    /// Pools the series of `fit.<experiment>.series[]` of `result` over the experiments: the
    /// clock error from each series' `time_scale`, the Gaussian from `time_scaled_rms` (with a
    /// clock error) or `rms` (without), by `points`.
    fn from_result(result: &serde_json::Value) -> Self {
        let fits: Vec<&serde_json::Value> = result["fit"].as_object().into_iter().flat_map(|m| m.values()).collect();
        let log_scales: Vec<(&str, f64)> = fits
            .iter()
            .flat_map(|fit| fit["series"].as_array().into_iter().flatten())
            .filter_map(|s| Some((s["station"].as_str()?, s["time_scale"].as_f64()?.ln())))
            .filter(|(_, r)| r.is_finite())
            .collect();
        let rms_of = |v: &[f64]| (v.len() >= 2).then(|| (v.iter().map(|r| r * r).sum::<f64>() / v.len() as f64).sqrt());
        let timing = rms_of(&log_scales.iter().map(|x| x.1).collect::<Vec<_>>());
        let mut by_station: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        for (station, r) in &log_scales {
            by_station.entry(station.to_string()).or_default().push(*r);
        }
        let station_timing = by_station.into_iter().filter_map(|(st, v)| Some((st, rms_of(&v)?))).collect();
        let mut series: BTreeMap<(String, String), (f64, f64)> = BTreeMap::new();
        let mut quantity: BTreeMap<String, (f64, f64)> = BTreeMap::new();
        for fit in &fits {
            for s in fit["series"].as_array().into_iter().flatten() {
                let (Some(station), Some(q), Some(rms), Some(n)) =
                    (s["station"].as_str(), s["quantity"].as_str(), s["rms"].as_f64(), s["points"].as_f64())
                else {
                    continue;
                };
                // a series the alignment could not measure keeps its clock: its plain RMS
                let rms = if timing.is_some() { s["time_scaled_rms"].as_f64().unwrap_or(rms) } else { rms };
                if !rms.is_finite() || n <= 0.0 {
                    continue;
                }
                for acc in [
                    series.entry((station.to_string(), q.to_string())).or_default(),
                    quantity.entry(q.to_string()).or_default(),
                ] {
                    acc.0 += rms * rms * n;
                    acc.1 += n;
                }
            }
        }
        let pooled = |(sq, n): (f64, f64)| (sq / n).sqrt();
        Self {
            series: series.into_iter().map(|(k, v)| (k, pooled(v))).collect(),
            quantity: quantity.into_iter().map(|(k, v)| (k, pooled(v))).collect(),
            timing,
            station_timing,
        }
    }

    fn get(&self, station: &str, quantity: &str) -> Option<f64> {
        self.series
            .get(&(station.to_string(), quantity.to_string()))
            .or_else(|| self.quantity.get(quantity))
            .copied()
            .filter(|s| *s > 0.0)
    }

    /// The σ of the clock error's log at `station`: its own, or the one over all series.
    fn timing_at(&self, station: &str) -> Option<f64> {
        self.station_timing.get(station).copied().or(self.timing)
    }

    /// The factors the model's clock is scaled by in the band at `station`: `TIMING_NODES`
    /// equal-probability points of exp(N(0, s²)), or just 1 without a clock error.
    fn clock_factors(&self, station: &str) -> Vec<f64> {
        match self.timing_at(station) {
            Some(s) if s > 0.0 => {
                (0..TIMING_NODES).map(|j| (s * normal_quantile((j as f64 + 0.5) / TIMING_NODES as f64)).exp()).collect()
            }
            _ => vec![1.0],
        }
    }
}

/// Standard normal CDF, from the complementary error function's Chebyshev-fitted form
/// (fractional error below 1.2e-7 everywhere).
fn normal_cdf(z: f64) -> f64 {
    let x = z.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.5 * x);
    let poly = -x * x - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98 + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let erfc = t * poly.exp();
    if z >= 0.0 { 1.0 - 0.5 * erfc } else { 0.5 * erfc }
}

/// The standard normal's `p` quantile: the mixture of one (to [`normal_cdf`]'s accuracy).
fn normal_quantile(p: f64) -> f64 {
    mixture_quantile(&[0.0], 1.0, (f64::NEG_INFINITY, f64::INFINITY), p)
}

/// The range a measured `quantity` can take in a line of `fluid`: temperatures from the fluid's
/// triple point up, pressures above 0, void fractions in 0–1; other quantities are unbounded.
fn physical_range(quantity: &str, fluid: &FluidConstants) -> (f64, f64) {
    match quantity {
        q if q.ends_with("_temperature_k") => (fluid.t_triple_k, f64::INFINITY),
        "pressure_pa" => (0.0, f64::INFINITY),
        "void_fraction" => (0.0, 1.0),
        _ => (f64::NEG_INFINITY, f64::INFINITY),
    }
}

/// The CDF at `x` of N(c, σ²) truncated to `range` and renormalised; a centre so far outside the
/// range that no mass is left in it is the point at the range's nearer end.
fn truncated_normal_cdf(x: f64, c: f64, sigma: f64, (a, b): (f64, f64)) -> f64 {
    if x < a {
        return 0.0;
    }
    if x >= b {
        return 1.0;
    }
    // normal_cdf(±∞) is exactly 1 or 0: an open end needs no case of its own
    let at = |y: f64| normal_cdf((y - c) / sigma);
    let (fa, fb) = (at(a), at(b));
    let mass = fb - fa;
    if mass < 1e-12 {
        return if x >= c.clamp(a, b) { 1.0 } else { 0.0 };
    }
    ((at(x) - fa) / mass).clamp(0.0, 1.0)
}

/// The `q` quantile of the equal-weight mixture of N(c, σ²) over `centres`, each truncated to
/// `range` (see [`truncated_normal_cdf`]), by bisection (80 halvings of a bracket 20 σ wider than
/// the centres' range, cut to `range`: far below a rounding of the value).
fn mixture_quantile(centres: &[f64], sigma: f64, range: (f64, f64), q: f64) -> f64 {
    if centres.is_empty() || sigma.is_nan() || sigma <= 0.0 {
        return f64::NAN;
    }
    let cdf =
        |x: f64| centres.iter().map(|&c| truncated_normal_cdf(x, c, sigma, range)).sum::<f64>() / centres.len() as f64;
    let mut lo = (centres.iter().copied().fold(f64::INFINITY, f64::min) - 10.0 * sigma).clamp(range.0, range.1);
    let mut hi = (centres.iter().copied().fold(f64::NEG_INFINITY, f64::max) + 10.0 * sigma).clamp(range.0, range.1);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < q {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
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

/// `bands.csv`: per probe row of the runs `ok` (every one records the same rows in the same
/// order), the model's 5/50/95 % over the draws and the measurement band of `errors` within the
/// quantity's physical range in a line of `fluid`.
fn bands_csv(ok: &[&Output], errors: &ErrorModel, fluid: &FluidConstants) -> Result<String> {
    let n_rows = ok[0].probes.len();
    let mut bands = CsvText::new(["time_s", "station", "x_m", "quantity", "q05", "q50", "q95", "p05", "p95"])?;
    // one set of clock factors per station (not per probe row)
    let mut factors: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for o in &ok[0].probes {
        factors.entry(o.station.as_str()).or_insert_with(|| errors.clock_factors(&o.station));
    }
    let series: Vec<Dataset> = ok.iter().map(|o| probes_dataset(&o.probes)).collect();
    let mut values = Vec::with_capacity(ok.len());
    let mut centres = Vec::with_capacity(ok.len() * TIMING_NODES);
    for k in 0..n_rows {
        let o = &ok[0].probes[k];
        values.clear();
        values.extend(ok.iter().map(|r| r.probes[k].value));
        values.sort_by(f64::total_cmp);
        let (p05, p95) = errors.get(&o.station, o.quantity).map_or((String::new(), String::new()), |sigma| {
            let key = (o.station.clone(), o.quantity.to_string());
            let factors = &factors[o.station.as_str()];
            centres.clear();
            for s in series.iter().filter_map(|d| d.series.get(&key)) {
                let (first, last) = (s.times[0], s.times[s.times.len() - 1]);
                centres.extend(factors.iter().filter_map(|f| s.at((o.time_s * f).clamp(first, last))));
            }
            let range = physical_range(o.quantity, fluid);
            (
                fmt_num(mixture_quantile(&centres, sigma, range, 0.05)),
                fmt_num(mixture_quantile(&centres, sigma, range, 0.95)),
            )
        });
        bands.row([
            &fmt_num(o.time_s),
            o.station.as_str(),
            &fmt_num(o.x_m),
            o.quantity,
            &fmt_num(quantile(&values, 0.05)),
            &fmt_num(quantile(&values, 0.5)),
            &fmt_num(quantile(&values, 0.95)),
            &p05,
            &p95,
        ])?;
    }
    bands.finish()
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
    let (result_path, result) = read_result_json(&args.from, "--from")?;
    let (sets, method) = draws(&args.from, &result_path, &result, args.samples, args.seed)?;
    let errors = ErrorModel::from_result(&result);
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
    let bands = bands_csv(&ok, &errors, table.constants())?;
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
        "residual_sigma": {
            "series": errors.series.iter()
                .map(|((st, q), v)| json!({"station": st, "quantity": q, "sigma": v}))
                .collect::<Vec<_>>(),
            "quantity": errors.quantity,
        },
        "timing_sigma_log": errors.timing,
        "timing_sigma_log_per_station": stations.iter()
            .filter_map(|st| Some((st.clone(), json!(errors.timing_at(st)?))))
            .collect::<serde_json::Map<_, _>>(),
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
    let sigmas: Vec<String> =
        stations.iter().filter_map(|st| Some(format!("{st} {:.1}", errors.get(st, "wall_temperature_k")?))).collect();
    if !sigmas.is_empty() {
        match errors.timing {
            Some(_) => println!(
                "  measurement band p05–p95: the model at the draws, its clock scaled by the calibration's clock error \
                 (σ of the log: {}), ± the misfit left at the best alignment (wall temperature, K: {})",
                stations
                    .iter()
                    .filter_map(|st| Some(format!("{st} {:.3}", errors.timing_at(st)?)))
                    .collect::<Vec<_>>()
                    .join(", "),
                sigmas.join(", ")
            ),
            None => println!(
                "  measurement band p05–p95: the model at the draws ± the calibration's residual σ (wall temperature, K: {})",
                sigmas.join(", ")
            ),
        }
    }
    println!("  wrote bands.csv, prediction.json to {}", out_dir.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_normal_cdf_matches_known_values() {
        for (z, p) in
            [(0.0, 0.5), (1.0, 0.841_344_746), (-1.644_853_627, 0.05), (2.326_347_874, 0.99), (-4.0, 3.167_124e-5)]
        {
            assert!((normal_cdf(z) - p).abs() < 2e-7 * p.max(1e-3), "Φ({z}) = {} against {p}", normal_cdf(z));
        }
    }

    #[test]
    fn a_mixture_of_one_is_the_normal_and_of_two_far_apart_splits() {
        let all = (f64::NEG_INFINITY, f64::INFINITY);
        let q = mixture_quantile(&[100.0], 10.0, all, 0.95);
        assert!((q - 116.448_536).abs() < 1e-4, "{q}");
        // two components 1000 σ apart: the 5 % point is the lower one's 10 % point
        let q = mixture_quantile(&[0.0, 1000.0], 1.0, all, 0.05);
        assert!((q + 1.281_551_6).abs() < 1e-5, "{q}");
    }

    #[test]
    fn a_truncated_mixture_stays_in_the_physical_range_and_renormalises() {
        // a 20 K hydrogen wall with σ = 20 K: untruncated its 5 % point is near −13 K
        let free = mixture_quantile(&[20.0], 20.0, (f64::NEG_INFINITY, f64::INFINITY), 0.05);
        assert!(free < -12.0, "{free}");
        let floor = 13.8;
        let q05 = mixture_quantile(&[20.0], 20.0, (floor, f64::INFINITY), 0.05);
        // the 5 % point of N(20, 20²) given X ≥ 13.8: Φ(z) = Φ(−0.31) + 0.05·(1 − Φ(−0.31))
        let fa = normal_cdf((floor - 20.0) / 20.0);
        let expect = 20.0 + 20.0 * normal_quantile(fa + 0.05 * (1.0 - fa));
        assert!(q05 >= floor && (q05 - expect).abs() < 1e-6, "{q05} against {expect}");
        // far above the floor the truncation changes nothing
        let q = mixture_quantile(&[300.0], 10.0, (floor, f64::INFINITY), 0.95);
        assert!((q - 316.448_536).abs() < 1e-4, "{q}");
        // a void fraction stays in 0–1 on both sides
        let (lo, hi) = physical_range("void_fraction", &nitrogen());
        assert!(mixture_quantile(&[0.98], 0.1, (lo, hi), 0.95) <= 1.0);
        assert!(mixture_quantile(&[0.02], 0.1, (lo, hi), 0.05) >= 0.0);
        // a centre with no mass left in the range is the range's end
        assert!((mixture_quantile(&[-50.0], 1.0, (0.0, f64::INFINITY), 0.5) - 0.0).abs() < 1e-9);
    }

    fn nitrogen() -> FluidConstants {
        cryofit_solver::fluids::embedded("nitrogen").unwrap().constants().clone()
    }

    #[test]
    fn temperatures_are_bounded_by_the_triple_point_and_velocities_not_at_all() {
        let n2 = nitrogen();
        assert_eq!(physical_range("wall_temperature_k", &n2).0, n2.t_triple_k);
        assert!((n2.t_triple_k - 63.15).abs() < 0.1, "{}", n2.t_triple_k);
        assert_eq!(physical_range("pressure_pa", &n2), (0.0, f64::INFINITY));
        assert_eq!(physical_range("gas_velocity_m_s", &n2), (f64::NEG_INFINITY, f64::INFINITY));
    }

    #[test]
    fn residual_sigma_pools_over_experiments_by_points() {
        let result = json!({"fit": {
            "a": {"series": [{"station": "TS1", "quantity": "wall_temperature_k", "rms": 3.0, "points": 1}]},
            "b": {"series": [
                {"station": "TS1", "quantity": "wall_temperature_k", "rms": 5.0, "points": 3},
                {"station": "TS2", "quantity": "wall_temperature_k", "rms": 1.0, "points": 4}
            ]}
        }});
        let r = ErrorModel::from_result(&result);
        let ts1 = ((9.0 + 3.0 * 25.0) / 4.0f64).sqrt();
        assert!((r.get("TS1", "wall_temperature_k").unwrap() - ts1).abs() < 1e-12);
        assert_eq!(r.get("TS2", "wall_temperature_k"), Some(1.0));
        // a station the calibration did not fit takes the quantity's pooled σ
        let all = ((9.0 + 75.0 + 4.0) / 8.0f64).sqrt();
        assert!((r.get("TS9", "wall_temperature_k").unwrap() - all).abs() < 1e-12);
        assert_eq!(r.get("TS1", "pressure_pa"), None);
    }

    #[test]
    fn the_clock_error_comes_from_the_series_alignments_and_the_shape_error_from_what_they_leave() {
        let result = json!({"fit": {
            "a": {"series": [{"station": "TS1", "quantity": "wall_temperature_k", "rms": 40.0, "points": 2,
                              "time_scale": 1.1, "time_scaled_rms": 6.0}]},
            "b": {"series": [{"station": "TS1", "quantity": "wall_temperature_k", "rms": 30.0, "points": 2,
                              "time_scale": 0.9, "time_scaled_rms": 8.0},
                             {"station": "TS2", "quantity": "wall_temperature_k", "rms": 3.0, "points": 2,
                              "time_scale": null, "time_scaled_rms": null}]}
        }});
        let r = ErrorModel::from_result(&result);
        let s = ((1.1f64.ln().powi(2) + 0.9f64.ln().powi(2)) / 2.0).sqrt();
        assert!((r.timing.unwrap() - s).abs() < 1e-12, "{:?}", r.timing);
        // TS1 has two aligned series, its own σ; TS2 none, the one over all
        assert_eq!(r.timing_at("TS1"), r.station_timing.get("TS1").copied());
        assert!((r.timing_at("TS1").unwrap() - s).abs() < 1e-12);
        assert_eq!(r.timing_at("TS2"), r.timing);
        assert!((r.get("TS1", "wall_temperature_k").unwrap() - 50f64.sqrt()).abs() < 1e-12);
        // a series without an alignment keeps its plain RMS
        assert_eq!(r.get("TS2", "wall_temperature_k"), Some(3.0));
        // the clock factors: 16 equal-probability points of a log-normal, symmetric in the log
        let f = r.clock_factors("TS1");
        assert_eq!(f.len(), TIMING_NODES);
        assert!((f[0] * f[TIMING_NODES - 1] - 1.0).abs() < 1e-9);
        assert!(f.windows(2).all(|w| w[0] < w[1]));
        let mean_sq = f.iter().map(|x| x.ln().powi(2)).sum::<f64>() / f.len() as f64;
        assert!((mean_sq.sqrt() / s - 1.0).abs() < 0.1, "{mean_sq}");
        // without alignments (an older result.json), no clock error and the plain RMS
        let old = json!({"fit": {"a": {"series": [{"station": "TS1", "quantity": "wall_temperature_k", "rms": 40.0,
            "points": 2}], "chilldown_time_s": {"TS1": {"data_s": 100.0, "model_s": 110.0},
            "TS2": {"data_s": 50.0, "model_s": 60.0}}}}});
        let r = ErrorModel::from_result(&old);
        assert_eq!((r.timing, r.clock_factors("TS1")), (None, vec![1.0]));
        assert_eq!(r.get("TS1", "wall_temperature_k"), Some(40.0));
    }

    #[test]
    fn the_normal_quantile_inverts_the_cdf() {
        for p in [0.01, 0.05, 0.3, 0.5, 0.9, 0.999] {
            assert!((normal_cdf(normal_quantile(p)) - p).abs() < 1e-9, "{p}");
        }
        assert!((normal_quantile(0.95) - 1.644_853_627).abs() < 1e-5);
    }
}
