//! The one error type of the crate: every variant names the offending input.
use thiserror::Error;

/// Errors of the Cubli model, controllers and learning.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum CubliError {
    /// A parameter or state field holds NaN or infinity.
    #[error("`{field}` is not finite (NaN or infinite)")]
    NonFinite {
        /// Name of the field.
        field: &'static str,
    },
    /// A scalar that must be positive is zero or negative.
    #[error("`{field}` must be positive, got {value}")]
    NonPositive {
        /// Name of the field.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
    /// An inertia matrix is not symmetric.
    #[error("inertia `{field}` is not symmetric (largest asymmetry {asymmetry:e})")]
    NotSymmetric {
        /// Name of the field.
        field: &'static str,
        /// max |A - A^T|.
        asymmetry: f64,
    },
    /// An inertia matrix is not positive definite.
    #[error("inertia `{field}` is not positive definite")]
    NotPositiveDefinite {
        /// Name of the field.
        field: &'static str,
    },
    /// The gravity vector of a reduced state does not have the magnitude |g| of the parameters.
    #[error("gravity vector `g` has magnitude {actual}, expected |g| = {expected}")]
    GravityMagnitude {
        /// |g| of the parameters.
        expected: f64,
        /// |g| of the state.
        actual: f64,
    },
    /// The feedback linearization is undefined near 90 degrees inclination (inertial m_3 ~ 0).
    #[error("feedback linearization singular: inertial m_3 = {m3:e} is below {threshold:e} (inclination near 90 degrees)")]
    LinearizationSingular {
        /// Vertical component of the inertial centre-of-mass vector m.
        m3: f64,
        /// The refusal threshold epsilon |m|.
        threshold: f64,
    },
    /// The centre of mass lies on the gravity line (upright or hanging): the tilt axis e_phi is undefined.
    #[error("tilt axis e_phi undefined: m is parallel to g")]
    TiltAxisUndefined,
    /// Desired closed-loop poles must have negative real part and come in conjugate pairs.
    #[error("pole {index} ({re} + {im}i) is not admissible: {reason}")]
    InvalidPole {
        /// Index of the pole.
        index: usize,
        /// Real part.
        re: f64,
        /// Imaginary part.
        im: f64,
        /// Why it is refused.
        reason: &'static str,
    },
    /// The chosen yaw gain gamma_hat lies outside the admissible set (1.35).
    #[error("gamma_hat = {gamma_hat} is not admissible: needs 0 < gamma_hat < A = {a} and h(gamma_hat) = {h} > 0")]
    InadmissibleGamma {
        /// The requested gamma_hat.
        gamma_hat: f64,
        /// Coefficient A of the tilt polynomial.
        a: f64,
        /// h(gamma_hat).
        h: f64,
    },
    /// An edge jump needs an edge of the resting face (normal −e3): body axis 0 or 1.
    #[error("edge axis {axis} is not an edge of the resting face (use 0 or 1)")]
    EdgeAxis {
        /// The requested body axis index.
        axis: usize,
    },
    /// The learning step size must lie in (0, 2).
    #[error("learning step size lambda = {0} must lie in (0, 2)")]
    StepSize(f64),
    /// The model Jacobian of the jump has no usable pseudoinverse.
    #[error("jump model Jacobian is rank deficient (m parallel to g at the start?)")]
    SingularJacobian,
    /// A sample time or step is not positive or does not divide the run sensibly.
    #[error("`{field}` = {value} is not a valid time step")]
    TimeStep {
        /// Name of the field.
        field: &'static str,
        /// The offending value.
        value: f64,
    },
}
