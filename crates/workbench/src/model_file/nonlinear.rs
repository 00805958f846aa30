//! The `[nonlinear]` section of a model file: `f.<state>` and `h.<output>` expressions in
//! states, inputs, parameters and definitions, the operating point, the terms effects add to
//! definitions and to `f` and `h`; the model as [`Dynamics`] and its linearization (symbolic
//! partial derivatives, chained through the definitions).
use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::DMatrix;
use toml::{Table, Value};

use super::super::dynamics::Dynamics;
use super::super::expr::{Derivative, Program};
use super::{number, Entry, Reader};
use crate::error::{Result, SimError};

/// Where an effect's added term goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Target {
    /// A definition, by symbol slot.
    Definition(usize),
    /// The derivative of a state.
    F(usize),
    /// An output.
    H(usize),
}

/// An expression with its partial derivatives by the symbols it reads.
#[derive(Debug, Clone)]
pub(super) struct Node {
    pub entry: Entry,
    pub key: String,
    partials: Vec<(usize, Derivative)>,
}

impl Node {
    pub fn new(entry: Entry, key: String) -> Self {
        Self {
            entry,
            key,
            partials: Vec::new(),
        }
    }

    fn differentiate(&mut self, r: &Reader) -> Result<()> {
        if let Entry::Expr(e) = &self.entry {
            self.partials = e
                .reads()
                .iter()
                .map(|&s| {
                    e.derivative(s)
                        .map(|d| (s, d))
                        .map_err(|e| r.err(&self.key, e.reason))
                })
                .collect::<Result<_>>()?;
        }
        Ok(())
    }

    pub fn reads(&self) -> &[usize] {
        match &self.entry {
            Entry::Number(_) => &[],
            Entry::Expr(e) => e.reads(),
        }
    }
}

/// A term an effect adds.
#[derive(Debug, Clone)]
pub(super) struct Addition {
    pub target: Target,
    pub node: Node,
}

/// Everything the nonlinear model evaluates, shared by every [`FileDynamics`] built from it.
#[derive(Debug)]
pub(super) struct Section {
    path: PathBuf,
    symbols: Vec<String>,
    /// First state slot; the effects' states follow the model's, the inputs follow them.
    state0: usize,
    m: usize,
    p: usize,
    /// Definitions in evaluation order, `(slot, node)`.
    definitions: Vec<(usize, Node)>,
    /// `f` of every state, the model's and the effects' (whose own are zero: their additions
    /// give them).
    f: Vec<Node>,
    h: Vec<Node>,
    /// Additions per effect, in the file's effect order.
    additions: Vec<(String, Vec<Addition>)>,
    /// Operating point of every state, and of the inputs.
    x_op: Vec<f64>,
    u_op: Vec<f64>,
}

/// The symbol layout of a model file, for reading its `[nonlinear]` section.
pub(super) struct Layout<'a> {
    pub symbols: &'a [String],
    pub visible: &'a [bool],
    pub states: &'a [String],
    pub inputs: &'a [String],
    pub outputs: &'a [String],
}

/// The `f` and `h` expressions of `[nonlinear]` (of the model's states and outputs) and its
/// `operating_point` (of the model's states, and of the inputs).
type Read = (Vec<Node>, Vec<Node>, Vec<f64>, Vec<f64>);

