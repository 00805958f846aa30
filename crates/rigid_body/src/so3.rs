//! The rotation group SO(3): hat/vee, exponential and logarithm (accurate near 0 and near pi),
//! ZYX Euler angles, and the right/left Jacobians with their inverses. Allocation-free, no_std.
//!
//! ```
//! use nalgebra::Vector3;
//! use rigid_body::so3;
//!
//! let w = Vector3::new(0.1, -0.2, 3.0);
//! let r = so3::exp(&w);
//! assert!((so3::log(&r) - w).norm() < 1e-12);
//! let (roll, pitch, yaw) = so3::euler_zyx(&r);
//! assert!((so3::from_euler_zyx(roll, pitch, yaw).matrix() - r.matrix()).norm() < 1e-12);
//! ```

use crate::{Error, Result};
use nalgebra::{ComplexField, Matrix3, RealField, Rotation3, Vector3};

/// Below this angle the trigonometric coefficients use their Taylor series (error < 1e-17).
const SERIES_ANGLE: f64 = 1e-2;

/// Skew-symmetric matrix `[w]x` with `[w]x v = w x v`.
pub fn hat(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// Inverse of [`hat`]: the vector of the skew-symmetric part of `s`
/// (for skew `s` this is `(s32, s13, s21)`).
pub fn vee(s: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(
        0.5 * (s[(2, 1)] - s[(1, 2)]),
        0.5 * (s[(0, 2)] - s[(2, 0)]),
        0.5 * (s[(1, 0)] - s[(0, 1)]),
    )
}

/// `(sin θ / θ, (1 - cos θ) / θ^2)` without cancellation.
fn rodrigues_coefficients(theta: f64) -> (f64, f64) {
    if theta < SERIES_ANGLE {
        let t2 = theta * theta;
        (
            1.0 - t2 / 6.0 * (1.0 - t2 / 20.0),
            0.5 - t2 / 24.0 * (1.0 - t2 / 30.0),
        )
    } else {
        let half = ComplexField::sin(0.5 * theta) / theta;
        (ComplexField::sin(theta) / theta, 2.0 * half * half)
    }
}

/// Exponential map `exp([w]x)`: the rotation by angle `|w|` about `w / |w|` (Rodrigues).
///
/// Beyond an angle of 1 rad it works with the unit axis, `I + sin θ [n]x + (1 - cos θ) [n]x²`,
/// and a norm scaled by the largest component, so that a rotation vector too large to square
/// (|w| above 1e154) is still the rotation by `|w|` (mod 2 pi) rather than NaN.
pub fn exp(w: &Vector3<f64>) -> Rotation3<f64> {
    let largest = w.amax();
    if largest > 1.0 && largest.is_finite() {
        let n = w / largest;
        let theta = largest * n.norm();
        let k = hat(&(n / n.norm()));
        let (s, c) = (ComplexField::sin(theta), ComplexField::cos(theta));
        return Rotation3::from_matrix_unchecked(Matrix3::identity() + k * s + k * k * (1.0 - c));
    }
    let (a, b) = rodrigues_coefficients(w.norm());
    let k = hat(w);
    Rotation3::from_matrix_unchecked(Matrix3::identity() + k * a + k * k * b)
}

/// Logarithm map: the rotation vector `w` with `|w| <= pi` and `exp(w) = r`.
///
/// The angle comes from `atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2)`, accurate at every angle.
/// For angles above pi/2 the axis is read off the symmetric part `(R + R^T)/2 - cos θ I =
/// (1 - cos θ) n n^T` (its largest column), with the sign taken from `vee(R - R^T)`, so the
/// result stays accurate up to pi. At exactly pi either sign is a valid logarithm.
pub fn log(r: &Rotation3<f64>) -> Vector3<f64> {
    let m = r.matrix();
    let v = vee(m); // sin θ n
    let s = v.norm();
    let c = 0.5 * (m.trace() - 1.0);
    let theta = RealField::atan2(s, c);
    if c > 0.0 {
        // θ < pi/2: θ / sin θ is well conditioned.
        let scale = if theta < SERIES_ANGLE {
            let t2 = theta * theta;
            1.0 + t2 / 6.0 * (1.0 + 7.0 * t2 / 60.0)
        } else {
            theta / s
        };
        return v * scale;
    }
    let sym = (m + m.transpose()) * 0.5 - Matrix3::identity() * c;
    let one_minus_c = 1.0 - c;
    let j = (0..3).fold(0, |best, i| {
        if sym[(i, i)] > sym[(best, best)] {
            i
        } else {
            best
        }
    });
    let mut n = sym.column(j) / one_minus_c;
    n /= n.norm();
    if n.dot(&v) < 0.0 {
        n = -n;
    }
    n * theta
}

/// Composition `a b` re-orthonormalised, so that long products stay on SO(3).
pub fn compose(a: &Rotation3<f64>, b: &Rotation3<f64>) -> Rotation3<f64> {
    let mut r = a * b;
    r.renormalize();
    r
}

/// Checks that `m` is a rotation matrix (`|m^T m - I|_F <= 1e-9` and `det m > 0`).
pub fn rotation(name: &'static str, m: &Matrix3<f64>) -> Result<Rotation3<f64>> {
    if !m.iter().all(|x| x.is_finite()) {
        return Err(Error::NonFinite { name });
    }
    let orthogonality_error = (m.transpose() * m - Matrix3::identity()).norm();
    let determinant = m.determinant();
    if orthogonality_error > 1e-9 || determinant <= 0.0 {
        return Err(Error::NotRotation {
            name,
            orthogonality_error,
            determinant,
        });
    }
    Ok(Rotation3::from_matrix_unchecked(*m))
}

/// Rotation `R = Rz(yaw) Ry(pitch) Rx(roll)` from ZYX Euler angles.
pub fn from_euler_zyx(roll: f64, pitch: f64, yaw: f64) -> Rotation3<f64> {
    Rotation3::from_euler_angles(roll, pitch, yaw)
}

/// ZYX Euler angles `(roll, pitch, yaw)` of `r = Rz(yaw) Ry(pitch) Rx(roll)`, with
/// `pitch` in `[-pi/2, pi/2]` and roll, yaw in `(-pi, pi]`.
///
/// All angles come from `atan2` (accurate near the poles, unlike `asin`). At gimbal lock
/// (`cos pitch < 1e-10`) only `yaw -+ roll` is determined; roll is set to 0 and the whole
/// rotation about the vertical goes into yaw.
pub fn euler_zyx(r: &Rotation3<f64>) -> (f64, f64, f64) {
    let m = r.matrix();
    let cos_pitch = ComplexField::sqrt(m[(0, 0)] * m[(0, 0)] + m[(1, 0)] * m[(1, 0)]);
    let pitch = RealField::atan2(-m[(2, 0)], cos_pitch);
    if cos_pitch < 1e-10 {
        return (0.0, pitch, RealField::atan2(-m[(0, 1)], m[(1, 1)]));
    }
    let roll = RealField::atan2(m[(2, 1)], m[(2, 2)]);
    let yaw = RealField::atan2(m[(1, 0)], m[(0, 0)]);
    (roll, pitch, yaw)
}

/// Coefficients `((1 - cos θ)/θ^2, (θ - sin θ)/θ^3)` of the Jacobians.
fn jacobian_coefficients(theta: f64) -> (f64, f64) {
    let (_, b) = rodrigues_coefficients(theta);
    let c = if theta < SERIES_ANGLE {
        let t2 = theta * theta;
        1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0)
    } else {
        (theta - ComplexField::sin(theta)) / (theta * theta * theta)
    };
    (b, c)
}

