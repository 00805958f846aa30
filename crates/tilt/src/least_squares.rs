//! The baseline: unconstrained linear least squares over `Omega` and `g` (Trimpe and D'Andrea,
//! spec section 3.4), the method the paper compares against and the estimator's initial guess.

use nalgebra::{Matrix3, Matrix3x4, Vector3};

use rigid_body::s2;

use crate::{Layout, TiltError, G0};

/// Result of the linear least-squares method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeastSquaresEstimate {
    /// Unconstrained `Omega` (not in M in general).
    pub omega_matrix: Matrix3<f64>,
    /// Unconstrained gravity vector (its length is not g0 in general).
    pub g_raw: Vector3<f64>,
    /// The baseline tilt estimate: `g_raw` projected onto the sphere of radius g0, or `None`
    /// when `g_raw` is zero.
    pub g: Option<Vector3<f64>>,
    /// True when the sensors lie on one affine plane: the problem is rank deficient and the
    /// minimum-norm solution is returned (not unique).
    pub rank_deficient: bool,
}

/// Minimum-norm least-squares solution of `m_i = Omega p_i - g` over all 3x3 `Omega` and all
/// `g`: `[Omega | -g] = [mbar | m] Z^+`.
///
/// ```
/// use nalgebra::Vector3;
/// let positions = [
///     Vector3::new(1.0, 0.0, 0.0),
///     Vector3::new(0.0, 1.0, 0.0),
///     Vector3::new(0.0, 0.0, 1.0),
///     Vector3::new(-1.0, -1.0, -1.0),
/// ];
/// let layout = tilt::Layout::new(&positions)?;
/// let g = Vector3::new(0.0, 0.0, -tilt::G0);
/// let mut m = [Vector3::zeros(); 4];
/// tilt::ideal_measurements(&positions, &Vector3::new(1.0, 2.0, 3.0), &Vector3::new(0.5, 0.0, 0.0), &g, &mut m);
/// let ls = tilt::least_squares(&layout, &m)?;
/// assert!((ls.g_raw - g).norm() < 1e-9);
/// # Ok::<(), tilt::TiltError>(())
/// ```
pub fn least_squares(
    layout: &Layout,
    measurements: &[Vector3<f64>],
) -> Result<LeastSquaresEstimate, TiltError> {
    let (m_sum, m_bar) = layout.sample_sums(measurements)?;
    Ok(from_sums(layout, &m_sum, &m_bar))
}

/// The same from the sample sums `m = sum m_i`, `mbar = sum m_i p_i^T`.
pub(crate) fn from_sums(
    layout: &Layout,
    m_sum: &Vector3<f64>,
    m_bar: &Matrix3<f64>,
) -> LeastSquaresEstimate {
    let mut rhs = Matrix3x4::zeros();
    rhs.fixed_view_mut::<3, 3>(0, 0).copy_from(m_bar);
    rhs.set_column(3, m_sum);
    let x = rhs * layout.z_pinv();
    let omega_matrix = x.fixed_view::<3, 3>(0, 0).into_owned();
    let g_raw = -x.column(3).into_owned();
    LeastSquaresEstimate {
        omega_matrix,
        g_raw,
        g: s2::project(&g_raw, G0).ok(),
        rank_deficient: layout.affine_plane().is_some(),
    }
}
