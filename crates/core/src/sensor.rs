//! Position sensor: white noise, quantization and a delay of whole samples (SPEC §3.2).
use crate::error::{check_scalar, ModelError};
use crate::rng::Rng;

/// Longest delay, samples.
pub const MAX_DELAY: usize = 16;

/// Sensor configuration (build it with [`Sensor::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    /// Quantization step, m (0: none). Mid-tread rounding.
    pub quantization: f64,
    /// White-noise standard deviation before quantization, m.
    pub noise_std: f64,
    /// Delay, whole controller samples (0..=MAX_DELAY).
    pub delay: usize,
    /// `1 / quantization` (derived; 0 when there is no quantization).
    inv_quantization: f64,
}

/// Sensor state: the delay line and the noise generator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorState {
    line: [f64; MAX_DELAY + 1],
    head: usize,
    rng: Rng,
}

impl Sensor {
    /// Validate and build.
    pub fn new(quantization: f64, noise_std: f64, delay: usize) -> Result<Self, ModelError> {
        check_scalar("quantization", quantization)?;
        check_scalar("noise_std", noise_std)?;
        if quantization < 0.0 {
            return Err(ModelError::Negative("quantization", usize::MAX, quantization));
        }
        if noise_std < 0.0 {
            return Err(ModelError::Negative("noise_std", usize::MAX, noise_std));
        }
        if delay > MAX_DELAY {
            return Err(ModelError::Structure("delay", delay));
        }
        let inv_quantization = if quantization > 0.0 { 1.0 / quantization } else { 0.0 };
        Ok(Sensor { quantization, noise_std, delay, inv_quantization })
    }

    /// A fresh state whose delay line holds the noiseless reading of `x0`, and a
    /// noise stream from `seed`.
    pub fn state(&self, x0: f64, seed: u64) -> SensorState {
        let q = self.quantize(x0);
        SensorState { line: [q; MAX_DELAY + 1], head: 0, rng: Rng::new(seed) }
    }

    /// Mid-tread quantization (round half to even). Adding and removing 1.5 * 2^52 rounds
    /// to the nearest integer in two additions, exactly, for |x / q| < 2^51; beyond that
    /// (readings of more than 10^15 steps) the value is already an integer multiple.
    #[inline]
    fn quantize(&self, x: f64) -> f64 {
        const SHIFT: f64 = 6755399441055744.0; // 1.5 * 2^52
        if self.quantization > 0.0 {
            let t = x * self.inv_quantization;
            let r = if crate::math::abs(t) < 2251799813685248.0 { (t + SHIFT) - SHIFT } else { t };
            r * self.quantization
        } else {
            x
        }
    }

    /// Sample the true position now; return the reading the controller sees now (the one
    /// taken `delay` samples ago).
    #[inline]
    pub fn read(&self, st: &mut SensorState, x: f64) -> f64 {
        let noisy = if self.noise_std > 0.0 { x + self.noise_std * st.rng.normal() } else { x };
        st.head = (st.head + 1) % (MAX_DELAY + 1);
        st.line[st.head] = self.quantize(noisy);
        st.line[(st.head + MAX_DELAY + 1 - self.delay) % (MAX_DELAY + 1)]
    }
}
