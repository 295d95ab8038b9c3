//! Hysteresis models: every model is addressed by its family name, dims and one flat
//! parameter row (see `piezohyst_core::spec`). Batch entry points release the GIL and
//! spread parameter sets over rayon's threads.
use crate::util::ParameterError;
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadwriteArray1, PyUntypedArrayMethods,
};
use piezohyst_core::batch::pi_group;
use piezohyst_core::inverse::{inverse_simulate, solve_increasing};
use piezohyst_core::pi::Pi;
use piezohyst_core::spec::{Family, Model as CoreModel};
use piezohyst_core::{Hysteresis, ModelError};
use pyo3::prelude::*;

use crate::util::{check_alloc, check_finite, err, guarded, interruptible, slice, Stop, INTERRUPTIBLE_WORK};

use rayon::prelude::*;

pub(crate) fn family(name: &str, dims: Vec<usize>) -> PyResult<Family> {
    Family::parse(name, &dims).map_err(|e| match e {
        ModelError::Structure("family (unknown name)", _) => {
            let names: Vec<&str> = piezohyst_core::layout::FAMILIES.iter().map(|f| f.name).collect();
            ParameterError::new_err(format!("family = {name:?} is unknown; expected one of {}", names.join(", ")))
        }
        e => err(e),
    })
}

fn check_output(ys: &[f64]) -> PyResult<()> {
    match ys.iter().position(|y| !y.is_finite()) {
        Some(k) => Err(ParameterError::new_err(format!(
            "the model output diverged at sample {k} (value {}); the parameters do not keep it bounded for this input",
            ys[k]
        ))),
        None => Ok(()),
    }
}

fn with_model<R>(
    fam: Family,
    params: &[f64],
    f: impl FnOnce(&CoreModel<'_>) -> Result<R, ModelError>,
) -> Result<R, ModelError> {
    let mut scratch = vec![0.0; fam.scratch_len()];
    let model = fam.build(params, &mut scratch)?;
    f(&model)
}

fn state_slice<'a>(fam: Family, st: &'a mut PyReadwriteArray1<'_, f64>) -> PyResult<&'a mut [f64]> {
    let s = st.as_slice_mut().map_err(|_| ParameterError::new_err("state must be a contiguous float64 array"))?;
    if s.len() != fam.state_len() {
        return Err(ParameterError::new_err(format!(
            "state has length {}, expected {} for this model",
            s.len(),
            fam.state_len()
        )));
    }
    check_finite("state", s)?;
    Ok(s)
}

/// `(param_len, state_len)` of a family.
#[pyfunction]
fn family_sizes(name: &str, dims: Vec<usize>) -> PyResult<(usize, usize)> {
    let fam = family(name, dims)?;
    Ok((fam.param_len(), fam.state_len()))
}

/// Validate a parameter row; raises ValueError naming the offending parameter.
#[pyfunction]
fn validate(name: &str, dims: Vec<usize>, params: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
    guarded(|| {
        let fam = family(name, dims)?;
        with_model(fam, slice(&params, "params")?, |_| Ok(())).map_err(err)
    })
}

fn initial_state_of(fam: Family, p: &[f64]) -> PyResult<Vec<f64>> {
    let mut st = vec![0.0; fam.state_len()];
    with_model(fam, p, |m| {
        m.reset(&mut st);
        Ok(())
    })
    .map_err(err)?;
    Ok(st)
}

/// Samples per chunk of a single-threaded loop between two looks at the stop flag: about
/// 2^16 state slots of work.
fn chunk_len(state_len: usize) -> usize {
    (1usize << 16) / state_len.max(1) + 1
}

/// Run a single-threaded loop over `n` samples of a model with `state_len` slots: through
/// [`interruptible`] when it is long, else directly with the GIL released.
fn run_long<T: Send>(py: Python<'_>, n: usize, state_len: usize, work: impl FnOnce(&Stop) -> T + Send) -> PyResult<T> {
    if n.saturating_mul(state_len.max(1)) > INTERRUPTIBLE_WORK {
        interruptible(py, work)
    } else {
        Ok(py.detach(|| work(&Stop::default())))
    }
}

fn simulate_from(py: Python<'_>, fam: Family, p: &[f64], v: &[f64], st: &mut [f64]) -> PyResult<Vec<f64>> {
    check_finite("input", v)?;
    check_alloc("simulate: the output", &[v.len()])?;
    let mut y = vec![0.0; v.len()];
    let chunk = chunk_len(fam.state_len());
    run_long(py, v.len(), fam.state_len(), |stop| {
        with_model(fam, p, |m| {
            m.check_state(st)?;
            for (ys, vs) in y.chunks_mut(chunk).zip(v.chunks(chunk)) {
                if stop.stopped() {
                    break;
                }
                for (yk, &vk) in ys.iter_mut().zip(vs) {
                    *yk = m.step(st, vk);
                }
            }
            Ok(())
        })
    })?
    .map_err(err)?;
    check_output(&y)?;
    Ok(y)
}

fn inverse_from(py: Python<'_>, fam: Family, p: &[f64], yd: &[f64], st: &mut [f64], guess: f64) -> PyResult<Vec<f64>> {
    check_finite("desired", yd)?;
    if !guess.is_finite() {
        return Err(ParameterError::new_err(format!("guess = {guess} is not finite")));
    }
    check_alloc("inverse: the output", &[yd.len()])?;
    let mut v = vec![0.0; yd.len()];
    let chunk = chunk_len(fam.state_len());
    run_long(py, yd.len(), fam.state_len(), |stop| {
        with_model(fam, p, |m| {
            m.check_state(st)?;
            // in chunks (the guess of each sample is the input before it, as in one call);
            // a sample index in an error counts from the record's start
            let mut guess = guess;
            for (c, (vs, ys)) in v.chunks_mut(chunk).zip(yd.chunks(chunk)).enumerate() {
                if stop.stopped() {
                    break;
                }
                inverse_simulate(m, st, ys, vs, guess).map_err(|e| match e {
                    ModelError::Unreachable(k, y) => ModelError::Unreachable(k + c * chunk, y),
                    e => e,
                })?;
                guess = vs[vs.len() - 1];
            }
            Ok(())
        })
    })?
    .map_err(err)?;
    Ok(v)
}

/// The relaxed initial state.
#[pyfunction]
fn initial_state<'py>(
    py: Python<'py>,
    name: &str,
    dims: Vec<usize>,
    params: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let fam = family(name, dims)?;
        Ok(initial_state_of(fam, slice(&params, "params")?)?.into_pyarray(py))
    })
}

