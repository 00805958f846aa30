//! Complex Schur form of a real matrix, shared by the Lyapunov solvers and the eigenvalue tests.

use crate::{Error, Result};
use nalgebra::{Complex, DMatrix};

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

impl ComplexSchur {
    pub fn new(a: &DMatrix<f64>) -> Result<Self> {
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
