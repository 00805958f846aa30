//! Offline set-up of the per-step problem (spec/pmpc.md §4.2, §7.3): the upper-bound QP
//!
//! ```text
//! min ½ zᵀHz  s.t.  A_eq z = (0, x0),  lower ≤ τ(t)ᵀ(C_z z)_k ≤ upper  ∀ t ≥ 0
//! ```
//!
//! reduced to constraint-coefficient space by the range-space matrices
//! S = Z(ZᵀHZ)⁻¹Zᵀ (Z a null-space basis of A_eq), G (x0 ↦ equality-only minimiser b̂),
//! Φ = C_z S C_zᵀ, Ψ = C_z G and S C_zᵀ = Y (C_z Y)ᵀ with S = Y Yᵀ (Y = Z L⁻ᵀ, L the Cholesky
//! factor of ZᵀHZ): rank m·s − n, so the plan costs (n+m)s·(n + m·s − n) + nc·s·(m·s − n)
//! multiplications instead of (n+m)s·(n + nc·s). Online work is then a few small mat-vecs.

use crate::constraints::Constraints;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use rigid_body::laguerre::Laguerre;
use rigid_body::siqp;

/// Row-major copy of a matrix, for the allocation-free online mat-vecs.
fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

/// `out = M x` for a row-major `rows × cols` matrix (zero when `cols` is 0).
pub(crate) fn matvec(m: &[f64], cols: usize, x: &[f64], out: &mut [f64]) {
    if cols == 0 {
        out.fill(0.0);
        return;
    }
    for (o, row) in out.iter_mut().zip(m.chunks_exact(cols)) {
        *o = row.iter().zip(x).map(|(a, b)| a * b).sum();
    }
}

/// The parametrized infinite-horizon problem of one system, with all offline matrices.
#[derive(Debug, Clone)]
pub struct Problem {
    n: usize,
    m: usize,
    basis: Laguerre,
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    constraints: Constraints,
    h: DMatrix<f64>,
    aeq: DMatrix<f64>,
    cz: DMatrix<f64>,
    rows: Vec<siqp::Row>,
    phi: Vec<f64>,
    psi: Vec<f64>,
    /// [G, −Y], (n+m)s × (n + dof) row-major, with Y = Z L⁻ᵀ (S = Y Yᵀ): the plan is
    /// [G, −Y] (x, (C_z Y)ᵀμ).
    g_y: Vec<f64>,
    /// (C_z Y)ᵀ, dof × nc·s row-major.
    cy_t: Vec<f64>,
    dof: usize,
}

