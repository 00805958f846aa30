//! Python bindings of the rigid_body geometry: `so3`, `s2` and `matrix_set`, on single items
//! (`(3,)`, `(3, 3)`) or batches (`(N, 3)`, `(N, 3, 3)`) of float64 arrays.

use nalgebra::{Matrix3, Vector3};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rigid_body::{matrix_set, s2, so3};

use crate::errors::to_py_err;
use crate::real::real;

const VECTOR: &[usize] = &[3];
const MATRIX: &[usize] = &[3, 3];

fn shape_text(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    if parts.len() == 1 {
        format!("({},)", parts[0])
    } else {
        format!("({})", parts.join(", "))
    }
}

/// Checks the shape (`item` or `(N,) + item`) and finiteness of `x`, then applies `f` to each
/// item (row-major data) and assembles the outputs with item shape `out`.
fn map_items<'py>(
    py: Python<'py>,
    x: &PyReadonlyArrayDyn<'py, f64>,
    name: &str,
    item: &[usize],
    out: &[usize],
    f: impl Fn(&[f64]) -> PyResult<Vec<f64>>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let shape = x.shape();
    let batch = if shape == item {
        None
    } else if shape.len() == item.len() + 1 && &shape[1..] == item {
        Some(shape[0])
    } else {
        let mut batched = vec![0];
        batched.extend_from_slice(item);
        return Err(PyValueError::new_err(format!(
            "{name} must have shape {} or {}, got {}",
            shape_text(item),
            shape_text(&batched).replacen('0', "N", 1),
            shape_text(shape)
        )));
    };
    let data: Vec<f64> = x.as_array().iter().copied().collect();
    if data.iter().any(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name} contains NaN or infinity"
        )));
    }
    let size: usize = item.iter().product();
    let mut result = Vec::with_capacity(data.len() / size.max(1) * out.iter().product::<usize>());
    for chunk in data.chunks(size) {
        result.extend(f(chunk)?);
    }
    let mut out_shape: Vec<usize> = batch.into_iter().collect();
    out_shape.extend_from_slice(out);
    let array = ArrayD::from_shape_vec(IxDyn(&out_shape), result)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(array.into_pyarray(py))
}

fn vector(d: &[f64]) -> Vector3<f64> {
    Vector3::new(d[0], d[1], d[2])
}

fn matrix(d: &[f64]) -> Matrix3<f64> {
    Matrix3::from_row_slice(d)
}

fn rows(m: &Matrix3<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

/// Applies a vector-to-matrix function to `(3,)` or `(N, 3)` input.
fn vector_to_matrix<'py>(
    py: Python<'py>,
    x: &PyReadonlyArrayDyn<'py, f64>,
    name: &str,
    f: impl Fn(&Vector3<f64>) -> Matrix3<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, x, name, VECTOR, MATRIX, |d| Ok(rows(&f(&vector(d)))))
}

/// Defines a Python function that applies a vector-to-matrix map to its one array argument.
macro_rules! vector_to_matrix_fn {
    ($(#[$doc:meta])* $name:ident($arg:ident) => $f:expr) => {
        $(#[$doc])*
        #[pyfunction]
        fn $name<'py>(
            py: Python<'py>,
            $arg: PyReadonlyArrayDyn<'py, f64>,
        ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
            vector_to_matrix(py, &$arg, stringify!($arg), $f)
        }
    };
}

vector_to_matrix_fn! {
    /// Skew matrix `[w]x` with `[w]x v = w x v`.
    hat(w) => so3::hat
}

/// Vector of the skew-symmetric part of `s` (inverse of `hat`).
#[pyfunction]
fn vee<'py>(
    py: Python<'py>,
    s: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &s, "s", MATRIX, VECTOR, |d| {
        Ok(so3::vee(&matrix(d)).as_slice().to_vec())
    })
}

vector_to_matrix_fn! {
    /// Rotation matrix `exp([w]x)` of a rotation vector `w`.
    exp(w) => |w| *so3::exp(w).matrix()
}

/// Rotation vector (angle at most pi) of a rotation matrix.
#[pyfunction]
fn log<'py>(
    py: Python<'py>,
    r: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &r, "r", MATRIX, VECTOR, |d| {
        let rot = so3::rotation("r", &matrix(d)).map_err(to_py_err)?;
        Ok(so3::log(&rot).as_slice().to_vec())
    })
}

/// ZYX Euler angles `(roll, pitch, yaw)` with `R = Rz(yaw) Ry(pitch) Rx(roll)`.
#[pyfunction]
fn euler_zyx<'py>(
    py: Python<'py>,
    r: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &r, "r", MATRIX, VECTOR, |d| {
        let rot = so3::rotation("r", &matrix(d)).map_err(to_py_err)?;
        let (roll, pitch, yaw) = so3::euler_zyx(&rot);
        Ok(vec![roll, pitch, yaw])
    })
}

