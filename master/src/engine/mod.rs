//! The lock-step engine: owns simulated time and steps the participants tick by tick.
//!
//! A run is composed of small parts, one concern per file:
//! * [`launch`]: the participants' settings, their start on either transport, their shut-down;
//! * [`team`]: the participants handle the master algorithm works through, with the
//!   manipulators on the way ([`manipulator`]: scheduled faults, degraded replacement; link
//!   effects in `crate::links`);
//! * [`algorithm`]: the master algorithms, Gauss-Seidel and Jacobi;
//! * [`observer`]: the recorder, timing, compute, latency, trace, pacing and drive events;
//! * [`observe`]: the [`Observer`](observe::Observer) trait a caller implements and adds to a
//!   [`Run`], with its lifecycle (start, each tick, finish with its part of the summary);
//! * [`cpu_plan`]: where the participants' processes run; [`mcap`]: `run.mcap`;
//! * [`summary`]: the schema of `summary.json`.
//!
//! A [`Run`] is built by the caller (`Run::new(..).add_observer(..).simulate()`); [`run`] and
//! [`run_recorded`] are its short forms. It reads as: launch, loop, shut down, report. Analysis of the recorded series (quick
//! look, comfort, flags, figures) is the caller's step (`tiltsim_report::analysis`).

pub(crate) mod algorithm;
pub mod cpu_plan;
pub(crate) mod launch;
pub(crate) mod manipulator;
pub mod mcap;
pub mod observe;
pub(crate) mod observer;
mod options;
pub mod summary;
pub(crate) mod team;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use cosim::msg::now_ns;
use cosim::{LinkError, Role};

pub use launch::{finish_logs, Inits};
pub use options::{RunError, RunOptions, Status};
pub use summary::{
    CpuTime, LinkLatency, PacingReport, ParticipantReport, QuickLook, RunMode, SolverReport,
    Summary, Timing,
};

use crate::events::EventLog;
use crate::roles::RoleMap;
use crate::scenario::{Scenario, Transport};
use crate::table::{Recorder, Row};
use launch::Held;
pub use observer::LatencyHistogram;
use observer::{
    ComputeStats, DriveEvents, FinishedTick, Latency, Observer, Pacing, RowRecorder, RowSink,
};
use observer::{TickTiming, Trace};
use team::Team;

/// The observers of one run.
struct Observers {
    recorder: RowRecorder,
    timing: TickTiming,
    compute: ComputeStats,
    latency: Latency,
    drive: DriveEvents,
    trace: Option<Trace>,
    pacing: Option<Pacing>,
    progress: Option<observer::Progress>,
    ticks_done: Option<std::sync::Arc<std::sync::atomic::AtomicU64>>,
    mcap: Option<mcap::McapRecorder>,
    cpu_plan: Option<cpu_plan::CpuPlanner>,
    /// The caller's observers, in the order added.
    user: Vec<Box<dyn observe::Observer>>,
    /// Base tick (s), for the times the caller's observers see.
    dt: f64,
}

impl Observers {
    fn new(s: &Scenario, opts: &RunOptions, out: Outputs) -> Self {
        let Outputs {
            recorder,
            trace,
            mcap,
        } = out;
        Observers {
            recorder,
            cpu_plan: None,
            timing: TickTiming::default(),
            compute: ComputeStats::default(),
            latency: Latency::default(),
            drive: DriveEvents::default(),
            trace,
            mcap,
            progress: if opts.machine_progress {
                Some(observer::Progress::new(s.steps(), s.run.dt_s))
            } else if opts.progress_bar {
                Some(observer::Progress::bar(s.steps(), s.run.dt_s))
            } else {
                None
            },
            ticks_done: opts.ticks_done.clone(),
            pacing: opts
                .pace
                .map(|f| Pacing::new(f, s.run.dt_s, opts.realtime.is_some())),
            user: Vec::new(),
            dt: s.run.dt_s,
        }
    }

    /// Tells the caller's observers and the recorders the outputs at the start time (before
    /// the first tick).
    fn at_start(&mut self, s: &Scenario, held: &Held) -> std::io::Result<()> {
        let start = observe::Start {
            scenario: &s.name,
            dt_s: s.run.dt_s,
            steps: s.steps(),
            plant: &held.p,
            actuator: &held.a,
            controller: &held.c,
        };
        for o in &mut self.user {
            o.start(&start)?;
        }
        if let Some(m) = &mut self.mcap {
            m.at_start(&held.p, &held.a)?;
        }
        self.recorder.at_start(held)
    }

