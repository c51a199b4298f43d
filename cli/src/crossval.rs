//! `cryofit crossval CALIBRATION.toml [--from DIR] [--out DIR] [--coordinator URL]`: leave-one-out
//! cross-validation of a joint calibration. For each experiment in turn the calibration is
//! refitted without it
//! (the stages of the file's `[crossval]` table, warm-started from the joint optimum of `--from`)
//! and the left-out experiment is predicted: its best-fit prediction (RMS per station, station-4
//! chilldown against the data) and, where the refit has a posterior that holds, the 5–95 %
//! posterior-predictive band and the share of the measurements it covers. It writes, in `--out`,
//! a folder per fold (the refit's calibration file and outputs, the predictions), `crossval.json`,
//! `crossval.csv` and a figure per fold (left-out data, prediction and band). With
//! `--coordinator URL` the refits run on that coordinator's workers: all are submitted first, so
//! that they share the workers, and each is then waited for and written as `cryofit calibrate
//! --coordinator` writes it.
//!
//! Decisions:
//! - The refit frees the joint calibration's last-stage parameters (after any screening stage
//!   chose them) and starts them at the joint optimum; without `--from` it frees the file's
//!   parameters from their starts. A per-experiment copy of a case field that belongs to the
//!   left-out experiment is not refitted (nothing constrains it) and the prediction uses the
//!   left-out case's own value: a new run's apparatus is not known in advance.
//! - An MCMC refit stage tempered by `"noise"` with no variance stage before it in the refit takes
//!   the noise inflation the joint calibration's last variance stage measured (`--from`), written
//!   into the fold's calibration file as a number; the refit then needs no Hessian of its own.
//! - The band is the posterior-predictive band of a measurement that `cryofit predict` writes
//!   (`p05`–`p95`: the model at posterior draws, its clock scaled by the refit's own clock
//!   error, plus the misfit left at the best alignment, per station; see `predict`'s decision);
//!   its coverage counts the left-out measurements whose value lies between the band's 5 and
//!   95 % at the measurement's time (linear between the band's times), and its mean width there
//!   is reported with it. The coverage of the parameters' band alone (`q05`–`q95`) is reported beside
//!   it: the share of the measurements that the parameters' uncertainty by itself explains.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_calib::apparatus;
use cryofit_calib::config::{CalibrationSpec, ExperimentRef, ParameterSpec, Temperature};
use cryofit_calib::data::Dataset;
use cryofit_calib::pipeline::{self, StageReport};
use cryofit_plots::{Figure, FitPanels, Plot, StationPanel};
use serde_json::json;

use crate::csv_text::CsvText;
use crate::output::{fmt_num, read_result_json, write_outputs};

/// Arguments of `cryofit crossval`.
#[derive(Debug, Args)]
pub struct CrossvalArgs {
    /// The joint calibration file (TOML), with a `[crossval]` table giving the refits' stages.
    file: PathBuf,
    /// Output folder of the joint calibration: its best point starts each refit and its last
    /// stage's free parameters are the ones refitted.
    #[arg(long, value_name = "DIR")]
    from: Option<PathBuf>,
    /// Output directory [default: out/crossval-<calibration file stem>].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Simulations run at once [default: the number of cores].
    #[arg(long, value_name = "N")]
    workers: Option<usize>,
    /// Run the refits on this coordinator's workers (token from CRYOFIT_TOKEN): every fold's
    /// refit is submitted at once, so that they share the workers, and each is written, as
    /// `cryofit calibrate --coordinator` writes it, when it ends; the left-out predictions run
    /// here. Re-running into the same --out waits for the same refits.
    #[arg(long, value_name = "URL", conflicts_with = "workers")]
    coordinator: Option<String>,
    /// Posterior draws for each left-out prediction's band.
    #[arg(long, value_name = "N", default_value_t = 40)]
    samples: usize,
    /// Seed of the posterior draws.
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
}

/// The joint optimum: best values and the last stage's free parameters.
struct Joint {
    best: BTreeMap<String, f64>,
    free: Vec<String>,
    /// The noise inflation the joint calibration's last variance stage measured (1 when it
    /// measured none), if it had one: see [`fold_spec`] for its use.
    noise_temperature: Option<f64>,
}

