//! Weighted least-squares fit of a model's parameters (Levenberg-Marquardt on the whitened
//! residuals, box bounds by projection), parameter standard errors from the Gauss-Newton
//! Hessian, and the identifiability check that holds parameters the data cannot separate at
//! their documented values. One solver for every criterion ([`LeastSquares`]): the FRF here,
//! the time-domain prediction error in [`super::prediction`].
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::cost::{LineCorrelation, WeightedCost};
use super::frf::{model_noise, FrfEstimate, LineMap, ModelFrf};
use super::model::{Model, Parameter};
use crate::cancel::Cancel;
use crate::error::{Result, SimError};

/// Fit settings.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Iteration budget.
    pub max_iterations: usize,
    /// Stop when a step lowers the cost by less than this fraction.
    pub rel_tolerance: f64,
    /// Or by less than this (the cost is in units of noise variance, so 1e-3 is far below
    /// anything a test could resolve).
    pub abs_tolerance: f64,
    /// Smallest singular value of the column-normalised Jacobian below which a parameter
    /// combination counts as invisible to the data.
    pub rank_tolerance: f64,
    /// Sample period of the held inputs (`None`: no zero-order-hold factor).
    pub hold: Option<f64>,
    /// Stop as soon as the cost's Gauss-Newton model says it cannot fall below this even
    /// with twice the predicted decrease (a candidate that cannot become significant).
    pub give_up_above: Option<f64>,
    /// Checked at every iteration: once set, the fit ends with [`SimError::Cancelled`].
    pub cancel: Cancel,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            rel_tolerance: 1e-9,
            abs_tolerance: 1e-3,
            rank_tolerance: 1e-6,
            hold: None,
            give_up_above: None,
            cancel: Cancel::default(),
        }
    }
}

/// One fitted parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamEstimate {
    /// Name.
    pub name: String,
    /// Estimate.
    pub value: f64,
    /// Standard error (absent when held).
    pub std: Option<f64>,
    /// Unit.
    pub unit: String,
    /// Held at its documented value because the data cannot separate it from others.
    pub held: bool,
    /// Ended on a bound.
    pub at_bound: bool,
    /// Standard error larger than the magnitude of the estimate, or known only as a lower
    /// bound (the time criterion's widening reached its cap).
    pub poorly_determined: bool,
}

/// Result of a fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Parameter vector (model order).
    pub theta: Vec<f64>,
    /// Per-parameter report.
    pub params: Vec<ParamEstimate>,
    /// Weighted cost at the estimate.
    pub cost: f64,
    /// Model FRF at the estimate as the cost's lines see it.
    pub model_frf: ModelFrf,
    /// Iterations used.
    pub iterations: usize,
    /// Number of free (estimated) parameters.
    pub free: usize,
    /// Stopped by [`FitOptions::give_up_above`] (the cost is then an upper bound of the
    /// fitted one).
    pub gave_up: bool,
    /// How the noise enters the fit along its free parameters.
    pub information: Information,
}

/// How the noise enters a fit along its free parameters: `J^T J` and `J^T Ω J` at the
/// estimate (columns scaled as the fit scales them, `Ω` the residuals' correlation). Fitted to
/// noise alone, parameters absorb `σ² tr((J^T J)^-1 J^T Ω J)` of the cost: their count when
/// the residuals are independent, more when neighbouring Welch lines correlate, which is what
/// a nested-model test must allow for ([`Self::design_effect`]).
#[derive(Debug, Clone)]
pub struct Information {
    /// The free parameters' names, in model order.
    pub free: Vec<String>,
    /// `J^T J` over them.
    pub gram: DMatrix<f64>,
    /// `J^T Ω J` over them.
    pub correlated: DMatrix<f64>,
}

impl Information {
    /// Residuals' worth of noise the free parameters absorb when fitted to noise alone,
    /// `tr(G^-1 H)`: their count for independent residuals, about the design effect times it
    /// where neighbouring Welch lines correlate. What a fitted cost's expected level is lowered
    /// by ([`crate::noise::NoiseReference::fitted_level`]).
    pub fn absorbed(&self) -> f64 {
        self.free.len() as f64 * self.design_effect(&[])
    }

