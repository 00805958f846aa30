//! Python bindings of stabilis: the native module `stabilis._stabilis`. Each domain is one file
//! with `pub fn register(parent: &Bound<PyModule>)` that adds a submodule, registered below with
//! one line; the Python package re-exports it from `python/stabilis/<domain>.py`.
use pyo3::prelude::*;

mod callables;
mod cubli;
mod errors;
mod event_est;
mod flying_platform;
mod geometry;
mod interrupt;
mod log;
mod pmpc;
mod power;
mod real;
mod sim;
mod tilt;
mod workbench;

#[pymodule]
fn _stabilis(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    real::register(m)?;
    event_est::register(m)?;
    flying_platform::register(m)?;
    cubli::register(m)?;
    geometry::register(m)?;
    log::register(m)?;
    pmpc::register(m)?;
    power::register(m)?;
    sim::register(m)?;
    tilt::register(m)?;
    workbench::register(m)?;
    Ok(())
}
