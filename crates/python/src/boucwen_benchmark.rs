//! Bindings of the Bouc–Wen benchmark system (docs/spec.md §3.3): the implicit Newmark +
//! trapezoidal integration at the internal rate, MATLAB-style FIR decimation, and the batch
//! entry points of identification (many parameter rows on one high-rate input: the record
//! simulated and decimated as one simulation does, rayon across rows). All release the GIL;
//! the Python layer (`piezohyst.boucwen_benchmark`) upsamples the input.
use crate::util::ParameterError;
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadwriteArray1, PyUntypedArrayMethods,
};
use piezohyst_core::boucwen_benchmark::{
    cascade_work_len, decimate_cascade, decimated_len, integrate, record_rmse, simulate_record, BoucWenBenchmark,
    Newmark, RecordBuffers, State,
};
use piezohyst_core::ModelError;
use pyo3::prelude::*;
use rayon::prelude::*;

use crate::util::{check_alloc, guarded, interruptible};

/// `(y, z)` records.
type Pair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

fn err(e: ModelError) -> PyErr {
    ParameterError::new_err(e.to_string())
}

fn slice<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice().map_err(|_| ParameterError::new_err(format!("{name} must be a contiguous float64 array")))
}

fn check_finite(name: &str, xs: &[f64]) -> PyResult<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(k) => Err(ParameterError::new_err(format!("{name}[{k}] = {} is not finite", xs[k]))),
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
    guarded(|| {
        let cfg = BoucWenBenchmark::from_slice(slice(&params, "params")?).map_err(err)?;
        let stepper = Newmark::new(cfg, h).map_err(err)?;
        let u = slice(&input, "input")?;
        check_finite("input", u)?;
        let st =
            state.as_slice_mut().map_err(|_| ParameterError::new_err("state must be a contiguous float64 array"))?;
        if st.len() != 4 {
            return Err(ParameterError::new_err(format!(
                "state has length {}, expected 4 ([y, dy, ddy, z])",
                st.len()
            )));
        }
        check_finite("state", st)?;
        let mut s = State::from_array([st[0], st[1], st[2], st[3]]);
        let mut y = vec![0.0; u.len()];
        let mut z = vec![0.0; u.len()];
        let failed = py.detach(|| integrate(&stepper, &mut s, u, &mut y, &mut z)).map_err(err)?;
        st.copy_from_slice(&s.to_array());
        if let Some(k) = failed {
            return Err(ParameterError::new_err(format!(
            "the implicit step at internal step {k} could not be solved (y = {}, z = {}); the input or the parameters drive the system beyond what the step h = {h} resolves",
            y[k], z[k]
        )));
        }
        if let Some(k) = y.iter().zip(&z).position(|(a, b)| !a.is_finite() || !b.is_finite()) {
            return Err(ParameterError::new_err(format!(
            "the simulation diverged at internal step {k} (y = {}, z = {}); the parameters or the step h = {h} do not keep it bounded for this input",
            y[k], z[k]
        )));
        }
        Ok((y.into_pyarray(py), z.into_pyarray(py)))
    })
}

/// MATLAB `decimate(x, p, 'fir')` applied for each prime factor `p` of `factor` in
/// increasing order (the official generator's decimation); `factor = 1` copies.
#[pyfunction]
fn boucwen_benchmark_decimate<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    factor: usize,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        if factor == 0 {
            return Err(ParameterError::new_err("factor = 0 must be >= 1"));
        }
        let xs = slice(&x, "x")?;
        check_finite("x", xs)?;
        let out = py.detach(|| -> Result<Vec<f64>, ModelError> {
            let mut cur = xs.to_vec();
            let mut work = vec![0.0; cascade_work_len(xs.len(), factor)];
            let mut out = vec![0.0; decimated_len(xs.len(), factor)];
            decimate_cascade(&mut cur, factor, &mut work, &mut out)?;
            Ok(out)
        });
        Ok(out.map_err(err)?.into_pyarray(py))
    })
}

