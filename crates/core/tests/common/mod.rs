//! Helpers shared by the integration tests (not a test target itself).
#![allow(dead_code)]

use piezohyst_core::Hysteresis;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestCaseError};

/// Proptest configuration: `cases` cases, no regression files written into the source tree.
pub fn cfg(cases: u32) -> Config {
    Config { cases, failure_persistence: None, ..Config::default() }
}

/// Run `m` from its relaxed state over `v`; returns the outputs and the final state.
pub fn simulate<M: Hysteresis + ?Sized>(m: &M, v: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut st = vec![0.0; m.state_len()];
    m.reset(&mut st);
    let y = v.iter().map(|&x| m.step(&mut st, x)).collect();
    (y, st)
}

/// Repeat sample `i` of `v` `1 + reps[i % reps.len()]` times. Returns the expanded record and,
/// for every original sample, the index of its last copy.
pub fn repeat_samples(v: &[f64], reps: &[usize]) -> (Vec<f64>, Vec<usize>) {
    let mut out = Vec::new();
    let mut idx = Vec::new();
    for (i, &x) in v.iter().enumerate() {
        let r = if reps.is_empty() { 0 } else { reps[i % reps.len()] };
        for _ in 0..=r {
            out.push(x);
        }
        idx.push(out.len() - 1);
    }
    (out, idx)
}

/// Time-stretch `v`: between samples `i-1` and `i` insert `ins[i % ins.len()]` linearly
/// interpolated samples. The inserted samples are monotone and stay inside the closed
/// interval between the two original samples (clamped, so rounding cannot overshoot), so the
/// path between original samples stays monotone. Returns the record and the indices of the
/// original samples in it.
pub fn stretch(v: &[f64], ins: &[usize]) -> (Vec<f64>, Vec<usize>) {
    let mut out = Vec::new();
    let mut idx = Vec::new();
    for (i, &x) in v.iter().enumerate() {
        if i > 0 {
            let a = v[i - 1];
            let k = if ins.is_empty() { 0 } else { ins[i % ins.len()] };
            let (lo, hi) = if a <= x { (a, x) } else { (x, a) };
            for j in 1..=k {
                let t = j as f64 / (k + 1) as f64;
                let m = (a + (x - a) * t).clamp(lo, hi);
                out.push(m);
            }
        }
        out.push(x);
        idx.push(out.len() - 1);
    }
    (out, idx)
}

/// Pick the samples `idx` of `y`.
pub fn pick(y: &[f64], idx: &[usize]) -> Vec<f64> {
    idx.iter().map(|&i| y[i]).collect()
}

/// Largest absolute value; NaN if any value is NaN (so a comparison against it fails).
pub fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, v| if m.is_nan() || v.is_nan() { f64::NAN } else { m.max(v.abs()) })
}

/// Largest absolute difference; NaN if any difference is NaN or any value is not finite
/// (so `max_diff(..) <= tol` fails on a diverged record).
pub fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| {
        if m.is_nan() || !x.is_finite() || !y.is_finite() {
            f64::NAN
        } else {
            m.max((x - y).abs())
        }
    })
}

/// Assert two records are bit-identical, naming the first differing sample.
pub fn assert_bits_eq(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths differ");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(x.to_bits() == y.to_bits(), "{what}: sample {k} differs: {x:e} vs {y:e}");
    }
}

/// As [`assert_bits_eq`], for use inside proptest bodies (returns the failure).
pub fn prop_bits_eq(a: &[f64], b: &[f64], what: &str) -> Result<(), TestCaseError> {
    prop_assert_eq!(a.len(), b.len(), "{}: lengths differ", what);
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        prop_assert!(x.to_bits() == y.to_bits(), "{}: sample {} differs: {:e} vs {:e}", what, k, x, y);
    }
    Ok(())
}

/// Strictly increasing thresholds from positive increments: `first + cumsum(increments)`.
pub fn thresholds_from(first: f64, inc: &[f64]) -> Vec<f64> {
    let mut r = Vec::with_capacity(inc.len());
    let mut acc = first;
    for (i, &d) in inc.iter().enumerate() {
        if i > 0 {
            acc += d;
        }
        r.push(acc);
    }
    r
}

/// A random input record: `len` samples in `[-amp, amp]`.
pub fn input_strategy(amp: f64, len: std::ops::Range<usize>) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-amp..amp, len)
}

/// Classical RK4 of `dx/dt = f(t, x)` from `t0` over `dt_total` in `steps` steps.
pub fn rk4<F: Fn(f64, f64) -> f64>(f: F, mut x: f64, t0: f64, dt_total: f64, steps: usize) -> f64 {
    let h = dt_total / steps as f64;
    for i in 0..steps {
        let t = t0 + h * i as f64;
        let k1 = f(t, x);
        let k2 = f(t + 0.5 * h, x + 0.5 * h * k1);
        let k3 = f(t + 0.5 * h, x + 0.5 * h * k2);
        let k4 = f(t + h, x + h * k3);
        x += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    x
}

/// RK4 as [`rk4`], but a step in which `x` changes sign (where `|x|` makes the right-hand
/// side non-smooth) is redone with `refine` sub-steps, so the kink costs no accuracy.
pub fn rk4_sign_refined<F: Fn(f64, f64) -> f64>(
    f: F,
    mut x: f64,
    t0: f64,
    dt_total: f64,
    steps: usize,
    refine: usize,
) -> f64 {
    let h = dt_total / steps as f64;
    for i in 0..steps {
        let t = t0 + h * i as f64;
        let x1 = rk4(&f, x, t, h, 1);
        if !x1.is_finite() {
            return f64::NAN; // diverged: let the comparison fail fast
        }
        x = if x != 0.0 && x1.signum() != x.signum() { rk4(&f, x, t, h, refine) } else { x1 };
    }
    x
}
