//! Measurements as the workbench sees them: equally sampled experiments with named inputs,
//! outputs and (when logged) the known excitation, checked once so that every later stage can
//! trust shapes and finiteness.
use nalgebra::DMatrix;

use crate::error::{Result, SimError};

/// How a periodic experiment is laid out: `transient` samples to discard, then `periods`
/// repetitions of `period` samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Periodic {
    /// Samples per period.
    pub period: usize,
    /// Number of whole periods recorded after the transient.
    pub periods: usize,
    /// Samples discarded at the start.
    pub transient: usize,
}

/// One experiment: samples in rows, channels in columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Name used in messages (file name, or `experiment 3`).
    pub name: String,
    /// Measured inputs, samples x inputs.
    pub u: DMatrix<f64>,
    /// Measured outputs, samples x outputs.
    pub y: DMatrix<f64>,
    /// Known excitation added to the inputs (the instrument for closed-loop data), if logged.
    pub r: Option<DMatrix<f64>>,
    /// Periodic layout, if the experiment is periodic.
    pub periodic: Option<Periodic>,
}

/// A set of experiments on one system.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Sample rate in Hz, common to all experiments.
    pub sample_rate_hz: f64,
    /// Input channel names.
    pub inputs: Vec<String>,
    /// Output channel names.
    pub outputs: Vec<String>,
    /// The experiments.
    pub experiments: Vec<Experiment>,
}

impl Dataset {
    /// Checks shapes, finiteness and periodic layouts, naming the experiment, channel and
    /// sample at fault.
    pub fn validate(&self) -> Result<()> {
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(SimError::invalid(
                "sample_rate_hz",
                self.sample_rate_hz,
                "must be a positive finite number",
            ));
        }
        if self.inputs.is_empty() || self.outputs.is_empty() {
            return Err(SimError::invalid(
                "channels",
                format!(
                    "{} inputs, {} outputs",
                    self.inputs.len(),
                    self.outputs.len()
                ),
                "need at least one input and one output",
            ));
        }
        if self.experiments.is_empty() {
            return Err(SimError::invalid(
                "data",
                "no experiments",
                "need at least one experiment",
            ));
        }
        for e in &self.experiments {
            check_block(&e.name, "input", &self.inputs, &e.u, e.u.nrows())?;
            check_block(&e.name, "output", &self.outputs, &e.y, e.u.nrows())?;
            if let Some(r) = &e.r {
                check_block(&e.name, "excitation", &self.inputs, r, e.u.nrows())?;
            }
            if let Some(p) = e.periodic {
                if p.period < 4 {
                    return Err(SimError::invalid(
                        format!("period_samples of {}", e.name),
                        p.period,
                        "a period needs at least 4 samples",
                    ));
                }
                if p.periods < 2 {
                    return Err(SimError::invalid(
                        format!("periods of {}", e.name),
                        p.periods,
                        "need at least 2 periods to estimate the noise from period-to-period variation",
                    ));
                }
                let needed = p.transient + p.period * p.periods;
                if e.u.nrows() < needed {
                    return Err(SimError::LengthMismatch {
                        what: format!(
                            "samples of {} (transient {} + {} periods of {})",
                            e.name, p.transient, p.periods, p.period
                        ),
                        expected: needed,
                        found: e.u.nrows(),
                    });
                }
            }
        }
        Ok(())
    }

    /// True when every experiment carries the known excitation.
    pub fn has_excitation(&self) -> bool {
        self.experiments.iter().all(|e| e.r.is_some())
    }

    /// True when every experiment logs its excitation and the input equals it (to 1e-9 of
    /// its size): no feedback, so an estimator that uses the input as its instrument is unbiased.
    pub fn is_open_loop(&self) -> bool {
        self.experiments.iter().all(|e| {
            e.r.as_ref()
                .is_some_and(|r| (r - &e.u).norm() <= 1e-9 * e.u.norm().max(f64::MIN_POSITIVE))
        })
    }

    /// True when every experiment is periodic.
    pub fn is_periodic(&self) -> bool {
        self.experiments.iter().all(|e| e.periodic.is_some())
    }
}

fn check_block(
    experiment: &str,
    kind: &str,
    names: &[String],
    m: &DMatrix<f64>,
    samples: usize,
) -> Result<()> {
    if m.ncols() != names.len() {
        return Err(SimError::LengthMismatch {
            what: format!("{kind} channels of {experiment}"),
            expected: names.len(),
            found: m.ncols(),
        });
    }
    if m.nrows() != samples {
        return Err(SimError::LengthMismatch {
            what: format!("{kind} samples of {experiment} (must match the input samples)"),
            expected: samples,
            found: m.nrows(),
        });
    }
    for (j, name) in names.iter().enumerate() {
        if let Some(i) = m.column(j).iter().position(|v| !v.is_finite()) {
            return Err(SimError::NotFinite {
                context: format!("{kind} of {experiment}, sample {i}"),
                field: name.clone(),
                value: m[(i, j)].to_string(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Dataset {
        Dataset {
            sample_rate_hz: 10.0,
            inputs: vec!["u".into()],
            outputs: vec!["y".into()],
            experiments: vec![Experiment {
                name: "e1".into(),
                u: DMatrix::zeros(20, 1),
                y: DMatrix::zeros(20, 1),
                r: None,
                periodic: Some(Periodic {
                    period: 8,
                    periods: 2,
                    transient: 4,
                }),
            }],
        }
    }

    #[test]
    fn accepts_consistent_data() {
        assert!(small().validate().is_ok());
    }

    #[test]
    fn open_loop_only_when_every_input_is_its_logged_excitation() {
        let mut d = small();
        assert!(!d.is_open_loop(), "no excitation logged");
        d.experiments[0].u = DMatrix::from_fn(20, 1, |i, _| (i as f64).sin());
        d.experiments[0].r = Some(d.experiments[0].u.clone());
        assert!(d.is_open_loop());
        // Feedback of a small output term makes the input differ from the excitation.
        d.experiments[0].u[(5, 0)] += 1e-6;
        assert!(!d.is_open_loop());
    }

    #[test]
    fn names_nan_sample_and_channel() {
        let mut d = small();
        d.experiments[0].y[(7, 0)] = f64::NAN;
        let msg = d.validate().unwrap_err().to_string();
        assert!(
            msg.contains("\"y\"") && msg.contains("sample 7") && msg.contains("e1"),
            "{msg}"
        );
    }

    #[test]
    fn names_too_short_periodic_record() {
        let mut d = small();
        d.experiments[0].periodic = Some(Periodic {
            period: 8,
            periods: 3,
            transient: 4,
        });
        let msg = d.validate().unwrap_err().to_string();
        assert!(
            msg.contains("expected 28") && msg.contains("found 20"),
            "{msg}"
        );
    }

    #[test]
    fn names_mismatched_lengths() {
        let mut d = small();
        d.experiments[0].y = DMatrix::zeros(19, 1);
        let msg = d.validate().unwrap_err().to_string();
        assert!(msg.contains("output samples of e1"), "{msg}");
    }
}
