//! Piezo-driven flexure stage with counter-electromotive-force (CEMF) hysteresis, creep,
//! electrostriction and a drive amplifier (SPEC §2.6, §3.1, §3.2). SI units throughout:
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
use crate::differential::bouc_wen_1_exact;
use crate::error::{check_scalar, ModelError};
use crate::linalg::{expm, Mat};
use crate::math::{abs, exp};


/// Most creep lags a stage can have.
pub const MAX_CREEP: usize = 8;

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
struct Discrete<const N: usize> {
    phi: Mat<N>,
    gu: [f64; N],
    g0: [f64; N],
    g1: [f64; N],
}

impl<const N: usize> Discrete<N> {
    /// Van Loan: exponential of `[[A, B, E, 0], [0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0]]`.
    fn new<const M: usize>(a: &Mat<N>, b: &[f64; N], e: &[f64; N], h: f64) -> Self {
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
    fn apply(&self, z: &[f64; N], u: f64, d0: f64, d1: f64) -> [f64; N] {
        let mut out = [0.0; N];
        for i in 0..N {
            let mut acc = self.gu[i] * u + self.g0[i] * d0 + self.g1[i] * d1;
            for j in 0..N {
                acc += self.phi[i][j] * z[j];
            }
            out[i] = acc;
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
    /// `vh0` > 0), and the loop root's `Cz c' g / 2` (`c' = beta s + gamma sign(vh0)`):
    /// constants of the sub-step, computed exactly as the CEMF solve did inline, so that
    /// solve, which waits for the motion, only selects them.
    sh: f64,
    c: [f64; 2],
    a_c: [f64; 2],
    half_czcg: [f64; 2],
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
            creep_1me[j] = -crate::math::expm1(-x);
            // b = 1 - (1 - e^-x)/x, by its series where the difference would cancel
            creep_b[j] = if x < 1e-3 {
                x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0 - x / 120.0)))
            } else {
                1.0 + crate::math::expm1(-x) / x
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
    /// Check every parameter is physical.
    pub fn validate(&self) -> Result<(), ModelError> {
        for (name, x) in [
            ("mass", self.mass),
            ("stiffness", self.stiffness),
            ("tem", self.tem),
            ("capacitance", self.capacitance),
        ] {
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
        let omega_n = crate::math::sqrt(p.stiffness / p.mass);
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
        crate::math::clamp(u, self.params.amp_min, self.params.amp_max)
    }

    /// Forcing (acceleration) that is not in the exact linear part.
    #[inline(always)]
    fn extra_accel(&self, va: f64, vh: f64, vcr: f64, with_va: bool) -> f64 {
        let lin = if with_va { va } else { 0.0 };
        self.accel_gain * (lin - vh + vcr + self.params.electrostriction * va * va)
    }

    /// Slope `dVh/dq` of the CEMF law at `vh` for a charge increment of sign `s`.
    #[inline(always)]
    fn cemf_slope(&self, vh: f64, s: f64) -> f64 {
        let p = &self.params;
        p.hyst_alpha - p.hyst_beta * s * vh - p.hyst_gamma * abs(vh)
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
    /// start, for a rising (`[0]`) and a falling (`[1]`) charge: computed from the start
    /// state alone, so no division waits for the motion.
    #[inline(always)]
    fn cemf_start<const T: bool>(&self, vh0: f64) -> CemfStart {
        let p = &self.params;
        let g = [self.cemf_slope(vh0, 1.0), self.cemf_slope(vh0, -1.0)];
        let cz = if self.charge::<T>() { p.capacitance } else { 0.0 };
        let (a, beta, gamma) = (p.hyst_alpha, p.hyst_beta, p.hyst_gamma);
        let sh = if vh0 > 0.0 { 1.0 } else { -1.0 };
        let c = [beta * 1.0 + gamma * sh, beta * -1.0 + gamma * sh];
        let sv = crate::math::sign(vh0);
        let half_cz = 0.5 * p.capacitance;
        CemfStart {
            vh0,
            g,
            inv_b: [1.0 / (1.0 + cz * g[0]), 1.0 / (1.0 + cz * g[1])],
            sh,
            c,
            a_c: [a - c[0] * vh0, a - c[1] * vh0],
            half_czcg: [half_cz * (beta * 1.0 + gamma * sv) * g[0], half_cz * (beta * -1.0 + gamma * sv) * g[1]],
        }
    }

    /// First-order estimate of the CEMF voltage after the motion (no exponentials): the
    /// predictor's value.
    #[inline(always)]
    fn cemf_linear<const T: bool>(&self, at: &CemfStart, dx: f64, va0: f64, va1: f64) -> f64 {
        let q = self.drive_increment::<T>(dx, va0, va1);
        let i = (q < 0.0) as usize;
        at.vh0 + at.g[i] * q * at.inv_b[i]
    }

    /// CEMF voltage after the stack moved by `dx` while the amplifier went `va0 -> va1`,
    /// through the exact Bouc–Wen increment. For charge drive the loop
    /// `dq = q_ext - Cz dVh`, `dVh = BW(vh0, dq) - vh0` is solved from its second-order
    /// expansion, refined by one Newton step when that is not already at rounding level.
    #[inline(always)]
    fn cemf<const T: bool>(&self, at: &CemfStart, dx: f64, va0: f64, va1: f64) -> f64 {
        let p = &self.params;
        let vh0 = at.vh0;
        let q_ext = self.drive_increment::<T>(dx, va0, va1);
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
        // dq = l (1 + k + 2 k^2 + ...), l = q_ext / b, k = e l / b: a guess off by O(k^3).
        let lin = q_ext * inv_b;
        let k = at.half_czcg[i] * lin * inv_b;
        let mut dq = if abs(k) < 0.1 { lin * (1.0 + k * (1.0 + 2.0 * k)) } else { lin };
        // below |k| = 1e-4 the guess is within 1e-12 relative (the common case of small
        // sub-steps); otherwise one Newton step with the starting slope (its own error is
        // second order) takes the residual to rounding level
        if abs(k) < 1e-4 {
            return bw(dq);
        }
        let vh = bw(dq);
        let r = dq - q_ext + cz * (vh - vh0);
        dq -= r * inv_b;
        bw(dq)
    }

    /// The exact Bouc–Wen increment of the CEMF voltage from `vh0` for a drive increment
    /// `dq`, with its common case (no zero crossing of Vh) inline.
    #[inline(always)]
    fn cemf_increment(&self, at: &CemfStart, dq: f64) -> f64 {
        let vh0 = at.vh0;
        if vh0 != 0.0 {
            // vh0 + (a - c vh0) dq phi1(c dq), c = beta sign(dq) + gamma sign(vh0)
            let j = if dq > 0.0 { 0 } else { 1 };
            let end = vh0 + at.a_c[j] * dq * crate::differential::phi1(at.c[j] * dq);
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
            return (if abs(d) <= step { u } else { va0 + step * crate::math::sign(d) }, false);
        }
        let gap = u - va0;
        if (!T && slew.is_infinite()) || abs(gap) <= self.slew_tau {
            return (u - gap * lv.amp_decay, true);
        }
        // slew-limited ramp until |u - Va| = slew * tau, then the exponential
        let s = crate::math::sign(gap);
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
        if self.typical {
            self.advance_t::<true>(st, u)
        } else {
            self.advance_t::<false>(st, u)
        }
    }

    #[inline(always)]
    fn advance_t<const T: bool>(&self, st: &mut StageState, u: f64) -> f64 {
        match self.params.creep_terms {
            0 => self.advance_n::<0, T>(st, u),
            1 => self.advance_n::<1, T>(st, u),
            2 => self.advance_n::<2, T>(st, u),
            3 => self.advance_n::<3, T>(st, u),
            4 => self.advance_n::<4, T>(st, u),
            5 => self.advance_n::<5, T>(st, u),
            6 => self.advance_n::<6, T>(st, u),
            7 => self.advance_n::<7, T>(st, u),
            _ => self.advance_n::<MAX_CREEP, T>(st, u),
        }
    }

    /// [`Stage::advance`] with the number of creep lags a constant, `NC ==
    /// params.creep_terms`, and `T` true only for a typical stage ([`Stage::is_typical`]):
    /// loops over a whole run pick both once (see [`crate::closed_loop`]).
    #[inline(always)]
    pub(crate) fn advance_n<const NC: usize, const T: bool>(&self, st: &mut StageState, u: f64) -> f64 {
        let vcr = self.creep_voltage::<NC>(st);
        self.advance_from::<NC, T>(st, u, vcr);
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
    pub(crate) fn advance_from<const NC: usize, const T: bool>(&self, st: &mut StageState, u: f64, vcr: f64) -> f64 {
        debug_assert_eq!(NC, self.params.creep_terms);
        debug_assert!(!T || self.typical);
        let u = self.saturate(u);
        if !T && self.amp_steps && u != st.va {
            // the voltage steps at the start of the period: charge jumps, position does not
            st.vh = self.cemf::<T>(&self.cemf_start::<T>(st.vh), 0.0, st.va, u);
            st.va = u;
        }
        let level = self.refinement::<T>(st, u, vcr);
        let lv = &self.levels[level];
        let count = self.substeps << level;
        if count == 1 {
            // the common case on its own: nothing to hoist out of a loop
            return self.substep::<NC, T>(lv, st, u, vcr);
        }
        let mut vcr = vcr;
        for _ in 0..count {
            vcr = self.substep::<NC, T>(lv, st, u, vcr);
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
    fn substep<const NC: usize, const T: bool>(&self, lv: &Level, st: &mut StageState, u: f64, vcr0: f64) -> f64 {
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
        // predictor: CEMF held; corrector: CEMF first-order held to its linearized
        // predicted end; then the exact CEMF from the corrected motion
        let at = self.cemf_start::<T>(vh0);
        let xp = base_x + g1x * self.extra_accel(va1, vh0, vcr1, !use3);
        let vh_p = self.cemf_linear::<T>(&at, xp - x0, va0, va1);
        let d1 = self.extra_accel(va1, vh_p, vcr1, !use3);
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
    /// From the flat layout `[mass, damping, stiffness, tem, capacitance, hyst_alpha,
    /// hyst_beta, hyst_gamma, drive (0 charge, 1 voltage), electrostriction, amp_min,
    /// amp_max, amp_bandwidth, amp_slew, creep_terms, creep_taus[8], creep_weights[8]]`,
    /// validated.
    pub fn from_slice(p: &[f64]) -> Result<Self, ModelError> {
        if p.len() != PARAM_LEN {
            return Err(ModelError::Length("stage parameters", PARAM_LEN, p.len()));
        }
        let drive = match p[8] {
            x if x == 0.0 => HysteresisDrive::Charge,
            x if x == 1.0 => HysteresisDrive::Voltage,
            x => return Err(ModelError::NotFinite("hyst_drive (0 charge, 1 voltage)", usize::MAX, x)),
        };
        let terms = p[14];
        if !(terms >= 0.0 && terms <= MAX_CREEP as f64 && terms == libm::floor(terms)) {
            return Err(ModelError::Structure("creep_terms", if terms.is_finite() && terms >= 0.0 { terms as usize } else { usize::MAX }));
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
