//! The model workbench: compare a model with measurements, see where it fails, find which
//! physical effect is missing, add it and watch the weighted error fall.
//!
//! The chain is the flying-platform paper's identification made general:
//! 1. a non-parametric FRF from all experiments ([`frf`]: least squares, or the
//!    instrumental-variable estimate when the excitation is logged, which stays unbiased in
//!    closed loop), with its covariance from period-to-period variation; for non-periodic logs
//!    the Welch estimate ([`welch`]: H1, or its instrumental-variable form with the excitation);
//! 2. the variance-weighted cost ([`cost`]) and what it would be from noise alone ([`noise`]);
//! 3. Levenberg-Marquardt fits with standard errors ([`fit`]);
//! 4. diagnosis by line and channel ([`diagnose`]), in the time domain ([`timedomain`]: fit %
//!    of simulation and k-step prediction; [`residual`]: whiteness and input correlation) and
//!    the discovery loop ([`discover`]).
//!
//! The crate knows no system: a system is a [`ModelStructure`] (the simulator crate adapts the
//! flying platform and the Cubli; a user writes a model file, [`ModelFile`]). Below the chain
//! lie the data it reads and writes: [`log`] (MCAP and CSV logs), [`output`] (never over an
//! input, temporary file + rename), [`limits`] (memory budgets) and the one [`error`] type.
pub mod cancel;
pub mod closed_loop;
pub mod coherence;
pub mod cost;
pub mod dataset;
pub mod diagnose;
pub mod discover;
pub mod distortion;
pub mod dynamics;
pub mod error;
pub mod expr;
pub mod fit;
pub mod frf;
pub mod generic;
pub mod identifiability;
pub mod kalman;
pub mod limits;
pub mod load;
pub mod log;
pub mod model;
pub mod model_file;
pub mod noise;
pub mod output;
pub mod power;
pub mod prediction;
pub mod report;
pub mod residual;
pub mod search;
pub mod spectra;
pub mod stats;
pub mod timedomain;
mod transient;
pub mod welch;

use std::sync::Arc;

pub use cancel::Cancel;
pub use dataset::{Dataset, Experiment, Periodic};
pub use discover::{CandidateScore, Discovery, Step, Verdict};
pub use fit::{FitOptions, FitResult, ParamEstimate};
pub use frf::{Estimator, EstimatorChoice, FrfEstimate};
pub use model::{Drift, Effect, Model, ModelStructure, Parameter, StateSpace};
pub use model_file::{Controller, ModelFile};
pub use prediction::Criterion;

use cost::WeightedCost;
pub use error::{Result, SimError};
use noise::NoiseReference;

/// Monte-Carlo draws for the noise reference.
pub const NOISE_DRAWS: usize = 300;

/// Measurements, their FRF and noise reference, and the current model.
#[derive(Debug, Clone)]
pub struct Workbench {
    data: Dataset,
    /// The logs' samples per input hold when the time criterion reads them at the inputs'
    /// rate ([`Dataset::input_hold`]).
    hold: Option<usize>,
    frf: FrfEstimate,
    cost: WeightedCost,
    noise: NoiseReference,
    model: Model,
    criterion: Criterion,
    /// Stops this workbench's runs from outside ([`Workbench::set_cancel`]).
    cancel: Cancel,
}

/// Choices a user may make about the data; the defaults take everything from the data.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DataOptions {
    /// The band, Hz, when the experiment was designed for a known band: a Welch estimate
    /// covers it, a periodic one keeps its excited lines within it; `None` finds it from the
    /// data ([`welch::excited_band`], every excited line).
    pub band_hz: Option<(f64, f64)>,
    /// The criterion; `None`: the prediction error for a nonlinear model, else the FRF
    /// ([`Criterion::default_for`]).
    pub criterion: Option<Criterion>,
}

impl Workbench {
    /// Estimates the FRF of `data` and prepares the cost for `structure` (no effect enabled).
    pub fn new(
        structure: Arc<dyn ModelStructure>,
        data: Dataset,
        estimator: EstimatorChoice,
    ) -> Result<Self> {
        Self::with_options(structure, data, estimator, DataOptions::default())
    }

