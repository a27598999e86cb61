//! Words, numbers, parameters and `[ ]` expressions of one normalised line.
//!
//! The line has been lower-cased with comments and blanks removed (as
//! LinuxCNC does before reading), so `x 1 0` reads as `x10`. `cols[i]` is the
//! byte offset in the source line of `buf[i]`.

use std::collections::HashMap;

use crate::error::ParseErrorKind;

/// Numbered parameters `#1` … `#5601` (LinuxCNC's range; `#0` reads as 0).
pub const PARAMETER_COUNT: usize = 5602;
/// Deepest nesting inside one word: `[ ]` (a function's included), unary signs
/// and `#` indirections each count a level (protects the stack on hostile input).
pub const MAX_EXPRESSION_DEPTH: u32 = 64;
/// How close to an integer a value must be to count as one (LinuxCNC's `is_near_int`).
pub const NEAR_INT_TOL: f64 = 1e-4;

/// Parameter storage: numbered and named (`#<name>`, case-insensitive).
#[derive(Debug, Clone)]
pub struct Parameters {
    numbered: Vec<f64>,
    named: HashMap<String, f64>,
}

impl Default for Parameters {
    fn default() -> Self {
        Parameters {
            numbered: vec![0.0; PARAMETER_COUNT],
            named: HashMap::new(),
        }
    }
}

/// A parameter assignment waiting for the end of its line (RS274/NGC applies
/// them after the line is read, so reads on the line see the old values).
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    /// `#n`.
    Numbered(usize),
    /// `#<name>`.
    Named(String),
}

impl Parameters {
    /// Stores `value`.
    pub fn set(&mut self, target: Target, value: f64) {
        match target {
            Target::Numbered(i) => self.numbered[i] = value,
            Target::Named(n) => {
                self.named.insert(n, value);
            }
        }
    }
}

/// An error at byte offset `pos` of the normalised line.
pub type ExprResult<T> = Result<T, (usize, ParseErrorKind)>;

/// Reader over one normalised line.
pub struct Cursor<'a> {
    pub buf: &'a [u8],
    pub pos: usize,
    pub params: &'a Parameters,
}

fn expr_err<T>(pos: usize, msg: &str) -> ExprResult<T> {
    Err((pos, ParseErrorKind::Expression(msg.to_string())))
}

/// Binary operators, by precedence (higher binds tighter).
#[derive(Clone, Copy, PartialEq, Debug)]
enum Op {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl Op {
    fn precedence(self) -> u8 {
        match self {
            Op::Pow => 4,
            Op::Mul | Op::Div | Op::Mod => 3,
            Op::Add | Op::Sub => 2,
            Op::Eq | Op::Ne | Op::Gt | Op::Ge | Op::Lt | Op::Le => 1,
            Op::And | Op::Or | Op::Xor => 0,
        }
    }
}

impl<'a> Cursor<'a> {
    fn peek(&self) -> Option<u8> {
        self.buf.get(self.pos).copied()
    }

    fn starts_with(&self, s: &[u8]) -> bool {
        self.buf[self.pos.min(self.buf.len())..].starts_with(s)
    }

    /// A plain decimal number: optional sign, digits with at most one point.
    pub fn number(&mut self) -> ExprResult<f64> {
        let start = self.pos;
        let mut i = self.pos;
        if matches!(self.buf.get(i), Some(b'+' | b'-')) {
            i += 1;
        }
        let digits_start = i;
        let mut seen_dot = false;
        while let Some(&c) = self.buf.get(i) {
            if c.is_ascii_digit() {
                i += 1;
            } else if c == b'.' && !seen_dot {
                seen_dot = true;
                i += 1;
            } else {
                break;
            }
        }
        let body = &self.buf[digits_start..i];
        if body.is_empty() || body == b"." {
            return Err((start, ParseErrorKind::BadNumber));
        }
        if let Some(v) = fast_decimal(body) {
            self.pos = i;
            return Ok(if self.buf[start] == b'-' { -v } else { v });
        }
        let text = match core::str::from_utf8(&self.buf[start..i]) {
            Ok(t) => t,
            Err(_) => return Err((start, ParseErrorKind::BadNumber)),
        };
        // Rust's float parser does not take a leading '+' with nothing after
        // the point ("1." is fine, ".5" too), which matches RS274/NGC.
        match text.parse::<f64>() {
            Ok(v) => {
                self.pos = i;
                Ok(v)
            }
            Err(_) => Err((start, ParseErrorKind::BadNumber)),
        }
    }

