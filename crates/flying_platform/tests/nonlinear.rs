//! The nonlinear rigid body linearised at hover equals the hover-linear model with the
//! same effects (an independent derivation: body-frame physics vs the paper's matrices).
#![allow(clippy::unwrap_used)]

use flying_platform::nonlinear::{Disturbance, NonlinearPlant, NonlinearState};
use flying_platform::{EffectSet, Model, PlatformParams};
use nalgebra::{DMatrix, SVector};

/// Nonlinear state index of each hover state (v, Euler angles, rates).
const MAP: [usize; 9] = [3, 4, 5, 6, 7, 8, 9, 10, 11];

fn jacobians(plant: &NonlinearPlant) -> (DMatrix<f64>, DMatrix<f64>) {
    let x0 = plant.hover_state();
    let u0 = plant.model.params.hover_input();
    let d = Disturbance::default();
    let eps = 1e-6;
    let mut a = DMatrix::zeros(9, 9);
    let mut b = DMatrix::zeros(9, 9);
    for j in 0..9 {
        let mut xp: NonlinearState = x0;
        let mut xm: NonlinearState = x0;
        xp[MAP[j]] += eps;
        xm[MAP[j]] -= eps;
        let df = (plant.derivative(&xp, &u0, &d) - plant.derivative(&xm, &u0, &d)) / (2.0 * eps);
        let mut up: SVector<f64, 9> = u0;
        let mut um: SVector<f64, 9> = u0;
        up[j] += eps;
        um[j] -= eps;
        let du = (plant.derivative(&x0, &up, &d) - plant.derivative(&x0, &um, &d)) / (2.0 * eps);
        for i in 0..9 {
            a[(i, j)] = df[MAP[i]];
            b[(i, j)] = du[MAP[i]];
        }
    }
    (a, b)
}

#[test]
fn hover_is_an_equilibrium_and_linearisation_matches_linear_model() {
    for effects in [
        "",
        "momentum_drag",
        "fan_gyroscopic",
        "momentum_drag,fan_gyroscopic,input_delay",
    ] {
        let mut params = PlatformParams::nominal();
        params.rotor_inertia = 0.0; // the linear model uses Theta instead of Theta_hat
        let model = Model::new(params, EffectSet::parse(effects).unwrap());
        let plant = NonlinearPlant::new(model.clone()).unwrap();
        let x0 = plant.hover_state();
        let f0 = plant.derivative(&x0, &model.params.hover_input(), &Disturbance::default());
        assert!(
            f0.amax() < 1e-12,
            "{effects}: hover not an equilibrium: {f0}"
        );
        let (a, b) = jacobians(&plant);
        let (al, bl) = model.hover_matrices().unwrap();
        assert!((&a - &al).amax() < 1e-6, "{effects}: A differs\n{a}\n{al}");
        assert!((&b - &bl).amax() < 1e-6, "{effects}: B differs\n{b}\n{bl}");
    }
}

#[test]
fn actuator_lag_states_follow_the_command_with_time_constant_tau() {
    let model = Model::new(
        PlatformParams::nominal(),
        EffectSet::parse("actuator_lag").unwrap(),
    );
    let tau = model.parameter("tau").unwrap();
    let plant = NonlinearPlant::new(model).unwrap();
    let mut x = plant.hover_state();
    let mut u = plant.model.params.hover_input();
    let before = u[2];
    u[2] += 1.0;
    let h = 1e-4;
    for _ in 0..(tau / h).round() as usize {
        x = plant.rk4_step(&x, &u, &Disturbance::default(), h);
    }
    // After one time constant the thrust has covered 1 - 1/e of the step.
    assert!(
        (x[14] - before - (1.0 - (-1.0f64).exp())).abs() < 1e-6,
        "{}",
        x[14] - before
    );
}
