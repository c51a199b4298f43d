//! Temperature-dependent properties of pipe wall materials.
//!
//! Specific heat and thermal conductivity come from the NIST cryogenic material property
//! correlations (NIST Cryogenics Technologies Group, "Material Properties",
//! <https://trc.nist.gov/cryogenics/materials/materialproperties.htm>; E. D. Marquardt,
//! J. P. Le and R. Radebaugh, "Cryogenic Material Properties Database", 11th International
//! Cryocooler Conference, 2000):
//!
//! | material | property | form | fit range |
//! |----------|----------|------|-----------|
//! | OFHC copper | `c_p` | `log10 y = Σ a_k (log10 T)^k` | 4–300 K |
//! | OFHC copper, RRR = 100 | `k` | `log10 y = (a + c√T + eT + gT^1.5 + iT²) / (1 + b√T + dT + fT^1.5 + hT²)` | 4–300 K |
//! | 304 stainless | `c_p` | `log10 y = Σ a_k (log10 T)^k` | 4–300 K |
//! | 304 stainless | `k` | `log10 y = Σ a_k (log10 T)^k` | 1–300 K |
//!
//! NIST quotes curve-fit errors of about 2 % (conductivity) and 5 % (304 specific heat) relative
//! to the underlying data.
//!
//! # Outside the fit ranges
//!
//! * **Below the lower limit** of a fit the property is held at its value at the limit (the
//!   temperature is clamped). A NaN temperature is treated as the lower limit.
//! * **Above 300 K** each property follows a C¹ quadratic that starts with the value and slope of
//!   the fit at 300 K and reaches zero slope at 330 K, and is constant from there on:
//!   `y(T) = y₀ + y₀′ τ − y₀′ τ²/(2w)` with `τ = min(T − 300 K, w)`, `w = 30 K`. The fits are not
//!   trustworthy past their end point (the 304 `c_p` polynomial turns over near 290 K and has a
//!   *negative* slope at 300 K, so continuing it or holding its slope would make `c_p` fall with
//!   temperature, which is unphysical), while the true properties change by only 1–5 % between
//!   300 K and 350 K, comparable to the fits' own uncertainty. Leveling off in a C¹ way keeps
//!   `c_p` continuous with a continuous derivative (the wall energy `e(T)` is then C²), stays
//!   bounded and positive, and invents no data. The change across the blend is tiny: copper `c_p`
//!   389.4 → 389.7 J/(kg·K), 304 `c_p` 469.4 → 466.0 J/(kg·K), 304 `k` 15.31 → 15.71 W/(m·K),
//!   copper `k` 396.3 → 395.1 W/(m·K).
//!
//! # Wall energy
//!
//! [`WallMaterial::specific_energy_j_kg`] is the exact integral of the `c_p` defined above from
//! 4 K, evaluated with 8-point Gauss–Legendre quadrature on 1 K cells (the cumulative integral at
//! the cell edges is tabulated once per material, on first use). The integrand is smooth inside
//! every cell (the 300 K and 330 K joints are cell edges), so the quadrature error is at round-off
//! level and `de/dT = c_p(T)` holds to round-off. [`WallMaterial::temperature_from_energy`]
//! inverts it by safeguarded Newton iteration inside the bracketing cell.

use std::f64::consts::{LN_10, PI};
use std::sync::OnceLock;

/// Lower end of the `c_p` fits and reference temperature of the wall energy, K.
const T_MIN_K: f64 = 4.0;
/// Upper end of every NIST fit used here, K.
const T_FIT_MAX_K: f64 = 300.0;
/// Width of the C¹ blend from the fit's end point to a constant, K.
const BLEND_WIDTH_K: f64 = 30.0;
/// Temperature from which every property is constant, K.
const T_PLATEAU_K: f64 = T_FIT_MAX_K + BLEND_WIDTH_K;
/// Upper end of the range [`WallMaterial::temperature_from_energy`] clamps to, K. Above the
/// solver's 500 K fluid tables, with margin.
const T_MAX_K: f64 = 550.0;
/// Width of the energy table's quadrature cells, K. Divides both 300 K − 4 K and 330 K − 4 K,
/// so the blend joints are cell edges.
const CELL_K: f64 = 1.0;
/// Number of energy table cells between 4 K and 330 K.
const N_CELLS: usize = 326;
/// Gauss–Legendre points per cell.
const GL_POINTS: usize = 8;

/// NIST OFHC copper specific heat, `log10 c_p = Σ a_k (log10 T)^k`, J/(kg·K), 4–300 K.
const COPPER_CP: [f64; 8] = [-1.91844, -0.15973, 8.61013, -18.996, 21.9661, -12.7328, 3.54322, -0.3797];
/// NIST OFHC copper thermal conductivity for RRR = 100, coefficients `a..i` of the rational form
/// in `√T` (see the module docs), W/(m·K), 4–300 K.
const COPPER_K_RRR100: [f64; 9] =
    [2.2154, -0.47461, -0.88068, 0.13871, 0.29505, -0.02043, -0.04831, 0.001281, 0.003207];
