//! Piezo-driven flexure stage with counter-electromotive-force (CEMF) hysteresis, creep,
//! electrostriction and a drive amplifier (docs/spec.md §2.6, §3.1, §3.2). SI units throughout:
//! m, s, V, N, F (farad), C (coulomb).
//!
//! ```text
//! m x'' + b x' + k x = Tem (Va - Vh + Vcr + e2 Va^2)         mechanics (force from the stack)
//! q    = Cz (Va - Vh) + Tem x                                 charge on the stack
//! dVh  = alpha dq - beta |dq| Vh - gamma dq |Vh|              CEMF: Bouc–Wen (n = 1) on charge
//! Vcr  = sum_j c_j w_j,  tau_j w_j' = Va - w_j                creep: lags over decades
//! tau_a Va' = u - Va, |Va'| <= slew, vmin <= u <= vmax         amplifier
//! ```
//! The input-driven variant replaces `dq` by `dVa` in the CEMF law.
//!
//! ## Integration
//! One call advances one controller period `ts` (the command `u` is held) in `substeps`
//! equal sub-steps of length `h`. The linear part is discretized exactly: amplifier and
//! mechanics together (3 states, `u` held, the nonlinear forcing first-order held) while
//! the amplifier is not slew-limited, mechanics alone with the amplifier voltage
//! first-order held while it is (then `Va` is an exact ramp). The CEMF voltage follows the
//! charge through the exact Bouc–Wen increment of §2.5; the algebraic loop
//! `dq = Tem dx + Cz (dVa - dVh)` is solved by Newton on the increment. Each sub-step is a
//! predictor (forcing held at its start value) and a corrector (forcing first-order held
//! between the start and the predicted end), then the CEMF voltage is re-solved from the
//! corrected motion. The error is O(h^2) in the coupling only; `bench/closed_loop.py`
//! reports it against `scipy.integrate.solve_ivp` as a function of `substeps`.
use crate::error::{check_scalar, ModelError};
use crate::hysteresis::differential::bouc_wen_1_exact;
use crate::num::linalg::{expm, Mat};
use crate::num::math::{abs, exp, F2};

/// Most creep lags a stage can have.
pub const MAX_CREEP: usize = 8;

/// What a stage with structure adds to the stage's periods and sub-steps
/// ([`crate::plant::structure`]: more modes, a voltage-driven hysteresis law, a DAC). The
/// plain stage runs with [`NoExtra`], whose `ACTIVE = false` folds every hook away: the same
/// code, the same bits.
pub trait Extra {
    /// Whether the hooks do anything.
    const ACTIVE: bool;
    /// The command the amplifier receives for the controller's `u` (a DAC's resolution).
    fn command(&mut self, u: f64) -> f64 {
        u
    }
    /// A voltage-driven hysteresis in place of the CEMF law: the hysteresis voltage `Vh` at
    /// the amplifier voltage `va` if `va` were the period's end voltage (the law's state is
    /// not changed: see [`Extra::end_period`]), or `None` for the CEMF law.
    fn input_vh(&mut self, va: f64) -> Option<f64> {
        let _ = va;
        None
    }
    /// The period ended at amplifier voltage `va`: commit the hysteresis law's step.
    fn end_period(&mut self, va: f64) {
        let _ = va;
    }
    /// One sub-step of everything else the stage's force drives (see [`SubStep`]).
    fn substep(&mut self, step: &SubStep) {
        let _ = step;
    }
    /// The position the sensor sees, from the stack's displacement `x`.
    fn position(&self, x: f64) -> f64 {
        x
    }
}

/// What a sub-step hands [`Extra::substep`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubStep {
    /// Refinement level (the sub-step length is the stage's level `h`).
    pub level: usize,
    /// Amplifier voltage at the start, V.
    pub va0: f64,
    /// Command (held), V.
    pub u: f64,
    /// Forcing of the stack's mode (acceleration, m/s^2) at the start and the end,
    /// first-order held between them.
    pub d0: f64,
    /// See `d0`.
    pub d1: f64,
    /// Whether the forcing includes the amplifier voltage's linear force (the amplifier is
    /// slew-limited or ideal, so the voltage is not integrated exactly beside the mechanics).
    pub with_va: bool,
}

/// The plain stage: no structure.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoExtra;

impl Extra for NoExtra {
    const ACTIVE: bool = false;
}

/// What drives the CEMF hysteresis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HysteresisDrive {
    /// The stack charge (seed 1's model, algebraic loop closed exactly).
    Charge,
    /// The amplifier voltage (the simpler input-driven variant).
    Voltage,
}

/// Physical parameters (the contents of a stage file).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageParams {
    /// Equivalent moving mass `m`, kg.
    pub mass: f64,
    /// Equivalent damping `b`, N s/m.
    pub damping: f64,
    /// Equivalent stiffness `k`, N/m.
    pub stiffness: f64,
    /// Electromechanical transformation ratio `Tem`, N/V.
    pub tem: f64,
    /// Stack capacitance `Cz`, F.
    pub capacitance: f64,
    /// CEMF Bouc–Wen `alpha` (V/C for charge drive, V/V for voltage drive).
    pub hyst_alpha: f64,
    /// CEMF Bouc–Wen `beta` (1/C or 1/V).
    pub hyst_beta: f64,
    /// CEMF Bouc–Wen `gamma` (1/C or 1/V).
    pub hyst_gamma: f64,
    /// Charge or voltage drive of the CEMF law.
    pub hyst_drive: HysteresisDrive,
    /// Electrostriction `e2`, 1/V: extra force `Tem e2 Va^2`.
    pub electrostriction: f64,
    /// Creep lag time constants, s (first `creep_terms` used).
    pub creep_taus: [f64; MAX_CREEP],
    /// Creep weights `c_j` (dimensionless, per volt of drive).
    pub creep_weights: [f64; MAX_CREEP],
    /// Number of creep lags in use.
    pub creep_terms: usize,
    /// Amplifier output limits, V.
    pub amp_min: f64,
    /// Amplifier upper limit, V.
    pub amp_max: f64,
    /// Amplifier -3 dB bandwidth, Hz (`inf`: ideal).
    pub amp_bandwidth: f64,
    /// Amplifier slew-rate limit, V/s (`inf`: none).
    pub amp_slew: f64,
}

/// Mechanical state and everything the integrator carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageState {
    /// Amplifier output voltage, V.
    pub va: f64,
    /// Position, m.
    pub x: f64,
    /// Velocity, m/s.
    pub v: f64,
    /// CEMF voltage, V.
    pub vh: f64,
    /// Creep lag outputs, V.
    pub creep: [f64; MAX_CREEP],
}

impl StageState {
    /// At rest, everything at zero.
    pub const ZERO: StageState = StageState { va: 0.0, x: 0.0, v: 0.0, vh: 0.0, creep: [0.0; MAX_CREEP] };

