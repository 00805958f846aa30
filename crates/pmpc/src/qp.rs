//! Thin Clarabel wrapper for the dense QPs of the bounds, the reference solve and the baseline.

use crate::error::{Error, Result};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::DMatrix;

/// Dense matrix to CSC, dropping exact zeros; `upper` keeps only the upper triangle.
pub(crate) fn csc(m: &DMatrix<f64>, upper: bool) -> CscMatrix<f64> {
    let (mut ri, mut ci, mut v) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            if (!upper || i <= j) && m[(i, j)] != 0.0 {
                ri.push(i);
                ci.push(j);
                v.push(m[(i, j)]);
            }
        }
    }
    CscMatrix::new_from_triplets(m.nrows(), m.ncols(), ri, ci, v)
}

/// Settings with tight tolerances, no output, and data updates allowed.
pub(crate) fn settings(tol: f64) -> DefaultSettings<f64> {
    let mut s = DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .build()
        .unwrap_or_default();
    s.tol_gap_abs = tol;
    s.tol_gap_rel = tol;
    s.tol_feas = tol;
    s.tol_ktratio = tol.min(1e-6);
    s.max_iter = 400;
    s
}

/// Upper triangle of a dense square matrix embedded in the top-left of a `dim`×`dim` CSC.
pub(crate) fn csc_padded(m: &DMatrix<f64>, dim: usize) -> CscMatrix<f64> {
    let (mut ri, mut ci, mut v) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..m.ncols() {
        for i in 0..=j.min(m.nrows().saturating_sub(1)) {
            if m[(i, j)] != 0.0 {
                ri.push(i);
                ci.push(j);
                v.push(m[(i, j)]);
            }
        }
    }
    CscMatrix::new_from_triplets(dim, dim, ri, ci, v)
}

/// min ½xᵀPx + qᵀx s.t. Ax + s = b, s ∈ cones (dense P). Returns (x, objective).
pub(crate) fn solve(
    p: &DMatrix<f64>,
    q: &[f64],
    a: &CscMatrix<f64>,
    b: &[f64],
    cones: &[SupportedConeT<f64>],
    tol: f64,
) -> Result<(Vec<f64>, f64)> {
    solve_sparse(&csc(p, true), q, a, b, cones, tol)
}

/// As [`solve`] with P given as an upper-triangular CSC.
pub(crate) fn solve_sparse(
    p: &CscMatrix<f64>,
    q: &[f64],
    a: &CscMatrix<f64>,
    b: &[f64],
    cones: &[SupportedConeT<f64>],
    tol: f64,
) -> Result<(Vec<f64>, f64)> {
    let mut solver =
        DefaultSolver::new(p, q, a, b, cones, settings(tol)).map_err(|e| Error::Solver {
            solver: "Clarabel",
            status: format!("{e:?}"),
        })?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {
            Ok((solver.solution.x.clone(), solver.solution.obj_val))
        }
        st => Err(Error::Solver {
            solver: "Clarabel",
            status: format!("{st:?}"),
        }),
    }
}
