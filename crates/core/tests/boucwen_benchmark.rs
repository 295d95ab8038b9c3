//! Bouc–Wen benchmark core (docs/spec.md §3.3): exact discrete invariants of the Newmark +
//! trapezoidal step, convergence order, the MATLAB-style FIR decimation, validation.
use piezohyst_core::boucwen_benchmark::{
    decimate_fir, decimated_len, fir1_taps, integrate, prime_factors, BoucWenBenchmark, Newmark, State, FIR_TAPS,
};
use piezohyst_core::ModelError;

const H: f64 = 1.0 / 15_000.0;
const BENCHMARK: BoucWenBenchmark = BoucWenBenchmark::NOEL_SCHOUKENS;

fn linear(mass: f64, damping: f64, stiffness: f64, alpha: f64) -> BoucWenBenchmark {
    BoucWenBenchmark { mass, damping, stiffness, alpha, beta: 0.0, ..BENCHMARK }.validated().unwrap()
}

#[test]
fn defaults_are_the_benchmark() {
    let p = BoucWenBenchmark::default();
    assert_eq!(p.to_array(), [2.0, 10.0, 5e4, 5e4, 1e3, 0.8, -1.1, 1.0]);
    assert_eq!(BoucWenBenchmark::from_slice(&p.to_array()).unwrap(), p);
}

#[test]
fn validation_names_parameter_and_value() {
    let e = BoucWenBenchmark { mass: 0.0, ..BENCHMARK }.validated().unwrap_err();
    assert_eq!(e.to_string(), "mass = 0 must be > 0");
    let e = BoucWenBenchmark { damping: -1.0, ..BENCHMARK }.validated().unwrap_err();
    assert_eq!(e.to_string(), "damping = -1 must be >= 0");
    let e = BoucWenBenchmark { gamma: f64::NAN, ..BENCHMARK }.validated().unwrap_err();
    assert!(e.to_string().starts_with("gamma = NaN"), "{e}");
    assert!(BoucWenBenchmark { nu: 0.5, ..BENCHMARK }.validated().is_err());
    assert_eq!(BoucWenBenchmark::from_slice(&[1.0; 3]), Err(ModelError::Length("params", 8, 3)));
    assert!(Newmark::new(BoucWenBenchmark::default(), 0.0).is_err());
    assert!(Newmark::new(BoucWenBenchmark::default(), f64::INFINITY).is_err());
}

/// Undamped linear oscillator (beta = 0): the average-acceleration rule conserves the
/// energy exactly, and the trapezoidal z' = alpha y' gives z = alpha y exactly.
#[test]
fn linear_limit_conserves_energy_and_z_tracks_alpha_y() {
    let p = linear(2.0, 0.0, 5e4, 3e4);
    let nm = Newmark::new(p, H).unwrap();
    let y0 = 1e-3;
    let mut s = State::at(&p, y0, 0.0, p.alpha * y0, 0.0);
    let energy = |s: &State| 0.5 * p.mass * s.v * s.v + 0.5 * (p.stiffness + p.alpha) * s.y * s.y;
    let e0 = energy(&s);
    for _ in 0..150_000 {
        assert!(nm.step(&mut s, 0.0));
        assert!((s.z - p.alpha * s.y).abs() <= 1e-12 * p.alpha * y0);
    }
    assert!((energy(&s) - e0).abs() <= 1e-9 * e0, "{} vs {e0}", energy(&s));
}

/// Damped linear oscillator under a step: settles at u / (k + alpha).
#[test]
fn static_deflection() {
    let p = linear(2.0, 400.0, 5e4, 5e4);
    let nm = Newmark::new(p, H).unwrap();
    let mut s = State::at(&p, 0.0, 0.0, 0.0, 10.0);
    for _ in 0..60_000 {
        nm.step(&mut s, 10.0);
    }
    assert!((s.y - 10.0 / 1e5).abs() < 1e-12, "{}", s.y);
}

/// Free vibration of the linear oscillator: second-order convergence to the exact
/// solution y0 cos(w t) (the rule's period elongation is (w h)^2 / 12).
#[test]
fn second_order_in_h() {
    let p = linear(2.0, 0.0, 5e4, 5e4);
    let w = ((p.stiffness + p.alpha) / p.mass).sqrt();
    let err = |h: f64| {
        let nm = Newmark::new(p, h).unwrap();
        let mut s = State::at(&p, 1e-3, 0.0, p.alpha * 1e-3, 0.0);
        let n = (0.5 / h).round() as usize;
        for _ in 0..n {
            nm.step(&mut s, 0.0);
        }
        (s.y - 1e-3 * (w * n as f64 * h).cos()).abs()
    };
    let (e1, e2) = (err(1.0 / 3750.0), err(1.0 / 7500.0));
    assert!((3.8..4.2).contains(&(e1 / e2)), "{e1} {e2}");
}

