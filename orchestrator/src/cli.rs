//! The `tiltsim` command line.
//!
//! Exit codes: 0 success; 1 the run failed (a participant died, stalled or sent bad data);
//! 2 invalid input (command line or scenario file); 130 interrupted by Ctrl-C.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use clap::{Parser, Subcommand, ValueEnum};
use cosim::wait::WaitStrategy;

use crate::engine::{self, RunOptions, Status};
use crate::scenario::{Master, Scenario, Transport};

/// Exit code: the run failed.
pub const EXIT_FAILED: i32 = 1;
/// Exit code: invalid input.
pub const EXIT_INVALID: i32 = 2;
/// Exit code: interrupted.
pub const EXIT_INTERRUPTED: i32 = 130;

#[derive(Parser, Debug)]
#[command(
    name = "tiltsim",
    version,
    about = "Co-simulator for active tilt control of railway vehicles"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// More log output (repeat for more).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a scenario and write DIR/timeseries.csv, DIR/summary.json, DIR/scenario.toml.
    Run(RunArgs),
    /// Check a scenario file without running it.
    Validate {
        /// Scenario file (TOML).
        scenario: PathBuf,
    },
    /// Run several scenarios and write DIR/table.md and DIR/table.csv laid out like the
    /// paper's Table 4 (each run's files go to DIR/<scenario name>/).
    Compare {
        /// Scenario files (TOML).
        #[arg(required = true)]
        scenarios: Vec<PathBuf>,
        /// Output directory.
        #[arg(long, default_value = "out/compare")]
        out: PathBuf,
        /// Transport for every run, overriding run.transport.
        #[arg(long, value_enum)]
        transport: Option<TransportArg>,
    },
    /// Redraw DIR/plots/*.svg and *.png from a finished run's DIR/timeseries.csv and DIR/scenario.toml.
    Plot {
        /// A run's output directory.
        dir: PathBuf,
    },
    /// Robustness or parameter sweep: many runs in parallel, a table of comfort metrics
    /// (median, 5th and 95th percentile) and plots in DIR. Either --samples (Monte Carlo
    /// over masses, inertias and suspension, Fig. 21) or --grid KEY=START:STOP:STEP.
    Sweep(SweepArgs),
    /// Merge the outputs of `tiltsim sweep --shard i/n` runs into the whole sweep's files.
    SweepMerge {
        /// Shard output directories.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
    },
    /// Measure this machine: the iceoryx2 round-trip floor, the per-tick coordination
    /// overhead of every master algorithm and wait strategy, and in-process vs IPC wall time.
    Bench {
        /// Scenario to run in every configuration.
        #[arg(default_value = "scenarios/paper-passive.toml")]
        scenario: PathBuf,
        /// Simulated seconds per configuration.
        #[arg(long, default_value_t = 2.0)]
        duration: f64,
        /// JSON report.
        #[arg(long, default_value = "out/bench.json")]
        out: PathBuf,
    },
    /// Print the linear design model (matrices, eigenvalues, damping, frequencies) and the
    /// scenario controller's gains as JSON.
    Linearize {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Write the JSON here instead of standard output.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Also design a PI for this scenario's vehicle and actuator: the largest K_p with
        /// integral time --ti whose margins reach --phase-margin and --gain-margin.
        #[arg(long)]
        design_pi: bool,
        /// Phase-margin target of --design-pi (deg).
        #[arg(long, default_value_t = 60.0)]
        phase_margin: f64,
        /// Gain-margin target of --design-pi (dB).
        #[arg(long, default_value_t = 6.0)]
        gain_margin: f64,
        /// Integral time K_p/K_i of --design-pi (s).
        #[arg(long, default_value_t = 0.25)]
        ti: f64,
    },
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Output directory [default: out/<scenario name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Transport, overriding run.transport.
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
    /// Seed, overriding run.seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Master algorithm, overriding run.master.
    #[arg(long, value_enum)]
    master: Option<MasterArg>,
    /// Wait strategy, overriding run.wait.
    #[arg(long, value_enum)]
    wait: Option<WaitArg>,
    /// Stall deadline in ms, overriding run.deadline_ms.
    #[arg(long)]
    deadline_ms: Option<u64>,
    /// Simulated duration in s, overriding run.duration_s.
    #[arg(long)]
    duration: Option<f64>,
    /// iceoryx2 file prefix for this run (default: unique per run).
    #[arg(long, hide = true)]
    ipc_prefix: Option<String>,
    /// Write DIR/trace.csv (every exchange: sent, received, step started and finished,
    /// reply sent and received, monotonic ns) and plots/latency_histogram.
    #[arg(long)]
    trace: bool,
    /// Run at FACTOR simulated seconds per wall second (1.0 = real time) and report every
    /// tick that finished late.
    #[arg(long, value_name = "FACTOR")]
    pace: Option<f64>,
    /// Serve ROLE from another executable (ROLE=PATH; for test participants).
    #[arg(long, hide = true, value_name = "ROLE=PATH")]
    participant_exe: Vec<String>,
    /// Print nothing but errors.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args, Debug)]
struct SweepArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Monte Carlo samples (uniform factors on masses, inertias and suspension).
    #[arg(long, conflicts_with = "grid", required_unless_present = "grid")]
    samples: Option<usize>,
    /// Relative half-width of the Monte Carlo factors.
    #[arg(long, default_value_t = 0.22)]
    spread: f64,
    /// Seed of the Monte Carlo draws.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Vary one scenario key instead: KEY=START:STOP:STEP or KEY=V1,V2,...
    /// (e.g. links.actuator_command.delay_ticks=0:100:10).
    #[arg(long)]
    grid: Option<String>,
    /// Run only samples j with j mod N = I, for a batch scheduler; merge with sweep-merge.
    #[arg(long, value_name = "I/N")]
    shard: Option<String>,
    /// Parallel runs [default: the number of CPUs].
    #[arg(long)]
    jobs: Option<usize>,
    /// Transport of every run [default: in-process].
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
    /// Output directory [default: out/sweep-<scenario name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Keep every sample's run directory (timeseries, summary, plots) under DIR/runs/.
    #[arg(long)]
    keep_runs: bool,
    /// No progress bar and no table on standard output.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(ValueEnum, Clone, Copy, Debug)]
enum TransportArg {
    Ipc,
    InProcess,
}
#[derive(ValueEnum, Clone, Copy, Debug)]
enum MasterArg {
    GaussSeidel,
    Jacobi,
}
#[derive(ValueEnum, Clone, Copy, Debug)]
enum WaitArg {
    Spin,
    Adaptive,
    Sleep,
}

/// Runs the program; returns the exit code.
pub fn main() -> i32 {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("participant") {
        return participant(&args[2..]);
    }
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { EXIT_INVALID } else { 0 };
        }
    };
    let level = match cli.verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| level.into()),
        )
        .with_writer(std::io::stderr)
        .try_init();
    match cli.command {
        Command::Validate { scenario } => match Scenario::load(&scenario) {
            Ok(s) => {
                println!(
                    "{}: valid ({} s at {} km/h, {} steps of {} ms, controller {:?}, actuator {:?})",
                    scenario.display(),
                    s.duration(),
                    s.track.speed_kmh,
                    s.steps(),
                    s.run.dt_s * 1e3,
                    s.controller.mode,
                    s.actuator.model
                );
                0
            }
            Err(e) => {
                eprintln!("error: {e}");
                EXIT_INVALID
            }
        },
        Command::Run(a) => run(a),
        Command::Linearize {
            scenario,
            out,
            design_pi,
            phase_margin,
            gain_margin,
            ti,
        } => {
            let targets = design_pi.then_some(crate::linearize::PiTargets {
                phase_margin_deg: phase_margin,
                gain_margin_db: gain_margin,
                ti_s: ti,
            });
            linearize(&scenario, out.as_deref(), targets)
        }
        Command::Sweep(a) => sweep(a),
        Command::Bench {
            scenario,
            duration,
            out,
        } => bench(&scenario, duration, &out),
        Command::SweepMerge { shards, out } => match crate::sweep::merge(&shards) {
            Ok((base, plan, rows)) => {
                match crate::sweep::write_outputs(&out, &base, &plan, None, &rows) {
                    Ok(_) => {
                        println!(
                            "merged {} samples from {} shards into {}",
                            rows.len(),
                            shards.len(),
                            out.display()
                        );
                        0
                    }
                    Err(e) => {
                        eprintln!("error: {}: {e}", out.display());
                        EXIT_FAILED
                    }
                }
            }
            Err(e) => {
                eprintln!("error: {e}");
                EXIT_INVALID
            }
        },
        Command::Plot { dir } => {
            let s = match Scenario::load(&dir.join("scenario.toml")) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("error: {e}");
                    return EXIT_INVALID;
                }
            };
            match crate::analysis::write_plots(&s, &dir) {
                Ok(files) => {
                    for f in files {
                        println!("wrote {}", f.display());
                    }
                    0
                }
                Err(e) => {
                    eprintln!("error: {}: {e}", dir.join("timeseries.csv").display());
                    EXIT_INVALID
                }
            }
        }
        Command::Compare {
            scenarios,
            out,
            transport,
        } => compare(&scenarios, &out, transport),
    }
}

