//! Cubli model discovery by time-domain prediction error.
//!
//! The Cubli logs the full state (housing rates, wheel speeds, gravity direction), so the
//! nominal model (documented parameters of [`cubli::Params::reference`]) predicts, over a short
//! window of `window` samples, the change of the wheel momenta p_w = Θw (ω_h + ω_w), of the
//! housing momentum p_h = Θ0 ω_h + p_w and of the gravity direction ĝ:
//!
//! * Δp_w = ∫ k T − c_v ω_w − c_c tanh(ω_w / ε) dt (the commanded torque is held over a sample,
//!   so ∫T dt is exact, and the wheel speed moves linearly between samples, so the tanh is
//!   integrated exactly along that ramp);
//! * Δp_h = ∫ −ω_h × p_h + m × g dt (wheel torques are internal and do not appear);
//! * Δĝ = −∫ ω_h × ĝ dt, with ω_h the measured rate minus the gyro bias.
//!
//! The residual of the nominal prediction is linear in every candidate parameter (to first
//! order in the bias) but the smoothing speed ε, so each candidate is a set of regressor
//! columns and each fit is a weighted linear least-squares problem, with ε profiled when
//! Coulomb friction is in the model (a real friction's width is not the nominal one). Integrating over a window instead of differentiating
//! one sample keeps the endpoint noise fixed while the effects accumulate; disjoint windows
//! keep the residuals of different windows independent. Sensor noise enters the regressors
//! only through window integrals of many samples, which averages it out; the residual variance
//! of each channel is estimated from the data (the fit with every candidate), not assumed.
//!
//! Significance follows the flying-platform loop ([`workbench::discover`]): F test of the nested
//! models at the Bonferroni-corrected level, a lower BIC and a cost reduction beyond what
//! noise alone varies it, friction coefficients non-negative, best candidate first, repeat;
//! a candidate is added only if it then leaves no structured misfit, or stays significant
//! with the generic probes below as nuisance columns (see [`CubliBench::discover`]).
//! The verdict tests each channel's final residual against generic probe regressors (a
//! constant and every measured signal and input at the sample before the window, which in
//! closed loop is the latest one independent of the window's noise); a channel whose residual
//! they explain significantly carries a structured misfit.
//!
//! Held parameters: the inertias Θ0, Θw and m are held at their documented values (a torque
//! constant and an inertia scale enter only as their ratio); the gyro-bias component along the
//! mean gravity direction is held at zero (near upright it is indistinguishable from a slow
//! yaw rate of the housing).
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::Serialize;
use serde_json::{json, Value};

use workbench::dataset::Dataset;
use workbench::diagnose::LEVEL;
use workbench::discover::{
    rivals, CandidateScore, Conclusion, NestedCosts, Robustness, Verdict, MISFIT_CAVEAT,
};
use workbench::fit::ParamEstimate;
use workbench::load;
use workbench::model::Parameter;
use workbench::report::{
    chart, conclusion_fields, cost_bars, count, escape, page, parameters_html, per_step, publish,
    step_fields, XAxis,
};
use workbench::search::{forward_selection, Search};
use workbench::stats::f_sf;
use workbench::{Result, SimError};

/// Candidate effects, in the order tried.
pub const CANDIDATES: [&str; 4] = [
    "wheel_viscous_friction",
    "wheel_coulomb_friction",
    "gyro_bias",
    "torque_constant",
];
/// Input channels of the Cubli logs.
pub const INPUTS: [&str; 3] = ["T1", "T2", "T3"];
/// Output channels of the Cubli logs.
pub const OUTPUTS: [&str; 9] = ["wx", "wy", "wz", "w1", "w2", "w3", "gx", "gy", "gz"];
/// Residual channels: wheel momenta, housing momentum, gravity direction.
pub const CHANNELS: [&str; 9] = [
    "p_w1", "p_w2", "p_w3", "p_hx", "p_hy", "p_hz", "g_x", "g_y", "g_z",
];
/// Range (rad/s) searched for the speed ε of the Coulomb smoothing tanh(ω/ε): the width is
/// fitted with the level (a sign smoothed over another width than the plant's would leave a
/// misfit that viscous friction and the torque constant partly absorb), from a near-sign at
/// the wheel-speed noise to a width past which tanh is a viscous slope.
pub const COULOMB_SMOOTHING_RANGE: (f64, f64) = (0.01, 2.0);
/// Name of the fitted smoothing speed among the parameters.
pub const COULOMB_SMOOTHING: &str = "wheel_coulomb_smoothing";
/// Parameters that cannot be negative (friction coefficients).
const NON_NEGATIVE: [&str; 2] = ["wheel_viscous_friction", "wheel_coulomb_friction"];
/// Parameters held at documented values, with the reason.
pub const HELD: [(&str, &str); 3] = [
    (
        "theta0, theta_w",
        "inertias of cubli::Params::reference; an inertia scale and a torque constant enter only as their ratio",
    ),
    ("m", "mass times centre-of-mass vector of cubli::Params::reference"),
    (
        "gyro_bias along the mean gravity direction",
        "held at 0: near upright a yaw-rate offset cannot be told from a slow yaw rotation",
    ),
];

/// Options of the Cubli discovery.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubliOptions {
    /// Integration window in samples.
    pub window: usize,
    /// Samples dropped at the start of an experiment without a periodic layout (with one, its
    /// transient is dropped): the recovery from the initial tilt may saturate the motors.
    pub skip: usize,
}

impl Default for CubliOptions {
    fn default() -> Self {
        Self {
            window: 25,
            skip: 200,
        }
    }
}

/// Regressor columns: viscous c, Coulomb c, two bias components, torque constant − 1, and
/// the derivative of the Coulomb column by the smoothing speed ε (for the covariance of ε;
/// no candidate names it).
const NCOL: usize = 6;
/// The Coulomb column and its derivative by ε.
const COULOMB: usize = 1;
const D_SMOOTHING: usize = 5;

fn columns_of(effect: &str) -> &'static [usize] {
    match effect {
        "wheel_viscous_friction" => &[0],
        "wheel_coulomb_friction" => &[1],
        "gyro_bias" => &[2, 3],
        _ => &[4],
    }
}

/// Window residuals of the nominal model and their regressors.
#[derive(Debug, Clone)]
struct Rows {
    /// Residual of the nominal prediction.
    r: Vec<f64>,
    /// Candidate regressors (residual = X θ + noise).
    x: Vec<[f64; NCOL]>,
    /// Generic probes for the misfit test.
    probes: Vec<Vec<f64>>,
    /// Residual channel of each row.
    channel: Vec<usize>,
    /// Wheel speed at every sample of a wheel row's window (empty for the other rows): the
    /// Coulomb column at any smoothing speed.
    speeds: Vec<Vec<f64>>,
    /// Sample period, s.
    h: f64,
    /// Experiment index and start time (s) of each row's window.
    window: Vec<(usize, f64)>,
    /// Orthonormal basis of the identifiable bias plane (body axes).
    bias_basis: [Vector3<f64>; 2],
}

impl Rows {
    fn empty(bias_basis: [Vector3<f64>; 2]) -> Self {
        Self {
            r: Vec::new(),
            x: Vec::new(),
            probes: Vec::new(),
            channel: Vec::new(),
            speeds: Vec::new(),
            h: 1.0,
            window: Vec::new(),
            bias_basis,
        }
    }

