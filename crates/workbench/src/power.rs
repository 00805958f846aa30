//! Detection power before the experiment: how large an effect must be for the discovery to
//! find it with this excitation, this noise and this many periods, and how often it finds
//! something that is not there.
//!
//! A study ([`StudySpec`]) is prepared once from a model file with a `[controller]` and the
//! user's logs ([`prepare`]): the nominal model fitted to the logs (the `compare` step), the
//! noise level estimated from them (the stationary Kalman predictor's covariances,
//! [`super::kalman`]: process noise per sample and white sensor noise), and the logged
//! excitation of each experiment. A campaign ([`Study::campaign`]) is then a pure function of
//! the spec, the value index and the campaign index: the fitted nominal model plus the effect at
//! that value, sampled with a zero-order hold at the logs' rate, runs in closed loop with the
//! file's controller from zero states, driven by each experiment's excitation (same lengths,
//! same number of experiments, same periodic layout), with Gaussian process and sensor noise of
//! the estimated covariances (scaled to the logs' period-to-period noise,
//! [`calibration_factors`], then along the effect where it hides the effect otherwise than the
//! logs' noise does, [`size_along_effect`], and compared with the logs' per output and band,
//! [`Study::noise_check`], which warns where they differ); the full discovery then runs on the
//! simulated logs. The spec is
//! plain JSON (model-file text and excitation arrays, no paths), so campaigns run anywhere: in
//! threads here ([`run`]) or in Dask tasks through the Python package. Outcomes are aggregated
//! in one place ([`aggregate`]), whatever ran them.
//!
//! Random numbers: campaign `c` of value `i` draws from ChaCha8 keyed by `seed`
//! (`seed_from_u64`) on stream `(i << 32) | c`, in sample order: per sample, the process noise
//! (one standard normal per state, times a square root of its covariance), then the sensor
//! noise (one per output, times its standard deviation), experiment after experiment. The
//! results are therefore identical to the bit for the same spec and seed however the campaigns
//! are scheduled.
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::cancel::Cancel;
use super::closed_loop::{controller_rate, growth, run_loop, GROWTH};
use super::dataset::{Dataset, Experiment, Periodic};
use super::diagnose::LEVEL;
use super::discover::in_parallel;
use super::kalman::{Gain, Predictor};
use super::model::Model;
use super::model_file::ModelFile;
use super::prediction::simulate_closed_loop;
use super::report::fmt_num;
use super::stats::clopper_pearson;
use super::timedomain::{demeaned, Discrete};
use super::{Criterion, DataOptions, EstimatorChoice, Workbench};
use crate::error::{Result, SimError};

/// Power the reverse question asks for: the smallest value detected this often.
pub const TARGET_POWER: f64 = 0.95;

/// One minus the confidence of the binomial intervals (95 %).
pub const ALPHA: f64 = 0.05;

/// The excitation of one logged experiment, as the simulated campaign replays it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Excitation {
    /// The log's name.
    pub name: String,
    /// Excitation per sample (rows) and input (columns).
    pub r: Vec<Vec<f64>>,
    /// Periodic layout `(period, periods, transient)` from the log's metadata, if any.
    pub periodic: Option<(usize, usize, usize)>,
}

/// Everything a campaign needs, as plain data: the study is this and nothing else.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudySpec {
    /// The model file's text.
    pub model_text: String,
    /// Its path, for messages only (never read by a campaign).
    pub model_path: String,
    /// The effect whose power is studied.
    pub effect: String,
    /// Its parameter set to each value.
    pub parameter: String,
    /// The parameter's unit as the model gives it (empty: none given).
    #[serde(default)]
    pub unit: String,
    /// Values of the parameter, increasing; 0 is the effect absent (the nominal model).
    pub values: Vec<f64>,
    /// The parameter's bounds in the model sized to the logs, which the values are checked
    /// against (a campaign's discovery sizes the candidates to its own logs again).
    pub bounds: [f64; 2],
    /// Campaigns per value.
    pub campaigns: usize,
    /// Seed of every campaign's random numbers.
    pub seed: u64,
    /// The nominal model's parameters fitted to the logs, by name.
    pub nominal: Vec<(String, f64)>,
    /// Process-noise covariance per sample, rows of the nominal model's states.
    pub process_noise: Vec<Vec<f64>>,
    /// Sensor-noise variance per output.
    pub sensor_noise: Vec<f64>,
    /// Sample rate of the logs, Hz.
    pub sample_rate_hz: f64,
    /// The experiments' excitations.
    pub experiments: Vec<Excitation>,
    /// FRF estimator of the discovery: `auto`, `ls` or `iv`.
    pub estimator: String,
    /// Welch band of the discovery, if the user fixed one.
    pub band_hz: Option<(f64, f64)>,
    /// The discovery's criterion, if the user chose one (`None`: the default for the model,
    /// the prediction error for a nonlinear one).
    #[serde(default)]
    pub criterion: Option<Criterion>,
    /// Period-to-period noise rms per output of the logs ([`period_noise_rms`]), to compare
    /// the simulated campaigns' with; `None` for logs that are not periodic.
    pub measured_noise_rms: Option<Vec<f64>>,
    /// The factors `(process, sensor)` the Kalman estimate's covariances were scaled by so
    /// that the simulated period-to-period noise matches the logs' (`None`: not periodic, not
    /// scaled).
    pub noise_calibration: Option<(f64, Vec<f64>)>,
    /// Where the calibrated simulation's noise is not the logs' ([`Study::noise_check`]).
    #[serde(default)]
    pub noise_warnings: Vec<NoiseWarning>,
    /// The process noise's colour when it is not white ([`NoiseShape`]; `None`: white, as
    /// the Kalman estimate takes it).
    #[serde(default)]
    pub process_noise_shape: Option<NoiseShape>,
    /// How precisely a fit sizes the parameter on the logs and on the simulated records
    /// ([`Study::sizing`]; `None` in a spec written before it was computed).
    #[serde(default)]
    pub sizing: Option<Sizing>,
}

/// A low-pass process noise: each sample's draw of the estimated covariance passed through a
/// first-order filter of unit gain in variance, `w[k] = a w[k-1] + sqrt(1 - a^2) e[k]`,
/// `a = exp(-T / correlation_s)`, stationary from the first sample. A gust or a ground
/// vibration is coloured, while the Kalman estimate is of white noise; calibrated to the
/// logs' total noise, white noise then puts too much of it above the disturbance's corner and
/// too little below (a bicycle's gust of 0.2 s: 1.7-4.6 times the logged noise above 2.5 Hz),
/// and the study misjudges the effects acting there. [`prepare`] chooses the correlation time
/// whose simulated spectrum across the excited band is the logs'.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseShape {
    /// Correlation time, s.
    pub correlation_s: f64,
    /// The band mismatch of this colour and of white noise: the sum over outputs and bands of
    /// the noise check of `dof / 2 ln^2(simulated / logged)` (about one per term when the
    /// spectra agree, `dof` the band's degrees of freedom, [`band_dof`]).
    pub mismatch: f64,
    /// The same for white process noise.
    pub white_mismatch: f64,
    /// Outputs times bands the mismatch sums over.
    pub terms: usize,
}

impl StudySpec {
    /// Every campaign of the study, `(value index, campaign index)`, in order.
    pub fn jobs(&self) -> Vec<(usize, usize)> {
        (0..self.values.len())
            .flat_map(|i| (0..self.campaigns).map(move |c| (i, c)))
            .collect()
    }
}

/// What the discovery made of one simulated campaign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// Index of the value.
    pub value_index: usize,
    /// Index of the campaign at that value.
    pub campaign: usize,
    /// The studied effect is among the found.
    pub found: bool,
    /// The other effects found.
    pub other_found: Vec<String>,
    /// The discovery reported an unexplained structured misfit.
    pub unexplained: bool,
    /// The discovery added the studied effect but left it tentative (a rival fits as well, or
    /// a caveat speaks against it): seen, not confirmed.
    #[serde(default)]
    pub tentative: bool,
    /// The studied parameter's estimate when the effect was found.
    pub estimate: Option<f64>,
    /// Why the campaign failed (a diverged loop, a failed fit); the rest is then empty.
    pub error: Option<String>,
    /// Period-to-period noise rms per output of the simulated logs.
    pub noise_rms: Option<Vec<f64>>,
}

fn estimator_choice(name: &str) -> Result<EstimatorChoice> {
    match name {
        "auto" => Ok(EstimatorChoice::Auto),
        "ls" => Ok(EstimatorChoice::LeastSquares),
        "iv" => Ok(EstimatorChoice::InstrumentalVariable),
        other => Err(SimError::invalid(
            "estimator",
            other,
            "must be auto, ls or iv",
        )),
    }
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

fn matrix(what: &str, rows: &[Vec<f64>], ncols: usize) -> Result<DMatrix<f64>> {
    if let Some(bad) = rows.iter().position(|r| r.len() != ncols) {
        return Err(SimError::LengthMismatch {
            what: format!("{what}, row {bad}"),
            expected: ncols,
            found: rows[bad].len(),
        });
    }
    Ok(DMatrix::from_fn(rows.len(), ncols, |i, j| rows[i][j]))
}

/// The inputs of a study: what [`prepare`] needs besides the model file and the logs.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    /// The effect (declared in the file, or `actuator_lag` / `input_delay`).
    pub effect: String,
    /// Values of its parameter, increasing and within its bounds.
    pub values: Vec<f64>,
    /// Campaigns per value.
    pub campaigns: usize,
    /// Seed.
    pub seed: u64,
    /// FRF estimator of the discovery (`auto`, `ls`, `iv`).
    pub estimator: String,
    /// Welch band, Hz, when the user fixes one.
    pub band_hz: Option<(f64, f64)>,
    /// The discovery's criterion; `None`: its default for the model.
    pub criterion: Option<Criterion>,
    /// Stops the preparation at its next fit iteration or simulation (Ctrl-C in Python):
    /// `prepare` then returns [`SimError::Cancelled`].
    pub cancel: Cancel,
}

