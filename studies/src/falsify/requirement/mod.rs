//! Requirements as engineers write them, each with a margin (positive: met with room to
//! spare) and a verdict:
//!
//! * on a comfort metric of the run: `p_ct < 28`, `n_mv <= 2.5` (margin in the metric's unit);
//! * on validity: `valid` (the comfort numbers mean what they say: no oscillation, P_CT in the
//!   formula's range), `no flags`, or one flag, `no oscillation`, `no bump_stop`,
//!   `no drive_limit`, `no chopper`, `no thermal`, `no p_ct_range`. A flag is a decision, not
//!   a measure: its margin is +1 when it holds and −1 when it does not (the measured values
//!   are in the run's `summary.json` → `flags`);
//! * on signals over time, in a small signal temporal logic ([`stl`]) whose robustness is the
//!   margin ([`robustness`]): `always |lat_acc| < 1.2`,
//!   `always (transition_end -> always[0,3] |tilt_error| < 0.5deg)`.

pub mod robustness;
pub mod signals;
pub mod stl;
#[cfg(test)]
mod tests;

use tiltsim_assessment::comfort::{Comfort, METRICS};

use super::objective::{metric_index, Cmp};
use super::FalsifyError;
use signals::Trace;
use stl::Formula;

/// The validity requirements: the name written after `no`, and the flag's name in
/// `summary.json` → `flags` (`Flags::raised`).
pub const FLAGS: [(&str, &str); 6] = [
    ("oscillation", "oscillation"),
    ("bump_stop", "bump stop"),
    ("drive_limit", "drive limit"),
    ("chopper", "chopper"),
    ("thermal", "thermal"),
    ("p_ct_range", "P_CT > 100 %"),
];

/// What a validity requirement asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Validity {
    /// `valid`: the comfort numbers are valid (`summary.json` `comfort_valid`).
    Valid,
    /// `no flags`: no flag raised.
    NoFlags,
    /// `no NAME`: this flag (index in [`FLAGS`]) not raised.
    No(usize),
}

/// One requirement.
#[derive(Debug, Clone, PartialEq)]
pub enum Requirement {
    /// `METRIC OP VALUE`.
    Metric {
        /// Index in [`METRICS`].
        metric: usize,
        /// The comparison.
        cmp: Cmp,
        /// The bound.
        bound: f64,
    },
    /// On validity.
    Validity(Validity),
    /// On signals over time.
    Signal {
        /// As written, blanks collapsed.
        text: String,
        /// As parsed.
        formula: Formula,
    },
}

/// What a run gives a requirement to judge.
pub struct Judged<'a> {
    /// Its comfort numbers.
    pub comfort: &'a Comfort,
    /// `summary.json` `comfort_valid`.
    pub comfort_valid: bool,
    /// The flags raised (`Flags::raised`).
    pub raised: &'a [&'a str],
    /// Its signals.
    pub trace: &'a Trace<'a>,
}

/// A requirement's judgement of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Check {
    /// Margin (positive: met with room to spare; NaN: not a number to judge).
    pub margin: f64,
    /// Whether it holds.
    pub holds: bool,
}

/// How the requirements may be written, for messages.
pub const ALLOWED: &str = "`METRIC OP VALUE` (e.g. `p_ct < 35`), `valid`, `no flags`, \
`no FLAG` (oscillation, bump_stop, drive_limit, chopper, thermal, p_ct_range), or a \
temporal formula (e.g. `always |lat_acc| < 1.2`, \
`always (transition_end -> always[0,3] |tilt_error| < 0.5deg)`; docs/studies.md)";

fn metric_requirement(text: &str) -> Result<Requirement, String> {
    let (at, op) = ["<=", ">=", "<", ">"]
        .iter()
        .find_map(|op| text.find(op).map(|i| (i, *op)))
        .ok_or("no comparison")?;
    let name = text[..at].trim();
    let value = text[at + op.len()..].trim();
    let metric = metric_index(name, "--requirement").map_err(|e| {
        if signals::Signal::named(name).is_some() {
            format!("`{name}` is a signal: say when, e.g. `always {text}`")
        } else {
            e.to_string()
                .trim_start_matches("--requirement: ")
                .to_string()
        }
    })?;
    let bound: f64 = value
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(|| format!("`{value}` is not a finite number"))?;
    let cmp = match op {
        "<" => Cmp::Less,
        "<=" => Cmp::LessEq,
        ">" => Cmp::Greater,
        _ => Cmp::GreaterEq,
    };
    Ok(Requirement::Metric { metric, cmp, bound })
}

