//! Jump-up (spec §5): impact models of the brakes, the nominal pre-brake wheel speeds, the model
//! error and Jacobian (1.64)–(1.67), the learning update (1.63) and the guiding-effort
//! compensation (1.68)–(1.69).
//!
//! The learning update is written once for any jump through [`ErrorModel`]: the face → corner
//! jump learns three wheel speeds from three errors ([`JumpModel`]), the face → edge jump one
//! wheel speed from the energy error ([`crate::edge::EdgeJumpModel`]).
use nalgebra::{ComplexField, Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};

use crate::model::{figure_axis_momentum, housing_energy, tilt_axis, yaw_momentum};
use crate::{CubliError, FullState, Params, ReducedState};

/// How the brakes act at t = 0 (spec §5.1). `Ideal` is the paper's model; the others serve as
/// higher-fidelity "true plants" that the learner does not know.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImpactModel {
    /// p_w⁺ = 0, p_h continuous.
    Ideal,
    /// Wheels stop relative to the housing: ω_w⁺ = 0, p_h continuous.
    Lock,
    /// A fraction 1 − κ_i of each relative wheel speed remains; p_h continuous.
    Slip {
        /// Braking efficiency per wheel in [0, 1].
        kappa: Vector3<f64>,
    },
    /// Unmodelled impulses: p_h⁺ = κ ⊙ p_h⁻, then `Lock`.
    Lossy {
        /// Momentum retained per body axis.
        kappa: Vector3<f64>,
    },
}

impl ImpactModel {
    /// State right after braking, for the state `x` right before.
    pub fn apply(&self, params: &Params, x: &FullState) -> FullState {
        let tw = Matrix3::from_diagonal(params.theta_w());
        let lock = |p_h: Vector3<f64>, w_rel: Vector3<f64>| {
            // Momentum balance p_h = (Θ0 + Θw) ω_h + Θw ω_w with ω_w = w_rel given.
            let wh = params.total_inertia_inv() * (p_h - tw * w_rel);
            FullState {
                attitude: x.attitude,
                p_h,
                p_w: tw * (wh + w_rel),
            }
        };
        match self {
            Self::Ideal => FullState {
                p_w: Vector3::zeros(),
                ..*x
            },
            Self::Lock => lock(x.p_h, Vector3::zeros()),
            Self::Slip { kappa } => {
                let ww = x.omega_w(params);
                lock(x.p_h, (Vector3::repeat(1.0) - kappa).component_mul(&ww))
            }
            Self::Lossy { kappa } => lock(kappa.component_mul(&x.p_h), Vector3::zeros()),
        }
    }

    /// The same brake with its efficiency scaled per wheel by `factor` (spec §5.1: random κ per
    /// trial): `Slip` and `Lossy` scale κ (clamped to [0, 1]), `Lock` becomes `Lossy` with
    /// κ = `factor` clamped, `Ideal` (the model, which has no efficiency) stays `Ideal`.
    pub fn scaled(&self, factor: &Vector3<f64>) -> Result<Self, CubliError> {
        if !factor.iter().all(|v| v.is_finite()) {
            return Err(CubliError::NonFinite {
                field: "brake efficiency factor",
            });
        }
        let scale = |kappa: &Vector3<f64>| kappa.component_mul(factor).map(|k| k.clamp(0.0, 1.0));
        Ok(match self {
            Self::Ideal => Self::Ideal,
            Self::Lock => Self::Lossy {
                kappa: scale(&Vector3::repeat(1.0)),
            },
            Self::Slip { kappa } => Self::Slip {
                kappa: scale(kappa),
            },
            Self::Lossy { kappa } => Self::Lossy {
                kappa: scale(kappa),
            },
        })
    }
}

/// Attitude lying on the face through the pivot with normal −e3 (spec §7.4): R = I.
pub fn face_attitude() -> UnitQuaternion<f64> {
    UnitQuaternion::identity()
}

/// Pre-brake state: housing at rest with attitude `attitude`, wheels spinning at `theta`.
pub fn pre_brake_state(
    params: &Params,
    attitude: UnitQuaternion<f64>,
    theta: &Vector3<f64>,
) -> FullState {
    FullState::from_velocities(params, attitude, &Vector3::zeros(), theta)
}