/// NIST 304 stainless steel specific heat, `log10 c_p = Σ a_k (log10 T)^k`, J/(kg·K), 4–300 K.
const SS304_CP: [f64; 8] = [22.0061, -127.5528, 303.647, -381.0098, 274.0328, -112.9212, 24.7593, -2.239153];
/// NIST 304 stainless steel thermal conductivity, `log10 k = Σ a_k (log10 T)^k`, W/(m·K), 1–300 K.
const SS304_K: [f64; 9] = [-1.4087, 1.3982, 0.2543, -0.6260, 0.2334, 0.4256, -0.4658, 0.1650, -0.0199];

/// A pipe wall material.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WallMaterial {
    /// Oxygen-free high-conductivity copper (conductivity for RRR = 100).
    Copper,
    /// Austenitic stainless steel AISI 304.
    Stainless304,
}

impl WallMaterial {
    /// Parses a material name, ASCII case-insensitively and ignoring surrounding whitespace:
    /// `"copper"`, `"ofhc_copper"`, `"cu"` give [`WallMaterial::Copper`]; `"stainless304"`,
    /// `"ss304"`, `"304_stainless"` give [`WallMaterial::Stainless304`]. Anything else is `None`.
    pub fn from_name(name: &str) -> Option<Self> {
        let name = name.trim().to_ascii_lowercase();
        match name.as_str() {
            "copper" | "ofhc_copper" | "cu" => Some(WallMaterial::Copper),
            "stainless304" | "ss304" | "304_stainless" => Some(WallMaterial::Stainless304),
            _ => None,
        }
    }

