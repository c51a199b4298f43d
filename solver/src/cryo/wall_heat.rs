//! Wall heat transfer: the split of the wall heat between gas and liquid along the boiling
//! curve, and the drop–wall contact of dispersed flow.

use super::TINY;
use super::boiling::{BoilingCurve, WallRegime};
use super::convection::gas_convection_htc;
use super::parameters::{CorrelationSet, CryoParams};
use super::particles::{particle_diameter, relative_speed};
use super::regime::Regime;
use super::state::{Local, boiling_gravity, diameter, void};
use crate::closures::smooth_step;

/// Wall heat transfer at the old state: coefficients such that the heat flux from wall to gas is
/// h_wg (T_w − T_g) and to liquid h_wl (T_w − T_l), per unit of the WHOLE inner wall area (the
/// split of the perimeter between liquid-wetted and dry is already inside them, using `wetted`),
/// and the fraction of the liquid-side heat that generates vapour at the wall (0 in
/// single-phase convection, rising to 1 from onset of nucleate boiling on, smoothly).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallHeat {
    /// Wall → gas coefficient, W/(m² K) of the whole wall: (1 − wetted) h_gas (times the drops'
    /// enhancement in a mist).
    pub h_wg: f64,
    /// Wall → liquid coefficient, W/(m² K) of the whole wall: wetted q(T_w)/(T_w − T_l).
    pub h_wl: f64,
    /// Fraction of the wall → liquid heat that evaporates liquid at the wall (Γ_wg).
    pub boiling_fraction: f64,
    /// Critical heat flux, W/m².
    pub q_chf: f64,
    /// Wall temperature of the critical heat flux, K.
    pub t_chf: f64,
    /// Minimum film boiling (or rewet) temperature, K.
    pub t_mfb: f64,
    /// Onset of nucleate boiling, K.
    pub t_onb: f64,
    /// Regime: the branch of the boiling curve at `s.t_w`, or [`WallRegime::Dry`].
    pub regime: WallRegime,
}

/// Wall heat transfer at `s.t_w` with liquid-covered perimeter fraction `wetted`.
///
/// h_wl = wetted q(T_w)/(T_w − T_l) with q the [`boiling_curve`](super::boiling_curve) (in the
/// convective branch, wetted h_cb(T_w), no division); h_wg = (1 − wetted) [`gas_convection_htc`] times
/// the drops' [`drop_enhancement`] (1 unless `hg_drop_gain` is set). The boiling
/// fraction is the smooth step of (T_w − T_s)/(T_onb − T_s): 0 with the wall at or below
/// saturation, 1 from T_onb on (nucleate, transition and film boiling all evaporate liquid).
pub fn wall_heat(s: &Local, p: &CryoParams, set: CorrelationSet, wetted: f64, regime: &Regime) -> WallHeat {
    WallHeatBasis::new(s, p, set, regime).at(wetted)
}

/// The part of [`wall_heat`] that does not depend on the wetted fraction: the boiling curve at
/// the wall temperature, the dry wall's gas convection and the drops' contact, evaluated once
/// for a state whose wetted fraction is still to be set (the scheme's steps from one state
/// differ in their wetted fraction alone). [`WallHeatBasis::at`] gives the same numbers, to
/// the bit, as [`wall_heat`] at the same wetted fraction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallHeatBasis {
    /// The drops' contact coefficient times the regime's dryout weight, as its two factors
    /// (none with the wall at or below the liquid's temperature).
    drops: Option<(f64, f64)>,
    /// The liquid-covered wall's coefficient q(T_w)/(T_w − T_l) (h_cb(T_w) in the convective
    /// branch) and the branch.
    h_liquid: f64,
    branch: WallRegime,
    /// The dry wall's gas convection and the drops' enhancement of it.
    h_gas: f64,
    enhancement: f64,
    boiling_fraction: f64,
    q_chf: f64,
    t_chf: f64,
    t_mfb: f64,
    t_onb: f64,
}

impl WallHeatBasis {
    /// The wetted-fraction-free part of [`wall_heat`] at the state `s` in the flow `regime`.
    pub fn new(s: &Local, p: &CryoParams, set: CorrelationSet, regime: &Regime) -> Self {
        // drops of a dispersed flow that reach the dry part of the wall
        let drops = (s.t_w > s.t_l).then(|| (regime.dryout, drop_contact_htc(s, p)));
        let curve = BoilingCurve::new(s, p, set);
        let a = curve.anchors;
        let (h_liquid, branch) = if s.t_w <= a.t_onb {
            (curve.liquid.htc(s.t_w), WallRegime::Convection)
        } else {
            // T_w > T_onb ≥ T_l + 0.1 K here
            let (q, branch) = curve.at(s.t_w);
            (q / (s.t_w - s.t_l), branch)
        };
        Self {
            drops,
            h_liquid,
            branch,
            h_gas: gas_convection_htc(s, p, s.t_w),
            enhancement: drop_enhancement(s, p, regime),
            boiling_fraction: smooth_step((s.t_w - s.t_sat) / (a.t_onb - s.t_sat).max(1e-6)),
            q_chf: a.q_chf,
            t_chf: a.t_chf,
            t_mfb: a.t_mfb,
            t_onb: a.t_onb,
        }
    }

