//! Effects every model gets as discovery candidates, whatever its system: a first-order lag
//! on every input (`actuator_lag`, time constant `tau`), a transport delay of every input
//! (`input_delay`, `td`), with two to four inputs a first-order lag on each input alone
//! (`actuator_lag_<input>`, `tau_<input>`), with two to four outputs one on each output alone
//! (`sensor_lag_<output>`, `tau_<output>`), and for a nonlinear model a constant offset on
//! every output (`sensor_bias`, `bias_<output>`) and on every input (`input_bias`,
//! `bias_<input>`). A structure that declares an effect of the same name (the flying platform
//! does) keeps its own.
use std::sync::Arc;

use nalgebra::DMatrix;

use super::dataset::Dataset;
use super::dynamics::{
    DelayedInputs, Dynamics, EditedInputs, InputEdit, LaggedInputs, LaggedOutput, OutputBias,
};
use super::model::{Effect, ModelStructure, Parameter, StateSpace};
use crate::error::Result;

/// Most channels on one side (inputs, or outputs) that get a lag (or an input a gain) of their
/// own as a candidate: each is one more fit per discovery step and per search a rival is
/// followed into. The flying platform's discovery tests (9 inputs, 6 outputs) took 128 s with
/// a lag on each of its 6 outputs offered against 49 s without, one on logs without the
/// excitation (where a biased estimate makes the search add and follow many effects) 40 s
/// alone.
pub const MAX_CHANNELS: usize = 4;

/// The range a lag's time constant `tau` is searched in, and where its fit starts.
#[derive(Debug, Clone, Copy)]
struct LagRange {
    /// Smallest `tau` searched, s.
    min_tau: f64,
    /// Longest `tau` searched, s.
    max_tau: f64,
    /// Where its fit starts, s.
    start: f64,
}

impl Default for LagRange {
    /// For a model without data (listing its candidates): `tau` from 0.1 ms to 0.5 s. The
    /// workbench sizes the bounds to the data ([`LagRange::for_data`]).
    fn default() -> Self {
        Self {
            min_tau: 1e-4,
            max_tau: 0.5,
            start: 0.01,
        }
    }
}

impl LagRange {
    /// For data at sample period `t` whose closest frequency lines are `resolution` Hz apart:
    /// `tau` from 1e-4 `t`, where the lag shifts the response by less than 2.5e-4 rad up to
    /// 0.4 times the sample rate, so the lagged model nests the one without and its fit can
    /// never be worse. (A bound fixed in seconds is not: 0.1 ms turns a 400 Hz line of 1 kHz
    /// data by 14 degrees. Nor is one of 1/40 sample: a lag-free record of 16 000 samples at
    /// high signal-to-noise saw it, and the fit with the lag ended on the bound with
    /// innovations correlated with the input.) The time-domain predictor integrates the lag
    /// exactly whatever its step, so the shortest is not stiff. Up to `1 / (2 pi resolution)`,
    /// the lag whose corner lies at the resolution, below every line the data resolve: a
    /// longer one only scales the response in the band. (A bound fixed at 0.5 s left a
    /// reactor's 3 s thermocouple lag at 1 s sampling on the bound.) The fit starts at one
    /// sample period.
    fn for_data(t: f64, resolution: f64) -> Self {
        let min_tau = 1e-4 * t;
        let max_tau = (1.0 / (2.0 * std::f64::consts::PI * resolution)).max(2.0 * t);
        Self {
            min_tau,
            max_tau,
            start: t,
        }
    }

    /// The parameter `name` over this range.
    fn parameter(&self, name: String) -> Parameter {
        Parameter::new(
            name,
            self.start.clamp(self.min_tau, self.max_tau),
            self.min_tau,
            self.max_tau,
            "s",
        )
    }
}

/// `x_a' = (u - x_a) / tau` for every input, the plant driven by `x_a`.
#[derive(Debug, Clone, Copy, Default)]
pub struct ActuatorLag(LagRange);