impl Problem {
    /// Build H, A_eq, C_z and the range-space matrices for `ẋ = Ax + Bu`, cost
    /// ½∫(xᵀQx + uᵀRu)dt and the stage constraints, in the span of `basis`.
    pub fn new(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        q: &DMatrix<f64>,
        r: &DMatrix<f64>,
        constraints: &Constraints,
        basis: Laguerre,
    ) -> Result<Self> {
        let n = a.nrows();
        if n == 0 || a.ncols() != n {
            return Err(Error::Shape {
                name: "A",
                rows: a.nrows(),
                cols: a.ncols(),
                expected_rows: a.nrows().max(1),
                expected_cols: a.nrows().max(1),
            });
        }
        let m = b.ncols();
        crate::check_shape("B", b, n, m.max(1))?;
        crate::check_shape("Q", q, n, n)?;
        crate::check_shape("R", r, m, m)?;
        for (name, mat) in [("A", a), ("B", b), ("Q", q), ("R", r)] {
            crate::check_finite(name, mat.as_slice())?;
        }
        for (name, mat) in [("Q", q), ("R", r)] {
            let asym = (mat - mat.transpose()).amax();
            if asym > 1e-12 * mat.amax().max(1.0) || mat.clone().cholesky().is_none() {
                return Err(Error::NotPositiveDefinite(name));
            }
        }
        constraints.validate(n, m)?;
        let s = basis.dim();
        let nc = constraints.len();
        let big_n = (n + m).saturating_mul(s);
        crate::check_dense_size("decision variables (n+m)*s", big_n, crate::MAX_VARIABLES, 8)?;
        let p = n * s + n;

        let mut h = DMatrix::zeros(big_n, big_n);
        let is = DMatrix::<f64>::identity(s, s);
        h.view_mut((0, 0), (n * s, n * s))
            .copy_from(&q.kronecker(&is));
        h.view_mut((n * s, n * s), (m * s, m * s))
            .copy_from(&r.kronecker(&is));

        let mut buf = vec![0.0; p * big_n];
        basis.equality_matrix(n, m, &row_major(a), &row_major(b), &mut buf)?;
        let aeq = DMatrix::from_row_slice(p, big_n, &buf);
        let mut buf = vec![0.0; nc * s * big_n];
        basis.stage_matrix(
            n,
            m,
            &row_major(&constraints.cx),
            &row_major(&constraints.cu),
            &mut buf,
        )?;
        let cz = DMatrix::from_row_slice(nc * s, big_n, &buf);

        // Full row rank of A_eq, a null-space basis Z and the pseudo-inverse, from faer's full
        // SVD A_eq = U Σ Vᵀ (Z = the last (n+m)s − p columns of V). nalgebra's SVD of this wide
        // matrix can return singular vectors that do not recompose it (error 5e-4 seen).
        if p > big_n {
            return Err(Error::TooFewBasisFunctions { s, n, m });
        }
        let svd = faer::Mat::<f64>::from_fn(p, big_n, |i, j| aeq[(i, j)])
            .svd()
            .map_err(|e| Error::Solver {
                solver: "SVD of the equality constraints",
                status: format!("{e:?}"),
            })?;
        let sigma: Vec<f64> = (0..p).map(|i| svd.S().column_vector()[i]).collect();
        let smax = sigma.iter().copied().fold(0.0, f64::max);
        let smin = sigma.iter().copied().fold(f64::INFINITY, f64::min);
        if smin <= 1e-10 * smax {
            return Err(Error::RankDeficient(if smax > 0.0 {
                smin / smax
            } else {
                0.0
            }));
        }
        let (u, v) = (svd.U(), svd.V());
        // (n+m)s − (ns + n) for a full-rank A_eq.
        let dof = big_n - p;
        let z = DMatrix::from_fn(big_n, dof, |i, j| v[(i, p + j)]);
        let y = if dof == 0 {
            DMatrix::zeros(big_n, 0)
        } else {
            let reduced = z.transpose() * &h * &z;
            let chol = reduced
                .cholesky()
                .ok_or(Error::NotPositiveDefinite("reduced Hessian Z^T H Z"))?;
            // Yᵀ = L⁻¹ Zᵀ; L is invertible because ZᵀHZ is positive definite.
            let yt = chol
                .l()
                .solve_lower_triangular(&z.transpose())
                .ok_or(Error::NotPositiveDefinite("reduced Hessian Z^T H Z"))?;
            yt.transpose()
        };
        let s_mat = &y * y.transpose();
        // Particular solution of A_eq z = (0, x0) by the pseudo-inverse V₁ Σ⁻¹ Uᵀ, projected
        // to the equality-only minimiser: b̂ = (I − S H) A⁺ (0, x0). Only the last n columns
        // of Uᵀ meet (0, x0).
        let pinv_x0 = DMatrix::from_fn(big_n, n, |i, j| {
            (0..p)
                .map(|k| v[(i, k)] / sigma[k] * u[(n * s + j, k)])
                .sum::<f64>()
        });
        let g = (DMatrix::<f64>::identity(big_n, big_n) - &s_mat * &h) * pinv_x0;
        let phi = &cz * &s_mat * cz.transpose();
        let phi = (&phi + phi.transpose()) * 0.5;
        let psi = &cz * &g;
        let cy = &cz * &y;
        let rows = constraints
            .lower
            .iter()
            .zip(&constraints.upper)
            .map(|(&lower, &upper)| siqp::Row { lower, upper })
            .collect();
        Ok(Self {
            n,
            m,
            basis,
            a: a.clone(),
            b: b.clone(),
            q: q.clone(),
            r: r.clone(),
            constraints: constraints.clone(),
            h,
            aeq,
            cz,
            rows,
            phi: row_major(&phi),
            psi: row_major(&psi),
            g_y: row_major(&DMatrix::from_fn(big_n, n + dof, |i, j| {
                if j < n {
                    g[(i, j)]
                } else {
                    -y[(i, j - n)]
                }
            })),
            cy_t: row_major(&cy.transpose()),
            dof,
        })
    }

    /// Number of states n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of inputs m.
    pub fn m(&self) -> usize {
        self.m
    }

    /// The basis.
    pub fn basis(&self) -> &Laguerre {
        &self.basis
    }

    /// Number of decision variables (n+m)s.
    pub fn num_variables(&self) -> usize {
        (self.n + self.m) * self.basis.dim()
    }

    /// Number of equality constraints ns + n.
    pub fn num_equalities(&self) -> usize {
        self.n * self.basis.dim() + self.n
    }

    /// Degrees of freedom left by the equalities, m·s − n.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// The system, weights and constraints this problem was built from.
    pub fn system(
        &self,
    ) -> (
        &DMatrix<f64>,
        &DMatrix<f64>,
        &DMatrix<f64>,
        &DMatrix<f64>,
        &Constraints,
    ) {
        (&self.a, &self.b, &self.q, &self.r, &self.constraints)
    }

