//! Real-coded genetic algorithm: tournament selection, simulated binary or blend crossover,
//! polynomial or Gaussian mutation, elitism.
//!
//! The operators follow Deb and Agrawal, "Simulated binary crossover for continuous search space"
//! (Complex Systems, 1995), Deb and Goyal's bounded polynomial mutation (1996, in the form used by
//! NSGA-II), Eshelman and Schaffer's blend crossover BLX-α (1993), and Goldberg and Deb's tournament
//! selection (1991). The generational scheme with a few elite individuals copied unchanged is the
//! one of MATLAB's `ga`, which the paper used.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use super::OptimError;
use super::engine::{
    Book, Generational, MAX_GENERATION, argmin, check_common, check_tolerance, delegate_optimizer, ranking, reflect,
    require,
};
use crate::api::StopReason;

/// Crossover operator of [`Genetic`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(tag = "kind", rename_all = "snake_case"))]
pub enum Crossover {
    /// Simulated binary crossover (Deb and Agrawal, 1995) with distribution index `eta` (> 0; larger
    /// keeps children closer to their parents). Each coordinate crosses with probability 1/2.
    Sbx {
        /// Distribution index.
        eta: f64,
    },
    /// Blend crossover BLX-α (Eshelman and Schaffer, 1993): each child coordinate uniform on the
    /// parents' interval widened by `alpha` times its length on both sides (`alpha ≥ 0`).
    Blend {
        /// Widening factor.
        alpha: f64,
    },
}

/// Mutation operator of [`Genetic`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(tag = "kind", rename_all = "snake_case"))]
pub enum Mutation {
    /// Bounded polynomial mutation (Deb and Goyal, 1996) with distribution index `eta` (> 0).
    Polynomial {
        /// Distribution index.
        eta: f64,
    },
    /// Gaussian mutation with standard deviation `sigma` (unit coordinates, > 0) shrinking linearly
    /// to zero over the budget, like MATLAB's `mutationgaussian` with shrink 1.
    Gaussian {
        /// Initial standard deviation.
        sigma: f64,
    },
}

/// Options of [`Genetic`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(default, deny_unknown_fields))]
pub struct GeneticOptions {
    /// Individuals per generation (2 to 1 000 000). `None`: `10·dim`, kept within 20…200.
    pub population: Option<usize>,
    /// Best individuals copied unchanged into the next generation (< population). `None`: 5 % of
    /// the population, at least 1.
    pub elite: Option<usize>,
    /// Tournament size (≥ 1; 1 means random selection).
    pub tournament: usize,
    /// Crossover operator.
    pub crossover: Crossover,
    /// Probability that a pair of parents is crossed (in `[0, 1]`); otherwise they are copied.
    pub crossover_rate: f64,
    /// Mutation operator.
    pub mutation: Mutation,
    /// Probability that a coordinate of a child is mutated (in `[0, 1]`). `None`: `1/dim`.
    pub mutation_rate: Option<f64>,
    /// Stop when the best cost improved by less than this over `stall_generations` generations.
    pub tolerance: Option<f64>,
    /// Generations over which the improvement is measured for `tolerance` (≥ 1).
    pub stall_generations: usize,
}

