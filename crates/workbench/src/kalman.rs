//! The stationary Kalman predictor of a sampled model, with its noise covariances estimated
//! from the data: the time-domain comparison that stays meaningful for an unstable plant in
//! closed loop, where a free run diverges.
//!
//! Noise model: process noise entering where the inputs do, `a (Γ0 Γ0ᵀ + Γ1 Γ1ᵀ)`, plus noise
//! entering each state directly, `b diag(d)` with `d` the state's mean squared motion per
//! sample (a disturbance that does not come through the inputs, such as a torque on a pole
//! driven by a force), and white sensor noise `R = diag(c_i r_i)`, `r` from the first
//! differences of the outputs (white noise of variance σ² gives 2σ² there). The factors are
//! chosen by coordinate descent over logarithmic grids to minimise the log-determinant of the
//! sample innovation covariance (the prediction-error criterion of the innovations form),
//! evaluated on the first [`SEARCH_SAMPLES`] samples. The
//! predictor `x̂_{k+1} = Φ x̂_k + Γ0 u_{k-w} + Γ1 u_{k-w-1} + K (y_k - C x̂_k - D u_{k-d})` is
//! stable whenever `(Φ, C)` is detectable; otherwise the design is refused by name. A
//! [`Gain::Refined`] predictor then frees every entry of the gain on the same criterion.
use nalgebra::{DMatrix, DVector};
use rigid_body::lti::spectral_radius;
use serde::Serialize;

use super::timedomain::Discrete;
use crate::error::{Result, SimError};

/// Process-to-sensor noise ratios tried, relative to the output-referred scale.
const RATIOS: [f64; 7] = [1e-6, 1e-4, 1e-2, 1.0, 1e2, 1e4, 1e6];

/// Which gain a predictor gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gain {
    /// The stationary gain of the estimated noise covariances: what a model is fitted under
    /// (the extended predictor of the time-domain criterion) and what simulated noise is
    /// drawn from (power studies). A free gain fitted to one model's innovations let an
    /// effect exploit inputs that carry a state the outputs do not (a controller's own,
    /// unlogged sensor): a lag the data do not have fitted to half a millisecond at 300
    /// standard errors.
    NoiseModel,
    /// That gain refined over all gains ([`Predictor::refine`]): the predictor that scores and
    /// tests a model fitted elsewhere (the FRF criterion's time-domain table and residual
    /// tests), whose innovations are then white for the true model whatever direction the
    /// disturbances enter in.
    Refined,
}

/// The designed predictor and what was estimated for it.
#[derive(Debug, Clone)]
pub struct Predictor {
    disc: Discrete,
    /// Predictor gain, states x outputs.
    gain: DMatrix<f64>,
    /// The designed process and sensor noise covariances `(Q, R)`, in the model's own
    /// coordinates when every state is observable (`None` otherwise).
    covariances: Option<(DMatrix<f64>, DMatrix<f64>)>,
    /// The gain in the model's own coordinates when the modes the outputs do not see decay
    /// (`None` otherwise).
    state_gain: Option<DMatrix<f64>>,
    /// Summary for the report.
    pub noise: NoiseEstimate,
}

/// The estimated noise covariances.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseEstimate {
    /// Sensor noise variance per output (first differences).
    pub sensor_variance: Vec<f64>,
    /// Input-referred process noise, relative to the output-referred scale.
    pub process_ratio: f64,
    /// Process noise entering the states directly, relative likewise.
    pub state_ratio: f64,
    /// Spectral radius of `Φ - K C`, below 1 for a stable predictor.
    pub predictor_spectral_radius: f64,
}

/// Samples of the records the noise search evaluates each candidate on (the final predictor
/// runs on all of them).
const SEARCH_SAMPLES: usize = 5_000;

/// Samples at the start of each record left out of the search's criterion: the predictor's
/// start-up from the fitted starting state ([`initial_state`]) would dominate a short record.
pub(crate) const BURN_IN: usize = 50;

/// Samples after the first that a record's starting state is fitted to
/// ([`initial_state`]); the time-domain table's window.
pub(crate) const START_WINDOW: usize = super::timedomain::DEFAULT_WINDOW;

/// Multipliers of a factor tried in the refining sweeps: coarse, then fine.
const REFINE: [[f64; 4]; 2] = [[0.1, 0.3, 3.0, 10.0], [0.6, 0.8, 1.25, 1.6]];

/// Gauss-Newton steps of the free-gain refinement ([`Predictor::refine`]) at most.
const REFINE_STEPS: usize = 10;

/// The refinement stops when a step lowers the log-determinant by less than this (a relative
/// change of the innovations' generalized variance of 1e-4).
const REFINE_TOLERANCE: f64 = 1e-4;

/// The noise-covariance factors being searched: `Q = a (Q_0 + sum_k e_k Q_k) + b Q_x`, `R =
/// diag(c_i r_i)`.
#[derive(Debug, Clone)]
struct Factors {
    input: f64,
    /// `e_k`: the share of each direction the inputs reach ([`Shapes::directions`]).
    each: Vec<f64>,
    state: f64,
    sensor: Vec<f64>,
}

impl Factors {
    /// The process noise covariance.
    fn process(&self, shapes: &Shapes) -> DMatrix<f64> {
        let mut q = &shapes.floor * self.input + &shapes.state * self.state;
        for (part, e) in shapes.directions.iter().zip(&self.each) {
            q += part * (self.input * e);
        }
        q
    }
}

/// A factor the noise search moves.
#[derive(Debug, Clone, Copy)]
enum Coordinate {
    Input,
    Direction(usize),
    State,
    AllSensors,
    Sensor(usize),
}

