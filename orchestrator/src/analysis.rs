//! Analysis of a run, composed by the caller after the engine has run (or on a finished run's
//! directory): the quick look, ride comfort, validity flags and figures, all read back from
//! `timeseries.csv` as typed rows.

use std::path::{Path, PathBuf};

use cosim::Role;

use crate::engine::{QuickLook, RunError, RunOptions, Summary};
use crate::record::read_rows;
use crate::roles::RoleMap;
use crate::scenario::Scenario;

/// Runs `s` with the engine, then completes its summary with the analysis of what it recorded
/// and, when `opts.plots`, draws its figures.
pub fn run(s: &Scenario, scenario_file: &str, opts: &RunOptions) -> Result<Summary, RunError> {
    let mut summary = crate::engine::run(s, scenario_file, opts)?;
    analyse(s, &opts.out_dir, &mut summary);
    if opts.plots {
        if let Err(e) = write_plots(s, &opts.out_dir) {
            tracing::warn!("plots not written: {e}");
        }
    }
    Ok(summary)
}

/// Fills `results`, `comfort` and `flags` of `summary` from the series recorded in `dir`
/// (works on partial runs too).
pub fn analyse(s: &Scenario, dir: &Path, summary: &mut Summary) {
    summary.results = quick_look(s, dir);
    summary.comfort = comfort_of(s, dir);
    summary.flags = flags_of(s, dir, &summary.comfort);
}

/// The histogram of every participant's request latency, `plots/latency_histogram.{svg,png}`
/// (0.5 µs bins up to the 99.9th percentile of all of them).
pub fn latency_histogram(dir: &Path, requests: &RoleMap<Vec<f64>>) -> std::io::Result<()> {
    let mut all: Vec<f64> = requests
        .iter()
        .flat_map(|(_, r)| r.iter().copied())
        .collect();
    all.sort_by(|a, b| a.total_cmp(b));
    let top = all
        .get(((all.len() as f64) * 0.999) as usize)
        .copied()
        .unwrap_or(1.0)
        .max(1.0);
    let bin = (top / 80.0).max(0.05);
    let nb = (top / bin).ceil() as usize + 1;
    let x: Vec<f64> = (0..nb).map(|i| (i as f64 + 0.5) * bin).collect();
    let lines = Role::ALL
        .iter()
        .enumerate()
        .map(|(k, role)| {
            let mut h = vec![0.0; nb];
            for v in &requests[*role] {
                let i = ((v / bin) as usize).min(nb - 1);
                h[i] += 1.0;
            }
            crate::plot::Line {
                label: role.name(),
                y: h,
                colour: crate::plot::PALETTE[k],
                dashed: false,
            }
        })
        .collect();
    let chart = crate::plot::Chart {
        title: "Request latency: orchestrator sent → participant received",
        x_label: "latency (µs)",
        y_label: "exchanges per bin",
        lines,
        bands: Vec::new(),
        note: "",
    };
    let plots = dir.join("plots");
    std::fs::create_dir_all(&plots)?;
    crate::plot::write_chart(&plots, "latency_histogram", &chart, &x)?;
    Ok(())
}

/// Times (s) at which the vehicle enters the first transition, the steady curve, the second
/// transition and the final straight.
fn section_times(tp: &vehicle_model::TrackParams) -> [f64; 4] {
    let v = tp.speed();
    let t1 = tp.straight_before_m / v;
    let t2 = t1 + tp.transition_m / v;
    let t3 = t2 + tp.curve_m / v;
    [t1, t2, t3, t3 + tp.transition_m / v]
}

