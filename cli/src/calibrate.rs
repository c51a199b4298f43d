//! `cryofit calibrate CALIBRATION.toml [--workers N] [--out DIR]`: fits registry parameters to
//! measured time series, running the simulations on a local thread pool.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{IsTerminal, Write as _};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_calib::config::{AlgorithmName, CalibrationSpec};
use cryofit_calib::data::Dataset;
use cryofit_calib::inference::InferenceSummary;
use cryofit_calib::pipeline::{Job, Pipeline};
use cryofit_calib::problem::{Experiment, Problem, experiment_from_texts};
use cryofit_calib::{Evaluation, Outcome, Space};
use cryofit_solver::params::{self, ParameterSet};
use rayon::prelude::*;
use serde_json::json;

use crate::fluid_source;
use crate::simulate::{csv_field, fmt_num, probes_csv, write_outputs};

/// Arguments of `cryofit calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// The calibration file (TOML).
    file: PathBuf,
    /// Simulations run at once [default: the number of cores].
    #[arg(long, value_name = "N")]
    workers: Option<usize>,
    /// Output directory [default: out/<calibration file stem>].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// A calibration read from disk: its spec, its problem and its (not yet started) pipeline.
pub struct Loaded {
    pub spec: CalibrationSpec,
    pub problem: Problem,
    pub pipeline: Pipeline,
}

/// Reads a calibration file and every case and data file it names (relative to its folder).
pub fn load(file: &Path) -> Result<Loaded> {
    let label = file.display().to_string();
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {label}"))?;
    let spec = CalibrationSpec::from_toml(&text, &label)?;
    // stages and bounds first: they need no other file
    let space = spec.space().map_err(|e| anyhow!("{label}: {e}"))?;
    let start = default_start(&space);
    let pipeline = Pipeline::new(space, spec.stages.clone(), start, spec.seed).map_err(|e| anyhow!("{label}: {e}"))?;
    let dir = file.parent().unwrap_or(Path::new("."));
    let mut fixed = ParameterSet::new();
    for (name, &v) in &spec.fixed {
        fixed.set(name, v).map_err(|e| anyhow!("{label}: fixed.{name}: {e}"))?;
    }
    let mut experiments = Vec::new();
    for (k, e) in spec.experiments.iter().enumerate() {
        let case_path = dir.join(&e.case);
        let data_path = dir.join(&e.data);
        let read = |p: &Path, field: &str| {
            std::fs::read_to_string(p)
                .with_context(|| format!("{label}: experiments[{k}].{field}: cannot read {}", p.display()))
        };
        let case_text = read(&case_path, "case")?;
        let data_text = read(&data_path, "data")?;
        let name = e.name.clone().unwrap_or_else(|| {
            case_path.file_stem().map_or_else(|| format!("experiment-{k}"), |s| s.to_string_lossy().into_owned())
        });
        if experiments.iter().any(|x: &Experiment| x.name == name) {
            bail!("{label}: experiments[{k}]: the name `{name}` is used twice; give each experiment its own `name`");
        }
        let fluid = |n: &str| fluid_source::load(n).map(|t| Arc::new(t.into_owned())).map_err(|e| format!("{e:#}"));
        let exp = experiment_from_texts(
            &name,
            &case_text,
            &case_path.display().to_string(),
            &data_text,
            &data_path.display().to_string(),
            fluid,
            &fixed,
            Some(spec.max_evaluation_s),
        )
        .map_err(|e| anyhow!("{label}: experiments[{k}]: {e}"))?;
        experiments.push(exp);
    }
    let problem = Problem::new(experiments, spec.weights()).map_err(|e| anyhow!("{label}: {e}"))?;
    Ok(Loaded { spec, problem, pipeline })
}

/// Unit coordinates of the registry defaults (clamped into the calibration's bounds): where the
/// first stage starts.
pub fn default_start(space: &Space) -> Vec<f64> {
    space
        .params()
        .iter()
        .enumerate()
        .map(|(i, p)| space.unit(i, params::spec(&p.name).map_or(0.5 * (p.lower + p.upper), |s| s.default)))
        .collect()
}

/// One row of `evaluations.csv`.
struct Row {
    job: Job,
    outcome: Outcome,
}

