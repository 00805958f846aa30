//! Networked closed-loop simulation: plant, N agents running [`crate::runtime::Agent`], and a
//! broadcast bus that loses packets (independent Bernoulli per link or per broadcast).
//! Deterministic for a given seed.

use crate::error::EventEstError;
use crate::model::{System, UniformNoise};
use crate::runtime::{Agent, InputMode, LocalUpdate, Network, NetworkData};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Estimator gains and thresholds of a design.
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// L = [L_1 … L_N] (n×p).
    pub l: DMatrix<f64>,
    /// Δ_i (p_i×p_i, symmetric positive definite) per agent.
    pub delta: Vec<DMatrix<f64>>,
}

impl Design {
    /// Scalar thresholds Δ_i (for agents with one output each).
    pub fn scalar(l: DMatrix<f64>, delta: &[f64]) -> Self {
        Self {
            l,
            delta: delta
                .iter()
                .map(|&d| DMatrix::from_element(1, 1, d))
                .collect(),
        }
    }

    /// Block-diagonal Δ^{-1} (p×p), checking every Δ_i is symmetric positive definite.
    pub fn delta_inverse(&self, sys: &System) -> Result<DMatrix<f64>, EventEstError> {
        if self.delta.len() != sys.agents() {
            return Err(EventEstError::BlockSizes {
                name: "thresholds Δ (one per agent)",
                sum: self.delta.len(),
                expected: sys.agents(),
            });
        }
        let p = sys.p();
        let off = sys.output_offsets();
        let mut inv = DMatrix::zeros(p, p);
        for (i, d) in self.delta.iter().enumerate() {
            let pi = sys.outputs[i];
            if d.nrows() != pi || d.ncols() != pi {
                return Err(EventEstError::Dimension {
                    name: "Δ_i",
                    expected_rows: pi,
                    expected_cols: pi,
                    found_rows: d.nrows(),
                    found_cols: d.ncols(),
                });
            }
            if pi == 0 {
                continue;
            }
            if d.iter().any(|v| !v.is_finite()) {
                return Err(EventEstError::NonFinite { name: "Δ_i" });
            }
            let sym = (d - d.transpose()).norm() <= 1e-12 * d.norm();
            let chol = d
                .clone()
                .cholesky()
                .filter(|_| sym)
                .ok_or(EventEstError::NotPositiveDefinite { name: "Δ_i" })?;
            inv.view_mut((off[i], off[i]), (pi, pi))
                .copy_from(&chol.inverse());
        }
        Ok(inv)
    }
}

/// Which packets the bus loses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DropMode {
    /// Each sender→receiver link independently.
    PerLink,
    /// The whole broadcast for all other receivers at once.
    PerBroadcast,
}

/// Simulation settings.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// Number of steps K.
    pub steps: usize,
    /// Packet loss probability in [0, 1).
    pub loss: f64,
    /// Loss model.
    pub drop_mode: DropMode,
    /// Own-measurement policy.
    pub local_update: LocalUpdate,
    /// Input reconstruction or communicated inputs.
    pub input_mode: InputMode,
    /// Initial plant state x(0).
    pub x0: DVector<f64>,
    /// Initial estimate of every agent (one per agent).
    pub xhat0: Vec<DVector<f64>>,
    /// Uniform noise; `None` for a noise-free run.
    pub noise: Option<UniformNoise>,
    /// First step of the window over which rates and error power are averaged.
    pub window_start: usize,
    /// Reset all estimates to their mean every this many steps (estimator resets).
    pub reset_period: Option<usize>,
    /// Bound r on a disturbance δ_i(k) added to every estimate after the update (uniform in a
    /// box of half-width r/√n per component, so |δ_i| ≤ r and |d_ji| ≤ 2r): the bounded
    /// inter-agent disturbance of the reset analysis (App. E), injected directly.
    pub estimate_disturbance: Option<f64>,
    /// RNG seed.
    pub seed: u64,
    /// Keep the full trajectory in [`SimResult::log`].
    pub record: bool,
}

impl SimConfig {
    /// Zero initial state and estimates, 10 % per-link loss, the given noise, no recording.
    pub fn new(sys: &System, steps: usize, noise: Option<UniformNoise>, seed: u64) -> Self {
        let n = sys.n();
        Self {
            steps,
            loss: 0.1,
            drop_mode: DropMode::PerLink,
            local_update: LocalUpdate::OnlyOnEvent,
            input_mode: InputMode::Reconstructed,
            x0: DVector::zeros(n),
            xhat0: vec![DVector::zeros(n); sys.agents()],
            noise,
            window_start: 0,
            reset_period: None,
            estimate_disturbance: None,
            seed,
            record: false,
        }
    }
}

