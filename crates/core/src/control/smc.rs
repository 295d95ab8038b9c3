//! Extended sliding-mode control with a dynamic compensator — seed 1 (docs/spec.md §5), with the
//! CEMF observer estimate `V̂h` (Case 2) or without it (Case 1), and a super-twisting
//! (chattering-free) switching law as an alternative to the boundary layer.
//!
//! ```text
//! e = x_d - x,  xi' = -alpha xi + e,  s = e' + kv e + kp xi
//! u = M̂ (x_d'' + kv e' + kp e - alpha kp xi) + B̂ x' + K̂ x + [V̂h] + switching(s)
//! boundary layer:  switching = Ks sat(s / Phi)
//! super-twisting:  switching = k1 |s|^(1/2) sign(s) + nu,  nu' = k2 sign(s)
//! ```
//! **Model terms.** Seed 1 writes `B̂ x' + K̂ x` on the measured motion: that cancels the
//! stage's stiffness by positive position feedback. When the identified `K̂` (or `V̂h`) asks
//! for more than the amplifier gives at the stroke's end — creep raises the real static gain
//! over time — the equivalent control alone exceeds `u_max` there, the switching gain cannot
//! pull it back, and the loop latches at the limit (`crates/core/tests/soak.rs` shows it on
//! set-point steps). `desired_model_terms` evaluates them on the reference instead,
//! `B̂ x_d' + K̂ x_d` (desired compensation): the stage's own stiffness and damping then act on
//! the error, and saturation cannot latch.
//!
//! On `s = 0`: `e'' + (kv + alpha) e' + (alpha kv + kp) e = 0`, stable iff
//! `kv + alpha > 0` and `alpha kv + kp > 0` (checked). Position and velocity come from the
//! [`VelocityObserver`]; `xi` is discretized exactly for a held `e` and, like `nu`, holds
//! while the output is saturated in the direction it would push.
use crate::control::cemf::CemfModel;
use crate::control::{nonnegative, positive, terms, Controller, Limits, Output, Reference, VelocityObserver};
use crate::error::{check_scalar, ModelError};
use crate::num::math::{abs, clamp, exp, sign, sqrt};

/// The switching part of the control.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Switching {
    /// `Ks sat(s / Phi)`: gain `Ks` (V) and boundary layer `Phi` (m/s).
    BoundaryLayer {
        /// `Ks`, V.
        gain: f64,
        /// `Phi`, m/s.
        width: f64,
    },
    /// `k1 |s|^(1/2) sign(s) + nu`, `nu' = k2 sign(s)`.
    SuperTwisting {
        /// `k1`, V (m/s)^-1/2.
        k1: f64,
        /// `k2`, V/s.
        k2: f64,
    },
}

/// Seed 1's controller tuning and model, as a struct literal; [`Smc::new`] validates it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmcConfig {
    /// Nominal `M̂`, V s^2/m.
    pub m: f64,
    /// Nominal `B̂`, V s/m.
    pub b: f64,
    /// Nominal `K̂`, V/m.
    pub k: f64,
    /// Sliding-surface gain on the error, 1/s^2.
    pub kp: f64,
    /// Sliding-surface gain on the error rate, 1/s.
    pub kv: f64,
    /// Compensator pole `alpha >= 0`, 1/s.
    pub alpha: f64,
    /// Switching law.
    pub switching: Switching,
    /// CEMF observer model (Case 2), or none (Case 1).
    pub cemf: Option<CemfModel>,
    /// `B̂ x_d' + K̂ x_d` instead of `B̂ x' + K̂ x` (see the module notes).
    pub desired_model_terms: bool,
    /// Position/velocity observer.
    pub observer: VelocityObserver,
    /// Output limits, V.
    pub limits: Limits,
}

/// Seed 1's controller: a validated [`SmcConfig`] and the compensator's discretization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Smc {
    config: SmcConfig,
    xi_decay: f64,
    xi_gain: f64,
}

