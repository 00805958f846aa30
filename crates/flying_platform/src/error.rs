//! The crate's single error type: every message names the offending input.

/// Errors of the flying-platform crate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A named parameter is outside its documented bounds or not finite.
    #[error("parameter `{name}` = {value} is outside its bounds [{lower}, {upper}]")]
    OutOfBounds {
        /// Parameter name.
        name: String,
        /// Offending value.
        value: f64,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
    },
    /// A parameter name that no enabled effect declares.
    #[error("unknown parameter `{0}` (not declared by any enabled effect)")]
    UnknownParameter(String),
    /// An effect name that is not one of the four known effects.
    #[error(
        "unknown effect `{0}` (known: momentum_drag, fan_gyroscopic, actuator_lag, input_delay)"
    )]
    UnknownEffect(String),
    /// A vector or matrix argument with the wrong length or shape.
    #[error("`{what}` has length {got}, expected {expected}")]
    Length {
        /// Which argument.
        what: &'static str,
        /// Length received.
        got: usize,
        /// Length expected.
        expected: usize,
    },
    /// A physical or design parameter with an invalid value (non-positive mass, ...).
    #[error("invalid `{name}`: {reason}")]
    Invalid {
        /// Which parameter or setting.
        name: &'static str,
        /// Why it is rejected.
        reason: String,
    },
    /// A numerical step failed (singular matrix at a frequency, ...).
    #[error("numerical failure in {0}")]
    Numerical(String),
    /// The closed-loop simulation left the region where the model is meaningful.
    #[error("simulation diverged at t = {t:.3} s: {reason}")]
    Diverged {
        /// Time of divergence in seconds.
        t: f64,
        /// What exceeded its limit.
        reason: String,
    },
}

/// Result alias of this crate.
pub type Result<T> = core::result::Result<T, Error>;

/// Rejects a non-finite or non-positive value of a named quantity.
pub(crate) fn require_positive(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::Invalid {
            name,
            reason: format!("must be finite and > 0, got {value}"),
        })
    }
}

/// Rejects a non-finite value of a named quantity.
pub(crate) fn require_finite(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(Error::Invalid {
            name,
            reason: format!("must be finite, got {value}"),
        })
    }
}
