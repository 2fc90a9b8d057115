//! The orchestrator of a free run: the hub that relays the newest outputs without waiting,
//! and records every step's timing.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::Ordering;
use std::time::Duration;

use cosim::endpoint::check_reply;
use cosim::msg::{now_ns, FromActuator, FromController, FromPlant, Header, Kind, Message};
use cosim::msg::{FreeClock, ToActuator, ToController, ToPlant, FLAG_FREE_START};
use cosim::{Endpoint, LinkError, ProcessFault, Role};

use super::compose::Store;
use super::trace::{age, col, inputs_of, StepTrace, TraceHead, TraceWriter, TIMING_CSV};
use super::{init_all, FilesGuard, FreeError, RowStream};
use crate::engine::launch::{self, Participants};
use crate::engine::manipulator::FaultSchedule;
use crate::engine::{RunOptions, Status};
use crate::faults::FaultAction;
use crate::links::LinkId;
use crate::roles::RoleMap;
use crate::scenario::Scenario;

/// A free run is judged not real-time when one of its plant steps started later than this
/// many base ticks after it was due.
pub const NOT_REAL_TIME_TICKS: u64 = 10;

/// Time from sending the start requests to the common start instant: the participants are
/// connected and waiting, so this only has to cover the delivery of three samples.
const START_MARGIN: Duration = Duration::from_millis(50);

/// Pause of the hub between two polls that found nothing.
const HUB_NAP: Duration = Duration::from_micros(20);

/// Relays one consumer's inputs and remembers which producer steps each carried.
#[derive(Default)]
struct Relay {
    next: u64,
    sent: VecDeque<(u64, [Option<i64>; 3])>,
}

impl Relay {
    fn send<I: Message, O: Message>(
        &mut self,
        ep: &mut Box<dyn Endpoint<I, O>>,
        mut req: I,
        from: [Option<i64>; 3],
    ) -> Result<(), LinkError> {
        req.header_mut().relay = self.next;
        self.sent.push_back((self.next, from));
        self.next += 1;
        ep.send(&req)
    }

    /// The producer steps of the oldest relay the consumer may still read.
    fn oldest(&self) -> Option<[Option<i64>; 3]> {
        self.sent.front().map(|(_, f)| *f)
    }

    /// The producer steps of relay `n`; older relays are forgotten (a consumer reads newer
    /// relays only).
    fn take(&mut self, n: u64) -> Option<[Option<i64>; 3]> {
        while self.sent.front().is_some_and(|(m, _)| *m < n) {
            self.sent.pop_front();
        }
        self.sent.front().filter(|(m, _)| *m == n).map(|(_, f)| *f)
    }
}

/// Per-role timing statistics of a free run (wall clock), in constant memory.
#[derive(Default)]
struct RoleTiming {
    lateness_us: cosim::stats::Timings,
    late_start: u64,
    late_finish: u64,
}

/// One role's wall-clock timing in a free run.
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct RoleFreeTiming {
    /// Steps recorded.
    pub steps: u64,
    /// How long after it was due each step read its input (µs).
    pub start_lateness_us: cosim::stats::Percentiles,
    /// Steps that started after the next one was due.
    pub late_starts: u64,
    /// Steps published after the next one was due.
    pub late_finishes: u64,
}

/// The distribution of one link's input ages over its consumer's steps (ticks; see
/// [`super::trace::age`]).
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct AgeDistribution {
    /// Youngest.
    pub min: i64,
    /// Median.
    pub p50: i64,
    /// 99th percentile.
    pub p99: i64,
    /// Oldest.
    pub max: i64,
    /// `[age, steps]` pairs in increasing age.
    pub counts: Vec<[i64; 2]>,
}

impl AgeDistribution {
    fn of(h: &BTreeMap<i64, u64>) -> Self {
        let n: u64 = h.values().sum();
        let at = |q: f64| {
            let want = ((n.saturating_sub(1)) as f64 * q).round() as u64;
            let mut seen = 0;
            for (a, c) in h {
                seen += c;
                if seen > want {
                    return *a;
                }
            }
            0
        };
        AgeDistribution {
            min: h.keys().next().copied().unwrap_or(0),
            p50: at(0.5),
            p99: at(0.99),
            max: h.keys().next_back().copied().unwrap_or(0),
            counts: h.iter().map(|(a, c)| [*a, *c as i64]).collect(),
        }
    }
}

