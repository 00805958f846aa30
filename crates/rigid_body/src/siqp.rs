//! Active-set solver for the semi-infinite QPs of parametrized MPC (spec/pmpc.md §7):
//!
//! ```text
//! min ½ zᵀHz  s.t.  A_eq z = b_eq,   l_l,k ≤ τ(t)ᵀ (C_z z)_k ≤ l_u,k   for all t ≥ 0, every row k
//! ```
//!
//! The solver works in the constraint-coefficient space w = C_z z (dimension nc·s): the
//! caller precomputes Φ = C_z S C_zᵀ and the unconstrained coefficients w0 = C_z b̂ (see the
//! `pmpc` crate), then `z` follows from the returned multipliers. It is a range-space dual
//! active set method of Goldfarb–Idnani type that doubles as a cutting-plane method: the
//! Taylor-bound check finds the first violated instant of every row, one dual step per row
//! adds them (dropping blocking instants), Newton steps then move the active instants onto
//! the extrema of their constraint functions (`polish`), and the cost rises monotonically.
//! The working-set matrix K_W is kept as a Cholesky factor with bordered updates and Givens
//! deletions.
//!
//! Nothing allocates: all memory is a caller-provided [`Workspace`] (or, with `std`, a
//! [`WorkspaceStorage`] sized once at set-up). The iteration budget is explicit and the
//! returned [`Outcome`] always carries the current iterate with a typed [`Status`].
//!
//! ```
//! use rigid_body::laguerre::Laguerre;
//! use rigid_body::siqp::{solve, Problem, Row, Settings, WorkspaceStorage};
//! // One row, s = 2, Φ = I: project w0 onto {w : τ(t)ᵀw ≤ 1 for all t ≥ 0}.
//! let basis = Laguerre::new(2, 1.0).unwrap();
//! let rows = [Row { lower: f64::NEG_INFINITY, upper: 1.0 }];
//! let phi = [1.0, 0.0, 0.0, 1.0];
//! let problem = Problem::new(basis, &rows, &phi, 2).unwrap();
//! let mut storage = WorkspaceStorage::new(&problem);
//! let mut ws = storage.workspace(&problem).unwrap();
//! let out = solve(&problem, &Settings::default(), &[2.0, 0.0], false, &mut ws).unwrap();
//! assert!(out.status.is_optimal());
//! ```

mod check;
mod factor;
mod polish;

use crate::laguerre::{check_len, Laguerre};
use crate::Error;
use check::{check_row, RowCheck, Scratch};
use factor::Factor;

mod fmath {
    use nalgebra::ComplexField;
    pub(super) fn sqrt(x: f64) -> f64 {
        <f64 as ComplexField>::sqrt(x)
    }
    pub(super) fn abs(x: f64) -> f64 {
        <f64 as ComplexField>::abs(x)
    }
}

/// Limits of one constraint row, `lower ≤ 0 ≤ upper`; use ±∞ for a one-sided row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Lower limit l_l (≤ 0, may be −∞).
    pub lower: f64,
    /// Upper limit l_u (≥ 0, may be +∞).
    pub upper: f64,
}

/// Which limit an active instant holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// τ(t)ᵀ w_k = l_u.
    Upper,
    /// τ(t)ᵀ w_k = l_l.
    Lower,
}

impl Side {
    /// +1 for the upper limit, −1 for the lower.
    pub fn sign(self) -> f64 {
        match self {
            Side::Upper => 1.0,
            Side::Lower => -1.0,
        }
    }
}

/// One element of the working set: constraint row `row` active at instant `t` on `side`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Active {
    /// Instant (s, relative to the problem's time origin).
    pub t: f64,
    /// Constraint row index.
    pub row: usize,
    /// Active limit.
    pub side: Side,
}

