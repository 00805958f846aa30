//! Affine linear matrix inequalities G(x) = G_0 + Σ_k x_k G_k ⪰ ε I, assembled sparsely into
//! Clarabel's PSD cone and checked afterwards by eigenvalues.
//!
//! Clarabel's PSD vectorisation (svec) takes the upper triangle column by column with the
//! off-diagonal entries multiplied by √2, so that ⟨svec A, svec B⟩ = tr(AB). Every variable
//! touches only a few entries of each LMI, so coefficients are kept as (variable, row, col, value)
//! triplets and never as dense matrices (dense coefficients would need O(n^4) memory).
//!
//! ```
//! use event_est::lmi::{Problem, Vars};
//! // minimise t subject to [[t, 1], [1, t]] ⪰ 0, optimum t = 1.
//! let mut vars = Vars::default();
//! let t = vars.scalar();
//! let mut prob = Problem::new(vars);
//! let lmi = prob.lmi("[[t,1],[1,t]] ⪰ 0", 2);
//! lmi.add_scalar_identity(t, 0, 2, 1.0);
//! lmi.add_const(0, 1, &nalgebra::DMatrix::from_element(1, 1, 1.0));
//! prob.objective[t.index(0, 0)] = 1.0;
//! let sol = prob.solve("example", 0.0).unwrap();
//! assert!((sol.x[t.index(0, 0)] - 1.0).abs() < 1e-6);
//! ```

use crate::error::EventEstError;
use crate::ipm::Solver;
use crate::linalg::min_eigenvalue;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::DMatrix;

/// Relative eigenvalue tolerance of the post-verification: an interior-point solution meets
/// G(x) ⪰ ε I only up to the solver's feasibility tolerance (1e−8 relative), so λ_min(G(x)) is
/// accepted down to −1e−7·‖G(x)‖_F. The properties the LMIs stand for (Schur stability, Lyapunov
/// decrease with the recovered gains, the H2 bound) are re-checked strictly by the callers.
pub const VERIFY_TOL: f64 = 1e-7;

/// Shape of one block of decision variables.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarKind {
    /// Symmetric d×d matrix, parametrised by its upper triangle (basis E_ii, E_ij + E_ji).
    Sym(usize),
    /// Unconstrained r×c matrix, entrywise.
    Full(usize, usize),
    /// One scalar.
    Scalar,
}

/// A block of decision variables inside the vector x.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VarId {
    offset: usize,
    kind: VarKind,
}

impl VarId {
    /// Index in x of entry (i, j) (for symmetric blocks the upper-triangle entry of {i, j}).
    pub fn index(&self, i: usize, j: usize) -> usize {
        match self.kind {
            VarKind::Sym(_) => {
                let (i, j) = if i <= j { (i, j) } else { (j, i) };
                self.offset + j * (j + 1) / 2 + i
            }
            VarKind::Full(rows, _) => self.offset + i + j * rows,
            VarKind::Scalar => self.offset,
        }
    }

    /// Number of scalar variables in the block.
    pub fn len(&self) -> usize {
        match self.kind {
            VarKind::Sym(d) => d * (d + 1) / 2,
            VarKind::Full(r, c) => r * c,
            VarKind::Scalar => 1,
        }
    }

    /// Whether the block is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The block's value as a matrix, read from a solution vector.
    pub fn value(&self, x: &[f64]) -> DMatrix<f64> {
        match self.kind {
            VarKind::Sym(d) => DMatrix::from_fn(d, d, |i, j| x[self.index(i, j)]),
            VarKind::Full(r, c) => DMatrix::from_fn(r, c, |i, j| x[self.index(i, j)]),
            VarKind::Scalar => DMatrix::from_element(1, 1, x[self.offset]),
        }
    }
}

/// Layout of the decision vector.
#[derive(Debug, Clone, Default)]
pub struct Vars {
    len: usize,
}

impl Vars {
    fn push(&mut self, kind: VarKind) -> VarId {
        let id = VarId {
            offset: self.len,
            kind,
        };
        self.len += id.len();
        id
    }