impl Default for GeneticOptions {
    fn default() -> Self {
        Self {
            population: None,
            elite: None,
            tournament: 2,
            crossover: Crossover::Sbx { eta: 15.0 },
            crossover_rate: 0.9,
            mutation: Mutation::Polynomial { eta: 20.0 },
            mutation_rate: None,
            tolerance: None,
            stall_generations: 20,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
enum CrossoverKind {
    Sbx,
    Blend,
}

#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
enum MutationKind {
    Polynomial,
    Gaussian,
}

#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
struct Core {
    rng: ChaCha8Rng,
    dim: usize,
    budget: usize,
    size: usize,
    elite: usize,
    tournament: usize,
    crossover: CrossoverKind,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    crossover_param: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    crossover_rate: f64,
    mutation: MutationKind,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    mutation_param: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    mutation_rate: f64,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    tolerance: Option<f64>,
    stall: usize,
    /// Start point for the first generation, if any.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    start: Option<Vec<f64>>,
    /// The evaluated population and its costs (empty before the first generation is learnt).
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    population: Vec<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    costs: Vec<f64>,
    /// Elite carried into the generation being evaluated.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    elite_points: Vec<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    elite_costs: Vec<f64>,
    /// Best cost of the last `stall + 1` generations.
    #[cfg_attr(feature = "serde", serde(with = "super::exact"))]
    history: Vec<f64>,
    evaluated: usize,
}

impl Core {
    fn select(&mut self) -> usize {
        let n = self.population.len();
        let mut winner = self.rng.gen_range(0..n);
        for _ in 1..self.tournament {
            let c = self.rng.gen_range(0..n);
            if self.costs[c] < self.costs[winner] {
                winner = c;
            }
        }
        winner
    }

    fn cross(&mut self, a: &[f64], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut c1, mut c2) = (a.to_vec(), b.to_vec());
        if self.rng.r#gen::<f64>() >= self.crossover_rate {
            return (c1, c2);
        }
        for i in 0..self.dim {
            match self.crossover {
                CrossoverKind::Sbx => {
                    if self.rng.r#gen::<f64>() >= 0.5 || (a[i] - b[i]).abs() < 1e-14 {
                        continue;
                    }
                    let u: f64 = self.rng.r#gen();
                    let e = 1.0 / (self.crossover_param + 1.0);
                    let beta = if u <= 0.5 { (2.0 * u).powf(e) } else { (0.5 / (1.0 - u)).powf(e) };
                    c1[i] = (0.5 * ((1.0 + beta) * a[i] + (1.0 - beta) * b[i])).clamp(0.0, 1.0);
                    c2[i] = (0.5 * ((1.0 - beta) * a[i] + (1.0 + beta) * b[i])).clamp(0.0, 1.0);
                }
                CrossoverKind::Blend => {
                    let (lo, hi) = (a[i].min(b[i]), a[i].max(b[i]));
                    let w = self.crossover_param * (hi - lo);
                    let (u1, u2): (f64, f64) = (self.rng.r#gen(), self.rng.r#gen());
                    c1[i] = reflect(lo - w + u1 * (hi - lo + 2.0 * w));
                    c2[i] = reflect(lo - w + u2 * (hi - lo + 2.0 * w));
                }
            }
        }
        (c1, c2)
    }

    fn mutate(&mut self, x: &mut [f64]) {
        let shrink = 1.0 - (self.evaluated as f64 / self.budget as f64).min(1.0);
        for v in x.iter_mut() {
            if self.rng.r#gen::<f64>() >= self.mutation_rate {
                continue;
            }
            match self.mutation {
                MutationKind::Polynomial => {
                    let eta = self.mutation_param;
                    let e = 1.0 / (eta + 1.0);
                    let u: f64 = self.rng.r#gen();
                    let dq = if u < 0.5 {
                        let xy = 1.0 - *v;
                        let val = 2.0 * u + (1.0 - 2.0 * u) * xy.powf(eta + 1.0);
                        val.powf(e) - 1.0
                    } else {
                        let xy = *v;
                        let val = 2.0 * (1.0 - u) + 2.0 * (u - 0.5) * xy.powf(eta + 1.0);
                        1.0 - val.powf(e)
                    };
                    *v = (*v + dq).clamp(0.0, 1.0);
                }
                MutationKind::Gaussian => {
                    let z: f64 = self.rng.sample(StandardNormal);
                    *v = reflect(*v + self.mutation_param * shrink * z);
                }
            }
        }
    }
}

