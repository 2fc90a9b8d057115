//! The standard figures of a run, drawn from its recorded rows.

use std::path::{Path, PathBuf};

use super::{write_chart, write_panels, Chart, Line};

/// What the shaded bands of a run's charts mean.
pub const SECTION_NOTE: &str = "shaded: transitions (light), steady curve (dark)";

/// One line of a run's chart: its label, the value it takes from a row, colour and dash.
type RowLine = (
    &'static str,
    Box<dyn Fn(&tiltsim_master::table::Row) -> f64>,
    &'static str,
    bool,
);

/// The run's charts: file name, title, y label and lines (angles in degrees).
fn run_charts(u_max: f64) -> Vec<(&'static str, &'static str, &'static str, Vec<RowLine>)> {
    let d = 1f64.to_degrees();
    vec![
        (
            "lateral_acceleration",
            "Passenger lateral acceleration (eq 13; Figs 8b, 14-15)",
            "lateral acceleration (m/s²)",
            vec![("ÿ", Box::new(|r| r.lat_acc), "#1f77b4", false)],
        ),
        (
            "body_roll",
            "Carbody roll relative to the track (Figs 8a, 12-13, 16)",
            "roll (deg)",
            vec![
                (
                    "θ_v measured",
                    Box::new(move |r| r.theta_v_meas * d),
                    "#bbbbbb",
                    false,
                ),
                ("θ_v", Box::new(move |r| r.theta_v * d), "#1f77b4", false),
                (
                    "θ̂_v estimate",
                    Box::new(move |r| r.theta_v_hat * d),
                    "#2ca02c",
                    false,
                ),
                (
                    "θ_v^d reference (eq 18)",
                    Box::new(move |r| r.theta_ref * d),
                    "#d62728",
                    true,
                ),
            ],
        ),
        (
            "control",
            "Anti-roll bar: command and achieved angle with limits (Fig. 17)",
            "bar angle δ_a (deg)",
            vec![
                (
                    "δ_a command",
                    Box::new(move |r| r.delta_a_cmd * d),
                    "#ff7f0e",
                    false,
                ),
                (
                    "δ_a achieved",
                    Box::new(move |r| r.delta_a * d),
                    "#1f77b4",
                    false,
                ),
                ("+u_max", Box::new(move |_| u_max), "#d62728", true),
                ("−u_max", Box::new(move |_| -u_max), "#d62728", true),
            ],
        ),
        (
            "motor",
            "BLDC motor: electromagnetic torque (Fig. 18, upper panel)",
            "torque (N·m)",
            vec![("torque T_e", Box::new(|r| r.motor_torque), "#9467bd", false)],
        ),
        (
            "motor",
            "BLDC motor: current (Fig. 18, lower panel)",
            "current (A)",
            vec![(
                "current T_e/k_t",
                Box::new(|r| r.motor_current),
                "#8c564b",
                false,
            )],
        ),
    ]
}

/// One panel of a figure: its title, y label and lines.
type Panel = (String, &'static str, Vec<RowLine>);

/// What a run's figures are titled with: its scenario and its controller.
pub struct RunTitle<'a> {
    /// Scenario name.
    pub scenario: &'a str,
    /// Controller, as the comparison table names it ("MPC-KF", "passive", ...).
    pub controller: &'a str,
    /// Whether the run commands the bar (false for the passive vehicle: its bar and motor
    /// figures would be empty and are not drawn).
    pub tilts: bool,
}

/// The figures of the bar and its drive.
const DRIVE_FIGURES: [&str; 2] = ["control", "motor"];

/// Writes the standard set of plots for a run into `dir/plots/`; returns the files written.
/// Charts that share a file name are the panels of one figure, drawn one above the other.
pub fn write_run_plots(
    dir: &Path,
    rows: &[tiltsim_master::table::Row],
    sections: &[(f64, f64, bool)],
    u_max: f64,
    who: &RunTitle,
) -> std::io::Result<Vec<PathBuf>> {
    let t: Vec<f64> = rows.iter().map(|r| r.time).collect();
    let out = dir.join("plots");
    std::fs::create_dir_all(&out)
        .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", out.display())))?;
    let mut files = Vec::new();
    let mut figures: Vec<(&str, Vec<Panel>)> = Vec::new();
    for (name, title, y_label, lines) in run_charts(u_max) {
        let title = format!("{} ({}): {title}", who.scenario, who.controller);
        match figures.last_mut() {
            Some((n, panels)) if *n == name => panels.push((title, y_label, lines)),
            _ => figures.push((name, vec![(title, y_label, lines)])),
        }
    }
    for (name, panels) in figures {
        // A passive run's drive figures are not drawn; a stale one of an earlier run in the
        // directory is removed.
        if !who.tilts && DRIVE_FIGURES.contains(&name) {
            for ext in ["svg", "png"] {
                let _ = std::fs::remove_file(out.join(format!("{name}.{ext}")));
            }
            continue;
        }
        let charts: Vec<Chart> = panels
            .iter()
            .map(|(title, y_label, lines)| Chart {
                title,
                x_label: "time (s)",
                y_label,
                lines: lines
                    .iter()
                    .map(|(label, f, colour, dashed)| Line {
                        label,
                        y: rows.iter().map(f).collect(),
                        colour,
                        dashed: *dashed,
                    })
                    .collect(),
                bands: sections.to_vec(),
                note: SECTION_NOTE,
            })
            .collect();
        if charts.len() == 1 {
            files.extend(write_chart(&out, name, &charts[0], &t)?);
        } else {
            files.extend(write_panels(&out, name, &charts, &t)?);
        }
    }
    Ok(files)
}