/// Simulate from `state` (updated in place); returns the outputs.
#[pyfunction]
fn simulate<'py>(
    py: Python<'py>,
    name: &str,
    dims: Vec<usize>,
    params: PyReadonlyArray1<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
    mut state: PyReadwriteArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let fam = family(name, dims)?;
        let p = slice(&params, "params")?;
        let v = slice(&input, "input")?;
        check_finite("input", v)?;
        let st = state_slice(fam, &mut state)?;
        Ok(simulate_from(py, fam, p, v, st)?.into_pyarray(py))
    })
}

/// Exact per-sample inverse from `state` (the forward state, updated in place).
#[pyfunction]
fn inverse<'py>(
    py: Python<'py>,
    name: &str,
    dims: Vec<usize>,
    params: PyReadonlyArray1<'py, f64>,
    desired: PyReadonlyArray1<'py, f64>,
    mut state: PyReadwriteArray1<'py, f64>,
    guess: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let fam = family(name, dims)?;
        let p = slice(&params, "params")?;
        let yd = slice(&desired, "desired")?;
        check_finite("desired", yd)?;
        if !guess.is_finite() {
            return Err(ParameterError::new_err(format!("guess = {guess} is not finite")));
        }
        let st = state_slice(fam, &mut state)?;
        Ok(inverse_from(py, fam, p, yd, st, guess)?.into_pyarray(py))
    })
}

/// A hysteresis model built once from its family name, dims and parameter row, validated
/// at construction (immutable; states are the caller's arrays).
#[pyclass(frozen, module = "piezohyst._core")]
#[derive(Debug)]
pub struct Model {
    pub(crate) fam: Family,
    pub(crate) name: String,
    pub(crate) dims: Vec<usize>,
    pub(crate) params: Vec<f64>,
}

