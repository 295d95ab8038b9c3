//! Exact per-sample inverse (docs/spec.md §2.1) for every invertible model, and the analytic PI
//! inverse against it: inverse∘forward = identity, state consistency, trial = step.
mod common;

use common::*;
use piezohyst_core::creep::{lag_gains, Creep, WithCreep};
use piezohyst_core::envelope::Envelope;
use piezohyst_core::generalized::GeneralizedPi;
use piezohyst_core::inverse::{inverse_simulate, inverse_step, solve_increasing};
use piezohyst_core::pi::Pi;
use piezohyst_core::preisach::{cell_count, row_prefix, Preisach, MAX_MEMORY};
use piezohyst_core::rate::RateDependentPi;
use piezohyst_core::{Hysteresis, Invertible, ModelError};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// Tolerance on `max|y - y_d|` required of the inverse.
const TOL: f64 = 1e-9;

/// Seed-2 (MPI) reference parameters, docs/spec.md §2.2.
const MPI_R: [f64; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
const MPI_B: [f64; 9] = [0.2054, 0.1985, 0.0237, 0.0148, 0.0456, 0.0645, 0.0051, 0.0014, 0.0033];
const MPI_POLY: [f64; 4] = [0.0, 0.2547, -0.00358, 0.7123];

/// Invert `yd` from a fresh state, run the forward model from a fresh state on the found
/// input, and check the output reproduces `yd` and the two final states are identical.
fn check_inverse<M: Invertible + ?Sized>(m: &M, yd: &[f64], what: &str) -> Result<Vec<f64>, TestCaseError> {
    let mut st = vec![0.0; m.state_len()];
    m.reset(&mut st);
    let mut v = vec![f64::NAN; yd.len()];
    inverse_simulate(m, &mut st, yd, &mut v, 0.0)
        .map_err(|e| TestCaseError::fail(format!("{what}: inverse failed: {e}")))?;
    let (y, st_fwd) = simulate(m, &v);
    let err = max_diff(&y, yd);
    prop_assert!(err <= TOL, "{}: max|y - y_d| = {:e} > {:e}", what, err, TOL);
    prop_assert!(v.iter().all(|x| x.is_finite()));
    for (k, (a, b)) in st.iter().zip(&st_fwd).enumerate() {
        prop_assert!(a.to_bits() == b.to_bits(), "{}: state[{}] {:e} (inverse) vs {:e} (forward)", what, k, a, b);
    }
    Ok(v)
}

/// `trial` must return exactly what `step` returns, and leave the state alone; its slope,
/// when reported, must agree with a one-sided finite difference on at least one side.
fn check_trial<M: Invertible + ?Sized>(
    m: &M,
    history: &[f64],
    probes: &[f64],
    what: &str,
) -> Result<(), TestCaseError> {
    let mut st = vec![0.0; m.state_len()];
    m.reset(&mut st);
    for &x in history {
        m.step(&mut st, x);
    }
    let frozen = st.clone();
    // probe away from the previous input (a genuine kink of the rate-dependent model)
    for v in probes.iter().map(|&x| 0.7 * x + 0.1) {
        let (y, d) = m.trial(&st, v);
        prop_assert!(st == frozen, "{}: trial changed the state", what);
        let mut copy = st.clone();
        let ys = m.step(&mut copy, v);
        prop_assert!(y.to_bits() == ys.to_bits(), "{}: trial {:e} != step {:e} at v={}", what, y, ys, v);
        if d.is_finite() {
            let h = 1e-7 * (1.0 + v.abs());
            let right = (m.trial(&st, v + h).0 - y) / h;
            let left = (y - m.trial(&st, v - h).0) / h;
            let tol = 1e-5 * (1.0 + d.abs());
            prop_assert!(
                (d - right).abs() <= tol || (d - left).abs() <= tol,
                "{}: slope {} vs finite differences left {} right {} at v={}",
                what,
                d,
                left,
                right,
                v
            );
        }
    }
    Ok(())
}

#[derive(Debug, Clone)]
struct PiP {
    p0: f64,
    r: Vec<f64>,
    w: Vec<f64>,
}

/// Invertible PI: p0 > 0, r_1 > 0; weights positive, or (when `allow_neg`) some negative
/// ones clipped so that every partial sum S_i stays >= 0.1.
fn invertible_pi(max_n: usize, allow_neg: bool) -> impl Strategy<Value = PiP> {
    (1..=max_n).prop_flat_map(move |n| {
        (
            0.2..2.0f64,
            0.02..0.3f64,
            prop::collection::vec(0.02..0.5f64, n),
            prop::collection::vec(if allow_neg { -0.8..1.0f64 } else { 0.01..1.0f64 }, n),
        )
            .prop_map(|(p0, r0, inc, mut w)| {
                let mut s = p0;
                for wi in w.iter_mut() {
                    if s + *wi < 0.1 {
                        *wi = 0.1 - s;
                    }
                    s += *wi;
                }
                PiP { p0, r: thresholds_from(r0, &inc), w }
            })
    })
}

fn preisach_weights(levels: usize) -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(prop_oneof![Just(0.0), 0.0..1.0f64], cell_count(levels))
}