fn compare(files: &[PathBuf], out: &std::path::Path, transport: Option<TransportArg>) -> i32 {
    let mut loaded = Vec::new();
    for f in files {
        match Scenario::load(f) {
            Ok(mut s) => {
                if let Some(t) = transport {
                    s.run.transport = match t {
                        TransportArg::Ipc => Transport::Ipc,
                        TransportArg::InProcess => Transport::InProcess,
                    };
                }
                loaded.push((f.clone(), s));
            }
            Err(e) => {
                eprintln!("error: {e}");
                return EXIT_INVALID;
            }
        }
    }
    let Some((interrupt, exe)) = interrupt_and_exe() else {
        return EXIT_FAILED;
    };
    let mut entries = Vec::new();
    let mut runs = Vec::new();
    for (file, s) in loaded {
        let dir = out.join(&s.name);
        let mut opts = RunOptions::new(dir.clone(), exe.clone());
        opts.interrupt = interrupt.clone();
        let summary = match crate::analysis::run(&s, &file.display().to_string(), &opts) {
            Ok(sum) => sum,
            Err(e) => {
                eprintln!("error: {}: {e}", file.display());
                return EXIT_FAILED;
            }
        };
        let _ = std::fs::write(
            dir.join("summary.json"),
            serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n",
        );
        println!(
            "{}: {:?}, P_CT standing {:.2} %, peak lateral acceleration {:.2} %g",
            s.name,
            summary.status,
            summary.comfort.p_ct.standing,
            summary.comfort.lat_acc_peak_pct_g
        );
        match summary.status {
            Status::Completed | Status::Degraded => {}
            Status::Interrupted => return EXIT_INTERRUPTED,
            Status::Failed => {
                eprintln!(
                    "error: {}: {}",
                    s.name,
                    summary.error.as_deref().unwrap_or("run failed")
                );
                return EXIT_FAILED;
            }
        }
        let ideal =
            crate::comfort::ideal_tilt(&crate::analysis::signals_from_run(&s, &dir), &s.comfort);
        runs.push((s.name.clone(), s.clone(), dir));
        entries.push(crate::compare::entry(s, summary, ideal));
    }
    let (md, csv) = crate::compare::tables(&entries);
    for (name, text) in [("table.md", &md), ("table.csv", &csv)] {
        let p = out.join(name);
        if let Err(e) = std::fs::write(&p, text) {
            eprintln!("error: {}: {e}", p.display());
            return EXIT_FAILED;
        }
    }
    if let Err(e) = crate::analysis::write_compare_plots(&runs, out) {
        eprintln!("error: {}: {e}", out.join("plots").display());
        return EXIT_FAILED;
    }
    println!(
        "wrote {0}/table.md, {0}/table.csv and {0}/plots/compare_*.svg|png",
        out.display()
    );
    0
}