impl Model {
    /// Validate and keep a model.
    pub fn build(name: &str, dims: Vec<usize>, params: &[f64]) -> PyResult<Self> {
        let fam = family(name, dims.clone())?;
        with_model(fam, params, |_| Ok(())).map_err(err)?;
        Ok(Model { fam, name: fam.layout().name.to_string(), dims, params: params.to_vec() })
    }
}

#[pymethods]
impl Model {
    #[new]
    fn new(family: &str, dims: Vec<usize>, params: PyReadonlyArray1<'_, f64>) -> PyResult<Self> {
        guarded(|| Model::build(family, dims, slice(&params, "params")?))
    }
    /// Family name.
    #[getter]
    fn family(&self) -> &str {
        &self.name
    }
    /// Structural sizes.
    #[getter]
    fn dims(&self) -> Vec<usize> {
        self.dims.clone()
    }
    /// The parameter row (a copy).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.params.clone().into_pyarray(py)
    }
    /// Length of the parameter row.
    #[getter]
    fn param_len(&self) -> usize {
        self.fam.param_len()
    }
    /// Length of a state.
    #[getter]
    fn state_len(&self) -> usize {
        self.fam.state_len()
    }
    /// The row's layout (as `family_layout`).
    #[getter]
    fn layout<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        crate::layout::family_dict(py, &self.name, &self.dims)
    }
    /// The relaxed initial state.
    fn initial_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guarded(|| Ok(initial_state_of(self.fam, &self.params)?.into_pyarray(py)))
    }
    /// Outputs for `input` from `state` (updated in place), or from the relaxed state.
    #[pyo3(signature = (input, state=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        input: PyReadonlyArray1<'py, f64>,
        state: Option<PyReadwriteArray1<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guarded(|| {
            let v = slice(&input, "input")?;
            let y = match state {
                Some(mut st) => simulate_from(py, self.fam, &self.params, v, state_slice(self.fam, &mut st)?)?,
                None => {
                    let mut st = initial_state_of(self.fam, &self.params)?;
                    simulate_from(py, self.fam, &self.params, v, &mut st)?
                }
            };
            Ok(y.into_pyarray(py))
        })
    }
    /// Exact per-sample inverse from the forward `state` (updated in place).
    #[pyo3(signature = (desired, state, guess=0.0))]
    fn inverse<'py>(
        &self,
        py: Python<'py>,
        desired: PyReadonlyArray1<'py, f64>,
        mut state: PyReadwriteArray1<'py, f64>,
        guess: f64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guarded(|| {
            let yd = slice(&desired, "desired")?;
            let st = state_slice(self.fam, &mut state)?;
            Ok(inverse_from(py, self.fam, &self.params, yd, st, guess)?.into_pyarray(py))
        })
    }
    fn __repr__(&self) -> String {
        format!("Model({:?}, {:?}, <{} params>)", self.name, self.dims, self.params.len())
    }
}

