//! The one table of parameter layouts: every model family and every controller kind is
//! declared here once — its name, its C code (`PhsFamily` / `PhsControllerKind` of
//! `crates/capi`), its dimension names, its slot names in row order (with repetition such
//! as `r[n]`) and its decoder. The Python binding (`_core.family_layout`,
//! `_core.controller_layout`), the Python package (`export_c.row_names`, the controller
//! file keys, `identify`'s regressor columns) and the C header's slot documentation
//! (`crates/capi`, checked by `tests/layout_doc.rs`) are all read from or generated from
//! these rows, so a slot renamed here is renamed everywhere.
//!
//! Adding a family is one [`FAMILIES`] row plus its [`Family`] variant (structure and
//! `build` arm); adding a controller is one [`CONTROLLERS`] row plus its [`Law`] variant.
use core::fmt;

use crate::absmc::Absmc;
use crate::cemf::{CemfFeedforward, CemfModel};
use crate::control::filtered::{Biquad, FilteredPid, FilteredPidConfig, MAX_NOTCHES};
use crate::control::{Controller, Limits, OpenLoop, Output, Pid, PidConfig, Reference, VelocityObserver};
use crate::envelope::Envelope;
use crate::error::ModelError;
use crate::preisach::MAX_LEVELS;
use crate::smc::{Smc, SmcConfig, Switching};
use crate::spec::{Family, MAX_OPERATORS};

// ---------------------------------------------------------------------------------------
// slots

/// How many values a slot holds, given the family's dims.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Count {
    /// One scalar.
    One,
    /// One scalar, present only when `dims[i] > 0` (the creep tail's sample time).
    IfPositive(usize),
    /// A fixed number of values, `name[k]`.
    Fixed(usize),
    /// `dims[i]` values, `name[k]`.
    Dim(usize),
    /// `dims[i] (dims[i] + 1) / 2` values (Preisach cells).
    Triangle(usize),
}

/// One named slot (or run of slots) of a parameter row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    /// Name; repeated slots are `name[k]`.
    pub name: &'static str,
    /// How many values.
    pub count: Count,
}

const fn one(name: &'static str) -> Slot {
    Slot { name, count: Count::One }
}
const fn rep(name: &'static str, count: Count) -> Slot {
    Slot { name, count }
}

impl Slot {
    /// Number of values for these dims (a dim left out counts as 0: a Preisach row of two
    /// dims, written before its creep tail existed, has no tail).
    pub fn len(&self, dims: &[usize]) -> usize {
        let dim = |i: usize| dims.get(i).copied().unwrap_or(0);
        match self.count {
            Count::One => 1,
            Count::IfPositive(i) => usize::from(dim(i) > 0),
            Count::Fixed(k) => k,
            Count::Dim(i) => dim(i),
            Count::Triangle(i) => dim(i) * (dim(i) + 1) / 2,
        }
    }
    /// Whether the slot is a scalar (named without an index).
    pub fn is_scalar(&self) -> bool {
        matches!(self.count, Count::One | Count::IfPositive(_))
    }
}

// ---------------------------------------------------------------------------------------
// model families

/// One model family: everything the bindings need to know about its row.
#[derive(Debug, Clone, Copy)]
pub struct FamilyLayout {
    /// Name (`HysteresisModel.family` in Python).
    pub name: &'static str,
    /// `PhsFamily` code of the C library.
    pub code: u32,
    /// Label in the C header (`PHS_FAMILY_<label>`).
    pub label: &'static str,
    /// Names of the structural sizes, in order.
    pub dims: &'static [&'static str],
    /// The row's slots, in order.
    pub slots: &'static [Slot],
    /// The slots the output is linear in, in the order of the regressor columns of
    /// [`crate::spec::Model::regressors_step`] (empty: not linear in any parameters).
    pub linear: &'static [&'static str],
    /// The linear slots an identification keeps non-negative (the weights whose sign makes
    /// the model increasing, hence invertible); the others are free.
    pub nonnegative: &'static [&'static str],
    /// Decoder of the dims (their count is already checked against `dims`).
    pub decode: fn(&[usize]) -> Result<Family, ModelError>,
}

const CREEP_TS: &str = "creep_ts";
const CREEP_TAU: &str = "creep_tau";
const CREEP_C: &str = "creep_c";

