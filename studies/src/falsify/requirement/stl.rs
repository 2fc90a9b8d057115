//! A small signal temporal logic (STL, after Maler and Nickovic, "Monitoring temporal
//! properties of continuous signals", FORMATS 2004) over a run's signals, written as engineers
//! write requirements:
//!
//! ```text
//! formula     := implication
//! implication := disjunction [ "->" implication ]
//! disjunction := conjunction { "or" conjunction }
//! conjunction := unary { "and" unary }
//! unary       := "not" unary | ("always" | "eventually") [ window ] unary
//!              | "(" formula ")" | EVENT | predicate
//! window      := "[" TIME "," ( TIME | "inf" ) "]"          (seconds, "s" optional)
//! predicate   := expr ("<" | "<=" | ">" | ">=") NUMBER [ UNIT ]
//! expr        := [ "-" ] term { ("+" | "-") term }
//! term        := "|" expr "|" | SIGNAL
//! ```
//!
//! `always |lat_acc| < 1.2`, `always (transition_end -> always[0,3] |tilt_error| < 0.5deg)`.
//! A bound is in its signal's SI unit, or carries a unit of the same quantity (`deg` for a
//! signal in rad, `g` for one in m/s²); a sum's signals share one unit.

use super::signals::{Event, Signal, EVENTS};
use crate::falsify::objective::Cmp;

/// A window of time after the present, `[from, to]` seconds (`to` `None`: to the end).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// Start (s).
    pub from_s: f64,
    /// End (s), `None` for the end of the run.
    pub to_s: Option<f64>,
}

/// A signed sum of signals, or the magnitude of one.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    /// A signal.
    Signal(Signal),
    /// `|e|`.
    Abs(Box<Expr>),
    /// Σ sign·e.
    Sum(Vec<(f64, Expr)>),
}

/// A formula.
#[derive(Debug, Clone, PartialEq)]
pub enum Formula {
    /// `expr cmp bound` (bound in SI).
    Pred {
        /// The expression.
        expr: Expr,
        /// The comparison.
        cmp: Cmp,
        /// The bound, in the expression's unit.
        bound: f64,
    },
    /// An event of the track.
    Event(Event),
    /// `not f`.
    Not(Box<Formula>),
    /// `a and b`.
    And(Box<Formula>, Box<Formula>),
    /// `a or b`.
    Or(Box<Formula>, Box<Formula>),
    /// `always[w] f`.
    Always(Window, Box<Formula>),
    /// `eventually[w] f`.
    Eventually(Window, Box<Formula>),
}

impl Formula {
    /// The largest magnitude of a bound in the formula (1 when there is none or all are 0):
    /// its margin's scale beside other requirements.
    pub fn scale(&self) -> f64 {
        fn largest(f: &Formula) -> f64 {
            match f {
                Formula::Pred { bound, .. } => bound.abs(),
                Formula::Event(_) => 0.0,
                Formula::Not(a) | Formula::Always(_, a) | Formula::Eventually(_, a) => largest(a),
                Formula::And(a, b) | Formula::Or(a, b) => largest(a).max(largest(b)),
            }
        }
        let s = largest(self);
        if s > 0.0 {
            s
        } else {
            1.0
        }
    }
}

/// Units a bound may carry: the suffix, the SI unit it is a value of, and its factor.
pub const UNITS: [(&str, &str, f64); 14] = [
    ("deg", "rad", std::f64::consts::PI / 180.0),
    ("rad", "rad", 1.0),
    ("deg/s", "rad/s", std::f64::consts::PI / 180.0),
    ("rad/s", "rad/s", 1.0),
    ("mm", "m", 1e-3),
    ("m", "m", 1.0),
    ("m/s", "m/s", 1.0),
    ("m/s2", "m/s2", 1.0),
    ("g", "m/s2", 9.80665),
    ("s", "s", 1.0),
    ("A", "A", 1.0),
    ("V", "V", 1.0),
    ("W", "W", 1.0),
    ("N.m", "N.m", 1.0),
];

