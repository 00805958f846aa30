//! Closed-loop simulation of the cascaded controller against a truth model (spec §9):
//! 50 Hz sample-and-hold control, a fine internal step, in-loop actuator delay, process
//! (input-side) noise, sensor noise and an optional logging offset.
//!
//! The truth is a [`Model`]: its enabled effects act on the plant, and its `input_delay`
//! (`td`) is the **in-loop** actuator delay. The paper's identified 45 ms must not all sit
//! in the loop (the rate loop diverges above ~35 ms, spec §9.2 item 3); use
//! [`SimConfig::log_delay_samples`] for the rest.

use crate::control::{CascadedController, Measurement, Setpoint};
use crate::error::{require_positive, Error, Result};
use crate::geometry::N_INPUTS;
use crate::model::Model;
use crate::nonlinear::{Disturbance, NonlinearPlant, NonlinearState};
use nalgebra::{DMatrix, DVector, SVector, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

/// Names of the logged outputs, in the order of [`SimLog::output`] (DESIGN.md topic fields).
pub const LOG_OUTPUT_NAMES: [&str; 9] =
    ["vx", "vy", "vz", "wx", "wy", "wz", "roll", "pitch", "yaw"];

/// Which dynamics the truth uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dynamics {
    /// Hover-linear model (exact zero-order-hold discretisation on the internal step).
    Linear,
    /// Nonlinear rigid body (RK4 on the internal step).
    Nonlinear,
}

/// Noise levels (spec §9.2 items 9-10). Standard deviations are per 50 Hz sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// White force noise as CoG acceleration per axis, m/s²/√Hz.
    pub force_psd: f64,
    /// White torque noise as angular acceleration per axis, rad/s²/√Hz.
    pub torque_psd: f64,
    /// White noise on each of the nine applied thrusts (not logged), N.
    pub thrust_std: f64,
    /// Motion-capture position noise, m.
    pub position_std: f64,
    /// Motion-capture attitude noise, rad.
    pub attitude_std: f64,
    /// Velocity noise, m/s.
    pub velocity_std: f64,
    /// Gyroscope noise, rad/s.
    pub gyro_std: f64,
}

impl Noise {
    /// The spec's defaults, which give hover errors close to the paper's Table 1.
    pub fn paper() -> Self {
        Self {
            force_psd: 0.02,
            torque_psd: 0.05,
            thrust_std: 0.0,
            position_std: 3e-4,
            attitude_std: 3e-3,
            velocity_std: 5e-3,
            gyro_std: 5e-3,
        }
    }

    /// No noise at all.
    pub fn none() -> Self {
        Self {
            force_psd: 0.0,
            torque_psd: 0.0,
            thrust_std: 0.0,
            position_std: 0.0,
            attitude_std: 0.0,
            velocity_std: 0.0,
            gyro_std: 0.0,
        }
    }

    fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("force_psd", self.force_psd),
            ("torque_psd", self.torque_psd),
            ("thrust_std", self.thrust_std),
            ("position_std", self.position_std),
            ("attitude_std", self.attitude_std),
            ("velocity_std", self.velocity_std),
            ("gyro_std", self.gyro_std),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Invalid {
                    name,
                    reason: format!("noise level must be >= 0, got {v}"),
                });
            }
        }
        Ok(())
    }
}

/// Everything a closed-loop run needs besides the scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct SimConfig {
    /// Truth model: effects on the plant; `input_delay` is the in-loop actuator delay (rounded
    /// to the internal step).
    pub truth: Model,
    /// Linear or nonlinear truth dynamics.
    pub dynamics: Dynamics,
    /// Controller (designed on its own design model).
    pub controller: CascadedController,
    /// Noise levels.
    pub noise: Noise,
    /// Control and logging rate, Hz.
    pub sample_rate_hz: f64,
    /// Internal integration steps per sample (20 gives 1 ms at 50 Hz).
    pub substeps: usize,
    /// Logged outputs lag the logged inputs by this many samples (not in the loop).
    pub log_delay_samples: usize,
    /// Wind in the inertial frame, m/s (nonlinear truth with momentum drag only).
    pub wind: Vector3<f64>,
    /// Seed of the noise generator.
    pub seed: u64,
}

impl SimConfig {
    /// The spec's reference set-up around `truth`: paper controller on the nominal design
    /// model, paper noise, 50 Hz with 1 ms internal step, no logging offset.
    pub fn reference(truth: Model, dynamics: Dynamics, seed: u64) -> Result<Self> {
        Ok(Self {
            truth,
            dynamics,
            controller: CascadedController::paper()?,
            noise: Noise::paper(),
            sample_rate_hz: 50.0,
            substeps: 20,
            log_delay_samples: 0,
            wind: Vector3::zeros(),
            seed,
        })
    }

