//! Python bindings of the model workbench: `stabilis.Workbench(system, data, model=...)` with
//! `compare`, `diagnose`, `discover`, `add`, `fit`, `report` and the measured FRF as numpy, for
//! any model (a model file, a Python model, a shipped system) under the FRF or the time-domain
//! criterion, or the Cubli's own time-domain workbench; and `stabilis.Effect`, a user-defined
//! effect whose Python callables return the terms it adds to the model.
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use numpy::ndarray::{Array2, Array3};
use numpy::{Complex64, IntoPyArray, PyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sim::systems::cubli::{
    load_cubli, write_cubli_report, CubliBench, CubliDiscovery, CubliOptions,
};
use sim::systems::flying_platform::embedded_dataset;
use sim::systems::{self, Source};
use workbench::dataset::detect_period;
use workbench::dynamics::Dynamics;
use workbench::model::{Effect as EffectTrait, Parameter, StateSpace};
use workbench::report::{json, write_report};
use workbench::{load, Dataset, Discovery, EstimatorChoice, Experiment, ModelFile, ModelStructure};

use crate::callables::{Callables, Extra, PyDynamics};
use crate::errors::{to_py_err, ModelError};
use crate::interrupt::{interruptible, Raised};
use crate::real::{real_array, Real};

fn to_dict<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?
        .call_method1("loads", (value.to_string(),))
}

fn checked(value: serde_json::Result<serde_json::Value>) -> PyResult<serde_json::Value> {
    value.map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A user-defined effect, in one of two forms. Matrix form (linear models, and any model
/// under the FRF criterion): `func(params, model)` gets the parameter values as a dict
/// `{name: float}` and the model's current matrices as a dict `{"A", "B", "C", "D"}` of numpy
/// arrays, and returns a dict with any of `"A"`, `"B"`, `"C"`, `"D"`: arrays of the same shape
/// added to the model. Nonlinear form (a nonlinear Python model, `Model(f=, h=)`): `f(x, u,
/// params)` returns the terms added to the state derivative, `h(x, u, params)` those added to
/// the outputs (either may be omitted), `params` holding the model's parameters (fitted and
/// fixed) and the effect's own. The workbench fits its parameters with the model's own.
#[pyclass(name = "Effect", module = "stabilis._stabilis.workbench", frozen)]
#[derive(Debug)]
struct Effect {
    name: String,
    description: String,
    params: Vec<Parameter>,
    func: Option<Py<PyAny>>,
    f: Option<Py<PyAny>>,
    h: Option<Py<PyAny>>,
    /// States of its own (nonlinear form), after the model's.
    states: Vec<String>,
    /// Their operating point.
    x_op: Vec<f64>,
}

#[pymethods]
impl Effect {
    #[new]
    #[pyo3(signature = (name, params, func = None, bounds = None, units = None, description = "", f = None, h = None, states = None, operating_point = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        name: String,
        params: &Bound<'_, PyAny>,
        func: Option<Py<PyAny>>,
        bounds: Option<&Bound<'_, PyAny>>,
        units: Option<&Bound<'_, PyAny>>,
        description: &str,
        f: Option<Py<PyAny>>,
        h: Option<Py<PyAny>>,
        states: Option<Vec<String>>,
        operating_point: Option<HashMap<String, Real<f64>>>,
    ) -> PyResult<Self> {
        let wrong = |what: &str, expected: &str| {
            PyTypeError::new_err(format!("effect {name}: {what} must map {expected}"))
        };
        let params: Vec<(String, f64)> = params
            .cast::<PyDict>()
            .map_err(PyErr::from)
            .and_then(|d| {
                d.iter()
                    .map(|(k, v)| Ok((k.extract::<String>()?, v.extract::<Real<f64>>()?.0)))
                    .collect::<PyResult<_>>()
            })
            .map_err(|_| wrong("params", "names (str) to documented values (float)"))?;
        if name.is_empty() {
            return Err(PyValueError::new_err("effect name must not be empty"));
        }
        if params.is_empty() {
            return Err(PyValueError::new_err(format!(
                "effect {name}: give at least one parameter"
            )));
        }
        let bounds: HashMap<String, Real<(f64, f64)>> = bounds
            .map(|b| b.extract())
            .transpose()
            .map_err(|e| wrong("bounds", &format!("parameter names to (min, max); {e}")))?
            .unwrap_or_default();
        let units: HashMap<String, String> = units
            .map(|u| u.extract())
            .transpose()
            .map_err(|_| wrong("units", "parameter names to units (str)"))?
            .unwrap_or_default();
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
                    .map_or((f64::NEG_INFINITY, f64::INFINITY), |b| b.0);
                let unit = units.get(&p).cloned().unwrap_or_default();
                Parameter::new(p, value, lower, upper, unit)
            })
            .collect();
        // A ValueError naming the effect, as a model's parameters get.
        workbench::model::check_parameters(&params)
            .map_err(|e| PyValueError::new_err(format!("effect {name}: {e}")))?;
        match (&func, &f, &h) {
            (Some(_), None, None) | (None, Some(_), _) | (None, None, Some(_)) => {}
            (None, None, None) => {
                return Err(PyTypeError::new_err(format!(
                    "effect {name}: give func (terms added to A, B, C, D) or f= and/or h= (terms added to a nonlinear model's f and h)"
                )))
            }
            _ => {
                return Err(PyTypeError::new_err(format!(
                    "effect {name}: give func (terms added to A, B, C, D) or f=/h= (terms added to a nonlinear model's f and h), not both"
                )))
            }
        }
        for (label, c) in [("func", &func), ("f", &f), ("h", &h)] {
            if c.as_ref().is_some_and(|c| !c.bind(py).is_callable()) {
                return Err(PyTypeError::new_err(format!(
                    "effect {name}: {label} must be callable"
                )));
            }
        }
        // States of its own: its f gives their derivatives after the model's (the matrix
        // form adds states by returning a larger A instead).
        let states = states.unwrap_or_default();
        let mut point = operating_point.unwrap_or_default();
        if !states.is_empty() && f.is_none() {
            return Err(PyValueError::new_err(format!(
                "effect {name}: states need f= giving their derivatives (after the model's); the matrix form adds states by returning a larger A"
            )));
        }
        if states.is_empty() && !point.is_empty() {
            return Err(PyValueError::new_err(format!(
                "effect {name}: operating_point is for the effect's own states, and it has none (states=)"
            )));
        }
        for (i, state) in states.iter().enumerate() {
            if state.is_empty() || states[..i].contains(state) {
                return Err(PyValueError::new_err(format!(
                    "effect {name}: state {state:?} is empty or named twice"
                )));
            }
        }
        let x_op = states
            .iter()
            .map(|s| point.remove(s).map_or(0.0, |v| v.0))
            .collect();
        if let Some(other) = point.keys().next() {
            return Err(PyValueError::new_err(format!(
                "effect {name}: operating_point names {other:?}, not one of its states: {}",
                states.join(", ")
            )));
        }
        Ok(Self {
            name,
            description: description.to_string(),
            params,
            func,
            f,
            h,
            states,
            x_op,
        })
    }

    /// Whether the effect is in nonlinear form (`f=`/`h=`).
    #[getter]
    fn nonlinear(&self) -> bool {
        self.func.is_none()
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
    error: Arc<Raised>,
}