/// The Ctrl-C flag (handler installed) and the executable that serves participants; `None`
/// (after saying why) when the executable cannot be found.
fn interrupt_and_exe() -> Option<(Arc<AtomicBool>, PathBuf)> {
    let interrupt = Arc::new(AtomicBool::new(false));
    let flag = interrupt.clone();
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    match std::env::current_exe() {
        Ok(exe) => Some((interrupt, exe)),
        Err(e) => {
            eprintln!("error: cannot find the tiltsim executable to start participants: {e}");
            None
        }
    }
}

fn sweep(a: SweepArgs) -> i32 {
    use crate::sweep::{Exec, Plan, Shard};
    let mut s = match Scenario::load(&a.scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_INVALID;
        }
    };
    s.run.transport = match a.transport {
        Some(TransportArg::Ipc) => Transport::Ipc,
        Some(TransportArg::InProcess) => Transport::InProcess,
        // In-process by default: a sample then costs no process start, and the results are
        // the same bytes either way.
        None => Transport::InProcess,
    };
    let plan = match (&a.grid, a.samples) {
        (Some(g), _) => match crate::sweep::parse_grid(g) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("error: {e}");
                return EXIT_INVALID;
            }
        },
        (None, Some(n)) => {
            if n == 0 || !(0.0..1.0).contains(&a.spread) {
                eprintln!("error: --samples must be at least 1 and --spread in [0, 1)");
                return EXIT_INVALID;
            }
            Plan::MonteCarlo {
                samples: n,
                spread: a.spread,
                seed: a.seed,
            }
        }
        (None, None) => {
            eprintln!("error: give --samples N or --grid KEY=START:STOP:STEP");
            return EXIT_INVALID;
        }
    };
    // Every sample's scenario must be valid before anything runs.
    if let Plan::Grid { key, values } = &plan {
        for v in values {
            if let Err(e) = crate::sweep::with_key(&s, key, *v) {
                eprintln!("error: {}: {e}", a.scenario.display());
                return EXIT_INVALID;
            }
        }
    }
    let shard = match a.shard.as_deref().map(Shard::parse).transpose() {
        Ok(sh) => sh,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_INVALID;
        }
    };
    let Some((interrupt, exe)) = interrupt_and_exe() else {
        return EXIT_FAILED;
    };
    let out = a
        .out
        .unwrap_or_else(|| PathBuf::from("out").join(format!("sweep-{}", s.name)));
    let jobs = a.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    let ex = Exec {
        out: out.clone(),
        jobs,
        keep_runs: a.keep_runs,
        exe,
        interrupt,
        progress: !a.quiet,
    };
    let started = std::time::Instant::now();
    let Some(rows) = crate::sweep::run(&s, &plan, shard, &ex) else {
        eprintln!("interrupted; nothing written");
        return EXIT_INTERRUPTED;
    };
    let wall = started.elapsed().as_secs_f64();
    if let Err(e) = crate::sweep::write_outputs(&out, &s, &plan, shard, &rows) {
        eprintln!("error: {}: {e}", out.display());
        return EXIT_FAILED;
    }
    let failed = rows.iter().filter(|r| !r.status.completed()).count();
    if !a.quiet {
        if let Ok(t) = std::fs::read_to_string(out.join("table.md")) {
            println!("{t}");
        }
        println!(
            "{} samples ({} failed) in {wall:.1} s wall with {jobs} parallel runs ({:.2} s per sample)",
            rows.len(),
            failed,
            wall * jobs as f64 / rows.len().max(1) as f64
        );
        println!(
            "wrote {0}/table.md, table.csv, samples.csv, series.csv, sweep.json, plots/",
            out.display()
        );
    }
    0
}

