//! Kinematics and the measurement equation `m_i = Omega p_i - g + n_i` (2.5)-(2.8).

use nalgebra::{Matrix3, Vector3};

/// `Omega = [omega]x^2 + [omega_dot]x`: body-frame acceleration of a point at `p` is `Omega p`.
pub fn omega_matrix(omega: &Vector3<f64>, omega_dot: &Vector3<f64>) -> Matrix3<f64> {
    let w = omega.cross_matrix();
    w * w + omega_dot.cross_matrix()
}

/// Noise-free readings of accelerometers at `positions` (written into `out`, same length):
/// `m_i = Omega p_i - g`.
///
/// ```
/// use nalgebra::Vector3;
/// let p = [Vector3::new(1.0, 0.0, 0.0)];
/// let mut m = [Vector3::zeros()];
/// tilt::ideal_measurements(&p, &Vector3::zeros(), &Vector3::zeros(), &Vector3::new(0.0, 0.0, -tilt::G0), &mut m);
/// assert_eq!(m[0], Vector3::new(0.0, 0.0, tilt::G0)); // at rest a z-up sensor reads +g0
/// ```
pub fn ideal_measurements(
    positions: &[Vector3<f64>],
    omega: &Vector3<f64>,
    omega_dot: &Vector3<f64>,
    g: &Vector3<f64>,
    out: &mut [Vector3<f64>],
) {
    let omega_mat = omega_matrix(omega, omega_dot);
    for (m, p) in out.iter_mut().zip(positions) {
        *m = omega_mat * p - g;
    }
}
