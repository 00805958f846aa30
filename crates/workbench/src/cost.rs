//! The paper's variance-weighted frequency-domain cost (spec §6.5),
//! `V(theta) = sum_w vec(G_theta - Ĝ)^H Cov(vec Ĝ)^-1 vec(G_theta - Ĝ)`, as a sum of squares of
//! whitened real residuals so that Gauss-Newton and Levenberg-Marquardt apply.
use nalgebra::{DMatrix, DVector};

use super::frf::{CMatrix, FrfEstimate, LineMap};
use super::spectra::C64;
use crate::error::{Result, SimError};

/// Whitening of one line: `z = L^-1 vec(E)` with `Cov = L L^H`.
#[derive(Debug, Clone)]
enum Whitener {
    /// A general covariance.
    Full(CMatrix),
    /// `Cov = M ⊗ S`: `L = L_M ⊗ L_S`, so `z = vec(L_S^-1 E L_M^-T)` (same result, a fraction
    /// of the work).
    Kronecker { m_inv_t: CMatrix, s_inv: CMatrix },
}

impl Whitener {
    fn apply(&self, e: &CMatrix) -> CMatrix {
        match self {
            Self::Full(linv) => {
                let z = linv * DVector::from_iterator(e.len(), e.iter().cloned());
                CMatrix::from_iterator(e.nrows(), e.ncols(), z.iter().cloned())
            }
            Self::Kronecker { m_inv_t, s_inv } => s_inv * e * m_inv_t,
        }
    }
}

/// Correlation of the whitened errors of neighbouring Welch lines, which share the window's
/// kernel (see [`crate::welch::CORRELATED_LINES`]): after each line's whitening `z_k = (L_Mk^-1
/// ⊗ L_Sk^-1) vec E_k`, `E[z_k z_j^H] = A_kj ⊗ I` with `A_kj = L_Mk^-1 M_kj L_Mj^-H` for a noise
/// flat over the lines. The fit keeps every line and weighs each alone (whitening across
/// lines with a modelled noise cross-spectrum bent a two-output fit whose noise turns within a
/// few bins); this correlation goes into its parameters' covariance ([`LineCorrelation::gram`]).
#[derive(Debug, Clone, Default)]
pub struct LineCorrelation {
    /// `A_kj` per line for `j = k - 1, k - 2, ...`, nearest first; empty for periodic lines.
    blocks: Vec<Vec<CMatrix>>,
    ny: usize,
}

impl LineCorrelation {
    /// The correlation of the lines of `frf` (none for periodic estimates).
    pub fn new(frf: &FrfEstimate) -> Result<Self> {
        if frf.lines.iter().all(|l| l.previous.is_empty()) {
            return Ok(Self::default());
        }
        let l_inv: Vec<CMatrix> = frf
            .lines
            .iter()
            .map(|line| match &line.kronecker {
                Some((m, _)) => chol_inv(m, &format!("FRF weights at {:.3} Hz", line.freq_hz)),
                None => Err(SimError::invalid(
                    format!("FRF line at {:.3} Hz", line.freq_hz),
                    "correlated with its neighbours but not of the form M ⊗ S",
                    "only a Kronecker-structured covariance has a line correlation",
                )),
            })
            .collect::<Result<_>>()?;
        let blocks = frf
            .lines
            .iter()
            .enumerate()
            .map(|(k, line)| {
                (1..=k)
                    .zip(&line.previous)
                    .map(|(d, m)| &l_inv[k] * m * l_inv[k - d].adjoint())
                    .collect()
            })
            .collect();
        Ok(Self {
            blocks,
            ny: frf.ny(),
        })
    }