proptest! {
    #![proptest_config(cfg(256))]

    #[test]
    fn inverse_pi(p in invertible_pi(10, false), yd in input_strategy(3.0, 1..200)) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        check_inverse(&m, &yd, "pi")?;
        check_trial(&m, &yd, &yd, "pi")?;
    }

    #[test]
    fn inverse_pi_negative_weights(p in invertible_pi(10, true), yd in input_strategy(3.0, 1..200)) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        m.check_invertible().unwrap();
        check_inverse(&m, &yd, "pi (negative weights)")?;
    }

    /// Seed-2 MPI (identity envelopes, cubic P).
    #[test]
    fn inverse_mpi_seed2(yd in input_strategy(1.5, 1..200)) {
        let m = GeneralizedPi::new(MPI_POLY, &MPI_R, &MPI_B, Envelope::Identity, Envelope::Identity, (-10.0, 10.0)).unwrap();
        check_inverse(&m, &yd, "mpi seed 2")?;
        check_trial(&m, &yd, &yd, "mpi seed 2")?;
    }

    /// GPI with asymmetric polynomial envelopes and a small linear P.
    #[test]
    fn inverse_gpi_polynomial(
        b in prop::collection::vec(0.01..0.5f64, 1..8),
        p1 in 0.02..0.5f64,
        v_true in input_strategy(1.4, 1..200),
    ) {
        let r: Vec<f64> = (0..b.len()).map(|i| 0.2 + 0.1 * i as f64).collect();
        let rising = Envelope::Polynomial([-0.02, 0.9, 0.05, 0.3]);
        let falling = Envelope::Polynomial([0.02, 1.1, -0.05, 0.25]);
        let m = GeneralizedPi::new([0.0, p1, 0.0, 0.0], &r, &b, rising, falling, (-1.5, 1.5)).unwrap();
        let (yd, _) = simulate(&m, &v_true);
        check_inverse(&m, &yd, "gpi polynomial")?;
        check_trial(&m, &v_true, &v_true, "gpi polynomial")?;
    }

    /// GPI with asymmetric tanh envelopes and a small linear P; desired outputs produced by
    /// the model itself, so they are reachable.
    #[test]
    fn inverse_gpi_tanh(
        b in prop::collection::vec(0.01..0.5f64, 1..8),
        p1 in 0.02..0.5f64,
        v_true in input_strategy(2.0, 1..200),
    ) {
        let r: Vec<f64> = (0..b.len()).map(|i| 0.05 + 0.1 * i as f64).collect();
        let rising = Envelope::Tanh([1.0, 1.2, -0.1, 0.0]);
        let falling = Envelope::Tanh([1.1, 1.0, 0.1, 0.05]);
        let m = GeneralizedPi::new([0.0, p1, 0.0, 0.0], &r, &b, rising, falling, (-2.0, 2.0)).unwrap();
        let (yd, _) = simulate(&m, &v_true);
        check_inverse(&m, &yd, "gpi tanh")?;
        check_trial(&m, &v_true, &v_true, "gpi tanh")?;
    }

    /// GPI with equal polynomial envelopes, P = 0 and a zero first threshold: the per-sample
    /// inverse equals the analytic route v = g^{-1}(PI^{-1}[y_d]) (docs/spec.md §2.2).
    #[test]
    fn inverse_gpi_equal_envelopes_matches_analytic(
        b in prop::collection::vec(0.05..0.5f64, 2..8),
        yd in input_strategy(1.0, 1..150),
    ) {
        let r: Vec<f64> = (0..b.len()).map(|i| 0.1 * i as f64).collect();
        let g = Envelope::Polynomial([0.05, 0.8, 0.1, 0.4]);
        let m = GeneralizedPi::new([0.0; 4], &r, &b, g, g, (-3.0, 3.0)).unwrap();
        let v = check_inverse(&m, &yd, "gpi equal envelopes")?;
        let p0 = m.as_pi_of_envelope().unwrap();
        prop_assert_eq!(p0, b[0]);
        let pi = Pi::new(p0, &r[1..], &b[1..]).unwrap();
        let n = r.len() - 1;
        let (mut ri, mut wi) = (vec![0.0; n], vec![0.0; n]);
        let p0i = pi.analytic_inverse(&mut ri, &mut wi).unwrap();
        let inv = Pi::new(p0i, &ri, &wi).unwrap();
        let (u, _) = simulate(&inv, &yd);
        for k in 0..yd.len() {
            let va = g.inverse(u[k], v[k]).unwrap();
            prop_assert!((va - v[k]).abs() <= 1e-10, "k={} analytic {} per-sample {}", k, va, v[k]);
        }
    }

    #[test]
    fn inverse_rate_dependent_pi(
        p in invertible_pi(8, false),
        beta_frac in 0.0..0.45f64,
        filtered in any::<bool>(),
        c in prop::collection::vec(0.0..1e-5f64, 8),
        yd in input_strategy(2.0, 1..200),
    ) {
        let ts: f64 = 1e-3;
        let tau: f64 = if filtered { 2e-3 } else { 0.0 };
        let a = if filtered { 1.0 - (-ts / tau).exp() } else { 1.0 };
        let beta = beta_frac * ts / a; // beta * a / ts < 0.45
        let n = p.r.len();
        let m = RateDependentPi::new(ts, p.p0 + 0.3, beta, tau, &p.r, &p.w, &c[..n]).unwrap();
        check_inverse(&m, &yd, "rate-dependent pi")?;
        check_trial(&m, &yd, &yd, "rate-dependent pi")?;
    }

    #[test]
    fn inverse_preisach(
        levels in 1usize..10,
        seed_w in preisach_weights(9),
        slope in 0.05..1.0f64,
        offset in -0.5..0.5f64,
        yd in input_strategy(2.0, 1..120),
    ) {
        let w = &seed_w[..cell_count(levels)];
        let mut pre = vec![0.0; w.len()];
        row_prefix(levels, w, &mut pre);
        let m = Preisach { lo: -1.0, hi: 1.0, levels, weights: w, prefix: &pre, offset, slope, memory: MAX_MEMORY }.validated().unwrap();
        check_inverse(&m, &yd, "preisach")?;
        check_trial(&m, &yd, &yd, "preisach")?;
    }

    #[test]
    fn inverse_pi_with_creep(
        p in invertible_pi(8, false),
        c in prop::collection::vec(0.0..0.3f64, 3),
        yd in input_strategy(3.0, 1..200),
    ) {
        let taus = [0.01, 0.1, 1.0];
        let mut gains = [0.0; 3];
        lag_gains(1e-3, &taus, &mut gains).unwrap();
        let m = WithCreep { model: Pi::new(p.p0, &p.r, &p.w).unwrap(), creep: Creep::new(&gains, &c).unwrap() };
        check_inverse(&m, &yd, "pi with creep")?;
        check_trial(&m, &yd, &yd, "pi with creep")?;
    }

    /// Analytic PI inverse (inverse PI driven by y_d) equals the per-sample inverse to 1e-12,
    /// for positive and for mixed-sign weights with positive partial sums.
    #[test]
    fn analytic_pi_inverse_equals_per_sample(
        p in prop_oneof![invertible_pi(10, false), invertible_pi(10, true)],
        yd in input_strategy(3.0, 1..200),
    ) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        let n = p.r.len();
        let (mut ri, mut wi) = (vec![0.0; n], vec![0.0; n]);
        let p0i = m.analytic_inverse(&mut ri, &mut wi).unwrap();
        let inv = Pi::new(p0i, &ri, &wi).expect("inverse thresholds must be increasing");
        let (va, _) = simulate(&inv, &yd);
        let vs = check_inverse(&m, &yd, "pi")?;
        let d = max_diff(&va, &vs);
        prop_assert!(d <= 1e-12, "analytic vs per-sample inverse differ by {:e}", d);
        // and the analytic inverse really inverts
        let (y, _) = simulate(&m, &va);
        prop_assert!(max_diff(&y, &yd) <= 1e-12);
    }
}

