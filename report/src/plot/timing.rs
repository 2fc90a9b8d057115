//! The figures of a free run's timing trace (`timing.csv`): each consumer's input age and each
//! participant's start lateness over simulated time.

use std::path::{Path, PathBuf};

use cosim::Role;
use tiltsim_master::free::trace::{age, col, StepTrace};

use super::{write_chart, Chart, Line};

/// Per tick of the run, the value a role's steps give it (held between the steps of a role
/// slower than the tick).
fn per_tick(
    steps: u64,
    trace: &[StepTrace],
    role: Role,
    value: impl Fn(&StepTrace) -> f64,
) -> Vec<f64> {
    let mut y = vec![f64::NAN; steps as usize];
    for t in trace.iter().filter(|t| t.role == role) {
        if let Some(v) = y.get_mut(t.step as usize) {
            *v = value(t);
        }
    }
    let mut held = f64::NAN;
    for v in &mut y {
        if v.is_nan() {
            *v = held;
        } else {
            held = *v;
        }
    }
    y
}

/// Per tick, how many ticks after the controller's step its new command was first read by
/// the actuator, held over the controller's `period`. The held command's age grows by a tick
/// every tick by design: what timing changes is when each new command takes effect, the
/// first actuator step that read it, less its own step (lock-step Gauss-Seidel: 0).
fn command_effect(steps: u64, trace: &[StepTrace], period: u64) -> Vec<f64> {
    let mut effect = vec![f64::NAN; steps as usize];
    for s in trace.iter().filter(|s| s.role == Role::Actuator) {
        if let Some(c) = s.from[col(Role::Controller)].filter(|&c| c >= 0) {
            let lag = s.step as f64 - c as f64;
            if let Some(v) = effect.get_mut(c as usize) {
                if v.is_nan() || lag < *v {
                    *v = lag;
                }
            }
        }
    }
    let mut held = f64::NAN;
    for (k, v) in effect.iter_mut().enumerate() {
        if (k as u64).is_multiple_of(period.max(1)) {
            held = *v;
        } else {
            *v = held;
        }
    }
    effect
}

/// Writes `dir/plots/timing_input_age.{svg,png}` and `timing_lateness.{svg,png}` from a free
/// run's trace of `steps` ticks of `dt_s` with a controller of `period` ticks; `title` names
/// the run. Every line is 0 where lock-step Gauss-Seidel would have read the same output.
/// Returns the files written.
pub fn write_timing_plots(
    dir: &Path,
    title: &str,
    trace: &[StepTrace],
    steps: u64,
    dt_s: f64,
    period: u64,
) -> std::io::Result<Vec<PathBuf>> {
    let out = dir.join("plots");
    std::fs::create_dir_all(&out)
        .map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", out.display())))?;
    let t: Vec<f64> = (0..steps).map(|k| k as f64 * dt_s).collect();
    let input_age = |consumer: Role, producer: Role| {
        per_tick(steps, trace, consumer, move |s| {
            s.from[col(producer)].map_or(f64::NAN, |f| age(producer, s.step, f) as f64)
        })
    };
    let effect = command_effect(steps, trace, period);
    let age_title = format!("{title}: age of the inputs each step read (free run)");
    let age_chart = Chart {
        title: &age_title,
        x_label: "simulated time (s)",
        y_label: "input age (ticks)",
        lines: vec![
            Line {
                label: "actuator ← controller (new δ_{a,cmd})",
                y: effect,
                colour: "#ff7f0e",
                ..Default::default()
            },
            Line {
                label: "controller ← plant (θ_{v} measured)",
                y: input_age(Role::Controller, Role::Plant),
                colour: "#2ca02c",
                ..Default::default()
            },
            Line {
                label: "actuator ← plant (ψ)",
                y: input_age(Role::Actuator, Role::Plant),
                colour: "#9467bd",
                ..Default::default()
            },
            Line {
                label: "plant ← actuator (δ_{a})",
                y: input_age(Role::Plant, Role::Actuator),
                colour: "#1f77b4",
                ..Default::default()
            },
        ],
        note: "0: as lock-step Gauss-Seidel reads; −1: a newer output; δ_{a,cmd}: ticks until a new one is first read",
        ..Default::default()
    };
    let lateness = |role: Role| {
        per_tick(steps, trace, role, |s| {
            s.read_ns.saturating_sub(s.due_ns) as f64 * 1e-6
        })
    };
    let late_title = format!("{title}: how late each step started (free run)");
    let late_chart = Chart {
        title: &late_title,
        x_label: "simulated time (s)",
        y_label: "start lateness (ms)",
        lines: vec![
            Line {
                label: "plant",
                y: lateness(Role::Plant),
                colour: "#1f77b4",
                ..Default::default()
            },
            Line {
                label: "actuator",
                y: lateness(Role::Actuator),
                colour: "#9467bd",
                ..Default::default()
            },
            Line {
                label: "controller",
                y: lateness(Role::Controller),
                colour: "#2ca02c",
                ..Default::default()
            },
        ],
        note: "lateness: wall-clock time from the instant a step was due to its start",
        ..Default::default()
    };
    let mut files = Vec::new();
    files.extend(write_chart(&out, "timing_input_age", &age_chart, &t)?);
    files.extend(write_chart(&out, "timing_lateness", &late_chart, &t)?);
    Ok(files)
}
