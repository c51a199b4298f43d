//! A case's numeric fields by their TOML path (`inlet.loss_coefficient`, `time.max_dt_s`): read
//! one, or set several and get a new case that passed the case's own validation.
//!
//! There is no hand-written list of settable fields. The case is serialised to its TOML structure
//! (a `toml::Table`, so numbers keep every bit), the path is set there, and the table is read back
//! with the case file's own deserialiser and validation: whatever a case file may hold in a number
//! field, a path may set, and whatever a case file may not hold is refused with the validation's
//! own message. Decisions:
//!
//! - A field that holds one number can be set: a float, or a whole number for an integer field
//!   (`pipe.cells`). A profile given as a number (`inlet.pressure_pa = 5e5`) is such a field; one
//!   given as a table of `[x, value]` points is not.
//! - Elements of lists (`stations`, the points of a profile table) have no path: they are refused
//!   with an error that says to edit the case file.
//! - A field a case leaves out (`time.max_wall_s`, an optional profile) can be set: it is added and
//!   the whole case checked, so a name the case file format does not know is refused by the same
//!   `deny_unknown_fields` that refuses it in a file.
//! - `parameters.<name>` is refused: the case's `[parameters]` are registry parameters, named by
//!   their own names.

use toml::Value;

use super::Case;

/// Why a case field cannot be read or set. Every message names the path and, where one was
/// given, the value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FieldError {
    /// The path is not dot-separated names.
    #[error("`{path}` is not a field path: give section and field names joined by dots (inlet.loss_coefficient)")]
    BadPath {
        /// The path given.
        path: String,
    },
    /// No such field in a case.
    #[error("`{path}` is not a field of a case{}", suggestion.as_ref().map(|s| format!("; did you mean `{s}`?")).unwrap_or_default())]
    Unknown {
        /// The path given.
        path: String,
        /// The closest numeric field of this case, if one is close.
        suggestion: Option<String>,
    },
    /// A path into the case's `[parameters]`, which hold registry parameters.
    #[error("`{path}`: the case's [parameters] are registry parameters; name the parameter `{name}` itself")]
    Registry {
        /// The path given.
        path: String,
        /// The registry name it names.
        name: String,
    },
    /// A path through a list (stations, the points of a profile table).
    #[error("`{path}`: `{list}` is a list, and list elements cannot be set by name; edit the case file instead")]
    InList {
        /// The path given.
        path: String,
        /// The part of the path that is a list.
        list: String,
    },
    /// A field that does not hold one number.
    #[error("`{path}` holds {found}, not a single number; only a field holding one number can be read or set")]
    NotNumber {
        /// The path given.
        path: String,
        /// What it holds, in words.
        found: &'static str,
    },
    /// A fractional value for an integer field.
    #[error("`{path}` = {value}: the field holds a whole number")]
    NotWhole {
        /// The path given.
        path: String,
        /// The value given.
        value: f64,
    },
    /// A field this case leaves out, read.
    #[error("`{path}` is not given in this case, so it has no value to read")]
    NotGiven {
        /// The path given.
        path: String,
    },
    /// The case refuses the values (its deserialiser or its validation): `message` names the field.
    #[error("{} makes the case invalid: {message}", assignments_text(assignments))]
    Invalid {
        /// The paths and values set.
        assignments: Vec<(String, f64)>,
        /// The case's reason.
        message: String,
    },
}

/// The unit a case field's name spells (the case format names units in field names): `s`, `m`,
/// `m/s`, `K`, `Pa`, `W/(m² K)`, `degrees`, or `-` for a count or a dimensionless number
/// (`loss_coefficient`, `void_fraction`, `cells`).
pub fn field_unit(path: &str) -> &'static str {
    const SUFFIXES: [(&str, &str); 7] = [
        ("_w_m2k", "W/(m² K)"),
        ("_m_s", "m/s"),
        ("_pa", "Pa"),
        ("_k", "K"),
        ("_deg", "degrees"),
        ("_m", "m"),
        ("_s", "s"),
    ];
    SUFFIXES.iter().find(|(suffix, _)| path.ends_with(suffix)).map_or("-", |(_, unit)| unit)
}

fn assignments_text(assignments: &[(String, f64)]) -> String {
    let parts: Vec<String> = assignments.iter().map(|(p, v)| format!("{p} = {v}")).collect();
    parts.join(", ")
}

