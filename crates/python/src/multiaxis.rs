//! Multi-axis closed loop bindings (`piezohyst_core::multiaxis`): a plant of `N` coupled
//! axes (stages with a static coupling matrix, or an identified LFR model with a hysteresis
//! law per actuator), one sensor and one controller per axis. Runs start at rest; batch
//! tracking releases the GIL and puts one candidate per rayon task.
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use piezohyst_core::closed_loop::Sample;
use piezohyst_core::control::{Controller, MAX_TERMS};
use piezohyst_core::lfr::Lfr;
use piezohyst_core::multiaxis::{
    run_multi, Axes, Coupled, CoupledStages, LfrPlant, MultiRecorder, MultiTracking, MultiTrajectory, MAX_AXES,
};
use piezohyst_core::sensor::Sensor;
use piezohyst_core::spec::{Family, Model};
use piezohyst_core::stage::{Extra, Stage as CoreStage, StageState, SubStep};
use piezohyst_core::structure::StructureRun;
use piezohyst_core::Hysteresis;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::control::{with_controller, ControllerSpec};
use crate::plant::{controller_spec, ControllerArg, Plant, Stage};
use crate::util::{bad_arg, check_alloc, check_finite, err, guarded, interruptible, slice};

/// A stage axis's structure, or none: one type for the coupled stages' hooks.
enum AxisExtra<'s> {
    Plain,
    Structured(StructureRun<'s, Model<'s>>),
}

impl Extra for AxisExtra<'_> {
    const ACTIVE: bool = true;
    #[inline]
    fn command(&mut self, u: f64) -> f64 {
        match self {
            AxisExtra::Plain => u,
            AxisExtra::Structured(s) => s.command(u),
        }
    }
    #[inline]
    fn input_vh(&mut self, va: f64) -> Option<f64> {
        match self {
            AxisExtra::Plain => None,
            AxisExtra::Structured(s) => s.input_vh(va),
        }
    }
    #[inline]
    fn end_period(&mut self, va: f64) {
        if let AxisExtra::Structured(s) = self {
            s.end_period(va)
        }
    }
    #[inline]
    fn substep(&mut self, step: &SubStep) {
        if let AxisExtra::Structured(s) = self {
            s.substep(step)
        }
    }
    #[inline]
    fn position(&self, x: f64) -> f64 {
        match self {
            AxisExtra::Plain => x,
            AxisExtra::Structured(s) => s.position(x),
        }
    }
}

/// The matrices and laws of an LFR plant, owned.
#[derive(Debug, Clone)]
struct LfrSpec {
    dims: [usize; 5],
    /// The last `nt` feedback channels are static saturations.
    nt: usize,
    mats: [Vec<f64>; 10],
    laws: Vec<Option<(Family, Vec<f64>)>>,
    limits: Vec<[f64; 2]>,
}

impl LfrSpec {
    fn model(&self) -> Lfr<'_> {
        let [nx, nu, ny, nw, nr] = self.dims;
        let m = &self.mats;
        Lfr {
            nx,
            nu,
            ny,
            nw,
            nr,
            a: &m[0],
            b: &m[1],
            c: &m[2],
            d: &m[3],
            e: &m[4],
            f: &m[5],
            g: &m[6],
            h: &m[7],
            thresholds: &m[8],
            weights: &m[9],
            nt: self.nt,
            modal: false,
        }
    }
}

#[derive(Debug)]
enum Kind {
    Stages { stages: Vec<Py<Stage>>, coupling: Vec<f64> },
    Lfr(Box<LfrSpec>),
}

/// A multi-axis plant with one sensor per output, built once (see the module docs).
#[pyclass(frozen, module = "piezohyst._core")]
#[derive(Debug)]
pub struct MultiAxisPlant {
    kind: Kind,
    sensors: Vec<Sensor>,
    ts: f64,
}

fn check_axes(n: usize, what: &str) -> PyResult<()> {
    if n == 0 || n > MAX_AXES {
        return Err(bad_arg(format!("{what} has {n} axes; a multi-axis plant has 1 to {MAX_AXES}")));
    }
    Ok(())
}

