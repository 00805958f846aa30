//! Fixed-step RK4 under zero-order-hold inputs with an optional input delay.
//!
//! Inputs are issued at the sample instants k T and held. A delay of tau = (d + f) T, with d an
//! integer number of samples and 0 <= f < 1, means the input issued at j T acts on
//! [j T + tau, (j + 1) T + tau). Each sample interval is therefore split exactly at k T + f T:
//! the first part runs on the input issued d + 1 samples earlier, the second on the one issued d
//! samples earlier, so a fractional delay is not rounded to the integration grid.
use std::collections::VecDeque;

use crate::error::{Result, SimError};
use crate::system::{Dimensions, System};

/// Fractional rounding slack when a delay in seconds is converted to samples.
const DELAY_SNAP: f64 = 1e-9;

/// An input delay as whole samples plus a fraction of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InputDelay {
    samples: usize,
    fraction: f64,
}

impl InputDelay {
    /// No delay.
    pub fn none() -> Self {
        Self::default()
    }

    /// A delay of a whole number of samples.
    pub fn samples(samples: usize) -> Self {
        Self {
            samples,
            fraction: 0.0,
        }
    }

    /// A delay of `seconds` at sample period `period`; a fraction of a sample is kept exactly.
    pub fn from_seconds(seconds: f64, period: f64) -> Result<Self> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(SimError::invalid(
                "input delay",
                seconds,
                "must be finite and >= 0 s",
            ));
        }
        check_positive("sample period", period)?;
        let in_samples = seconds / period;
        let mut samples = in_samples.floor();
        let mut fraction = in_samples - samples;
        if fraction > 1.0 - DELAY_SNAP {
            samples += 1.0;
            fraction = 0.0;
        } else if fraction < DELAY_SNAP {
            fraction = 0.0;
        }
        if samples > 1e6 {
            return Err(SimError::invalid(
                "input delay",
                seconds,
                "is more than a million samples",
            ));
        }
        Ok(Self {
            samples: samples as usize,
            fraction,
        })
    }

    /// Whole samples of delay.
    pub fn whole_samples(&self) -> usize {
        self.samples
    }

    /// Fraction of a sample, in [0, 1).
    pub fn fraction(&self) -> f64 {
        self.fraction
    }
}

/// Simulation settings.
#[derive(Debug, Clone, PartialEq)]
pub struct ZohOptions {
    /// Sample period T of the held inputs, s.
    pub period: f64,
    /// RK4 steps per sample period (a delay split adds at most one).
    pub substeps: usize,
    /// Input delay.
    pub delay: InputDelay,
    /// The input in effect before the first delayed input arrives.
    pub initial_input: Vec<f64>,
}

/// Integrates a [`System`] one sample period at a time.
///
/// ```
/// use sim::{System, integrate::{Zoh, ZohOptions, InputDelay}};
/// /// dx/dt = u: the state is the integral of the held input.
/// struct Integrator;
/// impl System for Integrator {
///     fn state_names(&self) -> Vec<String> { vec!["x".into()] }
///     fn input_names(&self) -> Vec<String> { vec!["u".into()] }
///     fn output_names(&self) -> Vec<String> { vec!["x".into()] }
///     fn parameter_names(&self) -> Vec<String> { vec![] }
///     fn nominal_parameters(&self) -> Vec<f64> { vec![] }
///     fn dynamics(&self, _x: &[f64], u: &[f64], _p: &[f64], dx: &mut [f64]) { dx[0] = u[0]; }
///     fn output(&self, x: &[f64], _u: &[f64], _p: &[f64], y: &mut [f64]) { y[0] = x[0]; }
/// }
/// let options = ZohOptions { period: 0.1, substeps: 1, delay: InputDelay::none(), initial_input: vec![0.0] };
/// let mut sim = Zoh::new(&Integrator, vec![], vec![0.0], options).unwrap();
/// sim.advance(&[2.0]).unwrap();
/// assert!((sim.state()[0] - 0.2).abs() < 1e-15);
/// ```
#[derive(Debug)]
pub struct Zoh<'a, S: System + ?Sized> {
    system: &'a S,
    params: Vec<f64>,
    x: Vec<f64>,
    t: f64,
    steps: u64,
    options: ZohOptions,
    /// Issued inputs, oldest first; the last `delay.samples + 2` are kept.
    history: VecDeque<Vec<f64>>,
    work: Rk4Work,
    state_names: Vec<String>,
}

