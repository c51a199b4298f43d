//! Small closures shared by the scheme and the cryogenic closure set ([`crate::cryo`]): Churchill's
//! friction factor and the smooth step of phase blending. Each is a pure function.

use crate::fastmath;

/// Darcy friction factor from Churchill's (1977) correlation, valid for laminar, transitional
/// and turbulent flow.
///
/// f_D = 8 [ (8/Re)^12 + (A + B)^(−3/2) ]^(1/12),
/// A = [2.457 ln(1 / ((7/Re)^0.9 + 0.27 ε/D))]^16, B = (37530/Re)^16.
/// (The paper prints 2.475 for Churchill's 2.457, and writes the Fanning form 2[…]^(1/12) = f_D/4.)
///
/// Evaluated without `powf`: (7/Re)^0.9 = exp(0.9 ln(7/Re)) (and, smooth pipe, ln(1/(7/Re)^0.9)
/// = −0.9 ln(7/Re) without the exponential), x^−3/2 = 1/(x √x), x^(1/12) = ∛√√x; no logarithm
/// at all deep in the laminar range.
pub fn churchill_darcy(re: f64, relative_roughness: f64) -> f64 {
    let re = re.max(1e-3);
    let laminar = (8.0 / re).powi(12);
    let b = (37530.0 / re).powi(16);
    // Deep in the laminar range (Re ≲ 700), (A + B)^−3/2 ≤ B^−3/2 is below a tenth of an ulp of
    // (8/Re)^12 for any A ≥ 0, so the sum is (8/Re)^12 and A is not needed.
    if relative_roughness >= 0.0 && 1.0 / (b * b.sqrt()) < 1e-17 * laminar {
        return 8.0 * fastmath::cbrt(fastmath::fourth_root(laminar));
    }
    let ln_7_re = (7.0 / re).ln();
    let ln_inv = if relative_roughness == 0.0 {
        -0.9 * ln_7_re
    } else {
        -((0.9 * ln_7_re).exp() + 0.27 * relative_roughness).ln()
    };
    let a = (2.457 * ln_inv).powi(16);
    let ab = a + b;
    8.0 * fastmath::cbrt(fastmath::fourth_root(laminar + 1.0 / (ab * ab.sqrt())))
}

/// Smooth step g(x) = 3x² − 2x³ on [0, 1] (0 below, 1 above), used to blend a disappearing
/// phase into the continuous one between void fractions x_min and x_max. The paper prints
/// x²(2x − 3), which is −g(x).
pub fn smooth_step(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// The slope of [`smooth_step`], 6 x (1 − x) on (0, 1) and 0 outside.
pub fn smooth_step_slope(x: f64) -> f64 {
    if x <= 0.0 || x >= 1.0 { 0.0 } else { 6.0 * x * (1.0 - x) }
}

/// Presence weight of a phase with volume fraction `frac`: 0 below `x_min`, 1 above `x_max`,
/// the smooth step between.
pub fn presence(frac: f64, x_min: f64, x_max: f64) -> f64 {
    smooth_step((frac - x_min) / (x_max - x_min))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn churchill_limits() {
        // laminar: 64/Re
        assert!((churchill_darcy(500.0, 0.0) - 64.0 / 500.0).abs() < 1e-3 * 64.0 / 500.0);
        // smooth turbulent at Re = 1e5: Blasius 0.316 Re^-0.25 = 0.0178; Churchill ≈ 0.0180
        let f = churchill_darcy(1e5, 0.0);
        assert!((f - 0.018).abs() < 0.0006, "{f}");
    }

    /// The correlation as printed, with `powf`.
    fn churchill_reference(re: f64, relative_roughness: f64) -> f64 {
        let re = re.max(1e-3);
        let a = (2.457 * (1.0 / ((7.0 / re).powf(0.9) + 0.27 * relative_roughness)).ln()).powi(16);
        let b = (37530.0 / re).powi(16);
        8.0 * ((8.0 / re).powi(12) + (a + b).powf(-1.5)).powf(1.0 / 12.0)
    }

    #[test]
    fn churchill_matches_the_printed_form() {
        let mut x: u64 = 0x2545_f491_4f6c_dd1d;
        let mut unit = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..200_000 {
            let re = 10f64.powf(-4.0 + 13.0 * unit());
            let rough = match (unit() * 3.0) as u32 {
                0 => 0.0,
                1 => 10f64.powf(-7.0 + 6.0 * unit()),
                _ => 0.05 * unit(),
            };
            let (a, b) = (churchill_darcy(re, rough), churchill_reference(re, rough));
            assert!((a - b).abs() <= 1e-13 * b.abs(), "Re {re:e} ε/D {rough:e}: {a} vs {b}");
        }
        for re in [0.0, 1e-3, 1.0, 2300.0, 4000.0, 1e5, 1e8] {
            for rough in [0.0, 1e-4, 0.05] {
                let (a, b) = (churchill_darcy(re, rough), churchill_reference(re, rough));
                assert!((a - b).abs() <= 1e-13 * b.abs(), "Re {re:e} ε/D {rough:e}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn smooth_step_is_the_right_sign() {
        assert_eq!(smooth_step(0.0), 0.0);
        assert_eq!(smooth_step(1.0), 1.0);
        assert!((smooth_step(0.5) - 0.5).abs() < 1e-15);
        assert_eq!(presence(1e-9, 1e-7, 1e-2), 0.0);
        assert_eq!(presence(0.5, 1e-7, 1e-2), 1.0);
    }
}