    /// Number of `f64` in [`StageState::to_array`].
    pub const LEN: usize = 4 + MAX_CREEP;

    /// Flat copy `[va, x, v, vh, creep...]`.
    pub fn to_array(&self) -> [f64; Self::LEN] {
        let mut a = [0.0; Self::LEN];
        a[0] = self.va;
        a[1] = self.x;
        a[2] = self.v;
        a[3] = self.vh;
        a[4..].copy_from_slice(&self.creep);
        a
    }

    /// From the flat layout of [`StageState::to_array`].
    pub fn from_array(a: &[f64]) -> Result<Self, ModelError> {
        if a.len() != Self::LEN {
            return Err(ModelError::Length("state", Self::LEN, a.len()));
        }
        crate::error::check_finite("state", a)?;
        let mut creep = [0.0; MAX_CREEP];
        creep.copy_from_slice(&a[4..]);
        Ok(StageState { va: a[0], x: a[1], v: a[2], vh: a[3], creep })
    }
}

/// Exact discretization over `h` of `z' = A z + B u + E d(t)` with `u` held and `d` linear
/// from `d0` to `d1`: `z1 = phi z0 + gu u + g0 d0 + g1 d1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Discrete<const N: usize> {
    pub(crate) phi: Mat<N>,
    pub(crate) gu: [f64; N],
    pub(crate) g0: [f64; N],
    pub(crate) g1: [f64; N],
}

impl<const N: usize> Discrete<N> {
    /// Van Loan: exponential of `[[A, B, E, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0]]`.
    pub(crate) fn new<const M: usize>(a: &Mat<N>, b: &[f64; N], e: &[f64; N], h: f64) -> Self {
        debug_assert!(M == N + 3);
        let mut m = [[0.0; M]; M];
        for i in 0..N {
            for j in 0..N {
                m[i][j] = a[i][j] * h;
            }
            m[i][N] = b[i] * h;
            m[i][N + 1] = e[i] * h;
        }
        m[N + 1][N + 2] = h; // d(t) = d0 + s * (d1 - d0)/h, with s the slope state
        let x = expm(&m);
        let mut phi = [[0.0; N]; N];
        let (mut gu, mut ge, mut gs) = ([0.0; N], [0.0; N], [0.0; N]);
        for i in 0..N {
            phi[i].copy_from_slice(&x[i][..N]);
            gu[i] = x[i][N];
            ge[i] = x[i][N + 1];
            gs[i] = x[i][N + 2] / h; // per unit of (d1 - d0)
        }
        let mut g0 = [0.0; N];
        let mut g1 = [0.0; N];
        for i in 0..N {
            g0[i] = ge[i] - gs[i];
            g1[i] = gs[i];
        }
        Discrete { phi, gu, g0, g1 }
    }

    #[inline(always)]
    pub(crate) fn apply(&self, z: &[f64; N], u: f64, d0: f64, d1: f64) -> [f64; N] {
        let mut out = [0.0; N];
        for (i, out_i) in out.iter_mut().enumerate() {
            let mut acc = self.gu[i] * u + self.g0[i] * d0 + self.g1[i] * d1;
            for (&phi_ij, &z_j) in self.phi[i].iter().zip(z) {
                acc += phi_ij * z_j;
            }
            *out_i = acc;
        }
        out
    }
}

/// CEMF slopes at a sub-step's start (see `Stage::cemf_start`); index 0 for a rising,
/// 1 for a falling drive.
#[derive(Debug, Clone, Copy)]
struct CemfStart {
    vh0: f64,
    g: [f64; 2],
    inv_b: [f64; 2],
    /// The exact increment's `c = beta s + gamma sh` and `a - c vh0` (`sh = +-1` the side of
    /// `vh0` > 0): constants of the sub-step, computed from `vh0` ahead of the motion so
    /// the CEMF solve, which waits for the motion, only selects them.
    sh: f64,
    c: [f64; 2],
    a_c: [f64; 2],
    /// The series solve of the charge loop (`Stage::cemf_series`), both directions side by
    /// side: `(a - c vh0) / b`, `c / b`, `c / b^2` (`b = 1 + Cz g`), the coefficients of
    /// `Q`, and the directions it applies to from this start (bit 0 rising, 1 falling).
    a_cb: F2,
    cb: F2,
    /// `g / b`, the predictor's slope
    g_b: F2,
    cb2: F2,
    series: [F2; 8],
    series_ok: u32,
}

/// The series solve of the charge loop covers `|t| <= SERIES_T_MAX` (`t = c q_ext / b`,
/// about the CEMF exponent change of the sub-step) ...
const SERIES_T_MAX: f64 = 0.04;
/// ... and `0 <= kappa <= SERIES_KAPPA_MAX` (`kappa = Cz g / b`, >= 0 inside the envelope;
/// the packaged stage's is at most 0.25). Its truncation then changes the CEMF increment by
/// less than 4e-17 relative (see `loop_series`).
const SERIES_KAPPA_MAX: f64 = 0.5;

/// Coefficients `A_2 .. A_9` of `Q(t) = sum_m A_m(kappa) t^(m-2)`, the charge loop's inverse
/// series (see `Stage::cemf_series`): `A_m = a_m / kappa` where `y = sum_m a_m l^m` inverts
/// `l = y - kappa (y - 1 + exp(-y))`. The integers are `m! a_m`'s coefficients of
/// `kappa^1 .. kappa^(m-1)` (Lagrange inversion; exact rational arithmetic gives integers).
/// Over `0 <= kappa <= 1/2`, `|A_10| <= 1.3e-4`, `|A_11| <= 8.5e-5`, `|A_12| <= 3.9e-5`, so
/// for `|t| <= 0.04` the omitted terms change `t Q(t) / b` by less than 4e-17.
#[inline(always)]
fn loop_series(k: F2) -> [F2; 8] {
    // both directions side by side; each polynomial's integer coefficients divided by m!
    // at compile time
    #[inline(always)]
    fn horner<const N: usize>(k: F2, c: [f64; N], m_factorial: f64) -> F2 {
        let mut acc = F2::splat(c[N - 1] / m_factorial);
        let mut j = N - 1;
        while j > 0 {
            j -= 1;
            acc = F2::splat(c[j] / m_factorial) + k * acc;
        }
        acc
    }
    [
        F2::splat(0.5),
        horner(k, [-1.0, 3.0], 6.0),
        horner(k, [1.0, -10.0, 15.0], 24.0),
        horner(k, [-1.0, 25.0, -105.0, 105.0], 120.0),
        horner(k, [1.0, -56.0, 490.0, -1260.0, 945.0], 720.0),
        horner(k, [-1.0, 119.0, -1918.0, 9450.0, -17325.0, 10395.0], 5040.0),
        horner(k, [1.0, -246.0, 6825.0, -56980.0, 190575.0, -270270.0, 135135.0], 40320.0),
        horner(k, [-1.0, 501.0, -22935.0, 302995.0, -1636635.0, 4099095.0, -4729725.0, 2027025.0], 362880.0),
    ]
}

