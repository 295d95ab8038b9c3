//! A controller behind an inverse hysteresis model (docs/spec.md §5: inverse feedforward, and
//! feedback "in the linearized domain"). The inner controller outputs a desired actuator
//! displacement `w`; the exact per-sample inverse of the identified model finds the voltage
//! `u` with `model(u) = w` (docs/spec.md §2.1), saturated to the amplifier, and the model state is
//! advanced with the voltage actually applied, so the inverse never drifts from it.
//!
//! The inner controller's limits are in displacement: give it the model's outputs at the
//! amplifier limits (for rate-independent models with wiping-out these are the extremes of
//! the major loop, reached from any history), so its anti-windup sees the saturation.
use crate::control::{Controller, Limits, Output, Reference};
use crate::hysteresis::inverse::solve_increasing;
use crate::hysteresis::Invertible;

/// Inner controller `C` behind the inverse of model `M`.
#[derive(Debug, Clone, Copy)]
pub struct Compensated<C, M> {
    /// Controller in the linearized (displacement) domain.
    pub inner: C,
    /// The identified, invertible hysteresis model (input V, output m).
    pub model: M,
    /// Voltage limits.
    pub limits: Limits,
}

impl<C: Controller, M: Invertible> Compensated<C, M> {
    fn split(&self) -> (usize, usize) {
        (self.inner.state_len(), self.model.state_len())
    }
}

impl<C: Controller, M: Invertible> Controller for Compensated<C, M> {
    /// Inner state, model state, previous voltage.
    fn state_len(&self) -> usize {
        let (a, b) = self.split();
        a + b + 1
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        let (a, b) = self.split();
        self.inner.reset(&mut state[..a], y0);
        self.model.reset(&mut state[a..a + b]);
        state[a + b] = 0.0;
    }
    #[inline]
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        let (a, b) = self.split();
        let (inner, rest) = state.split_at_mut(a);
        let (model_state, last) = rest.split_at_mut(b);
        let mut out = self.inner.step(inner, r, y);
        let frozen: &[f64] = model_state;
        // unreachable targets (beyond what the model can output) hold the last voltage
        let solved = solve_increasing(|v| self.model.trial(frozen, v), out.u, last[0]).unwrap_or(last[0]);
        let u = crate::num::math::clamp(solved, self.limits.min, self.limits.max);
        self.model.step(model_state, u);
        last[0] = u;
        out.u = u;
        out
    }
    fn term_names(&self) -> &'static [&'static str] {
        self.inner.term_names()
    }
    fn check_state(&self, state: &[f64]) -> Result<(), crate::ModelError> {
        crate::hysteresis::check_state_len(state, self.state_len())?;
        let (a, b) = self.split();
        self.inner.check_state(&state[..a])?;
        self.model.check_state(&state[a..a + b]).map_err(|e| offset_slot(e, a))?;
        crate::error::check_scalar("state (previous voltage)", state[a + b])
            .map_err(|_| crate::ModelError::NotFinite("state", a + b, state[a + b]))
    }
    fn limits(&self) -> Limits {
        self.limits
    }
}

/// A slot error of a part of the state, renumbered as a slot of the whole state.
pub(crate) fn offset_slot(e: crate::ModelError, at: usize) -> crate::ModelError {
    use crate::ModelError::*;
    match e {
        NotFinite(n, i, v) if i != usize::MAX => NotFinite(n, i + at, v),
        OutOfRange(n, i, v, lo, hi) if i != usize::MAX => OutOfRange(n, i + at, v, lo, hi),
        e => e,
    }
}
