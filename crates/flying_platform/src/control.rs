//! Cascaded hover controller (spec §5): onboard rate LQR, offboard position/attitude loop,
//! and the actuator limits (flap deflection ±18°, thrust range).

use crate::error::{require_positive, Error, Result};
use crate::geometry::N_INPUTS;
use crate::model::Model;
use crate::params::PlatformParams;
use crate::EffectSet;
use nalgebra::{DMatrix, Matrix3, SMatrix, SVector, Vector3};

/// Symmetric square root of a symmetric positive-definite matrix (and of its inverse).
fn sqrt_spd(s: &Matrix3<f64>, what: &'static str) -> Result<(Matrix3<f64>, Matrix3<f64>)> {
    let eig = s.symmetric_eigen();
    if eig.eigenvalues.iter().any(|&l| !(l > 0.0 && l.is_finite())) {
        return Err(Error::Invalid {
            name: what,
            reason: format!(
                "must be positive definite, eigenvalues {:?}",
                eig.eigenvalues.as_slice()
            ),
        });
    }
    let v = eig.eigenvectors;
    let root = v * Matrix3::from_diagonal(&eig.eigenvalues.map(f64::sqrt)) * v.transpose();
    let inv_root =
        v * Matrix3::from_diagonal(&eig.eigenvalues.map(|l| 1.0 / l.sqrt())) * v.transpose();
    Ok((root, inv_root))
}

/// Onboard body-rate LQR for `w' = B (u - u_bar)` (no drift), in closed form (spec §5.1):
/// with `S = B R^-1 B^T`, `P = S^-1/2 (S^1/2 Q S^1/2)^1/2 S^-1/2` and `K = R^-1 B^T P`.
#[derive(Debug, Clone, PartialEq)]
pub struct InnerLqr {
    /// Gain `K` (9 x 3): thrust deviations from rate errors, N per rad/s.
    pub k: SMatrix<f64, 9, 3>,
    /// Riccati solution `P` (3 x 3).
    pub p: Matrix3<f64>,
    /// Design input matrix `B` (3 x 9), the rate rows of the design model.
    pub b: SMatrix<f64, 3, 9>,
}

impl InnerLqr {
    /// Paper weights: `Q = 512 I`, `R = diag(1, 2, 2, 1, 2, 2, 1, 2, 2)`.
    pub fn paper_weights() -> (Matrix3<f64>, SVector<f64, 9>) {
        (
            Matrix3::identity() * 512.0,
            SVector::<f64, 9>::from_column_slice(&[1.0, 2.0, 2.0, 1.0, 2.0, 2.0, 1.0, 2.0, 2.0]),
        )
    }

    /// Designs the gain for the rate rows of `design` (the low-complexity hover model).
    pub fn design(
        design: &PlatformParams,
        q: &Matrix3<f64>,
        r_diag: &SVector<f64, 9>,
    ) -> Result<Self> {
        let (_, b9) = Model::new(design.clone(), EffectSet::none()).hover_matrices()?;
        let b = SMatrix::<f64, 3, 9>::from_fn(|i, j| b9[(6 + i, j)]);
        if let Some(i) = r_diag.iter().position(|&r| !(r > 0.0 && r.is_finite())) {
            return Err(Error::Invalid {
                name: "r_diag",
                reason: format!("entry {i} = {} must be > 0", r_diag[i]),
            });
        }
        if (q - q.transpose()).amax() > 1e-12 * q.amax().max(1.0) {
            return Err(Error::Invalid {
                name: "q",
                reason: "must be symmetric".into(),
            });
        }
        let r_inv = SMatrix::<f64, 9, 9>::from_diagonal(&r_diag.map(|r| 1.0 / r));
        let s = b * r_inv * b.transpose();
        let (s_half, s_inv_half) = sqrt_spd(&s, "B R^-1 B^T (rate loop not controllable)")?;
        let (inner, _) = sqrt_spd(&(s_half * q * s_half), "Q")?;
        let p = s_inv_half * inner * s_inv_half;
        let k = r_inv * b.transpose() * p;
        Ok(Self { k, p, b })
    }

