//! Algebraic Riccati equations and LQR gains.
//!
//! Both equations are first checked for solvability with PBH rank tests (stabilizability of
//! `(A, B)` and detectability of `(A, Q)` on every eigenvalue of `A` that is not asymptotically
//! stable), so that an unsolvable problem is reported by name. Both are then solved by the
//! structure-preserving doubling algorithm (SDA; Chu, Fan, Lin, Wang 2004 for the DARE; Chu, Fan,
//! Lin 2005 for the CARE, after a Cayley transform of the Hamiltonian), and polished by Newton
//! steps (Hewer / Kleinman) on the Lyapunov solvers.

use super::schur::{complexify, ComplexSchur};
use super::{dlyap, lyap, shaped, square, symmetric, symmetrized};
use crate::{Error, Result};
use nalgebra::{Complex, DMatrix};

/// Infinite-horizon LQR solution: gain `k` for `u = -k x` and the Riccati solution `p`
/// (cost-to-go `x^T p x`).
#[derive(Debug, Clone, PartialEq)]
pub struct Lqr {
    /// State-feedback gain, `m x n`.
    pub k: DMatrix<f64>,
    /// Stabilizing solution of the Riccati equation, `n x n`, symmetric positive semidefinite.
    pub p: DMatrix<f64>,
}

/// Time domain of the problem: decides which modes count as unstable.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Domain {
    Continuous,
    Discrete,
}

impl Domain {
    fn strictly_stable(self, z: Complex<f64>) -> bool {
        match self {
            Domain::Continuous => z.re < -1e-10,
            Domain::Discrete => z.norm() < 1.0 - 1e-10,
        }
    }
}

/// Validated data of a Riccati problem.
#[derive(Debug)]
struct Problem {
    n: usize,
    /// `R^{-1} B^T`.
    r_inv_bt: DMatrix<f64>,
}

fn validate(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    domain: Domain,
) -> Result<Problem> {
    let n = square("A", a)?;
    shaped("B", b, n, b.ncols())?;
    let m = b.ncols();
    shaped("Q", q, n, n)?;
    shaped("R", r, m, m)?;
    symmetric("Q", q)?;
    symmetric("R", r)?;
    // nalgebra's eigen-decomposition panics on an empty matrix: a model with no state has
    // nothing to check.
    let q_min = if n == 0 {
        0.0
    } else {
        symmetrized(q)
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    };
    if q_min < -1e-12 * q.norm() {
        return Err(Error::NotPositiveSemidefinite {
            name: "Q",
            eigenvalue: q_min,
        });
    }
    let chol = symmetrized(r)
        .cholesky()
        .ok_or(Error::NotPositiveDefinite { name: "R" })?;
    let r_inv_bt = chol.solve(&b.transpose());
    pbh_checks(a, b, q, domain)?;
    Ok(Problem { n, r_inv_bt })
}

/// Smallest singular value of a complex matrix (0 for an empty one).
fn sigma_min(m: nalgebra::DMatrix<Complex<f64>>) -> Result<f64> {
    let iterations = 1000 + 100 * m.nrows().max(m.ncols());
    let svd = m
        .try_svd(false, false, f64::EPSILON, iterations)
        .ok_or(Error::NoConvergence {
            algorithm: "SVD in the PBH test",
            iterations,
        })?;
    Ok(svd
        .singular_values
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min))
}

/// PBH tests on every eigenvalue of `A` that is not asymptotically stable:
/// rank `[A - λI, B] = n` (stabilizable) and rank `[A - λI; Q] = n` (detectable).
fn pbh_checks(a: &DMatrix<f64>, b: &DMatrix<f64>, q: &DMatrix<f64>, domain: Domain) -> Result<()> {
    let n = a.nrows();
    if n == 0 {
        return Ok(());
    }
    let eig: std::vec::Vec<_> = ComplexSchur::new(a)?.eigenvalues().collect();
    let ac = complexify(a);
    let tol_b = 1e-9 * (a.norm() + b.norm()).max(1.0);
    let tol_q = 1e-9 * (a.norm() + q.norm()).max(1.0);
    for lambda in eig.into_iter().filter(|z| !domain.strictly_stable(*z)) {
        let shifted = &ac - DMatrix::<Complex<f64>>::identity(n, n) * lambda;
        let mut wide = DMatrix::zeros(n, n + b.ncols());
        wide.view_mut((0, 0), (n, n)).copy_from(&shifted);
        wide.view_mut((0, n), (n, b.ncols()))
            .copy_from(&complexify(b));
        if sigma_min(wide)? <= tol_b {
            return Err(Error::NotStabilizable {
                re: lambda.re,
                im: lambda.im,
            });
        }
        let mut tall = DMatrix::zeros(2 * n, n);
        tall.view_mut((0, 0), (n, n)).copy_from(&shifted);
        tall.view_mut((n, 0), (n, n)).copy_from(&complexify(q));
        if sigma_min(tall)? <= tol_q {
            return Err(Error::NotDetectable {
                re: lambda.re,
                im: lambda.im,
            });
        }
    }
    Ok(())
}

