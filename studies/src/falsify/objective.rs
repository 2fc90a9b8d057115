//! What a falsifying search maximises: one summary metric, or the violation of a requirement
//! on one (`p_ct < 35`: its margin, 35 − P_CT, is minimised).

use tiltsim_assessment::comfort::{Comfort, METRICS};

use super::FalsifyError;

/// Short names for the metrics most often asked for.
pub const ALIASES: [(&str, &str); 8] = [
    ("p_ct", "p_ct_en12299_standing_pct"),
    ("p_ct_standing", "p_ct_en12299_standing_pct"),
    ("p_ct_seated", "p_ct_en12299_seated_pct"),
    ("lat_acc_peak", "lat_acc_peak_pct_g"),
    ("tilt_error", "tilt_error_rms_deg"),
    ("n_mv", "n_mv_lateral"),
    ("jerk_peak", "jerk_peak_pct_g_s"),
    ("roll_speed_peak", "roll_speed_peak_rad_s"),
];

/// A comparison of a requirement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cmp {
    /// `<`
    Less,
    /// `<=`
    LessEq,
    /// `>`
    Greater,
    /// `>=`
    GreaterEq,
}

impl Cmp {
    fn symbol(self) -> &'static str {
        match self {
            Cmp::Less => "<",
            Cmp::LessEq => "<=",
            Cmp::Greater => ">",
            Cmp::GreaterEq => ">=",
        }
    }
}

/// The objective of a search.
#[derive(Debug, Clone, PartialEq)]
pub enum Objective {
    /// Maximise the metric at this index of [`METRICS`].
    Maximise(usize),
    /// Minimise the margin of `metric cmp bound`.
    Requirement {
        /// Index in [`METRICS`].
        metric: usize,
        /// The comparison.
        cmp: Cmp,
        /// The bound.
        bound: f64,
    },
}

/// The index in [`METRICS`] of `name` (a key or an alias); the error says what is allowed.
pub fn metric_index(name: &str, flag: &str) -> Result<usize, FalsifyError> {
    let key = ALIASES
        .iter()
        .find(|(a, _)| *a == name)
        .map_or(name, |(_, k)| *k);
    METRICS.iter().position(|m| m.key == key).ok_or_else(|| {
        let keys: Vec<&str> = METRICS.iter().map(|m| m.key).collect();
        let aliases: Vec<&str> = ALIASES.iter().map(|(a, _)| *a).collect();
        FalsifyError::Invalid(format!(
            "{flag}: `{name}` is not a metric; allowed: {} (or {})",
            keys.join(", "),
            aliases.join(", ")
        ))
    })
}

impl Objective {
    /// `--objective NAME`.
    pub fn maximise(name: &str) -> Result<Objective, FalsifyError> {
        Ok(Objective::Maximise(metric_index(
            name.trim(),
            "--objective",
        )?))
    }

    /// `--requirement "NAME OP VALUE"`, OP one of `<`, `<=`, `>`, `>=`.
    pub fn requirement(text: &str) -> Result<Objective, FalsifyError> {
        let bad = |what: &str| {
            FalsifyError::Invalid(format!(
                "--requirement `{text}`: {what}; allowed: `METRIC OP VALUE` with OP one of <, <=, >, >= (e.g. `p_ct < 35`)"
            ))
        };
        let (at, op) = ["<=", ">=", "<", ">"]
            .iter()
            .find_map(|op| text.find(op).map(|i| (i, *op)))
            .ok_or_else(|| bad("no comparison"))?;
        let name = text[..at].trim();
        let value = text[at + op.len()..].trim();
        let metric = metric_index(name, "--requirement")?;
        let bound: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(&format!("`{value}` is not a finite number")))?;
        let cmp = match op {
            "<" => Cmp::Less,
            "<=" => Cmp::LessEq,
            ">" => Cmp::Greater,
            _ => Cmp::GreaterEq,
        };
        Ok(Objective::Requirement { metric, cmp, bound })
    }

    /// The metric's index in [`METRICS`].
    pub fn metric(&self) -> usize {
        match self {
            Objective::Maximise(m) => *m,
            Objective::Requirement { metric, .. } => *metric,
        }
    }

    /// The metric's key.
    pub fn key(&self) -> &'static str {
        METRICS[self.metric()].key
    }

    /// The value the search maximises for a run's comfort: the metric, or the requirement's
    /// margin negated. NaN when the metric is not a number.
    pub fn value(&self, c: &Comfort) -> f64 {
        let v = (METRICS[self.metric()].get)(c);
        match self {
            Objective::Maximise(_) => v,
            Objective::Requirement { .. } => -self.margin(v),
        }
    }

    /// The value the search maximises for metric value `v` (as [`Objective::value`]).
    pub fn of_metric(&self, v: f64) -> f64 {
        match self {
            Objective::Maximise(_) => v,
            Objective::Requirement { .. } => -self.margin(v),
        }
    }

    /// A requirement's margin for metric value `v` (positive: met with room to spare).
    pub fn margin(&self, v: f64) -> f64 {
        match self {
            Objective::Maximise(_) => f64::NAN,
            Objective::Requirement { cmp, bound, .. } => match cmp {
                Cmp::Less | Cmp::LessEq => bound - v,
                Cmp::Greater | Cmp::GreaterEq => v - bound,
            },
        }
    }

    /// Whether metric value `v` breaks the requirement (never for a metric maximised).
    pub fn violated(&self, v: f64) -> bool {
        match self {
            Objective::Maximise(_) => false,
            Objective::Requirement { cmp, .. } => {
                let m = self.margin(v);
                match cmp {
                    Cmp::Less | Cmp::Greater => m <= 0.0 || m.is_nan(),
                    Cmp::LessEq | Cmp::GreaterEq => m < 0.0 || m.is_nan(),
                }
            }
        }
    }

    /// How it reads: `maximise p_ct_en12299_standing_pct`, `p_ct_en12299_standing_pct < 35`.
    pub fn describe(&self) -> String {
        match self {
            Objective::Maximise(_) => format!("maximise {}", self.key()),
            Objective::Requirement { cmp, bound, .. } => {
                format!("{} {} {bound}", self.key(), cmp.symbol())
            }
        }
    }
}
