//! Flat parameter rows (`spec::Family`): every family builds from a row into the same model
//! as direct construction, sizes are consistent, and bad rows give the right `ModelError`.
mod common;

use common::*;
use piezohyst_core::creep::{lag_gains, Creep, WithCreep};
use piezohyst_core::differential::{BoucWen, Dahl, Duhem};
use piezohyst_core::envelope::Envelope;
use piezohyst_core::generalized::GeneralizedPi;
use piezohyst_core::pi::Pi;
use piezohyst_core::preisach::{cell_count, row_prefix, Preisach};
use piezohyst_core::rate::RateDependentPi;
use piezohyst_core::spec::{Base, Family, Model, MAX_OPERATORS};
use piezohyst_core::{Hysteresis, Invertible, ModelError};

const MAXI: usize = usize::MAX;

fn input() -> Vec<f64> {
    let mut v: Vec<f64> = (0..300).map(|k| 1.3 * (0.07 * k as f64).sin() * (0.011 * k as f64).cos()).collect();
    v.extend([0.4, 0.4, -0.9, 1.5, -1.5, 0.0]);
    v
}

/// Build `row` for `fam`, check sizes, and compare its outputs and state with `direct`
/// (bit-identical); also check `trial` == `step` for the built model.
fn check_family<D: Hysteresis>(name: &str, dims: &[usize], row: &[f64], direct: &D, invertible: bool) {
    let fam = Family::parse(name, dims).unwrap();
    assert_eq!(fam.param_len(), row.len(), "{name}: param_len");
    let mut scratch = vec![0.0; fam.scratch_len()];
    let m = fam.build(row, &mut scratch).unwrap();
    assert_eq!(m.state_len(), fam.state_len(), "{name}: state_len of the model vs the family");
    assert_eq!(direct.state_len(), fam.state_len(), "{name}: state_len vs direct construction");
    let v = input();
    let (y, st) = simulate(&m, &v);
    let (yd, std) = simulate(direct, &v);
    assert_bits_eq(&y, &yd, &format!("{name}: outputs"));
    assert_bits_eq(&st, &std, &format!("{name}: final state"));
    // the relaxed state is written by reset, whatever was there
    let mut s1 = vec![3.0; fam.state_len()];
    let mut s2 = vec![-3.0; fam.state_len()];
    m.reset(&mut s1);
    direct.reset(&mut s2);
    assert_bits_eq(&s1, &s2, &format!("{name}: reset"));
    if invertible {
        let mut s = vec![0.0; fam.state_len()];
        m.reset(&mut s);
        for &x in &v[..50] {
            let (yt, _) = m.trial(&s, x + 0.01);
            let mut c = s.clone();
            assert_eq!(yt.to_bits(), m.step(&mut c, x + 0.01).to_bits(), "{name}: trial vs step");
            m.step(&mut s, x);
        }
    }
}

fn build_err(name: &str, dims: &[usize], row: &[f64]) -> ModelError {
    let fam = Family::parse(name, dims).unwrap();
    let mut scratch = vec![0.0; fam.scratch_len()];
    match fam.build(row, &mut scratch) {
        Ok(_) => panic!("{name}: row {row:?} was accepted"),
        Err(e) => e,
    }
}

const R3: [f64; 3] = [0.1, 0.4, 0.8];
const W3: [f64; 3] = [0.5, -0.2, 0.3];

fn pi_row(p0: f64, r: &[f64], w: &[f64]) -> Vec<f64> {
    let mut row = vec![p0];
    row.extend_from_slice(r);
    row.extend_from_slice(w);
    row
}

#[test]
fn pi_round_trip() {
    check_family("pi", &[3, 0], &pi_row(0.9, &R3, &W3), &Pi::new(0.9, &R3, &W3).unwrap(), true);
    check_family("pi", &[0, 0], &[1.7], &Pi::new(1.7, &[], &[]).unwrap(), true);
}

#[test]
fn pi_with_creep_round_trip() {
    let (ts, taus, c) = (1e-3, [0.01, 0.5], [0.05, 0.02]);
    let mut row = pi_row(0.9, &R3, &W3);
    row.push(ts);
    row.extend_from_slice(&taus);
    row.extend_from_slice(&c);
    let mut gains = [0.0; 2];
    lag_gains(ts, &taus, &mut gains).unwrap();
    let direct = WithCreep { model: Pi::new(0.9, &R3, &W3).unwrap(), creep: Creep::new(&gains, &c).unwrap() };
    check_family("pi", &[3, 2], &row, &direct, true);
    assert_eq!(Family::parse("pi", &[3, 2]).unwrap().state_len(), 5);
    assert_eq!(Family::parse("pi", &[3, 2]).unwrap().param_len(), 7 + 5);
}

