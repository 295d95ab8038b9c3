//! Rate independence (docs/spec.md §2.1, §2.2, §2.5, §2.7): repeating samples or time-stretching
//! the input (monotone linear interpolation between samples) leaves the outputs at the
//! original samples unchanged. Bit-identical for repeated samples everywhere and for
//! stretching of the play-type models (GPI, Preisach); ~1e-12 relative for the closed-form
//! differential models (Bouc–Wen n = 1, Dahl, Duhem). PI is covered in `play_pi.rs`.
mod common;

use common::*;
use piezohyst_core::differential::{BoucWen, Dahl, Duhem};
use piezohyst_core::envelope::Envelope;
use piezohyst_core::generalized::GeneralizedPi;
use piezohyst_core::preisach::{cell_count, row_prefix, Preisach, MAX_MEMORY};
use piezohyst_core::Hysteresis;
use proptest::prelude::*;

/// How a record is re-timed without changing its path: sample `i` is repeated
/// `repeats[i % len]` more times ([`repeat_samples`]), or followed by `inserts[i % len]`
/// interpolated samples ([`stretch`]).
struct Retiming<'a> {
    repeats: &'a [usize],
    inserts: &'a [usize],
}

/// Check repeated samples (bit-identical) and stretching (bit-identical if `tol` is None,
/// else within `tol * max(max|y|, floor)`). `start` is the input of the relaxed state,
/// prepended so that the first segment is stretched too.
fn check_rate_independence<M: Hysteresis>(
    m: &M,
    state_view: fn(&[f64]) -> &[f64],
    start: f64,
    v: &[f64],
    retiming: Retiming<'_>,
    tol: Option<(f64, f64)>,
    what: &str,
) -> Result<(), TestCaseError> {
    let mut v0 = vec![start];
    v0.extend_from_slice(v);
    let (y, st) = simulate(m, &v0);
    prop_assert!(y.iter().all(|x| x.is_finite()), "{}: non-finite output", what);
    let (vr, ir) = repeat_samples(&v0, retiming.repeats);
    let (yr, str_) = simulate(m, &vr);
    prop_bits_eq(&pick(&yr, &ir), &y, &format!("{what}: repeated samples"))?;
    prop_bits_eq(state_view(&str_), state_view(&st), &format!("{what}: state after repeated samples"))?;
    let (vs, is) = stretch(&v0, retiming.inserts);
    let (ys, sts) = simulate(m, &vs);
    let ys = pick(&ys, &is);
    match tol {
        None => {
            prop_bits_eq(&ys, &y, &format!("{what}: time-stretched"))?;
            prop_bits_eq(state_view(&sts), state_view(&st), &format!("{what}: state after time-stretching"))?;
        }
        Some((rel, floor)) => {
            let scale = max_abs(&y).max(floor);
            let d = max_diff(&ys, &y);
            prop_assert!(d <= rel * scale, "{}: stretched output differs by {:e} (scale {:e})", what, d, scale);
        }
    }
    Ok(())
}

use proptest::test_runner::TestCaseError;

/// The whole state vector.
fn all(s: &[f64]) -> &[f64] {
    s
}

/// The meaningful part of a Preisach state: previous input, stack length, stored extrema
/// (slots above the stack length are scratch and may hold stale values).
fn preisach_view(s: &[f64]) -> &[f64] {
    &s[..2 + s[1] as usize]
}

fn reps_strategy() -> impl Strategy<Value = Vec<usize>> {
    prop::collection::vec(prop_oneof![3 => Just(0usize), 1 => 1usize..4], 1..30)
}
fn ins_strategy() -> impl Strategy<Value = Vec<usize>> {
    prop::collection::vec(0usize..7, 1..30)
}

