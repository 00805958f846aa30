//! Python bindings of the Cubli: parameters, model functions, the backstepping and guiding
//! controllers, the tuning method and jump-up learning. 3-vectors are anything numpy can turn
//! into three floats; results are float64 arrays.
use cubli::edge::{EdgeJump, EdgeJumpModel};
use cubli::jump::{face_attitude, pre_brake_state, JumpModel};
use cubli::model;
use cubli::{
    Backstepping, CubliError, FullState, Gains, GuidingController, JumpReference, Limits, Params,
    ReducedState, TiltPolynomial,
};
use nalgebra::{Complex, Matrix3, Quaternion, UnitQuaternion, Vector3};
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyComplex, PyDict};
use sim::scenarios::cubli::{learn_jump as learn_jump_trials, Jump, JumpSetup};

use crate::errors::{to_py_err, Error, IntoPyError};
use crate::real::{real, Real};

impl IntoPyError for CubliError {
    fn into_py_error(self) -> PyErr {
        Error::new_err(self.to_string())
    }
}

fn vec3(name: &str, v: Vec<f64>) -> PyResult<Vector3<f64>> {
    if v.len() != 3 {
        return Err(PyValueError::new_err(format!(
            "{name} must have 3 elements, got {}",
            v.len()
        )));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// A float64 vector returned to Python.
type Array<'py> = Bound<'py, PyArray1<f64>>;

fn array<'py>(py: Python<'py>, v: &Vector3<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

/// Rigid-body parameters of the Cubli about its pivot; defaults are the reference set
/// (spec §7.5: 150 mm cube, |m||g| = 1.8639 N m, Θ0 diagonal 0.0220 / off-diagonal −0.0082,
/// Θw = 3e-4 kg m²).
#[pyclass(name = "Params", module = "stabilis.cubli", frozen)]
#[derive(Debug, Clone, Copy)]
pub struct PyParams {
    inner: Params,
}

#[pymethods]
impl PyParams {
    #[new]
    #[pyo3(signature = (theta0=None, theta_w=None, m=None, gravity=None))]
    fn new(
        theta0: Option<Real<Vec<Vec<f64>>>>,
        theta_w: Option<Real<Vec<f64>>>,
        m: Option<Real<Vec<f64>>>,
        gravity: Option<Real<f64>>,
    ) -> PyResult<Self> {
        let r = Params::reference();
        let theta0 = match theta0 {
            None => *r.theta0(),
            Some(Real(rows)) => {
                if rows.len() != 3 || rows.iter().any(|row| row.len() != 3) {
                    return Err(PyValueError::new_err("theta0 must be a 3 x 3 matrix"));
                }
                Matrix3::from_fn(|i, j| rows[i][j])
            }
        };
        let theta_w = theta_w
            .map(|v| vec3("theta_w", v.0))
            .transpose()?
            .unwrap_or(*r.theta_w());
        let m = m.map(|v| vec3("m", v.0)).transpose()?.unwrap_or(*r.m());
        let inner = Params::new(theta0, theta_w, m, gravity.map_or(r.gravity(), |g| g.0))
            .map_err(to_py_err)?;
        Ok(Self { inner })
    }

    /// Housing inertia about the pivot (kg m²), 3 x 3.
    #[getter]
    fn theta0<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let t = self.inner.theta0();
        let rows: Vec<Vec<f64>> = (0..3)
            .map(|i| (0..3).map(|j| t[(i, j)]).collect())
            .collect();
        PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
    }
    /// Wheel spin inertias (kg m²).
    #[getter]
    fn theta_w<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, self.inner.theta_w())
    }
    /// Mass times centre-of-mass vector (kg m).
    #[getter]
    fn m<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array(py, self.inner.m())
    }
    /// |g| (m/s²).
    #[getter]
    fn gravity(&self) -> f64 {
        self.inner.gravity()
    }
    /// |m||g| (N m).
    #[getter]
    fn mg(&self) -> f64 {
        self.inner.mg()
    }
    fn __repr__(&self) -> String {
        format!(
            "Params(mg={:.4}, gravity={})",
            self.inner.mg(),
            self.inner.gravity()
        )
    }
}

fn params(p: Option<&PyParams>) -> Params {
    p.map(|p| p.inner).unwrap_or_else(Params::reference)
}