impl<'a, S: System + ?Sized> Zoh<'a, S> {
    /// Starts at t = 0 in state `x0` with parameters `params`.
    pub fn new(system: &'a S, params: Vec<f64>, x0: Vec<f64>, options: ZohOptions) -> Result<Self> {
        let dims = Dimensions::of(system);
        check_len("initial state", dims.states, x0.len())?;
        check_len("parameter vector", dims.parameters, params.len())?;
        check_len("initial input", dims.inputs, options.initial_input.len())?;
        check_positive("sample period", options.period)?;
        if options.substeps == 0 {
            return Err(SimError::invalid("substeps", 0, "must be at least 1"));
        }
        if let Some(i) = x0.iter().position(|v| !v.is_finite()) {
            return Err(SimError::NotFinite {
                context: "initial state".into(),
                field: system.state_names()[i].clone(),
                value: x0[i].to_string(),
            });
        }
        Ok(Self {
            system,
            params,
            work: Rk4Work::new(dims.states),
            x: x0,
            t: 0.0,
            steps: 0,
            history: VecDeque::new(),
            state_names: system.state_names(),
            options,
        })
    }

    /// Current time, s.
    pub fn time(&self) -> f64 {
        self.t
    }

    /// Current state.
    pub fn state(&self) -> &[f64] {
        &self.x
    }

    /// The input that acted on the plant at the end of the last sample period (after the delay).
    pub fn applied_input(&self) -> &[f64] {
        self.delayed(self.options.delay.samples)
    }

    /// Output `h(x, u, p)` at the current time with [`Zoh::applied_input`].
    pub fn output(&self, y: &mut [f64]) {
        self.system
            .output(&self.x, self.applied_input(), &self.params, y);
    }

    /// Issues input `u` at the current sample instant and integrates one sample period.
    pub fn advance(&mut self, u: &[f64]) -> Result<()> {
        check_len("input", self.options.initial_input.len(), u.len())?;
        self.history.push_back(u.to_vec());
        while self.history.len() > self.options.delay.samples + 2 {
            self.history.pop_front();
        }
        let period = self.options.period;
        let fraction = self.options.delay.fraction;
        let d = self.options.delay.samples;
        let substeps = self.options.substeps;
        if fraction > 0.0 {
            let first = ((substeps as f64) * fraction).ceil().max(1.0) as usize;
            let second = ((substeps as f64) * (1.0 - fraction)).ceil().max(1.0) as usize;
            self.integrate(d + 1, fraction * period, first);
            self.integrate(d, (1.0 - fraction) * period, second);
        } else {
            self.integrate(d, period, substeps);
        }
        self.steps += 1;
        self.t = self.steps as f64 * period;
        if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
            return Err(SimError::NotFinite {
                context: format!("simulated state at t = {}", self.t),
                field: self.state_names[i].clone(),
                value: self.x[i].to_string(),
            });
        }
        Ok(())
    }

    /// The input issued `age` samples before the latest one (or the initial input).
    fn delayed(&self, age: usize) -> &[f64] {
        self.history
            .len()
            .checked_sub(age + 1)
            .and_then(|i| self.history.get(i))
            .map_or(self.options.initial_input.as_slice(), Vec::as_slice)
    }

    fn integrate(&mut self, age: usize, duration: f64, steps: usize) {
        let h = duration / steps as f64;
        let u = self.delayed(age).to_vec();
        for _ in 0..steps {
            rk4_step(
                self.system,
                &self.params,
                &mut self.x,
                &u,
                h,
                &mut self.work,
            );
        }
    }
}

/// Scratch vectors for [`rk4_step`], allocated once per simulation.
#[derive(Debug, Clone)]
pub struct Rk4Work {
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
}

