//! Python bindings of the flying platform: `stabilis.flying_platform.Model` (effects,
//! parameters, state space, frequency response), the controller, the multisine experiment
//! design, and closed-loop simulation into numpy arrays.

use ::flying_platform as fp;
use fp::control::Setpoint;
use fp::controllability::{
    gramian_det_closed_form, reachability_gramian, thrust_vectoring_system, LeverArmTradeoff,
};
use fp::simulate::RateOverride;
use nalgebra::{Complex, DMatrix, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyComplex, PyDict};

use crate::errors::{to_py_err, Error, IntoPyError, SimError};
use crate::real::{real, Real};

impl IntoPyError for fp::Error {
    fn into_py_error(self) -> PyErr {
        let message = self.to_string();
        match self {
            fp::Error::Length { .. } => PyValueError::new_err(message),
            fp::Error::Diverged { .. } => SimError::new_err(message),
            _ => Error::new_err(message),
        }
    }
}

/// Two float64 matrices, e.g. `(A, B)`.
type MatrixPair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

fn matrix<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]).into_pyarray(py)
}

fn rows<'py, const N: usize>(py: Python<'py>, data: &[[f64; N]]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((data.len(), N), |(i, j)| data[i][j]).into_pyarray(py)
}

fn complex_list<'py>(py: Python<'py>, z: &[Complex<f64>]) -> Vec<Bound<'py, PyComplex>> {
    z.iter()
        .map(|c| PyComplex::from_doubles(py, c.re, c.im))
        .collect()
}

fn params_by_name(name: &str) -> PyResult<fp::PlatformParams> {
    match name {
        "table3" => Ok(fp::PlatformParams::default()),
        "nominal" => Ok(fp::PlatformParams::nominal()),
        other => Err(PyValueError::new_err(format!(
            "params must be \"table3\" (appendix, identified input matrix) or \"nominal\", got {other:?}"
        ))),
    }
}

/// A hover model with switchable effects (`momentum_drag`, `fan_gyroscopic`, `actuator_lag`,
/// `input_delay`); `params` is `"table3"` (paper appendix) or `"nominal"` (first principles).
#[pyclass(module = "stabilis.flying_platform", name = "Model")]
#[derive(Debug, Clone)]
struct PyModel {
    inner: fp::Model,
}

#[pymethods]
impl PyModel {
    #[new]
    #[pyo3(signature = (effects = "", params = "table3"))]
    fn new(effects: &str, params: &str) -> PyResult<Self> {
        let effects = fp::EffectSet::parse(effects).map_err(to_py_err)?;
        Ok(Self {
            inner: fp::Model::new(params_by_name(params)?, effects),
        })
    }

    /// The paper's augmented model (drag, gyroscopic torque, 45 ms delay; Table 3).
    #[staticmethod]
    fn augmented() -> Self {
        Self {
            inner: fp::Model::augmented(),
        }
    }

