//! Speeds of sound: a phase's own from its `(p, T)` derivatives, and a two-phase mixture's
//! without phase change. The scheme's choking criterion (`crate::scheme`) compares the
//! outflow with them.

use super::table::{PhaseProps, Saturation};

impl PhaseProps {
    /// Isentropic speed of sound of the phase, m/s: c² = (∂p/∂ρ)_s with
    /// (∂ρ/∂p)_s = ∂ρ/∂p|_T + ∂ρ/∂T|_p (1/ρ − ∂h/∂p|_T)/(∂h/∂T|_p), from dh = dp/ρ at constant
    /// entropy. `None` where the derivatives do not give a positive compressibility.
    pub fn sound_speed(&self) -> Option<f64> {
        if !(self.rho > 0.0 && self.dh_dt > 0.0) {
            return None;
        }
        let drho_dp_s = self.drho_dp + self.drho_dt * (1.0 / self.rho - self.dh_dp) / self.dh_dt;
        (drho_dp_s > 0.0 && drho_dp_s.is_finite()).then(|| 1.0 / drho_dp_s.sqrt())
    }
}

/// Speed of sound of a two-phase mixture without phase change or slip between its phases
/// (Wood's), m/s: 1/(ρ_m c²) = α/(ρ_g c_g²) + (1 − α)/(ρ_l c_l²), ρ_m = α ρ_g + (1 − α) ρ_l,
/// each phase at its own state. It tends to each phase's own speed as the other vanishes and
/// falls far below both between (tens of m/s for a nitrogen mist of a few per cent liquid by
/// volume). `None` where a phase's speed is not defined.
pub fn frozen_mixture_sound_speed(alpha: f64, gas: &PhaseProps, liquid: &PhaseProps) -> Option<f64> {
    let a = alpha.clamp(0.0, 1.0);
    let (c_g, c_l) = (gas.sound_speed()?, liquid.sound_speed()?);
    let compliance = a / (gas.rho * c_g * c_g) + (1.0 - a) / (liquid.rho * c_l * c_l);
    let rho_m = a * gas.rho + (1.0 - a) * liquid.rho;
    let c = 1.0 / (rho_m * compliance).sqrt();
    (c.is_finite() && c > 0.0).then_some(c)
}

/// Speed of sound of a flashing two-phase mixture, m/s, at static quality `x`: the homogeneous
/// equilibrium speed with Henry and Fauske's nonequilibrium factor on the phase change.
///
/// Along an isentrope dh = v dp, so that the equilibrium quality changes as
/// dx_E/dp = (v − h_l' − x h_lg')/h_lg (primes: derivatives along the saturation line), and
/// dv/dp = x v_g' + (1 − x) v_l' + (v_g − v_l) N dx_E/dp, c = v/√(−dv/dp).
///
/// Decision: N = min(1, x/0.14), Henry and Fauske's factor (J. Heat Transfer 93, 1971) for the
/// part of the equilibrium phase change a discharge at low quality completes in its throat; with
/// N = 1 (homogeneous equilibrium) the nitrogen mixture at the NBS line's exit after its
/// chilldown (x ≈ 0.02, 1 bar) has c ≈ 15 m/s, below its vapour's 20 m/s: the exit choked for the
/// rest of the saturated runs (700 of the 2.5 atm run's 1000 s) and the subcooled run, choking
/// and unchoking, took 28 times its steps; with the factor c ≈ 24 m/s and the runs keep their
/// steps. `None` where the saturation line does not give a positive compressibility.
pub fn flashing_mixture_sound_speed(x: f64, sat: &Saturation) -> Option<f64> {
    if !(sat.rho_l > 0.0 && sat.rho_g > 0.0 && sat.h_lg > 0.0) {
        return None;
    }
    let x = x.clamp(0.0, 1.0);
    let (v_l, v_g) = (1.0 / sat.rho_l, 1.0 / sat.rho_g);
    let (dv_l, dv_g) = (-sat.drho_l_dp * v_l * v_l, -sat.drho_g_dp * v_g * v_g);
    let v = x * v_g + (1.0 - x) * v_l;
    let dx_dp = (v - sat.dh_l_dp - x * (sat.dh_g_dp - sat.dh_l_dp)) / sat.h_lg;
    let n = (x / HENRY_FAUSKE_QUALITY).min(1.0);
    let dv_dp = x * dv_g + (1.0 - x) * dv_l + n * (v_g - v_l) * dx_dp;
    let c = v / (-dv_dp).sqrt();
    (c.is_finite() && c > 0.0).then_some(c)
}

/// The equilibrium quality from which Henry and Fauske take a discharge's phase change as
/// complete ([`flashing_mixture_sound_speed`]).
pub const HENRY_FAUSKE_QUALITY: f64 = 0.14;

