//! Creep operators (docs/spec.md §2.4): a bank of first-order lags with time constants spread over
//! decades, approximating the logarithmic drift of a piezo after a step.
//!
//! ```text
//! w_j(k) = w_j(k-1) + a_j (v(k) - w_j(k-1)),   a_j = 1 - exp(-Ts/tau_j)
//! y(k)   = sum_j c_j w_j(k)
//! ```
//! [`WithCreep`] adds the creep output to any other model (Kuhnen's modified PI: play +
//! creep + superposition).
use crate::error::{check_finite, check_scalar, ModelError};
use crate::hysteresis::{Hysteresis, Invertible};

/// Lag gains `a_j = 1 - exp(-ts/tau_j)` for the given time constants.
pub fn lag_gains(ts: f64, taus: &[f64], out: &mut [f64]) -> Result<(), ModelError> {
    check_scalar("ts", ts)?;
    if !(ts > 0.0) {
        return Err(ModelError::NotPositive("ts", usize::MAX, ts));
    }
    check_finite("taus", taus)?;
    if out.len() != taus.len() {
        return Err(ModelError::Length("out", taus.len(), out.len()));
    }
    for (i, (&tau, a)) in taus.iter().zip(out.iter_mut()).enumerate() {
        if !(tau > 0.0) {
            return Err(ModelError::NotPositive("taus", i, tau));
        }
        *a = -crate::num::math::expm1(-ts / tau);
    }
    Ok(())
}

/// Creep configuration. State: one lag output per time constant.
#[derive(Debug, Clone, Copy)]
pub struct Creep<'a> {
    /// Lag gains `a_j` in (0, 1] (see [`lag_gains`]).
    pub gains: &'a [f64],
    /// Output weights `c_j`.
    pub weights: &'a [f64],
}

impl<'a> Creep<'a> {
    /// Validate and build.
    pub fn new(gains: &'a [f64], weights: &'a [f64]) -> Result<Self, ModelError> {
        if weights.len() != gains.len() {
            return Err(ModelError::Length("creep_weights", gains.len(), weights.len()));
        }
        check_finite("creep_gains", gains)?;
        check_finite("creep_weights", weights)?;
        for (i, &a) in gains.iter().enumerate() {
            if !(a > 0.0 && a <= 1.0) {
                return Err(ModelError::NotPositive("creep_gains", i, a));
            }
        }
        Ok(Creep { gains, weights })
    }
}

impl Hysteresis for Creep<'_> {
    fn state_len(&self) -> usize {
        self.gains.len()
    }
    #[inline]
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let mut y = 0.0;
        for ((w, &a), &c) in state.iter_mut().zip(self.gains).zip(self.weights) {
            *w += a * (v - *w);
            y += c * *w;
        }
        y
    }
}

impl Invertible for Creep<'_> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let (mut y, mut dy) = (0.0, 0.0);
        for ((&w0, &a), &c) in state.iter().zip(self.gains).zip(self.weights) {
            let w = w0 + a * (v - w0);
            y += c * w;
            dy += c * a;
        }
        (y, dy)
    }
}

/// Any model plus creep: `y = model(v) + creep(v)`. State: the model's, then the creep's.
#[derive(Debug, Clone, Copy)]
pub struct WithCreep<'a, M> {
    /// The rate-independent (or rate-dependent) part.
    pub model: M,
    /// The creep part.
    pub creep: Creep<'a>,
}

impl<M: Hysteresis> Hysteresis for WithCreep<'_, M> {
    fn state_len(&self) -> usize {
        self.model.state_len() + self.creep.state_len()
    }
    fn reset(&self, state: &mut [f64]) {
        let (a, b) = state.split_at_mut(self.model.state_len());
        self.model.reset(a);
        self.creep.reset(b);
    }
    #[inline]
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let (a, b) = state.split_at_mut(self.model.state_len());
        self.model.step(a, v) + self.creep.step(b, v)
    }
}

impl<M: Invertible> Invertible for WithCreep<'_, M> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let (a, b) = state.split_at(self.model.state_len());
        let (y1, d1) = self.model.trial(a, v);
        let (y2, d2) = self.creep.trial(b, v);
        (y1 + y2, d1 + d2)
    }
}
