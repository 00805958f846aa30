//! Stability of the sampled closed loop linearised at hover: the cascaded controller (a static
//! gain on position, velocity, attitude and rates, limits inactive) against a truth
//! [`Model`] (its actuator lag and in-loop delay included), held over each sample.
//!
//! Used to check a [`Tuning`](crate::control::Tuning) before flying it: the loop is stable
//! when every eigenvalue lies inside the unit circle.

use crate::control::{CascadedController, Measurement, Setpoint};
use crate::error::{require_positive, Error, Result};
use crate::geometry::N_INPUTS;
use crate::model::Model;
use nalgebra::{Complex, DMatrix, Vector3};

/// Measured quantities the controller reads, in this order: position, velocity, attitude, rates.
const N_MEASURED: usize = 12;

/// Linear map `u - trim = F m` of the controller from the 12 measured quantities `m`
/// (position, velocity, attitude, rates; yaw error not wrapped, limits inactive).
pub fn feedback_gain(controller: &CascadedController) -> DMatrix<f64> {
    let sp = Setpoint::default();
    let mut f = DMatrix::<f64>::zeros(N_INPUTS, N_MEASURED);
    for j in 0..N_MEASURED {
        let mut v = [Vector3::zeros(); 4];
        v[j / 3][j % 3] = 1.0;
        let y = Measurement {
            position: v[0],
            velocity: v[1],
            attitude: v[2],
            rates: v[3],
        };
        let (rates_des, fz) = controller.outer(&y, &sp);
        let u = controller.inner(&y.rates, &rates_des, fz) - controller.trim;
        f.column_mut(j).copy_from(&u);
    }
    f
}

/// Eigenvalues of the sampled closed loop: zero-order hold at `sample_rate_hz`, the truth's
/// `input_delay` in the loop (exact fractional-delay discretisation), its actuator lag as
/// extra states, position integrated from the velocity.
pub fn closed_loop_eigenvalues(
    controller: &CascadedController,
    truth: &Model,
    sample_rate_hz: f64,
) -> Result<Vec<Complex<f64>>> {
    require_positive("sample_rate_hz", sample_rate_hz)?;
    let ss = truth.state_space()?;
    let n = ss.a.nrows();
    // Plant states, then the position in J (p' = v).
    let mut a = DMatrix::<f64>::zeros(n + 3, n + 3);
    a.view_mut((0, 0), (n, n)).copy_from(&ss.a);
    let mut b = DMatrix::<f64>::zeros(n + 3, N_INPUTS);
    b.view_mut((0, 0), (n, N_INPUTS)).copy_from(&ss.b);
    for i in 0..3 {
        a[(n + i, i)] = 1.0;
    }
    let d = rigid_body::lti::c2d_zoh_delay(&a, &b, 1.0 / sample_rate_hz, ss.delay)
        .map_err(|e| Error::Numerical(format!("discretising the loop: {e}")))?;
    // Measured quantities from the augmented state: position, velocity, attitude, rates.
    let mut c = DMatrix::<f64>::zeros(N_MEASURED, d.a.nrows());
    for i in 0..3 {
        c[(i, n + i)] = 1.0;
    }
    for i in 0..9 {
        c[(3 + i, i)] = 1.0;
    }
    let closed = &d.a + &d.b * feedback_gain(controller) * c;
    // faer's Hessenberg-QR eigen-solver (nalgebra's real Schur may not converge here).
    let m = faer::Mat::<f64>::from_fn(closed.nrows(), closed.ncols(), |i, j| closed[(i, j)]);
    let eig = m
        .eigenvalues()
        .map_err(|e| Error::Numerical(format!("closed-loop eigenvalues: {e:?}")))?;
    Ok(eig.iter().map(|l| Complex::new(l.re, l.im)).collect())
}

/// Largest eigenvalue modulus of [`closed_loop_eigenvalues`]; below 1 means stable.
pub fn spectral_radius(
    controller: &CascadedController,
    truth: &Model,
    sample_rate_hz: f64,
) -> Result<f64> {
    Ok(closed_loop_eigenvalues(controller, truth, sample_rate_hz)?
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max))
}
