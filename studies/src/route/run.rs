//! A route run: the line cut into segments, each simulated as a run of its own at its running
//! speed, in parallel, and the segments' assessments gathered in route order.
//!
//! Every curve is a segment from the middle of the straight before it (at most `LEAD_M`
//! before its first transition) to the middle of the straight after (at most `LEAD_M` after
//! its second), run at the lowest speed the profile has on the curve. What is left of each
//! straight is cut into segments of at most `STRAIGHT_CHUNK_S` of running, each at its mean
//! profile speed (so its simulated time is the profile's). Each segment starts from rest on
//! straight track and draws its own track irregularity from the run's seed and its index, so
//! a segment's result depends on nothing but its own settings: segments run in any order, in
//! parallel, and hold at most one segment's rows in memory each, whatever the route's length.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use serde::Serialize;
use tiltsim_assessment::comfort::{
    p_ct, Assessor, Body, ComfortSettings, Pct, Position, Ride, Sickness, SicknessAssessor,
    STANDING,
};
use tiltsim_master::engine::{RunOptions, Status};
use tiltsim_scenario::scenario::Scenario;

use super::file::Route;
use super::profile::{Bound, Profile};

/// Longest stretch of straight simulated before and after a curve (m).
pub const LEAD_M: f64 = 400.0;
/// Longest straight segment (s of running).
pub const STRAIGHT_CHUNK_S: f64 = 60.0;
/// The cut-offs of the EN 12299 reading sensitivity (Hz), the standard's 0.3 Hz first.
pub const READINGS_HZ: [f64; 3] = [0.3, 0.25, 0.4];

/// One simulated stretch of the line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Segment {
    /// Its place in the route run (0-based).
    pub index: usize,
    /// The route section it is in (a curve's, or the straight it cuts).
    pub section: usize,
    /// A curve (with its leads) or a piece of straight.
    pub curve: bool,
    /// Start and end chainage (m).
    pub from_m: f64,
    #[allow(missing_docs)]
    pub to_m: f64,
    /// Straight run before the curve's first transition and after its second (m).
    pub lead_in_m: f64,
    #[allow(missing_docs)]
    pub lead_out_m: f64,
    /// Running speed (m/s).
    pub speed_m_s: f64,
}

/// The segments of `route` under `profile`.
pub fn plan(route: &Route, profile: &Profile) -> Vec<Segment> {
    let secs = &route.sections;
    let lead = |j: usize| (secs[j].length_m / 2.0).min(LEAD_M);
    let mut out: Vec<Segment> = Vec::new();
    for (i, s) in secs.iter().enumerate() {
        if s.curve.is_some() {
            // A curve has straights on both sides (checked when the file was read).
            let (lead_in_m, lead_out_m) = (lead(i - 1), lead(i + 1));
            out.push(Segment {
                index: out.len(),
                section: i,
                curve: true,
                from_m: s.chainage_m - lead_in_m,
                to_m: s.end_m() + lead_out_m,
                lead_in_m,
                lead_out_m,
                speed_m_s: profile.section_min_speed(i),
            });
            continue;
        }
        let from = s.chainage_m + if i > 0 { lead(i) } else { 0.0 };
        let to = s.end_m() - if i + 1 < secs.len() { lead(i) } else { 0.0 };
        if to - from < 1.0 {
            continue;
        }
        let pieces = (profile.time_between(i, from, to) / STRAIGHT_CHUNK_S)
            .ceil()
            .max(1.0) as usize;
        let step = (to - from) / pieces as f64;
        for k in 0..pieces {
            let (a, b) = (from + step * k as f64, from + step * (k + 1) as f64);
            out.push(Segment {
                index: out.len(),
                section: i,
                curve: false,
                from_m: a,
                to_m: b,
                lead_in_m: 0.0,
                lead_out_m: 0.0,
                speed_m_s: (b - a) / profile.time_between(i, a, b),
            });
        }
    }
    out
}

