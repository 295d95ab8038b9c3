//! Adaptive backstepping sliding-mode control — seed 2 (docs/spec.md §5), for a plant
//! `x'' = theta^T phi + b u + d` with `phi = [-x, -x']` (`theta = [a0, a1]`: stiffness and
//! damping per unit input gain), unknown `theta` and a bounded lumped disturbance `d`.
//!
//! ```text
//! e1 = x - x_d,  alpha1 = x_d' - c1 e1,  e2 = x' - alpha1,  s = lambda e1 + e2
//! u  = (1/b) [ -theta^T phi + alpha1' - lambda (e2 - c1 e1) - e1 - ks s - D sat(s/Phi) ]
//! theta' = Gamma phi s,   D' = gamma_D |s|          (projected onto their bounds)
//! ```
//! `alpha1' = x_d'' - c1 (x' - x_d')`.
//!
//! **Regressor.** Seed 2 evaluates `phi` on the measured motion. On a stiff stage
//! (`a0 = omega_n^2`) that cancels the stiffness with a delayed, quantized position:
//! `a0 (x̂ - x) ~ -a0 delay x'` is a negative damping far above what the loop can hold
//! (on the virtual stage the measured form loses the 80 Hz sine entirely; see
//! `tests/test_control.py`). With `desired_regressor` the model terms use the reference,
//! `phi_d = [-x_d, -x_d']` (desired-compensation adaptive law, Sadegh & Horowitz 1990):
//! the same Lyapunov argument holds with the mismatch `theta^T (phi - phi_d)` bounded by
//! the tracking error and absorbed by `ks` and `D`, and the stiffness enters as feedforward.
//!
//! Alone it drives the stage in volts
//! (`b = 1/M`, `theta = [K/M, B/M]`); behind an inverse hysteresis model
//! ([`crate::control::compensated::Compensated`]) it acts in the linearized (displacement) domain
//! (`b = a0 = omega_n^2` of the linearized stage). Adaptation is explicit Euler with the
//! observer's sample time and stops while the output is saturated (anti-windup).
use crate::control::{nonnegative, positive, terms, Controller, Limits, Output, Reference, VelocityObserver};
use crate::error::{check_scalar, ModelError};
use crate::num::math::{abs, clamp};

/// Seed 2's controller, built as a struct literal and checked by [`Absmc::validated`] (it
/// derives nothing, so the configuration is the controller).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Absmc {
    /// Input gain `b` (> 0).
    pub b: f64,
    /// Initial `theta = [a0, a1]`.
    pub theta0: [f64; 2],
    /// Projection bounds of `theta`: `[lo0, lo1]`, `[hi0, hi1]`.
    pub theta_min: [f64; 2],
    /// Upper projection bounds.
    pub theta_max: [f64; 2],
    /// Backstepping gain `c1` (> 0), 1/s.
    pub c1: f64,
    /// Sliding-surface slope `lambda` (> 0), 1/s.
    pub lambda: f64,
    /// Reaching gain `ks` (>= 0), 1/s.
    pub ks: f64,
    /// Boundary layer `Phi` (> 0), m/s.
    pub phi: f64,
    /// Adaptation rates `Gamma` (diagonal, > 0).
    pub gamma_theta: [f64; 2],
    /// Disturbance-bound adaptation rate `gamma_D` (> 0).
    pub gamma_d: f64,
    /// Initial disturbance bound `D`.
    pub d0: f64,
    /// Upper bound of `D`.
    pub d_max: f64,
    /// Evaluate the regressor on the reference instead of the measurement.
    pub desired_regressor: bool,
    /// Position/velocity observer.
    pub observer: VelocityObserver,
    /// Output limits.
    pub limits: Limits,
}

impl Absmc {
    /// Validate; returns the configuration unchanged.
    pub fn validated(self) -> Result<Self, ModelError> {
        let Absmc { b, theta0, theta_min, theta_max, c1, lambda, ks, phi, gamma_theta, gamma_d, d0, d_max, .. } = self;
        positive("b", b)?;
        positive("c1", c1)?;
        positive("lambda", lambda)?;
        nonnegative("ks", ks)?;
        positive("phi", phi)?;
        positive("gamma_theta[0]", gamma_theta[0])?;
        positive("gamma_theta[1]", gamma_theta[1])?;
        positive("gamma_d", gamma_d)?;
        nonnegative("d0", d0)?;
        nonnegative("d_max", d_max)?;
        for i in 0..2 {
            check_scalar("theta0", theta0[i])?;
            check_scalar("theta_min", theta_min[i])?;
            check_scalar("theta_max", theta_max[i])?;
            if !(theta_min[i] <= theta0[i] && theta0[i] <= theta_max[i]) {
                return Err(ModelError::OutOfRange("theta0", i, theta0[i], theta_min[i], theta_max[i]));
            }
        }
        if d0 > d_max {
            return Err(ModelError::OutOfRange("d0", usize::MAX, d0, 0.0, d_max));
        }
        Ok(self)
    }
}

// state slots: observer [x, v], theta [a0, a1], D
const TH: usize = 2;
const D: usize = 4;

impl Controller for Absmc {
    fn state_len(&self) -> usize {
        5
    }
    fn reset(&self, state: &mut [f64], y0: f64) {
        self.observer.reset(&mut state[..2], y0);
        state[TH] = self.theta0[0];
        state[TH + 1] = self.theta0[1];
        state[D] = self.d0;
    }
    fn step(&self, state: &mut [f64], r: &Reference, y: f64) -> Output {
        let (x, v) = self.observer.update(&mut state[..2], y);
        let e1 = x - r.x;
        let alpha1 = r.v - self.c1 * e1;
        let e2 = v - alpha1;
        let s = self.lambda * e1 + e2;
        let d_alpha1 = r.a - self.c1 * (v - r.v);
        let phi = if self.desired_regressor { [-r.x, -r.v] } else { [-x, -v] };
        let (th, d) = ([state[TH], state[TH + 1]], state[D]);
        let raw = (-(th[0] * phi[0] + th[1] * phi[1]) + d_alpha1
            - self.lambda * (e2 - self.c1 * e1)
            - e1
            - self.ks * s
            - d * clamp(s / self.phi, -1.0, 1.0))
            / self.b;
        // the laws push u against s: hold them while u is saturated in that direction
        let (u, hold) = self.limits.apply(raw, -s);
        if !hold {
            let ts = self.observer.ts;
            for i in 0..2 {
                let next = th[i] + ts * self.gamma_theta[i] * phi[i] * s;
                state[TH + i] = clamp(next, self.theta_min[i], self.theta_max[i]);
            }
            state[D] = clamp(d + ts * self.gamma_d * abs(s), 0.0, self.d_max);
        }
        Output { u, terms: terms([e1, e2, s, state[TH], state[TH + 1], state[D], raw, v]) }
    }
    fn term_names(&self) -> &'static [&'static str] {
        &["e1", "e2", "s", "theta0", "theta1", "d_hat", "u_unsaturated", "v_hat"]
    }
    fn limits(&self) -> Limits {
        self.limits
    }
}
