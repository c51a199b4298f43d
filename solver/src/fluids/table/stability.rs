//! Keeping each phase interpolant thermodynamically stable between its nodes.
//!
//! The node values and derivatives of a table are exact (Helmholtz equation of state), but a
//! cubic Hermite interpolant with exact node slopes overshoots where a property peaks more
//! sharply than the grid resolves: along the pseudo-critical line just above the critical
//! pressure, c_p and the compressibility peak within a fraction of the 0.3–0.5 K node spacing.
//! There the interpolant gave ∂ρ/∂p|T < 0 (a negative compressibility, which turns the pressure
//! equation's diagonal negative), ∂u/∂T|p < 0 and c_p < 0 between nodes: 7 to 110 samples per
//! fluid, all within 2 % of the critical point, none elsewhere.
//!
//! The loader keeps the signs a stable fluid has (∂ρ/∂p|T > 0, ∂u/∂T|p > 0, c_p > 0) in three
//! steps, each of which leaves smooth data untouched, so that only cells at the critical point
//! change:
//!
//! 1. **Grid lines.** Along every pressure row and temperature column, node slopes are limited
//!    as monotone (Fritsch–Carlson) and positivity-preserving cubic interpolation does: ρ
//!    increasing with p and decreasing with T, u increasing with T (each slope of the right sign
//!    and at most three times the secant on either side); c_p, ∂ρ/∂p and ∂u/∂T positive (a
//!    slope `m` of a positive quantity `f` kept within `-3f/h` towards the next node and `3f/h`
//!    towards the previous one).
//! 2. **Cells, screened.** The tensor product can still dip inside a cell although every grid
//!    line is clean. A bicubic Hermite patch is a bicubic Bézier patch, whose value lies in the
//!    convex hull of its 16 control points and whose derivative along an axis is the Bézier
//!    patch of the control points' differences along it: a cell whose c_p control points are
//!    positive, whose density control points do not fall along p and whose energy control
//!    points do not fall along T is stable everywhere. Nearly every cell passes this test; the
//!    others are sampled on a 12 × 12 pattern.
//! 3. **Cells, repaired.** Where samples have the wrong sign, the cross derivatives of that
//!    property at the cell's four corners are halved (ten rounds), then its temperature slopes
//!    too (two rounds). Halving pressure slopes, or temperature slopes further, spreads the
//!    defect to the neighbouring cells one after another, far from the critical point: a
//!    table that this does not clean needs finer nodes there (`tools/fluid_tables.py` refines
//!    oxygen and methane near the critical point for that reason).
//!
//! Limiting a slope changes the interpolant by much less than it already deviated from the
//! equation of state there (the CoolProp check points near the critical point keep their
//! tolerances). [`FluidTable::limiter_report`] counts what changed, and a test holds every
//! shipped table to zero unrepaired cells and zero violations on sampling patterns other
//! than the repair's.

use super::{FluidTable, LANES, MEM_NODE, Phase, PhaseTable};
use crate::fluids::hermite::Axis;

/// Lanes and components in memory: `data[node][component * LANES + property]`.
const RHO: usize = 0;
const U: usize = 1;
const CP: usize = 2;
const VALUE: usize = 0;
const D_P: usize = 1;
const D_T: usize = 2;
const D_PT: usize = 3;

/// Samples per cell and direction where the sufficient condition does not settle a cell.
const REPAIR_SAMPLES: usize = 12;
/// Rounds of halving before the repair gives up on a cell.
const REPAIR_ROUNDS: usize = 12;

/// What the limiter changed in one table.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LimiterReport {
    /// Node slopes limited along grid lines.
    pub slopes_limited: usize,
    /// Cells whose corner derivatives were reduced.
    pub cells_repaired: usize,
    /// Cells still unstable after the repair (0 for every table cryofit ships; a test checks).
    pub cells_unrepaired: usize,
}