    /// Paper design on the nominal structure with `l3 = 0.079` (spec §9.3).
    pub fn paper() -> Result<Self> {
        let (q, r) = Self::paper_weights();
        Self::design(&PlatformParams::nominal(), &q, &r)
    }

    /// Closed-loop rate matrix `-B K` of the design model.
    pub fn closed_loop(&self) -> Matrix3<f64> {
        -self.b * self.k
    }
}

/// How the yaw command is computed from the yaw error (spec §13 item 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum YawLaw {
    /// `w_des,z = -p_z (yaw - yaw_des)`: yaw time constant 1/p_z (default).
    Intended,
    /// `w_des,z = -(1/g0) p_z (yaw - yaw_des)`, as printed in the paper.
    AsPrinted,
}

/// Offboard loop gains (spec §5.2): `d` damping, `w` natural frequency (rad/s), `p` pole (rad/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OuterGains {
    /// Damping of the x/y second-order factor.
    pub d_xy: f64,
    /// Natural frequency of the x/y second-order factor, rad/s.
    pub w_xy: f64,
    /// Real pole of x/y, rad/s.
    pub p_xy: f64,
    /// Damping of z.
    pub d_z: f64,
    /// Natural frequency of z, rad/s.
    pub w_z: f64,
    /// Yaw pole, rad/s.
    pub p_z: f64,
    /// Yaw law.
    pub yaw_law: YawLaw,
}

impl Default for OuterGains {
    fn default() -> Self {
        Self {
            d_xy: 1.0,
            w_xy: 3.0,
            p_xy: 1.0,
            d_z: 1.0,
            w_z: 2.0,
            p_z: 2.0,
            yaw_law: YawLaw::Intended,
        }
    }
}

/// Loop bandwidths of the cascade: the rate-loop weight and the outer-loop gains.
///
/// The paper's tuning (`Q = 512 I`, [`OuterGains::default`]) tolerates about 35 ms of
/// actuator latency in the loop; fans whose thrust follows the command with a first-order lag
/// of 60-80 ms need lower bandwidths, which [`Tuning::slow_actuators`] provides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tuning {
    /// Rate-loop weight `q` of `Q = q I` (R stays the paper's); smaller is slower.
    pub rate_weight: f64,
    /// Position/attitude loop gains.
    pub gains: OuterGains,
}

impl Tuning {
    /// The paper's tuning: `Q = 512 I` and [`OuterGains::default`].
    pub fn paper() -> Self {
        Self {
            rate_weight: 512.0,
            gains: OuterGains::default(),
        }
    }

    /// Lower bandwidths for slow actuators: stable at hover with a first-order thrust lag of up
    /// to 80 ms plus 15 ms of in-loop delay, on the low-complexity and on the augmented plant
    /// (rate weight 192, x/y: d 0.5, w 3.5 rad/s, p 1 rad/s; z: w 1.5 rad/s; yaw pole 1 rad/s;
    /// closed-loop eigenvalues and simulation checked in the tests).
    pub fn slow_actuators() -> Self {
        Self {
            rate_weight: SLOW_RATE_WEIGHT,
            gains: OuterGains {
                d_xy: SLOW_D_XY,
                w_xy: SLOW_W_XY,
                p_xy: SLOW_P_XY,
                d_z: 1.0,
                w_z: SLOW_W_Z,
                p_z: SLOW_P_Z,
                yaw_law: YawLaw::Intended,
            },
        }
    }

    /// Parses `paper` or `slow-actuators` (CLI spelling).
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "paper" => Ok(Self::paper()),
            "slow-actuators" | "slow_actuators" => Ok(Self::slow_actuators()),
            other => Err(Error::Invalid {
                name: "tuning",
                reason: format!("unknown tuning `{other}` (known: paper, slow-actuators)"),
            }),
        }
    }
}

// Chosen on a grid (rate weight 64..256, w_xy 2.5..4, p_xy 0.5..1.5, d_xy 0.4..0.7) for the
// smallest closed-loop spectral radius over thrust lags 10-80 ms, with and without momentum
// drag and fan gyroscopic torque, 0 and 15 ms in-loop delay. Momentum drag needs a fast
// enough x/y loop, the lag a slower rate loop: the compromise lowers the rate weight and the
// x/y damping.
const SLOW_RATE_WEIGHT: f64 = 192.0;
const SLOW_D_XY: f64 = 0.5;
const SLOW_W_XY: f64 = 3.5;
const SLOW_P_XY: f64 = 1.0;
const SLOW_W_Z: f64 = 1.5;
const SLOW_P_Z: f64 = 1.0;