/// The wall-clock side of a free run: whether it kept real time, each role's lateness and each
/// link's input ages (all of it differs from one free run to the next; the replay of the trace
/// is what repeats).
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct FreeTiming {
    /// A plant step started more than [`NOT_REAL_TIME_TICKS`] ticks after it was due: the run
    /// did not keep real time, and its ride is not the answer to a real-time question.
    pub not_real_time: bool,
    /// That margin (s).
    pub not_real_time_margin_s: f64,
    /// The plant's largest start lateness (s).
    pub plant_max_lateness_s: f64,
    /// Per participant.
    pub participants: BTreeMap<String, RoleFreeTiming>,
    /// Per link, by its `[links]` name.
    pub input_age_ticks: BTreeMap<String, AgeDistribution>,
    /// The CPU each participant was pinned to (empty when not pinned).
    pub cpus: BTreeMap<String, usize>,
}

/// What a free run reports beyond its files.
pub struct FreeReport {
    /// How the run ended.
    pub status: Status,
    /// Why it failed or stopped, naming the participant.
    pub error: Option<String>,
    /// Rows in `timeseries.csv` after the one at the start time.
    pub steps_completed: u64,
    /// Wall time from the start instant to the end of the relays (s).
    pub wall_time_s: f64,
    /// The timing the run had.
    pub timing: FreeTiming,
    /// Each participant's process id and exit.
    pub exits: RoleMap<cosim::endpoint::ExitReport>,
    /// Each participant's process id.
    pub pids: RoleMap<u32>,
    /// The run's iceoryx2 prefix.
    pub ipc_prefix: String,
    /// Shared-memory files left behind (empty unless something is wrong).
    pub leftover_ipc_files: Vec<String>,
    /// The rows, when kept in memory (`RunOptions::keep_rows`).
    pub rows: Option<Vec<crate::record::Row>>,
    /// `run.mcap` (`--record`), to be closed with the summary.
    pub recording: Option<super::record::FreeRecording>,
    /// Files that could not be written (each named), besides the run's own outcome.
    pub write_errors: Vec<String>,
    /// Participant logs that are not empty (`logs/<role>.log`).
    pub participant_logs: Vec<String>,
}

/// The link a consumer reads from a producer, by its `[links]` name.
fn link_name(consumer: Role, producer: Role) -> &'static str {
    match (consumer, producer) {
        (Role::Actuator, Role::Controller) => "actuator_command",
        (Role::Plant, _) => "bar_angle",
        (Role::Controller, _) => "measurement",
        _ => "bar_twist",
    }
}

