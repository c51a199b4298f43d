//! Checks of experiments and calibrations before anything is stored. Errors name the field.

use std::collections::BTreeMap;

use cryofit_api as api;
use cryofit_calib::config::{CalibrationSpec, DEFAULT_MAX_EVALUATION_S, ExperimentRef};
use cryofit_calib::model::SolverModel;
use cryofit_calib::pipeline::Pipeline;
use cryofit_calib::problem::{BuildError, Fixed, Problem, default_start, experiment_from_texts};

use crate::fluids::FluidLoader;
use crate::invalid::Invalid;
use crate::limits::{self, Limits};

/// Checks an experiment by building it (case, data, stations, duration, fluid). Returns the
/// canonical fluid name.
pub fn experiment(req: &api::CreateExperiment, fluids: &FluidLoader, limits: &Limits) -> Result<String, Invalid> {
    check_name(&req.name)?;
    let case =
        cryofit_solver::case::Case::from_toml(&req.case, "case").map_err(|e| Invalid::at("case", e.to_string()))?;
    cryofit_calib::data::Dataset::from_csv(&req.data, "data").map_err(|e| Invalid::at("data", e.to_string()))?;
    let fluid = cryofit_solver::fluids::canonical_name(&case.fluid.name)
        .ok_or_else(|| Invalid::at("case", format!("case: fluid.name `{}` is not a known fluid", case.fluid.name)))?;
    let loader = |n: &str| fluids(n).map(|(t, _)| t);
    let built = experiment_from_texts(&req.name, &req.case, "case", &req.data, "data", loader, &Fixed::default(), None)
        .map_err(|m| {
            let m = m.to_string();
            let field = if m.starts_with("data") { "data" } else { "case" };
            Invalid::at(field, m)
        })?;
    if let Some(model) = built.model.as_any().downcast_ref::<SolverModel>() {
        limits::check_outputs(model, "case", "case", limits)?;
    }
    Ok(fluid.to_string())
}

/// Longest name of an experiment or a calibration, characters.
pub const MAX_NAME_CHARS: usize = 200;

/// A name: not blank, at most [`MAX_NAME_CHARS`] characters (not bytes).
pub(crate) fn check_name(name: &str) -> Result<(), Invalid> {
    if name.trim().is_empty() {
        return Err(Invalid::at("name", "must not be empty"));
    }
    let n = name.chars().count();
    if n > MAX_NAME_CHARS {
        return Err(Invalid::at("name", format!("{n} characters: at most {MAX_NAME_CHARS}")));
    }
    Ok(())
}

/// A validated calibration: the pipeline to start and the fluid hashes.
#[derive(Debug)]
pub struct Prepared {
    /// Fresh pipeline.
    pub pipeline: Pipeline,
    /// Fluid hash per fluid.
    pub fluid_hashes: BTreeMap<String, String>,
}

/// The calibration-file form of a stored request: each experiment names its stored row
/// (`experiments[k]` = the row of `req.experiments[k]`); nothing is checked here.
pub fn spec_of(req: &api::CreateCalibration, experiments: &[api::Experiment]) -> CalibrationSpec {
    CalibrationSpec {
        name: req.name.clone(),
        description: req.description.clone(),
        seed: req.seed,
        experiments: experiments
            .iter()
            .map(|e| ExperimentRef {
                case: format!("experiment {}", e.id),
                data: format!("experiment {}", e.id),
                name: Some(e.name.clone()),
            })
            .collect(),
        parameters: req.parameters.clone(),
        fixed: req.fixed.clone(),
        weights: req.weights.clone(),
        stages: req.stages.clone(),
        max_evaluation_s: req.max_evaluation_s.unwrap_or(DEFAULT_MAX_EVALUATION_S),
        // a file's [crossval] is `cryofit crossval`'s, run in-process: the coordinator runs the
        // calibration itself
        crossval: None,
    }
}

