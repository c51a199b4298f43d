//! The server-wide ceilings ([`Limits`]) on what one request can size, and the checks that apply
//! them before anything is built or stored: stage sizes, budgets (checked sums), the optimiser
//! state a calibration would hold, the values one evaluation records and its computing time.
//!
//! The checks run before [`cryofit_calib::pipeline::Pipeline::new`], which builds every stage up
//! front: a stage of 10¹⁴ Morris trajectories or MCMC walkers must be refused before anything
//! allocates for it.

use cryofit_api as api;
use cryofit_calib::config::{AlgorithmName, CalibrationSpec, StageSpec};
use cryofit_calib::inference::{EnsembleSampler, SensitivityOptions};
use cryofit_calib::model::SolverModel;
use cryofit_solver::driver::PROBE_QUANTITIES;

pub use cryofit_api::Limits;

use crate::invalid::Invalid;

/// Values one whole-line profile records per cell: six cell quantities and two junction
/// velocities (one junction more than cells, counted with the cells).
const PROFILE_VALUES_PER_CELL: f64 = 8.0;

/// [`check_calibration`] for a caller outside the coordinator (the local `cryofit calibrate`,
/// whose embedded coordinator would see the calibration only after the pipeline is built): the
/// message names the field and the limit.
pub fn check_calibration_sizes(spec: &CalibrationSpec, limits: &Limits) -> Result<(), String> {
    check_calibration(spec, spec.dimension(), limits).map_err(|e| e.message)
}

/// Checks the sizes of a calibration (stages, budgets, optimiser state, evaluation time) against
/// `limits`; `dim` is the number of free parameters. Errors name the field and the limit.
pub(crate) fn check_calibration(spec: &CalibrationSpec, dim: usize, limits: &Limits) -> Result<(), Invalid> {
    let e = spec.max_evaluation_s;
    if !(e.is_finite() && e > 0.0 && e <= limits.max_evaluation_s) {
        return Err(Invalid::at(
            "max_evaluation_s",
            format!(
                "max_evaluation_s = {e}: at most {} s on this coordinator (--max-evaluation-s); a longer simulation \
                 holds a worker slot that long",
                limits.max_evaluation_s
            ),
        ));
    }
    let mut total: u64 = 0;
    for (k, s) in spec.stages.iter().enumerate() {
        let at = format!("stages[{k}]");
        let budget = s.budget as u64;
        if budget > limits.max_budget {
            return Err(Invalid::at(
                format!("{at}.budget"),
                format!(
                    "{at}.budget = {budget}: at most {} evaluations on this coordinator (--max-budget)",
                    limits.max_budget
                ),
            ));
        }
        total = match total.checked_add(budget) {
            Some(t) if t <= limits.max_budget => t,
            _ => {
                return Err(Invalid::at(
                    "stages",
                    format!(
                        "stages: the budgets of stages[0..={k}] add up to more than {} evaluations, the limit of \
                         this coordinator (--max-budget)",
                        limits.max_budget
                    ),
                ));
            }
        };
        for (name, v) in stage_sizes(s) {
            if v as u64 > limits.max_stage_size {
                return Err(Invalid::at(
                    format!("{at}.{name}"),
                    format!(
                        "{at}.{name} = {v}: at most {} on this coordinator (--max-stage-size)",
                        limits.max_stage_size
                    ),
                ));
            }
        }
    }
    // the largest free set each stage can see, as the pipeline builds them
    let mut d = dim;
    let mut reports = 0.0;
    let mut worst: Option<(usize, f64)> = None;
    for (k, s) in spec.stages.iter().enumerate() {
        let running = state_bytes(s, d);
        reports += report_bytes(s, d);
        if worst.is_none_or(|(_, b)| running > b) {
            worst = Some((k, running));
        }
        if matches!(s.algorithm, AlgorithmName::Sensitivity | AlgorithmName::Morris) {
            d = d.min(s.keep.unwrap_or(SensitivityOptions::default().max_free));
        }
    }
    if let Some((k, running)) = worst {
        let bytes = running + reports + BASE_BYTES + 64.0 * dim as f64;
        if bytes > limits.max_state_bytes as f64 {
            return Err(Invalid::at(
                format!("stages[{k}]"),
                format!(
                    "stages[{k}] ({}): the optimiser state would grow to about {} while this stage runs: at most {} on \
                     this coordinator (--max-state-bytes); lower the stage's budget{}",
                    s_name(&spec.stages[k]),
                    mib(bytes),
                    mib(limits.max_state_bytes as f64),
                    match spec.stages[k].algorithm {
                        AlgorithmName::Morris => ", trajectories",
                        AlgorithmName::Mcmc => " or walkers",
                        _ => " or population",
                    }
                ),
            ));
        }
    }
    Ok(())
}