/// Evaluates jobs on the pool: every (job, experiment) pair is one task, so the cores stay busy
/// even with fewer jobs than cores.
fn evaluate(pool: &rayon::ThreadPool, problem: &Problem, jobs: &[Job]) -> Vec<Outcome> {
    let n_exp = problem.experiments.len();
    let parts: Vec<Outcome> = pool.install(|| {
        (0..jobs.len() * n_exp)
            .into_par_iter()
            .map(|k| problem.evaluate_experiment(k % n_exp, &jobs[k / n_exp].parameters))
            .collect()
    });
    parts
        .chunks(n_exp)
        .map(|chunk| {
            let mut total = 0.0;
            for o in chunk {
                match o {
                    Outcome::Ok { cost } => total += cost,
                    failed => return failed.clone(),
                }
            }
            Outcome::Ok { cost: total }
        })
        .collect()
}

/// Runs the calibration and writes its outputs.
pub fn run(args: &CalibrateArgs) -> Result<()> {
    let Loaded { spec, problem, mut pipeline } = load(&args.file)?;
    let spec = &spec;
    let label = args.file.display().to_string();
    let out_dir = match &args.out {
        Some(dir) => dir.clone(),
        None => {
            let stem = args.file.file_stem().map_or_else(|| "calibration".into(), |s| s.to_string_lossy().into_owned());
            Path::new("out").join(stem)
        }
    };
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("--out {}: exists and is not a directory", out_dir.display());
    }
    let workers = match args.workers {
        Some(0) => bail!("--workers 0: give at least 1"),
        Some(n) => n,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(workers)
        .build()
        .map_err(|e| anyhow!("cannot start {workers} worker threads: {e}"))?;
    let space = pipeline.space().clone();

    let clock = Instant::now();
    let mut bar = Bar::new(std::io::stderr().is_terminal());
    let mut rows: Vec<Row> = Vec::new();
    let batch = (workers * 4).max(8);
    while !pipeline.is_finished() {
        let jobs = pipeline.ask(batch);
        if jobs.is_empty() {
            if pipeline.is_finished() {
                break;
            }
            bail!("{label}: the calibration stalled at stage {} with nothing to evaluate", pipeline.stage());
        }
        let outcomes = evaluate(&pool, &problem, &jobs);
        let told: Vec<Evaluation> =
            jobs.iter().zip(&outcomes).map(|(j, o)| Evaluation { id: j.id, outcome: o.clone() }).collect();
        pipeline.tell(&told).map_err(|e| anyhow!("internal error: {e}"))?;
        rows.extend(jobs.into_iter().zip(outcomes).map(|(job, outcome)| Row { job, outcome }));
        bar.update(&pipeline, clock.elapsed());
    }
    bar.clear();
    if let Some(e) = pipeline.error() {
        bail!("{label}: {e}");
    }
    let wall = clock.elapsed().as_secs_f64();
    let Some(best) = pipeline.best().cloned() else {
        let reasons: BTreeMap<String, usize> = rows.iter().fold(BTreeMap::new(), |mut m, r| {
            if let Outcome::Failed { reason } = &r.outcome {
                *m.entry(reason.clone()).or_default() += 1;
            }
            m
        });
        let first = reasons.keys().next().cloned().unwrap_or_default();
        bail!("{label}: every one of the {} evaluations failed; first reason: {first}", rows.len());
    };
    let best_parameters = pipeline.parameters(&best.unit);

    // the best fit, once more, for its probes and per-series figures
    let mut fits = Vec::new();
    let mut files: Vec<(String, String)> = Vec::new();
    for (k, e) in problem.experiments.iter().enumerate() {
        let fit = problem.fit_experiment(k, &best_parameters).map_err(|m| anyhow!("best fit: {m}"))?;
        let model = solver_of(e)?;
        let out = model.run(&best_parameters).map_err(|m| anyhow!("best fit, experiment `{}`: {m}", e.name))?;
        files.push((format!("fit-{}.csv", e.name), probes_csv(&out.probes)));
        fits.push((e, fit, out));
    }

    let data_points = problem.data_points();
    let result = result_json(spec, &pipeline, &best, &best_parameters, &fits, data_points, wall)?;
    let best_toml = best_toml(spec, &best_parameters);
    let mut outputs: Vec<(String, String)> = vec![
        ("result.json".into(), result),
        ("best.toml".into(), best_toml),
        ("evaluations.csv".into(), evaluations_csv(&space, &pipeline, &rows)),
    ];
    if let Some(draws) = posterior_csv(&pipeline) {
        outputs.push(("posterior.csv".into(), draws));
    }
    outputs.extend(files);
    let refs: Vec<(&str, String)> = outputs.iter().map(|(n, c)| (n.as_str(), c.clone())).collect();
    write_outputs(&out_dir, &refs)?;
    print_report(spec, &pipeline, &best, &best_parameters, &fits, wall, &out_dir, &outputs);
    Ok(())
}