#[test]
fn analytic_inverse_parameters_of_a_known_model() {
    // p0 = 2, r = [1, 3], w = [2, -1]: S = [2, 4, 3]
    let m = Pi::new(2.0, &[1.0, 3.0], &[2.0, -1.0]).unwrap();
    let (mut ri, mut wi) = ([0.0; 2], [0.0; 2]);
    let p0i = m.analytic_inverse(&mut ri, &mut wi).unwrap();
    assert_eq!(p0i, 0.5);
    // r'_1 = phi(1) = 2, r'_2 = phi(3) = 6 + 2*2 = 10
    assert_eq!(ri, [2.0, 10.0]);
    // p'_1 = -2/(4*2) = -0.25, p'_2 = 1/(3*4) = 1/12
    assert_eq!(wi[0], -0.25);
    assert!((wi[1] - 1.0 / 12.0).abs() < 1e-16);
    // the inverse of the loading curve is the loading curve of the inverse
    let inv = Pi::new(p0i, &ri, &wi).unwrap();
    for s in [0.0, 0.5, 1.0, 2.0, 3.0, 7.0] {
        assert!((inv.loading_curve(m.loading_curve(s)) - s).abs() < 1e-14, "s={s}");
    }
}

#[test]
fn analytic_inverse_rejections() {
    let m = Pi::new(1.0, &[0.0, 1.0], &[1.0, 1.0]).unwrap();
    let (mut ri, mut wi) = ([0.0; 2], [0.0; 2]);
    assert!(matches!(m.analytic_inverse(&mut ri, &mut wi), Err(ModelError::NoAnalyticInverse(_))));
    let m = Pi::new(1.0, &[0.5, 1.0, 2.0], &[-0.5, 0.2, -0.9]).unwrap();
    let (mut ri, mut wi) = ([0.0; 3], [0.0; 3]);
    match m.analytic_inverse(&mut ri, &mut wi) {
        Err(ModelError::NotInvertible(3, s)) => {
            assert!((s - (1.0 - 0.5 + 0.2 - 0.9)).abs() < 1e-15)
        }
        other => panic!("expected NotInvertible(3, ..), got {other:?}"),
    }
    let mut short = [0.0; 2];
    assert_eq!(m.analytic_inverse(&mut short, &mut wi), Err(ModelError::Length("inv_thresholds", 3, 2)));
}

