//! Feedback linearization of the Cubli (spec §4) and the guiding controller that tracks the ideal
//! jump-up trajectory (spec §4.3, §5.2).
use nalgebra::{ComplexField, SMatrix, SVector, Vector2, Vector3};

use crate::model::inclination;
use crate::{CubliError, FullState, Gains, Params, TiltPolynomial};

/// J P v for J = [[0, 1], [−1, 0]] and P the projection on the first two components.
fn jp(v: &Vector3<f64>) -> Vector2<f64> {
    Vector2::new(v[1], -v[0])
}

/// The linearizing output y = P R p_h and its first two derivatives (1.37), (1.40)–(1.41), plus the
/// inertial yaw rate ᴵω_h,3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outputs {
    /// y: horizontal inertial angular momentum (N m s).
    pub y: Vector2<f64>,
    /// ẏ = −|g| J P ᴵm.
    pub y_dot: Vector2<f64>,
    /// ÿ = −|g| J P (ᴵω_h × ᴵm).
    pub y_ddot: Vector2<f64>,
    /// Inertial vertical rate ᴵω_h,3.
    pub omega3: f64,
}

/// Input transformation (1.44)–(1.46): turns the Cubli into two triple integrators (y) and one
/// integrator (ᴵω_h,3), away from 90° inclination.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackLinearization {
    params: Params,
    epsilon: f64,
}

impl FeedbackLinearization {
    /// Linearization for the model `params`; refuses states with |ᴵm_3| < 0.05 |m|.
    pub fn new(params: Params) -> Self {
        Self {
            params,
            epsilon: 0.05,
        }
    }

    /// The model parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The outputs y, ẏ, ÿ and ᴵω_h,3 at `x`.
    pub fn outputs(&self, x: &FullState) -> Outputs {
        let p = &self.params;
        let im = x.attitude * p.m();
        let iw = x.attitude * x.omega_h(p);
        let ip = x.attitude * x.p_h;
        Outputs {
            y: Vector2::new(ip[0], ip[1]),
            y_dot: -jp(&im) * p.gravity(),
            y_ddot: -jp(&iw.cross(&im)) * p.gravity(),
            omega3: iw[2],
        }
    }

    /// Torque that makes y⃛ = `w` and ᴵω̇_h,3 = `v3`; an error near 90° inclination.
    pub fn torque_from_virtual(
        &self,
        x: &FullState,
        w: &Vector2<f64>,
        v3: f64,
    ) -> Result<Vector3<f64>, CubliError> {
        x.validate()?;
        let p = &self.params;
        let im = x.attitude * p.m();
        let threshold = self.epsilon * p.m().norm();
        if im[2].is_nan() || im[2].abs() < threshold {
            return Err(CubliError::LinearizationSingular {
                m3: im[2],
                threshold,
            });
        }
        let w_body = x.omega_h(p);
        let iw = x.attitude * w_body;
        let c = iw.cross(&iw.cross(&im));
        let pv = (Vector2::new(im[0], im[1]) * v3 + jp(&c) + w / p.gravity()) / im[2];
        let iv = Vector3::new(pv[0], pv[1], v3);
        let g = x.gravity_body(p);
        Ok(-w_body.cross(&x.p_h) + p.m().cross(&g)
            - p.theta0() * x.attitude.inverse_transform_vector(&iv))
    }
}

/// Reference signals (1.62) of the ideal jump, evaluated at the current inclination φ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    /// y_des.
    pub y: Vector2<f64>,
    /// ẏ_des.
    pub y_dot: Vector2<f64>,
    /// ÿ_des.
    pub y_ddot: Vector2<f64>,
    /// y⃛_des.
    pub y_dddot: Vector2<f64>,
}

/// The ideal jump trajectory: torque-free motion to upright about a fixed inertial axis ᴵe_φ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpReference {
    axis: Vector2<f64>,
    mg: f64,
    i1: f64,
}

