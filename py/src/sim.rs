//! Python binding of the scenario runner: the same registry and defaults as
//! `stabilis sim <system>`, returning numpy arrays.
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use sim::cli::SimSystem;

use crate::errors::to_py_err;
use crate::log::tables_to_py;

/// Runs `system` with command-line style options (`["--duration", "5", ...]`); returns
/// `(topics, experiment, summary_json, out)`.
#[pyfunction]
fn run<'py>(py: Python<'py>, system: &str, args: Vec<String>) -> PyResult<Bound<'py, PyTuple>> {
    let parsed = SimSystem::parse_args(system, args).map_err(to_py_err)?;
    let recording = py
        .detach(|| sim::scenarios::run(parsed.scenario(), &mut sim::progress::Progress::hidden()))
        .map_err(to_py_err)?;
    let experiment = PyDict::new(py);
    for (key, value) in &recording.experiment {
        experiment.set_item(key, value)?;
    }
    let summary = serde_json::Value::Object(recording.summary).to_string();
    let out = recording.out.map(|p| p.display().to_string());
    PyTuple::new(
        py,
        [
            tables_to_py(py, &recording.topics)?.into_any(),
            experiment.into_any(),
            summary.into_pyobject(py)?.into_any(),
            out.into_pyobject(py)?.into_any(),
        ],
    )
}

/// Adds the `sim` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let module = PyModule::new(parent.py(), "sim")?;
    module.add_function(wrap_pyfunction!(run, &module)?)?;
    parent.add_submodule(&module)
}
