//! Apparatus parameters end to end: case fields (`case.<path>`) as free parameters of `cryofit
//! calibrate`, shared and per experiment; a twin experiment that recovers a known inlet loss
//! coefficient; `best.toml` back through `cryofit simulate --params` and `cryofit predict`; bad input.

use std::path::{Path, PathBuf};

mod common;
use common::{cryofit, ok, read_json, refused, small_nbs_case};

/// The NBS subcooled case cut to CI size: 10 cells, 220 s (the front passes every station), with
/// the case file's loss coefficient of 10.
fn small_case(dir: &Path) -> PathBuf {
    let path = small_nbs_case(dir, "case.toml", 220.0, &[]);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("loss_coefficient = 10.0"), "the case's loss coefficient changed: update this test");
    path
}

/// The true loss coefficient of the twin, where the wall traces determine it. On this 10-cell case
/// the cost against traces simulated at a truth is flat within its jitter (the subcooled inlet's
/// geysering) on one side of some truths: at 15 from 12.4 to 15.2, and, since the end throttles'
/// heat leaves with the outflow, at 20 from 17.5 to 20 and at 25 from 22.75 to 25, where the
/// estimate settles on the valley's middle. At 30 the valley is narrow and about symmetric
/// (28.2–30.6); over optimiser seeds 1–6 the estimate lies within 2.1 % of 30 and every 95 %
/// interval holds it (VALIDATION.md, "Apparatus parameters: the twin experiment").
const TRUE_K: f64 = 30.0;

const TWIN: &str = r#"
name = "twin-loss-coefficient"
seed = 3
[[experiments]]
case = "case.toml"
data = "data.csv"
[[parameters]]
name = "case.inlet.loss_coefficient"
lower = 4.0
upper = 40.0
scale = "log"
[weights]
wall_temperature_k = { weight = 1.0, sigma = 1.0 }
[[stages]]
algorithm = "cmaes"
budget = 48
population = 6
[[stages]]
algorithm = "variance"
budget = 24
step = 0.03
restarts = 1
"#;

