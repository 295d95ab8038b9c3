//! Valid models and controllers for the C ABI tests, and safe wrappers around the calls.
#![allow(dead_code)]
use piezohyst::*;
use std::ptr;

/// One model: name, family code, dims, parameter row.
pub struct ModelCase {
    pub name: &'static str,
    pub family: u32,
    pub dims: Vec<usize>,
    pub row: Vec<f64>,
    /// Whether the per-sample inverse applies (the model is increasing in its input).
    pub invertible: bool,
}

const R: [f64; 3] = [0.1, 0.4, 0.8];
const W: [f64; 3] = [0.5, -0.2, 0.3];

fn cat(parts: &[&[f64]]) -> Vec<f64> {
    parts.iter().flat_map(|p| p.iter().copied()).collect()
}

/// The seed-2 MPI structure of the benchmarks: 9 generalized plays, a cubic polynomial,
/// identity envelopes (input V, output m).
pub fn mpi9_row() -> Vec<f64> {
    let mut row = vec![0.0; 14 + 18];
    row[0] = -100.0;
    row[1] = 250.0;
    row[3] = 0.13e-6;
    for i in 0..9 {
        row[14 + i] = 15.0 * i as f64;
        row[14 + 9 + i] = 0.01e-6 / (1.0 + i as f64);
    }
    row
}

pub fn models() -> Vec<ModelCase> {
    let creep: &[f64] = &[1e-3, 0.01, 0.5, 0.05, 0.02];
    let pre_w: Vec<f64> = (0..10).map(|i| 0.05 * (i + 1) as f64).collect();
    vec![
        ModelCase { name: "pi", family: 1, dims: vec![3, 0], row: cat(&[&[0.9], &R, &W]), invertible: true },
        ModelCase {
            name: "pi+creep",
            family: 1,
            dims: vec![3, 2],
            row: cat(&[&[0.9], &R, &W, creep]),
            invertible: true,
        },
        ModelCase {
            name: "gpi",
            family: 2,
            dims: vec![3, 1, 2, 0],
            row: cat(&[
                &[-1.0, 1.0],
                &[0.0, 0.25, -0.004, 0.7],
                &[-0.02, 0.9, 0.05, 0.3],
                &[1.5, 1.0, 0.0, 0.05],
                &R,
                &W,
            ]),
            invertible: true,
        },
        ModelCase { name: "mpi9", family: 2, dims: vec![9, 0, 0, 0], row: mpi9_row(), invertible: true },
        ModelCase {
            name: "rdpi",
            family: 3,
            dims: vec![3, 0],
            row: cat(&[&[1e-3, 0.8, 1e-4, 2e-3], &R, &W, &[1e-6, 0.0, 2e-6]]),
            invertible: true,
        },
        ModelCase { name: "creep", family: 4, dims: vec![2], row: creep.to_vec(), invertible: true },
        ModelCase {
            name: "preisach",
            family: 5,
            dims: vec![4, 16],
            row: cat(&[&[-1.5, 1.5, 0.2, 0.3], &pre_w]),
            invertible: true,
        },
        ModelCase { name: "boucwen", family: 6, dims: vec![], row: vec![0.3, 0.03, 0.01, 1.0, 0.1], invertible: true },
        ModelCase {
            name: "duhem",
            family: 7,
            dims: vec![],
            row: vec![2.0, 0.1, 1.2, -0.1, 0.05, 0.5, 0.1, 0.2, -0.05],
            invertible: true,
        },
        ModelCase { name: "dahl", family: 8, dims: vec![], row: vec![1.5, 0.8, 0.5], invertible: true },
    ]
}

pub fn spec(family: u32, dims: &[usize], row: &[f64]) -> PhsModelSpec {
    let mut d = [0usize; PHS_MAX_DIMS];
    d[..dims.len()].copy_from_slice(dims);
    PhsModelSpec { family, n_dims: dims.len() as u32, dims: d, params: row.as_ptr(), n_params: row.len() }
}

pub fn empty_model() -> PhsModel {
    PhsModel { magic: 0, family: 0, flags: 0, n_params: 0, state_len: 0, scratch_len: 0, built: [0; PHS_MODEL_WORDS] }
}

pub fn empty_controller() -> PhsController {
    PhsController { magic: 0, kind: 0, flags: 0, state_len: 0, built: [0; PHS_CONTROLLER_WORDS] }
}

/// The scratch size of a spec.
pub fn scratch_len(s: &PhsModelSpec) -> usize {
    let mut n = 0;
    assert_eq!(unsafe { phs_model_sizes(s, ptr::null_mut(), ptr::null_mut(), &mut n) }, PhsStatus::PHS_OK);
    n
}

