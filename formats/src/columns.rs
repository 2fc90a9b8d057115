//! `columns.csv`: what each column of a directory's tables holds and its unit, one line per
//! column (`file,column,unit,description`), so that a reader gets units by machine without
//! putting them into the column names (`pd.read_csv("columns.csv")`). Units are ASCII
//! symbols: `m/s2`, `rad/s`, `N.m`, `%`, `%g` (percent of g), `1` for a pure number, empty
//! for a name, a code or a set of bits.

use std::path::Path;

use crate::events::EVENT_COLUMNS;
use crate::table::{COLUMNS, DESCRIPTIONS, UNITS};

/// One column of one table.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    /// The table's file name (`timeseries.csv`).
    pub file: String,
    /// The column's name.
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// What it holds.
    pub description: String,
}

impl Column {
    /// A column of `file`.
    pub fn new(file: &str, name: &str, unit: &str, description: &str) -> Self {
        Column {
            file: file.into(),
            name: name.into(),
            unit: unit.into(),
            description: description.trim().into(),
        }
    }
}

/// The columns of `timeseries.csv`.
pub fn timeseries() -> Vec<Column> {
    COLUMNS
        .iter()
        .zip(UNITS)
        .zip(DESCRIPTIONS)
        .map(|((n, u), d)| Column::new("timeseries.csv", n, u, without_unit(d)))
        .collect()
}

/// A field's description without its closing `(unit).`, which `columns.csv` gives apart.
fn without_unit(doc: &str) -> &str {
    let d = doc.trim().trim_end_matches('.');
    match d.rfind(" (") {
        Some(i) if d.ends_with(')') => &d[..i],
        _ => d,
    }
}

/// The columns of `events.csv`.
pub fn events() -> Vec<Column> {
    let what: [(&str, &str); 6] = [
        ("s", "Simulated time at which the tick starts"),
        ("1", "Tick"),
        ("", "The link or participant"),
        (
            "",
            "What happened (a name of the event kinds in docs/outputs.md)",
        ),
        (
            "",
            "A number that goes with the event; its unit depends on the event (detail)",
        ),
        ("", "Words"),
    ];
    EVENT_COLUMNS
        .iter()
        .zip(what)
        .map(|(n, (u, d))| Column::new("events.csv", n, u, d))
        .collect()
}

/// The text of `columns.csv` for `columns`.
pub fn csv_text(columns: &[Column]) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    let _ = w.write_record(["file", "column", "unit", "description"]);
    for c in columns {
        let _ = w.write_record([&c.file, &c.name, &c.unit, &c.description]);
    }
    w.into_inner()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .unwrap_or_default()
}

/// Writes `dir/columns.csv` for `columns`, whole or not at all.
pub fn write(dir: &Path, columns: &[Column]) -> std::io::Result<()> {
    tiltsim_rundir::files::write_atomic(&dir.join("columns.csv"), csv_text(columns))
}

/// Writes `dir/columns.csv` for a run's tables (`timeseries.csv` and `events.csv`).
pub fn write_run(dir: &Path) -> std::io::Result<()> {
    let mut all = timeseries();
    all.extend(events());
    write(dir, &all)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_column_of_the_run_tables_has_one_line_and_units_are_those_of_the_quantities() {
        let ts = timeseries();
        assert_eq!(ts.len(), COLUMNS.len());
        let unit = |n: &str| ts.iter().find(|c| c.name == n).unwrap().unit.as_str();
        assert_eq!(unit("time"), "s");
        assert_eq!(unit("lat_acc"), "m/s2");
        assert_eq!(unit("theta_v"), "rad");
        assert_eq!(unit("motor_torque"), "N.m");
        assert_eq!(unit("v_dc"), "V");
        // Every description is words, not an empty doc, and the unit is not repeated there.
        assert!(ts.iter().all(|c| c.description.len() > 2), "{ts:?}");
        let d = |n: &str| {
            ts.iter()
                .find(|c| c.name == n)
                .unwrap()
                .description
                .as_str()
        };
        assert_eq!(d("curvature"), "Curvature 1/R");
        assert_eq!(d("lat_acc"), "Passenger lateral acceleration, eq 13");
        let ev = events();
        assert_eq!(
            ev.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(),
            EVENT_COLUMNS
        );
    }
}