impl Case {
    /// The value of the numeric field at `path` (`inlet.loss_coefficient`; see the module doc for
    /// which fields have one).
    pub fn field(&self, path: &str) -> Result<f64, FieldError> {
        let table = self.to_table();
        let segments = segments(path)?;
        let (parent, last) = parent_of(&table, path, &segments)?;
        match parent.get(last) {
            Some(v) => number_of(path, v),
            None => {
                // an optional field left out, or no field at all: ask the deserialiser
                let mut probe = table.clone();
                let (slot, last) = parent_mut(&mut probe, path, &segments)?;
                slot.insert(last.to_string(), Value::Float(1.0));
                match unknown_field(&probe) {
                    Some(_) => Err(unknown(&table, path)),
                    None => Err(FieldError::NotGiven { path: path.to_string() }),
                }
            }
        }
    }

    /// A copy of the case with each `(path, value)` set, in order, then read back and validated as a
    /// whole, as a case file would be (see the module doc). The case itself is not changed.
    pub fn with_fields(&self, values: &[(&str, f64)]) -> Result<Case, FieldError> {
        if values.is_empty() {
            return Ok(self.clone());
        }
        let assignments: Vec<(String, f64)> = values.iter().map(|&(p, v)| (p.to_string(), v)).collect();
        let invalid = |message: String| FieldError::Invalid { assignments: assignments.clone(), message };
        let original = self.to_table();
        let mut table = original.clone();
        for &(path, value) in values {
            if !value.is_finite() {
                return Err(invalid(format!("{path} = {value}: must be a finite number")));
            }
            set(&mut table, &original, path, value)?;
        }
        let case: Case = Value::Table(table).try_into().map_err(|e: toml::de::Error| invalid(one_line(&e)))?;
        case.validate().map_err(invalid)?;
        Ok(case)
    }

    /// The case as the TOML structure a case file parses to.
    fn to_table(&self) -> toml::Table {
        match Value::try_from(self) {
            Ok(Value::Table(t)) => t,
            // a case is a struct of numbers, strings, lists and sections: always a table
            _ => toml::Table::new(),
        }
    }
}

/// `path` split at its dots; every part a non-empty name.
fn segments(path: &str) -> Result<Vec<&str>, FieldError> {
    let parts: Vec<&str> = path.split('.').collect();
    if parts.iter().any(|p| p.trim().is_empty() || p.trim() != *p) {
        return Err(FieldError::BadPath { path: path.to_string() });
    }
    if parts[0] == "parameters" {
        return Err(FieldError::Registry { path: path.to_string(), name: parts[1..].join(".") });
    }
    Ok(parts)
}

/// The section holding the last segment of `path`, and that segment.
fn parent_of<'t>(
    table: &'t toml::Table,
    path: &str,
    segments: &[&'t str],
) -> Result<(&'t toml::Table, &'t str), FieldError> {
    let (last, sections) = segments.split_last().ok_or_else(|| FieldError::BadPath { path: path.to_string() })?;
    let mut cur = table;
    for (k, seg) in sections.iter().enumerate() {
        cur = match cur.get(*seg) {
            Some(Value::Table(t)) => t,
            Some(Value::Array(_)) => {
                return Err(FieldError::InList { path: path.to_string(), list: segments[..=k].join(".") });
            }
            _ => return Err(unknown(table, path)),
        };
    }
    Ok((cur, last))
}

/// [`parent_of`], mutable.
fn parent_mut<'t>(
    table: &'t mut toml::Table,
    path: &str,
    segments: &[&'t str],
) -> Result<(&'t mut toml::Table, &'t str), FieldError> {
    let (last, sections) = segments.split_last().ok_or_else(|| FieldError::BadPath { path: path.to_string() })?;
    let mut cur = table;
    for (k, seg) in sections.iter().enumerate() {
        cur = match cur.get_mut(*seg) {
            Some(Value::Table(t)) => t,
            Some(Value::Array(_)) => {
                return Err(FieldError::InList { path: path.to_string(), list: segments[..=k].join(".") });
            }
            _ => return Err(FieldError::Unknown { path: path.to_string(), suggestion: None }),
        };
    }
    Ok((cur, last))
}

/// The number a field holds, or what it holds instead.
fn number_of(path: &str, v: &Value) -> Result<f64, FieldError> {
    let found = match v {
        Value::Float(f) => return Ok(*f),
        // integer fields are counts (cells, steps): exact in f64
        Value::Integer(i) => return Ok(*i as f64),
        Value::Array(a) if a.iter().all(Value::is_array) && !a.is_empty() => "a table of [x, value] points",
        Value::Array(_) => "a list",
        Value::String(_) => "text",
        Value::Boolean(_) => "a switch (true or false)",
        Value::Table(_) => "a section",
        Value::Datetime(_) => "a date",
    };
    Err(FieldError::NotNumber { path: path.to_string(), found })
}

