//! The lock-step engine: owns simulated time and steps the participants tick by tick.
//!
//! A run is composed of small parts, one concern per file:
//! * [`launch`]: the participants' settings, their start on either transport, their shut-down;
//! * [`team`]: the participants handle the master algorithm works through, with the
//!   manipulators on the way ([`manipulator`]: scheduled faults, degraded replacement; link
//!   effects in `crate::links`);
//! * [`algorithm`]: the master algorithms, Gauss-Seidel and Jacobi;
//! * [`instruments`]: the engine's own measurements: timing, compute, latency, pacing and drive
//!   events;
//! * [`observe`]: the [`Observer`](observe::Observer) trait a caller implements and adds to a
//!   [`Run`], with its lifecycle (start, each tick, close, finish with its part of the
//!   summary); [`outputs`]: the rows, trace, recording and progress as observers;
//! * [`manipulate`]: the [`Manipulator`](manipulate::Manipulator) trait: what acts on the
//!   participants and the values in flight (link effects, scheduled faults, degraded
//!   stand-ins, and the caller's own), in an ordered list the caller extends;
//! * [`cpu_plan`]: where the participants' processes run; [`mcap`]: `run.mcap`;
//! * [`summary`]: the schema of `summary.json`.
//!
//! A [`Run`] is built by the caller (`Run::new(..).add_observer(..).add_manipulator(..)
//! .simulate()`); [`run`] is its short form with the rows written to `timeseries.csv`. It reads as: launch, loop, shut down, report. Analysis of the recorded series (quick
//! look, comfort, flags, figures) is the caller's step (`tiltsim_report::analysis`).

pub(crate) mod algorithm;
pub mod cpu_plan;
pub(crate) mod instruments;
pub(crate) mod launch;
pub mod machine;
pub mod manipulate;
pub(crate) mod manipulator;
pub mod mcap;
pub mod observe;
mod options;
pub mod outputs;
pub(crate) mod session;
pub mod summary;
pub(crate) mod team;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use cosim::LinkError;
use tiltsim_formats::events::EventLog;
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::Scenario;

pub use launch::{finish_logs, Inits};
pub use options::{RunError, RunOptions, Status};
pub use summary::{
    CpuTime, LinkLatency, PacingReport, ParticipantReport, QuickLook, RunMode, SolverReport,
    Summary, Timing,
};

pub use instruments::LatencyHistogram;
use instruments::{
    ComputeStats, DriveEvents, FinishedTick, Instrument, Latency, Pacing, TickTiming,
};
use launch::Held;
use outputs::Outputs;
use session::{Closed, Session};
use team::Team;

/// The observers of one run: the engine's own measurements, then the caller's list.
struct Observers {
    timing: TickTiming,
    compute: ComputeStats,
    latency: Latency,
    drive: DriveEvents,
    pacing: Option<Pacing>,
    cpu_plan: Option<cpu_plan::CpuPlanner>,
    /// The caller's observers (the outputs among them), in the order added.
    list: Vec<Box<dyn observe::Observer>>,
    /// Ticks every observer was told about.
    ticks: u64,
    /// Base tick (s), for the times the caller's observers see.
    dt: f64,
}

impl Observers {
    fn new(s: &Scenario, opts: &RunOptions, list: Vec<Box<dyn observe::Observer>>) -> Self {
        Observers {
            cpu_plan: None,
            timing: TickTiming::default(),
            compute: ComputeStats::default(),
            latency: Latency::default(),
            drive: DriveEvents::default(),
            pacing: opts
                .pace
                .map(|f| Pacing::new(f, s.run.dt_s, opts.realtime.is_some())),
            list,
            ticks: 0,
            dt: s.run.dt_s,
        }
    }

    /// Tells the caller's observers the outputs at the start time (before the first tick).
    fn at_start(&mut self, s: &Scenario, held: &Held) -> std::io::Result<()> {
        let start = observe::Start {
            scenario: &s.name,
            dt_s: s.run.dt_s,
            steps: s.steps(),
            plant: &held.p,
            actuator: &held.a,
            controller: &held.c,
        };
        for o in &mut self.list {
            o.start(&start)?;
        }
        Ok(())
    }

    fn before_tick(&mut self, k: u64) {
        if let Some(p) = &mut self.pacing {
            p.before_tick(k);
        }
    }