    /// The canonical name, `"copper"` or `"stainless304"` (the serde name as well).
    pub fn name(self) -> &'static str {
        match self {
            WallMaterial::Copper => "copper",
            WallMaterial::Stainless304 => "stainless304",
        }
    }

    /// Density, kg/m³, taken as constant (8960 for OFHC copper, 7900 for 304 stainless). Thermal
    /// contraction from 300 K to 4 K raises it by under 1 %; the wall mass is what matters for
    /// energy bookkeeping and that does not change.
    pub fn density_kg_m3(self) -> f64 {
        match self {
            WallMaterial::Copper => 8960.0,
            WallMaterial::Stainless304 => 7900.0,
        }
    }

    /// Isobaric specific heat `c_p(T)`, J/(kg·K), from the NIST fit (4–300 K).
    ///
    /// Below 4 K (and for a NaN temperature) the value at 4 K is returned; above 300 K the C¹
    /// level-off described in the module docs applies (constant from 330 K). Never NaN, always
    /// positive.
    pub fn specific_heat_j_kg_k(self, t_k: f64) -> f64 {
        self.cp_correlation().value(t_k)
    }

    /// Thermal conductivity `k(T)`, W/(m·K), from the NIST fit: OFHC copper with RRR = 100
    /// (4–300 K) or 304 stainless steel (1–300 K).
    ///
    /// Below the fit's lower limit (and for a NaN temperature) the value at the limit is
    /// returned; above 300 K the C¹ level-off described in the module docs applies (constant from
    /// 330 K). Never NaN, always positive.
    pub fn conductivity_w_m_k(self, t_k: f64) -> f64 {
        match self {
            WallMaterial::Copper => Correlation { fit: Fit::CopperRational(&COPPER_K_RRR100), t_low: 4.0 },
            WallMaterial::Stainless304 => Correlation { fit: Fit::LogPoly(&SS304_K), t_low: 1.0 },
        }
        .value(t_k)
    }

    /// Specific internal energy `e(T) = ∫ c_p dT` from the reference temperature 4 K to `T`, J/kg
    /// (so `e(4 K) = 0`; the neglected 0–4 K part is about 0.1 J/kg for copper and about 4 J/kg
    /// for 304, irrelevant for differences). Solids are treated as incompressible, so internal
    /// energy and enthalpy coincide.
    ///
    /// `de/dT` equals [`WallMaterial::specific_heat_j_kg_k`] for every temperature, to
    /// round-off: the integral is evaluated with 8-point Gauss–Legendre quadrature on 1 K cells
    /// whose joints include the 300 K and 330 K blend points, so the quadrature is exact to
    /// round-off. Because `c_p` is constant below 4 K and above 330 K, `e` continues linearly
    /// there (negative below 4 K). A NaN temperature is treated as 4 K (energy 0); infinite
    /// temperatures give infinite energies of the same sign, never NaN.
    pub fn specific_energy_j_kg(self, t_k: f64) -> f64 {
        let t = if t_k.is_nan() { T_MIN_K } else { t_k };
        if t <= T_MIN_K {
            return self.specific_heat_j_kg_k(T_MIN_K) * (t - T_MIN_K);
        }
        let table = self.energy_table();
        if t >= T_PLATEAU_K {
            return table.e_plateau + table.cp_plateau * (t - T_PLATEAU_K);
        }
        let cell = (((t - T_MIN_K) / CELL_K) as usize).min(N_CELLS - 1);
        let t_left = T_MIN_K + cell as f64 * CELL_K;
        table.e[cell] + table.integrate(self, t_left, t)
    }

    /// Inverse of [`WallMaterial::specific_energy_j_kg`]: the temperature at which the wall has
    /// specific energy `e_j_kg`, K, clamped to the range 4–400 K.
    ///
    /// Energies at or below `e(4 K) = 0`, `-∞` and NaN give 4 K; energies at or above `e(400 K)`
    /// give 400 K. In between, the cell holding the energy is found in the table and the
    /// temperature is refined by Newton iteration safeguarded by bisection within that cell, to
    /// about 1e-11 K (round-off level).
    pub fn temperature_from_energy(self, e_j_kg: f64) -> f64 {
        if e_j_kg.is_nan() || e_j_kg <= 0.0 {
            return T_MIN_K;
        }
        let table = self.energy_table();
        if e_j_kg >= table.e_plateau {
            // Linear branch: c_p is constant here, so the inverse is exact.
            return (T_PLATEAU_K + (e_j_kg - table.e_plateau) / table.cp_plateau).min(T_MAX_K);
        }
        // e[0] = 0 < e_j_kg < e[N_CELLS], so 1 <= partition_point <= N_CELLS.
        let cell = table.e.partition_point(|&e| e <= e_j_kg) - 1;
        let (e_left, e_right) = (table.e[cell], table.e[cell + 1]);
        let mut lo = T_MIN_K + cell as f64 * CELL_K;
        let mut hi = lo + CELL_K;
        let mut t = lo + CELL_K * (e_j_kg - e_left) / (e_right - e_left);
        for _ in 0..100 {
            let f = self.specific_energy_j_kg(t) - e_j_kg;
            if f == 0.0 {
                return t;
            }
            if f > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let step = f / self.specific_heat_j_kg_k(t);
            if step.abs() <= NEWTON_TOL_K {
                return (t - step).clamp(lo, hi);
            }
            let next = t - step;
            t = if next > lo && next < hi { next } else { 0.5 * (lo + hi) };
            if hi - lo <= NEWTON_TOL_K {
                return t;
            }
        }
        t
    }

    /// The fast tabulated form the solver uses (see [`WallTable`]), built once per material.
    pub fn table(self) -> &'static WallTable {
        static COPPER: OnceLock<WallTable> = OnceLock::new();
        static STAINLESS304: OnceLock<WallTable> = OnceLock::new();
        match self {
            WallMaterial::Copper => COPPER.get_or_init(|| WallTable::build(self)),
            WallMaterial::Stainless304 => STAINLESS304.get_or_init(|| WallTable::build(self)),
        }
    }

    fn cp_correlation(self) -> Correlation {
        match self {
            WallMaterial::Copper => Correlation { fit: Fit::LogPoly(&COPPER_CP), t_low: T_MIN_K },
            WallMaterial::Stainless304 => Correlation { fit: Fit::LogPoly(&SS304_CP), t_low: T_MIN_K },
        }
    }

    fn energy_table(self) -> &'static EnergyTable {
        static COPPER: OnceLock<EnergyTable> = OnceLock::new();
        static STAINLESS304: OnceLock<EnergyTable> = OnceLock::new();
        match self {
            WallMaterial::Copper => COPPER.get_or_init(|| EnergyTable::build(self)),
            WallMaterial::Stainless304 => STAINLESS304.get_or_init(|| EnergyTable::build(self)),
        }
    }
}

/// The wall material in the form the time stepping needs, at a few nanoseconds a call: c_p
/// piecewise linear in T between nodes 0.1 K apart (from the NIST fit at the nodes), and the
/// specific energy its exact integral, a piecewise quadratic. So `d energy/dT = cp` holds exactly
/// and `temperature` inverts `energy` in closed form (a quadratic in each interval): the wall's
/// energy bookkeeping is exact. The interpolated c_p differs from the fit by less than 1e-4
/// relative (near 10 K, where c_p bends most; far less above). Outside 4–400 K the end values of c_p hold (energy continues linearly).
#[derive(Debug)]
pub struct WallTable {
    /// c_p at the nodes, J/(kg K).
    cp: Vec<f64>,
    /// Energy at the nodes, J/kg (0 at 4 K).
    e: Vec<f64>,
}