/// The checked arguments of a batch call: one stepper per row (`None`: invalid row), the
/// high-rate input and the decimated record length.
struct Batch<'a> {
    steppers: Vec<Option<Newmark>>,
    input: &'a [f64],
    n_out: usize,
}

fn batch_args<'a>(
    params: &PyReadonlyArray2<'_, f64>,
    input: &'a PyReadonlyArray1<'_, f64>,
    h: f64,
    factor: usize,
    raise_invalid: bool,
) -> PyResult<Batch<'a>> {
    let shape = params.shape();
    let width = BoucWenBenchmark::PARAM_LEN;
    if shape[1] != width {
        return Err(ParameterError::new_err(format!(
            "params has shape ({}, {}), expected (S, {width}) rows [mass, damping, stiffness, alpha, beta, gamma, delta, nu]",
            shape[0], shape[1]
        )));
    }
    // as_slice also accepts Fortran order (then in memory order): insist on rows
    let p = params
        .as_slice()
        .ok()
        .filter(|_| params.is_c_contiguous())
        .ok_or_else(|| ParameterError::new_err("params must be a C-contiguous float64 array"))?;
    if factor == 0 {
        return Err(ParameterError::new_err("factor = 0 must be >= 1"));
    }
    // the step is checked once, not per row
    Newmark::new(BoucWenBenchmark::default(), h).map_err(err)?;
    let u = slice(input, "input")?;
    if u.is_empty() {
        return Err(ParameterError::new_err("input has 0 samples"));
    }
    check_finite("input", u)?;
    let mut steppers = Vec::with_capacity(shape[0]);
    for (j, row) in p.chunks_exact(width).enumerate() {
        let nu = row[width - 1];
        if raise_invalid && nu.is_finite() && nu < 1.0 {
            return Err(ParameterError::new_err(format!("params[{j}]: nu = {nu} must be >= 1")));
        }
        match BoucWenBenchmark::from_slice(row).and_then(|cfg| Newmark::new(cfg, h)) {
            Ok(s) => steppers.push(Some(s)),
            Err(e) if raise_invalid => return Err(ParameterError::new_err(format!("params[{j}]: {e}"))),
            Err(_) => steppers.push(None),
        }
    }
    Ok(Batch { steppers, input: u, n_out: decimated_len(u.len(), factor) })
}

/// `(S,)` RMSE (m) of `S` parameter rows `[mass, damping, stiffness, alpha, beta, gamma,
/// delta, nu]` against `target`: each row simulates the high-rate force `input` (N,
/// `input[i]` at `i h`) from rest and FIR-decimates by `factor` exactly as one simulation
/// does (`piezohyst_core::boucwen_benchmark::simulate_record`); the RMSE is over decimated
/// samples `skip .. skip + len(target)`. GIL released, rayon across rows, each row summed
/// in sample order (the result does not depend on the thread count). Invalid rows raise
/// naming the row, or cost `invalid_cost` if given; a run whose implicit step cannot be
/// solved or that diverges costs +inf.
#[pyfunction]
#[pyo3(signature = (params, input, h, factor, target, skip=0, invalid_cost=None))]
fn boucwen_benchmark_batch_rmse<'py>(
    params: PyReadonlyArray2<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
    h: f64,
    factor: usize,
    target: PyReadonlyArray1<'py, f64>,
    skip: usize,
    invalid_cost: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let py = params.py();
        let b = batch_args(&params, &input, h, factor, invalid_cost.is_none())?;
        let t = slice(&target, "target")?;
        check_finite("target", t)?;
        if t.is_empty() || skip + t.len() > b.n_out {
            return Err(ParameterError::new_err(format!(
            "target has length {} and skip = {skip}, but the decimated record has {} samples (len(input) = {}, factor = {factor}); need 1 <= len(target) <= {}",
            t.len(),
            b.n_out,
            b.input.len(),
            b.n_out.saturating_sub(skip)
        )));
        }
        let bad = invalid_cost.unwrap_or(f64::INFINITY);
        let (u, n_out) = (b.input, b.n_out);
        let wl = cascade_work_len(u.len(), factor);
        // work buffers per rayon thread
        check_alloc(
            "boucwen_benchmark_batch_rmse: the work buffers",
            &[rayon::current_num_threads(), u.len() + wl + n_out],
        )?;
        let out: Result<Vec<f64>, ModelError> = interruptible(py, |stop| {
            b.steppers
                .par_iter()
                .map_init(
                    || (vec![0.0; u.len()], vec![0.0; wl], vec![0.0; n_out]),
                    |(fine, work, dec), st| match st {
                        _ if stop.stopped() => Ok(bad),
                        None => Ok(bad),
                        Some(st) => record_rmse(st, u, factor, t, skip, &mut RecordBuffers { fine, work, out: dec }),
                    },
                )
                .collect()
        })?;
        Ok(out.map_err(err)?.into_pyarray(py))
    })
}

