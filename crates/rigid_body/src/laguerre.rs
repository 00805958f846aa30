//! Laguerre basis functions on [0, ∞) for parametrized infinite-horizon MPC.
//!
//! `τ_i(t) = sqrt(2ν) L_{i-1}(2νt) e^{-νt}`, i = 1..s, is orthonormal in L2(0, ∞) and closed
//! under time shifts: `τ̇ = M τ` with a constant lower-triangular Toeplitz generator `M`, so
//! `τ(t + h) = e^{M h} τ(t)`. The shift matrix `e^{M h}` has a closed form, which is what
//! makes the re-solve of a shifted trajectory (warm start, recursive feasibility) cheap.
//!
//! All matrices are dense row-major `f64` slices so the module stays `no_std` and
//! allocation-free; callers size the output buffers.
//!
//! ```
//! use rigid_body::laguerre::Laguerre;
//! let basis = Laguerre::new(4, 0.7).unwrap();
//! let mut tau = [0.0; 4];
//! basis.tau(0.0, &mut tau);
//! assert!((tau[0] - (1.4f64).sqrt()).abs() < 1e-15);
//! ```

use nalgebra::ComplexField;

use crate::Error;

fn exp(x: f64) -> f64 {
    <f64 as ComplexField>::exp(x)
}

fn sqrt(x: f64) -> f64 {
    <f64 as ComplexField>::sqrt(x)
}

/// 1/k for the three-term recurrences: a table lookup for k ≤ 64 keeps the division off
/// their dependency chain (τ(t) and the shift run in every step of the constraint check).
fn reciprocal(k: usize) -> f64 {
    const TABLE: [f64; 65] = {
        let mut t = [0.0; 65];
        let mut k = 1;
        while k < 65 {
            t[k] = 1.0 / k as f64;
            k += 1;
        }
        t
    };
    match TABLE.get(k) {
        Some(&r) => r,
        None => 1.0 / k as f64,
    }
}

/// Length check of a flat slice, reported as a column of the wrong height.
pub(crate) fn check_len(name: &'static str, found: usize, expected: usize) -> Result<(), Error> {
    if found == expected {
        Ok(())
    } else {
        Err(Error::DimensionMismatch {
            name,
            rows: found,
            cols: 1,
            expected_rows: expected,
            expected_cols: 1,
        })
    }
}

/// Taylor data of `g(t) = τ(t)ᵀy` at t = 0 from [`Laguerre::taylor_data`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaylorData {
    /// `Σ y`, `Σ Mᵀy`, `Σ (Mᵀ)²y`: g, ġ, g̈ at 0 divided by the entry of τ(0).
    pub sums: [f64; 3],
    /// `|y|`.
    pub norm: f64,
    /// `|(Mᵀ)³y|`, which bounds the third derivative of g by `c_τ |(Mᵀ)³y|`.
    pub norm3: f64,
}

/// The first `s` Laguerre functions with decay rate `nu` (1/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Laguerre {
    s: usize,
    nu: f64,
}

impl Laguerre {
    /// Basis of `s >= 1` functions with decay rate `nu > 0`.
    pub fn new(s: usize, nu: f64) -> Result<Self, Error> {
        if s == 0 {
            return Err(Error::InvalidParameter {
                name: "s",
                value: 0.0,
                requirement: "the basis needs at least one function",
            });
        }
        if !nu.is_finite() || nu <= 0.0 {
            return Err(Error::InvalidParameter {
                name: "nu",
                value: nu,
                requirement: "the decay rate must be finite and > 0",
            });
        }
        Ok(Self { s, nu })
    }

    /// Number of basis functions s.
    pub fn dim(&self) -> usize {
        self.s
    }

    /// Decay rate ν.
    pub fn nu(&self) -> f64 {
        self.nu
    }

    /// Every entry of τ(0) (all equal): sqrt(2ν).
    pub fn tau0_entry(&self) -> f64 {
        sqrt(2.0 * self.nu)
    }

    /// c_τ = sup_t |τ(t)| = |τ(0)| = sqrt(2νs); bounds every function of the span by its
    /// coefficient norm, which is what the Taylor remainder and tail certificates use.
    pub fn sup_norm(&self) -> f64 {
        sqrt(2.0 * self.nu * self.s as f64)
    }

