//! Simulator, the shipped systems' workbench adapters and the `stabilis` command-line runner.
//!
//! - [`System`]: the slice-based model interface that domain models are adapted to;
//! - [`integrate`]: fixed-step RK4 under zero-order-hold inputs with exact input delays;
//! - [`runner`]: the sampled closed loop with seeded measurement noise;
//! - [`output`]: the rules every output follows (never over an input, temporary file + rename),
//!   and [`log`]: MCAP writing and reading, CSV reading, per-topic column tables (both from the
//!   [`workbench`] crate);
//! - [`systems`]: the flying platform and the Cubli adapted to the [`workbench`], and the
//!   registry of systems by name;
//! - [`wheel_pendulum`]: a small unstable system balanced by LQR, the default scenario;
//! - [`scenarios`] and [`cli`]: `stabilis sim <system>`, `stabilis info` and the other verbs.
pub mod cli;
pub mod integrate;
pub mod progress;
pub mod runner;
pub mod scenarios;
pub mod system;
pub mod systems;
pub mod wheel_pendulum;

// The error type, the logs and the output rules live below the simulator, in the workbench
// crate, so that the workbench depends on nothing that knows a system.
pub use error::{Result, SimError};
pub use system::System;
pub use workbench::{error, limits, log, output};