/// Prepares a study from the model file's text (`model_path` names it in messages) and the
/// logs: fits the nominal model, estimates the noise, keeps the excitation.
pub fn prepare(
    model_text: &str,
    model_path: &Path,
    data: Dataset,
    options: &StudyOptions,
) -> Result<StudySpec> {
    let structure = Arc::new(ModelFile::parse(model_text, model_path)?);
    let controller =
        super::model::ModelStructure::controller(structure.as_ref()).ok_or_else(|| {
            SimError::invalid(
            "controller",
            model_path.display(),
            "a power study simulates the closed loop: the model file needs a [controller] section",
        )
        })?;
    let rate = controller_rate(&controller);
    if (rate - data.sample_rate_hz).abs() > 1e-9 * rate {
        return Err(SimError::invalid(
            "controller.sample_rate_hz",
            rate,
            format!(
                "the logs are sampled at {} Hz; they must agree",
                data.sample_rate_hz
            ),
        ));
    }
    if let Some(e) = data.experiments.iter().find(|e| e.r.is_none()) {
        return Err(SimError::invalid(
            "data",
            &e.name,
            format!(
                "logs no excitation (MCAP topic /{}/excitation, CSV columns r_<input>): a power \
                 study replays it",
                super::model::ModelStructure::system(structure.as_ref())
            ),
        ));
    }
    if options.campaigns == 0 {
        return Err(SimError::invalid("campaigns", 0, "must be at least 1"));
    }
    let mut wb = Workbench::with_options(
        structure.clone(),
        data,
        estimator_choice(&options.estimator)?,
        DataOptions {
            band_hz: options.band_hz,
            criterion: options.criterion,
        },
    )?;
    wb.set_cancel(options.cancel.clone());
    let nominal_model = wb.model().clone();
    let names: Vec<String> = nominal_model
        .parameters()?
        .into_iter()
        .map(|p| p.name)
        .collect();
    let with = nominal_model.with_effect(&options.effect)?;
    let added: Vec<_> = with
        .parameters()?
        .into_iter()
        .filter(|p| !names.contains(&p.name))
        .collect();
    let parameter = match added.as_slice() {
        [one] => one.clone(),
        other => {
            return Err(SimError::invalid(
                "effect",
                &options.effect,
                format!(
                    "a power study sets one parameter to each value; this effect has {} ({})",
                    other.len(),
                    other
                        .iter()
                        .map(|p| p.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ))
        }
    };
    let bounds = [parameter.lower, parameter.upper];
    check_values(&options.values, &parameter.name, bounds)?;
    let step = wb.compare()?;
    let nominal_p = wb.noise_p_value(&step);
    let ss = nominal_model.state_space(&step.theta)?;
    let disc = ss.discretize(1.0 / wb.data().sample_rate_hz)?;
    let centred: Vec<(DMatrix<f64>, DMatrix<f64>)> = wb
        .data()
        .experiments
        .iter()
        .map(|e| (demeaned(&e.u), demeaned(&e.y)))
        .collect();
    let pairs: Vec<(&DMatrix<f64>, &DMatrix<f64>)> = centred.iter().map(|(u, y)| (u, y)).collect();
    options.cancel.check()?;
    let predictor = Predictor::design(&disc, &pairs, Gain::NoiseModel)?;
    options.cancel.check()?;
    let (q, r) = predictor.covariances().ok_or_else(|| {
        SimError::invalid(
            "model",
            model_path.display(),
            "has states its outputs do not observe; a power study needs the noise of every \
             state (the Kalman estimate covers the observable ones only)",
        )
    })?;
    let data = wb.data();
    let mut spec = StudySpec {
        model_text: model_text.to_string(),
        model_path: model_path.display().to_string(),
        effect: options.effect.clone(),
        parameter: parameter.name,
        unit: parameter.unit,
        values: options.values.clone(),
        bounds,
        campaigns: options.campaigns,
        seed: options.seed,
        nominal: names.into_iter().zip(step.theta).collect(),
        process_noise: rows(q),
        sensor_noise: r.diagonal().iter().copied().collect(),
        sample_rate_hz: data.sample_rate_hz,
        experiments: data
            .experiments
            .iter()
            .map(|e| Excitation {
                name: e.name.clone(),
                r: e.r.as_ref().map(rows).unwrap_or_default(),
                periodic: e.periodic.map(|p| (p.period, p.periods, p.transient)),
            })
            .collect(),
        estimator: options.estimator.clone(),
        band_hz: options.band_hz,
        criterion: options.criterion,
        measured_noise_rms: period_noise_rms(data),
        noise_calibration: None,
        noise_warnings: Vec::new(),
        process_noise_shape: None,
        sizing: None,
    };
    let band = options
        .band_hz
        .or_else(|| super::welch::excited_band(data).ok());
    if let Some(measured) = spec.measured_noise_rms.clone() {
        let bands = band.map_or_else(Vec::new, |b| noise_bands(data, b));
        let logged = band_noise(data, &bands).filter(|_| !bands.is_empty());
        let dof: Vec<usize> = bands.iter().map(|b| band_dof(data, *b)).collect();
        let study = Study::new(spec.clone())?;
        let sensors = study.sensor_power(&bands, &options.cancel)?;
        let (mut factors, white_mismatch) = calibrate(
            &measured,
            &study.process_power(&bands, &options.cancel)?,
            &sensors,
            logged.as_ref(),
            &dof,
        )?;
        // The process noise's colour: the correlation time whose calibrated spectrum is the
        // logs' across the excited band, when it fits clearly better than white noise.
        if let Some(logged) = &logged {
            let mut best: Option<NoiseShape> = None;
            for correlation_s in correlation_times(&bands) {
                options.cancel.check()?;
                let mut trial = spec.clone();
                let shape = NoiseShape {
                    correlation_s,
                    mismatch: f64::INFINITY,
                    white_mismatch,
                    terms: logged.len(),
                };
                trial.process_noise_shape = Some(shape.clone());
                let process = Study::new(trial)?.process_power(&bands, &options.cancel)?;
                let (f, mismatch) = calibrate(&measured, &process, &sensors, Some(logged), &dof)?;
                let bar = best
                    .as_ref()
                    .map_or(white_mismatch - NOISE_SHAPE_GAIN, |b| b.mismatch);
                if mismatch < bar {
                    best = Some(NoiseShape { mismatch, ..shape });
                    factors = f;
                }
            }
            spec.process_noise_shape = best;
        }
        let (cq, cr) = factors;
        spec.process_noise
            .iter_mut()
            .flatten()
            .for_each(|q| *q *= cq);
        spec.sensor_noise
            .iter_mut()
            .zip(&cr)
            .for_each(|(r, c)| *r *= c);
        spec.noise_calibration = Some((cq, cr));
    }
    size_along_effect(&mut spec, data, nominal_p, &options.cancel)?;
    options.cancel.check()?;
    spec.noise_warnings = Study::new(spec.clone())?.noise_check(data, band, &options.cancel)?;
    Ok(spec)
}

/// Sets the spec's sizing ([`Study::sizing`]) on `logs`, which the nominal model explains
/// with the probability `nominal_p` under noise alone (the cost test of `compare`). Along the
/// effect the logs' own fit says how much the noise hides it: where the spec's noise hides it
/// otherwise ([`Sizing::noise_scale`]), every noise source is scaled by that amplitude factor
/// and the sizing is measured again on the scaled noise. Calibrated to the logs'
/// period-to-period deviations alone, a cart-pole's noise under ten times the pole torque
/// disturbance hid the cart's friction 2.6 times as much as the logs' noise does, and the
/// study found b = 0.1 in 0 of 20 campaigns where independent records found it in 40 of 40.
/// Only noise widens the logs' error when the nominal model explains them (`nominal_p` at
/// least the discovery's level); a misfit widens it too (an unmodelled friction made a lag's
/// error 5.6 times the simulated records'), and then the study warns and does not scale.
pub fn size_along_effect(
    spec: &mut StudySpec,
    logs: &Dataset,
    nominal_p: f64,
    cancel: &Cancel,
) -> Result<()> {
    let mut sizing = Study::new(spec.clone())?.sizing(logs, cancel)?;
    let explained = nominal_p >= LEVEL;
    if sizing.noise_scale().is_some() && !explained {
        sizing.warnings.push(format!(
            "the nominal model leaves a structured misfit in the logs ({} for its cost under \
             noise alone), which widens the logs' error of {} as noise would: the study does \
             not scale its noise along {}",
            super::stats::p_equals(nominal_p),
            spec.parameter,
            spec.effect
        ));
    }
    spec.sizing = Some(match (sizing.noise_scale(), sizing.simulated_std) {
        (Some(factor), Some(unscaled_std)) if explained => {
            spec.process_noise
                .iter_mut()
                .flatten()
                .for_each(|q| *q *= factor * factor);
            spec.sensor_noise
                .iter_mut()
                .for_each(|r| *r *= factor * factor);
            let mut scaled = Study::new(spec.clone())?.sizing(logs, cancel)?;
            scaled.rescaled = Some(Rescale {
                factor,
                unscaled_std,
            });
            scaled.warn(&spec.effect, &spec.parameter, &spec.unit, &spec.values);
            scaled
        }
        _ => sizing,
    });
    Ok(())
}

/// The rms per output of the deviation of each period from the mean period (the noise a
/// periodic FRF estimate sees), pooled over the experiments and corrected for the mean's own
/// share (`P / (P - 1)` for `P` periods); `None` unless every experiment is periodic.
pub fn period_noise_rms(data: &Dataset) -> Option<Vec<f64>> {
    let (layouts, _) = data.periodic_layouts()?;
    let (mut sum, mut count) = (vec![0.0; data.outputs.len()], 0usize);
    for (e, l) in data.experiments.iter().zip(&layouts) {
        let periods = l.periods as f64;
        for (i, total) in sum.iter_mut().enumerate() {
            for k in 0..l.period {
                let at = |j: usize| e.y[(l.transient + j * l.period + k, i)];
                let mean = (0..l.periods).map(at).sum::<f64>() / periods;
                *total += (0..l.periods).map(|j| (at(j) - mean).powi(2)).sum::<f64>()
                    * (periods / (periods - 1.0));
            }
        }
        count += l.period * l.periods;
    }
    Some(
        sum.iter()
            .map(|s| (s / count.max(1) as f64).sqrt())
            .collect(),
    )
}

/// An output, and optionally a frequency band of it, whose simulated period-to-period noise
/// is not the logs' after the calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseWarning {
    /// The output.
    pub output: String,
    /// The band, Hz; `None` for the whole noise.
    pub band_hz: Option<[f64; 2]>,
    /// Simulated over logged rms.
    pub ratio: f64,
    /// The warning for people.
    pub message: String,
}

/// How precisely a fit of the model with the effect sizes the studied parameter, on the logs
/// and on the study's own simulated records of the nominal model. No test tells a value within
/// about two standard errors of 0 from noise (the discovery asks more: a cart-pole's friction
/// is found 19 times in 20 at 7), so the two errors say before any campaign whether the values
/// studied can be found at all, and whether the simulated noise hides the effect as the
/// logged noise does, which scales every rate's threshold: the band noise check compares
/// spectra per output, this compares the noise along the effect itself (on a reaction-wheel
/// pendulum disturbed by a torque on its body, where the model's noise enters at its input,
/// the band check warned both ways at once, and the logs hid a pivot friction about twice as
/// much as the study's noise).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sizing {
    /// The parameter's estimate in the fit to the logs; `None` when that fit failed (the
    /// study runs without a sizing, and a warning says why).
    pub logs_estimate: Option<f64>,
    /// Its standard error there; `None` when the fit held it at its documented value (the
    /// logs cannot separate it from the other parameters).
    pub logs_std: Option<f64>,
    /// The median of its standard errors in the same fit to [`SIZING_DRAWS`] simulated
    /// records of the nominal model (random stream `u64::MAX - 2`); `None` when a fit held
    /// it or failed.
    pub simulated_std: Option<f64>,
    /// The parameters the outputs cannot tell the studied one from, in the model with the
    /// effect at the logs' fit ([`super::identifiability`]): a refit of these absorbs the
    /// effect whatever its size.
    #[serde(default)]
    pub trades_against: Vec<String>,
    /// The amplitude factor the study's noise was scaled by so that its simulated records
    /// size the parameter as the logs do ([`Sizing::noise_scale`]), and the simulated
    /// records' standard error before it; `None`: not scaled.
    #[serde(default)]
    pub rescaled: Option<Rescale>,
    /// What they say about the study, for people (empty: nothing to say).
    pub warnings: Vec<String>,
}

/// The study's noise scaled along the effect ([`prepare`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rescale {
    /// Amplitude factor of every noise source (process and sensor, the covariances by its
    /// square).
    pub factor: f64,
    /// The simulated records' standard error of the parameter before the scaling.
    pub unscaled_std: f64,
}

/// Simulated records whose fits give [`Sizing::simulated_std`]. The standard error of one
/// record varies by 10-20 % from draw to draw; the median of five by about half that.
pub const SIZING_DRAWS: usize = 5;

/// How many of the logs' standard errors the largest value studied must lie from 0: below it
/// no campaign is likely to tell the effect from noise, whatever the discovery.
pub const SIZED_APART: f64 = 2.0;

/// How far the simulated records' standard error may be from the logs', as a factor either
/// way, before the study warns that its noise hides the effect more or less than the logs'.
pub const SIZING_TOLERANCE: f64 = 1.5;

/// `" unit"` after a number, or nothing when the model gives no unit.
fn unit_suffix(unit: &str) -> String {
    if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    }
}

impl Sizing {
    /// The amplitude factor that would give the simulated records the logs' standard error,
    /// when they differ by more than [`SIZING_TOLERANCE`] and the parameter can be sized
    /// apart from the others: the noise calibrated to the logs' period-to-period deviations
    /// then hides the effect more or less than the logged noise does, because it enters in
    /// other directions (the standard error of a fit scales with the noise's amplitude). Within
    /// the tolerance the two agree up to the 10-20 % by which one record's error varies, and
    /// the calibration stands.
    pub fn noise_scale(&self) -> Option<f64> {
        let ratio = self.logs_std? / self.simulated_std?;
        (self.trades_against.is_empty()
            && ratio.is_finite()
            && ratio > 0.0
            && !(1.0 / SIZING_TOLERANCE..=SIZING_TOLERANCE).contains(&ratio))
        .then_some(ratio)
    }

    /// The warnings for `values` of `parameter` (its `unit`, possibly empty) of `effect`.
    fn warn(&mut self, effect: &str, parameter: &str, unit: &str, values: &[f64]) {
        self.warnings.clear();
        let unit = unit_suffix(unit);
        if !self.trades_against.is_empty() {
            self.warnings.push(format!(
                "the outputs cannot tell {parameter} from {} (the identifiability analysis of \
                 the model with {effect}): a refit of the model absorbs {effect} at any size, so \
                 no value studied can be found as {effect}",
                self.trades_against.join(", ")
            ));
            return;
        }
        let Some(logs) = self.logs_std else {
            self.warnings.push(format!(
                "the logs cannot size {parameter}: a fit of the model with {effect} to them holds \
                 it at its documented value (the outputs cannot tell it from the other \
                 parameters with this excitation), so a campaign that sees {effect} cannot \
                 measure it; the detection rates say how often a held effect is found"
            ));
            return;
        };
        // A study of the value 0 alone asks for its false discoveries only.
        let largest = values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        if largest > 0.0 && largest < SIZED_APART * logs {
            self.warnings.push(format!(
                "the largest value studied, {parameter} = {}{unit}, is {:.2} standard errors \
                 from 0 where a fit of the model with {effect} to the logs sizes it to ±{}{unit}: \
                 no value studied is likely to be told from noise (from about {}{unit}, \
                 {SIZED_APART} standard errors, it may)",
                fmt_num(largest),
                largest / logs,
                fmt_num(logs),
                fmt_num(SIZED_APART * logs)
            ));
        }
        if let (Some(r), Some(sim)) = (&self.rescaled, self.simulated_std) {
            let how = if r.factor < 1.0 { "more" } else { "less" };
            self.warnings.push(format!(
                "a fit of the model with {effect} sized {parameter} to ±{}{unit} on the study's \
                 simulated records and to ±{}{unit} on the logs: the study's noise hid {effect} \
                 {how} than the logged noise does (it enters {how} along the effect), so the \
                 study scales every noise source by {} in amplitude, after which its records size \
                 {parameter} to ±{}{unit}: its rates follow the logs' noise along {effect}, and \
                 the noise check compares the scaled noise with the logs'",
                fmt_num(r.unscaled_std),
                fmt_num(logs),
                fmt_num(r.factor),
                fmt_num(sim)
            ));
        }
        if let Some(sim) = self.simulated_std {
            let ratio = logs / sim;
            if !(1.0 / SIZING_TOLERANCE..=SIZING_TOLERANCE).contains(&ratio) {
                let (how, likely) = if ratio > 1.0 {
                    ("more", "too high, and its threshold too small")
                } else {
                    ("less", "too low, and its threshold too large")
                };
                self.warnings.push(format!(
                    "a fit of the model with {effect} sizes {parameter} to ±{}{unit} on the \
                     logs and to ±{}{unit} on the study's simulated records: the logged noise \
                     hides {effect} {:.2} times as much as the simulated (it enters {how} along \
                     the effect than the estimated noise sources do), so the detection rates are \
                     likely {likely}, by about that factor in {parameter}",
                    fmt_num(logs),
                    fmt_num(sim),
                    ratio
                ));
            }
        }
    }
}

/// How far an output's simulated period-to-period noise rms may be from the logged one,
/// as a factor either way, before the study warns. The calibration matches it exactly when
/// the noise sources can; its own sampling error (eight simulated records) is a few percent.
pub const NOISE_TOTAL_TOLERANCE: f64 = 1.15;

/// The same within one band of the excited band. The logged band noise is itself an estimate
/// (see [`MIN_BAND_DOF`]); a factor of 2 to 3 at a few hertz turned a ball-and-beam's 12 ms
/// servo lag from found in all of a user's own records to found in none of the study's.
pub const NOISE_BAND_TOLERANCE: f64 = 1.5;

/// Degrees of freedom of the logged noise in a band of the noise check: octaves of the
/// excited band are merged until they have this many (a chi-square variance estimate with
/// 64 has a relative standard deviation of 0.18, so [`NOISE_BAND_TOLERANCE`] is 3.7 of them).
pub const MIN_BAND_DOF: usize = 64;

/// The bands of the noise check within `band` (Hz): octaves from its lower edge, merged
/// until each holds [`MIN_BAND_DOF`] degrees of freedom of the period-to-period noise (two per
/// line of the period's DFT and period less one, per experiment); a short last band joins the
/// one before it, and an excited band too short for one band leaves none.
pub fn noise_bands(data: &Dataset, band: (f64, f64)) -> Vec<(f64, f64)> {
    let Some((layouts, _)) = data.periodic_layouts() else {
        return Vec::new();
    };
    let (lo, hi) = band;
    if !(lo > 0.0 && hi > lo) {
        return Vec::new();
    }
    let dof = |a: f64, b: f64| band_dof_of(data, &layouts, (a, b));
    let mut bands: Vec<(f64, f64)> = Vec::new();
    let mut start = lo;
    while start < hi {
        let mut end = (2.0 * start).min(hi);
        while end < hi && dof(start, end) < MIN_BAND_DOF {
            end = (2.0 * end).min(hi);
        }
        if dof(start, end) < MIN_BAND_DOF {
            if let Some(last) = bands.last_mut() {
                last.1 = end;
            }
            break;
        }
        bands.push((start, end));
        start = end;
    }
    bands
}

/// Degrees of freedom of the logs' period-to-period noise in `band` (Hz, `[lo, hi)`): two per
/// line of the period's DFT and period less one, per experiment; 0 unless every experiment is
/// periodic.
pub fn band_dof(data: &Dataset, band: (f64, f64)) -> usize {
    data.periodic_layouts()
        .map_or(0, |(layouts, _)| band_dof_of(data, &layouts, band))
}

fn band_dof_of(data: &Dataset, layouts: &[Periodic], (a, b): (f64, f64)) -> usize {
    layouts
        .iter()
        .map(|l| {
            let df = data.sample_rate_hz / l.period as f64;
            let lines = (1..=l.period / 2)
                .filter(|k| (a..b).contains(&(*k as f64 * df)))
                .count();
            2 * lines * (l.periods - 1)
        })
        .sum()
}

