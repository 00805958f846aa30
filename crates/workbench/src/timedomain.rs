//! Time-domain comparison: the fitted model's sampled response to the measured inputs, its
//! fit % per output for free-run simulation and for k-step-ahead prediction.
//!
//! The model is driven by the measured inputs, so on closed-loop data it is compared in the
//! loop's operating conditions without re-simulating the controller. Fit % is
//! `100 (1 - |y - ŷ| / |y - mean y|)` per output, pooled over the experiments.
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::dataset::Dataset;
use super::kalman::{Gain, Predictor};
use super::model::StateSpace;
use crate::error::{Result, SimError};

/// Default prediction horizon in samples.
pub const DEFAULT_HORIZON: usize = 10;

pub use rigid_body::lti::Discrete;

/// Default length (samples after the first) of the output window the state is fitted to.
pub const DEFAULT_WINDOW: usize = 25;

/// The sampled model with the least-squares state estimator over a window of `m + 1` outputs:
/// `x̂_s = Σ_j P_j (y_{s-m+j} - D u) + Σ_i Q_i v_{s-m+i}`, where `v_i = Γ0 u_{i-whole} +
/// Γ1 u_{i-whole-1}` is the input's effect on the state (linear in the data, so the gains are
/// computed once). Unobservable directions (the yaw of a hovering vehicle, say) are set to
/// zero by the minimum-norm solution.
///
/// Every record is processed as a whole: samples are rows, and each gain multiplies a block
/// of shifted rows in one matrix product, instead of one small product per sample.
struct Runner<'a> {
    disc: &'a Discrete,
    m: usize,
    /// `P_j^T` (outputs x states).
    p_t: Vec<DMatrix<f64>>,
    /// `Q_i^T` (states x states).
    q_t: Vec<DMatrix<f64>>,
}

/// One record run through the estimator: the input's effect on the state `v` (samples x
/// states), the feed-through `D u` (samples x outputs) and the window estimates `x̂_s`
/// (row `s - m`, for `s = m .. n`).
struct Prepared {
    v: DMatrix<f64>,
    feed: DMatrix<f64>,
    estimates: DMatrix<f64>,
}

/// `out` (samples x columns of `g_t`) `= beta out + S u g_t`, where `S u` is `u` delayed by
/// `lag` rows (zero before the record starts).
fn add_delayed(out: &mut DMatrix<f64>, u: &DMatrix<f64>, g_t: &DMatrix<f64>, lag: usize) {
    let n = u.nrows();
    if lag < n {
        out.rows_mut(lag, n - lag)
            .gemm(1.0, &u.rows(0, n - lag), g_t, 1.0);
    }
}

impl<'a> Runner<'a> {
    fn new(disc: &'a Discrete, m: usize) -> Result<Self> {
        let (nx, ny) = (disc.phi.nrows(), disc.c.nrows());
        // Observability matrix O = [C; C Φ; ...; C Φ^m].
        let mut powers = vec![DMatrix::identity(nx, nx)];
        for j in 1..=m {
            powers.push(&disc.phi * &powers[j - 1]);
        }
        let mut o = DMatrix::zeros((m + 1) * ny, nx);
        for (j, pw) in powers.iter().enumerate() {
            o.rows_mut(j * ny, ny).copy_from(&(&disc.c * pw));
        }
        if o.iter().any(|v| !v.is_finite()) {
            return Err(SimError::invalid(
                "observability matrix",
                format!("C Φ^k for k up to {m}"),
                "overflows: the model grows too fast per sample for its prediction (is the logs' time column in seconds?)",
            ));
        }
        // A short window makes O wide; nalgebra's SVD of a wide matrix can return singular
        // vectors that do not recompose it, so the tall one of O and Oᵀ is decomposed.
        let wide = o.nrows() < o.ncols();
        let svd = if wide { o.transpose() } else { o }.svd(true, true);
        let tol = 1e-9 * svd.singular_values.max();
        let o_pinv = svd
            .pseudo_inverse(tol.max(f64::MIN_POSITIVE))
            .map_err(|e| SimError::invalid("observability matrix", "pseudo-inverse", e))?;
        let o_pinv = if wide { o_pinv.transpose() } else { o_pinv };
        let pm = &powers[m] * o_pinv;
        let p: Vec<DMatrix<f64>> = (0..=m)
            .map(|j| pm.columns(j * ny, ny).into_owned())
            .collect();
        let q_t = (0..m)
            .map(|i| {
                let mut qi = powers[m - 1 - i].clone();
                for (j, pj) in p.iter().enumerate().skip(i + 1) {
                    qi -= pj * &disc.c * &powers[j - 1 - i];
                }
                qi.transpose()
            })
            .collect();
        let p_t = p.iter().map(|pj| pj.transpose()).collect();
        Ok(Self { disc, m, p_t, q_t })
    }

