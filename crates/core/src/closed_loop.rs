//! The closed-loop engine: controller at its sample time, amplifier and stage with
//! sub-steps, sensor with noise, quantization and delay (SPEC §3.2, issue 3).
//!
//! Per sample `k` (time `k Ts`): the sensor samples the true position `x_k` and hands the
//! controller the reading it took `delay` samples ago; the controller returns a command;
//! the amplifier and stage advance one period under it. Recorded at `k`: reference, command,
//! amplifier output at the end of the period, `x_k`, the reading, and the controller terms.
use crate::control::{Controller, Reference, MAX_TERMS};
use crate::sensor::{Sensor, SensorState};
use crate::stage::{Stage, StageState};

/// Where a run writes its signals; every slice has the run's length (`terms`: the
/// controller's `term_names().len()` values per sample, row-major).
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

/// Run a whole reference. `reference`, `velocity`, `acceleration` are the desired signals
/// per sample; an empty `velocity` or `acceleration` means zeros (for controllers that do
/// not use them). Stops at the shortest of the other slices.
#[allow(clippy::too_many_arguments)]
pub fn run<C: Controller + ?Sized>(
    stage: &Stage,
    stage_state: &mut StageState,
    sensor: &Sensor,
    sensor_state: &mut SensorState,
    controller: &C,
    controller_state: &mut [f64],
    reference: &[f64],
    velocity: &[f64],
    acceleration: &[f64],
    rec: Record<'_>,
) {
    let len_or_any = |s: &[f64]| if s.is_empty() { usize::MAX } else { s.len() };
    let n = reference.len().min(len_or_any(velocity)).min(len_or_any(acceleration)).min(rec.command.len());
    let width = controller.term_names().len().min(MAX_TERMS);
    let n = n.min(rec.terms.len() / width.max(1));
    for k in 0..n {
        let x = stage_state.x;
        let y = sensor.read(sensor_state, x);
        let r = Reference {
            x: reference[k],
            v: if velocity.is_empty() { 0.0 } else { velocity[k] },
            a: if acceleration.is_empty() { 0.0 } else { acceleration[k] },
        };
        let out = controller.step(controller_state, &r, y);
        stage.advance(stage_state, out.u);
        rec.command[k] = out.u;
        rec.voltage[k] = stage_state.va;
        rec.position[k] = x;
        rec.measured[k] = y;
        rec.terms[k * width..(k + 1) * width].copy_from_slice(&out.terms[..width]);
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

/// Run a whole reference like [`run`], recording nothing; errors count from sample `skip`
/// on (to leave out the start-up transient). A diverging plant gives infinite figures.
#[allow(clippy::too_many_arguments)]
pub fn run_tracking<C: Controller + ?Sized>(
    stage: &Stage,
    stage_state: &mut StageState,
    sensor: &Sensor,
    sensor_state: &mut SensorState,
    controller: &C,
    controller_state: &mut [f64],
    reference: &[f64],
    velocity: &[f64],
    acceleration: &[f64],
    skip: usize,
) -> Tracking {
    let limits = controller.limits();
    let mut t = Tracking::default();
    for k in 0..reference.len() {
        let x = stage_state.x;
        if k >= skip {
            let e = reference[k] - x;
            t.sse += e * e;
            t.max_error = if crate::math::abs(e) > t.max_error || e.is_nan() { crate::math::abs(e) } else { t.max_error };
            t.samples += 1;
        }
        let y = sensor.read(sensor_state, x);
        let r = Reference {
            x: reference[k],
            v: velocity.get(k).copied().unwrap_or(0.0),
            a: acceleration.get(k).copied().unwrap_or(0.0),
        };
        let out = controller.step(controller_state, &r, y);
        if out.u <= limits.min || out.u >= limits.max {
            t.saturated += 1;
        }
        stage.advance(stage_state, out.u);
    }
    if !t.sse.is_finite() || !stage_state.x.is_finite() {
        t.sse = f64::INFINITY;
        t.max_error = f64::INFINITY;
    }
    t
}
