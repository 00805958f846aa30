//! Model files: a user's linear(ized) grey-box model in TOML, read into a [`ModelStructure`]
//! the workbench treats like any shipped system.
//!
//! ```toml
//! name = "pendulum"                # MCAP topics /pendulum/input, /pendulum/output, /pendulum/excitation
//! states = ["theta", "omega"]
//! inputs = ["T"]
//! outputs = ["theta"]
//! [parameters]                     # a number, or { value, min, max, unit, fixed }
//! m = { value = 0.5, min = 0.01, unit = "kg" }
//! l = 0.4
//! J = { value = 0.02, min = 0.0 }
//! g = { value = 9.81, fixed = true }
//! [definitions]                    # named expressions in parameters and earlier definitions
//! Jp = "J + m*l^2"
//! [linear]                         # x' = A x + B u, y = C x + D u (D optional)
//! A = [[0, 1], ["m*g*l/Jp", 0]]
//! B = [[0], ["1/Jp"]]
//! C = [[1, 0]]
//! [effects.joint_friction]         # a suspected effect: parameters and added terms
//! description = "viscous friction torque -b omega at the joint"
//! parameters = { b = { value = 0.001, min = 0.0 } }
//! A = { "omega,omega" = "-b/Jp" }  # "row,column" by state / input / output names
//! [controller]                     # optional: the experimenter's controller, see [`Controller`]
//! sample_rate_hz = 100
//! K = [[-2.0, -0.3]]               # u = -K x + r
//! ```
//!
//! An effect may add states of its own (`states = ["q", "qd"]`, a structural mode, a motor's
//! current): they follow the model's, and its terms name them like the model's.
//!
//! Every error names the file and the key (`linear.A[1][0]`), and for an expression the
//! position of an unknown name or a stray character.
mod nonlinear;

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::DMatrix;
use toml::{Table, Value};

use super::dynamics::Dynamics;
use super::expr::{check_name, Expr};
use super::model::{ModelStructure, Parameter, StateSpace};
use crate::error::{Result, SimError};
use nonlinear::{Addition, Layout, Node, Section, Target};

/// A matrix entry: a number or an expression.
#[derive(Debug, Clone)]
enum Entry {
    Number(f64),
    /// Boxed: a parsed expression is large (tens of kilobytes of inline storage).
    Expr(Box<Expr>),
}

/// A parameter of the file and where its value lives in the symbol table.
#[derive(Debug, Clone)]
struct FileParameter {
    parameter: Parameter,
    fixed: bool,
    slot: usize,
}

/// Which state-space matrix a term belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Which {
    A,
    B,
    C,
    D,
}

impl Which {
    const ALL: [Which; 4] = [Which::A, Which::B, Which::C, Which::D];

    fn key(self) -> &'static str {
        match self {
            Which::A => "A",
            Which::B => "B",
            Which::C => "C",
            Which::D => "D",
        }
    }
}

/// A term an effect adds to one matrix entry.
#[derive(Debug, Clone)]
struct Term {
    which: Which,
    row: usize,
    col: usize,
    entry: Entry,
    key: String,
}

/// A declared effect.
#[derive(Debug, Clone)]
struct FileEffect {
    name: String,
    description: String,
    parameters: Vec<FileParameter>,
    /// The states it adds, as indices into the model's and all effects' states.
    states: Range<usize>,
    /// Their operating point (a nonlinear model's).
    operating_point: Vec<f64>,
    /// Terms added to matrix entries (rows and columns of states index all states).
    terms: Vec<Term>,
    /// Terms added to definitions, and in a nonlinear model to `f` and `h`.
    additions: Vec<Addition>,
}

/// The experimenter's controller, for closed-loop re-simulation. Sampled at
/// `sample_rate_hz`, its output held over the period (zero-order hold), `r` the logged
/// excitation:
/// - `StateFeedback`: `u[k] = -K x[k] + r[k]`, `x` the model's state;
/// - `Discrete`: `xc[k+1] = A xc[k] + B y[k]`, `u[k] = C xc[k] + D y[k] + r[k]`, driven by the
///   measured outputs `y`.
#[derive(Debug, Clone, PartialEq)]
pub enum Controller {
    /// Static state feedback.
    StateFeedback {
        /// Sample rate in Hz.
        sample_rate_hz: f64,
        /// Gain, inputs x states.
        k: DMatrix<f64>,
    },
    /// Discrete-time dynamic output feedback.
    Discrete {
        /// Sample rate in Hz.
        sample_rate_hz: f64,
        /// Controller state matrix.
        a: DMatrix<f64>,
        /// Controller input (measured outputs) matrix.
        b: DMatrix<f64>,
        /// Controller output matrix.
        c: DMatrix<f64>,
        /// Feed-through from the measured outputs.
        d: DMatrix<f64>,
    },
}

/// A model read from a file.
#[derive(Debug, Clone)]
pub struct ModelFile {
    path: PathBuf,
    name: String,
    /// The model's states.
    states: Vec<String>,
    /// The model's states, then those its effects add.
    all_states: Vec<String>,
    inputs: Vec<String>,
    outputs: Vec<String>,
    /// Every parameter (base, then each effect's), every definition, then the states and
    /// the inputs (read by a nonlinear model's expressions).
    symbols: Vec<String>,
    /// Documented values of the symbol table (definitions evaluated).
    documented: Vec<f64>,
    parameters: Vec<FileParameter>,
    /// Definitions in an order that evaluates each after what it reads.
    definitions: Vec<(usize, Entry)>,
    /// The matrices of a linear model (empty for a nonlinear one).
    linear: [Vec<Vec<Entry>>; 4],
    /// The nonlinear model, linearized at its operating point for the linear tools.
    nonlinear: Option<Arc<Section>>,
    effects: Vec<FileEffect>,
    controller: Option<Controller>,
}

/// Reads a model-file value as a number.
fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Integer(i) => Some(*i as f64),
        Value::Float(f) => Some(*f),
        _ => None,
    }
}

struct Reader<'a> {
    path: &'a Path,
}

