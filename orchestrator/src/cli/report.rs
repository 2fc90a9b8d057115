//! What `tiltsim run` (and `replay-timing`) prints about a finished run: what the run found
//! first (EN 12299's P_CT, the validity flags in words, where the files are), then the ride's
//! other figures, the paper's form of P_CT as a reproduction, and the transport and timing in
//! one line; `-v` prints every timing figure.

use std::path::Path;

use tiltsim_assessment::comfort::Comfort;
use tiltsim_assessment::validity::Flags;
use tiltsim_master::engine::{QuickLook, RunMode, Summary};
use tiltsim_scenario::scenario::Scenario;

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

/// Whether the run's controller commands the bar: any but the passive vehicle (a controller
/// FMU always may).
pub fn commands(s: &Scenario) -> bool {
    s.participants.get(cosim::Role::Controller).is_some()
        || s.controller.mode != controller_proc::Mode::Passive
}

/// The start of the line that gives EN 12299's P_CT; the tests read the numbers after it.
pub const P_CT_LINE: &str = "P_CT, EN 12299 (per transition, 0.3 Hz filtered):";

/// The start of the one line of transport and timing.
pub const RUN_LINE: &str = "  run:";

/// Prints what a run of `sc` did and found: its own line (lock-step, free or replayed) naming
/// what ran, then what it found, where its files are, the rest of the ride, the paper's form,
/// and its transport and timing in one line (every timing figure when `verbose`), saying so
/// when the files replaced an earlier run's (`replaced`).
pub fn print(s: &Summary, sc: &Scenario, out: &Path, replaced: bool, verbose: bool) {
    let head = format!("{} ({})", s.scenario, who(sc));
    match s.execution {
        RunMode::LockStep => println!(
            "{head}: {}, {} steps ({:.3} s simulated)",
            s.status, s.steps_completed, s.simulated_time_s
        ),
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
    match &s.analysis_skipped {
        Some(why) => println!("  analysis skipped: {why}"),
        None => print_findings(&s.comfort, &s.flags),
    }
    print_files(s, out, replaced);
    if s.analysis_skipped.is_none() {
        print_ride(&s.results, &s.comfort, commands(sc));
    }
    if s.execution == RunMode::LockStep {
        print_timing(s, verbose);
    }
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

/// What the run found: EN 12299's P_CT, standing and seated, marked when the flags make it
/// meaningless (it is never printed as a plain result then), and the flags in words.
fn print_findings(c: &Comfort, flags: &Flags) {
    let verdict = if flags.not_real_time() {
        " NOT VALID for real time (the run fell behind its clock; see the flag below)"
    } else if flags.ride_invalid() {
        " NOT VALID (see the flags below)"
    } else {
        ""
    };
    println!(
        "  {P_CT_LINE} standing {:.2} %, seated {:.2} %{verdict}",
        c.p_ct_en12299.standing, c.p_ct_en12299.seated,
    );
    let described = flags.describe();
    if described.is_empty() {
        println!(
            "  validity flags: none raised (no oscillation, bump stop, drive limit, chopper duty, motor over its continuous torque or P_CT out of range)"
        );
        return;
    }
    println!("  validity flags: {} raised", described.len());
    for f in described {
        println!("  FLAG {f}");
    }
    if flags.ride_invalid() {
        println!("  the comfort numbers of this run do not describe a working tilt system");
    }
    if flags.not_real_time() {
        println!(
            "  the comfort numbers of this run do not answer the real-time question; `tiltsim replay-timing` replays this timing exactly"
        );
    }
}

/// Where the files are: the directory, the files in it, the participants' logs, and whether
/// they replaced an earlier run's.
fn print_files(s: &Summary, out: &Path, replaced: bool) {
    let drawn = out.join("plots").is_dir();
    let figures = if s.analysis_skipped.is_some() || !drawn {
        format!(" (`tiltsim plot {}` draws the figures)", out.display())
    } else {
        ", plots/*.svg|png".to_string()
    };
    println!(
        "  wrote {}/: timeseries.csv, columns.csv, summary.json, perf.json, events.csv, scenario.toml{}{}",
        out.display(),
        optional_files(out),
        figures
    );
    for log in &s.participant_logs {
        println!(
            "  a participant wrote to its standard error: {}",
            out.join(log).display()
        );
    }
    if replaced {
        println!("  replaced the earlier run in {}", out.display());
    }
}

/// The ride's other figures, the command's (only for a controller that commands the bar) and
/// the paper's form of P_CT, labelled as the reproduction it is.
fn print_ride(results: &QuickLook, c: &Comfort, commands: bool) {
    println!(
        "  ride: lateral acceleration peak {:.2} %g ({:.3} m/s²), RMS deviation from the ideal tilt {:.3} %g, mid-curve {:.3} m/s²; jerk peak {:.2} %g/s; body roll mid-curve {:.3} deg",
        c.lat_acc_peak_pct_g,
        results.lat_acc_peak,
        c.lat_acc_rms_dev_pct_g,
        results.lat_acc_mid_curve,
        c.jerk_peak_pct_g_s,
        results.theta_v_mid_curve.to_degrees(),
    );
    if commands {
        println!(
            "  command: bar angle delta_a peak {:.3} deg; at its limit for {:.3} s",
            results.delta_a_peak.to_degrees(),
            results.command_at_limit_s
        );
    }
    println!(
        "  reproduction of the paper's Table 4 form (whole-run peaks of the unfiltered signals, not EN 12299): P_CT standing {:.2} %, seated {:.2} %",
        c.p_ct_paper.standing, c.p_ct_paper.seated
    );
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

/// The transport and timing: one line, then (`verbose`) the processes, the coordination
/// overhead and CPU, each participant's compute and link latency. What the command line asked
/// for (`--pace`) and a solver that failed are results, printed either way.
fn print_timing(s: &Summary, verbose: bool) {
    println!(
        "{RUN_LINE} transport {}, master {}, wait {}; {:.3} s wall ({:.1}x real time), coordination overhead p50 {:.2} us per tick{}",
        s.transport.name(),
        s.master_algorithm.name(),
        s.wait_strategy.name(),
        s.wall_time_s,
        s.realtime_factor,
        s.timing.p50,
        if verbose { "" } else { " (-v: every timing figure)" }
    );
    if verbose {
        print_internals(s);
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
    if let Some(q) = s
        .controller_solver
        .as_ref()
        .filter(|q| verbose || q.failures > 0)
    {
        println!(
            "  MPC QP: {} solves, {} failed (previous command held), iterations p50 {:.0}, max {:.0}",
            q.solves, q.failures, q.iterations.p50, q.iterations.max
        );
    }
}

/// Every timing figure of a lock-step run (`-v`).
fn print_internals(s: &Summary) {
    println!(
        "  pids: {}",
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
}