/// The solver model of an experiment (every experiment of a file-based calibration is one).
fn solver_of(e: &Experiment) -> Result<cryofit_calib::model::SolverModel> {
    let any: &dyn std::any::Any = e.model.as_any();
    any.downcast_ref::<cryofit_calib::model::SolverModel>()
        .cloned()
        .ok_or_else(|| anyhow!("experiment `{}` is not a solver model", e.name))
}

/// First time a series falls below `threshold`, linearly interpolated; `None` if it never does.
pub fn first_below(times: &[f64], values: &[f64], threshold: f64) -> Option<f64> {
    if values.first().is_some_and(|&v| v < threshold) {
        return times.first().copied();
    }
    for k in 1..values.len() {
        if values[k] < threshold && values[k - 1] >= threshold {
            let w = (values[k - 1] - threshold) / (values[k - 1] - values[k]);
            return Some(times[k - 1] + w * (times[k] - times[k - 1]));
        }
    }
    None
}

/// Chilldown times (wall below the inlet liquid temperature + 15 K) of data and model, per station.
fn chilldown_pairs(
    data: &Dataset,
    out: &cryofit_solver::driver::Output,
) -> BTreeMap<String, (Option<f64>, Option<f64>)> {
    let threshold = out.summary.inlet_liquid_temperature_k + cryofit_solver::driver::CHILLDOWN_MARGIN_K;
    let mut m = BTreeMap::new();
    for ((station, quantity), s) in &data.series {
        if quantity != "wall_temperature_k" {
            continue;
        }
        let model = out.summary.chilldown_time_s.get(station).copied().flatten();
        m.insert(station.clone(), (first_below(&s.times, &s.values, threshold), model));
    }
    m
}

type FitRow<'a> = (&'a Experiment, cryofit_calib::cost::Fit, cryofit_solver::driver::Output);