    /// A new symmetric d×d matrix variable.
    pub fn sym(&mut self, d: usize) -> VarId {
        self.push(VarKind::Sym(d))
    }

    /// A new unconstrained r×c matrix variable.
    pub fn full(&mut self, r: usize, c: usize) -> VarId {
        self.push(VarKind::Full(r, c))
    }

    /// A new scalar variable.
    pub fn scalar(&mut self) -> VarId {
        self.push(VarKind::Scalar)
    }

    /// Total number of scalar variables.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are no variables.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// One LMI G(x) ⪰ ε I of size `dim`. Blocks are addressed by their top-left corner; only the
/// upper triangle is stored, so off-diagonal blocks must lie above the diagonal (r0 + rows ≤ c0).
#[derive(Debug, Clone)]
pub struct Lmi {
    /// Name used in errors and verification reports.
    pub name: String,
    dim: usize,
    constant: DMatrix<f64>,
    terms: Vec<(usize, usize, usize, f64)>,
    margin: Option<f64>,
}

impl Lmi {
    fn push(&mut self, var: usize, i: usize, j: usize, v: f64) {
        if v != 0.0 {
            let (i, j) = if i <= j { (i, j) } else { (j, i) };
            self.terms.push((var, i, j, v));
        }
    }

    /// Own strictness margin ε (G(x) ⪰ ε I) instead of the problem-wide one.
    pub fn set_margin(&mut self, eps: f64) {
        self.margin = Some(eps);
    }

