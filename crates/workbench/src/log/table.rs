//! A topic of a log as columns: one time vector and one vector per named field, the shape in
//! which identification and plotting want measurements.
use crate::error::{Result, SimError};

/// How far one step of `t` may stray from the median step of a uniformly sampled table, as a
/// fraction of that step (timestamps printed to a few digits stay well inside it; a missing or
/// repeated sample is a whole step off).
pub const UNIFORM_TOLERANCE: f64 = 0.01;

/// How far a stamp may lie from the regular grid fitted to all stamps, as a fraction of the
/// period, for the samples to be taken as evenly spaced. A logger that stamps a message when it
/// handles it scatters the stamps around the instants a hardware clock sampled; a missing or
/// repeated sample moves every later stamp by a whole period, which no line through the stamps
/// follows to better than half a period.
pub const JITTER_TOLERANCE: f64 = 0.2;

/// Time stamps that scatter around a regular grid by more than [`UNIFORM_TOLERANCE`] of a step
/// but at most [`JITTER_TOLERANCE`] of the period: the samples are taken as evenly spaced at
/// the grid's period, which the caller reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jitter {
    /// The sample whose stamp lies farthest from the grid.
    pub sample: usize,
    /// Its distance from the grid, s.
    pub deviation: f64,
    /// The grid's period (least squares through every stamp), s.
    pub period: f64,
}

impl std::fmt::Display for Jitter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "time stamps scatter around a regular grid by up to {:.3e} s ({:.1} % of the period, \
             at sample {}); the samples are taken as evenly spaced at {:.6} Hz",
            self.deviation,
            100.0 * self.deviation / self.period,
            self.sample,
            1.0 / self.period
        )
    }
}

/// Time-stamped samples of named fields, stored by column.
///
/// ```
/// use workbench::log::Table;
/// let mut table = Table::new("/demo/output", ["x", "v"]);
/// table.push(0.0, &[1.0, 0.0]).unwrap();
/// table.push(0.1, &[0.9, -1.0]).unwrap();
/// assert_eq!(table.column("v").unwrap(), &[0.0, -1.0]);
/// assert!(table.column("a").is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Where the table came from (a topic or a file), used in error messages.
    pub name: String,
    /// Sample times in seconds.
    pub t: Vec<f64>,
    /// Field names, in the order of `columns`.
    pub fields: Vec<String>,
    /// One column per field, each as long as `t`.
    pub columns: Vec<Vec<f64>>,
}

impl Table {
    /// An empty table with the given fields.
    pub fn new<S: Into<String>>(
        name: impl Into<String>,
        fields: impl IntoIterator<Item = S>,
    ) -> Self {
        let fields: Vec<String> = fields.into_iter().map(Into::into).collect();
        let columns = vec![Vec::new(); fields.len()];
        Self {
            name: name.into(),
            t: Vec::new(),
            fields,
            columns,
        }
    }

    /// A table from whole columns; every column must be as long as `t`.
    pub fn from_columns(
        name: impl Into<String>,
        t: Vec<f64>,
        fields: Vec<String>,
        columns: Vec<Vec<f64>>,
    ) -> Result<Self> {
        let name = name.into();
        if fields.len() != columns.len() {
            return Err(SimError::LengthMismatch {
                what: format!("number of columns of {name}"),
                expected: fields.len(),
                found: columns.len(),
            });
        }
        for (field, column) in fields.iter().zip(&columns) {
            if column.len() != t.len() {
                return Err(SimError::LengthMismatch {
                    what: format!("column {field:?} of {name}"),
                    expected: t.len(),
                    found: column.len(),
                });
            }
        }
        Ok(Self {
            name,
            t,
            fields,
            columns,
        })
    }

    /// Appends one sample; `values` holds one value per field.
    pub fn push(&mut self, t: f64, values: &[f64]) -> Result<()> {
        if values.len() != self.fields.len() {
            return Err(SimError::LengthMismatch {
                what: format!("sample of {} at t = {t}", self.name),
                expected: self.fields.len(),
                found: values.len(),
            });
        }
        self.t.push(t);
        for (column, &value) in self.columns.iter_mut().zip(values) {
            column.push(value);
        }
        Ok(())
    }

