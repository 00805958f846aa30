//! The paper's simulation study and Cramer-Rao comparisons as seeded, reusable experiments
//! (spec sections 6.2 and 8): used by the reproduction tests and `examples/reproduce.rs`.

use std::vec::Vec;

use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::simulation::{measure, simulate_trajectory, TrajectoryConfig, TrueState};
use crate::{fisher_information, least_squares, Estimator, TiltError, MAX_SENSORS};

/// Mean and (population) variance of a sample of errors.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Moments {
    /// Mean.
    pub mean: f64,
    /// Variance.
    pub var: f64,
}

impl Moments {
    /// Moments of `values` (zero for an empty slice).
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
        Self { mean, var }
    }

    /// Standard deviation.
    pub fn std(&self) -> f64 {
        self.var.sqrt()
    }
}

/// Settings of the randomised-trajectory study (Tables 1-3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudyConfig {
    /// Number of random trajectories (paper: 50).
    pub trajectories: usize,
    /// Motion of each trajectory.
    pub trajectory: TrajectoryConfig,
    /// Accelerometer noise standard deviation (m/s^2).
    pub noise_std: f64,
    /// Half-width of the uniform bias drawn once per trajectory, sensor and axis (0: none).
    pub bias_half_width: f64,
    /// Seed of the random generator.
    pub seed: u64,
}

impl StudyConfig {
    /// The paper's study at noise level `noise_std`: 50 trajectories of 2 s, no bias.
    pub fn paper(noise_std: f64, seed: u64) -> Self {
        Self {
            trajectories: 50,
            trajectory: TrajectoryConfig::default(),
            noise_std,
            bias_half_width: 0.0,
            seed,
        }
    }
}

/// Per-sample error statistics over all samples of all trajectories.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyResult {
    /// Number of samples.
    pub samples: usize,
    /// `|g_hat - g|` of the maximum-likelihood estimator.
    pub tilt_ml: Moments,
    /// Median of `|g_hat - g|` of the maximum-likelihood estimator.
    pub tilt_ml_median: f64,
    /// `|g_hat - g|` of least squares normalised to the sphere (the paper's baseline).
    pub tilt_ls: Moments,
    /// `|g_hat - g|` of raw (unnormalised) least squares; `NaN` when rank deficient.
    pub tilt_ls_raw: Moments,
    /// Mean `|abs(omega_hat) - abs(omega)|` (componentwise absolute values: the sign is
    /// unobservable).
    pub omega_abs_error: f64,
    /// Mean `|omega_dot_hat - omega_dot|`.
    pub omega_dot_error: f64,
    /// Iterations per sample (mean and variance).
    pub iterations: Moments,
    /// Samples where the iteration budget ran out.
    pub not_converged: usize,
    /// Samples with a non-finite estimate.
    pub non_finite: usize,
    /// Mean squared tilt error of the ML estimator over the samples where the Cramer-Rao bound
    /// exists, and the mean trace of that bound over the same samples.
    pub tilt_mse_vs_crb: (f64, f64),
    /// Same for omega_dot.
    pub omega_dot_mse_vs_crb: (f64, f64),
}

impl StudyResult {
    /// Relative reduction of the mean tilt error against normalised least squares.
    pub fn mean_reduction(&self) -> f64 {
        1.0 - self.tilt_ml.mean / self.tilt_ls.mean
    }

    /// Relative reduction of the tilt-error variance against normalised least squares.
    pub fn var_reduction(&self) -> f64 {
        1.0 - self.tilt_ml.var / self.tilt_ls.var
    }
}

