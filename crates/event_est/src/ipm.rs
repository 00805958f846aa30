//! Primal-dual interior-point method for LMI problems with a few thousand variables and
//! blocks of medium size, in Schur-complement form (HKM direction, Mehrotra predictor-corrector).
//!
//! Why a second solver: Clarabel's KKT system carries one dense svec(k)² block per k×k PSD
//! cone. The Cor 13 design of the 20-vehicle platoon has 23 cones of size 78–79 (each block
//! 3081² ≈ 9.5 M entries) and its factorisation dominates every iteration, so the direct
//! formulation needs hours. The LMI form G(x) = G_0 + Σ_i x_i G_i ⪰ 0 is the dual of a standard
//! SDP; forming the m×m Schur complement M_ij = ⟨A_i, X A_j Z^{-1}⟩ (m = number of variables)
//! like SDPT3 and CSDP do costs O(nnz · m) per block because every coefficient matrix A_i has
//! rank ≤ 6 (a variable touches a few rows/columns of an LMI), and the dense m×m Cholesky
//! runs on faer.
//!
//! Standard form: (primal) min ⟨C, X⟩ s.t. ⟨A_i, X⟩ = b_i, X ⪰ 0; (dual) max bᵀy s.t.
//! Z = C − Σ_i y_i A_i ⪰ 0. An LMI problem min qᵀx s.t. G_l(x) ⪰ ε_l I maps to y = x,
//! A_i = −G_i, C = G_0 − ε I, b = −q.
//!
//! ```
//! use event_est::ipm::Solver;
//! use event_est::lmi::{Problem, Vars};
//! // minimise t subject to [[t, 1], [1, t]] ⪰ 0, optimum t = 1.
//! let mut vars = Vars::default();
//! let t = vars.scalar();
//! let mut prob = Problem::new(vars);
//! let lmi = prob.lmi("[[t,1],[1,t]] ⪰ 0", 2);
//! lmi.add_scalar_identity(t, 0, 2, 1.0);
//! lmi.add_const(0, 1, &nalgebra::DMatrix::from_element(1, 1, 1.0));
//! prob.objective[t.index(0, 0)] = 1.0;
//! let sol = prob.solve_with(Solver::SchurIpm, "example", 0.0).unwrap();
//! assert!((sol.x[t.index(0, 0)] - 1.0).abs() < 1e-6);
//! ```

use crate::error::EventEstError;
use crate::linalg::min_eigenvalue;
use crate::lmi::Problem;
use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};
use nalgebra::{DMatrix, DVector};
use std::time::Instant;

/// SDP solver behind [`Problem::solve_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Solver {
    /// Clarabel (direct KKT factorisation); fastest for small problems.
    #[default]
    Clarabel,
    /// The Schur-complement interior-point method of this module; for problems with many
    /// variables and PSD blocks of size ≳ 30 (e.g. Cor 13 with ≥ 8 vehicles).
    SchurIpm,
}

impl Solver {
    /// The faster solver for a system of `n` states: Clarabel up to 10 states, the
    /// Schur-complement method above (6 or more platoon vehicles, where Clarabel's KKT blocks of
    /// the vertex LMIs take seconds to hours; see the README's synthesis times).
    pub fn for_states(n: usize) -> Self {
        if n > 10 {
            Self::SchurIpm
        } else {
            Self::Clarabel
        }
    }

    /// Parses "clarabel" or "schur".
    pub fn parse(s: &str) -> Result<Self, EventEstError> {
        match s.to_ascii_lowercase().as_str() {
            "clarabel" => Ok(Self::Clarabel),
            "schur" | "schur_ipm" => Ok(Self::SchurIpm),
            _ => Err(EventEstError::Name {
                what: "solver",
                given: s.to_string(),
                reason: "unknown; known: clarabel, schur",
            }),
        }
    }
}

