//! Python exceptions of stabilis and the conversion of Rust errors into them: `ValueError` for
//! bad shapes and lengths, `stabilis.Error` (or a subclass) for everything else, with the Rust
//! message unchanged. Domain files implement [`IntoPyError`] for their crate's error enum.
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;

create_exception!(
    stabilis,
    Error,
    PyException,
    "Base class of every stabilis error."
);
create_exception!(
    stabilis,
    LogError,
    Error,
    "A log (MCAP or CSV) is missing, malformed, or lacks a topic or field."
);
create_exception!(
    stabilis,
    ModelError,
    Error,
    "A model file or Python model is malformed (the message names the file, key and problem)."
);
create_exception!(
    stabilis,
    SimError,
    Error,
    "Invalid options or values, or data the workbench refuses (an unknown effect, logs in other units than the model's or far from its operating point), or a computation that diverged."
);

/// A Rust error that knows which Python exception it becomes.
pub trait IntoPyError {
    /// The Python exception carrying this error's message.
    fn into_py_error(self) -> PyErr;
}

/// `map_err(to_py_err)` turns any [`IntoPyError`] into a `PyErr`.
pub fn to_py_err<E: IntoPyError>(error: E) -> PyErr {
    error.into_py_error()
}

impl IntoPyError for sim::SimError {
    fn into_py_error(self) -> PyErr {
        use sim::SimError as E;
        let message = self.to_string();
        match self {
            E::LengthMismatch { .. }
            | E::StateSpace(
                rigid_body::Error::NotSquare { .. } | rigid_body::Error::DimensionMismatch { .. },
            ) => PyValueError::new_err(message),
            E::FileNotFound { .. }
            | E::Io { .. }
            | E::NotMcap { .. }
            | E::Mcap { .. }
            | E::Csv { .. }
            | E::MissingTopic { .. }
            | E::MissingField { .. }
            | E::NotFinite { .. }
            | E::BadMessage { .. } => LogError::new_err(message),
            E::ModelFile { .. } => ModelError::new_err(message),
            E::InvalidParameter { .. } | E::Domain { .. } | E::StateSpace(_) => {
                SimError::new_err(message)
            }
            E::UnsafeOutput { .. } => Error::new_err(message),
            E::Cancelled => pyo3::exceptions::PyKeyboardInterrupt::new_err(message),
        }
    }
}

impl IntoPyError for rigid_body::Error {
    fn into_py_error(self) -> PyErr {
        use rigid_body::Error as E;
        let message = self.to_string();
        match self {
            E::NotSquare { .. } | E::DimensionMismatch { .. } => PyValueError::new_err(message),
            _ => Error::new_err(message),
        }
    }
}

/// Adds the exception classes to the native module.
pub fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = module.py();
    module.add("Error", py.get_type::<Error>())?;
    module.add("LogError", py.get_type::<LogError>())?;
    module.add("SimError", py.get_type::<SimError>())?;
    module.add("ModelError", py.get_type::<ModelError>())?;
    Ok(())
}