    /// Delay of the logged FRF relative to a continuous model: half a sample (hold),
    /// the in-loop delay and the logging offset.
    pub fn effective_delay(&self) -> f64 {
        let ts = 1.0 / self.sample_rate_hz;
        ts / 2.0
            + self.in_loop_delay_steps() as f64 * ts / self.substeps as f64
            + self.log_delay_samples as f64 * ts
    }

    fn in_loop_delay_steps(&self) -> usize {
        let h = 1.0 / (self.sample_rate_hz * self.substeps as f64);
        (self.truth.effects.delay() / h).round() as usize
    }
}

/// A time window in which the desired body rates are overridden (disturbance test, §5.3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RateOverride {
    /// Start time, s.
    pub start: f64,
    /// End time (exclusive), s.
    pub end: f64,
    /// Desired body rates during the window, rad/s.
    pub rates: Vector3<f64>,
}

/// What happens during a run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scenario {
    /// Number of samples to run.
    pub samples: usize,
    /// Excitation added to the controller output, one 9-vector per sample (or empty).
    pub excitation: Vec<[f64; N_INPUTS]>,
    /// Set-points `(from time s, set-point)`, in time order; hover at the origin before the first.
    pub setpoints: Vec<(f64, Setpoint)>,
    /// Optional override of the desired rates.
    pub rate_override: Option<RateOverride>,
}

/// Logged run, one row per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct SimLog {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Sample times, s.
    pub t: Vec<f64>,
    /// Thrust commands after the limits (trim included), N: `F1x .. F3z`.
    pub input: Vec<[f64; N_INPUTS]>,
    /// Measured outputs in [`LOG_OUTPUT_NAMES`] order (with the logging offset).
    pub output: Vec<[f64; 9]>,
    /// Excitation added to each input channel, N.
    pub excitation: Vec<[f64; N_INPUTS]>,
    /// True position in J, m.
    pub position: Vec<[f64; 3]>,
    /// True outputs (noise-free, no logging offset) in [`LOG_OUTPUT_NAMES`] order.
    pub true_output: Vec<[f64; 9]>,
    /// Number of samples in which a limit clipped the command.
    pub saturated_samples: usize,
}

/// The truth's state in the frame the controller sees.
struct Observed {
    position: Vector3<f64>,
    velocity: Vector3<f64>,
    attitude: Vector3<f64>,
    rates: Vector3<f64>,
}

/// The truth being integrated. The linear truth is stepped exactly (zero-order hold) over
/// each stretch of constant input; at most two stretch lengths occur per sample (the
/// in-loop delay splits a sample once), so their transition matrices are cached.
enum Plant {
    Linear {
        x: DVector<f64>,
        next: DVector<f64>,
        w: DVector<f64>,
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        h: f64,
        steps: Vec<(usize, DMatrix<f64>, DMatrix<f64>)>,
        n: usize,
        trim: SVector<f64, N_INPUTS>,
    },
    Nonlinear {
        plant: Box<NonlinearPlant>,
        x: NonlinearState,
        wind: Vector3<f64>,
        h: f64,
    },
}

impl Plant {
    fn new(config: &SimConfig, h: f64) -> Result<Self> {
        match config.dynamics {
            Dynamics::Linear => {
                let ss = config.truth.state_space()?;
                let n = ss.a.nrows();
                // States (model states, position in J); inputs (thrust deviation, acc, ang acc).
                let mut a = DMatrix::<f64>::zeros(n + 3, n + 3);
                a.view_mut((0, 0), (n, n)).copy_from(&ss.a);
                let mut b = DMatrix::<f64>::zeros(n + 3, N_INPUTS + 6);
                b.view_mut((0, 0), (n, N_INPUTS)).copy_from(&ss.b);
                for i in 0..3 {
                    a[(n + i, i)] = 1.0;
                    b[(i, N_INPUTS + i)] = 1.0;
                    b[(6 + i, N_INPUTS + 3 + i)] = 1.0;
                }
                Ok(Plant::Linear {
                    x: DVector::zeros(n + 3),
                    next: DVector::zeros(n + 3),
                    w: DVector::zeros(N_INPUTS + 6),
                    a,
                    b,
                    h,
                    steps: Vec::with_capacity(2),
                    n,
                    trim: config.truth.params.hover_input(),
                })
            }
            Dynamics::Nonlinear => {
                let plant = NonlinearPlant::new(config.truth.clone())?;
                let x = plant.hover_state();
                Ok(Plant::Nonlinear {
                    plant: Box::new(plant),
                    x,
                    wind: config.wind,
                    h,
                })
            }
        }
    }