impl Reader<'_> {
    fn err(&self, key: impl Into<String>, reason: impl Into<String>) -> SimError {
        SimError::ModelFile {
            path: self.path.to_path_buf(),
            key: key.into(),
            reason: reason.into(),
        }
    }

    /// A list of names: `table[field]`, called `key` in errors.
    fn names(&self, table: &Table, field: &str, key: &str) -> Result<Vec<String>> {
        let list = table
            .get(field)
            .ok_or_else(|| self.err(key, "missing (a list of names)"))?
            .as_array()
            .ok_or_else(|| self.err(key, "must be a list of names"))?;
        let mut out: Vec<String> = Vec::with_capacity(list.len());
        for (i, v) in list.iter().enumerate() {
            let name = v
                .as_str()
                .ok_or_else(|| self.err(format!("{key}[{i}]"), "must be a string"))?;
            check_name(name).map_err(|r| self.err(format!("{key}[{i}]"), r))?;
            if out.iter().any(|n| n == name) {
                return Err(self.err(key, format!("{name:?} is named twice")));
            }
            out.push(name.to_string());
        }
        if out.is_empty() {
            return Err(self.err(key, "must name at least one"));
        }
        Ok(out)
    }

    /// `name = number` or `name = { value, min, max, unit, fixed }`.
    fn parameter(&self, key: &str, name: &str, v: &Value) -> Result<(Parameter, bool)> {
        check_name(name).map_err(|r| self.err(key, r))?;
        if let Some(x) = number(v) {
            return self.bounded(
                key,
                Parameter::new(name, x, f64::NEG_INFINITY, f64::INFINITY, ""),
                false,
            );
        }
        let t = v.as_table().ok_or_else(|| {
            self.err(
                key,
                "must be a number or a table { value, min, max, unit, fixed }",
            )
        })?;
        let get = |field: &str| -> Result<Option<f64>> {
            t.get(field)
                .map(|x| {
                    number(x).ok_or_else(|| self.err(format!("{key}.{field}"), "must be a number"))
                })
                .transpose()
        };
        for field in t.keys() {
            if !["value", "min", "max", "unit", "fixed"].contains(&field.as_str()) {
                return Err(self.err(
                    format!("{key}.{field}"),
                    "unknown field (expected value, min, max, unit, fixed)",
                ));
            }
        }
        let value = get("value")?.ok_or_else(|| self.err(format!("{key}.value"), "missing"))?;
        let lower = get("min")?.unwrap_or(f64::NEG_INFINITY);
        let upper = get("max")?.unwrap_or(f64::INFINITY);
        let unit = match t.get("unit") {
            None => String::new(),
            Some(u) => u
                .as_str()
                .ok_or_else(|| self.err(format!("{key}.unit"), "must be a string"))?
                .to_string(),
        };
        let fixed = match t.get("fixed") {
            None => false,
            Some(f) => f
                .as_bool()
                .ok_or_else(|| self.err(format!("{key}.fixed"), "must be true or false"))?,
        };
        self.bounded(key, Parameter::new(name, value, lower, upper, unit), fixed)
    }

    fn bounded(&self, key: &str, p: Parameter, fixed: bool) -> Result<(Parameter, bool)> {
        if !p.value.is_finite() {
            return Err(self.err(key, format!("value {} is not finite", p.value)));
        }
        if p.lower > p.upper {
            return Err(self.err(key, format!("min {} > max {}", p.lower, p.upper)));
        }
        if !(p.lower <= p.value && p.value <= p.upper) {
            return Err(self.err(
                key,
                format!(
                    "value {} lies outside [min, max] = [{}, {}]",
                    p.value, p.lower, p.upper
                ),
            ));
        }
        if !fixed && p.lower == p.upper {
            return Err(self.err(key, "min = max leaves nothing to fit: say fixed = true"));
        }
        Ok((p, fixed))
    }

    fn entry(&self, key: &str, v: &Value, symbols: &[String], visible: &[bool]) -> Result<Entry> {
        if let Some(x) = number(v) {
            return Ok(Entry::Number(x));
        }
        let text = v
            .as_str()
            .ok_or_else(|| self.err(key, "must be a number or an expression string"))?;
        let e = Expr::parse(text, symbols).map_err(|e| match e.unknown {
            // Only the names this place may read: a [linear] entry lists no state.
            Some(_) => {
                let here: Vec<&str> = symbols
                    .iter()
                    .zip(visible)
                    .filter(|(_, v)| **v)
                    .map(|(s, _)| s.as_str())
                    .collect();
                self.err(
                    key,
                    format!("{}; names here: {}", e.reason, here.join(", ")),
                )
            }
            None => self.err(key, e.reason),
        })?;
        if let Some(&slot) = e.reads().iter().find(|&&s| !visible[s]) {
            return Err(self.err(
                key,
                format!(
                    "{:?} in {text:?} is not visible here: a parameter of another effect, or a \
                     state or input, which only a [nonlinear] model's expressions read",
                    symbols[slot]
                ),
            ));
        }
        Ok(Entry::Expr(Box::new(e)))
    }

    fn matrix(
        &self,
        key: &str,
        v: &Value,
        shape: (usize, usize),
        what: &str,
        symbols: &[String],
        visible: &[bool],
    ) -> Result<Vec<Vec<Entry>>> {
        let rows = v
            .as_array()
            .ok_or_else(|| self.err(key, "must be a list of rows, e.g. [[0, 1], [2, 3]]"))?;
        let ncols = rows
            .first()
            .and_then(|r| r.as_array())
            .map_or(0, |r| r.len());
        let mut out = Vec::with_capacity(rows.len());
        for (i, row) in rows.iter().enumerate() {
            let row = row
                .as_array()
                .ok_or_else(|| self.err(format!("{key}[{i}]"), "must be a list (a row)"))?;
            if row.len() != ncols {
                return Err(self.err(
                    key,
                    format!("row {i} has {} entries, row 0 has {ncols}", row.len()),
                ));
            }
            out.push(
                row.iter()
                    .enumerate()
                    .map(|(j, x)| self.entry(&format!("{key}[{i}][{j}]"), x, symbols, visible))
                    .collect::<Result<Vec<_>>>()?,
            );
        }
        if (rows.len(), ncols) != shape {
            return Err(self.err(
                key,
                format!(
                    "is {}x{ncols}, must be {}x{} ({what})",
                    rows.len(),
                    shape.0,
                    shape.1
                ),
            ));
        }
        Ok(out)
    }

    fn numbers(&self, key: &str, v: &Value) -> Result<DMatrix<f64>> {
        let rows = v
            .as_array()
            .ok_or_else(|| self.err(key, "must be a list of rows of numbers"))?;
        let ncols = rows
            .first()
            .and_then(|r| r.as_array())
            .map_or(0, |r| r.len());
        let mut m = DMatrix::zeros(rows.len(), ncols);
        for (i, row) in rows.iter().enumerate() {
            let row = row.as_array().filter(|r| r.len() == ncols).ok_or_else(|| {
                self.err(
                    format!("{key}[{i}]"),
                    format!("must be a row of {ncols} numbers"),
                )
            })?;
            for (j, x) in row.iter().enumerate() {
                m[(i, j)] = number(x).filter(|x| x.is_finite()).ok_or_else(|| {
                    self.err(format!("{key}[{i}][{j}]"), "must be a finite number")
                })?;
            }
        }
        Ok(m)
    }
}

fn section<'t>(r: &Reader, table: &'t Table, key: &str) -> Result<Option<&'t Table>> {
    table
        .get(key)
        .map(|v| v.as_table().ok_or_else(|| r.err(key, "must be a table")))
        .transpose()
}

