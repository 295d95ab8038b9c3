//! Stage, sensor and closed-loop bindings. A stage is a flat parameter array (layout in
//! `piezohyst_core::stage::StageParams::from_slice`); a controller is a kind name and a
//! flat array. Batch runs release the GIL and put one scenario per rayon task.
use std::mem::MaybeUninit;

use crate::util::ParameterError;
use numpy::ndarray::Array2;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadwriteArray1, PyUntypedArrayMethods,
};
use piezohyst_core::closed_loop::{
    run_recorder_with, run_tracking, run_tracking_with, Loop, Recorder, Sample, Trajectory,
};
use piezohyst_core::control::{Controller as CoreController, Pid, MAX_TERMS};
use piezohyst_core::layout::Law;
use piezohyst_core::sensor::Sensor;
use piezohyst_core::spec::Family;
use piezohyst_core::stage::{Extra, NoExtra, Stage as CoreStage, StageParams, StageState};
use piezohyst_core::structure::{Drift, Mode, Structure, MAX_MODES};
use pyo3::prelude::*;

use crate::control::{with_controller, ControllerSpec};
use crate::models::Model;
#[cfg(target_arch = "x86_64")]
use crate::util::use_avx2;
use crate::util::{check_alloc, check_finite, err, guarded, interruptible, slice};
use pyo3::types::{PyDict, PyTuple};
use rayon::prelude::*;

fn stage(params: &[f64], ts: f64, substeps: usize, tolerance: f64) -> PyResult<CoreStage> {
    let p = StageParams::from_slice(params).map_err(err)?;
    CoreStage::new(p, ts, substeps, tolerance).map_err(err)
}

type Positions<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

fn simulate_stage<'py>(
    py: Python<'py>,
    st: &CoreStage,
    structure: Option<&StructureSpec>,
    command: &PyReadonlyArray1<'py, f64>,
    state: &mut PyReadwriteArray1<'py, f64>,
) -> PyResult<Positions<'py>> {
    let u = slice(command, "command")?;
    check_finite("command", u)?;
    let s = state.as_slice_mut().map_err(|_| ParameterError::new_err("state must be a contiguous float64 array"))?;
    let n = u.len();
    check_alloc("stage simulate: the three output records", &[3, n])?;
    let (mut x, mut va, mut vh) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    fn run<E: Extra>(st: &CoreStage, ss: &mut StageState, u: &[f64], out: [&mut [f64]; 3], e: &mut E) {
        let [x, va, vh] = out;
        for k in 0..u.len() {
            x[k] = e.position(ss.x);
            st.advance_with(ss, u[k], e);
            va[k] = ss.va;
            vh[k] = ss.vh;
        }
    }
    match structure {
        None => {
            let mut ss = StageState::from_array(s).map_err(err)?;
            py.detach(|| run(st, &mut ss, u, [&mut x, &mut va, &mut vh], &mut NoExtra));
            s.copy_from_slice(&ss.to_array());
        }
        Some(spec) => spec.with(st, |structure| -> PyResult<()> {
            let (mut ss, mut extra) = structured_state(structure, s)?;
            py.detach(|| run(st, &mut ss, u, [&mut x, &mut va, &mut vh], &mut structure.run(&mut extra)));
            s[..StageState::LEN].copy_from_slice(&ss.to_array());
            s[StageState::LEN..].copy_from_slice(&extra);
            Ok(())
        })??,
    }
    if let Some(k) = x.iter().position(|v| !v.is_finite()) {
        return Err(ParameterError::new_err(format!("the stage simulation diverged at sample {k}")));
    }
    Ok((x.into_pyarray(py), va.into_pyarray(py), vh.into_pyarray(py)))
}

/// Simulate the stage open loop under a held voltage command per period; `state` (12
/// values `[va, x, v, vh, creep[8]]`) is updated in place. Returns `(position at the start
/// of each period, amplifier voltage at the end, CEMF voltage at the end)`.
#[pyfunction]
fn stage_simulate<'py>(
    py: Python<'py>,
    params: PyReadonlyArray1<'py, f64>,
    ts: f64,
    substeps: usize,
    tolerance: f64,
    command: PyReadonlyArray1<'py, f64>,
    mut state: PyReadwriteArray1<'py, f64>,
) -> PyResult<Positions<'py>> {
    guarded(|| {
        let st = stage(slice(&params, "params")?, ts, substeps, tolerance)?;
        simulate_stage(py, &st, None, &command, &mut state)
    })
}

/// The tuple form of a controller: `(kind, params, inverse, ilc)` with `inverse` either
/// `None` or `(family, dims, row, u_min, u_max)` and `ilc` either `None` or `(period, gain,
/// forgetting, lead, delay)`.
pub type ControllerTuple<'py> = (
    String,
    PyReadonlyArray1<'py, f64>,
    Option<(String, Vec<usize>, PyReadonlyArray1<'py, f64>, f64, f64)>,
    Option<(usize, f64, f64, usize, usize)>,
);

