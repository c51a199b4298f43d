//! The variance stage (paper, section "Variance of the model parameters").
//!
//! The paper repeats the optimisation "using local search with multiple restarts in the vicinity
//! of the quasi-optimal parameter value", fits the Gaussian of its dispersion equation,
//! `F = A exp(−½ (c − c₀) ∂²S/∂c² (c − c₀))`, to cost evaluations near the optimum, and notes that
//! the same evaluations reveal "the range of parameter values where simulations diverge". This
//! stage does that in four steps, each a run of generations:
//!
//! 1. **Restarts**: a few Nelder–Mead runs with a small simplex, the first from `start`, the others
//!    from the best point so far moved by a small random offset.
//! 2. **Hessian** of `S` at the best point by central finite differences in unit coordinates
//!    (one-sided, shifted inward, for a coordinate within a step of a bound), all points in one
//!    generation. With `S/2` the negative log-likelihood, the Laplace (Gaussian) approximation of
//!    the posterior has covariance `Σ_u = (H_{S/2})⁻¹ = 2 H_S⁻¹` in unit coordinates; the delta
//!    method with the [`Space`] jacobian turns it into physical standard deviations.
//! 3. **Profiles**: each parameter alone moved to a few points on both sides of the optimum (out to a
//!    few conditional standard deviations), the paper's "direct calculations of the cost function
//!    for various values of the model parameter close to its optimal value", reported beside the
//!    Gaussian prediction so that departures from the Gaussian show.
//! 4. **Divergence report**: every failed evaluation within a radius of the optimum.
//! 5. **Response surface**: a quadratic fitted by least squares to every evaluation of the stage
//!    near the optimum; its minimum, evaluated once more, is the stage's estimate when it is
//!    consistent (see [`ResponseSurface`]).

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use std::collections::BTreeMap;

use nalgebra::{DMatrix, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::InferenceError;
use super::common::{Completed, Core, Told, check, clamp_unit, distance, resolve_start};
use super::nelder_mead::{NelderMeadOptions, Simplex, Step};
use super::surface::{ResponseSurface, SurfaceEstimate, SurfaceRecord, fit_surface, judge_surface};
use crate::api::{CandidateId, StopReason};
use crate::space::Space;

/// Options of [`Variance`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default))]
pub struct VarianceOptions {
    /// Number of Nelder–Mead restarts (0 skips the refinement: the Hessian is taken at `start`).
    /// Default 3.
    pub restarts: usize,
    /// Edge of each restart's initial simplex, unit coordinates. Default 0.02.
    pub simplex_size: f64,
    /// Standard deviation of the random offset of restarts after the first, unit coordinates.
    /// Default 0.02.
    pub restart_spread: f64,
    /// Restart stop: simplex size (max-norm, unit coordinates). Default 1e-5.
    pub x_tol: f64,
    /// Restart stop: cost spread over the simplex (absolute). Default 1e-6.
    pub f_tol: f64,
    /// Gao–Han adaptive simplex coefficients when d > 2. Default true.
    pub adaptive: bool,
    /// Finite-difference step of the Hessian, unit coordinates, in (0, 0.25]. Default 5e-3.
    pub hessian_step: f64,
    /// Hessian eigenvalues below this fraction of the largest are raised to it before inverting
    /// (a warning names them): a flat or concave direction then gets a very large variance rather
    /// than a negative or infinite one. Default 1e-10.
    pub eigen_floor: f64,
    /// Profile points on each side of the optimum per parameter (0 disables profiles). Default 3.
    pub profile_points: usize,
    /// Profiles reach this many conditional standard deviations (`√(2/H_ii)`), capped at
    /// `neighbourhood`. Default 3.
    pub profile_sigmas: f64,
    /// Radius (Euclidean, unit coordinates) within which failed evaluations are reported as nearby
    /// divergent regions, and the cap on profile extent. Default 0.1.
    pub neighbourhood: f64,
}

impl Default for VarianceOptions {
    fn default() -> Self {
        Self {
            restarts: 3,
            simplex_size: 0.02,
            restart_spread: 0.02,
            x_tol: 1e-5,
            f_tol: 1e-6,
            adaptive: true,
            hessian_step: 5e-3,
            eigen_floor: 1e-10,
            profile_points: 3,
            profile_sigmas: 3.0,
            neighbourhood: 0.1,
        }
    }
}

/// Which step of the stage an evaluation belonged to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum VarianceStage {
    /// Nelder–Mead restart number `index` (from 0).
    Restart {
        /// Restart number.
        index: usize,
    },
    /// The finite-difference Hessian.
    Hessian,
    /// The one-parameter profiles.
    Profile,
    /// The evaluation at the response surface's minimum.
    Surface,
}

/// One Nelder–Mead restart.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct RestartSummary {
    /// Where it started (unit coordinates).
    pub start_unit: Vec<f64>,
    /// Its best point (unit coordinates).
    pub best_unit: Vec<f64>,
    /// Its best cost (`None` when every evaluation failed).
    pub best_cost: Option<f64>,
    /// Evaluations it used.
    pub evaluations: usize,
    /// Simplex iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub stop: StopReason,
}

