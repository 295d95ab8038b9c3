//! The MIMO model through the C ABI (issue 15): bit-identical to the core's simulation over a
//! long record, every bad argument a documented code with a message naming it, no allocation.
// Every unsafe block here calls the C ABI with pointers to the test's own live buffers (or
// deliberately NULL / wrong ones): the safety argument is the same for each and lives here.
#![allow(clippy::undocumented_unsafe_blocks)]

use piezohyst::PhsStatus::*;
use piezohyst::*;
use piezohyst_core::lfr::Lfr;
use std::ffi::CStr;
use std::ptr;

/// A deterministic pseudo-random sequence in [-1, 1) (xorshift64*).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let r = self.0.wrapping_mul(0x2545_F491_4F6C_DD1D);
        (r >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// An FSM-sized LFR: 3 inputs, 3 outputs, 12 states (two modes per output and a fast pole),
/// 3 feedback channels of 8 operators each, the last a static saturation; `A` stable
/// (spectral radius < 0.98).
fn fsm_like(seed: u64) -> ([usize; 6], Vec<f64>) {
    let (nx, nu, ny, nw, nr, nt) = (12, 3, 3, 3, 8, 1);
    let mut rng = Rng(seed);
    let mut a = vec![0.0; nx * nx];
    for k in 0..nx / 2 {
        // rotation blocks, radius 0.9..0.97
        let (r, th) = (0.9 + 0.07 * (k as f64) / 6.0, 0.3 + 0.4 * k as f64);
        let i = 2 * k;
        a[i * nx + i] = r * th.cos();
        a[i * nx + i + 1] = -r * th.sin();
        a[(i + 1) * nx + i] = r * th.sin();
        a[(i + 1) * nx + i + 1] = r * th.cos();
    }
    let mut row = a;
    let mut fill = |n: usize, scale: f64, row: &mut Vec<f64>| {
        for _ in 0..n {
            row.push(scale * rng.next());
        }
    };
    fill(nx * nu, 1.0, &mut row); // B
    fill(ny * nx, 1e-6, &mut row); // C
    fill(ny * nu, 1e-7, &mut row); // D
    fill(nx * nw, 0.05, &mut row); // E
    fill(ny * nw, 1e-8, &mut row); // F
    fill(nw * nx, 0.1, &mut row); // G
    fill(nw * nu, 1.0, &mut row); // H
    for i in 0..nw * nr {
        // thresholds 0 .. 0.14 (plays), 0.05 .. 0.19 (the static channel's scales)
        row.push(0.02 * (i % nr) as f64 + if i / nr >= nw - nt { 0.05 } else { 0.0 });
    }
    fill(nw * nr, 0.3, &mut row); // weights
    ([nx, nu, ny, nw, nr, nt], row)
}

fn spec(d: [usize; 6], row: &[f64]) -> PhsMimoSpec {
    PhsMimoSpec {
        nx: d[0],
        nu: d[1],
        ny: d[2],
        nw: d[3],
        nr: d[4],
        nt: d[5],
        params: row.as_ptr(),
        n_params: row.len(),
    }
}

fn message() -> String {
    unsafe { CStr::from_ptr(phs_last_error_message()) }.to_string_lossy().into_owned()
}

fn empty() -> PhsMimo {
    PhsMimo { magic: 0, dims: [0; 6], flags: 0, params: ptr::null(), n_params: 0, state_len: 0, work_len: 0 }
}

#[test]
fn c_steps_are_bit_identical_to_the_core_simulation() {
    let (d, row) = fsm_like(7);
    let s = spec(d, &row);
    let (mut n_params, mut n_state, mut n_work) = (0, 0, 0);
    assert_eq!(unsafe { phs_mimo_sizes(&s, &mut n_params, &mut n_state, &mut n_work) }, PHS_OK);
    assert_eq!((n_params, n_state, n_work), (row.len(), 12 + 24, 12 + 6));
    let mut m = empty();
    assert_eq!(unsafe { phs_mimo_init(&mut m, &s) }, PHS_OK, "{}", message());
    assert_eq!(m.flags, PHS_MIMO_FLAG_MODAL); // rotation blocks: the core's modal step
    let n = 50_000;
    let mut rng = Rng(99);
    let u: Vec<f64> = (0..n * 3).map(|_| 0.3 * rng.next()).collect();
    // the core: one call over the record
    let (nx, nu, ny, nw, nr) = (d[0], d[1], d[2], d[3], d[4]);
    let mut k = 0;
    let mut take = |len: usize| {
        let part = &row[k..k + len];
        k += len;
        part
    };
    let lfr = Lfr {
        nx,
        nu,
        ny,
        nw,
        nr,
        a: take(nx * nx),
        b: take(nx * nu),
        c: take(ny * nx),
        d: take(ny * nu),
        e: take(nx * nw),
        f: take(ny * nw),
        g: take(nw * nx),
        h: take(nw * nu),
        thresholds: take(nw * nr),
        weights: take(nw * nr),
        nt: d[5],
        modal: false,
    }
    .validated()
    .unwrap();
    let mut st_core = vec![0.0; lfr.state_len()];
    let mut scratch = vec![0.0; lfr.scratch_len()];
    let (mut y_core, mut z_core) = (vec![0.0; n * ny], vec![0.0; n * nw]);
    assert!(lfr.simulate(&u, &mut st_core, &mut scratch, &mut y_core, &mut z_core, &|| false));
    // the C ABI: one step per sample
    let mut st = vec![1.0; n_state];
    assert_eq!(unsafe { phs_mimo_reset(&m, st.as_mut_ptr(), n_state) }, PHS_OK);
    assert!(st.iter().all(|&v| v == 0.0));
    let mut work = vec![0.0; n_work];
    let mut y = vec![0.0; n * ny];
    for t in 0..n {
        let code = unsafe {
            phs_mimo_step(
                &m,
                st.as_mut_ptr(),
                n_state,
                work.as_mut_ptr(),
                n_work,
                u[t * nu..].as_ptr(),
                nu,
                y[t * ny..].as_mut_ptr(),
                ny,
            )
        };
        assert_eq!(code, PHS_OK, "{}", message());
    }
    assert!(y.iter().zip(&y_core).all(|(a, b)| a.to_bits() == b.to_bits()), "not bit-identical");
    assert!(st.iter().zip(&st_core).all(|(a, b)| a.to_bits() == b.to_bits()));
    // the feedback moved: the plays are not idle (a Hammerstein/LFR path, not a linear model)
    assert!(st[nx..].iter().any(|&p| p.abs() > 1e-3));
    assert!(y.iter().map(|v| v.abs()).fold(0.0, f64::max) > 1e-7);
}

#[test]
fn bad_arguments_are_named() {
    let (d, mut row) = fsm_like(1);
    let mut m = empty();
    // lengths
    let mut s = spec(d, &row[..row.len() - 1]);
    assert_eq!(unsafe { phs_mimo_init(&mut m, &s) }, PHS_ERR_BAD_LENGTH);
    assert!(message().contains("spec->n_params"), "{}", message());
    assert_eq!(m.magic, 0);
    s = spec([4, 0, 3, 0, 0, 0], &row);
    assert_eq!(unsafe { phs_mimo_init(&mut m, &s) }, PHS_ERR_BAD_LENGTH);
    assert!(message().contains("nu"), "{}", message());
    s = spec([1 << 21, 1, 1, 0, 0, 0], &row);
    assert_eq!(unsafe { phs_mimo_sizes(&s, ptr::null_mut(), ptr::null_mut(), ptr::null_mut()) }, PHS_ERR_BAD_LENGTH);
    // a NaN in B, a negative threshold: the matrix named
    let b0 = 12 * 12 + 4;
    row[b0] = f64::NAN;
    assert_eq!(unsafe { phs_mimo_init(&mut m, &spec(d, &row)) }, PHS_ERR_NOT_FINITE);
    assert!(message().starts_with("phs_mimo_init: B"), "{}", message());
    row[b0] = 0.5;
    let th0 = row.len() - 2 * 24 + 3;
    row[th0] = -0.1;
    assert_eq!(unsafe { phs_mimo_init(&mut m, &spec(d, &row)) }, PHS_ERR_INVALID_PARAMETER);
    assert!(message().contains("thresholds") && message().contains("-0.1"), "{}", message());
    row[th0] = 0.1;
    // a static channel's scale must be > 0; at most nw static channels
    let last = row.len() - 24 - 1;
    let keep = row[last];
    row[last] = 0.0;
    assert_eq!(unsafe { phs_mimo_init(&mut m, &spec(d, &row)) }, PHS_ERR_INVALID_PARAMETER);
    assert!(message().contains("static-channel thresholds[23] = 0"), "{}", message());
    row[last] = keep;
    let mut too_many = d;
    too_many[5] = 4;
    assert_ne!(unsafe { phs_mimo_init(&mut m, &spec(too_many, &row)) }, PHS_OK);
    assert!(message().contains("nt (static channels, at most nw) = 4"), "{}", message());
    assert_eq!(unsafe { phs_mimo_init(&mut m, &spec(d, &row)) }, PHS_OK, "{}", message());
    // NULLs, uninitialized, wrong buffer lengths, NaN input, NaN state
    assert_eq!(unsafe { phs_mimo_init(ptr::null_mut(), &spec(d, &row)) }, PHS_ERR_NULL_POINTER);
    assert_eq!(unsafe { phs_mimo_init(&mut m, ptr::null()) }, PHS_ERR_NULL_POINTER);
    let mut st = vec![0.0; 36];
    let mut work = vec![0.0; 18];
    let (u, mut y) = ([0.1, 0.2, 0.3], [0.0; 3]);
    let step = |m: &PhsMimo, st: &mut [f64], work: &mut [f64], u: &[f64], y: &mut [f64]| unsafe {
        phs_mimo_step(
            m,
            st.as_mut_ptr(),
            st.len(),
            work.as_mut_ptr(),
            work.len(),
            u.as_ptr(),
            u.len(),
            y.as_mut_ptr(),
            y.len(),
        )
    };
    assert_eq!(step(&m, &mut st, &mut work, &u, &mut y), PHS_ERR_NOT_INITIALIZED);
    assert_eq!(unsafe { phs_mimo_init(&mut m, &spec(d, &row)) }, PHS_OK, "{}", message());
    assert_eq!(step(&m, &mut st[..35], &mut work, &u, &mut y), PHS_ERR_BAD_LENGTH);
    assert!(message().contains("n_state = 35, expected 36"), "{}", message());
    assert_eq!(step(&m, &mut st, &mut work[..17], &u, &mut y), PHS_ERR_BAD_LENGTH);
    assert_eq!(step(&m, &mut st, &mut work, &u[..2], &mut y), PHS_ERR_BAD_LENGTH);
    assert!(message().contains("n_u = 2, expected 3"), "{}", message());
    assert_eq!(step(&m, &mut st, &mut work, &[0.1, f64::INFINITY, 0.0], &mut y), PHS_ERR_NOT_FINITE);
    assert!(message().contains("u[1] = inf"), "{}", message());
    st[5] = f64::NAN;
    assert_eq!(step(&m, &mut st, &mut work, &u, &mut y), PHS_ERR_NOT_FINITE);
    assert!(message().contains("state[5]"), "{}", message());
    st[5] = 0.0;
    assert_eq!(step(&m, &mut st, &mut work, &u, &mut y), PHS_OK);
    let mut len = 0;
    assert_eq!(unsafe { phs_mimo_state_len(&m, &mut len, ptr::null_mut()) }, PHS_OK);
    assert_eq!(len, 36);
}

#[test]
fn a_linear_model_without_feedback_channels() {
    // nw = 0: x+ = 0.5 x + u, y = x (1 state, 1 input, 1 output)
    let row = [0.5, 1.0, 1.0, 0.0];
    let mut m = empty();
    assert_eq!(unsafe { phs_mimo_init(&mut m, &spec([1, 1, 1, 0, 0, 0], &row)) }, PHS_OK, "{}", message());
    let (mut st, mut work, mut y) = ([0.0], [0.0], [0.0]);
    let mut out = vec![];
    for u in [1.0, 0.0, 0.0] {
        let code = unsafe { phs_mimo_step(&m, st.as_mut_ptr(), 1, work.as_mut_ptr(), 1, &u, 1, y.as_mut_ptr(), 1) };
        assert_eq!(code, PHS_OK);
        out.push(y[0]);
    }
    assert_eq!(out, [0.0, 1.0, 0.5]);
}