/// Sub-step refinement levels: level `j` splits a period into `substeps * 2^j` sub-steps.
pub const LEVELS: usize = 11;

/// Everything that depends on the sub-step length `h`, precomputed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Level {
    h: f64,
    /// mechanics alone: z = [x, v], u unused, d = force/mass (first-order held)
    mech: Discrete<2>,
    /// amplifier + mechanics: z = [Va, x, v], u = command (held), d = extra force/mass
    amp_mech: Discrete<3>,
    amp_decay: f64,
    /// creep lag update for a first-order-held input: w1 = e w0 + (1 - e) va0 + b (va1 - va0)
    creep_e: [f64; MAX_CREEP],
    creep_1me: [f64; MAX_CREEP],
    creep_b: [f64; MAX_CREEP],
}

impl Level {
    fn new(p: &StageParams, amp_ideal: bool, amp_tau: f64, h: f64) -> Self {
        let (m, b, k) = (p.mass, p.damping, p.stiffness);
        let mech = Discrete::new::<5>(&[[0.0, 1.0], [-k / m, -b / m]], &[0.0, 0.0], &[0.0, 1.0], h);
        let amp_mech = if amp_ideal {
            Discrete::new::<6>(&[[0.0; 3]; 3], &[0.0; 3], &[0.0; 3], h)
        } else {
            let a = [[-1.0 / amp_tau, 0.0, 0.0], [0.0, 0.0, 1.0], [p.tem / m, -k / m, -b / m]];
            Discrete::new::<6>(&a, &[1.0 / amp_tau, 0.0, 0.0], &[0.0, 0.0, 1.0], h)
        };
        let amp_decay = if amp_ideal { 0.0 } else { exp(-h / amp_tau) };
        let (mut creep_e, mut creep_1me, mut creep_b) = ([1.0; MAX_CREEP], [0.0; MAX_CREEP], [0.0; MAX_CREEP]);
        for j in 0..p.creep_terms {
            let x = h / p.creep_taus[j];
            creep_e[j] = exp(-x);
            creep_1me[j] = -crate::num::math::expm1(-x);
            // b = 1 - (1 - e^-x)/x, by its series where the difference would cancel
            creep_b[j] = if x < 1e-3 {
                x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0 - x / 120.0)))
            } else {
                1.0 + crate::num::math::expm1(-x) / x
            };
        }
        Level { h, mech, amp_mech, amp_decay, creep_e, creep_1me, creep_b }
    }
}

/// A stage prepared for one controller period `ts`.
///
/// A period is integrated in `substeps` sub-steps, refined by powers of two (up to
/// `2^(LEVELS-1)`) when the charge driving the CEMF would change by more than
/// `tolerance / (beta + gamma)` in one sub-step: the coupling error is second order in
/// that change, so fast voltage changes get short sub-steps and smooth motion stays cheap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stage {
    /// The physics.
    pub params: StageParams,
    /// Controller period, s.
    pub ts: f64,
    /// Minimum sub-steps per period.
    pub substeps: usize,
    /// Largest CEMF exponent change `(beta + gamma) |dq|` allowed in one sub-step.
    pub tolerance: f64,
    levels: [Level; LEVELS],
    amp_ideal: bool,
    amp_tau: f64,
    omega_n: f64,
    static_gain: f64,
    // Derived constants of the hot path, each computed exactly as the expression it stands
    // for was (so results do not change by a bit).
    /// `tem / mass`
    accel_gain: f64,
    /// `amp_slew * amp_tau`
    slew_tau: f64,
    /// `|beta| + |gamma|` and `2 |e2|` of the refinement rule
    refine_hyst: f64,
    refine_e2: f64,
    /// The ideal amplifier without a slew limit steps the voltage at a period's start.
    amp_steps: bool,
    /// The common configuration (see [`Stage::is_typical`]).
    typical: bool,
}

fn positive(name: &'static str, x: f64) -> Result<(), ModelError> {
    if x.is_nan() {
        return Err(ModelError::NotFinite(name, usize::MAX, x));
    }
    if !(x > 0.0) {
        return Err(ModelError::NotPositive(name, usize::MAX, x));
    }
    Ok(())
}

impl StageParams {
    /// The parameters of piezohyst's packaged virtual stage
    /// (`python/piezohyst/presets/virtual_stage.json`: seed 1's flexure stage and stack, CEMF on
    /// charge, electrostriction, five creep decades, a 3 kHz / 0.14 V/us amplifier; damping from
    /// its damping ratio 0.03), for Rust tests, examples and benchmarks. The Python test
    /// `tests/test_stage.py::test_rust_virtual_stage_matches_the_preset` keeps the two equal.
    pub fn virtual_stage() -> Self {
        let (mass, stiffness) = (0.0714, 7.333e7);
        let mut creep_taus = [1.0; MAX_CREEP];
        creep_taus[..5].copy_from_slice(&[0.01, 0.1, 1.0, 10.0, 100.0]);
        let mut creep_weights = [0.0; MAX_CREEP];
        creep_weights[..5].copy_from_slice(&[0.015; 5]);
        StageParams {
            mass,
            damping: 2.0 * 0.03 * libm::sqrt(stiffness * mass),
            stiffness,
            tem: 10.5,
            capacitance: 1.8e-6,
            hyst_alpha: 1.25e5,
            hyst_beta: 8000.0,
            hyst_gamma: 3000.0,
            hyst_drive: HysteresisDrive::Charge,
            electrostriction: 3.3e-4,
            creep_taus,
            creep_weights,
            creep_terms: 5,
            amp_min: -20.0,
            amp_max: 150.0,
            amp_bandwidth: 3000.0,
            amp_slew: 1.4e5,
        }
    }

    /// Check every parameter is physical.
    pub fn validate(&self) -> Result<(), ModelError> {
        for (name, x) in
            [("mass", self.mass), ("stiffness", self.stiffness), ("tem", self.tem), ("capacitance", self.capacitance)]
        {
            check_scalar(name, x)?;
            positive(name, x)?;
        }
        for (name, x) in [
            ("damping", self.damping),
            ("hyst_alpha", self.hyst_alpha),
            ("hyst_beta", self.hyst_beta),
            ("hyst_gamma", self.hyst_gamma),
            ("electrostriction", self.electrostriction),
            ("amp_min", self.amp_min),
            ("amp_max", self.amp_max),
        ] {
            check_scalar(name, x)?;
        }
        if self.damping < 0.0 {
            return Err(ModelError::Negative("damping", usize::MAX, self.damping));
        }
        if !(self.amp_max > self.amp_min) {
            return Err(ModelError::NotIncreasing("amp_max (must exceed amp_min)", usize::MAX, self.amp_max));
        }
        positive("amp_bandwidth", self.amp_bandwidth)?;
        positive("amp_slew", self.amp_slew)?;
        if self.creep_terms > MAX_CREEP {
            return Err(ModelError::Structure("creep_terms", self.creep_terms));
        }
        for j in 0..self.creep_terms {
            let (t, c) = (self.creep_taus[j], self.creep_weights[j]);
            if !(t > 0.0) || t.is_infinite() {
                return Err(ModelError::NotPositive("creep_taus", j, t));
            }
            if !c.is_finite() {
                return Err(ModelError::NotFinite("creep_weights", j, c));
            }
        }
        Ok(())
    }
}