/// A 95 % interval of one parameter.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Interval {
    /// Lower end, physical units.
    pub lower: f64,
    /// Upper end, physical units.
    pub upper: f64,
    /// True when `±1.96 σ` in unit coordinates reached a bound and was clamped to it.
    pub clamped: bool,
}

/// The Gaussian (Laplace) approximation of the posterior at the optimum.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct GaussianApproximation {
    /// The optimum (Hessian centre), unit coordinates.
    pub centre_unit: Vec<f64>,
    /// The optimum, physical values.
    pub centre_physical: Vec<f64>,
    /// `S` at the optimum.
    pub cost: f64,
    /// `∂²S/∂u_i∂u_j` in unit coordinates (symmetric; an off-diagonal entry whose stencil failed
    /// is 0, with a warning).
    pub hessian_unit: Vec<Vec<f64>>,
    /// Eigenvalues of `hessian_unit`, ascending, before regularisation.
    pub eigenvalues: Vec<f64>,
    /// True when every eigenvalue is above the floor (`eigen_floor` × the largest).
    pub positive_definite: bool,
    /// Number of eigenvalues raised to the floor.
    pub regularised: usize,
    /// `ln det H_{S/2}` (after regularisation), for the Laplace evidence.
    pub log_det_half_hessian: f64,
    /// `Σ_u = 2 H_S⁻¹`, unit coordinates.
    pub covariance_unit: Vec<Vec<f64>>,
    /// `J Σ_u J` with `J = diag(dx/du)` at the optimum (delta method), physical units.
    pub covariance_physical: Vec<Vec<f64>>,
    /// Standard deviations, unit coordinates.
    pub sd_unit: Vec<f64>,
    /// Standard deviations, physical units (delta method; for a log-scaled parameter the interval
    /// below, mapped through the scale, is the better description).
    pub sd_physical: Vec<f64>,
    /// Correlation matrix (the same in unit and physical coordinates).
    pub correlation: Vec<Vec<f64>>,
    /// `±1.96 σ` in unit coordinates, clamped to the box and mapped to physical values.
    pub interval95: Vec<Interval>,
    /// Numerical noise of the cost near the optimum, in cost units: the pooled residual RMS of
    /// cubic fits to the one-parameter profiles (`None` when the profiles leave no degree of
    /// freedom).
    pub cost_noise: Option<f64>,
    /// Factor applied to the covariance for that noise, `1 + 2 σ_ε` (1 without a noise estimate).
    ///
    /// Decision: a simulation cost is not a smooth function of the parameters. Adaptive time
    /// stepping and the two-phase flow's sensitivity to small perturbations make `S` jitter by
    /// σ_ε between nearby points, so the minimum of the computed `S` wanders over the region where
    /// the smooth part rises by about 2σ_ε: `½ δᵀ H δ ≈ 2σ_ε`, i.e. a spread of `2σ_ε · 2 H⁻¹ =
    /// 2σ_ε Σ`. The reported covariance, standard deviations and intervals are the statistical
    /// ones times `1 + 2σ_ε` (in variance); `log_det_half_hessian` stays that of the Hessian.
    pub noise_inflation: f64,
}

/// One point of a one-parameter profile.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ProfilePoint {
    /// Offset from the optimum, unit coordinates.
    pub offset_unit: f64,
    /// The parameter's physical value.
    pub value: f64,
    /// The cost (`None` when the evaluation failed).
    pub cost: Option<f64>,
    /// The failure reason.
    pub failure: Option<String>,
    /// `S_min + ½ H_ii δ²`: what the Gaussian approximation predicts along this line.
    pub gaussian_cost: Option<f64>,
}

/// A one-parameter profile through the optimum.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Profile {
    /// Parameter index.
    pub index: usize,
    /// Parameter name.
    pub name: String,
    /// Points by increasing offset.
    pub points: Vec<ProfilePoint>,
    /// Smallest |offset| (unit coordinates, signed) at which the simulation failed.
    pub nearest_failure: Option<f64>,
}

/// A failed evaluation near the optimum.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct DivergentPoint {
    /// Candidate id.
    pub id: CandidateId,
    /// Where, unit coordinates.
    pub unit: Vec<f64>,
    /// Where, physical values.
    pub physical: Vec<f64>,
    /// Euclidean distance from the optimum, unit coordinates.
    pub distance: f64,
    /// The failure reason.
    pub reason: String,
    /// Which step evaluated it.
    pub stage: VarianceStage,
}