/// Reads `[nonlinear]`: `f`, `h` and `operating_point`.
pub(super) fn read(r: &Reader, t: &Table, l: &Layout) -> Result<Read> {
    for key in t.keys() {
        if !["f", "h", "operating_point"].contains(&key.as_str()) {
            return Err(r.err(
                format!("nonlinear.{key}"),
                "unknown key (expected f.<state>, h.<output>, operating_point)",
            ));
        }
    }
    let exprs = |what: &str, names: &[String], kind: &str| -> Result<Vec<Node>> {
        let table = t.get(what).and_then(Value::as_table).ok_or_else(|| {
            let problem = match t.get(what) {
                None => "missing".to_string(),
                Some(v) => format!("not a table (given: {})", v.type_str()),
            };
            r.err(
                format!("nonlinear.{what}"),
                format!(
                    "{problem}: one expression per {kind} by name, {what}.{} = \"...\"",
                    names.first().map_or("<name>", String::as_str)
                ),
            )
        })?;
        for k in table.keys() {
            if !names.contains(k) {
                return Err(r.err(
                    format!("nonlinear.{what}.{k}"),
                    format!("{k:?} is not one of the {kind}s: {}", names.join(", ")),
                ));
            }
        }
        names
            .iter()
            .map(|name| {
                let key = format!("nonlinear.{what}.{name}");
                let v = table.get(name).ok_or_else(|| {
                    r.err(
                        &key,
                        format!("missing: every {kind} needs {what}.{name} = \"...\""),
                    )
                })?;
                Ok(Node::new(r.entry(&key, v, l.symbols, l.visible)?, key))
            })
            .collect()
    };
    let f = exprs("f", l.states, "state")?;
    let h = exprs("h", l.outputs, "output")?;
    let op = t
        .get("operating_point")
        .and_then(Value::as_table)
        .ok_or_else(|| {
            r.err(
                "nonlinear.operating_point",
                format!(
                    "missing: a value for every state and input, e.g. {{ {} = 0 }}",
                    l.states
                        .iter()
                        .chain(l.inputs)
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(" = 0, ")
                ),
            )
        })?;
    let mut point = Vec::with_capacity(l.states.len() + l.inputs.len());
    for (name, kind) in l
        .states
        .iter()
        .map(|s| (s, "state"))
        .chain(l.inputs.iter().map(|s| (s, "input")))
    {
        let v = op.get(name).ok_or_else(|| {
            r.err(
                "nonlinear.operating_point",
                format!("missing {kind} {name} (give a value for every state and input)"),
            )
        })?;
        point.push(number(v).filter(|x| x.is_finite()).ok_or_else(|| {
            r.err(
                format!("nonlinear.operating_point.{name}"),
                "must be a finite number",
            )
        })?);
    }
    if let Some(k) = op
        .keys()
        .find(|k| !l.states.contains(k) && !l.inputs.contains(k))
    {
        return Err(r.err(
            format!("nonlinear.operating_point.{k}"),
            format!("{k:?} is not a state or input"),
        ));
    }
    let u_op = point.split_off(l.states.len());
    Ok((f, h, point, u_op))
}

