//! Python bindings of the model workbench: `stabilis.Workbench(system, data)` with
//! `compare`, `diagnose`, `discover`, `add`, `fit`, `report` (flying platform: FRF-based, plus
//! the measured FRF as numpy; Cubli: time-domain prediction error), and `stabilis.Effect`, a
//! user-defined effect whose Python callable returns the extra terms of the state-space model.
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use numpy::ndarray::{Array2, Array3};
use numpy::{Complex64, IntoPyArray, PyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sim::workbench::cubli::{CubliBench, CubliDiscovery};
use sim::workbench::flying_platform::{embedded_dataset, FlyingPlatform};
use sim::workbench::model::{Effect as EffectTrait, Parameter, StateSpace};
use sim::workbench::report::{json, write_cubli_report, write_report};
use sim::workbench::{load, Discovery, EstimatorChoice, ModelStructure};

use crate::errors::to_py_err;

fn to_dict<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?
        .call_method1("loads", (value.to_string(),))
}

fn checked(value: serde_json::Result<serde_json::Value>) -> PyResult<serde_json::Value> {
    value.map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A user-defined effect: `fn(params, model)` gets the parameter values as a dict
/// `{name: float}` and the model's current matrices as a dict `{"A", "B", "C", "D"}` of numpy
/// arrays, and returns a dict with any of `"A"`, `"B"`, `"C"`, `"D"`: arrays of the same shape
/// added to the model. The workbench fits its parameters with the model's own.
#[pyclass(name = "Effect", module = "stabilis._stabilis.workbench", frozen)]
#[derive(Debug)]
struct Effect {
    name: String,
    description: String,
    params: Vec<Parameter>,
    func: Py<PyAny>,
}

#[pymethods]
impl Effect {
    #[new]
    #[pyo3(signature = (name, params, func, bounds = None, units = None, description = ""))]
    fn new(
        py: Python<'_>,
        name: String,
        params: &Bound<'_, PyDict>,
        func: Py<PyAny>,
        bounds: Option<HashMap<String, (f64, f64)>>,
        units: Option<HashMap<String, String>>,
        description: &str,
    ) -> PyResult<Self> {
        let params: Vec<(String, f64)> = params
            .iter()
            .map(|(k, v)| Ok((k.extract::<String>()?, v.extract::<f64>()?)))
            .collect::<PyResult<_>>()
            .map_err(|_| {
                PyTypeError::new_err(format!(
                    "effect {name}: params must map names (str) to documented values (float)"
                ))
            })?;
        if name.is_empty() {
            return Err(PyValueError::new_err("effect name must not be empty"));
        }
        if params.is_empty() {
            return Err(PyValueError::new_err(format!(
                "effect {name}: give at least one parameter"
            )));
        }
        let bounds = bounds.unwrap_or_default();
        let units = units.unwrap_or_default();
        for key in bounds.keys().chain(units.keys()) {
            if !params.iter().any(|(p, _)| p == key) {
                return Err(PyValueError::new_err(format!(
                    "effect {name}: bounds or units name {key:?}, which is not a parameter"
                )));
            }
        }
        let params: Vec<Parameter> = params
            .into_iter()
            .map(|(p, value)| {
                let (lower, upper) = bounds
                    .get(&p)
                    .copied()
                    .unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
                let unit = units.get(&p).cloned().unwrap_or_default();
                Parameter::new(p, value, lower, upper, unit)
            })
            .collect();
        sim::workbench::model::check_parameters(&params).map_err(to_py_err)?;
        if !func.bind(py).is_callable() {
            return Err(PyTypeError::new_err(format!(
                "effect {name}: func must be callable"
            )));
        }
        Ok(Self {
            name,
            description: description.to_string(),
            params,
            func,
        })
    }

    /// The effect's name.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// `{parameter: documented value}`.
    #[getter]
    fn params(&self) -> Vec<(String, f64)> {
        self.params
            .iter()
            .map(|p| (p.name.clone(), p.value))
            .collect()
    }

    fn __repr__(&self) -> String {
        format!("Effect({:?}, {:?})", self.name, self.params())
    }
}

/// The Rust side of a [`Effect`]: calls the Python function under the GIL and keeps the first
/// Python exception so that the workbench call that failed re-raises it unchanged.
#[derive(Debug)]
struct PyEffect {
    effect: Py<Effect>,
    error: Arc<Mutex<Option<PyErr>>>,
}

impl PyEffect {
    fn call(&self, py: Python<'_>, theta: &[f64], ss: &mut StateSpace) -> PyResult<()> {
        let effect = self.effect.get();
        let params = PyDict::new(py);
        for (p, v) in effect.params.iter().zip(theta) {
            params.set_item(&p.name, v)?;
        }
        let model = PyDict::new(py);
        let mats: [(&str, &mut nalgebra::DMatrix<f64>); 4] = [
            ("A", &mut ss.a),
            ("B", &mut ss.b),
            ("C", &mut ss.c),
            ("D", &mut ss.d),
        ];
        for (key, m) in &mats {
            let a = Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]);
            model.set_item(*key, a.into_pyarray(py))?;
        }
        let out = effect.func.call1(py, (params, model))?;
        let out = out.bind(py).cast::<PyDict>().map_err(|_| {
            PyTypeError::new_err(format!(
                "effect {}: the callable must return a dict with keys among A, B, C, D",
                effect.name
            ))
        })?;
        let np = py.import("numpy")?;
        let mut additions = Vec::new();
        for (key, value) in out.iter() {
            let key: String = key.extract()?;
            let Some(i) = mats.iter().position(|(k, _)| *k == key) else {
                return Err(PyValueError::new_err(format!(
                    "effect {}: returned key {key:?}; use A, B, C or D",
                    effect.name
                )));
            };
            let array = np.call_method1("asarray", (value, "float64"))?;
            let array: PyReadonlyArray2<f64> = array.extract().map_err(|_| {
                PyValueError::new_err(format!("effect {}: {key} must be a 2-D array", effect.name))
            })?;
            let array = array.as_array();
            let target = &mats[i].1;
            if array.dim() != (target.nrows(), target.ncols()) {
                return Err(PyValueError::new_err(format!(
                    "effect {}: returned {key} of shape {:?}; the model's {key} is ({}, {})",
                    effect.name,
                    array.dim(),
                    target.nrows(),
                    target.ncols()
                )));
            }
            if let Some(((r, c), v)) = array.indexed_iter().find(|(_, v)| !v.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "effect {}: returned {key}[{r}, {c}] = {v} at params {theta:?}",
                    effect.name
                )));
            }
            additions.push((i, array.to_owned()));
        }
        let [(_, a), (_, b), (_, c), (_, d)] = mats;
        let mut targets = [a, b, c, d];
        for (i, array) in additions {
            let m = &mut targets[i];
            for ((r, c), v) in array.indexed_iter() {
                m[(r, c)] += v;
            }
        }
        Ok(())
    }
}