fn square<'a>(a: &'a PyReadonlyArray2<'_, f64>, name: &str, n: usize) -> PyResult<&'a [f64]> {
    let s = a.shape();
    if s[0] != n || s[1] != n {
        return Err(bad_arg(format!("{name} has shape ({}, {}), expected ({n}, {n})", s[0], s[1])));
    }
    let v = a.as_slice().map_err(|_| bad_arg(format!("{name} must be a C-contiguous float64 array")))?;
    check_finite(name, v)?;
    Ok(v)
}

/// Signals `(n, N)` of a reference, or empty (zeros) when `None`.
fn signal<'a>(a: &'a Option<PyReadonlyArray2<'_, f64>>, name: &str, n: usize, axes: usize) -> PyResult<&'a [f64]> {
    match a {
        None => Ok(&[]),
        Some(a) => {
            let s = a.shape();
            if s[1] != axes || s[0] != n {
                return Err(bad_arg(format!("{name} has shape ({}, {}), expected ({n}, {axes})", s[0], s[1])));
            }
            let v = a.as_slice().map_err(|_| bad_arg(format!("{name} must be a C-contiguous float64 array")))?;
            check_finite(name, v)?;
            Ok(v)
        }
    }
}

/// Build the controllers of `specs` and hand them to `f` (nested builds: each borrows its
/// inverse model's row in its own frame).
fn with_controllers<R>(
    specs: &[ControllerSpec],
    acc: &[&(dyn Controller + Sync)],
    f: &mut dyn FnMut(&[&(dyn Controller + Sync)]) -> R,
) -> Result<R, String> {
    match specs.split_first() {
        None => Ok(f(acc)),
        Some((spec, rest)) => with_controller(spec, |c| {
            let mut v: Vec<&(dyn Controller + Sync)> = acc.to_vec();
            v.push(c);
            with_controllers(rest, &v, f)
        })?,
    }
}

/// The [`Plant`]s (stage, sensor, built structure) of `stages`, handed to `f`.
fn with_plants<R>(stages: &[&Stage], acc: &[Plant<'_>], f: &mut dyn FnMut(&[Plant<'_>]) -> R) -> PyResult<R> {
    match stages.split_first() {
        None => Ok(f(acc)),
        Some((s, rest)) => s.with_plant(|p| {
            let mut v: Vec<Plant<'_>> = acc.to_vec();
            v.push(*p);
            with_plants(rest, &v, f)
        })?,
    }
}

/// The recorded signals of a run.
struct Signals {
    command: Vec<f64>,
    voltage: Vec<f64>,
    position: Vec<f64>,
    measured: Vec<f64>,
    terms: Vec<Vec<f64>>,
    widths: Vec<usize>,
}

impl MultiRecorder for Signals {
    fn record(&mut self, _k: usize, axis: usize, s: &Sample<'_>) {
        self.command.push(s.command);
        self.voltage.push(s.voltage);
        self.position.push(s.position);
        self.measured.push(s.measured);
        let w = self.widths[axis];
        self.terms[axis].extend_from_slice(&s.terms[..w]);
    }
}

/// A run's inputs, checked.
struct RunArgs<'a> {
    trajectory: MultiTrajectory<'a>,
    seeds: &'a [u64],
    decoupling: Option<&'a [f64]>,
}

impl MultiAxisPlant {
    fn axes(&self) -> usize {
        self.sensors.len()
    }

