//! `cryofit simulate CASE.toml [--out DIR] [--set NAME=VALUE]... [--params FILE.toml]
//! [--experiment NAME] [--noise QUANTITY=SIGMA]... [--seed N] [--data DATA.csv] [--step-log]`.
//!
//! `--set` and `--params` take registry parameters and case fields (`case.<path>`; see
//! [`crate::param_values`] for the forms and the precedence).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_solver::case::Case;
use cryofit_solver::driver::{self, Observation, Output, ProfilePoint, Progress, StepAttempt};
use cryofit_solver::params::ParameterSet;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

use crate::csv_text::CsvText;
use crate::fluid_source;
use crate::output::{chilldown_pairs, fmt_num, fmt_sig, probes_csv, write_outputs};
use crate::param_values::{case_parameters, split_assignment};
use cryofit_calib::cost::Weights;
use cryofit_calib::data::Dataset;
use cryofit_calib::model::probes_dataset;

use cryofit_solver::driver::PROBE_QUANTITIES;

/// Arguments of `cryofit simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The case file (TOML).
    pub(crate) case: PathBuf,
    /// Output directory [default: out/<case file stem>].
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
    /// Set a registry parameter, or a case field by its `case.` name (`case.inlet.loss_coefficient=8`)
    /// (repeatable; overrides --params, the case's [parameters] and its fields).
    #[arg(long = "set", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub(crate) set: Vec<String>,
    /// A TOML file of `name = number` values: registry parameters and case fields
    /// (`"case.inlet.loss_coefficient" = 8.0`), as `best.toml` of a calibration holds them.
    #[arg(long, value_name = "FILE.toml")]
    pub(crate) params: Option<PathBuf>,
    /// The calibration experiment this case is: its per-experiment values (`case.<path>@NAME`)
    /// apply, other experiments' are skipped [default: the case file's stem].
    #[arg(long, value_name = "NAME")]
    pub(crate) experiment: Option<String>,
    /// Add Gaussian noise N(0, SIGMA) to every probe value of QUANTITY (repeatable).
    #[arg(long = "noise", value_name = "QUANTITY=SIGMA", allow_hyphen_values = true)]
    pub(crate) noise: Vec<String>,
    /// Seed of the noise generator: the same seed gives the same noise.
    #[arg(long, value_name = "N", default_value_t = 0, allow_negative_numbers = true)]
    pub(crate) seed: u64,
    /// Measured data (time_s,station,x_m,quantity,value) to compare the run with: prints the RMS
    /// per station and quantity (and what is left of it once the model's clock best aligns with
    /// the data's: the curve's shape apart from its timing) and the chilldown times of model and
    /// data, and adds them to summary.json as `fit`.
    #[arg(long, value_name = "DATA.csv")]
    pub(crate) data: Option<PathBuf>,
    /// Also write steps.csv: every attempt at a step, accepted or rejected, with what limited or
    /// rejected it (written for a run that fails too, up to its failure).
    #[arg(long)]
    pub(crate) step_log: bool,
}