/// Sub-steps per controller period are capped so a typo cannot hang a simulation.
pub const MAX_SUBSTEPS: usize = 10_000;

impl Stage {
    /// Prepare the stage for controller period `ts` with at least `substeps` sub-steps and
    /// refinement `tolerance` (> 0; `inf` never refines).
    pub fn new(params: StageParams, ts: f64, substeps: usize, tolerance: f64) -> Result<Self, ModelError> {
        params.validate()?;
        check_scalar("ts", ts)?;
        positive("ts", ts)?;
        if substeps == 0 || substeps > MAX_SUBSTEPS {
            return Err(ModelError::Structure("substeps", substeps));
        }
        positive("tolerance", tolerance)?;
        let p = &params;
        let amp_ideal = p.amp_bandwidth.is_infinite();
        let amp_tau = if amp_ideal { 0.0 } else { 1.0 / (2.0 * core::f64::consts::PI * p.amp_bandwidth) };
        let mut levels = [Level::new(p, amp_ideal, amp_tau, ts / substeps as f64); LEVELS];
        for (j, level) in levels.iter_mut().enumerate().skip(1) {
            *level = Level::new(p, amp_ideal, amp_tau, ts / (substeps << j) as f64);
        }
        let omega_n = crate::num::math::sqrt(p.stiffness / p.mass);
        let static_gain = p.tem / p.stiffness;
        Ok(Stage {
            params,
            ts,
            substeps,
            tolerance,
            levels,
            amp_ideal,
            amp_tau,
            omega_n,
            static_gain,
            accel_gain: p.tem / p.mass,
            slew_tau: p.amp_slew * amp_tau,
            refine_hyst: abs(p.hyst_beta) + abs(p.hyst_gamma),
            refine_e2: 2.0 * abs(p.electrostriction),
            amp_steps: amp_ideal && p.amp_slew.is_infinite(),
            typical: p.hyst_drive == HysteresisDrive::Charge
                && !amp_ideal
                && p.amp_slew.is_finite()
                && tolerance.is_finite(),
        })
    }

    /// Clamp a command to the amplifier's range.
    #[inline]
    pub fn saturate(&self, u: f64) -> f64 {
        crate::num::math::clamp(u, self.params.amp_min, self.params.amp_max)
    }

    /// Sub-step length of refinement level `j`, s.
    pub(crate) fn level_h(&self, j: usize) -> f64 {
        self.levels[j].h
    }

    /// The amplifier's time constant (`None`: ideal, no lag).
    pub(crate) fn amplifier_tau(&self) -> Option<f64> {
        if self.amp_ideal {
            None
        } else {
            Some(self.amp_tau)
        }
    }

    /// Forcing (acceleration) that is not in the exact linear part.
    #[inline(always)]
    fn extra_accel(&self, va: f64, vh: f64, vcr: f64, with_va: bool) -> f64 {
        let lin = if with_va { va } else { 0.0 };
        self.accel_gain * (lin - vh + vcr + self.params.electrostriction * va * va)
    }

    /// The common configuration: charge drive, an amplifier with finite bandwidth and slew
    /// rate, a finite refinement tolerance (the packaged virtual stage's). The step code
    /// takes a constant `T` that, when true, asserts this so the configuration checks fold
    /// away; with `T` false everything is checked at run time. Either way the arithmetic is
    /// the same.
    #[inline(always)]
    pub(crate) fn is_typical(&self) -> bool {
        self.typical
    }

    #[inline(always)]
    fn charge<const T: bool>(&self) -> bool {
        T || self.params.hyst_drive == HysteresisDrive::Charge
    }

    #[inline(always)]
    fn ideal_amp<const T: bool>(&self) -> bool {
        !T && self.amp_ideal
    }

    /// Charge (or voltage) increment driving the CEMF, before its own feedback.
    #[inline(always)]
    fn drive_increment<const T: bool>(&self, dx: f64, va0: f64, va1: f64) -> f64 {
        let p = &self.params;
        if self.charge::<T>() {
            p.tem * dx + p.capacitance * (va1 - va0)
        } else {
            va1 - va0
        }
    }

    /// The CEMF law's slope `G` and the loop factor `1 / (1 + Cz G)` at the sub-step's
    /// start, for a rising (`[0]`) and a falling (`[1]`) charge, and the series solve's
    /// constants: computed from the start state alone, so no division or coefficient waits
    /// for the motion.
    #[inline(always)]
    fn cemf_start<const T: bool>(&self, vh0: f64) -> CemfStart {
        let p = &self.params;
        let cz = if self.charge::<T>() { p.capacitance } else { 0.0 };
        let (a, beta, gamma) = (p.hyst_alpha, p.hyst_beta, p.hyst_gamma);
        let sh = if vh0 > 0.0 { 1.0 } else { -1.0 };
        // both directions at once (s = +1, -1), each lane the scalar expression's operations
        // in its order: g = cemf_slope(vh0, s), c = beta s + gamma sh, 1 / (1 + Cz g), a - c vh0
        let (one, vh) = (F2::splat(1.0), F2::splat(vh0));
        let beta_s = F2::splat(beta) * F2::new(1.0, -1.0);
        let g = (F2::splat(a) - beta_s * vh) - F2::splat(gamma * abs(vh0));
        let c = beta_s + F2::splat(gamma * sh);
        let inv_b = one / (one + F2::splat(cz) * g);
        let a_c = F2::splat(a) - c * vh;
        // kappa = Cz g / (1 + Cz g) = 1 - 1 / b
        let kappa = one - inv_b;
        let in_range = F2::splat(0.0).le_bits(kappa) & kappa.le_bits(F2::splat(SERIES_KAPPA_MAX));
        let cb = c * inv_b;
        CemfStart {
            vh0,
            g: g.get(),
            inv_b: inv_b.get(),
            sh,
            c: c.get(),
            a_c: a_c.get(),
            a_cb: a_c * inv_b,
            cb,
            g_b: g * inv_b,
            cb2: cb * inv_b,
            series: loop_series(kappa),
            series_ok: if self.charge::<T>() && vh0 != 0.0 { in_range } else { 0 },
        }
    }

