//! Python bindings of the piezohyst core (`piezohyst._core`): array in, array out. One file
//! per topic; each registers its functions here.
use pyo3::prelude::*;

// mimalloc keeps freed pages for reuse: a simulation's recorded signals (megabytes per
// run) land in memory the previous run released instead of freshly mapped pages, whose first
// touch dominated short runs. Freed memory goes back to the OS after a second of idling.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

mod boucwen_benchmark;
mod control;
mod layout;
mod lfr;
mod models;
mod multiaxis;
mod plant;
mod steps;
mod util;

/// A deliberate panic inside [`util::guarded`], so a test can check the last line of
/// defence: an `InternalError`, not a `PanicException`. Private (not in the stub).
#[pyfunction]
fn _panic_for_tests() -> PyResult<()> {
    util::guarded(|| -> PyResult<()> { panic!("a deliberate panic of the test") })
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // purge freed pages after 1 s rather than mimalloc's default 10 ms (option 15 is
    // mi_option_purge_delay in the bundled mimalloc v2 header)
    // SAFETY: mi_option_set stores one integer option; it takes no pointers
    unsafe { libmimalloc_sys::mi_option_set(15, 1000) };
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // set as a plain attribute, so it stays out of `__all__` and the stub (private)
    m.setattr("_panic_for_tests", wrap_pyfunction!(_panic_for_tests, m)?)?;
    models::register(m)?;
    layout::register(m)?;
    lfr::register(m)?;
    boucwen_benchmark::register(m)?;
    plant::register(m)?;
    multiaxis::register(m)?;
    steps::register(m)?;
    Ok(())
}