fn result_json(
    spec: &CalibrationSpec,
    p: &Pipeline,
    best: &cryofit_calib::Best,
    best_parameters: &BTreeMap<String, f64>,
    fits: &[FitRow<'_>],
    data_points: usize,
    wall: f64,
) -> Result<String> {
    let (evaluations, failed) = p.evaluations();
    let mut fit = serde_json::Map::new();
    for (e, f, out) in fits {
        let series: Vec<_> = f
            .series
            .iter()
            .map(|((station, quantity), s)| {
                json!({"station": station, "quantity": quantity, "rms": s.rms, "points": s.points, "cost": s.cost})
            })
            .collect();
        let chill: BTreeMap<String, serde_json::Value> = chilldown_pairs(&e.data, out)
            .into_iter()
            .map(|(st, (d, m))| (st, json!({"data_s": d, "model_s": m})))
            .collect();
        fit.insert(e.name.clone(), json!({"cost": f.cost, "series": series, "chilldown_time_s": chill}));
    }
    let value = json!({
        "name": spec.name,
        "seed": spec.seed,
        "best_cost": best.cost,
        "best_parameters": best_parameters,
        "fixed_parameters": spec.fixed,
        "evaluations": evaluations,
        "failed_evaluations": failed,
        "budget": p.budget(),
        "data_points": data_points,
        "wall_time_s": wall,
        "solver_version": env!("CARGO_PKG_VERSION"),
        "stages": p.reports(),
        "uncertainty": uncertainty(p),
        "fit": fit,
        "calibration": spec,
    });
    let mut text = serde_json::to_string_pretty(&value)?;
    text.push('\n');
    Ok(text)
}

/// Standard deviations and 95 % intervals from the last variance or MCMC stage.
fn uncertainty(p: &Pipeline) -> serde_json::Value {
    for r in p.reports().iter().rev() {
        match &r.details {
            Some(InferenceSummary::Mcmc(m)) => {
                let params: BTreeMap<&str, serde_json::Value> = m
                    .parameters
                    .iter()
                    .map(|q| {
                        (
                            r.free[q.index].as_str(),
                            json!({"value": q.mean, "sd": q.sd, "lower95": q.quantiles.q025, "upper95": q.quantiles.q975,
                                   "median": q.quantiles.q50, "r_hat": q.r_hat}),
                        )
                    })
                    .collect();
                return json!({"method": "mcmc", "stage": r.index, "parameters": params,
                              "names": r.free, "covariance": m.covariance_physical, "correlation": m.correlation});
            }
            Some(InferenceSummary::Variance(v)) => {
                let Some(g) = &v.gaussian else { continue };
                let params: BTreeMap<&str, serde_json::Value> = r
                    .free
                    .iter()
                    .enumerate()
                    .map(|(i, name)| {
                        (
                            name.as_str(),
                            json!({"value": g.centre_physical[i], "sd": g.sd_physical[i],
                                   "lower95": g.interval95[i].lower, "upper95": g.interval95[i].upper}),
                        )
                    })
                    .collect();
                return json!({"method": "variance", "stage": r.index, "parameters": params,
                              "names": r.free, "covariance": g.covariance_physical, "correlation": g.correlation,
                              "divergent_nearby": v.divergent.len()});
            }
            _ => {}
        }
    }
    serde_json::Value::Null
}

/// `best.toml`: the fixed and the best free values, a flat table for `cryofit simulate --params`.
fn best_toml(spec: &CalibrationSpec, best: &BTreeMap<String, f64>) -> String {
    let mut s = format!("# best parameters of calibration \"{}\" (cryofit calibrate)\n", spec.name.replace('"', "'"));
    let mut all: BTreeMap<&str, f64> = spec.fixed.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    all.extend(best.iter().map(|(k, v)| (k.as_str(), *v)));
    for (k, v) in all {
        let _ = writeln!(s, "{k} = {}", toml_num(v));
    }
    s
}

/// A TOML float that reads back to the same value.
fn toml_num(v: f64) -> String {
    let s = fmt_num(v);
    if s.contains(['.', 'e', 'E']) || s.contains("inf") || s.contains("NaN") { s } else { format!("{s}.0") }
}

fn evaluations_csv(space: &Space, p: &Pipeline, rows: &[Row]) -> String {
    let mut s = String::from("id,stage,algorithm,status,cost");
    for name in space.names() {
        let _ = write!(s, ",{}", csv_field(name));
    }
    s.push_str(",reason\n");
    for r in rows {
        let algorithm = p.stages().get(r.job.stage).map_or("?", |st| st.algorithm.as_str());
        let (status, cost, reason) = match &r.outcome {
            Outcome::Ok { cost } => ("ok", fmt_num(*cost), String::new()),
            Outcome::Failed { reason } => ("failed", String::new(), reason.clone()),
        };
        let _ = write!(s, "{},{},{algorithm},{status},{cost}", r.job.id, r.job.stage);
        for name in space.names() {
            let _ = write!(s, ",{}", fmt_num(r.job.parameters[name]));
        }
        let _ = writeln!(s, ",{}", csv_field(&reason));
    }
    s
}

fn posterior_csv(p: &Pipeline) -> Option<String> {
    let r = p.reports().iter().rev().find(|r| r.posterior_draws.is_some())?;
    let draws = r.posterior_draws.as_ref()?;
    let mut s = r.free.iter().map(|n| csv_field(n)).collect::<Vec<_>>().join(",");
    s.push('\n');
    for d in draws {
        s.push_str(&d.iter().map(|v| fmt_num(*v)).collect::<Vec<_>>().join(","));
        s.push('\n');
    }
    Some(s)
}

#[allow(clippy::too_many_arguments)]
fn print_report(
    spec: &CalibrationSpec,
    p: &Pipeline,
    best: &cryofit_calib::Best,
    best_parameters: &BTreeMap<String, f64>,
    fits: &[FitRow<'_>],
    wall: f64,
    out_dir: &Path,
    outputs: &[(String, String)],
) {
    let (n, failed) = p.evaluations();
    println!(
        "calibration \"{}\": {n} evaluations ({failed} failed) in {wall:.1} s; best cost {}",
        spec.name,
        fmt_sig(best.cost)
    );
    for r in p.reports() {
        let best = r.best_cost.map_or_else(|| "no successful evaluation".into(), |c| format!("best {}", fmt_sig(c)));
        println!(
            "  stage {} {}: {} evaluations ({} failed), {best}, {} free; {}",
            r.index,
            r.algorithm,
            r.evaluations,
            r.failed_evaluations,
            r.free.len(),
            r.stop
        );
        if let (AlgorithmName::Sensitivity | AlgorithmName::Morris, Some(d)) = (r.algorithm, &r.details) {
            let ranking = match d {
                InferenceSummary::Sensitivity(s) => &s.ranking,
                InferenceSummary::Morris(m) => &m.ranking,
                _ => continue,
            };
            let top: Vec<String> = ranking
                .entries
                .iter()
                .take(8)
                .map(|e| format!("{} {:.2}", r.free[e.index], e.normalised.unwrap_or(0.0)))
                .collect();
            println!("    ranking (normalised): {}", top.join(", "));
        }
    }
    let unc = uncertainty(p);
    println!("  best parameters:");
    for (name, v) in best_parameters {
        let pm = unc["parameters"][name.as_str()].as_object().map(|u| {
            format!(
                "  ± {} (95 %: {} – {})",
                fmt_sig(u["sd"].as_f64().unwrap_or(f64::NAN)),
                fmt_sig(u["lower95"].as_f64().unwrap_or(f64::NAN)),
                fmt_sig(u["upper95"].as_f64().unwrap_or(f64::NAN))
            )
        });
        println!("    {name} = {}{}", fmt_sig(*v), pm.unwrap_or_default());
    }
    println!("  fit:");
    for (e, f, out) in fits {
        let rms: Vec<String> =
            f.series.iter().map(|((st, q), s)| format!("{st} {} {}", short_quantity(q), fmt_sig(s.rms))).collect();
        println!("    {}: cost {}; RMS {}", e.name, fmt_sig(f.cost), rms.join(", "));
        for (st, (d, m)) in chilldown_pairs(&e.data, out) {
            if let (Some(d), Some(m)) = (d, m) {
                println!("      {st} chilldown: model {m:.1} s, data {d:.1} s ({:+.1} %)", (m / d - 1.0) * 100.0);
            }
        }
    }
    let names: Vec<&str> = outputs.iter().map(|(n, _)| n.as_str()).collect();
    println!("  wrote {} to {}", names.join(", "), out_dir.display());
}

fn short_quantity(q: &str) -> &str {
    match q {
        "wall_temperature_k" => "wall T (K)",
        "fluid_temperature_k" => "fluid T (K)",
        "pressure_pa" => "p (Pa)",
        other => other,
    }
}

/// Four significant digits.
fn fmt_sig(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) { format!("{v:.3e}") } else { format!("{}", (v * 1e4).round() / 1e4) }
}

/// A one-line progress bar: stage, evaluations, best cost, ETA.
struct Bar {
    enabled: bool,
    last: Option<Instant>,
    drawn: usize,
}

impl Bar {
    fn new(enabled: bool) -> Self {
        Self { enabled, last: None, drawn: 0 }
    }

    fn update(&mut self, p: &Pipeline, elapsed: Duration) {
        if !self.enabled {
            return;
        }
        let now = Instant::now();
        if self.last.is_some_and(|l| now.duration_since(l) < Duration::from_millis(200)) {
            return;
        }
        self.last = Some(now);
        let (n, failed) = p.evaluations();
        let budget = p.budget().max(1);
        let stage = p.stage().min(p.stages().len().saturating_sub(1));
        let algorithm = p.stages().get(stage).map_or("", |s| s.algorithm.as_str());
        let eta = if n > 0 {
            let per = elapsed.as_secs_f64() / n as f64;
            format!("{:.0} s", per * budget.saturating_sub(n) as f64)
        } else {
            "…".into()
        };
        let best = p.best().map_or_else(|| "—".into(), |b| fmt_sig(b.cost));
        let line = format!(
            "stage {}/{} {algorithm}  evaluations {n}/{budget} ({failed} failed)  best cost {best}  ETA ≤ {eta}",
            stage + 1,
            p.stages().len()
        );
        let pad = self.drawn.saturating_sub(line.chars().count());
        self.drawn = line.chars().count();
        let mut err = std::io::stderr().lock();
        let _ = write!(err, "\r{line}{}", " ".repeat(pad));
        let _ = err.flush();
    }

    fn clear(&mut self) {
        if self.drawn > 0 {
            let mut err = std::io::stderr().lock();
            let _ = write!(err, "\r{}\r", " ".repeat(self.drawn));
            let _ = err.flush();
            self.drawn = 0;
        }
    }
}
