//! Multi-axis closed loop (issue 19): `N` actuators driving coupled dynamics, one sensor per
//! output and one controller per axis (decentralized control), optionally behind a static
//! decoupling matrix.
//!
//! Per sample `k`: the plant's true outputs `x_k` ([`Coupled::positions`]); each sensor `i`
//! samples `x_k[i]` and hands controller `i` its (delayed, noisy, quantized) reading; the
//! controllers' commands `c` pass the decoupling matrix (`u = T c`, or `u = c`) and the
//! plant advances one period under `u` ([`Coupled::advance`]). Recorded at `k`: the commands
//! `c`, what each actuator applied at the end of the period, `x_k`, the readings and the
//! controller terms. Nothing is allocated per sample: every per-sample buffer is a fixed
//! array of [`MAX_AXES`].
//!
//! Two plants are here: [`CoupledStages`] (each axis a piezo [`Stage`] with its amplifier,
//! hysteresis and structure; the outputs a static coupling matrix of the axes' positions)
//! and [`LfrPlant`] (an identified MIMO [`Lfr`] model with a hysteresis law per actuator
//! ahead of it and the actuators' voltage limits).
use crate::control::{Controller, Output, Reference, MAX_TERMS};
use crate::hysteresis::Hysteresis;
use crate::num::linalg::dot;
use crate::plant::closed_loop::{Sample, Tracking};
use crate::plant::lfr::Lfr;
use crate::plant::sensor::{Sensor, SensorState};
use crate::plant::stage::{Extra, Stage, StageState};

/// Most axes a multi-axis loop runs.
pub const MAX_AXES: usize = 8;

/// A plant with as many actuators as outputs, stepped one controller period at a time.
pub trait Coupled {
    /// Number of axes (inputs = outputs), at most [`MAX_AXES`].
    fn axes(&self) -> usize;
    /// The true outputs now (`axes()` values into `x`).
    fn positions(&self, x: &mut [f64]);
    /// Advance one period under the commands `u` (held); write what each actuator applied at
    /// the end of the period (amplifier voltage, V) into `applied`.
    fn advance(&mut self, u: &[f64], applied: &mut [f64]);
    /// Whether the state is finite.
    fn finite(&self) -> bool;
}

/// `N` piezo stages, each with its own amplifier, hysteresis, creep and structure (`E`), and
/// a static coupling of their displacements: output `i` is `sum_j coupling[i, j] x_j` (with
/// `x_j` the position stage `j`'s sensor would see). The identity matrix gives `N`
/// independent single-axis stages, to the bit.
#[derive(Debug)]
pub struct CoupledStages<'a, E> {
    /// The stages.
    pub stages: &'a [Stage],
    /// Their states, advanced.
    pub states: &'a mut [StageState],
    /// Their structures with state (or [`crate::plant::stage::NoExtra`]).
    pub extras: &'a mut [E],
    /// `N * N`, row-major.
    pub coupling: &'a [f64],
}

impl<E: Extra> Coupled for CoupledStages<'_, E> {
    fn axes(&self) -> usize {
        self.stages.len()
    }
    #[inline]
    fn positions(&self, x: &mut [f64]) {
        let n = self.stages.len();
        let mut own = [0.0; MAX_AXES];
        for ((o, e), st) in own.iter_mut().zip(self.extras.iter()).zip(self.states.iter()) {
            *o = e.position(st.x);
        }
        for (i, xi) in x.iter_mut().enumerate().take(n) {
            let mut acc = 0.0;
            for (j, &c) in self.coupling[i * n..(i + 1) * n].iter().enumerate() {
                if c != 0.0 {
                    acc += c * own[j];
                }
            }
            *xi = acc;
        }
    }
    #[inline]
    fn advance(&mut self, u: &[f64], applied: &mut [f64]) {
        for j in 0..self.stages.len() {
            self.stages[j].advance_with(&mut self.states[j], u[j], &mut self.extras[j]);
            applied[j] = self.states[j].va;
        }
    }
    fn finite(&self) -> bool {
        self.states.iter().all(|s| s.x.is_finite() && s.v.is_finite())
    }
}

