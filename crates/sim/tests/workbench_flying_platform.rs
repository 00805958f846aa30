//! Acceptance of the workbench on the flying platform's closed-loop 18-experiment
//! identification runs (simulated by the flying_platform crate with hidden effects).
#![allow(clippy::unwrap_used)]
use std::sync::Arc;

use flying_platform::{
    ActuatorLimits, CascadedController, Dynamics, Effect, EffectSet, ExperimentDesign, Model,
    PlatformParams, SimConfig, Tuning,
};
use sim::systems::flying_platform::{dataset_from_experiments, FlyingPlatform};
use workbench::{Dataset, Estimator, EstimatorChoice, Verdict, Workbench};

fn data(effects: &[(Effect, &[(&str, f64)])], seed: u64) -> (Dataset, Model) {
    data_tuned(
        effects,
        seed,
        &Tuning::paper(),
        ExperimentDesign::paper(seed).unwrap(),
    )
}

/// Experiments flown with the controller tuned by `tuning`.
fn data_tuned(
    effects: &[(Effect, &[(&str, f64)])],
    seed: u64,
    tuning: &Tuning,
    design: ExperimentDesign,
) -> (Dataset, Model) {
    let mut set = EffectSet::none();
    for (e, values) in effects {
        set.enable(*e);
        for (name, v) in *values {
            set.set(name, *v).unwrap();
        }
    }
    let truth = Model::new(PlatformParams::default(), set);
    let mut config = SimConfig::reference(truth.clone(), Dynamics::Linear, seed).unwrap();
    config.controller = CascadedController::with_tuning(
        &PlatformParams::nominal(),
        tuning,
        ActuatorLimits::default(),
    )
    .unwrap();
    let runs = flying_platform::run_experiments(&config, &design).unwrap();
    (dataset_from_experiments(&runs, &design).unwrap(), truth)
}

fn discover(effects: &[(Effect, &[(&str, f64)])], seed: u64) -> (workbench::Discovery, Model) {
    let (d, truth) = data(effects, seed);
    (workbench_discover(d), truth)
}

/// Experiments flown with the slow-actuator tuning and the within-limits excitation (with a
/// 60-80 ms lag the paper's amplitudes drive the clipped loop into a limit cycle).
fn discover_slow(effects: &[(Effect, &[(&str, f64)])], seed: u64) -> (workbench::Discovery, Model) {
    let (d, truth) = data_tuned(
        effects,
        seed,
        &Tuning::slow_actuators(),
        ExperimentDesign::within_limits(seed).unwrap(),
    );
    (workbench_discover(d), truth)
}

fn workbench_discover(d: Dataset) -> workbench::Discovery {
    let wb = Workbench::new(
        Arc::new(FlyingPlatform::default()),
        d,
        EstimatorChoice::Auto,
    )
    .unwrap();
    assert_eq!(
        wb.frf().estimator,
        workbench::Estimator::InstrumentalVariable
    );
    wb.discover().unwrap()
}

/// Relative error of each named fitted parameter against the truth, checked against `tol`.
fn check_params(d: &workbench::Discovery, truth: &Model, tol: &[(&str, f64)]) {
    let last = d.steps.last().unwrap();
    for (name, t) in tol {
        let fitted = last.params.iter().find(|p| p.name == *name).unwrap();
        let true_value = truth.parameter(name).unwrap();
        let rel = (fitted.value - true_value).abs() / true_value.abs();
        assert!(
            rel <= *t,
            "{name}: fitted {} +- {:?}, truth {true_value}, error {:.1}% > {:.0}%",
            fitted.value,
            fitted.std,
            100.0 * rel,
            100.0 * t
        );
    }
}

fn explained(d: &workbench::Discovery) {
    assert!(
        matches!(d.conclusion.verdict, Verdict::ExplainedToNoiseLevel { .. }),
        "{}",
        d.conclusion.verdict.sentence()
    );
    assert!(!d.conclusion.unexplained);
}