    /// [`wall_heat`] with liquid-covered perimeter fraction `wetted`.
    pub fn at(&self, wetted: f64) -> WallHeat {
        let w = if wetted.is_finite() { wetted.clamp(0.0, 1.0) } else { 0.0 };
        let h_drops = match self.drops {
            Some((dryout, contact)) => (1.0 - w) * dryout * contact,
            None => 0.0,
        };
        WallHeat {
            h_wg: (1.0 - w) * self.h_gas * self.enhancement,
            h_wl: w * self.h_liquid + h_drops,
            boiling_fraction: self.boiling_fraction,
            q_chf: self.q_chf,
            t_chf: self.t_chf,
            t_mfb: self.t_mfb,
            t_onb: self.t_onb,
            regime: if w < 1e-3 { WallRegime::Dry } else { self.branch },
        }
    }
}

/// Factor on the vapour's convection to the dry wall from the drops it carries in the dispersed
/// (mist) regime: 1 + E w_dry ε/(ε + ε₀), ε = 1 − α the liquid fraction, w_dry the regime's
/// dryout/mist weight, E = `hg_drop_gain`, ε₀ = `hg_drop_eps`; exactly 1 where E = 0 (the default)
/// or no liquid is present.
///
/// Not in the paper, and not a published correlation: a hypothesis put to the data. The drops
/// of a dispersed flow cool the vapour near the wall and stir its boundary layer, so a
/// drop-laden vapour takes more heat from a dry wall than the single-phase Dittus–Boelter
/// coefficient gives (the enhancement dispersed-flow film boiling models carry). The NBS runs
/// ask for it at their first station: there the model's vapour, a mist of void fraction
/// 0.97–0.999, runs 40–60 K below the wall, and the first station chills 48–57 % late in the
/// hydrogen runs with the six-run parameters, where the data's wall cools at 5–10 K/s
/// (VALIDATION.md, "The first station's vapour"). The saturating form in ε keeps the far line's
/// nearly dry vapour at its single-phase coefficient. Fitted to the six runs
/// (`examples/nbs/calibrate-six-drops.toml`: gain 2.9, ε₀ 8.5e-4) it hastens the nitrogen runs,
/// whose mist reaches further down the line, more than the hydrogen runs' first station; it stays
/// off by default until cross-validation has judged it.
pub fn drop_enhancement(s: &Local, p: &CryoParams, regime: &Regime) -> f64 {
    let e = p.gas_wall_drop_gain;
    if e <= 0.0 {
        return 1.0;
    }
    let liquid = (1.0 - void(s)).clamp(0.0, 1.0);
    let eps0 = p.gas_wall_drop_fraction.max(TINY);
    1.0 + e * regime.dryout.clamp(0.0, 1.0) * liquid / (liquid + eps0)
}

/// Drop–wall contact heat transfer of dispersed-flow film boiling, W/(m² K) of wall, for the
/// flux h (T_w − T_sat) that the drops of a mist take from the dry wall and evaporate with:
/// Forslund and Rohsenow's coefficient as RELAP5 and TRACE use it above the critical heat flux,
/// h = K (1 − α)^(2/3) [g ρ_l,sat ρ_g h_lg κ_g³ / ((T_w − T_sat) μ_g d_d)]^(1/4), with K
/// `drop_contact_k` (0.2552 in the source form), the vapour properties at the film temperature
/// ([`Local::vap_film`]), d_d the drop diameter of the interface closure and g at least the
/// boiling correlations' floor. The scheme applies it on the dry share of the perimeter in the
/// dryout/mist regime; its heat goes to the liquid, which it evaporates. Decision: the heat is
/// driven by T_w − T_l, the liquid-side difference of the scheme's linearisation, rather than
/// the source's T_w − T_sat: the drops of a mist are at saturation to within a kelvin, and the
/// ratio (T_w − T_sat)/(T_w − T_l) that converts one into the other grows without bound where
/// a superheated liquid meets a wall at its own temperature (a 10-cell subcooled run failed on
/// it with a pressure of −10¹⁴ Pa).
pub fn drop_contact_htc(s: &Local, p: &CryoParams) -> f64 {
    let dt_w = s.t_w - s.t_sat;
    let beta = 1.0 - void(s);
    if !(dt_w > 0.0 && beta > 0.0 && s.h_lg > 0.0 && p.drop_contact_k > 0.0) {
        return 0.0;
    }
    let v = &s.vap_film;
    let d_d = particle_diameter(s.sigma, s.rho_g, relative_speed(s), diameter(s), p.drop_diameter_max);
    let group = boiling_gravity(s) * s.rho_l_sat * v.rho * s.h_lg * v.k.powi(3) / (dt_w * v.mu * d_d).max(TINY);
    let h = p.drop_contact_k * beta.powf(2.0 / 3.0) * group.max(0.0).powf(0.25);
    if h.is_finite() { h } else { 0.0 }
}