/// The shapes the process noise is built of, each scaled to the outputs' noise.
struct Shapes {
    /// The input-referred noise `Γ Γᵀ` split along its eigenvectors, `λ_k v_k v_kᵀ`: a
    /// disturbance where the actuators act, of its own size along each direction they reach.
    /// One factor for all of them put a quadrotor stand's torque noise, equal on its three
    /// axes, 85 times too weak on the yaw (which the rotors reach through their drag alone),
    /// and the fit under that gain bent the yaw inertia 10-20 % (9-15 standard errors) to
    /// make up for it: a misfit on the true model, 4 of 4 seeds. (A share per state instead
    /// let a coloured angle sensor's drift pass for noise on the angle itself and whitened its
    /// innovations while the pendulum's stiffness fitted 7 % low, unflagged.)
    directions: Vec<DMatrix<f64>>,
    /// A floor under `Γ Γᵀ` (1e-9 of its trace on the diagonal) that keeps every state noisy.
    floor: DMatrix<f64>,
    /// Noise entering each state directly (diagonal).
    state: DMatrix<f64>,
}

impl Predictor {
    /// Designs the predictor of `disc` for the records `(u, y)` (samples x channels), its gain
    /// as `gain_choice` says.
    pub fn design(
        disc: &Discrete,
        records: &[(&DMatrix<f64>, &DMatrix<f64>)],
        gain_choice: Gain,
    ) -> Result<Self> {
        // Modes the outputs never see (a yaw angle measured only through its rate) cannot be
        // estimated and do not change the outputs: the predictor runs on the observable part.
        let (observable, split) = observable_part(disc);
        let whole_state = split.is_none();
        let hidden_decay = match &split {
            Some(s) => {
                Some(spectral_radius(&(&s.hidden * &disc.phi * s.hidden.transpose()))? < 1.0)
            }
            None => None,
        };
        let disc = &observable;
        let (n, p) = (disc.phi.nrows(), disc.c.nrows());
        let r: Vec<f64> = difference_variance(records.iter().map(|(_, y)| *y), p)
            .into_iter()
            .map(|v| v.max(1e-300))
            .collect();
        // The search runs on the first samples of each record, SEARCH_SAMPLES in all.
        let total: usize = records.iter().map(|(_, y)| y.nrows()).sum();
        let share = (SEARCH_SAMPLES as f64 / total.max(1) as f64).min(1.0);
        let search: Vec<Segment> = records
            .iter()
            .map(|(u, y)| {
                let rows =
                    ((y.nrows() as f64 * share) as usize).clamp(y.nrows().min(64), y.nrows());
                Segment::new(
                    disc,
                    u.rows(0, rows).into_owned(),
                    y.rows(0, rows).into_owned(),
                )
            })
            .collect();
        let gu = &disc.gamma0 * disc.gamma0.transpose() + &disc.gamma1 * disc.gamma1.transpose();
        let trace = gu.trace().max(1e-300);
        let floor = DMatrix::identity(n, n) * (1e-9 * trace / n as f64);
        let output_scale = |g: &DMatrix<f64>| {
            (r.iter().sum::<f64>() / p as f64)
                / ((&disc.c * g * disc.c.transpose()).trace() / p as f64).max(1e-300)
        };
        let scale = output_scale(&(&gu + &floor));
        let eigen = gu.clone().symmetric_eigen();
        let largest = eigen.eigenvalues.amax();
        let directions: Vec<DMatrix<f64>> = (0..n)
            .filter(|&k| eigen.eigenvalues[k] > 1e-9 * largest)
            .map(|k| {
                let v = eigen.eigenvectors.column(k);
                v * v.transpose() * (eigen.eigenvalues[k] * scale)
            })
            .collect();
        let mut shapes = Shapes {
            directions,
            floor: floor * scale,
            state: DMatrix::zeros(n, n),
        };
        // Noise entering each state directly (a disturbance that does not come through the
        // inputs), in proportion to how much the state moves per sample.
        let mut f = Factors {
            input: 1.0,
            each: vec![1.0; shapes.directions.len()],
            state: 0.0,
            sensor: vec![1.0; p],
        };
        let mut best = (f64::INFINITY, None);
        for ratio in RATIOS {
            f.input = ratio;
            if let Ok((ld, k)) = Self::score(disc, &shapes, &r, &f, &search) {
                if ld < best.0 {
                    best = (ld, Some((f.clone(), k)));
                }
            }
        }
        let Some((mut f, k0)) = best.1.clone() else {
            let q = f.process(&shapes);
            let rm = DMatrix::from_diagonal(&DVector::from_vec(r.clone()));
            return Err(gain(disc, &q, &rm).err().unwrap_or_else(|| {
                SimError::invalid(
                    "Kalman predictor",
                    "no noise ratio",
                    "gave a finite innovation covariance",
                )
            }));
        };
        let first = Self {
            disc: disc.clone(),
            gain: k0,
            covariances: None,
            state_gain: None,
            noise: Self::estimate(&r, &f, 0.0),
        };
        let mut motion = vec![0.0; n];
        let mut steps = 0usize;
        for segment in &search {
            let (_, xs) = first.run_from(&segment.u, &segment.y, segment.start.clone());
            for k in 1..xs.nrows() {
                for i in 0..n {
                    motion[i] += (xs[(k, i)] - xs[(k - 1, i)]).powi(2);
                }
                steps += 1;
            }
        }
        let mut qx = DMatrix::zeros(n, n);
        for i in 0..n {
            qx[(i, i)] = (motion[i] / steps.max(1) as f64).max(1e-12 * trace);
        }
        shapes.state = &qx * output_scale(&qx);
        // The state noise starts from its absolute grid; the coarse sweep refines the input
        // and state factors and all sensor factors together, then each input direction's
        // share and each sensor's factor (with more than one), the fine sweep each factor. (A
        // sensor's first differences also hold the motion of its output per sample: a
        // reaction wheel's speed, driven by the torque noise, read 18 times its sensor noise
        // while the angle read 2.5 times; with the sensors moved only together and each by
        // at most 1.6 after, the wheel's stayed 18 times too large, the gain too low there,
        // and the true model read a misfit with its inertia 4 standard errors off. Sweeping
        // each grid until it stopped gaining changed nothing on that rig's logs once each
        // record started from its fitted state, and made the flying platform's discovery 1.5
        // times slower.)
        let directions = shapes.directions.len();
        let shares = (0..directions)
            .filter(|_| directions > 1)
            .map(Coordinate::Direction);
        let coarse: Vec<Coordinate> =
            [Coordinate::Input, Coordinate::State, Coordinate::AllSensors]
                .into_iter()
                .chain(shares.clone())
                .chain((0..p).filter(|_| p > 1).map(Coordinate::Sensor))
                .collect();
        let fine: Vec<Coordinate> = [Coordinate::Input, Coordinate::State]
            .into_iter()
            .chain(shares)
            .chain((0..p).map(Coordinate::Sensor))
            .collect();
        let mut sweep = |coordinates: &[Coordinate], multipliers: Option<&[f64]>| {
            for &coordinate in coordinates {
                let keep = f.clone();
                let current = match coordinate {
                    Coordinate::Input => keep.input,
                    Coordinate::Direction(k) => keep.each[k],
                    Coordinate::State => keep.state,
                    Coordinate::AllSensors => 1.0,
                    Coordinate::Sensor(i) => keep.sensor[i],
                };
                let grid: Vec<f64> = match multipliers {
                    None => RATIOS.to_vec(),
                    Some(_) if current == 0.0 => Vec::new(),
                    Some(m) => m.iter().map(|m| m * current).collect(),
                };
                for v in grid {
                    let mut t = keep.clone();
                    match coordinate {
                        Coordinate::Input => t.input = v,
                        Coordinate::Direction(k) => t.each[k] = v,
                        Coordinate::State => t.state = v,
                        Coordinate::AllSensors => t.sensor.iter_mut().for_each(|c| *c *= v),
                        Coordinate::Sensor(i) => t.sensor[i] = v,
                    }
                    if let Ok((ld, k)) = Self::score(disc, &shapes, &r, &t, &search) {
                        if ld < best.0 {
                            best = (ld, Some((t.clone(), k)));
                            f = t;
                        }
                    }
                }
            }
        };
        sweep(&[Coordinate::State], None);
        sweep(&coarse, Some(&REFINE[0]));
        sweep(&fine, Some(&REFINE[1]));
        let (f, gain) = best.1.unwrap_or((f, first.gain));
        let gain = match gain_choice {
            Gain::NoiseModel => gain,
            Gain::Refined => Self::refine(disc, gain, &search),
        };
        let covariances = whole_state.then(|| {
            (
                f.process(&shapes),
                DMatrix::from_fn(p, p, |i, j| if i == j { r[i] * f.sensor[i] } else { 0.0 }),
            )
        });
        let rho = spectral_radius(&(&disc.phi - &gain * &disc.c))?;
        // The error in modes the outputs do not see evolves by itself: a gain that leaves
        // them alone is stable when they decay (the pair is detectable).
        let state_gain = match (&split, hidden_decay) {
            (None, _) => Some(gain.clone()),
            (Some(split), Some(true)) => Some(split.observable.transpose() * &gain),
            _ => None,
        };
        Ok(Self {
            disc: disc.clone(),
            gain,
            covariances,
            state_gain,
            noise: Self::estimate(&r, &f, rho),
        })
    }

