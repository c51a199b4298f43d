//! The figures of a calibration, from what the coordinator stores about it: its request and stage
//! reports, its told parameter sets and its experiments (case and data texts).
//!
//! Model curves need simulations: the best fit of every experiment, and, when a posterior exists
//! and [`FigureOptions::band_draws`] asks for it, a posterior-predictive band from runs at drawn
//! parameter sets. The boiling curves come from the solver's closures at the best parameters.
//! Everything here is blocking computation (the dashboard runs it on the blocking pool, `cryofit
//! report` directly); it reads no file and no database. A figure whose inputs are missing is
//! returned with the reason instead of its data.

use std::collections::BTreeMap;
use std::sync::Arc;

use cryofit_api as api;
use cryofit_calib::Space;
use cryofit_calib::config::{AlgorithmName, CalibrationSpec, StageSpec};
use cryofit_calib::data::Dataset;
use cryofit_calib::draws::space_draws;
use cryofit_calib::inference::InferenceSummary;
use cryofit_calib::model::{SolverModel, probes_dataset};
use cryofit_calib::pipeline::StageReport;
use cryofit_calib::problem::Fixed;
use cryofit_plots as plots;
use cryofit_plots::{Figure, Plot};
use cryofit_solver::boiling::{BoilingConditions, boiling_curve};
use cryofit_solver::case::Case;
use cryofit_solver::cryo::CorrelationSet;
use cryofit_solver::params;

use crate::fluids::FluidLoader;

/// What a calibration's figures are made from.
#[derive(Debug, Clone)]
pub struct CalibrationData {
    /// The calibration as the API reports it.
    pub calibration: api::Calibration,
    /// Its parameter sets; pending ones are ignored.
    pub sets: Vec<api::ParameterSetItem>,
    /// Its experiments, in the calibration's order.
    pub experiments: Vec<api::Experiment>,
}

/// How much to compute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FigureOptions {
    /// Simulations at posterior draws for the posterior-predictive bands (0: no bands).
    pub band_draws: usize,
    /// Seed of Gaussian posterior draws.
    pub seed: u64,
    /// Threads for those simulations.
    pub threads: usize,
    /// End the model runs at the end of each experiment's data (the dashboard) instead of the
    /// case's `time.end_s` (reports, which show the whole run).
    pub end_at_data: bool,
}

impl Default for FigureOptions {
    fn default() -> Self {
        Self { band_draws: 0, seed: 0, threads: 1, end_at_data: false }
    }
}

/// Pressures of the boiling-curve figure, atm (the paper's boiling surface: 1, 3 and 7 atm).
pub const BOILING_PRESSURES_ATM: [f64; 3] = [1.0, 3.0, 7.0];
/// Liquid Reynolds numbers of the boiling-curve figure.
pub const BOILING_REYNOLDS: [f64; 4] = [0.0, 1e3, 1e4, 1e5];

/// A calibration's figures in their order: cost history, parameter traces, sensitivity ranking,
/// posterior marginals and corner plot, model against data per experiment and quantity, boiling
/// curves. Never fails: a figure that cannot be made carries the reason.
pub fn figures(d: &CalibrationData, fluids: &FluidLoader, opts: &FigureOptions) -> Vec<Figure> {
    let c = &d.calibration;
    let ctx = Context::new(d);
    let mut out = vec![cost_history(&ctx), traces(&ctx), sensitivity(&ctx)];
    let posterior = ctx.posterior(opts.seed);
    let (marginals, corner) = posterior_figures(&ctx, &posterior);
    out.push(marginals);
    out.push(corner);
    let built = ctx.experiments(fluids, opts.end_at_data);
    let best = c.best_parameters.clone();
    match &built {
        Err(why) => out.push(skipped("fit", "Model against data", why.clone())),
        Ok(exps) => {
            for e in exps {
                out.extend(fit_figures(&ctx, e, best.as_ref(), &posterior, opts));
            }
        }
    }
    out.push(boiling_figure(&ctx, built.as_deref().ok(), best.as_ref(), fluids));
    out
}