/// Checks a calibration against its stored experiments (`experiments[k]` = the stored row of
/// `req.experiments[k]`) and builds its pipeline.
pub fn calibration(
    req: &api::CreateCalibration,
    experiments: &[api::Experiment],
    fluids: &FluidLoader,
    limits: &Limits,
) -> Result<Prepared, Invalid> {
    check_name(&req.name)?;
    let spec = spec_of(req, experiments);
    // sizes first (plain arithmetic on the request): building the pipeline allocates what its
    // stages ask for, and the limits name the flag that sets them
    limits::check_calibration(&spec, spec.dimension(), limits)?;
    spec.validate().map_err(|e| Invalid::from_message(e.to_string()))?;
    let fixed = Fixed::new(&spec.fixed).map_err(|e| Invalid::at(format!("fixed.{}", e.name), e.error.to_string()))?;
    let mut built = Vec::new();
    let mut hashes = BTreeMap::new();
    for (k, e) in experiments.iter().enumerate() {
        let field = format!("experiments[{k}]");
        let mut hash = None;
        let loader = |n: &str| {
            fluids(n).map(|(t, h)| {
                hash = Some((cryofit_solver::fluids::canonical_name(n).unwrap_or(n).to_string(), h));
                t
            })
        };
        let case_label = format!("experiment {} case", e.id);
        let data_label = format!("experiment {} data", e.id);
        let exp = experiment_from_texts(
            &e.name,
            &e.case,
            &case_label,
            &e.data,
            &data_label,
            loader,
            &fixed,
            Some(spec.max_evaluation_s),
        )
        .map_err(|m| match &m {
            // a fixed value the stored case refuses is the request's `fixed` entry's fault
            BuildError::FixedCaseField { name, .. } => Invalid::at(format!("fixed.{name}"), m.to_string()),
            _ => Invalid::at(field.clone(), m.to_string()),
        })?;
        if let Some(model) = exp.model.as_any().downcast_ref::<SolverModel>() {
            limits::check_outputs(model, &case_label, &field, limits)?;
            spec.check_case_fields(&e.name, model.case(), &case_label)
                .map_err(|m| Invalid::from_message(m.to_string()))?;
        }
        if let Some((fluid, h)) = hash {
            hashes.insert(fluid, h);
        }
        built.push(exp);
    }
    let problem = Problem::new(built, spec.weights()).map_err(|m| {
        let mut inv = Invalid::from_message(m.to_string());
        inv.field.get_or_insert_with(|| "experiments".into());
        inv
    })?;
    let space = spec.space().map_err(|e| Invalid::from_message(e.to_string()))?;
    let start = default_start(&space, &problem.experiments, &spec.start_values());
    let pipeline = Pipeline::new(space, spec.stages.clone(), start, spec.seed).map_err(|m| {
        let mut inv = Invalid::from_message(m.to_string());
        if inv.field.is_none() {
            inv.field = Some("stages".into());
        }
        inv
    })?;
    Ok(Prepared { pipeline, fluid_hashes: hashes })
}

#[cfg(test)]
mod tests {
    use crate::invalid::field_of;
    use cryofit_api as api;
    use serde_json::json;

    fn stored(id: i64, name: &str) -> api::Experiment {
        api::Experiment {
            id,
            name: name.into(),
            fluid: "nitrogen".into(),
            case: include_str!("../../tests/fixtures/tiny.toml").into(),
            data: include_str!("../../tests/fixtures/tiny-data.csv").into(),
            created: 0,
        }
    }

    fn request(parameters: serde_json::Value) -> api::CreateCalibration {
        serde_json::from_value(json!({
            "name": "apparatus", "experiments": [1, 2], "parameters": parameters,
            "stages": [{"algorithm": "sensitivity", "budget": 5}]
        }))
        .expect("request")
    }

    fn check(parameters: serde_json::Value) -> Result<super::Prepared, crate::invalid::Invalid> {
        let rows = [stored(1, "a"), stored(2, "b")];
        super::calibration(&request(parameters), &rows, &crate::fluids::embedded_fluids(), &api::Limits::default())
    }

