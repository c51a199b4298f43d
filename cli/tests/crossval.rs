//! `cryofit crossval` end to end on a CI-sized pair of runs: a joint calibration of two drive
//! pressures of the same line (twin data), then each run left out in turn, refitted without and
//! predicted; and the errors of a calibration file that cannot be cross-validated.

use std::path::Path;

mod common;
use common::{cryofit, ok, scratch, small_nbs_case, wall_data};

/// The NBS subcooled case cut to CI size (10 cells, 240 s: at 340 kPa its station-4 chilldown comes
/// at about 198 s) at dewar pressure `p` (Pa), and its twin data: wall temperatures simulated at
/// Gwsc = 0.8, every 2 s.
fn run_of(dir: &Path, name: &str, p: &str) {
    let pressure = format!("pressure_pa = {p}");
    let case = small_nbs_case(dir, &format!("{name}.toml"), 240.0, &[("pressure_pa = 425565.0", &pressure)]);
    let truth = dir.join(format!("truth-{name}"));
    ok(&cryofit(&["simulate", case.to_str().unwrap(), "--set", "Gwsc=0.8", "--out", truth.to_str().unwrap()]));
    let data = wall_data(&std::fs::read_to_string(truth.join("probes.csv")).unwrap());
    std::fs::write(dir.join(format!("{name}-data.csv")), data).unwrap();
}

const JOINT: &str = r#"
name = "pair"
seed = 5
[[experiments]]
case = "high.toml"
data = "high-data.csv"
[[experiments]]
case = "low.toml"
data = "low-data.csv"
[[parameters]]
name = "Gwsc"
scale = "log"
[weights]
wall_temperature_k = { weight = 1.0, sigma = 3.0 }
[[stages]]
algorithm = "cmaes"
budget = 16
population = 4
sigma = 0.2
[[stages]]
algorithm = "variance"
budget = 14
step = 0.06
restarts = 1
[[crossval.stages]]
algorithm = "cmaes"
budget = 8
population = 4
sigma = 0.05
[[crossval.stages]]
algorithm = "mcmc"
budget = 12
walkers = 4
burn_in = 0.25
spread = 0.02
temperature = "noise"
"#;

#[test]
fn each_run_is_refitted_without_itself_and_predicted() {
    let dir = scratch("crossval", "pair");
    run_of(&dir, "high", "425565.0");
    run_of(&dir, "low", "340000.0");
    let file = dir.join("pair.toml");
    std::fs::write(&file, JOINT).unwrap();
    let joint = dir.join("joint");
    ok(&cryofit(&["calibrate", file.to_str().unwrap(), "--workers", "2", "--out", joint.to_str().unwrap()]));
    let best: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(joint.join("result.json")).unwrap()).unwrap();
    let best_gwsc = best["best_parameters"]["Gwsc"].as_f64().unwrap();
    let joint_t = best["stages"][1]["details"]["variance"]["gaussian"]["noise_inflation"].as_f64().unwrap_or(1.0);

    let cv = dir.join("cv");
    let stdout = ok(&cryofit(&[
        "crossval",
        file.to_str().unwrap(),
        "--from",
        joint.to_str().unwrap(),
        "--out",
        cv.to_str().unwrap(),
        "--workers",
        "2",
        "--samples",
        "6",
    ]));
    println!("{stdout}");
    assert!(stdout.contains("cross-validation: each experiment predicted by the refit without it"), "{stdout}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cv.join("crossval.json")).unwrap()).unwrap();
    let folds = summary["folds"].as_array().unwrap();
    assert_eq!(folds.len(), 2);
    for (fold, (name, other)) in folds.iter().zip([("high", "low"), ("low", "high")]) {
        assert_eq!(fold["left_out"], name);
        assert_eq!(fold["rms_k"].as_object().unwrap().len(), 4, "{fold}");
        assert_eq!(fold["chilldown"]["station"], "TS4");
        // the refit: the other run only, starting at the joint optimum
        let refit = std::fs::read_to_string(cv.join(format!("without-{name}/calibration.toml"))).unwrap();
        assert!(refit.contains(&format!("{other}.toml")) && !refit.contains(&format!("{name}.toml")), "{refit}");
        assert!(refit.contains(&format!("start = {best_gwsc}")), "{refit}");
        // the refit's MCMC stage is tempered by the jitter the joint's variance stage measured
        assert!(refit.contains(&format!("temperature = {joint_t:?}")), "{joint_t} {refit}");
        // twin data, one parameter: the left-out run is predicted closely
        for (station, rms) in fold["rms_k"].as_object().unwrap() {
            assert!(rms.as_f64().unwrap() < 10.0, "{name} {station}: RMS {rms}");
        }
        // an MCMC posterior always gives a band, with its coverage
        let band = &fold["band"];
        let n = band["measurements"].as_u64().filter(|&n| n > 0).unwrap_or_else(|| panic!("{band}"));
        let (c, p) = (band["covered"].as_u64().unwrap(), band["covered_by_parameter_band"].as_u64().unwrap());
        assert!(p <= n && c <= n, "{band}");
        // and its sharpness: its mean width at the measurements
        assert!(band["mean_width_k"].as_f64().is_some_and(|w| w > 0.0 && w.is_finite()), "{band}");
        let figure = cv.join(format!("crossval-{name}.svg"));
        assert!(std::fs::read_to_string(&figure).unwrap().contains("predicted by the refit without it"));
    }
    assert!(summary["mean_absolute_chilldown_error"].as_f64().is_some(), "{summary}");
    let csv = std::fs::read_to_string(cv.join("crossval.csv")).unwrap();
    assert!(csv.starts_with(
        "left_out,station,rms_k,chilldown_data_s,chilldown_model_s,covered,measurements,covered_by_parameter_band,\
         band_mean_width_k\n"
    ));
    assert_eq!(csv.lines().count(), 1 + 8);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_file_that_cannot_be_cross_validated_is_refused_with_the_reason() {
    let dir = scratch("crossval", "refused");
    let file = dir.join("pair.toml");
    let without = JOINT.split("[[crossval.stages]]").next().unwrap().to_string();
    std::fs::write(&file, &without).unwrap();
    // (the cases are not read before the file's own checks pass)
    let out = cryofit(&["crossval", file.to_str().unwrap(), "--out", dir.join("cv").to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no [crossval] table") && err.contains("[[crossval.stages]]"), "{err}");
    // a refit tempered by "noise" measures it itself or takes the joint calibration's (--from)
    std::fs::write(&file, JOINT).unwrap();
    let out = cryofit(&["crossval", file.to_str().unwrap(), "--out", dir.join("cv").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("[[crossval.stages]] 2: temperature = \"noise\""), "{err}");
    assert!(err.contains("--from"), "{err}");
    let one = without.replace("[[experiments]]\ncase = \"low.toml\"\ndata = \"low-data.csv\"\n", "");
    std::fs::write(&file, one).unwrap();
    let out = cryofit(&["crossval", file.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("needs at least two; it has one"));
    assert!(!dir.join("cv").exists(), "nothing written for a refused file");
    std::fs::remove_dir_all(&dir).ok();
}