/// Short facts about a calibration for the head of a report.
pub fn facts(c: &api::Calibration) -> Vec<String> {
    let mut v = vec![
        format!("calibration {} “{}”: {}", c.id, c.name, c.status.as_str()),
        format!("{} of {} evaluations ({} failed)", c.evaluations, c.budget, c.failed_evaluations),
    ];
    if let Some(b) = c.best_cost {
        v.push(format!("best cost {}", plots_tick(b)));
    }
    if let Some(p) = &c.best_parameters {
        let s: Vec<String> = p.iter().map(|(k, x)| format!("{k} = {}", plots_tick(*x))).collect();
        v.push(format!("best parameters: {}", s.join(", ")));
    }
    if let Some(e) = &c.error {
        v.push(format!("error: {e}"));
    }
    v
}

fn plots_tick(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e5).contains(&v.abs()) {
        format!("{v:.4e}")
    } else {
        format!("{}", (v * 1e4).round() / 1e4)
    }
}

fn skipped(name: &str, title: &str, why: impl Into<String>) -> Figure {
    Figure { name: name.into(), title: title.into(), plot: Err(why.into()) }
}

/// Posterior draws: (parameter names, draws, what they are), or why there are none.
type Posterior = Result<(Vec<String>, Vec<Vec<f64>>, &'static str), String>;

/// A calibration's decoded parts.
struct Context<'a> {
    d: &'a CalibrationData,
    spec: Result<CalibrationSpec, String>,
    space: Result<Space, String>,
    stages: Vec<StageSpec>,
    reports: Result<Vec<StageReport>, String>,
    /// Told sets in the optimiser's order.
    sets: Vec<&'a api::ParameterSetItem>,
}

impl<'a> Context<'a> {
    fn new(d: &'a CalibrationData) -> Self {
        let c = &d.calibration;
        let spec = serde_json::from_value::<api::CreateCalibration>(c.spec.clone())
            .map_err(|e| format!("the stored calibration request cannot be read: {e}"))
            .map(|req| crate::validate::spec_of(&req, &d.experiments));
        let space = spec.as_ref().map_err(Clone::clone).and_then(|s| s.space().map_err(|e| e.to_string()));
        let stages = spec.as_ref().map(|s| s.stages.clone()).unwrap_or_default();
        let reports = c
            .stages
            .iter()
            .enumerate()
            .map(|(k, v)| {
                serde_json::from_value::<StageReport>(v.clone())
                    .map_err(|e| format!("the report of stage {} cannot be read: {e}", k + 1))
            })
            .collect();
        let mut sets: Vec<&api::ParameterSetItem> = d.sets.iter().filter(|s| s.status != "pending").collect();
        sets.sort_by_key(|s| s.job);
        Self { d, spec, space, stages, reports, sets }
    }

    fn stage_labels(&self) -> Vec<String> {
        self.stages.iter().enumerate().map(|(k, s)| format!("stage {}: {}", k + 1, s.algorithm.as_str())).collect()
    }

    fn title(&self, what: &str) -> String {
        format!("{} — {what}", self.d.calibration.name)
    }

    /// Posterior draws of the free parameters: (names, draws, what they are), or why there are none.
    fn posterior(&self, seed: u64) -> Posterior {
        let reports = self.reports.as_ref().map_err(Clone::clone)?;
        if let Some(r) = reports.iter().rev().find(|r| r.posterior_draws.as_ref().is_some_and(|d| !d.is_empty())) {
            return Ok((r.free.clone(), r.posterior_draws.clone().unwrap_or_default(), "MCMC"));
        }
        for r in reports.iter().rev() {
            if let Some(InferenceSummary::Variance(v)) = &r.details
                && let Some(g) = &v.gaussian
            {
                if !g.positive_definite {
                    return Err(format!(
                        "the variance stage's Hessian is not positive definite ({} of {} directions regularised): \
                         the best point is not a minimum along every direction and the Gaussian approximation \
                         does not hold there",
                        g.regularised,
                        g.eigenvalues.len()
                    ));
                }
                let space = self.space.as_ref().map_err(Clone::clone)?;
                let own = space.select(&r.free).ok_or_else(|| {
                    format!("the variance stage's parameters {:?} are not free parameters of the calibration", r.free)
                })?;
                let draws =
                    space_draws(&own, &g.centre_unit, &g.covariance_unit, 1000, seed).map_err(|e| e.to_string())?;
                return Ok((r.free.clone(), draws, "Gaussian approximation of the variance stage"));
            }
        }
        Err("no MCMC stage and no finished variance stage: there is no posterior yet".into())
    }