#[test]
fn paper_truth_finds_drag_then_gyroscopic_and_recovers_parameters() {
    let (d, truth) = discover(
        &[(Effect::MomentumDrag, &[]), (Effect::FanGyroscopic, &[])],
        1,
    );
    assert_eq!(d.conclusion.found, ["momentum_drag", "fan_gyroscopic"]);
    explained(&d);
    let total = d.steps.last().unwrap().reduction_percent;
    assert!(total >= 95.0, "total cost reduction {total}%");
    // Drag alone carries almost all of it; the gyroscopic step a small further part.
    let drag = d.steps[1].reduction_percent;
    assert!(
        drag >= 90.0 && total - drag > 0.0 && total - drag < 10.0,
        "drag {drag}%, total {total}%"
    );
    // In the time domain the drag step improves the 10-step prediction of every channel; the
    // hover model with drag is open-loop unstable and the one without has integrators, so
    // neither free run is scored.
    let (t0, t1) = (&d.steps[0].time_fit, &d.steps[1].time_fit);
    for ((o, before), (_, after)) in t0.prediction.iter().zip(&t1.prediction) {
        assert!(after > before, "{o}: {before} -> {after}");
    }
    assert!(t1.spectral_radius > 1.0 && t1.simulation.is_none());
    assert!((t0.spectral_radius - 1.0).abs() < 1e-9 && t0.simulation.is_none());
    // Tolerances of spec AT-23 (10% for the well-determined drag parameters).
    check_params(
        &d,
        &truth,
        &[
            ("c_alpha1", 0.10),
            ("c_alpha2", 0.10),
            ("l_alpha2", 0.10),
            ("l_alpha4", 0.10),
            ("l_alpha3", 0.20),
            ("l_alpha1", 0.35),
            ("c_omega_t0", 0.15),
        ],
    );
}

#[test]
fn low_complexity_truth_finds_nothing() {
    for seed in [2, 7] {
        let (d, _) = discover(&[], seed);
        assert!(
            d.conclusion.found.is_empty(),
            "seed {seed}: found {:?}",
            d.conclusion.found
        );
        explained(&d);
    }
}

#[test]
fn least_squares_on_closed_loop_fakes_drag() {
    // The paper's estimator Y U^+ is biased by feedback of noise (spec AT-25): on data without
    // drag, adding drag "explains" a large part of the cost; the instrumental variable does not.
    let (d, _) = data(&[], 2);
    let mut reductions = Vec::new();
    for choice in [
        EstimatorChoice::LeastSquares,
        EstimatorChoice::InstrumentalVariable,
    ] {
        let wb = Workbench::new(Arc::new(FlyingPlatform::default()), d.clone(), choice).unwrap();
        let base = wb.compare().unwrap();
        let mut with = wb.clone();
        with.add("momentum_drag").unwrap();
        let drag = with.compare().unwrap();
        reductions.push(100.0 * (1.0 - drag.cost / base.cost));
    }
    assert!(reductions[0] > 20.0, "least squares: {reductions:?}");
    assert!(
        reductions[1] < 10.0,
        "instrumental variable: {reductions:?}"
    );
}

#[test]
fn drag_alone_is_found_alone() {
    let (d, truth) = discover(&[(Effect::MomentumDrag, &[])], 3);
    assert_eq!(d.conclusion.found, ["momentum_drag"]);
    explained(&d);
    check_params(
        &d,
        &truth,
        &[
            ("c_alpha1", 0.10),
            ("c_alpha2", 0.10),
            ("l_alpha2", 0.10),
            ("l_alpha4", 0.10),
        ],
    );
}

#[test]
fn larger_fan_momentum_alone_is_found_alone() {
    let (d, truth) = discover(&[(Effect::FanGyroscopic, &[("c_omega_t0", 0.1)])], 4);
    assert_eq!(d.conclusion.found, ["fan_gyroscopic"]);
    explained(&d);
    check_params(&d, &truth, &[("c_omega_t0", 0.05)]);
}

