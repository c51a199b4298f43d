//! Integration tests of the inference stages: sensitivity, Morris, Nelder–Mead, variance, ensemble
//! sampler and model comparison, each on a problem with a known answer, plus determinism under
//! batching and reordering, and (feature `serde`) pause/resume through JSON.

use cryofit_calib::inference::*;
use cryofit_calib::{
    Candidate, Evaluation, FreeParameter, Optimizer, Outcome, Scale, Space, TellError, minimize, testfns,
};
use nalgebra::DMatrix;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn param(name: &str, lower: f64, upper: f64, scale: Scale) -> FreeParameter {
    FreeParameter { name: name.into(), lower, upper, scale }
}

fn ok(cost: f64) -> Outcome {
    Outcome::Ok { cost }
}

/// Runs an optimiser asking `batch` at a time until nothing more is handed out, then tells every
/// outstanding result in a shuffled order and in random groupings; repeats to the end.
fn run_shuffled<O: Optimizer + ?Sized>(opt: &mut O, batch: usize, seed: u64, mut f: impl FnMut(&[f64]) -> Outcome) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    while opt.finished().is_none() {
        let mut pending: Vec<Candidate> = Vec::new();
        loop {
            let got = opt.ask(batch);
            if got.is_empty() {
                break;
            }
            pending.extend(got);
        }
        assert!(!pending.is_empty(), "nothing handed out but not finished");
        pending.shuffle(&mut rng);
        let mut results: Vec<Evaluation> =
            pending.iter().map(|c| Evaluation { id: c.id, outcome: f(&c.unit) }).collect();
        while !results.is_empty() {
            let k = rng.gen_range(1..=results.len());
            let chunk: Vec<Evaluation> = results.drain(..k).collect();
            opt.tell(&chunk).unwrap();
        }
    }
}

/// `S = s0 + (x − m)ᵀ A (x − m)`.
fn quadratic(a: &DMatrix<f64>, m: &[f64], s0: f64) -> impl Fn(&[f64]) -> f64 + Clone + use<> {
    let a = a.clone();
    let m = m.to_vec();
    move |x: &[f64]| {
        let d = m.len();
        let mut s = s0;
        for i in 0..d {
            for j in 0..d {
                s += (x[i] - m[i]) * a[(i, j)] * (x[j] - m[j]);
            }
        }
        s
    }
}

/// Covariance from standard deviations and a correlation matrix.
fn covariance(sd: &[f64], corr: &[&[f64]]) -> DMatrix<f64> {
    let d = sd.len();
    DMatrix::from_fn(d, d, |i, j| sd[i] * sd[j] * corr[i][j])
}

mod sensitivity {
    use super::*;

    fn space() -> Space {
        Space::new(vec![
            param("a", 0.0, 10.0, Scale::Linear),
            param("b", 0.1, 100.0, Scale::Log),
            param("c", -5.0, 5.0, Scale::Linear),
            param("d", 0.0, 1.0, Scale::Linear),
        ])
        .unwrap()
    }

    const WEIGHTS: [f64; 4] = [1.0, 0.5, 3.0, 0.0];
    const BASE: [f64; 4] = [2.0, 3.0, -1.0, 0.5];

    fn cost(space: &Space, u: &[f64]) -> f64 {
        let x = space.to_physical(u);
        WEIGHTS.iter().zip(&x).map(|(a, x)| a * x * x).sum()
    }

    #[test]
    fn one_at_a_time_matches_the_analytic_relative_sensitivity() {
        let space = space();
        let base = space.to_unit(&BASE);
        let mut s = Sensitivity::new(&space, Some(&base), SensitivityOptions::default(), 100, 1).unwrap();
        minimize(&mut s, 4, |u| ok(cost(&space, u)));
        let r = s.summary();
        assert!(matches!(s.finished(), Some(cryofit_calib::StopReason::Converged { .. })));
        assert_eq!((r.evaluations, s.told()), (9, 9), "2d + 1 evaluations, no more");
        let s0: f64 = WEIGHTS.iter().zip(&BASE).map(|(a, x)| a * x * x).sum();
        assert!((r.base_cost.unwrap() - s0).abs() < 1e-12);
        // S = Σ a x² ⇒ (∂S/∂x)(x/S) = 2 a x² / S; central differences are exact for quadratics.
        for (p, (a, x)) in r.parameters.iter().zip(WEIGHTS.iter().zip(&BASE)) {
            let expected = 2.0 * a * x * x / s0;
            let got = p.relative_sensitivity.unwrap();
            assert!((got - expected).abs() < 1e-9, "{}: {got} vs {expected}", p.name);
            assert_eq!(p.difference, Difference::Central);
        }
        let total: f64 = r.parameters.iter().map(|p| p.relative_sensitivity.unwrap()).sum();
        assert!((total - 2.0).abs() < 1e-9, "Euler: a homogeneous quadratic's sensitivities sum to 2");
        assert_eq!(r.ranking.order(), vec![1, 0, 2, 3]);
        assert_eq!(r.suggested_free, vec![1, 0, 2]);
        assert_eq!(r.ranking.suggested_free(FreeSelection::Top(2)), vec![1, 0]);
        let e = Sensitivity::new(&space, Some(&base), SensitivityOptions::default(), 8, 1).unwrap_err();
        assert!(matches!(e, InferenceError::BudgetTooSmall { required: 9, .. }), "{e}");
    }

    #[test]
    fn a_single_square_has_sensitivity_two() {
        let space = Space::new(vec![param("x", 0.5, 20.0, Scale::Log)]).unwrap();
        let base = space.to_unit(&[4.0]);
        let mut s = Sensitivity::new(&space, Some(&base), SensitivityOptions::default(), 3, 0).unwrap();
        minimize(&mut s, 1, |u| ok(3.0 * space.value(0, u[0]).powi(2)));
        let v = s.summary().parameters[0].relative_sensitivity.unwrap();
        assert!((v - 2.0).abs() < 1e-9, "{v}");
    }

