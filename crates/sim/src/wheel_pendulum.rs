//! A planar reaction-wheel inverted pendulum: a body pivoting on an edge with a motor-driven
//! wheel on its top, like the one-dimensional Cubli balancing on an edge. Upright is unstable;
//! the motor torque accelerates the wheel and reacts on the body.
//!
//! With `phi` the tilt from upright, `omega_w` the wheel speed relative to the body and `tau`
//! the motor torque, Lagrange's equations give
//!
//! ```text
//! Theta_0 phi''   = m l g sin(phi) - tau - C_b phi' + C_w omega_w
//! Theta_w (phi'' + omega_w') = tau - C_w omega_w
//! ```
//!
//! where `Theta_0` is the inertia of everything about the pivot except the wheel's spin inertia
//! `Theta_w` (the convention of the Cubli papers), `m l` is the total mass times the pivot-to-
//! centre-of-mass distance, and `C_b`, `C_w` are viscous friction of pivot and wheel bearing.
use nalgebra::DMatrix;

use crate::error::{Result, SimError};
use crate::system::System;

/// Physical parameters, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelPendulumParams {
    /// Inertia about the pivot without the wheel's spin inertia, kg m^2.
    pub theta_0: f64,
    /// Wheel spin inertia, kg m^2.
    pub theta_w: f64,
    /// Total mass times distance from pivot to centre of mass, kg m.
    pub mass_length: f64,
    /// Viscous friction at the pivot, N m s.
    pub c_b: f64,
    /// Viscous friction of the wheel bearing, N m s.
    pub c_w: f64,
    /// Gravity, m/s^2.
    pub g: f64,
}

impl Default for WheelPendulumParams {
    /// A 15 cm edge balancer of the size of the one-dimensional Cubli prototype: body 0.419 kg
    /// with its centre of mass 0.075 m from the pivot, wheel 0.204 kg at 0.085 m with spin
    /// inertia 0.57e-3 kg m^2, body inertia 3.34e-3 kg m^2 about the pivot.
    fn default() -> Self {
        let (m_b, l_b, m_w, l_w) = (0.419, 0.075, 0.204, 0.085);
        Self {
            theta_0: 3.34e-3 + m_w * l_w * l_w,
            theta_w: 0.57e-3,
            mass_length: m_b * l_b + m_w * l_w,
            c_b: 1.02e-3,
            c_w: 0.05e-3,
            g: 9.81,
        }
    }
}

/// Names of [`WheelPendulumParams`] in the order of the parameter vector.
pub const PARAMETERS: [&str; 6] = ["theta_0", "theta_w", "mass_length", "c_b", "c_w", "g"];

impl WheelPendulumParams {
    /// The parameter vector in the order of [`PARAMETERS`].
    pub fn to_vec(&self) -> Vec<f64> {
        vec![
            self.theta_0,
            self.theta_w,
            self.mass_length,
            self.c_b,
            self.c_w,
            self.g,
        ]
    }

    /// Parameters from a vector in the order of [`PARAMETERS`]; inertias must be positive and
    /// the others finite and not negative.
    pub fn from_slice(p: &[f64]) -> Result<Self> {
        crate::integrate::check_len("wheel-pendulum parameter vector", PARAMETERS.len(), p.len())?;
        for (i, (&value, name)) in p.iter().zip(PARAMETERS).enumerate() {
            let ok = value.is_finite() && if i < 2 { value > 0.0 } else { value >= 0.0 };
            if !ok {
                let rule = if i < 2 {
                    "must be positive"
                } else {
                    "must be finite and >= 0"
                };
                return Err(SimError::invalid(name, value, rule));
            }
        }
        Ok(Self {
            theta_0: p[0],
            theta_w: p[1],
            mass_length: p[2],
            c_b: p[3],
            c_w: p[4],
            g: p[5],
        })
    }

