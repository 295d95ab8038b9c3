//! Bindings of the Bouc–Wen benchmark system (SPEC §3.3).
use pyo3::prelude::*;

/// Add this module's functions to the extension module.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
