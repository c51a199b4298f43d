//! The binary table format and its evaluation.

use serde::Deserialize;

use super::hermite::{Axis, Hermite1, Located, SegmentSpec, Weights};
use super::{FluidError, Phase};

mod stability;

pub use stability::{LimiterReport, StabilityViolation};

const MAGIC: &[u8; 8] = b"CRYOFLT1";
const FORMAT_VERSION: u32 = 1;
/// Tabulated properties per node, in this order.
const PROPS: [&str; 5] = ["rho", "u", "cp", "mu", "k"];
const NPROP: usize = PROPS.len();
/// Floats per node in the file: value, d/dp, d/dT, d²/dpdT for every property.
const NODE: usize = 4 * NPROP;
/// Properties per component in memory, padded to an even count for two-wide vector lanes.
const LANES: usize = 6;
/// Floats per node in memory.
const MEM_NODE: usize = 4 * LANES;

/// Constants of a fluid and the limits of its table.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FluidConstants {
    /// Table name (`nitrogen`, `hydrogen`, `parahydrogen`, ...).
    pub name: String,
    /// Human-readable name.
    pub description: String,
    /// CoolProp version the table was generated with.
    pub coolprop_version: String,
    /// Citation key of the equation of state.
    pub eos_reference: String,
    /// Molar mass, kg/mol.
    pub molar_mass_kg_mol: f64,
    /// Specific gas constant R/M, J/(kg K).
    pub gas_constant_j_kg_k: f64,
    /// Triple-point temperature, K.
    pub t_triple_k: f64,
    /// Triple-point pressure, Pa.
    pub p_triple_pa: f64,
    /// Critical temperature, K.
    pub t_critical_k: f64,
    /// Critical pressure, Pa.
    pub p_critical_pa: f64,
    /// Lowest tabulated pressure, Pa.
    pub p_min_pa: f64,
    /// Highest tabulated pressure, Pa.
    pub p_max_pa: f64,
    /// Highest tabulated temperature, K.
    pub t_max_k: f64,
    /// Guaranteed reach of each phase past the saturation line (unless the spinodal is closer), K.
    pub metastable_k: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    format: u32,
    fluid: String,
    description: String,
    #[allow(dead_code)]
    coolprop_name: String,
    coolprop_version: String,
    eos_reference: String,
    molar_mass_kg_mol: f64,
    gas_constant_j_kg_k: f64,
    t_triple_k: f64,
    p_triple_pa: f64,
    t_critical_k: f64,
    p_critical_pa: f64,
    p_min_pa: f64,
    p_max_pa: f64,
    t_max_k: f64,
    metastable_k: f64,
    p_axis: Vec<SegmentSpec>,
    t_axis: Vec<SegmentSpec>,
    properties: Vec<String>,
    phases: PhasesHeader,
    saturation: SatHeader,
    melting_nodes: usize,
    blobs: Vec<(String, usize)>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PhasesHeader {
    liquid: RowsHeader,
    gas: RowsHeader,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RowsHeader {
    row_first: Vec<u32>,
    row_count: Vec<u32>,
    row_spinodal_k: Vec<Option<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SatHeader {
    p_nodes: usize,
    columns: Vec<String>,
    t_nodes: usize,
    t_columns: Vec<String>,
}

/// One pressure row of a phase table.
#[derive(Debug, Clone, Copy)]
struct Row {
    first: u32,
    end: u32,
    start: u32,
}

/// One phase's grid: rows of nodes (one row per pressure node), each row a contiguous run of
/// temperature nodes `row_first .. row_first + row_count`.
#[derive(Debug, Clone)]
struct PhaseTable {
    /// Spinodal temperature where a row ends at the spinodal, else `None`.
    row_spinodal: Vec<Option<f64>>,
    /// Per pressure row: first temperature node, one past the last, and where its nodes start.
    rows: Vec<Row>,
    /// Node data in memory order `[component][property]` (component: value, d/dp, d/dT,
    /// d²/dpdT), so that one pass over the properties vectorises.
    data: Vec<[f64; MEM_NODE]>,
    /// Per pair of pressure rows `i`, `i + 1`: the temperatures of the first and last node of
    /// their usable cells ([`PhaseTable::cell_range`]), where there are any; computed once.
    ranges: Vec<Option<(f64, f64)>>,
}

impl PhaseTable {
    /// Offset (in nodes) of node `(i, j)` if both `j` and `j + 1` are in row `i`.
    #[inline]
    fn cell_offset(&self, i: usize, j: usize) -> Option<usize> {
        let row = self.rows.get(i)?;
        let (first, end) = (row.first as usize, row.end as usize);
        if j < first || j + 1 >= end {
            return None;
        }
        Some(row.start as usize + (j - first))
    }

    /// Offset (in nodes) of node `(i, j)` if it is in row `i`.
    fn node_offset(&self, i: usize, j: usize) -> Option<usize> {
        let row = self.rows.get(i)?;
        let (first, end) = (row.first as usize, row.end as usize);
        (j >= first && j < end).then(|| row.start as usize + (j - first))
    }

    /// The temperature interval of the cells usable between pressure rows `i` and `i + 1`.
    #[inline]
    fn temperature_range(&self, i: usize) -> Option<(f64, f64)> {
        self.ranges.get(i).copied().flatten()
    }

    /// First and last temperature node of the cells usable between pressure rows `i` and `i + 1`.
    fn cell_range(&self, i: usize) -> Option<(usize, usize)> {
        let (a, b) = (self.rows.get(i)?, self.rows.get(i + 1)?);
        if a.end == a.first || b.end == b.first {
            return None;
        }
        let lo = a.first.max(b.first) as usize;
        let (end_a, end_b) = (a.end as usize, b.end as usize);
        let last = end_a.min(end_b).checked_sub(1)?;
        (last > lo).then_some((lo, last))
    }
}

/// The lane of the specific internal energy (the order of [`PROPS`]).
const U: usize = 1;

/// Where a pressure lies on the pressure axis and the Hermite weights there: the pressure half
/// of a table evaluation, which evaluations at one pressure share ([`Isobar`]).
#[derive(Debug, Clone, Copy)]
struct PressureAt {
    p: f64,
    /// The interval and fraction of `p` and their weights; `None` outside the axis (NaN too).
    located: Option<(Located, Weights)>,
}

/// The four corner nodes of a table cell, `(i, j)`, `(i, j+1)`, `(i+1, j)`, `(i+1, j+1)` (`i`
/// the pressure row, `j` the temperature node), and the weights of a state in it along
/// pressure (`wx`) and temperature (`wy`).
///
/// Its evaluations ([`Cell::props`], [`Cell::values`], [`Cell::energy`]) form each quantity
/// with the same operations in the same order, so that a quantity any two of them give has
/// the same bits in both.
struct Cell<'a> {
    n00: &'a [f64; MEM_NODE],
    n01: &'a [f64; MEM_NODE],
    n10: &'a [f64; MEM_NODE],
    n11: &'a [f64; MEM_NODE],
    wx: Weights,
    wy: Weights,
}

impl Cell<'_> {
    /// The properties and their derivatives at pressure `p` (the pressure the cell was found
    /// for).
    #[inline(always)]
    fn props(&self, p: f64) -> PhaseProps {
        let (n00, n01, n10, n11) = (self.n00, self.n01, self.n10, self.n11);
        // Interpolate along T on the two pressure rows (the value and the d/dp component), then
        // along p; straight loops over the property lanes, which the compiler vectorises.
        let (f00, fp00, ft00, fpt00) = (lane(n00, 0), lane(n00, 1), lane(n00, 2), lane(n00, 3));
        let (f01, fp01, ft01, fpt01) = (lane(n01, 0), lane(n01, 1), lane(n01, 2), lane(n01, 3));
        let (f10, fp10, ft10, fpt10) = (lane(n10, 0), lane(n10, 1), lane(n10, 2), lane(n10, 3));
        let (f11, fp11, ft11, fpt11) = (lane(n11, 0), lane(n11, 1), lane(n11, 2), lane(n11, 3));
        let wv = value_weights(&self.wy);
        let wd = slope_weights(&self.wy);
        let g0: [f64; LANES] = along(wv, &f00, &ft00, &f01, &ft01);
        let g1: [f64; LANES] = along(wv, &f10, &ft10, &f11, &ft11);
        let gp0: [f64; LANES] = along(wv, &fp00, &fpt00, &fp01, &fpt01);
        let gp1: [f64; LANES] = along(wv, &fp10, &fpt10, &fp11, &fpt11);
        // T derivatives are needed for density and internal energy only (lanes 0 and 1)
        let gt0: [f64; 2] = along(wd, &f00, &ft00, &f01, &ft01);
        let gt1: [f64; 2] = along(wd, &f10, &ft10, &f11, &ft11);
        let gpt0: [f64; 2] = along(wd, &fp00, &fpt00, &fp01, &fpt01);
        let gpt1: [f64; 2] = along(wd, &fp10, &fpt10, &fp11, &fpt11);
        let v: [f64; LANES] = along(value_weights(&self.wx), &g0, &gp0, &g1, &gp1);
        let dp: [f64; 2] = along(slope_weights(&self.wx), &g0, &gp0, &g1, &gp1);
        let dt: [f64; 2] = along(value_weights(&self.wx), &gt0, &gpt0, &gt1, &gpt1);
        let rho = v[0];
        let inv_rho = 1.0 / rho;
        let p_rho2 = p * inv_rho * inv_rho;
        PhaseProps {
            rho,
            drho_dp: dp[0],
            drho_dt: dt[0],
            u: v[U],
            du_dp: dp[U],
            du_dt: dt[U],
            h: v[U] + p * inv_rho,
            dh_dp: dp[U] + inv_rho - p_rho2 * dp[0],
            dh_dt: dt[U] - p_rho2 * dt[0],
            cp: v[2],
            mu: v[3],
            k: v[4],
        }
    }

    /// The tabulated values without derivatives: the `v` of [`Cell::props`] alone.
    #[inline]
    fn values(&self) -> PhaseValues {
        let (n00, n01, n10, n11) = (self.n00, self.n01, self.n10, self.n11);
        let wv = value_weights(&self.wy);
        let g0: [f64; LANES] = along(wv, &lane(n00, 0), &lane(n00, 2), &lane(n01, 0), &lane(n01, 2));
        let g1: [f64; LANES] = along(wv, &lane(n10, 0), &lane(n10, 2), &lane(n11, 0), &lane(n11, 2));
        let gp0: [f64; LANES] = along(wv, &lane(n00, 1), &lane(n00, 3), &lane(n01, 1), &lane(n01, 3));
        let gp1: [f64; LANES] = along(wv, &lane(n10, 1), &lane(n10, 3), &lane(n11, 1), &lane(n11, 3));
        let v: [f64; LANES] = along(value_weights(&self.wx), &g0, &gp0, &g1, &gp1);
        PhaseValues { rho: v[0], u: v[U], cp: v[2], mu: v[3], k: v[4] }
    }

    /// Specific internal energy u and ∂u/∂T at constant p: the energy lane of [`Cell::props`]
    /// alone (its `v[U]` and `dt[U]`).
    #[inline]
    fn energy(&self) -> (f64, f64) {
        // component `comp` (value, d/dp, d/dT, d²/dpdT) of the energy lane at a node
        let e = |n: &[f64; MEM_NODE], comp: usize| n[comp * LANES + U];
        // along T from node `a` (j) to node `b` (j + 1) of one pressure row: component `comp`
        // (value 0 or d/dp 1) with its d/dT companion (`comp + 2`), the operands `along` takes
        // for lane U of `g*`, `gp*` (weights `wv`) and `gt*`, `gpt*` (weights `wd`)
        let row = |w: [f64; 4], a: &[f64; MEM_NODE], b: &[f64; MEM_NODE], comp: usize| {
            hermite4(w, e(a, comp), e(a, comp + 2), e(b, comp), e(b, comp + 2))
        };
        let (n00, n01, n10, n11) = (self.n00, self.n01, self.n10, self.n11);
        let (wv, wd) = (value_weights(&self.wy), slope_weights(&self.wy));
        let (g0, g1) = (row(wv, n00, n01, 0), row(wv, n10, n11, 0));
        let (gp0, gp1) = (row(wv, n00, n01, 1), row(wv, n10, n11, 1));
        let (gt0, gt1) = (row(wd, n00, n01, 0), row(wd, n10, n11, 0));
        let (gpt0, gpt1) = (row(wd, n00, n01, 1), row(wd, n10, n11, 1));
        let wxv = value_weights(&self.wx);
        (hermite4(wxv, g0, gp0, g1, gp1), hermite4(wxv, gt0, gpt0, gt1, gpt1))
    }
}

