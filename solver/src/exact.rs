//! Exact (analytic) solutions of classic two-fluid verification problems.
//!
//! These are pure functions, with no I/O and no dependencies beyond `std`. Tests and benchmarks
//! compare the numerical two-fluid solver against them.
//!
//! * [Ransom's water faucet](faucet_void_fraction): a liquid jet accelerated by gravity in a
//!   vertical tube. It checks the void-fraction transport and the momentum source terms, and
//!   the solution has a moving discontinuity.
//! * [The frictionless U-tube manometer](manometer_period_s): a liquid column oscillating
//!   under gravity. It checks the phase inertia and the gravity source.
//! * [Schumann's problem](Schumann) (Schumann 1929; Anzelius 1926): a fluid at constant inlet
//!   temperature flowing through a channel whose wall starts at another temperature. It
//!   checks fluid–wall heat exchange coupled with advection, which is the core of a chilldown
//!   computation.
//!
//! Units are SI throughout, and each argument name carries its unit.

use std::f64::consts::PI;

// ---------------------------------------------------------------------------------------------
// Ransom's water faucet
// ---------------------------------------------------------------------------------------------

/// Void fraction (gas volume fraction) `α(x, t)` in Ransom's water faucet problem.
///
/// # Problem
///
/// A vertical tube has its `x` axis pointing **downward** and its top at `x = 0`. At `t = 0`
/// the tube holds a uniform liquid column with liquid fraction `1 − α0` and velocity `v0`,
/// surrounded by stagnant gas. For `t > 0` the liquid keeps entering at `x = 0` with the same
/// velocity `v0` and liquid fraction `1 − α0`. Gravity `g` accelerates the liquid. There is
/// no interfacial drag and no wall friction, the liquid is incompressible and the pressure is
/// uniform. The gas stays at rest, so the liquid equations decouple:
///
/// ```text
/// ∂(1−α)/∂t + ∂((1−α) v)/∂x = 0,        ∂v/∂t + v ∂v/∂x = g.
/// ```
///
/// # Solution
///
/// The front `x_f(t) = v0 t + g t²/2` is the path of the liquid that was at the inlet at
/// `t = 0`. Behind it (`x < x_f`) the flow has reached steady state: `v = √(v0² + 2 g x)`
/// (free fall), and the liquid flux `(1 − α) v = (1 − α0) v0` is constant, so
///
/// ```text
/// α(x, t) = 1 − (1 − α0) v0 / √(v0² + 2 g x)        for x <  v0 t + g t²/2,
/// α(x, t) = α0                                       for x ≥ v0 t + g t²/2.
/// ```
///
/// Ahead of the front the initial column accelerates uniformly (`v = v0 + g t`, independent
/// of `x`), so its liquid fraction does not change. Velocity is continuous at the front
/// (`√(v0² + 2 g x_f) = v0 + g t`), but the void fraction **jumps** there, from
/// `1 − (1 − α0) v0/(v0 + g t)` just behind it to `α0` just ahead. At `x = x_f` itself this
/// function returns the downstream value `α0`.
///
/// The classic benchmark uses `α0 = 0.2`, `v0 = 10 m/s`, `g = 9.81 m/s²`, a 12 m tube and
/// `t = 0.5 s`. The front is then at 6.226 m, and the void fraction jumps from 0.4633 to 0.2.
///
/// The solution holds for `x ≥ 0`, `t ≥ 0`, `v0 > 0` and `g ≥ 0`. Ignoring the tube length
/// is correct: the flow is supersonic in the direction of the liquid, so the outlet has no
/// effect upstream.
pub fn faucet_void_fraction(x_m: f64, t_s: f64, alpha0: f64, v0_m_s: f64, g_m_s2: f64) -> f64 {
    if x_m < faucet_front_m(t_s, v0_m_s, g_m_s2) {
        1.0 - (1.0 - alpha0) * v0_m_s / (v0_m_s * v0_m_s + 2.0 * g_m_s2 * x_m).sqrt()
    } else {
        alpha0
    }
}

/// Liquid velocity `v(x, t)` in Ransom's water faucet problem.
///
/// See [`faucet_void_fraction`] for the problem. Behind the front, `x < v0 t + g t²/2`, the
/// flow is steady free fall, `v = √(v0² + 2 g x)`. Ahead of the front the initial column
/// falls as a solid body, `v = v0 + g t`. The two values agree at the front, so the velocity
/// is continuous and only its `x`-derivative jumps.
pub fn faucet_liquid_velocity(x_m: f64, t_s: f64, v0_m_s: f64, g_m_s2: f64) -> f64 {
    if x_m < faucet_front_m(t_s, v0_m_s, g_m_s2) {
        (v0_m_s * v0_m_s + 2.0 * g_m_s2 * x_m).sqrt()
    } else {
        v0_m_s + g_m_s2 * t_s
    }
}

/// Position of the faucet's void-fraction discontinuity, `x_f(t) = v0 t + g t²/2`.
fn faucet_front_m(t_s: f64, v0_m_s: f64, g_m_s2: f64) -> f64 {
    v0_m_s * t_s + 0.5 * g_m_s2 * t_s * t_s
}

// ---------------------------------------------------------------------------------------------
// U-tube manometer
// ---------------------------------------------------------------------------------------------

/// Oscillation period of a frictionless U-tube manometer, `P = 2π √(l / (2 g))`.
///
/// # Problem
///
/// A U-tube with uniform cross-section holds an incompressible liquid column of total length
/// `l`, measured along the tube axis. Both free surfaces see the same gas pressure, and there
/// is no friction. If one surface rises by `z`, the other falls by `z`, and the unbalanced
/// hydrostatic head `2 z` accelerates the whole column:
///
/// ```text
/// l d²z/dt² = −2 g z    ⇒    ω = √(2 g / l),    P = 2π/ω = 2π √(l / (2 g)).
/// ```
///
/// For `l = 10 m` and `g = 9.81 m/s²`, `P = 4.4857 s`.
pub fn manometer_period_s(liquid_column_m: f64, g_m_s2: f64) -> f64 {
    2.0 * PI / manometer_omega(liquid_column_m, g_m_s2)
}