impl ActuatorLag {
    /// For data at sample period `t` whose closest frequency lines are `resolution` Hz apart
    /// (see [`LagRange::for_data`]). Without data ([`Default`]): `tau` from 0.1 ms to 0.5 s.
    pub fn for_data(t: f64, resolution: f64) -> Self {
        Self(LagRange::for_data(t, resolution))
    }
}

/// A lag of time constant `tau` on the inputs `lagged` of `ss`: one state `x_a` per lagged
/// input, `x_a' = (u_j - x_a) / tau`, which drives the plant (and the feed-through) in its place.
fn lag_inputs(ss: &mut StateSpace, lagged: &[usize], tau: f64) {
    let (n, m, p, q) = (ss.a.nrows(), ss.b.ncols(), ss.c.nrows(), lagged.len());
    let rate = 1.0 / tau;
    let mut a = DMatrix::zeros(n + q, n + q);
    a.view_mut((0, 0), (n, n)).copy_from(&ss.a);
    let mut b = DMatrix::zeros(n + q, m);
    b.view_mut((0, 0), (n, m)).copy_from(&ss.b);
    let mut c = DMatrix::zeros(p, n + q);
    c.view_mut((0, 0), (p, n)).copy_from(&ss.c);
    let mut d = ss.d.clone();
    for (k, &j) in lagged.iter().enumerate() {
        a.view_mut((0, n + k), (n, 1)).copy_from(&ss.b.column(j));
        a[(n + k, n + k)] = -rate;
        b.view_mut((0, j), (n, 1)).fill(0.0);
        b[(n + k, j)] = rate;
        c.view_mut((0, n + k), (p, 1)).copy_from(&ss.d.column(j));
        d.column_mut(j).fill(0.0);
    }
    ss.a = a;
    ss.b = b;
    ss.c = c;
    ss.d = d;
}

/// Which channel a [`ChannelLag`] puts behind its lag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    /// `x_a' = (u_j - x_a) / tau` drives the plant in place of input `j`: a motor slower than
    /// the others.
    Input(usize),
    /// `y_s' = (h_i(x, u) - y_s) / tau` is read in place of output `i`: a sensor's own filter
    /// (a gyro's low-pass, an estimator behind an encoder), and the closest first-order
    /// reading of a short sensor delay.
    Output(usize),
}

/// A first-order lag on one input or one output alone (`actuator_lag_<input>`, time constant
/// `tau_<input>`; `sensor_lag_<output>`, `tau_<output>`). Offered per channel when a side has
/// two to [`MAX_CHANNELS`]: with one input it is `actuator_lag`, and with one output the
/// actuator lag's twin in every response from the inputs.
#[derive(Debug, Clone)]
pub struct ChannelLag {
    channel: Channel,
    name: String,
    parameter: String,
    range: LagRange,
}

impl ChannelLag {
    /// A lag on each of `inputs`, for a model without data (`tau` from 0.1 ms to 0.5 s).
    pub fn for_inputs(inputs: &[String]) -> Vec<Self> {
        Self::each(inputs, Channel::Input, "actuator_lag", LagRange::default())
    }

    /// A lag on each of `outputs`, for a model without data.
    pub fn for_outputs(outputs: &[String]) -> Vec<Self> {
        Self::each(outputs, Channel::Output, "sensor_lag", LagRange::default())
    }

    /// A lag on each of `inputs`, over the range of [`ActuatorLag::for_data`].
    pub fn inputs_for_data(inputs: &[String], t: f64, resolution: f64) -> Vec<Self> {
        let range = LagRange::for_data(t, resolution);
        Self::each(inputs, Channel::Input, "actuator_lag", range)
    }

    /// A lag on each of `outputs`, over the range of [`ActuatorLag::for_data`].
    pub fn outputs_for_data(outputs: &[String], t: f64, resolution: f64) -> Vec<Self> {
        let range = LagRange::for_data(t, resolution);
        Self::each(outputs, Channel::Output, "sensor_lag", range)
    }

    /// One lag per channel of `names` (none unless two to [`MAX_CHANNELS`]).
    fn each(
        names: &[String],
        channel: fn(usize) -> Channel,
        effect: &str,
        range: LagRange,
    ) -> Vec<Self> {
        per_channel(names, |i, name| Self {
            channel: channel(i),
            name: format!("{effect}_{name}"),
            parameter: format!("tau_{name}"),
            range,
        })
    }
}

