//! Controllers (control.rs, smc.rs, absmc.rs, cemf.rs, compensated.rs, ilc.rs) through the
//! public API: construction errors name the parameter, the velocity observer is type 2 and
//! delay-compensated, every controller keeps its output inside the limits whatever it is fed,
//! PID anti-windup, the CEMF observer and the CEMF inverse feedforward against the stage
//! simulation, the exact inverse behind `Compensated`, and a long soak of the SMC.
//!
//! `cargo test -p piezohyst-core --test controllers`: ~3 s with the workspace's test profile
//! (opt-level 2), ~20 s at opt-level 0. The 10^7-step soak runs in `make test` (~7 s at opt-level 2 with the CEMF observer's
//! Newton solve).
use piezohyst_core::absmc::Absmc;
use piezohyst_core::cemf::{CemfFeedforward, CemfModel};
use piezohyst_core::closed_loop::{run_tracking, Loop, Trajectory};
use piezohyst_core::compensated::Compensated;
use piezohyst_core::control::{Controller, Limits, OpenLoop, Pid, PidConfig, Reference, VelocityObserver};
use piezohyst_core::ilc::Ilc;
use piezohyst_core::rng::Rng;
use piezohyst_core::sensor::Sensor;
use piezohyst_core::smc::{Smc, SmcConfig, Switching};
use piezohyst_core::spec::{Base, Family, Model};
use piezohyst_core::stage::{HysteresisDrive, Stage, StageParams, StageState, MAX_CREEP};
use piezohyst_core::{Hysteresis, Invertible, ModelError};
use proptest::prelude::*;
use proptest::test_runner::Config;
use std::f64::consts::PI;

const TS: f64 = 1e-4;
const U_MIN: f64 = -20.0;
const U_MAX: f64 = 150.0;

fn cfg(cases: u32) -> Config {
    Config { cases, failure_persistence: None, ..Config::default() }
}

fn volts() -> Limits {
    Limits::new(U_MIN, U_MAX).unwrap()
}

/// The virtual stage (python/piezohyst/presets/virtual_stage.json) with an ideal amplifier,
/// no creep and no electrostriction: exactly the CEMF model the observer and the
/// feedforward are built on.
fn ideal_stage_params() -> StageParams {
    let (mass, stiffness, tem) = (0.0714, 7.333e7, 10.5);
    StageParams {
        mass,
        damping: 2.0 * 0.03 * (stiffness * mass).sqrt(),
        stiffness,
        tem,
        capacitance: 1.8e-6,
        hyst_alpha: 1.25e5,
        hyst_beta: 8000.0,
        hyst_gamma: 3000.0,
        hyst_drive: HysteresisDrive::Charge,
        electrostriction: 0.0,
        creep_taus: [1.0; MAX_CREEP],
        creep_weights: [0.0; MAX_CREEP],
        creep_terms: 0,
        amp_min: U_MIN,
        amp_max: U_MAX,
        amp_bandwidth: f64::INFINITY,
        amp_slew: f64::INFINITY,
    }
}

/// The CEMF model of a stage (volt-normalized: M = m/Tem, B = b/Tem, K = k/Tem).
fn cemf_of(p: &StageParams) -> CemfModel {
    CemfModel {
        m: p.mass / p.tem,
        b: p.damping / p.tem,
        k: p.stiffness / p.tem,
        tem: p.tem,
        cz: p.capacitance,
        alpha: p.hyst_alpha,
        beta: p.hyst_beta,
        gamma: p.hyst_gamma,
    }
    .validated()
    .unwrap()
}

fn observer() -> VelocityObserver {
    VelocityObserver::new(1000.0, TS, 1.0).unwrap()
}

fn smc_boundary_layer(cemf: Option<CemfModel>, alpha: f64) -> Smc {
    let c = cemf_of(&ideal_stage_params());
    Smc::new(SmcConfig {
        m: c.m,
        b: c.b,
        k: c.k,
        kp: 1e6,
        kv: 2e3,
        alpha,
        switching: Switching::BoundaryLayer { gain: 5.0, width: 1e-3 },
        cemf,
        desired_model_terms: false,
        observer: observer(),
        limits: volts(),
    })
    .unwrap()
}

fn smc_super_twisting() -> Smc {
    let c = cemf_of(&ideal_stage_params());
    Smc::new(SmcConfig {
        m: c.m,
        b: c.b,
        k: c.k,
        kp: 1e6,
        kv: 2e3,
        alpha: 0.0,
        switching: Switching::SuperTwisting { k1: 50.0, k2: 1e4 },
        cemf: None,
        desired_model_terms: false,
        observer: observer(),
        limits: volts(),
    })
    .unwrap()
}

fn absmc(desired_regressor: bool) -> Absmc {
    let c = cemf_of(&ideal_stage_params());
    let (b, th) = (1.0 / c.m, [c.k / c.m, c.b / c.m]);
    Absmc {
        b,
        theta0: th,
        theta_min: [th[0] / 3.0, th[1] / 3.0],
        theta_max: [th[0] * 3.0, th[1] * 3.0],
        c1: 2e3,
        lambda: 2e3,
        ks: 1e3,
        phi: 1e-3,
        gamma_theta: [1e12, 1e6],
        gamma_d: 1e6,
        d0: 0.0,
        d_max: (U_MAX - U_MIN) * b,
        desired_regressor,
        observer: observer(),
        limits: volts(),
    }
    .validated()
    .unwrap()
}

fn pid() -> Pid {
    let p = ideal_stage_params();
    Pid::new(PidConfig {
        kp: 1e6,
        ki: 5e9,
        kd: 10.0,
        tau_d: 1e-4,
        ts: TS,
        ff_gain: p.stiffness / p.tem,
        offset: 0.0,
        limits: volts(),
    })
    .unwrap()
}