    /// Size of the LMI.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Adds the constant block `m` at (r0, c0) (a diagonal block if r0 == c0, then `m` is symmetric).
    pub fn add_const(&mut self, r0: usize, c0: usize, m: &DMatrix<f64>) {
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                let (r, c) = (r0 + i, c0 + j);
                if r <= c {
                    self.constant[(r, c)] += m[(i, j)];
                }
            }
        }
    }

    /// Adds `scale`·S at diagonal block (r0, r0) for a symmetric variable S.
    pub fn add_sym(&mut self, s: VarId, r0: usize, scale: f64) {
        let VarKind::Sym(d) = s.kind else { return };
        for j in 0..d {
            for i in 0..=j {
                self.push(s.index(i, j), r0 + i, r0 + j, scale);
            }
        }
    }

    /// Adds `scale`·x[`var`] at entry (i, j) (and its mirror), for one scalar entry of any block
    /// (`VarId::index`), e.g. a trace in a scalar constraint.
    pub fn add_entry(&mut self, var: usize, i: usize, j: usize, scale: f64) {
        self.push(var, i, j, scale);
    }

    /// Adds `scale`·t·I_d at diagonal block (r0, r0) for a scalar variable t.
    pub fn add_scalar_identity(&mut self, t: VarId, r0: usize, d: usize, scale: f64) {
        for i in 0..d {
            self.push(t.index(0, 0), r0 + i, r0 + i, scale);
        }
    }

    /// Adds `scale`·S·M at off-diagonal block (r0, c0) (S symmetric d×d, M d×k).
    pub fn add_sym_times(&mut self, s: VarId, m: &DMatrix<f64>, r0: usize, c0: usize, scale: f64) {
        let VarKind::Sym(d) = s.kind else { return };
        for j in 0..d {
            for i in 0..=j {
                let idx = s.index(i, j);
                for b in 0..m.ncols() {
                    self.push(idx, r0 + i, c0 + b, scale * m[(j, b)]);
                    if i != j {
                        self.push(idx, r0 + j, c0 + b, scale * m[(i, b)]);
                    }
                }
            }
        }
    }

    /// Adds `scale`·M·S at off-diagonal block (r0, c0) (M h×d, S symmetric d×d): the transpose
    /// S·Mᵀ of the mirrored block, since only the upper triangle is stored.
    pub fn add_times_sym(&mut self, m: &DMatrix<f64>, s: VarId, r0: usize, c0: usize, scale: f64) {
        self.add_sym_times(s, &m.transpose(), c0, r0, scale);
    }

    /// Adds `scale`·U[:, cols]·G[cols, :] at off-diagonal block (r0, c0) for a full variable U
    /// (only the columns `cols` of U, matching rows of G, take part).
    pub fn add_full_times(
        &mut self,
        u: VarId,
        g: &DMatrix<f64>,
        cols: core::ops::Range<usize>,
        r0: usize,
        c0: usize,
        scale: f64,
    ) {
        self.add_full_product(None, u, g, cols, (r0, c0), scale);
    }

    /// Adds `scale`·M·U[:, cols]·G[cols, :] at the off-diagonal block whose top-left corner is
    /// `at`, for a full variable U and a constant M (h×rows of U; `None` = identity), e.g. a
    /// congruence-transformed gain R·L·G.
    pub fn add_full_product(
        &mut self,
        m: Option<&DMatrix<f64>>,
        u: VarId,
        g: &DMatrix<f64>,
        cols: core::ops::Range<usize>,
        at: (usize, usize),
        scale: f64,
    ) {
        let VarKind::Full(rows, _) = u.kind else {
            return;
        };
        let identity;
        let m = match m {
            Some(m) => m,
            None => {
                identity = DMatrix::identity(rows, rows);
                &identity
            }
        };
        let (r0, c0) = at;
        for r in cols {
            for a in 0..rows {
                let idx = u.index(a, r);
                for h in 0..m.nrows() {
                    let ma = scale * m[(h, a)];
                    if ma == 0.0 {
                        continue;
                    }
                    for b in 0..g.ncols() {
                        self.push(idx, r0 + h, c0 + b, ma * g[(r, b)]);
                    }
                }
            }
        }
    }

    /// G(x) as a dense symmetric matrix.
    pub fn evaluate(&self, x: &[f64]) -> DMatrix<f64> {
        let mut g = self.constant.clone();
        for &(var, i, j, v) in &self.terms {
            g[(i, j)] += v * x[var];
        }
        symmetric_from_upper(&g)
    }

    /// G_0 as a dense symmetric matrix.
    pub(crate) fn constant_full(&self) -> DMatrix<f64> {
        symmetric_from_upper(&self.constant)
    }

    /// The LMI's own strictness margin, else `eps`.
    pub(crate) fn margin_or(&self, eps: f64) -> f64 {
        self.margin.unwrap_or(eps)
    }

    /// Coefficients (variable, row, col, value), row ≤ col, possibly repeated.
    pub(crate) fn terms(&self) -> &[(usize, usize, usize, f64)] {
        &self.terms
    }
}

/// The symmetric matrix whose upper triangle is that of `g`.
fn symmetric_from_upper(g: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(g.nrows(), g.ncols(), |i, j| {
        if i <= j {
            g[(i, j)]
        } else {
            g[(j, i)]
        }
    })
}

/// A linear objective (minimised) over LMI constraints.
#[derive(Debug, Clone)]
pub struct Problem {
    /// Variable layout.
    pub vars: Vars,
    /// Constraints G_l(x) ⪰ ε I.
    pub lmis: Vec<Lmi>,
    /// Objective coefficients q (minimise qᵀx).
    pub objective: Vec<f64>,
}

/// Solver output.
#[derive(Debug, Clone)]
pub struct Solution {
    /// Decision vector.
    pub x: Vec<f64>,
    /// Clarabel's status (Solved or AlmostSolved).
    pub status: String,
    /// Wall-clock solve time in seconds (as reported by Clarabel).
    pub solve_time: f64,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Smallest eigenvalue of each LMI at x relative to its Frobenius norm, in the order of
    /// `lmis` (all ≥ −[`VERIFY_TOL`] when returned).
    pub margins: Vec<f64>,
}

/// Index of entry (i, j), i ≤ j, in svec of a d×d matrix.
pub fn svec_index(i: usize, j: usize) -> usize {
    j * (j + 1) / 2 + i
}

