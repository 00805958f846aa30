//! Python bindings of parametrized infinite-horizon MPC: `stabilis.pmpc.Controller`.
//! Matrices are anything numpy can turn into nested float sequences; results are float64
//! arrays and plain dicts.
use ::pmpc::bounds::bounds;
use ::pmpc::{Constraints, Error as PmpcError, Pmpc, Source};
use nalgebra::DMatrix;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rigid_body::laguerre::Laguerre;
use rigid_body::siqp::Settings;

use crate::errors::{to_py_err, Error, IntoPyError};
use crate::real::{check_real, real, Real};

impl IntoPyError for PmpcError {
    fn into_py_error(self) -> PyErr {
        let message = self.to_string();
        match self {
            PmpcError::Shape { .. }
            | PmpcError::NonFinite(_)
            | PmpcError::InvalidParameter { .. }
            | PmpcError::TooLarge { .. } => PyValueError::new_err(message),
            _ => Error::new_err(message),
        }
    }
}

fn matrix(name: &str, rows: Vec<Vec<f64>>) -> PyResult<DMatrix<f64>> {
    let nrows = rows.len();
    let ncols = rows.first().map_or(0, Vec::len);
    if rows.iter().any(|r| r.len() != ncols) {
        return Err(PyValueError::new_err(format!(
            "{name} must be a rectangular matrix"
        )));
    }
    Ok(DMatrix::from_fn(nrows, ncols, |i, j| rows[i][j]))
}

fn bounds_list(name: &str, v: Option<Vec<(f64, f64)>>, len: usize) -> PyResult<Vec<(f64, f64)>> {
    match v {
        None => Ok(vec![(f64::NEG_INFINITY, f64::INFINITY); len]),
        Some(v) if v.len() == len => Ok(v),
        Some(v) => Err(PyValueError::new_err(format!(
            "{name} must have {len} (lower, upper) pairs, got {}",
            v.len()
        ))),
    }
}

/// Parametrized infinite-horizon MPC: states and inputs in the span of `s` Laguerre functions
/// with decay `nu` (1/s), constraints imposed for all t ≥ 0, re-solved every `Td` seconds.
/// Constraints are box limits `x_bounds` / `u_bounds` (lists of (lower, upper), ±inf for
/// none) or general rows `lower <= Cx x + Cu u <= upper`. Real-time mode: `budget` outer
/// iterations per step after the first (the shifted previous plan when it runs out) and at
/// most `max_check_steps` Taylor steps per row check; `work_bound()` states the resulting
/// worst case before running.
#[pyclass(name = "Controller", module = "stabilis.pmpc")]
#[derive(Debug)]
pub struct PyController {
    inner: Pmpc,
    /// Wall time of the last Rust step (s): the solver's own time, as DAQP reports its own.
    solve_time: f64,
}

#[pymethods]
impl PyController {
    #[new]
    #[pyo3(signature = (a, b, q, r, x_bounds=None, u_bounds=None, cx=None, cu=None, lower=None, upper=None, nu=0.7, s=12, td=0.02, tolerance=1e-6, max_iter=1000, budget=None, max_check_steps=10_000))]
    #[allow(clippy::too_many_arguments)] // mirrors the Python keyword signature
    fn new(
        a: Real<Vec<Vec<f64>>>,
        b: Real<Vec<Vec<f64>>>,
        q: Real<Vec<Vec<f64>>>,
        r: Real<Vec<Vec<f64>>>,
        x_bounds: Option<Real<Vec<(f64, f64)>>>,
        u_bounds: Option<Real<Vec<(f64, f64)>>>,
        cx: Option<Real<Vec<Vec<f64>>>>,
        cu: Option<Real<Vec<Vec<f64>>>>,
        lower: Option<Real<Vec<f64>>>,
        upper: Option<Real<Vec<f64>>>,
        #[pyo3(from_py_with = real)] nu: f64,
        s: usize,
        #[pyo3(from_py_with = real)] td: f64,
        #[pyo3(from_py_with = real)] tolerance: f64,
        max_iter: usize,
        budget: Option<usize>,
        max_check_steps: usize,
    ) -> PyResult<Self> {
        let (x_bounds, u_bounds) = (x_bounds.map(|b| b.0), u_bounds.map(|b| b.0));
        let (a, b, q, r) = (
            matrix("A", a.0)?,
            matrix("B", b.0)?,
            matrix("Q", q.0)?,
            matrix("R", r.0)?,
        );
        let (n, m) = (a.nrows(), b.ncols());
        let constraints = match (cx, cu, lower, upper) {
            (Some(cx), Some(cu), Some(lower), Some(upper)) => Constraints {
                cx: matrix("Cx", cx.0)?,
                cu: matrix("Cu", cu.0)?,
                lower: lower.0,
                upper: upper.0,
            },
            (None, None, None, None) => Constraints::boxes(
                &bounds_list("x_bounds", x_bounds, n)?,
                &bounds_list("u_bounds", u_bounds, m)?,
            ),
            _ => {
                return Err(PyValueError::new_err(
                    "give all of cx, cu, lower, upper, or none of them",
                ))
            }
        };
        let basis = Laguerre::new(s, nu).map_err(to_py_err)?;
        if max_check_steps == 0 {
            return Err(PyValueError::new_err(
                "max_check_steps = 0 is invalid: at least one Taylor step per row check",
            ));
        }
        let settings = Settings {
            tolerance,
            max_iter,
            max_check_steps,
            ..Settings::default()
        };
        let mut inner = Pmpc::new(&a, &b, &q, &r, &constraints, basis, td)
            .map_err(to_py_err)?
            .with_settings(settings);
        if let Some(budget) = budget {
            if budget == 0 {
                return Err(PyValueError::new_err(
                    "budget = 0 is invalid: at least one iteration per step",
                ));
            }
            inner = inner.with_budget(budget);
        }
        Ok(Self {
            inner,
            solve_time: 0.0,
        })
    }