impl Generational for Core {
    fn propose(&mut self, max: usize) -> Vec<Vec<f64>> {
        if self.population.is_empty() {
            let n = self.size.min(max);
            let mut out = Vec::with_capacity(n);
            if let Some(s) = self.start.take() {
                out.push(s);
            }
            while out.len() < n {
                out.push((0..self.dim).map(|_| self.rng.r#gen::<f64>()).collect());
            }
            return out;
        }
        let order = ranking(&self.costs);
        let elite = self.elite.min(self.population.len());
        self.elite_points = order[..elite].iter().map(|&i| self.population[i].clone()).collect();
        self.elite_costs = order[..elite].iter().map(|&i| self.costs[i]).collect();
        let n = (self.size - elite).min(max);
        let mut out = Vec::with_capacity(n + 1);
        while out.len() < n {
            let a = self.select();
            let b = self.select();
            let (pa, pb) = (self.population[a].clone(), self.population[b].clone());
            let (mut c1, mut c2) = self.cross(&pa, &pb);
            self.mutate(&mut c1);
            self.mutate(&mut c2);
            out.push(c1);
            out.push(c2);
        }
        out.truncate(n);
        out
    }

    fn learn(&mut self, points: &[Vec<f64>], costs: &[f64]) -> Option<StopReason> {
        self.evaluated += points.len();
        self.population = std::mem::take(&mut self.elite_points);
        self.population.extend(points.iter().cloned());
        self.costs = std::mem::take(&mut self.elite_costs);
        self.costs.extend_from_slice(costs);
        let best = argmin(&self.costs).map_or(f64::INFINITY, |b| self.costs[b]);
        self.history.push(best);
        if self.history.len() > self.stall + 1 {
            self.history.remove(0);
        }
        if let Some(tol) = self.tolerance
            && self.history.len() == self.stall + 1
        {
            let gain = self.history[0] - best;
            if gain < tol {
                return Some(StopReason::Converged {
                    message: format!(
                        "best cost improved by {gain:.3e} < tolerance {tol:.3e} over the last {} generations",
                        self.stall
                    ),
                });
            }
        }
        None
    }
}

/// Real-coded generational genetic algorithm with elitism (operators after Deb and Agrawal 1995,
/// Deb and Goyal 1996, Eshelman and Schaffer 1993; scheme after MATLAB's `ga`).
///
/// The first generation is `population` uniform random points (the start, if given, replaces the
/// first). Each later generation keeps the `elite` best individuals with their known costs and
/// evaluates `population − elite` children: parents by tournament, crossed with probability
/// `crossover_rate`, then mutated coordinate-wise. Failed individuals rank last.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Genetic {
    core: Core,
    book: Book,
}

impl Genetic {
    /// A genetic algorithm in `dim` unit coordinates, seeded with `start` if given, with at most
    /// `budget` evaluations.
    pub fn new(
        dim: usize,
        start: Option<&[f64]>,
        options: GeneticOptions,
        budget: usize,
        seed: u64,
    ) -> Result<Self, OptimError> {
        let centre = check_common(dim, start, budget)?;
        let size = options.population.unwrap_or((10 * dim).clamp(20, 200));
        require((2..=MAX_GENERATION).contains(&size), "population", size as f64, "at least 2 and at most 1 000 000")?;
        let elite = options.elite.unwrap_or(size.div_ceil(20).max(1));
        require(elite < size, "elite", elite as f64, "less than the population")?;
        require(options.tournament >= 1, "tournament", options.tournament as f64, "at least 1")?;
        let (crossover, crossover_param) = match options.crossover {
            Crossover::Sbx { eta } => {
                require(eta.is_finite() && eta > 0.0, "crossover.eta", eta, "a finite number > 0")?;
                (CrossoverKind::Sbx, eta)
            }
            Crossover::Blend { alpha } => {
                require(alpha.is_finite() && alpha >= 0.0, "crossover.alpha", alpha, "a finite number ≥ 0")?;
                (CrossoverKind::Blend, alpha)
            }
        };
        require((0.0..=1.0).contains(&options.crossover_rate), "crossover_rate", options.crossover_rate, "in [0, 1]")?;
        let (mutation, mutation_param) = match options.mutation {
            Mutation::Polynomial { eta } => {
                require(eta.is_finite() && eta > 0.0, "mutation.eta", eta, "a finite number > 0")?;
                (MutationKind::Polynomial, eta)
            }
            Mutation::Gaussian { sigma } => {
                require(sigma.is_finite() && sigma > 0.0, "mutation.sigma", sigma, "a finite number > 0")?;
                (MutationKind::Gaussian, sigma)
            }
        };
        let mutation_rate = options.mutation_rate.unwrap_or(1.0 / dim as f64);
        require((0.0..=1.0).contains(&mutation_rate), "mutation_rate", mutation_rate, "in [0, 1]")?;
        check_tolerance("tolerance", options.tolerance)?;
        require(options.stall_generations >= 1, "stall_generations", options.stall_generations as f64, "at least 1")?;
        let mut core = Core {
            rng: ChaCha8Rng::seed_from_u64(seed),
            dim,
            budget,
            size,
            elite,
            tournament: options.tournament,
            crossover,
            crossover_param,
            crossover_rate: options.crossover_rate,
            mutation,
            mutation_param,
            mutation_rate,
            tolerance: options.tolerance,
            stall: options.stall_generations,
            start: start.map(|_| centre),
            population: Vec::new(),
            costs: Vec::new(),
            elite_points: Vec::new(),
            elite_costs: Vec::new(),
            history: Vec::new(),
            evaluated: 0,
        };
        let book = Book::start(dim, budget, &mut core);
        Ok(Self { core, book })
    }