fn s_name(s: &StageSpec) -> &'static str {
    s.algorithm.as_str()
}

fn mib(bytes: f64) -> String {
    if bytes >= 1024.0 * 1024.0 * 1024.0 * 1024.0 {
        format!("{:.3e} bytes", bytes)
    } else {
        format!("{:.1} MiB", bytes / (1024.0 * 1024.0))
    }
}

/// The options of a stage that size something, with their values.
fn stage_sizes(s: &StageSpec) -> Vec<(&'static str, usize)> {
    [
        ("population", s.population),
        ("trajectories", s.trajectories),
        ("walkers", s.walkers),
        ("points", s.points),
        ("levels", s.levels),
        ("restarts", s.restarts),
        ("keep", s.keep),
        ("stall_generations", s.stall_generations),
    ]
    .into_iter()
    .filter_map(|(n, v)| v.map(|v| (n, v)))
    .collect()
}

/// Bytes of a pipeline's own fields (space, stage specs, counters).
const BASE_BYTES: f64 = 4096.0;

/// Bytes of one number in the stored JSON (a shortest round-trip f64 and its separator).
const NUMBER_BYTES: f64 = 26.0;

/// An upper estimate of a running stage's state as stored, bytes: what the algorithm keeps
/// between generations. Morris keeps every point of its trajectories, the ensemble sampler its
/// whole chain; the others keep a generation (population × d) and at most a d × d matrix.
/// `tests::estimates_bound_the_stored_state` checks the estimate against measured states.
pub fn state_bytes(s: &StageSpec, d: usize) -> f64 {
    let d = d as f64;
    let budget = s.budget as f64;
    let n = NUMBER_BYTES;
    let generation = |size: f64| 4.0 * size * (d + 2.0) * n;
    match s.algorithm {
        AlgorithmName::Morris => {
            let r = s.trajectories.unwrap_or(10) as f64;
            // points of every trajectory (r (d + 1) × d), their costs and elementary effects
            let points = r * (d + 1.0);
            2.0 * points * (d + 4.0) * n + 1024.0
        }
        AlgorithmName::Mcmc => {
            let w = s.walkers.unwrap_or_else(|| EnsembleSampler::default_walkers(d as usize)) as f64;
            // the chain: every position and cost, plus the current generation and proposals
            2.0 * budget.max(w) * (d + 1.0) * n + generation(w) + 1024.0
        }
        AlgorithmName::Sensitivity => generation(2.0 * d + 1.0) + 1024.0,
        AlgorithmName::DirectSearch => generation(s.points.unwrap_or(20) as f64 * d.max(1.0)) + 1024.0,
        AlgorithmName::Pattern | AlgorithmName::NelderMead => generation(2.0 * d + 2.0) + 4.0 * d * d * n + 1024.0,
        AlgorithmName::Annealing => generation(s.population.unwrap_or(8) as f64) + 1024.0,
        AlgorithmName::Genetic | AlgorithmName::Swarm => {
            generation(s.population.unwrap_or(4 * d as usize + 20) as f64 * 2.0) + 1024.0
        }
        AlgorithmName::Cmaes => {
            let lambda = s.population.unwrap_or(4 + (3.0 * d.max(1.0).ln()).floor() as usize) as f64;
            generation(lambda) + 8.0 * d * d * n + 1024.0
        }
        AlgorithmName::Variance => {
            let restarts = s.restarts.unwrap_or(3) as f64 + 1.0;
            // Hessian stencils (2 d² points), restarts' simplices, profiles and divergent points,
            // and every evaluation (point and cost) for the response surface
            generation(2.0 * d * d + 2.0 * d + 1.0)
                + restarts * generation(d + 1.0)
                + 16.0 * d * d * n
                + 2.0 * budget * (d + 1.0) * n
                + 4096.0
        }
    }
}