/// Residual `A^T X + X A - X B R^{-1} B^T X + Q`.
fn care_residual(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    pr: &Problem,
    x: &DMatrix<f64>,
) -> DMatrix<f64> {
    a.transpose() * x + x * a - x * b * (&pr.r_inv_bt * x) + q
}

/// Stabilizing solution `X` of `A^T X + X A - X B R^{-1} B^T X + Q = 0`.
///
/// Requires `Q = Q^T >= 0`, `R = R^T > 0`, `(A, B)` stabilizable and `(A, Q)` detectable; each
/// violated assumption is a named error.
pub fn care(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let pr = validate(a, b, q, r, Domain::Continuous)?;
    let n = pr.n;
    if n == 0 {
        return Ok(q.clone());
    }
    let g = symmetrized(&(b * &pr.r_inv_bt));
    let x = care_doubling(a, &g, q)?;
    let mut x = symmetrized(&x);
    // Kleinman–Newton polishing: X+ solves (A - G X)^T X+ + X+ (A - G X) + Q + X G X = 0.
    for _ in 0..3 {
        let closed = (a - &g * &x).transpose();
        let Ok(next) = lyap(&closed, &(q + &x * &g * &x)) else {
            break;
        };
        let next = symmetrized(&next);
        if care_residual(a, b, q, &pr, &next).norm() >= care_residual(a, b, q, &pr, &x).norm() {
            break;
        }
        x = next;
    }
    let closed = a - &g * &x;
    check_closed_loop(&closed, Domain::Continuous, "CARE (doubling)")?;
    Ok(x)
}

/// CARE by SDA on the Cayley transform `(H - γI)^{-1} (H + γI)` of the Hamiltonian, whose
/// stable invariant subspace `[I; X]` is that of `H` (Chu, Fan, Lin 2005):
/// `A_γ = A - γI`, `W = A_γ^T + Q A_γ^{-1} G`, `V = A_γ + G A_γ^{-T} Q`, then
/// `A0 = I + 2γ V^{-1}`, `G0 = 2γ A_γ^{-1} G W^{-1}`, `H0 = 2γ W^{-1} Q A_γ^{-1}`.
/// `γ` starts at `max(1, |A|_F)` and is enlarged if one of the inverses does not exist.
fn care_doubling(a: &DMatrix<f64>, g: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = a.nrows();
    let identity = DMatrix::<f64>::identity(n, n);
    let mut gamma = a.norm().max(1.0);
    for _ in 0..4 {
        let a_gamma = a - &identity * gamma;
        let Some(a_gamma_inv) = a_gamma.clone().try_inverse() else {
            gamma *= 1.7;
            continue;
        };
        let w = a_gamma.transpose() + q * &a_gamma_inv * g;
        let v = &a_gamma + g * a_gamma_inv.transpose() * q;
        let (Some(w_inv), Some(v_inv)) = (w.try_inverse(), v.try_inverse()) else {
            gamma *= 1.7;
            continue;
        };
        let a0 = &identity + v_inv * (2.0 * gamma);
        let g0 = symmetrized(&(&a_gamma_inv * g * &w_inv * (2.0 * gamma)));
        let h0 = symmetrized(&(&w_inv * q * &a_gamma_inv * (2.0 * gamma)));
        return doubling(a0, g0, h0, "doubling iteration for the CARE");
    }
    Err(Error::Singular {
        name: "A - γI or its Cayley-transformed Hamiltonian blocks",
    })
}