/// Iteration limit.
const MAX_ITER: usize = 100;
/// Relative gap and infeasibility accepted as `Solved`.
const TOL: f64 = 1e-8;
/// Accepted as `AlmostSolved` when progress stalls or the iteration limit is hit.
const TOL_ALMOST: f64 = 1e-6;
/// Passes of the equilibration.
const EQUILIBRATION_PASSES: usize = 4;
/// |A(X)|/|⟨C, X⟩| below which X certifies infeasibility.
const INFEASIBILITY_TOL: f64 = 1e-8;
/// Weight of the primal residual in the `AlmostSolved` test.
const PRIMAL_WEIGHT: f64 = 1e-2;
/// Iterations without a smaller residual before the iteration stops.
const STALL: usize = 5;

/// What [`solve`] returns before the caller's eigenvalue post-verification.
pub(crate) struct Outcome {
    /// y = x.
    pub x: Vec<f64>,
    /// "Solved" or "AlmostSolved".
    pub status: &'static str,
    /// Iterations.
    pub iterations: u32,
    /// Wall-clock time in seconds.
    pub solve_time: f64,
}

/// One coefficient matrix A_i restricted to a block, as a sum of symmetrised rank-one terms
/// Σ_g (e_g w_gᵀ + w_g e_gᵀ) (the low-rank form that makes X A_i Z^{-1} cheap) and as the list
/// of its upper-triangle entries (for inner products).
struct Coefficient {
    var: usize,
    entries: Vec<(usize, usize, f64)>,
    groups: Vec<(usize, Vec<(usize, f64)>)>,
}

impl Coefficient {
    fn new(var: usize, entries: Vec<(usize, usize, f64)>) -> Self {
        // Assign each entry (a, b) to whichever index occurs more often in this matrix, so that
        // a row of P·A or a column of Ã·Q becomes one group.
        let mut count = std::collections::HashMap::<usize, usize>::new();
        for &(a, b, _) in &entries {
            *count.entry(a).or_default() += 1;
            if a != b {
                *count.entry(b).or_default() += 1;
            }
        }
        let mut groups: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
        for &(a, b, v) in &entries {
            let (g, other, w) = if a == b {
                (a, a, 0.5 * v)
            } else if count[&b] > count[&a] {
                (b, a, v)
            } else {
                (a, b, v)
            };
            match groups.iter_mut().find(|(h, _)| *h == g) {
                Some((_, w_g)) => w_g.push((other, w)),
                None => groups.push((g, vec![(other, w)])),
            }
        }
        Self {
            var,
            entries,
            groups,
        }
    }

    /// ‖A_i‖_F.
    fn norm(&self) -> f64 {
        self.entries
            .iter()
            .map(|&(a, b, v)| if a == b { v * v } else { 2.0 * v * v })
            .sum::<f64>()
            .sqrt()
    }

    /// A_i ← f A_i.
    fn scale(&mut self, f: f64) {
        for e in &mut self.entries {
            e.2 *= f;
        }
        for (_, w) in &mut self.groups {
            for e in w {
                e.1 *= f;
            }
        }
    }

    /// ⟨A_i, G⟩ for a symmetric G.
    fn inner(&self, g: &DMatrix<f64>) -> f64 {
        self.entries
            .iter()
            .map(|&(a, b, v)| {
                if a == b {
                    v * g[(a, a)]
                } else {
                    2.0 * v * g[(a, b)]
                }
            })
            .sum()
    }
}

/// One LMI block in standard form: Z = C − Σ_i y_i A_i ⪰ 0.
struct Block {
    dim: usize,
    c: DMatrix<f64>,
    coeffs: Vec<Coefficient>,
}

impl Block {
    /// Σ_i y_i A_i.
    fn adjoint(&self, y: &[f64]) -> DMatrix<f64> {
        let mut s = DMatrix::zeros(self.dim, self.dim);
        for co in &self.coeffs {
            let yi = y[co.var];
            if yi == 0.0 {
                continue;
            }
            for &(a, b, v) in &co.entries {
                s[(a, b)] += v * yi;
                if a != b {
                    s[(b, a)] += v * yi;
                }
            }
        }
        s
    }

    /// Adds ⟨A_i, G⟩ to out[i] (G symmetric).
    fn apply(&self, g: &DMatrix<f64>, out: &mut [f64]) {
        for co in &self.coeffs {
            out[co.var] += co.inner(g);
        }
    }

