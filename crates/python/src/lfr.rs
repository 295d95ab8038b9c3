//! Bindings of the MIMO LFR model with play-operator feedback (`piezohyst_core::lfr`):
//! batch simulation over records (rayon across records, GIL released) and a bank of play
//! operators over multi-channel signals (the regressors of the LFR's identification), and the
//! gradient of the simulation's squared output error (records in parallel) for output-error fits.
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use numpy::{PyArray1, PyReadonlyArray1};
use piezohyst_core::lfr::{play_bank as core_play_bank, Lfr};
use piezohyst_core::lfr_grad::{grad_len, loss_grad, work_len};

/// Records per batch of the gradient (stepped in lockstep; see `piezohyst_core::lfr_grad`).
const LANES: usize = 4;
use pyo3::prelude::*;
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use crate::util::use_avx2;
use crate::util::{bad_arg, check_alloc, check_finite, err, guarded, interruptible};

/// `(y, z, state)`: outputs, feedback signals and final states of the records.
/// `(outputs, final state)` of a play bank.
type BankOut<'py> = (Bound<'py, PyArray3<f64>>, Bound<'py, PyArray2<f64>>);

/// `(losses per record, flat gradient)` of [`lfr_loss_grad`].
type GradOut<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

type SimOut<'py> = (Bound<'py, PyArray3<f64>>, Bound<'py, PyArray3<f64>>, Bound<'py, PyArray2<f64>>);

fn mat<'a>(a: &'a PyReadonlyArray2<'_, f64>, name: &str, rows: usize, cols: usize) -> PyResult<&'a [f64]> {
    let s = a.shape();
    if s[0] != rows || s[1] != cols {
        return Err(bad_arg(format!("{name} has shape ({}, {}), expected ({rows}, {cols})", s[0], s[1])));
    }
    a.as_slice().map_err(|_| bad_arg(format!("{name} must be a C-contiguous float64 array")))
}

/// The LFR model of the ten matrices `[A, B, C, D, E, F, G, H, thresholds, weights]` (its
/// dimensions read from A, B, C, G and the thresholds; the last `nt` channels static), each
/// shape checked, validated.
fn lfr_model<'a>(m: [&'a PyReadonlyArray2<'_, f64>; 10], nt: usize) -> PyResult<Lfr<'a>> {
    let nx = m[0].shape()[0];
    let nu = m[1].shape()[1];
    let ny = m[2].shape()[0];
    let nw = m[6].shape()[0];
    let nr = m[8].shape()[1];
    Lfr {
        nx,
        nu,
        ny,
        nw,
        nr,
        a: mat(m[0], "A", nx, nx)?,
        b: mat(m[1], "B", nx, nu)?,
        c: mat(m[2], "C", ny, nx)?,
        d: mat(m[3], "D", ny, nu)?,
        e: mat(m[4], "E", nx, nw)?,
        f: mat(m[5], "F", ny, nw)?,
        g: mat(m[6], "G", nw, nx)?,
        h: mat(m[7], "H", nw, nu)?,
        thresholds: mat(m[8], "thresholds", nw, nr)?,
        weights: mat(m[9], "weights", nw, nr)?,
        nt,
        modal: false,
    }
    .validated()
    .map_err(err)
}