fn dim(dims: &[usize], i: usize, name: &'static str) -> Result<usize, ModelError> {
    let d = dims[i];
    if d > MAX_OPERATORS {
        // the range in the message: a typo asking for terabytes says what is allowed
        return Err(ModelError::OutOfRange(name, usize::MAX, d as f64, 0.0, MAX_OPERATORS as f64));
    }
    Ok(d)
}

fn decode_pi(d: &[usize]) -> Result<Family, ModelError> {
    Ok(Family::Pi { n: dim(d, 0, "n")?, creep: dim(d, 1, "creep_terms")? })
}
fn decode_gpi(d: &[usize]) -> Result<Family, ModelError> {
    let (rising, falling) = (d[1], d[2]);
    Envelope::from_code(rising, [0.0; 4])?;
    Envelope::from_code(falling, [0.0; 4])?;
    Ok(Family::Gpi { n: dim(d, 0, "n")?, rising, falling, creep: dim(d, 3, "creep_terms")? })
}
fn decode_rdpi(d: &[usize]) -> Result<Family, ModelError> {
    Ok(Family::Rdpi { n: dim(d, 0, "n")?, creep: dim(d, 1, "creep_terms")? })
}
fn decode_creep(d: &[usize]) -> Result<Family, ModelError> {
    Ok(Family::Creep { terms: dim(d, 0, "terms")? })
}
fn decode_preisach(d: &[usize]) -> Result<Family, ModelError> {
    let levels = dim(d, 0, "levels")?;
    if levels == 0 || levels > MAX_LEVELS {
        return Err(ModelError::OutOfRange("levels", usize::MAX, levels as f64, 1.0, MAX_LEVELS as f64));
    }
    Ok(Family::Preisach { levels, memory: dim(d, 1, "memory")?, creep: dim(d, 2, "creep_terms")? })
}

/// Every model family, in `PhsFamily` code order.
pub const FAMILIES: &[FamilyLayout] = &[
    FamilyLayout {
        name: "pi",
        code: 1,
        label: "PI",
        dims: &["n", "creep_terms"],
        slots: &[
            one("p0"),
            rep("r", Count::Dim(0)),
            rep("w", Count::Dim(0)),
            rep(CREEP_TS, Count::IfPositive(1)),
            rep(CREEP_TAU, Count::Dim(1)),
            rep(CREEP_C, Count::Dim(1)),
        ],
        linear: &["p0", "w", CREEP_C],
        nonnegative: &["p0", "w", CREEP_C],
        decode: decode_pi,
    },
    FamilyLayout {
        name: "gpi",
        code: 2,
        label: "GPI",
        dims: &["n", "rising_kind", "falling_kind", "creep_terms"],
        slots: &[
            one("range_lo"),
            one("range_hi"),
            rep("poly", Count::Fixed(4)),
            rep("rising", Count::Fixed(4)),
            rep("falling", Count::Fixed(4)),
            rep("r", Count::Dim(0)),
            rep("b", Count::Dim(0)),
            rep(CREEP_TS, Count::IfPositive(3)),
            rep(CREEP_TAU, Count::Dim(3)),
            rep(CREEP_C, Count::Dim(3)),
        ],
        linear: &["poly", "b", CREEP_C],
        nonnegative: &["b", CREEP_C],
        decode: decode_gpi,
    },
    FamilyLayout {
        name: "rdpi",
        code: 3,
        label: "RDPI",
        dims: &["n", "creep_terms"],
        slots: &[
            one("ts"),
            one("p0"),
            one("beta"),
            one("filter_tau"),
            rep("r", Count::Dim(0)),
            rep("w", Count::Dim(0)),
            rep("c", Count::Dim(0)),
            rep(CREEP_TS, Count::IfPositive(1)),
            rep(CREEP_TAU, Count::Dim(1)),
            rep(CREEP_C, Count::Dim(1)),
        ],
        linear: &["p0", "w", "c", CREEP_C],
        nonnegative: &["p0", "w", CREEP_C],
        decode: decode_rdpi,
    },
    FamilyLayout {
        name: "creep",
        code: 4,
        label: "CREEP",
        dims: &["terms"],
        slots: &[one(CREEP_TS), rep(CREEP_TAU, Count::Dim(0)), rep(CREEP_C, Count::Dim(0))],
        linear: &[CREEP_C],
        nonnegative: &[CREEP_C],
        decode: decode_creep,
    },
    FamilyLayout {
        name: "preisach",
        code: 5,
        label: "PREISACH",
        dims: &["levels", "memory", "creep_terms"],
        slots: &[
            one("lo"),
            one("hi"),
            one("offset"),
            one("slope"),
            rep("w", Count::Triangle(0)),
            rep(CREEP_TS, Count::IfPositive(2)),
            rep(CREEP_TAU, Count::Dim(2)),
            rep(CREEP_C, Count::Dim(2)),
        ],
        linear: &["offset", "slope", "w", CREEP_C],
        nonnegative: &["slope", "w", CREEP_C],
        decode: decode_preisach,
    },
    FamilyLayout {
        name: "boucwen",
        code: 6,
        label: "BOUCWEN",
        dims: &[],
        slots: &[one("a"), one("beta"), one("gamma"), one("n"), one("d")],
        linear: &[],
        nonnegative: &[],
        decode: |_| Ok(Family::BoucWen),
    },
    FamilyLayout {
        name: "duhem",
        code: 7,
        label: "DUHEM",
        dims: &[],
        slots: &[one("alpha"), rep("f", Count::Fixed(4)), rep("g", Count::Fixed(4))],
        linear: &[],
        nonnegative: &[],
        decode: |_| Ok(Family::Duhem),
    },
    FamilyLayout {
        name: "dahl",
        code: 8,
        label: "DAHL",
        dims: &[],
        slots: &[one("sigma"), one("h_c"), one("a")],
        linear: &[],
        nonnegative: &[],
        decode: |_| Ok(Family::Dahl),
    },
];