/// The period-to-period noise power per output (rows) and band (columns, `[lo, hi)` Hz): the
/// mean over the DFT lines of each period's deviation from the mean period within the band,
/// over periods and experiments, corrected for the mean's own share as in
/// [`period_noise_rms`]; `None` unless every experiment is periodic.
pub fn band_noise(data: &Dataset, bands: &[(f64, f64)]) -> Option<DMatrix<f64>> {
    let (layouts, _) = data.periodic_layouts()?;
    let outputs = data.outputs.len();
    let mut sum = DMatrix::zeros(outputs, bands.len());
    let mut count = vec![0usize; bands.len()];
    for (e, l) in data.experiments.iter().zip(&layouts) {
        let p = l.period;
        let df = data.sample_rate_hz / p as f64;
        let (cos, sin): (Vec<f64>, Vec<f64>) = (0..p)
            .map(|k| (2.0 * std::f64::consts::PI * k as f64 / p as f64).sin_cos())
            .map(|(s, c)| (c, s))
            .unzip();
        let lines: Vec<(usize, usize)> = (1..=p / 2)
            .filter_map(|k| {
                let f = k as f64 * df;
                bands
                    .iter()
                    .position(|(a, b)| (*a..*b).contains(&f))
                    .map(|band| (k, band))
            })
            .collect();
        let periods = l.periods as f64;
        for i in 0..outputs {
            let at = |j: usize, k: usize| e.y[(l.transient + j * p + k, i)];
            let mean: Vec<f64> = (0..p)
                .map(|k| (0..l.periods).map(|j| at(j, k)).sum::<f64>() / periods)
                .collect();
            for j in 0..l.periods {
                let d: Vec<f64> = (0..p).map(|k| at(j, k) - mean[k]).collect();
                for &(line, band) in &lines {
                    let (mut re, mut im) = (0.0, 0.0);
                    for (k, v) in d.iter().enumerate() {
                        let t = (line * k) % p;
                        re += v * cos[t];
                        im -= v * sin[t];
                    }
                    sum[(i, band)] += (re * re + im * im) / p as f64 * (periods / (periods - 1.0));
                }
            }
        }
        for &(_, band) in &lines {
            count[band] += l.periods;
        }
    }
    for (b, n) in count.iter().enumerate() {
        sum.column_mut(b).scale_mut(1.0 / (*n).max(1) as f64);
    }
    Some(sum)
}

/// Noise factors from each output's simulated variances relative to the logged one, `a[i]`
/// with process noise alone and `b[(i, j)]` with sensor `j`'s noise alone: `cq` for the
/// process noise and `cr[j]` for sensor `j`'s, so that `cq a_i + sum_j cr_j b_ij` is as close
/// to 1 as it can be on every output. In closed loop a sensor's noise reaches the other
/// outputs through the controller (a ball's position sensor moves the beam), so the cross
/// terms `b_ij`, `i != j`, count; fitting each output with its own sensor alone left a beam
/// angle at 1.9 times its logged noise.
///
/// Every sensor keeps a floor, [`SENSOR_FLOOR`] times the common factor (the one that fits
/// `a + b` best in least squares). The process factor is first the common one, lowered where
/// process noise alone would exceed an output's logged noise less every sensor's floor (this
/// keeps the Kalman estimate's split between process and sensor noise), and the sensor
/// factors above their floors the non-negative least-squares fit of the rest ([`nnls`]).
/// Without cross terms that fits every output whose floor fits exactly. Where it leaves a
/// misfit (a sensor's noise reaching another output beyond that output's logged noise), the
/// process factor is fitted with the sensors', which lets the process noise make up what the
/// sensors cannot; what remains is reported by the study's noise check
/// ([`Study::noise_check`]). A sensor that reaches no output keeps the common factor. `None`
/// when the simulated noise is zero on every output.
pub fn calibration_factors(a: &[f64], b: &DMatrix<f64>) -> Option<(f64, Vec<f64>)> {
    let m = a.len();
    let reach: Vec<f64> = b.row_iter().map(|r| r.sum()).collect();
    let both: Vec<f64> = a.iter().zip(&reach).map(|(x, y)| x + y).collect();
    let norm = both.iter().map(|v| v * v).sum::<f64>();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    let common = both.iter().sum::<f64>() / norm;
    let floor = SENSOR_FLOOR * common;
    let rest = DVector::from_iterator(m, reach.iter().map(|y| 1.0 - floor * y));
    let kept = a
        .iter()
        .zip(rest.iter())
        .filter(|(x, _)| **x > 0.0)
        .fold(common, |c, (x, r)| c.min(r.max(0.0) / x));
    let av = DVector::from_column_slice(a);
    let above = nnls(b, &(&rest - &av * kept));
    let misfit = (&rest - &av * kept - b * &above).norm();
    let (cq, above) = if misfit <= 1e-9 * rest.norm() {
        (kept, above)
    } else {
        let both = DMatrix::from_fn(
            m,
            b.ncols() + 1,
            |i, j| {
                if j == 0 {
                    a[i]
                } else {
                    b[(i, j - 1)]
                }
            },
        );
        let x = nnls(&both, &rest);
        (x[0], x.rows(1, b.ncols()).into_owned())
    };
    let cr = b
        .column_iter()
        .zip(above.iter())
        .map(|(col, d)| {
            if col.iter().any(|v| *v > 0.0) {
                floor + d
            } else {
                common
            }
        })
        .collect();
    Some((cq, cr))
}

/// The non-negative least-squares solution `x >= 0` of `a x ~ b` (Lawson and Hanson's active
/// set method): variables enter the passive set one at a time where the gradient most
/// favours them, and leave it when the unconstrained solution on the set would make them
/// negative.
pub fn nnls(a: &DMatrix<f64>, b: &DVector<f64>) -> DVector<f64> {
    let n = a.ncols();
    let mut x = DVector::zeros(n);
    let mut passive = vec![false; n];
    let scale = (a.transpose() * b).amax().max(f64::MIN_POSITIVE);
    let tol = 1e-12 * scale;
    // Each pass adds a variable; a variable that leaves does so in the inner loop, which
    // ends when the set is empty or its solution positive.
    for _ in 0..3 * n + 3 {
        let w = a.transpose() * (b - a * &x);
        let Some(enter) = (0..n)
            .filter(|&j| !passive[j] && w[j] > tol)
            .max_by(|&i, &k| w[i].total_cmp(&w[k]))
        else {
            break;
        };
        passive[enter] = true;
        loop {
            let set: Vec<usize> = (0..n).filter(|&j| passive[j]).collect();
            if set.is_empty() {
                break;
            }
            let sub = a.select_columns(&set);
            let z = match sub.clone().svd(true, true).solve(b, 1e-14) {
                Ok(z) => z,
                Err(_) => break,
            };
            if z.iter().all(|v| *v > 0.0) {
                for (k, &j) in set.iter().enumerate() {
                    x[j] = z[k];
                }
                break;
            }
            // Move from x toward z as far as every variable stays non-negative; the one that
            // reaches zero first (and any other at zero) leaves the set.
            let (step, first) = set
                .iter()
                .enumerate()
                .filter(|(k, _)| z[*k] <= 0.0)
                .map(|(k, &j)| (x[j] / (x[j] - z[k]), j))
                .fold(
                    (f64::INFINITY, usize::MAX),
                    |m, c| if c.0 < m.0 { c } else { m },
                );
            for (k, &j) in set.iter().enumerate() {
                x[j] += step * (z[k] - x[j]);
                if j == first || x[j] <= 0.0 {
                    x[j] = 0.0;
                    passive[j] = false;
                }
            }
        }
    }
    x
}

/// The least sensor noise an output keeps in the calibration, relative to the common factor:
/// an output whose logged noise the process noise alone reproduces would otherwise be
/// simulated without sensor noise, which no sensor has, and the discovery's predictor of such
/// logs is not the real one's. (A cart's position, simulated noise-free beside a noisy pole
/// angle, read "unexplained" in 4 of 4 campaigns of the nominal model; with a quarter of its
/// estimated sensor noise, explained.)
pub const SENSOR_FLOOR: f64 = 0.25;

/// Values finite, increasing and within `bounds`, or 0: the effect absent, whatever its
/// bounds (a lag's `tau` starts above 0).
fn check_values(values: &[f64], name: &str, bounds: [f64; 2]) -> Result<()> {
    if values.is_empty() {
        return Err(SimError::invalid(
            "values",
            "(none)",
            "give at least one value",
        ));
    }
    for (i, v) in values.iter().enumerate() {
        if *v != 0.0 && !(v.is_finite() && *v >= bounds[0] && *v <= bounds[1]) {
            return Err(SimError::invalid(
                "values",
                v,
                format!(
                    "{name} must be 0 (the effect absent) or finite and within its bounds [{}, {}]",
                    bounds[0], bounds[1]
                ),
            ));
        }
        if i > 0 && *v <= values[i - 1] {
            return Err(SimError::invalid(
                "values",
                values
                    .iter()
                    .map(|v| v.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
                "must increase",
            ));
        }
    }
    Ok(())
}

/// Simulated records per noise source the calibration averages over (a short record's
/// period-to-period noise varies much from one draw to the next).
const CALIBRATION_DRAWS: usize = 8;

/// How much a coloured process noise must lower the band mismatch ([`NoiseShape::mismatch`],
/// about a chi-square statistic) below white noise's to be used: the 1 % point of a
/// chi-square of one degree of freedom, the one parameter it adds.
pub const NOISE_SHAPE_GAIN: f64 = 6.63;

/// Simulated period-to-period noise power per output: in all, and per band (outputs x bands).
#[derive(Debug, Clone)]
struct NoisePower {
    total: Vec<f64>,
    bands: DMatrix<f64>,
}

/// The factors `(process, sensor per output)` that scale the noise sources so that the
/// simulated period-to-period noise matches the logs' `measured` rms on every output as well
/// as it can: the noise enters linearly, so output `i`'s variance is `cq A_i + sum_j cr_j
/// B_ij` with `A` the power simulated with process noise alone and `B_ij` output `i`'s with
/// sensor `j`'s noise alone ([`calibration_factors`]). With `logged` band powers (outputs x
/// bands, of `dof` degrees of freedom each), also the band mismatch the calibrated sources
/// leave ([`NoiseShape::mismatch`]; 0 without bands).
fn calibrate(
    measured: &[f64],
    process: &NoisePower,
    sensors: &[NoisePower],
    logged: Option<&DMatrix<f64>>,
    dof: &[usize],
) -> Result<((f64, Vec<f64>), f64)> {
    let rel = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(measured)
            .map(|(x, m)| x / (m * m).max(1e-300))
            .collect()
    };
    let a = rel(&process.total);
    let mut b = DMatrix::zeros(measured.len(), sensors.len());
    for (j, sensor) in sensors.iter().enumerate() {
        b.set_column(j, &DVector::from_vec(rel(&sensor.total)));
    }
    let (cq, cr) = calibration_factors(&a, &b).ok_or_else(|| {
        SimError::invalid(
            "noise calibration",
            "simulated noise",
            "is zero on every output",
        )
    })?;
    let mut mismatch = 0.0;
    if let Some(logged) = logged {
        let simulated = sensors
            .iter()
            .zip(&cr)
            .fold(&process.bands * cq, |acc, (sensor, c)| {
                acc + &sensor.bands * *c
            });
        for i in 0..logged.nrows() {
            for (b, dof) in dof.iter().enumerate() {
                let (v, l) = (simulated[(i, b)], logged[(i, b)]);
                if l > 0.0 && v > 0.0 {
                    mismatch += *dof as f64 / 2.0 * (v / l).ln().powi(2);
                }
            }
        }
    }
    Ok(((cq, cr), mismatch))
}

/// Correlation times the noise shape is chosen among: corners from half the lowest band's
/// lower edge up to the highest band's upper edge, an octave apart (`tau = 1 / (2 pi f)`).
fn correlation_times(bands: &[(f64, f64)]) -> Vec<f64> {
    let (Some(first), Some(last)) = (bands.first(), bands.last()) else {
        return Vec::new();
    };
    let mut times = Vec::new();
    let mut corner = first.0 / 2.0;
    while corner <= last.1 {
        times.push(1.0 / (2.0 * std::f64::consts::PI * corner));
        corner *= 2.0;
    }
    times
}

/// A symmetric positive semi-definite matrix's square root factor `L` (`L Lᵀ = S`) from its
/// eigen-decomposition, negative rounding clipped (the process covariance may be singular).
fn sqrt_factor(s: &DMatrix<f64>) -> DMatrix<f64> {
    let sym = (s + s.transpose()) * 0.5;
    let eig = sym.symmetric_eigen();
    let roots = eig.eigenvalues.map(|l| l.max(0.0).sqrt());
    &eig.eigenvectors * DMatrix::from_diagonal(&roots)
}

/// One model of a study as its campaigns simulate it.
#[derive(Debug, Clone)]
enum Plant {
    /// A linear model sampled with a zero-order hold.
    Linear(Discrete),
    /// A nonlinear model (a `[nonlinear]` section) at its parameter values, integrated
    /// between the samples as the time-domain criterion integrates it.
    Nonlinear(Model, Vec<f64>),
}

/// The model with the effect fitted to one set of records ([`Study::sizing`]).
struct Sized {
    model: Model,
    theta: Vec<f64>,
    /// The studied parameter's estimate.
    estimate: super::fit::ParamEstimate,
}

/// A study ready to run: the spec checked and parsed once.
#[derive(Debug, Clone)]
pub struct Study {
    spec: StudySpec,
    structure: Arc<ModelFile>,
    /// The nominal model at its fitted values, simulated for the value 0.
    nominal: Plant,
    /// The model with the effect on, and the parameter vector with its slot.
    with: Model,
    theta: Vec<f64>,
    slot: usize,
    noise_factor: DMatrix<f64>,
    /// The process noise's filter coefficient per sample ([`NoiseShape`]; 0: white).
    noise_pole: f64,
    sensor_sd: DVector<f64>,
    controller: super::model_file::Controller,
    excitations: Vec<DMatrix<f64>>,
    inputs: Vec<String>,
    outputs: Vec<String>,
}

impl Study {
    /// Checks and parses a spec.
    pub fn new(spec: StudySpec) -> Result<Self> {
        let path = Path::new(&spec.model_path);
        let structure = Arc::new(ModelFile::parse(&spec.model_text, path)?);
        let controller = super::model::ModelStructure::controller(structure.as_ref())
            .ok_or_else(|| SimError::invalid("controller", path.display(), "is missing"))?;
        let nominal = Model::new(structure.clone());
        let with = nominal.with_effect(&spec.effect)?;
        let params = with.parameters()?;
        let slot = params
            .iter()
            .position(|p| p.name == spec.parameter)
            .ok_or_else(|| SimError::invalid("parameter", &spec.parameter, "not in the model"))?;
        // Each parameter at its fitted nominal value, the effect's own at its default.
        let fitted = |params: &[super::model::Parameter]| -> Vec<f64> {
            params
                .iter()
                .map(|p| {
                    spec.nominal
                        .iter()
                        .find(|(n, _)| *n == p.name)
                        .map_or(p.value, |(_, v)| *v)
                })
                .collect()
        };
        let theta = fitted(&params);
        check_values(&spec.values, &spec.parameter, spec.bounds)?;
        let nominal_theta = fitted(&nominal.parameters()?);
        let nominal = if super::model::ModelStructure::is_nonlinear(structure.as_ref()) {
            Plant::Nonlinear(nominal, nominal_theta)
        } else {
            Plant::Linear(
                nominal
                    .state_space(&nominal_theta)?
                    .discretize(1.0 / spec.sample_rate_hz)?,
            )
        };
        let n = spec.process_noise.len();
        let q = matrix("process_noise", &spec.process_noise, n)?;
        let inputs = super::model::ModelStructure::inputs(structure.as_ref());
        let outputs = super::model::ModelStructure::outputs(structure.as_ref());
        if spec.sensor_noise.len() != outputs.len() {
            return Err(SimError::LengthMismatch {
                what: "sensor_noise (one variance per output)".into(),
                expected: outputs.len(),
                found: spec.sensor_noise.len(),
            });
        }
        let excitations = spec
            .experiments
            .iter()
            .map(|e| matrix(&format!("excitation of {}", e.name), &e.r, inputs.len()))
            .collect::<Result<_>>()?;
        let noise_pole = match &spec.process_noise_shape {
            None => 0.0,
            Some(shape) if shape.correlation_s > 0.0 && shape.correlation_s.is_finite() => {
                (-1.0 / (spec.sample_rate_hz * shape.correlation_s)).exp()
            }
            Some(shape) => {
                return Err(SimError::invalid(
                    "process_noise_shape.correlation_s",
                    shape.correlation_s,
                    "must be a finite time above 0 s (white noise has no shape)",
                ))
            }
        };
        Ok(Self {
            noise_factor: sqrt_factor(&q),
            noise_pole,
            sensor_sd: DVector::from_iterator(
                spec.sensor_noise.len(),
                spec.sensor_noise.iter().map(|v| v.max(0.0).sqrt()),
            ),
            structure,
            nominal,
            with,
            theta,
            slot,
            controller,
            excitations,
            inputs,
            outputs,
            spec,
        })
    }

