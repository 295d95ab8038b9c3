//! Rate-independent differential hysteresis models driven by a signal `w` (docs/spec.md §2.5):
//! Bouc–Wen, generalized Duhem (Coleman–Hodgdon) and Dahl.
//!
//! Rate independence means only the path of `w` matters, so each sample is integrated in
//! the driver's increment `dw = w(k) - w(k-1)` along a monotone (linear) path. Where a
//! closed form exists it is used, so there is no step-size error under zero-order hold:
//! Bouc–Wen with n = 1, Duhem with cubic `f`, `g`, and Dahl for any exponent.
//!
//! State layout of all three: `[hysteretic variable, w_prev]`, relaxed at `w = 0`.
use crate::error::{check_finite, check_scalar, ModelError};
use crate::hysteresis::{Hysteresis, Invertible};
use crate::num::math::{abs, exp, expm1, pow, sign};

/// `(1 - exp(-x)) / x`, with its limit 1 at 0. Below |x| = 0.03 its Taylor series to
/// x^7 is exact to rounding (the next term is under 2e-18) and needs no exponential: the
/// common case of small increments in a simulation loop.
#[inline(always)]
pub(crate) fn phi1(x: f64) -> f64 {
    if abs(x) < 0.03 {
        // Estrin's scheme: the same polynomial with a short dependency chain
        let x2 = x * x;
        let x4 = x2 * x2;
        let p01 = 1.0 - x * (1.0 / 2.0);
        let p23 = 1.0 / 6.0 - x * (1.0 / 24.0);
        let p45 = 1.0 / 120.0 - x * (1.0 / 720.0);
        let p67 = 1.0 / 5040.0 - x * (1.0 / 40320.0);
        (p01 + x2 * p23) + x4 * (p45 + x2 * p67)
    } else {
        -expm1(-x) / x
    }
}

/// Bouc–Wen in the form `dh/dw = a - beta*s*|h|^(n-1)*h - gamma*|h|^n`, `s = sign(dw)`,
/// with output `y = d*w - h` (the piezo convention of Low & Guo / Rakotondrabe; set
/// `d = 0` to read `-h`). The benchmark's `z' = alpha*y' - B*(G*|y'||z|^(nu-1) z +
/// D*y'|z|^nu)` is `a = alpha, beta = B*G, gamma = B*D, n = nu`.
#[derive(Debug, Clone, Copy)]
pub struct BoucWen {
    /// Gain `A` of the driver increment.
    pub a: f64,
    /// `beta` (sign-of-increment term).
    pub beta: f64,
    /// `gamma` (sign-of-h term).
    pub gamma: f64,
    /// Exponent `n >= 1`.
    pub n: f64,
    /// Linear output gain `d` in `y = d*w - h`.
    pub d: f64,
}

/// Sub-steps of RK4 (general n) are sized so that the local Lipschitz constant times the
/// step stays below this; the count is capped so a step always ends.
const RK4_LIPSCHITZ_STEP: f64 = 0.02;
const RK4_MAX_SUBSTEPS: f64 = 20_000.0;

impl BoucWen {
    /// Validate and build.
    pub fn new(a: f64, beta: f64, gamma: f64, n: f64, d: f64) -> Result<Self, ModelError> {
        check_finite("a/beta/gamma/n/d", &[a, beta, gamma, n, d])?;
        if !(n >= 1.0) {
            return Err(ModelError::NotPositive("n (must be >= 1)", usize::MAX, n));
        }
        Ok(BoucWen { a, beta, gamma, n, d })
    }

    /// `dh/dw` at `h` for increment sign `s`.
    #[inline]
    pub fn slope(&self, h: f64, s: f64) -> f64 {
        if self.n == 1.0 {
            self.a - (self.beta * s + self.gamma * sign(h)) * h
        } else {
            let ah = abs(h);
            let p = pow(ah, self.n - 1.0);
            self.a - self.beta * s * p * h - self.gamma * p * ah
        }
    }

    /// Advance `h` over the increment `dw`.
    pub fn advance(&self, h: f64, dw: f64) -> f64 {
        if dw == 0.0 {
            return h;
        }
        if self.n == 1.0 {
            bouc_wen_1_exact(h, dw, self.a, self.beta, self.gamma)
        } else {
            self.advance_rk4(h, dw)
        }
    }

