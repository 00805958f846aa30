//! Kinematics and the measurement equation `m_i = Omega p_i - g + n_i` (2.5)-(2.8).

use nalgebra::{Matrix3, Vector3};

use crate::math;

/// Standard gravity, the radius of the sphere S^2 on which the body-frame gravity lives.
pub const G0: f64 = 9.81;

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

/// Splits an element of M into `(omega_dot, |omega|, omega)`: `omega_dot = vee(skew Omega)`,
/// `|omega|^2 = -tr(symm Omega)/2`, and `omega` up to its unobservable sign, read off
/// `omega omega^T = symm(Omega) + |omega|^2 I` (largest column); the sign is chosen so that the
/// component of largest magnitude is positive.
pub fn decompose(omega_matrix: &Matrix3<f64>) -> (Vector3<f64>, f64, Vector3<f64>) {
    let skew = (omega_matrix - omega_matrix.transpose()) * 0.5;
    let omega_dot = Vector3::new(skew[(2, 1)], skew[(0, 2)], skew[(1, 0)]);
    let symm = (omega_matrix + omega_matrix.transpose()) * 0.5;
    let norm_sq = (-0.5 * symm.trace()).max(0.0);
    let outer = symm + Matrix3::identity() * norm_sq;
    let k = (0..3)
        .max_by(|&a, &b| outer[(a, a)].total_cmp(&outer[(b, b)]))
        .unwrap_or(0);
    let column = outer.column(k).into_owned();
    let column_norm = column.norm();
    let norm = math::sqrt(norm_sq);
    let mut omega = if column_norm > 0.0 {
        column * (norm / column_norm)
    } else {
        Vector3::zeros()
    };
    let lead = omega.iamax();
    if omega[lead] < 0.0 {
        omega = -omega;
    }
    (omega_dot, norm, omega)
}
