//! `cryofit calibrate --coordinator` and `cryofit crossval --coordinator`: the refits run on a
//! coordinator's workers, the outputs are written where the command runs.

use std::time::Duration;

use crate::common::*;

/// Two runs of the tiny case (drive pressures 4.2 atm and 3.75 atm, the same twin data), one
/// closure parameter, CMA-ES then the variance stage; the refits of the cross-validation CMA-ES
/// alone.
const PAIR: &str = r#"
name = "pair"
seed = 3
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
[weights]
wall_temperature_k = { weight = 1.0, sigma = 1.0 }
[[stages]]
algorithm = "cmaes"
budget = 8
population = 4
[[crossval.stages]]
algorithm = "cmaes"
budget = 4
population = 4
sigma = 0.05
"#;

/// The joint calibration through `calibrate --coordinator`, then the cross-validation with every
/// refit submitted to the coordinator at once: each fold's refit is a calibration there, each
/// output folder notes it, and a second `crossval` into the same folder waits for the same refits
/// (submits none).
#[test]
fn crossval_refits_run_on_the_coordinators_workers() {
    let dir = scratch("crossval-remote");
    let tiny = std::fs::read_to_string(fixture("tiny.toml")).unwrap();
    assert!(tiny.contains("pressure_pa = 425565.0"), "tiny.toml changed: update this test");
    std::fs::write(dir.join("tiny.toml"), &tiny).unwrap();
    std::fs::write(dir.join("b.toml"), tiny.replace("pressure_pa = 425565.0", "pressure_pa = 380000.0")).unwrap();
    std::fs::copy(fixture("tiny-data.csv"), dir.join("tiny-data.csv")).unwrap();
    let file = dir.join("pair.toml");
    std::fs::write(&file, PAIR).unwrap();
    let server = Server::start(&dir, "serve", "127.0.0.1:0", &dir.join("c.db"), &[]);
    let _w1 = worker(&dir, "work-1", &server.url, "60");
    let _w2 = worker(&dir, "work-2", &server.url, "60");

    let run = |name: &str, args: &[&str]| {
        let mut p = Proc::start(name, &dir, args, &[]);
        let status = p.wait(Duration::from_secs(120)).expect("finished");
        assert!(status.success(), "{name} failed: {}", p.logs());
        p.stdout()
    };
    let joint = dir.join("joint");
    let (file_s, joint_s) = (file.display().to_string(), joint.display().to_string());
    run("calibrate", &["calibrate", &file_s, "--coordinator", &server.url, "--out", &joint_s]);
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(joint.join("result.json")).unwrap()).unwrap();
    assert!(result["best_parameters"]["Gwsc"].as_f64().is_some(), "{result}");
    assert!(joint.join("best.toml").exists() && !joint.join("calibration.sqlite").exists());
    let noted: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(joint.join("coordinator.json")).unwrap()).unwrap();
    assert_eq!(noted["coordinator"], server.url.as_str());
    let joint_id = noted["id"].as_i64().expect("id");
    // the folder is that coordinator's calibration: a local run into it is refused
    let mut local = Proc::start("calibrate-local", &dir, &["calibrate", &file_s, "--out", &joint_s], &[]);
    let status = local.wait(Duration::from_secs(60)).expect("finished");
    assert!(!status.success() && local.logs().contains("give the same --coordinator"), "{}", local.logs());

    let cv = dir.join("cv");
    let cv_s = cv.display().to_string();
    let args =
        ["crossval", &file_s, "--from", &joint_s, "--coordinator", &server.url, "--out", &cv_s, "--samples", "2"];
    let out = run("crossval", &args);
    assert!(out.contains("is calibration"), "{out}");
    let calibrations = get_json(&format!("{}/api/v1/calibrations", server.url), None);
    let items = calibrations["items"].as_array().or(calibrations.as_array()).expect("calibrations").clone();
    assert_eq!(items.len(), 3, "{calibrations}");
    for (fold, left_out) in ["without-tiny", "without-b"].iter().zip(["tiny", "b"]) {
        let refit = cv.join(fold).join("refit");
        let noted: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(refit.join("coordinator.json")).unwrap()).unwrap();
        let id = noted["id"].as_i64().expect("id");
        assert_ne!(id, joint_id);
        let c = get_json(&format!("{}/api/v1/calibrations/{id}", server.url), None);
        assert_eq!(c["status"], "completed", "{c}");
        assert_eq!(c["evaluations"], 4, "{c}");
        assert!(refit.join("result.json").exists() && refit.join("best.toml").exists());
        let summary = cv.join("crossval.json");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
        assert!(v.to_string().contains(left_out), "{v}");
    }
    // again into the same folder: the noted refits are waited for, none submitted
    run("crossval-again", &args);
    let calibrations = get_json(&format!("{}/api/v1/calibrations", server.url), None);
    let items = calibrations["items"].as_array().or(calibrations.as_array()).expect("calibrations").clone();
    assert_eq!(items.len(), 3, "{calibrations}");
}
