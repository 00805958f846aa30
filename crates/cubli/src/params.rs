//! Physical parameters of the Cubli, validated once so that every later computation can trust them.
use nalgebra::{ComplexField, Matrix3, Vector3};

use crate::CubliError;

/// Rigid-body parameters of the Cubli about its pivot (spec §1.3), in body axes.
///
/// The paper gives only the side length (0.15 m) and, through its reported poles, |m||g|. The
/// remaining values of [`Params::reference`] are the illustrative set of spec §7.5: they match the
/// 150 mm cube, |m||g| = 1.8639 N m inferred from the poles, the symmetry of Assumption 4.1 and the
/// wheel speeds of Fig. 1.10.
///
/// ```
/// let p = cubli::Params::reference();
/// assert!((p.m().norm() * p.gravity() - 1.8639).abs() < 1e-4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    theta0: Matrix3<f64>,
    theta0_inv: Matrix3<f64>,
    total_inv: Matrix3<f64>,
    theta_w: Vector3<f64>,
    m: Vector3<f64>,
    gravity: f64,
}

impl Params {
    /// Validates and builds the parameters.
    ///
    /// * `theta0`: housing inertia about the pivot without the wheels' spin inertia (kg m², SPD);
    /// * `theta_w`: spin inertia of each wheel about its axis (kg m², positive);
    /// * `m`: total mass times the pivot-to-centre-of-mass vector (kg m, non-zero);
    /// * `gravity`: |g| (m/s², positive).
    pub fn new(
        theta0: Matrix3<f64>,
        theta_w: Vector3<f64>,
        m: Vector3<f64>,
        gravity: f64,
    ) -> Result<Self, CubliError> {
        if theta0.iter().any(|v| !v.is_finite()) {
            return Err(CubliError::NonFinite { field: "theta0" });
        }
        if theta_w.iter().any(|v| !v.is_finite()) {
            return Err(CubliError::NonFinite { field: "theta_w" });
        }
        if m.iter().any(|v| !v.is_finite()) {
            return Err(CubliError::NonFinite { field: "m" });
        }
        if !gravity.is_finite() {
            return Err(CubliError::NonFinite { field: "gravity" });
        }
        if gravity <= 0.0 {
            return Err(CubliError::NonPositive {
                field: "gravity",
                value: gravity,
            });
        }
        if let Some(&w) = theta_w.iter().find(|w| **w <= 0.0) {
            return Err(CubliError::NonPositive {
                field: "theta_w",
                value: w,
            });
        }
        if m.norm() == 0.0 {
            return Err(CubliError::NonPositive {
                field: "|m|",
                value: 0.0,
            });
        }
        let asymmetry = (theta0 - theta0.transpose()).amax();
        if asymmetry > 1e-12 * theta0.amax() {
            return Err(CubliError::NotSymmetric {
                field: "theta0",
                asymmetry,
            });
        }
        let theta0 = (theta0 + theta0.transpose()) * 0.5;
        let chol = theta0
            .cholesky()
            .ok_or(CubliError::NotPositiveDefinite { field: "theta0" })?;
        let total_inv = (theta0 + Matrix3::from_diagonal(&theta_w))
            .cholesky()
            .ok_or(CubliError::NotPositiveDefinite {
                field: "theta0 + theta_w",
            })?
            .inverse();
        Ok(Self {
            theta0,
            theta0_inv: chol.inverse(),
            total_inv,
            theta_w,
            m,
            gravity,
        })
    }

    /// The reference set of spec §7.5 (see the type documentation): |g| = 9.81 m/s²,
    /// m = 0.19 (1,1,1)/√3 kg m, Θ0 with diagonal 0.0220 and off-diagonal −0.0082 kg m²,
    /// Θw = 3·10⁻⁴ I kg m².
    pub fn reference() -> Self {
        let d = 0.0220;
        let o = -0.0082;
        let theta0 = Matrix3::new(d, o, o, o, d, o, o, o, d);
        let m = Vector3::repeat(0.19 / ComplexField::sqrt(3.0));
        Self {
            theta0,
            theta0_inv: reference_inverse(d, o),
            total_inv: reference_inverse(d + 3.0e-4, o),
            theta_w: Vector3::repeat(3.0e-4),
            m,
            gravity: 9.81,
        }
    }