    fn experiments(&self, fluids: &FluidLoader, end_at_data: bool) -> Result<Vec<Built>, String> {
        let spec = self.spec.as_ref().map_err(Clone::clone)?;
        let fixed = Fixed::new(&spec.fixed).map_err(|e| e.to_string())?;
        self.d
            .experiments
            .iter()
            .map(|e| {
                let case_label = format!("experiment {} case", e.id);
                let case = Case::from_toml(&e.case, &case_label).map_err(|x| x.to_string())?;
                let case =
                    fixed.apply(case, &e.name).map_err(|(name, x)| format!("{case_label}: fixed.{name}: {x}"))?;
                let data =
                    Dataset::from_csv(&e.data, &format!("experiment {} data", e.id)).map_err(|x| x.to_string())?;
                let (table, _) = fluids(&case.fluid.name).map_err(|m| format!("{case_label}: {m}"))?;
                let mut model = SolverModel::new(case.clone(), table, fixed.params())
                    .map_err(|m| format!("{case_label}: {m}"))?
                    .with_experiment(&e.name)
                    .with_wall_limit(Some(spec.max_evaluation_s));
                if end_at_data {
                    model = model.with_end_at(data.end_time());
                }
                Ok(Built { name: e.name.clone(), case, data, model: Arc::new(model) })
            })
            .collect()
    }
}

/// An experiment ready to run.
struct Built {
    name: String,
    case: Case,
    data: Dataset,
    model: Arc<SolverModel>,
}

fn cost_history(ctx: &Context<'_>) -> Figure {
    let (name, title) = ("cost-history", "Best cost against evaluations");
    if ctx.sets.is_empty() {
        return skipped(name, title, "no evaluation has finished yet");
    }
    let evaluations = ctx
        .sets
        .iter()
        .enumerate()
        .map(|(i, s)| plots::Evaluation {
            index: i,
            stage: s.stage.max(0) as usize,
            cost: if s.status == "ok" { s.cost } else { None },
        })
        .collect();
    let plot =
        Plot::CostHistory(plots::CostHistory { title: ctx.title(title), stages: ctx.stage_labels(), evaluations });
    Figure { name: name.into(), title: title.into(), plot: Ok(plot) }
}

/// `name (unit)`-style unit of a registry parameter or a case field (empty when dimensionless).
fn unit_of(name: &str) -> String {
    let unit = match cryofit_calib::apparatus::case_name(name) {
        Some(field) => Some(cryofit_solver::case::field_unit(field.path)),
        None => params::spec(name).map(|s| s.unit),
    };
    unit.map(str::to_string).filter(|u| u != "-" && u != "1").unwrap_or_default()
}

fn label_of(name: &str) -> String {
    let u = unit_of(name);
    if u.is_empty() { format!("{name} (dimensionless)") } else { format!("{name} ({u})") }
}

fn traces(ctx: &Context<'_>) -> Figure {
    let (name, title) = ("parameter-traces", "Parameter values against evaluations");
    let space = match &ctx.space {
        Ok(s) => s,
        Err(e) => return skipped(name, title, e.clone()),
    };
    if ctx.sets.is_empty() {
        return skipped(name, title, "no evaluation has finished yet");
    }
    let best = ctx.d.calibration.best_parameters.as_ref();
    let traces = space
        .params()
        .iter()
        .map(|p| plots::Trace {
            name: p.name.clone(),
            unit: unit_of(&p.name),
            log: matches!(p.scale, cryofit_calib::space::Scale::Log),
            points: ctx
                .sets
                .iter()
                .enumerate()
                .filter_map(|(i, s)| s.parameters.get(&p.name).map(|&v| (i, s.stage.max(0) as usize, v)))
                .collect(),
            best: best.and_then(|b| b.get(&p.name).copied()),
        })
        .collect();
    let plot = Plot::Traces(plots::Traces { title: ctx.title(title), stages: ctx.stage_labels(), traces });
    Figure { name: name.into(), title: title.into(), plot: Ok(plot) }
}

