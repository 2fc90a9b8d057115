//! `tiltsim run SCENARIO`: one run, its files and its report.

use std::path::PathBuf;

use super::bounds::{self, End};
use super::common::{interrupt_and_exe, load, MasterArg, TransportArg, WaitArg};
use super::error::{CliError, CliResult};
use tiltsim_master::engine::outputs::{Outputs, ProgressStyle};
use tiltsim_master::engine::{RunOptions, Status, Summary};
use tiltsim_runner::pipeline::{carry_out, Job};
use tiltsim_scenario::scenario::Scenario;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Output directory [default: out/<scenario name>].
    #[arg(long)]
    out: Option<PathBuf>,
    /// Transport, overriding run.transport.
    #[arg(long, value_enum)]
    transport: Option<TransportArg>,
    /// Seed, overriding run.seed.
    #[arg(long, value_parser = bounds::int(0..=u64::MAX, ""))]
    seed: Option<u64>,
    /// Master algorithm, overriding run.master.
    #[arg(long, value_enum)]
    master: Option<MasterArg>,
    /// Wait strategy, overriding run.wait.
    #[arg(long, value_enum)]
    wait: Option<WaitArg>,
    /// Stall deadline in ms, overriding run.deadline_ms.
    #[arg(long, value_parser = bounds::int(1..=60_000u64, " ms"))]
    deadline_ms: Option<u64>,
    /// Simulated duration in s, overriding run.duration_s.
    #[arg(long, value_parser = bounds::real((1e-5, End::Closed), (3600.0, End::Closed), " s"))]
    duration: Option<f64>,
    /// Set a scenario value, KEY=VALUE with KEY a dotted path: a number
    /// (`vehicle.m_v=21000`), a choice or word (`controller.mode=lqg`), true or false, or a
    /// list as in a scenario file (`controller.lqg.q_diag=[0.1, 1000]`); repeatable. The lines of `tiltsim sweep --plan-only` give a sample's settings.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// iceoryx2 file prefix for this run (default: unique per run).
    #[arg(long, hide = true)]
    ipc_prefix: Option<String>,
    /// Write DIR/trace.csv (every exchange: sent, received, step started and finished,
    /// reply sent and received, monotonic ns) and plots/latency_histogram.
    #[arg(long)]
    trace: bool,
    /// Run at FACTOR simulated seconds per wall second (1.0 = real time) and report every
    /// tick that finished late.
    #[arg(long, value_name = "FACTOR", value_parser = bounds::real((1e-6, End::Closed), (1000.0, End::Closed), ""))]
    pace: Option<f64>,
    /// With --pace: run the orchestrator and every participant under the SCHED_FIFO
    /// real-time policy with memory locked (root, CAP_SYS_NICE and CAP_IPC_LOCK, or the
    /// matching ulimits).
    #[arg(long)]
    realtime: bool,
    /// Serve ROLE from another executable (ROLE=PATH; for test participants).
    #[arg(long, hide = true, value_name = "ROLE=PATH")]
    participant_exe: Vec<String>,
    /// `machine`: a JSON line on standard error at every percent of the run (progress, step,
    /// steps, simulated and wall seconds), for wrappers and notebooks.
    #[arg(long, value_enum, value_name = "machine")]
    progress: Option<ProgressArg>,
    /// Record the run as DIR/run.mcap (every participant's inputs and outputs, every link as
    /// sent and received, the events and the summary; opens in Foxglove, Rerun, `mcap`).
    #[arg(long)]
    record: bool,
    /// Free running (run.execution = "free", IPC only): every participant steps on its own
    /// wall-clock timer and reads the newest input that has arrived; the real timing goes to
    /// DIR/timing.csv, which `tiltsim replay-timing DIR` replays exactly in lock-step.
    #[arg(long)]
    free_run: bool,
    /// Serve ROLE from another host (adds it to network.remote; repeatable): the run waits
    /// for `tiltsim participant ROLE --connect ADDRESS` started there (docs/network.md).
    #[arg(long, value_enum, value_name = "ROLE")]
    remote: Vec<RoleArg>,
    /// Where the run listens for participants on other hosts, overriding network.listen
    /// (`HOST:PORT`, e.g. 10.0.0.1:7447; the link is QUIC, TLS 1.3 with the run's
    /// credentials, on that UDP port).
    #[arg(long, value_name = "HOST:PORT")]
    listen: Option<String>,
    /// File holding the secret participants on other hosts prove they hold [default: the
    /// TILTSIM_SECRET variable, or a secret drawn for the run and printed with the command
    /// that joins].
    #[arg(long, value_name = "PATH")]
    secret_file: Option<PathBuf>,
    /// Draw no figures (`tiltsim plot DIR` draws them later from the run's files).
    #[arg(long)]
    no_plots: bool,
    /// Print nothing but errors: no progress bar, no warnings, no report.
    #[arg(short, long)]
    quiet: bool,
}

