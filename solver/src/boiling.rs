//! The liquid-side boiling curve of the closure set at chosen conditions, for figures and
//! parameter studies: saturated liquid flowing at a given Reynolds number through a pipe whose
//! wall is held at each of a list of temperatures (the paper's boiling-surface figure).
//!
//! Pure: a fluid table and a parameter set in, heat fluxes out, through [`cryo::boiling_curve`].

use crate::cryo::{self, CorrelationSet, CryoParams, Local};
use crate::fluids::{FluidError, FluidTable, Phase};
use crate::model::GRAVITY;
use crate::params::ParameterSet;

/// Where the boiling curve is evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoilingConditions {
    /// Pressure, Pa (below the critical pressure).
    pub pressure_pa: f64,
    /// Liquid Reynolds number ρ_l v_l D / μ_l (0: pool boiling).
    pub reynolds_l: f64,
    /// Inner diameter of the pipe, m.
    pub diameter_m: f64,
}

/// One point of a boiling curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoilingPoint {
    /// Wall temperature, K.
    pub t_w: f64,
    /// Heat flux wall → liquid, W/m² of liquid-covered wall.
    pub q_w_m2: f64,
}

/// A boiling curve: the saturation temperature at the pressure and the points.
#[derive(Debug, Clone, PartialEq)]
pub struct BoilingCurve {
    /// Saturation temperature, K.
    pub t_sat_k: f64,
    /// The anchors (onset of nucleate boiling, critical heat flux, minimum film boiling).
    pub anchors: cryo::Anchors,
    /// One per requested wall temperature, in order.
    pub points: Vec<BoilingPoint>,
}