impl PyEffect {
    fn call(&self, py: Python<'_>, theta: &[f64], ss: &mut StateSpace) -> PyResult<()> {
        let effect = self.effect.get();
        let params = PyDict::new(py);
        for (p, v) in effect.params.iter().zip(theta) {
            params.set_item(&p.name, v)?;
        }
        let model = PyDict::new(py);
        let mut mats: [(&str, &mut nalgebra::DMatrix<f64>); 4] = [
            ("A", &mut ss.a),
            ("B", &mut ss.b),
            ("C", &mut ss.c),
            ("D", &mut ss.d),
        ];
        for (key, m) in &mats {
            let a = Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]);
            model.set_item(*key, a.into_pyarray(py))?;
        }
        let func = effect.func.as_ref().ok_or_else(|| {
            PyValueError::new_err(format!(
                "effect {}: gives f/h (terms of a nonlinear model), not matrix terms",
                effect.name
            ))
        })?;
        let out = func.call1(py, (params, model))?;
        let out = out.bind(py).cast::<PyDict>().map_err(|_| {
            PyTypeError::new_err(format!(
                "effect {}: the callable must return a dict with keys among A, B, C, D",
                effect.name
            ))
        })?;
        let mut additions = Vec::new();
        for (key, value) in out.iter() {
            let key: String = key.extract()?;
            let Some(i) = mats.iter().position(|(k, _)| *k == key) else {
                return Err(PyValueError::new_err(format!(
                    "effect {}: returned key {key:?}; use A, B, C or D",
                    effect.name
                )));
            };
            let array = real_array(&value, &format!("effect {}: {key}", effect.name))?;
            let array: PyReadonlyArray2<f64> = array.as_any().extract().map_err(|_| {
                PyValueError::new_err(format!("effect {}: {key} must be a 2-D array", effect.name))
            })?;
            let array = array.as_array();
            if let Some(((r, c), v)) = array.indexed_iter().find(|(_, v)| !v.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "effect {}: returned {key}[{r}, {c}] = {v} at params {theta:?}",
                    effect.name
                )));
            }
            additions.push((i, array.to_owned()));
        }
        // An effect may add states: a returned A larger than the model's extends the state,
        // the model's matrices padded with zeros.
        let n = mats[0].1.nrows();
        let n_new = additions
            .iter()
            .find(|(i, _)| *i == 0)
            .map_or(n, |(_, a)| a.nrows());
        if n_new < n {
            return Err(PyValueError::new_err(format!(
                "effect {}: returned A with {n_new} rows; the model has {n} states",
                effect.name
            )));
        }
        let (ny, nu) = (mats[2].1.nrows(), mats[1].1.ncols());
        let shapes = [(n_new, n_new), (n_new, nu), (ny, n_new), (ny, nu)];
        for (key, m) in mats.iter_mut() {
            let want = shapes[["A", "B", "C", "D"]
                .iter()
                .position(|k| k == key)
                .unwrap_or(0)];
            if (m.nrows(), m.ncols()) != want {
                let mut padded = nalgebra::DMatrix::zeros(want.0, want.1);
                padded.view_mut((0, 0), (m.nrows(), m.ncols())).copy_from(m);
                **m = padded;
            }
        }
        for (i, array) in &additions {
            let target = &mats[*i].1;
            if array.dim() != (target.nrows(), target.ncols()) {
                let key = ["A", "B", "C", "D"][*i];
                return Err(PyValueError::new_err(format!(
                    "effect {}: returned {key} of shape {:?}; with {n_new} states the model's {key} is ({}, {})",
                    effect.name,
                    array.dim(),
                    target.nrows(),
                    target.ncols()
                )));
            }
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
    fn parallel(&self) -> bool {
        false
    }

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
        self.error.cancel().check()?;
        Python::attach(|py| self.call(py, theta, ss)).map_err(|err| {
            let name = format!("effect {}", self.effect.get().name);
            self.error.keep_as(err, name, "Python callable")
        })
    }
}

/// A user's model as a workbench structure: Python callables evaluated under the GIL, their
/// first exception kept for the caller like an effect's.
#[derive(Debug)]
struct PyStructure {
    name: String,
    states: Vec<String>,
    inputs: Vec<String>,
    outputs: Vec<String>,
    params: Vec<Parameter>,
    fixed: Vec<(String, f64)>,
    form: Form,
    /// Effects in nonlinear form (`Effect(f=, h=)`), declared by `Model(effects=)` or, on a
    /// workbench's own copy, by `suspect` and `add`: the structure's effects, as a model
    /// file's `[effects]`.
    declared: Mutex<Vec<Arc<Py<Effect>>>>,
    error: Arc<Raised>,
}

/// How a Python model is given.
#[derive(Debug)]
enum Form {
    /// `matrices(params) -> (A, B, C, D)`.
    Linear(Py<PyAny>),
    /// `f(x, u, params)` and `h(x, u, params)`.
    Nonlinear(Arc<Callables>),
}

impl PyStructure {
    /// How messages name this model.
    fn label(&self) -> String {
        model_label(&self.name)
    }

    /// The same model under another system name, keeping its callables' exceptions in `error`.
    fn named(&self, py: Python<'_>, name: String, error: Arc<Raised>) -> Self {
        Self {
            name,
            states: self.states.clone(),
            inputs: self.inputs.clone(),
            outputs: self.outputs.clone(),
            params: self.params.clone(),
            fixed: self.fixed.clone(),
            form: match &self.form {
                Form::Linear(m) => Form::Linear(m.clone_ref(py)),
                Form::Nonlinear(c) => Form::Nonlinear(Arc::new(c.clone_ref(py))),
            },
            declared: Mutex::new(self.declared_effects()),
            error,
        }
    }

    /// The declared effects (the lock is never held while Python runs).
    fn declared_effects(&self) -> Vec<Arc<Py<Effect>>> {
        self.declared.lock().map(|d| d.clone()).unwrap_or_default()
    }

    /// The `enabled` declared effects, in that order.
    fn enabled_effects(&self, enabled: &[String]) -> sim::Result<Vec<Arc<Py<Effect>>>> {
        let all = self.declared_effects();
        enabled
            .iter()
            .map(|n| {
                all.iter()
                    .find(|e| e.get().name == *n)
                    .cloned()
                    .ok_or_else(|| {
                        sim::SimError::invalid(
                            "effect",
                            n,
                            format!("not declared in the Python {}", self.label()),
                        )
                    })
            })
            .collect()
    }

    /// Declares a nonlinear effect after checking its name against `taken` (the effects the
    /// model may not lose) and its parameters against the model's.
    fn declare(&self, effect: Arc<Py<Effect>>, taken: &[String]) -> PyResult<()> {
        let e = effect.get();
        let Form::Nonlinear(_) = self.form else {
            return Err(PyValueError::new_err(format!(
                "effect {}: f=/h= add terms to a nonlinear model's f and h; the {} is linear (matrices=): give the effect as Effect(name, params, func) returning terms added to A, B, C, D",
                e.name, self.label()
            )));
        };
        let declared = self.declared_effects();
        if taken.contains(&e.name) || declared.iter().any(|d| d.get().name == e.name) {
            return Err(PyValueError::new_err(format!(
                "effect {}: the model already has an effect of that name",
                e.name
            )));
        }
        let model_params = self
            .params
            .iter()
            .map(|p| &p.name)
            .chain(self.fixed.iter().map(|(n, _)| n));
        for name in model_params {
            if e.params.iter().any(|p| &p.name == name) {
                return Err(PyValueError::new_err(format!(
                    "effect {}: parameter {name:?} is also a parameter of the model, and the effect's f and h get both in one dict; rename it",
                    e.name
                )));
            }
        }
        if let Ok(mut d) = self.declared.lock() {
            d.push(effect);
        }
        Ok(())
    }

