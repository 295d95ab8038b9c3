//! Simulated plants: what a controller acts on, and the loop that runs them together.
//!
//! - [`stage`]: the piezo-driven flexure stage with CEMF hysteresis, creep and amplifier;
//! - [`sensor`]: the position sensor (noise, quantization, delay);
//! - [`structure`]: what a stage can add (more modes, a voltage-driven hysteresis law, a DAC);
//! - [`closed_loop`]: the engine running controller, amplifier, stage and sensor per sample;
//! - [`lfr`], [`lfr_grad`]: the MIMO LFR with play-operator feedback and its adjoint gradient;
//! - [`boucwen_benchmark`]: the Bouc–Wen hysteretic benchmark system (Noël & Schoukens), its
//!   integrator, decimation and record error.
pub mod boucwen_benchmark;
pub mod closed_loop;
pub mod lfr;
pub mod lfr_grad;
pub mod multiaxis;
pub mod sensor;
pub mod stage;
pub mod structure;