    /// [`Workbench::new`] with the user's choices about the data.
    pub fn with_options(
        structure: Arc<dyn ModelStructure>,
        data: Dataset,
        estimator: EstimatorChoice,
        options: DataOptions,
    ) -> Result<Self> {
        data.validate()?;
        if let Some((lo, hi)) = options.band_hz {
            if !(lo > 0.0 && lo < hi && hi.is_finite() && hi < 0.5 * data.sample_rate_hz) {
                return Err(SimError::invalid(
                    "band",
                    format!("{lo},{hi} Hz"),
                    format!(
                        "must satisfy 0 < low < high < {} Hz (Nyquist)",
                        0.5 * data.sample_rate_hz
                    ),
                ));
            }
        }
        for (what, want, have) in [
            ("input", structure.inputs(), &data.inputs),
            ("output", structure.outputs(), &data.outputs),
        ] {
            if &want != have {
                let missing: Vec<&String> = want.iter().filter(|n| !have.contains(n)).collect();
                return Err(SimError::invalid(
                    format!("{what} channels"),
                    have.join(","),
                    format!(
                        "the {} model needs {} in this order{}",
                        structure.system(),
                        want.join(","),
                        if missing.is_empty() {
                            String::new()
                        } else {
                            format!(
                                "; missing channel {}",
                                missing
                                    .iter()
                                    .map(|s| s.as_str())
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            )
                        }
                    ),
                ));
            }
        }
        frf::check_excited(&data, frf::uses_instrumental_variable(&data, estimator)?)?;
        let time = options
            .criterion
            .map_or(structure.is_nonlinear(), |c| c == Criterion::Time);
        // The time criterion reads logs taken faster than their inputs change at the inputs'
        // rate: at ten samples per hold the one-step prediction error is nearly all sensor
        // noise, and a design that puts a model's misfit into its process noise flattens it (a
        // ball-and-beam logged at 1 kHz under a 100 Hz controller fitted a 25 ms motor lag to
        // 13 ms and its mass 68 % high, "explained"; every tenth sample reads the misfit).
        let hold = data.input_hold().filter(|_| time);
        let data = match &hold {
            Some(h) => data.decimated(h),
            None => data,
        };
        let hold = hold.map(|h| h.factor);
        let welch = || -> Result<(FrfEstimate, NoiseReference)> {
            let band = match options.band_hz {
                Some(band) => band,
                None => welch::excited_band(&data)?,
            };
            let segment = welch::segment_length(data.sample_rate_hz, band.0);
            let w = welch::welch_frf(&data, estimator, band, segment)?;
            let noise = w.noise_reference(NOISE_DRAWS, 0x5eed)?;
            Ok((w.frf, noise))
        };
        let periodic = || -> Result<(FrfEstimate, NoiseReference)> {
            let mut frf = frf::periodic_frf(&data, estimator)?;
            if let Some((lo, hi)) = options.band_hz {
                // The excited lines within the band: the user's band narrows the periodic
                // estimate as it sets the Welch one.
                let all = frf.lines.len();
                frf.lines.retain(|l| (lo..=hi).contains(&l.freq_hz));
                if frf.lines.is_empty() {
                    return Err(SimError::invalid(
                        "band",
                        format!("{lo},{hi} Hz"),
                        format!("holds none of the {all} excited lines of the periodic logs"),
                    ));
                }
            }
            let noise = NoiseReference::periodic(&frf, NOISE_DRAWS, 0x5eed)?;
            Ok((frf, noise))
        };
        // The time criterion rests on the prediction error, not on the periodic FRF's noise
        // reference: logs with too few periods for that (a single record of four periods
        // with three outputs) go through Welch under it, as logs without a period do; they
        // were refused, naming the periodic FRF's degrees of freedom.
        let (frf, noise) = match (data.is_periodic(), time) {
            (false, _) => welch()?,
            (true, false) => periodic()?,
            (true, true) => match periodic() {
                Err(SimError::InvalidParameter { name, .. })
                    if name == "noise degrees of freedom" =>
                {
                    welch()?
                }
                other => other?,
            },
        };
        let cost = WeightedCost::new(&frf)?;
        let mut model = Model::new(structure);
        let silent = model.silent_outputs(&model.documented()?)?;
        if !silent.is_empty() {
            return Err(SimError::invalid(
                "model",
                model.structure().system(),
                format!(
                    "output {} depends on no state and no input at the documented values (its row of C and D{} is zero): the model holds it constant, so no log of it can be compared; check its output expression or C row",
                    silent.join(", "),
                    if model.structure().is_nonlinear() {
                        ", the linearization at the operating point,"
                    } else {
                        ""
                    }
                ),
            ));
        }
        check_sample_rate(&model, data.sample_rate_hz)?;
        let criterion = options
            .criterion
            .unwrap_or_else(|| Criterion::default_for(&model));
        let spacing = frf
            .freqs_hz()
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .fold(f64::INFINITY, f64::min);
        let spacing = if spacing.is_finite() { spacing } else { 0.0 };
        for effect in generic::for_data(model.structure().as_ref(), &data, spacing) {
            model = model.with_candidate(effect)?;
        }
        if criterion == Criterion::Time {
            check_operating_point(&model, &data)?;
        }
        if criterion == Criterion::Time && !model.structure().is_nonlinear() {
            return Err(SimError::invalid(
                "criterion",
                "time",
                format!(
                    "needs a nonlinear model ([nonlinear] in the model file); the {} model is linear: use the FRF criterion (--criterion frf; criterion=\"frf\" in Python)",
                    model.structure().system()
                ),
            ));
        }
        Ok(Self {
            data,
            hold,
            frf,
            cost,
            noise,
            model,
            criterion,
            cancel: Cancel::default(),
        })
    }

