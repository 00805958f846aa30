//! The crate's one error type; every message names the offending input.

use thiserror::Error;

/// Errors of `pmpc`.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Error {
    /// A matrix or vector has the wrong shape.
    #[error("{name} is {rows}x{cols}, expected {expected_rows}x{expected_cols}")]
    Shape {
        /// Name of the input (A, B, Q, R, Cx, Cu, lower, upper, x).
        name: &'static str,
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
        /// Required rows.
        expected_rows: usize,
        /// Required columns.
        expected_cols: usize,
    },
    /// An input contains NaN or infinity.
    #[error("{0} contains NaN or an infinite entry")]
    NonFinite(&'static str),
    /// A scalar parameter is out of range.
    #[error("{name} = {value} is invalid: {requirement}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },
    /// Q or R is not symmetric positive definite.
    #[error("{0} must be symmetric positive definite")]
    NotPositiveDefinite(&'static str),
    /// Constraint limits must satisfy lower <= 0 <= upper (the origin must be admissible).
    #[error("constraint row {row}: limits [{lower}, {upper}] must satisfy lower <= 0 <= upper")]
    Limits {
        /// Row index.
        row: usize,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// Fewer degrees of freedom than initial conditions: m·s < n.
    #[error("s = {s} basis functions leave m*s - n < 0 degrees of freedom for n = {n} states and m = {m} inputs; increase s")]
    TooFewBasisFunctions {
        /// Basis size.
        s: usize,
        /// States.
        n: usize,
        /// Inputs.
        m: usize,
    },
    /// The Galerkin dynamics are singular (e.g. −ν is an eigenvalue of A).
    #[error("the equality constraints of the parametrized problem are rank deficient (smallest relative singular value {0:e}); choose another nu")]
    RankDeficient(f64),
    /// No trajectory in the span satisfies the constraints from this state.
    #[error("no input trajectory in the basis span satisfies the constraints from x = {x:?}")]
    Infeasible {
        /// The state.
        x: Vec<f64>,
    },
    /// The solver stopped before convergence and there is no previous plan to fall back on.
    #[error("the semi-infinite QP did not converge ({0}) and no previous plan exists")]
    NotConverged(&'static str),
    /// A generic solver (Clarabel, OSQP) failed.
    #[error("{solver} failed: {status}")]
    Solver {
        /// Solver name.
        solver: &'static str,
        /// Its status.
        status: String,
    },
    /// A problem dimension exceeds what the dense offline set-up can hold or finish promptly.
    #[error("{what} = {size} is too large: the limit is {limit} ({reason})")]
    TooLarge {
        /// Which dimension (e.g. "decision variables (n+m)*s").
        what: &'static str,
        /// The size asked for.
        size: usize,
        /// The largest size accepted on this machine.
        limit: usize,
        /// Why the limit exists.
        reason: &'static str,
    },
    /// Error from the shared numerics of `rigid_body`.
    #[error(transparent)]
    Core(#[from] rigid_body::Error),
}

/// Result type of this crate.
pub type Result<T> = core::result::Result<T, Error>;