impl Default for Active {
    fn default() -> Self {
        Self {
            t: 0.0,
            row: 0,
            side: Side::Upper,
        }
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Absolute constraint tolerance ε: the result satisfies the limits within ε on [0, ∞).
    pub tolerance: f64,
    /// Budget of outer iterations (constraint checks).
    pub max_iter: usize,
    /// Optional fixed horizon T_c; `None` uses the adaptive tail certificate only.
    pub horizon: Option<f64>,
    /// Cap on Taylor steps per row check (guards against pathological data).
    pub max_check_steps: usize,
    /// Newton refinement of a found violation instant towards the local extremum.
    pub refine: bool,
    /// Relative Schur-complement threshold below which a new instant counts as dependent.
    pub dependence_tol: f64,
    /// Newton moves of the active instants towards their extrema after each addition
    /// (0 turns them off: the plain exchange of the dual method).
    pub polish_steps: usize,
    /// Outer iterations of a cold solve whose checks stop at the first violation; later checks
    /// scan each row for its most violated instant (0: always scan, `usize::MAX`: never). From
    /// the unconstrained solution the first violation walks along a saturated arc one lobe per
    /// check; the worst one jumps there (on the quadruple integrator 76 → 20 iterations at
    /// s = 10, ν = 1.3 and 662 → 37 at s = 12, ν = 1.8).
    pub scan_after_cold: usize,
    /// The same for a warm-started solve. Late by default: from a predicted working set the
    /// first violation is usually the instant that is missing (scanning after 4 or 8
    /// iterations raised the p99 of the warm steps by 25-75 % on the quadruple integrator),
    /// but a warm step that has walked 20 iterations is on an arc (its slowest steps at
    /// s = 14-16, ν = 1.8: 5.9-7.7 ms → 1.3-2.0 ms).
    pub scan_after_warm: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            max_iter: 1000,
            horizon: None,
            max_check_steps: 10_000,
            refine: true,
            dependence_tol: 1e-10,
            polish_steps: 3,
            scan_after_cold: 2,
            scan_after_warm: 20,
        }
    }
}

/// How the solve ended; the iterate in [`Outcome`] is valid in every case.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Satisfies every row within ε on [0, ∞) (or [0, T_c)) and is optimal for its working set.
    Optimal,
    /// The outer-iteration budget ran out; the iterate is dual feasible but may violate rows.
    IterationLimit,
    /// The dual step is unbounded: no z satisfies the equalities and the sampled limits.
    Infeasible,
    /// A row check exceeded `max_check_steps`.
    CheckStepLimit,
}

impl Status {
    /// True for [`Status::Optimal`].
    pub fn is_optimal(self) -> bool {
        self == Status::Optimal
    }
}

/// Work counters of one solve.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Outer iterations (constraint checks).
    pub iterations: usize,
    /// Instants added to the working set.
    pub adds: usize,
    /// Instants dropped from the working set.
    pub drops: usize,
    /// Taylor steps over all checks.
    pub taylor_steps: usize,
    /// Accepted Newton moves of the working set's instants.
    pub moves: usize,
}

/// Problem data borrowed from the caller (precomputed offline).
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    basis: Laguerre,
    rows: &'a [Row],
    phi: &'a [f64],
    max_active: usize,
    phi_scale: f64,
}

impl<'a> Problem<'a> {
    /// `phi` is Φ = C_z S C_zᵀ, (nc·s)×(nc·s), symmetric, row-major; `max_active` bounds the
    /// working set (the degrees of freedom m·s − n suffice: K_W must stay positive definite).
    pub fn new(
        basis: Laguerre,
        rows: &'a [Row],
        phi: &'a [f64],
        max_active: usize,
    ) -> Result<Self, Error> {
        let dim = rows.len() * basis.dim();
        if rows.is_empty() {
            return Err(Error::InvalidParameter {
                name: "rows",
                value: 0.0,
                requirement: "at least one constraint row",
            });
        }
        check_len("phi", phi.len(), dim * dim)?;
        if phi.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite { name: "phi" });
        }
        for r in rows {
            if r.lower.is_nan() || r.lower > 0.0 {
                return Err(Error::InvalidParameter {
                    name: "row lower limit",
                    value: r.lower,
                    requirement: "lower <= 0 (use -inf for none)",
                });
            }
            if r.upper.is_nan() || r.upper < 0.0 {
                return Err(Error::InvalidParameter {
                    name: "row upper limit",
                    value: r.upper,
                    requirement: "upper >= 0 (use +inf for none)",
                });
            }
        }
        if max_active == 0 {
            return Err(Error::InvalidParameter {
                name: "max_active",
                value: 0.0,
                requirement: "room for at least one active instant",
            });
        }
        let phi_scale = (0..dim).map(|i| phi[i * dim + i]).fold(0.0, f64::max);
        Ok(Self {
            basis,
            rows,
            phi,
            max_active,
            phi_scale,
        })
    }

    /// Dimension nc·s of the coefficient space.
    pub fn dim(&self) -> usize {
        self.rows.len() * self.basis.dim()
    }

    /// The basis.
    pub fn basis(&self) -> &Laguerre {
        &self.basis
    }

    /// Number of `f64` and [`Active`] slots a [`Workspace`] needs.
    pub fn workspace_len(&self) -> (usize, usize) {
        let (d, c, s) = (self.dim(), self.max_active, self.basis.dim());
        let nc = self.rows.len();
        (
            5 * d + 3 * c * d + 6 * c * c + 9 * c + 3 * c * s + 6 * s + nc,
            2 * c + nc,
        )
    }

    fn beta(&self, a: &Active) -> f64 {
        match a.side {
            Side::Upper => self.rows[a.row].upper,
            Side::Lower => -self.rows[a.row].lower,
        }
    }

    /// `out = Φ v` for v = σ e_k ⊗ τ (Φ symmetric, so read rows of the k-th block).
    fn phi_v(&self, row: usize, sign: f64, tau: &[f64], out: &mut [f64]) {
        let (d, s) = (self.dim(), self.basis.dim());
        out.fill(0.0);
        for (p, &tp) in tau.iter().enumerate().take(s) {
            let c = sign * tp;
            let base = (row * s + p) * d;
            for (o, &f) in out.iter_mut().zip(&self.phi[base..base + d]) {
                *o += c * f;
            }
        }
    }
}