    /// The measurements.
    pub fn data(&self) -> &Dataset {
        &self.data
    }

    /// The logs' samples per input hold when the time criterion reads them at the inputs'
    /// rate, every `hold`-th sample from the start of each hold (`None`: every sample).
    pub fn hold(&self) -> Option<usize> {
        self.hold
    }

    /// The non-parametric FRF.
    pub fn frf(&self) -> &FrfEstimate {
        &self.frf
    }

    /// Why the FRF is a Welch estimate although some experiments are periodic (an
    /// experiment without a period among periodic ones, or periods that differ), naming the
    /// experiments ([`Dataset::why_not_periodic`]), or all are but too few periods for the
    /// time criterion to take the periodic estimate; `None` for a periodic estimate or logs
    /// none of which is periodic.
    pub fn welch_reason(&self) -> Option<String> {
        self.frf.welch.as_ref()?;
        self.data.why_not_periodic().or_else(|| {
            self.data.is_periodic().then(|| {
                "the periodic FRF's noise reference needs more periods than the logs hold, and \
                 the time criterion does not rest on it"
                    .to_string()
            })
        })
    }

    /// The weighted cost.
    pub fn cost(&self) -> &WeightedCost {
        &self.cost
    }

    /// The noise reference.
    pub fn noise(&self) -> &NoiseReference {
        &self.noise
    }

    /// The current model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Enables an effect of the structure by name.
    pub fn add(&mut self, effect: &str) -> Result<()> {
        self.model = self.model.with_effect(effect)?;
        Ok(())
    }

    /// Offers a user-defined effect to discovery as a candidate (not enabled).
    pub fn offer(&mut self, effect: Arc<dyn Effect>) -> Result<()> {
        self.model = self.model.with_candidate(effect)?;
        Ok(())
    }

    /// Adds a user-defined effect.
    pub fn add_user_effect(&mut self, effect: Arc<dyn Effect>) -> Result<()> {
        self.model = self.model.with_user_effect(effect)?;
        Ok(())
    }

    /// Shares `cancel` with this workbench's runs: once it is set, a run (and each clone's)
    /// stops at its next fit iteration with [`SimError::Cancelled`] (Ctrl-C from Python).
    pub fn set_cancel(&mut self, cancel: Cancel) {
        self.cancel = cancel;
    }

    /// Fit options for this data (zero-order hold at the sample period, the workbench's
    /// [`Cancel`]).
    pub fn fit_options(&self) -> FitOptions {
        FitOptions {
            hold: Some(1.0 / self.data.sample_rate_hz),
            cancel: self.cancel.clone(),
            ..FitOptions::default()
        }
    }

    /// Fits the current model to the FRF and diagnoses it.
    pub fn compare(&self) -> Result<Step> {
        self.step(&self.model, None, None, None)
    }

    /// Fits the current model with the workbench's criterion and records it with its verdict
    /// (the "compare" of the workflow). No candidate is tried, whatever the criterion, so a
    /// misfit verdict says so rather than that none explains it.
    pub fn compared(&self) -> Result<Discovery> {
        let mut d = match self.criterion {
            Criterion::Frf => self.record(self.compare()?)?,
            Criterion::Time => self.compare_time()?,
        };
        d.conclusion = d
            .conclusion
            .with_candidates(discover::Candidates::of(&self.model, false));
        // A step whose fits were cancelled may have been recorded as failed, not returned.
        self.cancel.check()?;
        Ok(d)
    }
}

