//! Draws from a multivariate Gaussian (the variance stage's approximation of the posterior), for
//! predictions when no MCMC stage ran.
//!
//! Decision: the variance stage fits its Gaussian in unit coordinates, where a logarithmic
//! parameter is uniform in `ln x`; [`space_draws`] draws there and maps each draw through the
//! [`Space`], so that a wide interval of a log-scaled parameter stays positive and skewed as its
//! reported 95 % interval is, instead of a symmetric physical Gaussian clamped at the lower bound
//! (which piles draws on the bound and shifts a posterior-predictive band away from the best fit).

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::space::Space;

/// Why no draws can be made.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DrawsError {
    /// The covariance or the bounds do not match the mean's dimension.
    #[error("covariance must be {dim} × {dim} and there must be {dim} bounds")]
    Shape {
        /// The mean's dimension.
        dim: usize,
    },
    /// A mean or covariance entry is not a finite number.
    #[error("the mean and covariance must be finite")]
    NotFinite,
    /// Not even the covariance with floored eigenvalues has a Cholesky factor.
    #[error("the covariance cannot be factorised")]
    NotFactorisable,
}

/// `n` draws of N(mean, cov), each clamped into `[lower_i, upper_i]`. The covariance is
/// factorised by Cholesky; a covariance that is not positive definite gets its eigenvalues
/// floored at 1e-12 of the largest first.
pub fn gaussian_draws(
    mean: &[f64],
    cov: &[Vec<f64>],
    bounds: &[(f64, f64)],
    n: usize,
    seed: u64,
) -> Result<Vec<Vec<f64>>, DrawsError> {
    let d = mean.len();
    if cov.len() != d || cov.iter().any(|r| r.len() != d) || bounds.len() != d {
        return Err(DrawsError::Shape { dim: d });
    }
    if mean.iter().chain(cov.iter().flatten()).any(|v| !v.is_finite()) {
        return Err(DrawsError::NotFinite);
    }
    let c = DMatrix::from_fn(d, d, |i, j| 0.5 * (cov[i][j] + cov[j][i]));
    let l = match c.clone().cholesky() {
        Some(ch) => ch.l(),
        None => {
            let eig = c.symmetric_eigen();
            let top = eig.eigenvalues.iter().fold(0.0f64, |m, &v| m.max(v.abs())).max(1e-300);
            let vals = eig.eigenvalues.map(|v| v.max(1e-12 * top));
            let fixed = &eig.eigenvectors * DMatrix::from_diagonal(&vals) * eig.eigenvectors.transpose();
            fixed.cholesky().ok_or(DrawsError::NotFactorisable)?.l()
        }
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let m = DVector::from_column_slice(mean);
    Ok((0..n)
        .map(|_| {
            let z = DVector::from_fn(d, |_, _| StandardNormal.sample(&mut rng));
            let x = &m + &l * z;
            x.iter().zip(bounds).map(|(&v, &(lo, hi))| v.clamp(lo, hi)).collect()
        })
        .collect())
}

/// `n` draws of the Gaussian N(`centre_unit`, `cov_unit`) in the unit coordinates of `space`,
/// each clamped into the unit box and returned in physical values (see the module's decision).
pub fn space_draws(
    space: &Space,
    centre_unit: &[f64],
    cov_unit: &[Vec<f64>],
    n: usize,
    seed: u64,
) -> Result<Vec<Vec<f64>>, DrawsError> {
    if centre_unit.len() != space.dim() {
        return Err(DrawsError::Shape { dim: space.dim() });
    }
    let unit = gaussian_draws(centre_unit, cov_unit, &vec![(0.0, 1.0); space.dim()], n, seed)?;
    Ok(unit.iter().map(|u| space.to_physical(u)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_mean_and_covariance() {
        let cov = vec![vec![4.0, 1.2], vec![1.2, 1.0]];
        let b = [(-1e9, 1e9), (-1e9, 1e9)];
        let x = gaussian_draws(&[1.0, -2.0], &cov, &b, 40_000, 7).unwrap();
        let n = x.len() as f64;
        let m0 = x.iter().map(|v| v[0]).sum::<f64>() / n;
        let m1 = x.iter().map(|v| v[1]).sum::<f64>() / n;
        let c01 = x.iter().map(|v| (v[0] - m0) * (v[1] - m1)).sum::<f64>() / n;
        let c00 = x.iter().map(|v| (v[0] - m0).powi(2)).sum::<f64>() / n;
        assert!((m0 - 1.0).abs() < 0.03 && (m1 + 2.0).abs() < 0.015, "{m0} {m1}");
        assert!((c00 - 4.0).abs() < 0.1 && (c01 - 1.2).abs() < 0.05, "{c00} {c01}");
        // clamped into the bounds
        let y = gaussian_draws(&[0.0], &[vec![1.0]], &[(-0.5, 0.5)], 100, 1).unwrap();
        assert!(y.iter().all(|v| v[0].abs() <= 0.5));
        assert_eq!(gaussian_draws(&[0.0], &[vec![f64::NAN]], &[(0.0, 1.0)], 1, 1), Err(DrawsError::NotFinite));
        assert_eq!(gaussian_draws(&[0.0], &[vec![1.0]], &[], 1, 1), Err(DrawsError::Shape { dim: 1 }));
    }

    #[test]
    fn draws_in_unit_coordinates_keep_a_log_parameter_positive_and_its_median() {
        use crate::space::{FreeParameter, Scale};
        let p =
            |name: &str, lower: f64, upper: f64, scale: Scale| FreeParameter { name: name.into(), lower, upper, scale };
        let space = Space::new(vec![p("a", 0.01, 100.0, Scale::Log), p("b", 0.0, 10.0, Scale::Linear)]).unwrap();
        // a wide Gaussian around a = 1 (unit 0.5): a physical Gaussian this wide would be clamped
        // at 0.01 for about a third of its draws
        let x = space_draws(&space, &[0.5, 0.5], &[vec![0.04, 0.0], vec![0.0, 0.0001]], 4000, 3).unwrap();
        let mut a: Vec<f64> = x.iter().map(|v| v[0]).collect();
        a.sort_by(f64::total_cmp);
        assert!(a.iter().all(|&v| (0.01..=100.0).contains(&v)));
        let clamped = a.iter().filter(|&&v| v == 0.01).count();
        assert!(clamped < 40, "{clamped} draws on the lower bound");
        let median = a[a.len() / 2];
        assert!((median / 1.0 - 1.0).abs() < 0.1, "median {median}");
        assert!(x.iter().all(|v| (v[1] - 5.0).abs() < 0.5));
        assert_eq!(space_draws(&space, &[0.5], &[vec![1.0]], 1, 1), Err(DrawsError::Shape { dim: 2 }));
    }
}
