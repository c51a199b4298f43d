//! Particle swarm optimisation, global-best topology, constriction coefficients.
//!
//! After Kennedy and Eberhart, "Particle swarm optimization" (1995), with the inertia/constriction
//! form of Clerc and Kennedy, "The particle swarm — explosion, stability, and convergence in a
//! multidimensional complex space" (IEEE TEC, 2002): `v ← w v + c₁ r₁ (p − x) + c₂ r₂ (g − x)`,
//! `x ← x + v`, with `w = 0.7298` and `c₁ = c₂ = 1.49618` (constriction χ = 0.7298 applied to
//! φ₁ = φ₂ = 2.05). The paper used MATLAB's `particleswarm`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use super::engine::{
    Book, Generational, MAX_GENERATION, check_common, check_tolerance, delegate_optimizer, reflect, require,
};
use crate::api::StopReason;

/// What a particle does at a face of the unit box.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(rename_all = "snake_case"))]
pub enum Boundary {
    /// Mirror the position back into the box and reverse that velocity component.
    #[default]
    Reflect,
    /// Put the position on the face and zero that velocity component.
    Clamp,
}

/// Options of [`Swarm`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default, deny_unknown_fields))]
pub struct SwarmOptions {
    /// Particles (2 to 1 000 000). `None`: `10·dim`, kept within 20…100 (MATLAB's `min(100, 10·dim)` with a
    /// floor).
    pub swarm: Option<usize>,
    /// Inertia weight `w` (in `[0, 1)`).
    pub inertia: f64,
    /// Attraction `c₁` to the particle's own best (≥ 0).
    pub cognitive: f64,
    /// Attraction `c₂` to the swarm's best (≥ 0).
    pub social: f64,
    /// Largest velocity component, unit coordinates per generation (in `(0, 1]`).
    pub max_velocity: f64,
    /// Behaviour at the faces of the box.
    pub boundary: Boundary,
    /// Stop when every particle is within this distance (largest coordinate difference) of the
    /// swarm's best point.
    pub tolerance: Option<f64>,
}

