//! Fuzz-style: random bytes as parameter arrays and as the plain parameter structs
//! (`PhsModelSpec` scalars, `PhsIlcSpec`, `PhsInverse` limits, an uninitialized `PhsModel`
//! or `PhsController`), random lengths and NULL pointers. Every call returns a documented
//! status code, never `PHS_ERR_INTERNAL` (a caught panic), never crashes; what succeeds
//! gives finite results (and controller outputs inside their limits).
//!
//! Pointers themselves are never random: a C caller's wild pointer cannot be detected by
//! any library. Every length passed is at most the buffer's real length.
// Every unsafe block here calls the C ABI with pointers to the test's own live buffers (or
// deliberately NULL ones): the safety argument is the same for each and lives in this comment.
#![allow(clippy::undocumented_unsafe_blocks)]
mod common;

use common::*;
use piezohyst::PhsStatus::*;
use piezohyst::*;
use proptest::prelude::*;
use std::ptr;

fn last_message() -> String {
    unsafe { std::ffi::CStr::from_ptr(phs_last_error_message()) }.to_string_lossy().into_owned()
}

fn documented(code: PhsStatus) -> bool {
    (code as i32) >= 0 && (code as i32) < PHS_STATUS_COUNT && code != PHS_ERR_INTERNAL
}

/// A double from raw bits, or a "nice" value that gets past the finiteness checks.
fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<u64>().prop_map(f64::from_bits),
        -2.0..2.0f64,
        0.0..200.0f64,
        Just(0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-1.0),
        (1e-9..1e-3f64),
        (1e3..1e9f64),
    ]
}

fn dim() -> impl Strategy<Value = usize> {
    prop_oneof![0usize..12, any::<usize>(), Just(100_000), Just(100_001), Just(1000), Just(1001)]
}

/// A model description: random family, dims and (mostly) a row of the length the family
/// wants, filled with random values; sometimes a valid row with one value replaced.
#[derive(Debug, Clone)]
struct ModelInput {
    family: u32,
    n_dims: u32,
    dims: [usize; PHS_MAX_DIMS],
    row: Vec<f64>,
    declared: usize,
    null_params: bool,
    scratch_delta: i64,
    null_scratch: bool,
}

fn model_input() -> impl Strategy<Value = ModelInput> {
    let random = (
        prop_oneof![0u32..10, any::<u32>()],
        prop_oneof![0u32..6, any::<u32>()],
        [dim(), dim(), dim(), dim()],
        proptest::collection::vec(value(), 0..80),
        any::<u16>(),
        prop::bool::weighted(0.05),
        prop_oneof![Just(0i64), -2i64..3],
        prop::bool::weighted(0.05),
    )
        .prop_map(|(family, n_dims, dims, row, declared, null_params, scratch_delta, null_scratch)| {
            let declared = declared as usize % (row.len() + 1);
            ModelInput { family, n_dims, dims, row, declared, null_params, scratch_delta, null_scratch }
        });
    // a valid model with some values replaced by random ones: reaches the deep checks
    let mutated = (
        0usize..10,
        proptest::collection::vec((any::<prop::sample::Index>(), value()), 1..4),
        prop_oneof![Just(0i64), -1i64..2],
    )
        .prop_map(|(which, changes, scratch_delta)| {
            let case = &models()[which];
            let mut row = case.row.clone();
            for (i, x) in changes {
                let j = i.index(row.len());
                row[j] = x;
            }
            let mut dims = [0; PHS_MAX_DIMS];
            dims[..case.dims.len()].copy_from_slice(&case.dims);
            let declared = row.len();
            ModelInput {
                family: case.family,
                n_dims: case.dims.len() as u32,
                dims,
                row,
                declared,
                null_params: false,
                scratch_delta,
                null_scratch: false,
            }
        });
    // random dims, a row of exactly the family's length
    let sized = (1u32..9, [0usize..6, 0usize..3, 0usize..3, 0usize..3], proptest::collection::vec(value(), 200))
        .prop_map(|(family, dims, pool)| {
            let n_dims = match family {
                1 | 3 | 5 => 2,
                2 => 4,
                4 => 1,
                _ => 0,
            };
            let mut d = [0; PHS_MAX_DIMS];
            d[..n_dims].copy_from_slice(&dims[..n_dims]);
            if family == 5 {
                d[0] = d[0].max(1);
            }
            let s = spec(family, &d[..n_dims], &[]);
            let mut n = 0;
            unsafe { phs_model_sizes(&s, &mut n, ptr::null_mut(), ptr::null_mut()) };
            let row: Vec<f64> = pool.iter().cycle().take(n).copied().collect();
            let declared = row.len();
            ModelInput {
                family,
                n_dims: n_dims as u32,
                dims: d,
                row,
                declared,
                null_params: false,
                scratch_delta: 0,
                null_scratch: false,
            }
        });
    prop_oneof![random, mutated, sized]
}

