//! Continuous and discrete Lyapunov equations by the Bartels–Stewart method on the complex
//! Schur form of `A` (nalgebra's Schur decomposition; O(n^3)).

use super::schur::{complexify, ComplexSchur};
use super::CMatrix;
use super::{shaped, square};
use crate::{Error, Result};
use nalgebra::{Complex, DMatrix};

/// Which Lyapunov equation the triangular solver handles.
#[derive(Debug, Clone, Copy)]
enum Kind {
    /// `T Y + Y T^H = C`.
    Continuous,
    /// `T Y T^H - Y = C`.
    Discrete,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Continuous => "Lyapunov",
            Kind::Discrete => "discrete Lyapunov",
        }
    }
}

/// Solves `A X + X A^T + Q = 0` for `X` (`Q` need not be symmetric; if it is, so is `X`).
///
/// Errors if shapes disagree, entries are not finite, or `λ_i + λ_j ≈ 0` for two eigenvalues of
/// `A` (then the solution is not unique).
pub fn lyap(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    solve(a, q, Kind::Continuous)
}

/// Solves `A X A^T - X + Q = 0` for `X`.
///
/// Errors if shapes disagree, entries are not finite, or `λ_i conj(λ_j) ≈ 1` for two eigenvalues
/// of `A`.
pub fn dlyap(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    solve(a, q, Kind::Discrete)
}

fn solve(a: &DMatrix<f64>, q: &DMatrix<f64>, kind: Kind) -> Result<DMatrix<f64>> {
    let n = square("A", a)?;
    shaped("Q", q, n, n)?;
    if n == 0 {
        return Ok(q.clone());
    }
    let schur = ComplexSchur::new(a)?;
    let u = &schur.u;
    let c = -(u.adjoint() * complexify(q) * u);
    let y = triangular(&schur.t, &c, kind, a.norm())?;
    let x = (u * y * u.adjoint()).map(|z| z.re);
    let symmetric_q = q == &q.transpose();
    Ok(if symmetric_q {
        (&x + x.transpose()) * 0.5
    } else {
        x
    })
}

/// Column-by-column back substitution for the triangular equation, last column first.
fn triangular(t: &CMatrix, c: &CMatrix, kind: Kind, scale: f64) -> Result<CMatrix> {
    let n = t.nrows();
    let tol = 1e3 * f64::EPSILON * scale.max(1.0);
    let mut y = CMatrix::zeros(n, n);
    for k in (0..n).rev() {
        let tkk = t[(k, k)].conj();
        // Contribution of the already known columns j > k.
        let mut known = nalgebra::DVector::<Complex<f64>>::zeros(n);
        for j in k + 1..n {
            known += y.column(j) * t[(k, j)].conj();
        }
        let rhs = match kind {
            Kind::Continuous => c.column(k) - known,
            Kind::Discrete => c.column(k) - t * known,
        };
        // Upper-triangular system M y_k = rhs with M = T + tkk I or tkk T - I.
        for i in (0..n).rev() {
            let mut acc = rhs[i];
            for l in i + 1..n {
                let m_il = match kind {
                    Kind::Continuous => t[(i, l)],
                    Kind::Discrete => t[(i, l)] * tkk,
                };
                acc -= m_il * y[(l, k)];
            }
            let diag = match kind {
                Kind::Continuous => t[(i, i)] + tkk,
                Kind::Discrete => t[(i, i)] * tkk - Complex::new(1.0, 0.0),
            };
            if diag.norm() <= tol {
                let (li, lk) = (t[(i, i)], t[(k, k)]);
                return Err(Error::SingularEquation {
                    equation: kind.name(),
                    re1: li.re,
                    im1: li.im,
                    re2: lk.re,
                    im2: lk.im,
                });
            }
            y[(i, k)] = acc / diag;
        }
    }
    Ok(y)
}