    /// Withdraws a declared effect (one whose probe failed).
    fn undeclare(&self, name: &str) {
        if let Ok(mut d) = self.declared.lock() {
            d.retain(|e| e.get().name != name);
        }
    }

    /// The model's parameter dict and the `enabled` effects' terms at `theta` (the model's
    /// parameters, then each enabled effect's in `enabled` order).
    fn at<'py>(
        &self,
        py: Python<'py>,
        enabled: &[String],
        theta: &[f64],
    ) -> PyResult<(Bound<'py, PyDict>, Vec<Extra>)> {
        let effects = self.enabled_effects(enabled).map_err(to_py_err)?;
        let n = self.params.len();
        let want = n + effects.iter().map(|e| e.get().params.len()).sum::<usize>();
        if theta.len() != want {
            return Err(PyValueError::new_err(format!(
                "{}: {} parameter values given, expected {want}",
                self.label(),
                theta.len()
            )));
        }
        let base = self.params_at(py, &theta[..n])?;
        let mut at = n;
        let mut extras = Vec::with_capacity(effects.len());
        for e in effects {
            let e = e.get();
            let params = base.copy()?;
            for p in &e.params {
                params.set_item(&p.name, theta[at])?;
                at += 1;
            }
            extras.push(Extra {
                name: e.name.clone(),
                f: e.f.as_ref().map(|f| f.clone_ref(py)),
                h: e.h.as_ref().map(|h| h.clone_ref(py)),
                params: params.unbind(),
                x_op: e.x_op.clone(),
            });
        }
        Ok((base, extras))
    }

    /// The parameter values `{name: float}` the callables receive, fixed ones included.
    fn params_at<'py>(&self, py: Python<'py>, theta: &[f64]) -> PyResult<Bound<'py, PyDict>> {
        let params = PyDict::new(py);
        for (p, v) in self.params.iter().zip(theta) {
            params.set_item(&p.name, v)?;
        }
        for (name, v) in &self.fixed {
            params.set_item(name, v)?;
        }
        Ok(params)
    }

    fn call(&self, py: Python<'_>, enabled: &[String], theta: &[f64]) -> PyResult<StateSpace> {
        let (params, extras) = self.at(py, enabled, theta)?;
        let matrices = match &self.form {
            Form::Linear(m) => m,
            Form::Nonlinear(c) => return c.linearize(py, &self.label(), &params, &extras),
        };
        let out = matrices.call1(py, (params,))?;
        let out = out.bind(py);
        let parts: Vec<Bound<'_, PyAny>> = out
            .try_iter()
            .and_then(|it| it.collect::<PyResult<Vec<_>>>())
            .map_err(|_| {
                PyTypeError::new_err(format!(
                    "{}: matrices(params) must return (A, B, C, D)",
                    self.label()
                ))
            })?;
        if parts.len() != 4 {
            return Err(PyValueError::new_err(format!(
                "{}: matrices(params) returned {} items, expected (A, B, C, D)",
                self.label(),
                parts.len()
            )));
        }
        let np = py.import("numpy")?;
        let (n, m, p) = (self.states.len(), self.inputs.len(), self.outputs.len());
        let shapes = [(n, n), (n, m), (p, n), (p, m)];
        let mut mats = Vec::with_capacity(4);
        for ((key, part), want) in ["A", "B", "C", "D"].iter().zip(parts).zip(shapes) {
            let array = np.call_method1(
                "atleast_2d",
                (real_array(&part, &format!("{}: {key}", self.label()))?,),
            )?;
            let array: PyReadonlyArray2<f64> = array.extract().map_err(|_| {
                PyValueError::new_err(format!("{}: {key} must be a 2-D array", self.label()))
            })?;
            let a = array.as_array();
            if a.dim() != want {
                return Err(PyValueError::new_err(format!(
                    "{}: {key} has shape {:?}, must be {want:?} ({n} states, {m} inputs, {p} outputs)",
                    self.label(),
                    a.dim()
                )));
            }
            if let Some(((r, c), v)) = a.indexed_iter().find(|(_, v)| !v.is_finite()) {
                return Err(PyValueError::new_err(format!(
                    "{}: {key}[{r}, {c}] = {v} at params {theta:?}",
                    self.label()
                )));
            }
            mats.push(nalgebra::DMatrix::from_fn(want.0, want.1, |i, j| a[(i, j)]));
        }
        let d = mats.pop().unwrap_or_default();
        let c = mats.pop().unwrap_or_default();
        let b = mats.pop().unwrap_or_default();
        let a = mats.pop().unwrap_or_default();
        Ok(StateSpace {
            a,
            b,
            c,
            d,
            delay: 0.0,
        })
    }
}

impl ModelStructure for PyStructure {
    fn system(&self) -> &str {
        &self.name
    }

    fn inputs(&self) -> Vec<String> {
        self.inputs.clone()
    }

    fn outputs(&self) -> Vec<String> {
        self.outputs.clone()
    }

    fn state_names(&self, enabled: &[String]) -> Vec<String> {
        let own = self.enabled_effects(enabled).unwrap_or_default();
        self.states
            .iter()
            .chain(own.iter().flat_map(|e| &e.get().states))
            .cloned()
            .collect()
    }

    fn effects(&self) -> Vec<String> {
        self.declared_effects()
            .iter()
            .map(|e| e.get().name.clone())
            .collect()
    }

    fn describe(&self, effect: &str) -> String {
        self.declared_effects()
            .iter()
            .find(|e| e.get().name == effect)
            .map_or_else(
                || format!("unknown effect {effect}"),
                |e| e.get().description.clone(),
            )
    }

    fn fixed(&self) -> Vec<(String, f64, String)> {
        self.fixed
            .iter()
            .map(|(n, v)| (n.clone(), *v, "fixed in the Python model".into()))
            .collect()
    }

    /// The model's parameters, then each enabled effect's as `<effect>.<parameter>`.
    fn parameters(&self, enabled: &[String]) -> sim::Result<Vec<Parameter>> {
        let mut params = self.params.clone();
        for e in self.enabled_effects(enabled)? {
            let e = e.get();
            params.extend(e.params.iter().map(|p| Parameter {
                name: format!("{}.{}", e.name, p.name),
                ..p.clone()
            }));
        }
        Ok(params)
    }

    fn state_space(&self, enabled: &[String], theta: &[f64]) -> sim::Result<StateSpace> {
        self.error.cancel().check()?;
        Python::attach(|py| self.call(py, enabled, theta)).map_err(|err| self.stash(err))
    }

    fn parallel(&self) -> bool {
        false
    }

    fn is_nonlinear(&self) -> bool {
        matches!(self.form, Form::Nonlinear(_))
    }

