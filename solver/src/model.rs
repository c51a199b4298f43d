//! The discretised problem: grid, boundary states and the solution state.
//!
//! Staggered grid: cells `0..n` hold pressure, void fraction, phasic temperatures, conserved
//! phasic masses and energies and the wall temperature; junctions `0..=n` hold phasic
//! velocities. Junction `j` joins cell `j - 1` and cell `j`; junction 0 is the inlet boundary and
//! junction `n` the outlet boundary. `x` is the distance from the inlet end.

use crate::case::{BoundaryKind, BoundarySection, Case, Profile};
use crate::fluids::{FluidError, FluidTable, Phase, PhaseProps};
use crate::materials::WallMaterial;

/// Standard gravity, m/s².
pub const GRAVITY: f64 = 9.80665;

/// Geometry of the discretised line.
#[derive(Debug, Clone)]
pub struct Grid {
    /// Number of cells.
    pub n: usize,
    /// Cell lengths, m.
    pub dx: Vec<f64>,
    /// Cell centres, m from the inlet.
    pub x_cell: Vec<f64>,
    /// Junction positions, m from the inlet (`n + 1` of them).
    pub x_junction: Vec<f64>,
    /// Cell flow areas, m².
    pub area_cell: Vec<f64>,
    /// Junction flow areas, m².
    pub area_junction: Vec<f64>,
    /// Cell volumes, m³.
    pub volume: Vec<f64>,
    /// Hydraulic (inner) diameter of each cell, m.
    pub d_h: Vec<f64>,
    /// Inner perimeter of each cell, m.
    pub perimeter: Vec<f64>,
    /// Sine of the inclination of each cell (flow direction, positive upwards).
    pub sin_cell: Vec<f64>,
    /// Sine of the inclination at each junction (mean of the neighbouring cells).
    pub sin_junction: Vec<f64>,
    /// Wall mass of each cell, kg.
    pub wall_mass: Vec<f64>,
    /// Outer wall surface of each cell, m².
    pub outer_area: Vec<f64>,
    /// Wall material.
    pub material: WallMaterial,
    /// Relative roughness ε/D of each cell.
    pub relative_roughness: Vec<f64>,
}

impl Grid {
    /// Builds a grid from a case: equal cells, or cells graded towards the ends
    /// ([`cell_lengths`]). The diameter may change from cell to cell; a junction between cells of
    /// different area takes the smaller area (the throat).
    pub fn from_case(case: &Case) -> Self {
        let p = &case.pipe;
        let n = p.cells;
        let dx = cell_lengths(p.length_m, n, p.grading);
        let material = case.wall_material();
        let x_junction = junction_positions(&dx, p.length_m);
        let x_cell: Vec<f64> = if dx.iter().all(|&d| d == dx[0]) {
            (0..n).map(|i| (i as f64 + 0.5) * dx[0]).collect()
        } else {
            (0..n).map(|i| 0.5 * (x_junction[i] + x_junction[i + 1])).collect()
        };
        let d: Vec<f64> = x_cell.iter().map(|&x| p.inner_diameter_m.step_at(x)).collect();
        let area_cell: Vec<f64> = d.iter().map(|d| std::f64::consts::PI * d * d / 4.0).collect();
        let area_junction: Vec<f64> =
            (0..=n).map(|j| area_cell[j.saturating_sub(1)].min(area_cell[j.min(n - 1)])).collect();
        let wall_mass = d
            .iter()
            .zip(&dx)
            .map(|(d, dx)| {
                let d_out = d + 2.0 * p.wall_thickness_m;
                material.density_kg_m3() * std::f64::consts::PI * (d_out * d_out - d * d) / 4.0 * dx
            })
            .collect();
        let sin_cell: Vec<f64> = x_cell.iter().map(|&x| p.inclination_deg.step_at(x).to_radians().sin()).collect();
        let sin_junction = (0..=n)
            .map(|j| {
                let l = sin_cell[j.saturating_sub(1)];
                let r = sin_cell[j.min(n - 1)];
                0.5 * (l + r)
            })
            .collect();
        Self {
            n,
            volume: area_cell.iter().zip(&dx).map(|(a, dx)| a * dx).collect(),
            outer_area: d
                .iter()
                .zip(&dx)
                .map(|(d, dx)| std::f64::consts::PI * (d + 2.0 * p.wall_thickness_m) * dx)
                .collect(),
            dx,
            x_junction,
            area_cell,
            area_junction,
            perimeter: d.iter().map(|d| std::f64::consts::PI * d).collect(),
            relative_roughness: d.iter().map(|d| p.roughness_m / d).collect(),
            d_h: d,
            x_cell,
            sin_cell,
            sin_junction,
            wall_mass,
            material,
        }
    }

