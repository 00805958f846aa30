//! Expressions of model files: parsed, checked and differentiated by `exmex`, with the checks
//! a user needs to find a mistake (an unknown name or a stray character, with its position).
//!
//! The time-domain criterion evaluates a nonlinear model's expressions millions of times per
//! fit, where `exmex`'s interpreter (about 7 ns an operation, `x^2` through `powf`) is most of
//! the cost. Each expression is therefore also compiled to a small stack program
//! ([`program`]), used only after it agrees with `exmex` at random points; an expression it
//! does not cover (an operator spelled as a word, say) keeps `exmex`.
mod program;

pub use exmex::{Differentiate, Express, FlatEx};
pub use program::Program;

/// Names `exmex` reads as constants or functions: a parameter may not take them, or an
/// expression would silently use the constant (`e` is Euler's number).
pub const RESERVED: [&str; 40] = [
    "PI", "E", "e", "TAU", "abs", "signum", "sin", "cos", "tan", "asin", "acos", "atan", "sinh",
    "cosh", "tanh", "asinh", "acosh", "atanh", "floor", "round", "ceil", "trunc", "fract", "exp",
    "sqrt", "cbrt", "ln", "log2", "log10", "log", "min", "max", "atan2", "if", "else", "and", "or",
    "true", "false", "pi",
];

/// An expression in named quantities, evaluated against a table of values.
#[derive(Debug, Clone)]
pub struct Expr {
    text: String,
    flat: FlatEx<f64>,
    /// Index into the symbol table of each of `flat`'s variables (in exmex's sorted order).
    slots: Vec<usize>,
    /// The compiled form, when it agrees with `flat`.
    program: Option<Program>,
}

/// Why an expression was refused, with its 1-based column where one is known.
#[derive(Debug, Clone, PartialEq)]
pub struct ExprError {
    /// What is wrong.
    pub reason: String,
    /// The name not among the symbols, when that is what is wrong (the caller lists the
    /// names the place may read).
    pub unknown: Option<String>,
}

impl Expr {
    /// Parses `text`, whose names must all be in `symbols`.
    pub fn parse(text: &str, symbols: &[String]) -> Result<Self, ExprError> {
        check_characters(text)?;
        check_functions(text)?;
        let rewritten = conventional_minus(&plain_numbers(text));
        let flat = exmex::parse::<f64>(&rewritten).map_err(|e| ExprError {
            unknown: None,
            reason: format!("syntax error in {text:?}: {}", e.msg()),
        })?;
        let mut slots = Vec::with_capacity(flat.var_names().len());
        for name in flat.var_names() {
            match symbols.iter().position(|s| s == name) {
                Some(i) => slots.push(i),
                None => {
                    let at = position_of(text, name)
                        .map_or(String::new(), |c| format!(" at position {c}"));
                    return Err(ExprError {
                        reason: format!("unknown name {name:?}{at} in {text:?}"),
                        unknown: Some(name.to_string()),
                    });
                }
            }
        }
        let mut e = Self {
            text: text.to_string(),
            flat,
            slots,
            program: None,
        };
        let program = Program::compile(&rewritten, symbols)
            .filter(|p| p.agrees_with(|table| e.interpret(table).ok(), symbols.len(), &e.slots));
        e.program = program;
        Ok(e)
    }

    /// The source text.
    pub fn text(&self) -> &str {
        &self.text
    }

    /// Symbol-table indices this expression reads.
    pub fn reads(&self) -> &[usize] {
        &self.slots
    }

    /// The value for the symbol values `table`.
    pub fn eval(&self, table: &[f64]) -> Result<f64, ExprError> {
        match &self.program {
            Some(p) => Ok(p.eval(table)),
            None => self.interpret(table),
        }
    }

    /// The compiled program, when the expression has one.
    pub fn program(&self) -> Option<&Program> {
        self.program.as_ref()
    }

