//! Real-number arguments: the one rule by which every array or number the package takes is
//! read. Numbers whose numpy dtype is boolean, integer or floating point are accepted; a
//! complex, object, string or other dtype is a `TypeError` naming the argument and the dtype.
//! (numpy would otherwise cast a complex array to float, keeping the real part with only a
//! `ComplexWarning`, and parse an array of strings as numbers.) [`real_array`] converts an
//! array argument to float64 under this rule; a [`Real`] argument checks it before extracting
//! a number or a sequence; the Python wrappers call [`real_array`] through
//! `stabilis._arrays.real_array`. Number arguments follow the rule too: `Option<Real<f64>>`, or
//! `#[pyo3(from_py_with = real)] x: f64`, which keeps a default such as `nu=0.7` readable in
//! the Python signature (a `Real(0.7)` default shows as `...`); the Python wrappers convert a
//! number with [`real_scalar`] (`stabilis._arrays.real_scalar`) where they called `float()`. A
//! Python `complex` is refused even with a zero imaginary part, like a complex array.
use numpy::{PyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyComplex, PyList, PyTuple};

/// The numpy dtype kinds read as real numbers: boolean, signed and unsigned integer, float.
const REAL_KINDS: [&str; 4] = ["b", "i", "u", "f"];

/// The dtype of a numpy array or scalar whose values are not real numbers (`complex128`,
/// `object`, `<U3`...); None for a real dtype and for objects without a numpy dtype.
fn refused_dtype(obj: &Bound<'_, PyAny>) -> PyResult<Option<String>> {
    let Ok(dtype) = obj.getattr("dtype") else {
        return Ok(None);
    };
    // Objects with a `dtype` that is not numpy's (no `kind`) are left to the conversion.
    let Ok(kind) = dtype.getattr("kind").and_then(|k| k.extract::<String>()) else {
        return Ok(None);
    };
    if REAL_KINDS.contains(&kind.as_str()) {
        return Ok(None);
    }
    Ok(Some(dtype.str()?.to_string()))
}

/// The `TypeError` for values of dtype `dtype` where `expected` ("x must hold") wants real
/// numbers.
fn refusal(expected: &str, dtype: &str) -> PyErr {
    let hint = if dtype.starts_with("complex") {
        " (pass .real to drop the imaginary part)"
    } else {
        ""
    };
    PyTypeError::new_err(format!("{expected} real numbers; got dtype {dtype}{hint}"))
}

/// `value` (anything `numpy.asarray` accepts) as a C-contiguous float64 array; `TypeError`
/// naming `name` and the dtype when its values are not real numbers (see the module doc).
pub fn real_array<'py>(
    value: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    if let Ok(array) = value.cast::<PyArrayDyn<f64>>() {
        if array.is_c_contiguous() {
            return Ok(array.clone());
        }
    }
    let np = value.py().import("numpy")?;
    let array = np.call_method1("asarray", (value,)).map_err(|e| {
        let message = format!("{name}: {}", e.value(value.py()));
        if e.is_instance_of::<PyTypeError>(value.py()) {
            PyTypeError::new_err(message)
        } else {
            PyValueError::new_err(message)
        }
    })?;
    if let Some(dtype) = refused_dtype(&array)? {
        return Err(refusal(&format!("{name} must hold"), &dtype));
    }
    let array = np.call_method1("ascontiguousarray", (array, "float64"))?;
    Ok(array.cast_into::<PyArrayDyn<f64>>()?)
}

/// `stabilis._arrays.real_array(x, name="argument")`: [`real_array`] for the Python wrappers.
#[pyfunction]
#[pyo3(name = "real_array", signature = (x, name = "argument"))]
fn py_real_array<'py>(x: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    real_array(x, name)
}

/// An argument extracted as `T` (`f64`, `Vec<f64>`, `[f64; 3]`...) after checking that it
/// holds no value of a refused dtype (see the module doc).
#[derive(Debug, Clone)]
pub struct Real<T>(pub T);

/// The dtype of the first value in `obj` (a number, a numpy array, or a list or tuple of
/// them) that is not a real number: a Python complex is `complex`.
fn refused(obj: &Bound<'_, PyAny>) -> PyResult<Option<String>> {
    if obj.is_instance_of::<PyComplex>() {
        return Ok(Some("complex".to_string()));
    }
    if let Some(dtype) = refused_dtype(obj)? {
        return Ok(Some(dtype));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        for item in obj.try_iter()? {
            if let Some(dtype) = refused(&item?)? {
                return Ok(Some(dtype));
            }
        }
    }
    Ok(None)
}

/// `TypeError` naming `name` and the dtype when `obj` (a number, a numpy array, or a list or
/// tuple of them) holds a value that is not a real number.
pub fn check_real(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    match refused(obj)? {
        Some(dtype) => Err(refusal(&format!("{name} must hold"), &dtype)),
        None => Ok(()),
    }
}

impl<'a, 'py, T> FromPyObject<'a, 'py> for Real<T>
where
    T: for<'b> FromPyObject<'b, 'py>,
    PyErr: for<'b> From<<T as FromPyObject<'b, 'py>>::Error>,
{
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if let Some(dtype) = refused(&obj)? {
            // pyo3 adds the note "while processing 'ARG'" naming the argument.
            return Err(refusal("expected", &dtype));
        }
        Ok(Self(obj.extract::<T>()?))
    }
}

/// A number argument, `#[pyo3(from_py_with = real)] x: f64`: a [`Real<f64>`] whose default
/// stays a plain number in the Python signature.
pub fn real(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    Ok(obj.extract::<Real<f64>>()?.0)
}

/// `stabilis._arrays.real_scalar(x, name="argument")`: `x` as a float by the rule of a
/// `Real<f64>` argument, for the Python wrappers (`float(x)` keeps the real part of a numpy
/// complex and parses a string); a `TypeError` names `name`.
#[pyfunction]
#[pyo3(signature = (x, name = "argument"))]
pub fn real_scalar(x: &Bound<'_, PyAny>, name: &str) -> PyResult<f64> {
    check_real(x, name)?;
    x.extract().map_err(|e: PyErr| {
        if e.is_instance_of::<PyTypeError>(x.py()) {
            PyTypeError::new_err(format!("{name}: {}", e.value(x.py())))
        } else {
            e
        }
    })
}

/// Adds `real_array` and `real_scalar` to the native module.
pub fn register(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(py_real_array, module)?)?;
    module.add_function(wrap_pyfunction!(real_scalar, module)?)
}
