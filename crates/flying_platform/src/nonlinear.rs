//! Nonlinear rigid body with three ducted fans (spec §3.1, §3.5, §9.1 L2) and the same
//! switchable effects as the linear model: momentum drag written in the body frame with the
//! air-relative velocity, the rotor angular momentum `3 C omega_T0 e_z` (gyroscopic torque),
//! and the first-order thrust lag as nine extra states. The input delay is applied by the
//! simulator, not here.

use crate::error::Result;
use crate::geometry::N_INPUTS;
use crate::model::Model;
use nalgebra::{Matrix3, Rotation3, SVector, Vector3};

/// Length of the nonlinear state vector.
pub const N_NONLINEAR: usize = 21;

/// State `(p_I [0..3], v_I [3..6], (roll, pitch, yaw) [6..9], w_B [9..12], thrust [12..21])`:
/// inertial position and velocity of the CoG, Z-Y-X Euler angles, body rates, and the nine
/// actual thrusts (local frames, N; they equal the command when the lag is off).
pub type NonlinearState = SVector<f64, N_NONLINEAR>;

/// External inputs besides the thrust command.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Disturbance {
    /// Wind velocity in the inertial frame, m/s (enters through momentum drag).
    pub wind: Vector3<f64>,
    /// Additive acceleration of the CoG in the inertial frame, m/s².
    pub acceleration: Vector3<f64>,
    /// Additive body angular acceleration, rad/s².
    pub angular_acceleration: Vector3<f64>,
}

/// The nonlinear plant built from a [`Model`] (parameters and enabled effects).
#[derive(Debug, Clone, PartialEq)]
pub struct NonlinearPlant {
    /// Parameters and effects.
    pub model: Model,
    inertia: Matrix3<f64>,
    inertia_hat_inv: Matrix3<f64>,
}

impl NonlinearPlant {
    /// Builds the plant; checks the parameters.
    pub fn new(model: Model) -> Result<Self> {
        let p = &model.params;
        p.validate()?;
        let inertia = Matrix3::from_diagonal(&Vector3::new(p.i1, p.i1, p.i3));
        // Theta_hat = Theta - 3 C e_z e_z^T: rotor spin-up torque is cut free (spec §3.1).
        let mut hat = inertia;
        hat[(2, 2)] -= 3.0 * p.rotor_inertia;
        let inertia_hat_inv = hat.try_inverse().ok_or_else(|| crate::Error::Invalid {
            name: "i3",
            reason: "I3 - 3 C must be positive".into(),
        })?;
        Ok(Self {
            model,
            inertia,
            inertia_hat_inv,
        })
    }

    /// Hover at rest at the origin with the thrusts at the trim.
    pub fn hover_state(&self) -> NonlinearState {
        let mut x = NonlinearState::zeros();
        x.fixed_rows_mut::<9>(12)
            .copy_from(&self.model.params.hover_input());
        x
    }

    /// `R_IB = Rz(yaw) Ry(pitch) Rx(roll)`.
    pub fn rotation(x: &NonlinearState) -> Rotation3<f64> {
        Rotation3::from_euler_angles(x[6], x[7], x[8])
    }

    /// Time derivative of the state for the thrust command `u` (local frames, N).
    pub fn derivative(
        &self,
        x: &NonlinearState,
        u: &SVector<f64, N_INPUTS>,
        d: &Disturbance,
    ) -> NonlinearState {
        let p = &self.model.params;
        let fx = &self.model.effects;
        let v_i = x.fixed_rows::<3>(3).into_owned();
        let (roll, pitch) = (x[6], x[7]);
        let w = x.fixed_rows::<3>(9).into_owned();
        let r_ib = Self::rotation(x);
        let thrust: SVector<f64, N_INPUTS> = match fx.actuator_tau() {
            Some(_) => x.fixed_rows::<9>(12).into_owned(),
            None => *u,
        };
        let mut force = p.total_force(&thrust);
        let mut torque = p.total_torque(&thrust) - Vector3::z() * (3.0 * p.hover_torque);
        if let Some(md) = fx.momentum_drag() {
            let v_b = r_ib.transpose() * (v_i - d.wind);
            let c = Vector3::new(md.c_alpha1, md.c_alpha1, md.c_alpha2);
            let ez_w = Vector3::z().cross(&w);
            let ez_v = Vector3::z().cross(&v_b);
            force += -3.0 * c.component_mul(&v_b) + 3.0 * md.l_alpha1 * c.component_mul(&ez_w);
            let l = Vector3::new(md.l_alpha3, md.l_alpha3, md.l_alpha4);
            torque += -3.0 * md.l_alpha2 * c.component_mul(&ez_v)
                - 3.0 * l.component_mul(&c.component_mul(&w));
        }
        let rotor = Vector3::z() * (3.0 * fx.fan_momentum().unwrap_or(0.0));
        torque -= w.cross(&(self.inertia * w + rotor));
        let v_dot = Vector3::new(0.0, 0.0, -p.g0) + r_ib * force / p.mass + d.acceleration;
        let w_dot = self.inertia_hat_inv * torque + d.angular_acceleration;
        let (sr, cr) = roll.sin_cos();
        let (tp, cp) = (pitch.tan(), pitch.cos());
        let euler_dot = Vector3::new(
            w[0] + sr * tp * w[1] + cr * tp * w[2],
            cr * w[1] - sr * w[2],
            (sr * w[1] + cr * w[2]) / cp,
        );
        let mut dx = NonlinearState::zeros();
        dx.fixed_rows_mut::<3>(0).copy_from(&v_i);
        dx.fixed_rows_mut::<3>(3).copy_from(&v_dot);
        dx.fixed_rows_mut::<3>(6).copy_from(&euler_dot);
        dx.fixed_rows_mut::<3>(9).copy_from(&w_dot);
        if let Some(tau) = fx.actuator_tau() {
            dx.fixed_rows_mut::<9>(12).copy_from(&((u - thrust) / tau));
        }
        dx
    }

    /// One classical Runge-Kutta step of length `h` with the command held.
    pub fn rk4_step(
        &self,
        x: &NonlinearState,
        u: &SVector<f64, N_INPUTS>,
        d: &Disturbance,
        h: f64,
    ) -> NonlinearState {
        let k1 = self.derivative(x, u, d);
        let k2 = self.derivative(&(x + k1 * (h / 2.0)), u, d);
        let k3 = self.derivative(&(x + k2 * (h / 2.0)), u, d);
        let k4 = self.derivative(&(x + k3 * h), u, d);
        x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0)
    }

    /// Position and velocity in the yaw frame J (`R_IJ = Rz(yaw)`).
    pub fn in_yaw_frame(x: &NonlinearState) -> (Vector3<f64>, Vector3<f64>) {
        let r_ij = Rotation3::from_axis_angle(&Vector3::z_axis(), x[8]);
        (
            r_ij.transpose() * x.fixed_rows::<3>(0).into_owned(),
            r_ij.transpose() * x.fixed_rows::<3>(3).into_owned(),
        )
    }
}