    /// The value by `exmex`.
    fn interpret(&self, table: &[f64]) -> Result<f64, ExprError> {
        // Evaluated once per model-function call on the predictor's hot path: the variables
        // are gathered on the stack (model expressions read a handful of names).
        const ON_STACK: usize = 24;
        let result = if self.slots.len() <= ON_STACK {
            let mut vars = [0.0; ON_STACK];
            for (v, &i) in vars.iter_mut().zip(&self.slots) {
                *v = table[i];
            }
            self.flat.eval(&vars[..self.slots.len()])
        } else {
            let vars: Vec<f64> = self.slots.iter().map(|&i| table[i]).collect();
            self.flat.eval(&vars)
        };
        result.map_err(|e| ExprError {
            unknown: None,
            reason: format!("cannot evaluate {:?}: {}", self.text, e.msg()),
        })
    }

    /// The partial derivative with respect to symbol `slot` (zero when the expression does
    /// not read it), by `exmex`'s symbolic differentiation.
    pub fn derivative(&self, slot: usize) -> Result<Derivative, ExprError> {
        let Some(var) = self.slots.iter().position(|&s| s == slot) else {
            return Ok(Derivative::Zero);
        };
        let flat = self.flat.clone().partial(var).map_err(|e| ExprError {
            unknown: None,
            reason: format!(
                "cannot differentiate {:?}: {}; the model is linearized at its operating \
                 point, and abs, signum, min, max, floor, ceil, round, trunc and fract have no \
                 derivative here: write a smooth form, e.g. sqrt(v^2 + eps^2) for abs(v), \
                 tanh(v/eps) for signum(v)",
                self.text,
                e.msg()
            ),
        })?;
        // The derivative reads a subset of the variables, in exmex's sorted order again.
        let slots = flat
            .var_names()
            .iter()
            .map(|n| {
                self.flat
                    .var_names()
                    .iter()
                    .position(|m| m == n)
                    .map(|k| self.slots[k])
            })
            .collect::<Option<Vec<usize>>>()
            .ok_or_else(|| ExprError {
                unknown: None,
                reason: format!("derivative of {:?} reads an unknown name", self.text),
            })?;
        Ok(Derivative::Expr(Box::new(Self {
            text: format!("d({})/d[{slot}]", self.text),
            flat,
            slots,
            program: None,
        })))
    }
}

/// A partial derivative of an [`Expr`].
#[derive(Debug, Clone)]
pub enum Derivative {
    /// The expression does not read the symbol.
    Zero,
    /// The derivative expression (boxed: a parsed expression is large).
    Expr(Box<Expr>),
}

impl Derivative {
    /// The value at `table`.
    pub fn eval(&self, table: &[f64]) -> Result<f64, ExprError> {
        match self {
            Self::Zero => Ok(0.0),
            Self::Expr(e) => e.eval(table),
        }
    }
}

/// Numbers in scientific notation (`1e-3`, `2.5E6`), which `exmex` does not read (it takes
/// `e` for Euler's number), written out in decimals.
fn plain_numbers(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < chars.len() {
        let starts = (chars[i].is_ascii_digit() || chars[i] == '.')
            && (i == 0 || !(chars[i - 1].is_ascii_alphanumeric() || chars[i - 1] == '_'));
        if !starts {
            out.push(chars[i]);
            i += 1;
            continue;
        }
        let mut j = i;
        while j < chars.len() && (chars[j].is_ascii_digit() || chars[j] == '.') {
            j += 1;
        }
        let mut end = j;
        if j < chars.len() && matches!(chars[j], 'e' | 'E') {
            let mut k = j + 1;
            if k < chars.len() && matches!(chars[k], '+' | '-') {
                k += 1;
            }
            if k < chars.len() && chars[k].is_ascii_digit() {
                while k < chars.len() && chars[k].is_ascii_digit() {
                    k += 1;
                }
                end = k;
            }
        }
        let literal: String = chars[i..end].iter().collect();
        match (end > j, literal.parse::<f64>()) {
            (true, Ok(v)) => out.push_str(&v.to_string()),
            _ => out.push_str(&literal),
        }
        i = end;
    }
    out
}

/// `exmex` binds a unary minus tighter than `^` (`-m^2` is `(-m)^2`); written as `-1*`, it
/// takes the conventional meaning `-(m^2)`. After `^` the minus stays (`2^-x` is `2^(-x)`).
fn conventional_minus(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + 8);
    let mut prev: Option<char> = None;
    for ch in text.chars() {
        let unary = ch == '-' && prev.is_none_or(|p| "(+-*/,".contains(p));
        if unary {
            out.push_str("-1*");
        } else {
            out.push(ch);
        }
        if !ch.is_whitespace() {
            prev = Some(ch);
        }
    }
    out
}

