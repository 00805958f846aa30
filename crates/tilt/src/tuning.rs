//! Step sizes q (for g) and r (for Omega) and the local-convergence certificate of Theorem 2:
//! the 2x2 matrix `A_s` must have spectral radius below one (spec section 5.4-5.5).

use nalgebra::{Matrix3, SymmetricEigen};

use crate::{math, Layout};

/// Step sizes with the eigenvalues of `A_s` they give.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tuning {
    /// Step size of the gravity update (dimensionless).
    pub q: f64,
    /// Step size of the Omega update (1/m^2).
    pub r: f64,
    /// Eigenvalues of `A_s`, ascending (real: `A_s` is non-negative).
    pub eigenvalues: [f64; 2],
    /// How the step sizes were chosen.
    pub rule: TuningRule,
}

/// Origin of a [`Tuning`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TuningRule {
    /// `q = 1/L`, `r = r*` of (2.48).
    ClosedForm,
    /// Numerical minimisation of the spectral radius over (q, r), used when (2.48) has no
    /// minimiser (`c < 0`) and the minimum certifies convergence.
    Numerical,
    /// `q = 1/L`, `r = 1/lambda_max(P)` (the longest step for which the Omega gradient step
    /// `I - rP` does not expand), used when no step sizes give a certificate: there the bound
    /// of Theorem 2 is loose and minimising it picks slow steps (five sensors clustered
    /// within 5 cm: 26-37 % of samples converged within 10 000 iterations with the
    /// minimiser's steps, all of them with these).
    GradientStep,
    /// Given by the caller.
    Manual,
}

impl Tuning {
    /// Spectral radius of `A_s`.
    pub fn spectral_radius(&self) -> f64 {
        self.eigenvalues[1].abs().max(self.eigenvalues[0].abs())
    }

    /// True when Theorem 2 certifies local convergence (spectral radius < 1).
    pub fn certified(&self) -> bool {
        self.spectral_radius() < 1.0
    }
}

/// `A_s(q, r) = [[|I - rP|_F, r|p|], [q|p| |I - rP|_F, |1 - qL| + q r |p|^2]]`.
pub fn a_s(layout: &Layout, q: f64, r: f64) -> [[f64; 2]; 2] {
    let a = (Matrix3::identity() - layout.p_outer() * r).norm();
    let p = layout.p_sum().norm();
    let l = layout.len() as f64;
    [[a, r * p], [q * p * a, (1.0 - q * l).abs() + q * r * p * p]]
}

/// Eigenvalues of `A_s(q, r)`, ascending.
pub fn a_s_eigenvalues(layout: &Layout, q: f64, r: f64) -> [f64; 2] {
    let [[a, b], [c, d]] = a_s(layout, q, r);
    let half_trace = 0.5 * (a + d);
    let disc = math::sqrt((0.25 * (a - d) * (a - d) + b * c).max(0.0));
    [half_trace - disc, half_trace + disc]
}

/// Step sizes for the given layout with their certificate.
pub fn manual_tuning(layout: &Layout, q: f64, r: f64) -> Tuning {
    Tuning {
        q,
        r,
        eigenvalues: a_s_eigenvalues(layout, q, r),
        rule: TuningRule::Manual,
    }
}

/// The paper's rule: `q = 1/L` and `r*` minimising `lambda_2(A_s)` (2.48); when `c < 0` the
/// paper's second branch is not a minimiser (spec erratum), so the spectral radius is then
/// minimised numerically over both step sizes; when even that minimum is not below one, the
/// gradient step of [`TuningRule::GradientStep`] is used instead (no certificate).
///
/// ```
/// use nalgebra::Vector3;
/// let layout = tilt::Layout::new(&[
///     Vector3::new(1.0, 0.0, 0.0),
///     Vector3::new(0.0, 1.0, 0.0),
///     Vector3::new(0.0, 0.0, 1.0),
///     Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
/// ])?;
/// let tuning = tilt::default_tuning(&layout);
/// assert!((tuning.r - 0.975).abs() < 1e-3 && tuning.certified());
/// # Ok::<(), tilt::TiltError>(())
/// ```
pub fn default_tuning(layout: &Layout) -> Tuning {
    let l = layout.len() as f64;
    let t = layout.p_outer().trace();
    let f = layout.p_outer().norm_squared();
    let a = layout.p_sum().norm_squared() / l;
    if f > a * a {
        let c = (t * t - 3.0 * a * a) / (f - a * a);
        if c >= 0.0 {
            let r = (t - math::sqrt((t * t - c * f).max(0.0))) / f;
            let q = 1.0 / l;
            return Tuning {
                q,
                r,
                eigenvalues: a_s_eigenvalues(layout, q, r),
                rule: TuningRule::ClosedForm,
            };
        }
    }
    let numerical = numerical_tuning(layout);
    if numerical.certified() {
        return numerical;
    }
    let q = 1.0 / l;
    let r = 1.0 / SymmetricEigen::new(*layout.p_outer()).eigenvalues.max();
    Tuning {
        q,
        r,
        eigenvalues: a_s_eigenvalues(layout, q, r),
        rule: TuningRule::GradientStep,
    }
}

/// Minimises the spectral radius of `A_s` over the box `q in [0.1/L, 2/L]`,
/// `r in [1e-3/tr P, 4/tr P]` by a logarithmic grid followed by a shrinking pattern search
/// kept inside the box (a 2-D problem for which no solver dependency is warranted in a
/// `no_std` crate). The lower bound on q keeps the gravity update from stalling: the radius
/// tends to `max(|I - rP|_F, 1)` as q goes to 0.
pub fn numerical_tuning(layout: &Layout) -> Tuning {
    let l = layout.len() as f64;
    let t = layout.p_outer().trace();
    let (lq_min, lq_max) = (math::ln(0.1 / l), math::ln(2.0 / l));
    let (lr_min, lr_max) = (math::ln(1e-3 / t), math::ln(4.0 / t));
    let radius = |lq: f64, lr: f64| {
        let [lo, hi] = a_s_eigenvalues(layout, math::exp(lq), math::exp(lr));
        lo.abs().max(hi.abs())
    };
    const GRID: usize = 48;
    let mut best = (lq_min, lr_min, f64::INFINITY);
    for i in 0..=GRID {
        for j in 0..=GRID {
            let lq = lq_min + (lq_max - lq_min) * i as f64 / GRID as f64;
            let lr = lr_min + (lr_max - lr_min) * j as f64 / GRID as f64;
            let rho = radius(lq, lr);
            if rho < best.2 {
                best = (lq, lr, rho);
            }
        }
    }
    let mut step = (lq_max - lq_min).max(lr_max - lr_min) / GRID as f64;
    while step > 1e-9 {
        let mut improved = false;
        for (dq, dr) in [(step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step)] {
            let lq = (best.0 + dq).clamp(lq_min, lq_max);
            let lr = (best.1 + dr).clamp(lr_min, lr_max);
            let rho = radius(lq, lr);
            if rho < best.2 {
                best = (lq, lr, rho);
                improved = true;
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    let (q, r) = (math::exp(best.0), math::exp(best.1));
    Tuning {
        q,
        r,
        eigenvalues: a_s_eigenvalues(layout, q, r),
        rule: TuningRule::Numerical,
    }
}
