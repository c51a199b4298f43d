//! `cryofit bench robustness` end to end.

use std::process::Command;

#[test]
fn robustness_reports_completion_and_causes() {
    let case = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/verification/faucet.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["bench", "robustness", "--case", case, "--samples", "6", "--seed", "4", "--json"])
        .env_remove("CRYOFIT_DATA_DIR")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["samples"], 6);
    let completed = v["completed"].as_u64().unwrap();
    let failures = v["failures"].as_array().unwrap();
    assert_eq!(completed as usize + failures.len(), 6);
    let fraction = v["completion_fraction"].as_f64().unwrap();
    assert!((fraction - completed as f64 / 6.0).abs() < 1e-12);
    // every failure carries its error text and the parameters that caused it
    for f in failures {
        assert!(!f["error"].as_str().unwrap().is_empty());
        assert!(!f["parameters"].as_object().unwrap().is_empty());
    }
    // the same seed draws the same sets: the report is reproducible
    let again = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["bench", "robustness", "--case", case, "--samples", "6", "--seed", "4", "--json"])
        .output()
        .unwrap();
    let w: serde_json::Value = serde_json::from_slice(&again.stdout).unwrap();
    assert_eq!(v["completed"], w["completed"]);
    assert_eq!(v["failure_causes"], w["failure_causes"]);
}

#[test]
fn robustness_rejects_bad_arguments() {
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["bench", "robustness", "--case", "/nonexistent/case.toml", "--samples", "3"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("/nonexistent/case.toml"), "{err}");
}

/// 100 random parameter sets on a CI-sized NBS subcooled case (10 cells, 60 s): no run panics,
/// and every failure is an error naming time, cell, variable and value. The completion fraction
/// is printed; BENCHMARKS.md records the full-size figure and its target.
#[test]
fn robustness_on_the_nbs_case_never_panics() {
    let src = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs/subcooled-4.2atm.toml");
    let text = std::fs::read_to_string(src)
        .unwrap()
        .replace("cells = 30", "cells = 10")
        .replace("end_s = 1000.0", "end_s = 60.0")
        .replace("output_interval_s = 1.0", "output_interval_s = 5.0")
        // bound each sample's cost: a sample still crawling after 2 s of computing ends with
        // a max_wall_s error, which is a reported failure like the others
        .replace("[time]\n", "[time]\nmax_wall_s = 2.0\n");
    assert!(text.contains("max_wall_s = 2.0"), "the case's [time] section was not found");
    let dir = std::env::temp_dir().join(format!("cryofit-robustness-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let case = dir.join("subcooled-small.toml");
    std::fs::write(&case, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["bench", "robustness", "--case", case.to_str().unwrap(), "--samples", "100", "--seed", "7", "--json"])
        .env_remove("CRYOFIT_DATA_DIR")
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let failures = v["failures"].as_array().unwrap();
    assert_eq!(v["completed"].as_u64().unwrap() as usize + failures.len(), 100);
    for f in failures {
        let e = f["error"].as_str().unwrap();
        let located = e.contains("t = ") && (e.contains("cell") || e.contains("max_wall_s"));
        assert!(located, "failure without time and place: {e}");
    }
    println!("robustness: {} of 100 complete; causes {}", v["completed"], v["failure_causes"]);
}

/// `cryofit bench coordinator` end to end on a CI-sized run: the JSON summary is the last line
/// and its figures are consistent (the speed is not checked); bad arguments get one line.
#[test]
fn coordinator_benchmark_reports_json() {
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["bench", "coordinator", "--workers", "2", "--evaluations", "200", "--json"])
        .env_remove("CRYOFIT_DATA_DIR")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("evaluations/s"), "no table: {stdout}");
    let last = stdout.trim_end().lines().last().unwrap();
    let v: serde_json::Value = serde_json::from_str(last).unwrap();
    assert_eq!(v["evaluations"], 200);
    assert_eq!(v["workers"], 2);
    let wall = v["wall_s"].as_f64().unwrap();
    let rate = v["evaluations_per_s"].as_f64().unwrap();
    assert!(wall > 0.0 && rate > 0.0, "{v}");
    assert!((rate * wall - 200.0).abs() < 1e-6 * 200.0, "{v}");
    for key in ["claim_latency_ms_p50", "claim_latency_ms_p99", "result_latency_ms_p50", "result_latency_ms_p99"] {
        let x = v[key].as_f64().unwrap_or(-1.0);
        assert!(x.is_finite() && x >= 0.0, "{key}: {v}");
    }
    assert!(v["claim_latency_ms_p50"].as_f64() <= v["claim_latency_ms_p99"].as_f64(), "{v}");
    assert!(v["claims"].as_u64().unwrap() >= 1 && v["result_requests"].as_u64().unwrap() >= 1, "{v}");
    // bad arguments: one line naming the argument
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["bench", "coordinator", "--workers", "0", "--evaluations", "200"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("--workers 0"), "{err}");
}

