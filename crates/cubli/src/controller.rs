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

/// The jump-up controller of Algorithm 1 after braking: the guide every call (call it at 10 ms;
/// [`NoControl`] for a free flight) until the inclination of the model `model` drops below
/// `switch_inclination`, then the balancer every `balance_every` calls (2 gives 20 ms), holding
/// its torque in between. Corner: [`GuidingController`] and [`Backstepping`]; edge: [`NoControl`]
/// and [`crate::edge::EdgeBalance`] with the edge's planar model and
/// [`JumpController::hand_over_at_top`], as in [`crate::jump_trial`] without a guide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpController<G = GuidingController, B = Backstepping> {
    model: Params,
    guide: G,
    balance: B,
    switch_inclination: f64,
    balance_every: usize,
    calls_since_switch: Option<usize>,
    held: Vector3<f64>,
    at_top: bool,
    last_inclination: f64,
}

impl<G: SampledController, B: SampledController> JumpController<G, B> {
    /// Guide, then balance below `switch_inclination` (rad) of `model`, updating the balancer
    /// every `balance_every` calls.
    pub fn new(
        model: Params,
        guide: G,
        balance: B,
        switch_inclination: f64,
        balance_every: usize,
    ) -> Self {
        Self {
            model,
            guide,
            balance,
            switch_inclination,
            balance_every: balance_every.max(1),
            calls_since_switch: None,
            held: Vector3::zeros(),
            at_top: false,
            last_inclination: f64::INFINITY,
        }
    }

    /// Also hand over at the first sample whose measured inclination is not below the previous
    /// one (the top point of a free flight that stops short of the region).
    pub fn hand_over_at_top(mut self) -> Self {
        self.at_top = true;
        self
    }

    /// Whether the balancing controller has taken over.
    pub fn balancing(&self) -> bool {
        self.calls_since_switch.is_some()
    }
}

impl<G: SampledController, B: SampledController> SampledController for JumpController<G, B> {
    fn sample(&mut self, y: &Measurement, dt: f64) -> Result<Vector3<f64>, CubliError> {
        let x = y.state(&self.model)?;
        let phi = crate::model::inclination(&self.model, &x.gravity_body(&self.model));
        let top = self.at_top && phi >= self.last_inclination;
        self.last_inclination = phi;
        if self.calls_since_switch.is_none() && (phi < self.switch_inclination || top) {
            self.calls_since_switch = Some(0);
        }
        match self.calls_since_switch {
            None => self.guide.sample(y, dt),
            Some(k) => {
                if k % self.balance_every == 0 {
                    self.held = self.balance.sample(y, dt * self.balance_every as f64)?;
                }
                self.calls_since_switch = Some(k + 1);
                Ok(self.held)
            }
        }
    }
}
