//! Design by controllability (spec §4): the finite-horizon controllability Gramian of the
//! thrust-vectoring x/y/roll/pitch subsystem, its closed-form determinant, and the
//! lever-arm vs inertia trade-off that fixes `l3`.

use crate::error::{require_positive, Error, Result};
use crate::geometry::{j2, N_INPUTS};
use crate::params::PlatformParams;
use nalgebra::DMatrix;

/// `(A, B)` of the x/y/roll/pitch subsystem driven by thrust vectoring only, state
/// `(vx, vy, roll, pitch, roll rate, pitch rate)` (spec §4), with the parameters' `T11`.
pub fn thrust_vectoring_system(p: &PlatformParams) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    p.validate()?;
    let mut a = DMatrix::<f64>::zeros(6, 6);
    let g = j2() * p.g0;
    a.view_mut((0, 2), (2, 2)).copy_from(&g);
    a[(2, 4)] = 1.0;
    a[(3, 5)] = 1.0;
    let mut b = DMatrix::<f64>::zeros(6, N_INPUTS);
    let tilt = j2() * p.input.t11 * (p.l3 / p.i1);
    for col in 0..N_INPUTS {
        b[(0, col)] = p.input.t11[(0, col)] / p.mass;
        b[(1, col)] = p.input.t11[(1, col)] / p.mass;
        b[(4, col)] = tilt[(0, col)];
        b[(5, col)] = tilt[(1, col)];
    }
    Ok((a, b))
}

/// Reachability Gramian `Wc(T) = ∫_0^T e^{-At} B B^T e^{-A^T t} dt`, from one matrix
/// exponential (Van Loan): `exp([[A, B B^T], [0, -A^T]] T) = [[., H12], [0, H22]]` gives
/// `Wc = e^{-AT} H12`. A Lyapunov solve cannot be used here: every pole is at 0.
pub fn reachability_gramian(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    horizon: f64,
) -> Result<DMatrix<f64>> {
    require_positive("horizon", horizon)?;
    let n = a.nrows();
    if a.ncols() != n || b.nrows() != n {
        return Err(Error::Invalid {
            name: "A/B",
            reason: format!(
                "A is {}x{}, B is {}x{}",
                a.nrows(),
                a.ncols(),
                b.nrows(),
                b.ncols()
            ),
        });
    }
    let mut c = DMatrix::<f64>::zeros(2 * n, 2 * n);
    c.view_mut((0, 0), (n, n)).copy_from(&(a * horizon));
    c.view_mut((0, n), (n, n))
        .copy_from(&(b * b.transpose() * horizon));
    c.view_mut((n, n), (n, n))
        .copy_from(&(-a.transpose() * horizon));
    let e = rigid_body::lti::expm(&c)
        .map_err(|err| Error::Numerical(format!("Gramian exponential: {err}")))?;
    let back = rigid_body::lti::expm(&(-a * horizon))
        .map_err(|err| Error::Numerical(format!("e^(-AT): {err}")))?;
    let w = back * e.view((0, n), (n, n));
    Ok((&w + w.transpose()) * 0.5)
}

/// Closed form `det Wc(T) = g0^4 T^18 / 102400 · (l3/I1)^12` (nominal `T11`, any mass).
pub fn gramian_det_closed_form(g0: f64, horizon: f64, l3: f64, i1: f64) -> f64 {
    g0.powi(4) * horizon.powi(18) / 102_400.0 * (l3 / i1).powi(12)
}

/// Roll/pitch inertia as a function of the lever arm (spec §4, eq. 3.32):
/// `I1(l3) = I0 + 2 l1² m_t + k δ² l3² m_t`, with `k = 2` as printed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeverArmTradeoff {
    /// Inertia that does not depend on l3, kg m².
    pub i0: f64,
    /// Mass of one actuation unit, kg.
    pub unit_mass: f64,
    /// Horizontal lever arm l1, m.
    pub l1: f64,
    /// The unit CoG lies `delta · l3` below the vehicle CoG.
    pub delta: f64,
    /// Factor `k` of the vertical term (2 as printed; 3 units would suggest 3).
    pub vertical_factor: f64,
}

impl LeverArmTradeoff {
    /// The paper's numbers: `I0 = 1.4 kg · l1²`, `m_t = 1.2 kg`, `δ = 0.75`, `l1 = 0.1 m`, `k = 2`.
    pub fn paper() -> Self {
        Self {
            i0: 1.4 * 0.01,
            unit_mass: 1.2,
            l1: 0.1,
            delta: 0.75,
            vertical_factor: 2.0,
        }
    }

    fn validate(&self) -> Result<()> {
        require_positive("unit_mass", self.unit_mass)?;
        require_positive("delta", self.delta)?;
        require_positive("vertical_factor", self.vertical_factor)?;
        require_positive("l1", self.l1)?;
        if !(self.i0.is_finite() && self.i0 >= 0.0) {
            return Err(Error::Invalid {
                name: "i0",
                reason: format!("must be >= 0, got {}", self.i0),
            });
        }
        Ok(())
    }

    /// `I1(l3)`, kg m².
    pub fn inertia(&self, l3: f64) -> f64 {
        self.i0
            + 2.0 * self.l1 * self.l1 * self.unit_mass
            + self.vertical_factor * self.delta.powi(2) * l3 * l3 * self.unit_mass
    }

    /// The figure of merit `l3 / I1(l3)` (the Gramian volume grows with its 12th power).
    pub fn merit(&self, l3: f64) -> f64 {
        l3 / self.inertia(l3)
    }

    /// Maximiser `l3 = sqrt((I0 + 2 l1² m_t) / (k δ² m_t))` of `l3 / I1(l3)`.
    pub fn optimal_l3(&self) -> Result<f64> {
        self.validate()?;
        Ok(((self.i0 + 2.0 * self.l1 * self.l1 * self.unit_mass)
            / (self.vertical_factor * self.delta.powi(2) * self.unit_mass))
            .sqrt())
    }
}