#[test]
fn unreachable_target_is_an_error_not_a_hang() {
    // tanh envelopes with P = 0 saturate: y is bounded, so a far target is unreachable
    let r = [0.1];
    let b = [1.0];
    let g = Envelope::Tanh([1.0, 1.0, 0.0, 0.0]);
    let m = GeneralizedPi::new([0.0; 4], &r, &b, g, g, (-5.0, 5.0)).unwrap();
    let mut st = vec![0.0; m.state_len()];
    assert_eq!(inverse_step(&m, &mut st, 5.0, 0.0, 7), Err(ModelError::Unreachable(7, 5.0)));
    let mut v = [0.0; 3];
    assert!(matches!(
        inverse_simulate(&m, &mut st, &[0.1, f64::NAN, 0.2], &mut v, 0.0),
        Err(ModelError::Unreachable(1, _))
    ));
}

#[test]
fn solve_increasing_on_kinked_and_flat_slopes() {
    // piecewise linear with slopes 0.01 and 100; NaN slope forces bisection
    let f = |v: f64| {
        if v < 1.0 {
            (0.01 * v, 0.01)
        } else {
            (0.01 + 100.0 * (v - 1.0), 100.0)
        }
    };
    for &t in &[-3.0, 0.0, 0.005, 0.01, 0.02, 50.0, 1e6] {
        let v = solve_increasing(f, t, 0.3).unwrap();
        assert!((f(v).0 - t).abs() <= 1e-12 * (1.0 + t.abs()), "t={t} v={v}");
        let g = |v: f64| (f(v).0, f64::NAN);
        let v2 = solve_increasing(g, t, 0.3).unwrap();
        assert!((f(v2).0 - t).abs() <= 1e-12 * (1.0 + t.abs()), "bisection t={t}");
    }
    assert_eq!(solve_increasing(|v: f64| (v.tanh(), 1.0), 2.0, 0.0), None);
}