    /// The regressors with the Coulomb column (and its derivative) at smoothing speed `eps`.
    fn smoothed_x(&self, eps: f64) -> Vec<[f64; NCOL]> {
        let mut out = self.x.clone();
        // Residual = −c_c ∫ tanh(ω/ε) dt; its derivative by ε by central differences.
        let step = 1e-5 * eps;
        for (x, speeds) in out.iter_mut().zip(&self.speeds) {
            if speeds.is_empty() {
                continue;
            }
            let column = |e: f64| {
                -self.h
                    * speeds
                        .windows(2)
                        .map(|w| mean_tanh(w[0], w[1], e))
                        .sum::<f64>()
            };
            x[COULOMB] = column(eps);
            x[D_SMOOTHING] = (column(eps + step) - column(eps - step)) / (2.0 * step);
        }
        out
    }
}

/// Mean of tanh(ω/ε) over a sample interval along which ω goes linearly from `a` to `b` (the
/// torque is held over a sample): exactly ε (ln cosh(b/ε) − ln cosh(a/ε)) / (b − a). A
/// trapezoid on the samples would miss the sign's step between them when ε is below the
/// speed change of one sample.
fn mean_tanh(a: f64, b: f64, eps: f64) -> f64 {
    let (x, y) = (a / eps, b / eps);
    if (y - x).abs() < 1e-4 {
        // Second-order accurate and free of the cancellation below.
        return (0.5 * (x + y)).tanh();
    }
    let ln_cosh = |v: f64| v.abs() + (-2.0 * v.abs()).exp().ln_1p();
    (ln_cosh(y) - ln_cosh(x)) / (y - x)
}

fn build_rows(data: &Dataset, opts: &CubliOptions) -> Result<Rows> {
    let p = cubli::Params::reference();
    let (theta0, theta_w) = (*p.theta0(), *p.theta_w());
    let m = *p.m();
    let gravity = p.gravity();
    let h = 1.0 / data.sample_rate_hz;
    let nw = opts.window;
    if nw < 2 {
        return Err(SimError::invalid(
            "window",
            nw,
            "must be at least 2 samples",
        ));
    }
    // Mean gravity direction, for the identifiable bias plane.
    let mut gmean = Vector3::zeros();
    for e in &data.experiments {
        for k in 0..e.y.nrows() {
            gmean += Vector3::new(e.y[(k, 6)], e.y[(k, 7)], e.y[(k, 8)]);
        }
    }
    let gm = gmean.try_normalize(1e-12).ok_or_else(|| {
        SimError::invalid(
            "gx, gy, gz",
            "mean 0",
            "the gravity direction must be a unit vector",
        )
    })?;
    let a = if gm.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = (a - gm * gm.dot(&a)).normalize();
    let e2 = gm.cross(&e1);
    let basis = [e1, e2];
    let mut rows = Rows::empty(basis);
    rows.h = h;
    for (ei, e) in data.experiments.iter().enumerate() {
        let n = e.y.nrows();
        let start = e
            .periodic
            .map_or(opts.skip, |pl| pl.transient)
            .max(1)
            .min(n);
        let wh = |k: usize| Vector3::new(e.y[(k, 0)], e.y[(k, 1)], e.y[(k, 2)]);
        let ww = |k: usize| Vector3::new(e.y[(k, 3)], e.y[(k, 4)], e.y[(k, 5)]);
        let gh = |k: usize| Vector3::new(e.y[(k, 6)], e.y[(k, 7)], e.y[(k, 8)]);
        let tq = |k: usize| Vector3::new(e.u[(k, 0)], e.u[(k, 1)], e.u[(k, 2)]);
        let pw = |k: usize| theta_w.component_mul(&(wh(k) + ww(k)));
        let ph = |k: usize| theta0 * wh(k) + pw(k);
        let mut k0 = start;
        while k0 + nw < n {
            let k1 = k0 + nw;
            // Trapezoid weights over samples k0..=k1.
            let wt = |k: usize| if k == k0 || k == k1 { 0.5 * h } else { h };
            let mut int_t = Vector3::zeros();
            let mut int_ww = Vector3::zeros();
            let mut speeds: [Vec<f64>; 3] = Default::default();
            let mut int_ph = Vector3::zeros();
            let mut int_g = Vector3::zeros();
            let mut int_bias_h = [Vector3::zeros(); 2];
            let mut int_bias_g = [Vector3::zeros(); 2];
            for k in k0..k1 {
                int_t += tq(k) * h;
            }
            for k in k0..=k1 {
                let c = wt(k);
                let (w, wwk, g, p_h) = (wh(k), ww(k), gh(k), ph(k));
                int_ww += wwk * c;
                for (i, s) in speeds.iter_mut().enumerate() {
                    s.push(wwk[i]);
                }
                int_ph += (-w.cross(&p_h) + m.cross(&(g * gravity))) * c;
                int_g += (-w.cross(&g)) * c;
                let mh = theta0 + Matrix3::from_diagonal(&theta_w);
                for (j, b) in basis.iter().enumerate() {
                    // Measured rate = true + b: first-order change of the measured-data
                    // prediction, so residual = (these) · bias.
                    int_bias_h[j] += (b.cross(&p_h) + w.cross(&(mh * b))) * c;
                    int_bias_g[j] += b.cross(&g) * c;
                }
            }
            let dpw = pw(k1) - pw(k0);
            let dph = ph(k1) - ph(k0);
            let dg = gh(k1) - gh(k0);
            // Generic probes: a constant and every signal at the sample before the window,
            // times its length. The residual carries the noise of the window's samples, and in
            // closed loop everything measured inside the window reacts to it through the
            // controller; the sample before belongs to the previous window, so the probes stay
            // independent of this residual under the null and the F test stays calibrated.
            let tw = h * nw as f64;
            let before = k0 - 1;
            let mut probe = vec![tw];
            for v in [wh(before), ww(before), gh(before), tq(before)] {
                probe.extend(v.iter().map(|x| x * tw));
            }
            let mut push = |r: f64, x: [f64; NCOL], channel: usize, s: Vec<f64>| {
                rows.r.push(r);
                rows.x.push(x);
                rows.channel.push(channel);
                rows.speeds.push(s);
                rows.window.push((ei, k0 as f64 * h));
                rows.probes.push(probe.clone());
            };
            for (i, s) in speeds.into_iter().enumerate() {
                // Wheel i: residual = (k − 1) ∫T − c_v ∫ω_w − c_c ∫tanh (the Coulomb column
                // is set at each smoothing speed tried, `Rows::with_smoothing`).
                let x = [-int_ww[i], 0.0, 0.0, 0.0, int_t[i], 0.0];
                push(dpw[i] - int_t[i], x, i, s);
            }
            for i in 0..3 {
                let x = [0.0, 0.0, int_bias_h[0][i], int_bias_h[1][i], 0.0, 0.0];
                push(dph[i] - int_ph[i], x, 3 + i, Vec::new());
            }
            for i in 0..3 {
                let x = [0.0, 0.0, int_bias_g[0][i], int_bias_g[1][i], 0.0, 0.0];
                push(dg[i] - int_g[i], x, 6 + i, Vec::new());
            }
            k0 = k1 + 1;
        }
    }
    if rows.r.len() < 9 * 20 {
        return Err(SimError::invalid(
            "data",
            format!("{} windows", rows.r.len() / 9),
            format!(
                "too short: need at least 20 windows of {nw} samples after the first {} samples of each experiment",
                opts.skip
            ),
        ));
    }
    Ok(rows)
}

