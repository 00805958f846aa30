//! States of the Cubli in generalized momenta (spec §1.4) and the maps to and from velocities.
use nalgebra::{UnitQuaternion, Vector3};

use crate::{CubliError, Params};

/// Reduced state x = (g, p_h, p_w) on S² × R³ × R³: the yaw angle and wheel angles are dropped.
///
/// `g` is gravity in body coordinates with magnitude |g| (not a unit vector).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReducedState {
    /// Gravity in body coordinates (m/s²), |g| = `Params::gravity`.
    pub g: Vector3<f64>,
    /// Total angular momentum about the pivot, body frame (N m s).
    pub p_h: Vector3<f64>,
    /// Absolute angular momentum of the wheels, Θw (ω_h + ω_w) (N m s).
    pub p_w: Vector3<f64>,
}

/// Full state (R, p_h, p_w) on SO(3) × R³ × R³; R maps body to inertial coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FullState {
    /// Attitude R_IK as a unit quaternion.
    pub attitude: UnitQuaternion<f64>,
    /// Total angular momentum about the pivot, body frame (N m s).
    pub p_h: Vector3<f64>,
    /// Absolute angular momentum of the wheels (N m s).
    pub p_w: Vector3<f64>,
}

fn check_finite(v: &Vector3<f64>, field: &'static str) -> Result<(), CubliError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(CubliError::NonFinite { field })
    }
}

impl Params {
    /// Housing rate ω_h = Θ0⁻¹ (p_h − p_w).
    pub fn omega_h(&self, p_h: &Vector3<f64>, p_w: &Vector3<f64>) -> Vector3<f64> {
        self.theta0_inv() * (p_h - p_w)
    }
    /// Wheel rates relative to the housing, ω_w = Θw⁻¹ p_w − ω_h.
    pub fn omega_w(&self, p_h: &Vector3<f64>, p_w: &Vector3<f64>) -> Vector3<f64> {
        p_w.component_div(self.theta_w()) - self.omega_h(p_h, p_w)
    }
    /// Generalized momenta (p_h, p_w) from housing and relative wheel rates.
    pub fn momenta(
        &self,
        omega_h: &Vector3<f64>,
        omega_w: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let p_w = self.theta_w().component_mul(&(omega_h + omega_w));
        (self.theta0() * omega_h + p_w, p_w)
    }
}

impl ReducedState {
    /// Builds the state from gravity in body axes and the housing and relative wheel rates.
    pub fn from_velocities(
        params: &Params,
        g: Vector3<f64>,
        omega_h: &Vector3<f64>,
        omega_w: &Vector3<f64>,
    ) -> Self {
        let (p_h, p_w) = params.momenta(omega_h, omega_w);
        Self { g, p_h, p_w }
    }

    /// Checks that all fields are finite and that |g| matches the parameters to 1 % (loose enough
    /// for intermediate integrator stages, tight enough to catch a unit vector passed as g).
    pub fn validate(&self, params: &Params) -> Result<(), CubliError> {
        check_finite(&self.g, "g")?;
        check_finite(&self.p_h, "p_h")?;
        check_finite(&self.p_w, "p_w")?;
        let actual = self.g.norm();
        let expected = params.gravity();
        if (actual - expected).abs() > 1e-2 * expected {
            return Err(CubliError::GravityMagnitude { expected, actual });
        }
        Ok(())
    }

    /// Housing rate ω_h.
    pub fn omega_h(&self, params: &Params) -> Vector3<f64> {
        params.omega_h(&self.p_h, &self.p_w)
    }
    /// Wheel rates relative to the housing.
    pub fn omega_w(&self, params: &Params) -> Vector3<f64> {
        params.omega_w(&self.p_h, &self.p_w)
    }
}

impl FullState {
    /// Builds the state from attitude and the housing and relative wheel rates.
    pub fn from_velocities(
        params: &Params,
        attitude: UnitQuaternion<f64>,
        omega_h: &Vector3<f64>,
        omega_w: &Vector3<f64>,
    ) -> Self {
        let (p_h, p_w) = params.momenta(omega_h, omega_w);
        Self { attitude, p_h, p_w }
    }

    /// Gravity in body coordinates, g = Rᵀ ᴵg with ᴵg = (0, 0, −|g|).
    pub fn gravity_body(&self, params: &Params) -> Vector3<f64> {
        self.attitude
            .inverse_transform_vector(&Vector3::new(0.0, 0.0, -params.gravity()))
    }

    /// The reduced state (g, p_h, p_w).
    pub fn reduced(&self, params: &Params) -> ReducedState {
        ReducedState {
            g: self.gravity_body(params),
            p_h: self.p_h,
            p_w: self.p_w,
        }
    }

    /// Checks that all fields are finite.
    pub fn validate(&self) -> Result<(), CubliError> {
        if !self.attitude.coords.iter().all(|x| x.is_finite()) {
            return Err(CubliError::NonFinite { field: "attitude" });
        }
        check_finite(&self.p_h, "p_h")?;
        check_finite(&self.p_w, "p_w")
    }

    /// Housing rate ω_h.
    pub fn omega_h(&self, params: &Params) -> Vector3<f64> {
        params.omega_h(&self.p_h, &self.p_w)
    }
    /// Wheel rates relative to the housing.
    pub fn omega_w(&self, params: &Params) -> Vector3<f64> {
        params.omega_w(&self.p_h, &self.p_w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn vec3() -> impl Strategy<Value = Vector3<f64>> {
        (-50.0..50.0f64, -50.0..50.0f64, -50.0..50.0f64).prop_map(|(a, b, c)| Vector3::new(a, b, c))
    }

    proptest! {
        /// Spec test 2: (ω_h, ω_w) -> (p_h, p_w) -> (ω_h, ω_w) round trip.
        #[test]
        fn momentum_velocity_round_trip(wh in vec3(), ww in vec3()) {
            let p = Params::reference();
            let (ph, pw) = p.momenta(&wh, &ww);
            prop_assert!((p.omega_h(&ph, &pw) - wh).amax() < 1e-12 * (1.0 + wh.amax()));
            prop_assert!((p.omega_w(&ph, &pw) - ww).amax() < 1e-12 * (1.0 + ww.amax() + wh.amax()));
        }
    }

    #[test]
    fn nan_state_is_named() {
        let p = Params::reference();
        let x = ReducedState {
            g: Vector3::new(0.0, 0.0, -9.81),
            p_h: Vector3::new(0.0, f64::NAN, 0.0),
            p_w: Vector3::zeros(),
        };
        assert_eq!(x.validate(&p), Err(CubliError::NonFinite { field: "p_h" }));
        let y = ReducedState {
            g: Vector3::new(0.0, 0.0, -1.0),
            ..x
        };
        assert!(matches!(
            ReducedState {
                p_h: Vector3::zeros(),
                ..y
            }
            .validate(&p),
            Err(CubliError::GravityMagnitude { .. })
        ));
    }
}