/// `make(index, name)` for each channel of `names`, none unless there are two to
/// [`MAX_CHANNELS`] of them.
fn per_channel<T>(names: &[String], make: impl Fn(usize, &str) -> T) -> Vec<T> {
    if !(2..=MAX_CHANNELS).contains(&names.len()) {
        return Vec::new();
    }
    names.iter().enumerate().map(|(i, n)| make(i, n)).collect()
}

/// Input `j` times `gain_<input>` where it drives the plant (`actuator_gain_<input>`): one
/// actuator weaker or stronger than documented (a worn rotor, a motor driver's scaling).
/// Offered per input with two to [`MAX_CHANNELS`] inputs; with one, its gain trades against
/// the model's own parameters. Searched from 0.2 to 5: a factor beyond is a unit (which the
/// unit hints name) more than an actuator's strength.
#[derive(Debug, Clone)]
pub struct ActuatorGain {
    input: usize,
    name: String,
    parameter: String,
}

impl ActuatorGain {
    /// A gain on each of `inputs` (none unless two to [`MAX_CHANNELS`]).
    pub fn for_inputs(inputs: &[String]) -> Vec<Self> {
        per_channel(inputs, |input, name| Self {
            input,
            name: format!("actuator_gain_{name}"),
            parameter: format!("gain_{name}"),
        })
    }
}

impl Effect for ActuatorGain {
    fn name(&self) -> &str {
        &self.name
    }

    fn description(&self) -> &str {
        "gain on one input alone (an actuator weaker or stronger than documented)"
    }

    fn parameters(&self) -> Vec<Parameter> {
        vec![Parameter::new(self.parameter.clone(), 1.0, 0.2, 5.0, "")]
    }

    fn qualified_names(&self) -> bool {
        false
    }

    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> Result<()> {
        ss.b.column_mut(self.input).scale_mut(theta[0]);
        ss.d.column_mut(self.input).scale_mut(theta[0]);
        Ok(())
    }

    fn has_dynamics(&self) -> bool {
        true
    }

    fn apply_dynamics(&self, theta: &[f64], inner: Box<dyn Dynamics>) -> Result<Box<dyn Dynamics>> {
        Ok(Box::new(EditedInputs::new(
            inner,
            InputEdit::Gain {
                input: self.input,
                gain: theta[0],
            },
        )?))
    }

    fn edits_inputs(&self) -> bool {
        true
    }
}

/// `u(t - td)` for every input, exact for fractional delays.
#[derive(Debug, Clone, Copy)]
pub struct InputDelay {
    /// Longest `td` searched, s.
    max_td: f64,
    /// Where its fit starts, s.
    start: f64,
}

impl Default for InputDelay {
    /// For a model without data: `td` up to 0.5 s. The workbench bounds it by what the data
    /// resolve ([`InputDelay::for_data`]).
    fn default() -> Self {
        Self {
            max_td: 0.5,
            start: 0.01,
        }
    }
}

impl InputDelay {
    /// For data at sample period `t` whose closest frequency lines are `resolution` Hz apart:
    /// `td` up to a quarter of `1 / resolution`. A delay turns neighbouring lines' phases
    /// apart by `2 pi resolution td`, so delays `1 / resolution` apart fit the same lines,
    /// and a Welch segment's spectrum holds the delayed relation only for a delay well inside
    /// the segment: a longer one fits any misfit and makes the residual look like
    /// segment-to-segment noise. (A cap fixed at 0.5 s hid a reactor's 3 s coolant delay.)
    /// The fit starts at one sample period.
    pub fn for_data(t: f64, resolution: f64) -> Self {
        let max_td = (0.25 / resolution).max(2.0 * t);
        Self {
            max_td,
            start: t.min(0.5 * max_td),
        }
    }
}

/// Which side of the model an [`Offsets`] shifts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// `y = h(x, u) + b` (`sensor_bias`): an encoder's zero, a gyro's offset.
    Outputs,
    /// `f(x, u + b)` where the inputs drive the plant (`input_bias`): a driver's zero, or a
    /// constant force or torque the model lacks (a cable's pull, an unbalanced mass), which
    /// the loop of an unstable plant holds with a mean input the model does not predict.
    Inputs,
}

