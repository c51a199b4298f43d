//! Where the coordinator's fluid tables come from: a [`FluidLoader`] names a table and returns it
//! with the hash of its bytes ([`cryofit_api::fluid_hash`]).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

use cryofit_solver::fluids::FluidTable;

/// Loads a fluid table by name and returns it with [`cryofit_api::fluid_hash`] of its bytes.
pub type FluidLoader = Arc<dyn Fn(&str) -> Result<(Arc<FluidTable>, String), String> + Send + Sync>;

/// The tables built into the binary, hashed; each copied out once and shared afterwards.
pub fn embedded_fluids() -> FluidLoader {
    let loaded: Mutex<HashMap<&'static str, (Arc<FluidTable>, String)>> = Mutex::default();
    Arc::new(move |name: &str| {
        let canon = cryofit_solver::fluids::canonical_name(name).ok_or_else(|| format!("unknown fluid `{name}`"))?;
        let mut map = loaded.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((t, h)) = map.get(canon) {
            return Ok((t.clone(), h.clone()));
        }
        let table = cryofit_solver::fluids::embedded(canon).map_err(|e| e.to_string())?;
        let bytes = cryofit_solver::fluids::embedded_bytes(canon).ok_or_else(|| format!("unknown fluid `{name}`"))?;
        let v = (Arc::new(table.clone()), cryofit_api::fluid_hash(bytes));
        map.insert(canon, v.clone());
        Ok(v)
    })
}
