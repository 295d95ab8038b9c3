//! Rate-dependent PI model (docs/spec.md §2.3).
//!
//! ```text
//! rate(k) = rate(k-1) + a (|v(k) - v(k-1)| / Ts - rate(k-1)),  a = 1 - exp(-Ts/tau_f)
//! r_i(k)  = r_i + beta * rate(k)            (dynamic thresholds, Al Janaideh et al. 2008)
//! w_i(k)  = w_i + c_i  * rate(k)            (rate-dependent weights, Ang et al. 2007)
//! y(k)    = p0 v(k) + sum_i w_i(k) * play_{r_i(k)}(k)
//! ```
//! `|dv/dt|` is the backward difference of the input; `tau_f = 0` disables the low-pass
//! (a = 1). At the first sample after reset the rate is taken as 0 (no previous input).
//!
//! State layout: `[z_1 .. z_n, v_prev, rate, started]`.
use crate::error::{check_finite, check_scalar, check_thresholds, ModelError};
use crate::hysteresis::{Hysteresis, Invertible};
use crate::num::math::{abs, clamp, exp, sign};

/// Rate-dependent PI configuration.
#[derive(Debug, Clone, Copy)]
pub struct RateDependentPi<'a> {
    /// Sample time, s.
    pub ts: f64,
    /// Linear weight.
    pub p0: f64,
    /// Threshold growth per unit input rate, s (input units per (input units / s)).
    pub beta: f64,
    /// Derivative low-pass gain `a = 1 - exp(-Ts/tau_f)` in (0, 1].
    pub filter_gain: f64,
    /// Static thresholds `r_i`.
    pub thresholds: &'a [f64],
    /// Static weights `w_i`.
    pub weights: &'a [f64],
    /// Weight growth per unit input rate `c_i`.
    pub rate_weights: &'a [f64],
}

impl<'a> RateDependentPi<'a> {
    /// Validate and build; `filter_tau = 0` means no derivative filter.
    pub fn new(
        ts: f64,
        p0: f64,
        beta: f64,
        filter_tau: f64,
        thresholds: &'a [f64],
        weights: &'a [f64],
        rate_weights: &'a [f64],
    ) -> Result<Self, ModelError> {
        check_scalar("ts", ts)?;
        if !(ts > 0.0) {
            return Err(ModelError::NotPositive("ts", usize::MAX, ts));
        }
        check_scalar("p0", p0)?;
        check_scalar("beta", beta)?;
        if beta < 0.0 {
            return Err(ModelError::Negative("beta", usize::MAX, beta));
        }
        check_scalar("filter_tau", filter_tau)?;
        if filter_tau < 0.0 {
            return Err(ModelError::Negative("filter_tau", usize::MAX, filter_tau));
        }
        check_thresholds("thresholds", thresholds)?;
        let n = thresholds.len();
        if weights.len() != n {
            return Err(ModelError::Length("weights", n, weights.len()));
        }
        if rate_weights.len() != n {
            return Err(ModelError::Length("rate_weights", n, rate_weights.len()));
        }
        check_finite("weights", weights)?;
        check_finite("rate_weights", rate_weights)?;
        let filter_gain = if filter_tau == 0.0 { 1.0 } else { 1.0 - exp(-ts / filter_tau) };
        Ok(RateDependentPi { ts, p0, beta, filter_gain, thresholds, weights, rate_weights })
    }

    #[inline(always)]
    fn rate(&self, state: &[f64], v: f64) -> (f64, f64) {
        let n = self.thresholds.len();
        let (v_prev, rate_prev, started) = (state[n], state[n + 1], state[n + 2]);
        if started == 0.0 {
            return (0.0, 0.0);
        }
        let a = self.filter_gain;
        let raw = abs(v - v_prev) / self.ts;
        (rate_prev + a * (raw - rate_prev), a * sign(v - v_prev) / self.ts)
    }
}

impl Hysteresis for RateDependentPi<'_> {
    fn state_len(&self) -> usize {
        self.thresholds.len() + 3
    }
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let n = self.thresholds.len();
        let (rate, _) = self.rate(state, v);
        let mut y = self.p0 * v;
        let operators = self.thresholds.iter().zip(self.weights).zip(self.rate_weights);
        for (z, ((&r0, &w0), &c)) in state[..n].iter_mut().zip(operators) {
            let r = r0 + self.beta * rate;
            let w = w0 + c * rate;
            *z = clamp(*z, v - r, v + r);
            y += w * *z;
        }
        state[n] = v;
        state[n + 1] = rate;
        state[n + 2] = 1.0;
        y
    }
}

impl Invertible for RateDependentPi<'_> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let n = self.thresholds.len();
        let (rate, drate) = self.rate(state, v);
        let mut y = self.p0 * v;
        let mut dy = self.p0;
        let operators = self.thresholds.iter().zip(self.weights).zip(self.rate_weights);
        for (&z0, ((&r0, &w0), &c)) in state[..n].iter().zip(operators) {
            let r = r0 + self.beta * rate;
            let w = w0 + c * rate;
            let z = clamp(z0, v - r, v + r);
            y += w * z;
            let dz = if v + r < z0 {
                1.0 + self.beta * drate
            } else if v - r > z0 {
                1.0 - self.beta * drate
            } else {
                0.0
            };
            dy += c * drate * z + w * dz;
        }
        (y, dy)
    }
}