/// An upper estimate of a finished stage's report as stored, bytes (summaries; an MCMC stage's
/// posterior draws).
fn report_bytes(s: &StageSpec, d: usize) -> f64 {
    let d = d as f64;
    let n = NUMBER_BYTES;
    let base = 2048.0 + 64.0 * d + 8.0 * d * d * n;
    match s.algorithm {
        AlgorithmName::Mcmc => base + cryofit_calib::pipeline::POSTERIOR_DRAWS as f64 * d * n,
        AlgorithmName::Morris | AlgorithmName::Sensitivity => base + 16.0 * d * n,
        _ => base,
    }
}

/// Values one run of `model` records: probes at every station every `time.output_interval_s`
/// and whole-line profiles every `time.profile_interval_s`, up to where its runs stop (the end
/// of the data). Computed in floating point: a tiny interval gives a huge number, not an overflow.
pub fn output_values(model: &SolverModel) -> f64 {
    let case = model.case();
    let t = &case.time;
    let stop = model.stop_s();
    let probe_times = (stop / t.output_interval_s).floor() + 2.0;
    let profile_times = (stop / t.profile_interval_s).floor() + 2.0;
    probe_times * case.stations.len() as f64 * PROBE_QUANTITIES.len() as f64
        + profile_times * (case.pipe.cells as f64 + 1.0) * PROFILE_VALUES_PER_CELL
}