/// Weighted least squares of residuals `r` (channel `channel`) on the columns `cols` of `x`;
/// returns (θ over cols, weighted RSS, covariance).
fn wls(
    x: &[[f64; NCOL]],
    r: &[f64],
    channel: &[usize],
    weight: &[f64; 9],
    cols: &[usize],
) -> Result<(Vec<f64>, f64, DMatrix<f64>)> {
    let p = cols.len();
    if p == 0 {
        let rss = r.iter().zip(channel).map(|(r, c)| weight[*c] * r * r).sum();
        return Ok((Vec::new(), rss, DMatrix::zeros(0, 0)));
    }
    let rows_x = x;
    let mut a = DMatrix::<f64>::zeros(p, p);
    let mut b = DVector::<f64>::zeros(p);
    for ((x, r), c) in rows_x.iter().zip(r).zip(channel) {
        let w = weight[*c];
        for (i, &ci) in cols.iter().enumerate() {
            b[i] += w * x[ci] * r;
            for (j, &cj) in cols.iter().enumerate() {
                a[(i, j)] += w * x[ci] * x[cj];
            }
        }
    }
    // Column scaling for conditioning.
    let s: Vec<f64> = (0..p).map(|i| a[(i, i)].sqrt().max(1e-300)).collect();
    let scaled = DMatrix::from_fn(p, p, |i, j| a[(i, j)] / (s[i] * s[j]));
    let chol = scaled.cholesky().ok_or_else(|| {
        SimError::invalid(
            "data",
            "rank-deficient regressors",
            "the logs do not excite the candidate effects (wheels at rest, no torque?)",
        )
    })?;
    let inv = chol.inverse();
    let cov = DMatrix::from_fn(p, p, |i, j| inv[(i, j)] / (s[i] * s[j]));
    let theta = &cov * &b;
    let rss = rows_x
        .iter()
        .zip(r)
        .zip(channel)
        .map(|((x, r), c)| {
            let e = r - cols
                .iter()
                .enumerate()
                .map(|(i, &ci)| theta[i] * x[ci])
                .sum::<f64>();
            weight[*c] * e * e
        })
        .sum();
    Ok((theta.iter().copied().collect(), rss, cov))
}

fn residuals(x: &[[f64; NCOL]], r: &[f64], cols: &[usize], theta: &[f64]) -> Vec<f64> {
    x.iter()
        .zip(r)
        .map(|(x, r)| r - cols.iter().zip(theta).map(|(&c, t)| t * x[c]).sum::<f64>())
        .collect()
}

/// A weighted least-squares fit on candidate columns, with the Coulomb smoothing speed
/// profiled when the Coulomb column is among them.
#[derive(Debug, Clone)]
struct Fitted {
    /// Candidate columns.
    cols: Vec<usize>,
    /// Regressors (the Coulomb column at `smoothing`).
    x: Vec<[f64; NCOL]>,
    /// Estimates over `cols`.
    theta: Vec<f64>,
    /// Weighted RSS.
    rss: f64,
    /// Covariance over `cols` (with ε profiled, it includes ε's uncertainty).
    cov: DMatrix<f64>,
    /// Fitted smoothing speed ε and its standard error, when Coulomb friction is fitted.
    smoothing: Option<(f64, f64)>,
}

impl Fitted {
    /// Free parameters: the columns, and ε.
    fn free(&self) -> usize {
        self.cols.len() + usize::from(self.smoothing.is_some())
    }
}

/// Fits `cols` of `rows`; with the Coulomb column, the least-squares cost profiled over the
/// smoothing speed ε (linear in every other parameter at a given ε): a log grid over
/// [`COULOMB_SMOOTHING_RANGE`], then golden-section search between the best point's neighbours.
/// The covariance is that of the linearization in all parameters (the ε-derivative column
/// times the Coulomb level added), so the other standard errors include ε's uncertainty.
fn fit_profiled(rows: &Rows, weight: &[f64; 9], cols: &[usize]) -> Result<Fitted> {
    let fit_at = |eps: f64| -> Result<Fitted> {
        let x = rows.smoothed_x(eps);
        let (theta, rss, cov) = wls(&x, &rows.r, &rows.channel, weight, cols)?;
        Ok(Fitted {
            cols: cols.to_vec(),
            x,
            theta,
            rss,
            cov,
            smoothing: Some((eps, f64::INFINITY)),
        })
    };
    if !cols.contains(&COULOMB) {
        let (theta, rss, cov) = wls(&rows.x, &rows.r, &rows.channel, weight, cols)?;
        return Ok(Fitted {
            cols: cols.to_vec(),
            x: rows.x.clone(),
            theta,
            rss,
            cov,
            smoothing: None,
        });
    }
    let (lo, hi) = COULOMB_SMOOTHING_RANGE;
    let (a, b) = (lo.ln(), hi.ln());
    let grid: Vec<f64> = (0..=GRID)
        .map(|i| a + (b - a) * i as f64 / GRID as f64)
        .collect();
    let cost = |l: f64| fit_at(l.exp()).map_or(f64::INFINITY, |f| f.rss);
    let costs: Vec<f64> = grid.iter().map(|&l| cost(l)).collect();
    let best = (0..costs.len())
        .min_by(|&i, &j| costs[i].total_cmp(&costs[j]))
        .unwrap_or(0);
    // Golden-section search on ln ε between the neighbours of the best grid point.
    let (mut l, mut u) = (grid[best.saturating_sub(1)], grid[(best + 1).min(GRID)]);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut c, mut d) = (u - g * (u - l), l + g * (u - l));
    let (mut fc, mut fd) = (cost(c), cost(d));
    for _ in 0..GOLDEN_STEPS {
        if fc < fd {
            (u, d, fd) = (d, c, fc);
            c = u - g * (u - l);
            fc = cost(c);
        } else {
            (l, c, fc) = (c, d, fd);
            d = l + g * (u - l);
            fd = cost(d);
        }
    }
    let ln_eps = [(grid[best], costs[best]), (c, fc), (d, fd)]
        .into_iter()
        .min_by(|p, q| p.1.total_cmp(&q.1))
        .map_or(grid[best], |p| p.0);
    let eps = ln_eps.exp();
    let mut fitted = fit_at(eps)?;
    // Linearization in ε: the column ∂x/∂ε times the level c_c. A near-collinear column (the
    // level near zero, or ε so wide that tanh is a viscous slope) leaves ε undetermined: its
    // standard error is then infinite and the others are conditional on it.
    let level = fitted
        .cols
        .iter()
        .position(|&c| c == COULOMB)
        .map_or(0.0, |i| fitted.theta[i]);
    let mut with_d = fitted.cols.clone();
    with_d.push(D_SMOOTHING);
    if let Ok((_, _, cov)) = wls(&fitted.x, &rows.r, &rows.channel, weight, &with_d) {
        let p = fitted.cols.len();
        if level != 0.0 && cov[(p, p)].is_finite() {
            fitted.smoothing = Some((eps, cov[(p, p)].max(0.0).sqrt() / level.abs()));
            fitted.cov = cov.view((0, 0), (p, p)).into_owned();
        }
    }
    Ok(fitted)
}

/// Points of the smoothing-speed grid (log spaced) and golden-section steps after it.
const GRID: usize = 24;
const GOLDEN_STEPS: usize = 24;

/// Orthonormal basis of one channel's probe regressors (column-scaled, rank-revealing SVD).
#[derive(Debug, Clone)]
struct ProbeBasis {
    /// Rows of the channel.
    idx: Vec<usize>,
    /// Orthonormal columns spanning the probes on those rows.
    u: DMatrix<f64>,
}