/// Simulate the LFR model on `R` records at once: `u` `(R, N, nu)`, `state` `(R, nx + nw*nr)`
/// → `(y (R, N, ny), z (R, N, nw), final state (R, nx + nw*nr))`. Matrices as in the core's
/// module docs; `thresholds`, `weights` `(nw, nr)`; the last `nt` channels static saturations.
/// A record whose state diverges raises.
#[pyfunction]
#[pyo3(signature = (a, b, c, d, e, f, g, h, thresholds, weights, u, state, nt = 0))]
#[allow(clippy::too_many_arguments)]
fn lfr_simulate<'py>(
    py: Python<'py>,
    a: PyReadonlyArray2<'py, f64>,
    b: PyReadonlyArray2<'py, f64>,
    c: PyReadonlyArray2<'py, f64>,
    d: PyReadonlyArray2<'py, f64>,
    e: PyReadonlyArray2<'py, f64>,
    f: PyReadonlyArray2<'py, f64>,
    g: PyReadonlyArray2<'py, f64>,
    h: PyReadonlyArray2<'py, f64>,
    thresholds: PyReadonlyArray2<'py, f64>,
    weights: PyReadonlyArray2<'py, f64>,
    u: PyReadonlyArray3<'py, f64>,
    state: PyReadonlyArray2<'py, f64>,
    nt: usize,
) -> PyResult<SimOut<'py>> {
    guarded(|| {
        let model = lfr_model([&a, &b, &c, &d, &e, &f, &g, &h, &thresholds, &weights], nt)?;
        let (nu, ny, nw) = (model.nu, model.ny, model.nw);
        let us = u.shape();
        let (r, n) = (us[0], us[1]);
        if us[2] != nu {
            return Err(bad_arg(format!("u has {} channels (shape[2]), the model has {nu} inputs", us[2])));
        }
        let ns = model.state_len();
        let s0 = mat(&state, "state", r, ns)?;
        let uu = u.as_slice().map_err(|_| bad_arg("u must be a C-contiguous float64 array".into()))?;
        check_finite("u", uu)?;
        check_finite("state", s0)?;
        check_alloc("lfr_simulate: the (R, N, ny + nw) result", &[r, n, ny + nw])?;
        // every buffer holds at least one value per record, so the records zip even when a
        // dimension is 0 (a linear model has no feedback channel)
        let (ly, lz, ls) = ((n * ny).max(1), (n * nw).max(1), ns.max(1));
        let mut y = vec![0.0; r * ly];
        let mut z = vec![0.0; r * lz];
        let mut st = vec![0.0; r * ls];
        for i in 0..r {
            st[i * ls..i * ls + ns].copy_from_slice(&s0[i * ns..(i + 1) * ns]);
        }
        let ok: Vec<bool> = interruptible(py, |stop| {
            y.par_chunks_mut(ly)
                .zip(z.par_chunks_mut(lz))
                .zip(st.par_chunks_mut(ls))
                .enumerate()
                .map(|(i, ((yi, zi), si))| {
                    let mut scratch = vec![0.0; model.scratch_len()];
                    let (yi, zi, si) = (&mut yi[..n * ny], &mut zi[..n * nw], &mut si[..ns]);
                    model.simulate(&uu[i * n * nu..(i + 1) * n * nu], si, &mut scratch, yi, zi, &|| stop.stopped())
                })
                .collect()
        })?;
        if let Some(i) = ok.iter().position(|o| !o) {
            return Err(bad_arg(format!("the simulation of record {i} diverged (its state is not finite)")));
        }
        let trim = |v: Vec<f64>, chunk: usize, len: usize| -> Vec<f64> {
            if chunk == len {
                v
            } else {
                (0..r).flat_map(|i| v[i * chunk..i * chunk + len].to_vec()).collect()
            }
        };
        let y = Array3::from_shape_vec((r, n, ny), trim(y, ly, n * ny)).expect("shape matches length");
        let z = Array3::from_shape_vec((r, n, nw), trim(z, lz, n * nw)).expect("shape matches length");
        let st = Array2::from_shape_vec((r, ns), trim(st, ls, ns)).expect("shape matches length");
        Ok((y.into_pyarray(py), z.into_pyarray(py), st.into_pyarray(py)))
    })
}