fn read_joint(dir: &Path) -> Result<Joint> {
    let (path, result) = read_result_json(dir, "--from")?;
    let best: BTreeMap<String, f64> = serde_json::from_value(result["best_parameters"].clone())
        .with_context(|| format!("{}: `best_parameters` is missing or not a table of numbers", path.display()))?;
    let reports: Vec<StageReport> = serde_json::from_value(result["stages"].clone())
        .with_context(|| format!("{}: `stages` is missing or not a list of stage reports", path.display()))?;
    let free = reports
        .last()
        .map(|r| r.free.clone())
        .ok_or_else(|| anyhow!("{}: `stages` holds no stage with its free parameters", path.display()))?;
    Ok(Joint { best, free, noise_temperature: pipeline::measured_noise_temperature(&reports) })
}

/// A free parameter's name as the `[[parameters]]` entry it comes from and, for a per-experiment
/// copy of a case field (`case.<path>@<experiment>`), its experiment.
fn entry_of(name: &str) -> (&str, Option<&str>) {
    match apparatus::case_name(name).and_then(|c| c.experiment) {
        Some(e) => (&name[..name.len() - e.len() - apparatus::EXPERIMENT_MARK.len_utf8()], Some(e)),
        None => (name, None),
    }
}

/// The refit without experiment `left` (index): the other experiments (paths made absolute from
/// `base`), the refitted parameters starting at the joint optimum, the `[crossval]` stages.
fn fold_spec(spec: &CalibrationSpec, left: usize, joint: Option<&Joint>, base: &Path) -> Result<CalibrationSpec> {
    let cv = spec.crossval.as_ref().ok_or_else(|| {
        anyhow!(
            "the calibration file has no [crossval] table: add the refits' stages, e.g.\n  [[crossval.stages]]\n  \
             algorithm = \"cmaes\"\n  budget = 60\n  sigma = 0.1\n  [[crossval.stages]]\n  algorithm = \"variance\"\n  \
             budget = 40"
        )
    })?;
    let left_name = spec.experiments[left].label(left);
    let space = spec.space()?;
    let names: Vec<String> = space.names().map(str::to_owned).collect();
    let absolute = |p: &str| base.join(p).display().to_string();
    let experiments: Vec<ExperimentRef> = spec
        .experiments
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != left)
        .map(|(k, e)| ExperimentRef { case: absolute(&e.case), data: absolute(&e.data), name: Some(e.label(k)) })
        .collect();
    let mut parameters = Vec::new();
    for p in &spec.parameters {
        // the space names of this entry: itself, or one copy per listed experiment
        let kept: Vec<&String> = names
            .iter()
            .filter(|n| entry_of(n).0 == p.name)
            .filter(|n| joint.is_none_or(|j| j.free.contains(n)))
            .filter(|n| entry_of(n).1 != Some(left_name.as_str()))
            .collect();
        let Some(first) = kept.first() else { continue };
        let experiments = p
            .experiments
            .as_ref()
            .map(|_| kept.iter().filter_map(|n| entry_of(n).1.map(str::to_owned)).collect::<Vec<_>>());
        let start = joint.and_then(|j| j.best.get(*first).copied()).or(p.start);
        parameters.push(ParameterSpec { experiments, start, ..p.clone() });
    }
    if parameters.is_empty() {
        bail!("without experiment `{left_name}` no free parameter is left to refit");
    }
    // Decision: a per-experiment fixed case field of the left-out experiment is refused rather
    // than dropped: the refit has no such experiment to hold it, and the left-out prediction reads
    // the refit's outputs, so the value would be lost without a word; in its case file it holds.
    if let Some(name) =
        spec.fixed.keys().find(|n| apparatus::case_name(n).and_then(|c| c.experiment) == Some(left_name.as_str()))
    {
        bail!(
            "fixed.{name}: cross-validation predicts experiment `{left_name}` from refits without it, which cannot \
             hold its own fixed case fields; set the value in its case file instead"
        );
    }
    // the joint's values of parameters it did not refit (screened out) stay as they were: fixed
    let mut fixed = spec.fixed.clone();
    if let Some(j) = joint {
        for (name, &v) in &j.best {
            let free = parameters.iter().any(|p| p.name == entry_of(name).0);
            if !free && !apparatus::is_case_name(name) && !fixed.contains_key(name) {
                fixed.insert(name.clone(), v);
            }
        }
    }
    // `temperature = "noise"` on a refit's MCMC stage with no variance stage before it in the
    // refit: the jitter the joint calibration's variance stage measured at the joint optimum, where
    // the refit starts. Decision: the joint cost sums one run more than a refit's, so its jitter is
    // if anything larger and the tempered refit posterior if anything wider — the conservative side
    // for a coverage check; a refit that wants its own measurement puts a variance stage first.
    let mut stages = cv.stages.clone();
    for k in 0..stages.len() {
        if !pipeline::noise_unmeasured(&stages, k) {
            continue;
        }
        let t = joint.and_then(|j| j.noise_temperature).ok_or_else(|| {
            anyhow!(
                "[[crossval.stages]] {}: temperature = \"noise\" needs a variance stage before it in [crossval], or \
                 --from a joint calibration that ran a variance stage (its measured noise is used); add one, or give \
                 the temperature as a number ≥ 1",
                k + 1
            )
        })?;
        stages[k].temperature = Some(Temperature::Value(t));
    }
    let fold = CalibrationSpec {
        name: format!("{} without {left_name}", spec.name),
        description: None,
        experiments,
        parameters,
        fixed,
        stages,
        crossval: None,
        ..spec.clone()
    };
    fold.validate().map_err(|e| anyhow!("the refit without `{left_name}`: {e}"))?;
    Ok(fold)
}

