//! Time the closed loop on the virtual stage's values (a quick check during development;
//! the benchmark of record is bench/closed_loop.py):
//! `cargo run --release -p piezohyst-core --example closed_loop_speed`.
use piezohyst_core::closed_loop::{run, Loop, Record, Trajectory};
use piezohyst_core::control::{Limits, Pid, PidConfig};
use piezohyst_core::sensor::Sensor;
use piezohyst_core::stage::{Stage, StageParams, StageState};
use std::time::Instant;

fn main() {
    let p = StageParams::virtual_stage();
    let ts = 1e-4;
    let n = 100_000; // 10 s
    let r: Vec<f64> =
        (0..n).map(|k| 5e-6 * (1.0 - (2.0 * std::f64::consts::PI * 10.0 * k as f64 * ts).cos())).collect();
    let z = vec![0.0; n];
    for (substeps, tol) in [(1, f64::INFINITY), (1, 0.05), (1, 0.01), (2, f64::INFINITY)] {
        let stage = Stage::new(p, ts, substeps, tol).unwrap();
        let sensor = Sensor::new(1e-7, if std::env::var("NONOISE").is_ok() { 0.0 } else { 1e-8 }, 1).unwrap();
        let pid = Pid::new(PidConfig {
            kp: 1e6,
            ki: 5e9,
            kd: 0.0,
            tau_d: 1e-4,
            ts,
            ff_gain: 1.0 / (10.5 / 7.333e7),
            offset: 0.0,
            limits: Limits::new(-20.0, 150.0).unwrap(),
        })
        .unwrap();
        let (mut c, mut va, mut x, mut y) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut terms = vec![0.0; n * 5];
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let mut st = StageState::ZERO;
            let mut sst = sensor.state(0.0, 1);
            let mut cst = [0.0; 3];
            piezohyst_core::control::Controller::reset(&pid, &mut cst, 0.0);
            let t0 = Instant::now();
            let parts = Loop {
                stage: &stage,
                stage_state: &mut st,
                sensor: &sensor,
                sensor_state: &mut sst,
                controller: &pid,
                controller_state: &mut cst,
            };
            let trajectory = Trajectory { position: &r, velocity: &z, acceleration: &z };
            let rec =
                Record { command: &mut c, voltage: &mut va, position: &mut x, measured: &mut y, terms: &mut terms };
            run(parts, trajectory, rec);
            best = best.min(t0.elapsed().as_secs_f64());
        }
        let rmse = (r.iter().zip(&x).map(|(a, b)| (a - b) * (a - b)).sum::<f64>() / n as f64).sqrt();
        println!(
            "substeps {substeps} tolerance {tol}: {:.0} ns/step, real-time factor {:.0}x, rmse {:.3e}",
            best / n as f64 * 1e9,
            n as f64 * ts / best,
            rmse
        );
    }
}
