//! Case files: the TOML description of one simulation (DESIGN.md §3.3).
//!
//! Parsing takes the file's text and a name to put in messages; it does no I/O. Every error is
//! one line naming the file, the field (as a dotted path) and what to change. Unknown fields are
//! errors. [`Case::field`] and [`Case::with_fields`] read and set any numeric field by its TOML
//! path (module `fields`), for calibrations that free a field of the apparatus.

mod fields;

pub use fields::{FieldError, field_unit};

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

use crate::fluids;
use crate::materials::WallMaterial;

/// A problem with a case file, as one line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {message}")]
pub struct CaseError {
    /// The file (or source name) the case came from.
    pub file: String,
    /// What is wrong, naming the field.
    pub message: String,
}

/// A value that is constant or a piecewise-linear table of `[x, value]` points (in time for
/// boundary conditions, in distance for initial profiles). Outside the table the end values hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Profile {
    /// The same value everywhere / always.
    Constant(f64),
    /// `[[x, value], ...]` with increasing `x`.
    Table(Vec<[f64; 2]>),
}

impl Profile {
    /// The value at `x`.
    pub fn at(&self, x: f64) -> f64 {
        match self {
            Profile::Constant(v) => *v,
            Profile::Table(pts) => {
                let n = pts.len();
                if x <= pts[0][0] {
                    return pts[0][1];
                }
                if x >= pts[n - 1][0] {
                    return pts[n - 1][1];
                }
                let k = pts.partition_point(|p| p[0] <= x).clamp(1, n - 1);
                let (a, b) = (pts[k - 1], pts[k]);
                if b[0] == a[0] { b[1] } else { a[1] + (b[1] - a[1]) * (x - a[0]) / (b[0] - a[0]) }
            }
        }
    }

    fn validate(&self, field: &str, lo: f64, hi: f64, what: &str) -> Result<(), String> {
        let check = |v: f64| -> Result<(), String> {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(format!("{field} = {v}: {what}"));
            }
            Ok(())
        };
        match self {
            Profile::Constant(v) => check(*v),
            Profile::Table(pts) => {
                if pts.is_empty() {
                    return Err(format!("{field}: the table is empty; give a number or [[x, value], ...]"));
                }
                for (k, p) in pts.iter().enumerate() {
                    if !p[0].is_finite() {
                        return Err(format!("{field}[{k}]: coordinate {} is not a finite number", p[0]));
                    }
                    if k > 0 && p[0] < pts[k - 1][0] {
                        return Err(format!(
                            "{field}[{k}]: coordinates must increase ({} after {})",
                            p[0],
                            pts[k - 1][0]
                        ));
                    }
                    check(p[1]).map_err(|e| format!("{e} (at point {k})"))?;
                }
                Ok(())
            }
        }
    }

    /// The value at `x` read as piecewise constant: the value of the last point at or before `x`
    /// (the first point's value before it).
    pub fn step_at(&self, x: f64) -> f64 {
        match self {
            Profile::Constant(v) => *v,
            Profile::Table(pts) => {
                let k = pts.partition_point(|p| p[0] <= x);
                pts[k.saturating_sub(1)][1]
            }
        }
    }

    /// Smallest value of the profile.
    pub fn min(&self) -> f64 {
        match self {
            Profile::Constant(v) => *v,
            Profile::Table(p) => p.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min),
        }
    }

    /// Largest value of the profile.
    pub fn max(&self) -> f64 {
        match self {
            Profile::Constant(v) => *v,
            Profile::Table(p) => p.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// `[fluid]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluidSection {
    /// Table name: nitrogen, hydrogen (normal), parahydrogen, oxygen, methane (or an alias such as N2).
    pub name: String,
}

/// `[pipe]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipeSection {
    /// Pipe length, m.
    pub length_m: f64,
    /// Inner diameter, m: a number, or `[[x_m, metres], ...]` read as piecewise constant from
    /// each point on (a contraction or expansion at a point).
    pub inner_diameter_m: Profile,
    /// Wall thickness, m.
    pub wall_thickness_m: f64,
    /// Wall material: `copper` or `stainless304`.
    pub wall_material: String,
    /// Absolute wall roughness, m.
    #[serde(default)]
    pub roughness_m: f64,
    /// Inclination of the pipe axis above the horizontal, degrees (flow direction positive):
    /// a number, or `[[x_m, degrees], ...]` read as piecewise constant from each point on.
    #[serde(default = "zero_profile")]
    pub inclination_deg: Profile,
    /// Number of cells.
    pub cells: usize,
    /// Grading of the cells towards the line's ends: the middle cell is this many times as long
    /// as the first and the last, the lengths growing geometrically from each end to the middle
    /// (1, the default: equal cells; a line of two cells stays equal). The ends are where a coarse grid errs most: the inlet's
    /// quench front and the exit's expansion, whose pressure work the donor-cell scheme takes to
    /// first order in the cell (VALIDATION.md, "Each fluid alone on 120 cells").
    #[serde(default = "one")]
    pub grading: f64,
}