/// A PI row (µm per V when `scale = 1`, m per V when `scale = 1e-6`) with one negative
/// weight (all partial sums stay > 0, so it is invertible).
fn pi_row(scale: f64) -> (Family, Vec<f64>) {
    let n = 8;
    let fam = Family::parse("pi", &[n, 0]).unwrap();
    let p0 = 0.05 * scale;
    let r: Vec<f64> = (0..n).map(|i| 15.0 * i as f64).collect();
    let w: Vec<f64> = [0.06, 0.03, 0.02, -0.01, 0.015, 0.01, 0.005, 0.004].iter().map(|w| w * scale).collect();
    let mut row = vec![p0];
    row.extend(&r);
    row.extend(&w);
    assert_eq!(row.len(), fam.param_len());
    (fam, row)
}

/// Output of the model on its initial loading curve at `v` (from the relaxed state, `v >= 0`)
/// and on the descent from relaxed to `v < 0`: the outputs at the amplifier limits.
fn model_range(m: &Model<'_>) -> (f64, f64) {
    let mut s = vec![0.0; m.state_len()];
    m.reset(&mut s);
    let lo = m.step(&mut s, U_MIN);
    m.reset(&mut s);
    let hi = m.step(&mut s, U_MAX);
    (lo, hi)
}

fn msg(e: ModelError) -> String {
    format!("{e}")
}

// ---------------------------------------------------------------------------------------
// 1. construction errors
// ---------------------------------------------------------------------------------------

#[test]
fn construction_errors_name_the_parameter() {
    let c = cemf_of(&ideal_stage_params());
    let bl = Switching::BoundaryLayer { gain: 5.0, width: 1e-3 };
    let smc = |kp: f64, kv: f64, alpha: f64, sw: Switching| {
        Smc::new(SmcConfig {
            m: c.m,
            b: c.b,
            k: c.k,
            kp,
            kv,
            alpha,
            switching: sw,
            cemf: None,
            desired_model_terms: false,
            observer: observer(),
            limits: volts(),
        })
    };
    assert!(smc(1e6, 2e3, 0.0, bl).is_ok());

    // kv + alpha <= 0 (boundary included)
    for (kv, alpha) in [(-1.0, 0.5), (0.0, 0.0), (-3.0, 3.0)] {
        let e = msg(smc(1e6, kv, alpha, bl).unwrap_err());
        assert!(e.contains("kv + alpha") && e.contains("sliding dynamics unstable"), "{e}");
    }
    // alpha kv + kp <= 0 with kv + alpha > 0
    for (kp, kv, alpha) in [(-2.0, 1.0, 1.0), (0.0, 1.0, 0.0), (-1e6, 2e3, 100.0)] {
        let e = msg(smc(kp, kv, alpha, bl).unwrap_err());
        assert!(e.contains("alpha * kv + kp") && e.contains("sliding dynamics unstable"), "{e}");
    }
    // just stable: alpha kv + kp = 1e-9 > 0
    assert!(smc(-2.0 + 1e-9, 1.0, 2.0, bl).is_ok());
    for width in [0.0, -1e-3] {
        let e = msg(smc(1e6, 2e3, 0.0, Switching::BoundaryLayer { gain: 5.0, width }).unwrap_err());
        assert!(e.starts_with("phi = ") && e.contains("must be > 0"), "{e}");
    }
    let e = msg(smc(1e6, 2e3, 0.0, Switching::BoundaryLayer { gain: -1.0, width: 1e-3 }).unwrap_err());
    assert!(e.starts_with("ks = -1") && e.contains(">= 0"), "{e}");
    assert!(smc(1e6, 2e3, 0.0, Switching::BoundaryLayer { gain: 0.0, width: 1e-3 }).is_ok());
    let e = msg(smc(1e6, 2e3, 0.0, Switching::SuperTwisting { k1: -1.0, k2: 0.0 }).unwrap_err());
    assert!(e.starts_with("k1 = "), "{e}");
    let e = msg(smc(1e6, 2e3, -1.0, bl).unwrap_err());
    assert!(e.starts_with("alpha = -1"), "{e}");

    // ABSMC
    let th = [c.k / c.m, c.b / c.m];
    let ab = |theta0: [f64; 2], gains: (f64, f64, f64, f64), gamma_d: f64| {
        Absmc {
            b: 1.0 / c.m,
            theta0,
            theta_min: [th[0] / 3.0, th[1] / 3.0],
            theta_max: [th[0] * 3.0, th[1] * 3.0],
            c1: gains.0,
            lambda: gains.1,
            ks: gains.2,
            phi: gains.3,
            gamma_theta: [1e12, 1e6],
            gamma_d,
            d0: 0.0,
            d_max: 1e6,
            desired_regressor: true,
            observer: observer(),
            limits: volts(),
        }
        .validated()
    };
    assert!(ab(th, (2e3, 2e3, 1e3, 1e-3), 1e6).is_ok());
    for c1 in [0.0, -5.0] {
        let e = msg(ab(th, (c1, 2e3, 1e3, 1e-3), 1e6).unwrap_err());
        assert!(e.starts_with("c1 = ") && e.contains("must be > 0"), "{e}");
    }
    for gamma_d in [0.0, -1.0] {
        let e = msg(ab(th, (2e3, 2e3, 1e3, 1e-3), gamma_d).unwrap_err());
        assert!(e.starts_with("gamma_d = ") && e.contains("must be > 0"), "{e}");
    }
    for (i, theta0) in [[th[0] * 3.5, th[1]], [th[0], th[1] / 4.0]].into_iter().enumerate() {
        let err = ab(theta0, (2e3, 2e3, 1e3, 1e-3), 1e6).unwrap_err();
        let (lo, hi) = ([th[0] / 3.0, th[1] / 3.0][i], [th[0] * 3.0, th[1] * 3.0][i]);
        assert_eq!(err, ModelError::OutOfRange("theta0", i, theta0[i], lo, hi));
        let e = msg(err);
        assert_eq!(e, format!("theta0[{i}] = {} must lie within [{lo}, {hi}]", theta0[i]));
    }
    let e = msg(Absmc {
        b: 1.0 / c.m,
        theta0: th,
        theta_min: [th[0] / 3.0, th[1] / 3.0],
        theta_max: [th[0] * 3.0, th[1] * 3.0],
        c1: 2e3,
        lambda: 2e3,
        ks: 1e3,
        phi: 1e-3,
        gamma_theta: [1e12, 1e6],
        gamma_d: 1e6,
        d0: 2.0,
        d_max: 1.0,
        desired_regressor: true,
        observer: observer(),
        limits: volts(),
    }
    .validated()
    .unwrap_err());
    assert_eq!(e, "d0 = 2 must lie within [0, 1]");
    // on the bounds is fine
    assert!(ab([th[0] * 3.0, th[1] / 3.0], (2e3, 2e3, 1e3, 1e-3), 1e6).is_ok());

    // velocity observer: Nyquist
    assert!(VelocityObserver::new(4999.999, TS, 0.0).is_ok());
    for bw in [5000.0, 6000.0] {
        let e = msg(VelocityObserver::new(bw, TS, 0.0).unwrap_err());
        assert!(e.contains("observer_bandwidth") && e.contains("Nyquist"), "{e}");
    }
    let e = msg(VelocityObserver::new(100.0, TS, -1.0).unwrap_err());
    assert!(e.starts_with("observer_delay = -1"), "{e}");

    // ILC
    let ilc = |period: usize, forgetting: f64, lead: usize| Ilc::new(pid(), period, 0.5, forgetting, lead, 1);
    assert!(ilc(100, 1.0, 99).is_ok());
    let e = msg(ilc(100, 1.0 + 1e-12, 3).unwrap_err());
    assert!(e.contains("forgetting") && e.contains("must lie within [0, 1]"), "{e}");
    let e = msg(ilc(100, 0.0, 3).unwrap_err());
    assert!(e.contains("forgetting"), "{e}");
    let e = msg(ilc(0, 1.0, 0).unwrap_err());
    assert_eq!(e, "period = 0 is out of range");
    let e = msg(ilc(piezohyst_core::ilc::MAX_PERIOD + 1, 1.0, 0).unwrap_err());
    assert!(e.starts_with("period = "), "{e}");
    for lead in [100, 250] {
        let e = msg(ilc(100, 1.0, lead).unwrap_err());
        assert!(e.contains("lead") && e.contains(&format!("= {lead}")), "{e}");
    }

    // CEMF model: beta >= |gamma| (equality allowed)
    let cm = |beta: f64, gamma: f64| {
        CemfModel { m: c.m, b: c.b, k: c.k, tem: c.tem, cz: c.cz, alpha: c.alpha, beta, gamma }.validated()
    };
    assert!(cm(3000.0, 3000.0).is_ok() && cm(3000.0, -3000.0).is_ok());
    for (beta, gamma) in [(2999.0, 3000.0), (2999.0, -3000.0), (-1.0, 0.0)] {
        let err = cm(beta, gamma).unwrap_err();
        let e = msg(err);
        assert!(e.contains("hyst_beta - |hyst_gamma|") && e.contains(&format!("= {}", beta - gamma.abs())), "{e}");
    }
}