    /// The designed noise covariances `(Q, R)` when every state is observable.
    pub fn covariances(&self) -> Option<&(DMatrix<f64>, DMatrix<f64>)> {
        self.covariances.as_ref()
    }

    /// The gain for the model's whole state (states x outputs): the design's when every
    /// state is observable; otherwise the observable part's, zero on the modes the outputs do
    /// not see, when those decay (a lag far shorter than the sample period, which one step
    /// forgets); `None` when one of them does not.
    pub fn state_gain(&self) -> Option<&DMatrix<f64>> {
        self.state_gain.as_ref()
    }

    fn estimate(r: &[f64], f: &Factors, rho: f64) -> NoiseEstimate {
        NoiseEstimate {
            sensor_variance: r.iter().zip(&f.sensor).map(|(v, c)| v * c).collect(),
            process_ratio: f.input,
            state_ratio: f.state,
            predictor_spectral_radius: rho,
        }
    }

    /// Log-determinant of the sample innovation covariance of the design `f`, and its gain.
    fn score(
        disc: &Discrete,
        shapes: &Shapes,
        r: &[f64],
        f: &Factors,
        records: &[Segment],
    ) -> Result<(f64, DMatrix<f64>)> {
        let p = r.len();
        let q = f.process(shapes);
        let rm = DMatrix::from_fn(p, p, |i, j| if i == j { r[i] * f.sensor[i] } else { 0.0 });
        let k = gain(disc, &q, &rm)?;
        let logdet = log_det(&Self::with_gain(disc, &k).innovations(records));
        if !logdet.is_finite() {
            return Err(SimError::invalid(
                "Kalman predictor",
                "innovation covariance",
                "is singular",
            ));
        }
        Ok((logdet, k))
    }

    /// A predictor of `disc` with the gain `k` and nothing estimated: what the searches run.
    fn with_gain(disc: &Discrete, k: &DMatrix<f64>) -> Self {
        Self {
            disc: disc.clone(),
            gain: k.clone(),
            covariances: None,
            state_gain: None,
            noise: NoiseEstimate {
                sensor_variance: Vec::new(),
                process_ratio: 0.0,
                state_ratio: 0.0,
                predictor_spectral_radius: 0.0,
            },
        }
    }

    /// The innovations on `records`, each record's first [`BURN_IN`] samples left out (the
    /// predictor's start-up), stacked (samples x outputs).
    fn innovations(&self, records: &[Segment]) -> DMatrix<f64> {
        let parts: Vec<DMatrix<f64>> = records
            .iter()
            .map(|s| {
                let (e, _) = self.run_from(&s.u, &s.y, s.start.clone());
                let from = BURN_IN.min(e.nrows() / 2);
                e.rows(from, e.nrows() - from).into_owned()
            })
            .collect();
        let rows = parts.iter().map(|e| e.nrows()).sum();
        let mut all = DMatrix::zeros(rows, self.disc.c.nrows());
        let mut at = 0;
        for e in parts {
            all.rows_mut(at, e.nrows()).copy_from(&e);
            at += e.nrows();
        }
        all
    }

