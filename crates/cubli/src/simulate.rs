//! Recording closed-loop runs of the simulated plant (std only): sensors with bias and noise,
//! sampled controllers with zero-order hold, known excitation and unknown disturbances.
use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use std::vec::Vec;

use crate::model::inclination;
use crate::{CubliError, FullState, Measurement, Plant, SampledController};

/// Sensor model of the simulated Cubli (defaults: perfect sensors).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sensors {
    /// Constant gyroscope bias added to the measured housing rates (rad/s).
    pub gyro_bias: Vector3<f64>,
    /// Standard deviation of white gyroscope noise (rad/s).
    pub gyro_noise: f64,
    /// Standard deviation of white wheel-speed noise (rad/s).
    pub wheel_noise: f64,
    /// Standard deviation of the attitude-estimate error about each axis (rad).
    pub tilt_noise: f64,
}

impl Sensors {
    fn validate(&self) -> Result<(), CubliError> {
        if !self.gyro_bias.iter().all(|v| v.is_finite()) {
            return Err(CubliError::NonFinite { field: "gyro_bias" });
        }
        for (field, value) in [
            ("gyro_noise", self.gyro_noise),
            ("wheel_noise", self.wheel_noise),
            ("tilt_noise", self.tilt_noise),
        ] {
            if !value.is_finite() || value < 0.0 {
                return Err(CubliError::NonPositive { field, value });
            }
        }
        Ok(())
    }

    /// A reading of the true state `x`.
    pub fn measure(&self, plant: &Plant, x: &FullState, rng: &mut StdRng) -> Measurement {
        let mut white = |sd: f64| -> Vector3<f64> {
            if sd == 0.0 {
                Vector3::zeros()
            } else {
                Vector3::from_fn(|_, _| {
                    let z: f64 = StandardNormal.sample(rng);
                    z * sd
                })
            }
        };
        let exact = Measurement::exact(&plant.params, x);
        let tilt = white(self.tilt_noise);
        Measurement {
            attitude: x.attitude * UnitQuaternion::from_scaled_axis(tilt),
            omega_h: exact.omega_h + self.gyro_bias + white(self.gyro_noise),
            omega_w: exact.omega_w + white(self.wheel_noise),
        }
    }
}

/// Timing of a recorded run: the plant input may change every `tick` (the log rate), the
/// controller runs every `control_every` ticks, the plant takes `plant_substeps` RK4 steps per tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunConfig {
    /// Run length (s).
    pub duration: f64,
    /// Log and excitation period (s); 10 ms = 100 Hz.
    pub tick: f64,
    /// Controller period in ticks (2 gives the paper's 20 ms balancing rate).
    pub control_every: usize,
    /// RK4 steps per tick.
    pub plant_substeps: usize,
    /// Sensor model.
    pub sensors: Sensors,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            duration: 5.0,
            tick: 0.01,
            control_every: 2,
            plant_substeps: 10,
            sensors: Sensors::default(),
            seed: 0,
        }
    }
}

/// Column-wise record of a run, one row per tick (state at the start of the tick, input held
/// during it).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Time (s).
    pub t: Vec<f64>,
    /// Torque commanded to the motors: controller output plus known excitation (N m).
    pub input: Vec<Vector3<f64>>,
    /// Known excitation added to the controller output (N m).
    pub excitation: Vec<Vector3<f64>>,
    /// Unknown disturbance torque added on the wheels (N m), not part of `input`.
    pub disturbance: Vec<Vector3<f64>>,
    /// Sensor readings.
    pub measured: Vec<Measurement>,
    /// True state.
    pub state: Vec<FullState>,
    /// True housing rates (rad/s).
    pub omega_h: Vec<Vector3<f64>>,
    /// True wheel rates relative to the housing (rad/s).
    pub omega_w: Vec<Vector3<f64>>,
    /// True inclination (rad).
    pub inclination: Vec<f64>,
}