/// Copy of the iterate and its factor, so that a rejected polish is undone by a copy rather
/// than a refactorisation.
#[derive(Debug)]
struct Saved<'a> {
    w: &'a mut [f64],
    u: &'a mut [f64],
    taus: &'a mut [f64],
    lambda: &'a mut [f64],
    l: &'a mut [f64],
}

/// Borrowed solver memory; build it from slices or from a [`WorkspaceStorage`].
#[derive(Debug)]
pub struct Workspace<'a> {
    dim: usize,
    s: usize,
    cap: usize,
    w: &'a mut [f64],
    w0: &'a mut [f64],
    dw: &'a mut [f64],
    uq: &'a mut [f64],
    u: &'a mut [f64],
    chol: Factor<'a>,
    lambda: &'a mut [f64],
    r: &'a mut [f64],
    b: &'a mut [f64],
    l: &'a mut [f64],
    taus: &'a mut [f64],
    tau: &'a mut [f64],
    y: &'a mut [f64],
    y2: &'a mut [f64],
    d1: &'a mut [f64],
    d2: &'a mut [f64],
    s_k: &'a mut [f64],
    active: &'a mut [Active],
    n_active: usize,
    dtau: &'a mut [f64],
    up: &'a mut [f64],
    jac: &'a mut [f64],
    rhs: &'a mut [f64],
    f2: &'a mut [f64],
    g2: &'a mut [f64],
    backup: &'a mut [Active],
    saved: Saved<'a>,
    cands: &'a mut [Active],
    cand_excess: &'a mut [f64],
}

