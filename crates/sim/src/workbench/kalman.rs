//! The stationary Kalman predictor of a sampled model, with its noise covariances estimated
//! from the data: the time-domain comparison that stays meaningful for an unstable plant in
//! closed loop, where a free run diverges.
//!
//! Noise model: process noise entering where the inputs do, `a (Γ0 Γ0ᵀ + Γ1 Γ1ᵀ)`, plus noise
//! entering each state directly, `b diag(d)` with `d` the state's mean squared motion per
//! sample (a disturbance that does not come through the inputs, such as a torque on a pole
//! driven by a force), and white sensor noise `R = diag(c_i r_i)`, `r` from the first
//! differences of the outputs (white noise of variance σ² gives 2σ² there). The factors are
//! chosen by coordinate descent over logarithmic grids to minimise the log-determinant of the
//! sample innovation covariance (the prediction-error criterion of the innovations form),
//! evaluated on the first [`SEARCH_SAMPLES`] samples. The
//! predictor `x̂_{k+1} = Φ x̂_k + Γ0 u_{k-w} + Γ1 u_{k-w-1} + K (y_k - C x̂_k - D u_{k-d})` is
//! stable whenever `(Φ, C)` is detectable; otherwise the design is refused by name.
use nalgebra::DMatrix;
use serde::Serialize;

use super::timedomain::Discrete;
use crate::error::{Result, SimError};

/// Process-to-sensor noise ratios tried, relative to the output-referred scale.
const RATIOS: [f64; 13] = [
    1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6,
];

/// The designed predictor and what was estimated for it.
#[derive(Debug, Clone)]
pub struct Predictor {
    disc: Discrete,
    /// Predictor gain, states x outputs.
    gain: DMatrix<f64>,
    /// Summary for the report.
    pub noise: NoiseEstimate,
}

/// The estimated noise covariances.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseEstimate {
    /// Sensor noise variance per output (first differences).
    pub sensor_variance: Vec<f64>,
    /// Input-referred process noise, relative to the output-referred scale.
    pub process_ratio: f64,
    /// Process noise entering the states directly, relative likewise.
    pub state_ratio: f64,
    /// Spectral radius of `Φ - K C`, below 1 for a stable predictor.
    pub predictor_spectral_radius: f64,
}

/// Samples of the records the noise search evaluates each candidate on (the final predictor
/// runs on all of them).
const SEARCH_SAMPLES: usize = 8_000;

/// Samples at the start of each record left out of the search's criterion: the predictor
/// starts from the zero state, and its start-up would dominate a short record.
const BURN_IN: usize = 50;

/// Coordinate-descent sweeps of the noise search after the first, absolute grids.
const SWEEPS: usize = 2;

/// Multipliers of a factor tried in each refining sweep.
const REFINE: [f64; 4] = [0.1, 0.3, 3.0, 10.0];

/// The noise-covariance factors being searched: `Q = a Q_u + b Q_x`, `R = diag(c_i r_i)`.
#[derive(Debug, Clone)]
struct Factors {
    input: f64,
    state: f64,
    sensor: Vec<f64>,
}