impl Section {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        r: &Reader,
        symbols: &[String],
        state0: usize,
        (m, p): (usize, usize),
        definitions: Vec<(usize, Node)>,
        (f, h, x_op, u_op): Read,
        additions: Vec<(String, Vec<Addition>)>,
    ) -> Result<Self> {
        let mut s = Self {
            path: r.path.to_path_buf(),
            symbols: symbols.to_vec(),
            state0,
            m,
            p,
            definitions,
            f,
            h,
            additions,
            x_op,
            u_op,
        };
        for (_, d) in &mut s.definitions {
            d.differentiate(r)?;
        }
        for node in s.f.iter_mut().chain(s.h.iter_mut()) {
            node.differentiate(r)?;
        }
        for (_, adds) in &mut s.additions {
            for a in adds {
                a.node.differentiate(r)?;
            }
        }
        Ok(s)
    }

    fn err(&self, key: &str, reason: String) -> SimError {
        SimError::ModelFile {
            path: self.path.clone(),
            key: key.to_string(),
            reason,
        }
    }

    fn value(&self, node: &Node, table: &[f64]) -> Result<f64> {
        match &node.entry {
            Entry::Number(x) => Ok(*x),
            Entry::Expr(e) => e.eval(table).map_err(|e| self.err(&node.key, e.reason)),
        }
    }

    /// The additions of the `enabled` effects.
    fn active<'a>(&'a self, enabled: &'a [String]) -> impl Iterator<Item = &'a Addition> + 'a {
        self.additions
            .iter()
            .filter(move |(name, _)| enabled.contains(name))
            .flat_map(|(_, adds)| adds)
    }

    /// Slot of the first input: all states come first.
    fn input0(&self) -> usize {
        self.state0 + self.x_op.len()
    }

    /// The model at the symbol values `table` (parameters set, definitions evaluated at the
    /// operating point) with the `enabled` effects, whose states are `active` (indices into
    /// all states, the model's first).
    pub fn dynamics(
        self: &Arc<Self>,
        enabled: &[String],
        active: Vec<usize>,
        table: Vec<f64>,
    ) -> FileDynamics {
        let adds: Vec<Addition> = self.active(enabled).cloned().collect();
        // A definition is evaluated per call when it reads a state, an input, or such a
        // definition, itself or through a term an enabled effect adds to it.
        let mut moving = vec![false; self.symbols.len()];
        for s in &mut moving[self.state0..] {
            *s = true;
        }
        let mut dynamic = Vec::new();
        for (i, (slot, node)) in self.definitions.iter().enumerate() {
            let reads_motion = |n: &Node| n.reads().iter().any(|&s| moving[s]);
            let moves = reads_motion(node)
                || adds
                    .iter()
                    .any(|a| a.target == Target::Definition(*slot) && reads_motion(&a.node));
            if moves {
                moving[*slot] = true;
                dynamic.push(i);
            }
        }
        // The outputs often read a few states only: `h` evaluates just the definitions its
        // expressions reach.
        let mut reached = vec![false; self.symbols.len()];
        let mark = |n: &Node, reached: &mut Vec<bool>| {
            for &s in n.reads() {
                reached[s] = true;
            }
        };
        for (i, n) in self.h.iter().enumerate() {
            mark(n, &mut reached);
            for a in adds.iter().filter(|a| a.target == Target::H(i)) {
                mark(&a.node, &mut reached);
            }
        }
        for (slot, node) in self.definitions.iter().rev() {
            if reached[*slot] {
                mark(node, &mut reached);
                for a in adds
                    .iter()
                    .filter(|a| a.target == Target::Definition(*slot))
                {
                    mark(&a.node, &mut reached);
                }
            }
        }
        let dynamic_h: Vec<usize> = (0..dynamic.len())
            .filter(|&k| reached[self.definitions[dynamic[k]].0])
            .collect();
        // Everything but the states, the inputs and the moving definitions is a constant of
        // this parameter vector.
        let known = |slot: usize| (!moving[slot]).then(|| table[slot]);
        let with_adds = |node: &Node, target: Target| {
            let mut parts = vec![node.clone()];
            parts.extend(
                adds.iter()
                    .filter(|a| a.target == target)
                    .map(|a| a.node.clone()),
            );
            Hot::new(parts, &known)
        };
        let dynamic = dynamic
            .iter()
            .map(|&i| {
                let (slot, node) = &self.definitions[i];
                (*slot, with_adds(node, Target::Definition(*slot)))
            })
            .collect();
        let f = active
            .iter()
            .map(|&i| with_adds(&self.f[i], Target::F(i)))
            .collect();
        let h = (0..self.p)
            .map(|i| with_adds(&self.h[i], Target::H(i)))
            .collect();
        FileDynamics {
            section: self.clone(),
            table,
            active,
            dynamic,
            dynamic_h,
            f,
            h,
        }
    }

    /// `(A, B, C, D)` at the symbol values `table`: the partial derivatives of `f` and `h` by
    /// the states and inputs, chained through the definitions (`d def / d z` accumulated in
    /// evaluation order), in the rows and columns of the `active` states.
    pub fn linearize(
        &self,
        enabled: &[String],
        active: &[usize],
        table: &[f64],
    ) -> Result<[DMatrix<f64>; 4]> {
        let nz = self.x_op.len() + self.m;
        let mut grad = vec![vec![0.0; nz]; self.symbols.len()];
        for (j, g) in grad[self.state0..].iter_mut().enumerate() {
            g[j] = 1.0;
        }
        let adds: Vec<&Addition> = self.active(enabled).collect();
        let total = |node: &Node, grad: &[Vec<f64>], out: &mut [f64]| -> Result<()> {
            for (s, d) in &node.partials {
                if grad[*s].iter().all(|g| *g == 0.0) {
                    continue;
                }
                let v = d.eval(table).map_err(|e| self.err(&node.key, e.reason))?;
                if !v.is_finite() {
                    // Named here, where the term is known: summed, it would blame whichever
                    // state or input it spoils and the expression it was added to.
                    return Err(self.err(
                        &node.key,
                        format!(
                            "its derivative by {} is {v} at the operating point ({})",
                            self.symbols[*s],
                            self.point_text(table)
                        ),
                    ));
                }
                for (o, g) in out.iter_mut().zip(&grad[*s]) {
                    *o += v * g;
                }
            }
            Ok(())
        };
        for (slot, node) in &self.definitions {
            let mut g = vec![0.0; nz];
            total(node, &grad, &mut g)?;
            for a in adds
                .iter()
                .filter(|a| a.target == Target::Definition(*slot))
            {
                total(&a.node, &grad, &mut g)?;
            }
            grad[*slot] = g;
        }
        let rows = |nodes: &[Node], target: fn(usize) -> Target| -> Result<DMatrix<f64>> {
            let mut out = DMatrix::zeros(nodes.len(), nz);
            for (i, node) in nodes.iter().enumerate() {
                let mut g = vec![0.0; nz];
                total(node, &grad, &mut g)?;
                for a in adds.iter().filter(|a| a.target == target(i)) {
                    total(&a.node, &grad, &mut g)?;
                }
                for (j, v) in g.iter().enumerate() {
                    if !v.is_finite() {
                        let at = self.point_text(table);
                        return Err(self.err(
                            &node.key,
                            format!(
                                "its derivative by {} is {v} at the operating point ({at})",
                                self.symbols[self.state0 + j]
                            ),
                        ));
                    }
                    out[(i, j)] = *v;
                }
            }
            Ok(out)
        };
        let fx = rows(&self.f, Target::F)?;
        let hx = rows(&self.h, Target::H)?;
        let inputs: Vec<usize> = (self.x_op.len()..nz).collect();
        Ok([
            fx.select_rows(active).select_columns(active),
            fx.select_rows(active).select_columns(&inputs),
            hx.select_columns(active),
            hx.select_columns(&inputs),
        ])
    }

    fn point_text(&self, table: &[f64]) -> String {
        self.symbols[self.state0..]
            .iter()
            .zip(&table[self.state0..])
            .map(|(s, v)| format!("{s} = {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A model file's nonlinear model at fixed parameter values.
#[derive(Debug)]
pub struct FileDynamics {
    section: Arc<Section>,
    /// Symbol values: parameters, definitions at the operating point.
    table: Vec<f64>,
    /// Its states, as indices into the section's: the model's and the enabled effects'.
    active: Vec<usize>,
    /// Per definition evaluated per call of `f` (it moves with the states or inputs): its
    /// slot and its expression with the enabled effects' terms.
    dynamic: Vec<(usize, Hot)>,
    /// How many of those `h` needs, and which: indices into `dynamic`.
    dynamic_h: Vec<usize>,
    /// `f` and `h`, each with the enabled effects' terms.
    f: Vec<Hot>,
    h: Vec<Hot>,
}

/// An expression with the terms effects add to it, as the predictor evaluates it millions of
/// times: one program with the parameters (and the definitions that do not move) folded in,
/// or, when a part has no compiled program, the parts.
#[derive(Debug)]
enum Hot {
    Program(Program),
    Parts(Vec<Node>),
}

impl Hot {
    fn new(parts: Vec<Node>, known: &dyn Fn(usize) -> Option<f64>) -> Self {
        let programs: Option<Vec<Program>> = parts
            .iter()
            .map(|n| match &n.entry {
                Entry::Number(x) => Some(Program::constant(*x)),
                Entry::Expr(e) => e.program().cloned(),
            })
            .collect();
        let summed = programs.and_then(|ps| {
            let mut it = ps.into_iter();
            let first = it.next()?;
            it.try_fold(first, |acc, p| acc.plus(&p))
        });
        match summed {
            Some(p) => Self::Program(p.specialized(known)),
            None => Self::Parts(parts),
        }
    }

    fn eval(&self, section: &Section, table: &[f64]) -> Result<f64> {
        match self {
            Self::Program(p) => Ok(p.eval(table)),
            Self::Parts(parts) => parts
                .iter()
                .try_fold(0.0, |acc, n| Ok(acc + section.value(n, table)?)),
        }
    }
}

impl FileDynamics {
    /// Fills `scratch` with the symbol values at `(x, u)`, evaluating the moving definitions
    /// `which` (indices into `dynamic`; all of them when `None`).
    fn prepare(
        &self,
        x: &[f64],
        u: &[f64],
        which: Option<&[usize]>,
        scratch: &mut Vec<f64>,
    ) -> Result<()> {
        let s = &self.section;
        scratch.clear();
        scratch.extend_from_slice(&self.table);
        for (&i, v) in self.active.iter().zip(x) {
            scratch[s.state0 + i] = *v;
        }
        scratch[s.input0()..].copy_from_slice(u);
        let set = |(slot, hot): &(usize, Hot), scratch: &mut Vec<f64>| -> Result<()> {
            scratch[*slot] = hot.eval(s, scratch)?;
            Ok(())
        };
        match which {
            None => self.dynamic.iter().try_for_each(|d| set(d, scratch)),
            Some(ks) => ks.iter().try_for_each(|&k| set(&self.dynamic[k], scratch)),
        }
    }

    /// Evaluates `hot` into `out`; an error names `node(k)`'s key for the `k`-th.
    fn outputs_of<'n>(
        &self,
        hot: &[Hot],
        node: impl Fn(usize) -> &'n Node,
        scratch: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        let s = &self.section;
        for (k, (hot, o)) in hot.iter().zip(out.iter_mut()).enumerate() {
            let v = hot.eval(s, scratch)?;
            if !v.is_finite() {
                return Err(s.err(&node(k).key, format!("is {v} at {}", s.point_text(scratch))));
            }
            *o = v;
        }
        Ok(())
    }
}

impl Dynamics for FileDynamics {
    fn states(&self) -> usize {
        self.active.len()
    }
    fn inputs(&self) -> usize {
        self.section.m
    }
    fn outputs(&self) -> usize {
        self.section.p
    }
    fn f(&self, x: &[f64], u: &[f64], dx: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.prepare(x, u, None, scratch)?;
        let s = &self.section;
        self.outputs_of(&self.f, |k| &s.f[self.active[k]], scratch, dx)
    }
    fn h(&self, x: &[f64], u: &[f64], y: &mut [f64], scratch: &mut Vec<f64>) -> Result<()> {
        self.prepare(x, u, Some(&self.dynamic_h), scratch)?;
        let s = &self.section;
        self.outputs_of(&self.h, |k| &s.h[k], scratch, y)
    }
    fn operating_point(&self) -> (Vec<f64>, Vec<f64>) {
        let s = &self.section;
        (
            self.active.iter().map(|&i| s.x_op[i]).collect(),
            s.u_op.clone(),
        )
    }
}
