//! `stabilis sim cubli`: the reaction-wheel cube balancing on its corner (backstepping at 20 ms),
//! rejecting a push, or jumping up from a face to its corner or to an edge after learning its
//! pre-brake wheel speeds.
//!
//! The simulated plant may carry effects the controller's model lacks (wheel friction, a
//! torque-constant error, a gyro bias, a known multisine excitation on the motor torques), so
//! that its logs can serve model discovery.
use nalgebra::{SVector, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use cubli::edge::{EdgeJump, EdgeJumpModel};
use cubli::jump::{face_attitude, pre_brake_state, ErrorModel, ImpactModel, JumpModel, Learner};
use cubli::simulate::{simulate, Multisine, RunConfig, Sensors, Trajectory};
use cubli::{
    jump_trial, Backstepping, CubliError, FullState, Gains, GuidingController, JumpConfig,
    JumpController, JumpControllers, JumpReference, Limits, NoControl, Params, Plant,
    SampledController, WheelEffects,
};

use crate::error::{Result, SimError};
use crate::log::{Experiment, Periodic};
use crate::progress::Progress;
use crate::scenarios::{Common, Recorder, Scenario};

/// Topic prefix of this system's log.
pub const TOPIC: &str = "/cubli";
/// Fields of `/cubli/input` and `/cubli/excitation` (motor torques, N m).
pub const INPUT_FIELDS: [&str; 3] = ["T1", "T2", "T3"];
/// Fields of `/cubli/output`: housing rates, wheel rates relative to the housing, unit gravity.
pub const OUTPUT_FIELDS: [&str; 9] = ["wx", "wy", "wz", "w1", "w2", "w3", "gx", "gy", "gz"];
/// Fields of `/cubli/state`: attitude quaternion, momenta, true rates, gravity, inclination.
pub const STATE_FIELDS: [&str; 20] = [
    "qw",
    "qx",
    "qy",
    "qz",
    "phx",
    "phy",
    "phz",
    "pwx",
    "pwy",
    "pwz",
    "wx",
    "wy",
    "wz",
    "w1",
    "w2",
    "w3",
    "gx",
    "gy",
    "gz",
    "inclination",
];

/// Log and excitation rate (Hz); the balancing controller runs at half of it (20 ms).
pub const SAMPLE_RATE_HZ: f64 = 100.0;

/// What to simulate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// Released at rest from a tilt; backstepping with torque limits and sensor noise.
    Balance,
    /// Upright at rest, a torque pulse on one wheel (paper: 0.17 N m for 60 ms).
    Disturbance,
    /// Jump from a face (`--jump corner` or `edge`): learning trials on a plant the model does
    /// not match, then the last jump (brake, flight, balancing at 20 ms) is logged.
    JumpUp,
}

/// Target of `jump-up`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Jump {
    /// Face to corner (paper): three wheels, guided flight at 10 ms, corner backstepping.
    #[default]
    Corner,
    /// Face to edge e1 (the planar Cubli): wheel 1 only, free flight, edge backstepping.
    Edge,
}

