//! Cubli model discovery by time-domain prediction error.
//!
//! The Cubli logs the full state (housing rates, wheel speeds, gravity direction), so the
//! nominal model (documented parameters of [`cubli::Params::reference`]) predicts, over a short
//! window of `window` samples, the change of the wheel momenta p_w = Θw (ω_h + ω_w), of the
//! housing momentum p_h = Θ0 ω_h + p_w and of the gravity direction ĝ:
//!
//! * Δp_w = ∫ k T − c_v ω_w − c_c tanh(ω_w / ε) dt (the commanded torque is held over a sample,
//!   so ∫T dt is exact);
//! * Δp_h = ∫ −ω_h × p_h + m × g dt (wheel torques are internal and do not appear);
//! * Δĝ = −∫ ω_h × ĝ dt, with ω_h the measured rate minus the gyro bias.
//!
//! The residual of the nominal prediction is linear in every candidate parameter (to first
//! order in the bias), so each candidate is a set of regressor columns and each fit is a
//! weighted linear least-squares problem. Integrating over a window instead of differentiating
//! one sample keeps the endpoint noise fixed while the effects accumulate; disjoint windows
//! keep the residuals of different windows independent. Sensor noise enters the regressors
//! only through window integrals of many samples, which averages it out; the residual variance
//! of each channel is estimated from the data (the fit with every candidate), not assumed.
//!
//! Significance follows the flying-platform loop ([`super::discover`]): F test of the nested
//! models at the Bonferroni-corrected level and a lower BIC, best candidate first, repeat.
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
use std::path::PathBuf;

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use serde::Serialize;
use serde_json::{json, Value};

use super::dataset::Dataset;
use super::diagnose::LEVEL;
use super::load;
use super::stats::f_sf;
use crate::error::{Result, SimError};

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
/// Speed ε (rad/s) of the Coulomb smoothing tanh(ω/ε), as in [`cubli::WheelEffects`].
pub const COULOMB_SMOOTHING: f64 = 0.1;
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

/// Regressor columns: viscous c, Coulomb c, two bias components, torque constant − 1.
const NCOL: usize = 5;

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
    /// Orthonormal basis of the identifiable bias plane (body axes).
    bias_basis: [Vector3<f64>; 2],
}