vector_to_matrix_fn! {
    /// Rotation matrix `Rz(yaw) Ry(pitch) Rx(roll)` from `(roll, pitch, yaw)`.
    from_euler_zyx(angles) => |a| *so3::from_euler_zyx(a.x, a.y, a.z).matrix()
}

vector_to_matrix_fn! {
    /// Right Jacobian `J_r(w)`: `exp(w + d) ≈ exp(w) exp(J_r d)`.
    right_jacobian(w) => so3::right_jacobian
}

vector_to_matrix_fn! {
    /// Left Jacobian `J_l(w)`: `exp(w + d) ≈ exp(J_l d) exp(w)`.
    left_jacobian(w) => so3::left_jacobian
}

vector_to_matrix_fn! {
    /// Inverse of the right Jacobian.
    right_jacobian_inverse(w) => so3::right_jacobian_inverse
}

vector_to_matrix_fn! {
    /// Inverse of the left Jacobian.
    left_jacobian_inverse(w) => so3::left_jacobian_inverse
}

/// Nearest point of the sphere of radius `radius` (default g0 = 9.81) to `x`.
#[pyfunction]
#[pyo3(name = "project", signature = (x, radius = s2::G0))]
fn s2_project<'py>(
    py: Python<'py>,
    x: PyReadonlyArrayDyn<'py, f64>,
    #[pyo3(from_py_with = real)] radius: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &x, "x", VECTOR, VECTOR, |d| {
        let p = s2::project(&vector(d), radius).map_err(to_py_err)?;
        Ok(p.as_slice().to_vec())
    })
}

/// Projector `I - n n^T` onto the tangent plane at the direction `n = x / |x|`.
#[pyfunction]
fn tangent_projector<'py>(
    py: Python<'py>,
    x: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &x, "x", VECTOR, MATRIX, |d| {
        let p = s2::tangent_projector(&vector(d)).map_err(to_py_err)?;
        Ok(rows(&p))
    })
}

/// Frobenius-nearest point of `M = {[w]x^2 + [h]x}` to `a`.
#[pyfunction]
#[pyo3(name = "project")]
fn matrix_set_project<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &a, "a", MATRIX, MATRIX, |d| {
        let p = matrix_set::project(&matrix(d)).map_err(to_py_err)?;
        Ok(rows(&p.matrix))
    })
}

/// Factors `(w, h)` of the projection of `a` onto M: `project(a) = [w]x^2 + [h]x`, with the sign
/// of `w` fixed so that its largest-magnitude component is positive. Returns an array of
/// shape `(2, 3)` (or `(N, 2, 3)`): row 0 is `w`, row 1 is `h`.
#[pyfunction]
fn factors<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    map_items(py, &a, "a", MATRIX, &[2, 3], |d| {
        let p = matrix_set::project(&matrix(d)).map_err(to_py_err)?;
        Ok(p.w.iter().chain(p.h.iter()).copied().collect())
    })
}

/// Adds the submodule `geometry` with `so3`, `s2` and `matrix_set` to `parent`.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = parent.py();
    let geometry = PyModule::new(py, "geometry")?;

    let so3 = PyModule::new(py, "so3")?;
    so3.add_function(wrap_pyfunction!(hat, &so3)?)?;
    so3.add_function(wrap_pyfunction!(vee, &so3)?)?;
    so3.add_function(wrap_pyfunction!(exp, &so3)?)?;
    so3.add_function(wrap_pyfunction!(log, &so3)?)?;
    so3.add_function(wrap_pyfunction!(euler_zyx, &so3)?)?;
    so3.add_function(wrap_pyfunction!(from_euler_zyx, &so3)?)?;
    so3.add_function(wrap_pyfunction!(right_jacobian, &so3)?)?;
    so3.add_function(wrap_pyfunction!(left_jacobian, &so3)?)?;
    so3.add_function(wrap_pyfunction!(right_jacobian_inverse, &so3)?)?;
    so3.add_function(wrap_pyfunction!(left_jacobian_inverse, &so3)?)?;
    geometry.add_submodule(&so3)?;

    let s2m = PyModule::new(py, "s2")?;
    s2m.add("G0", s2::G0)?;
    s2m.add_function(wrap_pyfunction!(s2_project, &s2m)?)?;
    s2m.add_function(wrap_pyfunction!(tangent_projector, &s2m)?)?;
    geometry.add_submodule(&s2m)?;

    let set = PyModule::new(py, "matrix_set")?;
    set.add_function(wrap_pyfunction!(matrix_set_project, &set)?)?;
    set.add_function(wrap_pyfunction!(factors, &set)?)?;
    geometry.add_submodule(&set)?;

    parent.add_submodule(&geometry)
}
