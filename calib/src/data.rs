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
    /// The file (or source name) the text came from.
    pub file: String,
    /// The line the faulty record starts on (1-based).
    pub line: usize,
    /// What is wrong, naming the field.
    pub message: String,
}

/// The header every data file starts with (after comment lines).
pub const HEADER: &str = "time_s,station,x_m,quantity,value";

/// The records of a long-format CSV text: comment lines (`#` first) and blank lines skipped,
/// fields split by the csv crate (double-quoted fields may hold commas, `""` and line breaks).
/// Each record comes with the line it starts on; an error with the line where it lies.
fn records(text: &str) -> impl Iterator<Item = Result<(usize, csv::StringRecord), (usize, String)>> + '_ {
    let mut reader =
        csv::ReaderBuilder::new().has_headers(false).flexible(true).comment(Some(b'#')).from_reader(text.as_bytes());
    let mut record = csv::StringRecord::new();
    let mut done = false;
    std::iter::from_fn(move || {
        loop {
            if done {
                return None;
            }
            let before = reader.position().clone();
            match reader.read_record(&mut record) {
                Ok(false) => return None,
                Ok(true) => {
                    if record.len() <= 1 && record.iter().all(|f| f.trim().is_empty()) {
                        continue; // a line of blanks
                    }
                    let (byte, line) = record_start(text, before.byte() as usize, before.line() as usize);
                    // a quote left open runs to the end of the text (the csv crate reads it leniently)
                    let at_end = reader.position().byte() as usize >= text.len();
                    if at_end && text[byte..].matches('"').count() % 2 == 1 {
                        done = true;
                        return Some(Err((line, "unterminated quoted field".into())));
                    }
                    return Some(Ok((line, record.clone())));
                }
                Err(e) => {
                    done = true;
                    let line = e.position().map_or(before.line(), csv::Position::line) as usize;
                    return Some(Err((line, format!("cannot read the record: {e}"))));
                }
            }
        }
    })
}

/// Where the record read from `byte` (on `line`) starts: past the blank and comment lines that
/// the reader skips before it (the reader's positions count from the end of the previous record).
fn record_start(text: &str, mut byte: usize, mut line: usize) -> (usize, usize) {
    let bytes = text.as_bytes();
    loop {
        match bytes.get(byte) {
            Some(b'\n') => (byte, line) = (byte + 1, line + 1),
            Some(b'\r') => byte += 1,
            Some(b'#') => match text[byte..].find('\n') {
                Some(k) => (byte, line) = (byte + k + 1, line + 1),
                None => return (byte, line),
            },
            _ => return (byte, line),
        }
    }
}

impl Dataset {
    /// Parses long-format CSV text; `file` names the source in errors, with the line the faulty
    /// record starts on.
    pub fn from_csv(text: &str, file: &str) -> Result<Self, DataError> {
        let err = |line: usize, message: String| DataError { file: file.to_string(), line, message };
        // per series: station position and (time, value, line) rows
        type Rows = (f64, Vec<(f64, f64, usize)>);
        let mut rows: BTreeMap<SeriesKey, Rows> = BTreeMap::new();
        let mut header_seen = false;
        for record in records(text) {
            let (line_no, f) = record.map_err(|(line, message)| err(line, message))?;
            if !header_seen {
                let names: Vec<&str> = f.iter().map(str::trim).collect();
                if names.join(",") != HEADER {
                    let found = text.lines().nth(line_no - 1).unwrap_or("").trim();
                    return Err(err(line_no, format!("expected the header `{HEADER}`, found `{found}`")));
                }
                header_seen = true;
                continue;
            }
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

    /// Writes the dataset back as long-format CSV (no comment header); fields that hold a comma,
    /// a quote or a line break are quoted, so [`Dataset::from_csv`] reads the text back.
    pub fn to_csv(&self) -> String {
        let mut w = csv::WriterBuilder::new().terminator(csv::Terminator::Any(b'\n')).from_writer(Vec::new());
        // writing into memory cannot fail: the only errors of the csv writer are I/O errors and
        // records of unequal length, and every record here has five fields
        let mut row = |fields: [&str; 5]| w.write_record(fields).expect("a five-field record written to memory");
        row(["time_s", "station", "x_m", "quantity", "value"]);
        for ((station, quantity), s) in &self.series {
            let x = s.x_m.to_string();
            for (t, v) in s.times.iter().zip(&s.values) {
                row([&t.to_string(), station, &x, quantity, &v.to_string()]);
            }
        }
        let bytes = w.into_inner().expect("flushing into memory cannot fail");
        String::from_utf8(bytes).expect("the records are UTF-8 text")
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

    #[test]
    fn a_quoted_field_with_a_comma_a_quote_and_a_line_break_round_trips() {
        let name = "TS \"north\",\nrow 2";
        let mut d = Dataset::default();
        d.series.insert(
            (name.to_string(), "wall_temperature_k".to_string()),
            Series { x_m: 6.1, times: vec![0.0, 0.5], values: vec![290.0, 1.0 / 3.0] },
        );
        d.series.insert(
            ("TS2".to_string(), "pressure_pa".to_string()),
            Series { x_m: 24.4, times: vec![1e-7], values: vec![101_325.0] },
        );
        let text = d.to_csv();
        assert!(text.contains("\"TS \"\"north\"\",\nrow 2\""), "{text}");
        let back = Dataset::from_csv(&text, "d.csv").unwrap();
        assert_eq!(back, d);
        assert_eq!(back.to_csv(), text);
    }

    #[test]
    fn error_lines_are_those_the_record_starts_on() {
        // a record spanning lines 3–4 (a quoted line break), then a bad one on line 6
        let text = "# c\ntime_s,station,x_m,quantity,value\n0,\"A\nB\",1,pressure_pa,3\n\n1,C,1,pressure,4\n";
        let e = Dataset::from_csv(text, "d.csv").unwrap_err();
        assert_eq!((e.line, e.file.as_str()), (6, "d.csv"), "{e}");
        assert!(e.to_string().starts_with("d.csv:6: unknown quantity `pressure`"), "{e}");
        let e = Dataset::from_csv("time_s,station,x_m,quantity,value\r\n0,A,1,pressure_pa\r\n", "d").unwrap_err();
        assert_eq!(e.to_string(), "d:2: expected 5 fields (time_s,station,x_m,quantity,value), found 4");
        let e = Dataset::from_csv("time_s,station,x_m,quantity,value\n0,\"A,1,pressure_pa,3\n", "d").unwrap_err();
        assert_eq!(e.to_string(), "d:2: unterminated quoted field");
        let dup = "time_s,station,x_m,quantity,value\n0,\"A\n\",1,pressure_pa,3\n0,\"A\n\",1,pressure_pa,4\n";
        let e = Dataset::from_csv(dup, "d").unwrap_err();
        assert!(e.to_string().starts_with("d:4: ") && e.to_string().contains("(lines 2 and 4)"), "{e}");
    }

    proptest::proptest! {
        #[test]
        fn any_station_name_and_values_round_trip(
            name in "[^#\\s][ -~\n\"]{0,12}[^\\s]",
            values in proptest::collection::vec(-1e6f64..1e6, 1..5),
        ) {
            let mut d = Dataset::default();
            let times: Vec<f64> = (0..values.len()).map(|k| k as f64 * 0.25).collect();
            d.series.insert((name.clone(), "pressure_pa".into()), Series { x_m: 1.5, times, values });
            let back = Dataset::from_csv(&d.to_csv(), "p.csv").unwrap();
            proptest::prop_assert_eq!(back, d);
        }
    }
}