proptest! {
    #![proptest_config(cfg(256))]

    #[test]
    fn gpi_polynomial_envelopes(
        b in prop::collection::vec(-0.3..1.0f64, 1..8),
        poly in prop::array::uniform4(-0.5..0.5f64),
        v in input_strategy(1.4, 1..150),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let r: Vec<f64> = (0..b.len()).map(|i| 0.2 + 0.1 * i as f64).collect();
        let rising = Envelope::Polynomial([-0.02, 0.9, 0.05, 0.3]);
        let falling = Envelope::Polynomial([0.02, 1.1, -0.05, 0.25]);
        let m = GeneralizedPi::new(poly, &r, &b, rising, falling, (-1.5, 1.5)).unwrap();
        check_rate_independence(&m, all, 0.0, &v, Retiming { repeats: &reps, inserts: &ins }, None, "gpi polynomial")?;
    }

    #[test]
    fn gpi_tanh_envelopes(
        b in prop::collection::vec(-0.3..1.0f64, 1..8),
        poly in prop::array::uniform4(-0.5..0.5f64),
        v in input_strategy(2.0, 1..150),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let r: Vec<f64> = (0..b.len()).map(|i| 0.05 + 0.1 * i as f64).collect();
        let rising = Envelope::Tanh([1.0, 1.2, -0.1, 0.0]);
        let falling = Envelope::Tanh([1.1, 1.0, 0.1, 0.05]);
        let m = GeneralizedPi::new(poly, &r, &b, rising, falling, (-2.0, 2.0)).unwrap();
        check_rate_independence(&m, all, 0.0, &v, Retiming { repeats: &reps, inserts: &ins }, None, "gpi tanh")?;
    }

    #[test]
    fn preisach(
        levels in 1usize..10,
        w in prop::collection::vec(prop_oneof![Just(0.0), 0.0..1.0f64], cell_count(9)),
        slope in 0.0..1.0f64,
        v in input_strategy(1.3, 1..120),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let w = &w[..cell_count(levels)];
        let mut pre = vec![0.0; w.len()];
        row_prefix(levels, w, &mut pre);
        let m = Preisach { lo: -1.0, hi: 1.0, levels, weights: w, prefix: &pre, offset: 0.1, slope, memory: MAX_MEMORY }.validated().unwrap();
        // the relaxed Preisach state is negative saturation: its input is `lo`
        check_rate_independence(&m, preisach_view, -1.0, &v, Retiming { repeats: &reps, inserts: &ins }, None, "preisach")?;
    }

    #[test]
    fn bouc_wen_n1(
        a in 0.1..2.0f64,
        beta in 0.0..1.5f64,
        gamma_frac in -1.0..1.0f64,
        d in 0.0..1.0f64,
        v in input_strategy(3.0, 1..150),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let m = BoucWen::new(a, beta, gamma_frac * beta, 1.0, d).unwrap();
        check_rate_independence(&m, all, 0.0, &v, Retiming { repeats: &reps, inserts: &ins }, Some((1e-12, 1e-3)), "bouc-wen n=1")?;
    }

    /// The Bouc–Wen benchmark parameters (Noël & Schoukens) with displacement-sized inputs.
    #[test]
    fn bouc_wen_n1_benchmark(
        v in input_strategy(1.5e-3, 1..150),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let m = BoucWen::new(5e4, 1e3 * 0.8, 1e3 * -1.1, 1.0, 0.0).unwrap();
        check_rate_independence(&m, all, 0.0, &v, Retiming { repeats: &reps, inserts: &ins }, Some((1e-12, 1.0)), "bouc-wen benchmark")?;
    }

    #[test]
    fn dahl(
        sigma in 0.5..5.0f64,
        h_c in 0.2..2.0f64,
        a in prop_oneof![Just(1.0), Just(0.5), Just(2.0), 0.3..3.0f64],
        v in input_strategy(2.0, 1..150),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let m = Dahl::new(sigma, h_c, a).unwrap();
        check_rate_independence(&m, all, 0.0, &v, Retiming { repeats: &reps, inserts: &ins }, Some((1e-12, 1e-3)), "dahl")?;
    }

    #[test]
    fn duhem(
        alpha in prop_oneof![Just(0.0), 0.0..4.0f64],
        f in prop::array::uniform4(-1.0..1.0f64),
        g in prop::array::uniform4(-1.0..1.0f64),
        v in input_strategy(1.5, 1..150),
        reps in reps_strategy(),
        ins in ins_strategy(),
    ) {
        let m = Duhem::new(alpha, f, g).unwrap();
        check_rate_independence(&m, all, 0.0, &v, Retiming { repeats: &reps, inserts: &ins }, Some((1e-12, 1e-3)), "duhem")?;
    }
}