/// A state where a phase table's interpolant has the wrong sign for a stable fluid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityViolation {
    /// The phase table.
    pub phase: Phase,
    /// Pressure, Pa.
    pub p: f64,
    /// Temperature, K.
    pub t: f64,
    /// Which quantity: `rho`, `drho_dp`, `du_dt` or `cp`.
    pub what: &'static str,
    /// Its (non-positive) value.
    pub value: f64,
}

fn clamp_slope(m: &mut f64, lo: f64, hi: f64, count: &mut usize) {
    let c = m.clamp(lo, hi);
    if c != *m {
        *m = c;
        *count += 1;
    }
}

/// Limits the slope `comp` of `lane` at every node of a grid line so that the line's cubic
/// Hermite interpolant of a positive quantity (component `value_comp` of `lane`) stays
/// positive: a slope within `-3f/h` towards the next node and `3f/h` towards the previous one.
fn positive_line(
    data: &mut [[f64; MEM_NODE]],
    line: &[(usize, f64)],
    lane: usize,
    value_comp: usize,
    comp: usize,
) -> usize {
    let mut n = 0;
    for k in 0..line.len() {
        let (o, x) = line[k];
        let f = data[o][value_comp * LANES + lane];
        if f <= 0.0 {
            continue;
        }
        let lo = line.get(k + 1).map_or(f64::NEG_INFINITY, |&(_, x1)| -3.0 * f / (x1 - x));
        let hi = if k > 0 { 3.0 * f / (x - line[k - 1].1) } else { f64::INFINITY };
        clamp_slope(&mut data[o][comp * LANES + lane], lo, hi, &mut n);
    }
    n
}

/// Limits the slope `comp` of `lane` along a grid line so that a monotone quantity stays
/// monotone (Fritsch–Carlson: each slope has the sign `sign` and at most three times the
/// secant on either side in magnitude).
fn monotone_line(data: &mut [[f64; MEM_NODE]], line: &[(usize, f64)], lane: usize, comp: usize, sign: f64) -> usize {
    let mut n = 0;
    let secant = |a: usize, data: &[[f64; MEM_NODE]]| {
        let ((oa, xa), (ob, xb)) = (line[a], line[a + 1]);
        sign * (data[ob][lane] - data[oa][lane]) / (xb - xa)
    };
    for k in 0..line.len() {
        let mut hi = f64::INFINITY;
        if k > 0 {
            hi = hi.min(3.0 * secant(k - 1, data).max(0.0));
        }
        if k + 1 < line.len() {
            hi = hi.min(3.0 * secant(k, data).max(0.0));
        }
        let o = line[k].0;
        let mut m = sign * data[o][comp * LANES + lane];
        clamp_slope(&mut m, 0.0, hi, &mut n);
        data[o][comp * LANES + lane] = sign * m;
    }
    n
}

/// Grid-line limits of one phase table (only near the critical point do any bind); returns
/// the number of slopes changed.
fn limit_lines(tab: &mut PhaseTable, p_axis: &Axis, t_axis: &Axis) -> usize {
    let mut cols: Vec<Vec<(usize, f64)>> = Vec::new();
    for j in 0..t_axis.len() {
        let mut run = Vec::new();
        for i in 0..tab.rows.len() {
            match tab.node_offset(i, j) {
                Some(o) => run.push((o, p_axis.node(i))),
                None if !run.is_empty() => cols.push(std::mem::take(&mut run)),
                None => {}
            }
        }
        if !run.is_empty() {
            cols.push(run);
        }
    }
    let rows: Vec<Vec<(usize, f64)>> = (0..tab.rows.len())
        .map(|i| (0..t_axis.len()).filter_map(|j| Some((tab.node_offset(i, j)?, t_axis.node(j)))).collect())
        .collect();
    let data = &mut tab.data;
    let mut n = 0;
    // density's pressure slopes first: its temperature cross slopes are limited relative to them
    for c in &cols {
        n += monotone_line(data, c, RHO, D_P, 1.0);
    }
    for r in &rows {
        // a fluid expands on heating at constant pressure (no fluid cryofit tabulates has a
        // density maximum), so the rows' density interpolants do not cross each other
        n += monotone_line(data, r, RHO, D_T, -1.0);
        n += monotone_line(data, r, U, D_T, 1.0);
        n += positive_line(data, r, CP, VALUE, D_T);
        n += positive_line(data, r, RHO, D_P, D_PT);
    }
    for c in &cols {
        n += positive_line(data, c, CP, VALUE, D_P);
        n += positive_line(data, c, U, D_T, D_PT);
    }
    n
}