    #[test]
    fn bounds_and_failures_give_one_sided_differences() {
        let space = space();
        // `a` at its upper bound: only the lower side exists.
        let base = space.to_unit(&[10.0, 3.0, -1.0, 0.5]);
        let mut s = Sensitivity::new(&space, Some(&base), SensitivityOptions::default(), 8, 1).unwrap();
        // `c` above −0.95 diverges: its upper perturbation (−0.9) fails.
        minimize(&mut s, 3, |u| {
            if space.value(2, u[2]) > -0.95 {
                Outcome::Failed { reason: "diverged".into() }
            } else {
                ok(cost(&space, u))
            }
        });
        let r = s.summary();
        assert_eq!(r.evaluations, 8);
        let s0 = 100.0 + 4.5 + 3.0;
        let a = &r.parameters[0];
        assert_eq!((a.difference, a.upper_value), (Difference::Backward, None));
        // Backward difference of a x² with step h = 0.1 x: (2x − h) a x / S = 1.9 a x² / S.
        assert!((a.relative_sensitivity.unwrap() - 1.9 * 100.0 / s0).abs() < 1e-9);
        let c = &r.parameters[2];
        assert_eq!(c.difference, Difference::Backward);
        assert_eq!(c.failures.len(), 1);
        assert_eq!((c.failures[0].side, c.failures[0].reason.as_str()), (Side::Upper, "diverged"));
    }

    #[test]
    fn morris_ranks_influential_above_inert() {
        let d = 6;
        let f = |u: &[f64]| 50.0 * u[0] * u[0] + 20.0 * (u[1] - 0.5).powi(2) + 10.0 * u[2] + 0.01 * u[5];
        let options = MorrisOptions { trajectories: 12, ..MorrisOptions::default() };
        let mut m = Morris::new(d, None, options, 1000, 7).unwrap();
        minimize(&mut m, 5, |u| ok(f(u)));
        let r = m.summary();
        assert_eq!((r.evaluations, m.told()), (12 * (d + 1), 12 * (d + 1)));
        for inert in [3, 4] {
            assert_eq!(r.parameters[inert].mu_star, Some(0.0));
        }
        let top: std::collections::BTreeSet<usize> = r.ranking.order()[..3].iter().copied().collect();
        assert_eq!(top, [0, 1, 2].into_iter().collect());
        assert_eq!(r.ranking.order()[3], 5);
        let mut free = r.suggested_free.clone();
        free.sort();
        assert_eq!(free, vec![0, 1, 2]);
        // A linear effect has σ = 0; a quadratic one does not.
        assert!(r.parameters[2].sigma.unwrap() < 1e-9 && r.parameters[0].sigma.unwrap() > 1.0);
        let e = Morris::new(d, None, MorrisOptions::default(), 69, 7).unwrap_err();
        assert!(matches!(e, InferenceError::BudgetTooSmall { required: 70, .. }), "{e}");
        let e = Morris::new(d, None, MorrisOptions { levels: 5, ..MorrisOptions::default() }, 100, 7).unwrap_err();
        assert!(matches!(e, InferenceError::InvalidOption { option: "levels", .. }), "{e}");
    }
}

mod nelder_mead {
    use super::*;

    fn solve(f: fn(&[f64]) -> f64, d: usize, budget: usize) -> (NelderMeadSummary, usize) {
        let mut nm = NelderMead::new(d, Some(&vec![0.6; d]), NelderMeadOptions::default(), budget, 0).unwrap();
        minimize(&mut nm, 1, |u| ok(f(u)));
        (nm.summary(), nm.told())
    }

    #[test]
    fn converges_on_sphere_and_rosenbrock() {
        for d in [2, 3, 5] {
            for (name, f, budget) in
                [("sphere", testfns::sphere as fn(&[f64]) -> f64, 3000), ("rosenbrock", testfns::rosenbrock, 20000)]
            {
                let (s, told) = solve(f, d, budget);
                let best = s.best_unit.clone().unwrap();
                let err = best.iter().map(|v| (v - testfns::OPTIMUM_UNIT).abs()).fold(0.0, f64::max);
                println!(
                    "NM {name} d={d}: cost {:.2e}, error {err:.1e}, {told} evaluations, {:?}",
                    s.best_cost.unwrap(),
                    s.stop
                );
                assert!(s.best_cost.unwrap() < 1e-8, "{name} d={d}: {s:?}");
                assert!(err < 1e-4, "{name} d={d}: {best:?}");
                assert!(
                    matches!(s.stop, Some(cryofit_calib::StopReason::Converged { .. })),
                    "{name} d={d}: {:?}",
                    s.stop
                );
                assert!(told <= budget);
            }
        }
    }

    #[test]
    fn stays_in_the_box_handles_failures_and_respects_the_budget() {
        // Minimum outside the box at u = −0.2: the search presses against the face u₀ = 0.
        let f = |u: &[f64]| (u[0] + 0.2).powi(2) + (u[1] - 0.5).powi(2);
        let mut nm = NelderMead::new(2, None, NelderMeadOptions::default(), 30, 0).unwrap();
        let mut seen = 0;
        minimize(&mut nm, 2, |u| {
            seen += 1;
            assert!(u.iter().all(|v| (0.0..=1.0).contains(v)));
            if u[1] > 0.8 { Outcome::Failed { reason: "diverged".into() } } else { ok(f(u)) }
        });
        assert_eq!((seen, nm.told()), (30, 30));
        assert_eq!(nm.finished(), Some(cryofit_calib::StopReason::Budget));
        let best = nm.best().unwrap();
        assert!(best.unit[0] < 1e-3 && (best.unit[1] - 0.5).abs() < 1e-2, "{best:?}");
    }
}

mod variance {
    use super::*;

    /// x₀ linear, x₁ logarithmic, x₂ linear; correlated Gaussian in physical units.
    fn problem() -> (Space, Vec<f64>, DMatrix<f64>) {
        let space = Space::new(vec![
            param("gwsc", 0.0, 10.0, Scale::Linear),
            param("hg0sc", 0.1, 100.0, Scale::Log),
            param("xmin", -1.0, 1.0, Scale::Linear),
        ])
        .unwrap();
        let m = vec![4.0, 2.0, 0.3];
        let cov = covariance(&[0.05, 0.02, 0.01], &[&[1.0, 0.6, -0.3], &[0.6, 1.0, 0.2], &[-0.3, 0.2, 1.0]]);
        (space, m, cov)
    }