/// The nominal model's view of a jump from the resting gravity direction `g0` (body frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpModel {
    params: Params,
    g0: Vector3<f64>,
}

impl JumpModel {
    /// Jump model of `params` from rest with body gravity `g0` (scaled to |g|); fails if m ∥ g0.
    pub fn new(params: Params, g0: &Vector3<f64>) -> Result<Self, CubliError> {
        if !g0.iter().all(|v| v.is_finite()) {
            return Err(CubliError::NonFinite { field: "g0" });
        }
        let g0 = g0 * (params.gravity() / g0.norm());
        tilt_axis(&params, &g0)?;
        Ok(Self { params, g0 })
    }

    /// Model root (1.67): θ̄ = Θw⁻¹ p₀^φ e_φ(0), p₀^φ = −√(2 (mᵀg + |m||g|)/(e_φᵀΘ0⁻¹e_φ)).
    pub fn nominal_wheel_speeds(&self) -> Vector3<f64> {
        let p = &self.params;
        let e = p.m().cross(&self.g0).normalize();
        let p_phi = -ComplexField::sqrt(2.0 * (p.m().dot(&self.g0) + p.mg()) * p.tilt_inertia(&e));
        (e * p_phi).component_div(p.theta_w())
    }

    /// Predicted top-point error (1.64)–(1.65): (p_hᵐ, p_hᵍ, H_h) after an ideal brake at `theta`.
    pub fn error(&self, theta: &Vector3<f64>) -> Vector3<f64> {
        let p = &self.params;
        let pw = theta.component_mul(p.theta_w());
        let gh = self.g0 / self.g0.norm();
        Vector3::new(
            p.m_hat().dot(&pw),
            gh.dot(&pw),
            0.5 * pw.dot(&(p.theta0_inv() * pw)) - p.m().dot(&self.g0) - p.mg(),
        )
    }

    /// Model Jacobian (1.66) of [`JumpModel::error`] at `theta`.
    pub fn jacobian(&self, theta: &Vector3<f64>) -> Matrix3<f64> {
        let p = &self.params;
        let tw = Matrix3::from_diagonal(p.theta_w());
        let gh = self.g0 / self.g0.norm();
        let row3 = tw * p.theta0_inv() * tw * theta;
        Matrix3::from_rows(&[
            (tw * p.m_hat()).transpose(),
            (tw * gh).transpose(),
            row3.transpose(),
        ])
    }

    /// Resting gravity direction (body frame, magnitude |g|).
    pub fn g0(&self) -> &Vector3<f64> {
        &self.g0
    }
}

/// What the learner needs to know about a jump: P adjustable wheel speeds θ, N error
/// components, the nominal model's root and Jacobian, and how θ and the measured
/// (p_hᵐ, p_hᵍ, H_h) map onto the experiment.
pub trait ErrorModel<const P: usize, const N: usize> {
    /// Model root θ̄ with zero predicted error (the initial guess (1.67)).
    fn root(&self) -> SVector<f64, P>;
    /// Predicted error at `theta` (1.64)–(1.65).
    fn predict(&self, theta: &SVector<f64, P>) -> SVector<f64, N>;
    /// Model Jacobian ∂E/∂θ at `theta` (1.66).
    fn jacobian(&self, theta: &SVector<f64, P>) -> SMatrix<f64, N, P>;
    /// The three pre-brake wheel speeds of the experiment for `theta`.
    fn wheel_speeds(&self, theta: &SVector<f64, P>) -> Vector3<f64>;
    /// The learned error components out of a measured (p_hᵐ, p_hᵍ, H_h).
    fn measured(&self, error: &Vector3<f64>) -> SVector<f64, N>;
}

impl ErrorModel<3, 3> for JumpModel {
    fn root(&self) -> Vector3<f64> {
        self.nominal_wheel_speeds()
    }
    fn predict(&self, theta: &Vector3<f64>) -> Vector3<f64> {
        self.error(theta)
    }
    fn jacobian(&self, theta: &Vector3<f64>) -> Matrix3<f64> {
        JumpModel::jacobian(self, theta)
    }
    fn wheel_speeds(&self, theta: &Vector3<f64>) -> Vector3<f64> {
        *theta
    }
    fn measured(&self, error: &Vector3<f64>) -> Vector3<f64> {
        *error
    }
}