    /// τ(t) into `out` (length s), by the three-term Laguerre recurrence (stable for large t).
    pub fn tau(&self, t: f64, out: &mut [f64]) {
        let x = 2.0 * self.nu * t;
        let scale = self.tau0_entry() * exp(-self.nu * t);
        let mut prev = 0.0;
        let mut cur = 1.0;
        for (k, o) in out.iter_mut().take(self.s).enumerate() {
            *o = scale * cur;
            let kf = k as f64;
            let next = ((2.0 * kf + 1.0 - x) * cur - kf * prev) * reciprocal(k + 1);
            prev = cur;
            cur = next;
        }
    }

    /// Entry (i, j) of the generator M (0-based): −ν on the diagonal, −2ν below, 0 above.
    pub fn m_entry(&self, i: usize, j: usize) -> f64 {
        match i.cmp(&j) {
            core::cmp::Ordering::Equal => -self.nu,
            core::cmp::Ordering::Greater => -2.0 * self.nu,
            core::cmp::Ordering::Less => 0.0,
        }
    }

    /// The generator M (s×s, row-major) into `out`.
    pub fn m_matrix(&self, out: &mut [f64]) -> Result<(), Error> {
        let s = self.s;
        check_len("out", out.len(), s * s)?;
        for i in 0..s {
            for j in 0..s {
                out[i * s + j] = self.m_entry(i, j);
            }
        }
        Ok(())
    }

    /// `out = Mᵀ y` in O(s) via suffix sums (the derivative of `t ↦ τ(t)ᵀ y` has
    /// coefficients `Mᵀ y`). `y` and `out` have length s and must not alias.
    pub fn mt_apply(&self, y: &[f64], out: &mut [f64]) {
        let mut suffix = 0.0;
        for (o, yi) in out[..self.s].iter_mut().zip(&y[..self.s]).rev() {
            *o = -self.nu * yi - 2.0 * self.nu * suffix;
            suffix += yi;
        }
    }

    /// The data of a third-order Taylor bound of `g(t) = τ(t)ᵀy` at t = 0, in one O(s) pass
    /// with no scratch: the three suffix-sum recurrences of [`Self::mt_apply`] run side by
    /// side. As τ(0) is a multiple of 𝟙, g's derivatives at 0 are multiples of the sums.
    pub fn taylor_data(&self, y: &[f64]) -> TaylorData {
        let (a, b) = (-self.nu, -2.0 * self.nu);
        let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
        let (mut y_sq, mut d3_sq) = (0.0, 0.0);
        for &yi in y[..self.s].iter().rev() {
            let d1 = a * yi + b * s0;
            let d2 = a * d1 + b * s1;
            let d3 = a * d2 + b * s2;
            s0 += yi;
            s1 += d1;
            s2 += d2;
            y_sq += yi * yi;
            d3_sq += d3 * d3;
        }
        TaylorData {
            sums: [s0, s1, s2],
            norm: sqrt(y_sq),
            norm3: sqrt(d3_sq),
        }
    }

    /// `out = M x` in O(s) via prefix sums (τ̇(t) = M τ(t): the time derivative of τ).
    /// `x` and `out` have length s and must not alias.
    pub fn m_apply(&self, x: &[f64], out: &mut [f64]) {
        let mut prefix = 0.0;
        for i in 0..self.s {
            out[i] = -self.nu * x[i] - 2.0 * self.nu * prefix;
            prefix += x[i];
        }
    }

    /// Toeplitz coefficient d (0-based sub-diagonal) of E(h) = e^{Mh}, for all d < s, passed to
    /// `f(d, e_d)`. Closed form e_0 = e^{−νh}, e_d = e^{−νh}(L_d(2νh) − L_{d−1}(2νh)).
    fn for_each_shift_coeff(&self, h: f64, mut f: impl FnMut(usize, f64)) {
        let x = 2.0 * self.nu * h;
        let decay = exp(-self.nu * h);
        let mut prev = 0.0; // L_{d-1}
        let mut cur = 1.0; // L_d
        for d in 0..self.s {
            let coeff = if d == 0 { decay } else { decay * (cur - prev) };
            f(d, coeff);
            let kf = d as f64;
            let next = ((2.0 * kf + 1.0 - x) * cur - kf * prev) * reciprocal(d + 1);
            prev = cur;
            cur = next;
        }
    }