/// A controller as Python passes it: a [`Controller`] object or the tuple form.
#[derive(FromPyObject)]
pub enum ControllerArg<'py> {
    /// A validated `_core.Controller`.
    Typed(Bound<'py, Controller>),
    /// `(kind, params, inverse, ilc)`.
    Tuple(ControllerTuple<'py>),
}

/// Validate a controller argument into an owned spec (built once to check it).
pub(crate) fn controller_spec(arg: &ControllerArg<'_>) -> PyResult<ControllerSpec> {
    let (kind, params, inverse, ilc) = match arg {
        ControllerArg::Typed(c) => return Ok(c.get().spec.clone()),
        ControllerArg::Tuple(t) => t,
    };
    let inverse = match inverse {
        None => None,
        Some((name, dims, row, lo, hi)) => {
            let family = crate::models::family(name, dims.clone())?;
            let row = slice(row, "inverse row")?.to_vec();
            check_finite("inverse row", &row)?;
            Some((family, row, [*lo, *hi]))
        }
    };
    let params = slice(params, "controller_params")?.to_vec();
    checked_spec(ControllerSpec { kind: kind.clone(), params, inverse, ilc: *ilc })
}

fn checked_spec(spec: ControllerSpec) -> PyResult<ControllerSpec> {
    with_controller(&spec, |_| ()).map_err(ParameterError::new_err)?;
    Ok(spec)
}

/// A controller validated once: kind and flat parameters (layout: `controller_layout`),
/// optionally behind the exact inverse of a model (`inverse = (model, u_min, u_max)`)
/// and/or with learning (`ilc = (period, gain, forgetting, lead, delay)`).
#[pyclass(frozen, module = "piezohyst._core")]
#[derive(Debug)]
pub struct Controller {
    pub(crate) spec: ControllerSpec,
    state_len: usize,
}

#[pymethods]
impl Controller {
    #[new]
    #[pyo3(signature = (kind, params, inverse=None, ilc=None))]
    fn new(
        kind: String,
        params: PyReadonlyArray1<'_, f64>,
        inverse: Option<(Bound<'_, Model>, f64, f64)>,
        ilc: Option<(usize, f64, f64, usize, usize)>,
    ) -> PyResult<Self> {
        let params = slice(&params, "controller_params")?.to_vec();
        check_finite("controller_params", &params)?;
        let inverse = inverse.map(|(m, lo, hi)| {
            let m = m.get();
            (m.fam, m.params.clone(), [lo, hi])
        });
        let spec = checked_spec(ControllerSpec { kind, params, inverse, ilc })?;
        let state_len = with_controller(&spec, |c| c.state_len()).map_err(ParameterError::new_err)?;
        Ok(Controller { spec, state_len })
    }
    /// Kind name.
    #[getter]
    fn kind(&self) -> &str {
        &self.spec.kind
    }
    /// The flat parameters (a copy).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.spec.params.clone().into_pyarray(py)
    }
    /// Length of a state.
    #[getter]
    fn state_len(&self) -> usize {
        self.state_len
    }
    /// The parameter layout (as `controller_layout`).
    #[getter]
    fn layout<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        crate::layout::controller_dict(py, &self.spec.kind)
    }
    /// The state before the first step, given the first measurement `y0`.
    fn initial_state<'py>(&self, py: Python<'py>, y0: f64) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guarded(|| crate::steps::initial_state(py, &self.spec, y0))
    }
    /// Step from `state` (updated in place) on the reference and the measured positions;
    /// returns the commands (empty velocity / acceleration stand for zeros).
    fn steps<'py>(
        &self,
        py: Python<'py>,
        reference: PyReadonlyArray1<'py, f64>,
        velocity: PyReadonlyArray1<'py, f64>,
        acceleration: PyReadonlyArray1<'py, f64>,
        measured: PyReadonlyArray1<'py, f64>,
        state: PyReadwriteArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        guarded(|| {
            let signals = crate::steps::Signals { reference, velocity, acceleration, measured };
            crate::steps::steps(py, &self.spec, signals, state)
        })
    }
    fn __repr__(&self) -> String {
        format!("Controller({:?}, <{} params>)", self.spec.kind, self.spec.params.len())
    }
}

/// One closed-loop scenario: a controller, the reference (position, velocity and
/// acceleration; empty derivatives stand for zeros) and the sensor noise seed.
#[pyclass(frozen, module = "piezohyst._core")]
#[derive(Debug)]
pub struct Scenario {
    controller: ControllerSpec,
    reference: Vec<f64>,
    velocity: Vec<f64>,
    acceleration: Vec<f64>,
    seed: u64,
}

#[pymethods]
impl Scenario {
    #[new]
    #[pyo3(signature = (controller, reference, velocity=None, acceleration=None, seed=0))]
    fn new(
        controller: ControllerArg<'_>,
        reference: PyReadonlyArray1<'_, f64>,
        velocity: Option<PyReadonlyArray1<'_, f64>>,
        acceleration: Option<PyReadonlyArray1<'_, f64>>,
        seed: u64,
    ) -> PyResult<Self> {
        let controller = controller_spec(&controller)?;
        let empty = |a: Option<PyReadonlyArray1<'_, f64>>, name: &str| -> PyResult<Vec<f64>> {
            a.map_or(Ok(Vec::new()), |a| Ok(slice(&a, name)?.to_vec()))
        };
        let reference = slice(&reference, "reference")?.to_vec();
        let (velocity, acceleration) = (empty(velocity, "velocity")?, empty(acceleration, "acceleration")?);
        check_scenario(&reference, &velocity, &acceleration)?;
        Ok(Scenario { controller, reference, velocity, acceleration, seed })
    }
    /// Number of samples.
    fn __len__(&self) -> usize {
        self.reference.len()
    }
    /// Sensor noise seed.
    #[getter]
    fn seed(&self) -> u64 {
        self.seed
    }
}

/// A scenario as Python passes it: a [`Scenario`] or `(controller, reference, velocity,
/// acceleration, seed)`.
#[derive(FromPyObject)]
pub enum ScenarioArg<'py> {
    /// A validated `_core.Scenario`.
    Typed(Bound<'py, Scenario>),
    /// The tuple form.
    Tuple(
        (ControllerArg<'py>, PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>, u64),
    ),
}

/// The runs of `scenarios` (validated; errors name the scenario).
fn runs<'a>(py: Python<'_>, scenarios: &'a [ScenarioArg<'_>]) -> PyResult<Vec<Run<'a>>> {
    let mut list = Vec::with_capacity(scenarios.len());
    for (j, sc) in scenarios.iter().enumerate() {
        let prefix = |e: PyErr| ParameterError::new_err(format!("scenarios[{j}]: {}", e.value(py)));
        list.push(match sc {
            ScenarioArg::Typed(s) => {
                let s = s.get();
                Run {
                    reference: &s.reference,
                    velocity: &s.velocity,
                    acceleration: &s.acceleration,
                    seed: s.seed,
                    controller: s.controller.clone(),
                }
            }
            ScenarioArg::Tuple((cp, r, v, a, seed)) => {
                let c = controller_spec(cp).map_err(prefix)?;
                let (r, v, a) = scenario_arrays(r, v, a).map_err(prefix)?;
                Run { reference: r, velocity: v, acceleration: a, seed: *seed, controller: c }
            }
        });
    }
    Ok(list)
}

/// A stage's structure (`piezohyst_core::structure`) as the binding keeps it: added modes,
/// a voltage-driven hysteresis law (family and row), a DAC step. Built into the core's
/// [`Structure`] for each run (the law borrows its row there).
#[derive(Debug, Clone)]
pub(crate) struct StructureSpec {
    modes: Vec<Mode>,
    law: Option<(Family, Vec<f64>)>,
    dac_step: f64,
    drift: Option<Drift>,
}