    /// Run `controllers` from rest over `args`, handing samples to `rec`; returns whether the
    /// plant stayed finite.
    fn run<R: MultiRecorder>(
        &self,
        controllers: &[&(dyn Controller + Sync)],
        args: &RunArgs<'_>,
        rec: &mut R,
    ) -> PyResult<bool> {
        let n = self.axes();
        let mut offsets = vec![0usize; n + 1];
        for (i, c) in controllers.iter().enumerate() {
            offsets[i + 1] = offsets[i] + c.state_len();
        }
        let mut cst = vec![0.0; offsets[n]];
        // x0 = 0 at rest for both plants (a structured stage's position at rest is 0 too)
        for (i, c) in controllers.iter().enumerate() {
            c.reset(&mut cst[offsets[i]..offsets[i + 1]], 0.0);
        }
        let mut sst: Vec<_> = self.sensors.iter().zip(args.seeds).map(|(s, &seed)| s.state(0.0, seed)).collect();
        let mut axes = Some(Axes {
            sensors: &self.sensors,
            sensor_states: &mut sst,
            controllers,
            controller_states: &mut cst,
            offsets: &offsets,
            decoupling: args.decoupling,
        });
        match &self.kind {
            Kind::Stages { stages, coupling } => {
                let refs: Vec<&Stage> = stages.iter().map(|s| s.get()).collect();
                with_plants(&refs, &[], &mut |plants: &[Plant<'_>]| {
                    let core: Vec<CoreStage> = plants.iter().map(|p| *p.stage).collect();
                    let mut extra_states: Vec<Vec<f64>> = plants
                        .iter()
                        .map(|p| match p.structure {
                            None => Vec::new(),
                            Some(s) => {
                                let mut e = vec![0.0; s.state_len()];
                                s.reset(&mut e, 0.0);
                                e
                            }
                        })
                        .collect();
                    let mut extras: Vec<AxisExtra<'_>> = plants
                        .iter()
                        .zip(extra_states.iter_mut())
                        .map(|(p, e)| match p.structure {
                            None => AxisExtra::Plain,
                            Some(s) => AxisExtra::Structured(s.run(e)),
                        })
                        .collect();
                    let mut states = vec![StageState::ZERO; n];
                    let mut plant = CoupledStages { stages: &core, states: &mut states, extras: &mut extras, coupling };
                    run_multi(&mut plant, axes.take().expect("one run"), args.trajectory, rec);
                    plant.finite()
                })
            }
            Kind::Lfr(spec) => {
                let model = spec.model();
                let mut scratches: Vec<Vec<f64>> = spec
                    .laws
                    .iter()
                    .map(|l| l.as_ref().map_or(Vec::new(), |(fam, _)| vec![0.0; fam.scratch_len()]))
                    .collect();
                let mut laws: Vec<Option<Model<'_>>> = Vec::with_capacity(n);
                for (l, scratch) in spec.laws.iter().zip(scratches.iter_mut()) {
                    laws.push(match l {
                        None => None,
                        Some((fam, row)) => Some(fam.build(row, scratch).map_err(err)?),
                    });
                }
                let len: usize = laws.iter().map(|l| l.as_ref().map_or(0, |h| h.state_len())).sum();
                let mut law_states = vec![0.0; len];
                let mut at = 0;
                for h in laws.iter().flatten() {
                    let k = h.state_len();
                    h.reset(&mut law_states[at..at + k]);
                    at += k;
                }
                let mut state = vec![0.0; model.state_len()];
                let mut scratch = vec![0.0; model.scratch_len()];
                let (mut held, mut z, mut y) = (vec![0.0; n], vec![0.0; model.nw], vec![0.0; n]);
                let mut plant = LfrPlant {
                    model,
                    state: &mut state,
                    scratch: &mut scratch,
                    laws: &laws,
                    law_states: &mut law_states,
                    limits: &spec.limits,
                    held: &mut held,
                    z: &mut z,
                    y: &mut y,
                };
                run_multi(&mut plant, axes.take().expect("one run"), args.trajectory, rec);
                Ok(plant.finite())
            }
        }
    }

    fn args<'a>(
        &self,
        reference: &'a PyReadonlyArray2<'_, f64>,
        velocity: &'a Option<PyReadonlyArray2<'_, f64>>,
        acceleration: &'a Option<PyReadonlyArray2<'_, f64>>,
        seeds: &'a [u64],
        decoupling: &'a Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<RunArgs<'a>> {
        let n = self.axes();
        let s = reference.shape();
        if s[1] != n {
            return Err(bad_arg(format!("reference has shape ({}, {}), expected (n, {n})", s[0], s[1])));
        }
        let position = reference.as_slice().map_err(|_| bad_arg("reference must be C-contiguous".into()))?;
        check_finite("reference", position)?;
        let rows = reference.shape()[0];
        if rows < 2 {
            return Err(bad_arg(format!("reference has {rows} samples; at least 2")));
        }
        let velocity = signal(velocity, "velocity", rows, n)?;
        let acceleration = signal(acceleration, "acceleration", rows, n)?;
        if seeds.len() != n {
            return Err(bad_arg(format!("seeds has {} values, one per axis ({n})", seeds.len())));
        }
        let decoupling = match decoupling {
            None => None,
            Some(t) => Some(square(t, "decoupling", n)?),
        };
        Ok(RunArgs { trajectory: MultiTrajectory { position, velocity, acceleration }, seeds, decoupling })
    }