fn zero_profile() -> Profile {
    Profile::Constant(0.0)
}

fn one() -> f64 {
    1.0
}

/// Boundary kinds of `[inlet]` and `[outlet]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryKind {
    /// A large tank at a given pressure and temperature (or quality) behind a valve.
    Reservoir,
    /// A fixed pressure (fluid state for inflow given by the temperature / void fields).
    Pressure,
    /// Prescribed phasic velocities, void fraction and temperatures.
    Velocity,
    /// A closed end: no flow.
    Closed,
}

/// `[inlet]` / `[outlet]`. Which fields are required depends on `kind`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySection {
    /// Boundary kind.
    pub kind: BoundaryKind,
    /// Pressure, Pa (reservoir, pressure).
    pub pressure_pa: Option<Profile>,
    /// Liquid temperature of a reservoir, K (omit for a saturated reservoir).
    pub temperature_k: Option<Profile>,
    /// Reservoir vapour quality in [0, 1] (a saturated reservoir; 0 is saturated liquid).
    pub quality: Option<Profile>,
    /// Valve opening time, s (linear opening of the flow area from 0).
    #[serde(default)]
    pub valve_opening_time_s: f64,
    /// Loss coefficient of the valve or entrance (velocity heads).
    #[serde(default)]
    pub loss_coefficient: f64,
    /// Gas velocity, m/s (velocity inlet).
    pub gas_velocity_m_s: Option<Profile>,
    /// Liquid velocity, m/s (velocity inlet).
    pub liquid_velocity_m_s: Option<Profile>,
    /// Gas volume fraction of the inflowing fluid (velocity inlet; pressure boundary on reverse flow).
    pub void_fraction: Option<Profile>,
    /// Gas temperature of the inflowing fluid, K.
    pub gas_temperature_k: Option<Profile>,
    /// Liquid temperature of the inflowing fluid, K.
    pub liquid_temperature_k: Option<Profile>,
}

/// `[initial]`: the state of the line at t = 0. Profiles are in `x_m`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSection {
    /// Pressure, Pa.
    pub pressure_pa: Profile,
    /// Gas volume fraction.
    pub void_fraction: Profile,
    /// Gas temperature, K.
    pub gas_temperature_k: Profile,
    /// Liquid temperature, K (default: the gas temperature clamped to the liquid's range).
    pub liquid_temperature_k: Option<Profile>,
    /// Gas velocity, m/s (default 0).
    #[serde(default = "zero_profile")]
    pub gas_velocity_m_s: Profile,
    /// Liquid velocity, m/s (default 0).
    #[serde(default = "zero_profile")]
    pub liquid_velocity_m_s: Profile,
    /// Wall temperature, K: a number or `[[x_m, kelvin], ...]` interpolated linearly.
    pub wall_temperature_k: Profile,
}

/// `[ambient]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmbientSection {
    /// Ambient temperature, K.
    pub temperature_k: f64,
    /// Heat transfer coefficient from the ambient to the outer wall surface, W/(m² K)
    /// (a vacuum-jacketed line: close to 0).
    #[serde(default)]
    pub heat_transfer_coefficient_w_m2k: f64,
}

