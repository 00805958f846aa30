//! Hover-linear model with switchable effects (spec §3.6, §6.7): state space and FRF.
//!
//! State `x = (vx vy vz roll pitch yaw wx wy wz)` (velocity of the CoG in the yaw-aligned
//! frame J, Z-Y-X Euler angles, body rates), in deviation from hover; when the actuator lag
//! is enabled the nine lagged thrusts are appended as states 9..18. Inputs are the nine
//! thrusts `(F1x .. F3z)` minus the hover trim. Outputs are the identification outputs
//! `(vx vy vz wx wy wz)` of spec §6.5. The input delay is not a state: it is returned in
//! [`StateSpace::delay`] and applied as `e^{-j w Td}` in the frequency response.

use crate::effects::{EffectSet, ParamSpec};
use crate::error::{Error, Result};
use crate::geometry::{circumradius, j2, N_INPUTS};
use crate::params::PlatformParams;
use nalgebra::{Complex, DMatrix};

/// Names of the nine hover states, in order.
pub const STATE_NAMES: [&str; 9] = ["vx", "vy", "vz", "roll", "pitch", "yaw", "wx", "wy", "wz"];
/// Names of the six identification outputs, in order.
pub const OUTPUT_NAMES: [&str; 6] = ["vx", "vy", "vz", "wx", "wy", "wz"];

/// Indices of the hover states.
pub(crate) mod idx {
    pub const VX: usize = 0;
    pub const VY: usize = 1;
    pub const VZ: usize = 2;
    pub const ROLL: usize = 3;
    pub const PITCH: usize = 4;
    pub const YAW: usize = 5;
    pub const WX: usize = 6;
    pub const WY: usize = 7;
    pub const WZ: usize = 8;
}

/// Continuous-time model `x' = A x + B u(t - delay)`, `y = C x + D u(t - delay)`; here A is
/// n x n (n = 9, or 18 with the actuator lag), B n x 9, C 6 x n, D 6 x 9 (zero). The one
/// state-space type of stabilis, shared with the workbench.
pub use rigid_body::lti::StateSpace;

/// A flying-platform model: vehicle parameters plus a set of enabled effects.
///
/// ```
/// use flying_platform::{Effect, Model};
/// let mut model = Model::augmented();
/// assert_eq!(model.param_names()[0], "c_alpha1");
/// model.set_parameter("td", 0.025).unwrap();
/// let g = model.frequency_response(&[1.0, 10.0]).unwrap();
/// assert_eq!((g[0].nrows(), g[0].ncols()), (6, 9));
/// assert!(model.set_parameter("c_alpha1", -1.0).is_err()); // below its bound
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Model {
    /// Vehicle parameters (mass, geometry, inertias, input matrix).
    pub params: PlatformParams,
    /// Enabled effects and their parameters.
    pub effects: EffectSet,
}

impl Model {
    /// A model from parameters and effects.
    pub fn new(params: PlatformParams, effects: EffectSet) -> Self {
        Self { params, effects }
    }

    /// The paper's low-complexity model: Table-3 parameters, no effect.
    pub fn low_complexity() -> Self {
        Self::new(PlatformParams::default(), EffectSet::none())
    }

    /// The paper's augmented model: Table-3 parameters, drag + gyroscopic + delay.
    pub fn augmented() -> Self {
        Self::new(PlatformParams::default(), EffectSet::augmented())
    }

    /// Declarations of the flat parameter vector (enabled effects, canonical order).
    pub fn param_specs(&self) -> Vec<ParamSpec> {
        self.effects.param_specs()
    }

