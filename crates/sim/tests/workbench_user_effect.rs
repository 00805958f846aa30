//! A user-defined effect (the `workbench::Effect` trait) is fitted like a built-in one: a
//! linear drag on the vertical velocity, fitted to data whose truth carries momentum drag,
//! recovers the truth's vz-vz entry of A (the flying_platform model, computed independently).
//! The data are the files `stabilis sim flying-platform --scenario sysid` writes, the same as
//! py/tests/test_workbench.py fits with a Python callable.
#![allow(clippy::unwrap_used)]
use std::sync::Arc;

use flying_platform::{Effect as FpEffect, EffectSet, Model, PlatformParams};
use sim::cli::SimSystem;
use sim::systems::flying_platform::FlyingPlatform;
use workbench::load;
use workbench::model::{Effect, Parameter, StateSpace};
use workbench::{EstimatorChoice, ModelStructure, Workbench};

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
    // The paper's design and amplitudes, linear hover dynamics, seed 12.
    let tmp = tempfile::Builder::new()
        .prefix("sim-user-effect-")
        .tempdir()
        .unwrap();
    let dir = tmp.path().join("sysid");
    let out = dir.display().to_string();
    let args = [
        "--scenario=sysid",
        "--effects=momentum_drag",
        "--dynamics=linear",
        "--lambda=1.2,0.8,2.0",
        "--seed=12",
        "--out",
        &out,
    ];
    SimSystem::parse_args("flying-platform", args)
        .unwrap()
        .run()
        .unwrap();
    let structure = Arc::new(FlyingPlatform::default());
    let data = load::load(
        structure.system(),
        &structure.inputs(),
        &structure.outputs(),
        std::slice::from_ref(&dir),
    )
    .unwrap();
    drop(tmp);
    let base = Workbench::new(structure, data, EstimatorChoice::Auto).unwrap();
    let before = base.compare().unwrap();
    let mut wb = base.clone();
    wb.add_user_effect(Arc::new(VerticalDrag)).unwrap();
    let after = wb.compare().unwrap();
    let d = after.params.iter().find(|p| p.name == "vz_drag.d").unwrap();
    println!("vz_drag.d = {} +- {:?} (truth {expected})", d.value, d.std);
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
