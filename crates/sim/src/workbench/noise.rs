//! What the cost looks like when the model is right: a Monte-Carlo reference distribution.
//!
//! The weights of the cost come from an estimated covariance, so even the true model does not
//! give `V/dof = 1`: a noisy covariance inflates `E[V]` (inverse-Wishart effect) by an amount
//! that depends on the number of periods and experiments and on the stacking weights. The cost
//! is invariant to the true noise covariance (whitening by the estimate cancels it), so the
//! reference distribution can be drawn exactly for the estimator at hand: per draw and line,
//! period noise with unit covariance, the FRF error `Σ_e n̄_e w_e^T` and the
//! covariance estimate of the same draw, and the statistic `tr(E^H Ŝ^-1 E M^-T)` with
//! `Cov(vec Ĝ) = M ⊗ S`.
use nalgebra::DMatrix;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use serde::Serialize;

use super::frf::{period_covariance, CMatrix, FrfEstimate};
use super::spectra::C64;
use crate::error::{Result, SimError};

/// Reference distribution of the weighted cost at the true parameters.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseReference {
    /// Mean cost per line.
    pub line_mean: Vec<f64>,
    /// Standard deviation of the cost per line.
    pub line_sd: Vec<f64>,
    /// Sorted draws of the total cost.
    #[serde(skip)]
    pub total: Vec<f64>,
    /// Mean of the summed standardised squared error per output row.
    pub row_mean: Vec<f64>,
    /// Its standard deviation.
    pub row_sd: Vec<f64>,
    /// Mean of the summed standardised squared error per FRF entry (outputs x inputs).
    #[serde(skip)]
    pub entry_mean: DMatrix<f64>,
    /// Number of real residuals.
    pub n_residuals: usize,
}

impl NoiseReference {
    /// Draws the reference for a periodic estimate (`draws` Monte-Carlo samples, seeded).
    pub fn periodic(frf: &FrfEstimate, draws: usize, seed: u64) -> Result<Self> {
        if draws < 20 {
            return Err(SimError::invalid(
                "draws",
                draws,
                "need at least 20 Monte-Carlo draws",
            ));
        }
        let (ny, nu) = (frf.ny(), frf.nu());
        let nl = frf.lines.len();
        let mut rng = StdRng::seed_from_u64(seed);
        let mut line_draws = vec![vec![0.0; draws]; nl];
        let mut row_draws = vec![vec![0.0; draws]; ny];
        let mut entry_mean = DMatrix::zeros(ny, nu);
        let dof = frf.noise_dof;
        let scale = std::f64::consts::FRAC_1_SQRT_2;
        let normal = move |rng: &mut StdRng| {
            let re: f64 = rng.sample(StandardNormal);
            let im: f64 = rng.sample(StandardNormal);
            C64::new(re * scale, im * scale)
        };
        for (k, line) in frf.lines.iter().enumerate() {
            let w = &line.weights;
            let mut m = CMatrix::zeros(nu, nu);
            for (e, &p) in frf.periods.iter().enumerate() {
                let we = w.row(e).transpose();
                m += &we * we.adjoint() / C64::from(p as f64);
            }
            let m_inv_t = m
                .clone()
                .try_inverse()
                .ok_or_else(|| {
                    SimError::invalid(
                        "stacking weights",
                        "singular",
                        "cannot draw the noise reference",
                    )
                })?
                .transpose();
            for d in 0..draws {
                let mut err = CMatrix::zeros(ny, nu);
                let mut residuals = Vec::with_capacity(frf.periods.len());
                for (e, &p) in frf.periods.iter().enumerate() {
                    let z = CMatrix::from_fn(ny, p, |_, _| normal(&mut rng));
                    let mean =
                        CMatrix::from_fn(ny, 1, |c, _| z.row(c).iter().sum::<C64>() / p as f64);
                    err += &mean * w.row(e);
                    residuals.push(z);
                }
                let s = period_covariance(&residuals, dof);
                let s_inv = s.clone().try_inverse().ok_or_else(|| {
                    SimError::invalid("noise reference", "singular draw", "too few periods")
                })?;
                let v = (err.adjoint() * &s_inv * &err * &m_inv_t).trace().re;
                line_draws[k][d] = v;
                for i in 0..ny {
                    let mut row = 0.0;
                    for j in 0..nu {
                        let z = err[(i, j)].norm_sqr() / (m[(j, j)].re * s[(i, i)].re);
                        row += z;
                        entry_mean[(i, j)] += z / draws as f64;
                    }
                    row_draws[i][d] += row;
                }
            }
        }
        let stats = |v: &[f64]| {
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (mean, var.sqrt())
        };
        let (line_mean, line_sd): (Vec<_>, Vec<_>) = line_draws.iter().map(|v| stats(v)).unzip();
        let (row_mean, row_sd): (Vec<_>, Vec<_>) = row_draws.iter().map(|v| stats(v)).unzip();
        let mut total: Vec<f64> = (0..draws)
            .map(|d| line_draws.iter().map(|l| l[d]).sum())
            .collect();
        total.sort_by(f64::total_cmp);
        Ok(Self {
            line_mean,
            line_sd,
            total,
            row_mean,
            row_sd,
            entry_mean,
            n_residuals: 2 * ny * nu * nl,
        })
    }

    /// Mean of the total cost at the true parameters.
    pub fn mean(&self) -> f64 {
        self.line_mean.iter().sum()
    }

    /// Mean cost per real residual (the noise scale of one squared whitened residual).
    pub fn per_residual(&self) -> f64 {
        self.mean() / self.n_residuals as f64
    }

    /// Quantile `q` of the total cost at the true parameters.
    pub fn quantile(&self, q: f64) -> f64 {
        let n = self.total.len();
        let i = ((q * (n - 1) as f64).round() as usize).min(n - 1);
        self.total[i]
    }

    /// Expected cost and its upper 99% bound after fitting `p` parameters: fitting removes
    /// about one residual's worth of noise per parameter.
    pub fn fitted_level(&self, p: usize) -> (f64, f64) {
        let shift = p as f64 * self.per_residual();
        (self.mean() - shift, self.quantile(0.99) - shift)
    }
}
