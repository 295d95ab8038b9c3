//! Generalized play operator, envelopes and the GPI/MPI model (docs/spec.md §2.2) against the
//! defining formulas written out independently.
mod common;

use common::*;
use piezohyst_core::envelope::Envelope;
use piezohyst_core::generalized::{generalized_play, GeneralizedPi};
use piezohyst_core::pi::Pi;
use piezohyst_core::Hysteresis;
use proptest::prelude::*;

/// Envelopes written out with std's tanh (libm's may differ in the last bit).
fn g_ref(e: &Envelope, v: f64) -> f64 {
    match *e {
        Envelope::Identity => v,
        Envelope::Polynomial(c) => c[0] + c[1] * v + c[2] * v * v + c[3] * v * v * v,
        Envelope::Tanh(a) => a[0] * (a[1] * v + a[2]).tanh() + a[3],
    }
}

fn envelope_strategy() -> impl Strategy<Value = Envelope> {
    prop_oneof![
        Just(Envelope::Identity),
        // c3 > 0 and c2^2 < 3 c1 c3: increasing everywhere
        (-0.5..0.5f64, 0.5..1.5f64, -0.3..0.3f64, 0.1..0.5f64)
            .prop_map(|(c0, c1, c2, c3)| Envelope::Polynomial([c0, c1, c2, c3])),
        (0.5..2.0f64, 0.3..2.0f64, -0.5..0.5f64, -0.3..0.3f64)
            .prop_map(|(a0, a1, a2, a3)| Envelope::Tanh([a0, a1, a2, a3])),
    ]
}

proptest! {
    #![proptest_config(cfg(256))]

    /// Envelope value, slope (vs central difference) and inverse.
    #[test]
    fn envelope_eval_slope_inverse(e in envelope_strategy(), v in -2.0..2.0f64) {
        let g = e.eval(v);
        prop_assert!((g - g_ref(&e, v)).abs() <= 1e-14 * (1.0 + g.abs()));
        let h = 1e-6;
        let fd = (g_ref(&e, v + h) - g_ref(&e, v - h)) / (2.0 * h);
        prop_assert!((e.slope(v) - fd).abs() <= 1e-7 * (1.0 + fd.abs()), "slope {} vs {}", e.slope(v), fd);
        prop_assert!(e.slope(v) > 0.0);
        let back = e.inverse(g, 0.0).unwrap();
        prop_assert!((back - v).abs() <= 1e-9, "inverse {} vs {}", back, v);
        e.check_increasing("rising", -2.0, 2.0).unwrap();
    }

    /// GPI output and states equal the generalized-play formula
    /// z = max(g_l(v) - r, min(g_r(v) + r, z)), y = P(v) + sum b z.
    #[test]
    fn gpi_matches_formula(
        rising in envelope_strategy(),
        falling in envelope_strategy(),
        poly in prop::array::uniform4(-1.0..1.0f64),
        b in prop::collection::vec(-0.5..1.0f64, 1..8),
        v in input_strategy(1.5, 1..150),
    ) {
        // thresholds wide enough that these envelopes never cross on [-1.5, 1.5]
        let gap = (0..=300).map(|j| -1.5 + 0.01 * j as f64).map(|x| g_ref(&rising, x) - g_ref(&falling, x)).fold(0.0f64, f64::max);
        let r: Vec<f64> = (0..b.len()).map(|i| 0.5 * gap + 0.01 + 0.2 * i as f64).collect();
        let m = GeneralizedPi::new(poly, &r, &b, rising, falling, (-1.5, 1.5)).unwrap();
        let mut st = vec![0.0; m.state_len()];
        let mut z = vec![0.0; r.len()];
        for (k, &vk) in v.iter().enumerate() {
            let y = m.step(&mut st, vk);
            let (gl, gr) = (g_ref(&rising, vk), g_ref(&falling, vk));
            let mut y_ref = poly[0] + poly[1] * vk + poly[2] * vk * vk + poly[3] * vk * vk * vk;
            for i in 0..r.len() {
                z[i] = (gl - r[i]).max((gr + r[i]).min(z[i]));
                prop_assert!((st[i] - z[i]).abs() <= 1e-13, "k={} i={}", k, i);
                // the operator is idempotent at a fixed input (repeated samples change nothing)
                let again = generalized_play(st[i], vk, r[i], &rising, &falling);
                prop_assert_eq!(again.to_bits(), st[i].to_bits());
                y_ref += b[i] * z[i];
            }
            prop_assert!((y - y_ref).abs() <= 1e-12 * (1.0 + y_ref.abs()), "k={}: {} vs {}", k, y, y_ref);
        }
    }

    /// With identity envelopes and P(v) = p0 v the GPI is the classical PI (equal values;
    /// only the sign of a zero may differ).
    #[test]
    fn gpi_with_identity_envelopes_is_pi(
        p0 in -1.0..2.0f64,
        inc in prop::collection::vec(0.01..0.5f64, 1..8),
        w in prop::collection::vec(-1.0..1.0f64, 8),
        v in input_strategy(2.0, 1..150),
    ) {
        let r = thresholds_from(0.0, &inc);
        let n = r.len();
        let g = GeneralizedPi::new([0.0, p0, 0.0, 0.0], &r, &w[..n], Envelope::Identity, Envelope::Identity, (f64::NEG_INFINITY, f64::INFINITY)).unwrap();
        let pi = Pi::new(p0, &r, &w[..n]).unwrap();
        let (yg, sg) = simulate(&g, &v);
        let (yp, sp) = simulate(&pi, &v);
        for k in 0..v.len() {
            prop_assert!(yg[k] == yp[k], "k={}: {} vs {}", k, yg[k], yp[k]);
        }
        prop_assert!(sg == sp);
    }
}

