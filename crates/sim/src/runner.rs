//! The closed loop: a plant integrated under held inputs, a controller sampled at a fixed rate
//! that sees the outputs with optional seeded Gaussian measurement noise.
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::error::{Result, SimError};
use crate::integrate::{check_len, check_positive, InputDelay, Zoh, ZohOptions};
use crate::log::Table;
use crate::system::{Dimensions, System};

/// A discrete-time controller: measured outputs in, inputs out, once per sample.
pub trait Controller {
    /// Writes the input to issue at time `t` given the measured outputs `y`.
    fn control(&mut self, t: f64, y: &[f64], u: &mut [f64]);
}

impl<F: FnMut(f64, &[f64], &mut [f64])> Controller for F {
    fn control(&mut self, t: f64, y: &[f64], u: &mut [f64]) {
        self(t, y, u)
    }
}

/// Settings of a closed-loop run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOptions {
    /// Length of the run, s.
    pub duration: f64,
    /// Controller (and logging) rate, Hz.
    pub sample_rate_hz: f64,
    /// RK4 steps per sample.
    pub substeps: usize,
    /// Delay between the controller and the plant.
    pub delay: InputDelay,
    /// Standard deviation of the noise added to each output; empty for none.
    pub noise_std: Vec<f64>,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl RunOptions {
    /// Number of sample periods in the run (the samples logged are one more).
    pub fn steps(&self) -> Result<usize> {
        check_positive("duration", self.duration)?;
        check_positive("sample rate", self.sample_rate_hz)?;
        let steps = (self.duration * self.sample_rate_hz).round();
        if !(1.0..=1e9).contains(&steps) {
            return Err(SimError::invalid(
                "duration",
                self.duration,
                format!(
                    "gives {steps} samples at {} Hz; need 1 to 1e9",
                    self.sample_rate_hz
                ),
            ));
        }
        Ok(steps as usize)
    }
}

/// One logged sample, handed to the observer of [`run_closed_loop`].
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// Time, s.
    pub t: f64,
    /// True state.
    pub x: &'a [f64],
    /// Measured outputs (with noise).
    pub y: &'a [f64],
    /// Input issued at `t`.
    pub u: &'a [f64],
}

/// What a run produced: true states, measured outputs and issued inputs at every sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// True states.
    pub state: Table,
    /// Measured outputs.
    pub output: Table,
    /// Issued inputs.
    pub input: Table,
}

