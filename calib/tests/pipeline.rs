//! The stage pipeline end to end on an analytic cost.

use std::collections::BTreeMap;

use cryofit_calib::config::{AlgorithmName, StageSpec};
use cryofit_calib::inference::InferenceSummary;
use cryofit_calib::pipeline::{Job, Pipeline};
use cryofit_calib::{Evaluation, FreeParameter, Outcome, Scale, Space};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

fn space() -> Space {
    let p = |name: &str, lower: f64, upper: f64, scale| FreeParameter { name: name.into(), lower, upper, scale };
    Space::new(vec![
        p("a", 0.0, 4.0, Scale::Linear),
        p("b", 0.1, 10.0, Scale::Log),
        p("inert1", 0.0, 1.0, Scale::Linear),
        p("c", -1.0, 1.0, Scale::Linear),
        p("inert2", 1.0, 2.0, Scale::Linear),
    ])
    .unwrap()
}

/// S = Σ ((x − m)/σ)² on a, ln b, c; the inert parameters do nothing.
fn cost(params: &BTreeMap<String, f64>) -> Outcome {
    let a = params["a"];
    let b = params["b"];
    let c = params["c"];
    let s = ((a - 1.3) / 0.05).powi(2) + ((b.ln() - 2f64.ln()) / 0.02).powi(2) + ((c + 0.2) / 0.01).powi(2);
    Outcome::Ok { cost: s }
}

fn stages() -> Vec<StageSpec> {
    let mut sens = StageSpec::new(AlgorithmName::Sensitivity, 20);
    sens.keep = Some(3);
    let cma = StageSpec::new(AlgorithmName::Cmaes, 900);
    let var = StageSpec::new(AlgorithmName::Variance, 200);
    vec![sens, cma, var]
}

/// Runs to the end asking `batch` at a time; with `shuffle`, tells each batch in a random order
/// and in random chunks.
fn run(batch: usize, shuffle: Option<u64>) -> Pipeline {
    let s = space();
    let start = s.to_unit(&[2.0, 1.0, 0.5, 0.0, 1.5]);
    let mut p = Pipeline::new(s, stages(), start, 5).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(shuffle.unwrap_or(0));
    let mut guard = 0;
    while !p.is_finished() {
        let mut jobs: Vec<Job> = p.ask(batch);
        assert!(!jobs.is_empty(), "nothing to do but not finished");
        if shuffle.is_some() {
            jobs.shuffle(&mut rng);
        }
        let mut results: Vec<Evaluation> =
            jobs.iter().map(|j| Evaluation { id: j.id, outcome: cost(&j.parameters) }).collect();
        while !results.is_empty() {
            let k = if shuffle.is_some() { rng.gen_range(1..=results.len()) } else { results.len() };
            let chunk: Vec<Evaluation> = results.drain(..k).collect();
            p.tell(&chunk).unwrap();
        }
        guard += 1;
        assert!(guard < 100_000);
    }
    p
}

#[test]
fn sensitivity_narrows_then_cmaes_and_variance_find_the_optimum() {
    let p = run(1000, None);
    assert!(p.error().is_none());
    let reports = p.reports();
    assert_eq!(reports.len(), 3);
    // the screen keeps the three parameters that matter
    assert_eq!(reports[1].free, vec!["a", "b", "c"]);
    let best = p.best().unwrap();
    let x = p.parameters(&best.unit);
    assert!((x["a"] - 1.3).abs() < 1e-3 && (x["b"] - 2.0).abs() < 1e-3 && (x["c"] + 0.2).abs() < 1e-3, "{x:?}");
    // inert parameters stay where they started
    assert_eq!((x["inert1"], x["inert2"]), (0.5, 1.5));
    // the Gaussian approximation: σ of S/2 = Σ((x−m)/σ)²/2 ... S = Σ((x−m)/σ)² gives sd = σ/√1
    // (S/2 is the negative log-likelihood of N(m, σ²/ ... ): with S = ((x−m)/σ)², −ln L = S/2,
    // so the posterior sd is σ exactly.
    let Some(InferenceSummary::Variance(v)) = &reports[2].details else { panic!("no variance summary") };
    let g = v.gaussian.as_ref().unwrap();
    assert!((g.sd_physical[0] - 0.05).abs() < 0.05 * 0.02, "{:?}", g.sd_physical);
    assert!((g.sd_physical[2] - 0.01).abs() < 0.01 * 0.02, "{:?}", g.sd_physical);
    // b is log-scaled: sd(b) ≈ b σ_ln = 2 × 0.02
    assert!((g.sd_physical[1] - 0.04).abs() < 0.04 * 0.03, "{:?}", g.sd_physical);
    let (n, failed) = p.evaluations();
    assert_eq!(failed, 0);
    assert!(n <= p.budget());
}