    /// Adds this block's part of the Schur complement M_ij = ⟨A_i, X A_j Z^{-1}⟩ (upper triangle).
    fn schur(&self, x: &DMatrix<f64>, zi: &DMatrix<f64>, m: &mut Mat<f64>) {
        let k = self.dim;
        let nv = self.coeffs.len();
        let mut g = DMatrix::<f64>::zeros(k, k);
        let mut xw = DVector::<f64>::zeros(k);
        let mut ziw = DVector::<f64>::zeros(k);
        // G_j = X A_j Z^{-1} for a chunk of SCHUR_CHUNK columns j, stored by upper-triangle
        // position p(a, b) (row p holds G_ab + G_ba, or G_aa on the diagonal, for every j of the
        // chunk), so that ⟨A_i, G_j⟩ for the whole chunk is one contiguous axpy per entry of A_i.
        let mut buf = vec![0.0; k * (k + 1) / 2 * SCHUR_CHUNK];
        let mut acc = [0.0; SCHUR_CHUNK];
        for j0 in (0..nv).step_by(SCHUR_CHUNK) {
            let jn = (nv - j0).min(SCHUR_CHUNK);
            for (t, cj) in self.coeffs[j0..j0 + jn].iter().enumerate() {
                g.fill(0.0);
                for (e, w) in &cj.groups {
                    xw.fill(0.0);
                    ziw.fill(0.0);
                    for &(r, v) in w {
                        xw.axpy(v, &x.column(r), 1.0);
                        ziw.axpy(v, &zi.column(r), 1.0);
                    }
                    // X (e wᵀ + w eᵀ) Z^{-1} = (X e)(Z^{-1} w)ᵀ + (X w)(Z^{-1} e)ᵀ.
                    g.ger(1.0, &x.column(*e), &ziw, 1.0);
                    g.ger(1.0, &xw, &zi.column(*e), 1.0);
                }
                for b in 0..k {
                    for a in 0..b {
                        buf[position(a, b) * SCHUR_CHUNK + t] = g[(a, b)] + g[(b, a)];
                    }
                    buf[position(b, b) * SCHUR_CHUNK + t] = g[(b, b)];
                }
            }
            // ⟨A_i, G_j⟩ for i ≤ j (each unordered pair once; local order is variable order).
            for (i, ci) in self.coeffs[..j0 + jn].iter().enumerate() {
                acc.fill(0.0);
                for &(a, b, v) in &ci.entries {
                    let row = &buf[position(a, b) * SCHUR_CHUNK..][..SCHUR_CHUNK];
                    for (s, r) in acc.iter_mut().zip(row) {
                        *s += v * r;
                    }
                }
                for (t, cj) in self.coeffs[j0..j0 + jn].iter().enumerate() {
                    if i <= j0 + t {
                        m[(ci.var, cj.var)] += acc[t];
                    }
                }
            }
        }
    }
}

/// Columns of the Schur complement formed together (the chunk of G_j stays in cache).
const SCHUR_CHUNK: usize = 32;

/// Index of the upper-triangle entry (a, b), a ≤ b, in column-major order.
fn position(a: usize, b: usize) -> usize {
    b * (b + 1) / 2 + a
}

/// Ruiz equilibration: variables y_i = d_i ỹ_i and blocks scaled by s_l > 0 (neither changes
/// the feasible set) until every ‖A_i‖ and every block's largest coefficient are near 1.
/// Returns d.
fn equilibrate(blocks: &mut [Block], m: usize) -> Vec<f64> {
    let mut d = vec![1.0; m];
    for _ in 0..EQUILIBRATION_PASSES {
        let mut col = vec![0.0f64; m];
        for bl in blocks.iter() {
            for co in &bl.coeffs {
                col[co.var] = col[co.var].max(co.norm());
            }
        }
        let f: Vec<f64> = col
            .iter()
            .map(|&c| if c > 0.0 { 1.0 / c.sqrt() } else { 1.0 })
            .collect();
        for bl in blocks.iter_mut() {
            for co in &mut bl.coeffs {
                co.scale(f[co.var]);
            }
        }
        for (di, fi) in d.iter_mut().zip(&f) {
            *di *= fi;
        }
        for bl in blocks.iter_mut() {
            let r = bl.coeffs.iter().map(Coefficient::norm).fold(0.0, f64::max);
            if r > 0.0 {
                let s = 1.0 / r.sqrt();
                for co in &mut bl.coeffs {
                    co.scale(s);
                }
                bl.c *= s;
            }
        }
    }
    d
}

