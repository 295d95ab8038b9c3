//! Argument helpers shared by the binding modules: errors name the argument and the value,
//! and are raised as the classes of `piezohyst.errors` (each also a builtin
//! `ValueError`), so Python callers see one vocabulary whichever layer refused.
use numpy::PyReadonlyArray1;
use piezohyst_core::ModelError;
use pyo3::prelude::*;

pyo3::import_exception!(piezohyst.errors, ParameterError);
pyo3::import_exception!(piezohyst.errors, NotInvertibleError);
pyo3::import_exception!(piezohyst.errors, UnreachableError);

/// What a core error is about: `(parameter, index, value)`, each `None` where it does not
/// apply. Raised errors carry them as the attributes `.parameter`, `.index`, `.value`.
pub fn subject(e: &ModelError) -> (Option<&'static str>, Option<usize>, Option<f64>) {
    let at = |i: usize| if i == usize::MAX { None } else { Some(i) };
    match *e {
        ModelError::NotFinite(n, i, v)
        | ModelError::Negative(n, i, v)
        | ModelError::NotPositive(n, i, v)
        | ModelError::NotIncreasing(n, i, v)
        | ModelError::OutOfRange(n, i, v, _, _) => (Some(n), at(i), Some(v)),
        ModelError::Length(n, _, got) => (Some(n), None, Some(got as f64)),
        ModelError::Structure(n, v) => (Some(n), None, Some(v as f64)),
        ModelError::NotInvertible(i, s) => (Some("weights"), Some(i), Some(s)),
        ModelError::Unreachable(k, y) => (Some("desired"), Some(k), Some(y)),
        ModelError::EnvelopeNotMonotone(n, v, _) => (Some(n), None, Some(v)),
        ModelError::EnvelopesCross(v, i) => (Some("thresholds"), Some(i), Some(v)),
        ModelError::NoAnalyticInverse(_) => (None, None, None),
    }
}

/// A core error as the matching `piezohyst.errors` class, with `.parameter`, `.index` and
/// `.value` set from the error (see [`subject`]); `context` (if not empty) prefixes the
/// message.
pub fn err_in(context: &str, e: ModelError) -> PyErr {
    let msg = if context.is_empty() { e.to_string() } else { format!("{context}: {e}") };
    let raised = match e {
        ModelError::NotInvertible(..) => NotInvertibleError::new_err(msg),
        ModelError::Unreachable(..) => UnreachableError::new_err(msg),
        _ => ParameterError::new_err(msg),
    };
    let (parameter, index, value) = subject(&e);
    Python::attach(|py| {
        let v = raised.value(py);
        // plain attributes of a Python exception instance: setting them cannot fail
        let _ = v.setattr("parameter", parameter);
        let _ = v.setattr("index", index);
        let _ = v.setattr("value", value);
    });
    raised
}

/// A core error as the matching `piezohyst.errors` class (see [`err_in`]).
pub fn err(e: ModelError) -> PyErr {
    err_in("", e)
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
