//! The Bouc–Wen hysteretic benchmark system (Noël & Schoukens 2016), docs/spec.md §3.3.
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
//! record at 15 kHz the residual's slope stays within 4 % of 1). For `nu = 1` (the
//! benchmark) the equation is a quadratic on each quadrant of `(sign y', sign z)` and is
//! solved in closed form (Newton's method remains the fallback): 65 instead of 105 ns per
//! step.
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

    /// The benchmark's true parameters (docs/spec.md §3.3).
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

    /// Validate a configuration built as a struct literal (often
    /// `BoucWenBenchmark { mass: 3.0, ..BoucWenBenchmark::NOEL_SCHOUKENS }`); returns it
    /// unchanged. Errors name the parameter and its value.
    pub fn validated(self) -> Result<Self, ModelError> {
        let BoucWenBenchmark { mass, damping, stiffness, alpha, beta, gamma, delta, nu } = self;
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
        for (name, v) in [("damping", damping), ("stiffness", stiffness), ("alpha", alpha), ("beta", beta)] {
            if v < 0.0 {
                return Err(ModelError::Negative(name, usize::MAX, v));
            }
        }
        if !(nu >= 1.0) {
            return Err(ModelError::NotPositive("nu (must be >= 1)", usize::MAX, nu));
        }
        Ok(self)
    }

    /// Build from `[mass, damping, stiffness, alpha, beta, gamma, delta, nu]`.
    pub fn from_slice(p: &[f64]) -> Result<Self, ModelError> {
        if p.len() != Self::PARAM_LEN {
            return Err(ModelError::Length("params", Self::PARAM_LEN, p.len()));
        }
        let [mass, damping, stiffness, alpha, beta, gamma, delta, nu] =
            [p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]];
        BoucWenBenchmark { mass, damping, stiffness, alpha, beta, gamma, delta, nu }.validated()
    }

    /// The parameters as `[mass, damping, stiffness, alpha, beta, gamma, delta, nu]`.
    pub fn to_array(&self) -> [f64; 8] {
        [self.mass, self.damping, self.stiffness, self.alpha, self.beta, self.gamma, self.delta, self.nu]
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
        State { y: s[0], v: s[1], a: s[2], z: s[3] }
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
        if c.nu == 1.0 {
            if let Some(zq) = self.solve_nu1(base, v0, q, z) {
                z = zq;
                ok = true;
            }
        }
        for _ in 0..if ok { 0 } else { NEWTON_MAX } {
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

impl Newmark {
    /// For `nu = 1` the residual `g(z) = z - base - h/2 f(v0 - q z, z)` is a quadratic in
    /// `z` on each quadrant of signs `(sign v, sign z)`: with `kappa = beta (gamma sv +
    /// delta sz)`, `f = v (alpha - kappa z)` and `g(z) = -A z² + B z - C`,
    /// `A = h/2 kappa q`, `B = 1 + h/2 (kappa v0 + alpha q)`, `C = base + h/2 alpha v0`.
    /// The root where `g` rises (`g' = sqrt(B² - 4AC) >= 0`, the one Newton's method finds)
    /// is `2C / (B + sqrt(B² - 4AC))`, free of cancellation. The quadrant of the predictor
    /// `z_guess` is tried first; the root is kept when it lies in its quadrant (on a
    /// boundary the neighbouring quadratics agree). `None` when no quadrant has one (then
    /// the caller's Newton iteration decides).
    #[inline(always)]
    fn solve_nu1(&self, base: f64, v0: f64, q: f64, z_guess: f64) -> Option<f64> {
        let c = &self.cfg;
        let hh = 0.5 * self.h;
        let sz0 = if z_guess < 0.0 { -1.0 } else { 1.0 };
        let sv0 = if v0 - q * z_guess < 0.0 { -1.0 } else { 1.0 };
        let cc = base + hh * c.alpha * v0;
        let aq = hh * c.alpha * q;
        for (sv, sz) in [(sv0, sz0), (sv0, -sz0), (-sv0, sz0), (-sv0, -sz0)] {
            let kappa = c.beta * (c.gamma * sv + c.delta * sz);
            let a = hh * kappa * q;
            let b = 1.0 + hh * kappa * v0 + aq;
            let d = b * b - 4.0 * a * cc;
            if !(b > 0.0) || !(d >= 0.0) {
                continue;
            }
            let z = 2.0 * cc / (b + libm::sqrt(d));
            if z.is_finite() && z * sz >= 0.0 && (v0 - q * z) * sv >= 0.0 {
                return Some(z);
            }
        }
        None
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

/// Step `state` over the inputs `u[i] = u(t_0 + (i+1) h)`, handing the state after each
/// step to `sink(i, state)`. Returns the index of the first step whose implicit equation was
/// not solved to tolerance, if any; with `stop_at_failure` the run ends there (after the
/// failed step has been handed to `sink`).
#[inline(always)]
fn run(
    stepper: &Newmark,
    state: &mut State,
    u: &[f64],
    stop_at_failure: bool,
    mut sink: impl FnMut(usize, &State),
) -> Option<usize> {
    let mut failed = None;
    for (k, &uk) in u.iter().enumerate() {
        let ok = stepper.step(state, uk);
        sink(k, state);
        if !ok && failed.is_none() {
            failed = Some(k);
            if stop_at_failure {
                break;
            }
        }
    }
    failed
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
    Ok(run(stepper, state, u, false, |k, s| {
        y[k] = s.y;
        z[k] = s.z;
    }))
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
        let ideal = if m == 0.0 { wn } else { libm::sin(PI * wn * m) / (PI * m) };
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

/// Length of the `work` slice [`decimate_cascade`] needs for `n` samples and `factor`:
/// the output of the first stage when there are two stages or more, else 0.
pub fn cascade_work_len(n: usize, factor: usize) -> usize {
    let mut primes = [0usize; 64];
    let np = prime_factors(factor.max(1), &mut primes);
    if np >= 2 {
        decimated_len(n, primes[0])
    } else {
        0
    }
}

/// [`decimate_fir`] for each prime factor `p` of `factor` in increasing order (the official
/// generator's decimation; 20 = 2·2·5), into `out` of length
/// [`decimated_len`]`(x.len(), factor)`. `x` is overwritten (the stages alternate between
/// `x` and `work`, of length at least [`cascade_work_len`]); `factor = 1` copies.
pub fn decimate_cascade(x: &mut [f64], factor: usize, work: &mut [f64], out: &mut [f64]) -> Result<(), ModelError> {
    if factor == 0 {
        return Err(ModelError::Structure("factor", 0));
    }
    let want = decimated_len(x.len(), factor);
    if out.len() != want {
        return Err(ModelError::Length("out", want, out.len()));
    }
    let need = cascade_work_len(x.len(), factor);
    if work.len() < need {
        return Err(ModelError::Length("work", need, work.len()));
    }
    let mut primes = [0usize; 64];
    let np = prime_factors(factor, &mut primes);
    if np == 0 {
        out.copy_from_slice(x);
        return Ok(());
    }
    // the current signal lives in x[..len] (in_x) or work[..len]
    let mut len = x.len();
    let mut in_x = true;
    for (i, &p) in primes[..np].iter().enumerate() {
        let next = decimated_len(len, p);
        if i + 1 == np {
            let src = if in_x { &x[..len] } else { &work[..len] };
            decimate_fir(src, p, out)?;
        } else if in_x {
            decimate_fir(&x[..len], p, &mut work[..next])?;
        } else {
            decimate_fir(&work[..len], p, &mut x[..next])?;
        }
        in_x = !in_x;
        len = next;
    }
    Ok(())
}

/// Why a record simulation ([`simulate_record`]) produced no usable output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RecordFailure {
    /// The implicit step at this internal sample could not be solved to tolerance.
    Unsolved(usize),
    /// The displacement is not finite at this internal sample.
    Diverged(usize),
}

/// The buffers of one record simulation ([`simulate_record`], [`record_rmse`]), allocated once
/// per input length and decimation factor and reused across parameter sets.
#[derive(Debug)]
pub struct RecordBuffers<'b> {
    /// Displacement at every internal sample, m: same length as the high-rate input.
    pub fine: &'b mut [f64],
    /// Scratch of the decimation cascade: at least [`cascade_work_len`] long.
    pub work: &'b mut [f64],
    /// The decimated record, m: [`decimated_len`] long.
    pub out: &'b mut [f64],
}

/// The benchmark's simulation of a record, as the official generator and
/// `piezohyst.boucwen_benchmark.BoucWenBenchmark.simulate`: from rest at `t_0` (the initial
/// acceleration solves the equation of motion under `u_fine[0]`), integrate over the
/// high-rate input `u_fine` (`u_fine[i]` is the force at `t_0 + i h`, N; its length a
/// multiple of `factor` for a whole record), write the displacement at every internal
/// sample to `buffers.fine` (`fine[0] = 0`), then FIR-decimate by `factor`
/// ([`decimate_cascade`], `fine` is overwritten) into `buffers.out`. The run stops at the
/// first implicit step that cannot be solved or the first non-finite displacement, and
/// `out` is then not written.
pub fn simulate_record(
    stepper: &Newmark,
    u_fine: &[f64],
    factor: usize,
    buffers: &mut RecordBuffers<'_>,
) -> Result<Result<(), RecordFailure>, ModelError> {
    let RecordBuffers { fine, work, out } = buffers;
    if u_fine.is_empty() {
        return Err(ModelError::Length("u_fine", 1, 0));
    }
    if fine.len() != u_fine.len() {
        return Err(ModelError::Length("fine", u_fine.len(), fine.len()));
    }
    if factor == 0 {
        return Err(ModelError::Structure("factor", 0));
    }
    let want = decimated_len(u_fine.len(), factor);
    if out.len() != want {
        return Err(ModelError::Length("out", want, out.len()));
    }
    let need = cascade_work_len(u_fine.len(), factor);
    if work.len() < need {
        return Err(ModelError::Length("work", need, work.len()));
    }
    check_finite("u_fine", u_fine)?;
    let mut state = State::at(&stepper.cfg, 0.0, 0.0, 0.0, u_fine[0]);
    fine[0] = state.y;
    let rest = &mut fine[1..];
    let mut diverged = None;
    let failed = run(stepper, &mut state, &u_fine[1..], true, |k, s| {
        rest[k] = s.y;
        if !s.y.is_finite() && diverged.is_none() {
            diverged = Some(k + 1);
        }
    });
    if let Some(k) = failed {
        return Ok(Err(RecordFailure::Unsolved(k + 1)));
    }
    if let Some(k) = diverged {
        return Ok(Err(RecordFailure::Diverged(k)));
    }
    decimate_cascade(fine, factor, work, out)?;
    Ok(Ok(()))
}

/// RMSE (m) between `out[skip..skip + target.len()]` of [`simulate_record`] and `target`;
/// `+inf` when the simulation fails or diverges. The sum runs in sample order, so the value
/// depends only on the arguments. `target` must not be empty and must fit in the output.
pub fn record_rmse(
    stepper: &Newmark,
    u_fine: &[f64],
    factor: usize,
    target: &[f64],
    skip: usize,
    buffers: &mut RecordBuffers<'_>,
) -> Result<f64, ModelError> {
    let n_out = decimated_len(u_fine.len(), factor.max(1));
    if target.is_empty() || skip + target.len() > n_out {
        return Err(ModelError::Length("target", n_out.saturating_sub(skip), target.len()));
    }
    if simulate_record(stepper, u_fine, factor, buffers)?.is_err() {
        return Ok(f64::INFINITY);
    }
    let mut sse = 0.0;
    for (&o, &t) in buffers.out[skip..skip + target.len()].iter().zip(target) {
        let e = o - t;
        sse += e * e;
    }
    let r = libm::sqrt(sse / target.len() as f64);
    Ok(if r.is_finite() { r } else { f64::INFINITY })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn force(n: usize) -> [f64; 4000] {
        let mut u = [0.0; 4000];
        for (i, ui) in u.iter_mut().enumerate().take(n) {
            let t = i as f64 / 15_000.0;
            *ui = 40.0 * libm::sin(2.0 * core::f64::consts::PI * 7.0 * t)
                + 20.0 * libm::sin(2.0 * core::f64::consts::PI * 31.0 * t + 0.3);
        }
        u
    }

    #[test]
    fn cascade_equals_stagewise_decimation() {
        let u = force(4000);
        let x: [f64; 4000] = core::array::from_fn(|i| u[i] * (1.0 + (i % 7) as f64 * 1e-3));
        // stage by stage: 2, 2, 5
        let mut a = [0.0; 2000];
        let mut b = [0.0; 1000];
        let mut c = [0.0; 200];
        decimate_fir(&x, 2, &mut a).unwrap();
        decimate_fir(&a, 2, &mut b).unwrap();
        decimate_fir(&b, 5, &mut c).unwrap();
        let mut xs = x;
        let mut work = [0.0; 2000];
        let mut out = [0.0; 200];
        assert_eq!(cascade_work_len(4000, 20), 2000);
        decimate_cascade(&mut xs, 20, &mut work, &mut out).unwrap();
        assert_eq!(out, c);
        // one stage needs no work; factor 1 copies
        let mut xs = x;
        let mut out5 = [0.0; 800];
        let mut ref5 = [0.0; 800];
        decimate_fir(&x, 5, &mut ref5).unwrap();
        decimate_cascade(&mut xs, 5, &mut [], &mut out5).unwrap();
        assert_eq!(out5, ref5);
        let mut xs = x;
        let mut out1 = [0.0; 4000];
        decimate_cascade(&mut xs, 1, &mut [], &mut out1).unwrap();
        assert_eq!(out1, x);
        assert!(decimate_cascade(&mut xs, 20, &mut [0.0; 10], &mut out).is_err());
        assert!(decimate_cascade(&mut xs, 0, &mut work, &mut out).is_err());
    }

    #[test]
    fn record_is_integrate_then_cascade() {
        let u = force(4000);
        let cfg = BoucWenBenchmark::NOEL_SCHOUKENS;
        let nm = Newmark::new(cfg, 1.0 / 15_000.0).unwrap();
        // the reference path: integrate from rest, prepend y0, decimate stage by stage
        let mut s = State::at(&cfg, 0.0, 0.0, 0.0, u[0]);
        let mut y = [0.0; 4000];
        let mut z = [0.0; 3999];
        assert_eq!(integrate(&nm, &mut s, &u[1..], &mut y[1..], &mut z).unwrap(), None);
        let mut work = [0.0; 2000];
        let mut expect = [0.0; 200];
        decimate_cascade(&mut y, 20, &mut work, &mut expect).unwrap();
        let mut fine = [0.0; 4000];
        let mut out = [0.0; 200];
        simulate_record(&nm, &u, 20, &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out })
            .unwrap()
            .unwrap();
        assert_eq!(out, expect);
        let r = record_rmse(
            &nm,
            &u,
            20,
            &expect[50..],
            50,
            &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out },
        )
        .unwrap();
        assert_eq!(r, 0.0);
        let mut shifted = [0.0; 150];
        for (t, e) in shifted.iter_mut().zip(&expect[50..]) {
            *t = e + 1e-6;
        }
        let r = record_rmse(
            &nm,
            &u,
            20,
            &shifted,
            50,
            &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out },
        )
        .unwrap();
        assert!((r - 1e-6).abs() < 1e-15, "{r}");
        assert!(record_rmse(
            &nm,
            &u,
            20,
            &shifted,
            51,
            &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out }
        )
        .is_err());
        assert!(record_rmse(
            &nm,
            &u,
            20,
            &[],
            0,
            &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out }
        )
        .is_err());
    }

    /// For `nu = 1` the closed-form root solves the implicit equation of every step to
    /// round-off, in all four quadrants of `(sign y', sign z)`, and Newton's iteration from
    /// it does not move it beyond round-off.
    #[test]
    fn closed_form_step_solves_the_implicit_equation() {
        let u = force(4000);
        let cfg = BoucWenBenchmark::NOEL_SCHOUKENS;
        let nm = Newmark::new(cfg, 1.0 / 15_000.0).unwrap();
        let (h, hh) = (nm.h, 0.5 * nm.h);
        let mut s = State::at(&cfg, 0.0, 0.0, 0.0, u[0]);
        let mut quadrants = [0usize; 4];
        for &un in &u[1..] {
            let yp = s.y + h * s.v + 0.25 * h * h * s.a;
            let vp = s.v + hh * s.a;
            let r = un - cfg.damping * vp - cfg.stiffness * yp;
            let q = hh / nm.meff;
            let v0 = vp + q * r;
            let base = s.z + hh * cfg.z_rate(s.v, s.z);
            assert!(nm.step(&mut s, un));
            let z = s.z;
            let g = |z: f64| z - base - hh * cfg.z_rate(v0 - q * z, z);
            let tol = 1e-14 * (z.abs() + base.abs() + hh * (cfg.alpha * v0).abs());
            assert!(g(z).abs() <= tol, "residual {} > {tol}", g(z));
            let (_, fv, fz) = cfg.z_rate_jac(v0 - q * z, z);
            let newton = z - g(z) / (1.0 - hh * (fz - q * fv));
            assert!((newton - z).abs() <= tol);
            quadrants[usize::from(s.v < 0.0) * 2 + usize::from(z < 0.0)] += 1;
        }
        assert!(quadrants.iter().all(|&n| n > 100), "{quadrants:?}");
    }

    #[test]
    fn unresolvable_record_costs_inf() {
        let mut u = force(4000);
        for ui in u.iter_mut() {
            *ui *= 1e98;
        }
        let nm = Newmark::new(BoucWenBenchmark::NOEL_SCHOUKENS, 1.0 / 15_000.0).unwrap();
        let mut fine = [0.0; 4000];
        let mut work = [0.0; 2000];
        let mut out = [0.0; 200];
        let res = simulate_record(&nm, &u, 20, &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out })
            .unwrap();
        assert!(res.is_err(), "{res:?}");
        let r = record_rmse(
            &nm,
            &u,
            20,
            &[0.0; 200],
            0,
            &mut RecordBuffers { fine: &mut fine, work: &mut work, out: &mut out },
        )
        .unwrap();
        assert_eq!(r, f64::INFINITY);
    }
}
