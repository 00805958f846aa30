//! The crate's one error type: every message names the offending input.

use thiserror::Error;

/// Errors of `rigid_body`: bad shapes, non-finite data, degenerate geometry and
/// linear-systems problems that have no (unique, stabilizing) solution.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum Error {
    /// A matrix that must be square is not.
    #[error("{name} is {rows}x{cols}, must be square")]
    NotSquare {
        /// Name of the matrix (as in the documentation, e.g. "A").
        name: &'static str,
        /// Its number of rows.
        rows: usize,
        /// Its number of columns.
        cols: usize,
    },
    /// A matrix has a shape incompatible with the others.
    #[error("{name} is {rows}x{cols}, expected {expected_rows}x{expected_cols}")]
    DimensionMismatch {
        /// Name of the matrix.
        name: &'static str,
        /// Its number of rows.
        rows: usize,
        /// Its number of columns.
        cols: usize,
        /// Rows it must have.
        expected_rows: usize,
        /// Columns it must have.
        expected_cols: usize,
    },
    /// An input contains NaN or infinity.
    #[error("{name} contains a non-finite entry (NaN or infinity)")]
    NonFinite {
        /// Name of the input.
        name: &'static str,
    },
    /// A matrix that must be symmetric is not.
    #[error("{name} is not symmetric")]
    NotSymmetric {
        /// Name of the matrix.
        name: &'static str,
    },
    /// A matrix that must be positive definite is not.
    #[error("{name} is not positive definite")]
    NotPositiveDefinite {
        /// Name of the matrix.
        name: &'static str,
    },
    /// A matrix that must be positive semidefinite has a negative eigenvalue.
    #[error("{name} is not positive semidefinite (eigenvalue {eigenvalue})")]
    NotPositiveSemidefinite {
        /// Name of the matrix.
        name: &'static str,
        /// Its most negative eigenvalue.
        eigenvalue: f64,
    },
    /// A scalar parameter is out of its admissible range.
    #[error("{name} = {value} is invalid: {requirement}")]
    InvalidParameter {
        /// Name of the parameter.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What the parameter must satisfy.
        requirement: &'static str,
    },
    /// A matrix that must be a rotation is not orthonormal with determinant +1.
    #[error("{name} is not a rotation matrix (|R^T R - I| = {orthogonality_error}, det = {determinant})")]
    NotRotation {
        /// Name of the matrix.
        name: &'static str,
        /// Frobenius norm of `R^T R - I`.
        orthogonality_error: f64,
        /// Its determinant.
        determinant: f64,
    },
    /// A vector whose direction is needed is (numerically) zero.
    #[error("{name} is the zero vector; its direction is undefined")]
    ZeroVector {
        /// Name of the vector.
        name: &'static str,
    },
    /// The pair (A, B) has an uncontrollable mode that is not asymptotically stable.
    #[error("(A, B) is not stabilizable: the mode {re} + {im}i of A is uncontrollable")]
    NotStabilizable {
        /// Real part of the offending eigenvalue of A.
        re: f64,
        /// Imaginary part of the offending eigenvalue of A.
        im: f64,
    },
    /// The pair (A, Q) has an unobservable mode that is not asymptotically stable.
    #[error("(A, Q) is not detectable: the mode {re} + {im}i of A is unobservable through Q")]
    NotDetectable {
        /// Real part of the offending eigenvalue of A.
        re: f64,
        /// Imaginary part of the offending eigenvalue of A.
        im: f64,
    },
    /// A is not asymptotically stable where the problem requires it (e.g. an infinite-horizon
    /// Gramian).
    #[error("A is not {kind}: it has the eigenvalue {re} + {im}i")]
    Unstable {
        /// "Hurwitz" (continuous time) or "Schur stable" (discrete time).
        kind: &'static str,
        /// Real part of the offending eigenvalue.
        re: f64,
        /// Imaginary part of the offending eigenvalue.
        im: f64,
    },
    /// A (discrete or continuous) Lyapunov equation has no unique solution because two
    /// eigenvalues of A are in the reflected position.
    #[error("the {equation} equation is singular: eigenvalues {re1} + {im1}i and {re2} + {im2}i of A are reflected")]
    SingularEquation {
        /// "Lyapunov" or "discrete Lyapunov".
        equation: &'static str,
        /// First eigenvalue, real part.
        re1: f64,
        /// First eigenvalue, imaginary part.
        im1: f64,
        /// Second eigenvalue, real part.
        re2: f64,
        /// Second eigenvalue, imaginary part.
        im2: f64,
    },
    /// An iterative algorithm did not converge within its budget.
    #[error("{algorithm} did not converge within {iterations} iterations")]
    NoConvergence {
        /// Name of the algorithm.
        algorithm: &'static str,
        /// The iteration budget.
        iterations: usize,
    },
    /// A linear system that must be solved is numerically singular.
    #[error("{name} is singular")]
    Singular {
        /// Name of the matrix.
        name: &'static str,
    },
    /// A frequency response cannot be evaluated: its matrix is singular at that frequency.
    #[error("{name} is singular at {frequency_hz:.4} Hz")]
    SingularAt {
        /// Name of the matrix and what its singularity means.
        name: &'static str,
        /// The frequency, Hz.
        frequency_hz: f64,
    },
}
