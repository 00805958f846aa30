//! Python bindings of distributed event-based state estimation: the platoon model, the LMI
//! synthesis of gains and thresholds, and the networked simulation with packet loss.

use event_est::alternation::alternate;
use event_est::model::{platoon, System};
use event_est::runtime::{InputMode, LocalUpdate};
use event_est::sim::{simulate as run_sim, Design, SimConfig};
use event_est::synth::{
    complete_using, step1, step1_relaxed, step1_using, BudgetBase, Solver, Stability,
};
use event_est::EventEstError;
use nalgebra::{DMatrix, DVector};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{to_py_err, Error, IntoPyError};
use crate::real::{real, Real};

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

/// Entry `key` of the model dict.
fn model_item<'py>(model: &Bound<'py, PyDict>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    model
        .get_item(key)?
        .ok_or_else(|| PyValueError::new_err(format!("model has no entry {key}")))
}

/// Matrix entry `key` of the model dict (a float64 array).
fn model_matrix(model: &Bound<'_, PyDict>, key: &str) -> PyResult<DMatrix<f64>> {
    let item = model_item(model, key)?;
    let array: PyReadonlyArrayDyn<'_, f64> = item.extract()?;
    matrix(&array, key)
}

/// The system of a model dict (A, B, C, F, outputs, inputs and, if `covariances`, W and
/// V_sqrt; otherwise unit W and no process noise, which the simulation does not use).
fn system(model: &Bound<'_, PyDict>, covariances: bool) -> PyResult<System> {
    let a = model_matrix(model, "A")?;
    let c = model_matrix(model, "C")?;
    let (w, v_sqrt) = if covariances {
        (model_matrix(model, "W")?, model_matrix(model, "V_sqrt")?)
    } else {
        (
            DMatrix::identity(c.nrows(), c.nrows()),
            DMatrix::zeros(a.nrows(), 1),
        )
    };
    System::new(
        a,
        model_matrix(model, "B")?,
        c,
        model_matrix(model, "F")?,
        model_item(model, "outputs")?.extract()?,
        model_item(model, "inputs")?.extract()?,
        w,
        v_sqrt,
    )
    .map_err(to_py_err)
}

/// The M-vehicle platoon of the paper: dict with A, B, C, F, outputs, inputs, W, V_sqrt and
/// the uniform noise half-widths noise_output, noise_input.
#[pyfunction]
fn platoon_model(py: Python<'_>, vehicles: usize) -> PyResult<Bound<'_, PyDict>> {
    sim::scenarios::platoon::check_vehicles(vehicles).map_err(to_py_err)?;
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

/// Gains L and thresholds Δ_i for the bound J_max (default 37·c*): Step 1 + Step 2
/// (`objective = "kalman"`, optionally with the relaxed Step 1 of weight `relax`) or the
/// alternation of gain and threshold steps that maximises Σ tr Δ_i (`objective = "general"`).
/// `solver` ("auto", "clarabel" or "schur") picks the SDP solver of the plain two-step design;
/// "auto" takes the Schur-complement method above 10 states (large platoons).
#[pyfunction]
#[pyo3(signature = (model, j_max = None, condition = "cor12", objective = "kalman", relax = None,
    max_iter = 20, solver = "auto"))]
