//! ns per controller step, single thread, no plant: the controller alone fed a recorded
//! measurement, as it runs in a real-time loop. Mean over 10^6 steps (best of 5 runs) and
//! the worst single step. Prints JSON (`bench/results/controller_step.json` is this output):
//! `cargo run --release -p piezohyst-core --example controller_step`.
use piezohyst_core::absmc::Absmc;
use piezohyst_core::cemf::CemfModel;
use piezohyst_core::compensated::Compensated;
use piezohyst_core::control::{Controller, Limits, OpenLoop, Reference, VelocityObserver};
use piezohyst_core::inverse::inverse_step;
use piezohyst_core::smc::{Smc, SmcConfig, Switching};
use piezohyst_core::spec::Family;
use piezohyst_core::Invertible;
use std::time::Instant;

const N: usize = 1_000_000;

fn time<C: Controller>(c: &C, refs: &[Reference], ys: &[f64]) -> (f64, f64) {
    let mut state = vec![0.0; c.state_len()];
    let mut best = f64::INFINITY;
    let mut worst = 0.0f64;
    let mut sink = 0.0;
    for _ in 0..5 {
        c.reset(&mut state, 0.0);
        let t0 = Instant::now();
        for (r, &y) in refs.iter().zip(ys) {
            sink += c.step(&mut state, r, y).u;
        }
        best = best.min(t0.elapsed().as_secs_f64() / N as f64 * 1e9);
    }
    c.reset(&mut state, 0.0);
    for (r, &y) in refs.iter().zip(ys) {
        let t0 = Instant::now();
        sink += c.step(&mut state, r, y).u;
        worst = worst.max(t0.elapsed().as_secs_f64() * 1e9);
    }
    assert!(sink.is_finite());
    (best, worst)
}

/// The model's per-sample inverse alone (`inverse_step`, previous input as the guess).
fn time_inverse<M: Invertible + ?Sized>(m: &M, refs: &[Reference]) -> (f64, f64) {
    let mut state = vec![0.0; m.state_len()];
    let (mut best, mut worst, mut sink) = (f64::INFINITY, 0.0f64, 0.0);
    for _ in 0..5 {
        state.iter_mut().for_each(|z| *z = 0.0);
        let mut v = 0.0;
        let t0 = Instant::now();
        for (k, r) in refs.iter().enumerate() {
            v = inverse_step(m, &mut state, r.x, v, k).unwrap();
            sink += v;
        }
        best = best.min(t0.elapsed().as_secs_f64() / N as f64 * 1e9);
    }
    state.iter_mut().for_each(|z| *z = 0.0);
    let mut v = 0.0;
    for (k, r) in refs.iter().enumerate() {
        let t0 = Instant::now();
        v = inverse_step(m, &mut state, r.x, v, k).unwrap();
        worst = worst.max(t0.elapsed().as_secs_f64() * 1e9);
    }
    assert!((sink + v).is_finite());
    (best, worst)
}

