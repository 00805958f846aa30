//! A nonlinear model given as Python callables, `f(x, u, params) -> dx` and
//! `h(x, u, params) -> y` (`x`, `u` numpy arrays, `params` a dict `{name: float}`): the
//! workbench's [`Dynamics`], and its linearization at the operating point by central
//! differences, with the terms of the model's declared effects (`stabilis.Effect(f=, h=)`)
//! added. Every call takes the GIL, so the predictor's records and candidates share
//! one interpreter: a fit costs about one Python call per model evaluation (README, "Your own
//! system").
use std::sync::Arc;

use nalgebra::DMatrix;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyMappingProxy};
use workbench::dynamics::Dynamics;
use workbench::model::StateSpace;

use crate::interrupt::Raised;
use crate::real::real_array;

/// `f`, `h` and where the model is linearized and the predictor starts.
#[derive(Debug)]
pub struct Callables {
    pub f: Py<PyAny>,
    pub h: Py<PyAny>,
    pub x_op: Vec<f64>,
    pub u_op: Vec<f64>,
    pub outputs: usize,
}

impl Callables {
    pub fn clone_ref(&self, py: Python<'_>) -> Self {
        Self {
            f: self.f.clone_ref(py),
            h: self.h.clone_ref(py),
            x_op: self.x_op.clone(),
            u_op: self.u_op.clone(),
            outputs: self.outputs,
        }
    }

    /// `f` (`output = false`) or `h` at `(x, u)` into `out`: the model's, plus the terms of
    /// the `extras` (declared effects) that give one, each call's length and values checked.
    /// `x` holds the model's states, then each extra's own; an extra's callables see the
    /// model's and its own, and its `f` gives the derivatives of both.
    #[allow(clippy::too_many_arguments)]
    pub fn eval(
        &self,
        py: Python<'_>,
        model: &str,
        output: bool,
        (x, u): (&[f64], &[f64]),
        params: &Bound<'_, PyDict>,
        extras: &[Extra],
        out: &mut [f64],
    ) -> PyResult<()> {
        let n = self.x_op.len();
        let func = if output { &self.h } else { &self.f };
        let (model_out, own_out) = out.split_at_mut(if output { out.len() } else { n });
        call_checked(py, model, output, func, (&x[..n], u), params, model_out)?;
        own_out.fill(0.0);
        let (mut term, mut seen) = (Vec::new(), Vec::new());
        let mut at = n;
        for e in extras {
            let own = at..at + e.x_op.len();
            at = own.end;
            let Some(func) = (if output { &e.h } else { &e.f }) else {
                continue;
            };
            seen.clear();
            seen.extend_from_slice(&x[..n]);
            seen.extend_from_slice(&x[own.clone()]);
            term.clear();
            term.resize(if output { out.len() } else { seen.len() }, 0.0);
            let who = format!("effect {}", e.name);
            call_checked(
                py,
                &who,
                output,
                func,
                (&seen, u),
                e.params.bind(py),
                &mut term,
            )?;
            // `h` adds to the outputs; `f` to the model's derivatives, then to its own.
            let (to_model, to_own) = if output {
                (&term[..], &[][..])
            } else {
                term.split_at(n)
            };
            for (o, t) in out.iter_mut().zip(to_model) {
                *o += t;
            }
            if !output {
                for (o, t) in out[own].iter_mut().zip(to_own) {
                    *o += t;
                }
            }
        }
        Ok(())
    }

    /// The operating point of the model's states and of the `extras`' own.
    pub fn x_op_with(&self, extras: &[Extra]) -> Vec<f64> {
        self.x_op
            .iter()
            .chain(extras.iter().flat_map(|e| &e.x_op))
            .copied()
            .collect()
    }

    /// The Jacobians `(A, B, C, D)` at the operating point, by central differences with steps
    /// of 1e-6 relative (truncation and rounding both near 1e-10 relative).
    pub fn linearize(
        &self,
        py: Python<'_>,
        model: &str,
        params: &Bound<'_, PyDict>,
        extras: &[Extra],
    ) -> PyResult<StateSpace> {
        let x_op = self.x_op_with(extras);
        let (n, m, p) = (x_op.len(), self.u_op.len(), self.outputs);
        let mut z: Vec<f64> = x_op.iter().chain(&self.u_op).copied().collect();
        let mut jac = DMatrix::zeros(n + p, n + m);
        let (mut plus, mut minus) = (vec![0.0; n + p], vec![0.0; n + p]);
        for j in 0..n + m {
            let step = 1e-6 * z[j].abs().max(1.0);
            let z0 = z[j];
            for (sign, out) in [(1.0, &mut plus), (-1.0, &mut minus)] {
                z[j] = z0 + sign * step;
                let (x, u) = z.split_at(n);
                let (df, dh) = out.split_at_mut(n);
                self.eval(py, model, false, (x, u), params, extras, df)?;
                self.eval(py, model, true, (x, u), params, extras, dh)?;
            }
            z[j] = z0;
            for i in 0..n + p {
                jac[(i, j)] = (plus[i] - minus[i]) / (2.0 * step);
            }
        }
        let j = jac;
        Ok(StateSpace {
            a: j.view((0, 0), (n, n)).into_owned(),
            b: j.view((0, n), (n, m)).into_owned(),
            c: j.view((n, 0), (p, n)).into_owned(),
            d: j.view((n, n), (p, m)).into_owned(),
            delay: 0.0,
        })
    }
}