    /// The column of `field`, or [`SimError::MissingField`] naming the fields there are.
    pub fn column(&self, field: &str) -> Result<&[f64]> {
        self.fields
            .iter()
            .position(|f| f == field)
            .map(|i| self.columns[i].as_slice())
            .ok_or_else(|| SimError::MissingField {
                context: self.name.clone(),
                field: field.to_string(),
                available: self.fields.clone(),
            })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when the table holds no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The sample rate of a uniformly sampled table, Hz, and the stamps' [`Jitter`] if they
    /// scatter. A named error unless `t` increases and either every step stays within
    /// [`UNIFORM_TOLERANCE`] of the median step, or every stamp lies within
    /// [`JITTER_TOLERANCE`] of a period from the regular grid fitted to them (a missing,
    /// repeated or out-of-order sample, or a clock that changes rate, fails both); and, when
    /// `declared` (the `sample_rate_hz` of the experiment record), unless that rate agrees with
    /// the stamps to [`UNIFORM_TOLERANCE`]. The spectral and time-domain fits assume one known
    /// step, so each problem is an error, not a warning.
    pub fn sample_rate(
        &self,
        declared: Option<f64>,
        file: &std::path::Path,
    ) -> Result<(f64, Option<Jitter>)> {
        let t = &self.t;
        let name = if self.name == file.display().to_string() {
            self.name.clone()
        } else {
            format!("{} in {}", self.name, file.display())
        };
        if t.len() < 2 {
            return Err(SimError::invalid(
                format!("samples of {name}"),
                t.len(),
                "need at least two samples",
            ));
        }
        for (k, w) in t.windows(2).enumerate() {
            if (w[1] - w[0]).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return Err(SimError::invalid(
                    format!("t of {name} at sample {}", k + 1),
                    format!("{} s", w[1]),
                    format!("must increase (the sample before is at t = {})", w[0]),
                ));
            }
        }
        // Steps are judged against the median step, which a gap does not move (against the
        // mean, one long gap makes every regular step look uneven and is named at sample 1).
        let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
        let mid = steps.len() / 2;
        let typical = *steps.select_nth_unstable_by(mid, f64::total_cmp).1;
        let uneven = |k: usize, value: f64, why: String| {
            SimError::invalid(
                format!("t of {name} at sample {k}"),
                format!("{value} s"),
                format!("uneven sampling: {why} (samples missing, repeated or out of order?)"),
            )
        };
        let stray = |tol: f64| {
            t.windows(2)
                .enumerate()
                .find(|(_, w)| ((w[1] - w[0]) - typical).abs() > tol * typical)
        };
        if stray(UNIFORM_TOLERANCE).is_none() {
            let rate = 1.0 / ((t[t.len() - 1] - t[0]) / (t.len() - 1) as f64);
            return Ok((Self::agree(&name, declared, rate)?, None));
        }
        // Jitter of at most JITTER_TOLERANCE per stamp changes a step by at most twice that:
        // a longer or shorter step is a sample missing or repeated, named where it is.
        if let Some((k, w)) = stray(2.0 * JITTER_TOLERANCE) {
            let step = w[1] - w[0];
            return Err(uneven(
                k + 1,
                w[1],
                format!("a step of {step:.6} s where the typical (median) step is {typical:.6} s"),
            ));
        }
        // The regular grid t0 + k T through the stamps (least squares, centred for accuracy).
        let n = t.len() as f64;
        let kbar = 0.5 * (n - 1.0);
        let tbar = t.iter().map(|v| v - t[0]).sum::<f64>() / n;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (k, v) in t.iter().enumerate() {
            let dk = k as f64 - kbar;
            sxy += dk * (v - t[0] - tbar);
            sxx += dk * dk;
        }
        let period = sxy / sxx;
        let (sample, deviation) = t
            .iter()
            .enumerate()
            .map(|(k, v)| (k, (v - t[0] - tbar - (k as f64 - kbar) * period).abs()))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        if deviation.is_nan() || deviation > JITTER_TOLERANCE * period {
            return Err(uneven(
                sample,
                t[sample],
                format!(
                    "the stamp lies {deviation:.3e} s ({:.0} % of the {period:.6} s period) from \
                     the regular grid through all stamps, more than the {:.0} % a logger's \
                     jitter may",
                    100.0 * deviation / period,
                    100.0 * JITTER_TOLERANCE
                ),
            ));
        }
        let jitter = Jitter {
            sample,
            deviation,
            period,
        };
        Ok((Self::agree(&name, declared, 1.0 / period)?, Some(jitter)))
    }

    /// The declared rate where one is given and agrees with the stamps' `rate`, else `rate`.
    fn agree(name: &str, declared: Option<f64>, rate: f64) -> Result<f64> {
        match declared {
            Some(fs)
                if (fs - rate).abs().is_nan() || (fs - rate).abs() > UNIFORM_TOLERANCE * rate =>
            {
                Err(SimError::invalid(
                    format!("sample_rate_hz of {name}"),
                    fs,
                    format!("disagrees with its t column, which steps at {rate:.6} Hz"),
                ))
            }
            Some(fs) => Ok(fs),
            None => Ok(rate),
        }
    }

    /// First and last sample time, if there are samples.
    pub fn span(&self) -> Option<(f64, f64)> {
        Some((*self.t.first()?, *self.t.last()?))
    }
}
