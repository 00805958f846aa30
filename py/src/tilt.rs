//! Python bindings of the tilt estimator: `stabilis.tilt.Estimator(positions)` with
//! `.estimate` on one sample `(N, 3)` or a batch `(T, N, 3)`, `.least_squares`, `.fisher`,
//! and the placement helpers.

use ::tilt::{Estimate, LeastSquaresEstimate, TiltError};
use nalgebra::{Matrix3, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::IntoPyObjectExt;

use crate::errors::{to_py_err, Error, IntoPyError};
use crate::real::{real, Real};

impl IntoPyError for TiltError {
    fn into_py_error(self) -> PyErr {
        let message = self.to_string();
        match self {
            TiltError::MeasurementCount { .. }
            | TiltError::TooFewSensors { .. }
            | TiltError::TooManySensors { .. }
            | TiltError::NonFinitePosition { .. }
            | TiltError::NonFiniteMeasurement { .. }
            | TiltError::NonFiniteBias { .. } => PyValueError::new_err(message),
            _ => Error::new_err(message),
        }
    }
}

/// Rows of an `(N, 3)` float64 array as vectors; `name` appears in the error.
fn vectors(array: &PyReadonlyArrayDyn<'_, f64>, name: &str) -> PyResult<Vec<Vector3<f64>>> {
    let shape = array.shape();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape (N, 3), got {shape:?}"
        )));
    }
    let a = array.as_array();
    Ok((0..shape[0])
        .map(|i| Vector3::new(a[[i, 0]], a[[i, 1]], a[[i, 2]]))
        .collect())
}

fn vector3(values: [f64; 3], name: &str) -> PyResult<Vector3<f64>> {
    let v = Vector3::from(values);
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} contains NaN or infinity"
        )))
    }
}

fn matrix_rows(m: &Matrix3<f64>) -> Array2<f64> {
    Array2::from_shape_fn((3, 3), |(i, j)| m[(i, j)])
}

fn vec_array(v: &Vector3<f64>) -> Array1<f64> {
    Array1::from_iter(v.iter().copied())
}

/// The maximum-likelihood estimator of tilt (gravity in the body frame), angular velocity and
/// angular acceleration from N >= 3 accelerometers at known positions relative to a
/// non-accelerated pivot.
#[pyclass(module = "stabilis.tilt", name = "Estimator")]
struct PyEstimator {
    inner: ::tilt::Estimator,
}

#[pymethods]
impl PyEstimator {
    /// `positions` (N, 3) in metres relative to the pivot; `q`, `r` step sizes (default: the
    /// paper's rule q = 1/N, r = r*); `biases` (N, 3) calibrated accelerometer biases.
    #[new]
    #[pyo3(signature = (positions, q = None, r = None, tol = 1e-8, max_iterations = 10_000, biases = None))]
    fn new(
        positions: PyReadonlyArrayDyn<'_, f64>,
        q: Option<Real<f64>>,
        r: Option<Real<f64>>,
        #[pyo3(from_py_with = real)] tol: f64,
        max_iterations: usize,
        biases: Option<PyReadonlyArrayDyn<'_, f64>>,
    ) -> PyResult<Self> {
        let mut layout =
            ::tilt::Layout::new(&vectors(&positions, "positions")?).map_err(to_py_err)?;
        if let Some(b) = biases {
            layout = layout
                .with_biases(&vectors(&b, "biases")?)
                .map_err(to_py_err)?;
        }
        let mut options = ::tilt::Options {
            tol,
            max_iterations,
            ..::tilt::Options::for_layout(&layout)
        };
        match (q, r) {
            (None, None) => {}
            (Some(Real(q)), Some(Real(r))) => options = options.with_step_sizes(&layout, q, r),
            _ => {
                return Err(PyValueError::new_err(
                    "give both step sizes q and r, or neither",
                ))
            }
        }
        let inner = ::tilt::Estimator::with_options(layout, options).map_err(to_py_err)?;
        Ok(Self { inner })
    }

