//! States from outside (issue 20): `check_state` refuses a tampered or non-finite state,
//! naming the slot, and passes every state the model or controller itself produces.
use piezohyst_core::compensated::Compensated;
use piezohyst_core::control::{Controller, Limits, Pid, PidConfig, Reference};
use piezohyst_core::ilc::Ilc;
use piezohyst_core::spec::Family;
use piezohyst_core::{Hysteresis, ModelError};

fn preisach_row(levels: usize) -> Vec<f64> {
    let mut row = vec![-1.0, 1.0, 0.0, 0.1];
    row.extend((0..levels * (levels + 1) / 2).map(|i| 0.01 * (1 + i % 3) as f64));
    row
}

fn pid() -> Pid {
    let limits = Limits::new(0.0, 150.0).unwrap();
    Pid::new(PidConfig { kp: 1e5, ki: 1e7, kd: 0.0, tau_d: 1e-4, ts: 1e-4, ff_gain: 1e6, offset: 0.0, limits }).unwrap()
}

#[test]
fn preisach_memory_length_out_of_range_is_refused_not_a_panic() {
    let fam = Family::parse("preisach", &[6, 4]).unwrap();
    let row = preisach_row(6);
    let mut scratch = vec![0.0; fam.scratch_len()];
    let m = fam.build(&row, &mut scratch).unwrap();
    let mut st = vec![0.0; m.state_len()];
    m.reset(&mut st);
    for k in 0..200 {
        let v = 0.9 * (0.13 * k as f64).sin() * (0.021 * k as f64).cos();
        m.check_state(&st).unwrap();
        m.step(&mut st, v);
    }
    for bad in [5.0, 1e9, -1.0, 1.5, f64::NAN, f64::INFINITY] {
        let mut t = st.clone();
        t[1] = bad;
        match m.check_state(&t) {
            Err(ModelError::OutOfRange(name, 1, _, lo, hi)) => {
                assert!(name.starts_with("state"), "{name}");
                assert_eq!((lo, hi), (0.0, 4.0));
            }
            Err(ModelError::NotFinite("state", 1, _)) => assert!(!bad.is_finite()),
            other => panic!("memory length {bad}: {other:?}"),
        }
    }
    assert!(matches!(m.check_state(&st[1..]), Err(ModelError::Length("state", 6, 5))));
}

#[test]
fn non_finite_pi_state_is_refused() {
    let fam = Family::parse("pi", &[3, 0]).unwrap();
    let row = [1.0, 0.0, 0.2, 0.4, 0.5, 0.3, 0.2];
    let mut scratch = vec![0.0; fam.scratch_len()];
    let m = fam.build(&row, &mut scratch).unwrap();
    let mut st = vec![0.0; m.state_len()];
    m.reset(&mut st);
    m.check_state(&st).unwrap();
    for (i, bad) in [(0, f64::NAN), (2, f64::NEG_INFINITY)] {
        let mut t = st.clone();
        t[i] = bad;
        assert!(matches!(m.check_state(&t), Err(ModelError::NotFinite("state", j, _)) if j == i));
    }
}

#[test]
fn controller_states_nan_or_infinite_are_refused_with_the_slot() {
    let c = pid();
    let mut st = vec![0.0; c.state_len()];
    c.reset(&mut st, 0.0);
    c.check_state(&st).unwrap();
    for bad in [f64::NAN, f64::NEG_INFINITY, f64::INFINITY] {
        let mut t = st.clone();
        t[0] = bad;
        assert!(matches!(c.check_state(&t), Err(ModelError::NotFinite("state", 0, _))));
    }
}

#[test]
fn compensated_and_learning_states_name_the_whole_state_slot() {
    let fam = Family::parse("preisach", &[6, 4]).unwrap();
    let row = preisach_row(6);
    let mut scratch = vec![0.0; fam.scratch_len()];
    let model = fam.build(&row, &mut scratch).unwrap();
    let inner = Pid::new(PidConfig { limits: Limits::new(-0.5, 0.5).unwrap(), ..*pid().config() }).unwrap();
    let ilc = Ilc::new(inner, 50, 0.5, 0.99, 3, 1).unwrap();
    let c = Compensated { inner: ilc, model, limits: Limits::new(-1.0, 1.0).unwrap() };
    let mut st = vec![0.0; c.state_len()];
    c.reset(&mut st, 0.0);
    for k in 0..300 {
        c.check_state(&st).unwrap();
        let x = 0.3 * (0.1 * k as f64).sin();
        c.step(&mut st, &Reference { x, v: 0.0, a: 0.0 }, 0.9 * x);
    }
    let a = ilc.state_len();
    // the Preisach memory length sits at slot a + 1 of the whole state
    let mut t = st.clone();
    t[a + 1] = 1e6;
    assert!(matches!(c.check_state(&t), Err(ModelError::OutOfRange(_, i, _, _, _)) if i == a + 1));
    // the ILC sample counter
    let mut t = st.clone();
    t[3] = -2.0;
    assert!(matches!(c.check_state(&t), Err(ModelError::OutOfRange(_, 3, _, _, _))));
    // the previous voltage
    let mut t = st.clone();
    t[c.state_len() - 1] = f64::NAN;
    assert!(matches!(c.check_state(&t), Err(ModelError::NotFinite("state", i, _)) if i == c.state_len() - 1));
}