/// The boiling curve q(T_w) of saturated liquid (no vapour in the cell, liquid at T_sat) at
/// `c`, with the closure constants of `params` (registry defaults for the others) and the
/// film-boiling set `set`, at each wall temperature of `wall_temperatures`.
///
/// Errors: a pressure outside the saturation table, a non-finite or negative Reynolds number or
/// diameter (as [`FluidError::NoSaturation`] naming the quantity).
pub fn boiling_curve(
    fluid: &FluidTable,
    params: &ParameterSet,
    set: CorrelationSet,
    c: &BoilingConditions,
    wall_temperatures: &[f64],
) -> Result<BoilingCurve, FluidError> {
    let bad = |quantity: &'static str, value: f64, reason: &str| FluidError::NoSaturation {
        fluid: fluid.name().to_string(),
        quantity,
        value,
        reason: reason.to_string(),
    };
    if !(c.reynolds_l.is_finite() && c.reynolds_l >= 0.0) {
        return Err(bad("reynolds_l", c.reynolds_l, "give a finite Reynolds number ≥ 0"));
    }
    if !(c.diameter_m.is_finite() && c.diameter_m > 0.0) {
        return Err(bad("diameter_m", c.diameter_m, "give a positive diameter"));
    }
    let sat = fluid.saturation(c.pressure_pa)?;
    let t_sat = sat.t_sat;
    let liquid = fluid.phase_props(Phase::Liquid, c.pressure_pa, t_sat)?;
    // the gas table may stop a hair above the saturation line
    let gas = fluid
        .phase_props(Phase::Gas, c.pressure_pa, t_sat)
        .or_else(|_| fluid.phase_props(Phase::Gas, c.pressure_pa, t_sat + 0.5))?;
    let v_l = c.reynolds_l * liquid.mu / (liquid.rho * c.diameter_m);
    let base = Local {
        p: c.pressure_pa,
        t_w: t_sat,
        t_g: t_sat,
        t_l: t_sat,
        t_sat,
        alpha: 0.0,
        rho_g: sat.rho_g,
        rho_l: liquid.rho,
        mu_g: gas.mu,
        mu_l: liquid.mu,
        k_g: gas.k,
        k_l: liquid.k,
        cp_g: gas.cp,
        cp_l: liquid.cp,
        h_lg: sat.h_lg,
        sigma: sat.sigma,
        h_l: sat.h_l,
        h_g: sat.h_g,
        h_l_sat: sat.h_l,
        h_g_sat: sat.h_g,
        v_g: 0.0,
        v_l,
        d_h: c.diameter_m,
        gravity: GRAVITY,
        beta_g: -gas.drho_dt / gas.rho,
        beta_l: -liquid.drho_dt / liquid.rho,
        rho_l_sat: sat.rho_l,
        ..Local::default()
    }
    .with_boiling_basis(fluid);
    let p = CryoParams::from_set(params)
        .with_fluid(fluid.constants())
        .with_ideal_cp_over_r(crate::driver::ideal_cp_over_r(fluid));
    let anchors = cryo::boiling_anchors(&base, &p, set);
    let points = wall_temperatures
        .iter()
        .map(|&t_w| BoilingPoint {
            t_w,
            q_w_m2: cryo::boiling_curve(&Local { t_w, ..base }.with_boiling_basis(fluid), &p, set),
        })
        .collect();
    Ok(BoilingCurve { t_sat_k: t_sat, anchors, points })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(p_atm: f64, re: f64, params: &ParameterSet) -> BoilingCurve {
        let fluid = crate::fluids::embedded("nitrogen").unwrap();
        let c = BoilingConditions { pressure_pa: p_atm * 101_325.0, reynolds_l: re, diameter_m: 0.015875 };
        let t: Vec<f64> = (0..400).map(|k| 78.0 + k as f64 * 0.55).collect();
        boiling_curve(fluid, params, CorrelationSet::Paper, &c, &t).unwrap()
    }

    #[test]
    fn curve_has_the_boiling_shape_and_follows_its_anchors() {
        let b = curve(1.0, 1e4, &ParameterSet::new());
        assert!((b.t_sat_k - 77.35).abs() < 0.1, "{}", b.t_sat_k);
        let a = b.anchors;
        assert!(a.t_onb < a.t_chf && a.t_chf < a.t_mfb);
        // the maximum is the critical heat flux at T_chf, the curve dips to q_mfb at T_mfb
        let max = b.points.iter().map(|p| p.q_w_m2).fold(0.0, f64::max);
        assert!((max - a.q_chf).abs() <= 0.02 * a.q_chf, "max {max} vs q_chf {}", a.q_chf);
        let near_mfb =
            b.points.iter().min_by(|x, y| (x.t_w - a.t_mfb).abs().total_cmp(&(y.t_w - a.t_mfb).abs())).unwrap();
        assert!(near_mfb.q_w_m2 < a.q_chf);
        assert!(b.points.iter().all(|p| p.q_w_m2.is_finite()));
    }

    #[test]
    fn flow_and_pressure_move_the_curve_and_parameters_act() {
        let pool = curve(1.0, 0.0, &ParameterSet::new());
        let flow = curve(1.0, 1e5, &ParameterSet::new());
        assert!(flow.anchors.q_chf > pool.anchors.q_chf, "{} vs {}", flow.anchors.q_chf, pool.anchors.q_chf);
        let high = curve(7.0, 1e4, &ParameterSet::new());
        assert!(high.t_sat_k > pool.t_sat_k + 15.0);
        let mut scaled = ParameterSet::new();
        let default = crate::params::spec("qmfbsc").unwrap().default;
        scaled.set("qmfbsc", default * 1.5).unwrap();
        let b = curve(1.0, 1e4, &scaled);
        let base = curve(1.0, 1e4, &ParameterSet::new());
        assert!(b.points.last().unwrap().q_w_m2 > base.points.last().unwrap().q_w_m2);
    }

    #[test]
    fn bad_conditions_are_errors() {
        let fluid = crate::fluids::embedded("nitrogen").unwrap();
        let set = ParameterSet::new();
        let c = BoilingConditions { pressure_pa: 1e5, reynolds_l: -1.0, diameter_m: 0.01 };
        assert!(boiling_curve(fluid, &set, CorrelationSet::Paper, &c, &[80.0]).is_err());
        let c = BoilingConditions { pressure_pa: 1e9, reynolds_l: 1.0, diameter_m: 0.01 };
        assert!(boiling_curve(fluid, &set, CorrelationSet::Paper, &c, &[80.0]).is_err());
    }
}