/// Initialize a model into `model` with `scratch` (sized by the caller).
pub fn init_model(model: &mut PhsModel, s: &PhsModelSpec, scratch: &mut [f64]) -> PhsStatus {
    let p = if scratch.is_empty() { ptr::null_mut() } else { scratch.as_mut_ptr() };
    unsafe { phs_model_init(model, s, p, scratch.len()) }
}

/// One controller: name, kind, parameters, whether it sits behind the MPI inverse, ILC.
pub struct ControllerCase {
    pub name: &'static str,
    pub kind: u32,
    pub params: Vec<f64>,
    pub inverse: bool,
    pub ilc: Option<PhsIlcSpec>,
}

pub const TS: f64 = 1e-4;

pub fn cemf_row() -> [f64; 8] {
    [0.0068, 13.0, 6.98e6, 10.5, 1.8e-6, 1.25e5, 8000.0, 3000.0]
}

pub fn smc_params(cemf: bool, super_twisting: bool) -> Vec<f64> {
    let c = cemf_row();
    let sw: [f64; 3] = if super_twisting { [1.0, 500.0, 2e5] } else { [0.0, 20.0, 0.01] };
    cat(&[
        &c[..3],
        &[1e6, 2e3, 0.0],
        &sw,
        &[1000.0, TS, 1.0],
        &[if cemf { 1.0 } else { 0.0 }],
        &c[3..],
        &[0.0, -20.0, 150.0],
    ])
}

pub fn absmc_linearized_params() -> Vec<f64> {
    let w2 = (2.0 * std::f64::consts::PI * 2000.0f64).powi(2);
    let w = w2.sqrt();
    vec![
        w2,
        w2,
        1.4 * w,
        w2 / 3.0,
        0.0,
        3.0 * w2,
        3.0 * w,
        2e3,
        2e3,
        5e3,
        1e-3,
        1e6,
        1e3,
        1e4,
        0.0,
        1e5,
        1.0,
        1000.0,
        TS,
        1.0,
        -2e-6,
        22e-6,
    ]
}

pub fn controllers() -> Vec<ControllerCase> {
    let ilc = PhsIlcSpec { period: 100, gain: 0.3, forgetting: 0.99, lead: 3, delay: 1 };
    vec![
        ControllerCase {
            name: "open_loop",
            kind: 1,
            params: vec![7e6, 0.0, 1e-4, 1e-8, -20.0, 150.0],
            inverse: false,
            ilc: None,
        },
        ControllerCase {
            name: "pid",
            kind: 2,
            params: vec![2e6, 2e9, 10.0, 1e-4, TS, 7e6, 0.0, -20.0, 150.0],
            inverse: false,
            ilc: None,
        },
        ControllerCase { name: "smc", kind: 3, params: smc_params(false, false), inverse: false, ilc: None },
        ControllerCase { name: "smc+cemf", kind: 3, params: smc_params(true, false), inverse: false, ilc: None },
        ControllerCase {
            name: "smc super-twisting",
            kind: 3,
            params: smc_params(false, true),
            inverse: false,
            ilc: None,
        },
        ControllerCase { name: "absmc+mpi", kind: 4, params: absmc_linearized_params(), inverse: true, ilc: None },
        ControllerCase {
            name: "cemf_feedforward",
            kind: 5,
            params: cat(&[&cemf_row(), &[-20.0, 150.0]]),
            inverse: false,
            ilc: None,
        },
        ControllerCase {
            name: "inverse feedforward (mpi)",
            kind: 1,
            params: vec![1.0, 0.0, 0.0, 0.0, -2e-6, 22e-6],
            inverse: true,
            ilc: None,
        },
        ControllerCase {
            name: "pid+ilc",
            kind: 2,
            params: vec![2e6, 2e9, 10.0, 1e-4, TS, 7e6, 0.0, -20.0, 150.0],
            inverse: false,
            ilc: Some(ilc),
        },
        ControllerCase {
            name: "absmc+mpi+ilc",
            kind: 4,
            params: absmc_linearized_params(),
            inverse: true,
            ilc: Some(ilc),
        },
    ]
}

/// An 80 Hz scan and a quantized reading of it with a small tracking error.
pub fn scan(k: usize) -> (f64, f64, f64, f64) {
    let w = 2.0 * std::f64::consts::PI * 80.0;
    let t = k as f64 * TS;
    let (x, v, a) = (9e-6 + 8e-6 * (w * t).sin(), 8e-6 * w * (w * t).cos(), -8e-6 * w * w * (w * t).sin());
    let y = ((x + 2e-8 * (k as f64 * 0.37).sin()) / 1e-7).round() * 1e-7;
    (x, v, a, y)
}
