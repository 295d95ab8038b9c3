//! Hostile input through the C ABI (issue 20): tampered and non-finite states, references
//! beyond a controller's declared range, and a panic — each a status with a message naming
//! the slot or value, the state untouched, and nothing printed on stderr.
// Every unsafe block here calls the C ABI with pointers to the test's own live buffers of
// the sizes the library reported: the safety argument is the same for each and lives here.
#![allow(clippy::undocumented_unsafe_blocks)]
mod common;

use common::*;
use piezohyst::*;
use std::ffi::CStr;
use std::process::Command;

fn message() -> String {
    // SAFETY: never NULL, NUL-terminated, valid until the next failing call on this thread
    unsafe { CStr::from_ptr(phs_last_error_message()) }.to_string_lossy().into_owned()
}

fn model(case: &ModelCase, scratch: &mut Vec<f64>) -> PhsModel {
    let s = spec(case.family, &case.dims, &case.row);
    scratch.resize(scratch_len(&s), 0.0);
    let mut m = empty_model();
    assert_eq!(init_model(&mut m, &s, scratch), PhsStatus::PHS_OK, "{}", case.name);
    m
}

fn case(name: &str) -> ModelCase {
    models().into_iter().find(|c| c.name == name).unwrap()
}

#[test]
fn tampered_preisach_memory_length_is_a_status_naming_the_slot() {
    let c = case("preisach");
    let mut scratch = vec![];
    let m = model(&c, &mut scratch);
    let mut st = vec![0.0; m.state_len];
    let mut y = 0.0;
    let mut v = 0.0;
    // SAFETY: buffers of the right sizes
    unsafe {
        assert_eq!(phs_model_reset(&m, st.as_mut_ptr(), st.len()), PhsStatus::PHS_OK);
        for k in 0..50 {
            let x = 1.2 * (0.3 * k as f64).sin();
            assert_eq!(phs_model_step(&m, st.as_mut_ptr(), st.len(), x, &mut y), PhsStatus::PHS_OK);
        }
        for bad in [1e9, 17.0, -1.0, 2.5, f64::MAX] {
            let mut t = st.clone();
            t[1] = bad;
            let before = t.clone();
            let got = phs_model_step(&m, t.as_mut_ptr(), t.len(), 0.3, &mut y);
            assert_eq!(got, PhsStatus::PHS_ERR_INVALID_PARAMETER, "memory length {bad}: {}", message());
            assert!(message().contains("state (memory length)[1]"), "{}", message());
            let got = phs_model_inverse_step(&m, t.as_mut_ptr(), t.len(), 0.1, 0.0, &mut v);
            assert_eq!(got, PhsStatus::PHS_ERR_INVALID_PARAMETER, "{}", message());
            assert_eq!(t, before, "the state is untouched");
        }
    }
}

#[test]
fn non_finite_model_state_is_refused_for_every_family() {
    for c in models() {
        let mut scratch = vec![];
        let m = model(&c, &mut scratch);
        let mut st = vec![0.0; m.state_len];
        let mut y = 0.0;
        // SAFETY: buffers of the right sizes
        unsafe {
            assert_eq!(phs_model_reset(&m, st.as_mut_ptr(), st.len()), PhsStatus::PHS_OK);
            for k in 0..20 {
                let x = 0.5 * (0.3 * k as f64).sin();
                assert_eq!(phs_model_step(&m, st.as_mut_ptr(), st.len(), x, &mut y), PhsStatus::PHS_OK, "{}", c.name);
            }
            for i in 0..st.len() {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut t = st.clone();
                    t[i] = bad;
                    let got = phs_model_step(&m, t.as_mut_ptr(), t.len(), 0.2, &mut y);
                    assert_eq!(got, PhsStatus::PHS_ERR_NOT_FINITE, "{} state[{i}] = {bad}: {}", c.name, message());
                    assert!(message().contains(&format!("state[{i}] = ")), "{}", message());
                }
            }
        }
    }
}

fn controller(cc: &ControllerCase, inv_model: &PhsModel) -> PhsController {
    let mut c = empty_controller();
    let inv = PhsInverse { model: inv_model, u_min: -20.0, u_max: 150.0 };
    let inv_ptr = if cc.inverse { &inv as *const PhsInverse } else { std::ptr::null() };
    let ilc_ptr = cc.ilc.as_ref().map_or(std::ptr::null(), |s| s as *const PhsIlcSpec);
    // SAFETY: valid pointers or NULL
    let got = unsafe { phs_controller_init(&mut c, cc.kind, cc.params.as_ptr(), cc.params.len(), inv_ptr, ilc_ptr) };
    assert_eq!(got, PhsStatus::PHS_OK, "{}: {}", cc.name, message());
    c
}