/// A segment's seed: the run's seed and the segment's index mixed (SplitMix64's finaliser), so
/// neighbouring segments draw unrelated irregularity and sensor noise.
pub fn segment_seed(seed: u64, index: usize) -> u64 {
    let mut z = seed ^ (index as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The scenario of segment `g` of `route`: `base`'s vehicle, actuator, controller and
/// irregularity model, the segment's track and speed.
pub fn segment_scenario(base: &Scenario, route: &Route, g: &Segment) -> Scenario {
    let mut s = base.clone();
    s.name = format!("{}-{}-{:04}", base.name, route.name, g.index);
    s.run.seed = segment_seed(base.run.seed, g.index);
    s.track.speed_kmh = g.speed_m_s * 3.6;
    let sec = &route.sections[g.section];
    match (g.curve, sec.curve) {
        (true, Some(c)) => {
            s.track.radius_m = c.radius_m;
            s.track.cant_deg = c.radius_m.signum() * c.cant_rad().to_degrees();
            s.track.transition_m = c.transition_m;
            s.track.transition_shape = c.shape;
            s.track.curve_m = sec.length_m - 2.0 * c.transition_m;
            s.track.straight_before_m = g.lead_in_m;
            s.track.straight_after_m = g.lead_out_m;
            s.run.duration_s = None;
        }
        _ => {
            // Straight track for the whole run: the model's curve lies beyond its end.
            let len = g.to_m - g.from_m;
            s.track.straight_before_m = len + 100.0;
            s.run.duration_s = Some(len / g.speed_m_s);
        }
    }
    s
}

/// One transition's P_CT under the readings of EN 12299: the standard's (0.3 Hz), the other
/// cut-offs of [`READINGS_HZ`], and 0.3 Hz with the roll speed unfiltered.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct TransitionComfort {
    /// The standard's reading.
    pub p_ct: Pct,
    /// P_CT standing at 0.25 Hz and 0.4 Hz (%).
    pub standing_at_cutoffs: [f64; 2],
    /// P_CT standing at 0.3 Hz with the unfiltered roll speed's peak in the window (%).
    pub standing_unfiltered_roll: f64,
}

/// The limits the vehicle met on a segment.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Met {
    /// Time the bar spent at its angle limit (s).
    pub bar_at_limit_s: f64,
    /// Largest secondary lateral deflection as a share of the bump-stop clearance (%).
    pub bump_stop_pct: f64,
    /// Time the drive was at a current, speed or power limit (s).
    pub drive_limited_s: f64,
    /// Largest bar angle (deg).
    pub bar_peak_deg: f64,
}

/// What a segment's run gave.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentResult {
    /// The segment.
    pub segment: Segment,
    /// `completed`, or why not.
    pub status: String,
    /// Its curve's entry and exit transitions (curves only).
    pub transitions: Vec<TransitionComfort>,
    /// The straight-track ride over the segment.
    pub ride: Ride,
    /// Motion-sickness doses at each passenger position, by name.
    pub sickness: Vec<(String, Sickness)>,
    /// The limits met.
    pub met: Met,
    /// Validity flags raised.
    pub flags: Vec<String>,
    /// Simulated time (s).
    pub simulated_s: f64,
    /// The whole car's running safety over the segment (`vehicle.model = "full"`).
    pub running_safety: Option<SegmentSafety>,
}

/// The whole car's running safety over one segment, as its run's `summary.json` gives it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentSafety {
    /// Each quantity's worst value, wheelset and limit.
    pub values: Vec<tiltsim_assessment::running_safety::SafetyValue>,
    /// The flag: raised, the quantities exceeded, the binding one.
    pub flag: tiltsim_assessment::running_safety::RunningSafetyFlag,
}

/// How to run a route's segments.
pub struct RouteExec {
    /// Where the segments run (each in its own directory, removed after unless kept).
    pub out: PathBuf,
    /// Parallel runs.
    pub jobs: usize,
    /// Keep each segment's run directory.
    pub keep_runs: bool,
    /// Executable serving participants.
    pub exe: PathBuf,
    /// Set by Ctrl-C.
    pub interrupt: Arc<AtomicBool>,
}