#[derive(Debug, Clone, PartialEq)]
enum Token {
    Word(String),
    Number(f64, Option<String>),
    Sym(&'static str),
}

const SYMBOLS: [&str; 12] = [
    "->", "<=", ">=", "<", ">", "(", ")", "[", "]", ",", "|", "+",
];

fn lex(text: &str) -> Result<Vec<Token>, String> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i] as char;
        if c.is_whitespace() {
            i += 1;
        } else if let Some(s) = SYMBOLS.iter().find(|s| text[i..].starts_with(**s)) {
            out.push(Token::Sym(s));
            i += s.len();
        } else if c == '-' {
            out.push(Token::Sym("-"));
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                i += 1;
            }
            if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                let mut j = i + 1;
                if j < b.len() && (b[j] == b'-' || b[j] == b'+') {
                    j += 1;
                }
                if j < b.len() && b[j].is_ascii_digit() {
                    i = j;
                    while i < b.len() && b[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            let v: f64 = text[start..i]
                .parse()
                .map_err(|_| format!("`{}` is not a number", &text[start..i]))?;
            let unit_char = |c: u8| c.is_ascii_alphanumeric() || c == b'/' || c == b'.';
            let mut u0 = i;
            if i < b.len() && b[i].is_ascii_alphabetic() {
                while i < b.len() && unit_char(b[i]) {
                    i += 1;
                }
            } else {
                // A unit after blanks, when it is one: `0.1 m/s2`, not `1 and`.
                let j = i + text[i..].len() - text[i..].trim_start().len();
                let mut known: Vec<&str> = UNITS.iter().map(|(u, _, _)| *u).collect();
                known.sort_by_key(|u| std::cmp::Reverse(u.len()));
                if let Some(u) = known.iter().find(|u| {
                    text[j..].starts_with(**u) && !b.get(j + u.len()).is_some_and(|c| unit_char(*c))
                }) {
                    u0 = j;
                    i = j + u.len();
                }
            }
            let unit = (i > u0).then(|| text[u0..i].to_string());
            out.push(Token::Number(v, unit));
        } else if c.is_ascii_alphabetic() || c == '_' {
            let start = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                i += 1;
            }
            out.push(Token::Word(text[start..i].to_string()));
        } else {
            let c = text[i..].chars().next().unwrap_or(c);
            return Err(format!("`{c}` is not part of a formula"));
        }
    }
    Ok(out)
}

struct Parser {
    tokens: Vec<Token>,
    at: usize,
}

