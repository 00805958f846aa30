//! The slow-actuator tuning: closed-loop eigenvalues of the sampled hover loop with a
//! first-order thrust lag, checked against closed-loop simulation (stable runs settle,
//! unstable ones diverge), and the linear feedback map against the controller itself.
#![allow(clippy::unwrap_used)]

use flying_platform::control::{Measurement, Setpoint};
use flying_platform::loop_analysis::{feedback_gain, spectral_radius};
use flying_platform::{
    simulate, ActuatorLimits, CascadedController, Dynamics, Effect, EffectSet, Error, Model,
    PlatformParams, Scenario, SimConfig, Tuning,
};
use nalgebra::{DVector, Vector3};
use proptest::prelude::*;

/// Truth with a thrust lag `tau` (s) and 15 ms in the loop: the low-complexity model, or with
/// `augmented` the REF truth (momentum drag and fan gyroscopic torque).
fn lagged_truth(tau: f64, augmented: bool) -> Model {
    let mut effects = vec![Effect::ActuatorLag, Effect::InputDelay];
    if augmented {
        effects.extend([Effect::MomentumDrag, Effect::FanGyroscopic]);
    }
    let mut m = Model::new(PlatformParams::default(), EffectSet::from_effects(&effects));
    m.set_parameter("td", 0.015).unwrap();
    m.set_parameter("tau", tau).unwrap();
    m
}

fn controller(tuning: &Tuning) -> CascadedController {
    CascadedController::with_tuning(
        &PlatformParams::nominal(),
        tuning,
        ActuatorLimits::default(),
    )
    .unwrap()
}

#[test]
fn paper_tuning_gives_the_papers_gains_and_the_specs_rate_poles() {
    // Spec §5.2 [paper]: d = 1 everywhere, w_xy = 3, p_xy = 1, w_z = 2, p_z = 2 rad/s.
    let paper = controller(&Tuning::paper());
    let g = paper.gains;
    assert_eq!(
        (g.d_xy, g.w_xy, g.p_xy, g.d_z, g.w_z, g.p_z),
        (1.0, 3.0, 1.0, 1.0, 2.0, 2.0)
    );
    // Spec §5.1 [derived]: Q = 512 I on the nominal structure (l3 = 0.079) puts the continuous
    // rate-loop poles at -50.1, -50.1, -29.1 rad/s (printed to 0.1 rad/s).
    let mut poles: Vec<f64> = paper
        .inner
        .closed_loop()
        .complex_eigenvalues()
        .iter()
        .map(|p| {
            assert!(p.im.abs() < 1e-9, "complex rate pole {p}");
            p.re
        })
        .collect();
    poles.sort_by(f64::total_cmp);
    for (pole, spec) in poles.iter().zip([-50.1, -50.1, -29.1]) {
        assert!((pole - spec).abs() <= 0.05, "poles {poles:?}");
    }
}

#[test]
fn eigenvalues_agree_with_the_latency_limit_of_the_paper_tuning() {
    // Pure delay, no lag: the simulation test `latency_limit_is_detected` flies 20 ms and
    // diverges at 45 ms; the sampled-loop eigenvalues say the same.
    let paper = controller(&Tuning::paper());
    let mut truth = Model::augmented();
    truth.set_parameter("td", 0.020).unwrap();
    assert!(spectral_radius(&paper, &truth, 50.0).unwrap() < 1.0);
    truth.set_parameter("td", 0.045).unwrap();
    assert!(spectral_radius(&paper, &truth, 50.0).unwrap() > 1.0);
}

#[test]
fn slow_actuator_tuning_is_stable_up_to_80_ms_of_lag() {
    let paper = controller(&Tuning::paper());
    let slow = controller(&Tuning::slow_actuators());
    for augmented in [false, true] {
        for tau in [0.01, 0.03, 0.06, 0.07, 0.08] {
            let rho = spectral_radius(&slow, &lagged_truth(tau, augmented), 50.0).unwrap();
            assert!(
                rho < 0.995,
                "augmented {augmented}, tau {tau}: spectral radius {rho}"
            );
        }
        // The paper's bandwidths are unstable with 60 ms or more of lag.
        for tau in [0.06, 0.08] {
            let rho = spectral_radius(&paper, &lagged_truth(tau, augmented), 50.0).unwrap();
            assert!(
                rho > 1.0,
                "paper tuning, augmented {augmented}, tau {tau}: {rho}"
            );
        }
    }
}

fn hover(tuning: &Tuning, tau: f64) -> flying_platform::Result<flying_platform::SimLog> {
    let mut cfg = SimConfig::reference(lagged_truth(tau, true), Dynamics::Linear, 11)?;
    cfg.controller = controller(tuning);
    simulate(
        &cfg,
        &Scenario {
            samples: 3000,
            ..Scenario::default()
        },
    )
}

#[test]
fn slow_actuator_tuning_hovers_with_80_ms_of_lag_and_the_paper_tuning_does_not() {
    let log = hover(&Tuning::slow_actuators(), 0.08).unwrap();
    let worst = log
        .position
        .iter()
        .skip(500)
        .map(|p| Vector3::from(*p).norm())
        .fold(0.0, f64::max);
    assert!(worst < 0.2, "largest hover error {worst} m");
    assert_eq!(log.saturated_samples, 0);
    match hover(&Tuning::paper(), 0.08) {
        Err(Error::Diverged { .. }) => {}
        other => panic!(
            "the paper tuning must diverge with 80 ms of lag, got {:?}",
            other.map(|l| l.t.len())
        ),
    }
}

#[test]
fn tuning_names_parse_and_unknown_names_are_named() {
    assert_eq!(Tuning::from_name("paper").unwrap(), Tuning::paper());
    assert_eq!(
        Tuning::from_name("slow-actuators").unwrap(),
        Tuning::slow_actuators()
    );
    let msg = Tuning::from_name("fast").unwrap_err().to_string();
    assert!(msg.contains("tuning") && msg.contains("fast"), "{msg}");
    let bad = Tuning {
        rate_weight: -1.0,
        ..Tuning::paper()
    };
    let msg = CascadedController::with_tuning(
        &PlatformParams::nominal(),
        &bad,
        ActuatorLimits::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(msg.contains("rate_weight"), "{msg}");
}

proptest! {
    /// The linear map of `loop_analysis` is the controller: `u - trim = F m` for any
    /// measurement (yaw inside (-pi, pi) so that no wrapping occurs).
    #[test]
    fn feedback_gain_reproduces_the_controller(m in proptest::collection::vec(-1.0f64..1.0, 12)) {
        let c = controller(&Tuning::slow_actuators());
        let y = Measurement {
            position: Vector3::new(m[0], m[1], m[2]),
            velocity: Vector3::new(m[3], m[4], m[5]),
            attitude: Vector3::new(m[6], m[7], m[8]),
            rates: Vector3::new(m[9], m[10], m[11]),
        };
        let (rates_des, fz) = c.outer(&y, &Setpoint::default());
        let direct = c.inner(&y.rates, &rates_des, fz) - c.trim;
        let linear = feedback_gain(&c) * DVector::from_column_slice(&m);
        for i in 0..9 {
            prop_assert!((direct[i] - linear[i]).abs() <= 1e-9 * (1.0 + direct[i].abs()));
        }
    }
}
