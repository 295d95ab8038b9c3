//! Soak (issue 8): 10^8 play-operator updates with random inputs and 10^7 closed-loop steps
//! on the virtual stage with random references, sensor dropouts and spikes, and saturation.
//! Invariants are checked at every step; the peak resident memory (VmHWM) is printed, and the
//! core never allocates, so it cannot grow. `cargo test -p piezohyst-core --test soak -- --nocapture`.
use piezohyst_core::cemf::CemfModel;
use piezohyst_core::control::{Controller, Limits, Reference, VelocityObserver};
use piezohyst_core::pi::{play, Pi};
use piezohyst_core::rng::Rng;
use piezohyst_core::sensor::Sensor;
use piezohyst_core::smc::{Smc, SmcConfig, Switching};
use piezohyst_core::stage::{Stage, StageParams, StageState};
use piezohyst_core::Hysteresis;

fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn uniform(rng: &mut Rng) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

#[test]
fn hundred_million_operator_updates_keep_the_play_invariants() {
    let thresholds = [0.0, 0.1, 0.2, 0.35, 0.5, 0.7, 0.9, 1.2, 1.5, 2.0];
    let weights = [1.0, 0.5, 0.3, 0.2, 0.15, 0.1, 0.08, 0.05, 0.03, 0.02];
    let pi = Pi::new(0.1, &thresholds, &weights).unwrap();
    let mut rng = Rng::new(7);
    let mut state = [0.0; 10];
    let (mut v_prev, mut y_max) = (0.0f64, 0.0f64);
    let total = 10_000_000usize; // x 10 operators = 1e8 operator updates
    for k in 0..total {
        // random walk with occasional jumps across the whole range
        let v = if k % 1000 == 0 {
            6.0 * uniform(&mut rng) - 3.0
        } else {
            (v_prev + 0.2 * (uniform(&mut rng) - 0.5)).clamp(-3.0, 3.0)
        };
        let before = state;
        let y = pi.step(&mut state, v);
        for i in 0..10 {
            // the play band |v - z| <= r and the Lipschitz bound |dz| <= |dv|
            assert!((v - state[i]).abs() <= thresholds[i] + 1e-12, "band broken at step {k}, operator {i}");
            assert!((state[i] - before[i]).abs() <= (v - v_prev).abs() + 1e-12, "|dz| > |dv| at step {k}");
            assert_eq!(state[i], play(before[i], v, thresholds[i]));
        }
        assert!(y.is_finite());
        y_max = y_max.max(y.abs());
        v_prev = v;
    }
    // bounded: |y| <= p0 |v| + sum w (|v| + r) for |v| <= 3
    let bound: f64 = 0.1 * 3.0 + weights.iter().zip(&thresholds).map(|(w, r)| w * (3.0 + r)).sum::<f64>();
    assert!(y_max <= bound, "{y_max} > {bound}");
    if let Some(kib) = peak_rss_kib() {
        println!("play soak: 1e8 operator updates, peak RSS {kib} KiB");
    }
}

fn virtual_stage() -> Stage {
    Stage::new(StageParams::virtual_stage(), 1e-4, 1, 0.05).unwrap()
}

#[test]
fn ten_million_closed_loop_steps_with_faults_stay_finite_and_bounded() {
    // seed 1's form latches at the upper voltage limit once a set point drives the stage to
    // the end of its stroke (K̂ x then asks for more than 150 V): it stays finite and bounded,
    // but saturated; the desired-compensation form keeps tracking
    let latched = soak_closed_loop(false, 10_000_000);
    assert!(latched > 0.5, "seed 1's form saturated {latched}");
    let tracking = soak_closed_loop(true, 10_000_000);
    assert!(tracking < 0.4, "desired form saturated {tracking}");
    println!("saturated fraction: seed 1 form {latched:.3}, desired form {tracking:.3}");
}

/// Returns the fraction of saturated samples.
fn soak_closed_loop(desired: bool, steps: usize) -> f64 {
    let stage = virtual_stage();
    let sensor = Sensor::new(1e-7, 1e-8, 1).unwrap();
    let limits = Limits::new(-20.0, 150.0).unwrap();
    let cemf =
        CemfModel { m: 0.0068, b: 13.0, k: 6.98e6, tem: 10.5, cz: 1.8e-6, alpha: 1.25e5, beta: 8000.0, gamma: 3000.0 }
            .validated()
            .unwrap();
    let observer = VelocityObserver::new(300.0, 1e-4, 1.0).unwrap();
    let smc = Smc::new(SmcConfig {
        m: 0.0068,
        b: 13.0,
        k: 6.98e6,
        kp: 1e6,
        kv: 2e3,
        alpha: 0.0,
        switching: Switching::BoundaryLayer { gain: 13.0, width: 0.015 },
        cemf: Some(cemf),
        desired_model_terms: desired,
        observer,
        limits,
    })
    .unwrap();
    let mut cst = vec![0.0; smc.state_len()];
    smc.reset(&mut cst, 0.0);
    let mut st = StageState::ZERO;
    let mut sst = sensor.state(0.0, 3);
    let mut rng = Rng::new(11);
    let (mut target, mut dropout, mut held) = (10e-6, 0usize, 0.0);
    let (mut spikes, mut dropouts, mut saturated) = (0usize, 0usize, 0usize);
    let (mut x_min, mut x_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..steps {
        // a new random set point every 0.1 s, sometimes beyond the stroke (saturation)
        if k % 1000 == 0 {
            target = -5e-6 + 35e-6 * uniform(&mut rng);
        }
        let reading = sensor.read(&mut sst, st.x);
        let u = uniform(&mut rng);
        let y = if dropout > 0 {
            dropout -= 1;
            held
        } else if u < 1e-4 {
            dropout = 1 + (uniform(&mut rng) * 200.0) as usize; // the reading freezes
            dropouts += 1;
            held = reading;
            reading
        } else if u < 2e-4 {
            spikes += 1;
            reading + if uniform(&mut rng) < 0.5 { 1e-3 } else { -1e-3 } // a 1 mm glitch
        } else {
            reading
        };
        let out = smc.step(&mut cst, &Reference { x: target, v: 0.0, a: 0.0 }, y);
        assert!(out.u.is_finite() && out.u >= limits.min && out.u <= limits.max, "u = {} at step {k}", out.u);
        if out.u == limits.min || out.u == limits.max {
            saturated += 1;
        }
        stage.advance(&mut st, out.u);
        assert!(st.x.is_finite() && st.v.is_finite() && st.vh.is_finite(), "stage state not finite at step {k}");
        for (i, s) in cst.iter().enumerate() {
            assert!(s.is_finite(), "controller state[{i}] = {s} at step {k}");
        }
        x_min = x_min.min(st.x);
        x_max = x_max.max(st.x);
    }
    if let Some(kib) = peak_rss_kib() {
        println!("closed-loop soak (desired model terms: {desired}): {steps} steps, {spikes} spikes, {dropouts} dropouts, {saturated} saturated samples, peak RSS {kib} KiB");
    }
    // the stage never leaves what the amplifier range can produce (with creep, electrostriction
    // and resonance overshoot margin); the CEMF estimate stays within its Bouc-Wen bound
    assert!(x_min > -10e-6 && x_max < 40e-6, "x in [{x_min}, {x_max}]");
    assert!(cst[4].abs() <= 1.25e5 / (8000.0 - 3000.0) + 1e-9);
    assert!(spikes > 500 && dropouts > 500 && saturated > 1000, "{spikes} {dropouts} {saturated}");
    saturated as f64 / steps as f64
}