    /// A cost with numerical noise (a deterministic hash of the point, sd 20 cost units, like a
    /// simulation's): the noise is measured from the profiles and the intervals are widened
    /// enough to cover the truth, which the statistical intervals alone do not.
    #[test]
    fn noisy_cost_is_measured_and_widens_the_intervals() {
        let (space, m, cov) = problem();
        let s = quadratic(&cov.clone().try_inverse().unwrap(), &m, 10.0);
        let noise = |u: &[f64]| {
            let h = u.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, x| (h ^ x.to_bits()).wrapping_mul(0x0100_0000_01b3));
            // two uniform draws → a normal one (Box–Muller)
            let a = ((h >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            let b = ((h.rotate_left(29) >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
            20.0 * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let start: Vec<f64> = space.to_unit(&m).iter().map(|u| u + 0.01).collect();
        let o = VarianceOptions { hessian_step: 0.05, ..VarianceOptions::default() };
        let mut v = Variance::new(&space, Some(&start), o, 800, 3).unwrap();
        minimize(&mut v, 4, |u: &[f64]| ok((s(&space.to_physical(u)) + noise(u)).max(0.0)));
        let r = v.summary();
        let g = r.gaussian.as_ref().expect("gaussian");
        let sigma = g.cost_noise.expect("noise estimate");
        assert!((8.0..50.0).contains(&sigma), "cost noise {sigma}");
        assert!(g.noise_inflation > 10.0, "{}", g.noise_inflation);
        for (i, (iv, &truth)) in g.interval95.iter().zip(&m).enumerate() {
            assert!(
                iv.lower <= truth && truth <= iv.upper,
                "parameter {i}: {truth} not in [{}, {}]",
                iv.lower,
                iv.upper
            );
        }
        // The response surface's minimum is the estimate, and it lies inside the intervals too.
        // (Here the quadratic spans a region where the log-scaled parameter makes the cost far from
        // quadratic, so the residual RMS holds shape as well as noise.)
        let surface = r.surface.as_ref().expect("surface");
        assert!(surface.accepted, "{surface:?}");
        let inv = cov.clone().try_inverse().unwrap();
        let mahalanobis = |x: &[f64]| quadratic(&inv, &m, 0.0)(x).sqrt();
        let lowest = mahalanobis(&space.to_physical(&v.best().unwrap().unit));
        let centre = surface.centre_physical.as_ref().unwrap();
        println!(
            "residual RMS {:.1}; distance from the truth: lowest evaluation {lowest:.2} sd, surface minimum {:.2} sd",
            surface.residual_rms,
            mahalanobis(centre)
        );
        for (i, (iv, &c)) in g.interval95.iter().zip(centre).enumerate() {
            assert!(iv.lower <= c && c <= iv.upper, "parameter {i}: {c} not in [{}, {}]", iv.lower, iv.upper);
        }
        let e = v.surface_estimate().expect("estimate");
        assert_eq!(Some(&e.unit), surface.centre_unit.as_ref());
        assert_eq!(Some(e.cost), surface.cost);
    }

    /// On an exact quadratic the surface's minimum is the minimum, and its evaluation agrees with
    /// the prediction; on a cost with a cliff beside the optimum the evaluation disagrees and the
    /// lowest evaluation stays the estimate.
    #[test]
    fn the_response_surface_finds_an_exact_minimum_and_rejects_a_cliff() {
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear), param("b", 0.0, 1.0, Scale::Linear)]).unwrap();
        let cov = covariance(&[0.02, 0.03], &[&[1.0, 0.4], &[0.4, 1.0]]);
        let m = [0.4, 0.55];
        let s = quadratic(&cov.clone().try_inverse().unwrap(), &m, 3.0);
        let mut v = Variance::new(&space, Some(&[0.42, 0.53]), VarianceOptions::default(), 200, 2).unwrap();
        minimize(&mut v, 5, |u| ok(s(u)));
        let r = v.summary();
        let surface = r.surface.as_ref().expect("surface");
        assert!(surface.accepted, "{surface:?}");
        let c = surface.centre_unit.as_ref().unwrap();
        assert!((c[0] - m[0]).abs() < 1e-9 && (c[1] - m[1]).abs() < 1e-9, "{c:?}");
        assert!(surface.residual_rms < 1e-9 && (surface.predicted_cost.unwrap() - 3.0).abs() < 1e-9);
        // a cliff exactly where the surface's minimum falls (the runs are deterministic, so only its
        // evaluation lands there): the evaluation is far off the prediction
        let centre = c.clone();
        let cliff = |u: &[f64]| if u == centre.as_slice() { 50.0 } else { s(u) };
        let mut v = Variance::new(&space, Some(&[0.42, 0.53]), VarianceOptions::default(), 200, 2).unwrap();
        minimize(&mut v, 5, |u| ok(cliff(u)));
        let surface = v.summary().surface.expect("surface");
        assert!(!surface.accepted && surface.cost == Some(50.0), "{surface:?}");
        assert!(surface.note.as_deref().unwrap().contains("within three residual RMS"), "{surface:?}");
        assert!(v.surface_estimate().is_none());
    }

    #[test]
    fn hessian_covariance_matches_the_analytic_one_in_physical_units() {
        let (space, m, cov) = problem();
        let s = quadratic(&cov.clone().try_inverse().unwrap(), &m, 10.0);
        let start: Vec<f64> = space.to_unit(&m).iter().map(|u| u + 0.01).collect();
        let mut v = Variance::new(&space, Some(&start), VarianceOptions::default(), 800, 3).unwrap();
        let f = |u: &[f64]| ok(s(&space.to_physical(u)));
        minimize(&mut v, 4, f);
        let r = v.summary();
        let g = r.gaussian.as_ref().expect("gaussian");
        println!(
            "variance: {} evaluations, restarts {:?}",
            r.evaluations,
            r.restarts.iter().map(|r| r.evaluations).collect::<Vec<_>>()
        );
        println!("sd {:?}, eigenvalues {:?}, warnings {:?}", g.sd_physical, g.eigenvalues, r.warnings);
        assert!(g.positive_definite && r.warnings.is_empty(), "{:?}", r.warnings);
        for i in 0..3 {
            let sd = cov[(i, i)].sqrt();
            assert!((g.sd_physical[i] / sd - 1.0).abs() < 0.01, "sd {i}: {} vs {sd}", g.sd_physical[i]);
            assert!((g.centre_physical[i] - m[i]).abs() < 0.05 * sd, "centre {i}");
            for j in 0..3 {
                let rho = cov[(i, j)] / (sd * cov[(j, j)].sqrt());
                assert!((g.correlation[i][j] - rho).abs() < 0.01, "corr {i}{j}: {} vs {rho}", g.correlation[i][j]);
            }
            let half = 1.96 * sd;
            let iv = &g.interval95[i];
            assert!(((iv.upper - iv.lower) / (2.0 * half) - 1.0).abs() < 0.01, "interval {i}: {iv:?}");
            assert!(!iv.clamped);
        }
        assert!((g.cost - 10.0).abs() < 1e-6);
        assert_eq!(r.hessian_evaluations, Variance::hessian_evaluations(3));
        assert_eq!(r.restarts.len(), 3);
        assert!(r.divergent.is_empty());
        // Profiles follow the Gaussian prediction closely on a (nearly) quadratic cost.
        for p in &r.profiles {
            assert_eq!(p.points.len(), 6);
            for q in &p.points {
                let (c, g) = (q.cost.unwrap(), q.gaussian_cost.unwrap());
                assert!((c - g).abs() < 0.05 * (g - 10.0) + 1e-6, "{}: {c} vs {g}", p.name);
            }
        }
    }

    #[test]
    fn finds_a_divergent_region_next_to_the_optimum() {
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear), param("b", 0.0, 1.0, Scale::Linear)]).unwrap();
        let (m, sd) = ([0.4, 0.6], 0.01);
        let s = quadratic(&(DMatrix::identity(2, 2) / (sd * sd)), &m, 5.0);
        let mut v = Variance::new(&space, Some(&[0.41, 0.59]), VarianceOptions::default(), 400, 1).unwrap();
        // Beyond 2.5 σ above the optimum in `a`, the simulation diverges.
        minimize(&mut v, 3, |u| {
            if u[0] > 0.425 { Outcome::Failed { reason: "void fraction above 1 in cell 7".into() } } else { ok(s(u)) }
        });
        let r = v.summary();
        let g = r.gaussian.as_ref().unwrap();
        assert!((g.sd_unit[0] / sd - 1.0).abs() < 0.01 && (g.sd_unit[1] / sd - 1.0).abs() < 0.01);
        assert!(!r.divergent.is_empty());
        let nearest = &r.divergent[0];
        println!("nearest divergent point: {nearest:?} ({} in all)", r.divergent.len());
        assert!(nearest.distance > 0.025 - 1e-3 && nearest.distance < 0.035, "{nearest:?}");
        assert!(nearest.unit[0] > 0.425 && nearest.reason.contains("void fraction"));
        let pa = &r.profiles[0];
        assert!((pa.nearest_failure.unwrap() - 0.03).abs() < 1e-3, "{:?}", pa.nearest_failure);
        assert!(r.profiles[1].nearest_failure.is_none());
        assert!(r.divergent.iter().all(|p| p.distance <= 0.1));
    }

    #[test]
    fn one_sided_hessian_at_a_bound() {
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear), param("b", 0.0, 1.0, Scale::Linear)]).unwrap();
        let cov = covariance(&[0.02, 0.03], &[&[1.0, -0.5], &[-0.5, 1.0]]);
        let m = [0.998, 0.5];
        let s = quadratic(&cov.clone().try_inverse().unwrap(), &m, 0.0);
        let options = VarianceOptions { restarts: 0, profile_points: 0, ..VarianceOptions::default() };
        let mut v = Variance::new(&space, Some(&m), options, 9, 1).unwrap();
        minimize(&mut v, 9, |u| ok(s(u)));
        let r = v.summary();
        let g = r.gaussian.unwrap();
        // Upper stencil for `a`: fewer distinct points than 1 + 2d².
        assert!(r.hessian_evaluations < 9, "{}", r.hessian_evaluations);
        for i in 0..2 {
            for j in 0..2 {
                assert!((g.covariance_unit[i][j] / cov[(i, j)] - 1.0).abs() < 1e-6, "{i}{j}");
            }
        }
        assert!(g.interval95[0].clamped && g.interval95[0].upper == 1.0);
    }

    #[test]
    fn rejects_a_budget_without_room_for_the_hessian() {
        let (space, _, _) = problem();
        // 1 + 2·9 Hessian + 2·3·3 profile + 3·4 restarts = 49 (the response surface's minimum is
        // evaluated only when the budget has room for it)
        let e = Variance::new(&space, None, VarianceOptions::default(), 48, 0).unwrap_err();
        assert!(matches!(e, InferenceError::BudgetTooSmall { required: 49, .. }), "{e}");
        assert!(Variance::new(&space, None, VarianceOptions::default(), 49, 0).is_ok());
    }

    #[test]
    fn is_deterministic_under_batching_and_reordering() {
        let (space, m, cov) = problem();
        let s = quadratic(&cov.clone().try_inverse().unwrap(), &m, 1.0);
        let start: Vec<f64> = space.to_unit(&m).iter().map(|u| u + 0.02).collect();
        let f =
            |u: &[f64]| if u[2] > 0.66 { Outcome::Failed { reason: "x".into() } } else { ok(s(&space.to_physical(u))) };
        let mut runs = Vec::new();
        for (batch, seed) in [(1, 0), (3, 1), (1000, 2)] {
            let mut v = Variance::new(&space, Some(&start), VarianceOptions::default(), 300, 9).unwrap();
            run_shuffled(&mut v, batch, seed, f);
            runs.push(format!("{:?}", v.summary()));
        }
        assert!(runs.iter().all(|r| *r == runs[0]));
    }
}