/// Runs a case and writes `probes.csv`, `profiles.csv` and `summary.json`.
pub fn run(args: &SimulateArgs) -> Result<()> {
    let case_path = args.case.display().to_string();
    let text = std::fs::read_to_string(&args.case).with_context(|| format!("cannot read {case_path}"))?;
    let case = Case::from_toml(&text, &case_path)?;
    let experiment = crate::param_values::experiment_of(&args.case, args.experiment.as_deref());
    let (applied, params, _) = case_parameters(&case, &case_path, &experiment, args.params.as_deref(), &args.set)?;
    let case = applied.case;
    let noise = parse_noise(&args.noise)?;
    let out_dir = match &args.out {
        Some(dir) => dir.clone(),
        None => {
            let stem = args.case.file_stem().map_or_else(|| "case".into(), |s| s.to_string_lossy().into_owned());
            Path::new("out").join(stem)
        }
    };
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("--out {}: exists and is not a directory", out_dir.display());
    }
    let table = fluid_source::load(&case.fluid.name)?;
    // read the data before the run: a bad file is reported before minutes of simulation
    let data = args.data.as_deref().map(|path| read_case_data(path, &case, &case_path)).transpose()?;

    let mut bar = RunProgress::new();
    let mut attempts: Vec<StepAttempt> = Vec::new();
    let result = if args.step_log {
        driver::run_logged(&case, &table, &params, &mut |p| bar.update(p), &mut |a| attempts.push(a))
    } else {
        driver::run(&case, &table, &params, &mut |p| bar.update(p))
    };
    bar.clear();
    if result.is_err() && args.step_log {
        // the steps that led to the failure are what the log is for
        write_outputs(&out_dir, &[("steps.csv", steps_csv(&attempts)?)])?;
        let steps = out_dir.join("steps.csv");
        return result.map(|_| ()).with_context(|| {
            format!(
                "{case_path}: simulation failed (its {} step attempts up to the failure are in {})",
                attempts.len(),
                steps.display()
            )
        });
    }
    let mut output = result.with_context(|| format!("{case_path}: simulation failed"))?;

    add_noise(&mut output.probes, &noise, args.seed);
    let comparison = match &data {
        Some((file, data)) => Some(compare(&case, &output, file, data)?),
        None => None,
    };
    let summary =
        summary_json(&output, &case_path, &params, &applied.case_fields, &noise, args.seed, comparison.as_ref())?;
    let mut files = vec![
        ("probes.csv", probes_csv(&output.probes)?),
        ("profiles.csv", profiles_csv(&output.profiles)?),
        ("summary.json", summary),
    ];
    if args.step_log {
        files.push(("steps.csv", steps_csv(&attempts)?));
    }
    write_outputs(&out_dir, &files)?;
    print_summary(&case, &case_path, &output, &params, &applied.case_fields, &noise, args.seed, &out_dir);
    if let Some(c) = &comparison {
        print_comparison(c);
    }
    Ok(())
}

/// Reads `--data` for `case` (at `case_path`): the file's name and its readings, which must be
/// stations the case probes, within its `time.end_s`. Errors name the file and what to do.
pub(crate) fn read_case_data(path: &Path, case: &Case, case_path: &str) -> Result<(String, Dataset)> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| format!("--data: cannot read {file}"))?;
    let data = Dataset::from_csv(&text, &file).map_err(|e| anyhow!("--data: {e}"))?;
    if data.is_empty() {
        bail!("--data {file}: no readings to compare with");
    }
    for (station, quantity) in data.series.keys() {
        if !case.stations.iter().any(|s| &s.name == station) {
            let names: Vec<&str> = case.stations.iter().map(|s| s.name.as_str()).collect();
            bail!(
                "--data {file}: {quantity} at station `{station}`, which {case_path} does not probe \
                 (its [[stations]]: {})",
                if names.is_empty() { "none".to_string() } else { names.join(", ") }
            );
        }
    }
    if data.end_time() > case.time.end_s {
        bail!(
            "--data {file}: readings run to {} s, past the case's time.end_s = {} s",
            data.end_time(),
            case.time.end_s
        );
    }
    Ok((file, data))
}

/// The run against measured data: RMS per station and quantity, chilldown of model and data.
#[derive(Debug)]
struct Comparison {
    file: String,
    fit: cryofit_calib::cost::Fit,
    /// Per series, the clock factor that best aligns the model with the data and the RMS left
    /// there ([`cryofit_calib::cost::best_time_scale`]): how much of the misfit is timing.
    aligned: BTreeMap<(String, String), (f64, f64)>,
    chilldown: BTreeMap<String, (Option<f64>, Option<f64>)>,
    /// Heat the wall released by each time, J, data and model read alike from the stations' wall
    /// temperatures (`cryofit_calib::heat`); empty without wall temperatures in the data.
    heat: Vec<(f64, Option<f64>, Option<f64>)>,
}

/// Windows of the heat-release comparison.
const HEAT_WINDOWS: usize = 6;

/// The times at which the wall's heat release is compared: six equal windows up to the data's
/// last station chilldown, or to the end of the readings where no station chills down after t = 0.
fn heat_times(data: &Dataset, chilldown: &BTreeMap<String, (Option<f64>, Option<f64>)>) -> Vec<f64> {
    let last_chill = chilldown.values().filter_map(|(d, _)| *d).fold(f64::NEG_INFINITY, f64::max);
    let end = if last_chill > 0.0 { last_chill } else { data.end_time() };
    if end.is_nan() || end <= 0.0 {
        return Vec::new();
    }
    (1..=HEAT_WINDOWS).map(|k| end * k as f64 / HEAT_WINDOWS as f64).collect()
}

