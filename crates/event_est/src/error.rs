//! The crate's one error type: every variant names the offending input or condition.

#[cfg(feature = "std")]
use std::string::String;

/// Errors of the runtime, the models, the simulator and the synthesis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EventEstError {
    /// A matrix or vector has the wrong shape.
    #[error(
        "{name} has shape {found_rows}x{found_cols}, expected {expected_rows}x{expected_cols}"
    )]
    Dimension {
        /// Which input.
        name: &'static str,
        /// Expected rows.
        expected_rows: usize,
        /// Expected columns.
        expected_cols: usize,
        /// Rows given.
        found_rows: usize,
        /// Columns given.
        found_cols: usize,
    },
    /// Block sizes (outputs or inputs per agent) do not add up to the matrix dimension.
    #[error("{name}: agent block sizes sum to {sum}, but the matrices have {expected}")]
    BlockSizes {
        /// Which partition.
        name: &'static str,
        /// Sum of the block sizes.
        sum: usize,
        /// Matrix dimension they must cover.
        expected: usize,
    },
    /// An agent index beyond the number of agents.
    #[error("agent index {index} out of range (network has {agents} agents)")]
    AgentIndex {
        /// Index given.
        index: usize,
        /// Number of agents.
        agents: usize,
    },
    /// An input contains NaN or infinity.
    #[error("{name} contains a non-finite entry")]
    NonFinite {
        /// Which input.
        name: &'static str,
    },
    /// A name (of a stability condition, a solver) that is unknown or not accepted here
    /// (names are parsed by the std-only synthesis, so the variant needs `String`).
    #[cfg(feature = "std")]
    #[error("{what} {given:?} is not accepted: {reason}")]
    Name {
        /// What the name selects.
        what: &'static str,
        /// The name as given.
        given: String,
        /// The names accepted.
        reason: &'static str,
    },
    /// A scalar parameter is outside its valid range.
    #[error("{name} = {value} is invalid: {reason}")]
    Parameter {
        /// Which parameter.
        name: &'static str,
        /// Value given.
        value: f64,
        /// What is required.
        reason: &'static str,
    },
    /// The communicated-input mode needs the true previous input.
    #[error("input mode Communicated needs the previous plant input u(k-1)")]
    MissingInput,
    /// A matrix that must be symmetric positive definite is not.
    #[error("{name} is not symmetric positive definite")]
    NotPositiveDefinite {
        /// Which matrix.
        name: &'static str,
    },
    /// A matrix that must be invertible is singular.
    #[error("{name} is singular")]
    Singular {
        /// Which matrix.
        name: &'static str,
    },
    /// The state feedback does not stabilise the plant.
    #[error("A+BF is not Schur stable (spectral radius {rho})")]
    UnstableFeedback {
        /// Spectral radius of A+BF.
        rho: f64,
    },
    /// A Riccati or Lyapunov equation has no stabilising solution.
    #[cfg(feature = "std")]
    #[error("{what}: {reason}")]
    Lti {
        /// Which equation (e.g. "Kalman filter DARE for (A, C)").
        what: &'static str,
        /// The underlying failure.
        reason: String,
    },
    /// The SDP is infeasible; `condition` names the LMI set that cannot be met.
    #[cfg(feature = "std")]
    #[error("{problem} is infeasible ({status}): {condition}")]
    Infeasible {
        /// Which problem (Step 1, Step 2, ...).
        problem: &'static str,
        /// The solver's status.
        status: String,
        /// The conditions that cannot be met together.
        condition: String,
    },
    /// The SDP solver stopped without a usable solution.
    #[cfg(feature = "std")]
    #[error("{problem}: the SDP solver stopped with status {status}")]
    Solver {
        /// Which problem.
        problem: &'static str,
        /// The solver's status.
        status: String,
    },
    /// A returned certificate fails the eigenvalue check of one LMI.
    #[cfg(feature = "std")]
    #[error("post-verification failed for {condition}: margin {margin:e}")]
    Verification {
        /// The LMI or property that fails.
        condition: String,
        /// The violating value (e.g. the largest eigenvalue that should be negative).
        margin: f64,
    },
    /// Step 2 has no budget left: J_max must exceed the full-communication cost c*.
    #[error("J_max = {j_max} does not exceed the full-communication cost c* = {c_star}")]
    Budget {
        /// Requested bound.
        j_max: f64,
        /// Step-1 cost.
        c_star: f64,
    },
}