/// An identified MIMO model ([`Lfr`], `nu = ny = N`) driven by `N` actuators: actuator `j`'s
/// command is clipped to `limits[j]`, passes its hysteresis law (if any) and enters the
/// model's input `j`. The command is held over the period: the outputs at sample `k` are
/// `C x_k + D u_{k-1} + F w_{k-1}` (the model's feedthrough of the held input).
#[derive(Debug)]
pub struct LfrPlant<'a, H> {
    /// The model.
    pub model: Lfr<'a>,
    /// Its state (`model.state_len()`), advanced.
    pub state: &'a mut [f64],
    /// `model.scratch_len()` slots; after a step its last `nw` hold the feedback `w`.
    pub scratch: &'a mut [f64],
    /// Per actuator: a hysteresis law ahead of the model, or none.
    pub laws: &'a [Option<H>],
    /// The laws' states, concatenated in actuator order.
    pub law_states: &'a mut [f64],
    /// Per actuator: voltage limits `[min, max]`.
    pub limits: &'a [[f64; 2]],
    /// The model input held over the current period (`N`).
    pub held: &'a mut [f64],
    /// Feedback-channel scratch (`nw`).
    pub z: &'a mut [f64],
    /// Output scratch of the model's step (`N`).
    pub y: &'a mut [f64],
}

impl<H: Hysteresis> Coupled for LfrPlant<'_, H> {
    fn axes(&self) -> usize {
        self.model.nu
    }
    #[inline]
    fn positions(&self, x: &mut [f64]) {
        let m = &self.model;
        let (nx, nu, nw) = (m.nx, m.nu, m.nw);
        let w = &self.scratch[nx..nx + nw];
        for (o, xo) in x.iter_mut().enumerate().take(m.ny) {
            *xo = dot(&m.c[o * nx..(o + 1) * nx], &self.state[..nx])
                + dot(&m.d[o * nu..(o + 1) * nu], self.held)
                + dot(&m.f[o * nw..(o + 1) * nw], w);
        }
    }
    #[inline]
    fn advance(&mut self, u: &[f64], applied: &mut [f64]) {
        let mut at = 0;
        for j in 0..self.model.nu {
            let [lo, hi] = self.limits[j];
            let v = u[j].max(lo).min(hi);
            applied[j] = v;
            self.held[j] = match &self.laws[j] {
                None => v,
                Some(h) => {
                    let len = h.state_len();
                    let out = h.step(&mut self.law_states[at..at + len], v);
                    at += len;
                    out
                }
            };
        }
        self.model.step(self.held, self.state, self.scratch, self.y, self.z);
    }
    fn finite(&self) -> bool {
        self.state.iter().all(|v| v.is_finite())
    }
}

/// The control side of a multi-axis loop: a sensor and a controller per axis.
#[derive(Debug)]
pub struct Axes<'a, C: ?Sized> {
    /// Sensor of each output.
    pub sensors: &'a [Sensor],
    /// Their states, advanced.
    pub sensor_states: &'a mut [SensorState],
    /// Controller of each axis.
    pub controllers: &'a [&'a C],
    /// Their states, concatenated in axis order (`offsets[i]..offsets[i + 1]` is axis `i`'s).
    pub controller_states: &'a mut [f64],
    /// `N + 1` offsets into `controller_states`.
    pub offsets: &'a [usize],
    /// Static decoupling `T` (`N * N`, row-major): the actuators get `T c`; `None`: `c`.
    pub decoupling: Option<&'a [f64]>,
}

/// The desired motion of every axis: `n * N` values, row-major (sample `k`, axis `i` at
/// `k * N + i`); an empty velocity or acceleration means zeros.
#[derive(Debug, Clone, Copy)]
pub struct MultiTrajectory<'a> {
    /// Desired positions, m.
    pub position: &'a [f64],
    /// Desired velocities, or empty.
    pub velocity: &'a [f64],
    /// Desired accelerations, or empty.
    pub acceleration: &'a [f64],
}