    /// How many times the noise a fit absorbs along the parameters free here but not among
    /// `base` (another fit's free parameters) exceeds their count: `tr(S^-1 T^T H T) / q`,
    /// with `S = G_nn - G_nb G_bb^-1 G_bn` and `T = [-G_bb^-1 G_bn; I]` the added columns
    /// with the base's projected out (`G = J^T J`, `H = J^T Ω J`, both here). Under noise
    /// alone the cost the added parameters remove is then about `design_effect · σ² χ²_q`,
    /// so the F statistic divided by it has the F distribution again. 1 for independent
    /// residuals, when nothing is added, or when the added columns are not of full rank.
    pub fn design_effect(&self, base: &[String]) -> f64 {
        let (b, n): (Vec<usize>, Vec<usize>) =
            (0..self.free.len()).partition(|&i| base.contains(&self.free[i]));
        if n.is_empty() {
            return 1.0;
        }
        let pick = |m: &DMatrix<f64>, rows: &[usize], cols: &[usize]| {
            DMatrix::from_fn(rows.len(), cols.len(), |r, c| m[(rows[r], cols[c])])
        };
        let g_bb = pick(&self.gram, &b, &b);
        let g_bn = pick(&self.gram, &b, &n);
        // G_bb^-1 G_bn by Cholesky (an empty base projects nothing out).
        let coef = if b.is_empty() {
            Some(DMatrix::zeros(0, n.len()))
        } else {
            g_bb.cholesky().map(|c| c.solve(&g_bn))
        };
        let Some(coef) = coef else {
            return 1.0;
        };
        let mut t = DMatrix::zeros(self.free.len(), n.len());
        for (r, &i) in b.iter().enumerate() {
            t.row_mut(i).copy_from(&(-coef.row(r)));
        }
        for (c, &i) in n.iter().enumerate() {
            t[(i, c)] = 1.0;
        }
        let s = t.transpose() * &self.gram * &t;
        let h = t.transpose() * &self.correlated * &t;
        let d = s.cholesky().map(|c| c.solve(&h).trace() / n.len() as f64);
        match d {
            Some(d) if d.is_finite() && d > 0.0 => d,
            _ => 1.0,
        }
    }
}

impl FitResult {
    /// Names of the parameters held at their documented values.
    pub fn held(&self) -> Vec<String> {
        self.params
            .iter()
            .filter(|p| p.held)
            .map(|p| p.name.clone())
            .collect()
    }
}

/// A weighted least-squares criterion in a model's parameters.
pub trait LeastSquares: Sync {
    /// Whitened residuals at `theta` (their squared norm is the cost).
    fn residuals(&self, theta: &[f64]) -> Result<DVector<f64>>;
    /// The Jacobian of the residuals by every parameter (columns in model order) at `theta`,
    /// where they are `r` (a criterion that differences them starts from these).
    fn jacobian(&self, theta: &[f64], r: &DVector<f64>) -> Result<DMatrix<f64>>;
    /// `J^T Ω J` with `Ω` the correlation of the residuals (unit diagonal), for the
    /// parameters' covariance `σ² (J^T J)^-1 J^T Ω J (J^T J)^-1`: `J^T J` for independent
    /// residuals.
    fn correlated_gram(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        j.transpose() * j
    }
}

/// The FRF criterion: the weighted misfit of the model FRF on the cost's lines.
struct FrfCriterion<'a> {
    model: &'a Model,
    cost: &'a WeightedCost,
    hold: Option<f64>,
}

impl LeastSquares for FrfCriterion<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<DVector<f64>> {
        let g = self.model.frf_seen(theta, &self.cost.map, self.hold)?;
        Ok(self.cost.residuals(&g.lines))
    }

    fn jacobian(&self, theta: &[f64], _r: &DVector<f64>) -> Result<DMatrix<f64>> {
        let map = &self.cost.map;
        let (_, d) = self
            .model
            .frf_with_jacobian(theta, map.grid_hz(), self.hold)?;
        Ok(self.cost.jacobian(&map.seen_derivatives(&d)))
    }

    fn correlated_gram(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        self.cost.correlation.gram(j)
    }
}