impl Default for SwarmOptions {
    fn default() -> Self {
        Self {
            swarm: None,
            inertia: 0.7298,
            cognitive: 1.49618,
            social: 1.49618,
            max_velocity: 0.5,
            boundary: Boundary::Reflect,
            tolerance: None,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Core {
    rng: ChaCha8Rng,
    dim: usize,
    size: usize,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    inertia: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    cognitive: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    social: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    max_velocity: f64,
    boundary: Boundary,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolerance: Option<f64>,
    /// Start point for the first generation, if any.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    start: Option<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    x: Vec<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    v: Vec<Vec<f64>>,
    /// Personal bests and their costs (`+∞` until a particle has a successful evaluation).
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    p: Vec<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    pcost: Vec<f64>,
    /// Index of the particle holding the swarm's best.
    gbest: Option<usize>,
}

impl Generational for Core {
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>> {
        if self.x.is_empty() {
            // First generation: uniform positions, velocities towards a uniform point (Clerc's
            // standard PSO initialisation, halved).
            for i in 0..self.size {
                let x: Vec<f64> = match (i, &self.start) {
                    (0, Some(s)) => s.clone(),
                    _ => (0..self.dim).map(|_| self.rng.r#gen::<f64>()).collect(),
                };
                let v = x
                    .iter()
                    .map(|&xi| (0.5 * (self.rng.r#gen::<f64>() - xi)).clamp(-self.max_velocity, self.max_velocity))
                    .collect();
                self.x.push(x);
                self.v.push(v);
            }
            self.p = self.x.clone();
            self.pcost = vec![f64::INFINITY; self.size];
        } else {
            let g = self.gbest;
            for i in 0..self.size {
                for k in 0..self.dim {
                    let (r1, r2): (f64, f64) = (self.rng.r#gen(), self.rng.r#gen());
                    let xi = self.x[i][k];
                    let social = g.map_or(0.0, |g| self.social * r2 * (self.p[g][k] - xi));
                    let own = if self.pcost[i].is_finite() { self.cognitive * r1 * (self.p[i][k] - xi) } else { 0.0 };
                    let mut v =
                        (self.inertia * self.v[i][k] + own + social).clamp(-self.max_velocity, self.max_velocity);
                    let mut x = xi + v;
                    if !(0.0..=1.0).contains(&x) {
                        match self.boundary {
                            Boundary::Reflect => {
                                x = reflect(x);
                                v = -v;
                            }
                            Boundary::Clamp => {
                                x = x.clamp(0.0, 1.0);
                                v = 0.0;
                            }
                        }
                    }
                    self.x[i][k] = x;
                    self.v[i][k] = v;
                }
            }
        }
        self.x.iter().take(max).cloned().collect()
    }

    fn learn(&mut self, points: &[Vec<f64>], costs: &[f64]) -> Option<StopReason> {
        for (i, &c) in costs.iter().enumerate() {
            if c < self.pcost[i] {
                self.pcost[i] = c;
                self.p[i].clone_from(&points[i]);
                if self.gbest.is_none_or(|g| c < self.pcost[g]) {
                    self.gbest = Some(i);
                }
            }
        }
        if let (Some(tol), Some(g)) = (self.tolerance, self.gbest) {
            let spread =
                self.x.iter().flat_map(|x| x.iter().zip(&self.p[g]).map(|(a, b)| (a - b).abs())).fold(0.0, f64::max);
            if spread < tol {
                return Some(StopReason::Converged {
                    message: format!("swarm spread {spread:.3e} < tolerance {tol:.3e}"),
                });
            }
        }
        None
    }
}

/// Particle swarm optimisation (Kennedy and Eberhart 1995; constriction form of Clerc and Kennedy
/// 2002) with the global-best topology.
///
/// The first generation places the particles uniformly (the start, if given, is the first
/// particle); every later generation moves each particle once with fresh uniforms `r₁, r₂` per
/// coordinate, velocity components capped at `max_velocity`, the box handled by `boundary`. A
/// generation is the whole swarm. A failed evaluation never becomes a personal or swarm best.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Swarm {
    core: Core,
    book: Book,
}

impl Swarm {
    /// A particle swarm in `dim` unit coordinates, with `start` as its first particle if given, and
    /// at most `budget` evaluations.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: SwarmOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        let centre = check_common(dim, start, budget)?;
        let size = options.swarm.unwrap_or((10 * dim).clamp(20, 100));
        require((2..=MAX_GENERATION).contains(&size), "swarm", size as f64, "at least 2 and at most 1 000 000")?;
        require((0.0..1.0).contains(&options.inertia), "inertia", options.inertia, "in [0, 1)")?;
        require(
            options.cognitive.is_finite() && options.cognitive >= 0.0,
            "cognitive",
            options.cognitive,
            "a finite number ≥ 0",
        )?;
        require(options.social.is_finite() && options.social >= 0.0, "social", options.social, "a finite number ≥ 0")?;
        require(
            options.max_velocity > 0.0 && options.max_velocity <= 1.0,
            "max_velocity",
            options.max_velocity,
            "in (0, 1]",
        )?;
        check_tolerance("tolerance", options.tolerance)?;
        let mut core = Core {
            rng: ChaCha8Rng::seed_from_u64(seed),
            dim,
            size,
            inertia: options.inertia,
            cognitive: options.cognitive,
            social: options.social,
            max_velocity: options.max_velocity,
            boundary: options.boundary,
            tolerance: options.tolerance,
            start: start.map(|_| centre),
            x: Vec::new(),
            v: Vec::new(),
            p: Vec::new(),
            pcost: Vec::new(),
            gbest: None,
        };
        let book = Book::start(dim, budget, &mut core);
        Ok(Self { core, book })
    }

    /// Completed generations.
    pub fn generation(&self) -> usize {
        self.book.generation()
    }

    /// Number of particles.
    pub fn swarm_size(&self) -> usize {
        self.core.size
    }

    /// The swarm's best point and cost from completed generations.
    pub fn swarm_best(&self) -> Option<(&[f64], f64)> {
        self.core.gbest.map(|g| (self.core.p[g].as_slice(), self.core.pcost[g]))
    }
}

delegate_optimizer!(Swarm);
