//! The Bouc–Wen hysteretic benchmark system (Noël & Schoukens 2016), SPEC §3.3.
//!
//! ```text
//! mL y'' + cL y' + kL y + z = u
//! z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu)
//! ```
//!
//! Units (SI): input force `u` in N, displacement `y` in m, velocity `y'` in m/s,
//! acceleration `y''` in m/s², hysteretic force `z` in N, time step `h` in s; `mL` in kg,
//! `cL` in N·s/m, `kL` and `alpha` in N/m, `beta` in 1/m (for `nu = 1`; in general
//! N^(1-nu)/m), `gamma`, `delta` and `nu` dimensionless.
//!
//! # Integration (one step of length `h` at the internal rate, e.g. 15 kHz)
//! As the official generator: Newmark's average-acceleration rule (`γ = 1/2, β = 1/4`,
//! unconditionally stable, second order) for the mechanical part and the trapezoidal rule
//! for `z`, both implicit and solved together. The equation of motion is linear in the new
//! acceleration, so `a_{n+1}`, `y'_{n+1}` and `y_{n+1}` are affine in `z_{n+1}`; what is
//! left is one scalar equation in `z_{n+1}`, solved by Newton's method to round-off, with a
//! bracketing bisection as the fallback (not needed for the benchmark: on its training
//! record at 15 kHz the residual's slope stays within 4 % of 1).
//!
//! The input is sampled at the step ends: [`Newmark::step`] takes `u(t_{n+1})`. The state
//! ([`State`]) holds `y, y', y'', z` at `t_n`; the initial acceleration follows from the
//! equation of motion at `t_0` ([`State::at`]).
//!
//! # Decimation
//! [`decimate_fir`] is MATLAB's `decimate(x, r, 'fir')`: the 31-tap Hamming-window
//! low-pass `fir1(30, 1/r)` ([`fir1_taps`]), applied as a zero-phase (centred) filter with
//! the record extended by odd reflection about its end samples, keeping samples
//! `0, r, 2r, …`. The official generator decimates by the prime factors of the upsampling
//! factor in increasing order (20 = 2·2·5).
//!
//! Everything here is allocation-free; outputs go to caller-provided slices.
use crate::error::{check_finite, ModelError};

/// Number of taps of MATLAB's default `decimate(…, 'fir')` filter (`fir1(30, 1/r)`).
pub const FIR_TAPS: usize = 31;
/// Half the filter length: the centred filter reaches this many samples to each side.
const FIR_HALF: usize = FIR_TAPS / 2;

/// Newton iterations before the bracketing fallback.
const NEWTON_MAX: usize = 40;
/// Relative step size at which Newton's iteration has converged.
const NEWTON_TOL: f64 = 1e-14;
/// Bisection iterations of the fallback (the bracket halves each time).
const BISECT_MAX: usize = 200;

/// Parameters of the benchmark system (the configuration; the state is [`State`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoucWenBenchmark {
    /// Mass `mL`, kg (> 0).
    pub mass: f64,
    /// Viscous damping `cL`, N·s/m (>= 0).
    pub damping: f64,
    /// Linear stiffness `kL`, N/m (>= 0).
    pub stiffness: f64,
    /// Hysteretic stiffness `alpha`, N/m (>= 0).
    pub alpha: f64,
    /// Hysteresis amplitude `beta` (>= 0).
    pub beta: f64,
    /// Shape parameter `gamma` (|y'| term).
    pub gamma: f64,
    /// Shape parameter `delta` (y' term).
    pub delta: f64,
    /// Smoothness exponent `nu` (>= 1, so that the implicit step has a finite Jacobian).
    pub nu: f64,
}

impl Default for BoucWenBenchmark {
    fn default() -> Self {
        Self::NOEL_SCHOUKENS
    }
}

impl BoucWenBenchmark {
    /// Number of parameters of [`BoucWenBenchmark::from_slice`].
    pub const PARAM_LEN: usize = 8;