    fn specs(&self, controllers: &[ControllerArg<'_>]) -> PyResult<Vec<ControllerSpec>> {
        if controllers.len() != self.axes() {
            return Err(bad_arg(format!(
                "controllers has {} controllers, one per axis ({})",
                controllers.len(),
                self.axes()
            )));
        }
        controllers
            .iter()
            .enumerate()
            .map(|(i, c)| controller_spec(c).map_err(|e| bad_arg(format!("controllers[{i}]: {e}"))))
            .collect()
    }
}

type LawArg<'py> = Option<(String, Vec<usize>, PyReadonlyArray1<'py, f64>)>;

#[pymethods]
impl MultiAxisPlant {
    /// `N` stages (`_core.Stage`, one control period) whose positions are mixed by
    /// `coupling` `(N, N)`; each stage's sensor reads its output.
    #[staticmethod]
    fn stages(stages: Vec<Bound<'_, Stage>>, coupling: PyReadonlyArray2<'_, f64>) -> PyResult<Self> {
        guarded(|| {
            let n = stages.len();
            check_axes(n, "stages")?;
            let coupling = square(&coupling, "coupling", n)?.to_vec();
            let ts = stages[0].get().ts_value();
            for (j, s) in stages.iter().enumerate() {
                if s.get().ts_value() != ts {
                    return Err(bad_arg(format!(
                        "stages[{j}] runs at {} s, stages[0] at {ts} s: one control period",
                        s.get().ts_value()
                    )));
                }
            }
            let sensors = stages.iter().map(|s| *s.get().sensor_ref()).collect();
            Ok(MultiAxisPlant {
                kind: Kind::Stages { stages: stages.into_iter().map(Bound::unbind).collect(), coupling },
                sensors,
                ts,
            })
        })
    }

    /// An LFR model (matrices as `lfr_simulate`; `nu == ny == N`) with a hysteresis law per
    /// actuator (`None` or `(family, dims, row)`), the actuators' voltage limits `(lo, hi)`
    /// and a sensor `(quantization, noise, delay)` per output; `ts` the model's sample time.
    #[staticmethod]
    #[pyo3(signature = (a, b, c, d, e, f, g, h, thresholds, weights, hysteresis, limits, sensors, ts, nt = 0))]
    #[allow(clippy::too_many_arguments)]
    fn lfr(
        a: PyReadonlyArray2<'_, f64>,
        b: PyReadonlyArray2<'_, f64>,
        c: PyReadonlyArray2<'_, f64>,
        d: PyReadonlyArray2<'_, f64>,
        e: PyReadonlyArray2<'_, f64>,
        f: PyReadonlyArray2<'_, f64>,
        g: PyReadonlyArray2<'_, f64>,
        h: PyReadonlyArray2<'_, f64>,
        thresholds: PyReadonlyArray2<'_, f64>,
        weights: PyReadonlyArray2<'_, f64>,
        hysteresis: Vec<LawArg<'_>>,
        limits: Vec<(f64, f64)>,
        sensors: Vec<(f64, f64, usize)>,
        ts: f64,
        nt: usize,
    ) -> PyResult<Self> {
        guarded(|| {
            let (nx, nu, ny, nw, nr) = (a.shape()[0], b.shape()[1], c.shape()[0], g.shape()[0], thresholds.shape()[1]);
            if nu != ny {
                return Err(bad_arg(format!("the model has {nu} inputs and {ny} outputs; one actuator per output")));
            }
            check_axes(nu, "the model")?;
            let arrays = [&a, &b, &c, &d, &e, &f, &g, &h, &thresholds, &weights];
            let mut mats: [Vec<f64>; 10] = Default::default();
            for (m, x) in mats.iter_mut().zip(arrays) {
                *m = x.as_slice().map_err(|_| bad_arg("model matrices must be C-contiguous float64".into()))?.to_vec();
            }
            let spec_dims = [nx, nu, ny, nw, nr];
            if hysteresis.len() != nu || limits.len() != nu || sensors.len() != nu {
                return Err(bad_arg(format!(
                    "hysteresis, limits and sensors have {}, {}, {} entries; one per axis ({nu})",
                    hysteresis.len(),
                    limits.len(),
                    sensors.len()
                )));
            }
            let mut laws = Vec::with_capacity(nu);
            for (j, l) in hysteresis.into_iter().enumerate() {
                laws.push(match l {
                    None => None,
                    Some((name, dims, row)) => {
                        let fam = crate::models::family(&name, dims)?;
                        let row = slice(&row, "hysteresis row")?.to_vec();
                        check_finite(&format!("hysteresis[{j}] row"), &row)?;
                        let mut scratch = vec![0.0; fam.scratch_len()];
                        fam.build(&row, &mut scratch).map_err(|e| bad_arg(format!("hysteresis[{j}]: {e}")))?;
                        Some((fam, row))
                    }
                });
            }
            let limits: Vec<[f64; 2]> = limits.into_iter().map(|(lo, hi)| [lo, hi]).collect();
            for (j, [lo, hi]) in limits.iter().enumerate() {
                if !(lo < hi) || lo.is_nan() {
                    return Err(bad_arg(format!("limits[{j}] = ({lo}, {hi}): low must be < high")));
                }
            }
            let sensors = sensors
                .into_iter()
                .map(|(q, noise, delay)| Sensor::new(q, noise, delay).map_err(err))
                .collect::<PyResult<Vec<_>>>()?;
            if !(ts > 0.0 && ts.is_finite()) {
                return Err(bad_arg(format!("ts = {ts} must be a positive number of seconds")));
            }
            let spec = LfrSpec { dims: spec_dims, nt, mats, laws, limits };
            spec.model().validated().map_err(err)?;
            Ok(MultiAxisPlant { kind: Kind::Lfr(Box::new(spec)), sensors, ts })
        })
    }

