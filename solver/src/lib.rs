//! cryofit-solver: the numerical core of cryofit.
//!
//! This crate owns everything the two-fluid chilldown model computes: fluid properties
//! ([`fluids`]), and (as they land) closures, the nearly-implicit scheme and case definitions.
//! It performs no I/O: tables arrive as bytes (the four standard fluids are embedded at compile
//! time), and nothing here knows about files, HTTP, SQL or async runtimes.
#![warn(missing_docs)]

pub mod boiling;
pub mod case;
pub mod closures;
pub mod cryo;
pub mod driver;
pub mod exact;
mod fastmath;
pub mod fluids;
pub mod linalg;
pub mod materials;
pub mod model;
pub mod params;
pub mod reference;
pub mod scheme;
