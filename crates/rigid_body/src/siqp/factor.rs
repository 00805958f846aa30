//! Cholesky factor of the working-set matrix K_W with bordered updates and Givens deletion,
//! so adding or dropping one active instant costs O(|W|²) instead of a refactorisation.

use super::fmath::sqrt;

/// Lower-triangular factor stored row-major with a fixed stride (`cap`), in a borrowed slice.
#[derive(Debug)]
pub(super) struct Factor<'a> {
    pub(super) l: &'a mut [f64],
    pub(super) cap: usize,
}

impl Factor<'_> {
    fn at(&self, i: usize, j: usize) -> f64 {
        self.l[i * self.cap + j]
    }

    fn set(&mut self, i: usize, j: usize, v: f64) {
        self.l[i * self.cap + j] = v;
    }

    /// Forward substitution `x ← L⁻¹ x` on the leading `p` entries.
    pub(super) fn forward(&self, p: usize, x: &mut [f64]) {
        for i in 0..p {
            let row = &self.l[i * self.cap..i * self.cap + i];
            let acc = x[i] - row.iter().zip(&x[..i]).map(|(a, b)| a * b).sum::<f64>();
            x[i] = acc / self.at(i, i);
        }
    }

    /// Back substitution `x ← L⁻ᵀ x` on the leading `p` entries.
    pub(super) fn backward(&self, p: usize, x: &mut [f64]) {
        for i in (0..p).rev() {
            let acc = x[i]
                - (i + 1..p)
                    .zip(&x[i + 1..p])
                    .map(|(j, xj)| self.at(j, i) * xj)
                    .sum::<f64>();
            x[i] = acc / self.at(i, i);
        }
    }

    /// Append row p: `row[..p] = L⁻¹ b` (already forward-substituted) and the Schur
    /// complement `schur > 0` of the new diagonal element.
    pub(super) fn append(&mut self, p: usize, row: &[f64], schur: f64) {
        for (j, &v) in row.iter().enumerate().take(p) {
            self.set(p, j, v);
        }
        self.set(p, p, sqrt(schur));
    }

    /// Remove index `j` from a factor of size `p` (Givens rotations re-triangularise the
    /// rows below it).
    pub(super) fn remove(&mut self, p: usize, j: usize) {
        for i in j..p - 1 {
            for c in 0..=i + 1 {
                let v = self.at(i + 1, c);
                self.set(i, c, v);
            }
        }
        let np = p - 1;
        for i in j..np {
            let a = self.at(i, i);
            let b = self.at(i, i + 1);
            let r = sqrt(a * a + b * b);
            let (c, s) = (a / r, b / r);
            for k in i..np {
                let x = self.at(k, i);
                let y = self.at(k, i + 1);
                self.set(k, i, c * x + s * y);
                self.set(k, i + 1, -s * x + c * y);
            }
            self.set(i, i + 1, 0.0);
        }
    }
}