/// The measured error (p_hᵐ, p_hᵍ, H_h) of a state, evaluated with `params`.
pub fn jump_error(params: &Params, x: &ReducedState) -> Vector3<f64> {
    Vector3::new(
        figure_axis_momentum(params, x),
        yaw_momentum(x),
        housing_energy(params, x),
    )
}

/// Learning update (1.63) with a fixed model Jacobian pseudoinverse, computed once.
///
/// ```
/// use cubli::jump::{ErrorModel, JumpModel, Learner};
/// let model = JumpModel::new(cubli::Params::reference(), &nalgebra::Vector3::new(0.0, 0.0, -9.81)).unwrap();
/// let learner = Learner::new(&model, 0.8).unwrap();
/// let root = model.root();
/// // Near the root, on the model itself, one step removes 80 % of the distance (λ = 0.8).
/// let start = root * 1.01;
/// let next = learner.update(&start, &model.predict(&start));
/// assert!(((next - root).norm() / (start - root).norm() - 0.2).abs() < 0.02);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Learner<const P: usize, const N: usize> {
    jac_pinv: SMatrix<f64, P, N>,
    lambda: f64,
}

impl<const P: usize, const N: usize> Learner<P, N> {
    /// Learner with step `lambda` ∈ (0, 2) and the model Jacobian at the model root.
    ///
    /// The Jacobian must have full column rank (N ≥ P); its pseudoinverse is (JᵀJ)⁻¹Jᵀ from a
    /// Cholesky factor, refused when a pivot falls below 10⁻¹⁰ of the largest.
    pub fn new<M: ErrorModel<P, N>>(model: &M, lambda: f64) -> Result<Self, CubliError> {
        let inside = lambda > 0.0 && lambda < 2.0;
        if !inside {
            return Err(CubliError::StepSize(lambda));
        }
        let j = model.jacobian(&model.root());
        if !j.iter().all(|v| v.is_finite()) {
            return Err(CubliError::SingularJacobian);
        }
        let chol = j
            .tr_mul(&j)
            .cholesky()
            .ok_or(CubliError::SingularJacobian)?;
        let pivots = chol.l_dirty().diagonal();
        if pivots.min() <= 1e-10 * pivots.max() {
            return Err(CubliError::SingularJacobian);
        }
        Ok(Self {
            jac_pinv: chol.solve(&j.transpose()),
            lambda,
        })
    }

    /// θ_{i+1} = θ_i − λ J† E_i.
    pub fn update(&self, theta: &SVector<f64, P>, error: &SVector<f64, N>) -> SVector<f64, P> {
        theta - self.jac_pinv * error * self.lambda
    }
}

/// Trapezoidal accumulation of the guiding effort ∫ṗ_hᵐ and ∫Ḣ_h (1.68), pairing both ends of
/// each sample interval with the torque held during it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EffortIntegrator {
    figure: f64,
    energy: f64,
}

impl EffortIntegrator {
    /// Adds the interval from `start` to `end` (reduced states) under the held `torque`.
    pub fn accumulate(
        &mut self,
        params: &Params,
        start: &ReducedState,
        end: &ReducedState,
        torque: &Vector3<f64>,
        dt: f64,
    ) {
        let mh = params.m_hat();
        let rates = |x: &ReducedState| {
            let w = x.omega_h(params);
            (-mh.dot(&w.cross(&x.p_h)), -w.dot(torque))
        };
        let (a0, b0) = rates(start);
        let (a1, b1) = rates(end);
        self.figure += 0.5 * dt * (a0 + a1);
        self.energy += 0.5 * dt * (b0 + b1);
    }

    /// E' = (p_hᵐ − ∫ṗ_hᵐ, p_hᵍ, H_h − ∫Ḣ_h) (1.68) from the measured error E.
    pub fn corrected(&self, error: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(error[0] - self.figure, error[1], error[2] - self.energy)
    }
}