    /// The spec.
    pub fn spec(&self) -> &StudySpec {
        &self.spec
    }

    /// Every campaign of the study (see [`StudySpec::jobs`]).
    pub fn jobs(&self) -> Vec<(usize, usize)> {
        self.spec.jobs()
    }

    /// The random numbers of one campaign (see the module documentation).
    fn rng(&self, value_index: usize, campaign: usize) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::seed_from_u64(self.spec.seed);
        rng.set_stream(((value_index as u64) << 32) | campaign as u64);
        rng
    }

    /// The simulated logs of one campaign.
    pub fn simulate(&self, value_index: usize, campaign: usize) -> Result<Dataset> {
        let value = *self.spec.values.get(value_index).ok_or_else(|| {
            SimError::invalid(
                "value index",
                value_index,
                format!("the study has {} values", self.spec.values.len()),
            )
        })?;
        let mut theta = self.theta.clone();
        theta[self.slot] = value;
        let plant = match &self.nominal {
            _ if value == 0.0 => self.nominal.clone(),
            Plant::Linear(_) => Plant::Linear(
                self.with
                    .state_space(&theta)?
                    .discretize(1.0 / self.spec.sample_rate_hz)?,
            ),
            Plant::Nonlinear(..) => Plant::Nonlinear(self.with.clone(), theta),
        };
        let mut rng = self.rng(value_index, campaign);
        let label = (self.spec.parameter.as_str(), value.to_string());
        self.logs(
            &plant,
            &label,
            &mut rng,
            &self.noise_factor,
            &self.sensor_sd,
        )
    }

    /// Simulated logs of `plant` in the loop, noise drawn from `rng` with the process-noise
    /// factor `factor` (`factor factorᵀ` the covariance) and sensor standard deviations `sd`;
    /// `label` (a parameter and its value) names the model in a divergence message.
    fn logs(
        &self,
        plant: &Plant,
        label: &(&str, String),
        rng: &mut ChaCha8Rng,
        factor: &DMatrix<f64>,
        sd: &DVector<f64>,
    ) -> Result<Dataset> {
        let n_noise = factor.nrows();
        let mut z = DVector::zeros(n_noise);
        let pole = self.noise_pole;
        let mut experiments = Vec::with_capacity(self.excitations.len());
        for (r, e) in self.excitations.iter().zip(&self.spec.experiments) {
            let mut last: Option<DVector<f64>> = None;
            let mut noise = |w: &mut DVector<f64>, v: &mut DVector<f64>| {
                for zi in z.iter_mut() {
                    *zi = StandardNormal.sample(&mut *rng);
                }
                // The noise enters the nominal model's states; states the effect adds (a lag's)
                // come after them and get none. A coloured one keeps its variance per sample.
                let fresh = factor * &z;
                let drawn = match last.take() {
                    Some(before) if pole > 0.0 => {
                        before * pole + fresh * (1.0 - pole * pole).sqrt()
                    }
                    _ => fresh,
                };
                if pole > 0.0 {
                    last = Some(drawn.clone());
                }
                let n = n_noise.min(w.len());
                w.rows_mut(0, n).copy_from(&drawn.rows(0, n));
                for (vi, sd) in v.iter_mut().zip(sd.iter()) {
                    let s: f64 = StandardNormal.sample(&mut *rng);
                    *vi = sd * s;
                }
            };
            let run = match plant {
                Plant::Linear(disc) => run_loop(disc, &self.controller, r, &mut noise),
                Plant::Nonlinear(model, theta) => simulate_closed_loop(
                    model,
                    theta,
                    1.0 / self.spec.sample_rate_hz,
                    &self.controller,
                    r,
                    &mut noise,
                )?,
            };
            let (u, y) = run.map_err(|k| {
                SimError::invalid(
                    label.0,
                    &label.1,
                    format!(
                        "the simulated loop of the model and the controller diverges in {} at \
                         sample {k}",
                        e.name
                    ),
                )
            })?;
            // A nonlinear model's outputs are absolute: the growth is of their deviations.
            let growth = growth(&demeaned(&y));
            if growth > GROWTH {
                return Err(SimError::invalid(
                    label.0,
                    &label.1,
                    format!(
                        "the simulated loop of the model and the controller diverges in {}: the \
                         output rms grows {growth:.3e}-fold from the second to the last quarter \
                         of the record",
                        e.name
                    ),
                ));
            }
            experiments.push(Experiment {
                name: format!("{} (simulated)", e.name),
                u,
                y,
                r: Some(r.clone()),
                periodic: e.periodic.map(|(period, periods, transient)| Periodic {
                    period,
                    periods,
                    transient,
                }),
            });
        }
        Ok(Dataset {
            sample_rate_hz: self.spec.sample_rate_hz,
            inputs: self.inputs.clone(),
            outputs: self.outputs.clone(),
            experiments,
        })
    }

    /// The nominal model's simulated period-to-period noise power with process noise alone,
    /// per output in all and per band of `bands`, averaged over [`CALIBRATION_DRAWS`] records
    /// (random stream `u64::MAX`, which no campaign uses).
    fn process_power(&self, bands: &[(f64, f64)], cancel: &Cancel) -> Result<NoisePower> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.spec.seed);
        rng.set_stream(u64::MAX);
        let none_r = DVector::zeros(self.sensor_sd.len());
        self.noise_power(&mut rng, &self.noise_factor, &none_r, bands, cancel)
    }

    /// The same with each sensor's noise alone, in the order of the outputs (random stream
    /// `u64::MAX - 2`). It does not depend on the process noise's colour.
    fn sensor_power(&self, bands: &[(f64, f64)], cancel: &Cancel) -> Result<Vec<NoisePower>> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.spec.seed);
        rng.set_stream(u64::MAX - 2);
        let none_q = DMatrix::zeros(self.noise_factor.nrows(), self.noise_factor.ncols());
        (0..self.sensor_sd.len())
            .map(|j| {
                let mut one = DVector::zeros(self.sensor_sd.len());
                one[j] = self.sensor_sd[j];
                self.noise_power(&mut rng, &none_q, &one, bands, cancel)
            })
            .collect()
    }

    /// The nominal model's period-to-period noise power with the process-noise factor
    /// `factor` and sensor standard deviations `sd`, averaged over [`CALIBRATION_DRAWS`]
    /// records drawn from `rng`; `cancel` stops it before a record.
    fn noise_power(
        &self,
        rng: &mut ChaCha8Rng,
        factor: &DMatrix<f64>,
        sd: &DVector<f64>,
        bands: &[(f64, f64)],
        cancel: &Cancel,
    ) -> Result<NoisePower> {
        let mut power = NoisePower {
            total: vec![0.0; self.outputs.len()],
            bands: DMatrix::zeros(self.outputs.len(), bands.len()),
        };
        let draws = CALIBRATION_DRAWS as f64;
        for _ in 0..CALIBRATION_DRAWS {
            cancel.check()?;
            let label = ("nominal model", "fitted".to_string());
            let logs = self.logs(&self.nominal, &label, rng, factor, sd)?;
            for (s, v) in power
                .total
                .iter_mut()
                .zip(period_noise_rms(&logs).unwrap_or_default())
            {
                *s += v * v / draws;
            }
            if let Some(b) = band_noise(&logs, bands) {
                power.bands += b / draws;
            }
        }
        Ok(power)
    }

    /// Compares the study's simulated period-to-period noise with the logs' on every output,
    /// in all and per band of the excited band `band` ([`noise_bands`]), over
    /// eight (`CALIBRATION_DRAWS`) records of the nominal model (random stream
    /// `u64::MAX - 1`, which no campaign uses): a warning for every ratio beyond [`NOISE_TOTAL_TOLERANCE`] or
    /// [`NOISE_BAND_TOLERANCE`]. Where the simulated noise is lower than the logged one an
    /// effect acting there stands out more in the study than in the logs, so its detection
    /// rates are likely too high; where higher, too low.
    pub fn noise_check(
        &self,
        logs: &Dataset,
        band: Option<(f64, f64)>,
        cancel: &Cancel,
    ) -> Result<Vec<NoiseWarning>> {
        let Some(measured) = period_noise_rms(logs) else {
            return Ok(Vec::new());
        };
        let bands = band.map_or_else(Vec::new, |b| noise_bands(logs, b));
        let logged = band_noise(logs, &bands).unwrap_or_else(|| DMatrix::zeros(0, 0));
        let mut rng = ChaCha8Rng::seed_from_u64(self.spec.seed);
        rng.set_stream(u64::MAX - 1);
        let NoisePower {
            total,
            bands: banded,
        } = self.noise_power(
            &mut rng,
            &self.noise_factor,
            &self.sensor_sd,
            &bands,
            cancel,
        )?;
        // After a scaling along the effect the noise elsewhere differs by design: the
        // warnings then say why, and that they concern the other effects.
        let (why_total, why_band, effects) = match self
            .spec
            .sizing
            .as_ref()
            .and_then(|z| z.rescaled.as_ref())
        {
            Some(r) => {
                let why = format!(
                    "the study scaled its noise by {} so that it hides {} as the logs' does (the \
                     sizing), and the noise sources it estimates cannot match both",
                    fmt_num(r.factor),
                    self.spec.effect
                );
                (why.clone(), why, "other effects")
            }
            None => (
                "no scaling of the estimated noise sources gives every output its logged noise \
                 (in closed loop a sensor's noise reaches the other outputs)"
                    .to_string(),
                "the estimated noise spectrum's shape is not the logs'".to_string(),
                "effects",
            ),
        };
        let likely = |ratio: f64| {
            if ratio < 1.0 {
                "too high (the simulated noise hides them less than the logged one)"
            } else {
                "too low (the simulated noise hides them more than the logged one)"
            }
        };
        let mut warnings = Vec::new();
        for (i, output) in self.outputs.iter().enumerate() {
            let ratio = (total[i] / (measured[i] * measured[i]).max(1e-300)).sqrt();
            if !(1.0 / NOISE_TOTAL_TOLERANCE..=NOISE_TOTAL_TOLERANCE).contains(&ratio) {
                warnings.push(NoiseWarning {
                    output: output.clone(),
                    band_hz: None,
                    ratio,
                    message: format!(
                        "the simulated period-to-period noise on {output} is {ratio:.2} times \
                         the logged (rms) after the calibration: {why_total}; detection rates \
                         of {effects} seen on {output} are likely {}",
                        likely(ratio)
                    ),
                });
            }
            for (b, (lo, hi)) in bands.iter().enumerate() {
                let ratio = (banded[(i, b)] / logged[(i, b)].max(1e-300)).sqrt();
                if !(1.0 / NOISE_BAND_TOLERANCE..=NOISE_BAND_TOLERANCE).contains(&ratio) {
                    warnings.push(NoiseWarning {
                        output: output.clone(),
                        band_hz: Some([*lo, *hi]),
                        ratio,
                        message: format!(
                            "the simulated noise on {output} at {}-{} Hz is {ratio:.2} times the \
                             logged (period-to-period rms): {why_band}; detection rates of \
                             {effects} acting on {output} at these frequencies are likely {}",
                            fmt_num(*lo),
                            fmt_num(*hi),
                            likely(ratio)
                        ),
                    });
                }
            }
        }
        Ok(warnings)
    }

    /// How precisely the model with the effect sizes the parameter on `logs` and on the
    /// study's simulated records ([`Sizing`]), with its warnings for the study's values;
    /// `cancel` stops its fits.
    pub fn sizing(&self, logs: &Dataset, cancel: &Cancel) -> Result<Sizing> {
        // The logs first, then the simulated records, drawn in order and fitted on threads.
        let mut rng = ChaCha8Rng::seed_from_u64(self.spec.seed);
        rng.set_stream(u64::MAX - 2);
        let label = ("nominal model", "fitted".to_string());
        let mut records = vec![logs.clone()];
        for _ in 0..SIZING_DRAWS {
            cancel.check()?;
            records.push(self.logs(
                &self.nominal,
                &label,
                &mut rng,
                &self.noise_factor,
                &self.sensor_sd,
            )?);
        }
        // Each job keeps its fit's own failure; a job that panics fails the sizing alone.
        let jobs: Vec<_> = records
            .into_iter()
            .map(|data| move || Ok(self.sized(data, cancel)))
            .collect();
        let fits =
            in_parallel(self.with.parallel(), jobs, "sizing fit").unwrap_or_else(|e| vec![Err(e)]);
        self.sizing_of(fits.into_iter())
    }

    /// The sizing from the fits to the logs (first) and to the simulated records.
    fn sizing_of(&self, mut fits: impl Iterator<Item = Result<Sized>>) -> Result<Sizing> {
        let spec = &self.spec;
        // A fit that fails leaves the study without a sizing, not without its campaigns (whose
        // discoveries record a candidate whose fit fails and go on); a cancel stops it.
        let on_logs = match fits
            .next()
            .unwrap_or_else(|| Err(SimError::invalid("sizing", "fit", "no logs")))
        {
            Ok(fitted) => fitted,
            Err(SimError::Cancelled) => return Err(SimError::Cancelled),
            Err(e) => {
                return Ok(Sizing {
                    logs_estimate: None,
                    logs_std: None,
                    simulated_std: None,
                    trades_against: Vec::new(),
                    rescaled: None,
                    warnings: vec![format!(
                        "no sizing: the model with {} could not be fitted to the logs ({e}); \
                         the detection rates stand without it",
                        spec.effect
                    )],
                })
            }
        };
        let simulated_std = fits
            .map(|f| match f {
                Err(SimError::Cancelled) => Err(SimError::Cancelled),
                other => Ok(other.ok().and_then(|s| s.estimate.std)),
            })
            .collect::<Result<Vec<Option<f64>>>>()?
            .into_iter()
            .collect::<Option<Vec<f64>>>()
            .map(|mut v| {
                v.sort_by(f64::total_cmp);
                v[v.len() / 2]
            });
        // The parameters the outputs cannot tell the studied one from (at the logs' fit).
        let trades_against: Vec<String> =
            super::identifiability::analyse(&on_logs.model, &on_logs.theta)
                .map(|a| a.unseparated)
                .unwrap_or_default()
                .into_iter()
                .filter(|group| group.contains(&self.spec.parameter))
                .flatten()
                .filter(|p| *p != self.spec.parameter)
                .fold(Vec::new(), |mut all, p| {
                    if !all.contains(&p) {
                        all.push(p);
                    }
                    all
                });
        let on_logs = on_logs.estimate;
        let mut sizing = Sizing {
            logs_estimate: Some(on_logs.value),
            logs_std: on_logs.std.filter(|_| !on_logs.held),
            simulated_std,
            trades_against,
            rescaled: None,
            warnings: Vec::new(),
        };
        sizing.warn(&spec.effect, &spec.parameter, &spec.unit, &spec.values);
        Ok(sizing)
    }

    /// A workbench of the nominal model on `data` under the study's estimator and criterion.
    fn workbench(&self, data: Dataset) -> Result<Workbench> {
        Workbench::with_options(
            self.structure.clone(),
            data,
            estimator_choice(&self.spec.estimator)?,
            DataOptions {
                band_hz: self.spec.band_hz,
                criterion: self.spec.criterion,
            },
        )
    }

    /// The studied parameter as the model with the effect, fitted to `data` under the study's
    /// estimator and criterion, reports it.
    fn sized(&self, data: Dataset, cancel: &Cancel) -> Result<Sized> {
        // A stopped sizing builds no more workbenches (each estimates its FRF first).
        cancel.check()?;
        let mut wb = self.workbench(data)?;
        wb.set_cancel(cancel.clone());
        wb.add(&self.spec.effect)?;
        let model = wb.model().clone();
        let slot = model
            .parameters()?
            .iter()
            .position(|p| p.name == self.spec.parameter)
            .ok_or_else(|| {
                SimError::invalid("parameter", &self.spec.parameter, "not in the model")
            })?;
        let r = wb.fit_sized(slot)?;
        Ok(Sized {
            model,
            estimate: r.params[slot].clone(),
            theta: r.theta,
        })
    }

    /// One campaign: simulate, discover, and what was found. Never fails: a failure is the
    /// outcome's `error` (also a discovery stopped by `cancel`, which [`run`] does not return).
    pub fn campaign(&self, value_index: usize, campaign: usize, cancel: &Cancel) -> Outcome {
        let mut out = Outcome {
            value_index,
            campaign,
            found: false,
            other_found: Vec::new(),
            unexplained: false,
            tentative: false,
            estimate: None,
            error: None,
            noise_rms: None,
        };
        let result = self.simulate(value_index, campaign).and_then(|data| {
            out.noise_rms = period_noise_rms(&data);
            let mut wb = self.workbench(data)?;
            wb.set_cancel(cancel.clone());
            wb.discover_alone(&mut |_: &str| {})
        });
        match result {
            Err(e) => out.error = Some(e.to_string()),
            Ok(d) => {
                out.found = d.conclusion.found.contains(&self.spec.effect);
                out.other_found = d
                    .conclusion
                    .found
                    .iter()
                    .filter(|f| **f != self.spec.effect)
                    .cloned()
                    .collect();
                out.unexplained = d.conclusion.unexplained;
                out.tentative = d.conclusion.tentative.contains(&self.spec.effect);
                out.estimate = out
                    .found
                    .then(|| {
                        d.steps.last().and_then(|s| {
                            s.params
                                .iter()
                                .find(|p| p.name == self.spec.parameter)
                                .map(|p| p.value)
                        })
                    })
                    .flatten();
            }
        }
        out
    }
}