impl StructureSpec {
    /// Build the core structure for `stage` and hand it to `f`.
    fn with<R>(
        &self,
        stage: &CoreStage,
        f: impl FnOnce(&Structure<piezohyst_core::spec::Model<'_>>) -> R,
    ) -> PyResult<R> {
        let mut scratch = vec![0.0; self.law.as_ref().map_or(0, |(fam, _)| fam.scratch_len())];
        let law = match &self.law {
            None => None,
            Some((fam, row)) => {
                Some(fam.build(row, &mut scratch).map_err(|e| ParameterError::new_err(format!("hysteresis: {e}")))?)
            }
        };
        let s = Structure::new(stage, &self.modes, law, self.dac_step).map_err(err)?.with_drift(self.drift);
        Ok(f(&s))
    }
}

/// Split a structured stage's state (`[va, x, v, vh, creep[8]]` then the structure's
/// slots; the stage part alone starts the structure at rest) and check it.
fn structured_state<H: piezohyst_core::Invertible>(s: &Structure<H>, a: &[f64]) -> PyResult<(StageState, Vec<f64>)> {
    let n = StageState::LEN;
    let want = n + s.state_len();
    if a.len() != n && a.len() != want {
        return Err(ParameterError::new_err(format!(
            "state has {} values; this stage's state has {want} (the stage's {n}, then its structure's {})",
            a.len(),
            s.state_len()
        )));
    }
    let ss = StageState::from_array(&a[..n]).map_err(err)?;
    let mut extra = vec![0.0; s.state_len()];
    if a.len() == n {
        s.reset(&mut extra, ss.x);
    } else {
        extra.copy_from_slice(&a[n..]);
        s.check_state(&extra).map_err(|e| ParameterError::new_err(format!("state (structure): {e}")))?;
    }
    Ok((ss, extra))
}

/// A stage with its sensor, built once: the stage parameters (`STAGE_PARAM_LEN` values),
/// the control period `ts`, the integration settings and the sensor; optionally a structure
/// (added modes, a voltage-driven hysteresis law, a DAC).
#[pyclass(frozen, module = "piezohyst._core")]
#[derive(Debug)]
pub struct Stage {
    stage: CoreStage,
    sensor: Sensor,
    params: Vec<f64>,
    ts: f64,
    structure: Option<StructureSpec>,
}

#[pymethods]
impl Stage {
    #[new]
    #[pyo3(signature = (
        params, ts, substeps, tolerance, sensor_quantization=0.0, sensor_noise=0.0, sensor_delay=0, *,
        modes=None, hysteresis=None, dac_step=0.0, drift=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        params: PyReadonlyArray1<'_, f64>,
        ts: f64,
        substeps: usize,
        tolerance: f64,
        sensor_quantization: f64,
        sensor_noise: f64,
        sensor_delay: usize,
        modes: Option<Vec<(f64, f64, f64)>>,
        hysteresis: Option<(String, Vec<usize>, PyReadonlyArray1<'_, f64>)>,
        dac_step: f64,
        drift: Option<(f64, f64, f64)>,
    ) -> PyResult<Self> {
        let params = slice(&params, "stage_params")?.to_vec();
        let stage = stage(&params, ts, substeps, tolerance)?;
        let sensor = sensor(sensor_quantization, sensor_noise, sensor_delay)?;
        let modes: Vec<Mode> = modes
            .unwrap_or_default()
            .into_iter()
            .map(|(frequency, damping_ratio, gain)| Mode { frequency, damping_ratio, gain })
            .collect();
        if modes.len() > MAX_MODES {
            return Err(ParameterError::new_err(format!("modes has {} modes, at most {MAX_MODES}", modes.len())));
        }
        let law = match hysteresis {
            None => None,
            Some((name, dims, row)) => {
                let fam = crate::models::family(&name, dims)?;
                let row = slice(&row, "hysteresis row")?.to_vec();
                check_finite("hysteresis row", &row)?;
                Some((fam, row))
            }
        };
        let drift = match drift {
            None => None,
            Some((offset, gain, tau)) => Some(Drift::new(offset, gain, tau).map_err(err)?),
        };
        let structure = if modes.is_empty() && law.is_none() && dac_step == 0.0 && drift.is_none() {
            None
        } else {
            let spec = StructureSpec { modes, law, dac_step, drift };
            spec.with(&stage, |_| ())?; // validate once
            Some(spec)
        };
        Ok(Stage { stage, sensor, params, ts, structure })
    }
    /// Slots of this stage's state: the stage's `STAGE_STATE_LEN`, then its structure's.
    #[getter]
    fn state_len(&self) -> PyResult<usize> {
        match &self.structure {
            None => Ok(StageState::LEN),
            Some(spec) => spec.with(&self.stage, |s| StageState::LEN + s.state_len()),
        }
    }
    /// The state at rest: zeros, then the structure at rest (modes still, the law relaxed).
    fn rest_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mut st = StageState::ZERO.to_array().to_vec();
        if let Some(spec) = &self.structure {
            let extra = spec.with(&self.stage, |s| {
                let mut e = vec![0.0; s.state_len()];
                s.reset(&mut e, 0.0);
                e
            })?;
            st.extend(extra);
        }
        Ok(st.into_pyarray(py))
    }
    /// Whether the stage has a structure (modes, a voltage-driven law, a DAC).
    #[getter]
    fn structured(&self) -> bool {
        self.structure.is_some()
    }
    /// The stage parameters (a copy).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.params.clone().into_pyarray(py)
    }
    /// Control period, s.
    #[getter]
    fn ts(&self) -> f64 {
        self.ts
    }
    /// Open loop under a held command per period (as `stage_simulate`).
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        command: PyReadonlyArray1<'py, f64>,
        mut state: PyReadwriteArray1<'py, f64>,
    ) -> PyResult<Positions<'py>> {
        guarded(|| simulate_stage(py, &self.stage, self.structure.as_ref(), &command, &mut state))
    }
    /// One closed loop (as `closed_loop`).
    fn closed_loop<'py>(
        &self,
        py: Python<'py>,
        scenario: ScenarioArg<'py>,
        initial_state: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(|| {
            let init = self.initial(&initial_state)?;
            let scenarios = [scenario];
            let sc = runs(py, &scenarios).map_err(|e| ParameterError::new_err(strip_prefix(py, e)))?;
            let sig = self.with_plant(|plant| py.detach(|| plant.run(&sc[0], &init)))?;
            if let Some(k) = sig.diverged_at {
                return Err(ParameterError::new_err(format!("the closed loop diverged at sample {k}")));
            }
            signals_dict(py, sig)
        })
    }
    /// Many closed loops in parallel (as `closed_loop_batch`).
    fn closed_loop_batch<'py>(
        &self,
        py: Python<'py>,
        scenarios: Vec<ScenarioArg<'py>>,
        initial_state: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Vec<Bound<'py, PyDict>>> {
        guarded(|| {
            let init = self.initial(&initial_state)?;
            self.with_plant(|plant| batch(py, plant, &scenarios, &init))?
        })
    }
    /// Tracking figures of many closed loops (as `closed_loop_batch_tracking`).
    fn closed_loop_batch_tracking<'py>(
        &self,
        py: Python<'py>,
        scenarios: Vec<ScenarioArg<'py>>,
        initial_state: PyReadonlyArray1<'py, f64>,
        skip: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guarded(|| {
            let init = self.initial(&initial_state)?;
            self.with_plant(|plant| tracking(py, plant, &scenarios, &init, skip))?
        })
    }
    /// Tracking figures of one scenario on many stages: row `j` of `params` (`(S,
    /// STAGE_PARAM_LEN)`, this stage's layout) replaces this stage's parameters (same control
    /// period, integration settings and sensor) and `seeds[j]` the scenario's noise seed. An
    /// `(S, 3)` array as `closed_loop_batch_tracking` (GIL released, rayon across rows; each
    /// row's figures are the same whatever the number of threads). The engine of Monte-Carlo
    /// robustness over part-to-part variation.
    fn closed_loop_batch_stages<'py>(
        &self,
        py: Python<'py>,
        params: PyReadonlyArray2<'py, f64>,
        scenario: ScenarioArg<'py>,
        seeds: PyReadonlyArray1<'py, u64>,
        initial_state: PyReadonlyArray1<'py, f64>,
        skip: usize,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        guarded(|| {
            if self.structure.is_some() {
                return Err(ParameterError::new_err(
                    "closed_loop_batch_stages runs the stage's own kernel on each row: a stage with added modes or \
                     another hysteresis (Stage.with_modes / with_hysteresis) is not supported here",
                ));
            }
            let init = StageState::from_array(slice(&initial_state, "initial_state")?).map_err(err)?;
            let scenarios = [scenario];
            let sc = runs(py, &scenarios).map_err(|e| ParameterError::new_err(strip_prefix(py, e)))?;
            let rows = stage_rows(&self.stage, &params)?;
            let seeds =
                seeds.as_slice().map_err(|_| ParameterError::new_err("seeds must be a contiguous uint64 array"))?;
            if seeds.len() != rows.len() {
                return Err(ParameterError::new_err(format!(
                    "seeds has length {}, params has {} rows; one seed per row",
                    seeds.len(),
                    rows.len()
                )));
            }
            stages_tracking(py, &rows, &self.sensor, &sc[0], seeds, init, skip)
        })
    }

    /// One closed loop with a controller written in Python: `step(reference, velocity,
    /// acceleration, measured) -> command` is called once per sample (the loop is Rust's; each
    /// call holds the GIL, so this path is slow: ~1 us of Python per sample). Returns a dict
    /// as `closed_loop` (no terms). An exception in `step` stops the run and is raised, with
    /// the sample; a command that is not a finite number raises `ParameterError`.
    #[pyo3(signature = (step, reference, velocity, acceleration, seed, initial_state))]
    #[allow(clippy::too_many_arguments)]
    fn closed_loop_python<'py>(
        &self,
        py: Python<'py>,
        step: Bound<'py, PyAny>,
        reference: PyReadonlyArray1<'py, f64>,
        velocity: PyReadonlyArray1<'py, f64>,
        acceleration: PyReadonlyArray1<'py, f64>,
        seed: u64,
        initial_state: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(|| {
            let init = self.initial(&initial_state)?;
            let (r, v, a) = scenario_arrays(&reference, &velocity, &acceleration)?;
            let sig = self.with_plant(|plant| plant.run_python(py, &step, r, v, a, seed, &init))??;
            if let Some(k) = sig.diverged_at {
                return Err(ParameterError::new_err(format!("the closed loop diverged at sample {k}")));
            }
            signals_dict(py, sig)
        })
    }
}