impl ModelFile {
    /// Reads and checks a model file.
    pub fn from_path(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| SimError::io(path, e))?;
        Self::parse(&text, path)
    }

    /// Parses model-file text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let r = Reader { path };
        let root: Table = text.parse().map_err(|e: toml::de::Error| {
            r.err(
                "(file)",
                format!("not valid TOML: {}", e.to_string().trim_end()),
            )
        })?;
        for key in root.keys() {
            if ![
                "name",
                "states",
                "inputs",
                "outputs",
                "parameters",
                "definitions",
                "linear",
                "nonlinear",
                "effects",
                "controller",
            ]
            .contains(&key.as_str())
            {
                return Err(r.err(key, "unknown section (expected name, states, inputs, outputs, parameters, definitions, linear, nonlinear, effects, controller)"));
            }
        }
        let name = root
            .get("name")
            .and_then(Value::as_str)
            .ok_or_else(|| {
                r.err(
                    "name",
                    "missing (the system name; MCAP topics are /<name>/input, ...)",
                )
            })?
            .to_string();
        check_name(&name).map_err(|e| r.err("name", e))?;
        let states = r.names(&root, "states", "states")?;
        let inputs = r.names(&root, "inputs", "inputs")?;
        let outputs = r.names(&root, "outputs", "outputs")?;
        if let Some(s) = states.iter().find(|s| inputs.contains(s)) {
            return Err(r.err("inputs", format!("{s:?} is a state and an input")));
        }
        if let Some(o) = outputs.iter().find(|o| inputs.contains(o)) {
            return Err(r.err(
                "outputs",
                format!("{o:?} is an input and an output; a log's column can feed only one"),
            ));
        }

        let effect_tables: Vec<(String, Table)> = match section(&r, &root, "effects")? {
            None => Vec::new(),
            Some(t) => t
                .iter()
                .map(|(n, v)| {
                    v.as_table()
                        .map(|t| (n.clone(), t.clone()))
                        .ok_or_else(|| r.err(format!("effects.{n}"), "must be a table"))
                })
                .collect::<Result<_>>()?,
        };
        // States an effect adds (a structural mode, a motor's current) follow the model's
        // own, in the file's order of effects: `all_states` names them all.
        let mut all_states = states.clone();
        let mut effect_states: Vec<Range<usize>> = Vec::with_capacity(effect_tables.len());
        for (ename, t) in &effect_tables {
            check_name(ename).map_err(|e| r.err(format!("effects.{ename}"), e))?;
            let start = all_states.len();
            if t.contains_key("states") {
                let key = format!("effects.{ename}.states");
                for s in r.names(t, "states", &key)? {
                    if all_states.contains(&s) || inputs.contains(&s) {
                        return Err(r.err(&key, format!("{s:?} is already a state or input name")));
                    }
                    all_states.push(s);
                }
            }
            effect_states.push(start..all_states.len());
        }

        // The symbol table: base parameters, effect parameters, definitions.
        let mut symbols: Vec<String> = Vec::new();
        let mut documented: Vec<f64> = Vec::new();
        let mut declare = |r: &Reader,
                           key: &str,
                           name: &str,
                           value: f64,
                           symbols: &mut Vec<String>|
         -> Result<usize> {
            if symbols.iter().any(|s| s == name) {
                return Err(r.err(key, format!("{name:?} is named twice")));
            }
            if all_states.iter().chain(&inputs).any(|s| s == name) {
                return Err(r.err(key, format!("{name:?} is also a state or input name")));
            }
            symbols.push(name.to_string());
            documented.push(value);
            Ok(symbols.len() - 1)
        };
        let mut parameters = Vec::new();
        if let Some(t) = section(&r, &root, "parameters")? {
            for (pname, v) in t {
                let key = format!("parameters.{pname}");
                let (p, fixed) = r.parameter(&key, pname, v)?;
                let slot = declare(&r, &key, pname, p.value, &mut symbols)?;
                parameters.push(FileParameter {
                    parameter: p,
                    fixed,
                    slot,
                });
            }
        }
        let mut effect_params: Vec<Vec<FileParameter>> = Vec::new();
        for (ename, t) in &effect_tables {
            let mut list = Vec::new();
            if let Some(p) = t.get("parameters") {
                let p = p.as_table().ok_or_else(|| {
                    r.err(format!("effects.{ename}.parameters"), "must be a table")
                })?;
                for (pname, v) in p {
                    let key = format!("effects.{ename}.parameters.{pname}");
                    let (p, fixed) = r.parameter(&key, pname, v)?;
                    let slot = declare(&r, &key, pname, p.value, &mut symbols)?;
                    list.push(FileParameter {
                        parameter: p,
                        fixed,
                        slot,
                    });
                }
            }
            effect_params.push(list);
        }
        let n_params = symbols.len();
        let definition_table = section(&r, &root, "definitions")?
            .cloned()
            .unwrap_or_default();
        let mut def_slots = Vec::new();
        for (dname, _) in &definition_table {
            let key = format!("definitions.{dname}");
            check_name(dname).map_err(|e| r.err(&key, e))?;
            def_slots.push(declare(&r, &key, dname, f64::NAN, &mut symbols)?);
        }

        // States (the model's, then the effects') and inputs, read by a nonlinear model's
        // expressions.
        let is_nonlinear = root.contains_key("nonlinear");
        if is_nonlinear && root.contains_key("linear") {
            return Err(r.err(
                "linear",
                "give [linear] or [nonlinear], not both (a nonlinear model is linearized at its operating point)",
            ));
        }
        let state0 = symbols.len();
        for s in all_states.iter().chain(&inputs) {
            symbols.push(s.clone());
            documented.push(0.0);
        }
        // Base visibility: base parameters and definitions (and the model's states and the
        // inputs in a nonlinear model; an effect's states only in its own terms).
        let mut base_visible = vec![false; symbols.len()];
        for p in &parameters {
            base_visible[p.slot] = true;
        }
        for &s in &def_slots {
            base_visible[s] = true;
        }
        if is_nonlinear {
            for (i, v) in base_visible[state0..].iter_mut().enumerate() {
                *v = i < states.len() || i >= all_states.len();
            }
        }
        let mut pending: Vec<(usize, Entry, String)> = Vec::new();
        for ((dname, v), &slot) in definition_table.iter().zip(&def_slots) {
            let key = format!("definitions.{dname}");
            let e = r.entry(&key, v, &symbols, &base_visible)?;
            pending.push((slot, e, key));
        }
        // Order definitions so that each is evaluated after the ones it reads.
        let mut definitions: Vec<(usize, Entry)> = Vec::new();
        let mut ready = vec![true; symbols.len()];
        for &s in &def_slots {
            ready[s] = false;
        }
        let definition_keys: Vec<(usize, String)> = pending
            .iter()
            .map(|(slot, _, key)| (*slot, key.clone()))
            .collect();
        while !pending.is_empty() {
            let before = pending.len();
            let mut i = 0;
            while i < pending.len() {
                let reads_ready = match &pending[i].1 {
                    Entry::Number(_) => true,
                    Entry::Expr(e) => e.reads().iter().all(|&s| ready[s]),
                };
                if reads_ready {
                    let (slot, e, _) = pending.remove(i);
                    ready[slot] = true;
                    definitions.push((slot, e));
                } else {
                    i += 1;
                }
            }
            if pending.len() == before {
                let cycle: Vec<&str> = pending.iter().map(|(_, _, k)| k.as_str()).collect();
                return Err(r.err(
                    cycle[0],
                    format!(
                        "definitions read each other in a circle: {}",
                        cycle.join(", ")
                    ),
                ));
            }
        }

        let n = states.len();
        let (m, p) = (inputs.len(), outputs.len());
        let empty = Table::new();
        let linear = match section(&r, &root, "linear")? {
            Some(t) => t,
            None if is_nonlinear => &empty,
            None => {
                return Err(r.err(
                    "linear",
                    "missing: [linear] with the matrices A, B, C (and D), or [nonlinear] with f, h and operating_point",
                ))
            }
        };
        for key in linear.keys() {
            if !["A", "B", "C", "D"].contains(&key.as_str()) {
                return Err(r.err(
                    format!("linear.{key}"),
                    "unknown matrix (expected A, B, C, D)",
                ));
            }
        }
        let shapes = [
            ((n, n), "states x states"),
            ((n, m), "states x inputs"),
            ((p, n), "outputs x states"),
            ((p, m), "outputs x inputs"),
        ];
        let mut mats: Vec<Vec<Vec<Entry>>> = Vec::with_capacity(4);
        for (which, (shape, what)) in Which::ALL.iter().zip(shapes) {
            let key = format!("linear.{}", which.key());
            mats.push(match linear.get(which.key()) {
                Some(v) => r.matrix(&key, v, shape, what, &symbols, &base_visible)?,
                None if is_nonlinear => Vec::new(),
                None if *which == Which::D => (0..p)
                    .map(|_| (0..m).map(|_| Entry::Number(0.0)).collect())
                    .collect(),
                None => return Err(r.err(key, format!("missing ({what})"))),
            });
        }
        let linear: [Vec<Vec<Entry>>; 4] = match mats.try_into() {
            Ok(l) => l,
            Err(_) => return Err(r.err("linear", "needs A, B, C")),
        };

        let mut effects = Vec::new();
        for (((ename, t), params), own) in
            effect_tables.iter().zip(effect_params).zip(&effect_states)
        {
            let mut visible = base_visible.clone();
            for q in &params {
                visible[q.slot] = true;
            }
            if is_nonlinear {
                for i in own.clone() {
                    visible[state0 + i] = true;
                }
            }
            // The states its terms may name: the model's and its own, by index in `all_states`.
            let state_index: Vec<usize> = (0..n).chain(own.clone()).collect();
            let state_names: Vec<String> =
                state_index.iter().map(|&i| all_states[i].clone()).collect();
            let mut terms = Vec::new();
            let mut additions = Vec::new();
            let mut description = String::new();
            let mut point = vec![0.0; own.len()];
            for (k, v) in t {
                let key = format!("effects.{ename}.{k}");
                match k.as_str() {
                    "parameters" | "states" => {}
                    "description" => {
                        description = v
                            .as_str()
                            .ok_or_else(|| r.err(&key, "must be a string"))?
                            .to_string()
                    }
                    "operating_point" if is_nonlinear && !own.is_empty() => {
                        let op = v.as_table().ok_or_else(|| {
                            r.err(&key, "must be a table of the effect's states, e.g. { eta = 0 }")
                        })?;
                        for (name, x) in op {
                            let i = all_states[own.clone()].iter().position(|s| s == name).ok_or_else(|| {
                                r.err(format!("{key}.{name}"), format!("{name:?} is not one of the effect's states: {}", all_states[own.clone()].join(", ")))
                            })?;
                            point[i] = number(x).filter(|x| x.is_finite()).ok_or_else(|| {
                                r.err(format!("{key}.{name}"), "must be a finite number")
                            })?;
                        }
                    }
                    "add" => {
                        additions.extend(Self::read_additions(
                            &r,
                            &key,
                            v,
                            (&symbols, &visible),
                            &definition_keys,
                            (&state_names, &state_index, &outputs),
                            is_nonlinear,
                        )?);
                    }
                    "A" | "B" | "C" | "D" if is_nonlinear => {
                        return Err(r.err(
                            &key,
                            "a [nonlinear] model's effects add terms to expressions: add.<definition>, add.f.<state>, add.h.<output>",
                        ))
                    }
                    "A" | "B" | "C" | "D" => {
                        let which = Which::ALL[["A", "B", "C", "D"].iter().position(|w| w == k).unwrap_or(0)];
                        let (rows, cols): (&[String], &[String]) = match which {
                            Which::A => (&state_names, &state_names),
                            Which::B => (&state_names, &inputs),
                            Which::C => (&outputs, &state_names),
                            Which::D => (&outputs, &inputs),
                        };
                        let entries = v.as_table().ok_or_else(|| {
                            r.err(&key, "must be a table of added terms keyed \"row,column\"")
                        })?;
                        for (rc, x) in entries {
                            let tkey = format!("{key}.\"{rc}\"");
                            let (rn, cn) = rc.split_once(',').ok_or_else(|| {
                                r.err(&tkey, "key must be \"row,column\" (names)")
                            })?;
                            let find = |list: &[String], name: &str, what: &str| {
                                list.iter().position(|s| s == name.trim()).ok_or_else(|| {
                                    r.err(&tkey, format!("{:?} is not one of the {what}s: {}", name.trim(), list.join(", ")))
                                })
                            };
                            let row_is_state = matches!(which, Which::A | Which::B);
                            let col_is_state = matches!(which, Which::A | Which::C);
                            let row = find(rows, rn, if row_is_state { "state" } else { "output" })?;
                            let col = find(cols, cn, if col_is_state { "state" } else { "input" })?;
                            let entry = r.entry(&tkey, x, &symbols, &visible)?;
                            terms.push(Term {
                                which,
                                row: if row_is_state { state_index[row] } else { row },
                                col: if col_is_state { state_index[col] } else { col },
                                entry,
                                key: tkey,
                            });
                        }
                    }
                    "operating_point" => {
                        return Err(r.err(&key, if is_nonlinear {
                            "only an effect with states of its own has an operating point (give states first)"
                        } else {
                            "only a [nonlinear] model has an operating point"
                        }))
                    }
                    other => {
                        return Err(r.err(&key, format!("unknown field {other:?} (expected description, parameters, states, operating_point, add, A, B, C, D)")))
                    }
                }
            }
            if terms.is_empty() && additions.is_empty() {
                return Err(r.err(
                    format!("effects.{ename}"),
                    if is_nonlinear {
                        "adds no term (give add.<definition>, add.f.<state> or add.h.<output>)"
                    } else {
                        "adds no term (give A, B, C or D, or add.<definition>)"
                    },
                ));
            }
            // Each state of its own must move, and the model or the outputs must read one: a
            // state with no derivative never leaves its start, states only the effect reads
            // change nothing the outputs see.
            let key = format!("effects.{ename}.states");
            let mine = |i: usize| own.contains(&i);
            for i in own.clone() {
                let name = &all_states[i];
                let moves = if is_nonlinear {
                    additions.iter().any(|a| a.target == Target::F(i))
                } else {
                    terms
                        .iter()
                        .any(|t| matches!(t.which, Which::A | Which::B) && t.row == i)
                };
                if !moves {
                    return Err(r.err(&key, format!(
                        "{name:?} has no derivative: give {}",
                        if is_nonlinear { format!("add.f.{name}") } else { format!("terms in its row of A or B, A = {{ \"{name},<state>\" = ... }}") }
                    )));
                }
            }
            let seen = if is_nonlinear {
                additions.iter().any(|a| {
                    !matches!(a.target, Target::F(i) if mine(i))
                        && a.node
                            .reads()
                            .iter()
                            .any(|&s| s >= state0 && mine(s - state0))
                })
            } else {
                terms.iter().any(|t| {
                    (t.which == Which::A && mine(t.col) && !mine(t.row))
                        || (t.which == Which::C && mine(t.col))
                })
            };
            if !own.is_empty() && !seen {
                return Err(r.err(&key, format!(
                    "{} read by nothing outside the effect, so no output can see {}: {}",
                    all_states[own.clone()].join(", "),
                    if own.len() == 1 { "it" } else { "them" },
                    if is_nonlinear { "read one in add.f of a state of the model, in add.h or in a definition" } else { "give a term in the column of one of them in a row of the model's A or in C" }
                )));
            }
            effects.push(FileEffect {
                name: ename.clone(),
                description,
                parameters: params,
                states: own.clone(),
                operating_point: point,
                terms,
                additions,
            });
        }
        let nonlinear = match section(&r, &root, "nonlinear")? {
            None => None,
            Some(t) => {
                let layout = Layout {
                    symbols: &symbols,
                    visible: &base_visible,
                    states: &states,
                    inputs: &inputs,
                    outputs: &outputs,
                };
                let (mut f, h, mut x_op, u_op) = nonlinear::read(&r, t, &layout)?;
                // An effect's states have no `f` of the model's: their additions give it.
                for e in &effects {
                    for i in e.states.clone() {
                        let key = format!("effects.{}.add.f.{}", e.name, all_states[i]);
                        f.push(Node::new(Entry::Number(0.0), key));
                    }
                    x_op.extend(&e.operating_point);
                }
                for (d, v) in documented[state0..]
                    .iter_mut()
                    .zip(x_op.iter().chain(&u_op))
                {
                    *d = *v;
                }
                let defs = definitions
                    .iter()
                    .map(|(slot, e)| {
                        (
                            *slot,
                            Node::new(e.clone(), format!("definitions.{}", symbols[*slot])),
                        )
                    })
                    .collect();
                let additions = effects
                    .iter()
                    .map(|e| (e.name.clone(), e.additions.clone()))
                    .collect();
                Some(Arc::new(Section::new(
                    &r,
                    &symbols,
                    state0,
                    (m, p),
                    defs,
                    (f, h, x_op, u_op),
                    additions,
                )?))
            }
        };

        let controller = match section(&r, &root, "controller")? {
            None => None,
            Some(t) => Some(Self::read_controller(&r, t, n, m, p)?),
        };

        let mut model = Self {
            path: path.to_path_buf(),
            name,
            states,
            all_states,
            inputs,
            outputs,
            symbols,
            documented,
            parameters,
            definitions,
            linear,
            nonlinear,
            effects,
            controller,
        };
        debug_assert!(n_params <= model.symbols.len());
        model.documented = model.table(&[], &[])?;
        // Every effect alone must give finite matrices (and a nonlinear model finite `f` and
        // `h` at its operating point) at the documented values.
        let mut alone: Vec<Vec<String>> = vec![Vec::new()];
        alone.extend(model.effects().into_iter().map(|e| vec![e]));
        for enabled in &alone {
            let theta: Vec<f64> = model.parameters(enabled)?.iter().map(|p| p.value).collect();
            model.state_space(enabled, &theta)?;
            if let Some(d) = model.dynamics(enabled, &theta) {
                let d = d?;
                let (x, u) = d.operating_point();
                let mut scratch = Vec::new();
                d.f(&x, &u, &mut vec![0.0; x.len()], &mut scratch)?;
                d.h(&x, &u, &mut vec![0.0; d.outputs()], &mut scratch)?;
            }
        }
        Ok(model)
    }

    /// An effect's `add` table: `name = "term"` for a definition, and in a nonlinear model
    /// `f.<state> = "term"`, `h.<output> = "term"`.
    fn read_additions(
        r: &Reader,
        key: &str,
        v: &Value,
        (symbols, visible): (&[String], &[bool]),
        definitions: &[(usize, String)],
        (states, state_index, outputs): (&[String], &[usize], &[String]),
        is_nonlinear: bool,
    ) -> Result<Vec<Addition>> {
        let t = v.as_table().ok_or_else(|| {
            r.err(key, "must be a table: add.<definition> = \"term\" (and add.f.<state>, add.h.<output> in a [nonlinear] model)")
        })?;
        let mut out = Vec::new();
        for (name, x) in t {
            let akey = format!("{key}.{name}");
            match (name.as_str(), x.as_table()) {
                (fh @ ("f" | "h"), Some(sub)) => {
                    if !is_nonlinear {
                        return Err(r.err(&akey, "only a [nonlinear] model has f and h; add to a definition, or give A, B, C, D terms"));
                    }
                    let (names, kind) = if fh == "f" {
                        (states, "state")
                    } else {
                        (outputs, "output")
                    };
                    for (target, term) in sub {
                        let tkey = format!("{akey}.{target}");
                        let i = names.iter().position(|s| s == target).ok_or_else(|| {
                            r.err(
                                &tkey,
                                format!(
                                    "{target:?} is not one of the {kind}s: {}",
                                    names.join(", ")
                                ),
                            )
                        })?;
                        let entry = r.entry(&tkey, term, symbols, visible)?;
                        out.push(Addition {
                            target: if fh == "f" {
                                Target::F(state_index[i])
                            } else {
                                Target::H(i)
                            },
                            node: Node::new(entry, tkey),
                        });
                    }
                }
                _ => {
                    let slot = definitions
                        .iter()
                        .find(|(s, _)| symbols[*s] == *name)
                        .map(|(s, _)| *s)
                        .ok_or_else(|| {
                            let known: Vec<&str> = definitions
                                .iter()
                                .map(|(s, _)| symbols[*s].as_str())
                                .collect();
                            r.err(
                                &akey,
                                format!(
                                    "{name:?} is not a definition; definitions: {}",
                                    known.join(", ")
                                ),
                            )
                        })?;
                    let entry = r.entry(&akey, x, symbols, visible)?;
                    out.push(Addition {
                        target: Target::Definition(slot),
                        node: Node::new(entry, akey),
                    });
                }
            }
        }
        Ok(out)
    }

    fn read_controller(r: &Reader, t: &Table, n: usize, m: usize, p: usize) -> Result<Controller> {
        let sample_rate_hz = t
            .get("sample_rate_hz")
            .and_then(number)
            .filter(|f| f.is_finite() && *f > 0.0)
            .ok_or_else(|| {
                r.err(
                    "controller.sample_rate_hz",
                    "missing or not a positive number",
                )
            })?;
        let kind = match t.get("type") {
            None => "state_feedback",
            Some(v) => v.as_str().ok_or_else(|| {
                r.err(
                    "controller.type",
                    "must be \"state_feedback\" or \"discrete\"",
                )
            })?,
        };
        // A misspelt key, or a gain of the other kind, would be dropped silently.
        let keys: &[&str] = match kind {
            "discrete" => &["sample_rate_hz", "type", "A", "B", "C", "D"],
            _ => &["sample_rate_hz", "type", "K"],
        };
        if let Some(other) = t.keys().find(|k| !keys.contains(&k.as_str())) {
            return Err(r.err(
                format!("controller.{other}"),
                format!(
                    "unknown field for a controller of type {kind:?} (expected {})",
                    keys.join(", ")
                ),
            ));
        }
        let get = |k: &str| {
            t.get(k)
                .ok_or_else(|| r.err(format!("controller.{k}"), "missing"))
                .and_then(|v| r.numbers(&format!("controller.{k}"), v))
        };
        let shape = |k: &str, mat: &DMatrix<f64>, want: (usize, usize), what: &str| {
            if mat.shape() == want {
                Ok(())
            } else {
                Err(r.err(
                    format!("controller.{k}"),
                    format!(
                        "is {}x{}, must be {}x{} ({what})",
                        mat.nrows(),
                        mat.ncols(),
                        want.0,
                        want.1
                    ),
                ))
            }
        };
        match kind {
            "state_feedback" => {
                let k = get("K")?;
                shape("K", &k, (m, n), "inputs x states")?;
                Ok(Controller::StateFeedback { sample_rate_hz, k })
            }
            "discrete" => {
                let (a, b, c, d) = (get("A")?, get("B")?, get("C")?, get("D")?);
                let nc = a.nrows();
                shape("A", &a, (nc, nc), "controller states x controller states")?;
                shape("B", &b, (nc, p), "controller states x outputs")?;
                shape("C", &c, (m, nc), "inputs x controller states")?;
                shape("D", &d, (m, p), "inputs x outputs")?;
                Ok(Controller::Discrete {
                    sample_rate_hz,
                    a,
                    b,
                    c,
                    d,
                })
            }
            other => Err(r.err(
                "controller.type",
                format!("{other:?}: expected \"state_feedback\" or \"discrete\""),
            )),
        }
    }

    fn err(&self, key: impl Into<String>, reason: impl Into<String>) -> SimError {
        Reader { path: &self.path }.err(key, reason)
    }

    /// The file it was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// State names.
    pub fn states(&self) -> &[String] {
        &self.states
    }

    /// The states a declared effect adds (empty for an unknown name or an effect without).
    pub fn effect_states(&self, effect: &str) -> &[String] {
        self.effects
            .iter()
            .find(|e| e.name == effect)
            .map_or(&[], |e| &self.all_states[e.states.clone()])
    }

    /// The states of the model with the `enabled` effects, as indices into all states: the
    /// model's, then each enabled effect's in the file's order.
    fn active_states(&self, enabled: &[String]) -> Vec<usize> {
        (0..self.states.len())
            .chain(self.enabled_effects(enabled).flat_map(|e| e.states.clone()))
            .collect()
    }

    fn enabled_effects<'a>(
        &'a self,
        enabled: &'a [String],
    ) -> impl Iterator<Item = &'a FileEffect> + 'a {
        self.effects
            .iter()
            .filter(move |e| enabled.contains(&e.name))
    }

    /// Symbol values with the free parameters of the base and of the `enabled` effects set to
    /// `theta`, everything else documented, definitions evaluated.
    fn table(&self, enabled: &[String], theta: &[f64]) -> Result<Vec<f64>> {
        let mut table = self.documented.clone();
        let free = self
            .parameters
            .iter()
            .chain(self.enabled_effects(enabled).flat_map(|e| &e.parameters))
            .filter(|p| !p.fixed);
        for (p, v) in free.zip(theta) {
            table[p.slot] = *v;
        }
        for (slot, entry) in &self.definitions {
            let mut v = self.value(
                entry,
                &table,
                &format!("definitions.{}", self.symbols[*slot]),
            )?;
            for a in self
                .enabled_effects(enabled)
                .flat_map(|e| &e.additions)
                .filter(|a| a.target == Target::Definition(*slot))
            {
                v += self.value(&a.node.entry, &table, &a.node.key)?;
            }
            table[*slot] = v;
        }
        Ok(table)
    }

    fn value(&self, entry: &Entry, table: &[f64], key: &str) -> Result<f64> {
        let v = match entry {
            Entry::Number(x) => *x,
            Entry::Expr(e) => e.eval(table).map_err(|e| self.err(key, e.reason))?,
        };
        if !v.is_finite() {
            let at: Vec<String> = match entry {
                Entry::Expr(e) => e
                    .reads()
                    .iter()
                    .map(|&s| format!("{} = {}", self.symbols[s], table[s]))
                    .collect(),
                Entry::Number(_) => Vec::new(),
            };
            return Err(self.err(
                key,
                format!(
                    "{} is {v} at {}",
                    match entry {
                        Entry::Expr(e) => format!("{:?}", e.text()),
                        Entry::Number(x) => x.to_string(),
                    },
                    if at.is_empty() {
                        "these values".to_string()
                    } else {
                        at.join(", ")
                    }
                ),
            ));
        }
        Ok(v)
    }

    fn matrices(&self, enabled: &[String], theta: &[f64]) -> Result<[DMatrix<f64>; 4]> {
        let table = self.table(enabled, theta)?;
        if let Some(nl) = &self.nonlinear {
            return nl.linearize(enabled, &self.active_states(enabled), &table);
        }
        // The enabled effects' states follow the model's: `at[i]` is the row and column of
        // state `i` of all states.
        let active = self.active_states(enabled);
        let mut at = vec![usize::MAX; self.all_states.len()];
        for (k, &i) in active.iter().enumerate() {
            at[i] = k;
        }
        let (n, m, p) = (active.len(), self.inputs.len(), self.outputs.len());
        let mut out: Vec<DMatrix<f64>> = vec![
            DMatrix::zeros(n, n),
            DMatrix::zeros(n, m),
            DMatrix::zeros(p, n),
            DMatrix::zeros(p, m),
        ];
        for ((which, rows), mat) in Which::ALL.iter().zip(&self.linear).zip(&mut out) {
            for (i, row) in rows.iter().enumerate() {
                for (j, e) in row.iter().enumerate() {
                    mat[(i, j)] =
                        self.value(e, &table, &format!("linear.{}[{i}][{j}]", which.key()))?;
                }
            }
        }
        for e in self.enabled_effects(enabled) {
            for t in &e.terms {
                let row = if matches!(t.which, Which::A | Which::B) {
                    at[t.row]
                } else {
                    t.row
                };
                let col = if matches!(t.which, Which::A | Which::C) {
                    at[t.col]
                } else {
                    t.col
                };
                out[t.which as usize][(row, col)] += self.value(&t.entry, &table, &t.key)?;
            }
        }
        let [a, b, c, d]: [DMatrix<f64>; 4] = out
            .try_into()
            .map_err(|_| self.err("linear", "needs A, B, C"))?;
        Ok([a, b, c, d])
    }

    fn checked_theta(&self, enabled: &[String], theta: &[f64]) -> Result<()> {
        let want = self.parameters(enabled)?.len();
        if theta.len() != want {
            return Err(SimError::LengthMismatch {
                what: format!("parameter vector of {}", self.name),
                expected: want,
                found: theta.len(),
            });
        }
        Ok(())
    }

    /// The linear model at the documented values, with the given effects on.
    pub fn documented_state_space(&self, enabled: &[String]) -> Result<StateSpace> {
        let theta: Vec<f64> = self.parameters(enabled)?.iter().map(|p| p.value).collect();
        self.state_space(enabled, &theta)
    }
}