    fn advance_rk4(&self, mut h: f64, dw: f64) -> f64 {
        let s = sign(dw);
        let bg = abs(self.beta) + abs(self.gamma);
        let h_scale = if bg > 0.0 { pow(abs(self.a) / bg, 1.0 / self.n) } else { 0.0 };
        let hh = if abs(h) > h_scale { abs(h) } else { h_scale };
        let lip = self.n * bg * pow(hh, self.n - 1.0);
        let mut m = libm::ceil(abs(dw) * lip / RK4_LIPSCHITZ_STEP);
        if !(m >= 1.0) {
            m = 1.0;
        }
        if m > RK4_MAX_SUBSTEPS {
            m = RK4_MAX_SUBSTEPS;
        }
        let dx = dw / m;
        for _ in 0..(m as usize) {
            let k1 = self.slope(h, s);
            let k2 = self.slope(h + 0.5 * dx * k1, s);
            let k3 = self.slope(h + 0.5 * dx * k2, s);
            let k4 = self.slope(h + dx * k3, s);
            h += dx / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        h
    }
}

/// Exact n = 1 Bouc–Wen increment (docs/spec.md §2.5): on a monotone piece with fixed `sign(h)`,
/// `dh/dw = a - c h`, `c = beta*s + gamma*sign(h)`, so
/// `h(w + dw) = h + (a - c h) dw phi1(c dw)`; the step is split where `h` crosses 0.
#[inline]
pub fn bouc_wen_1_exact(mut h: f64, dw: f64, a: f64, beta: f64, gamma: f64) -> f64 {
    if dw == 0.0 {
        return h;
    }
    let s = sign(dw);
    let mut rem = dw;
    // h can cross zero at most once on a monotone piece: it then moves towards a/c.
    for _ in 0..2 {
        let sh = if h != 0.0 { sign(h) } else { sign(a * dw) };
        if sh == 0.0 {
            return h; // a = 0 and h = 0: nothing drives h
        }
        let c = beta * s + gamma * sh;
        let h_end = h + (a - c * h) * rem * phi1(c * rem);
        if h == 0.0 || h_end == 0.0 || sign(h_end) == sh {
            return h_end;
        }
        // increment at which h reaches 0: a/c + (h - a/c) e^{-c x} = 0
        let x = if c == 0.0 { -h / a } else { libm::log1p(-c * h / a) / c };
        rem -= x;
        h = 0.0;
        if rem == 0.0 || sign(rem) != s {
            return 0.0;
        }
    }
    h
}

impl Hysteresis for BoucWen {
    fn state_len(&self) -> usize {
        2
    }
    #[inline]
    fn step(&self, state: &mut [f64], w: f64) -> f64 {
        state[0] = self.advance(state[0], w - state[1]);
        state[1] = w;
        self.d * w - state[0]
    }
}

impl Invertible for BoucWen {
    fn trial(&self, state: &[f64], w: f64) -> (f64, f64) {
        let h = self.advance(state[0], w - state[1]);
        (self.d * w - h, self.d - self.slope(h, sign(w - state[1])))
    }
}

/// Generalized Duhem (Coleman–Hodgdon): `dy/du = alpha*s*(f(u) - y) + g(u)`, `s = sign(du)`,
/// with cubic `f`, `g` (coefficients `[c0, c1, c2, c3]`). Integrated in closed form.
#[derive(Debug, Clone, Copy)]
pub struct Duhem {
    /// Rate of approach to the anhysteretic curve `f`, `alpha >= 0`.
    pub alpha: f64,
    /// Anhysteretic curve `f(u)`.
    pub f: [f64; 4],
    /// Slope function `g(u)`.
    pub g: [f64; 4],
}

/// `psi_m(x) = int_0^1 exp(-x (1 - t)) t^m dt` for m = 0..=3, x >= 0.
fn psi(x: f64) -> [f64; 4] {
    let mut out = [0.0; 4];
    if x < 1.0 {
        // series: psi_m(x) = sum_j (-x)^j m! / (m + j + 1)!
        for (m, o) in out.iter_mut().enumerate() {
            let mut term = 1.0 / ((m + 1) as f64); // j = 0: m!/(m+1)!
            let mut sum = term;
            for j in 1..40 {
                term *= -x / ((m + j + 1) as f64);
                sum += term;
                if abs(term) < 1e-18 * abs(sum) {
                    break;
                }
            }
            *o = sum;
        }
    } else {
        // upward recurrence psi_m = (1 - m psi_{m-1}) / x is stable for x >= 1
        out[0] = phi1(x);
        for m in 1..4 {
            out[m] = (1.0 - (m as f64) * out[m - 1]) / x;
        }
    }
    out
}

impl Duhem {
    /// Validate and build.
    pub fn new(alpha: f64, f: [f64; 4], g: [f64; 4]) -> Result<Self, ModelError> {
        check_scalar("alpha", alpha)?;
        if alpha < 0.0 {
            return Err(ModelError::Negative("alpha", usize::MAX, alpha));
        }
        check_finite("f", &f)?;
        check_finite("g", &g)?;
        Ok(Duhem { alpha, f, g })
    }

