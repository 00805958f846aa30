//! A topic of a log as columns: one time vector and one vector per named field, the shape in
//! which identification and plotting want measurements.
use crate::error::{Result, SimError};

/// How far one step of `t` may stray from the median step of a uniformly sampled table, as a
/// fraction of that step (timestamps printed to a few digits stay well inside it; a missing or
/// repeated sample is a whole step off).
pub const UNIFORM_TOLERANCE: f64 = 0.01;

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

    /// The sample rate of a uniformly sampled table, Hz: a named error unless `t` increases in
    /// steps that each stay within [`UNIFORM_TOLERANCE`] of their median, and, when `declared`
    /// (the `sample_rate_hz` of the experiment record), unless that rate agrees with the steps
    /// to the same tolerance. The spectral and time-domain fits assume one known step, so
    /// either problem is an error, not a warning.
    pub fn sample_rate(&self, declared: Option<f64>, file: &std::path::Path) -> Result<f64> {
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
        let dt = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
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
        for (k, w) in t.windows(2).enumerate() {
            let step = w[1] - w[0];
            if (step - typical).abs() > UNIFORM_TOLERANCE * typical {
                return Err(SimError::invalid(
                    format!("t of {name} at sample {}", k + 1),
                    format!("{} s", w[1]),
                    format!(
                        "uneven sampling: a step of {step:.6} s where the typical (median) step \
                         is {typical:.6} s (samples missing, repeated or out of order?)"
                    ),
                ));
            }
        }
        let rate = 1.0 / dt;
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