    /// Jacobians `(A, B)` of the dynamics at the upright equilibrium, state (phi, phi', omega_w).
    pub fn linearize(&self) -> (DMatrix<f64>, DMatrix<f64>) {
        let Self {
            theta_0,
            theta_w,
            mass_length,
            c_b,
            c_w,
            g,
        } = *self;
        let a = DMatrix::from_row_slice(
            3,
            3,
            &[
                0.0,
                1.0,
                0.0,
                mass_length * g / theta_0,
                -c_b / theta_0,
                c_w / theta_0,
                -mass_length * g / theta_0,
                c_b / theta_0,
                -c_w / theta_w - c_w / theta_0,
            ],
        );
        let b =
            DMatrix::from_row_slice(3, 1, &[0.0, -1.0 / theta_0, 1.0 / theta_w + 1.0 / theta_0]);
        (a, b)
    }
}

/// The pendulum as a [`System`]: state and output (phi, phi_dot, omega_w), input `tau`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WheelPendulum {
    /// Nominal parameters.
    pub params: WheelPendulumParams,
}

const SIGNALS: [&str; 3] = ["phi", "phi_dot", "omega_w"];

impl System for WheelPendulum {
    fn state_names(&self) -> Vec<String> {
        SIGNALS.map(String::from).to_vec()
    }

    fn input_names(&self) -> Vec<String> {
        vec!["tau".into()]
    }

    fn output_names(&self) -> Vec<String> {
        SIGNALS.map(String::from).to_vec()
    }

    fn parameter_names(&self) -> Vec<String> {
        PARAMETERS.map(String::from).to_vec()
    }

    fn nominal_parameters(&self) -> Vec<f64> {
        self.params.to_vec()
    }

    fn dynamics(&self, x: &[f64], u: &[f64], p: &[f64], dx: &mut [f64]) {
        let [theta_0, theta_w, mass_length, c_b, c_w, g] = [p[0], p[1], p[2], p[3], p[4], p[5]];
        let (phi, phi_dot, omega_w) = (x[0], x[1], x[2]);
        let tau = u[0];
        let phi_ddot =
            (mass_length * g * phi.sin() - tau - c_b * phi_dot + c_w * omega_w) / theta_0;
        dx[0] = phi_dot;
        dx[1] = phi_ddot;
        dx[2] = (tau - c_w * omega_w) / theta_w - phi_ddot;
    }

    fn output(&self, x: &[f64], _u: &[f64], _p: &[f64], y: &mut [f64]) {
        y.copy_from_slice(x);
    }
}

/// A discrete LQR state feedback `tau = sat(-K x)` with a torque limit.
#[derive(Debug, Clone, PartialEq)]
pub struct Lqr {
    /// Gain, 1 x 3.
    pub k: [f64; 3],
    /// Torque limit of the motor, N m.
    pub torque_max: f64,
    /// Closed-loop matrix `Ad - Bd K` of the discretised linearisation.
    pub closed_loop: DMatrix<f64>,
}

/// LQR weights: `Q = diag(q)` on (phi, phi', omega_w), `R = r` on the torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LqrWeights {
    /// State weights.
    pub q: [f64; 3],
    /// Input weight.
    pub r: f64,
}

impl Default for LqrWeights {
    /// Bryson's rule: 1 deg of tilt, 0.5 rad/s of tilt rate, 20 rad/s of wheel speed and
    /// 0.05 N m of torque cost the same.
    fn default() -> Self {
        let inverse_square = |x: f64| 1.0 / (x * x);
        Self {
            q: [
                inverse_square(1f64.to_radians()),
                inverse_square(0.5),
                inverse_square(20.0),
            ],
            r: inverse_square(0.05),
        }
    }
}