impl EffectTrait for PyEffect {
    fn name(&self) -> &str {
        &self.effect.get().name
    }

    fn description(&self) -> &str {
        &self.effect.get().description
    }

    fn parameters(&self) -> Vec<Parameter> {
        self.effect.get().params.clone()
    }

    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> sim::Result<()> {
        Python::attach(|py| self.call(py, theta, ss)).map_err(|err| {
            let message = err.to_string();
            if let Ok(mut slot) = self.error.lock() {
                slot.get_or_insert(err);
            }
            sim::SimError::invalid(
                format!("effect {}", self.effect.get().name),
                "Python callable",
                message,
            )
        })
    }
}

/// What a workbench works on.
enum Inner {
    /// FRF-based (flying platform).
    Frf {
        wb: Box<sim::workbench::Workbench>,
        last: Option<Discovery>,
    },
    /// Time-domain prediction error (Cubli).
    Cubli {
        bench: Box<CubliBench>,
        last: Option<CubliDiscovery>,
    },
}

/// Workbench on one system's measurements (for the flying platform, the embedded dataset when
/// `data` is None; the Cubli needs logs).
#[pyclass(name = "Workbench", module = "stabilis._stabilis.workbench")]
struct Workbench {
    inner: Inner,
    /// First Python exception raised by a user effect during the running call.
    error: Arc<Mutex<Option<PyErr>>>,
}

impl Workbench {
    /// [`run_with`] on this workbench's error slot.
    fn run<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce() -> sim::Result<T> + Send,
    ) -> PyResult<T> {
        run_with(&self.error, py, f)
    }
}

/// Runs `f` without the GIL; a failure caused by a user effect re-raises that effect's Python
/// exception (kept in `error`).
fn run_with<T: Send>(
    error: &Mutex<Option<PyErr>>,
    py: Python<'_>,
    f: impl FnOnce() -> sim::Result<T> + Send,
) -> PyResult<T> {
    if let Ok(mut slot) = error.lock() {
        slot.take();
    }
    let result = py.detach(f);
    let stashed = error.lock().ok().and_then(|mut slot| slot.take());
    match (result, stashed) {
        (Ok(v), _) => Ok(v),
        (Err(_), Some(err)) => Err(err),
        (Err(e), None) => Err(to_py_err(e)),
    }
}