/// Sets `path` to `value` in `table` (`original` is the case before any change, for suggestions).
fn set(table: &mut toml::Table, original: &toml::Table, path: &str, value: f64) -> Result<(), FieldError> {
    let segments = segments(path)?;
    let probe = table.clone();
    let (parent, last) = parent_mut(table, path, &segments).map_err(|e| match e {
        FieldError::Unknown { .. } => unknown(original, path),
        other => other,
    })?;
    match parent.get(last) {
        Some(Value::Integer(_)) => {
            parent.insert(last.to_string(), Value::Integer(whole(path, value)?));
            Ok(())
        }
        Some(v) => {
            number_of(path, v)?;
            parent.insert(last.to_string(), Value::Float(value));
            Ok(())
        }
        None => {
            // a field the case leaves out: a float, or a whole number where the field is an
            // integer; a name the case format does not know is refused as in a file
            let mut trial = probe;
            let (slot, _) = parent_mut(&mut trial, path, &segments)?;
            slot.insert(last.to_string(), Value::Float(value));
            let as_float = Value::Table(trial.clone()).try_into::<Case>();
            let integer = match as_float {
                Err(e) if one_line(&e).contains(&format!("unknown field `{last}`")) => {
                    return Err(unknown(original, path));
                }
                Err(e) if one_line(&e).contains("invalid type: floating point") => true,
                _ => false,
            };
            let v = if integer { Value::Integer(whole(path, value)?) } else { Value::Float(value) };
            parent.insert(last.to_string(), v);
            Ok(())
        }
    }
}

/// `value` as an integer, or the error for a fractional one.
fn whole(path: &str, value: f64) -> Result<i64, FieldError> {
    if value.fract() != 0.0 || value.abs() > 9.0e15 {
        return Err(FieldError::NotWhole { path: path.to_string(), value });
    }
    Ok(value as i64)
}

/// The unknown field the deserialiser names when reading `table` as a case, if it names one.
fn unknown_field(table: &toml::Table) -> Option<String> {
    match Value::Table(table.clone()).try_into::<Case>() {
        Err(e) if one_line(&e).contains("unknown field") => Some(one_line(&e)),
        _ => None,
    }
}

/// [`FieldError::Unknown`] with the closest numeric field of `table` as a suggestion: one with the
/// same last name (`loss_coefficient` → `inlet.loss_coefficient`), else one within three edits.
fn unknown(table: &toml::Table, path: &str) -> FieldError {
    let mut fields = Vec::new();
    numeric_paths(table, "", &mut fields);
    let last = path.rsplit('.').next().unwrap_or(path);
    let same_last: Vec<&String> = fields.iter().filter(|f| f.rsplit('.').next() == Some(last)).collect();
    let suggestion = if !same_last.is_empty() {
        Some(same_last.iter().map(|s| s.as_str()).collect::<Vec<_>>().join("` or `"))
    } else {
        fields
            .iter()
            .map(|f| (crate::params::edit_distance(path, f), f))
            .filter(|(d, _)| *d <= 3)
            .min()
            .map(|(_, f)| f.clone())
    };
    FieldError::Unknown { path: path.to_string(), suggestion }
}

/// Every path of `table` that holds one number (not inside lists, not the `[parameters]`).
fn numeric_paths(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (key, v) in table {
        let path = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        match v {
            Value::Float(_) | Value::Integer(_) => out.push(path),
            Value::Table(t) if path != "parameters" => numeric_paths(t, &path, out),
            _ => {}
        }
    }
}