    /// Advances `substeps` internal steps with the input held.
    fn advance(
        &mut self,
        substeps: usize,
        u: &SVector<f64, N_INPUTS>,
        acc: &Vector3<f64>,
        ang: &Vector3<f64>,
    ) -> Result<()> {
        match self {
            Plant::Linear {
                x,
                next,
                w,
                a,
                b,
                h,
                steps,
                trim,
                ..
            } => {
                let cached = steps.iter().position(|(len, _, _)| *len == substeps);
                let i = match cached {
                    Some(i) => i,
                    None => {
                        let (phi, gamma) = rigid_body::lti::c2d_zoh(a, b, *h * substeps as f64)
                            .map_err(|e| {
                                Error::Numerical(format!("discretising the truth: {e}"))
                            })?;
                        steps.push((substeps, phi, gamma));
                        steps.len() - 1
                    }
                };
                let (_, phi, gamma) = &steps[i];
                w.rows_mut(0, N_INPUTS).copy_from(&(u - *trim));
                w.rows_mut(N_INPUTS, 3).copy_from(acc);
                w.rows_mut(N_INPUTS + 3, 3).copy_from(ang);
                next.gemv(1.0, phi, x, 0.0);
                next.gemv(1.0, gamma, w, 1.0);
                core::mem::swap(x, next);
            }
            Plant::Nonlinear { plant, x, wind, h } => {
                let d = Disturbance {
                    wind: *wind,
                    acceleration: *acc,
                    angular_acceleration: *ang,
                };
                for _ in 0..substeps {
                    *x = plant.rk4_step(x, u, &d, *h);
                }
            }
        }
        Ok(())
    }

    fn observe(&self) -> Observed {
        match self {
            Plant::Linear { x, n, .. } => Observed {
                position: Vector3::new(x[*n], x[*n + 1], x[*n + 2]),
                velocity: Vector3::new(x[0], x[1], x[2]),
                attitude: Vector3::new(x[3], x[4], x[5]),
                rates: Vector3::new(x[6], x[7], x[8]),
            },
            Plant::Nonlinear { x, .. } => {
                let (p, v) = NonlinearPlant::in_yaw_frame(x);
                Observed {
                    position: p,
                    velocity: v,
                    attitude: Vector3::new(x[6], x[7], x[8]),
                    rates: Vector3::new(x[9], x[10], x[11]),
                }
            }
        }
    }
}

fn gaussian3(rng: &mut StdRng, std: f64) -> Vector3<f64> {
    if std == 0.0 {
        return Vector3::zeros();
    }
    Vector3::from_fn(|_, _| std * rng.sample::<f64, _>(StandardNormal))
}

fn outputs(v: &Vector3<f64>, w: &Vector3<f64>, att: &Vector3<f64>) -> [f64; 9] {
    [v[0], v[1], v[2], w[0], w[1], w[2], att[0], att[1], att[2]]
}