#[test]
fn non_finite_controller_states_are_refused_not_driven_to_a_rail() {
    let mpi = case("mpi9");
    let mut scratch = vec![];
    let m = model(&mpi, &mut scratch);
    for cc in controllers() {
        let c = controller(&cc, &m);
        let mut st = vec![0.0; c.state_len];
        let mut u = 0.0;
        // SAFETY: buffers of the right sizes
        unsafe {
            assert_eq!(phs_controller_reset(&c, st.as_mut_ptr(), st.len(), 1e-6), PhsStatus::PHS_OK);
            for k in 0..30 {
                let (x, v, a, y) = scan(k);
                let got = phs_controller_step(&c, st.as_mut_ptr(), st.len(), x, v, a, y, &mut u);
                assert_eq!(got, PhsStatus::PHS_OK, "{}: {}", cc.name, message());
            }
            let (x, v, a, y) = scan(30);
            // every slot of a state without ILC (an ILC state's learned slots are checked
            // where the step reads them: slot 0 and the counter's neighbourhood)
            let slots: Vec<usize> = if cc.ilc.is_some() { vec![0] } else { (0..st.len()).collect() };
            for i in slots {
                for bad in [f64::NAN, f64::NEG_INFINITY, f64::INFINITY] {
                    let mut t = st.clone();
                    t[i] = bad;
                    let got = phs_controller_step(&c, t.as_mut_ptr(), t.len(), x, v, a, y, &mut u);
                    assert_eq!(got, PhsStatus::PHS_ERR_NOT_FINITE, "{} state[{i}] = {bad}: {}", cc.name, message());
                    assert!(message().contains(&format!("state[{i}] = ")), "{}", message());
                }
            }
        }
    }
}

#[test]
fn a_reference_far_beyond_the_declared_range_behind_an_inverse_is_refused() {
    let mpi = case("mpi9");
    let mut scratch = vec![];
    let m = model(&mpi, &mut scratch);
    // PID in the linearized domain: output limits -2 .. 22 µm (span 24 µm)
    let pid = ControllerCase {
        name: "pid+mpi",
        kind: 2,
        params: vec![0.5, 2e3, 0.0, 1e-4, TS, 1.0, 0.0, -2e-6, 22e-6],
        inverse: true,
        ilc: None,
    };
    for cc in [pid] {
        let c = controller(&cc, &m);
        let mut st = vec![0.0; c.state_len];
        let mut u = 0.0;
        // SAFETY: buffers of the right sizes
        unsafe {
            assert_eq!(phs_controller_reset(&c, st.as_mut_ptr(), st.len(), 0.0), PhsStatus::PHS_OK);
            for x_ref in [1e300, -1e300, 1.0, 46.01e-6, -26.01e-6] {
                let before = st.clone();
                let got = phs_controller_step(&c, st.as_mut_ptr(), st.len(), x_ref, 0.0, 0.0, 0.0, &mut u);
                assert_eq!(got, PhsStatus::PHS_ERR_UNREACHABLE, "x_ref = {x_ref}: {}", message());
                assert!(message().contains("x_ref = "), "{}", message());
                assert_eq!(st, before, "the state is untouched");
            }
            // inside [u_min - w, u_max + w]: accepted, beyond reach saturates
            for x_ref in [45.9e-6, -25.9e-6, 10e-6] {
                let got = phs_controller_step(&c, st.as_mut_ptr(), st.len(), x_ref, 0.0, 0.0, 0.0, &mut u);
                assert_eq!(got, PhsStatus::PHS_OK, "x_ref = {x_ref}: {}", message());
                assert!((-20.0..=150.0).contains(&u));
            }
        }
    }
}

/// Run `test` of this binary in a child process (uncaptured) and return its stderr.
fn child_stderr(test: &str) -> (bool, String) {
    let out = Command::new(std::env::current_exe().unwrap())
        .args([test, "--exact", "--nocapture", "--test-threads=1"])
        .env("PIEZOHYST_HOSTILE_CHILD", "1")
        .output()
        .unwrap();
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn child_panics_through_the_guard() {
    if std::env::var_os("PIEZOHYST_HOSTILE_CHILD").is_none() {
        return;
    }
    assert_eq!(__panic_through_guard(), PhsStatus::PHS_ERR_INTERNAL);
    let msg = message();
    assert!(msg.contains("internal error"), "{msg}");
    assert!(msg.contains("a deliberate panic of the test"), "{msg}");
    assert_eq!(phs_last_error(), PhsStatus::PHS_ERR_INTERNAL);
    // the library still works afterwards
    tampered_preisach_memory_length_is_a_status_naming_the_slot();
}

#[test]
fn a_panic_is_a_status_with_its_message_and_prints_nothing() {
    let (ok, err) = child_stderr("child_panics_through_the_guard");
    assert!(ok, "child failed: {err}");
    assert!(err.is_empty(), "stderr of the child is not empty:\n{err}");
}

#[test]
fn child_runs_every_hostile_case() {
    if std::env::var_os("PIEZOHYST_HOSTILE_CHILD").is_none() {
        return;
    }
    tampered_preisach_memory_length_is_a_status_naming_the_slot();
    non_finite_model_state_is_refused_for_every_family();
    non_finite_controller_states_are_refused_not_driven_to_a_rail();
    a_reference_far_beyond_the_declared_range_behind_an_inverse_is_refused();
}

#[test]
fn hostile_cases_print_nothing_on_stderr() {
    let (ok, err) = child_stderr("child_runs_every_hostile_case");
    assert!(ok, "child failed: {err}");
    assert!(err.is_empty(), "stderr of the child is not empty:\n{err}");
}
