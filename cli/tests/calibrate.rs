//! `cryofit calibrate` and `cryofit predict` end to end: a twin experiment (data simulated at
//! known parameter values plus noise, then fitted), predictions over its posterior, and bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::{cryofit, ok, small_nbs_case, small_nbs_case_from, wall_data};

/// True values of the twin experiment: the dry-wall gas convection scale (the vapour's pre-cooling
/// ahead of the front) and the wall friction scale (the line's flow, and with it the front's
/// speed), two effects the wall traces tell apart. (The film-boiling scale qmfbsc trades off
/// against Gwsc or Tmfbsc along a valley of equal cost on this case: those twins fit to the noise
/// level 8–17 % away from the truth. The wall mass-transfer scale Gwsc, this twin's second
/// parameter before, hardly shows in it: with steps of at most 1 ms its station-4 chilldown moves
/// by 0.26 s from Gwsc 0.6 to 1.0, against a one-ulp spread with a standard deviation of 0.2 s at
/// the default steps; the 0.66 s it moved under the 25 % velocity rule was the steps', and the
/// test passed or failed with the seed.)
const TRUE_HG0SC: f64 = 2.0;
/// Above 1: more friction than the defaults, less flow.
const TRUE_FWSC: f64 = 1.3;

/// Writes data simulated at the true values with 1 K of noise on the wall temperatures.
fn twin_data(dir: &Path, case: &Path) -> PathBuf {
    let truth = dir.join("truth");
    ok(&cryofit(&[
        "simulate",
        case.to_str().unwrap(),
        "--set",
        &format!("hg0sc={TRUE_HG0SC}"),
        "--set",
        &format!("fwsc={TRUE_FWSC}"),
        "--noise",
        "wall_temperature_k=1.0",
        "--seed",
        "5",
        "--out",
        truth.to_str().unwrap(),
    ]));
    let probes = std::fs::read_to_string(truth.join("probes.csv")).unwrap();
    let data = format!(
        "# twin data: simulated at hg0sc = {TRUE_HG0SC}, fwsc = {TRUE_FWSC}, noise 1 K\n{}",
        wall_data(&probes)
    );
    let path = dir.join("data.csv");
    std::fs::write(&path, data).unwrap();
    path
}

const TWIN: &str = r#"
name = "twin"
seed = 2
[[experiments]]
case = "case.toml"
data = "data.csv"
[[parameters]]
name = "hg0sc"
scale = "log"
[[parameters]]
name = "fwsc"
scale = "log"
[weights]
wall_temperature_k = { weight = 1.0, sigma = 1.0 }
[[stages]]
algorithm = "cmaes"
budget = 150
# finite differences over 6 % of each (log) range: at 3 % the cost's jitter (about 14 units on the
# subcooled case this twin was first made on) outweighed the curvature along the valley of hg0sc
# and the wall mass-transfer scale Gwsc and the Hessian came out indefinite
[[stages]]
algorithm = "variance"
budget = 40
step = 0.06
restarts = 1
"#;