/// Options of the Cubli run.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct Args {
    /// Options shared by all scenarios.
    #[command(flatten)]
    pub common: Common,
    /// Which experiment.
    #[arg(long, value_enum, default_value_t = Kind::Balance)]
    pub scenario: Kind,
    /// Initial inclination from upright for `balance`, degrees (0.2 N m motors recover up to
    /// about 5 degrees).
    #[arg(long, default_value_t = 5.0)]
    pub tilt_deg: f64,
    /// Push for `disturbance`: torque (N m), duration (s), wheel (1, 2 or 3).
    #[arg(long, value_delimiter = ',', default_values_t = [0.17, 0.06, 1.0])]
    pub push: Vec<f64>,
    /// Motor torque limit, N m (not given in the paper).
    #[arg(long, default_value_t = 0.2)]
    pub torque_max: f64,
    /// Wheel speed limit, rad/s (not given in the paper).
    #[arg(long, default_value_t = 700.0)]
    pub wheel_speed_max: f64,
    /// Sensor noise standard deviations: gyro (rad/s), wheel speed (rad/s), attitude (rad).
    #[arg(long, value_delimiter = ',', default_values_t = [2e-3, 0.05, 2e-4])]
    pub noise: Vec<f64>,
    /// Hidden effect: gyro bias on the measured housing rates, rad/s (x,y,z).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 0.0, 0.0], allow_negative_numbers = true)]
    pub gyro_bias: Vec<f64>,
    /// Hidden effect: viscous wheel friction, N m s/rad (per wheel).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 0.0, 0.0])]
    pub viscous: Vec<f64>,
    /// Hidden effect: Coulomb wheel friction, N m (per wheel), smoothed by
    /// tanh(w / coulomb-smoothing).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 0.0, 0.0])]
    pub coulomb: Vec<f64>,
    /// Speed (rad/s) over which the true Coulomb friction's sign is smoothed; the workbench's
    /// candidate assumes 0.1, so another width is a model-class mismatch.
    #[arg(long, default_value_t = 0.1)]
    pub coulomb_smoothing: f64,
    /// Hidden effect: applied torque = constant x commanded (per wheel).
    #[arg(long, value_delimiter = ',', default_values_t = [1.0, 1.0, 1.0])]
    pub torque_constant: Vec<f64>,
    /// RMS (N m) of a known multisine excitation added to each motor torque at 100 Hz
    /// (0 = none); logged as `/cubli/excitation`.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub excitation_rms: f64,
    /// Excitation period in samples (100 Hz).
    #[arg(long, default_value_t = 200)]
    pub excitation_period: usize,
    /// Learning trials before the logged jump (`jump-up`).
    #[arg(long, default_value_t = 6)]
    pub trials: usize,
    /// First trial's wheel speeds as a multiple of the model's nominal speeds (`jump-up`).
    #[arg(long, default_value_t = 0.8)]
    pub start_scale: f64,
    /// Jump target for `jump-up`.
    #[arg(long, value_enum, default_value_t = Jump::Corner)]
    pub jump: Jump,
    /// Random brake efficiency per jump (`jump-up`): every wheel's κ is scaled by
    /// U(1 − s, 1 + s), seeded by `--seed` (0 = the same brake every time).
    #[arg(long, default_value_t = 0.0)]
    pub brake_spread: f64,
}

impl Args {
    /// The default run of `kind` with the given common options.
    pub fn new(common: Common, kind: Kind) -> Self {
        Self {
            common,
            scenario: kind,
            tilt_deg: 5.0,
            push: vec![0.17, 0.06, 1.0],
            torque_max: 0.2,
            wheel_speed_max: 700.0,
            noise: vec![2e-3, 0.05, 2e-4],
            gyro_bias: vec![0.0; 3],
            viscous: vec![0.0; 3],
            coulomb: vec![0.0; 3],
            coulomb_smoothing: 0.1,
            torque_constant: vec![1.0; 3],
            excitation_rms: 0.0,
            excitation_period: 200,
            trials: 6,
            start_scale: 0.8,
            jump: Jump::Corner,
            brake_spread: 0.0,
        }
    }
}

fn vec3(name: &str, v: &[f64]) -> Result<Vector3<f64>> {
    if v.len() != 3 {
        return Err(SimError::LengthMismatch {
            what: name.to_string(),
            expected: 3,
            found: v.len(),
        });
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

fn domain(context: &str) -> impl Fn(cubli::CubliError) -> SimError + '_ {
    move |e| SimError::domain(context, e)
}

/// The true plant of a truth-mismatch jump experiment (spec test 33): 5 % heavier housing,
/// centre of mass 3 % closer and shifted by (2, −2, 0) g m, lossy brake.
pub fn mismatched_jump_plant(model: &Params, limits: Limits) -> Result<(Plant, ImpactModel)> {
    let m = model.m() * 0.97 + Vector3::new(0.002, -0.002, 0.0);
    let params = model
        .with_mismatch(1.05, m)
        .map_err(domain("mismatched plant"))?;
    Ok((
        Plant {
            params,
            limits,
            ..Plant::ideal(params)
        },
        ImpactModel::Lossy {
            kappa: Vector3::new(0.90, 0.88, 0.92),
        },
    ))
}

/// How a jump-up is learned: target, motor limits, first guess, trials, random brake.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JumpSetup {
    /// Corner or edge.
    pub jump: Jump,
    /// Motor limits of the true plant.
    pub limits: Limits,
    /// First trial's speeds as a multiple of the model's nominal speeds.
    pub start_scale: f64,
    /// Number of learning trials.
    pub trials: usize,
    /// Guided flight and balancing (false: the free jump, judged at its top point).
    pub guided: bool,
    /// Random brake efficiency spread s (κ scaled by U(1 − s, 1 + s) per jump), in [0, 1).
    pub brake_spread: f64,
    /// Seed of the random brake.
    pub seed: u64,
}