impl<'a> Workspace<'a> {
    /// Split caller memory (lengths from [`Problem::workspace_len`]) into the solver's buffers.
    pub fn new(
        problem: &Problem<'_>,
        floats: &'a mut [f64],
        active: &'a mut [Active],
    ) -> Result<Self, Error> {
        let (nf, na) = problem.workspace_len();
        check_len("floats", floats.len(), nf)?;
        check_len("active", active.len(), na)?;
        let (d, c, s) = (problem.dim(), problem.max_active, problem.basis.dim());
        let (w, rest) = floats.split_at_mut(d);
        let (w0, rest) = rest.split_at_mut(d);
        let (dw, rest) = rest.split_at_mut(d);
        let (uq, rest) = rest.split_at_mut(d);
        let (u, rest) = rest.split_at_mut(c * d);
        let (l_factor, rest) = rest.split_at_mut(c * c);
        let (lambda, rest) = rest.split_at_mut(c);
        let (r, rest) = rest.split_at_mut(c);
        let (b, rest) = rest.split_at_mut(c);
        let (l, rest) = rest.split_at_mut(c);
        let (taus, rest) = rest.split_at_mut(c * s);
        let (tau, rest) = rest.split_at_mut(s);
        let (y, rest) = rest.split_at_mut(s);
        let (y2, rest) = rest.split_at_mut(s);
        let (d1, rest) = rest.split_at_mut(s);
        let (d2, rest) = rest.split_at_mut(s);
        let (s_k, rest) = rest.split_at_mut(s);
        let (dtau, rest) = rest.split_at_mut(c * s);
        let (up, rest) = rest.split_at_mut(c * d);
        let (jac, rest) = rest.split_at_mut(4 * c * c);
        let (rhs, rest) = rest.split_at_mut(2 * c);
        let (f2, rest) = rest.split_at_mut(c);
        let (g2, rest) = rest.split_at_mut(c);
        let (saved_w, rest) = rest.split_at_mut(d);
        let (saved_u, rest) = rest.split_at_mut(c * d);
        let (saved_taus, rest) = rest.split_at_mut(c * s);
        let (saved_lambda, rest) = rest.split_at_mut(c);
        let (saved_l, cand_excess) = rest.split_at_mut(c * c);
        let (active, rest) = active.split_at_mut(c);
        let (backup, cands) = rest.split_at_mut(c);
        Ok(Self {
            dim: d,
            s,
            cap: c,
            w,
            w0,
            dw,
            uq,
            u,
            chol: Factor {
                l: l_factor,
                cap: c,
            },
            lambda,
            r,
            b,
            l,
            taus,
            tau,
            y,
            y2,
            d1,
            d2,
            s_k,
            active,
            n_active: 0,
            dtau,
            up,
            jac,
            rhs,
            f2,
            g2,
            backup,
            saved: Saved {
                w: saved_w,
                u: saved_u,
                taus: saved_taus,
                lambda: saved_lambda,
                l: saved_l,
            },
            cands,
            cand_excess,
        })
    }

    /// The current working set.
    pub fn active(&self) -> &[Active] {
        &self.active[..self.n_active]
    }

    /// Replace the working set used by the next warm-started solve (truncated to capacity).
    pub fn set_active(&mut self, list: &[Active]) {
        let n = list.len().min(self.cap);
        self.active[..n].copy_from_slice(&list[..n]);
        self.n_active = n;
    }

    /// Shift the working set by `h` seconds (t ← max(t − h, 0)): the warm start of the next MPC
    /// step (spec §7.6). An instant that falls before 0 moves to 0 instead of being dropped: a
    /// row held at the start of the plan (a saturated input) is held at the start of the next
    /// one too, and without it the rest of the set is not dual feasible, so the seed would drop
    /// it all and the step would start cold. A duplicate this makes at 0 is dropped by the seed
    /// (dependent instant).
    pub fn shift_active(&mut self, h: f64) {
        for a in &mut self.active[..self.n_active] {
            a.t = (a.t - h).max(0.0);
        }
    }

    /// Save the working set, iterate, multipliers and factor (see [`Workspace::restore`]).
    fn save(&mut self) {
        let (p, d, s) = (self.n_active, self.dim, self.s);
        self.backup[..p].copy_from_slice(&self.active[..p]);
        self.saved.w.copy_from_slice(self.w);
        self.saved.u[..p * d].copy_from_slice(&self.u[..p * d]);
        self.saved.taus[..p * s].copy_from_slice(&self.taus[..p * s]);
        self.saved.lambda[..p].copy_from_slice(&self.lambda[..p]);
        self.saved.l.copy_from_slice(self.chol.l);
    }

    /// Return to the state of the last [`Workspace::save`], which held `p` instants.
    fn restore(&mut self, p: usize) {
        let (d, s) = (self.dim, self.s);
        self.active[..p].copy_from_slice(&self.backup[..p]);
        self.w.copy_from_slice(self.saved.w);
        self.u[..p * d].copy_from_slice(&self.saved.u[..p * d]);
        self.taus[..p * s].copy_from_slice(&self.saved.taus[..p * s]);
        self.lambda[..p].copy_from_slice(&self.saved.lambda[..p]);
        self.chol.l.copy_from_slice(self.saved.l);
        self.n_active = p;
    }

    fn v_dot(&self, j: usize, x: &[f64]) -> f64 {
        let a = self.active[j];
        let blk = &x[a.row * self.s..(a.row + 1) * self.s];
        let tj = &self.taus[j * self.s..(j + 1) * self.s];
        a.side.sign() * tj.iter().zip(blk).map(|(p, q)| p * q).sum::<f64>()
    }

