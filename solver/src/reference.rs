//! Reference problems with known answers, shared by tests and benchmarks.
//!
//! Each is one of the case files in `examples/verification/`, compiled into the library, with
//! the number of cells as a knob for grid-refinement studies.

use crate::case::Case;

/// The verification problems.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reference {
    /// Ransom's water faucet (`faucet.toml`).
    Faucet,
    /// Frictionless oscillating manometer (`manometer.toml`).
    Manometer,
    /// Drag-free phase separation in a closed vertical tube (`separation.toml`).
    Separation,
    /// Single-phase gas cooling a warm wall (`schumann.toml`).
    Schumann,
    /// Liquid from a reservoir through a valve and a pipe (`liquid_reservoir.toml`).
    LiquidReservoir,
    /// Cold gas cooling the 61 m NBS line for 1000 s (`gas_cooldown.toml`).
    GasCooldown,
}

impl Reference {
    /// All of them.
    pub const ALL: [Reference; 4] =
        [Reference::Faucet, Reference::Manometer, Reference::Separation, Reference::Schumann];

    /// File name in `examples/verification/`.
    pub fn file_name(self) -> &'static str {
        match self {
            Reference::Faucet => "faucet.toml",
            Reference::Manometer => "manometer.toml",
            Reference::Separation => "separation.toml",
            Reference::Schumann => "schumann.toml",
            Reference::LiquidReservoir => "liquid_reservoir.toml",
            Reference::GasCooldown => "gas_cooldown.toml",
        }
    }

    /// The case file's text.
    pub fn text(self) -> &'static str {
        match self {
            Reference::Faucet => include_str!("../../examples/verification/faucet.toml"),
            Reference::Manometer => include_str!("../../examples/verification/manometer.toml"),
            Reference::Separation => include_str!("../../examples/verification/separation.toml"),
            Reference::Schumann => include_str!("../../examples/verification/schumann.toml"),
            Reference::LiquidReservoir => include_str!("../../examples/verification/liquid_reservoir.toml"),
            Reference::GasCooldown => include_str!("../../examples/verification/gas_cooldown.toml"),
        }
    }

    /// The case as shipped.
    pub fn case(self) -> Case {
        Case::from_toml(self.text(), self.file_name()).expect("reference cases are valid")
    }

    /// The case with `cells` cells.
    pub fn with_cells(self, cells: usize) -> Case {
        let mut c = self.case();
        c.pipe.cells = cells;
        c
    }
}
