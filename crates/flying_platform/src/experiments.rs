//! The paper's 18 closed-loop identification experiments (spec §6.2, §9.3): each a fresh
//! hover start with its own seed, excited by one row of the orthogonal multisine design.

use crate::error::Result;
use crate::excitation::{ExperimentDesign, ExperimentSlot, N_EXPERIMENTS};
use crate::simulate::{simulate, Scenario, SimConfig, SimLog};

/// One simulated experiment with its `experiment` metadata (DESIGN.md: string values).
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Experiment index, 0-based.
    pub index: usize,
    /// Signal, DFT row and channel of this experiment.
    pub slot: ExperimentSlot,
    /// The logged run.
    pub log: SimLog,
    /// Metadata record `experiment`: `sample_rate_hz`, `period_samples`, `periods`,
    /// `transient_samples`, `excited`, plus the seed and the truth's description.
    pub metadata: Vec<(String, String)>,
}

/// Seed of experiment `e` derived from the configuration's seed.
pub fn experiment_seed(base: u64, e: usize) -> u64 {
    base.wrapping_mul(6_364_136_223_846_793_005)
        .wrapping_add(1_442_695_040_888_963_407 ^ e as u64)
}

/// Simulates experiment `e` (0-based) of `design` under `config`.
pub fn run_experiment(
    config: &SimConfig,
    design: &ExperimentDesign,
    e: usize,
) -> Result<Experiment> {
    let slot = ExperimentSlot::of(e)?;
    let mut cfg = config.clone();
    cfg.seed = experiment_seed(config.seed, e);
    let scenario = Scenario {
        samples: design.samples(),
        excitation: design.excitation(e)?,
        ..Scenario::default()
    };
    let log = simulate(&cfg, &scenario)?;
    let truth = &config.truth;
    let params: Vec<String> = truth
        .param_names()
        .iter()
        .zip(truth.parameter_vector())
        .map(|(n, v)| format!("{n}={v}"))
        .collect();
    let metadata = vec![
        (
            "sample_rate_hz".into(),
            format!("{}", design.sample_rate_hz),
        ),
        (
            "period_samples".into(),
            design.signals[0].period.to_string(),
        ),
        ("periods".into(), design.periods.to_string()),
        ("transient_samples".into(), design.transient.to_string()),
        ("excited".into(), design.excited_names(e)?),
        ("experiment_index".into(), (e + 1).to_string()),
        ("signal".into(), (slot.signal + 1).to_string()),
        ("dft_row".into(), slot.dft_row.to_string()),
        ("seed".into(), cfg.seed.to_string()),
        (
            "truth_effects".into(),
            truth
                .effects
                .enabled()
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(","),
        ),
        ("truth_params".into(), params.join(",")),
        (
            "effective_delay_s".into(),
            format!("{}", config.effective_delay()),
        ),
        (
            "saturated_samples".into(),
            log.saturated_samples.to_string(),
        ),
    ];
    Ok(Experiment {
        index: e,
        slot,
        log,
        metadata,
    })
}

/// All 18 experiments of `design`.
pub fn run_experiments(config: &SimConfig, design: &ExperimentDesign) -> Result<Vec<Experiment>> {
    (0..N_EXPERIMENTS)
        .map(|e| run_experiment(config, design, e))
        .collect()
}