fn bench(scenario: &std::path::Path, duration: f64, out: &std::path::Path) -> i32 {
    let s = match Scenario::load(scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_INVALID;
        }
    };
    if !(duration.is_finite() && duration > 0.0 && duration <= 600.0) {
        eprintln!("error: command line: --duration {duration}: allowed (0, 600] s");
        return EXIT_INVALID;
    }
    let Ok(exe) = std::env::current_exe() else {
        eprintln!("error: cannot find the tiltsim executable to start participants");
        return EXIT_FAILED;
    };
    let scratch = crate::bench::scratch_dir(out);
    let report = crate::bench::run(&s, duration, &exe, &scratch, |name| {
        eprintln!("  measuring {name} ...");
    });
    let _ = std::fs::remove_dir_all(&scratch);
    let report = match report {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: bench: {e}");
            return EXIT_FAILED;
        }
    };
    println!("{}", crate::bench::table(&report));
    if let Some(dir) = out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    if let Err(e) = std::fs::write(
        out,
        serde_json::to_string_pretty(&report).unwrap_or_default() + "\n",
    ) {
        eprintln!("error: {}: {e}", out.display());
        return EXIT_FAILED;
    }
    println!("wrote {}", out.display());
    0
}

fn linearize(
    scenario: &std::path::Path,
    out: Option<&std::path::Path>,
    design: Option<crate::linearize::PiTargets>,
) -> i32 {
    if let Some(t) = design {
        for (flag, v, lo, hi) in [
            ("--phase-margin", t.phase_margin_deg, 0.0, 89.0),
            ("--gain-margin", t.gain_margin_db, 0.0, 40.0),
            ("--ti", t.ti_s, 1e-3, 100.0),
        ] {
            if !(lo..=hi).contains(&v) {
                eprintln!("error: {flag} = {v}: allowed {lo} to {hi}");
                return EXIT_INVALID;
            }
        }
    }
    let s = match Scenario::load(scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_INVALID;
        }
    };
    let report = match crate::linearize::report(&s, design) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {}: controller design: {e}", scenario.display());
            return EXIT_INVALID;
        }
    };
    let text = serde_json::to_string_pretty(&report).unwrap_or_default() + "\n";
    match out {
        Some(p) => match std::fs::write(p, text) {
            Ok(()) => 0,
            Err(e) => {
                eprintln!("error: {}: {e}", p.display());
                EXIT_FAILED
            }
        },
        None => {
            print!("{text}");
            0
        }
    }
}