/// Liquid velocity of the frictionless U-tube manometer, `v(t) = v0 cos(ω t)`, `ω = √(2g/l)`.
///
/// The column starts at its equilibrium position (`z(0) = 0`) with velocity `v0`. See
/// [`manometer_period_s`] for the problem. The displacement is
/// [`manometer_displacement_m`], and `v² + ω² z² = v0²` holds at all times.
pub fn manometer_velocity_m_s(t_s: f64, v0_m_s: f64, liquid_column_m: f64, g_m_s2: f64) -> f64 {
    v0_m_s * (manometer_omega(liquid_column_m, g_m_s2) * t_s).cos()
}

/// Column displacement of the frictionless U-tube manometer, `z(t) = (v0/ω) sin(ω t)`.
///
/// `ω = √(2 g / l)`. The displacement is measured along the tube axis: one free surface rises
/// by `z` and the other falls by `z`. It is the time integral of [`manometer_velocity_m_s`],
/// with `z(0) = 0`.
pub fn manometer_displacement_m(t_s: f64, v0_m_s: f64, liquid_column_m: f64, g_m_s2: f64) -> f64 {
    let omega = manometer_omega(liquid_column_m, g_m_s2);
    v0_m_s / omega * (omega * t_s).sin()
}

/// Angular frequency of the manometer, `ω = √(2 g / l)`.
fn manometer_omega(liquid_column_m: f64, g_m_s2: f64) -> f64 {
    (2.0 * g_m_s2 / liquid_column_m).sqrt()
}

// ---------------------------------------------------------------------------------------------
// Schumann's problem
// ---------------------------------------------------------------------------------------------

/// Schumann's (1929) / Anzelius' (1926) problem: transient heat exchange between a fluid
/// advected at constant velocity and a wall with no axial conduction.
///
/// # Problem
///
/// A fluid moves at constant velocity `u > 0` through a channel along `x ≥ 0`. Per unit length
/// of channel, the fluid has heat capacity `C_f = ρ c_p A` (J/(m K)), the wall has heat
/// capacity `C_w` (J/(m K)), and they exchange heat through the conductance `H = h P`
/// (W/(m K)), where `h` is the heat transfer coefficient and `P` the heated perimeter. Axial
/// conduction is neglected and all properties are constant:
///
/// ```text
/// C_f (∂T_f/∂t + u ∂T_f/∂x) = H (T_w − T_f),
/// C_w  ∂T_w/∂t              = H (T_f − T_w).
/// ```
///
/// At `t = 0`, fluid and wall are at `T0` everywhere. For `t > 0`, fluid at `T_in` enters at
/// `x = 0`. The packed-bed form, `(ρc)_f ε (∂_t + u ∂_x) T_f = h_v (T_w − T_f)` and
/// `(ρc)_w (1 − ε) ∂_t T_w = h_v (T_f − T_w)`, is the same problem with `C_f = (ρc)_f ε`,
/// `C_w = (ρc)_w (1 − ε)` and `H = h_v`, all per unit volume.
///
/// # Dimensionless form
///
/// The variables are the dimensionless distance and the dimensionless time elapsed since
/// the front passed:
///
/// ```text
/// ξ = H x / (C_f u),        τ = H (t − x/u) / C_w,        θ = (T − T0) / (T_in − T0).
/// ```
///
/// In these variables, `∂_t + u ∂_x = (H/C_f) ∂_ξ` at fixed `τ`, and `∂_t = (H/C_w) ∂_τ` at
/// fixed `ξ`. The system becomes a Goursat problem on the quadrant `ξ ≥ 0`, `τ ≥ 0`:
///
/// ```text
/// ∂θ_f/∂ξ = θ_w − θ_f,    ∂θ_w/∂τ = θ_f − θ_w,    θ_f(0, τ) = 1,    θ_w(ξ, 0) = 0.
/// ```
///
/// The front (`τ = 0`) meets a wall still at `T0`, so `θ_f(ξ, 0) = e^{−ξ}`. Ahead of the front
/// (`t < x/u`, i.e. `τ < 0`), the fluid present since `t = 0` and the wall are both at `T0`,
/// and nothing changes there.
///
/// # Solution
///
/// Take the Laplace transform in `τ`, with `s` the transform variable:
/// `W̄ = F̄/(s + 1)` and `dF̄/dξ = −F̄ s/(s + 1)`, so `F̄ = s⁻¹ e^{−ξ} e^{ξ/(s+1)}`. Inverting
/// with `L⁻¹[(s+1)⁻¹ e^{ξ/(s+1)}] = e^{−τ} I₀(2√(ξτ))` gives
///
/// ```text
/// θ_f(ξ, τ) = J(ξ, τ),
/// θ_w(ξ, τ) = J(ξ, τ) − e^{−ξ−τ} I₀(2√(ξτ)),
/// ```
///
/// Here `J` is Goldstein's J-function (Goldstein 1953),
///
/// ```text
/// J(ξ, τ) = 1 − e^{−τ} ∫₀^ξ e^{−s} I₀(2√(τ s)) ds,
/// ```
///
/// and `I₀` is the modified Bessel function of the first kind of order zero. An equivalent
/// form is `θ_w(ξ, τ) = e^{−ξ} ∫₀^τ e^{−σ} I₀(2√(ξσ)) dσ = 1 − J(τ, ξ)`, which is the identity
/// `J(ξ, τ) + J(τ, ξ) = 1 + e^{−ξ−τ} I₀(2√(ξτ))`. Checks: `θ_f(0, τ) = 1`,
/// `θ_w(0, τ) = 1 − e^{−τ}`, `θ_f(ξ, 0) = e^{−ξ}`, `θ_w(ξ, 0) = 0`, and `θ → 1` as `τ → ∞`.
///
/// # Numerics
///
/// The integrand is evaluated without overflow as `e^{−(√s − √τ)²} · [e^{−z} I₀(z)]` with
/// `z = 2√(τ s)`. The scaled Bessel function `e^{−z} I₀(z) ≤ 1` comes from the power series
/// for `z ≤ 20` and from the asymptotic expansion, truncated at its smallest term, above that.
/// Because the integrand is bounded by `e^{−(√s − √τ)²}`, integration is restricted to
/// `(√τ − 10)² ≤ s ≤ (√τ + 10)²`, where the neglected part is below `e^{−100}` times the
/// interval length. That range is split into panels of width `max(1, √τ)`, and each panel is
/// integrated by adaptive 10-point Gauss–Legendre quadrature. The absolute error in `θ` is
/// about 1e-13, well below the 1e-8 target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schumann {
    /// Fluid heat capacity per unit channel length, `C_f = ρ c_p A` (J/(m K)).
    c_fluid: f64,
    /// Wall heat capacity per unit channel length, `C_w` (J/(m K)).
    c_wall: f64,
    /// Fluid–wall conductance per unit length, `H = h P` (W/(m K)).
    conductance: f64,
    /// Fluid velocity `u` (m/s).
    velocity: f64,
    /// Inlet fluid temperature `T_in` (K).
    t_inlet: f64,
    /// Initial fluid and wall temperature `T0` (K).
    t_initial: f64,
}