/// The most e-folds per sample period a model's fastest unstable mode may grow in logs of a
/// loop that holds it: loops sample an unstable plant many times per time constant (the
/// magnetic levitator of the README: 0.044 per sample), and a deadbeat loop of a plant growing
/// twentyfold per sample would multiply its sensor noise as much. A time column in
/// milliseconds read as seconds makes the period a thousand times too long.
pub const MAX_GROWTH_PER_SAMPLE: f64 = 3.0;

/// How far from the operating point's value, relative to it, a channel's logged mean may
/// lie under the time criterion (which compares absolute values) before the logs are taken
/// for other units or deviations: Celsius against a model in kelvin is 78 % off, deviation
/// logs 100 %.
pub const OFF_OPERATING_POINT: f64 = 0.5;

/// Kelvin at 0 degrees Celsius.
const CELSIUS: f64 = 273.15;

/// How far from the operating point's value, relative to it, a channel's logged mean may lie
/// under the FRF criterion before its verdict says the logs rest elsewhere
/// ([`Level::resting_elsewhere`]): a maglev rig's gap sensor 0.3 mm off at 8 mm, or its magnet
/// constant 10 % above the documented one, kept the coil current 4-5 % below the operating
/// point's, and the FRF fit, linearized there, read "explained" with the magnet constant
/// 9-10 standard errors from the truth.
pub const LEVELS_APART: f64 = 0.02;

/// One logged channel's mean against the nonlinear model's operating point (its inputs, and
/// the outputs `h` gives there).
struct Level<'a> {
    name: &'a str,
    /// "input" or "output".
    kind: &'static str,
    mean: f64,
    /// The channel's standard deviation over the logs.
    spread: f64,
    op: f64,
}

impl Level<'_> {
    fn apart(&self) -> f64 {
        (self.mean - self.op).abs()
    }

    /// Every logged channel of `data` against the operating point of `model` at its documented
    /// values; empty for a linear model or one whose operating point cannot be evaluated
    /// (reported where the model is used).
    fn of<'a>(model: &Model, data: &'a Dataset) -> Result<Vec<Level<'a>>> {
        if !model.structure().is_nonlinear() {
            return Ok(Vec::new());
        }
        let Ok(d) = model.dynamics(&model.documented()?) else {
            return Ok(Vec::new());
        };
        let (x, u) = d.operating_point();
        let mut y = vec![0.0; d.outputs()];
        if d.h(&x, &u, &mut y, &mut Vec::new()).is_err() {
            return Ok(Vec::new());
        }
        let level = |name: &'a String, kind, op, values: Vec<f64>| {
            let n = values.len().max(1) as f64;
            let mean = values.iter().sum::<f64>() / n;
            let spread = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
            Level {
                name,
                kind,
                mean,
                spread,
                op,
            }
        };
        let inputs = (0..u.len().min(data.inputs.len())).map(|j| {
            level(
                &data.inputs[j],
                "input",
                u[j],
                data.input_samples(j).collect(),
            )
        });
        let outputs = (0..y.len().min(data.outputs.len())).map(|j| {
            level(
                &data.outputs[j],
                "output",
                y[j],
                data.output_samples(j).collect(),
            )
        });
        Ok(inputs.chain(outputs).collect())
    }

    /// "the logged input u averages 7.69 where the operating point holds at 8.0".
    fn describe(&self) -> String {
        format!(
            "the logged {} {} averages {:.6} where the operating point {} {:.6}",
            self.kind,
            self.name,
            self.mean,
            if self.kind == "input" {
                "holds at"
            } else {
                "gives"
            },
            self.op
        )
    }

    /// The channels whose logged mean lies more than [`LEVELS_APART`] of the operating point's
    /// value from it, as one sentence for the FRF criterion's verdict (which compares the
    /// linearization there); `None` when none does. Channels whose operating value is zero set
    /// no scale and are not judged.
    pub(crate) fn resting_elsewhere(model: &Model, data: &Dataset) -> Result<Option<String>> {
        let apart: Vec<String> = Self::of(model, data)?
            .iter()
            .filter(|l| l.op != 0.0 && l.apart() > LEVELS_APART * l.op.abs())
            .map(|l| {
                format!(
                    "{}, {:.1} % apart",
                    l.describe(),
                    100.0 * l.apart() / l.op.abs()
                )
            })
            .collect();
        Ok((!apart.is_empty()).then(|| {
            format!(
                "the logs rest away from the operating point ({}): the FRF criterion compares the linearization at the operating point, and its fit makes up the difference in the parameters (a sensor offset, a wrong documented value or a load the model lacks moves the levels so); give the operating point where the loop rests, or use the time criterion, which compares absolute levels",
                apart.join("; ")
            )
        }))
    }
}