    /// The gain that minimises the log-determinant of the innovation covariance over all
    /// gains near `k0` (the noise family's best), each entry free: Gauss-Newton steps on the
    /// innovations weighted by the inverse of their current covariance (forward-difference
    /// Jacobian), each kept only when the log-determinant falls and `Φ - K C` stays stable.
    /// A disturbance that enters neither where the inputs do nor one state alone (a torque on
    /// a balancing body moves its angle and the wheels' position together) gets its
    /// correlated direction this way, which the family's diagonal cannot give.
    fn refine(disc: &Discrete, k0: DMatrix<f64>, records: &[Segment]) -> DMatrix<f64> {
        let innovations = |k: &DMatrix<f64>| Self::with_gain(disc, k).innovations(records);
        let stable =
            |k: &DMatrix<f64>| spectral_radius(&(&disc.phi - k * &disc.c)).is_ok_and(|r| r < 1.0);
        let mut k = k0;
        let mut e = innovations(&k);
        let mut current = log_det(&e);
        let mut damping = 1e-3;
        for _ in 0..REFINE_STEPS {
            let Some(whiten) = (e.transpose() * &e / e.nrows().max(1) as f64)
                .try_inverse()
                .and_then(|w| w.cholesky())
                .map(|l| l.l())
            else {
                break;
            };
            let residual = |e: &DMatrix<f64>| {
                let w = e * &whiten;
                DVector::from_column_slice(w.as_slice())
            };
            let r0 = residual(&e);
            let entries = k.len();
            let mut jac = DMatrix::zeros(r0.len(), entries);
            // Steps relative to each state's row of the gain: the rows carry the states'
            // units, which may differ by orders of magnitude.
            let rows: Vec<f64> = (0..k.nrows())
                .map(|i| k.row(i).amax())
                .map(|a| if a > 0.0 { a } else { k.amax() })
                .map(|a| if a > 0.0 { a } else { 1.0 })
                .collect();
            for j in 0..entries {
                let step = 1e-6 * (k[j].abs() + 1e-3 * rows[j % k.nrows()]);
                let mut shifted = k.clone();
                shifted[j] += step;
                jac.set_column(j, &((residual(&innovations(&shifted)) - &r0) / step));
            }
            let jtj = jac.transpose() * &jac;
            let grad = jac.transpose() * &r0;
            let mut improved = false;
            while damping < 1e8 {
                let mut m = jtj.clone();
                for i in 0..entries {
                    m[(i, i)] += damping * jtj[(i, i)].max(1e-300);
                }
                let Some(delta) = m.cholesky().map(|c| c.solve(&(-&grad))) else {
                    damping *= 10.0;
                    continue;
                };
                let trial = &k + DMatrix::from_column_slice(k.nrows(), k.ncols(), delta.as_slice());
                let e_trial = innovations(&trial);
                let value = log_det(&e_trial);
                if value < current && stable(&trial) {
                    improved = current - value > REFINE_TOLERANCE;
                    (k, e, current) = (trial, e_trial, value);
                    damping = (damping / 10.0).max(1e-9);
                    break;
                }
                damping *= 10.0;
            }
            if !improved {
                break;
            }
        }
        k
    }

    /// `Γ0 u_{k-w} + Γ1 u_{k-w-1}` per sample (rows), zero before the inputs start.
    fn input_drive(&self, u: &DMatrix<f64>) -> DMatrix<f64> {
        let d = &self.disc;
        shifted(u, d.whole) * d.gamma0.transpose() + shifted(u, d.whole + 1) * d.gamma1.transpose()
    }

    /// Innovations `y_k - ŷ_{k|k-1}` and the one-step predicted states, per sample, from the
    /// state fitted to the record's first outputs ([`initial_state`]). The recursion
    /// `x_{k+1} = (Φ - K C) x_k + drive_k` runs on whole-record products.
    pub fn run(&self, u: &DMatrix<f64>, y: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
        self.run_from(u, y, initial_state(&self.disc, u, y, None))
    }

    /// [`Predictor::run`] from the starting state `x`.
    fn run_from(
        &self,
        u: &DMatrix<f64>,
        y: &DMatrix<f64>,
        mut x: DVector<f64>,
    ) -> (DMatrix<f64>, DMatrix<f64>) {
        let d = &self.disc;
        let (n, samples) = (d.phi.nrows(), y.nrows());
        let feed = shifted(u, d.d_shift) * d.d.transpose();
        let drive = (self.input_drive(u) + (y - &feed) * self.gain.transpose()).transpose();
        let f = &d.phi - &self.gain * &d.c;
        let mut xs = DMatrix::zeros(n, samples);
        for k in 0..samples {
            xs.set_column(k, &x);
            let mut next = drive.column(k).into_owned();
            next.gemv(1.0, &f, &x, 1.0);
            x = next;
        }
        let xs = xs.transpose();
        let e = y - &xs * d.c.transpose() - feed;
        (e, xs)
    }

    /// `k`-step-ahead output predictions: sample `t` predicted from the one-step state at
    /// `t - k + 1` (data up to `t - k`) propagated with the logged inputs (rows before `k - 1`
    /// are zero). Each propagation step is one product over the whole record.
    pub fn predict(&self, u: &DMatrix<f64>, xs: &DMatrix<f64>, k: usize) -> DMatrix<f64> {
        let d = &self.disc;
        let g = shifted(&self.input_drive(u), 1);
        let phi_t = d.phi.transpose();
        let mut z = xs.clone();
        for _ in 1..k {
            z = shifted(&z, 1) * &phi_t + &g;
        }
        let mut out = z * d.c.transpose() + shifted(u, d.d_shift) * d.d.transpose();
        let invalid = (k.max(1) - 1).min(out.nrows());
        out.rows_mut(0, invalid).fill(0.0);
        out
    }
}