    /// The shift matrix E(h) = e^{Mh} (s×s, row-major, lower-triangular Toeplitz) in closed
    /// form, so that τ(t + h) = E(h) τ(t).
    pub fn shift_matrix(&self, h: f64, out: &mut [f64]) -> Result<(), Error> {
        let s = self.s;
        check_len("out", out.len(), s * s)?;
        out.fill(0.0);
        self.for_each_shift_coeff(h, |d, e| {
            for j in 0..s - d {
                out[(j + d) * s + j] = e;
            }
        });
        Ok(())
    }

    /// Shift a coefficient vector by h: `out = E(h)ᵀ y`, so that τ(t)ᵀ out = τ(t + h)ᵀ y.
    /// O(s²), no scratch memory. `y` and `out` have length s and must not alias.
    pub fn shift(&self, h: f64, y: &[f64], out: &mut [f64]) {
        let s = self.s;
        let (y, out) = (&y[..s], &mut out[..s]);
        out.fill(0.0);
        // Zipped slices instead of indices: no bounds check in the inner loop, which the
        // constraint check runs at every Taylor step.
        self.for_each_shift_coeff(h, |d, e| {
            for (o, yj) in out.iter_mut().zip(&y[d..]) {
                *o += e * yj;
            }
        });
    }

    /// τ̄ = ∫_0^∞ τ dt = −M⁻¹ τ(0) = sqrt(2/ν)(+1, −1, +1, …) into `out` (length s).
    pub fn integral(&self, out: &mut [f64]) {
        let v = sqrt(2.0 / self.nu);
        for (i, o) in out.iter_mut().take(self.s).enumerate() {
            *o = if i % 2 == 0 { v } else { -v };
        }
    }

    /// Equality constraints of the upper-bound problem, `A_eq z = b_eq` with
    /// z = (η_x, η_u) in state-major order:
    ///
    /// ```text
    /// A_eq = [ I_n⊗Mᵀ − A⊗I_s , −B⊗I_s ]   (ns rows: exact dynamics in the span)
    ///        [ I_n⊗τ(0)ᵀ      ,  0     ]   (n rows: initial condition, b_eq = (0, x0))
    /// ```
    ///
    /// `a` is n×n and `b` is n×m (row-major); `out` is (ns+n)×(n+m)s row-major.
    pub fn equality_matrix(
        &self,
        n: usize,
        m: usize,
        a: &[f64],
        b: &[f64],
        out: &mut [f64],
    ) -> Result<(), Error> {
        let s = self.s;
        let cols = (n + m) * s;
        check_len("a", a.len(), n * n)?;
        check_len("b", b.len(), n * m)?;
        check_len("out", out.len(), (n * s + n) * cols)?;
        out.fill(0.0);
        self.add_dynamics_rows(n, m, a, b, -1.0, out);
        for i in 0..n {
            let row = n * s + i;
            for q in 0..s {
                out[row * cols + i * s + q] = self.tau0_entry();
            }
        }
        Ok(())
    }

    /// Weak-dynamics matrix of the lower-bound problem, `D z + (I_n⊗τ(0)) x0 = 0` with
    /// `D = [ I_n⊗M + A⊗I_s , B⊗I_s ]` (ns × (n+m)s, row-major): the dynamics tested only
    /// against functions of the span, initial condition enforced weakly.
    pub fn weak_dynamics_matrix(
        &self,
        n: usize,
        m: usize,
        a: &[f64],
        b: &[f64],
        out: &mut [f64],
    ) -> Result<(), Error> {
        let s = self.s;
        let cols = (n + m) * s;
        check_len("a", a.len(), n * n)?;
        check_len("b", b.len(), n * m)?;
        check_len("out", out.len(), n * s * cols)?;
        out.fill(0.0);
        self.add_dynamics_rows(n, m, a, b, 1.0, out);
        Ok(())
    }

