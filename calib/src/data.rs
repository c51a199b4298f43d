//! Measured (or simulated) time series in the long format of DESIGN.md §3.2:
//! `time_s,station,x_m,quantity,value`, one observation a row, `#` comment lines allowed.
//!
//! Parsing works on text; reading the file is the caller's business.

use std::collections::BTreeMap;

/// The quantities a time series may hold: what a simulation probes (the solver's list).
pub use cryofit_solver::driver::PROBE_QUANTITIES as QUANTITIES;

/// One station's series of one quantity, sorted by time.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Station position, m.
    pub x_m: f64,
    /// Times, s, strictly increasing.
    pub times: Vec<f64>,
    /// Values, SI.
    pub values: Vec<f64>,
}

impl Series {
    /// Linear interpolation at `t`; `None` outside the series' time range.
    pub fn at(&self, t: f64) -> Option<f64> {
        let n = self.times.len();
        if n == 0 || t < self.times[0] || t > self.times[n - 1] {
            return None;
        }
        let k = self.times.partition_point(|&x| x < t);
        if k < n && self.times[k] == t {
            return Some(self.values[k]);
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let w = (t - t0) / (t1 - t0);
        Some(self.values[k - 1] + w * (self.values[k] - self.values[k - 1]))
    }
}

/// Key of a series: (station, quantity).
pub type SeriesKey = (String, String);

/// A set of time series keyed by station and quantity.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Dataset {
    pub series: BTreeMap<SeriesKey, Series>,
}

/// Why a data file could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct DataError {
    pub file: String,
    pub line: usize,
    pub message: String,
}

/// The header every data file starts with (after comment lines).
pub const HEADER: &str = "time_s,station,x_m,quantity,value";

/// Splits a CSV line with optional double-quoted fields (`""` inside quotes is a quote).
fn split_csv(line: &str) -> Result<Vec<String>, String> {
    let mut fields = Vec::new();
    let mut cur = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (false, ',') => fields.push(std::mem::take(&mut cur)),
            (false, '"') if cur.is_empty() => quoted = true,
            (true, '"') => {
                if chars.peek() == Some(&'"') {
                    chars.next();
                    cur.push('"');
                } else {
                    quoted = false;
                }
            }
            (_, c) => cur.push(c),
        }
    }
    if quoted {
        return Err("unterminated quoted field".into());
    }
    fields.push(cur);
    Ok(fields)
}

impl Dataset {
    /// Parses long-format CSV text; `file` names the source in errors.
    pub fn from_csv(text: &str, file: &str) -> Result<Self, DataError> {
        let err = |line: usize, message: String| DataError { file: file.to_string(), line, message };
        // per series: station position and (time, value, line) rows
        type Rows = (f64, Vec<(f64, f64, usize)>);
        let mut rows: BTreeMap<SeriesKey, Rows> = BTreeMap::new();
        let mut header_seen = false;
        for (k, raw) in text.lines().enumerate() {
            let line_no = k + 1;
            let line = raw.trim_end_matches('\r');
            if line.trim().is_empty() || line.starts_with('#') {
                continue;
            }
            if !header_seen {
                if line.trim() != HEADER {
                    return Err(err(line_no, format!("expected the header `{HEADER}`, found `{}`", line.trim())));
                }
                header_seen = true;
                continue;
            }
            let f = split_csv(line).map_err(|m| err(line_no, m))?;
            if f.len() != 5 {
                return Err(err(line_no, format!("expected 5 fields ({HEADER}), found {}", f.len())));
            }
            let num = |i: usize, name: &str| -> Result<f64, DataError> {
                let v: f64 = f[i]
                    .trim()
                    .parse()
                    .map_err(|_| err(line_no, format!("{name} `{}` is not a number", f[i].trim())))?;
                if !v.is_finite() {
                    return Err(err(line_no, format!("{name} `{}` is not a finite number", f[i].trim())));
                }
                Ok(v)
            };
            let t = num(0, "time_s")?;
            let station = f[1].trim().to_string();
            if station.is_empty() {
                return Err(err(line_no, "empty station name".into()));
            }
            let x = num(2, "x_m")?;
            let quantity = f[3].trim().to_string();
            if !QUANTITIES.contains(&quantity.as_str()) {
                return Err(err(line_no, format!("unknown quantity `{quantity}` (known: {})", QUANTITIES.join(", "))));
            }
            let v = num(4, "value")?;
            let entry = rows.entry((station.clone(), quantity)).or_insert((x, Vec::new()));
            if entry.0 != x {
                return Err(err(
                    line_no,
                    format!("station `{station}` is at x_m = {} here but {x} elsewhere", entry.0),
                ));
            }
            entry.1.push((t, v, line_no));
        }
        if !header_seen {
            return Err(err(1, format!("no header `{HEADER}` and no data")));
        }
        let mut series = BTreeMap::new();
        for (key, (x_m, mut pts)) in rows {
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            for w in pts.windows(2) {
                if w[0].0 == w[1].0 {
                    return Err(err(
                        w[1].2,
                        format!(
                            "station `{}`, {}: time {} appears twice (lines {} and {})",
                            key.0, key.1, w[0].0, w[0].2, w[1].2
                        ),
                    ));
                }
            }
            let times = pts.iter().map(|p| p.0).collect();
            let values = pts.iter().map(|p| p.1).collect();
            series.insert(key, Series { x_m, times, values });
        }
        if series.is_empty() {
            return Err(err(1, "the file holds a header but no observations".into()));
        }
        Ok(Self { series })
    }