/// Regression: on an S-shaped trial curve (tanh envelopes saturating on both sides) plain
/// Newton inside the bracket alternated between x = -0.39 and x = 3.12 forever and the solver
/// returned v = 3.12 with an output error of 0.47. The solver must force bisection when Newton
/// stops shrinking the bracket.
#[test]
fn newton_cycle_on_s_shaped_curve_is_broken() {
    let b = [0.3393283486216374, 0.01, 0.2436153630307812, 0.459200793786611, 0.14776088221735992];
    let r: Vec<f64> = (0..b.len()).map(|i| 0.05 + 0.1 * i as f64).collect();
    let rising = Envelope::Tanh([1.0, 1.2, -0.1, 0.0]);
    let falling = Envelope::Tanh([1.1, 1.0, 0.1, 0.05]);
    let m = GeneralizedPi::new([0.0, 0.13080873404961463, 0.0, 0.0], &r, &b, rising, falling, (-2.0, 2.0)).unwrap();
    let v_true = [-1.3559690566529872, 1.0682103549103203];
    let (yd, _) = simulate(&m, &v_true);
    let mut st = vec![0.0; m.state_len()];
    let mut v = [0.0; 2];
    inverse_simulate(&m, &mut st, &yd, &mut v, 0.0).unwrap();
    let (y, _) = simulate(&m, &v);
    assert!(max_diff(&y, &yd) <= 1e-12, "v = {v:?}, y = {y:?}, y_d = {yd:?}");
    assert!((v[1] - v_true[1]).abs() <= 1e-12);
    // the same on a scalar S-curve, from guesses on both sides of the inflexion
    let f = |x: f64| (x.tanh() + 0.05 * x, 1.0 - x.tanh().powi(2) + 0.05);
    for guess in [-3.0, -1.5, 0.7, 2.0, 5.0] {
        for target in [-1.2, -0.3, 0.0, 0.9, 1.1] {
            let x = solve_increasing(f, target, guess).unwrap();
            assert!((f(x).0 - target).abs() <= 1e-14, "guess {guess} target {target}: x = {x}");
        }
    }
}

/// The search stops at the model's own rounding: a PI and a seed-2 MPI inverse tracking an
/// 80 Hz scan take exactly three model evaluations per sample (guess, Newton step past the
/// root, Newton step from there) and land within a few ulps of the desired output. Before the
/// stop at rounding level the search walked on to the adjacent floats: 4.2 evaluations on
/// average, up to 54 when the root sat next to an operator's corner.
#[test]
fn inverse_takes_three_evaluations_per_sample_on_a_scan() {
    use piezohyst_core::inverse::solve_increasing;
    use piezohyst_core::spec::Family;
    use piezohyst_core::{Hysteresis, Invertible};
    use std::cell::Cell;
    for (name, dims) in [("pi", vec![9usize, 0]), ("gpi", vec![9, 0, 0, 0])] {
        let family = Family::parse(name, &dims).unwrap();
        let mut row = vec![0.0; family.param_len()];
        let (t0, w0) = if name == "pi" {
            row[0] = 0.13e-6;
            (1, 10)
        } else {
            row[0] = -100.0;
            row[1] = 250.0;
            row[3] = 0.13e-6;
            (14, 23)
        };
        for i in 0..9 {
            row[t0 + i] = 15.0 * i as f64;
            row[w0 + i] = 0.01e-6 / (1.0 + i as f64);
        }
        let mut scratch = vec![0.0; family.scratch_len()];
        let m = family.build(&row, &mut scratch).unwrap();
        let mut st = vec![0.0; m.state_len()];
        let evals = Cell::new(0usize);
        let (mut total, mut most, mut worst) = (0usize, 0usize, 0.0f64);
        let mut v = 0.0;
        let n = 20_000;
        for k in 0..n {
            let y = 9e-6 + 8e-6 * (2.0 * std::f64::consts::PI * 80.0 * k as f64 * 1e-4).sin();
            evals.set(0);
            let s: &[f64] = &st;
            v = solve_increasing(
                |x| {
                    evals.set(evals.get() + 1);
                    m.trial(s, x)
                },
                y,
                v,
            )
            .unwrap();
            let out = m.step(&mut st, v);
            worst = worst.max(((out - y) / y).abs());
            total += evals.get();
            most = most.max(evals.get());
        }
        assert!(total <= 3 * n + 10 && most <= 5, "{name}: {total} evaluations for {n} samples, at most {most}");
        assert!(worst <= 8.0 * f64::EPSILON, "{name}: relative residual {worst:e}");
    }
}