/// Result of a [`Variance`] run.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct VarianceSummary {
    /// The step running now (`None` once finished).
    pub stage: Option<VarianceStage>,
    /// The restarts so far.
    pub restarts: Vec<RestartSummary>,
    /// Standard deviation of the restarts' optima per coordinate (unit), when at least two
    /// restarts found a point: a crude, model-free spread to compare with the Gaussian one.
    pub restart_spread_unit: Option<Vec<f64>>,
    /// The optimum (Hessian centre) in unit coordinates.
    pub optimum_unit: Option<Vec<f64>>,
    /// The optimum in physical values.
    pub optimum_physical: Option<Vec<f64>>,
    /// `S` at the optimum.
    pub optimum_cost: Option<f64>,
    /// Evaluations of the Hessian stencil (after removing coinciding points).
    pub hessian_evaluations: usize,
    /// The Gaussian approximation (`None` until the Hessian is in, or when a diagonal entry could
    /// not be computed).
    pub gaussian: Option<GaussianApproximation>,
    /// One-parameter profiles.
    pub profiles: Vec<Profile>,
    /// Failed evaluations within `neighbourhood` of the optimum, nearest first.
    pub divergent: Vec<DivergentPoint>,
    /// The response surface and its minimum (`None` until the profiles are in).
    pub surface: Option<ResponseSurface>,
    /// Things the caller should know (failed stencil points, regularised eigenvalues, …).
    pub warnings: Vec<String>,
    /// Evaluations handed out.
    pub evaluations: usize,
    /// The budget.
    pub budget: usize,
    /// Why it stopped, once finished.
    pub stop: Option<StopReason>,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct RestartRecord {
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    start: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    best: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    best_cost: f64,
    evaluations: usize,
    iterations: usize,
    stop: StopReason,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct FailureRecord {
    id: CandidateId,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    unit: Vec<f64>,
    reason: String,
    stage: VarianceStage,
}

/// The Hessian stencil: per coordinate three offsets `o₀ < o₁ < o₂` spaced by the step (central
/// `−h, 0, h`; at the upper bound `−2h, −h, 0`; at the lower `0, h, 2h`) and indices of the points.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Stencil {
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    centre: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    fallback_cost: Option<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    offsets: Vec<Vec<f64>>,
    diagonal: Vec<[usize; 3]>,
    /// For pairs `i < j` in row order: points at `(o₀,o₀), (o₀,o₂), (o₂,o₀), (o₂,o₂)`.
    mixed: Vec<[usize; 4]>,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct HessianRecord {
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    centre: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    cost: f64,
    /// Row-major d × d; `None` when the diagonal could not be computed.
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    matrix: Option<Vec<f64>>,
    evaluations: usize,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct ProfileRecord {
    index: usize,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    unit: f64,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    offset: f64,
    result: Option<Told>,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
enum Stage {
    Restart {
        index: usize,
        #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
        start: Vec<f64>,
        simplex: Simplex,
        first: usize,
        budget: usize,
    },
    Hessian(Stencil),
    Profile,
    Surface,
    Done,
}

/// The variance stage: simplex restarts near the optimum, finite-difference Hessian and Gaussian
/// approximation, one-parameter profiles and a report of nearby divergent regions (paper, section
/// "Variance of the model parameters"; Laplace approximation as in MacKay 2003, ch. 27).
///
/// Budget: the Hessian needs at most `1 + 2d²` evaluations and the profiles `2 · profile_points · d`;
/// those are reserved and the restarts share the rest. The stage finishes when the profiles are in,
/// whatever budget is left.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Variance {
    #[cfg_attr(feature = "serde", serde(with = "crate::exact::space"))]
    space: Space,
    options: VarianceOptions,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    start: Vec<f64>,
    rng: ChaCha8Rng,
    restart_budget: usize,
    restart_used: usize,
    stage: Stage,
    restarts: Vec<RestartRecord>,
    failures: Vec<FailureRecord>,
    hessian: Option<HessianRecord>,
    profile: Vec<ProfileRecord>,
    /// Every successful evaluation of the stage, unit points and costs (the response surface's data).
    #[cfg_attr(feature = "serde", serde(default, with = "crate::inference::exact"))]
    sampled: Vec<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(default, with = "crate::inference::exact"))]
    sampled_cost: Vec<f64>,
    #[cfg_attr(feature = "serde", serde(default))]
    surface: Option<SurfaceRecord>,
    warnings: Vec<String>,
    core: Core,
}

impl Variance {
    const NAME: &'static str = "variance";

    /// Evaluations the Hessian may need in dimension `d`: the centre, two per diagonal and four
    /// per pair, `1 + 2d + 2d(d − 1) = 1 + 2d²` (fewer when points coincide at a bound).
    pub fn hessian_evaluations(d: usize) -> usize {
        1 + 2 * d * d
    }