    /// Sensor positions (N, 3).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let p = self.inner.layout().positions();
        Array2::from_shape_fn((p.len(), 3), |(i, k)| p[i][k]).into_pyarray(py)
    }

    /// Step sizes and convergence certificate:
    /// `{q, r, eigenvalues, spectral_radius, certified, rule}`.
    #[getter]
    fn tuning<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.inner.options().tuning;
        let d = PyDict::new(py);
        d.set_item("q", t.q)?;
        d.set_item("r", t.r)?;
        d.set_item("eigenvalues", PyArray1::from_slice(py, &t.eigenvalues))?;
        d.set_item("spectral_radius", t.spectral_radius())?;
        d.set_item("certified", t.certified())?;
        let rule = match t.rule {
            ::tilt::TuningRule::ClosedForm => "closed_form",
            ::tilt::TuningRule::Numerical => "numerical",
            ::tilt::TuningRule::GradientStep => "gradient_step",
            ::tilt::TuningRule::Manual => "manual",
        };
        d.set_item("rule", rule)?;
        Ok(d)
    }

    /// Estimates one sample `(N, 3)` or a batch `(T, N, 3)` of body-frame accelerometer readings
    /// (m/s^2). Returns a dict of arrays: `g`, `omega` (sign unobservable), `omega_dot`,
    /// `omega_norm`, `omega_matrix`, `iterations`, `converged`, `cost`, `certified`,
    /// `omega_along_plane_normal`, `plane_alignment` (NaN when the sensors are not on one
    /// affine plane), with a leading T axis for a batch.
    fn estimate<'py>(
        &self,
        py: Python<'py>,
        measurements: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let samples = samples(&measurements, self.inner.layout().len())?;
        let estimates = py.detach(|| {
            samples
                .iter()
                .enumerate()
                .map(|(t, m)| self.inner.estimate(m).map_err(|e| (t, e)))
                .collect::<Result<Vec<Estimate>, _>>()
        });
        let estimates = estimates.map_err(|(t, e)| batch_error(py, &samples, t, e))?;
        estimates_to_py(py, &estimates, measurements.shape().len() == 3)
    }

    /// The baseline linear least-squares method on one sample or a batch: `omega_matrix`,
    /// `g_raw` (unnormalised), `g` (normalised to g0), `rank_deficient`.
    fn least_squares<'py>(
        &self,
        py: Python<'py>,
        measurements: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let samples = samples(&measurements, self.inner.layout().len())?;
        let results = samples
            .iter()
            .enumerate()
            .map(|(t, m)| ::tilt::least_squares(self.inner.layout(), m).map_err(|e| (t, e)))
            .collect::<Result<Vec<LeastSquaresEstimate>, _>>()
            .map_err(|(t, e)| batch_error(py, &samples, t, e))?;
        let batch = measurements.shape().len() == 3;
        let d = PyDict::new(py);
        let omega: Vec<Matrix3<f64>> = results.iter().map(|r| r.omega_matrix).collect();
        d.set_item("omega_matrix", stack_matrices(py, &omega, batch))?;
        let raw: Vec<Vector3<f64>> = results.iter().map(|r| r.g_raw).collect();
        d.set_item("g_raw", stack_vectors(py, &raw, batch))?;
        let g: Vec<Vector3<f64>> = results
            .iter()
            .map(|r| r.g.unwrap_or(Vector3::repeat(f64::NAN)))
            .collect();
        d.set_item("g", stack_vectors(py, &g, batch))?;
        d.set_item(
            "rank_deficient",
            self.inner.layout().affine_plane().is_some(),
        )?;
        Ok(d)
    }

    /// Fisher information of one sample for noise `sigma` (m/s^2) at `(omega, omega_dot, g)`,
    /// parameters ordered (omega, omega_dot, n) with `g = exp([Pi n]x) g`. Returns
    /// `information` (8, 8), `rank`, `singular_values` (of the stacked Jacobian), `basis` (Pi,
    /// 3x2), and the Cramer-Rao bound `crb` (8, 8), `crb_omega`, `crb_omega_dot`, `crb_tilt`
    /// (3x3 each), or None for these when the information is singular.
    #[pyo3(signature = (omega, omega_dot, g, sigma = 1.0))]
    fn fisher<'py>(
        &self,
        py: Python<'py>,
        omega: Real<[f64; 3]>,
        omega_dot: Real<[f64; 3]>,
        g: Real<[f64; 3]>,
        #[pyo3(from_py_with = real)] sigma: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let f = ::tilt::fisher_information(
            self.inner.layout(),
            &vector3(omega.0, "omega")?,
            &vector3(omega_dot.0, "omega_dot")?,
            &vector3(g.0, "g")?,
            sigma,
        )
        .map_err(to_py_err)?;
        let d = PyDict::new(py);
        let info = f.matrix();
        d.set_item(
            "information",
            Array2::from_shape_fn((8, 8), |(i, j)| info[(i, j)]).into_pyarray(py),
        )?;
        d.set_item("rank", f.rank())?;
        d.set_item(
            "singular_values",
            PyArray1::from_slice(py, f.jacobian_singular_values().as_slice()),
        )?;
        let basis = f.tangent_basis();
        d.set_item(
            "basis",
            Array2::from_shape_fn((3, 2), |(i, j)| basis[(i, j)]).into_pyarray(py),
        )?;
        match f.crb() {
            Ok(crb) => {
                let c = crb.covariance;
                d.set_item(
                    "crb",
                    Array2::from_shape_fn((8, 8), |(i, j)| c[(i, j)]).into_pyarray(py),
                )?;
                d.set_item("crb_omega", matrix_rows(&crb.omega).into_pyarray(py))?;
                d.set_item(
                    "crb_omega_dot",
                    matrix_rows(&crb.omega_dot).into_pyarray(py),
                )?;
                d.set_item("crb_tilt", matrix_rows(&crb.tilt).into_pyarray(py))?;
            }
            Err(_) => {
                for key in ["crb", "crb_omega", "crb_omega_dot", "crb_tilt"] {
                    d.set_item(key, py.None())?;
                }
            }
        }
        Ok(d)
    }

    /// D-criterion (2.64) of this layout for gravity `g` in the body frame.
    #[pyo3(signature = (g = Real([0.0, 0.0, -::tilt::G0])))]
    fn d_criterion(&self, g: Real<[f64; 3]>) -> PyResult<f64> {
        Ok(::tilt::d_criterion(
            self.inner.layout(),
            &vector3(g.0, "g")?,
        ))
    }

    fn __repr__(&self) -> String {
        let t = self.inner.options().tuning;
        format!(
            "Estimator(sensors={}, q={}, r={}, spectral_radius={:.4})",
            self.inner.layout().len(),
            t.q,
            t.r,
            t.spectral_radius()
        )
    }
}