fn probe_bases(rows: &Rows) -> Vec<ProbeBasis> {
    (0..CHANNELS.len())
        .map(|ch| {
            let idx: Vec<usize> = (0..rows.r.len())
                .filter(|&i| rows.channel[i] == ch)
                .collect();
            let q = idx.first().map_or(0, |&i| rows.probes[i].len());
            let n = idx.len();
            let x = DMatrix::from_fn(n, q, |r, c| rows.probes[idx[r]][c]);
            // Scale columns, then keep the singular directions above 1e-9 of the largest
            // (probes may be nearly collinear).
            let scale: Vec<f64> = (0..q).map(|c| x.column(c).norm().max(1e-300)).collect();
            let xs = DMatrix::from_fn(n, q, |r, c| x[(r, c)] / scale[c]);
            let svd = xs.svd(true, false);
            let smax = svd.singular_values.max();
            let keep: Vec<usize> = (0..svd.singular_values.len())
                .filter(|&k| svd.singular_values[k] > 1e-9 * smax)
                .collect();
            let u = svd.u.map_or_else(
                || DMatrix::zeros(n, 0),
                |u| DMatrix::from_fn(n, keep.len(), |r, c| u[(r, keep[c])]),
            );
            ProbeBasis { idx, u }
        })
        .collect()
}

/// Regressors and residuals with every channel's probes projected out (Frisch-Waugh-Lovell:
/// least squares on them equals least squares with the probes as nuisance columns), and the
/// probe rank used.
type WithoutProbes = (Vec<[f64; NCOL]>, Vec<f64>, usize);

fn without_probes(x: &[[f64; NCOL]], r: &[f64], bases: &[ProbeBasis]) -> WithoutProbes {
    let (mut xo, mut ro) = (x.to_vec(), r.to_vec());
    let mut rank = 0;
    for b in bases {
        rank += b.u.ncols();
        let project = |v: DVector<f64>| &v - &b.u * (b.u.transpose() * &v);
        let n = b.idx.len();
        let rp = project(DVector::from_iterator(n, b.idx.iter().map(|&i| r[i])));
        for (k, &i) in b.idx.iter().enumerate() {
            ro[i] = rp[k];
        }
        for col in 0..NCOL {
            let xp = project(DVector::from_iterator(n, b.idx.iter().map(|&i| x[i][col])));
            for (k, &i) in b.idx.iter().enumerate() {
                xo[i][col] = xp[k];
            }
        }
    }
    (xo, ro, rank)
}

/// p-value per channel of the residual against the generic probes (F test).
fn probe_p_values(bases: &[ProbeBasis], resid: &[f64]) -> Vec<f64> {
    bases
        .iter()
        .map(|b| {
            let (n, rank) = (b.idx.len(), b.u.ncols());
            let y = DVector::from_iterator(n, b.idx.iter().map(|&i| resid[i]));
            let ss = (b.u.transpose() * &y).norm_squared();
            let rss1 = y.norm_squared() - ss;
            if rss1 <= 0.0 || n <= rank + 1 || rank == 0 {
                return 1.0;
            }
            let f = (ss / rank as f64) / (rss1 / (n - rank) as f64);
            f_sf(f, rank as f64, (n - rank) as f64)
        })
        .collect()
}

/// Channels whose residual the probes explain at 1% (Bonferroni over the nine channels).
fn flagged(channel_p_values: &[f64]) -> Vec<String> {
    channel_p_values
        .iter()
        .zip(CHANNELS)
        .filter(|(p, _)| **p < LEVEL / CHANNELS.len() as f64)
        .map(|(_, c)| c.to_string())
        .collect()
}

/// The verdict on a final residual: the channels its probes explain, at the smallest channel
/// p-value Bonferroni-corrected over the channels.
fn verdict_of(channel_p_values: &[f64]) -> Verdict {
    let p_value = channel_p_values
        .iter()
        .fold(1.0f64, |m, p| m.min(p * CHANNELS.len() as f64));
    let outputs = flagged(channel_p_values);
    if outputs.is_empty() {
        Verdict::ExplainedToNoiseLevel { p_value }
    } else {
        Verdict::UnexplainedStructuredMisfit {
            p_value,
            outputs,
            band_hz: None,
            worst_entries: Vec::new(),
        }
    }
}

/// The documented (nominal) value, range and unit of every parameter the candidates estimate:
/// the nominal model has none of the effects.
fn documented() -> Vec<Parameter> {
    let (lo, hi) = COULOMB_SMOOTHING_RANGE;
    let inf = f64::INFINITY;
    let mut p = vec![
        Parameter::new("wheel_viscous_friction", 0.0, 0.0, inf, "N m s/rad"),
        Parameter::new("wheel_coulomb_friction", 0.0, 0.0, inf, "N m"),
        Parameter::new(COULOMB_SMOOTHING, 0.1, lo, hi, "rad/s"),
        Parameter::new("torque_constant", 1.0, -inf, inf, ""),
    ];
    for axis in ["x", "y", "z"] {
        p.push(Parameter::new(
            format!("gyro_bias_{axis}"),
            0.0,
            -inf,
            inf,
            "rad/s",
        ));
    }
    p
}

/// An estimate with its documented unit (`std` absent when it is not determined).
fn estimate(name: &str, value: f64, std: f64) -> ParamEstimate {
    let unit = documented()
        .into_iter()
        .find(|p| p.name == name)
        .map_or_else(String::new, |p| p.unit);
    ParamEstimate {
        name: name.to_string(),
        value,
        std: std.is_finite().then_some(std),
        unit,
        held: false,
        at_bound: false,
        poorly_determined: !std.is_finite() || std >= value.abs(),
    }
}

/// One step of the Cubli discovery (or the one fitted model of `compare` / `fit`).
#[derive(Debug, Clone, Serialize)]
pub struct CubliStep {
    /// Effect added (`None` for the starting model).
    pub added: Option<String>,
    /// Effects in the model.
    pub effects: Vec<String>,
    /// Weighted cost (sum of squared residuals over noise variance).
    pub cost: f64,
    /// Reduction relative to the nominal model, %.
    pub reduction_percent: f64,
    /// RMS residual over estimated noise standard deviation, per channel.
    pub channel_rms_over_noise: Vec<f64>,
    /// Per channel, p-value of the residual against the generic probes.
    pub channel_p_values: Vec<f64>,
    /// Parameters with standard errors.
    pub params: Vec<ParamEstimate>,
    /// Candidates tried on this step.
    pub candidates: Vec<CandidateScore>,
    /// Why candidates that pass the plain F test were not added.
    pub not_added: Vec<String>,
    /// Residual of every window row over its channel's noise standard deviation.
    #[serde(skip)]
    pub whitened_residuals: Vec<f64>,
    /// The fit behind it.
    #[serde(skip)]
    fit: Fitted,
    /// Why, as a candidate, it is refused whatever its tests say.
    #[serde(skip)]
    refusal: Option<String>,
}

impl CubliStep {
    /// Channels carrying a structured misfit after this step.
    pub fn misfit_channels(&self) -> Vec<String> {
        flagged(&self.channel_p_values)
    }
}

/// Per-channel diagnosis of the current model.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelDiagnosis {
    /// Residual channel.
    pub channel: String,
    /// RMS residual over the estimated noise standard deviation.
    pub rms_over_noise: f64,
    /// Estimated noise standard deviation of the window residual.
    pub noise_std: f64,
    /// p-value of the residual against the generic probes.
    pub probe_p_value: f64,
    /// Structured misfit at 1% (Bonferroni over the channels).
    pub flagged: bool,
}