mod mcmc {
    use super::*;

    fn unit_space(d: usize) -> Space {
        Space::new((0..d).map(|i| param(&format!("p{i}"), 0.0, 1.0, Scale::Linear)).collect()).unwrap()
    }

    /// Samples `exp(−S/2)`, `S = (u − m)ᵀ Σ⁻¹ (u − m)`, and checks mean, sd, correlation and R-hat.
    /// Tolerances: `tol_mean_sd` in posterior standard deviations, `tol_sd` relative, `tol_corr`
    /// absolute. They are about twice the worst error seen over 15 seeds at the same budget.
    fn recovers(m: &[f64], cov: &DMatrix<f64>, budget: usize, tol_mean_sd: f64, tol_sd: f64, tol_corr: f64) {
        let seed = 11;
        let d = m.len();
        let space = unit_space(d);
        let s = quadratic(&cov.clone().try_inverse().unwrap(), m, 0.0);
        let start: Vec<f64> = m.iter().map(|v| v + 0.02).collect();
        let mut e = EnsembleSampler::new(&space, Some(&start), McmcOptions::default(), budget, seed).unwrap();
        minimize(&mut e, 64, |u| ok(s(u)));
        let r = e.summary();
        println!(
            "mcmc d={d}: {} iterations, acceptance {:.3}, max R-hat {:.4}, tau {:?}",
            r.iterations,
            r.acceptance_fraction.unwrap(),
            r.max_r_hat.unwrap(),
            r.parameters.iter().map(|p| p.autocorr_time.unwrap()).collect::<Vec<_>>()
        );
        let (mut em, mut es, mut ec) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..d {
            let sd = cov[(i, i)].sqrt();
            em = em.max((r.parameters[i].mean_unit - m[i]).abs() / sd);
            es = es.max((r.parameters[i].sd_unit / sd - 1.0).abs());
            for j in 0..d {
                ec = ec.max((r.correlation[i][j] - cov[(i, j)] / (sd * cov[(j, j)].sqrt())).abs());
            }
        }
        println!(
            "mcmc d={d} seed {seed}: max |mean error| {em:.3} σ, max sd error {:.1} %, max corr error {ec:.3}, warnings {}",
            100.0 * es,
            r.warnings.len()
        );
        assert!(r.max_r_hat.unwrap() < 1.05);
        assert!(r.warnings.is_empty(), "chains longer than 50 τ: {:?}", r.warnings);
        for i in 0..d {
            let p = &r.parameters[i];
            let sd = cov[(i, i)].sqrt();
            assert!((p.mean_unit - m[i]).abs() < tol_mean_sd * sd, "mean {i}: {} vs {}", p.mean_unit, m[i]);
            assert!((p.sd_unit / sd - 1.0).abs() < tol_sd, "sd {i}: {} vs {sd}", p.sd_unit);
            assert!((p.quantiles_unit.q50 - m[i]).abs() < 2.0 * tol_mean_sd * sd);
            let width = p.quantiles_unit.q975 - p.quantiles_unit.q025;
            assert!((width / (2.0 * 1.96 * sd) - 1.0).abs() < 2.0 * tol_sd, "95 % width {i}");
            for j in 0..d {
                let rho = cov[(i, j)] / (sd * cov[(j, j)].sqrt());
                assert!((r.correlation[i][j] - rho).abs() < tol_corr, "corr {i}{j}: {} vs {rho}", r.correlation[i][j]);
            }
        }
        assert!(r.evaluations <= budget && e.told() == r.evaluations);
        let a = r.acceptance_fraction.unwrap();
        assert!(a > 0.2 && a < 0.9, "acceptance {a}");
    }