#[test]
fn actuator_lag_alone_is_found_alone() {
    // 30 ms: with the paper's controller a lag of 60-80 ms inside the loop destabilises the
    // simulated hover (the flying_platform simulator reports the divergence).
    let (d, truth) = discover(&[(Effect::ActuatorLag, &[("tau", 0.03)])], 5);
    assert_eq!(d.conclusion.found, ["actuator_lag"]);
    explained(&d);
    check_params(&d, &truth, &[("tau", 0.15)]);
}

#[test]
fn drag_and_lag_together_are_both_found() {
    let (d, truth) = discover(
        &[
            (Effect::MomentumDrag, &[]),
            (Effect::ActuatorLag, &[("tau", 0.03)]),
        ],
        6,
    );
    assert_eq!(d.conclusion.found, ["momentum_drag", "actuator_lag"]);
    explained(&d);
    check_params(
        &d,
        &truth,
        &[("c_alpha1", 0.10), ("c_alpha2", 0.10), ("tau", 0.15)],
    );
}

#[test]
fn slow_actuator_lag_alone_is_found_alone() {
    // 70 ms of thrust lag: flown with the slow-actuator tuning (the paper's diverges).
    let (d, truth) = discover_slow(&[(Effect::ActuatorLag, &[("tau", 0.07)])], 8);
    assert_eq!(d.conclusion.found, ["actuator_lag"]);
    explained(&d);
    check_params(&d, &truth, &[("tau", 0.15)]);
}

#[test]
fn drag_and_slow_actuator_lag_are_both_found() {
    let (d, truth) = discover_slow(
        &[
            (Effect::MomentumDrag, &[]),
            (Effect::ActuatorLag, &[("tau", 0.07)]),
        ],
        9,
    );
    let mut found = d.conclusion.found.clone();
    found.sort();
    assert_eq!(found, ["actuator_lag", "momentum_drag"]);
    explained(&d);
    check_params(
        &d,
        &truth,
        &[("c_alpha1", 0.10), ("c_alpha2", 0.10), ("tau", 0.15)],
    );
}

/// Within-limits amplitudes (no command clipped): the gyroscopic step is small against the
/// total (3-6 % of the remaining cost, close to the noise) but its nested F test and its cost
/// reduction stand above the noise in most seeds. Over seeds 1-4 drag is always found and the
/// gyroscopic torque in 3 of 4 (seed 3 misses it: its step, 33 cost units, is below the noise
/// sd of 37); a miss rate above one in four fails. Nothing else is ever claimed.
#[test]
fn within_limits_paper_fan_inertia_finds_gyroscopic_in_most_seeds() {
    let seeds = [1, 2, 3, 4];
    let mut found_gyroscopic = 0;
    for seed in seeds {
        let (data, _) = data_tuned(
            &[(Effect::MomentumDrag, &[]), (Effect::FanGyroscopic, &[])],
            seed,
            &Tuning::paper(),
            ExperimentDesign::within_limits(seed).unwrap(),
        );
        let d = workbench_discover(data);
        assert_eq!(
            d.conclusion.found[0], "momentum_drag",
            "seed {seed}: {:?}",
            d.conclusion.found
        );
        assert!(
            d.conclusion.found[1..]
                .iter()
                .all(|e| e == "fan_gyroscopic"),
            "seed {seed}: {:?}",
            d.conclusion.found
        );
        explained(&d);
        if d.conclusion.found.len() == 2 {
            found_gyroscopic += 1;
            let total = d.steps.last().unwrap().reduction_percent;
            assert!(total >= 95.0, "seed {seed}: total cost reduction {total}%");
        }
    }
    println!(
        "fan_gyroscopic found in {found_gyroscopic} of {} seeds",
        seeds.len()
    );
    assert!(
        found_gyroscopic >= 3,
        "fan_gyroscopic found in only {found_gyroscopic} of {} seeds",
        seeds.len()
    );
}