    /// The benchmark's true parameters (SPEC §3.3).
    pub const NOEL_SCHOUKENS: Self = BoucWenBenchmark {
        mass: 2.0,
        damping: 10.0,
        stiffness: 5e4,
        alpha: 5e4,
        beta: 1e3,
        gamma: 0.8,
        delta: -1.1,
        nu: 1.0,
    };

    /// Validate and build. Errors name the parameter and its value.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        mass: f64,
        damping: f64,
        stiffness: f64,
        alpha: f64,
        beta: f64,
        gamma: f64,
        delta: f64,
        nu: f64,
    ) -> Result<Self, ModelError> {
        let named = [
            ("mass", mass),
            ("damping", damping),
            ("stiffness", stiffness),
            ("alpha", alpha),
            ("beta", beta),
            ("gamma", gamma),
            ("delta", delta),
            ("nu", nu),
        ];
        for (name, v) in named {
            if !v.is_finite() {
                return Err(ModelError::NotFinite(name, usize::MAX, v));
            }
        }
        if !(mass > 0.0) {
            return Err(ModelError::NotPositive("mass", usize::MAX, mass));
        }
        for (name, v) in [
            ("damping", damping),
            ("stiffness", stiffness),
            ("alpha", alpha),
            ("beta", beta),
        ] {
            if v < 0.0 {
                return Err(ModelError::Negative(name, usize::MAX, v));
            }
        }
        if !(nu >= 1.0) {
            return Err(ModelError::NotPositive("nu (must be >= 1)", usize::MAX, nu));
        }
        Ok(BoucWenBenchmark {
            mass,
            damping,
            stiffness,
            alpha,
            beta,
            gamma,
            delta,
            nu,
        })
    }

    /// Build from `[mass, damping, stiffness, alpha, beta, gamma, delta, nu]`.
    pub fn from_slice(p: &[f64]) -> Result<Self, ModelError> {
        if p.len() != Self::PARAM_LEN {
            return Err(ModelError::Length("params", Self::PARAM_LEN, p.len()));
        }
        Self::new(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7])
    }

    /// The parameters as `[mass, damping, stiffness, alpha, beta, gamma, delta, nu]`.
    pub fn to_array(&self) -> [f64; 8] {
        [
            self.mass,
            self.damping,
            self.stiffness,
            self.alpha,
            self.beta,
            self.gamma,
            self.delta,
            self.nu,
        ]
    }

    /// `|z|^(nu-1)`, exactly 1 for `nu = 1` (also at `z = 0`).
    #[inline(always)]
    fn zpow(&self, az: f64) -> f64 {
        if self.nu == 1.0 {
            1.0
        } else {
            libm::pow(az, self.nu - 1.0)
        }
    }

    /// `z' = f(y', z)`, N/s.
    #[inline]
    pub fn z_rate(&self, v: f64, z: f64) -> f64 {
        let az = libm::fabs(z);
        let p = self.zpow(az);
        self.alpha * v - self.beta * (self.gamma * libm::fabs(v) * p * z + self.delta * v * p * az)
    }

    /// `(f, ∂f/∂y', ∂f/∂z)` of [`Self::z_rate`]; the kinks at `y' = 0` and `z = 0` take
    /// the one-sided derivative of the positive side.
    #[inline]
    fn z_rate_jac(&self, v: f64, z: f64) -> (f64, f64, f64) {
        let az = libm::fabs(z);
        let av = libm::fabs(v);
        let p = self.zpow(az);
        let sv = if v < 0.0 { -1.0 } else { 1.0 };
        let sz = if z < 0.0 { -1.0 } else { 1.0 };
        let f = self.alpha * v - self.beta * (self.gamma * av * p * z + self.delta * v * p * az);
        let fv = self.alpha - self.beta * (self.gamma * sv * p * z + self.delta * p * az);
        let fz = -self.beta * self.nu * p * (self.gamma * av + self.delta * v * sz);
        (f, fv, fz)
    }

    /// Right-hand side of the continuous system in the state `[y, y', z]` for input `u`:
    /// `[y', y'', z']` (for reference integrators).
    pub fn derivative(&self, x: [f64; 3], u: f64) -> [f64; 3] {
        let [y, v, z] = x;
        let a = (u - self.damping * v - self.stiffness * y - z) / self.mass;
        [v, a, self.z_rate(v, z)]
    }
}

