//! Algebraic Riccati equations and LQR gains.
//!
//! Both equations are first checked for solvability with PBH rank tests (stabilizability of
//! `(A, B)` and detectability of `(A, Q)` on every eigenvalue of `A` that is not asymptotically
//! stable), so that an unsolvable problem is reported by name. The discrete equation is solved by
//! the structure-preserving doubling algorithm (Chu, Fan, Lin, Wang 2004), the continuous one by
//! the matrix sign function of the Hamiltonian (Newton iteration with determinant scaling); both
//! results are then polished by Newton steps (Hewer / Kleinman) on the Lyapunov solvers.

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
    let q_min = symmetrized(q)
        .symmetric_eigenvalues()
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    if n > 0 && q_min < -1e-12 * q.norm() {
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
    let mut ham = DMatrix::zeros(2 * n, 2 * n);
    ham.view_mut((0, 0), (n, n)).copy_from(a);
    ham.view_mut((0, n), (n, n)).copy_from(&(-&g));
    ham.view_mut((n, 0), (n, n)).copy_from(&(-q));
    ham.view_mut((n, n), (n, n)).copy_from(&(-a.transpose()));
    let w = sign(ham)?;
    // The stable invariant subspace is ker(W + I) = span [I; X].
    let mut lhs = DMatrix::zeros(2 * n, n);
    lhs.view_mut((0, 0), (n, n))
        .copy_from(&w.view((0, n), (n, n)));
    lhs.view_mut((n, 0), (n, n))
        .copy_from(&(w.view((n, n), (n, n)) + DMatrix::identity(n, n)));
    let mut rhs = DMatrix::zeros(2 * n, n);
    rhs.view_mut((0, 0), (n, n))
        .copy_from(&(-(w.view((0, 0), (n, n)) + DMatrix::identity(n, n))));
    rhs.view_mut((n, 0), (n, n))
        .copy_from(&(-w.view((n, 0), (n, n))));
    let qr = lhs.qr();
    let x = qr
        .r()
        .solve_upper_triangular(&(qr.q().transpose() * rhs))
        .ok_or(Error::Singular {
            name: "stable invariant subspace of the Hamiltonian",
        })?;
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
    check_closed_loop(&closed, Domain::Continuous, "CARE (sign function)")?;
    Ok(x)
}

/// Matrix sign function by the scaled Newton iteration `Z <- (Z / c + c Z^{-1}) / 2`.
fn sign(mut z: DMatrix<f64>) -> Result<DMatrix<f64>> {
    const ITERATIONS: usize = 100;
    let dim = z.nrows() as f64;
    let mut scaling = true;
    for _ in 0..ITERATIONS {
        let lu = z.clone().lu();
        let log_det: f64 = lu.u().diagonal().iter().map(|d| d.abs().ln()).sum();
        let inv = lu.try_inverse().ok_or(Error::Singular {
            name: "Hamiltonian (eigenvalue on the imaginary axis)",
        })?;
        let c = if scaling { (log_det / dim).exp() } else { 1.0 };
        if !c.is_finite() || c == 0.0 {
            return Err(Error::Singular {
                name: "Hamiltonian (eigenvalue on the imaginary axis)",
            });
        }
        let next = (&z / c + inv * c) * 0.5;
        let change = (&next - &z).norm();
        let size = next.norm();
        z = next;
        if change <= 1e-2 * size {
            scaling = false;
        }
        if change <= 1e3 * f64::EPSILON * size {
            return Ok(z);
        }
    }
    Err(Error::NoConvergence {
        algorithm: "matrix sign iteration for the CARE",
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
    const ITERATIONS: usize = 100;
    let pr = validate(a, b, q, r, Domain::Discrete)?;
    let n = pr.n;
    if n == 0 {
        return Ok(q.clone());
    }
    let identity = DMatrix::<f64>::identity(n, n);
    let mut ak = a.clone();
    let mut gk = symmetrized(&(b * &pr.r_inv_bt));
    let mut hk = symmetrized(q);
    let mut converged = false;
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
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(Error::NoConvergence {
            algorithm: "doubling iteration for the DARE",
            iterations: ITERATIONS,
        });
    }
    let mut x = hk;
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