/// The weighted squared output error of `R` records and its gradient with respect to every
/// parameter (`piezohyst_core::lfr_grad`, reverse mode): `u` `(R, N, nu)`, `y` `(R, N, ny)`
/// the measured outputs, `state` `(R, nx + nw*nr)` the initial states, `skip` the samples
/// of each record whose error is not counted (a warm-up), `record_weights` `(R,)` →
/// `(losses (R,), gradient)`: the gradient of the summed loss, flat, in the order
/// `A, B, C, D, E, F, G, H, thresholds, weights` (each row-major). Records run in batches of
/// [`LANES`] stepped in lockstep (one or two left over in a narrower one), batches in
/// parallel; a batch in which a simulation diverges
/// has the loss `inf` for each of its records (and adds nothing to the gradient).
#[pyfunction]
#[pyo3(signature = (a, b, c, d, e, f, g, h, thresholds, weights, u, y, state, skip, record_weights, nt = 0))]
#[allow(clippy::too_many_arguments)]
fn lfr_loss_grad<'py>(
    py: Python<'py>,
    a: PyReadonlyArray2<'py, f64>,
    b: PyReadonlyArray2<'py, f64>,
    c: PyReadonlyArray2<'py, f64>,
    d: PyReadonlyArray2<'py, f64>,
    e: PyReadonlyArray2<'py, f64>,
    f: PyReadonlyArray2<'py, f64>,
    g: PyReadonlyArray2<'py, f64>,
    h: PyReadonlyArray2<'py, f64>,
    thresholds: PyReadonlyArray2<'py, f64>,
    weights: PyReadonlyArray2<'py, f64>,
    u: PyReadonlyArray3<'py, f64>,
    y: PyReadonlyArray3<'py, f64>,
    state: PyReadonlyArray2<'py, f64>,
    skip: usize,
    record_weights: PyReadonlyArray1<'py, f64>,
    nt: usize,
) -> PyResult<GradOut<'py>> {
    guarded(|| {
        let model = lfr_model([&a, &b, &c, &d, &e, &f, &g, &h, &thresholds, &weights], nt)?;
        let (nu, ny) = (model.nu, model.ny);
        let us = u.shape();
        let (r, n) = (us[0], us[1]);
        if us[2] != nu {
            return Err(bad_arg(format!("u has {} channels (shape[2]), the model has {nu} inputs", us[2])));
        }
        let ys = y.shape();
        if ys[0] != r || ys[1] != n || ys[2] != ny {
            return Err(bad_arg(format!(
                "y has shape ({}, {}, {}), expected ({r}, {n}, {ny}) (the records of u, the model's outputs)",
                ys[0], ys[1], ys[2]
            )));
        }
        if r == 0 || n == 0 {
            return Err(bad_arg(format!("u has shape ({r}, {n}, {nu}): no record or no sample")));
        }
        if skip >= n {
            return Err(bad_arg(format!("skip = {skip} leaves no sample of the {n} to score")));
        }
        let ns = model.state_len();
        let s0 = mat(&state, "state", r, ns)?;
        let rw = record_weights
            .as_slice()
            .map_err(|_| bad_arg("record_weights must be a contiguous float64 array".into()))?;
        if rw.len() != r {
            return Err(bad_arg(format!("record_weights has {} values, expected {r} (one per record)", rw.len())));
        }
        let uu = u.as_slice().map_err(|_| bad_arg("u must be a C-contiguous float64 array".into()))?;
        let yy = y.as_slice().map_err(|_| bad_arg("y must be a C-contiguous float64 array".into()))?;
        check_finite("u", uu)?;
        check_finite("y", yy)?;
        check_finite("state", s0)?;
        check_finite("record_weights", rw)?;
        if let Some(k) = rw.iter().position(|&v| v < 0.0) {
            return Err(bad_arg(format!("record_weights[{k}] = {} must be >= 0", rw[k])));
        }
        let wl = work_len(&model, n);
        check_alloc("lfr_loss_grad: the stored trajectories of two batches", &[2, LANES, wl])?;
        let gl = grad_len(&model);
        // batches of LANES records stepped in lockstep, the one or two left over in a narrower
        // batch, three left over padded with a record of weight 0. A batch's time grows with
        // its lanes, by less than their number, and three vectorize badly (FSM records, a model
        // of 120 states and 33 feedback channels, 9216 samples, one thread: 1 record 0.074 s,
        // 2 in lockstep 0.111, 3 0.214, 4 0.167); on two threads, in the same run, 9 records took 0.33 s
        // padded to 12, 0.24 as 4 + 4 + 1; 17 0.49 and 0.41; 18 0.49 and 0.44 (8 and 16: the same)
        let (full, left) = (r / LANES, r % LANES);
        let mut batches: Vec<(usize, usize)> = (0..full).map(|b| (b * LANES, LANES)).collect();
        if left > 0 {
            batches.push((full * LANES, left));
        }
        let records = Records { u: uu, y: yy, state: s0, n, skip, weights: rw };
        let parts: Vec<(Vec<f64>, Vec<f64>)> = interruptible(py, |stop| {
            batches
                .par_iter()
                .map(|&(start, len)| {
                    let mut grad = vec![0.0; gl];
                    let stop = || stop.stopped();
                    let loss = match len {
                        1 => batch_loss_grad::<1>(&model, &records, start, len, &mut grad, wl, &stop),
                        2 => batch_loss_grad::<2>(&model, &records, start, len, &mut grad, wl, &stop),
                        _ => batch_loss_grad::<LANES>(&model, &records, start, len, &mut grad, wl, &stop),
                    };
                    match loss {
                        Some(l) => (l, grad),
                        None => (vec![f64::INFINITY; len], Vec::new()),
                    }
                })
                .collect()
        })?;
        let mut total = vec![0.0; gl];
        let mut losses = Vec::with_capacity(r);
        for (l, gr) in parts {
            losses.extend(l);
            for (t, v) in total.iter_mut().zip(&gr) {
                *t += v;
            }
        }
        Ok((losses.into_pyarray(py), total.into_pyarray(py)))
    })
}