#[test]
fn bit_identical_whatever_the_batch_size_and_telling_order() {
    let reference = run(1000, None);
    for (batch, shuffle) in [(1, None), (3, Some(1)), (7, Some(2)), (64, Some(3))] {
        let p = run(batch, shuffle);
        let (a, b) = (reference.best().unwrap(), p.best().unwrap());
        assert_eq!(a.cost.to_bits(), b.cost.to_bits(), "batch {batch}");
        assert_eq!(a.unit, b.unit);
        assert_eq!(reference.evaluations(), p.evaluations());
    }
}

#[test]
fn tell_rejects_unknown_and_repeated_ids_without_changing_anything() {
    let s = space();
    let start = vec![0.5; 5];
    let mut p = Pipeline::new(s, stages(), start, 1).unwrap();
    let jobs = p.ask(4);
    assert!(!jobs.is_empty());
    let ok = |id| Evaluation { id, outcome: Outcome::Ok { cost: 1.0 } };
    assert!(p.tell(&[ok(999)]).is_err());
    assert!(p.tell(&[ok(jobs[0].id), ok(jobs[0].id)]).is_err());
    assert!(p.tell(&[Evaluation { id: jobs[0].id, outcome: Outcome::Ok { cost: f64::NAN } }]).is_err());
    assert_eq!(p.evaluations(), (0, 0));
    assert_eq!(p.outstanding(), jobs.len());
    p.tell(&[ok(jobs[0].id)]).unwrap();
    assert!(p.tell(&[ok(jobs[0].id)]).is_err(), "a job told twice is refused");
}

#[test]
fn bad_stage_options_are_refused_up_front() {
    let s = space();
    let mut st = stages();
    st[2].budget = 5; // too small for the Hessian of 5 parameters
    let e = Pipeline::new(s, st, vec![0.5; 5], 1).unwrap_err();
    assert!(matches!(e, cryofit_calib::pipeline::PipelineError::Stage { index: 2, .. }), "{e:?}");
    let e = e.to_string();
    assert!(e.starts_with("stages[2]: ") && e.contains("budget"), "{e}");
}

#[cfg(feature = "serde")]
#[test]
fn persisted_mid_run_and_resumed_bit_identically() {
    let reference = run(16, None);
    let s = space();
    let start = s.to_unit(&[2.0, 1.0, 0.5, 0.0, 1.5]);
    let mut p = Pipeline::new(s, stages(), start, 5).unwrap();
    let mut asks = 0;
    while !p.is_finished() {
        let jobs = p.ask(16);
        let results: Vec<Evaluation> =
            jobs.iter().map(|j| Evaluation { id: j.id, outcome: cost(&j.parameters) }).collect();
        // persist with half of the batch outstanding, then resume
        let (first, second) = results.split_at(results.len() / 2);
        p.tell(first).unwrap();
        let json = serde_json::to_string(&p).unwrap();
        p = serde_json::from_str(&json).unwrap();
        p.tell(second).unwrap();
        asks += 1;
    }
    assert!(asks > 10);
    assert_eq!(reference.best().unwrap().cost.to_bits(), p.best().unwrap().cost.to_bits());
}

