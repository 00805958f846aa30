//! Ducted-fan flying platform (Muehlebach and D'Andrea, "The Flying Platform").
//!
//! The crate holds the vehicle's parameters ([`PlatformParams`], SI units, the paper's
//! appendix as default), the hover-linear model with **switchable physical effects**
//! ([`Model`], [`EffectSet`], [`Effect`]) and, built on them, the controllability design,
//! the cascaded hover controller and the identification experiments.
//!
//! # Models and effects
//! A [`Model`] is `{ params, effects }`. With no effect enabled it is the paper's
//! low-complexity model (all poles at 0); the paper's augmented model is
//! `momentum_drag + fan_gyroscopic + input_delay`. Each effect declares named parameters
//! with units, bounds and defaults ([`ParamSpec`]):
//!
//! | effect | parameters |
//! |---|---|
//! | `momentum_drag` | `c_alpha1`, `c_alpha2` (N s/m), `l_alpha1`, `l_alpha2` (m), `l_alpha3`, `l_alpha4` (m²) |
//! | `fan_gyroscopic` | `c_omega_t0` (kg m²/s) |
//! | `actuator_lag` | `tau` (s), first order on all nine thrusts (adds nine states) |
//! | `input_delay` | `td` (s), `e^{-s td}` on all inputs |
//!
//! The flat parameter vector of the enabled effects (canonical effect order, then the order
//! above) is read and written with [`Model::parameter_vector`] /
//! [`Model::set_parameter_vector`], or by name with [`Model::parameter`] /
//! [`Model::set_parameter`]. [`Model::state_space`] returns the continuous-time
//! `(A, B, C, D)` with the delay alongside; [`Model::frequency_response`] the 6x9 transfer
//! matrix from thrusts to `(vx vy vz wx wy wz)` at given angular frequencies.
//!
//! ```
//! use flying_platform::{Effect, EffectSet, Model, PlatformParams};
//! let mut model = Model::new(PlatformParams::default(), EffectSet::parse("momentum_drag").unwrap());
//! model.effects.enable(Effect::InputDelay);
//! let theta = model.parameter_vector(); // c_alpha1 .. l_alpha4, td
//! assert_eq!(theta.len(), 7);
//! let ss = model.state_space_at(&theta).unwrap();
//! assert_eq!((ss.a.nrows(), ss.b.ncols(), ss.c.nrows()), (9, 9, 6));
//! assert_eq!(ss.delay, 0.045);
//! ```

pub mod control;
pub mod controllability;
pub mod effects;
pub mod error;
pub mod excitation;
pub mod experiments;
pub mod geometry;
pub mod loop_analysis;
pub mod model;
pub mod nonlinear;
pub mod params;
pub mod simulate;

pub use control::{ActuatorLimits, CascadedController, InnerLqr, OuterGains, Tuning, YawLaw};
pub use effects::{Effect, EffectSet, MomentumDrag, ParamSpec};
pub use error::{Error, Result};
pub use excitation::{ExperimentDesign, ExperimentSlot, Multisine};
pub use experiments::{run_experiment, run_experiments, Experiment};
pub use geometry::{INPUT_NAMES, N_INPUTS};
pub use model::{Model, StateSpace, OUTPUT_NAMES, STATE_NAMES};
pub use nonlinear::NonlinearPlant;
pub use params::{InputMatrix, PlatformParams, G0};
pub use simulate::{simulate, Dynamics, Noise, Scenario, SimConfig, SimLog, LOG_OUTPUT_NAMES};