/// `[time]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSection {
    /// End of the simulation, s.
    pub end_s: f64,
    /// Interval between probe outputs, s.
    pub output_interval_s: f64,
    /// Interval between whole-line profiles, s.
    pub profile_interval_s: f64,
    /// First time step, s.
    #[serde(default = "default_initial_dt")]
    pub initial_dt_s: f64,
    /// Largest time step, s.
    #[serde(default = "default_max_dt")]
    pub max_dt_s: f64,
    /// Smallest time step before the run ends with an error, s.
    #[serde(default = "default_min_dt")]
    pub min_dt_s: f64,
    /// Largest material Courant number |v| Δt / Δx (accuracy; the scheme is stable beyond 1).
    #[serde(default = "default_courant")]
    pub max_courant: f64,
    /// End the run with an error after this many steps.
    pub max_steps: Option<u64>,
    /// End the run with an error after this many wall-clock seconds.
    pub max_wall_s: Option<f64>,
}

fn default_initial_dt() -> f64 {
    1e-3
}
fn default_max_dt() -> f64 {
    0.1
}
fn default_min_dt() -> f64 {
    1e-9
}
fn default_courant() -> f64 {
    1.0
}

/// One `[[stations]]` entry: a named measurement position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Station {
    /// Name, as it appears in probe output and measured data.
    pub name: String,
    /// Distance from the inlet end, m.
    pub x_m: f64,
}

/// `[physics]`: switches that make the verification problems expressible.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhysicsSection {
    /// Interphase and wall mass transfer.
    pub phase_change: bool,
    /// Heat transfer between wall and fluid.
    pub wall_heat_transfer: bool,
    /// Heat transfer between the phases.
    pub interphase_heat_transfer: bool,
    /// Interfacial drag.
    pub interphase_drag: bool,
    /// Wall friction.
    pub wall_friction: bool,
    /// Gravity.
    pub gravity: bool,
    /// Virtual-mass term.
    pub virtual_mass: bool,
    /// A fixed wall-to-fluid heat transfer coefficient, W/(m² K), replacing the correlations
    /// (for verification against exact solutions).
    pub wall_htc_w_m2k: Option<f64>,
    /// Film-boiling / rewet correlation set: `paper` (Bromley with the Iloeje corrections,
    /// Berenson–Iloeje minimum film boiling) or `miropolskii` (Miropolskii film boiling with a
    /// Darr–Hartwig wetting temperature).
    pub correlations: String,
}

impl Default for PhysicsSection {
    fn default() -> Self {
        Self {
            phase_change: true,
            wall_heat_transfer: true,
            interphase_heat_transfer: true,
            interphase_drag: true,
            wall_friction: true,
            gravity: true,
            virtual_mass: true,
            wall_htc_w_m2k: None,
            correlations: "paper".to_string(),
        }
    }
}

/// The whole case file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// Optional title.
    #[serde(default)]
    pub title: String,
    /// `[fluid]`.
    pub fluid: FluidSection,
    /// `[pipe]`.
    pub pipe: PipeSection,
    /// `[inlet]`.
    pub inlet: BoundarySection,
    /// `[outlet]`.
    pub outlet: BoundarySection,
    /// `[initial]`.
    pub initial: InitialSection,
    /// `[ambient]`.
    pub ambient: AmbientSection,
    /// `[time]`.
    pub time: TimeSection,
    /// `[[stations]]`.
    #[serde(default)]
    pub stations: Vec<Station>,
    /// `[parameters]`: overrides of registry parameters by name.
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
    /// `[physics]`.
    #[serde(default)]
    pub physics: PhysicsSection,
}