    fn dynamics(
        &self,
        enabled: &[String],
        theta: &[f64],
    ) -> Option<sim::Result<Box<dyn Dynamics>>> {
        let Form::Nonlinear(callables) = &self.form else {
            return None;
        };
        Some(
            Python::attach(|py| {
                let (params, extras) = self.at(py, enabled, theta)?;
                Ok(Box::new(PyDynamics {
                    model: self.label(),
                    callables: Arc::clone(callables),
                    params: params.unbind(),
                    extras,
                    error: Arc::clone(&self.error),
                }) as Box<dyn Dynamics>)
            })
            .map_err(|err| self.stash(err)),
        )
    }
}

impl PyStructure {
    /// Keeps the first exception of a user's callable for the caller.
    fn stash(&self, err: PyErr) -> sim::SimError {
        self.error.keep_as(err, self.label(), "Python callable")
    }
}

/// Reads one parameter given as `value`, `(value, min, max)` or
/// `{"value", "min", "max", "unit", "fixed"}`; returns it and whether it is fixed.
fn py_parameter(name: &str, spec: &Bound<'_, PyAny>) -> PyResult<(Parameter, bool)> {
    let bad = || {
        PyTypeError::new_err(format!(
            "parameter {name}: give a number, (value, min, max) or a dict with value, min, max, unit, fixed"
        ))
    };
    let (value, lower, upper, unit, fixed) = if let Ok(Real(v)) = spec.extract::<Real<f64>>() {
        (v, f64::NEG_INFINITY, f64::INFINITY, String::new(), false)
    } else if let Ok(Real((v, lo, hi))) = spec.extract::<Real<(f64, f64, f64)>>() {
        (v, lo, hi, String::new(), false)
    } else if let Ok(d) = spec.cast::<PyDict>() {
        for key in d.keys() {
            let key: String = key.extract().map_err(|_| bad())?;
            if !["value", "min", "max", "unit", "fixed"].contains(&key.as_str()) {
                return Err(PyValueError::new_err(format!(
                    "parameter {name}: unknown field {key:?} (expected value, min, max, unit, fixed)"
                )));
            }
        }
        let num = |k: &str, default: f64| -> PyResult<f64> {
            d.get_item(k)?.map_or(Ok(default), |v| {
                Ok(v.extract::<Real<f64>>().map_err(|_| bad())?.0)
            })
        };
        let value = d
            .get_item("value")?
            .ok_or_else(|| PyValueError::new_err(format!("parameter {name}: missing value")))?
            .extract::<Real<f64>>()
            .map_err(|_| bad())?
            .0;
        let unit = d.get_item("unit")?.map_or(Ok(String::new()), |u| {
            u.extract::<String>().map_err(|_| {
                PyTypeError::new_err(format!("parameter {name}: unit must be a string"))
            })
        })?;
        let fixed = d.get_item("fixed")?.map_or(Ok(false), |f| {
            f.extract::<bool>().map_err(|_| {
                PyTypeError::new_err(format!("parameter {name}: fixed must be True or False"))
            })
        })?;
        (
            value,
            num("min", f64::NEG_INFINITY)?,
            num("max", f64::INFINITY)?,
            unit,
            fixed,
        )
    } else {
        return Err(bad());
    };
    let p = Parameter::new(name, value, lower, upper, unit);
    workbench::model::check_parameters(std::slice::from_ref(&p))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok((p, fixed))
}

/// A model for the workbench: from a model file (`Model.from_file(path)`) or from Python,
/// `Model(states=, inputs=, outputs=, parameters=, matrices=callable, effects=[...], name=)`,
/// where `matrices(params)` returns `(A, B, C, D)` (numpy arrays) of the continuous-time model
/// for the parameter values `{name: float}`, and `effects` are [`Effect`]s that discovery
/// tries next to the generic `actuator_lag`, `input_delay` and, with two to four inputs or
/// outputs, `actuator_lag_<input>`, `actuator_gain_<input>` and `sensor_lag_<output>`. A
/// nonlinear model gives
/// `f=`, `h=` (`f(x, u, params) -> dx`, `h(x, u, params) -> y`) and `operating_point=`
/// (`{name: value}` for every state and input) instead of `matrices`.
#[pyclass(name = "Model", module = "stabilis._stabilis.workbench", frozen)]
#[derive(Debug)]
struct Model {
    structure: Arc<dyn ModelStructure>,
    /// A Python model, of which every workbench gets its own copy (named after the logs'
    /// topics when the model has no name), so that effects declared on one workbench stay
    /// there.
    python: Option<PyStructure>,
    /// Matrix-form effects, offered to discovery.
    effects: Vec<Py<Effect>>,
    error: Arc<Raised>,
}