/// One constant per channel of a side (`bias_<channel>`). Invisible to the FRF (it has no DC
/// line); the time-domain criterion, which compares signals in absolute units, sees it. On a
/// plant whose loop holds its outputs, a sensor's and an input's offset differ by the logged
/// inputs' mean (a cart-pole's angle offset moves the cart and leaves the mean force at zero, a
/// constant force on the cart is held by a mean force); with one input and one output they
/// hold the same levels.
#[derive(Debug, Clone)]
pub struct Offsets {
    side: Side,
    /// `(channel, bound)`: the offset is searched within `±bound`.
    channels: Vec<(String, f64)>,
}

impl Offsets {
    /// For the channels `names` of `side`, each offset bounded by one (in its unit).
    pub fn new(side: Side, names: &[String]) -> Self {
        Self {
            side,
            channels: names.iter().map(|n| (n.clone(), 1.0)).collect(),
        }
    }

    /// Bounds from the data: each offset within plus or minus the span of the channel's
    /// logged values (or one, for a channel that never moves).
    pub fn for_data(side: Side, data: &Dataset) -> Self {
        let range = |samples: &mut dyn Iterator<Item = f64>| {
            let (lo, hi) = samples.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
            let range = hi - lo;
            if range.is_finite() && range > 0.0 {
                range
            } else {
                1.0
            }
        };
        let channels = match side {
            Side::Outputs => data
                .outputs
                .iter()
                .enumerate()
                .map(|(i, n)| (n.clone(), range(&mut data.output_samples(i))))
                .collect(),
            Side::Inputs => data
                .inputs
                .iter()
                .enumerate()
                .map(|(j, n)| (n.clone(), range(&mut data.input_samples(j))))
                .collect(),
        };
        Self { side, channels }
    }
}

impl Effect for Offsets {
    fn name(&self) -> &str {
        match self.side {
            Side::Outputs => "sensor_bias",
            Side::Inputs => "input_bias",
        }
    }

    fn description(&self) -> &str {
        match self.side {
            Side::Outputs => "a constant offset on every output (bias_<output>)",
            Side::Inputs => {
                "a constant offset on every input where it drives the plant (bias_<input>): a driver's zero, or a constant force the model lacks"
            }
        }
    }

    fn parameters(&self) -> Vec<Parameter> {
        self.channels
            .iter()
            .map(|(c, bound)| Parameter::new(format!("bias_{c}"), 0.0, -bound, *bound, ""))
            .collect()
    }

    fn qualified_names(&self) -> bool {
        false
    }

    fn apply(&self, _theta: &[f64], _ss: &mut StateSpace) -> Result<()> {
        // A constant offset does not change a linear model's response.
        Ok(())
    }

    fn frf_visible(&self) -> bool {
        false
    }

    fn has_dynamics(&self) -> bool {
        true
    }

    fn apply_dynamics(&self, theta: &[f64], inner: Box<dyn Dynamics>) -> Result<Box<dyn Dynamics>> {
        Ok(match self.side {
            Side::Outputs => Box::new(OutputBias::new(inner, theta)?),
            Side::Inputs => Box::new(EditedInputs::new(
                inner,
                InputEdit::Offsets(theta.to_vec()),
            )?),
        })
    }

    fn edits_inputs(&self) -> bool {
        self.side == Side::Inputs
    }
}

impl Effect for ActuatorLag {
    fn name(&self) -> &str {
        "actuator_lag"
    }

    fn description(&self) -> &str {
        "first-order lag with one time constant tau on every input"
    }

    fn parameters(&self) -> Vec<Parameter> {
        vec![self.0.parameter("tau".into())]
    }

    fn qualified_names(&self) -> bool {
        false
    }

    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> Result<()> {
        let all: Vec<usize> = (0..ss.b.ncols()).collect();
        lag_inputs(ss, &all, theta[0]);
        Ok(())
    }

    fn lagged_inputs(&self, inputs: usize) -> Vec<usize> {
        (0..inputs).collect()
    }

