//! The variance stage's response surface: a quadratic fitted by least squares to the stage's
//! evaluations near the optimum, and the check of its minimum's evaluation.

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use nalgebra::DMatrix;

use super::common::{Told, distance};
use crate::api::CandidateId;

/// The response surface: a quadratic in unit coordinates fitted by least squares to every
/// successful evaluation of the stage within `neighbourhood` of the Hessian centre (restarts,
/// Hessian stencil and profiles), and its minimum.
///
/// Decision: a simulation cost jitters between nearby points (see
/// [`super::GaussianApproximation::noise_inflation`]), so the lowest evaluation is a lucky draw: over a
/// valley that is flat within the jitter it lands anywhere, and taken as the estimate it moves
/// with the optimiser's seed. The surface's minimum averages the jitter of every point the stage
/// evaluated. It is evaluated once more, so that the estimate is a real run that reproduces, and
/// it is accepted as the stage's estimate when the fit is a minimum (positive-definite curvature),
/// lies within the span of the points it was fitted to (no extrapolation), and its evaluation agrees
/// with the surface's prediction within three residual RMS. Otherwise the estimate stays the
/// lowest evaluation and `note` says why. On a cost that is quadratic over the stage's points
/// the minimum is exact; where the cost is far from quadratic there, the residual RMS holds that
/// shape as well as the jitter, and the check is as loose.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ResponseSurface {
    /// Evaluations the quadratic was fitted to.
    pub points: usize,
    /// Root-mean-square residual of the fit (over the degrees of freedom left): the cost's jitter
    /// plus whatever of its shape a quadratic does not hold.
    pub residual_rms: f64,
    /// The quadratic's minimum, unit coordinates (`None` when the fit has no minimum in range).
    pub centre_unit: Option<Vec<f64>>,
    /// The same, physical values.
    pub centre_physical: Option<Vec<f64>>,
    /// The quadratic's value there.
    pub predicted_cost: Option<f64>,
    /// The cost evaluated there (`None` before the evaluation, or when it failed).
    pub cost: Option<f64>,
    /// True when the minimum is the stage's estimate.
    pub accepted: bool,
    /// Why it is not (or not yet) the estimate.
    pub note: Option<String>,
}

/// The response surface's accepted minimum: the stage's estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceEstimate {
    /// The candidate that evaluated it.
    pub id: CandidateId,
    /// Where, unit coordinates of the stage's space.
    pub unit: Vec<f64>,
    /// Its evaluated cost.
    pub cost: f64,
    /// The surface's prediction there.
    pub predicted_cost: f64,
    /// The surface's residual RMS.
    pub residual_rms: f64,
}

#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub(super) struct SurfaceRecord {
    pub(super) points: usize,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    pub(super) residual_rms: f64,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    pub(super) centre: Option<Vec<f64>>,
    #[cfg_attr(feature = "serde", serde(with = "crate::inference::exact"))]
    pub(super) predicted: Option<f64>,
    /// The candidate evaluating the centre and its result, once in.
    pub(super) id: Option<CandidateId>,
    pub(super) result: Option<Told>,
    pub(super) accepted: bool,
    pub(super) note: Option<String>,
}