    /// Number of observations.
    pub fn len(&self) -> usize {
        self.series.values().map(|s| s.times.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Latest observation time, s.
    pub fn end_time(&self) -> f64 {
        self.series.values().filter_map(|s| s.times.last().copied()).fold(0.0, f64::max)
    }

    /// The quantities present.
    pub fn quantities(&self) -> Vec<String> {
        let mut q: Vec<String> = self.series.keys().map(|k| k.1.clone()).collect();
        q.sort();
        q.dedup();
        q
    }

    /// Writes the dataset back as long-format CSV (no comment header).
    pub fn to_csv(&self) -> String {
        let mut out = String::from(HEADER);
        out.push('\n');
        for ((station, quantity), s) in &self.series {
            for (t, v) in s.times.iter().zip(&s.values) {
                out.push_str(&format!("{t},{station},{},{quantity},{v}\n", s.x_m));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "# comment\ntime_s,station,x_m,quantity,value\n1,TS1,6.1,wall_temperature_k,280\n0,TS1,6.1,wall_temperature_k,290\n0,\"T,2\",24.4,wall_temperature_k,291\n";

    #[test]
    fn parses_sorts_and_interpolates() {
        let d = Dataset::from_csv(TEXT, "d.csv").unwrap();
        assert_eq!(d.len(), 3);
        let s = &d.series[&("TS1".to_string(), "wall_temperature_k".to_string())];
        assert_eq!(s.times, vec![0.0, 1.0]);
        assert_eq!(s.at(0.25), Some(287.5));
        assert_eq!(s.at(1.0), Some(280.0));
        assert_eq!(s.at(1.5), None);
        assert!(d.series.contains_key(&("T,2".to_string(), "wall_temperature_k".to_string())));
        let again = Dataset::from_csv(&d.to_csv().replace("T,2", "T2"), "x").unwrap();
        assert_eq!(again.len(), 3);
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let e = Dataset::from_csv("time_s,station,x_m,quantity,value\n0,A,1,wall_temp,3\n", "d.csv").unwrap_err();
        assert!(e.to_string().starts_with("d.csv:2: unknown quantity `wall_temp`"), "{e}");
        let e = Dataset::from_csv("time_s,station,x_m,quantity,value\n0,A,1,pressure_pa,NaN\n", "d.csv").unwrap_err();
        assert!(e.to_string().contains("value `NaN` is not a finite number"), "{e}");
        let e = Dataset::from_csv("t,s\n", "d.csv").unwrap_err();
        assert!(e.to_string().contains("expected the header"), "{e}");
        let dup = "time_s,station,x_m,quantity,value\n0,A,1,pressure_pa,3\n0,A,1,pressure_pa,4\n";
        assert!(Dataset::from_csv(dup, "d").unwrap_err().to_string().contains("appears twice"));
        let moved = "time_s,station,x_m,quantity,value\n0,A,1,pressure_pa,3\n1,A,2,pressure_pa,4\n";
        assert!(Dataset::from_csv(moved, "d").unwrap_err().to_string().contains("x_m"));
    }
}
