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

/// Speed of sound of a two-phase mixture whose phases are saturated and change phase as it
/// expands, m/s: between Wood's (no phase change, each phase at its own state) and the
/// homogeneous equilibrium speed (the phases along their saturation line, exchanging mass),
/// by the share `equilibrium` ∈ [0, 1] (how near both phases are to saturation) times Henry and
/// Fauske's factor N.
///
/// Per unit mass, with the static quality x and v = x v_g + (1 − x) v_l, the mixture's
/// compliance −dv/dp is Wood's, F = x v_g²/c_g² + (1 − x) v_l²/c_l²
/// ([`frozen_mixture_sound_speed`] written per unit mass), plus equilibrium · N · (E − F), E the
/// equilibrium one: along an isentrope dh = v dp, so that the equilibrium quality changes as
/// dx_E/dp = (v − h_l' − x h_lg')/h_lg and E = −[x v_g' + (1 − x) v_l' + (v_g − v_l) dx_E/dp]
/// (primes: derivatives along the saturation line). c = v/√(−dv/dp). Only a phase change that
/// adds to the compliance is counted (E > F).
///
/// Decision: N = min(1, x/0.14), Henry and Fauske's factor (J. Heat Transfer 93, 1971) for the
/// part of the equilibrium phase change a discharge at low quality completes in its throat.
/// Without it (N = 1) the nitrogen mixture at the NBS line's exit after its chilldown (x ≈ 0.02,
/// 1 bar) had c ≈ 15 m/s, below its vapour's 20 m/s: the exit choked for the rest of the
/// saturated runs (700 of the 2.5 atm run's 1000 s) and the subcooled run, choking and
/// unchoking, took 28 times its steps. `None` where a phase's speed is not defined.
pub fn flashing_mixture_sound_speed(
    alpha: f64,
    gas: &PhaseProps,
    liquid: &PhaseProps,
    sat: &Saturation,
    equilibrium: f64,
) -> Option<f64> {
    let a = alpha.clamp(0.0, 1.0);
    let (c_g, c_l) = (gas.sound_speed()?, liquid.sound_speed()?);
    let (m_g, m_l) = (a * gas.rho, (1.0 - a) * liquid.rho);
    let x = m_g / (m_g + m_l);
    let (v_g, v_l) = (1.0 / gas.rho, 1.0 / liquid.rho);
    let v = x * v_g + (1.0 - x) * v_l;
    let frozen = x * (v_g / c_g).powi(2) + (1.0 - x) * (v_l / c_l).powi(2);
    let share = equilibrium.clamp(0.0, 1.0) * (x / HENRY_FAUSKE_QUALITY).min(1.0);
    let mut compliance = frozen;
    if share > 0.0 && sat.h_lg > 0.0 && sat.rho_g > 0.0 && sat.rho_l > 0.0 {
        let (vs_g, vs_l) = (1.0 / sat.rho_g, 1.0 / sat.rho_l);
        let (dv_g, dv_l) = (-sat.drho_g_dp * vs_g * vs_g, -sat.drho_l_dp * vs_l * vs_l);
        let vs = x * vs_g + (1.0 - x) * vs_l;
        let dx_dp = (vs - sat.dh_l_dp - x * (sat.dh_g_dp - sat.dh_l_dp)) / sat.h_lg;
        let equilibrium_compliance = -(x * dv_g + (1.0 - x) * dv_l + (vs_g - vs_l) * dx_dp);
        compliance += share * (equilibrium_compliance - frozen).max(0.0);
    }
    let c = v / compliance.sqrt();
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

    /// Saturated nitrogen at `p`, each phase 0.01 K off saturation.
    fn saturated_n2(p: f64) -> (crate::fluids::PhaseProps, crate::fluids::PhaseProps, crate::fluids::Saturation) {
        let n2 = embedded("nitrogen").unwrap();
        let sat = n2.saturation(p).unwrap();
        let gas = n2.phase_props(Phase::Gas, p, sat.t_sat + 0.01).unwrap();
        let liquid = n2.phase_props(Phase::Liquid, p, sat.t_sat - 0.01).unwrap();
        (gas, liquid, sat)
    }

    /// Out of equilibrium the flashing speed is Wood's; in equilibrium, at qualities where Henry
    /// and Fauske's factor is 1, it is the equilibrium isentrope's on the table (dh = v dp, the
    /// quality from the enthalpy at a pressure 0.01 % lower).
    #[test]
    fn flashing_speed_spans_frozen_and_equilibrium() {
        let p = 2.0e5;
        let (gas, liquid, sat) = saturated_n2(p);
        let n2 = embedded("nitrogen").unwrap();
        for alpha in [0.5, 0.9, 0.95, 0.99] {
            let wood = super::frozen_mixture_sound_speed(alpha, &gas, &liquid).unwrap();
            let none = super::flashing_mixture_sound_speed(alpha, &gas, &liquid, &sat, 0.0).unwrap();
            assert!((none - wood).abs() < 1e-9 * wood, "α = {alpha}: {none} against Wood's {wood} m/s");
            let full = super::flashing_mixture_sound_speed(alpha, &gas, &liquid, &sat, 1.0).unwrap();
            let half = super::flashing_mixture_sound_speed(alpha, &gas, &liquid, &sat, 0.5).unwrap();
            assert!(full < half && half < wood, "α = {alpha}: {full} < {half} < {wood} m/s");
            let (m_g, m_l) = (alpha * gas.rho, (1.0 - alpha) * liquid.rho);
            let x = m_g / (m_g + m_l);
            if x < super::HENRY_FAUSKE_QUALITY {
                continue;
            }
            // the equilibrium isentrope on the table across a finite step
            let v = x / sat.rho_g + (1.0 - x) / sat.rho_l;
            let h = sat.h_l + x * sat.h_lg;
            let dp = -1e-4 * p;
            let s2 = n2.saturation(p + dp).unwrap();
            let x2 = (h + v * dp - s2.h_l) / s2.h_lg;
            let v2 = x2 / s2.rho_g + (1.0 - x2) / s2.rho_l;
            let expected = v * (dp / (v - v2)).sqrt();
            assert!((full - expected).abs() < 0.01 * expected, "α = {alpha}: {full} against {expected} m/s");
        }
    }

    /// Below Henry and Fauske's quality only part of the phase change counts; nitrogen's mist
    /// at the NBS line's exit (x ≈ 0.02, 1 bar) leaves at 20–35 m/s, and the speed is continuous
    /// where the factor reaches 1.
    #[test]
    fn a_low_quality_discharge_flashes_only_in_part() {
        let (gas, liquid, sat) = saturated_n2(1.0e5);
        let alpha_of = |x: f64| (x / gas.rho) / (x / gas.rho + (1.0 - x) / liquid.rho);
        let c = |x: f64| super::flashing_mixture_sound_speed(alpha_of(x), &gas, &liquid, &sat, 1.0).unwrap();
        assert!(c(0.02) > 20.0 && c(0.02) < 35.0, "x = 0.02: {} m/s", c(0.02));
        let q = super::HENRY_FAUSKE_QUALITY;
        assert!((c(q - 1e-9) - c(q + 1e-9)).abs() < 1e-6 * c(q), "continuous where the factor reaches 1");
    }
}