    /// Names of the flat parameter vector.
    pub fn param_names(&self) -> Vec<&'static str> {
        self.effects.param_names()
    }

    /// The flat parameter vector of the enabled effects.
    pub fn parameter_vector(&self) -> Vec<f64> {
        self.effects.to_vector()
    }

    /// Sets the flat parameter vector of the enabled effects (length and bounds checked).
    pub fn set_parameter_vector(&mut self, theta: &[f64]) -> Result<()> {
        self.effects.set_vector(theta)
    }

    /// A named effect parameter.
    pub fn parameter(&self, name: &str) -> Result<f64> {
        self.effects.get(name)
    }

    /// Sets a named effect parameter (bounds checked).
    pub fn set_parameter(&mut self, name: &str, value: f64) -> Result<()> {
        self.effects.set(name, value)
    }

    /// The 9-state hover matrices `(A, B)` without actuator lag (the paper's `A_a`, `B_a`
    /// when drag and gyroscopic effects are enabled; `A0`, `B0` when none is).
    pub fn hover_matrices(&self) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
        use idx::*;
        let p = &self.params;
        p.validate()?;
        let mut a = DMatrix::<f64>::zeros(9, 9);
        a[(VX, PITCH)] = p.g0;
        a[(VY, ROLL)] = -p.g0;
        a[(ROLL, WX)] = 1.0;
        a[(PITCH, WY)] = 1.0;
        a[(YAW, WZ)] = 1.0;
        if let Some(d) = self.effects.momentum_drag() {
            let c1 = 3.0 * d.c_alpha1;
            let c2 = 3.0 * d.c_alpha2;
            a[(VX, VX)] -= c1 / p.mass;
            a[(VY, VY)] -= c1 / p.mass;
            a[(VZ, VZ)] -= c2 / p.mass;
            a[(VX, WY)] -= d.l_alpha1 * c1 / p.mass;
            a[(VY, WX)] += d.l_alpha1 * c1 / p.mass;
            a[(WX, VY)] += d.l_alpha2 * c1 / p.i1;
            a[(WY, VX)] -= d.l_alpha2 * c1 / p.i1;
            a[(WX, WX)] -= d.l_alpha3 * c1 / p.i1;
            a[(WY, WY)] -= d.l_alpha3 * c1 / p.i1;
            a[(WZ, WZ)] -= d.l_alpha4 * c2 / p.i3;
        }
        if let Some(h) = self.effects.fan_momentum() {
            a[(WX, WY)] -= 3.0 * h / p.i1;
            a[(WY, WX)] += 3.0 * h / p.i1;
        }
        let inp = &p.input;
        let mut b = DMatrix::<f64>::zeros(9, N_INPUTS);
        let tilt = j2() * inp.t11 * p.l3;
        let rho = circumradius(p.l1);
        for col in 0..N_INPUTS {
            b[(VX, col)] = inp.t11[(0, col)] / p.mass;
            b[(VY, col)] = inp.t11[(1, col)] / p.mass;
            b[(WX, col)] = tilt[(0, col)] / p.i1;
            b[(WY, col)] = tilt[(1, col)] / p.i1;
        }
        for unit in 0..3 {
            let z = 3 * unit + 2;
            b[(VZ, z)] = inp.b_z[unit];
            b[(WX, z)] += rho * inp.v1[(0, unit)] / p.i1;
            b[(WY, z)] += rho * inp.v1[(1, unit)] / p.i1;
            b[(WZ, z - 1)] = inp.t22_y[unit];
            b[(WZ, z)] = inp.t22_z[unit];
        }
        Ok((a, b))
    }

    /// The continuous-time state space with the current parameters.
    pub fn state_space(&self) -> Result<StateSpace> {
        let (a9, b9) = self.hover_matrices()?;
        let (a, b) = match self.effects.actuator_tau() {
            None => (a9, b9),
            Some(tau) => {
                let mut a = DMatrix::<f64>::zeros(18, 18);
                a.view_mut((0, 0), (9, 9)).copy_from(&a9);
                a.view_mut((0, 9), (9, 9)).copy_from(&b9);
                let mut b = DMatrix::<f64>::zeros(18, N_INPUTS);
                for i in 0..N_INPUTS {
                    a[(9 + i, 9 + i)] = -1.0 / tau;
                    b[(9 + i, i)] = 1.0 / tau;
                }
                (a, b)
            }
        };
        let n = a.nrows();
        let mut c = DMatrix::<f64>::zeros(6, n);
        for (row, state) in [idx::VX, idx::VY, idx::VZ, idx::WX, idx::WY, idx::WZ]
            .into_iter()
            .enumerate()
        {
            c[(row, state)] = 1.0;
        }
        Ok(StateSpace {
            a,
            b,
            c,
            d: DMatrix::zeros(6, N_INPUTS),
            delay: self.effects.delay(),
        })
    }

    /// The state space for a given flat effect-parameter vector (the model is not changed).
    pub fn state_space_at(&self, theta: &[f64]) -> Result<StateSpace> {
        let mut m = self.clone();
        m.set_parameter_vector(theta)?;
        m.state_space()
    }

    /// Frequency response `G(jw)` (6 x 9 per frequency, w in rad/s), including
    /// `1/(1 + jw tau)` for the actuator lag and `e^{-jw Td}` for the delay.
    pub fn frequency_response(&self, omegas: &[f64]) -> Result<Vec<DMatrix<Complex<f64>>>> {
        let (a, b) = self.hover_matrices()?;
        let ss = StateSpace {
            a,
            b,
            c: self.state_space()?.c.columns(0, 9).into_owned(),
            d: DMatrix::zeros(6, N_INPUTS),
            delay: self.effects.delay(),
        };
        let tau = self.effects.actuator_tau().unwrap_or(0.0);
        omegas
            .iter()
            .map(|&w| {
                if !w.is_finite() {
                    return Err(Error::Invalid {
                        name: "omegas",
                        reason: format!("frequency {w} is not finite"),
                    });
                }
                let lag = Complex::new(1.0, 0.0) / Complex::new(1.0, w * tau);
                let g = ss
                    .frequency_response_at(w)
                    .map_err(|e| Error::Numerical(e.to_string()))?;
                Ok(g * lag)
            })
            .collect()
    }

    /// Frequency response for a given flat effect-parameter vector.
    pub fn frequency_response_at(
        &self,
        theta: &[f64],
        omegas: &[f64],
    ) -> Result<Vec<DMatrix<Complex<f64>>>> {
        let mut m = self.clone();
        m.set_parameter_vector(theta)?;
        m.frequency_response(omegas)
    }
}