/// Component `comp` (value, d/dp, d/dT, d²/dpdT) of every property lane of a node.
#[inline(always)]
fn lane(n: &[f64; MEM_NODE], comp: usize) -> [f64; LANES] {
    let mut out = [0.0; LANES];
    for (o, x) in out.iter_mut().zip(&n[comp * LANES..comp * LANES + LANES]) {
        *o = *x;
    }
    out
}

/// One cubic Hermite combination `w · (a, a', b, b')`, summed left to right. Every table
/// interpolation goes through it, so that each evaluation gives a value the same bits.
#[inline(always)]
fn hermite4(w: [f64; 4], a: f64, at: f64, b: f64, bt: f64) -> f64 {
    w[0] * a + w[1] * at + w[2] * b + w[3] * bt
}

/// [`hermite4`] on the first `N` lanes; a straight loop, which the compiler vectorises.
#[inline(always)]
fn along<const N: usize>(w: [f64; 4], a: &[f64], at: &[f64], b: &[f64], bt: &[f64]) -> [f64; N] {
    let mut out = [0.0; N];
    for q in 0..N {
        out[q] = hermite4(w, a[q], at[q], b[q], bt[q]);
    }
    out
}

/// The weights of a value, in the order of [`hermite4`]'s operands.
#[inline(always)]
fn value_weights(w: &Weights) -> [f64; 4] {
    [w.a[0], w.b[0], w.a[1], w.b[1]]
}

