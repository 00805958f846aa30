//! The set `M = { A : A + A^T = [a]x^2 } = { [w]x^2 + [h]x }` of all centripetal plus
//! angular-acceleration matrices `Ω = [ω]x^2 + [ω']x` (tilt paper, (2.13)), with its closed-form
//! Frobenius projection (2.23)-(2.24). Allocation-free, no_std.
//!
//! ```
//! use nalgebra::{Matrix3, Vector3};
//! use rigid_body::{matrix_set, so3::hat};
//!
//! let (w, h) = (Vector3::new(1.0, 2.0, -0.5), Vector3::new(0.3, 0.0, 1.0));
//! let omega = hat(&w) * hat(&w) + hat(&h);
//! let p = matrix_set::project(&(omega + Matrix3::identity() * 1e-3))?;
//! assert!((p.h - h).norm() < 1e-12);
//! assert!((p.w.norm() - w.norm()).abs() < 1e-3);
//! # Ok::<(), rigid_body::Error>(())
//! ```

use crate::so3::{hat, vee};
use crate::{Error, Result};
use nalgebra::{ComplexField, Matrix3, SymmetricEigen, Vector3};

/// `(A + A^T) / 2`.
pub fn symm(a: &Matrix3<f64>) -> Matrix3<f64> {
    (a + a.transpose()) * 0.5
}

/// `(A - A^T) / 2`.
pub fn skew(a: &Matrix3<f64>) -> Matrix3<f64> {
    (a - a.transpose()) * 0.5
}

/// A point of `M` with its factors: `matrix = [w]x^2 + [h]x`.
///
/// `w` is determined up to sign (`[w]x^2 = [-w]x^2`); the returned sign makes the
/// largest-magnitude component of `w` positive. In the tilt estimator `h` is the angular
/// acceleration and `|w|` the angular rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// The projected matrix, an element of `M`.
    pub matrix: Matrix3<f64>,
    /// Factor of the symmetric part, `symm(matrix) = [w]x^2`.
    pub w: Vector3<f64>,
    /// Factor of the skew part, `skew(matrix) = [h]x`.
    pub h: Vector3<f64>,
    /// Squared Frobenius distance from the input to `matrix`.
    pub distance_squared: f64,
}

/// Frobenius-nearest point of `M` to `a` (paper (2.16), (2.23)-(2.24)).
///
/// With `symm(a)` having eigenvalues `λ1 <= λ2 <= λ3` and unit eigenvector `u3` of `λ3`: the
/// skew part is kept, and the symmetric part becomes `[w]x^2` with
/// `w = sqrt(max(0, -(λ1 + λ2) / 2)) u3`. When `λ2 = λ3` and `λ1 + λ2 < 0` the nearest point is
/// not unique; the eigenvector nalgebra returns is used (deterministic).
/// The eigen-decomposition is nalgebra's symmetric QR iteration (allocation-free for 3x3).
pub fn project(a: &Matrix3<f64>) -> Result<Projection> {
    if !a.iter().all(|x| x.is_finite()) {
        return Err(Error::NonFinite { name: "A" });
    }
    const ITERATIONS: usize = 1000;
    let eig =
        SymmetricEigen::try_new(symm(a), f64::EPSILON, ITERATIONS).ok_or(Error::NoConvergence {
            algorithm: "symmetric eigen-decomposition",
            iterations: ITERATIONS,
        })?;
    let mut order = [0usize, 1, 2];
    order.sort_unstable_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let [l1, l2, l3] = order.map(|i| eig.eigenvalues[i]);
    let mut u3: Vector3<f64> = eig.eigenvectors.column(order[2]).into_owned();
    let k = u3.iamax();
    if u3[k] < 0.0 {
        u3 = -u3;
    }
    let h = vee(a);
    let sum = l1 + l2;
    let (w, distance_squared) = if sum < 0.0 {
        let d = l1 - l2;
        (u3 * ComplexField::sqrt(-0.5 * sum), 0.5 * d * d + l3 * l3)
    } else {
        (Vector3::zeros(), l1 * l1 + l2 * l2 + l3 * l3)
    };
    let hw = hat(&w);
    Ok(Projection {
        matrix: hw * hw + hat(&h),
        w,
        h,
        distance_squared,
    })
}
