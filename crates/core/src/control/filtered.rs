//! The practitioner's loop (issue 19): a PID with notch filters on its output, a feedforward
//! that inverts identified dynamics, and a damping loop on the measurement.
//!
//! ```text
//! ff  = ff_gain F1 F2 [x_d] + c1 x_d' + c2 x_d''          feedforward: two biquads on the
//!                                                         reference, and derivative lead
//! e   = x_d(t - delay) - y                              the reference delayed as the reading is
//!     ~ x_d - delay x_d' + delay^2 / 2 x_d'' - y
//! pid = kp e + I + D,  I += ki Ts e,  D = a D - kd (1 - a) (y - y_prev) / Ts
//! fb  = N3 N2 N1 [pid]                                    notch filters (up to three biquads)
//! dmp = H [y]                                             damping loop (a biquad on the reading:
//!                                                         positive position feedback, PPF)
//! u   = sat(offset + ff + fb + dmp)
//! ```
//!
//! Every filter is a biquad `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)` in direct form
//! II transposed; the identity `[1, 0, 0, 0, 0]` is no filter. The designs (notch, low-pass,
//! lag-lead, PPF) are the Python package's (`piezohyst.control.filters`), discretized by the
//! bilinear transform with the frequency of interest prewarped. The integrator holds while the
//! output is saturated in the direction the error would push it (conditional integration).
//! State `[I, D, y_prev, ff1(2), ff2(2), notch1(2), notch2(2), notch3(2), damping(2)]`.
//! Terms: `[P, I, D, feedforward, feedback, damping, u_unsaturated]`.
use crate::control::{nonnegative, positive, terms, Controller, Limits, Output, Reference};
use crate::error::{check_scalar, ModelError};
use crate::num::math::clamp;

/// Notch filters a [`FilteredPid`] can have.
pub const MAX_NOTCHES: usize = 3;

/// A biquad `[b0, b1, b2, a1, a2]` (`a0 = 1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad(pub [f64; 5]);

impl Biquad {
    /// No filter.
    pub const IDENTITY: Biquad = Biquad([1.0, 0.0, 0.0, 0.0, 0.0]);

    /// Finite coefficients and poles inside the unit circle (the Jury conditions for
    /// `z^2 + a1 z + a2`: `|a2| < 1`, `|a1| < 1 + a2`).
    pub fn validated(self, name: &'static str) -> Result<Self, ModelError> {
        for (i, &c) in self.0.iter().enumerate() {
            if !c.is_finite() {
                return Err(ModelError::NotFinite(name, i, c));
            }
        }
        let [_, _, _, a1, a2] = self.0;
        if !(a2.abs() < 1.0 && a1.abs() < 1.0 + a2) {
            return Err(ModelError::OutOfRange(name, 3, a1, -1.0 - a2, 1.0 + a2));
        }
        Ok(self)
    }

    /// Whether it is the identity (skipped).
    #[inline(always)]
    fn is_identity(&self) -> bool {
        self.0 == Self::IDENTITY.0
    }

    /// One sample through the filter with state `s` (two slots).
    #[inline(always)]
    fn step(&self, s: &mut [f64], x: f64) -> f64 {
        let [b0, b1, b2, a1, a2] = self.0;
        let y = b0 * x + s[0];
        s[0] = b1 * x - a1 * y + s[1];
        s[1] = b2 * x - a2 * y;
        y
    }

    /// The state of a filter at rest with input and output held at `x` and `y` (`y = x dc`).
    fn rest(&self, s: &mut [f64], x: f64) {
        let [b0, b1, b2, a1, a2] = self.0;
        let den = 1.0 + a1 + a2;
        let y = if den != 0.0 { x * (b0 + b1 + b2) / den } else { 0.0 };
        s[1] = b2 * x - a2 * y;
        s[0] = b1 * x - a1 * y + s[1];
    }
}