    /// `J^T Ω J` for a Jacobian `j` of the stacked real residuals `[Re z_k; Im z_k]` (one
    /// column per parameter), `Ω` the residuals' correlation: `Re Σ_kj J_k^H Ω_kj J_j` in the
    /// complex residuals. `J^T J` when the lines are independent.
    pub fn gram(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        let mut g = j.transpose() * j;
        if self.blocks.is_empty() {
            return g;
        }
        let p = j.ncols();
        let m = j.nrows() / (2 * self.blocks.len());
        let line = |k: usize| {
            CMatrix::from_fn(m, p, |r, c| {
                C64::new(j[(2 * m * k + r, c)], j[(2 * m * k + m + r, c)])
            })
        };
        let lines: Vec<CMatrix> = (0..self.blocks.len()).map(line).collect();
        for (k, blocks_k) in self.blocks.iter().enumerate() {
            for (d, a) in blocks_k.iter().enumerate() {
                // (A ⊗ I_ny) J_j, vec index `input * ny + output`.
                let jj = &lines[k - d - 1];
                let moved = CMatrix::from_fn(m, p, |r, c| {
                    let (ai, oi) = (r / self.ny, r % self.ny);
                    (0..a.ncols())
                        .map(|b| a[(ai, b)] * jj[(b * self.ny + oi, c)])
                        .sum()
                });
                let cross = (lines[k].adjoint() * moved).map(|v| v.re);
                g += &cross + cross.transpose();
            }
        }
        g
    }
}

/// Lower Cholesky factor's inverse of a Hermitian matrix with a relative ridge of 1e-12 (keeps
/// a channel without noise, such as a constant output, from breaking the factorisation).
fn chol_inv(cov: &CMatrix, what: &str) -> Result<CMatrix> {
    let n = cov.nrows();
    let max_diag = (0..n).map(|i| cov[(i, i)].re).fold(0.0, f64::max);
    if max_diag.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(SimError::invalid(
            what,
            "zero",
            "the periods are identical (noise-free data); a variance-weighted cost needs noise",
        ));
    }
    let mut c = cov.clone();
    for i in 0..n {
        c[(i, i)] += C64::from(1e-12 * max_diag);
    }
    let chol = c.cholesky().ok_or_else(|| {
        SimError::invalid(
            what,
            "not positive definite",
            "too few periods or experiments to estimate the noise of every channel",
        )
    })?;
    chol.l()
        .solve_lower_triangular(&CMatrix::identity(n, n))
        .ok_or_else(|| SimError::invalid(what, "singular", "cannot whiten"))
}

/// Whitening operators per line, built once from the FRF covariance.
#[derive(Debug, Clone)]
pub struct WeightedCost {
    /// Where a model is evaluated and how the lines see it ([`crate::Model::frf_seen`]).
    pub map: LineMap,
    targets: Vec<CMatrix>,
    whiten: Vec<Whitener>,
    /// How the lines' whitened errors correlate, for the parameters' covariance.
    pub correlation: LineCorrelation,
    /// Standard deviation of each FRF entry per line (outputs x inputs), for bands and
    /// standardised errors.
    pub std: Vec<DMatrix<f64>>,
    ny: usize,
    nu: usize,
}

impl WeightedCost {
    /// Builds `L^-1` with `Cov = L L^H` for each line. A covariance that is exactly zero
    /// (noise-free data) cannot weight a cost and is reported as an error.
    pub fn new(frf: &FrfEstimate) -> Result<Self> {
        Self::build(frf, None)
    }

    /// The cost with each line's noise covariance `S` of `Cov = M ⊗ S` replaced by `noise[k]`
    /// (the weighting re-estimated from a model's residual, [`super::frf::model_noise`]).
    pub fn with_noise(frf: &FrfEstimate, noise: &[CMatrix]) -> Result<Self> {
        if noise.len() != frf.lines.len() {
            return Err(SimError::invalid(
                "noise covariances",
                noise.len(),
                format!("need one per FRF line ({})", frf.lines.len()),
            ));
        }
        Self::build(frf, Some(noise))
    }