/// Names of the LMIs whose block of the Farkas certificate X has weight above 1e-6 of the
/// largest: these conditions cannot hold together.
fn certificate_support(prob: &Problem, x: &[DMatrix<f64>]) -> String {
    let max = x.iter().map(|xl| xl.norm()).fold(0.0, f64::max);
    let names: Vec<&str> = prob
        .lmis
        .iter()
        .zip(x)
        .filter(|(_, xl)| xl.norm() > 1e-6 * max)
        .map(|(l, _)| l.name.as_str())
        .collect();
    format!("no solution satisfies together: {}", names.join("; "))
}

/// Largest α ≤ `cap` with S + α dS ⪰ 0 (S ≻ 0).
fn step_to_boundary(s: &DMatrix<f64>, ds: &DMatrix<f64>, cap: f64) -> f64 {
    let Some(ch) = s.clone().cholesky() else {
        return 0.0;
    };
    let l = ch.l();
    let Some(w) = l.solve_lower_triangular(ds) else {
        return 0.0;
    };
    let Some(t) = l.solve_lower_triangular(&w.transpose()) else {
        return 0.0;
    };
    let t = (&t + t.transpose()) * 0.5;
    let lam = min_eigenvalue(&t);
    if lam < 0.0 {
        (-1.0 / lam).min(cap)
    } else {
        cap
    }
}

/// Cholesky factor of the Schur complement, with a diagonal shift that grows from 1e-14 to
/// 1e-8 of the largest diagonal entry when round-off near the optimum breaks definiteness.
fn factor(schur: &mut Mat<f64>) -> Option<Llt<f64>> {
    let m = schur.nrows();
    let max_diag = (0..m).map(|i| schur[(i, i)].abs()).fold(0.0, f64::max);
    let mut shift = 0.0;
    for exponent in [-14, -12, -10, -8] {
        let next = 10f64.powi(exponent) * max_diag.max(1e-300);
        for i in 0..m {
            schur[(i, i)] += next - shift;
        }
        shift = next;
        if let Ok(llt) = schur.llt(Side::Lower) {
            return Some(llt);
        }
    }
    None
}

fn sym(m: &DMatrix<f64>) -> DMatrix<f64> {
    (m + m.transpose()) * 0.5
}

fn dot(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    a.dot(b)
}

/// State of the iteration: one (X_l, Z_l) per block, y.
struct Iterate {
    x: Vec<DMatrix<f64>>,
    z: Vec<DMatrix<f64>>,
    y: Vec<f64>,
}