    fn before_tick(&mut self, k: u64) {
        if let Some(p) = &mut self.pacing {
            p.before_tick(k);
        }
    }

    /// Tells every observer about tick `t.k`, in this order: the timing first, so that a tick's
    /// wall time ends with its exchanges (as the coordination overhead is defined), the
    /// recorder last. Static calls: no allocation per tick.
    fn after_tick(&mut self, t: &FinishedTick, ev: &mut EventLog) -> std::io::Result<()> {
        self.timing.after_tick(t, ev)?;
        if let Some(p) = &mut self.pacing {
            p.after_tick(t, ev)?;
        }
        self.compute.after_tick(t, ev)?;
        self.latency.after_tick(t, ev)?;
        self.drive.after_tick(t, ev)?;
        if let Some(tr) = &mut self.trace {
            tr.after_tick(t, ev)?;
        }
        if let Some(p) = &mut self.progress {
            p.after_tick(t, ev)?;
        }
        if let Some(n) = &self.ticks_done {
            n.store(t.k + 1, std::sync::atomic::Ordering::Relaxed);
        }
        if !self.user.is_empty() {
            let tick = observe::Tick {
                k: t.k,
                time: cosim::time::tick_time(t.k + 1, self.dt),
                plant: &t.held.p,
                actuator: &t.held.a,
                controller: &t.held.c,
                controller_stepped: t.controller_due,
                to_controller: t.controller_due.then_some(t.to_controller),
                sent: observe::LinkValues::from_ordered(t.tx),
                received: observe::LinkValues::from_ordered(t.rx),
            };
            for o in &mut self.user {
                o.tick(&tick)?;
            }
        }
        if let Some(m) = &mut self.mcap {
            m.after_tick(t, ev)?;
        }
        self.recorder.after_tick(t, ev)
    }
}

/// Why the lock-step stopped before its last tick.
#[derive(Debug, thiserror::Error)]
pub(crate) enum Stop {
    /// A participant or its link failed.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// An output could not be written; the message names the file and the system's error.
    #[error("cannot write {0}")]
    Write(std::io::Error),
}

/// Steps every tick; returns the error that stopped the run, if any.
fn lockstep(team: &mut Team, obs: &mut Observers, interrupt: &AtomicBool) -> Result<(), Stop> {
    let s = team.scenario();
    if obs.pacing.is_none() {
        return lockstep_pipelined(team, obs, interrupt);
    }
    // The Init exchanges stay in `team.exchanges`: the observers see them with tick 0's.
    team.initialise()?;
    obs.at_start(s, &team.held).map_err(Stop::Write)?;
    let algorithm = algorithm::of(s.run.master);
    let c_period = s.controller_period_ticks();
    for k in 0..s.steps() {
        if interrupt.load(Ordering::Relaxed) {
            return Ok(());
        }
        obs.before_tick(k);
        let started = Instant::now();
        team.inject_faults(k);
        let due = k % c_period == 0;
        let io = algorithm.tick(team, k, due)?;
        let h = team.held;
        let compute = RoleMap::new([
            h.p.header.compute_ns,
            h.a.header.compute_ns,
            if due { h.c.header.compute_ns } else { 0 },
        ]);
        let record = FinishedTick {
            k,
            held: &h,
            rx: &io.rx,
            tx: &io.tx,
            to_controller: &io.to_controller,
            controller_due: due,
            critical_us: algorithm.critical_path(compute.clone().into_array()) as f64 * 1e-3,
            compute_ns: compute,
            started,
            exchanges: &team.exchanges,
        };
        let recording = Instant::now();
        obs.after_tick(&record, &mut team.events)
            .map_err(Stop::Write)?;
        let own_ns = recording.elapsed().as_nanos() as u64;
        if let Some(plan) = &mut obs.cpu_plan {
            plan.observe(&record.compute_ns, own_ns, &mut team.ps);
        }
        team.exchanges.clear();
    }
    Ok(())
}

