//! Where the binary gets its fluid tables: built in, or from `CRYOFIT_DATA_DIR`.

use std::borrow::Cow;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use cryofit_solver::fluids::{self, FluidTable};

/// Environment variable naming a directory of `<fluid>.cft` tables that replace the built-in ones.
pub const DATA_DIR_VAR: &str = "CRYOFIT_DATA_DIR";

/// The table for `name`: `$CRYOFIT_DATA_DIR/<fluid>.cft` when that variable is set, otherwise the
/// table built into the binary.
pub fn load(name: &str) -> Result<Cow<'static, FluidTable>> {
    let Some(canon) = fluids::canonical_name(name) else {
        // the error lists the known fluids
        return Err(fluids::embedded(name).expect_err("not a known fluid").into());
    };
    match std::env::var_os(DATA_DIR_VAR) {
        Some(dir) if !dir.is_empty() => {
            let path = PathBuf::from(&dir).join(format!("{canon}.cft"));
            let bytes = std::fs::read(&path).with_context(|| {
                format!(
                    "{DATA_DIR_VAR} is set: cannot read {} (unset {DATA_DIR_VAR} to use the built-in tables)",
                    path.display()
                )
            })?;
            let table = FluidTable::from_bytes(&bytes).with_context(|| format!("{}", path.display()))?;
            if table.name() != canon {
                bail!("{} holds the table of '{}', not '{canon}'", path.display(), table.name());
            }
            Ok(Cow::Owned(table))
        }
        _ => Ok(Cow::Borrowed(fluids::embedded(canon)?)),
    }
}
