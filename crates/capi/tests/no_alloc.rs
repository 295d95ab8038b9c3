//! Zero allocations: every model (init, reset, step, inverse step) and every controller
//! kind (init, reset, step; behind an inverse model, with ILC) runs under a counting global
//! allocator, and the count on this thread stays 0 — including on error paths, whose
//! messages are formatted into a fixed per-thread buffer.
// Every unsafe block here calls the C ABI with pointers to the test's own live buffers (or
// deliberately NULL ones): the safety argument is the same for each and lives in this comment.
#![allow(clippy::undocumented_unsafe_blocks)]
mod common;

use common::*;
use piezohyst::PhsStatus::*;
use piezohyst::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ptr;

struct Counting;

thread_local! {
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

fn bump() {
    let _ = COUNT.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        bump();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        bump();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        bump();
        unsafe { System.realloc(p, layout, new_size) }
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        unsafe { System.dealloc(p, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations on this thread while `f` runs.
fn allocations(f: impl FnOnce()) -> usize {
    let before = COUNT.with(|c| c.get());
    f();
    COUNT.with(|c| c.get()) - before
}

const STEPS: usize = 20_000;

#[test]
fn the_counter_counts() {
    assert!(allocations(|| drop(std::hint::black_box(vec![1u8; 10]))) >= 1);
}

#[test]
fn models_never_allocate() {
    for case in models() {
        let s = spec(case.family, &case.dims, &case.row);
        let mut scratch = vec![0.0; scratch_len(&s)];
        let mut m = empty_model();
        let mut n_state = 0;
        unsafe { phs_model_sizes(&s, ptr::null_mut(), &mut n_state, ptr::null_mut()) };
        let mut state = vec![0.0; n_state];
        let amp = if case.name == "mpi9" { 70.0 } else { 0.9 };
        let offset = if case.name == "mpi9" { 75.0 } else { 0.0 };
        let v: Vec<f64> =
            (0..STEPS).map(|k| offset + amp * (k as f64 * 0.003).sin() * (k as f64 * 0.0007).cos()).collect();
        let mut y = vec![0.0; STEPS];
        let mut v_back = vec![0.0; STEPS];
        let init = allocations(|| {
            assert_eq!(init_model(&mut m, &s, &mut scratch), PHS_OK, "{}", case.name);
            assert_eq!(unsafe { phs_model_reset(&m, state.as_mut_ptr(), n_state) }, PHS_OK);
        });
        let step = allocations(|| {
            for k in 0..STEPS {
                assert_eq!(
                    unsafe { phs_model_step(&m, state.as_mut_ptr(), n_state, v[k], &mut y[k]) },
                    PHS_OK,
                    "{}",
                    case.name
                );
            }
        });
        let mut unreachable = 0;
        let inverse = allocations(|| {
            unsafe { phs_model_reset(&m, state.as_mut_ptr(), n_state) };
            let mut guess = 0.0;
            for k in 0..STEPS {
                match unsafe { phs_model_inverse_step(&m, state.as_mut_ptr(), n_state, y[k], guess, &mut v_back[k]) } {
                    PHS_OK => guess = v_back[k],
                    PHS_ERR_UNREACHABLE => unreachable += 1,
                    e => panic!("{}: inverse step {k}: {e:?}", case.name),
                }
            }
        });
        let mut bad = case.row.clone();
        bad[0] = f64::NAN;
        let errors = allocations(|| {
            let mut out = 0.0;
            assert_eq!(
                unsafe { phs_model_step(&m, state.as_mut_ptr(), n_state, f64::NAN, &mut out) },
                PHS_ERR_NOT_FINITE
            );
            assert_eq!(
                unsafe { phs_model_step(&m, state.as_mut_ptr(), n_state + 1, 0.0, &mut out) },
                PHS_ERR_BAD_LENGTH
            );
            assert_eq!(
                unsafe { phs_model_step(&m, state.as_mut_ptr(), n_state, 0.0, ptr::null_mut()) },
                PHS_ERR_NULL_POINTER
            );
            assert_eq!(
                unsafe { phs_model_step(&empty_model(), state.as_mut_ptr(), n_state, 0.0, &mut out) },
                PHS_ERR_NOT_INITIALIZED
            );
            let bs = spec(case.family, &case.dims, &bad);
            let mut m2 = empty_model();
            assert_eq!(init_model(&mut m2, &bs, &mut scratch), PHS_ERR_NOT_FINITE, "{}", case.name);
            assert!(!unsafe { std::ffi::CStr::from_ptr(phs_last_error_message()) }.is_empty());
        });
        eprintln!(
            "{:<10} allocations: init+reset {init}, {STEPS} steps {step}, {STEPS} inverse steps {inverse} ({unreachable} unreachable), error paths {errors}",
            case.name
        );
        assert_eq!((init, step, inverse, errors), (0, 0, 0, 0), "{}", case.name);
        // the inverse is exact where it is reachable
        if case.invertible && unreachable == 0 && case.name != "boucwen" && case.name != "duhem" && case.name != "dahl"
        {
            unsafe { phs_model_reset(&m, state.as_mut_ptr(), n_state) };
            for k in 0..STEPS {
                let mut yk = 0.0;
                unsafe { phs_model_step(&m, state.as_mut_ptr(), n_state, v_back[k], &mut yk) };
                assert!((yk - y[k]).abs() <= 1e-9 * (1.0 + y[k].abs()), "{}: sample {k}: {yk} vs {}", case.name, y[k]);
            }
        }
    }
}

#[test]
fn controllers_never_allocate() {
    let mpi = mpi9_row();
    let ms = spec(2, &[9, 0, 0, 0], &mpi);
    let mut mpi_scratch = vec![0.0; scratch_len(&ms)];
    let mut model = empty_model();
    assert_eq!(init_model(&mut model, &ms, &mut mpi_scratch), PHS_OK);
    let inputs: Vec<(f64, f64, f64, f64)> = (0..STEPS * 5).map(scan).collect();
    for case in controllers() {
        let inverse = PhsInverse { model: &model, u_min: -20.0, u_max: 150.0 };
        let inv_ptr = if case.inverse { &inverse as *const PhsInverse } else { ptr::null() };
        let ilc_ptr = case.ilc.as_ref().map_or(ptr::null(), |s| s as *const PhsIlcSpec);
        let mut c = empty_controller();
        // the state buffer is the caller's: ask its size first (before counting)
        assert_eq!(
            unsafe {
                phs_controller_init(&mut c, case.kind, case.params.as_ptr(), case.params.len(), inv_ptr, ilc_ptr)
            },
            PHS_OK,
            "{}",
            case.name
        );
        let mut state = vec![0.0; c.state_len];
        let n = state.len();
        let mut c = empty_controller();
        let init = allocations(|| {
            assert_eq!(
                unsafe {
                    phs_controller_init(&mut c, case.kind, case.params.as_ptr(), case.params.len(), inv_ptr, ilc_ptr)
                },
                PHS_OK,
                "{}",
                case.name
            );
            let mut len = 0;
            assert_eq!(unsafe { phs_controller_state_len(&c, &mut len) }, PHS_OK);
            assert_eq!(len, n);
            assert_eq!(unsafe { phs_controller_reset(&c, state.as_mut_ptr(), n, inputs[0].3) }, PHS_OK);
        });
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let step = allocations(|| {
            for &(x, v, a, y) in &inputs {
                let mut u = 0.0;
                assert_eq!(
                    unsafe { phs_controller_step(&c, state.as_mut_ptr(), n, x, v, a, y, &mut u) },
                    PHS_OK,
                    "{}",
                    case.name
                );
                lo = lo.min(u);
                hi = hi.max(u);
            }
        });
        let mut bad = case.params.clone();
        bad[0] = f64::INFINITY;
        let errors = allocations(|| {
            let mut u = 0.0;
            assert_eq!(
                unsafe { phs_controller_step(&c, state.as_mut_ptr(), n, 0.0, 0.0, 0.0, f64::NAN, &mut u) },
                PHS_ERR_NOT_FINITE
            );
            assert_eq!(
                unsafe { phs_controller_step(&c, state.as_mut_ptr(), n + 1, 0.0, 0.0, 0.0, 0.0, &mut u) },
                PHS_ERR_BAD_LENGTH
            );
            let mut c2 = empty_controller();
            assert_eq!(
                unsafe { phs_controller_init(&mut c2, case.kind, bad.as_ptr(), bad.len(), inv_ptr, ilc_ptr,) },
                PHS_ERR_NOT_FINITE
            );
        });
        eprintln!(
            "{:<26} state {n:>4} slots; allocations: init+reset {init}, {} steps {step}, error paths {errors}; u in [{lo:.4}, {hi:.4}]",
            case.name,
            inputs.len()
        );
        assert_eq!((init, step, errors), (0, 0, 0), "{}", case.name);
        assert!(lo >= -20.0 && hi <= 150.0);
    }
}

#[test]
fn the_mimo_model_never_allocates() {
    // 2 states, 2 inputs, 2 outputs, 2 feedback channels of 2 plays (row: A B C D E F G H r w)
    let mut row = vec![0.6, 0.1, 0.0, 0.5]; // A
    row.extend([1.0, 0.0, 0.0, 1.0]); // B
    row.extend([1e-6, 0.0, 0.0, 1e-6]); // C
    row.extend([0.0; 4]); // D
    row.extend([0.1, 0.0, 0.0, 0.1]); // E
    row.extend([1e-8; 4]); // F
    row.extend([0.2, 0.0, 0.0, 0.2]); // G
    row.extend([1.0, 0.0, 0.0, 1.0]); // H
    row.extend([0.0, 0.1, 0.0, 0.1]); // thresholds
    row.extend([0.5, 0.2, 0.5, 0.2]); // weights
    let spec = PhsMimoSpec { nx: 2, nu: 2, ny: 2, nw: 2, nr: 2, nt: 0, params: row.as_ptr(), n_params: row.len() };
    let mut m =
        PhsMimo { magic: 0, dims: [0; 6], flags: 0, params: ptr::null(), n_params: 0, state_len: 0, work_len: 0 };
    let (mut st, mut work, mut y) = ([0.0; 6], [0.0; 6], [0.0; 2]);
    let init = allocations(|| {
        assert_eq!(unsafe { phs_mimo_init(&mut m, &spec) }, PHS_OK);
        assert_eq!(unsafe { phs_mimo_reset(&m, st.as_mut_ptr(), 6) }, PHS_OK);
    });
    let step = allocations(|| {
        for k in 0..STEPS {
            let u = [(k as f64 * 0.01).sin(), (k as f64 * 0.013).cos()];
            let code = unsafe {
                phs_mimo_step(&m, st.as_mut_ptr(), 6, work.as_mut_ptr(), 6, u.as_ptr(), 2, y.as_mut_ptr(), 2)
            };
            assert_eq!(code, PHS_OK);
        }
    });
    let errors = allocations(|| {
        let u = [f64::NAN, 0.0];
        let code =
            unsafe { phs_mimo_step(&m, st.as_mut_ptr(), 6, work.as_mut_ptr(), 6, u.as_ptr(), 2, y.as_mut_ptr(), 2) };
        assert_eq!(code, PHS_ERR_NOT_FINITE);
        let bad = PhsMimoSpec { n_params: row.len() - 1, ..spec };
        assert_eq!(unsafe { phs_mimo_init(&mut m, &bad) }, PHS_ERR_BAD_LENGTH);
    });
    assert_eq!((init, step, errors), (0, 0, 0));
}