impl Case {
    /// Parses and validates a case from TOML text; `file` names it in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Case, CaseError> {
        let err = |message: String| CaseError { file: file.to_string(), message };
        let case: Case = toml::from_str(text).map_err(|e| err(toml_message(&e, text)))?;
        case.validate().map_err(err)?;
        Ok(case)
    }

    /// The wall material.
    pub fn wall_material(&self) -> WallMaterial {
        WallMaterial::from_name(&self.pipe.wall_material).unwrap_or(WallMaterial::Copper)
    }

    fn validate(&self) -> Result<(), String> {
        if fluids::canonical_name(&self.fluid.name).is_none() {
            return Err(format!(
                "fluid.name = \"{}\": unknown fluid; use one of {}",
                self.fluid.name,
                fluids::EMBEDDED_FLUIDS.join(", ")
            ));
        }
        let p = &self.pipe;
        positive("pipe.length_m", p.length_m)?;
        p.inner_diameter_m.validate("pipe.inner_diameter_m", 1e-6, 100.0, "must be a diameter in m (positive)")?;
        let d_min = p.inner_diameter_m.min();
        positive("pipe.wall_thickness_m", p.wall_thickness_m)?;
        if !(p.roughness_m.is_finite() && p.roughness_m >= 0.0 && p.roughness_m < d_min) {
            return Err(format!("pipe.roughness_m = {}: must be ≥ 0 and smaller than the diameter", p.roughness_m));
        }
        if WallMaterial::from_name(&p.wall_material).is_none() {
            return Err(format!("pipe.wall_material = \"{}\": use copper or stainless304", p.wall_material));
        }
        p.inclination_deg.validate("pipe.inclination_deg", -90.0, 90.0, "must be within -90 to 90 degrees")?;
        if !(2..=100_000).contains(&p.cells) {
            return Err(format!("pipe.cells = {}: must be between 2 and 100000", p.cells));
        }
        if !(p.grading.is_finite() && (1.0..=100.0).contains(&p.grading)) {
            return Err(format!(
                "pipe.grading = {}: must be between 1 (equal cells) and 100 (the middle cell 100 times the end cells)",
                p.grading
            ));
        }
        self.boundary("inlet", &self.inlet)?;
        self.boundary("outlet", &self.outlet)?;
        let i = &self.initial;
        i.pressure_pa.validate("initial.pressure_pa", 1.0, 1e8, "must be a positive pressure in Pa")?;
        i.void_fraction.validate("initial.void_fraction", 0.0, 1.0, "must be within 0 and 1")?;
        i.gas_temperature_k.validate("initial.gas_temperature_k", 1.0, 2000.0, "must be a temperature in K")?;
        if let Some(t) = &i.liquid_temperature_k {
            t.validate("initial.liquid_temperature_k", 1.0, 2000.0, "must be a temperature in K")?;
        }
        i.gas_velocity_m_s.validate("initial.gas_velocity_m_s", -1e3, 1e3, "must be a velocity in m/s")?;
        i.liquid_velocity_m_s.validate("initial.liquid_velocity_m_s", -1e3, 1e3, "must be a velocity in m/s")?;
        i.wall_temperature_k.validate("initial.wall_temperature_k", 1.0, 2000.0, "must be a temperature in K")?;
        if !(self.ambient.temperature_k.is_finite() && self.ambient.temperature_k > 0.0) {
            return Err(format!(
                "ambient.temperature_k = {}: must be a positive temperature",
                self.ambient.temperature_k
            ));
        }
        let h = self.ambient.heat_transfer_coefficient_w_m2k;
        if !(h.is_finite() && h >= 0.0) {
            return Err(format!("ambient.heat_transfer_coefficient_w_m2k = {h}: must be ≥ 0"));
        }
        let t = &self.time;
        positive("time.end_s", t.end_s)?;
        positive("time.output_interval_s", t.output_interval_s)?;
        positive("time.profile_interval_s", t.profile_interval_s)?;
        positive("time.initial_dt_s", t.initial_dt_s)?;
        positive("time.max_dt_s", t.max_dt_s)?;
        positive("time.min_dt_s", t.min_dt_s)?;
        positive("time.max_courant", t.max_courant)?;
        if t.min_dt_s > t.max_dt_s {
            return Err(format!("time.min_dt_s = {} is larger than time.max_dt_s = {}", t.min_dt_s, t.max_dt_s));
        }
        if let Some(w) = t.max_wall_s {
            positive("time.max_wall_s", w)?;
        }
        if t.max_steps == Some(0) {
            return Err("time.max_steps = 0: must be at least 1".into());
        }
        let mut names = std::collections::HashSet::new();
        for (k, s) in self.stations.iter().enumerate() {
            if s.name.trim().is_empty() {
                return Err(format!("stations[{k}].name is empty"));
            }
            if !names.insert(s.name.as_str()) {
                return Err(format!("stations[{k}].name = \"{}\": duplicate station name", s.name));
            }
            if !(s.x_m.is_finite() && s.x_m >= 0.0 && s.x_m <= p.length_m) {
                return Err(format!(
                    "stations[{k}].x_m = {}: must be within 0 and pipe.length_m = {}",
                    s.x_m, p.length_m
                ));
            }
        }
        for (name, v) in &self.parameters {
            if !v.is_finite() {
                return Err(format!("parameters.{name} = {v}: must be a finite number"));
            }
        }
        if self.physics.correlations.parse::<crate::cryo::CorrelationSet>().is_err() {
            return Err(format!(
                "physics.correlations = \"{}\": unknown correlation set; use paper or miropolskii",
                self.physics.correlations
            ));
        }
        if let Some(h) = self.physics.wall_htc_w_m2k
            && !(h.is_finite() && h >= 0.0)
        {
            return Err(format!("physics.wall_htc_w_m2k = {h}: must be ≥ 0"));
        }
        Ok(())
    }

    fn boundary(&self, side: &str, b: &BoundarySection) -> Result<(), String> {
        let need = |v: &Option<Profile>, field: &str| -> Result<(), String> {
            if v.is_none() {
                return Err(format!("{side}.{field} is required for kind = \"{}\"", kind_name(b.kind)));
            }
            Ok(())
        };
        let temp = |v: &Option<Profile>, field: &str| -> Result<(), String> {
            match v {
                Some(t) => t.validate(&format!("{side}.{field}"), 1.0, 2000.0, "must be a temperature in K"),
                None => Ok(()),
            }
        };
        if let Some(p) = &b.pressure_pa {
            p.validate(&format!("{side}.pressure_pa"), 1.0, 1e8, "must be a positive pressure in Pa")?;
        }
        if let Some(q) = &b.quality {
            q.validate(&format!("{side}.quality"), 0.0, 1.0, "must be within 0 and 1")?;
        }
        if let Some(a) = &b.void_fraction {
            a.validate(&format!("{side}.void_fraction"), 0.0, 1.0, "must be within 0 and 1")?;
        }
        temp(&b.temperature_k, "temperature_k")?;
        temp(&b.gas_temperature_k, "gas_temperature_k")?;
        temp(&b.liquid_temperature_k, "liquid_temperature_k")?;
        if !(b.valve_opening_time_s.is_finite() && b.valve_opening_time_s >= 0.0) {
            return Err(format!("{side}.valve_opening_time_s = {}: must be ≥ 0", b.valve_opening_time_s));
        }
        if !(b.loss_coefficient.is_finite() && b.loss_coefficient >= 0.0) {
            return Err(format!("{side}.loss_coefficient = {}: must be ≥ 0", b.loss_coefficient));
        }
        match b.kind {
            BoundaryKind::Reservoir => {
                need(&b.pressure_pa, "pressure_pa")?;
                if b.temperature_k.is_none() && b.quality.is_none() {
                    return Err(format!(
                        "{side}: a reservoir needs temperature_k (subcooled liquid) or quality (saturated)"
                    ));
                }
                if b.temperature_k.is_some() && b.quality.is_some() {
                    return Err(format!("{side}: give a reservoir either temperature_k or quality, not both"));
                }
            }
            BoundaryKind::Pressure => {
                need(&b.pressure_pa, "pressure_pa")?;
                need(&b.gas_temperature_k, "gas_temperature_k")?;
            }
            BoundaryKind::Velocity => {
                need(&b.gas_velocity_m_s, "gas_velocity_m_s")?;
                need(&b.liquid_velocity_m_s, "liquid_velocity_m_s")?;
                need(&b.void_fraction, "void_fraction")?;
                need(&b.gas_temperature_k, "gas_temperature_k")?;
                need(&b.liquid_temperature_k, "liquid_temperature_k")?;
            }
            BoundaryKind::Closed => {}
        }
        Ok(())
    }
}

