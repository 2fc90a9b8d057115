//! `tiltsim replay-timing DIR`: the exact lock-step replay of a free run's timing.

use std::path::PathBuf;

use super::common::{interrupt_and_exe, load, TransportArg};
use super::error::{CliError, CliResult};
use tiltsim_master::engine::RunOptions;
use tiltsim_runner::pipeline::{carry_out, Job};
use tiltsim_scenario::scenario::Transport;

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
    /// Print nothing but errors: no warnings, no report.
    #[arg(short, long)]
    quiet: bool,
    /// Draw no figures.
    #[arg(long)]
    no_plots: bool,
}

impl ReplayTimingArgs {
    /// `--quiet`: nothing but errors (the log too).
    pub fn quiet(&self) -> bool {
        self.quiet
    }
}

/// Runs `replay-timing`; `verbose` (`-v`) as for `run`.
pub fn replay_timing(a: ReplayTimingArgs, verbose: bool) -> CliResult {
    let file = a
        .scenario
        .clone()
        .unwrap_or_else(|| a.run_dir.join("scenario.toml"));
    let mut s = load(&file)?;
    tiltsim_runner::pipeline::as_timing_replay(&mut s);
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
    let (interrupt, exe) = interrupt_and_exe()?;
    let mut opts = RunOptions::new(out.clone(), exe);
    opts.interrupt = interrupt;
    opts.plots = !a.no_plots;
    let trace = a.run_dir.join(tiltsim_master::free::trace::TIMING_CSV);
    // Nothing is written for a run still going on, its directory included.
    tiltsim_master::free::trace::refuse_if_live(&trace)
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    let mut job = Job::new(&s, file.display().to_string(), opts);
    job.replay_trace = Some(trace);
    let done = carry_out(job).map_err(CliError::of_job)?;
    super::run::report(&done, &s, &out, a.quiet, verbose)
}
