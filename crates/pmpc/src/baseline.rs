//! Standard discrete-time MPC, the comparison baseline of spec/pmpc.md §8.5: ZOH model,
//! horizon N, stage cost ½(xᵀQx + uᵀRu), DARE terminal cost, no terminal set, constraints at
//! the samples (inputs k = 0..N−1, pure state rows k = 1..N). Condensed (states eliminated,
//! N·m variables) and solved by Clarabel. Solver failures fall back to the shifted previous
//! input sequence and are counted. OSQP is not offered: `osqp-sys` clones its LDL sources
//! from GitHub at build time, which an offline build cannot do.

use crate::constraints::Constraints;
use crate::error::{Error, Result};
use crate::qp;
use clarabel::solver::{DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector};
use rigid_body::lti;

/// QP back end of the baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// Clarabel interior point (data updated in place between steps).
    Clarabel,
}

enum Engine {
    Clarabel(Box<DefaultSolver<f64>>),
}

/// Result of one baseline step.
#[derive(Debug, Clone, PartialEq)]
pub struct DiscreteStep {
    /// Input to apply.
    pub u: Vec<f64>,
    /// True if the solver failed and the shifted previous sequence was used.
    pub fallback: bool,
}

/// Condensed discrete-time MPC.
pub struct DiscreteMpc {
    ad: DMatrix<f64>,
    bd: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    constraints: Constraints,
    td: f64,
    horizon: usize,
    f: DMatrix<f64>,
    g: DMatrix<f64>,
    e: DMatrix<f64>,
    limits: DVector<f64>,
    engine: Engine,
    previous: Option<Vec<f64>>,
    failures: usize,
}

impl core::fmt::Debug for DiscreteMpc {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DiscreteMpc")
            .field("horizon", &self.horizon)
            .field("td", &self.td)
            .field("variables", &self.g.ncols())
            .field("constraints", &self.g.nrows())
            .field("failures", &self.failures)
            .finish()
    }
}

impl DiscreteMpc {
    /// Discretise (ZOH, `td`), compute the DARE terminal cost and condense over `horizon`.
    #[allow(clippy::too_many_arguments)] // the system, weights, constraints and the 3 MPC knobs
    pub fn new(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        q: &DMatrix<f64>,
        r: &DMatrix<f64>,
        constraints: &Constraints,
        td: f64,
        horizon: usize,
        backend: Backend,
    ) -> Result<Self> {
        if horizon == 0 {
            return Err(Error::InvalidParameter {
                name: "horizon",
                value: 0.0,
                requirement: "at least one step",
            });
        }
        if !td.is_finite() || td <= 0.0 {
            return Err(Error::InvalidParameter {
                name: "Td",
                value: td,
                requirement: "finite and > 0",
            });
        }
        let n = a.nrows();
        let m = b.ncols();
        crate::check_shape("A", a, n, n)?;
        crate::check_shape("B", b, n, m)?;
        constraints.validate(n, m)?;
        // The condensed matrices are (n·N)×(n·N) and (n·N)×(m·N).
        crate::check_dense_size(
            "predicted states n*horizon",
            n.saturating_mul(horizon),
            crate::MAX_PREDICTED_STATES,
            4,
        )?;
        let (ad, bd) = lti::c2d_zoh(a, b, td)?;
        let p = lti::dare(&ad, &bd, q, r)?;
        let nn = horizon;
        // X = Sx x0 + Su U, X = (x_1, …, x_N).
        let mut sx = DMatrix::zeros(n * nn, n);
        let mut su = DMatrix::zeros(n * nn, m * nn);
        let mut pow = DMatrix::identity(n, n);
        let mut apb = Vec::with_capacity(nn);
        for k in 0..nn {
            apb.push(&pow * &bd);
            pow = &ad * &pow;
            sx.view_mut((k * n, 0), (n, n)).copy_from(&pow);
        }
        for k in 0..nn {
            for j in 0..=k {
                su.view_mut((k * n, j * m), (n, m)).copy_from(&apb[k - j]);
            }
        }
        let mut qbar = DMatrix::zeros(n * nn, n * nn);
        for k in 0..nn {
            let w = if k + 1 == nn { &p } else { q };
            qbar.view_mut((k * n, k * n), (n, n)).copy_from(w);
        }
        let rbar = DMatrix::from_fn(m * nn, m * nn, |i, j| {
            if i / m == j / m {
                r[(i % m, j % m)]
            } else {
                0.0
            }
        });
        let hc = su.transpose() * &qbar * &su + rbar;
        let hc = (&hc + hc.transpose()) * 0.5;
        let f = su.transpose() * &qbar * &sx;

        // Constraint rows G U ≤ limits − E x0.
        let mut grows: Vec<DVector<f64>> = Vec::new();
        let mut erows: Vec<DVector<f64>> = Vec::new();
        let mut lims: Vec<f64> = Vec::new();
        for k in 0..=nn {
            for row in 0..constraints.len() {
                let cx = constraints.cx.row(row).transpose();
                let cu = constraints.cu.row(row).transpose();
                let has_u = cu.iter().any(|v| *v != 0.0);
                if (k == 0 && !has_u) || (k == nn && has_u) {
                    continue;
                }
                let mut gr = DVector::zeros(m * nn);
                let er: DVector<f64> = if k == 0 {
                    cx.clone()
                } else {
                    let sxk = sx.rows((k - 1) * n, n);
                    let suk = su.rows((k - 1) * n, n);
                    gr += suk.transpose() * &cx;
                    sxk.transpose() * &cx
                };
                if k < nn {
                    let mut seg = gr.rows_mut(k * m, m);
                    seg += &cu;
                }
                for (sign, lim) in [
                    (1.0, constraints.upper[row]),
                    (-1.0, -constraints.lower[row]),
                ] {
                    if lim.is_finite() {
                        grows.push(&gr * sign);
                        erows.push(&er * sign);
                        lims.push(lim);
                    }
                }
            }
        }
        let nr = grows.len();
        let g = DMatrix::from_fn(nr, m * nn, |i, j| grows[i][j]);
        let e = DMatrix::from_fn(nr, n, |i, j| erows[i][j]);
        let limits = DVector::from_vec(lims);
        let q0 = vec![0.0; m * nn];
        let b0 = limits.as_slice().to_vec();
        let engine = match backend {
            Backend::Clarabel => {
                let cones = [SupportedConeT::NonnegativeConeT(nr)];
                let solver = DefaultSolver::new(
                    &qp::csc(&hc, true),
                    &q0,
                    &qp::csc(&g, false),
                    &b0,
                    &cones,
                    qp::settings(1e-6),
                )
                .map_err(|e| Error::Solver {
                    solver: "Clarabel",
                    status: format!("{e:?}"),
                })?;
                Engine::Clarabel(Box::new(solver))
            }
        };
        Ok(Self {
            ad,
            bd,
            q: q.clone(),
            r: r.clone(),
            constraints: constraints.clone(),
            td,
            horizon,
            f,
            g,
            e,
            limits,
            engine,
            previous: None,
            failures: 0,
        })
    }

