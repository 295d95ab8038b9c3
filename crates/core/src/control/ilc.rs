//! Iterative learning control for periodic references (beyond the seeds, docs/spec.md §5): a
//! correction learned from the error of previous periods is added to any controller's
//! output. Scanning stages repeat the same trajectory, so the error that repeats (the
//! unmodelled hysteresis and dynamics) is learned away period by period.
//!
//! ```text
//! u(k)  = sat(u_inner(k) + Q(L)[k mod N])
//! L[i] <- Q(L)[i] + gain e(k),   i = (k - lead) mod N
//! Q(L)[i] = q (L[i-1] + 2 L[i] + L[i+1]) / 4
//! ```
//! The correction applied is always the filtered one, so both the memory and each newly
//! learned error pass through `Q` before they act (learning the raw error at every
//! frequency lets the stage resonance grow period by period).
//! `e(k) = reference(k - delay) - y(k)`, with the reading `delay` samples old; `lead`
//! (>= `delay` + 1) is the learning shift that matches the plant's delay and lag; `q <= 1`
//! with the three-tap smoothing is the Q-filter that keeps high frequencies from being
//! learned. Learning holds while the output is saturated in the direction it would push.
use crate::control::{check_positive_count, nonnegative, terms, Controller, Limits, Output, Reference};
use crate::error::{check_scalar, ModelError};
use crate::num::math::clamp;

/// Learning on top of controller `C`.
#[derive(Debug, Clone, Copy)]
pub struct Ilc<C> {
    /// The controller whose output is corrected.
    pub inner: C,
    /// Samples per period `N`.
    pub period: usize,
    /// Learning gain (output units per metre).
    pub gain: f64,
    /// Forgetting factor `q` in `(0, 1]`.
    pub forgetting: f64,
    /// Learning shift, samples.
    pub lead: usize,
    /// Sensor delay, samples.
    pub delay: usize,
}

/// Longest learnable period, samples (10 s at 100 kHz).
pub const MAX_PERIOD: usize = 1_000_000;

impl<C: Controller> Ilc<C> {
    /// Validate and build.
    pub fn new(
        inner: C,
        period: usize,
        gain: f64,
        forgetting: f64,
        lead: usize,
        delay: usize,
    ) -> Result<Self, ModelError> {
        check_positive_count("period", period, MAX_PERIOD)?;
        nonnegative("gain", gain)?;
        check_scalar("forgetting", forgetting)?;
        if !(forgetting > 0.0 && forgetting <= 1.0) {
            return Err(ModelError::OutOfRange("forgetting", usize::MAX, forgetting, 0.0, 1.0));
        }
        if lead >= period || delay >= period {
            return Err(ModelError::Structure("lead and delay (must be below the period)", lead.max(delay)));
        }
        Ok(Ilc { inner, period, gain, forgetting, lead, delay })
    }
}

impl<C: Controller> Controller for Ilc<C> {
    /// Inner state, sample counter, learned correction `[N]`, reference history `[N]`.
    fn state_len(&self) -> usize {
        self.inner.state_len() + 1 + 2 * self.period
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        let a = self.inner.state_len();
        self.inner.reset(&mut state[..a], y0);
        state[a..].fill(0.0);
        state[a + 1 + self.period..].fill(y0);
    }
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        let a = self.inner.state_len();
        let n = self.period;
        let (inner, rest) = state.split_at_mut(a);
        let (counter, rest) = rest.split_at_mut(1);
        let (learned, history) = rest.split_at_mut(n);
        let k = counter[0] as usize; // exact: counts stay far below 2^53
        let now = k % n;
        history[now] = r.x;
        let out = self.inner.step(inner, r, y);
        let q = |l: &[f64], i: usize| self.forgetting * 0.25 * (l[(i + n - 1) % n] + 2.0 * l[i] + l[(i + 1) % n]);
        let correction = q(learned, now);
        let raw = out.u + correction;
        let limits = self.inner.limits();
        let e = history[(now + n - self.delay) % n] - y;
        let (u, hold) = limits.apply(raw, e);
        // learn once the delayed reference is known
        if !hold && k >= self.delay {
            let i = (now + n - self.lead) % n;
            learned[i] = q(learned, i) + self.gain * e;
        }
        counter[0] += 1.0;
        Output { u: clamp(u, limits.min, limits.max), terms: terms([correction, e, out.u, raw]) }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["learned", "error", "u_inner", "u_unsaturated"]
    }
    /// The inner state, the sample counter (a whole number `0 ..= 2^53`) and the learned
    /// and reference slots this step reads (checking all `2 period` each step would cost
    /// a real-time loop more than the step).
    fn check_state(&self, state: &[f64]) -> Result<(), ModelError> {
        crate::hysteresis::check_state_len(state, self.state_len())?;
        let a = self.inner.state_len();
        let n = self.period;
        self.inner.check_state(&state[..a])?;
        let k = state[a];
        if !((0.0..=9_007_199_254_740_992.0).contains(&k) && k == libm::trunc(k)) {
            return Err(ModelError::OutOfRange("state (sample counter)", a, k, 0.0, 9_007_199_254_740_992.0));
        }
        let now = k as usize % n;
        let learned = a + 1;
        let history = a + 1 + n;
        let back = |i: usize, by: usize| (i + n - by) % n;
        let learn_at = back(now, self.lead);
        let slots = [
            learned + back(now, 1),
            learned + now,
            learned + (now + 1) % n,
            learned + back(learn_at, 1),
            learned + learn_at,
            learned + (learn_at + 1) % n,
            history + back(now, self.delay),
        ];
        for i in slots {
            if !state[i].is_finite() {
                return Err(ModelError::NotFinite("state", i, state[i]));
            }
        }
        Ok(())
    }
    fn limits(&self) -> Limits {
        self.inner.limits()
    }
}
