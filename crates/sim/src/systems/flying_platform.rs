//! The flying platform in the workbench: its hover-linear model with the crate's switchable
//! effects as a [`ModelStructure`], and its simulated identification runs as a [`Dataset`].
//!
//! Free base parameters are the structured input matrix (`T11`, `b_z = T12/m`, `V1`,
//! `T22/I3`) and the lever arm `l3`; mass, `l1` and `I1` stay at their documented values
//! because the FRF only sees ratios such as `T11/m` and `l3/I1` (spec §6.5).
use flying_platform::{
    Effect as FpEffect, EffectSet, InputMatrix, Model as FpModel, PlatformParams,
};
use nalgebra::DMatrix;

use workbench::dataset::{Dataset, Experiment, Periodic};
use workbench::model::{ModelStructure, Parameter, StateSpace};
use workbench::{Result, SimError};

/// Output channels of the identification (DESIGN.md names).
pub const OUTPUTS: [&str; 6] = ["vx", "vy", "vz", "wx", "wy", "wz"];

/// The flying platform's hover-linear structure around documented vehicle parameters.
#[derive(Debug, Clone)]
pub struct FlyingPlatform {
    params: PlatformParams,
}

impl Default for FlyingPlatform {
    /// The paper's appendix values (Table 3) as documented values.
    fn default() -> Self {
        Self {
            params: PlatformParams::default(),
        }
    }
}

impl FlyingPlatform {
    /// A structure around the given vehicle parameters.
    pub fn new(params: PlatformParams) -> Self {
        Self { params }
    }

    fn effects(enabled: &[String]) -> Result<Vec<FpEffect>> {
        let mut list = Vec::with_capacity(enabled.len());
        for name in enabled {
            list.push(
                FpEffect::from_name(name)
                    .map_err(|e| SimError::domain("flying-platform effect", e))?,
            );
        }
        // The crate orders effect parameters canonically, whatever the order of enabling.
        list.sort();
        Ok(list)
    }

    fn base_parameters(&self) -> Vec<Parameter> {
        let values = self.params.input.to_vector();
        let mut out: Vec<Parameter> = InputMatrix::parameter_names()
            .into_iter()
            .zip(values)
            .map(|(name, v)| {
                let (bound, unit) = if name.starts_with("t22") {
                    (10.0, "1/(kg m)")
                } else if name.starts_with("bz") {
                    (1.0, "1/kg")
                } else {
                    (3.0, "1")
                };
                Parameter::new(name, v, -bound, bound, unit)
            })
            .collect();
        out.push(Parameter::new("l3", self.params.l3, -0.5, 0.5, "m"));
        out
    }
}

impl ModelStructure for FlyingPlatform {
    fn system(&self) -> &str {
        "flying_platform"
    }