fn reduced(
    p: &Params,
    g: Real<Vec<f64>>,
    p_h: Real<Vec<f64>>,
    p_w: Real<Vec<f64>>,
) -> PyResult<ReducedState> {
    let x = ReducedState {
        g: vec3("g", g.0)?,
        p_h: vec3("p_h", p_h.0)?,
        p_w: vec3("p_w", p_w.0)?,
    };
    x.validate(p).map_err(to_py_err)?;
    Ok(x)
}

/// Reduced model (1.5): returns (ġ, ṗ_h, ṗ_w) for gravity `g` (body, |g| = 9.81), momenta and torque.
#[pyfunction]
#[pyo3(signature = (g, p_h, p_w, torque, params=None))]
fn reduced_derivative<'py>(
    py: Python<'py>,
    g: Real<Vec<f64>>,
    p_h: Real<Vec<f64>>,
    p_w: Real<Vec<f64>>,
    torque: Real<Vec<f64>>,
    params: Option<&PyParams>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
    let p = self::params(params);
    let x = reduced(&p, g, p_h, p_w)?;
    let d = model::reduced_derivative(&p, &x, &vec3("torque", torque.0)?);
    Ok((array(py, &d.g), array(py, &d.p_h), array(py, &d.p_w)))
}

/// Conserved quantities at a reduced state: dict with yaw_momentum, energy, housing_energy,
/// figure_axis_momentum and inclination (rad).
#[pyfunction]
#[pyo3(signature = (g, p_h, p_w, params=None))]
fn invariants<'py>(
    py: Python<'py>,
    g: Real<Vec<f64>>,
    p_h: Real<Vec<f64>>,
    p_w: Real<Vec<f64>>,
    params: Option<&PyParams>,
) -> PyResult<Bound<'py, PyDict>> {
    let p = self::params(params);
    let x = reduced(&p, g, p_h, p_w)?;
    let d = PyDict::new(py);
    d.set_item("yaw_momentum", model::yaw_momentum(&x))?;
    d.set_item("energy", model::energy(&p, &x))?;
    d.set_item("housing_energy", model::housing_energy(&p, &x))?;
    d.set_item("figure_axis_momentum", model::figure_axis_momentum(&p, &x))?;
    d.set_item("inclination", model::inclination(&p, &x.g))?;
    Ok(d)
}

/// Generalized momenta (p_h, p_w) from housing rates and wheel rates relative to the housing.
#[pyfunction]
#[pyo3(signature = (omega_h, omega_w, params=None))]
fn momenta<'py>(
    py: Python<'py>,
    omega_h: Real<Vec<f64>>,
    omega_w: Real<Vec<f64>>,
    params: Option<&PyParams>,
) -> PyResult<(Array<'py>, Array<'py>)> {
    let p = self::params(params);
    let (ph, pw) = p.momenta(&vec3("omega_h", omega_h.0)?, &vec3("omega_w", omega_w.0)?);
    Ok((array(py, &ph), array(py, &pw)))
}

/// Backstepping balancing controller (1.10) with gains α, β, γ, δ (paper: 15, 18, 12, 1e-5).
#[pyclass(name = "Backstepping", module = "stabilis.cubli", frozen)]
#[derive(Debug, Clone, Copy)]
pub struct PyBackstepping {
    inner: Backstepping,
}

#[pymethods]
impl PyBackstepping {
    #[new]
    #[pyo3(signature = (params=None, alpha=15.0, beta=18.0, gamma=12.0, delta=1e-5))]
    fn new(
        params: Option<&PyParams>,
        #[pyo3(from_py_with = real)] alpha: f64,
        #[pyo3(from_py_with = real)] beta: f64,
        #[pyo3(from_py_with = real)] gamma: f64,
        #[pyo3(from_py_with = real)] delta: f64,
    ) -> PyResult<Self> {
        let gains = Gains::new(alpha, beta, gamma, delta).map_err(to_py_err)?;
        Ok(Self {
            inner: Backstepping::new(self::params(params), gains),
        })
    }

