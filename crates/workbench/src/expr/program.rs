//! A model-file expression compiled to a stack program: the fast evaluation of
//! [`super::Expr`]. Grammar (the operators and functions of `exmex`'s defaults, with its
//! binding: a unary minus binds tighter than `^`, `^` groups from the left):
//!
//! ```text
//! sum     = product (("+" | "-") product)*
//! product = power (("*" | "/") power)*
//! power   = unary ("^" unary)*
//! unary   = ("-" | "+") unary | atom
//! atom    = number | name | function "(" sum ")" | "(" sum ")"
//! ```
//!
//! Anything else (say `atan2` written between its arguments) does not compile, and the
//! expression keeps `exmex`; a compiled program is used only after it agrees with `exmex`.
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Deepest stack a program may use.
const STACK: usize = 32;

#[derive(Debug, Clone, Copy)]
enum Op {
    Const(f64),
    Var(usize),
    Add,
    Sub,
    Mul,
    Div,
    Pow,
    PowI(i32),
    Neg,
    Call(fn(f64) -> f64),
}

/// A compiled expression.
#[derive(Debug, Clone)]
pub struct Program {
    ops: Vec<Op>,
}

/// The unary functions of `exmex`'s defaults (`log` is the natural logarithm there).
/// A function of one argument.
type Unary = fn(f64) -> f64;

const FUNCTIONS: [(&str, Unary); 27] = [
    ("abs", f64::abs),
    ("signum", f64::signum),
    ("sin", f64::sin),
    ("cos", f64::cos),
    ("tan", f64::tan),
    ("asin", f64::asin),
    ("acos", f64::acos),
    ("atan", f64::atan),
    ("sinh", f64::sinh),
    ("cosh", f64::cosh),
    ("tanh", f64::tanh),
    ("asinh", f64::asinh),
    ("acosh", f64::acosh),
    ("atanh", f64::atanh),
    ("floor", f64::floor),
    ("round", f64::round),
    ("ceil", f64::ceil),
    ("trunc", f64::trunc),
    ("fract", f64::fract),
    ("exp", f64::exp),
    ("sqrt", f64::sqrt),
    ("cbrt", f64::cbrt),
    ("ln", f64::ln),
    ("log2", f64::log2),
    ("log10", f64::log10),
    ("log", f64::ln),
    ("exp2", f64::exp2),
];

const CONSTANTS: [(&str, f64); 4] = [
    ("PI", std::f64::consts::PI),
    ("E", std::f64::consts::E),
    ("e", std::f64::consts::E),
    ("TAU", std::f64::consts::TAU),
];

struct Parser<'a> {
    chars: Vec<char>,
    at: usize,
    symbols: &'a [String],
    ops: Vec<Op>,
}