fn gpi_row(range: (f64, f64), poly: [f64; 4], rising: [f64; 4], falling: [f64; 4], r: &[f64], b: &[f64]) -> Vec<f64> {
    let mut row = vec![range.0, range.1];
    row.extend_from_slice(&poly);
    row.extend_from_slice(&rising);
    row.extend_from_slice(&falling);
    row.extend_from_slice(r);
    row.extend_from_slice(b);
    row
}

#[test]
fn gpi_round_trip() {
    let (poly, rising, falling) = ([0.0, 0.25, -0.004, 0.7], [-0.02, 0.9, 0.05, 0.3], [1.5, 1.0, 0.0, 0.05]);
    let row = gpi_row((-1.0, 1.0), poly, rising, falling, &R3, &W3);
    let direct =
        GeneralizedPi::new(poly, &R3, &W3, Envelope::Polynomial(rising), Envelope::Tanh(falling), (-1.0, 1.0)).unwrap();
    check_family("gpi", &[3, 1, 2, 0], &row, &direct, true);
    // identity envelopes ignore their coefficient slots
    let row = gpi_row((-2.0, 2.0), poly, [5.0, -7.0, 1.0, 2.0], [0.0; 4], &R3, &W3);
    let direct = GeneralizedPi::new(poly, &R3, &W3, Envelope::Identity, Envelope::Identity, (-2.0, 2.0)).unwrap();
    check_family("gpi", &[3, 0, 0, 0], &row, &direct, true);
    // infinite input range is allowed
    let row = gpi_row((f64::NEG_INFINITY, f64::INFINITY), poly, [0.0; 4], [0.0; 4], &R3, &W3);
    let direct =
        GeneralizedPi::new(poly, &R3, &W3, Envelope::Identity, Envelope::Identity, (f64::NEG_INFINITY, f64::INFINITY))
            .unwrap();
    check_family("gpi", &[3, 0, 0, 0], &row, &direct, true);
}

#[test]
fn rdpi_round_trip() {
    let (ts, p0, beta, tau, c) = (1e-3, 0.8, 1e-4, 2e-3, [1e-6, 0.0, 2e-6]);
    let mut row = vec![ts, p0, beta, tau];
    row.extend_from_slice(&R3);
    row.extend_from_slice(&W3);
    row.extend_from_slice(&c);
    let direct = RateDependentPi::new(ts, p0, beta, tau, &R3, &W3, &c).unwrap();
    check_family("rdpi", &[3, 0], &row, &direct, true);
    assert_eq!(Family::parse("rdpi", &[3, 0]).unwrap().state_len(), 6);
}

#[test]
fn creep_round_trip() {
    let (ts, taus, c) = (1e-3, [0.01, 0.1, 1.0], [0.1, 0.05, 0.02]);
    let mut row = vec![ts];
    row.extend_from_slice(&taus);
    row.extend_from_slice(&c);
    let mut gains = [0.0; 3];
    lag_gains(ts, &taus, &mut gains).unwrap();
    check_family("creep", &[3], &row, &Creep::new(&gains, &c).unwrap(), true);
    let fam = Family::parse("creep", &[3]).unwrap();
    let mut scratch = vec![0.0; fam.scratch_len()];
    assert!(matches!(fam.build(&row, &mut scratch).unwrap(), Model { base: Base::Nothing, creep: Some(_) }));
    // gains are 1 - exp(-ts/tau)
    for (g, t) in gains.iter().zip(taus) {
        assert!((g - (1.0 - (-ts / t).exp())).abs() < 1e-16);
    }
}

#[test]
fn preisach_round_trip() {
    let levels = 3;
    let w: Vec<f64> = (0..cell_count(levels)).map(|i| 0.05 * (i + 1) as f64).collect();
    let mut row = vec![-1.5, 1.5, 0.2, 0.3];
    row.extend_from_slice(&w);
    let mut pre = vec![0.0; w.len()];
    row_prefix(levels, &w, &mut pre);
    let direct = Preisach { lo: -1.5, hi: 1.5, levels, weights: &w, prefix: &pre, offset: 0.2, slope: 0.3, memory: 16 }
        .validated()
        .unwrap();
    check_family("preisach", &[levels, 16], &row, &direct, true);
    let fam = Family::parse("preisach", &[levels, 16]).unwrap();
    assert_eq!((fam.param_len(), fam.state_len(), fam.scratch_len()), (10, 18, 6));
}