/// Checks [`output_values`] of an experiment's model against the limit; `field` names the
/// experiment in the request.
pub(crate) fn check_outputs(
    model: &SolverModel,
    label: &str,
    field: &str,
    limits: &api::Limits,
) -> Result<(), Invalid> {
    let values = output_values(model);
    if values > limits.max_output_points as f64 {
        let t = &model.case().time;
        return Err(Invalid::at(
            field,
            format!(
                "{label}: time.output_interval_s = {} and time.profile_interval_s = {} make one evaluation record \
                 about {values:.3e} values (probes at {} stations and profiles of {} cells up to {} s, the end of the \
                 data): at most {} on this coordinator (--max-output-points); lengthen the intervals",
                t.output_interval_s,
                t.profile_interval_s,
                model.case().stations.len(),
                model.case().pipe.cells,
                model.stop_s(),
                limits.max_output_points
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use cryofit_calib::pipeline::Pipeline;
    use cryofit_calib::space::{FreeParameter, Scale, Space};
    use cryofit_calib::{Evaluation, Outcome};

    /// Runs a one-stage pipeline on the sphere to the end; returns the largest stored state.
    fn largest_state(stage: &StageSpec, d: usize) -> usize {
        let space = Space::new(
            (0..d)
                .map(|i| FreeParameter { name: format!("p{i}"), lower: 0.0, upper: 1.0, scale: Scale::Linear })
                .collect(),
        )
        .expect("space");
        let mut p = Pipeline::new(space, vec![stage.clone()], vec![0.5; d], 1).expect("pipeline");
        let mut max = serde_json::to_string(&p).expect("json").len();
        while !p.is_finished() {
            let jobs = p.ask(64);
            if jobs.is_empty() {
                break;
            }
            let ev: Vec<Evaluation> = jobs
                .iter()
                .map(|j| Evaluation {
                    id: j.id,
                    outcome: Outcome::Ok { cost: cryofit_calib::testfns::sphere(&j.unit) },
                })
                .collect();
            p.tell(&ev).expect("tell");
            max = max.max(serde_json::to_string(&p).expect("json").len());
        }
        max
    }

    fn spec(stages: serde_json::Value, max_evaluation_s: f64) -> CalibrationSpec {
        serde_json::from_value(serde_json::json!({
            "name": "t",
            "experiments": [{"case": "c.toml", "data": "d.csv"}],
            "parameters": [{"name": "Gwsc"}, {"name": "hg0sc"}, {"name": "tauw"}, {"name": "Gisc"}],
            "stages": stages,
            "max_evaluation_s": max_evaluation_s,
        }))
        .expect("spec")
    }

    fn refused(stages: serde_json::Value, max_evaluation_s: f64) -> Invalid {
        check_calibration(&spec(stages, max_evaluation_s), 4, &Limits::default()).expect_err("refused")
    }

    #[test]
    fn oversized_requests_are_refused_naming_the_field_and_the_limit() {
        use serde_json::json;
        let e = refused(json!([{"algorithm": "morris", "budget": 500, "trajectories": 100_000_000_000_000u64}]), 60.0);
        assert_eq!(e.field.as_deref(), Some("stages[0].trajectories"), "{e:?}");
        assert!(e.message.contains("at most 10000") && e.message.contains("--max-stage-size"), "{e:?}");
        let e = refused(json!([{"algorithm": "mcmc", "budget": 500, "walkers": 100_000_000_000_000u64}]), 60.0);
        assert_eq!(e.field.as_deref(), Some("stages[0].walkers"), "{e:?}");
        let big = json!({"algorithm": "cmaes", "budget": 9_000_000_000_000_000_000u64});
        let e = refused(json!([big, big, big]), 60.0);
        assert_eq!(e.field.as_deref(), Some("stages[0].budget"), "{e:?}");
        assert!(e.message.contains("--max-budget"), "{e:?}");
        // each stage within the limit, the sum not
        let half = json!({"algorithm": "cmaes", "budget": 600_000});
        let e = refused(json!([half, half]), 60.0);
        assert_eq!(e.field.as_deref(), Some("stages"), "{e:?}");
        // a chain of 900 000 evaluations in four dimensions: about 100 MiB of state
        let e = refused(json!([{"algorithm": "mcmc", "budget": 900_000}]), 60.0);
        assert_eq!(e.field.as_deref(), Some("stages[0]"), "{e:?}");
        assert!(e.message.contains("--max-state-bytes") && e.message.contains("walkers"), "{e:?}");
        let e = refused(json!([{"algorithm": "cmaes", "budget": 50}]), 1e9);
        assert_eq!(e.field.as_deref(), Some("max_evaluation_s"), "{e:?}");
        // what the examples ask for passes
        let fine = json!([{"algorithm": "morris", "budget": 500, "trajectories": 100}, {"algorithm": "cmaes", "budget": 1500},
            {"algorithm": "variance", "budget": 420}, {"algorithm": "mcmc", "budget": 20_000}]);
        check_calibration(&spec(fine, 120.0), 4, &Limits::default()).expect("a usual calibration fits");
    }

    #[test]
    fn estimates_bound_the_stored_state() {
        use AlgorithmName::*;
        for alg in
            [Sensitivity, Morris, DirectSearch, Pattern, Annealing, Genetic, Swarm, Cmaes, NelderMead, Variance, Mcmc]
        {
            for d in [2usize, 7] {
                for budget in [300usize, 1200] {
                    let mut s = StageSpec::new(alg, budget);
                    if alg == Morris {
                        s.trajectories = Some(budget / (d + 1));
                    }
                    let measured = largest_state(&s, d);
                    let estimate = state_bytes(&s, d) + report_bytes(&s, d) + BASE_BYTES;
                    println!("{alg} d={d} budget={budget}: measured {measured}, estimate {estimate:.0}");
                    assert!(measured as f64 <= estimate, "{alg} d={d} budget={budget}: {measured} > {estimate}");
                }
            }
        }
        for alg in [Annealing, Genetic, Swarm, Cmaes, Mcmc] {
            let mut s = StageSpec::new(alg, 1200);
            if alg == Mcmc {
                s.walkers = Some(100);
            } else {
                s.population = Some(100);
            }
            let measured = largest_state(&s, 4);
            let estimate = state_bytes(&s, 4) + report_bytes(&s, 4) + BASE_BYTES;
            assert!(measured as f64 <= estimate, "{alg} size 100: {measured} > {estimate}");
        }
    }
}