    /// Completed generations.
    pub fn generation(&self) -> usize {
        self.book.generation()
    }

    /// Individuals per generation (elite included).
    pub fn population_size(&self) -> usize {
        self.core.size
    }

    /// The evaluated population of the last completed generation with its costs (`+∞` for failed
    /// individuals); empty before the first generation is complete.
    pub fn population(&self) -> (&[Vec<f64>], &[f64]) {
        (&self.core.population, &self.core.costs)
    }
}

delegate_optimizer!(Genetic);

#[cfg(test)]
mod tests {
    use super::*;

    fn core(crossover: Crossover, mutation: Mutation) -> Genetic {
        let options = GeneticOptions { crossover, mutation, mutation_rate: Some(1.0), ..Default::default() };
        Genetic::new(3, None, options, 1000, 4).unwrap()
    }

    #[test]
    fn operators_keep_children_in_the_box() {
        for (c, m) in [
            (Crossover::Sbx { eta: 2.0 }, Mutation::Polynomial { eta: 1.0 }),
            (Crossover::Blend { alpha: 2.0 }, Mutation::Gaussian { sigma: 3.0 }),
        ] {
            let mut g = core(c, m);
            let (a, b) = (vec![0.0, 0.99, 0.5], vec![1.0, 0.98, 0.5]);
            for _ in 0..2000 {
                let (mut c1, mut c2) = g.core.cross(&a, &b);
                g.core.mutate(&mut c1);
                g.core.mutate(&mut c2);
                assert!(c1.iter().chain(&c2).all(|v| (0.0..=1.0).contains(v)), "{c1:?} {c2:?}");
            }
        }
    }

    #[test]
    fn sbx_children_are_symmetric_about_the_parents_mean() {
        let mut g = core(Crossover::Sbx { eta: 15.0 }, Mutation::Polynomial { eta: 20.0 });
        let (a, b) = (vec![0.4, 0.5, 0.6], vec![0.6, 0.5, 0.4]);
        for _ in 0..100 {
            let (c1, c2) = g.core.cross(&a, &b);
            for i in 0..3 {
                assert!((c1[i] + c2[i] - a[i] - b[i]).abs() < 1e-12);
            }
        }
    }
}
