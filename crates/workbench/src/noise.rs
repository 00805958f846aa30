//! What the cost looks like when the model is right: a Monte-Carlo reference distribution.
//!
//! The weights of the cost come from an estimated covariance, so even the true model does not
//! give `V/dof = 1`: a noisy covariance inflates `E[V]` (inverse-Wishart effect) by an amount
//! that depends on the number of periods and experiments and on the stacking weights. The cost
//! is invariant to the true noise covariance (whitening by the estimate cancels it), so the
//! reference distribution can be drawn exactly for the estimator at hand: per draw and line,
//! period means with covariance `I/P_e`, the FRF error `Σ_e n̄_e w_e^T`, and the pooled
//! covariance estimate (independent of the means for Gaussian noise, complex Wishart with
//! `Σ_e (P_e - 1)` degrees of freedom, drawn by the Bartlett decomposition), and the statistic `tr(E^H Ŝ^-1 E M^-T)` with
//! `Cov(vec Ĝ) = M ⊗ S`.
use nalgebra::DMatrix;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{ChiSquared, Distribution, StandardNormal};
use serde::Serialize;

use super::frf::{pooled_weights, CMatrix, FrfEstimate};
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

/// Complex Wishart `CW_p(n, I)` by the Bartlett decomposition: `W = T T^H` with `T` lower
/// triangular, `|T_ii|^2 ~ chi2(2(n - i)) / 2` (i from 0) and `T_ij ~ CN(0, 1)` below the
/// diagonal; p(p+1)/2 draws instead of n p.
#[derive(Debug)]
struct ComplexWishart {
    diag: Vec<ChiSquared<f64>>,
}

impl ComplexWishart {
    fn new(p: usize, n: usize) -> Result<Self> {
        if n < p {
            return Err(SimError::invalid(
                "noise degrees of freedom",
                n,
                format!("need at least {p} (each experiment's periods after its first, less one, up to 4 and 2 P - 5 for P beyond, summed over the experiments: a single record of four periods gives 2) to estimate the {p}x{p} noise covariance of the periodic FRF: log more periods per experiment, or more experiments"),
            ));
        }
        let diag = (0..p)
            .map(|i| {
                ChiSquared::new(2.0 * (n - i) as f64)
                    .map_err(|e| SimError::invalid("chi-square", n - i, e.to_string()))
            })
            .collect::<Result<_>>()?;
        Ok(Self { diag })
    }

    fn sample(&self, rng: &mut StdRng, normal: &dyn Fn(&mut StdRng) -> C64) -> CMatrix {
        let p = self.diag.len();
        let mut t = CMatrix::zeros(p, p);
        for i in 0..p {
            t[(i, i)] = C64::from((0.5 * self.diag[i].sample(rng)).sqrt());
            for j in 0..i {
                t[(i, j)] = normal(rng);
            }
        }
        &t * t.adjoint()
    }
}

/// One Monte-Carlo draw at line `k`: the FRF error and the noise covariance estimate.
pub(crate) type LineDraw<'a> = dyn FnMut(usize, &mut StdRng) -> Result<(CMatrix, CMatrix)> + 'a;

/// A circular complex normal draw, `CN(0, 1)`.
pub(crate) fn complex_normal(rng: &mut StdRng) -> C64 {
    let scale = std::f64::consts::FRAC_1_SQRT_2;
    let re: f64 = rng.sample(StandardNormal);
    let im: f64 = rng.sample(StandardNormal);
    C64::new(re * scale, im * scale)
}

impl NoiseReference {
    /// Draws the reference for a periodic estimate (`draws` Monte-Carlo samples, seeded).
    pub fn periodic(frf: &FrfEstimate, draws: usize, seed: u64) -> Result<Self> {
        let (ny, nu) = (frf.ny(), frf.nu());
        let dof = frf.noise_dof;
        let wishart = ComplexWishart::new(ny, dof)?;
        let ms: Vec<CMatrix> = frf
            .lines
            .iter()
            .map(|line| pooled_weights(&line.weights, &line.mean_variance))
            .collect();
        Self::from_draws(&ms, ny, draws, seed, &mut |k, rng| {
            let line = &frf.lines[k];
            let w = &line.weights;
            let mut err = CMatrix::zeros(ny, nu);
            for (e, &v) in line.mean_variance.iter().enumerate() {
                let mean = CMatrix::from_fn(ny, 1, |_, _| complex_normal(rng) * v.sqrt());
                err += &mean * w.row(e);
            }
            let s = wishart.sample(rng, &complex_normal) / C64::from(dof as f64);
            Ok((err, s))
        })
    }