    /// The input's effect on the state between samples `k` and `k + 1`, row `k`.
    fn drive(&self, u: &DMatrix<f64>) -> DMatrix<f64> {
        let d = self.disc;
        let mut v = DMatrix::zeros(u.nrows(), d.phi.nrows());
        add_delayed(&mut v, u, &d.gamma0.transpose(), d.whole);
        add_delayed(&mut v, u, &d.gamma1.transpose(), d.whole + 1);
        v
    }

    /// The feed-through `D u_{k - d_shift}`, row `k`.
    fn feed(&self, u: &DMatrix<f64>) -> DMatrix<f64> {
        let mut f = DMatrix::zeros(u.nrows(), self.disc.c.nrows());
        add_delayed(&mut f, u, &self.disc.d.transpose(), self.disc.d_shift);
        f
    }

    /// The inputs' effects and the states at samples `s >= m` fitted to the outputs
    /// `y_{s-m} .. y_s` (row `s - m`; none when the record has `m` samples or fewer).
    fn prepare(&self, u: &DMatrix<f64>, y: &DMatrix<f64>) -> Prepared {
        let (v, feed) = (self.drive(u), self.feed(u));
        let n = u.nrows();
        let rows = n.saturating_sub(self.m);
        let mut estimates = DMatrix::zeros(rows, self.disc.phi.nrows());
        if rows > 0 {
            let z = y - &feed;
            for (j, pj) in self.p_t.iter().enumerate() {
                estimates.gemm(1.0, &z.rows(j, rows), pj, 1.0);
            }
            for (i, qi) in self.q_t.iter().enumerate() {
                estimates.gemm(1.0, &v.rows(i, rows), qi, 1.0);
            }
        }
        Prepared { v, feed, estimates }
    }

    /// Outputs `C x + D u` of the states `xs` (rows `from ..`) written into `yhat`.
    fn outputs(&self, pre: &Prepared, xs: &DMatrix<f64>, yhat: &mut DMatrix<f64>, from: usize) {
        let rows = xs.nrows() - from;
        let mut out = yhat.rows_mut(from, rows);
        out.copy_from(&pre.feed.rows(from, rows));
        out.gemm(1.0, &xs.rows(from, rows), &self.disc.c.transpose(), 1.0);
    }

    /// Free run from the first window estimate (see [`Discrete::simulate`]).
    fn simulate(&self, pre: &Prepared, y: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
        let (n, nx, m) = (y.nrows(), self.disc.phi.nrows(), self.m);
        let mut yhat = y.clone();
        let mut xs = DMatrix::zeros(n, nx);
        if n <= m {
            return (yhat, xs);
        }
        let mut x = pre.estimates.row(0).transpose();
        let mut next = DVector::zeros(nx);
        for k in m..n {
            xs.row_mut(k).tr_copy_from(&x);
            next.tr_copy_from(&pre.v.row(k));
            next.gemv(1.0, &self.disc.phi, &x, 1.0);
            std::mem::swap(&mut x, &mut next);
        }
        self.outputs(pre, &xs, &mut yhat, m);
        (yhat, xs)
    }

    /// `k`-step-ahead predictions (see [`Discrete::predict`]): all window estimates are run
    /// forward together, one step at a time.
    fn predict(&self, pre: &Prepared, y: &DMatrix<f64>, k: usize) -> (DMatrix<f64>, DMatrix<f64>) {
        let (n, nx, m) = (y.nrows(), self.disc.phi.nrows(), self.m);
        let mut yhat = y.clone();
        let mut xs = DMatrix::zeros(n, nx);
        let rows = n.saturating_sub(m + k);
        if rows == 0 {
            return (yhat, xs);
        }
        let phi_t = self.disc.phi.transpose();
        // Row r holds the prediction of sample t = m + k + r from the estimate at t - k.
        let mut x = pre.estimates.rows(0, rows).into_owned();
        let mut next = DMatrix::zeros(rows, nx);
        for i in 0..k {
            next.copy_from(&pre.v.rows(m + i, rows));
            next.gemm(1.0, &x, &phi_t, 1.0);
            std::mem::swap(&mut x, &mut next);
        }
        xs.rows_mut(m + k, rows).copy_from(&x);
        self.outputs(pre, &xs, &mut yhat, m + k);
        (yhat, xs)
    }
}

