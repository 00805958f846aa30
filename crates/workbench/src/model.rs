//! The workbench's model interface: a structure with named parameters and switchable physical
//! effects that yields a continuous-time state-space model for a parameter vector.
//!
//! Domain crates export their effects as plain types; the simulator crate (`sim::systems`)
//! adapts them to [`ModelStructure`].
//! A user-defined effect is an [`Effect`] that edits the state-space model of any structure.
use std::sync::Arc;

use serde::Serialize;

use super::dynamics::Dynamics;
use super::frf::{CMatrix, LineMap, ModelFrf};
use super::spectra::C64;
use crate::error::{Result, SimError};

/// Relative size above which a state's derivative at the operating point counts as drift
/// ([`Model::drift`]): a balance written to a few digits, or at documented values a few per
/// cent off the plant's, stays below it; inputs far from the balance (a hover given at 0.3
/// where it needs 0.55) are far above it.
pub const DRIFT_TOLERANCE: f64 = 0.05;

/// A state that moves at a model's operating point ([`Model::drift`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Drift {
    /// The state.
    pub state: String,
    /// Its derivative at the operating point.
    pub rate: f64,
    /// `rate` over the terms the linearization sums in its row.
    pub relative: f64,
}

impl Drift {
    /// "d(vz)/dt = -4.4500, 84.2 % of its row's linear terms; d(w)/dt = ..." for a list.
    pub fn describe(drift: &[Self]) -> String {
        drift
            .iter()
            .map(|d| {
                let share = if d.relative.is_finite() {
                    format!(", {:.1} % of its row's linear terms", 100.0 * d.relative)
                } else {
                    String::new()
                };
                format!("d({})/dt = {:.4}{share}", d.state, d.rate)
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// A model parameter with its documented value, bounds and unit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Parameter {
    /// Name, unique within a model (effect parameters carry the effect's prefix).
    pub name: String,
    /// Documented (nominal) value: the start of every fit, and the value held when the data
    /// cannot determine the parameter.
    pub value: f64,
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
    /// SI unit.
    pub unit: String,
}

impl Parameter {
    /// A parameter; `lower <= value <= upper` is checked by [`check_parameters`].
    pub fn new(
        name: impl Into<String>,
        value: f64,
        lower: f64,
        upper: f64,
        unit: impl Into<String>,
    ) -> Self {
        Self {
            name: name.into(),
            value,
            lower,
            upper,
            unit: unit.into(),
        }
    }

    /// Typical magnitude used to scale the parameter in fits and identifiability checks.
    pub fn scale(&self) -> f64 {
        let span = if self.upper.is_finite() && self.lower.is_finite() {
            self.upper - self.lower
        } else {
            0.0
        };
        self.value.abs().max(1e-3 * span).max(1e-9)
    }
}

/// Checks names are unique and values lie inside their bounds.
pub fn check_parameters(params: &[Parameter]) -> Result<()> {
    for (i, p) in params.iter().enumerate() {
        if p.lower > p.upper {
            return Err(SimError::invalid(
                &p.name,
                format!("bounds [{}, {}]", p.lower, p.upper),
                "the lower bound (min) exceeds the upper (max)",
            ));
        }
        if !(p.lower <= p.value && p.value <= p.upper && p.value.is_finite()) {
            return Err(SimError::invalid(
                &p.name,
                p.value,
                format!(
                    "documented value must be finite and lie in [{}, {}]",
                    p.lower, p.upper
                ),
            ));
        }
        if params[..i].iter().any(|q| q.name == p.name) {
            return Err(SimError::invalid(
                &p.name,
                "duplicate",
                "parameter names must be unique",
            ));
        }
    }
    Ok(())
}

/// The state-space model every structure yields: one type for the domain crates and the
/// workbench ([`rigid_body::lti::StateSpace`]).
pub use rigid_body::lti::StateSpace;

/// The factor that turns the delay-free continuous response at `omega` into the model's: the
/// delay, and with a zero-order hold of period T its droop `e^{-jwT/2} sin(wT/2) / (wT/2)`.
fn factor(ss: &StateSpace, omega: f64, hold: Option<f64>) -> C64 {
    let delay = C64::new(0.0, -omega * ss.delay).exp();
    match hold {
        Some(t) if omega > 0.0 => {
            let x = 0.5 * omega * t;
            delay * C64::new(0.0, -x).exp() * (x.sin() / x)
        }
        _ => delay,
    }
}

/// A physical effect that edits a state-space model of any structure: the generic effects
/// ([`super::generic`]), effects a user writes in Python, and effects of a Rust program.
pub trait Effect: Send + Sync + std::fmt::Debug {
    /// The effect's name.
    fn name(&self) -> &str;
    /// One-line description of the physics.
    fn description(&self) -> &str;
    /// The effect's parameters.
    fn parameters(&self) -> Vec<Parameter>;
    /// Whether its parameters are reported as `<effect>.<parameter>` (the default, so that two
    /// effects may both call a parameter `k`) or under their own names (the generic effects'
    /// `tau` and `td`).
    fn qualified_names(&self) -> bool {
        true
    }
    /// Whether several threads may evaluate it at once (see [`ModelStructure::parallel`]).
    fn parallel(&self) -> bool {
        true
    }
    /// Adds the effect's terms to `ss` for parameter values `theta` (same order as
    /// [`Effect::parameters`]). It may add states (a lag) or change the delay.
    fn apply(&self, theta: &[f64], ss: &mut StateSpace) -> Result<()>;
    /// Whether the effect has a nonlinear form ([`Effect::apply_dynamics`]), so that the
    /// time-domain criterion can test it.
    fn has_dynamics(&self) -> bool {
        false
    }
    /// Whether the time-domain discovery tries it: by default when it has a nonlinear form.
    /// It may still be enabled by name under that criterion.
    fn searched_in_time(&self) -> bool {
        self.has_dynamics()
    }
    /// The effect on a nonlinear model, for parameter values `theta`.
    fn apply_dynamics(
        &self,
        _theta: &[f64],
        _inner: Box<dyn Dynamics>,
    ) -> Result<Box<dyn Dynamics>> {
        Err(SimError::invalid(
            "effect",
            self.name(),
            "has no nonlinear form, so the time-domain criterion cannot use it",
        ))
    }
    /// Whether the effect changes the frequency response (a constant sensor offset does not:
    /// the FRF has no DC line), so that the FRF criterion can test it.
    fn frf_visible(&self) -> bool {
        true
    }
    /// Whether it filters outputs with states of its own (a sensor lag): such effects apply
    /// after all others, in the linear and the nonlinear model alike, so that their states
    /// come last, where the predictor integrates them exactly.
    fn filters_outputs(&self) -> bool {
        false
    }
    /// Whether it changes inputs where they drive the plant (an actuator's gain or offset):
    /// such effects apply before all others, inside any input lag, whose state the predictor
    /// integrates towards the logged input.
    fn edits_inputs(&self) -> bool {
        false
    }
    /// The inputs (of `inputs`) it puts behind a lag with a state of its own: a second lag on
    /// one of them is not offered once it is in (a lag behind a lag is not integrated exactly,
    /// and the data seldom tell two apart).
    fn lagged_inputs(&self, _inputs: usize) -> Vec<usize> {
        Vec::new()
    }
}

/// A model structure: base parameters plus named optional effects.
pub trait ModelStructure: Send + Sync + std::fmt::Debug {
    /// System name.
    fn system(&self) -> &str;
    /// Input names (must match the data).
    fn inputs(&self) -> Vec<String>;
    /// Output names (must match the data).
    fn outputs(&self) -> Vec<String>;
    /// State names of the model with the `enabled` effects, for messages (numbered when
    /// empty).
    fn state_names(&self, _enabled: &[String]) -> Vec<String> {
        Vec::new()
    }
    /// Names of the effects this structure knows.
    fn effects(&self) -> Vec<String>;
    /// One-line description of an effect.
    fn describe(&self, effect: &str) -> String;
    /// Quantities held at documented values by construction, `(name, value, why)`.
    fn fixed(&self) -> Vec<(String, f64, String)> {
        Vec::new()
    }
    /// Whether several threads may evaluate it at once. Python callables take the
    /// interpreter's lock on every call, so threads would only queue for it, paying a context
    /// switch per call (ten times the calls' own cost, measured): their fits run on one.
    fn parallel(&self) -> bool {
        true
    }
    /// Parameters with `enabled` effects on, base parameters first.
    fn parameters(&self, enabled: &[String]) -> Result<Vec<Parameter>>;
    /// State-space model for `theta` (order of [`ModelStructure::parameters`]).
    fn state_space(&self, enabled: &[String], theta: &[f64]) -> Result<StateSpace>;
    /// The experimenter's controller, for closed-loop re-simulation, if known.
    fn controller(&self) -> Option<super::model_file::Controller> {
        None
    }
    /// Whether [`ModelStructure::dynamics`] gives a nonlinear model.
    fn is_nonlinear(&self) -> bool {
        false
    }
    /// The nonlinear model for `theta`, whose linearization at its operating point is
    /// [`ModelStructure::state_space`]; `None` for a linear structure.
    fn dynamics(&self, _enabled: &[String], _theta: &[f64]) -> Option<Result<Box<dyn Dynamics>>> {
        None
    }
}

/// A structure with some effects enabled, and a pool of further effects ([`Effect`]s: the
/// generic ones every model gets and those a user registers) that discovery may add.
#[derive(Debug, Clone)]
pub struct Model {
    structure: Arc<dyn ModelStructure>,
    /// Candidate effects that are not the structure's own, in the order they were offered.
    pool: Vec<Arc<dyn Effect>>,
    /// Enabled structure effects.
    enabled: Vec<String>,
    /// Enabled pool effects, in the order they were added.
    added: Vec<Arc<dyn Effect>>,
}

impl Model {
    /// The base structure with no effect enabled; the generic effects the structure does not
    /// declare itself ([`super::generic::for_structure`]) are candidates.
    pub fn new(structure: Arc<dyn ModelStructure>) -> Self {
        let pool = super::generic::for_structure(structure.as_ref());
        Self {
            structure,
            pool,
            enabled: Vec::new(),
            added: Vec::new(),
        }
    }

    /// Whether the structure and every effect it may use can be evaluated on several threads.
    pub fn parallel(&self) -> bool {
        self.structure.parallel() && self.offered().chain(&self.added).all(|e| e.parallel())
    }

    /// The pool less the effects the structure now declares itself: an effect declared in the
    /// structure after the model was built (a Python model's) replaces a generic one of that
    /// name, as an effect of a model file does.
    fn offered(&self) -> impl Iterator<Item = &Arc<dyn Effect>> {
        let own = self.structure.effects();
        self.pool
            .iter()
            .filter(move |e| !own.iter().any(|o| o == e.name()))
    }

    /// The structure.
    pub fn structure(&self) -> &Arc<dyn ModelStructure> {
        &self.structure
    }

    /// Names of the enabled effects, in the order they were added.
    pub fn enabled(&self) -> Vec<String> {
        let mut names = self.enabled.clone();
        names.extend(self.added.iter().map(|e| e.name().to_string()));
        names
    }

    /// Every effect name known to the model: the structure's, then the pool's.
    pub fn known(&self) -> Vec<String> {
        let mut names = self.structure.effects();
        names.extend(self.offered().map(|e| e.name().to_string()));
        names
    }

    /// Whether `effect` is a built-in one (offered to every model), not one the file declares.
    pub fn is_builtin(&self, effect: &str) -> bool {
        self.offered().any(|e| e.name() == effect)
    }

    /// One-line description of a known effect.
    pub fn describe(&self, effect: &str) -> String {
        match self.offered().find(|e| e.name() == effect) {
            Some(e) => e.description().to_string(),
            None => self.structure.describe(effect),
        }
    }

    /// The effects discovery may still add: structure effects and pool effects not enabled,
    /// but none that lags an input an added effect already lags ([`Effect::lagged_inputs`]).
    pub fn candidates(&self) -> Vec<String> {
        let on = self.enabled();
        let m = self.structure.inputs().len();
        let lagged: Vec<usize> = self.added.iter().flat_map(|e| e.lagged_inputs(m)).collect();
        let lags_again = |name: &str| {
            self.offered()
                .find(|e| e.name() == name)
                .is_some_and(|e| e.lagged_inputs(m).iter().any(|j| lagged.contains(j)))
        };
        self.known()
            .into_iter()
            .filter(|e| !on.contains(e) && !lags_again(e))
            .collect()
    }

    /// The candidates the FRF criterion can test (those that change the response).
    pub fn frf_candidates(&self) -> Vec<String> {
        self.candidates()
            .into_iter()
            .filter(|c| self.offered().all(|e| e.name() != c || e.frf_visible()))
            .collect()
    }

    /// The candidates the time-domain criterion tests ([`Effect::searched_in_time`]).
    pub fn dynamics_candidates(&self) -> Vec<String> {
        self.candidates()
            .into_iter()
            .filter(|c| {
                self.offered()
                    .all(|e| e.name() != c || e.searched_in_time())
            })
            .collect()
    }

    /// The nonlinear model at `theta`: the structure's, with the added effects' nonlinear
    /// forms.
    pub fn dynamics(&self, theta: &[f64]) -> Result<Box<dyn Dynamics>> {
        let n_struct = self.check_theta(theta)?;
        let mut d = self
            .structure
            .dynamics(&self.enabled, &theta[..n_struct])
            .ok_or_else(|| {
                SimError::invalid(
                    "criterion",
                    "time",
                    format!(
                        "the {} model is linear (no [nonlinear] section): use the FRF criterion",
                        self.structure.system()
                    ),
                )
            })??;
        for (e, at) in self.added_in_state_order(n_struct) {
            d = e.apply_dynamics(&theta[at..at + e.parameters().len()], d)?;
        }
        Ok(d)
    }

    /// The states that move at the operating point of the nonlinear model at `theta`, with
    /// their derivative there: an operating point that is no equilibrium (inputs that do not
    /// balance the model) gives a linearization that is not the loop's. A derivative counts
    /// when it exceeds [`DRIFT_TOLERANCE`] of the terms the linearization sums in its row
    /// (`|A_ij x_j|`, `|B_ij u_j|`), or of the largest row's when its own are all zero.
    /// Empty for a linear structure and at an equilibrium.
    pub fn drift(&self, theta: &[f64]) -> Result<Vec<Drift>> {
        if !self.structure.is_nonlinear() {
            return Ok(Vec::new());
        }
        let d = self.dynamics(theta)?;
        let ss = self.state_space(theta)?;
        let (x, u) = d.operating_point();
        let mut dx = vec![0.0; x.len()];
        d.f(&x, &u, &mut dx, &mut Vec::new())?;
        let terms: Vec<f64> = (0..x.len())
            .map(|i| {
                let a: f64 = x
                    .iter()
                    .enumerate()
                    .map(|(j, xj)| (ss.a[(i, j)] * xj).abs())
                    .sum();
                let b: f64 = u
                    .iter()
                    .enumerate()
                    .map(|(j, uj)| (ss.b[(i, j)] * uj).abs())
                    .sum();
                a + b
            })
            .collect();
        let largest = terms.iter().copied().fold(0.0, f64::max);
        let names = self.structure.state_names(&self.enabled);
        Ok(dx
            .iter()
            .zip(&terms)
            .enumerate()
            .filter_map(|(i, (&rate, &t))| {
                let scale = if t > 0.0 { t } else { largest };
                let relative = if scale > 0.0 {
                    rate.abs() / scale
                } else {
                    f64::INFINITY
                };
                (rate != 0.0 && relative > DRIFT_TOLERANCE).then(|| Drift {
                    state: names.get(i).cloned().unwrap_or_else(|| format!("x[{i}]")),
                    rate,
                    relative,
                })
            })
            .collect())
    }

    /// The outputs that depend on no state and no input of the model at `theta`: their rows
    /// of `C` and `D` (a nonlinear model's at its operating point) are zero, so the model
    /// holds them constant and no log of them can be compared with it (`h.theta = "0*theta"`,
    /// a `C` row left at zero).
    pub fn silent_outputs(&self, theta: &[f64]) -> Result<Vec<String>> {
        let ss = self.state_space(theta)?;
        Ok(self
            .structure
            .outputs()
            .into_iter()
            .enumerate()
            .filter(|(i, _)| {
                ss.c.row(*i)
                    .iter()
                    .chain(ss.d.row(*i).iter())
                    .all(|v| *v == 0.0)
            })
            .map(|(_, name)| name)
            .collect())
    }

    /// Checks the length of `theta`; returns how many of its entries are the structure's.
    fn check_theta(&self, theta: &[f64]) -> Result<usize> {
        let n_struct = self.structure.parameters(&self.enabled)?.len();
        let n_total = n_struct
            + self
                .added
                .iter()
                .map(|e| e.parameters().len())
                .sum::<usize>();
        if theta.len() != n_total {
            return Err(SimError::LengthMismatch {
                what: "parameter vector".into(),
                expected: n_total,
                found: theta.len(),
            });
        }
        Ok(n_struct)
    }

    /// Enables a known effect by name.
    pub fn with_effect(&self, name: &str) -> Result<Self> {
        let mut m = self.clone();
        if self.enabled().iter().any(|e| e == name) {
            return Ok(m);
        }
        if let Some(e) = self.offered().find(|e| e.name() == name) {
            m.added.push(e.clone());
        } else if self.structure.effects().iter().any(|e| e == name) {
            m.enabled.push(name.to_string());
        } else {
            return Err(SimError::invalid(
                "effect",
                name,
                format!(
                    "unknown for {}; known effects: {}",
                    self.structure.system(),
                    self.known().join(", ")
                ),
            ));
        }
        Ok(m)
    }

    /// The model with `name` disabled (offered again as a candidate); unchanged when it is not
    /// enabled.
    pub fn without_effect(&self, name: &str) -> Self {
        let mut m = self.clone();
        m.enabled.retain(|e| e != name);
        m.added.retain(|e| e.name() != name);
        m
    }

    /// The names of the parameters the enabled effect `name` brings: those the model has and
    /// has not without it (empty when it is not enabled).
    pub fn effect_parameters(&self, name: &str) -> Result<Vec<String>> {
        let others: Vec<String> = self
            .without_effect(name)
            .parameters()?
            .into_iter()
            .map(|p| p.name)
            .collect();
        Ok(self
            .parameters()?
            .into_iter()
            .map(|p| p.name)
            .filter(|n| !others.contains(n))
            .collect())
    }

    /// The names of the parameters every enabled effect brings: guesses where their fits
    /// start, not documented properties of the system.
    pub fn effect_parameter_names(&self) -> Result<Vec<String>> {
        let mut names = Vec::new();
        for e in self.enabled() {
            names.extend(self.effect_parameters(&e)?);
        }
        Ok(names)
    }

    /// Offers a further effect as a discovery candidate (replacing a generic effect of the same
    /// name); it is not enabled.
    pub fn with_candidate(&self, effect: Arc<dyn Effect>) -> Result<Self> {
        if self.structure.effects().iter().any(|e| e == effect.name())
            || self.added.iter().any(|e| e.name() == effect.name())
        {
            return Err(SimError::invalid(
                "effect",
                effect.name(),
                "already in the model",
            ));
        }
        let mut m = self.clone();
        m.pool.retain(|e| e.name() != effect.name());
        m.pool.push(effect);
        Ok(m)
    }

    /// Offers and enables a further effect.
    pub fn with_user_effect(&self, effect: Arc<dyn Effect>) -> Result<Self> {
        let name = effect.name().to_string();
        self.with_candidate(effect)?.with_effect(&name)
    }

    /// All parameters: structure (with enabled effects), then the added effects' (prefixed by
    /// the effect's name where [`Effect::qualified_names`] says so, or where the plain name is
    /// taken).
    pub fn parameters(&self) -> Result<Vec<Parameter>> {
        let mut params = self.structure.parameters(&self.enabled)?;
        for e in &self.added {
            for mut p in e.parameters() {
                // A plain name that is already taken (a structure's own `tau`) is qualified.
                if e.qualified_names() || params.iter().any(|q| q.name == p.name) {
                    p.name = format!("{}.{}", e.name(), p.name);
                }
                params.push(p);
            }
        }
        check_parameters(&params)?;
        Ok(params)
    }

    /// The documented value of every parameter, in the order of [`Model::parameters`]: where
    /// a fit starts and what a check evaluates at.
    pub fn documented(&self) -> Result<Vec<f64>> {
        Ok(self.parameters()?.iter().map(|p| p.value).collect())
    }

    /// The state-space model at `theta`.
    pub fn state_space(&self, theta: &[f64]) -> Result<StateSpace> {
        let n_struct = self.check_theta(theta)?;
        let mut ss = self
            .structure
            .state_space(&self.enabled, &theta[..n_struct])?;
        for (e, at) in self.added_in_state_order(n_struct) {
            e.apply(&theta[at..at + e.parameters().len()], &mut ss)?;
        }
        ss.check()?;
        Ok(ss)
    }

    /// The added effects with where their parameters start in theta (after the structure's
    /// `n_struct`), those that filter outputs last ([`Effect::filters_outputs`]).
    fn added_in_state_order(&self, n_struct: usize) -> Vec<(&Arc<dyn Effect>, usize)> {
        let mut at = n_struct;
        let mut order: Vec<(&Arc<dyn Effect>, usize)> = self
            .added
            .iter()
            .map(|e| {
                let start = at;
                at += e.parameters().len();
                (e, start)
            })
            .collect();
        // Input gains and offsets first, inside every input lag; output lags last.
        order.sort_by_key(|(e, _)| match (e.edits_inputs(), e.filters_outputs()) {
            (true, _) => 0,
            (false, false) => 1,
            (false, true) => 2,
        });
        order
    }

    /// FRF on `freqs_hz` at `theta`.
    pub fn frf(&self, theta: &[f64], freqs_hz: &[f64], hold: Option<f64>) -> Result<Vec<CMatrix>> {
        Ok(self.state_space(theta)?.frf_lines(freqs_hz, hold)?)
    }

    /// FRF as the lines of `map` see it (a Welch line through its window's kernel).
    pub fn frf_seen(&self, theta: &[f64], map: &LineMap, hold: Option<f64>) -> Result<ModelFrf> {
        Ok(map.seen(&self.frf(theta, map.grid_hz(), hold)?))
    }

    /// FRF and its derivatives with respect to each parameter, `out[k][i] = dG(w_k)/dtheta_i`.
    ///
    /// The values are exact ([`StateSpace::frf_lines`]). The derivatives are those of the
    /// continuous-time response times the hold factor `e^{-jwT/2} sinc(wT/2)` (aliasing
    /// neglected, about 1% at a fifth of the sample rate): the state-space matrices are
    /// differentiated by central differences (exact for entries affine in a parameter), the
    /// response analytically, `dG = C X dA X B + C X dB + dC X B + dD`. A Jacobian this close
    /// only affects the path of Gauss-Newton steps, never the optimum, which is set by the
    /// exact values.
    pub fn frf_with_jacobian(
        &self,
        theta: &[f64],
        freqs_hz: &[f64],
        hold: Option<f64>,
    ) -> Result<(Vec<CMatrix>, Vec<Vec<CMatrix>>)> {
        let params = self.parameters()?;
        let ss = self.state_space(theta)?;
        let mut derivs = Vec::with_capacity(theta.len());
        for (i, p) in params.iter().enumerate() {
            // Central differences, one-sided at a bound (domain models may reject values
            // outside their bounds).
            let h = 1e-6 * p.scale().max(theta[i].abs());
            let mut tp = theta.to_vec();
            let mut tm = theta.to_vec();
            tp[i] = (theta[i] + h).min(p.upper);
            tm[i] = (theta[i] - h).max(p.lower);
            let span = tp[i] - tm[i];
            if span <= 0.0 {
                return Err(SimError::invalid(
                    &p.name,
                    theta[i],
                    "bounds leave no room to vary it",
                ));
            }
            let sp = self.state_space(&tp)?;
            let sm = self.state_space(&tm)?;
            if sp.a.shape() != ss.a.shape() || sm.a.shape() != ss.a.shape() {
                return Err(SimError::invalid(
                    &p.name,
                    theta[i],
                    "changing it changes the state dimension",
                ));
            }
            let inv = 1.0 / span;
            derivs.push((
                (&sp.a - &sm.a) * inv,
                (&sp.b - &sm.b) * inv,
                (&sp.c - &sm.c) * inv,
                (&sp.d - &sm.d) * inv,
                (sp.delay - sm.delay) * inv,
            ));
        }
        let gs = ss.frf_lines(freqs_hz, hold)?;
        let mut js = Vec::with_capacity(freqs_hz.len());
        for f in freqs_hz {
            let w = 2.0 * std::f64::consts::PI * f;
            let (g0, (cx, xb)) = ss.resolvent(w)?;
            let fac = factor(&ss, w, hold);
            let g = &g0 * fac;
            let mut jac = Vec::with_capacity(derivs.len());
            for (da, db, dc, dd, ddelay) in &derivs {
                let mut dg = CMatrix::zeros(g0.nrows(), g0.ncols());
                if da.iter().any(|v| *v != 0.0) {
                    dg += &cx * da.map(C64::from) * &xb;
                }
                if db.iter().any(|v| *v != 0.0) {
                    dg += &cx * db.map(C64::from);
                }
                if dc.iter().any(|v| *v != 0.0) {
                    dg += dc.map(C64::from) * &xb;
                }
                if dd.iter().any(|v| *v != 0.0) {
                    dg += dd.map(C64::from);
                }
                let mut dg = dg * fac;
                if *ddelay != 0.0 {
                    dg += &g * (C64::new(0.0, -w) * *ddelay);
                }
                jac.push(dg);
            }
            js.push(jac);
        }
        Ok((gs, js))
    }
}
