//! Nonlinear grey-box models `x' = f(x, u)`, `y = h(x, u)` in absolute units, and the
//! generic effects' nonlinear forms: what the time-domain prediction-error criterion
//! ([`super::prediction`]) integrates between samples. A model file's `[nonlinear]` section
//! is one ([`super::ModelFile`]); its linearization at the operating point is the
//! [`super::StateSpace`] every linear tool of the workbench uses.
use crate::error::{Result, SimError};

/// A continuous-time nonlinear model at fixed parameter values.
///
/// `scratch` is the caller's reusable buffer (the predictor calls `f` four times per sample
/// and integration step, so an implementation should not allocate).
pub trait Dynamics: Send + Sync + std::fmt::Debug {
    /// Number of states.
    fn states(&self) -> usize;
    /// Number of inputs.
    fn inputs(&self) -> usize;
    /// Number of outputs.
    fn outputs(&self) -> usize;
    /// `dx = f(x, u)`.
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()>;
    /// `y = h(x, u)`.
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()>;
    /// The operating point `(x, u)`: where the model is linearized and the predictor starts.
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>);
    /// Transport delay of every input, s.
    fn input_delay(&self) -> f64 {
        0.0
    }
    /// `(input, tau)` of each first-order input lag ([`LaggedInputs`]), in the order of their
    /// states, which come right before the output lags'; the predictor integrates them
    /// exactly, since a lag much shorter than a sample is stiff.
    fn input_lags(&self) -> Vec<(usize, f64)> {
        Vec::new()
    }
    /// `(output, tau)` of each first-order lag on one output ([`LaggedOutput`]), in the order
    /// of their states, which are the model's last; the predictor integrates them exactly.
    fn output_lags(&self) -> Vec<(usize, f64)> {
        Vec::new()
    }
    /// The outputs before any output lag: what each lag filters.
    fn h_unlagged(
        &self,
        x: &[f64],
        u: &[f64],
        y: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> Result<()> {
        self.h(x, u, y, scratch)
    }
}

/// A constant offset on every output: `y = h(x, u) + bias`.
#[derive(Debug)]
pub struct OutputBias {
    inner: Box<dyn Dynamics>,
    bias: Vec<f64>,
}

impl OutputBias {
    /// `inner` with `bias` added to its outputs.
    pub fn new(inner: Box<dyn Dynamics>, bias: &[f64]) -> Result<Self> {
        if bias.len() != inner.outputs() {
            return Err(SimError::LengthMismatch {
                what: "sensor biases (one per output)".into(),
                expected: inner.outputs(),
                found: bias.len(),
            });
        }
        Ok(Self {
            inner,
            bias: bias.to_vec(),
        })
    }
}

impl Dynamics for OutputBias {
    fn states(&self) -> usize {
        self.inner.states()
    }
    fn inputs(&self) -> usize {
        self.inner.inputs()
    }
    fn outputs(&self) -> usize {
        self.inner.outputs()
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.inner.f(x, u, dx, scratch)
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.inner.h(x, u, y, scratch)?;
        for (y, b) in y.iter_mut().zip(&self.bias) {
            *y += b;
        }
        Ok(())
    }
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        self.inner.operating_point()
    }
    fn input_delay(&self) -> f64 {
        self.inner.input_delay()
    }
    fn input_lags(&self) -> Vec<(usize, f64)> {
        self.inner.input_lags()
    }
    fn output_lags(&self) -> Vec<(usize, f64)> {
        self.inner.output_lags()
    }
    fn h_unlagged(
        &self,
        x: &[f64],
        u: &[f64],
        y: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> Result<()> {
        self.inner.h_unlagged(x, u, y, scratch)?;
        for (y, b) in y.iter_mut().zip(&self.bias) {
            *y += b;
        }
        Ok(())
    }
}

/// A first-order lag of one time constant on some inputs: states `(x, x_a)`, one per lagged
/// input, `x_a' = (u_j - x_a) / tau`, the plant driven by `x_a` in place of `u_j`.
#[derive(Debug)]
pub struct LaggedInputs {
    inner: Box<dyn Dynamics>,
    /// The lagged inputs, in the order of their states.
    lagged: Vec<usize>,
    rate: f64,
}