fn one_line(e: &toml::de::Error) -> String {
    e.message().trim().replace('\n', " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nbs() -> Case {
        let text = include_str!("../../../examples/nbs/subcooled-4.2atm.toml");
        Case::from_toml(text, "subcooled-4.2atm.toml").unwrap()
    }

    #[test]
    fn a_case_reads_back_unchanged_from_its_table() {
        for (name, text) in [
            ("subcooled", include_str!("../../../examples/nbs/subcooled-4.2atm.toml")),
            ("saturated", include_str!("../../../examples/nbs/saturated-2.5atm.toml")),
            ("hydrogen", include_str!("../../../examples/nbs/hydrogen-saturated-5.1atm.toml")),
            ("faucet", include_str!("../../../examples/verification/faucet.toml")),
            ("schumann", include_str!("../../../examples/verification/schumann.toml")),
        ] {
            let case = Case::from_toml(text, name).unwrap();
            let back: Case = Value::Table(case.to_table()).try_into().unwrap();
            assert_eq!(back, case, "{name}");
            assert_eq!(case.with_fields(&[]).unwrap(), case);
        }
    }

    #[test]
    fn numeric_fields_are_read_and_set() {
        let case = nbs();
        assert_eq!(case.field("inlet.loss_coefficient").unwrap(), 10.0);
        assert_eq!(case.field("pipe.cells").unwrap(), 30.0);
        let set = case
            .with_fields(&[("inlet.loss_coefficient", 8.0), ("inlet.valve_opening_time_s", 1.5), ("pipe.cells", 12.0)])
            .unwrap();
        assert_eq!(set.inlet.loss_coefficient, 8.0);
        assert_eq!(set.inlet.valve_opening_time_s, 1.5);
        assert_eq!(set.pipe.cells, 12);
        // a profile given as a number, and a field the case leaves out
        let set = case.with_fields(&[("inlet.pressure_pa", 4.0e5), ("time.max_wall_s", 30.0)]).unwrap();
        assert_eq!(set.inlet.pressure_pa, Some(crate::case::Profile::Constant(4.0e5)));
        assert_eq!(set.time.max_wall_s, Some(30.0));
        let set = case.with_fields(&[("time.max_steps", 500.0)]).unwrap();
        assert_eq!(set.time.max_steps, Some(500));
        // the last value of a path given twice holds; the case itself is unchanged
        let set = case.with_fields(&[("inlet.loss_coefficient", 8.0), ("inlet.loss_coefficient", 9.0)]).unwrap();
        assert_eq!(set.inlet.loss_coefficient, 9.0);
        assert_eq!(case, nbs());
        assert!(matches!(case.field("time.max_wall_s"), Err(FieldError::NotGiven { .. })));
    }

    #[test]
    fn units_are_read_from_field_names() {
        for (path, unit) in [
            ("inlet.valve_opening_time_s", "s"),
            ("inlet.loss_coefficient", "-"),
            ("pipe.roughness_m", "m"),
            ("initial.gas_velocity_m_s", "m/s"),
            ("ambient.heat_transfer_coefficient_w_m2k", "W/(m² K)"),
            ("inlet.pressure_pa", "Pa"),
            ("inlet.temperature_k", "K"),
            ("pipe.inclination_deg", "degrees"),
            ("pipe.cells", "-"),
        ] {
            assert_eq!(field_unit(path), unit, "{path}");
        }
    }

    #[test]
    fn bad_paths_and_values_are_refused_with_the_path_and_the_value() {
        let case = nbs();
        let err = |path: &str, value: f64| case.with_fields(&[(path, value)]).unwrap_err();
        let e = err("inlet.loss_coeficient", 8.0);
        assert!(matches!(e, FieldError::Unknown { .. }));
        assert!(e.to_string().contains("did you mean `inlet.loss_coefficient`?"), "{e}");
        let e = err("loss_coefficient", 8.0).to_string();
        assert!(e.contains("`inlet.loss_coefficient` or `outlet.loss_coefficient`"), "{e}");
        let e = err("inlet.colour", 8.0).to_string();
        assert!(e.contains("`inlet.colour` is not a field of a case"), "{e}");
        let e = err("nozzle.loss_coefficient", 8.0).to_string();
        assert!(e.contains("`nozzle.loss_coefficient` is not a field"), "{e}");
        let e = err("inlet.loss_coefficient", -1.0).to_string();
        assert!(e.starts_with("inlet.loss_coefficient = -1 makes the case invalid"), "{e}");
        assert!(e.contains("must be ≥ 0"), "{e}");
        let e = err("time.min_dt_s", 10.0).to_string();
        assert!(e.contains("time.min_dt_s = 10 is larger than time.max_dt_s"), "{e}");
        let e = err("pipe.cells", 12.5).to_string();
        assert!(e.contains("`pipe.cells` = 12.5: the field holds a whole number"), "{e}");
        let e = err("stations.0.x_m", 3.0).to_string();
        assert!(e.contains("`stations` is a list"), "{e}");
        let e = err("initial.wall_temperature_k", 3.0).to_string();
        assert!(e.contains("holds a table of [x, value] points"), "{e}");
        let e = err("fluid.name", 3.0).to_string();
        assert!(e.contains("holds text"), "{e}");
        let e = err("physics.gravity", 1.0).to_string();
        assert!(e.contains("holds a switch"), "{e}");
        let e = err("inlet", 1.0).to_string();
        assert!(e.contains("holds a section"), "{e}");
        let e = err("parameters.Gwsc", 1.0).to_string();
        assert!(e.contains("name the parameter `Gwsc` itself"), "{e}");
        for bad in ["", "inlet.", ".x", "inlet..x", "inlet. x"] {
            assert!(matches!(err(bad, 1.0), FieldError::BadPath { .. }), "{bad}");
        }
        assert!(err("inlet.loss_coefficient", f64::NAN).to_string().contains("must be a finite number"));
        assert!(matches!(case.field("inlet.colour"), Err(FieldError::Unknown { .. })));
        assert!(matches!(case.field("fluid.name"), Err(FieldError::NotNumber { .. })));
    }
}
