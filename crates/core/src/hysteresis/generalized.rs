//! Generalized (asymmetric) play operator, the generalized PI model (GPI) and the seed-2
//! modified PI model (MPI) — docs/spec.md §2.2.
//!
//! ```text
//! z_r(k) = max(g_l(v(k)) - r, min(g_r(v(k)) + r, z_r(k-1)))    g_l rising, g_r falling
//! y(k)   = P(v(k)) + sum_i b_i z_{r_i}(k),   P(v) = c0 + c1 v + c2 v^2 + c3 v^3
//! ```
//! GPI is the case `P = 0` (a zero threshold then carries the linear part); MPI has a
//! polynomial `P`. With `g_l = g_r = identity` and `P = p0 v` this is the classical PI.
use crate::error::{check_finite, check_thresholds, ModelError};
use crate::hysteresis::envelope::Envelope;
use crate::hysteresis::{Hysteresis, Invertible};
use crate::num::math::clamp;

/// One step of the generalized play operator.
#[inline(always)]
pub fn generalized_play(z_prev: f64, v: f64, r: f64, rising: &Envelope, falling: &Envelope) -> f64 {
    clamp(z_prev, rising.eval(v) - r, falling.eval(v) + r)
}

/// GPI / MPI configuration. State: one operator output per threshold.
#[derive(Debug, Clone, Copy)]
pub struct GeneralizedPi<'a> {
    /// Direct polynomial `P(v)` coefficients `[c0, c1, c2, c3]`.
    pub poly: [f64; 4],
    /// Thresholds `0 <= r_1 < r_2 < ...`.
    pub thresholds: &'a [f64],
    /// Operator weights `b_i`.
    pub weights: &'a [f64],
    /// Envelope for rising input, `g_l`.
    pub rising: Envelope,
    /// Envelope for falling input, `g_r`.
    pub falling: Envelope,
}

impl<'a> GeneralizedPi<'a> {
    /// Validate and build. The envelopes must be increasing on `input_range` and must not
    /// cross there (`g_l(v) - r <= g_r(v) + r`, checked on a grid of 257 points when the
    /// range is finite, and at 0 otherwise).
    pub fn new(
        poly: [f64; 4],
        thresholds: &'a [f64],
        weights: &'a [f64],
        rising: Envelope,
        falling: Envelope,
        input_range: (f64, f64),
    ) -> Result<Self, ModelError> {
        check_finite("polynomial", &poly)?;
        check_thresholds("thresholds", thresholds)?;
        if weights.len() != thresholds.len() {
            return Err(ModelError::Length("weights", thresholds.len(), weights.len()));
        }
        check_finite("weights", weights)?;
        let (lo, hi) = input_range;
        if lo.is_nan() || hi.is_nan() {
            let (i, x) = if lo.is_nan() { (0, lo) } else { (1, hi) };
            return Err(ModelError::NotFinite("input_range", i, x));
        }
        if !(lo < hi) {
            return Err(ModelError::NotIncreasing("input_range", 1, hi));
        }
        rising.check_increasing("rising", lo, hi)?;
        falling.check_increasing("falling", lo, hi)?;
        let m = GeneralizedPi { poly, thresholds, weights, rising, falling };
        if let Some(&r) = thresholds.first() {
            let n_grid = if lo.is_finite() && hi.is_finite() { 257 } else { 1 };
            for j in 0..n_grid {
                let v = if n_grid == 1 { 0.0 } else { lo + (hi - lo) * (j as f64) / 256.0 };
                if rising.eval(v) - r > falling.eval(v) + r {
                    return Err(ModelError::EnvelopesCross(v, 0));
                }
            }
        }
        Ok(m)
    }

    /// `P(v)` and `P'(v)`.
    #[inline(always)]
    fn direct(&self, v: f64) -> (f64, f64) {
        let c = self.poly;
        (c[0] + v * (c[1] + v * (c[2] + v * c[3])), c[1] + v * (2.0 * c[2] + v * 3.0 * c[3]))
    }

    /// With equal envelopes `g`, `P = 0` and a zero first threshold of positive weight, the
    /// model is `PI[g(v)]` and has the analytic inverse `v = g^{-1}(PI^{-1}[y])`. Returns the
    /// equivalent classical PI's `p0` (the inverse is then built by [`crate::hysteresis::pi::Pi`]).
    pub fn as_pi_of_envelope(&self) -> Result<f64, ModelError> {
        if self.rising != self.falling {
            return Err(ModelError::NoAnalyticInverse("rising and falling envelopes differ"));
        }
        if self.poly != [0.0; 4] {
            return Err(ModelError::NoAnalyticInverse(
                "the direct polynomial P is not zero; use the per-sample inverse",
            ));
        }
        match self.thresholds.first() {
            Some(&0.0) => Ok(self.weights[0]),
            _ => Err(ModelError::NoAnalyticInverse("the first threshold must be 0 (its weight is the linear term)")),
        }
    }
}

impl Hysteresis for GeneralizedPi<'_> {
    fn state_len(&self) -> usize {
        self.thresholds.len()
    }
    #[inline]
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let gl = self.rising.eval(v);
        let gr = self.falling.eval(v);
        let mut y = self.direct(v).0;
        for ((z, &r), &b) in state.iter_mut().zip(self.thresholds).zip(self.weights) {
            *z = clamp(*z, gl - r, gr + r);
            y += b * *z;
        }
        y
    }
}

impl Invertible for GeneralizedPi<'_> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let gl = self.rising.eval(v);
        let gr = self.falling.eval(v);
        let (dl, dr) = (self.rising.slope(v), self.falling.slope(v));
        let (mut y, mut dy) = self.direct(v);
        for ((&z0, &r), &b) in state.iter().zip(self.thresholds).zip(self.weights) {
            let z = clamp(z0, gl - r, gr + r);
            y += b * z;
            if gr + r < z0 {
                dy += b * dr;
            } else if gl - r > z0 {
                dy += b * dl;
            }
        }
        (y, dy)
    }
}