/// Twin experiment: wall temperatures simulated at a loss coefficient of 30 with 1 K of noise,
/// fitted from the case file's 10 within [4, 40]: the estimate (the variance stage's response
/// surface minimum) lies within 5 % of the truth, the variance stage's 95 % interval holds the
/// truth, and the outputs carry the case field by its `case.` name (best.toml reproduces the best
/// fit).
#[test]
fn twin_experiment_recovers_a_known_loss_coefficient() {
    let dir = common::scratch("apparatus", "twin");
    let case = small_case(&dir);
    let truth = dir.join("truth");
    let k = format!("case.inlet.loss_coefficient={TRUE_K}");
    let noise = ["--noise", "wall_temperature_k=1.0", "--seed", "5"];
    let case_arg = case.to_str().unwrap();
    let stdout =
        ok(&cryofit(&[&["simulate", case_arg, "--set", &k], &noise[..], &["--out", truth.to_str().unwrap()]].concat()));
    assert!(stdout.contains("case fields: inlet.loss_coefficient = 30"), "{stdout}");
    let summary = read_json(&truth.join("summary.json"));
    assert_eq!(summary["case_fields"]["inlet.loss_coefficient"], TRUE_K);
    let probes = std::fs::read_to_string(truth.join("probes.csv")).unwrap();
    let mut data: Vec<&str> = probes.lines().take(1).collect();
    data.extend(probes.lines().filter(|l| l.contains(",wall_temperature_k,")));
    std::fs::write(dir.join("data.csv"), data.join("\n") + "\n").unwrap();

    let file = dir.join("twin.toml");
    std::fs::write(&file, TWIN).unwrap();
    let out_dir = dir.join("out");
    let clock = std::time::Instant::now();
    let stdout =
        ok(&cryofit(&["calibrate", file.to_str().unwrap(), "--workers", "2", "--out", out_dir.to_str().unwrap()]));
    println!("{stdout}calibration wall time {:.1} s", clock.elapsed().as_secs_f64());
    let result = read_json(&out_dir.join("result.json"));
    let best = result["best_parameters"]["case.inlet.loss_coefficient"].as_f64().unwrap();
    println!("twin: loss coefficient {best} (truth {TRUE_K}, {:+.2} %)", (best / TRUE_K - 1.0) * 100.0);
    assert!((best / TRUE_K - 1.0).abs() < 0.05, "best {best}, truth {TRUE_K}");
    // the variance stage reports it like any parameter, and its 95 % interval holds the truth
    let u = &result["uncertainty"]["parameters"]["case.inlet.loss_coefficient"];
    let (lo, hi) = (u["lower95"].as_f64().unwrap(), u["upper95"].as_f64().unwrap());
    assert!(lo <= TRUE_K && TRUE_K <= hi, "truth {TRUE_K} outside [{lo}, {hi}] (best {best})");
    assert!(stdout.contains("case.inlet.loss_coefficient = "), "{stdout}");
    // the estimate is the variance stage's response-surface minimum, not its lowest evaluation
    let variance = &result["stages"][1];
    let (estimate, lowest) = (variance["best_cost"].as_f64().unwrap(), variance["lowest_cost"].as_f64().unwrap());
    assert_eq!(variance["details"]["variance"]["surface"]["accepted"], true, "{variance}");
    assert!(lowest <= estimate, "lowest {lowest}, estimate {estimate}");
    if lowest < estimate {
        assert!(stdout.contains("(its response surface's minimum; lowest evaluation "), "{stdout}");
    }
    let evaluations = std::fs::read_to_string(out_dir.join("evaluations.csv")).unwrap();
    assert!(evaluations.starts_with("id,stage,algorithm,status,cost,case.inlet.loss_coefficient,reason\n"));
    let best_toml = std::fs::read_to_string(out_dir.join("best.toml")).unwrap();
    assert!(best_toml.contains("\n\"case.inlet.loss_coefficient\" = "), "{best_toml}");
    // best.toml sets the case field again: the run reproduces the best fit's probes
    let again = dir.join("again");
    let best_arg = out_dir.join("best.toml");
    ok(&cryofit(&["simulate", case_arg, "--params", best_arg.to_str().unwrap(), "--out", again.to_str().unwrap()]));
    let fit = std::fs::read_to_string(out_dir.join("fit-case.csv")).unwrap();
    assert_eq!(fit, std::fs::read_to_string(again.join("probes.csv")).unwrap());
    std::fs::remove_dir_all(&dir).ok();
}

/// Two experiments on the tiny case (5 cells, 8 s): a registry parameter, a case field shared by
/// both and one copied per experiment, through sensitivity, CMA-ES and the variance stage.
const JOINT: &str = r#"
name = "apparatus"
seed = 4
max_evaluation_s = 30.0
[[experiments]]
case = "tiny.toml"
data = "tiny-data.csv"
[[experiments]]
case = "b.toml"
data = "tiny-data.csv"
[[parameters]]
name = "Gwsc"
lower = 0.5
upper = 2.0
[[parameters]]
name = "case.inlet.valve_opening_time_s"
lower = 1.0
upper = 3.0
[[parameters]]
name = "case.inlet.loss_coefficient"
lower = 5.0
upper = 20.0
scale = "log"
experiments = ["tiny", "b.toml"]
[weights]
wall_temperature_k = { weight = 1.0, sigma = 1.0 }
[[stages]]
algorithm = "sensitivity"
budget = 9
[[stages]]
algorithm = "cmaes"
budget = 24
population = 6
[[stages]]
algorithm = "variance"
budget = 70
step = 0.05
restarts = 0
"#;

