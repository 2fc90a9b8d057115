//! The `tiltsim` command line: one file per command, one error type ([`CliError`]) mapped to
//! the exit code in one place ([`main`]).
//!
//! Exit codes: 0 success; 1 the run failed (a participant died, stalled or sent bad data);
//! 2 invalid input (command line or scenario file); 130 interrupted (Ctrl-C, SIGTERM, SIGHUP).

mod bench;
mod bench_concurrent;
mod bench_network;
mod bounds;
mod clean;
mod common;
mod compare;
mod completions;
mod error;
mod export_fmu;
mod export_mcap;
mod export_ssp;
mod falsify;
mod falsify_merge;
mod free_run;
mod inspect;
mod linearize;
mod log;
mod new;
mod participant;
mod plot;
mod replay;
mod report;
mod route;
mod run;
mod sweep;
mod sweep_merge;
mod validate;

#[cfg(test)]
mod definition_tests;

use clap::{CommandFactory, Parser, Subcommand};

pub use error::{CliError, CliResult, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_INVALID};

#[derive(Parser, Debug)]
#[command(
    name = "tiltsim",
    version,
    about = "Co-simulator for active tilt control of railway vehicles"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// More log output (repeat for more); `run` and `replay-timing` also print every timing
    /// figure of the run (processes, coordination overhead, compute, link latency).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a scenario and write DIR/timeseries.csv, DIR/summary.json, DIR/scenario.toml.
    Run(run::RunArgs),
    /// Check a scenario file without running it.
    Validate(validate::ValidateArgs),
    /// Write a commented scenario file to start from (NAME.toml), valid as written.
    New(new::NewArgs),
    /// Run several scenarios and write DIR/table.md and DIR/table.csv laid out like the
    /// paper's Table 4 (each run's files go to DIR/<scenario name>/).
    Compare(compare::CompareArgs),
    /// Redraw the figures (DIR/plots/*.svg and *.png) of a finished run, compare or sweep.
    Plot(plot::PlotArgs),
    /// Robustness or parameter sweep: many runs in parallel, a table of comfort metrics
    /// (median, 5th and 95th percentile) and plots in DIR. Either --samples (Monte Carlo
    /// over masses, inertias and suspension, Fig. 21) or --grid KEY=START:STOP:STEP.
    Sweep(sweep::SweepArgs),
    /// Merge the outputs of `tiltsim sweep --shard i/n` runs into the whole sweep's files.
    SweepMerge(sweep_merge::SweepMergeArgs),
    /// Run scenarios over a whole line (a route file): speed profiles and journey times,
    /// P_CT at every transition, N_MV on the straights, motion-sickness doses, the limit that
    /// binds at each curve; with --rho and --cd-tilting, the compensation trade-off.
    Route(route::RouteArgs),
    /// Search the admissible timing (per-link delay range, jitter, loss and freeze budgets,
    /// or the envelope of recorded free runs) for the one that hurts the ride most: CMA-ES
    /// against uniform random sampling with the same budget; the worst timing is written as
    /// DIR/worst/timing.csv, which `replay-timing DIR/worst` replays exactly.
    Falsify(falsify::FalsifyArgs),
    /// Merge the outputs of `tiltsim falsify --shard i/n` runs into one search's files: the
    /// worst over the shards (replayed again in DIR/worst), the progress and the result.
    FalsifyMerge(falsify_merge::FalsifyMergeArgs),
    /// Measure this machine: the iceoryx2 round-trip floor, the per-tick coordination
    /// overhead of every master algorithm and wait strategy, and in-process vs IPC wall time.
    Bench(bench::BenchArgs),
    /// Summarise the linear design model (modes: frequencies, damping) and the scenario
    /// controller's gains and loop; with --design-pi, design a PI for the drive and print its
    /// gains first. --json prints the whole report (matrices, eigenvalues, gains) as JSON.
    Linearize(linearize::LinearizeArgs),
    /// Remove the shared-memory files of runs whose orchestrator was killed (never a live
    /// run's; every IPC run does this when it starts).
    Clean(clean::CleanArgs),
    /// Run one participant of a run recorded with `run --record` alone against the inputs it
    /// received, and report where its outputs differ from the recording.
    Replay(replay::ReplayArgs),
    /// Replay a free run's timing (RUN_DIR/timing.csv) exactly, in lock-step: every step fed
    /// the producer outputs it read in the free run; RUN_DIR/replay-timing/timeseries.csv
    /// equals the free run's byte for byte (with --scenario: the same timing, another system).
    ReplayTiming(free_run::ReplayTimingArgs),
    /// Write a finished run's files as RUN_DIR/run.mcap (the channels of `run --record`).
    ExportMcap(export_mcap::ExportMcapArgs),
    /// Write one participant of a scenario as an FMI 3.0 co-simulation FMU (its inputs and
    /// outputs are the participant's sample fields, its parameters the scenario's values).
    ExportFmu(export_fmu::ExportFmuArgs),
    /// Write a scenario as an SSP 1.0 system for other co-simulation masters (libcosim,
    /// OMSimulator): its three participants as FMI 2.0 FMUs and SystemStructure.ssd with their
    /// connections, parameters and steps.
    ExportSsp(export_ssp::ExportSspArgs),
    /// List what an FMU declares: version, interfaces, steps, and every variable with its
    /// causality, type, unit and description.
    Inspect(inspect::InspectArgs),
    /// Print the completion script of a shell (bash, zsh, fish, elvish, powershell).
    Completions(completions::CompletionsArgs),
    /// The echo side of `bench --ping-pong`.
    #[command(hide = true)]
    BenchEcho(bench::EchoArgs),
    /// The echo side of `bench --network`.
    #[command(hide = true)]
    BenchNetEcho(bench_network::NetEchoArgs),
    /// Serve one participant: on another host, join a run with `--connect ENDPOINT` and the
    /// run's secret (TILTSIM_SECRET or `--secret-file`); on this host the orchestrator starts
    /// it over iceoryx2 itself.
    Participant(participant::ParticipantArgs),
    /// Serve an FMU as one participant over iceoryx2 (`[participants.<role>] fmu = ...`).
    #[command(hide = true)]
    FmuParticipant(participant::ParticipantArgs),
}