/// Runs `s` free over IPC: streams `timing.csv` and `timeseries.csv` to `opts.out_dir` as the
/// steps come in, then writes `events.csv`, `columns.csv` and `scenario.toml`.
pub fn run(s: &Scenario, opts: &RunOptions) -> Result<FreeReport, FreeError> {
    let dir = &opts.out_dir;
    std::fs::create_dir_all(dir).map_err(|e| FreeError::io(dir, e))?;
    let resolved = dir.join("scenario.toml");
    crate::files::write_atomic(&resolved, toml::to_string(s).unwrap_or_default())
        .map_err(|e| FreeError::io(&resolved, e))?;
    let prefix = opts
        .ipc_prefix
        .clone()
        .unwrap_or_else(cosim::ipc::unique_prefix);
    let guard = FilesGuard(prefix.clone());
    let cpus = cosim::ipc::allowed_cpus();
    let ps = launch::start(s, opts, &prefix).map_err(FreeError::Run)?;
    let placement = place(s, &ps, &cpus);
    let mut hub = Hub::new(s, opts, ps)?;
    let outcome = hub.run();
    let last_ns = now_ns();
    let Hub {
        ps,
        store,
        rows,
        writer,
        stats,
        kept,
        start_ns,
        ..
    } = hub;
    let mut write_errors = Vec::new();
    let path = dir.join(TIMING_CSV);
    if let Some(Err(e)) = writer.map(TraceWriter::finish) {
        write_errors.push(format!("{}: {e}", path.display()));
    }
    let pids = ps.pids();
    let exits = shut_down(ps, &prefix, &cpus);
    drop(guard);
    let participant_logs = crate::engine::finish_logs(dir);
    let leftover: Vec<String> = cosim::ipc::leftover_files(&prefix)
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let (ticks, kept_rows, rows_error) = rows.finish();
    write_errors.extend(rows_error);
    let events = super::run_events(s, &store, ticks);
    let events_csv = dir.join("events.csv");
    if let Err(e) = events.write(&events_csv) {
        write_errors.push(format!("{}: {e}", events_csv.display()));
    }
    if let Err(e) = crate::columns::write_run(dir) {
        write_errors.push(format!("{}: {e}", dir.join("columns.csv").display()));
    }
    let recording = match kept {
        Some(kept) => {
            let path = dir.join("run.mcap");
            let r =
                super::record::record(&path, s.run.dt_s, &store, &kept, ticks, start_ns, &events)
                    .map_err(|e| FreeError::io(&path, e))?;
            Some(r)
        }
        None => None,
    };
    let interrupted = opts.interrupt.load(Ordering::Relaxed);
    let (status, error) = match outcome {
        Ok(()) if interrupted => (
            Status::Interrupted,
            Some(format!("interrupted by {}", crate::signals::describe())),
        ),
        Ok(()) => (Status::Completed, None),
        Err(e) if interrupted => (
            Status::Interrupted,
            Some(format!(
                "interrupted by {} ({e})",
                crate::signals::describe()
            )),
        ),
        Err(e) => (Status::Failed, Some(e)),
    };
    let mut timing = stats.report(s.run.dt_s);
    timing.cpus = placement;
    Ok(FreeReport {
        status,
        error,
        steps_completed: ticks,
        wall_time_s: last_ns.saturating_sub(start_ns) as f64 * 1e-9,
        timing,
        exits,
        pids,
        ipc_prefix: prefix,
        leftover_ipc_files: leftover,
        rows: kept_rows,
        recording,
        write_errors,
        participant_logs,
    })
}

/// The timing statistics a free run gathers as its steps come in.
#[derive(Default)]
struct Stats {
    roles: RoleMap<RoleTiming>,
    ages: BTreeMap<&'static str, BTreeMap<i64, u64>>,
    dt_ns: u64,
    period: u64,
}

impl Stats {
    fn note(&mut self, t: &StepTrace) {
        let ticks = if t.role == Role::Controller {
            self.period
        } else {
            1
        };
        let rt = &mut self.roles[t.role];
        rt.lateness_us
            .record(t.read_ns.saturating_sub(t.due_ns) as f64 * 1e-3);
        rt.late_start += u64::from(t.late_start(ticks * self.dt_ns));
        rt.late_finish += u64::from(t.late_finish(ticks * self.dt_ns));
        for &p in inputs_of(t.role) {
            if let Some(f) = t.from[col(p)] {
                *self
                    .ages
                    .entry(link_name(t.role, p))
                    .or_default()
                    .entry(age(p, t.step, f))
                    .or_default() += 1;
            }
        }
    }

    fn report(&self, dt_s: f64) -> FreeTiming {
        let participants: BTreeMap<String, RoleFreeTiming> = Role::ALL
            .iter()
            .map(|&r| {
                let t = &self.roles[r];
                let p = t.lateness_us.percentiles();
                (
                    r.name().to_string(),
                    RoleFreeTiming {
                        steps: t.lateness_us.len() as u64,
                        start_lateness_us: p,
                        late_starts: t.late_start,
                        late_finishes: t.late_finish,
                    },
                )
            })
            .collect();
        let plant_max_s = self.roles[Role::Plant].lateness_us.percentiles().max * 1e-6;
        let margin_s = NOT_REAL_TIME_TICKS as f64 * dt_s;
        FreeTiming {
            not_real_time: plant_max_s > margin_s,
            not_real_time_margin_s: margin_s,
            plant_max_lateness_s: plant_max_s,
            participants,
            input_age_ticks: self
                .ages
                .iter()
                .map(|(l, h)| (l.to_string(), AgeDistribution::of(h)))
                .collect(),
            cpus: BTreeMap::new(),
        }
    }
}

