//! Face → edge jump and edge balancing: the planar ("1-D") Cubli.
//!
//! Lying on the face with normal −e3, the cube touches the ground along the edges e1 and e2
//! through the pivot. Spinning up the wheel whose axis is parallel to one of them and braking it
//! makes the cube rotate about that edge, from 45° (centre of mass over the face) to the upright
//! edge-balancing position. The edge contact is a hinge: its reaction impulses and torques have no
//! moment about the edge, so only the edge component of (1.1) matters,
//!
//!   ṗ = (m⊥ × g)·e,  ṗ_w = T,  ω = (p − p_w) / I_e,
//!
//! with e the edge direction, I_e = eᵀΘ0e, m⊥ the part of m normal to the edge and p, p_w the
//! momenta about the edge. This is exactly the invariant plane {ω ∥ e, g ⊥ e} of the 3-D reduced
//! model (1.5) with Θ0 replaced by I_e·I and m by m⊥ (the cross products that would leave the
//! plane vanish identically), so [`EdgeJump::params`] gives such an equivalent [`Params`] and
//! the 3-D plant, brake models, trial runner and learner are reused unchanged. The brake impact
//! conserves the momentum about the edge (the pivot-momentum balance (1.49) about the hinge axis).
//!
//! Balancing on the edge uses the backstepping law (1.10) of this planar model ([`EdgeBalance`]):
//! its Lyapunov proof carries over line by line (V = α/2 p² + |m⊥||g|(1 − cos φ) + z²/(2δI_e²)),
//! so it is almost-globally stabilizing on the circle, not only near upright as an LQR design
//! would be, and the paper's gains and tuning method (1.33)–(1.35) apply with |m||g| replaced by
//! |m⊥||g|.
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use crate::jump::{face_attitude, ErrorModel, JumpModel};
use crate::model::inclination;
use crate::{
    Backstepping, CubliError, FullState, Gains, Measurement, Params, Plant, ReducedState,
    SampledController,
};

/// The planar edge system of a Cubli about the body axis `axis` (0 or 1: the edges e1, e2 of the
/// resting face with normal −e3).
///
/// ```
/// let jump = cubli::edge::EdgeJump::new(&cubli::Params::reference(), 0).unwrap();
/// assert!((jump.resting_inclination().to_degrees() - 45.0).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeJump {
    full: Params,
    planar: Params,
    axis: usize,
}

impl EdgeJump {
    /// The edge system of `full` about body axis `axis` ∈ {0, 1}.
    pub fn new(full: &Params, axis: usize) -> Result<Self, CubliError> {
        if axis > 1 {
            return Err(CubliError::EdgeAxis { axis });
        }
        let mut m_perp = *full.m();
        m_perp[axis] = 0.0;
        if m_perp.norm() == 0.0 {
            return Err(CubliError::NonPositive {
                field: "|m| normal to the edge",
                value: 0.0,
            });
        }
        let inertia = full.theta0()[(axis, axis)];
        let planar = Params::new(
            Matrix3::identity() * inertia,
            *full.theta_w(),
            m_perp,
            full.gravity(),
        )?;
        Ok(Self {
            full: *full,
            planar,
            axis,
        })
    }

    /// The planar-equivalent parameters (Θ0 = I_e·I, m = m⊥): run the 3-D model with these on
    /// states with ω_h ∥ e and torque along e.
    pub fn params(&self) -> &Params {
        &self.planar
    }

    /// The full 3-D parameters the edge system was built from.
    pub fn full_params(&self) -> &Params {
        &self.full
    }

    /// Body axis index of the edge (and of the wheel that jumps).
    pub fn axis(&self) -> usize {
        self.axis
    }

    /// Unit edge direction in body coordinates.
    pub fn direction(&self) -> Vector3<f64> {
        Vector3::ith(self.axis, 1.0)
    }

    /// Housing inertia about the edge I_e = eᵀΘ0e (kg m²).
    pub fn inertia(&self) -> f64 {
        self.planar.theta0()[(0, 0)]
    }

    /// |m⊥||g| (N m): the largest gravity torque about the edge.
    pub fn mg(&self) -> f64 {
        self.planar.mg()
    }

    /// Inclination about the edge when lying on the face (45° with the centre of mass at the
    /// cube centre).
    pub fn resting_inclination(&self) -> f64 {
        let g = face_attitude().inverse_transform_vector(&Vector3::new(
            0.0,
            0.0,
            -self.planar.gravity(),
        ));
        inclination(&self.planar, &g)
    }

