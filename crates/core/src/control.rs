//! Controllers: the interface every controller implements, and the baselines (open loop,
//! PID). Configuration is separate from state; a step never allocates; the output voltage
//! is always inside the limits, with anti-windup where there is an integrator.
use crate::error::{check_scalar, ModelError};
use crate::math::clamp;

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
    /// Voltage command, inside the limits.
    pub u: f64,
    /// Internal terms for diagnostics (meaning documented per controller).
    pub terms: [f64; MAX_TERMS],
}

/// A discrete-time controller at a fixed sample time.
pub trait Controller {
    /// Mutable state.
    type State: Copy;
    /// State before the first step, given the first measurement.
    fn initial_state(&self, y0: f64) -> Self::State;
    /// One step: reference and measured position (m) in, voltage out.
    fn step(&self, st: &mut Self::State, r: &Reference, y: f64) -> Output;
    /// Names of the recorded terms, in order.
    fn term_names(&self) -> &'static [&'static str];
}

/// Output voltage range, V.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Lowest voltage.
    pub min: f64,
    /// Highest voltage.
    pub max: f64,
}

impl Limits {
    /// Validate.
    pub fn new(min: f64, max: f64) -> Result<Self, ModelError> {
        check_scalar("u_min", min)?;
        check_scalar("u_max", max)?;
        if !(max > min) {
            return Err(ModelError::NotIncreasing("u_max (must exceed u_min)", usize::MAX, max));
        }
        Ok(Limits { min, max })
    }
}

/// Open loop: `u = offset + gain * x_d`, saturated. Terms: `[u_unsaturated]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenLoop {
    /// Static inverse gain, V/m.
    pub gain: f64,
    /// Voltage offset, V.
    pub offset: f64,
    /// Output limits.
    pub limits: Limits,
}

impl Controller for OpenLoop {
    type State = ();
    fn initial_state(&self, _y0: f64) {}
    fn step(&self, _st: &mut (), r: &Reference, _y: f64) -> Output {
        let raw = self.offset + self.gain * r.x;
        let mut terms = [0.0; MAX_TERMS];
        terms[0] = raw;
        Output { u: clamp(raw, self.limits.min, self.limits.max), terms }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["u_unsaturated"]
    }
}

/// PID with static feedforward, derivative on the measurement through a first-order
/// filter (backward Euler, time constant `tau_d`), and conditional-integration anti-windup
/// (the integrator holds while the output is saturated and the error would deepen it).
/// Build it with [`Pid::new`] (it derives the filter coefficients).
///
/// `u = offset + ff_gain x_d + kp e + I + D`, `e = x_d - y`,
/// `I += ki Ts e`, `D = a D - kd (1 - a) (y - y_prev) / Ts`, `a = tau_d / (tau_d + Ts)`.
/// Terms: `[P, I, D, feedforward, u_unsaturated]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pid {
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
    /// Derivative filter pole `tau_d / (tau_d + Ts)` (derived).
    filter: f64,
    /// `kd (1 - filter) / Ts` (derived).
    derivative_gain: f64,
}

/// PID state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidState {
    /// Integrator, V.
    pub integral: f64,
    /// Filtered derivative term, V.
    pub derivative: f64,
    /// Previous measurement, m.
    pub y_prev: f64,
}

impl Pid {
    /// Validate and build.
    #[allow(clippy::too_many_arguments)]
    pub fn new(kp: f64, ki: f64, kd: f64, tau_d: f64, ts: f64, ff_gain: f64, offset: f64, limits: Limits) -> Result<Self, ModelError> {
        for (n, x) in [("kp", kp), ("ki", ki), ("kd", kd), ("ff_gain", ff_gain), ("offset", offset)] {
            check_scalar(n, x)?;
        }
        for (n, x) in [("kp", kp), ("ki", ki), ("kd", kd)] {
            if x < 0.0 {
                return Err(ModelError::Negative(n, usize::MAX, x));
            }
        }
        for (n, x) in [("tau_d", tau_d), ("ts", ts)] {
            check_scalar(n, x)?;
            if !(x > 0.0) {
                return Err(ModelError::NotPositive(n, usize::MAX, x));
            }
        }
        let filter = tau_d / (tau_d + ts);
        Ok(Pid { kp, ki, kd, tau_d, ts, ff_gain, offset, limits, filter, derivative_gain: kd * (1.0 - filter) / ts })
    }
}

impl Controller for Pid {
    type State = PidState;
    fn initial_state(&self, y0: f64) -> PidState {
        PidState { integral: 0.0, derivative: 0.0, y_prev: y0 }
    }
    fn step(&self, st: &mut PidState, r: &Reference, y: f64) -> Output {
        let e = r.x - y;
        st.derivative = self.filter * st.derivative - self.derivative_gain * (y - st.y_prev);
        st.y_prev = y;
        let p = self.kp * e;
        let ff = self.offset + self.ff_gain * r.x;
        let candidate = st.integral + self.ki * self.ts * e;
        let raw = ff + p + candidate + st.derivative;
        let deepening = (raw > self.limits.max && e > 0.0) || (raw < self.limits.min && e < 0.0);
        if !deepening {
            st.integral = candidate;
        }
        let raw = ff + p + st.integral + st.derivative;
        let mut terms = [0.0; MAX_TERMS];
        terms[..5].copy_from_slice(&[p, st.integral, st.derivative, ff, raw]);
        Output { u: clamp(raw, self.limits.min, self.limits.max), terms }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["P", "I", "D", "feedforward", "u_unsaturated"]
    }
}