/// Run every model entry point on the input; returns the model if it initialized.
fn exercise_model(inp: &ModelInput, drive: &[f64]) -> Result<(), TestCaseError> {
    let s = PhsModelSpec {
        family: inp.family,
        n_dims: inp.n_dims,
        dims: inp.dims,
        params: if inp.null_params { ptr::null() } else { inp.row.as_ptr() },
        n_params: inp.declared,
    };
    let (mut n_params, mut n_state, mut n_scratch) = (0, 0, 0);
    let sizes = unsafe { phs_model_sizes(&s, &mut n_params, &mut n_state, &mut n_scratch) };
    prop_assert!(documented(sizes), "sizes: {sizes:?}");
    if sizes != PHS_OK {
        // init must fail the same way, whatever the rest
        let mut m = empty_model();
        let code = unsafe { phs_model_init(&mut m, &s, ptr::null_mut(), 0) };
        prop_assert_eq!(code, sizes);
        prop_assert_eq!(m.magic, 0);
        return Ok(());
    }
    let want = (n_scratch as i64 + inp.scratch_delta).max(0) as usize;
    if want > 1 << 20 || inp.declared != n_params {
        // a wrong row length is refused before the scratch is looked at
        let mut m = empty_model();
        let code = unsafe { phs_model_init(&mut m, &s, ptr::null_mut(), want) };
        prop_assert!(code == PHS_ERR_BAD_LENGTH || code == PHS_ERR_NULL_POINTER, "init: {code:?}");
        return Ok(());
    }
    let mut scratch = vec![0.0; want];
    let sp = if inp.null_scratch || scratch.is_empty() { ptr::null_mut() } else { scratch.as_mut_ptr() };
    let mut m = empty_model();
    let code = unsafe { phs_model_init(&mut m, &s, sp, scratch.len()) };
    prop_assert!(documented(code), "init: {code:?}");
    let validate = unsafe { phs_model_validate(&s, sp, scratch.len()) };
    prop_assert_eq!(validate, code);
    if code != PHS_OK {
        prop_assert_eq!(m.magic, 0);
        let msg = unsafe { std::ffi::CStr::from_ptr(phs_last_error_message()) }.to_str().unwrap().to_owned();
        prop_assert!(msg.starts_with("phs_model_validate: "), "{}", msg);
        prop_assert_eq!(phs_last_error(), code);
        return Ok(());
    }
    prop_assert_eq!(m.state_len, n_state);
    if n_state > 1 << 20 {
        return Ok(());
    }
    let mut state = vec![f64::NAN; n_state];
    prop_assert_eq!(unsafe { phs_model_reset(&m, state.as_mut_ptr(), n_state) }, PHS_OK);
    for &v in drive {
        let mut y = 0.0;
        let code = unsafe { phs_model_step(&m, state.as_mut_ptr(), n_state, v, &mut y) };
        prop_assert!(documented(code), "step: {code:?}");
        match code {
            PHS_OK => prop_assert!(y.is_finite()),
            PHS_ERR_NOT_FINITE => {
                unsafe { phs_model_reset(&m, state.as_mut_ptr(), n_state) };
            }
            other => prop_assert!(false, "step returned {other:?}"),
        }
    }
    prop_assert_eq!(unsafe { phs_model_reset(&m, state.as_mut_ptr(), n_state) }, PHS_OK);
    // Bouc-Wen with n != 1 integrates each trial with up to 20000 RK4 sub-steps (a bounded
    // but slow step) and the inverse tries up to a few hundred inputs: keep those short
    let slow = inp.family == 6 && inp.row.get(3) != Some(&1.0);
    let mut guess = 0.0;
    for &yd in &drive[..if slow { drive.len().min(1) } else { drive.len() }] {
        let mut v = 0.0;
        let code = unsafe { phs_model_inverse_step(&m, state.as_mut_ptr(), n_state, yd, guess, &mut v) };
        prop_assert!(documented(code), "inverse: {code:?}");
        match code {
            PHS_OK => {
                prop_assert!(v.is_finite());
                guess = v;
            }
            PHS_ERR_UNREACHABLE | PHS_ERR_NOT_FINITE => {}
            PHS_ERR_NOT_INVERTIBLE => prop_assert!(m.flags & PHS_MODEL_FLAG_NOT_INVERTIBLE != 0),
            other => prop_assert!(false, "inverse returned {other:?}"),
        }
    }
    Ok(())
}