    /// First-order estimate of the CEMF voltage after the motion (no exponentials): the
    /// predictor's value.
    #[inline(always)]
    fn cemf_linear<const T: bool>(&self, at: &CemfStart, dx: f64, va0: f64, va1: f64) -> f64 {
        let q = self.drive_increment::<T>(dx, va0, va1);
        let [rising, falling] = at.g_b.get();
        at.vh0 + q * if q < 0.0 { falling } else { rising }
    }

    /// CEMF voltage after the stack moved by `dx` while the amplifier went `va0 -> va1`,
    /// through the exact Bouc–Wen increment. For charge drive the loop
    /// `dq = q_ext - Cz dVh`, `dVh = BW(vh0, dq) - vh0` is solved by its inverse series
    /// ([`Stage::cemf_series`]) when that applies, else by [`Stage::cemf_general`].
    #[inline(always)]
    fn cemf<const T: bool>(&self, at: &CemfStart, dx: f64, va0: f64, va1: f64) -> f64 {
        let q_ext = self.drive_increment::<T>(dx, va0, va1);
        if self.charge::<T>() {
            let (vh1, ok) = self.cemf_series(at, q_ext);
            if ok {
                return vh1;
            }
        }
        self.cemf_general::<T>(at, q_ext)
    }

    /// The charge loop solved in closed form. On a piece where `sign(Vh)` and
    /// `s = sign(dq)` hold, `dVh = (a - c vh0) dq phi1(c dq)` (`c = beta s + gamma sh`), so
    /// with `y = c dq`, `K = Cz (a - c vh0)`, `b = 1 + K` the loop
    /// `dq + Cz dVh = q_ext` reads `y + K (1 - exp(-y)) = b l`, `l = c q_ext / b`, i.e.
    /// `y - kappa (y - 1 + exp(-y)) = l` with `kappa = K / b`. Its inverse series is
    /// `y = l + kappa l^2 Q(l)` (Lagrange), and since `Cz dVh = q_ext - dq`,
    /// `dVh = (a - c vh0) (q_ext / b) (1 - l Q(l) / b)`: no exponential, no iteration, and
    /// the step's chain after the motion is a degree-7 polynomial. Returns the end voltage
    /// and whether it is valid: the start is on one side of zero (`vh0 != 0`), `kappa` and
    /// `|l|` are in the series' range (truncation below 4e-17 relative, see `loop_series`)
    /// and the end stays on the start's side (no zero crossing).
    #[inline(always)]
    fn cemf_series(&self, at: &CemfStart, q_ext: f64) -> (f64, bool) {
        // both directions side by side, the one of q_ext's sign picked at the end: nothing
        // on the chain waits for a load indexed by it
        let qv = F2::splat(q_ext);
        let t = qv * at.cb;
        let tb = qv * at.cb2;
        let q = &at.series;
        // Estrin's scheme for Q(t) (degree 7): a short dependency chain
        let t2 = t * t;
        let t4 = t2 * t2;
        let q01 = q[0] + q[1] * t;
        let q23 = q[2] + q[3] * t;
        let q45 = q[4] + q[5] * t;
        let q67 = q[6] + q[7] * t;
        let qt = (q01 + t2 * q23) + t4 * (q45 + t2 * q67);
        let vh1 = F2::splat(at.vh0) + qv * at.a_cb * (F2::splat(1.0) - tb * qt);
        let ok =
            at.series_ok & t.abs().le_bits(F2::splat(SERIES_T_MAX)) & (vh1 * F2::splat(at.sh)).gt_bits(F2::splat(0.0));
        let [rising, falling] = vh1.get();
        if q_ext < 0.0 {
            (falling, ok & 2 != 0)
        } else {
            (rising, ok & 1 != 0)
        }
    }

    /// The CEMF solve where the series does not apply (a zero crossing of Vh, a start at
    /// 0, `|t|` or `kappa` beyond the series' range, voltage drive). For charge drive the
    /// loop is solved by Newton's method with the exact slope at the current end
    /// (`1 + Cz (a - beta s Vh - gamma |Vh|)`) from the root of its second-order expansion,
    /// until the step is at rounding level (2-4 steps), so this solve and the series agree to
    /// rounding where they meet: the simulated stage is a continuous function of its
    /// parameters (identification differentiates it numerically).
    #[cold]
    #[inline(never)]
    fn cemf_general<const T: bool>(&self, at: &CemfStart, q_ext: f64) -> f64 {
        let p = &self.params;
        let vh0 = at.vh0;
        if q_ext == 0.0 {
            return vh0;
        }
        let bw = |dq: f64| self.cemf_increment(at, dq);
        if !self.charge::<T>() {
            return bw(q_ext);
        }
        let cz = p.capacitance;
        let i = (q_ext < 0.0) as usize;
        let inv_b = at.inv_b[i];
        // With Vh ~ vh0 + g0 dq (1 - c dq / 2), c = beta s + gamma sign(vh0), the balance
        // b dq - e dq^2 = q_ext (b = 1 + Cz g0, e = Cz c g0 / 2) has the root
        // dq = l (1 + k + 2 k^2 + ...), l = q_ext / b, k = e l / b: the start.
        let s = if i == 0 { 1.0 } else { -1.0 };
        let half_czcg = 0.5 * cz * (p.hyst_beta * s + p.hyst_gamma * crate::num::math::sign(vh0)) * at.g[i];
        let lin = q_ext * inv_b;
        let k = half_czcg * lin * inv_b;
        let mut dq = if abs(k) < 0.1 { lin * (1.0 + k * (1.0 + 2.0 * k)) } else { lin };
        let mut vh = bw(dq);
        // dq has the sign of q_ext (the loop's left side increases from 0), so the slope law
        // is the one of s throughout
        for _ in 0..12 {
            let r = dq - q_ext + cz * (vh - vh0);
            let slope = 1.0 + cz * (p.hyst_alpha - p.hyst_beta * s * vh - p.hyst_gamma * abs(vh));
            if !(slope > 0.0) {
                break;
            }
            let step = r / slope;
            let next = dq - step;
            if !next.is_finite() || next * s <= 0.0 {
                break;
            }
            dq = next;
            vh = bw(dq);
            if abs(step) <= 4.0 * f64::EPSILON * abs(dq) {
                break;
            }
        }
        vh
    }

    /// The exact Bouc–Wen increment of the CEMF voltage from `vh0` for a drive increment
    /// `dq`, with its common case (no zero crossing of Vh) inline.
    #[inline(always)]
    fn cemf_increment(&self, at: &CemfStart, dq: f64) -> f64 {
        let vh0 = at.vh0;
        if vh0 != 0.0 {
            // vh0 + (a - c vh0) dq phi1(c dq), c = beta sign(dq) + gamma sign(vh0)
            let j = if dq > 0.0 { 0 } else { 1 };
            let end = vh0 + at.a_c[j] * dq * crate::hysteresis::differential::phi1(at.c[j] * dq);
            if end * at.sh > 0.0 {
                return end;
            }
        }
        let p = &self.params;
        bouc_wen_1_exact(vh0, dq, p.hyst_alpha, p.hyst_beta, p.hyst_gamma)
    }