    /// A planar-plant copy of `plant` (its parameters restricted to this edge; motor effects and
    /// limits kept).
    pub fn plant(&self, plant: &Plant) -> Result<Plant, CubliError> {
        Ok(Plant {
            params: Self::new(&plant.params, self.axis)?.planar,
            ..*plant
        })
    }

    /// The 3-D state of the hinged cube for a planar-model state `x`: same attitude and rates,
    /// momenta recomputed with the full inertia (the hinge carries the off-axis components).
    pub fn hinged_state(&self, x: &FullState) -> FullState {
        FullState::from_velocities(
            &self.full,
            x.attitude,
            &x.omega_h(&self.planar),
            &x.omega_w(&self.planar),
        )
    }

    /// The balancing controller on this edge with `gains`.
    pub fn balancer(&self, gains: Gains) -> EdgeBalance {
        EdgeBalance {
            inner: Backstepping::new(self.planar, gains),
            axis: self.axis,
        }
    }
}

/// Backstepping (1.10) of the planar edge model: measurements are projected onto the plane
/// (g ⊥ e, momenta ∥ e) and only the edge wheel gets a torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeBalance {
    inner: Backstepping,
    axis: usize,
}

impl EdgeBalance {
    /// The planar backstepping law underneath.
    pub fn backstepping(&self) -> &Backstepping {
        &self.inner
    }

    /// Torque (only on the edge wheel) for the reduced state `x` of the planar model.
    pub fn control(&self, x: &ReducedState) -> Result<Vector3<f64>, CubliError> {
        x.validate(self.inner.params())?;
        let k = self.axis;
        let mut g = x.g;
        g[k] = 0.0;
        let norm = g.norm();
        if norm == 0.0 {
            return Err(CubliError::NonPositive {
                field: "gravity normal to the edge",
                value: 0.0,
            });
        }
        let planar = ReducedState {
            g: g * (self.inner.params().gravity() / norm),
            p_h: Vector3::ith(k, x.p_h[k]),
            p_w: Vector3::ith(k, x.p_w[k]),
        };
        Ok(Vector3::ith(k, self.inner.torque(&planar)[k]))
    }
}

impl SampledController for EdgeBalance {
    fn sample(&mut self, y: &Measurement, _dt: f64) -> Result<Vector3<f64>, CubliError> {
        let model = self.inner.params();
        self.control(&y.state(model)?.reduced(model))
    }
}

/// The nominal model of the face → edge jump for the learner: θ is the edge wheel's speed, the
/// error the housing energy H_h at the top point (the planar jump has one degree of freedom;
/// p_hᵐ and p_hᵍ vanish identically in the plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgeJumpModel {
    model: JumpModel,
    axis: usize,
}

impl EdgeJumpModel {
    /// Nominal model of the jump of `edge` from the resting face.
    pub fn new(edge: &EdgeJump) -> Result<Self, CubliError> {
        let g0 = face_attitude().inverse_transform_vector(&Vector3::new(
            0.0,
            0.0,
            -edge.params().gravity(),
        ));
        Ok(Self {
            model: JumpModel::new(*edge.params(), &g0)?,
            axis: edge.axis,
        })
    }

    /// The model root (1.67) restricted to the edge wheel: with the ideal brake,
    /// Θw θ̄ = √(2 I_e |m⊥||g| (1 − cos φ0)) makes the cube stop exactly upright.
    pub fn nominal_wheel_speed(&self) -> f64 {
        self.root()[0]
    }
}

impl ErrorModel<1, 1> for EdgeJumpModel {
    fn root(&self) -> SVector<f64, 1> {
        SVector::<f64, 1>::new(self.model.nominal_wheel_speeds()[self.axis])
    }
    fn predict(&self, theta: &SVector<f64, 1>) -> SVector<f64, 1> {
        SVector::<f64, 1>::new(self.model.error(&self.wheel_speeds(theta))[2])
    }
    fn jacobian(&self, theta: &SVector<f64, 1>) -> SMatrix<f64, 1, 1> {
        SMatrix::<f64, 1, 1>::new(self.model.jacobian(&self.wheel_speeds(theta))[(2, self.axis)])
    }
    fn wheel_speeds(&self, theta: &SVector<f64, 1>) -> Vector3<f64> {
        Vector3::ith(self.axis, theta[0])
    }
    fn measured(&self, error: &Vector3<f64>) -> SVector<f64, 1> {
        SVector::<f64, 1>::new(error[2])
    }
}