impl Parser<'_> {
    fn skip(&mut self) {
        while self.chars.get(self.at).is_some_and(|c| c.is_whitespace()) {
            self.at += 1;
        }
    }

    fn peek(&mut self) -> Option<char> {
        self.skip();
        self.chars.get(self.at).copied()
    }

    fn eat(&mut self, c: char) -> bool {
        if self.peek() == Some(c) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn sum(&mut self) -> Option<()> {
        self.product()?;
        loop {
            if self.eat('+') {
                self.product()?;
                self.ops.push(Op::Add);
            } else if self.eat('-') {
                self.product()?;
                self.ops.push(Op::Sub);
            } else {
                return Some(());
            }
        }
    }

    fn product(&mut self) -> Option<()> {
        self.power()?;
        loop {
            if self.eat('*') {
                self.power()?;
                self.ops.push(Op::Mul);
            } else if self.eat('/') {
                self.power()?;
                self.ops.push(Op::Div);
            } else {
                return Some(());
            }
        }
    }

    fn power(&mut self) -> Option<()> {
        self.unary()?;
        while self.eat('^') {
            let before = self.ops.len();
            self.unary()?;
            // A small whole exponent multiplies instead of calling `powf`.
            match self.ops[before..] {
                [Op::Const(k)] if k.fract() == 0.0 && k.abs() <= 16.0 => {
                    self.ops.truncate(before);
                    self.ops.push(Op::PowI(k as i32));
                }
                _ => self.ops.push(Op::Pow),
            }
        }
        Some(())
    }

    fn unary(&mut self) -> Option<()> {
        if self.eat('-') {
            self.unary()?;
            match self.ops.last_mut() {
                Some(Op::Const(k)) => *k = -*k,
                _ => self.ops.push(Op::Neg),
            }
            Some(())
        } else if self.eat('+') {
            self.unary()
        } else {
            self.atom()
        }
    }

    fn atom(&mut self) -> Option<()> {
        let c = self.peek()?;
        if self.eat('(') {
            self.sum()?;
            return self.eat(')').then_some(());
        }
        if c.is_ascii_digit() || c == '.' {
            let start = self.at;
            while self
                .chars
                .get(self.at)
                .is_some_and(|c| c.is_ascii_digit() || *c == '.')
            {
                self.at += 1;
            }
            // An exponent: e or E, a sign, digits (a name starting with e must not follow).
            if matches!(self.chars.get(self.at), Some('e' | 'E')) {
                let mut k = self.at + 1;
                if matches!(self.chars.get(k), Some('+' | '-')) {
                    k += 1;
                }
                if self.chars.get(k).is_some_and(|c| c.is_ascii_digit()) {
                    while self.chars.get(k).is_some_and(|c| c.is_ascii_digit()) {
                        k += 1;
                    }
                    self.at = k;
                }
            }
            let text: String = self.chars[start..self.at].iter().collect();
            self.ops.push(Op::Const(text.parse().ok()?));
            return Some(());
        }
        if c.is_ascii_alphabetic() || c == '_' {
            let start = self.at;
            while self
                .chars
                .get(self.at)
                .is_some_and(|c| c.is_ascii_alphanumeric() || *c == '_')
            {
                self.at += 1;
            }
            let name: String = self.chars[start..self.at].iter().collect();
            if self.peek() == Some('(') {
                let f = FUNCTIONS.iter().find(|(n, _)| *n == name)?.1;
                self.eat('(');
                self.sum()?;
                if !self.eat(')') {
                    return None;
                }
                self.ops.push(Op::Call(f));
                return Some(());
            }
            if let Some(i) = self.symbols.iter().position(|s| *s == name) {
                self.ops.push(Op::Var(i));
                return Some(());
            }
            let k = CONSTANTS.iter().find(|(n, _)| *n == name)?.1;
            self.ops.push(Op::Const(k));
            return Some(());
        }
        None
    }
}

impl Program {
    /// Compiles `text` over `symbols`; `None` when the grammar does not cover it or its
    /// stack would be deeper than [`STACK`].
    pub fn compile(text: &str, symbols: &[String]) -> Option<Self> {
        let mut p = Parser {
            chars: text.chars().collect(),
            at: 0,
            symbols,
            ops: Vec::new(),
        };
        p.sum()?;
        if p.peek().is_some() {
            return None;
        }
        let mut depth = 0usize;
        let mut deepest = 0usize;
        for op in &p.ops {
            match op {
                Op::Const(_) | Op::Var(_) => depth += 1,
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow => depth = depth.checked_sub(1)?,
                Op::PowI(_) | Op::Neg | Op::Call(_) => {}
            }
            deepest = deepest.max(depth);
        }
        (depth == 1 && deepest <= STACK).then_some(Self { ops: p.ops })
    }

