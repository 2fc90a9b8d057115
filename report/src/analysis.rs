//! Analysis of a run, composed by the run pipeline after the engine has run
//! (`tiltsim_runner::pipeline`), or on a finished run's directory: the quick look, ride comfort, validity flags and figures, all read back from
//! `timeseries.csv` as typed rows (or from the rows a sweep's sample kept in memory).

use std::path::{Path, PathBuf};

use tiltsim_formats::table::Rows;
use tiltsim_master::engine::{LatencyHistogram, QuickLook};
use tiltsim_scenario::scenario::Scenario;

/// What the analysis of a recorded series finds: the quick look, ride comfort and the
/// validity flags.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Assessment {
    /// Headline numbers.
    pub results: QuickLook,
    /// Ride comfort (Table 4 rows).
    pub comfort: tiltsim_assessment::comfort::Comfort,
    /// Whether the numbers are valid.
    pub flags: tiltsim_assessment::validity::Flags,
}

/// The quick look, ride comfort and flags of the series recorded in `rows` (works on partial
/// runs too), in one pass over them with one row in memory at a time (from a file), so the
/// analysis of an hour-long run needs no more memory than that of a short one. Any run's
/// series is assessed this way: lock-step, free-running or a replay of one.
pub fn assess(s: &Scenario, rows: Rows) -> std::io::Result<Assessment> {
    let mut look = QuickLooker::new(s);
    let mut comfort = tiltsim_assessment::comfort::Assessor::new(
        s.run.dt_s,
        &transitions(s),
        &s.comfort,
        body(s),
    );
    let b = &s.actuator.bldc;
    let rating = tiltsim_assessment::validity::DriveRating {
        continuous_torque_nm: b.continuous_torque_nm,
        k_t: b.k_t,
        k_vr: s.vehicle.k_vr,
        gear_efficiency: b.gear_efficiency,
    };
    let mut flags =
        tiltsim_assessment::validity::Flagger::new(s.run.dt_s, s.vehicle.bump_stop_m, rating);
    scan(s, rows, |r, x| {
        look.push(r);
        comfort.push(x);
        flags.push(&tiltsim_assessment::validity::FlagSample {
            roll_error: r.theta_v - r.theta_ref,
            reference: r.theta_ref,
            deflection: x.deflection,
            bump_force: s.vehicle.bump_stop_force(x.deflection),
            limits: r.actuator_limits,
            phase_current_peak: r.phase_current_peak,
            torque: r.motor_torque,
            dc_power: r.dc_power,
            chopper_power: r.chopper_power,
            v_dc: r.v_dc,
            bar_twist: r.delta_a - r.psi,
            delta_a: r.delta_a,
        });
    })?;
    let comfort = comfort.finish();
    let flags = flags.finish(&comfort);
    Ok(Assessment {
        results: look.q,
        comfort,
        flags,
    })
}

/// The body a run's comfort is assessed on.
pub fn body(s: &Scenario) -> tiltsim_assessment::comfort::Body {
    tiltsim_assessment::comfort::Body {
        bump_stop_m: s.vehicle.bump_stop_m,
        cog_height_m: s.vehicle.h_gv,
    }
}

/// The comfort of the ideal tilt on the track of a recorded run: the body follows eq 18
/// exactly (see [`tiltsim_assessment::comfort::Sample::ideal`]).
pub fn ideal_tilt(s: &Scenario, dir: &Path) -> tiltsim_assessment::comfort::Comfort {
    let mut a = tiltsim_assessment::comfort::Assessor::new(
        s.run.dt_s,
        &transitions(s),
        &s.comfort,
        body(s),
    );
    let _ = scan(s, Rows::File(dir), |_, x| a.push(&x.ideal()));
    a.finish()
}