thread_local! {
    /// Each worker thread's work buffer of [`lfr_loss_grad`], kept between calls: a fresh
    /// one of the FSM records' size (76 MB) cost 15 % of a call in page faults. It holds
    /// the largest trajectory a thread has stored.
    static WORK: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// `f` on this thread's work buffer of at least `len` lane vectors of `L` lanes.
fn with_work<const L: usize, T>(len: usize, f: impl FnOnce(&mut [[f64; L]]) -> T) -> T {
    WORK.with(|w| {
        let mut w = w.borrow_mut();
        if w.len() < len * L {
            w.resize(len * L, 0.0);
        }
        f(&mut w.as_chunks_mut::<L>().0[..len])
    })
}

/// The records of one [`lfr_loss_grad`] call: `u` `(R, n, nu)`, `y` `(R, n, ny)`, `state`
/// `(R, state_len)` flat, the samples `skip`ped and the record `weights`.
struct Records<'a> {
    u: &'a [f64],
    y: &'a [f64],
    state: &'a [f64],
    n: usize,
    skip: usize,
    weights: &'a [f64],
}

/// The losses of records `start .. start + len` (the gradient of their sum added to `grad`),
/// stepped in lockstep in `L >= len` lanes (the others repeat the last record at weight 0:
/// they add nothing); `None` when one diverged or `stop` said so.
fn batch_loss_grad<const L: usize>(
    model: &Lfr<'_>,
    rec: &Records<'_>,
    start: usize,
    len: usize,
    grad: &mut [f64],
    work_len: usize,
    stop: &dyn Fn() -> bool,
) -> Option<Vec<f64>> {
    let (n, nu, ny, ns) = (rec.n, model.nu, model.ny, model.state_len());
    let idx: [usize; L] = core::array::from_fn(|l| start + l.min(len - 1));
    let batch: Batch<'_, L> = (
        idx.map(|i| &rec.u[i * n * nu..(i + 1) * n * nu]),
        idx.map(|i| &rec.y[i * n * ny..(i + 1) * n * ny]),
        idx.map(|i| &rec.state[i * ns..(i + 1) * ns]),
        rec.skip,
        core::array::from_fn(|l| if l < len { rec.weights[start + l] } else { 0.0 }),
    );
    with_work::<L, _>(work_len, |work| loss_grad_dispatch::<L>(model, batch, grad, work, stop))
        .map(|l| l[..len].to_vec())
}