impl FamilyLayout {
    /// The family of this name.
    pub fn by_name(name: &str) -> Option<&'static FamilyLayout> {
        FAMILIES.iter().find(|f| f.name == name)
    }
    /// The family of this `PhsFamily` code.
    pub fn by_code(code: u32) -> Option<&'static FamilyLayout> {
        FAMILIES.iter().find(|f| f.code == code)
    }
    /// Check the dims' count and decode them.
    ///
    /// A Preisach row written before its creep tail existed gives two dims (`levels, memory`):
    /// it is read with `creep_terms = 0` (the same row, the same model).
    pub fn family(&self, dims: &[usize]) -> Result<Family, ModelError> {
        if self.name == "preisach" && dims.len() == 2 {
            return (self.decode)(&[dims[0], dims[1], 0]);
        }
        if dims.len() != self.dims.len() {
            return Err(ModelError::Length("dims", self.dims.len(), dims.len()));
        }
        (self.decode)(dims)
    }
    /// Row length for these (valid) dims.
    pub fn param_len(&self, dims: &[usize]) -> usize {
        self.slots.iter().map(|s| s.len(dims)).sum()
    }
    /// Each slot with its offset in the row and its length, for these (valid) dims.
    pub fn ranges<'a>(&'a self, dims: &'a [usize]) -> impl Iterator<Item = (&'static Slot, usize, usize)> + 'a {
        let mut at = 0;
        self.slots.iter().map(move |s| {
            let len = s.len(dims);
            at += len;
            (s, at - len, len)
        })
    }
}

// ---------------------------------------------------------------------------------------
// controllers

/// One controller kind: its flat parameter array and decoder. The last two values are
/// always the output limits `u_min, u_max`.
#[derive(Debug, Clone, Copy)]
pub struct ControllerLayout {
    /// Name (`controller.core(stage)[0]` in Python).
    pub name: &'static str,
    /// `PhsControllerKind` code of the C library.
    pub code: u32,
    /// Label in the C header (`PHS_CONTROLLER_<label>`).
    pub label: &'static str,
    /// Parameter names, in order (the keys of a controller file's `params`).
    pub slots: &'static [&'static str],
    /// What the flags and options mean (C header documentation).
    pub notes: &'static str,
    /// Decoder of a parameter array of `slots.len()` finite values.
    pub decode: fn(&[f64]) -> Result<Law, ModelError>,
}

fn limits(p: &[f64]) -> Result<Limits, ModelError> {
    Limits::new(p[p.len() - 2], p[p.len() - 1])
}
fn observer(p: &[f64], i: usize) -> Result<VelocityObserver, ModelError> {
    VelocityObserver::new(p[i], p[i + 1], p[i + 2])
}
fn cemf(p: [f64; 8]) -> Result<CemfModel, ModelError> {
    CemfModel::from_slice(&p)
}