/// Node spacing of [`WallTable`], K.
const TABLE_STEP_K: f64 = 0.1;

impl WallTable {
    fn build(material: WallMaterial) -> Self {
        let n = ((T_MAX_K - T_MIN_K) / TABLE_STEP_K).round() as usize;
        let cp: Vec<f64> = (0..=n).map(|k| material.specific_heat_j_kg_k(T_MIN_K + k as f64 * TABLE_STEP_K)).collect();
        let mut e = Vec::with_capacity(n + 1);
        let mut sum = 0.0;
        e.push(sum);
        for k in 0..n {
            sum += 0.5 * (cp[k] + cp[k + 1]) * TABLE_STEP_K;
            e.push(sum);
        }
        Self { cp, e }
    }

    fn locate(&self, t_k: f64) -> (usize, f64) {
        let n = self.cp.len() - 1;
        let x = ((t_k - T_MIN_K) / TABLE_STEP_K).clamp(0.0, n as f64);
        let k = (x as usize).min(n - 1);
        (k, (x - k as f64) * TABLE_STEP_K)
    }

    /// c_p at `t_k`, J/(kg K).
    #[inline]
    pub fn cp(&self, t_k: f64) -> f64 {
        let t = if t_k.is_nan() { T_MIN_K } else { t_k };
        let (k, tau) = self.locate(t);
        self.cp[k] + (self.cp[k + 1] - self.cp[k]) * tau / TABLE_STEP_K
    }

    /// Specific energy at `t_k`, J/kg, the integral of [`WallTable::cp`] from 4 K.
    #[inline]
    pub fn energy(&self, t_k: f64) -> f64 {
        let t = if t_k.is_nan() { T_MIN_K } else { t_k };
        let n = self.cp.len() - 1;
        let (t_lo, t_hi) = (T_MIN_K, T_MIN_K + n as f64 * TABLE_STEP_K);
        if t < t_lo {
            return self.cp[0] * (t - t_lo);
        }
        if t > t_hi {
            return self.e[n] + self.cp[n] * (t - t_hi);
        }
        let (k, tau) = self.locate(t);
        let slope = (self.cp[k + 1] - self.cp[k]) / TABLE_STEP_K;
        self.e[k] + self.cp[k] * tau + 0.5 * slope * tau * tau
    }

    /// The temperature with specific energy `e_j_kg`, K: the exact inverse of
    /// [`WallTable::energy`] (NaN gives 4 K).
    pub fn temperature(&self, e_j_kg: f64) -> f64 {
        let n = self.cp.len() - 1;
        if e_j_kg.is_nan() {
            return T_MIN_K;
        }
        if e_j_kg <= 0.0 {
            return T_MIN_K + e_j_kg / self.cp[0];
        }
        if e_j_kg >= self.e[n] {
            return T_MIN_K + n as f64 * TABLE_STEP_K + (e_j_kg - self.e[n]) / self.cp[n];
        }
        let k = (self.e.partition_point(|&v| v <= e_j_kg) - 1).min(n - 1);
        // e_k + c τ + ½ s τ² = e  →  τ = 2 Δ / (c + sqrt(c² + 2 s Δ)) (no cancellation)
        let c = self.cp[k];
        let slope = (self.cp[k + 1] - c) / TABLE_STEP_K;
        let delta = e_j_kg - self.e[k];
        let tau = 2.0 * delta / (c + (c * c + 2.0 * slope * delta).max(0.0).sqrt());
        T_MIN_K + k as f64 * TABLE_STEP_K + tau.clamp(0.0, TABLE_STEP_K)
    }
}

/// Convergence tolerance of the Newton iteration in `temperature_from_energy`, K.
const NEWTON_TOL_K: f64 = 1e-11;