// state slots
const OBS: usize = 0; // observer [x, v]
const XI: usize = 2;
const NU: usize = 3;
const VH: usize = 4;
const U_LAST: usize = 5; // command of the previous step
const U_OBS: usize = 6; // voltage and position at the observer's last update
const X_OBS: usize = 7;

impl Smc {
    /// Validate and build; the sample time is the observer's.
    pub fn new(config: SmcConfig) -> Result<Self, ModelError> {
        let SmcConfig { m, b, k, kp, kv, alpha, switching, observer, .. } = config;
        positive("M", m)?;
        nonnegative("B", b)?;
        nonnegative("K", k)?;
        check_scalar("kp", kp)?;
        check_scalar("kv", kv)?;
        nonnegative("alpha", alpha)?;
        if !(kv + alpha > 0.0) {
            return Err(ModelError::NotPositive("kv + alpha (sliding dynamics unstable)", usize::MAX, kv + alpha));
        }
        if !(alpha * kv + kp > 0.0) {
            return Err(ModelError::NotPositive(
                "alpha * kv + kp (sliding dynamics unstable)",
                usize::MAX,
                alpha * kv + kp,
            ));
        }
        match switching {
            Switching::BoundaryLayer { gain, width } => {
                nonnegative("ks", gain)?;
                positive("phi", width)?;
            }
            Switching::SuperTwisting { k1, k2 } => {
                nonnegative("k1", k1)?;
                nonnegative("k2", k2)?;
            }
        }
        let ts = observer.ts;
        // xi' = -alpha xi + e with e held over a period
        let (xi_decay, xi_gain) =
            if alpha * ts > 1e-12 { (exp(-alpha * ts), (1.0 - exp(-alpha * ts)) / alpha) } else { (1.0, ts) };
        Ok(Smc { config, xi_decay, xi_gain })
    }

    /// The configuration it was built from.
    pub fn config(&self) -> &SmcConfig {
        &self.config
    }
}

impl Controller for Smc {
    fn state_len(&self) -> usize {
        8
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        state.fill(0.0);
        self.config.observer.reset(&mut state[OBS..OBS + 2], y0);
        state[X_OBS] = y0;
    }
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        let c = &self.config;
        let (x, v) = c.observer.update(&mut state[OBS..OBS + 2], y);
        if let Some(model) = &c.cemf {
            // the voltage applied since the last update is the previous command
            state[VH] = model.observe(state[VH], x - state[X_OBS], state[U_LAST] - state[U_OBS]);
            state[U_OBS] = state[U_LAST];
            state[X_OBS] = x;
        }
        let e = r.x - x;
        let de = r.v - v;
        let xi = state[XI];
        let s = de + c.kv * e + c.kp * xi;
        let (xm, vm) = if c.desired_model_terms { (r.x, r.v) } else { (x, v) };
        let equivalent = c.m * (r.a + c.kv * de + c.kp * e - c.alpha * c.kp * xi) + c.b * vm + c.k * xm + state[VH];
        let switching = match c.switching {
            Switching::BoundaryLayer { gain, width } => gain * clamp(s / width, -1.0, 1.0),
            Switching::SuperTwisting { k1, .. } => k1 * sqrt(abs(s)) * sign(s) + state[NU],
        };
        let raw = equivalent + switching;
        let (u, hold_xi) = c.limits.apply(raw, c.kp * e);
        if !hold_xi {
            state[XI] = self.xi_decay * xi + self.xi_gain * e;
        }
        if let Switching::SuperTwisting { k2, .. } = c.switching {
            let (_, hold_nu) = c.limits.apply(raw, s);
            if !hold_nu {
                state[NU] += c.observer.ts * k2 * sign(s);
            }
        }
        state[U_LAST] = u;
        Output { u, terms: terms([equivalent, switching, s, xi, state[VH], x, v, raw]) }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["equivalent", "switching", "s", "xi", "vh_hat", "x_hat", "v_hat", "u_unsaturated"]
    }
    fn limits(&self) -> Limits {
        self.config.limits
    }
}
