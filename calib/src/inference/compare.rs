//! Model comparison: which set of correlations does the data favour?
//!
//! The paper (section "Probabilistic framework") proposes comparing models `m` through Bayes' rule
//! for the model, eq. "bayes_model", whose central quantity is the evidence `P(d|m) = ∫ P(d|θ,m)
//! P(θ|m) dθ` (the denominator of eq. "bayes_param"). (As printed, eq. "bayes_model" reads
//! `P(d|m) = P(m|d) P(m) / P(d)`; Bayes' rule gives `P(d|m) = P(m|d) P(d) / P(m)`. With equal prior
//! model probabilities the posterior odds of two models equal their evidence ratio, the Bayes
//! factor, which is what is reported here.) The evidence automatically penalises needless
//! parameters — the "Ockham's razor" the paper mentions.
//!
//! All functions are pure. Conventions: the cost `S` is the weighted sum of squares normalised by
//! known noise, so `−2 ln L = S + C` with `C = Σ ln(2π σ²)` the same for every model fitted to the
//! same data; information criteria and log evidences below drop `C`, so only **differences between
//! models on the same data** are meaningful. The prior is uniform on the unit box of each model's
//! free parameters (density 1 in unit coordinates; uniform in value for linear parameters,
//! log-uniform for logarithmic ones).

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use nalgebra::{DMatrix, SymmetricEigen};

use super::variance::GaussianApproximation;

/// Why a comparison could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ComparisonError {
    /// The Hessian is not square.
    #[error("the Hessian must be square: got {rows} rows, and a row of {cols} entries")]
    HessianShape {
        /// Rows.
        rows: usize,
        /// Length of the first row that differs.
        cols: usize,
    },
    /// A Hessian entry is not a finite number.
    #[error("Hessian entry ({row}, {col}) = {value} is not a finite number")]
    NonFiniteHessian {
        /// Row.
        row: usize,
        /// Column.
        col: usize,
        /// The entry.
        value: f64,
    },
    /// The Laplace approximation needs a positive-definite Hessian.
    #[error(
        "the Hessian is not positive definite (smallest eigenvalue {min_eigenvalue:e}); the optimum is not a strict minimum"
    )]
    NotPositiveDefinite {
        /// Smallest eigenvalue of the Hessian of `S`.
        min_eigenvalue: f64,
    },
    /// The best cost is not a finite number ≥ 0.
    #[error("the best cost {s_min} is not a finite number ≥ 0")]
    BadCost {
        /// The cost given.
        s_min: f64,
    },
    /// Fewer than two models.
    #[error("a comparison needs at least two models, got {count}")]
    TooFewModels {
        /// Models given.
        count: usize,
    },
    /// Models were fitted to different amounts of data.
    #[error("model `{name}` has {n_data} data points but `{first}` has {expected}; compare models on the same data")]
    DifferentData {
        /// The model that differs.
        name: String,
        /// Its data points.
        n_data: usize,
        /// The first model.
        first: String,
        /// The first model's data points.
        expected: usize,
    },
    /// Two models share a name.
    #[error("model name `{name}` is used twice")]
    DuplicateName {
        /// The name.
        name: String,
    },
    /// One model's numbers are invalid.
    #[error("model `{name}`: {error}")]
    InModel {
        /// The model.
        name: String,
        /// What is wrong with it.
        error: Box<ComparisonError>,
    },
}

/// Akaike information criterion `AIC = −2 ln L̂ + 2k = S_min + 2k` (Akaike 1974), up to the
/// model-independent constant described in the module documentation.
pub fn aic(s_min: f64, k: usize) -> f64 {
    s_min + 2.0 * k as f64
}

/// Bayesian information criterion `BIC = −2 ln L̂ + k ln N = S_min + k ln N` (Schwarz 1978),
/// `N` the number of data points, up to the same constant.
pub fn bic(s_min: f64, k: usize, n_data: usize) -> f64 {
    s_min + k as f64 * (n_data as f64).ln()
}

/// Laplace approximation of the log evidence (MacKay 2003, "Information Theory, Inference, and
/// Learning Algorithms", ch. 27–28):
/// `ln Z ≈ −S_min/2 + (k/2) ln 2π − ½ ln det H_{S/2} + ln π(θ̂)`, with `H_{S/2} = H_S / 2` the
/// Hessian of the negative log-likelihood at the optimum in unit coordinates and `π` the prior
/// density there: a uniform prior over a region of volume `V` in unit coordinates has density `1/V`,
/// so `log_prior_density = −ln V`, which is 0 for the whole unit box. Exact for a Gaussian
/// likelihood whose mass lies inside the box.
///
/// `hessian_s` is the Hessian of `S` (not of `S/2`), as [`GaussianApproximation::hessian_unit`].
pub fn laplace_log_evidence(
    s_min: f64,
    hessian_s: &[Vec<f64>],
    log_prior_density: f64,
) -> Result<f64, ComparisonError> {
    if !(s_min.is_finite() && s_min >= 0.0) {
        return Err(ComparisonError::BadCost { s_min });
    }
    let k = hessian_s.len();
    if let Some(row) = hessian_s.iter().find(|r| r.len() != k) {
        return Err(ComparisonError::HessianShape { rows: k, cols: row.len() });
    }
    for (row, r) in hessian_s.iter().enumerate() {
        if let Some((col, &value)) = r.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(ComparisonError::NonFiniteHessian { row, col, value });
        }
    }
    let h = DMatrix::from_fn(k, k, |i, j| 0.5 * (hessian_s[i][j] + hessian_s[j][i]) / 2.0);
    let eig = SymmetricEigen::new(h);
    let min_eigenvalue = eig.eigenvalues.iter().copied().fold(f64::INFINITY, f64::min);
    if k > 0 && !(min_eigenvalue > 0.0 && min_eigenvalue.is_finite()) {
        return Err(ComparisonError::NotPositiveDefinite { min_eigenvalue: 2.0 * min_eigenvalue });
    }
    let log_det: f64 = eig.eigenvalues.iter().map(|l| l.ln()).sum();
    Ok(-0.5 * s_min + 0.5 * k as f64 * (2.0 * std::f64::consts::PI).ln() - 0.5 * log_det + log_prior_density)
}