    #[test]
    fn recovers_a_correlated_2d_gaussian() {
        let cov = covariance(&[0.02, 0.03], &[&[1.0, 0.8], &[0.8, 1.0]]);
        recovers(&[0.4, 0.55], &cov, 80_000, 0.10, 0.05, 0.03);
    }

    #[test]
    fn recovers_a_correlated_5d_gaussian() {
        let corr: [&[f64]; 5] = [
            &[1.0, 0.5, 0.0, -0.3, 0.2],
            &[0.5, 1.0, 0.3, 0.0, 0.0],
            &[0.0, 0.3, 1.0, 0.4, -0.2],
            &[-0.3, 0.0, 0.4, 1.0, 0.1],
            &[0.2, 0.0, -0.2, 0.1, 1.0],
        ];
        let cov = covariance(&[0.02, 0.01, 0.03, 0.015, 0.025], &corr);
        recovers(&[0.3, 0.5, 0.6, 0.45, 0.55], &cov, 250_000, 0.12, 0.05, 0.08);
    }

    /// At temperature `T` the sampler draws from `exp(−S/(2T))`: for a quadratic `S` with
    /// covariance `Σ` that is the Gaussian of covariance `T Σ`.
    #[test]
    fn a_temperature_widens_the_posterior_by_its_square_root() {
        let cov = covariance(&[0.01, 0.015], &[&[1.0, -0.6], &[-0.6, 1.0]]);
        let m = [0.45, 0.5];
        let s = quadratic(&cov.clone().try_inverse().unwrap(), &m, 0.0);
        let t = 9.0;
        let options = McmcOptions { temperature: t, ..McmcOptions::default() };
        let mut e = EnsembleSampler::new(&unit_space(2), Some(&[0.46, 0.51]), options, 60_000, 5).unwrap();
        minimize(&mut e, 64, |u| ok(s(u)));
        let r = e.summary();
        assert_eq!(r.temperature, t);
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        for i in 0..2 {
            let sd = (t * cov[(i, i)]).sqrt();
            let p = &r.parameters[i];
            assert!((p.sd_unit / sd - 1.0).abs() < 0.08, "sd {i}: {} vs {sd}", p.sd_unit);
            assert!((p.mean_unit - m[i]).abs() < 0.15 * sd, "mean {i}: {} vs {}", p.mean_unit, m[i]);
        }
        assert!((r.correlation[0][1] + 0.6).abs() < 0.05, "{}", r.correlation[0][1]);
        let e = EnsembleSampler::new(
            &unit_space(2),
            None,
            McmcOptions { temperature: 0.5, ..McmcOptions::default() },
            1000,
            0,
        )
        .unwrap_err();
        assert!(matches!(e, InferenceError::InvalidOption { option: "temperature", .. }), "{e}");
    }