/// The weights of a derivative along the axis, in the order of [`hermite4`]'s operands.
#[inline(always)]
fn slope_weights(w: &Weights) -> [f64; 4] {
    [w.da[0], w.db[0], w.da[1], w.db[1]]
}

/// Properties of one phase at a pressure and temperature, with the partial derivatives the
/// implicit scheme needs (SI units; `_dp` at constant T, `_dt` at constant p).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PhaseProps {
    /// Density ρ, kg/m³.
    pub rho: f64,
    /// ∂ρ/∂p at constant T, kg/m³/Pa.
    pub drho_dp: f64,
    /// ∂ρ/∂T at constant p, kg/m³/K.
    pub drho_dt: f64,
    /// Specific internal energy u, J/kg.
    pub u: f64,
    /// ∂u/∂p at constant T, J/kg/Pa.
    pub du_dp: f64,
    /// ∂u/∂T at constant p, J/kg/K.
    pub du_dt: f64,
    /// Specific enthalpy h = u + p/ρ, J/kg.
    pub h: f64,
    /// ∂h/∂p at constant T, J/kg/Pa.
    pub dh_dp: f64,
    /// ∂h/∂T at constant p, J/kg/K (the interpolant's; `cp` is the tabulated value).
    pub dh_dt: f64,
    /// Isobaric specific heat c_p, J/kg/K.
    pub cp: f64,
    /// Dynamic viscosity μ, Pa s.
    pub mu: f64,
    /// Thermal conductivity k, W/m/K.
    pub k: f64,
}