/// Twin experiment: CMA-ES recovers both parameters (within 5 %, or two standard deviations where
/// the data pin one more loosely); the variance stage's Hessian is positive definite and its 95 %
/// intervals (widened for the simulation's numerical noise) cover both true values; the outputs are complete and best.toml reproduces the best fit.
#[test]
fn twin_experiment_recovers_the_truth_and_predicts() {
    let dir = common::scratch("calibrate", "twin");
    // the saturated 3.4 atm run, cut to 10 cells and 260 s (its station-4 chilldown comes at about
    // 233 s): a saturated inlet flashes where a subcooled one geysers, and the geysering of a
    // 10-cell subcooled inlet (6 m cells) makes the cost jitter between parameter sets one ulp
    // apart by as much as its curvature over the variance stage's steps (BENCHMARKS.md, "The inlet
    // junction's donor by what crosses it"); here the one-ulp spread of the chilldown has a
    // standard deviation of 0.1 s
    let case = small_nbs_case_from("saturated-3.4atm.toml", &dir, "case.toml", 260.0, &[]);
    twin_data(&dir, &case);
    let file = dir.join("twin.toml");
    std::fs::write(&file, TWIN).unwrap();
    let out_dir = dir.join("out");
    let stdout =
        ok(&cryofit(&["calibrate", file.to_str().unwrap(), "--workers", "2", "--out", out_dir.to_str().unwrap()]));
    println!("{stdout}");
    assert!(stdout.contains("best parameters:") && stdout.contains("fit:"), "{stdout}");

    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["uncertainty"]["positive_definite"], true, "the intervals are estimates, not placeholders");
    // CMA-ES's lowest evaluation within 5 % of the truth, or within two of the variance
    // stage's standard deviations where the data pin a parameter more loosely than that, and
    // every standard deviation below a quarter of the truth (the data do identify both); the
    // reported estimate, the variance stage's response-surface minimum, within its 95 % interval.
    // (That estimate is a quadratic fitted through the cost's jitter. The data pin fwsc to
    // 0.3 % and hg0sc to about 7 %: over the seeds 2, 3 and 4, on this solver and the one before
    // (its step control of the velocities by the 25 % rule), CMA-ES found fwsc within 0.4 % of
    // its truth each time, and hg0sc within 5 % but once, at 1.63 with the seed 4, where the
    // flat side of its valley and the jitter met; the Gwsc of the twin before had 15 % and
    // passed or failed with the seed.)
    let found = &result["stages"][0]["best_parameters"];
    for (name, truth) in [("hg0sc", TRUE_HG0SC), ("fwsc", TRUE_FWSC)] {
        let cmaes = found[name].as_f64().unwrap();
        let best = result["best_parameters"][name].as_f64().unwrap();
        let u = &result["uncertainty"]["parameters"][name];
        let (lo, hi, sd) = (u["lower95"].as_f64().unwrap(), u["upper95"].as_f64().unwrap(), u["sd"].as_f64().unwrap());
        assert!(sd < 0.25 * truth, "{name}: standard deviation {sd} against truth {truth}: not identified");
        let tolerance = (0.05 * truth).max(2.0 * sd);
        assert!((cmaes - truth).abs() < tolerance, "{name}: CMA-ES found {cmaes}, truth {truth} (sd {sd})");
        assert!(lo <= truth && truth <= hi, "{name}: truth {truth} outside [{lo}, {hi}] (best {best})");
    }
    // 150 + 40 where the variance stage's last evaluation is at its response surface's minimum,
    // which it then takes as the estimate; 150 + 39 where that minimum lies outside the
    // evaluations the surface was fitted to and is not used. The stage says which; where the
    // cost's jitter falls decides it (with a part-open valve's heat booked on its open area,
    // the second)
    let surface_used = stdout.contains("response surface minimum taken as the estimate");
    assert!(surface_used || stdout.contains("response surface minimum not used"), "{stdout}");
    let expected: u64 = if surface_used { 190 } else { 189 };
    assert_eq!(result["evaluations"].as_u64().unwrap(), expected);
    let evaluations = std::fs::read_to_string(out_dir.join("evaluations.csv")).unwrap();
    assert_eq!(evaluations.lines().count() as u64, expected + 1);
    assert!(evaluations.starts_with("id,stage,algorithm,status,cost,hg0sc,fwsc,reason"));
    assert_eq!(result["stages"].as_array().unwrap().len(), 2);
    // best.toml is a --params file that reproduces the best fit's probes
    // the comparison reads the folder's result.json (a folder against itself: equal criteria)
    let od = out_dir.to_str().unwrap();
    let compared: serde_json::Value = serde_json::from_str(&ok(&cryofit(&["compare", od, od, "--json"]))).unwrap();
    let models = compared["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!((models[0]["k"].as_u64(), models[0]["n_data"].as_u64()), (Some(2), result["data_points"].as_u64()));
    assert!(models[0]["log_evidence"].is_f64(), "{compared}");
    assert_eq!(models[1]["probability"].as_f64(), Some(0.5));
    let again = dir.join("again");
    ok(&cryofit(&[
        "simulate",
        case.to_str().unwrap(),
        "--params",
        out_dir.join("best.toml").to_str().unwrap(),
        "--out",
        again.to_str().unwrap(),
    ]));
    let fit = std::fs::read_to_string(out_dir.join("fit-case.csv")).unwrap();
    assert_eq!(fit, std::fs::read_to_string(again.join("probes.csv")).unwrap());

    // prediction of an untested condition (a lower drive pressure) over the posterior
    let untested = dir.join("untested.toml");
    let calibrated = std::fs::read_to_string(&case).unwrap();
    assert!(calibrated.contains("pressure_pa = 344505.0"), "the case's dewar pressure changed: update this test");
    std::fs::write(&untested, calibrated.replace("pressure_pa = 344505.0", "pressure_pa = 280000.0")).unwrap();
    let pred = dir.join("pred");
    let stdout = ok(&cryofit(&[
        "predict",
        untested.to_str().unwrap(),
        "--from",
        out_dir.to_str().unwrap(),
        "--samples",
        "6",
        "--out",
        pred.to_str().unwrap(),
    ]));
    assert!(stdout.contains("TS4 chilldown"), "{stdout}");
    let bands = std::fs::read_to_string(pred.join("bands.csv")).unwrap();
    assert!(bands.starts_with("time_s,station,x_m,quantity,q05,q50,q95,p05,p95\n"));
    let p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(pred.join("prediction.json")).unwrap()).unwrap();
    // the measurement's error, from the calibration's own fit: the clock's from each series'
    // best alignment, the shape's from the misfit that alignment leaves
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_dir.join("result.json")).unwrap()).unwrap();
    let logs: Vec<f64> = result["fit"]["case"]["series"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|s| Some(s["time_scale"].as_f64()?.ln()))
        .collect();
    match p["timing_sigma_log"].as_f64() {
        Some(s) => {
            assert!(logs.len() >= 2, "{logs:?}");
            let rms = (logs.iter().map(|r| r * r).sum::<f64>() / logs.len() as f64).sqrt();
            assert!((s - rms).abs() < 1e-12 * rms.max(1e-3), "{s} against {rms}");
        }
        None => assert!(logs.len() < 2, "{logs:?} but no clock error"),
    }
    let fitted = result["fit"]["case"]["series"].as_array().unwrap();
    let sigmas = p["residual_sigma"]["series"].as_array().unwrap();
    assert_eq!(sigmas.len(), fitted.len(), "{sigmas:?}");
    for (s, f) in sigmas.iter().zip(fitted) {
        assert_eq!(s["station"], f["station"]);
        let own = if p["timing_sigma_log"].is_null() { &f["rms"] } else { &f["time_scaled_rms"] };
        let own = own.as_f64().or(f["rms"].as_f64()).unwrap();
        assert!((s["sigma"].as_f64().unwrap() - own).abs() < 1e-9 * own, "{s} against {f}");
    }
    let mut at_start = 0;
    for line in bands.lines().skip(1).filter(|l| l.contains("wall_temperature_k")) {
        let v: Vec<f64> = line.split(',').skip(4).map(|x| x.parse().unwrap()).collect();
        assert!(v[0] <= v[1] && v[1] <= v[2] && v[3] < v[4], "{line}");
        let station = line.split(',').nth(1).unwrap();
        let sigma = sigmas.iter().find(|s| s["station"] == station).unwrap()["sigma"].as_f64().unwrap();
        // at the start every draw, at every clock, is the line's initial temperature: the band
        // is the Gaussian's alone, ±Φ⁻¹(0.95) σ
        if line.starts_with("0,") {
            assert_eq!(v[0], v[2], "{line}");
            assert!((v[3] - (v[1] - 1.644_853_6 * sigma)).abs() < 1e-3 * sigma, "{line} σ {sigma}");
            assert!((v[4] - (v[1] + 1.644_853_6 * sigma)).abs() < 1e-3 * sigma, "{line} σ {sigma}");
            at_start += 1;
        }
    }
    assert!(at_start > 0, "no band row at t = 0");
    assert_eq!(p["samples"], 6);
    assert_eq!(p["method"], "Gaussian approximation of the variance stage");
    std::fs::remove_dir_all(&dir).ok();
}