/// Pipelined: as soon as tick `k`'s replies are in, tick `k + 1`'s first requests (which
/// depend only on them: Jacobi's every request, Gauss-Seidel's first of the chain) go out,
/// and tick `k` is recorded while the participants compute. Every value, row and event is the one the plain loop gives, in the same order
/// (events of posting `k + 1`, link effects and faults, are kept aside and logged after tick
/// `k`'s); only wall-clock placement changes. Not used when paced: a paced tick's requests
/// wait for its wall-clock time.
fn lockstep_pipelined(
    team: &mut Team,
    obs: &mut Observers,
    interrupt: &AtomicBool,
) -> Result<(), Stop> {
    let s = team.scenario();
    team.initialise()?;
    obs.at_start(s, &team.held).map_err(Stop::Write)?;
    let c_period = s.controller_period_ticks();
    let steps = s.steps();
    let due = |k: u64| k.is_multiple_of(c_period);
    let algorithm = algorithm::of(s.run.master);
    let post = |team: &mut Team, k: u64| -> Result<algorithm::Pending, LinkError> {
        team.inject_faults(k);
        algorithm.start(team, k, due(k))
    };
    if steps == 0 || interrupt.load(Ordering::Relaxed) {
        return Ok(());
    }
    // A tick's wall time, as the overhead is defined, is the time spent starting it plus the
    // time from turning to it (after recording the one before) to its last reply: recording
    // is not coordination, here as in the plain loop.
    let t0 = Instant::now();
    let mut posted = post(team, 0)?;
    let mut post_time = t0.elapsed();
    for k in 0..steps {
        let now = Instant::now();
        let started = now.checked_sub(post_time).unwrap_or(now);
        let io = algorithm.finish(team, posted)?;
        let h = team.held;
        let tick_exchanges = std::mem::take(&mut team.exchanges);
        // The next tick's requests, with their events kept for after this tick's.
        let mut next = None;
        let mut next_events = team.events.aside();
        let next_started = Instant::now();
        if k + 1 < steps && !interrupt.load(Ordering::Relaxed) {
            std::mem::swap(&mut team.events, &mut next_events);
            next = Some(post(team, k + 1));
            std::mem::swap(&mut team.events, &mut next_events);
        }
        let next_post_time = next_started.elapsed();
        let compute = RoleMap::new([
            h.p.header.compute_ns,
            h.a.header.compute_ns,
            if due(k) { h.c.header.compute_ns } else { 0 },
        ]);
        let record = FinishedTick {
            k,
            held: &h,
            rx: &io.rx,
            tx: &io.tx,
            to_controller: &io.to_controller,
            controller_due: due(k),
            critical_us: algorithm.critical_path(compute.clone().into_array()) as f64 * 1e-3,
            compute_ns: compute,
            // The timing observer measures to now: the start is moved on by the time spent
            // starting tick k + 1, which is not tick k's.
            started: started + next_post_time,
            exchanges: &tick_exchanges,
        };
        let recording = Instant::now();
        obs.after_tick(&record, &mut team.events)
            .map_err(Stop::Write)?;
        let own_ns = recording.elapsed().as_nanos() as u64;
        if let Some(plan) = &mut obs.cpu_plan {
            plan.observe(&record.compute_ns, own_ns, &mut team.ps);
        }
        team.events.append(next_events);
        match next {
            None => return Ok(()),
            Some(p) => posted = p?,
        }
        post_time = next_post_time;
    }
    Ok(())
}

/// The files a run writes as it goes.
struct Outputs {
    recorder: RowRecorder,
    trace: Option<Trace>,
    mcap: Option<mcap::McapRecorder>,
}

/// A run's `run.mcap`, still open for the events and the analysed summary.
pub struct Recording {
    rec: mcap::McapRecorder,
    events: EventLog,
}

impl Recording {
    /// Writes the events and `summary`, and closes the file; returns its path.
    pub fn finish(self, summary: &Summary) -> std::io::Result<std::path::PathBuf> {
        self.rec.finish(&self.events, summary)
    }
}

/// The files a run writes as it goes: the output directory, `timeseries.csv` (header first),
/// `trace.csv` with `--trace` (header first), `run.mcap` with `--record`, and
/// `scenario.toml` (the scenario as run).
fn create_outputs(s: &Scenario, opts: &RunOptions) -> Result<Outputs, RunError> {
    let dir = &opts.out_dir;
    std::fs::create_dir_all(dir).map_err(RunError::io(dir.clone()))?;
    let rec = if opts.keep_rows {
        RowSink::Kept(Vec::with_capacity(s.steps() as usize + 1))
    } else {
        let csv = dir.join("timeseries.csv");
        RowSink::File(Box::new(Recorder::create(&csv).map_err(RunError::io(csv))?))
    };
    let rec = RowRecorder::new(s.run.dt_s, rec);
    let trace = if opts.trace {
        let path = dir.join("trace.csv");
        Some(Trace::create(&path, now_ns(), s.run.dt_s).map_err(RunError::io(path))?)
    } else {
        None
    };
    let mcap = if opts.record {
        let path = dir.join("run.mcap");
        Some(mcap::McapRecorder::create(&path, s.run.dt_s).map_err(RunError::io(path))?)
    } else {
        None
    };
    let resolved = dir.join("scenario.toml");
    crate::files::write_atomic(&resolved, toml::to_string(s).unwrap_or_default())
        .map_err(RunError::io(resolved))?;
    Ok(Outputs {
        recorder: rec,
        trace,
        mcap,
    })
}