impl ModelStructure for ModelFile {
    fn system(&self) -> &str {
        &self.name
    }

    fn state_names(&self, enabled: &[String]) -> Vec<String> {
        self.active_states(enabled)
            .into_iter()
            .map(|i| self.all_states[i].clone())
            .collect()
    }

    fn inputs(&self) -> Vec<String> {
        self.inputs.clone()
    }

    fn outputs(&self) -> Vec<String> {
        self.outputs.clone()
    }

    fn effects(&self) -> Vec<String> {
        self.effects.iter().map(|e| e.name.clone()).collect()
    }

    fn describe(&self, effect: &str) -> String {
        self.effects.iter().find(|e| e.name == effect).map_or_else(
            || format!("unknown effect {effect}"),
            |e| e.description.clone(),
        )
    }

    fn fixed(&self) -> Vec<(String, f64, String)> {
        self.parameters
            .iter()
            .filter(|p| p.fixed)
            .map(|p| {
                (
                    p.parameter.name.clone(),
                    p.parameter.value,
                    "fixed in the model file".into(),
                )
            })
            .collect()
    }

    fn parameters(&self, enabled: &[String]) -> Result<Vec<Parameter>> {
        for name in enabled {
            if !self.effects.iter().any(|e| &e.name == name) {
                return Err(SimError::invalid(
                    "effect",
                    name,
                    format!("not declared in {}", self.path.display()),
                ));
            }
        }
        Ok(self
            .parameters
            .iter()
            .chain(self.enabled_effects(enabled).flat_map(|e| &e.parameters))
            .filter(|p| !p.fixed)
            .map(|p| p.parameter.clone())
            .collect())
    }