/// Compares the probes with `data` (every quantity of the data, its default σ): the data must lie
/// within the simulated time at stations the case probes.
fn compare(case: &Case, output: &Output, file: &str, data: &Dataset) -> Result<Comparison> {
    let model = probes_dataset(&output.probes);
    let fit = cryofit_calib::cost::fit(&model, data, &Weights::default())
        .map_err(|e| anyhow!("--data {file}: {e} (the case's [[stations]] and time.end_s must cover the data)"))?;
    let aligned = data
        .series
        .iter()
        .filter_map(|(key, d)| Some((key.clone(), cryofit_calib::cost::best_time_scale(model.series.get(key)?, d)?)))
        .collect();
    let chilldown = chilldown_pairs(data, output);
    let wall = cryofit_calib::heat::Wall::of_case(case);
    let heat = cryofit_calib::heat::compare(data, &model, &wall, &heat_times(data, &chilldown));
    Ok(Comparison { file: file.to_string(), fit, aligned, chilldown, heat })
}

fn print_comparison(c: &Comparison) {
    println!("  against {}:", c.file);
    for (key, s) in &c.fit.series {
        let (station, quantity) = key;
        let aligned = c.aligned.get(key).map_or_else(String::new, |(r, rms)| {
            format!("; {} with its timing removed (the model's times ×{r:.3} the data's)", fmt_sig(*rms))
        });
        println!("    {station} {quantity}: RMS {} over {} readings{aligned}", fmt_sig(s.rms), s.points);
    }
    for (station, (d, m)) in &c.chilldown {
        match (d, m) {
            (Some(d), Some(m)) => {
                println!("    {station} chilldown: model {m:.1} s, data {d:.1} s ({:+.1} %)", (m / d - 1.0) * 100.0)
            }
            (Some(d), None) => println!("    {station} chilldown: data {d:.1} s, model not within the run"),
            (None, Some(m)) => println!("    {station} chilldown: model {m:.1} s, data not within the readings"),
            (None, None) => {}
        }
    }
    if c.heat.iter().any(|(_, d, m)| d.is_some() && m.is_some()) {
        println!("    heat released by the wall (from the stations' wall temperatures), data / model:");
        let mut prev = (0.0, 0.0, 0.0);
        for &(t, d, m) in &c.heat {
            let (Some(d), Some(m)) = (d, m) else { continue };
            let dt = t - prev.0;
            println!(
                "      by {t:6.1} s: {:7.3} / {:7.3} MJ; since {:.1} s {:6.1} / {:6.1} kW",
                d / 1e6,
                m / 1e6,
                prev.0,
                (d - prev.1) / dt / 1e3,
                (m - prev.2) / dt / 1e3
            );
            prev = (t, d, m);
        }
    }
}

/// `--noise QUANTITY=SIGMA` arguments as quantity → sigma.
fn parse_noise(args: &[String]) -> Result<BTreeMap<&'static str, f64>> {
    let mut noise = BTreeMap::new();
    for arg in args {
        let (name, sigma) = split_assignment(arg)
            .ok_or_else(|| anyhow!("--noise {arg}: expected QUANTITY=SIGMA, e.g. --noise wall_temperature_k=0.5"))?;
        let Some(quantity) = PROBE_QUANTITIES.iter().copied().find(|q| *q == name) else {
            bail!("--noise {arg}: unknown quantity '{name}'; use one of {}", PROBE_QUANTITIES.join(", "));
        };
        let sigma: f64 = sigma.parse().map_err(|_| anyhow!("--noise {arg}: '{sigma}' is not a number"))?;
        if !(sigma.is_finite() && sigma >= 0.0) {
            bail!("--noise {arg}: the standard deviation must be a finite number ≥ 0");
        }
        if noise.insert(quantity, sigma).is_some() {
            bail!("--noise {arg}: noise for {quantity} is given more than once");
        }
    }
    Ok(noise)
}

/// Adds N(0, sigma) to every probe value of each noisy quantity. Each quantity has its own
/// generator, seeded from `seed` and the quantity's name, so the noise on one quantity does not
/// depend on which other quantities are noisy.
fn add_noise(probes: &mut [Observation], noise: &BTreeMap<&'static str, f64>, seed: u64) {
    for (&quantity, &sigma) in noise {
        if sigma == 0.0 {
            continue;
        }
        let normal = Normal::new(0.0, sigma).expect("sigma is finite and positive");
        let mut rng = StdRng::seed_from_u64(seed ^ fnv1a(quantity));
        for obs in probes.iter_mut().filter(|o| o.quantity == quantity) {
            obs.value += normal.sample(&mut rng);
        }
    }
}