/// Gains, filters, sample time and limits of a [`FilteredPid`], as a struct literal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilteredPidConfig {
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain, per second.
    pub ki: f64,
    /// Derivative gain, seconds.
    pub kd: f64,
    /// Derivative filter time constant, s (> 0).
    pub tau_d: f64,
    /// Sample time, s.
    pub ts: f64,
    /// Feedforward gain on the (filtered) reference.
    pub ff_gain: f64,
    /// Velocity feedforward, s.
    pub c1: f64,
    /// Acceleration feedforward, s^2.
    pub c2: f64,
    /// Output offset.
    pub offset: f64,
    /// The reading's delay, s: the error compares the reading with the reference that long
    /// ago (second-order Taylor from the reference's derivatives), not with the reference now.
    pub error_delay: f64,
    /// Feedforward filters on the reference.
    pub ff_filters: [Biquad; 2],
    /// Notch filters on the PID's output.
    pub notches: [Biquad; MAX_NOTCHES],
    /// Damping loop on the reading (added to the output).
    pub damping: Biquad,
    /// Output limits.
    pub limits: Limits,
}

/// The practitioner's loop (see the module notes): a validated [`FilteredPidConfig`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilteredPid {
    config: FilteredPidConfig,
    /// Derivative filter pole `tau_d / (tau_d + Ts)`.
    filter: f64,
    /// `kd (1 - filter) / Ts`.
    derivative_gain: f64,
    /// No notch filter: the output is summed as `control::Pid` sums it.
    plain: bool,
}

// state slots
const I: usize = 0;
const D: usize = 1;
const Y_PREV: usize = 2;
const FF: usize = 3;
const NOTCH: usize = FF + 4;
const DAMP: usize = NOTCH + 2 * MAX_NOTCHES;
const LEN: usize = DAMP + 2;