/// SDA: `A+ = A (I + G H)^{-1} A`, `G+ = G + A (I + G H)^{-1} G A^T`,
/// `H+ = H + A^T H (I + G H)^{-1} A`; `H` converges quadratically to the stabilizing solution.
fn doubling(
    mut ak: DMatrix<f64>,
    mut gk: DMatrix<f64>,
    mut hk: DMatrix<f64>,
    algorithm: &'static str,
) -> Result<DMatrix<f64>> {
    const ITERATIONS: usize = 100;
    let identity = DMatrix::<f64>::identity(ak.nrows(), ak.nrows());
    for _ in 0..ITERATIONS {
        let lu = (&identity + &gk * &hk).lu();
        let singular = Error::Singular {
            name: "I + G H in the doubling iteration",
        };
        let w_a = lu.solve(&ak).ok_or(singular)?;
        let w_g = lu.solve(&gk).ok_or(singular)?;
        let h_next = symmetrized(&(&hk + ak.transpose() * &hk * &w_a));
        let g_next = symmetrized(&(&gk + &ak * w_g * ak.transpose()));
        ak = &ak * w_a;
        let change = (&h_next - &hk).norm();
        hk = h_next;
        gk = g_next;
        if !hk.iter().all(|v| v.is_finite()) {
            break;
        }
        if change <= 1e3 * f64::EPSILON * hk.norm().max(f64::MIN_POSITIVE) {
            return Ok(hk);
        }
    }
    Err(Error::NoConvergence {
        algorithm,
        iterations: ITERATIONS,
    })
}

fn check_closed_loop(closed: &DMatrix<f64>, domain: Domain, algorithm: &'static str) -> Result<()> {
    let schur = ComplexSchur::new(closed)?;
    if schur.eigenvalues().all(|z| match domain {
        Domain::Continuous => z.re < 0.0,
        Domain::Discrete => z.norm() < 1.0,
    }) {
        Ok(())
    } else {
        Err(Error::NoConvergence {
            algorithm,
            iterations: 0,
        })
    }
}

/// DARE gain `(R + B^T X B)^{-1} B^T X A`.
fn dare_gain(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let btx = b.transpose() * x;
    let s = symmetrized(&(r + &btx * b));
    let chol = s.cholesky().ok_or(Error::NotPositiveDefinite {
        name: "R + B^T P B",
    })?;
    Ok(chol.solve(&(btx * a)))
}

/// Residual `A^T X A - X - A^T X B (R + B^T X B)^{-1} B^T X A + Q`.
fn dare_residual(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let k = dare_gain(a, b, r, x)?;
    Ok(a.transpose() * x * a - x - a.transpose() * x * b * k + q)
}

/// Stabilizing solution `X` of `A^T X A - X - A^T X B (R + B^T X B)^{-1} B^T X A + Q = 0`.
///
/// Requires `Q = Q^T >= 0`, `R = R^T > 0`, `(A, B)` stabilizable and `(A, Q)` detectable; each
/// violated assumption is a named error.
pub fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>> {
    let pr = validate(a, b, q, r, Domain::Discrete)?;
    if pr.n == 0 {
        return Ok(q.clone());
    }
    let g = symmetrized(&(b * &pr.r_inv_bt));
    let mut x = doubling(
        a.clone(),
        g,
        symmetrized(q),
        "doubling iteration for the DARE",
    )?;
    // Hewer–Newton polishing: X+ solves Acl^T X+ Acl - X+ + Q + K^T R K = 0.
    for _ in 0..3 {
        let k = dare_gain(a, b, r, &x)?;
        let closed = a - b * &k;
        let Ok(next) = dlyap(&closed.transpose(), &(q + k.transpose() * r * &k)) else {
            break;
        };
        let next = symmetrized(&next);
        if dare_residual(a, b, q, r, &next)?.norm() >= dare_residual(a, b, q, r, &x)?.norm() {
            break;
        }
        x = next;
    }
    let k = dare_gain(a, b, r, &x)?;
    check_closed_loop(&(a - b * k), Domain::Discrete, "DARE (doubling)")?;
    Ok(x)
}

/// Continuous-time LQR: minimises `∫ x^T Q x + u^T R u dt` for `x' = A x + B u`; `K = R^{-1} B^T P`.
pub fn lqr(a: &DMatrix<f64>, b: &DMatrix<f64>, q: &DMatrix<f64>, r: &DMatrix<f64>) -> Result<Lqr> {
    let p = care(a, b, q, r)?;
    let chol = symmetrized(r)
        .cholesky()
        .ok_or(Error::NotPositiveDefinite { name: "R" })?;
    let k = chol.solve(&(b.transpose() * &p));
    Ok(Lqr { k, p })
}

/// Discrete-time LQR: minimises `Σ x^T Q x + u^T R u` for `x+ = A x + B u`;
/// `K = (R + B^T P B)^{-1} B^T P A`.
pub fn dlqr(a: &DMatrix<f64>, b: &DMatrix<f64>, q: &DMatrix<f64>, r: &DMatrix<f64>) -> Result<Lqr> {
    let p = dare(a, b, q, r)?;
    let k = dare_gain(a, b, r, &p)?;
    Ok(Lqr { k, p })
}