impl Workbench {
    /// Runs `discover` (or the one-step `fit`), keeps the result for `report` and returns its
    /// JSON.
    fn keep(&mut self, py: Python<'_>, discover: bool) -> PyResult<serde_json::Value> {
        let error = &self.error;
        Ok(match &mut self.inner {
            Inner::Frf { wb, last } => {
                let d = run_with(error, py, || {
                    if discover {
                        wb.discover()
                    } else {
                        wb.compare().map(|s| wb.record(s))
                    }
                })?;
                let value = json(wb, &d);
                *last = Some(d);
                value
            }
            Inner::Cubli { bench, last } => {
                let d = run_with(error, py, || {
                    if discover {
                        bench.discover()
                    } else {
                        bench.fit()
                    }
                })?;
                let value = d.json();
                *last = Some(d);
                value
            }
        })
    }
}

#[pymethods]
impl Workbench {
    #[new]
    #[pyo3(signature = (system = "flying_platform", data = None, estimator = "auto"))]
    fn new(
        py: Python<'_>,
        system: &str,
        data: Option<Vec<PathBuf>>,
        estimator: &str,
    ) -> PyResult<Self> {
        let choice = match estimator {
            "auto" => EstimatorChoice::Auto,
            "ls" => EstimatorChoice::LeastSquares,
            "iv" => EstimatorChoice::InstrumentalVariable,
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown estimator {other:?}; use auto, ls or iv"
                )))
            }
        };
        let inner = match system {
            "flying_platform" => {
                let structure: Arc<dyn ModelStructure> = Arc::new(FlyingPlatform::default());
                let wb = py
                    .detach(|| {
                        let dataset = match &data {
                            None => embedded_dataset()?,
                            Some(paths) => load::load(
                                structure.system(),
                                &structure.inputs(),
                                &structure.outputs(),
                                paths,
                            )?,
                        };
                        sim::workbench::Workbench::new(structure, dataset, choice)
                    })
                    .map_err(to_py_err)?;
                Inner::Frf {
                    wb: Box::new(wb),
                    last: None,
                }
            }
            "cubli" => {
                let paths = data.ok_or_else(|| {
                    PyValueError::new_err(
                        "the cubli workbench needs logs: data=[run1.mcap, run2.mcap, ...]",
                    )
                })?;
                let bench = py.detach(|| CubliBench::load(&paths)).map_err(to_py_err)?;
                Inner::Cubli {
                    bench: Box::new(bench),
                    last: None,
                }
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown system {other:?}; the workbench knows: flying_platform, cubli"
                )))
            }
        };
        Ok(Self {
            inner,
            error: Arc::new(Mutex::new(None)),
        })
    }

    /// The system name.
    #[getter]
    fn system(&self) -> &str {
        match &self.inner {
            Inner::Frf { .. } => "flying_platform",
            Inner::Cubli { .. } => "cubli",
        }
    }

    /// Fits the current model: a dict with `steps` (one), `found` (empty), `unexplained`.
    fn compare<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = match &self.inner {
            Inner::Frf { wb, .. } => {
                let d = self.run(py, || wb.compare().map(|s| wb.record(s)))?;
                json(wb, &d)
            }
            Inner::Cubli { bench, .. } => self.run(py, || bench.fit())?.json(),
        };
        to_dict(py, &value)
    }

    /// Where the current model fails. Flying platform: misfit per line and output against the
    /// noise level, time-domain fit % and the residual whiteness / input-correlation tests.
    /// Cubli: per residual channel the RMS over the noise level and the probe test.
    fn diagnose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = match &self.inner {
            Inner::Frf { wb, .. } => {
                let step = self.run(py, || wb.compare())?;
                let mut value = checked(serde_json::to_value(&step.diagnosis))?;
                for (key, part) in [
                    ("time_fit", checked(serde_json::to_value(&step.time_fit))?),
                    (
                        "residual_tests",
                        checked(serde_json::to_value(&step.residual_tests))?,
                    ),
                ] {
                    if let Some(map) = value.as_object_mut() {
                        map.insert(key.to_string(), part);
                    }
                }
                value
            }
            Inner::Cubli { bench, .. } => {
                let d = self.run(py, || bench.fit())?;
                let channels = self.run(py, || bench.diagnose())?;
                serde_json::json!({
                    "channels": checked(serde_json::to_value(&channels))?,
                    "misfit_channels": d.misfit_channels,
                    "unexplained": d.unexplained,
                    "verdict": d.verdict(),
                })
            }
        };
        to_dict(py, &value)
    }

    /// Runs the discovery loop: `{"steps": [...], "found": [...], "unexplained": bool, ...}`.
    fn discover<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = self.keep(py, true)?;
        to_dict(py, &value)
    }

    /// Enables an effect: a name (flying platform: `momentum_drag`, `fan_gyroscopic`,
    /// `actuator_lag`, `input_delay`; Cubli: `wheel_viscous_friction`,
    /// `wheel_coulomb_friction`, `gyro_bias`, `torque_constant`) or a [`Effect`] (flying
    /// platform), which is evaluated once at its documented values to catch errors now.
    ///
    /// A bare callable is wrapped as `Effect(name or func.__name__, params, func, bounds,
    /// units)`.
    #[pyo3(signature = (effect, params = None, bounds = None, units = None, name = None))]
    fn add(
        &mut self,
        py: Python<'_>,
        effect: &Bound<'_, PyAny>,
        params: Option<&Bound<'_, PyDict>>,
        bounds: Option<HashMap<String, (f64, f64)>>,
        units: Option<HashMap<String, String>>,
        name: Option<String>,
    ) -> PyResult<()> {
        let extras = params.is_some() || bounds.is_some() || units.is_some() || name.is_some();
        let is_effect = effect.cast::<Effect>().is_ok();
        if extras && (is_effect || !effect.is_callable()) {
            return Err(PyTypeError::new_err(
                "params, bounds, units and name go with a callable, not with an effect name or a stabilis.Effect",
            ));
        }
        if let Ok(name) = effect.extract::<String>() {
            return match &mut self.inner {
                Inner::Frf { wb, .. } => wb.add(&name),
                Inner::Cubli { bench, .. } => bench.add(&name),
            }
            .map_err(to_py_err);
        }
        let user: Bound<'_, Effect> = if let Ok(user) = effect.cast::<Effect>() {
            user.clone()
        } else if effect.is_callable() {
            let params = params.ok_or_else(|| {
                PyTypeError::new_err("add(func) needs params={name: documented value}")
            })?;
            let name = match name {
                Some(n) => n,
                None => effect.getattr("__name__")?.extract()?,
            };
            let built = Effect::new(py, name, params, effect.clone().unbind(), bounds, units, "")?;
            Bound::new(py, built)?
        } else {
            return Err(PyTypeError::new_err(
                "add() takes an effect name, a stabilis.Effect or a callable with params",
            ));
        };
        let Inner::Frf { wb, .. } = &self.inner else {
            return Err(PyValueError::new_err(
                "user-defined effects edit a state-space model; the cubli workbench fits its named candidates only",
            ));
        };
        let mut next = wb.clone();
        next.add_user_effect(Arc::new(PyEffect {
            effect: user.clone().unbind(),
            error: Arc::clone(&self.error),
        }))
        .map_err(to_py_err)?;
        self.run(py, || {
            let theta: Vec<f64> = next.model().parameters()?.iter().map(|p| p.value).collect();
            next.model().state_space(&theta).map(|_| ())
        })?;
        if let Inner::Frf { wb, .. } = &mut self.inner {
            *wb = next;
        }
        Ok(())
    }

    /// Fits all parameters of the current model (same record as `compare`).
    fn fit<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = self.keep(py, false)?;
        to_dict(py, &value)
    }

    /// Writes the HTML report of the last `discover` or `fit` (running `discover` if neither ran).
    fn report(&mut self, py: Python<'_>, dir: PathBuf) -> PyResult<()> {
        let done = match &self.inner {
            Inner::Frf { last, .. } => last.is_some(),
            Inner::Cubli { last, .. } => last.is_some(),
        };
        if !done {
            self.discover(py)?;
        }
        match &self.inner {
            Inner::Frf { wb, last: Some(d) } => self.run(py, || write_report(&dir, wb, d)),
            Inner::Cubli { last: Some(d), .. } => self.run(py, || write_cubli_report(&dir, d)),
            _ => Err(PyValueError::new_err("nothing to report")),
        }
    }

    /// The measured FRF: `(freqs_hz, G, std)` with `G` complex of shape (lines, outputs, inputs).
    fn frf<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let Inner::Frf { wb, .. } = &self.inner else {
            return Err(PyValueError::new_err(
                "the cubli workbench works in the time domain and has no FRF",
            ));
        };
        let frf = wb.frf();
        let (n, ny, nu) = (frf.lines.len(), frf.ny(), frf.nu());
        let g = Array3::from_shape_fn((n, ny, nu), |(k, i, j)| {
            let z = frf.lines[k].g[(i, j)];
            Complex64::new(z.re, z.im)
        });
        let std = Array3::from_shape_fn((n, ny, nu), |(k, i, j)| wb.cost().std[k][(i, j)]);
        let out = PyDict::new(py);
        out.set_item("freqs_hz", PyArray1::from_vec(py, frf.freqs_hz()))?;
        out.set_item("G", g.into_pyarray(py))?;
        out.set_item("std", std.into_pyarray(py))?;
        out.set_item("inputs", frf.inputs.clone())?;
        out.set_item("outputs", frf.outputs.clone())?;
        out.set_item("estimator", format!("{:?}", frf.estimator))?;
        Ok(out)
    }
}

/// Adds the `workbench` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let module = PyModule::new(parent.py(), "workbench")?;
    module.add_class::<Workbench>()?;
    module.add_class::<Effect>()?;
    parent.add_submodule(&module)
}
