//! A controller stepped on given inputs, without a plant: what a real-time loop (or the C
//! ABI, `crates/capi`) does with the same controller, so Python can produce the reference
//! outputs the C test replays (`make test-c`).
use crate::util::ParameterError;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadwriteArray1};
use pyo3::prelude::*;

use crate::control::{with_controller, ControllerSpec};
use crate::plant::{controller_spec, ControllerArg};
use crate::util::{check_alloc, check_finite, err, guarded, slice};

fn state_of<'a>(state: &'a mut PyReadwriteArray1<'_, f64>, want: usize) -> PyResult<&'a mut [f64]> {
    let s = state.as_slice_mut().map_err(|_| ParameterError::new_err("state must be a contiguous float64 array"))?;
    if s.len() != want {
        return Err(ParameterError::new_err(format!(
            "state has length {}, expected {want} for this controller",
            s.len()
        )));
    }
    Ok(s)
}

/// The state of the controller `spec` describes before its first step, given `y0`.
pub fn initial_state<'py>(py: Python<'py>, spec: &ControllerSpec, y0: f64) -> PyResult<Bound<'py, PyArray1<f64>>> {
    if !y0.is_finite() {
        return Err(ParameterError::new_err(format!("y0 = {y0} is not finite")));
    }
    let st = with_controller(spec, |c| {
        let mut st = vec![0.0; c.state_len()];
        c.reset(&mut st, y0);
        st
    })
    .map_err(ParameterError::new_err)?;
    Ok(st.into_pyarray(py))
}

/// The signals a controller is stepped on.
pub struct Signals<'py> {
    pub reference: PyReadonlyArray1<'py, f64>,
    pub velocity: PyReadonlyArray1<'py, f64>,
    pub acceleration: PyReadonlyArray1<'py, f64>,
    pub measured: PyReadonlyArray1<'py, f64>,
}

/// Step the controller `spec` describes from `state` (updated in place); the commands.
pub fn steps<'py>(
    py: Python<'py>,
    spec: &ControllerSpec,
    signals: Signals<'py>,
    mut state: PyReadwriteArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (r, v, a, y) = (
        slice(&signals.reference, "reference")?,
        slice(&signals.velocity, "velocity")?,
        slice(&signals.acceleration, "acceleration")?,
        slice(&signals.measured, "measured")?,
    );
    for (name, x) in [("reference", r), ("velocity", v), ("acceleration", a), ("measured", y)] {
        check_finite(name, x)?;
    }
    let n = r.len();
    if y.len() != n || (!v.is_empty() && v.len() != n) || (!a.is_empty() && a.len() != n) {
        return Err(ParameterError::new_err(format!(
            "measured must be as long as the reference and velocity/acceleration empty or as long, got reference {n}, \
             velocity {}, acceleration {}, measured {}",
            v.len(),
            a.len(),
            y.len()
        )));
    }
    check_alloc("controller_steps: the commands", &[n])?;
    let mut u = vec![0.0; n];
    let run = with_controller(spec, |c| -> PyResult<()> {
        let st = state_of(&mut state, c.state_len())?;
        c.check_state(st).map_err(err)?;
        let pick = |s: &[f64], k: usize| if s.is_empty() { 0.0 } else { s[k] };
        py.detach(|| {
            for k in 0..n {
                let rk = piezohyst_core::control::Reference { x: r[k], v: pick(v, k), a: pick(a, k) };
                u[k] = c.step(st, &rk, y[k]).u;
            }
        });
        Ok(())
    })
    .map_err(ParameterError::new_err)?;
    run?;
    Ok(u.into_pyarray(py))
}

/// The controller's state before its first step, given the first measurement `y0`.
#[pyfunction]
fn controller_initial_state<'py>(
    py: Python<'py>,
    controller: ControllerArg<'py>,
    y0: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        if !y0.is_finite() {
            return Err(ParameterError::new_err(format!("y0 = {y0} is not finite")));
        }
        initial_state(py, &controller_spec(&controller)?, y0)
    })
}

/// Step the controller from `state` (updated in place) on the reference `(reference,
/// velocity, acceleration)` and the `measured` positions; returns the commands. Empty
/// `velocity` / `acceleration` stand for zeros.
#[pyfunction]
fn controller_steps<'py>(
    py: Python<'py>,
    controller: ControllerArg<'py>,
    reference: PyReadonlyArray1<'py, f64>,
    velocity: PyReadonlyArray1<'py, f64>,
    acceleration: PyReadonlyArray1<'py, f64>,
    measured: PyReadonlyArray1<'py, f64>,
    state: PyReadwriteArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let spec = controller_spec(&controller)?;
        steps(py, &spec, Signals { reference, velocity, acceleration, measured }, state)
    })
}

/// Add this module's functions to the extension module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(controller_initial_state, m)?)?;
    m.add_function(wrap_pyfunction!(controller_steps, m)?)?;
    Ok(())
}