    /// Checks the options, reserves the Hessian and profile budget (and one evaluation for the
    /// response surface's minimum when the budget has room) and starts the first restart.
    /// Errors: bad options or start; a budget below `1 + 2d² + 2 · profile_points · d + restarts (d + 1)`.
    pub fn new(
        space: &Space,
        start: Option<&[f64]>,
        options: VarianceOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, InferenceError> {
        let n = Self::NAME;
        let o = &options;
        let d = space.dim();
        let start = resolve_start(n, d, start)?;
        let pos_finite = |v: f64| v > 0.0 && v.is_finite();
        check(n, "simplex_size", o.simplex_size, o.simplex_size > 0.0 && o.simplex_size <= 0.5, "in (0, 0.5]")?;
        check(n, "restart_spread", o.restart_spread, o.restart_spread >= 0.0 && o.restart_spread <= 1.0, "in [0, 1]")?;
        check(n, "x_tol", o.x_tol, o.x_tol >= 0.0 && o.x_tol.is_finite(), "finite and ≥ 0")?;
        check(n, "f_tol", o.f_tol, o.f_tol >= 0.0 && o.f_tol.is_finite(), "finite and ≥ 0")?;
        check(n, "hessian_step", o.hessian_step, o.hessian_step > 0.0 && o.hessian_step <= 0.25, "in (0, 0.25]")?;
        check(n, "eigen_floor", o.eigen_floor, pos_finite(o.eigen_floor) && o.eigen_floor < 1.0, "in (0, 1)")?;
        check(n, "profile_sigmas", o.profile_sigmas, pos_finite(o.profile_sigmas), "finite and > 0")?;
        check(n, "neighbourhood", o.neighbourhood, pos_finite(o.neighbourhood), "finite and > 0")?;
        let reserve = Self::hessian_evaluations(d) + 2 * o.profile_points * d;
        let required = reserve + o.restarts * (d + 1);
        if budget < required {
            return Err(InferenceError::BudgetTooSmall {
                algorithm: n,
                budget,
                required,
                needed_for: "1 + 2d² Hessian points, 2·profile_points·d profile points and d + 1 per restart",
            });
        }
        let mut v = Self {
            space: space.clone(),
            options,
            start,
            rng: ChaCha8Rng::seed_from_u64(seed),
            // one evaluation for the response surface's minimum, when there is room for it
            restart_budget: budget - reserve - usize::from(budget > required),
            restart_used: 0,
            stage: Stage::Done,
            restarts: Vec::new(),
            failures: Vec::new(),
            hessian: None,
            profile: Vec::new(),
            sampled: Vec::new(),
            sampled_cost: Vec::new(),
            surface: None,
            warnings: Vec::new(),
            core: Core::new(budget),
        };
        v.begin_restart(0);
        Ok(v)
    }

    fn nm_options(&self) -> NelderMeadOptions {
        NelderMeadOptions {
            initial_step: self.options.simplex_size,
            adaptive: self.options.adaptive,
            x_tol: self.options.x_tol,
            f_tol: self.options.f_tol,
        }
    }

    fn begin_restart(&mut self, index: usize) {
        let total = self.options.restarts;
        if index >= total {
            return self.begin_hessian();
        }
        let d = self.space.dim();
        let budget = (self.restart_budget - self.restart_used) / (total - index);
        if budget < d + 1 {
            self.warnings.push(format!("restart {index} skipped: only {budget} evaluations left for it"));
            return self.begin_restart(index + 1);
        }
        let start = match (index, self.core.best_point()) {
            (0, _) | (_, None) => self.start.clone(),
            (_, Some((best, _))) => {
                let best = best.to_vec();
                let spread = self.options.restart_spread;
                clamp_unit(best.iter().map(|&b| b + spread * self.rng.sample::<f64, _>(StandardNormal)).collect())
            }
        };
        let simplex = Simplex::new(&start, &self.nm_options());
        let first = self.core.used();
        self.core.start(simplex.initial_points());
        self.stage = Stage::Restart { index, start, simplex, first, budget };
    }

    fn begin_hessian(&mut self) {
        let (centre, fallback_cost) = match self.core.best_point() {
            Some((b, c)) => (b.to_vec(), Some(c)),
            None if self.options.restarts == 0 => (self.start.clone(), None),
            None => {
                self.stage = Stage::Done;
                return self.core.finish(StopReason::Exhausted {
                    message: "every evaluation of the restarts failed; there is no optimum to expand around".into(),
                });
            }
        };
        let d = centre.len();
        let h = self.options.hessian_step;
        let offsets: Vec<Vec<f64>> = centre
            .iter()
            .map(|&c| {
                if c + h > 1.0 {
                    vec![-2.0 * h, -h, 0.0]
                } else if c - h < 0.0 {
                    vec![0.0, h, 2.0 * h]
                } else {
                    vec![-h, 0.0, h]
                }
            })
            .collect();
        let mut points: Vec<Vec<f64>> = Vec::new();
        let mut index: BTreeMap<Vec<u64>, usize> = BTreeMap::new();
        let mut add = |moves: &[(usize, f64)]| -> usize {
            let mut x = centre.clone();
            for &(i, o) in moves {
                x[i] = (x[i] + o).clamp(0.0, 1.0);
            }
            let key: Vec<u64> = x.iter().map(|v| v.to_bits()).collect();
            *index.entry(key).or_insert_with(|| {
                points.push(x);
                points.len() - 1
            })
        };
        add(&[]);
        let diagonal: Vec<[usize; 3]> = (0..d).map(|i| [0, 1, 2].map(|k| add(&[(i, offsets[i][k])]))).collect();
        let mut mixed = Vec::with_capacity(d * d.saturating_sub(1) / 2);
        for i in 0..d {
            for j in i + 1..d {
                let (a, b) = (&offsets[i], &offsets[j]);
                mixed.push([
                    add(&[(i, a[0]), (j, b[0])]),
                    add(&[(i, a[0]), (j, b[2])]),
                    add(&[(i, a[2]), (j, b[0])]),
                    add(&[(i, a[2]), (j, b[2])]),
                ]);
            }
        }
        self.core.start(points);
        self.stage = Stage::Hessian(Stencil { centre, fallback_cost, offsets, diagonal, mixed });
    }

    fn finish_hessian(&mut self, stencil: Stencil, results: &[Told]) {
        let d = stencil.centre.len();
        let centre_cost = match (results[0].cost(), stencil.fallback_cost) {
            (Some(c), _) => Some(c),
            (None, Some(c)) => {
                self.warnings.push("the Hessian centre failed on re-evaluation; using the restarts' cost".into());
                Some(c)
            }
            (None, None) => None,
        };
        let f = |k: usize| if k == 0 { centre_cost } else { results[k].cost() };
        let mut h = vec![0.0; d * d];
        let mut diagonal_ok = centre_cost.is_some();
        for i in 0..d {
            let [a, b, c] = stencil.diagonal[i];
            let step = stencil.offsets[i][1] - stencil.offsets[i][0];
            match (f(a), f(b), f(c)) {
                (Some(fa), Some(fb), Some(fc)) => h[i * d + i] = (fa - 2.0 * fb + fc) / (step * step),
                _ => {
                    diagonal_ok = false;
                    self.warnings.push(format!(
                        "Hessian diagonal {i} ({}) could not be computed: a stencil point failed",
                        self.space.params()[i].name
                    ));
                }
            }
        }
        let mut pair = 0;
        for i in 0..d {
            for j in i + 1..d {
                let [mm, mp, pm, pp] = stencil.mixed[pair];
                pair += 1;
                let wi = stencil.offsets[i][2] - stencil.offsets[i][0];
                let wj = stencil.offsets[j][2] - stencil.offsets[j][0];
                let v = match (f(mm), f(mp), f(pm), f(pp)) {
                    (Some(a), Some(b), Some(c), Some(e)) => (e - b - c + a) / (wi * wj),
                    _ => {
                        let names = (&self.space.params()[i].name, &self.space.params()[j].name);
                        self.warnings.push(format!(
                            "Hessian entry ({i}, {j}) ({}, {}) set to 0: a stencil point failed",
                            names.0, names.1
                        ));
                        0.0
                    }
                };
                h[i * d + j] = v;
                h[j * d + i] = v;
            }
        }
        if diagonal_ok && h.iter().any(|v| !v.is_finite()) {
            diagonal_ok = false;
            self.warnings.push("the Hessian has entries that are not finite numbers (costs too large?)".into());
        }
        let evaluations = results.len();
        if centre_cost.is_none() {
            self.warnings.push("the Hessian centre failed; no Gaussian approximation".into());
        }
        self.hessian = centre_cost.map(|cost| HessianRecord {
            centre: stencil.centre.clone(),
            cost,
            matrix: diagonal_ok.then_some(h.clone()),
            evaluations,
        });
        // Profiles: K points per side out to `profile_sigmas` conditional standard deviations.
        let k_max = self.options.profile_points;
        let mut points = Vec::new();
        self.profile.clear();
        for i in 0..d {
            let hii = h[i * d + i];
            let sigma = if diagonal_ok && hii > 0.0 { (2.0 / hii).sqrt() } else { f64::INFINITY };
            let extent = (self.options.profile_sigmas * sigma).min(self.options.neighbourhood);
            for sign in [-1.0, 1.0] {
                let mut last = stencil.centre[i];
                for k in 1..=k_max {
                    let u = (stencil.centre[i] + sign * extent * k as f64 / k_max as f64).clamp(0.0, 1.0);
                    if u == last {
                        continue;
                    }
                    last = u;
                    let mut x = stencil.centre.clone();
                    x[i] = u;
                    points.push(x);
                    self.profile.push(ProfileRecord { index: i, unit: u, offset: u - stencil.centre[i], result: None });
                }
            }
        }
        if points.is_empty() {
            self.begin_surface();
        } else {
            self.core.start(points);
            self.stage = Stage::Profile;
        }
    }

    /// Fits the response surface around the Hessian centre and hands out its minimum, or finishes
    /// with a note when there is no usable minimum.
    fn begin_surface(&mut self) {
        let Some(centre) = self.hessian.as_ref().map(|h| h.centre.clone()) else { return self.finish() };
        let names: Vec<&str> = self.space.names().collect();
        let mut record = fit_surface(&centre, &names, &self.sampled, &self.sampled_cost, self.options.neighbourhood);
        match record.centre.clone() {
            Some(x) if self.core.remaining() > 0 => {
                record.id = Some(self.core.used() as CandidateId);
                self.surface = Some(record);
                self.core.start(vec![x]);
                self.stage = Stage::Surface;
            }
            Some(_) => {
                record.note = Some("no evaluation left for the surface's minimum".into());
                self.surface = Some(record);
                self.finish();
            }
            None => {
                self.surface = Some(record);
                self.finish();
            }
        }
    }

    /// The response surface's minimum when it is the stage's estimate.
    pub fn surface_estimate(&self) -> Option<SurfaceEstimate> {
        let s = self.surface.as_ref().filter(|s| s.accepted)?;
        Some(SurfaceEstimate {
            id: s.id?,
            unit: s.centre.clone()?,
            cost: s.result.as_ref()?.cost()?,
            predicted_cost: s.predicted?,
            residual_rms: s.residual_rms,
        })
    }

    fn finish(&mut self) {
        self.stage = Stage::Done;
        let message = format!(
            "{} restarts, Hessian from {} evaluations, {} profile points, response surface {}; {} of {} \
             evaluations used",
            self.restarts.len(),
            self.hessian.as_ref().map_or(0, |h| h.evaluations),
            self.profile.len(),
            match &self.surface {
                Some(s) if s.accepted => "minimum taken as the estimate".to_string(),
                Some(s) => format!("minimum not used: {}", s.note.as_deref().unwrap_or("no reason recorded")),
                None => "not fitted".to_string(),
            },
            self.core.used(),
            self.core.budget()
        );
        self.core.finish(StopReason::Converged { message });
    }

    fn absorb(&mut self, done: Completed) {
        let tag = match &self.stage {
            Stage::Restart { index, .. } => VarianceStage::Restart { index: *index },
            Stage::Hessian(_) => VarianceStage::Hessian,
            Stage::Surface => VarianceStage::Surface,
            _ => VarianceStage::Profile,
        };
        for (k, (p, r)) in done.points.iter().zip(&done.results).enumerate() {
            match r {
                Told::Failed(reason) => {
                    let id = done.first_id + k as CandidateId;
                    self.failures.push(FailureRecord { id, unit: p.clone(), reason: reason.clone(), stage: tag });
                }
                Told::Cost(c) => {
                    self.sampled.push(p.clone());
                    self.sampled_cost.push(*c);
                }
            }
        }
        match std::mem::replace(&mut self.stage, Stage::Done) {
            Stage::Restart { index, start, mut simplex, first, budget } => {
                let costs: Vec<f64> = done.results.iter().map(Told::rank).collect();
                let used = self.core.used() - first;
                match simplex.absorb(&costs, budget.saturating_sub(used)) {
                    Step::Evaluate(points) => {
                        self.core.start(points);
                        self.stage = Stage::Restart { index, start, simplex, first, budget };
                    }
                    terminal => {
                        let (best, best_cost) = simplex.best();
                        self.restarts.push(RestartRecord {
                            start,
                            best: best.to_vec(),
                            best_cost,
                            evaluations: used,
                            iterations: simplex.iterations(),
                            stop: terminal.stop_reason().unwrap_or(StopReason::Budget),
                        });
                        self.restart_used += used;
                        self.begin_restart(index + 1);
                    }
                }
            }
            Stage::Hessian(stencil) => self.finish_hessian(stencil, &done.results),
            Stage::Profile => {
                for (rec, r) in self.profile.iter_mut().zip(done.results) {
                    rec.result = Some(r);
                }
                self.begin_surface();
            }
            Stage::Surface => {
                if let (Some(s), Some(r)) = (self.surface.as_mut(), done.results.into_iter().next()) {
                    judge_surface(s, r);
                }
                self.finish();
            }
            Stage::Done => {}
        }
    }

    /// The optimum the stage is working around: the Hessian centre once chosen, else the best point.
    fn optimum(&self) -> Option<(Vec<f64>, f64)> {
        match (&self.hessian, &self.stage) {
            (Some(h), _) => Some((h.centre.clone(), h.cost)),
            (None, Stage::Hessian(s)) => s.fallback_cost.map(|c| (s.centre.clone(), c)),
            _ => self.core.best_point().map(|(b, c)| (b.to_vec(), c)),
        }
    }

    /// The stage so far.
    pub fn summary(&self) -> VarianceSummary {
        let d = self.space.dim();
        let restarts: Vec<RestartSummary> = self
            .restarts
            .iter()
            .map(|r| RestartSummary {
                start_unit: r.start.clone(),
                best_unit: r.best.clone(),
                best_cost: r.best_cost.is_finite().then_some(r.best_cost),
                evaluations: r.evaluations,
                iterations: r.iterations,
                stop: r.stop.clone(),
            })
            .collect();
        let found: Vec<&RestartRecord> = self.restarts.iter().filter(|r| r.best_cost.is_finite()).collect();
        let restart_spread_unit = (found.len() >= 2).then(|| {
            let m = found.len() as f64;
            (0..d)
                .map(|k| {
                    let mean = found.iter().map(|r| r.best[k]).sum::<f64>() / m;
                    (found.iter().map(|r| (r.best[k] - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt()
                })
                .collect()
        });
        let optimum = self.optimum();
        let mut warnings = self.warnings.clone();
        let gaussian = self.hessian.as_ref().and_then(|h| {
            h.matrix
                .as_ref()
                .map(|m| gaussian(&self.space, &h.centre, h.cost, m, self.options.eigen_floor, &mut warnings))
        });
        let hdiag = self.hessian.as_ref().and_then(|h| h.matrix.as_ref());
        let mut profiles: Vec<Profile> = Vec::new();
        if let Some((_, cost)) = &optimum {
            for rec in &self.profile {
                let Some(result) = &rec.result else { continue };
                if profiles.last().is_none_or(|p| p.index != rec.index) {
                    let name = self.space.params()[rec.index].name.clone();
                    profiles.push(Profile { index: rec.index, name, points: Vec::new(), nearest_failure: None });
                }
                let p = profiles.last_mut().expect("just pushed");
                let i = rec.index;
                p.points.push(ProfilePoint {
                    offset_unit: rec.offset,
                    value: self.space.value(i, rec.unit),
                    cost: result.cost(),
                    failure: result.reason().map(str::to_owned),
                    gaussian_cost: hdiag.map(|m| cost + 0.5 * m[i * d + i] * rec.offset * rec.offset),
                });
                if result.cost().is_none() && p.nearest_failure.is_none_or(|o| rec.offset.abs() < o.abs()) {
                    p.nearest_failure = Some(rec.offset);
                }
            }
            for p in &mut profiles {
                p.points.sort_by(|a, b| a.offset_unit.total_cmp(&b.offset_unit));
            }
        }
        let mut gaussian = gaussian;
        if let (Some(g), Some((_, centre_cost))) = (gaussian.as_mut(), &optimum)
            && let Some(noise) = profile_noise(&profiles, *centre_cost)
        {
            inflate(&self.space, g, noise);
        }
        let mut divergent: Vec<DivergentPoint> = match &optimum {
            Some((centre, _)) => self
                .failures
                .iter()
                .map(|f| (f, distance(&f.unit, centre)))
                .filter(|(_, dist)| *dist <= self.options.neighbourhood)
                .map(|(f, dist)| DivergentPoint {
                    id: f.id,
                    unit: f.unit.clone(),
                    physical: self.space.to_physical(&f.unit),
                    distance: dist,
                    reason: f.reason.clone(),
                    stage: f.stage,
                })
                .collect(),
            None => Vec::new(),
        };
        divergent.sort_by(|a, b| a.distance.total_cmp(&b.distance).then(a.id.cmp(&b.id)));
        VarianceSummary {
            stage: match &self.stage {
                Stage::Restart { index, .. } => Some(VarianceStage::Restart { index: *index }),
                Stage::Hessian(_) => Some(VarianceStage::Hessian),
                Stage::Profile => Some(VarianceStage::Profile),
                Stage::Surface => Some(VarianceStage::Surface),
                Stage::Done => None,
            },
            restarts,
            restart_spread_unit,
            optimum_physical: optimum.as_ref().map(|(c, _)| self.space.to_physical(c)),
            optimum_unit: optimum.as_ref().map(|(c, _)| c.clone()),
            optimum_cost: optimum.as_ref().map(|(_, c)| *c),
            hessian_evaluations: self.hessian.as_ref().map_or(0, |h| h.evaluations),
            gaussian,
            profiles,
            divergent,
            surface: self.surface.as_ref().map(|r| ResponseSurface {
                points: r.points,
                residual_rms: r.residual_rms,
                centre_physical: r.centre.as_ref().map(|c| self.space.to_physical(c)),
                centre_unit: r.centre.clone(),
                predicted_cost: r.predicted,
                cost: r.result.as_ref().and_then(Told::cost),
                accepted: r.accepted,
                note: r.note.clone(),
            }),
            warnings,
            evaluations: self.core.used(),
            budget: self.core.budget(),
            stop: self.core.finished(),
        }
    }
}

super::delegate_to_core!(Variance);

/// The Laplace approximation from a Hessian of `S` (row-major d × d) at `centre`.
fn gaussian(
    space: &Space,
    centre: &[f64],
    cost: f64,
    hessian: &[f64],
    eigen_floor: f64,
    warnings: &mut Vec<String>,
) -> GaussianApproximation {
    let d = centre.len();
    let h = DMatrix::from_row_slice(d, d, hessian);
    let eig = SymmetricEigen::new(h.clone());
    let mut eigenvalues: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    let largest = eigenvalues.iter().copied().fold(0.0f64, f64::max);
    let floor = eigen_floor * if largest > 0.0 { largest } else { 1.0 };
    let regularised = eigenvalues.iter().filter(|&&l| l <= floor).count();
    if regularised > 0 {
        let low: Vec<String> = eigenvalues.iter().filter(|&&l| l <= floor).map(|l| format!("{l:.3e}")).collect();
        warnings.push(format!(
            "the Hessian is not positive definite: eigenvalue(s) {} raised to {floor:.3e}; \
             the covariance along those directions is only a large placeholder",
            low.join(", ")
        ));
    }
    // Σ_u = 2 H⁻¹ = V diag(2/λ) Vᵀ with λ raised to the floor.
    let inv: Vec<f64> = eigenvalues.iter().map(|&l| 2.0 / if l > floor { l } else { floor }).collect();
    let v = &eig.eigenvectors;
    let cov = DMatrix::from_fn(d, d, |i, j| (0..d).map(|k| v[(i, k)] * inv[k] * v[(j, k)]).sum::<f64>());
    let log_det_half_hessian = eigenvalues.iter().map(|&l| (0.5 * if l > floor { l } else { floor }).ln()).sum();
    eigenvalues.sort_by(f64::total_cmp);
    let sd_unit: Vec<f64> = (0..d).map(|i| cov[(i, i)].max(0.0).sqrt()).collect();
    let jac: Vec<f64> = (0..d).map(|i| space.jacobian(i, centre[i])).collect();
    let rows = |f: &dyn Fn(usize, usize) -> f64| -> Vec<Vec<f64>> {
        (0..d).map(|i| (0..d).map(|j| f(i, j)).collect()).collect()
    };
    let covariance_unit = rows(&|i, j| cov[(i, j)]);
    let covariance_physical = rows(&|i, j| jac[i] * jac[j] * cov[(i, j)]);
    let correlation = rows(&|i, j| {
        if i == j {
            1.0
        } else if sd_unit[i] > 0.0 && sd_unit[j] > 0.0 {
            cov[(i, j)] / (sd_unit[i] * sd_unit[j])
        } else {
            0.0
        }
    });
    let interval95 = (0..d)
        .map(|i| {
            let (lo, hi) = (centre[i] - 1.96 * sd_unit[i], centre[i] + 1.96 * sd_unit[i]);
            Interval { lower: space.value(i, lo), upper: space.value(i, hi), clamped: lo < 0.0 || hi > 1.0 }
        })
        .collect();
    GaussianApproximation {
        centre_unit: centre.to_vec(),
        centre_physical: space.to_physical(centre),
        cost,
        hessian_unit: rows(&|i, j| hessian[i * d + j]),
        eigenvalues,
        positive_definite: regularised == 0,
        regularised,
        log_det_half_hessian,
        covariance_unit,
        covariance_physical,
        sd_physical: (0..d).map(|i| jac[i].abs() * sd_unit[i]).collect(),
        sd_unit,
        correlation,
        interval95,
        cost_noise: None,
        noise_inflation: 1.0,
    }
}

/// Numerical noise of the cost from the profiles: each profile's costs (with the optimum's at
/// offset 0) are fitted by a cubic in the offset, which absorbs any smooth shape (the map from
/// unit to physical coordinates makes a quadratic cost cubic); the pooled residual RMS over the
/// degrees of freedom left is σ_ε. `None` without at least one degree of freedom.
fn profile_noise(profiles: &[Profile], centre_cost: f64) -> Option<f64> {
    let mut sum = 0.0;
    let mut dof = 0usize;
    for p in profiles {
        let mut pts: Vec<(f64, f64)> = p.points.iter().filter_map(|q| Some((q.offset_unit, q.cost?))).collect();
        pts.push((0.0, centre_cost));
        if pts.len() <= 4 {
            continue;
        }
        let scale = pts.iter().map(|(x, _)| x.abs()).fold(0.0f64, f64::max).max(1e-300);
        let a = DMatrix::from_fn(pts.len(), 4, |r, c| (pts[r].0 / scale).powi(c as i32));
        let b = nalgebra::DVector::from_iterator(pts.len(), pts.iter().map(|(_, y)| *y));
        let Ok(coef) = a.clone().svd(true, true).solve(&b, 1e-12) else { continue };
        let r = &b - &a * coef;
        sum += r.norm_squared();
        dof += pts.len() - 4;
    }
    (dof > 0).then(|| (sum / dof as f64).sqrt())
}

/// Applies the noise inflation (see [`GaussianApproximation::noise_inflation`]) to `g`.
fn inflate(space: &Space, g: &mut GaussianApproximation, noise: f64) {
    let f = 1.0 + 2.0 * noise.max(0.0);
    let d = g.centre_unit.len();
    g.cost_noise = Some(noise);
    g.noise_inflation = f;
    for i in 0..d {
        for j in 0..d {
            g.covariance_unit[i][j] *= f;
            g.covariance_physical[i][j] *= f;
        }
        g.sd_unit[i] *= f.sqrt();
        g.sd_physical[i] *= f.sqrt();
        let c = g.centre_unit[i];
        let (lo, hi) = (c - 1.96 * g.sd_unit[i], c + 1.96 * g.sd_unit[i]);
        g.interval95[i] =
            Interval { lower: space.value(i, lo), upper: space.value(i, hi), clamped: lo < 0.0 || hi > 1.0 };
    }
}