/// Takes a multi-axis run's samples: `record(k, i, sample)` for each sample `k` and axis `i`
/// in order.
pub trait MultiRecorder {
    /// One axis of one sample (`voltage` is what the actuator applied at the end of the period).
    fn record(&mut self, k: usize, axis: usize, sample: &Sample<'_>);
}

/// Run the loop over the whole trajectory; returns the samples run (`position.len() / N`).
/// `axes.controller_states` must hold each controller's reset state.
pub fn run_multi<P: Coupled, C: Controller + ?Sized, R: MultiRecorder>(
    plant: &mut P,
    axes: Axes<'_, C>,
    trajectory: MultiTrajectory<'_>,
    recorder: &mut R,
) -> usize {
    let n_axes = plant.axes();
    assert!(n_axes <= MAX_AXES && n_axes > 0, "1..={MAX_AXES} axes");
    let Axes { sensors, sensor_states, controllers, controller_states, offsets, decoupling } = axes;
    let n = trajectory.position.len() / n_axes;
    let (mut x, mut y, mut c, mut u, mut applied) =
        ([0.0; MAX_AXES], [0.0; MAX_AXES], [0.0; MAX_AXES], [0.0; MAX_AXES], [0.0; MAX_AXES]);
    let mut outs = [Output { u: 0.0, terms: [0.0; MAX_TERMS] }; MAX_AXES];
    let at = |s: &[f64], idx: usize| if s.is_empty() { 0.0 } else { s[idx] };
    for k in 0..n {
        plant.positions(&mut x[..n_axes]);
        for i in 0..n_axes {
            y[i] = sensors[i].read(&mut sensor_states[i], x[i]);
            let idx = k * n_axes + i;
            let r = Reference {
                x: trajectory.position[idx],
                v: at(trajectory.velocity, idx),
                a: at(trajectory.acceleration, idx),
            };
            outs[i] = controllers[i].step(&mut controller_states[offsets[i]..offsets[i + 1]], &r, y[i]);
            c[i] = outs[i].u;
        }
        match decoupling {
            None => u[..n_axes].copy_from_slice(&c[..n_axes]),
            Some(t) => {
                for i in 0..n_axes {
                    u[i] = dot(&t[i * n_axes..(i + 1) * n_axes], &c[..n_axes]);
                }
            }
        }
        plant.advance(&u[..n_axes], &mut applied[..n_axes]);
        for i in 0..n_axes {
            recorder.record(
                k,
                i,
                &Sample {
                    reference: trajectory.position[k * n_axes + i],
                    command: c[i],
                    voltage: applied[i],
                    position: x[i],
                    measured: y[i],
                    terms: &outs[i].terms,
                },
            );
        }
    }
    n
}

/// Per-axis tracking figures ([`Tracking`]) of a multi-axis run, from sample `skip` on; a
/// command on a controller limit counts as saturated.
#[derive(Debug, Clone)]
pub struct MultiTracking {
    /// Figures per axis.
    pub axes: [Tracking; MAX_AXES],
    /// First sample counted.
    pub skip: usize,
    /// Each controller's lower and upper limit.
    pub limits: [[f64; 2]; MAX_AXES],
}

impl MultiTracking {
    /// Empty figures for controllers `controllers`, counting from sample `skip`.
    pub fn new<C: Controller + ?Sized>(controllers: &[&C], skip: usize) -> Self {
        let mut limits = [[f64::NEG_INFINITY, f64::INFINITY]; MAX_AXES];
        for (l, c) in limits.iter_mut().zip(controllers) {
            let lim = c.limits();
            *l = [lim.min, lim.max];
        }
        MultiTracking { axes: [Tracking::default(); MAX_AXES], skip, limits }
    }
}

impl MultiRecorder for MultiTracking {
    #[inline]
    fn record(&mut self, k: usize, axis: usize, s: &Sample<'_>) {
        let t = &mut self.axes[axis];
        if s.command <= self.limits[axis][0] || s.command >= self.limits[axis][1] {
            t.saturated += 1;
        }
        if k >= self.skip {
            let e = s.reference - s.position;
            t.sse += e * e;
            let a = crate::num::math::abs(e);
            t.max_error = if a > t.max_error || e.is_nan() { a } else { t.max_error };
            t.samples += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{Limits, Pid, PidConfig};
    use crate::plant::closed_loop::{run, Loop, Record, Trajectory};
    use crate::plant::stage::{NoExtra, StageParams};

    fn pid() -> Pid {
        Pid::new(PidConfig {
            kp: 1e6,
            ki: 5e9,
            kd: 0.0,
            tau_d: 1e-4,
            ts: 1e-4,
            ff_gain: 7.333e7 / 10.5,
            offset: 0.0,
            limits: Limits::new(-20.0, 150.0).unwrap(),
        })
        .unwrap()
    }

    struct Rows(Vec<[f64; 4]>);
    impl MultiRecorder for Rows {
        fn record(&mut self, _k: usize, _i: usize, s: &Sample<'_>) {
            self.0.push([s.command, s.voltage, s.position, s.measured]);
        }
    }

    /// Two stages under the identity coupling give, axis by axis, the single-axis engine's
    /// run to the bit (same sensor seeds); a coupling changes the second axis.
    #[test]
    fn identity_coupling_is_two_single_axis_loops() {
        let ts = 1e-4;
        let n = 2000;
        let stage = Stage::new(StageParams::virtual_stage(), ts, 1, 0.05).unwrap();
        let sensor = Sensor::new(1e-9, 2e-9, 1).unwrap();
        let rx: Vec<f64> =
            (0..n).map(|k| 8e-6 + 5e-6 * libm::sin(k as f64 * ts * 2.0 * core::f64::consts::PI * 20.0)).collect();
        let ry: Vec<f64> =
            (0..n).map(|k| 6e-6 + 2e-6 * libm::cos(k as f64 * ts * 2.0 * core::f64::consts::PI * 7.0)).collect();
        let p = pid();
        let single = |r: &[f64], seed: u64| {
            let (mut c, mut va, mut x, mut y, mut t) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; 5 * n]);
            let mut st = StageState::ZERO;
            let mut sst = sensor.state(0.0, seed);
            let mut cst = [0.0; 3];
            p.reset(&mut cst, 0.0);
            run(
                Loop {
                    stage: &stage,
                    stage_state: &mut st,
                    sensor: &sensor,
                    sensor_state: &mut sst,
                    controller: &p,
                    controller_state: &mut cst,
                },
                Trajectory { position: r, velocity: &[], acceleration: &[] },
                Record { command: &mut c, voltage: &mut va, position: &mut x, measured: &mut y, terms: &mut t },
            );
            (c, va, x, y)
        };
        let multi = |coupling: &[f64]| {
            let stages = [stage, stage];
            let mut states = [StageState::ZERO; 2];
            let mut extras = [NoExtra, NoExtra];
            let mut plant = CoupledStages { stages: &stages, states: &mut states, extras: &mut extras, coupling };
            let sensors = [sensor, sensor];
            let mut sst = [sensor.state(0.0, 11), sensor.state(0.0, 12)];
            let ctl = [&p, &p];
            let mut cst = [0.0; 6];
            p.reset(&mut cst[..3], 0.0);
            p.reset(&mut cst[3..], 0.0);
            let r: Vec<f64> = rx.iter().zip(&ry).flat_map(|(a, b)| [*a, *b]).collect();
            let mut rows = Rows(Vec::new());
            let done = run_multi(
                &mut plant,
                Axes {
                    sensors: &sensors,
                    sensor_states: &mut sst,
                    controllers: &ctl,
                    controller_states: &mut cst,
                    offsets: &[0, 3, 6],
                    decoupling: None,
                },
                MultiTrajectory { position: &r, velocity: &[], acceleration: &[] },
                &mut rows,
            );
            assert_eq!(done, n);
            rows.0
        };
        let rows = multi(&[1.0, 0.0, 0.0, 1.0]);
        for (axis, (r, seed)) in [(&rx, 11), (&ry, 12)].into_iter().enumerate() {
            let (c, va, x, y) = single(r, seed);
            for k in 0..n {
                let row = rows[2 * k + axis];
                assert_eq!(row.map(f64::to_bits), [c[k], va[k], x[k], y[k]].map(f64::to_bits), "axis {axis} k {k}");
            }
        }
        let coupled = multi(&[1.0, 0.0, 0.05, 1.0]);
        assert_eq!(coupled[0], rows[0]);
        let moved = (0..n).any(|k| coupled[2 * k + 1][2] != rows[2 * k + 1][2]);
        assert!(moved);
    }
}