#[cfg(test)]
mod tests {
    use crate::fluids::{Phase, embedded};

    /// Nitrogen gas at 1 atm and 300 K: close to the ideal gas's √(γ R T) = 353 m/s (NIST
    /// gives 353.1 m/s).
    #[test]
    fn nitrogen_gas_sound_speed() {
        let n2 = embedded("nitrogen").unwrap();
        let c = n2.phase_props(Phase::Gas, 101_325.0, 300.0).unwrap().sound_speed().unwrap();
        assert!((c - 353.1).abs() < 2.0, "c = {c} m/s");
    }

    /// Saturated liquid nitrogen at 1 atm: about 853 m/s (NIST, 77.36 K).
    #[test]
    fn nitrogen_liquid_sound_speed() {
        let n2 = embedded("nitrogen").unwrap();
        let t = n2.saturation(101_325.0).unwrap().t_sat;
        let c = n2.phase_props(Phase::Liquid, 101_325.0, t - 0.01).unwrap().sound_speed().unwrap();
        assert!((c - 853.0).abs() < 15.0, "c = {c} m/s");
    }

    /// The mixture's speed tends to each phase's own as the other vanishes and dips far below
    /// both between.
    #[test]
    fn mixture_sound_speed_spans_the_phases() {
        let n2 = embedded("nitrogen").unwrap();
        let t = n2.saturation(101_325.0).unwrap().t_sat;
        let gas = n2.phase_props(Phase::Gas, 101_325.0, t + 0.01).unwrap();
        let liquid = n2.phase_props(Phase::Liquid, 101_325.0, t - 0.01).unwrap();
        let (c_g, c_l) = (gas.sound_speed().unwrap(), liquid.sound_speed().unwrap());
        let c = |a: f64| super::frozen_mixture_sound_speed(a, &gas, &liquid).unwrap();
        assert!((c(1.0) - c_g).abs() < 1e-9 * c_g && (c(0.0) - c_l).abs() < 1e-9 * c_l);
        assert!((c(1.0 - 1e-12) - c_g).abs() < 1e-3, "a trace of liquid leaves the gas's speed");
        let mid = c(0.95);
        assert!(mid > 10.0 && mid < 0.5 * c_g, "α = 0.95: {mid} m/s against the gas's {c_g} m/s");
    }

    /// The flashing speed from the saturation line's derivatives against the same isentrope
    /// taken across a finite pressure step on the table (dh = v dp, the quality from the enthalpy
    /// at the new pressure), at qualities where Henry and Fauske's factor is 1.
    #[test]
    fn flashing_speed_follows_the_isentrope_on_the_table() {
        for (fluid, p) in [("nitrogen", 2.0e5), ("parahydrogen", 2.1e5), ("methane", 3.0e5)] {
            let table = embedded(fluid).unwrap();
            let sat = table.saturation(p).unwrap();
            for x in [0.2, 0.5, 0.9] {
                let c = super::flashing_mixture_sound_speed(x, &sat).unwrap();
                let v = x / sat.rho_g + (1.0 - x) / sat.rho_l;
                let h = sat.h_l + x * sat.h_lg;
                let dp = -1e-4 * p;
                let s2 = table.saturation(p + dp).unwrap();
                let x2 = (h + v * dp - s2.h_l) / s2.h_lg;
                let v2 = x2 / s2.rho_g + (1.0 - x2) / s2.rho_l;
                let c_fd = v * (dp / (v - v2)).sqrt();
                assert!((c - c_fd).abs() < 0.01 * c_fd, "{fluid} x = {x}: {c} against {c_fd} m/s");
            }
        }
    }

    /// Below Henry and Fauske's quality the phase change lags, down to none as the quality
    /// vanishes; nitrogen's mist at the NBS line's exit (x = 0.02, 1 bar) leaves at 20–30 m/s.
    #[test]
    fn a_low_quality_discharge_flashes_only_in_part() {
        let n2 = embedded("nitrogen").unwrap();
        let sat = n2.saturation(1.0e5).unwrap();
        let c = |x: f64| super::flashing_mixture_sound_speed(x, &sat).unwrap();
        assert!(c(0.02) > 20.0 && c(0.02) < 30.0, "x = 0.02: {} m/s", c(0.02));
        let q = super::HENRY_FAUSKE_QUALITY;
        assert!((c(q - 1e-9) - c(q + 1e-9)).abs() < 1e-6 * c(q), "continuous where the factor reaches 1");
        // the saturated liquid expands as its saturation pressure rises: with no phase change
        // left to make up for it there is no speed
        assert!(super::flashing_mixture_sound_speed(0.0, &sat).is_none());
    }
}
