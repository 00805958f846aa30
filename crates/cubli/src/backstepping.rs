//! The backstepping balancing law (1.10) with its Lyapunov function (1.11) and the integral
//! extension of spec §3.3.
use nalgebra::Vector3;

use crate::model::split_momentum;
use crate::{CubliError, Params, ReducedState};

/// The four tuning parameters α, β, γ, δ of (1.10), all positive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gains {
    /// Weight of the controllable momentum p_h⊥.
    pub alpha: f64,
    /// Weight of the tilt m × g.
    pub beta: f64,
    /// Decay rate of z; the yaw braking rate (time constant 1/γ).
    pub gamma: f64,
    /// Coupling of z to the tilt; δ → 0 puts one tilt pole at −γ.
    pub delta: f64,
}

impl Gains {
    /// Validates positivity and finiteness of every gain.
    pub fn new(alpha: f64, beta: f64, gamma: f64, delta: f64) -> Result<Self, CubliError> {
        for (field, value) in [
            ("alpha", alpha),
            ("beta", beta),
            ("gamma", gamma),
            ("delta", delta),
        ] {
            if !value.is_finite() {
                return Err(CubliError::NonFinite { field });
            }
            if value <= 0.0 {
                return Err(CubliError::NonPositive { field, value });
            }
        }
        Ok(Self {
            alpha,
            beta,
            gamma,
            delta,
        })
    }

    /// The gains of the experiments (paper Sec. 5.1): α = 15, β = 18, γ = 12, δ = 10⁻⁵.
    pub fn paper() -> Self {
        Self {
            alpha: 15.0,
            beta: 18.0,
            gamma: 12.0,
            delta: 1e-5,
        }
    }
}

/// Backstepping balancing controller on the reduced state; almost-globally stabilizes upright
/// (Theorem 1) and leaves the yaw momentum p_hᵍ untouched.
///
/// ```
/// use cubli::{Backstepping, Gains, Params, model};
/// let p = Params::reference();
/// let ctrl = Backstepping::new(p, Gains::paper());
/// let up = model::upright(&p, nalgebra::Vector3::zeros());
/// assert!(ctrl.control(&up).unwrap().norm() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backstepping {
    params: Params,
    gains: Gains,
}

impl Backstepping {
    /// Controller for the model `params` (the controller's belief, not necessarily the plant).
    pub fn new(params: Params, gains: Gains) -> Self {
        Self { params, gains }
    }

    /// The controller's model parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }
    /// The gains.
    pub fn gains(&self) -> &Gains {
        &self.gains
    }

    /// Auxiliary variable z = Θ0(α p_h⊥ + β m × g) + p_h − p_w.
    pub fn z(&self, x: &ReducedState) -> Vector3<f64> {
        let (pp, _) = split_momentum(x);
        let k = &self.gains;
        self.params.theta0() * (pp * k.alpha + self.params.m().cross(&x.g) * k.beta) + x.p_h - x.p_w
    }

    /// Lyapunov function (1.11): V = α/2 |p_h⊥|² + mᵀg + |m||g| + zᵀΘ0⁻²z / (2δ).
    pub fn lyapunov(&self, x: &ReducedState) -> f64 {
        let (pp, _) = split_momentum(x);
        let zi = self.params.theta0_inv() * self.z(x);
        0.5 * self.gains.alpha * pp.norm_squared()
            + self.params.m().dot(&x.g)
            + self.params.mg()
            + zi.norm_squared() / (2.0 * self.gains.delta)
    }

    /// Motor torques (1.10), in the expanded form of spec §3.1. Fails on a non-finite state or a
    /// gravity vector whose magnitude is not |g|.
    pub fn control(&self, x: &ReducedState) -> Result<Vector3<f64>, CubliError> {
        x.validate(&self.params)?;
        Ok(self.torque(x))
    }

    /// (1.10) without input checks, for callers that validated the state already.
    pub(crate) fn torque(&self, x: &ReducedState) -> Vector3<f64> {
        let p = &self.params;
        let k = &self.gains;
        let (pp, _) = split_momentum(x);
        let w = x.omega_h(p);
        let mxg = p.m().cross(&x.g);
        mxg + p.theta0()
            * (mxg * (k.alpha + k.beta * k.gamma + k.delta)
                + pp.cross(&w) * k.alpha
                + p.m().cross(&x.g.cross(&w)) * k.beta
                + pp * (k.gamma * k.alpha))
            + x.p_h.cross(&w)
            + (x.p_h - x.p_w) * k.gamma
    }
}

/// Backstepping with the integral extension û = u + ν z_int, ż_int = z (spec §3.3): removes the
/// effect of a constant torque bias, but not the wheel spin caused by a wrong centre of mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IntegralBackstepping {
    inner: Backstepping,
    nu: f64,
    z_int: Vector3<f64>,
}

impl IntegralBackstepping {
    /// Integral gain `nu` ≥ 0; the integrator starts at zero.
    pub fn new(inner: Backstepping, nu: f64) -> Result<Self, CubliError> {
        if !nu.is_finite() || nu < 0.0 {
            return Err(CubliError::NonPositive {
                field: "nu",
                value: nu,
            });
        }
        Ok(Self {
            inner,
            nu,
            z_int: Vector3::zeros(),
        })
    }

    /// The controller's model parameters.
    pub fn params(&self) -> &Params {
        self.inner.params()
    }

    /// Torque û = u + ν z_int for the current integrator value.
    pub fn control(&self, x: &ReducedState) -> Result<Vector3<f64>, CubliError> {
        Ok(self.inner.control(x)? + self.z_int * self.nu)
    }

    /// Advances the integrator by `dt` with z(x) (rectangle rule at the sample time).
    pub fn advance(&mut self, x: &ReducedState, dt: f64) {
        self.z_int += self.inner.z(x) * dt;
    }

    /// The integrator state z_int.
    pub fn z_int(&self) -> &Vector3<f64> {
        &self.z_int
    }

    /// V_I = V + ν/(2δ) z_intᵀ Θ0⁻² z_int.
    pub fn lyapunov(&self, x: &ReducedState) -> f64 {
        let zi = self.inner.params.theta0_inv() * self.z_int;
        self.inner.lyapunov(x) + self.nu / (2.0 * self.inner.gains.delta) * zi.norm_squared()
    }
}