    /// Adds `[ I_n⊗M̃ + sign·A⊗I_s , sign·B⊗I_s ]` to the first ns rows of `out` (row-major,
    /// (n+m)s columns), with `M̃ = M` for `sign = 1` (weak form) and `M̃ = Mᵀ` for `sign = -1`
    /// (the strong form `ṽ = Mᵀ v` moved to the left-hand side).
    fn add_dynamics_rows(
        &self,
        n: usize,
        m: usize,
        a: &[f64],
        b: &[f64],
        sign: f64,
        out: &mut [f64],
    ) {
        let s = self.s;
        let cols = (n + m) * s;
        for i in 0..n {
            for p in 0..s {
                let row = i * s + p;
                for q in 0..s {
                    let entry = if sign > 0.0 {
                        self.m_entry(p, q)
                    } else {
                        self.m_entry(q, p)
                    };
                    out[row * cols + i * s + q] += entry;
                }
                for j in 0..n {
                    out[row * cols + j * s + p] += sign * a[i * n + j];
                }
                for j in 0..m {
                    out[row * cols + n * s + j * s + p] += sign * b[i * m + j];
                }
            }
        }
    }

    /// Stage-constraint coefficient map `C_z = [Cx⊗I_s, Cu⊗I_s]` (nc·s × (n+m)s, row-major):
    /// block k of `C_z z` holds the coefficients of the scalar constraint function
    /// `t ↦ (Cx x̃(t) + Cu ũ(t))_k`.
    pub fn stage_matrix(
        &self,
        n: usize,
        m: usize,
        cx: &[f64],
        cu: &[f64],
        out: &mut [f64],
    ) -> Result<(), Error> {
        let s = self.s;
        let cols = (n + m) * s;
        if n == 0 || cx.len() % n != 0 {
            return Err(Error::DimensionMismatch {
                name: "cx",
                rows: cx.len(),
                cols: 1,
                expected_rows: n,
                expected_cols: 1,
            });
        }
        let nc = cx.len() / n;
        check_len("cu", cu.len(), nc * m)?;
        check_len("out", out.len(), nc * s * cols)?;
        out.fill(0.0);
        for k in 0..nc {
            for p in 0..s {
                let row = k * s + p;
                for j in 0..n {
                    out[row * cols + j * s + p] = cx[k * n + j];
                }
                for j in 0..m {
                    out[row * cols + n * s + j * s + p] = cu[k * m + j];
                }
            }
        }
        Ok(())
    }
}

/// Local extrema of g(t) = τ(t)ᵀw on [0, ∞), including t = 0, as (t, g(t)) pairs: a dense
/// scan in νt ∈ [0, 120] (step 0.01; beyond it every function of the span is below
/// 1e-20·|w| for s ≤ 20) with Newton polishing of every sampled extremum, the first sample
/// included. An exact reference for tests and analysis, far slower than the solver's check.
#[cfg(feature = "std")]
pub fn extrema(basis: &Laguerre, w: &[f64]) -> std::vec::Vec<(f64, f64)> {
    use std::vec;
    let s = basis.dim();
    let mut tau = vec![0.0; s];
    let eval = |v: &[f64], t: f64, tau: &mut [f64]| -> f64 {
        basis.tau(t, tau);
        tau.iter().zip(v).map(|(a, b)| a * b).sum()
    };
    let (mut d1, mut d2) = (vec![0.0; s], vec![0.0; s]);
    basis.mt_apply(w, &mut d1);
    basis.mt_apply(&d1, &mut d2);
    let h = 0.01 / basis.nu();
    let n = (120.0 / basis.nu() / h) as usize;
    let vals: std::vec::Vec<f64> = (0..=n).map(|i| eval(w, i as f64 * h, &mut tau)).collect();
    let mut out = vec![(0.0, vals[0])];
    for i in 0..n {
        let (b, c) = (vals[i], vals[i + 1]);
        let a = if i == 0 { b } else { vals[i - 1] };
        if (b >= a && b >= c) || (b <= a && b <= c) {
            let lo = i.saturating_sub(1) as f64 * h;
            let hi = (i + 1) as f64 * h;
            let mut t = i as f64 * h;
            for _ in 0..30 {
                let g1 = eval(&d1, t, &mut tau);
                let g2 = eval(&d2, t, &mut tau);
                if g2 == 0.0 {
                    break;
                }
                let tn = (t - g1 / g2).clamp(lo, hi);
                if (tn - t).abs() < 1e-15 {
                    break;
                }
                t = tn;
            }
            out.push((t, eval(w, t, &mut tau)));
        }
    }
    out
}

#[cfg(test)]
mod tests;
