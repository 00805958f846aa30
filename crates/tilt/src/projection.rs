//! Euclidean projections onto the two feasible sets of the estimator.
//!
//! Placeholder until `rigid_body::{s2, matrix_set}` land: the sphere of radius g0 and the set
//! M = { [w]x^2 + [h]x } (spec/tilt.md section 4).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Projection onto the sphere of radius `radius`; `None` for a zero or non-finite input.
pub(crate) fn sphere(x: &Vector3<f64>, radius: f64) -> Option<Vector3<f64>> {
    let n = x.norm();
    (n > 0.0 && n.is_finite()).then(|| x * (radius / n))
}

/// Projection onto M (2.23)/(2.24): keep the skew part, replace the symmetric part by the
/// nearest `[w]x^2`, built from the largest eigenpair of `symm(a)`.
pub(crate) fn matrix_set(a: &Matrix3<f64>) -> Matrix3<f64> {
    let s = (a + a.transpose()) * 0.5;
    let k = (a - a.transpose()) * 0.5;
    let eig = SymmetricEigen::new(s);
    let top = eig.eigenvalues.imax();
    let lambda12 = s.trace() - eig.eigenvalues[top];
    if lambda12 < 0.0 {
        let u3 = eig.eigenvectors.column(top).into_owned();
        k + (Matrix3::identity() - u3 * u3.transpose()) * (0.5 * lambda12)
    } else {
        k
    }
}