impl Predictor {
    /// Designs the predictor of `disc` for the records `(u, y)` (samples x channels).
    pub fn design(disc: &Discrete, records: &[(&DMatrix<f64>, &DMatrix<f64>)]) -> Result<Self> {
        let (n, p) = (disc.phi.nrows(), disc.c.nrows());
        let mut r = vec![0.0; p];
        let mut count = 0usize;
        for (_, y) in records {
            for k in 1..y.nrows() {
                for i in 0..p {
                    let d = y[(k, i)] - y[(k - 1, i)];
                    r[i] += d * d;
                }
                count += 1;
            }
        }
        for v in &mut r {
            *v = (*v / (2.0 * count.max(1) as f64)).max(1e-300);
        }
        // The search runs on the first samples of each record, SEARCH_SAMPLES in all.
        let total: usize = records.iter().map(|(_, y)| y.nrows()).sum();
        let share = (SEARCH_SAMPLES as f64 / total.max(1) as f64).min(1.0);
        let search: Vec<(DMatrix<f64>, DMatrix<f64>)> = records
            .iter()
            .map(|(u, y)| {
                let rows =
                    ((y.nrows() as f64 * share) as usize).clamp(y.nrows().min(64), y.nrows());
                (u.rows(0, rows).into_owned(), y.rows(0, rows).into_owned())
            })
            .collect();
        let mut gu =
            &disc.gamma0 * disc.gamma0.transpose() + &disc.gamma1 * disc.gamma1.transpose();
        let trace = gu.trace().max(1e-300);
        for i in 0..n {
            gu[(i, i)] += 1e-9 * trace / n as f64;
        }
        let output_scale = |g: &DMatrix<f64>| {
            (r.iter().sum::<f64>() / p as f64)
                / ((&disc.c * g * disc.c.transpose()).trace() / p as f64).max(1e-300)
        };
        let qu = &gu * output_scale(&gu);
        // Noise entering each state directly (a disturbance that does not come through the
        // inputs), in proportion to how much the state moves per sample.
        let mut qx = DMatrix::zeros(n, n);
        let mut f = Factors {
            input: 1.0,
            state: 0.0,
            sensor: vec![1.0; p],
        };
        let mut best = (f64::INFINITY, None);
        for ratio in RATIOS {
            f.input = ratio;
            if let Ok((ld, k)) = Self::score(disc, &qu, &qx, &r, &f, &search) {
                if ld < best.0 {
                    best = (ld, Some((f.clone(), k)));
                }
            }
        }
        let Some((mut f, k0)) = best.1.clone() else {
            let q = &qu * 1.0;
            let rm = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(r.clone()));
            return Err(gain(disc, &q, &rm).err().unwrap_or_else(|| {
                SimError::invalid(
                    "Kalman predictor",
                    "no noise ratio",
                    "gave a finite innovation covariance",
                )
            }));
        };
        let first = Self {
            disc: disc.clone(),
            gain: k0,
            noise: Self::estimate(&r, &f, 0.0),
        };
        let mut motion = vec![0.0; n];
        let mut steps = 0usize;
        for (u, y) in &search {
            let (_, xs) = first.run(u, y);
            for k in 1..xs.nrows() {
                for i in 0..n {
                    motion[i] += (xs[(k, i)] - xs[(k - 1, i)]).powi(2);
                }
                steps += 1;
            }
        }
        for i in 0..n {
            qx[(i, i)] = (motion[i] / steps.max(1) as f64).max(1e-12 * trace);
        }
        let qx = &qx * output_scale(&qx);
        // The state noise starts from its absolute grid; then every factor is refined around
        // its current value.
        for sweep in 0..=SWEEPS {
            let coordinates: Vec<usize> = if sweep == 0 {
                vec![1]
            } else {
                (0..2 + p).collect()
            };
            for coordinate in coordinates {
                let keep = f.clone();
                let current = match coordinate {
                    0 => keep.input,
                    1 => keep.state,
                    i => keep.sensor[i - 2],
                };
                let grid: Vec<f64> = if sweep == 0 {
                    RATIOS.to_vec()
                } else if current == 0.0 {
                    Vec::new()
                } else {
                    REFINE.iter().map(|m| m * current).collect()
                };
                for v in grid {
                    let mut t = keep.clone();
                    match coordinate {
                        0 => t.input = v,
                        1 => t.state = v,
                        i => t.sensor[i - 2] = v,
                    }
                    if let Ok((ld, k)) = Self::score(disc, &qu, &qx, &r, &t, &search) {
                        if ld < best.0 {
                            best = (ld, Some((t.clone(), k)));
                            f = t;
                        }
                    }
                }
            }
        }
        let (f, gain) = best.1.unwrap_or((f, first.gain));
        let closed = &disc.phi - &gain * &disc.c;
        let rho = closed
            .complex_eigenvalues()
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max);
        Ok(Self {
            disc: disc.clone(),
            gain,
            noise: Self::estimate(&r, &f, rho),
        })
    }

    fn estimate(r: &[f64], f: &Factors, rho: f64) -> NoiseEstimate {
        NoiseEstimate {
            sensor_variance: r.iter().zip(&f.sensor).map(|(v, c)| v * c).collect(),
            process_ratio: f.input,
            state_ratio: f.state,
            predictor_spectral_radius: rho,
        }
    }

    /// Log-determinant of the sample innovation covariance of the design `f`, and its gain.
    fn score(
        disc: &Discrete,
        qu: &DMatrix<f64>,
        qx: &DMatrix<f64>,
        r: &[f64],
        f: &Factors,
        records: &[(DMatrix<f64>, DMatrix<f64>)],
    ) -> Result<(f64, DMatrix<f64>)> {
        let p = r.len();
        let q = qu * f.input + qx * f.state;
        let rm = DMatrix::from_fn(p, p, |i, j| if i == j { r[i] * f.sensor[i] } else { 0.0 });
        let k = gain(disc, &q, &rm)?;
        let candidate = Self {
            disc: disc.clone(),
            gain: k,
            noise: Self::estimate(r, f, 0.0),
        };
        let mut s = DMatrix::zeros(p, p);
        let mut samples = 0usize;
        for (u, y) in records {
            let (e, _) = candidate.run(u, y);
            let from = BURN_IN.min(e.nrows() / 2);
            let e = e.rows(from, e.nrows() - from);
            s += e.transpose() * e;
            samples += e.nrows();
        }
        let s = s / samples.max(1) as f64;
        let logdet = s
            .cholesky()
            .map(|c| 2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>())
            .unwrap_or(f64::INFINITY);
        if !logdet.is_finite() {
            return Err(SimError::invalid(
                "Kalman predictor",
                "innovation covariance",
                "is singular",
            ));
        }
        Ok((logdet, candidate.gain))
    }

    /// Innovations `y_k - ŷ_{k|k-1}` and the one-step predicted states, per sample.
    pub fn run(&self, u: &DMatrix<f64>, y: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
        let d = &self.disc;
        let (n, p) = (d.phi.nrows(), d.c.nrows());
        let samples = y.nrows();
        let mut e = DMatrix::zeros(samples, p);
        let mut xs = DMatrix::zeros(samples, n);
        let mut x = nalgebra::DVector::zeros(n);
        for k in 0..samples {
            xs.row_mut(k).copy_from(&x.transpose());
            let mut yhat = &d.c * &x;
            if k >= d.d_shift {
                yhat += &d.d * u.row(k - d.d_shift).transpose();
            }
            let innov = y.row(k).transpose() - yhat;
            e.row_mut(k).copy_from(&innov.transpose());
            let mut next = &d.phi * &x + &self.gain * &innov;
            if k >= d.whole {
                next += &d.gamma0 * u.row(k - d.whole).transpose();
            }
            if k > d.whole {
                next += &d.gamma1 * u.row(k - d.whole - 1).transpose();
            }
            x = next;
        }
        (e, xs)
    }

    /// `k`-step-ahead output predictions: sample `t` predicted from the one-step state at
    /// `t - k + 1` (data up to `t - k`) propagated with the logged inputs (rows before `k - 1`
    /// are zero).
    pub fn predict(&self, u: &DMatrix<f64>, xs: &DMatrix<f64>, k: usize) -> DMatrix<f64> {
        let d = &self.disc;
        let (samples, p) = (xs.nrows(), d.c.nrows());
        let mut out = DMatrix::zeros(samples, p);
        for t in (k - 1)..samples {
            let start = t + 1 - k;
            let mut x = xs.row(start).transpose();
            for j in start..t {
                let mut next = &d.phi * &x;
                if j >= d.whole {
                    next += &d.gamma0 * u.row(j - d.whole).transpose();
                }
                if j > d.whole {
                    next += &d.gamma1 * u.row(j - d.whole - 1).transpose();
                }
                x = next;
            }
            let mut yhat = &d.c * &x;
            if t >= d.d_shift {
                yhat += &d.d * u.row(t - d.d_shift).transpose();
            }
            out.row_mut(t).copy_from(&yhat.transpose());
        }
        out
    }
}

/// `K = Φ P Cᵀ (C P Cᵀ + R)^-1`, `P` the stabilizing solution of the filter Riccati equation.
fn gain(disc: &Discrete, q: &DMatrix<f64>, r: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let phi_t = disc.phi.transpose();
    let c_t = disc.c.transpose();
    let p = rigid_body::lti::dare(&phi_t, &c_t, q, r).map_err(|e| {
        SimError::domain(
            "Kalman predictor (is the model detectable from its outputs?)",
            e,
        )
    })?;
    let s = &disc.c * &p * &c_t + r;
    let s_inv = s
        .try_inverse()
        .ok_or_else(|| SimError::invalid("Kalman predictor", "C P C^T + R", "is singular"))?;
    Ok(&disc.phi * p * c_t * s_inv)
}