/// What one fold found.
#[derive(Debug, Clone)]
struct FoldResult {
    experiment: String,
    /// RMS per station of the best-fit prediction, K.
    rms: BTreeMap<String, f64>,
    /// Station-4 (last station's) chilldown of data and prediction, s.
    chilldown: Option<(String, Option<f64>, Option<f64>)>,
    /// The measurement's band against the measurements, or why there is no band.
    coverage: Result<Coverage, String>,
    /// The parameters' band alone (`q05`–`q95`) against the measurements.
    parameter_coverage: Option<Coverage>,
    refit_cost: Option<f64>,
}

/// Linear interpolation of `(t, lo, hi)` rows (sorted by time) at `t`; `None` outside.
fn band_at(band: &[(f64, f64, f64)], t: f64) -> Option<(f64, f64)> {
    let k = band.partition_point(|r| r.0 < t);
    if k < band.len() && band[k].0 == t {
        return Some((band[k].1, band[k].2));
    }
    if k == 0 || k >= band.len() {
        return None;
    }
    let (a, b) = (band[k - 1], band[k]);
    let w = (t - a.0) / (b.0 - a.0);
    Some((a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2)))
}

/// Per station, the band's rows `(time, 5 %, 95 %)` sorted by time.
type Bands = BTreeMap<String, Vec<(f64, f64, f64)>>;

/// The bands per station (wall temperature) from a `bands.csv`: the measurement's
/// posterior-predictive band (`p05`–`p95`) and the parameters' band (`q05`–`q95`). The first is
/// an error when the file has none (a calibration without residuals to size it).
fn read_bands(path: &Path) -> Result<(Bands, Bands)> {
    let file = path.display();
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {file}"))?;
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header = reader.headers().with_context(|| format!("{file}: unreadable header"))?.clone();
    let column =
        |name: &str| header.iter().position(|h| h == name).ok_or_else(|| anyhow!("{file}: no `{name}` column"));
    let [t, station, quantity, q05, q95, p05, p95] =
        ["time_s", "station", "quantity", "q05", "q95", "p05", "p95"].map(column);
    let (t, station, quantity, q05, q95, p05, p95) = (t?, station?, quantity?, q05?, q95?, p05?, p95?);
    let (mut predictive, mut parameters) = (Bands::new(), Bands::new());
    for record in reader.records() {
        let r = record.with_context(|| format!("{file}: unreadable row"))?;
        if r.get(quantity) != Some("wall_temperature_k") {
            continue;
        }
        let num = |i: usize| -> Option<f64> { r.get(i).and_then(|v| v.parse().ok()) };
        let (Some(time), Some(lo), Some(hi)) = (num(t), num(q05), num(q95)) else {
            bail!("{file}: a row without numbers");
        };
        let name = r.get(station).unwrap_or_default().to_string();
        parameters.entry(name.clone()).or_default().push((time, lo, hi));
        if let (Some(lo), Some(hi)) = (num(p05), num(p95)) {
            predictive.entry(name).or_default().push((time, lo, hi));
        }
    }
    if predictive.is_empty() {
        bail!("{file}: no measurement band (the refit's result.json has no wall-temperature residuals to size it)");
    }
    for v in predictive.values_mut().chain(parameters.values_mut()) {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    Ok((predictive, parameters))
}

/// How a band meets the measured wall temperatures: how many it covers, of how many within its
/// times, and its width summed over them (its sharpness: a band as wide as the whole chilldown
/// covers everything and predicts nothing).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Coverage {
    covered: usize,
    total: usize,
    width_sum_k: f64,
}

