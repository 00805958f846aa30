//! Python bindings of the model workbench: `stabilis.Workbench(system, data)` with
//! `compare`, `diagnose`, `discover`, `add`, `fit`, `report` and the measured FRF as numpy.
use std::path::PathBuf;
use std::sync::Arc;

use numpy::ndarray::Array3;
use numpy::{Complex64, IntoPyArray, PyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use sim::workbench::flying_platform::{embedded_dataset, FlyingPlatform};
use sim::workbench::report::{json, write_report};
use sim::workbench::{load, Discovery, EstimatorChoice, ModelStructure};

use crate::errors::to_py_err;

/// Workbench on one system's measurements (the embedded dataset when `data` is None).
#[pyclass(name = "Workbench", module = "stabilis._stabilis.workbench")]
struct Workbench {
    inner: sim::workbench::Workbench,
    last: Option<Discovery>,
}

fn to_dict<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?
        .call_method1("loads", (value.to_string(),))
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
        let structure: Arc<dyn ModelStructure> = match system {
            "flying_platform" => Arc::new(FlyingPlatform::default()),
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown system {other:?}; the workbench knows: flying_platform"
                )))
            }
        };
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
        let inner = py
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
        Ok(Self { inner, last: None })
    }

    /// Fits the current model: a dict with `steps` (one), `found` (empty), `unexplained`.
    fn compare<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = py
            .detach(|| self.inner.compare().map(|s| self.inner.record(s)))
            .map_err(to_py_err)?;
        to_dict(py, &json(&self.inner, &d))
    }

    /// Where the current model fails: misfit per line and output against the noise level,
    /// time-domain fit % and the residual whiteness / input-correlation tests.
    fn diagnose<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let step = py.detach(|| self.inner.compare()).map_err(to_py_err)?;
        let mut value = serde_json::to_value(&step.diagnosis)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        for (key, part) in [
            ("time_fit", serde_json::to_value(&step.time_fit)),
            ("residual_tests", serde_json::to_value(&step.residual_tests)),
        ] {
            let part = part.map_err(|e| PyValueError::new_err(e.to_string()))?;
            if let Some(map) = value.as_object_mut() {
                map.insert(key.to_string(), part);
            }
        }
        to_dict(py, &value)
    }

    /// Runs the discovery loop: `{"steps": [...], "found": [...], "unexplained": bool, ...}`.
    fn discover<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = py.detach(|| self.inner.discover()).map_err(to_py_err)?;
        let value = json(&self.inner, &d);
        self.last = Some(d);
        to_dict(py, &value)
    }

    /// Enables an effect by name (`momentum_drag`, `fan_gyroscopic`, `actuator_lag`, `input_delay`).
    fn add(&mut self, effect: &str) -> PyResult<()> {
        self.inner.add(effect).map_err(to_py_err)
    }

    /// Fits all parameters of the current model (same record as `compare`).
    fn fit<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = py
            .detach(|| self.inner.compare().map(|s| self.inner.record(s)))
            .map_err(to_py_err)?;
        let value = json(&self.inner, &d);
        self.last = Some(d);
        to_dict(py, &value)
    }

    /// Writes the HTML report of the last `discover` or `fit` (running `discover` if neither ran).
    fn report(&mut self, py: Python<'_>, dir: PathBuf) -> PyResult<()> {
        if self.last.is_none() {
            self.last = Some(py.detach(|| self.inner.discover()).map_err(to_py_err)?);
        }
        match &self.last {
            Some(d) => py
                .detach(|| write_report(&dir, &self.inner, d))
                .map_err(to_py_err),
            None => Err(PyValueError::new_err("nothing to report")),
        }
    }

    /// The measured FRF: `(freqs_hz, G, std)` with `G` complex of shape (lines, outputs, inputs).
    fn frf<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let frf = self.inner.frf();
        let (n, ny, nu) = (frf.lines.len(), frf.ny(), frf.nu());
        let g = Array3::from_shape_fn((n, ny, nu), |(k, i, j)| {
            let z = frf.lines[k].g[(i, j)];
            Complex64::new(z.re, z.im)
        });
        let std = Array3::from_shape_fn((n, ny, nu), |(k, i, j)| self.inner.cost().std[k][(i, j)]);
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
    parent.add_submodule(&module)
}