    fn remove(&mut self, j: usize) {
        let p = self.n_active;
        self.chol.remove(p, j);
        let (d, s) = (self.dim, self.s);
        for i in j..p - 1 {
            self.active[i] = self.active[i + 1];
            self.lambda[i] = self.lambda[i + 1];
            self.u.copy_within((i + 1) * d..(i + 2) * d, i * d);
            self.taus.copy_within((i + 1) * s..(i + 2) * s, i * s);
        }
        self.n_active = p - 1;
    }

    /// Try to append the candidate whose τ is in `self.tau` and Φv in `self.uq`; returns the
    /// Schur complement or `None` if dependent on the working set (or at capacity).
    fn try_append(&mut self, cand: Active, dep_tol: f64, scale: f64) -> Option<f64> {
        let p = self.n_active;
        if p >= self.cap {
            return None;
        }
        let sign = cand.side.sign();
        let blk = &self.uq[cand.row * self.s..(cand.row + 1) * self.s];
        let vqu = sign * self.tau.iter().zip(blk).map(|(a, b)| a * b).sum::<f64>();
        for j in 0..p {
            self.l[j] = self.v_dot(j, self.uq);
        }
        self.chol.forward(p, self.l);
        let schur = vqu - self.l[..p].iter().map(|x| x * x).sum::<f64>();
        let tau2: f64 = self.tau.iter().map(|x| x * x).sum();
        if schur.is_nan() || schur <= dep_tol * vqu.max(scale * tau2) {
            return None;
        }
        self.chol.append(p, self.l, schur);
        self.active[p] = cand;
        self.lambda[p] = 0.0;
        let d = self.dim;
        self.u[p * d..(p + 1) * d].copy_from_slice(self.uq);
        self.taus[p * self.s..(p + 1) * self.s].copy_from_slice(self.tau);
        self.n_active = p + 1;
        Some(schur)
    }
}

/// Owned workspace memory, sized once from a problem (allocation happens only here).
#[cfg(feature = "std")]
#[derive(Debug, Clone)]
pub struct WorkspaceStorage {
    floats: std::vec::Vec<f64>,
    active: std::vec::Vec<Active>,
}

#[cfg(feature = "std")]
impl WorkspaceStorage {
    /// Allocate the buffers a solve of `problem` needs.
    pub fn new(problem: &Problem<'_>) -> Self {
        let (nf, na) = problem.workspace_len();
        Self {
            floats: std::vec![0.0; nf],
            active: std::vec![Active::default(); na],
        }
    }

    /// Borrow the buffers as a [`Workspace`] (no allocation). The working set starts empty.
    pub fn workspace(&mut self, problem: &Problem<'_>) -> Result<Workspace<'_>, Error> {
        Workspace::new(problem, &mut self.floats, &mut self.active)
    }
}

/// Result of a solve: status, counters and the current iterate (borrowed from the workspace).
#[derive(Debug)]
pub struct Outcome<'w> {
    /// How the solve ended.
    pub status: Status,
    /// Work counters.
    pub stats: Stats,
    /// Constraint coefficients w = C_z z of the iterate (row k is block k).
    pub w: &'w [f64],
    /// Unconstrained coefficients w0 the solve started from.
    pub w0: &'w [f64],
    /// Working set.
    pub active: &'w [Active],
    /// Multipliers λ ≥ 0 of the working set.
    pub lambda: &'w [f64],
}

impl Outcome<'_> {
    /// Increase of the cost ½zᵀHz over the unconstrained optimum: ½ μᵀ(w0 − w) with
    /// μ = Σ λ_j v_j (since w0 − w = Φ μ).
    pub fn cost_increase(&self, problem: &Problem<'_>, tau: &mut [f64]) -> f64 {
        let s = problem.basis.dim();
        let mut acc = 0.0;
        for (a, lam) in self.active.iter().zip(self.lambda) {
            problem.basis.tau(a.t, tau);
            let blk = a.row * s;
            let dot: f64 = (0..s)
                .map(|p| tau[p] * (self.w0[blk + p] - self.w[blk + p]))
                .sum();
            acc += lam * a.side.sign() * dot;
        }
        0.5 * acc
    }

    /// μ = Σ λ_j σ_j e_{k_j} ⊗ τ(t_j) into `out` (length nc·s), so that z = b̂ − S C_zᵀ μ.
    pub fn multiplier_coefficients(&self, problem: &Problem<'_>, tau: &mut [f64], out: &mut [f64]) {
        let s = problem.basis.dim();
        out.fill(0.0);
        for (a, lam) in self.active.iter().zip(self.lambda) {
            problem.basis.tau(a.t, tau);
            for p in 0..s {
                out[a.row * s + p] += lam * a.side.sign() * tau[p];
            }
        }
    }
}

