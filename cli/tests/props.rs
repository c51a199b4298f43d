//! `cryofit props` end to end: the real binary, its JSON contract and its errors.

use std::process::{Command, Output};

fn cryofit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cryofit")).args(args).env_remove("CRYOFIT_DATA_DIR").output().expect("run cryofit")
}

#[test]
fn liquid_nitrogen_at_one_atmosphere() {
    let out = cryofit(&["props", "nitrogen", "--p", "101325", "--t", "77", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    let mut want = vec![
        "fluid",
        "phase",
        "pressure_pa",
        "temperature_k",
        "density_kg_m3",
        "specific_enthalpy_j_kg",
        "specific_internal_energy_j_kg",
        "cp_j_kg_k",
        "viscosity_pa_s",
        "conductivity_w_m_k",
        "t_sat_k",
    ];
    let mut got = keys.clone();
    got.sort_unstable();
    want.sort_unstable();
    assert_eq!(got, want);
    assert_eq!(v["fluid"], "nitrogen");
    assert_eq!(v["phase"], "liquid");
    let rho = v["density_kg_m3"].as_f64().unwrap();
    // CoolProp 8.0.0: 807.70 kg/m³
    assert!((rho / 807.70 - 1.0).abs() < 5e-4, "density {rho}");
    let t_sat = v["t_sat_k"].as_f64().unwrap();
    assert!((t_sat - 77.355).abs() < 1e-3, "T_sat {t_sat}");
}

#[test]
fn supercritical_state_has_no_saturation_temperature() {
    let out = cryofit(&["props", "N2", "--p", "3.5e6", "--t", "200", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["phase"], "supercritical");
    assert!(v["t_sat_k"].is_null());
}

fn props_json(args: &[&str]) -> serde_json::Value {
    let out = cryofit(args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("JSON")
}

#[test]
fn parahydrogen_is_its_own_table() {
    // CoolProp 8.0.0 at 300 kPa and 100 K: ParaHydrogen ρ 0.727887 kg/m³, c_p 13494.1 J/(kg K);
    // (normal) Hydrogen ρ 0.727798 kg/m³, c_p 11291.4 J/(kg K)
    let para = props_json(&["props", "parahydrogen", "--p", "300000", "--t", "100", "--json"]);
    assert_eq!(para["fluid"], "parahydrogen");
    assert_eq!(para["phase"], "gas");
    let normal = props_json(&["props", "hydrogen", "--p", "300000", "--t", "100", "--json"]);
    assert_eq!(normal["fluid"], "hydrogen");
    let rel = |v: &serde_json::Value, key: &str, want: f64| (v[key].as_f64().unwrap() / want - 1.0).abs();
    assert!(rel(&para, "density_kg_m3", 0.727887) < 5e-4, "{para}");
    assert!(rel(&para, "cp_j_kg_k", 13494.14) < 5e-3, "{para}");
    assert!(rel(&normal, "density_kg_m3", 0.727798) < 5e-4, "{normal}");
    assert!(rel(&normal, "cp_j_kg_k", 11291.40) < 5e-3, "{normal}");
    assert_eq!(props_json(&["props", "p-H2", "--p", "300000", "--t", "100", "--json"])["fluid"], "parahydrogen");
}

#[test]
fn tables_hold_pressure_surges_up_to_thirty_megapascals() {
    // CoolProp 8.0.0: nitrogen at 8 MPa and 100 K, 725.778 kg/m³; at 2 kPa and 300 K, 0.0224616;
    // at 20 MPa and 100 K, 765.348 (a liquid hammer's pressure)
    let v = props_json(&["props", "nitrogen", "--p", "8e6", "--t", "100", "--json"]);
    assert_eq!(v["phase"], "supercritical");
    assert!((v["density_kg_m3"].as_f64().unwrap() / 725.778 - 1.0).abs() < 5e-4, "{v}");
    let v = props_json(&["props", "nitrogen", "--p", "2e3", "--t", "300", "--json"]);
    assert!((v["density_kg_m3"].as_f64().unwrap() / 0.0224616 - 1.0).abs() < 5e-4, "{v}");
    let v = props_json(&["props", "nitrogen", "--p", "2e7", "--t", "100", "--json"]);
    assert!((v["density_kg_m3"].as_f64().unwrap() / 765.348 - 1.0).abs() < 5e-4, "{v}");
}

#[test]
fn near_the_critical_point_the_missing_saturation_says_why() {
    // para-hydrogen's critical pressure is 1.2858 MPa; the table's saturation ends at 0.995 of it
    let out = cryofit(&["props", "parahydrogen", "--p", "1.285e6", "--t", "40"]);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("within 0.5 % of the critical pressure"), "{text}");
    assert!(!text.contains("triple-point"), "{text}");
}

#[test]
fn human_readable_output_names_units() {
    let out = cryofit(&["props", "methane", "--p", "2e5", "--t", "300"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("gas") && text.contains("kg/m³") && text.contains("saturation temperature"), "{text}");
}

fn assert_one_line_error(args: &[&str], needle: &str) {
    let out = cryofit(args);
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err}");
    assert!(err.contains(needle), "{args:?}: '{err}' does not mention '{needle}'");
    assert!(out.stdout.is_empty());
}

#[test]
fn bad_input_gives_one_line_errors() {
    assert_one_line_error(&["props", "helium", "--p", "1e5", "--t", "4"], "unknown fluid 'helium'");
    assert_one_line_error(&["props", "nitrogen", "--p", "1e5", "--t", "600"], "500 K");
    assert_one_line_error(&["props", "nitrogen", "--p", "1e8", "--t", "100"], "pressure must be within");
    assert_one_line_error(&["props", "nitrogen", "--p", "-5", "--t", "100"], "pressure must be within");
    assert_one_line_error(&["props", "nitrogen", "--p", "abc", "--t", "100"], "--p");
    assert_one_line_error(&["props", "nitrogen", "--t", "100"], "--p");
}

#[test]
fn data_dir_overrides_the_built_in_tables() {
    let dir = std::env::temp_dir().join(format!("cryofit-props-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // an empty directory: the error names the file and the variable
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["props", "nitrogen", "--p", "101325", "--t", "77"])
        .env("CRYOFIT_DATA_DIR", &dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("CRYOFIT_DATA_DIR") && err.contains("nitrogen.cft"), "{err}");
    // a copy of the real table is read and used
    let src = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/fluids/nitrogen.cft");
    std::fs::copy(src, dir.join("nitrogen.cft")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["props", "nitrogen", "--p", "101325", "--t", "77", "--json"])
        .env("CRYOFIT_DATA_DIR", &dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // a corrupt table is refused with its path
    std::fs::write(dir.join("nitrogen.cft"), b"CRYOFLT1garbage").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["props", "nitrogen", "--p", "101325", "--t", "77"])
        .env("CRYOFIT_DATA_DIR", &dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("nitrogen.cft"));
    std::fs::remove_dir_all(&dir).ok();
}

/// A reader that closes the pipe before the output is written (`cryofit params --json | head`)
/// ends the command quietly, as a pipe's writer ends: exit 141 (128 + SIGPIPE), no panic
/// report. (Should the write land in the pipe before the read end closes, the run simply
/// succeeds.)
#[test]
fn a_closed_stdout_ends_the_command_without_a_panic() {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(["params", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run cryofit");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait for cryofit");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(matches!(out.status.code(), Some(0 | 141)), "exit {:?}: {stderr}", out.status.code());
}
