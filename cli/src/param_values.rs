//! Parameter values given on the command line or in a `--params` file: registry (closure)
//! parameters by their names and case fields by `case.<path>` names (see
//! [`cryofit_calib::apparatus`]), applied to one case.
//!
//! Decisions:
//! - A `--params` file is a TOML table of `name = number` lines. A case field is written with its
//!   name quoted (`"case.inlet.loss_coefficient" = 8.0`, as `best.toml` writes it), or as TOML's
//!   dotted keys or a `[case.inlet]` section (`case.inlet.loss_coefficient = 8.0`): both read as
//!   the same name. A per-experiment value's name must be quoted (`@` is not a bare-key character):
//!   `"case.inlet.loss_coefficient@saturated-2.5atm" = 7.9`.
//! - The case run is treated as the experiment `--experiment NAME`, by default the case file's
//!   stem (which is also an experiment's default name in a calibration): the per-experiment values
//!   of that name apply, over a shared value of the same field; those of other experiments are
//!   skipped, and the skipped names are printed on stderr.
//! - Sources apply in order of precedence, later over earlier: the case itself, `--params`, then
//!   each `--set`. Each source's case fields are set and the case validated again, so an error
//!   names the source, the case file, the field and the value.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result, anyhow, bail};
use cryofit_calib::apparatus;
use cryofit_solver::case::Case;
use cryofit_solver::driver;
use cryofit_solver::params::ParameterSet;

/// Named values from one source (`--params FILE` or a `--set`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamValues {
    /// Names the source in messages (`--params best.toml`, `--set vm_coeff=0.7`).
    pub source: String,
    /// The values by name (registry names and case fields).
    pub values: BTreeMap<String, f64>,
}

impl ParamValues {
    /// The registry values as a checked set (their names and bounds were checked on reading).
    pub fn registry(&self) -> Result<ParameterSet> {
        let mut set = ParameterSet::new();
        for (name, &v) in self.values.iter().filter(|(n, _)| !apparatus::is_case_name(n)) {
            set.set(name, v).map_err(|e| anyhow!("{}: {e}", self.source))?;
        }
        Ok(set)
    }

    /// Checks one value: a registry name and its bounds, or the form of a case field's name.
    fn insert(&mut self, name: &str, value: f64) -> Result<()> {
        if apparatus::is_case_name(name) {
            let field = apparatus::case_name(name).map(|c| c.path).unwrap_or_default();
            if field.is_empty() || field.split('.').any(str::is_empty) || !value.is_finite() {
                bail!(
                    "{}: {name} = {value}: give a case field as `case.<section>.<field>` and a finite number",
                    self.source
                );
            }
        } else {
            ParameterSet::new().set(name, value).map_err(|e| anyhow!("{}: {e}", self.source))?;
        }
        self.values.insert(name.to_string(), value);
        Ok(())
    }
}

/// Reads a `--params` file (see the module doc for its form).
pub(crate) fn read_params_file(path: &Path) -> Result<ParamValues> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {file}"))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| {
        let msg = e.message().trim().replace('\n', " ");
        match e.span() {
            Some(s) => anyhow!("{file}: line {}: {msg}", text[..s.start.min(text.len())].lines().count().max(1)),
            None => anyhow!("{file}: {msg}"),
        }
    })?;
    let mut values = ParamValues { source: file.clone(), values: BTreeMap::new() };
    let mut flat = Vec::new();
    flatten(&table, "", &mut flat).map_err(|e| anyhow!("{file}: {e}"))?;
    for (key, number) in flat {
        values.insert(&key, number)?;
    }
    Ok(values)
}

/// The `name = number` entries of `table`, the sections under `case` read as dotted names.
fn flatten(table: &toml::Table, prefix: &str, out: &mut Vec<(String, f64)>) -> Result<()> {
    for (key, value) in table {
        let name = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        let number = match value {
            toml::Value::Float(f) => *f,
            // integers are exact in f64 up to 2^53, far beyond any parameter bound
            toml::Value::Integer(i) => *i as f64,
            toml::Value::Table(t) if name == "case" || name.starts_with(apparatus::CASE_PREFIX) => {
                flatten(t, &name, out)?;
                continue;
            }
            toml::Value::Table(_) => bail!(
                "'{name}' is a table; the file must be a flat list of `name = number` lines (case fields under \
                 `case.`)"
            ),
            other => bail!("{name} = {other}: expected a number, found a {}", other.type_str()),
        };
        out.push((name, number));
    }
    Ok(())
}