fn smooth_sign(w: f64) -> f64 {
    (w / COULOMB_SMOOTHING).tanh()
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
    let mut rows = Rows {
        r: Vec::new(),
        x: Vec::new(),
        probes: Vec::new(),
        channel: Vec::new(),
        bias_basis: basis,
    };
    for e in &data.experiments {
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
            let mut int_sign = Vector3::zeros();
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
                int_sign += wwk.map(smooth_sign) * c;
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
            for i in 0..3 {
                // Wheel i: residual = (k − 1) ∫T − c_v ∫ω_w − c_c ∫tanh.
                rows.r.push(dpw[i] - int_t[i]);
                rows.x.push([-int_ww[i], -int_sign[i], 0.0, 0.0, int_t[i]]);
                rows.channel.push(i);
                rows.probes.push(probe.clone());
            }
            for i in 0..3 {
                rows.r.push(dph[i] - int_ph[i]);
                rows.x
                    .push([0.0, 0.0, int_bias_h[0][i], int_bias_h[1][i], 0.0]);
                rows.channel.push(3 + i);
                rows.probes.push(probe.clone());
            }
            for i in 0..3 {
                rows.r.push(dg[i] - int_g[i]);
                rows.x
                    .push([0.0, 0.0, int_bias_g[0][i], int_bias_g[1][i], 0.0]);
                rows.channel.push(6 + i);
                rows.probes.push(probe.clone());
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

/// Weighted least squares on the columns `cols`; returns (θ over cols, weighted RSS, covariance).
fn wls(rows: &Rows, weight: &[f64; 9], cols: &[usize]) -> Result<(Vec<f64>, f64, DMatrix<f64>)> {
    let p = cols.len();
    if p == 0 {
        let rss = rows
            .r
            .iter()
            .zip(&rows.channel)
            .map(|(r, c)| weight[*c] * r * r)
            .sum();
        return Ok((Vec::new(), rss, DMatrix::zeros(0, 0)));
    }
    let mut a = DMatrix::<f64>::zeros(p, p);
    let mut b = DVector::<f64>::zeros(p);
    for ((x, r), c) in rows.x.iter().zip(&rows.r).zip(&rows.channel) {
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
    let rss = rows
        .x
        .iter()
        .zip(&rows.r)
        .zip(&rows.channel)
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

fn residuals(rows: &Rows, cols: &[usize], theta: &[f64]) -> Vec<f64> {
    rows.x
        .iter()
        .zip(&rows.r)
        .map(|(x, r)| r - cols.iter().zip(theta).map(|(&c, t)| t * x[c]).sum::<f64>())
        .collect()
}

/// One estimated parameter.
#[derive(Debug, Clone, Serialize)]
pub struct CubliParam {
    /// Name (`wheel_viscous_friction`, `gyro_bias_x`, ...).
    pub name: String,
    /// Estimate.
    pub value: f64,
    /// Standard error.
    pub std: f64,
}

/// Score of one candidate on one step.
#[derive(Debug, Clone, Serialize)]
pub struct CubliCandidate {
    /// Effect name.
    pub effect: String,
    /// Weighted cost with the effect added.
    pub cost: f64,
    /// Cost reduction relative to the step's model, %.
    pub reduction_percent: f64,
    /// Parameters added.
    pub added_parameters: usize,
    /// F statistic of the nested test.
    pub f_statistic: f64,
    /// Its p-value.
    pub p_value: f64,
    /// Change of BIC (cost in units of the noise variance + p ln n).
    pub delta_bic: f64,
    /// F test at the Bonferroni level and lower BIC.
    pub significant: bool,
}

/// One step of the Cubli discovery.
#[derive(Debug, Clone, Serialize)]
pub struct CubliStep {
    /// Effect added (`None` for the nominal model).
    pub added: Option<String>,
    /// Effects in the model.
    pub effects: Vec<String>,
    /// Weighted cost (sum of squared residuals over noise variance).
    pub cost: f64,
    /// Reduction relative to the nominal model, %.
    pub reduction_percent: f64,
    /// RMS residual over estimated noise standard deviation, per channel.
    pub channel_rms_over_noise: Vec<f64>,
    /// Parameters with standard errors.
    pub params: Vec<CubliParam>,
    /// Candidates tried on this step.
    pub candidates: Vec<CubliCandidate>,
}

/// Result of [`discover`].
#[derive(Debug, Clone, Serialize)]
pub struct CubliDiscovery {
    /// Steps from the nominal model.
    pub steps: Vec<CubliStep>,
    /// Effects in the order added.
    pub found: Vec<String>,
    /// True when a structured misfit remains.
    pub unexplained: bool,
    /// Channels carrying it.
    pub misfit_channels: Vec<String>,
    /// Per-channel p-value of the final residual against the generic probes.
    pub channel_p_values: Vec<f64>,
    /// Estimated residual noise standard deviation per channel.
    pub noise_std: Vec<f64>,
    /// Windows used and window length (samples).
    pub windows: usize,
    /// Window length in samples.
    pub window_samples: usize,
    /// Significance level.
    pub level: f64,
}

impl CubliDiscovery {
    /// A sentence for the verdict.
    pub fn verdict(&self) -> String {
        if self.unexplained {
            format!(
                "structured misfit remains in channels [{}]; no candidate effect explains it",
                self.misfit_channels.join(", ")
            )
        } else {
            "explained to the noise level".to_string()
        }
    }

    /// The workbench JSON (`steps`, `found`, `unexplained`, plus details).
    pub fn json(&self) -> Value {
        let steps: Vec<Value> = self
            .steps
            .iter()
            .map(|s| {
                let params: serde_json::Map<String, Value> = s
                    .params
                    .iter()
                    .map(|p| (p.name.clone(), json!(p.value)))
                    .collect();
                let std: serde_json::Map<String, Value> = s
                    .params
                    .iter()
                    .map(|p| (p.name.clone(), json!(p.std)))
                    .collect();
                json!({
                    "added": s.added,
                    "effects": s.effects,
                    "cost": s.cost,
                    "reduction_percent": s.reduction_percent,
                    "params": params,
                    "std": std,
                    "channel_rms_over_noise": s.channel_rms_over_noise,
                    "candidates": s.candidates,
                })
            })
            .collect();
        let held: serde_json::Map<String, Value> = HELD
            .iter()
            .map(|(k, v)| (k.to_string(), json!(v)))
            .collect();
        json!({
            "system": "cubli",
            "method": format!("time-domain prediction error over {}-sample windows", self.window_samples),
            "steps": steps,
            "found": self.found,
            "unexplained": self.unexplained,
            "verdict": self.verdict(),
            "misfit_channels": self.misfit_channels,
            "channels": CHANNELS,
            "channel_p_values": self.channel_p_values,
            "noise_std": self.noise_std,
            "windows": self.windows,
            "held": held,
            "level": self.level,
        })
    }

    /// The terminal summary table.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Cubli: {} windows of {} samples, prediction error on {}",
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
                st.added.as_deref().unwrap_or("(nominal)"),
                st.cost,
                st.reduction_percent,
                ch.join(" ")
            );
        }
        if let Some(last) = self.steps.last() {
            for p in &last.params {
                let _ = writeln!(s, "  {} = {:.4e} ± {:.1e}", p.name, p.value, p.std);
            }
        }
        for (k, v) in HELD {
            let _ = writeln!(s, "  held: {k} ({v})");
        }
        let _ = writeln!(s, "found: [{}]", self.found.join(", "));
        let _ = writeln!(s, "verdict: {}", self.verdict());
        s
    }
}

fn params_of(
    rows: &Rows,
    effects: &[String],
    cols: &[usize],
    theta: &[f64],
    cov: &DMatrix<f64>,
) -> Vec<CubliParam> {
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
                        out.push(CubliParam {
                            name: format!("gyro_bias_{name}"),
                            value: v[a],
                            std: var.max(0.0).sqrt(),
                        });
                    }
                }
            }
            name => {
                if let Some(i) = columns_of(name).first().and_then(|&c| at(c)) {
                    let offset = if name == "torque_constant" { 1.0 } else { 0.0 };
                    out.push(CubliParam {
                        name: name.to_string(),
                        value: theta[i] + offset,
                        std: cov[(i, i)].max(0.0).sqrt(),
                    });
                }
            }
        }
    }
    out
}

