//! `stabilis sim wheel-pendulum`: the reaction-wheel pendulum released at a tilt and balanced by
//! a discrete LQR with a torque limit, seeded sensor noise and an optional input delay.
use crate::error::{Result, SimError};
use crate::integrate::InputDelay;
use crate::log::Experiment;
use crate::progress::Progress;
use crate::runner::{run_closed_loop, RunOptions};
use crate::scenarios::{Common, Recorder, Scenario};
use crate::system::System;
use crate::wheel_pendulum::{Lqr, LqrWeights, WheelPendulum};

/// Topic prefix of this system's log.
pub const TOPIC: &str = "/wheel_pendulum";

/// Options of the wheel-pendulum run.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Args {
    /// Options shared by all scenarios.
    #[command(flatten)]
    pub common: Common,
    /// Initial tilt from upright, degrees.
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub tilt_deg: f64,
    /// Controller rate, Hz.
    #[arg(long, default_value_t = 200.0)]
    pub sample_rate: f64,
    /// Motor torque limit, N m.
    #[arg(long, default_value_t = 0.2)]
    pub torque_max: f64,
    /// Delay from controller to motor, s (fractions of a sample are simulated exactly).
    #[arg(long, default_value_t = 0.0)]
    pub delay: f64,
    /// Standard deviations of the sensor noise on phi (rad), phi_dot (rad/s), omega_w (rad/s),
    /// comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [1e-3, 5e-3, 0.05])]
    pub noise: Vec<f64>,
    /// Leave the motor off: the pendulum falls.
    #[arg(long)]
    pub no_control: bool,
}

impl Args {
    /// The default run with the given common options.
    pub fn new(common: Common) -> Self {
        Self {
            common,
            tilt_deg: 5.0,
            sample_rate: 200.0,
            torque_max: 0.2,
            delay: 0.0,
            noise: vec![1e-3, 5e-3, 0.05],
            no_control: false,
        }
    }
}

impl Scenario for Args {
    fn common(&self) -> &Common {
        &self.common
    }

    fn run(&self, recorder: &mut Recorder, progress: &mut Progress) -> Result<()> {
        if !(self.tilt_deg.is_finite() && self.tilt_deg.abs() < 90.0) {
            return Err(SimError::invalid(
                "tilt-deg",
                self.tilt_deg,
                "must be within (-90, 90) degrees",
            ));
        }
        super::samples(self.common.duration, self.sample_rate)?;
        let system = WheelPendulum::default();
        let period = 1.0 / self.sample_rate;
        let options = RunOptions {
            duration: self.common.duration,
            sample_rate_hz: self.sample_rate,
            substeps: 4,
            delay: InputDelay::from_seconds(self.delay, period)?,
            noise_std: self.noise.clone(),
            seed: self.common.seed,
        };
        let steps = options.steps()?;
        let lqr = Lqr::design(
            &system.params,
            &LqrWeights::default(),
            period,
            self.torque_max,
        )?;

        let mut experiment = Experiment::new(self.sample_rate);
        for (key, value) in [
            ("system", "wheel-pendulum".to_string()),
            ("duration_s", self.common.duration.to_string()),
            ("seed", self.common.seed.to_string()),
            ("initial_tilt_deg", self.tilt_deg.to_string()),
            ("input_delay_s", self.delay.to_string()),
            ("torque_max_nm", self.torque_max.to_string()),
            (
                "controller",
                if self.no_control { "none" } else { "dlqr" }.to_string(),
            ),
            ("gain", lqr.k.map(|k| k.to_string()).join(",")),
        ] {
            experiment.extra.insert(key.into(), value);
        }
        recorder.experiment(&experiment)?;
        let input = recorder.add_topic(&format!("{TOPIC}/input"), &system.input_names())?;
        let output = recorder.add_topic(&format!("{TOPIC}/output"), &system.output_names())?;
        let state = recorder.add_topic(&format!("{TOPIC}/state"), &system.state_names())?;

        let mut controller = |_t: f64, y: &[f64], u: &mut [f64]| {
            u[0] = if self.no_control { 0.0 } else { lqr.torque(y) };
        };
        let x0 = vec![self.tilt_deg.to_radians(), 0.0, 0.0];
        let mut k: u64 = 0;
        let trajectory = run_closed_loop(
            &system,
            system.nominal_parameters(),
            x0,
            &mut controller,
            &options,
            |sample| {
                recorder.record(input, sample.t, sample.u)?;
                recorder.record(output, sample.t, sample.y)?;
                recorder.record(state, sample.t, sample.x)?;
                k += 1;
                progress.set(k * 100 / (steps as u64 + 1));
                Ok(())
            },
        )?;

        let phi = trajectory.state.column("phi")?;
        let tau = trajectory.input.column("tau")?;
        let peak = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let last_second = phi.len().saturating_sub(self.sample_rate.round() as usize);
        recorder.summarize("samples", phi.len());
        recorder.summarize(
            "final_tilt_deg",
            phi.last().copied().unwrap_or(0.0).to_degrees(),
        );
        recorder.summarize("max_tilt_deg", peak(phi).to_degrees());
        recorder.summarize(
            "max_tilt_last_second_deg",
            peak(&phi[last_second..]).to_degrees(),
        );
        recorder.summarize("peak_torque_nm", peak(tau));
        recorder.summarize("gain", lqr.k.to_vec());
        Ok(())
    }
}