/// Splits `(N, 3)` or `(T, N, 3)` input into samples of `sensors` vectors.
fn samples(
    measurements: &PyReadonlyArrayDyn<'_, f64>,
    sensors: usize,
) -> PyResult<Vec<Vec<Vector3<f64>>>> {
    let shape = measurements.shape().to_vec();
    let a = measurements.as_array();
    let ok = match shape.as_slice() {
        [n, 3] | [_, n, 3] => *n == sensors,
        _ => false,
    };
    if !ok {
        return Err(PyValueError::new_err(format!(
            "measurements must have shape ({sensors}, 3) or (T, {sensors}, 3), got {shape:?}"
        )));
    }
    let data: Vec<f64> = a.iter().copied().collect();
    Ok(data
        .chunks(3 * sensors)
        .map(|chunk| {
            chunk
                .chunks(3)
                .map(|v| Vector3::new(v[0], v[1], v[2]))
                .collect()
        })
        .collect())
}

/// The error of sample `t`, naming the sample in a batch.
fn batch_error(py: Python<'_>, samples: &[Vec<Vector3<f64>>], t: usize, error: TiltError) -> PyErr {
    let err = error.into_py_error();
    if samples.len() > 1 {
        let message = format!("sample {t}: {}", err.value(py));
        if err.is_instance_of::<PyValueError>(py) {
            PyValueError::new_err(message)
        } else {
            Error::new_err(message)
        }
    } else {
        err
    }
}

fn stack_vectors<'py>(py: Python<'py>, v: &[Vector3<f64>], batch: bool) -> Bound<'py, PyAny> {
    if batch {
        Array2::from_shape_fn((v.len(), 3), |(t, k)| v[t][k])
            .into_pyarray(py)
            .into_any()
    } else {
        vec_array(&v[0]).into_pyarray(py).into_any()
    }
}