fn decode_open_loop(p: &[f64]) -> Result<Law, ModelError> {
    Ok(Law::OpenLoop(OpenLoop::new(p[0], p[1], p[2], p[3], limits(p)?)?))
}
fn decode_pid(p: &[f64]) -> Result<Law, ModelError> {
    let limits = limits(p)?;
    Ok(Law::Pid(Pid::new(PidConfig {
        kp: p[0],
        ki: p[1],
        kd: p[2],
        tau_d: p[3],
        ts: p[4],
        ff_gain: p[5],
        offset: p[6],
        limits,
    })?))
}
fn decode_smc(p: &[f64]) -> Result<Law, ModelError> {
    let limits = limits(p)?;
    // a finite value that is neither option is out of range (never "not finite")
    let switching = if p[6] == 0.0 {
        Switching::BoundaryLayer { gain: p[7], width: p[8] }
    } else if p[6] == 1.0 {
        Switching::SuperTwisting { k1: p[7], k2: p[8] }
    } else {
        return Err(ModelError::OutOfRange(
            "switching (0 boundary layer, 1 super-twisting)",
            usize::MAX,
            p[6],
            0.0,
            1.0,
        ));
    };
    let model = if p[12] != 0.0 { Some(cemf([p[0], p[1], p[2], p[13], p[14], p[15], p[16], p[17]])?) } else { None };
    Ok(Law::Smc(Smc::new(SmcConfig {
        m: p[0],
        b: p[1],
        k: p[2],
        kp: p[3],
        kv: p[4],
        alpha: p[5],
        switching,
        cemf: model,
        desired_model_terms: p[18] != 0.0,
        observer: observer(p, 9)?,
        limits,
    })?))
}
fn decode_absmc(p: &[f64]) -> Result<Law, ModelError> {
    Ok(Law::Absmc(
        Absmc {
            b: p[0],
            theta0: [p[1], p[2]],
            theta_min: [p[3], p[4]],
            theta_max: [p[5], p[6]],
            c1: p[7],
            lambda: p[8],
            ks: p[9],
            phi: p[10],
            gamma_theta: [p[11], p[12]],
            gamma_d: p[13],
            d0: p[14],
            d_max: p[15],
            desired_regressor: p[16] != 0.0,
            observer: observer(p, 17)?,
            limits: limits(p)?,
        }
        .validated()?,
    ))
}
fn decode_cemf_feedforward(p: &[f64]) -> Result<Law, ModelError> {
    let m = cemf([p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]])?;
    Ok(Law::CemfFeedforward(CemfFeedforward { model: m, limits: limits(p)? }))
}

fn biquad(p: &[f64], at: usize) -> Biquad {
    Biquad([p[at], p[at + 1], p[at + 2], p[at + 3], p[at + 4]])
}
fn decode_filtered_pid(p: &[f64]) -> Result<Law, ModelError> {
    let limits = limits(p)?;
    let mut notches = [Biquad::IDENTITY; MAX_NOTCHES];
    for (j, n) in notches.iter_mut().enumerate() {
        *n = biquad(p, 20 + 5 * j);
    }
    Ok(Law::FilteredPid(FilteredPid::new(FilteredPidConfig {
        kp: p[0],
        ki: p[1],
        kd: p[2],
        tau_d: p[3],
        ts: p[4],
        ff_gain: p[5],
        c1: p[6],
        c2: p[7],
        offset: p[8],
        error_delay: p[9],
        ff_filters: [biquad(p, 10), biquad(p, 15)],
        notches,
        damping: biquad(p, 20 + 5 * MAX_NOTCHES),
        limits,
    })?))
}