/// One `--set NAME=VALUE`.
pub(crate) fn parse_set(arg: &str) -> Result<ParamValues> {
    let (name, value) = split_assignment(arg).ok_or_else(|| {
        anyhow!("--set {arg}: expected NAME=VALUE, e.g. --set vm_coeff=0.7 or --set case.inlet.loss_coefficient=8")
    })?;
    let value: f64 = value.parse().map_err(|_| anyhow!("--set {arg}: '{value}' is not a number"))?;
    let mut values = ParamValues { source: format!("--set {arg}"), values: BTreeMap::new() };
    values.insert(name, value)?;
    Ok(values)
}

/// `NAME=VALUE` split and trimmed; `None` when there is no `=` or the name is empty.
pub(crate) fn split_assignment(arg: &str) -> Option<(&str, &str)> {
    let (name, value) = arg.split_once('=')?;
    let name = name.trim();
    (!name.is_empty()).then_some((name, value.trim()))
}

/// A case with the values of some sources applied.
#[derive(Debug, Clone)]
pub struct Applied {
    /// The case with the case fields that apply set.
    pub case: Case,
    /// The case fields set, by path (the last source's value of each).
    pub case_fields: BTreeMap<String, f64>,
    /// Per-experiment values of other experiments, skipped.
    pub skipped: Vec<String>,
}

/// Applies the case fields of `sources` (in order, later over earlier) to `case` (`case_path`
/// names it), treating it as experiment `experiment`'s case.
pub(crate) fn apply_case_fields(
    case: &Case,
    case_path: &str,
    experiment: &str,
    sources: &[&ParamValues],
) -> Result<Applied> {
    let mut applied = Applied { case: case.clone(), case_fields: BTreeMap::new(), skipped: Vec::new() };
    for source in sources {
        let sorted = apparatus::sort(&source.values, Some(experiment));
        // the experiment matters to a message only where the source holds per-experiment values
        let per_experiment =
            source.values.keys().any(|n| apparatus::case_name(n).is_some_and(|c| c.experiment.is_some()));
        let taken_as = if per_experiment { format!(" (as experiment `{experiment}`)") } else { String::new() };
        applied.case = sorted
            .apply(&applied.case)
            .map_err(|e| anyhow!("{}: case field of {case_path}{taken_as}: {e}", source.source))?;
        applied.case_fields.extend(sorted.case.clone());
        applied.skipped.extend(sorted.skipped);
    }
    Ok(applied)
}

/// The case and the parameter set of the run, with precedence `--set` > `--params` > the case's
/// own `[parameters]` and fields > registry defaults; the case is taken as experiment
/// `experiment` for per-experiment values. Per-experiment values of other experiments are
/// reported on stderr ([`report_skipped`]). Returns the applied case fields, the parameter set and
/// the sources (`--params`, then each `--set`) as read.
pub(crate) fn case_parameters(
    case: &Case,
    case_path: &str,
    experiment: &str,
    params_file: Option<&Path>,
    sets: &[String],
) -> Result<(Applied, ParameterSet, Vec<ParamValues>)> {
    let mut params = driver::case_parameters(case).map_err(|e| anyhow!("{case_path}: {e}"))?;
    let mut sources = Vec::new();
    if let Some(file) = params_file {
        sources.push(read_params_file(file)?);
    }
    for arg in sets {
        sources.push(parse_set(arg)?);
    }
    for source in &sources {
        params.overlay(&source.registry()?);
    }
    let refs: Vec<&ParamValues> = sources.iter().collect();
    let applied = apply_case_fields(case, case_path, experiment, &refs)?;
    report_skipped(&applied.skipped, experiment);
    Ok((applied, params, sources))
}

/// The experiment a case file is taken for: `--experiment`, or its file stem.
pub(crate) fn experiment_of(case: &Path, given: Option<&str>) -> String {
    given
        .map(str::to_string)
        .unwrap_or_else(|| case.file_stem().map_or_else(|| "case".to_string(), |s| s.to_string_lossy().into_owned()))
}