/// Bézier control points `[along p][along T]` of `lane` on the cell whose corners are the
/// nodes `o[p corner][T corner]`, with interval widths `hp`, `ht`.
fn control_points(data: &[[f64; MEM_NODE]], o: [[usize; 2]; 2], lane: usize, hp: f64, ht: f64) -> [[f64; 4]; 4] {
    let at = |k: usize, c: usize, comp: usize| data[o[k][c]][comp * LANES + lane];
    // along T at each pressure corner: the value and the d/dp columns
    let along_t = |k: usize, v: usize, d: usize| -> [f64; 4] {
        [at(k, 0, v), at(k, 0, v) + ht / 3.0 * at(k, 0, d), at(k, 1, v) - ht / 3.0 * at(k, 1, d), at(k, 1, v)]
    };
    let (v0, v1) = (along_t(0, VALUE, D_T), along_t(1, VALUE, D_T));
    let (d0, d1) = (along_t(0, D_P, D_PT), along_t(1, D_P, D_PT));
    let mut b = [[0.0; 4]; 4];
    for t in 0..4 {
        b[0][t] = v0[t];
        b[1][t] = v0[t] + hp / 3.0 * d0[t];
        b[2][t] = v1[t] - hp / 3.0 * d1[t];
        b[3][t] = v1[t];
    }
    b
}

/// Whether `lane` keeps its stable sign everywhere on the cell (the sufficient condition of the
/// module documentation).
fn cell_is_stable(b: &[[f64; 4]; 4], lane: usize) -> bool {
    match lane {
        RHO => (0..3).all(|a| (0..4).all(|t| b[a + 1][t] >= b[a][t])),
        U => (0..4).all(|a| (0..3).all(|t| b[a][t + 1] >= b[a][t])),
        _ => b.iter().flatten().all(|&x| x > 0.0),
    }
}

impl FluidTable {
    /// Reduces node derivatives where a cell's interpolant leaves the stable signs (see the
    /// module documentation).
    pub(super) fn enforce_stability(&mut self) -> LimiterReport {
        let mut report = LimiterReport::default();
        for tab in &mut self.phases {
            report.slopes_limited += limit_lines(tab, &self.p_axis, &self.t_axis);
        }
        for phase in Phase::ALL {
            let mut changed = std::collections::BTreeSet::new();
            let mut bad = self.unstable_cells(phase, None);
            for round in 0..=REPAIR_ROUNDS {
                if bad.is_empty() {
                    break;
                }
                if round == REPAIR_ROUNDS {
                    let mut left: Vec<(usize, usize)> = bad.iter().map(|&(i, j, _)| (i, j)).collect();
                    left.dedup();
                    report.cells_unrepaired += left.len();
                    break;
                }
                let tab = &mut self.phases[phase.index()];
                let mut halved = std::collections::BTreeSet::new();
                let mut touched = Vec::new();
                for &(i, j, lane) in &bad {
                    // halve the cross derivatives first, then twice the temperature slopes as
                    // well (the pressure slopes never: halving those, or the temperature slopes
                    // further, spreads the defect to the neighbouring cells, cell after cell,
                    // far from the critical point)
                    let comps: &[usize] = if round < 10 { &[D_PT] } else { &[D_T, D_PT] };
                    changed.insert((i, j));
                    for (a, b) in [(i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1)] {
                        if let Some(o) = tab.node_offset(a, b)
                            && halved.insert((o, lane))
                        {
                            for &c in comps {
                                tab.data[o][c * LANES + lane] *= 0.5;
                            }
                        }
                    }
                    // the changed nodes are corners of the eight cells around this one too
                    for a in i.saturating_sub(1)..=i + 1 {
                        for b in j.saturating_sub(1)..=j + 1 {
                            touched.push((a, b));
                        }
                    }
                }
                touched.sort_unstable();
                touched.dedup();
                bad = self.unstable_cells(phase, Some(&touched));
            }
            report.cells_repaired += changed.len();
        }
        report
    }

