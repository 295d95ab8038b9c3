//! Argument helpers shared by the binding modules: errors name the argument and the value,
//! and are raised as the classes of `piezohyst.errors` (each also a builtin
//! `ValueError`), so Python callers see one vocabulary whichever layer refused.
use numpy::PyReadonlyArray1;
use piezohyst_core::ModelError;
use pyo3::prelude::*;

pyo3::import_exception!(piezohyst.errors, ParameterError);
pyo3::import_exception!(piezohyst.errors, NotInvertibleError);
pyo3::import_exception!(piezohyst.errors, UnreachableError);

/// A core error as the matching `piezohyst.errors` class.
pub fn err(e: ModelError) -> PyErr {
    let msg = e.to_string();
    match e {
        ModelError::NotInvertible(..) => NotInvertibleError::new_err(msg),
        ModelError::Unreachable(..) => UnreachableError::new_err(msg),
        _ => ParameterError::new_err(msg),
    }
}

/// A bad argument (`piezohyst.errors.ParameterError`, a `ValueError`).
pub fn bad_arg(msg: String) -> PyErr {
    ParameterError::new_err(msg)
}

/// The array's data, which must be contiguous.
pub fn slice<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| bad_arg(format!("{name} must be a contiguous float64 array")))
}

/// Every value finite, else an error naming the first offender.
pub fn check_finite(name: &str, xs: &[f64]) -> PyResult<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(bad_arg(format!("{name}[{k}] = {} is not finite", xs[k]))),
        None => Ok(()),
    }
}