/// Every controller kind, in `PhsControllerKind` code order.
pub const CONTROLLERS: &[ControllerLayout] = &[
    ControllerLayout {
        name: "open_loop",
        code: 1,
        label: "OPEN_LOOP",
        slots: &["gain", "offset", "c1", "c2", "u_min", "u_max"],
        notes: "u = offset + gain (x_d + c1 x_d' + c2 x_d'').",
        decode: decode_open_loop,
    },
    ControllerLayout {
        name: "pid",
        code: 2,
        label: "PID",
        slots: &["kp", "ki", "kd", "tau_d", "ts", "ff_gain", "offset", "u_min", "u_max"],
        notes: "PID with feedforward, filtered derivative and anti-windup.",
        decode: decode_pid,
    },
    ControllerLayout {
        name: "smc",
        code: 3,
        label: "SMC",
        slots: &[
            "M",
            "B",
            "K",
            "kp",
            "kv",
            "alpha",
            "switching",
            "ks_or_k1",
            "phi_or_k2",
            "observer_bandwidth",
            "ts",
            "observer_delay",
            "cemf",
            "tem",
            "capacitance",
            "hyst_alpha",
            "hyst_beta",
            "hyst_gamma",
            "desired_model_terms",
            "u_min",
            "u_max",
        ],
        notes: "switching: 0 boundary layer (ks, phi), 1 super-twisting (k1, k2); cemf: 0 or 1; \
                desired_model_terms: 0 measured, 1 on the reference.",
        decode: decode_smc,
    },
    ControllerLayout {
        name: "absmc",
        code: 4,
        label: "ABSMC",
        slots: &[
            "b",
            "theta0_0",
            "theta0_1",
            "theta_min_0",
            "theta_min_1",
            "theta_max_0",
            "theta_max_1",
            "c1",
            "lambda",
            "ks",
            "phi",
            "gamma_theta_0",
            "gamma_theta_1",
            "gamma_d",
            "d0",
            "d_max",
            "desired_regressor",
            "observer_bandwidth",
            "ts",
            "observer_delay",
            "u_min",
            "u_max",
        ],
        notes: "desired_regressor: 0 or 1.",
        decode: decode_absmc,
    },
    ControllerLayout {
        name: "cemf_feedforward",
        code: 5,
        label: "CEMF_FEEDFORWARD",
        slots: &["M", "B", "K", "tem", "capacitance", "hyst_alpha", "hyst_beta", "hyst_gamma", "u_min", "u_max"],
        notes: "exact inverse feedforward of the CEMF stage model.",
        decode: decode_cemf_feedforward,
    },
    ControllerLayout {
        name: "filtered_pid",
        code: 6,
        label: "FILTERED_PID",
        slots: &[
            "kp",
            "ki",
            "kd",
            "tau_d",
            "ts",
            "ff_gain",
            "c1",
            "c2",
            "offset",
            "error_delay",
            "ff1_b0",
            "ff1_b1",
            "ff1_b2",
            "ff1_a1",
            "ff1_a2",
            "ff2_b0",
            "ff2_b1",
            "ff2_b2",
            "ff2_a1",
            "ff2_a2",
            "notch1_b0",
            "notch1_b1",
            "notch1_b2",
            "notch1_a1",
            "notch1_a2",
            "notch2_b0",
            "notch2_b1",
            "notch2_b2",
            "notch2_a1",
            "notch2_a2",
            "notch3_b0",
            "notch3_b1",
            "notch3_b2",
            "notch3_a1",
            "notch3_a2",
            "damping_b0",
            "damping_b1",
            "damping_b2",
            "damping_a1",
            "damping_a2",
            "u_min",
            "u_max",
        ],
        notes: "u = offset + ff_gain F2 F1[x_d] + c1 x_d' + c2 x_d'' + N3 N2 N1[PID(e)] + H[y], \
                e = x_d - error_delay x_d' + error_delay^2 / 2 x_d'' - y; \
                each filter a biquad (b0, b1, b2, a1, a2), 1 0 0 0 0 for none.",
        decode: decode_filtered_pid,
    },
];

impl ControllerLayout {
    /// The kind of this name.
    pub fn by_name(name: &str) -> Option<&'static ControllerLayout> {
        CONTROLLERS.iter().find(|c| c.name == name)
    }
    /// The kind of this `PhsControllerKind` code.
    pub fn by_code(code: u32) -> Option<&'static ControllerLayout> {
        CONTROLLERS.iter().find(|c| c.code == code)
    }
    /// Number of parameters.
    pub fn param_len(&self) -> usize {
        self.slots.len()
    }
    /// The one controller decoder: checks the count (`Length("params", want, got)`) and
    /// that every value is finite (`NotFinite("params", k, x)`), then builds the law
    /// (option values that are finite but not an option are `OutOfRange`).
    pub fn decode(&self, p: &[f64]) -> Result<Law, ModelError> {
        if p.len() != self.slots.len() {
            return Err(ModelError::Length("params", self.slots.len(), p.len()));
        }
        crate::error::check_finite("params", p)?;
        (self.decode)(p)
    }
}