    /// (A_d, B_d) of the ZOH model.
    pub fn discretization(&self) -> (&DMatrix<f64>, &DMatrix<f64>) {
        (&self.ad, &self.bd)
    }

    /// Q, R and the constraints.
    pub fn weights_and_constraints(&self) -> (&DMatrix<f64>, &DMatrix<f64>, &Constraints) {
        (&self.q, &self.r, &self.constraints)
    }

    /// Sampling time.
    pub fn sampling_time(&self) -> f64 {
        self.td
    }

    /// Number of QP variables N·m and constraint rows.
    pub fn size(&self) -> (usize, usize) {
        (self.g.ncols(), self.g.nrows())
    }

    /// Solver failures so far.
    pub fn failures(&self) -> usize {
        self.failures
    }

    /// Forget the previous solution.
    pub fn reset(&mut self) {
        self.previous = None;
        self.failures = 0;
    }

    /// Solve for state `x`; on solver failure apply the shifted previous sequence.
    pub fn step(&mut self, x: &[f64]) -> Result<DiscreteStep> {
        let n = self.ad.nrows();
        let m = self.bd.ncols();
        crate::check_vector("x", x, n)?;
        let xv = DVector::from_column_slice(x);
        let q = &self.f * &xv;
        let b = &self.limits - &self.e * &xv;
        let solution: Option<Vec<f64>> = match &mut self.engine {
            Engine::Clarabel(solver) => {
                solver
                    .update_q(&q.as_slice().to_vec())
                    .and_then(|_| solver.update_b(&b.as_slice().to_vec()))
                    .map_err(|e| Error::Solver {
                        solver: "Clarabel",
                        status: format!("{e:?}"),
                    })?;
                solver.solve();
                match solver.solution.status {
                    SolverStatus::Solved | SolverStatus::AlmostSolved => {
                        Some(solver.solution.x.clone())
                    }
                    _ => None,
                }
            }
        };
        let (seq, fallback) = match (solution, self.previous.take()) {
            (Some(u), _) => (u, false),
            (None, Some(prev)) => {
                self.failures += 1;
                let mut shifted = prev[m..].to_vec();
                shifted.extend(std::iter::repeat_n(0.0, m));
                (shifted, true)
            }
            (None, None) => {
                return Err(Error::Solver {
                    solver: "discrete-time MPC",
                    status: "failed at the first step".into(),
                })
            }
        };
        let u = seq[..m].to_vec();
        self.previous = Some(seq);
        Ok(DiscreteStep { u, fallback })
    }
}