/// Runs `jobs` (each a scenario of one segment, labelled by a directory name) on `ex.jobs`
/// threads; results in the order given, `None` where an interrupt stopped it.
pub fn run_all(jobs: &[(String, Scenario, Segment)], ex: &RouteExec) -> Vec<Option<SegmentResult>> {
    let next = AtomicUsize::new(0);
    let out: Mutex<Vec<Option<SegmentResult>>> = Mutex::new(vec![None; jobs.len()]);
    std::thread::scope(|sc| {
        for _ in 0..ex.jobs.clamp(1, jobs.len().max(1)) {
            sc.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= jobs.len() || ex.interrupt.load(Ordering::Relaxed) {
                    break;
                }
                let (dir, s, g) = &jobs[i];
                let r = run_segment(s, g, &ex.out.join("runs").join(dir), ex);
                if ex.interrupt.load(Ordering::Relaxed) {
                    break;
                }
                if let Ok(mut o) = out.lock() {
                    o[i] = Some(r);
                }
            });
        }
    });
    let _ = std::fs::remove_dir(ex.out.join("runs"));
    out.into_inner().unwrap_or_default()
}

/// Runs one segment's scenario in `dir` and assesses it.
fn run_segment(s: &Scenario, g: &Segment, dir: &Path, ex: &RouteExec) -> SegmentResult {
    let mut opts = RunOptions::new(dir.to_path_buf(), ex.exe.clone());
    opts.interrupt = ex.interrupt.clone();
    opts.plots = ex.keep_runs;
    opts.timing = ex.keep_runs;
    let mut job = tiltsim_runner::pipeline::Job::new(s, s.name.clone(), opts);
    job.claim = false;
    job.outputs.rows_in_memory = !ex.keep_runs;
    let done = tiltsim_runner::pipeline::carry_out(job);
    let mut result = SegmentResult {
        segment: *g,
        status: String::new(),
        transitions: Vec::new(),
        ride: Ride::default(),
        sickness: Vec::new(),
        met: Met::default(),
        flags: Vec::new(),
        simulated_s: 0.0,
        running_safety: None,
    };
    let done = match done {
        Ok(d) => d,
        Err(e) => {
            result.status = e.to_string();
            return result;
        }
    };
    result.status = match done.summary.status {
        Status::Completed => "completed".to_string(),
        other => format!(
            "{other}: {}",
            done.summary.error.clone().unwrap_or_default()
        ),
    };
    result.flags = done
        .summary
        .flags
        .raised()
        .iter()
        .map(|f| f.to_string())
        .collect();
    result.simulated_s = done.summary.simulated_time_s;
    if let (Some(car), Some(flag)) = (&done.summary.full_car, &done.summary.flags.running_safety) {
        result.running_safety = Some(SegmentSafety {
            values: car.running_safety.clone(),
            flag: flag.clone(),
        });
    }
    let assessed = if ex.keep_runs {
        assess(s, g, tiltsim_formats::table::Rows::File(dir))
    } else {
        assess(s, g, tiltsim_formats::table::Rows::Kept(&done.rows))
    };
    drop(done);
    if !ex.keep_runs {
        let _ = std::fs::remove_dir_all(dir);
    }
    match assessed {
        Ok((t, ride, sickness, met)) => {
            result.transitions = t;
            result.ride = ride;
            result.sickness = sickness;
            result.met = met;
        }
        Err(e) => result.status = format!("assessment: {e}"),
    }
    result
}

type Assessed = (Vec<TransitionComfort>, Ride, Vec<(String, Sickness)>, Met);