/// S of [`cost`] on a and c plus a deterministic jitter of standard deviation `noise` (a hash of
/// the point's bits), as a simulated cost jitters between nearby parameter sets.
fn jittered(params: &BTreeMap<String, f64>, noise: f64) -> Outcome {
    let (a, c) = (params["a"], params["c"]);
    let mut h = a.to_bits() ^ c.to_bits().rotate_left(29) ^ 0x9E37_79B9_7F4A_7C15;
    for _ in 0..3 {
        h ^= h >> 31;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    }
    let u = (h >> 11) as f64 / (1u64 << 53) as f64;
    let s = ((a - 1.3) / 0.05).powi(2) + ((c + 0.2) / 0.01).powi(2);
    Outcome::Ok { cost: 100.0 + s + noise * 12f64.sqrt() * (u - 0.5) }
}

/// An MCMC stage at `temperature = "noise"` samples the likelihood tempered by the variance
/// stage's noise inflation: on a cost that jitters, its walkers keep moving and its spread is
/// the one the variance stage reports, where the plain likelihood leaves them stuck on lucky
/// points of the jitter.
#[test]
fn an_mcmc_stage_at_the_noise_temperature_samples_the_variance_stage_spread() {
    use cryofit_calib::config::Temperature;
    let p =
        |name: &str, lower: f64, upper: f64| FreeParameter { name: name.into(), lower, upper, scale: Scale::Linear };
    let run = |temperature: Temperature| {
        let s = Space::new(vec![p("a", 0.0, 4.0), p("c", -1.0, 1.0)]).unwrap();
        let start = s.to_unit(&[1.5, 0.0]);
        let mut mcmc = StageSpec::new(AlgorithmName::Mcmc, 16 * 500);
        mcmc.walkers = Some(16);
        mcmc.spread = Some(0.02);
        mcmc.temperature = Some(temperature);
        let mut variance = StageSpec::new(AlgorithmName::Variance, 60);
        variance.step = Some(0.05);
        let stages = vec![StageSpec::new(AlgorithmName::Cmaes, 400), variance, mcmc];
        let mut pipe = Pipeline::new(s, stages, start, 9).unwrap();
        while !pipe.is_finished() {
            let jobs = pipe.ask(64);
            let results: Vec<Evaluation> =
                jobs.iter().map(|j| Evaluation { id: j.id, outcome: jittered(&j.parameters, 5.0) }).collect();
            pipe.tell(&results).unwrap();
        }
        pipe
    };
    let pipe = run(Temperature::Noise);
    let reports = pipe.reports();
    let Some(InferenceSummary::Variance(v)) = &reports[1].details else { panic!("no variance summary") };
    let g = v.gaussian.as_ref().unwrap();
    let noise = g.cost_noise.unwrap();
    println!("jitter {noise}, variance sd {:?}, positive definite {}", g.sd_physical, g.positive_definite);
    assert!(noise > 2.5 && noise < 10.0, "measured jitter {noise} (5 put in)");
    let Some(InferenceSummary::Mcmc(m)) = &reports[2].details else { panic!("no MCMC summary") };
    assert_eq!(m.temperature, g.noise_inflation);
    assert_eq!(pipe.noise_temperature(), g.noise_inflation);
    assert!(m.acceptance_fraction.unwrap() > 0.2, "acceptance {:?}", m.acceptance_fraction);
    for i in 0..2 {
        let ratio = m.parameters[i].sd / g.sd_physical[i];
        assert!(
            ratio > 0.6 && ratio < 1.5,
            "parameter {i}: MCMC sd {} vs variance sd {}",
            m.parameters[i].sd,
            g.sd_physical[i]
        );
    }
    // the plain likelihood on the same jitter: the walkers stick
    let plain = run(Temperature::Value(1.0));
    let Some(InferenceSummary::Mcmc(m1)) = &plain.reports()[2].details else { panic!("no MCMC summary") };
    assert_eq!(m1.temperature, 1.0);
    assert!(m1.acceptance_fraction.unwrap() < 0.5 * m.acceptance_fraction.unwrap(), "{:?}", m1.acceptance_fraction);
}