/// What a finished loop leaves for the report.
struct Ended {
    outcome: Result<(), Stop>,
    wall: f64,
    cpu_orchestrator: f64,
    exits: RoleMap<cosim::endpoint::ExitReport>,
    pids: RoleMap<u32>,
    counts: RoleMap<cosim::endpoint::ExchangeCounts>,
    leftover: Vec<String>,
    participant_logs: Vec<String>,
    degraded: bool,
}

/// Stops every participant, removes the run's shared-memory files and the empty participant
/// logs in `out_dir`, and restores this process's CPU set.
fn shut_down(
    mut team: Team,
    out_dir: &std::path::Path,
    prefix: &str,
    cpus: &[usize],
    outcome: Result<(), Stop>,
    wall: f64,
    cpu0: f64,
) -> Ended {
    let pids = team.ps.pids();
    let counts = team.ps.counts();
    let lost = team.take_lost();
    let exits = team.ps.shut_down(lost);
    // FMUs unpacked by participant processes that were killed.
    if !team.scenario().participants.is_empty() {
        tiltsim_fmi::archive::remove_dead_unpacked();
    }
    let degraded = team.degraded();
    let mut leftover = Vec::new();
    let mut participant_logs = Vec::new();
    if let Some(hub) = team.ps.hub.take() {
        hub.cleanup_dead();
        drop(team);
        drop(hub);
        cosim::ipc::remove_run_files(prefix);
        leftover = cosim::ipc::leftover_files(prefix)
            .iter()
            .map(|p| p.display().to_string())
            .collect();
        participant_logs = finish_logs(out_dir);
    }
    if !cpus.is_empty() {
        cosim::ipc::set_cpus(cpus);
    }
    Ended {
        outcome,
        wall,
        cpu_orchestrator: launch::cpu_self() - cpu0,
        exits,
        pids,
        counts,
        leftover,
        participant_logs,
        degraded,
    }
}

/// Removes a run's shared-memory files when dropped: on every way out of [`run`], a failed
/// start, an error, a panic, as well as the normal end (where [`shut_down`] has already
/// removed them and reported any it could not).
struct RunFilesGuard(String);

impl Drop for RunFilesGuard {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            cosim::ipc::remove_run_files(&self.0);
        }
    }
}

/// Runs a validated scenario: launch, loop, shut down, report. Always writes what it has to
/// `out_dir` (`timeseries.csv`, `events.csv`, `scenario.toml`, `trace.csv` with `--trace`);
/// the returned summary says whether the run completed. The participants are shut down and
/// the shared-memory files removed before any output after the loop is written, so a write
/// that fails (a full disk) is reported in the summary and never skips the clean-up.
/// `results`, `comfort` and `flags` are left for the caller's analysis
/// (`tiltsim_report::analysis::analyse`).
pub fn run(s: &Scenario, scenario_file: &str, opts: &RunOptions) -> Result<Summary, RunError> {
    let Ran {
        summary, recording, ..
    } = run_recorded(s, scenario_file, opts)?;
    if let Some(r) = recording {
        if let Err(e) = r.finish(&summary) {
            tracing::warn!("recording not completed: {e}");
        }
    }
    Ok(summary)
}

/// What [`run_recorded`] returns.
pub struct Ran {
    /// The run's summary (not yet analysed).
    pub summary: Summary,
    /// `run.mcap` (with `--record`), open for the caller to finish with the analysed summary.
    pub recording: Option<Recording>,
    /// The rows, when kept in memory (`RunOptions::keep_rows`) instead of `timeseries.csv`.
    pub rows: Option<Vec<Row>>,
    /// With `--trace`: the request latency binned for the caller's histogram figure.
    pub latency_histogram: Option<LatencyHistogram>,
}