/// The CPU of each participant in a free run, when pinned: the controller keeps the
/// participants' CPU to itself, as a controller computer of its own, and the plant and the
/// actuator (a few µs each per millisecond, woken by their timers) move to the orchestrator's,
/// so the controller's compute, however long, never delays the vehicle or its drive, nor the
/// hub's relays it (in lock-step all three share one CPU, since only one computes at a time).
/// Empty when not pinned.
fn place(s: &Scenario, ps: &Participants, cpus: &[usize]) -> BTreeMap<String, usize> {
    let (Some(&first), Some(&last)) = (cpus.first(), cpus.last()) else {
        return BTreeMap::new();
    };
    if !s.run.pin_cpus || first == last {
        return BTreeMap::new();
    }
    let pids = ps.pids();
    let mut placed = BTreeMap::new();
    for (r, cpu) in [
        (Role::Plant, first),
        (Role::Actuator, first),
        (Role::Controller, last),
    ] {
        if cosim::ipc::set_cpus_of(pids[r], &[cpu]) {
            placed.insert(r.name().to_string(), cpu);
        }
    }
    placed
}

/// Stops the participants and removes the run's files; returns their exits.
fn shut_down(
    mut ps: Participants,
    prefix: &str,
    cpus: &[usize],
) -> RoleMap<cosim::endpoint::ExitReport> {
    let exits = ps.shut_down(RoleMap::default());
    if let Some(hub) = ps.hub.take() {
        hub.cleanup_dead();
        drop(ps);
        drop(hub);
        cosim::ipc::remove_run_files(prefix);
    }
    if !cpus.is_empty() {
        cosim::ipc::set_cpus(cpus);
    }
    exits
}

/// A sample on its way over a link, delivered to its consumer at `due_ns`.
#[derive(Clone, Copy)]
struct InFlight {
    due_ns: u64,
    link: LinkId,
    step: i64,
}

/// What the hub has delivered over the links and what is still on its way.
struct Deliveries {
    /// Per link ([`LinkId`] order), the newest producer step delivered (−1: the output at t₀).
    newest: [i64; 4],
    in_flight: Vec<InFlight>,
    /// Flags for the next request of each role (a scheduled crash).
    flags: RoleMap<u32>,
    /// Which consumers have published a step (and so read their starting request).
    started: RoleMap<bool>,
    /// Consumers with a newer input held back until they have started.
    held: RoleMap<bool>,
}

impl Deliveries {
    /// Sends a sample of producer step `step` over `link` with the delay the link gave it
    /// (`None`: lost): relayed at once, or later by [`Deliveries::release`].
    #[allow(clippy::too_many_arguments)]
    fn send(
        &mut self,
        link: LinkId,
        step: i64,
        delay: Option<u64>,
        now: u64,
        dt_ns: u64,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        match delay {
            None => Ok(()),
            Some(0) => self.deliver(link, step, ps, store, relays),
            Some(d) => {
                self.in_flight.push(InFlight {
                    due_ns: now + d * dt_ns,
                    link,
                    step,
                });
                Ok(())
            }
        }
    }

    /// Delivers every sample whose delay has passed, in the order they became due.
    fn release(
        &mut self,
        now: u64,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        if self.in_flight.iter().all(|f| f.due_ns > now) {
            return Ok(());
        }
        let mut due: Vec<InFlight> = Vec::new();
        self.in_flight.retain(|f| {
            if f.due_ns <= now {
                due.push(*f);
                false
            } else {
                true
            }
        });
        due.sort_by_key(|f| (f.due_ns, f.link as usize, f.step));
        for f in due {
            self.deliver(f.link, f.step, ps, store, relays)?;
        }
        Ok(())
    }

