//! `tiltsim compare`: Table 4 of the paper from several runs, with the paper's published
//! values alongside where it gives them.

use std::fmt::Write as _;

use controller_proc::Mode;

use crate::comfort::Comfort;
use crate::engine::Summary;
use crate::scenario::Scenario;

/// The paper's Table 4 columns for its own controllers (ρ = 0.30, no preview), in row order.
fn paper_column(s: &Scenario) -> Option<[f64; 7]> {
    let c = &s.controller;
    if (c.rho - 0.30).abs() > 1e-9 {
        return None;
    }
    match c.mode {
        Mode::Pi => Some([0.133, 8.491, 0.033, 0.118, 4.373, 35.975, 8.397]),
        Mode::Lqg => Some([0.832, 9.796, 0.008, 0.100, 4.893, 36.412, 9.448]),
        Mode::Mpc if !c.mpc.preview && !c.kalman.track_input => {
            Some([0.142, 8.287, 0.002, 0.09, 5.096, 23.944, 6.289])
        }
        _ => None,
    }
}

/// Row labels (unit in parentheses), in the order of [`values`].
pub const ROWS: [&str; 10] = [
    "Lateral acceleration RMS deviation (%g)",
    "Lateral acceleration peak (%g)",
    "Roll speed RMS deviation (rad/s)",
    "Roll speed peak (rad/s)",
    "Peak jerk level (%g/s)",
    "P_CT standing, paper-peak (%)",
    "P_CT seated, paper-peak (%)",
    "P_CT standing, EN 12299 per transition (%)",
    "P_CT seated, EN 12299 per transition (%)",
    "Secondary lateral deflection peak (mm, bump stop 60)",
];

/// A run's values in [`ROWS`] order.
pub fn values(c: &Comfort) -> [f64; 10] {
    [
        c.lat_acc_rms_dev_pct_g,
        c.lat_acc_peak_pct_g,
        c.roll_speed_rms_dev_rad_s,
        c.roll_speed_peak_rad_s,
        c.jerk_peak_pct_g_s,
        c.p_ct.standing,
        c.p_ct.seated,
        c.p_ct_en12299.standing,
        c.p_ct_en12299.seated,
        c.deflection_peak_mm,
    ]
}

/// One compared run.
pub struct Entry {
    /// Column label.
    pub label: String,
    /// The scenario as run.
    pub scenario: Scenario,
    /// Its summary.
    pub summary: Summary,
}

fn label(s: &Scenario) -> String {
    let mode = match s.controller.mode {
        Mode::Passive => "passive".to_string(),
        Mode::Pi => "PI".to_string(),
        Mode::Lqg => "LQG".to_string(),
        Mode::Mpc if s.controller.mpc.preview => "MPC-KF preview (ours)".to_string(),
        Mode::Mpc => "MPC-KF".to_string(),
    };
    format!("{mode} [{}]", s.name)
}

/// Builds an entry.
pub fn entry(scenario: Scenario, summary: Summary) -> Entry {
    Entry {
        label: label(&scenario),
        scenario,
        summary,
    }
}

pub(crate) fn fmt(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.1}")
    } else if v.abs() >= 1.0 {
        format!("{v:.3}")
    } else {
        format!("{v:.4}")
    }
}

/// `table.md` and `table.csv`.
pub fn tables(entries: &[Entry]) -> (String, String) {
    let mut md = String::new();
    let mut csv = String::from("metric,column,scenario,value,paper,difference\n");
    let _ = writeln!(
        md,
        "# Comfort assessment (the paper's Table 4 layout)\n\nOurs, with the paper's value in \
         brackets and our difference where the paper gives one. P_CT headline: whole-run peaks \
         as the paper evaluates them; the EN 12299 rows use per-transition windows on 0.3 Hz \
         filtered signals (docs/results.md).\n"
    );
    let _ = write!(md, "| metric |");
    for e in entries {
        let _ = write!(md, " {} |", e.label);
    }
    let _ = write!(md, "\n|---|");
    for _ in entries {
        let _ = write!(md, "---|");
    }
    md.push('\n');
    for (r, name) in ROWS.iter().enumerate() {
        let _ = write!(md, "| {name} |");
        for e in entries {
            let v = values(&e.summary.comfort)[r];
            let paper = paper_column(&e.scenario).and_then(|p| p.get(r).copied());
            match paper {
                Some(p) => {
                    let _ = write!(md, " {} [{}] ({:+}) |", fmt(v), fmt(p), fmt(v - p));
                    let _ = writeln!(
                        csv,
                        "\"{name}\",\"{}\",{},{v},{p},{}",
                        e.label,
                        e.scenario.name,
                        v - p
                    );
                }
                None => {
                    let _ = write!(md, " {} |", fmt(v));
                    let _ = writeln!(csv, "\"{name}\",\"{}\",{},{v},,", e.label, e.scenario.name);
                }
            }
        }
        md.push('\n');
    }
    let _ = writeln!(md, "\n| run | status | steps | wall (s) | actuator | controller compute p99 (µs) |\n|---|---|---|---|---|---|");
    for e in entries {
        let s = &e.summary;
        let _ = writeln!(
            md,
            "| {} | {:?} | {} | {:.2} | {:?} | {:.1} |",
            e.scenario.name,
            s.status,
            s.steps_completed,
            s.wall_time_s,
            e.scenario.actuator.model,
            s.participants
                .get(2)
                .map(|p| p.compute_us.p99)
                .unwrap_or(0.0)
        );
    }
    (md, csv)
}