/// Runs `jobs` on `threads` threads (at least one), calling `progress(done)` after each
/// campaign; the outcomes come back in the order of `jobs`. Once `cancel` is set no campaign
/// starts, the running ones stop at their next fit iteration, and the run returns
/// [`SimError::Cancelled`].
pub fn run(
    study: &Study,
    jobs: &[(usize, usize)],
    threads: usize,
    progress: &(dyn Fn(usize) + Sync),
    cancel: &Cancel,
) -> Result<Vec<Outcome>> {
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<Outcome>>> = Mutex::new(vec![None; jobs.len()]);
    std::thread::scope(|scope| {
        for _ in 0..threads.clamp(1, jobs.len().max(1)) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(&(v, c)) = jobs.get(i).filter(|_| !cancel.is_cancelled()) else {
                    break;
                };
                let outcome = study.campaign(v, c, cancel);
                if let Ok(mut s) = slots.lock() {
                    s[i] = Some(outcome);
                }
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            });
        }
    });
    cancel.check()?;
    Ok(slots
        .into_inner()
        .unwrap_or_default()
        .into_iter()
        .zip(jobs)
        .map(|(o, &(v, c))| {
            o.unwrap_or_else(|| Outcome {
                value_index: v,
                campaign: c,
                found: false,
                other_found: Vec::new(),
                unexplained: false,
                tentative: false,
                estimate: None,
                error: Some("the campaign's thread failed".into()),
                noise_rms: None,
            })
        })
        .collect())
}

/// The aggregate of one value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ValueSummary {
    /// The parameter's value.
    pub value: f64,
    /// Campaigns that found the effect, of those that completed.
    pub detection_rate: f64,
    /// Its Clopper-Pearson interval.
    pub ci: [f64; 2],
    /// Campaigns that found any other effect.
    pub other_found_rate: f64,
    /// Campaigns whose discovery reported an unexplained misfit.
    pub unexplained_rate: f64,
    /// Campaigns whose discovery added the effect but left it tentative: the data show it,
    /// the tests cannot confirm it (a lag and a delay of a millisecond fit a 250 Hz rig alike).
    pub tentative_rate: f64,
    /// Mean of the parameter's estimate where the effect was found.
    pub estimate_mean: Option<f64>,
    /// Its sample standard deviation (two estimates at least).
    pub estimate_std: Option<f64>,
    /// At value 0 (the nominal model is the truth): campaigns that found any effect.
    pub false_discovery_rate: Option<f64>,
    /// Its Clopper-Pearson interval.
    pub false_discovery_ci: Option<[f64; 2]>,
    /// Campaigns that completed.
    pub completed: usize,
    /// Campaigns that failed.
    pub failed: usize,
}

/// The smallest value detected with [`TARGET_POWER`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MinDetectable {
    /// Where the detection rate, linearly interpolated between the values, first reaches the
    /// target; `None` when it never does.
    pub value: Option<f64>,
    /// Where the upper and the lower interval bounds first reach it (`None`: not within the
    /// values studied).
    pub ci: [Option<f64>; 2],
    /// How to read it.
    pub note: String,
}

/// A failed campaign, named.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Failure {
    /// The parameter's value.
    pub value: f64,
    /// Campaign index.
    pub campaign: usize,
    /// Why.
    pub error: String,
}

/// The study's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PowerResult {
    /// The effect.
    pub effect: String,
    /// Its parameter.
    pub parameter: String,
    /// The parameter's unit (empty: none given).
    pub unit: String,
    /// Campaigns per value.
    pub campaigns: usize,
    /// Seed.
    pub seed: u64,
    /// Significance level of the discovery's tests (the nominal false-discovery level).
    pub level: f64,
    /// Which interval, at which confidence.
    pub interval: String,
    /// Per value.
    pub values: Vec<ValueSummary>,
    /// The reverse question.
    pub min_detectable: MinDetectable,
    /// Failed campaigns.
    pub failures: Vec<Failure>,
    /// Per output, the simulated campaigns' period-to-period noise rms (mean over the
    /// campaigns at the smallest value) over the logs': near 1 when the campaigns have the
    /// logged noise level; `None` for logs that are not periodic.
    pub noise_ratio: Option<Vec<f64>>,
    /// Where the study's simulated noise is not the logs' (see [`Study::noise_check`]).
    pub noise_warnings: Vec<NoiseWarning>,
    /// The process noise's colour, when not white.
    pub process_noise_shape: Option<NoiseShape>,
    /// How precisely a fit sizes the parameter on the logs and on the simulated records.
    pub sizing: Option<Sizing>,
    /// How the campaigns were simulated.
    pub policy: String,
}