/// Prints the skipped per-experiment values, if any, on stderr.
pub(crate) fn report_skipped(skipped: &[String], experiment: &str) {
    if !skipped.is_empty() {
        eprintln!(
            "note: skipped {} (values of other experiments; this case is taken as experiment `{experiment}`, \
             see --experiment)",
            skipped.join(", ")
        );
    }
}

/// A TOML key for `name`: bare where TOML allows it, quoted otherwise (every case field).
pub(crate) fn toml_key(name: &str) -> String {
    if !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        return name.to_string();
    }
    toml::Value::String(name.to_string()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> Result<ParamValues> {
        let dir = std::env::temp_dir().join(format!("cryofit-param-values-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("p{}.toml", text.len()));
        std::fs::write(&path, text).unwrap();
        let r = read_params_file(&path);
        std::fs::remove_file(&path).ok();
        r
    }

    #[test]
    fn case_fields_read_quoted_dotted_and_in_sections() {
        let v = file(
            "vm_coeff = 0.7\n\"case.inlet.loss_coefficient\" = 8.0\ncase.outlet.loss_coefficient = 2\n\
             \"case.inlet.valve_opening_time_s@saturated-2.5atm\" = 1.5\n[case.time]\nmax_dt_s = 0.25\n",
        )
        .unwrap();
        let names: Vec<&str> = v.values.keys().map(String::as_str).collect();
        assert_eq!(
            names,
            [
                "case.inlet.loss_coefficient",
                "case.inlet.valve_opening_time_s@saturated-2.5atm",
                "case.outlet.loss_coefficient",
                "case.time.max_dt_s",
                "vm_coeff"
            ]
        );
        assert_eq!(v.registry().unwrap().explicit().len(), 1);
        let e = file("[inlet]\nloss_coefficient = 3\n").unwrap_err().to_string();
        assert!(e.contains("'inlet' is a table"), "{e}");
        let e = file("vm_coef = 3\n").unwrap_err().to_string();
        assert!(e.contains("did you mean 'vm_coeff'"), "{e}");
        let e = file("\"case.\" = 3\n").unwrap_err().to_string();
        assert!(e.contains("give a case field as"), "{e}");
    }

    /// Every parameter file beside the NBS runs (`examples/nbs/calibrated*.toml`, the `--params`
    /// files of the validation) reads as `--params` reads it: registry values within their
    /// registry bounds, and case fields (the grid a fit was made on) that every NBS case accepts
    /// (a file copied from a calibration's `best.toml` must still be one `cryofit simulate
    /// --params` accepts as the registry and the cases stand).
    #[test]
    fn every_example_parameter_file_reads_as_params() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/nbs");
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".toml"))
            .collect();
        let cases: Vec<(String, Case)> = names
            .iter()
            .filter(|n| !n.starts_with("calibrate"))
            .map(|n| (n.clone(), Case::from_toml(&std::fs::read_to_string(dir.join(n)).unwrap(), n).unwrap()))
            .collect();
        assert_eq!(cases.len(), 6, "the six NBS cases");
        let mut seen = Vec::new();
        for name in names.iter().filter(|n| n.starts_with("calibrated")) {
            let values = read_params_file(&dir.join(name)).unwrap_or_else(|e| panic!("{e:#}"));
            assert!(!values.values.is_empty(), "{name}: no parameters");
            for (case_name, case) in &cases {
                let applied = apply_case_fields(case, case_name, "any", &[&values]).unwrap_or_else(|e| panic!("{e:#}"));
                assert!(applied.skipped.is_empty(), "{name}: per-experiment values {:?}", applied.skipped);
            }
            seen.push(name.clone());
        }
        seen.sort();
        assert_eq!(
            seen,
            [
                "calibrated-120.toml",
                "calibrated-fb.toml",
                "calibrated-regime.toml",
                "calibrated-six-drops.toml",
                "calibrated-six.toml",
                "calibrated.toml"
            ],
            "parameter files beside the runs"
        );
    }

    #[test]
    fn keys_are_quoted_where_toml_needs_it() {
        assert_eq!(toml_key("vm_coeff"), "vm_coeff");
        assert_eq!(toml_key("case.inlet.loss_coefficient"), "\"case.inlet.loss_coefficient\"");
        let line = format!("{} = 1.0", toml_key("case.inlet.k@a \"b\""));
        let t: toml::Table = toml::from_str(&line).unwrap();
        assert!(t.contains_key("case.inlet.k@a \"b\""), "{line}");
    }
}
