//! The cost: the paper's weighted sum of squares (eq. "cost"), generalised to several
//! quantities, stations and experiments.
//!
//! For each measured series (station, quantity) that carries a weight,
//! `S = Σ_t η_q ((y_model(t) − y_data(t)) / σ_q)²`, the model output interpolated linearly to the
//! data times and stations matched by name. With σ_q the measurement noise and η_q = 1, `S/2` is
//! the negative log-likelihood of independent Gaussian errors (up to a constant).

use std::collections::BTreeMap;

use crate::data::{Dataset, Series, SeriesKey};

/// Weight η and noise σ of one quantity.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize), serde(deny_unknown_fields))]
pub struct Weight {
    /// η: relative weight (dimensionless, ≥ 0).
    #[cfg_attr(feature = "serde", serde(default = "one"))]
    pub weight: f64,
    /// σ: measurement noise in the quantity's unit (> 0).
    pub sigma: f64,
}

#[cfg(feature = "serde")]
fn one() -> f64 {
    1.0
}

/// Noise assumed for a quantity when the calibration gives no weights: 1 K for temperatures,
/// 1 kPa for pressure, 0.05 for void fraction, 5 % of typical values for the others.
pub fn default_sigma(quantity: &str) -> f64 {
    match quantity {
        q if q.ends_with("temperature_k") => 1.0,
        "pressure_pa" => 1000.0,
        "void_fraction" => 0.05,
        "gas_velocity_m_s" | "liquid_velocity_m_s" => 0.5,
        "wall_heat_flux_w_m2" => 1000.0,
        "mass_flow_kg_s" => 0.005,
        _ => 1.0,
    }
}

/// Weights per quantity. Empty means: every quantity present in the data, weight 1 and
/// [`default_sigma`]; otherwise only the listed quantities count.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Weights(pub BTreeMap<String, Weight>);

impl Weights {
    /// The weight of `quantity`, or `None` when it does not enter the cost.
    pub fn get(&self, quantity: &str) -> Option<Weight> {
        if self.0.is_empty() {
            Some(Weight { weight: 1.0, sigma: default_sigma(quantity) })
        } else {
            self.0.get(quantity).copied()
        }
    }

    /// Checks every weight: η finite and ≥ 0, σ finite and > 0.
    pub fn validate(&self) -> Result<(), WeightError> {
        for (q, w) in &self.0 {
            if !(w.weight.is_finite() && w.weight >= 0.0) {
                return Err(WeightError::Weight { quantity: q.clone(), value: w.weight });
            }
            if !(w.sigma.is_finite() && w.sigma > 0.0) {
                return Err(WeightError::Sigma { quantity: q.clone(), value: w.sigma });
            }
        }
        Ok(())
    }
}

/// A weight that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum WeightError {
    /// η is negative or not a number.
    #[error("weights.{quantity}.weight = {value}: must be a finite number ≥ 0")]
    Weight {
        /// The weighted quantity.
        quantity: String,
        /// The η given.
        value: f64,
    },
    /// σ is not positive or not a number.
    #[error("weights.{quantity}.sigma = {value}: must be a finite number > 0")]
    Sigma {
        /// The weighted quantity.
        quantity: String,
        /// The σ given.
        value: f64,
    },
}

impl WeightError {
    /// The field at fault (`weights.<quantity>.weight` or `.sigma`).
    pub fn field(&self) -> String {
        match self {
            Self::Weight { quantity, .. } => format!("weights.{quantity}.weight"),
            Self::Sigma { quantity, .. } => format!("weights.{quantity}.sigma"),
        }
    }
}

/// Why a model output cannot be compared with the data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// The data have a series (station, quantity) that the model output lacks.
    #[error("the model output has no {quantity} at station `{station}`")]
    MissingSeries {
        /// Station name.
        station: String,
        /// Quantity.
        quantity: String,
    },
    /// A data time lies outside the model output's time range.
    #[error("station `{station}`, {quantity}: the model output covers {from_s}–{to_s} s, not the data time {time_s} s")]
    NotCovered {
        /// Station name.
        station: String,
        /// Quantity.
        quantity: String,
        /// First time of the model series, s.
        from_s: f64,
        /// Last time of the model series, s.
        to_s: f64,
        /// The data time, s.
        time_s: f64,
    },
    /// The model value (or its difference from the data) at a data time is not a finite number.
    #[error("station `{station}`, {quantity}: the model value at {time_s} s is not finite")]
    NotFinite {
        /// Station name.
        station: String,
        /// Quantity.
        quantity: String,
        /// The data time, s.
        time_s: f64,
    },
}