#[pymethods]
impl Model {
    #[new]
    #[pyo3(signature = (states, inputs, outputs, parameters, matrices = None, effects = None, name = None, f = None, h = None, operating_point = None))]
    #[allow(clippy::too_many_arguments)]
    fn new<'py>(
        py: Python<'py>,
        states: &Bound<'_, PyAny>,
        inputs: &Bound<'_, PyAny>,
        outputs: &Bound<'_, PyAny>,
        parameters: &Bound<'py, PyAny>,
        matrices: Option<Py<PyAny>>,
        effects: Option<&Bound<'py, PyAny>>,
        name: Option<String>,
        f: Option<Py<PyAny>>,
        h: Option<Py<PyAny>>,
        operating_point: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Self> {
        // Without a name the system is read from the logs' topics when the workbench loads them.
        let name = name.unwrap_or_default();
        let name = name.as_str();
        let this = model_label(name);
        let names = |what: &str, list: &Bound<'_, PyAny>| -> PyResult<Vec<String>> {
            list.extract::<Vec<String>>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "{this}: {what} must be a list of names (str), e.g. [\"x\"]; got {}",
                    type_name(list)
                ))
            })
        };
        let dict = |what: &str, d: &Bound<'py, PyAny>, expected: &str| {
            d.cast::<PyDict>().cloned().map_err(|_| {
                PyTypeError::new_err(format!(
                    "{this}: {what} must be a dict {{name: {expected}}}; got {}",
                    type_name(d)
                ))
            })
        };
        let (states, inputs, outputs) = (
            names("states", states)?,
            names("inputs", inputs)?,
            names("outputs", outputs)?,
        );
        let parameters = &dict("parameters", parameters, "value, (value, min, max) or dict")?;
        let operating_point = operating_point
            .map(|p| dict("operating_point", p, "value"))
            .transpose()?;
        for (what, list) in [
            ("states", &states),
            ("inputs", &inputs),
            ("outputs", &outputs),
        ] {
            if list.is_empty() {
                return Err(PyValueError::new_err(format!(
                    "{this}: {what} must name at least one"
                )));
            }
            if let Some((i, n)) = list
                .iter()
                .enumerate()
                .find(|(i, n)| list[..*i].contains(n))
            {
                return Err(PyValueError::new_err(format!(
                    "{this}: {what}[{i}] {n:?} is named twice"
                )));
            }
        }
        let form = match (matrices, f, h) {
            (Some(m), None, None) => {
                if !m.bind(py).is_callable() {
                    return Err(PyTypeError::new_err(format!(
                        "{this}: matrices must be callable"
                    )));
                }
                if operating_point.is_some() {
                    return Err(PyValueError::new_err(format!(
                        "{this}: operating_point belongs to a nonlinear model (f=, h=)"
                    )));
                }
                Form::Linear(m)
            }
            (None, Some(f), Some(h)) => {
                for (label, c) in [("f", &f), ("h", &h)] {
                    if !c.bind(py).is_callable() {
                        return Err(PyTypeError::new_err(format!(
                            "{this}: {label} must be callable"
                        )));
                    }
                }
                let point = operating_point.ok_or_else(|| {
                    PyValueError::new_err(format!(
                        "{this}: a nonlinear model needs operating_point={{name: value}} for every state and input"
                    ))
                })?;
                let value_of = |n: &String| -> PyResult<f64> {
                    let v = point.get_item(n)?.ok_or_else(|| {
                        PyValueError::new_err(format!("{this}: operating_point is missing {n:?}"))
                    })?;
                    let Real(v) = v.extract::<Real<f64>>().map_err(|_| {
                        PyTypeError::new_err(format!(
                            "{this}: operating_point[{n:?}] must be a number"
                        ))
                    })?;
                    if v.is_finite() {
                        Ok(v)
                    } else {
                        Err(PyValueError::new_err(format!(
                            "{this}: operating_point[{n:?}] = {v} must be finite"
                        )))
                    }
                };
                for key in point.keys() {
                    let key: String = key.extract()?;
                    if !states.contains(&key) && !inputs.contains(&key) {
                        return Err(PyValueError::new_err(format!(
                            "{this}: operating_point names {key:?}, which is neither a state nor an input"
                        )));
                    }
                }
                Form::Nonlinear(Arc::new(Callables {
                    f,
                    h,
                    x_op: states.iter().map(value_of).collect::<PyResult<_>>()?,
                    u_op: inputs.iter().map(value_of).collect::<PyResult<_>>()?,
                    outputs: outputs.len(),
                }))
            }
            _ => {
                return Err(PyTypeError::new_err(format!(
                    "{this}: give matrices= (a linear model) or both f= and h= (a nonlinear one)"
                )))
            }
        };
        let mut params = Vec::new();
        let mut fixed = Vec::new();
        for (k, v) in parameters.iter() {
            let pname: String = k.extract()?;
            let (p, is_fixed) = py_parameter(&pname, &v)?;
            if is_fixed {
                fixed.push((p.name, p.value));
            } else {
                params.push(p);
            }
        }
        workbench::model::check_parameters(&params).map_err(to_py_err)?;
        let error = Arc::new(Raised::default());
        let structure = PyStructure {
            name: name.to_string(),
            states,
            inputs,
            outputs,
            params,
            fixed,
            form,
            declared: Mutex::new(Vec::new()),
            error: Arc::clone(&error),
        };
        let theta: Vec<f64> = structure.params.iter().map(|p| p.value).collect();
        structure.call(py, &[], &theta)?;
        // Effects in nonlinear form become the model's declared effects, each evaluated once
        // at its documented values so that a broken callable fails here.
        let mut matrix_form = Vec::new();
        let effects = effects
            .map(|e| e.extract::<Vec<Py<Effect>>>())
            .transpose()
            .map_err(|_| {
                PyTypeError::new_err(format!("{this}: effects must be a list of stabilis.Effect"))
            })?;
        for e in effects.unwrap_or_default() {
            if !e.get().nonlinear() {
                matrix_form.push(e);
                continue;
            }
            let name = e.get().name.clone();
            let mut theta = theta.clone();
            theta.extend(e.get().params.iter().map(|p| p.value));
            structure.declare(Arc::new(e), &[])?;
            structure.call(py, std::slice::from_ref(&name), &theta)?;
        }
        let python = Some(structure.named(py, name.to_string(), Arc::clone(&error)));
        Ok(Self {
            structure: Arc::new(structure),
            python,
            effects: matrix_form,
            error,
        })
    }

    /// Reads a model file (TOML; README "Your own system"). `stabilis.ModelError` when the
    /// file is missing, unreadable or malformed.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let file = py
            .detach(|| ModelFile::from_path(&path))
            .map_err(|e| match e {
                // Not a log: the model file itself is what is missing or unreadable.
                sim::SimError::FileNotFound { path } => {
                    ModelError::new_err(format!("model file not found: {}", path.display()))
                }
                sim::SimError::Io { path, source } => ModelError::new_err(format!(
                    "cannot read model file {}: {source}",
                    path.display()
                )),
                other => to_py_err(other),
            })?;
        Ok(Self {
            structure: Arc::new(file),
            python: None,
            effects: Vec::new(),
            error: Arc::new(Raised::default()),
        })
    }

    /// The system name (MCAP topics `/<name>/input`, ...).
    #[getter]
    fn name(&self) -> &str {
        self.structure.system()
    }

    /// Input names.
    #[getter]
    fn inputs(&self) -> Vec<String> {
        self.structure.inputs()
    }

    /// Output names.
    #[getter]
    fn outputs(&self) -> Vec<String> {
        self.structure.outputs()
    }

    /// The matrices at the documented values: `{"A", "B", "C", "D"}` as numpy arrays.
    fn matrices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = Arc::clone(&self.structure);
        let ss = run_with(&self.error, self.python.is_some(), py, move || {
            let theta: Vec<f64> = s.parameters(&[])?.iter().map(|p| p.value).collect();
            s.state_space(&[], &theta)
        })?;
        let out = PyDict::new(py);
        for (k, m) in [("A", &ss.a), ("B", &ss.b), ("C", &ss.c), ("D", &ss.d)] {
            let a = Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]);
            out.set_item(k, a.into_pyarray(py))?;
        }
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "Model({:?}, inputs={:?}, outputs={:?})",
            self.structure.system(),
            self.structure.inputs(),
            self.structure.outputs()
        )
    }
}