impl LaggedInputs {
    /// `inner` with the inputs `lagged` behind a lag of time constant `tau` (s, positive);
    /// `inner` lags none of them (a lag behind a lag is not integrated exactly) and has no
    /// output lag (whose states must stay the last).
    pub fn new(inner: Box<dyn Dynamics>, lagged: Vec<usize>, tau: f64) -> Result<Self> {
        if !(tau.is_finite() && tau > 0.0) {
            return Err(SimError::invalid("tau", tau, "must be positive and finite"));
        }
        let m = inner.inputs();
        if let Some(&j) = lagged.iter().find(|&&j| j >= m) {
            return Err(SimError::invalid(
                "input",
                j,
                format!("the model has {m} inputs"),
            ));
        }
        let already = inner.input_lags();
        if let Some(&j) = lagged
            .iter()
            .find(|&&j| already.iter().any(|(i, _)| *i == j))
        {
            return Err(SimError::invalid("input", j, "already has a lag"));
        }
        if !inner.output_lags().is_empty() {
            return Err(SimError::invalid(
                "tau",
                tau,
                "an input lag must wrap the model inside its output lags (their states come last)",
            ));
        }
        Ok(Self {
            inner,
            lagged,
            rate: 1.0 / tau,
        })
    }

    /// `g` of `u` with the lagged inputs replaced by their states `xa`.
    fn driven<R>(&self, u: &[f64], xa: &[f64], g: impl FnOnce(&[f64]) -> R) -> R {
        with_inputs(
            u,
            |v| {
                for (&j, a) in self.lagged.iter().zip(xa) {
                    v[j] = *a;
                }
            },
            g,
        )
    }
}

/// Room for the inputs of a small model on the stack (a larger one allocates).
const STACK: usize = 16;

impl Dynamics for LaggedInputs {
    fn states(&self) -> usize {
        self.inner.states() + self.lagged.len()
    }
    fn inputs(&self) -> usize {
        self.inner.inputs()
    }
    fn outputs(&self) -> usize {
        self.inner.outputs()
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        let n = self.inner.states();
        let (xp, xa) = x.split_at(n);
        let (dp, da) = dx.split_at_mut(n);
        self.driven(u, xa, |v| self.inner.f(xp, v, dp, scratch))?;
        for ((d, a), &j) in da.iter_mut().zip(xa).zip(&self.lagged) {
            *d = (u[j] - a) * self.rate;
        }
        Ok(())
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        let (xp, xa) = x.split_at(self.inner.states());
        self.driven(u, xa, |v| self.inner.h(xp, v, y, scratch))
    }
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        let (mut x, u) = self.inner.operating_point();
        x.extend(self.lagged.iter().map(|&j| u[j]));
        (x, u)
    }
    fn input_delay(&self) -> f64 {
        self.inner.input_delay()
    }
    fn input_lags(&self) -> Vec<(usize, f64)> {
        let mut lags = self.inner.input_lags();
        lags.extend(self.lagged.iter().map(|&j| (j, 1.0 / self.rate)));
        lags
    }
}

/// `g` of a copy of the inputs `u` that `edit` changes (on the stack for a small model: the
/// predictor evaluates the model four times per integration step).
fn with_inputs<R>(u: &[f64], edit: impl FnOnce(&mut [f64]), g: impl FnOnce(&[f64]) -> R) -> R {
    let (mut stack, mut heap) = ([0.0; STACK], Vec::new());
    let v = room(&mut stack, &mut heap, u.len());
    v.copy_from_slice(u);
    edit(v);
    g(v)
}

/// `len` numbers of `stack`, or of `heap` when the stack is too small.
fn room<'a>(stack: &'a mut [f64; STACK], heap: &'a mut Vec<f64>, len: usize) -> &'a mut [f64] {
    if len <= STACK {
        &mut stack[..len]
    } else {
        heap.resize(len, 0.0);
        &mut heap[..]
    }
}

