//! The closed-loop engine: controller at its sample time, amplifier and stage with
//! sub-steps, sensor with noise, quantization and delay (docs/spec.md §3.2, issue 3).
//!
//! Per sample `k` (time `k Ts`): the sensor samples the true position `x_k` and hands the
//! controller the reading it took `delay` samples ago; the controller returns a command;
//! the amplifier and stage advance one period under it. Recorded at `k`: reference, command,
//! amplifier output at the end of the period, `x_k`, the reading, and the controller terms.
use crate::control::{Controller, Reference, MAX_TERMS};
use crate::plant::sensor::{Sensor, SensorState};
use crate::plant::stage::{Extra, NoExtra, Stage, StageState, MAX_CREEP};

/// The parts of a closed loop, each configuration with its state (the caller resets them):
/// the stage with its amplifier, the sensor and the controller.
#[derive(Debug)]
pub struct Loop<'a, C: ?Sized> {
    /// Stage and amplifier.
    pub stage: &'a Stage,
    /// Their state, advanced by the run.
    pub stage_state: &'a mut StageState,
    /// Position sensor.
    pub sensor: &'a Sensor,
    /// Its state (noise stream, delay line), advanced by the run.
    pub sensor_state: &'a mut SensorState,
    /// Controller.
    pub controller: &'a C,
    /// Its state ([`Controller::state_len`] slots), advanced by the run.
    pub controller_state: &'a mut [f64],
}

/// The desired motion, one value per sample (m, m/s, m/s^2). An empty `velocity` or
/// `acceleration` means zeros (for controllers that do not use them).
#[derive(Debug, Clone, Copy)]
pub struct Trajectory<'a> {
    /// Desired position.
    pub position: &'a [f64],
    /// Desired velocity, or empty.
    pub velocity: &'a [f64],
    /// Desired acceleration, or empty.
    pub acceleration: &'a [f64],
}

/// Where a run writes its signals; every slice has the run's length (`terms`: the
/// controller's `term_names().len()` values per sample, row-major).
#[derive(Debug)]
pub struct Record<'a> {
    /// Voltage command, V.
    pub command: &'a mut [f64],
    /// Amplifier output at the end of each period, V.
    pub voltage: &'a mut [f64],
    /// True position at each sample, m.
    pub position: &'a mut [f64],
    /// Sensor reading the controller used, m.
    pub measured: &'a mut [f64],
    /// Controller internal terms.
    pub terms: &'a mut [f64],
}

/// What a run hands its [`Recorder`] at each sample.
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// Reference position, m.
    pub reference: f64,
    /// Voltage command, V.
    pub command: f64,
    /// Amplifier output at the end of the period, V.
    pub voltage: f64,
    /// True position at the sample, m.
    pub position: f64,
    /// Sensor reading the controller used, m.
    pub measured: f64,
    /// The controller's terms (its `term_names().len()` first values are meaningful).
    pub terms: &'a [f64; MAX_TERMS],
}