/// Result of [`CubliBench::discover`] or [`CubliBench::fit`].
#[derive(Debug, Clone, Serialize)]
pub struct CubliDiscovery {
    /// Steps from the starting model.
    pub steps: Vec<CubliStep>,
    /// Found and tentative effects, verdict (its outputs are the residual channels). Effects
    /// are tentative when the final model leaves a structured misfit.
    #[serde(flatten)]
    pub conclusion: Conclusion,
    /// Channels carrying the misfit.
    pub misfit_channels: Vec<String>,
    /// Per-channel p-value of the final residual against the generic probes.
    pub channel_p_values: Vec<f64>,
    /// Estimated residual noise standard deviation per channel.
    pub noise_std: Vec<f64>,
    /// Windows used.
    pub windows: usize,
    /// Window length in samples.
    pub window_samples: usize,
    /// Experiments used.
    pub experiments: usize,
    /// Channel, experiment and start time (s) of each window row.
    #[serde(skip)]
    pub rows: Vec<(usize, usize, f64)>,
}

impl CubliDiscovery {
    /// The verdict's sentence, with the tentative effects and why.
    pub fn verdict_sentence(&self) -> String {
        let mut text = self.conclusion.verdict_sentence();
        if let (false, Some(last)) = (self.conclusion.tentative.is_empty(), self.steps.last()) {
            text.push_str(&format!(
                " ([{}] lower the cost by {:.2}% but are tentative, not found: {})",
                self.conclusion.tentative.join(", "),
                last.reduction_percent,
                self.conclusion.caveats.join("; ")
            ));
        }
        text
    }

    /// The workbench JSON: the fields every criterion writes ([`step_fields`],
    /// [`conclusion_fields`]) and the window regression's own.
    pub fn json(&self) -> Value {
        let steps: Vec<Value> = self
            .steps
            .iter()
            .map(|s| {
                let mut step = step_fields(
                    &s.added,
                    &s.effects,
                    s.cost,
                    s.reduction_percent,
                    &s.params,
                    &s.candidates,
                );
                for (k, v) in [
                    ("channel_rms_over_noise", json!(s.channel_rms_over_noise)),
                    ("channel_p_values", json!(s.channel_p_values)),
                    ("not_added", json!(s.not_added)),
                ] {
                    step.insert(k.to_string(), v);
                }
                Value::Object(step)
            })
            .collect();
        let held: serde_json::Map<String, Value> = HELD
            .iter()
            .map(|(k, v)| (k.to_string(), json!(v)))
            .collect();
        let mut doc = conclusion_fields("cubli", steps, &self.conclusion);
        for (k, v) in [
            (
                "method",
                json!(format!(
                    "time-domain prediction error over {}-sample windows",
                    self.window_samples
                )),
            ),
            ("misfit_channels", json!(self.misfit_channels)),
            ("channels", json!(CHANNELS)),
            ("channel_p_values", json!(self.channel_p_values)),
            ("noise_std", json!(self.noise_std)),
            ("windows", json!(self.windows)),
            ("experiments", json!(self.experiments)),
            ("held", json!(held)),
        ] {
            doc.insert(k.to_string(), v);
        }
        Value::Object(doc)
    }

    /// The terminal summary table.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Cubli: {}, {} windows of {} samples, prediction error on {}",
            count(self.experiments, "experiment"),
            self.windows,
            self.window_samples,
            CHANNELS.join(" ")
        );
        let _ = writeln!(
            s,
            "{:>4}  {:<24} {:>12} {:>9}  rms/noise per channel",
            "step", "effect added", "cost", "red. %"
        );
        for (i, st) in self.steps.iter().enumerate() {
            let ch: Vec<String> = st
                .channel_rms_over_noise
                .iter()
                .map(|v| format!("{v:.2}"))
                .collect();
            let _ = writeln!(
                s,
                "{:>4}  {:<24} {:>12.1} {:>9.2}  {}",
                i,
                st.added.as_deref().unwrap_or("(start)"),
                st.cost,
                st.reduction_percent,
                ch.join(" ")
            );
        }
        if let Some(last) = self.steps.last() {
            for p in &last.params {
                let std = p
                    .std
                    .map_or_else(|| "undetermined".to_string(), |v| format!("{v:.1e}"));
                let _ = writeln!(s, "  {} = {:.4e} ± {std}", p.name, p.value);
            }
        }
        for st in &self.steps {
            for why in &st.not_added {
                let _ = writeln!(s, "  not added: {why}");
            }
        }
        for (k, v) in HELD {
            let _ = writeln!(s, "  held: {k} ({v})");
        }
        s.push_str(&self.conclusion.lines());
        s
    }
}

fn params_of(rows: &Rows, effects: &[String], fit: &Fitted) -> Vec<ParamEstimate> {
    let (cols, theta, cov) = (&fit.cols, &fit.theta, &fit.cov);
    let at = |c: usize| cols.iter().position(|&x| x == c);
    let mut out = Vec::new();
    for e in effects {
        match e.as_str() {
            "gyro_bias" => {
                if let (Some(i), Some(j)) = (at(2), at(3)) {
                    let [b1, b2] = rows.bias_basis;
                    let v = b1 * theta[i] + b2 * theta[j];
                    for (a, name) in ["x", "y", "z"].iter().enumerate() {
                        let var = b1[a] * b1[a] * cov[(i, i)]
                            + b2[a] * b2[a] * cov[(j, j)]
                            + 2.0 * b1[a] * b2[a] * cov[(i, j)];
                        out.push(estimate(
                            &format!("gyro_bias_{name}"),
                            v[a],
                            var.max(0.0).sqrt(),
                        ));
                    }
                }
            }
            name => {
                if let Some(i) = columns_of(name).first().and_then(|&c| at(c)) {
                    let offset = if name == "torque_constant" { 1.0 } else { 0.0 };
                    out.push(estimate(
                        name,
                        theta[i] + offset,
                        cov[(i, i)].max(0.0).sqrt(),
                    ));
                }
                if let (true, Some((eps, std))) = (c_is_coulomb(name), fit.smoothing) {
                    out.push(estimate(COULOMB_SMOOTHING, eps, std));
                }
            }
        }
    }
    out
}

fn c_is_coulomb(effect: &str) -> bool {
    columns_of(effect) == [COULOMB]
}

fn cols_for(effects: &[String]) -> Vec<usize> {
    let mut c: Vec<usize> = effects
        .iter()
        .flat_map(|e| columns_of(e).iter().copied())
        .collect();
    c.sort_unstable();
    c
}

/// Loads Cubli logs (MCAP or CSV, or directories of them).
pub fn load_cubli(paths: &[PathBuf]) -> Result<Dataset> {
    let inputs: Vec<String> = INPUTS.iter().map(|s| s.to_string()).collect();
    let outputs: Vec<String> = OUTPUTS.iter().map(|s| s.to_string()).collect();
    load::load("cubli", &inputs, &outputs, paths)
}

/// The Cubli workbench: window rows of the logs, the per-channel noise level and the effects
/// enabled so far.
#[derive(Debug, Clone)]
pub struct CubliBench {
    rows: Rows,
    bases: Vec<ProbeBasis>,
    var: [f64; 9],
    weight: [f64; 9],
    base_cost: f64,
    effects: Vec<String>,
    window: usize,
    experiments: usize,
}