    /// Amplifier output after `h` toward command `u`; returns `(va1, exponential)` where
    /// `exponential` says the path was the unlimited first-order response (or ideal).
    #[inline(always)]
    fn amplifier<const T: bool>(&self, lv: &Level, va0: f64, u: f64) -> (f64, bool) {
        let p = &self.params;
        let slew = p.amp_slew;
        if self.ideal_amp::<T>() {
            if slew.is_infinite() {
                return (u, true);
            }
            let step = slew * lv.h;
            let d = u - va0;
            return (if abs(d) <= step { u } else { va0 + step * crate::num::math::sign(d) }, false);
        }
        let gap = u - va0;
        if (!T && slew.is_infinite()) || abs(gap) <= self.slew_tau {
            return (u - gap * lv.amp_decay, true);
        }
        // slew-limited ramp until |u - Va| = slew * tau, then the exponential
        let s = crate::num::math::sign(gap);
        let t_ramp = (abs(gap) - self.slew_tau) / slew;
        if t_ramp >= lv.h {
            (va0 + s * slew * lv.h, false)
        } else {
            let rest = lv.h - t_ramp;
            (u - s * slew * self.amp_tau * exp(-rest / self.amp_tau), false)
        }
    }

    /// Advance one controller period with command `u` (saturated to the amplifier range).
    /// Returns the position at the end of the period.
    pub fn advance(&self, st: &mut StageState, u: f64) -> f64 {
        self.advance_with(st, u, &mut NoExtra)
    }

    /// [`Stage::advance`] with the structure `extra` (see [`Extra`]); returns the stack's
    /// displacement at the end of the period (`extra.position` of it is what a sensor sees).
    pub fn advance_with<E: Extra>(&self, st: &mut StageState, u: f64, extra: &mut E) -> f64 {
        if self.typical {
            self.advance_t::<true, E>(st, u, extra)
        } else {
            self.advance_t::<false, E>(st, u, extra)
        }
    }

    #[inline(always)]
    fn advance_t<const T: bool, E: Extra>(&self, st: &mut StageState, u: f64, e: &mut E) -> f64 {
        match self.params.creep_terms {
            0 => self.advance_n::<0, T, E>(st, u, e),
            1 => self.advance_n::<1, T, E>(st, u, e),
            2 => self.advance_n::<2, T, E>(st, u, e),
            3 => self.advance_n::<3, T, E>(st, u, e),
            4 => self.advance_n::<4, T, E>(st, u, e),
            5 => self.advance_n::<5, T, E>(st, u, e),
            6 => self.advance_n::<6, T, E>(st, u, e),
            7 => self.advance_n::<7, T, E>(st, u, e),
            _ => self.advance_n::<MAX_CREEP, T, E>(st, u, e),
        }
    }

    /// [`Stage::advance`] with the number of creep lags a constant, `NC ==
    /// params.creep_terms`, and `T` true only for a typical stage ([`Stage::is_typical`]):
    /// loops over a whole run pick both once (see [`crate::plant::closed_loop`]).
    #[inline(always)]
    pub(crate) fn advance_n<const NC: usize, const T: bool, E: Extra>(
        &self,
        st: &mut StageState,
        u: f64,
        e: &mut E,
    ) -> f64 {
        let vcr = self.creep_voltage::<NC>(st);
        self.advance_from::<NC, T, E>(st, u, vcr, e);
        st.x
    }

    /// The creep voltage `sum_j c_j w_j` of a state, summed in that order from 0.
    #[inline(always)]
    pub(crate) fn creep_voltage<const NC: usize>(&self, st: &StageState) -> f64 {
        debug_assert_eq!(NC, self.params.creep_terms);
        let mut vcr = 0.0;
        for j in 0..NC {
            vcr += self.params.creep_weights[j] * st.creep[j];
        }
        vcr
    }

    /// [`Stage::advance_n`] given `vcr = creep_voltage(st)`; returns `creep_voltage` of the
    /// new state (the same sum, carried rather than computed again: a loop over periods
    /// passes it on).
    #[inline(always)]
    pub(crate) fn advance_from<const NC: usize, const T: bool, E: Extra>(
        &self,
        st: &mut StageState,
        u: f64,
        vcr: f64,
        e: &mut E,
    ) -> f64 {
        debug_assert_eq!(NC, self.params.creep_terms);
        debug_assert!(!T || self.typical);
        let u = self.saturate(if E::ACTIVE { e.command(u) } else { u });
        if !T && self.amp_steps && u != st.va {
            // the voltage steps at the start of the period: charge jumps, position does not
            st.vh = match if E::ACTIVE { e.input_vh(u) } else { None } {
                Some(vh) => vh,
                None => self.cemf::<T>(&self.cemf_start::<T>(st.vh), 0.0, st.va, u),
            };
            st.va = u;
        }
        let level = self.refinement::<T>(st, u, vcr);
        let lv = &self.levels[level];
        let count = self.substeps << level;
        if count == 1 {
            // the common case on its own: nothing to hoist out of a loop
            let vcr = self.substep::<NC, T, E>(lv, level, st, u, vcr, e);
            if E::ACTIVE {
                e.end_period(st.va);
            }
            return vcr;
        }
        let mut vcr = vcr;
        for _ in 0..count {
            vcr = self.substep::<NC, T, E>(lv, level, st, u, vcr, e);
        }
        if E::ACTIVE {
            e.end_period(st.va);
        }
        vcr
    }

    /// Refinement level for this period: the charge the CEMF will see, estimated from the
    /// amplifier's remaining travel and the current velocity, split finely enough.
    #[inline(always)]
    fn refinement<const T: bool>(&self, st: &StageState, u: f64, vcr: f64) -> usize {
        if !T && self.tolerance.is_infinite() {
            return 0;
        }
        let p = &self.params;
        let travel = if self.ideal_amp::<T>() { 0.0 } else { abs(u - st.va) };
        // The stack may swing inside the period even when the period starts at rest (the
        // resonance rings after a step): bound the motion by the velocity plus the
        // distance from the quasi-static position times the natural frequency, plus the
        // quasi-static motion the amplifier's travel causes.
        let x_static = self.static_gain * (st.va - st.vh + vcr + p.electrostriction * st.va * st.va);
        let motion = (abs(st.v) + self.omega_n * abs(st.x - x_static)) * self.ts + self.static_gain * travel;
        let drive = if self.charge::<T>() { p.capacitance * travel + p.tem * motion } else { travel };
        // dimensionless nonlinearity per period: the CEMF exponent change, and the relative
        // change of the electrostrictive gain (its force is first-order held too)
        let change = self.refine_hyst * drive + self.refine_e2 * travel;
        // (x / 1 is exactly x)
        let exponent = if self.substeps == 1 { change } else { change / self.substeps as f64 };
        let mut level = 0;
        let mut limit = self.tolerance;
        while exponent > limit && level + 1 < LEVELS {
            level += 1;
            limit *= 2.0;
        }
        level
    }