/// One batch of [`loss_grad`].
type Batch<'a, const L: usize> = ([&'a [f64]; L], [&'a [f64]; L], [&'a [f64]; L], usize, [f64; L]);

/// [`loss_grad`] compiled for AVX2 (four lanes fill one register); the same IEEE operations
/// in the same order (never fused), so the same bits as the portable path.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn loss_grad_avx2<const L: usize>(
    m: &Lfr<'_>,
    (u, y, s0, skip, w): Batch<'_, L>,
    grad: &mut [f64],
    work: &mut [[f64; L]],
    stop: &dyn Fn() -> bool,
) -> Option<[f64; L]> {
    loss_grad(m, u, y, s0, skip, w, grad, work, stop)
}

fn loss_grad_dispatch<const L: usize>(
    m: &Lfr<'_>,
    batch: Batch<'_, L>,
    grad: &mut [f64],
    work: &mut [[f64; L]],
    stop: &dyn Fn() -> bool,
) -> Option<[f64; L]> {
    #[cfg(target_arch = "x86_64")]
    {
        if use_avx2() {
            // SAFETY: the CPU has AVX2
            return unsafe { loss_grad_avx2::<L>(m, batch, grad, work, stop) };
        }
    }
    let (u, y, s0, skip, w) = batch;
    loss_grad(m, u, y, s0, skip, w, grad, work, stop)
}

/// Play operators on every channel of `R` records: `x` `(R, N, m)`, `thresholds` `(m, nr)`,
/// `state` `(R, m*nr)` → `(outputs (R, N, m*nr), final state (R, m*nr))`.
#[pyfunction]
fn play_bank<'py>(
    py: Python<'py>,
    x: PyReadonlyArray3<'py, f64>,
    thresholds: PyReadonlyArray2<'py, f64>,
    state: PyReadonlyArray2<'py, f64>,
) -> PyResult<BankOut<'py>> {
    guarded(|| {
        let xs = x.shape();
        let (r, n, m) = (xs[0], xs[1], xs[2]);
        let nr = thresholds.shape()[1];
        let th = mat(&thresholds, "thresholds", m, nr)?;
        check_finite("thresholds", th)?;
        if let Some(k) = th.iter().position(|&v| v < 0.0) {
            return Err(bad_arg(format!("thresholds[{k}] = {} must be >= 0", th[k])));
        }
        let s0 = mat(&state, "state", r, m * nr)?;
        check_finite("state", s0)?;
        let xx = x.as_slice().map_err(|_| bad_arg("x must be a C-contiguous float64 array".into()))?;
        check_finite("x", xx)?;
        check_alloc("play_bank: the (R, N, m*nr) result", &[r, n, m * nr])?;
        let mut out = vec![0.0; r * n * m * nr];
        let mut st = s0.to_vec();
        if m * nr == 0 || n == 0 {
            let out = Array3::from_shape_vec((r, n, m * nr), out).expect("shape matches length");
            let st = Array2::from_shape_vec((r, m * nr), st).expect("shape matches length");
            return Ok((out.into_pyarray(py), st.into_pyarray(py)));
        }
        interruptible(py, |_stop| {
            out.par_chunks_mut((n * m * nr).max(1))
                .zip(st.par_chunks_mut((m * nr).max(1)))
                .enumerate()
                .for_each(|(i, (oi, si))| core_play_bank(&xx[i * n * m..(i + 1) * n * m], m, th, si, oi))
        })?;
        let out = Array3::from_shape_vec((r, n, m * nr), out).expect("shape matches length");
        let st = Array2::from_shape_vec((r, m * nr), st).expect("shape matches length");
        Ok((out.into_pyarray(py), st.into_pyarray(py)))
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(lfr_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(play_bank, m)?)?;
    m.add_function(wrap_pyfunction!(lfr_loss_grad, m)?)?;
    Ok(())
}