    /// Hydraulic diameter at junction `j` (mean of the neighbouring cells), m.
    pub fn d_h_junction(&self, j: usize) -> f64 {
        0.5 * (self.d_h[j.saturating_sub(1)] + self.d_h[j.min(self.n - 1)])
    }

    /// Length of the momentum control volume around junction `j`, m.
    pub fn dx_junction(&self, j: usize) -> f64 {
        let l = if j > 0 { self.dx[j - 1] } else { 0.0 };
        let r = if j < self.n { self.dx[j] } else { 0.0 };
        0.5 * (l + r)
    }

    /// The cell holding `x` (clamped to the line; a junction's position belongs to the cell
    /// downstream of it).
    pub fn cell_at(&self, x: f64) -> usize {
        let past = self.x_junction[1..self.n].partition_point(|&xj| xj <= x);
        past.min(self.n - 1)
    }
}

/// The lengths of `n` cells over `length` m, the middle cell `grading` times as long as the end
/// cells ([`crate::case::PipeSection::grading`]). Equal cells for a grading of 1 (and for fewer
/// than three cells, which have no middle to grow towards), each `length / n` exactly; otherwise lengths l₀ q^min(i, n−1−i), the ratio q from cell to cell
/// such that the middle cell (the two middle cells of an even count) is `grading` l₀, and l₀
/// such that they sum to `length`.
pub fn cell_lengths(length: f64, n: usize, grading: f64) -> Vec<f64> {
    if grading == 1.0 || n < 3 {
        return vec![length / n as f64; n];
    }
    let steps = (n - 1) / 2;
    let q = grading.powf(1.0 / steps as f64);
    let shape: Vec<f64> = (0..n).map(|i| q.powi(i.min(n - 1 - i) as i32)).collect();
    let l0 = length / shape.iter().sum::<f64>();
    shape.iter().map(|s| l0 * s).collect()
}

/// The junctions' positions from the cells' lengths: 0, then the running sum, the last set to
/// `length` exactly; for equal cells j · (length / n), as the grid always had them.
fn junction_positions(dx: &[f64], length: f64) -> Vec<f64> {
    let n = dx.len();
    if dx.iter().all(|&d| d == dx[0]) {
        return (0..=n).map(|j| j as f64 * dx[0]).collect();
    }
    let mut x = Vec::with_capacity(n + 1);
    let mut sum = 0.0;
    x.push(0.0);
    for d in &dx[..n - 1] {
        sum += d;
        x.push(sum);
    }
    x.push(length);
    x
}

/// The fluid state on one side of a boundary junction, at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundaryState {
    /// What kind of boundary.
    pub kind: BoundaryKind,
    /// Pressure, Pa (for reservoir and pressure boundaries).
    pub p: f64,
    /// Gas volume fraction of fluid entering through it.
    pub alpha: f64,
    /// Gas temperature of entering fluid, K.
    pub t_g: f64,
    /// Liquid temperature of entering fluid, K.
    pub t_l: f64,
    /// Prescribed gas velocity (velocity boundaries), m/s.
    pub v_g: f64,
    /// Prescribed liquid velocity (velocity boundaries), m/s.
    pub v_l: f64,
    /// Gas properties of the entering fluid.
    pub gas: PhaseProps,
    /// Liquid properties of the entering fluid.
    pub liquid: PhaseProps,
    /// Fraction of the junction area open (valve opening), 0..1.
    pub open_fraction: f64,
    /// Loss coefficient, velocity heads.
    pub loss: f64,
}

