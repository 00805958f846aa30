//! A user-defined effect (the `workbench::Effect` trait) is fitted like a built-in one: a
//! linear drag on the vertical velocity, fitted to data whose truth carries momentum drag,
//! recovers the truth's vz-vz entry of A (the flying_platform model, computed independently).
#![allow(clippy::unwrap_used)]
use std::sync::Arc;

use flying_platform::{
    Dynamics, Effect as FpEffect, EffectSet, ExperimentDesign, Model, PlatformParams, SimConfig,
};
use sim::workbench::flying_platform::{dataset_from_experiments, FlyingPlatform};
use sim::workbench::model::{Effect, Parameter, StateSpace};
use sim::workbench::{EstimatorChoice, Workbench};

/// `vz' += -d vz`: linear vertical drag, `d` in 1/s.
#[derive(Debug)]
struct VerticalDrag;

impl Effect for VerticalDrag {
    fn name(&self) -> &str {
        "vz_drag"
    }
    fn description(&self) -> &str {
        "linear drag on the vertical velocity"
    }
    fn parameters(&self) -> Vec<Parameter> {
        vec![Parameter::new("d", 0.1, 0.0, 50.0, "1/s")]
    }
    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> sim::Result<()> {
        ss.a[(2, 2)] -= theta[0];
        Ok(())
    }
}

#[test]
fn user_defined_vertical_drag_is_fitted_to_the_truths_value() {
    let truth = Model::new(
        PlatformParams::default(),
        EffectSet::from_effects(&[FpEffect::MomentumDrag]),
    );
    let (a_truth, _) = truth.hover_matrices().unwrap();
    let expected = -a_truth[(2, 2)];
    assert!(expected > 0.5, "truth vz drag {expected}");
    let config = SimConfig::reference(truth, Dynamics::Linear, 12).unwrap();
    let design = ExperimentDesign::paper(12).unwrap();
    let runs = flying_platform::run_experiments(&config, &design).unwrap();
    let data = dataset_from_experiments(&runs, &design).unwrap();
    let base = Workbench::new(
        Arc::new(FlyingPlatform::default()),
        data,
        EstimatorChoice::Auto,
    )
    .unwrap();
    let before = base.compare().unwrap();
    let mut wb = base.clone();
    wb.add_user_effect(Arc::new(VerticalDrag)).unwrap();
    let after = wb.compare().unwrap();
    let d = after.params.iter().find(|p| p.name == "vz_drag.d").unwrap();
    let rel = (d.value - expected).abs() / expected;
    assert!(
        rel < 0.10,
        "fitted d {} vs truth {expected} ({:.1}%)",
        d.value,
        100.0 * rel
    );
    assert!(
        after.cost < before.cost,
        "cost {} -> {}",
        before.cost,
        after.cost
    );
    // Adding the same effect twice is refused by name.
    let msg = wb
        .add_user_effect(Arc::new(VerticalDrag))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("vz_drag"), "{msg}");
}