/// One learning trial.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialRecord {
    /// Pre-brake wheel speeds (rad/s).
    pub theta: Vector3<f64>,
    /// Learned error E' (corner: p_hᵐ, p_hᵍ, H_h; edge: H_h in the last slot, zeros else).
    pub error: Vector3<f64>,
    /// Balanced after the jump (free jump: top point in the balancing region).
    pub success: bool,
    /// Inclination at the top point or hand-over (rad).
    pub top_inclination: f64,
    /// The brake the plant used.
    pub brake: ImpactModel,
}

/// Result of [`learn_jump`]: the trials, and what the logged jump needs.
#[derive(Debug, Clone, PartialEq)]
pub struct JumpLearning {
    /// Every trial in order.
    pub trials: Vec<TrialRecord>,
    /// Wheel speeds after the last update (rad/s).
    pub theta: Vector3<f64>,
    /// The model's nominal speeds (rad/s).
    pub nominal: Vector3<f64>,
    /// The true plant (for the edge: restricted to the edge plane).
    pub plant: Plant,
    /// The plant's nominal brake.
    pub brake: ImpactModel,
    /// The edge system of the model, for an edge jump.
    pub edge: Option<EdgeJump>,
    rng: StdRng,
    spread: f64,
}

impl JumpLearning {
    /// The brake of the next jump (random when a spread is set).
    pub fn next_brake(&mut self) -> Result<ImpactModel> {
        brake_draw(&self.brake, self.spread, &mut self.rng)
    }
}

fn brake_draw(brake: &ImpactModel, spread: f64, rng: &mut StdRng) -> Result<ImpactModel> {
    if spread == 0.0 {
        return Ok(*brake);
    }
    let f = Vector3::from_fn(|_, _| rng.random_range(1.0 - spread..1.0 + spread));
    brake.scaled(&f).map_err(domain("brake efficiency"))
}

/// Algorithm 1 for either jump, through the shared learner.
fn learning_loop<const P: usize, const N: usize, M: ErrorModel<P, N>, B>(
    model: &M,
    plant: &Plant,
    controllers: JumpControllers<'_, B>,
    cfg: &JumpConfig,
    setup: &JumpSetup,
    rng: &mut StdRng,
) -> Result<(Vec<TrialRecord>, Vector3<f64>)>
where
    B: SampledController + Copy,
{
    let learner = Learner::new(model, 0.8).map_err(domain("learner"))?;
    let mut theta: SVector<f64, P> = model.root() * setup.start_scale;
    let mut trials = Vec::with_capacity(setup.trials);
    for _ in 0..setup.trials {
        let brake = brake_draw(&cfg.brake, setup.brake_spread, rng)?;
        let speeds = model.wheel_speeds(&theta);
        let out = jump_trial(
            plant,
            face_attitude(),
            &speeds,
            controllers,
            &JumpConfig { brake, ..*cfg },
        )
        .map_err(domain("jump trial"))?;
        let error = model.measured(&out.corrected);
        trials.push(TrialRecord {
            theta: speeds,
            error: Vector3::from_fn(|i, _| if i + N >= 3 { error[i + N - 3] } else { 0.0 }),
            success: out.success,
            top_inclination: out.top_inclination,
            brake,
        });
        theta = learner.update(&theta, &error);
    }
    Ok((trials, model.wheel_speeds(&theta)))
}