/// The refined first violation of every row into `ws.cands`, largest excess first; returns
/// how many rows are violated.
fn find_violations(
    problem: &Problem<'_>,
    settings: &Settings,
    warm: bool,
    ws: &mut Workspace<'_>,
    stats: &mut Stats,
) -> Result<usize, ()> {
    let s = ws.s;
    let mut found = 0;
    let scan = stats.iterations
        > if warm {
            settings.scan_after_warm
        } else {
            settings.scan_after_cold
        };
    for (k, row) in problem.rows.iter().enumerate() {
        if row.lower == f64::NEG_INFINITY && row.upper == f64::INFINITY {
            continue;
        }
        let wk = &ws.w[k * s..(k + 1) * s];
        let mut sc = Scratch {
            y: &mut *ws.y,
            y2: &mut *ws.y2,
            s_k: &mut *ws.s_k,
        };
        let res = check_row(
            &problem.basis,
            *row,
            wk,
            settings,
            scan,
            &mut sc,
            &mut stats.taylor_steps,
        );
        match res {
            RowCheck::Satisfied => {}
            RowCheck::StepLimit => return Err(()),
            RowCheck::Violated(v) => {
                let cand = Active {
                    t: v.t,
                    row: k,
                    side: v.side,
                };
                let (t, excess) = if settings.refine {
                    refine(problem, ws, cand, *row)
                } else {
                    (v.t, excess_at(problem, ws, cand, *row, v.t))
                };
                // Insertion by decreasing excess (earliest row first on ties).
                let mut i = found;
                while i > 0 && ws.cand_excess[i - 1] < excess {
                    ws.cands[i] = ws.cands[i - 1];
                    ws.cand_excess[i] = ws.cand_excess[i - 1];
                    i -= 1;
                }
                ws.cands[i] = Active { t, ..cand };
                ws.cand_excess[i] = excess;
                found += 1;
            }
        }
    }
    Ok(found)
}

/// Signed excess σ g(t) − β of candidate `a` at instant `t` (uses `ws.tau`).
fn excess_at(problem: &Problem<'_>, ws: &mut Workspace<'_>, a: Active, row: Row, t: f64) -> f64 {
    let s = ws.s;
    problem.basis.tau(t, ws.tau);
    let g: f64 = ws
        .tau
        .iter()
        .zip(&ws.w[a.row * s..(a.row + 1) * s])
        .map(|(p, q)| p * q)
        .sum();
    match a.side {
        Side::Upper => g - row.upper,
        Side::Lower => row.lower - g,
    }
}

/// A few Newton steps on g'(t) = 0, kept only while the violation grows and t ≥ 0.
fn refine(problem: &Problem<'_>, ws: &mut Workspace<'_>, a: Active, row: Row) -> (f64, f64) {
    let s = ws.s;
    let basis = &problem.basis;
    let wk = &ws.w[a.row * s..(a.row + 1) * s];
    basis.mt_apply(wk, ws.d1);
    basis.mt_apply(ws.d1, ws.d2);
    let mut t = a.t;
    let mut best = excess_at(problem, ws, a, row, t);
    for _ in 0..8 {
        basis.tau(t, ws.tau);
        let g1: f64 = ws.tau.iter().zip(ws.d1.iter()).map(|(p, q)| p * q).sum();
        let g2: f64 = ws.tau.iter().zip(ws.d2.iter()).map(|(p, q)| p * q).sum();
        if g2 == 0.0 {
            break;
        }
        let tn = t - g1 / g2;
        if tn.is_nan() || tn < 0.0 {
            break;
        }
        let e = excess_at(problem, ws, a, row, tn);
        if e > best {
            best = e;
            t = tn;
        } else {
            break;
        }
    }
    (t, best)
}

