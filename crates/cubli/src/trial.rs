//! One jump-up experiment on the simulated plant: brake, free or guided flight to the top point,
//! optional hand-over to the balancing controller. Allocation-free.
use nalgebra::{ComplexField, UnitQuaternion, Vector3};

use crate::jump::{jump_error, pre_brake_state, EffortIntegrator, ImpactModel};
use crate::model::inclination;
use crate::{
    Backstepping, CubliError, FullState, GuidingController, Measurement, Plant, SampledController,
};

/// Timing and thresholds of a jump experiment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpConfig {
    /// Brake model of the plant.
    pub brake: ImpactModel,
    /// RK4 step of the plant (s).
    pub plant_step: f64,
    /// Sample time of the guiding controller (paper: 10 ms).
    pub guide_sample: f64,
    /// Sample time of the balancing controller (paper: 20 ms).
    pub balance_sample: f64,
    /// Inclination below which balancing takes over (not given in the paper; 5°).
    pub switch_inclination: f64,
    /// Longest flight before the trial is declared failed (s).
    pub flight_timeout: f64,
    /// Duration of balancing after the hand-over (s).
    pub balance_time: f64,
    /// Inclination the balancing phase must reach for success (0.5°).
    pub success_inclination: f64,
}

impl Default for JumpConfig {
    fn default() -> Self {
        Self {
            brake: ImpactModel::Lock,
            plant_step: 1e-3,
            guide_sample: 0.01,
            balance_sample: 0.02,
            switch_inclination: 5f64.to_radians(),
            flight_timeout: 2.0,
            balance_time: 4.0,
            success_inclination: 0.5f64.to_radians(),
        }
    }
}

/// Result of one jump.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpOutcome {
    /// Measured (p_hᵐ, p_hᵍ, H_h) at the top point.
    pub error: Vector3<f64>,
    /// E' (1.68): the error with the guiding effort removed (equal to `error` without guiding).
    pub corrected: Vector3<f64>,
    /// Time of the top point after braking (s).
    pub top_time: f64,
    /// Inclination at the top point (rad).
    pub top_inclination: f64,
    /// Hand-over time to balancing, if it happened (s).
    pub switch_time: Option<f64>,
    /// Inclination at the end of the trial (rad).
    pub final_inclination: f64,
    /// Largest |T_i| commanded (N m).
    pub peak_torque: f64,
    /// Without controllers: the top point lies inside the balancing region; with a guide only:
    /// the flight reached the region; with a balancer: it took over and settled below the
    /// success inclination without falling back onto the face.
    pub success: bool,
}

/// Controllers used in a jump; both optional. The balancer is [`Backstepping`] on a corner and
/// [`crate::edge::EdgeBalance`] on an edge.
#[derive(Debug, Clone, Copy)]
pub struct JumpControllers<'a, B = Backstepping> {
    /// Guiding (tracking) controller during the flight.
    pub guide: Option<&'a GuidingController>,
    /// Balancing controller after the hand-over.
    pub balance: Option<&'a B>,
}

impl JumpControllers<'static> {
    /// Neither guide nor balancer: the free jump, measured at its top point.
    pub const NONE: Self = Self {
        guide: None,
        balance: None,
    };
}

fn check_step(field: &'static str, value: f64) -> Result<(), CubliError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(CubliError::TimeStep { field, value })
    }
}

fn substeps(sample: f64, h: f64) -> usize {
    let n = ComplexField::round(sample / h);
    if n < 1.0 {
        1
    } else {
        n as usize
    }
}

