//! `tiltsim run SCENARIO --free-run` (or `run.execution = "free"`): the free-running mode's
//! files and report; and `tiltsim replay-timing DIR`: its exact lock-step replay.

use std::path::{Path, PathBuf};

use super::common::{interrupt_and_exe, load, write_json, TransportArg};
use super::error::{CliError, CliResult};
use tiltsim_master::engine::{RunOptions, Status};
use tiltsim_master::free::{FreeError, FreeReport};
use tiltsim_master::scenario::{Execution, Scenario, Transport};

/// Fields of a free run's `summary.json` measured on the wall clock (they differ on every
/// run; a free run's values do too, which is why its replay is what repeats).
const WALL_CLOCK_FIELDS: &[&str] = &[
    "wall_time_s",
    "not_real_time",
    "plant_max_lateness_s",
    "free_run",
];

fn of_free(e: FreeError) -> CliError {
    match e {
        FreeError::Trace(t) => CliError::Invalid(t.to_string()),
        FreeError::Run(r) => CliError::of_run(r, ""),
        FreeError::Link(l) => CliError::Failed(l.to_string()),
    }
}

/// The analysis of a free run's or a replay's series: the same comfort and flags as a
/// lock-step run's, or why there are none.
enum Ride {
    Assessed(Box<tiltsim_report::analysis::Assessment>),
    Skipped(String),
}

impl Ride {
    /// Adds `results`, `comfort` and `flags` (or `analysis_skipped`) to a summary.
    fn insert_into(&self, summary: &mut serde_json::Value) {
        let Some(m) = summary.as_object_mut() else {
            return;
        };
        match self {
            Ride::Assessed(a) => {
                m.insert("results".into(), serde_json::json!(a.results));
                m.insert("comfort".into(), serde_json::json!(a.comfort));
                m.insert("flags".into(), serde_json::json!(a.flags));
            }
            Ride::Skipped(why) => {
                m.insert("analysis_skipped".into(), serde_json::json!(why));
            }
        }
    }

    fn print(&self) {
        match self {
            Ride::Assessed(a) => super::report::print_ride(&a.results, &a.comfort, &a.flags),
            Ride::Skipped(why) => println!("  analysis skipped: {why}"),
        }
    }
}

/// Assesses the series in `dir/timeseries.csv`.
fn assess(s: &Scenario, dir: &Path, interrupted: bool) -> Ride {
    if interrupted {
        return Ride::Skipped(format!(
            "interrupted by {}: comfort, flags and figures not computed",
            tiltsim_master::signals::describe()
        ));
    }
    match tiltsim_report::analysis::assess(s, tiltsim_master::record::Rows::File(dir)) {
        Ok(a) => Ride::Assessed(Box::new(a)),
        Err(e) => Ride::Skipped(format!("comfort, flags and results not computed: {e}")),
    }
}

/// Draws the run's figures and, when `dir` holds a whole timing trace, its timing figures.
fn draw(s: &Scenario, dir: &Path) {
    if let Err(e) = tiltsim_report::analysis::write_plots(s, dir) {
        eprintln!("warning: plots not written: {e}");
    }
    // A run that ended early has an incomplete trace: no timing figures (the trace is kept).
    if let Err(e) = tiltsim_report::analysis::write_timing_plots(s, dir) {
        eprintln!("warning: timing plots not drawn: {e}");
    }
}