/// The FRF criterion weighted at every parameter vector by the noise of that model's own
/// residual, `S(θ)` of `y - G(θ) u` at the bins beside each line ([`model_noise`]): the
/// errors-in-variables maximum likelihood. In closed loop the input carries the fed-back
/// noise, so the residual's noise `S(θ)` is least where `G(θ)` follows the noise's own
/// output-to-input ratio (minus the controller's inverse); a weighting held at the last fit
/// leaves that pull in the numerator, and at lines where the noise rivals the excitation
/// it biases the fit toward it. (A balancing robot under a low-pass torque disturbance fitted
/// its pendulum length 72-88 % long, 5 standard errors, under the held weighting.)
struct NoiseWeightedCriterion<'a> {
    model: &'a Model,
    frf: &'a FrfEstimate,
    map: LineMap,
    hold: Option<f64>,
    /// The lines' correlation (the weights' alone, whatever the noise).
    correlation: LineCorrelation,
}

impl NoiseWeightedCriterion<'_> {
    /// The cost weighted by the noise of the residual of the model FRF `g`.
    fn weighting(&self, g: &ModelFrf) -> Result<WeightedCost> {
        WeightedCost::with_noise(self.frf, &model_noise(self.frf, g)?)
    }
}

impl LeastSquares for NoiseWeightedCriterion<'_> {
    fn residuals(&self, theta: &[f64]) -> Result<DVector<f64>> {
        let g = self.model.frf_seen(theta, &self.map, self.hold)?;
        Ok(self.weighting(&g)?.residuals(&g.lines))
    }

    fn jacobian(&self, theta: &[f64], r0: &DVector<f64>) -> Result<DMatrix<f64>> {
        // By differences: the weighting moves with the parameters, and its share of the
        // gradient is what removes the pull.
        difference_jacobian(self, self.model, theta, r0)
    }

    fn correlated_gram(&self, j: &DMatrix<f64>) -> DMatrix<f64> {
        self.correlation.gram(j)
    }
}

/// The Jacobian of `criterion`'s residuals in the parameters of `model` at `theta`, where
/// they are `r0`, by forward differences (backward at an upper bound), one column per
/// parameter, computed in parallel when the model allows.
pub(crate) fn difference_jacobian(
    criterion: &dyn LeastSquares,
    model: &Model,
    theta: &[f64],
    r0: &DVector<f64>,
) -> Result<DMatrix<f64>> {
    let params = model.parameters()?;
    let jobs: Vec<_> = params
        .iter()
        .enumerate()
        .map(|(i, p)| {
            move || {
                let h0 = 1e-6 * p.scale().max(theta[i].abs());
                let h = if theta[i] + h0 <= p.upper { h0 } else { -h0 };
                let mut t = theta.to_vec();
                t[i] += h;
                Ok((criterion.residuals(&t)? - r0) / h)
            }
        })
        .collect();
    let cols = super::discover::in_parallel(model.parallel(), jobs, "Jacobian by differences")?;
    // A model with every parameter held has no column (nalgebra's `from_columns` panics on
    // none).
    Ok(if cols.is_empty() {
        DMatrix::zeros(r0.len(), 0)
    } else {
        DMatrix::from_columns(&cols)
    })
}

/// Fits all parameters of `model` to the FRF `frf` from `start` (documented values when
/// `None`) under the weighting of each model's own residual ([`NoiseWeightedCriterion`]);
/// with the fit, the weighting at the fitted model, under which its cost is the fit's.
pub fn fit_noise_weighted(
    model: &Model,
    frf: &FrfEstimate,
    start: Option<&[f64]>,
    opts: &FitOptions,
) -> Result<(FitResult, WeightedCost)> {
    let criterion = NoiseWeightedCriterion {
        model,
        frf,
        map: LineMap::new(frf),
        hold: opts.hold,
        correlation: LineCorrelation::new(frf)?,
    };
    let params = model.parameters()?;
    let mut r = solve(&criterion, &params, start, opts)?;
    r.model_frf = model.frf_seen(&r.theta, &criterion.map, opts.hold)?;
    let weighting = criterion.weighting(&r.model_frf)?;
    Ok((r, weighting))
}