#[test]
fn differential_round_trips() {
    check_family("boucwen", &[], &[0.3, 0.03, 0.01, 1.0, 0.1], &BoucWen::new(0.3, 0.03, 0.01, 1.0, 0.1).unwrap(), true);
    check_family("boucwen", &[], &[1.0, 0.5, 0.2, 2.0, 0.0], &BoucWen::new(1.0, 0.5, 0.2, 2.0, 0.0).unwrap(), false);
    let (f, g) = ([0.1, 1.2, -0.1, 0.05], [0.5, 0.1, 0.2, -0.05]);
    let mut row = vec![2.0];
    row.extend_from_slice(&f);
    row.extend_from_slice(&g);
    check_family("duhem", &[], &row, &Duhem::new(2.0, f, g).unwrap(), true);
    check_family("dahl", &[], &[1.5, 0.8, 0.5], &Dahl::new(1.5, 0.8, 0.5).unwrap(), true);
    for name in ["boucwen", "duhem", "dahl"] {
        assert_eq!(Family::parse(name, &[]).unwrap().state_len(), 2);
    }
}

#[test]
fn parse_errors() {
    assert_eq!(Family::parse("pi", &[3]), Err(ModelError::Length("dims", 2, 1)));
    assert_eq!(Family::parse("gpi", &[3, 0, 0]), Err(ModelError::Length("dims", 4, 3)));
    assert_eq!(Family::parse("dahl", &[1]), Err(ModelError::Length("dims", 0, 1)));
    assert_eq!(Family::parse("gpi", &[3, 3, 0, 0]), Err(ModelError::Structure("envelope kind", 3)));
    assert_eq!(Family::parse("gpi", &[3, 0, 7, 0]), Err(ModelError::Structure("envelope kind", 7)));
    assert_eq!(Family::parse("nope", &[]), Err(ModelError::Structure("family (unknown name)", 0)));
    assert_eq!(Family::parse("preisach", &[0, 8]), Err(ModelError::OutOfRange("levels", MAXI, 0.0, 1.0, 1000.0)));
    assert_eq!(Family::parse("preisach", &[1001, 8]), Err(ModelError::OutOfRange("levels", MAXI, 1001.0, 1.0, 1000.0)));
    let e = Family::parse("pi", &[MAX_OPERATORS + 1, 0]).unwrap_err();
    assert_eq!(e, ModelError::OutOfRange("n", MAXI, (MAX_OPERATORS + 1) as f64, 0.0, MAX_OPERATORS as f64));
    assert_eq!(e.to_string(), "n = 100001 must lie within [0, 100000]");
    assert_eq!(
        Family::parse("rdpi", &[2, MAX_OPERATORS + 1]),
        Err(ModelError::OutOfRange("creep_terms", MAXI, (MAX_OPERATORS + 1) as f64, 0.0, MAX_OPERATORS as f64))
    );
}

#[test]
fn wrong_lengths() {
    let fam = Family::parse("pi", &[3, 0]).unwrap();
    let mut scratch = vec![0.0; fam.scratch_len()];
    let row = pi_row(0.9, &R3, &W3);
    assert_eq!(fam.build(&row[..6], &mut scratch).err(), Some(ModelError::Length("params", 7, 6)));
    let mut long = row.clone();
    long.push(0.0);
    assert_eq!(fam.build(&long, &mut scratch).err(), Some(ModelError::Length("params", 7, 8)));
    let fam = Family::parse("preisach", &[3, 8]).unwrap();
    let mut scratch = vec![0.0; 5];
    let row = vec![0.1; fam.param_len()];
    assert_eq!(fam.build(&row, &mut scratch).err(), Some(ModelError::Length("scratch", 6, 5)));
    // direct constructors check the slices they pair
    assert_eq!(Pi::new(1.0, &R3, &W3[..2]).err(), Some(ModelError::Length("weights", 3, 2)));
    assert_eq!(
        RateDependentPi::new(1e-3, 1.0, 0.0, 0.0, &R3, &W3, &[0.0; 2]).err(),
        Some(ModelError::Length("rate_weights", 3, 2))
    );
    assert_eq!(Creep::new(&[0.5, 0.5], &[1.0]).err(), Some(ModelError::Length("creep_weights", 2, 1)));
}

