//! Dense helpers on top of nalgebra and `rigid_body::lti`: eigenvalue margins, the centralised
//! Kalman filter, H2 and H∞ norms of the error dynamics.

use crate::error::EventEstError;
use nalgebra::{Complex, DMatrix};
use rigid_body::lti;

/// Spectral radius (largest eigenvalue modulus) of a square matrix.
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    m.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// Eigenvalues of the symmetric part of `m`, ascending.
pub fn sym_eigenvalues(m: &DMatrix<f64>) -> Vec<f64> {
    let s = (m + m.transpose()) * 0.5;
    let mut ev: Vec<f64> = s.symmetric_eigenvalues().iter().copied().collect();
    ev.sort_by(f64::total_cmp);
    ev
}

/// Smallest eigenvalue of the symmetric part of `m` (+∞ for an empty matrix).
pub fn min_eigenvalue(m: &DMatrix<f64>) -> f64 {
    sym_eigenvalues(m).first().copied().unwrap_or(f64::INFINITY)
}

/// Largest eigenvalue of the symmetric part of `m` (−∞ for an empty matrix).
pub fn max_eigenvalue(m: &DMatrix<f64>) -> f64 {
    sym_eigenvalues(m)
        .last()
        .copied()
        .unwrap_or(f64::NEG_INFINITY)
}

pub(crate) fn lti_err(what: &'static str) -> impl Fn(rigid_body::Error) -> EventEstError {
    move |e| EventEstError::Lti {
        what,
        reason: e.to_string(),
    }
}

/// Discrete Lyapunov solution Σ = A Σ Aᵀ + Q.
pub fn dlyap(
    a: &DMatrix<f64>,
    q: &DMatrix<f64>,
    what: &'static str,
) -> Result<DMatrix<f64>, EventEstError> {
    lti::dlyap(a, q).map_err(lti_err(what))
}

/// Steady-state centralised Kalman filter in current-estimator form.
#[derive(Debug, Clone)]
pub struct Kalman {
    /// Gain K (n×p): x̂ = x̂⁻ + K (y − C x̂⁻).
    pub gain: DMatrix<f64>,
    /// A-priori error covariance Σ⁻.
    pub prior: DMatrix<f64>,
    /// A-posteriori error covariance Σ⁺ = (I − KC) Σ⁻.
    pub posterior: DMatrix<f64>,
}

/// Centralised steady-state Kalman filter for x+ = A x + v, y = C x + w (covariances V, W).
pub fn kalman(
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    v: &DMatrix<f64>,
    w: &DMatrix<f64>,
) -> Result<Kalman, EventEstError> {
    let prior = lti::dare(&a.transpose(), &c.transpose(), v, w)
        .map_err(lti_err("Kalman filter DARE (is (A, C) detectable?)"))?;
    let s = c * &prior * c.transpose() + w;
    let chol = s.cholesky().ok_or(EventEstError::NotPositiveDefinite {
        name: "C Σ Cᵀ + W"
    })?;
    let gain = chol.solve(&(c * &prior)).transpose();
    let n = a.nrows();
    let posterior = (DMatrix::identity(n, n) - &gain * c) * &prior;
    let posterior = (&posterior + posterior.transpose()) * 0.5;
    Ok(Kalman {
        gain,
        prior,
        posterior,
    })
}

/// Squared H2 norm of e+ = Â e + B̂ s (output e): tr Σ with Σ = Â Σ Âᵀ + B̂ B̂ᵀ.
pub fn h2_squared(a_hat: &DMatrix<f64>, b_hat: &DMatrix<f64>) -> Result<f64, EventEstError> {
    if spectral_radius(a_hat) >= 1.0 {
        return Err(EventEstError::Verification {
            condition: "ρ((I−LC)A) < 1 for the H2 cost".into(),
            margin: spectral_radius(a_hat) - 1.0,
        });
    }
    Ok(dlyap(
        a_hat,
        &(b_hat * b_hat.transpose()),
        "H2 Gramian Σ = ÂΣÂᵀ + B̂B̂ᵀ",
    )?
    .trace())
}