    /// Names of the enabled effects, canonical order.
    #[getter]
    fn effects(&self) -> Vec<&'static str> {
        self.inner
            .effects
            .enabled()
            .iter()
            .map(|e| e.name())
            .collect()
    }

    /// Enables an effect by name (default parameters).
    fn enable(&mut self, name: &str) -> PyResult<()> {
        self.inner
            .effects
            .enable(fp::Effect::from_name(name).map_err(to_py_err)?);
        Ok(())
    }

    /// Disables an effect by name.
    fn disable(&mut self, name: &str) -> PyResult<()> {
        self.inner
            .effects
            .disable(fp::Effect::from_name(name).map_err(to_py_err)?);
        Ok(())
    }

    /// Names of the flat parameter vector.
    #[getter]
    fn param_names(&self) -> Vec<&'static str> {
        self.inner.param_names()
    }

    /// Parameter declarations: name, unit, lower, upper, default, description.
    fn param_specs<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.inner
            .param_specs()
            .iter()
            .map(|s| spec_dict(py, s))
            .collect()
    }

    /// The flat parameter vector of the enabled effects.
    fn parameter_vector<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.inner.parameter_vector()).into_pyarray(py)
    }

    /// Sets the flat parameter vector (length and bounds checked).
    fn set_parameter_vector(&mut self, theta: Real<Vec<f64>>) -> PyResult<()> {
        self.inner.set_parameter_vector(&theta.0).map_err(to_py_err)
    }

    /// A named effect parameter.
    fn parameter(&self, name: &str) -> PyResult<f64> {
        self.inner.parameter(name).map_err(to_py_err)
    }

    /// Sets a named effect parameter (bounds checked).
    fn set_parameter(
        &mut self,
        name: &str,
        #[pyo3(from_py_with = real)] value: f64,
    ) -> PyResult<()> {
        self.inner.set_parameter(name, value).map_err(to_py_err)
    }

    /// The 9-state hover matrices (A, B) without actuator lag.
    fn hover_matrices<'py>(&self, py: Python<'py>) -> PyResult<MatrixPair<'py>> {
        let (a, b) = self.inner.hover_matrices().map_err(to_py_err)?;
        Ok((matrix(py, &a), matrix(py, &b)))
    }

    /// Continuous-time state space {"a", "b", "c", "d", "delay"}, optionally at `theta`.
    #[pyo3(signature = (theta = None))]
    fn state_space<'py>(
        &self,
        py: Python<'py>,
        theta: Option<Real<Vec<f64>>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let ss = match theta {
            Some(Real(t)) => self.inner.state_space_at(&t),
            None => self.inner.state_space(),
        }
        .map_err(to_py_err)?;
        let d = PyDict::new(py);
        d.set_item("a", matrix(py, &ss.a))?;
        d.set_item("b", matrix(py, &ss.b))?;
        d.set_item("c", matrix(py, &ss.c))?;
        d.set_item("d", matrix(py, &ss.d))?;
        d.set_item("delay", ss.delay)?;
        Ok(d)
    }

    /// Frequency response (F, 6, 9) complex at angular frequencies `omegas` (rad/s), from the
    /// thrusts to (vx vy vz wx wy wz), with lag and delay; optionally at `theta`.
    #[pyo3(signature = (omegas, theta = None))]
    fn frequency_response<'py>(
        &self,
        py: Python<'py>,
        omegas: Real<Vec<f64>>,
        theta: Option<Real<Vec<f64>>>,
    ) -> PyResult<Bound<'py, PyArray3<Complex<f64>>>> {
        let g = match theta {
            Some(Real(t)) => self.inner.frequency_response_at(&t, &omegas.0),
            None => self.inner.frequency_response(&omegas.0),
        }
        .map_err(to_py_err)?;
        Ok(Array3::from_shape_fn((g.len(), 6, 9), |(f, i, j)| g[f][(i, j)]).into_pyarray(py))
    }

    /// Eigenvalues of A.
    fn poles<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyComplex>>> {
        Ok(complex_list(
            py,
            &self
                .inner
                .state_space()
                .map_err(to_py_err)?
                .poles()
                .map_err(to_py_err)?,
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "Model(effects={:?}, params={:?})",
            self.effects().join(","),
            self.inner.param_names()
        )
    }
}

fn spec_dict<'py>(py: Python<'py>, s: &fp::ParamSpec) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("name", s.name)?;
    d.set_item("unit", s.unit)?;
    d.set_item("lower", s.lower)?;
    d.set_item("upper", s.upper)?;
    d.set_item("default", s.default)?;
    d.set_item("description", s.description)?;
    Ok(d)
}

/// The four effects with their parameter declarations.
#[pyfunction]
fn effects(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    fp::Effect::ALL
        .iter()
        .map(|e| {
            let d = PyDict::new(py);
            d.set_item("name", e.name())?;
            let specs: PyResult<Vec<_>> = e.params().iter().map(|s| spec_dict(py, s)).collect();
            d.set_item("params", specs?)?;
            Ok(d)
        })
        .collect()
}

