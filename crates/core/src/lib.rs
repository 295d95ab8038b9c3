//! Hysteresis operators and models for piezoelectric actuators.
//!
//! Every model is split into an immutable **configuration** (a struct that borrows its
//! parameter slices) and a mutable **state** (a flat `&mut [f64]` owned by the caller, of
//! length [`Hysteresis::state_len`]). One configuration can drive many states; a step never
//! allocates, and the crate is `no_std` without its `std` feature.
//!
//! Units: the models are unit-agnostic; inputs `v` (usually volts) and outputs `y`
//! (usually metres or µm) only need to be consistent with the parameters.
//!
//! The state starts *relaxed at zero input*: all-zero for the play-type models, so the first
//! sample `v0` gives `z_r = max(v0 - r, min(v0 + r, 0))` as in docs/spec.md §2.1.
#![cfg_attr(not(feature = "std"), no_std)]

pub mod absmc;
pub mod batch;
pub mod boucwen_benchmark;
pub mod cemf;
pub mod closed_loop;
pub mod compensated;
pub mod control;
pub mod creep;
pub mod differential;
pub mod envelope;
pub mod error;
pub mod generalized;
pub mod ilc;
pub mod inverse;
pub mod layout;
pub mod linalg;
mod math;
pub mod pi;
pub mod preisach;
pub mod rate;
pub mod rng;
pub mod sensor;
pub mod smc;
pub mod spec;
pub mod stage;
mod ziggurat_tables;

pub use error::ModelError;

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
}

/// A model whose output at one sample is a continuous, increasing function of that
/// sample's input, so it can be inverted sample by sample (docs/spec.md §2.1).
pub trait Invertible: Hysteresis {
    /// Output and its slope `dy/dv` if `v` were applied now; `state` is untouched.
    /// The output must be bit-identical to what [`Hysteresis::step`] would return.
    /// A slope that is not finite and positive makes the solver bisect.
    fn trial(&self, state: &[f64], v: f64) -> (f64, f64);
}