/// Experiments given as arrays: each a dict with `u` (samples x inputs), `y` (samples x
/// outputs) and optionally `r` (the logged excitation, shaped like `u`); periods are detected
/// from `r` as for logs without period metadata.
fn dataset_from_arrays(
    structure: &dyn ModelStructure,
    experiments: &[Bound<'_, PyDict>],
    sample_rate_hz: f64,
) -> PyResult<Dataset> {
    if experiments.is_empty() {
        return Err(PyValueError::new_err("data: give at least one experiment"));
    }
    let mut out = Vec::with_capacity(experiments.len());
    for (i, e) in experiments.iter().enumerate() {
        // A misspelt key would silently drop what it holds (an excitation lost changes the
        // estimator).
        for key in e.keys() {
            let name = key.str()?.to_string();
            if !["u", "y", "r"].contains(&name.as_str()) {
                return Err(PyValueError::new_err(format!(
                    "data[{i}] has the key {key}; an experiment holds \"u\" (inputs), \"y\" (outputs) and optionally \"r\" (the logged excitation)",
                    key = key.repr()?
                )));
            }
        }
        let get = |key: &str, cols: usize| -> PyResult<Option<nalgebra::DMatrix<f64>>> {
            let Some(v) = e.get_item(key)? else {
                return Ok(None);
            };
            let arr = real_array(&v, &format!("data[{i}][{key:?}]"))?.into_any();
            let arr = if arr.getattr("ndim")?.extract::<usize>()? == 1 {
                arr.call_method1("reshape", ((-1i64, 1i64),))?
            } else {
                arr
            };
            let arr: PyReadonlyArray2<f64> = arr.extract().map_err(|_| {
                PyValueError::new_err(format!("data[{i}][{key:?}] must be a 1-D or 2-D array"))
            })?;
            let a = arr.as_array();
            if a.ncols() != cols {
                return Err(PyValueError::new_err(format!(
                    "data[{i}][{key:?}] has {} columns; the model has {cols}",
                    a.ncols()
                )));
            }
            Ok(Some(nalgebra::DMatrix::from_fn(a.nrows(), cols, |r, c| {
                a[(r, c)]
            })))
        };
        let (m, p) = (structure.inputs().len(), structure.outputs().len());
        let u =
            get("u", m)?.ok_or_else(|| PyValueError::new_err(format!("data[{i}] needs \"u\"")))?;
        let y =
            get("y", p)?.ok_or_else(|| PyValueError::new_err(format!("data[{i}] needs \"y\"")))?;
        let r = get("r", m)?;
        let periodic = r.as_ref().and_then(detect_period);
        out.push(Experiment {
            // As the messages above name it, so that a row in a later message (0-based)
            // reads as numpy indexes it.
            name: format!("data[{i}]"),
            u,
            y,
            r,
            periodic,
        });
    }
    let data = Dataset {
        sample_rate_hz,
        inputs: structure.inputs(),
        outputs: structure.outputs(),
        experiments: out,
    };
    data.validate().map_err(to_py_err)?;
    Ok(data)
}

/// The criterion a Python caller names: `"frf"`, `"time"` or `None` (the model's default).
pub(crate) fn criterion_of(name: Option<&str>) -> PyResult<Option<workbench::Criterion>> {
    match name {
        None => Ok(None),
        Some("frf") => Ok(Some(workbench::Criterion::Frf)),
        Some("time") => Ok(Some(workbench::Criterion::Time)),
        Some(other) => Err(PyValueError::new_err(format!(
            "unknown criterion {other:?}; use \"frf\" or \"time\" (default: time for a nonlinear model)"
        ))),
    }
}

/// `ValueError` when the `sample_rate_hz` given in Python contradicts the rate the data carry
/// (logs and the embedded dataset have their own; a matching value is accepted).
fn check_rate(given: Option<f64>, data_hz: f64) -> PyResult<()> {
    match given {
        Some(fs) if fs.is_nan() || (fs - data_hz).abs() > 1e-6 * data_hz.abs() => {
            let data_hz = workbench::load::hz(data_hz);
            Err(PyValueError::new_err(format!(
                "sample_rate_hz={fs} contradicts the data, which were recorded at {data_hz} Hz; \
                 omit sample_rate_hz (it is needed only for data given as arrays) or give {data_hz}"
            )))
        }
        _ => Ok(()),
    }
}

/// What a workbench works on.
enum Inner {
    /// Any model (a model file, a Python model, the flying platform) under the FRF or the
    /// time-domain criterion.
    Frf {
        wb: Box<workbench::Workbench>,
        last: Option<Discovery>,
    },
    /// The Cubli's own time-domain prediction error (`system="cubli"`).
    Cubli {
        bench: Box<CubliBench>,
        last: Option<CubliDiscovery>,
    },
}

/// Workbench on one system's measurements. `model` is a `stabilis.Model` or the path of a
/// model file; without it, `system` names a shipped one ("flying_platform", whose embedded
/// dataset is used when `data` is None, or "cubli", which needs logs). `data` is a list of log
/// paths (MCAP or CSV) or of dicts `{"u", "y", "r"}` of arrays (samples in rows, `r` the
/// logged excitation, optional). `criterion` is "frf" (the linearization against the measured
/// FRF) or "time" (the nonlinear model's prediction error); the default is "time" for a
/// nonlinear model and "frf" otherwise. `estimator` is the FRF estimator: "auto", "ls" or
/// "iv". `sample_rate_hz` is required for data given as arrays; logs carry their own rate, and
/// a different `sample_rate_hz` is a `ValueError`.
#[pyclass(name = "Workbench", module = "stabilis._stabilis.workbench")]
struct Workbench {
    inner: Inner,
    /// This workbench's copy of a Python model, to which `suspect` and `add` declare effects
    /// in nonlinear form.
    python: Option<Arc<PyStructure>>,
    /// First Python exception raised by a user effect during the running call; its
    /// [`Cancel`] stops the running call.
    error: Arc<Raised>,
    /// Whether a run calls Python: a Python model, or an effect given as a callable.
    calls_python: bool,
}

/// Why the Cubli workbench takes no Python effect.
const CUBLI_USER_EFFECT: &str =
    "user-defined effects edit a state-space model; the cubli workbench fits its named candidates only";

/// `ValueError` naming a matrix-form effect when `wb` fits in the time domain: that
/// criterion integrates the nonlinear model, which a matrix-form effect (terms added to A, B,
/// C, D) does not describe, so discovery could not try it.
fn refuse_matrix_form(wb: &workbench::Workbench, name: &str, python: bool) -> PyResult<()> {
    if wb.criterion() != workbench::Criterion::Time {
        return Ok(());
    }
    let instead = if python {
        "give it as Effect(name, params, f=..., h=...), whose f(x, u, params) and \
         h(x, u, params) return the terms added to the model's f and h"
    } else {
        "declare it in the model file's [effects]"
    };
    Err(PyValueError::new_err(format!(
        "effect {name}: its callable returns terms added to the matrices A, B, C, D, which \
         describe a linear model; the {} model is nonlinear and fitted in the time domain, \
         where such an effect cannot be tried: {instead}, or use criterion=\"frf\" (the \
         model's linearization, to which the matrix terms are added)",
        wb.model().structure().system()
    )))
}

impl Workbench {
    /// The user's effect for this workbench, evaluated once at its documented values on top
    /// of the current model, so that a broken callable fails when it is given, not in a fit.
    fn checked_effect(&self, py: Python<'_>, user: Bound<'_, Effect>) -> PyResult<Arc<PyEffect>> {
        let Inner::Frf { wb, .. } = &self.inner else {
            return Err(PyValueError::new_err(CUBLI_USER_EFFECT));
        };
        refuse_matrix_form(wb, &user.get().name, self.python.is_some())?;
        let effect = Arc::new(PyEffect {
            effect: user.unbind(),
            error: Arc::clone(&self.error),
        });
        let probe = wb
            .model()
            .with_user_effect(effect.clone())
            .map_err(to_py_err)?;
        self.run(py, || probe.state_space(&probe.documented()?).map(|_| ()))?;
        Ok(effect)
    }

    /// Declares an effect in nonlinear form on this workbench's copy of a nonlinear Python
    /// model, evaluates it once at its documented values (a broken callable fails now and is
    /// withdrawn) and, with `enable`, enables it.
    fn declare(&mut self, py: Python<'_>, user: Bound<'_, Effect>, enable: bool) -> PyResult<()> {
        let name = user.get().name.clone();
        let Inner::Frf { wb, .. } = &mut self.inner else {
            return Err(PyValueError::new_err(CUBLI_USER_EFFECT));
        };
        let Some(own) = self.python.as_ref().filter(|s| s.is_nonlinear()) else {
            return Err(PyValueError::new_err(format!(
                "effect {name}: f=/h= add terms to the equations of a nonlinear Python model (Model(f=, h=)); the {} model is {}: {}",
                wb.model().structure().system(),
                if self.python.is_some() { "a linear Python model (matrices=)" } else { "not a Python model" },
                if self.python.is_some() || !wb.model().structure().is_nonlinear() {
                    "give the effect as Effect(name, params, func) returning terms added to A, B, C, D"
                } else {
                    "declare the effect in the model file's [effects]"
                }
            )));
        };
        // An enabled effect cannot be replaced; a generic or offered one of the same name can.
        own.declare(Arc::new(user.unbind()), &wb.model().enabled())?;
        let probe = wb.model().with_effect(&name).map_err(to_py_err);
        let checked = probe.and_then(|probe| {
            run_with(&self.error, true, py, || {
                probe.state_space(&probe.documented()?).map(|_| ())
            })
        });
        if let Err(err) = checked {
            own.undeclare(&name);
            return Err(err);
        }
        if enable {
            wb.add(&name).map_err(to_py_err)?;
        }
        Ok(())
    }

    /// [`run_with`] on this workbench's error slot.
    fn run<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce() -> sim::Result<T> + Send,
    ) -> PyResult<T> {
        run_with(&self.error, self.calls_python, py, f)
    }
}