fn mean_std(x: &[f64]) -> (Option<f64>, Option<f64>) {
    if x.is_empty() {
        return (None, None);
    }
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let std = (x.len() > 1)
        .then(|| (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt());
    (Some(mean), std)
}

/// Where `curve` (at increasing `values`), linearly interpolated, first reaches `target`.
fn first_crossing(values: &[f64], curve: &[f64], target: f64) -> Option<f64> {
    let i = curve.iter().position(|c| *c >= target)?;
    if i == 0 {
        return Some(values[0]);
    }
    let (v0, v1, c0, c1) = (values[i - 1], values[i], curve[i - 1], curve[i]);
    Some(v0 + (v1 - v0) * (target - c0) / (c1 - c0))
}

/// Aggregates the outcomes of a study (in any order; each `(value, campaign)` once). Sums run
/// in campaign order, so the result does not depend on the order the outcomes arrived in.
pub fn aggregate(spec: &StudySpec, outcomes: &[Outcome]) -> Result<PowerResult> {
    // For the policy's wording only: a text that does not parse has run no campaign.
    let nonlinear = ModelFile::parse(&spec.model_text, Path::new(&spec.model_path))
        .is_ok_and(|m| super::model::ModelStructure::is_nonlinear(&m));
    let mut sorted: Vec<&Outcome> = outcomes.iter().collect();
    sorted.sort_by_key(|o| (o.value_index, o.campaign));
    let outcomes = sorted;
    let mut seen = vec![vec![false; spec.campaigns]; spec.values.len()];
    for o in &outcomes {
        let slot = seen
            .get_mut(o.value_index)
            .and_then(|s| s.get_mut(o.campaign))
            .ok_or_else(|| {
                SimError::invalid(
                    "outcome",
                    format!("value {} campaign {}", o.value_index, o.campaign),
                    "is not a campaign of this study",
                )
            })?;
        if *slot {
            return Err(SimError::invalid(
                "outcome",
                format!("value {} campaign {}", o.value_index, o.campaign),
                "given twice",
            ));
        }
        *slot = true;
    }
    let alpha = ALPHA;
    let mut failures = Vec::new();
    let mut values = Vec::with_capacity(spec.values.len());
    for (i, &value) in spec.values.iter().enumerate() {
        let mine: Vec<&Outcome> = outcomes
            .iter()
            .copied()
            .filter(|o| o.value_index == i)
            .collect();
        let (ok, bad): (Vec<&Outcome>, Vec<&Outcome>) =
            mine.into_iter().partition(|o| o.error.is_none());
        failures.extend(bad.iter().map(|o| Failure {
            value,
            campaign: o.campaign,
            error: o.error.clone().unwrap_or_default(),
        }));
        let n = ok.len();
        let rate = |k: usize| if n == 0 { 0.0 } else { k as f64 / n as f64 };
        let detected = ok.iter().filter(|o| o.found).count();
        let (lo, hi) = clopper_pearson(detected, n, alpha);
        let estimates: Vec<f64> = ok.iter().filter_map(|o| o.estimate).collect();
        let (estimate_mean, estimate_std) = mean_std(&estimates);
        let any = ok
            .iter()
            .filter(|o| o.found || !o.other_found.is_empty())
            .count();
        let at_zero = value == 0.0;
        values.push(ValueSummary {
            value,
            detection_rate: rate(detected),
            ci: [lo, hi],
            other_found_rate: rate(ok.iter().filter(|o| !o.other_found.is_empty()).count()),
            unexplained_rate: rate(ok.iter().filter(|o| o.unexplained).count()),
            tentative_rate: rate(ok.iter().filter(|o| o.tentative).count()),
            estimate_mean,
            estimate_std,
            false_discovery_rate: at_zero.then(|| rate(any)),
            false_discovery_ci: at_zero.then(|| {
                let (a, b) = clopper_pearson(any, n, alpha);
                [a, b]
            }),
            completed: n,
            failed: bad.len(),
        });
    }
    let xs: Vec<f64> = values.iter().map(|v| v.value).collect();
    let point: Vec<f64> = values.iter().map(|v| v.detection_rate).collect();
    let upper: Vec<f64> = values.iter().map(|v| v.ci[1]).collect();
    let lower: Vec<f64> = values.iter().map(|v| v.ci[0]).collect();
    let min_detectable = MinDetectable {
        value: first_crossing(&xs, &point, TARGET_POWER),
        ci: [
            first_crossing(&xs, &upper, TARGET_POWER),
            first_crossing(&xs, &lower, TARGET_POWER),
        ],
        note: format!(
            "value: where the detection rate, linearly interpolated between the values \
             studied, first reaches {:.0} %; interval: where the upper and the lower {:.0} % \
             Clopper-Pearson bounds first reach it (null: not within the values studied; the \
             smallest value when already reached there)",
            100.0 * TARGET_POWER,
            100.0 * (1.0 - ALPHA)
        ),
    };
    let noise_ratio = spec.measured_noise_rms.as_ref().and_then(|measured| {
        let sims: Vec<&Vec<f64>> = outcomes
            .iter()
            .filter(|o| o.value_index == 0)
            .filter_map(|o| o.noise_rms.as_ref())
            .filter(|v| v.len() == measured.len())
            .collect();
        (!sims.is_empty()).then(|| {
            (0..measured.len())
                .map(|i| sims.iter().map(|v| v[i]).sum::<f64>() / sims.len() as f64 / measured[i])
                .collect()
        })
    });
    Ok(PowerResult {
        noise_ratio,
        noise_warnings: spec.noise_warnings.clone(),
        process_noise_shape: spec.process_noise_shape.clone(),
        sizing: spec.sizing.clone(),
        effect: spec.effect.clone(),
        parameter: spec.parameter.clone(),
        unit: spec.unit.clone(),
        campaigns: spec.campaigns,
        seed: spec.seed,
        level: LEVEL,
        interval: format!(
            "Clopper-Pearson (exact) {:.0} % interval over the completed campaigns",
            100.0 * (1.0 - ALPHA)
        ),
        values,
        min_detectable,
        failures,
        policy: format!(
            "each campaign: the nominal model fitted to the logs plus {} with {} at the value, \
             {} at {} Hz, in closed loop with the model file's controller from zero {}, driven \
             by the logged excitation of each of the {} experiments, with Gaussian process and \
             sensor noise of the covariances the Kalman predictor estimated from the logs{}{}; \
             then the full discovery under the {} criterion",
            spec.effect,
            spec.parameter,
            if nonlinear {
                "its nonlinear equations integrated (RK4) under a zero-order hold"
            } else {
                "sampled with a zero-order hold"
            },
            spec.sample_rate_hz,
            if nonlinear {
                "controller states and the operating point, the controller acting on the \
                 deviations from it"
            } else {
                "states"
            },
            spec.experiments.len(),
            spec.noise_calibration
                .as_ref()
                .map_or(String::new(), |(cq, cr)| format!(
                    ", scaled by {cq:.3} (process) and {} (sensor, per output) so that the \
                     nominal model's simulated period-to-period noise matches the logs' on \
                     every output as closely as these sources allow (a sensor's noise \
                     reaching other outputs through the controller counted)",
                    cr.iter()
                        .map(|c| format!("{c:.3}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )),
            spec.process_noise_shape
                .as_ref()
                .map_or(", white".to_string(), |n| format!(
                    ", the sensor noise white and the process noise low-pass with a correlation \
                     time of {} s (see `process_noise_shape`)",
                    fmt_num(n.correlation_s)
                )),
            match spec.criterion {
                Some(Criterion::Time) => "time",
                Some(Criterion::Frf) => "FRF",
                None if nonlinear => "time",
                None => "FRF",
            },
        ),
    })
}

impl PowerResult {
    /// `", unit"` for labels, or nothing when the model gives no unit.
    fn in_unit(&self) -> String {
        if self.unit.is_empty() {
            String::new()
        } else {
            format!(", {}", self.unit)
        }
    }

    /// The summary for people: one row per value, then the smallest detectable value.
    pub fn table(&self) -> String {
        let mut s = format!(
            "power of {} ({}{}), {} campaigns per value, seed {}; {}\n",
            self.effect,
            self.parameter,
            self.in_unit(),
            self.campaigns,
            self.seed,
            self.interval
        );
        s.push_str(&format!(
            "{:>12} {:>9} {:>17} {:>9} {:>7} {:>11} {:>12} {:>10} {:>6}\n",
            self.parameter,
            "detected",
            "95% CI",
            "tentative",
            "other",
            "unexplained",
            "estimate",
            "std",
            "failed"
        ));
        let opt = |v: Option<f64>| v.map_or("-".to_string(), fmt_num);
        for v in &self.values {
            s.push_str(&format!(
                "{:>12} {:>8.1}% {:>8.1}-{:>6.1}% {:>8.1}% {:>6.1}% {:>10.1}% {:>12} {:>10} {:>6}\n",
                fmt_num(v.value),
                100.0 * v.detection_rate,
                100.0 * v.ci[0],
                100.0 * v.ci[1],
                100.0 * v.tentative_rate,
                100.0 * v.other_found_rate,
                100.0 * v.unexplained_rate,
                opt(v.estimate_mean),
                opt(v.estimate_std),
                v.failed
            ));
            if let (Some(rate), Some([lo, hi])) = (v.false_discovery_rate, v.false_discovery_ci) {
                s.push_str(&format!(
                    "{:>12} false discoveries (any effect found with the nominal model true): \
                     {:.1}% (95% CI {:.1}-{:.1}%), nominal level {}%\n",
                    "",
                    100.0 * rate,
                    100.0 * lo,
                    100.0 * hi,
                    100.0 * self.level
                ));
            }
        }
        let m = &self.min_detectable;
        // Reached at the smallest value studied: the smallest detectable may lie below it.
        let smallest = self
            .values
            .iter()
            .map(|v| v.value)
            .fold(f64::INFINITY, f64::min);
        s.push_str(&match m.value {
            Some(v) => format!(
                "smallest {} detected with {:.0}% power: {}{} (interval {} to {})\n",
                self.parameter,
                100.0 * TARGET_POWER,
                if v <= smallest {
                    "at most "
                } else {
                    ""
                },
                fmt_num(v),
                opt(m.ci[0]),
                m.ci[1].map_or_else(
                    || {
                        // The lower Clopper-Pearson bound of n successes in n is (ALPHA/2)^(1/n).
                        let needed = ((ALPHA / 2.0).ln() / TARGET_POWER.ln()).ceil();
                        if (self.campaigns as f64) < needed {
                            format!(
                                "beyond reach with {} campaigns per value (the lower bound reaches {:.0}% from {needed})",
                                self.campaigns,
                                100.0 * TARGET_POWER
                            )
                        } else {
                            "beyond the values studied".into()
                        }
                    },
                    fmt_num
                )
            ),
            None => format!(
                "{:.0}% power is not reached within the values studied\n",
                100.0 * TARGET_POWER
            ),
        });
        if let Some(ratio) = &self.noise_ratio {
            // The campaigns of the smallest value: an effect changes the loop the noise
            // passes through, so the ratio read at a large one is not the calibration's.
            s.push_str(&format!(
                "simulated / logged period-to-period noise rms per output: {} (the campaigns at \
                 {} = {})\n",
                ratio
                    .iter()
                    .map(|r| format!("{r:.2}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                self.parameter,
                self.values
                    .first()
                    .map_or_else(String::new, |v| fmt_num(v.value))
            ));
        }
        if let Some(n) = &self.process_noise_shape {
            s.push_str(&format!(
                "process noise: low-pass, correlation time {} s (corner {} Hz): the colour whose \
                 simulated noise spectrum is the logs' across the excited band (mismatch {:.1} \
                 over {} output-bands, white noise's {:.1}; about one per output-band when they \
                 agree)\n",
                fmt_num(n.correlation_s),
                fmt_num(1.0 / (2.0 * std::f64::consts::PI * n.correlation_s)),
                n.mismatch,
                n.terms,
                n.white_mismatch
            ));
        }
        if let Some((z, estimate)) = self
            .sizing
            .as_ref()
            .and_then(|z| Some((z, z.logs_estimate?)))
        {
            let std = |v: Option<f64>| {
                v.map_or("held (not sized)".to_string(), |v| {
                    format!("±{}{}", fmt_num(v), unit_suffix(&self.unit))
                })
            };
            s.push_str(&format!(
                "sizing: the model with {} fitted to the logs: {} = {} {}; to the study's \
                 simulated nominal records: {} (median of {})\n",
                self.effect,
                self.parameter,
                fmt_num(estimate),
                std(z.logs_std),
                std(z.simulated_std),
                SIZING_DRAWS
            ));
        }
        let sizing = self.sizing.iter().flat_map(|z| z.warnings.iter());
        for w in self.noise_warnings.iter().map(|w| &w.message).chain(sizing) {
            s.push_str(&format!("warning: {w}\n"));
        }
        for f in &self.failures {
            s.push_str(&format!(
                "failed: {} = {}, campaign {}: {}\n",
                self.parameter, f.value, f.campaign, f.error
            ));
        }
        s
    }

    /// The HTML page: power against the value with its interval band, the other rates, the
    /// estimates, and the table.
    pub fn html(&self) -> String {
        use super::report::{chart, escape, page, Series, XAxis, COLORS};
        let xs: Vec<f64> = self.values.iter().map(|v| v.value).collect();
        let series = |name: &str, color: usize, y: &dyn Fn(&ValueSummary) -> f64| Series {
            name: name.to_string(),
            color: COLORS[color],
            points: self
                .values
                .iter()
                .map(|v| (v.value, 100.0 * y(v)))
                .collect(),
            markers: true,
            band: None,
        };
        let mut power = series("detected", 3, &|v| v.detection_rate);
        power.band = Some(
            self.values
                .iter()
                .map(|v| (v.value, 100.0 * v.ci[0], 100.0 * v.ci[1]))
                .collect(),
        );
        let target = Series {
            name: format!("{:.0} %", 100.0 * TARGET_POWER),
            color: COLORS[0],
            points: vec![
                (xs[0], 100.0 * TARGET_POWER),
                (xs[xs.len() - 1], 100.0 * TARGET_POWER),
            ],
            markers: false,
            band: None,
        };
        let label = format!("{} ({}){}", self.parameter, self.effect, self.in_unit());
        let mut body = format!(
            "<h1>Detection power of {}</h1><p>{} campaigns per value, seed {}. {}.</p>",
            escape(&self.effect),
            self.campaigns,
            self.seed,
            escape(&self.interval)
        );
        body.push_str(&chart(
            "power: campaigns that found the effect (%), with the 95 % band",
            XAxis::linear(&label),
            "%",
            &[power, target],
        ));
        body.push_str(&chart(
            "the effect added but tentative, other effects found, unexplained misfit (%)",
            XAxis::linear(&label),
            "%",
            &[
                series("tentative", 2, &|v| v.tentative_rate),
                series("other found", 1, &|v| v.other_found_rate),
                series("unexplained", 4, &|v| v.unexplained_rate),
            ],
        ));
        let est: Vec<&ValueSummary> = self
            .values
            .iter()
            .filter(|v| v.estimate_mean.is_some())
            .collect();
        if !est.is_empty() {
            let truth = Series {
                name: "true value".into(),
                color: COLORS[0],
                points: xs.iter().map(|x| (*x, *x)).collect(),
                markers: false,
                band: None,
            };
            let mean = Series {
                name: "mean estimate".into(),
                color: COLORS[2],
                points: est
                    .iter()
                    .filter_map(|v| Some((v.value, v.estimate_mean?)))
                    .collect(),
                markers: true,
                band: Some(
                    est.iter()
                        .filter_map(|v| {
                            let (m, s) = (v.estimate_mean?, v.estimate_std.unwrap_or(0.0));
                            Some((v.value, m - s, m + s))
                        })
                        .collect(),
                ),
            };
            body.push_str(&chart(
                "estimate where found (mean, band one standard deviation)",
                XAxis::linear(&label),
                &format!("{}{}", self.parameter, self.in_unit()),
                &[mean, truth],
            ));
        }
        body.push_str(&format!(
            "<h2>Table</h2><pre>{}</pre><p>{}</p><p>{}</p>",
            escape(&self.table()),
            escape(&self.min_detectable.note),
            escape(&self.policy)
        ));
        page(&body)
    }

    /// Writes `index.html` and `power.json` into a new directory `dir` (see
    /// [`crate::output`]: never over anything this program did not write, nor an input).
    pub fn write_report(&self, dir: &Path, inputs: &[std::path::PathBuf]) -> Result<()> {
        let json = serde_json::to_value(self)
            .and_then(|v| serde_json::to_string_pretty(&crate::output::stamped(&v)))
            .map_err(|e| SimError::invalid("json", "serialisation", e.to_string()))?;
        let html = self.html();
        crate::output::write_dir_atomically(dir, inputs, |tmp| {
            for (name, text) in [("index.html", &html), ("power.json", &json)] {
                let path = tmp.join(name);
                std::fs::write(&path, text).map_err(|e| SimError::io(&path, e))?;
            }
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODEL: &str = r#"
name = "cart"
states = ["x", "v"]
inputs = ["F"]
outputs = ["x"]
[parameters]
M = { value = 1.0, min = 0.1, max = 10.0 }
[linear]
A = [[0, 1], [0, 0]]
B = [[0], ["1/M"]]
C = [[1, 0]]
[effects.friction]
description = "viscous friction -b v"
parameters = { b = { value = 0.5, min = 0.0, max = 50.0, unit = "N s/m" } }
A = { "v,v" = "-b/M" }
[controller]
sample_rate_hz = 50
K = [[4.0, 3.0]]
"#;

    /// The cart measured in position and velocity under output feedback (a dynamic
    /// controller of one dummy state), so that the position sensor's noise reaches the
    /// velocity through the force.
    const MEASURED_BOTH: &str = r#"
name = "cart"
states = ["x", "v"]
inputs = ["F"]
outputs = ["x", "v"]
[parameters]
M = { value = 1.0, min = 0.1, max = 10.0 }
[linear]
A = [[0, 1], [0, 0]]
B = [[0], ["1/M"]]
C = [[1, 0], [0, 1]]
[effects.friction]
description = "viscous friction -b v"
parameters = { b = { value = 0.5, min = 0.0, max = 50.0 } }
A = { "v,v" = "-b/M" }
[controller]
sample_rate_hz = 50
type = "discrete"
A = [[0.0]]
B = [[0.0, 0.0]]
C = [[0.0]]
D = [[-4.0, -3.0]]
"#;

    /// A periodic multisine excitation and noisy closed-loop logs of [`MODEL`]'s structure
    /// (the values and the noise level do not matter for what the tests check).
    fn logs(experiments: usize) -> Dataset {
        logs_of(MODEL, experiments, 1e-3, &[1e-4])
    }

    /// The same for the model file `model`, with white process noise of rms `process_sd` on
    /// the velocity and sensor noise of rms `sensor_sd` on each output.
    fn logs_of(model: &str, experiments: usize, process_sd: f64, sensor_sd: &[f64]) -> Dataset {
        coloured_logs(model, (experiments, 4), process_sd, 0.0, sensor_sd, 7)
    }

    /// The same with `periods` periods per experiment and process noise of rms `process_sd`
    /// low-passed to a correlation time `correlation_s` (AR(1), stationary; 0: white), drawn
    /// with `seed`.
    fn coloured_logs(
        model: &str,
        (experiments, periods): (usize, usize),
        process_sd: f64,
        correlation_s: f64,
        sensor_sd: &[f64],
        seed: u64,
    ) -> Dataset {
        let (period, transient) = (250, 100);
        let samples = transient + period * periods;
        let pole = if correlation_s > 0.0 {
            (-1.0 / (50.0 * correlation_s)).exp()
        } else {
            0.0
        };
        let structure = Arc::new(ModelFile::parse(model, Path::new("cart.toml")).unwrap());
        let outputs = super::super::model::ModelStructure::outputs(structure.as_ref());
        let ss = Model::new(structure.clone())
            .with_effect("friction")
            .unwrap()
            .state_space(&[1.1, 0.8])
            .unwrap();
        let disc = ss.discretize(1.0 / 50.0).unwrap();
        let controller =
            super::super::model::ModelStructure::controller(structure.as_ref()).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Dataset {
            sample_rate_hz: 50.0,
            inputs: vec!["F".into()],
            outputs,
            experiments: (0..experiments)
                .map(|e| {
                    let r = DMatrix::from_fn(samples, 1, |k, _| {
                        (1..40)
                            .map(|l| {
                                let w = 2.0 * std::f64::consts::PI * l as f64 / period as f64;
                                (w * k as f64 + (l * l + e) as f64).sin()
                            })
                            .sum::<f64>()
                            * 0.1
                    });
                    // Stationary from the first sample (no draw for white noise, whose logs
                    // stay those of the other tests).
                    let mut gust = if pole > 0.0 {
                        process_sd * Distribution::<f64>::sample(&StandardNormal, &mut rng)
                    } else {
                        0.0
                    };
                    let (u, y) = run_loop(&disc, &controller, &r, &mut |w, v| {
                        let z: f64 = Distribution::<f64>::sample(&StandardNormal, &mut rng);
                        gust = pole * gust + (1.0 - pole * pole).sqrt() * process_sd * z;
                        w[1] = gust;
                        for (vi, sd) in v.iter_mut().zip(sensor_sd) {
                            *vi = sd * Distribution::<f64>::sample(&StandardNormal, &mut rng);
                        }
                    })
                    .unwrap();
                    Experiment {
                        name: format!("e{e}"),
                        u,
                        y,
                        r: Some(r),
                        periodic: Some(Periodic {
                            period,
                            periods,
                            transient,
                        }),
                    }
                })
                .collect(),
        }
    }

    fn options(values: Vec<f64>, campaigns: usize) -> StudyOptions {
        StudyOptions {
            effect: "friction".into(),
            values,
            campaigns,
            seed: 3,
            estimator: "auto".into(),
            band_hz: None,
            criterion: None,
            cancel: Cancel::default(),
        }
    }

    #[test]
    fn campaigns_are_pure_functions_of_spec_value_and_seed() {
        let spec = prepare(
            MODEL,
            Path::new("cart.toml"),
            logs(2),
            &options(vec![0.0, 2.0], 3),
        )
        .unwrap();
        // Through JSON (as shipped to a Dask worker) the spec is the same to the bit.
        let text = serde_json::to_string(&spec).unwrap();
        let back: StudySpec = serde_json::from_str(&text).unwrap();
        assert_eq!(back, spec);
        assert_eq!(spec.unit, "N s/m");
        let study = Study::new(back).unwrap();
        let jobs = study.jobs();
        let serial = run(&study, &jobs, 1, &|_| {}, &Cancel::default()).unwrap();
        let reversed: Vec<_> = jobs.iter().rev().copied().collect();
        let mut parallel = run(&study, &reversed, 3, &|_| {}, &Cancel::default()).unwrap();
        parallel.reverse();
        assert_eq!(serial, parallel);
        // Cancelled after its first campaign, a run starts no other and returns no outcome.
        let cancel = Cancel::default();
        let done = AtomicUsize::new(0);
        let stopped = run(
            &study,
            &jobs,
            1,
            &|n| {
                done.store(n, Ordering::Relaxed);
                cancel.cancel();
            },
            &cancel,
        );
        assert!(matches!(stopped, Err(SimError::Cancelled)), "{stopped:?}");
        assert_eq!(done.load(Ordering::Relaxed), 1);
        // Different campaigns draw different noise; the same campaign the same.
        let a = study.simulate(1, 0).unwrap();
        let b = study.simulate(1, 1).unwrap();
        assert_eq!(a, study.simulate(1, 0).unwrap());
        assert_ne!(a.experiments[0].y, b.experiments[0].y);
        // Another seed, other noise.
        let mut other = spec.clone();
        other.seed = 4;
        assert_ne!(Study::new(other).unwrap().simulate(1, 0).unwrap(), a);
        assert!(serial.iter().all(|o| o.error.is_none()), "{serial:?}");
    }

    /// The sizing's standard error is the scatter of the campaigns' estimates: on 3 of 3 seeds
    /// the simulated records' error is within 1.6 times (both ways) of the standard deviation
    /// of 20 campaigns' estimates at 20 standard errors (0.83 on each seed: the fit's error
    /// reads the scatter a little small), the logs' within 1.5 of the simulated (1.01-1.28),
    /// and the study warns of nothing.
    #[test]
    fn the_sizing_predicts_the_campaigns_scatter() {
        for seed in [7, 8, 9] {
            let logs = coloured_logs(MODEL, (2, 4), 1e-3, 0.0, &[1e-4], seed);
            let spec = prepare(
                MODEL,
                Path::new("cart.toml"),
                logs,
                &options(vec![0.0, 2.0], 20),
            )
            .unwrap();
            let z = spec.sizing.clone().unwrap();
            assert!(z.warnings.is_empty(), "seed {seed}: {z:?}");
            let (logs_std, sim) = (z.logs_std.unwrap(), z.simulated_std.unwrap());
            assert!(
                (1.0 / SIZING_TOLERANCE..=SIZING_TOLERANCE).contains(&(logs_std / sim)),
                "seed {seed}: {z:?}"
            );
            let at = StudySpec {
                values: vec![20.0 * sim],
                ..spec
            };
            let study = Study::new(at.clone()).unwrap();
            let out = run(&study, &study.jobs(), 2, &|_| {}, &Cancel::default()).unwrap();
            let r = aggregate(&at, &out).unwrap();
            assert!(
                r.values[0].detection_rate >= 0.8,
                "seed {seed}: {}",
                r.table()
            );
            let scatter = r.values[0].estimate_std.unwrap();
            assert!(
                (1.0 / 1.6..=1.6).contains(&(sim / scatter)),
                "seed {seed}: simulated std {sim}, campaigns' scatter {scatter}"
            );
        }
    }

    /// The study with noise sources a ninth of `spec`'s (a third in rms).
    fn quieted(spec: &StudySpec) -> StudySpec {
        let mut quiet = spec.clone();
        quiet
            .process_noise
            .iter_mut()
            .flatten()
            .for_each(|q| *q /= 9.0);
        quiet.sensor_noise.iter_mut().for_each(|r| *r /= 9.0);
        quiet
    }

    /// Noise that hides the effect far less than the logs' is scaled until it hides it as
    /// much, measured again on the scaled noise, when the nominal model explains the logs;
    /// logs with a misfit keep the noise and say why.
    #[test]
    fn noise_that_hides_the_effect_otherwise_is_scaled_along_it() {
        let nominal_p = |spec: &StudySpec, logs: &Dataset| {
            let wb = Study::new(spec.clone())
                .unwrap()
                .workbench(logs.clone())
                .unwrap();
            wb.noise_p_value(&wb.compare().unwrap())
        };
        let study_of = |logs: &Dataset| {
            prepare(
                MODEL,
                Path::new("cart.toml"),
                logs.clone(),
                &options(vec![0.0, 2.0], 20),
            )
            .unwrap()
        };
        // The unit tests' logs carry a friction of 0.8 the nominal model lacks; a campaign of
        // their study at b = 0 gives logs of the nominal model itself, which it explains.
        let friction_logs = logs(2);
        let friction = study_of(&friction_logs);
        let logs = Study::new(friction.clone())
            .unwrap()
            .simulate(0, 0)
            .unwrap();
        let spec = study_of(&logs);
        let p = nominal_p(&spec, &logs);
        assert!(p >= LEVEL, "{p}");
        // At the calibrated noise the two errors agree within the tolerance: no scaling.
        let full = spec.sizing.clone().unwrap();
        assert!(
            full.rescaled.is_none() && full.noise_scale().is_none(),
            "{full:?}"
        );
        // Noise sources a ninth of it: the logs' error is about 3 times the simulated.
        let mut quiet = quieted(&spec);
        size_along_effect(&mut quiet, &logs, p, &Cancel::default()).unwrap();
        let z = quiet.sizing.clone().unwrap();
        let r = z.rescaled.clone().unwrap();
        assert!((2.0..4.5).contains(&r.factor), "{z:?}");
        assert!(
            (r.factor - z.logs_std.unwrap() / r.unscaled_std).abs() < 1e-12,
            "{z:?}"
        );
        // Every source scaled by the factor's square in variance.
        let k2 = r.factor * r.factor / 9.0;
        for (scaled, calibrated) in quiet.sensor_noise.iter().zip(&spec.sensor_noise) {
            assert!((scaled / calibrated - k2).abs() < 1e-12 * k2);
        }
        for (scaled, calibrated) in quiet
            .process_noise
            .iter()
            .flatten()
            .zip(spec.process_noise.iter().flatten())
        {
            assert!((scaled - calibrated * k2).abs() <= 1e-12 * calibrated.abs() * k2);
        }
        // The scaled noise's records size the parameter as the logs do (measured anew).
        let ratio = z.logs_std.unwrap() / z.simulated_std.unwrap();
        assert!((1.0 / 1.15..1.15).contains(&ratio), "{z:?}");
        assert!(
            matches!(z.warnings.as_slice(), [w] if w.contains("scales every noise source by")),
            "{z:?}"
        );
        // On the logs with the friction the nominal model's misfit widens the logs' error
        // too, and the quieted study warns without scaling.
        let p = nominal_p(&friction, &friction_logs);
        assert!(p < LEVEL, "{p}");
        let mut quiet = quieted(&friction);
        size_along_effect(&mut quiet, &friction_logs, p, &Cancel::default()).unwrap();
        let z = quiet.sizing.clone().unwrap();
        assert!(z.rescaled.is_none() && z.noise_scale().is_some(), "{z:?}");
        assert!(
            z.warnings.iter().any(|w| w.contains("likely too high"))
                && z.warnings
                    .iter()
                    .any(|w| w.contains("does not scale its noise")),
            "{z:?}"
        );
        assert_eq!(quiet.process_noise, quieted(&friction).process_noise);
    }

    /// Values the logs cannot size apart from 0, noise that hides the effect less than the
    /// logs' and an effect the outputs cannot tell from a nominal parameter are each named;
    /// the campaigns then bear the warnings out.
    #[test]
    fn the_sizing_warns_where_the_study_cannot_be_trusted() {
        let logs = logs(2);
        let spec = prepare(
            MODEL,
            Path::new("cart.toml"),
            logs.clone(),
            &options(vec![0.0, 2.0], 20),
        )
        .unwrap();
        let logs_std = spec.sizing.as_ref().unwrap().logs_std.unwrap();
        // A largest value of half a standard error: named, and found in at most 2 of 20.
        let small = StudySpec {
            values: vec![0.0, 0.5 * logs_std],
            ..spec.clone()
        };
        let study = Study::new(small.clone()).unwrap();
        let z = study.sizing(&logs, &Cancel::default()).unwrap();
        assert!(
            matches!(z.warnings.as_slice(), [w] if w.contains("0.50 standard errors from 0")),
            "{z:?}"
        );
        let out = run(&study, &study.jobs(), 2, &|_| {}, &Cancel::default()).unwrap();
        let r = aggregate(&small, &out).unwrap();
        assert!(r.values[1].detection_rate <= 0.1, "{}", r.table());
        // Noise sources a ninth of the estimated (a third in rms): the simulated records size
        // the friction 3.1 times as precisely as at the estimated noise (the logs' error
        // 4.25 times the simulated, 1.36 times at the estimated noise), and the study says
        // its rates are likely too high.
        let full = spec.sizing.as_ref().unwrap();
        let full_ratio = full.logs_std.unwrap() / full.simulated_std.unwrap();
        let z = Study::new(quieted(&spec))
            .unwrap()
            .sizing(&logs, &Cancel::default())
            .unwrap();
        let ratio = z.logs_std.unwrap() / z.simulated_std.unwrap();
        assert!((2.4..3.6).contains(&(ratio / full_ratio)), "{z:?}");
        assert!(
            matches!(z.warnings.as_slice(), [w] if w.contains("likely too high")),
            "{z:?}"
        );
        // A payload that adds to the cart's mass: the outputs see M + m only.
        let payload = format!(
            "{MODEL}\n[effects.payload]\ndescription = \"a payload on the cart\"\n\
             parameters = {{ m = {{ value = 0.2, min = 0.0, max = 5.0, unit = \"kg\" }} }}\n\
             B = {{ \"v,F\" = \"1/(M+m)\" }}\n"
        );
        let spec = prepare(
            &payload,
            Path::new("cart.toml"),
            logs.clone(),
            &StudyOptions {
                effect: "payload".into(),
                ..options(vec![0.0, 0.5], 4)
            },
        )
        .unwrap();
        let z = spec.sizing.clone().unwrap();
        assert_eq!(z.trades_against, ["M"], "{z:?}");
        assert!(
            matches!(z.warnings.as_slice(), [w] if w.contains("cannot tell m from M")),
            "{z:?}"
        );
        let study = Study::new(spec.clone()).unwrap();
        let out = run(&study, &study.jobs(), 2, &|_| {}, &Cancel::default()).unwrap();
        let r = aggregate(&spec, &out).unwrap();
        assert_eq!(r.values[1].detection_rate, 0.0, "{}", r.table());
        assert!(r.table().contains("warning: the outputs cannot tell m"));
        // A fit to the logs that fails leaves the study without a sizing, which says why; a
        // cancel stops it.
        let study = Study::new(spec).unwrap();
        let failed = || Err(SimError::invalid("fit", "logs", "diverged"));
        let z = study.sizing_of([failed(), failed()].into_iter()).unwrap();
        assert!(
            z.logs_estimate.is_none()
                && matches!(z.warnings.as_slice(), [w] if w.starts_with("no sizing: the model with payload could not be fitted to the logs (invalid fit = logs: diverged)")),
            "{z:?}"
        );
        assert!(matches!(
            study.sizing_of([Err(SimError::Cancelled)].into_iter()),
            Err(SimError::Cancelled)
        ));
    }

    /// The verdict's false alarms on the nominal model are at its level: 100 nominal
    /// campaigns of 1, 2 and 4 records (4 periods of 250 samples after a 100-sample start,
    /// under feedback, process and sensor noise), on logs of 2 seeds, read "unexplained" in at
    /// most 4 (measured 1 of 100 in each of the six; binomial at 1 %: 4 or more in 1.8 % of
    /// such runs), and find no effect. With the record's transient left in the line and its
    /// noise estimate, 3, 7 and 23 of 100 on the first seed (2, 4 and 21 on the second).
    #[test]
    fn nominal_campaigns_read_unexplained_at_the_level() {
        for experiments in [1, 2, 4] {
            for seed in [7, 8] {
                let logs = coloured_logs(MODEL, (experiments, 4), 1e-3, 0.0, &[1e-4], seed);
                let spec = prepare(
                    MODEL,
                    Path::new("cart.toml"),
                    logs,
                    &options(vec![0.0], 100),
                )
                .unwrap();
                let study = Study::new(spec.clone()).unwrap();
                let out = run(&study, &study.jobs(), 2, &|_| {}, &Cancel::default()).unwrap();
                let r = aggregate(&spec, &out).unwrap();
                let v = &r.values[0];
                let what = format!("{experiments} records, seed {seed}");
                assert!(out.iter().all(|o| o.error.is_none()), "{what}: {out:?}");
                assert!(v.unexplained_rate <= 0.04, "{what}: {}", r.table());
                assert_eq!(v.detection_rate, 0.0, "{what}: {}", r.table());
            }
        }
    }

    #[test]
    fn a_lag_study_takes_zero_and_the_bounds_sized_to_the_logs() {
        // The logs' lines are 0.2 Hz apart, so `tau` runs to 1 / (2 pi 0.2) = 0.8 s, beyond the
        // 0.5 s of a model without data; 0 (below tau's lower bound) is the lag absent.
        let lag = StudyOptions {
            effect: "actuator_lag".into(),
            ..options(vec![0.0, 0.6], 1)
        };
        let spec = prepare(MODEL, Path::new("cart.toml"), logs(1), &lag).unwrap();
        assert!(
            spec.bounds[0] > 0.0 && spec.bounds[1] > 0.6,
            "{:?}",
            spec.bounds
        );
        let back: StudySpec = serde_json::from_str(&serde_json::to_string(&spec).unwrap()).unwrap();
        let study = Study::new(back).unwrap();
        // At 0 the campaign simulates the nominal model: the same logs as a friction study's
        // at b = 0 (same seed, value and campaign).
        let friction = prepare(
            MODEL,
            Path::new("cart.toml"),
            logs(1),
            &options(vec![0.0], 1),
        );
        let friction = Study::new(friction.unwrap()).unwrap();
        assert_eq!(
            study.simulate(0, 0).unwrap(),
            friction.simulate(0, 0).unwrap()
        );
        assert_ne!(
            study.simulate(1, 0).unwrap(),
            friction.simulate(0, 0).unwrap()
        );
        let beyond = StudyOptions {
            effect: "actuator_lag".into(),
            ..options(vec![0.0, 5.0], 1)
        };
        let err = prepare(MODEL, Path::new("cart.toml"), logs(1), &beyond).unwrap_err();
        assert!(
            err.to_string()
                .contains("tau must be 0 (the effect absent)"),
            "{err}"
        );
    }

    /// A low-pass process noise (correlation time 0.5 s, corner 0.32 Hz, in a band of 0.2-8
    /// Hz) is read from the logs' band spectrum: the study's correlation time is within an
    /// octave of the truth on 3 of 3 seeds (0.52, 0.26, 0.26 s), and its simulated band noise
    /// then matches the logs' (no band warning; mismatch 1.4-18 over 4 output-bands, white
    /// noise's 38-71). With white process noise the study keeps white noise (3 of 3 seeds).
    #[test]
    fn a_low_pass_process_noise_is_read_from_the_logs_spectrum() {
        for seed in [1, 2, 3] {
            let study = |correlation_s: f64, sensor_sd: f64| {
                let logs = coloured_logs(MODEL, (4, 8), 1e-3, correlation_s, &[sensor_sd], seed);
                let options = StudyOptions {
                    seed,
                    ..options(vec![0.0], 1)
                };
                prepare(MODEL, Path::new("cart.toml"), logs, &options).unwrap()
            };
            let spec = study(0.5, 1e-5);
            let shape = spec.process_noise_shape.clone().expect("a shape");
            assert!(
                (0.25..=1.0).contains(&shape.correlation_s),
                "seed {seed}: {shape:?}"
            );
            // Its mismatch is about one per output-band: the spectrum is the logs'.
            assert!(
                shape.mismatch < 6.0 * shape.terms as f64,
                "seed {seed}: {shape:?}"
            );
            assert!(
                spec.noise_warnings.iter().all(|w| w.band_hz.is_none()),
                "seed {seed}: {:?}",
                spec.noise_warnings
            );
            assert_eq!(study(0.0, 1e-4).process_noise_shape, None, "seed {seed}");
        }
    }

    #[test]
    fn simulated_noise_has_the_estimated_covariances() {
        // With the effect at 0 and no excitation, the measured output is the loop's response
        // to the drawn noise alone; its first differences are dominated by the sensor noise
        // (2 sigma^2 for white noise), which is what the spec says.
        let spec = prepare(
            MODEL,
            Path::new("cart.toml"),
            logs(1),
            &options(vec![0.0], 1),
        )
        .unwrap();
        let mut quiet = spec.clone();
        for row in &mut quiet.experiments[0].r {
            row.fill(0.0);
        }
        quiet.process_noise.iter_mut().for_each(|r| r.fill(0.0));
        quiet.sensor_noise = vec![4e-6];
        let y = Study::new(quiet)
            .unwrap()
            .simulate(0, 0)
            .unwrap()
            .experiments[0]
            .y
            .clone();
        let d: Vec<f64> = (1..y.nrows()).map(|k| y[(k, 0)] - y[(k - 1, 0)]).collect();
        let ms = d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64;
        // Not exactly 2 sigma^2: the loop feeds the sensor noise back into the state.
        assert!((ms / (2.0 * 4e-6) - 1.0).abs() < 0.25, "{ms}");
        assert!(spec.sensor_noise[0] > 0.0 && spec.process_noise.len() == 2);
        // Calibrated: on every output the campaigns' period-to-period noise (rms over 32
        // campaigns, an estimate independent of the check's eight records) is the logs', or
        // the study warns about that output with that ratio. On the cart measured in position
        // alone it is the logs'. Measured in both, most of the velocity's noise is the
        // position sensor's, reaching it through the controller's force (4e-3 N rms, 7e-5 m/s
        // per sample; its own sensor noise is 5e-5 and its process noise 2e-5 per sample),
        // and the Kalman estimate's noise sources cannot give both outputs their logged noise.
        for (model, process_sd, sensor_sd) in [
            (MODEL, 1e-3, vec![1e-4]),
            (MEASURED_BOTH, 2e-5, vec![1e-3, 5e-5]),
        ] {
            for seed in [3, 4] {
                let spec = prepare(
                    model,
                    Path::new("cart.toml"),
                    logs_of(model, 2, process_sd, &sensor_sd),
                    &StudyOptions {
                        seed,
                        ..options(vec![0.0], 1)
                    },
                )
                .unwrap();
                let study = Study::new(spec.clone()).unwrap();
                let measured = spec.measured_noise_rms.clone().unwrap();
                let draws = 32;
                let mut simulated = vec![0.0; measured.len()];
                for c in 0..draws {
                    let rms = period_noise_rms(&study.simulate(0, c).unwrap()).unwrap();
                    for (s, r) in simulated.iter_mut().zip(rms) {
                        *s += r * r / draws as f64;
                    }
                }
                for (i, (s, m)) in simulated.iter().zip(&measured).enumerate() {
                    let ratio = s.sqrt() / m;
                    let warned = spec
                        .noise_warnings
                        .iter()
                        .find(|w| w.band_hz.is_none() && w.output == study.outputs[i]);
                    match warned {
                        None => assert!((ratio - 1.0).abs() < 0.15, "output {i}: {ratio}"),
                        Some(w) => assert!(
                            (w.ratio / ratio - 1.0).abs() < 0.1 && (ratio - 1.0).abs() > 0.1,
                            "output {i}: {ratio} warned {}",
                            w.ratio
                        ),
                    }
                }
                if model == MODEL {
                    assert!(spec.noise_warnings.is_empty(), "{:?}", spec.noise_warnings);
                }
            }
        }
    }

    proptest::proptest! {
        /// Without cross terms every output gets its logged noise back
        /// (`cq a_i + cr_i b_ii = 1`) where its sensor's floor fits, no factor is negative,
        /// every sensor keeps its floor, and where one common factor fits every output, cross
        /// terms or not, it is kept.
        #[test]
        fn calibration_matches_every_output(
            ab in proptest::collection::vec((0.0f64..10.0, 1e-3f64..10.0), 1..5),
            // Cross terms below a third keep the sensors' matrix diagonally dominant: near
            // 1 it is near singular, and the common factor is then one of many fits.
            cross in proptest::collection::vec(0.0f64..0.3, 16),
            shared in 0.01f64..100.0,
        ) {
            let m = ab.len();
            let (a, b): (Vec<f64>, Vec<f64>) = ab.iter().copied().unzip();
            let diagonal = DMatrix::from_diagonal(&DVector::from_vec(b.clone()));
            let (cq, cr) = calibration_factors(&a, &diagonal).unwrap();
            proptest::prop_assert!(cq >= 0.0);
            let both: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
            let common = both.iter().sum::<f64>() / both.iter().map(|v| v * v).sum::<f64>();
            let floor = SENSOR_FLOOR * common;
            for i in 0..m {
                proptest::prop_assert!(cr[i] >= floor * (1.0 - 1e-9), "output {i}: {} < {floor}", cr[i]);
                if floor * b[i] <= 1.0 {
                    let v = cq * a[i] + cr[i] * b[i];
                    proptest::prop_assert!((v - 1.0).abs() < 1e-9, "output {i}: {v}");
                }
            }
            // Variances that one factor fits exactly, with a sensor reaching every output: that
            // factor for both noises.
            let full = DMatrix::from_fn(m, m, |i, j| if i == j { b[i] } else { cross[i * 4 + j] * b[j] });
            let t: Vec<f64> = (0..m).map(|i| 1.0 / (shared * (a[i] + full.row(i).sum()))).collect();
            let a2: Vec<f64> = a.iter().zip(&t).map(|(x, t)| x * t).collect();
            let b2 = DMatrix::from_fn(m, m, |i, j| full[(i, j)] * t[i]);
            let (cq, cr) = calibration_factors(&a2, &b2).unwrap();
            proptest::prop_assert!((cq / shared - 1.0).abs() < 1e-9, "{cq} {shared}");
            proptest::prop_assert!(cr.iter().all(|c| (c / shared - 1.0).abs() < 1e-6), "{cr:?}");
        }

        /// The active-set solution has the least residual of every sign-constrained one: that
        /// of the best unconstrained least-squares fit on any subset of the columns whose
        /// solution is non-negative (the optimum is one of them).
        #[test]
        fn nnls_is_the_best_non_negative_fit(
            values in proptest::collection::vec(-1.0f64..1.0, 24),
            rhs in proptest::collection::vec(-1.0f64..1.0, 6),
            cols in 1usize..5,
        ) {
            let rows = 6;
            let a = DMatrix::from_fn(rows, cols, |i, j| values[i * 4 + j]);
            let b = DVector::from_vec(rhs);
            let x = nnls(&a, &b);
            proptest::prop_assert!(x.iter().all(|v| *v >= 0.0));
            let residual = (&b - &a * &x).norm();
            let mut best = b.norm();
            for mask in 1..(1usize << cols) {
                let set: Vec<usize> = (0..cols).filter(|j| mask & (1 << j) != 0).collect();
                let sub = a.select_columns(&set);
                let z = sub.clone().svd(true, true).solve(&b, 1e-14).unwrap();
                if z.iter().all(|v| *v >= 0.0) {
                    best = best.min((&b - &sub * &z).norm());
                }
            }
            proptest::prop_assert!(residual <= best + 1e-9, "{residual} > {best}");
        }
    }

    #[test]
    fn band_noise_over_every_line_is_the_period_noise_by_parseval() {
        // With an odd period (no Nyquist line) and deviations of zero mean (no DC line), the
        // lines 1..(P-1)/2 carry half of each period's energy (Parseval), so their mean power
        // is the period-to-period variance times P / (P - 1).
        let (period, periods) = (63, 3);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for seed in 0..3 {
            let mut y = DMatrix::from_fn(period * periods, 2, |_, _| {
                Distribution::<f64>::sample(&StandardNormal, &mut rng) * (1.0 + seed as f64)
            });
            for j in 0..periods {
                for i in 0..2 {
                    let mean = y.view((j * period, i), (period, 1)).mean();
                    y.view_mut((j * period, i), (period, 1))
                        .add_scalar_mut(-mean);
                }
            }
            let samples = y.nrows();
            let data = Dataset {
                sample_rate_hz: 63.0,
                inputs: vec!["F".into()],
                outputs: vec!["a".into(), "b".into()],
                experiments: vec![Experiment {
                    name: "e".into(),
                    u: DMatrix::zeros(samples, 1),
                    y,
                    r: Some(DMatrix::zeros(samples, 1)),
                    periodic: Some(Periodic {
                        period,
                        periods,
                        transient: 0,
                    }),
                }],
            };
            let band = band_noise(&data, &[(0.5, 31.6)]).unwrap();
            let rms = period_noise_rms(&data).unwrap();
            for i in 0..2 {
                let expected = rms[i].powi(2) * period as f64 / (period - 1) as f64;
                assert!(
                    (band[(i, 0)] / expected - 1.0).abs() < 1e-12,
                    "{} {expected}",
                    band[(i, 0)]
                );
            }
        }
    }

    #[test]
    fn calibration_without_simulated_noise_is_refused() {
        assert!(calibration_factors(&[0.0, 0.0], &DMatrix::zeros(2, 2)).is_none());
    }

    fn outcome(v: usize, c: usize, found: bool, estimate: Option<f64>) -> Outcome {
        Outcome {
            value_index: v,
            campaign: c,
            found,
            other_found: Vec::new(),
            unexplained: false,
            tentative: false,
            estimate,
            error: None,
            noise_rms: None,
        }
    }

    fn spec_of(values: Vec<f64>, campaigns: usize) -> StudySpec {
        StudySpec {
            model_text: String::new(),
            model_path: String::new(),
            effect: "friction".into(),
            parameter: "b".into(),
            unit: "N s/m".into(),
            values,
            bounds: [0.0, 50.0],
            campaigns,
            seed: 0,
            nominal: Vec::new(),
            process_noise: Vec::new(),
            sensor_noise: Vec::new(),
            sample_rate_hz: 50.0,
            experiments: Vec::new(),
            estimator: "auto".into(),
            band_hz: None,
            criterion: None,
            measured_noise_rms: None,
            noise_calibration: None,
            noise_warnings: Vec::new(),
            process_noise_shape: None,
            sizing: None,
        }
    }

    #[test]
    fn aggregates_rates_intervals_and_the_crossing() {
        let spec = spec_of(vec![0.0, 1.0, 2.0], 4);
        let mut out = Vec::new();
        // Value 0: one false find of another effect, one failure.
        for c in 0..4 {
            let mut o = outcome(0, c, false, None);
            if c == 1 {
                o.other_found = vec!["actuator_lag".into()];
            }
            if c == 3 {
                o.error = Some("diverged".into());
            }
            out.push(o);
        }
        // Value 1: 2 of 4 found, estimates 0.9 and 1.3, one more added but tentative (its
        // estimate is not a found one's). Value 2: all found.
        for c in 0..4 {
            let mut o = outcome(1, c, c < 2, (c < 2).then(|| [0.9, 1.3][c]));
            o.tentative = c == 2;
            out.push(o);
            out.push(outcome(2, c, true, Some(2.0)));
        }
        let in_order = aggregate(&spec, &out).unwrap();
        out.reverse();
        let r = aggregate(&spec, &out).unwrap();
        assert_eq!(r, in_order);
        let v0 = &r.values[0];
        assert_eq!((v0.completed, v0.failed), (3, 1));
        assert_eq!(v0.detection_rate, 0.0);
        assert!((v0.other_found_rate - 1.0 / 3.0).abs() < 1e-15);
        assert_eq!(v0.false_discovery_rate, Some(1.0 / 3.0));
        assert_eq!(r.failures.len(), 1);
        assert_eq!(r.failures[0].error, "diverged");
        let v1 = &r.values[1];
        assert_eq!(v1.detection_rate, 0.5);
        assert_eq!((v0.tentative_rate, v1.tentative_rate), (0.0, 0.25));
        assert_eq!(v1.ci, {
            let (a, b) = clopper_pearson(2, 4, 0.05);
            [a, b]
        });
        assert!((v1.estimate_mean.unwrap() - 1.1).abs() < 1e-12);
        assert!((v1.estimate_std.unwrap() - (0.08f64).sqrt()).abs() < 1e-12);
        assert_eq!(v1.false_discovery_rate, None);
        // 95 % between 1 (0.5) and 2 (1.0): 1 + 0.45 / 0.5.
        assert!((r.min_detectable.value.unwrap() - 1.9).abs() < 1e-12);
        // The upper bound is above 0.95 already at 1 (2 of 4); the lower bound at 2
        // (4 of 4: 0.025^(1/4) = 0.398) never reaches it.
        assert_eq!(r.min_detectable.ci[1], None);
        assert!(r.min_detectable.ci[0].unwrap() <= 1.9);
        // A campaign given twice, or not of the study, is refused.
        out.push(outcome(2, 0, true, None));
        assert!(aggregate(&spec, &out).is_err());
        assert!(aggregate(&spec, &[outcome(5, 0, true, None)]).is_err());
    }

    #[test]
    fn the_table_prints_small_values_with_four_significant_digits() {
        // A Furuta pendulum's joint friction: every value below 1e-4 read 0.0000.
        let spec = spec_of(vec![0.0, 2e-6, 4e-6, 8e-6, 1.6e-5], 4);
        let mut out = Vec::new();
        for (v, found) in [0, 1, 2, 4, 4].into_iter().enumerate() {
            for c in 0..4 {
                let value = spec.values[v];
                out.push(outcome(
                    v,
                    c,
                    c < found,
                    (c < found).then_some(value * 1.05),
                ));
            }
        }
        let r = aggregate(&spec, &out).unwrap();
        let m = r.min_detectable.value.unwrap();
        assert!(m > 4e-6 && m < 8e-6, "{m}");
        let table = r.table();
        assert!(!table.contains("0.0000"), "{table}");
        // The parameter's unit names the values, in the table and on the report's axes.
        assert!(table.starts_with("power of friction (b, N s/m)"), "{table}");
        assert!(r.html().contains("b (friction), N s/m"));
        for v in ["2.000e-6", "4.000e-6", "8.000e-6", "1.600e-5", "8.400e-6"] {
            assert!(table.contains(v), "{v} missing from\n{table}");
        }
        let line = table
            .lines()
            .find(|l| l.starts_with("smallest b detected"))
            .unwrap();
        assert!(
            line.contains(&format!("power: {} (interval", fmt_num(m))),
            "{line}"
        );
        // The interval's ends are printed the same way; with 4 campaigns per value its upper
        // end cannot be reached (0.025^(1/n) >= 0.95 from n = 72), which the line says.
        let ci = |v: Option<f64>| v.map_or("beyond the values studied".into(), fmt_num);
        assert!(r.min_detectable.ci[1].is_none());
        assert!(
            line.ends_with(&format!(
                "{} to beyond reach with 4 campaigns per value (the lower bound reaches 95% from 72))",
                ci(r.min_detectable.ci[0]),
            )),
            "{line}"
        );
        // Reached at the smallest value studied, the smallest detectable may lie below it (a
        // bicycle's steer friction studied at 0.5 and 1.0 read "0.5000").
        let spec = spec_of(vec![0.5, 1.0], 4);
        let out: Vec<_> = (0..2)
            .flat_map(|v| (0..4).map(move |c| outcome(v, c, true, Some(0.5))))
            .collect();
        let table = aggregate(&spec, &out).unwrap().table();
        assert!(
            table.contains("smallest b detected with 95% power: at most 0.5000 (interval"),
            "{table}"
        );
    }

    #[test]
    fn refuses_effects_values_and_logs_it_cannot_study() {
        let bad = |o: StudyOptions| {
            prepare(MODEL, Path::new("cart.toml"), logs(1), &o)
                .unwrap_err()
                .to_string()
        };
        assert!(bad(options(vec![1.0, 0.5], 1)).contains("must increase"));
        assert!(bad(options(vec![-1.0], 1)).contains("bounds"));
        let mut o = options(vec![1.0], 1);
        o.effect = "nothing_like_it".into();
        assert!(bad(o).contains("nothing_like_it"));
        let mut data = logs(1);
        data.experiments[0].r = None;
        let msg = prepare(MODEL, Path::new("cart.toml"), data, &options(vec![1.0], 1))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("excitation"), "{msg}");
        let no_controller = MODEL.split("[controller]").next().unwrap();
        let msg = prepare(
            no_controller,
            Path::new("cart.toml"),
            logs(1),
            &options(vec![1.0], 1),
        )
        .unwrap_err()
        .to_string();
        assert!(msg.contains("[controller]"), "{msg}");
    }
}