fn cols_for(effects: &[String]) -> Vec<usize> {
    let mut c: Vec<usize> = effects
        .iter()
        .flat_map(|e| columns_of(e).iter().copied())
        .collect();
    c.sort_unstable();
    c
}

/// p-value per channel of the residual against the generic probes (F test).
fn probe_p_values(rows: &Rows, resid: &[f64]) -> Vec<f64> {
    (0..9)
        .map(|ch| {
            let idx: Vec<usize> = (0..resid.len())
                .filter(|&i| rows.channel[i] == ch)
                .collect();
            let q = rows.probes[idx[0]].len();
            let n = idx.len();
            let x = DMatrix::from_fn(n, q, |r, c| rows.probes[idx[r]][c]);
            let y = DVector::from_iterator(n, idx.iter().map(|&i| resid[i]));
            // Scale columns, then solve by SVD (probes may be nearly collinear).
            let scale: Vec<f64> = (0..q).map(|c| x.column(c).norm().max(1e-300)).collect();
            let xs = DMatrix::from_fn(n, q, |r, c| x[(r, c)] / scale[c]);
            let svd = xs.clone().svd(true, true);
            let rank = svd.rank(1e-9 * svd.singular_values.max());
            let Ok(beta) = svd.solve(&y, 1e-9 * svd.singular_values.max()) else {
                return 1.0;
            };
            let fitted = &xs * beta;
            let rss1 = (&y - &fitted).norm_squared();
            let ss = fitted.norm_squared();
            if rss1 <= 0.0 || n <= rank + 1 {
                return 1.0;
            }
            let f = (ss / rank as f64) / (rss1 / (n - rank) as f64);
            f_sf(f, rank as f64, (n - rank) as f64)
        })
        .collect()
}