#[test]
fn nan_parameters_are_named() {
    let e = build_err("pi", &[3, 0], &pi_row(f64::NAN, &R3, &W3));
    assert!(matches!(e, ModelError::NotFinite("p0", MAXI, x) if x.is_nan()), "{e:?}");
    let e = build_err("pi", &[3, 0], &pi_row(1.0, &R3, &[0.1, f64::NAN, 0.2]));
    assert!(matches!(e, ModelError::NotFinite("weights", 1, x) if x.is_nan()), "{e:?}");
    let e = build_err("pi", &[3, 0], &pi_row(1.0, &[0.1, 0.2, f64::INFINITY], &W3));
    assert_eq!(e, ModelError::NotFinite("thresholds", 2, f64::INFINITY));
    let mut row = pi_row(1.0, &R3, &W3);
    row.extend_from_slice(&[1e-3, 0.1, f64::NAN]);
    let e = build_err("pi", &[3, 1], &row);
    assert!(matches!(e, ModelError::NotFinite("creep_weights", 0, x) if x.is_nan()), "{e:?}");
    let e = build_err(
        "gpi",
        &[3, 1, 1, 0],
        &gpi_row((-1.0, 1.0), [0.0, f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], &R3, &W3),
    );
    assert!(matches!(e, ModelError::NotFinite("polynomial", 1, x) if x.is_nan()), "{e:?}");
    let e = build_err(
        "gpi",
        &[3, 1, 1, 0],
        &gpi_row((-1.0, 1.0), [0.0; 4], [0.0, 1.0, f64::NAN, 0.0], [0.0, 1.0, 0.0, 0.0], &R3, &W3),
    );
    assert!(matches!(e, ModelError::NotFinite("rising", 2, x) if x.is_nan()), "{e:?}");
    let e = build_err("gpi", &[3, 0, 0, 0], &gpi_row((f64::NAN, 1.0), [0.0; 4], [0.0; 4], [0.0; 4], &R3, &W3));
    assert!(matches!(e, ModelError::NotFinite("input_range", 0, x) if x.is_nan()), "{e:?}");
    let e = build_err("boucwen", &[], &[1.0, 0.5, f64::NAN, 1.0, 0.0]);
    assert!(matches!(e, ModelError::NotFinite(_, 2, x) if x.is_nan()), "{e:?}");
    let e = build_err("duhem", &[], &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::NAN, 0.0]);
    assert!(matches!(e, ModelError::NotFinite("g", 2, x) if x.is_nan()), "{e:?}");
    let e = build_err("dahl", &[], &[1.0, f64::NAN, 1.0]);
    assert!(matches!(e, ModelError::NotFinite("h_c", MAXI, x) if x.is_nan()), "{e:?}");
    let mut row = vec![-1.0, 1.0, 0.0, 0.1];
    row.extend_from_slice(&[0.1, f64::NAN, 0.1]);
    let e = build_err("preisach", &[2, 8], &row);
    assert!(matches!(e, ModelError::NotFinite("weights", 1, x) if x.is_nan()), "{e:?}");
    let e = build_err("rdpi", &[1, 0], &[1e-3, 1.0, f64::NAN, 0.0, 0.1, 0.5, 0.0]);
    assert!(matches!(e, ModelError::NotFinite("beta", MAXI, x) if x.is_nan()), "{e:?}");
}

#[test]
fn thresholds_must_be_ordered_and_nonnegative() {
    assert_eq!(
        build_err("pi", &[3, 0], &pi_row(1.0, &[0.1, 0.5, 0.3], &W3)),
        ModelError::NotIncreasing("thresholds", 2, 0.3)
    );
    assert_eq!(
        build_err("pi", &[3, 0], &pi_row(1.0, &[0.1, 0.1, 0.3], &W3)),
        ModelError::NotIncreasing("thresholds", 1, 0.1)
    );
    assert_eq!(
        build_err("pi", &[3, 0], &pi_row(1.0, &[-0.1, 0.1, 0.3], &W3)),
        ModelError::Negative("thresholds", 0, -0.1)
    );
    assert_eq!(
        build_err("gpi", &[3, 0, 0, 0], &gpi_row((-1.0, 1.0), [0.0; 4], [0.0; 4], [0.0; 4], &[0.0, 0.4, 0.2], &W3)),
        ModelError::NotIncreasing("thresholds", 2, 0.2)
    );
    assert_eq!(
        build_err("rdpi", &[2, 0], &[1e-3, 1.0, 0.0, 0.0, 0.3, -0.2, 0.1, 0.1, 0.0, 0.0]),
        ModelError::Negative("thresholds", 1, -0.2)
    );
    // a zero threshold is fine (it carries the linear part of a GPI)
    let fam = Family::parse("pi", &[3, 0]).unwrap();
    let mut scratch = vec![];
    assert!(fam.build(&pi_row(1.0, &[0.0, 0.1, 0.3], &W3), &mut scratch).is_ok());
}

