//! Envelope functions of the generalized play operator (docs/spec.md §2.2).
use crate::error::ModelError;
use crate::num::math::{abs, atanh, tanh};

/// An increasing envelope `g(v)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Envelope {
    /// `g(v) = v`.
    Identity,
    /// `g(v) = c0 + c1 v + c2 v^2 + c3 v^3`.
    Polynomial([f64; 4]),
    /// `g(v) = a0 tanh(a1 v + a2) + a3`.
    Tanh([f64; 4]),
}

impl Envelope {
    /// Code used in flat parameter layouts: 0 identity, 1 polynomial, 2 tanh.
    pub fn from_code(code: usize, c: [f64; 4]) -> Result<Self, ModelError> {
        match code {
            0 => Ok(Envelope::Identity),
            1 => Ok(Envelope::Polynomial(c)),
            2 => Ok(Envelope::Tanh(c)),
            _ => Err(ModelError::Structure("envelope kind", code)),
        }
    }

    /// `g(v)`.
    #[inline(always)]
    pub fn eval(&self, v: f64) -> f64 {
        match *self {
            Envelope::Identity => v,
            Envelope::Polynomial(c) => c[0] + v * (c[1] + v * (c[2] + v * c[3])),
            Envelope::Tanh(a) => a[0] * tanh(a[1] * v + a[2]) + a[3],
        }
    }

    /// `g'(v)`.
    #[inline(always)]
    pub fn slope(&self, v: f64) -> f64 {
        match *self {
            Envelope::Identity => 1.0,
            Envelope::Polynomial(c) => c[1] + v * (2.0 * c[2] + v * 3.0 * c[3]),
            Envelope::Tanh(a) => {
                let t = tanh(a[1] * v + a[2]);
                a[0] * a[1] * (1.0 - t * t)
            }
        }
    }

    /// Check the envelope is strictly increasing on `[lo, hi]` (infinite ends allowed).
    pub fn check_increasing(&self, name: &'static str, lo: f64, hi: f64) -> Result<(), ModelError> {
        match *self {
            Envelope::Identity => Ok(()),
            Envelope::Tanh(a) => {
                crate::error::check_finite(name, &a)?;
                if a[0] * a[1] > 0.0 {
                    Ok(())
                } else {
                    Err(ModelError::EnvelopeNotMonotone(name, lo, a[0] * a[1]))
                }
            }
            Envelope::Polynomial(c) => {
                crate::error::check_finite(name, &c)?;
                // g' is a quadratic; its minimum on [lo, hi] is at an end or at the vertex
                let mut candidates = [lo, hi, f64::NAN];
                if c[3] > 0.0 {
                    candidates[2] = -c[2] / (3.0 * c[3]);
                }
                if c[3] < 0.0 && (lo.is_infinite() || hi.is_infinite()) {
                    let at = if lo.is_infinite() { lo } else { hi };
                    return Err(ModelError::EnvelopeNotMonotone(name, at, f64::NEG_INFINITY));
                }
                if c[3] == 0.0 && c[2] != 0.0 && (lo.is_infinite() || hi.is_infinite()) {
                    let at = if c[2] > 0.0 { lo } else { hi };
                    if at.is_infinite() {
                        return Err(ModelError::EnvelopeNotMonotone(name, at, f64::NEG_INFINITY));
                    }
                }
                for &v in &candidates {
                    if v.is_nan() || v < lo || v > hi || v.is_infinite() {
                        continue;
                    }
                    let d = self.slope(v);
                    if !(d > 0.0) {
                        return Err(ModelError::EnvelopeNotMonotone(name, v, d));
                    }
                }
                if lo.is_infinite() && hi.is_infinite() && c[3] == 0.0 && c[2] == 0.0 && !(c[1] > 0.0) {
                    return Err(ModelError::EnvelopeNotMonotone(name, 0.0, c[1]));
                }
                Ok(())
            }
        }
    }

    /// `g^{-1}(y)`: closed form for identity and tanh, safeguarded Newton for polynomials
    /// (the envelope must be increasing; `guess` seeds the search).
    pub fn inverse(&self, y: f64, guess: f64) -> Option<f64> {
        match *self {
            Envelope::Identity => Some(y),
            Envelope::Tanh(a) => {
                let t = (y - a[3]) / a[0];
                if abs(t) >= 1.0 {
                    None
                } else {
                    Some((atanh(t) - a[2]) / a[1])
                }
            }
            Envelope::Polynomial(_) => {
                let f = |v: f64| (self.eval(v), self.slope(v));
                crate::hysteresis::inverse::solve_increasing(f, y, guess)
            }
        }
    }
}