/// Coefficient `1/θ^2 - (1 + cos θ) / (2 θ sin θ) = 1/θ^2 - cot(θ/2) / (2θ)` of the inverses.
fn inverse_coefficient(theta: f64) -> f64 {
    if theta < SERIES_ANGLE {
        let t2 = theta * theta;
        1.0 / 12.0 + t2 / 720.0 * (1.0 + t2 / 42.0)
    } else {
        let half = 0.5 * theta;
        1.0 / (theta * theta) - ComplexField::cos(half) / (2.0 * theta * ComplexField::sin(half))
    }
}

/// Right Jacobian: `exp(w + d) ≈ exp(w) exp(J_r(w) d)` for small `d`.
pub fn right_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let (b, c) = jacobian_coefficients(w.norm());
    let k = hat(w);
    Matrix3::identity() - k * b + k * k * c
}

/// Left Jacobian: `exp(w + d) ≈ exp(J_l(w) d) exp(w)`; `J_l(w) = J_r(-w) = R J_r(w)`.
pub fn left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    right_jacobian(&-w)
}

/// Inverse of [`right_jacobian`] in closed form; singular at `|w| = 2 pi`.
pub fn right_jacobian_inverse(w: &Vector3<f64>) -> Matrix3<f64> {
    let k = hat(w);
    Matrix3::identity() + k * 0.5 + k * k * inverse_coefficient(w.norm())
}

/// Inverse of [`left_jacobian`] in closed form; singular at `|w| = 2 pi`.
pub fn left_jacobian_inverse(w: &Vector3<f64>) -> Matrix3<f64> {
    right_jacobian_inverse(&-w)
}