    fn build(frf: &FrfEstimate, noise: Option<&[CMatrix]>) -> Result<Self> {
        let (ny, nu) = (frf.ny(), frf.nu());
        let mut whiten = Vec::with_capacity(frf.lines.len());
        let mut std = Vec::with_capacity(frf.lines.len());
        for (k, line) in frf.lines.iter().enumerate() {
            let what = format!("FRF noise covariance at {:.3} Hz", line.freq_hz);
            let (w, sd) = match (&line.kronecker, noise) {
                (Some((m, s)), _) => {
                    let s = noise.map_or(s, |n| &n[k]);
                    let sd = DMatrix::from_fn(ny, nu, |i, j| {
                        (m[(j, j)].re * s[(i, i)].re).max(0.0).sqrt()
                    });
                    let w = Whitener::Kronecker {
                        m_inv_t: chol_inv(m, &what)?.transpose(),
                        s_inv: chol_inv(s, &what)?,
                    };
                    (w, sd)
                }
                (None, Some(_)) => {
                    return Err(SimError::invalid(
                        what,
                        "not of the form M ⊗ S",
                        "only a Kronecker-structured covariance can take a re-estimated noise",
                    ))
                }
                (None, None) => {
                    let sd = DMatrix::from_fn(ny, nu, |i, j| {
                        line.cov[(j * ny + i, j * ny + i)].re.max(0.0).sqrt()
                    });
                    (Whitener::Full(chol_inv(&line.cov, &what)?), sd)
                }
            };
            whiten.push(w);
            std.push(sd);
        }
        Ok(Self {
            map: LineMap::new(frf),
            targets: frf.lines.iter().map(|l| l.g.clone()).collect(),
            whiten,
            correlation: LineCorrelation::new(frf)?,
            std,
            ny,
            nu,
        })
    }

    /// Number of real residuals (2 per complex FRF entry and line).
    pub fn n_residuals(&self) -> usize {
        2 * self.ny * self.nu * self.targets.len()
    }

    /// The measured FRF per line.
    pub fn targets(&self) -> &[CMatrix] {
        &self.targets
    }

    fn whitened(&self, k: usize, g: &CMatrix) -> CMatrix {
        self.whiten[k].apply(&(g - &self.targets[k]))
    }

    /// Cost of one line.
    pub fn line_cost(&self, k: usize, g: &CMatrix) -> f64 {
        self.whitened(k, g).iter().map(|z| z.norm_sqr()).sum()
    }

    /// Total cost for model FRFs on every line.
    pub fn cost(&self, model: &[CMatrix]) -> f64 {
        model
            .iter()
            .enumerate()
            .map(|(k, g)| self.line_cost(k, g))
            .sum()
    }

    /// Real whitened residuals `[Re z; Im z]` per line, stacked.
    pub fn residuals(&self, model: &[CMatrix]) -> DVector<f64> {
        let m = self.ny * self.nu;
        let mut r = DVector::zeros(self.n_residuals());
        for (k, g) in model.iter().enumerate() {
            let z = self.whitened(k, g);
            for (i, v) in z.iter().enumerate() {
                r[2 * m * k + i] = v.re;
                r[2 * m * k + m + i] = v.im;
            }
        }
        r
    }

    /// Jacobian of [`WeightedCost::residuals`] from FRF derivatives `d[k][i] = dG_k/dtheta_i`.
    pub fn jacobian(&self, d: &[Vec<CMatrix>]) -> DMatrix<f64> {
        let m = self.ny * self.nu;
        let p = d.first().map_or(0, |v| v.len());
        let mut j = DMatrix::zeros(self.n_residuals(), p);
        for (k, dk) in d.iter().enumerate() {
            for (i, dg) in dk.iter().enumerate() {
                let z = self.whiten[k].apply(dg);
                for (r, v) in z.iter().enumerate() {
                    j[(2 * m * k + r, i)] = v.re;
                    j[(2 * m * k + m + r, i)] = v.im;
                }
            }
        }
        j
    }

