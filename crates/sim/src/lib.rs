//! Simulator, MCAP logging, model workbench and the `stabilis` command-line runner.
//!
//! - [`System`]: the slice-based model interface that domain models are adapted to;
//! - [`integrate`]: fixed-step RK4 under zero-order-hold inputs with exact input delays;
//! - [`runner`]: the sampled closed loop with seeded measurement noise;
//! - [`output`]: the rules every output follows (never over an input, temporary file + rename);
//! - [`log`]: MCAP writing and reading, CSV reading, per-topic column tables;
//! - [`wheel_pendulum`]: a small unstable system balanced by LQR, the default scenario;
//! - [`scenarios`] and [`cli`]: `stabilis sim <system>`, `stabilis info` and the other verbs.
pub mod cli;
pub mod error;
pub mod integrate;
pub mod limits;
pub mod log;
pub mod output;
pub mod progress;
pub mod runner;
pub mod scenarios;
pub mod system;
pub mod wheel_pendulum;
pub mod workbench;

pub use error::{Result, SimError};
pub use system::System;