#[test]
fn non_invertible_weights_name_the_partial_sum() {
    let fam = Family::parse("pi", &[4, 0]).unwrap();
    let mut scratch = vec![];
    // S = [1, 0.6, 0.9, -0.1, ...]: S_3 is the first non-positive partial sum
    let row = pi_row(1.0, &[0.1, 0.2, 0.3, 0.4], &[-0.4, 0.3, -1.0, 5.0]);
    let m = fam.build(&row, &mut scratch).unwrap(); // a forward model may be non-invertible
    let Base::Pi(pi) = m.base else { panic!("not a PI") };
    match pi.check_invertible() {
        Err(ModelError::NotInvertible(3, s)) => {
            assert!((s - (1.0 - 0.4 + 0.3 - 1.0)).abs() < 1e-15, "{s}")
        }
        other => panic!("expected NotInvertible(3, ..), got {other:?}"),
    }
    let (mut ri, mut wi) = ([0.0; 4], [0.0; 4]);
    assert!(matches!(pi.analytic_inverse(&mut ri, &mut wi), Err(ModelError::NotInvertible(3, _))));
    // S_i = 0 exactly is not invertible either
    let row = pi_row(1.0, &[0.1, 0.2, 0.3, 0.4], &[-0.5, -0.5, 0.1, 0.1]);
    let m = fam.build(&row, &mut scratch).unwrap();
    let Base::Pi(pi) = m.base else { panic!() };
    assert_eq!(pi.check_invertible(), Err(ModelError::NotInvertible(2, 0.0)));
    // p0 <= 0 is S_0
    let row = pi_row(-0.5, &[0.1, 0.2, 0.3, 0.4], &[1.0; 4]);
    let m = fam.build(&row, &mut scratch).unwrap();
    let Base::Pi(pi) = m.base else { panic!() };
    assert_eq!(pi.check_invertible(), Err(ModelError::NotInvertible(0, -0.5)));
    // and the message names the index and the value
    let msg = ModelError::NotInvertible(3, -0.1).to_string();
    assert!(msg.contains("S[3]") && msg.contains("-0.1"), "{msg}");
}

#[test]
fn envelope_errors() {
    let r = [0.1, 0.3];
    let b = [0.5, 0.5];
    let row = |rk: [f64; 4], fk: [f64; 4]| gpi_row((-1.0, 1.0), [0.0; 4], rk, fk, &r, &b);
    // decreasing everywhere: reported at the first checked point, the range's lower end
    assert_eq!(
        build_err("gpi", &[2, 1, 1, 0], &row([0.0, -1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0])),
        ModelError::EnvelopeNotMonotone("rising", -1.0, -1.0)
    );
    // increasing at both ends but not at the vertex of g' (v = 0, slope -0.3)
    assert_eq!(
        build_err("gpi", &[2, 1, 1, 0], &row([0.0, 1.0, 0.0, 0.0], [0.0, -0.3, 0.0, 1.0])),
        ModelError::EnvelopeNotMonotone("falling", 0.0, -0.3)
    );
    // the same cubic is fine on a range that excludes the dip (g_r = g_l + 0.5: no crossing)
    let fam = Family::parse("gpi", &[2, 1, 1, 0]).unwrap();
    let mut scratch = vec![];
    let (gl, gr) = ([0.0, -0.3, 0.0, 1.0], [0.5, -0.3, 0.0, 1.0]);
    assert!(fam.build(&gpi_row((0.5, 2.0), [0.0; 4], gl, gr, &r, &b), &mut scratch).is_ok());
    assert_eq!(
        build_err("gpi", &[2, 1, 1, 0], &gpi_row((-1.0, 1.0), [0.0; 4], gl, gr, &r, &b)),
        ModelError::EnvelopeNotMonotone("rising", 0.0, -0.3)
    );
    // a cubic with c3 < 0 cannot be increasing on an infinite range
    let inf =
        gpi_row((f64::NEG_INFINITY, f64::INFINITY), [0.0; 4], [0.0, 1.0, 0.0, -0.1], [0.0, 1.0, 0.0, 0.0], &r, &b);
    assert!(matches!(build_err("gpi", &[2, 1, 1, 0], &inf), ModelError::EnvelopeNotMonotone("rising", _, _)));
    // tanh with a0*a1 <= 0
    assert!(matches!(
        build_err("gpi", &[2, 2, 2, 0], &row([1.0, 1.0, 0.0, 0.0], [1.0, -2.0, 0.0, 0.0])),
        ModelError::EnvelopeNotMonotone("falling", _, s) if s == -2.0
    ));
    // crossing envelopes: g_l(v) - r_1 > g_r(v) + r_1 somewhere on the range
    let e = build_err("gpi", &[2, 1, 1, 0], &row([0.3, 1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]));
    assert!(matches!(e, ModelError::EnvelopesCross(_, 0)), "{e:?}");
    // lower end not below the upper end
    let bad = gpi_row((1.0, 1.0), [0.0; 4], [0.0; 4], [0.0; 4], &r, &b);
    assert_eq!(build_err("gpi", &[2, 0, 0, 0], &bad), ModelError::NotIncreasing("input_range", 1, 1.0));
}