    /// The consumer of `link` holds the newest sample (by producer step) that has arrived: a
    /// newer one is relayed with the other input of that consumer as it stands.
    fn deliver(
        &mut self,
        link: LinkId,
        step: i64,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        if step <= self.newest[link as usize] {
            return Ok(());
        }
        self.newest[link as usize] = step;
        let consumer = match link {
            LinkId::Measurement => Role::Controller,
            LinkId::BarAngle => Role::Plant,
            LinkId::ActuatorCommand | LinkId::BarTwist => Role::Actuator,
        };
        if self.started[consumer] {
            self.relay(consumer, ps, store, relays)
        } else {
            // Not yet started: a relay now could overwrite its starting request, unread (a
            // participant stopped before its first step). It gets the newest at its first output.
            self.held[consumer] = true;
            Ok(())
        }
    }

    /// `role` has published its first step, so it has read its starting request: the input
    /// held back since then is relayed.
    fn started(
        &mut self,
        role: Role,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        self.started[role] = true;
        if std::mem::take(&mut self.held[role]) {
            self.relay(role, ps, store, relays)?;
        }
        Ok(())
    }

    /// Relays to `consumer` its input composed from the newest samples delivered to it.
    fn relay(
        &mut self,
        consumer: Role,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        let n = self.newest;
        let lost = || format!("{consumer}: a delivered sample is not in the store");
        let link_err = |e: LinkError| e.to_string();
        let flags = std::mem::take(&mut self.flags[consumer]);
        match consumer {
            Role::Controller => {
                let q = n[LinkId::Measurement as usize];
                let mut req = store.controller_input(q).ok_or_else(lost)?;
                req.header.flags |= flags;
                relays[consumer]
                    .send(&mut ps.controller, req, [Some(q), None, None])
                    .map_err(link_err)
            }
            Role::Plant => {
                let q = n[LinkId::BarAngle as usize];
                let mut req = store.plant_input(q).ok_or_else(lost)?;
                req.header.flags |= flags;
                relays[consumer]
                    .send(&mut ps.plant, req, [None, Some(q), None])
                    .map_err(link_err)
            }
            Role::Actuator => {
                let (qc, qp) = (
                    n[LinkId::ActuatorCommand as usize],
                    n[LinkId::BarTwist as usize],
                );
                let mut req = store.actuator_input(qc, qp).ok_or_else(lost)?;
                req.header.flags |= flags;
                relays[consumer]
                    .send(&mut ps.actuator, req, [Some(qp), None, Some(qc)])
                    .map_err(link_err)
            }
        }
    }
}

/// The orchestrator's side of a free run: the participants, what they have sent, what was
/// relayed to whom, and the files the steps stream to.
struct Hub<'a> {
    s: &'a Scenario,
    opts: &'a RunOptions,
    ps: Participants,
    store: Store,
    rows: RowStream,
    /// `timing.csv`, created once the start instant is known.
    writer: Option<TraceWriter>,
    relays: RoleMap<Relay>,
    deliveries: Deliveries,
    faults: FaultSchedule,
    stats: Stats,
    /// Every step's trace, kept for `run.mcap` (`--record`; the store then forgets nothing).
    kept: Option<Vec<StepTrace>>,
    /// Steps recorded per role.
    done: RoleMap<u64>,
    totals: RoleMap<u64>,
    ticks: RoleMap<u64>,
    last_heard: RoleMap<u64>,
    start_ns: u64,
    dt_ns: u64,
}

/// An output as it came in, by role.
#[derive(Clone, Copy)]
enum Output {
    Plant(FromPlant),
    Actuator(FromActuator),
    Controller(FromController),
}