impl Rk4Work {
    /// Scratch for a state of dimension `n`.
    pub fn new(n: usize) -> Self {
        Self {
            k: [vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            tmp: vec![0.0; n],
        }
    }
}

/// One classical Runge-Kutta step of length `h` with input `u` held.
pub fn rk4_step<S: System + ?Sized>(
    system: &S,
    p: &[f64],
    x: &mut [f64],
    u: &[f64],
    h: f64,
    work: &mut Rk4Work,
) {
    let Rk4Work { k, tmp } = work;
    let [k1, k2, k3, k4] = k;
    system.dynamics(x, u, p, k1);
    for i in 0..x.len() {
        tmp[i] = x[i] + 0.5 * h * k1[i];
    }
    system.dynamics(tmp, u, p, k2);
    for i in 0..x.len() {
        tmp[i] = x[i] + 0.5 * h * k2[i];
    }
    system.dynamics(tmp, u, p, k3);
    for i in 0..x.len() {
        tmp[i] = x[i] + h * k3[i];
    }
    system.dynamics(tmp, u, p, k4);
    for i in 0..x.len() {
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

pub(crate) fn check_len(what: &str, expected: usize, found: usize) -> Result<()> {
    if expected == found {
        Ok(())
    } else {
        Err(SimError::LengthMismatch {
            what: what.into(),
            expected,
            found,
        })
    }
}

pub(crate) fn check_positive(name: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SimError::invalid(
            name,
            value,
            "must be a positive finite number",
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use proptest::prelude::*;

    /// `x' = A x + B u`, `y = x`.
    #[derive(Debug)]
    struct Linear {
        a: DMatrix<f64>,
        b: DMatrix<f64>,
    }

    fn names(prefix: &str, n: usize) -> Vec<String> {
        (0..n).map(|i| format!("{prefix}{i}")).collect()
    }

    impl System for Linear {
        fn state_names(&self) -> Vec<String> {
            names("x", self.a.nrows())
        }
        fn input_names(&self) -> Vec<String> {
            names("u", self.b.ncols())
        }
        fn output_names(&self) -> Vec<String> {
            names("x", self.a.nrows())
        }
        fn parameter_names(&self) -> Vec<String> {
            Vec::new()
        }
        fn nominal_parameters(&self) -> Vec<f64> {
            Vec::new()
        }
        fn dynamics(&self, x: &[f64], u: &[f64], _p: &[f64], dx: &mut [f64]) {
            let dxv =
                &self.a * DVector::from_column_slice(x) + &self.b * DVector::from_column_slice(u);
            dx.copy_from_slice(dxv.as_slice());
        }
        fn output(&self, x: &[f64], _u: &[f64], _p: &[f64], y: &mut [f64]) {
            y.copy_from_slice(x);
        }
    }

    fn oscillator() -> Linear {
        // Lightly damped oscillator with an unstable real mode: both kinds of dynamics.
        Linear {
            a: DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, -4.0, -0.2, 0.0, 0.0, 0.0, 0.5]),
            b: DMatrix::from_row_slice(3, 1, &[0.0, 1.0, 1.0]),
        }
    }

    fn options(period: f64, substeps: usize, delay: InputDelay) -> ZohOptions {
        ZohOptions {
            period,
            substeps,
            delay,
            initial_input: vec![0.0],
        }
    }

    /// Input sequence used by the delay tests: a few steps of different signs.
    fn input(k: usize) -> f64 {
        [1.0, -0.5, 2.0, 0.0, -1.5, 0.7, 0.3, -2.0][k % 8]
    }

    #[test]
    fn rk4_matches_exact_zoh_discretisation() {
        let sys = oscillator();
        let h = 0.05;
        let (ad, bd) = rigid_body::lti::c2d_zoh(&sys.a, &sys.b, h).unwrap();
        let mut sim = Zoh::new(
            &sys,
            vec![],
            vec![1.0, 0.0, 0.2],
            options(h, 10, InputDelay::none()),
        )
        .unwrap();
        let mut x = DVector::from_column_slice(&[1.0, 0.0, 0.2]);
        for k in 0..40 {
            sim.advance(&[input(k)]).unwrap();
            x = &ad * x + &bd * input(k);
        }
        // RK4 local error ~ (h/10)^5 |A|^5 / 120 per substep: well below 1e-9 here.
        for (s, e) in sim.state().iter().zip(x.iter()) {
            assert!((s - e).abs() < 1e-9 * e.abs().max(1.0), "{s} vs {e}");
        }
        assert!((sim.time() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn rk4_error_falls_with_fourth_power_of_step() {
        let sys = oscillator();
        let exact = rigid_body::lti::expm(&(&sys.a * 1.0)).unwrap()
            * DVector::from_column_slice(&[1.0, 0.0, 0.2]);
        let error = |substeps: usize| {
            let mut sim = Zoh::new(
                &sys,
                vec![],
                vec![1.0, 0.0, 0.2],
                options(1.0, substeps, InputDelay::none()),
            )
            .unwrap();
            sim.advance(&[0.0]).unwrap();
            (DVector::from_column_slice(sim.state()) - &exact).norm()
        };
        let ratio = error(32) / error(64);
        assert!(
            (ratio - 16.0).abs() < 1.0,
            "error ratio {ratio}, expected 16 for RK4"
        );
    }

    #[test]
    fn fractional_and_integer_delays_match_exact_delayed_discretisation() {
        let sys = oscillator();
        let h = 0.1;
        for tau in [0.0, 0.03, 0.1, 0.17, 0.25] {
            let delayed = rigid_body::lti::c2d_zoh_delay(&sys.a, &sys.b, h, tau).unwrap();
            let delay = InputDelay::from_seconds(tau, h).unwrap();
            let mut sim =
                Zoh::new(&sys, vec![], vec![0.5, 0.0, 0.0], options(h, 20, delay)).unwrap();
            let mut z = DVector::zeros(delayed.a.nrows());
            z[0] = 0.5;
            for k in 0..30 {
                sim.advance(&[input(k)]).unwrap();
                z = &delayed.a * z + &delayed.b * input(k);
            }
            for i in 0..3 {
                let (s, e) = (sim.state()[i], z[i]);
                assert!(
                    (s - e).abs() < 1e-9 * e.abs().max(1.0),
                    "tau {tau}: {s} vs {e}"
                );
            }
        }
    }

    #[test]
    fn delay_from_seconds_splits_whole_and_fraction() {
        let d = InputDelay::from_seconds(0.0125, 0.005).unwrap();
        assert_eq!(d.whole_samples(), 2);
        assert!((d.fraction() - 0.5).abs() < 1e-12);
        // 0.3 / 0.1 is 2.9999999999999996 in floating point: snapped to 3 whole samples.
        let d = InputDelay::from_seconds(0.3, 0.1).unwrap();
        assert_eq!((d.whole_samples(), d.fraction()), (3, 0.0));
        assert!(InputDelay::from_seconds(-1.0, 0.1).is_err());
        assert!(InputDelay::from_seconds(0.1, 0.0).is_err());
    }

    #[test]
    fn bad_dimensions_are_named() {
        let sys = oscillator();
        let err =
            Zoh::new(&sys, vec![], vec![1.0], options(0.1, 1, InputDelay::none())).unwrap_err();
        assert_eq!(
            err.to_string(),
            "length mismatch for initial state: expected 3, found 1"
        );
        let mut sim = Zoh::new(
            &sys,
            vec![],
            vec![0.0; 3],
            options(0.1, 1, InputDelay::none()),
        )
        .unwrap();
        let err = sim.advance(&[1.0, 2.0]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "length mismatch for input: expected 1, found 2"
        );
        let err = Zoh::new(
            &sys,
            vec![],
            vec![0.0, f64::NAN, 0.0],
            options(0.1, 1, InputDelay::none()),
        )
        .unwrap_err();
        assert!(err.to_string().contains("\"x1\""), "{err}");
    }

    /// `x' = u`: the state is the exact integral of the delayed, held input.
    #[derive(Debug)]
    struct Integrator;
    impl System for Integrator {
        fn state_names(&self) -> Vec<String> {
            vec!["x".into()]
        }
        fn input_names(&self) -> Vec<String> {
            vec!["u".into()]
        }
        fn output_names(&self) -> Vec<String> {
            vec!["x".into()]
        }
        fn parameter_names(&self) -> Vec<String> {
            Vec::new()
        }
        fn nominal_parameters(&self) -> Vec<f64> {
            Vec::new()
        }
        fn dynamics(&self, _x: &[f64], u: &[f64], _p: &[f64], dx: &mut [f64]) {
            dx[0] = u[0];
        }
        fn output(&self, x: &[f64], _u: &[f64], _p: &[f64], y: &mut [f64]) {
            y[0] = x[0];
        }
    }

    proptest! {
        /// For x' = u the integral of the delayed input is known in closed form: the input issued
        /// at j T acts on [j T + tau, (j + 1) T + tau) intersected with [0, N T].
        #[test]
        fn delayed_integral_is_exact(
            inputs in proptest::collection::vec(-10.0f64..10.0, 1..20),
            tau_samples in 0.0f64..3.0,
        ) {
            let period = 0.01;
            let tau = tau_samples * period;
            let delay = InputDelay::from_seconds(tau, period).unwrap();
            let mut sim = Zoh::new(&Integrator, vec![], vec![0.0], options(period, 1, delay)).unwrap();
            for u in &inputs {
                sim.advance(&[*u]).unwrap();
            }
            let end = inputs.len() as f64 * period;
            let exact: f64 = inputs
                .iter()
                .enumerate()
                .map(|(j, u)| {
                    let start = j as f64 * period + tau;
                    let stop = (start + period).min(end);
                    u * (stop - start).max(0.0)
                })
                .sum();
            prop_assert!((sim.state()[0] - exact).abs() < 1e-12, "{} vs {}", sim.state()[0], exact);
        }
    }
}