#[derive(Debug, Clone)]
struct ControllerInput {
    kind: u32,
    params: Vec<f64>,
    declared: usize,
    inverse: Option<(usize, f64, f64)>,
    ilc: Option<[u8; 40]>,
}

fn controller_input() -> impl Strategy<Value = ControllerInput> {
    let random = (
        prop_oneof![0u32..8, any::<u32>()],
        proptest::collection::vec(value(), 0..30),
        any::<u8>(),
        proptest::option::weighted(0.3, (0usize..10, value(), value())),
        proptest::option::weighted(0.3, any::<[u8; 40]>()),
    )
        .prop_map(|(kind, params, declared, inverse, ilc)| {
            let declared = declared as usize % (params.len() + 1);
            ControllerInput { kind, params, declared, inverse, ilc }
        });
    let mutated = (
        0usize..10,
        proptest::collection::vec((any::<prop::sample::Index>(), value()), 0..3),
        proptest::option::weighted(0.3, (0usize..10, value(), value())),
        proptest::option::weighted(0.2, (0usize..300, value(), value(), 0usize..300, 0usize..300)),
    )
        .prop_map(|(which, changes, inverse, ilc)| {
            let case = &controllers()[which];
            let mut params = case.params.clone();
            for (i, x) in changes {
                let j = i.index(params.len());
                params[j] = x;
            }
            let inverse = if case.inverse { Some(inverse.unwrap_or((3, -20.0, 150.0))) } else { inverse };
            let ilc = ilc.map(|(period, gain, forgetting, lead, delay)| {
                let mut b = [0u8; 40];
                b[..8].copy_from_slice(&period.to_ne_bytes());
                b[8..16].copy_from_slice(&gain.to_ne_bytes());
                b[16..24].copy_from_slice(&forgetting.to_ne_bytes());
                b[24..32].copy_from_slice(&lead.to_ne_bytes());
                b[32..40].copy_from_slice(&delay.to_ne_bytes());
                b
            });
            let declared = params.len();
            ControllerInput { kind: case.kind, params, declared, inverse, ilc }
        });
    prop_oneof![random, mutated]
}