fn joint(dir: &Path) -> PathBuf {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures");
    std::fs::copy(fixtures.join("tiny.toml"), dir.join("tiny.toml")).unwrap();
    // the data end at 8 s, the case's end: every run lands on it exactly (the driver's output
    // times are exact decimals, whatever the valve settings do to the steps before)
    std::fs::copy(fixtures.join("tiny-data.csv"), dir.join("tiny-data.csv")).unwrap();
    // the second run of the line: a lower drive pressure
    let b = std::fs::read_to_string(fixtures.join("tiny.toml")).unwrap();
    assert!(b.contains("pressure_pa = 425565.0"), "tiny.toml changed: update this test");
    std::fs::write(dir.join("b.toml"), b.replace("pressure_pa = 425565.0", "pressure_pa = 380000.0")).unwrap();
    let file = dir.join("joint.toml");
    std::fs::write(&file, JOINT).unwrap();
    file
}

/// Runs experiment `exp`'s case (`dir/<exp>.toml`) with the calibration's `best.toml` (in
/// `out_dir`) into `dir/again-<exp>`, checks that it reproduces the calibration's best fit of that
/// experiment (`fit-<exp>.csv`), and returns the run's output and folder.
fn reproduce_fit(dir: &Path, out_dir: &Path, exp: &str) -> (std::process::Output, PathBuf) {
    let again = dir.join(format!("again-{exp}"));
    let case = dir.join(format!("{exp}.toml"));
    let params = out_dir.join("best.toml");
    let args =
        ["simulate", case.to_str().unwrap(), "--params", params.to_str().unwrap(), "--out", again.to_str().unwrap()];
    let out = cryofit(&args);
    ok(&out);
    let fit = std::fs::read_to_string(out_dir.join(format!("fit-{exp}.csv"))).unwrap();
    assert_eq!(fit, std::fs::read_to_string(again.join("probes.csv")).unwrap(), "{exp}");
    (out, again)
}