fn main() {
    let ts = 1e-4;
    let limits = Limits::new(-20.0, 150.0).unwrap();
    // an 80 Hz scan, read through a 0.1 um quantizer with a small tracking error
    let refs: Vec<Reference> = (0..N)
        .map(|k| {
            let w = 2.0 * std::f64::consts::PI * 80.0;
            let t = k as f64 * ts;
            Reference { x: 9e-6 + 8e-6 * (w * t).sin(), v: 8e-6 * w * (w * t).cos(), a: -8e-6 * w * w * (w * t).sin() }
        })
        .collect();
    let ys: Vec<f64> = refs
        .iter()
        .enumerate()
        .map(|(k, r)| ((r.x + 2e-8 * ((k as f64) * 0.37).sin()) / 1e-7).round() * 1e-7)
        .collect();
    // seed 2's MPI structure: 9 generalized plays, cubic polynomial, identity envelopes
    let family = Family::parse("gpi", &[9, 0, 0, 0]).unwrap();
    let mut row = vec![0.0; family.param_len()];
    row[0] = -100.0;
    row[1] = 250.0;
    row[3] = 0.13e-6; // linear term, m/V
    for i in 0..9 {
        row[14 + i] = 15.0 * i as f64; // thresholds, V
        row[14 + 9 + i] = 0.01e-6 / (1.0 + i as f64); // weights
    }
    let mut scratch = vec![0.0; family.scratch_len()];
    let mpi = family.build(&row, &mut scratch).unwrap();
    // the classical PI with the same thresholds and weights (linear term 0.13 um/V)
    let pi_family = Family::parse("pi", &[9, 0]).unwrap();
    let mut pi_row = vec![0.0; pi_family.param_len()];
    pi_row[0] = 0.13e-6;
    for i in 0..9 {
        pi_row[1 + i] = 15.0 * i as f64;
        pi_row[1 + 9 + i] = 0.01e-6 / (1.0 + i as f64);
    }
    let mut pi_scratch = vec![0.0; pi_family.scratch_len()];
    let pi = pi_family.build(&pi_row, &mut pi_scratch).unwrap();
    let observer = VelocityObserver::new(1000.0, ts, 1.0).unwrap();
    let cemf =
        CemfModel { m: 0.0068, b: 13.0, k: 6.98e6, tem: 10.5, cz: 1.8e-6, alpha: 1.25e5, beta: 8000.0, gamma: 3000.0 }
            .validated()
            .unwrap();
    let smc = |with: bool| {
        Smc::new(SmcConfig {
            m: 0.0068,
            b: 13.0,
            k: 6.98e6,
            kp: 1e6,
            kv: 2e3,
            alpha: 0.0,
            switching: Switching::BoundaryLayer { gain: 20.0, width: 0.01 },
            cemf: if with { Some(cemf) } else { None },
            desired_model_terms: false,
            observer,
            limits,
        })
        .unwrap()
    };
    let disp = Limits::new(-2e-6, 22e-6).unwrap();
    let w2 = (2.0 * std::f64::consts::PI * 2000.0f64).powi(2);
    let absmc = Absmc {
        b: w2,
        theta0: [w2, 1.4 * w2.sqrt()],
        theta_min: [w2 / 3.0, 0.0],
        theta_max: [3.0 * w2, 3.0 * w2.sqrt()],
        c1: 2e3,
        lambda: 2e3,
        ks: 5e3,
        phi: 1e-3,
        gamma_theta: [1e6, 1e3],
        gamma_d: 1e4,
        d0: 0.0,
        d_max: 1e5,
        desired_regressor: true,
        observer,
        limits: disp,
    }
    .validated()
    .unwrap();
    let smc_disp = Smc::new(SmcConfig {
        m: 1.0 / w2,
        b: 1.4 / w2.sqrt(),
        k: 1.0,
        kp: 1e6,
        kv: 2e3,
        alpha: 0.0,
        switching: Switching::BoundaryLayer { gain: 1e-6, width: 0.01 },
        cemf: None,
        desired_model_terms: false,
        observer,
        limits: disp,
    })
    .unwrap();
    let rows = [
        ("PI inverse, 9 operators (inverse_step)", time_inverse(&pi, &refs)),
        ("MPI inverse, 9 operators (inverse_step)", time_inverse(&mpi, &refs)),
        (
            "PI-type inverse, 9 operators (MPI feedforward)",
            time(
                &Compensated { inner: OpenLoop::new(1.0, 0.0, 0.0, 0.0, disp).unwrap(), model: mpi, limits },
                &refs,
                &ys,
            ),
        ),
        ("SMC", time(&smc(false), &refs, &ys)),
        ("SMC + CEMF observer", time(&smc(true), &refs, &ys)),
        ("MPI inverse (9 operators) + SMC", time(&Compensated { inner: smc_disp, model: mpi, limits }, &refs, &ys)),
        ("MPI inverse (9 operators) + ABSMC", time(&Compensated { inner: absmc, model: mpi, limits }, &refs, &ys)),
    ];
    println!("{{\"steps\": {N}, \"unit\": \"ns\", \"target_mpi_inverse_plus_smc_ns\": 200, \"results\": {{");
    for (i, (name, (mean, worst))) in rows.iter().enumerate() {
        let comma = if i + 1 < rows.len() { "," } else { "" };
        println!("  \"{name}\": {{\"mean\": {mean:.1}, \"worst\": {worst:.0}}}{comma}");
    }
    println!("}}}}");
}