fn ilc_from_bytes(b: &[u8; 40]) -> PhsIlcSpec {
    // SAFETY: PhsIlcSpec is 40 bytes of plain integers and doubles; any bits are a value
    assert_eq!(size_of::<PhsIlcSpec>(), 40);
    unsafe { ptr::read_unaligned(b.as_ptr().cast::<PhsIlcSpec>()) }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn models_from_random_bytes(inp in model_input(), drive in proptest::collection::vec(value(), 0..40)) {
        exercise_model(&inp, &drive)?;
    }

    #[test]
    fn controllers_from_random_bytes(
        inp in controller_input(),
        steps in proptest::collection::vec((value(), value(), value(), value()), 0..60),
        y0 in value(),
    ) {
        // the inverse models are valid ones (a PhsInverse holds a pointer), its limits random
        let cases = models();
        let (which, lo, hi) = inp.inverse.unwrap_or((0, 0.0, 1.0));
        let (mpi, mut scratch) = (mpi9_row(), Vec::new());
        let row: &[f64] = if which == 3 { &mpi } else { &cases[which].row };
        let s = spec(cases[which].family, &cases[which].dims, row);
        scratch.resize(scratch_len(&s), 0.0);
        let mut model = empty_model();
        prop_assert_eq!(init_model(&mut model, &s, &mut scratch), PHS_OK);
        let inverse = PhsInverse { model: &model, u_min: lo, u_max: hi };
        let ilc = inp.ilc.as_ref().map(ilc_from_bytes);
        let inv_ptr = if inp.inverse.is_some() { &inverse as *const PhsInverse } else { ptr::null() };
        let ilc_ptr = ilc.as_ref().map_or(ptr::null(), |x| x as *const PhsIlcSpec);
        let params = if inp.params.is_empty() { ptr::null() } else { inp.params.as_ptr() };
        let mut c = empty_controller();
        let code = unsafe { phs_controller_init(&mut c, inp.kind, params, inp.declared, inv_ptr, ilc_ptr) };
        prop_assert!(documented(code), "init: {code:?}");
        prop_assert_eq!(unsafe { phs_controller_validate(inp.kind, params, inp.declared, inv_ptr, ilc_ptr) }, code);
        if code != PHS_OK {
            prop_assert_eq!(c.magic, 0);
            let mut u = 0.0;
            let mut st = [0.0; 4];
            prop_assert_eq!(unsafe { phs_controller_step(&c, st.as_mut_ptr(), 4, 0.0, 0.0, 0.0, 0.0, &mut u) }, PHS_ERR_NOT_INITIALIZED);
            return Ok(());
        }
        // output limits: the inverse's voltage limits, else the kind's last two parameters
        let (u_lo, u_hi) = if inp.inverse.is_some() { (lo, hi) } else { (inp.params[inp.declared - 2], inp.params[inp.declared - 1]) };
        let n = c.state_len;
        if n > 1 << 20 {
            return Ok(());
        }
        let mut state = vec![0.0; n];
        let code = unsafe { phs_controller_reset(&c, state.as_mut_ptr(), n, y0) };
        prop_assert!(code == PHS_OK || (code == PHS_ERR_NOT_FINITE && !y0.is_finite()), "reset: {code:?}");
        if code != PHS_OK {
            return Ok(());
        }
        // behind an inverse: the reference rule of phs_controller_step (the controller's
        // limits widened by their span)
        let declared = |x: f64| {
            inp.inverse.is_none() || {
                let (l, h) = (inp.params[inp.declared - 2], inp.params[inp.declared - 1]);
                x >= l - (h - l) && x <= h + (h - l)
            }
        };
        for (x, v, a, y) in steps {
            let mut u = f64::NAN;
            let before = state.clone();
            let code = unsafe { phs_controller_step(&c, state.as_mut_ptr(), n, x, v, a, y, &mut u) };
            prop_assert!(documented(code), "step: {code:?}");
            let inputs_finite = [x, v, a, y].iter().all(|z| z.is_finite());
            // a step that ran and diverged (garbage gains drove the state or the command past
            // 1.8e308): PHS_ERR_NOT_FINITE "reset the state", the state may have changed
            let diverged = code == PHS_ERR_NOT_FINITE && last_message().contains("reset the state");
            match code {
                PHS_OK => prop_assert!(u.is_finite() && u >= u_lo && u <= u_hi, "u = {} outside [{}, {}]", u, u_lo, u_hi),
                // a non-finite input, or a state that an earlier step drove to infinity:
                // refused, never pinned to a rail
                PHS_ERR_NOT_FINITE => prop_assert!(
                    !inputs_finite || before.iter().any(|z| !z.is_finite()) || diverged,
                    "finite inputs and state rejected"
                ),
                PHS_ERR_UNREACHABLE => prop_assert!(inputs_finite && !declared(x), "x_ref = {} refused", x),
                other => prop_assert!(false, "step returned {other:?}"),
            }
            if code != PHS_OK && !diverged {
                prop_assert!(state.iter().zip(&before).all(|(a, b)| a.to_bits() == b.to_bits()), "state touched");
            }
            if diverged {
                break; // the state must be reset
            }
        }
    }

    /// Garbage where an initialized struct belongs is refused, not trusted.
    #[test]
    fn uninitialized_structs_are_refused(words in proptest::collection::vec(any::<u64>(), 40 + PHS_CONTROLLER_WORDS), v in value()) {
        let mut m = empty_model();
        m.magic = words[0];
        m.state_len = words[1] as usize % 64;
        m.built.copy_from_slice(&words[8..8 + PHS_MODEL_WORDS]);
        prop_assume!(m.magic != PHS_MODEL_MAGIC);
        let mut st = [0.0; 64];
        let mut y = 0.0;
        prop_assert_eq!(unsafe { phs_model_step(&m, st.as_mut_ptr(), m.state_len, v, &mut y) }, PHS_ERR_NOT_INITIALIZED);
        prop_assert_eq!(unsafe { phs_model_inverse_step(&m, st.as_mut_ptr(), m.state_len, v, 0.0, &mut y) }, PHS_ERR_NOT_INITIALIZED);
        prop_assert_eq!(unsafe { phs_model_reset(&m, st.as_mut_ptr(), m.state_len) }, PHS_ERR_NOT_INITIALIZED);
        let mut c = empty_controller();
        c.magic = words[2];
        c.state_len = words[3] as usize % 64;
        c.built.copy_from_slice(&words[40..40 + PHS_CONTROLLER_WORDS]);
        prop_assume!(c.magic != PHS_CONTROLLER_MAGIC);
        prop_assert_eq!(unsafe { phs_controller_step(&c, st.as_mut_ptr(), c.state_len, v, 0.0, 0.0, v, &mut y) }, PHS_ERR_NOT_INITIALIZED);
        prop_assert_eq!(unsafe { phs_controller_reset(&c, st.as_mut_ptr(), c.state_len, 0.0) }, PHS_ERR_NOT_INITIALIZED);
        // and the controller built on an uninitialized inverse model refuses too
        let inverse = PhsInverse { model: &m, u_min: 0.0, u_max: 1.0 };
        let p = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        prop_assert_eq!(unsafe { phs_controller_init(&mut c, 1, p.as_ptr(), 6, &inverse, ptr::null()) }, PHS_ERR_NOT_INITIALIZED);
    }
}

