//! The continuous-time state-space model with an input delay, shared by the domain crates and
//! the workbench: its frequency response (continuous, or of the sampled system under a
//! zero-order hold), its zero-order-hold discretisation and its poles.

use super::{c2d_zoh, sized};
use crate::{Error, Result};
use nalgebra::{Complex, DMatrix};
use std::vec::Vec;

/// Complex matrices (a frequency response at one frequency).
pub type CMatrix = DMatrix<Complex<f64>>;

/// Continuous-time `x' = A x + B u(t - delay)`, `y = C x + D u(t - delay)`.
///
/// ```
/// use nalgebra::DMatrix;
/// use rigid_body::lti::StateSpace;
/// // A first-order lag 1 / (s + 1) with a 0.1 s delay.
/// let ss = StateSpace {
///     a: DMatrix::from_element(1, 1, -1.0),
///     b: DMatrix::from_element(1, 1, 1.0),
///     c: DMatrix::from_element(1, 1, 1.0),
///     d: DMatrix::zeros(1, 1),
///     delay: 0.1,
/// };
/// ss.check()?;
/// let g = ss.frequency_response_at(1.0)?[(0, 0)];
/// assert!((g.norm() - 0.5f64.sqrt()).abs() < 1e-12);
/// assert!((g.arg() + std::f64::consts::FRAC_PI_4 + 0.1).abs() < 1e-12);
/// assert_eq!(ss.poles()?[0].re, -1.0);
/// # Ok::<(), rigid_body::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// State matrix.
    pub a: DMatrix<f64>,
    /// Input matrix.
    pub b: DMatrix<f64>,
    /// Output matrix.
    pub c: DMatrix<f64>,
    /// Feed-through.
    pub d: DMatrix<f64>,
    /// Input delay in seconds.
    pub delay: f64,
}

/// The model sampled with a zero-order hold at period `t`, input delay `whole T + f`:
/// `x_{k+1} = Φ x_k + Γ0 u_{k-whole} + Γ1 u_{k-whole-1}`, `y_k = C x_k + D u_{k-d_shift}`.
#[derive(Debug, Clone, PartialEq)]
pub struct Discrete {
    /// State transition Φ.
    pub phi: DMatrix<f64>,
    /// Input matrix of `u_{k-whole}`.
    pub gamma0: DMatrix<f64>,
    /// Input matrix of `u_{k-whole-1}` (zero without a fractional delay).
    pub gamma1: DMatrix<f64>,
    /// Output matrix.
    pub c: DMatrix<f64>,
    /// Feed-through.
    pub d: DMatrix<f64>,
    /// Whole samples of input delay.
    pub whole: usize,
    /// Delay of the feed-through in samples (`whole`, plus one with a fractional delay).
    pub d_shift: usize,
}

impl StateSpace {
    /// Checks the four matrices fit together, naming the one that does not.
    pub fn check(&self) -> Result<()> {
        let n = self.a.nrows();
        let (m, p) = (self.b.ncols(), self.c.nrows());
        if self.a.ncols() != n {
            return Err(Error::NotSquare {
                name: "A",
                rows: n,
                cols: self.a.ncols(),
            });
        }
        sized("B", &self.b, n, m)?;
        sized("C", &self.c, p, n)?;
        sized("D", &self.d, p, m)
    }

    /// Eigenvalues of `A` (see [`super::eigenvalues`]).
    pub fn poles(&self) -> Result<Vec<Complex<f64>>> {
        super::eigenvalues(&self.a)
    }

    /// `(C (jwI - A)^-1 B + D) e^{-jw delay}` at one angular frequency `omega` (rad/s).
    pub fn frequency_response_at(&self, omega: f64) -> Result<CMatrix> {
        let lu = self.shifted(omega).lu();
        let x = lu
            .solve(&self.b.map(Complex::from))
            .ok_or(singular(omega))?;
        let g = self.c.map(Complex::from) * x + self.d.map(Complex::from);
        Ok(g * Complex::new(0.0, -omega * self.delay).exp())
    }

    /// `C (jwI - A)^-1 B + D` (without the delay) and the resolvent pieces `(C X, X B)`,
    /// `X = (jwI - A)^-1`, from which the derivatives with respect to the matrices follow.
    pub fn resolvent(&self, omega: f64) -> Result<(CMatrix, (CMatrix, CMatrix))> {
        let m = self.shifted(omega);
        let xb = m
            .clone()
            .lu()
            .solve(&self.b.map(Complex::from))
            .ok_or(singular(omega))?;
        // (C X)^T = X^T C^T: solve with the transposed matrix.
        let cx = m
            .transpose()
            .lu()
            .solve(&self.c.transpose().map(Complex::from))
            .ok_or(singular(omega))?
            .transpose();
        let g = self.c.map(Complex::from) * &xb + self.d.map(Complex::from);
        Ok((g, (cx, xb)))
    }