/// How [`EditedInputs`] changes the inputs where they drive the plant.
#[derive(Debug, Clone, PartialEq)]
pub enum InputEdit {
    /// Input `input` times `gain` (an actuator weaker or stronger than documented).
    Gain { input: usize, gain: f64 },
    /// One constant added to each input (a driver's zero, a constant force the model lacks).
    Offsets(Vec<f64>),
}

impl InputEdit {
    /// `u` as it drives the plant.
    fn apply(&self, u: &mut [f64]) {
        match self {
            Self::Gain { input, gain } => u[*input] *= gain,
            Self::Offsets(b) => u.iter_mut().zip(b).for_each(|(u, b)| *u += b),
        }
    }

    /// The logged inputs that drive the plant with `u`.
    fn undo(&self, u: &mut [f64]) {
        match self {
            Self::Gain { input, gain } => u[*input] /= gain,
            Self::Offsets(b) => u.iter_mut().zip(b).for_each(|(u, b)| *u -= b),
        }
    }
}

/// The inputs changed where they drive the plant: `f(x, u')`, `h(x, u')` with `u'` the
/// logged `u` under an [`InputEdit`].
#[derive(Debug)]
pub struct EditedInputs {
    inner: Box<dyn Dynamics>,
    edit: InputEdit,
}

impl EditedInputs {
    /// `inner` with its inputs changed by `edit` (a finite, non-zero gain on one of its
    /// inputs, or one finite offset per input); `inner` has no input lag (whose state the
    /// predictor integrates towards the logged input, so the edit must act inside it).
    pub fn new(inner: Box<dyn Dynamics>, edit: InputEdit) -> Result<Self> {
        let m = inner.inputs();
        match &edit {
            InputEdit::Gain { gain, .. } if !(gain.is_finite() && *gain != 0.0) => {
                return Err(SimError::invalid(
                    "gain",
                    gain,
                    "must be finite and non-zero",
                ));
            }
            InputEdit::Gain { input, .. } if *input >= m => {
                return Err(SimError::invalid(
                    "input",
                    input,
                    format!("the model has {m} inputs"),
                ));
            }
            InputEdit::Offsets(b) if b.len() != m => {
                return Err(SimError::LengthMismatch {
                    what: "input offsets (one per input)".into(),
                    expected: m,
                    found: b.len(),
                });
            }
            InputEdit::Offsets(b) if b.iter().any(|b| !b.is_finite()) => {
                return Err(SimError::invalid(
                    "input offsets",
                    format!("{b:?}"),
                    "must be finite",
                ));
            }
            _ => {}
        }
        if !inner.input_lags().is_empty() {
            return Err(SimError::invalid(
                "input edit",
                format!("{edit:?}"),
                "an input's gain or offset must act inside the input lags",
            ));
        }
        Ok(Self { inner, edit })
    }

    /// `g` of `u` as it drives the plant.
    fn driven<R>(&self, u: &[f64], g: impl FnOnce(&[f64]) -> R) -> R {
        with_inputs(u, |v| self.edit.apply(v), g)
    }
}

impl Dynamics for EditedInputs {
    fn states(&self) -> usize {
        self.inner.states()
    }
    fn inputs(&self) -> usize {
        self.inner.inputs()
    }
    fn outputs(&self) -> usize {
        self.inner.outputs()
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.driven(u, |v| self.inner.f(x, v, dx, scratch))
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.driven(u, |v| self.inner.h(x, v, y, scratch))
    }
    /// The inner model's, its inputs the logged ones that hold it.
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        let (x, mut u) = self.inner.operating_point();
        self.edit.undo(&mut u);
        (x, u)
    }
    fn input_delay(&self) -> f64 {
        self.inner.input_delay()
    }
    fn output_lags(&self) -> Vec<(usize, f64)> {
        self.inner.output_lags()
    }
    fn h_unlagged(
        &self,
        x: &[f64],
        u: &[f64],
        y: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> Result<()> {
        self.driven(u, |v| self.inner.h_unlagged(x, v, y, scratch))
    }
}

/// A transport delay `td` of every input, added to the inner model's.
#[derive(Debug)]
pub struct DelayedInputs {
    inner: Box<dyn Dynamics>,
    td: f64,
}