impl Command {
    /// How much the command logs: `-q` of `run` and `replay-timing` keeps errors only; a
    /// participant process, whose standard error is its log file, times every line.
    fn verbosity(&self, verbose: u8) -> log::Verbosity {
        let quiet = match self {
            Command::Run(a) => a.quiet(),
            Command::ReplayTiming(a) => a.quiet(),
            _ => false,
        };
        let detailed = matches!(
            self,
            Command::Participant(_)
                | Command::FmuParticipant(_)
                | Command::BenchEcho(_)
                | Command::BenchNetEcho(_)
        );
        log::Verbosity {
            verbose,
            quiet,
            detailed,
        }
    }
}

/// Adds the closest allowed value to an error about a value an option does not take when clap
/// found none (its Jaro similarity misses a swap in a short name: `--controller mcp`), so
/// that the message ends "tip: a similar value exists: 'mpc'".
fn suggest_value(e: &mut clap::Error) {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if e.kind() != ErrorKind::InvalidValue || e.get(ContextKind::SuggestedValue).is_some() {
        return;
    }
    let (Some(ContextValue::String(given)), Some(ContextValue::Strings(allowed))) = (
        e.get(ContextKind::InvalidValue),
        e.get(ContextKind::ValidValue),
    ) else {
        return;
    };
    let near =
        tiltsim_scenario::scenario::suggest::closest(given, allowed.iter().map(String::as_str))
            .map(str::to_string);
    if let Some(near) = near {
        e.insert(ContextKind::SuggestedValue, ContextValue::String(near));
    }
}

/// Runs the program with the process's arguments; returns the exit code.
pub fn main() -> i32 {
    main_from(std::env::args_os())
}

/// Runs the program with `args` (the program's name first); returns the exit code.
pub fn main_from<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(mut e) => {
            suggest_value(&mut e);
            let _ = e.print();
            return if e.use_stderr() { EXIT_INVALID } else { 0 };
        }
    };
    log::init(cli.command.verbosity(cli.verbose));
    let verbose = cli.verbose > 0;
    if matches!(
        cli.command,
        Command::Validate(_) | Command::New(_) | Command::Inspect(_) | Command::Completions(_)
    ) {
        tiltsim_rundir::signals::end_quietly_on_closed_pipe();
    }
    let result = match cli.command {
        Command::Run(a) => run::exec(a, verbose),
        Command::Validate(a) => validate::exec(a),
        Command::New(a) => new::exec(a),
        Command::Inspect(a) => inspect::exec(a),
        Command::Completions(a) => completions::exec(a, &mut Cli::command()),
        Command::Compare(a) => compare::exec(a),
        Command::Plot(a) => plot::exec(a),
        Command::ReplayTiming(a) => free_run::replay_timing(a, verbose),
        Command::Sweep(a) => sweep::exec(a),
        Command::SweepMerge(a) => sweep_merge::exec(a),
        Command::Route(a) => route::exec(a),
        Command::Falsify(a) => falsify::exec(a),
        Command::FalsifyMerge(a) => falsify_merge::exec(a),
        Command::Bench(a) => bench::exec(a),
        Command::Linearize(a) => linearize::exec(a),
        Command::Clean(a) => clean::exec(a),
        Command::Replay(a) => replay::exec(a),
        Command::BenchEcho(a) => bench::echo(a),
        Command::BenchNetEcho(a) => bench_network::echo(a),
        Command::ExportMcap(a) => export_mcap::exec(a),
        Command::Participant(a) => participant::exec(a),
        Command::FmuParticipant(a) => participant::exec_fmu(a),
        Command::ExportFmu(a) => export_fmu::exec(a),
        Command::ExportSsp(a) => export_ssp::exec(a),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("{e}");
            e.exit_code()
        }
    }
}
