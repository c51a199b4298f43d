//! Standard test functions on the unit box, for tests and benchmarks of the algorithms.
//!
//! Each maps unit coordinates `u ∈ [0, 1]^d` to the function's usual domain and has its global
//! minimum 0 at a known unit point, away from the centre and from the box faces, so an algorithm
//! that merely returns the centre or a corner cannot pass.

/// Where the minimum of every test function lies in each unit coordinate.
pub const OPTIMUM_UNIT: f64 = 0.3;

/// Sphere: `Σ z²`, `z = 10 (u − 0.3)`.
pub fn sphere(u: &[f64]) -> f64 {
    u.iter().map(|&v| (10.0 * (v - OPTIMUM_UNIT)).powi(2)).sum()
}

/// Rosenbrock: `Σ 100 (z_{i+1} − z_i²)² + (1 − z_i)²`, `z = 1 + 5 (u − 0.3)` (minimum at z = 1).
pub fn rosenbrock(u: &[f64]) -> f64 {
    let z: Vec<f64> = u.iter().map(|&v| 1.0 + 5.0 * (v - OPTIMUM_UNIT)).collect();
    z.windows(2).map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (1.0 - w[0]).powi(2)).sum()
}

/// Rastrigin: `10 d + Σ z² − 10 cos(2π z)`, `z = 10.24 (u − 0.3)` (z ∈ [−3.07, 7.17]).
pub fn rastrigin(u: &[f64]) -> f64 {
    let d = u.len() as f64;
    10.0 * d
        + u.iter()
            .map(|&v| {
                let z = 10.24 * (v - OPTIMUM_UNIT);
                z * z - 10.0 * (2.0 * std::f64::consts::PI * z).cos()
            })
            .sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minima_at_the_stated_point() {
        let x = vec![OPTIMUM_UNIT; 5];
        assert!(sphere(&x).abs() < 1e-24);
        assert!(rosenbrock(&x).abs() < 1e-24);
        assert!(rastrigin(&x).abs() < 1e-9);
        assert!(sphere(&[0.5; 5]) > 1.0 && rosenbrock(&[0.5; 5]) > 1.0 && rastrigin(&[0.5; 5]) > 1.0);
    }
}
