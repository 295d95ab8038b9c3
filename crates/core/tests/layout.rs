//! The layout table (`piezohyst_core::layout`) is the one description of every row: its
//! lengths are the ones the builders consume, its codes are unique, and the controller
//! decoder is the one both bindings use (a bad option is out of range, never "not finite").
use piezohyst_core::layout::{ControllerLayout, FamilyLayout, Law, CONTROLLERS, FAMILIES};
use piezohyst_core::spec::Family;
use piezohyst_core::ModelError;

#[test]
fn codes_and_names_are_unique_and_in_code_order() {
    for (i, f) in FAMILIES.iter().enumerate() {
        assert_eq!(f.code as usize, i + 1, "{}", f.name);
        assert_eq!(FamilyLayout::by_name(f.name).unwrap().code, f.code);
        assert_eq!(FamilyLayout::by_code(f.code).unwrap().name, f.name);
        for l in f.linear {
            assert!(f.slots.iter().any(|s| s.name == *l), "{}: linear slot {l} is not a slot", f.name);
        }
    }
    for (i, c) in CONTROLLERS.iter().enumerate() {
        assert_eq!(c.code as usize, i + 1, "{}", c.name);
        assert_eq!(ControllerLayout::by_name(c.name).unwrap().code, c.code);
        assert_eq!(c.slots[c.slots.len() - 2..], ["u_min", "u_max"], "{}", c.name);
    }
}

/// Rows of the table's length build (and one value fewer does not), for several dims.
#[test]
fn table_lengths_are_what_the_builders_consume() {
    let cases: &[(&str, &[usize])] = &[
        ("pi", &[3, 0]),
        ("pi", &[4, 2]),
        ("gpi", &[3, 1, 2, 0]),
        ("gpi", &[2, 0, 0, 1]),
        ("rdpi", &[3, 0]),
        ("rdpi", &[2, 2]),
        ("creep", &[3]),
        ("preisach", &[4, 8]),
        ("preisach", &[4, 8, 2]),
        ("boucwen", &[]),
        ("duhem", &[]),
        ("dahl", &[]),
    ];
    for &(name, dims) in cases {
        let fam = Family::parse(name, dims).unwrap();
        let layout = FamilyLayout::by_name(name).unwrap();
        let n = layout.param_len(dims);
        assert_eq!(fam.param_len(), n, "{name} {dims:?}");
        assert_eq!(fam.layout().name, name);
        let (d, k) = fam.dims();
        // a two-dims Preisach row (written before its creep tail) reads with creep_terms = 0
        let want: Vec<usize> =
            if name == "preisach" && dims.len() == 2 { [dims, &[0]].concat() } else { dims.to_vec() };
        assert_eq!(&d[..k], &want[..], "{name} {dims:?}");
        let total: usize = layout.ranges(dims).map(|(_, _, len)| len).sum();
        assert_eq!(total, n);
        let mut scratch = vec![0.0; fam.scratch_len()];
        assert_eq!(fam.build(&vec![0.5; n - 1], &mut scratch).err(), Some(ModelError::Length("params", n, n - 1)));
    }
}

fn smc_params(switching: f64) -> Vec<f64> {
    let mut p = vec![0.0; 21];
    let l = ControllerLayout::by_name("smc").unwrap();
    let at = |name: &str| l.slots.iter().position(|s| *s == name).unwrap();
    for (name, v) in [
        ("M", 1e-3),
        ("B", 10.0),
        ("K", 1e5),
        ("kp", 1e6),
        ("kv", 2e3),
        ("alpha", 0.0),
        ("ks_or_k1", 10.0),
        ("phi_or_k2", 0.01),
        ("observer_bandwidth", 300.0),
        ("ts", 1e-4),
        ("u_min", -10.0),
        ("u_max", 100.0),
    ] {
        p[at(name)] = v;
    }
    p[at("switching")] = switching;
    p
}

#[test]
fn one_decoder_with_consistent_errors() {
    let smc = ControllerLayout::by_name("smc").unwrap();
    assert!(matches!(smc.decode(&smc_params(0.0)), Ok(Law::Smc(_))));
    assert!(matches!(smc.decode(&smc_params(1.0)), Ok(Law::Smc(_))));
    // a finite switching code that is no option is out of range, not "not finite"
    assert!(matches!(smc.decode(&smc_params(2.0)), Err(ModelError::OutOfRange(_, _, x, _, _)) if x == 2.0));
    let mut p = smc_params(0.0);
    p[3] = f64::NAN;
    assert!(matches!(smc.decode(&p), Err(ModelError::NotFinite("params", 3, _))));
    assert_eq!(smc.decode(&p[..20]).err(), Some(ModelError::Length("params", 21, 20)));
}

#[test]
fn nonnegative_and_linear_slots_are_declared_slots() {
    for f in FAMILIES {
        let declared: Vec<&str> = f.slots.iter().map(|s| s.name).collect();
        for name in f.linear {
            assert!(declared.contains(name), "{}: linear slot {name} is not a slot", f.name);
        }
        for name in f.nonnegative {
            assert!(f.linear.contains(name), "{}: nonnegative slot {name} is not linear", f.name);
        }
    }
}