    fn has_dynamics(&self) -> bool {
        true
    }

    fn apply_dynamics(&self, theta: &[f64], inner: Box<dyn Dynamics>) -> Result<Box<dyn Dynamics>> {
        let all = (0..inner.inputs()).collect();
        Ok(Box::new(LaggedInputs::new(inner, all, theta[0])?))
    }
}

impl Effect for ChannelLag {
    fn name(&self) -> &str {
        &self.name
    }

    fn description(&self) -> &str {
        match self.channel {
            Channel::Input(_) => {
                "first-order lag on one input alone (an actuator slower than the others)"
            }
            Channel::Output(_) => {
                "first-order lag on one output (a sensor's filter, or a short sensor delay)"
            }
        }
    }

    fn parameters(&self) -> Vec<Parameter> {
        vec![self.range.parameter(self.parameter.clone())]
    }

    fn qualified_names(&self) -> bool {
        false
    }

    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> Result<()> {
        match self.channel {
            Channel::Input(j) => lag_inputs(ss, &[j], theta[0]),
            Channel::Output(i) => lag_output(ss, i, theta[0]),
        }
        Ok(())
    }

    fn has_dynamics(&self) -> bool {
        true
    }

    /// An output's lag is not: under the predictor's held gain it also reshapes the one-step
    /// prediction of that output, which lowered the cost of a double pendulum's logs with no
    /// lag in the plant (4096-count encoders and an offset: three sensor lags added, 7, 4 and
    /// 3 %, ahead of the offset). The FRF criterion tries it, and the time criterion's verdict
    /// on a misfit names what the FRF criterion reads.
    fn searched_in_time(&self) -> bool {
        matches!(self.channel, Channel::Input(_))
    }

    fn apply_dynamics(&self, theta: &[f64], inner: Box<dyn Dynamics>) -> Result<Box<dyn Dynamics>> {
        Ok(match self.channel {
            Channel::Input(j) => Box::new(LaggedInputs::new(inner, vec![j], theta[0])?),
            Channel::Output(i) => Box::new(LaggedOutput::new(inner, i, theta[0])?),
        })
    }

    fn filters_outputs(&self) -> bool {
        matches!(self.channel, Channel::Output(_))
    }

    fn lagged_inputs(&self, _inputs: usize) -> Vec<usize> {
        match self.channel {
            Channel::Input(j) => vec![j],
            Channel::Output(_) => Vec::new(),
        }
    }
}

/// A lag of time constant `tau` on output `i` of `ss`: one state `y_s' = (C_i x + D_i u - y_s)
/// / tau`, read in place of the output.
fn lag_output(ss: &mut StateSpace, i: usize, tau: f64) {
    let (n, m, p) = (ss.a.nrows(), ss.b.ncols(), ss.c.nrows());
    let rate = 1.0 / tau;
    let mut a = DMatrix::zeros(n + 1, n + 1);
    a.view_mut((0, 0), (n, n)).copy_from(&ss.a);
    a.view_mut((n, 0), (1, n)).copy_from(&(ss.c.row(i) * rate));
    a[(n, n)] = -rate;
    let mut b = DMatrix::zeros(n + 1, m);
    b.view_mut((0, 0), (n, m)).copy_from(&ss.b);
    b.view_mut((n, 0), (1, m)).copy_from(&(ss.d.row(i) * rate));
    let mut c = DMatrix::zeros(p, n + 1);
    c.view_mut((0, 0), (p, n)).copy_from(&ss.c);
    c.row_mut(i).fill(0.0);
    c[(i, n)] = 1.0;
    ss.d.row_mut(i).fill(0.0);
    ss.a = a;
    ss.b = b;
    ss.c = c;
}

impl Effect for InputDelay {
    fn name(&self) -> &str {
        "input_delay"
    }

    fn description(&self) -> &str {
        "transport delay td of every input"
    }

    fn parameters(&self) -> Vec<Parameter> {
        vec![Parameter::new("td", self.start, 0.0, self.max_td, "s")]
    }

    fn qualified_names(&self) -> bool {
        false
    }

    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> Result<()> {
        ss.delay += theta[0];
        Ok(())
    }