    /// One nesting level deeper than `depth`: a `[ ]` (a function's own
    /// included), a unary sign or a `#` indirection each count one, up to
    /// [`MAX_EXPRESSION_DEPTH`].
    fn deeper(&self, depth: u32) -> ExprResult<u32> {
        if depth >= MAX_EXPRESSION_DEPTH {
            return expr_err(
                self.pos,
                &format!("nested more than {MAX_EXPRESSION_DEPTH} levels deep"),
            );
        }
        Ok(depth + 1)
    }

    /// A real value: number, `[expr]`, parameter, function, or a signed one of
    /// those, `depth` levels inside the word (0 at its start).
    pub fn real_value(&mut self, depth: u32) -> ExprResult<f64> {
        match self.peek() {
            Some(b'[') => {
                let d = self.deeper(depth)?;
                self.bracketed(d)
            }
            Some(b'#') => {
                let at = self.pos;
                let d = self.deeper(depth)?;
                self.pos += 1;
                let t = self.parameter_target(d)?;
                self.read_parameter(&t, at)
            }
            Some(b'-') if !matches!(self.buf.get(self.pos + 1), Some(b'0'..=b'9' | b'.')) => {
                let d = self.deeper(depth)?;
                self.pos += 1;
                Ok(-self.real_value(d)?)
            }
            Some(b'+') if !matches!(self.buf.get(self.pos + 1), Some(b'0'..=b'9' | b'.')) => {
                let d = self.deeper(depth)?;
                self.pos += 1;
                self.real_value(d)
            }
            Some(c) if c.is_ascii_lowercase() => self.function(depth),
            _ => self.number(),
        }
    }

    /// After a `#`: the parameter named or numbered.
    pub fn parameter_target(&mut self, depth: u32) -> ExprResult<Target> {
        if self.peek() == Some(b'<') {
            let start = self.pos;
            let Some(len) = self.buf[self.pos + 1..].iter().position(|&c| c == b'>') else {
                return expr_err(start, "named parameter without closing '>'");
            };
            let name = &self.buf[self.pos + 1..self.pos + 1 + len];
            if name.is_empty() {
                return expr_err(start, "empty parameter name");
            }
            self.pos += len + 2;
            return Ok(Target::Named(String::from_utf8_lossy(name).into_owned()));
        }
        let at = self.pos;
        let v = self.real_value(depth)?;
        let r = v.round();
        if !((v - r).abs() < NEAR_INT_TOL) || r < 0.0 || r >= PARAMETER_COUNT as f64 {
            return Err((
                at,
                ParseErrorKind::BadValue(format!(
                    "parameter number {v} is not an integer in 0..{PARAMETER_COUNT}"
                )),
            ));
        }
        Ok(Target::Numbered(r as usize))
    }

    fn read_parameter(&self, t: &Target, at: usize) -> ExprResult<f64> {
        match t {
            Target::Numbered(i) => Ok(self.params.numbered[*i]),
            Target::Named(n) => match self.params.named.get(n) {
                Some(v) => Ok(*v),
                None => expr_err(at, &format!("named parameter #<{n}> is not defined")),
            },
        }
    }

    fn bracketed(&mut self, depth: u32) -> ExprResult<f64> {
        let open = self.pos;
        self.pos += 1; // '['
        let v = self.expression(depth)?;
        if self.peek() != Some(b']') {
            return expr_err(open, "'[' without matching ']'");
        }
        self.pos += 1;
        Ok(v)
    }

    fn expression(&mut self, depth: u32) -> ExprResult<f64> {
        self.binary(0, depth)
    }

    /// Operators of precedence `min_prec` and above; the recursion is bounded
    /// by the number of precedence levels, so it adds no nesting depth.
    fn binary(&mut self, min_prec: u8, depth: u32) -> ExprResult<f64> {
        let mut lhs = self.real_value(depth)?;
        loop {
            let at = self.pos;
            let Some((op, len)) = self.operator() else {
                return Ok(lhs);
            };
            let prec = op.precedence();
            if prec < min_prec {
                return Ok(lhs);
            }
            self.pos += len;
            let rhs = self.binary(prec + 1, depth)?;
            lhs =
                apply(op, lhs, rhs).map_err(|m| (at, ParseErrorKind::Expression(m.to_string())))?;
        }
    }

    fn operator(&self) -> Option<(Op, usize)> {
        let ops: [(&[u8], Op); 15] = [
            (b"**", Op::Pow),
            (b"*", Op::Mul),
            (b"/", Op::Div),
            (b"mod", Op::Mod),
            (b"+", Op::Add),
            (b"-", Op::Sub),
            (b"eq", Op::Eq),
            (b"ne", Op::Ne),
            (b"gt", Op::Gt),
            (b"ge", Op::Ge),
            (b"lt", Op::Lt),
            (b"le", Op::Le),
            (b"and", Op::And),
            (b"or", Op::Or),
            (b"xor", Op::Xor),
        ];
        ops.iter()
            .find(|(s, _)| self.starts_with(s))
            .map(|(s, op)| (*op, s.len()))
    }

