//! The tuning method (1.33)–(1.35): from desired tilt poles and a yaw rate to the four gains.
use nalgebra::{Complex, Matrix3};

use crate::{CubliError, Gains};

/// Tilt characteristic polynomial s³ + A s² + B s + C of the linearized closed loop (1.31).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltPolynomial {
    /// A = β̂ + γ̂.
    pub a: f64,
    /// B = α̂ + β̂γ̂ + δ̂.
    pub b: f64,
    /// C = γ̂ α̂.
    pub c: f64,
}

/// Admissible values of γ̂ (1.35): at most two open intervals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GammaIntervals {
    intervals: [(f64, f64); 2],
    count: usize,
}

impl GammaIntervals {
    /// The intervals (lower, upper), lowest first.
    pub fn as_slice(&self) -> &[(f64, f64)] {
        &self.intervals[..self.count]
    }
    /// Whether γ̂ lies inside one of the intervals.
    pub fn contains(&self, gamma_hat: f64) -> bool {
        self.as_slice()
            .iter()
            .any(|(lo, hi)| gamma_hat > *lo && gamma_hat < *hi)
    }
}

impl TiltPolynomial {
    /// Polynomial with the given closed-loop poles; they need negative real parts and complex
    /// ones must come in conjugate pairs.
    pub fn from_poles(poles: &[Complex<f64>; 3]) -> Result<Self, CubliError> {
        for (index, p) in poles.iter().enumerate() {
            let reason = if !p.re.is_finite() || !p.im.is_finite() {
                Some("not finite")
            } else if p.re >= 0.0 {
                Some("real part must be negative")
            } else {
                None
            };
            if let Some(reason) = reason {
                return Err(CubliError::InvalidPole {
                    index,
                    re: p.re,
                    im: p.im,
                    reason,
                });
            }
        }
        let [s0, s1, s2] = *poles;
        let a = -(s0 + s1 + s2);
        let b = s0 * s1 + s0 * s2 + s1 * s2;
        let c = -(s0 * s1 * s2);
        let scale = 1.0 + a.l1_norm() + b.l1_norm() + c.l1_norm();
        if a.im.abs() + b.im.abs() + c.im.abs() > 1e-9 * scale {
            let index = poles.iter().position(|p| p.im != 0.0).unwrap_or(0);
            return Err(CubliError::InvalidPole {
                index,
                re: poles[index].re,
                im: poles[index].im,
                reason: "complex poles must come in conjugate pairs",
            });
        }
        Ok(Self {
            a: a.re,
            b: b.re,
            c: c.re,
        })
    }

    /// Forward map (1.33) for gains and |m||g|.
    pub fn from_gains(gains: &Gains, mg: f64) -> Self {
        let (ah, bh, gh, dh) = (
            gains.alpha * mg,
            gains.beta * mg,
            gains.gamma,
            gains.delta * mg,
        );
        Self {
            a: bh + gh,
            b: ah + bh * gh + dh,
            c: gh * ah,
        }
    }

    /// h(s) = s³ − A s² + B s − C; its zeros are the negated poles.
    pub fn h(&self, s: f64) -> f64 {
        ((s - self.a) * s + self.b) * s - self.c
    }

    /// Roots of s³ + A s² + B s + C (the closed-loop tilt poles), from the companion matrix.
    pub fn poles(&self) -> [Complex<f64>; 3] {
        let comp = Matrix3::new(-self.a, -self.b, -self.c, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
        let e = comp.complex_eigenvalues();
        let mut out = [e[0], e[1], e[2]];
        out.sort_unstable_by(|x, y| y.re.total_cmp(&x.re));
        out
    }

    /// The admissible γ̂ set (1.35): 0 < γ̂ < A and h(γ̂) > 0.
    pub fn admissible_gamma(&self) -> GammaIntervals {
        let scale = 1.0 + self.a.abs();
        let mut roots = [0.0; 3];
        let mut n = 0;
        for p in self.poles() {
            if p.im.abs() <= 1e-9 * scale {
                roots[n] = -p.re;
                n += 1;
            }
        }
        roots[..n].sort_unstable_by(f64::total_cmp);
        let mut out = GammaIntervals {
            intervals: [(0.0, 0.0); 2],
            count: 0,
        };
        let mut push = |lo: f64, hi: f64| {
            let (lo, hi) = (lo.max(0.0), hi.min(self.a));
            if hi > lo {
                out.intervals[out.count] = (lo, hi);
                out.count += 1;
            }
        };
        match n {
            3 => {
                push(roots[0], roots[1]);
                push(roots[2], self.a);
            }
            1 => push(roots[0], self.a),
            _ => {}
        }
        out
    }

    /// Inverse map (1.34) and unscaling: the gains that realize this polynomial with yaw rate γ̂.
    pub fn gains(&self, gamma_hat: f64, mg: f64) -> Result<Gains, CubliError> {
        if !mg.is_finite() || mg <= 0.0 {
            return Err(CubliError::NonPositive {
                field: "|m||g|",
                value: mg,
            });
        }
        let h = self.h(gamma_hat);
        let admissible = gamma_hat > 0.0 && gamma_hat < self.a && h > 0.0;
        if !admissible {
            return Err(CubliError::InadmissibleGamma {
                gamma_hat,
                a: self.a,
                h,
            });
        }
        Gains::new(
            self.c / gamma_hat / mg,
            (self.a - gamma_hat) / mg,
            gamma_hat,
            h / gamma_hat / mg,
        )
    }
}