impl Schumann {
    /// Sets up Schumann's problem.
    ///
    /// The arguments are: fluid heat capacity per unit length `C_f = ρ c_p A` (J/(m K)), wall
    /// heat capacity per unit length `C_w` (J/(m K)), conductance per unit length `H = h P`
    /// (W/(m K)), fluid velocity `u` (m/s), inlet temperature `T_in` and initial temperature
    /// `T0` (K).
    ///
    /// # Panics
    ///
    /// Panics unless `C_f > 0`, `C_w > 0`, `H ≥ 0`, `u > 0` and both temperatures are finite.
    pub fn new(
        fluid_heat_capacity_j_m_k: f64,
        wall_heat_capacity_j_m_k: f64,
        conductance_w_m_k: f64,
        velocity_m_s: f64,
        t_inlet_k: f64,
        t_initial_k: f64,
    ) -> Self {
        assert!(
            fluid_heat_capacity_j_m_k > 0.0 && fluid_heat_capacity_j_m_k.is_finite(),
            "Schumann: fluid heat capacity must be positive and finite, got {fluid_heat_capacity_j_m_k}"
        );
        assert!(
            wall_heat_capacity_j_m_k > 0.0 && wall_heat_capacity_j_m_k.is_finite(),
            "Schumann: wall heat capacity must be positive and finite, got {wall_heat_capacity_j_m_k}"
        );
        assert!(
            conductance_w_m_k >= 0.0 && conductance_w_m_k.is_finite(),
            "Schumann: conductance must be non-negative and finite, got {conductance_w_m_k}"
        );
        assert!(
            velocity_m_s > 0.0 && velocity_m_s.is_finite(),
            "Schumann: velocity must be positive and finite, got {velocity_m_s}"
        );
        assert!(
            t_inlet_k.is_finite() && t_initial_k.is_finite(),
            "Schumann: temperatures must be finite, got T_in = {t_inlet_k}, T0 = {t_initial_k}"
        );
        Self {
            c_fluid: fluid_heat_capacity_j_m_k,
            c_wall: wall_heat_capacity_j_m_k,
            conductance: conductance_w_m_k,
            velocity: velocity_m_s,
            t_inlet: t_inlet_k,
            t_initial: t_initial_k,
        }
    }

    /// Fluid and wall temperatures `(T_f, T_w)` (K) at distance `x` (m) from the inlet and
    /// time `t` (s).
    ///
    /// `t` is measured from the moment inlet fluid starts entering at `x = 0`. For `t < x/u`
    /// (ahead of the fluid front), both temperatures are the initial `T0`. Behind the front
    /// (`t ≥ x/u`), `T = T0 + (T_in − T0) θ(ξ, τ)` with `ξ = H x/(C_f u)` and
    /// `τ = H (t − x/u)/C_w`. The `θ` values are given by [`Schumann::theta`] and documented
    /// on [`Schumann`]. Exactly on the front (`t = x/u`) this returns the limit from behind:
    /// `θ_f = e^{−ξ}` and `θ_w = 0`. Negative `x` is treated as the inlet, `x = 0`.
    pub fn temperatures(&self, x_m: f64, t_s: f64) -> (f64, f64) {
        let x = x_m.max(0.0);
        let since_front = t_s - x / self.velocity;
        if since_front < 0.0 || t_s <= 0.0 {
            return (self.t_initial, self.t_initial);
        }
        let xi = self.conductance * x / (self.c_fluid * self.velocity);
        let tau = self.conductance * since_front / self.c_wall;
        let (theta_f, theta_w) = Self::theta(xi, tau);
        let dt = self.t_inlet - self.t_initial;
        (self.t_initial + dt * theta_f, self.t_initial + dt * theta_w)
    }

