//! `cryofit compare DIR DIR [DIR ...] [--json]`: calibrations of the same data, fitted with
//! different models (other correlations, another reading of a case's boundary data, other free
//! parameters), side by side — best cost, AIC, BIC and the Laplace evidence with Bayes factors
//! and model probabilities (paper, "Probabilistic framework", eq. "bayes_model"; the criteria are
//! `cryofit_calib::inference::compare`).
//!
//! Each DIR is a `cryofit calibrate` output folder; its `result.json` gives the best cost `S_min`,
//! the number of data points `N` and the free parameters `k` of its last stage. The Laplace
//! evidence needs a variance stage whose Hessian is positive definite; a calibration without one
//! still gets its AIC and BIC, and the reason its evidence is missing is printed.
//!
//! Decision: the calibrations must be fits to the same data under the same weights, or their
//! costs are not comparable: the command refuses folders whose data point counts, weights or data
//! file names differ, naming the first difference.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use cryofit_calib::inference::InferenceSummary;
use cryofit_calib::inference::{aic, bic, laplace_log_evidence};
use cryofit_calib::pipeline::StageReport;
use serde_json::json;

use crate::output::read_result_json;

/// Arguments of `cryofit compare`.
#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Two or more `cryofit calibrate` output folders, fits of the same data.
    #[arg(required = true, num_args = 2.., value_name = "DIR")]
    dirs: Vec<PathBuf>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// What the comparison needs of one calibration.
#[derive(Debug, Clone, PartialEq)]
struct Fit {
    /// The folder as given.
    name: String,
    s_min: f64,
    n_data: usize,
    k: usize,
    /// The Laplace log evidence, or why there is none.
    log_evidence: Result<f64, String>,
    /// The variance stage's measure of the cost's jitter near the optimum, cost units.
    noise: Option<f64>,
    /// For the same-data check: the weights and the data files' names.
    weights: serde_json::Value,
    data_files: Vec<String>,
}

/// Reads one output folder's `result.json`.
fn read_fit(dir: &Path) -> Result<Fit> {
    let (path, result) = read_result_json(dir, "")?;
    let field = |name: &str| anyhow!("{}: `{name}` is missing or not a number", path.display());
    let s_min = result["best_cost"].as_f64().ok_or_else(|| field("best_cost"))?;
    let n_data = result["data_points"].as_u64().ok_or_else(|| field("data_points"))? as usize;
    let reports: Vec<StageReport> = serde_json::from_value(result["stages"].clone())
        .with_context(|| format!("{}: `stages` cannot be read", path.display()))?;
    let last = reports.last().ok_or_else(|| anyhow!("{}: the calibration ran no stage", path.display()))?;
    let variance = reports.iter().rev().find_map(|r| match &r.details {
        Some(InferenceSummary::Variance(v)) => Some((r, v)),
        _ => None,
    });
    let (k, log_evidence) = match variance {
        None => (last.free.len(), Err("no variance stage".to_string())),
        Some((r, v)) => match &v.gaussian {
            None => (r.free.len(), Err("the variance stage gave no Hessian".to_string())),
            Some(g) if !g.positive_definite => (
                r.free.len(),
                Err(format!(
                    "the variance stage's Hessian is not positive definite ({} of {} directions)",
                    g.regularised,
                    g.eigenvalues.len()
                )),
            ),
            // the evidence at the Hessian's centre, whose cost the Hessian expands
            Some(g) => (r.free.len(), laplace_log_evidence(g.cost, &g.hessian_unit, 0.0).map_err(|e| e.to_string())),
        },
    };
    let spec = &result["calibration"];
    let noise = variance.and_then(|(_, v)| v.gaussian.as_ref()).and_then(|g| g.cost_noise);
    let data_files = spec["experiments"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|e| {
                    let d = e["data"].as_str().unwrap_or_default();
                    Path::new(d).file_name().map_or(d.to_string(), |f| f.to_string_lossy().into_owned())
                })
                .collect()
        })
        .unwrap_or_default();
    Ok(Fit {
        name: dir.display().to_string(),
        s_min,
        n_data,
        k,
        log_evidence,
        noise,
        weights: spec["weights"].clone(),
        data_files,
    })
}

/// Refuses fits that are not of the same data, naming the first difference.
fn same_data(fits: &[Fit]) -> Result<()> {
    let first = &fits[0];
    for f in &fits[1..] {
        if f.n_data != first.n_data {
            bail!(
                "{} fits {} data points and {} fits {}: the costs of different data cannot be compared",
                first.name,
                first.n_data,
                f.name,
                f.n_data
            );
        }
        if f.weights != first.weights {
            bail!(
                "{} and {} weigh the data differently (result.json: calibration.weights {} against {}): their costs \
                 are not on one scale",
                first.name,
                f.name,
                first.weights,
                f.weights
            );
        }
        if f.data_files != first.data_files {
            bail!(
                "{} fits the data files {:?} and {} fits {:?}: compare calibrations of the same experiments",
                first.name,
                first.data_files,
                f.name,
                f.data_files
            );
        }
    }
    Ok(())
}

/// One row of the comparison.
#[derive(Debug, Clone, PartialEq)]
struct Row {
    aic: f64,
    bic: f64,
    delta_aic: f64,
    delta_bic: f64,
    /// `ln Z − ln Z_best` and the model probability (equal prior odds) among the models that
    /// have an evidence.
    log_bayes_factor: Option<f64>,
    probability: Option<f64>,
}