/// Solve with unconstrained coefficients `w0` (= C_z b̂ = Ψ x0). With `warm`, the working set
/// left in `ws` (e.g. after [`Workspace::shift_active`]) seeds the solve; otherwise it starts
/// empty.
pub fn solve<'w>(
    problem: &Problem<'_>,
    settings: &Settings,
    w0: &[f64],
    warm: bool,
    ws: &'w mut Workspace<'_>,
) -> Result<Outcome<'w>, Error> {
    let d = problem.dim();
    check_len("workspace", ws.dim * ws.cap, d * problem.max_active)?;
    check_len("workspace basis", ws.s, problem.basis.dim())?;
    check_len("w0", w0.len(), d)?;
    if w0.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite { name: "w0" });
    }
    if !settings.tolerance.is_finite() || settings.tolerance <= 0.0 {
        return Err(Error::InvalidParameter {
            name: "tolerance",
            value: settings.tolerance,
            requirement: "finite and > 0",
        });
    }
    if let Some(h) = settings.horizon {
        if h.is_nan() || h <= 0.0 {
            return Err(Error::InvalidParameter {
                name: "horizon",
                value: h,
                requirement: "> 0",
            });
        }
    }
    ws.w0.copy_from_slice(w0);
    let mut stats = Stats::default();
    let status = run(problem, settings, warm, ws, &mut stats);
    let n = ws.n_active;
    Ok(Outcome {
        status,
        stats,
        w: &ws.w[..],
        w0: &ws.w0[..],
        active: &ws.active[..n],
        lambda: &ws.lambda[..n],
    })
}

/// Seed the working set from the warm-start list: keep independent instants, then drop
/// negative multipliers one at a time until the equality-constrained solution is dual feasible.
fn seed(problem: &Problem<'_>, settings: &Settings, ws: &mut Workspace<'_>, stats: &mut Stats) {
    let candidates = ws.n_active;
    ws.n_active = 0;
    for i in 0..candidates {
        let a = ws.active[i];
        if a.row >= problem.rows.len() || !a.t.is_finite() || a.t < 0.0 {
            continue;
        }
        problem.basis.tau(a.t, ws.tau);
        problem.phi_v(a.row, a.side.sign(), ws.tau, ws.uq);
        // `try_append` writes slot n_active <= i, so unread candidates survive.
        if ws
            .try_append(a, settings.dependence_tol, problem.phi_scale)
            .is_none()
        {
            stats.drops += 1;
        }
    }
    loop {
        let p = ws.n_active;
        if p == 0 {
            break;
        }
        for j in 0..p {
            let a = ws.active[j];
            ws.lambda[j] = ws.v_dot(j, ws.w0) - problem.beta(&a);
        }
        ws.chol.forward(p, ws.lambda);
        ws.chol.backward(p, ws.lambda);
        let (jmin, lmin) =
            ws.lambda[..p]
                .iter()
                .enumerate()
                .fold(
                    (0, f64::INFINITY),
                    |acc, (j, &l)| if l < acc.1 { (j, l) } else { acc },
                );
        if lmin >= 0.0 {
            break;
        }
        ws.remove(jmin);
        stats.drops += 1;
    }
    let d = ws.dim;
    ws.w.copy_from_slice(ws.w0);
    for j in 0..ws.n_active {
        let lam = ws.lambda[j];
        for (wi, ui) in ws.w.iter_mut().zip(&ws.u[j * d..(j + 1) * d]) {
            *wi -= lam * ui;
        }
    }
}

fn run(
    problem: &Problem<'_>,
    settings: &Settings,
    warm: bool,
    ws: &mut Workspace<'_>,
    stats: &mut Stats,
) -> Status {
    if !warm {
        ws.n_active = 0;
    }
    seed(problem, settings, ws, stats);
    for _ in 0..settings.max_iter {
        stats.iterations += 1;
        let found = match find_violations(problem, settings, warm, ws, stats) {
            Err(()) => return Status::CheckStepLimit,
            Ok(0) => return Status::Optimal,
            Ok(n) => n,
        };
        // Every violated row's instant is added in this iteration (a block): one check
        // serves several dual steps. Later candidates are re-evaluated against the updated
        // iterate and skipped once satisfied.
        for i in 0..found {
            let q = ws.cands[i];
            let mut cq = ws.cand_excess[i];
            if i > 0 {
                cq = excess_at(problem, ws, q, problem.rows[q.row], q.t);
                if cq <= 0.5 * settings.tolerance {
                    continue;
                }
            }
            let duplicate = ws.active[..ws.n_active]
                .iter()
                .any(|a| a.row == q.row && a.side == q.side && fmath::abs(a.t - q.t) < 1e-9);
            if duplicate {
                if i == 0 {
                    return Status::Optimal;
                }
                continue;
            }
            if let Err(status) = add(problem, settings, ws, stats, q, cq) {
                return status;
            }
        }
    }
    Status::IterationLimit
}