    /// Squared standardised error `|G - Ĝ|^2 / var` per line and entry (outputs x inputs).
    pub fn standardised(&self, model: &[CMatrix]) -> Vec<DMatrix<f64>> {
        model
            .iter()
            .enumerate()
            .map(|(k, g)| {
                DMatrix::from_fn(self.ny, self.nu, |i, j| {
                    let s = self.std[k][(i, j)];
                    let e = (g[(i, j)] - self.targets[k][(i, j)]).norm_sqr();
                    if s > 0.0 {
                        e / (s * s)
                    } else {
                        0.0
                    }
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn hermitian_pd(n: usize, seed: &[f64]) -> CMatrix {
        let a = CMatrix::from_fn(n, n, |i, j| {
            C64::new(
                seed[(i * n + j) % seed.len()],
                seed[(i + 3 * j + 1) % seed.len()],
            )
        });
        &a * a.adjoint() + CMatrix::identity(n, n) * C64::from(0.5)
    }

    proptest! {
        /// Whitening with `L_M^-1 ⊗ L_S^-1` gives the same cost as the Cholesky factor of the
        /// full covariance `M ⊗ S`.
        #[test]
        fn kronecker_whitening_equals_full_whitening(
            seed in proptest::collection::vec(-1.0f64..1.0, 12),
            e in proptest::collection::vec(-1.0f64..1.0, 12),
        ) {
            let (m, s) = (hermitian_pd(3, &seed), hermitian_pd(2, &seed[3..]));
            let err = CMatrix::from_fn(2, 3, |i, j| C64::new(e[2 * (i * 3 + j)], e[2 * (i * 3 + j) + 1]));
            let kron = Whitener::Kronecker { m_inv_t: chol_inv(&m, "m").unwrap().transpose(), s_inv: chol_inv(&s, "s").unwrap() };
            let full = Whitener::Full(chol_inv(&m.kronecker(&s), "full").unwrap());
            let (a, b) = (kron.apply(&err), full.apply(&err));
            let direct = {
                let v = DVector::from_iterator(6, err.iter().cloned());
                (v.adjoint() * m.kronecker(&s).try_inverse().unwrap() * &v)[(0, 0)].re
            };
            prop_assert!((a.norm_squared() - b.norm_squared()).abs() <= 1e-6 * (1.0 + direct));
            prop_assert!((a.norm_squared() - direct).abs() <= 1e-6 * (1.0 + direct));
        }

        /// `LineCorrelation::gram` is `J^T Ω_r J` with `Ω_r` the real form `[[Re Ω, -Im Ω],
        /// [Im Ω, Re Ω]]` of the complex correlation `Ω` (blocks `A_kj ⊗ I` below the diagonal,
        /// their adjoints above, `I` on it), written out densely; two outputs, two inputs, five
        /// lines, each correlated with the two before it.
        #[test]
        fn line_correlation_gram_is_the_dense_sandwich_middle(
            a in proptest::collection::vec(-0.3f64..0.3, 5 * 2 * 8),
            jv in proptest::collection::vec(-1.0f64..1.0, 5 * 8 * 3),
        ) {
            let (nl, ny, nu, p) = (5, 2, 2, 3);
            let m = ny * nu;
            let block = |k: usize, d: usize| {
                let o = (k * 2 + d) * 8;
                CMatrix::from_fn(nu, nu, |i, j| C64::new(a[o + 2 * (i * nu + j)], a[o + 2 * (i * nu + j) + 1]))
            };
            let blocks: Vec<Vec<CMatrix>> = (0..nl).map(|k| (0..k.min(2)).map(|d| block(k, d)).collect()).collect();
            let omega = |k: usize, j: usize| -> CMatrix {
                if k == j {
                    CMatrix::identity(m, m)
                } else if k > j && k - j <= 2 {
                    blocks[k][k - j - 1].kronecker(&CMatrix::identity(ny, ny))
                } else if j > k && j - k <= 2 {
                    blocks[j][j - k - 1].kronecker(&CMatrix::identity(ny, ny)).adjoint()
                } else {
                    CMatrix::zeros(m, m)
                }
            };
            let n = 2 * m * nl;
            let dense = DMatrix::from_fn(n, n, |r, c| {
                let (k, j) = (r / (2 * m), c / (2 * m));
                let (rr, cc) = (r % (2 * m), c % (2 * m));
                let w = omega(k, j)[(rr % m, cc % m)];
                match (rr < m, cc < m) {
                    (true, true) | (false, false) => w.re,
                    (true, false) => -w.im,
                    (false, true) => w.im,
                }
            });
            let j = DMatrix::from_column_slice(n, p, &jv);
            let correlation = LineCorrelation { blocks, ny };
            let direct = j.transpose() * dense * &j;
            let gram = correlation.gram(&j);
            prop_assert!((&gram - &direct).norm() <= 1e-9 * (1.0 + direct.norm()), "{gram} vs {direct}");
        }
    }
}