/// Error texts must not contradict themselves. Some controller checks reuse variants whose
/// `Display` was written for other cases.
#[test]
fn error_texts_are_not_misleading() {
    let limits = msg(Limits::new(1.0, 1.0).unwrap_err());
    assert!(!limits.contains("18446744073709551"), "{limits}");
    assert!(!limits.contains("thresholds must be strictly increasing"), "{limits}");
    let forgetting = msg(Ilc::new(pid(), 100, 0.5, 1.5, 3, 1).unwrap_err());
    assert!(!forgetting.ends_with("= 1.5 must be > 0"), "{forgetting}");
    let nyquist = msg(VelocityObserver::new(6000.0, TS, 0.0).unwrap_err());
    assert!(!nyquist.ends_with("= 6000 must be > 0"), "{nyquist}");
}

// ---------------------------------------------------------------------------------------
// 2. velocity observer
// ---------------------------------------------------------------------------------------

#[test]
fn observer_is_type_two_on_an_exact_ramp() {
    let (x0, v0) = (3e-6, 1.7e-3);
    for bandwidth in [200.0, 1000.0] {
        let obs = VelocityObserver::new(bandwidth, TS, 0.0).unwrap();
        let mut s = [0.0; VelocityObserver::STATE_LEN];
        obs.reset(&mut s, x0);
        let mut last_bad = 0;
        let (mut worst_v, mut worst_x) = (0.0f64, 0.0f64);
        for k in 0..2000 {
            let y = x0 + v0 * k as f64 * TS;
            let (x, v) = obs.update(&mut s, y);
            let rel = ((v - v0) / v0).abs();
            if rel > 1e-9 {
                last_bad = k;
            }
            if k >= 1000 {
                worst_v = worst_v.max(rel);
                worst_x = worst_x.max((x - y).abs());
            }
        }
        eprintln!("observer {bandwidth} Hz ramp: |v/v0 - 1| <= 1e-9 from step {} on; after 1000 steps worst {worst_v:.2e}, |x - y| {worst_x:.2e} m", last_bad + 1);
        // double pole at p = exp(-2 pi f Ts): 0.533 at 1 kHz, 0.882 at 200 Hz
        assert!(last_bad < 400, "{bandwidth} Hz: not within 1e-9 by step {last_bad}");
        assert!(worst_v < 1e-11, "{worst_v}");
        assert!(worst_x < 1e-18, "no lag on a ramp: {worst_x}");
    }
}

#[test]
fn observer_compensates_the_delay_on_a_ramp() {
    let (x0, v0) = (-2e-6, 4e-3);
    for delay in [1.0, 2.5, 7.0] {
        let obs = VelocityObserver::new(1000.0, TS, delay).unwrap();
        let mut s = [0.0; 2];
        obs.reset(&mut s, x0);
        let mut worst = 0.0f64;
        for k in 0..1000 {
            let y = x0 + v0 * k as f64 * TS;
            let (x, v) = obs.update(&mut s, y);
            if k >= 500 {
                worst = worst.max((x - (y + delay * TS * v0)).abs() / (delay * TS * v0));
                assert!(((v - v0) / v0).abs() < 1e-10);
            }
        }
        eprintln!("observer delay {delay}: |x_reported - (y + d Ts v0)| / (d Ts v0) <= {worst:.2e}");
        assert!(worst < 1e-9, "delay {delay}: {worst}");
    }
    // and the uncompensated reading lags by exactly d Ts v0: zero delay reports y itself
    let obs = VelocityObserver::new(1000.0, TS, 0.0).unwrap();
    let mut s = [0.0; 2];
    obs.reset(&mut s, x0);
    let mut x = 0.0;
    for k in 0..1000 {
        x = obs.update(&mut s, x0 + v0 * k as f64 * TS).0;
    }
    assert!((x - (x0 + v0 * 999.0 * TS)).abs() < 1e-18);
}