    fn controller(&self) -> Option<Controller> {
        self.controller.clone()
    }

    fn is_nonlinear(&self) -> bool {
        self.nonlinear.is_some()
    }

    fn dynamics(&self, enabled: &[String], theta: &[f64]) -> Option<Result<Box<dyn Dynamics>>> {
        let nl = self.nonlinear.as_ref()?;
        Some(self.checked_theta(enabled, theta).and_then(|()| {
            let table = self.table(enabled, theta)?;
            Ok(
                Box::new(nl.dynamics(enabled, self.active_states(enabled), table))
                    as Box<dyn Dynamics>,
            )
        }))
    }

    fn state_space(&self, enabled: &[String], theta: &[f64]) -> Result<StateSpace> {
        self.checked_theta(enabled, theta)?;
        let [a, b, c, d] = self.matrices(enabled, theta)?;
        Ok(StateSpace {
            a,
            b,
            c,
            d,
            delay: 0.0,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::spectra::C64;

    /// The issue's example, verbatim.
    pub(crate) const PENDULUM: &str = r#"
name = "pendulum"                      # MCAP topics /pendulum/input, /pendulum/output, /pendulum/excitation
states = ["theta", "omega"]
inputs = ["T"]
outputs = ["theta"]

[parameters]                           # a number, or a table: value (documented), min, max, unit, fixed
m = { value = 0.5, min = 0.01, unit = "kg" }
l = 0.4
J = { value = 0.02, min = 0.0, unit = "kg m^2" }
g = { value = 9.81, fixed = true }

[definitions]                          # named expressions usable below
Jp = "J + m*l^2"

[linear]                               # continuous time: x' = A x + B u, y = C x + D u (D optional)
A = [[0, 1], ["m*g*l/Jp", 0]]          # entries: numbers or expressions in parameters and definitions
B = [[0], ["1/Jp"]]
C = [[1, 0]]

[effects.joint_friction]               # a candidate effect the user suspects
description = "viscous friction torque -b omega at the joint"
parameters = { b = { value = 0.001, min = 0.0, unit = "N m s/rad" } }
A = { "omega,omega" = "-b/Jp" }        # added terms, keyed "row,column" by state / input / output names
"#;

    fn parse(text: &str) -> Result<ModelFile> {
        ModelFile::parse(text, Path::new("pendulum.toml"))
    }

    #[test]
    fn the_documented_example_gives_the_closed_form_matrices() {
        let m = parse(PENDULUM).unwrap();
        let jp: f64 = 0.02 + 0.5 * 0.4 * 0.4;
        let ss = m.documented_state_space(&[]).unwrap();
        assert_eq!(
            ss.a,
            DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.5 * 9.81 * 0.4 / jp, 0.0])
        );
        assert_eq!(ss.b, DMatrix::from_row_slice(2, 1, &[0.0, 1.0 / jp]));
        assert_eq!(ss.d, DMatrix::zeros(1, 1));
        let names: Vec<String> = m
            .parameters(&[])
            .unwrap()
            .into_iter()
            .map(|p| p.name)
            .collect();
        assert_eq!(names, ["m", "l", "J"]);
        assert_eq!(m.fixed()[0].0, "g");
        let with = vec!["joint_friction".to_string()];
        let ss = m.state_space(&with, &[0.5, 0.4, 0.02, 0.003]).unwrap();
        assert!((ss.a[(1, 1)] + 0.003 / jp).abs() < 1e-15);
    }

    fn error_of(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    /// A flexible sensor mount as an effect with states of its own: `q`, flexed by the
    /// pendulum's angular acceleration, is read with the angle.
    const MOUNT: &str = r#"
[effects.mount]
description = "sensor mount mode q'' + 2 z w q' + w^2 q = a theta'', read with theta"
parameters = { w = { value = 60.0, min = 1.0 }, z = { value = 0.05, min = 0.0 }, a = 0.2 }
states = ["q", "qd"]
A = { "q,qd" = 1, "qd,q" = "-w^2", "qd,qd" = "-2*z*w", "qd,theta" = "a*m*g*l/Jp" }
B = { "qd,T" = "a/Jp" }
C = { "theta,q" = 1 }
"#;

    /// The mount's states follow the pendulum's, and the response is the closed form
    /// `P(s) (1 + a s^2 / (s^2 + 2 z w s + w^2))`, `P = 1 / (Jp s^2 - m g l)` (1e-12).
    #[test]
    fn an_effect_with_states_of_its_own_grows_the_model() {
        let m = parse(&format!("{PENDULUM}{MOUNT}")).unwrap();
        let (w, z, a) = (60.0, 0.05, 0.2);
        let jp: f64 = 0.02 + 0.5 * 0.4 * 0.4;
        let mount = vec!["mount".to_string()];
        assert_eq!(m.state_names(&[]), ["theta", "omega"]);
        assert_eq!(m.state_names(&mount), ["theta", "omega", "q", "qd"]);
        assert_eq!(m.documented_state_space(&[]).unwrap().a.nrows(), 2);
        let ss = m.documented_state_space(&mount).unwrap();
        assert_eq!((ss.a.nrows(), ss.b.nrows(), ss.c.ncols()), (4, 4, 4));
        for omega in [0.3, 2.0, 45.0, 60.0, 300.0] {
            let s = C64::new(0.0, omega);
            let p = 1.0 / (jp * s * s - 0.5 * 9.81 * 0.4);
            let want = p * (1.0 + a * s * s / (s * s + 2.0 * z * w * s + w * w));
            let got = ss.frequency_response_at(omega).unwrap()[(0, 0)];
            assert!(
                (got - want).norm() <= 1e-12 * want.norm(),
                "{omega}: {got} vs {want}"
            );
        }
        // Its parameters are the effect's, the matrices of the model without it unchanged.
        let names: Vec<String> = m
            .parameters(&mount)
            .unwrap()
            .into_iter()
            .map(|p| p.name)
            .collect();
        assert_eq!(names, ["m", "l", "J", "w", "z", "a"]);
        assert_eq!(
            m.documented_state_space(&[]).unwrap().a,
            parse(PENDULUM)
                .unwrap()
                .documented_state_space(&[])
                .unwrap()
                .a
        );
    }

    #[test]
    fn an_effects_states_are_checked_by_name() {
        let cases = [
            (
                MOUNT.replace("[\"q\", \"qd\"]", "[\"q\", \"theta\"]"),
                vec!["effects.mount.states", "\"theta\" is already a state"],
            ),
            (
                MOUNT.replace("\"q,qd\" = 1, ", ""),
                vec!["effects.mount.states", "\"q\" has no derivative"],
            ),
            (
                MOUNT.replace("C = { \"theta,q\" = 1 }\n", ""),
                vec![
                    "effects.mount.states",
                    "q, qd read by nothing outside the effect",
                ],
            ),
            (
                MOUNT.replace("\"q,qd\"", "\"q,qq\""),
                vec![
                    "effects.mount.A.\"q,qq\"",
                    "\"qq\" is not one of the states: theta, omega, q, qd",
                ],
            ),
            (
                format!("{MOUNT}operating_point = {{ q = 0 }}\n"),
                vec!["effects.mount.operating_point", "only a [nonlinear] model"],
            ),
            (
                MOUNT.replace("\"a*m*g*l/Jp\"", "\"a*q\""),
                vec![
                    "effects.mount.A.\"qd,theta\"",
                    "\"q\" in \"a*q\" is not visible here",
                ],
            ),
        ];
        for (mount, wants) in cases {
            let text = format!("{PENDULUM}{mount}");
            let msg = parse(&text)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_else(|| panic!("accepted: {mount}"));
            for w in wants {
                assert!(msg.contains(w), "{msg:?} lacks {w:?}");
            }
        }
    }

    #[test]
    fn bad_files_are_refused_naming_file_key_and_problem() {
        let cases = [
            (
                PENDULUM.replace("\"m*g*l/Jp\"", "\"m*g*l/Jq\""),
                // Only the names the entry may read: no state, input or effect parameter.
                vec![
                    "pendulum.toml",
                    "linear.A[1][0]",
                    "\"Jq\" at position 7",
                    "names here: m, l, J, g, Jp",
                ],
            ),
            (
                PENDULUM.replace(
                    "A = [[0, 1], [\"m*g*l/Jp\", 0]]",
                    "A = [[0, 1, 2], [\"m*g*l/Jp\", 0, 1]]",
                ),
                vec!["linear.A", "is 2x3, must be 2x2"],
            ),
            (
                PENDULUM.replace("B = [[0], [\"1/Jp\"]]", "B = [[0], [\"1/Jp\"], [1]]"),
                vec!["linear.B", "3x1, must be 2x1"],
            ),
            (
                PENDULUM.replace(
                    "states = [\"theta\", \"omega\"]",
                    "states = [\"theta\", \"theta\"]",
                ),
                vec!["states", "named twice"],
            ),
            (
                PENDULUM.replace("outputs = [\"theta\"]", "outputs = [\"T\"]"),
                vec!["outputs", "\"T\" is an input and an output"],
            ),
            (
                PENDULUM.replace("l = 0.4", "l = 0.4\nm = 2.0"),
                vec!["not valid TOML"],
            ),
            (
                PENDULUM.replace("l = 0.4", "l = 0.4\nJp = 2.0"),
                vec!["definitions.Jp", "named twice"],
            ),
            (
                PENDULUM
                    .replace("J = { value = 0.02", "J = { value = 0.0")
                    .replace("l = 0.4", "l = 0.0"),
                vec!["linear.A[1][0]", "is NaN", "Jp = 0"],
            ),
            (
                PENDULUM.replace("\"omega,omega\"", "\"omega,phi\""),
                vec![
                    "effects.joint_friction.A",
                    "\"phi\" is not one of the states",
                ],
            ),
            (
                PENDULUM.replace("\"-b/Jp\"", "\"-b/Jp +\""),
                vec!["effects.joint_friction.A", "syntax error"],
            ),
            (
                PENDULUM.replace("l = 0.4", "e = 0.4"),
                vec!["parameters.e", "constant"],
            ),
            (
                PENDULUM.replace("Jp = \"J + m*l^2\"", "Jp = \"J + m*l^2 + Jq\"\nJq = \"Jp\""),
                vec!["circle"],
            ),
        ];
        for (text, wants) in cases {
            let msg = error_of(&text);
            for w in wants {
                assert!(msg.contains(w), "{msg:?} lacks {w:?}");
            }
        }
    }

    #[test]
    fn controllers_of_both_kinds_are_read_and_checked() {
        let sf = format!("{PENDULUM}\n[controller]\nsample_rate_hz = 100\nK = [[-2.0, -0.3]]\n");
        match parse(&sf).unwrap().controller() {
            Some(Controller::StateFeedback { k, sample_rate_hz }) => {
                assert_eq!(k.shape(), (1, 2));
                assert_eq!(sample_rate_hz, 100.0);
            }
            other => panic!("{other:?}"),
        }
        let bad = format!("{PENDULUM}\n[controller]\nsample_rate_hz = 100\nK = [[-2.0]]\n");
        assert!(error_of(&bad).contains("controller.K: is 1x1, must be 1x2"));
        let dc = format!(
            "{PENDULUM}\n[controller]\nsample_rate_hz = 50\ntype = \"discrete\"\nA = [[0.9]]\nB = [[1.0]]\nC = [[-3.0]]\nD = [[-10.0]]\n"
        );
        assert!(matches!(
            parse(&dc).unwrap().controller(),
            Some(Controller::Discrete { .. })
        ));
        // A misspelt key, or a gain of the other kind beside the one used, is refused by name.
        let typo = sf.replace(
            "sample_rate_hz = 100\n",
            "sample_rate_hz = 100\nsampel_rate = 100\n",
        );
        assert!(
            error_of(&typo).contains("controller.sampel_rate: unknown field for a controller of type \"state_feedback\" (expected sample_rate_hz, type, K)"),
            "{}",
            error_of(&typo)
        );
        let both = format!("{dc}K = [[-2.0, -0.3]]\n");
        assert!(
            error_of(&both)
                .contains("controller.K: unknown field for a controller of type \"discrete\""),
            "{}",
            error_of(&both)
        );
    }
}