#[test]
fn other_range_errors() {
    // rdpi
    assert_eq!(
        build_err("rdpi", &[1, 0], &[0.0, 1.0, 0.0, 0.0, 0.1, 0.5, 0.0]),
        ModelError::NotPositive("ts", MAXI, 0.0)
    );
    assert_eq!(
        build_err("rdpi", &[1, 0], &[1e-3, 1.0, -1.0, 0.0, 0.1, 0.5, 0.0]),
        ModelError::Negative("beta", MAXI, -1.0)
    );
    assert_eq!(
        build_err("rdpi", &[1, 0], &[1e-3, 1.0, 0.0, -1.0, 0.1, 0.5, 0.0]),
        ModelError::Negative("filter_tau", MAXI, -1.0)
    );
    // creep
    assert_eq!(build_err("creep", &[2], &[1e-3, 0.1, 0.0, 1.0, 1.0]), ModelError::NotPositive("taus", 1, 0.0));
    assert_eq!(build_err("creep", &[1], &[-1e-3, 0.1, 1.0]), ModelError::NotPositive("ts", MAXI, -1e-3));
    // preisach
    let mut row = vec![1.0, 1.0, 0.0, 0.1, 0.1, 0.1, 0.1];
    assert_eq!(build_err("preisach", &[2, 8], &row), ModelError::NotIncreasing("input_range", 1, 1.0));
    row[0] = -1.0;
    row[5] = -0.2;
    assert_eq!(build_err("preisach", &[2, 8], &row), ModelError::Negative("weights", 1, -0.2));
    row[5] = 0.2;
    assert_eq!(build_err("preisach", &[2, 1], &row), ModelError::Structure("memory", 1));
    // differential
    assert_eq!(
        build_err("boucwen", &[], &[1.0, 0.5, 0.2, 0.5, 0.0]),
        ModelError::NotPositive("n (must be >= 1)", MAXI, 0.5)
    );
    assert_eq!(build_err("dahl", &[], &[1.0, 0.0, 1.0]), ModelError::NotPositive("h_c", MAXI, 0.0));
    assert_eq!(build_err("dahl", &[], &[-1.0, 1.0, 1.0]), ModelError::NotPositive("sigma", MAXI, -1.0));
    assert_eq!(
        build_err("duhem", &[], &[-1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        ModelError::Negative("alpha", MAXI, -1.0)
    );
}

#[test]
fn error_messages_name_the_argument_and_value() {
    let cases = [
        (ModelError::NotFinite("p0", MAXI, f64::NAN), ["p0", "NaN"]),
        (ModelError::NotFinite("weights", 4, f64::INFINITY), ["weights[4]", "inf"]),
        (ModelError::Negative("thresholds", 0, -0.5), ["thresholds[0]", "-0.5"]),
        (ModelError::NotIncreasing("thresholds", 2, 0.25), ["thresholds[2]", "thresholds[1]"]),
        (ModelError::Length("weights", 3, 2), ["weights", "length 2"]),
        (ModelError::EnvelopeNotMonotone("rising", 0.5, -0.3), ["rising", "-0.3"]),
        (ModelError::Unreachable(17, 4.5), ["17", "4.5"]),
    ];
    for (e, words) in cases {
        let msg = e.to_string();
        for w in words {
            assert!(msg.contains(w), "{msg:?} should contain {w:?}");
        }
    }
}
