//! Cheap, accurate replacements for a few elementary functions on the closures' hot path.
//!
//! `f64::cbrt` goes to the correctly rounded cbrt of `compiler_builtins`, which emulates `fma`
//! in software on targets without it (x86-64 baseline) and costs ~150 instructions; [`cbrt`]
//! here is the classic FreeBSD/musl algorithm (bit-trick seed, a polynomial to 23 bits, one
//! rounding to 32 bits and a Newton step), error below 0.667 ulp, ~30 instructions.
//! The powers with fixed exponents are written with square roots and [`cbrt`].

/// Cube root, |error| < 0.667 ulp (FreeBSD `s_cbrt.c`, as in musl). cbrt(±0) = ±0,
/// cbrt(±∞) = ±∞, cbrt(NaN) = NaN; subnormal arguments are handled.
#[inline]
pub fn cbrt(x: f64) -> f64 {
    // B1 = (1023 − 1023/3 − 0.03306235651) 2^20, B2 = B1 − (54/3) 2^20 (subnormals, scaled by 2^54)
    const B1: u32 = 715_094_163;
    const B2: u32 = 696_219_795;
    // |1/cbrt(x) − p(x)| < 2^−23.5; the bits of 1.87595182427177009643, −1.88497979543377169875,
    // 1.621429720105354466140, −0.758397934778766047437, 0.145996192886612446982
    const P0: f64 = f64::from_bits(0x3ffe_03e6_0f61_e692);
    const P1: f64 = f64::from_bits(0xbffe_28e0_92f0_2420);
    const P2: f64 = f64::from_bits(0x3ff9_f160_4a49_d6c2);
    const P3: f64 = f64::from_bits(0xbfe8_44cb_bee7_51d9);
    const P4: f64 = f64::from_bits(0x3fc2_b000_d4e4_edd7);

    let mut ui = x.to_bits();
    let mut hx = ((ui >> 32) as u32) & 0x7fff_ffff;
    if hx >= 0x7ff0_0000 {
        // NaN or ±∞
        return x + x;
    }
    if hx < 0x0010_0000 {
        // zero or subnormal
        ui = (x * f64::from_bits(0x4350_0000_0000_0000)).to_bits(); // x 2^54
        hx = ((ui >> 32) as u32) & 0x7fff_ffff;
        if hx == 0 {
            return x;
        }
        hx = hx / 3 + B2;
    } else {
        hx = hx / 3 + B1;
    }
    ui &= 1u64 << 63;
    ui |= (hx as u64) << 32;
    let mut t = f64::from_bits(ui);

    // new cbrt to 23 bits: cbrt(x) = t cbrt(x/t³) ≈ t P(t³/x)
    let r = (t * t) * (t / x);
    t *= (P0 + r * (P1 + r * P2)) + ((r * r) * r) * (P3 + r * P4);

    // round t away from zero to 23 bits (so that t*t is exact below)
    t = f64::from_bits((t.to_bits().wrapping_add(0x8000_0000)) & 0xffff_ffff_c000_0000);

    // one step of Newton's method to 53 bits, error < 0.667 ulp
    let s = t * t;
    let r = x / s;
    let w = t + t;
    let r = (r - t) / (w + r);
    t + t * r
}

/// x^(1/4) = √√x (NaN below zero, as `powf(0.25)` is, except that (−0)^¼ = −0 here and +0
/// there; the callers' arguments are ≥ 0).
#[inline]
pub fn fourth_root(x: f64) -> f64 {
    x.sqrt().sqrt()
}