/// State of the benchmark system at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct State {
    /// Displacement `y`, m.
    pub y: f64,
    /// Velocity `y'`, m/s.
    pub v: f64,
    /// Acceleration `y''`, m/s² (consistent with the equation of motion).
    pub a: f64,
    /// Hysteretic force `z`, N.
    pub z: f64,
}

impl State {
    /// The state with displacement `y` (m), velocity `v` (m/s) and hysteretic force `z` (N)
    /// under input `u` (N); the acceleration solves the equation of motion.
    pub fn at(cfg: &BoucWenBenchmark, y: f64, v: f64, z: f64, u: f64) -> Self {
        let a = (u - cfg.damping * v - cfg.stiffness * y - z) / cfg.mass;
        State { y, v, a, z }
    }

    /// `[y, y', y'', z]`.
    pub fn to_array(&self) -> [f64; 4] {
        [self.y, self.v, self.a, self.z]
    }

    /// From `[y, y', y'', z]`.
    pub fn from_array(s: [f64; 4]) -> Self {
        State {
            y: s[0],
            v: s[1],
            a: s[2],
            z: s[3],
        }
    }
}

/// The implicit Newmark (average acceleration) + trapezoidal-`z` step of length `h`.
#[derive(Debug, Clone, Copy)]
pub struct Newmark {
    /// The system.
    pub cfg: BoucWenBenchmark,
    /// Step, s.
    pub h: f64,
    /// Effective mass `mL + cL h/2 + kL h²/4`, kg.
    meff: f64,
}

impl Newmark {
    /// Integrator of `cfg` with time step `h` (s, > 0).
    pub fn new(cfg: BoucWenBenchmark, h: f64) -> Result<Self, ModelError> {
        if !h.is_finite() {
            return Err(ModelError::NotFinite("h", usize::MAX, h));
        }
        if !(h > 0.0) {
            return Err(ModelError::NotPositive("h", usize::MAX, h));
        }
        let meff = cfg.mass + 0.5 * h * cfg.damping + 0.25 * h * h * cfg.stiffness;
        Ok(Newmark { cfg, h, meff })
    }

    /// Advance `s` from `t_n` to `t_{n+1} = t_n + h` under the input `u_next = u(t_{n+1})`
    /// (N). Returns `false` if the implicit equation could not be solved to tolerance (the
    /// state then holds the best iterate; it is non-finite if the solution diverged).
    #[inline]
    pub fn step(&self, s: &mut State, u_next: f64) -> bool {
        let c = &self.cfg;
        let h = self.h;
        let hh = 0.5 * h;
        // Newmark predictors: y = yp + h²/4 a', v = vp + h/2 a' with a' = a_{n+1}
        let yp = s.y + h * s.v + 0.25 * h * h * s.a;
        let vp = s.v + hh * s.a;
        // equation of motion: a' = (r - z') / meff  =>  v' = v0 - q z'
        let r = u_next - c.damping * vp - c.stiffness * yp;
        let q = hh / self.meff;
        let v0 = vp + q * r;
        let f_n = c.z_rate(s.v, s.z);
        let base = s.z + hh * f_n;
        // g(z) = z - base - h/2 f(v0 - q z, z) = 0
        let eval = |z: f64| {
            let v = v0 - q * z;
            let (f, fv, fz) = c.z_rate_jac(v, z);
            (z - base - hh * f, 1.0 - hh * (fz - q * fv))
        };
        let scale = libm::fabs(s.z) + libm::fabs(h * f_n) + f64::MIN_POSITIVE;
        // explicit (Euler) predictor as the start
        let mut z = s.z + h * f_n;
        let mut ok = false;
        for _ in 0..NEWTON_MAX {
            let (g, dg) = eval(z);
            if g == 0.0 {
                ok = true;
                break;
            }
            if !(dg > 0.0) || !dg.is_finite() || !g.is_finite() {
                break;
            }
            let dz = g / dg;
            z -= dz;
            if libm::fabs(dz) <= NEWTON_TOL * (libm::fabs(z) + scale) {
                ok = true;
                break;
            }
        }
        if !ok {
            let (zb, okb) = bracket_solve(|x| eval(x).0, if z.is_finite() { z } else { s.z }, scale);
            z = zb;
            ok = okb;
        }
        let a = (r - z) / self.meff;
        s.y = yp + 0.25 * h * h * a;
        s.v = vp + hh * a;
        s.a = a;
        s.z = z;
        ok && z.is_finite()
    }
}