#[test]
fn observer_smooths_a_quantized_slow_ramp() {
    let q = 1e-7; // 0.1 µm encoder at 10 kHz
    let v0 = 2e-4; // 0.2 quantization steps per sample
    let quantize = |x: f64| (x / q).round() * q;
    let y = |k: usize| quantize(1.234e-6 + v0 * k as f64 * TS);
    // the raw difference: 0 or a whole step per sample (1 mm/s = 5 v0)
    let (mut raw_zero, mut raw_nonzero_min, mut worst_raw, mut n) = (0usize, f64::INFINITY, 0.0f64, 0usize);
    for k in 2000..20_000 {
        let raw = (y(k) - y(k - 1)) / TS;
        n += 1;
        worst_raw = worst_raw.max(((raw - v0) / v0).abs());
        if raw == 0.0 {
            raw_zero += 1;
        } else {
            raw_nonzero_min = raw_nonzero_min.min(raw);
        }
    }
    eprintln!(
        "quantized ramp v0 = {v0} m/s: raw difference 0 on {raw_zero}/{n} samples, otherwise >= {raw_nonzero_min:.3e} m/s \
         (= {:.2} v0); worst |raw/v0 - 1| = {worst_raw:.2}",
        raw_nonzero_min / v0
    );
    assert_eq!(raw_zero, 4 * n / 5);
    assert!(raw_nonzero_min >= 0.999 * q / TS, "{raw_nonzero_min}");
    assert!((worst_raw - 4.0).abs() < 1e-6, "{worst_raw}");
    // the observer spreads a step over ~1/bandwidth: the ripple grows ~ bandwidth^2
    for (bandwidth, bound) in [(100.0, 0.02), (1000.0, 0.75)] {
        let obs = VelocityObserver::new(bandwidth, TS, 0.0).unwrap();
        let mut s = [0.0; 2];
        obs.reset(&mut s, y(0));
        let mut worst = 0.0f64;
        for k in 1..20_000 {
            let (_, v) = obs.update(&mut s, y(k));
            if k >= 2000 {
                worst = worst.max(((v - v0) / v0).abs());
            }
        }
        eprintln!("quantized ramp, observer at {bandwidth} Hz: worst |v/v0 - 1| = {worst:.4}");
        assert!(worst < bound, "{bandwidth} Hz: {worst}");
        assert!(worst < worst_raw / 5.0);
    }
}

// ---------------------------------------------------------------------------------------
// 3. outputs always inside the limits, whatever the inputs
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy)]
enum Reading {
    Normal(f64),
    Spike(f64),
    Huge(f64),
    Dropout,
}

fn reading() -> impl Strategy<Value = Reading> {
    prop_oneof![
        12 => (-3e-5..3e-5f64).prop_map(Reading::Normal),
        1 => prop::sample::select(vec![1.0, -1.0]).prop_map(Reading::Spike),
        1 => prop::sample::select(vec![1e6, -1e6, 1e3]).prop_map(Reading::Huge),
        2 => Just(Reading::Dropout),
    ]
}

fn scalar(normal: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        10 => -normal..normal,
        1 => prop::sample::select(vec![1.0, -1.0, 1e6, -1e6, 0.0]),
    ]
}

fn references() -> impl Strategy<Value = Vec<Reference>> {
    prop::collection::vec((scalar(3e-5), scalar(1e-2), scalar(1e2)).prop_map(|(x, v, a)| Reference { x, v, a }), 1000)
}