/// Evaluates a boundary section at time `t` against the fluid table.
///
/// A reservoir holds liquid: subcooled at `temperature_k`, or saturated with vapour `quality`
/// (void fraction from the homogeneous relation). Its vapour, should it enter, is saturated.
/// Temperatures the phase tables cannot represent at the boundary pressure are moved to the
/// nearest represented value (a liquid temperature given for an all-gas inflow, say).
pub fn boundary_state(
    b: &BoundarySection,
    t: f64,
    fluid: &FluidTable,
    fallback_p: f64,
) -> Result<BoundaryState, FluidError> {
    let at = |p: &Option<Profile>, default: f64| p.as_ref().map_or(default, |p| p.at(t));
    let p = at(&b.pressure_pa, fallback_p);
    let open = if b.valve_opening_time_s > 0.0 { (t / b.valve_opening_time_s).clamp(0.0, 1.0) } else { 1.0 };
    let sat = fluid.saturation(p).ok();
    let (alpha, t_g, t_l) = match b.kind {
        BoundaryKind::Reservoir => {
            let s = fluid.saturation(p)?;
            match (&b.temperature_k, &b.quality) {
                (Some(temp), _) => (0.0, s.t_sat, temp.at(t).min(s.t_sat)),
                (None, Some(q)) => {
                    let x = q.at(t);
                    let alpha = if x <= 0.0 { 0.0 } else { x * s.rho_l / (x * s.rho_l + (1.0 - x) * s.rho_g) };
                    (alpha, s.t_sat, s.t_sat)
                }
                (None, None) => (0.0, s.t_sat, s.t_sat),
            }
        }
        _ => {
            let t_g = at(&b.gas_temperature_k, sat.map_or(300.0, |s| s.t_sat));
            let t_l = at(&b.liquid_temperature_k, sat.map_or(t_g, |s| t_g.min(s.t_sat)));
            (at(&b.void_fraction, 1.0), t_g, t_l)
        }
    };
    let t_g = clamp_to_phase(fluid, Phase::Gas, p, t_g);
    let t_l = clamp_to_phase(fluid, Phase::Liquid, p, t_l);
    Ok(BoundaryState {
        kind: b.kind,
        p,
        alpha,
        t_g,
        t_l,
        v_g: at(&b.gas_velocity_m_s, 0.0),
        v_l: at(&b.liquid_velocity_m_s, 0.0),
        gas: fluid.phase_props(Phase::Gas, p, t_g)?,
        liquid: fluid.phase_props(Phase::Liquid, p, t_l)?,
        open_fraction: open,
        loss: b.loss_coefficient,
    })
}

/// Moves `t` into the temperature range the `phase` table covers at pressure `p`.
pub fn clamp_to_phase(fluid: &FluidTable, phase: Phase, p: f64, t: f64) -> f64 {
    clamp_to_range(fluid.phase_temperature_range(phase, p), t)
}

/// [`clamp_to_phase`] with the table's range ([`FluidTable::phase_temperature_range`]) already
/// looked up: `t` a millionth of the range inside it, unchanged where there is no range.
pub fn clamp_to_range(range: Option<(f64, f64)>, t: f64) -> f64 {
    match range {
        Some((lo, hi)) => {
            let margin = 1e-6 * (hi - lo);
            t.clamp(lo + margin, hi - margin)
        }
        None => t,
    }
}

/// The solution: per-cell and per-junction arrays (structure of arrays).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct State {
    /// Time, s.
    pub time: f64,
    /// Pressure, Pa.
    pub p: Vec<f64>,
    /// Gas volume fraction (normalised so that gas + liquid fill the cell).
    pub alpha: Vec<f64>,
    /// Gas temperature, K.
    pub t_g: Vec<f64>,
    /// Liquid temperature, K.
    pub t_l: Vec<f64>,
    /// Gas mass per unit volume α ρ_g, kg/m³ (conserved).
    pub m_g: Vec<f64>,
    /// Liquid mass per unit volume (1 − α) ρ_l, kg/m³ (conserved).
    pub m_l: Vec<f64>,
    /// Gas internal energy per unit volume α ρ_g u_g, J/m³ (conserved).
    pub e_g: Vec<f64>,
    /// Liquid internal energy per unit volume, J/m³ (conserved).
    pub e_l: Vec<f64>,
    /// Gas properties at (p, T_g).
    pub gas: Vec<PhaseProps>,
    /// Liquid properties at (p, T_l).
    pub liquid: Vec<PhaseProps>,
    /// Volume error α_g + α_l − 1 of the conserved masses at the state's pressure and temperatures.
    pub volume_error: Vec<f64>,
    /// Gas velocity at each junction, m/s.
    pub v_g: Vec<f64>,
    /// Liquid velocity at each junction, m/s.
    pub v_l: Vec<f64>,
    /// Wall temperature, K.
    pub t_w: Vec<f64>,
    /// Wall specific internal energy, J/kg (conserved; `t_w` follows from it).
    pub e_w: Vec<f64>,
    /// Heat flux from the wall into the fluid over the last step, W/m² of inner wall.
    pub wall_heat_flux: Vec<f64>,
    /// Fraction of the inner wall perimeter wetted by liquid (relaxes to the flow regime's value
    /// with the time constant `tauw`).
    pub wetted: Vec<f64>,
    /// Saturation properties at the cell pressure (zeros where there is no saturation line).
    pub sat: Vec<crate::fluids::Saturation>,
    /// Mass flow through the inlet and the outlet junction, both phases, kg/s in the +x
    /// direction, as the mass equations of the step that ended at this state carried it (the
    /// boundary's fluid the donor where it enters, the end cell's where it leaves); 0 at the
    /// initial state.
    pub boundary_mass_flow: [f64; 2],
    /// The exit's resistance λ, 1/s, with which the step that ended at this state would have
    /// held its exit exactly at the critical speed (0 where its flow stayed below it without
    /// one; `scheme::choking`): the next step starts from it.
    pub exit_resistance: f64,
    /// Per cell: whether the step that ended at this state recovered it as one near-critical
    /// mixture (`scheme::recovery`; the next step refills such a cell where its volume error is
    /// above the limit); empty at a state no step made.
    pub mixture: Vec<bool>,
}