impl Output {
    fn role(&self) -> Role {
        match self {
            Output::Plant(_) => Role::Plant,
            Output::Actuator(_) => Role::Actuator,
            Output::Controller(_) => Role::Controller,
        }
    }
    fn header(&self) -> &Header {
        match self {
            Output::Plant(o) => o.header(),
            Output::Actuator(o) => o.header(),
            Output::Controller(o) => o.header(),
        }
    }
    /// Checks the output against the step expected of its role.
    fn check(&self, step: u64) -> Result<(), LinkError> {
        match self {
            Output::Plant(o) => check_reply::<ToPlant, FromPlant>(Role::Plant, o, step, Kind::Step),
            Output::Actuator(o) => {
                check_reply::<ToActuator, FromActuator>(Role::Actuator, o, step, Kind::Step)
            }
            Output::Controller(o) => {
                check_reply::<ToController, FromController>(Role::Controller, o, step, Kind::Step)
            }
        }
    }
}

impl<'a> Hub<'a> {
    /// Creates `timeseries.csv`, which the rows stream to.
    fn new(s: &'a Scenario, opts: &'a RunOptions, ps: Participants) -> Result<Self, FreeError> {
        let steps = s.steps();
        let period = s.controller_period_ticks();
        let dt_ns = (s.run.dt_s * 1e9).round() as u64;
        let rows = RowStream::create(s, opts).map_err(FreeError::Run)?;
        let start_ns = now_ns();
        Ok(Hub {
            s,
            opts,
            ps,
            store: Store::new(period, s.run.dt_s, &s.links, s.run.seed),
            rows,
            writer: None,
            relays: RoleMap::default(),
            deliveries: Deliveries {
                newest: [-1; 4],
                in_flight: Vec::new(),
                flags: RoleMap::default(),
                started: RoleMap::default(),
                held: RoleMap::default(),
            },
            faults: FaultSchedule::new(&s.faults, s.run.dt_s),
            stats: Stats {
                dt_ns,
                period,
                ..Stats::default()
            },
            kept: opts.record.then(Vec::new),
            done: RoleMap::default(),
            totals: RoleMap::new([steps, steps, steps.div_ceil(period)]),
            ticks: RoleMap::new([1, 1, period]),
            last_heard: RoleMap::new([start_ns; 3]),
            start_ns,
            dt_ns,
        })
    }

    /// Takes the outputs at t₀, starts every participant free at the start instant and
    /// relays until every step of the run is in (or the run is interrupted).
    fn run(&mut self) -> Result<(), String> {
        init_all(&mut self.ps, &mut self.store).map_err(|e| e.to_string())?;
        self.rows
            .start(&self.store)
            .map_err(|e| format!("cannot write timeseries.csv: {e}"))?;
        self.start_ns = now_ns() + START_MARGIN.as_nanos() as u64;
        self.last_heard = RoleMap::new([self.start_ns; 3]);
        let head = TraceHead {
            dt_s: self.s.run.dt_s,
            steps: self.s.steps(),
            controller_period_ticks: self.ticks[Role::Controller],
            start_ns: self.start_ns,
        };
        let path = self.opts.out_dir.join(TIMING_CSV);
        self.writer = Some(
            TraceWriter::create(&path, &head)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?,
        );
        self.start_all()?;
        let link = |e: LinkError| e.to_string();
        let mut arrived: Vec<Output> = Vec::new();
        let (mut bp, mut ba, mut bc) = (Vec::new(), Vec::new(), Vec::new());
        while !Role::ALL.iter().all(|&r| self.done[r] >= self.totals[r]) {
            if self.opts.interrupt.load(Ordering::Relaxed) {
                return Ok(());
            }
            // Each role's outputs in the order they were published; the roles in the order of
            // the data flow within a tick.
            arrived.clear();
            bp.clear();
            self.ps.plant.take_arrived(&mut bp).map_err(link)?;
            arrived.extend(bp.iter().map(|o| Output::Plant(*o)));
            bc.clear();
            self.ps.controller.take_arrived(&mut bc).map_err(link)?;
            arrived.extend(bc.iter().map(|o| Output::Controller(*o)));
            ba.clear();
            self.ps.actuator.take_arrived(&mut ba).map_err(link)?;
            arrived.extend(ba.iter().map(|o| Output::Actuator(*o)));
            let now = now_ns();
            for r in Role::ALL {
                if arrived.iter().any(|o| o.role() == r) {
                    self.last_heard[r] = now;
                }
            }
            for o in &arrived {
                self.take(*o)?;
            }
            let now = now_ns();
            let Hub {
                deliveries,
                ps,
                store,
                relays,
                ..
            } = self;
            deliveries.release(now, ps, store, relays)?;
            self.check_silence(now)?;
            if !arrived.is_empty() {
                self.forget();
            } else {
                std::thread::sleep(HUB_NAP);
            }
        }
        Ok(())
    }