/// Measured state used by the controller (positions and velocities in the yaw frame J).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Measurement {
    /// Position in J, m.
    pub position: Vector3<f64>,
    /// CoG velocity in J, m/s.
    pub velocity: Vector3<f64>,
    /// (roll, pitch, yaw), rad.
    pub attitude: Vector3<f64>,
    /// Body rates, rad/s.
    pub rates: Vector3<f64>,
}

/// Set-point: position in J (m) and yaw (rad).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Setpoint {
    /// Desired position in J, m.
    pub position: Vector3<f64>,
    /// Desired yaw, rad.
    pub yaw: f64,
}

/// Actuator limits: flap deflection and thrust range (spec §2.2, §9.2 item 6).
///
/// A flap's lateral force is `gain * deflection * (thrust / reference_thrust)`, so the
/// lateral force available at ±`flap_limit_deg` scales with the unit's vertical thrust.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActuatorLimits {
    /// Flap deflection limit, degrees (both flaps).
    pub flap_limit_deg: f64,
    /// Flap-1 (local x) force gain, N per degree at the reference thrust.
    pub flap1_gain: f64,
    /// Flap-2 (local y) force gain, N per degree at the reference thrust.
    pub flap2_gain: f64,
    /// Thrust at which the flap gains were measured, N.
    pub reference_thrust: f64,
    /// Minimum vertical thrust per unit, N.
    pub thrust_min: f64,
    /// Maximum vertical thrust per unit (ESC plateau), N.
    pub thrust_max: f64,
}

impl Default for ActuatorLimits {
    fn default() -> Self {
        Self {
            flap_limit_deg: 18.0,
            flap1_gain: 3.0 / 18.0,
            flap2_gain: 1.5 / 18.0,
            reference_thrust: 26.4,
            thrust_min: 0.0,
            thrust_max: 46.9,
        }
    }
}

impl ActuatorLimits {
    /// Clamps a thrust command to the limits; returns the clamped command and whether any
    /// channel saturated.
    pub fn saturate(&self, u: &SVector<f64, N_INPUTS>) -> (SVector<f64, N_INPUTS>, bool) {
        let mut out = *u;
        for unit in 0..3 {
            let z = u[3 * unit + 2].clamp(self.thrust_min, self.thrust_max);
            let scale = self.flap_limit_deg * z / self.reference_thrust;
            out[3 * unit + 2] = z;
            out[3 * unit] = u[3 * unit].clamp(-self.flap1_gain * scale, self.flap1_gain * scale);
            out[3 * unit + 1] =
                u[3 * unit + 1].clamp(-self.flap2_gain * scale, self.flap2_gain * scale);
        }
        let saturated = (out - u).amax() > 0.0;
        (out, saturated)
    }

    /// Flap deflections (degrees) that realise the lateral forces of `u` at its thrusts.
    pub fn flap_angles_deg(&self, u: &SVector<f64, N_INPUTS>) -> [[f64; 2]; 3] {
        core::array::from_fn(|unit| {
            let t = u[3 * unit + 2].max(1e-9) / self.reference_thrust;
            [
                u[3 * unit] / (self.flap1_gain * t),
                u[3 * unit + 1] / (self.flap2_gain * t),
            ]
        })
    }
}

/// The cascaded hover controller of the paper (Fig. 3.11).
#[derive(Debug, Clone, PartialEq)]
pub struct CascadedController {
    /// Rate loop.
    pub inner: InnerLqr,
    /// Position/attitude loop gains.
    pub gains: OuterGains,
    /// Actuator limits applied to the output.
    pub limits: ActuatorLimits,
    /// Hover trim `u_bar` of the design model, N.
    pub trim: SVector<f64, N_INPUTS>,
    /// Mass used by the height loop, kg.
    pub mass: f64,
    /// Gravity, m/s².
    pub g0: f64,
}