/// Per-series contribution to the cost.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesFit {
    /// Weighted sum of squares of this series.
    pub cost: f64,
    /// Root-mean-square difference model − data, in the quantity's unit.
    pub rms: f64,
    /// Number of data points.
    pub points: usize,
}

/// The cost of one model output against one dataset, with its parts.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub cost: f64,
    pub series: BTreeMap<SeriesKey, SeriesFit>,
}

/// Cost of `model` output against `data`. Errors name the station/quantity the model lacks or
/// the data time it does not cover.
pub fn fit(model: &Dataset, data: &Dataset, weights: &Weights) -> Result<Fit, FitError> {
    let mut total = 0.0;
    let mut series = BTreeMap::new();
    for (key, d) in &data.series {
        let Some(w) = weights.get(&key.1) else { continue };
        let (station, quantity) = (&key.0, &key.1);
        let m = model
            .series
            .get(key)
            .ok_or_else(|| FitError::MissingSeries { station: station.clone(), quantity: quantity.clone() })?;
        let mut sum = 0.0;
        let mut sq = 0.0;
        for (&t, &y) in d.times.iter().zip(&d.values) {
            let ym = m.at(t).ok_or_else(|| FitError::NotCovered {
                station: station.clone(),
                quantity: quantity.clone(),
                from_s: m.times.first().copied().unwrap_or(0.0),
                to_s: m.times.last().copied().unwrap_or(0.0),
                time_s: t,
            })?;
            let r = ym - y;
            if !r.is_finite() {
                return Err(FitError::NotFinite { station: station.clone(), quantity: quantity.clone(), time_s: t });
            }
            sq += r * r;
            sum += w.weight * (r / w.sigma) * (r / w.sigma);
        }
        let n = d.times.len();
        total += sum;
        series.insert(key.clone(), SeriesFit { cost: sum, rms: (sq / n.max(1) as f64).sqrt(), points: n });
    }
    Ok(Fit { cost: total, series })
}

/// RMS of data − model with the model's clock scaled by `ratio`: the data at `t` against the model
/// at `ratio · t` (held at the model's first or last value outside its time range). `None` for
/// an empty series or a ratio that is not a positive number.
pub fn time_scaled_rms(model: &Series, data: &Series, ratio: f64) -> Option<f64> {
    let (&first, &last) = (model.times.first()?, model.times.last()?);
    if data.times.is_empty() || !(ratio.is_finite() && ratio > 0.0) {
        return None;
    }
    let mut sq = 0.0;
    for (&t, &y) in data.times.iter().zip(&data.values) {
        let r = model.at((ratio * t).clamp(first, last))? - y;
        sq += r * r;
    }
    Some((sq / data.times.len() as f64).sqrt())
}

/// Largest clock error [`best_time_scale`] considers, in the log of the factor (0.5–2).
pub const MAX_LOG_TIME_SCALE: f64 = 0.7;

/// Resolution of [`best_time_scale`]'s search, in the log of the factor.
const LOG_TIME_SCALE_STEP: f64 = 0.005;

/// The clock factor `r` (within e^{±[`MAX_LOG_TIME_SCALE`]}) that best aligns the model with the
/// data — the least [`time_scaled_rms`] — and that RMS: the misfit left once the model's front
/// runs on the data's time, the error of the curve's shape apart from its timing.
///
/// Searched on a grid of ln r in steps of 0.005 outward from r = 1, a factor farther out taken
/// only where it lowers the RMS by more than a relative 1e-9: a series the clock does not change
/// (a station that stays warm) keeps r = 1. Decision: the best alignment, not the ratio of the
/// chilldown times — a model whose front is shaped otherwise than the measured one (a long
/// precooling ramp where the data hold warm and then plunge) matches the crossing at the ratio
/// and misses the rest by more than it does unscaled (hydrogen subcooled 4.2 atm, station 4:
/// 79 K against 28 K), which would call a shape error a clock error and count it twice.
pub fn best_time_scale(model: &Series, data: &Series) -> Option<(f64, f64)> {
    let mut best = (1.0, time_scaled_rms(model, data, 1.0)?);
    let steps = (MAX_LOG_TIME_SCALE / LOG_TIME_SCALE_STEP).round() as i32;
    for k in 1..=steps {
        for sign in [1.0, -1.0] {
            let r = (sign * k as f64 * LOG_TIME_SCALE_STEP).exp();
            if let Some(rms) = time_scaled_rms(model, data, r)
                && rms < best.1 * (1.0 - 1e-9)
            {
                best = (r, rms);
            }
        }
    }
    Some(best)
}