/// The histogram of every participant's request latency in the run of scenario `name`,
/// `plots/latency_histogram.{svg,png}` (binned by the engine, [`LatencyHistogram`]).
pub fn latency_histogram(dir: &Path, name: &str, h: &LatencyHistogram) -> std::io::Result<()> {
    let lines = h
        .counts
        .iter()
        .enumerate()
        .map(|(k, (role, counts))| crate::plot::Line {
            label: role.name(),
            y: counts.clone(),
            colour: crate::plot::PALETTE[k],
            ..Default::default()
        })
        .collect();
    let title = format!("{name}: request latency, orchestrator sent → participant received");
    let chart = crate::plot::Chart {
        title: &title,
        x_label: "latency (µs)",
        y_label: "exchanges per bin (count)",
        lines,
        ..Default::default()
    };
    let plots = dir.join("plots");
    std::fs::create_dir_all(&plots)?;
    crate::plot::write_chart(&plots, "latency_histogram", &chart, &h.centres_us)?;
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

/// The curve transitions of the scenario's track as (start, end) times (s).
pub fn transitions(s: &Scenario) -> [(f64, f64); 2] {
    let [t1, t2, t3, t4] = section_times(&s.track);
    [(t1, t2), (t3, t4)]
}

/// One recorded row with its quantities derived for comfort, as [`scan`] hands them over.
struct Derived {
    row: tiltsim_formats::table::Row,
    /// θ_v^d at the row's position, continuous (rad).
    reference: f64,
}

/// Reads a run's recorded series (`dir/timeseries.csv`) and hands each row, in order, to
/// `visit` with its comfort sample. The reference of eq 18 is taken at each row's own
/// position, continuous: the recorded θ_ref is the controller's, held over its period (50 ms
/// for the MPC), whose steps would read as roll-speed spikes of the reference. The roll speed
/// is the recorded θ̇_v plus the track model's cant rate at the row's time, on the same side
/// of a ramp corner as the recorded state ([`vehicle_model::Track::cant_rate_at_time`]): a
/// difference of the recorded cant would mix the slopes before and after the corner with a
/// θ̇_v taken after its jump. The reference's roll speed is a central difference of the cant
/// plus θ_v^d (one-sided at the ends), so a row is handed over when the next one has been
/// read: three rows are in memory at most.
pub fn scan(
    s: &Scenario,
    rows: Rows,
    mut visit: impl FnMut(&tiltsim_formats::table::Row, &tiltsim_assessment::comfort::Sample),
) -> std::io::Result<u64> {
    let controller = controller_proc::Controller::new(&s.controller_init()).ok();
    let veh = vehicle_model::Vehicle::new(s.vehicle.clone(), s.track.speed());
    let track = vehicle_model::Track::new(&s.track, s.run.seed);
    let v = s.track.speed();
    let dt = s.run.dt_s;
    let (h1, h2) = (s.vehicle.h1, s.vehicle.h2);
    let p = &s.vehicle;
    let form = s.comfort.lateral_acceleration;
    let sample = |x: &Derived, before: &Derived, after: &Derived, steps: f64| {
        let r = &x.row;
        // Eq 13 as recorded, and with the body's sway acceleration ÿ_v + h_gv·θ̈_o, which eq 9
        // gives as −2 f_s/m_v − v²κ + g·θ_o without the ramp corners' impulses
        // (comfort::LateralAcceleration).
        let ds = r.y_v - h1 * r.theta_v - r.y_b - h2 * r.theta_b;
        let dds = r.dy_v - h1 * r.dtheta_v - r.dy_b - h2 * r.dtheta_b;
        // The secondary spring-damper and, past the free play, the bump stop (D49).
        let f_s = p.k_sy * ds + p.c_sy * dds + p.bump_stop_force(ds);
        let sway = -2.0 * f_s / p.m_v - v * v * r.curvature + vehicle_model::G * r.cant;
        let (eq13, with_sway) = (r.lat_acc, r.lat_acc + sway);
        let (lat_acc, lat_acc_other) = match form {
            tiltsim_assessment::comfort::LateralAcceleration::Eq13 => (eq13, with_sway),
            tiltsim_assessment::comfort::LateralAcceleration::WithSway => (with_sway, eq13),
        };
        let deriv = |f: &dyn Fn(&Derived) -> f64| {
            if steps == 0.0 {
                0.0
            } else {
                (f(after) - f(before)) / (steps * dt)
            }
        };
        tiltsim_assessment::comfort::Sample {
            t: r.time,
            lat_acc,
            lat_acc_ref: veh.lateral_acceleration(x.reference, r.curvature, r.cant),
            roll_speed: r.dtheta_v + track.cant_rate_at_time(r.time, v),
            roll_speed_ref: deriv(&|d| d.row.cant + d.reference),
            deflection: ds,
            lat_acc_other,
            tilt_error: r.theta_v - x.reference,
            vertical: 0.0,
        }
    };
    // rows k−1 and k, waiting for k+1.
    let mut prev: Option<Derived> = None;
    let mut cur: Option<Derived> = None;
    let n = rows.each(|r| {
        if r.step % 4096 == 0 && tiltsim_rundir::signals::received() {
            return false;
        }
        let next = Derived {
            row: *r,
            reference: controller
                .as_ref()
                .map_or(r.theta_ref, |c| c.reference_at(r.s)),
        };
        if let Some(c) = &cur {
            let (before, steps) = match &prev {
                Some(p) => (p, 2.0),
                None => (c, 1.0),
            };
            visit(&c.row, &sample(c, before, &next, steps));
        }
        prev = cur.take();
        cur = Some(next);
        true
    })?;
    if let Some(c) = &cur {
        let (before, steps) = match &prev {
            Some(p) => (p, 1.0),
            None => (c, 0.0),
        };
        visit(&c.row, &sample(c, before, c, steps));
    }
    Ok(n)
}

pub fn bands(s: &Scenario) -> Vec<(f64, f64, bool)> {
    let [t1, t2, t3, t4] = section_times(&s.track);
    vec![(t1, t2, false), (t2, t3, true), (t3, t4, false)]
}

/// Most points per line of a figure: a paper run's 20,000 rows are drawn whole, an hour-long
/// run as a min/max envelope.
const PLOT_POINTS: usize = 40_000;

/// Writes `dir/plots/*.svg` and `*.png` from `dir/timeseries.csv`.
pub fn write_plots(s: &Scenario, dir: &std::path::Path) -> std::io::Result<Vec<PathBuf>> {
    let rows = tiltsim_formats::table::rows_to_plot(dir, PLOT_POINTS)?;
    let controller = crate::table4::controller_name(s);
    let who = crate::plot::RunTitle {
        scenario: &s.name,
        controller: &controller,
        tilts: s.controller.mode != controller_proc::Mode::Passive,
        estimates: s.participants.get(cosim::Role::Controller).is_none()
            && matches!(
                s.controller.mode,
                controller_proc::Mode::Lqg | controller_proc::Mode::Mpc
            ),
        cite: &|q| crate::plot::cite::run_figure(s, q),
    };
    crate::plot::write_run_plots(dir, &rows, &bands(s), s.controller.u_max_deg, &who)
}

/// Writes the timing figures of a free run (`plots/timing_input_age`, `timing_lateness`) from
/// `dir/timing.csv`; none when there is no trace. An incomplete trace (a run that ended early)
/// is an error naming it: its figures would show a part as the whole.
pub fn write_timing_plots(s: &Scenario, dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let path = dir.join(tiltsim_master::free::trace::TIMING_CSV);
    if !path.is_file() {
        return Ok(Vec::new());
    }
    let steps = s.steps();
    let period = s.controller_period_ticks();
    // One pass over the trace, one step in memory at a time.
    let mut figures = crate::plot::TimingFigures::new(steps, period);
    let partial = tiltsim_master::free::trace::each_step(&path, s.run.dt_s, steps, period, |t| {
        figures.step(t)
    })
    .map_err(|e| std::io::Error::other(e.to_string()))?;
    if let Some(why) = partial {
        return Err(std::io::Error::other(format!("{}: {why}", path.display())));
    }
    figures.write(dir, &s.name, s.run.dt_s)
}

/// Writes the figures that put several runs side by side (`out/plots/compare_*`): lateral
/// acceleration, body roll and bar angle of every run on one time axis. `runs` are (label,
/// scenario, run directory); the shaded sections are the first run's.
pub fn write_compare_plots(
    runs: &[(String, Scenario, PathBuf)],
    out: &std::path::Path,
) -> std::io::Result<Vec<PathBuf>> {
    use crate::plot::cite::{caption, compare_figure, Quantity};
    use crate::plot::{Chart, Line, PALETTE};
    use tiltsim_formats::table::Row;
    let mut data = Vec::new();
    for (label, _, dir) in runs {
        data.push((
            label.as_str(),
            tiltsim_formats::table::rows_to_plot(dir, PLOT_POINTS)?,
        ));
    }
    let n = data.iter().map(|(_, r)| r.len()).min().unwrap_or(0);
    let t: Vec<f64> = data
        .first()
        .map(|(_, r)| r[..n].iter().map(|x| x.time).collect())
        .unwrap_or_default();
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots)?;
    let bands = runs.first().map(|r| bands(&r.1)).unwrap_or_default();
    let names: Vec<&str> = runs.iter().map(|(label, _, _)| label.as_str()).collect();
    let compared = compare_name(&names);
    let mut files = Vec::new();
    /// (file name, what it shows, y label, quantity, column, scale).
    type Figure = (
        &'static str,
        &'static str,
        &'static str,
        Quantity,
        fn(&Row) -> f64,
        f64,
    );
    let figures: [Figure; 3] = [
        (
            "compare_lateral_acceleration",
            "passenger lateral acceleration (eq 13)",
            "lateral acceleration (m/s²)",
            Quantity::LateralAcceleration,
            |r| r.lat_acc,
            1.0,
        ),
        (
            "compare_body_roll",
            "carbody roll relative to the track",
            "roll θ_{v} (deg)",
            Quantity::Roll,
            |r| r.theta_v,
            1f64.to_degrees(),
        ),
        (
            "compare_control",
            "achieved anti-roll-bar angle",
            "bar angle δ_{a} (deg)",
            Quantity::BarAngle,
            |r| r.delta_a,
            1f64.to_degrees(),
        ),
    ];
    for (name, what, y_label, quantity, column, scale) in figures {
        let title = format!("{compared}: {what}");
        let cited: Vec<(&str, Option<&'static str>)> = runs
            .iter()
            .map(|(label, s, _)| (label.as_str(), compare_figure(s, quantity)))
            .collect();
        let caption = caption(&cited);
        let chart = Chart {
            title: &title,
            x_label: "time (s)",
            y_label,
            lines: data
                .iter()
                .enumerate()
                .map(|(k, (label, rows))| Line {
                    label,
                    y: rows[..n].iter().map(|r| column(r) * scale).collect(),
                    colour: PALETTE[k % PALETTE.len()],
                    ..Default::default()
                })
                .collect(),
            bands: bands.clone(),
            note: crate::plot::SECTION_NOTE,
            caption: &caption,
        };
        files.extend(crate::plot::write_chart(&plots, name, &chart, &t)?);
    }
    Ok(files)
}

/// What a compare's titles call it: "Compare of a, b, c", or of its first names and how many
/// more when they would not fit a title.
pub fn compare_name(names: &[&str]) -> String {
    const FITS: usize = 48;
    let all = names.join(", ");
    if all.chars().count() <= FITS {
        return format!("Compare of {all}");
    }
    let mut shown = String::new();
    for (k, name) in names.iter().enumerate() {
        let more = names.len() - k;
        if k > 0 && shown.chars().count() + name.chars().count() + 2 > FITS - 12 {
            return format!("Compare of {shown} and {more} more");
        }
        if k > 0 {
            shown.push_str(", ");
        }
        shown.push_str(name);
    }
    format!("Compare of {shown}")
}

/// The headline numbers, row by row.
struct QuickLooker {
    t_mid: f64,
    best: f64,
    u_max: f64,
    dt: f64,
    at_limit: u64,
    q: QuickLook,
}

impl QuickLooker {
    fn new(s: &Scenario) -> Self {
        let tp = &s.track;
        QuickLooker {
            t_mid: (tp.straight_before_m + tp.transition_m + tp.curve_m / 2.0) / tp.speed(),
            best: f64::INFINITY,
            u_max: s.controller.u_max_deg.to_radians(),
            dt: s.run.dt_s,
            at_limit: 0,
            q: QuickLook::default(),
        }
    }

    fn push(&mut self, r: &tiltsim_formats::table::Row) {
        let q = &mut self.q;
        q.lat_acc_peak = q.lat_acc_peak.max(r.lat_acc.abs());
        q.delta_a_peak = q.delta_a_peak.max(r.delta_a.abs());
        // At the limit within 1e-6 rad: the controllers clamp to ±u_max, the MPC's QP to
        // within its feasibility tolerance (about 1e-8 rad).
        if r.delta_a_cmd.abs() >= self.u_max - 1e-6 {
            self.at_limit += 1;
            q.command_at_limit_s = self.at_limit as f64 * self.dt;
        }
        if (r.time - self.t_mid).abs() < self.best {
            self.best = (r.time - self.t_mid).abs();
            q.lat_acc_mid_curve = r.lat_acc;
            q.theta_v_mid_curve = r.theta_v;
        }
    }
}