impl FilteredPid {
    /// Validate and build.
    pub fn new(config: FilteredPidConfig) -> Result<Self, ModelError> {
        let c = &config;
        for (n, x) in [("kp", c.kp), ("ki", c.ki), ("kd", c.kd)] {
            nonnegative(n, x)?;
        }
        for (n, x) in [("ff_gain", c.ff_gain), ("c1", c.c1), ("c2", c.c2), ("offset", c.offset)] {
            check_scalar(n, x)?;
        }
        nonnegative("error_delay", c.error_delay)?;
        positive("tau_d", c.tau_d)?;
        positive("ts", c.ts)?;
        for f in &c.ff_filters {
            f.validated("ff_filter")?;
        }
        for f in &c.notches {
            f.validated("notch")?;
        }
        c.damping.validated("damping")?;
        let filter = c.tau_d / (c.tau_d + c.ts);
        let plain = c.notches.iter().all(Biquad::is_identity);
        Ok(FilteredPid { config, filter, derivative_gain: c.kd * (1.0 - filter) / c.ts, plain })
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &FilteredPidConfig {
        &self.config
    }
}

impl Controller for FilteredPid {
    fn state_len(&self) -> usize {
        LEN
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        state.fill(0.0);
        state[Y_PREV] = y0;
        // the feedforward filters at rest at y0 (the reference is where the stage is);
        // the damping loop at rest at y0 (its output then is its static gain times y0)
        let c = &self.config;
        let mut x = y0;
        for (j, f) in c.ff_filters.iter().enumerate() {
            f.rest(&mut state[FF + 2 * j..FF + 2 * j + 2], x);
            let den = 1.0 + f.0[3] + f.0[4];
            x = if den != 0.0 { x * (f.0[0] + f.0[1] + f.0[2]) / den } else { 0.0 };
        }
        c.damping.rest(&mut state[DAMP..DAMP + 2], y0);
    }
    #[inline]
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        let c = &self.config;
        // feedforward
        let mut xf = r.x;
        for (j, f) in c.ff_filters.iter().enumerate() {
            if !f.is_identity() {
                xf = f.step(&mut state[FF + 2 * j..FF + 2 * j + 2], xf);
            }
        }
        let ff = c.offset + c.ff_gain * xf + c.c1 * r.v + c.c2 * r.a;
        // feedback
        let e = if c.error_delay == 0.0 {
            r.x - y
        } else {
            let d = c.error_delay;
            (r.x - d * r.v + 0.5 * d * d * r.a) - y
        };
        state[D] = self.filter * state[D] - self.derivative_gain * (y - state[Y_PREV]);
        state[Y_PREV] = y;
        let p = c.kp * e;
        let damping = if c.damping.is_identity() { 0.0 } else { c.damping.step(&mut state[DAMP..DAMP + 2], y) };
        let candidate = state[I] + c.ki * c.ts * e;
        if self.plain {
            // ((ff + P) + I) + D, as control::Pid sums it
            let (_, hold) = c.limits.apply(ff + p + candidate + state[D] + damping, e);
            if !hold {
                state[I] = candidate;
            }
            let raw = ff + p + state[I] + state[D] + damping;
            return Output {
                u: clamp(raw, c.limits.min, c.limits.max),
                terms: terms([p, state[I], state[D], ff, p + state[I] + state[D], damping, raw]),
            };
        }
        let notched = |state: &mut [f64], pid: f64| {
            let mut v = pid;
            for (j, f) in c.notches.iter().enumerate() {
                if !f.is_identity() {
                    v = f.step(&mut state[NOTCH + 2 * j..NOTCH + 2 * j + 2], v);
                }
            }
            v
        };
        // conditional integration: judge the candidate through a copy of the notch states,
        // keep it only if it does not deepen a saturation
        let mut scratch = [0.0; LEN];
        scratch[NOTCH..DAMP].copy_from_slice(&state[NOTCH..DAMP]);
        let fb_candidate = notched(&mut scratch, p + candidate + state[D]);
        let (_, hold) = c.limits.apply(ff + fb_candidate + damping, e);
        if !hold {
            state[I] = candidate;
        }
        let fb = notched(state, p + state[I] + state[D]);
        let raw = ff + fb + damping;
        Output {
            u: clamp(raw, c.limits.min, c.limits.max),
            terms: terms([p, state[I], state[D], ff, fb, damping, raw]),
        }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["P", "I", "D", "feedforward", "feedback", "damping", "u_unsaturated"]
    }
    fn limits(&self) -> Limits {
        self.config.limits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> FilteredPidConfig {
        FilteredPidConfig {
            kp: 0.0,
            ki: 0.0,
            kd: 0.0,
            tau_d: 1e-4,
            ts: 1e-4,
            ff_gain: 1.0,
            c1: 0.0,
            c2: 0.0,
            offset: 0.0,
            error_delay: 0.0,
            ff_filters: [Biquad::IDENTITY; 2],
            notches: [Biquad::IDENTITY; MAX_NOTCHES],
            damping: Biquad::IDENTITY,
            limits: Limits::new(-1e3, 1e3).unwrap(),
        }
    }

    /// Without filters it is the PID of `control::Pid` (same law, same anti-windup), to the
    /// bit, saturating or not.
    #[test]
    fn without_filters_it_is_the_pid() {
        use crate::control::{Pid, PidConfig};
        let limits = Limits::new(-20.0, 150.0).unwrap();
        let (kp, ki, kd, tau_d, ts, ff_gain, offset) = (3e4, 1e9, 2.0, 2e-4, 1e-4, 7e6, 1.5);
        let pid = Pid::new(PidConfig { kp, ki, kd, tau_d, ts, ff_gain, offset, limits }).unwrap();
        let f =
            FilteredPid::new(FilteredPidConfig { kp, ki, kd, tau_d, ts, ff_gain, offset, limits, ..config() }).unwrap();
        let (mut a, mut b) = ([0.0; 3], [0.0; LEN]);
        pid.reset(&mut a, 1e-6);
        f.reset(&mut b, 1e-6);
        for k in 0..5000 {
            let t = k as f64 * ts;
            let r = Reference { x: 10e-6 + 12e-6 * libm::sin(60.0 * t), v: 0.0, a: 0.0 };
            let y = 10e-6 + 11e-6 * libm::sin(60.0 * t - 0.3);
            let (oa, ob) = (pid.step(&mut a, &r, y), f.step(&mut b, &r, y));
            assert_eq!(oa.u.to_bits(), ob.u.to_bits(), "{k}");
        }
    }

    /// A notch at 1 kHz removes a 1 kHz component of the PID's output and passes 100 Hz; a
    /// feedforward biquad's DC gain scales the reference; the damping loop adds `H[y]`.
    #[test]
    fn notch_feedforward_and_damping() {
        let ts = 1e-5;
        // notch at 1 kHz, depth 0 (zeros on the circle), width zeta 0.3: bilinear, prewarped
        let w = 2.0 * libm::tan(core::f64::consts::PI * 1000.0 * ts) / ts;
        let (z, wt) = (0.3, w * ts);
        let k = 2.0 / ts;
        let a0 = k * k + 2.0 * z * w * k + w * w;
        let notch = Biquad([
            (k * k + w * w) / a0,
            (2.0 * w * w - 2.0 * k * k) / a0,
            (k * k + w * w) / a0,
            (2.0 * w * w - 2.0 * k * k) / a0,
            (k * k - 2.0 * z * w * k + w * w) / a0,
        ]);
        assert!(wt > 0.0);
        let mut cfg = config();
        cfg.ts = ts;
        cfg.kp = 1.0;
        cfg.ff_gain = 0.0;
        cfg.notches[1] = notch;
        let f = FilteredPid::new(cfg).unwrap();
        let amplitude = |freq: f64| {
            let mut s = [0.0; LEN];
            f.reset(&mut s, 0.0);
            let mut peak: f64 = 0.0;
            for n in 0..20_000 {
                let e = libm::sin(2.0 * core::f64::consts::PI * freq * n as f64 * ts);
                let out = f.step(&mut s, &Reference { x: e, v: 0.0, a: 0.0 }, 0.0);
                if n > 10_000 {
                    peak = peak.max(out.u.abs());
                }
            }
            peak
        };
        assert!(amplitude(1000.0) < 1e-3, "{}", amplitude(1000.0));
        assert!((amplitude(100.0) - 1.0).abs() < 0.02, "{}", amplitude(100.0));
        // feedforward: a biquad with DC gain 2 (b = [2, 0, 0], no poles)
        let mut cfg = config();
        cfg.ff_filters[0] = Biquad([2.0, 0.0, 0.0, 0.0, 0.0]);
        cfg.damping = Biquad([0.5, 0.0, 0.0, 0.0, 0.0]);
        let f = FilteredPid::new(cfg).unwrap();
        let mut s = [0.0; LEN];
        f.reset(&mut s, 0.0);
        let out = f.step(&mut s, &Reference { x: 3.0, v: 0.0, a: 0.0 }, 4.0);
        assert_eq!(out.terms[3], 6.0);
        assert_eq!(out.terms[5], 2.0);
        assert_eq!(out.u, 8.0);
    }

    /// Saturated, the integrator holds: back from saturation the output is not wound up.
    #[test]
    fn the_integrator_holds_while_saturated() {
        let mut cfg = config();
        cfg.ki = 1e4;
        cfg.ff_gain = 0.0;
        cfg.limits = Limits::new(-1.0, 1.0).unwrap();
        let f = FilteredPid::new(cfg).unwrap();
        let mut s = [0.0; LEN];
        f.reset(&mut s, 0.0);
        for _ in 0..10_000 {
            f.step(&mut s, &Reference { x: 1.0, v: 0.0, a: 0.0 }, 0.0);
        }
        // it stopped one step past the limit (a wound-up one would be at 10_000)
        assert!(s[I] <= 1.0 + 1e4 * 1e-4, "{}", s[I]);
        let mut out = f.step(&mut s, &Reference { x: -1.0, v: 0.0, a: 0.0 }, 0.0);
        for _ in 0..2 {
            out = f.step(&mut s, &Reference { x: -1.0, v: 0.0, a: 0.0 }, 0.0);
        }
        assert!(out.u < 0.0, "{}", out.u);
    }

    #[test]
    fn unstable_filters_are_refused() {
        let mut cfg = config();
        cfg.notches[0] = Biquad([1.0, 0.0, 0.0, 0.0, 1.0]);
        assert!(matches!(FilteredPid::new(cfg), Err(ModelError::OutOfRange("notch", 3, _, _, _))));
        let mut cfg = config();
        cfg.damping = Biquad([1.0, f64::NAN, 0.0, 0.0, 0.0]);
        assert!(matches!(FilteredPid::new(cfg), Err(ModelError::NotFinite("damping", 1, _))));
    }
}