/// The response surface around `centre` (see [`ResponseSurface`]): the quadratic least-squares fit
/// to the `points` within `radius`, with its minimum when it has one in the span of those points.
pub(super) fn fit_surface(
    centre: &[f64],
    names: &[&str],
    points: &[Vec<f64>],
    costs: &[f64],
    radius: f64,
) -> SurfaceRecord {
    let d = centre.len();
    let mut record = SurfaceRecord::default();
    // distinct points only: a simplex may evaluate one twice, which adds no information
    let mut seen = std::collections::BTreeSet::new();
    let near: Vec<(&[f64], f64)> = points
        .iter()
        .zip(costs)
        .filter(|(p, _)| distance(p, centre) <= radius)
        .filter(|(p, _)| seen.insert(p.iter().map(|v| v.to_bits()).collect::<Vec<u64>>()))
        .map(|(p, &c)| (p.as_slice(), c))
        .collect();
    record.points = near.len();
    let terms = 1 + d + d * (d + 1) / 2;
    if near.len() <= terms {
        record.note = Some(format!(
            "{} distinct evaluations within {radius} of the optimum; a quadratic in {d} parameters needs more than {terms}",
            near.len()
        ));
        return record;
    }
    // coordinates relative to the centre, scaled to the points' reach along each axis
    let mut lo = vec![0.0f64; d];
    let mut hi = vec![0.0f64; d];
    for (p, _) in &near {
        for i in 0..d {
            lo[i] = lo[i].min(p[i] - centre[i]);
            hi[i] = hi[i].max(p[i] - centre[i]);
        }
    }
    let scale: Vec<f64> = (0..d).map(|i| lo[i].abs().max(hi[i])).collect();
    if let Some(i) = scale.iter().position(|&s| s <= 0.0 || s.is_nan()) {
        record.note = Some(format!("no evaluation near the optimum moves {}", names[i]));
        return record;
    }
    let row = |p: &[f64]| -> Vec<f64> {
        let x: Vec<f64> = (0..d).map(|i| (p[i] - centre[i]) / scale[i]).collect();
        let mut r = Vec::with_capacity(terms);
        r.push(1.0);
        r.extend_from_slice(&x);
        for i in 0..d {
            for j in i..d {
                r.push(x[i] * x[j]);
            }
        }
        r
    };
    let rows: Vec<Vec<f64>> = near.iter().map(|(p, _)| row(p)).collect();
    let a = DMatrix::from_fn(near.len(), terms, |r, c| rows[r][c]);
    let b = nalgebra::DVector::from_iterator(near.len(), near.iter().map(|(_, c)| *c));
    let svd = a.clone().svd(true, true);
    let largest = svd.singular_values.max();
    if svd.singular_values.min() <= 1e-10 * largest {
        record.note = Some(
            "the evaluations near the optimum do not determine a quadratic (they lie too close to a line or plane)"
                .into(),
        );
        return record;
    }
    let Ok(coef) = svd.solve(&b, 0.0) else {
        record.note = Some("the least-squares fit failed".into());
        return record;
    };
    let residual = &b - &a * &coef;
    record.residual_rms = (residual.norm_squared() / (near.len() - terms) as f64).sqrt();
    // S(x) ≈ c₀ + gᵀx + ½ xᵀ A x
    let g = nalgebra::DVector::from_iterator(d, (0..d).map(|i| coef[1 + i]));
    let mut hess = DMatrix::zeros(d, d);
    let mut k = 1 + d;
    for i in 0..d {
        for j in i..d {
            if i == j {
                hess[(i, i)] = 2.0 * coef[k];
            } else {
                hess[(i, j)] = coef[k];
                hess[(j, i)] = coef[k];
            }
            k += 1;
        }
    }
    let Some(chol) = hess.clone().cholesky() else {
        record.note = Some("the fitted quadratic has no minimum (its curvature is not positive definite)".into());
        return record;
    };
    let x = -chol.solve(&g);
    let inside = (0..d).all(|i| x[i] * scale[i] >= lo[i] && x[i] * scale[i] <= hi[i]);
    if !inside {
        record.note = Some("the fitted quadratic's minimum lies outside the evaluations it was fitted to".into());
        return record;
    }
    let predicted = coef[0] + g.dot(&x) + 0.5 * x.dot(&(&hess * &x));
    record.centre = Some((0..d).map(|i| (centre[i] + x[i] * scale[i]).clamp(0.0, 1.0)).collect());
    record.predicted = Some(predicted);
    record
}

/// Decides whether the surface's minimum, now evaluated, is the estimate: the evaluation must agree
/// with the prediction within three residual RMS (a relative 1e-9 for an exact fit).
pub(super) fn judge_surface(s: &mut SurfaceRecord, result: Told) {
    let predicted = s.predicted.unwrap_or(f64::NAN);
    match result.cost() {
        Some(c) => {
            let tolerance = 3.0 * s.residual_rms + 1e-9 * predicted.abs().max(c.abs());
            if (c - predicted).abs() <= tolerance {
                s.accepted = true;
            } else {
                s.note = Some(format!(
                    "its cost {c:.6e} is not the surface's {predicted:.6e} within three residual RMS ({:.3e})",
                    s.residual_rms
                ));
            }
        }
        None => s.note = Some(format!("its evaluation failed: {}", result.reason().unwrap_or("no reason given"))),
    }
    s.result = Some(result);
}