/// Free-run simulation of `disc` from the state fitted to the first `m + 1` output samples:
/// outputs (samples x outputs) and states (samples x states); scored from sample `m`.
pub fn simulate(
    disc: &Discrete,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
    m: usize,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let r = Runner::new(disc, m)?;
    Ok(r.simulate(&r.prepare(u, y), y))
}

/// k-step-ahead predictions of `disc` for each horizon in `ks`: for every sample `t >= m + k`
/// the state at `t - k` is fitted to the outputs `y_{t-k-m} .. y_{t-k}` and run `k` steps on
/// the measured inputs. Rows before `m + k` are copied from the measurement (not scored).
/// Also returns, per horizon, the predicted states.
pub fn predict(
    disc: &Discrete,
    u: &DMatrix<f64>,
    y: &DMatrix<f64>,
    ks: &[usize],
    m: usize,
) -> Result<Vec<(DMatrix<f64>, DMatrix<f64>)>> {
    let r = Runner::new(disc, m)?;
    let pre = r.prepare(u, y);
    Ok(ks.iter().map(|&k| r.predict(&pre, y, k)).collect())
}

/// Accumulates `|y - ŷ|²` and `|y - mean y|²` per output over several records.
#[derive(Debug, Clone)]
struct FitAccumulator {
    err: Vec<f64>,
    sum: Vec<f64>,
    sum_sq: Vec<f64>,
    count: usize,
}

impl FitAccumulator {
    fn new(ny: usize) -> Self {
        Self {
            err: vec![0.0; ny],
            sum: vec![0.0; ny],
            sum_sq: vec![0.0; ny],
            count: 0,
        }
    }

    fn add(&mut self, y: &DMatrix<f64>, yhat: &DMatrix<f64>, from: usize) {
        for t in from..y.nrows() {
            for i in 0..y.ncols() {
                self.err[i] += (y[(t, i)] - yhat[(t, i)]).powi(2);
                self.sum[i] += y[(t, i)];
                self.sum_sq[i] += y[(t, i)].powi(2);
            }
            self.count += 1;
        }
    }

