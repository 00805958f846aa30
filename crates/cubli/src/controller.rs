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

/// The jump-up controller of Algorithm 1 after braking: the guiding controller every call
/// (call it at 10 ms) until the inclination drops below `switch_inclination`, then the balancing
/// controller every `balance_every` calls (2 gives 20 ms), holding its torque in between.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpController {
    guide: GuidingController,
    balance: Backstepping,
    switch_inclination: f64,
    balance_every: usize,
    calls_since_switch: Option<usize>,
    held: Vector3<f64>,
}

impl JumpController {
    /// Guide, then balance below `switch_inclination` (rad), updating balance every `balance_every` calls.
    pub fn new(
        guide: GuidingController,
        balance: Backstepping,
        switch_inclination: f64,
        balance_every: usize,
    ) -> Self {
        Self {
            guide,
            balance,
            switch_inclination,
            balance_every: balance_every.max(1),
            calls_since_switch: None,
            held: Vector3::zeros(),
        }
    }

    /// Whether the balancing controller has taken over.
    pub fn balancing(&self) -> bool {
        self.calls_since_switch.is_some()
    }
}

impl SampledController for JumpController {
    fn sample(&mut self, y: &Measurement, _dt: f64) -> Result<Vector3<f64>, CubliError> {
        let model = *self.guide.params();
        let x = y.state(&model)?;
        if self.calls_since_switch.is_none()
            && crate::model::inclination(&model, &x.gravity_body(&model)) < self.switch_inclination
        {
            self.calls_since_switch = Some(0);
        }
        match self.calls_since_switch {
            None => self.guide.control(&x),
            Some(k) => {
                if k % self.balance_every == 0 {
                    self.held = self.balance.control(&x.reduced(&model))?;
                }
                self.calls_since_switch = Some(k + 1);
                Ok(self.held)
            }
        }
    }
}
