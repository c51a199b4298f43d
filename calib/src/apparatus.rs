//! Apparatus parameters: numeric fields of a case as parameters, beside the registry's closure
//! parameters.
//!
//! Naming convention (one place for it; calibration files, `--set`, `--params` files, `best.toml`,
//! `result.json`, `evaluations.csv` and `posterior.csv` all use it):
//!
//! - `case.<path>` is the case field at TOML path `<path>` (`case.inlet.loss_coefficient`), the
//!   same value for every experiment (one apparatus);
//! - `case.<path>@<experiment>` is that field in one experiment's case only: the per-experiment
//!   copy a calibration makes for each experiment listed in the parameter's `experiments`
//!   (`case.inlet.loss_coefficient@saturated-2.5atm`). `<experiment>` is the experiment's name:
//!   its `name` in the calibration file, or else its case file's stem. A path never holds `@`, so
//!   the name is everything after the first `@`.
//!
//! Where both a shared and a per-experiment value of one field apply to a case, the
//! per-experiment value holds (it is the more specific). Values of other experiments do not
//! apply and are returned as skipped, so that a caller can say so.

use std::collections::BTreeMap;

use cryofit_solver::case::{Case, FieldError};

/// The prefix of a case field's parameter name.
pub const CASE_PREFIX: &str = "case.";

/// What separates a per-experiment copy's field from its experiment's name.
pub const EXPERIMENT_MARK: char = '@';

/// A parameter name read as a case field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CaseName<'a> {
    /// The field's TOML path in the case (`inlet.loss_coefficient`).
    pub path: &'a str,
    /// The experiment of a per-experiment copy; `None` for a shared value.
    pub experiment: Option<&'a str>,
}

/// `name` read as a case field (`case.<path>` or `case.<path>@<experiment>`), or `None` for any
/// other name (a registry parameter).
pub fn case_name(name: &str) -> Option<CaseName<'_>> {
    let rest = name.strip_prefix(CASE_PREFIX)?;
    Some(match rest.split_once(EXPERIMENT_MARK) {
        Some((path, experiment)) => CaseName { path, experiment: Some(experiment) },
        None => CaseName { path: rest, experiment: None },
    })
}

/// True for a case field's name.
pub fn is_case_name(name: &str) -> bool {
    name.starts_with(CASE_PREFIX)
}

/// The name of the per-experiment copy of case field `name` (`case.<path>`) for `experiment`.
pub fn copy_name(name: &str, experiment: &str) -> String {
    format!("{name}{EXPERIMENT_MARK}{experiment}")
}

/// Named values sorted for one case.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Sorted {
    /// Registry (closure) parameters.
    pub registry: BTreeMap<String, f64>,
    /// Case fields that apply, by path (a per-experiment value over a shared one).
    pub case: BTreeMap<String, f64>,
    /// Per-experiment values of other experiments, by name: they do not apply.
    pub skipped: Vec<String>,
}

impl Sorted {
    /// The case fields as `Case::with_fields` takes them.
    pub fn case_fields(&self) -> Vec<(&str, f64)> {
        self.case.iter().map(|(p, v)| (p.as_str(), *v)).collect()
    }

    /// `case` with the case fields that apply set (the case itself where none does).
    pub fn apply(&self, case: &Case) -> Result<Case, FieldError> {
        case.with_fields(&self.case_fields())
    }
}

/// `case` with the case fields among `values` that apply to experiment `experiment` set one by
/// one (a per-experiment value over a shared one; registry names are passed over), or the name of
/// the first value the case refuses (as given: `case.<path>` or `case.<path>@<experiment>`) and why.
pub fn set_fields(values: &BTreeMap<String, f64>, case: &Case, experiment: &str) -> Result<Case, (String, FieldError)> {
    let mut case = case.clone();
    for (path, value) in sort(values, Some(experiment)).case {
        let shared = format!("{CASE_PREFIX}{path}");
        let specific = copy_name(&shared, experiment);
        let name = if values.contains_key(&specific) { specific } else { shared };
        case = case.with_fields(&[(path.as_str(), value)]).map_err(|error| (name, error))?;
    }
    Ok(case)
}

/// Sorts `values` for the case of `experiment` (`None`: a case that is no experiment's, to which
/// only shared values apply).
pub fn sort<'a>(values: impl IntoIterator<Item = (&'a String, &'a f64)>, experiment: Option<&str>) -> Sorted {
    let mut sorted = Sorted::default();
    let mut specific = BTreeMap::new();
    for (name, &value) in values {
        match case_name(name) {
            None => {
                sorted.registry.insert(name.clone(), value);
            }
            Some(CaseName { path, experiment: None }) => {
                sorted.case.insert(path.to_string(), value);
            }
            Some(CaseName { path, experiment: Some(e) }) if Some(e) == experiment => {
                specific.insert(path.to_string(), value);
            }
            Some(_) => sorted.skipped.push(name.clone()),
        }
    }
    sorted.case.extend(specific);
    sorted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_split_into_path_and_experiment() {
        assert_eq!(case_name("Gwsc"), None);
        assert_eq!(
            case_name("case.inlet.loss_coefficient"),
            Some(CaseName { path: "inlet.loss_coefficient", experiment: None })
        );
        let copy = copy_name("case.inlet.loss_coefficient", "saturated-2.5atm@x");
        assert_eq!(copy, "case.inlet.loss_coefficient@saturated-2.5atm@x");
        assert_eq!(
            case_name(&copy),
            Some(CaseName { path: "inlet.loss_coefficient", experiment: Some("saturated-2.5atm@x") })
        );
    }

    #[test]
    fn values_sort_by_kind_and_experiment() {
        let values: BTreeMap<String, f64> = [
            ("Gwsc", 1.5),
            ("case.inlet.loss_coefficient", 8.0),
            ("case.inlet.loss_coefficient@a", 9.0),
            ("case.inlet.valve_opening_time_s@b", 3.0),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        let a = sort(&values, Some("a"));
        assert_eq!(a.registry, BTreeMap::from([("Gwsc".to_string(), 1.5)]));
        assert_eq!(a.case, BTreeMap::from([("inlet.loss_coefficient".to_string(), 9.0)]), "specific over shared");
        assert_eq!(a.skipped, vec!["case.inlet.valve_opening_time_s@b".to_string()]);
        let none = sort(&values, None);
        assert_eq!(none.case, BTreeMap::from([("inlet.loss_coefficient".to_string(), 8.0)]));
        assert_eq!(none.skipped.len(), 2);
    }
}
