//! `table.csv` of a compare, tidy: one line per metric and run (or ideal-tilt reference), its
//! `value` a number in shortest round-trip form (empty where there is none), never text, and
//! `columns.csv` beside it with the unit and meaning of every column and every metric. The
//! display text (rounded cells, brackets, ⚠ and the reasons in words) is `table.md`'s alone.

use serde::Serialize;
use tiltsim_formats::columns::Column;
use tiltsim_formats::table::fmt_f64;

/// The file this module writes and the one described beside it.
const FILE: &str = "table.csv";

/// One line of `table.csv`.
#[derive(Serialize)]
struct Line<'a> {
    metric: &'a str,
    position: &'a str,
    run: &'a str,
    controller: &'a str,
    ideal: &'a str,
    unit: &'a str,
    value: String,
    paper: String,
    difference: String,
    flags: String,
}

/// A metric of the table: its key (the `metric` column), unit and meaning.
#[derive(Clone, Copy)]
pub(crate) struct Key<'a> {
    pub metric: &'a str,
    pub unit: &'a str,
    pub about: &'a str,
}

/// Whose value a line holds: a run or an ideal-tilt reference.
#[derive(Clone, Copy)]
pub(crate) struct Who<'a> {
    /// The run's directory (its scenario's name made distinct), or the reference's name.
    pub run: &'a str,
    /// The controller as the paper names it, or `ideal tilt`.
    pub controller: &'a str,
    /// The `run` of the ideal-tilt reference on the same track at the same ρ.
    pub ideal: &'a str,
}

/// The name of the `i`-th ideal-tilt reference (0-based): `ideal-tilt`, `ideal-tilt-2`, ...
pub(crate) fn ideal_name(i: usize) -> String {
    if i == 0 {
        "ideal-tilt".to_string()
    } else {
        format!("ideal-tilt-{}", i + 1)
    }
}

/// A number, or empty.
fn num(v: Option<f64>) -> String {
    v.map(fmt_f64).unwrap_or_default()
}

/// `table.csv` and the metrics it holds, as they are added.
pub(crate) struct Tidy {
    out: csv::Writer<Vec<u8>>,
    metrics: Vec<Column>,
}

impl Tidy {
    pub(crate) fn new() -> Self {
        Tidy {
            out: csv::Writer::from_writer(Vec::new()),
            metrics: Vec::new(),
        }
    }

    /// One value of metric `k` (at passenger position `position`, or `""`), for `who`, with
    /// the paper's value and the validity flag codes that concern it.
    pub(crate) fn put(
        &mut self,
        k: Key,
        position: &str,
        who: Who,
        value: f64,
        paper: Option<f64>,
        flags: &[&str],
    ) {
        if !self.metrics.iter().any(|c| c.name == k.metric) {
            let about = k.about;
            self.metrics
                .push(Column::new(FILE, k.metric, k.unit, about));
        }
        let line = Line {
            metric: k.metric,
            position,
            run: who.run,
            controller: who.controller,
            ideal: who.ideal,
            unit: k.unit,
            value: num(Some(value)),
            paper: num(paper),
            difference: num(paper.map(|p| value - p)),
            flags: flags.join(";"),
        };
        // Writing into memory cannot fail.
        let _ = self.out.serialize(line);
    }

    /// The text of `table.csv` and of its `columns.csv`.
    pub(crate) fn finish(self) -> (String, String) {
        let table = self
            .out
            .into_inner()
            .map(|b| String::from_utf8_lossy(&b).into_owned())
            .unwrap_or_default();
        let mut all = columns();
        all.extend(self.metrics);
        (table, tiltsim_formats::columns::csv_text(&all))
    }
}

/// The columns of `table.csv`; the metrics follow them in `columns.csv`, each as the column
/// it becomes when the table is pivoted wide (`metric` against `run`).
fn columns() -> Vec<Column> {
    let c = |name: &str, unit: &str, about: &str| Column::new(FILE, name, unit, about);
    vec![
        c("metric", "", "The metric: a key, listed below with its unit and meaning"),
        c(
            "position",
            "",
            "The passenger position ([comfort] positions) of a metric at a position, else empty",
        ),
        c(
            "run",
            "",
            "The run's directory (its scenario's name, made distinct), or an ideal-tilt reference (ideal-tilt, ideal-tilt-2, ...)",
        ),
        c(
            "controller",
            "",
            "passive, PI, LQG, MPC-KF, MPC-KF preview (ours), or ideal tilt",
        ),
        c(
            "ideal",
            "",
            "The ideal-tilt reference of the run: the body following eq 18 exactly on the same track at the same rho",
        ),
        c("unit", "", "The unit of value, paper and difference"),
        c("value", "", "The value in the line's unit, exact (shortest round trip); NaN where the run gave none"),
        c(
            "paper",
            "",
            "The paper's Table 4 value for its own controller, where it gives one, else empty",
        ),
        c("difference", "", "value - paper, where the paper gives a value, else empty"),
        c(
            "flags",
            "",
            "Why value is not a valid ride measure, codes separated by ';': oscillation, p_ct_range (a P_CT above 100 %), not_real_time; on a flag's own rows the flag's code when it is raised",
        ),
    ]
}