/// A base controller law of any kind (what a [`ControllerLayout`] decodes to).
#[derive(Debug, Clone, Copy)]
pub enum Law {
    /// Open loop with dynamic feedforward.
    OpenLoop(OpenLoop),
    /// PID.
    Pid(Pid),
    /// Extended sliding-mode control.
    Smc(Smc),
    /// Adaptive backstepping sliding-mode control.
    Absmc(Absmc),
    /// CEMF inverse feedforward.
    CemfFeedforward(CemfFeedforward),
    /// PID with notch filters, feedforward filters and a damping loop.
    FilteredPid(FilteredPid),
}

macro_rules! on_law {
    ($b:expr, $c:ident => $e:expr) => {
        match $b {
            Law::OpenLoop($c) => $e,
            Law::Pid($c) => $e,
            Law::Smc($c) => $e,
            Law::Absmc($c) => $e,
            Law::CemfFeedforward($c) => $e,
            Law::FilteredPid($c) => $e,
        }
    };
}

impl Controller for Law {
    fn state_len(&self) -> usize {
        on_law!(self, c => c.state_len())
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        on_law!(self, c => c.reset(state, y0))
    }
    #[inline]
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        on_law!(self, c => c.step(state, r, y))
    }
    fn term_names(&self) -> &'static [&'static str] {
        on_law!(self, c => c.term_names())
    }
    fn limits(&self) -> Limits {
        on_law!(self, c => c.limits())
    }
}

// ---------------------------------------------------------------------------------------
// documentation rendered from the table (the C header's doc blocks)

/// One slot as documentation: `p0`, `r[n]`, `poly[4]`, `w[levels(levels+1)/2]`,
/// `creep_ts (if creep_terms > 0)`.
struct SlotDoc<'a>(&'a Slot, &'a [&'static str]);

impl fmt::Display for SlotDoc<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (s, dims) = (self.0, self.1);
        match s.count {
            Count::One => write!(f, "{}", s.name),
            Count::IfPositive(i) => write!(f, "{} (if {} > 0)", s.name, dims[i]),
            Count::Fixed(k) => write!(f, "{}[{k}]", s.name),
            Count::Dim(i) => write!(f, "{}[{}]", s.name, dims[i]),
            Count::Triangle(i) => write!(f, "{}[{d}({d}+1)/2]", s.name, d = dims[i]),
        }
    }
}

/// Markdown table of the model families (the `PhsFamily` doc block), one line per row,
/// written line by line to `line`.
pub fn family_doc(mut line: impl FnMut(fmt::Arguments<'_>)) {
    line(format_args!("| family | code | dims | row |"));
    line(format_args!("|---|---|---|---|"));
    for fam in FAMILIES {
        struct Dims(&'static [&'static str]);
        impl fmt::Display for Dims {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                if self.0.is_empty() {
                    return write!(f, "(none)");
                }
                for (i, d) in self.0.iter().enumerate() {
                    write!(f, "{}{d}", if i > 0 { ", " } else { "" })?;
                }
                Ok(())
            }
        }
        struct Row(&'static FamilyLayout);
        impl fmt::Display for Row {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                for (i, s) in self.0.slots.iter().enumerate() {
                    write!(f, "{}{}", if i > 0 { ", " } else { "" }, SlotDoc(s, self.0.dims))?;
                }
                Ok(())
            }
        }
        line(format_args!("| {} | {} | {} | {} |", fam.label, fam.code, Dims(fam.dims), Row(fam)));
    }
}

/// List of the controller kinds (the `PhsControllerKind` doc block), line by line.
pub fn controller_doc(mut line: impl FnMut(fmt::Arguments<'_>)) {
    for c in CONTROLLERS {
        struct Slots(&'static [&'static str]);
        impl fmt::Display for Slots {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                for (i, s) in self.0.iter().enumerate() {
                    write!(f, "{}{s}", if i > 0 { ", " } else { "" })?;
                }
                Ok(())
            }
        }
        line(format_args!("* {} = {} ({}): {}.", c.label, c.code, c.slots.len(), Slots(c.slots)));
        line(format_args!("  {}", c.notes));
    }
}