    /// Motor torques (N m) for gravity `g` in body axes and the momenta.
    fn control<'py>(
        &self,
        py: Python<'py>,
        g: Real<Vec<f64>>,
        p_h: Real<Vec<f64>>,
        p_w: Real<Vec<f64>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = reduced(self.inner.params(), g, p_h, p_w)?;
        Ok(array(py, &self.inner.control(&x).map_err(to_py_err)?))
    }

    /// Lyapunov function V (1.11).
    fn lyapunov(
        &self,
        g: Real<Vec<f64>>,
        p_h: Real<Vec<f64>>,
        p_w: Real<Vec<f64>>,
    ) -> PyResult<f64> {
        let x = reduced(self.inner.params(), g, p_h, p_w)?;
        Ok(self.inner.lyapunov(&x))
    }

    /// Closed-loop tilt poles s³ + A s² + B s + C = 0 for this controller's |m||g|.
    fn tilt_poles<'py>(&self, py: Python<'py>) -> Vec<Bound<'py, PyComplex>> {
        TiltPolynomial::from_gains(self.inner.gains(), self.inner.params().mg())
            .poles()
            .iter()
            .map(|s| PyComplex::from_doubles(py, s.re, s.im))
            .collect()
    }
}

fn poles3(poles: Vec<Bound<'_, PyAny>>) -> PyResult<[Complex<f64>; 3]> {
    if poles.len() != 3 {
        return Err(PyValueError::new_err(format!(
            "poles must have 3 entries, got {}",
            poles.len()
        )));
    }
    let mut out = [Complex::new(0.0, 0.0); 3];
    for (o, p) in out.iter_mut().zip(&poles) {
        let c: Complex<f64> = match p.cast::<PyComplex>() {
            Ok(c) => Complex::new(c.real(), c.imag()),
            Err(_) => Complex::new(p.extract::<Real<f64>>()?.0, 0.0),
        };
        *o = c;
    }
    Ok(out)
}

/// Tuning method (1.34): gains (alpha, beta, gamma, delta) placing the tilt poles at `poles`
/// (three real or complex numbers) with yaw rate `gamma_hat`, for |m||g| = `mg`.
#[pyfunction]
fn tune(
    poles: Vec<Bound<'_, PyAny>>,
    #[pyo3(from_py_with = real)] gamma_hat: f64,
    #[pyo3(from_py_with = real)] mg: f64,
) -> PyResult<(f64, f64, f64, f64)> {
    let g = TiltPolynomial::from_poles(&poles3(poles)?)
        .and_then(|t| t.gains(gamma_hat, mg))
        .map_err(to_py_err)?;
    Ok((g.alpha, g.beta, g.gamma, g.delta))
}

/// Admissible intervals of gamma_hat (1.35) for the desired tilt poles.
#[pyfunction]
fn admissible_gamma(poles: Vec<Bound<'_, PyAny>>) -> PyResult<Vec<(f64, f64)>> {
    let t = TiltPolynomial::from_poles(&poles3(poles)?).map_err(to_py_err)?;
    Ok(t.admissible_gamma().as_slice().to_vec())
}

fn attitude(q: Vec<f64>) -> PyResult<UnitQuaternion<f64>> {
    if q.len() != 4 {
        return Err(PyValueError::new_err(format!(
            "quaternion must have 4 elements (w, x, y, z), got {}",
            q.len()
        )));
    }
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(
        q[0], q[1], q[2], q[3],
    )))
}

/// Guiding controller (feedback linearization tracking the ideal face → corner jump), built
/// for the nominal jump from the face with normal −e3.
#[pyclass(name = "GuidingController", module = "stabilis.cubli", frozen)]
#[derive(Debug, Clone, Copy)]
pub struct PyGuiding {
    inner: GuidingController,
}

#[pymethods]
impl PyGuiding {
    #[new]
    #[pyo3(signature = (params=None))]
    fn new(params: Option<&PyParams>) -> PyResult<Self> {
        let p = self::params(params);
        let jm = JumpModel::new(p, &Vector3::new(0.0, 0.0, -p.gravity())).map_err(to_py_err)?;
        let pre = pre_brake_state(&p, face_attitude(), &jm.nominal_wheel_speeds());
        let reference = JumpReference::at_brake(&p, &pre).map_err(to_py_err)?;
        Ok(Self {
            inner: GuidingController::new(p, &Gains::paper(), reference),
        })
    }

    /// Motor torques for attitude quaternion (w, x, y, z) and momenta; raises near 90°.
    fn control<'py>(
        &self,
        py: Python<'py>,
        quaternion: Real<Vec<f64>>,
        p_h: Real<Vec<f64>>,
        p_w: Real<Vec<f64>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = FullState {
            attitude: attitude(quaternion.0)?,
            p_h: vec3("p_h", p_h.0)?,
            p_w: vec3("p_w", p_w.0)?,
        };
        Ok(array(py, &self.inner.control(&x).map_err(to_py_err)?))
    }
}

