//! The simulated plant: rigid-body model plus the motor effects a real Cubli has and a controller
//! model may lack (limits, torque constant, wheel friction), integrated with fixed-step RK4.
//!
//! RK4 is written here because a domain crate may not depend on the simulator crate; the
//! attitude is integrated as a quaternion and renormalized after each step, which keeps
//! RᵀR = I to rounding error.
use nalgebra::{ComplexField, Quaternion, UnitQuaternion, Vector3};

use crate::model::{full_derivative, reduced_derivative};
use crate::{CubliError, FullState, Params, ReducedState};

/// Motor torque and wheel speed limits (spec §7.3 lists them as not given in the paper).
///
/// The defaults are unlimited, as in the paper's analysis; [`Limits::cubli`] gives suggested
/// values for a Cubli-sized motor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Largest |T_i| a motor can apply (N m).
    pub max_torque: f64,
    /// Largest |ω_w,i| (rad/s); torque that would spin a wheel faster is cut.
    pub max_wheel_speed: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_torque: f64::INFINITY,
            max_wheel_speed: f64::INFINITY,
        }
    }
}

impl Limits {
    /// Suggested limits (not from the paper): 0.2 N m per motor, enough for the 0.17 N m
    /// disturbance test, and 700 rad/s, above the jump speeds of Fig. 1.10.
    pub fn cubli() -> Self {
        Self {
            max_torque: 0.2,
            max_wheel_speed: 700.0,
        }
    }

    /// Saturates `torque` and cuts any component that would drive a wheel beyond its speed limit.
    pub fn saturate(&self, torque: &Vector3<f64>, omega_w: &Vector3<f64>) -> Vector3<f64> {
        Vector3::from_fn(|i, _| {
            let t = torque[i].clamp(-self.max_torque, self.max_torque);
            if omega_w[i].abs() >= self.max_wheel_speed && t * omega_w[i] > 0.0 {
                0.0
            } else {
                t
            }
        })
    }
}

/// Wheel-motor effects of the simulated plant (defaults: none, torque constant 1).
///
/// Applied torque on wheel i: k_i T_i − c_v,i ω_w,i − c_c,i tanh(ω_w,i / ε). All are internal
/// torques between wheel and housing, so they leave the yaw momentum conserved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelEffects {
    /// Torque constant error k (applied = k × commanded), 1 when the motor model is right.
    pub torque_constant: Vector3<f64>,
    /// Viscous friction coefficient c_v (N m s/rad).
    pub viscous: Vector3<f64>,
    /// Coulomb friction level c_c (N m).
    pub coulomb: Vector3<f64>,
    /// Speed ε (rad/s) over which the Coulomb sign is smoothed by tanh(ω/ε).
    pub coulomb_smoothing: f64,
}

impl Default for WheelEffects {
    fn default() -> Self {
        Self {
            torque_constant: Vector3::repeat(1.0),
            viscous: Vector3::zeros(),
            coulomb: Vector3::zeros(),
            coulomb_smoothing: 0.1,
        }
    }
}

impl WheelEffects {
    /// Torque that reaches the wheels for a commanded (already saturated) torque.
    pub fn applied(&self, commanded: &Vector3<f64>, omega_w: &Vector3<f64>) -> Vector3<f64> {
        Vector3::from_fn(|i, _| {
            self.torque_constant[i] * commanded[i]
                - self.viscous[i] * omega_w[i]
                - self.coulomb[i] * ComplexField::tanh(omega_w[i] / self.coulomb_smoothing)
        })
    }

    /// Checks that every coefficient is finite, friction non-negative and ε positive.
    pub fn validate(&self) -> Result<(), CubliError> {
        for (field, v) in [
            ("torque_constant", &self.torque_constant),
            ("viscous", &self.viscous),
            ("coulomb", &self.coulomb),
        ] {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(CubliError::NonFinite { field });
            }
        }
        if let Some(&c) = self
            .viscous
            .iter()
            .chain(self.coulomb.iter())
            .find(|c| **c < 0.0)
        {
            return Err(CubliError::NonPositive {
                field: "friction coefficient",
                value: c,
            });
        }
        if self.coulomb_smoothing.is_nan() || self.coulomb_smoothing <= 0.0 {
            return Err(CubliError::NonPositive {
                field: "coulomb_smoothing",
                value: self.coulomb_smoothing,
            });
        }
        Ok(())
    }
}