    fn has_dynamics(&self) -> bool {
        true
    }

    fn apply_dynamics(&self, theta: &[f64], inner: Box<dyn Dynamics>) -> Result<Box<dyn Dynamics>> {
        Ok(Box::new(DelayedInputs::new(inner, theta[0])?))
    }
}

/// The generic effects `structure` does not declare itself (the sensor and input biases only
/// for a nonlinear structure: the linear path compares deviations, where an offset cannot
/// show).
pub fn for_structure(structure: &dyn ModelStructure) -> Vec<Arc<dyn Effect>> {
    let outputs = structure.outputs();
    let mut all: Vec<Arc<dyn Effect>> = vec![
        Arc::new(ActuatorLag::default()),
        Arc::new(InputDelay::default()),
    ];
    let inputs = structure.inputs();
    if structure.is_nonlinear() {
        all.push(Arc::new(Offsets::new(Side::Outputs, &outputs)));
        all.push(Arc::new(Offsets::new(Side::Inputs, &inputs)));
    }
    let lags = ChannelLag::for_inputs(&inputs);
    for lag in lags.into_iter().chain(ChannelLag::for_outputs(&outputs)) {
        all.push(Arc::new(lag));
    }
    for gain in ActuatorGain::for_inputs(&inputs) {
        all.push(Arc::new(gain));
    }
    undeclared(structure, all)
}

/// The generic effects sized to the data, for those `structure` does not declare: the
/// offsets within each output's and input's logged range (nonlinear structure), and the lag's and the
/// delay's ranges from the sample period and the data's frequency resolution: the closest
/// spacing of the lines, `line_spacing` Hz, or with fewer than two lines one over the
/// shortest record. Both criteria search the same ranges.
pub fn for_data(
    structure: &dyn ModelStructure,
    data: &Dataset,
    line_spacing: f64,
) -> Vec<Arc<dyn Effect>> {
    let h = 1.0 / data.sample_rate_hz;
    let resolution = if line_spacing > 0.0 {
        line_spacing
    } else {
        let shortest = data
            .experiments
            .iter()
            .map(|e| e.u.nrows())
            .min()
            .unwrap_or(1)
            .max(1);
        data.sample_rate_hz / shortest as f64
    };
    let mut all: Vec<Arc<dyn Effect>> = Vec::new();
    if structure.is_nonlinear() {
        all.push(Arc::new(Offsets::for_data(Side::Outputs, data)));
        all.push(Arc::new(Offsets::for_data(Side::Inputs, data)));
    }
    all.push(Arc::new(ActuatorLag::for_data(h, resolution)));
    all.push(Arc::new(InputDelay::for_data(h, resolution)));
    let lags = ChannelLag::inputs_for_data(&data.inputs, h, resolution);
    for lag in lags
        .into_iter()
        .chain(ChannelLag::outputs_for_data(&data.outputs, h, resolution))
    {
        all.push(Arc::new(lag));
    }
    for gain in ActuatorGain::for_inputs(&data.inputs) {
        all.push(Arc::new(gain));
    }
    undeclared(structure, all)
}