/// [`run`], leaving `run.mcap` (with `--record`) open for the caller to finish with the
/// analysed summary, and handing back the rows kept in memory.
pub fn run_recorded(s: &Scenario, scenario_file: &str, opts: &RunOptions) -> Result<Ran, RunError> {
    Run::new(s, scenario_file, opts).simulate()
}

/// A lock-step run as the caller builds it: the scenario, the options, and the caller's
/// observers in the order they are told about each tick.
///
/// ```no_run
/// # use tiltsim_master::engine::{observe, Run, RunOptions};
/// # fn f(s: &tiltsim_master::scenario::Scenario, mine: Box<dyn observe::Observer>) {
/// let opts = RunOptions::new("out/mine".into(), "tiltsim".into());
/// let ran = Run::new(s, "mine.toml", &opts).add_observer(mine).simulate();
/// # }
/// ```
pub struct Run<'a> {
    s: &'a Scenario,
    scenario_file: &'a str,
    opts: &'a RunOptions,
    observers: Vec<Box<dyn observe::Observer>>,
}

impl<'a> Run<'a> {
    /// A run of `s` (read from `scenario_file`, as the summary names it) with `opts`.
    pub fn new(s: &'a Scenario, scenario_file: &'a str, opts: &'a RunOptions) -> Self {
        Run {
            s,
            scenario_file,
            opts,
            observers: Vec::new(),
        }
    }

    /// Adds an observer after those added before.
    pub fn add_observer(mut self, o: Box<dyn observe::Observer>) -> Self {
        self.observers.push(o);
        self
    }

    /// Runs the lock-step to its end (or to the failure or interrupt that ends it early), as
    /// [`run_recorded`] describes, with the observers' parts in the summary.
    pub fn simulate(self) -> Result<Ran, RunError> {
        let names: Vec<&str> = self.observers.iter().map(|o| o.name()).collect();
        if let Some(dup) = names
            .iter()
            .enumerate()
            .find_map(|(i, n)| names[..i].contains(n).then_some(*n))
        {
            return Err(RunError::Observer(format!(
                "two observers are named `{dup}`; each needs its own name (its key in summary.json)"
            )));
        }
        simulate(self.s, self.scenario_file, self.opts, self.observers)
    }
}

fn simulate(
    s: &Scenario,
    scenario_file: &str,
    opts: &RunOptions,
    observers: Vec<Box<dyn observe::Observer>>,
) -> Result<Ran, RunError> {
    let outputs = create_outputs(s, opts)?;
    let prefix = match s.run.transport {
        Transport::Ipc => opts
            .ipc_prefix
            .clone()
            .unwrap_or_else(cosim::ipc::unique_prefix),
        Transport::InProcess => String::new(),
    };
    let _files = RunFilesGuard(prefix.clone());
    let cpu0 = launch::cpu_self();
    // `start` may pin this process to one CPU for the run; the set is restored afterwards so
    // a process that runs several scenarios (sweeps, benchmarks) starts each one alike.
    let cpus = cosim::ipc::allowed_cpus();
    let ps = launch::start(s, opts, &prefix).inspect_err(|_| {
        // Participants that were started are stopped by now; the log of one that ended while
        // starting stays (its error quotes its last line).
        if s.run.transport == Transport::Ipc {
            finish_logs(&opts.out_dir);
        }
    })?;
    let mut team = Team::new(s, ps);
    team.timed = opts.timing;
    let mut obs = Observers::new(s, opts, outputs);
    obs.user = observers;
    obs.cpu_plan = cpu_plan::CpuPlanner::new(s, &cpus);
    let loop_started = Instant::now();
    let mut outcome = lockstep(&mut team, &mut obs, &opts.interrupt);
    let wall = loop_started.elapsed().as_secs_f64();
    // The analysis and the files after the loop run at ordinary priority.
    if opts.realtime.is_some() {
        cosim::realtime::leave();
    }
    let finished = obs.recorder.finish();
    if let (Ok(()), Err(e)) = (&outcome, finished) {
        outcome = Err(Stop::Write(e));
    }
    let rows = obs.recorder.ticks();
    let kept = obs.recorder.take_kept();
    if let Err(Stop::Link(e)) = &outcome {
        team.log_failure(rows, e);
    }
    let mut events = EventLog::default();
    std::mem::swap(&mut events, &mut team.events);
    let ended = shut_down(team, &opts.out_dir, &prefix, &cpus, outcome, wall, cpu0);
    // Outputs after the loop: each failure is kept for the summary, none skips another.
    let mut write_errors = Vec::new();
    if let Err(e) = events.write(&opts.out_dir.join("events.csv")) {
        write_errors.push(e);
    }
    if let Err(e) = crate::columns::write_run(&opts.out_dir) {
        write_errors.push(e);
    }
    let mut latency_histogram = None;
    if let Some(tr) = &mut obs.trace {
        match tr.finish() {
            Ok(()) => latency_histogram = Some(obs.latency.request_histogram()),
            Err(e) => write_errors.push(e),
        }
    }
    let mcap = obs.mcap.take();
    let mut user = std::mem::take(&mut obs.user);
    let mut summary = report(s, scenario_file, opts, &prefix, obs, ended, rows);
    for o in &mut user {
        if let Some(part) = o.finish(&summary) {
            summary.observers.insert(o.name().to_string(), part);
        }
    }
    if let Some(e) = write_errors.first() {
        if summary.error.is_none() {
            summary.status = Status::Failed;
            summary.error = Some(format!("cannot write {e}"));
        }
    }
    Ok(Ran {
        summary,
        recording: mcap.map(|rec| Recording { rec, events }),
        rows: kept,
        latency_histogram,
    })
}