fn participant(args: &[String]) -> i32 {
    let Some(role) = args.first().and_then(|r| cosim::Role::parse(r)) else {
        eprintln!("usage: tiltsim participant plant|actuator|controller --params JSON --prefix P [--wait W]");
        return EXIT_INVALID;
    };
    let rest = &args[1..];
    let r = match role {
        cosim::Role::Plant => plant_proc::serve(rest),
        cosim::Role::Actuator => actuator_proc::serve(rest),
        cosim::Role::Controller => controller_proc::serve(rest),
    };
    match r {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("{e}");
            EXIT_FAILED
        }
    }
}

fn run(a: RunArgs) -> i32 {
    let mut s = match Scenario::load(&a.scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_INVALID;
        }
    };
    if let Some(t) = a.transport {
        s.run.transport = match t {
            TransportArg::Ipc => Transport::Ipc,
            TransportArg::InProcess => Transport::InProcess,
        };
    }
    if let Some(m) = a.master {
        s.run.master = match m {
            MasterArg::GaussSeidel => Master::GaussSeidel,
            MasterArg::Jacobi => Master::Jacobi,
        };
    }
    if let Some(w) = a.wait {
        s.run.wait = match w {
            WaitArg::Spin => WaitStrategy::Spin,
            WaitArg::Adaptive => WaitStrategy::Adaptive,
            WaitArg::Sleep => WaitStrategy::Sleep,
        };
    }
    if let Some(seed) = a.seed {
        s.run.seed = seed;
    }
    if let Some(d) = a.deadline_ms {
        s.run.deadline_ms = d;
    }
    if let Some(d) = a.duration {
        s.run.duration_s = Some(d);
    }
    let errors = s.validate();
    if !errors.is_empty() {
        for e in errors {
            eprintln!("error: command line: {e}");
        }
        return EXIT_INVALID;
    }
    let out = a.out.unwrap_or_else(|| PathBuf::from("out").join(&s.name));
    let Some((interrupt, exe)) = interrupt_and_exe() else {
        return EXIT_FAILED;
    };
    if let Some(p) = a.pace {
        if !(p.is_finite() && p > 0.0 && p <= 1000.0) {
            eprintln!("error: command line: --pace {p}: allowed a factor in (0, 1000]");
            return EXIT_INVALID;
        }
    }
    let mut overrides = Vec::new();
    for o in &a.participant_exe {
        match o
            .split_once('=')
            .and_then(|(r, p)| Some((cosim::Role::parse(r)?, p)))
        {
            Some((role, path)) => overrides.push((role, PathBuf::from(path))),
            None => {
                eprintln!("error: command line: --participant-exe {o}: expected ROLE=PATH");
                return EXIT_INVALID;
            }
        }
    }
    let opts = RunOptions {
        out_dir: out.clone(),
        participant_exe: exe,
        participant_overrides: overrides,
        ipc_prefix: a.ipc_prefix,
        interrupt,
        plots: true,
        trace: a.trace,
        pace: a.pace,
    };
    let summary = match crate::analysis::run(&s, &a.scenario.display().to_string(), &opts) {
        Ok(sum) => sum,
        Err(e) => {
            eprintln!("error: {e}");
            return EXIT_FAILED;
        }
    };
    let path = out.join("summary.json");
    if let Err(e) = std::fs::write(
        &path,
        serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n",
    ) {
        eprintln!("error: {}: {e}", path.display());
        return EXIT_FAILED;
    }
    if !a.quiet {
        print_report(&summary, &out);
    }
    match summary.status {
        Status::Completed => 0,
        Status::Degraded => {
            eprintln!(
                "warning: a participant was lost and the run continued in degraded mode; see {}",
                out.join("events.csv").display()
            );
            0
        }
        Status::Failed => {
            eprintln!(
                "error: {}; {} of {} steps recorded in {}",
                summary.error.as_deref().unwrap_or("run failed"),
                summary.steps_completed,
                summary.steps_planned,
                out.join("timeseries.csv").display()
            );
            EXIT_FAILED
        }
        Status::Interrupted => {
            eprintln!(
                "interrupted: {} of {} steps recorded",
                summary.steps_completed, summary.steps_planned
            );
            EXIT_INTERRUPTED
        }
    }
}

