//! Position sensor: white noise, quantization and a delay of whole samples (docs/spec.md §3.2).
use crate::error::{check_scalar, ModelError};
use crate::num::rng::Rng;

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

/// Length of the delay line: a power of two above `MAX_DELAY` (indices wrap by masking).
const RING: usize = 32;
const _: () = assert!(RING.is_power_of_two() && RING > MAX_DELAY);

/// Sensor state: the delay line and the noise generator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorState {
    line: [f64; RING],
    head: usize,
    rng: Rng,
}

impl SensorState {
    /// Standard normal deviate: [`Rng::normal`] (the same stream as `Rng::normal` for the
    /// same seed); its common case, one word and a table look-up, inlines into the loop.
    #[inline(always)]
    fn normal(&mut self) -> f64 {
        self.rng.normal()
    }
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
        SensorState { line: [q; RING], head: 0, rng: Rng::new(seed) }
    }

    /// Mid-tread quantization (round half to even). Adding and removing 1.5 * 2^52 rounds
    /// to the nearest integer in two additions, exactly, for |x / q| < 2^51; beyond that
    /// (readings of more than 10^15 steps) the value is already an integer multiple.
    #[inline(always)]
    fn quantize(&self, x: f64) -> f64 {
        self.quantize_t::<false>(x)
    }

    /// [`Sensor::quantize`]; `T` true asserts `quantization > 0` ([`Sensor::is_typical`]).
    #[inline(always)]
    fn quantize_t<const T: bool>(&self, x: f64) -> f64 {
        const SHIFT: f64 = 6755399441055744.0; // 1.5 * 2^52
        if T || self.quantization > 0.0 {
            let t = x * self.inv_quantization;
            let r = if crate::num::math::abs(t) < 2251799813685248.0 { (t + SHIFT) - SHIFT } else { t };
            r * self.quantization
        } else {
            x
        }
    }

    /// Sample the true position now; return the reading the controller sees now (the one
    /// taken `delay` samples ago).
    #[inline]
    pub fn read(&self, st: &mut SensorState, x: f64) -> f64 {
        self.read_t::<false>(st, x)
    }

    /// Noise and quantization both on (the packaged virtual stage's sensor).
    #[inline(always)]
    pub(crate) fn is_typical(&self) -> bool {
        self.noise_std > 0.0 && self.quantization > 0.0
    }

    /// [`Sensor::read`]; `T` true asserts [`Sensor::is_typical`] so its checks fold away
    /// (the same arithmetic either way).
    #[inline(always)]
    pub(crate) fn read_t<const T: bool>(&self, st: &mut SensorState, x: f64) -> f64 {
        debug_assert!(!T || self.is_typical());
        let noisy = if T || self.noise_std > 0.0 { x + self.noise_std * st.normal() } else { x };
        st.head = (st.head + 1) & (RING - 1);
        st.line[st.head] = self.quantize_t::<T>(noisy);
        st.line[st.head.wrapping_sub(self.delay) & (RING - 1)]
    }
}
