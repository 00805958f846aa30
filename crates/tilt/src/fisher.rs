//! Fisher information and Cramer-Rao bound for `x = (omega, omega_dot, n)` with the sphere
//! parametrised as `g = exp([Pi n]x) g_bar` (spec section 6), using the exact Jacobian (the
//! paper's (2.54) drops the term `-[p_i]x [omega]x`, which changes the omega_dot block).

use nalgebra::{Matrix3, Matrix3x2, SMatrix, SVector, Vector3, QR};

use crate::{Layout, TiltError};

/// 3x8 Jacobian of one residual.
pub type Jacobian = SMatrix<f64, 3, 8>;
/// 8x8 information or covariance matrix, ordered `(omega, omega_dot, n)`.
pub type Matrix8 = SMatrix<f64, 8, 8>;

/// Relative singular-value threshold of the stacked Jacobian below which a direction counts
/// as unobservable.
pub const RANK_TOL: f64 = 1e-9;

/// Orthonormal basis `Pi` (3x2) of the plane orthogonal to `g_bar`, right-handed with
/// `g_bar / |g_bar|` pointing down: for `g_bar = (0, 0, -g0)` it is `[e1, e2]`.
pub fn tangent_basis(g_bar: &Vector3<f64>) -> Result<Matrix3x2<f64>, TiltError> {
    let norm = g_bar.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return Err(TiltError::InvalidState(
            "gravity must be finite and non-zero",
        ));
    }
    let down = g_bar / norm;
    let k = down.iamin();
    let mut seed = Vector3::zeros();
    seed[k] = 1.0;
    let first = (seed - down * down.dot(&seed)).normalize();
    let second = first.cross(&down);
    Ok(Matrix3x2::from_columns(&[first, second]))
}

/// Exact Jacobian of the residual `m_i - Omega p_i + g` at `(omega, omega_dot, n = 0)`:
/// `(2[omega]x[p]x - [p]x[omega]x, [p]x, -[g_bar]x Pi)`.
pub fn jacobian(
    position: &Vector3<f64>,
    omega: &Vector3<f64>,
    g_bar: &Vector3<f64>,
    basis: &Matrix3x2<f64>,
) -> Jacobian {
    let w = omega.cross_matrix();
    let p = position.cross_matrix();
    let mut j = Jacobian::zeros();
    j.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(w * p * 2.0 - p * w));
    j.fixed_view_mut::<3, 3>(0, 3).copy_from(&p);
    j.fixed_view_mut::<3, 2>(0, 6)
        .copy_from(&(-g_bar.cross_matrix() * basis));
    j
}

/// The Fisher information at one state, held as an upper-triangular square root `R` of
/// `sum J_i^T J_i` (accumulated by QR updates, so singular values are accurate far below
/// the square root of machine precision).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fisher {
    factor: Matrix8,
    sigma: f64,
    g_bar: Vector3<f64>,
    basis: Matrix3x2<f64>,
}

/// Fisher information of one sample for noise standard deviation `sigma` (m/s^2) at
/// `(omega, omega_dot, g_bar)`.
///
/// ```
/// use nalgebra::Vector3;
/// let layout = tilt::Layout::new(&[
///     Vector3::new(0.05, 0.0, 0.0),
///     Vector3::new(0.0, 0.05, 0.0),
///     Vector3::new(0.0, 0.0, 0.05),
/// ])?;
/// let g = Vector3::new(0.0, 0.0, -tilt::G0);
/// let generic = tilt::fisher_information(&layout, &Vector3::new(1.0, -0.5, 0.8), &Vector3::zeros(), &g, 1.0)?;
/// assert_eq!(generic.rank(), 8); // three sensors suffice...
/// let normal = tilt::fisher_information(&layout, &Vector3::new(1.0, 1.0, 1.0), &Vector3::zeros(), &g, 1.0)?;
/// assert_eq!(normal.rank(), 7); // ...except for omega along the normal of their plane
/// # Ok::<(), tilt::TiltError>(())
/// ```
pub fn fisher_information(
    layout: &Layout,
    omega: &Vector3<f64>,
    omega_dot: &Vector3<f64>,
    g_bar: &Vector3<f64>,
    sigma: f64,
) -> Result<Fisher, TiltError> {
    if !omega.iter().chain(omega_dot.iter()).all(|v| v.is_finite()) {
        return Err(TiltError::InvalidState(
            "omega and omega_dot must be finite",
        ));
    }
    if !(sigma > 0.0 && sigma.is_finite()) {
        return Err(TiltError::InvalidOption {
            name: "sigma",
            value: sigma,
            requirement: "noise standard deviation must be positive and finite",
        });
    }
    let basis = tangent_basis(g_bar)?;
    let mut factor = Matrix8::zeros();
    for p in layout.positions() {
        let mut stacked = SMatrix::<f64, 11, 8>::zeros();
        stacked.fixed_view_mut::<8, 8>(0, 0).copy_from(&factor);
        stacked
            .fixed_view_mut::<3, 8>(8, 0)
            .copy_from(&jacobian(p, omega, g_bar, &basis));
        factor = QR::new(stacked).r();
    }
    Ok(Fisher {
        factor,
        sigma,
        g_bar: *g_bar,
        basis,
    })
}