    #[test]
    fn failed_evaluations_have_zero_likelihood() {
        let space = unit_space(2);
        let s = quadratic(&(DMatrix::identity(2, 2) / 0.03f64.powi(2)), &[0.5, 0.5], 0.0);
        let mut e = EnsembleSampler::new(&space, None, McmcOptions::default(), 20_000, 2).unwrap();
        // Everything right of u₀ = 0.5 diverges: a half-Gaussian remains.
        minimize(&mut e, 16, |u| if u[0] > 0.5 { Outcome::Failed { reason: "nan".into() } } else { ok(s(u)) });
        let r = e.summary();
        assert!(r.failed_proposals > 0);
        let burn = r.burn_in;
        assert!(
            e.chain_costs().iter().all(|c| c[burn..].iter().all(|v| v.is_finite())),
            "no walker stuck on a failure"
        );
        let post_burn: Vec<f64> = e.samples(4000, 1).unit.iter().map(|u| u[0]).collect();
        assert!(post_burn.iter().all(|&v| v <= 0.5));
        // Half-normal mean: m − σ √(2/π).
        let mean = post_burn.iter().sum::<f64>() / post_burn.len() as f64;
        assert!((mean - (0.5 - 0.03 * (2.0 / std::f64::consts::PI).sqrt())).abs() < 0.004, "{mean}");
    }

    #[test]
    fn draws_are_seeded_and_physical() {
        let space = Space::new(vec![param("a", 1.0, 100.0, Scale::Log), param("b", -2.0, 2.0, Scale::Linear)]).unwrap();
        let s = quadratic(&(DMatrix::identity(2, 2) / 0.05f64.powi(2)), &[0.5, 0.5], 0.0);
        let mut e = EnsembleSampler::new(&space, None, McmcOptions::default(), 4_000, 3).unwrap();
        minimize(&mut e, 10, |u| ok(s(u)));
        let d1 = e.samples(50, 9);
        assert_eq!(d1, e.samples(50, 9));
        assert_ne!(d1, e.samples(50, 10));
        assert_eq!(d1.unit.len(), 50);
        for (u, x) in d1.unit.iter().zip(&d1.physical) {
            assert_eq!(*x, space.to_physical(u));
        }
        let r = e.summary();
        // Median of a log parameter: 10^(2 · 0.5) = 10 (the unit median, mapped).
        assert!((r.parameters[0].quantiles.q50.log10() - 2.0 * r.parameters[0].quantiles_unit.q50).abs() < 1e-9);
        assert_eq!(e.chains().len(), 16);
        assert_eq!(e.chains()[0].len(), r.iterations);
    }

    #[test]
    fn is_deterministic_under_batching_and_reordering() {
        let space = unit_space(3);
        let cov = covariance(&[0.02, 0.03, 0.01], &[&[1.0, 0.5, 0.0], &[0.5, 1.0, 0.2], &[0.0, 0.2, 1.0]]);
        let s = quadratic(&cov.try_inverse().unwrap(), &[0.3, 0.4, 0.5], 0.0);
        let f = |u: &[f64]| if u[1] > 0.45 { Outcome::Failed { reason: "x".into() } } else { ok(s(u)) };
        let mut runs = Vec::new();
        for (batch, seed) in [(1, 0), (3, 1), (7, 5), (1000, 2)] {
            let mut e = EnsembleSampler::new(&space, None, McmcOptions::default(), 3_000, 4).unwrap();
            run_shuffled(&mut e, batch, seed, f);
            runs.push((e.chains(), format!("{:?}", e.summary())));
        }
        assert!(runs.iter().all(|r| *r == runs[0]));
    }
}

mod compare {
    use super::*;