    /// Cells `(i, j)` of `phase` (all, or those of `only` that exist) whose interpolant has the
    /// wrong sign somewhere, with the property to blame.
    ///
    /// A cell passes outright when its Bézier control points satisfy the sufficient condition
    /// of the module documentation (nearly every cell); the rest are sampled densely.
    fn unstable_cells(&self, phase: Phase, only: Option<&[(usize, usize)]>) -> Vec<(usize, usize, usize)> {
        let tab = &self.phases[phase.index()];
        let mut out = Vec::new();
        let mut visit = |i: usize, j: usize| {
            let (Some(a), Some(b)) = (tab.node_offset(i, j), tab.node_offset(i + 1, j)) else { return };
            if tab.node_offset(i, j + 1).is_none() || tab.node_offset(i + 1, j + 1).is_none() {
                return;
            }
            let hp = self.p_axis.node(i + 1) - self.p_axis.node(i);
            let ht = self.t_axis.node(j + 1) - self.t_axis.node(j);
            let certain = [RHO, U, CP]
                .iter()
                .all(|&lane| cell_is_stable(&control_points(&tab.data, [[a, a + 1], [b, b + 1]], lane, hp, ht), lane));
            if certain {
                return;
            }
            self.check_cell(phase, i, j, REPAIR_SAMPLES, |v| {
                let lane = match v.what {
                    "cp" => CP,
                    "du_dt" => U,
                    _ => RHO,
                };
                if !out.contains(&(i, j, lane)) {
                    out.push((i, j, lane));
                }
            });
        };
        match only {
            Some(cells) => cells.iter().for_each(|&(i, j)| visit(i, j)),
            None => self.for_each_cell(phase, visit),
        }
        out
    }

    fn for_each_cell(&self, phase: Phase, mut f: impl FnMut(usize, usize)) {
        let tab = &self.phases[phase.index()];
        for i in 0..self.p_axis.len().saturating_sub(1) {
            let Some((lo, last)) = tab.cell_range(i) else { continue };
            for j in lo..last {
                f(i, j);
            }
        }
    }

    fn check_cell(&self, phase: Phase, i: usize, j: usize, samples: usize, mut found: impl FnMut(StabilityViolation)) {
        let (p0, p1) = (self.p_axis.node(i), self.p_axis.node(i + 1));
        let (t0, t1) = (self.t_axis.node(j), self.t_axis.node(j + 1));
        for a in 0..samples {
            let p = p0 + (p1 - p0) * (a as f64 + 0.5) / samples as f64;
            for b in 0..samples {
                let t = t0 + (t1 - t0) * (b as f64 + 0.5) / samples as f64;
                let Ok(s) = self.phase_props(phase, p, t) else { continue };
                for (what, value) in [("rho", s.rho), ("drho_dp", s.drho_dp), ("du_dt", s.du_dt), ("cp", s.cp)] {
                    if value.is_nan() || value <= 0.0 {
                        found(StabilityViolation { phase, p, t, what, value });
                    }
                }
            }
        }
    }

    /// Samples every interpolation cell of both phase tables at `samples × samples` interior
    /// points  for the signs a stable fluid
    /// has: ρ > 0, ∂ρ/∂p|T > 0, ∂u/∂T|p > 0, c_p > 0. One entry per violating sample.
    pub fn stability_violations(&self, samples: usize) -> Vec<StabilityViolation> {
        let mut out = Vec::new();
        for phase in Phase::ALL {
            self.for_each_cell(phase, |i, j| self.check_cell(phase, i, j, samples, |v| out.push(v)));
        }
        out
    }

    /// What loading changed to keep the interpolants stable.
    pub fn limiter_report(&self) -> LimiterReport {
        self.limiter
    }
}