    /// Tells every observer about tick `t.k`, in this order: the timing first, so that a tick's
    /// wall time ends with its exchanges (as the coordination overhead is defined), then the
    /// engine's other measurements, then the caller's list. No allocation per tick.
    fn after_tick(&mut self, t: &FinishedTick, ev: &mut EventLog) -> std::io::Result<()> {
        self.timing.after_tick(t, ev)?;
        if let Some(p) = &mut self.pacing {
            p.after_tick(t, ev)?;
        }
        self.compute.after_tick(t, ev)?;
        self.latency.after_tick(t, ev)?;
        self.drive.after_tick(t, ev)?;
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
            exchanges: t.exchanges,
            events: &ev.events,
        };
        for o in &mut self.list {
            o.tick(&tick)?;
        }
        self.ticks = t.k + 1;
        Ok(())
    }

    /// Closes the caller's observers; every error, in their order.
    fn close(&mut self) -> Vec<std::io::Error> {
        self.list
            .iter_mut()
            .filter_map(|o| o.close().err())
            .collect()
    }

    /// The ticks done and held whole by every observer.
    fn ticks_kept(&self) -> u64 {
        self.list
            .iter()
            .filter_map(|o| o.ticks_kept())
            .fold(self.ticks, u64::min)
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
/// depend only on them: Jacobi's every request, Gauss-Seidel's first of the chain) go out
/// (under Jacobi those that need no actuator reply already before it, `finish_early`),
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
        // The next tick's requests, with their events kept for after this tick's; the
        // algorithm may begin them before this tick's last reply is in.
        let more = k + 1 < steps && !interrupt.load(Ordering::Relaxed);
        let mut next_events = team.events.aside();
        let ahead = more.then(|| algorithm::Next {
            k: k + 1,
            due: due(k + 1),
            events: &mut next_events,
        });
        let (io, begun) = algorithm.finish_early(team, posted, ahead)?;
        let h = team.held;
        let tick_exchanges = std::mem::take(&mut team.exchanges);
        let mut next = None;
        let next_started = Instant::now();
        if more {
            std::mem::swap(&mut team.events, &mut next_events);
            next = Some(match begun {
                Some(b) => algorithm.resume(team, b),
                None => post(team, k + 1),
            });
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

/// Runs a validated scenario with its rows written to `timeseries.csv`: launch, loop, shut
/// down, report. Always writes what it has to `out_dir` (`timeseries.csv`, `events.csv`,
/// `columns.csv`, `scenario.toml`); the returned summary says whether the run completed. The
/// participants are shut down and the shared-memory files removed before any output after the
/// loop is written, so a write that fails (a full disk) is reported in the summary and never
/// skips the clean-up. `results`, `comfort` and `flags` are left for the caller's analysis
/// (`tiltsim_report::analysis::analyse`). For other outputs, build a [`Run`].
pub fn run(s: &Scenario, scenario_file: &str, opts: &RunOptions) -> Result<Summary, RunError> {
    session::prepare(s, opts)?;
    let made = Outputs::default()
        .observers(s, &opts.out_dir)
        .map_err(|(path, source)| RunError::Io { path, source })?;
    let mut run = Run::new(s, scenario_file, opts);
    for o in made.observers {
        run = run.add_observer(o);
    }
    Ok(run.simulate()?.summary)
}

/// What a [`Run`] returns.
pub struct Ran {
    /// The run's summary (not yet analysed).
    pub summary: Summary,
    /// Every event of the run (`events.csv`), for a recording closed after the analysis.
    pub events: EventLog,
    /// The request latency binned for a histogram figure (when the run measured wall-clock
    /// times, `RunOptions::timing`).
    pub latency_histogram: Option<LatencyHistogram>,
}

/// A lock-step run as the caller builds it: the scenario, the options, and the observers in
/// the order they are told about each tick (the outputs among them: [`outputs`]).
///
/// ```no_run
/// # use tiltsim_master::engine::{observe, outputs, Run, RunOptions};
/// # fn f(s: &tiltsim_scenario::scenario::Scenario, mine: Box<dyn observe::Observer>) {
/// let opts = RunOptions::new("out/mine".into(), "tiltsim".into());
/// std::fs::create_dir_all(&opts.out_dir).unwrap();
/// let csv = outputs::Rows::to_file(&opts.out_dir.join("timeseries.csv"), s.run.dt_s).unwrap();
/// let ran = Run::new(s, "mine.toml", &opts)
///     .add_observer(Box::new(csv))
///     .add_observer(mine)
///     .simulate();
/// # }
/// ```
pub struct Run<'a> {
    s: &'a Scenario,
    scenario_file: &'a str,
    opts: &'a RunOptions,
    observers: Vec<Box<dyn observe::Observer>>,
    manipulators: Vec<Box<dyn manipulate::Manipulator>>,
}

impl<'a> Run<'a> {
    /// A run of `s` (read from `scenario_file`, as the summary names it) with `opts`, with
    /// no observers and the scenario's own manipulators (link effects, scheduled faults,
    /// degraded stand-ins).
    pub fn new(s: &'a Scenario, scenario_file: &'a str, opts: &'a RunOptions) -> Self {
        Run {
            s,
            scenario_file,
            opts,
            observers: Vec::new(),
            manipulators: Vec::new(),
        }
    }

    /// Adds an observer after those added before.
    pub fn add_observer(mut self, o: Box<dyn observe::Observer>) -> Self {
        self.observers.push(o);
        self
    }

    /// Adds a manipulator after the scenario's own and those added before.
    pub fn add_manipulator(mut self, m: Box<dyn manipulate::Manipulator>) -> Self {
        self.manipulators.push(m);
        self
    }

    /// Runs the lock-step to its end (or to the failure or interrupt that ends it early), as
    /// [`run`] describes, with the observers' parts in the summary.
    pub fn simulate(self) -> Result<Ran, RunError> {
        observe::distinct_names(&self.observers)?;
        simulate(self)
    }
}

fn simulate(run: Run<'_>) -> Result<Ran, RunError> {
    let Run {
        s,
        scenario_file,
        opts,
        observers,
        manipulators,
    } = run;
    let (session, ps) = Session::start(s, opts, true)?;
    let mut team = Team::new(s, ps, manipulators);
    team.timed = opts.timing;
    let mut obs = Observers::new(s, opts, observers);
    obs.cpu_plan = cpu_plan::CpuPlanner::new(s, team.ps.placement.as_ref());
    let pids: Vec<u32> = team.ps.pids().iter().map(|(_, p)| *p).collect();
    let at_start = machine::Snapshot::take(&pids, session.cpus());
    let loop_started = Instant::now();
    let mut outcome = lockstep(&mut team, &mut obs, &opts.interrupt);
    let wall = loop_started.elapsed().as_secs_f64();
    let at_end = machine::Snapshot::take(&pids, session.cpus());
    let load = machine::load_average().and_then(|l| {
        let cpus = session.cpus().len();
        machine::MachineLoad::between(&at_start, &at_end, wall, l, cpus, opts.realtime.is_some())
    });
    // The analysis and the files after the loop run at ordinary priority.
    if opts.realtime.is_some() {
        cosim::realtime::leave();
    }
    // Outputs after the loop: each failure is kept for the summary, none skips another.
    let mut write_errors = Vec::new();
    for e in obs.close() {
        match outcome {
            Ok(()) => outcome = Err(Stop::Write(e)),
            Err(_) => write_errors.push(e.to_string()),
        }
    }
    let rows = obs.ticks_kept();
    if let Err(Stop::Link(e)) = &outcome {
        team.log_failure(rows, e);
    }
    let mut events = std::mem::take(&mut team.events);
    let degraded = team.degraded();
    let lost = team.take_lost();
    let dir = session.dir();
    let closed = session.close(team.into_participants(), lost);
    closed.write_files(dir, &mut events, &mut write_errors);
    let latency_histogram = opts.timing.then(|| obs.latency.request_histogram());
    let mut list = std::mem::take(&mut obs.list);
    let mut summary = Summary::blank(s, scenario_file, summary::RunMode::LockStep);
    (summary.status, summary.error) = session::status(&outcome, degraded, &opts.interrupt);
    closed.fill(s, &mut summary, Some(obs.compute.percentiles()));
    report(&mut summary, obs, &closed, rows, wall);
    summary.timing.machine = load;
    for o in &mut list {
        if let Some(part) = o.finish(&summary) {
            summary.observers.insert(o.name().to_string(), part);
        }
    }
    session::fail_on_write_error(&mut summary, &write_errors);
    Ok(Ran {
        summary,
        events,
        latency_histogram,
    })
}

/// The lock-step's own part of `summary.json`: progress, timing, latency, pacing and the
/// controller's solver.
fn report(sm: &mut Summary, mut obs: Observers, closed: &Closed, rows: u64, wall: f64) {
    sm.set_progress(rows, wall);
    sm.timing = timing(&mut obs, closed);
    sm.link_latency = obs.latency.report();
    sm.pacing = obs.pacing.as_mut().map(|p| p.report(rows, wall));
    sm.controller_solver = obs.compute.solver();
}

/// The coordination overhead, tick times, CPU plan and CPU time of the run.
fn timing(obs: &mut Observers, e: &Closed) -> Timing {
    let o = obs.timing.overhead.percentiles();
    Timing {
        p50: o.p50,
        p99: o.p99,
        max: o.max,
        mean: o.mean,
        tick_us: obs.timing.ticks.percentiles(),
        cpu_plan: obs.cpu_plan.as_ref().and_then(|p| p.report()),
        machine: None,
        placement: e.placement.clone(),
        hand_over: e.hand_over,
        cpu_s: CpuTime::new(e.cpu_orchestrator_s, e.exits.iter().map(|(_, x)| x.cpu_s)),
    }
}