impl JumpReference {
    /// Reference about the fixed inertial tilt axis `inertial_axis` (reading (a) of spec §5.2),
    /// for |m||g| = `mg` and tilt inertia `i1`.
    pub fn new(inertial_axis: &Vector3<f64>, mg: f64, i1: f64) -> Result<Self, CubliError> {
        let n = inertial_axis.norm();
        if !n.is_finite() || n <= 0.0 {
            return Err(CubliError::NonFinite {
                field: "inertial_axis",
            });
        }
        for (field, value) in [("mg", mg), ("i1", i1)] {
            if !value.is_finite() || value <= 0.0 {
                return Err(CubliError::NonPositive { field, value });
            }
        }
        let e = inertial_axis / n;
        Ok(Self {
            axis: Vector2::new(e[0], e[1]),
            mg,
            i1,
        })
    }

    /// Reference whose axis is R e_φ of the pre-brake state `x`, computed once at braking.
    pub fn at_brake(params: &Params, x: &FullState) -> Result<Self, CubliError> {
        let e = crate::model::tilt_axis(params, &x.gravity_body(params))?;
        Self::new(&(x.attitude * e), params.mg(), params.tilt_inertia(&e))
    }

    /// φ̇_des(φ) = −2 √(|m||g|/I1) sin(φ/2): the ideal rate toward upright.
    pub fn phi_dot(&self, phi: f64) -> f64 {
        -2.0 * ComplexField::sqrt(self.mg / self.i1) * ComplexField::sin(0.5 * phi)
    }

    /// The references at inclination `phi`.
    pub fn at(&self, phi: f64) -> Reference {
        let (s, c) = (ComplexField::sin(phi), ComplexField::cos(phi));
        let pd = self.phi_dot(phi);
        Reference {
            y: self.axis * (self.i1 * pd),
            y_dot: self.axis * (self.mg * s),
            y_ddot: self.axis * (self.mg * c * pd),
            y_dddot: self.axis * (self.mg * self.mg / self.i1 * s * (3.0 * c - 2.0)),
        }
    }
}

/// Tracking controller (1.60)–(1.61): u = K ξ_e on the error state ξ_e = (e, ė, ë, ᴵω_h,3), with
/// the gain that matches the balancing loop at upright (spec §4.3):
/// K = −[[C I₂, B I₂, A I₂, 0], [0, 0, 0, γ]].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidingController {
    linearization: FeedbackLinearization,
    reference: JumpReference,
    gain: SMatrix<f64, 3, 7>,
}

impl GuidingController {
    /// Guiding controller whose error dynamics have the tilt poles of `gains` (twice) and −γ.
    pub fn new(params: Params, gains: &Gains, reference: JumpReference) -> Self {
        let k = TiltPolynomial::from_gains(gains, params.mg());
        let mut gain = SMatrix::<f64, 3, 7>::zeros();
        for i in 0..2 {
            gain[(i, i)] = -k.c;
            gain[(i, 2 + i)] = -k.b;
            gain[(i, 4 + i)] = -k.a;
        }
        gain[(2, 6)] = -gains.gamma;
        Self {
            linearization: FeedbackLinearization::new(params),
            reference,
            gain,
        }
    }

    /// The controller's model parameters.
    pub fn params(&self) -> &Params {
        self.linearization.params()
    }

    /// The reference it tracks.
    pub fn reference(&self) -> &JumpReference {
        &self.reference
    }

    /// The gain K (3 × 7) acting on ξ_e = (e, ė, ë, ᴵω_h,3).
    pub fn gain(&self) -> &SMatrix<f64, 3, 7> {
        &self.gain
    }

    /// Error state ξ_e = (e, ė, ë, ᴵω_h,3) and the reference at the state's inclination.
    pub fn error(&self, x: &FullState) -> (SVector<f64, 7>, Reference) {
        let p = self.linearization.params();
        let phi = inclination(p, &x.gravity_body(p));
        let o = self.linearization.outputs(x);
        let r = self.reference.at(phi);
        let (e, de, dde) = (o.y - r.y, o.y_dot - r.y_dot, o.y_ddot - r.y_ddot);
        let xi = SVector::<f64, 7>::from_column_slice(&[
            e[0], e[1], de[0], de[1], dde[0], dde[1], o.omega3,
        ]);
        (xi, r)
    }

    /// Motor torques; an error near 90° inclination or for a non-finite state.
    pub fn control(&self, x: &FullState) -> Result<Vector3<f64>, CubliError> {
        x.validate()?;
        let (xi, r) = self.error(x);
        let u = self.gain * xi;
        self.linearization
            .torque_from_virtual(x, &(r.y_dddot + Vector2::new(u[0], u[1])), u[2])
    }
}