/// A participant's role on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoleArg {
    /// The vehicle and track.
    Plant,
    /// The drive.
    Actuator,
    /// The tilt controller.
    Controller,
}

impl From<RoleArg> for cosim::Role {
    fn from(r: RoleArg) -> Self {
        match r {
            RoleArg::Plant => cosim::Role::Plant,
            RoleArg::Actuator => cosim::Role::Actuator,
            RoleArg::Controller => cosim::Role::Controller,
        }
    }
}

/// The run's secret for participants on other hosts: `--secret-file`, else `TILTSIM_SECRET`,
/// else none (the engine draws one).
fn network_secret(a: &RunArgs) -> Result<Option<String>, CliError> {
    let secret = match &a.secret_file {
        Some(path) => Some(
            std::fs::read_to_string(path)
                .map_err(|e| {
                    CliError::Invalid(format!(
                        "command line: --secret-file {}: {e}",
                        path.display()
                    ))
                })?
                .trim()
                .to_string(),
        ),
        None => std::env::var(tiltsim_net::serve::SECRET_VAR).ok(),
    };
    match secret {
        Some(s) if s.trim().is_empty() => Err(CliError::Invalid(match &a.secret_file {
            Some(path) => format!(
                "command line: --secret-file {}: the file is empty",
                path.display()
            ),
            None => format!("{} is set but empty", tiltsim_net::serve::SECRET_VAR),
        })),
        other => Ok(other.map(|s| s.trim().to_string())),
    }
}

impl RunArgs {
    /// `--quiet`: nothing but errors (the log too).
    pub fn quiet(&self) -> bool {
        self.quiet
    }
}

/// `--progress`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum ProgressArg {
    /// JSON lines on standard error.
    Machine,
}

