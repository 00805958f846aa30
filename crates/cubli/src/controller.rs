//! What a controller sees (sensor readings) and the common interface of sampled controllers.
use nalgebra::{UnitQuaternion, Vector3};

use crate::{Backstepping, CubliError, FullState, GuidingController, IntegralBackstepping, Params};

/// Sensor readings: attitude (from the estimator), housing rates (gyroscopes) and wheel rates
/// relative to the housing (Hall sensors). Controllers rebuild the momenta with their own model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Estimated attitude R_IK.
    pub attitude: UnitQuaternion<f64>,
    /// Measured housing body rates (rad/s).
    pub omega_h: Vector3<f64>,
    /// Measured wheel rates relative to the housing (rad/s).
    pub omega_w: Vector3<f64>,
}

impl Measurement {
    /// Noise-free reading of the true state `x` of a plant with parameters `plant`.
    pub fn exact(plant: &Params, x: &FullState) -> Self {
        Self {
            attitude: x.attitude,
            omega_h: x.omega_h(plant),
            omega_w: x.omega_w(plant),
        }
    }

    /// Unit gravity direction in body coordinates, Rᵀ (0, 0, −1).
    pub fn gravity_direction(&self) -> Vector3<f64> {
        self.attitude
            .inverse_transform_vector(&Vector3::new(0.0, 0.0, -1.0))
    }

    /// The state as a controller with model `model` reconstructs it.
    pub fn state(&self, model: &Params) -> Result<FullState, CubliError> {
        let x = FullState::from_velocities(model, self.attitude, &self.omega_h, &self.omega_w);
        x.validate()?;
        Ok(x)
    }
}

/// A controller run at a fixed sample time with zero-order hold.
pub trait SampledController {
    /// Torque command for the reading `y`; `dt` is the sample time (for integrators).
    fn sample(&mut self, y: &Measurement, dt: f64) -> Result<Vector3<f64>, CubliError>;
}

impl SampledController for Backstepping {
    fn sample(&mut self, y: &Measurement, _dt: f64) -> Result<Vector3<f64>, CubliError> {
        let x = y.state(self.params())?.reduced(self.params());
        self.control(&x)
    }
}

impl SampledController for IntegralBackstepping {
    fn sample(&mut self, y: &Measurement, dt: f64) -> Result<Vector3<f64>, CubliError> {
        let model = *self.params();
        let x = y.state(&model)?.reduced(&model);
        let t = self.control(&x)?;
        self.advance(&x, dt);
        Ok(t)
    }
}

impl SampledController for GuidingController {
    fn sample(&mut self, y: &Measurement, _dt: f64) -> Result<Vector3<f64>, CubliError> {
        let x = y.state(self.params())?;
        self.control(&x)
    }
}

/// Zero torque: the open-loop plant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NoControl;

impl SampledController for NoControl {
    fn sample(&mut self, _y: &Measurement, _dt: f64) -> Result<Vector3<f64>, CubliError> {
        Ok(Vector3::zeros())
    }
}
