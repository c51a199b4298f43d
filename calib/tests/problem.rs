//! Experiments built from case and data texts: the model runs to the end of the data, not of the case.

use std::collections::BTreeMap;
use std::sync::Arc;

use cryofit_calib::model::SolverModel;
use cryofit_calib::problem::{Fixed, experiment_from_texts};
use cryofit_solver::case::Case;
use cryofit_solver::fluids::{self, FluidTable};
use cryofit_solver::params::ParameterSet;

const CASE: &str = include_str!("../../examples/nbs/subcooled-4.2atm.toml");

fn nitrogen(name: &str) -> Result<Arc<FluidTable>, String> {
    fluids::embedded(name).map(|t| Arc::new(t.clone())).map_err(|e| e.to_string())
}

fn data_ending_at(t_end: f64) -> String {
    format!(
        "time_s,station,x_m,quantity,value\n0,TS1,6.1,wall_temperature_k,290\n{t_end},TS1,6.1,wall_temperature_k,200\n"
    )
}

#[test]
fn the_model_stops_at_the_first_output_time_after_the_data() {
    let case = Case::from_toml(CASE, "case.toml").unwrap();
    assert_eq!(case.time.end_s, 1000.0);
    assert_eq!(case.time.output_interval_s, 1.0);
    let e = experiment_from_texts(
        "x",
        CASE,
        "case.toml",
        &data_ending_at(2.45),
        "data.csv",
        nitrogen,
        &Fixed::default(),
        None,
    )
    .unwrap();
    let solver = e.model.as_any().downcast_ref::<SolverModel>().unwrap();
    assert_eq!(solver.stop_s(), 3.0);
    assert_eq!(solver.case().time.end_s, 1000.0);
    let out = e.model.evaluate(&BTreeMap::new()).unwrap();
    let ts1 = &out.series[&("TS1".to_string(), "wall_temperature_k".to_string())];
    assert_eq!(ts1.times.last(), Some(&3.0));
    // the data's last time is bracketed, so the cost can read the model there
    assert!(ts1.at(2.45).is_some());

    // a data time on the output grid is itself the end; the case's end is never extended
    let model = SolverModel::new(case.clone(), nitrogen("nitrogen").unwrap(), &ParameterSet::new()).unwrap();
    assert_eq!(model.clone().with_end_at(132.0).stop_s(), 132.0);
    assert_eq!(model.clone().with_end_at(2000.0).stop_s(), 1000.0);
    assert_eq!(model.with_end_at(f64::NAN).stop_s(), 1000.0);
}

const TINY: &str = include_str!("../../tests/fixtures/tiny.toml");

fn values(pairs: &[(&str, f64)]) -> BTreeMap<String, f64> {
    pairs.iter().map(|&(k, v)| (k.to_string(), v)).collect()
}

/// A point's case fields set the case of the experiment they apply to: shared ones every case,
/// `@<experiment>` ones only that experiment's (over a shared value), others' not at all.
#[test]
fn case_fields_of_a_point_set_the_case_of_their_experiment_only() {
    use cryofit_calib::model::ModelError;
    let e = experiment_from_texts(
        "a",
        TINY,
        "tiny.toml",
        &data_ending_at(4.0),
        "data.csv",
        nitrogen,
        &Fixed::default(),
        None,
    )
    .unwrap();
    let solver = e.model.as_any().downcast_ref::<SolverModel>().unwrap();
    assert_eq!(solver.experiment(), Some("a"));
    let k = |pairs: &[(&str, f64)]| solver.case_at(&values(pairs)).unwrap().inlet.loss_coefficient;
    assert_eq!(k(&[]), 10.0);
    assert_eq!(k(&[("case.inlet.loss_coefficient", 8.0)]), 8.0);
    assert_eq!(k(&[("case.inlet.loss_coefficient@b", 8.0)]), 10.0);
    assert_eq!(k(&[("case.inlet.loss_coefficient", 5.0), ("case.inlet.loss_coefficient@a", 8.0)]), 8.0);
    // the registry set ignores case fields
    let set = solver.parameter_set(&values(&[("case.inlet.loss_coefficient", 8.0), ("Gwsc", 1.5)])).unwrap();
    assert_eq!(set.explicit().len(), 1);

    // the start of a case field is its value in the case
    assert_eq!(e.model.own_value("case.inlet.loss_coefficient"), Some(10.0));
    assert_eq!(e.model.own_value("case.inlet.loss_coefficient@a"), Some(10.0));
    assert_eq!(e.model.own_value("case.inlet.loss_coefficient@b"), None);
    assert_eq!(e.model.own_value("Gwsc"), None);
    let space = cryofit_calib::Space::new(vec![
        cryofit_calib::FreeParameter {
            name: "case.inlet.loss_coefficient".into(),
            lower: 2.0,
            upper: 20.0,
            scale: cryofit_calib::Scale::Linear,
        },
        cryofit_calib::FreeParameter {
            name: "case.inlet.valve_opening_time_s@b".into(),
            lower: 1.0,
            upper: 3.0,
            scale: cryofit_calib::Scale::Linear,
        },
        cryofit_calib::FreeParameter {
            name: "Gwsc".into(),
            lower: 0.5,
            upper: 2.0,
            scale: cryofit_calib::Scale::Linear,
        },
    ])
    .unwrap();
    let start = cryofit_calib::problem::default_start(&space, std::slice::from_ref(&e), &BTreeMap::new());
    assert_eq!(start, vec![8.0 / 18.0, 0.5, space.unit(2, 1.0)]);
    // a given start wins over the registry default and the case's value
    let given = BTreeMap::from([("Gwsc".to_string(), 1.5), ("case.inlet.loss_coefficient".to_string(), 3.0)]);
    let start = cryofit_calib::problem::default_start(&space, std::slice::from_ref(&e), &given);
    assert_eq!((start[0], start[2]), (space.unit(0, 3.0), space.unit(2, 1.5)));

    // the runs: another experiment's value changes nothing, a shared one does
    let base = e.model.evaluate(&BTreeMap::new()).unwrap();
    assert_eq!(e.model.evaluate(&values(&[("case.inlet.loss_coefficient@b", 3.0)])).unwrap(), base);
    assert_ne!(e.model.evaluate(&values(&[("case.inlet.loss_coefficient", 3.0)])).unwrap(), base);
    let err = e.model.evaluate(&values(&[("case.inlet.loss_coefficient", -1.0)])).unwrap_err();
    assert!(matches!(err, ModelError::CaseField(_)), "{err}");
    assert!(err.to_string().contains("inlet.loss_coefficient = -1 makes the case invalid"), "{err}");
}

