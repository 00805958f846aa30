//! Reaction-wheel 3D inverted pendulum (the Cubli): model in generalized momenta, backstepping
//! balance, feedback linearization, jump-up with learning of the pre-brake wheel speeds.
//!
//! Follows Muehlebach and D'Andrea, "Nonlinear analysis and control of a reaction-wheel-based
//! 3-D inverted pendulum", IEEE TCST 25(1), 2017; equation numbers are the thesis numbering.
//!
//! ```
//! use cubli::{model, Backstepping, Gains, Params, ReducedState};
//! use nalgebra::Vector3;
//! let p = Params::reference();
//! let ctrl = Backstepping::new(p, Gains::paper());
//! let x = ReducedState { g: Vector3::new(0.0, 0.0, -9.81), p_h: Vector3::zeros(), p_w: Vector3::zeros() };
//! let torque = ctrl.control(&x).unwrap();
//! assert!(model::inclination(&p, &x.g) > 0.9);
//! assert!(torque.norm() > 0.0);
//! ```
#![cfg_attr(not(feature = "std"), no_std)]

mod backstepping;
mod controller;
pub mod edge;
mod error;
mod feedback_linearization;
pub mod jump;
pub mod model;
mod params;
mod plant;
#[cfg(feature = "std")]
pub mod simulate;
mod state;
mod trial;
mod tuning;

pub use backstepping::{Backstepping, Gains, IntegralBackstepping};
pub use controller::{JumpController, Measurement, NoControl, SampledController};
pub use error::CubliError;
pub use feedback_linearization::{
    FeedbackLinearization, GuidingController, JumpReference, Outputs, Reference,
};
pub use params::Params;
pub use plant::{reduced_step, Limits, Plant, WheelEffects};
pub use state::{FullState, ReducedState};
pub use trial::{jump_trial, JumpConfig, JumpControllers, JumpOutcome};
pub use tuning::{GammaIntervals, TiltPolynomial};