/// Drive `c` with the references and readings; every output inside the limits, finite;
/// every state slot finite at the end (and after every step).
fn check_bounded<C: Controller>(
    name: &str,
    c: &C,
    refs: &[Reference],
    readings: &[Reading],
) -> Result<(), TestCaseError> {
    let lim = c.limits();
    let mut s = vec![f64::NAN; c.state_len()];
    let y0 = 1e-6;
    c.reset(&mut s, y0);
    prop_assert!(s.iter().all(|x| x.is_finite()), "{name}: reset left {s:?}");
    let mut last = y0;
    for (k, (r, rd)) in refs.iter().zip(readings).enumerate() {
        let y = match *rd {
            Reading::Normal(y) | Reading::Spike(y) | Reading::Huge(y) => y,
            Reading::Dropout => last,
        };
        last = y;
        let out = c.step(&mut s, r, y);
        prop_assert!(
            out.u.is_finite() && lim.min <= out.u && out.u <= lim.max,
            "{name}: step {k}: u = {} outside [{}, {}]",
            out.u,
            lim.min,
            lim.max
        );
        prop_assert!(s.iter().all(|x| x.is_finite()), "{name}: step {k}: state {s:?}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(cfg(200))]
    #[test]
    fn outputs_stay_inside_the_limits(refs in references(), readings in prop::collection::vec(reading(), 1000)) {
        check_bounded("pid", &pid(), &refs, &readings)?;
        check_bounded("smc boundary layer + cemf", &smc_boundary_layer(Some(cemf_of(&ideal_stage_params())), 0.0), &refs, &readings)?;
        check_bounded("smc boundary layer, alpha 200", &smc_boundary_layer(None, 200.0), &refs, &readings)?;
        check_bounded("smc super-twisting", &smc_super_twisting(), &refs, &readings)?;
        check_bounded("absmc desired", &absmc(true), &refs, &readings)?;
        check_bounded("absmc measured", &absmc(false), &refs, &readings)?;
        check_bounded("ilc(pid)", &Ilc::new(pid(), 97, 2e5, 0.99, 3, 1).unwrap(), &refs, &readings)?;
        check_bounded("ilc(smc)", &Ilc::new(smc_super_twisting(), 50, 1e6, 1.0, 2, 1).unwrap(), &refs, &readings)?;

        // behind an exact inverse PI model (in m), inner limits = model outputs at the volt limits
        let (fam, row) = pi_row(1e-6);
        let mut scratch = vec![0.0; fam.scratch_len()];
        let model = fam.build(&row, &mut scratch).unwrap();
        let (y_lo, y_hi) = model_range(&model);
        let disp = Limits::new(y_lo, y_hi).unwrap();
        let inner_pid = Pid::new(PidConfig { kp: 0.5, ki: 2e3, kd: 0.0, tau_d: 1e-4, ts: TS, ff_gain: 1.0, offset: 0.0, limits: disp }).unwrap();
        check_bounded("compensated(pid, pi)", &Compensated { inner: inner_pid, model, limits: volts() }, &refs, &readings)?;
        // inner limits far wider than the model can reach: the voltage is still clamped
        let wide = OpenLoop::new(1.0, 0.0, 1e-4, 1e-8, Limits::new(-1e7, 1e7).unwrap()).unwrap();
        check_bounded("compensated(open loop, pi)", &Compensated { inner: wide, model, limits: volts() }, &refs, &readings)?;
        check_bounded("ilc(compensated(pid, pi))", &Ilc::new(Compensated { inner: inner_pid, model, limits: volts() }, 40, 1e6, 1.0, 2, 1).unwrap(), &refs, &readings)?;
        check_bounded("cemf feedforward", &CemfFeedforward { model: cemf_of(&ideal_stage_params()), limits: volts() }, &refs, &readings)?;
    }
}

// ---------------------------------------------------------------------------------------
// 4. anti-windup
// ---------------------------------------------------------------------------------------

#[test]
fn pid_integrator_does_not_wind_up() {
    let (kp, ki) = (1e6, 1e10); // P = 10 V and I grows 10 V per sample at e = 10 µm
    let pid = Pid::new(PidConfig { kp, ki, kd: 0.0, tau_d: 1e-4, ts: TS, ff_gain: 0.0, offset: 0.0, limits: volts() })
        .unwrap();
    let mut s = [0.0; 3];
    pid.reset(&mut s, 0.0);
    let r = Reference { x: 1e-5, v: 0.0, a: 0.0 };
    // the stage is stuck at 0: saturated high for 10 000 samples
    let mut naive_i = 0.0; // an unclamped integrator with the same gain
    let mut out = pid.step(&mut s, &r, 0.0);
    naive_i += ki * TS * 1e-5;
    for _ in 1..10_000 {
        out = pid.step(&mut s, &r, 0.0);
        naive_i += ki * TS * 1e-5;
    }
    assert_eq!(out.u, U_MAX);
    let i_held = out.terms[1];
    eprintln!(
        "anti-windup: integral held at {i_held} V (limit - P = {}), unclamped integrator {naive_i:.0} V",
        U_MAX - 10.0
    );
    // the integrator stopped at the last value that kept the output inside: I <= max - P
    assert!(i_held <= U_MAX - kp * 1e-5 + 1e-9 && i_held > U_MAX - kp * 1e-5 - ki * TS * 1e-5 - 1e-9, "{i_held}");
    assert!((naive_i - 1e5).abs() < 1e-3);

    // the error changes sign: the stage overshoots to 20 µm
    let flipped = Reference { x: 1e-5, v: 0.0, a: 0.0 };
    let y = 2e-5;
    let first = pid.step(&mut s, &flipped, y).u;
    // leaves saturation at once: u = P + I = -10 + (I - 10)
    assert!(first < U_MAX - 15.0, "{first}");
    let mut steps_to_min = 1;
    while pid.step(&mut s, &flipped, y).u > U_MIN {
        steps_to_min += 1;
        assert!(steps_to_min < 100);
    }
    // an unclamped PI would stay at the upper limit until 1e5 V were unwound at 10 V/sample
    let (mut naive_steps, mut ni) = (0usize, naive_i);
    loop {
        ni += ki * TS * (flipped.x - y);
        naive_steps += 1;
        if kp * (flipped.x - y) + ni < U_MAX {
            break;
        }
    }
    eprintln!("anti-windup: off the upper limit after 1 step (u = {first:.3} V), at the lower limit after {steps_to_min}; unclamped: {naive_steps} steps at the upper limit");
    assert!(steps_to_min <= 16, "{steps_to_min}");
    assert!(naive_steps > 9_900, "{naive_steps}");
}

// ---------------------------------------------------------------------------------------
// 5. CEMF observer against the stage
// ---------------------------------------------------------------------------------------

/// Slow, continuous voltage: 1 Hz 0..140 V for 2 s, then a 1.5 Hz 0..80 V minor loop.
fn slow_drive(k: usize) -> f64 {
    let t = k as f64 * TS;
    if k < 20_000 {
        70.0 * (1.0 - (2.0 * PI * t).cos())
    } else {
        40.0 * (1.0 - (3.0 * PI * (t - 2.0)).cos())
    }
}

struct ObserverRun {
    /// Largest |Vh_hat - Vh| over the run, V.
    worst: f64,
    /// Range of the stage's Vh, V.
    range: f64,
    /// Largest |Vh_hat - Vh| of an observer fed the voltage only (dx = 0), V.
    worst_blind: f64,
    /// Largest loop residual `|BW(vh, q_ext - Cz dVh) - vh_new|` of an observe call, V.
    residual: f64,
}

/// Drive the stage with `slow_drive` (held over each sample `TS`), integrated with
/// `substeps` sub-steps per `TS / fine`; run the observer on every `TS / fine` (voltage
/// increment at the first, position increments at each; both in one call when `fine = 1`,
/// as the SMC does).
fn observe_along(p: StageParams, substeps: usize, fine: usize) -> ObserverRun {
    let stage = Stage::new(p, TS / fine as f64, substeps, f64::INFINITY).unwrap();
    let model = cemf_of(&p);
    let mut st = StageState::ZERO;
    let (mut vh_hat, mut vh_blind, mut u_prev) = (0.0, 0.0, 0.0);
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    let mut run = ObserverRun { worst: 0.0, range: 0.0, worst_blind: 0.0, residual: 0.0 };
    for k in 0..30_000 {
        let u = slow_drive(k);
        for j in 0..fine {
            let du = if j == 0 { u - u_prev } else { 0.0 };
            let x0 = st.x;
            stage.advance(&mut st, u);
            let dx = st.x - x0;
            // fed finer than a sample, the voltage step goes first (the stage steps the
            // ideal amplifier at the start of the period, then moves)
            let parts = if fine > 1 { [(0.0, du), (dx, 0.0)] } else { [(dx, du), (0.0, 0.0)] };
            for (dx, du) in parts {
                let next = model.observe(vh_hat, dx, du);
                // the charge balance dq = Tem dx + Cz (du - dVh) holds with dVh = BW(vh, dq)
                let dq = model.tem * dx + model.cz * (du - (next - vh_hat));
                run.residual = run.residual.max((model.hysteresis(vh_hat, dq) - next).abs());
                vh_hat = next;
            }
            vh_blind = model.observe(vh_blind, 0.0, du);
        }
        u_prev = u;
        lo = lo.min(st.vh);
        hi = hi.max(st.vh);
        run.worst = run.worst.max((vh_hat - st.vh).abs());
        run.worst_blind = run.worst_blind.max((vh_blind - st.vh).abs());
    }
    run.range = hi - lo;
    run
}

#[test]
fn cemf_observer_matches_the_stage() {
    // critically damped: the motion inside a sample is monotone, so the sampled increments
    // carry the whole charge path and the observer must reproduce the stage's Vh
    let mut damped = ideal_stage_params();
    damped.damping = 2.0 * (damped.stiffness * damped.mass).sqrt();
    let a = observe_along(damped, 64, 1);
    eprintln!(
        "cemf observer, zeta = 1, 64 sub-steps: Vh range {:.4} V, worst |Vh_hat - Vh| = {:.3e} V ({:.2e} of the range), \
         loop residual {:.1e} V; ignoring dx: {:.3} V",
        a.range,
        a.worst,
        a.worst / a.range,
        a.residual,
        a.worst_blind
    );
    assert!(a.range > 20.0, "{}", a.range);
    assert!(a.worst < 1e-6 * a.range, "{}", a.worst);
    assert!(a.residual < 1e-12, "{}", a.residual);
    assert!(a.worst_blind > 0.05 * a.range, "{}", a.worst_blind);

    // the virtual stage (zeta = 0.03) rings at 5.1 kHz inside each 100 µs sample, so the
    // charge reverses between samples: fed every sub-step the observer still matches ...
    let p = ideal_stage_params();
    let b = observe_along(p, 1, 16);
    // ... fed only the sampled increments it cannot see the reversals (a modelling limit of
    // any sampled observer, not an error of the solve)
    let c = observe_along(p, 16, 1);
    eprintln!(
        "cemf observer, zeta = 0.03: fed every TS/16: worst {:.3e} V ({:.2e} of the range); fed every TS with 16 sub-steps: \
         {:.3e} V ({:.2e} of the range)",
        b.worst,
        b.worst / b.range,
        c.worst,
        c.worst / c.range
    );
    assert!(b.worst < 1e-6 * b.range, "{}", b.worst);
    assert!(b.residual < 1e-12 && c.residual < 1e-12);
    assert!(c.worst < 5e-3 * c.range, "{}", c.worst);
}

/// The ideal amplifier (infinite bandwidth and slew) steps the voltage at the start of a
/// period; the CEMF loop `dq = Cz (dVa - dVh)`, `dVh = BW(vh, dq)` must then hold like it
/// does for every sub-step. A period of 1 ns on the virtual stage leaves the position
/// nearly still (|dx| ~ 1e-14 m, in the step's direction), so the observer's exact loop solution is the reference.
#[test]
#[ignore = "BUG: Stage::advance with an ideal amplifier (amp_bandwidth = amp_slew = inf) solves \
            the CEMF loop of the voltage step at the start of a period only approximately (stage.rs \
            `cemf`: second-order guess + one Newton step with the starting slope, for the whole step, \
            outside the sub-step refinement): loop residual 2.6e-7 V for 0 -> 1 V, 1.8e-4 V for \
            0 -> 10 V, 4.3e-2 V for 0 -> 150 V, 1.5 V for 100 -> -50 V (Vh crosses 0: stage -7.985 V, \
            exact -9.441 V)"]
fn stage_voltage_step_satisfies_the_cemf_loop() {
    let p = ideal_stage_params();
    let model = cemf_of(&p);
    let stage = Stage::new(p, 1e-9, 1, f64::INFINITY).unwrap();
    let slow = Stage::new(p, TS, 4, 0.01).unwrap();
    let mut report = Vec::new();
    for (from, to) in [(0.0, 1.0), (0.0, 10.0), (0.0, 150.0), (100.0, -50.0)] {
        let mut st = StageState::ZERO;
        // reach `from` in 0.1 s and settle for 0.1 s
        for i in 1..=2000 {
            slow.advance(&mut st, from * (i.min(1000) as f64 / 1000.0));
        }
        let (vh0, x0) = (st.vh, st.x);
        stage.advance(&mut st, to);
        let dx = st.x - x0;
        // the position barely moves, in the direction of the step: the charge path is monotone
        assert!(dx * (to - from) >= 0.0 && (model.tem * dx).abs() < 1e-6 * model.cz * (to - from).abs(), "{dx}");
        let dq = model.tem * dx + model.cz * ((to - from) - (st.vh - vh0));
        let residual = (model.hysteresis(vh0, dq) - st.vh).abs();
        let exact = model.observe(vh0, dx, to - from);
        report.push((
            format!("{from} -> {to} V: stage Vh {:.9}, exact {exact:.9}, loop residual {residual:.2e} V", st.vh),
            residual,
        ));
    }
    eprintln!("{}", report.iter().map(|r| r.0.as_str()).collect::<Vec<_>>().join("\n"));
    for (line, residual) in &report {
        assert!(*residual < 1e-9, "{line}");
    }
}

// ---------------------------------------------------------------------------------------
// 6. CEMF inverse feedforward drives the stage along the reference
// ---------------------------------------------------------------------------------------

#[test]
fn cemf_feedforward_inverts_the_stage() {
    let p = ideal_stage_params();
    let stage = Stage::new(p, TS, 8, 0.01).unwrap();
    let sensor = Sensor::new(0.0, 0.0, 0).unwrap();
    let model = cemf_of(&p);
    let ff = CemfFeedforward { model, limits: volts() };
    let amp = 15e-6;
    let w = 2.0 * PI; // 1 Hz
    let n = 20_000; // two periods
    let t = |k: usize| k as f64 * TS;
    let r: Vec<f64> = (0..n).map(|k| 0.5 * amp * (1.0 - (w * t(k)).cos())).collect();
    let v: Vec<f64> = (0..n).map(|k| 0.5 * amp * w * (w * t(k)).sin()).collect();
    let a: Vec<f64> = (0..n).map(|k| 0.5 * amp * w * w * (w * t(k)).cos()).collect();

    let mut st = StageState::ZERO;
    let mut sst = sensor.state(0.0, 1);
    let mut cs = [0.0; 2];
    ff.reset(&mut cs, 0.0);
    let trajectory = Trajectory { position: &r, velocity: &v, acceleration: &a };
    let parts = Loop {
        stage: &stage,
        stage_state: &mut st,
        sensor: &sensor,
        sensor_state: &mut sst,
        controller: &ff,
        controller_state: &mut cs,
    };
    let tr = run_tracking(parts, trajectory, 0);
    // a static inverse without the hysteresis voltage, for contrast
    let static_inverse = OpenLoop::new(model.k, 0.0, 0.0, 0.0, volts()).unwrap();
    let mut st2 = StageState::ZERO;
    let mut sst2 = sensor.state(0.0, 1);
    let parts = Loop {
        stage: &stage,
        stage_state: &mut st2,
        sensor: &sensor,
        sensor_state: &mut sst2,
        controller: &static_inverse,
        controller_state: &mut [],
    };
    let tr_static = run_tracking(parts, trajectory, 0);
    let rms = |t: &piezohyst_core::closed_loop::Tracking| (t.sse / t.samples as f64).sqrt() / amp;
    eprintln!(
        "cemf feedforward: max |r - x| = {:.3e} m = {:.3} % of the amplitude (rms {:.3} %), saturated {}; static inverse: {:.2} %",
        tr.max_error,
        100.0 * tr.max_error / amp,
        100.0 * rms(&tr),
        tr.saturated,
        100.0 * tr_static.max_error / amp
    );
    assert_eq!(tr.samples, n);
    assert_eq!(tr.saturated, 0);
    assert!(tr.max_error < 0.005 * amp, "{}", tr.max_error);
    assert!(tr_static.max_error > 0.05 * amp, "{}", tr_static.max_error);
}

// ---------------------------------------------------------------------------------------
// 7. exact inverse behind Compensated
// ---------------------------------------------------------------------------------------

#[test]
fn compensated_open_loop_is_the_exact_inverse() {
    let (fam, row) = pi_row(1.0); // µm per volt
    let mut scratch = vec![0.0; fam.scratch_len()];
    let model = fam.build(&row, &mut scratch).unwrap();
    assert!(matches!(model.base, Base::Pi(_)));
    let (y_lo, y_hi) = model_range(&model);
    let inner = OpenLoop::new(1.0, 0.0, 0.0, 0.0, Limits::new(-1e3, 1e3).unwrap()).unwrap();
    let comp = Compensated { inner, model, limits: volts() };
    assert_eq!(comp.state_len(), fam.state_len() + 1); // open loop has no state

    let run = |refs: &dyn Fn(usize) -> f64, n: usize| {
        let mut s = vec![0.0; comp.state_len()];
        comp.reset(&mut s, 0.0);
        let mut shadow = vec![0.0; model.state_len()];
        model.reset(&mut shadow);
        let (mut inside, mut above, mut below, mut worst) = (0, 0, 0, 0.0f64);
        for k in 0..n {
            let target = refs(k);
            // what the model can output at this sample, from its current state
            let lo = model.trial(&shadow, U_MIN).0;
            let hi = model.trial(&shadow, U_MAX).0;
            let u = comp.step(&mut s, &Reference { x: target, v: 0.0, a: 0.0 }, 0.0).u;
            assert!((U_MIN..=U_MAX).contains(&u), "u = {u}");
            let y = model.step(&mut shadow, u);
            if target >= lo && target <= hi {
                inside += 1;
                worst = worst.max((y - target).abs());
            } else if target > hi {
                above += 1;
                assert_eq!(u, U_MAX, "k {k}: target {target} above {hi}");
                assert_eq!(y, hi);
            } else {
                below += 1;
                assert_eq!(u, U_MIN, "k {k}: target {target} below {lo}");
                assert_eq!(y, lo);
            }
        }
        (inside, above, below, worst)
    };
    let mid = 0.5 * (y_lo + y_hi);
    let half = 0.5 * (y_hi - y_lo);
    // inside the range: a decaying two-tone reference (nested minor loops)
    let inside_ref = |k: usize| {
        let t = k as f64 * 1e-3;
        mid + half * (0.9 * (-0.2 * t).exp() * (2.0 * PI * 0.5 * t).sin() + 0.05 * (2.0 * PI * 7.3 * t).sin())
    };
    let (i1, a1, b1, w1) = run(&inside_ref, 10_000);
    // beyond the range on both sides, and huge targets
    let beyond_ref = |k: usize| {
        let t = k as f64 * 1e-3;
        match k % 1000 {
            500 => 1e6,
            501 => -1e6,
            _ => mid + 1.4 * half * (2.0 * PI * 0.5 * t).sin(),
        }
    };
    let (i2, a2, b2, w2) = run(&beyond_ref, 10_000);
    eprintln!(
        "compensated PI: output range [{y_lo:.3}, {y_hi:.3}] µm; in-range reference {i1} samples, worst |model(u) - r| = {w1:.2e} µm; \
         beyond-range reference: {i2} inside (worst {w2:.2e} µm), {a2} above, {b2} below (u at the limit, output at the reachable extreme)"
    );
    assert_eq!((a1, b1), (0, 0));
    assert!(w1 <= 1e-9, "{w1}");
    assert!(a2 > 1000 && b2 > 1000 && i2 > 1000);
    assert!(w2 <= 1e-9, "{w2}");
}

// ---------------------------------------------------------------------------------------
// 8. soak
// ---------------------------------------------------------------------------------------

/// l1 norms of the observer's impulse responses (state slots x and v): bounds of |x| and |v|
/// per unit of the largest |reading| (BIBO; the state after a reset at `y0` is the steady
/// state of a constant reading `y0`).
fn observer_l1_gains(obs: &VelocityObserver) -> (f64, f64) {
    let mut s = [0.0; 2];
    let (mut gx, mut gv) = (0.0, 0.0);
    for k in 0..100_000 {
        obs.update(&mut s, if k == 0 { 1.0 } else { 0.0 });
        gx += s[0].abs();
        gv += s[1].abs();
    }
    (gx, gv)
}

/// `steps` steps of the SMC with the CEMF observer, alpha > 0 (xi bounded), no plant.
/// Readings follow a sine reference with errors, spikes of +-1 m and dropouts (the reading
/// repeats for 1..500 samples). Returns the largest |slot| of the state.
fn soak(steps: usize, seed: u64) -> [f64; 8] {
    let model = cemf_of(&ideal_stage_params());
    let alpha = 200.0;
    let smc = smc_boundary_layer(Some(model), alpha);
    assert_eq!(smc.state_len(), 8);
    let (gx, gv) = observer_l1_gains(&smc.config().observer);
    let vh_bound = model.alpha / (model.beta + model.gamma);
    let mut rng = Rng::new(seed);
    let mut s = [0.0; 8];
    smc.reset(&mut s, 0.0);
    let (mut max_slot, mut max_y, mut max_e) = ([0.0f64; 8], 0.0f64, 0.0f64);
    let (mut hold, mut y, mut spikes, mut dropouts, mut saturated) = (0usize, 0.0f64, 0usize, 0usize, 0usize);
    for k in 0..steps {
        let t = k as f64 * TS;
        let f = 1.0 + 40.0 * ((k / 200_000) % 7) as f64; // 1..241 Hz in blocks of 20 s
        let w = 2.0 * PI * f;
        let r =
            Reference { x: 8e-6 * (1.0 - (w * t).cos()), v: 8e-6 * w * (w * t).sin(), a: 8e-6 * w * w * (w * t).cos() };
        if hold > 0 {
            hold -= 1;
        } else {
            let u = rng.uniform();
            if u < 1e-3 {
                y = if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
                spikes += 1;
            } else if u < 2e-3 {
                hold = 1 + (rng.uniform() * 500.0) as usize;
                dropouts += 1;
            } else {
                y = r.x + 2e-6 * rng.normal();
            }
        }
        max_y = max_y.max(y.abs());
        let out = smc.step(&mut s, &r, y);
        if out.u == U_MIN || out.u == U_MAX {
            saturated += 1;
        }
        assert!(out.u.is_finite() && (U_MIN..=U_MAX).contains(&out.u), "step {k}: u = {}", out.u);
        max_e = max_e.max((r.x - out.terms[5]).abs());
        for (m, x) in max_slot.iter_mut().zip(&s) {
            assert!(x.is_finite(), "step {k}: state {s:?}");
            *m = m.max(x.abs());
        }
        assert!(
            s[4].abs() <= vh_bound * (1.0 + 1e-12),
            "step {k}: Vh_hat = {} beyond alpha/(beta+gamma) = {vh_bound}",
            s[4]
        );
    }
    // observer: BIBO bounds from the l1 gains (reported position adds delay Ts v)
    let delay_ts = smc.config().observer.delay * TS;
    assert!(max_slot[0] <= gx * max_y * (1.0 + 1e-9), "x_hat {} > {gx} * {max_y}", max_slot[0]);
    assert!(max_slot[1] <= gv * max_y * (1.0 + 1e-9), "v_hat {} > {gv} * {max_y}", max_slot[1]);
    // xi' = -alpha xi + e, held or decaying: |xi| <= max|e| / alpha
    assert!(max_slot[2] <= max_e / alpha * (1.0 + 1e-9), "xi {} > {max_e} / {alpha}", max_slot[2]);
    assert_eq!(max_slot[3], 0.0); // nu is unused with a boundary layer
    assert!(max_slot[5] <= U_MAX && max_slot[6] <= U_MAX);
    assert!(max_slot[7] <= (gx + delay_ts * gv) * max_y * (1.0 + 1e-9));
    eprintln!(
        "soak {steps}: {spikes} spikes, {dropouts} dropouts, {saturated} saturated; max |slot| = {:?}; \
         bounds x {:.3e}, v {:.3e}, xi {:.3e}, Vh {vh_bound:.4}",
        max_slot.map(|x| format!("{x:.3e}")),
        gx * max_y,
        gv * max_y,
        max_e / alpha
    );
    max_slot
}

#[test]
fn soak_smc_cemf_1m() {
    let t0 = std::time::Instant::now();
    let m = soak(1_000_000, 7);
    eprintln!("soak 1e6 steps: {:.2} s", t0.elapsed().as_secs_f64());
    assert!(m[4] > 1.0, "the CEMF observer was exercised: max |Vh_hat| = {}", m[4]);
}

#[test]
fn soak_smc_cemf_10m() {
    let t0 = std::time::Instant::now();
    let m = soak(10_000_000, 11);
    eprintln!("soak 1e7 steps: {:.2} s", t0.elapsed().as_secs_f64());
    assert!(m[4] > 1.0);
}
