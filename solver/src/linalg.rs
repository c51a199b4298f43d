//! Small linear solvers for the scheme: scalar and block-tridiagonal systems (2×2 blocks for
//! the momentum equations, 4×4 for the pressure equation).

use nalgebra::{Const, DimMin, SMatrix, SVector};

/// Solves the tridiagonal system `a[i] x[i-1] + b[i] x[i] + c[i] x[i+1] = d[i]` in place
/// (Thomas algorithm; `a[0]` and `c[n-1]` are ignored). Returns `false` on a zero pivot.
/// `scratch` must have the length of the system.
pub fn tridiagonal(a: &[f64], b: &[f64], c: &[f64], d: &mut [f64], scratch: &mut [f64]) -> bool {
    let n = b.len();
    debug_assert!(a.len() == n && c.len() == n && d.len() == n && scratch.len() == n);
    if n == 0 {
        return true;
    }
    let mut beta = b[0];
    if beta == 0.0 || !beta.is_finite() {
        return false;
    }
    d[0] /= beta;
    for i in 1..n {
        scratch[i] = c[i - 1] / beta;
        beta = b[i] - a[i] * scratch[i];
        if beta == 0.0 || !beta.is_finite() {
            return false;
        }
        d[i] = (d[i] - a[i] * d[i - 1]) / beta;
    }
    for i in (0..n - 1).rev() {
        d[i] -= scratch[i + 1] * d[i + 1];
    }
    true
}

/// Solves the block-tridiagonal system `L[i] x[i-1] + D[i] x[i] + U[i] x[i+1] = r[i]` with K×K
/// blocks in place (block Thomas algorithm; `lower[0]` and `upper[n-1]` are ignored). Returns
/// `false` on a singular pivot block or a solution that is not finite. `scratch` must have the
/// length of the system.
pub fn block_tridiagonal<const K: usize>(
    lower: &[SMatrix<f64, K, K>],
    diag: &[SMatrix<f64, K, K>],
    upper: &[SMatrix<f64, K, K>],
    rhs: &mut [SVector<f64, K>],
    scratch: &mut [SMatrix<f64, K, K>],
) -> bool
where
    Const<K>: DimMin<Const<K>, Output = Const<K>>,
{
    let n = diag.len();
    debug_assert!(lower.len() >= n && upper.len() >= n && rhs.len() >= n && scratch.len() >= n);
    if n == 0 {
        return true;
    }
    let Some(mut inv) = diag[0].try_inverse() else { return false };
    rhs[0] = inv * rhs[0];
    for i in 1..n {
        scratch[i] = inv * upper[i - 1];
        let piv = diag[i] - lower[i] * scratch[i];
        let Some(next) = piv.try_inverse() else { return false };
        inv = next;
        rhs[i] = inv * (rhs[i] - lower[i] * rhs[i - 1]);
    }
    for i in (0..n - 1).rev() {
        let r = rhs[i + 1];
        rhs[i] -= scratch[i + 1] * r;
    }
    rhs[..n].iter().all(|v| v.iter().all(|x| x.is_finite()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix4, Vector2, Vector4};

    #[test]
    fn tridiagonal_matches_direct_product() {
        let a = [0.0, -1.0, -1.0, -1.0];
        let b = [4.0, 4.0, 4.0, 4.0];
        let c = [-1.0, -1.0, -1.0, 0.0];
        let x = [1.0, 2.0, -3.0, 0.5];
        let mut d: Vec<f64> = (0..4)
            .map(|i| {
                b[i] * x[i] + if i > 0 { a[i] * x[i - 1] } else { 0.0 } + if i < 3 { c[i] * x[i + 1] } else { 0.0 }
            })
            .collect();
        let mut s = vec![0.0; 4];
        assert!(tridiagonal(&a, &b, &c, &mut d, &mut s));
        for i in 0..4 {
            assert!((d[i] - x[i]).abs() < 1e-12);
        }
    }

    /// Builds the right-hand sides of the block system (`l`, `d`, `u`) from the solution `x`,
    /// solves it and checks that the solve gives `x` back.
    fn solves_back<const K: usize>(
        l: &[SMatrix<f64, K, K>],
        d: &[SMatrix<f64, K, K>],
        u: &[SMatrix<f64, K, K>],
        x: &[SVector<f64, K>],
    ) where
        Const<K>: DimMin<Const<K>, Output = Const<K>>,
    {
        let n = d.len();
        let mut r: Vec<SVector<f64, K>> = (0..n)
            .map(|i| {
                let mut v = d[i] * x[i];
                if i > 0 {
                    v += l[i] * x[i - 1];
                }
                if i + 1 < n {
                    v += u[i] * x[i + 1];
                }
                v
            })
            .collect();
        let mut s = vec![SMatrix::<f64, K, K>::zeros(); n];
        assert!(block_tridiagonal(l, d, u, &mut r, &mut s));
        for i in 0..n {
            assert!((r[i] - x[i]).norm() < 1e-12);
        }
    }

    #[test]
    fn block_tridiagonal_matches_direct_product() {
        let n = 5;
        let d: Vec<Matrix2<f64>> = (0..n).map(|i| Matrix2::new(5.0 + i as f64, 1.0, -0.5, 4.0)).collect();
        let l: Vec<Matrix2<f64>> = (0..n).map(|_| Matrix2::new(-1.0, 0.2, 0.0, -1.0)).collect();
        let u: Vec<Matrix2<f64>> = (0..n).map(|_| Matrix2::new(-0.5, 0.0, 0.1, -1.0)).collect();
        let x: Vec<Vector2<f64>> = (0..n).map(|i| Vector2::new(i as f64, 1.0 - i as f64)).collect();
        solves_back(&l, &d, &u, &x);
    }

    #[test]
    fn block_tridiagonal_with_4x4_blocks_matches_direct_product() {
        let n = 6;
        let d: Vec<Matrix4<f64>> = (0..n)
            .map(|i| Matrix4::from_fn(|r, c| if r == c { 6.0 + i as f64 } else { 0.3 * (r as f64 - c as f64) }))
            .collect();
        let l: Vec<Matrix4<f64>> =
            (0..n).map(|_| Matrix4::from_fn(|r, c| if r == c { -1.0 } else { 0.1 * c as f64 })).collect();
        let u: Vec<Matrix4<f64>> =
            (0..n).map(|_| Matrix4::from_fn(|r, c| if r == c { -0.5 } else { -0.05 * r as f64 })).collect();
        let x: Vec<Vector4<f64>> = (0..n).map(|i| Vector4::new(i as f64, -1.0, 0.5 * i as f64, 2.0)).collect();
        solves_back(&l, &d, &u, &x);
    }
}