/// Fits all parameters of `model` to the FRF from `start` (documented values when `None`).
pub fn fit(
    model: &Model,
    cost: &WeightedCost,
    start: Option<&[f64]>,
    opts: &FitOptions,
) -> Result<FitResult> {
    let criterion = FrfCriterion {
        model,
        cost,
        hold: opts.hold,
    };
    let params = model.parameters()?;
    let mut r = solve(&criterion, &params, start, opts)?;
    r.model_frf = model.frf_seen(&r.theta, &cost.map, opts.hold)?;
    Ok(r)
}

/// Minimises `criterion` over `params` from `start` (documented values when `None`); the
/// result's `model_frf` is left empty for the caller.
pub fn solve(
    criterion: &dyn LeastSquares,
    params: &[Parameter],
    start: Option<&[f64]>,
    opts: &FitOptions,
) -> Result<FitResult> {
    let mut theta: Vec<f64> = match start {
        Some(s) if s.len() == params.len() => s.to_vec(),
        Some(s) => {
            return Err(SimError::LengthMismatch {
                what: "start parameter vector".into(),
                expected: params.len(),
                found: s.len(),
            })
        }
        None => params.iter().map(|p| p.value).collect(),
    };
    clamp(&mut theta, params);
    let mut held = vec![false; params.len()];
    let mut iterations = 0;
    let mut r = criterion.residuals(&theta)?;
    loop {
        opts.cancel.check()?;
        let (used, d, gave_up) =
            levenberg_marquardt(criterion, params, &held, &mut theta, &mut r, opts)?;
        iterations += used;
        let j = scaled_free_jacobian(&d, params, &held);
        let weak = if gave_up {
            None
        } else {
            weakest(&j, opts.rank_tolerance)
        };
        match weak {
            Some(col) => {
                let idx = free_indices(&held)[col];
                held[idx] = true;
                theta[idx] = params[idx].value;
                r = criterion.residuals(&theta)?;
            }
            None => {
                let v = r.norm_squared();
                let information = Information {
                    free: free_indices(&held)
                        .into_iter()
                        .map(|i| params[i].name.clone())
                        .collect(),
                    gram: j.transpose() * &j,
                    correlated: criterion.correlated_gram(&j),
                };
                let estimates = report(params, &held, &theta, &information, v, r.len());
                // A fit that gave up has not held its unseen combinations; they are not
                // free parameters of its cost either.
                let unseen = if gave_up {
                    holds(&j, opts.rank_tolerance).len()
                } else {
                    0
                };
                let free = held.iter().filter(|h| !**h).count() - unseen;
                return Ok(FitResult {
                    theta,
                    params: estimates,
                    cost: v,
                    model_frf: ModelFrf::default(),
                    iterations,
                    free,
                    gave_up,
                    information,
                });
            }
        }
    }
}

fn clamp(theta: &mut [f64], params: &[Parameter]) {
    for (t, p) in theta.iter_mut().zip(params) {
        *t = t.clamp(p.lower, p.upper);
    }
}

fn free_indices(held: &[bool]) -> Vec<usize> {
    held.iter()
        .enumerate()
        .filter(|(_, h)| !**h)
        .map(|(i, _)| i)
        .collect()
}

fn scaled_free_jacobian(full: &DMatrix<f64>, params: &[Parameter], held: &[bool]) -> DMatrix<f64> {
    let free = free_indices(held);
    DMatrix::from_fn(full.nrows(), free.len(), |r, c| {
        full[(r, free[c])] * params[free[c]].scale()
    })
}