/// Refuses characters no expression can hold and unbalanced parentheses, with the column.
fn check_characters(text: &str) -> Result<(), ExprError> {
    let mut depth = 0i32;
    for (col, ch) in text.chars().enumerate() {
        let col = col + 1;
        match ch {
            '(' => depth += 1,
            ')' => {
                depth -= 1;
                if depth < 0 {
                    return Err(ExprError {
                        unknown: None,
                        reason: format!("unmatched ')' at position {col} in {text:?}"),
                    });
                }
            }
            c if c.is_ascii_alphanumeric() || c.is_whitespace() || "_.+-*/^,".contains(c) => {}
            c => {
                return Err(ExprError {
                    unknown: None,
                    reason: format!("unexpected character {c:?} at position {col} in {text:?}"),
                })
            }
        }
    }
    if depth > 0 {
        return Err(ExprError {
            unknown: None,
            reason: format!("unclosed '(' in {text:?}"),
        });
    }
    if text.trim().is_empty() {
        return Err(ExprError {
            unknown: None,
            reason: "empty expression".into(),
        });
    }
    Ok(())
}

/// The functions an expression may call (`exmex`'s).
const FUNCTIONS: [&str; 29] = [
    "abs", "signum", "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "asinh",
    "acosh", "atanh", "floor", "round", "ceil", "trunc", "fract", "exp", "sqrt", "cbrt", "ln",
    "log2", "log10", "log", "min", "max", "atan2",
];

/// Refuses a name called as a function that is none (`sinn(x)`, `k(x)`), with its column:
/// `exmex` reports it in its own words, without a position.
fn check_functions(text: &str) -> Result<(), ExprError> {
    let chars: Vec<char> = text.chars().collect();
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut i = 0;
    while i < chars.len() {
        let starts = (chars[i].is_ascii_alphabetic() || chars[i] == '_')
            && (i == 0 || !is_ident(chars[i - 1]));
        if !starts {
            i += 1;
            continue;
        }
        let end = (i..chars.len())
            .find(|&k| !is_ident(chars[k]))
            .unwrap_or(chars.len());
        let name: String = chars[i..end].iter().collect();
        let next = chars[end..].iter().find(|c| !c.is_whitespace());
        if next == Some(&'(') && !FUNCTIONS.contains(&name.as_str()) {
            return Err(ExprError {
                unknown: None,
                reason: format!(
                    "unknown function {name:?} at position {} in {text:?}; functions: {}",
                    i + 1,
                    FUNCTIONS.join(", ")
                ),
            });
        }
        i = end;
    }
    Ok(())
}

/// 1-based column of the first whole-word occurrence of `name` in `text`.
fn position_of(text: &str, name: &str) -> Option<usize> {
    let chars: Vec<char> = text.chars().collect();
    let word: Vec<char> = name.chars().collect();
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    (0..chars.len()).find_map(|i| {
        let end = i + word.len();
        let hit = end <= chars.len()
            && chars[i..end] == word[..]
            && (i == 0 || !is_ident(chars[i - 1]))
            && (end == chars.len() || !is_ident(chars[end]));
        hit.then_some(i + 1)
    })
}