/// The functional form of a NIST fit.
#[derive(Debug, Clone, Copy)]
enum Fit {
    /// `log10 y = Σ a_k (log10 T)^k`.
    LogPoly(&'static [f64]),
    /// `log10 y = (a + c s + e s² + g s³ + i s⁴) / (1 + b s + d s² + f s³ + h s⁴)`, `s = √T`,
    /// coefficients in the order `a..i`.
    CopperRational(&'static [f64; 9]),
}

impl Fit {
    /// Value and temperature derivative of the fit at `t` (inside its range, `t > 0`).
    fn value_and_slope(self, t: f64) -> (f64, f64) {
        match self {
            Fit::LogPoly(a) => {
                let x = t.log10();
                let (mut p, mut dp) = (0.0, 0.0);
                for &coef in a.iter().rev() {
                    dp = dp * x + p;
                    p = p * x + coef;
                }
                // y = 10^p(x), x = log10 T: dy/dT = y ln10 p'(x) / (T ln10) = y p'(x) / T.
                let y = (p * LN_10).exp();
                (y, y * dp / t)
            }
            Fit::CopperRational(c) => {
                let s = t.sqrt();
                let num = [c[0], c[2], c[4], c[6], c[8]];
                let den = [1.0, c[1], c[3], c[5], c[7]];
                let (n, dn) = poly_and_derivative(&num, s);
                let (d, dd) = poly_and_derivative(&den, s);
                let y = (n / d * LN_10).exp();
                // d(log10 y)/ds = (n'd − nd')/d², ds/dT = 1/(2s).
                let dlog10y_ds = (dn * d - n * dd) / (d * d);
                (y, y * LN_10 * dlog10y_ds / (2.0 * s))
            }
        }
    }
}

/// Value and derivative of `Σ c_k x^k`.
fn poly_and_derivative(c: &[f64], x: f64) -> (f64, f64) {
    let (mut p, mut dp) = (0.0, 0.0);
    for &coef in c.iter().rev() {
        dp = dp * x + p;
        p = p * x + coef;
    }
    (p, dp)
}

/// A NIST fit with its lower limit and the common 300 K upper limit plus C¹ level-off.
#[derive(Debug, Clone, Copy)]
struct Correlation {
    fit: Fit,
    t_low: f64,
}

impl Correlation {
    fn value(self, t_k: f64) -> f64 {
        if t_k.is_nan() || t_k <= self.t_low {
            return self.fit.value_and_slope(self.t_low).0;
        }
        if t_k <= T_FIT_MAX_K {
            return self.fit.value_and_slope(t_k).0;
        }
        let (y0, slope) = self.fit.value_and_slope(T_FIT_MAX_K);
        let tau = (t_k - T_FIT_MAX_K).min(BLEND_WIDTH_K);
        y0 + slope * tau * (1.0 - 0.5 * tau / BLEND_WIDTH_K)
    }
}

/// Cumulative `∫ c_p dT` at the 1 K cell edges from 4 K to 330 K, plus the quadrature rule.
#[derive(Debug)]
struct EnergyTable {
    /// Gauss–Legendre nodes on [-1, 1].
    nodes: [f64; GL_POINTS],
    /// Gauss–Legendre weights on [-1, 1].
    weights: [f64; GL_POINTS],
    /// `e[i] = e(4 K + i · 1 K)`, J/kg, `i = 0..=N_CELLS`.
    e: Vec<f64>,
    /// `e(330 K)`, J/kg.
    e_plateau: f64,
    /// `c_p` at and above 330 K, J/(kg·K).
    cp_plateau: f64,
}

impl EnergyTable {
    fn build(material: WallMaterial) -> Self {
        let (nodes, weights) = gauss_legendre();
        let mut table =
            EnergyTable { nodes, weights, e: Vec::with_capacity(N_CELLS + 1), e_plateau: 0.0, cp_plateau: 0.0 };
        let mut sum = 0.0;
        table.e.push(sum);
        for cell in 0..N_CELLS {
            let a = T_MIN_K + cell as f64 * CELL_K;
            sum += table.integrate(material, a, a + CELL_K);
            table.e.push(sum);
        }
        table.e_plateau = sum;
        table.cp_plateau = material.specific_heat_j_kg_k(T_PLATEAU_K);
        table
    }

    /// `∫_a^b c_p dT` by one application of the Gauss–Legendre rule (`[a, b]` inside one cell).
    fn integrate(&self, material: WallMaterial, a: f64, b: f64) -> f64 {
        let half = 0.5 * (b - a);
        let mid = 0.5 * (a + b);
        let cp = material.cp_correlation();
        let sum: f64 = self.nodes.iter().zip(&self.weights).map(|(&x, &w)| w * cp.value(mid + half * x)).sum();
        sum * half
    }
}

/// Nodes and weights of the `GL_POINTS`-point Gauss–Legendre rule on [-1, 1], by Newton iteration
/// on the Legendre polynomial from the usual cosine initial guesses.
fn gauss_legendre() -> ([f64; GL_POINTS], [f64; GL_POINTS]) {
    let n = GL_POINTS;
    let nf = n as f64;
    let mut nodes = [0.0; GL_POINTS];
    let mut weights = [0.0; GL_POINTS];
    // P_n(x) and P_n'(x) by the three-term recurrence.
    let legendre = |x: f64| {
        let (mut p_prev, mut p) = (1.0, x);
        for k in 2..=n {
            let kf = k as f64;
            let p_next = ((2.0 * kf - 1.0) * x * p - (kf - 1.0) * p_prev) / kf;
            p_prev = p;
            p = p_next;
        }
        (p, nf * (x * p - p_prev) / (x * x - 1.0))
    };
    for i in 0..n {
        let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        for _ in 0..100 {
            let (p, dp) = legendre(x);
            let dx = p / dp;
            x -= dx;
            if dx.abs() <= 1e-15 {
                break;
            }
        }
        let (_, dp) = legendre(x);
        nodes[i] = x;
        weights[i] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
    (nodes, weights)
}

#[cfg(test)]
mod tests {
    use super::*;

    const MATERIALS: [WallMaterial; 2] = [WallMaterial::Copper, WallMaterial::Stainless304];

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs()
    }

    /// Composite Simpson reference for `∫_a^b c_p dT` with a fine step.
    fn simpson_cp(m: WallMaterial, a: f64, b: f64) -> f64 {
        let n = (((b - a) / 1e-3).ceil() as usize).next_multiple_of(2);
        let h = (b - a) / n as f64;
        let mut sum = m.specific_heat_j_kg_k(a) + m.specific_heat_j_kg_k(b);
        for i in 1..n {
            let w = if i % 2 == 1 { 4.0 } else { 2.0 };
            sum += w * m.specific_heat_j_kg_k(a + i as f64 * h);
        }
        sum * h / 3.0
    }

    #[test]
    fn fast_table_is_consistent_and_close_to_the_fits() {
        for m in MATERIALS {
            let t = m.table();
            let mut worst: f64 = 0.0;
            let mut temp = 10.0;
            while temp < 399.0 {
                worst = worst.max(rel(t.cp(temp), m.specific_heat_j_kg_k(temp)));
                // the energy is the exact integral of the table's c_p
                let h = 1e-4;
                let fd = (t.energy(temp + h) - t.energy(temp - h)) / (2.0 * h);
                assert!(rel(fd, t.cp(temp)) < 1e-6, "{m:?} at {temp}");
                // and the inverse is exact
                assert!((t.temperature(t.energy(temp)) - temp).abs() < 1e-9, "{m:?} at {temp}");
                // energy differences agree with the fits' integral
                temp += 0.37;
            }
            assert!(worst < 2e-4, "{m:?}: table c_p off by {worst}");
            let d_table = t.energy(290.0) - t.energy(80.0);
            let d_exact = m.specific_energy_j_kg(290.0) - m.specific_energy_j_kg(80.0);
            assert!(rel(d_table, d_exact) < 1e-6);
            assert!(t.temperature(f64::NAN) == 4.0 && t.cp(f64::NAN).is_finite());
        }
    }

    #[test]
    fn names_round_trip_and_aliases() {
        for m in MATERIALS {
            assert_eq!(WallMaterial::from_name(m.name()), Some(m));
            let json = serde_json::to_string(&m).unwrap();
            assert_eq!(json, format!("\"{}\"", m.name()));
            assert_eq!(serde_json::from_str::<WallMaterial>(&json).unwrap(), m);
        }
        for alias in ["copper", "OFHC_Copper", "Cu", " cu "] {
            assert_eq!(WallMaterial::from_name(alias), Some(WallMaterial::Copper), "{alias}");
        }
        for alias in ["stainless304", "SS304", "304_Stainless"] {
            assert_eq!(WallMaterial::from_name(alias), Some(WallMaterial::Stainless304), "{alias}");
        }
        assert_eq!(WallMaterial::from_name("aluminium"), None);
        assert_eq!(WallMaterial::from_name(""), None);
    }

    #[test]
    fn densities() {
        assert_eq!(WallMaterial::Copper.density_kg_m3(), 8960.0);
        assert_eq!(WallMaterial::Stainless304.density_kg_m3(), 7900.0);
    }

    #[test]
    fn gauss_legendre_rule_is_exact_for_degree_15() {
        let (x, w) = gauss_legendre();
        assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-14);
        for degree in 0..16 {
            let got: f64 = x.iter().zip(&w).map(|(&x, &w)| w * x.powi(degree)).sum();
            let exact = if degree % 2 == 1 { 0.0 } else { 2.0 / (degree as f64 + 1.0) };
            assert!((got - exact).abs() < 1e-14, "degree {degree}: {got} vs {exact}");
        }
    }

    #[test]
    fn copper_anchors() {
        let cu = WallMaterial::Copper;
        assert!(rel(cu.specific_heat_j_kg_k(77.0), 196.0) < 0.015);
        assert!(rel(cu.specific_heat_j_kg_k(300.0), 389.0) < 0.015);
        let released = cu.specific_energy_j_kg(290.0) - cu.specific_energy_j_kg(80.0);
        assert!(rel(released, 70.5e3) < 0.02, "{released}");
        // RRR = 100 conductivity: ~550 W/(m·K) at 77 K, ~400 at room temperature.
        assert!(rel(cu.conductivity_w_m_k(77.0), 547.2) < 0.01);
        assert!(rel(cu.conductivity_w_m_k(300.0), 396.3) < 0.01);
    }

    #[test]
    fn stainless_anchors() {
        let ss = WallMaterial::Stainless304;
        // The NIST fit gives 204.5 at 77 K and 469.4 at 300 K (handbook data: ~200 and ~477; the
        // fit's stated error is 5 %).
        assert!(rel(ss.specific_heat_j_kg_k(77.0), 200.0) < 0.05);
        assert!(rel(ss.specific_heat_j_kg_k(300.0), 477.0) < 0.03);
        assert!(rel(ss.conductivity_w_m_k(77.0), 8.0) < 0.03);
        assert!(rel(ss.conductivity_w_m_k(300.0), 15.0) < 0.03);
    }

    /// Values of the fits evaluated independently (Python, straight from the NIST formulas) to
    /// catch transcription or evaluation mistakes.
    #[test]
    fn fits_match_independent_evaluation() {
        let cases = [
            (WallMaterial::Copper, 4.0, 0.0994409, 642.297),
            (WallMaterial::Copper, 20.0, 7.506073, 2422.51),
            (WallMaterial::Copper, 77.0, 195.9209, 547.1997),
            (WallMaterial::Copper, 200.0, 359.0114, 406.952),
            (WallMaterial::Copper, 300.0, 389.4015, 396.324),
            (WallMaterial::Stainless304, 4.0, 2.065986, 0.2723962),
            (WallMaterial::Stainless304, 20.0, 13.45248, 2.168622),
            (WallMaterial::Stainless304, 77.0, 204.493, 7.920652),
            (WallMaterial::Stainless304, 200.0, 416.4285, 12.6327),
            (WallMaterial::Stainless304, 300.0, 469.4488, 15.30865),
        ];
        for (m, t, cp, k) in cases {
            assert!(rel(m.specific_heat_j_kg_k(t), cp) < 1e-5, "{m:?} cp({t})");
            assert!(rel(m.conductivity_w_m_k(t), k) < 1e-5, "{m:?} k({t})");
        }
    }

    #[test]
    fn fit_slopes_match_finite_differences() {
        let fits = [
            (Fit::LogPoly(&COPPER_CP), 4.0),
            (Fit::LogPoly(&SS304_CP), 4.0),
            (Fit::LogPoly(&SS304_K), 1.0),
            (Fit::CopperRational(&COPPER_K_RRR100), 4.0),
        ];
        for (fit, t_low) in fits {
            let mut t = t_low + 0.5;
            while t <= 299.0 {
                let h = 1e-4 * t;
                let fd = (fit.value_and_slope(t + h).0 - fit.value_and_slope(t - h).0) / (2.0 * h);
                let (y, slope) = fit.value_and_slope(t);
                assert!((slope - fd).abs() <= 1e-6 * (y / t).max(slope.abs()), "{fit:?} at {t}: {slope} vs {fd}");
                t += 0.5;
            }
        }
    }

    #[test]
    fn level_off_above_300_k_is_c1_and_bounded() {
        for m in MATERIALS {
            for prop in [WallMaterial::specific_heat_j_kg_k, WallMaterial::conductivity_w_m_k] {
                let h = 1e-3;
                for joint in [T_FIT_MAX_K, T_PLATEAU_K] {
                    let left = (prop(m, joint) - prop(m, joint - h)) / h;
                    let right = (prop(m, joint + h) - prop(m, joint)) / h;
                    assert!((left - right).abs() < 1e-3 * prop(m, joint) / joint, "{m:?} slope jump at {joint}");
                    assert!(rel(prop(m, joint + h), prop(m, joint - h)) < 1e-5);
                }
                let at_300 = prop(m, 300.0);
                for t in [310.0, 330.0, 350.0, 400.0, 1e6] {
                    assert!(rel(prop(m, t), at_300) < 0.03, "{m:?} at {t}");
                }
                assert_eq!(prop(m, 350.0), prop(m, 1e6));
            }
        }
    }

    #[test]
    fn copper_cp_is_monotonic_20_to_300_k() {
        let cu = WallMaterial::Copper;
        let mut prev = cu.specific_heat_j_kg_k(20.0);
        for i in 1..=2800 {
            let t = 20.0 + 0.1 * i as f64;
            let cp = cu.specific_heat_j_kg_k(t);
            assert!(cp > prev, "c_p not increasing at {t} K");
            prev = cp;
        }
    }

    #[test]
    fn energy_differences_match_reference_quadrature() {
        let intervals = [(4.0, 20.0), (20.0, 77.0), (77.0, 300.0), (80.0, 290.0), (250.0, 350.0), (4.0, 350.0)];
        for m in MATERIALS {
            assert_eq!(m.specific_energy_j_kg(T_MIN_K), 0.0);
            for (a, b) in intervals {
                let got = m.specific_energy_j_kg(b) - m.specific_energy_j_kg(a);
                let reference = simpson_cp(m, a, b);
                assert!(rel(got, reference) < 1e-9, "{m:?} {a}..{b}: {got} vs {reference}");
            }
            // Sub-cell intervals too (the per-call quadrature, not just the table).
            for (a, b) in [(4.25, 4.75), (20.1, 20.9), (77.3, 77.35), (299.5, 300.5), (329.7, 331.0)] {
                let got = m.specific_energy_j_kg(b) - m.specific_energy_j_kg(a);
                let reference = simpson_cp(m, a, b);
                assert!(rel(got, reference) < 1e-9, "{m:?} {a}..{b}: {got} vs {reference}");
            }
        }
    }

    #[test]
    fn energy_derivative_is_specific_heat() {
        for m in MATERIALS {
            for h in [1e-4, 1e-3] {
                let mut t = 1.0;
                while t <= 420.0 {
                    let fd = (m.specific_energy_j_kg(t + h) - m.specific_energy_j_kg(t - h)) / (2.0 * h);
                    let cp = m.specific_heat_j_kg_k(t);
                    assert!(rel(fd, cp) < 1e-6, "{m:?} at {t} K (h = {h}): {fd} vs {cp}");
                    t += 0.37;
                }
            }
        }
    }

    #[test]
    fn energy_is_continuous_across_cell_edges() {
        for m in MATERIALS {
            for i in 0..=N_CELLS {
                let t = T_MIN_K + i as f64 * CELL_K;
                let below = m.specific_energy_j_kg(t - 1e-9);
                let at = m.specific_energy_j_kg(t);
                let above = m.specific_energy_j_kg(t + 1e-9);
                let cp = m.specific_heat_j_kg_k(t);
                assert!(below < at && at < above, "{m:?} not monotonic at {t}");
                assert!((above - below - 2e-9 * cp).abs() < 1e-9 * cp + 1e-10 * at.abs(), "{m:?} jump at {t}");
            }
        }
    }

    #[test]
    fn temperature_from_energy_round_trips() {
        for m in MATERIALS {
            let mut t = 20.0;
            while t <= 350.0 {
                let back = m.temperature_from_energy(m.specific_energy_j_kg(t));
                assert!((back - t).abs() < 1e-9, "{m:?}: {t} -> {back}");
                t += 0.173;
            }
            for t in [4.0 + 1e-6, 4.5, 5.0, 19.99, 300.0, 330.0, 350.0, 399.9, 400.0, 500.0, 549.9] {
                let back = m.temperature_from_energy(m.specific_energy_j_kg(t));
                assert!((back - t).abs() < 1e-9, "{m:?}: {t} -> {back}");
            }
        }
    }

    #[test]
    fn temperature_from_energy_clamps() {
        for m in MATERIALS {
            assert_eq!(m.temperature_from_energy(f64::NAN), T_MIN_K);
            assert_eq!(m.temperature_from_energy(-1.0), T_MIN_K);
            assert_eq!(m.temperature_from_energy(0.0), T_MIN_K);
            assert_eq!(m.temperature_from_energy(f64::NEG_INFINITY), T_MIN_K);
            assert_eq!(m.temperature_from_energy(f64::INFINITY), T_MAX_K);
            assert_eq!(m.temperature_from_energy(m.specific_energy_j_kg(1000.0)), T_MAX_K);
            assert_eq!(m.temperature_from_energy(1e300), T_MAX_K);
        }
    }

    #[test]
    fn no_nan_for_odd_inputs() {
        let inputs = [0.0, -0.0, -5.0, 1e-300, 0.5, 1000.0, 1e300, f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
        for m in MATERIALS {
            for t in inputs {
                let cp = m.specific_heat_j_kg_k(t);
                let k = m.conductivity_w_m_k(t);
                assert!(cp.is_finite() && cp > 0.0, "{m:?} cp({t}) = {cp}");
                assert!(k.is_finite() && k > 0.0, "{m:?} k({t}) = {k}");
                let e = m.specific_energy_j_kg(t);
                assert!(!e.is_nan(), "{m:?} e({t}) is NaN");
                if t.is_finite() {
                    assert!(e.is_finite(), "{m:?} e({t}) = {e}");
                }
                let back = m.temperature_from_energy(t);
                assert!((T_MIN_K..=T_MAX_K).contains(&back), "{m:?} T(e = {t}) = {back}");
            }
            // Clamping below the fit: values at the lower limit, NaN treated as the lower limit.
            assert_eq!(m.specific_heat_j_kg_k(-5.0), m.specific_heat_j_kg_k(T_MIN_K));
            assert_eq!(m.specific_heat_j_kg_k(f64::NAN), m.specific_heat_j_kg_k(T_MIN_K));
            assert_eq!(m.specific_energy_j_kg(f64::NAN), 0.0);
        }
    }
}
