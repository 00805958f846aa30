//! Python bindings of the log readers: MCAP and CSV into numpy arrays, one
//! `(t, {field: values})` pair per topic.
use std::path::PathBuf;

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use sim::log::Table;

use crate::errors::to_py_err;

/// `(t, {field: values})` with float64 arrays.
pub fn table_to_py<'py>(py: Python<'py>, table: &Table) -> PyResult<Bound<'py, PyTuple>> {
    let fields = PyDict::new(py);
    for (name, column) in table.fields.iter().zip(&table.columns) {
        fields.set_item(name, PyArray1::from_slice(py, column))?;
    }
    PyTuple::new(
        py,
        [
            PyArray1::from_slice(py, &table.t).into_any(),
            fields.into_any(),
        ],
    )
}

/// `{topic: (t, {field: values})}` for a set of tables.
pub fn tables_to_py<'py, 'a>(
    py: Python<'py>,
    tables: impl IntoIterator<Item = (&'a String, &'a Table)>,
) -> PyResult<Bound<'py, PyDict>> {
    let topics = PyDict::new(py);
    for (name, table) in tables {
        topics.set_item(name, table_to_py(py, table)?)?;
    }
    Ok(topics)
}

/// Reads an MCAP log: returns `(topics, metadata, complete, problem)`; raises
/// `stabilis.LogError` if a topic of `topics` is missing.
#[pyfunction]
#[pyo3(signature = (path, topics = None))]
fn read_mcap<'py>(
    py: Python<'py>,
    path: PathBuf,
    topics: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let log = py
        .detach(|| sim::log::read_mcap(&path))
        .map_err(to_py_err)?;
    for topic in topics.iter().flatten() {
        log.topic(topic).map_err(to_py_err)?;
    }
    let metadata = PyDict::new(py);
    for (name, record) in &log.metadata {
        metadata.set_item(name, record.clone())?;
    }
    PyTuple::new(
        py,
        [
            tables_to_py(py, &log.topics)?.into_any(),
            metadata.into_any(),
            log.complete.into_pyobject(py)?.to_owned().into_any(),
            log.problem.into_pyobject(py)?.into_any(),
        ],
    )
}

/// Reads a CSV file (header row, a `t` column): returns `(t, {field: values})`.
#[pyfunction]
fn read_csv<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyTuple>> {
    let table = py.detach(|| sim::log::read_csv(&path)).map_err(to_py_err)?;
    table_to_py(py, &table)
}

/// Adds the `log` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let module = PyModule::new(parent.py(), "log")?;
    module.add_function(wrap_pyfunction!(read_mcap, &module)?)?;
    module.add_function(wrap_pyfunction!(read_csv, &module)?)?;
    parent.add_submodule(&module)
}