/// Reads a run's recorded series (`dir/timeseries.csv`) back into the signals the comfort
/// assessment needs.
pub fn signals_from_run(s: &Scenario, dir: &std::path::Path) -> crate::comfort::Signals {
    use crate::comfort::Signals;
    let Ok(rows) = read_rows(dir) else {
        return Signals::default();
    };
    // The reference of eq 18 at each row's own position, continuous: the recorded θ_ref is
    // the controller's, held over its period (50 ms for the MPC), whose steps would read as
    // roll-speed spikes of the reference.
    let reference: Vec<f64> = match controller_proc::Controller::new(&s.controller_init()) {
        Ok(c) => rows.iter().map(|r| c.reference_at(r.s)).collect(),
        Err(_) => rows.iter().map(|r| r.theta_ref).collect(),
    };
    let veh = vehicle_model::Vehicle::new(s.vehicle.clone(), s.track.speed());
    let n = rows.len();
    let dt = s.run.dt_s;
    // Central difference of a per-row quantity (one-sided at the ends).
    let deriv = |k: usize, f: &dyn Fn(usize) -> f64| {
        if n < 2 {
            return 0.0;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (f(b) - f(a)) / ((b - a) as f64 * dt)
    };
    let (h1, h2) = (s.vehicle.h1, s.vehicle.h2);
    let [t1, t2, t3, t4] = section_times(&s.track);
    Signals {
        t: rows.iter().map(|r| r.t).collect(),
        lat_acc: rows.iter().map(|r| r.lat_acc).collect(),
        lat_acc_ref: rows
            .iter()
            .zip(&reference)
            .map(|(r, th)| veh.lateral_acceleration(*th, r.curvature, r.cant))
            .collect(),
        roll_speed: (0..n)
            .map(|k| rows[k].dtheta_v + deriv(k, &|i| rows[i].cant))
            .collect(),
        roll_speed_ref: (0..n)
            .map(|k| deriv(k, &|i| rows[i].cant + reference[i]))
            .collect(),
        deflection: rows
            .iter()
            .map(|r| r.y_v - h1 * r.theta_v - r.y_b - h2 * r.theta_b)
            .collect(),
        transitions: vec![(t1, t2), (t3, t4)],
    }
}

pub(crate) fn bands(s: &Scenario) -> Vec<(f64, f64, bool)> {
    let [t1, t2, t3, t4] = section_times(&s.track);
    vec![(t1, t2, false), (t2, t3, true), (t3, t4, false)]
}

/// Writes `dir/plots/*.svg` and `*.png` from `dir/timeseries.csv`.
pub fn write_plots(s: &Scenario, dir: &std::path::Path) -> std::io::Result<Vec<PathBuf>> {
    let rows = read_rows(dir)?;
    crate::plot::write_run_plots(dir, &rows, &bands(s), s.controller.u_max_deg)
}

/// Writes the figures that put several runs side by side (`out/plots/compare_*`): lateral
/// acceleration, body roll and bar angle of every run on one time axis. `runs` are (label,
/// scenario, run directory); the shaded sections are the first run's.
pub fn write_compare_plots(
    runs: &[(String, Scenario, PathBuf)],
    out: &std::path::Path,
) -> std::io::Result<Vec<PathBuf>> {
    use crate::plot::{Chart, Line, PALETTE};
    use crate::record::Row;
    let mut data = Vec::new();
    for (label, _, dir) in runs {
        data.push((label.as_str(), read_rows(dir)?));
    }
    let n = data.iter().map(|(_, r)| r.len()).min().unwrap_or(0);
    let t: Vec<f64> = data
        .first()
        .map(|(_, r)| r[..n].iter().map(|x| x.t).collect())
        .unwrap_or_default();
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots)?;
    let bands = runs.first().map(|r| bands(&r.1)).unwrap_or_default();
    let mut files = Vec::new();
    /// (file name, title, y label, column, scale).
    type Figure = (
        &'static str,
        &'static str,
        &'static str,
        fn(&Row) -> f64,
        f64,
    );
    let figures: [Figure; 3] = [
        (
            "compare_lateral_acceleration",
            "Passenger lateral acceleration of each run (Figs 14-15)",
            "lateral acceleration (m/s²)",
            |r| r.lat_acc,
            1.0,
        ),
        (
            "compare_body_roll",
            "Carbody roll of each run (Fig. 16)",
            "roll θ_v (deg)",
            |r| r.theta_v,
            1f64.to_degrees(),
        ),
        (
            "compare_control",
            "Achieved anti-roll-bar angle of each run (Fig. 17)",
            "bar angle δ_a (deg)",
            |r| r.delta_a,
            1f64.to_degrees(),
        ),
    ];
    for (name, title, y_label, column, scale) in figures {
        let chart = Chart {
            title,
            x_label: "time (s)",
            y_label,
            lines: data
                .iter()
                .enumerate()
                .map(|(k, (label, rows))| Line {
                    label,
                    y: rows[..n].iter().map(|r| column(r) * scale).collect(),
                    colour: PALETTE[k % PALETTE.len()],
                    dashed: false,
                })
                .collect(),
            bands: bands.clone(),
            note: crate::plot::SECTION_NOTE,
        };
        files.extend(crate::plot::write_chart(&plots, name, &chart, &t)?);
    }
    Ok(files)
}

/// The validity flags of a finished run, from its recorded series.
pub fn flags_of(
    s: &Scenario,
    dir: &std::path::Path,
    comfort: &crate::comfort::Comfort,
) -> crate::validity::Flags {
    let Ok(rows) = read_rows(dir) else {
        return crate::validity::Flags::default();
    };
    let get = |f: fn(&crate::record::Row) -> f64| -> Vec<f64> { rows.iter().map(f).collect() };
    let inputs = crate::validity::FlagInputs {
        dt: s.run.dt_s,
        roll_error: get(|r| r.theta_v - r.theta_ref),
        reference: get(|r| r.theta_ref),
        deflection: signals_from_run(s, dir).deflection,
        clearance: s.comfort.bump_stop_m,
        limits: rows.iter().map(|r| r.actuator_limits).collect(),
        phase_current_peak: get(|r| r.phase_current_peak),
        torque: get(|r| r.motor_torque),
        dc_power: get(|r| r.dc_power),
        chopper_power: get(|r| r.chopper_power),
        v_dc: get(|r| r.v_dc),
    };
    crate::validity::assess(&inputs, comfort)
}

pub fn comfort_of(s: &Scenario, dir: &std::path::Path) -> crate::comfort::Comfort {
    crate::comfort::assess(&signals_from_run(s, dir), &s.comfort)
}

/// Reads back the recorded series for the headline numbers (works on partial runs too).
pub fn quick_look(s: &Scenario, dir: &std::path::Path) -> QuickLook {
    let Ok(rows) = read_rows(dir) else {
        return QuickLook::default();
    };
    let tp = &s.track;
    let t_mid = (tp.straight_before_m + tp.transition_m + tp.curve_m / 2.0) / tp.speed();
    let mut q = QuickLook::default();
    let mut best = f64::INFINITY;
    for r in &rows {
        q.lat_acc_peak = q.lat_acc_peak.max(r.lat_acc.abs());
        q.delta_a_peak = q.delta_a_peak.max(r.delta_a.abs());
        if (r.t - t_mid).abs() < best {
            best = (r.t - t_mid).abs();
            q.lat_acc_mid_curve = r.lat_acc;
            q.theta_v_mid_curve = r.theta_v;
        }
    }
    q
}