fn sensitivity(ctx: &Context<'_>) -> Figure {
    let (name, title) = ("sensitivity", "Sensitivity ranking");
    let reports = match &ctx.reports {
        Ok(r) => r,
        Err(e) => return skipped(name, title, e.clone()),
    };
    let mut panels = Vec::new();
    let mut score_label = "score, normalised to the largest".to_string();
    for (k, r) in reports.iter().enumerate() {
        let (ranking, suggested) = match (&r.algorithm, &r.details) {
            (AlgorithmName::Sensitivity, Some(InferenceSummary::Sensitivity(s))) => {
                score_label = "|relative sensitivity of the cost|, normalised to the largest".into();
                (&s.ranking, &s.suggested_free)
            }
            (AlgorithmName::Morris, Some(InferenceSummary::Morris(m))) => {
                score_label = "Morris μ* (mean |elementary effect|), normalised to the largest".into();
                (&m.ranking, &m.suggested_free)
            }
            _ => continue,
        };
        if ranking.entries.is_empty() {
            continue;
        }
        let next_free = reports.get(k + 1).map(|n| &n.free);
        let bars = ranking
            .entries
            .iter()
            .map(|e| {
                let pname = r.free.get(e.index).cloned().unwrap_or_else(|| format!("#{}", e.index));
                let kept = match next_free {
                    Some(free) => free.contains(&pname),
                    None => suggested.is_empty() || suggested.contains(&e.index),
                };
                plots::RankedBar { name: pname, score: e.normalised, kept }
            })
            .collect();
        panels.push(plots::RankingPanel { label: format!("stage {}: {}", r.index + 1, r.algorithm.as_str()), bars });
    }
    if panels.is_empty() {
        let why =
            if ctx.stages.iter().any(|s| matches!(s.algorithm, AlgorithmName::Sensitivity | AlgorithmName::Morris)) {
                "the screening stage has not finished yet"
            } else {
                "the calibration has no sensitivity or Morris stage"
            };
        return skipped(name, title, why);
    }
    let plot = Plot::Sensitivity(plots::Sensitivity { title: ctx.title(title), score_label, panels });
    Figure { name: name.into(), title: title.into(), plot: Ok(plot) }
}

fn posterior_figures(ctx: &Context<'_>, posterior: &Posterior) -> (Figure, Figure) {
    let (mn, mt) = ("posterior-marginals", "Posterior marginals");
    let (cn, ct) = ("posterior-corner", "Posterior, pairwise");
    let (names, draws, what) = match posterior {
        Ok(p) => p,
        Err(e) => return (skipped(mn, mt, e.clone()), skipped(cn, ct, e.clone())),
    };
    let best = ctx
        .d
        .calibration
        .best_parameters
        .as_ref()
        .and_then(|b| names.iter().map(|n| b.get(n).copied()).collect::<Option<Vec<f64>>>());
    let samples = |t: &str| plots::Samples {
        title: format!("{} ({what}, {} draws)", ctx.title(t), draws.len()),
        labels: names.iter().map(|n| label_of(n)).collect(),
        draws: draws.clone(),
        best: best.clone(),
    };
    let m = Figure { name: mn.into(), title: mt.into(), plot: Ok(Plot::Marginals(samples(mt))) };
    let c = if names.len() < 2 {
        skipped(cn, ct, "only one parameter is free: nothing to pair")
    } else {
        Figure { name: cn.into(), title: ct.into(), plot: Ok(Plot::Corner(samples(ct))) }
    };
    (m, c)
}

/// Axis label, scale to display units and file-name part of a probe quantity.
fn quantity_display(q: &str) -> (String, f64, String) {
    match q {
        "wall_temperature_k" => ("wall temperature (K)".into(), 1.0, "wall-temperature".into()),
        "fluid_temperature_k" => ("fluid temperature (K)".into(), 1.0, "fluid-temperature".into()),
        "pressure_pa" => ("pressure (kPa)".into(), 1e-3, "pressure".into()),
        "void_fraction" => ("void fraction (dimensionless)".into(), 1.0, "void-fraction".into()),
        other => (other.replace('_', " "), 1.0, other.replace('_', "-")),
    }
}