    /// Solve for the measured state and return the input to apply now (shape (m,)).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        // A contiguous float64 array is read in place: converting it element by element as a
        // sequence cost 1.7 us more per step. Anything else is read as a sequence.
        let array = x
            .cast::<PyArray1<f64>>()
            .ok()
            .and_then(|a| a.try_readonly().ok());
        let copied: Vec<f64>;
        let x = match array.as_ref().and_then(|a| a.as_slice().ok()) {
            Some(x) => x,
            None => {
                check_real(x, "x")?;
                copied = x.extract().map_err(|_| {
                    PyValueError::new_err("x must be a 1-D sequence of numbers (the state)")
                })?;
                &copied
            }
        };
        let start = std::time::Instant::now();
        let u = self.inner.step(x);
        self.solve_time = start.elapsed().as_secs_f64();
        Ok(PyArray1::from_slice(py, u.map_err(to_py_err)?))
    }

    /// Planned input t >= 0 seconds after the last step (shape (m,)).
    fn input_at<'py>(
        &self,
        py: Python<'py>,
        #[pyo3(from_py_with = real)] t: f64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mut out = vec![0.0; self.inner.problem().m()];
        self.inner.input_at(t, &mut out).map_err(to_py_err)?;
        Ok(PyArray1::from_vec(py, out))
    }

    /// Coefficients (eta_x, eta_u) of the current plan.
    #[getter]
    fn plan<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.plan())
    }

    /// Diagnostics of the last step: cost, iterations, active instants, fallback flag, and
    /// `solve_time`, the seconds the Rust step took (argument conversion and the returned
    /// array excluded).
    fn last_step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let info = self.inner.last_step();
        let d = PyDict::new(py);
        d.set_item("cost", info.cost)?;
        d.set_item("iterations", info.stats.iterations)?;
        d.set_item("active", info.active)?;
        d.set_item("fallback", matches!(info.source, Source::Fallback(_)))?;
        d.set_item("taylor_steps", info.stats.taylor_steps)?;
        d.set_item("adds", info.stats.adds)?;
        d.set_item("drops", info.stats.drops)?;
        d.set_item("moves", info.stats.moves)?;
        d.set_item("solve_time", self.solve_time)?;
        Ok(d)
    }

    /// Worst-case work of every step after the first, known before running (None without a
    /// budget): outer iterations, Taylor steps, added and dropped instants, Newton moves; the
    /// keys of `last_step()` that count the same work.
    fn work_bound<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(b) = self.inner.work_bound() else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("iterations", b.iterations)?;
        d.set_item("taylor_steps", b.taylor_steps)?;
        d.set_item("adds", b.adds)?;
        d.set_item("drops", b.drops)?;
        d.set_item("moves", b.moves)?;
        Ok(Some(d))
    }

    /// Forget the previous plan and warm start.
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// Upper bound J_s, lower bound J~_s (Clarabel), their gap and the L2 error bound at x0.
    fn bounds<'py>(&self, py: Python<'py>, x0: Real<Vec<f64>>) -> PyResult<Bound<'py, PyDict>> {
        let b = bounds(self.inner.problem(), &x0.0, self.inner.settings()).map_err(to_py_err)?;
        let d = PyDict::new(py);
        d.set_item("upper", b.upper)?;
        d.set_item("lower", b.lower)?;
        d.set_item("gap", b.gap)?;
        d.set_item("l2_error_bound", b.l2_error_bound)?;
        Ok(d)
    }
}

/// Adds the `pmpc` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "pmpc")?;
    m.add_class::<PyController>()?;
    parent.add_submodule(&m)?;
    Ok(())
}