    #[test]
    fn laplace_evidence_equals_the_gaussian_integral() {
        // S = S₀ + (u − m)ᵀ A (u − m): Z = ∫ exp(−S/2) du = exp(−S₀/2) 2π / √det A (mass inside the box).
        let a = covariance(&[0.05, 0.04], &[&[1.0, 0.3], &[0.3, 1.0]]).try_inverse().unwrap();
        let (m, s0) = ([0.5, 0.45], 7.0);
        let h: Vec<Vec<f64>> = (0..2).map(|i| (0..2).map(|j| 2.0 * a[(i, j)]).collect()).collect();
        let analytic = -s0 / 2.0 + (2.0 * std::f64::consts::PI).ln() - 0.5 * a.determinant().ln();
        let lz = laplace_log_evidence(s0, &h, 0.0).unwrap();
        assert!((lz - analytic).abs() < 1e-12, "{lz} vs {analytic}");
        // Independent check: midpoint-rule integral over the unit box.
        let s = quadratic(&a, &m, s0);
        let n = 800;
        let mut z = 0.0;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                z += (-s(&u) / 2.0).exp();
            }
        }
        let numeric = (z / (n * n) as f64).ln();
        assert!((numeric - analytic).abs() < 1e-6, "{numeric} vs {analytic}");
        // End to end: the variance stage's Hessian gives the same evidence.
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear), param("b", 0.0, 1.0, Scale::Linear)]).unwrap();
        let mut v = Variance::new(&space, Some(&[0.52, 0.43]), VarianceOptions::default(), 300, 0).unwrap();
        minimize(&mut v, 8, |u| ok(s(u)));
        let g = v.summary().gaussian.unwrap();
        let fit = ModelFit::from_gaussian("quadratic", 100, &g);
        let lz = laplace_log_evidence(fit.s_min, &fit.hessian_unit, 0.0).unwrap();
        assert!((lz - analytic).abs() < 1e-5, "{lz} vs {analytic}");
    }

    #[test]
    fn comparison_table() {
        let n = 200;
        let simple = ModelFit::new("simple", 210.0, n, vec![vec![800.0, 0.0], vec![0.0, 500.0]]);
        let rich = ModelFit::new(
            "rich",
            207.0,
            n,
            vec![vec![800.0, 0.0, 0.0], vec![0.0, 500.0, 0.0], vec![0.0, 0.0, 20000.0]],
        );
        let c = ModelComparison::new(&[simple.clone(), rich.clone()]).unwrap();
        let (a, b) = (&c.rows[0], &c.rows[1]);
        assert_eq!((a.aic, b.aic), (214.0, 213.0));
        assert!((a.bic - (210.0 + 2.0 * 200f64.ln())).abs() < 1e-12);
        assert!((b.delta_aic, a.delta_aic) == (0.0, 1.0));
        // The third parameter buys ΔS = 3 but costs an Ockham factor √(2π/10000).
        let ln_b = c.log_bayes_factor("rich", "simple").unwrap();
        let expected = 1.5 + 0.5 * (2.0 * std::f64::consts::PI).ln() - 0.5 * 10000f64.ln();
        assert!((ln_b - expected).abs() < 1e-12, "{ln_b} vs {expected}");
        assert_eq!(c.best, 0, "the evidence prefers the simpler model");
        assert!((a.probability + b.probability - 1.0).abs() < 1e-12);
        assert!((b.bayes_factor - expected.exp()).abs() < 1e-12);
        let bad = ModelFit::new("bad", 1.0, n, vec![vec![1.0, 2.0], vec![2.0, 1.0]]);
        assert!(matches!(ModelComparison::new(&[simple.clone(), bad]), Err(ComparisonError::InModel { .. })));
        let other = ModelFit::new("other", 1.0, n + 1, vec![vec![1.0]]);
        assert!(matches!(ModelComparison::new(&[simple.clone(), other]), Err(ComparisonError::DifferentData { .. })));
        assert!(matches!(ModelComparison::new(&[simple]), Err(ComparisonError::TooFewModels { count: 1 })));
    }
}

mod contract {
    use super::*;

    #[test]
    fn bad_results_are_rejected_atomically() {
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear)]).unwrap();
        let mut e = EnsembleSampler::new(&space, None, McmcOptions::default(), 100, 0).unwrap();
        let c = e.ask(3);
        assert_eq!(c.len(), 3);
        let good = Evaluation { id: c[0].id, outcome: ok(1.0) };
        assert_eq!(
            e.tell(&[good.clone(), Evaluation { id: 99, outcome: ok(1.0) }]),
            Err(TellError::Unknown { id: 99 })
        );
        assert_eq!(
            e.tell(&[Evaluation { id: c[1].id, outcome: ok(-1.0) }]),
            Err(TellError::BadCost { id: 1, cost: -1.0 })
        );
        let nan = Evaluation { id: c[1].id, outcome: ok(f64::NAN) };
        assert!(matches!(e.tell(&[nan]), Err(TellError::BadCost { .. })));
        assert_eq!(e.told(), 0, "nothing stored from a rejected batch");
        e.tell(std::slice::from_ref(&good)).unwrap();
        assert_eq!(e.tell(std::slice::from_ref(&good)), Err(TellError::Duplicate { id: 0 }));
        let twice = Evaluation { id: c[1].id, outcome: ok(1.0) };
        assert_eq!(e.tell(&[twice.clone(), twice]), Err(TellError::Duplicate { id: 1 }));
        // Not yet handed out.
        assert_eq!(e.tell(&[Evaluation { id: 5, outcome: ok(1.0) }]), Err(TellError::Unknown { id: 5 }));
    }

    #[test]
    fn bad_options_name_the_option() {
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear), param("b", 0.0, 1.0, Scale::Linear)]).unwrap();
        let e = EnsembleSampler::new(&space, None, McmcOptions { walkers: Some(7), ..McmcOptions::default() }, 1000, 0)
            .unwrap_err();
        assert!(e.to_string().contains("`walkers` = 7"), "{e}");
        let e = NelderMead::new(2, Some(&[0.5, 1.5]), NelderMeadOptions::default(), 100, 0).unwrap_err();
        assert!(matches!(e, InferenceError::StartOutside { index: 1, .. }), "{e}");
        let e =
            Variance::new(&space, None, VarianceOptions { hessian_step: 0.0, ..VarianceOptions::default() }, 1000, 0)
                .unwrap_err();
        assert!(matches!(e, InferenceError::InvalidOption { option: "hessian_step", .. }), "{e}");
        let e = Sensitivity::new(&space, Some(&[0.5]), SensitivityOptions::default(), 100, 0).unwrap_err();
        assert!(matches!(e, InferenceError::StartDimension { expected: 2, got: 1, .. }), "{e}");
    }

    #[test]
    fn one_parameter_and_all_failures_finish_without_panicking() {
        let space = Space::new(vec![param("a", 0.5, 2.0, Scale::Log)]).unwrap();
        let algorithms = || {
            vec![
                InferenceAlgorithm::Sensitivity(Sensitivity::new(&space, None, Default::default(), 10, 0).unwrap()),
                InferenceAlgorithm::Morris(Morris::new(1, None, Default::default(), 100, 0).unwrap()),
                InferenceAlgorithm::NelderMead(NelderMead::new(1, None, Default::default(), 100, 0).unwrap()),
                InferenceAlgorithm::Variance(Box::new(
                    Variance::new(&space, None, Default::default(), 100, 0).unwrap(),
                )),
                InferenceAlgorithm::Mcmc(Box::new(
                    EnsembleSampler::new(&space, None, Default::default(), 100, 0).unwrap(),
                )),
            ]
        };
        for mut alg in algorithms() {
            minimize(&mut alg, 2, |u| ok((u[0] - 0.3).powi(2)));
            let _ = alg.summary();
            assert!(alg.told() <= 100);
        }
        for mut alg in algorithms() {
            minimize(&mut alg, 2, |_| Outcome::Failed { reason: "diverged".into() });
            let _ = alg.summary();
            assert!(alg.best().is_none());
            assert!(
                matches!(alg.finished(), Some(cryofit_calib::StopReason::Exhausted { .. })),
                "{:?}",
                alg.finished()
            );
        }
    }

    #[test]
    fn the_enum_delegates() {
        let space = Space::new(vec![param("a", 0.0, 1.0, Scale::Linear), param("b", 0.0, 1.0, Scale::Linear)]).unwrap();
        let nm = NelderMead::new(2, None, NelderMeadOptions::default(), 500, 0).unwrap();
        let mut alg = InferenceAlgorithm::NelderMead(nm);
        minimize(&mut alg, 1, |u| ok(testfns::sphere(u)));
        assert!(alg.best().unwrap().cost < 1e-8);
        assert!(matches!(alg.summary(), InferenceSummary::NelderMead(_)));
        let v = Variance::new(&space, None, VarianceOptions::default(), 200, 0).unwrap();
        let mut alg = InferenceAlgorithm::Variance(Box::new(v));
        minimize(&mut alg, 5, |u| ok(testfns::sphere(u)));
        assert!(alg.finished().is_some() && alg.told() <= 200);
    }
}