/// The paper's cascaded controller on the nominal design model with lever arm `l3`:
/// {"k" (9, 3), "p" (3, 3), "poles" (rate loop), "trim" (9,)}.
#[pyfunction]
#[pyo3(signature = (l3 = 0.079))]
fn controller(py: Python<'_>, #[pyo3(from_py_with = real)] l3: f64) -> PyResult<Bound<'_, PyDict>> {
    let mut design = fp::PlatformParams::nominal();
    design.l3 = l3;
    let c = fp::CascadedController::new(
        &design,
        fp::OuterGains::default(),
        fp::ActuatorLimits::default(),
    )
    .map_err(to_py_err)?;
    let d = PyDict::new(py);
    d.set_item("k", matrix(py, &c.inner_gain()))?;
    d.set_item(
        "p",
        matrix(py, &DMatrix::from_fn(3, 3, |i, j| c.inner.p[(i, j)])),
    )?;
    let cl = DMatrix::from_fn(3, 3, |i, j| c.inner.closed_loop()[(i, j)]);
    let poles: Vec<Complex<f64>> = cl.complex_eigenvalues().iter().copied().collect();
    d.set_item("poles", complex_list(py, &poles))?;
    d.set_item(
        "trim",
        Array1::from_iter(c.trim.iter().copied()).into_pyarray(py),
    )?;
    Ok(d)
}

fn design(seed: u64, lambda: Option<[f64; 3]>, periods: usize) -> PyResult<fp::ExperimentDesign> {
    // The 18 experiments of 200 + 250 periods samples are returned together.
    sim::limits::check(
        "periods",
        periods,
        18.0 * (200.0 + 250.0 * periods as f64),
        sim::limits::BYTES_PER_SAMPLE,
    )
    .map_err(to_py_err)?;
    let lambda = lambda.unwrap_or(fp::ExperimentDesign::LAMBDA_WITHIN_LIMITS);
    fp::ExperimentDesign::new(
        lambda,
        50.0,
        250,
        &(1..=20).collect::<Vec<_>>(),
        1000,
        periods,
        200,
        seed,
    )
    .map_err(to_py_err)
}

/// The 18-experiment multisine design: {"excitation" (18, samples, 9), "omegas" (20,),
/// "crest_factors" (2,), "period", "periods", "transient", "excited" (18 names), "lambda"}.
#[pyfunction]
#[pyo3(signature = (seed = 0, lambda_ = None, periods = 10))]
fn experiment_design(
    py: Python<'_>,
    seed: u64,
    lambda_: Option<Real<[f64; 3]>>,
    periods: usize,
) -> PyResult<Bound<'_, PyDict>> {
    let d = design(seed, lambda_.map(|l| l.0), periods)?;
    let signals: PyResult<Vec<Vec<[f64; 9]>>> = (0..18)
        .map(|e| d.excitation(e).map_err(to_py_err))
        .collect();
    let signals = signals?;
    let n = d.samples();
    let out = PyDict::new(py);
    out.set_item(
        "excitation",
        Array3::from_shape_fn((18, n, 9), |(e, k, i)| signals[e][k][i]).into_pyarray(py),
    )?;
    out.set_item("omegas", Array1::from(d.omegas()).into_pyarray(py))?;
    out.set_item(
        "crest_factors",
        vec![d.signals[0].crest_factor(), d.signals[1].crest_factor()],
    )?;
    out.set_item("period", d.signals[0].period)?;
    out.set_item("periods", d.periods)?;
    out.set_item("transient", d.transient)?;
    let excited: PyResult<Vec<String>> = (0..18)
        .map(|e| d.excited_names(e).map_err(to_py_err))
        .collect();
    out.set_item("excited", excited?)?;
    out.set_item("lambda", d.lambda.to_vec())?;
    Ok(out)
}

/// Truth and closed-loop settings shared by `simulate` and `run_experiments`.
#[allow(clippy::too_many_arguments)]
fn config(
    effects: &str,
    td: f64,
    dynamics: &str,
    noise_free: bool,
    seed: u64,
    log_delay_samples: usize,
    set: Option<Vec<(String, Real<f64>)>>,
) -> PyResult<fp::SimConfig> {
    let (dynamics, params) = match dynamics {
        "linear" => (fp::Dynamics::Linear, fp::PlatformParams::default()),
        "nonlinear" => (fp::Dynamics::Nonlinear, fp::PlatformParams::nominal()),
        other => {
            return Err(PyValueError::new_err(format!(
                "dynamics must be \"linear\" or \"nonlinear\", got {other:?}"
            )))
        }
    };
    let mut truth = fp::Model::new(params, fp::EffectSet::parse(effects).map_err(to_py_err)?);
    if truth.effects.contains(fp::Effect::InputDelay) {
        truth.set_parameter("td", td).map_err(to_py_err)?;
    }
    for (name, Real(value)) in set.unwrap_or_default() {
        truth.set_parameter(&name, value).map_err(to_py_err)?;
    }
    let mut cfg = fp::SimConfig::reference(truth, dynamics, seed).map_err(to_py_err)?;
    cfg.log_delay_samples = log_delay_samples;
    if noise_free {
        cfg.noise = fp::Noise::none();
    }
    Ok(cfg)
}

