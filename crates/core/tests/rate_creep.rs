//! Rate-dependent PI (docs/spec.md §2.3) and creep (docs/spec.md §2.4) against independent implementations
//! of their defining formulas.
mod common;

use common::*;
use piezohyst_core::creep::{lag_gains, Creep, WithCreep};
use piezohyst_core::pi::Pi;
use piezohyst_core::rate::RateDependentPi;
use piezohyst_core::{Hysteresis, ModelError};
use proptest::prelude::*;

/// docs/spec.md §2.3, written out: rate(k) = rate(k-1) + a (|v(k) - v(k-1)|/Ts - rate(k-1)), rate = 0
/// at the first sample; r_i(k) = r_i + beta rate(k); w_i(k) = w_i + c_i rate(k).
/// The rate-dependent PI's parameters as the formulas name them (`a`: the rate filter's gain).
struct RdpiFormula<'a> {
    ts: f64,
    p0: f64,
    beta: f64,
    a: f64,
    r: &'a [f64],
    w: &'a [f64],
    c: &'a [f64],
}

fn rdpi_reference(f: &RdpiFormula<'_>, v: &[f64]) -> Vec<f64> {
    let RdpiFormula { ts, p0, beta, a, r, w, c } = *f;
    let mut z = vec![0.0; r.len()];
    let mut rate = 0.0;
    let mut v_prev: Option<f64> = None;
    v.iter()
        .map(|&vk| {
            if let Some(vp) = v_prev {
                rate += a * ((vk - vp).abs() / ts - rate);
            }
            v_prev = Some(vk);
            let mut y = p0 * vk;
            for i in 0..r.len() {
                let ri = r[i] + beta * rate;
                z[i] = (vk - ri).max((vk + ri).min(z[i]));
                y += (w[i] + c[i] * rate) * z[i];
            }
            y
        })
        .collect()
}

proptest! {
    #![proptest_config(cfg(128))]

    #[test]
    fn rate_dependent_pi_matches_its_formulas(
        p0 in 0.1..2.0f64,
        beta in 0.0..1e-3f64,
        tau in prop_oneof![Just(0.0), 1e-4..1e-2f64],
        r0 in 0.0..0.2f64,
        inc in prop::collection::vec(0.01..0.4f64, 1..8),
        w in prop::collection::vec(-0.5..1.0f64, 8),
        c in prop::collection::vec(-1e-4..1e-4f64, 8),
        v in input_strategy(2.0, 1..150),
    ) {
        let ts = 1e-3;
        let r = thresholds_from(r0, &inc);
        let n = r.len();
        let m = RateDependentPi::new(ts, p0, beta, tau, &r, &w[..n], &c[..n]).unwrap();
        let a = if tau == 0.0 { 1.0 } else { 1.0 - (-ts / tau).exp() };
        prop_assert!((m.filter_gain - a).abs() <= 1e-15);
        let (y, st) = simulate(&m, &v);
        let formula = RdpiFormula { ts, p0, beta, a: m.filter_gain, r: &r, w: &w[..n], c: &c[..n] };
        let y_ref = rdpi_reference(&formula, &v);
        let scale = max_abs(&y_ref).max(1.0);
        prop_assert!(max_diff(&y, &y_ref) <= 1e-13 * scale, "max diff {:e}", max_diff(&y, &y_ref));
        // state layout [z.., v_prev, rate, started]
        prop_assert_eq!(st[n], *v.last().unwrap());
        prop_assert_eq!(st[n + 2], 1.0);
    }

    /// With beta = 0 and c = 0 the rate-dependent PI is the classical PI, bit for bit.
    #[test]
    fn rate_dependent_pi_without_rate_terms_is_pi(
        p0 in 0.1..2.0f64,
        inc in prop::collection::vec(0.01..0.4f64, 1..8),
        w in prop::collection::vec(-0.5..1.0f64, 8),
        v in input_strategy(2.0, 1..150),
    ) {
        let r = thresholds_from(0.05, &inc);
        let n = r.len();
        let zeros = vec![0.0; n];
        let rd = RateDependentPi::new(1e-3, p0, 0.0, 0.0, &r, &w[..n], &zeros).unwrap();
        let pi = Pi::new(p0, &r, &w[..n]).unwrap();
        let (y1, _) = simulate(&rd, &v);
        let (y2, _) = simulate(&pi, &v);
        prop_bits_eq(&y1, &y2, "rdpi(beta = 0, c = 0) vs pi")?;
    }

    /// Creep is a bank of first-order lags: w_j += a_j (v - w_j), y = sum c_j w_j; and
    /// WithCreep adds it to the model's output.
    #[test]
    fn creep_matches_its_formula(
        taus in prop::collection::vec(1e-3..10.0f64, 1..5),
        c in prop::collection::vec(-1.0..1.0f64, 5),
        v in input_strategy(2.0, 1..200),
    ) {
        let ts = 1e-3;
        let m = taus.len();
        let mut gains = vec![0.0; m];
        lag_gains(ts, &taus, &mut gains).unwrap();
        for (g, t) in gains.iter().zip(&taus) {
            prop_assert!((g - (1.0 - (-ts / t).exp())).abs() <= 1e-15);
            prop_assert!(*g > 0.0 && *g <= 1.0);
        }
        let creep = Creep::new(&gains, &c[..m]).unwrap();
        let (y, _) = simulate(&creep, &v);
        let mut wj = vec![0.0; m];
        for (k, &vk) in v.iter().enumerate() {
            let mut yr = 0.0;
            for j in 0..m {
                wj[j] += gains[j] * (vk - wj[j]);
                yr += c[j] * wj[j];
            }
            prop_assert!((y[k] - yr).abs() <= 1e-14 * (1.0 + yr.abs()), "k={}", k);
        }
        let pi_r = [0.1, 0.3];
        let pi_w = [0.4, 0.2];
        let pi = Pi::new(0.8, &pi_r, &pi_w).unwrap();
        let both = WithCreep { model: pi, creep };
        prop_assert_eq!(both.state_len(), 2 + m);
        let (yb, _) = simulate(&both, &v);
        let (yp, _) = simulate(&pi, &v);
        for k in 0..v.len() {
            prop_assert_eq!(yb[k].to_bits(), (yp[k] + y[k]).to_bits());
        }
    }
}

