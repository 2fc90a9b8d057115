//! What a falsifying search maximises: one summary metric, or the violation of requirements
//! (`p_ct < 35`: its margin, 35 − P_CT, is minimised; several at once: the least of their
//! scaled margins).

use tiltsim_assessment::comfort::METRICS;

use super::requirement::{Check, Judged, Requirement};

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
    /// As written.
    pub fn symbol(self) -> &'static str {
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
    /// Minimise the margin of these requirements, all at once (at least one).
    Requirements(Vec<Requirement>),
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

/// What an objective makes of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    /// The objective's metric ([`Objective::metric`]).
    pub metric: f64,
    /// The requirements' margin (NaN when a metric is maximised).
    pub margin: f64,
    /// Whether a requirement is broken (never when a metric is maximised).
    pub violated: bool,
    /// What the search maximises: the metric, or the margin negated.
    pub objective: f64,
    /// Each requirement's judgement, in order.
    pub checks: Vec<Check>,
}

impl Objective {
    /// `--objective NAME`.
    pub fn maximise(name: &str) -> Result<Objective, FalsifyError> {
        Ok(Objective::Maximise(metric_index(
            name.trim(),
            "--objective",
        )?))
    }

    /// One `--requirement` per text; a text may also hold several separated by `;`
    /// (as [`Objective::describe`] writes them).
    pub fn requirements<S: AsRef<str>>(texts: &[S]) -> Result<Objective, FalsifyError> {
        let mut all = Vec::new();
        for text in texts {
            for one in text.as_ref().split(';') {
                all.push(Requirement::parse(one)?);
            }
        }
        if all.is_empty() {
            return Err(FalsifyError::Invalid(format!(
                "--requirement: none given; allowed: {}",
                super::requirement::ALLOWED
            )));
        }
        Ok(Objective::Requirements(all))
    }

    /// `--requirement TEXT` (several separated by `;`).
    pub fn requirement(text: &str) -> Result<Objective, FalsifyError> {
        Objective::requirements(&[text])
    }

    /// The objective's metric's index in [`METRICS`]: the one maximised, or the first metric
    /// a requirement names (P_CT standing when none does), shown beside the margin.
    pub fn metric(&self) -> usize {
        match self {
            Objective::Maximise(m) => *m,
            Objective::Requirements(rs) => rs
                .iter()
                .find_map(|r| match r {
                    Requirement::Metric { metric, .. } => Some(*metric),
                    _ => None,
                })
                .unwrap_or_else(|| {
                    METRICS
                        .iter()
                        .position(|m| m.key == "p_ct_en12299_standing_pct")
                        .unwrap_or(0)
                }),
        }
    }

    /// The metric's key.
    pub fn key(&self) -> &'static str {
        METRICS[self.metric()].key
    }

    /// Whether requirements are judged (rather than a metric maximised).
    pub fn is_requirement(&self) -> bool {
        matches!(self, Objective::Requirements(_))
    }

    /// Whether a requirement speaks of signals (so an evaluation keeps its rows).
    pub fn on_signals(&self) -> bool {
        matches!(self, Objective::Requirements(rs) if rs.iter().any(Requirement::on_signals))
    }

    /// What the objective makes of run `r`. With one requirement the margin is its own; with
    /// several, the least of their margins each divided by its scale
    /// ([`Requirement::scale`]: the magnitude of its bound), so margins in different units
    /// compare as fractions of their bounds. NaN when a margin is.
    pub fn score(&self, r: &Judged) -> Score {
        let metric = (METRICS[self.metric()].get)(r.comfort);
        let Objective::Requirements(rs) = self else {
            return Score {
                metric,
                margin: f64::NAN,
                violated: false,
                objective: metric,
                checks: Vec::new(),
            };
        };
        let checks: Vec<Check> = rs.iter().map(|q| q.check(r)).collect();
        let margin = if let [one] = checks.as_slice() {
            one.margin
        } else {
            rs.iter().zip(&checks).fold(f64::INFINITY, |m, (q, c)| {
                let scaled = c.margin / q.scale();
                if m.is_nan() || scaled.is_nan() {
                    f64::NAN
                } else {
                    m.min(scaled)
                }
            })
        };
        Score {
            metric,
            margin,
            violated: checks.iter().any(|c| !c.holds),
            objective: -margin,
            checks,
        }
    }

    /// How it reads: `maximise p_ct_en12299_standing_pct`, `p_ct_en12299_standing_pct < 35`,
    /// several requirements separated by `; ` (parsed again, it gives the same objective).
    pub fn describe(&self) -> String {
        match self {
            Objective::Maximise(_) => format!("maximise {}", self.key()),
            Objective::Requirements(rs) => rs
                .iter()
                .map(Requirement::describe)
                .collect::<Vec<_>>()
                .join("; "),
        }
    }

    /// Each requirement as it reads (none when a metric is maximised).
    pub fn each(&self) -> Vec<String> {
        match self {
            Objective::Maximise(_) => Vec::new(),
            Objective::Requirements(rs) => rs.iter().map(Requirement::describe).collect(),
        }
    }
}
