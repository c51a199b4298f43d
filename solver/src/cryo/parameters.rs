//! The closure set's constants: [`CryoParams`], read once from the parameter registry, the
//! registry names it reads ([`PARAMETER_NAMES`]) and the choice of film-boiling pair
//! ([`CorrelationSet`]).

use std::fmt;
use std::str::FromStr;

use crate::fluids::FluidConstants;
use crate::params::ParameterSet;

/// Theler's k_g = c_p/R of a diatomic ideal gas with its rotation excited: nitrogen's, the
/// default of [`CryoParams::ideal_cp_over_r`].
pub const DIATOMIC_CP_OVER_R: f64 = 3.5;
/// Nitrogen's specific gas constant, J/(kg K): the default of [`CryoParams::gas_constant`].
pub const NITROGEN_GAS_CONSTANT: f64 = 296.8;
/// Nitrogen's critical temperature, K: the default of [`CryoParams::t_critical`].
pub const NITROGEN_T_CRITICAL: f64 = 126.192;

/// Which film-boiling / minimum-film-boiling pair the boiling curve uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum CorrelationSet {
    /// The paper's: Berenson ΔT_mfb with the Iloeje correction (eq:Tmfb, eq:Iloeje) and Bromley
    /// film boiling with the Iloeje correction (eq:Bromley, eq:Iloeje_hfb).
    #[default]
    Paper,
    /// The alternative: Miropolskii film boiling with its Y correction (never below pool
    /// Bromley) and a Darr–Hartwig-type rewet temperature in place of T_mfb.
    Miropolskii,
}

impl CorrelationSet {
    /// Every set, in order.
    pub const ALL: [CorrelationSet; 2] = [CorrelationSet::Paper, CorrelationSet::Miropolskii];

    /// The name used in case files: `paper` or `miropolskii`.
    pub fn name(self) -> &'static str {
        match self {
            CorrelationSet::Paper => "paper",
            CorrelationSet::Miropolskii => "miropolskii",
        }
    }
}

impl fmt::Display for CorrelationSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown correlation-set name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown correlation set '{0}' (expected 'paper' or 'miropolskii')")]
pub struct UnknownCorrelationSet(pub String);

impl FromStr for CorrelationSet {
    type Err = UnknownCorrelationSet;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        CorrelationSet::ALL
            .into_iter()
            .find(|c| c.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownCorrelationSet(s.to_string()))
    }
}

/// `PARAMETER_NAMES`, [`CryoParams`] and [`CryoParams::from_set`] from the registry's parameter
/// table (`crate::params::parameter_table`): the entries with a field, in table order.
macro_rules! cryo_params {
    (@emit $($(#[$doc:meta])* $field:ident = $name:literal;)*) => {
        /// The registry names [`CryoParams::from_set`] reads, in the order of the struct fields.
        pub const PARAMETER_NAMES: &[&str] = &[$($name),*];

        /// The constants of the closure set, read once from a [`ParameterSet`] (each field's doc
        /// starts with its registry name), plus three fluid constants.
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct CryoParams {
            $($(#[$doc])* pub $field: f64,)*
            /// Specific gas constant R_g of the fluid, J/(kg K) (Theler's T_chf). Nitrogen unless set
            /// with [`CryoParams::with_fluid`].
            pub gas_constant: f64,
            /// Critical temperature of the fluid, K (Darr–Hartwig rewet temperature). Nitrogen unless
            /// set with [`CryoParams::with_fluid`].
            pub t_critical: f64,
            /// Ideal-gas c_p/R of the fluid's vapour near its normal boiling point (Theler's k_g):
            /// 3.5 for nitrogen and oxygen, about 4 for methane, 2.5 for para-hydrogen (rotation
            /// frozen). Nitrogen's unless set with [`CryoParams::with_ideal_cp_over_r`].
            pub ideal_cp_over_r: f64,
        }

        impl CryoParams {
            /// Reads every closure constant from `set` (registry defaults for the rest). The fluid
            /// constants are nitrogen's: call [`CryoParams::with_fluid`] for another fluid.
            pub fn from_set(set: &ParameterSet) -> Self {
                let g = |n: &str| set.get(n);
                Self {
                    $($field: g($name),)*
                    gas_constant: NITROGEN_GAS_CONSTANT,
                    t_critical: NITROGEN_T_CRITICAL,
                    ideal_cp_over_r: DIATOMIC_CP_OVER_R,
                }
            }
        }
    };
    // an entry read elsewhere: skipped
    (@acc [$($acc:tt)*]
        $name:literal {
            group: $group:literal,
            default: $default:expr,
            lower: $lower:expr,
            upper: $upper:expr,
            unit: $unit:literal,
            description: $description:literal,
            $(#[$doc:meta])*
            field: _,
        }
        $($rest:tt)*
    ) => {
        cryo_params! { @acc [$($acc)*] $($rest)* }
    };
    // an entry with a field: kept
    (@acc [$($acc:tt)*]
        $name:literal {
            group: $group:literal,
            default: $default:expr,
            lower: $lower:expr,
            upper: $upper:expr,
            unit: $unit:literal,
            description: $description:literal,
            $(#[$doc:meta])*
            field: $field:ident,
        }
        $($rest:tt)*
    ) => {
        cryo_params! { @acc [$($acc)* $(#[$doc])* $field = $name;] $($rest)* }
    };
    (@acc [$($acc:tt)*]) => {
        cryo_params! { @emit $($acc)* }
    };
    ($($table:tt)*) => {
        cryo_params! { @acc [] $($table)* }
    };
}

crate::params::parameter_table!(cryo_params);

impl CryoParams {
    /// The stratified → stratified-wavy boundary's coefficients [c0, c1, c2] (`regime_strat_c0..c2`):
    /// G_strat(χ) = c0 + c1 χ + c2 χ².
    pub fn strat_poly(&self) -> [f64; 3] {
        [self.strat_c0, self.strat_c1, self.strat_c2]
    }

    /// The stratified-wavy → annular/intermittent boundary's coefficients [c0, c1, c2]
    /// (`regime_wavy_c0..c2`): G_wavy(χ) = c0 + c1 χ + c2 χ².
    pub fn wavy_poly(&self) -> [f64; 3] {
        [self.wavy_c0, self.wavy_c1, self.wavy_c2]
    }

    /// The same constants with the fluid's ideal-gas c_p/R (Theler's k_g).
    pub fn with_ideal_cp_over_r(mut self, cp_over_r: f64) -> Self {
        if cp_over_r.is_finite() && cp_over_r > 1.0 {
            self.ideal_cp_over_r = cp_over_r;
        }
        self
    }

    /// The same constants with the fluid's gas constant and critical temperature.
    pub fn with_fluid(mut self, fluid: &FluidConstants) -> Self {
        self.gas_constant = fluid.gas_constant_j_kg_k;
        self.t_critical = fluid.t_critical_k;
        self
    }
}

impl Default for CryoParams {
    /// Registry defaults, nitrogen.
    fn default() -> Self {
        Self::from_set(&ParameterSet::new())
    }
}