impl Coverage {
    /// Share of the measurements inside the band (NaN without measurements).
    fn share(&self) -> f64 {
        self.covered as f64 / self.total as f64
    }

    /// Mean width of the band at the measurements, K.
    fn mean_width_k(&self) -> Option<f64> {
        (self.total > 0).then(|| self.width_sum_k / self.total as f64)
    }

    fn add(self, o: Coverage) -> Coverage {
        Coverage {
            covered: self.covered + o.covered,
            total: self.total + o.total,
            width_sum_k: self.width_sum_k + o.width_sum_k,
        }
    }
}

/// The measured wall temperatures inside the band.
fn coverage(data: &Dataset, bands: &Bands) -> Coverage {
    let mut c = Coverage::default();
    for ((station, quantity), s) in &data.series {
        let Some(band) = bands.get(station).filter(|_| quantity == "wall_temperature_k") else { continue };
        for (&t, &v) in s.times.iter().zip(&s.values) {
            if let Some((lo, hi)) = band_at(band, t) {
                c.total += 1;
                c.width_sum_k += hi - lo;
                if (lo..=hi).contains(&v) {
                    c.covered += 1;
                }
            }
        }
    }
    c
}

/// Runs `cryofit crossval`.
pub fn run(args: &CrossvalArgs) -> Result<()> {
    let label = args.file.display().to_string();
    let text = std::fs::read_to_string(&args.file).with_context(|| format!("cannot read {label}"))?;
    let spec = CalibrationSpec::from_toml(&text, &label)?;
    if spec.experiments.len() < 2 {
        bail!("{label}: cross-validation leaves one experiment out in turn and needs at least two; it has one");
    }
    let joint = args.from.as_deref().map(read_joint).transpose()?;
    let base = args.file.parent().unwrap_or(Path::new(".")).canonicalize().unwrap_or_else(|_| PathBuf::from("."));
    let folds: Vec<CalibrationSpec> = (0..spec.experiments.len())
        .map(|k| fold_spec(&spec, k, joint.as_ref(), &base))
        .collect::<Result<_>>()
        .map_err(|e| anyhow!("{label}: {e:#}"))?;
    let out_dir = args.out.clone().unwrap_or_else(|| {
        let stem = args.file.file_stem().map_or_else(|| "calibration".into(), |s| s.to_string_lossy().into_owned());
        Path::new("out").join(format!("crossval-{stem}"))
    });
    // each fold's calibration file, and where its refit goes
    let mut refits = Vec::new();
    for (k, fold) in folds.iter().enumerate() {
        let name = spec.experiments[k].label(k);
        let dir = out_dir.join(format!("without-{name}"));
        let toml_text = toml::to_string(fold).context("cannot write the refit's calibration file")?;
        write_outputs(&dir, &[("calibration.toml", format!("# cryofit crossval: {}\n{toml_text}", fold.name))])?;
        let args = crate::calibrate::CalibrateArgs {
            file: dir.join("calibration.toml"),
            workers: args.workers,
            out: Some(dir.join("refit")),
            coordinator: args.coordinator.clone(),
        };
        refits.push((name, dir, args));
    }
    if let Some(url) = &args.coordinator {
        for (k, (name, _, refit)) in refits.iter().enumerate() {
            let id = crate::calibrate::submit_to_coordinator(refit)?;
            println!("fold {} of {}: refit without `{name}` is calibration {id} on {url}", k + 1, refits.len());
        }
    }
    let mut results = Vec::new();
    let mut figures = Vec::new();
    for (k, (name, dir, refit)) in refits.iter().enumerate() {
        println!("fold {} of {}: refit without `{name}`", k + 1, refits.len());
        crate::calibrate::run(refit)?;
        let (result, figure) = predict_left_out(&spec, k, &base, dir, &dir.join("refit"), args)?;
        results.push(result);
        figures.push(figure);
    }
    write_summary(&out_dir, &results, &figures)?;
    print_table(&results);
    println!("  wrote crossval.json, crossval.csv and the figures to {}", out_dir.display());
    Ok(())
}

