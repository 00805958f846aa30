//! Parametrized infinite-horizon MPC with Laguerre basis functions and semi-infinite
//! constraints (spec/pmpc.md).
//!
//! States and inputs are restricted to the span of s Laguerre functions; the dynamics then
//! hold exactly, the constraints are imposed for all t ≥ 0, and the infinite-horizon problem
//! becomes a small semi-infinite QP solved online by [`rigid_body::siqp`]. Because the span is
//! shift-invariant, the shifted previous plan is always feasible: recursive feasibility and
//! closed-loop stability follow without a terminal set.
//!
//! * [`Pmpc`]: the warm-started controller with fallback.
//! * [`bounds`]: upper bound J_s and the lower bound J̃_s (Clarabel) to quantify sub-optimality.
//! * [`baseline`]: standard discrete-time MPC (condensed, Clarabel or OSQP) for comparison.
//! * [`simulate`]: nominal closed loops with the continuous-time plant.
//! * [`reference`]: exact extremum oracle and a cutting-plane Clarabel solve of the same problem.
//! * [`scenario`]: the quadruple integrator and the integrator chains of the paper.

mod constraints;
mod controller;
mod error;
mod problem;
mod qp;

pub mod baseline;
pub mod bounds;
pub mod reference;
pub mod scenario;
pub mod simulate;

pub use constraints::Constraints;
pub use controller::{Pmpc, Source, StepInfo};
pub use error::{Error, Result};
pub use problem::Problem;

use nalgebra::DMatrix;

pub(crate) fn check_shape(
    name: &'static str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<()> {
    if m.nrows() == rows && m.ncols() == cols {
        Ok(())
    } else {
        Err(Error::Shape {
            name,
            rows: m.nrows(),
            cols: m.ncols(),
            expected_rows: rows,
            expected_cols: cols,
        })
    }
}

pub(crate) fn check_finite(name: &'static str, v: &[f64]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite(name))
    }
}

pub(crate) fn check_vector(name: &'static str, v: &[f64], len: usize) -> Result<()> {
    if v.len() != len {
        return Err(Error::Shape {
            name,
            rows: v.len(),
            cols: 1,
            expected_rows: len,
            expected_cols: 1,
        });
    }
    check_finite(name, v)
}
