//! `cryofit simulate` and `cryofit params` end to end: the real binary, its files and its errors.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const FAUCET: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/verification/faucet.toml");

const PROBE_QUANTITIES: [&str; 10] = [
    "wall_temperature_k",
    "fluid_temperature_k",
    "gas_temperature_k",
    "liquid_temperature_k",
    "pressure_pa",
    "void_fraction",
    "gas_velocity_m_s",
    "liquid_velocity_m_s",
    "wall_heat_flux_w_m2",
    "mass_flow_kg_s",
];

const SUMMARY_KEYS: [&str; 10] = [
    "steps",
    "rejected_steps",
    "wall_time_s",
    "simulated_time_s",
    "min_dt_s",
    "max_dt_s",
    "mass_balance_error",
    "energy_balance_error",
    "chilldown_time_s",
    "quench_arrival_s",
];

/// A scratch directory unique to this process and test, removed when dropped (also on panic).
struct Scratch(PathBuf);

impl Scratch {
    fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("cryofit-simulate-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Writes `text` to `name` in the scratch directory and returns its path as a string.
    fn write(&self, name: &str, text: &str) -> String {
        let path = self.path(name);
        std::fs::write(&path, text).unwrap();
        path.to_str().unwrap().to_string()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The faucet case, shortened (0.1 s, 20 cells) to keep the tests fast.
fn fast_faucet() -> String {
    let text = std::fs::read_to_string(FAUCET).unwrap();
    assert!(text.contains("end_s = 0.5") && text.contains("cells = 100"), "faucet.toml changed");
    text.replace("end_s = 0.5", "end_s = 0.1").replace("cells = 100", "cells = 20")
}

fn cryofit_in(dir: Option<&Path>, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_cryofit"));
    cmd.args(args).env_remove("CRYOFIT_DATA_DIR");
    if let Some(dir) = dir {
        cmd.current_dir(dir);
    }
    cmd.output().expect("run cryofit")
}

fn cryofit(args: &[&str]) -> Output {
    cryofit_in(None, args)
}

fn assert_success(out: &Output) {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
}

/// The command fails with one line on stderr that mentions every needle, and prints nothing.
fn assert_one_line_error<S: AsRef<str>>(args: &[S], needles: &[&str]) {
    let args: Vec<&str> = args.iter().map(AsRef::as_ref).collect();
    let out = cryofit(&args);
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err}");
    assert!(err.starts_with("error: "), "{args:?}: {err}");
    for needle in needles {
        assert!(err.contains(needle), "{args:?}: '{}' does not mention '{needle}'", err.trim_end());
    }
    assert!(out.stdout.is_empty(), "{args:?}: printed {}", String::from_utf8_lossy(&out.stdout));
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&read(&dir.join("summary.json"))).expect("summary.json is JSON")
}

/// `probes.csv` rows split into fields (header excluded).
fn probe_rows(dir: &Path) -> Vec<Vec<String>> {
    read(&dir.join("probes.csv")).lines().skip(1).map(|l| l.split(',').map(String::from).collect()).collect()
}

#[test]
fn writes_probes_profiles_and_summary() {
    let tmp = Scratch::new("files");
    let case = tmp.write("fast.toml", &fast_faucet());
    let out_dir = tmp.path("results");
    let out = cryofit(&["simulate", &case, "--out", out_dir.to_str().unwrap()]);
    assert_success(&out);
    // stderr is not a terminal here: no progress bar
    assert!(out.stderr.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("steps") && stdout.contains("mass balance") && stdout.contains("station mid"), "{stdout}");
    assert!(stdout.contains(out_dir.to_str().unwrap()), "{stdout}");

    // exactly the three files, no temporaries left behind
    let mut names: Vec<String> =
        std::fs::read_dir(&out_dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    names.sort();
    assert_eq!(names, ["probes.csv", "profiles.csv", "summary.json"]);

    let probes = read(&out_dir.join("probes.csv"));
    assert_eq!(probes.lines().next(), Some("time_s,station,x_m,quantity,value"));
    let rows = probe_rows(&out_dir);
    assert!(!rows.is_empty());
    let mut stations = BTreeSet::new();
    let mut quantities = BTreeSet::new();
    let mut times = BTreeSet::new();
    for row in &rows {
        assert_eq!(row.len(), 5, "{row:?}");
        let t: f64 = row[0].parse().unwrap();
        assert_eq!(row[2].parse::<f64>().unwrap(), 6.0);
        assert!(row[4].parse::<f64>().unwrap().is_finite(), "{row:?}");
        times.insert(t.to_bits());
        stations.insert(row[1].clone());
        quantities.insert(row[3].clone());
    }
    assert_eq!(stations, BTreeSet::from(["mid".to_string()]));
    assert_eq!(quantities, PROBE_QUANTITIES.iter().map(|q| q.to_string()).collect());
    assert!(times.len() >= 2, "probe times: {}", times.len());

    let profiles = read(&out_dir.join("profiles.csv"));
    assert_eq!(profiles.lines().next(), Some("time_s,x_m,quantity,value"));
    assert!(profiles.lines().skip(1).any(|l| l.split(',').nth(2) == Some("void_fraction")));
    assert!(profiles.lines().skip(1).all(|l| l.split(',').count() == 4));

    let s = summary(&out_dir);
    for key in SUMMARY_KEYS {
        assert!(s.get(key).is_some(), "summary.json has no '{key}': {s}");
    }
    assert!(s["steps"].as_u64().unwrap() > 0);
    assert!((s["simulated_time_s"].as_f64().unwrap() - 0.1).abs() < 1e-9);
    assert!(s["chilldown_time_s"].as_object().unwrap().contains_key("mid"));
    assert_eq!(s["case"], case.as_str());
    assert!(s["parameters"].as_object().unwrap().is_empty());
}

#[test]
fn default_output_directory_is_out_and_the_case_stem() {
    let tmp = Scratch::new("default-out");
    tmp.write("quick.toml", &fast_faucet());
    let out = cryofit_in(Some(&tmp.0), &["simulate", "quick.toml"]);
    assert_success(&out);
    for name in ["probes.csv", "profiles.csv", "summary.json"] {
        assert!(tmp.path("out/quick").join(name).is_file(), "no out/quick/{name}");
    }
}

#[test]
fn noise_is_reproducible_and_touches_only_its_quantity() {
    let tmp = Scratch::new("noise");
    let case = tmp.write("fast.toml", &fast_faucet());
    let run = |dir: &str, extra: &[&str]| -> PathBuf {
        let out_dir = tmp.path(dir);
        let mut args = vec!["simulate", case.as_str(), "--out", out_dir.to_str().unwrap()];
        args.extend_from_slice(extra);
        assert_success(&cryofit(&args));
        out_dir
    };
    let clean = run("clean", &[]);
    let noisy = ["--noise", "wall_temperature_k=0.5", "--seed", "3"];
    let a = run("a", &noisy);
    let b = run("b", &noisy);
    let other_seed = run("c", &["--noise", "wall_temperature_k=0.5", "--seed", "4"]);

    assert_eq!(read(&a.join("probes.csv")), read(&b.join("probes.csv")), "same seed, different probes");
    assert_eq!(read(&a.join("profiles.csv")), read(&clean.join("profiles.csv")), "profiles are never noisy");
    assert_ne!(read(&a.join("probes.csv")), read(&other_seed.join("probes.csv")), "seed has no effect");

    let (clean_rows, noisy_rows) = (probe_rows(&clean), probe_rows(&a));
    assert_eq!(clean_rows.len(), noisy_rows.len());
    let mut changed = 0;
    for (c, n) in clean_rows.iter().zip(&noisy_rows) {
        assert_eq!(c[..4], n[..4]);
        if c[3] == "wall_temperature_k" {
            let (vc, vn): (f64, f64) = (c[4].parse().unwrap(), n[4].parse().unwrap());
            assert!((vn - vc).abs() < 5.0, "noise of σ = 0.5 moved {vc} to {vn}");
            changed += usize::from(vc != vn);
        } else {
            assert_eq!(c, n, "only wall_temperature_k rows may change");
        }
    }
    assert!(changed > 0, "no wall temperature changed");
    let s = summary(&a);
    assert_eq!(s["seed"], 3);
    assert_eq!(s["noise"]["wall_temperature_k"], 0.5);
}

#[test]
fn set_overrides_params_file_which_overrides_the_case() {
    let tmp = Scratch::new("precedence");
    let case = tmp.write("fast.toml", &fast_faucet());
    let out_dir = tmp.path("set");
    assert_success(&cryofit(&["simulate", &case, "--out", out_dir.to_str().unwrap(), "--set", "vm_coeff=0.7"]));
    assert_eq!(summary(&out_dir)["parameters"], serde_json::json!({ "vm_coeff": 0.7 }));

    let case =
        tmp.write("with-params.toml", &format!("{}\n[parameters]\nvm_coeff = 0.6\nhi_vol = 5.0\n", fast_faucet()));
    let params = tmp.write("params.toml", "# calibrated\nvm_coeff = 0.9\nfwsc = 2\n");
    let out_dir = tmp.path("all");
    let out =
        cryofit(&["simulate", &case, "--out", out_dir.to_str().unwrap(), "--params", &params, "--set", "vm_coeff=0.7"]);
    assert_success(&out);
    assert_eq!(summary(&out_dir)["parameters"], serde_json::json!({ "vm_coeff": 0.7, "fwsc": 2.0, "hi_vol": 5.0 }));
}

#[test]
fn bad_parameters_give_one_line_errors() {
    let tmp = Scratch::new("bad-params");
    let case = tmp.write("fast.toml", &fast_faucet());
    let out_dir = tmp.path("never");
    let base = ["simulate", case.as_str(), "--out", out_dir.to_str().unwrap()];
    let with = |extra: &[&str]| -> Vec<String> { base.iter().chain(extra).map(|s| s.to_string()).collect() };

    assert_one_line_error(&with(&["--set", "nosuch=1"]), &["nosuch"]);
    assert_one_line_error(&with(&["--set", "vm_coeff=99"]), &["--set vm_coeff=99", "bounds"]);
    assert_one_line_error(&with(&["--set", "abc"]), &["--set abc", "NAME=VALUE"]);
    assert_one_line_error(&with(&["--set", "x=notanumber"]), &["--set x=notanumber", "not a number"]);

    let unknown = tmp.write("unknown.toml", "vm_coeff = 0.7\nbogus_key = 1.0\n");
    assert_one_line_error(&with(&["--params", &unknown]), &[&unknown, "bogus_key"]);
    let nested = tmp.write("nested.toml", "[parameters]\nvm_coeff = 0.7\n");
    assert_one_line_error(&with(&["--params", &nested]), &[&nested, "parameters"]);
    let text = tmp.write("text.toml", "vm_coeff = \"high\"\n");
    assert_one_line_error(&with(&["--params", &text]), &[&text, "vm_coeff", "number"]);
    let broken = tmp.write("broken.toml", "vm_coeff = = 1\n");
    assert_one_line_error(&with(&["--params", &broken]), &[&broken, "line 1"]);
    let missing = tmp.path("missing.toml").to_str().unwrap().to_string();
    assert_one_line_error(&with(&["--params", &missing]), &["cannot read", &missing]);

    // the case's own [parameters] are checked too, naming the file and the field
    let bad_case = tmp.write("bad.toml", &format!("{}\n[parameters]\nbogus = 1.0\n", fast_faucet()));
    assert_one_line_error(
        &["simulate", &bad_case, "--out", out_dir.to_str().unwrap()],
        &[&bad_case, "parameters.bogus"],
    );
    assert!(!out_dir.exists(), "a failed command created its output directory");
}

#[test]
fn bad_noise_gives_one_line_errors() {
    let tmp = Scratch::new("bad-noise");
    let case = tmp.write("fast.toml", &fast_faucet());
    let out_dir = tmp.path("never");
    let base = ["simulate", case.as_str(), "--out", out_dir.to_str().unwrap()];
    let with = |extra: &[&str]| -> Vec<String> { base.iter().chain(extra).map(|s| s.to_string()).collect() };
    assert_one_line_error(&with(&["--noise", "colour=1"]), &["colour", "wall_temperature_k", "mass_flow_kg_s"]);
    assert_one_line_error(&with(&["--noise", "wall_temperature_k=-0.5"]), &["wall_temperature_k=-0.5"]);
    assert_one_line_error(&with(&["--noise", "wall_temperature_k=inf"]), &["wall_temperature_k=inf"]);
    assert_one_line_error(&with(&["--noise", "wall_temperature_k"]), &["QUANTITY=SIGMA"]);
    assert_one_line_error(&with(&["--seed", "many"]), &["--seed"]);
    assert!(!out_dir.exists());
}

#[test]
fn bad_case_files_give_one_line_errors() {
    let tmp = Scratch::new("bad-case");
    let good = fast_faucet();
    let out_dir = tmp.path("never");
    let check = |name: &str, text: &str, needles: &[&str]| {
        assert_ne!(text, good, "{name}: the edit did not apply");
        let case = tmp.write(name, text);
        let mut all = vec![case.as_str()];
        all.extend_from_slice(needles);
        assert_one_line_error(&["simulate", &case, "--out", out_dir.to_str().unwrap()], &all);
    };
    check("colour.toml", &good.replace("[pipe]\n", "[pipe]\ncolour = 1\n"), &["colour"]);
    check("negative.toml", &good.replace("length_m = 12.0", "length_m = -12.0"), &["pipe.length_m"]);
    check("no-ambient.toml", &good.replace("[ambient]\ntemperature_k = 80.0\n", ""), &["ambient"]);
    check("helium.toml", &good.replace("name = \"nitrogen\"", "name = \"helium\""), &["fluid.name", "helium"]);
    let missing = tmp.path("missing.toml");
    assert_one_line_error(
        &["simulate", missing.to_str().unwrap(), "--out", out_dir.to_str().unwrap()],
        &["cannot read", missing.to_str().unwrap()],
    );
    assert!(!out_dir.exists());
}

#[test]
fn failed_run_writes_nothing() {
    let tmp = Scratch::new("failed-run");
    let case = tmp.write("stops.toml", &fast_faucet().replace("[time]\n", "[time]\nmax_steps = 1\n"));
    let fresh = tmp.path("fresh");
    assert_one_line_error(&["simulate", &case, "--out", fresh.to_str().unwrap()], &[&case, "max_steps"]);
    assert!(!fresh.exists(), "a failed run created its output directory");
    // earlier results in the output directory are left as they were
    let old = tmp.path("old");
    std::fs::create_dir_all(&old).unwrap();
    std::fs::write(old.join("probes.csv"), "earlier\n").unwrap();
    assert_one_line_error(&["simulate", &case, "--out", old.to_str().unwrap()], &["max_steps"]);
    assert_eq!(read(&old.join("probes.csv")), "earlier\n");
    assert_eq!(std::fs::read_dir(&old).unwrap().count(), 1);
}

#[test]
fn params_lists_the_registry() {
    let out = cryofit(&["params", "--json"]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let list = v.as_array().expect("a JSON list");
    assert!(!list.is_empty());
    let want: BTreeSet<&str> = ["name", "group", "default", "lower", "upper", "unit", "description"].into();
    for p in list {
        let keys: BTreeSet<&str> = p.as_object().unwrap().keys().map(String::as_str).collect();
        assert_eq!(keys, want, "{p}");
        let (d, lo, hi) = (p["default"].as_f64().unwrap(), p["lower"].as_f64().unwrap(), p["upper"].as_f64().unwrap());
        assert!(lo <= d && d <= hi, "{p}");
    }
    let vm = list.iter().find(|p| p["name"] == "vm_coeff").expect("vm_coeff is listed");
    assert!(vm["group"].is_string() && vm["unit"].is_string() && vm["description"].is_string());

    let out = cryofit(&["params"]);
    assert_success(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    assert_eq!(header, ["NAME", "GROUP", "DEFAULT", "LOWER", "UPPER", "UNIT", "DESCRIPTION"]);
    assert_eq!(lines.count(), list.len());
    assert!(text.lines().any(|l| l.starts_with("vm_coeff ")), "{text}");
}

/// `--data` compares the run with measurements: a run against its own probes fits exactly; against
/// the same probes with noise on one quantity, only that quantity's RMS moves, by about the noise;
/// the comparison is printed and kept in summary.json; data the case does not probe is refused
/// with the file and the station named, before anything is written.
#[test]
fn data_compares_the_run_with_measurements() {
    let tmp = Scratch::new("data");
    let case = tmp.write("fast.toml", &fast_faucet());
    let run = |dir: &str, extra: &[&str]| -> (PathBuf, Output) {
        let out_dir = tmp.path(dir);
        let mut args = vec!["simulate", case.as_str(), "--out", out_dir.to_str().unwrap()];
        args.extend_from_slice(extra);
        let out = cryofit(&args);
        assert_success(&out);
        (out_dir, out)
    };
    let (clean, _) = run("clean", &[]);
    let (noisy, _) = run("noisy", &["--noise", "void_fraction=0.01", "--seed", "5"]);

    let own = clean.join("probes.csv");
    let (dir, out) = run("own", &["--data", own.to_str().unwrap()]);
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("against ") && stdout.contains("RMS 0 over"), "{stdout}");
    let fit = &summary(&dir)["fit"];
    let series = fit["series"].as_array().expect("fit.series");
    assert!(!series.is_empty());
    assert!(series.iter().all(|s| s["rms"] == 0.0), "{series:?}");
    // the wall's heat release, read alike from both: the same at every time, and printed
    let heat = fit["heat_released"].as_array().expect("fit.heat_released");
    assert_eq!(heat.len(), 6, "{heat:?}");
    assert!(heat.iter().all(|h| h["data_j"].as_f64().is_some() && h["data_j"] == h["model_j"]), "{heat:?}");
    assert!(stdout.contains("heat released by the wall"), "{stdout}");

    // the run's own probes on a clock 10 % slower: the misfit is all timing, which the aligned
    // RMS removes (the model's times ×1/1.1 the data's, to the search's resolution)
    let probes = read(&own);
    let end = probes.lines().skip(1).filter_map(|l| l.split(',').next()?.parse::<f64>().ok()).fold(0.0, f64::max);
    let mut slow = String::from("time_s,station,x_m,quantity,value\n");
    for line in probes.lines().skip(1) {
        let (t, rest) = line.split_once(',').unwrap();
        let t: f64 = t.parse().unwrap();
        if 1.1 * t <= end {
            slow.push_str(&format!("{},{rest}\n", 1.1 * t));
        }
    }
    let slow = tmp.write("slow.csv", &slow);
    let (dir, out) = run("slow", &["--data", slow.as_str()]);
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("with its timing removed (the model's times ×0.909 the data's)"), "{stdout}");
    let mut moved = 0;
    for s in summary(&dir)["fit"]["series"].as_array().unwrap() {
        let (rms, aligned, r) =
            (s["rms"].as_f64().unwrap(), s["aligned_rms"].as_f64().unwrap(), s["time_scale"].as_f64());
        assert!(aligned <= rms, "{s}");
        if rms > 0.0 {
            moved += 1;
            assert!(aligned < 0.2 * rms, "{s}");
            assert!((r.unwrap() - 1.0 / 1.1).abs() < 0.005, "{s}");
        }
    }
    assert!(moved > 0, "no series changed with the clock");

    let noisy_data = noisy.join("probes.csv");
    let (dir, _) = run("against-noisy", &["--data", noisy_data.to_str().unwrap()]);
    let fit = &summary(&dir)["fit"];
    for s in fit["series"].as_array().unwrap() {
        let rms = s["rms"].as_f64().unwrap();
        if s["quantity"] == "void_fraction" {
            assert!(rms > 0.003 && rms < 0.03, "void fraction RMS {rms} against noise of σ = 0.01");
        } else {
            assert_eq!(rms, 0.0, "{s}");
        }
    }

    let bad = tmp.write("bad.csv", "time_s,station,x_m,quantity,value\n0,elsewhere,1.0,pressure_pa,1e5\n");
    let out_dir = tmp.path("refused");
    assert_one_line_error(
        &["simulate", case.as_str(), "--out", out_dir.to_str().unwrap(), "--data", bad.as_str()],
        &["--data", "bad.csv", "elsewhere"],
    );
    assert!(!out_dir.exists(), "a refused comparison wrote {}", out_dir.display());
    assert_one_line_error(&["simulate", case.as_str(), "--data", "/nonexistent/data.csv"], &["--data", "data.csv"]);
}

/// `steps.csv` rows split into fields (header checked and excluded).
fn step_rows(dir: &Path) -> Vec<Vec<String>> {
    let text = read(&dir.join("steps.csv"));
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header, ["time_s", "dt_s", "outcome", "variable", "index", "value", "reason"]);
    reader.records().map(|r| r.unwrap().iter().map(String::from).collect()).collect()
}

const NBS_SUBCOOLED: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs/subcooled-4.2atm.toml");

#[test]
fn step_log_lists_every_attempt_as_the_summary_counts_them() {
    let tmp = Scratch::new("step-log");
    let out_dir = tmp.path("results");
    // 10 cells, the first 2 s: the first-contact surge rejects steps
    let args = ["simulate", NBS_SUBCOOLED, "--set", "case.pipe.cells=10", "--set", "case.time.end_s=2", "--step-log"];
    let out = cryofit(&[&args[..], &["--out", out_dir.to_str().unwrap()]].concat());
    assert_success(&out);
    let s = summary(&out_dir);
    let rows = step_rows(&out_dir);
    let accepted: Vec<&Vec<String>> = rows.iter().filter(|r| r[2] == "accepted").collect();
    let rejected: Vec<&Vec<String>> = rows.iter().filter(|r| r[2] == "rejected").collect();
    assert_eq!(accepted.len() + rejected.len(), rows.len(), "an outcome is neither accepted nor rejected");
    assert_eq!(accepted.len() as u64, s["steps"].as_u64().unwrap());
    assert_eq!(rejected.len() as u64, s["rejected_steps"].as_u64().unwrap());
    assert!(!rejected.is_empty(), "the case no longer rejects a step: choose one that does");
    // the accepted steps add up to the run, each starting where the one before ended
    let num = |r: &Vec<String>, k: usize| -> f64 { r[k].parse().unwrap() };
    let mut t = 0.0;
    for r in &accepted {
        assert!((num(r, 0) - t).abs() <= 1e-9, "step at {} after the run reached {t}", r[0]);
        t = num(r, 0) + num(r, 1);
        assert!((0.0..=1.0).contains(&num(r, 5)), "change ratio {} of an accepted step", r[5]);
        assert!(r[6].is_empty());
    }
    assert!((t - s["simulated_time_s"].as_f64().unwrap()).abs() <= 1e-9);
    // what limited and what rejected the steps, as the summary counts them
    let mut limited = std::collections::BTreeMap::<String, u64>::new();
    for r in &accepted {
        *limited.entry(r[3].clone()).or_default() += 1;
    }
    let counted: std::collections::BTreeMap<String, u64> =
        serde_json::from_value(s["step_limited_by"].clone()).unwrap();
    assert_eq!(limited, counted);
    let mut causes = std::collections::BTreeMap::<String, u64>::new();
    for r in &rejected {
        *causes.entry(format!("{}: {}", r[3], r[6])).or_default() += 1;
    }
    let counted: std::collections::BTreeMap<String, u64> =
        serde_json::from_value(s["rejection_causes"].clone()).unwrap();
    assert_eq!(causes, counted);
    // a rejected step is retried shorter from the same time
    for (k, r) in rows.iter().enumerate().filter(|(_, r)| r[2] == "rejected") {
        let retry = &rows[k + 1];
        assert_eq!(retry[0], r[0]);
        assert!(num(retry, 1) < num(r, 1));
    }
}

#[test]
fn step_log_of_a_failed_run_holds_its_steps_up_to_the_failure() {
    let tmp = Scratch::new("step-log-failed");
    let out_dir = tmp.path("results");
    let out = cryofit(&[
        "simulate",
        NBS_SUBCOOLED,
        "--set",
        "case.pipe.cells=10",
        "--set",
        "case.time.max_steps=40",
        "--step-log",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.contains("max_steps") && err.contains("steps.csv"), "{err}");
    let rows = step_rows(&out_dir);
    assert_eq!(rows.iter().filter(|r| r[2] == "accepted").count(), 40);
    // only the step log: no probes, profiles or summary of a run that did not finish
    assert_eq!(std::fs::read_dir(&out_dir).unwrap().count(), 1);
}
