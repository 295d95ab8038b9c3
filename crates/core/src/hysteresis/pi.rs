//! Classical play operator and the Prandtl–Ishlinskii (PI) model (docs/spec.md §2.1).
//!
//! ```text
//! z_r(k) = max(v(k) - r, min(v(k) + r, z_r(k-1)))
//! y(k)   = p0*v(k) + sum_i w_i * z_{r_i}(k)
//! ```
use crate::error::{check_finite, check_scalar, check_thresholds, ModelError};
use crate::hysteresis::{Hysteresis, Invertible};
use crate::num::math::clamp;

/// One step of the classical play (backlash) operator with threshold `r >= 0`.
#[inline(always)]
pub fn play(z_prev: f64, v: f64, r: f64) -> f64 {
    clamp(z_prev, v - r, v + r)
}

/// PI model configuration. State: one play output per threshold (`thresholds.len()` slots).
#[derive(Debug, Clone, Copy)]
pub struct Pi<'a> {
    /// Weight of the linear (zero-threshold) term.
    pub p0: f64,
    /// Play thresholds, `0 <= r_1 < r_2 < ...`.
    pub thresholds: &'a [f64],
    /// Play weights, one per threshold.
    pub weights: &'a [f64],
}

impl<'a> Pi<'a> {
    /// Validate and build.
    pub fn new(p0: f64, thresholds: &'a [f64], weights: &'a [f64]) -> Result<Self, ModelError> {
        check_scalar("p0", p0)?;
        check_thresholds("thresholds", thresholds)?;
        if weights.len() != thresholds.len() {
            return Err(ModelError::Length("weights", thresholds.len(), weights.len()));
        }
        check_finite("weights", weights)?;
        Ok(Pi { p0, thresholds, weights })
    }

    /// Initial loading curve `phi(s) = p0*s + sum_i w_i*max(s - r_i, 0)`.
    pub fn loading_curve(&self, s: f64) -> f64 {
        let mut y = self.p0 * s;
        for (&r, &w) in self.thresholds.iter().zip(self.weights) {
            if s > r {
                y += w * (s - r);
            }
        }
        y
    }

    /// Partial sums `S_i = p0 + w_1 + ... + w_i` must all be > 0 for an inverse to exist.
    pub fn check_invertible(&self) -> Result<(), ModelError> {
        let mut s = self.p0;
        if s <= 0.0 {
            return Err(ModelError::NotInvertible(0, s));
        }
        for (i, &w) in self.weights.iter().enumerate() {
            s += w;
            if s <= 0.0 {
                return Err(ModelError::NotInvertible(i + 1, s));
            }
        }
        Ok(())
    }

    /// Parameters of the analytic inverse PI model (docs/spec.md §2.1): returns `p0'` and fills
    /// `inv_thresholds` (`r'_i = phi(r_i)`) and `inv_weights` (`p'_i = -w_i/(S_i S_{i-1})`).
    /// Driving the returned PI with the desired output `y_d` gives the input `v`.
    pub fn analytic_inverse(&self, inv_thresholds: &mut [f64], inv_weights: &mut [f64]) -> Result<f64, ModelError> {
        let n = self.thresholds.len();
        if inv_thresholds.len() != n {
            return Err(ModelError::Length("inv_thresholds", n, inv_thresholds.len()));
        }
        if inv_weights.len() != n {
            return Err(ModelError::Length("inv_weights", n, inv_weights.len()));
        }
        if n > 0 && self.thresholds[0] == 0.0 {
            return Err(ModelError::NoAnalyticInverse(
                "thresholds[0] = 0 duplicates the linear term; move its weight into p0",
            ));
        }
        self.check_invertible()?;
        let mut s_prev = self.p0;
        for i in 0..n {
            let s_i = s_prev + self.weights[i];
            // r'_i = sum_{j<=i} p_j (r_i - r_j) with r_0 = 0, p_0 = p0
            let mut rp = self.p0 * self.thresholds[i];
            for j in 0..i {
                rp += self.weights[j] * (self.thresholds[i] - self.thresholds[j]);
            }
            inv_thresholds[i] = rp;
            inv_weights[i] = -self.weights[i] / (s_i * s_prev);
            s_prev = s_i;
        }
        Ok(1.0 / self.p0)
    }
}

impl Hysteresis for Pi<'_> {
    fn state_len(&self) -> usize {
        self.thresholds.len()
    }
    #[inline]
    fn step(&self, state: &mut [f64], v: f64) -> f64 {
        let mut y = self.p0 * v;
        for ((z, &r), &w) in state.iter_mut().zip(self.thresholds).zip(self.weights) {
            *z = play(*z, v, r);
            y += w * *z;
        }
        y
    }
}

impl Invertible for Pi<'_> {
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64) {
        let mut y = self.p0 * v;
        let mut dy = self.p0;
        for ((&z0, &r), &w) in state.iter().zip(self.thresholds).zip(self.weights) {
            let z = play(z0, v, r);
            y += w * z;
            // the play follows v (slope 1) unless it stays inside its band
            if v - r > z0 || v + r < z0 {
                dy += w;
            }
        }
        (y, dy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn play_band_and_first_sample_convention() {
        // first sample from the relaxed state: z = max(v0 - r, min(v0 + r, 0))
        assert_eq!(play(0.0, 3.0, 1.0), 2.0);
        assert_eq!(play(0.0, -0.5, 1.0), 0.0);
        assert_eq!(play(2.0, 2.5, 1.0), 2.0);
        assert_eq!(play(2.0, 0.5, 1.0), 1.5);
    }

    #[test]
    fn analytic_inverse_of_two_operator_model() {
        // p0 = 1, r = [1], w = [1]: phi(s) = s + max(s-1, 0)
        let r = [1.0];
        let w = [1.0];
        let m = Pi::new(1.0, &r, &w).unwrap();
        let (mut ri, mut wi) = ([0.0], [0.0]);
        let p0i = m.analytic_inverse(&mut ri, &mut wi).unwrap();
        assert_eq!(p0i, 1.0);
        assert_eq!(ri[0], 1.0); // phi(1) = 1
        assert_eq!(wi[0], -0.5); // -1/(2*1)
    }

    #[test]
    fn non_invertible_weights_name_the_partial_sum() {
        let r = [0.5, 1.0];
        let w = [-0.4, -0.7];
        let m = Pi::new(1.0, &r, &w).unwrap();
        assert_eq!(m.check_invertible(), Err(ModelError::NotInvertible(2, 1.0 - 0.4 - 0.7)));
    }
}
