//! Piecewise-uniform axes and cubic Hermite basis functions.

use serde::Deserialize;

/// One uniform segment of an axis: `n` equal intervals from `lo` to `hi`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Segment {
    lo: f64,
    hi: f64,
    step: f64,
    inv_step: f64,
    n: usize,
    /// Index of the node at `lo` in the whole axis.
    first: usize,
}

/// A grid axis made of consecutive uniform segments (finer where properties vary fast).
///
/// Locating a coordinate is a scan over at most a handful of segments and one multiplication,
/// with no transcendental function and no binary search.
#[derive(Debug, Clone)]
pub(crate) struct Axis {
    segments: Vec<Segment>,
    nodes: usize,
}

/// Serialized segment: `[lo, hi, intervals]`.
#[derive(Debug, Deserialize)]
pub(crate) struct SegmentSpec(pub f64, pub f64, pub usize);

/// Where a coordinate falls: interval index, fraction in `[0, 1]` and interval width.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Located {
    pub index: usize,
    pub frac: f64,
    pub width: f64,
}

impl Axis {
    pub(crate) fn new(specs: &[SegmentSpec]) -> Result<Self, String> {
        if specs.is_empty() {
            return Err("axis has no segments".into());
        }
        let mut segments = Vec::with_capacity(specs.len());
        let mut first = 0;
        for (k, s) in specs.iter().enumerate() {
            // (`interval_index` needs fewer than 2³² intervals in a segment)
            if !(s.0.is_finite() && s.1.is_finite() && s.1 > s.0 && s.2 > 0 && s.2 <= u32::MAX as usize) {
                return Err(format!("axis segment {k} is malformed ({}..{} in {} intervals)", s.0, s.1, s.2));
            }
            if let Some(prev) = segments.last() {
                let prev: &Segment = prev;
                if (prev.hi - s.0).abs() > 1e-9 * s.0.abs().max(1.0) {
                    return Err(format!("axis segment {k} does not start where segment {} ends", k - 1));
                }
            }
            let step = (s.1 - s.0) / s.2 as f64;
            segments.push(Segment { lo: s.0, hi: s.1, step, inv_step: 1.0 / step, n: s.2, first });
            first += s.2;
        }
        Ok(Self { segments, nodes: first + 1 })
    }

    /// Number of nodes.
    pub(crate) fn len(&self) -> usize {
        self.nodes
    }

    pub(crate) fn lo(&self) -> f64 {
        self.segments[0].lo
    }

    pub(crate) fn hi(&self) -> f64 {
        self.segments[self.segments.len() - 1].hi
    }

    /// Coordinate of node `i`.
    pub(crate) fn node(&self, i: usize) -> f64 {
        for s in &self.segments {
            if i <= s.first + s.n {
                return s.lo + (i - s.first) as f64 * s.step;
            }
        }
        self.hi()
    }

    /// The interval holding `x`, or `None` outside the axis (NaN included).
    #[inline]
    pub(crate) fn locate(&self, x: f64) -> Option<Located> {
        // written so that NaN fails both comparisons
        if !(x >= self.segments[0].lo && x <= self.segments[self.segments.len() - 1].hi) {
            return None;
        }
        let last = self.segments.len() - 1;
        for (k, s) in self.segments.iter().enumerate() {
            if x <= s.hi || k == last {
                let r = (x - s.lo) * s.inv_step;
                let i = interval_index(r, s.n);
                return Some(Located { index: s.first + i, frac: r - i as f64, width: s.step });
            }
        }
        None
    }
}

/// The interval of a segment of `n` intervals (`n` below 2³², [`Axis::new`]) that holds the
/// point at `r` intervals from its start: `r` is in `[0, n]` up to the rounding of the
/// segment's ends, and the upper node belongs to the last interval.
///
/// This is `(r as usize).min(n - 1)` for every `r` (NaN and the infinities included): the
/// truncation saturates at 0 below and, through `u32`, at 2³² − 1 ≥ n − 1 above. It is written
/// through `u32` because the conversion of a double to 64-bit unsigned costs a dozen
/// instructions more on x86-64, and this runs in every table evaluation.
#[inline(always)]
fn interval_index(r: f64, n: usize) -> usize {
    (r as u32 as usize).min(n - 1)
}

/// Cubic Hermite weights along one axis for a point at fraction `t` of an interval of width `h`.
///
/// `a[c]` multiplies the value at corner `c` (0 = lower, 1 = upper), `b[c]` the derivative there;
/// `da`, `db` are the same weights differentiated with respect to the physical coordinate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Weights {
    pub a: [f64; 2],
    pub b: [f64; 2],
    pub da: [f64; 2],
    pub db: [f64; 2],
}

impl Weights {
    #[inline]
    pub(crate) fn new(t: f64, h: f64) -> Self {
        let t2 = t * t;
        let t3 = t2 * t;
        let h00 = 2.0 * t3 - 3.0 * t2 + 1.0;
        let h10 = t3 - 2.0 * t2 + t;
        let h01 = -2.0 * t3 + 3.0 * t2;
        let h11 = t3 - t2;
        let d00 = 6.0 * t2 - 6.0 * t;
        let d10 = 3.0 * t2 - 4.0 * t + 1.0;
        let d11 = 3.0 * t2 - 2.0 * t;
        let inv_h = 1.0 / h;
        Self { a: [h00, h01], b: [h * h10, h * h11], da: [d00 * inv_h, -d00 * inv_h], db: [d10, d11] }
    }
}