#[cfg(feature = "serde")]
mod persistence {
    use super::*;

    /// Runs `steps` ask/tell rounds (leaving the last asks half told), serialises to JSON, restores,
    /// and finishes both the original and the restored copy: the summaries must agree bit for bit.
    fn pause_resume(mut alg: InferenceAlgorithm, steps: usize, f: impl Fn(&[f64]) -> Outcome) {
        pause_resume_when(&mut alg, |_, step| step == steps, f);
    }

    /// As `pause_resume`, pausing at the first round where `pause(algorithm, round)` holds.
    fn pause_resume_when(
        alg: &mut InferenceAlgorithm,
        pause: impl Fn(&InferenceAlgorithm, usize) -> bool,
        f: impl Fn(&[f64]) -> Outcome,
    ) {
        let eval = |c: &Candidate| Evaluation { id: c.id, outcome: f(&c.unit) };
        let mut outstanding: Vec<Candidate> = Vec::new();
        for step in 0.. {
            if alg.finished().is_some() || pause(alg, step) {
                break;
            }
            let asked = alg.ask(5);
            if asked.is_empty() {
                let results: Vec<Evaluation> = outstanding.drain(..).map(|c| eval(&c)).collect();
                alg.tell(&results).unwrap();
                continue;
            }
            let (now, later) = asked.split_at(asked.len() / 2);
            outstanding.extend_from_slice(later);
            alg.tell(&now.iter().map(eval).collect::<Vec<_>>()).unwrap();
        }
        assert!(alg.finished().is_none(), "the pause must come before the end");
        if let InferenceSummary::Variance(v) = alg.summary() {
            println!("variance paused in stage {:?}", v.stage);
        }
        let json = serde_json::to_string(&*alg).unwrap();
        let mut restored: InferenceAlgorithm = serde_json::from_str(&json).unwrap();
        assert_eq!(serde_json::to_string(&restored).unwrap(), json, "serialisation is stable");
        let rest: Vec<Evaluation> = outstanding.iter().map(eval).collect();
        alg.tell(&rest).unwrap();
        restored.tell(&rest).unwrap();
        minimize(alg, 3, &f);
        minimize(&mut restored, 3, &f);
        assert_eq!(format!("{:?}", alg.summary()), format!("{:?}", restored.summary()));
        assert_eq!(alg.best(), restored.best());
        if let (InferenceAlgorithm::Mcmc(a), InferenceAlgorithm::Mcmc(b)) = (&*alg, &restored) {
            assert_eq!(a.chains(), b.chains());
        }
        let summary = serde_json::to_string(&alg.summary()).unwrap();
        assert!(summary.len() > 10);
    }

    fn space() -> Space {
        Space::new(vec![
            param("a", 0.0, 3.0, Scale::Linear),
            param("b", 1e-3, 10.0, Scale::Log),
            param("c", -1.0, 1.0, Scale::Linear),
        ])
        .unwrap()
    }

    fn cost(u: &[f64]) -> Outcome {
        if u[2] > 0.9 { Outcome::Failed { reason: "diverged".into() } } else { ok(testfns::rosenbrock(u) + 0.1) }
    }

    #[test]
    fn every_algorithm_resumes_bit_identically() {
        let s = space();
        let start = [0.35, 0.25, 0.3];
        pause_resume(
            InferenceAlgorithm::Sensitivity(Sensitivity::new(&s, Some(&start), Default::default(), 7, 1).unwrap()),
            1,
            cost,
        );
        pause_resume(InferenceAlgorithm::Morris(Morris::new(3, None, Default::default(), 40, 1).unwrap()), 3, cost);
        pause_resume(
            InferenceAlgorithm::NelderMead(NelderMead::new(3, None, Default::default(), 300, 1).unwrap()),
            40,
            cost,
        );
        for stage in [VarianceStage::Restart { index: 1 }, VarianceStage::Hessian, VarianceStage::Profile] {
            let v = Variance::new(&s, Some(&start), Default::default(), 400, 1).unwrap();
            let mut alg = InferenceAlgorithm::Variance(Box::new(v));
            let in_stage = |a: &InferenceAlgorithm, _: usize| match a.summary() {
                InferenceSummary::Variance(v) => v.stage == Some(stage) && a.told() % 3 == 1,
                _ => false,
            };
            pause_resume_when(&mut alg, in_stage, cost);
        }
        let e = EnsembleSampler::new(&s, Some(&start), Default::default(), 3000, 1).unwrap();
        pause_resume(InferenceAlgorithm::Mcmc(Box::new(e)), 100, cost);
    }
}