/// Refuses logs whose inputs or outputs average far from the nonlinear model's operating
/// point ([`Level`]): more than [`OFF_OPERATING_POINT`] of the operating point's value and
/// more than ten times the channel's logged spread. A reactor logged in Celsius against a
/// model in kelvin fitted a heat-transfer coefficient 2.5 times off and called it a misfit;
/// logged as deviations its predictor diverged with a message about the reaction rate.
/// Channels whose operating value is zero are not judged: there nothing sets a scale.
fn check_operating_point(model: &Model, data: &Dataset) -> Result<()> {
    let levels = Level::of(model, data)?;
    // Whether `a` averages near the operating value of `b`.
    let near = |a: &Level, b: &Level| {
        b.op != 0.0 && (a.mean - b.op).abs() <= OFF_OPERATING_POINT * b.op.abs()
    };
    for l in &levels {
        let apart = l.apart();
        if l.op != 0.0 && apart > OFF_OPERATING_POINT * l.op.abs() && apart > 10.0 * l.spread {
            // Two columns of one side, each averaging near the other's operating value.
            let swap = levels
                .iter()
                .find(|o| o.kind == l.kind && o.name != l.name && near(l, o) && near(o, l))
                .map_or(String::new(), |o| {
                    format!(
                        "; {} averages {:.6}, near what the operating point {} for {} and the other way round: are the two columns swapped?",
                        o.name,
                        o.mean,
                        if l.kind == "input" { "holds" } else { "gives" },
                        l.name
                    )
                });
            // Kelvin against degrees Celsius is the one offset between units worth naming.
            let celsius = if (apart - CELSIUS).abs() < 2.0 {
                "; 273.15 apart is degrees Celsius against kelvin"
            } else {
                ""
            };
            return Err(SimError::invalid(
                format!("operating point of {}", model.structure().system()),
                l.op,
                format!(
                    "{} ({apart:.4} apart, {:.0} % of it and {:.0} times the logged spread){swap}{celsius}: the time criterion compares absolute values; are the logs in the model's units, and absolute rather than deviations from the operating point? If the loop ran there, give that operating point; the FRF criterion (--criterion frf) compares deviations",
                    l.describe(),
                    100.0 * apart / l.op.abs(),
                    apart / l.spread.max(f64::MIN_POSITIVE)
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses logs whose sample period is too long for the model at its documented values to be
/// held by a sampled loop ([`MAX_GROWTH_PER_SAMPLE`]), naming the rate, the mode and the likely
/// cause (a time column in other units).
fn check_sample_rate(model: &Model, sample_rate_hz: f64) -> Result<()> {
    let Ok(ss) = model.state_space(&model.documented()?) else {
        // The structure's own errors are reported where the model is used.
        return Ok(());
    };
    let fastest =
        ss.a.complex_eigenvalues()
            .iter()
            .map(|l| l.re)
            .fold(0.0, f64::max);
    let growth = fastest / sample_rate_hz;
    if growth > MAX_GROWTH_PER_SAMPLE {
        return Err(SimError::invalid(
            "sample rate",
            format!("{} Hz", load::hz(sample_rate_hz)),
            format!(
                "the {} model's fastest unstable mode ({fastest:.4} 1/s at the documented values) grows by a factor e^{} per sample period of {} s, more than e^{MAX_GROWTH_PER_SAMPLE}: no sampled loop holds such a plant; is the logs' time column in seconds (milliseconds read as seconds make the period a thousand times too long), and are the documented values right?",
                model.structure().system(),
                load::readable(growth, 3),
                load::readable(1.0 / sample_rate_hz, 4)
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use std::sync::Arc;

    /// A tank at 350 K cooled by a jacket at 300 K (`T' = a (Tc - T) + c`, balanced there).
    fn tank() -> Model {
        let text = "name = \"tank\"\nstates = [\"T\"]\ninputs = [\"Tc\"]\noutputs = [\"T\"]\n\
                    [parameters]\na = { value = 0.1, min = 0.0 }\nc = { value = 5.0, fixed = true }\n\
                    [nonlinear]\nf.T = \"a*(Tc - T) + c\"\nh.T = \"T\"\n\
                    operating_point = { T = 350, Tc = 300 }\n";
        let file = crate::ModelFile::parse(text, std::path::Path::new("tank.toml")).unwrap();
        Model::new(Arc::new(file))
    }

    /// Logs of `T` and `Tc` around `(t0, tc0)`, a kelvin of motion each.
    fn logs(tc0: f64, t0: f64) -> Dataset {
        Dataset {
            sample_rate_hz: 1.0,
            inputs: vec!["Tc".into()],
            outputs: vec!["T".into()],
            experiments: vec![Experiment {
                name: "e".into(),
                u: DMatrix::from_fn(500, 1, |k, _| tc0 + (0.1 * k as f64).sin()),
                y: DMatrix::from_fn(500, 1, |k, _| t0 + (0.07 * k as f64).cos()),
                r: None,
                periodic: None,
            }],
        }
    }

    /// Kelvin logs around the operating point pass, and so do logs 20 K away (a loop held
    /// elsewhere, 6 % of the value); Celsius logs and deviations are named by channel, the
    /// Celsius ones as such; an operating value of zero judges nothing.
    #[test]
    fn logs_far_from_the_operating_point_are_named() {
        let model = tank();
        assert!(check_operating_point(&model, &logs(300.0, 350.0)).is_ok());
        assert!(check_operating_point(&model, &logs(300.0, 370.0)).is_ok());
        let err = check_operating_point(&model, &logs(26.85, 76.85))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("the logged input Tc averages")
                && err.contains("holds at 300.000000")
                && err.contains("273.15 apart is degrees Celsius against kelvin"),
            "{err}"
        );
        let err = check_operating_point(&model, &logs(300.0, 0.0))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("the logged output T averages")
                && err.contains("gives 350.000000")
                && !err.contains("Celsius"),
            "{err}"
        );
        let zero = "name = \"z\"\nstates = [\"x\"]\ninputs = [\"u\"]\noutputs = [\"x\"]\n\
                    [parameters]\na = 1.0\n[nonlinear]\nf.x = \"a*x + u\"\nh.x = \"x\"\n\
                    operating_point = { x = 0, u = 0 }\n";
        let file = crate::ModelFile::parse(zero, std::path::Path::new("z.toml")).unwrap();
        let mut far = logs(300.0, 350.0);
        far.inputs = vec!["u".into()];
        far.outputs = vec!["x".into()];
        assert!(check_operating_point(&Model::new(Arc::new(file)), &far).is_ok());
    }

    /// A gap at 8 mm and a coil current at 0.8 A logged in the other order: both columns are
    /// named as swapped; in the model's order the logs pass.
    #[test]
    fn two_columns_logged_in_each_others_place_are_named_swapped() {
        let text = "name = \"lev\"\nstates = [\"z\", \"i\"]\ninputs = [\"u\"]\n\
                    outputs = [\"z\", \"i\"]\n[parameters]\na = 1.0\n[nonlinear]\n\
                    f.z = \"a*(i - 100*z)\"\nf.i = \"u - a*i\"\nh.z = \"z\"\nh.i = \"i\"\n\
                    operating_point = { z = 0.008, i = 0.8, u = 0.8 }\n";
        let file = crate::ModelFile::parse(text, std::path::Path::new("lev.toml")).unwrap();
        let model = Model::new(Arc::new(file));
        let data = |first: f64, second: f64| Dataset {
            sample_rate_hz: 1000.0,
            inputs: vec!["u".into()],
            outputs: vec!["z".into(), "i".into()],
            experiments: vec![Experiment {
                name: "e".into(),
                u: DMatrix::from_fn(500, 1, |k, _| 0.8 + 0.01 * (0.1 * k as f64).sin()),
                y: DMatrix::from_fn(500, 2, |k, j| {
                    let level = if j == 0 { first } else { second };
                    level * (1.0 + 0.001 * (0.07 * k as f64).cos())
                }),
                r: None,
                periodic: None,
            }],
        };
        assert!(check_operating_point(&model, &data(0.008, 0.8)).is_ok());
        let err = check_operating_point(&model, &data(0.8, 0.008))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("the logged output z averages")
                && err.contains("i averages 0.008000, near what the operating point gives for z")
                && err.contains("are the two columns swapped?"),
            "{err}"
        );
    }
}