/// The example calibration with apparatus parameters reads, makes its space, and its case fields
/// hold in each NBS case they apply to.
#[test]
fn the_example_apparatus_calibration_is_valid() {
    use cryofit_calib::config::CalibrationSpec;
    let spec = CalibrationSpec::from_toml(
        include_str!("../../examples/nbs/calibrate-apparatus.toml"),
        "calibrate-apparatus.toml",
    )
    .unwrap();
    let names: Vec<String> = spec.space().unwrap().names().map(str::to_string).collect();
    assert_eq!(names.len(), 8);
    assert!(names.contains(&"case.inlet.valve_opening_time_s@subcooled-4.2atm".to_string()), "{names:?}");
    let cases = [
        ("saturated-2.5atm", include_str!("../../examples/nbs/saturated-2.5atm.toml")),
        ("saturated-3.4atm", include_str!("../../examples/nbs/saturated-3.4atm.toml")),
        ("subcooled-4.2atm", include_str!("../../examples/nbs/subcooled-4.2atm.toml")),
    ];
    for (k, (name, text)) in cases.iter().enumerate() {
        assert_eq!(&spec.experiments[k].label(k), name);
        let case = Case::from_toml(text, name).unwrap();
        spec.check_case_fields(name, &case, name).unwrap();
    }
}

/// Every example calibration file reads and makes its parameter space, and the case and data
/// files its experiments name are beside it.
#[test]
fn every_example_calibration_reads_and_names_files_that_exist() {
    use cryofit_calib::config::CalibrationSpec;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/nbs");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        if !(name.starts_with("calibrate-") && name.ends_with(".toml")) {
            continue;
        }
        let spec = CalibrationSpec::from_toml(&std::fs::read_to_string(&path).unwrap(), &name)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        spec.space().unwrap_or_else(|e| panic!("{name}: {e}"));
        for e in &spec.experiments {
            for file in [&e.case, &e.data] {
                assert!(dir.join(file).is_file(), "{name}: {file} is not beside it");
            }
        }
        seen += 1;
    }
    assert!(seen >= 8, "only {seen} example calibrations found in {}", dir.display());
}

/// `[fixed]` case fields set the case before the experiment is built: shared ones every
/// experiment's, `@<experiment>` ones only that experiment's (over a shared value); a value the
/// case refuses is an error naming it and the case.
#[test]
fn fixed_case_fields_set_the_case_an_experiment_is_built_from() {
    let fixed = Fixed::new(&values(&[
        ("case.pipe.cells", 7.0),
        ("case.inlet.loss_coefficient", 6.0),
        ("case.inlet.loss_coefficient@b", 9.0),
        ("Gwsc", 1.5),
    ]))
    .unwrap();
    assert_eq!(fixed.params().explicit().len(), 1);
    let build = |name: &str, fixed: &Fixed| {
        experiment_from_texts(name, TINY, "tiny.toml", &data_ending_at(4.0), "data.csv", nitrogen, fixed, None)
    };
    for (name, k) in [("a", 6.0), ("b", 9.0)] {
        let e = build(name, &fixed).unwrap();
        let solver = e.model.as_any().downcast_ref::<SolverModel>().unwrap();
        assert_eq!(solver.case().pipe.cells, 7, "{name}");
        assert_eq!(solver.case().inlet.loss_coefficient, k, "{name}");
        // the case's value is where a free copy of the field starts
        assert_eq!(e.model.own_value("case.inlet.loss_coefficient"), Some(k), "{name}");
        let out = e.model.evaluate(&BTreeMap::new()).unwrap();
        assert!(out.series.contains_key(&("TS1".to_string(), "wall_temperature_k".to_string())));
    }
    let e = build("a", &Fixed::new(&values(&[("case.pipe.cells", 0.0)])).unwrap()).unwrap_err();
    assert!(e.to_string().starts_with("tiny.toml: fixed.case.pipe.cells: "), "{e}");
    let e = build("b", &Fixed::new(&values(&[("case.inlet.los_coefficient@b", 3.0)])).unwrap()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("tiny.toml: fixed.case.inlet.los_coefficient@b: `inlet.los_coefficient` is not a field"),
        "{e}"
    );
    // a registry value the registry refuses names itself
    let e = Fixed::new(&values(&[("Gwscc", 1.0)])).unwrap_err();
    assert!(e.to_string().starts_with("fixed.Gwscc: "), "{e}");
}