/// Hysteretic system under a strong sine: every implicit step converges, the response
/// is bounded, and the state is consistent with the equation of motion.
#[test]
fn hysteretic_steps_converge() {
    let p = BoucWenBenchmark::default();
    let nm = Newmark::new(p, H).unwrap();
    let n = 30_000;
    let u: Vec<f64> = (1..=n).map(|k| 150.0 * (2.0 * core::f64::consts::PI * 20.0 * k as f64 * H).sin()).collect();
    let (mut y, mut z) = (vec![0.0; n], vec![0.0; n]);
    let mut s = State::at(&p, 0.0, 0.0, 0.0, 0.0);
    assert_eq!(integrate(&nm, &mut s, &u, &mut y, &mut z), Ok(None));
    assert!(y.iter().all(|v| v.abs() < 1e-2) && z.iter().all(|v| v.abs() < 500.0));
    let resid = p.mass * s.a + p.damping * s.v + p.stiffness * s.y + s.z - u[n - 1];
    assert!(resid.abs() < 1e-9, "{resid}");
    // a coarse step (20x the benchmark's) still converges
    let nm = Newmark::new(p, 20.0 * H).unwrap();
    let mut s = State::default();
    for k in 0..2000 {
        assert!(nm.step(&mut s, 150.0 * (k as f64 * 0.05).sin()));
    }
    let mut bad = [f64::NAN];
    assert!(integrate(&nm, &mut s, &bad, &mut [0.0], &mut [0.0]).is_err());
    bad[0] = 0.0;
    assert!(integrate(&nm, &mut s, &bad, &mut [0.0; 2], &mut [0.0]).is_err());
}

#[test]
fn fir1_taps_are_symmetric_hamming_lowpass() {
    for r in [2, 3, 5, 7] {
        let b = fir1_taps(r);
        assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for j in 0..FIR_TAPS {
            assert_eq!(b[j], b[FIR_TAPS - 1 - j]);
        }
        // gain at the cutoff 1/r of Nyquist is about -6 dB
        let wc = core::f64::consts::PI / r as f64;
        let g: f64 = b.iter().enumerate().map(|(j, bj)| bj * (wc * (j as f64 - 15.0)).cos()).sum();
        assert!((g - 0.5).abs() < 0.02, "{r}: {g}");
    }
    // MATLAB fir1(30, 0.5): the centre tap and the zeros of the half-band filter
    let b = fir1_taps(2);
    assert!((b[15] - 0.5).abs() < 5e-3);
    assert!(b[13].abs() < 1e-16 && b[1].abs() < 1e-16);
}

/// Odd reflection at both ends + a symmetric unit-gain filter pass straight lines
/// unchanged, edges included (records of at least 16 samples: the reflection then never
/// reaches past the other end); a constant passes at any length.
#[test]
fn decimate_passes_lines_exactly() {
    for n in [1usize, 2, 7] {
        let mut out = vec![0.0; decimated_len(n, 2)];
        decimate_fir(&vec![0.3; n], 2, &mut out).unwrap();
        assert!(out.iter().all(|o| (o - 0.3).abs() < 1e-15), "{n}: {out:?}");
    }
    for n in [16usize, 31, 100, 101] {
        for r in [1usize, 2, 5] {
            let x: Vec<f64> = (0..n).map(|k| 0.5 - 0.25 * k as f64).collect();
            let mut out = vec![0.0; decimated_len(n, r)];
            decimate_fir(&x, r, &mut out).unwrap();
            for (k, o) in out.iter().enumerate() {
                assert!((o - x[k * r]).abs() < 1e-12, "n {n} r {r} k {k}: {o} vs {}", x[k * r]);
            }
        }
    }
    let mut out = vec![0.0; 3];
    assert!(decimate_fir(&[0.0; 10], 0, &mut out).is_err());
    assert!(decimate_fir(&[0.0; 10], 2, &mut out).is_err());
}

#[test]
fn prime_factor_stages() {
    let mut f = [0usize; 64];
    let n = prime_factors(20, &mut f);
    assert_eq!(&f[..n], &[2, 2, 5]);
    let n = prime_factors(1, &mut f);
    assert_eq!(n, 0);
    let n = prime_factors(97, &mut f);
    assert_eq!(&f[..n], &[97]);
}
