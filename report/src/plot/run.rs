//! The standard figures of a run, drawn from its recorded rows.

use std::path::{Path, PathBuf};

use super::cite::Quantity;
use super::{write_chart, write_panels, Chart, Line};

/// What the shaded bands of a run's charts mean.
pub const SECTION_NOTE: &str = "shaded: transitions (light), steady curve (dark)";

/// One line of a run's chart: its label, the value it takes from a row, colour and dash.
type RowLine = (
    &'static str,
    Box<dyn Fn(&tiltsim_formats::table::Row) -> f64>,
    &'static str,
    bool,
);

/// One chart of a run: file name, title, y label, the quantity it shows and its lines.
type RunChart = (
    &'static str,
    &'static str,
    &'static str,
    Quantity,
    Vec<RowLine>,
);

/// The legend of the controller's estimate of the body roll.
const ESTIMATE: &str = "θ̂_{v} estimate";

/// The run's charts (angles in degrees).
fn run_charts(u_max: f64) -> Vec<RunChart> {
    let d = 1f64.to_degrees();
    vec![
        (
            "lateral_acceleration",
            "passenger lateral acceleration (eq 13)",
            "lateral acceleration (m/s²)",
            Quantity::LateralAcceleration,
            vec![(
                "lateral acceleration ÿ",
                Box::new(|r| r.lat_acc),
                "#1f77b4",
                false,
            )],
        ),
        (
            "body_roll",
            "carbody roll relative to the track",
            "roll (deg)",
            Quantity::Roll,
            vec![
                (
                    "θ_{v} measured",
                    Box::new(move |r| r.theta_v_meas * d),
                    "#bbbbbb",
                    false,
                ),
                ("θ_{v}", Box::new(move |r| r.theta_v * d), "#1f77b4", false),
                (
                    ESTIMATE,
                    Box::new(move |r| r.theta_v_hat * d),
                    "#2ca02c",
                    false,
                ),
                (
                    "θ_{v}^{d} reference (eq 18)",
                    Box::new(move |r| r.theta_ref * d),
                    "#d62728",
                    true,
                ),
            ],
        ),
        (
            "control",
            "anti-roll bar, command and achieved angle with limits",
            "bar angle δ_{a} (deg)",
            Quantity::BarAngle,
            vec![
                (
                    "δ_{a,cmd} command",
                    Box::new(move |r| r.delta_a_cmd * d),
                    "#ff7f0e",
                    false,
                ),
                (
                    "δ_{a} achieved",
                    Box::new(move |r| r.delta_a * d),
                    "#1f77b4",
                    false,
                ),
                ("+u_{max}", Box::new(move |_| u_max), "#d62728", true),
                ("−u_{max}", Box::new(move |_| -u_max), "#d62728", true),
            ],
        ),
        (
            "motor",
            "BLDC motor, electromagnetic torque",
            "torque (N·m)",
            Quantity::MotorTorque,
            vec![(
                "torque T_{e}",
                Box::new(|r| r.motor_torque),
                "#9467bd",
                false,
            )],
        ),
        (
            "motor",
            "BLDC motor, current",
            "current (A)",
            Quantity::MotorCurrent,
            vec![(
                "current T_{e}/k_{t}",
                Box::new(|r| r.motor_current),
                "#8c564b",
                false,
            )],
        ),
    ]
}

/// One panel of a figure: its title, y label, caption and lines.
type Panel = (String, &'static str, String, Vec<RowLine>);

/// What a run's figures are titled with: its scenario and its controller.
pub struct RunTitle<'a> {
    /// Scenario name.
    pub scenario: &'a str,
    /// Controller, as the comparison table names it ("MPC-KF", "passive", ...).
    pub controller: &'a str,
    /// Whether the run commands the bar (false for the passive vehicle: its bar and motor
    /// figures would be empty and are not drawn).
    pub tilts: bool,
    /// Whether the controller estimates the body roll (the LQG's and the MPC's Kalman
    /// filters). Without an estimator the recorded estimate is the measurement as received,
    /// which would be drawn over the measured trace as a signal the run does not have.
    pub estimates: bool,
    /// The paper's figure of the same quantity for this run, if any ([`super::cite`]).
    pub cite: &'a dyn Fn(Quantity) -> Option<&'static str>,
}

/// The figures of the bar and its drive.
const DRIVE_FIGURES: [&str; 2] = ["control", "motor"];

/// Writes the standard set of plots for a run into `dir/plots/`; returns the files written.
/// Charts that share a file name are the panels of one figure, drawn one above the other.
pub fn write_run_plots(
    dir: &Path,
    rows: &[tiltsim_formats::table::Row],
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
    for (name, title, y_label, quantity, lines) in run_charts(u_max) {
        let title = format!("{} ({}): {title}", who.scenario, who.controller);
        let caption = super::cite::caption(&[(who.scenario, (who.cite)(quantity))]);
        let panel = (title, y_label, caption, lines);
        match figures.last_mut() {
            Some((n, panels)) if *n == name => panels.push(panel),
            _ => figures.push((name, vec![panel])),
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
            .map(|(title, y_label, caption, lines)| Chart {
                title,
                x_label: "time (s)",
                y_label,
                lines: lines
                    .iter()
                    .filter(|(label, ..)| who.estimates || *label != ESTIMATE)
                    .map(|(label, f, colour, dashed)| Line {
                        label,
                        y: rows.iter().map(f).collect(),
                        colour,
                        dashed: *dashed,
                        ..Default::default()
                    })
                    .collect(),
                bands: sections.to_vec(),
                note: SECTION_NOTE,
                caption,
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