fn log_dict<'py>(py: Python<'py>, log: &fp::SimLog) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("t", Array1::from(log.t.clone()).into_pyarray(py))?;
    d.set_item("input", rows(py, &log.input))?;
    d.set_item("output", rows(py, &log.output))?;
    d.set_item("excitation", rows(py, &log.excitation))?;
    d.set_item("position", rows(py, &log.position))?;
    d.set_item("true_output", rows(py, &log.true_output))?;
    d.set_item("input_names", fp::INPUT_NAMES.to_vec())?;
    d.set_item("output_names", fp::LOG_OUTPUT_NAMES.to_vec())?;
    d.set_item("saturated_samples", log.saturated_samples)?;
    Ok(d)
}

/// Closed-loop run: `scenario` "hover", "disturbance" (rate kick at 0.4 s) or "step"
/// (position set-point `step`); `excitation` (samples, 9) is added to the commands.
/// `effects` of the truth with `td` the in-loop delay; `set` overrides effect parameters.
/// Returns {"t", "input", "output", "excitation", "position", "true_output", ...}.
#[pyfunction]
#[pyo3(signature = (scenario = "hover", duration = 20.0, effects = "momentum_drag,fan_gyroscopic,input_delay", td = 0.015,
    dynamics = "linear", noise_free = false, seed = 0, log_delay_samples = 0, set = None, step = None, excitation = None))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    scenario: &str,
    #[pyo3(from_py_with = real)] duration: f64,
    effects: &str,
    #[pyo3(from_py_with = real)] td: f64,
    dynamics: &str,
    noise_free: bool,
    seed: u64,
    log_delay_samples: usize,
    set: Option<Vec<(String, Real<f64>)>>,
    step: Option<Real<[f64; 3]>>,
    excitation: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<Bound<'py, PyDict>> {
    if !(duration.is_finite() && duration > 0.0) {
        return Err(PyValueError::new_err(format!(
            "duration must be positive, got {duration}"
        )));
    }
    let cfg = config(
        effects,
        td,
        dynamics,
        noise_free,
        seed,
        log_delay_samples,
        set,
    )?;
    let samples = sim::scenarios::samples(duration, cfg.sample_rate_hz).map_err(to_py_err)?;
    let mut sc = fp::Scenario {
        samples,
        ..Default::default()
    };
    match scenario {
        "hover" => {}
        "disturbance" => {
            sc.rate_override = Some(RateOverride {
                start: 0.4,
                end: 0.58,
                rates: Vector3::new(0.0, 0.3, 0.0),
            });
        }
        "step" => {
            let s = step.map_or([1.0, 0.0, 0.0], |s| s.0);
            sc.setpoints = vec![(
                0.0,
                Setpoint {
                    position: Vector3::from(s),
                    yaw: 0.0,
                },
            )];
        }
        other => {
            return Err(PyValueError::new_err(format!(
                "scenario must be \"hover\", \"disturbance\" or \"step\", got {other:?}"
            )))
        }
    }
    if let Some(x) = excitation {
        let a = x.as_array();
        if a.ncols() != 9 || a.nrows() < sc.samples {
            return Err(PyValueError::new_err(format!(
                "excitation must have shape (>= {}, 9), got {:?}",
                sc.samples,
                a.shape()
            )));
        }
        sc.excitation = (0..sc.samples)
            .map(|k| core::array::from_fn(|i| a[[k, i]]))
            .collect();
    }
    let log = py.detach(|| fp::simulate(&cfg, &sc)).map_err(to_py_err)?;
    log_dict(py, &log)
}

/// The 18 closed-loop identification experiments as a list of dicts (arrays as in
/// `simulate`, plus "metadata", the `experiment` record of the MCAP files).
#[pyfunction]
#[pyo3(signature = (effects = "momentum_drag,fan_gyroscopic,input_delay", td = 0.015, dynamics = "linear",
    noise_free = false, seed = 0, lambda_ = None, periods = 10, log_delay_samples = 0, set = None))]