    /// `jwI - A`.
    fn shifted(&self, omega: f64) -> CMatrix {
        let n = self.a.nrows();
        let s = Complex::new(0.0, omega);
        CMatrix::from_fn(n, n, |i, j| {
            let a = Complex::from(-self.a[(i, j)]);
            if i == j {
                a + s
            } else {
                a
            }
        })
    }

    /// Frequency responses at `freqs_hz`. With `hold = None` the continuous-time response with
    /// the delay, `(C (jwI - A)^-1 B + D) e^{-jw delay}`. With `hold = Some(T)` the exact response
    /// of the sampled system whose inputs are held over each period T and whose outputs are
    /// sampled at the period boundaries: with the delay `tau = d T + f`,
    /// `x_{k+1} = Φ x_k + Γ0 u_{k-d} + Γ1 u_{k-d-1}` (Åström-Wittenmark), evaluated at
    /// `z = e^{jwT}`. This includes the hold's droop and the aliasing of the plant response.
    pub fn frf_lines(&self, freqs_hz: &[f64], hold: Option<f64>) -> Result<Vec<CMatrix>> {
        let two_pi = 2.0 * core::f64::consts::PI;
        let Some(t) = hold else {
            return freqs_hz
                .iter()
                .map(|f| self.frequency_response_at(two_pi * f))
                .collect();
        };
        let Discrete {
            phi,
            gamma0,
            gamma1,
            whole,
            d_shift,
            ..
        } = self.discretize(t)?;
        let (whole, d_shift) = (whole as f64, d_shift as f64);
        let n = self.a.nrows();
        let c = self.c.map(Complex::from);
        freqs_hz
            .iter()
            .map(|f| {
                let w = two_pi * f;
                let z = Complex::new(0.0, w * t).exp();
                let m = CMatrix::from_fn(n, n, |i, j| {
                    let a = Complex::from(-phi[(i, j)]);
                    if i == j {
                        a + z
                    } else {
                        a
                    }
                });
                let rhs = gamma0.map(Complex::from) + gamma1.map(Complex::from) / z;
                let x = m.lu().solve(&rhs).ok_or(Error::SingularAt {
                    name: "zI - Φ (a pole on the unit circle)",
                    frequency_hz: *f,
                })?;
                let delay = Complex::new(0.0, -w * t * whole).exp();
                let feed = self.d.map(Complex::from) * Complex::new(0.0, -w * t * d_shift).exp();
                Ok(&c * x * delay + feed)
            })
            .collect()
    }

    /// Samples the model with a zero-order hold at period `t` (exact, with the fractional part
    /// of the delay split over two input samples, Åström-Wittenmark).
    pub fn discretize(&self, t: f64) -> Result<Discrete> {
        self.check()?;
        if !(t.is_finite() && t > 0.0) {
            return Err(Error::InvalidParameter {
                name: "sample period",
                value: t,
                requirement: "must be positive and finite",
            });
        }
        if !(self.delay.is_finite() && self.delay >= 0.0) {
            return Err(Error::InvalidParameter {
                name: "delay",
                value: self.delay,
                requirement: "must be non-negative and finite",
            });
        }
        let whole = (self.delay / t).floor();
        let frac = self.delay - whole * t;
        let (phi, g_full) = c2d_zoh(&self.a, &self.b, t)?;
        let fractional = frac > 1e-12 * t;
        let (gamma0, gamma1) = if fractional {
            let (phi_rest, g0) = c2d_zoh(&self.a, &self.b, t - frac)?;
            let (_, gf) = c2d_zoh(&self.a, &self.b, frac)?;
            (g0, &phi_rest * gf)
        } else {
            (g_full, DMatrix::zeros(self.b.nrows(), self.b.ncols()))
        };
        let whole = whole as usize;
        Ok(Discrete {
            phi,
            gamma0,
            gamma1,
            c: self.c.clone(),
            d: self.d.clone(),
            whole,
            d_shift: whole + usize::from(fractional),
        })
    }
}

impl Discrete {
    /// Spectral radius of Φ (above one: the free-run simulation diverges).
    pub fn spectral_radius(&self) -> Result<f64> {
        super::spectral_radius(&self.phi)
    }
}

/// `jwI - A` is singular: a pole on the imaginary axis at `omega`.
fn singular(omega: f64) -> Error {
    Error::SingularAt {
        name: "jwI - A (a pole on the imaginary axis)",
        frequency_hz: omega / (2.0 * core::f64::consts::PI),
    }
}
