//! Play operator and classical Prandtl–Ishlinskii model (docs/spec.md §2.1): band, Lipschitz bound,
//! first-sample convention, rate independence, loading curve, odd symmetry, wiping-out.
mod common;

use common::*;
use piezohyst_core::pi::{play, Pi};
use piezohyst_core::Hysteresis;
use proptest::prelude::*;

/// A PI model (owned parameters) drawn at random: thresholds start at `>= 0`.
#[derive(Debug, Clone)]
struct PiParams {
    p0: f64,
    r: Vec<f64>,
    w: Vec<f64>,
}

fn pi_params(max_n: usize) -> impl Strategy<Value = PiParams> {
    (1..=max_n).prop_flat_map(|n| {
        (-1.0..2.0f64, 0.0..0.3f64, prop::collection::vec(0.01..0.5f64, n), prop::collection::vec(-1.0..1.0f64, n))
            .prop_map(|(p0, r0, inc, w)| PiParams { p0, r: thresholds_from(r0, &inc), w })
    })
}

/// Reference play written independently of the crate: `max(v - r, min(v + r, z))`.
fn play_ref(z: f64, v: f64, r: f64) -> f64 {
    (v - r).max((v + r).min(z))
}

#[test]
fn play_known_values() {
    // rising out of the band, inside the band, falling out of the band, r = 0 follows v
    assert_eq!(play(0.0, 3.0, 1.0), 2.0);
    assert_eq!(play(0.0, -0.5, 1.0), 0.0);
    assert_eq!(play(0.0, -3.0, 1.0), -2.0);
    assert_eq!(play(2.0, 2.5, 1.0), 2.0);
    assert_eq!(play(2.0, 0.5, 1.0), 1.5);
    assert_eq!(play(-7.0, 1.25, 0.0), 1.25);
    // a full cycle of a one-operator PI: p0 = 0.5, r = 1, w = 2
    let m = Pi::new(0.5, &[1.0], &[2.0]).unwrap();
    let v = [0.0, 2.0, 3.0, 1.0, 0.0, -2.0, 0.0, 3.0];
    let z = [0.0, 1.0, 2.0, 2.0, 1.0, -1.0, -1.0, 2.0];
    let (y, st) = simulate(&m, &v);
    for k in 0..v.len() {
        assert_eq!(y[k], 0.5 * v[k] + 2.0 * z[k], "sample {k}");
    }
    assert_eq!(st, vec![2.0]);
}