    /// Sends each participant its starting request: relay 0, its input from the outputs at
    /// t₀, carrying the common start instant and its period.
    fn start_all(&mut self) -> Result<(), String> {
        let busy_us = (self.s.run.controller_busy_wait_s * 1e6).round() as u32;
        let (ticks, start_ns, dt_ns) = (self.ticks.clone(), self.start_ns, self.dt_ns);
        // The fault events are written from the schedule (`run_events`), as the replay does.
        inject(&self.faults, 0, &mut self.ps, &mut self.deliveries.flags);
        let start = |mut h: Header, role: Role| {
            h.flags = FLAG_FREE_START;
            h.clock = FreeClock {
                start_ns,
                period_ns: ticks[role] * dt_ns,
                period_ticks: u32::try_from(ticks[role]).unwrap_or(u32::MAX),
                busy_us: if role == Role::Controller { busy_us } else { 0 },
            };
            h
        };
        let link = |e: LinkError| e.to_string();
        let missing = || "the outputs at t₀ are not in the store".to_string();
        let mut tp = self.store.plant_input(-1).ok_or_else(missing)?;
        tp.header = start(tp.header, Role::Plant);
        self.relays[Role::Plant]
            .send(&mut self.ps.plant, tp, [None, Some(-1), None])
            .map_err(link)?;
        let mut ta = self.store.actuator_input(-1, -1).ok_or_else(missing)?;
        ta.header = start(ta.header, Role::Actuator);
        self.relays[Role::Actuator]
            .send(&mut self.ps.actuator, ta, [Some(-1), None, Some(-1)])
            .map_err(link)?;
        let mut tc = self.store.controller_input(-1).ok_or_else(missing)?;
        tc.header = start(tc.header, Role::Controller);
        self.relays[Role::Controller]
            .send(&mut self.ps.controller, tc, [Some(-1), None, None])
            .map_err(link)
    }

    /// Records one output: its step's trace, the output in the store, its row when it
    /// completes one, and its samples sent over the links.
    fn take(&mut self, o: Output) -> Result<(), String> {
        let role = o.role();
        if self.done[role] >= self.totals[role] {
            return Ok(());
        }
        let step = self.done[role] * self.ticks[role];
        o.check(step).map_err(|e| e.to_string())?;
        let h = *o.header();
        let from = self.relays[role].take(h.relay).ok_or_else(|| {
            format!(
                "participant {role}: step {step} read relay {} that was never sent",
                h.relay
            )
        })?;
        self.done[role] += 1;
        let rel = |t: u64| t.saturating_sub(self.start_ns);
        let t = StepTrace {
            role,
            step,
            from,
            due_ns: step * self.dt_ns,
            read_ns: rel(h.recv_ns),
            compute_end_ns: rel(h.recv_ns + h.compute_ns),
            publish_ns: rel(h.sent_ns),
        };
        self.store.note_read(&t);
        self.stats.note(&t);
        if let Some(k) = &mut self.kept {
            k.push(t);
        }
        if let Some(w) = &mut self.writer {
            w.push(&t)
                .map_err(|e| format!("cannot write {TIMING_CSV}: {e}"))?;
        }
        let now = now_ns();
        let q = step as i64;
        let Hub {
            deliveries,
            ps,
            store,
            relays,
            dt_ns,
            ..
        } = self;
        if step == 0 {
            deliveries.started(role, ps, store, relays)?;
        }
        match o {
            Output::Plant(o) => {
                let [meas, twist] = store.put_plant(step, o);
                for (l, d) in [(LinkId::Measurement, meas), (LinkId::BarTwist, twist)] {
                    deliveries.send(l, q, d, now, *dt_ns, ps, store, relays)?;
                }
                self.rows
                    .advance(&self.store, self.totals[Role::Plant])
                    .map_err(|e| format!("cannot write timeseries.csv: {e}"))?;
                // The world's clock has reached tick q + 1: the faults scheduled for it happen.
                inject(
                    &self.faults,
                    step + 1,
                    &mut self.ps,
                    &mut self.deliveries.flags,
                );
            }
            Output::Actuator(o) => {
                let d = store.put_actuator(step, o);
                deliveries.send(LinkId::BarAngle, q, d, now, *dt_ns, ps, store, relays)?;
            }
            Output::Controller(o) => {
                let d = store.put_controller(step, o);
                deliveries.send(
                    LinkId::ActuatorCommand,
                    q,
                    d,
                    now,
                    *dt_ns,
                    ps,
                    store,
                    relays,
                )?;
            }
        }
        Ok(())
    }

