//! Real-number arguments that refuse complex values. pyo3 converts a numpy complex through
//! `__float__`, which keeps the real part and only warns; a [`Real`] argument raises
//! `TypeError` instead.
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyComplex, PyList, PyTuple};

/// An argument extracted as `T` (`f64`, `Vec<f64>`, `[f64; 3]`...) after checking that it
/// holds no complex number.
#[derive(Debug, Clone)]
pub struct Real<T>(pub T);

/// Whether `obj` is a complex number, a complex numpy array, or a list or tuple holding one.
fn holds_complex(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    if obj.is_instance_of::<PyComplex>() {
        return Ok(true);
    }
    if let Ok(dtype) = obj.getattr("dtype") {
        return Ok(dtype.getattr("kind")?.extract::<String>()? == "c");
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        for item in obj.try_iter()? {
            if holds_complex(&item?)? {
                return Ok(true);
            }
        }
    }
    Ok(false)
}

impl<'a, 'py, T> FromPyObject<'a, 'py> for Real<T>
where
    T: for<'b> FromPyObject<'b, 'py>,
    PyErr: for<'b> From<<T as FromPyObject<'b, 'py>>::Error>,
{
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if holds_complex(&obj)? {
            return Err(PyTypeError::new_err(
                "expected real numbers, got complex values (pass .real to drop the imaginary part)",
            ));
        }
        Ok(Self(obj.extract::<T>()?))
    }
}