/// A record the noise search runs on, with its starting state ([`initial_state`]): that
/// depends on the model and the data alone, so it is fitted once for every gain tried.
struct Segment {
    u: DMatrix<f64>,
    y: DMatrix<f64>,
    start: DVector<f64>,
}

impl Segment {
    fn new(disc: &Discrete, u: DMatrix<f64>, y: DMatrix<f64>) -> Self {
        let start = initial_state(disc, &u, &y, None);
        Self { u, y, start }
    }
}

/// Half the mean squared first difference of each of the `p` outputs, pooled over `records`
/// (samples x outputs): white sensor noise of variance σ² gives σ², a signal that moves
/// little per sample adds little.
fn difference_variance<'a>(
    records: impl IntoIterator<Item = &'a DMatrix<f64>>,
    p: usize,
) -> Vec<f64> {
    let mut sum = vec![0.0; p];
    let mut count = 0usize;
    for y in records {
        for k in 1..y.nrows() {
            for (i, s) in sum.iter_mut().enumerate() {
                *s += (y[(k, i)] - y[(k - 1, i)]).powi(2);
            }
            count += 1;
        }
    }
    sum.iter()
        .map(|s| s / (2.0 * count.max(1) as f64))
        .collect()
}

/// The state of `disc` at a record's first sample fitted by least squares to its first
/// [`START_WINDOW`] + 1 outputs, each weighted by the inverse of its first differences' scale
/// over the record (minimum norm on directions the window does not see); `offsets` are the
/// operating point's inputs and outputs, which `disc` deviates from (none: zero). From the
/// zero state the start-up lasts as long as the predictor's slowest mode: a reaction wheel's
/// speed, 0.13 rad/s from its record's mean at the start and corrected with a spectral radius
/// of 0.998, moved the noise search's optimum (on the records' first samples) to an angle
/// sensor noise a third of the true one, and the angle's innovations read correlated at -0.04
/// on the true model; the extended predictor, started at the operating point while the
/// pendulum leaned 0.01 rad, read them correlated at +0.17.
pub(crate) fn initial_state(
    disc: &Discrete,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
    offsets: Option<(&[f64], &[f64])>,
) -> DVector<f64> {
    let (n, p) = (disc.phi.nrows(), disc.c.nrows());
    let rows = y.nrows().min(u.nrows()).min(START_WINDOW + 1);
    let zero = DVector::zeros(n);
    if rows < 2 || n == 0 {
        return zero;
    }
    let scale: Vec<f64> = difference_variance([y], p)
        .into_iter()
        .map(f64::sqrt)
        .collect();
    let largest = scale.iter().copied().fold(0.0, f64::max);
    let weight: Vec<f64> = scale
        .iter()
        .map(|s| 1.0 / s.max(1e-12 * largest).max(f64::MIN_POSITIVE))
        .collect();
    let (mut du, mut dy) = (u.rows(0, rows).into_owned(), y.rows(0, rows).into_owned());
    if let Some((u_op, y_op)) = offsets {
        for k in 0..rows {
            for (j, v) in u_op.iter().enumerate() {
                du[(k, j)] -= v;
            }
            for (i, v) in y_op.iter().enumerate() {
                dy[(k, i)] -= v;
            }
        }
    }
    let feed = shifted(&du, disc.d_shift) * disc.d.transpose();
    let drive = shifted(&du, disc.whole) * disc.gamma0.transpose()
        + shifted(&du, disc.whole + 1) * disc.gamma1.transpose();
    // `y_k - D u_k - C x_forced,k = C Φ^k x_0`, stacked and weighted.
    let mut o = DMatrix::zeros(rows * p, n);
    let mut z = DVector::zeros(rows * p);
    let mut power = DMatrix::identity(n, n);
    let mut forced = DVector::zeros(n);
    for k in 0..rows {
        let cp = &disc.c * &power;
        let out = &disc.c * &forced;
        for i in 0..p {
            o.row_mut(k * p + i).copy_from(&(cp.row(i) * weight[i]));
            z[k * p + i] = (dy[(k, i)] - feed[(k, i)] - out[i]) * weight[i];
        }
        power = &disc.phi * power;
        forced = &disc.phi * forced + drive.row(k).transpose();
    }
    if o.iter().chain(z.iter()).any(|v| !v.is_finite()) {
        return zero;
    }
    let svd = o.svd(true, true);
    let tol = (1e-9 * svd.singular_values.max()).max(f64::MIN_POSITIVE);
    svd.solve(&z, tol)
        .ok()
        .filter(|x| x.iter().all(|v| v.is_finite()))
        .unwrap_or(zero)
}

/// Log-determinant of the sample covariance of `e` (samples x outputs); infinite when singular.
fn log_det(e: &DMatrix<f64>) -> f64 {
    let s = e.transpose() * e / e.nrows().max(1) as f64;
    s.cholesky()
        .map(|c| 2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>())
        .filter(|v| v.is_finite())
        .unwrap_or(f64::INFINITY)
}

/// Relative singular value below which a direction of the observability matrix counts as
/// unobservable.
const OBSERVABLE: f64 = 1e-9;

/// Orthonormal bases (rows) of a model's observable subspace and of its complement.
struct Split {
    observable: DMatrix<f64>,
    hidden: DMatrix<f64>,
}