proptest! {
    #![proptest_config(cfg(256))]

    /// Every play output stays in its band `[v - r, v + r]`, moves by no more than the input
    /// (here on a dyadic grid, so all arithmetic is exact and the bound is asserted exactly),
    /// and the first sample from the relaxed state is `max(v0 - r, min(v0 + r, 0))`.
    #[test]
    fn play_band_lipschitz_first_sample_exact(
        rj in prop::collection::vec(0i32..200, 1..6),
        vj in prop::collection::vec(-400i32..400, 1..150),
    ) {
        let mut r: Vec<f64> = rj.iter().map(|&j| j as f64 / 64.0).collect();
        r.sort_by(|a, b| a.partial_cmp(b).unwrap());
        r.dedup();
        let w = vec![1.0; r.len()];
        let m = Pi::new(0.0, &r, &w).unwrap();
        let v: Vec<f64> = vj.iter().map(|&j| j as f64 / 64.0).collect();
        let mut st = vec![0.0; m.state_len()];
        let (mut v_prev, mut z_prev) = (0.0, vec![0.0; r.len()]);
        for (k, &vk) in v.iter().enumerate() {
            m.step(&mut st, vk);
            for i in 0..r.len() {
                let z = st[i];
                prop_assert!(z >= vk - r[i] && z <= vk + r[i], "k={k} i={i} z={z} v={vk} r={}", r[i]);
                prop_assert!((z - z_prev[i]).abs() <= (vk - v_prev).abs(), "k={k} i={i}");
                if k == 0 {
                    prop_assert_eq!(z, (vk - r[i]).max((vk + r[i]).min(0.0)));
                }
            }
            v_prev = vk;
            z_prev.copy_from_slice(&st);
        }
    }

    /// The same on arbitrary floats: band exact against the computed bounds, Lipschitz bound
    /// up to the rounding of `v ± r` (two ulps of `|v| + r`), output formula bit-exact.
    #[test]
    fn pi_play_band_lipschitz_and_output(p in pi_params(8), v in input_strategy(3.0, 1..200)) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        let mut st = vec![0.0; m.state_len()];
        let mut z_ref = vec![0.0; p.r.len()];
        let mut v_prev = 0.0f64;
        for (k, &vk) in v.iter().enumerate() {
            let z_prev = st.clone();
            let y = m.step(&mut st, vk);
            let mut y_ref = p.p0 * vk;
            for i in 0..p.r.len() {
                let r = p.r[i];
                z_ref[i] = play_ref(z_ref[i], vk, r);
                prop_assert_eq!(st[i].to_bits(), z_ref[i].to_bits(), "k={} i={}", k, i);
                prop_assert!(st[i] >= vk - r && st[i] <= vk + r);
                let slack = 2.0 * f64::EPSILON * (vk.abs().max(v_prev.abs()) + r);
                prop_assert!((st[i] - z_prev[i]).abs() <= (vk - v_prev).abs() + slack);
                if k == 0 {
                    prop_assert_eq!(st[i].to_bits(), (vk - r).max((vk + r).min(0.0)).to_bits());
                }
                y_ref += p.w[i] * z_ref[i];
            }
            prop_assert_eq!(y.to_bits(), y_ref.to_bits(), "output at k={}", k);
            v_prev = vk;
        }
    }

    /// Rate independence of PI: repeating samples and time-stretching (monotone
    /// interpolation between samples) leave the outputs at the original samples bit-identical,
    /// and the final states too.
    #[test]
    fn pi_rate_independent(
        p in pi_params(8),
        v in input_strategy(3.0, 1..150),
        reps in prop::collection::vec(0usize..4, 1..20),
        ins in prop::collection::vec(0usize..6, 1..20),
    ) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        // start from the relaxed input 0 so the first segment is also stretched
        let mut v0 = vec![0.0];
        v0.extend_from_slice(&v);
        let (y, st) = simulate(&m, &v0);
        let (vr, ir) = repeat_samples(&v0, &reps);
        let (yr, str_) = simulate(&m, &vr);
        prop_bits_eq(&pick(&yr, &ir), &y, "repeated samples")?;
        prop_bits_eq(&str_, &st, "state after repeated samples")?;
        let (vs, is) = stretch(&v0, &ins);
        prop_assert!(vs.len() >= v0.len());
        let (ys, sts) = simulate(&m, &vs);
        prop_bits_eq(&pick(&ys, &is), &y, "time-stretched")?;
        prop_bits_eq(&sts, &st, "state after time-stretching")?;
    }

    /// A monotone rise from the relaxed state follows the initial loading curve
    /// `phi(s) = p0 s + sum w_i max(s - r_i, 0)` (same operations, so bit-identical).
    #[test]
    fn pi_initial_loading_curve(p in pi_params(8), mut s in prop::collection::vec(0.0..4.0f64, 1..60)) {
        s.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        let (y, _) = simulate(&m, &s);
        for (k, &sk) in s.iter().enumerate() {
            prop_assert_eq!(y[k].to_bits(), m.loading_curve(sk).to_bits(), "k={}", k);
        }
    }

    /// PI from the relaxed state is odd: PI[-v] = -PI[v] exactly.
    #[test]
    fn pi_odd_symmetry(p in pi_params(8), v in input_strategy(3.0, 1..150)) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        let (y, _) = simulate(&m, &v);
        let vn: Vec<f64> = v.iter().map(|x| -x).collect();
        let (yn, _) = simulate(&m, &vn);
        let yneg: Vec<f64> = yn.iter().map(|x| -x).collect();
        prop_bits_eq(&yneg, &y, "odd symmetry")?;
    }

    /// Wiping-out: after a prefix ending at v_p, a rise to M, nested minor loops inside
    /// [v_p, M] and then a rise above M, the state and every later output equal those of the
    /// path that went from v_p straight above M (the minor loops are forgotten exactly).
    #[test]
    fn pi_wiping_out(
        p in pi_params(8),
        prefix in input_strategy(2.0, 1..40),
        rise in 0.05..2.0f64,
        loops in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64), 1..12),
        above in 0.0..1.0f64,
        suffix in input_strategy(3.0, 0..40),
    ) {
        let m = Pi::new(p.p0, &p.r, &p.w).unwrap();
        let vp = *prefix.last().unwrap();
        let big_m = vp + rise;
        let m_new = big_m + above * 0.5 + 1e-3; // strictly above M
        // nested loops: maxima decrease, minima increase, all inside [vp, M]
        let mut a = vec![big_m];
        let (mut lo, mut hi) = (vp, big_m);
        for &(u, t) in &loops {
            let mn = lo + (hi - lo) * u * 0.9;
            let mx = mn + (hi - mn) * (0.1 + 0.9 * t);
            a.push(mn);
            a.push(mx);
            lo = mn;
            hi = mx;
        }
        let mut path_a = prefix.clone();
        path_a.extend_from_slice(&a);
        path_a.push(m_new);
        path_a.extend_from_slice(&suffix);
        let mut path_b = prefix.clone();
        path_b.push(m_new);
        path_b.extend_from_slice(&suffix);
        let (ya, _) = simulate(&m, &path_a);
        let (yb, _) = simulate(&m, &path_b);
        let tail = suffix.len() + 1;
        prop_bits_eq(&ya[ya.len() - tail..], &yb[yb.len() - tail..], "after exceeding M")?;
        // and the state right after exceeding M
        let (_, sa) = simulate(&m, &path_a[..path_a.len() - suffix.len()]);
        let (_, sb) = simulate(&m, &path_b[..path_b.len() - suffix.len()]);
        prop_bits_eq(&sa, &sb, "state after exceeding M")?;
    }
}

/// Wiping-out on a fixed case where the minor loops visibly change the state before the
/// input exceeds M, so equality afterwards is not a coincidence.
#[test]
fn pi_wiping_out_fixed_case() {
    let r = [0.1, 0.3, 0.6, 1.0];
    let w = [0.5, 0.4, 0.3, 0.2];
    let m = Pi::new(1.0, &r, &w).unwrap();
    let a = [0.0, 2.0, 0.5, 1.6, 0.9, 1.3, 1.0, 2.5, 1.7, 2.2];
    let b = [0.0, 2.5, 1.7, 2.2];
    let (_, s_before_a) = simulate(&m, &a[..7]);
    let (_, s_at_m) = simulate(&m, &a[..2]);
    assert!(s_before_a != s_at_m, "minor loops must have changed the state");
    let (ya, sa) = simulate(&m, &a);
    let (yb, sb) = simulate(&m, &b);
    assert_bits_eq(&ya[7..], &yb[1..], "outputs after exceeding M");
    assert_bits_eq(&sa, &sb, "final state");
    // and a path that does not exceed M keeps the memory of the loops
    let c = [0.0, 2.0, 0.5, 1.6, 0.9, 1.3, 1.0, 1.95];
    let d = [0.0, 1.95];
    let (_, sc) = simulate(&m, &c);
    let (_, sd) = simulate(&m, &d);
    assert!(sc != sd);
}