/// The stages of the rows of `params` (`(S, STAGE_PARAM_LEN)`, C order) with `base`'s control
/// period and integration settings; an invalid row raises, naming it.
fn stage_rows(base: &CoreStage, params: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<CoreStage>> {
    let shape = params.shape();
    let width = piezohyst_core::stage::PARAM_LEN;
    if shape[1] != width {
        return Err(ParameterError::new_err(format!(
            "params has shape ({}, {}), expected (S, {width})",
            shape[0], shape[1]
        )));
    }
    if !params.is_c_contiguous() {
        return Err(ParameterError::new_err("params must be a C-contiguous float64 array"));
    }
    let p = params.as_slice().map_err(|_| ParameterError::new_err("params must be a C-contiguous float64 array"))?;
    let py = params.py();
    let mut stages = Vec::with_capacity(shape[0]);
    for j in 0..shape[0] {
        let row = &p[j * width..(j + 1) * width];
        check_finite_fast(&format!("params[{j}]"), row)?;
        let st = stage(row, base.ts, base.substeps, base.tolerance)
            .map_err(|e| ParameterError::new_err(format!("params[{j}]: {}", e.value(py))))?;
        stages.push(st);
    }
    Ok(stages)
}

/// `[rmse, max_error, saturated_fraction]` of `sc` on each stage (rayon across stages).
fn stages_tracking<'py>(
    py: Python<'py>,
    stages: &[CoreStage],
    se: &Sensor,
    sc: &Run<'_>,
    seeds: &[u64],
    init: StageState,
    skip: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    if skip >= sc.reference.len() {
        return Err(ParameterError::new_err(format!(
            "skip = {skip} leaves nothing of the reference's {} samples",
            sc.reference.len()
        )));
    }
    let rows: Vec<[f64; 3]> = interruptible(py, |stop| {
        stages
            .par_iter()
            .zip(seeds.par_iter())
            .map(|(st, &seed)| {
                if stop.stopped() {
                    return [f64::NAN; 3];
                }
                with_controller(&sc.controller, |c| {
                    let mut ss = init;
                    let mut sst = se.state(ss.x, seed);
                    let mut cst = vec![0.0; c.state_len()];
                    c.reset(&mut cst, ss.x);
                    let t = run_tracking(
                        Loop {
                            stage: st,
                            stage_state: &mut ss,
                            sensor: se,
                            sensor_state: &mut sst,
                            controller: c,
                            controller_state: &mut cst,
                        },
                        Trajectory { position: sc.reference, velocity: sc.velocity, acceleration: sc.acceleration },
                        skip,
                    );
                    let n = t.samples.max(1) as f64;
                    [(t.sse / n).sqrt(), t.max_error, t.saturated as f64 / sc.reference.len() as f64]
                })
                .expect("validated before the run")
            })
            .collect()
    })?;
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Ok(Array2::from_shape_vec((rows.len(), 3), flat).expect("shape").into_pyarray(py))
}

impl Stage {
    /// A run's initial state: the stage's 12 values, optionally followed by the structure's.
    fn initial(&self, a: &PyReadonlyArray1<'_, f64>) -> PyResult<Vec<f64>> {
        let a = slice(a, "initial_state")?;
        match &self.structure {
            None => Ok(StageState::from_array(a).map_err(err)?.to_array().to_vec()),
            Some(spec) => spec.with(&self.stage, |s| {
                let (ss, extra) = structured_state(s, a)?;
                let mut v = ss.to_array().to_vec();
                v.extend(extra);
                Ok(v)
            })?,
        }
    }
    /// Control period, s (for the multi-axis plant).
    pub(crate) fn ts_value(&self) -> f64 {
        self.ts
    }
    /// The sensor (for the multi-axis plant).
    pub(crate) fn sensor_ref(&self) -> &Sensor {
        &self.sensor
    }
    /// The stage, its sensor and its structure (built) as one [`Plant`] for `f`.
    pub(crate) fn with_plant<R>(&self, f: impl FnOnce(&Plant<'_>) -> R) -> PyResult<R> {
        match &self.structure {
            None => Ok(f(&Plant { stage: &self.stage, sensor: &self.sensor, structure: None })),
            Some(spec) => {
                spec.with(&self.stage, |s| f(&Plant { stage: &self.stage, sensor: &self.sensor, structure: Some(s) }))
            }
        }
    }
}

/// What a run needs of a stage: the kernel, the sensor and the structure (if any).
#[derive(Clone, Copy)]
pub(crate) struct Plant<'a> {
    pub(crate) stage: &'a CoreStage,
    sensor: &'a Sensor,
    pub(crate) structure: Option<&'a Structure<piezohyst_core::spec::Model<'a>>>,
}

