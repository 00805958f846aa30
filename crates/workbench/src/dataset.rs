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

/// Inputs held over blocks of samples: logs sampled `factor` times faster than their inputs
/// change (a controller slower than the logger), each block starting at sample `phase[e]`
/// modulo `factor` in experiment `e` ([`Dataset::input_hold`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Hold {
    /// Samples per block.
    pub factor: usize,
    /// Per experiment, the first sample of its first block.
    pub phase: Vec<usize>,
}

/// Share of the blocks at whose start an input or the excitation changes, at least: a
/// controller's output moves at each of its samples, where a PRBS on a slower clock keeps its
/// level at about half of its ticks (and logs of it are no faster than its dynamics).
pub const HOLD_CHANGES: f64 = 0.9;

/// Fewest input changes in an experiment that make a hold pattern evidence.
const MIN_HOLD_CHANGES: usize = 20;

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
        if let Some(c) = self.inputs.iter().find(|c| self.outputs.contains(c)) {
            return Err(SimError::invalid(
                "channels",
                c,
                "is named as an input and as an output; a log's column or field can feed only one",
            ));
        }
        if self.experiments.is_empty() {
            return Err(SimError::invalid(
                "data",
                "no experiments",
                "need at least one experiment",
            ));
        }
        for (i, e) in self.experiments.iter().enumerate() {
            // Named before the checks that would read an empty record as an unexcited one.
            if e.u.nrows() < 2 {
                return Err(SimError::invalid(
                    "data",
                    &e.name,
                    format!(
                        "has {} sample{}: a record needs at least 2",
                        e.u.nrows(),
                        if e.u.nrows() == 1 { "" } else { "s" }
                    ),
                ));
            }
            check_block(&e.name, "input", &self.inputs, &e.u, e.u.nrows())?;
            check_block(&e.name, "output", &self.outputs, &e.y, e.u.nrows())?;
            if let Some(r) = &e.r {
                check_block(&e.name, "excitation", &self.inputs, r, e.u.nrows())?;
            }
            if let Some(first) = self.experiments[..i]
                .iter()
                .find(|f| same_samples(&f.u, &e.u) && same_samples(&f.y, &e.y))
            {
                return Err(SimError::invalid(
                    "data",
                    &e.name,
                    format!(
                        "holds the samples of {} (within {SAME_SAMPLES:e} of their range); each \
                         experiment must be given once, in one format",
                        first.name
                    ),
                ));
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
                if let Some(r) = &e.r {
                    check_repeats(&e.name, &self.inputs, r, p)?;
                }
            }
            for (kind, names, m) in [
                ("input", &self.inputs, &e.u),
                ("output", &self.outputs, &e.y),
            ] {
                check_spikes(&e.name, kind, names, m, self.sample_rate_hz)?;
            }
            check_outputs_move(e, &self.outputs)?;
        }
        Ok(())
    }

    /// The outputs logged through a coarse quantizer: every change between samples is a
    /// multiple of one step (an encoder's count) and the value stays on one step in at least
    /// [`COARSE_STILL`] of the samples. Its error then follows the signal for many samples
    /// instead of being white sensor noise.
    pub fn coarse_quantization(&self) -> Vec<Quantization> {
        self.outputs
            .iter()
            .enumerate()
            .filter_map(|(j, name)| {
                let columns: Vec<_> = self.experiments.iter().map(|e| e.y.column(j)).collect();
                let range = columns.iter().map(|c| c.amax()).fold(0.0, f64::max);
                let floor = 1e-8 * range;
                let steps: Vec<f64> = columns
                    .iter()
                    .flat_map(|c| (1..c.len()).map(move |k| (c[k] - c[k - 1]).abs()))
                    .collect();
                let moves: Vec<f64> = steps.iter().copied().filter(|d| *d > floor).collect();
                let step = moves.iter().copied().fold(f64::INFINITY, f64::min);
                if moves.len() < 10 || !step.is_finite() {
                    return None;
                }
                let on_grid = moves
                    .iter()
                    .filter(|d| {
                        let k = *d / step;
                        (k - k.round()).abs() <= 0.01 + floor / step
                    })
                    .count();
                let still = 1.0 - moves.len() as f64 / steps.len() as f64;
                if (on_grid as f64) < 0.99 * moves.len() as f64 || still < COARSE_STILL {
                    return None;
                }
                // Spread about each record's own mean, pooled.
                let (sq, n) = columns.iter().fold((0.0, 0usize), |(q, n), c| {
                    let mean = c.mean();
                    (
                        q + c.iter().map(|v| (v - mean).powi(2)).sum::<f64>(),
                        n + c.len(),
                    )
                });
                Some(Quantization {
                    output: name.clone(),
                    step,
                    still,
                    rms_steps: (sq / n.max(1) as f64).sqrt() / step,
                })
            })
            .collect()
    }

    /// Every sample of input `j`, experiment after experiment.
    pub fn input_samples(&self, j: usize) -> impl Iterator<Item = f64> + '_ {
        self.experiments
            .iter()
            .flat_map(move |e| e.u.column(j).into_iter().copied())
    }

    /// Every sample of output `j`, experiment after experiment.
    pub fn output_samples(&self, j: usize) -> impl Iterator<Item = f64> + '_ {
        self.experiments
            .iter()
            .flat_map(move |e| e.y.column(j).into_iter().copied())
    }

    /// True when every experiment carries the known excitation.
    pub fn has_excitation(&self) -> bool {
        self.experiments.iter().all(|e| e.r.is_some())
    }

    /// The records without the excitation when others log it, named: the excitation is used
    /// only when every record carries it, so one record without it turns it off for all (a
    /// ball-and-beam campaign with `r_tau` missing from one of three files read "explained"
    /// with its tests run against the inputs, "no excitation logged", and nothing else said).
    pub fn excitation_gap(&self) -> Option<String> {
        let (with, without): (Vec<&Experiment>, Vec<&Experiment>) =
            self.experiments.iter().partition(|e| e.r.is_some());
        if with.is_empty() || without.is_empty() {
            return None;
        }
        let names = |es: &[&Experiment]| {
            es.iter()
                .map(|e| e.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        };
        Some(format!(
            "the excitation ({}) is logged in {} but not in {}: it is used only when every record carries it, so none of it is used (the FRF is then a Welch estimate of the inputs, biased under feedback, and the time criterion's residual tests run against the inputs); log it in those records too, or leave them out",
            self.inputs
                .iter()
                .map(|i| format!("r_{i}"))
                .collect::<Vec<_>>()
                .join(", "),
            names(&with),
            names(&without)
        ))
    }

    /// True when every experiment logs its excitation and the input equals it (to 1e-9 of
    /// its size): no feedback, so an estimator that uses the input as its instrument is unbiased.
    pub fn is_open_loop(&self) -> bool {
        self.experiments.iter().all(|e| {
            e.r.as_ref()
                .is_some_and(|r| (r - &e.u).norm() <= 1e-9 * e.u.norm().max(f64::MIN_POSITIVE))
        })
    }

    /// How the inputs are held when every experiment's inputs and excitation change only on
    /// one grid of `factor` >= 2 samples, and at [`HOLD_CHANGES`] of its points at least:
    /// logs taken faster than the controller runs. `None` when they change at single samples,
    /// too rarely to tell, or on a grid a periodic layout does not fit (a period or transient
    /// not a whole number of blocks).
    pub fn input_hold(&self) -> Option<Hold> {
        let changed = |m: &DMatrix<f64>, k: usize| m.row(k) != m.row(k - 1);
        let mut factor = 0;
        let mut starts = Vec::new();
        let mut changes = Vec::new();
        for e in &self.experiments {
            let at: Vec<usize> = (1..e.u.nrows())
                .filter(|&k| changed(&e.u, k) || e.r.as_ref().is_some_and(|r| changed(r, k)))
                .collect();
            if at.len() < MIN_HOLD_CHANGES {
                return None;
            }
            factor = at.windows(2).fold(factor, |g, w| gcd(g, w[1] - w[0]));
            starts.push(at[0]);
            changes.push(at.len());
        }
        if factor < 2 {
            return None;
        }
        let phase: Vec<usize> = starts.iter().map(|s| s % factor).collect();
        for ((e, &p), &n) in self.experiments.iter().zip(&phase).zip(&changes) {
            let blocks = (e.u.nrows() - p) / factor;
            if (n as f64) < HOLD_CHANGES * blocks.saturating_sub(1) as f64 {
                return None;
            }
            if let Some(l) = e.periodic {
                if l.period % factor != 0 || l.transient < p || (l.transient - p) % factor != 0 {
                    return None;
                }
            }
        }
        Some(Hold { factor, phase })
    }

    /// The first sample of each block of `hold`: the logs at the rate their inputs change,
    /// each row's input held until the next and its outputs measured at its start, as the
    /// log's own rows are (a periodic layout in blocks).
    pub fn decimated(&self, hold: &Hold) -> Dataset {
        let experiments = self
            .experiments
            .iter()
            .zip(&hold.phase)
            .map(|(e, &p)| {
                let rows: Vec<usize> = (p..e.u.nrows()).step_by(hold.factor).collect();
                let pick = |m: &DMatrix<f64>| m.select_rows(&rows);
                Experiment {
                    name: e.name.clone(),
                    u: pick(&e.u),
                    y: pick(&e.y),
                    r: e.r.as_ref().map(pick),
                    periodic: e.periodic.map(|l| Periodic {
                        period: l.period / hold.factor,
                        periods: l.periods,
                        transient: (l.transient - p) / hold.factor,
                    }),
                }
            })
            .collect();
        Dataset {
            sample_rate_hz: self.sample_rate_hz / hold.factor as f64,
            inputs: self.inputs.clone(),
            outputs: self.outputs.clone(),
            experiments,
        }
    }

    /// True when every experiment is periodic (see [`Dataset::periodic_layouts`]).
    pub fn is_periodic(&self) -> bool {
        self.periodic_layouts().is_some()
    }

    /// The periodic layout of every experiment, from its metadata or else detected from its
    /// logged excitation ([`detect_period`]), and the detected period when any layout was
    /// detected. `None` when some experiment has neither, or when a detected period differs
    /// from the others (such records go through Welch).
    pub fn periodic_layouts(&self) -> Option<(Vec<Periodic>, Option<usize>)> {
        let mut detected = None;
        let layouts: Vec<Periodic> = self
            .experiments
            .iter()
            .map(|e| {
                e.periodic.or_else(|| {
                    let p = detect_period(e.r.as_ref()?)?;
                    detected = Some(p.period);
                    Some(p)
                })
            })
            .collect::<Option<_>>()?;
        match detected {
            Some(p) if layouts.iter().any(|l| l.period != p) => None,
            _ => Some((layouts, detected)),
        }
    }

    /// Why the experiments, some of them periodic, are not periodic as a whole (so they all
    /// go through Welch), naming the experiments at fault; `None` when every experiment is
    /// periodic (see [`Dataset::periodic_layouts`]) or none is.
    pub fn why_not_periodic(&self) -> Option<String> {
        if self.periodic_layouts().is_some() {
            return None;
        }
        let layouts: Vec<Option<(usize, &str)>> = self
            .experiments
            .iter()
            .map(|e| match e.periodic {
                Some(p) => Some((p.period, "period_samples metadata")),
                None => detect_period(e.r.as_ref()?).map(|p| (p.period, "detected")),
            })
            .collect();
        let n = self.experiments.len();
        let names = |pick: &dyn Fn(usize) -> bool| -> Vec<&str> {
            (0..n)
                .filter(|i| pick(*i))
                .map(|i| self.experiments[i].name.as_str())
                .collect()
        };
        let without = names(&|i| layouts[i].is_none());
        if without.len() == n {
            return None;
        }
        if !without.is_empty() {
            let with = names(&|i| layouts[i].is_some());
            let cause = |i: usize| {
                if self.experiments[i].r.is_some() {
                    "no period_samples metadata, and its logged excitation does not repeat"
                } else {
                    "no period_samples metadata, and no logged excitation to find a period in"
                }
            };
            let causes: Vec<String> = (0..n)
                .filter(|i| layouts[*i].is_none())
                .map(|i| {
                    if without.len() == 1 {
                        cause(i).to_string()
                    } else {
                        format!("{}: {}", self.experiments[i].name, cause(i))
                    }
                })
                .collect();
            let (subject, verb, pronoun) = if without.len() == 1 {
                ("experiment", "is", "it")
            } else {
                ("experiments", "are", "them")
            };
            return Some(format!(
                "{subject} {} {verb} not periodic ({}), while {} {}: the periodic estimate needs \
                 every experiment periodic, so all {n} went through Welch; leave {pronoun} out, \
                 or give {pronoun} in a run of {} own, to use the periodic estimate on the others",
                without.join(", "),
                causes.join("; "),
                with.join(", "),
                if with.len() == 1 { "is" } else { "are" },
                if without.len() == 1 { "its" } else { "their" },
            ));
        }
        // Every experiment has a period, but a detected one differs from the others.
        let mut groups: Vec<((usize, &str), Vec<&str>)> = Vec::new();
        for (e, l) in self.experiments.iter().zip(&layouts) {
            let l = l.expect("every experiment has a period here");
            match groups.iter_mut().find(|(k, _)| *k == l) {
                Some((_, names)) => names.push(&e.name),
                None => groups.push((l, vec![&e.name])),
            }
        }
        Some(format!(
            "the experiments' periods differ ({}): the periodic estimate needs one period over \
             all experiments, so all {n} went through Welch; give the experiments of each period \
             in a run of their own to use the periodic estimate",
            groups
                .iter()
                .map(|((period, how), names)| format!(
                    "{} {period} samples, {how}",
                    names.join(", ")
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ))
    }
}

/// Share of samples on the previous sample's value above which a quantized output counts as
/// coarse ([`Dataset::coarse_quantization`]): a double pendulum's link angles on 4096-count
/// encoders at 200 Hz sat still in 71-79 % of the samples, its cart position on 0.1 mm
/// counts in 12-14 %.
pub const COARSE_STILL: f64 = 0.5;

/// An output logged through a coarse quantizer ([`Dataset::coarse_quantization`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Quantization {
    /// The output.
    pub output: String,
    /// The quantization step, in the output's units.
    pub step: f64,
    /// Share of samples equal to the one before.
    pub still: f64,
    /// The output's rms about each record's mean, in steps.
    pub rms_steps: f64,
}

impl Quantization {
    /// "th2 (step 0.001534, still in 79 % of the samples, rms 3.7 steps)".
    pub fn describe(&self) -> String {
        format!(
            "{} (step {:.4e}, still in {:.0} % of the samples, rms {:.1} steps)",
            self.output,
            self.step,
            100.0 * self.still,
            self.rms_steps
        )
    }
}

/// Largest deviation between repetitions that still counts as exact repetition, relative to
/// the excitation's peak: logs written with single-precision (7-digit) values repeat to it.
const REPETITION_TOLERANCE: f64 = 1e-6;

/// The periodic layout of an excitation that repeats exactly (`r(t + P) = r(t)` on every
/// channel within rounding) over at least the later half of the record and at least two
/// periods; `None` for anything else (random excitation, a constant or absent signal).
///
/// The smallest such `P` is the period. Samples before the repeating part (a transient the
/// signal shows) and the incomplete period that precedes the last whole periods are the
/// transient; when that leaves none and three or more periods were recorded, the first period
/// is the transient, since the response to an excitation started with the record has not
/// settled in it.
///
/// ```
/// use nalgebra::DMatrix;
/// use workbench::dataset::detect_period;
///
/// let r = DMatrix::from_fn(110, 1, |i, _| [0.0, 1.0, -2.0, 0.5, 3.0][i % 5]);
/// let p = detect_period(&r).unwrap();
/// assert_eq!((p.period, p.periods, p.transient), (5, 21, 5));
/// let noise = DMatrix::from_fn(110, 1, |i, _| ((i * i) as f64).sin());
/// assert!(detect_period(&noise).is_none());
/// ```
pub fn detect_period(r: &DMatrix<f64>) -> Option<Periodic> {
    let n = r.nrows();
    let tol = REPETITION_TOLERANCE * r.amax();
    if tol == 0.0 || !tol.is_finite() {
        return None;
    }
    let repeats = |t: usize, p: usize| {
        r.row(t + p)
            .iter()
            .zip(r.row(t).iter())
            .all(|(a, b)| (a - b).abs() <= tol)
    };
    (4..=n / 2).find_map(|period| {
        // Start of the repeating tail: one past the last sample that does not repeat.
        let start = (0..n - period)
            .rev()
            .find(|&t| !repeats(t, period))
            .map_or(0, |t| t + 1);
        let periods = (n - start) / period;
        let tail = r.rows(start, n - start);
        let varies = tail
            .column_iter()
            .any(|c| c.iter().any(|v| (v - c[0]).abs() > 100.0 * tol));
        if periods < 2 || start > n / 2 || !varies {
            return None;
        }
        let transient = n - periods * period;
        Some(if transient == 0 && periods >= 3 {
            Periodic {
                period,
                periods: periods - 1,
                transient: period,
            }
        } else {
            Periodic {
                period,
                periods,
                transient,
            }
        })
    })
}

/// Deviation between periods, relative to the excitation's peak, above which a logged
/// excitation does not repeat with its `period_samples` metadata: far above single-precision
/// rounding, far below any period of a multisine or noise sequence of another length.
const METADATA_REPETITION_TOLERANCE: f64 = 1e-3;

/// Greatest common divisor (`gcd(0, b) = b`).
fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Refuses `period_samples` metadata that the logged excitation `r` contradicts: the periodic
/// estimate would average unrelated stretches as periods and call the result noise-free.
fn check_repeats(experiment: &str, inputs: &[String], r: &DMatrix<f64>, p: Periodic) -> Result<()> {
    let tol = METADATA_REPETITION_TOLERANCE * r.amax();
    let last = p.transient + p.period * (p.periods - 1);
    for t in p.transient..last {
        if let Some(j) = (0..r.ncols()).find(|&j| (r[(t + p.period, j)] - r[(t, j)]).abs() > tol) {
            let found = match detect_period(r) {
                Some(d) => format!("it repeats every {} samples", d.period),
                None => "it does not repeat at all".to_string(),
            };
            return Err(SimError::invalid(
                format!("period_samples of {experiment}"),
                p.period,
                format!(
                    "the logged excitation r_{} does not repeat with it (sample {t}: {:.6}, one period later {:.6}); {found}: correct the metadata or leave it out",
                    inputs.get(j).map_or("?", |s| s.as_str()),
                    r[(t, j)],
                    r[(t + p.period, j)]
                ),
            ));
        }
    }
    Ok(())
}

/// How many typical steps (the median absolute difference between neighbouring samples) a
/// sample must stand out from both neighbours, in the same direction, to be refused as a
/// logging glitch: a one-sample spike of 1e6 among samples of 1e-2 is 1e8 of them, a
/// controller's response to an impulse of the excitation a few thousand.
pub const SPIKE: f64 = 1e5;

/// Refuses a single sample that leaps far out of its channel and straight back
/// ([`SPIKE`]), naming the experiment, channel and sample: one such value dominates every
/// spectrum and fit, and nothing downstream can say where it came from.
fn check_spikes(
    experiment: &str,
    kind: &str,
    names: &[String],
    m: &DMatrix<f64>,
    sample_rate_hz: f64,
) -> Result<()> {
    let n = m.nrows();
    if n < 3 {
        return Ok(());
    }
    for (j, name) in names.iter().enumerate() {
        let c = m.column(j);
        let mut steps: Vec<f64> = (1..n).map(|k| (c[k] - c[k - 1]).abs()).collect();
        let mid = steps.len() / 2;
        let typical = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
        if typical <= 0.0 || !typical.is_finite() {
            continue;
        }
        for k in 1..n - 1 {
            let (before, after) = (c[k] - c[k - 1], c[k] - c[k + 1]);
            let leap = before.abs().min(after.abs());
            if before.signum() == after.signum() && leap > SPIKE * typical {
                return Err(SimError::invalid(
                    format!("{kind} {name} of {experiment}"),
                    format!("{:e} at sample {k} (t = {:.6} s from the start)", c[k], k as f64 / sample_rate_hz),
                    format!(
                        "leaps from {:e} and back to {:e}, {:.1e} times the channel's typical step between samples ({typical:.3e}): a logging glitch? repair or remove the sample",
                        c[k - 1],
                        c[k + 1],
                        leap / typical
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// True when column `j` of `m` takes more than one value (beyond rounding): the test of an
/// input, excitation or output that something moved.
pub(crate) fn column_moves(m: &DMatrix<f64>, j: usize) -> bool {
    let c = m.column(j);
    let (lo, hi) = (c.min(), c.max());
    hi - lo > 1e-12 * lo.abs().max(hi.abs())
}

/// Refuses an output that is constant in an experiment where an input moves: a dead or
/// unplugged sensor (a log of zeros) matches no model, and a fit would take it for data.
fn check_outputs_move(e: &Experiment, outputs: &[String]) -> Result<()> {
    if e.y.nrows() < 2 || !(0..e.u.ncols()).any(|j| column_moves(&e.u, j)) {
        return Ok(());
    }
    match (0..outputs.len()).find(|&j| !column_moves(&e.y, j)) {
        Some(j) => Err(SimError::invalid(
            format!("output {} of {}", outputs[j], e.name),
            format!("{} in every sample", e.y[(0, j)]),
            "stays constant while the inputs move: a dead or unplugged sensor, or the wrong column; leave the experiment out or repair the channel",
        )),
        None => Ok(()),
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

/// Relative distance below which two experiments hold the same samples: a log written twice in
/// different formats (a CSV's printed digits against an MCAP's doubles) differs by rounding,
/// two records of one rig differ by their noise.
const SAME_SAMPLES: f64 = 1e-6;

/// Whether `a` and `b` have one shape and agree within [`SAME_SAMPLES`] of their largest
/// magnitude, compared from the first row so that different records part at once.
fn same_samples(a: &DMatrix<f64>, b: &DMatrix<f64>) -> bool {
    if a.shape() != b.shape() || a.is_empty() {
        return false;
    }
    let tol = SAME_SAMPLES * a.amax().max(b.amax());
    (0..a.nrows()).all(|i| (0..a.ncols()).all(|j| (a[(i, j)] - b[(i, j)]).abs() <= tol))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Experiments of `blocks` blocks of `factor` samples after `phase` samples that hold the
    /// value before the first block, the input and excitation moving at each block start
    /// (`moves`: which blocks change), the output changing at every sample.
    fn held(
        factor: usize,
        phases: &[usize],
        blocks: usize,
        moves: impl Fn(usize) -> bool,
    ) -> Dataset {
        let experiments = phases
            .iter()
            .map(|&p| {
                let n = p + blocks * factor;
                let level = |k: usize| {
                    let b = k.saturating_sub(p) / factor;
                    let b = if k < p { 0 } else { b + 1 };
                    // A new level at each moving block, kept otherwise.
                    (0..=b).filter(|&j| j == 0 || moves(j)).count() as f64
                };
                let u = DMatrix::from_fn(n, 1, |k, _| level(k).sin());
                Experiment {
                    name: format!("phase {p}"),
                    r: Some(u.map(|v| 0.5 * v)),
                    y: DMatrix::from_fn(n, 1, |k, _| (0.37 * k as f64).cos()),
                    u,
                    periodic: None,
                }
            })
            .collect();
        Dataset {
            sample_rate_hz: 1000.0,
            inputs: vec!["u".into()],
            outputs: vec!["y".into()],
            experiments,
        }
    }

    proptest! {
        /// Inputs held over `factor` samples from each experiment's own phase are found with
        /// that factor and phase, and the decimated logs are the block starts at the block
        /// rate.
        #[test]
        fn held_inputs_are_read_at_their_own_rate(
            factor in 2usize..12,
            phases in proptest::collection::vec(0usize..11, 1..4),
            blocks in 40usize..90,
        ) {
            let phases: Vec<usize> = phases.iter().map(|p| p % factor).collect();
            let data = held(factor, &phases, blocks, |_| true);
            let hold = data.input_hold().unwrap();
            prop_assert_eq!(hold.factor, factor);
            prop_assert_eq!(&hold.phase, &phases);
            let d = data.decimated(&hold);
            prop_assert_eq!(d.sample_rate_hz, 1000.0 / factor as f64);
            for (e, (full, &p)) in d.experiments.iter().zip(data.experiments.iter().zip(&phases)) {
                prop_assert_eq!(e.u.nrows(), (full.u.nrows() - p).div_ceil(factor));
                for j in 0..e.u.nrows() {
                    prop_assert_eq!(e.u[(j, 0)], full.u[(p + j * factor, 0)]);
                    prop_assert_eq!(e.y[(j, 0)], full.y[(p + j * factor, 0)]);
                }
            }
        }
    }

    /// Inputs that change at single samples, or on a grid they keep their level at half the
    /// time (a PRBS on a slower clock), or a periodic layout not made of whole blocks, are
    /// read at every sample.
    #[test]
    fn inputs_not_held_or_held_like_a_prbs_keep_every_sample() {
        assert!(held(1, &[0], 200, |_| true).input_hold().is_none());
        assert!(held(7, &[3], 200, |b| (b * 37 + 11) % 17 < 8)
            .input_hold()
            .is_none());
        assert!(held(7, &[3], 200, |b| b % 20 != 0).input_hold().is_some());
        let mut periodic = held(10, &[0], 100, |_| true);
        periodic.experiments[0].periodic = Some(Periodic {
            period: 25,
            periods: 40,
            transient: 0,
        });
        assert!(periodic.input_hold().is_none());
        periodic.experiments[0].periodic = Some(Periodic {
            period: 50,
            periods: 20,
            transient: 0,
        });
        let hold = periodic.input_hold().unwrap();
        let p = periodic.decimated(&hold).experiments[0].periodic.unwrap();
        assert_eq!((p.period, p.periods, p.transient), (5, 20, 0));
    }

    /// One experiment of 2000 samples whose single output is `y(k)`.
    fn one_output(y: impl Fn(usize) -> f64) -> Dataset {
        Dataset {
            sample_rate_hz: 200.0,
            inputs: vec!["u".into()],
            outputs: vec!["angle".into()],
            experiments: vec![Experiment {
                name: "e".into(),
                u: DMatrix::from_fn(2000, 1, |k, _| (k as f64).sin()),
                y: DMatrix::from_fn(2000, 1, |k, _| y(k)),
                r: None,
                periodic: None,
            }],
        }
    }

    /// The excitation logged in some records only is named with the records that lack it;
    /// logged in all or in none, nothing is said.
    #[test]
    fn an_excitation_missing_from_some_records_is_named() {
        let mut d = one_output(|k| (0.1 * k as f64).sin());
        let mut second = d.experiments[0].clone();
        second.name = "run2.csv".into();
        second.r = Some(DMatrix::from_fn(2000, 1, |k, _| (0.3 * k as f64).cos()));
        d.experiments.push(second);
        let gap = d.excitation_gap().unwrap();
        assert!(
            gap.starts_with("the excitation (r_u) is logged in run2.csv but not in e:"),
            "{gap}"
        );
        let all = Dataset {
            experiments: vec![d.experiments[1].clone(); 2],
            ..d.clone()
        };
        assert_eq!(all.excitation_gap(), None);
        let none = Dataset {
            experiments: vec![d.experiments[0].clone(); 2],
            ..d
        };
        assert_eq!(none.excitation_gap(), None);
    }

    /// A slow angle on 4096-count encoder steps is coarse, with its step and stillness; the
    /// same angle moving several counts per sample, or with white noise after the encoder,
    /// is not.
    #[test]
    fn coarse_quantization_is_found_with_its_step() {
        let q = std::f64::consts::TAU / 4096.0;
        let slow = |k: usize| 0.006 * (0.05 * k as f64).sin() + 0.003 * (0.13 * k as f64).cos();
        let found = one_output(|k| (slow(k) / q).round() * q).coarse_quantization();
        assert_eq!(found.len(), 1);
        let f = &found[0];
        assert!((f.step / q - 1.0).abs() < 1e-9, "{f:?}");
        assert!(
            f.still > 0.5 && f.rms_steps > 1.0 && f.rms_steps < 5.0,
            "{f:?}"
        );
        assert!(
            f.describe().starts_with("angle (step 1.5340e-3"),
            "{}",
            f.describe()
        );
        let fast = |k: usize| 100.0 * slow(k);
        assert!(one_output(|k| (fast(k) / q).round() * q)
            .coarse_quantization()
            .is_empty());
        let noisy = |k: usize| (slow(k) / q).round() * q + 1e-4 * ((k * k) as f64).sin();
        assert!(one_output(noisy).coarse_quantization().is_empty());
    }

    /// `lead` samples of something else, then `n` samples of `pattern` repeated on two channels.
    fn repeated(pattern: &[f64], lead: usize, n: usize) -> DMatrix<f64> {
        DMatrix::from_fn(lead + n, 2, |i, j| {
            if i < lead {
                7.0 + (i * (j + 1)) as f64
            } else {
                pattern[(i - lead) % pattern.len()] * (j as f64 + 1.0)
            }
        })
    }

    proptest! {
        #[test]
        fn detects_the_period_and_keeps_only_whole_periods_after_the_transient(
            pattern in proptest::collection::vec(-5.0f64..5.0, 4..40),
            periods in 2usize..8,
            extra in 0usize..40,
            lead in 0usize..20,
        ) {
            let p = pattern.len();
            let n = periods * p + extra % p;
            let r = repeated(&pattern, lead, n);
            let smallest = (1..=p).find(|&q| p % q == 0 && (0..p).all(|i| pattern[i] == pattern[(i + q) % p])).unwrap_or(p);
            prop_assume!(smallest == p && lead <= n);
            let l = detect_period(&r).unwrap();
            prop_assert_eq!(l.period, p);
            prop_assert!(l.transient >= lead);
            prop_assert_eq!(l.transient + l.periods * l.period, r.nrows());
            prop_assert!(l.periods >= 2);
            // Every kept period repeats the last one.
            for k in 0..l.periods {
                for i in 0..p {
                    prop_assert_eq!(r[(l.transient + k * p + i, 1)], r[(r.nrows() - p + i, 1)]);
                }
            }
        }
    }

    #[test]
    fn single_precision_rounding_still_repeats() {
        let pattern: Vec<f64> = (0..25).map(|i| (0.37 * i as f64).sin()).collect();
        let mut r = repeated(&pattern, 0, 100);
        for (i, v) in r.iter_mut().enumerate() {
            *v = (*v as f32) as f64 + if i % 2 == 0 { 1e-8 } else { -1e-8 };
        }
        let l = detect_period(&r).unwrap();
        assert_eq!((l.period, l.periods, l.transient), (25, 3, 25));
    }

    #[test]
    fn nothing_repeating_over_the_record_is_not_periodic() {
        let pattern = [1.0, -1.0, 2.0, 0.5, -3.0];
        // Repeats only over the last 40 % of the record: a leading part that long is not a
        // transient but a different signal.
        assert!(detect_period(&repeated(&pattern, 60, 40)).is_none());
        // A constant or zero tail repeats with any period but carries no excitation.
        let mut r = repeated(&pattern, 0, 20);
        r = r.insert_rows(20, 60, 0.0);
        assert!(detect_period(&r).is_none());
        assert!(detect_period(&DMatrix::zeros(100, 2)).is_none());
        // A single period is not enough to see repetition.
        assert!(detect_period(&repeated(&pattern, 0, 9)).is_none());
    }

    #[test]
    fn detected_periods_must_agree_across_experiments() {
        let mut d = small();
        d.experiments[0].periodic = None;
        let pattern = [1.0, -1.0, 2.0, 0.5];
        d.experiments[0].r = Some(repeated(&pattern, 0, 20).columns(0, 1).into_owned());
        // Metadata says 8, the excitation repeats every 4: not one periodic layout.
        let mut other = d.experiments[0].clone();
        other.periodic = Some(Periodic {
            period: 8,
            periods: 2,
            transient: 4,
        });
        d.experiments.push(other);
        assert!(d.periodic_layouts().is_none());
        d.experiments.pop();
        let (layouts, detected) = d.periodic_layouts().unwrap();
        assert_eq!(detected, Some(4));
        assert_eq!(
            layouts,
            [Periodic {
                period: 4,
                periods: 4,
                transient: 4
            }]
        );
    }

    #[test]
    fn why_not_periodic_names_the_experiments_at_fault() {
        let mut d = small();
        d.experiments[0].periodic = None;
        d.experiments[0].r = Some(repeated(&[1.0, -1.0, 2.0, 0.5], 0, 20).columns(0, 1).into());
        // All periodic, or none: nothing to explain.
        assert_eq!(d.why_not_periodic(), None);
        let mut random = d.experiments[0].clone();
        random.name = "e2".into();
        random.u = DMatrix::from_fn(20, 1, |i, _| ((i * i) as f64).sin());
        random.r = Some(random.u.clone());
        let mut blind = random.clone();
        blind.name = "e3".into();
        blind.r = None;
        d.experiments.push(random);
        let why = d.why_not_periodic().unwrap();
        assert!(why.starts_with("experiment e2 is not periodic (no period_samples metadata, and its logged excitation does not repeat), while e1 is:"), "{why}");
        assert!(why.contains("so all 2 went through Welch"), "{why}");
        d.experiments.push(blind);
        let why = d.why_not_periodic().unwrap();
        assert!(
            why.starts_with("experiments e2, e3 are not periodic"),
            "{why}"
        );
        assert!(
            why.contains("e3: no period_samples metadata, and no logged excitation"),
            "{why}"
        );
        // Detected periods that differ from the metadata's.
        d.experiments.truncate(1);
        let mut other = d.experiments[0].clone();
        other.name = "e4".into();
        other.periodic = Some(Periodic {
            period: 8,
            periods: 2,
            transient: 4,
        });
        d.experiments.push(other);
        let why = d.why_not_periodic().unwrap();
        assert!(why.starts_with("the experiments' periods differ (e1 4 samples, detected; e4 8 samples, period_samples metadata)"), "{why}");
        // No experiment periodic: Welch needs no reason.
        for e in &mut d.experiments {
            (e.r, e.periodic) = (None, None);
        }
        assert_eq!(d.why_not_periodic(), None);
    }

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

    proptest! {
        /// An experiment given again with its samples printed to 10 digits (a CSV of an MCAP
        /// log) is refused naming both; one that differs by noise at 1e-4 of the range is
        /// another record.
        #[test]
        fn the_same_samples_twice_are_refused_and_noisy_repeats_are_not(
            samples in proptest::collection::vec(-100.0f64..100.0, 40),
            noise in proptest::collection::vec(-1.0f64..1.0, 40),
        ) {
            let scale = samples.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            prop_assume!(scale > 1.0 && noise.iter().any(|v| v.abs() > 0.5));
            let mut d = small();
            d.experiments[0].periodic = None;
            d.experiments[0].u = DMatrix::from_fn(20, 1, |i, _| samples[i]);
            d.experiments[0].y = DMatrix::from_fn(20, 1, |i, _| samples[20 + i]);
            let mut printed = d.experiments[0].clone();
            printed.name = "e1.csv".into();
            printed.u = printed.u.map(|v| format!("{v:.9e}").parse().unwrap());
            printed.y = printed.y.map(|v| format!("{v:.9e}").parse().unwrap());
            let mut noisy = d.experiments[0].clone();
            noisy.name = "e2".into();
            noisy.y += DMatrix::from_fn(20, 1, |i, _| 1e-4 * scale * noise[i]);
            let mut twice = d.clone();
            twice.experiments.push(printed);
            let err = twice.validate().unwrap_err().to_string();
            prop_assert!(err.contains("e1.csv") && err.contains("holds the samples of e1"), "{}", err);
            d.experiments.push(noisy);
            prop_assert!(d.validate().is_ok());
        }
    }

    #[test]
    fn a_channel_that_is_an_input_and_an_output_is_refused() {
        let mut d = small();
        d.outputs = vec!["u".into()];
        let err = d.validate().unwrap_err().to_string();
        assert!(err.contains("\"u\"") || err.contains("= u"), "{err}");
        assert!(err.contains("input and as an output"), "{err}");
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

    /// An empty or one-sample record is named as such, not as an input nothing excites.
    #[test]
    fn names_a_record_without_samples() {
        for n in [0, 1] {
            let mut d = small();
            d.experiments[0].u = DMatrix::zeros(n, 1);
            d.experiments[0].y = DMatrix::zeros(n, 1);
            d.experiments[0].r = None;
            let msg = d.validate().unwrap_err().to_string();
            assert!(
                msg.contains("e1") && msg.contains(&format!("has {n} sample")),
                "{msg}"
            );
            assert!(msg.contains("at least 2"), "{msg}");
        }
    }

    #[test]
    fn names_mismatched_lengths() {
        let mut d = small();
        d.experiments[0].y = DMatrix::zeros(19, 1);
        let msg = d.validate().unwrap_err().to_string();
        assert!(msg.contains("output samples of e1"), "{msg}");
    }
}
