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