    /// Dimensionless fluid and wall temperatures `(θ_f, θ_w)` behind the front, as functions
    /// of `ξ ≥ 0` and `τ ≥ 0`:
    ///
    /// ```text
    /// θ_f = J(ξ, τ),    θ_w = J(ξ, τ) − e^{−ξ−τ} I₀(2√(ξτ)),
    /// J(ξ, τ) = 1 − e^{−τ} ∫₀^ξ e^{−s} I₀(2√(τ s)) ds.
    /// ```
    ///
    /// See [`Schumann`] for the derivation. Negative arguments are treated as zero.
    pub fn theta(xi: f64, tau: f64) -> (f64, f64) {
        let xi = xi.max(0.0);
        let tau = tau.max(0.0);
        let theta_f = goldstein_j(xi, tau);
        let theta_w = theta_f - exp_minus_xi_tau_i0(xi, tau);
        (theta_f, theta_w.max(0.0))
    }
}

/// `e^{−ξ−τ} I₀(2√(ξτ))`, computed as `e^{−(√ξ − √τ)²} · i0e(2√(ξτ))` so it never overflows.
fn exp_minus_xi_tau_i0(xi: f64, tau: f64) -> f64 {
    let d = xi.sqrt() - tau.sqrt();
    (-d * d).exp() * bessel_i0_scaled(2.0 * (xi * tau).sqrt())
}

/// Half-width, in `√s`, of the window outside which the J-function integrand is below
/// `e^{−R²} = e^{−100}`.
const J_WINDOW: f64 = 10.0;

/// Goldstein's J-function, `J(ξ, τ) = 1 − e^{−τ} ∫₀^ξ e^{−s} I₀(2√(τ s)) ds`, for `ξ, τ ≥ 0`.
fn goldstein_j(xi: f64, tau: f64) -> f64 {
    if xi <= 0.0 {
        return 1.0;
    }
    if tau <= 0.0 {
        return (-xi).exp();
    }
    let rt = tau.sqrt();
    // Integrand e^{-τ-s} I0(2√(τs)) = e^{-(√s-√τ)²} · i0e(2√(τs)) ≤ e^{-(√s-√τ)²}.
    let integrand = |s: f64| {
        let d = s.sqrt() - rt;
        (-d * d).exp() * bessel_i0_scaled(2.0 * (tau * s).sqrt())
    };
    let lo = (rt - J_WINDOW).max(0.0).powi(2);
    let hi = xi.min((rt + J_WINDOW).powi(2));
    if hi <= lo {
        // ξ lies below the window: the integral is below ξ e^{-100}.
        return 1.0;
    }
    let width = rt.max(1.0);
    let panels = ((hi - lo) / width).ceil().max(1.0) as usize;
    let h = (hi - lo) / panels as f64;
    let mut integral = 0.0;
    for k in 0..panels {
        let a = lo + k as f64 * h;
        let b = if k + 1 == panels { hi } else { a + h };
        integral += adaptive_gauss_legendre(&integrand, a, b, 1e-15, 30);
    }
    (1.0 - integral).clamp(0.0, 1.0)
}

/// Exponentially scaled modified Bessel function of the first kind, order zero:
/// `e^{−z} I₀(z)` for `z ≥ 0`, with relative accuracy near machine precision.
///
/// For `z ≤ 20` it uses the power series `I₀(z) = Σ_k (z²/4)^k / (k!)²`. All its terms are
/// positive, so the sum does not cancel. Above that it uses the asymptotic expansion
/// `e^{−z} I₀(z) ~ (2πz)^{−1/2} Σ_k [(2k − 1)!!]² / (k! (8z)^k)`, summed until the terms stop
/// decreasing. The smallest term, relative to the sum, is about `e^{−2z} < 1e-17`.
fn bessel_i0_scaled(z: f64) -> f64 {
    let z = z.abs();
    if z <= 20.0 {
        let q = 0.25 * z * z;
        let mut term = 1.0;
        let mut sum = 1.0;
        let mut k = 1.0;
        loop {
            term *= q / (k * k);
            sum += term;
            if term <= 1e-17 * sum {
                break;
            }
            k += 1.0;
        }
        sum * (-z).exp()
    } else {
        let inv8z = 1.0 / (8.0 * z);
        let mut term: f64 = 1.0;
        let mut sum = 1.0;
        let mut k = 0.0;
        loop {
            let next = term * (2.0 * k + 1.0) * (2.0 * k + 1.0) * inv8z / (k + 1.0);
            if next >= term || next <= 1e-17 * sum {
                if next < term {
                    sum += next;
                }
                break;
            }
            term = next;
            sum += term;
            k += 1.0;
        }
        sum / (2.0 * PI * z).sqrt()
    }
}

/// Nodes (positive half) of the 10-point Gauss–Legendre rule on `[−1, 1]`.
const GL10_NODES: [f64; 5] = [
    0.148_874_338_981_631_22,
    0.433_395_394_129_247_2,
    0.679_409_568_299_024_4,
    0.865_063_366_688_984_5,
    0.973_906_528_517_171_7,
];

/// Weights matching [`GL10_NODES`].
const GL10_WEIGHTS: [f64; 5] = [
    0.295_524_224_714_752_87,
    0.269_266_719_309_996_35,
    0.219_086_362_515_982_04,
    0.149_451_349_150_580_6,
    0.066_671_344_308_688_14,
];

/// 10-point Gauss–Legendre quadrature of `f` over `[a, b]` (exact for degree ≤ 19).
fn gauss_legendre10(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let mid = 0.5 * (a + b);
    let half = 0.5 * (b - a);
    let mut sum = 0.0;
    for (x, w) in GL10_NODES.iter().zip(GL10_WEIGHTS.iter()) {
        sum += w * (f(mid - half * x) + f(mid + half * x));
    }
    sum * half
}