/// x^e for a calibration exponent `e`: exact forms for the common e = 1 and e = 2 (within an
/// ulp of `powf`), `powf` otherwise.
#[inline]
pub fn pow_param(x: f64, e: f64) -> f64 {
    if e == 2.0 {
        x * x
    } else if e == 1.0 {
        x
    } else {
        x.powf(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two finite doubles of the same sign.
    fn ulps(a: f64, b: f64) -> u64 {
        let (ia, ib) = (a.to_bits() as i64, b.to_bits() as i64);
        (ia - ib).unsigned_abs()
    }

    /// A seeded generator: the same sweep on every run.
    struct Rng(rand::rngs::StdRng);
    impl Rng {
        fn new(seed: u64) -> Self {
            Self(rand::SeedableRng::seed_from_u64(seed))
        }
        fn next(&mut self) -> u64 {
            rand::Rng::r#gen(&mut self.0)
        }
        fn unit(&mut self) -> f64 {
            rand::Rng::r#gen(&mut self.0)
        }
    }

    proptest::proptest! {
        #[test]
        fn cbrt_is_within_an_ulp_of_std(
            x in proptest::num::f64::POSITIVE
                | proptest::num::f64::NEGATIVE
                | proptest::num::f64::NORMAL
                | proptest::num::f64::SUBNORMAL
        ) {
            proptest::prop_assume!(x.is_finite() && x != 0.0);
            let (a, b) = (cbrt(x), x.cbrt());
            proptest::prop_assert!(ulps(a, b) <= 1, "cbrt({:e}) = {:e}, std {:e}", x, a, b);
        }
    }

    #[test]
    fn cbrt_matches_std_over_all_decades() {
        let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
        let mut worst = 0;
        // log-uniform over the whole normal and subnormal range, both signs
        for _ in 0..400_000 {
            let e = -1074.0 + 2097.0 * rng.unit();
            let x = 2f64.powf(e) * if rng.next() & 1 == 0 { 1.0 } else { -1.0 };
            if x == 0.0 || !x.is_finite() {
                continue;
            }
            let (a, b) = (cbrt(x), x.cbrt());
            let u = ulps(a, b);
            assert!(u <= 1, "cbrt({x:e}) = {a:e}, std {b:e}: {u} ulp");
            worst = worst.max(u);
        }
        // the closures' range, densely
        for _ in 0..400_000 {
            let x = 10f64.powf(-12.0 + 36.0 * rng.unit());
            let u = ulps(cbrt(x), x.cbrt());
            assert!(u <= 1, "{x:e}: {u} ulp");
        }
        // random bit patterns
        for _ in 0..400_000 {
            let x = f64::from_bits(rng.next());
            if !x.is_finite() || x == 0.0 {
                continue;
            }
            let u = ulps(cbrt(x), x.cbrt());
            assert!(u <= 1, "{x:e}: {u} ulp");
        }
        assert!(worst <= 1);
    }

    #[test]
    fn cbrt_exact_and_special_values() {
        for k in -300i32..=300 {
            // perfect cubes of powers of two are exact
            let x = 2f64.powi(3 * (k / 3));
            assert_eq!(cbrt(x), 2f64.powi(k / 3), "{x:e}");
        }
        for (i, c) in [1.0f64, 8.0, 27.0, 64.0, 125.0, 1000.0, 0.001, 0.125].into_iter().enumerate() {
            assert!(ulps(cbrt(c), c.cbrt()) <= 1, "{i}");
            assert!(ulps(cbrt(-c), -(c.cbrt())) <= 1, "{i}");
        }
        assert_eq!(cbrt(1.0), 1.0);
        assert_eq!(cbrt(0.0).to_bits(), 0.0f64.to_bits());
        assert_eq!(cbrt(-0.0).to_bits(), (-0.0f64).to_bits());
        assert_eq!(cbrt(f64::INFINITY), f64::INFINITY);
        assert_eq!(cbrt(f64::NEG_INFINITY), f64::NEG_INFINITY);
        assert!(cbrt(f64::NAN).is_nan());
        assert!(ulps(cbrt(f64::MIN_POSITIVE), f64::MIN_POSITIVE.cbrt()) <= 1);
        assert!(ulps(cbrt(5e-324), 5e-324f64.cbrt()) <= 1);
        assert!(ulps(cbrt(f64::MAX), f64::MAX.cbrt()) <= 1);
    }

    #[test]
    fn roots_and_param_powers() {
        let mut rng = Rng::new(12345);
        for _ in 0..100_000 {
            let x = 10f64.powf(-20.0 + 40.0 * rng.unit());
            assert!(ulps(fourth_root(x), x.powf(0.25)) <= 1, "{x:e}");
            let e = 4.0 * rng.unit();
            for e in [e, 1.0, 2.0] {
                let (a, b) = (pow_param(x, e), x.powf(e));
                assert!((a - b).abs() <= 1e-15 * b.abs(), "{x:e}^{e}");
            }
        }
        assert_eq!(fourth_root(0.0), 0.0);
        assert_eq!(fourth_root(f64::INFINITY), f64::INFINITY);
        assert_eq!(pow_param(0.0, 2.0), 0.0);
    }
}
