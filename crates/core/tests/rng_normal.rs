//! The normal generator (`Rng::normal`, a 256-layer ziggurat) against the exact standard
//! normal distribution: moments, tail probabilities, Kolmogorov–Smirnov and chi-square
//! tests, the tail sampler on its own, and the sensor's noise being the same stream.
//!
//! The draws are seeded, so each test is deterministic; the bounds are what a correct
//! generator meets except with a small probability (stated per test, from the sample size),
//! and a wrong layer, wedge or tail would miss them by far (see the notes per test).
use piezohyst_core::rng::Rng;
use piezohyst_core::sensor::Sensor;
use std::f64::consts::SQRT_2;

/// Standard normal CDF.
fn phi(x: f64) -> f64 {
    0.5 * libm::erfc(-x / SQRT_2)
}

/// P(|Z| > t).
fn two_sided_tail(t: f64) -> f64 {
    libm::erfc(t / SQRT_2)
}

#[test]
fn moments_of_a_million_draws() {
    // sample mean, variance, third and fourth moments against 0, 1, 0, 3, within 5
    // standard errors (sqrt of 1, 2, 15, 96 over n): two-sided p < 6e-7 each
    let n = 1_000_000;
    for seed in [1u64, 2, 3] {
        let mut r = Rng::new(seed);
        let (mut m1, mut m2, mut m3, mut m4) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..n {
            let z = r.normal();
            let z2 = z * z;
            m1 += z;
            m2 += z2;
            m3 += z2 * z;
            m4 += z2 * z2;
        }
        let nf = n as f64;
        let (m1, m2, m3, m4) = (m1 / nf, m2 / nf, m3 / nf, m4 / nf);
        let se = |v: f64| 5.0 * (v / nf).sqrt();
        assert!(m1.abs() < se(1.0), "seed {seed}: mean {m1}");
        assert!((m2 - 1.0).abs() < se(2.0), "seed {seed}: E z^2 {m2}");
        assert!(m3.abs() < se(15.0), "seed {seed}: E z^3 {m3}");
        assert!((m4 - 3.0).abs() < se(96.0), "seed {seed}: E z^4 {m4}");
    }
}

#[test]
fn tail_probabilities() {
    // counts of |z| > t in 10^7 draws against n P(|Z| > t) (erfc), within 5 binomial
    // standard deviations; t = R (3.654, where the ziggurat's tail starts) checks the tail
    // sampler's share, 4 and 4.5 its shape. Expected counts 27000, 2580, 633, 68.
    let n = 10_000_000u64;
    let ts = [3.0, 3.654152885361009, 4.0, 4.5];
    let mut counts = [0u64; 4];
    let mut r = Rng::new(2024);
    let mut max = 0.0f64;
    for _ in 0..n {
        let a = r.normal().abs();
        max = max.max(a);
        for (c, &t) in counts.iter_mut().zip(&ts) {
            *c += u64::from(a > t);
        }
    }
    for (&c, &t) in counts.iter().zip(&ts) {
        let p = two_sided_tail(t);
        let mean = n as f64 * p;
        let sd = (mean * (1.0 - p)).sqrt();
        assert!((c as f64 - mean).abs() < 5.0 * sd, "P(|z| > {t}): {c} of {n}, expected {mean:.1} +- {sd:.1}");
    }
    // the largest of 10^7 |z| is near 5.3 (P(max > 6) = 2e-2, P(max < 4.6) = 1e-10)
    assert!(max > 4.6 && max < 6.5, "max |z| {max}");
}

#[test]
fn kolmogorov_smirnov_one_million() {
    // D_n = sup |F_n - Phi|; sqrt(n) D_n exceeds 1.9495 with probability 1e-3 (asymptotic
    // Kolmogorov distribution). Equal-area layers off by 1 % would give D ~ 4e-3 = 4x that.
    let n = 1_000_000;
    for seed in [11u64, 12] {
        let mut r = Rng::new(seed);
        let mut z: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        z.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let nf = n as f64;
        let d = z
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let f = phi(x);
                (f - i as f64 / nf).max((i + 1) as f64 / nf - f)
            })
            .fold(0.0, f64::max);
        assert!(d * nf.sqrt() < 1.9495, "seed {seed}: KS D = {d}");
    }
}

