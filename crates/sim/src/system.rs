//! The `System` trait: what the integrator, the closed-loop runner and the workbench need from a
//! model. Domain crates keep their own fixed-size types; sim adapts them to this slice-based view
//! so that one integrator and one log format serve every system.

/// A continuous-time system `dx/dt = f(x, u, p)`, `y = h(x, u, p)` with named signals.
///
/// Parameters are passed explicitly so that identification can evaluate the same model at other
/// parameter values than its nominal ones.
pub trait System {
    /// Names of the state components; their number is the state dimension.
    fn state_names(&self) -> Vec<String>;
    /// Names of the inputs.
    fn input_names(&self) -> Vec<String>;
    /// Names of the outputs.
    fn output_names(&self) -> Vec<String>;
    /// Names of the parameters, in the order of `p`.
    fn parameter_names(&self) -> Vec<String>;
    /// The parameter values the system was built with.
    fn nominal_parameters(&self) -> Vec<f64>;
    /// Writes `f(x, u, p)` into `dx` (all slices have the dimensions the names give).
    fn dynamics(&self, x: &[f64], u: &[f64], p: &[f64], dx: &mut [f64]);
    /// Writes `h(x, u, p)` into `y`.
    fn output(&self, x: &[f64], u: &[f64], p: &[f64], y: &mut [f64]);
}

/// Signal dimensions of a system, read once from its names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dimensions {
    /// State dimension.
    pub states: usize,
    /// Input dimension.
    pub inputs: usize,
    /// Output dimension.
    pub outputs: usize,
    /// Number of parameters.
    pub parameters: usize,
}

impl Dimensions {
    /// The dimensions of `system`.
    pub fn of<S: System + ?Sized>(system: &S) -> Self {
        Self {
            states: system.state_names().len(),
            inputs: system.input_names().len(),
            outputs: system.output_names().len(),
            parameters: system.parameter_names().len(),
        }
    }
}
