//! Stage constraints `lower ≤ Cx x(t) + Cu u(t) ≤ upper`, imposed for all t ≥ 0.

use crate::error::{Error, Result};
use nalgebra::DMatrix;

/// Rows of mixed state/input constraints with two-sided limits (±∞ for one-sided rows).
/// The origin must be admissible (lower ≤ 0 ≤ upper), as MPC regulates to it.
#[derive(Debug, Clone, PartialEq)]
pub struct Constraints {
    /// State coefficients, nc×n.
    pub cx: DMatrix<f64>,
    /// Input coefficients, nc×m.
    pub cu: DMatrix<f64>,
    /// Lower limits (length nc, entries ≤ 0 or −∞).
    pub lower: Vec<f64>,
    /// Upper limits (length nc, entries ≥ 0 or +∞).
    pub upper: Vec<f64>,
}

impl Constraints {
    /// Box constraints: one row per state or input component with a finite limit.
    /// `state[i] = (lower, upper)`, `input[j] = (lower, upper)`.
    pub fn boxes(state: &[(f64, f64)], input: &[(f64, f64)]) -> Self {
        let (n, m) = (state.len(), input.len());
        let mut rows = Vec::new();
        for (i, &(lo, up)) in state.iter().enumerate() {
            if lo.is_finite() || up.is_finite() {
                rows.push((i, lo, up));
            }
        }
        for (j, &(lo, up)) in input.iter().enumerate() {
            if lo.is_finite() || up.is_finite() {
                rows.push((n + j, lo, up));
            }
        }
        let nc = rows.len();
        let mut cx = DMatrix::zeros(nc, n);
        let mut cu = DMatrix::zeros(nc, m);
        for (k, &(idx, _, _)) in rows.iter().enumerate() {
            if idx < n {
                cx[(k, idx)] = 1.0;
            } else {
                cu[(k, idx - n)] = 1.0;
            }
        }
        Self {
            cx,
            cu,
            lower: rows.iter().map(|r| r.1).collect(),
            upper: rows.iter().map(|r| r.2).collect(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.lower.len()
    }

    /// True if there are no rows.
    pub fn is_empty(&self) -> bool {
        self.lower.is_empty()
    }

    /// Check shapes against (n, m) and the limits.
    pub fn validate(&self, n: usize, m: usize) -> Result<()> {
        let nc = self.lower.len();
        crate::check_shape("Cx", &self.cx, nc, n)?;
        crate::check_shape("Cu", &self.cu, nc, m)?;
        if self.upper.len() != nc {
            return Err(Error::Shape {
                name: "upper",
                rows: self.upper.len(),
                cols: 1,
                expected_rows: nc,
                expected_cols: 1,
            });
        }
        crate::check_finite("Cx", self.cx.as_slice())?;
        crate::check_finite("Cu", self.cu.as_slice())?;
        for (row, (&lower, &upper)) in self.lower.iter().zip(&self.upper).enumerate() {
            if lower.is_nan() || upper.is_nan() || lower > 0.0 || upper < 0.0 {
                return Err(Error::Limits { row, lower, upper });
            }
        }
        Ok(())
    }
}