/// The tabulated values of one phase at a pressure and temperature, without derivatives
/// ([`Isobar::values`]; each the same bits as in [`PhaseProps`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhaseValues {
    /// Density ρ, kg/m³.
    pub rho: f64,
    /// Specific internal energy u, J/kg.
    pub u: f64,
    /// Isobaric specific heat c_p, J/kg/K.
    pub cp: f64,
    /// Dynamic viscosity μ, Pa s.
    pub mu: f64,
    /// Thermal conductivity k, W/m/K.
    pub k: f64,
}

/// Saturation properties at a pressure, with derivatives along the saturation line.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Saturation {
    /// Pressure, Pa.
    pub pressure_pa: f64,
    /// Saturation temperature, K.
    pub t_sat: f64,
    /// dT_sat/dp, K/Pa.
    pub dt_sat_dp: f64,
    /// Saturated liquid density, kg/m³.
    pub rho_l: f64,
    /// dρ_l,sat/dp.
    pub drho_l_dp: f64,
    /// Saturated vapour density, kg/m³.
    pub rho_g: f64,
    /// dρ_g,sat/dp.
    pub drho_g_dp: f64,
    /// Saturated liquid enthalpy, J/kg.
    pub h_l: f64,
    /// dh_l,sat/dp.
    pub dh_l_dp: f64,
    /// Saturated vapour enthalpy, J/kg.
    pub h_g: f64,
    /// dh_g,sat/dp.
    pub dh_g_dp: f64,
    /// Latent heat h_g − h_l, J/kg.
    pub h_lg: f64,
    /// Surface tension, N/m.
    pub sigma: f64,
    /// dσ/dp along the saturation line, N/m/Pa.
    pub dsigma_dp: f64,
}

/// The stable state at `(p, T)`, as `cryofit props` reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StableState {
    /// `liquid`, `gas` or `supercritical`.
    pub label: &'static str,
    /// The phase table that answered.
    pub phase: Phase,
    /// Properties.
    pub props: PhaseProps,
    /// Saturation temperature at that pressure, where there is one.
    pub t_sat: Option<f64>,
}

/// A loaded fluid property table. Cheap to share (`&FluidTable` is all evaluation needs).
#[derive(Debug, Clone)]
pub struct FluidTable {
    constants: FluidConstants,
    p_axis: Axis,
    t_axis: Axis,
    phases: [PhaseTable; 2],
    sat_p: Hermite1,
    sat_t: Hermite1,
    melt: Vec<f64>,
    /// Node slopes the loader limited to keep the interpolants stable.
    limiter: LimiterReport,
}

fn format_err(msg: impl Into<String>) -> FluidError {
    FluidError::Format(msg.into())
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], FluidError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or_else(|| {
            format_err(format!(
                "truncated: needs {n} more bytes at offset {}, has {}",
                self.pos,
                self.bytes.len() - self.pos
            ))
        })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn f32s(&mut self, n: usize) -> Result<Vec<f32>, FluidError> {
        let raw = self.take(n.checked_mul(4).ok_or_else(|| format_err("blob too large"))?)?;
        Ok(raw.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
    }

    fn f64s(&mut self, n: usize) -> Result<Vec<f64>, FluidError> {
        let raw = self.take(n.checked_mul(8).ok_or_else(|| format_err("blob too large"))?)?;
        Ok(raw.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("chunk of 8"))).collect())
    }
}