/// One dual step that adds instant `q` (excess `cq` > 0), dropping blocking instants.
fn add(
    problem: &Problem<'_>,
    settings: &Settings,
    ws: &mut Workspace<'_>,
    stats: &mut Stats,
    q: Active,
    mut cq: f64,
) -> Result<(), Status> {
    let d = ws.dim;
    let s = ws.s;
    problem.basis.tau(q.t, ws.tau);
    problem.phi_v(q.row, q.side.sign(), ws.tau, ws.uq);
    let sign = q.side.sign();
    let vqu: f64 = sign
        * ws.tau
            .iter()
            .zip(&ws.uq[q.row * s..(q.row + 1) * s])
            .map(|(a, b)| a * b)
            .sum::<f64>();
    // Absolute floor of the dependence test: a row fixed by the equalities (e.g. the
    // state at t = 0) has v_qᵀΦv_q at rounding level, not exactly zero.
    let tau2: f64 = ws.tau.iter().map(|x| x * x).sum();
    let dep_floor = settings.dependence_tol * vqu.max(problem.phi_scale * tau2);
    let mut theta_acc = 0.0;
    loop {
        let p = ws.n_active;
        for j in 0..p {
            ws.r[j] = ws.v_dot(j, ws.uq);
        }
        ws.b[..p].copy_from_slice(&ws.r[..p]);
        ws.chol.forward(p, ws.r);
        ws.chol.backward(p, ws.r);
        ws.dw.copy_from_slice(ws.uq);
        for j in 0..p {
            let rj = ws.r[j];
            for (x, u) in ws.dw.iter_mut().zip(&ws.u[j * d..(j + 1) * d]) {
                *x -= rj * u;
            }
        }
        let kappa: f64 = sign
            * ws.tau
                .iter()
                .zip(&ws.dw[q.row * s..(q.row + 1) * s])
                .map(|(a, b)| a * b)
                .sum::<f64>();
        let dependent = p >= ws.cap || kappa.is_nan() || kappa <= dep_floor;
        let theta_f = if dependent { f64::INFINITY } else { cq / kappa };
        let mut theta_p = f64::INFINITY;
        let mut jstar = usize::MAX;
        for j in 0..p {
            if ws.r[j] > 0.0 {
                let ratio = ws.lambda[j] / ws.r[j];
                if ratio < theta_p {
                    theta_p = ratio;
                    jstar = j;
                }
            }
        }
        if theta_f == f64::INFINITY && theta_p == f64::INFINITY {
            return Err(Status::Infeasible);
        }
        let theta = theta_f.min(theta_p);
        for (x, dx) in ws.w.iter_mut().zip(ws.dw.iter()) {
            *x -= theta * dx;
        }
        for j in 0..p {
            ws.lambda[j] -= theta * ws.r[j];
        }
        theta_acc += theta;
        cq -= theta * kappa;
        if theta_f <= theta_p {
            // Bordered Cholesky update with l = L⁻¹ b and Schur complement κ.
            ws.l[..p].copy_from_slice(&ws.b[..p]);
            ws.chol.forward(p, ws.l);
            ws.chol.append(p, ws.l, kappa);
            ws.active[p] = q;
            ws.lambda[p] = theta_acc;
            ws.u[p * d..(p + 1) * d].copy_from_slice(ws.uq);
            ws.taus[p * s..(p + 1) * s].copy_from_slice(ws.tau);
            ws.n_active = p + 1;
            stats.adds += 1;
            polish::polish(problem, settings, ws, stats);
            return Ok(());
        }
        ws.lambda[jstar] = 0.0;
        ws.remove(jstar);
        stats.drops += 1;
    }
}

#[cfg(test)]
mod tests;
