//! What `tiltsim run` prints about a finished run.

use std::path::Path;

use tiltsim_master::engine::{RunMode, Summary};
use tiltsim_master::scenario::Scenario;

/// What ran, as a user would say it: the controller and the actuator (and the vehicle when an
/// FMU plays it), e.g. "LQG servo, switched BLDC drive" or "controller FMU pi.fmu, ideal bar".
pub fn who(s: &Scenario) -> String {
    let fmu = |role: cosim::Role, what: &str| {
        s.participants.get(role).map(|f| {
            let file = f.fmu.file_name().unwrap_or(f.fmu.as_os_str());
            format!("{what} FMU {}", file.to_string_lossy())
        })
    };
    let mut parts = vec![
        fmu(cosim::Role::Controller, "controller")
            .unwrap_or_else(|| s.controller.mode.label().to_string()),
        fmu(cosim::Role::Actuator, "actuator")
            .unwrap_or_else(|| s.actuator.model.label().to_string()),
    ];
    parts.extend(fmu(cosim::Role::Plant, "vehicle"));
    parts.join(", ")
}

/// Prints what a run of `sc` did and found: its own line (lock-step, free or replayed) naming
/// what ran, the ride, the participants' logs, for lock-step runs the timing, and the files,
/// saying so when they replaced an earlier run's (`replaced`).
pub fn print(s: &Summary, sc: &Scenario, out: &Path, replaced: bool) {
    let head = format!("{} ({})", s.scenario, who(sc));
    match s.execution {
        RunMode::LockStep => print_lock_step(s, &head),
        RunMode::Free => print_free(s, &head),
        RunMode::ReplayTiming => println!(
            "{head}: {}, {} of {} steps replayed from {} ({} exchanges){}",
            s.status,
            s.steps_completed,
            s.steps_planned,
            s.timing_trace.as_deref().unwrap_or(""),
            s.replayed_exchanges.unwrap_or(0),
            s.trace_partial
                .as_deref()
                .map(|p| format!("; partial: {p}"))
                .unwrap_or_default()
        ),
    }
    for log in &s.participant_logs {
        println!(
            "  a participant wrote to its standard error: {}",
            out.join(log).display()
        );
    }
    let figures = if s.analysis_skipped.is_some() {
        format!(" (`tiltsim plot {}` draws the figures)", out.display())
    } else {
        ", plots/*.svg|png".to_string()
    };
    if let Some(why) = &s.analysis_skipped {
        println!("  analysis skipped: {why}");
    } else {
        print_ride(&s.results, &s.comfort, &s.flags);
    }
    if s.execution == RunMode::LockStep {
        print_timing(s);
    }
    if replaced {
        println!("  replaced the earlier run in {}", out.display());
    }
    println!(
        "  wrote {}/timeseries.csv, columns.csv, summary.json, perf.json, events.csv, scenario.toml{}{}",
        out.display(),
        optional_files(out),
        figures
    );
}

fn print_lock_step(s: &Summary, head: &str) {
    println!(
        "{head}: {}, {} steps ({:.3} s simulated) in {:.3} s wall ({:.1}x real time)",
        s.status, s.steps_completed, s.simulated_time_s, s.wall_time_s, s.realtime_factor
    );
    println!(
        "  transport {}, master {}, wait {}; pids: {}",
        s.transport.name(),
        s.master_algorithm.name(),
        s.wait_strategy.name(),
        s.participants
            .iter()
            .map(|p| format!("{}={}", p.process, p.pid))
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "  coordination overhead per tick: p50 {:.2} us, p99 {:.2} us, max {:.1} us; CPU: orchestrator {:.2} s, participants {:.2} s",
        s.timing.p50, s.timing.p99, s.timing.max, s.timing.cpu_s.orchestrator, s.timing.cpu_s.participants
    );
}

fn print_free(s: &Summary, head: &str) {
    let Some(f) = &s.free_run else { return };
    let plant = f.participants.get("plant").cloned().unwrap_or_default();
    println!(
        "{head}: free run, {}, {} of {} steps in {:.2} s; plant start lateness p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs, {} late steps{}",
        s.status,
        s.steps_completed,
        s.steps_planned,
        s.wall_time_s,
        plant.start_lateness_us.p50,
        plant.start_lateness_us.p99,
        plant.start_lateness_us.max,
        plant.late_starts,
        if f.not_real_time { "; NOT REAL-TIME" } else { "" }
    );
}