/// svec: upper triangle column by column, off-diagonals times √2.
pub fn svec(m: &DMatrix<f64>) -> Vec<f64> {
    let d = m.nrows();
    let mut v = vec![0.0; d * (d + 1) / 2];
    for j in 0..d {
        for i in 0..=j {
            let s = if i == j {
                1.0
            } else {
                std::f64::consts::SQRT_2
            };
            v[svec_index(i, j)] = s * m[(i, j)];
        }
    }
    v
}

/// Inverse of [`svec`].
pub fn smat(v: &[f64]) -> DMatrix<f64> {
    // d(d+1)/2 = len
    let d = ((((8 * v.len() + 1) as f64).sqrt() - 1.0) / 2.0).round() as usize;
    DMatrix::from_fn(d, d, |i, j| {
        let (i, j) = if i <= j { (i, j) } else { (j, i) };
        let s = if i == j {
            1.0
        } else {
            std::f64::consts::SQRT_2
        };
        v[svec_index(i, j)] / s
    })
}

impl Problem {
    /// An empty problem over `vars` with zero objective.
    pub fn new(vars: Vars) -> Self {
        let objective = vec![0.0; vars.len()];
        Self {
            vars,
            lmis: Vec::new(),
            objective,
        }
    }

    /// Adds an empty LMI of size `dim` and returns it for filling.
    pub fn lmi(&mut self, name: impl Into<String>, dim: usize) -> &mut Lmi {
        self.lmis.push(Lmi {
            name: name.into(),
            dim,
            constant: DMatrix::zeros(dim, dim),
            terms: Vec::new(),
            margin: None,
        });
        let last = self.lmis.len() - 1;
        &mut self.lmis[last]
    }

    /// [`Problem::solve`] with a choice of SDP solver; the same eigenvalue post-verification
    /// applies to both.
    pub fn solve_with(
        &self,
        solver: Solver,
        problem: &'static str,
        eps: f64,
    ) -> Result<Solution, EventEstError> {
        match solver {
            Solver::Clarabel => self.solve(problem, eps),
            Solver::SchurIpm => {
                let out = crate::ipm::solve(self, problem, eps)?;
                self.verified(
                    problem,
                    out.x,
                    out.status.into(),
                    out.solve_time,
                    out.iterations,
                )
            }
        }
    }