/// Adaptive bisection with 10-point Gauss–Legendre quadrature. An interval is accepted when
/// the sum over its two halves agrees with the whole-interval estimate to `tol` (absolute), or
/// to 1e-14 relative (the rounding floor), or when `depth` bisections have been made.
fn adaptive_gauss_legendre(f: &impl Fn(f64) -> f64, a: f64, b: f64, tol: f64, depth: u32) -> f64 {
    let whole = gauss_legendre10(f, a, b);
    adaptive_step(f, a, b, whole, tol, depth)
}

fn adaptive_step(f: &impl Fn(f64) -> f64, a: f64, b: f64, whole: f64, tol: f64, depth: u32) -> f64 {
    let m = 0.5 * (a + b);
    let left = gauss_legendre10(f, a, m);
    let right = gauss_legendre10(f, m, b);
    let split = left + right;
    if depth == 0 || (split - whole).abs() <= tol.max(1e-14 * split.abs()) {
        split
    } else {
        adaptive_step(f, a, m, left, 0.5 * tol, depth - 1) + adaptive_step(f, m, b, right, 0.5 * tol, depth - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // ----- faucet -----------------------------------------------------------------------------

    const A0: f64 = 0.2;
    const V0: f64 = 10.0;
    const G: f64 = 9.81;
    const T_CLASSIC: f64 = 0.5;

    #[test]
    fn faucet_classic_front_and_jump() {
        let xf = V0 * T_CLASSIC + 0.5 * G * T_CLASSIC * T_CLASSIC;
        assert!((xf - 6.22625).abs() < 1e-12);
        let eps = 1e-9;
        // Just behind the front: α = 1 − 0.8 · 10 / 14.905.
        let behind = faucet_void_fraction(xf - eps, T_CLASSIC, A0, V0, G);
        let expected_behind = 1.0 - 0.8 * 10.0 / (V0 + G * T_CLASSIC);
        assert!((behind - expected_behind).abs() < 1e-9, "{behind} vs {expected_behind}");
        assert!((expected_behind - 0.463_267_359_946_326_7).abs() < 1e-15, "{expected_behind}");
        // Just ahead, on, and far ahead of the front: α0.
        assert_eq!(faucet_void_fraction(xf + eps, T_CLASSIC, A0, V0, G), A0);
        assert_eq!(faucet_void_fraction(xf, T_CLASSIC, A0, V0, G), A0);
        assert_eq!(faucet_void_fraction(12.0, T_CLASSIC, A0, V0, G), A0);
        // The jump is finite, and is the one seen in the classic plots (0.2 → ~0.46).
        assert!(behind - A0 > 0.26);
        // Velocity is continuous across the front.
        let vb = faucet_liquid_velocity(xf - eps, T_CLASSIC, V0, G);
        let va = faucet_liquid_velocity(xf + eps, T_CLASSIC, V0, G);
        assert!((vb - va).abs() < 1e-8 && (va - 14.905).abs() < 1e-12, "{vb} {va}");
    }

    #[test]
    fn faucet_classic_values() {
        // Inlet: α0 and v0.
        assert!((faucet_void_fraction(0.0, T_CLASSIC, A0, V0, G) - A0).abs() < 1e-15);
        assert!((faucet_liquid_velocity(0.0, T_CLASSIC, V0, G) - V0).abs() < 1e-15);
        // Hand-computed values behind the front.
        for (x, alpha) in
            [(1.0, 0.268_544_199_995_670_8), (3.0, 0.365_279_233_071_511_8), (6.0, 0.457_823_332_091_197_2)]
        {
            let a = faucet_void_fraction(x, T_CLASSIC, A0, V0, G);
            let v = faucet_liquid_velocity(x, T_CLASSIC, V0, G);
            let v_exact = (100.0_f64 + 2.0 * 9.81 * x).sqrt();
            assert!((v - v_exact).abs() < 1e-12);
            assert!((a - (1.0 - 8.0 / v_exact)).abs() < 1e-14);
            assert!((a - alpha).abs() < 1e-12, "x = {x}: {a} vs {alpha}");
        }
        // Ahead of the front the column falls as a solid body.
        for x in [7.0, 9.0, 12.0] {
            assert_eq!(faucet_void_fraction(x, T_CLASSIC, A0, V0, G), A0);
            assert!((faucet_liquid_velocity(x, T_CLASSIC, V0, G) - 14.905).abs() < 1e-12);
        }
        // At t = 0 everything is the initial state.
        assert_eq!(faucet_void_fraction(5.0, 0.0, A0, V0, G), A0);
        assert_eq!(faucet_liquid_velocity(5.0, 0.0, V0, G), V0);
    }

    #[test]
    fn faucet_satisfies_conservation_laws() {
        // Behind the front the liquid flux (1 − α) v is the inlet flux; mass and momentum
        // equations checked by central differences at interior points on either side.
        let flux0 = (1.0 - A0) * V0;
        let h = 1e-5;
        for &(x, t) in &[(1.0, 0.5), (4.0, 0.5), (2.0, 0.3), (8.0, 0.5), (11.0, 0.9)] {
            let af = |x: f64, t: f64| 1.0 - faucet_void_fraction(x, t, A0, V0, G);
            let v = |x: f64, t: f64| faucet_liquid_velocity(x, t, V0, G);
            let mass = (af(x, t + h) - af(x, t - h)) / (2.0 * h)
                + (af(x + h, t) * v(x + h, t) - af(x - h, t) * v(x - h, t)) / (2.0 * h);
            let mom = (v(x, t + h) - v(x, t - h)) / (2.0 * h) + v(x, t) * (v(x + h, t) - v(x - h, t)) / (2.0 * h) - G;
            assert!(mass.abs() < 1e-6, "mass residual {mass} at ({x}, {t})");
            assert!(mom.abs() < 1e-5, "momentum residual {mom} at ({x}, {t})");
            if x < faucet_front_m(t, V0, G) {
                assert!((af(x, t) * v(x, t) - flux0).abs() < 1e-12);
            }
        }
    }

    // ----- manometer --------------------------------------------------------------------------

    #[test]
    fn manometer_period_classic() {
        let p = manometer_period_s(10.0, 9.81);
        assert!((p - 4.486).abs() < 1e-3, "{p}");
        assert!((p - 4.485_701_465_466_374).abs() < 1e-9, "{p}");
    }

    #[test]
    fn manometer_motion() {
        let (l, g, v0) = (10.0, 9.81, 2.1);
        let p = manometer_period_s(l, g);
        let omega = 2.0 * PI / p;
        for i in 0..=40 {
            let t = i as f64 * p / 16.0;
            let v = manometer_velocity_m_s(t, v0, l, g);
            let z = manometer_displacement_m(t, v0, l, g);
            // Energy: v² + ω² z² = v0².
            assert!((v * v + omega * omega * z * z - v0 * v0).abs() < 1e-12);
            // dz/dt = v and l dv/dt = −2 g z.
            let h = 1e-5;
            let dz =
                (manometer_displacement_m(t + h, v0, l, g) - manometer_displacement_m(t - h, v0, l, g)) / (2.0 * h);
            let dv = (manometer_velocity_m_s(t + h, v0, l, g) - manometer_velocity_m_s(t - h, v0, l, g)) / (2.0 * h);
            assert!((dz - v).abs() < 1e-8);
            assert!((l * dv + 2.0 * g * z).abs() < 1e-7);
        }
        // Periodicity and quarter-period values.
        assert!((manometer_velocity_m_s(p, v0, l, g) - v0).abs() < 1e-12);
        assert!(manometer_velocity_m_s(0.25 * p, v0, l, g).abs() < 1e-12);
        assert!((manometer_displacement_m(0.25 * p, v0, l, g) - v0 / omega).abs() < 1e-12);
        assert!(manometer_displacement_m(0.5 * p, v0, l, g).abs() < 1e-12);
    }

    // ----- Bessel / quadrature ----------------------------------------------------------------

    #[test]
    fn bessel_i0_scaled_reference_values() {
        // e^{-z} I0(z), 20 digits from mpmath.
        let reference = [
            (0.0, 1.0),
            (0.5, 0.645_035_270_449_150_1),
            (1.0, 0.465_759_607_593_640_43),
            (5.0, 0.183_540_812_609_328_36),
            (10.0, 0.127_833_337_163_428_6),
            (19.9, 0.090_008_588_864_389_6),
            (20.1, 0.089_553_763_620_613_44),
            (30.0, 0.073_145_946_482_237_3),
            (50.0, 0.056_561_626_647_454_19),
            (100.0, 0.039_944_379_299_096_68),
            (700.0, 0.015_081_295_651_531_358),
            (1e4, 0.003_989_472_674_604_732),
        ];
        for (z, want) in reference {
            let got = bessel_i0_scaled(z);
            assert!(((got - want) / want).abs() < 1e-14, "i0e({z}) = {got}, want {want}");
        }
        // Continuity across the series/asymptotic switch.
        let below = bessel_i0_scaled(20.0);
        let above = bessel_i0_scaled(20.0_f64.next_up());
        assert!(((below - above) / below).abs() < 1e-14, "{below} vs {above}");
    }

    #[test]
    fn gauss_legendre_is_exact_for_degree_19() {
        let f = |x: f64| x.powi(19) + 3.0 * x.powi(18) - x.powi(7) + 2.0;
        let exact = |x: f64| x.powi(20) / 20.0 + 3.0 * x.powi(19) / 19.0 - x.powi(8) / 8.0 + 2.0 * x;
        let (a, b) = (-0.3, 1.1);
        let got = gauss_legendre10(&f, a, b);
        assert!((got - (exact(b) - exact(a))).abs() < 1e-13, "{got}");
    }

    // ----- Schumann -------------------------------------------------------------------------

    #[test]
    fn goldstein_j_reference_values() {
        // (ξ, τ, θ_f = J, θ_w) from mpmath at 30 digits.
        let reference = [
            (1.0, 1.0, 0.654_254_161_276_835_6, 0.345_745_838_723_164_5),
            (5.0, 2.0, 0.168_568_913_530_131_4, 0.086_065_522_399_787_42),
            (2.0, 5.0, 0.913_934_477_600_212_6, 0.831_431_086_469_868_6),
            (10.0, 10.0, 0.544_890_155_942_413, 0.455_109_844_057_587),
            (20.0, 15.0, 0.223_016_988_012_356_1, 0.175_505_294_879_600_73),
            (15.0, 20.0, 0.824_494_705_120_399_2, 0.776_983_011_987_644),
            (0.3, 7.0, 0.999_432_067_461_403_6, 0.996_394_491_809_918_8),
            (50.0, 40.0, 0.157_981_265_898_288_56, 0.133_786_360_550_040_34),
            (100.0, 100.0, 0.514_113_579_974_556, 0.485_886_420_025_444),
        ];
        for (xi, tau, f, w) in reference {
            let (gf, gw) = Schumann::theta(xi, tau);
            assert!((gf - f).abs() < 1e-12, "θ_f({xi}, {tau}) = {gf}, want {f}");
            assert!((gw - w).abs() < 1e-12, "θ_w({xi}, {tau}) = {gw}, want {w}");
        }
    }

    #[test]
    fn goldstein_j_symmetry_identity() {
        // J(ξ,τ) + J(τ,ξ) = 1 + e^{-ξ-τ} I0(2√(ξτ)), i.e. θ_w(ξ,τ) = 1 − J(τ,ξ). This checks the
        // quadrature: the two sides integrate different functions over different ranges.
        for &xi in &[0.01, 0.3, 1.0, 4.0, 12.0, 30.0, 200.0, 3000.0] {
            for &tau in &[0.02, 0.5, 2.0, 8.0, 20.0, 60.0, 500.0, 5000.0] {
                let lhs = goldstein_j(xi, tau) + goldstein_j(tau, xi);
                let rhs = 1.0 + exp_minus_xi_tau_i0(xi, tau);
                assert!((lhs - rhs).abs() < 1e-12, "ξ = {xi}, τ = {tau}: {lhs} vs {rhs}");
            }
        }
    }

    #[test]
    fn schumann_boundary_values_and_limits() {
        for &x in &[0.0, 0.1, 1.0, 5.0, 30.0, 300.0] {
            let (f, w) = Schumann::theta(x, 0.0);
            assert!((f - (-x).exp()).abs() < 1e-15 && w.abs() < 1e-15);
            let (f, w) = Schumann::theta(0.0, x);
            assert!((f - 1.0).abs() < 1e-15 && (w - (1.0 - (-x).exp())).abs() < 1e-14, "{w}");
            // Just behind the front and just downstream of the inlet, by continuity.
            let (f, w) = Schumann::theta(x, 1e-12);
            assert!((f - (-x).exp()).abs() < 1e-10 && w.abs() < 1e-10);
            let (f, _) = Schumann::theta(1e-12, x);
            assert!((f - 1.0).abs() < 1e-10);
        }
        let s = Schumann::new(4000.0, 2500.0, 300.0, 1.5, 80.0, 300.0);
        // At the inlet the fluid is at T_in for t > 0.
        for &t in &[1e-6, 0.1, 3.0, 100.0] {
            let (tf, tw) = s.temperatures(0.0, t);
            assert!((tf - 80.0).abs() < 1e-12);
            assert!((tw - (300.0 - 220.0 * (1.0 - (-300.0 * t / 2500.0).exp()))).abs() < 1e-9);
        }
        // θ → 1 for t → ∞ at fixed x.
        for &x in &[1.0, 50.0, 300.0] {
            let (tf, tw) = s.temperatures(x, 1e5);
            assert!((tf - 80.0).abs() < 1e-10 && (tw - 80.0).abs() < 1e-10, "{tf} {tw}");
        }
        // Ahead of the front, and before the start, nothing has changed.
        assert_eq!(s.temperatures(30.0, 19.9), (300.0, 300.0));
        assert_eq!(s.temperatures(30.0, 0.0), (300.0, 300.0));
        assert_eq!(s.temperatures(0.0, -1.0), (300.0, 300.0));
        // The fluid jumps at the front, from the front value T0 + ΔT e^{-ξ} to T0.
        let (tf, tw) = s.temperatures(30.0, 20.0);
        let xi: f64 = 300.0 * 30.0 / (4000.0 * 1.5);
        assert!((tf - (300.0 - 220.0 * (-xi).exp())).abs() < 1e-12 && (tw - 300.0).abs() < 1e-12);
        // Monotone: fluid is always closer to T_in than the wall behind the front, and both cool.
        let mut prev = (300.0, 300.0);
        for i in 1..200 {
            let (tf, tw) = s.temperatures(60.0, 40.0 + i as f64);
            assert!(tf <= tw + 1e-12 && tf <= prev.0 + 1e-12 && tw <= prev.1 + 1e-12);
            prev = (tf, tw);
        }
        // H = 0: no exchange; fluid carries T_in, wall stays at T0.
        let s0 = Schumann::new(4000.0, 2500.0, 0.0, 1.5, 80.0, 300.0);
        assert_eq!(s0.temperatures(3.0, 10.0), (80.0, 300.0));
    }

    #[test]
    fn schumann_satisfies_pde() {
        // Residuals of ∂θ_f/∂ξ = θ_w − θ_f and ∂θ_w/∂τ = θ_f − θ_w by 4th-order differences.
        let h = 1e-3;
        let d = |g: &dyn Fn(f64) -> f64, z: f64| {
            (8.0 * (g(z + h) - g(z - h)) - (g(z + 2.0 * h) - g(z - 2.0 * h))) / (12.0 * h)
        };
        for &xi in &[0.1, 1.0, 3.0, 8.0, 20.0] {
            for &tau in &[0.1, 0.7, 2.5, 9.0, 20.0] {
                let (f, w) = Schumann::theta(xi, tau);
                let dfdxi = d(&|z| Schumann::theta(z, tau).0, xi);
                let dwdtau = d(&|z| Schumann::theta(xi, z).1, tau);
                assert!((dfdxi - (w - f)).abs() < 1e-8, "fluid residual at ({xi}, {tau})");
                assert!((dwdtau - (f - w)).abs() < 1e-8, "wall residual at ({xi}, {tau})");
            }
        }
    }

    #[test]
    fn schumann_conserves_energy() {
        // ∫₀^{ut} [C_f (T_f − T0) + C_w (T_w − T0)] dx = C_f u t (T_in − T0): all the enthalpy
        // brought in through the inlet, since nothing has left ahead of the front.
        let (cf, cw, hh, u, tin, t0) = (4000.0, 2500.0, 300.0, 1.5, 80.0, 300.0);
        let s = Schumann::new(cf, cw, hh, u, tin, t0);
        for &t in &[5.0, 60.0, 250.0] {
            let front = u * t;
            let stored = |x: f64| {
                let (tf, tw) = s.temperatures(x.min(front), t);
                cf * (tf - t0) + cw * (tw - t0)
            };
            let panels = 200;
            let dx = front / panels as f64;
            let total: f64 = (0..panels).map(|k| gauss_legendre10(&stored, k as f64 * dx, (k + 1) as f64 * dx)).sum();
            let inflow = cf * u * t * (tin - t0);
            assert!(((total - inflow) / inflow).abs() < 1e-10, "t = {t}: {total} vs {inflow}");
        }
    }

    /// Independent solution of the physical-variable system by the method of characteristics.
    ///
    /// Uses `x` and `η = t − x/u`. Along a characteristic (fixed `η`) the fluid obeys the ODE
    /// `dT_f/dx = a (T_w − T_f)` with `a = H/(C_f u)`. At a fixed station `x`, the wall obeys
    /// `dT_w/dη = b (T_f − T_w)` with `b = H/C_w`. Each cell integrates both ODEs with the
    /// trapezoidal rule (the box scheme), which is second order. The cell's 2×2 system is
    /// solved exactly. Returns `(T_f, T_w)` on the `(nx + 1) × (ne + 1)` grid, row-major in `x`.
    fn characteristics_grid(
        p: (f64, f64, f64, f64, f64, f64),
        x_max: f64,
        eta_max: f64,
        nx: usize,
        ne: usize,
    ) -> Vec<(f64, f64)> {
        let (cf, cw, hh, u, tin, t0) = p;
        let (a, b) = (hh / (cf * u), hh / cw);
        let pp = 0.5 * a * x_max / nx as f64;
        let qq = 0.5 * b * eta_max / ne as f64;
        let idx = |i: usize, j: usize| i * (ne + 1) + j;
        let mut g = vec![(0.0, 0.0); (nx + 1) * (ne + 1)];
        // Inlet station: fluid at T_in, wall heated from T0.
        g[idx(0, 0)] = (tin, t0);
        for j in 0..ne {
            let wd = g[idx(0, j)].1;
            let w1 = (wd + qq * (tin - wd) + qq * tin) / (1.0 + qq);
            g[idx(0, j + 1)] = (tin, w1);
        }
        // Front characteristic: wall at T0, fluid relaxes towards it.
        for i in 0..nx {
            let fl = g[idx(i, 0)].0;
            let f1 = (fl + pp * (t0 - fl) + pp * t0) / (1.0 + pp);
            g[idx(i + 1, 0)] = (f1, t0);
        }
        for i in 0..nx {
            for j in 0..ne {
                let (fl, wl) = g[idx(i, j + 1)];
                let (fd, wd) = g[idx(i + 1, j)];
                let r1 = fl + pp * (wl - fl);
                let r2 = wd + qq * (fd - wd);
                let det = 1.0 + pp + qq;
                let f1 = (r1 * (1.0 + qq) + pp * r2) / det;
                let w1 = (r2 * (1.0 + pp) + qq * r1) / det;
                g[idx(i + 1, j + 1)] = (f1, w1);
            }
        }
        g
    }

    #[test]
    fn schumann_matches_characteristic_integration() {
        let p = (4000.0, 2500.0, 300.0, 1.5, 80.0, 300.0);
        let (cf, cw, hh, u, tin, t0) = p;
        let s = Schumann::new(cf, cw, hh, u, tin, t0);
        let (a, b) = (hh / (cf * u), hh / cw);
        let (xi_max, tau_max) = (20.0, 20.0);
        let (x_max, eta_max) = (xi_max / a, tau_max / b);
        let n = 400;
        let coarse = characteristics_grid(p, x_max, eta_max, n, n);
        let fine = characteristics_grid(p, x_max, eta_max, 2 * n, 2 * n);
        let fine2 = characteristics_grid(p, x_max, eta_max, 4 * n, 4 * n);
        let dtemp = tin - t0;
        let mut worst_raw: f64 = 0.0;
        let mut worst_rich: f64 = 0.0;
        let points = [0.5, 1.0, 2.0, 3.5, 5.0, 7.5, 10.0, 15.0, 20.0];
        for &xi in &points {
            for &tau in &points {
                // Grid indices (exact: ξ and τ are multiples of the coarse step 0.05).
                let i = (xi / xi_max * n as f64).round() as usize;
                let j = (tau / tau_max * n as f64).round() as usize;
                let c = coarse[i * (n + 1) + j];
                let f = fine[2 * i * (2 * n + 1) + 2 * j];
                let f2 = fine2[4 * i * (4 * n + 1) + 4 * j];
                // Two levels of Richardson extrapolation (error ~ h², h⁴, ...).
                let r1 = |c: f64, f: f64| (4.0 * f - c) / 3.0;
                let r2 = |c: f64, f: f64, f2: f64| (16.0 * r1(f, f2) - r1(c, f)) / 15.0;
                let num_f = r2(c.0, f.0, f2.0);
                let num_w = r2(c.1, f.1, f2.1);
                // Formula, evaluated at the physical (x, t).
                let x = xi / a;
                let t = tau / b + x / u;
                let (tf, tw) = s.temperatures(x, t);
                let err_raw = ((f2.0 - tf) / dtemp).abs().max(((f2.1 - tw) / dtemp).abs());
                let err = ((num_f - tf) / dtemp).abs().max(((num_w - tw) / dtemp).abs());
                worst_raw = worst_raw.max(err_raw);
                worst_rich = worst_rich.max(err);
                assert!(err < 1e-5, "ξ = {xi}, τ = {tau}: θ error {err}");
            }
        }
        // The unextrapolated finest grid (h = 0.0125) already agrees to O(h²) (about 2e-6);
        // extrapolated, the agreement is about 5e-13.
        assert!(worst_raw < 1e-5, "raw error {worst_raw}");
        assert!(worst_rich < 1e-9, "extrapolated error {worst_rich}");
    }
}