fn stack_matrices<'py>(py: Python<'py>, m: &[Matrix3<f64>], batch: bool) -> Bound<'py, PyAny> {
    if batch {
        Array3::from_shape_fn((m.len(), 3, 3), |(t, i, j)| m[t][(i, j)])
            .into_pyarray(py)
            .into_any()
    } else {
        matrix_rows(&m[0]).into_pyarray(py).into_any()
    }
}

fn stack_scalars<'py, T: numpy::Element + Copy + IntoPyObject<'py>>(
    py: Python<'py>,
    values: Vec<T>,
    batch: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if batch {
        Ok(Array1::from_vec(values).into_pyarray(py).into_any())
    } else {
        values[0].into_bound_py_any(py)
    }
}

fn estimates_to_py<'py>(
    py: Python<'py>,
    e: &[Estimate],
    batch: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let collect_v = |f: fn(&Estimate) -> Vector3<f64>| e.iter().map(f).collect::<Vec<_>>();
    d.set_item("g", stack_vectors(py, &collect_v(|x| x.g), batch))?;
    d.set_item("omega", stack_vectors(py, &collect_v(|x| x.omega), batch))?;
    d.set_item(
        "omega_dot",
        stack_vectors(py, &collect_v(|x| x.omega_dot), batch),
    )?;
    let omega: Vec<Matrix3<f64>> = e.iter().map(|x| x.omega_matrix).collect();
    d.set_item("omega_matrix", stack_matrices(py, &omega, batch))?;
    d.set_item(
        "omega_norm",
        stack_scalars(py, e.iter().map(|x| x.omega_norm).collect(), batch)?,
    )?;
    d.set_item(
        "cost",
        stack_scalars(py, e.iter().map(|x| x.cost).collect(), batch)?,
    )?;
    d.set_item(
        "iterations",
        stack_scalars(py, e.iter().map(|x| x.iterations as u64).collect(), batch)?,
    )?;
    d.set_item(
        "converged",
        stack_scalars(py, e.iter().map(|x| x.flags.converged).collect(), batch)?,
    )?;
    d.set_item(
        "certified",
        stack_scalars(py, e.iter().map(|x| x.flags.certified).collect(), batch)?,
    )?;
    d.set_item(
        "omega_along_plane_normal",
        stack_scalars(
            py,
            e.iter().map(|x| x.flags.omega_along_plane_normal).collect(),
            batch,
        )?,
    )?;
    d.set_item(
        "plane_alignment",
        stack_scalars(
            py,
            e.iter()
                .map(|x| x.plane_alignment.unwrap_or(f64::NAN))
                .collect(),
            batch,
        )?,
    )?;
    Ok(d)
}

/// `(positions (n, 3), ratio)`: a D-optimal layout of `n` sensors on the unit sphere and its
/// D-criterion as a fraction of the bound `(n g0^2)^3 (2n/3)^6`.
#[pyfunction]
fn optimal_placement<'py>(py: Python<'py>, n: usize) -> PyResult<(Bound<'py, PyArray2<f64>>, f64)> {
    let mut buffer = [Vector3::zeros(); ::tilt::MAX_SENSORS];
    let (positions, ratio) = ::tilt::optimal_placement(n, &mut buffer).map_err(to_py_err)?;
    let array = Array2::from_shape_fn((positions.len(), 3), |(i, k)| positions[i][k]);
    Ok((array.into_pyarray(py), ratio))
}

/// Upper bound `(n g0^2)^3 (2n/3)^6` of the D-criterion over layouts in the unit ball.
#[pyfunction]
fn d_criterion_bound(n: usize) -> f64 {
    ::tilt::d_criterion_bound(n, ::tilt::G0)
}

/// Adds the submodule `tilt` to `parent`.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = parent.py();
    let module = PyModule::new(py, "tilt")?;
    module.add("G0", ::tilt::G0)?;
    module.add_class::<PyEstimator>()?;
    module.add_function(wrap_pyfunction!(optimal_placement, &module)?)?;
    module.add_function(wrap_pyfunction!(d_criterion_bound, &module)?)?;
    parent.add_submodule(&module)
}