    fn fit(&self) -> Vec<f64> {
        let n = self.count.max(1) as f64;
        self.err
            .iter()
            .zip(&self.sum)
            .zip(&self.sum_sq)
            .map(|((e, s), q)| {
                let var = q - s * s / n;
                if var > 0.0 {
                    100.0 * (1.0 - (e / var).sqrt())
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// Fit % per output pooled over records `(y, first scored sample)` and their predictions.
pub fn fit_percent_from(records: &[(DMatrix<f64>, usize)], yhat: &[DMatrix<f64>]) -> Vec<f64> {
    let mut acc = FitAccumulator::new(records.first().map_or(0, |(y, _)| y.ncols()));
    for ((y, from), yh) in records.iter().zip(yhat) {
        acc.add(y, yh, *from);
    }
    acc.fit()
}

/// Fit % per output, `100 (1 - |y - ŷ| / |y - mean y|)`.
pub fn fit_percent(y: &DMatrix<f64>, yhat: &DMatrix<f64>) -> Vec<f64> {
    let mut acc = FitAccumulator::new(y.ncols());
    acc.add(y, yhat, 0);
    acc.fit()
}

/// Time-domain fit of a model on all experiments.
#[derive(Debug, Clone, Serialize)]
pub struct TimeFit {
    /// How the comparison was made (horizon, initial condition, closed-loop note).
    pub policy: String,
    /// Prediction horizon in samples.
    pub horizon_samples: usize,
    /// Prediction horizon in seconds.
    pub horizon_s: f64,
    /// Samples after the first of the output window each state is fitted to.
    pub window_samples: usize,
    /// Spectral radius of the sampled model (above one it is unstable).
    pub spectral_radius: f64,
    /// Free-run simulation fit % per output; `None` unless the model is asymptotically
    /// stable (with integrators or unstable poles the free run drifts or diverges, so only
    /// predictions compare it with closed-loop data).
    pub simulation: Option<Vec<(String, f64)>>,
    /// k-step-ahead prediction fit % per output.
    pub prediction: Vec<(String, f64)>,
    /// One-step-ahead prediction fit % per output.
    pub one_step: Vec<(String, f64)>,
    /// The stationary Kalman predictor's fits (its innovations are what the residual tests
    /// examine); `None` with the reason in `kalman_error` when the model is not detectable.
    pub kalman: Option<KalmanFit>,
    /// Why there is no Kalman predictor.
    pub kalman_error: Option<String>,
    /// Closed-loop re-simulation with the experimenter's controller, when the model gives one.
    pub closed_loop: Option<super::closed_loop::ClosedLoopFit>,
    /// Why the loop was not re-simulated although a controller is given.
    pub closed_loop_error: Option<String>,
    /// The nonlinear model's extended Kalman predictor, under the time-domain criterion.
    pub prediction_error: Option<super::prediction::PredictionFit>,
}

/// Fits of the stationary Kalman predictor ([`super::kalman`]).
#[derive(Debug, Clone, Serialize)]
pub struct KalmanFit {
    /// How it was made.
    pub policy: String,
    /// One-step-ahead prediction fit % per output.
    pub one_step: Vec<(String, f64)>,
    /// k-step-ahead prediction fit % per output (the horizon of [`TimeFit`]).
    pub prediction: Vec<(String, f64)>,
    /// The estimated noise covariances.
    pub noise: super::kalman::NoiseEstimate,
}

/// The policy sentence of [`time_fit`].
pub fn policy(k: usize, m: usize, t: f64) -> String {
    format!(
        "model sampled with a zero-order hold at {t:.4} s and driven by the measured inputs \
         (on closed-loop data the loop is not re-simulated); inputs and outputs taken as \
         deviations from their record means (the operating point); initial condition: the \
         state is fitted by least squares to the {} preceding output samples (minimum norm \
         on unobservable directions); simulation: one fit at the record start, then free run, \
         scored from sample {m}; {k}-step prediction ({:.3} s): at each sample t the state at \
         t - {k} is fitted to the outputs up to t - {k} and run {k} steps, scored from sample \
         {}; fit % pooled over the experiments",
        m + 1,
        k as f64 * t,
        m + k
    )
}

/// `x` with each column's mean removed.
pub(crate) fn demeaned(x: &DMatrix<f64>) -> DMatrix<f64> {
    let mut d = x.clone();
    for mut c in d.column_iter_mut() {
        let mean = c.mean();
        c.add_scalar_mut(-mean);
    }
    d
}

/// Time-domain residuals of one experiment for the residual tests: the one-step prediction
/// residual, the predicted states and the (demeaned) inputs, from the first scored sample.
pub type ResidualRecord = (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>);

/// Simulation and `k`-step prediction fit % of `ss` on `data`, with state windows of
/// `m + 1` samples; also returns per experiment the one-step residual record.
pub fn time_fit(
    data: &Dataset,
    ss: &StateSpace,
    k: usize,
    m: usize,
) -> Result<(TimeFit, Vec<ResidualRecord>)> {
    if k == 0 {
        return Err(SimError::invalid(
            "prediction horizon",
            k,
            "must be at least one sample",
        ));
    }
    let t = 1.0 / data.sample_rate_hz;
    let disc = ss.discretize(t)?;
    if disc.c.nrows() != data.outputs.len() || disc.gamma0.ncols() != data.inputs.len() {
        return Err(SimError::LengthMismatch {
            what: "model outputs x inputs against the data channels".into(),
            expected: data.outputs.len() * data.inputs.len(),
            found: disc.c.nrows() * disc.gamma0.ncols(),
        });
    }
    if let Some(e) = data.experiments.iter().find(|e| e.u.nrows() <= m + k) {
        return Err(SimError::LengthMismatch {
            what: format!(
                "samples of {} (the time-domain comparison needs more than window {} + horizon {k})",
                e.name,
                m + 1
            ),
            expected: m + k + 1,
            found: e.u.nrows(),
        });
    }
    let rho = disc.spectral_radius()?;
    // Integrators (spectral radius 1) drift as fast as unstable poles diverge on closed-loop
    // data driven by noise: only an asymptotically stable model's free run is scored.
    let stable = rho < 1.0 - 1e-9;
    let ny = data.outputs.len();
    let (mut sim, mut pred, mut one) = (
        FitAccumulator::new(ny),
        FitAccumulator::new(ny),
        FitAccumulator::new(ny),
    );
    let runner = Runner::new(&disc, m)?;
    let centred: Vec<(DMatrix<f64>, DMatrix<f64>)> = data
        .experiments
        .iter()
        .map(|e| (demeaned(&e.u), demeaned(&e.y)))
        .collect();
    let mut records = Vec::with_capacity(data.experiments.len());
    for (u, y) in &centred {
        let pre = runner.prepare(u, y);
        if stable {
            let (ys, _) = runner.simulate(&pre, y);
            sim.add(y, &ys, m);
        }
        let (yk, _) = runner.predict(&pre, y, k);
        pred.add(y, &yk, m + k);
        let (y1, x1) = runner.predict(&pre, y, 1);
        one.add(y, &y1, m + 1);
        let from = m + 1;
        let rows = y.nrows() - from;
        records.push((
            (y - &y1).rows(from, rows).into_owned(),
            x1.rows(from, rows).into_owned(),
            u.rows(from, rows).into_owned(),
        ));
    }
    let named =
        |v: Vec<f64>| -> Vec<(String, f64)> { data.outputs.iter().cloned().zip(v).collect() };
    let pairs: Vec<(&DMatrix<f64>, &DMatrix<f64>)> = centred.iter().map(|(u, y)| (u, y)).collect();
    let (kalman, kalman_error) = match Predictor::design(&disc, &pairs, Gain::Refined) {
        Err(e) => (None, Some(e.to_string())),
        Ok(kp) => {
            let (mut one_k, mut pred_k) = (FitAccumulator::new(ny), FitAccumulator::new(ny));
            // The innovations replace the window residuals in the residual tests: for the true
            // model on data with white noise they are white.
            records.clear();
            for (u, y) in &centred {
                let (e, xs) = kp.run(u, y);
                one_k.add(y, &(y - &e), m + 1);
                pred_k.add(y, &kp.predict(u, &xs, k), m + k);
                let from = m + 1;
                let rows = y.nrows() - from;
                records.push((
                    e.rows(from, rows).into_owned(),
                    xs.rows(from, rows).into_owned(),
                    u.rows(from, rows).into_owned(),
                ));
            }
            let fit = KalmanFit {
                policy: format!(
                    "stationary Kalman predictor of the sampled model, started at the state fitted \
                     by least squares to the first {} outputs, \
                     noise covariances estimated from the data (sensor noise from first \
                     differences, input-referred process noise with a share per direction the \
                     inputs reach, state process noise and per-output sensor \
                     factors chosen to minimise the innovation log-determinant, then every \
                     entry of the gain refined on the same criterion); one-step and \
                     {k}-step predictions ({:.3} s) from the filtered state, scored from samples \
                     {} and {}",
                    super::kalman::START_WINDOW + 1,
                    k as f64 * t,
                    m + 1,
                    m + k
                ),
                one_step: named(one_k.fit()),
                prediction: named(pred_k.fit()),
                noise: kp.noise.clone(),
            };
            (Some(fit), None)
        }
    };
    Ok((
        TimeFit {
            policy: policy(k, m, t),
            horizon_samples: k,
            horizon_s: k as f64 * t,
            window_samples: m,
            spectral_radius: rho,
            simulation: stable.then(|| named(sim.fit())),
            prediction: named(pred.fit()),
            one_step: named(one.fit()),
            kalman,
            kalman_error,
            closed_loop: None,
            closed_loop_error: None,
            prediction_error: None,
        },
        records,
    ))
}

/// Measured outputs and the Kalman predictor's `k`-step predictions of `ss` on the first
/// `samples` samples of experiment `index` (deviations from the record means), for plots.
pub fn kalman_series(
    data: &Dataset,
    ss: &StateSpace,
    k: usize,
    index: usize,
    samples: usize,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let disc = ss.discretize(1.0 / data.sample_rate_hz)?;
    let centred: Vec<(DMatrix<f64>, DMatrix<f64>)> = data
        .experiments
        .iter()
        .map(|e| (demeaned(&e.u), demeaned(&e.y)))
        .collect();
    let pairs: Vec<(&DMatrix<f64>, &DMatrix<f64>)> = centred.iter().map(|(u, y)| (u, y)).collect();
    let kp = Predictor::design(&disc, &pairs, Gain::Refined)?;
    let (u, y) = centred
        .get(index)
        .ok_or_else(|| SimError::invalid("experiment", index, "no such experiment"))?;
    let (_, xs) = kp.run(u, y);
    let yk = kp.predict(u, &xs, k.max(1));
    let n = samples.min(y.nrows());
    Ok((y.rows(0, n).into_owned(), yk.rows(0, n).into_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{rngs::StdRng, Rng, SeedableRng};

    /// First-order lag `x' = -a x + b u`, `y = x`, with optional delay.
    fn lag(a: f64, b: f64, delay: f64) -> StateSpace {
        StateSpace {
            a: DMatrix::from_element(1, 1, -a),
            b: DMatrix::from_element(1, 1, b),
            c: DMatrix::from_element(1, 1, 1.0),
            d: DMatrix::zeros(1, 1),
            delay,
        }
    }

    fn random_input(n: usize, seed: u64) -> DMatrix<f64> {
        let mut rng = StdRng::seed_from_u64(seed);
        DMatrix::from_fn(n, 1, |_, _| rng.random_range(-1.0..1.0))
    }

    #[test]
    fn simulation_matches_the_closed_form_recursion() {
        // Zero-order hold of x' = -a x + b u: x+ = e^{-aT} x + b (1 - e^{-aT}) / a u.
        let (a, b, t) = (2.0, 3.0, 0.05);
        let disc = lag(a, b, 0.0).discretize(t).unwrap();
        let u = random_input(200, 1);
        let (p, g) = ((-a * t).exp(), b * (1.0 - (-a * t).exp()) / a);
        let mut y = DMatrix::zeros(200, 1);
        let mut x = 0.7;
        for k in 0..200 {
            y[(k, 0)] = x;
            x = p * x + g * u[(k, 0)];
        }
        // The window fit recovers the state exactly from noise-free outputs.
        let (ys, _) = simulate(&disc, &u, &y, 5).unwrap();
        for k in 5..200 {
            assert!((ys[(k, 0)] - y[(k, 0)]).abs() < 1e-10, "sample {k}");
        }
        assert!((disc.spectral_radius().unwrap() - p).abs() < 1e-12);
    }

    #[test]
    fn whole_sample_delay_shifts_the_response() {
        let t = 0.02;
        let u = random_input(100, 2);
        let y = DMatrix::zeros(100, 1);
        let plain = lag(1.0, 1.0, 0.0).discretize(t).unwrap();
        let late = lag(1.0, 1.0, 3.0 * t).discretize(t).unwrap();
        assert_eq!(late.whole, 3);
        // Zero outputs over the window: the fitted initial state is zero in both runs.
        let (a, _) = simulate(&plain, &u, &y, 0).unwrap();
        let (b, _) = simulate(&late, &u, &y, 0).unwrap();
        for k in 3..100 {
            assert!((b[(k, 0)] - a[(k - 3, 0)]).abs() < 1e-12);
        }
    }

    /// Two states, only the first measured: x1' = x2, x2' = -4 x1 - 0.4 x2 + u.
    fn oscillator() -> StateSpace {
        StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -4.0, -0.4]),
            b: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
            c: DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            d: DMatrix::zeros(1, 1),
            delay: 0.0,
        }
    }

    #[test]
    fn true_model_fits_noise_free_data_perfectly_and_a_wrong_one_does_not() {
        // The unmeasured velocity is recovered by the window fit.
        let disc = oscillator().discretize(0.05).unwrap();
        let u = random_input(600, 3);
        let n = 600;
        let mut y = DMatrix::zeros(n, 1);
        let mut x = DVector::from_row_slice(&[0.3, -0.5]);
        for k in 0..n {
            y[(k, 0)] = x[0];
            x = &disc.phi * x + &disc.gamma0 * u[(k, 0)];
        }
        let (ys, _) = simulate(&disc, &u, &y, 10).unwrap();
        let p = predict(&disc, &u, &y, &[5, 1], 10).unwrap();
        let score = |yhat: &DMatrix<f64>, from: usize| {
            let mut acc = FitAccumulator::new(1);
            acc.add(&y, yhat, from);
            acc.fit()[0]
        };
        assert!(score(&ys, 10) > 100.0 - 1e-6);
        assert!(score(&p[0].0, 15) > 100.0 - 1e-6);
        assert!(score(&p[1].0, 11) > 100.0 - 1e-6);
        let mut wrong = oscillator();
        wrong.a[(1, 0)] = -6.0;
        let wd = wrong.discretize(0.05).unwrap();
        let (yw, _) = simulate(&wd, &u, &y, 10).unwrap();
        let pw = predict(&wd, &u, &y, &[5, 1], 10).unwrap();
        let (fs, f5, f1) = (score(&yw, 10), score(&pw[0].0, 15), score(&pw[1].0, 11));
        // A wrong stiffness hurts the free run most and the one-step prediction least.
        assert!(fs < 90.0 && f1 > f5 && f5 > fs, "{fs} {f5} {f1}");
    }

    #[test]
    fn fit_percent_of_the_mean_is_zero() {
        let y = random_input(50, 4);
        let m = y.mean();
        let yhat = DMatrix::from_element(50, 1, m);
        assert!(fit_percent(&y, &yhat)[0].abs() < 1e-12);
    }

    #[test]
    fn zero_horizon_is_refused() {
        let data = Dataset {
            sample_rate_hz: 10.0,
            inputs: vec!["u".into()],
            outputs: vec!["y".into()],
            experiments: vec![],
        };
        let msg = time_fit(&data, &lag(1.0, 1.0, 0.0), 0, 5)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("prediction horizon"), "{msg}");
    }

    proptest! {
        /// On noise-free data of the model itself, with a fractional input delay and a
        /// feed-through, every prediction horizon and the free run reproduce the outputs.
        /// The data come from a per-sample recursion written out here, independent of the
        /// whole-record matrix products.
        #[test]
        fn predictions_reproduce_the_models_own_data(
            a in 0.5f64..3.0, w in 0.0f64..4.0, c in 0.5f64..3.0,
            cm in proptest::collection::vec(-1.0f64..1.0, 4),
            dm in proptest::collection::vec(-1.0f64..1.0, 2),
            delay_samples in 0.0f64..3.5, k in 1usize..6, seed in 0u64..1000,
        ) {
            let t = 0.05;
            let mut cmat = DMatrix::from_row_slice(2, 2, &cm);
            cmat[(0, 0)] += 2.5;
            cmat[(1, 1)] += 2.5;
            let ss = StateSpace {
                a: DMatrix::from_row_slice(2, 2, &[-a, w, -w, -c]),
                b: DMatrix::from_row_slice(2, 1, &[1.0, 0.5]),
                c: cmat,
                d: DMatrix::from_column_slice(2, 1, &dm),
                delay: delay_samples * t,
            };
            let disc = ss.discretize(t).unwrap();
            let n = 80;
            let u = random_input(n, seed);
            let at = |k: usize, lag: usize| if k >= lag { u[(k - lag, 0)] } else { 0.0 };
            let mut y = DMatrix::zeros(n, 2);
            let mut x = DVector::from_row_slice(&[0.4, -0.3]);
            for s in 0..n {
                let yk = &disc.c * &x + &disc.d * at(s, disc.d_shift);
                y.row_mut(s).copy_from(&yk.transpose());
                x = &disc.phi * x
                    + &disc.gamma0 * at(s, disc.whole)
                    + &disc.gamma1 * at(s, disc.whole + 1);
            }
            let m = 4;
            let (ys, _) = simulate(&disc, &u, &y, m).unwrap();
            let p = predict(&disc, &u, &y, &[k, 1], m).unwrap();
            let scale = y.amax().max(1e-3);
            for s in m..n {
                for i in 0..2 {
                    prop_assert!((ys[(s, i)] - y[(s, i)]).abs() < 1e-8 * scale);
                    if s >= m + k {
                        prop_assert!((p[0].0[(s, i)] - y[(s, i)]).abs() < 1e-8 * scale);
                    }
                    if s > m {
                        prop_assert!((p[1].0[(s, i)] - y[(s, i)]).abs() < 1e-8 * scale);
                    }
                }
            }
        }
    }
}
