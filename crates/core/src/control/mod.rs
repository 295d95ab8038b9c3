//! Control: the interface every controller implements, the velocity observer the
//! model-based laws share, and the baselines (open loop with dynamic feedforward, PID).
//!
//! Like the hysteresis models, a controller is an immutable **configuration** and a flat
//! `f64` **state** owned by the caller (length [`Controller::state_len`]), so one
//! configuration can drive many loops, a step never allocates, and the C ABI can hand the
//! state over as a plain buffer. The output voltage is always inside the limits, and every
//! integrator or adaptation law stops while the output is saturated in the direction that
//! would deepen the saturation (anti-windup).
//!
//! The model-based laws and wrappers live in the submodules: [`smc`] (seed 1), [`absmc`]
//! (seed 2), [`cemf`] (the identified CEMF model as observer and inverse feedforward, used by
//! [`smc`]), [`compensated`] (any controller behind an exact inverse hysteresis model) and
//! [`ilc`] (iterative learning on top of any controller) and [`filtered`] (the practitioner's
//! loop: PID with notch filters, dynamic-inversion feedforward and a damping loop).
pub mod absmc;
pub mod cemf;
pub mod compensated;
pub mod filtered;
pub mod ilc;
pub mod smc;

use crate::error::{check_scalar, ModelError};
use crate::num::math::{clamp, exp};

/// Internal terms a controller may record per step (unused slots are 0).
pub const MAX_TERMS: usize = 8;

/// The reference at one sample: position, velocity, acceleration (m, m/s, m/s^2).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Reference {
    /// Desired position.
    pub x: f64,
    /// Desired velocity.
    pub v: f64,
    /// Desired acceleration.
    pub a: f64,
}

/// What one controller step returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Output {
    /// Command, inside the limits (V, or m in the linearized domain behind an inverse).
    pub u: f64,
    /// Internal terms for diagnostics (meaning documented per controller).
    pub terms: [f64; MAX_TERMS],
}

/// A discrete-time controller at a fixed sample time.
pub trait Controller {
    /// Number of `f64` slots of the state.
    fn state_len(&self) -> usize;
    /// Write the state before the first step, given the first measurement `y0` (m).
    fn reset(&self, state: &mut [f64], y0: f64);
    /// One step: reference and measured position (m) in, command out. `state` has
    /// [`Controller::state_len`] slots.
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output;
    /// Names of the recorded terms, in order (at most [`MAX_TERMS`]).
    fn term_names(&self) -> &'static [&'static str];
    /// Output limits.
    fn limits(&self) -> Limits;
    /// Check a state that came from outside (a caller's buffer, possibly tampered with)
    /// before [`Controller::step`] reads it: the length, and every slot the step reads
    /// finite and in range (a NaN integrator would otherwise pin the output to a rail).
    /// The error names the slot as `state[i]`.
    fn check_state(&self, state: &[f64]) -> Result<(), ModelError> {
        crate::hysteresis::check_state_len(state, self.state_len())?;
        crate::error::check_finite("state", state)
    }
}

/// A borrowed controller is a controller (so a loop can run a `&dyn Controller`).
impl<C: Controller + ?Sized> Controller for &C {
    fn state_len(&self) -> usize {
        (**self).state_len()
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        (**self).reset(state, y0)
    }
    #[inline]
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        (**self).step(state, r, y)
    }
    fn term_names(&self) -> &'static [&'static str] {
        (**self).term_names()
    }
    fn limits(&self) -> Limits {
        (**self).limits()
    }
    fn check_state(&self, state: &[f64]) -> Result<(), ModelError> {
        (**self).check_state(state)
    }
}

/// Output range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Lowest output.
    pub min: f64,
    /// Highest output.
    pub max: f64,
}

impl Limits {
    /// Validate.
    pub fn new(min: f64, max: f64) -> Result<Self, ModelError> {
        check_scalar("u_min", min)?;
        check_scalar("u_max", max)?;
        if !(max > min) {
            return Err(ModelError::NotPositive("u_max - u_min", usize::MAX, max - min));
        }
        Ok(Limits { min, max })
    }

    /// Clamp `raw`; also say whether an integrator driven by `direction` (the sign of what
    /// it would add to the output) must hold: the output is saturated and it would deepen.
    #[inline]
    pub fn apply(&self, raw: f64, direction: f64) -> (f64, bool) {
        let hold = (raw > self.max && direction > 0.0) || (raw < self.min && direction < 0.0);
        (clamp(raw, self.min, self.max), hold)
    }
}

