//! Seeded simulation of the paper's test motion (spec section 8.1): a body starting at rest
//! with piecewise-constant Gaussian angular acceleration, sampled every `sample_time`.

use std::vec::Vec;

use nalgebra::{UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

use crate::{omega_matrix, G0};

/// The true state at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueState {
    /// Angular velocity, body frame (rad/s).
    pub omega: Vector3<f64>,
    /// Angular acceleration, body frame (rad/s^2).
    pub omega_dot: Vector3<f64>,
    /// Gravity in the body frame (m/s^2, length g0).
    pub g: Vector3<f64>,
}

/// Trajectory settings; the defaults are those of the paper (2 s reproduces its tables).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryConfig {
    /// Length in seconds.
    pub duration: f64,
    /// Sampling time (and hold time of the angular acceleration), seconds.
    pub sample_time: f64,
    /// Standard deviation of each angular-acceleration component (rad/s^2).
    pub omega_dot_std: f64,
    /// Integration sub-steps per sample (midpoint rule on the exact, linear omega).
    pub substeps: usize,
}

impl Default for TrajectoryConfig {
    fn default() -> Self {
        Self {
            duration: 2.0,
            sample_time: 0.02,
            omega_dot_std: 10.0,
            substeps: 20,
        }
    }
}

/// Simulates one trajectory from `R = I`, `omega = 0`: `omega_dot = q_k ~ N(0, std^2 I)` on
/// `[k Ts, (k+1) Ts)`, `R' = R [omega]x`, gravity `(0, 0, -g0)` in the inertial frame. Returns
/// the state at every sample time `k Ts < duration`.
pub fn simulate_trajectory<R: Rng>(rng: &mut R, config: &TrajectoryConfig) -> Vec<TrueState> {
    let samples = (config.duration / config.sample_time).round() as usize;
    let h = config.sample_time / config.substeps.max(1) as f64;
    let gravity = Vector3::new(0.0, 0.0, -G0);
    let mut attitude = UnitQuaternion::identity();
    let mut omega = Vector3::zeros();
    let mut states = Vec::with_capacity(samples);
    for _ in 0..samples {
        let omega_dot = gaussian_vector(rng) * config.omega_dot_std;
        states.push(TrueState {
            omega,
            omega_dot,
            g: attitude.inverse_transform_vector(&gravity),
        });
        for _ in 0..config.substeps.max(1) {
            let midpoint = omega + omega_dot * (0.5 * h);
            attitude *= UnitQuaternion::from_scaled_axis(midpoint * h);
            attitude.renormalize_fast();
            omega += omega_dot * h;
        }
    }
    states
}

/// Noisy, biased readings `m_i = Omega p_i - g + b_i + n_i`, `n_i ~ N(0, noise_std^2 I)`,
/// written into `out` (same length as `positions`; `biases` empty or the same length).
pub fn measure<R: Rng>(
    rng: &mut R,
    positions: &[Vector3<f64>],
    state: &TrueState,
    noise_std: f64,
    biases: &[Vector3<f64>],
    out: &mut [Vector3<f64>],
) {
    let omega_mat = omega_matrix(&state.omega, &state.omega_dot);
    for (i, (m, p)) in out.iter_mut().zip(positions).enumerate() {
        let bias = biases.get(i).copied().unwrap_or_else(Vector3::zeros);
        *m = omega_mat * p - state.g + bias + gaussian_vector(rng) * noise_std;
    }
}

/// A vector of three independent standard normal samples.
pub fn gaussian_vector<R: Rng>(rng: &mut R) -> Vector3<f64> {
    Vector3::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
}
