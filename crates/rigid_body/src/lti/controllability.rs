//! Controllability matrix and infinite-horizon controllability Gramian.

use super::schur::ComplexSchur;
use super::{lyap, shaped, square};
use crate::{Error, Result};
use nalgebra::DMatrix;

/// Controllability matrix `[B, A B, ..., A^{n-1} B]` (`n x n m`).
pub fn ctrb_matrix(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = square("A", a)?;
    let m = b.ncols();
    shaped("B", b, n, m)?;
    let mut c = DMatrix::zeros(n, n * m);
    let mut block = b.clone();
    for i in 0..n {
        c.view_mut((0, i * m), (n, m)).copy_from(&block);
        block = a * block;
    }
    Ok(c)
}

/// Continuous infinite-horizon controllability Gramian `W = ∫_0^∞ e^{At} B B^T e^{A^T t} dt`,
/// the solution of `A W + W A^T + B B^T = 0`. Errors unless `A` is Hurwitz.
pub fn ctrb_gramian(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = square("A", a)?;
    shaped("B", b, n, b.ncols())?;
    if n == 0 {
        return Ok(DMatrix::zeros(0, 0));
    }
    if let Some(z) = ComplexSchur::new(a)?.eigenvalues().find(|z| z.re >= 0.0) {
        return Err(Error::Unstable {
            kind: "Hurwitz",
            re: z.re,
            im: z.im,
        });
    }
    lyap(a, &(b * b.transpose()))
}
