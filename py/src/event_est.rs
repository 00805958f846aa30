//! Python bindings of distributed event-based state estimation: the platoon model, the LMI
//! synthesis of gains and thresholds, and the networked simulation with packet loss.

use event_est::model::{platoon, System};
use event_est::runtime::{InputMode, LocalUpdate};
use event_est::sim::{simulate as run_sim, Design, SimConfig};
use event_est::synth::{complete, step1, Stability};
use event_est::EventEstError;
use nalgebra::{DMatrix, DVector};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{to_py_err, Error, IntoPyError};

impl IntoPyError for EventEstError {
    fn into_py_error(self) -> PyErr {
        let message = self.to_string();
        match self {
            EventEstError::Dimension { .. }
            | EventEstError::BlockSizes { .. }
            | EventEstError::AgentIndex { .. }
            | EventEstError::NonFinite { .. } => PyValueError::new_err(message),
            _ => Error::new_err(message),
        }
    }
}

/// A 2-D float64 array as a matrix; `name` appears in the error.
fn matrix(array: &PyReadonlyArrayDyn<'_, f64>, name: &str) -> PyResult<DMatrix<f64>> {
    let shape = array.shape();
    if shape.len() != 2 {
        return Err(PyValueError::new_err(format!(
            "{name} must be a 2-D array, got shape {shape:?}"
        )));
    }
    let a = array.as_array();
    let m = DMatrix::from_fn(shape[0], shape[1], |i, j| a[[i, j]]);
    if m.iter().any(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name} contains NaN or infinity"
        )));
    }
    Ok(m)
}

fn to_numpy<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]).into_pyarray(py)
}

/// The system from its matrices and agent blocks.
#[allow(clippy::too_many_arguments)]
fn system(
    a: &PyReadonlyArrayDyn<'_, f64>,
    b: &PyReadonlyArrayDyn<'_, f64>,
    c: &PyReadonlyArrayDyn<'_, f64>,
    f: &PyReadonlyArrayDyn<'_, f64>,
    outputs: Vec<usize>,
    inputs: Vec<usize>,
    w: Option<&PyReadonlyArrayDyn<'_, f64>>,
    v_sqrt: Option<&PyReadonlyArrayDyn<'_, f64>>,
) -> PyResult<System> {
    let a = matrix(a, "A")?;
    let n = a.nrows();
    let c = matrix(c, "C")?;
    let w = match w {
        Some(w) => matrix(w, "W")?,
        None => DMatrix::identity(c.nrows(), c.nrows()),
    };
    let v_sqrt = match v_sqrt {
        Some(v) => matrix(v, "V_sqrt")?,
        None => DMatrix::zeros(n, 1),
    };
    System::new(
        a,
        matrix(b, "B")?,
        c,
        matrix(f, "F")?,
        outputs,
        inputs,
        w,
        v_sqrt,
    )
    .map_err(to_py_err)
}

/// The M-vehicle platoon of the paper: dict with A, B, C, F, outputs, inputs, W, V_sqrt and
/// the uniform noise half-widths noise_output, noise_input.
#[pyfunction]
fn platoon_model(py: Python<'_>, vehicles: usize) -> PyResult<Bound<'_, PyDict>> {
    let (sys, noise) = platoon(vehicles).map_err(to_py_err)?;
    let d = PyDict::new(py);
    d.set_item("A", to_numpy(py, &sys.a))?;
    d.set_item("B", to_numpy(py, &sys.b))?;
    d.set_item("C", to_numpy(py, &sys.c))?;
    d.set_item("F", to_numpy(py, &sys.f))?;
    d.set_item("outputs", sys.outputs.clone())?;
    d.set_item("inputs", sys.inputs.clone())?;
    d.set_item("W", to_numpy(py, &sys.w))?;
    d.set_item("V_sqrt", to_numpy(py, &sys.v_sqrt))?;
    d.set_item("noise_output", noise.output)?;
    d.set_item("noise_input", noise.input)?;
    Ok(d)
}

/// Step 1 + Step 2: gains L and thresholds Δ_i for the bound J_max (default 37·c*).
#[pyfunction]
#[pyo3(signature = (a, b, c, f, outputs, inputs, w, v_sqrt, j_max = None, condition = "cor12"))]
#[allow(clippy::too_many_arguments)]
fn synthesize<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
    b: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    f: PyReadonlyArrayDyn<'py, f64>,
    outputs: Vec<usize>,
    inputs: Vec<usize>,
    w: PyReadonlyArrayDyn<'py, f64>,
    v_sqrt: PyReadonlyArrayDyn<'py, f64>,
    j_max: Option<f64>,
    condition: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let sys = system(&a, &b, &c, &f, outputs, inputs, Some(&w), Some(&v_sqrt))?;
    let stability = Stability::parse(condition).map_err(to_py_err)?;
    let syn = py
        .detach(|| {
            let s1 = step1(&sys, stability)?;
            let j = j_max.unwrap_or(37.0 * s1.c_star);
            complete(&sys, s1, j)
        })
        .map_err(to_py_err)?;
    let d = PyDict::new(py);
    d.set_item("L", to_numpy(py, &syn.design.l))?;
    let deltas: Vec<_> = syn.design.delta.iter().map(|m| to_numpy(py, m)).collect();
    d.set_item("delta", deltas)?;
    let unit: Vec<_> = syn.unit.delta.iter().map(|m| to_numpy(py, m)).collect();
    d.set_item("delta_unit", unit)?;
    d.set_item("j_max", syn.j_max)?;
    d.set_item("c_star", syn.step1.c_star)?;
    d.set_item("true_h2", syn.step1.true_h2)?;
    d.set_item("kalman_cost", syn.step1.kalman_cost)?;
    d.set_item("bound", syn.bound.bound)?;
    d.set_item("g1_hinf", syn.bound.g1_hinf)?;
    d.set_item("status", syn.step1.status.clone())?;
    d.set_item("solve_time", syn.step1.solve_time + syn.unit.solve_time)?;
    d.set_item("stability_lmis", syn.step1.stability_lmis)?;
    Ok(d)
}