/// Predicts experiment `k` from the refit in `fit_dir`: best fit and, where possible, the band.
fn predict_left_out(
    spec: &CalibrationSpec,
    k: usize,
    base: &Path,
    dir: &Path,
    fit_dir: &Path,
    args: &CrossvalArgs,
) -> Result<(FoldResult, Figure)> {
    let e = &spec.experiments[k];
    let name = e.label(k);
    let (case, data_path) = (base.join(&e.case), base.join(&e.data));
    let best_dir = dir.join("prediction-best");
    crate::simulate::run(&crate::simulate::SimulateArgs {
        case: case.clone(),
        out: Some(best_dir.clone()),
        set: Vec::new(),
        params: Some(fit_dir.join("best.toml")),
        experiment: Some(name.clone()),
        noise: Vec::new(),
        seed: 0,
        data: Some(data_path.clone()),
        step_log: false,
    })?;
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(best_dir.join("summary.json")).context("cannot read the prediction's summary.json")?,
    )?;
    let rms = summary["fit"]["series"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter(|s| s["quantity"] == "wall_temperature_k")
                .filter_map(|s| Some((s["station"].as_str()?.to_string(), s["rms"].as_f64()?)))
                .collect()
        })
        .unwrap_or_default();
    let chilldown = summary["fit"]["chilldown"].as_object().and_then(|m| {
        let (station, v) = m.iter().max_by(|a, b| a.0.cmp(b.0))?;
        Some((station.clone(), v["data_s"].as_f64(), v["model_s"].as_f64()))
    });
    let band_dir = dir.join("prediction-band");
    let band = crate::predict::run(&crate::predict::PredictArgs {
        case,
        from: fit_dir.to_path_buf(),
        samples: args.samples,
        seed: args.seed,
        out: Some(band_dir.clone()),
        experiment: Some(name.clone()),
    })
    .and_then(|()| read_bands(&band_dir.join("bands.csv")));
    let data_label = data_path.display().to_string();
    let data = Dataset::from_csv(
        &std::fs::read_to_string(&data_path).with_context(|| format!("cannot read {data_label}"))?,
        &data_label,
    )?;
    let parameter_coverage = band.as_ref().ok().map(|(_, b)| coverage(&data, b));
    let coverage = match &band {
        Ok((b, _)) => Ok(coverage(&data, b)),
        Err(why) => Err(format!("{why:#}")),
    };
    let refit: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fit_dir.join("result.json")).unwrap_or_default())
            .unwrap_or_default();
    let probes_path = best_dir.join("probes.csv");
    let probes = Dataset::from_csv(
        &std::fs::read_to_string(&probes_path).with_context(|| format!("cannot read {}", probes_path.display()))?,
        &probes_path.display().to_string(),
    )?;
    let panels = data
        .series
        .iter()
        .filter(|((_, q), _)| q == "wall_temperature_k")
        .map(|((station, q), s)| StationPanel {
            station: station.clone(),
            x_m: None,
            data: s.times.iter().copied().zip(s.values.iter().copied()).collect(),
            model: probes
                .series
                .get(&(station.clone(), q.clone()))
                .map(|m| m.times.iter().copied().zip(m.values.iter().copied()).collect())
                .unwrap_or_default(),
            band: band.as_ref().ok().and_then(|(b, _)| b.get(station).cloned()),
        })
        .collect();
    let note = match &coverage {
        Ok(c) if c.total > 0 => format!(
            "band covers {:.0} % of the measurements, {:.0} K wide on average",
            100.0 * c.share(),
            c.mean_width_k().unwrap_or(f64::NAN)
        ),
        Ok(_) => "the band and the measurements do not overlap in time".into(),
        Err(_) => "no band (crossval.json says why)".into(),
    };
    let figure = Figure {
        name: format!("crossval-{}", name.replace(|c: char| !c.is_ascii_alphanumeric() && c != '-', "-")),
        title: format!("{name}, predicted without it"),
        plot: Ok(Plot::Fit(FitPanels {
            title: format!("{}: {name} predicted by the refit without it — {note}", spec.name),
            value_label: "wall temperature (K)".into(),
            value_scale: 1.0,
            band_label: format!(
                "5–95 % band of a measurement ({} runs; the refit's clock and shape errors)",
                args.samples
            ),
            panels,
        })),
    };
    let result = FoldResult {
        experiment: name,
        rms,
        chilldown,
        coverage,
        parameter_coverage,
        refit_cost: refit["best_cost"].as_f64(),
    };
    Ok((result, figure))
}