/// The simulated Cubli: true parameters, motor effects and limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plant {
    /// True rigid-body parameters (may differ from a controller's model).
    pub params: Params,
    /// Hidden motor effects.
    pub effects: WheelEffects,
    /// Motor limits.
    pub limits: Limits,
}

impl Plant {
    /// An ideal plant: the given parameters, no motor effects, no limits.
    pub fn ideal(params: Params) -> Self {
        Self {
            params,
            effects: WheelEffects::default(),
            limits: Limits::default(),
        }
    }

    /// Torque that reaches the wheels for a commanded torque in state `x`.
    pub fn applied_torque(&self, x: &FullState, commanded: &Vector3<f64>) -> Vector3<f64> {
        let ww = x.omega_w(&self.params);
        self.effects
            .applied(&self.limits.saturate(commanded, &ww), &ww)
    }

    /// One RK4 step of the full model with the commanded torque held over the step.
    pub fn step(&self, x: &FullState, commanded: &Vector3<f64>, h: f64) -> FullState {
        let f =
            |s: &FullState| full_derivative(&self.params, s, &self.applied_torque(s, commanded));
        let add =
            |s: &FullState, d: &(Quaternion<f64>, Vector3<f64>, Vector3<f64>), a: f64| FullState {
                attitude: UnitQuaternion::new_unchecked(s.attitude.quaternion() + d.0 * a),
                p_h: s.p_h + d.1 * a,
                p_w: s.p_w + d.2 * a,
            };
        let k1 = f(x);
        let k2 = f(&add(x, &k1, 0.5 * h));
        let k3 = f(&add(x, &k2, 0.5 * h));
        let k4 = f(&add(x, &k3, h));
        let q = x.attitude.quaternion() + (k1.0 + (k2.0 + k3.0) * 2.0 + k4.0) * (h / 6.0);
        FullState {
            attitude: UnitQuaternion::from_quaternion(q),
            p_h: x.p_h + (k1.1 + (k2.1 + k3.1) * 2.0 + k4.1) * (h / 6.0),
            p_w: x.p_w + (k1.2 + (k2.2 + k3.2) * 2.0 + k4.2) * (h / 6.0),
        }
    }
}

/// One RK4 step of the reduced model (1.5) with a torque law evaluated inside every stage
/// (continuous control) and |g| restored after the step.
pub fn reduced_step<F>(params: &Params, x: &ReducedState, h: f64, mut torque: F) -> ReducedState
where
    F: FnMut(&ReducedState) -> Vector3<f64>,
{
    let mut f = |s: &ReducedState| reduced_derivative(params, s, &torque(s));
    let add = |s: &ReducedState, d: &ReducedState, a: f64| ReducedState {
        g: s.g + d.g * a,
        p_h: s.p_h + d.p_h * a,
        p_w: s.p_w + d.p_w * a,
    };
    let k1 = f(x);
    let k2 = f(&add(x, &k1, 0.5 * h));
    let k3 = f(&add(x, &k2, 0.5 * h));
    let k4 = f(&add(x, &k3, h));
    let mut out = ReducedState {
        g: x.g + (k1.g + (k2.g + k3.g) * 2.0 + k4.g) * (h / 6.0),
        p_h: x.p_h + (k1.p_h + (k2.p_h + k3.p_h) * 2.0 + k4.p_h) * (h / 6.0),
        p_w: x.p_w + (k1.p_w + (k2.p_w + k3.p_w) * 2.0 + k4.p_w) * (h / 6.0),
    };
    out.g *= params.gravity() / out.g.norm();
    out
}
