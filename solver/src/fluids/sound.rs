//! Speeds of sound: a phase's own from its `(p, T)` derivatives, and a two-phase mixture's
//! without phase change. The scheme's choking criterion (`crate::scheme`) compares the
//! outflow with them.

use super::table::PhaseProps;

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
}