impl Plant<'_> {
    /// Split an initial state (already checked by `Stage::initial`) into the stage's and the
    /// structure's.
    fn split(init: &[f64]) -> (StageState, Vec<f64>) {
        (StageState::from_array(&init[..StageState::LEN]).expect("checked"), init[StageState::LEN..].to_vec())
    }

    /// One recorded run of a scenario.
    fn run(&self, sc: &Run<'_>, init: &[f64]) -> Signals {
        let (ss, mut extra) = Self::split(init);
        match self.structure {
            None => run_scenario(self.stage, self.sensor, sc, ss, &mut NoExtra),
            Some(s) => {
                let mut sig = run_scenario(self.stage, self.sensor, sc, ss, &mut s.run(&mut extra));
                sig.extra_state = extra;
                sig
            }
        }
    }

    /// Tracking figures of one scenario.
    fn tracking(&self, sc: &Run<'_>, init: &[f64], skip: usize) -> [f64; 3] {
        let (ss, mut extra) = Self::split(init);
        match self.structure {
            None => tracking_run(self.stage, self.sensor, sc, ss, skip, &mut NoExtra),
            Some(s) => tracking_run(self.stage, self.sensor, sc, ss, skip, &mut s.run(&mut extra)),
        }
    }

    /// One recorded run with a Python controller (`step(r, v, a, y) -> u` per sample).
    #[allow(clippy::too_many_arguments)]
    fn run_python(
        &self,
        py: Python<'_>,
        step: &Bound<'_, PyAny>,
        r: &[f64],
        v: &[f64],
        a: &[f64],
        seed: u64,
        init: &[f64],
    ) -> PyResult<Signals> {
        let (ss, mut extra) = Self::split(init);
        let mut sig = match self.structure {
            None => python_run(py, self.stage, self.sensor, step, (r, v, a), seed, ss, &mut NoExtra)?,
            Some(s) => python_run(py, self.stage, self.sensor, step, (r, v, a), seed, ss, &mut s.run(&mut extra))?,
        };
        if self.structure.is_some() {
            sig.extra_state = extra;
        }
        Ok(sig)
    }
}

/// The loop of `closed_loop_python`: sensor, the Python `step`, stage; per sample.
#[allow(clippy::too_many_arguments)]
fn python_run<E: Extra>(
    py: Python<'_>,
    stage: &CoreStage,
    sensor: &Sensor,
    step: &Bound<'_, PyAny>,
    (r, v, a): (&[f64], &[f64], &[f64]),
    seed: u64,
    init: StageState,
    e: &mut E,
) -> PyResult<Signals> {
    let n = r.len();
    check_alloc("closed_loop_python: the recorded signals", &[n, 5])?;
    let mut st = init;
    let mut sst = sensor.state(e.position(st.x), seed);
    let (mut command, mut voltage, mut position, mut measured) =
        (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        let x = e.position(st.x);
        let y = sensor.read(&mut sst, x);
        let vk = if v.is_empty() { 0.0 } else { v[k] };
        let ak = if a.is_empty() { 0.0 } else { a[k] };
        let out = step.call1((r[k], vk, ak, y)).map_err(|err| {
            let msg = format!("the controller's step raised at sample {k}");
            let new = pyo3::exceptions::PyRuntimeError::new_err(msg);
            new.set_cause(py, Some(err));
            new
        })?;
        let u: f64 = out.extract().map_err(|_| {
            ParameterError::new_err(format!(
                "the controller's step returned {} at sample {k}; it must return a number (the command, V)",
                out.repr().map(|s| s.to_string()).unwrap_or_else(|_| "an object".into())
            ))
        })?;
        if !u.is_finite() {
            return Err(ParameterError::new_err(format!(
                "the controller's step returned {u} at sample {k}; the command must be finite"
            )));
        }
        stage.advance_with(&mut st, u, e);
        command.push(u);
        voltage.push(st.va);
        position.push(x);
        measured.push(y);
    }
    let diverged_at = position.iter().position(|x: &f64| !x.is_finite());
    Ok(Signals {
        reference: r.to_vec(),
        command,
        voltage,
        position,
        measured,
        terms: Vec::new(),
        final_state: st,
        term_names: &[],
        diverged_at,
        extra_state: Vec::new(),
    })
}

/// The message of a `scenarios[0]: ...` error without its prefix (a single run).
fn strip_prefix(py: Python<'_>, e: PyErr) -> String {
    let msg = e.value(py).to_string();
    msg.strip_prefix("scenarios[0]: ").map(str::to_string).unwrap_or(msg)
}

/// One scenario's inputs, borrowed for a run.
struct Run<'a> {
    reference: &'a [f64],
    velocity: &'a [f64],
    acceleration: &'a [f64],
    seed: u64,
    controller: ControllerSpec,
}

/// One scenario's signals.
struct Signals {
    reference: Vec<f64>,
    command: Vec<f64>,
    voltage: Vec<f64>,
    position: Vec<f64>,
    measured: Vec<f64>,
    terms: Vec<f64>,
    final_state: StageState,
    term_names: &'static [&'static str],
    /// First sample whose true position is not finite (the run diverged there).
    diverged_at: Option<usize>,
    /// The structure's state at the end (empty for a plain stage).
    extra_state: Vec<f64>,
}

/// Writes a run's samples straight into the result vectors' spare capacity: no zero-filled
/// buffers to allocate first, no copy of the reference afterwards.
struct Out<'a> {
    reference: &'a mut [MaybeUninit<f64>],
    command: &'a mut [MaybeUninit<f64>],
    voltage: &'a mut [MaybeUninit<f64>],
    position: &'a mut [MaybeUninit<f64>],
    measured: &'a mut [MaybeUninit<f64>],
    /// `len * width + MAX_TERMS` slots: row `k` writes all `MAX_TERMS` terms at `k * width`
    /// (a fixed-size copy); the next row overwrites the tail.
    terms: &'a mut [MaybeUninit<f64>],
    width: usize,
}