/// H∞ norm of G(z) = Ĉ (zI − Â)^{-1} B̂ by a frequency sweep over ω ∈ [0, π]
/// (log-spaced near 0, where the slow platoon modes peak, plus the angle of every pole of Â,
/// then refined around every local maximum). Without the poles' angles a lightly damped pole at
/// ω = 2.56 (|p| = 0.92) fell between the grid's points 0.1 apart, and the sweep gave the
/// value at ω = 0, 3.4 % below the peak.
pub fn hinf_norm(a_hat: &DMatrix<f64>, b_hat: &DMatrix<f64>, c_hat: &DMatrix<f64>) -> f64 {
    let n = a_hat.nrows();
    let eval = |omega: f64| -> f64 {
        let z = Complex::new(omega.cos(), omega.sin());
        let m: DMatrix<Complex<f64>> = DMatrix::from_fn(n, n, |i, j| {
            let d = if i == j { z } else { Complex::new(0.0, 0.0) };
            d - Complex::new(a_hat[(i, j)], 0.0)
        });
        let rhs = b_hat.map(|v| Complex::new(v, 0.0));
        let Some(x) = m.lu().solve(&rhs) else {
            return f64::INFINITY;
        };
        let g = c_hat.map(|v| Complex::new(v, 0.0)) * x;
        g.singular_values().iter().copied().fold(0.0, f64::max)
    };
    let mut grid: Vec<f64> = vec![0.0];
    let points = 400;
    for k in 0..points {
        // 1e-6 .. π, logarithmic.
        let t = k as f64 / (points - 1) as f64;
        grid.push(1e-6 * (std::f64::consts::PI / 1e-6).powf(t));
    }
    grid.extend(
        a_hat
            .complex_eigenvalues()
            .iter()
            .map(|p| p.im.atan2(p.re).abs()),
    );
    grid.sort_by(f64::total_cmp);
    // A conjugate pair gives its angle twice; a repeated point would make the bracket around
    // it one-sided (a pair at 2.938 rad whose peak lies at 2.976 was read 3.6 % low).
    grid.dedup();
    let values: Vec<f64> = grid.iter().map(|&w| eval(w)).collect();
    let mut best = values.iter().copied().fold(0.0, f64::max);
    // Golden-section refinement in the bracket around every local maximum of the grid: the
    // largest grid value need not sit beside the largest peak.
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for i in 0..grid.len() {
        let left = if i > 0 {
            values[i - 1]
        } else {
            f64::NEG_INFINITY
        };
        let right = values.get(i + 1).copied().unwrap_or(f64::NEG_INFINITY);
        if values[i] < left || values[i] < right {
            continue;
        }
        let mut lo = grid[i.saturating_sub(1)];
        let mut hi = grid[(i + 1).min(grid.len() - 1)];
        for _ in 0..60 {
            let m1 = hi - phi * (hi - lo);
            let m2 = lo + phi * (hi - lo);
            let (g1, g2) = (eval(m1), eval(m2));
            best = best.max(g1).max(g2);
            if g1 > g2 {
                hi = m2;
            } else {
                lo = m1;
            }
        }
    }
    best
}

/// Cholesky factor (lower) of a symmetric positive definite matrix, or a named error.
pub fn cholesky_lower(m: &DMatrix<f64>, name: &'static str) -> Result<DMatrix<f64>, EventEstError> {
    Ok(m.clone()
        .cholesky()
        .ok_or(EventEstError::NotPositiveDefinite { name })?
        .l())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest singular value of G(e^{iω}) on a dense sweep of 200 001 points over
    /// [0, π]: the independent reference.
    fn dense_sweep(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (0..=200_000)
            .map(|k| {
                let w = std::f64::consts::PI * k as f64 / 200_000.0;
                let z = Complex::new(w.cos(), w.sin());
                let m = DMatrix::from_fn(3, 3, |i, j| {
                    (if i == j { z } else { Complex::new(0.0, 0.0) }) - Complex::new(a[(i, j)], 0.0)
                });
                let x = m.lu().solve(&b.map(|v| Complex::new(v, 0.0))).unwrap();
                x.singular_values().max()
            })
            .fold(0.0, f64::max)
    }

    /// Two cases the property test of the bounded-real certificate found, A = A0 ρ/ρ(A0) and
    /// B from the same draw: a lightly damped pole pair at ω = 2.556 (|p| = 0.919) between
    /// the sweep's log-spaced points (the sweep gave the value at ω = 0, 3.4 % low), and a
    /// pair at 2.938 rad whose peak lies at 2.976 (the repeated angle of the pair made the
    /// refinement's bracket one-sided, 3.6 % low). The norm is the dense sweep's within 1e-6.
    #[test]
    fn a_sharp_peak_between_the_grid_points_is_found() {
        let cases: [([f64; 15], f64); 2] = [
            (
                [
                    0.8129301032335399,
                    -0.2725659240154933,
                    -0.2521819936160757,
                    -0.4835954286014227,
                    -0.7242244966919832,
                    -0.4070255364816848,
                    0.5199427729562413,
                    0.4576783489733033,
                    -0.7530635488836819,
                    0.8271853796774447,
                    0.40323922139880547,
                    0.0,
                    -0.2734079919051301,
                    0.45961286030006504,
                    0.0,
                ],
                0.9187878586580117,
            ),
            (
                [
                    0.0,
                    0.38177458113825563,
                    -0.3678250259124011,
                    -0.41523826959621535,
                    -0.13939815481274268,
                    -0.39277328620280444,
                    -0.9821422726949992,
                    -0.04973409221608668,
                    -0.46782607850512187,
                    0.0,
                    -0.17678551686682778,
                    0.0,
                    -0.8669102171325703,
                    0.0,
                    0.7418826354378887,
                ],
                0.8848447200156628,
            ),
        ];
        for (v, rho) in cases {
            let a0 = DMatrix::from_column_slice(3, 3, &v[..9]);
            let a = &a0 * (rho / spectral_radius(&a0));
            let b = DMatrix::from_column_slice(3, 2, &v[9..]);
            let dense = dense_sweep(&a, &b);
            let norm = hinf_norm(&a, &b, &DMatrix::identity(3, 3));
            assert!(
                (norm - dense).abs() <= 1e-6 * dense,
                "{norm} against {dense}"
            );
        }
    }
}
