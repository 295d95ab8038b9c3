//! Fuzz target for the C ABI's state buffers (issue 20): a seeded mutational loop. Each
//! model family and controller kind of `common` runs to a realistic state, then the state
//! buffer is mutated — bits flipped, slots set to NaN, infinities, the largest and smallest
//! doubles, subnormals, negative zero, counters and memory lengths off by one, slots swapped
//! or copied — and stepped, inverted and reset.
//!
//! The property, for every call: a documented status, never `PHS_ERR_INTERNAL` (a caught
//! panic) and never a crash or hang; a state refused on entry is left bit-for-bit untouched
//! (only a divergence, `PHS_ERR_NOT_FINITE` "reset the state", may have changed it); a call
//! that succeeds gives a finite output (a controller's inside its limits) and makes no slot
//! of the state non-finite; a reset always succeeds. The run is deterministic (xorshift64*,
//! fixed seed) and bounded (`PIEZOHYST_FUZZ_STATE_ROUNDS` mutations per case, 5000 by
//! default: about 470,000 calls, under a second; 100,000 rounds, 9.3 million calls, ran
//! clean). Its findings are kept as the regression cases below.
// Every unsafe block here calls the C ABI with pointers to the test's own live buffers of
// the sizes the library reported: the safety argument is the same for each and lives here.
#![allow(clippy::undocumented_unsafe_blocks)]
mod common;

use common::*;
use piezohyst::PhsStatus::*;
use piezohyst::*;
use std::ffi::CStr;

/// xorshift64* (Vigna): a small deterministic generator, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn rounds() -> usize {
    std::env::var("PIEZOHYST_FUZZ_STATE_ROUNDS").ok().and_then(|s| s.parse().ok()).unwrap_or(5000)
}

fn message() -> String {
    unsafe { CStr::from_ptr(phs_last_error_message()) }.to_string_lossy().into_owned()
}

fn documented(code: PhsStatus) -> bool {
    (code as i32) >= 0 && (code as i32) < PHS_STATUS_COUNT && code != PHS_ERR_INTERNAL
}

/// A step that ran and diverged (its result not finite): the state must be reset, it may
/// have changed. Any other refusal happens before the step and leaves the state as it was.
fn diverged(code: PhsStatus) -> bool {
    code == PHS_ERR_NOT_FINITE && message().contains("reset the state")
}