/// Runs `s` free and writes `summary.json` and `perf.json` beside the trace.
pub fn exec(s: &Scenario, scenario_file: &Path, opts: &RunOptions, quiet: bool) -> CliResult {
    let out = opts.out_dir.clone();
    let mut r: FreeReport = tiltsim_master::free::run(s, opts).map_err(of_free)?;
    let recording = r.recording.take();
    let ride = assess(s, &out, r.status == Status::Interrupted);
    let mut summary = serde_json::json!({
        "tiltsim_version": env!("CARGO_PKG_VERSION"),
        "scenario": s.name,
        "scenario_file": scenario_file.display().to_string(),
        "seed": s.run.seed,
        "transport": s.run.transport,
        "execution": Execution::Free,
        "status": r.status,
        "error": r.error,
        "dt_s": s.run.dt_s,
        "steps_planned": s.steps(),
        "steps_completed": r.steps_completed,
        "simulated_time_s": r.steps_completed as f64 * s.run.dt_s,
        "wall_time_s": r.wall_time_s,
        "not_real_time": r.not_real_time,
        "not_real_time_margin_s": r.not_real_time_margin_s,
        "plant_max_lateness_s": r.plant_max_lateness_s,
        "timing_trace": tiltsim_master::free::trace::TIMING_CSV,
        "exits": r.exits,
        "ipc_prefix": r.ipc_prefix,
        "leftover_ipc_files": r.leftover_ipc_files,
        "wall_clock_fields": WALL_CLOCK_FIELDS,
    });
    ride.insert_into(&mut summary);
    let perf = serde_json::json!({
        "scenario": s.name,
        "execution": Execution::Free,
        "steps_completed": r.steps_completed,
        "wall_time_s": r.wall_time_s,
        "not_real_time": r.not_real_time,
        "plant_max_lateness_s": r.plant_max_lateness_s,
        "free_run": {
            "cpus": r.cpus,
            "participants": r.participants,
            "input_age_ticks": r.input_age_ticks,
        },
    });
    write_json(&out.join("summary.json"), &summary)?;
    write_json(&out.join("perf.json"), &perf)?;
    if let Some(rec) = recording {
        let mut det = summary.clone();
        if let Some(o) = det.as_object_mut() {
            for f in WALL_CLOCK_FIELDS {
                o.remove(*f);
            }
        }
        rec.finish(&det, &perf)
            .map_err(|e| CliError::Failed(format!("{}: {e}", out.join("run.mcap").display())))?;
    }
    if r.status != Status::Interrupted && opts.plots {
        draw(s, &out);
    }
    if !quiet {
        let plant = &r.participants["plant"];
        println!(
            "{}: free run, {} of {} steps in {:.2} s; plant start lateness p50 {} µs, p99 {} µs, max {} µs, {} late steps{}",
            s.name,
            r.steps_completed,
            s.steps(),
            r.wall_time_s,
            plant["start_lateness_us"]["p50"],
            plant["start_lateness_us"]["p99"],
            plant["start_lateness_us"]["max"],
            plant["late_starts"],
            if r.not_real_time { "; NOT REAL-TIME" } else { "" }
        );
        ride.print();
        println!(
            "  wrote {}/timeseries.csv, timing.csv, summary.json, perf.json, events.csv, scenario.toml{}, plots/*.svg|png",
            out.display(),
            if opts.record { ", run.mcap" } else { "" }
        );
    }
    match r.status {
        Status::Completed | Status::Degraded => Ok(()),
        Status::Failed => Err(CliError::Failed(format!(
            "{}; {} of {} steps recorded in {}",
            r.error.as_deref().unwrap_or("run failed"),
            r.steps_completed,
            s.steps(),
            out.join("timeseries.csv").display()
        ))),
        Status::Interrupted => Err(CliError::Interrupted(format!(
            "interrupted: {} of {} steps recorded",
            r.steps_completed,
            s.steps()
        ))),
    }
}

/// Arguments of `replay-timing`.
#[derive(clap::Args, Debug)]
pub struct ReplayTimingArgs {
    /// Directory of a free run (`tiltsim run SCENARIO --free-run`): its timing.csv and
    /// scenario.toml.
    run_dir: PathBuf,
    /// Scenario to replay the recorded timing with [default: RUN_DIR/scenario.toml]; another
    /// controller or other gains see the same timing.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Participants in this process (default) or as processes over iceoryx2.
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
    /// Output directory [default: RUN_DIR/replay-timing].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(short, long)]
    quiet: bool,
    /// Draw no figures.
    #[arg(long)]
    no_plots: bool,
}

/// Runs `replay-timing`.
pub fn replay_timing(a: ReplayTimingArgs) -> CliResult {
    let file = a
        .scenario
        .clone()
        .unwrap_or_else(|| a.run_dir.join("scenario.toml"));
    let mut s = load(&file)?;
    // The replay is a lock-step run; a study's busy wait changes no value.
    s.run.execution = Execution::LockStep;
    s.run.controller_busy_wait_s = 0.0;
    s.run.transport = a
        .transport
        .map(Transport::from)
        .unwrap_or(Transport::InProcess);
    let errors = s.validate();
    if !errors.is_empty() {
        let lines: Vec<String> = errors
            .iter()
            .map(|e| format!("{}: {e}", file.display()))
            .collect();
        return Err(CliError::Invalid(lines.join("\nerror: ")));
    }
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| a.run_dir.join("replay-timing"));
    let _lock = tiltsim_master::outdir::claim_run(&out, "run")
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    let (interrupt, exe) = interrupt_and_exe()?;
    let opts = RunOptions {
        out_dir: out.clone(),
        participant_exe: exe,
        participant_overrides: Vec::new(),
        ipc_prefix: None,
        interrupt,
        plots: false,
        trace: false,
        pace: None,
        realtime: None,
        machine_progress: false,
        progress_bar: false,
        record: false,
        keep_rows: false,
        timing: true,
        ticks_done: None,
    };
    let trace = a.run_dir.join(tiltsim_master::free::trace::TIMING_CSV);
    let r = tiltsim_master::free::replay(&s, &trace, &opts).map_err(of_free)?;
    let ride = assess(&s, &out, false);
    let mut summary = serde_json::json!({
        "tiltsim_version": env!("CARGO_PKG_VERSION"),
        "scenario": s.name,
        "scenario_file": file.display().to_string(),
        "seed": s.run.seed,
        "timing_trace": trace.display().to_string(),
        "transport": s.run.transport,
        "execution": "replay-timing",
        "status": Status::Completed,
        "dt_s": s.run.dt_s,
        "steps_completed": r.steps_completed,
        "simulated_time_s": r.steps_completed as f64 * s.run.dt_s,
        "exchanges": r.exchanges,
    });
    ride.insert_into(&mut summary);
    write_json(&out.join("summary.json"), &summary)?;
    if !a.no_plots {
        draw(&s, &out);
    }
    if !a.quiet {
        println!(
            "{}: {} steps replayed from {} ({} exchanges) into {}",
            s.name,
            r.steps_completed,
            trace.display(),
            r.exchanges,
            out.join("timeseries.csv").display()
        );
        ride.print();
    }
    Ok(())
}