impl Lqr {
    /// Designs the discrete LQR for sample period `period` on the zero-order-hold model of the
    /// linearisation at upright.
    pub fn design(
        params: &WheelPendulumParams,
        weights: &LqrWeights,
        period: f64,
        torque_max: f64,
    ) -> Result<Self> {
        if !(torque_max.is_finite() && torque_max > 0.0) {
            return Err(SimError::invalid(
                "torque limit",
                torque_max,
                "must be positive",
            ));
        }
        let (a, b) = params.linearize();
        let (ad, bd) = rigid_body::lti::c2d_zoh(&a, &b, period)
            .map_err(|e| SimError::domain("discretising the wheel pendulum", e))?;
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&weights.q));
        let r = DMatrix::from_element(1, 1, weights.r);
        let lqr = rigid_body::lti::dlqr(&ad, &bd, &q, &r)
            .map_err(|e| SimError::domain("LQR design for the wheel pendulum", e))?;
        let closed_loop = &ad - &bd * &lqr.k;
        Ok(Self {
            k: [lqr.k[(0, 0)], lqr.k[(0, 1)], lqr.k[(0, 2)]],
            torque_max,
            closed_loop,
        })
    }

    /// Torque for measured state `y`, clipped to the motor limit.
    pub fn torque(&self, y: &[f64]) -> f64 {
        let raw = -(self.k[0] * y[0] + self.k[1] * y[1] + self.k[2] * y[2]);
        raw.clamp(-self.torque_max, self.torque_max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::InputDelay;
    use crate::runner::{run_closed_loop, RunOptions, Trajectory};

    const RATE: f64 = 200.0;
    const TORQUE_MAX: f64 = 0.2;

    fn lqr() -> Lqr {
        Lqr::design(
            &WheelPendulumParams::default(),
            &LqrWeights::default(),
            1.0 / RATE,
            TORQUE_MAX,
        )
        .unwrap()
    }

    fn run(tilt_deg: f64, control: bool, delay: f64, duration: f64, seed: u64) -> Trajectory {
        let system = WheelPendulum::default();
        let lqr = lqr();
        let mut controller = |_t: f64, y: &[f64], u: &mut [f64]| {
            u[0] = if control { lqr.torque(y) } else { 0.0 };
        };
        let options = RunOptions {
            duration,
            sample_rate_hz: RATE,
            substeps: 4,
            delay: InputDelay::from_seconds(delay, 1.0 / RATE).unwrap(),
            noise_std: vec![1e-3, 5e-3, 0.05],
            seed,
        };
        run_closed_loop(
            &system,
            system.nominal_parameters(),
            vec![tilt_deg.to_radians(), 0.0, 0.0],
            &mut controller,
            &options,
            |_| Ok(()),
        )
        .unwrap()
    }

    fn peak(v: &[f64]) -> f64 {
        v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
    }

    #[test]
    fn linearisation_matches_finite_differences() {
        let system = WheelPendulum::default();
        let p = system.nominal_parameters();
        let (a, b) = system.params.linearize();
        let eps = 1e-6;
        let f = |x: &[f64], u: f64| {
            let mut dx = [0.0; 3];
            system.dynamics(x, &[u], &p, &mut dx);
            dx
        };
        for j in 0..3 {
            let mut plus = [0.0; 3];
            let mut minus = [0.0; 3];
            plus[j] = eps;
            minus[j] = -eps;
            let (fp, fm) = (f(&plus, 0.0), f(&minus, 0.0));
            for i in 0..3 {
                let fd = (fp[i] - fm[i]) / (2.0 * eps);
                assert!(
                    (fd - a[(i, j)]).abs() < 1e-6 * a[(i, j)].abs().max(1.0),
                    "A[{i},{j}]: {fd} vs {}",
                    a[(i, j)]
                );
            }
        }
        let (fp, fm) = (f(&[0.0; 3], eps), f(&[0.0; 3], -eps));
        for i in 0..3 {
            let fd = (fp[i] - fm[i]) / (2.0 * eps);
            assert!((fd - b[(i, 0)]).abs() < 1e-6 * b[(i, 0)].abs().max(1.0));
        }
    }

    #[test]
    fn upright_is_unstable_and_the_lqr_closed_loop_is_stable() {
        let (a, _) = WheelPendulumParams::default().linearize();
        let open = a.complex_eigenvalues();
        assert!(open.iter().any(|l| l.re > 5.0), "open loop {open}");
        let closed = lqr().closed_loop.complex_eigenvalues();
        let radius = closed.iter().map(|l| l.norm()).fold(0.0, f64::max);
        // Inside the unit circle, and the slowest mode (the wheel spinning down) decays at
        // more than 0.5 /s.
        let slowest_rate = -radius.ln() * RATE;
        assert!(
            radius < 1.0 && slowest_rate > 0.5,
            "spectral radius {radius}, rate {slowest_rate} /s"
        );
    }

    #[test]
    fn lqr_gain_is_optimal_against_perturbed_gains() {
        // Independent check of the Riccati solution: the LQR cost x0^T P x0 of the designed gain,
        // summed along the discrete closed loop, is below that of every nearby gain.
        let params = WheelPendulumParams::default();
        let weights = LqrWeights::default();
        let (a, b) = params.linearize();
        let (ad, bd) = rigid_body::lti::c2d_zoh(&a, &b, 1.0 / RATE).unwrap();
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&weights.q));
        let cost = |k: &DMatrix<f64>| {
            let mut x = nalgebra::DVector::from_row_slice(&[0.05, 0.0, 0.0]);
            let mut total = 0.0;
            for _ in 0..20_000 {
                let u = -(k * &x);
                total += (x.transpose() * &q * &x)[(0, 0)] + weights.r * u[0] * u[0];
                x = &ad * x + &bd * u;
            }
            total
        };
        let k = DMatrix::from_row_slice(1, 3, &lqr().k);
        let best = cost(&k);
        for j in 0..3 {
            for scale in [0.98, 1.02] {
                let mut other = k.clone();
                other[(0, j)] *= scale;
                assert!(cost(&other) > best, "gain {j} scaled by {scale} is cheaper");
            }
        }
    }

    #[test]
    fn balances_from_five_degrees_with_noise_and_torque_limit() {
        let run = run(5.0, true, 0.0, 5.0, 7);
        let phi = run.state.column("phi").unwrap();
        let tau = run.input.column("tau").unwrap();
        let last_second = &phi[phi.len() - RATE as usize..];
        assert!(
            peak(last_second).to_degrees() < 0.2,
            "tilt {} deg in the last second",
            peak(last_second).to_degrees()
        );
        // The limit is active at the start: the design is tested under saturation.
        assert!((peak(tau) - TORQUE_MAX).abs() < 1e-15);
        let omega = run.state.column("omega_w").unwrap();
        assert!(peak(omega) < 200.0, "wheel speed {}", peak(omega));
    }

    #[test]
    fn balances_with_one_and_a_half_samples_of_delay() {
        let run = run(3.0, true, 1.5 / RATE, 4.0, 1);
        let phi = run.state.column("phi").unwrap();
        assert!(peak(&phi[phi.len() - RATE as usize..]).to_degrees() < 0.3);
    }

    #[test]
    fn falls_without_control_as_the_linearisation_predicts() {
        let run = run(1.0, false, 0.0, 1.5, 0);
        let phi = run.state.column("phi").unwrap();
        assert!(
            peak(phi).to_degrees() > 45.0,
            "only reached {} deg",
            peak(phi).to_degrees()
        );
        // Early on (tilt < 1.5 deg) the fall follows exp(A t) x0 of the linearisation.
        let (a, _) = WheelPendulumParams::default().linearize();
        let x0 = nalgebra::DVector::from_row_slice(&[1f64.to_radians(), 0.0, 0.0]);
        let k = (0.2 * RATE) as usize;
        let linear = rigid_body::lti::expm(&(a * 0.2)).unwrap() * x0;
        assert!(
            (phi[k] - linear[0]).abs() < 1e-3 * linear[0],
            "{} vs {}",
            phi[k],
            linear[0]
        );
    }

    #[test]
    fn bad_parameters_are_named() {
        let mut p = WheelPendulumParams::default().to_vec();
        p[1] = 0.0;
        let err = WheelPendulumParams::from_slice(&p).unwrap_err();
        assert!(err.to_string().starts_with("invalid theta_w = 0"), "{err}");
        assert!(WheelPendulumParams::from_slice(&p[..3]).is_err());
        let err = Lqr::design(
            &WheelPendulumParams::default(),
            &LqrWeights::default(),
            0.005,
            -1.0,
        )
        .unwrap_err();
        assert!(err.to_string().contains("torque limit"));
    }
}