#[test]
fn null_pointers_everywhere() {
    let case = &models()[0];
    let s = spec(case.family, &case.dims, &case.row);
    let mut m = empty_model();
    let mut y = 0.0;
    let mut st = [0.0; 3];
    unsafe {
        assert_eq!(phs_model_init(ptr::null_mut(), &s, ptr::null_mut(), 0), PHS_ERR_NULL_POINTER);
        assert_eq!(phs_model_init(&mut m, ptr::null(), ptr::null_mut(), 0), PHS_ERR_NULL_POINTER);
        assert_eq!(
            phs_model_sizes(ptr::null(), ptr::null_mut(), ptr::null_mut(), ptr::null_mut()),
            PHS_ERR_NULL_POINTER
        );
        assert_eq!(phs_model_step(ptr::null(), st.as_mut_ptr(), 3, 0.0, &mut y), PHS_ERR_NULL_POINTER);
        assert_eq!(init_model(&mut m, &s, &mut []), PHS_OK);
        assert_eq!(phs_model_step(&m, ptr::null_mut(), 3, 0.0, &mut y), PHS_ERR_NULL_POINTER);
        assert_eq!(phs_model_step(&m, st.as_mut_ptr(), 3, 0.0, ptr::null_mut()), PHS_ERR_NULL_POINTER);
        assert_eq!(phs_model_inverse_step(&m, st.as_mut_ptr(), 3, 0.0, 0.0, ptr::null_mut()), PHS_ERR_NULL_POINTER);
        assert_eq!(phs_model_state_len(&m, ptr::null_mut()), PHS_ERR_NULL_POINTER);
        let mut c = empty_controller();
        assert_eq!(phs_controller_init(&mut c, 2, ptr::null(), 9, ptr::null(), ptr::null()), PHS_ERR_NULL_POINTER);
        assert_eq!(
            phs_controller_init(ptr::null_mut(), 2, ptr::null(), 9, ptr::null(), ptr::null()),
            PHS_ERR_NULL_POINTER
        );
        let inv = PhsInverse { model: ptr::null(), u_min: 0.0, u_max: 1.0 };
        let p = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(phs_controller_init(&mut c, 1, p.as_ptr(), 6, &inv, ptr::null()), PHS_ERR_NULL_POINTER);
        assert_eq!(phs_controller_param_count(3, ptr::null_mut()), PHS_ERR_NULL_POINTER);
        assert_eq!(
            phs_controller_step(ptr::null(), st.as_mut_ptr(), 0, 0.0, 0.0, 0.0, 0.0, &mut y),
            PHS_ERR_NULL_POINTER
        );
        let msg = std::ffi::CStr::from_ptr(phs_last_error_message()).to_str().unwrap();
        assert_eq!(msg, "phs_controller_step: controller is NULL");
    }
}

#[test]
fn overlapping_scratch_is_refused() {
    // a creep model needs scratch; pointing it into the parameter row is refused
    let mut row = models()[5].row.clone();
    let s = spec(4, &[2], &row);
    let n = scratch_len(&s);
    let mut m = empty_model();
    let p = row.as_mut_ptr();
    let s = PhsModelSpec { params: p, ..s };
    assert_eq!(unsafe { phs_model_init(&mut m, &s, p.wrapping_add(1), n) }, PHS_ERR_OVERLAP);
}

#[test]
fn error_names_and_messages() {
    unsafe {
        for code in 0..PHS_STATUS_COUNT {
            let name = std::ffi::CStr::from_ptr(phs_status_name(code)).to_str().unwrap();
            assert!(name.starts_with("PHS_"), "{name}");
            assert!(!std::ffi::CStr::from_ptr(phs_status_message(code)).to_bytes().is_empty());
        }
        assert_eq!(std::ffi::CStr::from_ptr(phs_status_name(-1)).to_str().unwrap(), "PHS_ERR_UNKNOWN_CODE");
        assert_eq!(std::ffi::CStr::from_ptr(phs_status_name(99)).to_str().unwrap(), "PHS_ERR_UNKNOWN_CODE");
        assert_eq!(std::ffi::CStr::from_ptr(phs_version()).to_str().unwrap(), env!("CARGO_PKG_VERSION"));
    }
}