/// The same flights with the fan's angular momentum at a quarter of the paper's: its effect
/// is below the noise and it is not claimed.
#[test]
fn within_limits_quarter_fan_inertia_leaves_gyroscopic_out() {
    let (data, _) = data_tuned(
        &[
            (Effect::MomentumDrag, &[]),
            (Effect::FanGyroscopic, &[("c_omega_t0", 0.018 / 4.0)]),
        ],
        1,
        &Tuning::paper(),
        ExperimentDesign::within_limits(1).unwrap(),
    );
    let d = workbench_discover(data);
    assert_eq!(d.conclusion.found, ["momentum_drag"]);
    explained(&d);
}

/// Clean within-limits flights: with the noise estimated from the estimate's own residual the
/// low-complexity truth faked a drag finding (cost 1272 against a reference mean of 1119);
/// with it from the model's residual nothing is found.
#[test]
fn within_limits_low_complexity_truth_finds_nothing() {
    for seed in [1, 2] {
        let (data, _) = data_tuned(
            &[],
            seed,
            &Tuning::paper(),
            ExperimentDesign::within_limits(seed).unwrap(),
        );
        let d = workbench_discover(data);
        assert!(
            d.conclusion.found.is_empty(),
            "seed {seed}: found {:?}",
            d.conclusion.found
        );
        explained(&d);
    }
}

/// Logs without the excitation: least squares on the periodic records, and H1 Welch on the
/// same records without their periodic layout (a DESIGN.md CSV), use the input as their own
/// instrument, which the loop's feedback of noise biases at the lowest lines. On a clean
/// closed loop the effects the discovery adds to absorb that bias are reported as tentative
/// with the reason, never as found.
#[test]
fn clean_closed_loop_without_excitation_finds_nothing() {
    let (mut periodic, _) = data(&[], 2);
    for e in &mut periodic.experiments {
        e.r = None;
    }
    let mut welch = periodic.clone();
    for e in &mut welch.experiments {
        e.periodic = None;
    }
    for (data, estimator) in [
        (periodic, Estimator::LeastSquares),
        (welch, Estimator::H1Welch),
    ] {
        let wb = Workbench::new(
            Arc::new(FlyingPlatform::default()),
            data,
            EstimatorChoice::Auto,
        )
        .unwrap();
        assert_eq!(wb.frf().estimator, estimator);
        let d = wb.discover().unwrap();
        assert!(
            d.conclusion.found.is_empty(),
            "{estimator:?}: found {:?}",
            d.conclusion.found
        );
        // Before this rule both listed drag under `found` (least squares: momentum_drag;
        // H1 Welch: momentum_drag, actuator_lag), with a structured misfit remaining. What
        // absorbs the bias first depends on the band: with the band read from the inputs'
        // power (no excitation logged) H1 Welch starts with input_delay.
        assert!(
            !d.conclusion.tentative.is_empty(),
            "{estimator:?}: nothing tentative"
        );
        let why = d.tentative_sentence().unwrap();
        assert!(
            why.contains("biased under feedback") && why.contains("/flying_platform/excitation"),
            "{why}"
        );
        // The tentative sentence names the bias, so the verdict does not repeat it (it names
        // the warnings the tentative reasons do not give: here parameters fitted 40-80 times
        // from their documented values); with nothing added (compare) the verdict itself
        // names the bias (it did not: a misfit read as one no candidate explains).
        let sentence = d.conclusion.verdict_sentence();
        assert!(!sentence.contains("biased under feedback"), "{sentence}");
        let verdict = wb.compared().unwrap().conclusion.verdict_sentence();
        assert!(
            verdict.contains("; but the FRF estimator is")
                && verdict.contains("biased under feedback")
                && verdict.contains("/flying_platform/excitation"),
            "{verdict}"
        );
    }
}