    /// Exact increment: `y(u0 + du) = y0 e^{-k du} + int_0^du e^{-k(du - t)} F(u0 + t) dt`
    /// with `k = alpha*s`, `F = k f + g` cubic, expanded in Taylor terms at `u0`.
    pub fn advance(&self, y0: f64, u0: f64, du: f64) -> f64 {
        if du == 0.0 {
            return y0;
        }
        let k = self.alpha * sign(du);
        let c: [f64; 4] = core::array::from_fn(|i| k * self.f[i] + self.g[i]);
        // Taylor coefficients of F at u0: F_m = F^{(m)}(u0) / m!
        let f0 = c[0] + u0 * (c[1] + u0 * (c[2] + u0 * c[3]));
        let f1 = c[1] + u0 * (2.0 * c[2] + u0 * 3.0 * c[3]);
        let f2 = c[2] + 3.0 * c[3] * u0;
        let f3 = c[3];
        let x = self.alpha * abs(du); // = k * du >= 0
        let p = psi(x);
        let mut y = y0 * exp(-x);
        let mut dpow = du;
        for (fm, pm) in [f0, f1, f2, f3].iter().zip(p) {
            y += fm * dpow * pm;
            dpow *= du;
        }
        y
    }
}

impl Hysteresis for Duhem {
    fn state_len(&self) -> usize {
        2
    }
    #[inline]
    fn step(&self, state: &mut [f64], u: f64) -> f64 {
        state[0] = self.advance(state[0], state[1], u - state[1]);
        state[1] = u;
        state[0]
    }
}

/// Dahl: `dh/du = sigma * (1 - (h/h_c) s)^a`, `s = sign(du)` (a = 1 is Bouc–Wen n = 1 with
/// gamma = 0). Closed form for every `a > 0`; output `h`.
#[derive(Debug, Clone, Copy)]
pub struct Dahl {
    /// Initial stiffness `sigma > 0`.
    pub sigma: f64,
    /// Saturation level `h_c > 0`.
    pub h_c: f64,
    /// Shape exponent `a > 0`.
    pub a: f64,
}

impl Dahl {
    /// Validate and build.
    pub fn new(sigma: f64, h_c: f64, a: f64) -> Result<Self, ModelError> {
        for (name, x) in [("sigma", sigma), ("h_c", h_c), ("a", a)] {
            check_scalar(name, x)?;
            if !(x > 0.0) {
                return Err(ModelError::NotPositive(name, usize::MAX, x));
            }
        }
        Ok(Dahl { sigma, h_c, a })
    }

    /// Exact increment. With `x = 1 - s h/h_c`: `dx/d|du| = -(sigma/h_c) x^a`.
    pub fn advance(&self, h: f64, du: f64) -> f64 {
        if du == 0.0 {
            return h;
        }
        let s = sign(du);
        let mut x0 = 1.0 - s * h / self.h_c;
        if x0 < 0.0 {
            x0 = 0.0; // h already at saturation in this direction
        }
        let t = self.sigma / self.h_c * abs(du);
        let x = if self.a == 1.0 {
            x0 * exp(-t)
        } else if x0 == 0.0 {
            0.0 // saturated in this direction: x stays at 0
        } else {
            // x^e = x0^e - e t (e = 1 - a), written as x = x0 (1 + u)^(1/e) with
            // u = -e t x0^(-e), evaluated through log1p so that it stays accurate as a -> 1
            // (the form (x0^e - e t)^(1/e) loses about log10(1/|e|) digits)
            let e = 1.0 - self.a;
            let u = -e * t * pow(x0, -e);
            if u <= -1.0 {
                0.0 // a < 1: saturation reached within this increment
            } else {
                x0 * exp(libm::log1p(u) / e)
            }
        };
        s * self.h_c * (1.0 - x)
    }
}

impl Hysteresis for Dahl {
    fn state_len(&self) -> usize {
        2
    }
    #[inline]
    fn step(&self, state: &mut [f64], u: f64) -> f64 {
        state[0] = self.advance(state[0], u - state[1]);
        state[1] = u;
        state[0]
    }
}