/// The seed-2 MPI reference set (docs/spec.md §2.2) on a known input: the loading branch from the
/// relaxed state is P(v) + sum b_i max(v - r_i, 0).
#[test]
fn mpi_seed2_loading_branch() {
    let r = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
    let b = [0.2054, 0.1985, 0.0237, 0.0148, 0.0456, 0.0645, 0.0051, 0.0014, 0.0033];
    let poly = [0.0, 0.2547, -0.00358, 0.7123];
    let m = GeneralizedPi::new(poly, &r, &b, Envelope::Identity, Envelope::Identity, (-1.0, 1.0)).unwrap();
    let v: Vec<f64> = (0..=20).map(|k| k as f64 / 20.0).collect();
    let (y, _) = simulate(&m, &v);
    for (k, &vk) in v.iter().enumerate() {
        let mut want = 0.2547 * vk - 0.00358 * vk * vk + 0.7123 * vk * vk * vk;
        for i in 0..9 {
            want += b[i] * (vk - r[i]).max(0.0);
        }
        assert!((y[k] - want).abs() < 1e-15, "v={vk}: {} vs {want}", y[k]);
    }
    // at v = 1: P(1) + sum b_i (1 - r_i)
    let p1 = 0.2547 - 0.00358 + 0.7123;
    let s: f64 = b.iter().zip(&r).map(|(bi, ri)| bi * (1.0 - ri)).sum();
    assert!((y[20] - (p1 + s)).abs() < 1e-15);
    // descending back to 0 leaves a remanence: the plays hold at v + r_i
    let (y2, st) = simulate(&m, &[1.0, 0.0]);
    let rem: f64 = b.iter().zip(&r).map(|(bi, ri)| bi * ri.min(1.0 - ri)).sum();
    assert!((y2[1] - rem).abs() < 1e-15, "{} vs {}", y2[1], rem);
    assert!(st.iter().zip(&r).all(|(z, ri)| (z - ri.min(1.0 - ri)).abs() < 1e-15));
}