/// `func(x, u, params)` (the `f` or the `h` of `who`, a model or an effect) into `out`,
/// checking the length and that every value is finite.
fn call_checked(
    py: Python<'_>,
    who: &str,
    output: bool,
    func: &Py<PyAny>,
    (x, u): (&[f64], &[f64]),
    params: &Bound<'_, PyDict>,
    out: &mut [f64],
) -> PyResult<()> {
    let (label, what) = if output {
        ("h", "outputs")
    } else {
        ("f", "states")
    };
    // A read-only view: the dict serves every call at this parameter vector, and a callable
    // that wrote to it (p["k"] = ...) silently changed the next call's parameters.
    let view = PyMappingProxy::new(py, params.as_mapping());
    let value = func.call1(
        py,
        (
            PyArray1::from_slice(py, x),
            PyArray1::from_slice(py, u),
            view,
        ),
    )?;
    let value = value.bind(py);
    // A float64 array is read directly; anything else (a list) is converted by the
    // package's one rule for arrays (a complex result is a TypeError, not its real part).
    let values: Vec<f64> = match value.cast::<PyArray1<f64>>() {
        Ok(a) => a.readonly().as_array().to_vec(),
        Err(_) => real_array(value, &format!("{who}: {label}(x, u, params)"))?
            .cast_into::<PyArray1<f64>>()
            .map_err(|_| {
                PyValueError::new_err(format!(
                    "{who}: {label}(x, u, params) must return a 1-D sequence of numbers"
                ))
            })?
            .readonly()
            .as_array()
            .to_vec(),
    };
    if values.len() != out.len() {
        return Err(PyValueError::new_err(format!(
            "{who}: {label}(x, u, params) returned {} values, expected {} ({what})",
            values.len(),
            out.len()
        )));
    }
    if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{who}: {label}(x, u, params)[{i}] = {v} at x = {x:?}, u = {u:?}"
        )));
    }
    out.copy_from_slice(&values);
    Ok(())
}

/// A declared effect of a nonlinear Python model at one parameter vector: the terms its
/// `f(x, u, params)` adds to the state derivative and its `h(x, u, params)` to the outputs,
/// `params` holding the model's parameters (fitted and fixed) and the effect's own.
#[derive(Debug)]
pub struct Extra {
    pub name: String,
    pub f: Option<Py<PyAny>>,
    pub h: Option<Py<PyAny>>,
    pub params: Py<PyDict>,
    /// The operating point of its own states (none for most).
    pub x_op: Vec<f64>,
}

/// The callables at one parameter vector: what the time-domain criterion integrates.
#[derive(Debug)]
pub struct PyDynamics {
    /// How messages name the model ("model <name>").
    pub model: String,
    pub callables: Arc<Callables>,
    pub params: Py<PyDict>,
    /// The enabled declared effects.
    pub extras: Vec<Extra>,
    /// The first exception of a user's callable, for the caller.
    pub error: Arc<Raised>,
}

impl PyDynamics {
    fn eval(&self, output: bool, x: &[f64], u: &[f64], out: &mut [f64]) -> sim::Result<()> {
        // A cancelled run calls no more Python on its way to its next check.
        self.error.cancel().check()?;
        Python::attach(|py| {
            self.callables.eval(
                py,
                &self.model,
                output,
                (x, u),
                self.params.bind(py),
                &self.extras,
                out,
            )
        })
        .map_err(|err| {
            let which = if output { "h" } else { "f" };
            self.error.keep_as(err, self.model.clone(), which)
        })
    }
}

impl Dynamics for PyDynamics {
    fn states(&self) -> usize {
        self.callables.x_op.len() + self.extras.iter().map(|e| e.x_op.len()).sum::<usize>()
    }
    fn inputs(&self) -> usize {
        self.callables.u_op.len()
    }
    fn outputs(&self) -> usize {
        self.callables.outputs
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], _scratch: &mut Vec<f64>) -> sim::Result<()> {
        self.eval(false, x, u, dx)
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], _scratch: &mut Vec<f64>) -> sim::Result<()> {
        self.eval(true, x, u, y)
    }
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        (
            self.callables.x_op_with(&self.extras),
            self.callables.u_op.clone(),
        )
    }
}