/// The scenario with the command line's overrides, validated again.
fn scenario(a: &RunArgs) -> Result<Scenario, CliError> {
    let mut s = load(&a.scenario)?;
    if let Some(t) = a.transport {
        s.run.transport = t.into();
    }
    if let Some(m) = a.master {
        s.run.master = m.into();
    }
    if let Some(w) = a.wait {
        s.run.wait = w.into();
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
    if a.free_run {
        s.run.execution = tiltsim_scenario::scenario::Execution::Free;
    }
    for &r in &a.remote {
        let r = cosim::Role::from(r);
        if !s.network.remote.contains(&r) {
            s.network.remote.push(r);
        }
    }
    if let Some(l) = &a.listen {
        tiltsim_protocol::address::Address::parse(l).map_err(|why| {
            CliError::Invalid(format!(
                "command line: --listen {l}: {why}; expected {}",
                tiltsim_protocol::address::ADDRESS_FORM
            ))
        })?;
        s.network.listen = l.clone();
    }
    for kv in &a.set {
        let bad = || CliError::Invalid(format!("command line: --set {kv}: expected KEY=VALUE"));
        let (k, v) = kv.split_once('=').ok_or_else(bad)?;
        s = s
            .with_setting(k.trim(), v)
            .map_err(|e| CliError::Invalid(format!("command line: --set {kv}: {e}")))?;
    }
    let errors = s.validate();
    if !errors.is_empty() {
        let lines: Vec<String> = errors
            .iter()
            .map(|e| format!("command line: {e}"))
            .collect();
        return Err(CliError::Invalid(lines.join("\nerror: ")));
    }
    check_network(a, &s)?;
    if a.pace.is_some() {
        // Between paced ticks the participants nap instead of keeping the cores busy.
        if a.wait.is_none() && s.run.wait == cosim::wait::WaitStrategy::Adaptive {
            s.run.wait = cosim::wait::WaitStrategy::Paced;
        }
    }
    let free = s.run.execution == tiltsim_scenario::scenario::Execution::Free;
    if free {
        for (given, flag) in [(a.pace.is_some(), "--pace"), (a.trace, "--trace")] {
            if given {
                return Err(CliError::Invalid(format!(
                    "command line: {flag}: not available with run.execution = \"free\" (a free run keeps its own clock; its timing goes to timing.csv)"
                )));
            }
        }
    }
    if a.realtime && a.pace.is_none() {
        // Unpaced, real-time processes poll for as long as the run lasts: only the kernel's
        // real-time throttling keeps a share of each CPU for everything else.
        cosim::realtime::throttled().map_err(|e| {
            CliError::Invalid(format!("command line: --realtime without --pace: {e}"))
        })?;
    }
    Ok(s)
}

/// `--listen` asks for participants on other hosts, so it needs one; the address must be one
/// this host can listen on, said in words before the network transport tries.
fn check_network(a: &RunArgs, s: &Scenario) -> Result<(), CliError> {
    if s.network.is_local() {
        if let Some(l) = &a.listen {
            return Err(CliError::Invalid(format!(
                "command line: --listen {l}: no participant runs on another host, so the run would not listen; add --remote ROLE (or network.remote in the scenario)"
            )));
        }
        return Ok(());
    }
    let where_from = if a.listen.is_some() {
        "command line: --listen".to_string()
    } else {
        format!("{}: network.listen", a.scenario.display())
    };
    let address = tiltsim_protocol::address::Address::parse(&s.network.listen)
        .map_err(|why| CliError::Invalid(format!("{where_from} {}: {why}", s.network.listen)))?;
    tiltsim_net::session::check_listen(&address)
        .map_err(|why| CliError::Invalid(format!("{where_from} {}: {why}", s.network.listen)))
}

/// `--participant-exe ROLE=PATH` overrides.
fn overrides(a: &RunArgs) -> Result<Vec<(cosim::Role, PathBuf)>, CliError> {
    a.participant_exe
        .iter()
        .map(|o| {
            o.split_once('=')
                .and_then(|(r, p)| Some((cosim::Role::parse(r)?, PathBuf::from(p))))
                .ok_or_else(|| {
                    CliError::Invalid(format!(
                        "command line: --participant-exe {o}: expected ROLE=PATH"
                    ))
                })
        })
        .collect()
}

/// Runs the command; `verbose` (`-v`) prints every timing figure in the report.
pub fn exec(a: RunArgs, verbose: bool) -> CliResult {
    let s = scenario(&a)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("out").join(&s.name));
    let (interrupt, exe) = interrupt_and_exe()?;
    let realtime = if a.realtime {
        cosim::realtime::enter(cosim::realtime::PRIORITY)
            .map_err(|e| CliError::Invalid(format!("command line: --realtime: {e}")))?;
        Some(cosim::realtime::PRIORITY)
    } else {
        None
    };
    let opts = RunOptions {
        out_dir: out.clone(),
        participant_exe: exe,
        participant_overrides: overrides(&a)?,
        ipc_prefix: a.ipc_prefix.clone(),
        interrupt,
        plots: !a.no_plots,
        pace: a.pace,
        realtime,
        timing: true,
        network_secret: network_secret(&a)?,
    };
    // A person watching gets a bar, unless quiet or reading the machine lines.
    let bar = !a.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut job = Job::new(&s, a.scenario.display().to_string(), opts);
    job.outputs = Outputs {
        trace: a.trace,
        record: a.record,
        progress: match a.progress {
            Some(_) => Some(ProgressStyle::Lines),
            None => bar.then_some(ProgressStyle::Bar),
        },
        ..Outputs::default()
    };
    let done = carry_out(job).map_err(CliError::of_job)?;
    report(&done, &s, &out, a.quiet, verbose)
}

/// Prints a finished run's warnings and report (neither when `quiet`; every timing figure
/// when `verbose`) and gives its exit.
pub(super) fn report(
    done: &tiltsim_runner::pipeline::Done,
    s: &Scenario,
    out: &std::path::Path,
    quiet: bool,
    verbose: bool,
) -> CliResult {
    if !quiet {
        for w in &done.warnings {
            eprintln!("warning: {w}");
        }
        super::report::print(&done.summary, s, out, done.replaced_earlier_run, verbose);
    }
    outcome(&done.summary, out, quiet)
}

/// The exit of a finished run, by its status; a degraded run warns unless `quiet`.
fn outcome(summary: &Summary, out: &std::path::Path, quiet: bool) -> CliResult {
    match summary.status {
        Status::Completed => Ok(()),
        Status::Degraded => {
            if !quiet {
                eprintln!(
                    "warning: a participant was lost and the run continued in degraded mode; see {}",
                    out.join("events.csv").display()
                );
            }
            Ok(())
        }
        Status::Failed => Err(CliError::Failed(format!(
            "{}; {} of {} steps recorded in {}",
            summary.error.as_deref().unwrap_or("run failed"),
            summary.steps_completed,
            summary.steps_planned,
            out.join("timeseries.csv").display()
        ))),
        Status::Interrupted => Err(CliError::Interrupted(format!(
            "interrupted: {} of {} steps recorded",
            summary.steps_completed, summary.steps_planned
        ))),
    }
}
