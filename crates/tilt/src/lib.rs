//! Accelerometer-only estimation of tilt, angular velocity and angular acceleration of a rigid
//! body rotating about a non-accelerated pivot (Muehlebach and D'Andrea, IEEE TCST 2017).
//!
//! Each accelerometer i at body position `p_i` reads `m_i = Omega p_i - g + n_i` with
//! `Omega = [omega]x^2 + [omega_dot]x` and `g` the body-frame gravity on the sphere of radius
//! [`G0`]. The maximum-likelihood estimate minimises `sum |m_i - Omega p_i + g|^2` over
//! `Omega` in M and `g` on the sphere by the projected fixed-point iteration of the paper
//! ([`Estimator`]); the unconstrained linear method ([`least_squares`]) is the baseline and
//! the starting point. [`fisher_information`] gives the Cramer-Rao bound, [`d_criterion`]
//! scores sensor placements. Everything per sample is allocation-free; the crate is `no_std`
//! without the `std` feature.
#![cfg_attr(not(feature = "std"), no_std)]

mod error;
mod estimator;
mod fisher;
mod layout;
mod least_squares;
mod math;
mod model;
mod placement;
#[cfg(feature = "std")]
pub mod simulation;
#[cfg(feature = "std")]
pub mod study;
mod tuning;

pub use error::TiltError;
pub use estimator::{Estimate, Estimator, Flags, Options};
pub use fisher::{
    expected_omega_block, fisher_information, jacobian, tangent_basis, Crb, Fisher, Jacobian,
    Matrix8, RANK_TOL,
};
pub use layout::{AffinePlane, Layout, MAX_SENSORS};
pub use least_squares::{least_squares, LeastSquaresEstimate};
pub use model::{ideal_measurements, omega_matrix};
pub use placement::{
    d_criterion, d_criterion_bound, optimal_placement, optimality_residuals, platonic_layout,
};
pub use rigid_body::s2::G0;
pub use tuning::{
    a_s, a_s_eigenvalues, default_tuning, manual_tuning, numerical_tuning, Tuning, TuningRule,
};