/// Trajectory of a recorded run; index k = 0..=K (k = 0 holds the initial values).
#[derive(Debug, Clone, Default)]
pub struct SimLog {
    /// Plant state x(k).
    pub x: Vec<DVector<f64>>,
    /// Estimates x̂_i(k) per agent.
    pub xhat: Vec<Vec<DVector<f64>>>,
    /// Predictions x̂_i(k|k−1) per agent (zeros at k = 0).
    pub xpred: Vec<Vec<DVector<f64>>>,
    /// Plant input u(k) applied from step k to k+1 (without actuator noise).
    pub u: Vec<DVector<f64>>,
    /// Measurement y(k) (zeros at k = 0).
    pub y: Vec<DVector<f64>>,
    /// Process noise v(k−1) = B ν(k−1) that entered x(k) (zeros at k = 0).
    pub v: Vec<DVector<f64>>,
    /// Measurement noise w(k).
    pub w: Vec<DVector<f64>>,
    /// fired[k][i]: agent i transmitted at step k.
    pub fired: Vec<Vec<bool>>,
    /// lost[k][j][i]: the packet of sender j did not reach receiver i at step k.
    pub lost: Vec<Vec<Vec<bool>>>,
}

/// Metrics of a run over the averaging window.
#[derive(Debug, Clone)]
pub struct SimResult {
    /// Fraction of window steps each agent transmitted.
    pub rates: Vec<f64>,
    /// Σ_i fired_i / (N_s · K): 1.0 means every measuring agent transmits every step.
    pub total_rate: f64,
    /// sqrt(mean over window steps and agents of |x − x̂_i|²).
    pub error_power: f64,
    /// Per-agent error power.
    pub agent_error_power: Vec<f64>,
    /// Largest inter-agent error |x̂_j − x̂_i| over the whole run.
    pub max_inter_agent: f64,
    /// Largest |x| over the run (divergence check).
    pub max_state: f64,
    /// Full trajectory if requested.
    pub log: Option<SimLog>,
}

fn check_vec(name: &'static str, v: &DVector<f64>, n: usize) -> Result<(), EventEstError> {
    if v.len() != n {
        return Err(EventEstError::Dimension {
            name,
            expected_rows: n,
            expected_cols: 1,
            found_rows: v.len(),
            found_cols: 1,
        });
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(EventEstError::NonFinite { name });
    }
    Ok(())
}

/// What an observer of [`simulate_with`] sees after each step k ≥ 1.
#[derive(Debug, Clone, Copy)]
pub struct Step<'s> {
    /// Step index k (time k·Ts).
    pub k: usize,
    /// Plant state x(k).
    pub x: &'s DVector<f64>,
    /// Input u(k−1) that drove the plant into x(k) (without actuator noise).
    pub u: &'s DVector<f64>,
    /// Which agents transmitted at k.
    pub fired: &'s [bool],
    /// |x(k) − x̂_i(k)| per agent.
    pub agent_errors: &'s [f64],
}

/// Runs the networked closed loop of `sys` with `design` under `cfg`.
pub fn simulate(
    sys: &System,
    design: &Design,
    cfg: &SimConfig,
) -> Result<SimResult, EventEstError> {
    simulate_with(sys, design, cfg, |_| {})
}