    /// The value at the symbol values `table`.
    pub fn eval(&self, table: &[f64]) -> f64 {
        let mut stack = [0.0f64; STACK];
        let mut top = 0usize;
        for op in &self.ops {
            match *op {
                Op::Const(k) => {
                    stack[top] = k;
                    top += 1;
                }
                Op::Var(i) => {
                    stack[top] = table[i];
                    top += 1;
                }
                Op::Add => {
                    top -= 1;
                    stack[top - 1] += stack[top];
                }
                Op::Sub => {
                    top -= 1;
                    stack[top - 1] -= stack[top];
                }
                Op::Mul => {
                    top -= 1;
                    stack[top - 1] *= stack[top];
                }
                Op::Div => {
                    top -= 1;
                    stack[top - 1] /= stack[top];
                }
                Op::Pow => {
                    top -= 1;
                    stack[top - 1] = stack[top - 1].powf(stack[top]);
                }
                Op::PowI(k) => stack[top - 1] = stack[top - 1].powi(k),
                Op::Neg => stack[top - 1] = -stack[top - 1],
                Op::Call(f) => stack[top - 1] = f(stack[top - 1]),
            }
        }
        stack[0]
    }

    /// Whether the program gives `reference`'s values (relative 1e-9) at 64 random points
    /// of the symbols `reads` (spanning signs and four decades), where the reference is finite.
    pub fn agrees_with(
        &self,
        reference: impl Fn(&[f64]) -> Option<f64>,
        symbols: usize,
        reads: &[usize],
    ) -> bool {
        let mut rng = StdRng::seed_from_u64(0x5eed);
        let mut table = vec![0.0; symbols];
        let mut compared = 0;
        for _ in 0..64 {
            for &i in reads {
                let magnitude = 10f64.powf(rng.random_range(-2.0..2.0));
                table[i] = if rng.random_bool(0.5) {
                    magnitude
                } else {
                    -magnitude
                };
            }
            let Some(want) = reference(&table).filter(|v| v.is_finite()) else {
                continue;
            };
            let got = self.eval(&table);
            // A NaN is a disagreement too.
            let close = (got - want).abs() <= 1e-9 * (1.0 + want.abs());
            if !close {
                return false;
            }
            compared += 1;
        }
        compared >= 8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    /// The grammar's binding against closed forms and `exmex` (on the text as
    /// [`super::super::Expr`] rewrites it, `-m^2` meaning `-(m^2)`): `^` from the left, whole
    /// powers, exponents of numbers, functions and constants.
    #[test]
    fn evaluates_with_exmex_binding() {
        let sym = names(&["a", "b"]);
        let t = [1.5, -0.5];
        let cases = [
            ("a + b*a^2", 1.5 + -0.5 * 2.25),
            ("-a^2", -2.25),
            ("-1*a^2", -2.25),
            ("2^3^2", 64.0),
            ("a/b/a", 1.5 / -0.5 / 1.5),
            ("0.001*a + 250", 1.5e-3 + 250.0),
            (
                "sin(a)*cos(b) + tanh(a/b) - log(a)",
                1.5f64.sin() * (-0.5f64).cos() + (-3.0f64).tanh() - 1.5f64.ln(),
            ),
            (
                "2^-a + PI*e",
                2f64.powf(-1.5) + std::f64::consts::PI * std::f64::consts::E,
            ),
            ("(a - b)^0.5", 2f64.sqrt()),
        ];
        for (text, want) in cases {
            let p = Program::compile(&super::super::conventional_minus(text), &sym)
                .unwrap_or_else(|| panic!("{text}"));
            let got = p.eval(&t);
            assert!(
                (got - want).abs() < 1e-12 * (1.0 + want.abs()),
                "{text}: {got} vs {want}"
            );
            let exmex = super::super::Expr::parse(text, &sym)
                .unwrap()
                .interpret(&t)
                .unwrap();
            assert!(
                (got - exmex).abs() < 1e-12 * (1.0 + want.abs()),
                "{text}: exmex {exmex}"
            );
        }
        for bad in ["a +", "sin a", "foo(a)", "a min b", "(a"] {
            assert!(Program::compile(bad, &sym).is_none(), "{bad}");
        }
    }
}