impl CubliBench {
    /// Checks the channels, builds the window rows and estimates the noise of each channel.
    pub fn new(data: &Dataset, opts: &CubliOptions) -> Result<Self> {
        data.validate()?;
        for (what, want, have) in [
            ("input", &INPUTS[..], &data.inputs),
            ("output", &OUTPUTS[..], &data.outputs),
        ] {
            if want.iter().ne(have.iter()) {
                let missing: Vec<&str> = want
                    .iter()
                    .copied()
                    .filter(|n| !have.iter().any(|h| h == n))
                    .collect();
                return Err(SimError::invalid(
                    format!("{what} channels"),
                    have.join(","),
                    format!(
                        "the Cubli model needs {} in this order{}",
                        want.join(","),
                        if missing.is_empty() {
                            String::new()
                        } else {
                            format!("; missing channel {}", missing.join(", "))
                        }
                    ),
                ));
            }
        }
        let rows = build_rows(data, opts)?;
        // Noise variance per channel from the fit with every candidate (consistent whichever
        // of them are present).
        let all = cols_for(&CANDIDATES.map(String::from));
        let fit_all = fit_profiled(&rows, &[1.0; 9], &all)?;
        let res_all = residuals(&fit_all.x, &rows.r, &all, &fit_all.theta);
        let mut var = [0.0; 9];
        let mut count = [0usize; 9];
        for (e, c) in res_all.iter().zip(&rows.channel) {
            var[*c] += e * e;
            count[*c] += 1;
        }
        for c in 0..9 {
            // Five parameters spread over nine channels: one degree of freedom per channel
            // is a conservative correction.
            var[c] = (var[c] / (count[c] as f64 - 1.0).max(1.0)).max(1e-300);
        }
        let weight: [f64; 9] = std::array::from_fn(|c| 1.0 / var[c]);
        let (_, base_cost, _) = wls(&rows.x, &rows.r, &rows.channel, &weight, &[])?;
        let bases = probe_bases(&rows);
        Ok(Self {
            rows,
            bases,
            var,
            weight,
            base_cost,
            effects: Vec::new(),
            window: opts.window,
            experiments: data.experiments.len(),
        })
    }

    /// Loads logs and prepares the workbench with the default options.
    pub fn load(paths: &[PathBuf]) -> Result<Self> {
        Self::new(&load_cubli(paths)?, &CubliOptions::default())
    }

    /// Effects enabled so far.
    pub fn effects(&self) -> &[String] {
        &self.effects
    }

    /// Enables a candidate effect by name.
    pub fn add(&mut self, effect: &str) -> Result<()> {
        if !CANDIDATES.contains(&effect) {
            return Err(SimError::invalid(
                "effect",
                effect,
                format!(
                    "unknown for cubli; known effects: {}",
                    CANDIDATES.join(", ")
                ),
            ));
        }
        if !self.effects.iter().any(|e| e == effect) {
            self.effects.push(effect.to_string());
        }
        Ok(())
    }

    fn channel_rms(&self, resid: &[f64]) -> Vec<f64> {
        (0..9)
            .map(|c| {
                let (s, k) = resid
                    .iter()
                    .zip(&self.rows.channel)
                    .filter(|(_, ch)| **ch == c)
                    .fold((0.0, 0usize), |(s, k), (e, _)| (s + e * e, k + 1));
                (s / k.max(1) as f64 / self.var[c]).sqrt()
            })
            .collect()
    }

    fn step(&self, effects: &[String], added: Option<String>) -> Result<CubliStep> {
        let fit = fit_profiled(&self.rows, &self.weight, &cols_for(effects))?;
        let resid = residuals(&fit.x, &self.rows.r, &fit.cols, &fit.theta);
        Ok(CubliStep {
            added,
            effects: effects.to_vec(),
            cost: fit.rss,
            reduction_percent: 100.0 * (1.0 - fit.rss / self.base_cost),
            channel_rms_over_noise: self.channel_rms(&resid),
            channel_p_values: probe_p_values(&self.bases, &resid),
            params: params_of(&self.rows, effects, &fit),
            candidates: Vec::new(),
            not_added: Vec::new(),
            whitened_residuals: resid
                .iter()
                .zip(&self.rows.channel)
                .map(|(e, c)| e / self.var[*c].sqrt())
                .collect(),
            fit,
            refusal: None,
        })
    }

    fn record(&self, steps: Vec<CubliStep>, found: Vec<String>) -> CubliDiscovery {
        let channel_p_values = steps
            .last()
            .map_or_else(Vec::new, |s| s.channel_p_values.clone());
        let misfit_channels = flagged(&channel_p_values);
        let unexplained = !misfit_channels.is_empty();
        let why = unexplained.then(|| MISFIT_CAVEAT.to_string());
        let rivals = rivals(
            steps
                .iter()
                .map(|s| (s.added.as_deref(), s.candidates.as_slice())),
        );
        let conclusion = Conclusion::settle(
            found,
            why.into_iter().collect(),
            rivals,
            unexplained,
            verdict_of(&channel_p_values),
            LEVEL,
        )
        .with_near_misses(steps.last().map_or(&[][..], |s| s.candidates.as_slice()))
        .with_test("for the probes' fit to the residual, the smallest over the channels");
        CubliDiscovery {
            steps,
            conclusion,
            misfit_channels,
            channel_p_values,
            noise_std: self.var.iter().map(|v| v.sqrt()).collect(),
            windows: self.rows.r.len() / 9,
            window_samples: self.window,
            experiments: self.experiments,
            rows: self
                .rows
                .channel
                .iter()
                .zip(&self.rows.window)
                .map(|(c, (e, t))| (*c, *e, *t))
                .collect(),
        }
    }

    /// Fits the current model (the enabled effects): a one-step record with its verdict.
    pub fn fit(&self) -> Result<CubliDiscovery> {
        Ok(self.record(vec![self.step(&self.effects, None)?], Vec::new()))
    }

    /// Where the current model fails: per channel the residual against the noise level and
    /// the generic probes.
    pub fn diagnose(&self) -> Result<Vec<ChannelDiagnosis>> {
        let step = self.step(&self.effects, None)?;
        Ok(CHANNELS
            .iter()
            .enumerate()
            .map(|(c, name)| ChannelDiagnosis {
                channel: name.to_string(),
                rms_over_noise: step.channel_rms_over_noise[c],
                noise_std: self.var[c].sqrt(),
                probe_p_value: step.channel_p_values[c],
                flagged: step.channel_p_values[c] < LEVEL / CHANNELS.len() as f64,
            })
            .collect())
    }

