//! Argument helpers shared by the binding modules: errors name the argument and the value.
use numpy::PyReadonlyArray1;
use piezohyst_core::ModelError;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// A core error as a Python `ValueError`.
pub fn err(e: ModelError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The array's data, which must be contiguous.
pub fn slice<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| PyValueError::new_err(format!("{name} must be a contiguous float64 array")))
}

/// Every value finite, else an error naming the first offender.
pub fn check_finite(name: &str, xs: &[f64]) -> PyResult<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(PyValueError::new_err(format!("{name}[{k}] = {} is not finite", xs[k]))),
        None => Ok(()),
    }
}
