//! What the `cryofit` command tests share: running the binary, its outcome, a scratch folder, the
//! NBS subcooled case cut to CI size and wall-temperature data from a run's probes.
//!
//! Each test file uses what it needs of these, so some are unused in some test binaries.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `cryofit` binary with `args`, without the environment's data folder or coordinator.
pub fn cryofit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cryofit"))
        .args(args)
        .env_remove("CRYOFIT_DATA_DIR")
        .env_remove("CRYOFIT_COORDINATOR")
        .output()
        .unwrap()
}

/// The standard output of a command that must succeed.
pub fn ok(out: &Output) -> String {
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The one-line error of a command that must fail.
pub fn refused(out: &Output) -> String {
    assert!(!out.status.success(), "succeeded: {}", String::from_utf8_lossy(&out.stdout));
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    err
}

/// An empty folder `cryofit-<group>-<name>-<pid>` in the temporary directory.
pub fn scratch(group: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cryofit-{group}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A JSON file's contents.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `examples/nbs/subcooled-4.2atm.toml` cut to CI size — 10 cells, `end_s`, probes every 2 s, one
/// profile at the end — with the replacements `extra` (each `(from, to)` must apply), written to
/// `dir/file`.
pub fn small_nbs_case(dir: &Path, file: &str, end_s: f64, extra: &[(&str, &str)]) -> PathBuf {
    small_nbs_case_from("subcooled-4.2atm.toml", dir, file, end_s, extra)
}

/// [`small_nbs_case`] from another of the NBS case files (`examples/nbs/<source>`).
pub fn small_nbs_case_from(source: &str, dir: &Path, file: &str, end_s: f64, extra: &[(&str, &str)]) -> PathBuf {
    let src = format!("{}/../examples/nbs/{source}", env!("CARGO_MANIFEST_DIR"));
    let mut text = std::fs::read_to_string(&src).unwrap();
    let end = format!("end_s = {end_s:?}");
    let profile = format!("profile_interval_s = {end_s:?}");
    let cuts = [
        ("cells = 30", "cells = 10"),
        ("end_s = 1000.0", end.as_str()),
        ("output_interval_s = 1.0", "output_interval_s = 2.0"),
        ("profile_interval_s = 10.0", profile.as_str()),
    ];
    for (from, to) in cuts.iter().chain(extra) {
        assert!(text.contains(from), "the NBS case no longer holds `{from}`: update this test");
        text = text.replacen(from, to, 1);
    }
    let path = dir.join(file);
    std::fs::write(&path, text).unwrap();
    path
}

/// The wall-temperature rows of a `probes.csv` (with its header): data in the format
/// `cryofit calibrate` reads.
pub fn wall_data(probes: &str) -> String {
    let mut lines = probes.lines();
    let mut data = String::from(lines.next().unwrap_or_default());
    data.push('\n');
    for l in lines.filter(|l| l.contains(",wall_temperature_k,")) {
        data.push_str(l);
        data.push('\n');
    }
    data
}