/// Loads Cubli logs (MCAP or CSV, or directories of them).
pub fn load_cubli(paths: &[PathBuf]) -> Result<Dataset> {
    let inputs: Vec<String> = INPUTS.iter().map(|s| s.to_string()).collect();
    let outputs: Vec<String> = OUTPUTS.iter().map(|s| s.to_string()).collect();
    load::load("cubli", &inputs, &outputs, paths)
}

/// Runs the discovery loop on Cubli data.
pub fn discover(data: &Dataset, opts: &CubliOptions) -> Result<CubliDiscovery> {
    data.validate()?;
    let want: Vec<String> = OUTPUTS.iter().map(|s| s.to_string()).collect();
    let want_in: Vec<String> = INPUTS.iter().map(|s| s.to_string()).collect();
    if data.outputs != want || data.inputs != want_in {
        return Err(SimError::invalid(
            "channels",
            format!("{} / {}", data.inputs.join(","), data.outputs.join(",")),
            format!(
                "the Cubli model needs inputs {} and outputs {}",
                INPUTS.join(","),
                OUTPUTS.join(",")
            ),
        ));
    }
    let rows = build_rows(data, opts)?;
    // Noise variance per channel from the fit with every candidate (consistent whichever of
    // them are present).
    let all: Vec<usize> = (0..NCOL).collect();
    let (theta_all, _, _) = wls(&rows, &[1.0; 9], &all)?;
    let res_all = residuals(&rows, &all, &theta_all);
    let mut var = [0.0; 9];
    let mut count = [0usize; 9];
    for (e, c) in res_all.iter().zip(&rows.channel) {
        var[*c] += e * e;
        count[*c] += 1;
    }
    for c in 0..9 {
        // Five parameters spread over nine channels: one degree of freedom per channel is
        // a conservative correction.
        var[c] = (var[c] / (count[c] as f64 - 1.0).max(1.0)).max(1e-300);
    }
    let weight: [f64; 9] = std::array::from_fn(|c| 1.0 / var[c]);
    let n = rows.r.len() as f64;
    let channel_rms = |resid: &[f64]| -> Vec<f64> {
        (0..9)
            .map(|c| {
                let (s, k) = resid
                    .iter()
                    .zip(&rows.channel)
                    .filter(|(_, ch)| **ch == c)
                    .fold((0.0, 0usize), |(s, k), (e, _)| (s + e * e, k + 1));
                (s / k.max(1) as f64 / var[c]).sqrt()
            })
            .collect()
    };
    let mut effects: Vec<String> = Vec::new();
    let (_, base_cost, _) = wls(&rows, &weight, &[])?;
    let make_step = |effects: &[String], added: Option<String>| -> Result<(CubliStep, f64)> {
        let cols = cols_for(effects);
        let (theta, cost, cov) = wls(&rows, &weight, &cols)?;
        let resid = residuals(&rows, &cols, &theta);
        Ok((
            CubliStep {
                added,
                effects: effects.to_vec(),
                cost,
                reduction_percent: 100.0 * (1.0 - cost / base_cost),
                channel_rms_over_noise: channel_rms(&resid),
                params: params_of(&rows, effects, &cols, &theta, &cov),
                candidates: Vec::new(),
            },
            cost,
        ))
    };
    let (mut current, mut cost) = make_step(&effects, None)?;
    let mut steps = Vec::new();
    let mut found = Vec::new();
    loop {
        let remaining: Vec<&str> = CANDIDATES
            .iter()
            .copied()
            .filter(|c| !effects.iter().any(|e| e == c))
            .collect();
        let p0 = cols_for(&effects).len();
        let mut best: Option<(usize, f64)> = None;
        for name in &remaining {
            let mut with = effects.clone();
            with.push(name.to_string());
            let cols = cols_for(&with);
            let (_, c1, _) = wls(&rows, &weight, &cols)?;
            let q = cols.len() - p0;
            let dv = cost - c1;
            let dof = n - cols.len() as f64;
            let f = if c1 > 0.0 {
                (dv / q as f64) / (c1 / dof)
            } else {
                0.0
            };
            let p_value = f_sf(f, q as f64, dof);
            let delta_bic = -dv + q as f64 * n.ln();
            let significant = p_value < LEVEL / remaining.len() as f64 && delta_bic < 0.0;
            current.candidates.push(CubliCandidate {
                effect: name.to_string(),
                cost: c1,
                reduction_percent: 100.0 * dv / cost,
                added_parameters: q,
                f_statistic: f,
                p_value,
                delta_bic,
                significant,
            });
            let i = current.candidates.len() - 1;
            if best.is_none_or(|(_, b)| c1 < b) {
                best = Some((i, c1));
            }
        }
        match best.filter(|(i, _)| current.candidates[*i].significant) {
            Some((i, _)) => {
                let name = current.candidates[i].effect.clone();
                effects.push(name.clone());
                found.push(name.clone());
                let (next, c) = make_step(&effects, Some(name))?;
                cost = c;
                steps.push(std::mem::replace(&mut current, next));
            }
            None => break,
        }
    }
    let cols = cols_for(&effects);
    let (theta, _, _) = wls(&rows, &weight, &cols)?;
    let resid = residuals(&rows, &cols, &theta);
    let channel_p_values = probe_p_values(&rows, &resid);
    let misfit_channels: Vec<String> = channel_p_values
        .iter()
        .enumerate()
        .filter(|(_, p)| **p < LEVEL / 9.0)
        .map(|(c, _)| CHANNELS[c].to_string())
        .collect();
    steps.push(current);
    Ok(CubliDiscovery {
        steps,
        found,
        unexplained: !misfit_channels.is_empty(),
        misfit_channels,
        channel_p_values,
        noise_std: var.iter().map(|v| v.sqrt()).collect(),
        windows: rows.r.len() / 9,
        window_samples: opts.window,
        level: LEVEL,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    proptest! {
        /// Noise-free rows generated from known parameters are fitted back exactly, whatever
        /// the channel weights.
        #[test]
        fn weighted_least_squares_recovers_generating_parameters(
            theta in proptest::array::uniform5(-2.0f64..2.0),
            seed in 0u64..1000,
            w in proptest::array::uniform9(0.1f64..10.0),
        ) {
            let mut rng = StdRng::seed_from_u64(seed);
            let mut next = || rng.random::<f64>() - 0.5;
            let mut rows = Rows {
                r: Vec::new(),
                x: Vec::new(),
                probes: Vec::new(),
                channel: Vec::new(),
                bias_basis: [Vector3::x(), Vector3::y()],
            };
            for i in 0..60 {
                let x: [f64; NCOL] = std::array::from_fn(|_| next());
                rows.r.push(x.iter().zip(&theta).map(|(a, b)| a * b).sum());
                rows.x.push(x);
                rows.channel.push(i % 9);
                rows.probes.push(vec![1.0]);
            }
            let cols: Vec<usize> = (0..NCOL).collect();
            let (est, rss, _) = wls(&rows, &w, &cols).unwrap();
            for (e, t) in est.iter().zip(&theta) {
                prop_assert!((e - t).abs() < 1e-9, "{e} vs {t}");
            }
            prop_assert!(rss < 1e-15);
        }
    }
}