    /// Housing inertia Θ0 about the pivot (kg m²).
    pub fn theta0(&self) -> &Matrix3<f64> {
        &self.theta0
    }
    /// Θ0⁻¹, computed once at construction.
    pub fn theta0_inv(&self) -> &Matrix3<f64> {
        &self.theta0_inv
    }
    /// (Θ0 + Θw)⁻¹: inverse of the total inertia about the pivot.
    pub fn total_inertia_inv(&self) -> &Matrix3<f64> {
        &self.total_inv
    }
    /// Wheel spin inertias (kg m²).
    pub fn theta_w(&self) -> &Vector3<f64> {
        &self.theta_w
    }
    /// Mass times centre-of-mass vector (kg m).
    pub fn m(&self) -> &Vector3<f64> {
        &self.m
    }
    /// |g| (m/s²).
    pub fn gravity(&self) -> f64 {
        self.gravity
    }
    /// |m||g| (N m): the torque scale of the tilt dynamics.
    pub fn mg(&self) -> f64 {
        self.m.norm() * self.gravity
    }
    /// Unit vector along m (the figure axis).
    pub fn m_hat(&self) -> Vector3<f64> {
        self.m / self.m.norm()
    }
    /// Tilt inertia about an axis `e` normal to m: 1 / (eᵀ Θ0⁻¹ e), which equals I1 under
    /// Assumption 4.1 (spec §9 lemma 12).
    pub fn tilt_inertia(&self, e: &Vector3<f64>) -> f64 {
        let e = e / e.norm();
        1.0 / (e.dot(&(self.theta0_inv * e)))
    }
    /// Copy with the inertia Θ0 scaled and m replaced: builds the "true plant" of a mismatch study.
    pub fn with_mismatch(&self, theta0_scale: f64, m: Vector3<f64>) -> Result<Self, CubliError> {
        Self::new(self.theta0 * theta0_scale, self.theta_w, m, self.gravity)
    }
}

/// Closed-form inverse of the matrix with diagonal `d` and off-diagonals `o` (eigenvalues d+2o
/// along (1,1,1) and d−o twice), so that the constant reference set needs no fallible solve.
fn reference_inverse(d: f64, o: f64) -> Matrix3<f64> {
    let a = 1.0 / (d + 2.0 * o);
    let b = 1.0 / (d - o);
    let proj = Matrix3::repeat(1.0 / 3.0);
    proj * a + (Matrix3::identity() - proj) * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_inverse_matches_cholesky() {
        let p = Params::reference();
        let q = Params::new(*p.theta0(), *p.theta_w(), *p.m(), p.gravity()).unwrap();
        assert!((p.theta0_inv() - q.theta0_inv()).amax() < 1e-10);
        assert!((p.theta0_inv() * p.theta0() - Matrix3::identity()).amax() < 1e-12);
        assert!((p.total_inertia_inv() - q.total_inertia_inv()).amax() < 1e-10);
    }

    #[test]
    fn reference_eigenvalues_match_spec() {
        let p = Params::reference();
        let e = Vector3::new(1.0, -1.0, 0.0);
        assert!((p.tilt_inertia(&e) - 0.0302).abs() < 1e-12);
        let mh = p.m_hat();
        assert!((mh.dot(&(p.theta0() * mh)) - 0.0056).abs() < 1e-12);
    }

    #[test]
    fn invalid_parameters_are_named() {
        let p = Params::reference();
        let neg = Params::new(-p.theta0(), *p.theta_w(), *p.m(), 9.81);
        assert_eq!(
            neg,
            Err(CubliError::NotPositiveDefinite { field: "theta0" })
        );
        // Symmetric, positive diagonal, but indefinite.
        let indefinite = Matrix3::new(0.02, 0.03, 0.0, 0.03, 0.02, 0.0, 0.0, 0.0, 0.02);
        assert!(matches!(
            Params::new(indefinite, *p.theta_w(), *p.m(), 9.81),
            Err(CubliError::NotPositiveDefinite { field: "theta0" })
        ));
        let mut asym = *p.theta0();
        asym[(0, 1)] += 1e-3;
        assert!(matches!(
            Params::new(asym, *p.theta_w(), *p.m(), 9.81),
            Err(CubliError::NotSymmetric {
                field: "theta0",
                ..
            })
        ));
        assert!(matches!(
            Params::new(*p.theta0(), Vector3::new(3e-4, -1e-4, 3e-4), *p.m(), 9.81),
            Err(CubliError::NonPositive {
                field: "theta_w",
                ..
            })
        ));
        assert!(matches!(
            Params::new(
                *p.theta0(),
                *p.theta_w(),
                Vector3::new(f64::NAN, 0.0, 0.0),
                9.81
            ),
            Err(CubliError::NonFinite { field: "m" })
        ));
        assert!(matches!(
            Params::new(*p.theta0(), *p.theta_w(), *p.m(), -9.81),
            Err(CubliError::NonPositive {
                field: "gravity",
                ..
            })
        ));
    }
}
