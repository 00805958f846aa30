//! Matrix exponential and zero-order-hold discretisation (with an optional input delay).

use super::{finite, shaped, square};
use crate::{Error, Result};
use nalgebra::DMatrix;

/// Matrix exponential `e^A` by Pade scaling and squaring (Higham 2005, with the
/// Al-Mohy–Higham 2009 backward-error refinement), as implemented by nalgebra.
///
/// Errors if `A` is not square, has non-finite entries or a 1-norm above [`EXPM_MAX_NORM`],
/// or the result overflows.
pub fn expm(a: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    square("A", a)?;
    if a.nrows() == 0 {
        return Ok(a.clone());
    }
    let norm = a
        .column_iter()
        .map(|c| c.iter().map(|x| x.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    if norm > EXPM_MAX_NORM {
        return Err(Error::InvalidParameter {
            name: "1-norm of the matrix exponential's argument",
            value: norm,
            requirement: "must be at most 1/ε (4.5e15): beyond it no digit of e^A is right",
        });
    }
    let e = a.exp();
    finite("expm(A) (overflow)", &e)?;
    Ok(e)
}

/// Largest 1-norm [`expm`] accepts: scaling and squaring loses about `‖A‖ ε` of accuracy, so
/// beyond `1/ε` the result has no correct digit; and nalgebra's `exp` did not return within
/// seconds for norms of 1e100 to 1e300 (a fit whose parameters ran to 3e8 hung there).
pub const EXPM_MAX_NORM: f64 = 1.0 / f64::EPSILON;

/// `(e^{A s}, ∫_0^s e^{A σ} dσ B)` from the exponential of `[[A, B], [0, 0]] s`.
fn phi_gamma(a: &DMatrix<f64>, b: &DMatrix<f64>, s: f64) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let (n, m) = (a.nrows(), b.ncols());
    let mut aug = DMatrix::zeros(n + m, n + m);
    aug.view_mut((0, 0), (n, n)).copy_from(&(a * s));
    aug.view_mut((0, n), (n, m)).copy_from(&(b * s));
    let e = expm(&aug)?;
    Ok((
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    ))
}

fn check_system(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Result<()> {
    let n = square("A", a)?;
    shaped("B", b, n, b.ncols())
}

fn check_positive(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidParameter {
            name,
            value,
            requirement: "must be positive and finite",
        })
    }
}

/// Zero-order-hold discretisation of `x' = A x + B u` with sample time `h`:
/// returns `(Ad, Bd) = (e^{A h}, ∫_0^h e^{A s} ds B)`, computed exactly from one exponential of
/// the augmented matrix `[[A, B], [0, 0]] h` (no inversion of `A`, so singular `A` is fine).
pub fn c2d_zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    check_system(a, b)?;
    check_positive("h", h)?;
    phi_gamma(a, b, h)
}

/// Largest delay, in whole sample times, that [`c2d_zoh_delay`] accepts.
pub const MAX_DELAY_STEPS: usize = 1000;

/// Zero-order-hold model of `x'(t) = A x(t) + B u(t - tau)` on the augmented state
/// `z_k = (x_k, u_{k-q}, ..., u_{k-1})` that buffers the last `q = delay_inputs` inputs
/// (oldest first), so that `z_{k+1} = a z_k + b u_k`.
#[derive(Debug, Clone, PartialEq)]
pub struct DelayedZoh {
    /// Augmented state matrix, `(n + q m) x (n + q m)`.
    pub a: DMatrix<f64>,
    /// Augmented input matrix, `(n + q m) x m`.
    pub b: DMatrix<f64>,
    /// Number `q` of past inputs held in the augmented state.
    pub delay_inputs: usize,
}

/// ZOH discretisation with an input delay `tau >= 0` (Åström–Wittenmark): writing
/// `tau = d h + f` with `0 <= f < h`, `x_{k+1} = Φ x_k + Γ1 u_{k-d-1} + Γ0 u_{k-d}` where
/// `Γ0 = ∫_0^{h-f} e^{As} ds B` and `Γ1 = e^{A(h-f)} ∫_0^f e^{As} ds B`. The buffer holds
/// `q = d + (f > 0)` past inputs; with `tau = 0` this is [`c2d_zoh`].
pub fn c2d_zoh_delay(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64, tau: f64) -> Result<DelayedZoh> {
    check_system(a, b)?;
    check_positive("h", h)?;
    if !(tau.is_finite() && tau >= 0.0) {
        return Err(Error::InvalidParameter {
            name: "tau",
            value: tau,
            requirement: "must be non-negative and finite",
        });
    }
    // Snap the fractional delay to the grid when it is within rounding of a multiple of h.
    let ratio = tau / h;
    let mut whole = ratio.floor();
    let mut frac = tau - whole * h;
    let snap = 1e-12 * h.max(tau);
    if frac <= snap {
        frac = 0.0;
    } else if h - frac <= snap {
        whole += 1.0;
        frac = 0.0;
    }
    if whole >= MAX_DELAY_STEPS as f64 {
        return Err(Error::InvalidParameter {
            name: "tau",
            value: tau,
            requirement:
                "must be below 1000 sample times (the augmented state buffers tau / h inputs)",
        });
    }
    let d = whole as usize;
    let (n, m) = (a.nrows(), b.ncols());
    let (phi, _) = phi_gamma(a, b, h)?;
    let (phi_rest, gamma0) = phi_gamma(a, b, h - frac)?;
    let q = d + usize::from(frac > 0.0);
    let dim = n + q * m;
    let mut ad = DMatrix::zeros(dim, dim);
    let mut bd = DMatrix::zeros(dim, m);
    ad.view_mut((0, 0), (n, n)).copy_from(&phi);
    // Column block of the augmented state holding u_{k-j} (j = 1..=q) is n + (q - j) m.
    let slot = |j: usize| n + (q - j) * m;
    if frac > 0.0 {
        let (_, gamma_f) = phi_gamma(a, b, frac)?;
        let gamma1 = &phi_rest * gamma_f;
        ad.view_mut((0, slot(d + 1)), (n, m)).copy_from(&gamma1);
    }
    if d == 0 {
        bd.view_mut((0, 0), (n, m)).copy_from(&gamma0);
    } else {
        ad.view_mut((0, slot(d)), (n, m)).copy_from(&gamma0);
    }
    // Shift register: u_{k-j} at time k+1 is u_{k-j+1} at time k; the newest slot takes u_k.
    for j in 2..=q {
        for i in 0..m {
            ad[(slot(j) + i, slot(j - 1) + i)] = 1.0;
        }
    }
    if q > 0 {
        for i in 0..m {
            bd[(slot(1) + i, i)] = 1.0;
        }
    }
    Ok(DelayedZoh {
        a: ad,
        b: bd,
        delay_inputs: q,
    })
}
