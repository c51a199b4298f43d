//! `cryofit report` on calibration output folders: every figure of a calibration with all kinds
//! of stages, notes for the figures a shorter calibration cannot have, and bad input.

use std::path::{Path, PathBuf};

mod common;
use common::{cryofit, ok};

/// The tiny case of the `tests` crate (NBS subcooled, 5 cells, 8 s) calibrated with `stages`.
fn calibrate(dir: &Path, stages: &str) -> PathBuf {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures");
    for name in ["tiny.toml", "tiny-data.csv"] {
        std::fs::copy(fixtures.join(name), dir.join(name)).unwrap();
    }
    let text = std::fs::read_to_string(fixtures.join("tiny-calibration.toml")).unwrap();
    let head = &text[..text.find("[[stages]]").unwrap()];
    let file = dir.join("cal.toml");
    std::fs::write(&file, format!("{head}{stages}")).unwrap();
    let out = dir.join("out");
    ok(&cryofit(&["calibrate", &file.display().to_string(), "--workers", "2", "--out", &out.display().to_string()]));
    out
}

/// Every kind of stage, the MCMC stage long enough (40 iterations of 8 walkers) for its samples to
/// surround the best point: with 48 evaluations (3 iterations kept) the best point lay at the edge
/// of the samples, and the report rightly declined to draw a band that excluded it; with 160 (20
/// iterations, R-hat 6.7) whether it did was the chain's chance (seed 7 of `tiny-calibration.toml`
/// left the best `Gwsc` at the samples' 95 % quantile on the solver whose end throttles' heat
/// leaves with the outflow, seeds 1–3 did not); with 320 seeds 7 and 1–3 all drew the band. With
/// dryout bounded by the intermittent/annular transition the tiny case's cost is as ragged in
/// `hg0sc` as before (station 1 on 5 cells over 8 s) and its best point lies elsewhere: with 320
/// evaluations the best point lies inside the 5–95 % range of 12 posterior runs for seeds 1 and 7,
/// not for seeds 2–5 (6 runs: seed 1 only). Whether the chain holds its best point is the chain's
/// chance on this fixture, so the fit figure must carry either the band or the reason it is not
/// drawn; with seed 7 and 12 runs it carries the band. The sensitivity stage keeps both
/// parameters (`threshold = 0.01`), so that the pairwise figure has a pair: since a cell's phase
/// change is held only where it takes nearly all of a phase, `Gwsc` ranks at 0.04 of `hg0sc` on
/// this case, below the default threshold of 0.05.
const ALL_STAGES: &str = r#"
[[stages]]
algorithm = "sensitivity"
budget = 5
threshold = 0.01

[[stages]]
algorithm = "cmaes"
budget = 12
population = 6

[[stages]]
algorithm = "variance"
budget = 24
step = 0.05
restarts = 1

[[stages]]
algorithm = "mcmc"
budget = 320
walkers = 8
"#;

#[test]
fn every_figure_of_a_calibration_with_every_kind_of_stage() {
    let dir = common::scratch("report", "all");
    let out = calibrate(&dir, ALL_STAGES);
    let report = dir.join("report");
    let text = ok(&cryofit(&[
        "report",
        &out.display().to_string(),
        "--out",
        &report.display().to_string(),
        "--band-draws",
        "12",
    ]));
    assert!(text.contains("7 figures"), "{text}");
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    for name in [
        "cost-history",
        "parameter-traces",
        "sensitivity",
        "posterior-marginals",
        "posterior-corner",
        "fit-tiny-wall-temperature",
        "boiling-curve",
    ] {
        let svg = std::fs::read_to_string(report.join(format!("{name}.svg"))).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(svg.starts_with("<svg") && svg.contains("</svg>"), "{name}");
        let png = std::fs::read(report.join(format!("{name}.png"))).unwrap();
        assert_eq!(&png[..4], b"\x89PNG", "{name}");
        assert!(index.contains(&format!("<img src=\"{name}.svg\"")), "{name} not in the index");
    }
    assert!(!index.contains("Not drawn"), "{index}");
    let fit = std::fs::read_to_string(report.join("fit-tiny-wall-temperature.svg")).unwrap();
    for station in ["TS1", "TS2", "TS3", "TS4"] {
        assert!(fit.contains(&format!("station {station}")), "{station}");
    }
    assert!(
        fit.contains("posterior predictive")
            || fit.contains("no posterior-predictive band: the best fit lies inside the 12 posterior runs"),
        "neither the band nor the reason it is not drawn"
    );
    let boiling = std::fs::read_to_string(report.join("boiling-curve.svg")).unwrap();
    assert!(boiling.contains("p = 7 atm") && boiling.contains("wall heat flux (W/m²)"));
    // nothing left behind but the files
    let leftovers: Vec<_> = std::fs::read_dir(&report)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn missing_inputs_are_noted_and_bad_sources_refused() {
    let dir = common::scratch("report", "short");
    let out = calibrate(&dir, "[[stages]]\nalgorithm = \"cmaes\"\nbudget = 12\npopulation = 6\n");
    let report = dir.join("report");
    let text = ok(&cryofit(&["report", &out.display().to_string(), "--out", &report.display().to_string()]));
    assert!(text.contains("skipped sensitivity: the calibration has no sensitivity or Morris stage"), "{text}");
    assert!(text.contains("skipped posterior-marginals"), "{text}");
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert!(index.contains("Not drawn: the calibration has no sensitivity or Morris stage"), "{index}");
    assert!(!report.join("sensitivity.svg").exists());
    assert!(report.join("fit-tiny-wall-temperature.png").exists() && report.join("boiling-curve.svg").exists());

    let fail = |args: &[&str], want: &str| {
        let o = cryofit(args);
        assert!(!o.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    };
    let r = report.display().to_string();
    fail(&["report", "no-such-thing", "--out", &r], "neither an existing folder nor a calibration id");
    fail(&["report", &dir.display().to_string(), "--out", &r], "no calibration.sqlite here");
    fail(&["report", "7", "--coordinator", "http://127.0.0.1:9", "--out", &r], "calibration 7 on http://127.0.0.1:9");
    fail(&["report", &out.display().to_string(), "--out", &r, "--band-draws", "5000"], "--band-draws 5000");
}
