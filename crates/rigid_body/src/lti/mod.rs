//! Linear time-invariant systems on dense `DMatrix<f64>` (feature `std`): the state-space model
//! with an input delay ([`StateSpace`]: frequency response, sampling, poles), matrix exponential and
//! zero-order-hold discretisation, Lyapunov and Riccati equations, LQR gains and
//! controllability. Every function validates shapes and finiteness and returns a named
//! [`Error`](crate::Error) instead of panicking.
//!
//! ```
//! use nalgebra::DMatrix;
//! use rigid_body::lti;
//!
//! // Double integrator, LQR with Q = I, R = 1.
//! let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, 0.0]);
//! let b = DMatrix::from_row_slice(2, 1, &[0.0, 1.0]);
//! let lqr = lti::lqr(&a, &b, &DMatrix::identity(2, 2), &DMatrix::identity(1, 1))?;
//! assert!((lqr.k[(0, 0)] - 1.0).abs() < 1e-9 && (lqr.k[(0, 1)] - 3f64.sqrt()).abs() < 1e-9);
//! # Ok::<(), rigid_body::Error>(())
//! ```

mod controllability;
mod discretize;
mod lyapunov;
mod riccati;
mod schur;
mod state_space;

pub use controllability::{ctrb_gramian, ctrb_matrix};
pub use discretize::{c2d_zoh, c2d_zoh_delay, expm, DelayedZoh, EXPM_MAX_NORM, MAX_DELAY_STEPS};
pub use lyapunov::{dlyap, lyap};
pub use riccati::{care, dare, dlqr, lqr, Lqr};
pub use schur::{eigenvalues, spectral_radius};
pub use state_space::{CMatrix, Discrete, StateSpace};

use crate::{Error, Result};
use nalgebra::DMatrix;

/// Checks that `m` is square and finite; returns its dimension.
fn square(name: &'static str, m: &DMatrix<f64>) -> Result<usize> {
    if m.nrows() != m.ncols() {
        return Err(Error::NotSquare {
            name,
            rows: m.nrows(),
            cols: m.ncols(),
        });
    }
    finite(name, m)?;
    Ok(m.nrows())
}

/// Checks that `m` is `rows x cols` and finite.
fn shaped(name: &'static str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<()> {
    sized(name, m, rows, cols)?;
    finite(name, m)
}

/// Checks that `m` is `rows x cols`.
fn sized(name: &'static str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<()> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(Error::DimensionMismatch {
            name,
            rows: m.nrows(),
            cols: m.ncols(),
            expected_rows: rows,
            expected_cols: cols,
        });
    }
    Ok(())
}

fn finite(name: &'static str, m: &DMatrix<f64>) -> Result<()> {
    if m.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite { name })
    }
}

/// Checks symmetry to a relative tolerance of 1e-10 (in the Frobenius norm).
fn symmetric(name: &'static str, m: &DMatrix<f64>) -> Result<()> {
    let asym = (m - m.transpose()).norm();
    if asym <= 1e-10 * m.norm().max(f64::MIN_POSITIVE) || asym == 0.0 {
        Ok(())
    } else {
        Err(Error::NotSymmetric { name })
    }
}

/// `(m + m^T) / 2`.
fn symmetrized(m: &DMatrix<f64>) -> DMatrix<f64> {
    (m + m.transpose()) * 0.5
}