/// The effects of `all` that `structure` does not declare under the same name.
fn undeclared(structure: &dyn ModelStructure, all: Vec<Arc<dyn Effect>>) -> Vec<Arc<dyn Effect>> {
    let own = structure.effects();
    all.into_iter()
        .filter(|e| !own.iter().any(|o| o == e.name()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectra::C64;

    fn plant() -> StateSpace {
        StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 4.0, -0.3]),
            b: DMatrix::from_row_slice(2, 1, &[0.0, 2.0]),
            c: DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 1.0]),
            d: DMatrix::from_row_slice(2, 1, &[0.0, 0.5]),
            delay: 0.0,
        }
    }

    /// An input's gain multiplies its column of the response and nothing else, and commutes
    /// with a lag on the same input (the nonlinear model applies it inside the lag).
    #[test]
    fn an_actuator_gain_scales_its_column_alone() {
        let names = ["p".to_string(), "v".to_string()];
        let mut two = plant();
        two.b = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 2.0, 0.5]);
        two.d = DMatrix::from_row_slice(2, 2, &[0.0, 0.3, 0.5, 0.2]);
        let (gain, tau) = (0.85, 0.02);
        let effect = &ActuatorGain::for_inputs(&names)[1];
        assert_eq!(effect.name(), "actuator_gain_v");
        let mut scaled = two.clone();
        effect.apply(&[gain], &mut scaled).unwrap();
        let lag = &ChannelLag::for_inputs(&names)[1];
        let (mut gain_then_lag, mut lag_then_gain) = (scaled.clone(), two.clone());
        lag.apply(&[tau], &mut gain_then_lag).unwrap();
        lag.apply(&[tau], &mut lag_then_gain).unwrap();
        effect.apply(&[gain], &mut lag_then_gain).unwrap();
        let freqs = [0.1, 0.7, 3.0, 11.0];
        let g = two.frf_lines(&freqs, None).unwrap();
        let gs = scaled.frf_lines(&freqs, None).unwrap();
        let a = gain_then_lag.frf_lines(&freqs, None).unwrap();
        let b = lag_then_gain.frf_lines(&freqs, None).unwrap();
        for k in 0..freqs.len() {
            for i in 0..2 {
                assert!((gs[k][(i, 0)] - g[k][(i, 0)]).norm() < 1e-12);
                assert!((gs[k][(i, 1)] - g[k][(i, 1)] * gain).norm() < 1e-12);
                assert!((a[k][(i, 1)] - b[k][(i, 1)]).norm() < 1e-12);
            }
        }
        assert!(ActuatorGain::for_inputs(&names[..1]).is_empty());
    }

    /// The lagged response is the plant's times `1 / (1 + j w tau)` (closed form), and the
    /// delayed one times `e^{-j w td}`, on every entry; a sensor lag's only on its output's row,
    /// a single input's lag only on its input's column.
    #[test]
    fn lag_and_delay_multiply_the_response_by_their_closed_forms() {
        let (tau, td) = (0.037, 0.0123);
        let mut lagged = plant();
        ActuatorLag::default().apply(&[tau], &mut lagged).unwrap();
        lagged.check().unwrap();
        let mut delayed = plant();
        InputDelay::default().apply(&[td], &mut delayed).unwrap();
        // A lag on the second output, which has a feed-through.
        let names = ["p".to_string(), "v".to_string()];
        let mut sensed = plant();
        ChannelLag::for_outputs(&names)[1]
            .apply(&[tau], &mut sensed)
            .unwrap();
        sensed.check().unwrap();
        let freqs = [0.1, 0.7, 3.0, 11.0];
        let g0 = plant().frf_lines(&freqs, None).unwrap();
        let gl = lagged.frf_lines(&freqs, None).unwrap();
        let gd = delayed.frf_lines(&freqs, None).unwrap();
        let gs = sensed.frf_lines(&freqs, None).unwrap();
        for (k, f) in freqs.iter().enumerate() {
            let w = 2.0 * std::f64::consts::PI * f;
            let lag = C64::new(1.0, w * tau).inv();
            let delay = C64::new(0.0, -w * td).exp();
            for i in 0..2 {
                assert!((gl[k][(i, 0)] - g0[k][(i, 0)] * lag).norm() < 1e-10);
                assert!((gd[k][(i, 0)] - g0[k][(i, 0)] * delay).norm() < 1e-12);
            }
            assert!((gs[k][(0, 0)] - g0[k][(0, 0)]).norm() < 1e-12);
            assert!((gs[k][(1, 0)] - g0[k][(1, 0)] * lag).norm() < 1e-10);
        }
        // With one output a sensor lag is the actuator lag's twin: none is offered.
        assert!(ChannelLag::for_outputs(&names[..1]).is_empty());
        // A lag on the second of two inputs, each with a feed-through: only its column.
        let mut two = plant();
        two.b = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 2.0, 0.5]);
        two.d = DMatrix::from_row_slice(2, 2, &[0.0, 0.3, 0.5, 0.2]);
        let mut slow = two.clone();
        ChannelLag::for_inputs(&names)[1]
            .apply(&[tau], &mut slow)
            .unwrap();
        slow.check().unwrap();
        let g2 = two.frf_lines(&freqs, None).unwrap();
        let gi = slow.frf_lines(&freqs, None).unwrap();
        for (k, f) in freqs.iter().enumerate() {
            let lag = C64::new(1.0, 2.0 * std::f64::consts::PI * f * tau).inv();
            for i in 0..2 {
                assert!((gi[k][(i, 0)] - g2[k][(i, 0)]).norm() < 1e-12);
                assert!((gi[k][(i, 1)] - g2[k][(i, 1)] * lag).norm() < 1e-10);
            }
        }
        assert!(ChannelLag::for_inputs(&names[..1]).is_empty());
        // Up to MAX_CHANNELS channels a side get one each, more get none.
        let many: Vec<String> = (0..=MAX_CHANNELS).map(|i| format!("c{i}")).collect();
        let most = &many[..MAX_CHANNELS];
        assert_eq!(ChannelLag::for_outputs(most).len(), MAX_CHANNELS);
        assert_eq!(ChannelLag::for_inputs(most).len(), MAX_CHANNELS);
        assert!(
            ChannelLag::for_outputs(&many).is_empty() && ChannelLag::for_inputs(&many).is_empty()
        );
    }

    /// The lag's and the delay's ranges follow the sample period `t` and the resolution `r`:
    /// tau from 1e-4 t to 1 / (2 pi r), td up to 1 / (4 r), both starting at one sample and
    /// reaching at least two (closed forms).
    #[test]
    fn the_lag_and_delay_ranges_follow_the_data() {
        let range = |p: Vec<Parameter>| (p[0].value, p[0].lower, p[0].upper);
        // A reactor sampled at 1 s with 200 s periods: beyond the old 0.5 s.
        let (v, lo, hi) = range(ActuatorLag::for_data(1.0, 0.005).parameters());
        assert_eq!((v, lo), (1.0, 1e-4));
        assert!((hi - 100.0 / std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(
            range(InputDelay::for_data(1.0, 0.005).parameters()),
            (1.0, 0.0, 50.0)
        );
        // 1 kHz logs with 0.5 Hz lines.
        let (v, lo, hi) = range(ActuatorLag::for_data(1e-3, 0.5).parameters());
        assert_eq!(v, 1e-3);
        assert!((lo - 1e-7).abs() < 1e-20);
        assert!((hi - 1.0 / std::f64::consts::PI).abs() < 1e-12);
        assert_eq!(
            range(InputDelay::for_data(1e-3, 0.5).parameters()),
            (1e-3, 0.0, 0.5)
        );
        // Lines as coarse as the sample rate still leave two samples of range.
        assert_eq!(
            range(InputDelay::for_data(0.01, 100.0).parameters()),
            (0.01, 0.0, 0.02)
        );
        assert_eq!(
            range(ActuatorLag::for_data(0.01, 100.0).parameters()).2,
            0.02
        );
    }

    /// A model whose own parameter is called `tau` keeps it; the generic lag's becomes
    /// `actuator_lag.tau`, and both can be fitted together.
    #[test]
    fn a_taken_parameter_name_is_qualified() {
        let text = "name = \"p\"\nstates = [\"x\"]\ninputs = [\"u\"]\noutputs = [\"x\"]\n\
                    [parameters]\ntau = { value = 0.5, min = 0.01 }\n\
                    [linear]\nA = [[\"-1/tau\"]]\nB = [[1]]\nC = [[1]]\n";
        let file = crate::ModelFile::parse(text, std::path::Path::new("p.toml")).unwrap();
        let model = crate::Model::new(Arc::new(file))
            .with_effect("actuator_lag")
            .unwrap();
        let names: Vec<String> = model
            .parameters()
            .unwrap()
            .into_iter()
            .map(|p| p.name)
            .collect();
        assert_eq!(names, ["tau", "actuator_lag.tau"]);
        let ss = model.state_space(&[0.5, 0.02]).unwrap();
        assert_eq!(ss.a.shape(), (2, 2));
        assert_eq!(ss.a[(1, 1)], -50.0);
    }
}