    /// H = blkdiag(Q⊗I_s, R⊗I_s).
    pub fn hessian(&self) -> &DMatrix<f64> {
        &self.h
    }

    /// A_eq (rows: Galerkin dynamics, then initial condition).
    pub fn equality_matrix(&self) -> &DMatrix<f64> {
        &self.aeq
    }

    /// b_eq = (0, x0).
    pub fn equality_rhs(&self, x0: &[f64]) -> DVector<f64> {
        let mut v = DVector::zeros(self.num_equalities());
        v.rows_mut(self.n * self.basis.dim(), self.n)
            .copy_from_slice(x0);
        v
    }

    /// C_z = [Cx⊗I_s, Cu⊗I_s].
    pub fn stage_matrix(&self) -> &DMatrix<f64> {
        &self.cz
    }

    /// Constraint rows in solver form.
    pub fn rows(&self) -> &[siqp::Row] {
        &self.rows
    }

    /// The problem in the form the semi-infinite solver takes.
    pub fn siqp(&self) -> Result<siqp::Problem<'_>> {
        Ok(siqp::Problem::new(
            self.basis,
            &self.rows,
            &self.phi,
            self.dof.max(1),
        )?)
    }

    /// Unconstrained constraint coefficients w0 = Ψ x into `out` (length nc·s).
    pub fn unconstrained_coefficients(&self, x: &[f64], out: &mut [f64]) {
        matvec(&self.psi, self.n, x, out);
    }

    /// z = G x − S C_zᵀ μ into `out` (length (n+m)s), from the solver's multiplier
    /// coefficients μ (length nc·s, empty without rows), as [G, −Y] (x, (C_z Y)ᵀμ);
    /// `scratch` has length n + [`Problem::dof`].
    pub fn coefficients(&self, x: &[f64], mu: &[f64], scratch: &mut [f64], out: &mut [f64]) {
        let (xs, reduced) = scratch[..self.n + self.dof].split_at_mut(self.n);
        xs.copy_from_slice(x);
        matvec(&self.cy_t, self.rows.len() * self.basis.dim(), mu, reduced);
        matvec(&self.g_y, self.n + self.dof, scratch, out);
    }

    /// Cost ½ zᵀHz, from the blocks of H = blkdiag(Q⊗I_s, R⊗I_s) (O((n² + m²)s), no
    /// allocation: it runs in every controller step).
    pub fn cost(&self, z: &[f64]) -> f64 {
        let s = self.basis.dim();
        let (x, u) = z.split_at(self.n * s);
        let quad = |w: &DMatrix<f64>, v: &[f64]| -> f64 {
            let k = w.nrows();
            let mut acc = 0.0;
            for i in 0..k {
                for j in 0..k {
                    let wij = w[(i, j)];
                    if wij != 0.0 {
                        let dot: f64 = v[i * s..(i + 1) * s]
                            .iter()
                            .zip(&v[j * s..(j + 1) * s])
                            .map(|(a, b)| a * b)
                            .sum();
                        acc += wij * dot;
                    }
                }
            }
            acc
        };
        0.5 * (quad(&self.q, x) + quad(&self.r, u))
    }

    /// w = C_z z (coefficients of every constraint function).
    pub fn constraint_coefficients(&self, z: &[f64]) -> DVector<f64> {
        &self.cz * DVector::from_column_slice(z)
    }

    /// x̃(t) = (I_n⊗τ(t)ᵀ) η_x into `out` (length n); `tau` is scratch of length s.
    pub fn state_at(&self, z: &[f64], t: f64, tau: &mut [f64], out: &mut [f64]) {
        self.eval_blocks(&z[..self.n * self.basis.dim()], t, tau, out);
    }

    /// ũ(t) = (I_m⊗τ(t)ᵀ) η_u into `out` (length m); `tau` is scratch of length s.
    pub fn input_at(&self, z: &[f64], t: f64, tau: &mut [f64], out: &mut [f64]) {
        self.eval_blocks(&z[self.n * self.basis.dim()..], t, tau, out);
    }

    fn eval_blocks(&self, coeffs: &[f64], t: f64, tau: &mut [f64], out: &mut [f64]) {
        let s = self.basis.dim();
        self.basis.tau(t, tau);
        for (o, blk) in out.iter_mut().zip(coeffs.chunks_exact(s)) {
            *o = blk.iter().zip(tau.iter()).map(|(a, b)| a * b).sum();
        }
    }

    /// Shift every s-block of z by h (E(h)ᵀ per block): the same trajectory seen from time h.
    pub fn shift(&self, z: &[f64], h: f64, out: &mut [f64]) {
        let s = self.basis.dim();
        for (zi, oi) in z.chunks_exact(s).zip(out.chunks_exact_mut(s)) {
            self.basis.shift(h, zi, oi);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    /// A, B, Q ≻ 0 and R ≻ 0 of an n-state, m-input system from 64 numbers in [−1, 1].
    fn system(n: usize, m: usize, e: &[f64]) -> [DMatrix<f64>; 4] {
        let a = DMatrix::from_fn(n, n, |i, j| e[i * 4 + j]);
        let b = DMatrix::from_fn(n, m, |i, j| e[16 + i * 3 + j]);
        let fq = DMatrix::from_fn(n, n, |i, j| e[32 + i * 4 + j]);
        let fr = DMatrix::from_fn(m, m, |i, j| e[48 + i * 3 + j]);
        let q = &fq * fq.transpose() + DMatrix::identity(n, n);
        let r = &fr * fr.transpose() + DMatrix::identity(m, m);
        [a, b, q, r]
    }

    proptest! {
        /// The block-wise cost equals the dense ½ zᵀHz.
        #[test]
        fn blockwise_cost_matches_dense_quadratic_form(
            n in 1usize..4,
            m in 1usize..3,
            s in 4usize..9,
            entries in proptest::collection::vec(-1.0f64..1.0, 64),
            zs in proptest::collection::vec(-2.0f64..2.0, 64),
        ) {
            let [a, b, q, r] = system(n, m, &entries);
            let c = Constraints::boxes(&vec![(f64::NEG_INFINITY, f64::INFINITY); n], &vec![(-1.0, 1.0); m]);
            let p = Problem::new(&a, &b, &q, &r, &c, Laguerre::new(s, 0.7).unwrap()).unwrap();
            let z: Vec<f64> = (0..p.num_variables()).map(|i| zs[i % 64] * (1.0 + i as f64 / 64.0)).collect();
            let zv = DVector::from_column_slice(&z);
            let dense = 0.5 * zv.dot(&(p.hessian() * &zv));
            prop_assert!((p.cost(&z) - dense).abs() <= 1e-12 * (1.0 + dense.abs()));
        }

        /// The plan from the low-rank factor, G x − Y((C_z Y)ᵀμ), is the minimiser of
        /// ½zᵀHz + μᵀC_z z subject to A_eq z = (0, x), from the dense KKT system (LU).
        #[test]
        fn plan_coefficients_solve_the_equality_constrained_qp(
            n in 1usize..4,
            m in 1usize..3,
            s in 4usize..9,
            entries in proptest::collection::vec(-1.0f64..1.0, 64),
            mus in proptest::collection::vec(-1.0f64..1.0, 64),
            x in proptest::collection::vec(-1.0f64..1.0, 3),
        ) {
            let [a, b, q, r] = system(n, m, &entries);
            let c = Constraints::boxes(&vec![(-1.0, 1.0); n], &vec![(-1.0, 1.0); m]);
            let p = Problem::new(&a, &b, &q, &r, &c, Laguerre::new(s, 0.7).unwrap());
            prop_assume!(p.is_ok());
            let p = p.unwrap();
            let (nv, ne, l) = (p.num_variables(), p.num_equalities(), p.rows().len() * s);
            let mu: Vec<f64> = (0..l).map(|i| mus[i % 64]).collect();
            let mut z = vec![0.0; nv];
            p.coefficients(&x[..n], &mu, &mut vec![0.0; n + p.dof()], &mut z);
            let mut kkt = DMatrix::zeros(nv + ne, nv + ne);
            kkt.view_mut((0, 0), (nv, nv)).copy_from(p.hessian());
            kkt.view_mut((0, nv), (nv, ne)).copy_from(&p.equality_matrix().transpose());
            kkt.view_mut((nv, 0), (ne, nv)).copy_from(p.equality_matrix());
            let mut rhs = DVector::zeros(nv + ne);
            rhs.rows_mut(0, nv).copy_from(&-(p.stage_matrix().transpose() * DVector::from_column_slice(&mu)));
            rhs.rows_mut(nv, ne).copy_from(&p.equality_rhs(&x[..n]));
            let sv = kkt.singular_values();
            let cond = sv.max() / sv.min();
            let reference = kkt.lu().solve(&rhs).unwrap();
            // Both solves carry a forward error of order cond(KKT)·ε; random systems near
            // uncontrollable reach cond ≈ 1e11.
            let tol = (1e-8 + 64.0 * f64::EPSILON * cond) * (1.0 + reference.rows(0, nv).amax());
            for (i, zi) in z.iter().enumerate() {
                prop_assert!((zi - reference[i]).abs() <= tol, "z[{i}] {zi} vs {} cond {cond:e}", reference[i]);
            }
        }
    }
}
