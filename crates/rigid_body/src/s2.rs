//! The sphere S² of radius `r` (the tilt estimator uses `r = G0`): Euclidean projection onto
//! it and the projector onto its tangent space. Allocation-free, no_std.
//!
//! ```
//! use nalgebra::Vector3;
//! use rigid_body::s2;
//!
//! let g = s2::project(&Vector3::new(0.0, 3.0, -4.0), s2::G0)?;
//! assert!((g.norm() - s2::G0).abs() < 1e-12);
//! let p = s2::tangent_projector(&g)?;
//! assert!((p * g).norm() < 1e-12);
//! # Ok::<(), rigid_body::Error>(())
//! ```

use crate::{Error, Result};
use nalgebra::{Matrix3, Vector3};

/// Gravitational acceleration used throughout the tilt paper, m/s².
pub const G0: f64 = 9.81;

/// Unit direction of `x`; errors on a non-finite or zero vector, where the direction is
/// undefined.
pub fn direction(name: &'static str, x: &Vector3<f64>) -> Result<Vector3<f64>> {
    if !x.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite { name });
    }
    // Scale by the largest component first so that tiny or huge vectors do not under- or
    // overflow when squared.
    let largest = x.amax();
    if largest == 0.0 {
        return Err(Error::ZeroVector { name });
    }
    let scaled = x / largest;
    Ok(scaled / scaled.norm())
}

/// Nearest point `r x / |x|` of the sphere of radius `radius` to `x`.
///
/// At `x = 0` every point of the sphere is nearest; this is reported as
/// [`Error::ZeroVector`] so that the caller decides (e.g. keeps its previous iterate).
pub fn project(x: &Vector3<f64>, radius: f64) -> Result<Vector3<f64>> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(Error::InvalidParameter {
            name: "radius",
            value: radius,
            requirement: "must be positive and finite",
        });
    }
    Ok(direction("x", x)? * radius)
}

/// Orthogonal projector `I - n n^T` onto the tangent plane at the point in direction
/// `n = x / |x|` (any nonzero `x`; the radius does not matter).
pub fn tangent_projector(x: &Vector3<f64>) -> Result<Matrix3<f64>> {
    let n = direction("x", x)?;
    Ok(Matrix3::identity() - n * n.transpose())
}