/// Whether `name` can name a quantity: an identifier that is not reserved.
pub fn check_name(name: &str) -> Result<(), String> {
    let mut chars = name.chars();
    let ok = chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !ok {
        return Err(format!(
            "{name:?} is not a name (ASCII letters, digits and '_', not starting with a digit)"
        ));
    }
    if RESERVED.contains(&name) {
        return Err(format!(
            "{name:?} is a constant or function of the expression language"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn evaluates_the_documented_operators_against_closed_forms() {
        let sym = names(&["m", "l", "x"]);
        let table = [0.5, 0.4, 0.3];
        let cases = [
            (
                "m*9.81*l/(0.02 + m*l^2)",
                0.5 * 9.81 * 0.4 / (0.02 + 0.5 * 0.16),
            ),
            (
                "sin(x) + cos(x) - tan(x)",
                0.3f64.sin() + 0.3f64.cos() - 0.3f64.tan(),
            ),
            (
                "exp(x)*log(m) + sqrt(l)",
                0.3f64.exp() * 0.5f64.ln() + 0.4f64.sqrt(),
            ),
            ("abs(-m) + tanh(x)", 0.5 + 0.3f64.tanh()),
            ("-m^2", -0.25),
            ("l*-m^2 + 2^-x", 0.4 * -0.25 + 2f64.powf(-0.3)),
            ("exp(-x^2)/(-l)", (-0.09f64).exp() / -0.4),
            ("1e-3*m + 2.5E2 - 3e+1*x", 0.5e-3 + 250.0 - 9.0),
        ];
        for (text, want) in cases {
            let e = Expr::parse(text, &sym).unwrap();
            let got = e.eval(&table).unwrap();
            assert!((got - want).abs() < 1e-14, "{text}: {got} vs {want}");
        }
    }

    /// Symbolic partial derivatives agree with central differences (relative 1e-7) at
    /// random points, for every operator a model file may use.
    #[test]
    fn derivatives_agree_with_central_differences() {
        use proptest::prelude::*;
        let sym = names(&["a", "b", "x"]);
        let texts = [
            "a*sin(x)*b^2 + cos(a*x)/b",
            "(a + b*x^2)/(1 + a^2*cos(x)^2)",
            "-a*tanh(x/b) + exp(-x^2)*sqrt(b) + log(b)*x",
            "x*x*x - 2^x",
        ];
        let exprs: Vec<Expr> = texts
            .iter()
            .map(|t| Expr::parse(t, &sym).unwrap())
            .collect();
        let mut runner = proptest::test_runner::TestRunner::default();
        runner
            .run(&(0.2f64..2.0, 0.5f64..2.0, -1.5f64..1.5), |(a, b, x)| {
                let table = [a, b, x];
                for e in &exprs {
                    for slot in 0..3 {
                        let d = e.derivative(slot).unwrap().eval(&table).unwrap();
                        let h = 1e-6;
                        let (mut tp, mut tm) = (table, table);
                        tp[slot] += h;
                        tm[slot] -= h;
                        let fd = (e.eval(&tp).unwrap() - e.eval(&tm).unwrap()) / (2.0 * h);
                        prop_assert!(
                            (d - fd).abs() <= 1e-7 * (1.0 + fd.abs()),
                            "{} d/d{slot}: {d} vs {fd}",
                            e.text()
                        );
                    }
                }
                Ok(())
            })
            .unwrap();
        let e = Expr::parse("a*b", &sym).unwrap();
        assert!(matches!(e.derivative(2).unwrap(), Derivative::Zero));
    }

    #[test]
    fn names_an_unknown_symbol_with_its_position() {
        let err = Expr::parse("m*g*l/Jq", &names(&["m", "g", "l", "Jp"])).unwrap_err();
        assert!(
            err.reason.contains("\"Jq\" at position 7"),
            "{}",
            err.reason
        );
        let err = Expr::parse("m*(l", &names(&["m", "l"])).unwrap_err();
        assert!(err.reason.contains("unclosed"), "{}", err.reason);
        let err = Expr::parse("m # l", &names(&["m", "l"])).unwrap_err();
        assert!(err.reason.contains("'#' at position 3"), "{}", err.reason);
        assert!(check_name("e").is_err());
        assert!(check_name("2x").is_err());
        assert!(check_name("J_p2").is_ok());
        // Names are ASCII, and the message says so (θ is a letter, but not one of them).
        let err = check_name("θ").unwrap_err();
        assert!(err.contains("ASCII letters"), "{err}");
        // A misspelt function, and a parameter called like one, with the column.
        let err = Expr::parse(
            "tau - m*g*sinn (alpha)",
            &names(&["tau", "m", "g", "alpha"]),
        )
        .unwrap_err();
        assert!(
            err.reason
                .contains("unknown function \"sinn\" at position 11"),
            "{}",
            err.reason
        );
        let err = Expr::parse("m(l)", &names(&["m", "l"])).unwrap_err();
        assert!(err.reason.contains("\"m\" at position 1"), "{}", err.reason);
        // Functions, and numbers in scientific notation, still parse.
        assert!(Expr::parse("atan2(m, l) + 2e-3*sin(l)", &names(&["m", "l"])).is_ok());
    }
}