/// Networked closed loop: returns rates, total_rate, error_power, agent_error_power,
/// max_inter_agent_error, max_state.
#[pyfunction]
#[pyo3(signature = (a, b, c, f, outputs, inputs, l, delta, steps, loss = 0.1, x0 = None,
    noise_output = None, noise_input = None, seed = 0, local_update = false,
    communicated_inputs = false, window_start = 0))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    a: PyReadonlyArrayDyn<'py, f64>,
    b: PyReadonlyArrayDyn<'py, f64>,
    c: PyReadonlyArrayDyn<'py, f64>,
    f: PyReadonlyArrayDyn<'py, f64>,
    outputs: Vec<usize>,
    inputs: Vec<usize>,
    l: PyReadonlyArrayDyn<'py, f64>,
    delta: Vec<PyReadonlyArrayDyn<'py, f64>>,
    steps: usize,
    loss: f64,
    x0: Option<Vec<f64>>,
    noise_output: Option<Vec<f64>>,
    noise_input: Option<Vec<f64>>,
    seed: u64,
    local_update: bool,
    communicated_inputs: bool,
    window_start: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let sys = system(&a, &b, &c, &f, outputs, inputs, None, None)?;
    let delta = delta
        .iter()
        .map(|d| matrix(d, "delta[i]"))
        .collect::<PyResult<Vec<_>>>()?;
    let design = Design {
        l: matrix(&l, "L")?,
        delta,
    };
    let noise = match (noise_output, noise_input) {
        (None, None) => None,
        (o, i) => Some(event_est::model::UniformNoise {
            output: o.unwrap_or_else(|| vec![0.0; sys.p()]),
            input: i.unwrap_or_else(|| vec![0.0; sys.b.ncols()]),
        }),
    };
    let mut cfg = SimConfig::new(&sys, steps, noise, seed);
    cfg.loss = loss;
    cfg.window_start = window_start;
    cfg.local_update = if local_update {
        LocalUpdate::Always
    } else {
        LocalUpdate::OnlyOnEvent
    };
    cfg.input_mode = if communicated_inputs {
        InputMode::Communicated
    } else {
        InputMode::Reconstructed
    };
    if let Some(x0) = x0 {
        cfg.x0 = DVector::from_vec(x0);
    }
    let r = py
        .detach(|| run_sim(&sys, &design, &cfg))
        .map_err(to_py_err)?;
    let d = PyDict::new(py);
    d.set_item("rates", r.rates)?;
    d.set_item("total_rate", r.total_rate)?;
    d.set_item("error_power", r.error_power)?;
    d.set_item("agent_error_power", r.agent_error_power)?;
    d.set_item("max_inter_agent_error", r.max_inter_agent)?;
    d.set_item("max_state", r.max_state)?;
    Ok(d)
}

/// Adds the `event_est` submodule.
pub fn register(parent: &Bound<'_, PyModule>) -> PyResult<()> {
    let m = PyModule::new(parent.py(), "event_est")?;
    m.add_function(wrap_pyfunction!(platoon_model, &m)?)?;
    m.add_function(wrap_pyfunction!(synthesize, &m)?)?;
    m.add_function(wrap_pyfunction!(simulate, &m)?)?;
    parent.add_submodule(&m)?;
    Ok(())
}