/// Solves `prob` with every LMI tightened to G_l(x) ⪰ ε_l I (`eps` unless the LMI has its own
/// margin). The caller post-verifies the returned x by eigenvalues.
pub(crate) fn solve(
    prob: &Problem,
    problem: &'static str,
    eps: f64,
) -> Result<Outcome, EventEstError> {
    let start = Instant::now();
    let m = prob.vars.len();
    let b: Vec<f64> = prob.objective.iter().map(|q| -q).collect();
    let mut blocks: Vec<Block> = prob
        .lmis
        .iter()
        .map(|lmi| {
            let k = lmi.dim();
            let mut c = lmi.constant_full();
            let e = lmi.margin_or(eps);
            for i in 0..k {
                c[(i, i)] -= e;
            }
            let mut by_var = std::collections::BTreeMap::<usize, Vec<(usize, usize, f64)>>::new();
            for &(var, i, j, v) in lmi.terms() {
                by_var.entry(var).or_default().push((i, j, -v));
            }
            let coeffs = by_var
                .into_iter()
                .map(|(var, mut entries)| {
                    // Merge repeated entries of one variable.
                    entries.sort_by_key(|p| (p.0, p.1));
                    let mut merged: Vec<(usize, usize, f64)> = Vec::with_capacity(entries.len());
                    for (a, b2, v) in entries {
                        match merged.last_mut() {
                            Some(last) if last.0 == a && last.1 == b2 => last.2 += v,
                            _ => merged.push((a, b2, v)),
                        }
                    }
                    Coefficient::new(var, merged)
                })
                .collect();
            Block { dim: k, c, coeffs }
        })
        .collect();
    let d = equilibrate(&mut blocks, m);
    let b: Vec<f64> = b.iter().zip(&d).map(|(bi, di)| bi * di).collect();
    let total_dim: usize = blocks.iter().map(|bl| bl.dim).sum();
    if total_dim == 0 || m == 0 {
        return Err(EventEstError::Solver {
            problem,
            status: "empty problem (no LMI or no variable)".into(),
        });
    }
    // Infeasible starting point of SDPT3: X = ξ I, Z = η I per block.
    let mut col_norm = vec![0.0f64; m];
    for bl in &blocks {
        for co in &bl.coeffs {
            let f2: f64 = co
                .entries
                .iter()
                .map(|&(a, b2, v)| if a == b2 { v * v } else { 2.0 * v * v })
                .sum();
            col_norm[co.var] += f2;
        }
    }
    let b_ratio = b
        .iter()
        .zip(&col_norm)
        .map(|(bi, n2)| (1.0 + bi.abs()) / (1.0 + n2.sqrt()))
        .fold(0.0, f64::max);
    let mut it = Iterate {
        x: Vec::with_capacity(blocks.len()),
        z: Vec::with_capacity(blocks.len()),
        y: vec![0.0; m],
    };
    for bl in &blocks {
        let k = bl.dim as f64;
        let max_a = bl
            .coeffs
            .iter()
            .map(|co| {
                co.entries
                    .iter()
                    .map(|&(a, b2, v)| if a == b2 { v * v } else { 2.0 * v * v })
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        let xi = 10f64.max(k.sqrt()).max(k * b_ratio);
        let eta = 10f64.max(k.sqrt()).max(max_a).max(bl.c.norm());
        it.x.push(DMatrix::identity(bl.dim, bl.dim) * xi);
        it.z.push(DMatrix::identity(bl.dim, bl.dim) * eta);
    }
    let b_norm = b.iter().map(|v| v * v).sum::<f64>().sqrt();
    let c_norm = blocks
        .iter()
        .map(|bl| bl.c.norm_squared())
        .sum::<f64>()
        .sqrt();
    let mut best: Option<(f64, Vec<f64>)> = None;
    let (mut since_best, mut iterations) = (0, 0);
    for iter in 0..MAX_ITER {
        // Residuals.
        let mut ax = vec![0.0; m];
        let mut rd = Vec::with_capacity(blocks.len());
        let mut xz = 0.0;
        let mut pobj = 0.0;
        for (l, bl) in blocks.iter().enumerate() {
            bl.apply(&it.x[l], &mut ax);
            rd.push(&bl.c - &it.z[l] - bl.adjoint(&it.y));
            xz += dot(&it.x[l], &it.z[l]);
            pobj += dot(&bl.c, &it.x[l]);
        }
        // Farkas certificate of an infeasible LMI: X ⪰ 0 with A(X) ≈ 0 and ⟨C, X⟩ < 0, so that
        // ⟨C − A*(y), X⟩ < 0 (no Z ⪰ 0) for every y with |y| < |⟨C, X⟩|/|A(X)|.
        let ax_norm = ax.iter().map(|v| v * v).sum::<f64>().sqrt();
        if pobj < 0.0 && ax_norm < INFEASIBILITY_TOL * -pobj {
            return Err(EventEstError::Infeasible {
                problem,
                status: format!("Schur IPM Farkas certificate, iteration {iter}"),
                condition: certificate_support(prob, &it.x),
            });
        }
        let rp: Vec<f64> = b.iter().zip(&ax).map(|(bi, a)| bi - a).collect();
        let dobj: f64 = b.iter().zip(&it.y).map(|(bi, yi)| bi * yi).sum();
        let pinf = rp.iter().map(|v| v * v).sum::<f64>().sqrt() / (1.0 + b_norm);
        let dinf = rd.iter().map(|r| r.norm_squared()).sum::<f64>().sqrt() / (1.0 + c_norm);
        let gap = xz.abs() / (1.0 + pobj.abs() + dobj.abs());
        let err = gap.max(pinf).max(dinf);
        // The returned y is only ever used through Z = C − A*(y) ⪰ 0 (re-checked by
        // eigenvalues); the primal residual only weakens the optimality certificate, so it
        // counts 100× less for `AlmostSolved`.
        let err_almost = gap.max(dinf).max(pinf * PRIMAL_WEIGHT);
        if err < TOL {
            return Ok(Outcome {
                x: it.y.iter().zip(&d).map(|(y, di)| y * di).collect(),
                status: "Solved",
                iterations: iter as u32,
                solve_time: start.elapsed().as_secs_f64(),
            });
        }
        if best.as_ref().is_none_or(|(e, _)| err_almost < *e) {
            best = Some((err_almost, it.y.clone()));
            since_best = 0;
        } else {
            // Round-off in the ill-conditioned Schur complement ends the progress near the
            // optimum: stop once the residuals have not improved for a few iterations.
            since_best += 1;
            if since_best > STALL && best.as_ref().is_some_and(|(e, _)| *e < TOL_ALMOST) {
                break;
            }
        }
        iterations = iter as u32 + 1;
        let mu = xz / total_dim as f64;
        // Inverses and the Schur complement.
        let mut zi = Vec::with_capacity(blocks.len());
        for z in &it.z {
            let ch = z.clone().cholesky().ok_or(EventEstError::Solver {
                problem,
                status: format!("NumericalError (dual slack lost definiteness, iteration {iter})"),
            })?;
            zi.push(ch.inverse());
        }
        let mut schur = Mat::<f64>::zeros(m, m);
        for (l, bl) in blocks.iter().enumerate() {
            bl.schur(&it.x[l], &zi[l], &mut schur);
        }
        for j in 0..m {
            for i in 0..j {
                schur[(j, i)] = schur[(i, j)];
            }
        }
        let Some(llt) = factor(&mut schur) else {
            break;
        };
        // Right-hand side M dy = b − A(σμ Z^{-1}) + A(X R_d Z^{-1}) + A(corr).
        let base: Vec<DMatrix<f64>> = (0..blocks.len())
            .map(|l| sym(&(&it.x[l] * &rd[l] * &zi[l])))
            .collect();
        let direction = |sigma_mu: f64,
                         corr: Option<&Vec<DMatrix<f64>>>|
         -> (Vec<f64>, Vec<DMatrix<f64>>, Vec<DMatrix<f64>>) {
            let mut rhs = b.clone();
            for (l, bl) in blocks.iter().enumerate() {
                let mut t = &base[l] - &zi[l] * sigma_mu;
                if let Some(c) = corr {
                    t += &c[l];
                }
                bl.apply(&t, &mut rhs);
            }
            let mut col = Mat::<f64>::from_fn(m, 1, |i, _| rhs[i]);
            llt.solve_in_place(col.as_mut());
            let dy: Vec<f64> = (0..m).map(|i| col[(i, 0)]).collect();
            let mut dxs = Vec::with_capacity(blocks.len());
            let mut dzs = Vec::with_capacity(blocks.len());
            for (l, bl) in blocks.iter().enumerate() {
                let dz = &rd[l] - bl.adjoint(&dy);
                let mut dx = &zi[l] * sigma_mu - &it.x[l] - sym(&(&it.x[l] * &dz * &zi[l]));
                if let Some(c) = corr {
                    dx -= &c[l];
                }
                dxs.push(dx);
                dzs.push(dz);
            }
            (dy, dxs, dzs)
        };
        let steps = |dxs: &[DMatrix<f64>], dzs: &[DMatrix<f64>], cap: f64| {
            let mut ap = cap;
            let mut ad = cap;
            for l in 0..blocks.len() {
                ap = step_to_boundary(&it.x[l], &dxs[l], ap);
                ad = step_to_boundary(&it.z[l], &dzs[l], ad);
            }
            (ap, ad)
        };
        // Predictor.
        let (_, dxa, dza) = direction(0.0, None);
        let (ap, ad) = steps(&dxa, &dza, 1.0);
        let mut xz_aff = 0.0;
        for l in 0..blocks.len() {
            xz_aff += dot(&(&it.x[l] + &dxa[l] * ap), &(&it.z[l] + &dza[l] * ad));
        }
        let expon = (3.0 * ap.min(ad).powi(2)).max(1.0);
        let sigma = (xz_aff / xz).max(0.0).powf(expon).min(1.0);
        // Corrector with the second-order term sym(dX_a dZ_a Z^{-1}).
        let corr: Vec<DMatrix<f64>> = (0..blocks.len())
            .map(|l| sym(&(&dxa[l] * &dza[l] * &zi[l])))
            .collect();
        let (dy, dx, dz) = direction(sigma * mu, Some(&corr));
        let (ap_max, ad_max) = steps(&dx, &dz, f64::INFINITY);
        let tau = 0.9 + 0.09 * ap.min(ad);
        let ap = (tau * ap_max).min(1.0);
        let ad = (tau * ad_max).min(1.0);
        if ap < 1e-10 && ad < 1e-10 {
            break;
        }
        for l in 0..blocks.len() {
            it.x[l] += &dx[l] * ap;
            it.z[l] += &dz[l] * ad;
        }
        for (yi, d) in it.y.iter_mut().zip(&dy) {
            *yi += ad * d;
        }
    }
    match best {
        Some((err, y)) if err < TOL_ALMOST => Ok(Outcome {
            x: y.iter().zip(&d).map(|(y, di)| y * di).collect(),
            status: "AlmostSolved",
            iterations,
            solve_time: start.elapsed().as_secs_f64(),
        }),
        Some((err, _)) => Err(EventEstError::Solver {
            problem,
            status: format!("not converged (best residual {err:.2e})"),
        }),
        None => Err(EventEstError::Solver {
            problem,
            status: "not converged".into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn dense(entries: &[(usize, usize, f64)], k: usize) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(k, k);
        for &(i, j, v) in entries {
            a[(i, j)] += v;
            if i != j {
                a[(j, i)] += v;
            }
        }
        a
    }

    proptest! {
        /// The low-rank groups Σ_g (e_g w_gᵀ + w_g e_gᵀ) reproduce the coefficient matrix, and
        /// the inner product and norm agree with the dense ones.
        #[test]
        fn groups_reproduce_the_coefficient(
            raw in proptest::collection::vec((0usize..7, 0usize..7, -2.0f64..2.0), 1..30),
            g in proptest::collection::vec(-1.0f64..1.0, 49),
        ) {
            let k = 7;
            let mut entries: Vec<(usize, usize, f64)> =
                raw.iter().map(|&(i, j, v)| (i.min(j), i.max(j), v)).collect();
            entries.sort_by_key(|p| (p.0, p.1));
            entries.dedup_by(|p, q| p.0 == q.0 && p.1 == q.1);
            let a = dense(&entries, k);
            let co = Coefficient::new(0, entries);
            let mut b = DMatrix::zeros(k, k);
            for (e, w) in &co.groups {
                for &(r, v) in w {
                    b[(*e, r)] += v;
                    b[(r, *e)] += v;
                }
            }
            prop_assert!((&a - &b).amax() < 1e-12);
            let gm = DMatrix::from_column_slice(k, k, &g);
            let gs = (&gm + gm.transpose()) * 0.5;
            prop_assert!((co.inner(&gs) - a.dot(&gs)).abs() < 1e-10);
            prop_assert!((co.norm() - a.norm()).abs() < 1e-10);
        }

        /// The step to the boundary lands exactly on it: S + α dS is singular and PSD.
        #[test]
        fn step_to_boundary_is_exact(v in proptest::collection::vec(-1.0f64..1.0, 16)) {
            let m = DMatrix::from_column_slice(4, 4, &v);
            let s = &m * m.transpose() + DMatrix::identity(4, 4);
            let ds = -(&s * 2.0) + (&m + m.transpose());
            let alpha = step_to_boundary(&s, &ds, f64::INFINITY);
            prop_assert!(alpha.is_finite() && alpha > 0.0);
            let lam = min_eigenvalue(&(&s + &ds * alpha));
            prop_assert!(lam.abs() < 1e-9 * s.norm(), "λ_min = {lam}");
        }
    }
}