#[test]
fn the_noise_temperature_needs_a_variance_stage_before_it() {
    let mut mcmc = StageSpec::new(AlgorithmName::Mcmc, 400);
    mcmc.temperature = Some(cryofit_calib::config::Temperature::Noise);
    let e = Pipeline::new(space(), vec![StageSpec::new(AlgorithmName::Cmaes, 100), mcmc], vec![0.5; 5], 1).unwrap_err();
    assert!(matches!(e, cryofit_calib::pipeline::PipelineError::NoiseWithoutVariance { index: 1 }), "{e:?}");
    assert!(e.to_string().starts_with("stages[1].temperature = \"noise\""), "{e}");
}

/// On a cost that jitters, the variance stage's response-surface minimum becomes the calibration's
/// estimate in place of the lowest (luckiest) evaluation, and a later evaluation replaces it only
/// when it is lower than the surface's prediction by more than three residual RMS.
#[test]
fn a_variance_stage_on_a_jittering_cost_estimates_at_its_response_surface_minimum() {
    let p =
        |name: &str, lower: f64, upper: f64| FreeParameter { name: name.into(), lower, upper, scale: Scale::Linear };
    let s = Space::new(vec![p("a", 0.0, 4.0), p("c", -1.0, 1.0)]).unwrap();
    let start = s.to_unit(&[1.5, 0.0]);
    let mut variance = StageSpec::new(AlgorithmName::Variance, 60);
    variance.step = Some(0.05);
    let mut mcmc = StageSpec::new(AlgorithmName::Mcmc, 16 * 50);
    mcmc.walkers = Some(16);
    mcmc.spread = Some(0.02);
    mcmc.temperature = Some(cryofit_calib::config::Temperature::Noise);
    let stages = vec![StageSpec::new(AlgorithmName::Cmaes, 400), variance, mcmc];
    let mut pipe = Pipeline::new(s, stages, start, 9).unwrap();
    let mut lowest = (f64::INFINITY, BTreeMap::new());
    while !pipe.is_finished() {
        let jobs = pipe.ask(64);
        let results: Vec<Evaluation> =
            jobs.iter().map(|j| Evaluation { id: j.id, outcome: jittered(&j.parameters, 5.0) }).collect();
        for (j, r) in jobs.iter().zip(&results) {
            if let Outcome::Ok { cost } = r.outcome
                && cost < lowest.0
            {
                lowest = (cost, j.parameters.clone());
            }
        }
        pipe.tell(&results).unwrap();
    }
    let reports = pipe.reports();
    let Some(InferenceSummary::Variance(v)) = &reports[1].details else { panic!("no variance summary") };
    let surface = v.surface.as_ref().expect("surface");
    assert!(surface.accepted, "{surface:?}");
    let centre = surface.centre_physical.as_ref().unwrap();
    let threshold = surface.predicted_cost.unwrap() - 3.0 * surface.residual_rms;
    assert!(lowest.0 >= threshold, "an evaluation beat the surface beyond its jitter: {} < {threshold}", lowest.0);
    // the variance stage reports it, and the calibration's estimate stays it through the MCMC stage
    assert_eq!(reports[1].best_cost, surface.cost);
    assert_eq!((reports[1].best_parameters["a"], reports[1].best_parameters["c"]), (centre[0], centre[1]));
    let best = pipe.best().unwrap();
    assert_eq!(best.cost, surface.cost.unwrap());
    assert_eq!(pipe.parameters(&best.unit)["a"], centre[0]);
    assert!(best.cost > lowest.0, "the estimate is not the lowest evaluation here");
    // nearer the true minimum (1.3, −0.2), in its standard deviations, than the lowest evaluation
    let distance = |a: f64, c: f64| (((a - 1.3) / 0.05).powi(2) + ((c + 0.2) / 0.01).powi(2)).sqrt();
    let (d_surface, d_lowest) = (distance(centre[0], centre[1]), distance(lowest.1["a"], lowest.1["c"]));
    println!("distance from the truth: surface minimum {d_surface:.3} sd, lowest evaluation {d_lowest:.3} sd");
    assert!(d_surface < d_lowest, "{d_surface} vs {d_lowest}");
}
