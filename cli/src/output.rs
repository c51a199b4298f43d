//! The files and numbers every command writes: round-trip numbers, `probes.csv`, the atomic
//! write of an output folder, and the chilldown times of model and data side by side.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use cryofit_calib::data::Dataset;
use cryofit_solver::driver::{Observation, Output};

use crate::csv_text::CsvText;

/// A number that reads back to the same `f64`: plain decimals for ordinary magnitudes,
/// scientific notation otherwise (both are Rust's shortest round-trip forms).
pub(crate) fn fmt_num(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() || (1e-3..1e6).contains(&a) { format!("{v}") } else { format!("{v:e}") }
}

/// `probes.csv` (also each `fit-<experiment>.csv` of a calibration): the long format of DESIGN.md
/// §3.2.
pub(crate) fn probes_csv(probes: &[Observation]) -> Result<String> {
    let mut t = CsvText::new(cryofit_calib::data::HEADER.split(','))?;
    for o in probes {
        t.row([&fmt_num(o.time_s), o.station.as_str(), &fmt_num(o.x_m), o.quantity, &fmt_num(o.value)])?;
    }
    t.finish()
}

/// Creates `dir` and writes every file under a temporary name first, then renames them all: a
/// failed write leaves no partial file behind (and leaves earlier results in place).
pub(crate) fn write_outputs<N: AsRef<str>, C: AsRef<[u8]>>(dir: &Path, files: &[(N, C)]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create output directory {}", dir.display()))?;
    let pid = std::process::id();
    let temps: Vec<(PathBuf, PathBuf)> = files
        .iter()
        .map(|(name, _)| (dir.join(format!(".{}.{pid}.tmp", name.as_ref())), dir.join(name.as_ref())))
        .collect();
    let cleanup = |temps: &[(PathBuf, PathBuf)]| {
        for (tmp, _) in temps {
            let _ = std::fs::remove_file(tmp);
        }
    };
    for ((tmp, _), (_, contents)) in temps.iter().zip(files) {
        if let Err(e) = std::fs::write(tmp, contents.as_ref()) {
            cleanup(&temps);
            return Err(e).with_context(|| format!("cannot write {}", tmp.display()));
        }
    }
    for (k, (tmp, dest)) in temps.iter().enumerate() {
        if let Err(e) = std::fs::rename(tmp, dest) {
            cleanup(&temps[k..]);
            return Err(e).with_context(|| format!("cannot rename {} to {}", tmp.display(), dest.display()));
        }
    }
    Ok(())
}

/// A `cryofit calibrate` output folder's `result.json`: its path and contents. `flag` is how the
/// command names the folder in errors (`--from`, or nothing for a positional argument).
pub(crate) fn read_result_json(dir: &Path, flag: &str) -> Result<(PathBuf, serde_json::Value)> {
    let path = dir.join("result.json");
    let named = if flag.is_empty() { dir.display().to_string() } else { format!("{flag} {}", dir.display()) };
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{named}: cannot read result.json (is it a `cryofit calibrate` output folder?)"))?;
    let value = serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", path.display()))?;
    Ok((path, value))
}

/// First time a series falls below `threshold`, linearly interpolated; `None` if it never does.
pub(crate) fn first_below(times: &[f64], values: &[f64], threshold: f64) -> Option<f64> {
    if values.first().is_some_and(|&v| v < threshold) {
        return times.first().copied();
    }
    for k in 1..values.len() {
        if values[k] < threshold && values[k - 1] >= threshold {
            let w = (values[k - 1] - threshold) / (values[k - 1] - values[k]);
            return Some(times[k - 1] + w * (times[k] - times[k - 1]));
        }
    }
    None
}

/// Chilldown times (wall below the inlet liquid temperature + 15 K) of data and model, per station.
pub(crate) fn chilldown_pairs(data: &Dataset, out: &Output) -> BTreeMap<String, (Option<f64>, Option<f64>)> {
    let threshold = out.summary.inlet_liquid_temperature_k + cryofit_solver::driver::CHILLDOWN_MARGIN_K;
    let mut m = BTreeMap::new();
    for ((station, quantity), s) in &data.series {
        if quantity != "wall_temperature_k" {
            continue;
        }
        let model = out.summary.chilldown_time_s.get(station).copied().flatten();
        m.insert(station.clone(), (first_below(&s.times, &s.values, threshold), model));
    }
    m
}

/// Four significant digits.
pub(crate) fn fmt_sig(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a != 0.0 && !(1e-3..1e5).contains(&a) { format!("{v:.3e}") } else { format!("{}", (v * 1e4).round() / 1e4) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip() {
        for v in [0.0, -0.0, 1.0, 0.1, 77.355, 1e5, 123456.789, 1e-7, 6.02e23, -3.5e-300, f64::MIN_POSITIVE, 1.0 / 3.0]
        {
            let s = fmt_num(v);
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{v} -> {s}");
        }
        assert_eq!(fmt_num(80.0), "80");
        assert_eq!(fmt_num(1e-7), "1e-7");
    }

    #[test]
    fn probes_with_any_station_name_read_back_as_data() {
        let obs = |station: &str, t: f64| Observation {
            time_s: t,
            station: station.into(),
            x_m: 6.1,
            quantity: "wall_temperature_k",
            value: 290.0 - t,
        };
        let name = "TS \"1\",\nnorth";
        let text = probes_csv(&[obs(name, 0.0), obs(name, 0.5), obs("TS2", 0.0)]).unwrap();
        assert!(text.starts_with("time_s,station,x_m,quantity,value\n0,\"TS \"\"1\"\",\nnorth\",6.1,"), "{text}");
        let data = Dataset::from_csv(&text, "probes.csv").unwrap();
        let s = &data.series[&(name.to_string(), "wall_temperature_k".to_string())];
        assert_eq!((s.times.as_slice(), s.values.as_slice()), ([0.0, 0.5].as_slice(), [290.0, 289.5].as_slice()));
        assert_eq!(data.len(), 3);
    }
}
