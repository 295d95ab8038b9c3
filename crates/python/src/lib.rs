//! Python bindings of the piezohyst core (`piezohyst._core`): array in, array out. One file
//! per topic; each registers its functions here.
use pyo3::prelude::*;

mod boucwen_benchmark;
mod models;
mod plant;
mod util;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    models::register(m)?;
    boucwen_benchmark::register(m)?;
    plant::register(m)?;
    Ok(())
}