    /// Scores adding `name` to the model of `current`: the step it would give (with why it is
    /// refused whatever its tests say: a negative friction coefficient, or a cost reduction
    /// within the noise) and the score.
    fn score(
        &self,
        current: &CubliStep,
        name: &str,
        n_candidates: usize,
    ) -> Result<(CubliStep, CandidateScore)> {
        let mut with = current.effects.clone();
        with.push(name.to_string());
        let next = self.step(&with, Some(name.to_string()))?;
        let (fit0, fit1) = (&current.fit, &next.fit);
        let n = self.rows.r.len() as f64;
        // Costs are in units of each channel's noise variance: a cost of n rows varies by
        // sqrt(2 n) under noise alone.
        let costs = |before: f64, after: f64| NestedCosts {
            before,
            after,
            residuals: n,
            free_before: fit0.free(),
            free_after: fit1.free(),
            scale: 1.0,
            noise_sd: (2.0 * n).sqrt(),
            // The rows' noise is taken as independent.
            design_effect: 1.0,
        };
        // The robustness check: the same F test with the probes as nuisance columns in both
        // models (each at its own fitted smoothing speed). Rank-deficient (the probes
        // reproduce the candidate's regressor) counts as not significant.
        let (x0, r0, rank) = without_probes(&fit0.x, &self.rows.r, &self.bases);
        let (x1, r1, _) = without_probes(&fit1.x, &self.rows.r, &self.bases);
        let ch = &self.rows.channel;
        let robust_p_value = match (
            wls(&x0, &r0, ch, &self.weight, &fit0.cols),
            wls(&x1, &r1, ch, &self.weight, &fit1.cols),
        ) {
            (Ok((_, c0, _)), Ok((_, c1, _))) => {
                let with_probes = NestedCosts {
                    before: c0,
                    after: c1,
                    residuals: n - rank as f64,
                    ..costs(current.cost, next.cost)
                };
                with_probes.f_test().1
            }
            _ => 1.0,
        };
        let score = CandidateScore::nested(
            name,
            &costs(current.cost, next.cost),
            Robustness::PValue(robust_p_value),
            n_candidates,
            false,
        );
        // A friction coefficient must come out non-negative: a negative one only fits a
        // mismatch of the model class (a regressor built from noisy wheel speeds, a friction
        // law of another shape), which the other candidates absorb in part.
        let negative = next
            .params
            .iter()
            .find(|p| p.value < 0.0 && NON_NEGATIVE.contains(&p.name.as_str()));
        let refusal = if let Some(p) = negative {
            Some(format!(
                "{} = {:.2e} is negative (a friction coefficient cannot be)",
                p.name, p.value
            ))
        } else if !score.exceeds_noise {
            Some(format!(
                "lowers the cost by {:.1}, within what noise alone varies it ({:.1})",
                current.cost - next.cost,
                (2.0 * n).sqrt()
            ))
        } else {
            None
        };
        let score = CandidateScore {
            significant: score.significant && refusal.is_none(),
            ..score
        };
        Ok((CubliStep { refusal, ..next }, score))
    }

    /// Runs the discovery loop from the current model.
    ///
    /// A candidate is added when it passes the nested F test at 1% (Bonferroni over the
    /// candidates) with a lower BIC and either leaves no structured misfit in any channel or
    /// stays significant with the generic probes as nuisance columns. The plain F test
    /// assumes the rest is noise; when a misfit no candidate describes remains (a logging
    /// delay, say), any candidate correlated with it passes that test, so it alone is not
    /// evidence. The probes do not capture every such misfit (a one-sample torque delay
    /// correlates with the torque inside the window, which they must leave out), so when
    /// the final model still carries a structured misfit the effects added are reported as
    /// `tentative`, not `found`.
    pub fn discover(&self) -> Result<CubliDiscovery> {
        let start = self.step(&self.effects, None)?;
        let (steps, found) = forward_selection(self, start, &mut |_: &str| {})?;
        Ok(self.record(steps, found))
    }
}

/// The window regression's moves in the workbench's forward selection.
impl Search for CubliBench {
    type Fit = CubliStep;
    type Context = ();

    fn candidates(&self, at: &CubliStep) -> Vec<String> {
        CANDIDATES
            .iter()
            .filter(|c| !at.effects.iter().any(|e| e == *c))
            .map(|c| c.to_string())
            .collect()
    }

    fn context(&self, _: &CubliStep) -> Result<()> {
        Ok(())
    }

    fn try_effect(
        &self,
        at: &CubliStep,
        _: &(),
        effect: &str,
        n: usize,
    ) -> Result<(CubliStep, CandidateScore)> {
        self.score(at, effect, n)
    }

    /// The lowest-cost candidate among those that are significant, or pass the plain F test
    /// and leave no structured misfit; why others that pass the plain F test are not added
    /// goes to `not_added`.
    fn choose(&self, at: &mut CubliStep, tried: &[(CubliStep, CandidateScore)]) -> Option<usize> {
        let alpha = LEVEL / tried.len().max(1) as f64;
        let mut best: Option<usize> = None;
        for (i, (next, score)) in tried.iter().enumerate() {
            let plain_f = score.p_value < alpha && score.delta_bic < 0.0;
            let passes_f = plain_f && next.refusal.is_none();
            let explains = passes_f && next.misfit_channels().is_empty();
            let name = &score.effect;
            if score.significant || explains {
                if best.is_none_or(|b| next.cost < tried[b].0.cost) {
                    best = Some(i);
                }
            } else if let (true, Some(why)) = (plain_f, &next.refusal) {
                at.not_added.push(format!(
                    "{name}: passes the F test (p = {:.1e}) but {why}",
                    score.p_value
                ));
            } else if passes_f {
                at.not_added.push(format!(
                    "{name}: reduces the cost by {:.2}% (F test p = {:.1e}) but leaves structured misfit in [{}] and is not significant beyond the generic probes (p = {:.2})",
                    score.reduction_percent,
                    score.p_value,
                    next.misfit_channels().join(", "),
                    score.robust_p_value
                ));
            }
        }
        best
    }

    fn record_scores(&self, at: &mut CubliStep, scores: Vec<CandidateScore>) {
        at.candidates = scores;
    }

    fn removed(&self, at: &CubliStep, effect: &str) -> Result<CubliStep> {
        let effects: Vec<String> = at
            .effects
            .iter()
            .filter(|e| *e != effect)
            .cloned()
            .collect();
        self.step(&effects, None)
    }

    /// Each fit is a small least-squares problem.
    fn parallel(&self) -> bool {
        false
    }
}

/// Runs the discovery loop on Cubli data from the nominal model.
pub fn discover(data: &Dataset, opts: &CubliOptions) -> Result<CubliDiscovery> {
    CubliBench::new(data, opts)?.discover()
}

/// Writes the Cubli HTML report into `dir` (same rules).
pub fn write_cubli_report(dir: &Path, d: &CubliDiscovery) -> Result<()> {
    publish(dir, &cubli_html(d), &d.json())
}

