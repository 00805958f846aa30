//! The one error type of the crate: every variant names the offending input.

/// Why a layout, a measurement or a tuning was rejected.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum TiltError {
    /// Fewer than three accelerometers cannot determine tilt, angular velocity and angular acceleration.
    #[error("{got} sensor positions given; at least 3 accelerometers are needed")]
    TooFewSensors {
        /// Number of positions supplied.
        got: usize,
    },
    /// The layout exceeds the fixed capacity of [`crate::Layout`].
    #[error("{got} sensor positions given; at most {max} are supported")]
    TooManySensors {
        /// Number of positions supplied.
        got: usize,
        /// Capacity ([`crate::MAX_SENSORS`]).
        max: usize,
    },
    /// A sensor position contains NaN or infinity.
    #[error("position of sensor {sensor} is not finite")]
    NonFinitePosition {
        /// Index of the sensor.
        sensor: usize,
    },
    /// The positions do not span R^3 (all sensors on a plane or line through the pivot): the
    /// least-squares start is undetermined and the Fisher information is singular whenever
    /// omega lies in that plane or along its normal (and always for a line).
    #[error("sensor positions span only a {rank}-dimensional subspace (coplanar with the pivot); they must span R^3")]
    PositionsDoNotSpan {
        /// Numerical rank of `sum p_i p_i^T`.
        rank: usize,
    },
    /// Number of measurement vectors differs from the number of sensors.
    #[error("{got} measurements given for a layout of {expected} sensors")]
    MeasurementCount {
        /// Sensors in the layout.
        expected: usize,
        /// Measurements supplied.
        got: usize,
    },
    /// The measurements are so large that the cost or the estimate overflows f64.
    #[error("the estimate overflows (its cost or state is not finite): the largest measurement component, {largest:e} m/s^2, is too large")]
    Overflow {
        /// Largest absolute measurement component.
        largest: f64,
    },
    /// A measurement contains NaN or infinity.
    #[error("measurement of sensor {sensor} is not finite")]
    NonFiniteMeasurement {
        /// Index of the sensor.
        sensor: usize,
    },
    /// A bias vector contains NaN or infinity.
    #[error("bias of sensor {sensor} is not finite")]
    NonFiniteBias {
        /// Index of the sensor.
        sensor: usize,
    },
    /// Step sizes must be positive and finite, the tolerance positive, the budget non-zero.
    #[error("invalid option {name} = {value}: {requirement}")]
    InvalidOption {
        /// Name of the option (`q`, `r`, `tol`, `max_iterations`, ...).
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What the option must satisfy.
        requirement: &'static str,
    },
    /// A state passed to the information tools is not finite or gravity has zero length.
    #[error("invalid state: {0}")]
    InvalidState(&'static str),
    /// A projection of the core geometry failed (non-finite iterate or eigen-solver failure).
    #[error("projection failed: {0}")]
    Geometry(#[from] rigid_body::Error),
    /// The Fisher information is singular, so the Cramer-Rao bound is infinite.
    #[error("Fisher information is singular (rank {rank} of 8); the Cramer-Rao bound does not exist at this state")]
    SingularFisher {
        /// Numerical rank of the 8x8 Fisher information.
        rank: usize,
    },
}