/// A successful step creates no non-finite slot. (A slot the mutation made non-finite may
/// stay: an ILC's learned samples are checked when a step reads them, not on every step.)
fn no_new_non_finite(after: &[f64], before: &[f64]) -> bool {
    after.iter().zip(before).all(|(a, b)| a.is_finite() || !b.is_finite())
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// One to four edits of the state buffer.
fn mutate(st: &mut [f64], rng: &mut Rng) {
    if st.is_empty() {
        return;
    }
    let n = st.len();
    for _ in 0..1 + rng.below(4) {
        let i = rng.below(n);
        let x = st[i];
        st[i] = match rng.below(12) {
            0 => f64::from_bits(x.to_bits() ^ (1u64 << rng.below(64))), // one bit
            1 => f64::from_bits(rng.next()),                            // any bits
            2 => [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][rng.below(3)],
            3 => [f64::MAX, -f64::MAX, f64::MIN_POSITIVE, -f64::MIN_POSITIVE][rng.below(4)],
            4 => [5e-324, -5e-324, 1e-310, -0.0, 0.0][rng.below(5)], // subnormal, signed zeros
            5 => [1e300, -1e300, 1e30, -1e30, 1e-30][rng.below(5)],
            6 => (rng.below(2 * n + 4) as f64) - 2.0, // a counter or length: -2 .. 2n + 1
            7 => x.round() + [-1.0, 1.0, 0.5][rng.below(3)], // off by one, or half
            8 => x * [-1.0, 2.0, 1e6, 1e-6][rng.below(4)],
            9 => st[rng.below(n)], // another slot's value
            10 => (rng.unit() - 0.5) * 10f64.powi(rng.below(40) as i32 - 20),
            _ => {
                let j = rng.below(n);
                st.swap(i, j);
                st[i]
            }
        };
    }
}

fn build_model(case: &ModelCase, scratch: &mut Vec<f64>) -> PhsModel {
    let s = spec(case.family, &case.dims, &case.row);
    scratch.resize(scratch_len(&s), 0.0);
    let mut m = empty_model();
    assert_eq!(init_model(&mut m, &s, scratch), PHS_OK, "{}: {}", case.name, message());
    m
}

fn build_controller(cc: &ControllerCase, inv_model: &PhsModel) -> PhsController {
    let mut c = empty_controller();
    let inv = PhsInverse { model: inv_model, u_min: -20.0, u_max: 150.0 };
    let inv_ptr = if cc.inverse { &inv as *const PhsInverse } else { std::ptr::null() };
    let ilc_ptr = cc.ilc.as_ref().map_or(std::ptr::null(), |s| s as *const PhsIlcSpec);
    let got = unsafe { phs_controller_init(&mut c, cc.kind, cc.params.as_ptr(), cc.params.len(), inv_ptr, ilc_ptr) };
    assert_eq!(got, PHS_OK, "{}: {}", cc.name, message());
    c
}

/// Steps of a model from `st` (mutated): the property of the module. Returns the calls made.
fn check_model_calls(name: &str, m: &PhsModel, st: &mut Vec<f64>, rng: &mut Rng) -> usize {
    let mut calls = 0;
    for _ in 0..3 {
        let x = (rng.unit() - 0.5) * 3.0;
        let before = st.clone();
        let mut y = f64::NAN;
        let code = unsafe {
            if rng.below(3) == 0 {
                phs_model_inverse_step(m, st.as_mut_ptr(), st.len(), 0.5 * x, 0.0, &mut y)
            } else {
                phs_model_step(m, st.as_mut_ptr(), st.len(), x, &mut y)
            }
        };
        calls += 1;
        assert!(documented(code), "{name}: status {code:?} from state {before:?}: {}", message());
        if code != PHS_OK {
            assert!(
                same_bits(st, &before) || diverged(code),
                "{name}: refused ({code:?}: {}) but the state changed: {before:?}",
                message()
            );
            return calls;
        }
        assert!(y.is_finite(), "{name}: PHS_OK with output {y} from state {before:?}");
        assert!(no_new_non_finite(st, &before), "{name}: PHS_OK made the state non-finite {st:?} from {before:?}");
    }
    calls
}

#[test]
fn mutated_model_states_give_documented_statuses() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut calls = 0;
    for case in models() {
        let mut scratch = vec![];
        let m = build_model(&case, &mut scratch);
        let mut base = vec![0.0; m.state_len];
        let mut y = 0.0;
        unsafe {
            assert_eq!(phs_model_reset(&m, base.as_mut_ptr(), base.len()), PHS_OK);
            for k in 0..200 {
                let x = 1.2 * (0.05 * k as f64).sin() * (1.0 - k as f64 / 400.0);
                assert_eq!(phs_model_step(&m, base.as_mut_ptr(), base.len(), x, &mut y), PHS_OK, "{}", case.name);
            }
        }
        for _ in 0..rounds() {
            let mut st = base.clone();
            mutate(&mut st, &mut rng);
            calls += check_model_calls(case.name, &m, &mut st, &mut rng);
            // a reset always gives a valid state again
            assert_eq!(unsafe { phs_model_reset(&m, st.as_mut_ptr(), st.len()) }, PHS_OK, "{}", case.name);
            assert_eq!(unsafe { phs_model_step(&m, st.as_mut_ptr(), st.len(), 0.1, &mut y) }, PHS_OK, "{}", case.name);
            calls += 2;
        }
    }
    println!("model state fuzz: {calls} calls");
}

