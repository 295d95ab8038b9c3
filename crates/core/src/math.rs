//! Elementary functions through libm, so results are identical with and without `std`.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    libm::exp(x)
}
#[inline(always)]
pub fn expm1(x: f64) -> f64 {
    libm::expm1(x)
}
#[inline(always)]
pub fn tanh(x: f64) -> f64 {
    libm::tanh(x)
}
#[inline(always)]
pub fn atanh(x: f64) -> f64 {
    libm::atanh(x)
}
#[inline(always)]
pub fn pow(x: f64, y: f64) -> f64 {
    libm::pow(x, y)
}
#[inline(always)]
pub fn sqrt(x: f64) -> f64 {
    libm::sqrt(x)
}
#[inline(always)]
pub fn abs(x: f64) -> f64 {
    libm::fabs(x)
}
/// Sign with `sign(0) = 0`.
#[inline(always)]
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}
/// The play operator's clamp, written with comparisons so it vectorizes and keeps
/// `max(lo, min(hi, z))` semantics exactly (lo <= hi assumed).
#[inline(always)]
pub fn clamp(z: f64, lo: f64, hi: f64) -> f64 {
    let z = if z < hi { z } else { hi };
    if z > lo {
        z
    } else {
        lo
    }
}