fn rows(fits: &[Fit]) -> Vec<Row> {
    let aics: Vec<f64> = fits.iter().map(|f| aic(f.s_min, f.k)).collect();
    let bics: Vec<f64> = fits.iter().map(|f| bic(f.s_min, f.k, f.n_data)).collect();
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let (min_aic, min_bic) = (min(&aics), min(&bics));
    let best_lz = fits.iter().filter_map(|f| f.log_evidence.as_ref().ok().copied()).fold(f64::NEG_INFINITY, f64::max);
    let norm: f64 = fits.iter().filter_map(|f| f.log_evidence.as_ref().ok()).map(|lz| (lz - best_lz).exp()).sum();
    fits.iter()
        .enumerate()
        .map(|(i, f)| {
            let lbf = f.log_evidence.as_ref().ok().map(|lz| lz - best_lz);
            Row {
                aic: aics[i],
                bic: bics[i],
                delta_aic: aics[i] - min_aic,
                delta_bic: bics[i] - min_bic,
                log_bayes_factor: lbf,
                probability: lbf.map(|l| l.exp() / norm),
            }
        })
        .collect()
}

/// Runs `cryofit compare`.
pub fn run(args: &CompareArgs) -> Result<()> {
    let fits: Vec<Fit> = args.dirs.iter().map(|d| read_fit(d)).collect::<Result<_>>()?;
    same_data(&fits)?;
    let rows = rows(&fits);
    if args.json {
        let models: Vec<serde_json::Value> = fits
            .iter()
            .zip(&rows)
            .map(|(f, r)| {
                json!({
                    "calibration": f.name, "s_min": f.s_min, "k": f.k, "n_data": f.n_data,
                    "aic": r.aic, "bic": r.bic, "delta_aic": r.delta_aic, "delta_bic": r.delta_bic,
                    "log_evidence": f.log_evidence.as_ref().ok(), "no_evidence": f.log_evidence.as_ref().err(),
                    "log_bayes_factor": r.log_bayes_factor, "probability": r.probability, "cost_noise": f.noise,
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&json!({ "models": models }))?);
        return Ok(());
    }
    println!("{} calibrations of the same {} data points:", fits.len(), fits[0].n_data);
    println!(
        "  {:<40} {:>12} {:>3} {:>12} {:>12} {:>14} {:>12}",
        "calibration", "S_min", "k", "ΔAIC", "ΔBIC", "ln Bayes factor", "probability"
    );
    for (f, r) in fits.iter().zip(&rows) {
        println!(
            "  {:<40} {:>12} {:>3} {:>12} {:>12} {:>14} {:>12}",
            f.name,
            format!("{:.2}", f.s_min),
            f.k,
            format!("{:.2}", r.delta_aic),
            format!("{:.2}", r.delta_bic),
            r.log_bayes_factor.map_or("—".into(), |v| format!("{v:.2}")),
            r.probability.map_or("—".into(), |v| format!("{v:.3}")),
        );
    }
    for f in &fits {
        if let Err(why) = &f.log_evidence {
            println!("  {}: no Laplace evidence: {why}", f.name);
        }
    }
    if let Some(noise) = fits.iter().filter_map(|f| f.noise).reduce(f64::max) {
        println!(
            "  the cost jitters by up to {noise:.2} between nearby parameter sets (the variance stages' cost noise): \
             differences of S_min, AIC, BIC or 2 ln Z below a few times that are within the jitter, not evidence"
        );
    }
    println!(
        "  (AIC = S_min + 2k, BIC = S_min + k ln N, evidence by the Laplace approximation at the variance stage's \
         optimum with a uniform prior on the unit box; the smallest AIC and BIC and the largest evidence are preferred)"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fit(name: &str, s_min: f64, k: usize, lz: Result<f64, String>) -> Fit {
        Fit {
            name: name.into(),
            s_min,
            n_data: 100,
            k,
            log_evidence: lz,
            noise: None,
            weights: json!({"wall_temperature_k": {"weight": 1.0, "sigma": 3.0}}),
            data_files: vec!["a.csv".into()],
        }
    }

    #[test]
    fn criteria_prefer_the_lower_cost_and_penalise_parameters() {
        let fits =
            [fit("a", 120.0, 2, Ok(-70.0)), fit("b", 110.0, 6, Ok(-68.0)), fit("c", 130.0, 1, Err("none".into()))];
        let r = rows(&fits);
        // AIC: 124, 122, 132; BIC: 120 + 2 ln 100 = 129.2, 110 + 6 ln 100 = 137.6, 134.6
        assert_eq!((r[1].delta_aic, r[0].delta_aic), (0.0, 2.0));
        assert!(r[0].delta_bic == 0.0 && (r[1].delta_bic - (4.0 * 100f64.ln() - 10.0)).abs() < 1e-12);
        assert_eq!(
            (r[1].log_bayes_factor, r[0].log_bayes_factor, r[2].log_bayes_factor),
            (Some(0.0), Some(-2.0), None)
        );
        let p = 1.0 / (1.0 + (-2.0f64).exp());
        assert!((r[1].probability.unwrap() - p).abs() < 1e-12 && r[2].probability.is_none());
    }

    #[test]
    fn fits_of_other_data_are_refused_naming_the_difference() {
        let a = fit("a", 1.0, 1, Ok(0.0));
        let mut b = fit("b", 1.0, 1, Ok(0.0));
        assert!(same_data(&[a.clone(), b.clone()]).is_ok());
        b.n_data = 99;
        let e = same_data(&[a.clone(), b.clone()]).unwrap_err().to_string();
        assert!(e.contains("100 data points") && e.contains("99"), "{e}");
        b.n_data = 100;
        b.weights = json!({"wall_temperature_k": {"weight": 1.0, "sigma": 1.0}});
        assert!(same_data(&[a.clone(), b.clone()]).unwrap_err().to_string().contains("weigh the data differently"));
        b.weights = a.weights.clone();
        b.data_files = vec!["other.csv".into()];
        assert!(same_data(&[a, b]).unwrap_err().to_string().contains("other.csv"));
    }
}