/// [`simulate`], calling `observer` after every step (for streaming logs of long runs).
pub fn simulate_with<F: FnMut(&Step<'_>)>(
    sys: &System,
    design: &Design,
    cfg: &SimConfig,
    mut observer: F,
) -> Result<SimResult, EventEstError> {
    let (n, p, nu, na) = (sys.n(), sys.p(), sys.b.ncols(), sys.agents());
    if design.l.nrows() != n || design.l.ncols() != p {
        return Err(EventEstError::Dimension {
            name: "L",
            expected_rows: n,
            expected_cols: p,
            found_rows: design.l.nrows(),
            found_cols: design.l.ncols(),
        });
    }
    if !(0.0..1.0).contains(&cfg.loss) {
        return Err(EventEstError::Parameter {
            name: "loss",
            value: cfg.loss,
            reason: "packet loss probability must lie in [0, 1)",
        });
    }
    if cfg.window_start >= cfg.steps {
        return Err(EventEstError::Parameter {
            name: "window_start",
            value: cfg.window_start as f64,
            reason: "the averaging window must start before the last step",
        });
    }
    if cfg.reset_period == Some(0) {
        return Err(EventEstError::Parameter {
            name: "reset_period",
            value: 0.0,
            reason: "must be at least 1 step",
        });
    }
    if let Some(r) = cfg.estimate_disturbance {
        if !(r.is_finite() && r > 0.0) {
            return Err(EventEstError::Parameter {
                name: "estimate_disturbance",
                value: r,
                reason: "the disturbance bound must be positive and finite",
            });
        }
    }
    check_vec("x0", &cfg.x0, n)?;
    if cfg.xhat0.len() != na {
        return Err(EventEstError::BlockSizes {
            name: "xhat0 (one initial estimate per agent)",
            sum: cfg.xhat0.len(),
            expected: na,
        });
    }
    for x in &cfg.xhat0 {
        check_vec("xhat0", x, n)?;
    }
    if let Some(noise) = &cfg.noise {
        if noise.output.len() != p || noise.input.len() != nu {
            return Err(EventEstError::BlockSizes {
                name: "noise half-widths (outputs, inputs)",
                sum: noise.output.len() + noise.input.len(),
                expected: p + nu,
            });
        }
    }
    let delta_inv = design.delta_inverse(sys)?;
    let out_off = sys.output_offsets();
    let in_off = sys.input_offsets();
    let data = NetworkData {
        n,
        a: sys.a.as_slice(),
        b: sys.b.as_slice(),
        c: sys.c.as_slice(),
        f: sys.f.as_slice(),
        l: design.l.as_slice(),
        delta_inv: delta_inv.as_slice(),
        outputs: &out_off,
        inputs: &in_off,
    };
    let mut a_cl = vec![0.0; n * n];
    let net = Network::new(data, &mut a_cl)?;
    let mut workspace = vec![0.0; (0..na).map(|i| Agent::workspace_len(&net, i)).sum()];
    let mut agents = Vec::with_capacity(na);
    let mut rest: &mut [f64] = &mut workspace;
    for i in 0..na {
        let (ws, tail) = rest.split_at_mut(Agent::workspace_len(&net, i));
        rest = tail;
        let mut agent = Agent::new(&net, i, ws, cfg.input_mode, cfg.local_update)?;
        agent.reset(cfg.xhat0[i].as_slice())?;
        agents.push(agent);
    }

    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let mut x = cfg.x0.clone();
    let mut u = DVector::zeros(nu);
    let mut nu_noise = DVector::zeros(nu);
    let mut y = DVector::zeros(p);
    let mut wn = DVector::zeros(p);
    let mut fired = vec![false; na];
    let mut lost = vec![vec![false; na]; na];
    let mut fire_count = vec![0usize; na];
    let mut err2 = vec![0.0; na];
    let mut agent_err = vec![0.0; na];
    let mut max_inter: f64 = 0.0;
    let mut max_state = x.amax();
    let mut mean = DVector::zeros(n);
    let mut log = cfg.record.then(|| SimLog {
        x: vec![x.clone()],
        xhat: vec![cfg.xhat0.clone()],
        xpred: vec![vec![DVector::zeros(n); na]],
        u: Vec::new(),
        y: vec![DVector::zeros(p)],
        v: vec![DVector::zeros(n)],
        w: vec![DVector::zeros(p)],
        fired: vec![vec![false; na]],
        lost: vec![vec![vec![false; na]; na]],
    });

    for k in 1..=cfg.steps {
        // 1. u(k−1) from each agent's estimate x̂_i(k−1).
        for (i, agent) in agents.iter().enumerate() {
            agent.control(&mut u.as_mut_slice()[in_off[i]..in_off[i + 1]])?;
        }
        if let Some(l) = log.as_mut() {
            l.u.push(u.clone());
        }
        // 2. Plant and measurements.
        if let Some(noise) = &cfg.noise {
            for (j, a) in noise.input.iter().enumerate() {
                nu_noise[j] = if *a > 0.0 {
                    rng.random_range(-a..*a)
                } else {
                    0.0
                };
            }
            for (j, a) in noise.output.iter().enumerate() {
                wn[j] = if *a > 0.0 {
                    rng.random_range(-a..*a)
                } else {
                    0.0
                };
            }
        }
        let v = &sys.b * &nu_noise;
        x = &sys.a * &x + &sys.b * &u + &v;
        y.copy_from(&(&sys.c * &x + &wn));
        // 3. Predict and trigger.
        for (i, agent) in agents.iter_mut().enumerate() {
            agent.predict(Some(u.as_slice()))?;
            fired[i] = agent.trigger(&y.as_slice()[out_off[i]..out_off[i + 1]])?;
        }
        // 4. Bus.
        for j in 0..na {
            let broadcast_lost =
                cfg.drop_mode == DropMode::PerBroadcast && rng.random_bool(cfg.loss);
            for (i, lost_ji) in lost[j].iter_mut().enumerate() {
                *lost_ji = fired[j]
                    && i != j
                    && match cfg.drop_mode {
                        DropMode::PerLink => cfg.loss > 0.0 && rng.random_bool(cfg.loss),
                        DropMode::PerBroadcast => broadcast_lost,
                    };
            }
        }
        // 5. Update.
        for (i, agent) in agents.iter_mut().enumerate() {
            let ys = y.as_slice();
            let received = (0..na)
                .filter(|&j| j != i && fired[j] && !lost[j][i])
                .map(|j| (j, &ys[out_off[j]..out_off[j + 1]]));
            agent.update(&ys[out_off[i]..out_off[i + 1]], received)?;
        }
        if let Some(r) = cfg.estimate_disturbance {
            let half = r / (n as f64).sqrt();
            for agent in agents.iter_mut() {
                mean.copy_from_slice(agent.estimate());
                for m in mean.iter_mut() {
                    *m += rng.random_range(-half..half);
                }
                agent.reset(mean.as_slice())?;
            }
        }
        if let Some(period) = cfg.reset_period {
            if k % period == 0 {
                mean.fill(0.0);
                for agent in &agents {
                    mean += DVector::from_column_slice(agent.estimate());
                }
                mean /= na as f64;
                for agent in agents.iter_mut() {
                    agent.reset(mean.as_slice())?;
                }
            }
        }
        // 6. Metrics and log.
        max_state = max_state.max(x.amax());
        for i in 0..na {
            for j in (i + 1)..na {
                let d: f64 = agents[i]
                    .estimate()
                    .iter()
                    .zip(agents[j].estimate())
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum();
                max_inter = max_inter.max(d.sqrt());
            }
        }
        for (i, agent) in agents.iter().enumerate() {
            agent_err[i] = agent
                .estimate()
                .iter()
                .zip(x.iter())
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            if k > cfg.window_start {
                fire_count[i] += usize::from(fired[i]);
                err2[i] += agent_err[i] * agent_err[i];
            }
        }
        observer(&Step {
            k,
            x: &x,
            u: &u,
            fired: &fired,
            agent_errors: &agent_err,
        });
        if let Some(l) = log.as_mut() {
            l.x.push(x.clone());
            l.xhat.push(
                agents
                    .iter()
                    .map(|a| DVector::from_column_slice(a.estimate()))
                    .collect(),
            );
            l.xpred.push(
                agents
                    .iter()
                    .map(|a| DVector::from_column_slice(a.prediction()))
                    .collect(),
            );
            l.y.push(y.clone());
            l.v.push(v.clone());
            l.w.push(wn.clone());
            l.fired.push(fired.clone());
            l.lost.push(lost.clone());
        }
        if !x.iter().all(|v| v.is_finite()) {
            return Err(EventEstError::NonFinite {
                name: "plant state (the closed loop diverged)",
            });
        }
    }
    let window = (cfg.steps - cfg.window_start) as f64;
    let rates: Vec<f64> = fire_count.iter().map(|&c| c as f64 / window).collect();
    let measuring = sys.measuring_agents().max(1) as f64;
    let total_rate = fire_count.iter().sum::<usize>() as f64 / (measuring * window);
    let error_power = (err2.iter().sum::<f64>() / (na as f64 * window)).sqrt();
    Ok(SimResult {
        rates,
        total_rate,
        error_power,
        agent_error_power: err2.iter().map(|e| (e / window).sqrt()).collect(),
        max_inter_agent: max_inter,
        max_state,
        log,
    })
}