fn print_report(s: &engine::Summary, out: &std::path::Path) {
    println!(
        "{}: {:?}, {} steps ({:.3} s simulated) in {:.3} s wall ({:.1}x real time)",
        s.scenario,
        s.status,
        s.steps_completed,
        s.simulated_time_s,
        s.wall_time_s,
        s.realtime_factor
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
    println!(
        "  lateral acceleration: peak {:.3} m/s², mid-curve {:.3} m/s²; body roll mid-curve {:.3} deg; peak delta_a {:.3} deg",
        s.results.lat_acc_peak,
        s.results.lat_acc_mid_curve,
        s.results.theta_v_mid_curve.to_degrees(),
        s.results.delta_a_peak.to_degrees()
    );
    let c = &s.comfort;
    println!(
        "  comfort: P_CT standing {:.2} %, seated {:.2} % (whole-run peaks, as the paper; EN 12299 per transition {:.2} / {:.2} %); lateral acceleration RMS deviation {:.3} %g, peak {:.2} %g; jerk {:.2} %g/s",
        c.p_ct.standing,
        c.p_ct.seated,
        c.p_ct_en12299.standing,
        c.p_ct_en12299.seated,
        c.lat_acc_rms_dev_pct_g,
        c.lat_acc_peak_pct_g,
        c.jerk_peak_pct_g_s
    );
    let flags = s.flags.describe();
    if flags.is_empty() {
        println!(
            "  flags: all clear (no oscillation, bump stop, drive limit, chopper duty or P_CT out of range)"
        );
    } else {
        for f in flags {
            println!("  FLAG {f}");
        }
        if s.flags.ride_invalid() {
            println!("  the comfort numbers above do not describe a working tilt system");
        }
    }
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
    }
    if let Some(q) = &s.controller_solver {
        println!(
            "  MPC QP: {} solves, {} failed (previous command held), iterations p50 {:.0}, max {:.0}",
            q.solves, q.failures, q.iterations.p50, q.iterations.max
        );
    }
    println!(
        "  wrote {}/timeseries.csv, summary.json, events.csv, scenario.toml, plots/*.svg|png",
        out.display()
    );
}