/// Number of data points that enter the cost.
pub fn counted_points(data: &Dataset, weights: &Weights) -> usize {
    data.series.iter().filter(|(k, _)| weights.get(&k.1).is_some()).map(|(_, s)| s.times.len()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ds(points: &[(f64, f64)]) -> Dataset {
        let mut d = Dataset::default();
        d.series.insert(
            ("TS1".into(), "wall_temperature_k".into()),
            Series {
                x_m: 1.0,
                times: points.iter().map(|p| p.0).collect(),
                values: points.iter().map(|p| p.1).collect(),
            },
        );
        d
    }

    #[test]
    fn weighted_sum_of_squares_at_interpolated_times() {
        let model = ds(&[(0.0, 300.0), (10.0, 200.0)]);
        let data = ds(&[(0.0, 301.0), (5.0, 248.0)]);
        let w = Weights([("wall_temperature_k".to_string(), Weight { weight: 2.0, sigma: 0.5 })].into());
        let f = fit(&model, &data, &w).unwrap();
        // residuals −1 and +2, σ = 0.5, η = 2: 2 (4 + 16) = 40
        assert!((f.cost - 40.0).abs() < 1e-12);
        let s = f.series.values().next().unwrap();
        assert!((s.rms - (2.5f64).sqrt()).abs() < 1e-12 && s.points == 2);
        // unlisted quantity: ignored
        let w2 = Weights([("pressure_pa".to_string(), Weight { weight: 1.0, sigma: 1.0 })].into());
        assert_eq!(fit(&model, &data, &w2).unwrap().cost, 0.0);
        // empty weights: defaults (σ = 1 K)
        assert!((fit(&model, &data, &Weights::default()).unwrap().cost - 5.0).abs() < 1e-12);
    }

    #[test]
    fn missing_station_or_time_is_an_error() {
        let model = ds(&[(0.0, 300.0), (4.0, 200.0)]);
        let data = ds(&[(5.0, 248.0)]);
        let e = fit(&model, &data, &Weights::default()).unwrap_err();
        assert!(matches!(e, FitError::NotCovered { time_s: 5.0, to_s: 4.0, .. }), "{e:?}");
        assert!(e.to_string().contains("not the data time 5"), "{e}");
        let mut other = Dataset::default();
        other.series.insert(("TS9".into(), "wall_temperature_k".into()), data.series.values().next().unwrap().clone());
        let e = fit(&model, &other, &Weights::default()).unwrap_err();
        assert!(matches!(&e, FitError::MissingSeries { station, .. } if station == "TS9"), "{e:?}");
        assert!(e.to_string().contains("station `TS9`"), "{e}");
    }

    #[test]
    fn a_late_front_scaled_back_in_time_fits_exactly() {
        // the model's front (a ramp from 300 to 100 K) starts at 1.5 times the data's time and lasts 1.5 times as long
        let ramp = |t0: f64, width: f64| -> Series {
            let times: Vec<f64> = (0..=400).map(|k| k as f64 * 0.5).collect();
            let values = times.iter().map(|&t| (300.0 - 200.0 * (t - t0) / width).clamp(100.0, 300.0)).collect();
            Series { x_m: 1.0, times, values }
        };
        let (model, data) = (ramp(75.0, 15.0), ramp(50.0, 10.0));
        assert!(time_scaled_rms(&model, &data, 1.0).unwrap() > 50.0);
        // data at t against the model at 1.5 t: the same curve (up to the model's sampling)
        assert!(time_scaled_rms(&model, &data, 1.5).unwrap() < 1e-9);
        assert_eq!(time_scaled_rms(&model, &data, 0.0), None);
        assert_eq!(time_scaled_rms(&model, &data, f64::NAN), None);
        // the search finds the factor to its grid (ln 1.5 = 0.4055 lies between 0.405 and 0.41)
        let (r, rms) = best_time_scale(&model, &data).unwrap();
        assert!((r.ln() - 1.5f64.ln()).abs() <= 0.0026, "{r}");
        assert!(rms < 5.0, "{rms}");
        // and never does worse than the model's own clock; a flat series keeps it
        let flat = ramp(500.0, 10.0);
        assert_eq!(best_time_scale(&flat, &flat.clone()), Some((1.0, 0.0)));
        let (_, rms) = best_time_scale(&flat, &data).unwrap();
        assert!(rms <= time_scaled_rms(&flat, &data, 1.0).unwrap());
    }
}