/// Runs `controller` against `system` from `x0`, calling `observe` on every sample (e.g. to write
/// a log as the run goes, so that a run cut off mid-way leaves its data behind).
pub fn run_closed_loop<S, C, O>(
    system: &S,
    params: Vec<f64>,
    x0: Vec<f64>,
    controller: &mut C,
    options: &RunOptions,
    mut observe: O,
) -> Result<Trajectory>
where
    S: System + ?Sized,
    C: Controller + ?Sized,
    O: FnMut(&Sample<'_>) -> Result<()>,
{
    let dims = Dimensions::of(system);
    let steps = options.steps()?;
    let noise = if options.noise_std.is_empty() {
        Vec::new()
    } else {
        check_len(
            "noise standard deviations",
            dims.outputs,
            options.noise_std.len(),
        )?;
        let names = system.output_names();
        options
            .noise_std
            .iter()
            .zip(names)
            .map(|(&std, name)| {
                Normal::new(0.0, std)
                    .ok()
                    .filter(|_| std.is_finite() && std >= 0.0)
                    .ok_or_else(|| {
                        SimError::invalid(
                            format!("noise std of {name}"),
                            std,
                            "must be finite and >= 0",
                        )
                    })
            })
            .collect::<Result<Vec<_>>>()?
    };
    let mut rng = StdRng::seed_from_u64(options.seed);
    let period = 1.0 / options.sample_rate_hz;
    let mut plant = Zoh::new(
        system,
        params,
        x0,
        ZohOptions {
            period,
            substeps: options.substeps,
            delay: options.delay,
            initial_input: vec![0.0; dims.inputs],
        },
    )?;
    let mut trajectory = Trajectory {
        state: Table::new("state", system.state_names()),
        output: Table::new("output", system.output_names()),
        input: Table::new("input", system.input_names()),
    };
    let mut y = vec![0.0; dims.outputs];
    let mut u = vec![0.0; dims.inputs];
    for k in 0..=steps {
        let t = plant.time();
        plant.output(&mut y);
        for (value, normal) in y.iter_mut().zip(&noise) {
            *value += normal.sample(&mut rng);
        }
        controller.control(t, &y, &mut u);
        if let Some(i) = u.iter().position(|v| !v.is_finite()) {
            return Err(SimError::NotFinite {
                context: format!("controller output at t = {t}"),
                field: system.input_names()[i].clone(),
                value: u[i].to_string(),
            });
        }
        let sample = Sample {
            t,
            x: plant.state(),
            y: &y,
            u: &u,
        };
        observe(&sample)?;
        trajectory.state.push(t, sample.x)?;
        trajectory.output.push(t, &y)?;
        trajectory.input.push(t, &u)?;
        if k < steps {
            plant.advance(&u)?;
        }
    }
    Ok(trajectory)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wheel_pendulum::WheelPendulum;

    fn options(noise_std: Vec<f64>, seed: u64) -> RunOptions {
        RunOptions {
            duration: 2.0,
            sample_rate_hz: 100.0,
            substeps: 2,
            delay: InputDelay::none(),
            noise_std,
            seed,
        }
    }

    /// Open-loop run from rest at upright: the true state stays exactly zero, so the measured
    /// outputs are the noise alone.
    fn noise_only(noise_std: Vec<f64>, seed: u64) -> Trajectory {
        let system = WheelPendulum::default();
        let mut zero = |_t: f64, _y: &[f64], u: &mut [f64]| u[0] = 0.0;
        run_closed_loop(
            &system,
            system.nominal_parameters(),
            vec![0.0; 3],
            &mut zero,
            &options(noise_std, seed),
            |_| Ok(()),
        )
        .unwrap()
    }

    #[test]
    fn noise_is_seeded_and_has_the_requested_spread() {
        let std = vec![0.01, 0.1, 1.0];
        let a = noise_only(std.clone(), 5);
        assert_eq!(a, noise_only(std.clone(), 5));
        assert_ne!(a.output, noise_only(std.clone(), 6).output);
        assert!(a.state.columns.iter().flatten().all(|&x| x == 0.0));
        for (column, sigma) in a.output.columns.iter().zip(&std) {
            let n = column.len() as f64;
            let sample_std = (column.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
            // 201 samples: the sample standard deviation is within 15 % with high probability
            // (its relative standard error is 1 / sqrt(2 n) = 5 %).
            assert!(
                (sample_std / sigma - 1.0).abs() < 0.15,
                "{sample_std} vs {sigma}"
            );
        }
        assert_eq!(a.output.len(), 201);
        assert_eq!(a.output.t[200], 2.0);
    }

    #[test]
    fn observer_sees_every_sample_and_can_stop_the_run() {
        let system = WheelPendulum::default();
        let mut zero = |_t: f64, _y: &[f64], u: &mut [f64]| u[0] = 0.0;
        let mut seen = 0;
        let err = run_closed_loop(
            &system,
            system.nominal_parameters(),
            vec![0.01, 0.0, 0.0],
            &mut zero,
            &options(vec![], 0),
            |s| {
                seen += 1;
                if s.t >= 0.5 {
                    Err(SimError::invalid("test", s.t, "stop"))
                } else {
                    Ok(())
                }
            },
        )
        .unwrap_err();
        assert_eq!(seen, 51);
        assert!(err.to_string().starts_with("invalid test = 0.5"));
    }

    #[test]
    fn bad_options_are_named() {
        let system = WheelPendulum::default();
        let mut zero = |_t: f64, _y: &[f64], u: &mut [f64]| u[0] = 0.0;
        let p = system.nominal_parameters();
        let run = |o: RunOptions, zero: &mut dyn Controller| {
            run_closed_loop(&system, p.clone(), vec![0.0; 3], zero, &o, |_| Ok(()))
        };
        let err = run(options(vec![0.1], 0), &mut zero).unwrap_err();
        assert_eq!(
            err.to_string(),
            "length mismatch for noise standard deviations: expected 3, found 1"
        );
        let err = run(options(vec![0.1, -1.0, 0.0], 0), &mut zero).unwrap_err();
        assert!(
            err.to_string()
                .starts_with("invalid noise std of phi_dot = -1"),
            "{err}"
        );
        let err = run(
            RunOptions {
                duration: -1.0,
                ..options(vec![], 0)
            },
            &mut zero,
        )
        .unwrap_err();
        assert!(
            err.to_string().starts_with("invalid duration = -1"),
            "{err}"
        );
        let mut nan = |_t: f64, _y: &[f64], u: &mut [f64]| u[0] = f64::NAN;
        let err = run(options(vec![], 0), &mut nan).unwrap_err();
        assert!(
            err.to_string().contains("controller output at t = 0"),
            "{err}"
        );
    }
}