/// `bench chaos` on the NBS subcooled case cut to 10 cells and 200 s (its station-4 chilldown
/// comes at about 162 s): three runs at Gwsc one unit
/// in the last place below, at and above its default, each with its station-4 chilldown, the range,
/// mean, standard deviation and largest move consistent with them; the same runs with the grid and
/// end given by `--set` on the full case; a `--set` of the perturbed parameter as the centre, and a
/// `--params` file's; and
/// the errors for a parameter, station or case field the case does not take.
#[test]
fn chaos_reports_the_chilldown_of_each_perturbation() {
    let dir = std::env::temp_dir().join(format!("cryofit-bench-chaos-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let src = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs/subcooled-4.2atm.toml");
    let text = std::fs::read_to_string(src).unwrap();
    assert!(text.contains("cells = 30") && text.contains("end_s = 1000.0"), "the NBS case changed: update this test");
    let case = dir.join("small.toml");
    std::fs::write(&case, text.replacen("cells = 30", "cells = 10", 1).replacen("end_s = 1000.0", "end_s = 200.0", 1))
        .unwrap();
    let case = case.to_str().unwrap();
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_cryofit")).args(args).output().unwrap();
    // `bench chaos --case CASE --param Gwsc --ulps 1 EXTRA... --json`: its report and stderr
    let chaos = |case: &str, extra: &[&str]| {
        let args = [&["bench", "chaos", "--case", case, "--param", "Gwsc", "--ulps", "1"], extra, &["--json"]].concat();
        let out = run(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (report, String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (v, _) = chaos(case, &[]);
    assert_eq!(v["station"], "TS4");
    let runs = v["runs"].as_array().unwrap();
    let values: Vec<f64> = runs.iter().map(|r| r["value"].as_f64().unwrap()).collect();
    assert_eq!(values, [1.0 - f64::EPSILON / 2.0, 1.0, 1.0 + f64::EPSILON]);
    let times: Vec<f64> = runs.iter().map(|r| r["chilldown_s"].as_f64().expect("a chilldown")).collect();
    let (lo, hi) = (times.iter().copied().fold(f64::INFINITY, f64::min), times.iter().copied().fold(0.0, f64::max));
    assert_eq!(v["range_s"], serde_json::json!([lo, hi]));
    let moved = times.iter().map(|t| (t - times[1]).abs()).fold(0.0, f64::max);
    assert_eq!(v["largest_move_s"].as_f64(), Some(moved));
    assert_eq!(v["target_met"], moved <= 1.0);
    let mean = times.iter().sum::<f64>() / 3.0;
    assert!((v["mean_s"].as_f64().unwrap() - mean).abs() < 1e-9 * mean);
    let sd = (times.iter().map(|t| (t - mean).powi(2)).sum::<f64>() / 2.0).sqrt();
    assert!((v["standard_deviation_s"].as_f64().unwrap() - sd).abs() <= 1e-9 * mean);

    // the same runs from the full case with its grid and end set on the command line, and the
    // perturbed parameter's centre moved by a --set of it
    let (w, _) = chaos(src, &["--set", "case.pipe.cells=10", "--set", "case.time.end_s=200"]);
    assert_eq!(w["runs"], v["runs"]);
    assert_eq!(w["set"], serde_json::json!({"case.pipe.cells": 10.0, "case.time.end_s": 200.0}));
    // per-experiment values apply to the experiment named (a later --set over an earlier one),
    // and are skipped for another
    let per = |experiment: &str| {
        let sets = ["case.time.end_s=150", "case.pipe.cells@short=10", "case.time.end_s@short=200"];
        chaos(src, &["--set", sets[0], "--set", sets[1], "--set", sets[2], "--experiment", experiment])
    };
    let (w, _) = per("short");
    assert_eq!(w["runs"], v["runs"]);
    let (w, stderr) = per("other");
    assert!(stderr.contains("skipped case.pipe.cells@short"), "{stderr}");
    assert!(w["runs"].as_array().unwrap().iter().all(|r| r["chilldown_s"].is_null()), "{w}");
    let (w, _) = chaos(case, &["--set", "Gwsc=0.5"]);
    assert_eq!(w["value"], 0.5);
    assert_eq!(w["runs"][1]["value"], 0.5);
    // a --params file: its values for every run, its value of the perturbed parameter the
    // centre, its case fields applied, a --set over it; the same runs as the --set above
    let file = dir.join("point.toml");
    std::fs::write(&file, "Gwsc = 0.5\ncase.time.end_s = 150.0\n").unwrap();
    let file = file.to_str().unwrap();
    let (p, _) = chaos(case, &["--params", file, "--set", "case.time.end_s=200"]);
    assert_eq!(p["params"], file);
    assert_eq!(p["set"], serde_json::json!({"Gwsc": 0.5, "case.time.end_s": 200.0}));
    assert_eq!(p["runs"], w["runs"]);
    let bad = run(&["bench", "chaos", "--case", case, "--param", "Gwsc", "--params", "/nonexistent/point.toml"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("/nonexistent/point.toml"));
    let bad = run(&["bench", "chaos", "--case", case, "--param", "Gwsc", "--set", "case.pipe.cells=-3"]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("cells"), "{}", String::from_utf8_lossy(&bad.stderr));

    let bad = run(&["bench", "chaos", "--case", case, "--param", "Gwsx"]);
    assert!(!bad.status.success());
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("did you mean 'Gwsc'"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
    let bad = run(&["bench", "chaos", "--case", case, "--param", "Gwsc", "--station", "TS9"]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("has the stations TS1, TS2, TS3, TS4"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench speed` on two CI-sized NBS cases (10 cells, 20 s), two repeats each: per case the
/// simulated time, steps, the wall time of each repeat and their median, the speed the median
/// gives and what held the steps, consistent with each other and with `cryofit simulate`'s
/// summary of the same run; the target held against the slowest case; a `--set` that moves the
/// run; and the errors for bad arguments.
#[test]
fn speed_reports_each_case_against_the_target() {
    let dir = std::env::temp_dir().join(format!("cryofit-bench-speed-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut cases = Vec::new();
    for name in ["saturated-2.5atm", "subcooled-4.2atm"] {
        let src = format!("{}/../examples/nbs/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&src).unwrap();
        assert!(text.contains("cells = 30") && text.contains("end_s = 1000.0"), "{name} changed: update this test");
        let case = dir.join(format!("{name}.toml"));
        std::fs::write(
            &case,
            text.replacen("cells = 30", "cells = 10", 1).replacen("end_s = 1000.0", "end_s = 20.0", 1),
        )
        .unwrap();
        cases.push(case.to_str().unwrap().to_string());
    }
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_cryofit")).args(args).output().unwrap();
    let speed = |extra: &[&str]| {
        let args =
            [&["bench", "speed", "--case", &cases[0], "--case", &cases[1], "--repeats", "2"], extra, &["--json"]]
                .concat();
        let out = run(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let v = speed(&[]);
    assert_eq!(v["repeats"], 2);
    assert_eq!(v["target"], 5000.0);
    assert!(v["failures"].as_array().unwrap().is_empty(), "{v}");
    let measured = v["cases"].as_array().unwrap();
    assert_eq!(measured.len(), 2);
    let mut slowest = f64::INFINITY;
    for (c, path) in measured.iter().zip(&cases) {
        assert_eq!(c["case"], path.as_str());
        assert_eq!(c["cells"], 10);
        assert_eq!(c["simulated_s"], 20.0);
        let walls: Vec<f64> = c["wall_times_s"].as_array().unwrap().iter().map(|w| w.as_f64().unwrap()).collect();
        assert_eq!(walls.len(), 2);
        let median = c["median_wall_s"].as_f64().unwrap();
        assert!((median - 0.5 * (walls[0] + walls[1])).abs() <= 1e-12 * median, "{c}");
        let s = c["speed"].as_f64().unwrap();
        assert!((s - 20.0 / median).abs() <= 1e-9 * s, "{c}");
        assert_eq!(c["target_met"], s >= 5000.0);
        slowest = slowest.min(s);
        let steps = c["steps"].as_u64().unwrap();
        let held: u64 = c["step_limited_by"].as_object().unwrap().values().map(|n| n.as_u64().unwrap()).sum();
        assert!(held > 0 && held <= steps, "{c}");
        // the steps are those of `cryofit simulate` on the same case
        let out_dir = dir.join(format!("sim-{}", c["steps"]));
        let sim = run(&["simulate", path, "--out", out_dir.to_str().unwrap()]);
        assert!(sim.status.success(), "{}", String::from_utf8_lossy(&sim.stderr));
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out_dir.join("summary.json")).unwrap()).unwrap();
        assert_eq!(summary["steps"], c["steps"]);
        assert_eq!(summary["rejected_steps"], c["rejected_steps"]);
    }
    assert_eq!(v["slowest_speed"].as_f64(), Some(slowest));
    assert_eq!(v["target_met"], slowest >= 5000.0);
    // a target every case meets, and one none does
    assert_eq!(speed(&["--target", "1"])["target_met"], true);
    assert_eq!(speed(&["--target", "1e12"])["target_met"], false);
    // a --set applies to every case and is reported
    let w = speed(&["--set", "case.time.end_s=10"]);
    assert_eq!(w["set"], serde_json::json!({"case.time.end_s": 10.0}));
    assert!(w["cases"].as_array().unwrap().iter().all(|c| c["simulated_s"] == 10.0), "{w}");

    for (args, needle) in [
        (vec!["--repeats", "0"], "--repeats 0"),
        (vec!["--target", "0"], "--target 0"),
        (vec!["--set", "Gwsx=1"], "Gwsx"),
    ] {
        let out = run(&[&["bench", "speed", "--case", cases[0].as_str()], args.as_slice()].concat());
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(needle), "{err}");
    }
    let out = run(&["bench", "speed", "--case", "/nonexistent/case.toml"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/case.toml"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench grid` on the NBS saturated 2.5 atm case at 4 and 8 cells against its data: each run's
/// station chilldowns are those `cryofit simulate` gives on that grid, the changes and the target
/// follow from them, the data's chilldowns and the fit are reported; and the errors for too few
/// grids, a data file per case missing, a grid set by `--set` and data of another line.
#[test]
fn grid_reports_each_grid_and_the_change_between_the_finest() {
    let nbs = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs");
    let case = format!("{nbs}/saturated-2.5atm.toml");
    let data = format!("{nbs}/saturated-2.5atm-data.csv");
    let run = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_cryofit")).args(args).output().unwrap();
    let out = run(&[
        "bench",
        "grid",
        "--case",
        &case,
        "--data",
        &data,
        "--cells",
        "8,4",
        "--set",
        "case.time.end_s=450",
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["cells"], serde_json::json!([4, 8]));
    let c = &v["cases"][0];
    assert_eq!(c["station"], "TS4");
    let runs = c["runs"].as_array().unwrap();
    assert_eq!(runs.iter().map(|r| r["cells"].as_u64().unwrap()).collect::<Vec<_>>(), [4, 8]);
    let ts4 = |r: &serde_json::Value| r["chilldown_s"]["TS4"].as_f64().expect("a station-4 chilldown");
    // the 8-cell run is the one `cryofit simulate` makes on that grid
    let dir = std::env::temp_dir().join(format!("cryofit-bench-grid-{}", std::process::id()));
    let sim = run(&[
        "simulate",
        &case,
        "--set",
        "case.time.end_s=450",
        "--set",
        "case.pipe.cells=8",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(sim.status.success(), "{}", String::from_utf8_lossy(&sim.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(runs[1]["chilldown_s"], summary["chilldown_time_s"]);
    assert_eq!(runs[1]["steps"], summary["steps"]);
    let change = (ts4(&runs[1]) / ts4(&runs[0]) - 1.0) * 100.0;
    assert!((c["finest_change_pct"]["TS4"].as_f64().unwrap() - change).abs() < 1e-9);
    let coarse = (ts4(&runs[0]) / ts4(&runs[1]) - 1.0) * 100.0;
    assert!((c["coarsest_from_finest_pct"]["TS4"].as_f64().unwrap() - coarse).abs() < 1e-9);
    assert_eq!(c["target_met"], change.abs() <= 2.0);
    // against the data: its chilldowns (about 245 s at station 4), each run's errors and RMS
    let d4 = c["data_chilldown_s"]["TS4"].as_f64().unwrap();
    assert!((240.0..250.0).contains(&d4), "{d4}");
    for r in runs {
        let e = r["chilldown_error_pct"]["TS4"].as_f64().unwrap();
        assert!((e - (ts4(r) / d4 - 1.0) * 100.0).abs() < 1e-9);
        let rms = r["wall_rms_k"].as_f64().unwrap();
        assert!(rms > 0.0 && rms < 200.0, "{rms}");
    }
    let _ = std::fs::remove_dir_all(&dir);

    // the same runs as a calibration file's experiment: its [fixed] values under --set, its
    // experiment name for per-experiment values
    let calibration = std::env::temp_dir().join(format!("cryofit-bench-grid-{}.toml", std::process::id()));
    std::fs::write(
        &calibration,
        format!(
            "name = \"grid\"\n[[experiments]]\ncase = \"{case}\"\ndata = \"{data}\"\nname = \"s25\"\n\
             [[parameters]]\nname = \"fwsc\"\n[fixed]\nGwsc = 0.5\n\
             [[stages]]\nalgorithm = \"cmaes\"\nbudget = 4\n"
        ),
    )
    .unwrap();
    // the runs without their wall times
    let runs_of = |v: &serde_json::Value| {
        let mut runs = v["cases"][0]["runs"].clone();
        runs.as_array_mut().unwrap().iter_mut().for_each(|r| {
            r.as_object_mut().unwrap().remove("wall_time_s");
        });
        runs
    };
    let grid = |args: &[&str]| {
        let out = run(&[&["bench", "grid", "--cells", "4,8", "--json"], args].concat());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let by_case = grid(&[
        "--case",
        &case,
        "--data",
        &data,
        "--set",
        "Gwsc=0.5",
        "--set",
        "case.time.end_s=450",
        "--set",
        "fwsc=1.1",
    ]);
    let cal = grid(&[
        "--calibration",
        calibration.to_str().unwrap(),
        "--set",
        "case.time.end_s@s25=450",
        "--set",
        "fwsc=1.1",
    ]);
    assert_eq!(runs_of(&cal), runs_of(&by_case));
    assert_ne!(runs_of(&cal), runs_of(&v), "Gwsc 0.5 changes the runs");
    // a --set over a [fixed] value wins
    let over =
        grid(&["--calibration", calibration.to_str().unwrap(), "--set", "case.time.end_s@s25=450", "--set", "Gwsc=1"]);
    assert_eq!(runs_of(&over), runs_of(&v));
    let both = run(&["bench", "grid", "--calibration", calibration.to_str().unwrap(), "--case", &case]);
    assert!(!both.status.success());
    let _ = std::fs::remove_file(&calibration);

    let fails = |args: &[&str], says: &str| {
        let out = run(&[&["bench", "grid", "--case", &case], args].concat());
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{err}");
    };
    fails(&["--cells", "30,30"], "at least two different");
    fails(&["--cells", "10,20", "--case", &case, "--data", &data], "one data file per case");
    fails(&["--cells", "10,20", "--set", "case.pipe.cells=12"], "given by --cells");
    let other = std::env::temp_dir().join(format!("cryofit-bench-grid-{}.csv", std::process::id()));
    std::fs::write(&other, "time_s,station,x_m,quantity,value\n0,TX,1,wall_temperature_k,290\n").unwrap();
    fails(&["--cells", "10,20", "--data", other.to_str().unwrap()], "`TX`");
    let _ = std::fs::remove_file(&other);
}