    /// The reference from joint draws, per line `k`, of the FRF error `E` and the noise
    /// covariance estimate `Ŝ` for unit noise (`draw(k, rng)`), where `Cov(vec Ĝ) = M_k ⊗ S`:
    /// the statistic of each draw is the line's cost `tr(E^H Ŝ^-1 E M_k^-T)`.
    pub(crate) fn from_draws(
        ms: &[CMatrix],
        ny: usize,
        draws: usize,
        seed: u64,
        draw: &mut LineDraw<'_>,
    ) -> Result<Self> {
        if draws < 20 {
            return Err(SimError::invalid(
                "draws",
                draws,
                "need at least 20 Monte-Carlo draws",
            ));
        }
        let nu = ms.first().map_or(0, |m| m.nrows());
        let nl = ms.len();
        let mut rng = StdRng::seed_from_u64(seed);
        let mut line_draws = vec![vec![0.0; draws]; nl];
        let mut row_draws = vec![vec![0.0; draws]; ny];
        let mut entry_mean = DMatrix::zeros(ny, nu);
        for (k, m) in ms.iter().enumerate() {
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
                let (err, s) = draw(k, &mut rng)?;
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

    /// The reference with `covariance` (the lines' costs' covariances summed over every
    /// ordered pair of different lines) added to the total's variance: each draw of the total
    /// is moved away from the mean by the factor that does it, so the mean stays and the
    /// quantiles widen with the spread. Draws that take the lines as independent need it where
    /// the lines correlate (neighbouring Welch lines).
    pub fn with_cross_line_covariance(mut self, covariance: f64) -> Self {
        let var = self.sd().powi(2);
        if covariance.is_finite() && var > 0.0 {
            let factor = (1.0 + covariance / var).max(0.0).sqrt();
            let mean = self.total.iter().sum::<f64>() / self.total.len() as f64;
            for x in &mut self.total {
                *x = mean + (*x - mean) * factor;
            }
        }
        self
    }

    /// Mean of the total cost at the true parameters.
    pub fn mean(&self) -> f64 {
        self.line_mean.iter().sum()
    }

    /// Mean cost per real residual (the noise scale of one squared whitened residual).
    pub fn per_residual(&self) -> f64 {
        self.mean() / self.n_residuals as f64
    }

    /// Standard deviation of the total cost at the true parameters.
    pub fn sd(&self) -> f64 {
        let t = &self.total;
        let n = t.len() as f64;
        let m = t.iter().sum::<f64>() / n;
        (t.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    }

    /// Quantile `q` of the total cost at the true parameters.
    pub fn quantile(&self, q: f64) -> f64 {
        let n = self.total.len();
        let i = ((q * (n - 1) as f64).round() as usize).min(n - 1);
        self.total[i]
    }

    /// Expected cost and its upper 99% bound after a fit that absorbs `absorbed` residuals'
    /// worth of noise ([`crate::fit::Information::absorbed`]: one per free parameter for
    /// independent residuals).
    pub fn fitted_level(&self, absorbed: f64) -> (f64, f64) {
        let shift = absorbed * self.per_residual();
        (self.mean() - shift, self.quantile(0.99) - shift)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moments of the complex Wishart against closed forms: `E[W] = n I` and
    /// `E[W^-1] = I / (n - p)`.
    #[test]
    fn wishart_draws_have_the_closed_form_moments() {
        let (p, n) = (3, 12);
        let w = ComplexWishart::new(p, n).unwrap();
        let mut rng = StdRng::seed_from_u64(7);
        let normal = |rng: &mut StdRng| {
            let s = std::f64::consts::FRAC_1_SQRT_2;
            C64::new(
                rng.sample::<f64, _>(StandardNormal) * s,
                rng.sample::<f64, _>(StandardNormal) * s,
            )
        };
        let draws = 20_000;
        let (mut mean, mut inv) = (CMatrix::zeros(p, p), CMatrix::zeros(p, p));
        for _ in 0..draws {
            let s = w.sample(&mut rng, &normal);
            inv += s.clone().try_inverse().unwrap();
            mean += s;
        }
        mean /= C64::from(draws as f64);
        inv /= C64::from(draws as f64);
        for i in 0..p {
            for j in 0..p {
                let (m, v) = (mean[(i, j)], inv[(i, j)]);
                let (em, ev) = if i == j {
                    (n as f64, 1.0 / (n - p) as f64)
                } else {
                    (0.0, 0.0)
                };
                assert!((m - C64::from(em)).norm() < 0.1, "E[W]({i},{j}) = {m}");
                assert!((v - C64::from(ev)).norm() < 0.01, "E[W^-1]({i},{j}) = {v}");
            }
        }
    }

    #[test]
    fn too_few_degrees_of_freedom_is_named() {
        let msg = ComplexWishart::new(6, 4).unwrap_err().to_string();
        assert!(
            msg.contains("noise degrees of freedom") && msg.contains("log more periods"),
            "{msg}"
        );
    }

    proptest::proptest! {
        /// Adding the lines' covariance keeps the mean and the order of the draws and adds
        /// exactly that covariance to the total's variance.
        #[test]
        fn cross_line_covariance_widens_the_total_by_itself(
            draws in proptest::collection::vec(0.0f64..100.0, 20..60),
            covariance in 0.0f64..500.0,
        ) {
            let mut total = draws;
            total.sort_by(f64::total_cmp);
            let reference = NoiseReference {
                line_mean: vec![total.iter().sum::<f64>() / total.len() as f64],
                line_sd: vec![1.0],
                total,
                row_mean: Vec::new(),
                row_sd: Vec::new(),
                entry_mean: DMatrix::zeros(0, 0),
                n_residuals: 2,
            };
            proptest::prop_assume!(reference.sd() > 1e-6);
            let (mean, var) = (reference.mean(), reference.sd().powi(2));
            let wide = reference.clone().with_cross_line_covariance(covariance);
            let wide_mean = wide.total.iter().sum::<f64>() / wide.total.len() as f64;
            proptest::prop_assert!((wide_mean - mean).abs() < 1e-9 * mean.max(1.0));
            proptest::prop_assert!((wide.sd().powi(2) - var - covariance).abs() < 1e-8 * (var + covariance));
            proptest::prop_assert!(wide.total.windows(2).all(|w| w[0] <= w[1]));
        }
    }
}
