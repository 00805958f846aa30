//! Distributed event-based state estimation for networked control systems.
//!
//! Every agent estimates the full state from the measurements broadcast on a shared bus,
//! reconstructs the plant input from its own estimate (no input communication) and transmits
//! its own measurement only when the innovation leaves a threshold ellipsoid. The gains L and
//! thresholds Δ are synthesised by linear matrix inequalities solved with Clarabel.
//!
//! * [`runtime`]: the per-agent estimator, trigger and controller (`no_std`, allocation-free).
//! * `model`, `sim`, `baseline` (feature `std`): system descriptions with agent blocks, the
//!   networked closed-loop simulator with packet loss, the centralised periodic Kalman filter.
//! * `lmi`, `synth` (feature `synthesis`): the LMI builder on Clarabel's PSD cone and the
//!   two-step synthesis of gains and thresholds with post-verification.
//! * `alternation` (feature `synthesis`): gain and threshold steps alternated to enlarge the
//!   thresholds at a fixed certified bound (spec 6.3).
//! * `ipm` (feature `synthesis`): a Schur-complement interior-point SDP method, the second
//!   backend of `lmi` for problems with thousands of variables (the 20-vehicle Cor 13 design).
#![cfg_attr(not(feature = "std"), no_std)]

pub mod error;
pub mod runtime;

#[cfg(feature = "std")]
pub mod baseline;
#[cfg(feature = "std")]
pub mod linalg;
#[cfg(feature = "std")]
pub mod model;
#[cfg(feature = "std")]
pub mod sim;

#[cfg(feature = "synthesis")]
extern crate openblas_src;
#[cfg(feature = "synthesis")]
pub mod alternation;
#[cfg(feature = "synthesis")]
pub mod ipm;
#[cfg(feature = "synthesis")]
pub mod lmi;
#[cfg(feature = "synthesis")]
pub mod synth;

pub use error::EventEstError;