/// Runs one jump of `plant` from rest at `attitude` with pre-brake wheel speeds `theta`.
///
/// Without a guide the top point is the first plant step at which the inclination stops
/// decreasing or, with a balancer, enters the balancing region; a balancer takes over there
/// (also at a top point short of the region) and success means it settles. With a guide it
/// is the first sample at which it stops decreasing or enters the balancing region; E and E' are
/// measured there with the plant's parameters.
pub fn jump_trial<B: SampledController + Copy>(
    plant: &Plant,
    attitude: UnitQuaternion<f64>,
    theta: &Vector3<f64>,
    controllers: JumpControllers<'_, B>,
    cfg: &JumpConfig,
) -> Result<JumpOutcome, CubliError> {
    check_step("plant_step", cfg.plant_step)?;
    check_step("guide_sample", cfg.guide_sample)?;
    check_step("balance_sample", cfg.balance_sample)?;
    if !theta.iter().all(|v| v.is_finite()) {
        return Err(CubliError::NonFinite { field: "theta" });
    }
    let p = &plant.params;
    let pre = pre_brake_state(p, attitude, theta);
    let ground = inclination(p, &pre.gravity_body(p)) + 1e-6;
    let phi_of = |x: &FullState| inclination(p, &x.gravity_body(p));
    let mut x = cfg.brake.apply(p, &pre);
    let mut t = 0.0;
    let mut effort = EffortIntegrator::default();
    let mut peak_torque: f64 = 0.0;
    let mut top: Option<(FullState, f64, EffortIntegrator)> = None;
    let mut switch_time = None;
    let mut phi = phi_of(&x);

    match controllers.guide {
        None => {
            let h = cfg.plant_step;
            while t < cfg.flight_timeout {
                if controllers.balance.is_some() && phi < cfg.switch_inclination {
                    switch_time = Some(t);
                    break;
                }
                let next = plant.step(&x, &Vector3::zeros(), h);
                let phi_next = phi_of(&next);
                if phi_next >= phi {
                    if controllers.balance.is_some() {
                        // Top point short of the region: the balancer still gets its chance.
                        switch_time = Some(t);
                    }
                    break;
                }
                x = next;
                phi = phi_next;
                t += h;
            }
            top = Some((x, t, effort));
        }
        Some(guide) => {
            let mut guide = *guide;
            let n = substeps(cfg.guide_sample, cfg.plant_step);
            let h = cfg.guide_sample / n as f64;
            while t < cfg.flight_timeout && phi <= ground {
                if phi < cfg.switch_inclination {
                    switch_time = Some(t);
                    break;
                }
                let torque = match guide.sample(&Measurement::exact(p, &x), cfg.guide_sample) {
                    Ok(torque) => torque,
                    Err(CubliError::LinearizationSingular { .. }) => break,
                    Err(e) => return Err(e),
                };
                peak_torque = peak_torque.max(torque.amax());
                let start = x;
                for _ in 0..n {
                    x = plant.step(&x, &torque, h);
                }
                let applied = plant.applied_torque(&start, &torque);
                effort.accumulate(
                    p,
                    &start.reduced(p),
                    &x.reduced(p),
                    &applied,
                    cfg.guide_sample,
                );
                t += cfg.guide_sample;
                let phi_next = phi_of(&x);
                if top.is_none() && phi_next >= phi {
                    top = Some((x, t, effort));
                }
                phi = phi_next;
            }
            if top.is_none() {
                top = Some((x, t, effort));
            }
        }
    }

    let (x_top, top_time, effort_top) = top.unwrap_or((x, t, effort));
    let error = jump_error(p, &x_top.reduced(p));
    let top_inclination = phi_of(&x_top);
    let mut final_inclination = phi;
    let mut success = match (controllers.guide, controllers.balance) {
        (None, None) => top_inclination < cfg.switch_inclination,
        _ => switch_time.is_some(),
    };
    if let (Some(mut balance), true) = (controllers.balance.copied(), success) {
        let n = substeps(cfg.balance_sample, cfg.plant_step);
        let h = cfg.balance_sample / n as f64;
        let mut tb = 0.0;
        let mut grounded = false;
        while tb < cfg.balance_time && !grounded {
            let torque = balance.sample(&Measurement::exact(p, &x), cfg.balance_sample)?;
            peak_torque = peak_torque.max(torque.amax());
            for _ in 0..n {
                x = plant.step(&x, &torque, h);
                // Falling back onto the resting face ends the trial (no ground contact model).
                grounded |= phi_of(&x) > ground;
            }
            tb += cfg.balance_sample;
        }
        final_inclination = phi_of(&x);
        success = !grounded && final_inclination < cfg.success_inclination;
    }
    Ok(JumpOutcome {
        error,
        corrected: effort_top.corrected(&error),
        top_time,
        top_inclination,
        switch_time,
        final_inclination,
        peak_torque,
        success,
    })
}