pub(crate) fn positive(name: &'static str, x: f64) -> Result<(), ModelError> {
    check_scalar(name, x)?;
    if !(x > 0.0) {
        return Err(ModelError::NotPositive(name, usize::MAX, x));
    }
    Ok(())
}

pub(crate) fn nonnegative(name: &'static str, x: f64) -> Result<(), ModelError> {
    check_scalar(name, x)?;
    if x < 0.0 {
        return Err(ModelError::Negative(name, usize::MAX, x));
    }
    Ok(())
}

pub(crate) fn terms<const N: usize>(values: [f64; N]) -> [f64; MAX_TERMS] {
    let mut t = [0.0; MAX_TERMS];
    t[..N].copy_from_slice(&values);
    t
}

/// Position and velocity from a quantized, noisy, delayed position reading.
///
/// A steady-state alpha–beta (constant-velocity Kalman) filter whose error dynamics have a
/// double pole at `p = exp(-2 pi bandwidth Ts)`: gains `a = 1 - p^2`, `b = (1 - p)^2`,
///
/// ```text
/// predict   x- = x + Ts v
/// correct   x  = x- + a (y - x-),   v = v + (b / Ts) (y - x-)
/// report    x + delay Ts v, v      (the reading is `delay` samples old)
/// ```
///
/// It tracks a ramp without lag (type 2) and spreads a quantization step over
/// ~1/bandwidth, so a 0.1 µm encoder at 10 kHz gives a usable velocity where the raw
/// difference would be 0 or 1 mm/s. Bandwidth trades noise for lag at turnarounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityObserver {
    /// Observer bandwidth, Hz.
    pub bandwidth: f64,
    /// Sample time, s.
    pub ts: f64,
    /// Sensor delay compensated, samples (may be fractional).
    pub delay: f64,
    gain_x: f64,
    gain_v: f64,
}

impl VelocityObserver {
    /// State slots: `[x, v]`.
    pub const STATE_LEN: usize = 2;

    /// Validate and build.
    pub fn new(bandwidth: f64, ts: f64, delay: f64) -> Result<Self, ModelError> {
        positive("observer_bandwidth", bandwidth)?;
        positive("ts", ts)?;
        nonnegative("observer_delay", delay)?;
        if bandwidth >= 0.5 / ts {
            return Err(ModelError::OutOfRange(
                "observer_bandwidth (below Nyquist)",
                usize::MAX,
                bandwidth,
                0.0,
                0.5 / ts,
            ));
        }
        let p = exp(-2.0 * core::f64::consts::PI * bandwidth * ts);
        Ok(VelocityObserver { bandwidth, ts, delay, gain_x: 1.0 - p * p, gain_v: (1.0 - p) * (1.0 - p) / ts })
    }

    /// Start at rest at `y0`.
    pub fn reset(&self, state: &mut [f64], y0: f64) {
        state[0] = y0;
        state[1] = 0.0;
    }

    /// Take a reading; return the current `(position, velocity)` estimate.
    #[inline]
    pub fn update(&self, state: &mut [f64], y: f64) -> (f64, f64) {
        let predicted = state[0] + self.ts * state[1];
        let innovation = y - predicted;
        state[0] = predicted + self.gain_x * innovation;
        state[1] += self.gain_v * innovation;
        (state[0] + self.delay * self.ts * state[1], state[1])
    }
}

/// Open loop with dynamic feedforward:
/// `u = offset + gain (x_d + c1 x_d' + c2 x_d'')`, saturated.
///
/// With `c1 = c2 = 0` it is a static inverse; with `c1 = B/K`, `c2 = M/K` it inverts a
/// second-order stage `M x'' + B x' + K x = u / gain`. Behind a hysteresis inverse
/// ([`crate::control::compensated::Compensated`]) with `gain = 1` it is the inverse feedforward.
/// Terms: `[u_unsaturated]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenLoop {
    /// Static inverse gain (V/m, or 1 in the linearized domain).
    pub gain: f64,
    /// Output offset.
    pub offset: f64,
    /// Velocity feedforward time constant `c1`, s.
    pub c1: f64,
    /// Acceleration feedforward coefficient `c2`, s^2.
    pub c2: f64,
    /// Output limits.
    pub limits: Limits,
}

