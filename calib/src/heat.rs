//! The heat the line's wall has given up, as its wall thermocouples see it.
//!
//! A chilldown is the wall's heat carried away by the fluid, and the pace at which the wall gives
//! it up is what the flow can carry: a test of a model that the station-by-station RMS does not
//! make (the fronts may be late because the flow carries too little, or because the heat goes
//! elsewhere). [`released`] reads it from the stations' wall temperatures alone, so that measured
//! data and a model's probes at the same stations are read the same way and compare like for like:
//! the wall temperature along the line is taken linear between stations and flat from the first
//! station to the inlet and from the last to the outlet; before a station's first reading it is
//! the case's initial wall temperature there, after its last reading it stays at that reading.
//! The heat released by time t is ∫ m'(x) [e(T₀(x)) − e(T(x, t))] dx, with m' the wall's mass per
//! metre and e the wall material's specific energy (`cryofit_solver::materials`). With four
//! stations on a 61 m line the reading is coarse (it overstates the heat released while the
//! quench front is between the inlet and the first station), the same coarseness for both.

use cryofit_solver::case::{Case, Profile};
use cryofit_solver::materials::WallMaterial;
use cryofit_solver::model::Grid;

use crate::data::Dataset;

/// The quantity read: the wall temperature, K.
const WALL_TEMPERATURE: &str = "wall_temperature_k";
/// Midpoints of the quadrature along the line.
const POINTS: usize = 600;

/// The wall of a case's line: what [`released`] needs of it.
#[derive(Debug, Clone)]
pub struct Wall {
    length_m: f64,
    material: WallMaterial,
    initial: Profile,
    /// Wall mass per metre at each quadrature midpoint, kg/m.
    mass_per_m: Vec<f64>,
    /// The wall material's specific energy at its initial temperature at each midpoint, J/kg.
    initial_energy: Vec<f64>,
}

impl Wall {
    /// The wall of `case`'s line (its geometry, material and initial wall temperatures).
    pub fn of_case(case: &Case) -> Self {
        let grid = Grid::from_case(case);
        let length_m = case.pipe.length_m;
        let initial = case.initial.wall_temperature_k.clone();
        let midpoints = (0..POINTS).map(|k| (k as f64 + 0.5) / POINTS as f64 * length_m);
        let mass_per_m = midpoints
            .clone()
            .map(|x| {
                let i = grid.x_junction.partition_point(|&xj| xj <= x).clamp(1, grid.n) - 1;
                grid.wall_mass[i] / grid.dx[i]
            })
            .collect();
        let initial_energy = midpoints.map(|x| grid.material.specific_energy_j_kg(initial.at(x))).collect();
        Self { length_m, material: grid.material, initial, mass_per_m, initial_energy }
    }

    /// The wall's total mass, kg.
    pub fn mass_kg(&self) -> f64 {
        self.mass_per_m.iter().sum::<f64>() * self.length_m / POINTS as f64
    }
}

/// Heat the wall has released by time `t_s`, J, read from the wall temperatures of `series` (see
/// the module): `None` where `series` holds no wall temperature at all.
pub fn released(series: &Dataset, wall: &Wall, t_s: f64) -> Option<f64> {
    let mut stations: Vec<[f64; 2]> = series
        .series
        .iter()
        .filter(|((_, q), _)| q == WALL_TEMPERATURE)
        .map(|(_, s)| {
            let t = match (s.times.first(), s.times.last(), s.values.last()) {
                (Some(&first), _, _) if t_s < first => wall.initial.at(s.x_m),
                (_, Some(&last), Some(&v)) if t_s > last => v,
                _ => s.at(t_s).unwrap_or_else(|| wall.initial.at(s.x_m)),
            };
            [s.x_m, t]
        })
        .collect();
    if stations.is_empty() {
        return None;
    }
    stations.sort_by(|a, b| a[0].total_cmp(&b[0]));
    // linear between the stations, flat beyond them: a case profile through them
    let now = Profile::Table(stations);
    let dx = wall.length_m / POINTS as f64;
    let q = (0..POINTS)
        .map(|k| {
            let x = (k as f64 + 0.5) * dx;
            let e = wall.material.specific_energy_j_kg(now.at(x));
            wall.mass_per_m[k] * (wall.initial_energy[k] - e) * dx
        })
        .sum();
    Some(q)
}