/// The restriction of `disc` to its observable subspace (exact for the outputs: the
/// unobservable subspace is invariant under Φ and in the kernel of C). The predicted states
/// are then coordinates of that subspace. With it the split, when some state is unobservable.
fn observable_part(disc: &Discrete) -> (Discrete, Option<Split>) {
    let (n, p) = (disc.phi.nrows(), disc.c.nrows());
    let mut o = DMatrix::zeros(n * p, n);
    let mut block = disc.c.clone();
    for i in 0..n {
        o.view_mut((i * p, 0), (p, n)).copy_from(&block);
        block = &block * &disc.phi;
    }
    if o.iter().any(|v| !v.is_finite()) {
        // Φ^i overflowed: no rank decision; the design's Riccati equation names the problem.
        return (disc.clone(), None);
    }
    // Normalise so that the rank decision does not depend on the growth of Φ^i.
    let scale = o.amax().max(1e-300);
    let svd = (o / scale).svd(false, true);
    let Some(v_t) = svd.v_t else {
        return (disc.clone(), None);
    };
    let top = svd.singular_values.max();
    let (keep, drop): (Vec<usize>, Vec<usize>) = (0..n)
        .partition(|&i| i < svd.singular_values.len() && svd.singular_values[i] > OBSERVABLE * top);
    if drop.is_empty() {
        return (disc.clone(), None);
    }
    let rows = |idx: &[usize]| DMatrix::from_fn(idx.len(), n, |r, c| v_t[(idx[r], c)]);
    let t = rows(&keep);
    let part = Discrete {
        phi: &t * &disc.phi * t.transpose(),
        gamma0: &t * &disc.gamma0,
        gamma1: &t * &disc.gamma1,
        c: &disc.c * t.transpose(),
        d: disc.d.clone(),
        whole: disc.whole,
        d_shift: disc.d_shift,
    };
    let hidden = rows(&drop);
    (
        part,
        Some(Split {
            observable: t,
            hidden,
        }),
    )
}

/// `m` moved down by `s` rows (row k holds row k - s), zeros above.
fn shifted(m: &DMatrix<f64>, s: usize) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(m.nrows(), m.ncols());
    if s < m.nrows() {
        let rows = m.nrows() - s;
        out.rows_mut(s, rows).copy_from(&m.rows(0, rows));
    }
    out
}