type InversePi<'py> = (f64, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Analytic inverse PI parameters `(p0', thresholds', weights')` (docs/spec.md §2.1).
#[pyfunction]
fn pi_analytic_inverse<'py>(
    py: Python<'py>,
    p0: f64,
    thresholds: PyReadonlyArray1<'py, f64>,
    weights: PyReadonlyArray1<'py, f64>,
) -> PyResult<InversePi<'py>> {
    guarded(|| {
        let r = slice(&thresholds, "thresholds")?;
        let w = slice(&weights, "weights")?;
        let m = Pi::new(p0, r, w).map_err(err)?;
        let mut ri = vec![0.0; r.len()];
        let mut wi = vec![0.0; r.len()];
        let p0i = m.analytic_inverse(&mut ri, &mut wi).map_err(err)?;
        Ok((p0i, ri.into_pyarray(py), wi.into_pyarray(py)))
    })
}

/// `g^{-1}(y)` element-wise for an envelope (kind 0 identity, 1 polynomial, 2 tanh).
#[pyfunction]
fn envelope_inverse<'py>(
    py: Python<'py>,
    kind: usize,
    coefficients: [f64; 4],
    values: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let g = piezohyst_core::envelope::Envelope::from_code(kind, coefficients).map_err(err)?;
        let ys = slice(&values, "values")?;
        check_finite("values", ys)?;
        let mut out = Vec::with_capacity(ys.len());
        let mut guess = 0.0;
        for (k, &y) in ys.iter().enumerate() {
            let v = g.inverse(y, guess).ok_or_else(|| {
                ParameterError::new_err(format!("values[{k}] = {y} is outside the range of the envelope"))
            })?;
            out.push(v);
            guess = v;
        }
        Ok(out.into_pyarray(py))
    })
}

/// `g(v)` element-wise for an envelope.
#[pyfunction]
fn envelope_eval<'py>(
    py: Python<'py>,
    kind: usize,
    coefficients: [f64; 4],
    values: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let g = piezohyst_core::envelope::Envelope::from_code(kind, coefficients).map_err(err)?;
        let vs = slice(&values, "values")?;
        Ok(vs.iter().map(|&v| g.eval(v)).collect::<Vec<_>>().into_pyarray(py))
    })
}

/// Solve `f(v) = y` for an increasing polynomial `f` (used by tests of the solver).
#[pyfunction]
fn solve_cubic_increasing(coefficients: [f64; 4], y: f64, guess: f64) -> Option<f64> {
    let c = coefficients;
    solve_increasing(
        |v| (c[0] + v * (c[1] + v * (c[2] + v * c[3])), c[1] + v * (2.0 * c[2] + 3.0 * c[3] * v)),
        y,
        guess,
    )
}

// ---------------------------------------------------------------------------------------
// batch evaluation

enum Sink<'a> {
    Outputs(&'a mut [f64]),
    Rmse { target: &'a [f64], sse: f64 },
}

/// One parameter set through the generic model (any family).
/// Stops early (leaving the rest of the output) once `stop` is set.
fn run_one(fam: Family, row: &[f64], v: &[f64], sink: &mut Sink<'_>, stop: &Stop) -> Result<(), ModelError> {
    let chunk = chunk_len(fam.state_len());
    with_model(fam, row, |m| {
        let mut st = vec![0.0; fam.state_len()];
        m.reset(&mut st);
        match sink {
            Sink::Outputs(out) => {
                for (os, vs) in out.chunks_mut(chunk).zip(v.chunks(chunk)) {
                    if stop.stopped() {
                        break;
                    }
                    for (o, &vk) in os.iter_mut().zip(vs) {
                        *o = m.step(&mut st, vk);
                    }
                }
            }
            Sink::Rmse { target, sse } => {
                for (ts, vs) in target.chunks(chunk).zip(v.chunks(chunk)) {
                    if stop.stopped() {
                        break;
                    }
                    for (&t, &vk) in ts.iter().zip(vs) {
                        let e = m.step(&mut st, vk) - t;
                        *sse += e * e;
                    }
                }
            }
        }
        Ok(())
    })
}

/// Parameter sets per lane group: with the operator count unrolled, 8 lanes (one AVX-512
/// register per operator) keep every play state in registers; wider groups spill.
const GROUP: usize = 8;

/// Largest `operators x samples` the lane kernel runs for one group in one go (about half a
/// second): beyond it rows go through the generic path, which looks at the stop flag every
/// chunk of samples (Ctrl-C within a second) and gives the same outputs bit for bit.
const GROUP_WORK_MAX: usize = 1 << 26;

/// Check rows; returns per-row validity or the first error (with its row index).
fn check_rows(fam: Family, params: &[f64], s: usize, raise: bool) -> PyResult<Vec<bool>> {
    let p = fam.param_len();
    let mut ok = Vec::with_capacity(s);
    for j in 0..s {
        let row = &params[j * p..(j + 1) * p];
        match with_model(fam, row, |_| Ok(())) {
            Ok(()) => ok.push(true),
            Err(e) if raise => return Err(crate::util::err_in(&format!("params[{j}]"), e)),
            Err(_) => ok.push(false),
        }
    }
    Ok(ok)
}

// two call sites, each passing its own buffers and the stop flag of `interruptible`
#[allow(clippy::too_many_arguments)]
fn batch_core(
    fam: Family,
    params: &[f64],
    s: usize,
    v: &[f64],
    target: Option<&[f64]>,
    valid: &[bool],
    out: &mut [f64],
    stop: &Stop,
) -> Vec<Option<ModelError>> {
    let p = fam.param_len();
    let nv = v.len();
    let per = if target.is_some() { 1 } else { nv };
    let mut errs: Vec<Option<ModelError>> = vec![None; s];
    match fam {
        Family::Pi { n, creep: 0 } if n.saturating_mul(nv) <= GROUP_WORK_MAX => {
            // groups of GROUP valid rows; invalid rows are left for the caller
            let idx: Vec<usize> = (0..s).filter(|&j| valid[j]).collect();
            let groups: Vec<&[usize]> = idx.chunks(GROUP).collect();
            let results: Vec<(Vec<usize>, Vec<f64>)> = groups
                .par_iter()
                .map(|g| {
                    if stop.stopped() {
                        return (Vec::new(), Vec::new());
                    }
                    let rows: Vec<&[f64]> = g.iter().map(|&j| &params[j * p..(j + 1) * p]).collect();
                    let mut buf = vec![0.0; g.len() * per];
                    let mut scratch = if n > piezohyst_core::batch::MAX_FIXED_OPERATORS {
                        vec![[0.0; GROUP]; 3 * n]
                    } else {
                        Vec::new()
                    };
                    pi_group::<GROUP>(n, &rows, v, &mut buf, target, &mut scratch);
                    (g.to_vec(), buf)
                })
                .collect();
            for (g, buf) in results {
                for (l, &j) in g.iter().enumerate() {
                    out[j * per..(j + 1) * per].copy_from_slice(&buf[l * per..(l + 1) * per]);
                }
            }
        }
        _ => {
            out.par_chunks_mut(per).zip(errs.par_iter_mut()).enumerate().for_each(|(j, (o, e))| {
                if !valid[j] || stop.stopped() {
                    return;
                }
                let row = &params[j * p..(j + 1) * p];
                let mut sink = match target {
                    None => Sink::Outputs(o),
                    Some(t) => Sink::Rmse { target: t, sse: 0.0 },
                };
                if let Err(x) = run_one(fam, row, v, &mut sink, stop) {
                    *e = Some(x);
                }
                if let Sink::Rmse { sse, .. } = sink {
                    o[0] = sse;
                }
            });
        }
    }
    errs
}

fn batch_inputs<'a>(
    fam: Family,
    params: &'a PyReadonlyArray2<'_, f64>,
    input: &'a PyReadonlyArray1<'_, f64>,
) -> PyResult<(&'a [f64], usize, &'a [f64])> {
    let shape = params.shape();
    if shape[1] != fam.param_len() {
        return Err(ParameterError::new_err(format!(
            "params has shape ({}, {}), expected (S, {}) for this family",
            shape[0],
            shape[1],
            fam.param_len()
        )));
    }
    // as_slice also accepts Fortran order (then in memory order): insist on rows
    if !params.is_c_contiguous() {
        return Err(ParameterError::new_err("params must be a C-contiguous float64 array"));
    }
    let p = params.as_slice().map_err(|_| ParameterError::new_err("params must be a C-contiguous float64 array"))?;
    let v = slice(input, "input")?;
    check_finite("input", v)?;
    if v.is_empty() {
        return Err(ParameterError::new_err("input is empty"));
    }
    Ok((p, shape[0], v))
}

/// `(S, N)` outputs of `S` parameter sets on one input record (GIL released, rayon).
#[pyfunction]
fn batch_simulate<'py>(
    py: Python<'py>,
    name: &str,
    dims: Vec<usize>,
    params: PyReadonlyArray2<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    guarded(|| {
        let fam = family(name, dims)?;
        let (p, s, v) = batch_inputs(fam, &params, &input)?;
        check_alloc("batch_simulate: the (S, N) result", &[s, v.len()])?;
        let valid = check_rows(fam, p, s, true)?;
        let mut out = vec![0.0; s * v.len()];
        let errs = interruptible(py, |stop| batch_core(fam, p, s, v, None, &valid, &mut out, stop))?;
        if let Some((j, e)) = errs.iter().enumerate().find_map(|(j, e)| e.map(|e| (j, e))) {
            return Err(crate::util::err_in(&format!("params[{j}]"), e));
        }
        let arr = Array2::from_shape_vec((s, v.len()), out).expect("shape matches length");
        Ok(arr.into_pyarray(py))
    })
}

/// `(S,)` RMSE of `S` parameter sets against `target` (GIL released, rayon). Invalid rows
/// raise, or cost `invalid_cost` if given; a diverging simulation costs +inf.
#[pyfunction]
#[pyo3(signature = (name, dims, params, input, target, invalid_cost=None))]
fn batch_rmse<'py>(
    py: Python<'py>,
    name: &str,
    dims: Vec<usize>,
    params: PyReadonlyArray2<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
    target: PyReadonlyArray1<'py, f64>,
    invalid_cost: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let fam = family(name, dims)?;
        let (p, s, v) = batch_inputs(fam, &params, &input)?;
        let t = slice(&target, "target")?;
        check_finite("target", t)?;
        if t.len() != v.len() {
            return Err(ParameterError::new_err(format!(
                "target has length {}, input has length {}; they must match",
                t.len(),
                v.len()
            )));
        }
        // rows, their results and one state each
        check_alloc("batch_rmse: the rows' work buffers", &[s, 3 + fam.state_len()])?;
        let valid = check_rows(fam, p, s, invalid_cost.is_none())?;
        let mut sse = vec![0.0; s];
        let errs = interruptible(py, |stop| batch_core(fam, p, s, v, Some(t), &valid, &mut sse, stop))?;
        let n = v.len() as f64;
        let bad = invalid_cost.unwrap_or(f64::INFINITY);
        let out: Vec<f64> = (0..s)
            .map(|j| {
                if !valid[j] || errs[j].is_some() {
                    bad
                } else if sse[j].is_finite() {
                    (sse[j] / n).sqrt()
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        Ok(out.into_pyarray(py))
    })
}

/// Regressors of a row's linear parameters over an input record, from the relaxed state:
/// `(N, m)` (columns in `piezohyst_core::spec::Model::regressors_step`).
#[pyfunction]
fn regressors<'py>(
    py: Python<'py>,
    name: &str,
    dims: Vec<usize>,
    params: PyReadonlyArray1<'py, f64>,
    input: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    guarded(|| {
        let fam = family(name, dims)?;
        let p = slice(&params, "params")?;
        let v = slice(&input, "input")?;
        check_finite("input", v)?;
        let m = fam.regressor_count();
        if m == 0 {
            return Err(ParameterError::new_err(format!("family = {name:?} has no linear parameters to regress on")));
        }
        check_alloc("regressors: the (N, m) result", &[v.len(), m])?;
        let mut out = vec![0.0; v.len() * m];
        let ok = run_long(py, v.len(), m + fam.state_len(), |stop| {
            with_model(fam, p, |model| {
                let mut st = vec![0.0; fam.state_len()];
                model.reset(&mut st);
                let mut ok = true;
                for (k, &vk) in v.iter().enumerate() {
                    if k % 1024 == 0 && stop.stopped() {
                        break;
                    }
                    ok &= model.regressors_step(&mut st, vk, &mut out[k * m..(k + 1) * m]);
                }
                Ok(ok)
            })
        })?
        .map_err(err)?;
        if !ok {
            return Err(ParameterError::new_err(format!("family = {name:?} has no linear parameters to regress on")));
        }
        let arr = Array2::from_shape_vec((v.len(), m), out).expect("shape matches length");
        Ok(arr.into_pyarray(py))
    })
}

/// Number of threads rayon uses for batch calls.
#[pyfunction]
fn thread_count() -> usize {
    rayon::current_num_threads()
}

/// Add this module's functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Model>()?;
    m.add_function(wrap_pyfunction!(family_sizes, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(initial_state, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(inverse, m)?)?;
    m.add_function(wrap_pyfunction!(pi_analytic_inverse, m)?)?;
    m.add_function(wrap_pyfunction!(envelope_inverse, m)?)?;
    m.add_function(wrap_pyfunction!(envelope_eval, m)?)?;
    m.add_function(wrap_pyfunction!(solve_cubic_increasing, m)?)?;
    m.add_function(wrap_pyfunction!(batch_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(batch_rmse, m)?)?;
    m.add_function(wrap_pyfunction!(thread_count, m)?)?;
    m.add_function(wrap_pyfunction!(regressors, m)?)?;
    Ok(())
}