/// Heat released by the wall at `times`, data against model (J; `None` where a side holds no
/// wall temperatures).
pub fn compare(data: &Dataset, model: &Dataset, wall: &Wall, times: &[f64]) -> Vec<(f64, Option<f64>, Option<f64>)> {
    times.iter().map(|&t| (t, released(data, wall, t), released(model, wall, t))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Series;

    fn case() -> Case {
        let mut case = Case::from_toml(include_str!("../../tests/fixtures/tiny.toml"), "tiny.toml").unwrap();
        case.pipe.length_m = 10.0;
        case.initial.wall_temperature_k = Profile::Constant(290.0);
        case
    }

    fn one_station(x_m: f64, times: Vec<f64>, values: Vec<f64>) -> Dataset {
        let mut d = Dataset::default();
        d.series.insert(("TS1".into(), WALL_TEMPERATURE.into()), Series { x_m, times, values });
        d
    }

    #[test]
    fn a_uniformly_cooled_wall_releases_its_mass_times_the_energy_change() {
        let case = case();
        let wall = Wall::of_case(&case);
        let m = case.wall_material();
        let d_i = case.pipe.inner_diameter_m.step_at(0.0);
        let d_o = d_i + 2.0 * case.pipe.wall_thickness_m;
        let mass = m.density_kg_m3() * std::f64::consts::PI * (d_o * d_o - d_i * d_i) / 4.0 * 10.0;
        assert!((wall.mass_kg() / mass - 1.0).abs() < 1e-12, "{} {mass}", wall.mass_kg());
        let data = one_station(5.0, vec![0.0, 10.0], vec![290.0, 90.0]);
        let expected = mass * (m.specific_energy_j_kg(290.0) - m.specific_energy_j_kg(90.0));
        let q = released(&data, &wall, 10.0).unwrap();
        assert!((q / expected - 1.0).abs() < 1e-12, "{q} {expected}");
        // halfway in time, halfway in temperature (one station: flat along the line)
        let half = released(&data, &wall, 5.0).unwrap();
        let e_half = mass * (m.specific_energy_j_kg(290.0) - m.specific_energy_j_kg(190.0));
        assert!((half / e_half - 1.0).abs() < 1e-12);
        // after the last reading the wall stays there; before the first it is the initial wall
        assert_eq!(released(&data, &wall, 50.0), Some(q));
        let late = one_station(5.0, vec![20.0, 30.0], vec![200.0, 100.0]);
        assert_eq!(released(&late, &wall, 10.0), Some(0.0));
    }

    #[test]
    fn the_temperature_is_linear_between_stations_and_flat_beyond() {
        let case = case();
        let wall = Wall::of_case(&case);
        let m = case.wall_material();
        let mut data = one_station(2.0, vec![0.0, 1.0], vec![100.0, 100.0]);
        data.series.insert(
            ("TS2".into(), WALL_TEMPERATURE.into()),
            Series { x_m: 8.0, times: vec![0.0, 1.0], values: vec![290.0, 290.0] },
        );
        let q = released(&data, &wall, 1.0).unwrap();
        // 0–2 m at 100 K, 2–8 m from 100 to 290 K, 8–10 m at 290 K (nothing released)
        let per_m = wall.mass_kg() / 10.0;
        let de = |t: f64| m.specific_energy_j_kg(290.0) - m.specific_energy_j_kg(t);
        let ramp: f64 = (0..6000).map(|k| de(100.0 + 190.0 * (k as f64 + 0.5) / 6000.0) * 6.0 / 6000.0).sum();
        let expected = per_m * (2.0 * de(100.0) + ramp);
        assert!((q / expected - 1.0).abs() < 1e-3, "{q} {expected}");
    }

    #[test]
    fn no_wall_temperatures_no_reading() {
        let wall = Wall::of_case(&case());
        let mut d = Dataset::default();
        d.series.insert(
            ("TS1".into(), "pressure_pa".into()),
            Series { x_m: 1.0, times: vec![0.0, 1.0], values: vec![1e5, 1e5] },
        );
        assert_eq!(released(&d, &wall, 1.0), None);
        assert_eq!(released(&Dataset::default(), &wall, 1.0), None);
    }
}