impl DelayedInputs {
    /// `inner` with its inputs delayed by `td` (s, non-negative) more.
    pub fn new(inner: Box<dyn Dynamics>, td: f64) -> Result<Self> {
        if !(td.is_finite() && td >= 0.0) {
            return Err(SimError::invalid(
                "td",
                td,
                "must be non-negative and finite",
            ));
        }
        Ok(Self { inner, td })
    }
}

impl Dynamics for DelayedInputs {
    fn states(&self) -> usize {
        self.inner.states()
    }
    fn inputs(&self) -> usize {
        self.inner.inputs()
    }
    fn outputs(&self) -> usize {
        self.inner.outputs()
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.inner.f(x, u, dx, scratch)
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.inner.h(x, u, y, scratch)
    }
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        self.inner.operating_point()
    }
    fn input_delay(&self) -> f64 {
        self.inner.input_delay() + self.td
    }
    fn input_lags(&self) -> Vec<(usize, f64)> {
        self.inner.input_lags()
    }
    fn output_lags(&self) -> Vec<(usize, f64)> {
        self.inner.output_lags()
    }
    fn h_unlagged(
        &self,
        x: &[f64],
        u: &[f64],
        y: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> Result<()> {
        self.inner.h_unlagged(x, u, y, scratch)
    }
}

/// A first-order lag on output `output`: state `x_s' = (h_i(x, u) - x_s) / tau` appended to
/// the inner model's, reported in place of `h_i`.
#[derive(Debug)]
pub struct LaggedOutput {
    inner: Box<dyn Dynamics>,
    output: usize,
    rate: f64,
}

impl LaggedOutput {
    /// `inner` with its output `output` behind a lag of time constant `tau` (s, positive).
    pub fn new(inner: Box<dyn Dynamics>, output: usize, tau: f64) -> Result<Self> {
        if !(tau.is_finite() && tau > 0.0) {
            return Err(SimError::invalid("tau", tau, "must be positive and finite"));
        }
        if output >= inner.outputs() {
            return Err(SimError::invalid(
                "output",
                output,
                format!("the model has {} outputs", inner.outputs()),
            ));
        }
        if inner.output_lags().iter().any(|(o, _)| *o == output) {
            return Err(SimError::invalid("output", output, "already has a lag"));
        }
        Ok(Self {
            inner,
            output,
            rate: 1.0 / tau,
        })
    }
}

impl Dynamics for LaggedOutput {
    fn states(&self) -> usize {
        self.inner.states() + 1
    }
    fn inputs(&self) -> usize {
        self.inner.inputs()
    }
    fn outputs(&self) -> usize {
        self.inner.outputs()
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        let n = self.inner.states();
        self.inner.f(&x[..n], u, &mut dx[..n], scratch)?;
        // The predictor integrates this state exactly and never uses its derivative here;
        // the operating point's drift check does.
        let (mut stack, mut heap) = ([0.0; STACK], Vec::new());
        let y = room(&mut stack, &mut heap, self.inner.outputs());
        self.inner.h(&x[..n], u, y, scratch)?;
        dx[n] = (y[self.output] - x[n]) * self.rate;
        Ok(())
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        let n = self.inner.states();
        self.inner.h(&x[..n], u, y, scratch)?;
        y[self.output] = x[n];
        Ok(())
    }
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        let (mut x, u) = self.inner.operating_point();
        let mut y = vec![0.0; self.inner.outputs()];
        // An operating point the inner model cannot evaluate fails at its first use.
        let settled = self
            .inner
            .h(&x, &u, &mut y, &mut Vec::new())
            .map_or(0.0, |_| y[self.output]);
        x.push(settled);
        (x, u)
    }
    fn input_delay(&self) -> f64 {
        self.inner.input_delay()
    }
    fn input_lags(&self) -> Vec<(usize, f64)> {
        self.inner.input_lags()
    }
    fn output_lags(&self) -> Vec<(usize, f64)> {
        let mut lags = self.inner.output_lags();
        lags.push((self.output, 1.0 / self.rate));
        lags
    }
    fn h_unlagged(
        &self,
        x: &[f64],
        u: &[f64],
        y: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> Result<()> {
        self.inner
            .h_unlagged(&x[..self.inner.states()], u, y, scratch)
    }
}
