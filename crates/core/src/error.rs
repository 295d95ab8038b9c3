//! Errors of model construction and inversion. Each names the parameter and the value.
use core::fmt;

/// What is wrong with a parameter set or a request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelError {
    /// A value is NaN or infinite: (parameter name, index or usize::MAX for a scalar, value).
    NotFinite(&'static str, usize, f64),
    /// A value must be >= 0 (or > 0): (parameter, index, value).
    Negative(&'static str, usize, f64),
    /// A value must be > 0: (parameter, index, value).
    NotPositive(&'static str, usize, f64),
    /// `thresholds[i] <= thresholds[i-1]`: (parameter, i, value).
    NotIncreasing(&'static str, usize, f64),
    /// Two slices that must have equal length do not: (name, expected, got).
    Length(&'static str, usize, usize),
    /// The partial weight sum S_i <= 0, so the PI model has no inverse: (i, S_i).
    NotInvertible(usize, f64),
    /// An envelope is not increasing at this input: (which envelope, input, slope).
    EnvelopeNotMonotone(&'static str, f64, f64),
    /// The envelopes cross: g_l(v) - r > g_r(v) + r at (input, threshold index).
    EnvelopesCross(f64, usize),
    /// The desired output cannot be reached at this sample: (sample index, desired).
    Unreachable(usize, f64),
    /// A structural option is out of range: (name, value).
    Structure(&'static str, usize),
    /// The requested closed-form inverse does not exist for these parameters.
    NoAnalyticInverse(&'static str),
    /// A value lies outside the range it must stay in: (name, index, value, low, high).
    OutOfRange(&'static str, usize, f64, f64, f64),
}

fn idx(i: usize) -> IdxFmt {
    IdxFmt(i)
}
struct IdxFmt(usize);
impl fmt::Display for IdxFmt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0 == usize::MAX {
            Ok(())
        } else {
            write!(f, "[{}]", self.0)
        }
    }
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use ModelError::*;
        match *self {
            NotFinite(n, i, v) => write!(f, "{n}{} = {v} is not finite", idx(i)),
            Negative(n, i, v) => write!(f, "{n}{} = {v} must be >= 0", idx(i)),
            NotPositive(n, i, v) => write!(f, "{n}{} = {v} must be > 0", idx(i)),
            NotIncreasing(n, i, v) => write!(
                f,
                "{n}{} = {v} is not greater than {n}[{}]: thresholds must be strictly increasing",
                idx(i),
                i.wrapping_sub(1)
            ),
            Length(n, e, g) => write!(f, "{n} has length {g}, expected {e}"),
            NotInvertible(i, s) => write!(
                f,
                "weights are not invertible: partial sum S[{i}] = p0 + sum(weights[:{i}]) = {s} must be > 0 (no inverse exists)"
            ),
            EnvelopeNotMonotone(n, v, d) => write!(
                f,
                "envelope {n} is not increasing at input {v} (slope {d}); it must be increasing on input_range"
            ),
            EnvelopesCross(v, i) => write!(
                f,
                "envelopes cross at input {v}: rising(v) - thresholds[{i}] > falling(v) + thresholds[{i}]"
            ),
            Unreachable(k, y) => write!(
                f,
                "desired output {y} at sample {k} is outside the range the model can produce"
            ),
            Structure(n, v) => write!(f, "{n} = {v} is out of range"),
            NoAnalyticInverse(why) => write!(f, "no analytic inverse: {why}"),
            OutOfRange(n, i, v, lo, hi) => write!(f, "{n}{} = {v} must lie within [{lo}, {hi}]", idx(i)),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ModelError {}

/// Check that every value of a slice is finite.
pub fn check_finite(name: &'static str, xs: &[f64]) -> Result<(), ModelError> {
    match xs.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(ModelError::NotFinite(name, i, xs[i])),
        None => Ok(()),
    }
}

/// Check a scalar is finite.
pub fn check_scalar(name: &'static str, x: f64) -> Result<(), ModelError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(ModelError::NotFinite(name, usize::MAX, x))
    }
}

/// Thresholds: finite, >= 0, strictly increasing.
pub fn check_thresholds(name: &'static str, r: &[f64]) -> Result<(), ModelError> {
    check_finite(name, r)?;
    for (i, &x) in r.iter().enumerate() {
        if x < 0.0 {
            return Err(ModelError::Negative(name, i, x));
        }
        if i > 0 && x <= r[i - 1] {
            return Err(ModelError::NotIncreasing(name, i, x));
        }
    }
    Ok(())
}