impl Recorder for Out<'_> {
    #[inline(always)]
    fn capacity(&self) -> usize {
        self.command.len()
    }
    #[inline(always)]
    fn record(&mut self, k: usize, s: &Sample<'_>) {
        debug_assert!(k < self.command.len());
        // SAFETY: run_recorder calls record only for k < capacity() (the Recorder
        // contract), and every slice holds capacity() samples (terms: capacity() rows of
        // `width` plus MAX_TERMS slots), so no index below is out of bounds.
        unsafe {
            self.reference.get_unchecked_mut(k).write(s.reference);
            self.command.get_unchecked_mut(k).write(s.command);
            self.voltage.get_unchecked_mut(k).write(s.voltage);
            self.position.get_unchecked_mut(k).write(s.position);
            self.measured.get_unchecked_mut(k).write(s.measured);
            let row = self.terms.get_unchecked_mut(k * self.width..k * self.width + MAX_TERMS);
            for (slot, &t) in row.iter_mut().zip(s.terms) {
                slot.write(t);
            }
        }
    }
}

#[inline(always)]
fn record_run<C: CoreController + ?Sized, E: Extra>(
    stage: &CoreStage,
    sensor: &Sensor,
    c: &C,
    sc: &Run<'_>,
    init: StageState,
    extra: &mut E,
) -> Signals {
    let n = sc.reference.len();
    let width = c.term_names().len().min(MAX_TERMS);
    let mut reference = Vec::with_capacity(n);
    let mut command = Vec::with_capacity(n);
    let mut voltage = Vec::with_capacity(n);
    let mut position = Vec::with_capacity(n);
    let mut measured = Vec::with_capacity(n);
    let mut terms = Vec::with_capacity(n * width + MAX_TERMS);
    let mut st = init;
    let x0 = extra.position(st.x);
    let mut sst = sensor.state(x0, sc.seed);
    let mut cst = vec![0.0; c.state_len()];
    c.reset(&mut cst, x0);
    let mut out = Out {
        reference: &mut reference.spare_capacity_mut()[..n],
        command: &mut command.spare_capacity_mut()[..n],
        voltage: &mut voltage.spare_capacity_mut()[..n],
        position: &mut position.spare_capacity_mut()[..n],
        measured: &mut measured.spare_capacity_mut()[..n],
        terms: &mut terms.spare_capacity_mut()[..n * width + MAX_TERMS],
        width,
    };
    let done = run_recorder_with(
        Loop { stage, stage_state: &mut st, sensor, sensor_state: &mut sst, controller: c, controller_state: &mut cst },
        Trajectory { position: sc.reference, velocity: sc.velocity, acceleration: sc.acceleration },
        &mut out,
        extra,
    );
    // SAFETY: run_recorder handed samples 0..done to `out` in order, which wrote element k
    // of every signal and terms[k * width .. k * width + MAX_TERMS] for each: the first
    // `done` (resp. `done * width`) elements are initialized.
    unsafe {
        reference.set_len(done);
        command.set_len(done);
        voltage.set_len(done);
        position.set_len(done);
        measured.set_len(done);
        terms.set_len(done * width);
    }
    // A non-finite position stays non-finite (every sub-step adds phi x0 to the new
    // position, and 0 * inf is NaN): the last sample tells whether to look for the first.
    let diverged_at = match position.last() {
        Some(x) if !x.is_finite() => position.iter().position(|x| !x.is_finite()),
        _ => None,
    };
    Signals {
        reference,
        command,
        voltage,
        position,
        measured,
        terms,
        final_state: st,
        term_names: c.term_names(),
        diverged_at,
        extra_state: Vec::new(),
    }
}

/// [`record_run`] compiled for AVX2: the same scalar IEEE operations in the three-operand
/// VEX encoding (fewer register copies), never fused (Rust does not contract `a * b + c`),
/// so the results are the same to the bit on either path.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn record_run_avx2<C: CoreController + ?Sized, E: Extra>(
    stage: &CoreStage,
    sensor: &Sensor,
    c: &C,
    sc: &Run<'_>,
    init: StageState,
    extra: &mut E,
) -> Signals {
    record_run(stage, sensor, c, sc, init, extra)
}

fn record_run_dispatch<C: CoreController + ?Sized, E: Extra>(
    stage: &CoreStage,
    sensor: &Sensor,
    c: &C,
    sc: &Run<'_>,
    init: StageState,
    extra: &mut E,
) -> Signals {
    #[cfg(target_arch = "x86_64")]
    {
        if use_avx2() {
            // SAFETY: the CPU has AVX2
            return unsafe { record_run_avx2(stage, sensor, c, sc, init, extra) };
        }
    }
    record_run(stage, sensor, c, sc, init, extra)
}

/// A plain PID (no inverse, no learning) as its own type, so the loop inlines its step
/// (decoded by the core's one decoder; validated there before any run).
fn plain_pid(spec: &ControllerSpec) -> Option<Pid> {
    if spec.kind != "pid" || spec.inverse.is_some() || spec.ilc.is_some() {
        return None;
    }
    match crate::control::law(&spec.kind, &spec.params) {
        Ok(Law::Pid(pid)) => Some(pid),
        _ => None,
    }
}

fn run_scenario<E: Extra>(
    stage: &CoreStage,
    sensor: &Sensor,
    sc: &Run<'_>,
    init: StageState,
    extra: &mut E,
) -> Signals {
    if let Some(pid) = plain_pid(&sc.controller) {
        return record_run_dispatch(stage, sensor, &pid, sc, init, extra);
    }
    with_controller(&sc.controller, |c| record_run_dispatch(stage, sensor, c, sc, init, extra))
        .expect("validated before the run")
}

fn signals_dict<'py>(py: Python<'py>, sig: Signals) -> PyResult<Bound<'py, PyDict>> {
    let names = sig.term_names;
    let d = PyDict::new(py);
    let n = sig.command.len();
    let k = names.len().min(MAX_TERMS);
    // the result's own copy of the reference (written by the run, like the other signals)
    d.set_item("reference", sig.reference.into_pyarray(py))?;
    d.set_item("command", sig.command.into_pyarray(py))?;
    d.set_item("voltage", sig.voltage.into_pyarray(py))?;
    d.set_item("position", sig.position.into_pyarray(py))?;
    d.set_item("measured", sig.measured.into_pyarray(py))?;
    let terms = Array2::from_shape_vec((n, k), sig.terms).expect("shape");
    let terms: Bound<'py, PyArray2<f64>> = terms.into_pyarray(py);
    d.set_item("terms", terms)?;
    d.set_item("term_names", names.to_vec())?;
    let mut final_state = sig.final_state.to_array().to_vec();
    final_state.extend(sig.extra_state);
    d.set_item("final_state", final_state)?;
    Ok(d)
}

fn sensor(q: f64, noise: f64, delay: usize) -> PyResult<Sensor> {
    Sensor::new(q, noise, delay).map_err(err)
}

/// [`check_finite`] with a branch-free pass first (an OR of the exponent fields, which
/// vectorizes); the error, if any, is `check_finite`'s.
fn check_finite_fast(name: &str, xs: &[f64]) -> PyResult<()> {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    if xs.iter().fold(0u64, |bad, x| bad | u64::from(x.to_bits() & EXPONENT == EXPONENT)) == 0 {
        Ok(())
    } else {
        check_finite(name, xs)
    }
}