/// `K = Φ P Cᵀ (C P Cᵀ + R)^-1`, `P` the stabilizing solution of the filter Riccati equation.
///
/// Solved in balanced coordinates `x̃ = T x`, `T` diagonal with each state's process noise
/// brought to the sensors' mean variance, then mapped back (`K = T⁻¹ K̃`): the gain does not
/// depend on the states' units, but the Riccati solver's checks have absolute floors. (A
/// magnetic bearing modelled in metres and measured in micrometres had its process noise,
/// 1e-18 of the sensors', read as reaching no mode: innovations correlated at -0.31, white
/// with the same model in micrometres.)
fn gain(disc: &Discrete, q: &DMatrix<f64>, r: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = q.nrows();
    let sensor = r.diagonal().mean();
    let t: Vec<f64> = (0..n)
        .map(|i| {
            let v = (sensor / q[(i, i)]).sqrt();
            if v.is_finite() && v > 0.0 {
                v
            } else {
                1.0
            }
        })
        .collect();
    let phi = DMatrix::from_fn(n, n, |i, j| t[i] * disc.phi[(i, j)] / t[j]);
    let c = DMatrix::from_fn(disc.c.nrows(), n, |i, j| disc.c[(i, j)] / t[j]);
    let q = DMatrix::from_fn(n, n, |i, j| t[i] * q[(i, j)] * t[j]);
    let (phi_t, c_t) = (phi.transpose(), c.transpose());
    // The gain is the same for (Q, R) scaled together.
    let scale = q.amax().max(r.amax());
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let (q, r) = (q / scale, r / scale);
    let p = rigid_body::lti::dare(&phi_t, &c_t, &q, &r).map_err(|e| {
        SimError::domain(
            "Kalman predictor (is the model detectable from its outputs?)",
            e,
        )
    })?;
    let s = &c * &p * &c_t + &r;
    let s_inv = s
        .try_inverse()
        .ok_or_else(|| SimError::invalid("Kalman predictor", "C P C^T + R", "is singular"))?;
    let k = &phi * p * c_t * s_inv;
    Ok(DMatrix::from_fn(k.nrows(), k.ncols(), |i, j| {
        k[(i, j)] / t[i]
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::StateSpace;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};
    use rand_distr::StandardNormal;

    fn scalar(a: f64) -> Discrete {
        Discrete {
            phi: DMatrix::from_element(1, 1, a),
            gamma0: DMatrix::from_element(1, 1, 1.0),
            gamma1: DMatrix::zeros(1, 1),
            c: DMatrix::from_element(1, 1, 1.0),
            d: DMatrix::zeros(1, 1),
            whole: 0,
            d_shift: 0,
        }
    }

    /// The gain equals the fixed point of the scalar Riccati recursion
    /// `P <- a²P - a²P²/(P + r) + q`, `K = a P / (P + r)`.
    #[test]
    fn gain_is_the_stationary_riccati_gain() {
        for (a, q, r) in [(0.9, 1.0, 2.0), (1.05, 0.1, 0.5), (0.3, 2.0, 0.01)] {
            let mut p = q;
            for _ in 0..10_000 {
                p = a * a * p - a * a * p * p / (p + r) + q;
            }
            let k = gain(
                &scalar(a),
                &DMatrix::from_element(1, 1, q),
                &DMatrix::from_element(1, 1, r),
            )
            .unwrap();
            assert!((k[(0, 0)] - a * p / (p + r)).abs() < 1e-10, "{a} {q} {r}");
        }
    }

    /// Noise covariances scaled together give the same gain, down to signals of 1e-10
    /// units (covariances of 1e-20), where the Riccati checks' absolute floor called the
    /// process noise unable to reach the unstable mode.
    #[test]
    fn the_gain_does_not_depend_on_the_signals_units() {
        let plant = unstable_plant();
        let q = DMatrix::from_row_slice(2, 2, &[1e-4, 0.0, 0.0, 1e-2]);
        let r = DMatrix::from_element(1, 1, 1e-6);
        let k = gain(&plant, &q, &r).unwrap();
        for scale in [1e-20, 1e20] {
            let ks = gain(&plant, &(&q * scale), &(&r * scale)).unwrap();
            assert!((&ks - &k).norm() < 1e-9 * k.norm(), "{scale}: {ks} {k}");
        }
    }

    /// The same plant with its states in another unit (`x̃ = s x`: Γ times s, C over s) gets
    /// the same innovations and the gain times s, whichever gain it is designed for, on 3
    /// seeds. Before the balancing, states in metres measured in micrometres (s = 1e-6 here)
    /// had their process noise read as reaching no mode.
    #[test]
    fn the_predictor_does_not_depend_on_the_states_units() {
        let plant = unstable_plant();
        for seed in 0..3u64 {
            let (u, y) = closed_loop(&plant, seed);
            for choice in [Gain::NoiseModel, Gain::Refined] {
                let own = Predictor::design(&plant, &[(&u, &y)], choice).unwrap();
                let e = own.run(&u, &y).0;
                for s in [1e-6, 1e6] {
                    let scaled = Discrete {
                        gamma0: &plant.gamma0 * s,
                        gamma1: &plant.gamma1 * s,
                        c: &plant.c / s,
                        ..plant.clone()
                    };
                    let other = Predictor::design(&scaled, &[(&u, &y)], choice).unwrap();
                    let es = other.run(&u, &y).0;
                    assert!((&es - &e).norm() < 1e-6 * e.norm(), "seed {seed}, s {s}");
                    let (k, ks) = (own.state_gain().unwrap(), other.state_gain().unwrap());
                    assert!(
                        (ks - k * s).norm() < 1e-6 * k.norm() * s,
                        "seed {seed}, s {s}"
                    );
                }
            }
        }
    }

    /// An unstable two-state plant sampled at 10 ms, its position measured.
    fn unstable_plant() -> Discrete {
        let ss = StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 9.0, -0.2]),
            b: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
            c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            d: DMatrix::zeros(1, 1),
            delay: 0.0,
        };
        ss.discretize(0.01).unwrap()
    }

    /// 6000 samples of `disc` (two states first) under a stabilizing feedback and a sine,
    /// with process noise through the input and sensor noise: `(u, y)`.
    fn closed_loop(disc: &Discrete, seed: u64) -> (DMatrix<f64>, DMatrix<f64>) {
        let mut rng = StdRng::seed_from_u64(seed);
        let n = 6000;
        let (mut u, mut y) = (DMatrix::zeros(n, 1), DMatrix::zeros(n, 1));
        let mut x = DVector::zeros(disc.phi.nrows());
        for k in 0..n {
            y[(k, 0)] = x[0] + 1e-3 * rng.sample::<f64, _>(StandardNormal);
            let r = (0.3 * k as f64).sin();
            u[(k, 0)] = -40.0 * y[(k, 0)] - 8.0 * x[1] + r;
            let w = 0.5 * rng.sample::<f64, _>(StandardNormal);
            x = &disc.phi * &x + &disc.gamma0 * (u[(k, 0)] + w);
        }
        (u, y)
    }

    /// A third state the output never sees, driven by the plant: when it decays, the whole
    /// state's gain leaves it alone (a zero row), and the extended predictor's form, that gain
    /// on all three states, is stable and has white innovations (the band of the whiteness
    /// test below, 3 seeds); when it does not (an integrator), there is no gain, and the
    /// extended predictor, which has no other, must refuse the model.
    #[test]
    fn a_hidden_mode_gets_no_gain_and_must_decay() {
        let plant = unstable_plant();
        for (pole, decays) in [(0.0, true), (0.6, true), (1.0, false)] {
            let mut phi = DMatrix::zeros(3, 3);
            phi.view_mut((0, 0), (2, 2)).copy_from(&plant.phi);
            phi[(2, 0)] = 0.3;
            phi[(2, 2)] = pole;
            let three = Discrete {
                phi,
                gamma0: plant.gamma0.clone().insert_row(2, 0.0),
                gamma1: plant.gamma1.clone().insert_row(2, 0.0),
                c: plant.c.clone().insert_column(2, 0.0),
                ..plant.clone()
            };
            for seed in 0..3u64 {
                let (u, y) = closed_loop(&plant, seed);
                let design = Predictor::design(&three, &[(&u, &y)], Gain::Refined).unwrap();
                assert!(design.covariances().is_none());
                match design.state_gain() {
                    Some(k) if decays => {
                        assert!(k[(2, 0)].abs() < 1e-12, "pole {pole}: {k}");
                        let whole = Predictor {
                            disc: three.clone(),
                            gain: k.clone(),
                            covariances: None,
                            state_gain: None,
                            noise: design.noise.clone(),
                        };
                        assert!(spectral_radius(&(&three.phi - k * &three.c)).unwrap() < 1.0);
                        let (e, _) = whole.run(&u, &y);
                        assert_white(&e, &format!("pole {pole} seed {seed}"));
                    }
                    None => assert!(!decays, "pole {pole}: no gain"),
                    Some(k) => panic!("pole {pole}: a gain {k} for a mode that does not decay"),
                }
            }
        }
    }

    /// Lags 1-10 of the first column of `e` (after 100 samples) inside the band of a 1 %
    /// family-wise test (z = 3.29 for ten lags, as in the residual tests).
    fn assert_white(e: &DMatrix<f64>, label: &str) {
        let e: Vec<f64> = e.column(0).iter().skip(100).copied().collect();
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let var: f64 = e.iter().map(|v| (v - mean).powi(2)).sum();
        let band = 3.29 / (e.len() as f64).sqrt();
        for lag in 1..=10 {
            let c: f64 = (lag..e.len())
                .map(|i| (e[i] - mean) * (e[i - lag] - mean))
                .sum();
            assert!((c / var).abs() < band, "{label} lag {lag}: {}", c / var);
        }
    }

    /// A balancing body on wheels at 5 ms (position and angle measured): the input and a
    /// torque disturbance enter the two accelerations in different proportions, so the
    /// disturbance is neither where the input enters nor on one state. The designed
    /// predictor's innovations are white on both outputs (the band above, 5 seeds) and their
    /// generalized variance is the true Kalman predictor's (`C P Cᵀ + R` of the true `Q`,
    /// `R`: an independent reference) to within 0.05 in the log-determinant (its sampling
    /// spread over 5950 samples is about 0.03).
    #[test]
    fn a_disturbance_in_its_own_direction_gets_the_true_kalman_predictor() {
        let ss = |b: &[f64]| StateSpace {
            a: DMatrix::from_row_slice(
                4,
                4,
                &[
                    0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -2.0, 0.0, 0.0, 0.0, 20.0, 0.0,
                    0.0,
                ],
            ),
            b: DMatrix::from_column_slice(4, 1, b),
            c: DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]),
            d: DMatrix::zeros(2, 1),
            delay: 0.0,
        };
        let t = 0.005;
        let disc = ss(&[0.0, 0.0, 1.0, -3.0]).discretize(t).unwrap();
        let torque = ss(&[0.0, 0.0, 1.0, 1.0]).discretize(t).unwrap().gamma0;
        let (sw, sv) = (2.0, [1e-3, 2e-3]);
        let lqr = rigid_body::lti::dlqr(
            &disc.phi,
            &disc.gamma0,
            &DMatrix::identity(4, 4),
            &DMatrix::from_element(1, 1, 1.0),
        )
        .unwrap();
        let q = &torque * torque.transpose() * (sw * sw);
        let r = DMatrix::from_diagonal(&DVector::from_iterator(2, sv.iter().map(|s| s * s)));
        let p = rigid_body::lti::dare(&disc.phi.transpose(), &disc.c.transpose(), &q, &r).unwrap();
        let truth = (&disc.c * p * disc.c.transpose() + &r).determinant().ln();
        for seed in 0..5u64 {
            let mut rng = StdRng::seed_from_u64(seed);
            let n = 6000;
            let (mut u, mut y) = (DMatrix::zeros(n, 1), DMatrix::zeros(n, 2));
            let mut x = DVector::zeros(4);
            for k in 0..n {
                for i in 0..2 {
                    y[(k, i)] = x[i] + sv[i] * rng.sample::<f64, _>(StandardNormal);
                }
                let excitation = 0.5 * rng.sample::<f64, _>(StandardNormal);
                u[(k, 0)] = -(&lqr.k * &x)[0] + excitation;
                let w = sw * rng.sample::<f64, _>(StandardNormal);
                x = &disc.phi * &x + &disc.gamma0 * u[(k, 0)] + &torque * w;
            }
            let kp = Predictor::design(&disc, &[(&u, &y)], Gain::Refined).unwrap();
            let (e, _) = kp.run(&u, &y);
            let e = e.rows(50, n - 50).into_owned();
            let got = (e.transpose() * &e / e.nrows() as f64).determinant().ln();
            assert!(
                (got - truth).abs() < 0.05,
                "seed {seed}: {got} against {truth}"
            );
            for i in 0..2 {
                assert_white(
                    &e.columns(i, 1).into_owned(),
                    &format!("seed {seed} output {i}"),
                );
            }
        }
    }

    /// Simulated from an unstable two-state model with process noise through the input and
    /// white sensor noise, fed back by a stabilizing gain: the designed predictor's
    /// innovations are white (lags 1-10 inside the band of a 1 % family-wise test, z = 3.29
    /// for ten lags as in the residual tests, 5 seeds), its k-step
    /// predictions equal a per-sample propagation, and it is stable.
    #[test]
    fn innovations_of_the_true_model_are_white() {
        let disc = unstable_plant();
        for seed in 0..5u64 {
            let (u, y) = closed_loop(&disc, seed);
            let n = u.nrows();
            let kp = Predictor::design(&disc, &[(&u, &y)], Gain::NoiseModel).unwrap();
            assert!(kp.noise.predictor_spectral_radius < 1.0);
            let (e, xs) = kp.run(&u, &y);
            assert_white(&e, &format!("seed {seed}"));
            let k = 5;
            let fast = kp.predict(&u, &xs, k);
            for t in [k - 1, 500, n - 1] {
                let mut z = xs.row(t + 1 - k).transpose();
                for j in (t + 1 - k)..t {
                    z = &disc.phi * z + &disc.gamma0 * u[(j, 0)];
                }
                assert!((fast[(t, 0)] - z[0]).abs() < 1e-12, "t = {t}");
            }
        }
    }

    /// On a noise-free record of the unstable plant the fitted starting state is the true one
    /// (1e-9 of it), with and without an operating point's offsets, and the predictor's
    /// innovations are zero from the first sample (1e-9 of the output's range).
    #[test]
    fn the_starting_state_is_the_one_the_first_outputs_fix() {
        let disc = unstable_plant();
        let x0 = DVector::from_vec(vec![0.02, -0.15]);
        let n = 300;
        let (mut u, mut y) = (DMatrix::zeros(n, 1), DMatrix::zeros(n, 1));
        let mut x = x0.clone();
        for k in 0..n {
            y[(k, 0)] = x[0];
            // A stabilizing feedback and a sine keep the record bounded and moving.
            u[(k, 0)] = 0.3 * (0.17 * k as f64).sin() - 40.0 * x[0] - 8.0 * x[1];
            x = &disc.phi * &x + &disc.gamma0 * u[(k, 0)];
        }
        let fitted = initial_state(&disc, &u, &y, None);
        assert!((&fitted - &x0).amax() < 1e-9 * x0.amax(), "{fitted}");
        let (u_op, y_op) = ([2.0], [0.7]);
        let offset = initial_state(
            &disc,
            &u.map(|v| v + u_op[0]),
            &y.map(|v| v + y_op[0]),
            Some((&u_op, &y_op)),
        );
        assert!((&offset - &x0).amax() < 1e-9 * x0.amax(), "{offset}");
        let kp = Predictor::design(&disc, &[(&u, &y)], Gain::NoiseModel).unwrap();
        let (e, _) = kp.run(&u, &y);
        let range = y.max() - y.min();
        assert!(e.amax() < 1e-9 * range, "{:.3e} of {range:.3e}", e.amax());
    }
}