/// A CI-sized calibration with one shared and one per-experiment case field: every output names
/// them (`case.<path>`, `case.<path>@<experiment>`), `best.toml` reproduces each experiment's best
/// fit, and `cryofit predict` applies the shared value and the case's own experiment's copy.
#[test]
fn a_calibration_frees_shared_and_per_experiment_case_fields() {
    let dir = common::scratch("apparatus", "joint");
    let file = joint(&dir);
    let out_dir = dir.join("out");
    let stdout =
        ok(&cryofit(&["calibrate", file.to_str().unwrap(), "--workers", "2", "--out", out_dir.to_str().unwrap()]));
    println!("{stdout}");
    assert!(stdout.contains(" evaluations (0 failed) in "), "{stdout}");
    let names = [
        "Gwsc",
        "case.inlet.loss_coefficient@b",
        "case.inlet.loss_coefficient@tiny",
        "case.inlet.valve_opening_time_s",
    ];
    let result = read_json(&out_dir.join("result.json"));
    let best: Vec<&str> = result["best_parameters"].as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(best, names);
    assert_eq!(result["stages"][0]["free"].as_array().unwrap().len(), 4, "the sensitivity stage ranks all four");
    assert!(stdout.contains("ranking (normalised):") && stdout.contains("case.inlet."), "{stdout}");
    let header = std::fs::read_to_string(out_dir.join("evaluations.csv")).unwrap();
    let header = header.lines().next().unwrap().to_string();
    assert_eq!(
        header,
        "id,stage,algorithm,status,cost,Gwsc,case.inlet.valve_opening_time_s,case.inlet.loss_coefficient@tiny,\
         case.inlet.loss_coefficient@b,reason"
    );
    let best_toml = std::fs::read_to_string(out_dir.join("best.toml")).unwrap();
    for line in ["\nGwsc = ", "\n\"case.inlet.loss_coefficient@b\" = ", "\n\"case.inlet.valve_opening_time_s\" = "] {
        assert!(best_toml.contains(line), "{line} in {best_toml}");
    }
    // best.toml on each experiment's case reproduces its best fit: the case file's stem names the
    // experiment, so its own copy applies and the other's is skipped (and said so)
    for exp in ["tiny", "b"] {
        let (out, again) = reproduce_fit(&dir, &out_dir, exp);
        let other = if exp == "tiny" { "b" } else { "tiny" };
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(&format!("skipped case.inlet.loss_coefficient@{other}")), "{stderr}");
        let summary = read_json(&again.join("summary.json"));
        let k = result["best_parameters"][format!("case.inlet.loss_coefficient@{exp}")].as_f64().unwrap();
        assert_eq!(summary["case_fields"]["inlet.loss_coefficient"].as_f64(), Some(k));
    }
    // predict over the posterior (when the variance stage gave one that holds) or say why not
    let pred = dir.join("pred");
    let case = dir.join("b.toml");
    let out = cryofit(&[
        "predict",
        case.to_str().unwrap(),
        "--from",
        out_dir.to_str().unwrap(),
        "--samples",
        "4",
        "--out",
        pred.to_str().unwrap(),
    ]);
    if result["uncertainty"].is_null() {
        assert!(String::from_utf8_lossy(&out.stderr).contains("no posterior"), "{out:?}");
    } else if result["uncertainty"]["positive_definite"] == false {
        assert!(String::from_utf8_lossy(&out.stderr).contains("not positive definite"), "{out:?}");
        assert!(!pred.exists(), "nothing written for a refused prediction");
    } else {
        ok(&out);
        assert!(String::from_utf8_lossy(&out.stderr).contains("skipped case.inlet.loss_coefficient@tiny"));
        assert_eq!(read_json(&pred.join("prediction.json"))["failed"], 0);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `[fixed]` case fields: the grid every experiment runs on and one experiment's valve, held at
/// given values; the fit is made on them, and `best.toml` carries them so that `simulate --params`
/// reproduces each experiment's fit.
#[test]
fn fixed_case_fields_set_the_grid_and_apparatus_of_a_calibration() {
    let dir = common::scratch("apparatus", "fixed");
    joint(&dir);
    let (head, _) = JOINT.split_once("[[parameters]]").unwrap();
    let text = format!(
        "{head}[[parameters]]\nname = \"Gwsc\"\nlower = 0.5\nupper = 2.0\n[fixed]\n\"case.pipe.cells\" = 4\n\
         \"case.inlet.loss_coefficient@b\" = 7.5\n[weights]\nwall_temperature_k = {{ weight = 1.0, sigma = 1.0 }}\n\
         [[stages]]\nalgorithm = \"pattern\"\nbudget = 4\n"
    );
    let file = dir.join("fixed.toml");
    std::fs::write(&file, &text).unwrap();
    let out_dir = dir.join("out");
    let stdout =
        ok(&cryofit(&["calibrate", file.to_str().unwrap(), "--workers", "2", "--out", out_dir.to_str().unwrap()]));
    assert!(stdout.contains(" evaluations (0 failed) in "), "{stdout}");
    let best_toml = std::fs::read_to_string(out_dir.join("best.toml")).unwrap();
    for line in ["\n\"case.pipe.cells\" = 4.0\n", "\n\"case.inlet.loss_coefficient@b\" = 7.5\n", "\nGwsc = "] {
        assert!(best_toml.contains(line), "{line} in {best_toml}");
    }
    for (exp, k) in [("tiny", None), ("b", Some(7.5))] {
        let (_, again) = reproduce_fit(&dir, &out_dir, exp);
        let summary = read_json(&again.join("summary.json"));
        assert_eq!(summary["case_fields"]["pipe.cells"].as_f64(), Some(4.0), "{exp}");
        assert_eq!(summary["case_fields"]["inlet.loss_coefficient"].as_f64(), k, "{exp}");
    }
    // a fixed value a case refuses: named with the experiment and case, nothing run
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, text.replace("\"case.pipe.cells\" = 4", "\"case.pipe.cells\" = 0")).unwrap();
    let bad_out = dir.join("bad-out");
    let err = refused(&cryofit(&["calibrate", bad.to_str().unwrap(), "--out", bad_out.to_str().unwrap()]));
    assert!(err.contains("bad.toml: ") && err.contains("fixed.case.pipe.cells"), "{err}");
    assert!(!bad_out.exists(), "output written");
    std::fs::remove_dir_all(&dir).ok();
}

