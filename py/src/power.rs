//! Python binding of the power study ([`workbench::power`]): prepare a study as JSON text,
//! run batches of its campaigns with the GIL released (one Dask task is one batch), aggregate
//! the outcomes. The study travels as text (the model file's contents and the excitation
//! arrays), so a worker on another machine needs no file of the client's.
use std::path::PathBuf;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use workbench::model::ModelStructure;
use workbench::model_file::ModelFile;
use workbench::power::{self, Outcome, Study, StudyOptions, StudySpec};
use workbench::Cancel;

use crate::errors::to_py_err;
use crate::interrupt::interruptible;
use crate::real::Real;
use crate::workbench::criterion_of;

fn spec_of(text: &str) -> PyResult<StudySpec> {
    serde_json::from_str(text)
        .map_err(|e| PyValueError::new_err(format!("not a power-study spec: {e}")))
}

fn to_text<T: serde::Serialize>(value: &T) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Fits the nominal model of the model file `model` to the logs `data`, estimates their noise
/// and returns the study as JSON text; without the GIL (Ctrl-C stops it at its next fit
/// iteration).
#[pyfunction]
#[pyo3(signature = (model, data, effect, values, campaigns, seed, estimator = "auto", criterion = None))]
#[allow(clippy::too_many_arguments)]
fn prepare(
    py: Python<'_>,
    model: PathBuf,
    data: Vec<PathBuf>,
    effect: String,
    values: Real<Vec<f64>>,
    campaigns: usize,
    seed: u64,
    estimator: &str,
    criterion: Option<&str>,
) -> PyResult<String> {
    let criterion = criterion_of(criterion)?;
    let cancel = Cancel::default();
    let spec = interruptible(py, &cancel, false, || {
        let text = std::fs::read_to_string(&model).map_err(|e| sim::SimError::io(&model, e))?;
        let file = ModelFile::parse(&text, &model)?;
        let logs = workbench::load::load(file.system(), &file.inputs(), &file.outputs(), &data)?;
        power::prepare(
            &text,
            &model,
            logs,
            &StudyOptions {
                effect,
                values: values.0,
                campaigns,
                seed,
                estimator: estimator.to_string(),
                band_hz: None,
                criterion,
                cancel: cancel.clone(),
            },
        )
    })?
    .map_err(to_py_err)?;
    to_text(&spec)
}

/// Every campaign of the study, `(value index, campaign index)`.
#[pyfunction]
fn jobs(spec: &str) -> PyResult<Vec<(usize, usize)>> {
    Ok(spec_of(spec)?.jobs())
}

/// Runs the campaigns `jobs` of the study on `threads` threads without the GIL (Ctrl-C stops
/// them at their next fit iteration); returns their outcomes as JSON text (a list).
#[pyfunction]
#[pyo3(signature = (spec, jobs, threads = 1))]
fn run(py: Python<'_>, spec: &str, jobs: Vec<(usize, usize)>, threads: usize) -> PyResult<String> {
    let spec = spec_of(spec)?;
    let cancel = Cancel::default();
    let outcomes = interruptible(py, &cancel, false, || {
        Study::new(spec).and_then(|study| power::run(&study, &jobs, threads, &|_| {}, &cancel))
    })?
    .map_err(to_py_err)?;
    to_text(&outcomes)
}

fn outcomes_of(batches: &[String]) -> PyResult<Vec<Outcome>> {
    let mut all = Vec::new();
    for b in batches {
        let part: Vec<Outcome> = serde_json::from_str(b)
            .map_err(|e| PyValueError::new_err(format!("not a batch of outcomes: {e}")))?;
        all.extend(part);
    }
    Ok(all)
}

/// Aggregates the outcome batches (JSON texts of [`run`]) of the study; returns the result as
/// JSON text, and writes the HTML report into `report` when given.
#[pyfunction]
#[pyo3(signature = (spec, batches, report = None))]
fn aggregate(spec: &str, batches: Vec<String>, report: Option<PathBuf>) -> PyResult<String> {
    let spec = spec_of(spec)?;
    let result = power::aggregate(&spec, &outcomes_of(&batches)?).map_err(to_py_err)?;
    if let Some(dir) = report {
        result
            .write_report(&dir, &[PathBuf::from(&spec.model_path)])
            .map_err(to_py_err)?;
    }
    to_text(&result)
}

/// Adds the `power` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let module = PyModule::new(parent.py(), "power")?;
    module.add_function(wrap_pyfunction!(prepare, &module)?)?;
    module.add_function(wrap_pyfunction!(jobs, &module)?)?;
    module.add_function(wrap_pyfunction!(run, &module)?)?;
    module.add_function(wrap_pyfunction!(aggregate, &module)?)?;
    parent.add_submodule(&module)
}