fn write_summary(out_dir: &Path, results: &[FoldResult], figures: &[Figure]) -> Result<()> {
    let folds: Vec<serde_json::Value> = results
        .iter()
        .map(|r| {
            let (station, data, model) = r.chilldown.clone().unwrap_or_default();
            let error = data.zip(model).map(|(d, m)| (m - d) / d);
            json!({
                "left_out": r.experiment, "refit_cost": r.refit_cost, "rms_k": r.rms,
                "chilldown": {"station": station, "data_s": data, "model_s": model, "relative_error": error},
                "band": match &r.coverage {
                    Ok(c) => json!({"covered": c.covered, "measurements": c.total, "mean_width_k": c.mean_width_k(),
                        "covered_by_parameter_band": r.parameter_coverage.map(|p| p.covered),
                        "parameter_band_mean_width_k": r.parameter_coverage.and_then(|p| p.mean_width_k())}),
                    Err(why) => json!({"none": why}),
                },
            })
        })
        .collect();
    let errors: Vec<f64> = results
        .iter()
        .filter_map(|r| r.chilldown.as_ref().and_then(|(_, d, m)| Some(((*m)? - (*d)?).abs() / (*d)?)))
        .collect();
    let all = results.iter().filter_map(|r| r.coverage.as_ref().ok()).fold(Coverage::default(), |a, c| a.add(*c));
    let (covered, total) = (all.covered, all.total);
    let parameter_covered: usize = results.iter().filter_map(|r| r.parameter_coverage.map(|p| p.covered)).sum();
    let summary = json!({
        "folds": folds,
        "mean_absolute_chilldown_error": (!errors.is_empty()).then(|| errors.iter().sum::<f64>() / errors.len() as f64),
        "band_coverage": (total > 0).then(|| covered as f64 / total as f64),
        "parameter_band_coverage": (total > 0).then(|| parameter_covered as f64 / total as f64),
        "band_mean_width_k": all.mean_width_k(),
        "folds_with_band": results.iter().filter(|r| r.coverage.is_ok()).count(),
    });
    let mut csv = CsvText::new([
        "left_out",
        "station",
        "rms_k",
        "chilldown_data_s",
        "chilldown_model_s",
        "covered",
        "measurements",
        "covered_by_parameter_band",
        "band_mean_width_k",
    ])?;
    for r in results {
        let (cs, d, m) = r.chilldown.clone().unwrap_or_default();
        let (c, t, w) = r.coverage.as_ref().map_or((String::new(), String::new(), String::new()), |c| {
            (c.covered.to_string(), c.total.to_string(), c.mean_width_k().map(fmt_num).unwrap_or_default())
        });
        let pc = r.parameter_coverage.map(|c| c.covered.to_string()).unwrap_or_default();
        for (station, rms) in &r.rms {
            let last = *station == cs;
            let opt = |v: Option<f64>| if last { v.map(fmt_num).unwrap_or_default() } else { String::new() };
            csv.row([r.experiment.as_str(), station, &fmt_num(*rms), &opt(d), &opt(m), &c, &t, &pc, &w])?;
        }
    }
    let mut files: Vec<(String, Vec<u8>)> = vec![
        ("crossval.json".into(), (serde_json::to_string_pretty(&summary)? + "\n").into_bytes()),
        ("crossval.csv".into(), csv.finish()?.into_bytes()),
    ];
    for f in figures {
        if let Ok(p) = &f.plot {
            files.push((format!("{}.svg", f.name), p.svg().map_err(|e| anyhow!("{}: {e}", f.name))?.into_bytes()));
            files.push((format!("{}.png", f.name), p.png().map_err(|e| anyhow!("{}: {e}", f.name))?));
        }
    }
    write_outputs(out_dir, &files)
}

