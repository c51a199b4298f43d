//! A run's outputs carry the times the case asks for: the k-th probe and profile time is exactly
//! `k × interval` as the case writes it (0.6, not 0.6000000000000001) and the last is exactly the
//! end time, whatever steps the run took to get there
//! (rejections, growth, Courant limits), not a sum of steps that misses it by rounding.

use cryofit_solver::case::Case;
use cryofit_solver::driver;
use cryofit_solver::fluids;
use cryofit_solver::params::ParameterSet;

/// The first seconds of the NBS subcooled chilldown on a few cells: many rejected and limited
/// steps between output times that are not binary fractions.
fn case(end_s: f64, output_interval_s: f64, profile_interval_s: f64) -> Case {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs/subcooled-4.2atm.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let mut case = Case::from_toml(&text, path).unwrap();
    case.pipe.cells = 12;
    case.time.end_s = end_s;
    case.time.output_interval_s = output_interval_s;
    case.time.profile_interval_s = profile_interval_s;
    case
}

fn distinct_times(times: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for t in times {
        if out.last() != Some(&t) {
            out.push(t);
        }
    }
    out
}

/// `t` to a tenth of a millisecond (the intervals here have one decimal).
fn decimal(t: f64) -> f64 {
    format!("{t:.4}").parse().unwrap()
}

#[test]
fn outputs_land_exactly_on_their_times_and_the_end() {
    for (end, interval, profile) in [(8.0, 0.5, 4.0), (3.0, 0.1, 1.5)] {
        let case = case(end, interval, profile);
        let fluid = fluids::embedded(&case.fluid.name).unwrap();
        let out = driver::run(&case, fluid, &ParameterSet::new(), &mut |_| {}).unwrap();
        assert_eq!(out.summary.simulated_time_s, end);
        let probes = distinct_times(out.probes.iter().map(|o| o.time_s));
        let expected: Vec<f64> = (0..probes.len()).map(|k| decimal(k as f64 * interval)).collect();
        assert_eq!(probes, expected, "probe times of a run to {end} s every {interval} s");
        assert_eq!(*probes.last().unwrap(), end, "the last probe is at the end");
        let profiles = distinct_times(out.profiles.iter().map(|p| p.time_s));
        let expected: Vec<f64> = (0..profiles.len()).map(|k| decimal(k as f64 * profile)).collect();
        assert_eq!(profiles, expected, "profile times every {profile} s");
    }
}

/// What a run writes does not change the run: the steps do not land on output times (the outputs
/// are interpolated between the accepted states around them), so runs that probe every 0.1 s
/// and every 0.7 s take the same steps, reach the same chilldown times and write the same values
/// at the times they share, to the bit.
#[test]
fn the_output_intervals_do_not_change_the_run() {
    let run = |interval: f64, profile: f64| {
        let case = case(7.0, interval, profile);
        let fluid = fluids::embedded(&case.fluid.name).unwrap();
        driver::run(&case, fluid, &ParameterSet::new(), &mut |_| {}).unwrap()
    };
    let (fine, coarse) = (run(0.1, 0.5), run(0.7, 3.5));
    assert_eq!(fine.summary.steps, coarse.summary.steps);
    assert_eq!(fine.summary.rejected_steps, coarse.summary.rejected_steps);
    assert_eq!(fine.summary.chilldown_time_s, coarse.summary.chilldown_time_s);
    assert_eq!(fine.summary.energy_balance_error.to_bits(), coarse.summary.energy_balance_error.to_bits());
    let mut shared = 0;
    for c in &coarse.probes {
        let f = fine
            .probes
            .iter()
            .find(|f| f.time_s == c.time_s && f.station == c.station && f.quantity == c.quantity)
            .unwrap_or_else(|| panic!("no fine probe at {} s", c.time_s));
        assert_eq!(f.value.to_bits(), c.value.to_bits(), "{} {} at {} s", c.station, c.quantity, c.time_s);
        shared += 1;
    }
    assert!(shared > 50, "{shared} probe values compared");
    let at = |out: &driver::Output, t: f64| -> Vec<u64> {
        out.profiles.iter().filter(|p| p.time_s == t).map(|p| p.value.to_bits()).collect()
    };
    assert_eq!(at(&fine, 3.5), at(&coarse, 3.5));
    assert_eq!(at(&fine, 7.0), at(&coarse, 7.0));
    assert!(!at(&fine, 3.5).is_empty());
}