impl Trajectory {
    fn with_capacity(n: usize) -> Self {
        Self {
            t: Vec::with_capacity(n),
            input: Vec::with_capacity(n),
            excitation: Vec::with_capacity(n),
            disturbance: Vec::with_capacity(n),
            measured: Vec::with_capacity(n),
            state: Vec::with_capacity(n),
            omega_h: Vec::with_capacity(n),
            omega_w: Vec::with_capacity(n),
            inclination: Vec::with_capacity(n),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the run recorded nothing.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Known excitation and unknown disturbance at tick `k` (time `t`).
pub trait External {
    /// (excitation, disturbance) torques in N m.
    fn at(&mut self, k: usize, t: f64) -> (Vector3<f64>, Vector3<f64>);
}

impl<F: FnMut(usize, f64) -> (Vector3<f64>, Vector3<f64>)> External for F {
    fn at(&mut self, k: usize, t: f64) -> (Vector3<f64>, Vector3<f64>) {
        self(k, t)
    }
}

/// Runs `controller` on `plant` from `x0` and records every tick.
pub fn simulate(
    plant: &Plant,
    x0: &FullState,
    controller: &mut dyn SampledController,
    cfg: &RunConfig,
    external: &mut dyn External,
) -> Result<Trajectory, CubliError> {
    x0.validate()?;
    plant.effects.validate()?;
    cfg.sensors.validate()?;
    for (field, value) in [("duration", cfg.duration), ("tick", cfg.tick)] {
        if !value.is_finite() || value <= 0.0 {
            return Err(CubliError::TimeStep { field, value });
        }
    }
    if cfg.control_every == 0 || cfg.plant_substeps == 0 {
        return Err(CubliError::TimeStep {
            field: "control_every / plant_substeps",
            value: 0.0,
        });
    }
    let n = (cfg.duration / cfg.tick).round() as usize;
    let h = cfg.tick / cfg.plant_substeps as f64;
    let sample = cfg.tick * cfg.control_every as f64;
    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let mut out = Trajectory::with_capacity(n);
    let mut x = *x0;
    let mut command = Vector3::zeros();
    let p = &plant.params;
    for k in 0..n {
        let t = k as f64 * cfg.tick;
        let y = cfg.sensors.measure(plant, &x, &mut rng);
        if k % cfg.control_every == 0 {
            command = controller.sample(&y, sample)?;
        }
        let (excitation, disturbance) = external.at(k, t);
        let input = command + excitation;
        out.t.push(t);
        out.input.push(input);
        out.excitation.push(excitation);
        out.disturbance.push(disturbance);
        out.measured.push(y);
        out.state.push(x);
        out.omega_h.push(x.omega_h(p));
        out.omega_w.push(x.omega_w(p));
        out.inclination.push(inclination(p, &x.gravity_body(p)));
        let total = input + disturbance;
        for _ in 0..cfg.plant_substeps {
            x = plant.step(&x, &total, h);
        }
        if !x.p_h.iter().chain(x.p_w.iter()).all(|v| v.is_finite()) {
            return Err(CubliError::NonFinite {
                field: "simulated state",
            });
        }
    }
    Ok(out)
}

/// No excitation and no disturbance.
pub fn quiet(_k: usize, _t: f64) -> (Vector3<f64>, Vector3<f64>) {
    (Vector3::zeros(), Vector3::zeros())
}

/// Periodic multisine excitation on the three wheels, zippered so that each channel owns every
/// third harmonic of the period (orthogonal inputs for MIMO identification), random phases.
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    period_samples: usize,
    /// (channel, harmonic, phase, amplitude) of each sine.
    lines: Vec<(usize, usize, f64, f64)>,
}

impl Multisine {
    /// Multisine with period `period_samples` ticks, harmonics 1..=`max_harmonic` shared out over
    /// the channels, and RMS `rms` (N m) on each channel; phases drawn from `seed`.
    pub fn new(
        rms: f64,
        period_samples: usize,
        max_harmonic: usize,
        seed: u64,
    ) -> Result<Self, CubliError> {
        if !rms.is_finite() || rms < 0.0 {
            return Err(CubliError::NonPositive {
                field: "rms",
                value: rms,
            });
        }
        if period_samples < 2 || max_harmonic < 3 || 2 * max_harmonic >= period_samples {
            return Err(CubliError::TimeStep {
                field:
                    "period_samples / max_harmonic (needs 3 <= max_harmonic < period_samples / 2)",
                value: period_samples as f64,
            });
        }
        let mut rng = StdRng::seed_from_u64(seed);
        let mut lines = Vec::new();
        for c in 0..3 {
            let harmonics: Vec<usize> = (1..=max_harmonic).filter(|k| (k - 1) % 3 == c).collect();
            // Equal amplitudes a: RMS = a √(n/2).
            let a = rms * (2.0 / harmonics.len() as f64).sqrt();
            for k in harmonics {
                lines.push((c, k, rng.random_range(0.0..core::f64::consts::TAU), a));
            }
        }
        Ok(Self {
            period_samples,
            lines,
        })
    }

    /// Period in ticks.
    pub fn period_samples(&self) -> usize {
        self.period_samples
    }

    /// Excitation at tick `k`.
    pub fn value(&self, k: usize) -> Vector3<f64> {
        let mut out = Vector3::zeros();
        let base =
            core::f64::consts::TAU * (k % self.period_samples) as f64 / self.period_samples as f64;
        for &(c, h, phase, a) in &self.lines {
            out[c] += a * (base * h as f64 + phase).sin();
        }
        out
    }
}