    /// Ends the run, naming the participant, when one that still has steps to take has
    /// published nothing for `run.hang_ceiling_ms` (stopped, hung, or starved that long).
    fn check_silence(&self, now: u64) -> Result<(), String> {
        let ceiling_ns = self.s.run.hang_ceiling_ms * 1_000_000;
        for r in Role::ALL {
            if self.done[r] < self.totals[r]
                && now.saturating_sub(self.last_heard[r].max(self.start_ns)) > ceiling_ns
            {
                let last = match self.done[r] {
                    0 => "none".to_string(),
                    n => ((n - 1) * self.ticks[r]).to_string(),
                };
                return Err(format!(
                    "participant {r} published nothing for {} ms (run.hang_ceiling_ms); its last step recorded: {last}",
                    self.s.run.hang_ceiling_ms,
                ));
            }
        }
        Ok(())
    }

    /// Lets the store forget what nothing can name any more: a consumer reads the relays sent
    /// to it in order, so the oldest relay it may still read bounds the producer steps its
    /// later steps name; the rows written bound what later rows name; a sample relayed or
    /// still on its way is newer than the newest delivered. With `--record` nothing is
    /// forgotten (the recording is written from the store after the run).
    fn forget(&mut self) {
        if self.kept.is_some() {
            return;
        }
        let mut floor = self.rows.floor();
        let n = self.deliveries.newest;
        let newest = [
            n[LinkId::Measurement as usize].min(n[LinkId::BarTwist as usize]),
            n[LinkId::BarAngle as usize],
            n[LinkId::ActuatorCommand as usize],
        ];
        for p in 0..3 {
            floor[p] = floor[p].min(newest[p]);
        }
        for r in Role::ALL {
            if let Some(from) = self.relays[r].oldest() {
                for p in 0..3 {
                    if let Some(q) = from[p] {
                        floor[p] = floor[p].min(q);
                    }
                }
            }
        }
        self.store.forget_before(floor);
    }
}

/// Applies the faults scheduled for tick `k` without waiting for their effect: a kill is a
/// SIGKILL (the next poll that finds nothing from the process sees it gone; waiting for the
/// exit here would leave every other participant's outputs unread meanwhile), a stall a
/// SIGSTOP resumed later, a crash a flag on the participant's next input.
fn inject(faults: &FaultSchedule, k: u64, ps: &mut Participants, flags: &mut RoleMap<u32>) {
    let pids = ps.pids();
    for f in faults.due_at(k) {
        let role = f.participant;
        match f.action {
            FaultAction::Kill => {
                // SAFETY: a signal to our own child, not reaped yet (it is reaped by the
                // endpoint, which then reports its exit).
                unsafe { libc::kill(pids[role] as libc::pid_t, libc::SIGKILL) };
            }
            FaultAction::Stall => {
                let stall = ProcessFault::Stall(Duration::from_secs_f64(f.stall_s));
                match role {
                    Role::Plant => ps.plant.inject(stall),
                    Role::Actuator => ps.actuator.inject(stall),
                    Role::Controller => ps.controller.inject(stall),
                }
            }
            FaultAction::Crash => flags[role] |= cosim::msg::FLAG_CRASH,
        }
    }
}