impl FluidTable {
    /// Parses a table written by `tools/fluid_tables.py`.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, FluidError> {
        let mut r = Reader { bytes, pos: 0 };
        if r.take(8)? != MAGIC {
            return Err(format_err("not a cryofit fluid table (bad magic bytes)"));
        }
        let len = u32::from_le_bytes(r.take(4)?.try_into().expect("4 bytes")) as usize;
        let header: Header = serde_json::from_slice(r.take(len)?).map_err(|e| format_err(format!("header: {e}")))?;
        if header.format != FORMAT_VERSION {
            return Err(format_err(format!(
                "format version {} (this build reads version {FORMAT_VERSION}); regenerate with tools/fluid_tables.py",
                header.format
            )));
        }
        if header.properties != PROPS {
            return Err(format_err(format!("properties {:?}, expected {PROPS:?}", header.properties)));
        }
        let p_axis = Axis::new(&header.p_axis).map_err(|e| format_err(format!("pressure axis: {e}")))?;
        let t_axis = Axis::new(&header.t_axis).map_err(|e| format_err(format!("temperature axis: {e}")))?;
        let expect_blobs = ["f32", "f32", "f64", "f64", "f64", "f64", "f64"];
        if header.blobs.len() != expect_blobs.len()
            || header.blobs.iter().zip(expect_blobs).any(|((kind, _), want)| kind != want)
        {
            return Err(format_err("unexpected blob layout"));
        }
        let mut phases = Vec::with_capacity(2);
        for (k, rows) in [&header.phases.liquid, &header.phases.gas].into_iter().enumerate() {
            let n_rows = rows.row_first.len();
            if n_rows != p_axis.len() || rows.row_count.len() != n_rows || rows.row_spinodal_k.len() != n_rows {
                return Err(format_err(format!("phase {k}: {n_rows} rows for {} pressure nodes", p_axis.len())));
            }
            let mut row_start = Vec::with_capacity(n_rows);
            let mut total: u32 = 0;
            for (f, c) in rows.row_first.iter().zip(&rows.row_count) {
                if (*f as usize + *c as usize) > t_axis.len() {
                    return Err(format_err(format!("phase {k}: a row runs past the temperature axis")));
                }
                row_start.push(total);
                total += c;
            }
            let want = total as usize * NODE;
            if header.blobs[k].1 != want {
                return Err(format_err(format!("phase {k}: {} floats for {total} nodes", header.blobs[k].1)));
            }
            let data = r.f32s(want)?;
            if data.iter().any(|v| !v.is_finite()) {
                return Err(format_err(format!("phase {k}: non-finite node data")));
            }
            // file order is [property][component]; transpose to [component][property]
            let data: Vec<[f64; MEM_NODE]> = data
                .chunks_exact(NODE)
                .map(|n| {
                    let mut out = [0.0f64; MEM_NODE];
                    for q in 0..NPROP {
                        for c in 0..4 {
                            out[c * LANES + q] = n[4 * q + c] as f64;
                        }
                    }
                    out
                })
                .collect();
            phases.push(PhaseTable {
                row_spinodal: rows.row_spinodal_k.clone(),
                rows: rows
                    .row_first
                    .iter()
                    .zip(&rows.row_count)
                    .zip(&row_start)
                    .map(|((&first, &count), &start)| Row { first, end: first + count, start })
                    .collect(),
                data,
                ranges: Vec::new(),
            });
        }
        for tab in &mut phases {
            tab.ranges = (0..tab.rows.len().saturating_sub(1))
                .map(|i| tab.cell_range(i).map(|(lo, hi)| (t_axis.node(lo), t_axis.node(hi))))
                .collect();
        }
        let sat = &header.saturation;
        if sat.columns.len() != 12 || sat.t_columns.len() != 2 {
            return Err(format_err("saturation columns"));
        }
        let sat_p_x = r.f64s(header.blobs[2].1)?;
        let sat_p_v = r.f64s(header.blobs[3].1)?;
        let sat_t_x = r.f64s(header.blobs[4].1)?;
        let sat_t_v = r.f64s(header.blobs[5].1)?;
        let melt = r.f64s(header.blobs[6].1)?;
        if sat_p_x.len() != sat.p_nodes
            || sat_p_v.len() != sat.p_nodes * 12
            || sat_t_x.len() != sat.t_nodes
            || sat_t_v.len() != sat.t_nodes * 2
            || melt.len() != header.melting_nodes
            || melt.len() != p_axis.len()
            || sat.p_nodes < 2
            || sat.t_nodes < 2
        {
            return Err(format_err("saturation or melting table sizes do not match the header"));
        }
        if sat_p_x.windows(2).any(|w| w[1] <= w[0]) || sat_t_x.windows(2).any(|w| w[1] <= w[0]) {
            return Err(format_err("saturation nodes are not increasing"));
        }
        if r.pos != bytes.len() {
            return Err(format_err(format!("{} trailing bytes", bytes.len() - r.pos)));
        }
        let constants = FluidConstants {
            name: header.fluid,
            description: header.description,
            coolprop_version: header.coolprop_version,
            eos_reference: header.eos_reference,
            molar_mass_kg_mol: header.molar_mass_kg_mol,
            gas_constant_j_kg_k: header.gas_constant_j_kg_k,
            t_triple_k: header.t_triple_k,
            p_triple_pa: header.p_triple_pa,
            t_critical_k: header.t_critical_k,
            p_critical_pa: header.p_critical_pa,
            p_min_pa: header.p_min_pa,
            p_max_pa: header.p_max_pa,
            t_max_k: header.t_max_k,
            metastable_k: header.metastable_k,
        };
        let [liquid, gas]: [PhaseTable; 2] = phases.try_into().expect("two phases");
        let mut table = Self {
            constants,
            p_axis,
            t_axis,
            phases: [liquid, gas],
            sat_p: Hermite1 { x: sat_p_x, values: sat_p_v, columns: 6 },
            sat_t: Hermite1 { x: sat_t_x, values: sat_t_v, columns: 1 },
            melt,
            limiter: LimiterReport::default(),
        };
        table.limiter = table.enforce_stability();
        Ok(table)
    }

    /// Fluid constants and table limits.
    pub fn constants(&self) -> &FluidConstants {
        &self.constants
    }

    /// Table name.
    pub fn name(&self) -> &str {
        &self.constants.name
    }

    fn out_of_range(&self, phase: Option<Phase>, p: f64, t: f64, reason: impl Into<String>) -> FluidError {
        FluidError::OutOfRange {
            fluid: self.constants.name.clone(),
            phase,
            pressure_pa: p,
            temperature_k: t,
            reason: reason.into(),
        }
    }

    fn range_error(&self, phase: Phase, p: f64, t: f64) -> FluidError {
        let c = &self.constants;
        if !p.is_finite() || !t.is_finite() {
            return self.out_of_range(Some(phase), p, t, "pressure and temperature must be finite numbers");
        }
        if !(p >= self.p_axis.lo() && p <= self.p_axis.hi()) {
            return self.out_of_range(
                Some(phase),
                p,
                t,
                format!("pressure must be within {} to {} Pa", self.p_axis.lo(), self.p_axis.hi()),
            );
        }
        if !(t >= self.t_axis.lo() && t <= self.t_axis.hi()) {
            return self.out_of_range(
                Some(phase),
                p,
                t,
                format!("temperature must be within {} K (triple point) to {} K", self.t_axis.lo(), self.t_axis.hi()),
            );
        }
        let range = self.phase_temperature_range(phase, p);
        let detail = match range {
            Some((lo, hi)) => format!("at this pressure the {phase} table spans {lo:.3} to {hi:.3} K"),
            None => format!("the {phase} table has no states at this pressure"),
        };
        let what = match phase {
            Phase::Liquid => "superheated liquid is tabulated",
            Phase::Gas => "subcooled vapour is tabulated",
        };
        self.out_of_range(
            Some(phase),
            p,
            t,
            format!("{what} up to {} K past saturation or to near the spinodal; {detail}", c.metastable_k),
        )
    }

    /// The temperature interval the `phase` table answers at pressure `p`, if any.
    pub fn phase_temperature_range(&self, phase: Phase, p: f64) -> Option<(f64, f64)> {
        self.phases[phase.index()].temperature_range(self.p_axis.locate(p)?.index)
    }

    /// Where the `phase` table ends at the spinodal near pressure `p`: the spinodal temperature
    /// (interpolated between the two pressure rows around `p`, or that of the one row of the two
    /// that ends at the spinodal), or `None` where the table ends
    /// for another reason (the 20 K reach, the triple point, the critical temperature).
    pub fn spinodal_temperature(&self, phase: Phase, p: f64) -> Option<f64> {
        let lp = self.p_axis.locate(p)?;
        let rows = &self.phases[phase.index()].row_spinodal;
        match (rows[lp.index], rows[lp.index + 1]) {
            (Some(a), Some(b)) => Some(a + (b - a) * lp.frac),
            // one row ended at the spinodal, the other at its 20 K reach: the spinodal limits
            (Some(a), None) | (None, Some(a)) => Some(a),
            (None, None) => None,
        }
    }

    /// Where pressure `p` lies on the pressure axis, and the Hermite weights there.
    #[inline(always)]
    fn pressure_at(&self, p: f64) -> PressureAt {
        PressureAt { p, located: self.p_axis.locate(p).map(|lp| (lp, Weights::new(lp.frac, lp.width))) }
    }

    /// The cell of the `phase` table that answers `(p, T)` (`p` located in `at`): its four
    /// corner nodes and the weights of the state in it. The one lookup behind
    /// [`FluidTable::phase_props`] and the evaluations of an [`Isobar`], so that all of them
    /// answer (or refuse) the same states from the same cell with the same weights.
    #[inline(always)]
    fn cell(&self, phase: Phase, at: &PressureAt, t: f64) -> Result<Cell<'_>, FluidError> {
        let (Some((mut lp, mut wx)), Some(mut lt)) = (at.located, self.t_axis.locate(t)) else {
            return Err(self.range_error(phase, at.p, t));
        };
        let tab = &self.phases[phase.index()];
        let (o0, o1) = match (tab.cell_offset(lp.index, lt.index), tab.cell_offset(lp.index + 1, lt.index)) {
            (Some(a), Some(b)) => (a, b),
            _ => {
                let Some((i, fi, j, fj)) = self.edge_cell(tab, &lp, &lt) else {
                    return Err(self.range_error(phase, at.p, t));
                };
                (lp.index, lp.frac, lt.index, lt.frac) = (i, fi, j, fj);
                // the weights of the pressure fraction in the cell the state moved to (the
                // interval width stays that of the cell `p` located in)
                wx = Weights::new(lp.frac, lp.width);
                (
                    tab.cell_offset(lp.index, lt.index).expect("checked cell"),
                    tab.cell_offset(lp.index + 1, lt.index).expect("checked cell"),
                )
            }
        };
        let data = &tab.data;
        Ok(Cell {
            n00: &data[o0],
            n01: &data[o0 + 1],
            n10: &data[o1],
            n11: &data[o1 + 1],
            wx,
            wy: Weights::new(lt.frac, lt.width),
        })
    }

    /// A state on the edge of the coverage may round into the neighbouring (missing) cell: the
    /// cell it borders, with the fraction just past 0 or 1 (pressure index and fraction,
    /// temperature index and fraction), or `None` where it borders none.
    #[cold]
    #[inline(never)]
    fn edge_cell(&self, tab: &PhaseTable, lp: &Located, lt: &Located) -> Option<(usize, f64, usize, f64)> {
        const EDGE: f64 = 1e-9;
        let cell_ok = |i: usize, j: usize| tab.cell_offset(i, j).is_some() && tab.cell_offset(i + 1, j).is_some();
        let np = self.p_axis.len() - 1;
        let nt = self.t_axis.len() - 1;
        let ip = [(lp.index, lp.frac), (lp.index.wrapping_sub(1), lp.frac + 1.0), (lp.index + 1, lp.frac - 1.0)];
        let it = [(lt.index, lt.frac), (lt.index.wrapping_sub(1), lt.frac + 1.0), (lt.index + 1, lt.frac - 1.0)];
        let near = |f: f64| (-EDGE..=1.0 + EDGE).contains(&f);
        ip.iter()
            .flat_map(|a| it.iter().map(move |b| (*a, *b)))
            .find(|&((i, fi), (j, fj))| i < np && j < nt && near(fi) && near(fj) && cell_ok(i, j))
            .map(|((i, fi), (j, fj))| (i, fi, j, fj))
    }

    /// Properties of `phase` at `(p, T)`, with derivatives.
    ///
    /// The phase is taken as given: a liquid above its saturation temperature is a superheated
    /// (metastable) liquid, evaluated on the continuation of the liquid equation of state.
    #[inline]
    pub fn phase_props(&self, phase: Phase, p: f64, t: f64) -> Result<PhaseProps, FluidError> {
        Ok(self.cell(phase, &self.pressure_at(p), t)?.props(p))
    }

    /// The `phase` table at pressure `p`, for several evaluations there: the pressure is
    /// located on the table's axis once. Each evaluation gives bit for bit what the
    /// corresponding `FluidTable` method gives at `(phase, p)`.
    #[inline]
    pub fn isobar(&self, phase: Phase, p: f64) -> Isobar<'_> {
        Isobar { table: self, phase, at: self.pressure_at(p) }
    }

    /// Temperature of `phase` at pressure `p` with specific internal energy `u`, and the
    /// properties there. `t_guess` (for example the previous time level's temperature) speeds up
    /// the Newton iteration; the answer does not depend on it.
    pub fn temperature_from_energy(
        &self,
        phase: Phase,
        p: f64,
        u: f64,
        t_guess: f64,
    ) -> Result<(f64, PhaseProps), FluidError> {
        self.isobar(phase, p).temperature_from_energy(u, t_guess)
    }

    /// Saturation properties at pressure `p` (from the triple-point pressure to 0.995 of the
    /// critical pressure; closer to the critical point the latent heat vanishes and the
    /// derivatives along the saturation line diverge).
    pub fn saturation(&self, p: f64) -> Result<Saturation, FluidError> {
        let Some((i, w)) = self.sat_p.locate(p) else {
            let (lo, hi) = (self.sat_p.x[0], self.sat_p.x[self.sat_p.x.len() - 1]);
            return Err(FluidError::NoSaturation {
                fluid: self.constants.name.clone(),
                quantity: "pressure_pa",
                value: p,
                reason: format!(
                    "saturation is tabulated from {lo:.6} Pa (triple point) to {hi:.6} Pa (near the critical point)"
                ),
            });
        };
        let s = &self.sat_p;
        let (t_sat, dt_sat_dp) = s.eval(i, &w, 0);
        let (rho_l, drho_l_dp) = s.eval(i, &w, 1);
        let (rho_g, drho_g_dp) = s.eval(i, &w, 2);
        let (h_l, dh_l_dp) = s.eval(i, &w, 3);
        let (h_g, dh_g_dp) = s.eval(i, &w, 4);
        let (sigma, dsigma_dp) = s.eval(i, &w, 5);
        Ok(Saturation {
            pressure_pa: p,
            t_sat,
            dt_sat_dp,
            rho_l,
            drho_l_dp,
            rho_g,
            drho_g_dp,
            h_l,
            dh_l_dp,
            h_g,
            dh_g_dp,
            h_lg: h_g - h_l,
            sigma: sigma.max(0.0),
            dsigma_dp,
        })
    }

    /// Saturation pressure at temperature `t` and its derivative dp_sat/dT.
    pub fn saturation_pressure(&self, t: f64) -> Result<(f64, f64), FluidError> {
        let Some((i, w)) = self.sat_t.locate(t) else {
            let (lo, hi) = (self.sat_t.x[0], self.sat_t.x[self.sat_t.x.len() - 1]);
            return Err(FluidError::NoSaturation {
                fluid: self.constants.name.clone(),
                quantity: "temperature_k",
                value: t,
                reason: format!(
                    "saturation is tabulated from {lo:.4} K (triple point) to {hi:.4} K (near the critical point)"
                ),
            });
        };
        Ok(self.sat_t.eval(i, &w, 0))
    }

    /// Surface tension at temperature `t` (on the saturation line), N/m.
    pub fn surface_tension(&self, t: f64) -> Result<f64, FluidError> {
        let (p, _) = self.saturation_pressure(t)?;
        Ok(self.saturation(p.clamp(self.sat_p.x[0], self.sat_p.x[self.sat_p.x.len() - 1]))?.sigma)
    }

    /// Melting temperature at pressure `p` (the triple-point temperature where the melting line
    /// lies below it), K.
    pub fn melting_temperature(&self, p: f64) -> Option<f64> {
        let lp = self.p_axis.locate(p)?;
        let (a, b) = (self.melt[lp.index], self.melt[lp.index + 1]);
        Some(a + (b - a) * lp.frac)
    }

    /// The thermodynamically stable state at `(p, T)`: liquid below saturation, gas above it,
    /// supercritical above the critical pressure. States below the melting line are rejected
    /// here (the phase tables still answer them as supercooled liquid).
    pub fn stable_state(&self, p: f64, t: f64) -> Result<StableState, FluidError> {
        let c = &self.constants;
        if !(p.is_finite() && t.is_finite()) {
            return Err(self.out_of_range(None, p, t, "pressure and temperature must be finite numbers"));
        }
        if !(p >= c.p_min_pa && p <= c.p_max_pa) {
            return Err(self.out_of_range(
                None,
                p,
                t,
                format!("pressure must be within {} to {} Pa", c.p_min_pa, c.p_max_pa),
            ));
        }
        let t_melt = self.melting_temperature(p).unwrap_or(c.t_triple_k);
        if !(t >= t_melt && t <= c.t_max_k) {
            return Err(self.out_of_range(
                None,
                p,
                t,
                format!("temperature must be within {t_melt:.4} K (triple point or melting line) to {} K", c.t_max_k),
            ));
        }
        let (label, phase, t_sat) = if p >= c.p_critical_pa {
            ("supercritical", Phase::Gas, None)
        } else if p < c.p_triple_pa {
            ("gas", Phase::Gas, None)
        } else if let Ok(sat) = self.saturation(p) {
            if t <= sat.t_sat {
                ("liquid", Phase::Liquid, Some(sat.t_sat))
            } else {
                ("gas", Phase::Gas, Some(sat.t_sat))
            }
        } else if t >= c.t_critical_k {
            ("gas", Phase::Gas, None)
        } else {
            return Err(self.out_of_range(
                None,
                p,
                t,
                "too close to the critical point to tell liquid from vapour (within 0.5 % of the critical pressure)",
            ));
        };
        let props = self.phase_props(phase, p, t)?;
        Ok(StableState { label, phase, props, t_sat })
    }
}