#[allow(clippy::too_many_arguments)]
fn run_experiments<'py>(
    py: Python<'py>,
    effects: &str,
    #[pyo3(from_py_with = real)] td: f64,
    dynamics: &str,
    noise_free: bool,
    seed: u64,
    lambda_: Option<Real<[f64; 3]>>,
    periods: usize,
    log_delay_samples: usize,
    set: Option<Vec<(String, Real<f64>)>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let cfg = config(
        effects,
        td,
        dynamics,
        noise_free,
        seed,
        log_delay_samples,
        set,
    )?;
    let d = design(seed, lambda_.map(|l| l.0), periods)?;
    let runs = py
        .detach(|| fp::run_experiments(&cfg, &d))
        .map_err(to_py_err)?;
    runs.iter()
        .map(|run| {
            let out = log_dict(py, &run.log)?;
            let meta = PyDict::new(py);
            for (k, v) in &run.metadata {
                meta.set_item(k, v)?;
            }
            out.set_item("metadata", meta)?;
            Ok(out)
        })
        .collect()
}

/// Reachability Gramian of the thrust-vectoring subsystem over `horizon` s, with its
/// determinant and the closed form: {"w" (6, 6), "det", "det_closed_form"}.
#[pyfunction]
#[pyo3(signature = (mass = 8.0, i1 = 0.07, l3 = 0.17, horizon = 1.0))]
fn gramian(
    py: Python<'_>,
    #[pyo3(from_py_with = real)] mass: f64,
    #[pyo3(from_py_with = real)] i1: f64,
    #[pyo3(from_py_with = real)] l3: f64,
    #[pyo3(from_py_with = real)] horizon: f64,
) -> PyResult<Bound<'_, PyDict>> {
    let mut p = fp::PlatformParams::nominal();
    p.mass = mass;
    p.i1 = i1;
    p.l3 = l3;
    let (a, b) = thrust_vectoring_system(&p).map_err(to_py_err)?;
    let w = reachability_gramian(&a, &b, horizon).map_err(to_py_err)?;
    let d = PyDict::new(py);
    d.set_item("det", w.determinant())?;
    d.set_item(
        "det_closed_form",
        gramian_det_closed_form(p.g0, horizon, l3, i1),
    )?;
    d.set_item("w", matrix(py, &w))?;
    Ok(d)
}

/// Optimal lever arm l3 (m) maximising l3 / I1(l3), with I1 = I0 + 2 l1² m_t + k δ² l3² m_t.
#[pyfunction]
#[pyo3(signature = (i0 = 0.014, unit_mass = 1.2, l1 = 0.1, delta = 0.75, vertical_factor = 2.0))]
fn optimal_l3(
    #[pyo3(from_py_with = real)] i0: f64,
    #[pyo3(from_py_with = real)] unit_mass: f64,
    #[pyo3(from_py_with = real)] l1: f64,
    #[pyo3(from_py_with = real)] delta: f64,
    #[pyo3(from_py_with = real)] vertical_factor: f64,
) -> PyResult<f64> {
    LeverArmTradeoff {
        i0,
        unit_mass,
        l1,
        delta,
        vertical_factor,
    }
    .optimal_l3()
    .map_err(to_py_err)
}

pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = parent.py();
    let module = PyModule::new(py, "flying_platform")?;
    module.add("INPUT_NAMES", fp::INPUT_NAMES.to_vec())?;
    module.add("OUTPUT_NAMES", fp::OUTPUT_NAMES.to_vec())?;
    module.add("LOG_OUTPUT_NAMES", fp::LOG_OUTPUT_NAMES.to_vec())?;
    module.add("STATE_NAMES", fp::STATE_NAMES.to_vec())?;
    module.add_class::<PyModel>()?;
    for f in [
        wrap_pyfunction!(effects, &module)?,
        wrap_pyfunction!(controller, &module)?,
        wrap_pyfunction!(experiment_design, &module)?,
        wrap_pyfunction!(simulate, &module)?,
        wrap_pyfunction!(run_experiments, &module)?,
        wrap_pyfunction!(gramian, &module)?,
        wrap_pyfunction!(optimal_l3, &module)?,
    ] {
        module.add_function(f)?;
    }
    parent.add_submodule(&module)
}