/// Learns the pre-brake wheel speeds of a jump on the mismatched plant of
/// [`mismatched_jump_plant`] with the reference model and the paper's gains and λ = 0.8.
pub fn learn_jump(setup: &JumpSetup) -> Result<JumpLearning> {
    if !setup.start_scale.is_finite() || setup.start_scale <= 0.0 {
        return Err(SimError::invalid(
            "start-scale",
            setup.start_scale,
            "must be positive",
        ));
    }
    if !(0.0..1.0).contains(&setup.brake_spread) {
        return Err(SimError::invalid(
            "brake-spread",
            setup.brake_spread,
            "must lie in [0, 1)",
        ));
    }
    let model = Params::reference();
    let gains = Gains::paper();
    let (full_plant, brake) = mismatched_jump_plant(&model, setup.limits)?;
    let cfg = JumpConfig {
        brake,
        ..JumpConfig::default()
    };
    let mut rng = StdRng::seed_from_u64(setup.seed);
    let (trials, theta, nominal, plant, edge) = match setup.jump {
        Jump::Corner => {
            let g0 = Vector3::new(0.0, 0.0, -model.gravity());
            let jm = JumpModel::new(model, &g0).map_err(domain("jump model"))?;
            let guide = corner_guide(&model, &gains)?;
            let balance = Backstepping::new(model, gains);
            let controllers = if setup.guided {
                JumpControllers {
                    guide: Some(&guide),
                    balance: Some(&balance),
                }
            } else {
                JumpControllers::NONE
            };
            let (trials, theta) =
                learning_loop(&jm, &full_plant, controllers, &cfg, setup, &mut rng)?;
            (trials, theta, jm.root(), full_plant, None)
        }
        Jump::Edge => {
            let edge = EdgeJump::new(&model, 0).map_err(domain("edge"))?;
            let em = EdgeJumpModel::new(&edge).map_err(domain("edge jump model"))?;
            let plant = edge.plant(&full_plant).map_err(domain("edge plant"))?;
            let balance = edge.balancer(gains);
            let controllers = JumpControllers {
                guide: None,
                balance: setup.guided.then_some(&balance),
            };
            let (trials, theta) = learning_loop(&em, &plant, controllers, &cfg, setup, &mut rng)?;
            (
                trials,
                theta,
                em.wheel_speeds(&em.root()),
                plant,
                Some(edge),
            )
        }
    };
    Ok(JumpLearning {
        trials,
        theta,
        nominal,
        plant,
        brake,
        edge,
        rng,
        spread: setup.brake_spread,
    })
}

fn corner_guide(model: &Params, gains: &Gains) -> Result<GuidingController> {
    let g0 = Vector3::new(0.0, 0.0, -model.gravity());
    let bar = JumpModel::new(*model, &g0)
        .map_err(domain("jump model"))?
        .nominal_wheel_speeds();
    let reference = JumpReference::at_brake(model, &pre_brake_state(model, face_attitude(), &bar))
        .map_err(domain("jump reference"))?;
    Ok(GuidingController::new(*model, gains, reference))
}

/// The logged jump after learning: brake at the learned speeds, then the jump controller.
fn jump_run(learned: &mut JumpLearning, cfg: &RunConfig) -> Result<Trajectory> {
    let brake = learned.next_brake()?;
    let plant = learned.plant;
    let x0 = brake.apply(
        &plant.params,
        &pre_brake_state(&plant.params, face_attitude(), &learned.theta),
    );
    let switch = 5f64.to_radians();
    let run = |ctrl: &mut dyn SampledController| -> std::result::Result<Trajectory, CubliError> {
        simulate(&plant, &x0, ctrl, cfg, &mut cubli::simulate::quiet)
    };
    let model = Params::reference();
    let gains = Gains::paper();
    match learned.edge {
        None => {
            let guide = corner_guide(&model, &gains)?;
            let balance = Backstepping::new(model, gains);
            run(&mut JumpController::new(model, guide, balance, switch, 2))
        }
        Some(edge) => {
            let mut ctrl =
                JumpController::new(*edge.params(), NoControl, edge.balancer(gains), switch, 2)
                    .hand_over_at_top();
            run(&mut ctrl).map(|mut t| {
                // Log the hinged cube's 3-D momenta (the plane model keeps only the edge part).
                for x in &mut t.state {
                    *x = edge.hinged_state(x);
                }
                t
            })
        }
    }
    .map_err(domain("jump run"))
}