/// A parameter the data cannot separate from the others, if any: the columns of the
/// Jacobian are normalised to unit length (so that only their directions count, not the
/// parameters' units or a dominant effect elsewhere) and a singular value below `tol` marks a
/// combination the cost does not see. Holding any parameter that weighs in it removes it, the
/// better conditioned the more it weighs; of those weighing at least a quarter of the most, the
/// last in model order is returned: effects' parameters follow the base model's, so a
/// candidate that only re-labels what the model has (an actuator gain against the masses and
/// the stiffness, weighing 0.26 against 0.67) is held, not a base parameter fitted before it. A column of zeros (a parameter
/// without any influence) is returned first.
fn weakest(j: &DMatrix<f64>, tol: f64) -> Option<usize> {
    // A derivative that is not finite says nothing of a direction (and would stop the SVD):
    // that parameter is held first, as one without influence.
    if let Some(i) = (0..j.ncols()).find(|&i| j.column(i).iter().any(|v| !v.is_finite())) {
        return Some(i);
    }
    if j.ncols() == 0 {
        return None;
    }
    let norms: Vec<f64> = j.column_iter().map(|c| c.norm()).collect();
    let max_norm = norms.iter().cloned().fold(0.0, f64::max);
    if let Some(i) = norms
        .iter()
        .position(|&n| n.partial_cmp(&(1e-14 * max_norm)) != Some(std::cmp::Ordering::Greater))
    {
        return Some(i);
    }
    let mut jn = j.clone();
    for (mut c, n) in jn.column_iter_mut().zip(&norms) {
        c /= *n;
    }
    let svd = jn.svd(false, true);
    let v_t = svd.v_t?;
    let s = &svd.singular_values;
    let (imin, smin) =
        s.iter().enumerate().fold(
            (0, f64::INFINITY),
            |acc, (i, v)| if *v < acc.1 { (i, *v) } else { acc },
        );
    if smin > tol {
        return None;
    }
    let direction = v_t.row(imin);
    let most = direction.amax();
    direction.iter().rposition(|v| v.abs() >= 0.25 * most)
}

/// The parameters (column indices of `j`, in the order held) a fit would hold if its scaled
/// Jacobian were `j` throughout: [`weakest`] on the columns still free, again until none is
/// left to hold. The fit itself refits between holds, so on data its Jacobian, and with it the
/// weights of an unseen combination, may differ; the rule is this one.
pub fn holds(j: &DMatrix<f64>, tol: f64) -> Vec<usize> {
    let mut free: Vec<usize> = (0..j.ncols()).collect();
    let mut held = Vec::new();
    while let Some(col) = weakest(&j.select_columns(free.iter()), tol) {
        held.push(free.remove(col));
    }
    held
}

/// The active set: positions in `free` of the parameters that may move. One on a bound whose
/// descent direction (against `grad`) leaves the box stays put.
fn moving(free: &[usize], params: &[Parameter], theta: &[f64], grad: &DVector<f64>) -> Vec<usize> {
    (0..free.len())
        .filter(|&k| {
            let (t, p) = (theta[free[k]], &params[free[k]]);
            !((t <= p.lower && grad[k] > 0.0) || (t >= p.upper && grad[k] < 0.0))
        })
        .collect()
}

/// Err when the fit stopped at a wall of the model's domain, not at a minimum: the
/// Gauss-Newton step over the parameters free to move would lower the cost by more than one
/// noise unit (the costs are sums of whitened residuals), yet a thousandth of it cannot be
/// evaluated. A model function that gives NaN or raises just beside the point (a branch on a
/// parameter, the square root of a difference) made every step fail or shrink towards the
/// wall, and the fit ended there with standard errors as if converged.
fn not_at_a_wall(
    criterion: &dyn LeastSquares,
    params: &[Parameter],
    held: &[bool],
    theta: &[f64],
    r: &DVector<f64>,
    d: &DMatrix<f64>,
) -> Result<()> {
    let free = free_indices(held);
    let j = scaled_free_jacobian(d, params, held);
    let grad = j.transpose() * r;
    let moving = moving(&free, params, theta, &grad);
    if moving.is_empty() {
        return Ok(());
    }
    let jtj = j.transpose() * &j;
    let mut a = DMatrix::from_fn(moving.len(), moving.len(), |x, y| {
        jtj[(moving[x], moving[y])]
    });
    let dmax = a.diagonal().max().max(1e-300);
    for i in 0..a.nrows() {
        a[(i, i)] += 1e-9 * dmax;
    }
    let grad_m = DVector::from_fn(moving.len(), |x, _| grad[moving[x]]);
    let Some(chol) = a.cholesky() else {
        return Ok(());
    };
    let step = -chol.solve(&grad_m);
    let predicted = -step.dot(&grad_m);
    if predicted.is_nan() || predicted <= 1.0_f64.max(1e-6 * r.norm_squared()) {
        return Ok(());
    }
    let mut trial = theta.to_vec();
    for (x, &k) in moving.iter().enumerate() {
        trial[free[k]] += 1e-3 * step[x] * params[free[k]].scale();
    }
    clamp(&mut trial, params);
    let why = match criterion.residuals(&trial) {
        Ok(rt) if rt.norm_squared().is_finite() => return Ok(()),
        Ok(_) => "the residuals are not finite there".to_string(),
        Err(e) => e.to_string(),
    };
    let at: Vec<String> = moving
        .iter()
        .map(|&k| free[k])
        .map(|i| {
            format!(
                "{} = {:.6e} (a step to {:.6e})",
                params[i].name, theta[i], trial[i]
            )
        })
        .collect();
    Err(SimError::invalid(
        "fit",
        at.join(", "),
        format!(
            "the fit stopped where the model cannot be evaluated a small step further ({why}), while the cost would still fall by about {predicted:.1} noise units: it stopped at a wall of the model's domain, not at a minimum"
        ),
    ))
}