    fn function(&mut self, depth: u32) -> ExprResult<f64> {
        let start = self.pos;
        let len = self.buf[self.pos..]
            .iter()
            .take_while(|c| c.is_ascii_lowercase())
            .count();
        let name = &self.buf[self.pos..self.pos + len];
        self.pos += len;
        if self.peek() != Some(b'[') {
            return expr_err(start, "expected a number, '[', '#' or a function");
        }
        let d = self.deeper(depth)?;
        let a = self.bracketed(d)?;
        let deg = core::f64::consts::PI / 180.0;
        let domain = |ok: bool, v: f64| {
            if ok {
                Ok(v)
            } else {
                expr_err(start, "argument out of the function's domain")
            }
        };
        match name {
            b"sin" => Ok((a * deg).sin()),
            b"cos" => Ok((a * deg).cos()),
            b"tan" => Ok((a * deg).tan()),
            b"asin" => domain((-1.0..=1.0).contains(&a), a.asin() / deg),
            b"acos" => domain((-1.0..=1.0).contains(&a), a.acos() / deg),
            b"atan" => {
                // ATAN[y]/[x] is the two-argument form.
                if self.peek() == Some(b'/') && self.buf.get(self.pos + 1) == Some(&b'[') {
                    self.pos += 1;
                    let x = self.bracketed(d)?;
                    Ok(a.atan2(x) / deg)
                } else {
                    Ok(a.atan() / deg)
                }
            }
            b"sqrt" => domain(a >= 0.0, a.sqrt()),
            b"abs" => Ok(a.abs()),
            b"exp" => Ok(a.exp()),
            b"ln" => domain(a > 0.0, a.ln()),
            b"round" => Ok(a.round()),
            b"fix" => Ok(a.floor()),
            b"fup" => Ok(a.ceil()),
            b"exists" => expr_err(start, "EXISTS is not supported"),
            _ => expr_err(
                start,
                &format!("unknown function '{}'", String::from_utf8_lossy(name)),
            ),
        }
    }
}

fn truth(b: bool) -> f64 {
    if b { 1.0 } else { 0.0 }
}

fn apply(op: Op, a: f64, b: f64) -> Result<f64, &'static str> {
    Ok(match op {
        Op::Pow => {
            if a < 0.0 && b.fract() != 0.0 {
                return Err("negative base to a non-integer power");
            }
            a.powf(b)
        }
        Op::Mul => a * b,
        Op::Div => {
            if b == 0.0 {
                return Err("division by zero");
            }
            a / b
        }
        Op::Mod => {
            if b == 0.0 {
                return Err("MOD by zero");
            }
            // LinuxCNC: the result has the sign of the divisor's magnitude (always ≥ 0 for b > 0).
            let r = a % b;
            if r < 0.0 { r + b.abs() } else { r }
        }
        Op::Add => a + b,
        Op::Sub => a - b,
        Op::Eq => truth(a == b),
        Op::Ne => truth(a != b),
        Op::Gt => truth(a > b),
        Op::Ge => truth(a >= b),
        Op::Lt => truth(a < b),
        Op::Le => truth(a <= b),
        Op::And => truth(a != 0.0 && b != 0.0),
        Op::Or => truth(a != 0.0 || b != 0.0),
        Op::Xor => truth((a != 0.0) != (b != 0.0)),
    })
}

/// Exact powers of ten up to 10^22 (all representable in an f64).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Largest integer below which every integer is exact in an f64 (2^53).
const EXACT_INT_LIMIT: u64 = 1 << 53;

/// Clinger's fast path: digits with at most one point, when the digits form an
/// integer below 2^53 and there are at most 22 after the point, is `m / 10^k`
/// with both exact, so one correctly rounded division gives the same f64 as a
/// full decimal parser. Anything else returns `None` (the caller falls back).
fn fast_decimal(body: &[u8]) -> Option<f64> {
    let mut m: u64 = 0;
    let mut frac: Option<usize> = None;
    for &c in body {
        if c == b'.' {
            frac = Some(0);
            continue;
        }
        m = m.checked_mul(10)?.checked_add(u64::from(c - b'0'))?;
        if let Some(f) = frac.as_mut() {
            *f += 1;
        }
    }
    let k = frac.unwrap_or(0);
    if m >= EXACT_INT_LIMIT || k >= POW10.len() {
        return None;
    }
    Some(m as f64 / POW10[k])
}