#[allow(clippy::too_many_arguments)] // the model and the synthesis options of the docstring
fn synthesize<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyDict>,
    j_max: Option<Real<f64>>,
    condition: &str,
    objective: &str,
    relax: Option<Real<f64>>,
    max_iter: usize,
    solver: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let (j_max, relax) = (j_max.map(|j| j.0), relax.map(|r| r.0));
    let sys = system(model, true)?;
    let stability = Stability::parse(condition).map_err(to_py_err)?;
    let chosen = match solver {
        "auto" => Solver::for_states(sys.n()),
        name => Solver::parse(name).map_err(|_| {
            PyValueError::new_err(format!(
                "solver must be \"auto\", \"clarabel\" or \"schur\", got {name:?}"
            ))
        })?,
    };
    if solver != "auto" && chosen != Solver::Clarabel && (relax.is_some() || objective == "general")
    {
        return Err(PyValueError::new_err(
            "solver applies to the plain two-step design (objective \"kalman\" without \
             relax); the relaxed Step 1 and the alternation run on Clarabel",
        ));
    }
    let d = PyDict::new(py);
    match objective {
        "kalman" => {
            let (syn, lambda_bar) = py
                .detach(|| {
                    let (s1, lambda_bar) = match relax {
                        Some(w) => {
                            let r = step1_relaxed(&sys, stability, w)?;
                            (r.step1, r.lambda_bar)
                        }
                        None => (step1_using(&sys, stability, chosen)?, 0.0),
                    };
                    let j = j_max.unwrap_or(37.0 * s1.c_star);
                    let base = BudgetBase::Step1Bound;
                    Ok::<_, EventEstError>((complete_using(&sys, s1, j, base, chosen)?, lambda_bar))
                })
                .map_err(to_py_err)?;
            design_items(py, &d, &syn.design, syn.j_max, &syn.bound)?;
            let unit: Vec<_> = syn.unit.delta.iter().map(|m| to_numpy(py, m)).collect();
            d.set_item("delta_unit", unit)?;
            d.set_item("c_star", syn.step1.c_star)?;
            d.set_item("true_h2", syn.step1.true_h2)?;
            d.set_item("kalman_cost", syn.step1.kalman_cost)?;
            d.set_item("lambda_bar", lambda_bar)?;
            d.set_item("status", syn.step1.status.clone())?;
            d.set_item("solve_time", syn.step1.solve_time + syn.unit.solve_time)?;
            d.set_item("stability_lmis", syn.step1.stability_lmis)?;
        }
        "general" => {
            if relax.is_some() {
                return Err(PyValueError::new_err(
                    "relax applies to objective \"kalman\" (the alternation certifies every \
                     iterate with the unrelaxed condition)",
                ));
            }
            let (alt, j) = py
                .detach(|| {
                    let j = match j_max {
                        Some(j) => j,
                        None => 37.0 * step1(&sys, stability)?.c_star,
                    };
                    Ok::<_, EventEstError>((alternate(&sys, stability, j, max_iter)?, j))
                })
                .map_err(to_py_err)?;
            let last = alt
                .iterates
                .last()
                .ok_or_else(|| Error::new_err("the alternation returned no iterate"))?;
            design_items(py, &d, &last.design, j, &last.bound)?;
            let history: Vec<f64> = alt.iterates.iter().map(|it| it.trace_delta).collect();
            d.set_item("trace_delta", history)?;
            let bounds: Vec<Option<f64>> =
                alt.iterates.iter().map(|it| it.gain_step_bound).collect();
            d.set_item("gain_step_bound", bounds)?;
            d.set_item("stop", alt.stop.clone())?;
            d.set_item(
                "stability_certificate",
                to_numpy(py, &last.stability_certificate),
            )?;
        }
        other => {
            return Err(PyValueError::new_err(format!(
                "objective must be \"kalman\" or \"general\", got {other:?}"
            )))
        }
    }
    Ok(d)
}

/// L, delta, j_max and the certified bound of a design.
fn design_items<'py>(
    py: Python<'py>,
    d: &Bound<'py, PyDict>,
    design: &Design,
    j_max: f64,
    bound: &event_est::synth::Bound,
) -> PyResult<()> {
    d.set_item("L", to_numpy(py, &design.l))?;
    let deltas: Vec<_> = design.delta.iter().map(|m| to_numpy(py, m)).collect();
    d.set_item("delta", deltas)?;
    d.set_item("j_max", j_max)?;
    d.set_item("bound", bound.bound)?;
    d.set_item("g1_hinf", bound.g1_hinf)?;
    d.set_item("g2_h2", bound.g2_h2)?;
    Ok(())
}

/// Networked closed loop: returns rates, total_rate, error_power, agent_error_power,
/// max_inter_agent_error, max_state.
#[pyfunction]
#[pyo3(signature = (model, l, delta, steps, loss = 0.1, x0 = None,
    noise_output = None, noise_input = None, seed = 0, local_update = false,
    communicated_inputs = false, window_start = 0))]
#[allow(clippy::too_many_arguments)]
fn simulate<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyDict>,
    l: PyReadonlyArrayDyn<'py, f64>,
    delta: Vec<PyReadonlyArrayDyn<'py, f64>>,
    steps: usize,
    #[pyo3(from_py_with = real)] loss: f64,
    x0: Option<Real<Vec<f64>>>,
    noise_output: Option<Real<Vec<f64>>>,
    noise_input: Option<Real<Vec<f64>>>,
    seed: u64,
    local_update: bool,
    communicated_inputs: bool,
    window_start: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let sys = system(model, false)?;
    let delta = delta
        .iter()
        .map(|d| matrix(d, "delta[i]"))
        .collect::<PyResult<Vec<_>>>()?;
    let design = Design {
        l: matrix(&l, "L")?,
        delta,
    };
    let noise = match (noise_output.map(|o| o.0), noise_input.map(|i| i.0)) {
        (None, None) => None,
        (o, i) => Some(event_est::model::UniformNoise {
            output: o.unwrap_or_else(|| vec![0.0; sys.p()]),
            input: i.unwrap_or_else(|| vec![0.0; sys.b.ncols()]),
        }),
    };
    // The run keeps the state trajectory and every agent's estimates per step: bounded by the
    // memory before anything is allocated.
    let per_step = 8.0 * (sys.a.nrows() * (1 + sys.agents())) as f64 + 64.0;
    sim::limits::check("steps", steps, steps as f64, per_step).map_err(to_py_err)?;
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
    if let Some(Real(x0)) = x0 {
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