fn scenario_arrays<'a>(
    r: &'a PyReadonlyArray1<'_, f64>,
    v: &'a PyReadonlyArray1<'_, f64>,
    a: &'a PyReadonlyArray1<'_, f64>,
) -> PyResult<(&'a [f64], &'a [f64], &'a [f64])> {
    let (r, v, a) = (slice(r, "reference")?, slice(v, "velocity")?, slice(a, "acceleration")?);
    check_scenario(r, v, a)?;
    Ok((r, v, a))
}

fn check_scenario(r: &[f64], v: &[f64], a: &[f64]) -> PyResult<()> {
    check_finite_fast("reference", r)?;
    check_finite_fast("velocity", v)?;
    check_finite_fast("acceleration", a)?;
    // empty derivatives stand for zeros
    if (!v.is_empty() && v.len() != r.len()) || (!a.is_empty() && a.len() != r.len()) {
        return Err(ParameterError::new_err(format!(
            "velocity and acceleration must be empty or as long as the reference, got {}, {}, {}",
            r.len(),
            v.len(),
            a.len()
        )));
    }
    Ok(())
}

/// The leading positional arguments of the free closed-loop functions: stage parameters,
/// `ts`, `substeps`, `tolerance`, sensor quantization, noise and delay.
#[derive(FromPyObject)]
struct StageArgs<'py>(PyReadonlyArray1<'py, f64>, f64, usize, f64, f64, f64, usize);

type Arr<'py> = PyReadonlyArray1<'py, f64>;

/// Split the positional arguments of a free closed-loop function into the stage (the
/// first 7) and the rest (`T`, `n` values).
fn split_args<'py, T: for<'a> FromPyObject<'a, 'py>>(
    name: &str,
    args: &Bound<'py, PyTuple>,
    n: usize,
) -> PyResult<(Stage, T)> {
    if args.len() != 7 + n {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "{name}() takes {} positional arguments, got {}",
            7 + n,
            args.len()
        )));
    }
    let StageArgs(p, ts, m, tol, q, noise, delay) = args.get_slice(0, 7).extract()?;
    let rest = args.get_slice(7, 7 + n).extract().map_err(Into::<PyErr>::into)?;
    Ok((stage_of(&p, ts, m, tol, q, noise, delay)?, rest))
}

/// The stage and sensor of the leading positional arguments.
fn stage_of(
    p: &PyReadonlyArray1<'_, f64>,
    ts: f64,
    m: usize,
    tol: f64,
    q: f64,
    noise: f64,
    delay: usize,
) -> PyResult<Stage> {
    let params = slice(p, "stage_params")?.to_vec();
    let st = stage(&params, ts, m, tol)?;
    Ok(Stage { stage: st, sensor: sensor(q, noise, delay)?, params, ts, structure: None })
}

/// Run one closed loop. Returns a dict of signals. (`Stage.closed_loop` with the stage
/// and the scenario as positional values.)
#[pyfunction]
#[pyo3(
    signature = (*args),
    text_signature = "(stage_params, ts, substeps, tolerance, sensor_quantization, sensor_noise, sensor_delay, \
                      controller, reference, velocity, acceleration, initial_state, seed)"
)]
fn closed_loop<'py>(py: Python<'py>, args: &Bound<'py, PyTuple>) -> PyResult<Bound<'py, PyDict>> {
    guarded(|| {
        type Rest<'py> = (ControllerArg<'py>, Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>, u64);
        let (st, (controller, reference, velocity, acceleration, init, seed)): (Stage, Rest<'py>) =
            split_args("closed_loop", args, 6)?;
        let c = controller_spec(&controller)?;
        let (r, v, a) = scenario_arrays(&reference, &velocity, &acceleration)?;
        let init = st.initial(&init)?;
        let sc = Run { reference: r, velocity: v, acceleration: a, seed, controller: c };
        let sig = st.with_plant(|plant| py.detach(|| plant.run(&sc, &init)))?;
        if let Some(k) = sig.diverged_at {
            return Err(ParameterError::new_err(format!("the closed loop diverged at sample {k}")));
        }
        signals_dict(py, sig)
    })
}

fn batch<'py>(
    py: Python<'py>,
    plant: &Plant<'_>,
    scenarios: &[ScenarioArg<'py>],
    init: &[f64],
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let list = runs(py, scenarios)?;
    // every run records five signals and up to MAX_TERMS terms per sample
    let samples = list.iter().fold(0usize, |acc, sc| acc.saturating_add(sc.reference.len()));
    check_alloc("closed_loop_batch: the recorded signals", &[samples, 5 + MAX_TERMS])?;
    let results: Vec<Option<Signals>> = interruptible(py, |stop| {
        list.par_iter().map(|sc| if stop.stopped() { None } else { Some(plant.run(sc, init)) }).collect()
    })?;
    let mut out = Vec::with_capacity(results.len());
    for (j, sig) in results.into_iter().enumerate() {
        let sig = sig.expect("every run ran (an interrupt raised above)");
        if let Some(k) = sig.diverged_at {
            return Err(ParameterError::new_err(format!("scenarios[{j}]: the closed loop diverged at sample {k}")));
        }
        out.push(signals_dict(py, sig)?);
    }
    Ok(out)
}

/// Run many closed-loop scenarios on one stage in parallel (GIL released, rayon).
/// `scenarios` is a list of `Scenario` or `(controller, reference, velocity, acceleration,
/// seed)`; returns a list of dicts as `closed_loop`. (`Stage.closed_loop_batch`.)
#[pyfunction]
#[pyo3(
    signature = (*args),
    text_signature = "(stage_params, ts, substeps, tolerance, sensor_quantization, sensor_noise, sensor_delay, \
                      scenarios, initial_state)"
)]
fn closed_loop_batch<'py>(py: Python<'py>, args: &Bound<'py, PyTuple>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    guarded(|| {
        let (st, (scenarios, init)): (Stage, (Vec<ScenarioArg<'py>>, Arr<'py>)) =
            split_args("closed_loop_batch", args, 2)?;
        let init = st.initial(&init)?;
        st.with_plant(|plant| batch(py, plant, &scenarios, &init))?
    })
}

fn tracking<'py>(
    py: Python<'py>,
    plant: &Plant<'_>,
    scenarios: &[ScenarioArg<'py>],
    init: &[f64],
    skip: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let list = runs(py, scenarios)?;
    for (j, sc) in list.iter().enumerate() {
        if skip >= sc.reference.len() {
            return Err(ParameterError::new_err(format!(
                "skip = {skip} leaves nothing of scenarios[{j}]'s {} samples",
                sc.reference.len()
            )));
        }
    }
    let rows: Vec<[f64; 3]> = interruptible(py, |stop| {
        list.par_iter()
            .map(|sc| {
                if stop.stopped() {
                    return [f64::NAN; 3];
                }
                plant.tracking(sc, init, skip)
            })
            .collect()
    })?;
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    Ok(Array2::from_shape_vec((rows.len(), 3), flat).expect("shape").into_pyarray(py))
}

