//! Nominal closed loops (spec/pmpc.md §8.4). The plant is integrated independently of the
//! controller's Galerkin prediction: the applied input ũ(t) = U τ(t) is the output of
//! τ̇ = Mτ, so (x, τ) evolves by the exponential of [[A, BU], [0, M]] (rigid_body::lti::expm).

use crate::baseline::DiscreteMpc;
use crate::controller::{Pmpc, Source, StepInfo};
use crate::error::Result;
use nalgebra::{DMatrix, DVector};
use rigid_body::lti;

/// Record of a closed-loop run.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedLoop {
    /// Sample times (s), k·T_d for k = 0..=steps.
    pub t: Vec<f64>,
    /// States at the samples.
    pub x: Vec<Vec<f64>>,
    /// Inputs applied at the samples (u(kT_d)).
    pub u: Vec<Vec<f64>>,
    /// J_cl = Σ_{k=1}^{steps} ½(x_kᵀQx_k + u_kᵀRu_k) T_d  (spec (4.102)).
    pub cost: f64,
    /// Largest excess over any constraint limit on a fine grid inside every sampling
    /// interval (≤ 0 means satisfied), for the continuous plant.
    pub max_violation: f64,
    /// Per-step diagnostics (parametrized controller only).
    pub steps: Vec<StepInfo>,
    /// Steps where the controller fell back to its shifted previous plan.
    pub fallbacks: usize,
}

fn stage_cost(q: &DMatrix<f64>, r: &DMatrix<f64>, x: &[f64], u: &[f64]) -> f64 {
    let xv = DVector::from_column_slice(x);
    let uv = DVector::from_column_slice(u);
    0.5 * (xv.dot(&(q * &xv)) + uv.dot(&(r * &uv)))
}

/// Run the parametrized controller for `steps` samples from `x0`; the constraints are
/// checked at `grid` points per sampling interval.
pub fn run_pmpc(ctrl: &mut Pmpc, x0: &[f64], steps: usize, grid: usize) -> Result<ClosedLoop> {
    let problem = ctrl.problem().clone();
    let (a, b, q, r, cons) = problem.system();
    let (n, m) = (problem.n(), problem.m());
    let basis = *problem.basis();
    let s = basis.dim();
    let td = ctrl.sampling_time();
    let mut mbuf = vec![0.0; s * s];
    basis.m_matrix(&mut mbuf)?;
    let mmat = DMatrix::from_row_slice(s, s, &mbuf);
    let mut tau0 = vec![0.0; s];
    basis.tau(0.0, &mut tau0);
    let grid = grid.max(1);

    let mut out = ClosedLoop {
        t: Vec::with_capacity(steps + 1),
        x: Vec::with_capacity(steps + 1),
        u: Vec::with_capacity(steps + 1),
        cost: 0.0,
        max_violation: f64::NEG_INFINITY,
        steps: Vec::with_capacity(steps + 1),
        fallbacks: 0,
    };
    let mut x = x0.to_vec();
    ctrl.reset();
    for k in 0..=steps {
        let u = ctrl.step(&x)?.to_vec();
        let info = ctrl.last_step();
        if matches!(info.source, Source::Fallback(_)) {
            out.fallbacks += 1;
        }
        if k >= 1 {
            out.cost += stage_cost(q, r, &x, &u) * td;
        }
        out.t.push(k as f64 * td);
        out.x.push(x.clone());
        out.u.push(u);
        out.steps.push(info);
        if k == steps {
            break;
        }
        // Augmented plant over one interval, sub-sampled for the constraint check.
        let z = ctrl.plan();
        let umat = DMatrix::from_fn(m, s, |i, j| z[n * s + i * s + j]);
        let mut aug = DMatrix::zeros(n + s, n + s);
        aug.view_mut((0, 0), (n, n)).copy_from(a);
        aug.view_mut((0, n), (n, s)).copy_from(&(b * &umat));
        aug.view_mut((n, n), (s, s)).copy_from(&mmat);
        let sub = lti::expm(&(aug * (td / grid as f64)))?;
        let mut xi = DVector::zeros(n + s);
        xi.rows_mut(0, n).copy_from_slice(&x);
        xi.rows_mut(n, s).copy_from_slice(&tau0);
        for _ in 0..grid {
            xi = &sub * xi;
            let xs = xi.rows(0, n).into_owned();
            let us = &umat * xi.rows(n, s);
            let g = &cons.cx * &xs + &cons.cu * &us;
            for (kk, gk) in g.iter().enumerate() {
                let excess = (gk - cons.upper[kk]).max(cons.lower[kk] - gk);
                out.max_violation = out.max_violation.max(excess);
            }
        }
        x = xi.rows(0, n).iter().copied().collect();
    }
    Ok(out)
}

/// Run a discrete-time MPC on the exact ZOH plant x_{k+1} = A_d x_k + B_d u_k; the constraints
/// are checked at the samples only (that is all the discrete formulation imposes).
pub fn run_discrete(ctrl: &mut DiscreteMpc, x0: &[f64], steps: usize) -> Result<ClosedLoop> {
    let (ad, bd) = ctrl.discretization();
    let (ad, bd) = (ad.clone(), bd.clone());
    let (q, r, cons) = ctrl.weights_and_constraints();
    let (q, r, cons) = (q.clone(), r.clone(), cons.clone());
    let td = ctrl.sampling_time();
    let mut out = ClosedLoop {
        t: Vec::with_capacity(steps + 1),
        x: Vec::with_capacity(steps + 1),
        u: Vec::with_capacity(steps + 1),
        cost: 0.0,
        max_violation: f64::NEG_INFINITY,
        steps: Vec::new(),
        fallbacks: 0,
    };
    let mut x = DVector::from_column_slice(x0);
    ctrl.reset();
    for k in 0..=steps {
        let step = ctrl.step(x.as_slice())?;
        if step.fallback {
            out.fallbacks += 1;
        }
        let u = step.u.clone();
        if k >= 1 {
            out.cost += stage_cost(&q, &r, x.as_slice(), &u) * td;
        }
        let uv = DVector::from_column_slice(&u);
        let g = &cons.cx * &x + &cons.cu * &uv;
        for (kk, gk) in g.iter().enumerate() {
            let excess = (gk - cons.upper[kk]).max(cons.lower[kk] - gk);
            out.max_violation = out.max_violation.max(excess);
        }
        out.t.push(k as f64 * td);
        out.x.push(x.iter().copied().collect());
        out.u.push(u);
        if k == steps {
            break;
        }
        x = &ad * &x + &bd * uv;
    }
    Ok(out)
}
