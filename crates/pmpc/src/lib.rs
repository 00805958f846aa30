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
pub use controller::{Pmpc, Source, StepInfo, WorkBound};
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

/// Largest number of decision variables of the parametrized problem: its set-up (SVD and
/// eigen-decomposition of N×N matrices, O(N³)) takes about 5 s at N = 1000 on the reference
/// machine and grows eightfold per doubling.
pub(crate) const MAX_VARIABLES: usize = 1000;

/// Largest n·N of the condensed discrete MPC (its (n·N)² state weight is the largest matrix).
pub(crate) const MAX_PREDICTED_STATES: usize = 4000;

/// Refuse a dense set-up of dimension `size` (holding about `matrices` such N×N f64 matrices)
/// before allocating: beyond `limit` it would take minutes, and beyond the memory available
/// (Linux `MemAvailable`) it would abort.
pub(crate) fn check_dense_size(
    what: &'static str,
    size: usize,
    limit: usize,
    matrices: usize,
) -> Result<()> {
    if size > limit {
        return Err(Error::TooLarge {
            what,
            size,
            limit,
            reason: "the dense O(N^3) set-up would take minutes",
        });
    }
    if let Some(avail) = available_memory() {
        let per = 8.0 * matrices.max(1) as f64;
        let limit = (avail as f64 / per).sqrt() as usize;
        if size > limit {
            return Err(Error::TooLarge {
                what,
                size,
                limit,
                reason: "the dense set-up would not fit in the available memory",
            });
        }
    }
    Ok(())
}

/// Bytes of memory available now (Linux /proc/meminfo), if known.
fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