/// `x > 0` (the sign test of the bracketing; `x` is never 0 or NaN where it is used).
#[inline(always)]
fn pos(x: f64) -> bool {
    x > 0.0
}

/// Root of a continuous scalar function by expanding a bracket from `x0` and bisecting.
fn bracket_solve(g: impl Fn(f64) -> f64, x0: f64, scale: f64) -> (f64, bool) {
    let g0 = g(x0);
    if g0 == 0.0 {
        return (x0, true);
    }
    if !g0.is_finite() {
        return (f64::NAN, false);
    }
    // g is increasing for any reasonable step: search against the sign of g first
    let width = libm::fabs(g0) + scale;
    let d0 = if pos(g0) { -1.0 } else { 1.0 };
    for dir in [d0, -d0] {
        let mut w = width;
        for _ in 0..1100 {
            let x1 = x0 + dir * w;
            let g1 = g(x1);
            if !g1.is_finite() {
                break;
            }
            if g1 == 0.0 {
                return (x1, true);
            }
            if pos(g1) != pos(g0) {
                let (mut lo, mut hi) = if x0 < x1 { (x0, x1) } else { (x1, x0) };
                let g_lo_sign = if x0 < x1 { pos(g0) } else { pos(g1) };
                for _ in 0..BISECT_MAX {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    let gm = g(mid);
                    if gm == 0.0 {
                        return (mid, true);
                    }
                    if pos(gm) == g_lo_sign {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                return (0.5 * (lo + hi), true);
            }
            w *= 2.0;
        }
    }
    (f64::NAN, false)
}

/// Integrate from `state` (at `t_0`) over the inputs `u[i] = u(t_0 + (i+1) h)`, writing
/// `y` (m) and `z` (N) at those instants; `state` ends at the last instant. Returns the
/// index of the first step whose implicit equation was not solved to tolerance, if any
/// (all outputs are written regardless; a diverged solution shows as non-finite values).
pub fn integrate(
    stepper: &Newmark,
    state: &mut State,
    u: &[f64],
    y: &mut [f64],
    z: &mut [f64],
) -> Result<Option<usize>, ModelError> {
    if y.len() != u.len() {
        return Err(ModelError::Length("y", u.len(), y.len()));
    }
    if z.len() != u.len() {
        return Err(ModelError::Length("z", u.len(), z.len()));
    }
    check_finite("input", u)?;
    let mut failed = None;
    for (k, ((&uk, yk), zk)) in u.iter().zip(y.iter_mut()).zip(z.iter_mut()).enumerate() {
        if !stepper.step(state, uk) && failed.is_none() {
            failed = Some(k);
        }
        *yk = state.y;
        *zk = state.z;
    }
    Ok(failed)
}

/// MATLAB's `fir1(30, 1/r)`: Hamming-windowed ideal low-pass with cutoff `1/r` of the
/// Nyquist frequency, scaled to unit DC gain. `r >= 1`.
pub fn fir1_taps(r: usize) -> [f64; FIR_TAPS] {
    use core::f64::consts::PI;
    let wn = 1.0 / (r.max(1) as f64);
    let order = (FIR_TAPS - 1) as f64;
    let mut b = [0.0; FIR_TAPS];
    // computed on one half and mirrored, so the filter is exactly symmetric (zero phase)
    for n in 0..=FIR_HALF {
        let m = n as f64 - 0.5 * order;
        let ideal = if m == 0.0 {
            wn
        } else {
            libm::sin(PI * wn * m) / (PI * m)
        };
        let w = 0.54 - 0.46 * libm::cos(2.0 * PI * n as f64 / order);
        b[n] = ideal * w;
        b[FIR_TAPS - 1 - n] = b[n];
    }
    let sum: f64 = b.iter().sum();
    for bn in b.iter_mut() {
        *bn /= sum;
    }
    b
}

/// Output length of [`decimate_fir`]: `ceil(n / r)`.
pub fn decimated_len(n: usize, r: usize) -> usize {
    n.div_ceil(r.max(1))
}

/// Sample `i` of `x` extended by odd reflection about its end samples
/// (`x[-m] = 2 x[0] - x[m]`, `x[n-1+m] = 2 x[n-1] - x[n-1-m]`), as MATLAB's `decimate`
/// pads; reflections that would reach past the other end are clamped to it.
#[inline]
fn reflected(x: &[f64], i: isize) -> f64 {
    let n = x.len() as isize;
    if i < 0 {
        let m = (-i).min(n - 1) as usize;
        2.0 * x[0] - x[m]
    } else if i >= n {
        let m = (i - (n - 1)).min(n - 1) as usize;
        2.0 * x[(n - 1) as usize] - x[(n - 1) as usize - m]
    } else {
        x[i as usize]
    }
}

/// MATLAB `decimate(x, r, 'fir')`: zero-phase `fir1(30, 1/r)` low-pass, then samples
/// `0, r, 2r, …`. `out` must have length [`decimated_len`]`(x.len(), r)`; `r = 1` copies.
pub fn decimate_fir(x: &[f64], r: usize, out: &mut [f64]) -> Result<(), ModelError> {
    if r == 0 {
        return Err(ModelError::Structure("factor", 0));
    }
    let want = decimated_len(x.len(), r);
    if out.len() != want {
        return Err(ModelError::Length("out", want, out.len()));
    }
    if r == 1 {
        out.copy_from_slice(x);
        return Ok(());
    }
    let b = fir1_taps(r);
    let n = x.len();
    for (k, o) in out.iter_mut().enumerate() {
        let c = k * r;
        let mut acc = 0.0;
        if c >= FIR_HALF && c + FIR_HALF < n {
            let w = &x[c - FIR_HALF..=c + FIR_HALF];
            // b is symmetric, so the convolution equals the correlation
            for (bj, xj) in b.iter().zip(w) {
                acc += bj * xj;
            }
        } else {
            for (j, bj) in b.iter().enumerate() {
                acc += bj * reflected(x, c as isize + FIR_HALF as isize - j as isize);
            }
        }
        *o = acc;
    }
    Ok(())
}

/// Prime factors of `r` in increasing order (the stages of the official decimation),
/// written to `out`; returns how many (at most 64, the bits of `usize`).
pub fn prime_factors(mut r: usize, out: &mut [usize; 64]) -> usize {
    let mut k = 0;
    let mut p = 2;
    while r > 1 && p * p <= r {
        while r % p == 0 {
            out[k] = p;
            k += 1;
            r /= p;
        }
        p += 1;
    }
    if r > 1 {
        out[k] = r;
        k += 1;
    }
    k
}
