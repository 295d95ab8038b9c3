//! Hysteresis operators and models for piezoelectric actuators, the controllers that
//! compensate them, and the simulated plants they are tested on.
//!
//! The crate is organized by role:
//!
//! - [`hysteresis`]: the models ([`Hysteresis`], [`Invertible`]) and their exact inverse;
//! - [`control`]: the controller interface ([`control::Controller`]) and the control laws;
//! - [`plant`]: the simulated stage, sensor and closed loop, and the Bouc–Wen benchmark;
//! - [`num`]: elementary functions, small matrices and the random generator;
//! - [`error`]: the construction and inversion errors every domain reports;
//! - [`spec`] and [`batch`]: the flat parameter rows shared with the bindings, and the lane
//!   kernels that run many parameter sets at once.
//!
//! Every model and controller is split into an immutable **configuration** and a mutable
//! **state** (a flat `&mut [f64]` owned by the caller). One configuration can drive many
//! states; a step never allocates, and the crate is `no_std` without its `std` feature.
//!
//! A configuration with many parameters is written as a struct literal with named fields.
//! One that derives coefficients is built from its `…Config` by `new` (e.g. [`control::PidConfig`],
//! [`control::smc::SmcConfig`]); one that derives nothing is its own configuration and
//! `validated()` checks it (e.g. [`control::absmc::Absmc`], [`plant::boucwen_benchmark::BoucWenBenchmark`]).
//!
//! Units: the models are unit-agnostic; inputs `v` (usually volts) and outputs `y`
//! (usually metres or µm) only need to be consistent with the parameters.
// unit tests run on the host with std (Vec, format!); the library itself is no_std without `std`
#![cfg_attr(not(any(feature = "std", test)), no_std)]

pub mod batch;
pub mod control;
pub mod error;
pub mod hysteresis;
pub mod layout;
pub mod num;
pub mod plant;
pub mod spec;

pub use error::ModelError;
pub use hysteresis::{Hysteresis, Invertible};

// The stable public paths: every module keeps the flat path it had before the domain folders
// (issue 18), so the bindings, tests and downstream code need not follow the reorganization.
pub use control::{absmc, cemf, compensated, ilc, smc};
pub use hysteresis::{creep, differential, envelope, generalized, inverse, pi, preisach, rate};
pub use num::{linalg, rng};
pub use plant::{boucwen_benchmark, closed_loop, lfr, lfr_grad, multiaxis, sensor, stage, structure};

// batch.rs (rewritten in parallel) imports the elementary functions from their old home.
use num::math;