    /// One sub-step; `vcr0` is the creep voltage `sum_j c_j w_j` of the state (summed in
    /// that order from 0), and the same sum at the end is returned.
    #[inline(always)]
    fn substep<const NC: usize, const T: bool, E: Extra>(
        &self,
        lv: &Level,
        level: usize,
        st: &mut StageState,
        u: f64,
        vcr0: f64,
        e: &mut E,
    ) -> f64 {
        let (va1, exponential) = self.amplifier::<T>(lv, st.va, u);
        let use3 = exponential && !self.ideal_amp::<T>();
        let (va0, x0, v0, vh0) = (st.va, st.x, st.v, st.vh);
        let mut vcr1 = 0.0;
        for j in 0..NC {
            let c = self.params.creep_weights[j];
            let w0 = st.creep[j];
            let w1 = lv.creep_e[j] * w0 + lv.creep_1me[j] * va0 + lv.creep_b[j] * (va1 - va0);
            vcr1 += c * w1;
            st.creep[j] = w1;
        }
        // the end state is affine in the end forcing d1: z1 = base + g1 d1
        let d0 = self.extra_accel(va0, vh0, vcr0, !use3);
        let (base_x, base_v, g1x, g1v) = if use3 {
            let z = lv.amp_mech.apply(&[va0, x0, v0], u, d0, 0.0);
            (z[1], z[2], lv.amp_mech.g1[1], lv.amp_mech.g1[2])
        } else {
            let z = lv.mech.apply(&[x0, v0], 0.0, d0, 0.0);
            (z[0], z[1], lv.mech.g1[0], lv.mech.g1[1])
        };
        if E::ACTIVE {
            if let Some(vh1) = e.input_vh(va1) {
                // a voltage-driven law: the end voltage is known before the motion
                let d1 = self.extra_accel(va1, vh1, vcr1, !use3);
                e.substep(&SubStep { level, va0, u, d0, d1, with_va: !use3 });
                st.x = base_x + g1x * d1;
                st.v = base_v + g1v * d1;
                st.vh = vh1;
                st.va = va1;
                return vcr1;
            }
        }
        // predictor: CEMF held; corrector: CEMF first-order held to its linearized
        // predicted end; then the exact CEMF from the corrected motion
        let at = self.cemf_start::<T>(vh0);
        let xp = base_x + g1x * self.extra_accel(va1, vh0, vcr1, !use3);
        let vh_p = self.cemf_linear::<T>(&at, xp - x0, va0, va1);
        let d1 = self.extra_accel(va1, vh_p, vcr1, !use3);
        if E::ACTIVE {
            e.substep(&SubStep { level, va0, u, d0, d1, with_va: !use3 });
        }
        let (x1, v1) = (base_x + g1x * d1, base_v + g1v * d1);
        st.vh = self.cemf::<T>(&at, x1 - x0, va0, va1);
        st.va = va1;
        st.x = x1;
        st.v = v1;
        vcr1
    }

    /// Longest sub-step length `ts / substeps`, s.
    pub fn sub_step_length(&self) -> f64 {
        self.levels[0].h
    }
}

/// Length of the flat parameter layout of [`StageParams::from_slice`].
pub const PARAM_LEN: usize = 15 + 2 * MAX_CREEP;

impl StageParams {
    /// The flat layout [`StageParams::from_slice`] reads.
    pub fn to_array(&self) -> [f64; PARAM_LEN] {
        let mut p = [0.0; PARAM_LEN];
        p[..15].copy_from_slice(&[
            self.mass,
            self.damping,
            self.stiffness,
            self.tem,
            self.capacitance,
            self.hyst_alpha,
            self.hyst_beta,
            self.hyst_gamma,
            if self.hyst_drive == HysteresisDrive::Charge { 0.0 } else { 1.0 },
            self.electrostriction,
            self.amp_min,
            self.amp_max,
            self.amp_bandwidth,
            self.amp_slew,
            self.creep_terms as f64,
        ]);
        p[15..15 + MAX_CREEP].copy_from_slice(&self.creep_taus);
        p[15 + MAX_CREEP..].copy_from_slice(&self.creep_weights);
        p
    }