/// A file-name-safe form of an experiment name.
fn slug(s: &str) -> String {
    let v: String =
        s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '-' }).collect();
    if v.is_empty() { "experiment".into() } else { v }
}

/// Runs the model at each parameter set on `threads` threads; returns the successful runs' probes.
fn run_many(model: &SolverModel, sets: &[BTreeMap<String, f64>], threads: usize) -> Vec<Dataset> {
    let threads = threads.clamp(1, sets.len().max(1));
    let chunk = sets.len().div_ceil(threads).max(1);
    std::thread::scope(|s| {
        let handles: Vec<_> = sets
            .chunks(chunk)
            .map(|part| {
                s.spawn(move || {
                    part.iter().filter_map(|p| model.run(p).ok()).map(|o| probes_dataset(&o.probes)).collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_default()).collect()
    })
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let k = pos.floor() as usize;
    let w = pos - k as f64;
    if k + 1 < sorted.len() { sorted[k] * (1.0 - w) + sorted[k + 1] * w } else { sorted[k] }
}

/// Fewest successful posterior runs for a band.
const MIN_BAND_RUNS: usize = 5;

fn fit_figures(
    ctx: &Context<'_>,
    e: &Built,
    best: Option<&BTreeMap<String, f64>>,
    posterior: &Posterior,
    opts: &FigureOptions,
) -> Vec<Figure> {
    let mut quantities: Vec<String> = e.data.series.keys().map(|(_, q)| q.clone()).collect();
    quantities.sort();
    quantities.dedup();
    if !quantities.iter().any(|q| q == "wall_temperature_k") {
        quantities.insert(0, "wall_temperature_k".into());
    }
    let fig = |q: &str| {
        let (label, _, file) = quantity_display(q);
        (format!("fit-{}-{file}", slug(&e.name)), format!("{}: {} (model and data)", e.name, label))
    };
    let Some(best) = best else {
        return quantities
            .iter()
            .map(|q| {
                let (n, t) = fig(q);
                skipped(&n, &t, "no evaluation has succeeded yet: there is no best point to run")
            })
            .collect();
    };
    let model = match e.model.run(best) {
        Ok(o) => probes_dataset(&o.probes),
        Err(m) => {
            return quantities
                .iter()
                .map(|q| {
                    let (n, t) = fig(q);
                    skipped(&n, &t, format!("the model at the best parameters failed: {m}"))
                })
                .collect();
        }
    };
    // posterior-predictive runs
    let mut band_note = String::from("no posterior-predictive band (no posterior)");
    let mut runs: Vec<Dataset> = Vec::new();
    if opts.band_draws == 0 {
        band_note = "posterior-predictive band not requested".into();
    } else if let Err(why) = posterior {
        band_note = format!("no posterior-predictive band: {why}");
    } else if let Ok((names, draws, _)) = posterior {
        let n = opts.band_draws.min(draws.len());
        let step = draws.len() as f64 / n.max(1) as f64;
        let sets: Vec<BTreeMap<String, f64>> = (0..n)
            .map(|k| {
                let row = &draws[((k as f64 * step) as usize).min(draws.len() - 1)];
                let mut m = best.clone();
                for (name, v) in names.iter().zip(row) {
                    m.insert(name.clone(), *v);
                }
                m
            })
            .collect();
        runs = run_many(&e.model, &sets, opts.threads);
        if runs.len() < MIN_BAND_RUNS {
            band_note = format!("no band: only {} of {n} posterior runs succeeded", runs.len());
            runs.clear();
        } else {
            band_note = String::new();
        }
    }
    quantities
        .iter()
        .map(|q| {
            let (n, t) = fig(q);
            let (label, scale, _) = quantity_display(q);
            let mut panels: Vec<plots::StationPanel> = e
                .case
                .stations
                .iter()
                .filter_map(|st| {
                    let key = (st.name.clone(), q.clone());
                    let data = e.data.series.get(&key);
                    let m = model.series.get(&key)?;
                    if data.is_none() && q != "wall_temperature_k" {
                        return None;
                    }
                    Some(plots::StationPanel {
                        station: st.name.clone(),
                        x_m: Some(st.x_m),
                        data: data
                            .map(|s| s.times.iter().copied().zip(s.values.iter().copied()).collect())
                            .unwrap_or_default(),
                        model: m.times.iter().copied().zip(m.values.iter().copied()).collect(),
                        band: (!runs.is_empty()).then(|| band(&runs, &key, &m.times)),
                    })
                })
                .collect();
            if panels.is_empty() {
                return skipped(&n, &t, format!("the model records no {label} at the stations"));
            }
            // the run-wide note on the first quantity's figure; a figure's own on that figure
            let mut note = if q == quantities[0].as_str() { band_note.clone() } else { String::new() };
            let mut band_label = format!("5–95 % posterior predictive ({} runs)", runs.len());
            if let Some(inside) = best_fit_coverage(&panels) {
                if inside < MIN_BEST_FIT_COVERAGE {
                    note = format!(
                        "no posterior-predictive band: the best fit lies inside the {} posterior runs' 5–95 % range at \
                         only {:.0} % of its points, so the posterior does not describe the runs near the best point",
                        runs.len(),
                        100.0 * inside
                    );
                    for p in &mut panels {
                        p.band = None;
                    }
                } else {
                    band_label = format!(
                        "5–95 % posterior predictive ({} runs; best fit inside at {:.0} % of its points)",
                        runs.len(),
                        100.0 * inside
                    );
                }
            }
            let mut title = ctx.title(&format!("{}, {label}", e.name));
            if !note.is_empty() {
                title.push_str(&format!(" — {note}"));
            }
            let plot =
                Plot::Fit(plots::FitPanels { title, value_label: label, value_scale: scale, band_label, panels });
            Figure { name: n, title: t, plot: Ok(plot) }
        })
        .collect()
}

/// The 5–95 % range of the posterior runs' `key` series at each of `times` (times where fewer
/// than [`MIN_BAND_RUNS`] runs have a finite value are left out).
fn band(runs: &[Dataset], key: &(String, String), times: &[f64]) -> Vec<(f64, f64, f64)> {
    times
        .iter()
        .filter_map(|&t| {
            let mut v: Vec<f64> =
                runs.iter().filter_map(|r| r.series.get(key).and_then(|s| s.at(t))).filter(|v| v.is_finite()).collect();
            if v.len() < MIN_BAND_RUNS {
                return None;
            }
            v.sort_by(f64::total_cmp);
            Some((t, quantile(&v, 0.05), quantile(&v, 0.95)))
        })
        .collect()
}

/// Fewest of the best fit's points (fraction, over the panels' banded times) that must lie inside
/// the posterior-predictive band for the band to be drawn.
///
/// Decision: were the best fit a typical run of the posterior it drew the band from, it would lie
/// inside the 5–95 % range at about 90 % of its points. A best point chosen for its low cost
/// among jittering neighbours (VALIDATION.md) is less typical than that, and the label states the
/// fraction; below one half, the band describes other runs than the best one and is not drawn,
/// with the reason in the title.
const MIN_BEST_FIT_COVERAGE: f64 = 0.5;

/// The fraction of the best fit's points, over all panels, that lie inside their panel's band at
/// the same time; `None` where no panel has a band.
fn best_fit_coverage(panels: &[plots::StationPanel]) -> Option<f64> {
    let (mut inside, mut total) = (0usize, 0usize);
    for p in panels {
        let Some(band) = &p.band else { continue };
        let model: BTreeMap<u64, f64> = p.model.iter().map(|&(t, v)| (t.to_bits(), v)).collect();
        for &(t, lo, hi) in band {
            if let Some(&v) = model.get(&t.to_bits()) {
                total += 1;
                if (lo..=hi).contains(&v) {
                    inside += 1;
                }
            }
        }
    }
    (total > 0).then(|| inside as f64 / total as f64)
}

fn boiling_figure(
    ctx: &Context<'_>,
    experiments: Option<&[Built]>,
    best: Option<&BTreeMap<String, f64>>,
    fluids: &FluidLoader,
) -> Figure {
    let (name, title) = ("boiling-curve", "Boiling curve at the best parameters");
    let Some(e) = experiments.and_then(|x| x.first()) else {
        return skipped(name, title, "the experiments could not be read");
    };
    let Some(best) = best else {
        return skipped(name, title, "no evaluation has succeeded yet: there are no best parameters");
    };
    let set = match e.model.parameter_set(best) {
        Ok(s) => s,
        Err(m) => return skipped(name, title, m.to_string()),
    };
    let correlations: CorrelationSet = e.case.physics.correlations.parse().unwrap_or_default();
    let table = match fluids(&e.case.fluid.name) {
        Ok((t, _)) => t,
        Err(m) => return skipped(name, title, m),
    };
    let d = e.case.pipe.inner_diameter_m.at(0.0);
    let mut panels = Vec::new();
    for atm in BOILING_PRESSURES_ATM {
        let p = atm * 101_325.0;
        let t_sat = match table.saturation(p) {
            Ok(s) => s.t_sat,
            Err(m) => return skipped(name, title, m.to_string()),
        };
        let top = 300.0f64.max(t_sat + 50.0);
        let temps: Vec<f64> = (0..=300).map(|k| t_sat + 0.2 + (top - t_sat - 0.2) * f64::from(k) / 300.0).collect();
        let mut series = Vec::new();
        for re in BOILING_REYNOLDS {
            let c = BoilingConditions { pressure_pa: p, reynolds_l: re, diameter_m: d };
            match boiling_curve(&table, &set, correlations, &c, &temps) {
                Ok(b) => series.push(plots::BoilingSeries {
                    reynolds: re,
                    points: b.points.iter().map(|q| (q.t_w, q.q_w_m2)).collect(),
                }),
                Err(m) => return skipped(name, title, m.to_string()),
            }
        }
        panels.push(plots::BoilingPanel { pressure_pa: p, t_sat_k: t_sat, series });
    }
    let full = format!(
        "{} ({}, saturated liquid, D = {} mm, {} correlations)",
        ctx.title(title),
        e.case.fluid.name,
        plots_tick(d * 1e3),
        correlations.name()
    );
    Figure {
        name: name.into(),
        title: title.into(),
        plot: Ok(Plot::Boiling(plots::BoilingCurves { title: full, panels })),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A calibration of the tiny case lengthened to 1000 s, with data to 8 s.
    fn data() -> CalibrationData {
        let case = include_str!("../../tests/fixtures/tiny.toml").replace("end_s = 8.0", "end_s = 1000.0");
        let experiment = api::Experiment {
            id: 1,
            name: "tiny".into(),
            fluid: "nitrogen".into(),
            case,
            data: include_str!("../../tests/fixtures/tiny-data.csv").into(),
            created: 0,
        };
        let spec = json!({
            "name": "t", "seed": 1, "experiments": [1],
            "parameters": [{"name": "Gwsc", "lower": 0.5, "upper": 2.0}],
            "weights": {"wall_temperature_k": {"weight": 1.0, "sigma": 1.0}},
            "stages": [{"algorithm": "cmaes", "budget": 6}]
        });
        let calibration = api::Calibration {
            id: 1,
            name: "t".into(),
            status: api::CalibrationStatus::Completed,
            evaluations: 0,
            failed_evaluations: 0,
            budget: 6,
            stage: 0,
            best_cost: None,
            best_parameters: None,
            experiments: vec![1],
            solver_version: api::SOLVER_VERSION.into(),
            fluid_hashes: BTreeMap::new(),
            error: None,
            spec,
            stages: Vec::new(),
            created: 0,
            updated: 0,
        };
        CalibrationData { calibration, sets: Vec::new(), experiments: vec![experiment] }
    }

    /// The variance stage of `Gwsc` with a Hessian of `h` at Gwsc = 1 (unit 1/3 of [0.5, 2]).
    fn with_variance_stage(h: f64) -> CalibrationData {
        use cryofit_calib::inference::{Variance, VarianceOptions};
        let space = Space::new(vec![cryofit_calib::space::FreeParameter {
            name: "Gwsc".into(),
            lower: 0.5,
            upper: 2.0,
            scale: cryofit_calib::space::Scale::Linear,
        }])
        .unwrap();
        let options = VarianceOptions { restarts: 0, profile_points: 0, ..VarianceOptions::default() };
        let v = Variance::new(&space, Some(&[1.0 / 3.0]), options, 3, 1).unwrap();
        let mut alg = cryofit_calib::inference::InferenceAlgorithm::Variance(Box::new(v));
        cryofit_calib::api::minimize(&mut alg, 8, |u: &[f64]| {
            let x = u[0] - 1.0 / 3.0;
            cryofit_calib::api::Outcome::Ok { cost: 10.0 + 0.5 * h * x * x }
        });
        let details = alg.summary();
        if let InferenceSummary::Variance(s) = &details {
            assert_eq!(s.gaussian.as_ref().expect("a Gaussian").positive_definite, h > 0.0);
        }
        let report = StageReport {
            index: 0,
            algorithm: AlgorithmName::Variance,
            budget: 3,
            evaluations: 3,
            failed_evaluations: 0,
            free: vec!["Gwsc".into()],
            best_cost: Some(10.0),
            lowest_cost: Some(10.0),
            best_parameters: BTreeMap::from([("Gwsc".to_string(), 1.0)]),
            stop: "converged".into(),
            details: Some(details),
            posterior_draws: None,
        };
        let mut d = data();
        d.calibration.stages = vec![serde_json::to_value(report).unwrap()];
        d
    }

    #[test]
    fn draws_come_only_from_a_positive_definite_gaussian_in_unit_coordinates() {
        let d = with_variance_stage(1e4);
        let (names, draws, what) = Context::new(&d).posterior(3).expect("a posterior");
        assert_eq!(names, ["Gwsc"]);
        assert!(what.contains("variance"), "{what}");
        // sd in unit coordinates √(2/1e4) = 0.0141, i.e. 0.0212 in Gwsc
        let n = draws.len() as f64;
        let mean = draws.iter().map(|x| x[0]).sum::<f64>() / n;
        let sd = (draws.iter().map(|x| (x[0] - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!((mean - 1.0).abs() < 0.005 && (sd / 0.0212 - 1.0).abs() < 0.1, "mean {mean}, sd {sd}");
        let d = with_variance_stage(-1e4);
        let why = Context::new(&d).posterior(3).expect_err("no posterior from a saddle");
        assert!(why.contains("not positive definite"), "{why}");
    }

    #[test]
    fn the_best_fit_coverage_counts_points_inside_the_band_at_the_same_times() {
        let panel = |model: Vec<(f64, f64)>, band: Option<Vec<(f64, f64, f64)>>| plots::StationPanel {
            station: "TS1".into(),
            x_m: None,
            data: Vec::new(),
            model,
            band,
        };
        let inside = panel(vec![(0.0, 1.0), (1.0, 2.0), (2.0, 3.0)], Some(vec![(0.0, 0.5, 1.5), (1.0, 2.5, 3.0)]));
        let no_band = panel(vec![(0.0, 1.0)], None);
        // (0 s inside, 1 s below the band; 2 s has no band)
        assert_eq!(best_fit_coverage(&[inside.clone(), no_band.clone()]), Some(0.5));
        assert_eq!(best_fit_coverage(&[no_band]), None);
        let edge = panel(vec![(0.0, 1.5)], Some(vec![(0.0, 0.5, 1.5)]));
        assert_eq!(best_fit_coverage(&[edge, inside]), Some(2.0 / 3.0));
    }

    #[test]
    fn dashboard_runs_end_at_the_data_and_reports_run_the_whole_case() {
        let d = data();
        let ctx = Context::new(&d);
        let fluids = crate::fluids::embedded_fluids();
        let dashboard = ctx.experiments(&fluids, true).expect("experiments");
        assert_eq!(dashboard[0].model.stop_s(), 8.0, "the data end at 8 s");
        let report = ctx.experiments(&fluids, false).expect("experiments");
        assert_eq!(report[0].model.stop_s(), 1000.0, "the case runs 1000 s");
    }
}