    /// Case fields are checked at submission against the stored experiments' cases, by experiment
    /// name, with the messages of a local calibration; the pipeline starts them at the case's value.
    #[test]
    fn case_field_parameters_are_checked_against_the_stored_cases() {
        let ok = check(json!([
            {"name": "case.inlet.loss_coefficient", "lower": 2.0, "upper": 20.0, "experiments": ["b"]},
            {"name": "case.inlet.valve_opening_time_s", "lower": 1.0, "upper": 5.0},
        ]))
        .expect("valid");
        let names: Vec<&str> = ok.pipeline.space().names().collect();
        assert_eq!(names, ["case.inlet.loss_coefficient@b", "case.inlet.valve_opening_time_s"]);
        // a sensitivity stage's first point is the start
        let mut pipeline = ok.pipeline;
        let start = &pipeline.ask(1)[0].parameters;
        assert_eq!(start["case.inlet.loss_coefficient@b"], 10.0, "the case's value");
        assert_eq!(start["case.inlet.valve_opening_time_s"], 2.0, "the case's value, not the middle");

        let e = check(json!([{"name": "case.inlet.loss_coefficient", "lower": -2.0, "upper": 20.0}])).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("parameters[0]"));
        assert!(
            e.message.starts_with(
                "parameters[0] (case.inlet.loss_coefficient), experiment `a` (experiment 1 case), at the lower bound"
            ),
            "{}",
            e.message
        );
        let e =
            check(json!([{"name": "case.inlet.loss_coefficient", "lower": 2.0, "upper": 20.0, "experiments": ["c"]}]))
                .unwrap_err();
        assert_eq!(e.field.as_deref(), Some("parameters[0].experiments[0]"));
        assert!(e.message.contains("not an experiment of this calibration (its experiments: a, b)"), "{}", e.message);
        let e = check(json!([{"name": "case.inlet.loss_coeficient", "lower": 2.0, "upper": 20.0}])).unwrap_err();
        assert!(e.message.contains("did you mean `inlet.loss_coefficient`?"), "{}", e.message);
        let e = check(json!([{"name": "case.inlet.loss_coefficient"}])).unwrap_err();
        assert!(e.message.contains("give both `lower` and `upper`"), "{}", e.message);
    }

    /// Fixed case fields apply to the stored cases (a shared one to every experiment's, an
    /// `@<experiment>` one to its own) and are checked there; a value a case refuses names the
    /// `fixed` entry.
    #[test]
    fn fixed_case_fields_are_checked_against_the_stored_cases() {
        let rows = [stored(1, "a"), stored(2, "b")];
        let with_fixed = |fixed: serde_json::Value| {
            let mut req = request(json!([{"name": "Gwsc"}]));
            req.fixed = serde_json::from_value(fixed).expect("fixed");
            super::calibration(&req, &rows, &crate::fluids::embedded_fluids(), &api::Limits::default())
        };
        with_fixed(json!({"case.pipe.cells": 7, "case.inlet.loss_coefficient@b": 6.0})).expect("valid");
        let e = with_fixed(json!({"case.pipe.cells": 0})).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("fixed.case.pipe.cells"), "{}", e.message);
        let e = with_fixed(json!({"case.inlet.loss_coefficient@c": 6.0})).unwrap_err();
        assert!(e.message.contains("`c` after `@` is not an experiment"), "{}", e.message);
    }

    #[test]
    fn names_are_counted_in_characters() {
        assert!(super::check_name(&"é".repeat(200)).is_ok(), "400 bytes, 200 characters");
        let e = super::check_name(&"é".repeat(201)).unwrap_err();
        assert_eq!(e.message, "201 characters: at most 200");
        assert!(super::check_name("  ").is_err());
    }

    #[test]
    fn fields_are_taken_from_messages() {
        assert_eq!(field_of("stages[0].budget: must be at least 1").as_deref(), Some("stages[0].budget"));
        assert_eq!(field_of("parameters[1] (Gwsc): bounds must be finite").as_deref(), Some("parameters[1]"));
        assert_eq!(field_of("fixed.tauw = 3: outside").as_deref(), Some("fixed.tauw"));
        assert_eq!(field_of("no field here"), None);
        assert_eq!(field_of("experiment `a`: none of its data"), None);
    }
}
