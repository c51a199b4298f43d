//! The three NBS Report 9264 chilldowns run with the registry's default closures, as shipped in
//! `examples/nbs/` (30 cells, 1000 s): each completes, the quench front reaches the stations in
//! order, station 4 chills down within 50 % of the measured time, the pressure stays physical,
//! mass and energy balances close, and the step count stays where the step control put it. VALIDATION.md tabulates the same runs.

use cryofit_solver::case::Case;
use cryofit_solver::driver;
use cryofit_solver::fluids;

const NBS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/nbs");

/// Outlet pressure of every run (atmosphere at Boulder), Pa.
const P_OUTLET: f64 = 83087.0;

/// Case stem and the measured station-4 chilldown time (wall below the inlet liquid
/// temperature + 15 K), s; `nbs_cases.rs` checks these against the data files.
const RUNS: [(&str, f64); 3] = [("saturated-2.5atm", 245.0), ("saturated-3.4atm", 199.0), ("subcooled-4.2atm", 127.0)];

/// Most accepted steps a default run may take (a count, not a time: it does not depend on the
/// machine). With the interphase drag linearised by Picard, the mist leaving the line made the
/// relative velocity oscillate from step to step, and the 25 % rule held the runs to 12 926 /
/// 13 980 / 17 890 steps; linearised by Newton they took 8 760 / 8 386 / 11 621. With the boiling
/// correlations on saturated and film-temperature vapour they take 11 290 / 8 879 / 15 499, the
/// subcooled run's extra steps held by the 25 % pressure rule in its first-contact surges. A
/// run above the limit shows where its steps went in `summary.step_limited_by`.
const MAX_STEPS: u64 = 16_000;

/// Largest physical energy balance error (residual over the heat the wall gave up). Measured
/// 8.6e-4 / 2.8e-4 / 2.9e-3: the subcooled run's residual (−9.7 kJ of 3.39 MJ) builds up at
/// about 60 J/s while two phases flow, and is not yet traced to its term.
const MAX_ENERGY_ERROR: f64 = 3.5e-3;

const STATIONS: [&str; 4] = ["TS1", "TS2", "TS3", "TS4"];

/// Largest physical pressure as a multiple of the dewar's. The first liquid to meet the warm
/// line boils and recondenses in surges: the subcooled run swings between 0.8 and 2.1 times
/// the drive pressure at TS1 in its first 20 s (the paper: the measured pressure oscillates with
/// an amplitude the model does not reach; the report's valve dynamics are unknown). Above 3 times
/// it would be a numerical liquid hammer, not a surge.
const SURGE_LIMIT: f64 = 3.0;

#[test]
fn default_closures_chill_the_nbs_line_down_in_order_and_near_the_data() {
    let fluid = fluids::embedded("nitrogen").unwrap();
    for (stem, measured) in RUNS {
        let path = format!("{NBS}/{stem}.toml");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let case = Case::from_toml(&text, &path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(case.pipe.cells, 30, "{stem}: the shipped case has 30 cells");
        assert_eq!(case.time.end_s, 1000.0, "{stem}: the shipped case runs 1000 s");
        let params = driver::case_parameters(&case).unwrap();
        let out = driver::run(&case, fluid, &params, &mut |_| {}).unwrap_or_else(|e| panic!("{stem}: {e}"));
        let s = &out.summary;
        assert!((s.simulated_time_s - 1000.0).abs() < 1e-6, "{stem}: stopped at {} s", s.simulated_time_s);

        let arrival: Vec<f64> = STATIONS
            .iter()
            .map(|st| s.quench_arrival_s[*st].unwrap_or_else(|| panic!("{stem}: no quench front at {st}")))
            .collect();
        assert!(arrival.windows(2).all(|w| w[0] < w[1]), "{stem}: quench front out of order: {arrival:?}");
        let chill = s.chilldown_time_s["TS4"].unwrap_or_else(|| panic!("{stem}: TS4 never chilled down"));
        let error = (chill - measured) / measured;
        println!(
            "{stem}: quench {arrival:.1?} s; TS4 chilldown {chill:.1} s vs {measured} s ({:+.1} %); {} steps, \
             mass {:.1e}, energy {:.1e} (scheme {:.1e})",
            100.0 * error,
            s.steps,
            s.mass_balance_error,
            s.energy_balance_error,
            s.scheme_energy_error
        );
        assert!(s.steps <= MAX_STEPS, "{stem}: {} steps (limited by {:?})", s.steps, s.step_limited_by);
        assert!(error.abs() <= 0.5, "{stem}: TS4 chilldown {chill:.1} s is not within 50 % of {measured} s");

        let reservoir = case.inlet.pressure_pa.as_ref().unwrap().at(0.0);
        for o in out.probes.iter().filter(|o| o.quantity == "pressure_pa") {
            assert!(
                o.value > 0.5 * P_OUTLET && o.value < SURGE_LIMIT * reservoir,
                "{stem}: pressure {} Pa at {} s, {} is not physical (outlet {P_OUTLET} Pa, dewar {reservoir} Pa)",
                o.value,
                o.time_s,
                o.station
            );
        }
        assert!(s.mass_balance_error < 1e-12, "{stem}: mass balance {}", s.mass_balance_error);
        assert!(s.scheme_energy_error < 1e-12, "{stem}: scheme energy budget {}", s.scheme_energy_error);
        assert!(
            s.energy_balance_error < MAX_ENERGY_ERROR,
            "{stem}: physical energy balance {} ({} J of {} J)",
            s.energy_balance_error,
            s.energy_balance_residual_j,
            s.wall_heat_j
        );
        assert!(s.trace_adjustment_j <= 3.35e3, "{stem}: trace adjustments {} J", s.trace_adjustment_j);
    }
}