/// Runs the randomised-trajectory study with `estimator` (spec section 8.1).
pub fn run_study(estimator: &Estimator, config: &StudyConfig) -> Result<StudyResult, TiltError> {
    let layout = estimator.layout();
    let positions = layout.positions();
    let mut rng = StdRng::seed_from_u64(config.seed);
    let mut buffer = [Vector3::zeros(); MAX_SENSORS];
    let mut biases = [Vector3::zeros(); MAX_SENSORS];
    let m = &mut buffer[..positions.len()];
    let (mut tilt_ml, mut tilt_ls, mut tilt_raw, mut iterations) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut omega_err, mut omega_dot_err) = (0.0, 0.0);
    let (mut not_converged, mut non_finite) = (0, 0);
    let (mut tilt_se, mut tilt_crb, mut dot_se, mut dot_crb, mut with_crb) =
        (0.0, 0.0, 0.0, 0.0, 0usize);
    for _ in 0..config.trajectories {
        let states = simulate_trajectory(&mut rng, &config.trajectory);
        let w = config.bias_half_width;
        for b in biases.iter_mut().take(positions.len()) {
            *b = if w > 0.0 {
                Vector3::from_fn(|_, _| rng.random_range(-w..=w))
            } else {
                Vector3::zeros()
            };
        }
        for state in &states {
            measure(&mut rng, positions, state, config.noise_std, &biases, m);
            let estimate = estimator.estimate(m)?;
            let ls = least_squares(layout, m)?;
            let finite = estimate.g.iter().all(|v| v.is_finite())
                && estimate.omega_matrix.iter().all(|v| v.is_finite());
            if !finite {
                non_finite += 1;
                continue;
            }
            if !estimate.flags.converged {
                not_converged += 1;
            }
            let g_err = (estimate.g - state.g).norm();
            tilt_ml.push(g_err);
            tilt_ls.push(ls.g.map_or(f64::NAN, |g| (g - state.g).norm()));
            tilt_raw.push(if ls.rank_deficient {
                f64::NAN
            } else {
                (ls.g_raw - state.g).norm()
            });
            iterations.push(estimate.iterations as f64);
            omega_err += (estimate.omega.abs() - state.omega.abs()).norm();
            let dot = (estimate.omega_dot - state.omega_dot).norm();
            omega_dot_err += dot;
            if let Ok(crb) = fisher_information(
                layout,
                &state.omega,
                &state.omega_dot,
                &state.g,
                config.noise_std,
            )
            .and_then(|f| f.crb())
            {
                with_crb += 1;
                tilt_se += g_err * g_err;
                tilt_crb += crb.tilt.trace();
                dot_se += dot * dot;
                dot_crb += crb.omega_dot.trace();
            }
        }
    }
    let samples = tilt_ml.len();
    let per_crb = 1.0 / with_crb.max(1) as f64;
    let mut sorted = tilt_ml.clone();
    sorted.sort_unstable_by(f64::total_cmp);
    Ok(StudyResult {
        samples,
        tilt_ml: Moments::of(&tilt_ml),
        tilt_ml_median: sorted.get(samples / 2).copied().unwrap_or(f64::NAN),
        tilt_ls: Moments::of(&tilt_ls),
        tilt_ls_raw: Moments::of(&tilt_raw),
        omega_abs_error: omega_err / samples.max(1) as f64,
        omega_dot_error: omega_dot_err / samples.max(1) as f64,
        iterations: Moments::of(&iterations),
        not_converged,
        non_finite,
        tilt_mse_vs_crb: (tilt_se * per_crb, tilt_crb * per_crb),
        omega_dot_mse_vs_crb: (dot_se * per_crb, dot_crb * per_crb),
    })
}

/// Monte-Carlo errors of the ML estimator at one fixed state, next to the Cramer-Rao bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedStateResult {
    /// Mean `|g_hat - g|`.
    pub tilt_error: f64,
    /// Mean `|abs(omega_hat) - abs(omega)|`.
    pub omega_abs_error: f64,
    /// Mean `|omega_dot_hat - omega_dot|`.
    pub omega_dot_error: f64,
    /// Mean squared tilt error (3-D error vector).
    pub tilt_mse: f64,
    /// Mean squared omega error after aligning the sign of `omega_hat` with `omega`.
    pub omega_mse: f64,
    /// Mean squared omega_dot error.
    pub omega_dot_mse: f64,
    /// Traces of the Cramer-Rao bound `(tilt, omega, omega_dot)`, if it exists.
    pub crb_traces: Option<(f64, f64, f64)>,
    /// Mean number of iterations.
    pub mean_iterations: f64,
    /// Draws where the iteration budget ran out.
    pub not_converged: usize,
}

/// Estimates `draws` noisy samples of one state (spec acceptance test F4 and the omega sweep
/// of Fig. 2.8).
pub fn fixed_state_study(
    estimator: &Estimator,
    state: &TrueState,
    noise_std: f64,
    draws: usize,
    seed: u64,
) -> Result<FixedStateResult, TiltError> {
    let layout = estimator.layout();
    let positions = layout.positions();
    let mut rng = StdRng::seed_from_u64(seed);
    let mut buffer = [Vector3::zeros(); MAX_SENSORS];
    let m = &mut buffer[..positions.len()];
    let mut sums = [0.0; 7];
    let mut not_converged = 0;
    for _ in 0..draws {
        measure(&mut rng, positions, state, noise_std, &[], m);
        let e = estimator.estimate(m)?;
        let aligned = if e.omega.dot(&state.omega) < 0.0 {
            -e.omega
        } else {
            e.omega
        };
        let g_err = (e.g - state.g).norm();
        let dot_err = (e.omega_dot - state.omega_dot).norm();
        sums[0] += g_err;
        sums[1] += (e.omega.abs() - state.omega.abs()).norm();
        sums[2] += dot_err;
        sums[3] += g_err * g_err;
        sums[4] += (aligned - state.omega).norm_squared();
        sums[5] += dot_err * dot_err;
        sums[6] += e.iterations as f64;
        if !e.flags.converged {
            not_converged += 1;
        }
    }
    let n = draws.max(1) as f64;
    let crb = fisher_information(layout, &state.omega, &state.omega_dot, &state.g, noise_std)
        .and_then(|f| f.crb())
        .ok()
        .map(|c| (c.tilt.trace(), c.omega.trace(), c.omega_dot.trace()));
    Ok(FixedStateResult {
        tilt_error: sums[0] / n,
        omega_abs_error: sums[1] / n,
        omega_dot_error: sums[2] / n,
        tilt_mse: sums[3] / n,
        omega_mse: sums[4] / n,
        omega_dot_mse: sums[5] / n,
        crb_traces: crb,
        mean_iterations: sums[6] / n,
        not_converged,
    })
}