/// Runs `f` without the GIL, stopped by Ctrl-C or by a user's exception ([`interruptible`]);
/// an exception a user's callable raised during the run (a model's `f`/`h`, an effect's) is
/// re-raised unchanged, whether or not the run failed (kept in `error`).
fn run_with<T: Send>(
    error: &Raised,
    calls_python: bool,
    py: Python<'_>,
    f: impl FnOnce() -> sim::Result<T> + Send,
) -> PyResult<T> {
    error.take();
    let result = interruptible(py, error.cancel(), calls_python, f);
    // A user's exception reaches the caller even when the run went on without it: a fit
    // takes a failed evaluation for a step too far and backs off, which turned an effect
    // that raised (or returned NaN) beyond some value into a plausible misfit verdict.
    match (result, error.take()) {
        (Err(interrupt), _) => Err(interrupt),
        (_, Some(err)) => Err(err),
        (Ok(Ok(v)), None) => Ok(v),
        (Ok(Err(e)), None) => Err(to_py_err(e)),
    }
}

impl Workbench {
    /// Runs `discover` (or the one-step `fit`), keeps the result for `report` and returns its
    /// JSON.
    fn keep(&mut self, py: Python<'_>, discover: bool) -> PyResult<serde_json::Value> {
        let (error, calls_python) = (&self.error, self.calls_python);
        Ok(match &mut self.inner {
            Inner::Frf { wb, last } => {
                let d = run_with(error, calls_python, py, || {
                    if discover {
                        wb.discover()
                    } else {
                        wb.compared()
                    }
                })?;
                let value = json(wb, &d);
                *last = Some(d);
                value
            }
            Inner::Cubli { bench, last } => {
                let d = run_with(error, calls_python, py, || {
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
    #[pyo3(signature = (system = "flying_platform", data = None, estimator = "auto", model = None, sample_rate_hz = None, criterion = None))]
    fn new(
        py: Python<'_>,
        system: &str,
        data: Option<&Bound<'_, PyAny>>,
        estimator: &str,
        model: Option<&Bound<'_, PyAny>>,
        sample_rate_hz: Option<Real<f64>>,
        criterion: Option<&str>,
    ) -> PyResult<Self> {
        let sample_rate_hz = sample_rate_hz.map(|fs| fs.0);
        let criterion = criterion_of(criterion)?;
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
        // This workbench's own slot, shared with its copy of a Python model and its effects:
        // a run of another workbench of the same model neither cancels this one's nor takes
        // its exception.
        let error = Arc::new(Raised::default());
        // `model` is a stabilis.Model or the path of a model file.
        let mut python = None;
        let (source, effects) = match model {
            None => (systems::shipped(system).map_err(to_py_err)?, Vec::new()),
            Some(m) => {
                let m: Py<Model> = match m.cast::<Model>() {
                    Ok(m) => m.clone().unbind(),
                    Err(_) => {
                        let path: PathBuf = m.extract().map_err(|_| {
                            PyTypeError::new_err(
                                "model must be a stabilis.Model or a model-file path",
                            )
                        })?;
                        Py::new(py, Model::from_file(py, path)?)?
                    }
                };
                let m = m.get();
                let effects: Vec<Py<Effect>> = m.effects.iter().map(|e| e.clone_ref(py)).collect();
                let logs = data.and_then(|d| d.extract::<Vec<PathBuf>>().ok());
                let structure: Arc<dyn ModelStructure> = match (&m.python, logs) {
                    (Some(own), logs) => {
                        let name = match logs {
                            Some(paths) if own.name.is_empty() => {
                                py.detach(|| load::system_of(&paths)).map_err(to_py_err)?
                            }
                            _ => own.name.clone(),
                        };
                        let own = Arc::new(own.named(py, name, Arc::clone(&error)));
                        python = Some(Arc::clone(&own));
                        own
                    }
                    (None, _) => Arc::clone(&m.structure),
                };
                (Source::Structure(structure), effects)
            }
        };
        let calls_python = python.is_some() || !effects.is_empty();
        let paths: Option<Vec<PathBuf>> = match data {
            None => None,
            Some(d) => d.extract::<Vec<PathBuf>>().ok(),
        };
        let arrays: Option<Vec<Bound<'_, PyDict>>> = match (data, &paths) {
            (Some(d), None) => Some(d.extract::<Vec<Bound<'_, PyDict>>>().map_err(|_| {
                PyTypeError::new_err(
                    "data must be a list of log paths or of dicts {\"u\", \"y\", \"r\"} of arrays",
                )
            })?),
            _ => None,
        };
        let inner = match source {
            Source::Structure(structure) => {
                let dataset = match (&paths, &arrays) {
                    (_, Some(experiments)) => {
                        let fs = sample_rate_hz.ok_or_else(|| {
                            PyValueError::new_err("data given as arrays needs sample_rate_hz=")
                        })?;
                        Some(dataset_from_arrays(structure.as_ref(), experiments, fs)?)
                    }
                    _ => None,
                };
                let s = Arc::clone(&structure);
                let shipped_default = model.is_none() && system == "flying_platform";
                let dataset = match dataset {
                    Some(d) => d,
                    None => run_with(&error, calls_python, py, || match &paths {
                        Some(p) => load::load(s.system(), &s.inputs(), &s.outputs(), p),
                        None if shipped_default => embedded_dataset(),
                        None => Err(sim::SimError::invalid(
                            "data",
                            "None",
                            format!("{} needs measurements: data=[paths] or arrays", s.system()),
                        )),
                    })?,
                };
                check_rate(sample_rate_hz, dataset.sample_rate_hz)?;
                let mut wb = run_with(&error, calls_python, py, move || {
                    workbench::Workbench::with_options(
                        s,
                        dataset,
                        choice,
                        workbench::DataOptions {
                            criterion,
                            ..Default::default()
                        },
                    )
                })?;
                for e in effects {
                    refuse_matrix_form(&wb, &e.get().name, python.is_some())?;
                    wb.offer(Arc::new(PyEffect {
                        effect: e,
                        error: Arc::clone(&error),
                    }))
                    .map_err(to_py_err)?;
                }
                wb.set_cancel(error.cancel().clone());
                Inner::Frf {
                    wb: Box::new(wb),
                    last: None,
                }
            }
            Source::Cubli => {
                let paths = paths.ok_or_else(|| {
                    PyValueError::new_err(
                        "the cubli workbench needs logs: data=[run1.mcap, run2.mcap, ...]",
                    )
                })?;
                let data = py.detach(|| load_cubli(&paths)).map_err(to_py_err)?;
                check_rate(sample_rate_hz, data.sample_rate_hz)?;
                let bench = py
                    .detach(|| CubliBench::new(&data, &CubliOptions::default()))
                    .map_err(to_py_err)?;
                Inner::Cubli {
                    bench: Box::new(bench),
                    last: None,
                }
            }
        };
        Ok(Self {
            inner,
            calls_python,
            python,
            error,
        })
    }

    /// The system name.
    #[getter]
    fn system(&self) -> String {
        match &self.inner {
            Inner::Frf { wb, .. } => wb.model().structure().system().to_string(),
            Inner::Cubli { .. } => "cubli".to_string(),
        }
    }

    /// Offers an effect to `discover()` as a candidate, next to the declared and generic ones
    /// (it is not enabled): a [`Effect`], or a callable with `params=` as for `add`.
    #[pyo3(signature = (effect, params = None, bounds = None, units = None, name = None))]
    fn suspect(
        &mut self,
        py: Python<'_>,
        effect: &Bound<'_, PyAny>,
        params: Option<&Bound<'_, PyAny>>,
        bounds: Option<&Bound<'_, PyAny>>,
        units: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<()> {
        let user = user_effect(py, effect, params, bounds, units, name)?;
        self.calls_python = true;
        if user.get().nonlinear() {
            return self.declare(py, user, false);
        }
        let effect = self.checked_effect(py, user)?;
        match &mut self.inner {
            Inner::Frf { wb, .. } => wb.offer(effect).map_err(to_py_err),
            Inner::Cubli { .. } => Err(PyValueError::new_err(CUBLI_USER_EFFECT)),
        }
    }

    /// Fits the current model: a dict with `steps` (one), `found` (empty), `unexplained`.
    fn compare<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let value = match &self.inner {
            Inner::Frf { wb, .. } => {
                let d = self.run(py, || wb.compared())?;
                json(wb, &d)
            }
            Inner::Cubli { bench, .. } => self.run(py, || bench.fit())?.json(),
        };
        to_dict(py, &value)
    }

    /// Where the current model fails, as a dict: the current model fitted to the measured FRF
    /// (for a nonlinear model, its linearization at the operating point, whatever the
    /// criterion), with its misfit per line, per output and per FRF entry against the noise
    /// level (`lines`, `outputs`, `worst_entries`), `time_fit` (fit % of the simulation and
    /// the k-step prediction) and `residual_tests` (whiteness and input correlation of the
    /// simulation residual). The Cubli's workbench (`system="cubli"`) gives per residual
    /// channel the RMS over the noise level and the probe test (`channels`) with its verdict.
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
                    "unexplained": d.conclusion.unexplained,
                    "verdict": checked(serde_json::to_value(&d.conclusion.verdict))?,
                    "verdict_text": d.verdict_sentence(),
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

    /// Enables an effect: the name of one the model knows (those declared in its model file's
    /// `[effects]` or given to `stabilis.Model`, the generic `sensor_bias`, `input_bias`, `actuator_lag`,
    /// `input_delay`, `actuator_lag_<input>`, `actuator_gain_<input>` and `sensor_lag_<output>`,
    /// or a shipped system's
    /// own; an unknown name raises
    /// `stabilis.SimError` listing the known ones), or a `stabilis.Effect`, which is
    /// evaluated once at its documented values to catch errors now: in matrix form
    /// (`func(params, model)`) for a linear model or under the FRF criterion, in nonlinear
    /// form (`f=`, `h=`) for a nonlinear Python model. The Cubli's workbench takes names only.
    ///
    /// A bare callable is wrapped as `Effect(name or func.__name__, params, func, bounds,
    /// units)`.
    #[pyo3(signature = (effect, params = None, bounds = None, units = None, name = None))]
    fn add(
        &mut self,
        py: Python<'_>,
        effect: &Bound<'_, PyAny>,
        params: Option<&Bound<'_, PyAny>>,
        bounds: Option<&Bound<'_, PyAny>>,
        units: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<()> {
        if let Ok(name) = effect.extract::<String>() {
            if params.is_some() || bounds.is_some() || units.is_some() {
                return Err(PyTypeError::new_err(
                    "params, bounds, units and name go with a callable, not with an effect name",
                ));
            }
            return match &mut self.inner {
                Inner::Frf { wb, .. } => wb.add(&name),
                Inner::Cubli { bench, .. } => bench.add(&name),
            }
            .map_err(to_py_err);
        }
        let user = user_effect(py, effect, params, bounds, units, name)?;
        self.calls_python = true;
        if user.get().nonlinear() {
            return self.declare(py, user, true);
        }
        let effect = self.checked_effect(py, user)?;
        match &mut self.inner {
            Inner::Frf { wb, .. } => wb.add_user_effect(effect).map_err(to_py_err),
            Inner::Cubli { .. } => Err(PyValueError::new_err(CUBLI_USER_EFFECT)),
        }
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

    /// The measured FRF as a dict: `freqs_hz` (float array, one frequency per line), `G`
    /// (complex array of shape (lines, outputs, inputs)), `std` (float array of `G`'s shape:
    /// the standard deviation of each entry), `inputs` and `outputs` (channel names, in the
    /// order of `G`'s axes) and `estimator` (`"LeastSquares"`, `"InstrumentalVariable"`,
    /// `"H1Welch"` or `"H1WelchInstrumental"`).
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

/// A [`Effect`] from what `add`/`suspect` were given: an Effect, or a callable with `params`.
fn user_effect<'py>(
    py: Python<'py>,
    effect: &Bound<'py, PyAny>,
    params: Option<&Bound<'py, PyAny>>,
    bounds: Option<&Bound<'py, PyAny>>,
    units: Option<&Bound<'py, PyAny>>,
    name: Option<String>,
) -> PyResult<Bound<'py, Effect>> {
    let extras = params.is_some() || bounds.is_some() || units.is_some() || name.is_some();
    if let Ok(user) = effect.cast::<Effect>() {
        if extras {
            return Err(PyTypeError::new_err(
                "params, bounds, units and name go with a callable, not with a stabilis.Effect",
            ));
        }
        return Ok(user.clone());
    }
    if !effect.is_callable() {
        return Err(PyTypeError::new_err(
            "give an effect name, a stabilis.Effect or a callable with params",
        ));
    }
    let params = params.ok_or_else(|| {
        PyTypeError::new_err("a callable effect needs params={name: documented value}")
    })?;
    let name = match name {
        Some(n) => n,
        None => effect.getattr("__name__")?.extract()?,
    };
    let built = Effect::new(
        py,
        name,
        params,
        Some(effect.clone().unbind()),
        bounds,
        units,
        "",
        None,
        None,
        None,
        None,
    )?;
    Bound::new(py, built)
}

/// How messages name a model: "model <name>", or "model" before it has one (a Python model
/// without `name=` is named after the logs' topics when a workbench loads them).
fn model_label(name: &str) -> String {
    if name.is_empty() {
        "model".into()
    } else {
        format!("model {name}")
    }
}

/// The Python type name of `obj` (`str`, `float`), for a type error that says what it got.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "?".to_string(), |n| n.to_string())
}

/// Adds the `workbench` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let module = PyModule::new(parent.py(), "workbench")?;
    module.add_class::<Workbench>()?;
    module.add_class::<Effect>()?;
    module.add_class::<Model>()?;
    parent.add_submodule(&module)
}