/// `[rmse, max_error, saturated_fraction]` of one scenario from `init`.
fn tracking_run<E: Extra>(
    stage: &CoreStage,
    se: &Sensor,
    sc: &Run<'_>,
    init: StageState,
    skip: usize,
    extra: &mut E,
) -> [f64; 3] {
    with_controller(&sc.controller, |c| {
        let mut ss = init;
        let x0 = extra.position(ss.x);
        let mut sst = se.state(x0, sc.seed);
        let mut cst = vec![0.0; c.state_len()];
        c.reset(&mut cst, x0);
        let t = run_tracking_with(
            Loop {
                stage,
                stage_state: &mut ss,
                sensor: se,
                sensor_state: &mut sst,
                controller: c,
                controller_state: &mut cst,
            },
            Trajectory { position: sc.reference, velocity: sc.velocity, acceleration: sc.acceleration },
            skip,
            extra,
        );
        let n = t.samples.max(1) as f64;
        [(t.sse / n).sqrt(), t.max_error, t.saturated as f64 / sc.reference.len() as f64]
    })
    .expect("validated before the run")
}

/// Tracking figures of many closed-loop scenarios on one stage, recording no signals (GIL
/// released, rayon): an `(S, 3)` array of `[rmse, max_error, saturated_fraction]` of
/// `reference - true position` from sample `skip` on. Scenarios as `closed_loop_batch`. A
/// diverging run gives `inf`. The engine of gain tuning. (`Stage.closed_loop_batch_tracking`.)
#[pyfunction]
#[pyo3(
    signature = (*args),
    text_signature = "(stage_params, ts, substeps, tolerance, sensor_quantization, sensor_noise, sensor_delay, \
                      scenarios, initial_state, skip)"
)]
fn closed_loop_batch_tracking<'py>(py: Python<'py>, args: &Bound<'py, PyTuple>) -> PyResult<Bound<'py, PyArray2<f64>>> {
    guarded(|| {
        type Rest<'py> = (Vec<ScenarioArg<'py>>, Arr<'py>, usize);
        let (st, (scenarios, init, skip)): (Stage, Rest<'py>) = split_args("closed_loop_batch_tracking", args, 3)?;
        let init = st.initial(&init)?;
        st.with_plant(|plant| tracking(py, plant, &scenarios, &init, skip))?
    })
}

/// `(S,)` RMSE between the open-loop position of `S` stage parameter rows (`(S,
/// STAGE_PARAM_LEN)`) driven by one held-command record and a measured position, from rest
/// (GIL released, rayon across rows). Invalid rows raise, or cost `invalid_cost` if given;
/// a diverging simulation costs +inf. The engine of grey-box stage identification.
#[pyfunction]
#[pyo3(signature = (params, ts, substeps, tolerance, command, target, invalid_cost=None))]
fn stage_batch_rmse<'py>(
    params: PyReadonlyArray2<'py, f64>,
    ts: f64,
    substeps: usize,
    tolerance: f64,
    command: PyReadonlyArray1<'py, f64>,
    target: PyReadonlyArray1<'py, f64>,
    invalid_cost: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    guarded(|| {
        let py = params.py();
        let shape = params.shape();
        let width = piezohyst_core::stage::PARAM_LEN;
        if shape[1] != width {
            return Err(ParameterError::new_err(format!(
                "params has shape ({}, {}), expected (S, {width})",
                shape[0], shape[1]
            )));
        }
        // as_slice also accepts Fortran order (then in memory order): insist on rows
        if !params.is_c_contiguous() {
            return Err(ParameterError::new_err("params must be a C-contiguous float64 array"));
        }
        let p =
            params.as_slice().map_err(|_| ParameterError::new_err("params must be a C-contiguous float64 array"))?;
        let u = slice(&command, "command")?;
        let t = slice(&target, "target")?;
        check_finite("command", u)?;
        check_finite("target", t)?;
        if t.len() != u.len() || u.is_empty() {
            return Err(ParameterError::new_err(format!(
                "target has length {}, command has length {}; they must match and not be empty",
                t.len(),
                u.len()
            )));
        }
        let mut stages = Vec::with_capacity(shape[0]);
        for j in 0..shape[0] {
            let row = &p[j * width..(j + 1) * width];
            match stage(row, ts, substeps, tolerance) {
                Ok(s) => stages.push(Some(s)),
                Err(e) if invalid_cost.is_none() => {
                    return Err(ParameterError::new_err(format!("params[{j}]: {}", e.value(py))))
                }
                Err(_) => stages.push(None),
            }
        }
        let bad = invalid_cost.unwrap_or(f64::INFINITY);
        let out: Vec<f64> = interruptible(py, |stop| {
            stages
                .par_iter()
                .map(|s| match s {
                    _ if stop.stopped() => bad,
                    None => bad,
                    Some(st) => {
                        let mut ss = StageState::ZERO;
                        let mut sse = 0.0;
                        for (k, (&uk, &tk)) in u.iter().zip(t).enumerate() {
                            if k % 4096 == 0 && stop.stopped() {
                                break;
                            }
                            let e = ss.x - tk;
                            sse += e * e;
                            st.advance(&mut ss, uk);
                        }
                        let r = (sse / u.len() as f64).sqrt();
                        if r.is_finite() {
                            r
                        } else {
                            f64::INFINITY
                        }
                    }
                })
                .collect()
        })?;
        Ok(out.into_pyarray(py))
    })
}

/// Add this module's functions to the extension module.
/// The Rust core's copy of the packaged virtual stage ([`StageParams::virtual_stage`]) in the
/// flat layout, so a test can hold it equal to the preset file.
#[pyfunction]
fn virtual_stage_params<'py>(py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
    StageParams::virtual_stage().to_array().to_vec().into_pyarray(py)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Stage>()?;
    m.add_class::<Controller>()?;
    m.add_class::<Scenario>()?;
    m.add_function(wrap_pyfunction!(virtual_stage_params, m)?)?;
    m.add_function(wrap_pyfunction!(stage_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(closed_loop, m)?)?;
    m.add_function(wrap_pyfunction!(closed_loop_batch, m)?)?;
    m.add_function(wrap_pyfunction!(closed_loop_batch_tracking, m)?)?;
    m.add_function(wrap_pyfunction!(stage_batch_rmse, m)?)?;
    m.add("STAGE_PARAM_LEN", piezohyst_core::stage::PARAM_LEN)?;
    m.add("STAGE_STATE_LEN", StageState::LEN)?;
    m.add("MAX_TERMS", MAX_TERMS)?;
    Ok(())
}