/// The rate model really is rate dependent: a faster ramp widens the loop.
#[test]
fn rate_dependent_pi_widens_with_rate() {
    let r = [0.1, 0.3, 0.6];
    let w = [0.5, 0.1, 0.1];
    let c = [0.0; 3];
    let m = RateDependentPi::new(1e-3, 1.0, 2e-4, 0.0, &r, &w, &c).unwrap();
    // triangle 0 -> 1 -> 0 at two speeds; compare the output at v = 0.5 on the way down
    let tri = |n: usize| -> Vec<f64> {
        (0..=2 * n).map(|k| if k <= n { k as f64 / n as f64 } else { (2 * n - k) as f64 / n as f64 }).collect()
    };
    let at_half_down = |n: usize| {
        let v = tri(n);
        let (y, _) = simulate(&m, &v);
        y[n + n / 2]
    };
    let slow = at_half_down(1000); // 1 V/s
    let fast = at_half_down(10); // 100 V/s: thresholds grow by beta*100 = 0.02
                                 // by hand: slow 0.5 + 0.5*0.6 + 0.1*0.7 + 0.1*0.4 = 0.91, fast 0.5 + 0.5*0.62 + 0.1*0.68 + 0.1*0.38
    assert!((fast - 0.916).abs() < 1e-12, "{fast}");
    assert!(fast > slow + 1e-3, "faster input should lag more: slow {slow}, fast {fast}");
    // and the slow one is close to the rate-independent PI
    let pi = Pi::new(1.0, &r, &w).unwrap();
    let v = tri(1000);
    let (yp, _) = simulate(&pi, &v);
    assert!((slow - yp[1500]).abs() < 1e-3);
}

#[test]
fn creep_step_response_and_errors() {
    // a single lag: after k samples of a unit step, w = 1 - (1 - a)^k
    let mut g = [0.0];
    lag_gains(1e-3, &[0.05], &mut g).unwrap();
    let cr = Creep::new(&g, &[2.0]).unwrap();
    let (y, _) = simulate(&cr, &vec![1.0; 100]);
    for (k, yk) in y.iter().enumerate() {
        let want = 2.0 * (1.0 - (1.0 - g[0]).powi(k as i32 + 1));
        assert!((yk - want).abs() < 1e-13, "k={k}");
    }
    assert_eq!(lag_gains(0.0, &[1.0], &mut g), Err(ModelError::NotPositive("ts", usize::MAX, 0.0)));
    assert_eq!(lag_gains(1e-3, &[-1.0], &mut g), Err(ModelError::NotPositive("taus", 0, -1.0)));
    assert_eq!(lag_gains(1e-3, &[1.0, 2.0], &mut g), Err(ModelError::Length("out", 2, 1)));
    assert_eq!(Creep::new(&[1.5], &[1.0]).err(), Some(ModelError::NotPositive("creep_gains", 0, 1.5)));
    assert_eq!(Creep::new(&[0.0], &[1.0]).err(), Some(ModelError::NotPositive("creep_gains", 0, 0.0)));
}