#[test]
fn chi_square_200_equiprobable_bins() {
    // 10^7 draws in 200 bins of probability 1/200 (bin = floor(200 Phi(z))): chi-square
    // with 199 degrees of freedom exceeds 281.87 with probability 1e-4. Each bin expects
    // 50000 +- 224, so a wedge or layer error of 1 % of a bin's mass adds ~ (500/224)^2 = 5.
    let (n, bins) = (10_000_000usize, 200usize);
    let mut counts = vec![0u64; bins];
    let mut r = Rng::new(99);
    for _ in 0..n {
        let b = (phi(r.normal()) * bins as f64) as usize;
        counts[b.min(bins - 1)] += 1;
    }
    let e = n as f64 / bins as f64;
    let chi2: f64 = counts.iter().map(|&c| (c as f64 - e) * (c as f64 - e) / e).sum();
    assert!(chi2 < 281.87, "chi-square {chi2} with 199 dof");
}

#[test]
fn tail_sampler_is_the_conditional_tail() {
    // the tail draws alone: P(Z > x | Z > R) = erfc(x / sqrt 2) / erfc(R / sqrt 2); KS on
    // 10^6 draws at the 1e-3 level, and the mean against the exact conditional mean
    // f(R) / (sqrt(pi/2) erfc(R / sqrt 2)) = 3.9108 (standard deviation ~0.24: 5 SE = 1.2e-3)
    let r0 = 3.654152885361009;
    let q = |x: f64| libm::erfc(x / SQRT_2) / libm::erfc(r0 / SQRT_2);
    let n = 1_000_000;
    let mut rng = Rng::new(5);
    let mut z: Vec<f64> = (0..n).map(|_| rng.normal_tail_for_tests()).collect();
    assert!(z.iter().all(|&x| x > r0));
    let nf = n as f64;
    let mean = z.iter().sum::<f64>() / nf;
    let exact_mean = libm::exp(-0.5 * r0 * r0) / ((std::f64::consts::FRAC_PI_2).sqrt() * libm::erfc(r0 / SQRT_2));
    let var = z.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / nf;
    assert!((mean - exact_mean).abs() < 5.0 * (var / nf).sqrt(), "tail mean {mean} vs {exact_mean}");
    z.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let d = z
        .iter()
        .enumerate()
        .map(|(i, &x)| {
            let f = 1.0 - q(x);
            (f - i as f64 / nf).max((i + 1) as f64 / nf - f)
        })
        .fold(0.0, f64::max);
    assert!(d * nf.sqrt() < 1.9495, "tail KS D = {d}");
}

#[test]
fn symmetric_and_layer_independent() {
    // the sign and the layer come from different bits: the positive share, and the
    // positive share among the ~1.5 % of draws that left the fast path (|z| beyond the
    // next layer's edge is not observable directly, so use |z| > 2.5, mostly wedges and
    // the tail), are 1/2 within 5 binomial standard deviations
    let n = 4_000_000;
    let mut r = Rng::new(77);
    let (mut pos, mut far, mut far_pos) = (0u64, 0u64, 0u64);
    for _ in 0..n {
        let z = r.normal();
        pos += u64::from(z > 0.0);
        if z.abs() > 2.5 {
            far += 1;
            far_pos += u64::from(z > 0.0);
        }
        assert!(z != 0.0 && z.is_finite());
    }
    let check = |k: u64, m: u64| (k as f64 - m as f64 / 2.0).abs() < 5.0 * (m as f64 / 4.0).sqrt();
    assert!(check(pos, n), "{pos} positive of {n}");
    assert!(check(far_pos, far), "{far_pos} positive of {far} beyond 2.5");
    let p_far = two_sided_tail(2.5);
    assert!((far as f64 - n as f64 * p_far).abs() < 5.0 * (n as f64 * p_far).sqrt(), "{far} beyond 2.5");
}

#[test]
fn sensor_noise_is_the_rng_stream() {
    // no quantization, no delay, unit noise: the readings of x = 0 are Rng::normal's stream
    let sensor = Sensor::new(0.0, 1.0, 0).unwrap();
    for seed in [0u64, 1, 123_456_789] {
        let mut st = sensor.state(0.0, seed);
        let mut r = Rng::new(seed);
        for k in 0..100_000 {
            let a = sensor.read(&mut st, 0.0);
            let b = r.normal();
            assert_eq!(a.to_bits(), b.to_bits(), "seed {seed} sample {k}");
        }
    }
}