/// Takes a run's samples as they come (see [`run_recorder`]).
pub trait Recorder {
    /// Samples it can take; the run stops there.
    fn capacity(&self) -> usize;
    /// Sample `k`; called for `k = 0, 1, ...` in order, once each, and only for
    /// `k < capacity()` (implementations may rely on it).
    fn record(&mut self, k: usize, sample: &Sample<'_>);
}

/// [`Record`] with the controller's term count.
struct RecordTerms<'r, 'a> {
    rec: &'r mut Record<'a>,
    width: usize,
    len: usize,
}

impl Recorder for RecordTerms<'_, '_> {
    #[inline(always)]
    fn capacity(&self) -> usize {
        self.len
    }
    #[inline(always)]
    fn record(&mut self, k: usize, s: &Sample<'_>) {
        let w = self.width;
        self.rec.command[k] = s.command;
        self.rec.voltage[k] = s.voltage;
        self.rec.position[k] = s.position;
        self.rec.measured[k] = s.measured;
        self.rec.terms[k * w..(k + 1) * w].copy_from_slice(&s.terms[..w]);
    }
}

/// Run a whole trajectory, writing every sample to `rec`. Stops at the shortest of the
/// trajectory's position (and non-empty derivatives) and the record's slices.
pub fn run<C: Controller + ?Sized>(parts: Loop<'_, C>, trajectory: Trajectory<'_>, mut rec: Record<'_>) {
    let width = parts.controller.term_names().len().min(MAX_TERMS);
    let len = [rec.command.len(), rec.voltage.len(), rec.position.len(), rec.measured.len()]
        .into_iter()
        .min()
        .unwrap_or(0)
        .min(rec.terms.len() / width.max(1));
    let mut sink = RecordTerms { rec: &mut rec, width, len };
    run_recorder(parts, trajectory, &mut sink);
}

/// [`run`] handing each sample to `recorder`; returns the number of samples run (the
/// shortest of the signals and the recorder's capacity). Exactly the same arithmetic as
/// [`run`], whatever the recorder keeps.
#[inline(always)]
pub fn run_recorder<C: Controller + ?Sized, R: Recorder>(
    parts: Loop<'_, C>,
    trajectory: Trajectory<'_>,
    recorder: &mut R,
) -> usize {
    run_recorder_with(parts, trajectory, recorder, &mut NoExtra)
}

/// [`run_recorder`] on a stage with structure `extra` (more modes, a voltage-driven
/// hysteresis, a DAC: [`crate::plant::structure`]); the recorded position is the one the
/// sensor sees (`extra.position` of the stack's displacement). With [`NoExtra`] it is
/// [`run_recorder`], to the bit.
#[inline(always)]
pub fn run_recorder_with<C: Controller + ?Sized, R: Recorder, E: Extra>(
    parts: Loop<'_, C>,
    trajectory: Trajectory<'_>,
    recorder: &mut R,
    extra: &mut E,
) -> usize {
    let Trajectory { position: reference, velocity, acceleration } = trajectory;
    let len_or_any = |s: &[f64]| if s.is_empty() { usize::MAX } else { s.len() };
    let n = reference.len().min(len_or_any(velocity)).min(len_or_any(acceleration)).min(recorder.capacity());
    // every signal cut to the run's length (empty derivatives stay empty: zeros)
    fn cut(s: &[f64], n: usize) -> &[f64] {
        if s.is_empty() {
            s
        } else {
            &s[..n]
        }
    }
    let cut_trajectory =
        Trajectory { position: &reference[..n], velocity: cut(velocity, n), acceleration: cut(acceleration, n) };
    let (stage, sensor) = (parts.stage, parts.sensor);
    // one copy of the loop per creep-lag count, so the stage's creep loops unroll, and for
    // the typical stage and sensor one whose configuration checks fold away
    macro_rules! dispatch {
        ($t:literal) => {
            match stage.params.creep_terms {
                0 => run_n::<C, R, E, 0, $t>(parts, cut_trajectory, recorder, extra),
                1 => run_n::<C, R, E, 1, $t>(parts, cut_trajectory, recorder, extra),
                2 => run_n::<C, R, E, 2, $t>(parts, cut_trajectory, recorder, extra),
                3 => run_n::<C, R, E, 3, $t>(parts, cut_trajectory, recorder, extra),
                4 => run_n::<C, R, E, 4, $t>(parts, cut_trajectory, recorder, extra),
                5 => run_n::<C, R, E, 5, $t>(parts, cut_trajectory, recorder, extra),
                6 => run_n::<C, R, E, 6, $t>(parts, cut_trajectory, recorder, extra),
                7 => run_n::<C, R, E, 7, $t>(parts, cut_trajectory, recorder, extra),
                _ => run_n::<C, R, E, MAX_CREEP, $t>(parts, cut_trajectory, recorder, extra),
            }
        };
    }
    if stage.is_typical() && sensor.is_typical() {
        dispatch!(true)
    } else {
        dispatch!(false)
    }
    n
}

#[inline(always)]
fn run_n<C: Controller + ?Sized, R: Recorder, E: Extra, const NC: usize, const T: bool>(
    Loop { stage, stage_state, sensor, sensor_state, controller, controller_state }: Loop<'_, C>,
    Trajectory { position: reference, velocity, acceleration }: Trajectory<'_>,
    recorder: &mut R,
    extra: &mut E,
) {
    // the creep voltage is carried from period to period (the same sum each period starts
    // with; see Stage::advance_from)
    let mut vcr = stage.creep_voltage::<NC>(stage_state);
    for (k, &xr) in reference.iter().enumerate() {
        let x = if E::ACTIVE { extra.position(stage_state.x) } else { stage_state.x };
        let y = sensor.read_t::<T>(sensor_state, x);
        let r = Reference {
            x: xr,
            v: if velocity.is_empty() { 0.0 } else { velocity[k] },
            a: if acceleration.is_empty() { 0.0 } else { acceleration[k] },
        };
        let out = controller.step(controller_state, &r, y);
        vcr = stage.advance_from::<NC, T, E>(stage_state, out.u, vcr, extra);
        recorder.record(
            k,
            &Sample {
                reference: xr,
                command: out.u,
                voltage: stage_state.va,
                position: x,
                measured: y,
                terms: &out.terms,
            },
        );
    }
}

/// Tracking figures of a run that records no signals (gain tuning, scenario sweeps).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tracking {
    /// Sum of squared errors `reference - true position`, m^2.
    pub sse: f64,
    /// Largest absolute error, m.
    pub max_error: f64,
    /// Samples counted.
    pub samples: usize,
    /// Samples whose command sat on a controller limit.
    pub saturated: usize,
}