/// Levenberg-Marquardt from `theta` (residuals `r` there) over the free parameters. Leaves
/// `theta` and `r` at the end point and returns the iterations, the Jacobian there and
/// whether it gave up ([`FitOptions::give_up_above`]).
fn levenberg_marquardt(
    criterion: &dyn LeastSquares,
    params: &[Parameter],
    held: &[bool],
    theta: &mut [f64],
    r: &mut DVector<f64>,
    opts: &FitOptions,
) -> Result<(usize, DMatrix<f64>, bool)> {
    let free = free_indices(held);
    let mut d = criterion.jacobian(theta, r)?;
    if free.is_empty() {
        return Ok((0, d, false));
    }
    let scale: Vec<f64> = free.iter().map(|&i| params[i].scale()).collect();
    let mut v = r.norm_squared();
    let mut j = scaled_free_jacobian(&d, params, held);
    let mut lambda = 1e-3;
    let mut growth = 2.0;
    for it in 0..opts.max_iterations {
        opts.cancel.check()?;
        let jtj = j.transpose() * &j;
        let grad = j.transpose() * &*r;
        let moving = moving(&free, params, theta, &grad);
        if moving.is_empty() {
            return Ok((it, d, false));
        }
        let jtj_m = DMatrix::from_fn(moving.len(), moving.len(), |a, b| {
            jtj[(moving[a], moving[b])]
        });
        let grad_m = DVector::from_fn(moving.len(), |a, _| grad[moving[a]]);
        if let Some(target) = opts.give_up_above {
            // The linear model's smallest cost is v - g' (J'J)^-1 g.
            let reachable = jtj_m
                .clone()
                .cholesky()
                .map(|c| v - 2.0 * grad_m.dot(&c.solve(&grad_m)));
            if reachable.is_some_and(|low| low > target) {
                return Ok((it, d, true));
            }
        }
        let dmax = jtj_m.diagonal().max();
        let mut accepted = None;
        for _ in 0..30 {
            // Each trial evaluates the criterion: a run of rejected steps is as long as
            // iterations.
            opts.cancel.check()?;
            let mut a = jtj_m.clone();
            for i in 0..a.nrows() {
                a[(i, i)] += lambda * jtj_m[(i, i)].max(1e-12 * dmax.max(1e-300));
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let step_m: DVector<f64> = -chol.solve(&grad_m);
            let mut trial = theta.to_vec();
            for (a, &k) in moving.iter().enumerate() {
                trial[free[k]] += step_m[a] * scale[k];
            }
            clamp(&mut trial, params);
            // A trial the criterion cannot evaluate (a predictor that diverges there) is a
            // failed step, like a rise in cost.
            if let Some(rt) = criterion.residuals(&trial).ok().filter(|rt| {
                let vt = rt.norm_squared();
                vt.is_finite() && vt < v
            }) {
                // Nielsen's update: the damping falls by up to 3 when the linear model
                // predicted the decrease well (gain ratio near 1), and stays when it did
                // not, so that the next step is not one that fails.
                let predicted = -(2.0 * step_m.dot(&grad_m) + step_m.dot(&(&jtj_m * &step_m)));
                let ratio = (v - rt.norm_squared()) / predicted.max(f64::MIN_POSITIVE);
                lambda = (lambda * (1.0 - (2.0 * ratio - 1.0).powi(3)).max(1.0 / 3.0)).max(1e-12);
                growth = 2.0;
                accepted = Some((trial, rt));
                break;
            }
            lambda *= growth;
            growth *= 2.0;
        }
        let Some((trial, rt)) = accepted else {
            not_at_a_wall(criterion, params, held, theta, r, &d)?;
            return Ok((it, d, false));
        };
        let vt = rt.norm_squared();
        let decrease = v - vt;
        theta.copy_from_slice(&trial);
        *r = rt;
        v = vt;
        d = criterion.jacobian(theta, r)?;
        if decrease <= opts.rel_tolerance * vt || decrease <= opts.abs_tolerance {
            not_at_a_wall(criterion, params, held, theta, r, &d)?;
            return Ok((it + 1, d, false));
        }
        j = scaled_free_jacobian(&d, params, held);
    }
    Ok((opts.max_iterations, d, false))
}

fn report(
    params: &[Parameter],
    held: &[bool],
    theta: &[f64],
    information: &Information,
    v: f64,
    n: usize,
) -> Vec<ParamEstimate> {
    let free = free_indices(held);
    let sigma2 = v / (n.saturating_sub(free.len()).max(1)) as f64;
    let cov = information
        .gram
        .clone()
        .try_inverse()
        .map(|inv| &inv * &information.correlated * &inv);
    params
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let std = free.iter().position(|&f| f == i).and_then(|k| {
                cov.as_ref()
                    .map(|c| (c[(k, k)].max(0.0) * sigma2).sqrt() * p.scale())
            });
            let at_bound = !held[i] && (theta[i] <= p.lower || theta[i] >= p.upper);
            ParamEstimate {
                name: p.name.clone(),
                value: theta[i],
                std,
                unit: p.unit.clone(),
                held: held[i],
                at_bound,
                poorly_determined: std.is_some_and(|s| s > theta[i].abs()),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Columns of a base model `c1 = e1`, `c2 = e1 + h e2`, `c3 = e3` and an effect's
    /// `d = c2 - c1` (it re-labels what the base has).
    fn relabelled(h: f64) -> DMatrix<f64> {
        DMatrix::from_column_slice(
            4,
            4,
            &[
                1.0, 0.0, 0.0, 0.0, // c1
                1.0, h, 0.0, 0.0, // c2
                0.0, 0.0, 1.0, 0.0, // c3
                0.0, h, 0.0, 0.0, // d
            ],
        )
    }

    /// The effect's parameter is held when it weighs in the unseen combination at least a
    /// quarter of the most (0.4 against 1.1 after normalising: the hold is well conditioned),
    /// a base parameter when it weighs too little for its hold to fix the combination well.
    #[test]
    fn the_newest_parameter_that_weighs_in_the_unseen_combination_is_held() {
        assert_eq!(weakest(&relabelled(0.4), 1e-8), Some(3));
        assert_eq!(weakest(&relabelled(0.05), 1e-8), Some(1));
        // Independent columns: nothing to hold.
        assert_eq!(weakest(&DMatrix::identity(4, 4), 1e-8), None);
    }

    /// `holds` applies the same rule again on what is left: one parameter per unseen
    /// combination, a column without influence first.
    #[test]
    fn holds_takes_one_parameter_per_unseen_combination() {
        assert_eq!(holds(&relabelled(0.4), 1e-8), [3]);
        assert_eq!(holds(&relabelled(0.05), 1e-8), [1]);
        assert!(holds(&DMatrix::identity(4, 4), 1e-8).is_empty());
        // Two combinations (c1 = c2, c3 = c4) and a column of zeros.
        let j = DMatrix::from_column_slice(
            3,
            5,
            &[
                1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0,
            ],
        );
        // (Which combination comes first is the SVD's choice between two zero values.)
        let held = holds(&j, 1e-8);
        assert_eq!(held[0], 4);
        let mut rest = held[1..].to_vec();
        rest.sort_unstable();
        assert_eq!(rest, [1, 3]);
    }

    /// `r = y - J theta` with a fixed `J`.
    struct Linear {
        j: DMatrix<f64>,
        y: DVector<f64>,
    }

    impl LeastSquares for Linear {
        fn residuals(&self, theta: &[f64]) -> Result<DVector<f64>> {
            Ok(&self.y - &self.j * DVector::from_column_slice(theta))
        }
        fn jacobian(&self, _: &[f64], _: &DVector<f64>) -> Result<DMatrix<f64>> {
            Ok(-&self.j)
        }
    }

    /// A fit that gives up at once counts the parameters the data can see: of three whose
    /// last two columns differ by 1e-7 (below the rank tolerance after normalising), two.
    /// The counted number is what the nested test charges the candidate for.
    #[test]
    fn a_fit_that_gives_up_counts_an_unseen_combination_once() {
        let j = DMatrix::from_column_slice(
            4,
            3,
            &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1e-7, 0.0],
        );
        let criterion = Linear {
            j,
            y: DVector::from_column_slice(&[1.0, 1.0, 0.0, 1.0]),
        };
        let params: Vec<Parameter> = ["a", "b", "c"]
            .iter()
            .map(|n| Parameter::new(*n, 0.0, -10.0, 10.0, ""))
            .collect();
        // The smallest reachable cost is 1 (the residual's fourth entry), from 3 at zero.
        let opts = FitOptions {
            give_up_above: Some(0.5),
            ..FitOptions::default()
        };
        let r = solve(&criterion, &params, None, &opts).unwrap();
        assert!(r.gave_up);
        assert_eq!(r.free, 2);
        // It stops where the cost cannot fall by half the way to 0.5 (an upper bound of 1).
        assert!((1.0..3.0).contains(&r.cost), "{}", r.cost);
        // Without the give-up the fit holds the combination itself and counts the same.
        let r = solve(&criterion, &params, None, &FitOptions::default()).unwrap();
        assert!(!r.gave_up);
        assert_eq!(r.free, 2);
        assert!((r.cost - 1.0).abs() < 1e-9, "{}", r.cost);
        // A cancelled fit returns no result.
        let opts = FitOptions::default();
        opts.cancel.cancel();
        let r = solve(&criterion, &params, None, &opts);
        assert!(matches!(r, Err(SimError::Cancelled)), "{r:?}");
    }

    /// The information of `j` (n x p) under the correlation `omega`, its parameters named
    /// `p0, p1, ...`.
    fn information(j: &DMatrix<f64>, omega: &DMatrix<f64>) -> Information {
        Information {
            free: (0..j.ncols()).map(|i| format!("p{i}")).collect(),
            gram: j.transpose() * j,
            correlated: j.transpose() * omega * j,
        }
    }

    proptest::proptest! {
        /// The design effect is 1 for independent residuals; it is additive, the base's share
        /// plus the added parameters' making up `tr(G^-1 H)` (the noise all of them absorb);
        /// and it does not depend on the parameters' units.
        #[test]
        fn design_effect_is_the_added_share_of_the_absorbed_noise(
            entries in proptest::collection::vec(-1.0f64..1.0, 40),
            rho in 0.0f64..0.45,
            scales in proptest::collection::vec(0.1f64..10.0, 4),
            base in 0usize..4,
        ) {
            let j = DMatrix::from_column_slice(10, 4, &entries)
                + DMatrix::from_fn(10, 4, |r, c| if r == c { 3.0 } else { 0.0 });
            let names: Vec<String> = (0..base).map(|i| format!("p{i}")).collect();
            let plain = information(&j, &DMatrix::identity(10, 10));
            proptest::prop_assert!((plain.design_effect(&names) - 1.0).abs() < 1e-9);
            let omega = DMatrix::from_fn(10, 10, |a, b| match a.abs_diff(b) {
                0 => 1.0,
                1 => rho,
                _ => 0.0,
            });
            let all = information(&j, &omega);
            let absorbed = |i: &Information| {
                i.gram.clone().try_inverse().map_or(f64::NAN, |g| (g * &i.correlated).trace())
            };
            let base_only = information(&j.columns(0, base).into_owned(), &omega);
            let d = all.design_effect(&names);
            let total = absorbed(&base_only) + (4 - base) as f64 * d;
            proptest::prop_assert!((total - absorbed(&all)).abs() < 1e-8 * absorbed(&all), "{total}");
            let scaled = j * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(scales));
            let d_scaled = information(&scaled, &omega).design_effect(&names);
            proptest::prop_assert!((d_scaled - d).abs() < 1e-8 * d, "{d_scaled} against {d}");
        }
    }
}