/// One fitted model: what a comparison needs.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ModelFit {
    /// A name for the correlation set (e.g. "Iloeje CHF").
    pub name: String,
    /// Best cost `S_min`.
    pub s_min: f64,
    /// Number of data points `N` the cost sums over.
    pub n_data: usize,
    /// Hessian of `S` at the optimum in unit coordinates, k × k (k free parameters).
    pub hessian_unit: Vec<Vec<f64>>,
    /// `ln` of the prior density at the optimum in unit coordinates: 0 for the unit box.
    pub log_prior_density: f64,
}

impl ModelFit {
    /// A model with the unit-box prior.
    pub fn new(name: impl Into<String>, s_min: f64, n_data: usize, hessian_unit: Vec<Vec<f64>>) -> Self {
        Self { name: name.into(), s_min, n_data, hessian_unit, log_prior_density: 0.0 }
    }

    /// A model from a variance stage's Gaussian approximation.
    pub fn from_gaussian(name: impl Into<String>, n_data: usize, gaussian: &GaussianApproximation) -> Self {
        Self::new(name, gaussian.cost, n_data, gaussian.hessian_unit.clone())
    }
}

/// One row of a [`ModelComparison`].
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ComparisonRow {
    /// Model name.
    pub name: String,
    /// Free parameters `k`.
    pub k: usize,
    /// Data points `N`.
    pub n_data: usize,
    /// Best cost.
    pub s_min: f64,
    /// [`aic`].
    pub aic: f64,
    /// [`bic`].
    pub bic: f64,
    /// [`laplace_log_evidence`].
    pub log_evidence: f64,
    /// AIC minus the smallest AIC (≥ 0; 0 for the preferred model).
    pub delta_aic: f64,
    /// BIC minus the smallest BIC.
    pub delta_bic: f64,
    /// `ln Z − ln Z_best` (≤ 0): the log Bayes factor of this model against the best.
    pub log_bayes_factor: f64,
    /// `Z / Z_best` (≤ 1).
    pub bayes_factor: f64,
    /// Posterior probability of the model with equal prior model probabilities.
    pub probability: f64,
}

/// Several models fitted to the same data, side by side (paper, eq. "bayes_model").
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ModelComparison {
    /// In the order given.
    pub rows: Vec<ComparisonRow>,
    /// Index of the model with the largest evidence.
    pub best: usize,
}

impl ModelComparison {
    /// Compares two or more models fitted to the same `N` data points.
    pub fn new(models: &[ModelFit]) -> Result<Self, ComparisonError> {
        if models.len() < 2 {
            return Err(ComparisonError::TooFewModels { count: models.len() });
        }
        let first = &models[0];
        let mut rows = Vec::with_capacity(models.len());
        for (i, m) in models.iter().enumerate() {
            if models[..i].iter().any(|o| o.name == m.name) {
                return Err(ComparisonError::DuplicateName { name: m.name.clone() });
            }
            if m.n_data != first.n_data {
                return Err(ComparisonError::DifferentData {
                    name: m.name.clone(),
                    n_data: m.n_data,
                    first: first.name.clone(),
                    expected: first.n_data,
                });
            }
            let log_evidence = laplace_log_evidence(m.s_min, &m.hessian_unit, m.log_prior_density)
                .map_err(|e| ComparisonError::InModel { name: m.name.clone(), error: Box::new(e) })?;
            let k = m.hessian_unit.len();
            rows.push(ComparisonRow {
                name: m.name.clone(),
                k,
                n_data: m.n_data,
                s_min: m.s_min,
                aic: aic(m.s_min, k),
                bic: bic(m.s_min, k, m.n_data),
                log_evidence,
                delta_aic: 0.0,
                delta_bic: 0.0,
                log_bayes_factor: 0.0,
                bayes_factor: 1.0,
                probability: 0.0,
            });
        }
        let min_aic = rows.iter().map(|r| r.aic).fold(f64::INFINITY, f64::min);
        let min_bic = rows.iter().map(|r| r.bic).fold(f64::INFINITY, f64::min);
        let best = (0..rows.len()).max_by(|&a, &b| rows[a].log_evidence.total_cmp(&rows[b].log_evidence)).unwrap_or(0);
        let max_lz = rows[best].log_evidence;
        let norm: f64 = rows.iter().map(|r| (r.log_evidence - max_lz).exp()).sum();
        for r in &mut rows {
            r.delta_aic = r.aic - min_aic;
            r.delta_bic = r.bic - min_bic;
            r.log_bayes_factor = r.log_evidence - max_lz;
            r.bayes_factor = r.log_bayes_factor.exp();
            r.probability = r.bayes_factor / norm;
        }
        Ok(Self { rows, best })
    }

    /// `ln (Z_a / Z_b)`, the log Bayes factor of model `a` against model `b` (by name).
    pub fn log_bayes_factor(&self, a: &str, b: &str) -> Option<f64> {
        let z = |n: &str| self.rows.iter().find(|r| r.name == n).map(|r| r.log_evidence);
        Some(z(a)? - z(b)?)
    }
}