    /// Solves with every LMI tightened to G(x) ⪰ `eps`·I (or its own margin), then checks λ_min(G_l(x)) > 0 for
    /// every l. `problem` names the problem in errors.
    pub fn solve(&self, problem: &'static str, eps: f64) -> Result<Solution, EventEstError> {
        let n = self.vars.len();
        let mut rows = Vec::new();
        let mut cols = Vec::new();
        let mut vals = Vec::new();
        let mut b = Vec::new();
        let mut cones = Vec::new();
        let mut row0 = 0;
        for lmi in &self.lmis {
            let d = lmi.dim;
            let mut g0 = lmi.constant.clone();
            let eps = lmi.margin.unwrap_or(eps);
            for i in 0..d {
                g0[(i, i)] -= eps;
            }
            // s = svec(G(x) − εI) = svec(G0 − εI) + Σ x_k svec(G_k) and A x + s = b.
            for j in 0..d {
                for i in 0..=j {
                    let s = if i == j {
                        1.0
                    } else {
                        std::f64::consts::SQRT_2
                    };
                    b.push(s * g0[(i, j)]);
                }
            }
            for &(var, i, j, v) in &lmi.terms {
                let s = if i == j {
                    1.0
                } else {
                    std::f64::consts::SQRT_2
                };
                rows.push(row0 + svec_index(i, j));
                cols.push(var);
                vals.push(-s * v);
            }
            cones.push(if d == 1 {
                SupportedConeT::NonnegativeConeT(1)
            } else {
                SupportedConeT::PSDTriangleConeT(d)
            });
            row0 += d * (d + 1) / 2;
        }
        let a = CscMatrix::new_from_triplets(row0, n, rows, cols, vals);
        let p = CscMatrix::zeros((n, n));
        let settings = DefaultSettings::<f64> {
            verbose: false,
            max_iter: 300,
            ..DefaultSettings::default()
        };
        let mut solver = DefaultSolver::new(&p, &self.objective, &a, &b, &cones, settings)
            .map_err(|e| EventEstError::Solver {
                problem,
                status: e.to_string(),
            })?;
        solver.solve();
        let sol = &solver.solution;
        match sol.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {}
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                return Err(EventEstError::Infeasible {
                    problem,
                    status: format!("{:?}", sol.status),
                    condition: self.certificate_support(&sol.z),
                });
            }
            other => {
                return Err(EventEstError::Solver {
                    problem,
                    status: format!("{other:?}"),
                })
            }
        }
        self.verified(
            problem,
            sol.x.clone(),
            format!("{:?}", sol.status),
            sol.solve_time,
            sol.iterations,
        )
    }

    /// Post-verification: λ_min(G_l(x)) ≥ −[`VERIFY_TOL`]·‖G_l(x)‖_F for every l.
    fn verified(
        &self,
        problem: &'static str,
        x: Vec<f64>,
        status: String,
        solve_time: f64,
        iterations: u32,
    ) -> Result<Solution, EventEstError> {
        let mut margins = Vec::with_capacity(self.lmis.len());
        for lmi in &self.lmis {
            let g = lmi.evaluate(&x);
            let m = min_eigenvalue(&g) / g.norm().max(f64::MIN_POSITIVE);
            if m.is_nan() || m < -VERIFY_TOL {
                return Err(EventEstError::Verification {
                    condition: format!("{problem}: {}", lmi.name),
                    margin: m,
                });
            }
            margins.push(m);
        }
        Ok(Solution {
            x,
            status,
            solve_time,
            iterations,
            margins,
        })
    }

    /// Names of the LMIs that carry the Farkas certificate of infeasibility (dual blocks with
    /// weight above 1e-6 of the largest): these conditions cannot hold together.
    fn certificate_support(&self, z: &[f64]) -> String {
        let mut weights = Vec::with_capacity(self.lmis.len());
        let mut row0 = 0;
        for lmi in &self.lmis {
            let len = lmi.dim * (lmi.dim + 1) / 2;
            let w: f64 = z[row0..row0 + len]
                .iter()
                .map(|v| v * v)
                .sum::<f64>()
                .sqrt();
            weights.push(w);
            row0 += len;
        }
        let max = weights.iter().copied().fold(0.0, f64::max);
        let names: Vec<&str> = self
            .lmis
            .iter()
            .zip(&weights)
            .filter(|(_, &w)| w > 1e-6 * max)
            .map(|(l, _)| l.name.as_str())
            .collect();
        format!("no solution satisfies together: {}", names.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{max_eigenvalue, spectral_radius};
    use proptest::prelude::*;

    fn sym_from(v: &[f64], d: usize) -> DMatrix<f64> {
        let m = DMatrix::from_column_slice(d, d, &v[..d * d]);
        (&m + m.transpose()) * 0.5
    }

    proptest! {
        #[test]
        fn svec_round_trip_and_inner_product(v in proptest::collection::vec(-3.0f64..3.0, 32), d in 1usize..5) {
            let a = sym_from(&v, d);
            let b = sym_from(&v[16..], d);
            prop_assert!((smat(&svec(&a)) - &a).amax() < 1e-14);
            let dot: f64 = svec(&a).iter().zip(svec(&b)).map(|(x, y)| x * y).sum();
            prop_assert!((dot - (&a * &b).trace()).abs() < 1e-12);
            // Diagonal entry (k, k) sits at k(k+3)/2.
            prop_assert!((svec(&a)[(d - 1) * (d + 2) / 2] - a[(d - 1, d - 1)]).abs() < 1e-15);
        }

        /// Every stable A has a Lyapunov certificate P ≻ 0 with AᵀPA − P ≺ 0, found by the SDP.
        #[test]
        fn lyapunov_feasibility_for_schur_matrices(v in proptest::collection::vec(-1.0f64..1.0, 9), rho in 0.1f64..0.95) {
            let a0 = DMatrix::from_column_slice(3, 3, &v);
            let r0 = spectral_radius(&a0);
            prop_assume!(r0 > 1e-3);
            let a = a0 * (rho / r0);
            let mut vars = Vars::default();
            let p = vars.sym(3);
            let mut prob = Problem::new(vars);
            {
                // [[P, PA], [AᵀP, P]] ⪰ ε, P ⪯ 100 I (bounded), minimise tr P.
                let l = prob.lmi("Lyapunov decrease", 6);
                l.add_sym(p, 0, 1.0);
                l.add_sym_times(p, &a, 0, 3, 1.0);
                l.add_sym(p, 3, 1.0);
                let l = prob.lmi("P ⪯ 100 I", 3);
                l.add_sym(p, 0, -1.0);
                l.add_const(0, 0, &(DMatrix::identity(3, 3) * 100.0));
                let l = prob.lmi("P ⪰ I", 3);
                l.add_sym(p, 0, 1.0);
                l.add_const(0, 0, &(-DMatrix::<f64>::identity(3, 3)));
            }
            for i in 0..3 {
                prob.objective[p.index(i, i)] = 1.0;
            }
            match prob.solve("Lyapunov", 1e-6) {
                Ok(sol) => {
                    let pm = p.value(&sol.x);
                    prop_assert!(max_eigenvalue(&(a.transpose() * &pm * &a - &pm)) < 0.0);
                }
                // P ⪯ 100 I may be too small for strongly non-normal A: then the SDP must say so.
                Err(EventEstError::Infeasible { .. }) => {
                    let pm = rigid_body::lti::dlyap(&a.transpose(), &DMatrix::identity(3, 3)).unwrap();
                    prop_assert!(pm.norm() > 10.0);
                }
                Err(e) => prop_assert!(false, "{e}"),
            }
        }
    }

    #[test]
    fn tiny_sdp_has_the_known_optimum() {
        // minimise t s.t. [[t, 1], [1, t]] ⪰ 0: t = 1.
        let mut vars = Vars::default();
        let t = vars.scalar();
        let mut prob = Problem::new(vars);
        let l = prob.lmi("[[t,1],[1,t]]", 2);
        l.add_scalar_identity(t, 0, 2, 1.0);
        l.add_const(0, 1, &DMatrix::from_element(1, 1, 1.0));
        prob.objective[0] = 1.0;
        let sol = prob.solve("tiny", 0.0).unwrap();
        assert!((sol.x[0] - 1.0).abs() < 1e-7);
    }

    #[test]
    fn infeasible_problem_names_the_conflicting_conditions() {
        // x ⪰ 1 and x ⪯ 0 with a harmless third constraint y ⪰ 0 that is not part of the conflict.
        let mut vars = Vars::default();
        let x = vars.sym(2);
        let y = vars.scalar();
        let mut prob = Problem::new(vars);
        let l = prob.lmi("X ⪰ I", 2);
        l.add_sym(x, 0, 1.0);
        l.add_const(0, 0, &(-DMatrix::<f64>::identity(2, 2)));
        let l = prob.lmi("X ⪯ 0", 2);
        l.add_sym(x, 0, -1.0);
        let l = prob.lmi("y ⪰ 0", 1);
        l.add_scalar_identity(y, 0, 1, 1.0);
        let err = prob.solve("conflict", 0.0).unwrap_err();
        let EventEstError::Infeasible { condition, .. } = &err else {
            panic!("expected Infeasible, got {err}");
        };
        assert!(
            condition.contains("X ⪰ I") && condition.contains("X ⪯ 0"),
            "{condition}"
        );
        assert!(!condition.contains("y ⪰ 0"), "{condition}");
    }
}