/// One-dimensional cubic Hermite interpolation on sorted nodes with stored derivatives.
#[derive(Debug, Clone)]
pub(crate) struct Hermite1 {
    pub x: Vec<f64>,
    /// `values[i * 2 * m + 2 * k]` is column `k` at node `i`, `+1` its derivative.
    pub values: Vec<f64>,
    pub columns: usize,
}

impl Hermite1 {
    /// Interval and weights for `x`, or `None` outside the nodes.
    #[inline]
    pub(crate) fn locate(&self, x: f64) -> Option<(usize, Weights)> {
        let n = self.x.len();
        if !(x >= self.x[0] && x <= self.x[n - 1]) {
            return None;
        }
        let i = match self.x.partition_point(|&v| v <= x) {
            0 => 0,
            k => (k - 1).min(n - 2),
        };
        let h = self.x[i + 1] - self.x[i];
        Some((i, Weights::new((x - self.x[i]) / h, h)))
    }

    /// Value and derivative of column `k` in interval `i`.
    #[inline]
    pub(crate) fn eval(&self, i: usize, w: &Weights, k: usize) -> (f64, f64) {
        let m = 2 * self.columns;
        let lo = &self.values[i * m + 2 * k..i * m + 2 * k + 2];
        let hi = &self.values[(i + 1) * m + 2 * k..(i + 1) * m + 2 * k + 2];
        let v = w.a[0] * lo[0] + w.b[0] * lo[1] + w.a[1] * hi[0] + w.b[1] * hi[1];
        let d = w.da[0] * lo[0] + w.db[0] * lo[1] + w.da[1] * hi[0] + w.db[1] * hi[1];
        (v, d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_locates_nodes_and_segments() {
        let axis = Axis::new(&[SegmentSpec(0.0, 1.0, 4), SegmentSpec(1.0, 3.0, 2)]).unwrap();
        assert_eq!(axis.len(), 7);
        assert_eq!(axis.node(4), 1.0);
        assert_eq!(axis.node(6), 3.0);
        let l = axis.locate(0.6).unwrap();
        assert_eq!(l.index, 2);
        assert!((l.frac - 0.4).abs() < 1e-12);
        let l = axis.locate(3.0).unwrap();
        assert_eq!(l.index, 5);
        assert!((l.frac - 1.0).abs() < 1e-12);
        let l = axis.locate(1.5).unwrap();
        assert_eq!((l.index, l.width), (4, 1.0));
        assert!(axis.locate(-0.1).is_none());
        assert!(axis.locate(f64::NAN).is_none());
        assert!(Axis::new(&[SegmentSpec(0.0, 1.0, 4), SegmentSpec(1.5, 3.0, 2)]).is_err());
    }

    #[test]
    fn interval_index_is_the_saturating_truncation() {
        let reference = |r: f64, n: usize| (r as usize).min(n - 1);
        let ns = [1, 2, 7, 40, 1000, 65_536, u32::MAX as usize - 1, u32::MAX as usize];
        let special = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            -0.0,
            0.0,
            -1e-300,
            -0.999,
            -1.0,
            -1e20,
            f64::MIN_POSITIVE,
            0.5,
            1.0 - f64::EPSILON,
            1.0,
            4_294_967_295.0,
            4_294_967_295.5,
            4_294_967_296.0,
            1e19,
            2e19,
            f64::MAX,
        ];
        for &n in &ns {
            let nf = n as f64;
            let near_n = [nf - 1.0, nf - 0.5, nf - 1e-9, nf, nf + 1e-9, nf + 0.5, nf + 1.0, nf * (1.0 + 1e-15)];
            let sweep = (0..2000).map(|k| (k as f64 - 100.0) * 0.013 * nf.min(1e6) / 7.0);
            for r in special.into_iter().chain(near_n).chain(sweep) {
                assert_eq!(interval_index(r, n), reference(r, n), "r = {r:e}, n = {n}");
            }
        }
    }

    #[test]
    fn hermite_reproduces_cubics() {
        // f(x) = x^3 - 2x on [1, 3] with exact derivatives at the ends
        let f = |x: f64| x * x * x - 2.0 * x;
        let df = |x: f64| 3.0 * x * x - 2.0;
        let h = Hermite1 { x: vec![1.0, 3.0], values: vec![f(1.0), df(1.0), f(3.0), df(3.0)], columns: 1 };
        for x in [1.0, 1.3, 2.0, 2.9, 3.0] {
            let (i, w) = h.locate(x).unwrap();
            let (v, d) = h.eval(i, &w, 0);
            assert!((v - f(x)).abs() < 1e-12, "{x}");
            assert!((d - df(x)).abs() < 1e-12, "{x}");
        }
    }
}