    fn inputs(&self) -> Vec<String> {
        flying_platform::INPUT_NAMES
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    fn outputs(&self) -> Vec<String> {
        OUTPUTS.iter().map(|s| s.to_string()).collect()
    }

    fn effects(&self) -> Vec<String> {
        FpEffect::ALL.iter().map(|e| e.name().to_string()).collect()
    }

    fn describe(&self, effect: &str) -> String {
        match effect {
            "momentum_drag" => "velocity-proportional forces and moments of the ducts".into(),
            "fan_gyroscopic" => "gyroscopic torque of three fans spinning the same way".into(),
            "actuator_lag" => "first-order lag from thrust command to thrust".into(),
            "input_delay" => "transport delay of all inputs".into(),
            other => format!("unknown effect {other}"),
        }
    }

    fn fixed(&self) -> Vec<(String, f64, String)> {
        let why = "only ratios (T11/m, l3/I1, l1 V1/I1) appear in the FRF";
        vec![
            ("mass".into(), self.params.mass, why.into()),
            ("l1".into(), self.params.l1, why.into()),
            ("i1".into(), self.params.i1, why.into()),
        ]
    }

    fn parameters(&self, enabled: &[String]) -> Result<Vec<Parameter>> {
        let mut out = self.base_parameters();
        for e in Self::effects(enabled)? {
            out.extend(
                e.params()
                    .iter()
                    .map(|p| Parameter::new(p.name, p.default, p.lower, p.upper, p.unit)),
            );
        }
        Ok(out)
    }

    fn state_space(&self, enabled: &[String], theta: &[f64]) -> Result<StateSpace> {
        let n_base = InputMatrix::parameter_names().len() + 1;
        if theta.len() < n_base {
            return Err(SimError::LengthMismatch {
                what: "flying-platform parameter vector".into(),
                expected: n_base,
                found: theta.len(),
            });
        }
        let mut params = self.params.clone();
        params
            .input
            .set_vector(&theta[..n_base - 1])
            .map_err(|e| SimError::domain("flying-platform input matrix", e))?;
        params.l3 = theta[n_base - 1];
        let mut model = FpModel::new(params, EffectSet::from_effects(&Self::effects(enabled)?));
        model
            .set_parameter_vector(&theta[n_base..])
            .map_err(|e| SimError::domain("flying-platform effect parameters", e))?;
        let ss = model
            .state_space()
            .map_err(|e| SimError::domain("flying-platform state space", e))?;
        Ok(StateSpace {
            a: ss.a,
            b: ss.b,
            c: ss.c,
            d: ss.d,
            delay: ss.delay,
        })
    }
}

/// A dataset from the crate's simulated identification experiments (measured inputs,
/// the six identification outputs, the logged excitation, the periodic layout).
pub fn dataset_from_experiments(
    experiments: &[flying_platform::Experiment],
    design: &flying_platform::ExperimentDesign,
) -> Result<Dataset> {
    let first = experiments
        .first()
        .ok_or_else(|| SimError::invalid("experiments", "none", "need at least one experiment"))?;
    let periodic = Periodic {
        period: design.signals[0].period,
        periods: design.periods,
        transient: design.transient,
    };
    let exps = experiments
        .iter()
        .map(|e| {
            let n = e.log.input.len();
            let u = DMatrix::from_fn(n, 9, |i, j| e.log.input[i][j]);
            let r = DMatrix::from_fn(n, 9, |i, j| e.log.excitation[i][j]);
            // Log outputs are vx vy vz wx wy wz roll pitch yaw: the first six are identified.
            let y = DMatrix::from_fn(n, 6, |i, j| e.log.output[i][j]);
            Experiment {
                name: format!("experiment {}", e.index + 1),
                u,
                y,
                r: Some(r),
                periodic: Some(periodic),
            }
        })
        .collect();
    Ok(Dataset {
        sample_rate_hz: first.log.sample_rate_hz,
        inputs: flying_platform::INPUT_NAMES
            .iter()
            .map(|s| s.to_string())
            .collect(),
        outputs: OUTPUTS.iter().map(|s| s.to_string()).collect(),
        experiments: exps,
    })
}

/// Seed of the embedded identification dataset.
pub const EMBEDDED_SEED: u64 = 1;

/// The embedded dataset of `stabilis discover` without `--data`: the paper's 18 closed-loop
/// multisine experiments (0.2-4 Hz, 10 periods of 5 s at 50 Hz, paper noise), simulated by
/// the flying_platform crate with momentum drag and fan gyroscopic torque hidden in the truth
/// (Table-3 values). Deterministic: the same seed gives the same data.
pub fn embedded_dataset() -> Result<Dataset> {
    let truth = FpModel::new(
        PlatformParams::default(),
        EffectSet::from_effects(&[FpEffect::MomentumDrag, FpEffect::FanGyroscopic]),
    );
    let config = flying_platform::SimConfig::reference(
        truth,
        flying_platform::Dynamics::Linear,
        EMBEDDED_SEED,
    )
    .map_err(|e| SimError::domain("embedded flying-platform dataset", e))?;
    let design = flying_platform::ExperimentDesign::paper(EMBEDDED_SEED)
        .map_err(|e| SimError::domain("embedded flying-platform dataset", e))?;
    let runs = flying_platform::run_experiments(&config, &design)
        .map_err(|e| SimError::domain("embedded flying-platform dataset", e))?;
    dataset_from_experiments(&runs, &design)
}