impl Parser {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.at)
    }

    fn next(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.at).cloned();
        self.at += 1;
        t
    }

    fn eat_sym(&mut self, s: &str) -> bool {
        if matches!(self.peek(), Some(Token::Sym(x)) if *x == s) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn eat_word(&mut self, w: &str) -> bool {
        if matches!(self.peek(), Some(Token::Word(x)) if x == w) {
            self.at += 1;
            true
        } else {
            false
        }
    }

    fn expect_sym(&mut self, s: &str) -> Result<(), String> {
        if self.eat_sym(s) {
            Ok(())
        } else {
            Err(format!("`{s}` expected {}", self.here()))
        }
    }

    fn here(&self) -> String {
        match self.peek() {
            None => "at the end".into(),
            Some(Token::Word(w)) => format!("before `{w}`"),
            Some(Token::Number(v, u)) => format!("before `{v}{}`", u.as_deref().unwrap_or("")),
            Some(Token::Sym(s)) => format!("before `{s}`"),
        }
    }

    fn implication(&mut self) -> Result<Formula, String> {
        let a = self.disjunction()?;
        if self.eat_sym("->") {
            let b = self.implication()?;
            return Ok(Formula::Or(
                Box::new(Formula::Not(Box::new(a))),
                Box::new(b),
            ));
        }
        Ok(a)
    }

    fn disjunction(&mut self) -> Result<Formula, String> {
        let mut a = self.conjunction()?;
        while self.eat_word("or") {
            a = Formula::Or(Box::new(a), Box::new(self.conjunction()?));
        }
        Ok(a)
    }

    fn conjunction(&mut self) -> Result<Formula, String> {
        let mut a = self.unary()?;
        while self.eat_word("and") {
            a = Formula::And(Box::new(a), Box::new(self.unary()?));
        }
        Ok(a)
    }

    fn unary(&mut self) -> Result<Formula, String> {
        if self.eat_word("not") {
            return Ok(Formula::Not(Box::new(self.unary()?)));
        }
        for (word, always) in [("always", true), ("eventually", false)] {
            if self.eat_word(word) {
                let w = self.window()?;
                let f = Box::new(self.unary()?);
                return Ok(if always {
                    Formula::Always(w, f)
                } else {
                    Formula::Eventually(w, f)
                });
            }
        }
        if self.eat_sym("(") {
            let f = self.implication()?;
            self.expect_sym(")")?;
            return Ok(f);
        }
        if let Some(Token::Word(w)) = self.peek() {
            if let Some(e) = Event::named(w) {
                let w = w.clone();
                self.at += 1;
                if matches!(
                    self.peek(),
                    Some(Token::Sym("<" | "<=" | ">" | ">=" | "+" | "-"))
                ) {
                    return Err(format!(
                        "`{w}` is true or false, not a number: use it as a formula (`{w} -> …`)"
                    ));
                }
                return Ok(Formula::Event(e));
            }
        }
        self.predicate()
    }

    fn time(&mut self) -> Result<f64, String> {
        match self.next() {
            Some(Token::Number(v, None)) => Ok(v),
            Some(Token::Number(v, Some(u))) if u == "s" => Ok(v),
            _ => Err("a window is `[FROM, TO]` in seconds (TO may be `inf`)".into()),
        }
    }

    fn window(&mut self) -> Result<Window, String> {
        if !self.eat_sym("[") {
            return Ok(Window {
                from_s: 0.0,
                to_s: None,
            });
        }
        let from_s = self.time()?;
        self.expect_sym(",")?;
        let to_s = if self.eat_word("inf") {
            None
        } else {
            Some(self.time()?)
        };
        self.expect_sym("]")?;
        if !(from_s >= 0.0 && to_s.is_none_or(|t| t >= from_s)) {
            return Err(format!(
                "window [{from_s}, {}]: the times must satisfy 0 ≤ FROM ≤ TO",
                to_s.map_or("inf".into(), |t| t.to_string())
            ));
        }
        Ok(Window { from_s, to_s })
    }

    fn predicate(&mut self) -> Result<Formula, String> {
        let (expr, unit) = self.expr()?;
        let cmp = match self.next() {
            Some(Token::Sym("<")) => Cmp::Less,
            Some(Token::Sym("<=")) => Cmp::LessEq,
            Some(Token::Sym(">")) => Cmp::Greater,
            Some(Token::Sym(">=")) => Cmp::GreaterEq,
            _ => {
                self.at -= 1;
                return Err(format!(
                    "a comparison (<, <=, >, >=) expected {}",
                    self.here()
                ));
            }
        };
        let negative = self.eat_sym("-");
        let Some(Token::Number(v, suffix)) = self.next() else {
            self.at -= 1;
            return Err(format!("a number expected {}", self.here()));
        };
        let factor = match suffix {
            None => 1.0,
            Some(s) => {
                let allowed: Vec<&str> = UNITS
                    .iter()
                    .filter(|(_, si, _)| *si == unit)
                    .map(|(u, _, _)| *u)
                    .collect();
                match UNITS.iter().find(|(u, si, _)| *u == s && *si == unit) {
                    Some((_, _, f)) => *f,
                    None => {
                        return Err(format!(
                            "`{s}` is not a unit of a signal in `{unit}`; allowed: {}",
                            if allowed.is_empty() {
                                "no unit".into()
                            } else {
                                allowed.join(", ")
                            }
                        ))
                    }
                }
            }
        };
        let bound = if negative { -v } else { v } * factor;
        Ok(Formula::Pred { expr, cmp, bound })
    }

    fn expr(&mut self) -> Result<(Expr, &'static str), String> {
        let mut terms = Vec::new();
        let mut unit: Option<&'static str> = None;
        let mut sign = if self.eat_sym("-") { -1.0 } else { 1.0 };
        loop {
            let (t, u) = self.term()?;
            if let Some(first) = unit.filter(|f| *f != u) {
                return Err(format!(
                    "a sum of signals in `{first}` and in `{u}`: the signals of a sum share one unit"
                ));
            }
            unit = Some(u);
            terms.push((sign, t));
            sign = if self.eat_sym("+") {
                1.0
            } else if self.eat_sym("-") {
                -1.0
            } else {
                break;
            };
        }
        let unit = unit.unwrap_or("");
        if terms.len() == 1 && terms[0].0 == 1.0 {
            return Ok((
                terms.pop().map(|(_, t)| t).unwrap_or(Expr::Sum(vec![])),
                unit,
            ));
        }
        Ok((Expr::Sum(terms), unit))
    }

    fn term(&mut self) -> Result<(Expr, &'static str), String> {
        if self.eat_sym("|") {
            let (e, u) = self.expr()?;
            self.expect_sym("|")?;
            return Ok((Expr::Abs(Box::new(e)), u));
        }
        match self.next() {
            Some(Token::Word(w)) => match Signal::named(&w) {
                Some(s) => Ok((Expr::Signal(s), s.unit())),
                None if Event::named(&w).is_some() => Err(format!(
                    "`{w}` is true or false, not a number: use it as a formula (`{w} -> …`)"
                )),
                None => Err(format!(
                    "`{w}` is not a signal; allowed: the columns of timeseries.csv \
                     (docs/outputs.md), `tilt_error`, and the events {}",
                    EVENTS.map(|(n, _)| n).join(", ")
                )),
            },
            _ => {
                self.at -= 1;
                Err(format!("a signal expected {}", self.here()))
            }
        }
    }
}

/// The formula `text` says.
pub fn parse(text: &str) -> Result<Formula, String> {
    let mut p = Parser {
        tokens: lex(text)?,
        at: 0,
    };
    let f = p.implication()?;
    if p.at < p.tokens.len() {
        return Err(format!("unexpected {}", p.here().replace("before ", "")));
    }
    Ok(f)
}