    /// Number of axes.
    #[getter(axes)]
    fn axes_py(&self) -> usize {
        self.axes()
    }

    /// Control period, s.
    #[getter]
    fn ts(&self) -> f64 {
        self.ts
    }

    /// One closed loop from rest: `controllers` one per axis, `reference` `(n, N)` (m),
    /// optional `velocity`/`acceleration` `(n, N)`, a sensor-noise seed per axis and an
    /// optional decoupling matrix `(N, N)`. Returns a dict: `command`, `voltage`, `position`,
    /// `measured` `(n, N)`; `terms` (a list of `(n, w_i)` arrays) and `term_names`.
    #[pyo3(signature = (controllers, reference, velocity, acceleration, seeds, decoupling=None))]
    #[allow(clippy::too_many_arguments)]
    fn closed_loop<'py>(
        &self,
        py: Python<'py>,
        controllers: Vec<ControllerArg<'py>>,
        reference: PyReadonlyArray2<'py, f64>,
        velocity: Option<PyReadonlyArray2<'py, f64>>,
        acceleration: Option<PyReadonlyArray2<'py, f64>>,
        seeds: Vec<u64>,
        decoupling: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        guarded(|| {
            let specs = self.specs(&controllers)?;
            let args = self.args(&reference, &velocity, &acceleration, &seeds, &decoupling)?;
            let n = self.axes();
            let rows = reference.shape()[0];
            check_alloc("multi-axis closed loop: the recorded signals", &[rows, n, 4 + MAX_TERMS])?;
            let result = with_controllers(&specs, &[], &mut |cs| {
                let widths: Vec<usize> = cs.iter().map(|c| c.term_names().len().min(MAX_TERMS)).collect();
                let mut sig = Signals {
                    command: Vec::with_capacity(rows * n),
                    voltage: Vec::with_capacity(rows * n),
                    position: Vec::with_capacity(rows * n),
                    measured: Vec::with_capacity(rows * n),
                    terms: widths.iter().map(|w| Vec::with_capacity(rows * w)).collect(),
                    widths,
                };
                let names: Vec<Vec<String>> =
                    cs.iter().map(|c| c.term_names().iter().map(|s| s.to_string()).collect()).collect();
                let finite = py.detach(|| self.run(cs, &args, &mut sig));
                finite.map(|f| (sig, names, f))
            })
            .map_err(bad_arg)??;
            let (sig, names, finite) = result;
            if !finite || sig.position.iter().any(|x| !x.is_finite()) {
                let k = sig.position.iter().position(|x| !x.is_finite()).unwrap_or(sig.position.len()) / n;
                return Err(bad_arg(format!("the multi-axis closed loop diverged at sample {k}")));
            }
            let d = PyDict::new(py);
            let shape = |v: Vec<f64>| Array2::from_shape_vec((rows, n), v).expect("shape").into_pyarray(py);
            d.set_item("command", shape(sig.command))?;
            d.set_item("voltage", shape(sig.voltage))?;
            d.set_item("position", shape(sig.position))?;
            d.set_item("measured", shape(sig.measured))?;
            let terms: Vec<Bound<'py, PyArray2<f64>>> = sig
                .terms
                .into_iter()
                .zip(&sig.widths)
                .map(|(t, &w)| Array2::from_shape_vec((rows, w), t).expect("shape").into_pyarray(py))
                .collect();
            d.set_item("terms", terms)?;
            d.set_item("term_names", names)?;
            Ok(d)
        })
    }

    /// Tracking figures of many candidates (each a list of controllers, one per axis) on
    /// the same reference and seeds: `(S, N, 3)` `[rmse, max_error, saturated fraction]`
    /// per candidate and axis, errors from sample `skip` on; a diverging run gives `inf`.
    /// GIL released, one candidate per rayon task.
    #[pyo3(signature = (candidates, reference, velocity, acceleration, seeds, skip, decoupling=None))]
    #[allow(clippy::too_many_arguments)]
    fn closed_loop_batch_tracking<'py>(
        &self,
        py: Python<'py>,
        candidates: Vec<Vec<ControllerArg<'py>>>,
        reference: PyReadonlyArray2<'py, f64>,
        velocity: Option<PyReadonlyArray2<'py, f64>>,
        acceleration: Option<PyReadonlyArray2<'py, f64>>,
        seeds: Vec<u64>,
        skip: usize,
        decoupling: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        guarded(|| {
            let specs: Vec<Vec<ControllerSpec>> = candidates
                .iter()
                .enumerate()
                .map(|(j, c)| self.specs(c).map_err(|e| bad_arg(format!("candidates[{j}]: {}", e.value(py)))))
                .collect::<PyResult<_>>()?;
            let args = self.args(&reference, &velocity, &acceleration, &seeds, &decoupling)?;
            let n = self.axes();
            let rows = reference.shape()[0];
            let figures: Vec<Vec<[f64; 3]>> = interruptible(py, |stop| {
                specs
                    .par_iter()
                    .map(|spec| {
                        if stop.stopped() {
                            return vec![[f64::NAN; 3]; n];
                        }
                        with_controllers(spec, &[], &mut |cs| {
                            let mut t = MultiTracking::new(cs, skip);
                            let finite = self.run(cs, &args, &mut t).unwrap_or(false);
                            (0..n)
                                .map(|i| {
                                    let a = &t.axes[i];
                                    if !finite || !a.sse.is_finite() {
                                        [f64::INFINITY, f64::INFINITY, a.saturated as f64 / rows as f64]
                                    } else {
                                        [
                                            (a.sse / a.samples.max(1) as f64).sqrt(),
                                            a.max_error,
                                            a.saturated as f64 / rows as f64,
                                        ]
                                    }
                                })
                                .collect()
                        })
                        .expect("validated before the run")
                    })
                    .collect()
            })?;
            let flat: Vec<f64> = figures.iter().flatten().flatten().copied().collect();
            Ok(Array3::from_shape_vec((figures.len(), n, 3), flat).expect("shape").into_pyarray(py))
        })
    }

    fn __repr__(&self) -> String {
        let kind = match &self.kind {
            Kind::Stages { .. } => "stages",
            Kind::Lfr(_) => "lfr",
        };
        format!("MultiAxisPlant(kind={kind:?}, axes={}, ts={})", self.axes(), self.ts)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<MultiAxisPlant>()?;
    Ok(())
}
