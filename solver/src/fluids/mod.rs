//! Fluid properties from precomputed CoolProp tables.
//!
//! # Primary variables
//!
//! Each phase is a smooth function of **pressure and temperature** `(p, T)`. The solver carries
//! phasic temperatures; where it knows a phasic internal energy instead (after the conservative
//! energy solve) it inverts `u(p, T)` with [`FluidTable::temperature_from_energy`]. `(p, T)` was
//! chosen over `(p, u)` because the coverage of a table (triple point, melting line, 500 K, a
//! fixed reach past saturation) is naturally expressed in temperature, and because the wall heat
//! transfer closures need temperatures anyway.
//!
//! # What a table holds
//!
//! For the liquid and for the gas, a tensor-product cubic Hermite interpolant of density,
//! specific internal energy, isobaric heat capacity, viscosity and thermal conductivity on a
//! piecewise-uniform `(p, T)` grid (see `data/fluids/README.md`). Node values and derivatives come
//! from the Helmholtz equation of state with the phase imposed, so each phase continues smoothly
//! through the saturation line into its metastable states (superheated liquid, subcooled
//! vapour) with continuous values and first derivatives. Specific enthalpy is `h = u + p/ρ`,
//! exactly consistent with the tabulated `u` and `ρ`. Saturation properties are separate
//! one-dimensional Hermite tables in pressure (and saturation pressure in temperature).
//!
//! A query outside a table is an error naming the fluid and the state, never NaN.

mod hermite;
mod sound;
mod table;

pub use sound::{flashing_mixture_sound_speed, frozen_mixture_sound_speed};
pub use table::{
    FluidConstants, FluidTable, Isobar, LimiterReport, PhaseProps, PhaseValues, Saturation, StabilityViolation,
    StableState,
};

use std::fmt;
use std::sync::OnceLock;

/// A fluid phase of the two-fluid model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// The liquid phase (index 0).
    Liquid,
    /// The gas (vapour) phase (index 1).
    Gas,
}

impl Phase {
    /// Both phases, liquid first.
    pub const ALL: [Phase; 2] = [Phase::Liquid, Phase::Gas];

    /// The other phase.
    pub fn other(self) -> Phase {
        match self {
            Phase::Liquid => Phase::Gas,
            Phase::Gas => Phase::Liquid,
        }
    }

    pub(crate) fn index(self) -> usize {
        match self {
            Phase::Liquid => 0,
            Phase::Gas => 1,
        }
    }
}

impl fmt::Display for Phase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Phase::Liquid => "liquid",
            Phase::Gas => "gas",
        })
    }
}

/// Errors from fluid property evaluation and table loading.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FluidError {
    /// No table of that name.
    #[error("unknown fluid '{name}'; known fluids: {known}")]
    UnknownFluid {
        /// The name asked for.
        name: String,
        /// Comma-separated list of available fluids.
        known: String,
    },
    /// The state lies outside what the table covers.
    #[error("{fluid}{} state p = {pressure_pa} Pa, T = {temperature_k} K is outside the property table: {reason}", phase.map(|p| format!(" {p}")).unwrap_or_default())]
    OutOfRange {
        /// Fluid name.
        fluid: String,
        /// The phase asked for, if any.
        phase: Option<Phase>,
        /// Pressure of the query.
        pressure_pa: f64,
        /// Temperature of the query.
        temperature_k: f64,
        /// Which limit was crossed.
        reason: String,
    },
    /// Saturation properties asked for where there is no saturation line in the table.
    #[error("{fluid}: no saturation state at {quantity} = {value}: {reason}")]
    NoSaturation {
        /// Fluid name.
        fluid: String,
        /// `pressure_pa` or `temperature_k`.
        quantity: &'static str,
        /// The value asked for.
        value: f64,
        /// Why.
        reason: String,
    },
    /// Inverting `u(p, T)` for the temperature failed.
    #[error(
        "{fluid} {phase}: no temperature with internal energy u = {energy_j_kg} J/kg at p = {pressure_pa} Pa within the table"
    )]
    EnergyOutOfRange {
        /// Fluid name.
        fluid: String,
        /// Phase.
        phase: Phase,
        /// Pressure of the query.
        pressure_pa: f64,
        /// Internal energy asked for.
        energy_j_kg: f64,
    },
    /// The table bytes are not a valid table.
    #[error("invalid fluid table: {0}")]
    Format(String),
}

/// Names of the tables built into every cryofit binary.
///
/// `hydrogen` is normal hydrogen (75 % ortho, room-temperature equilibrium); `parahydrogen` is
/// para-hydrogen, the composition of liquid hydrogen as delivered and of its vapour in a
/// transfer line (see `data/fluids/README.md`).
pub const EMBEDDED_FLUIDS: [&str; 5] = ["nitrogen", "hydrogen", "parahydrogen", "oxygen", "methane"];

macro_rules! embedded_bytes {
    ($name:literal) => {
        include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/fluids/", $name, ".cft"))
    };
}

static EMBEDDED: [(&str, &[u8]); 5] = [
    ("nitrogen", embedded_bytes!("nitrogen")),
    ("hydrogen", embedded_bytes!("hydrogen")),
    ("parahydrogen", embedded_bytes!("parahydrogen")),
    ("oxygen", embedded_bytes!("oxygen")),
    ("methane", embedded_bytes!("methane")),
];

static PARSED: [OnceLock<FluidTable>; 5] = [const { OnceLock::new() }; 5];

/// Normalises common aliases (`N2`, `LN2`, `p-H2`) to a table name. `H2` and `LH2` name normal
/// hydrogen; para-hydrogen is asked for by name (`parahydrogen`, `para-hydrogen`, `p-H2`).
pub fn canonical_name(name: &str) -> Option<&'static str> {
    let n = name.trim().to_ascii_lowercase();
    Some(match n.as_str() {
        "nitrogen" | "n2" | "ln2" => "nitrogen",
        "hydrogen" | "h2" | "lh2" | "normal-hydrogen" | "n-h2" => "hydrogen",
        "parahydrogen" | "para-hydrogen" | "p-h2" => "parahydrogen",
        "oxygen" | "o2" | "lox" | "lo2" => "oxygen",
        "methane" | "ch4" | "lch4" | "lng" => "methane",
        _ => return None,
    })
}

/// The table built into the binary for `name` (or an alias such as `N2`), parsed once.
pub fn embedded(name: &str) -> Result<&'static FluidTable, FluidError> {
    let unknown = || FluidError::UnknownFluid { name: name.to_string(), known: EMBEDDED_FLUIDS.join(", ") };
    let canon = canonical_name(name).ok_or_else(unknown)?;
    let idx = EMBEDDED.iter().position(|(n, _)| *n == canon).ok_or_else(unknown)?;
    if let Some(t) = PARSED[idx].get() {
        return Ok(t);
    }
    let table = FluidTable::from_bytes(EMBEDDED[idx].1)?;
    Ok(PARSED[idx].get_or_init(|| table))
}

/// The raw bytes of an embedded table (for hashing and for writing a copy next to a binary).
pub fn embedded_bytes(name: &str) -> Option<&'static [u8]> {
    let canon = canonical_name(name)?;
    EMBEDDED.iter().find(|(n, _)| *n == canon).map(|(_, b)| *b)
}