/// The Cubli report: summary, error per step, parameter table, residual level per channel
/// and step, the residual over time of the worst channel, verdict.
fn cubli_html(d: &CubliDiscovery) -> String {
    let mut body = String::new();
    let _ = write!(
        body,
        "<h1>stabilis workbench: cubli</h1><p>Time-domain prediction error over {} windows of {} samples from {}; residual channels {}.</p><h2>Verdict</h2><p><b>{}</b>. Found: [{}]. Tentative: [{}].</p>",
        d.windows,
        d.window_samples,
        count(d.experiments, "experiment"),
        CHANNELS.join(", "),
        escape(&d.verdict_sentence()),
        escape(&d.conclusion.found.join(", ")),
        escape(&d.conclusion.tentative.join(", "))
    );
    let _ = write!(body, "<h2>Summary</h2><pre>{}</pre>", escape(&d.table()));
    let bars: Vec<(String, f64)> = d
        .steps
        .iter()
        .map(|s| (s.added.clone().unwrap_or_else(|| "start".into()), s.cost))
        .collect();
    // The weighted cost of noise alone is about the number of residual rows.
    body.push_str(&cost_bars(&bars, Some((d.windows * CHANNELS.len()) as f64)));
    let steps: Vec<(Option<&str>, &[ParamEstimate])> = d
        .steps
        .iter()
        .map(|st| (st.added.as_deref(), st.params.as_slice()))
        .collect();
    body.push_str(&parameters_html(&documented(), &steps));
    let label =
        |k: usize, st: &CubliStep| format!("{k}: {}", st.added.as_deref().unwrap_or("start"));
    let rms = per_step(&d.steps, label, true, |st| {
        st.channel_rms_over_noise
            .iter()
            .enumerate()
            .map(|(c, v)| ((c + 1) as f64, *v))
            .collect()
    });
    let channel_axis = XAxis::linear("channel (1-3 p_w, 4-6 p_h, 7-9 g)");
    let _ = write!(
        body,
        "<h2>Residuals</h2><p>RMS window residual over the estimated noise standard deviation per channel (1 = noise level).</p>{}",
        chart("residual rms / noise", channel_axis, "ratio", &rms)
    );
    let worst = d.steps.first().map_or(0, |st| {
        st.channel_rms_over_noise
            .iter()
            .enumerate()
            .fold(
                (0, f64::NEG_INFINITY),
                |a, (c, v)| if *v > a.1 { (c, *v) } else { a },
            )
            .0
    });
    let series = per_step(&d.steps, label, false, |st| {
        d.rows
            .iter()
            .zip(&st.whitened_residuals)
            .filter(|((c, e, _), _)| *c == worst && *e == 0)
            .map(|((_, _, t), v)| (*t, *v))
            .collect()
    });
    let time_axis = XAxis::linear("time (s), experiment 1");
    let _ = write!(
        body,
        "<p>Residual of channel {} (largest misfit of the starting model) over the windows of the first experiment, in noise standard deviations.</p>{}",
        CHANNELS[worst],
        chart(&format!("{} residual / noise", CHANNELS[worst]), time_axis, "residual / std", &series)
    );
    page(&body)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    /// Random rows over the nine channels with three probe columns each.
    fn random_rows(seed: u64, n: usize) -> Rows {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut next = || rng.random::<f64>() - 0.5;
        let mut rows = Rows::empty([Vector3::x(), Vector3::y()]);
        for i in 0..n {
            rows.x.push(std::array::from_fn(|_| next()));
            rows.r.push(next());
            rows.probes.push(vec![1.0, next(), next()]);
            rows.channel.push(i % 9);
            rows.speeds.push(Vec::new());
            rows.window.push((0, i as f64));
        }
        rows
    }

    proptest! {
        /// Frisch-Waugh-Lovell: least squares on the rows with the probes projected out gives
        /// the candidate coefficients and residual sum of squares of the full least squares
        /// with nine channel-specific probe blocks as extra columns (solved directly by SVD).
        #[test]
        fn projecting_out_probes_equals_fitting_them(seed in 0u64..1000) {
            let rows = random_rows(seed, 180);
            let bases = probe_bases(&rows);
            let (x, r, rank) = without_probes(&rows.x, &rows.r, &bases);
            prop_assert_eq!(rank, 27);
            let cols: Vec<usize> = (0..NCOL).collect();
            let (theta, rss, _) = wls(&x, &r, &rows.channel, &[1.0; 9], &cols).unwrap();
            let n = rows.r.len();
            let full = DMatrix::from_fn(n, NCOL + 27, |i, j| {
                if j < NCOL {
                    rows.x[i][j]
                } else {
                    let (ch, k) = ((j - NCOL) / 3, (j - NCOL) % 3);
                    if rows.channel[i] == ch { rows.probes[i][k] } else { 0.0 }
                }
            });
            let y = DVector::from_column_slice(&rows.r);
            let beta = full.clone().svd(true, true).solve(&y, 1e-12).unwrap();
            for (a, b) in theta.iter().zip(beta.iter()) {
                prop_assert!((a - b).abs() < 1e-7, "{a} vs {b}");
            }
            let rss_full = (&y - &full * &beta).norm_squared();
            prop_assert!((rss - rss_full).abs() < 1e-7 * rss_full.max(1.0), "{rss} vs {rss_full}");
        }

        /// A residual that a channel's probes partly explain is flagged on that channel with
        /// a p-value near 0.
        #[test]
        fn probe_test_flags_a_residual_the_probes_explain(seed in 0u64..1000) {
            let rows = random_rows(seed, 900);
            let bases = probe_bases(&rows);
            let mut rng = StdRng::seed_from_u64(seed + 1);
            let resid: Vec<f64> = (0..rows.r.len())
                .map(|i| {
                    let noise = rng.random::<f64>() - 0.5;
                    if rows.channel[i] == 4 { noise + 2.0 * rows.probes[i][1] } else { noise }
                })
                .collect();
            let p = probe_p_values(&bases, &resid);
            prop_assert!(p[4] < 1e-9, "{:?}", p);
            prop_assert!(flagged(&p).contains(&"p_hy".to_string()), "{:?}", p);
        }
    }

    proptest! {
        /// The closed-form mean of tanh along a linear speed ramp equals Simpson's rule on a
        /// fine grid, across the step at zero and for nearly equal ends.
        #[test]
        fn mean_tanh_is_the_integral_along_the_ramp(
            a in -3.0f64..3.0,
            delta in prop_oneof![-0.5f64..0.5, -1e-6f64..1e-6],
            eps in 0.005f64..2.0,
        ) {
            let b = a + delta;
            let m = 2000;
            let f = |i: usize| (a + delta * i as f64 / m as f64) / eps;
            let simpson: f64 = (0..=m)
                .map(|i| {
                    let w = if i == 0 || i == m { 1.0 } else if i % 2 == 1 { 4.0 } else { 2.0 };
                    w * f(i).tanh()
                })
                .sum::<f64>()
                / (3.0 * m as f64);
            let got = mean_tanh(a, b, eps);
            prop_assert!((got - simpson).abs() < 1e-7, "{got} vs {simpson}");
        }

        /// Noise-free rows whose Coulomb friction is smoothed over speed ε are fitted back to ε
        /// and the friction levels: the profile finds the zero of the cost.
        #[test]
        fn profiled_smoothing_recovers_the_generating_width(
            eps in 0.02f64..1.5,
            level in 1e-4f64..1e-2,
            viscous in 0.0f64..1e-4,
            seed in 0u64..1000,
        ) {
            let mut rows = random_rows(seed, 180);
            let mut rng = StdRng::seed_from_u64(seed + 7);
            for (speeds, ch) in rows.speeds.iter_mut().zip(&rows.channel) {
                if *ch < 3 {
                    *speeds = (0..26).map(|_| 3.0 * (rng.random::<f64>() - 0.5)).collect();
                }
            }
            let x = rows.smoothed_x(eps);
            for (r, x) in rows.r.iter_mut().zip(&x) {
                *r = level * x[COULOMB] + viscous * x[0];
            }
            let fit = fit_profiled(&rows, &[1.0; 9], &[0, COULOMB]).unwrap();
            let (e, _) = fit.smoothing.unwrap();
            prop_assert!((e - eps).abs() < 1e-4 * eps, "{e} vs {eps}");
            prop_assert!((fit.theta[1] - level).abs() < 1e-4 * level, "{:?}", fit.theta);
            prop_assert!((fit.theta[0] - viscous).abs() < 1e-4 * level, "{:?}", fit.theta);
        }
    }

    proptest! {
        /// Noise-free rows generated from known parameters are fitted back exactly, whatever
        /// the channel weights.
        #[test]
        fn weighted_least_squares_recovers_generating_parameters(
            theta in proptest::array::uniform6(-2.0f64..2.0),
            seed in 0u64..1000,
            w in proptest::array::uniform9(0.1f64..10.0),
        ) {
            // Noise-free residuals: r = X theta.
            let mut rows = random_rows(seed, 60);
            for (r, x) in rows.r.iter_mut().zip(&rows.x) {
                *r = x.iter().zip(&theta).map(|(a, b)| a * b).sum();
            }
            let cols: Vec<usize> = (0..NCOL).collect();
            let (est, rss, _) = wls(&rows.x, &rows.r, &rows.channel, &w, &cols).unwrap();
            for (e, t) in est.iter().zip(&theta) {
                prop_assert!((e - t).abs() < 1e-9, "{e} vs {t}");
            }
            prop_assert!(rss < 1e-15);
        }
    }
}