/// Run a whole trajectory like [`run`], recording nothing; errors count from sample `skip`
/// on (to leave out the start-up transient). A diverging plant gives infinite figures.
pub fn run_tracking<C: Controller + ?Sized>(parts: Loop<'_, C>, trajectory: Trajectory<'_>, skip: usize) -> Tracking {
    run_tracking_with(parts, trajectory, skip, &mut NoExtra)
}

/// [`run_tracking`] on a stage with structure `extra` (see [`run_recorder_with`]).
pub fn run_tracking_with<C: Controller + ?Sized, E: Extra>(
    parts: Loop<'_, C>,
    trajectory: Trajectory<'_>,
    skip: usize,
    extra: &mut E,
) -> Tracking {
    let Loop { stage, stage_state, sensor, sensor_state, controller, controller_state } = parts;
    let Trajectory { position: reference, velocity, acceleration } = trajectory;
    let limits = controller.limits();
    let mut t = Tracking::default();
    for (k, &xr) in reference.iter().enumerate() {
        let x = if E::ACTIVE { extra.position(stage_state.x) } else { stage_state.x };
        if k >= skip {
            let e = xr - x;
            t.sse += e * e;
            t.max_error = if crate::num::math::abs(e) > t.max_error || e.is_nan() {
                crate::num::math::abs(e)
            } else {
                t.max_error
            };
            t.samples += 1;
        }
        let y = sensor.read(sensor_state, x);
        let r = Reference {
            x: xr,
            v: velocity.get(k).copied().unwrap_or(0.0),
            a: acceleration.get(k).copied().unwrap_or(0.0),
        };
        let out = controller.step(controller_state, &r, y);
        if out.u <= limits.min || out.u >= limits.max {
            t.saturated += 1;
        }
        stage.advance_with(stage_state, out.u, extra);
    }
    if !t.sse.is_finite() || !stage_state.x.is_finite() {
        t.sse = f64::INFINITY;
        t.max_error = f64::INFINITY;
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{Limits, Pid, PidConfig};
    use crate::plant::stage::{HysteresisDrive, StageParams};

    fn params(creep_terms: usize, drive: HysteresisDrive) -> StageParams {
        let mut taus = [1.0; MAX_CREEP];
        let mut weights = [0.0; MAX_CREEP];
        for j in 0..creep_terms {
            taus[j] = 10f64.powi(j as i32 - 2);
            weights[j] = 0.015;
        }
        let voltage = drive == HysteresisDrive::Voltage;
        StageParams {
            mass: 0.0714,
            damping: 137.3,
            stiffness: 7.333e7,
            tem: 10.5,
            capacitance: 1.8e-6,
            hyst_alpha: if voltage { 0.2 } else { 1.25e5 },
            hyst_beta: if voltage { 0.01 } else { 8000.0 },
            hyst_gamma: if voltage { 0.004 } else { 3000.0 },
            hyst_drive: drive,
            electrostriction: 3.3e-4,
            creep_taus: taus,
            creep_weights: weights,
            creep_terms,
            amp_min: -20.0,
            amp_max: 150.0,
            amp_bandwidth: 3000.0,
            amp_slew: 1.4e5,
        }
    }

    /// The engine's loop (one copy per creep count and configuration class, the creep voltage
    /// carried from period to period) gives the same bits as stepping sensor, controller and
    /// `Stage::advance` by hand. With the unquantized sensor the loop takes its general copy
    /// while `advance` takes the typical stage's: the two agree too.
    #[test]
    fn run_matches_stepping_by_hand() {
        let ts = 1e-4;
        let n = 3000;
        // a sine with steps on it: the steps make the stage refine its sub-steps
        let r: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * ts;
                8e-6 + 6e-6 * libm::sin(2.0 * core::f64::consts::PI * 20.0 * t) + if k % 700 < 350 { 2e-6 } else { 0.0 }
            })
            .collect();
        let pid = Pid::new(PidConfig {
            kp: 1e6,
            ki: 5e9,
            kd: 0.0,
            tau_d: 1e-4,
            ts,
            ff_gain: 7.333e7 / 10.5,
            offset: 0.0,
            limits: Limits::new(-20.0, 150.0).unwrap(),
        })
        .unwrap();
        for creep_terms in 0..=MAX_CREEP {
            for (drive, substeps, tolerance, sensor) in [
                (HysteresisDrive::Charge, 1, 0.05, (1e-8, 3e-9, 1)),
                (HysteresisDrive::Charge, 1, 0.05, (0.0, 3e-9, 2)),
                (HysteresisDrive::Charge, 3, 0.01, (1e-8, 3e-9, 1)),
                (HysteresisDrive::Charge, 1, f64::INFINITY, (1e-8, 3e-9, 1)),
                (HysteresisDrive::Voltage, 2, 0.05, (1e-8, 3e-9, 0)),
            ] {
                let stage = Stage::new(params(creep_terms, drive), ts, substeps, tolerance).unwrap();
                let sensor = Sensor::new(sensor.0, sensor.1, sensor.2).unwrap();
                let mut init = StageState::ZERO;
                init.creep[..creep_terms].iter_mut().enumerate().for_each(|(j, w)| *w = 10.0 + j as f64);
                let (mut c, mut va, mut x, mut y, mut terms) =
                    (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; 5 * n]);
                let mut st = init;
                let mut sst = sensor.state(st.x, 9);
                let mut cst = [0.0; 3];
                pid.reset(&mut cst, st.x);
                let rec =
                    Record { command: &mut c, voltage: &mut va, position: &mut x, measured: &mut y, terms: &mut terms };
                let parts = Loop {
                    stage: &stage,
                    stage_state: &mut st,
                    sensor: &sensor,
                    sensor_state: &mut sst,
                    controller: &pid,
                    controller_state: &mut cst,
                };
                run(parts, Trajectory { position: &r, velocity: &[], acceleration: &[] }, rec);

                let mut hand = init;
                let mut hsst = sensor.state(hand.x, 9);
                let mut hcst = [0.0; 3];
                pid.reset(&mut hcst, hand.x);
                for k in 0..n {
                    let xk = hand.x;
                    let yk = sensor.read(&mut hsst, xk);
                    let out = pid.step(&mut hcst, &Reference { x: r[k], v: 0.0, a: 0.0 }, yk);
                    stage.advance(&mut hand, out.u);
                    let at = (creep_terms, substeps, k);
                    assert_eq!(x[k].to_bits(), xk.to_bits(), "{at:?}");
                    assert_eq!(y[k].to_bits(), yk.to_bits(), "{at:?}");
                    assert_eq!(c[k].to_bits(), out.u.to_bits(), "{at:?}");
                    assert_eq!(va[k].to_bits(), hand.va.to_bits(), "{at:?}");
                    for t in 0..5 {
                        assert_eq!(terms[5 * k + t].to_bits(), out.terms[t].to_bits(), "{at:?}");
                    }
                }
                assert_eq!(st.to_array().map(f64::to_bits), hand.to_array().map(f64::to_bits));
            }
        }
    }

    /// A recorder with less room than the reference stops the run there.
    #[test]
    fn run_stops_at_the_recorder_capacity() {
        struct Count(usize, usize);
        impl Recorder for Count {
            fn capacity(&self) -> usize {
                self.0
            }
            fn record(&mut self, k: usize, _: &Sample<'_>) {
                assert_eq!(k, self.1);
                self.1 += 1;
            }
        }
        let stage = Stage::new(params(5, HysteresisDrive::Charge), 1e-4, 1, 0.05).unwrap();
        let sensor = Sensor::new(0.0, 0.0, 0).unwrap();
        let pid = Pid::new(PidConfig {
            kp: 1e6,
            ki: 5e9,
            kd: 0.0,
            tau_d: 1e-4,
            ts: 1e-4,
            ff_gain: 0.0,
            offset: 0.0,
            limits: Limits::new(-20.0, 150.0).unwrap(),
        })
        .unwrap();
        let mut st = StageState::ZERO;
        let mut sst = sensor.state(0.0, 1);
        let mut cst = [0.0; 3];
        let mut count = Count(7, 0);
        let parts = Loop {
            stage: &stage,
            stage_state: &mut st,
            sensor: &sensor,
            sensor_state: &mut sst,
            controller: &pid,
            controller_state: &mut cst,
        };
        let trajectory = Trajectory { position: &[1e-6; 20], velocity: &[], acceleration: &[] };
        let done = run_recorder(parts, trajectory, &mut count);
        assert_eq!((done, count.1), (7, 7));
    }
}