/// Runs the closed loop; errors on bad settings and when the run diverges.
pub fn simulate(config: &SimConfig, scenario: &Scenario) -> Result<SimLog> {
    require_positive("sample_rate_hz", config.sample_rate_hz)?;
    if config.substeps == 0 {
        return Err(Error::Invalid {
            name: "substeps",
            reason: "must be >= 1".into(),
        });
    }
    config.noise.validate()?;
    if !scenario.excitation.is_empty() && scenario.excitation.len() < scenario.samples {
        return Err(Error::Length {
            what: "excitation",
            got: scenario.excitation.len(),
            expected: scenario.samples,
        });
    }
    if let Some((k, i)) = scenario
        .excitation
        .iter()
        .enumerate()
        .find_map(|(k, r)| r.iter().position(|v| !v.is_finite()).map(|i| (k, i)))
    {
        return Err(Error::Invalid {
            name: "excitation",
            reason: format!(
                "sample {k}, input {i} is {}; every value must be finite",
                scenario.excitation[k][i]
            ),
        });
    }
    if scenario.samples > 0 && config.log_delay_samples >= scenario.samples {
        // Every logged output would be the first measurement.
        return Err(Error::Invalid {
            name: "log_delay_samples",
            reason: format!(
                "{} is not shorter than the run ({} samples)",
                config.log_delay_samples, scenario.samples
            ),
        });
    }
    let ts = 1.0 / config.sample_rate_hz;
    let h = ts / config.substeps as f64;
    let delay_steps = config.in_loop_delay_steps();
    let mut plant = Plant::new(config, h)?;
    let mut rng = StdRng::seed_from_u64(config.seed);
    let noise = config.noise;
    let ctrl = &config.controller;
    let n = scenario.samples;
    let mut log = SimLog {
        sample_rate_hz: config.sample_rate_hz,
        t: Vec::with_capacity(n),
        input: Vec::with_capacity(n),
        output: Vec::with_capacity(n),
        excitation: Vec::with_capacity(n),
        position: Vec::with_capacity(n),
        true_output: Vec::with_capacity(n),
        saturated_samples: 0,
    };
    let mut measured: Vec<[f64; 9]> = Vec::with_capacity(n);
    let mut commands: Vec<SVector<f64, N_INPUTS>> = Vec::with_capacity(n);
    let trim = ctrl.trim;
    // Loss of control with the limits active shows as a bounded limit cycle, not growth:
    // flag it when the limits clip in 90 % of the samples of the last second.
    let window = (config.sample_rate_hz.round() as usize).max(1);
    let mut recent_saturation = std::collections::VecDeque::with_capacity(window);
    for k in 0..n {
        let t = k as f64 * ts;
        let truth = plant.observe();
        let meas = Measurement {
            position: truth.position + gaussian3(&mut rng, noise.position_std),
            velocity: truth.velocity + gaussian3(&mut rng, noise.velocity_std),
            attitude: truth.attitude + gaussian3(&mut rng, noise.attitude_std),
            rates: truth.rates + gaussian3(&mut rng, noise.gyro_std),
        };
        let sp = scenario
            .setpoints
            .iter()
            .rev()
            .find(|(t0, _)| *t0 <= t + 1e-12)
            .map(|(_, s)| *s)
            .unwrap_or_default();
        let (mut rates_des, fz) = ctrl.outer(&meas, &sp);
        if let Some(o) = scenario
            .rate_override
            .filter(|o| t >= o.start - 1e-12 && t < o.end - 1e-12)
        {
            rates_des = o.rates;
        }
        let r = scenario
            .excitation
            .get(k)
            .copied()
            .unwrap_or([0.0; N_INPUTS]);
        let raw = ctrl.inner(&meas.rates, &rates_des, fz)
            + SVector::<f64, N_INPUTS>::from_column_slice(&r);
        let (u, saturated) = ctrl.limits.saturate(&raw);
        log.saturated_samples += usize::from(saturated);
        if recent_saturation.len() == window {
            recent_saturation.pop_front();
        }
        recent_saturation.push_back(saturated);
        let clipped = recent_saturation.iter().filter(|&&s| s).count();
        if recent_saturation.len() == window && 10 * clipped >= 9 * window {
            return Err(Error::Diverged {
                t,
                reason: format!("actuator limits clipped {clipped} of the last {window} commands (sustained oscillation)"),
            });
        }
        commands.push(u);
        measured.push(outputs(&meas.velocity, &meas.rates, &meas.attitude));
        log.t.push(t);
        log.input.push(u.into());
        log.output
            .push(measured[k.saturating_sub(config.log_delay_samples)]);
        log.excitation.push(r);
        log.position.push(truth.position.into());
        log.true_output
            .push(outputs(&truth.velocity, &truth.rates, &truth.attitude));
        // Process noise held over the sample: PSD sigma^2 at low frequency.
        let acc = gaussian3(&mut rng, noise.force_psd / ts.sqrt());
        let ang = gaussian3(&mut rng, noise.torque_psd / ts.sqrt());
        let thrust_noise = SVector::<f64, N_INPUTS>::from_fn(|_, _| {
            if noise.thrust_std == 0.0 {
                0.0
            } else {
                noise.thrust_std * rng.sample::<f64, _>(StandardNormal)
            }
        });
        // The command applied at internal step g was issued at step g - delay_steps; it
        // changes at most once inside this sample, at offset `split`.
        let split = delay_steps % config.substeps;
        let mut start = 0;
        for end in [split, config.substeps] {
            if end > start {
                let g = k * config.substeps + start;
                let applied = if g >= delay_steps {
                    commands[(g - delay_steps) / config.substeps]
                } else {
                    trim
                };
                plant.advance(end - start, &(applied + thrust_noise), &acc, &ang)?;
                start = end;
            }
        }
        let after = plant.observe();
        let bad = [
            after.position.norm(),
            after.velocity.norm(),
            after.rates.norm(),
        ]
        .iter()
        .any(|v| !v.is_finite())
            || after.attitude[0].abs() > 1.2
            || after.attitude[1].abs() > 1.2
            || after.position.norm() > 100.0;
        if bad {
            return Err(Error::Diverged {
                t: t + ts,
                reason: format!(
                    "roll {:.2} rad, pitch {:.2} rad, |position| {:.2} m",
                    after.attitude[0],
                    after.attitude[1],
                    after.position.norm()
                ),
            });
        }
    }
    Ok(log)
}