impl Fisher {
    /// `I(x) = sum J_i^T J_i / sigma^2`.
    pub fn matrix(&self) -> Matrix8 {
        self.factor.transpose() * self.factor / (self.sigma * self.sigma)
    }

    /// Singular values of the stacked Jacobian `[J_1; ...; J_L]`, descending.
    pub fn jacobian_singular_values(&self) -> SVector<f64, 8> {
        let mut s = self.factor.singular_values();
        s.as_mut_slice().sort_unstable_by(|a, b| b.total_cmp(a));
        s
    }

    /// Numerical rank (singular values above [`RANK_TOL`] times the largest).
    pub fn rank(&self) -> usize {
        let s = self.jacobian_singular_values();
        s.iter().filter(|&&v| v > RANK_TOL * s[0]).count()
    }

    /// The tangent basis `Pi` used for `n`.
    pub fn tangent_basis(&self) -> &Matrix3x2<f64> {
        &self.basis
    }

    /// The Cramer-Rao bound `I(x)^-1`, or [`TiltError::SingularFisher`].
    pub fn crb(&self) -> Result<Crb, TiltError> {
        let rank = self.rank();
        let inverse = match (rank, self.factor.try_inverse()) {
            (8, Some(inv)) => inv,
            _ => return Err(TiltError::SingularFisher { rank }),
        };
        let covariance = inverse * inverse.transpose() * (self.sigma * self.sigma);
        let to_tilt = -self.g_bar.cross_matrix() * self.basis;
        let n_block = covariance.fixed_view::<2, 2>(6, 6).into_owned();
        Ok(Crb {
            covariance,
            omega: covariance.fixed_view::<3, 3>(0, 0).into_owned(),
            omega_dot: covariance.fixed_view::<3, 3>(3, 3).into_owned(),
            tilt: to_tilt * n_block * to_tilt.transpose(),
        })
    }
}

/// Cramer-Rao lower bound on the covariance of any unbiased estimator of one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crb {
    /// Full 8x8 bound, ordered `(omega, omega_dot, n)`.
    pub covariance: Matrix8,
    /// Bound on the covariance of omega (rad^2/s^2).
    pub omega: Matrix3<f64>,
    /// Bound on the covariance of omega_dot (rad^2/s^4).
    pub omega_dot: Matrix3<f64>,
    /// Bound on the covariance of the 3-D tilt error `g_hat - g` (tangent to the sphere, m^2/s^4).
    pub tilt: Matrix3<f64>,
}

/// Expected omega-omega block of `sum J_i^T J_i` over `omega ~ N(0, sigma_omega^2 I)`:
/// `sigma_omega^2 (tr(Theta) I + 3 Theta)` (exact Jacobian; the paper's `8 sigma_omega^2 Theta`
/// follows from its truncated Jacobian).
pub fn expected_omega_block(layout: &Layout, sigma_omega: f64) -> Matrix3<f64> {
    let theta = layout.theta();
    (Matrix3::identity() * theta.trace() + theta * 3.0) * (sigma_omega * sigma_omega)
}
