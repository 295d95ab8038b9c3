//! Bindings of the Bouc–Wen benchmark system (SPEC §3.3): the implicit Newmark +
//! trapezoidal integration at the internal rate and MATLAB-style FIR decimation. Both
//! release the GIL; the Python layer (`piezohyst.boucwen_benchmark`) upsamples the input
//! and composes them.
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadwriteArray1};
use piezohyst_core::boucwen_benchmark::{
    decimate_fir, decimated_len, integrate, prime_factors, BoucWenBenchmark, Newmark, State,
};
use piezohyst_core::ModelError;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// `(y, z)` records.
type Pair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

fn err(e: ModelError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

fn slice<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice()
        .map_err(|_| PyValueError::new_err(format!("{name} must be a contiguous float64 array")))
}

fn check_finite(name: &str, xs: &[f64]) -> PyResult<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(PyValueError::new_err(format!("{name}[{k}] = {} is not finite", xs[k]))),
        None => Ok(()),
    }
}

/// Integrate the benchmark system at the internal step `h` (s).
///
/// `params` = `[mass, damping, stiffness, alpha, beta, gamma, delta, nu]`; `state` =
/// `[y, y', y'', z]` at `t_0` (updated in place to the last instant); `input[i]` is the
/// force (N) at `t_0 + (i+1) h`. Returns `(y, z)` (m, N) at those instants.
#[pyfunction]
fn boucwen_benchmark_integrate<'py>(
    py: Python<'py>,
    params: PyReadonlyArray1<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
    h: f64,
    mut state: PyReadwriteArray1<'py, f64>,
) -> PyResult<Pair<'py>> {
    let cfg = BoucWenBenchmark::from_slice(slice(&params, "params")?).map_err(err)?;
    let stepper = Newmark::new(cfg, h).map_err(err)?;
    let u = slice(&input, "input")?;
    check_finite("input", u)?;
    let st = state
        .as_slice_mut()
        .map_err(|_| PyValueError::new_err("state must be a contiguous float64 array"))?;
    if st.len() != 4 {
        return Err(PyValueError::new_err(format!(
            "state has length {}, expected 4 ([y, dy, ddy, z])",
            st.len()
        )));
    }
    check_finite("state", st)?;
    let mut s = State::from_array([st[0], st[1], st[2], st[3]]);
    let mut y = vec![0.0; u.len()];
    let mut z = vec![0.0; u.len()];
    let failed = py
        .detach(|| integrate(&stepper, &mut s, u, &mut y, &mut z))
        .map_err(err)?;
    st.copy_from_slice(&s.to_array());
    if let Some(k) = failed {
        return Err(PyValueError::new_err(format!(
            "the implicit step at internal step {k} could not be solved (y = {}, z = {}); the input or the parameters drive the system beyond what the step h = {h} resolves",
            y[k], z[k]
        )));
    }
    if let Some(k) = y.iter().zip(&z).position(|(a, b)| !a.is_finite() || !b.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "the simulation diverged at internal step {k} (y = {}, z = {}); the parameters or the step h = {h} do not keep it bounded for this input",
            y[k], z[k]
        )));
    }
    Ok((y.into_pyarray(py), z.into_pyarray(py)))
}

/// MATLAB `decimate(x, p, 'fir')` applied for each prime factor `p` of `factor` in
/// increasing order (the official generator's decimation); `factor = 1` copies.
#[pyfunction]
fn boucwen_benchmark_decimate<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    factor: usize,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    if factor == 0 {
        return Err(PyValueError::new_err("factor = 0 must be >= 1"));
    }
    let xs = slice(&x, "x")?;
    check_finite("x", xs)?;
    let out = py.detach(|| -> Result<Vec<f64>, ModelError> {
        let mut primes = [0usize; 64];
        let np = prime_factors(factor, &mut primes);
        let mut cur = xs.to_vec();
        for &p in &primes[..np] {
            let mut next = vec![0.0; decimated_len(cur.len(), p)];
            decimate_fir(&cur, p, &mut next)?;
            cur = next;
        }
        Ok(cur)
    });
    Ok(out.map_err(err)?.into_pyarray(py))
}

/// Add this module's functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(boucwen_benchmark_integrate, m)?)?;
    m.add_function(wrap_pyfunction!(boucwen_benchmark_decimate, m)?)?;
    Ok(())
}