impl CascadedController {
    /// The paper's controller designed on `design` (nominal structure with l3 = 0.079 by default).
    pub fn new(design: &PlatformParams, gains: OuterGains, limits: ActuatorLimits) -> Result<Self> {
        Self::with_tuning(
            design,
            &Tuning {
                gains,
                ..Tuning::paper()
            },
            limits,
        )
    }

    /// The cascade designed on `design` with the bandwidths of `tuning`.
    pub fn with_tuning(
        design: &PlatformParams,
        tuning: &Tuning,
        limits: ActuatorLimits,
    ) -> Result<Self> {
        design.validate()?;
        require_positive("rate_weight", tuning.rate_weight)?;
        let gains = tuning.gains;
        for (name, v) in [
            ("w_xy", gains.w_xy),
            ("p_xy", gains.p_xy),
            ("w_z", gains.w_z),
            ("p_z", gains.p_z),
        ] {
            require_positive(name, v)?;
        }
        let (_, r) = InnerLqr::paper_weights();
        let q = Matrix3::identity() * tuning.rate_weight;
        Ok(Self {
            inner: InnerLqr::design(design, &q, &r)?,
            gains,
            limits,
            trim: design.hover_input(),
            mass: design.mass,
            g0: design.g0,
        })
    }

    /// The paper's controller on the default design model.
    pub fn paper() -> Result<Self> {
        Self::new(
            &PlatformParams::nominal(),
            OuterGains::default(),
            ActuatorLimits::default(),
        )
    }

    /// Outer loop: desired body rates and collective thrust increment per fan (N).
    pub fn outer(&self, y: &Measurement, sp: &Setpoint) -> (Vector3<f64>, f64) {
        let g = &self.gains;
        let g0 = self.g0;
        let e = y.position - sp.position;
        let (v, att) = (y.velocity, y.attitude);
        let wx = (-(2.0 * g.d_xy * g.w_xy + g.p_xy) * g0 * att[0]
            + (g.w_xy * g.w_xy + 2.0 * g.d_xy * g.w_xy * g.p_xy) * v[1]
            + g.p_xy * g.w_xy * g.w_xy * e[1])
            / g0;
        let wy = (-(2.0 * g.d_xy * g.w_xy + g.p_xy) * g0 * att[1]
            - (g.w_xy * g.w_xy + 2.0 * g.d_xy * g.w_xy * g.p_xy) * v[0]
            - g.p_xy * g.w_xy * g.w_xy * e[0])
            / g0;
        let yaw_err = wrap_angle(att[2] - sp.yaw);
        let wz = match g.yaw_law {
            YawLaw::Intended => -g.p_z * yaw_err,
            YawLaw::AsPrinted => -g.p_z * yaw_err / g0,
        };
        let fz = self.mass / 3.0 * (-2.0 * g.d_z * g.w_z * v[2] - g.w_z * g.w_z * e[2]);
        (Vector3::new(wx, wy, wz), fz)
    }

    /// Inner loop: thrust command (before limits) from the rates and the outer-loop command.
    pub fn inner(
        &self,
        rates: &Vector3<f64>,
        rates_des: &Vector3<f64>,
        fz: f64,
    ) -> SVector<f64, N_INPUTS> {
        let mut u = self.trim - self.inner.k * (rates - rates_des);
        for unit in 0..3 {
            u[3 * unit + 2] += fz;
        }
        u
    }

    /// Full cascade with limits applied: returns the saturated command and the unsaturated one.
    pub fn command(
        &self,
        y: &Measurement,
        sp: &Setpoint,
    ) -> (SVector<f64, N_INPUTS>, SVector<f64, N_INPUTS>) {
        let (rates_des, fz) = self.outer(y, sp);
        let raw = self.inner(&y.rates, &rates_des, fz);
        (self.limits.saturate(&raw).0, raw)
    }

    /// Gain `K` as a dynamic matrix (for analysis with `rigid_body::lti`).
    pub fn inner_gain(&self) -> DMatrix<f64> {
        DMatrix::from_fn(9, 3, |i, j| self.inner.k[(i, j)])
    }
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = 2.0 * core::f64::consts::PI;
    let w = (a + core::f64::consts::PI).rem_euclid(two_pi) - core::f64::consts::PI;
    if w <= -core::f64::consts::PI {
        w + two_pi
    } else {
        w
    }
}