fn kind_name(k: BoundaryKind) -> &'static str {
    match k {
        BoundaryKind::Reservoir => "reservoir",
        BoundaryKind::Pressure => "pressure",
        BoundaryKind::Velocity => "velocity",
        BoundaryKind::Closed => "closed",
    }
}

fn positive(field: &str, v: f64) -> Result<(), String> {
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("{field} = {v}: must be a positive number"));
    }
    Ok(())
}

/// One line from a TOML error: the line number, the field path when serde knows it, the message.
fn toml_message(e: &toml::de::Error, text: &str) -> String {
    let msg = e.message().trim().replace('\n', " ");
    let line = e.span().map(|s| text[..s.start.min(text.len())].lines().count().max(1));
    match line {
        Some(l) => format!("line {l}: {msg}"),
        None => msg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[fluid]
name = "nitrogen"
[pipe]
length_m = 10.0
inner_diameter_m = 0.0159
wall_thickness_m = 0.0016
wall_material = "copper"
cells = 20
[inlet]
kind = "velocity"
gas_velocity_m_s = 0.0
liquid_velocity_m_s = 1.0
void_fraction = 0.0
gas_temperature_k = 80.0
liquid_temperature_k = 75.0
[outlet]
kind = "pressure"
pressure_pa = 1.0e5
gas_temperature_k = 80.0
[initial]
pressure_pa = 1.0e5
void_fraction = 1.0
gas_temperature_k = [[0.0, 290.0], [10.0, 280.0]]
wall_temperature_k = 290.0
[ambient]
temperature_k = 290.0
[time]
end_s = 1.0
output_interval_s = 0.1
profile_interval_s = 0.5
[[stations]]
name = "A"
x_m = 5.0
"#;

    #[test]
    fn parses_a_good_case() {
        let c = Case::from_toml(GOOD, "good.toml").unwrap();
        assert_eq!(c.pipe.cells, 20);
        assert_eq!(c.initial.gas_temperature_k.at(5.0), 285.0);
        assert!(c.physics.gravity);
    }

    fn error_of(text: &str) -> String {
        let e = Case::from_toml(text, "case.toml").unwrap_err().to_string();
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(e.starts_with("case.toml: "), "{e}");
        e
    }

    #[test]
    fn bad_cases_name_the_field() {
        let e = error_of(&GOOD.replace("cells = 20", "cells = 20\ncolour = 3"));
        assert!(e.contains("colour") && e.contains("line"), "{e}");
        let e = error_of(&GOOD.replace("length_m = 10.0", "length_m = -10.0"));
        assert!(e.contains("pipe.length_m"), "{e}");
        for bad in ["0.5", "101.0", "nan"] {
            let e = error_of(&GOOD.replace("cells = 20", &format!("cells = 20\ngrading = {bad}")));
            assert!(e.contains("pipe.grading") && e.contains("between 1"), "{bad}: {e}");
        }
        let e = error_of(&GOOD.replace("[ambient]\ntemperature_k = 290.0\n", ""));
        assert!(e.contains("ambient"), "{e}");
        let e = error_of(&GOOD.replace("\"nitrogen\"", "\"helium\""));
        assert!(e.contains("fluid.name") && e.contains("helium"), "{e}");
        let e = error_of(&GOOD.replace("x_m = 5.0", "x_m = 50.0"));
        assert!(e.contains("stations[0].x_m"), "{e}");
        let e = error_of(&GOOD.replace("liquid_velocity_m_s = 1.0\n", ""));
        assert!(e.contains("inlet.liquid_velocity_m_s"), "{e}");
        let e = error_of(&GOOD.replace("[[0.0, 290.0], [10.0, 280.0]]", "[[5.0, 290.0], [1.0, 280.0]]"));
        assert!(e.contains("initial.gas_temperature_k[1]"), "{e}");
    }

    #[test]
    fn profiles_interpolate_and_hold_ends() {
        let p = Profile::Table(vec![[0.0, 1.0], [2.0, 3.0]]);
        assert_eq!(p.at(-1.0), 1.0);
        assert_eq!(p.at(1.0), 2.0);
        assert_eq!(p.at(5.0), 3.0);
        assert_eq!(p.step_at(1.9), 1.0);
        assert_eq!(p.step_at(2.0), 3.0);
        assert_eq!(p.step_at(-1.0), 1.0);
    }
}