fn check_controller_calls(cc: &ControllerCase, c: &PhsController, st: &mut Vec<f64>, k0: usize) -> usize {
    let mut calls = 0;
    for k in k0..k0 + 3 {
        let (x, v, a, y) = scan(k);
        let before = st.clone();
        let mut u = f64::NAN;
        let code = unsafe { phs_controller_step(c, st.as_mut_ptr(), st.len(), x, v, a, y, &mut u) };
        calls += 1;
        assert!(documented(code), "{}: status {code:?} from state {before:?}: {}", cc.name, message());
        if code != PHS_OK {
            assert!(
                same_bits(st, &before) || diverged(code),
                "{}: refused ({code:?}: {}) but the state changed",
                cc.name,
                message()
            );
            return calls;
        }
        assert!((-20.0..=150.0).contains(&u), "{}: PHS_OK with command {u} from state {before:?}", cc.name);
        assert!(no_new_non_finite(st, &before), "{}: PHS_OK made the state non-finite from {before:?}", cc.name);
    }
    calls
}

#[test]
fn mutated_controller_states_give_documented_statuses() {
    let mut rng = Rng(0xD1B5_4A32_D192_ED03);
    let mpi = models().into_iter().find(|c| c.name == "mpi9").unwrap();
    let mut scratch = vec![];
    let m = build_model(&mpi, &mut scratch);
    let mut calls = 0;
    for cc in controllers() {
        let c = build_controller(&cc, &m);
        let mut base = vec![0.0; c.state_len];
        let mut u = 0.0;
        unsafe {
            assert_eq!(phs_controller_reset(&c, base.as_mut_ptr(), base.len(), 1e-6), PHS_OK);
            for k in 0..150 {
                let (x, v, a, y) = scan(k);
                let got = phs_controller_step(&c, base.as_mut_ptr(), base.len(), x, v, a, y, &mut u);
                assert_eq!(got, PHS_OK, "{}: {}", cc.name, message());
            }
        }
        for _ in 0..rounds() {
            let mut st = base.clone();
            mutate(&mut st, &mut rng);
            calls += check_controller_calls(&cc, &c, &mut st, 150);
            assert_eq!(unsafe { phs_controller_reset(&c, st.as_mut_ptr(), st.len(), 1e-6) }, PHS_OK, "{}", cc.name);
            let (x, v, a, y) = scan(150);
            let got = unsafe { phs_controller_step(&c, st.as_mut_ptr(), st.len(), x, v, a, y, &mut u) };
            assert_eq!(got, PHS_OK, "{} after reset: {}", cc.name, message());
            calls += 2;
        }
    }
    println!("controller state fuzz: {calls} calls");
}

/// Regression cases the loop found (kept fixed, whatever the generator does later).
#[test]
fn regressions() {
    // a PID whose integrator and filter slots hold +-f64::MAX: the step's integrator overflowed
    // to inf while the saturated command stayed finite, and returned PHS_OK (the next step then
    // refused the state); now the step itself says the controller diverged
    let pid = controllers().into_iter().find(|c| c.name == "pid").unwrap();
    let mpi = models().into_iter().find(|c| c.name == "mpi9").unwrap();
    let mut scratch = vec![];
    let m = build_model(&mpi, &mut scratch);
    let c = build_controller(&pid, &m);
    let mut st = vec![-f64::MAX, f64::MAX, f64::MAX];
    assert_eq!(st.len(), c.state_len);
    let (x, v, a, y) = scan(150);
    let mut u = 0.0;
    let got = unsafe { phs_controller_step(&c, st.as_mut_ptr(), st.len(), x, v, a, y, &mut u) };
    assert_eq!(got, PHS_ERR_NOT_FINITE, "{}", message());
    assert!(message().contains("reset the state"), "{}", message());
    // an RDPI state with -f64::MAX in its filter slot: the step diverges (documented, reset)
    let rdpi = models().into_iter().find(|c| c.name == "rdpi").unwrap();
    let mut scratch = vec![];
    let m = build_model(&rdpi, &mut scratch);
    let mut st = vec![-0.19970621104509656, 2.2250738585072014e-308, -5.413268380831308e-6, -f64::MAX, 26.41, 1.0];
    assert_eq!(st.len(), m.state_len);
    let mut y = 0.0;
    let got = unsafe { phs_model_step(&m, st.as_mut_ptr(), st.len(), 0.3, &mut y) };
    assert_eq!(got, PHS_ERR_NOT_FINITE, "{}", message());
    assert!(message().contains("reset the state"), "{}", message());
    assert_eq!(unsafe { phs_model_reset(&m, st.as_mut_ptr(), st.len()) }, PHS_OK);
}
