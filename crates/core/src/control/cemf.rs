//! The identified CEMF stage model of seed 1 as a controller component (docs/spec.md §2.6, §5):
//! the observer that estimates the hysteresis voltage `V̂h` from the applied voltage and
//! the measured displacement, and the exact inverse feedforward.
//!
//! ```text
//! M x'' + B x' + K x = Vin - Vh          (M = meq/Tem, B = beq/Tem, K = keq/Tem)
//! q   = Cz (Vin - Vh) + Tem x
//! dVh = alpha dq - beta |dq| Vh - gamma dq |Vh|
//! ```
use crate::control::{positive, terms, Controller, Limits, Output, Reference};
use crate::error::{check_scalar, ModelError};
use crate::hysteresis::differential::bouc_wen_1_exact;
use crate::hysteresis::inverse::solve_increasing;
use crate::num::math::{abs, clamp};

/// Parameters of the identified CEMF model (volt-normalized, as identified).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CemfModel {
    /// `M = meq / Tem`, V s^2/m.
    pub m: f64,
    /// `B = beq / Tem`, V s/m.
    pub b: f64,
    /// `K = keq / Tem`, V/m.
    pub k: f64,
    /// Electromechanical ratio `Tem`, N/V (= C/m).
    pub tem: f64,
    /// Stack capacitance `Cz`, F.
    pub cz: f64,
    /// Bouc–Wen `alpha`, V/C.
    pub alpha: f64,
    /// Bouc–Wen `beta`, 1/C.
    pub beta: f64,
    /// Bouc–Wen `gamma`, 1/C.
    pub gamma: f64,
}

impl CemfModel {
    /// Number of parameters of [`CemfModel::from_slice`].
    pub const PARAM_LEN: usize = 8;

    /// Validate a configuration built as a struct literal; returns it unchanged. Positive
    /// `M`, `K`, `Tem`, `Cz`; `B >= 0`; finite Bouc–Wen parameters with `beta + gamma >= 0`,
    /// `beta - gamma >= 0` (`Vh` stays bounded).
    pub fn validated(self) -> Result<Self, ModelError> {
        let CemfModel { m, b, k, tem, cz, alpha, beta, gamma } = self;
        positive("M", m)?;
        positive("K", k)?;
        positive("tem", tem)?;
        positive("capacitance", cz)?;
        check_scalar("B", b)?;
        if b < 0.0 {
            return Err(ModelError::Negative("B", usize::MAX, b));
        }
        for (n, x) in [("hyst_alpha", alpha), ("hyst_beta", beta), ("hyst_gamma", gamma)] {
            check_scalar(n, x)?;
        }
        if beta + gamma < 0.0 || beta - gamma < 0.0 {
            return Err(ModelError::Negative("hyst_beta - |hyst_gamma|", usize::MAX, beta - abs(gamma)));
        }
        Ok(self)
    }

    /// Build from `[M, B, K, tem, capacitance, hyst_alpha, hyst_beta, hyst_gamma]`, validated.
    pub fn from_slice(p: &[f64]) -> Result<Self, ModelError> {
        if p.len() != Self::PARAM_LEN {
            return Err(ModelError::Length("cemf model parameters", Self::PARAM_LEN, p.len()));
        }
        let [m, b, k, tem, cz, alpha, beta, gamma] = [p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]];
        CemfModel { m, b, k, tem, cz, alpha, beta, gamma }.validated()
    }

    /// The CEMF voltage after the charge changes by `dq` from a state with `vh`.
    #[inline]
    pub fn hysteresis(&self, vh: f64, dq: f64) -> f64 {
        bouc_wen_1_exact(vh, dq, self.alpha, self.beta, self.gamma)
    }

    /// Observer update: the stack moved by `dx` while the applied voltage changed by `du`;
    /// returns the new `V̂h`. The loop `dq = Tem dx + Cz (du - dVh)` is solved exactly (the
    /// left side `dq + Cz (Vh(dq) - vh)` increases in `dq` while `1 + Cz dVh/dq > 0`).
    pub fn observe(&self, vh: f64, dx: f64, du: f64) -> f64 {
        let q_ext = self.tem * dx + self.cz * du;
        if q_ext == 0.0 {
            return vh;
        }
        let cz = self.cz;
        // dq has the sign of q_ext (the left side is increasing and 0 at 0), so the Bouc–Wen
        // slope law is fixed: Newton from the linearized loop converges in 2-3 steps
        let s = if q_ext > 0.0 { 1.0 } else { -1.0 };
        let slope = |h: f64| self.alpha - self.beta * s * h - self.gamma * abs(h);
        let mut dq = q_ext / (1.0 + cz * slope(vh)).max(1e-12);
        for _ in 0..6 {
            let h = self.hysteresis(vh, dq);
            let r = dq + cz * (h - vh) - q_ext;
            let d = 1.0 + cz * slope(h);
            if abs(r) <= 1e-14 * abs(q_ext) {
                return h;
            }
            let next = dq - r / d;
            if !(d > 0.0) || !next.is_finite() || next * s <= 0.0 {
                break; // leave it to the bracketed solve
            }
            dq = next;
        }
        let f = |dq: f64| {
            let h = self.hysteresis(vh, dq);
            let sd = if dq >= 0.0 { 1.0 } else { -1.0 };
            (dq + cz * (h - vh), 1.0 + cz * (self.alpha - self.beta * sd * h - self.gamma * abs(h)))
        };
        match solve_increasing(f, q_ext, dq) {
            Some(dq) => self.hysteresis(vh, dq),
            None => vh,
        }
    }
}

/// Exact inverse feedforward of the CEMF model: the force voltage the reference needs,
/// `F = M x_d'' + B x_d' + K x_d`, fixes the charge `q = Cz F + Tem x_d` without an
/// algebraic loop, the Bouc–Wen law gives `Vh` on it, and `u = F + Vh`.
/// State `[vh, q_prev]`. Terms: `[force_voltage, vh_hat, u_unsaturated]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CemfFeedforward {
    /// The identified model.
    pub model: CemfModel,
    /// Output limits, V.
    pub limits: Limits,
}

impl Controller for CemfFeedforward {
    fn state_len(&self) -> usize {
        2
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        // at rest at y0 with no hysteresis voltage
        state[0] = 0.0;
        state[1] = (self.model.cz * self.model.k + self.model.tem) * y0;
    }
    fn step(&self, state: &mut [f64], r: &Reference, _y: f64) -> Output {
        let m = &self.model;
        let force = m.m * r.a + m.b * r.v + m.k * r.x;
        let q = m.cz * force + m.tem * r.x;
        state[0] = m.hysteresis(state[0], q - state[1]);
        state[1] = q;
        let raw = force + state[0];
        Output { u: clamp(raw, self.limits.min, self.limits.max), terms: terms([force, state[0], raw]) }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["force_voltage", "vh_hat", "u_unsaturated"]
    }
    fn limits(&self) -> Limits {
        self.limits
    }
}