/// Nominal wheel speeds (1.67) for the face with normal −e3 (rad/s): the three face → corner
/// speeds, or for `jump="edge"` the speeds with only wheel 1 spinning that lift the cube onto
/// edge e1 (ideal brake).
#[pyfunction]
#[pyo3(signature = (params=None, jump="corner"))]
fn nominal_wheel_speeds<'py>(
    py: Python<'py>,
    params: Option<&PyParams>,
    jump: &str,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let p = self::params(params);
    let theta = match jump {
        "corner" => JumpModel::new(p, &Vector3::new(0.0, 0.0, -p.gravity()))
            .map_err(to_py_err)?
            .nominal_wheel_speeds(),
        "edge" => {
            let edge = EdgeJump::new(&p, 0).map_err(to_py_err)?;
            let speed = EdgeJumpModel::new(&edge)
                .map_err(to_py_err)?
                .nominal_wheel_speed();
            Vector3::new(speed, 0.0, 0.0)
        }
        other => {
            return Err(PyValueError::new_err(format!(
                "jump must be \"corner\" or \"edge\", got {other:?}"
            )))
        }
    };
    Ok(array(py, &theta))
}

/// Learning of the pre-brake wheel speeds (Algorithm 1, λ = 0.8) on the mismatched plant of
/// `stabilis sim cubli --scenario jump-up`; `jump` is "corner" (three wheels) or "edge" (wheel 1,
/// face → edge e1); `brake_spread` > 0 draws a random brake efficiency per trial (seeded).
/// Returns one dict per trial (theta, error, success, top_inclination, brake).
#[pyfunction]
#[pyo3(signature = (trials=8, start_scale=0.8, torque_max=0.2, guided=true, jump="corner", brake_spread=0.0, seed=0))]
#[allow(clippy::too_many_arguments)]
fn learn_jump<'py>(
    py: Python<'py>,
    trials: usize,
    #[pyo3(from_py_with = real)] start_scale: f64,
    #[pyo3(from_py_with = real)] torque_max: f64,
    guided: bool,
    jump: &str,
    #[pyo3(from_py_with = real)] brake_spread: f64,
    seed: u64,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    if torque_max.is_nan() || torque_max <= 0.0 {
        return Err(PyValueError::new_err("torque_max must be positive"));
    }
    let jump = match jump {
        "corner" => Jump::Corner,
        "edge" => Jump::Edge,
        other => {
            return Err(PyValueError::new_err(format!(
                "jump must be \"corner\" or \"edge\", got {other:?}"
            )))
        }
    };
    let setup = JumpSetup {
        jump,
        limits: Limits {
            max_torque: torque_max,
            ..Limits::cubli()
        },
        start_scale,
        trials,
        guided,
        brake_spread,
        seed,
    };
    let learned = learn_jump_trials(&setup).map_err(to_py_err)?;
    learned
        .trials
        .iter()
        .map(|t| {
            let d = PyDict::new(py);
            d.set_item("theta", array(py, &t.theta))?;
            d.set_item("error", array(py, &t.error))?;
            d.set_item("success", t.success)?;
            d.set_item("top_inclination", t.top_inclination)?;
            d.set_item("brake", format!("{:?}", t.brake))?;
            Ok(d)
        })
        .collect()
}

/// Adds the `cubli` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let module = PyModule::new(parent.py(), "cubli")?;
    module.add_class::<PyParams>()?;
    module.add_class::<PyBackstepping>()?;
    module.add_class::<PyGuiding>()?;
    module.add_function(wrap_pyfunction!(reduced_derivative, &module)?)?;
    module.add_function(wrap_pyfunction!(invariants, &module)?)?;
    module.add_function(wrap_pyfunction!(momenta, &module)?)?;
    module.add_function(wrap_pyfunction!(tune, &module)?)?;
    module.add_function(wrap_pyfunction!(admissible_gamma, &module)?)?;
    module.add_function(wrap_pyfunction!(nominal_wheel_speeds, &module)?)?;
    module.add_function(wrap_pyfunction!(learn_jump, &module)?)?;
    parent.add_submodule(&module)
}