fn print_table(results: &[FoldResult]) {
    println!("cross-validation: each experiment predicted by the refit without it");
    for r in results {
        let rms: Vec<String> = r.rms.iter().map(|(s, v)| format!("{s} {v:.1}")).collect();
        let chill = match &r.chilldown {
            Some((s, Some(d), Some(m))) => {
                format!("{s} chilldown {m:.1} s against {d:.1} s ({:+.1} %)", 100.0 * (m - d) / d)
            }
            Some((s, d, m)) => {
                let t = |v: &Option<f64>| v.map_or_else(|| "not reached".to_string(), |x| format!("{x:.1} s"));
                format!("{s} chilldown: model {}, data {}", t(m), t(d))
            }
            None => "no chilldown".into(),
        };
        let band = match &r.coverage {
            Ok(c) if c.total > 0 => {
                let own = r.parameter_coverage.map_or_else(String::new, |p| {
                    format!("; the parameters' band alone {:.0} %", 100.0 * p.covered as f64 / c.total as f64)
                });
                format!(
                    "band covers {} of {} ({:.0} %{own}), {:.1} K wide on average",
                    c.covered,
                    c.total,
                    100.0 * c.share(),
                    c.mean_width_k().unwrap_or(f64::NAN)
                )
            }
            Ok(_) => "band and data do not overlap".into(),
            Err(why) => format!("no band ({why})"),
        };
        println!("  {}: RMS (K) {}; {chill}; {band}", r.experiment, rms.join(", "));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shared fixed case fields reach every refit; a left-out experiment's own is refused, naming it.
    #[test]
    fn fixed_case_fields_reach_the_refits_or_are_refused_for_the_left_out() {
        let text = "name = \"cv\"\n[[experiments]]\ncase = \"a.toml\"\ndata = \"a.csv\"\n[[experiments]]\n\
                    case = \"b.toml\"\ndata = \"b.csv\"\n[[parameters]]\nname = \"Gwsc\"\n[fixed]\n\
                    \"case.pipe.cells\" = 60\n\"case.inlet.loss_coefficient@b\" = 7.0\n[[stages]]\n\
                    algorithm = \"cmaes\"\nbudget = 10\n[[crossval.stages]]\nalgorithm = \"cmaes\"\nbudget = 6\n";
        let spec = CalibrationSpec::from_toml(text, "cv.toml").unwrap();
        let base = Path::new("/runs");
        let fold = fold_spec(&spec, 0, None, base).unwrap();
        assert_eq!(fold.fixed.get("case.pipe.cells"), Some(&60.0));
        assert_eq!(fold.fixed.get("case.inlet.loss_coefficient@b"), Some(&7.0));
        fold.validate().unwrap();
        let e = fold_spec(&spec, 1, None, base).unwrap_err().to_string();
        assert!(e.starts_with("fixed.case.inlet.loss_coefficient@b: "), "{e}");
        assert!(e.contains("set the value in its case file"), "{e}");
    }

    #[test]
    fn copies_are_read_as_their_entry_and_experiment() {
        assert_eq!(entry_of("Gwsc"), ("Gwsc", None));
        assert_eq!(entry_of("case.inlet.loss_coefficient"), ("case.inlet.loss_coefficient", None));
        assert_eq!(entry_of("case.inlet.loss_coefficient@run-b"), ("case.inlet.loss_coefficient", Some("run-b")));
    }

    #[test]
    fn the_band_is_read_between_its_times() {
        let band = [(0.0, 1.0, 3.0), (1.0, 3.0, 5.0)];
        assert_eq!(band_at(&band, 0.5), Some((2.0, 4.0)));
        assert_eq!(band_at(&band, 1.0), Some((3.0, 5.0)));
        assert_eq!(band_at(&band, 1.5), None);
        assert_eq!(band_at(&band, -0.1), None);
    }

    #[test]
    fn coverage_counts_the_measurements_inside_and_sums_the_width() {
        let mut data = Dataset::default();
        data.series.insert(
            ("TS1".into(), "wall_temperature_k".into()),
            cryofit_calib::data::Series { x_m: 1.0, times: vec![0.0, 0.5, 1.0, 2.0], values: vec![2.0, 1.0, 4.0, 9.0] },
        );
        let bands = Bands::from([("TS1".to_string(), vec![(0.0, 1.0, 3.0), (1.0, 3.0, 5.0)])]);
        // 2.0 in [1, 3]; 1.0 below [2, 4]; 4.0 in [3, 5]; 2 s is past the band
        let c = coverage(&data, &bands);
        assert_eq!((c.covered, c.total), (2, 3));
        assert_eq!(c.mean_width_k(), Some(2.0));
        assert_eq!(Coverage::default().mean_width_k(), None);
    }
}