impl OpenLoop {
    /// Validate and build.
    pub fn new(gain: f64, offset: f64, c1: f64, c2: f64, limits: Limits) -> Result<Self, ModelError> {
        check_scalar("gain", gain)?;
        check_scalar("offset", offset)?;
        check_scalar("c1", c1)?;
        check_scalar("c2", c2)?;
        Ok(OpenLoop { gain, offset, c1, c2, limits })
    }
}

impl Controller for OpenLoop {
    fn state_len(&self) -> usize {
        0
    }
    fn reset(&self, _state: &mut [f64], _y0: f64) {}
    #[inline]
    fn step(&self, _state: &mut [f64], r: &Reference, _y: f64) -> Output {
        let raw = self.offset + self.gain * (r.x + self.c1 * r.v + self.c2 * r.a);
        Output { u: clamp(raw, self.limits.min, self.limits.max), terms: terms([raw]) }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["u_unsaturated"]
    }
    fn limits(&self) -> Limits {
        self.limits
    }
}

/// PID with static feedforward, derivative on the measurement through a first-order
/// filter (backward Euler, time constant `tau_d`), and conditional-integration anti-windup
/// (the integrator holds while the output is saturated and the error would deepen it).
/// Build it from a [`PidConfig`] with [`Pid::new`] (it derives the filter coefficients).
///
/// `u = offset + ff_gain x_d + kp e + I + D`, `e = x_d - y`,
/// `I += ki Ts e`, `D = a D - kd (1 - a) (y - y_prev) / Ts`, `a = tau_d / (tau_d + Ts)`.
/// State `[I, D, y_prev]`. Terms: `[P, I, D, feedforward, u_unsaturated]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pid {
    config: PidConfig,
    /// Derivative filter pole `tau_d / (tau_d + Ts)`.
    filter: f64,
    /// `kd (1 - filter) / Ts`.
    derivative_gain: f64,
}

/// Gains, sample time and limits of a [`Pid`], as a struct literal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidConfig {
    /// Proportional gain, V/m.
    pub kp: f64,
    /// Integral gain, V/(m s).
    pub ki: f64,
    /// Derivative gain, V s/m.
    pub kd: f64,
    /// Derivative filter time constant, s (> 0).
    pub tau_d: f64,
    /// Sample time, s.
    pub ts: f64,
    /// Feedforward gain on the reference, V/m.
    pub ff_gain: f64,
    /// Voltage offset, V.
    pub offset: f64,
    /// Output limits.
    pub limits: Limits,
}

impl Pid {
    /// Validate and build.
    pub fn new(config: PidConfig) -> Result<Self, ModelError> {
        let PidConfig { kp, ki, kd, tau_d, ts, ff_gain, offset, .. } = config;
        for (n, x) in [("kp", kp), ("ki", ki), ("kd", kd)] {
            nonnegative(n, x)?;
        }
        check_scalar("ff_gain", ff_gain)?;
        check_scalar("offset", offset)?;
        positive("tau_d", tau_d)?;
        positive("ts", ts)?;
        let filter = tau_d / (tau_d + ts);
        Ok(Pid { config, filter, derivative_gain: kd * (1.0 - filter) / ts })
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &PidConfig {
        &self.config
    }
}

impl Controller for Pid {
    fn state_len(&self) -> usize {
        3
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        state.copy_from_slice(&[0.0, 0.0, y0]);
    }
    #[inline]
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        let c = &self.config;
        let e = r.x - y;
        state[1] = self.filter * state[1] - self.derivative_gain * (y - state[2]);
        state[2] = y;
        let p = c.kp * e;
        let ff = c.offset + c.ff_gain * r.x;
        let candidate = state[0] + c.ki * c.ts * e;
        let (_, hold) = c.limits.apply(ff + p + candidate + state[1], e);
        if !hold {
            state[0] = candidate;
        }
        let raw = ff + p + state[0] + state[1];
        Output { u: clamp(raw, c.limits.min, c.limits.max), terms: terms([p, state[0], state[1], ff, raw]) }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["P", "I", "D", "feedforward", "u_unsaturated"]
    }
    fn limits(&self) -> Limits {
        self.config.limits
    }
}

pub(crate) fn check_positive_count(name: &'static str, n: usize, max: usize) -> Result<(), ModelError> {
    if n == 0 || n > max {
        return Err(ModelError::Structure(name, n));
    }
    Ok(())
}