impl State {
    /// Makes `self` equal to `other`, reusing `self`'s arrays (no allocation where their
    /// lengths already match).
    pub fn copy_from(&mut self, other: &State) {
        // every field named, so that a field added to the state is not forgotten here
        let State {
            time,
            p,
            alpha,
            t_g,
            t_l,
            m_g,
            m_l,
            e_g,
            e_l,
            gas,
            liquid,
            volume_error,
            v_g,
            v_l,
            t_w,
            e_w,
            wall_heat_flux,
            wetted,
            sat,
            boundary_mass_flow,
            exit_resistance,
            mixture,
        } = other;
        self.time = *time;
        for (to, from) in [
            (&mut self.p, p),
            (&mut self.alpha, alpha),
            (&mut self.t_g, t_g),
            (&mut self.t_l, t_l),
            (&mut self.m_g, m_g),
            (&mut self.m_l, m_l),
            (&mut self.e_g, e_g),
            (&mut self.e_l, e_l),
            (&mut self.volume_error, volume_error),
            (&mut self.v_g, v_g),
            (&mut self.v_l, v_l),
            (&mut self.t_w, t_w),
            (&mut self.e_w, e_w),
            (&mut self.wall_heat_flux, wall_heat_flux),
            (&mut self.wetted, wetted),
        ] {
            to.clone_from(from);
        }
        self.gas.clone_from(gas);
        self.liquid.clone_from(liquid);
        self.sat.clone_from(sat);
        self.boundary_mass_flow = *boundary_mass_flow;
        self.exit_resistance = *exit_resistance;
        self.mixture.clone_from(mixture);
    }
}

#[cfg(test)]
mod grid_tests {
    use super::*;

    #[test]
    fn graded_cells_fill_the_line_symmetrically_at_the_grading() {
        for (n, grading) in [(30, 8.0), (31, 4.0), (3, 2.0), (40, 100.0)] {
            let dx = cell_lengths(61.0, n, grading);
            assert_eq!(dx.len(), n);
            assert!((dx.iter().sum::<f64>() - 61.0).abs() < 1e-12, "{n} cells: {}", dx.iter().sum::<f64>());
            for i in 0..n {
                assert!((dx[i] - dx[n - 1 - i]).abs() <= 1e-12 * dx[i], "{n} cells: cell {i}");
            }
            let middle = dx[(n - 1) / 2];
            assert!((middle / dx[0] - grading).abs() < 1e-9 * grading, "{n} cells: {}", middle / dx[0]);
            assert!(dx.windows(2).take((n - 1) / 2).all(|w| w[1] > w[0]), "{n} cells grow towards the middle");
        }
        // a grading of 1 is the equal cells the grid always had, to the bit
        assert_eq!(cell_lengths(61.0, 30, 1.0), vec![61.0 / 30.0; 30]);
    }

    #[test]
    fn a_graded_grid_places_its_cells_and_finds_them() {
        let mut case = crate::reference::Reference::GasCooldown.with_cells(30);
        case.pipe.grading = 8.0;
        let g = Grid::from_case(&case);
        assert_eq!(g.x_junction[0], 0.0);
        assert_eq!(g.x_junction[30], 61.0);
        for i in 0..30 {
            assert!((g.x_junction[i + 1] - g.x_junction[i] - g.dx[i]).abs() < 1e-12);
            assert!(g.x_junction[i] < g.x_cell[i] && g.x_cell[i] < g.x_junction[i + 1]);
            assert_eq!(g.cell_at(g.x_cell[i]), i);
            assert_eq!(g.cell_at(g.x_junction[i]), i, "a junction belongs to the cell downstream of it");
            assert!((g.volume[i] / g.dx[i] - g.area_cell[i]).abs() < 1e-15);
        }
        assert_eq!(g.cell_at(-1.0), 0);
        assert_eq!(g.cell_at(70.0), 29);
        // the wall's mass is the line's whatever the cells
        let equal = Grid::from_case(&crate::reference::Reference::GasCooldown.with_cells(30));
        let total = |g: &Grid| g.wall_mass.iter().sum::<f64>();
        assert!((total(&g) / total(&equal) - 1.0).abs() < 1e-12);
    }
}
