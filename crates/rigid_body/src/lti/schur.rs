//! Complex Schur form of a real matrix, shared by the Lyapunov solvers and the eigenvalue tests.

use crate::{Error, Result};
use nalgebra::{Complex, DMatrix};
use std::vec::Vec;

use super::CMatrix;

/// `A = U T U^H` with `U` unitary and `T` upper triangular (complex, so no 2x2 blocks).
#[derive(Debug)]
pub(super) struct ComplexSchur {
    pub u: CMatrix,
    pub t: CMatrix,
}

pub(super) fn complexify(m: &DMatrix<f64>) -> CMatrix {
    m.map(|x| Complex::new(x, 0.0))
}

/// Eigenvalues of `a` from its complex Schur form (see [`ComplexSchur::new`]).
pub fn eigenvalues(a: &DMatrix<f64>) -> Result<Vec<Complex<f64>>> {
    Ok(ComplexSchur::new(a)?.eigenvalues().collect())
}

/// The largest modulus of the eigenvalues of `a` (see [`eigenvalues`]).
pub fn spectral_radius(a: &DMatrix<f64>) -> Result<f64> {
    Ok(eigenvalues(a)?.iter().map(|l| l.norm()).fold(0.0, f64::max))
}

impl ComplexSchur {
    /// The Schur form in a bounded number of QR iterations (an error when they do not
    /// converge). nalgebra's `complex_eigenvalues` iterates without a bound and never returned
    /// on a matrix met in a fitted flying-platform model: nearly rank one, with a cluster of
    /// eigenvalues at rounding level. The iteration's deflation test is relative to the
    /// neighbouring diagonal entries, which such a cluster keeps at rounding level too; when it
    /// does not converge, `a + |a| I = U T' U^H` is taken and `T = T' - |a| I`, for which the
    /// test is relative to the matrix's norm, as LAPACK's is. The Lyapunov and Riccati solvers
    /// get the same fallback as the eigenvalues.
    pub fn new(a: &DMatrix<f64>) -> Result<Self> {
        Self::unshifted(a).or_else(|e| {
            let shift = a.norm();
            let identity = DMatrix::identity(a.nrows(), a.ncols());
            let mut schur = Self::unshifted(&(a + &identity * shift)).map_err(|_| e)?;
            for i in 0..schur.t.nrows() {
                schur.t[(i, i)] -= shift;
            }
            Ok(schur)
        })
    }

    fn unshifted(a: &DMatrix<f64>) -> Result<Self> {
        let iterations = 1000 + 100 * a.nrows();
        let schur =
            complexify(a)
                .try_schur(f64::EPSILON, iterations)
                .ok_or(Error::NoConvergence {
                    algorithm: "Schur decomposition of A",
                    iterations,
                })?;
        let (u, t) = schur.unpack();
        Ok(Self { u, t })
    }

    /// Eigenvalues of `A` (the diagonal of `T`).
    pub fn eigenvalues(&self) -> impl Iterator<Item = Complex<f64>> + '_ {
        (0..self.t.nrows()).map(move |i| self.t[(i, i)])
    }
}