/// One phase of a fluid table at one pressure ([`FluidTable::isobar`]), for several
/// evaluations at that pressure: the pressure is located on the table's axis once. Each answer
/// is bit for bit that of the corresponding [`FluidTable`] method at the same phase and
/// pressure ([`FluidTable::phase_temperature_range`], [`FluidTable::phase_props`],
/// [`FluidTable::temperature_from_energy`]), and it fails where that fails.
#[derive(Debug, Clone, Copy)]
pub struct Isobar<'a> {
    table: &'a FluidTable,
    phase: Phase,
    at: PressureAt,
}

impl Isobar<'_> {
    /// The temperature interval the table answers at this pressure, if any
    /// ([`FluidTable::phase_temperature_range`]).
    #[inline]
    pub fn temperature_range(&self) -> Option<(f64, f64)> {
        let (lp, _) = self.at.located?;
        self.table.phases[self.phase.index()].temperature_range(lp.index)
    }

    /// Properties at temperature `t`, with derivatives ([`FluidTable::phase_props`]).
    #[inline]
    pub fn props(&self, t: f64) -> Result<PhaseProps, FluidError> {
        Ok(self.table.cell(self.phase, &self.at, t)?.props(self.at.p))
    }

    /// The tabulated values at temperature `t`, without derivatives: the same numbers as
    /// [`Isobar::props`] gives for them, at a fraction of its work.
    #[inline]
    pub fn values(&self, t: f64) -> Result<PhaseValues, FluidError> {
        Ok(self.table.cell(self.phase, &self.at, t)?.values())
    }

    /// Temperature with specific internal energy `u`, and the properties there
    /// ([`FluidTable::temperature_from_energy`]). `t_guess` (for example the previous time
    /// level's temperature) speeds up the Newton iteration; the answer does not depend on it.
    ///
    /// The iterations evaluate u and ∂u/∂T alone (the same numbers as the properties give for
    /// them, in a fraction of the work); the properties are evaluated once, at the answer.
    pub fn temperature_from_energy(&self, u: f64, t_guess: f64) -> Result<(f64, PhaseProps), FluidError> {
        let (table, phase, p) = (self.table, self.phase, self.at.p);
        let fail = || FluidError::EnergyOutOfRange {
            fluid: table.constants.name.clone(),
            phase,
            pressure_pa: p,
            energy_j_kg: u,
        };
        if !u.is_finite() {
            return Err(fail());
        }
        let Some((lo, hi)) = self.temperature_range() else {
            return Err(table.range_error(phase, p, t_guess));
        };
        let cell = |t: f64| table.cell(phase, &self.at, t);
        // Newton from the guess; u(T) is monotone (du/dT|p > 0 wherever the phase exists)
        let mut t = if t_guess.is_finite() { t_guess.clamp(lo, hi) } else { 0.5 * (lo + hi) };
        for _ in 0..12 {
            let c = cell(t)?;
            let (u_t, du_dt) = c.energy();
            let f = u_t - u;
            if du_dt > 0.0 {
                let step = f / du_dt;
                let next = t - step;
                if step.abs() <= 1e-11 * t {
                    return Ok((t, c.props(p)));
                }
                if next >= lo && next <= hi {
                    t = next;
                    continue;
                }
            }
            break;
        }
        // safeguarded bisection-Newton on the bracket
        let (mut a, mut b) = (lo, hi);
        let fa = cell(a)?.energy().0 - u;
        let fb = cell(b)?.energy().0 - u;
        if fa > 0.0 || fb < 0.0 {
            return Err(fail());
        }
        t = 0.5 * (a + b);
        for _ in 0..200 {
            let (u_t, du_dt) = cell(t)?.energy();
            let f = u_t - u;
            if f > 0.0 {
                b = t;
            } else {
                a = t;
            }
            let newton = if du_dt > 0.0 { t - f / du_dt } else { f64::NAN };
            let next = if newton > a && newton < b { newton } else { 0.5 * (a + b) };
            if (next - t).abs() <= 1e-11 * t || b - a <= 1e-11 * t {
                return Ok((next, cell(next)?.props(p)));
            }
            t = next;
        }
        Err(fail())
    }
}