/// Bad calibration files: one line naming the file and the field, non-zero exit, nothing written.
#[test]
fn bad_calibration_files_are_refused_with_the_field_named() {
    let dir = common::scratch("calibrate", "bad");
    let case = small_nbs_case(&dir, "case.toml", 220.0, &[]);
    std::fs::write(
        dir.join("data.csv"),
        "time_s,station,x_m,quantity,value\n0,TS1,6.1,wall_temperature_k,290\n10,TS9,1,wall_temperature_k,280\n",
    )
    .unwrap();
    let cases = [
        (TWIN.replace("name = \"fwsc\"", "name = \"fwscc\""), "did you mean `fwsc`"),
        (TWIN.replace("budget = 150", "budget = 150\nwalkers = 4"), "stages[0].walkers: does not apply"),
        (TWIN.replace("sigma = 1.0 }", "sigma = -1.0 }"), "weights.wall_temperature_k.sigma"),
        (TWIN.replace("data = \"data.csv\"", "data = \"missing.csv\""), "experiments[0].data: cannot read"),
        (TWIN.to_string(), "station `TS9`"),
        (TWIN.replace("budget = 40", "budget = 3"), "budget"),
        // sizes are checked before anything is built: a stage this large would abort the process
        (
            TWIN.replace(
                "algorithm = \"cmaes\"\nbudget = 150",
                "algorithm = \"morris\"\nbudget = 150\ntrajectories = 100000000000000",
            ),
            "stages[0].trajectories",
        ),
    ];
    for (k, (text, expected)) in cases.iter().enumerate() {
        let file = dir.join(format!("bad{k}.toml"));
        std::fs::write(&file, text).unwrap();
        let out_dir = dir.join(format!("out{k}"));
        let out = cryofit(&["calibrate", file.to_str().unwrap(), "--out", out_dir.to_str().unwrap()]);
        assert!(!out.status.success(), "case {k} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "case {k}: {err}");
        assert!(err.contains(expected), "case {k}: expected `{expected}` in {err}");
        assert!(err.contains(&format!("bad{k}.toml")), "case {k}: file not named: {err}");
        assert!(!out_dir.exists(), "case {k}: output written");
    }
    // data longer than the case
    let short = std::fs::read_to_string(&case).unwrap().replace("end_s = 220.0", "end_s = 5.0");
    std::fs::write(&case, short).unwrap();
    std::fs::write(
        dir.join("data.csv"),
        "time_s,station,x_m,quantity,value\n0,TS1,6.1,wall_temperature_k,290\n10,TS1,6.1,wall_temperature_k,280\n",
    )
    .unwrap();
    let file = dir.join("short.toml");
    std::fs::write(&file, TWIN).unwrap();
    let out = cryofit(&["calibrate", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("ends at time.end_s = 5 s"), "{err}");
    // predict without a calibration folder
    let out = cryofit(&["predict", case.to_str().unwrap(), "--from", dir.join("nowhere").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("result.json"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The tiny end-to-end case of the `tests` crate (NBS subcooled, 5 cells, 8 s) with a CMA-ES
/// budget of 60 (10 generations of 6).
fn tiny_calibration(dir: &Path) -> PathBuf {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures");
    for name in ["tiny.toml", "tiny-data.csv"] {
        std::fs::copy(fixtures.join(name), dir.join(name)).unwrap();
    }
    let text =
        std::fs::read_to_string(fixtures.join("tiny-calibration.toml")).unwrap().replace("budget = 18", "budget = 60");
    assert!(text.contains("budget = 60"), "{text}");
    let file = dir.join("tiny-calibration.toml");
    std::fs::write(&file, text).unwrap();
    file
}

/// Evaluations stored in a calibration database, read as a second process would (`None` until
/// the calibration exists).
fn stored_evaluations(db: &Path) -> Option<i64> {
    use sqlx::Connection;
    if !db.exists() {
        return None;
    }
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    rt.block_on(async {
        let options = sqlx::sqlite::SqliteConnectOptions::new().filename(db).read_only(true);
        let mut c = sqlx::SqliteConnection::connect_with(&options).await.ok()?;
        let n: Option<i64> =
            sqlx::query_scalar("SELECT evaluations FROM calibrations").fetch_optional(&mut c).await.ok()?;
        let _ = c.close().await;
        n
    })
}

/// `cryofit calibrate` killed with SIGKILL mid-run and run again into the same folder resumes the
/// same calibration: it completes with exactly the budget evaluated, the same evaluations and a best
/// cost bit-identical to an uninterrupted run with the same seed. A finished folder is reported
/// again; a different calibration into it is refused.
#[test]
fn killed_calibration_resumes_bit_identically() {
    let dir = common::scratch("calibrate", "resume");
    let file = tiny_calibration(&dir);
    let file_arg = file.to_str().unwrap();
    let reference = dir.join("reference");
    ok(&cryofit(&["calibrate", file_arg, "--workers", "2", "--out", reference.to_str().unwrap()]));

    let out_dir = dir.join("out");
    let out_arg = out_dir.to_str().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["calibrate", file_arg, "--workers", "2", "--out", out_arg])
        .env_remove("CRYOFIT_DATA_DIR")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    let database = out_dir.join("calibration.sqlite");
    loop {
        if stored_evaluations(&database).is_some_and(|n| n >= 12) {
            break;
        }
        assert!(child.try_wait().unwrap().is_none(), "the calibration ended before it could be killed");
        assert!(std::time::Instant::now() < deadline, "no progress in the calibration database");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(!out_dir.join("result.json").exists(), "the killed run wrote its outputs");

    let again = cryofit(&["calibrate", file_arg, "--workers", "2", "--out", out_arg]);
    let stdout = ok(&again);
    let stderr = String::from_utf8_lossy(&again.stderr);
    let done: usize = stderr
        .split("resuming the unfinished calibration in ")
        .nth(1)
        .and_then(|s| s.split(": ").nth(1))
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no resume message: {stderr}"));
    assert!((12..60).contains(&done), "resumed at {done} evaluations: {stderr}");
    assert!(stdout.contains("60 evaluations (0 failed)"), "{stdout}");

    let read = |d: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("result.json")).unwrap()).unwrap()
    };
    let (resumed, uninterrupted) = (read(&out_dir), read(&reference));
    assert_eq!(resumed["evaluations"], 60);
    assert_eq!(resumed["budget"], 60);
    // bit-identical: serde_json prints the shortest string that reads back to the same float
    assert_eq!(resumed["best_cost"].to_string(), uninterrupted["best_cost"].to_string());
    assert_eq!(resumed["best_parameters"].to_string(), uninterrupted["best_parameters"].to_string());
    for name in ["evaluations.csv", "best.toml", "fit-tiny.csv"] {
        let a = std::fs::read_to_string(out_dir.join(name)).unwrap();
        assert_eq!(a, std::fs::read_to_string(reference.join(name)).unwrap(), "{name} differs");
    }
    assert_eq!(std::fs::read_to_string(out_dir.join("evaluations.csv")).unwrap().lines().count(), 61);

    // a finished folder: the outputs are written again, nothing runs
    std::fs::remove_file(out_dir.join("best.toml")).unwrap();
    let third = cryofit(&["calibrate", file_arg, "--workers", "2", "--out", out_arg]);
    assert!(ok(&third).contains("60 evaluations (0 failed)"));
    assert!(!String::from_utf8_lossy(&third.stderr).contains("resuming"));
    assert_eq!(stored_evaluations(&database), Some(60));
    assert!(out_dir.join("best.toml").exists());

    // another calibration into the same folder is refused, naming the way out
    let other = dir.join("other.toml");
    std::fs::write(&other, std::fs::read_to_string(&file).unwrap().replace("seed = 7", "seed = 8")).unwrap();
    let refused = cryofit(&["calibrate", other.to_str().unwrap(), "--out", out_arg]);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains(out_arg) && err.contains("pick another --out or delete the folder"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