impl Args {
    fn plant(&self, params: Params) -> Result<Plant> {
        let effects = WheelEffects {
            torque_constant: vec3("torque-constant", &self.torque_constant)?,
            viscous: vec3("viscous", &self.viscous)?,
            coulomb: vec3("coulomb", &self.coulomb)?,
            coulomb_smoothing: self.coulomb_smoothing,
        };
        effects.validate().map_err(domain("wheel effects"))?;
        for (name, v) in [
            ("torque-max", self.torque_max),
            ("wheel-speed-max", self.wheel_speed_max),
        ] {
            if v.is_nan() || v <= 0.0 {
                return Err(SimError::invalid(name, v, "must be positive"));
            }
        }
        Ok(Plant {
            params,
            effects,
            limits: Limits {
                max_torque: self.torque_max,
                max_wheel_speed: self.wheel_speed_max,
            },
        })
    }

    fn sensors(&self) -> Result<Sensors> {
        let noise = vec3("noise", &self.noise)?;
        Ok(Sensors {
            gyro_bias: vec3("gyro-bias", &self.gyro_bias)?,
            gyro_noise: noise[0],
            wheel_noise: noise[1],
            tilt_noise: noise[2],
        })
    }
}

/// Writes a trajectory to the recorder's `/cubli/*` topics.
pub fn record_trajectory(
    recorder: &mut Recorder,
    params: &Params,
    run: &Trajectory,
    excitation: bool,
    disturbance: bool,
) -> Result<()> {
    let input = recorder.add_topic(&format!("{TOPIC}/input"), &INPUT_FIELDS)?;
    let output = recorder.add_topic(&format!("{TOPIC}/output"), &OUTPUT_FIELDS)?;
    let state = recorder.add_topic(&format!("{TOPIC}/state"), &STATE_FIELDS)?;
    let exc = if excitation {
        Some(recorder.add_topic(&format!("{TOPIC}/excitation"), &INPUT_FIELDS)?)
    } else {
        None
    };
    let dist = if disturbance {
        Some(recorder.add_topic(&format!("{TOPIC}/disturbance"), &INPUT_FIELDS)?)
    } else {
        None
    };
    for i in 0..run.len() {
        let t = run.t[i];
        let u = run.input[i];
        recorder.record(input, t, u.as_slice())?;
        let y = &run.measured[i];
        let g = y.gravity_direction();
        let mut out = [0.0; 9];
        out[..3].copy_from_slice(y.omega_h.as_slice());
        out[3..6].copy_from_slice(y.omega_w.as_slice());
        out[6..].copy_from_slice(g.as_slice());
        recorder.record(output, t, &out)?;
        let x: &FullState = &run.state[i];
        let q = x.attitude.quaternion();
        let gt = x.gravity_body(params) / params.gravity();
        let (wh, ww) = (run.omega_h[i], run.omega_w[i]);
        let row = [
            q.w,
            q.i,
            q.j,
            q.k,
            x.p_h[0],
            x.p_h[1],
            x.p_h[2],
            x.p_w[0],
            x.p_w[1],
            x.p_w[2],
            wh[0],
            wh[1],
            wh[2],
            ww[0],
            ww[1],
            ww[2],
            gt[0],
            gt[1],
            gt[2],
            run.inclination[i],
        ];
        recorder.record(state, t, &row)?;
        if let Some(id) = exc {
            recorder.record(id, t, run.excitation[i].as_slice())?;
        }
        if let Some(id) = dist {
            recorder.record(id, t, run.disturbance[i].as_slice())?;
        }
    }
    Ok(())
}