/// The run's own part of `summary.json`.
fn report(
    s: &Scenario,
    scenario_file: &str,
    opts: &RunOptions,
    prefix: &str,
    mut obs: Observers,
    e: Ended,
    rows: u64,
) -> Summary {
    let (status, error) = status(&e, opts);
    let mut sm = Summary::blank(s, scenario_file, summary::RunMode::LockStep);
    sm.status = status;
    sm.error = error;
    sm.participants = participants(s, &mut obs, &e);
    sm.set_progress(rows, e.wall);
    sm.timing = timing(&mut obs, &e);
    sm.link_latency = obs.latency.report();
    sm.pacing = obs.pacing.as_mut().map(|p| p.report(rows, e.wall));
    sm.controller_solver = obs.compute.solver();
    sm.ipc_prefix = prefix.to_string();
    sm.leftover_ipc_files = e.leftover;
    sm.participant_logs = e.participant_logs;
    sm
}

/// How the run ended, in the summary's words: an interrupt (even one that ended a
/// participant first), a degraded run, a completion or a failure.
fn status(e: &Ended, opts: &RunOptions) -> (Status, Option<String>) {
    match &e.outcome {
        Ok(_) if opts.interrupt.load(Ordering::Relaxed) => (
            Status::Interrupted,
            Some(format!("interrupted by {}", crate::signals::describe())),
        ),
        Ok(_) if e.degraded => (
            Status::Degraded,
            Some("a participant was lost; the run continued degraded (events.csv)".into()),
        ),
        Ok(_) => (Status::Completed, None),
        // A signal to the whole process group (systemd, Slurm's scancel, a container
        // runtime) reaches the participants too, and they end first: the run was
        // interrupted, not failed by them.
        Err(err) if opts.interrupt.load(Ordering::Relaxed) => (
            Status::Interrupted,
            Some(format!(
                "interrupted by {} ({err})",
                crate::signals::describe()
            )),
        ),
        Err(err) => (Status::Failed, Some(err.to_string())),
    }
}

/// Each participant's part of the summary: process, period, exit, compute and exchanges.
fn participants(s: &Scenario, obs: &mut Observers, e: &Ended) -> Vec<ParticipantReport> {
    let periods = RoleMap::new([s.run.dt_s, s.run.dt_s, s.controller.period_s]);
    let compute = obs.compute.percentiles();
    Role::ALL
        .into_iter()
        .map(|role| ParticipantReport {
            role,
            process: role.process_name(),
            pid: e.pids[role],
            period_s: periods[role],
            exit: e.exits[role].clone(),
            compute_us: compute[role],
            starved_waits: e.counts[role].starved_waits,
            lost_samples: e.counts[role].lost_samples,
        })
        .collect()
}

/// The coordination overhead, tick times, CPU plan and CPU time of the run.
fn timing(obs: &mut Observers, e: &Ended) -> Timing {
    let o = obs.timing.overhead.percentiles();
    Timing {
        p50: o.p50,
        p99: o.p99,
        max: o.max,
        mean: o.mean,
        tick_us: obs.timing.ticks.percentiles(),
        cpu_plan: obs.cpu_plan.as_ref().and_then(|p| p.report()),
        cpu_s: CpuTime {
            orchestrator: e.cpu_orchestrator,
            participants: e.exits.iter().filter_map(|(_, x)| x.cpu_s).sum(),
        },
    }
}