/// One pass over a segment's rows: every transition under every reading, the ride, the doses
/// at each position and the limits met.
fn assess(
    s: &Scenario,
    g: &Segment,
    rows: tiltsim_formats::table::Rows,
) -> std::io::Result<Assessed> {
    let dt = s.run.dt_s;
    let v = s.track.speed();
    let body = Body {
        bump_stop_m: s.vehicle.bump_stop_m,
        cog_height_m: s.vehicle.h_gv,
    };
    let tp = &s.track;
    let windows: Vec<(f64, f64)> = if g.curve {
        let t1 = tp.straight_before_m / v;
        let t2 = t1 + tp.transition_m / v;
        let t3 = t2 + tp.curve_m / v;
        vec![(t1, t2), (t3, t3 + tp.transition_m / v)]
    } else {
        Vec::new()
    };
    let at = |hz: f64| ComfortSettings {
        filter_hz: hz,
        positions: Vec::new(),
        ..s.comfort.clone()
    };
    // readings[w][k]: transition w under cut-off k.
    let mut readings: Vec<Vec<Assessor>> = windows
        .iter()
        .map(|w| {
            READINGS_HZ
                .iter()
                .map(|&hz| Assessor::new(dt, &[*w], &at(hz), body))
                .collect()
        })
        .collect();
    let mut raw_roll = vec![0.0f64; windows.len()];
    let mut ride = Assessor::new(dt, &[], &at(s.comfort.filter_hz), body);
    let positions: Vec<Position> = s.comfort.positions.clone();
    let mut doses: Vec<SicknessAssessor> = positions
        .iter()
        .map(|_| SicknessAssessor::new(dt))
        .collect();
    let mut last_roll: Option<f64> = None;
    let mut met = Met::default();
    let u_max = s.controller.u_max_deg.to_radians();
    let margin = s.comfort.margin_s;
    tiltsim_report::analysis::scan(s, rows, |r, x| {
        readings.iter_mut().flatten().for_each(|a| a.push(x));
        for (k, w) in windows.iter().enumerate() {
            if x.t >= w.0 - margin && x.t <= w.1 + margin {
                raw_roll[k] = raw_roll[k].max(x.roll_speed.abs());
            }
        }
        ride.push(x);
        let roll_acc = last_roll.map_or(0.0, |p| (x.roll_speed - p) / dt);
        last_roll = Some(x.roll_speed);
        for (p, d) in positions.iter().zip(doses.iter_mut()) {
            d.push(&p.moved(x, roll_acc, body.cog_height_m));
        }
        if s.controller.mode != controller_proc::Mode::Passive && r.delta_a.abs() >= 0.999 * u_max {
            met.bar_at_limit_s += dt;
        }
        if r.actuator_limits != 0 {
            met.drive_limited_s += dt;
        }
        met.bump_stop_pct = met
            .bump_stop_pct
            .max(100.0 * x.deflection.abs() / body.bump_stop_m);
        met.bar_peak_deg = met.bar_peak_deg.max(r.delta_a.abs().to_degrees());
    })?;
    let transitions = readings
        .iter()
        .zip(&raw_roll)
        .map(|(set, raw)| {
            let c: Vec<Pct> = set.iter().map(|a| a.finish().p_ct_en12299).collect();
            TransitionComfort {
                p_ct: c[0],
                standing_at_cutoffs: [c[1].standing, c[2].standing],
                standing_unfiltered_roll: p_ct(
                    &STANDING,
                    c[0].lat_acc_m_s2,
                    c[0].jerk_m_s3,
                    raw.to_degrees(),
                ),
            }
        })
        .collect();
    let sickness = positions
        .iter()
        .zip(&doses)
        .map(|(p, d)| (p.name.clone(), d.finish()))
        .collect();
    Ok((transitions, ride.finish().ride, sickness, met))
}

/// The limits that bind on a curve: the profile's (its speed limit, the cant deficiency, or
/// the train still accelerating or braking there) and those the vehicle met (bar angle, bump
/// stop, drive), joined with "; ".
pub fn binding(profile: &Profile, section: usize, met: &Met) -> String {
    let sec = &profile.sections[section];
    let mut v = Vec::new();
    if profile.section_min_speed(section) < sec.limit_m_s - 0.01 {
        v.push("acceleration/braking");
    } else {
        v.push(match sec.bound {
            Bound::SpeedLimit => "speed limit",
            Bound::CantDeficiency => "cant deficiency",
        });
    }
    if met.bar_at_limit_s > 0.0 {
        v.push("bar angle");
    }
    if met.bump_stop_pct >= 100.0 {
        v.push("bump stop");
    }
    if met.drive_limited_s > 0.0 {
        v.push("drive");
    }
    v.join("; ")
}

/// CPU time of this process so far, user and system (s), all threads included: with
/// in-process runs, the CPU a study cost.
pub fn process_cpu_s() -> f64 {
    // SAFETY: getrusage writes the struct it is given and nothing else.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return f64::NAN;
    }
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    t(u.ru_utime) + t(u.ru_stime)
}