fn peak(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Summary numbers shared by all Cubli scenarios.
fn summarize(recorder: &mut Recorder, run: &Trajectory) {
    let n = run.len();
    let last = n.saturating_sub(SAMPLE_RATE_HZ as usize);
    let tail = &run.inclination[last..];
    let rms = (tail.iter().map(|v| v * v).sum::<f64>() / tail.len().max(1) as f64).sqrt();
    recorder.summarize("samples", n);
    recorder.summarize(
        "final_inclination_deg",
        run.inclination.last().copied().unwrap_or(0.0).to_degrees(),
    );
    recorder.summarize(
        "max_inclination_deg",
        peak(run.inclination.iter().copied()).to_degrees(),
    );
    recorder.summarize("rms_inclination_last_second_deg", rms.to_degrees());
    recorder.summarize(
        "peak_commanded_torque_nm",
        peak(run.input.iter().map(|u| u.amax())),
    );
    recorder.summarize(
        "final_wheel_speed_rad_s",
        run.omega_w.last().map(|w| w.norm()).unwrap_or(0.0),
    );
}

impl Scenario for Args {
    fn common(&self) -> &Common {
        &self.common
    }

    fn run(&self, recorder: &mut Recorder, progress: &mut Progress) -> Result<()> {
        super::samples(self.common.duration, SAMPLE_RATE_HZ)?;
        let model = Params::reference();
        let gains = Gains::paper();
        let sensors = self.sensors()?;
        let mut experiment = Experiment::new(SAMPLE_RATE_HZ);
        for (key, value) in [
            ("system", "cubli".to_string()),
            ("scenario", format!("{:?}", self.scenario).to_lowercase()),
            ("duration_s", self.common.duration.to_string()),
            ("seed", self.common.seed.to_string()),
            ("controller_sample_s", "0.02".to_string()),
            ("gains", "alpha=15,beta=18,gamma=12,delta=1e-5".to_string()),
            ("torque_max_nm", self.torque_max.to_string()),
        ] {
            experiment.extra.insert(key.into(), value);
        }
        let cfg = RunConfig {
            duration: self.common.duration,
            tick: 1.0 / SAMPLE_RATE_HZ,
            control_every: 2,
            plant_substeps: 10,
            sensors,
            seed: self.common.seed,
        };
        let upright_attitude =
            nalgebra::UnitQuaternion::rotation_between(&model.m_hat(), &Vector3::z())
                .ok_or_else(|| SimError::invalid("m", model.m(), "no upright attitude"))?;
        match self.scenario {
            Kind::Balance => {
                if !(self.tilt_deg.is_finite() && self.tilt_deg.abs() < 54.0) {
                    return Err(SimError::invalid(
                        "tilt-deg",
                        self.tilt_deg,
                        "must be within (-54, 54) degrees (the cube lies on a face beyond)",
                    ));
                }
                let plant = self.plant(model)?;
                let axis = upright_attitude * Vector3::new(1.0, -1.0, 0.0).normalize();
                let attitude =
                    nalgebra::UnitQuaternion::from_scaled_axis(axis * self.tilt_deg.to_radians())
                        * upright_attitude;
                let x0 = FullState::from_velocities(
                    &model,
                    attitude,
                    &Vector3::zeros(),
                    &Vector3::zeros(),
                );
                if !(self.excitation_rms.is_finite() && self.excitation_rms >= 0.0) {
                    return Err(SimError::invalid(
                        "excitation-rms",
                        self.excitation_rms,
                        "must be a torque RMS >= 0 N m (0 for no excitation)",
                    ));
                }
                let excitation = if self.excitation_rms > 0.0 {
                    let period = self.excitation_period;
                    let ms = Multisine::new(
                        self.excitation_rms,
                        period,
                        (period / 2).saturating_sub(1).min(period * 3 / 10),
                        self.common.seed,
                    )
                    .map_err(domain("excitation"))?;
                    let n = (self.common.duration * SAMPLE_RATE_HZ).round() as usize;
                    experiment.periodic = Some(Periodic {
                        period_samples: period,
                        periods: n.saturating_sub(period) / period,
                        transient_samples: n - (n.saturating_sub(period) / period) * period,
                        excited: INPUT_FIELDS.iter().map(|s| s.to_string()).collect(),
                    });
                    Some(ms)
                } else {
                    None
                };
                experiment
                    .extra
                    .insert("initial_tilt_deg".into(), self.tilt_deg.to_string());
                // The true plant effects, for checking what model discovery finds.
                for (key, v) in [
                    ("plant_viscous", &self.viscous),
                    ("plant_coulomb", &self.coulomb),
                    ("plant_torque_constant", &self.torque_constant),
                    ("plant_gyro_bias", &self.gyro_bias),
                ] {
                    let text: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                    experiment.extra.insert(key.into(), text.join(","));
                }
                experiment.extra.insert(
                    "plant_coulomb_smoothing".into(),
                    self.coulomb_smoothing.to_string(),
                );
                recorder.experiment(&experiment)?;
                let mut ctrl = Backstepping::new(model, gains);
                let mut ext = |k: usize, _t: f64| {
                    (
                        excitation
                            .as_ref()
                            .map(|m| m.value(k))
                            .unwrap_or_else(Vector3::zeros),
                        Vector3::zeros(),
                    )
                };
                let run = simulate(&plant, &x0, &mut ctrl, &cfg, &mut ext)
                    .map_err(domain("balance run"))?;
                progress.set(90);
                record_trajectory(recorder, &plant.params, &run, excitation.is_some(), false)?;
                summarize(recorder, &run);
            }
            Kind::Disturbance => {
                let push = vec3("push", &self.push)?;
                let wheel = push[2];
                if !(wheel == 1.0 || wheel == 2.0 || wheel == 3.0) {
                    return Err(SimError::invalid("push wheel", wheel, "must be 1, 2 or 3"));
                }
                let plant = self.plant(model)?;
                let x0 = FullState::from_velocities(
                    &model,
                    upright_attitude,
                    &Vector3::zeros(),
                    &Vector3::zeros(),
                );
                for (key, value) in [
                    ("push_torque_nm", push[0]),
                    ("push_duration_s", push[1]),
                    ("push_wheel", wheel),
                ] {
                    experiment.extra.insert(key.into(), value.to_string());
                }
                recorder.experiment(&experiment)?;
                let mut ctrl = Backstepping::new(model, gains);
                let mut pulse = Vector3::zeros();
                pulse[wheel as usize - 1] = push[0];
                let mut ext = |_k: usize, t: f64| {
                    let d = if t < push[1] - 1e-9 {
                        pulse
                    } else {
                        Vector3::zeros()
                    };
                    (Vector3::zeros(), d)
                };
                let run = simulate(&plant, &x0, &mut ctrl, &cfg, &mut ext)
                    .map_err(domain("disturbance run"))?;
                progress.set(90);
                record_trajectory(recorder, &plant.params, &run, false, true)?;
                summarize(recorder, &run);
                let peak_phi = peak(run.inclination.iter().copied());
                let settle = run
                    .t
                    .iter()
                    .zip(&run.inclination)
                    .filter(|(_, v)| **v > (0.05 * peak_phi).max(0.025f64.to_radians()))
                    .map(|(t, _)| *t)
                    .fold(0.0, f64::max);
                recorder.summarize("settled_below_max_5pct_or_0_025deg_s", settle);
            }
            Kind::JumpUp => {
                let limits = Limits {
                    max_torque: self.torque_max,
                    max_wheel_speed: self.wheel_speed_max,
                };
                let setup = JumpSetup {
                    jump: self.jump,
                    limits,
                    start_scale: self.start_scale,
                    trials: self.trials,
                    guided: true,
                    brake_spread: self.brake_spread,
                    seed: self.common.seed,
                };
                let mut learned = learn_jump(&setup)?;
                progress.set(50);
                let iterates: Vec<serde_json::Value> = learned
                    .trials
                    .iter()
                    .enumerate()
                    .map(|(i, t)| {
                        serde_json::json!({
                            "trial": i,
                            "theta": t.theta.as_slice(),
                            "error": t.error.as_slice(),
                            "success": t.success,
                            "brake": format!("{:?}", t.brake),
                        })
                    })
                    .collect();
                let theta = learned.theta;
                for (key, value) in [
                    ("jump", format!("{:?}", self.jump).to_lowercase()),
                    ("brake", format!("{:?}", learned.brake)),
                    ("brake_spread", self.brake_spread.to_string()),
                    (
                        "wheel_speeds_rad_s",
                        format!("{},{},{}", theta[0], theta[1], theta[2]),
                    ),
                    (
                        "inclination",
                        match self.jump {
                            Jump::Corner => "from upright on the corner",
                            Jump::Edge => "about edge e1 from upright on the edge",
                        }
                        .to_string(),
                    ),
                ] {
                    experiment.extra.insert(key.into(), value);
                }
                recorder.experiment(&experiment)?;
                let jump_cfg = RunConfig {
                    control_every: 1,
                    ..cfg
                };
                let run = jump_run(&mut learned, &jump_cfg)?;
                progress.set(90);
                record_trajectory(recorder, &model, &run, false, false)?;
                summarize(recorder, &run);
                recorder.summarize("learning", serde_json::Value::Array(iterates));
                recorder.summarize(
                    "nominal_wheel_speeds_rad_s",
                    learned.nominal.as_slice().to_vec(),
                );
                recorder.summarize("learned_wheel_speeds_rad_s", theta.as_slice().to_vec());
                recorder.summarize(
                    "first_successful_trial",
                    learned.trials.iter().position(|t| t.success).map(|i| i + 1),
                );
                let switch = run
                    .t
                    .iter()
                    .zip(&run.inclination)
                    .find(|(_, v)| **v < 5f64.to_radians())
                    .map(|(t, _)| *t);
                recorder.summarize("balancing_region_reached_s", switch);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::read_mcap;
    use crate::scenarios::run;

    fn common(duration: f64, out: Option<std::path::PathBuf>) -> Common {
        Common {
            duration,
            out,
            seed: 3,
        }
    }

    #[test]
    fn excited_balance_log_reads_back_with_the_design_topics() {
        let dir = tempfile::Builder::new()
            .prefix("cubli-scenario-")
            .tempdir()
            .unwrap();
        let path = dir.path().join("balance.mcap");
        let mut args = Args::new(common(4.0, Some(path.clone())), Kind::Balance);
        args.excitation_rms = 0.01;
        args.viscous = vec![1e-5; 3];
        args.gyro_bias = vec![0.01, 0.0, 0.0];
        run(&args, &mut Progress::hidden()).unwrap();
        let log = read_mcap(&path).unwrap();
        drop(dir);
        let input = &log.topics["/cubli/input"];
        let output = &log.topics["/cubli/output"];
        let excitation = &log.topics["/cubli/excitation"];
        let state = &log.topics["/cubli/state"];
        assert_eq!(input.fields, INPUT_FIELDS);
        assert_eq!(output.fields, OUTPUT_FIELDS);
        assert_eq!(input.len(), 400);
        let exp = &log.metadata["experiment"];
        assert_eq!(exp["period_samples"], "200");
        assert_eq!(exp["excited"], "T1,T2,T3");
        assert_eq!(exp["plant_gyro_bias"], "0.01,0,0");
        // The measured rate carries the hidden bias: at rest upright the mean of wx - true wx is 0.01.
        let (wx, true_wx) = (output.column("wx").unwrap(), state.column("wx").unwrap());
        let bias: f64 = wx.iter().zip(true_wx).map(|(a, b)| a - b).sum::<f64>() / wx.len() as f64;
        assert!((bias - 0.01).abs() < 1e-3, "{bias}");
        // Gravity output is a unit vector; the excitation is periodic with 200 samples.
        let (gx, gy, gz) = (
            output.column("gx").unwrap(),
            output.column("gy").unwrap(),
            output.column("gz").unwrap(),
        );
        assert!((gx[10].powi(2) + gy[10].powi(2) + gz[10].powi(2) - 1.0).abs() < 1e-12);
        let t1 = excitation.column("T1").unwrap();
        assert!((t1[5] - t1[205]).abs() < 1e-15 && t1.iter().any(|v| v.abs() > 1e-3));
    }

    #[test]
    fn disturbance_and_jump_up_reproduce_the_paper() {
        let rec = run(
            &Args::new(common(3.0, None), Kind::Disturbance),
            &mut Progress::hidden(),
        )
        .unwrap();
        let peak = rec.summary["max_inclination_deg"].as_f64().unwrap();
        assert!(peak < 0.5, "{peak}");
        let rec = run(
            &Args::new(common(3.0, None), Kind::JumpUp),
            &mut Progress::hidden(),
        )
        .unwrap();
        let reached = rec.summary["balancing_region_reached_s"].as_f64().unwrap();
        assert!(reached < 0.5, "{reached}");
        assert!(rec.summary["final_inclination_deg"].as_f64().unwrap() < 0.5);
    }

    #[test]
    fn bad_options_are_named() {
        let mut args = Args::new(common(1.0, None), Kind::Balance);
        args.viscous = vec![1.0, 2.0];
        let err = run(&args, &mut Progress::hidden()).unwrap_err();
        assert!(err.to_string().contains("viscous"), "{err}");
        let mut args = Args::new(common(1.0, None), Kind::Balance);
        args.tilt_deg = f64::NAN;
        assert!(run(&args, &mut Progress::hidden())
            .unwrap_err()
            .to_string()
            .contains("tilt-deg"));
    }
}
