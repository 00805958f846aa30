//! Python bindings of stabilis: the native module `stabilis._stabilis`.
use pyo3::prelude::*;

#[pymodule]
fn _stabilis(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
