//! Independent references for tests and analysis: an exact extremum oracle for functions of
//! the Laguerre span, and the same semi-infinite QP solved by Clarabel with cutting planes
//! from that oracle (spec/pmpc.md §10, item 12).

use crate::error::Result;
use crate::problem::Problem;
use crate::qp;
use clarabel::solver::SupportedConeT;
use nalgebra::{DMatrix, DVector};
use rigid_body::laguerre::Laguerre;

pub use rigid_body::laguerre::extrema;

/// Largest excess of g = τ(t)ᵀw over [lower, upper] on [0, ∞) (≤ 0 if satisfied).
pub fn max_violation(basis: &Laguerre, w: &[f64], lower: f64, upper: f64) -> f64 {
    extrema(basis, w)
        .iter()
        .map(|&(_, g)| (g - upper).max(lower - g))
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Largest constraint excess of the plan z over all rows, on [0, ∞).
pub fn plan_violation(problem: &Problem, z: &[f64]) -> f64 {
    let s = problem.basis().dim();
    let w = problem.constraint_coefficients(z);
    problem
        .rows()
        .iter()
        .enumerate()
        .map(|(k, r)| {
            max_violation(
                problem.basis(),
                &w.as_slice()[k * s..(k + 1) * s],
                r.lower,
                r.upper,
            )
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// Result of the reference solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Coefficients z.
    pub z: Vec<f64>,
    /// Cost ½zᵀHz.
    pub cost: f64,
    /// Number of sampled instants at the end.
    pub instants: usize,
    /// Largest remaining violation (oracle).
    pub violation: f64,
}

/// Solve the upper-bound problem at `x0` with Clarabel, sampling the constraints on a grid and
/// adding every oracle extremum that violates by more than `tol` until none is left.
pub fn solve_clarabel(problem: &Problem, x0: &[f64], tol: f64) -> Result<Reference> {
    let s = problem.basis().dim();
    let nvar = problem.num_variables();
    let aeq = problem.equality_matrix();
    let beq = problem.equality_rhs(x0);
    let cz = problem.stage_matrix();
    let basis = *problem.basis();
    let mut instants: Vec<(usize, f64)> = Vec::new();
    for k in 0..problem.rows().len() {
        for i in 0..=40 {
            instants.push((k, i as f64 * 0.5 / basis.nu()));
        }
    }
    let mut tau = vec![0.0; s];
    for _round in 0..100 {
        // Rows: equalities, then one inequality per finite side of each sampled instant.
        let mut rows: Vec<(DVector<f64>, f64)> = Vec::new();
        for &(k, t) in &instants {
            basis.tau(t, &mut tau);
            let c = cz.rows(k * s, s).transpose() * DVector::from_column_slice(&tau);
            let r = problem.rows()[k];
            if r.upper.is_finite() {
                rows.push((c.clone(), r.upper));
            }
            if r.lower.is_finite() {
                rows.push((-c, -r.lower));
            }
        }
        let p_eq = aeq.nrows();
        let mut a = DMatrix::zeros(p_eq + rows.len(), nvar);
        a.rows_mut(0, p_eq).copy_from(aeq);
        let mut b = beq.as_slice().to_vec();
        for (i, (c, lim)) in rows.iter().enumerate() {
            a.row_mut(p_eq + i).copy_from(&c.transpose());
            b.push(*lim);
        }
        let cones = [
            SupportedConeT::ZeroConeT(p_eq),
            SupportedConeT::NonnegativeConeT(rows.len()),
        ];
        let (z, _) = qp::solve(
            problem.hessian(),
            &vec![0.0; nvar],
            &qp::csc(&a, false),
            &b,
            &cones,
            1e-10,
        )?;
        let w = problem.constraint_coefficients(&z);
        let mut added = 0;
        let mut worst = f64::NEG_INFINITY;
        for (k, r) in problem.rows().iter().enumerate() {
            for (t, g) in extrema(&basis, &w.as_slice()[k * s..(k + 1) * s]) {
                let excess = (g - r.upper).max(r.lower - g);
                worst = worst.max(excess);
                if excess > tol {
                    instants.push((k, t));
                    added += 1;
                }
            }
        }
        if added == 0 {
            let cost = problem.cost(&z);
            return Ok(Reference {
                z: z.to_vec(),
                cost,
                instants: instants.len(),
                violation: worst,
            });
        }
    }
    Err(crate::error::Error::Solver {
        solver: "Clarabel cutting planes",
        status: "no convergence in 100 rounds".into(),
    })
}
