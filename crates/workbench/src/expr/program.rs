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
    // Fused forms, made by `specialized`: the operation with its right operand a symbol or
    // a constant, which halves the dispatches of a typical model expression.
    AddVar(usize),
    SubVar(usize),
    MulVar(usize),
    DivVar(usize),
    AddConst(f64),
    SubConst(f64),
    MulConst(f64),
    DivConst(f64),
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
        Self::checked(p.ops)
    }

    /// The program of `ops` if it leaves exactly one value and fits the stack.
    fn checked(ops: Vec<Op>) -> Option<Self> {
        let mut depth = 0usize;
        let mut deepest = 0usize;
        for op in &ops {
            match op {
                Op::Const(_) | Op::Var(_) => depth += 1,
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow => depth = depth.checked_sub(1)?,
                Op::PowI(_) | Op::Neg | Op::Call(_) => {}
                Op::AddVar(_) | Op::SubVar(_) | Op::MulVar(_) | Op::DivVar(_) => {}
                Op::AddConst(_) | Op::SubConst(_) | Op::MulConst(_) | Op::DivConst(_) => {}
            }
            if depth == 0 {
                return None;
            }
            deepest = deepest.max(depth);
        }
        (depth == 1 && deepest <= STACK).then_some(Self { ops })
    }

    /// The constant `k`.
    pub fn constant(k: f64) -> Self {
        Self {
            ops: vec![Op::Const(k)],
        }
    }

    /// The sum of `self` and `other` (`None` if its stack would be too deep).
    pub fn plus(&self, other: &Self) -> Option<Self> {
        let mut ops = self.ops.clone();
        ops.extend_from_slice(&other.ops);
        ops.push(Op::Add);
        Self::checked(ops)
    }

    /// This program with the symbols `known` gives a value for replaced by it, every
    /// operation on constants alone carried out, and the remaining operations fused with a
    /// symbol or constant right operand. Its value is the same for any table that holds
    /// the known values (to the rounding of the folded operations, which is the same).
    pub fn specialized(&self, known: &dyn Fn(usize) -> Option<f64>) -> Self {
        // Fold: `out` is the program so far; a stack entry is constant when its whole code
        // is one `Const` at the end of `out`.
        let mut out: Vec<Op> = Vec::with_capacity(self.ops.len());
        let mut constant: Vec<bool> = Vec::new();
        for &op in &self.ops {
            let last_const = |out: &[Op]| match out.last() {
                Some(Op::Const(k)) => *k,
                _ => f64::NAN,
            };
            match op {
                Op::Var(i) => match known(i) {
                    Some(k) => {
                        out.push(Op::Const(k));
                        constant.push(true);
                    }
                    None => {
                        out.push(op);
                        constant.push(false);
                    }
                },
                Op::Const(_) => {
                    out.push(op);
                    constant.push(true);
                }
                Op::Add | Op::Sub | Op::Mul | Op::Div | Op::Pow => {
                    let b = constant.pop().unwrap_or(false);
                    let a = constant.last().copied().unwrap_or(false);
                    if a && b {
                        let y = last_const(&out);
                        out.pop();
                        let x = last_const(&out);
                        out.pop();
                        let v = Self {
                            ops: vec![Op::Const(x), Op::Const(y), op],
                        }
                        .eval(&[]);
                        out.push(Op::Const(v));
                    } else {
                        out.push(op);
                        if let Some(c) = constant.last_mut() {
                            *c = false;
                        }
                    }
                }
                Op::PowI(_) | Op::Neg | Op::Call(_) => {
                    if constant.last().copied().unwrap_or(false) {
                        let x = last_const(&out);
                        out.pop();
                        let v = Self {
                            ops: vec![Op::Const(x), op],
                        }
                        .eval(&[]);
                        out.push(Op::Const(v));
                    } else {
                        out.push(op);
                    }
                }
                fused => {
                    out.push(fused);
                    if let Some(c) = constant.last_mut() {
                        *c = false;
                    }
                }
            }
        }
        // Fuse an operand pushed only to be consumed by the next operation.
        let mut fused = Vec::with_capacity(out.len());
        let mut i = 0;
        while i < out.len() {
            let pair = match (out[i], out.get(i + 1)) {
                (Op::Var(k), Some(Op::Add)) => Some(Op::AddVar(k)),
                (Op::Var(k), Some(Op::Sub)) => Some(Op::SubVar(k)),
                (Op::Var(k), Some(Op::Mul)) => Some(Op::MulVar(k)),
                (Op::Var(k), Some(Op::Div)) => Some(Op::DivVar(k)),
                (Op::Const(k), Some(Op::Add)) => Some(Op::AddConst(k)),
                (Op::Const(k), Some(Op::Sub)) => Some(Op::SubConst(k)),
                (Op::Const(k), Some(Op::Mul)) => Some(Op::MulConst(k)),
                (Op::Const(k), Some(Op::Div)) => Some(Op::DivConst(k)),
                _ => None,
            };
            match pair {
                Some(op) => {
                    fused.push(op);
                    i += 2;
                }
                None => {
                    fused.push(out[i]);
                    i += 1;
                }
            }
        }
        Self { ops: fused }
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
                Op::AddVar(i) => stack[top - 1] += table[i],
                Op::SubVar(i) => stack[top - 1] -= table[i],
                Op::MulVar(i) => stack[top - 1] *= table[i],
                Op::DivVar(i) => stack[top - 1] /= table[i],
                Op::AddConst(k) => stack[top - 1] += k,
                Op::SubConst(k) => stack[top - 1] -= k,
                Op::MulConst(k) => stack[top - 1] *= k,
                Op::DivConst(k) => stack[top - 1] /= k,
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
    use proptest::prelude::*;

    proptest! {
        /// Folding the known symbols and fusing operands gives the same value to the bit
        /// (or NaN where the program gives NaN), whichever symbols are known.
        #[test]
        fn specialized_is_the_same_function(
            values in proptest::collection::vec(-3.0f64..3.0, 4),
            known in proptest::collection::vec(any::<bool>(), 4),
            which in 0usize..6,
        ) {
            let sym = names(&["a", "b", "c", "d"]);
            let text = [
                "a*b + c/d - a^2",
                "(a + b)*(c - d)/(a*b - 1)",
                "sin(a)*cos(b)*tanh(c/0.05) + exp(-d)",
                "-a*b^3 + 2^c - d/2/a",
                "a + 1 + 2*3 - b*(4 - 1)",
                "sqrt(abs(a*b)) + log(1 + c^2) + d^0.5",
            ][which];
            let p = Program::compile(text, &sym).unwrap();
            let q = p.specialized(&|i| known[i].then_some(values[i]));
            let (want, got) = (p.eval(&values), q.eval(&values));
            prop_assert!(
                want.to_bits() == got.to_bits() || (want.is_nan() && got.is_nan()),
                "{text}: {want} against {got}"
            );
            prop_assert!(q.ops.len() <= p.ops.len());
        }
    }

    /// A sum of programs is the sum of their values; constants fold away entirely.
    #[test]
    fn sums_and_constants() {
        let sym = names(&["a", "b"]);
        let p = Program::compile("a*b", &sym).unwrap();
        let q = Program::compile("-2*tanh(b/0.5)", &sym).unwrap();
        let t = [1.5, -0.25];
        let s = p.plus(&q).unwrap();
        assert_eq!(s.eval(&t), p.eval(&t) + q.eval(&t));
        let folded = s.specialized(&|_| Some(0.0)).specialized(&|i| Some(t[i]));
        assert!(matches!(folded.ops[..], [Op::Const(_)]), "{:?}", folded.ops);
        assert_eq!(Program::constant(4.0).eval(&[]), 4.0);
    }

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