/// The quick look, ride comfort and flags of a run's series.
pub fn print_ride(
    results: &tiltsim_master::engine::QuickLook,
    comfort: &tiltsim_assessment::comfort::Comfort,
    flags: &tiltsim_assessment::validity::Flags,
) {
    println!(
        "  lateral acceleration: peak {:.3} m/s², mid-curve {:.3} m/s²; body roll mid-curve {:.3} deg; peak delta_a {:.3} deg; command at its limit {:.3} s",
        results.lat_acc_peak,
        results.lat_acc_mid_curve,
        results.theta_v_mid_curve.to_degrees(),
        results.delta_a_peak.to_degrees(),
        results.command_at_limit_s
    );
    let c = comfort;
    // A number the flags make meaningless is never printed as a plain result.
    let label = if flags.not_real_time() {
        "comfort NOT VALID for real time (the run fell behind its clock; see the flag below)"
    } else if flags.ride_invalid() {
        "comfort NOT VALID (see the flags below)"
    } else {
        "comfort"
    };
    println!(
        "  {label}: P_CT (EN 12299, per transition) standing {:.2} %, seated {:.2} %; the paper's Table 4 form (whole-run peaks) {:.2} / {:.2} %; lateral acceleration RMS deviation {:.3} %g, peak {:.2} %g; jerk {:.2} %g/s",
        c.p_ct_en12299.standing,
        c.p_ct_en12299.seated,
        c.p_ct_paper.standing,
        c.p_ct_paper.seated,
        c.lat_acc_rms_dev_pct_g,
        c.lat_acc_peak_pct_g,
        c.jerk_peak_pct_g_s
    );
    let described = flags.describe();
    if described.is_empty() {
        println!(
            "  flags: all clear (no oscillation, bump stop, drive limit, chopper duty, motor over its continuous torque or P_CT out of range)"
        );
    } else {
        for f in described {
            println!("  FLAG {f}");
        }
        if flags.ride_invalid() {
            println!("  the comfort numbers above do not describe a working tilt system");
        }
        if flags.not_real_time() {
            println!(
                "  the comfort numbers above do not answer the real-time question; `tiltsim replay-timing` replays this timing exactly"
            );
        }
    }
}

/// The files only some runs write (`--record`, `--trace`), as ", run.mcap, trace.csv" for
/// those in `out` (a run removes an earlier run's at its start, so what is there is its own).
fn optional_files(out: &Path) -> String {
    ["run.mcap", "trace.csv"]
        .iter()
        .filter(|f| out.join(f).is_file())
        .map(|f| format!(", {f}"))
        .collect()
}

/// Compute, latency, pacing and solver figures.
fn print_timing(s: &Summary) {
    for p in &s.participants {
        println!(
            "  {} compute per call: p50 {:.1} us, p99 {:.1} us, max {:.1} us ({} calls)",
            p.process, p.compute_us.p50, p.compute_us.p99, p.compute_us.max, p.compute_us.n
        );
    }
    for l in &s.link_latency {
        println!(
            "  {} link latency: request p50 {:.1} us, p99 {:.1} us, max {:.1} us; reply p50 {:.1} us, p99 {:.1} us",
            l.participant, l.request_us.p50, l.request_us.p99, l.request_us.max, l.reply_us.p50, l.reply_us.p99
        );
    }
    if let Some(p) = &s.pacing {
        println!(
            "  paced at {}x real time: achieved {:.3}x; {} of {} ticks overran (late by p50 {:.1} us, max {:.1} us)",
            p.factor, p.achieved_realtime_factor, p.overruns, p.ticks, p.lateness_us.p50, p.lateness_us.max
        );
        let c = &p.causes;
        if p.overruns > 0 {
            println!(
                "  late ticks by cause: {} carried over, {} orchestrator started late (p50 {:.1} us), {} participant compute (p50 {:.1} us), {} coordination (p50 {:.1} us){}",
                c.carried_over,
                c.orchestrator,
                c.start_delay_us.p50,
                c.compute,
                c.compute_us.p50,
                c.coordination,
                c.coordination_us.p50,
                if p.realtime { "; SCHED_FIFO" } else { "" }
            );
        }
    }
    if let Some(q) = &s.controller_solver {
        println!(
            "  MPC QP: {} solves, {} failed (previous command held), iterations p50 {:.0}, max {:.0}",
            q.solves, q.failures, q.iterations.p50, q.iterations.max
        );
    }
}