/// `(S, count)` displacements (m) of `S` parameter rows over the high-rate force `input`,
/// simulated and decimated as [`boucwen_benchmark_batch_rmse`] does: decimated samples
/// `skip .. skip + count` (`count` defaults to the rest of the record). Invalid rows raise
/// naming the row; a row whose implicit step cannot be solved or that diverges is NaN.
#[pyfunction]
#[pyo3(signature = (params, input, h, factor, skip=0, count=None))]
fn boucwen_benchmark_batch_simulate<'py>(
    py: Python<'py>,
    params: PyReadonlyArray2<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
    h: f64,
    factor: usize,
    skip: usize,
    count: Option<usize>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    guarded(|| {
        let b = batch_args(&params, &input, h, factor, true)?;
        let (u, n_out) = (b.input, b.n_out);
        let count = count.unwrap_or(n_out.saturating_sub(skip));
        if count == 0 || skip + count > n_out {
            return Err(ParameterError::new_err(format!(
            "skip = {skip} and count = {count}, but the decimated record has {n_out} samples (len(input) = {}, factor = {factor}); need 1 <= count <= {}",
            u.len(),
            n_out.saturating_sub(skip)
        )));
        }
        let s = b.steppers.len();
        let wl = cascade_work_len(u.len(), factor);
        check_alloc("boucwen_benchmark_batch_simulate: the (S, count) result", &[s, count])?;
        check_alloc(
            "boucwen_benchmark_batch_simulate: the work buffers",
            &[rayon::current_num_threads(), u.len() + wl + n_out],
        )?;
        let mut out = vec![0.0; s * count];
        let res: Result<(), ModelError> = interruptible(py, |stop| {
            out.par_chunks_mut(count.max(1)).zip(b.steppers.par_iter()).try_for_each_init(
                || (vec![0.0; u.len()], vec![0.0; wl], vec![0.0; n_out]),
                |(fine, work, dec), (row, st)| {
                    if stop.stopped() {
                        return Ok(());
                    }
                    let st = st.as_ref().expect("invalid rows raised above");
                    match simulate_record(st, u, factor, &mut RecordBuffers { fine, work, out: dec })? {
                        Ok(()) => row.copy_from_slice(&dec[skip..skip + count]),
                        Err(_) => row.fill(f64::NAN),
                    }
                    Ok(())
                },
            )
        })?;
        res.map_err(err)?;
        let arr = Array2::from_shape_vec((s, count), out).expect("shape matches length");
        Ok(arr.into_pyarray(py))
    })
}

/// Add this module's functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(boucwen_benchmark_integrate, m)?)?;
    m.add_function(wrap_pyfunction!(boucwen_benchmark_decimate, m)?)?;
    m.add_function(wrap_pyfunction!(boucwen_benchmark_batch_rmse, m)?)?;
    m.add_function(wrap_pyfunction!(boucwen_benchmark_batch_simulate, m)?)?;
    Ok(())
}