/// 64-bit FNV-1a: a stable hash (unlike `DefaultHasher`, fixed across Rust versions).
fn fnv1a(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// `v` rounded to 6 significant digits, for messages (hides 0.49999999999999994).
fn round_sig(v: f64) -> f64 {
    format!("{v:.5e}").parse().unwrap_or(v)
}

fn profiles_csv(profiles: &[ProfilePoint]) -> Result<String> {
    let mut t = CsvText::new(["time_s", "x_m", "quantity", "value"])?;
    for p in profiles {
        t.row([&fmt_num(p.time_s), &fmt_num(p.x_m), p.quantity, &fmt_num(p.value)])?;
    }
    t.finish()
}

/// `steps.csv`: one row per attempt at a step, in the order made. `variable`, `index` and
/// `value` are, for an accepted step, what came closest to its limit (the cell, or junction for a
/// velocity) and the step's change ratio; for a rejected one, what rejected it and its value,
/// with the reason.
fn steps_csv(attempts: &[StepAttempt]) -> Result<String> {
    let mut t = CsvText::new(["time_s", "dt_s", "outcome", "variable", "index", "value", "reason"])?;
    for a in attempts {
        let outcome = if a.accepted { "accepted" } else { "rejected" };
        t.row([
            &fmt_num(a.time_s),
            &fmt_num(a.dt_s),
            outcome,
            a.variable,
            &a.index.to_string(),
            &fmt_num(a.value),
            a.reason,
        ])?;
    }
    t.finish()
}

/// The run summary plus the case path, the parameters and case fields set explicitly and the
/// noise settings.
fn summary_json(
    output: &Output,
    case_path: &str,
    params: &ParameterSet,
    case_fields: &BTreeMap<String, f64>,
    noise: &BTreeMap<&'static str, f64>,
    seed: u64,
    comparison: Option<&Comparison>,
) -> Result<String> {
    let mut value = serde_json::to_value(&output.summary)?;
    let obj = value.as_object_mut().context("the run summary is not a JSON object")?;
    obj.insert("case".into(), case_path.into());
    obj.insert("parameters".into(), serde_json::to_value(params.explicit())?);
    if !case_fields.is_empty() {
        obj.insert("case_fields".into(), serde_json::to_value(case_fields)?);
    }
    obj.insert("noise".into(), serde_json::to_value(noise)?);
    obj.insert("seed".into(), seed.into());
    if let Some(c) = comparison {
        let series: Vec<serde_json::Value> = c
            .fit
            .series
            .iter()
            .map(|(key, s)| {
                let (station, quantity) = key;
                let mut v =
                    serde_json::json!({"station": station, "quantity": quantity, "rms": s.rms, "points": s.points});
                if let Some((r, rms)) = c.aligned.get(key) {
                    v["aligned_rms"] = (*rms).into();
                    v["time_scale"] = (*r).into();
                }
                v
            })
            .collect();
        let chilldown: BTreeMap<&String, serde_json::Value> =
            c.chilldown.iter().map(|(st, (d, m))| (st, serde_json::json!({"data_s": d, "model_s": m}))).collect();
        let heat: Vec<serde_json::Value> =
            c.heat.iter().map(|(t, d, m)| serde_json::json!({"time_s": t, "data_j": d, "model_j": m})).collect();
        obj.insert(
            "fit".into(),
            serde_json::json!({"data": c.file, "series": series, "chilldown": chilldown, "heat_released": heat}),
        );
    }
    let mut text = serde_json::to_string_pretty(&value)?;
    text.push('\n');
    Ok(text)
}

#[allow(clippy::too_many_arguments)]
fn print_summary(
    case: &Case,
    case_path: &str,
    output: &Output,
    params: &ParameterSet,
    case_fields: &BTreeMap<String, f64>,
    noise: &BTreeMap<&'static str, f64>,
    seed: u64,
    out_dir: &Path,
) {
    let s = &output.summary;
    let title = if case.title.is_empty() { case_path.to_string() } else { format!("{} ({case_path})", case.title) };
    println!("{title}");
    println!(
        "  {} steps ({} rejected), simulated {} s in {:.3} s of wall time",
        s.steps,
        s.rejected_steps,
        fmt_num(round_sig(s.simulated_time_s)),
        s.wall_time_s
    );
    println!("  time step {:.3e} … {:.3e} s", s.min_dt_s, s.max_dt_s);
    println!("  mass balance error {:.3e}, energy balance error {:.3e}", s.mass_balance_error, s.energy_balance_error);
    if s.mixture_recoveries > 0 {
        println!(
            "  {} cell state(s) near the critical point recovered as one mixture (mass and energy kept)",
            s.mixture_recoveries
        );
    }
    if s.pressure_refills > 0 {
        println!(
            "  {} cell state(s) whose volume error did not shrink with the step, or that a phase's merge left, recovered at the pressure that fills them (mass and energy kept)",
            s.pressure_refills
        );
    }
    if s.exit_choked_s > 0.0 {
        println!("  the exit was choked for {:.1} s (flowing at its mixture's speed of sound)", s.exit_choked_s);
    }
    if s.exported_heat_j >= 1.0 {
        println!(
            "  {:.3} kJ of heat from the throttles at the line's ends (valve and entrance losses, a choked exit) left with the outflow",
            s.exported_heat_j / 1e3
        );
    }
    let when = |t: Option<f64>| t.map_or_else(|| "not reached".to_string(), |t| format!("{t:.4} s"));
    for (station, chill) in &s.chilldown_time_s {
        let quench = s.quench_arrival_s.get(station).copied().flatten();
        println!("  station {station}: chilldown {}, quench front {}", when(*chill), when(quench));
    }
    if !params.explicit().is_empty() {
        let list: Vec<String> = params.explicit().iter().map(|(k, v)| format!("{k} = {}", fmt_num(*v))).collect();
        println!("  parameters: {}", list.join(", "));
    }
    if !case_fields.is_empty() {
        let list: Vec<String> = case_fields.iter().map(|(k, v)| format!("{k} = {}", fmt_num(*v))).collect();
        println!("  case fields: {}", list.join(", "));
    }
    if !noise.is_empty() {
        let list: Vec<String> = noise.iter().map(|(k, v)| format!("{k} σ = {}", fmt_num(*v))).collect();
        println!("  noise (seed {seed}): {}", list.join(", "));
    }
    println!("  wrote probes.csv, profiles.csv, summary.json to {}", out_dir.display());
}

/// The progress of a run on stderr: a bar of the simulated time with the time and the steps,
/// redrawn at most ten times a second; nothing when stderr is not a terminal.
#[derive(Debug)]
struct RunProgress {
    bar: indicatif::ProgressBar,
    last: Option<Instant>,
}

impl RunProgress {
    /// Resolution of the bar: the simulated fraction in thousandths.
    const STEPS: u64 = 1000;
    const TEMPLATE: &str = "[{bar:30}] {msg}";

    fn new() -> Self {
        Self { bar: crate::progress::bar(Self::STEPS, Self::TEMPLATE, 10), last: None }
    }

    fn update(&mut self, p: Progress) {
        if self.bar.is_hidden() {
            return;
        }
        // the driver reports every step: format at most ten times a second
        let now = Instant::now();
        if self.last.is_some_and(|l| now.duration_since(l) < Duration::from_millis(100)) {
            return;
        }
        self.last = Some(now);
        let frac = if p.end_s > 0.0 { (p.time_s / p.end_s).clamp(0.0, 1.0) } else { 1.0 };
        self.bar.set_position((frac * Self::STEPS as f64).round() as u64);
        self.bar.set_message(format!(
            "{:5.1}%  t = {:.4} of {} s, {} steps",
            frac * 100.0,
            p.time_s,
            fmt_num(p.end_s),
            p.steps
        ));
    }

    fn clear(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_progress_template_parses() {
        assert!(indicatif::ProgressStyle::with_template(RunProgress::TEMPLATE).is_ok());
    }

    #[test]
    fn noise_streams_are_independent_per_quantity() {
        let obs = |q: &'static str| Observation { time_s: 0.0, station: "s".into(), x_m: 0.0, quantity: q, value: 1.0 };
        let base = vec![obs("wall_temperature_k"), obs("pressure_pa"), obs("wall_temperature_k")];
        let mut one = base.clone();
        add_noise(&mut one, &BTreeMap::from([("wall_temperature_k", 0.5)]), 3);
        let mut two = base.clone();
        add_noise(&mut two, &BTreeMap::from([("wall_temperature_k", 0.5), ("pressure_pa", 10.0)]), 3);
        assert_eq!(one[0], two[0]);
        assert_eq!(one[2], two[2]);
        assert_eq!(one[1], base[1]);
        assert_ne!(two[1], base[1]);
        assert_ne!(one[0].value, one[2].value);
    }
}