    /// From the flat layout `[mass, damping, stiffness, tem, capacitance, hyst_alpha,
    /// hyst_beta, hyst_gamma, drive (0 charge, 1 voltage), electrostriction, amp_min,
    /// amp_max, amp_bandwidth, amp_slew, creep_terms, creep_taus[8], creep_weights[8]]`,
    /// validated.
    pub fn from_slice(p: &[f64]) -> Result<Self, ModelError> {
        if p.len() != PARAM_LEN {
            return Err(ModelError::Length("stage parameters", PARAM_LEN, p.len()));
        }
        let drive = match p[8] {
            0.0 => HysteresisDrive::Charge,
            1.0 => HysteresisDrive::Voltage,
            x => return Err(ModelError::NotFinite("hyst_drive (0 charge, 1 voltage)", usize::MAX, x)),
        };
        let terms = p[14];
        if !(terms >= 0.0 && terms <= MAX_CREEP as f64 && terms == libm::floor(terms)) {
            return Err(ModelError::Structure(
                "creep_terms",
                if terms.is_finite() && terms >= 0.0 { terms as usize } else { usize::MAX },
            ));
        }
        let mut taus = [1.0; MAX_CREEP];
        let mut weights = [0.0; MAX_CREEP];
        taus.copy_from_slice(&p[15..15 + MAX_CREEP]);
        weights.copy_from_slice(&p[15 + MAX_CREEP..]);
        let params = StageParams {
            mass: p[0],
            damping: p[1],
            stiffness: p[2],
            tem: p[3],
            capacitance: p[4],
            hyst_alpha: p[5],
            hyst_beta: p[6],
            hyst_gamma: p[7],
            hyst_drive: drive,
            electrostriction: p[9],
            amp_min: p[10],
            amp_max: p[11],
            amp_bandwidth: p[12],
            amp_slew: p[13],
            creep_terms: terms as usize,
            creep_taus: taus,
            creep_weights: weights,
        };
        params.validate()?;
        Ok(params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_layout_round_trips() {
        let v = StageParams::virtual_stage();
        let back = StageParams::from_slice(&v.to_array()).unwrap();
        assert_eq!(back.to_array(), v.to_array());
    }

    /// The virtual stage's CEMF (charge drive), with the capacitance scaled by `cz_scale`.
    fn stage(cz_scale: f64) -> Stage {
        let v = StageParams::virtual_stage();
        Stage::new(StageParams { capacitance: v.capacitance * cz_scale, ..v }, 1e-4, 1, 0.05).unwrap()
    }

    /// The charge loop's CEMF increment solved to rounding level: Newton on
    /// `y + K (1 - exp(-y)) = c q_ext` (exact derivative, until the step stops shrinking),
    /// then `dVh = (a - c vh0) (1 - exp(-y)) / c`.
    fn loop_reference(st: &Stage, vh0: f64, q_ext: f64) -> f64 {
        let p = &st.params;
        let s = if q_ext > 0.0 { 1.0 } else { -1.0 };
        let c = p.hyst_beta * s + p.hyst_gamma * if vh0 > 0.0 { 1.0 } else { -1.0 };
        let a_c = p.hyst_alpha - c * vh0;
        let k = p.capacitance * a_c;
        let target = c * q_ext;
        let mut y = target / (1.0 + k);
        for _ in 0..100 {
            let e = libm::exp(-y);
            let step = (y - k * libm::expm1(-y) - target) / (1.0 + k * e);
            y -= step;
            if abs(step) <= 1e-17 * abs(y) {
                break;
            }
        }
        a_c * -libm::expm1(-y) / c
    }

    /// Over the CEMF's range (|Vh| up to the envelope a / (beta + gamma) = 11.4 V), both
    /// directions and charge increments up to the series' limit, the series solve is valid
    /// and gives the increment of the loop's converged solution to 2e-15 relative (beyond
    /// the rounding of vh1 itself), and so does the general solve beyond two ulps of vh1
    /// (Newton to convergence; the solve before the series, a second-order guess plus one
    /// Newton step with the start slope, was off by up to 2.5e-6 here).
    #[test]
    fn series_solve_matches_the_converged_loop() {
        for cz_scale in [1.0, 3.0, 0.01] {
            let st = stage(cz_scale);
            let p = st.params;
            let env = p.hyst_alpha / (p.hyst_beta + p.hyst_gamma);
            let (mut worst, mut worst_general, mut n) = (0.0f64, 0.0f64, 0);
            for iv in -40..=40 {
                let vh0 = env * 0.99 * iv as f64 / 40.0 + 1e-3;
                let at = st.cemf_start::<true>(vh0);
                for dir in [1.0, -1.0] {
                    let i = usize::from(dir < 0.0);
                    // q_ext up to |t| = SERIES_T_MAX (t = c q_ext / b)
                    let q_max = SERIES_T_MAX / abs(at.cb.get()[i]);
                    for e in 0..=60 {
                        let q_ext = dir * q_max * 10f64.powf(-6.0 * e as f64 / 60.0) * 0.999;
                        let (vh1, ok) = st.cemf_series(&at, q_ext);
                        let reference = loop_reference(&st, vh0, q_ext);
                        if reference * 0.0 != 0.0 || (vh0 + reference) * vh0 <= 0.0 {
                            continue; // crosses zero: the general solve's case
                        }
                        assert!(ok, "series not taken: cz x{cz_scale} vh0 {vh0} q {q_ext}");
                        // the error beyond vh1's own rounding (half an ulp of vh1), relative
                        // to the increment
                        // (vh1 - vh0 is exact: the two are within a factor 2)
                        let ulp = f64::EPSILON * abs(vh1);
                        let err = (abs((vh1 - vh0) - reference) - 0.5 * ulp).max(0.0) / abs(reference);
                        worst = worst.max(err);
                        let general = st.cemf_general::<true>(&at, q_ext);
                        // the general solve feeds its rounded end back into the loop: allow
                        // two ulps of vh1 beyond it
                        worst_general =
                            worst_general.max((abs((general - vh0) - reference) - 2.0 * ulp).max(0.0) / abs(reference));
                        n += 1;
                    }
                }
            }
            assert!(n > 9000, "{n}");
            // measured: 3e-16 .. 4.4e-16 (x1, x3, x0.01)
            assert!(worst < 2e-15, "cz x{cz_scale}: worst relative error {worst:e}");
            assert!(worst_general < 2e-15, "cz x{cz_scale}: general solve {worst_general:e}");
        }
    }

    /// Outside its range the series declines and `cemf` takes the general solve: a start
    /// at Vh = 0, a step beyond `SERIES_T_MAX`, a zero crossing, `kappa > 1/2`, voltage
    /// drive. Inside, `cemf` is the series.
    #[test]
    fn series_declines_outside_its_range() {
        let st = stage(1.0);
        let general = |st: &Stage, at: &CemfStart, q: f64| st.cemf_general::<false>(at, q);
        let via_cemf = |st: &Stage, at: &CemfStart, q: f64| {
            // the drive is tem dx (charge, va0 = va1) or va1 - va0 (voltage drive)
            if st.params.hyst_drive == HysteresisDrive::Charge {
                st.cemf::<false>(at, q / st.params.tem, 1.0, 1.0)
            } else {
                st.cemf::<false>(at, 0.0, 0.0, q)
            }
        };
        let check_declined = |st: &Stage, vh0: f64, q: f64, why: &str| {
            let at = st.cemf_start::<false>(vh0);
            let q = st.params.tem * (q / st.params.tem); // the drive cemf computes from dx
            let (_, ok) = st.cemf_series(&at, q);
            assert!(!ok, "{why}: series taken");
            assert_eq!(via_cemf(st, &at, q).to_bits(), general(st, &at, q).to_bits(), "{why}");
        };
        check_declined(&st, 0.0, 1e-6, "vh0 = 0");
        let at = st.cemf_start::<false>(2.0);
        let q_limit = SERIES_T_MAX / abs(at.cb.get()[0]);
        check_declined(&st, 2.0, 1.01 * q_limit, "beyond t_max");
        let (v, ok) = st.cemf_series(&at, 0.99 * q_limit);
        assert!(ok);
        assert_eq!(via_cemf(&st, &at, 0.99 * q_limit).to_bits(), v.to_bits());
        // from 0.01 V a falling charge of ~1e-7 C takes Vh through zero
        let at = st.cemf_start::<false>(0.01);
        let (v, _) = st.cemf_series(&at, -2e-7);
        assert!(v < 0.0);
        check_declined(&st, 0.01, -2e-7, "zero crossing");
        // Cz x10: Cz alpha = 2.25, kappa = 0.69
        check_declined(&stage(10.0), 1.0, 1e-8, "kappa > 1/2");
        let mut p = st.params;
        p.hyst_drive = HysteresisDrive::Voltage;
        let stv = Stage::new(p, 1e-4, 1, 0.05).unwrap();
        check_declined(&stv, 1.0, 1e-8, "voltage drive");
    }
}