/// Bad case fields: one line naming the file, the parameter or field and the value, nothing run.
#[test]
fn bad_case_fields_are_refused_naming_file_field_and_value() {
    let dir = common::scratch("apparatus", "bad");
    joint(&dir);
    let cases = [
        (
            JOINT.replace("lower = 1.0\nupper = 3.0", "lower = -1.0\nupper = 3.0"),
            "parameters[1] (case.inlet.valve_opening_time_s), experiment `tiny` (",
            "at the lower bound: inlet.valve_opening_time_s = -1 makes the case invalid",
        ),
        (
            JOINT.replace("case.inlet.valve_opening_time_s", "case.inlet.valve_time_s"),
            "parameters[1] (case.inlet.valve_time_s), experiment `tiny`",
            "`inlet.valve_time_s` is not a field of a case",
        ),
        (
            JOINT.replace("[\"tiny\", \"b.toml\"]", "[\"tiny\", \"c\"]"),
            "parameters[2].experiments[1] (`c`)",
            "not an experiment of this calibration (its experiments: tiny, b)",
        ),
        (
            JOINT.replace("lower = 5.0\n", ""),
            "parameters[2] (`case.inlet.loss_coefficient`)",
            "give both `lower` and `upper`",
        ),
        (
            JOINT.replace("name = \"Gwsc\"", "name = \"Gwsc\"\nexperiments = [\"b\"]"),
            "parameters[0].experiments (`Gwsc`)",
            "`experiments` applies to case fields",
        ),
    ];
    for (k, (text, field, what)) in cases.iter().enumerate() {
        let bad = dir.join(format!("bad{k}.toml"));
        std::fs::write(&bad, text).unwrap();
        let out_dir = dir.join(format!("out{k}"));
        let err = refused(&cryofit(&["calibrate", bad.to_str().unwrap(), "--out", out_dir.to_str().unwrap()]));
        assert!(err.contains(&format!("bad{k}.toml: ")), "case {k}: file not named: {err}");
        assert!(err.contains(field) && err.contains(what), "case {k}: {err}");
        assert!(!out_dir.exists(), "case {k}: output written");
    }

    // simulate: --set and --params name the source, the case file, the field and the value
    let case = dir.join("tiny.toml");
    let case_arg = case.to_str().unwrap();
    let err = refused(&cryofit(&["simulate", case_arg, "--set", "case.inlet.loss_coefficient=-1"]));
    assert!(
        err.contains("--set case.inlet.loss_coefficient=-1: case field of")
            && err.contains("tiny.toml")
            && err.contains("inlet.loss_coefficient = -1 makes the case invalid"),
        "{err}"
    );
    let err = refused(&cryofit(&["simulate", case_arg, "--set", "case.inlet.loss_coeficient=8"]));
    assert!(err.contains("did you mean `inlet.loss_coefficient`?"), "{err}");
    let err = refused(&cryofit(&["simulate", case_arg, "--set", "case.pipe.cells=7.5"]));
    assert!(err.contains("`pipe.cells` = 7.5: the field holds a whole number"), "{err}");
    let err = refused(&cryofit(&["simulate", case_arg, "--set", "case.stations.x_m=7"]));
    assert!(err.contains("`stations` is a list"), "{err}");
    let params = dir.join("p.toml");
    std::fs::write(&params, "[inlet]\nloss_coefficient = 8.0\n").unwrap();
    let err = refused(&cryofit(&["simulate", case_arg, "--params", params.to_str().unwrap()]));
    assert!(err.contains("p.toml: 'inlet' is a table") && err.contains("case fields under `case.`"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