/// Words that make a text a temporal formula.
const TEMPORAL: [&str; 6] = ["always", "eventually", "not", "and", "or", "->"];

impl Requirement {
    /// The requirement `text` says; the error names it and what is allowed.
    pub fn parse(text: &str) -> Result<Requirement, FalsifyError> {
        let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
        let bad = |what: String| {
            FalsifyError::Invalid(format!(
                "--requirement `{text}`: {what}; allowed: {ALLOWED}"
            ))
        };
        if text == "valid" {
            return Ok(Requirement::Validity(Validity::Valid));
        }
        if let Some(flag) = text.strip_prefix("no ") {
            if flag == "flags" {
                return Ok(Requirement::Validity(Validity::NoFlags));
            }
            return FLAGS
                .iter()
                .position(|(n, _)| *n == flag)
                .map(|i| Requirement::Validity(Validity::No(i)))
                .ok_or_else(|| bad(format!("`{flag}` is not a flag")));
        }
        let words: Vec<&str> = text
            .split(|c: char| c.is_whitespace() || "()[]|".contains(c))
            .collect();
        if words.iter().any(|w| TEMPORAL.contains(w)) || text.starts_with('(') {
            let formula = stl::parse(&text).map_err(bad)?;
            return Ok(Requirement::Signal { text, formula });
        }
        metric_requirement(&text).map_err(bad)
    }

    /// How it reads (parsed again, it gives the same requirement).
    pub fn describe(&self) -> String {
        match self {
            Requirement::Metric { metric, cmp, bound } => {
                format!("{} {} {bound}", METRICS[*metric].key, cmp.symbol())
            }
            Requirement::Validity(Validity::Valid) => "valid".into(),
            Requirement::Validity(Validity::NoFlags) => "no flags".into(),
            Requirement::Validity(Validity::No(i)) => format!("no {}", FLAGS[*i].0),
            Requirement::Signal { text, .. } => text.clone(),
        }
    }

    /// The scale of its margin beside other requirements: the bound's magnitude (1 when 0,
    /// and for validity).
    pub fn scale(&self) -> f64 {
        match self {
            Requirement::Metric { bound, .. } if *bound != 0.0 => bound.abs(),
            Requirement::Metric { .. } | Requirement::Validity(_) => 1.0,
            Requirement::Signal { formula, .. } => formula.scale(),
        }
    }

    /// Whether it judges signals (so the run's rows are needed).
    pub fn on_signals(&self) -> bool {
        matches!(self, Requirement::Signal { .. })
    }

    /// Its judgement of run `r`.
    pub fn check(&self, r: &Judged) -> Check {
        let flag = |holds: bool| Check {
            margin: if holds { 1.0 } else { -1.0 },
            holds,
        };
        match self {
            Requirement::Metric { metric, cmp, bound } => {
                let v = (METRICS[*metric].get)(r.comfort);
                let margin = match cmp {
                    Cmp::Less | Cmp::LessEq => bound - v,
                    Cmp::Greater | Cmp::GreaterEq => v - bound,
                };
                let holds = match cmp {
                    Cmp::Less | Cmp::Greater => margin > 0.0,
                    Cmp::LessEq | Cmp::GreaterEq => margin >= 0.0,
                };
                Check { margin, holds }
            }
            Requirement::Validity(Validity::Valid) => flag(r.comfort_valid),
            Requirement::Validity(Validity::NoFlags) => flag(r.raised.is_empty()),
            Requirement::Validity(Validity::No(i)) => flag(!r.raised.contains(&FLAGS[*i].1)),
            Requirement::Signal { formula, .. } => match robustness::at_start(formula, r.trace) {
                Some((margin, holds)) => Check { margin, holds },
                None => Check {
                    margin: f64::NAN,
                    holds: false,
                },
            },
        }
    }
}
