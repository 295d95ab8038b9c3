//! Hysteresis models: the operators and models of an actuator's input-output memory, and
//! their exact per-sample inverse.
//!
//! Every model is split into an immutable **configuration** (a struct that borrows its
//! parameter slices) and a mutable **state** (a flat `&mut [f64]` owned by the caller, of
//! length [`Hysteresis::state_len`]). One configuration can drive many states and a step
//! never allocates.
//!
//! The state starts *relaxed at zero input*: all-zero for the play-type models, so the first
//! sample `v0` gives `z_r = max(v0 - r, min(v0 + r, 0))` as in docs/spec.md §2.1.
//!
//! - play-type: [`pi`] (classical Prandtl–Ishlinskii), [`generalized`] (asymmetric play with
//!   the [`envelope`] functions), [`rate`] (rate-dependent PI);
//! - [`creep`]: logarithmic drift as a bank of lags, added to any model;
//! - [`preisach`]: the discretized Preisach model;
//! - [`differential`]: Bouc–Wen, Duhem and Dahl;
//! - [`inverse`]: the exact per-sample inverse of any [`Invertible`] model.
pub mod creep;
pub mod differential;
pub mod envelope;
pub mod generalized;
pub mod inverse;
pub mod pi;
pub mod preisach;
pub mod rate;

/// A discrete-time hysteresis model: configuration of one parameter set.
pub trait Hysteresis {
    /// Number of `f64` slots the state needs.
    fn state_len(&self) -> usize;
    /// Write the relaxed initial state (input and memory at zero).
    fn reset(&self, state: &mut [f64]) {
        state.iter_mut().for_each(|s| *s = 0.0);
    }
    /// Apply input `v` for one sample: update `state`, return the output.
    fn step(&self, state: &mut [f64], v: f64) -> f64;
    /// Check a state that came from outside (a caller's buffer, possibly tampered with)
    /// before [`Hysteresis::step`] reads it: the length, every slot finite, and any slot
    /// with a structural meaning (Preisach's memory length) in its range. The error names
    /// the slot as `state[i]`. [`Hysteresis::step`] assumes a state that passes.
    fn check_state(&self, state: &[f64]) -> Result<(), crate::ModelError> {
        check_state_len(state, self.state_len())?;
        crate::error::check_finite("state", state)
    }
}

/// `state.len() == want`, else a [`crate::ModelError::Length`] naming `state`.
pub fn check_state_len(state: &[f64], want: usize) -> Result<(), crate::ModelError> {
    if state.len() != want {
        return Err(crate::ModelError::Length("state", want, state.len()));
    }
    Ok(())
}

/// A model whose output at one sample is a continuous, increasing function of that
/// sample's input, so it can be inverted sample by sample (docs/spec.md §2.1).
pub trait Invertible: Hysteresis {
    /// Output and its slope `dy/dv` if `v` were applied now; `state` is untouched.
    /// The output must be bit-identical to what [`Hysteresis::step`] would return.
    /// A slope that is not finite and positive makes the solver bisect.
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64);
}
