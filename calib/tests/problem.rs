//! Experiments built from case and data texts: the model runs to the end of the data, not of the case.

use std::collections::BTreeMap;
use std::sync::Arc;

use cryofit_calib::model::SolverModel;
use cryofit_calib::problem::experiment_from_texts;
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
        &ParameterSet::new(),
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
