//! The orchestrator of a free run: the hub that relays the newest outputs without waiting,
//! and records every step's timing.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::Duration;

use cosim::endpoint::check_reply;
use cosim::msg::{now_ns, FromActuator, FromController, FromPlant, Header, Kind, Message};
use cosim::msg::{FreeClock, ToActuator, ToController, ToPlant, FLAG_FREE_START};
use cosim::{LinkError, ProcessFault, Role};
use tiltsim_scenario::faults::FaultAction;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::Scenario;

use super::compose::Store;
use super::observed::ReplayObservers;
use super::recording::{FreeRecorder, FreeRecording};
use super::relay::{Deliveries, Relay};
use super::timing::Stats;
use super::trace::{StepTrace, TraceHead, TraceWriter, TIMING_CSV};
use super::{init_all, FreeError, RowStream};
use crate::engine::launch::Participants;
use crate::engine::manipulator::FaultSchedule;
use crate::engine::observe::Observer;
use crate::engine::outputs::Outputs;
use crate::engine::session::{self, Session};
use crate::engine::RunOptions;

pub use super::timing::FreeReport;

/// Time from sending the start requests to the common start instant: the participants are
/// connected and waiting, so this only has to cover the delivery of three samples.
const START_MARGIN: Duration = Duration::from_millis(50);

/// Pause of the hub between two polls that found nothing.
const HUB_NAP: Duration = Duration::from_micros(20);

/// Runs `s` free over IPC: streams `timing.csv` and `timeseries.csv` to `opts.out_dir` as the
/// steps come in, then writes `events.csv`, `columns.csv` and `scenario.toml`. `observers`
/// are told each row as it is written, as a timing replay tells them
/// ([`super::observed`]), and closed; the report hands them back for their part of the
/// summary.
pub fn run(
    s: &Scenario,
    opts: &RunOptions,
    out: &Outputs,
    observers: Vec<Box<dyn Observer>>,
) -> Result<FreeReport, FreeError> {
    crate::engine::observe::distinct_names(&observers).map_err(FreeError::Run)?;
    let (session, ps) = Session::start(s, opts, true).map_err(FreeError::Run)?;
    let placement = place(s, &ps);
    let placed_as = ps.placement.clone();
    let mut hub = Hub::new(s, opts, out, ps)?;
    hub.observers = (!observers.is_empty()).then(|| ReplayObservers::new(s, observers));
    let mut outcome = hub.run();
    let last_ns = now_ns();
    let Hub {
        ps,
        store,
        rows,
        writer,
        stats,
        recorder,
        record_error,
        start_ns,
        observers,
        ..
    } = hub;
    let observers = match observers {
        Some(mut o) => {
            if let Some(e) = o.close().into_iter().next() {
                outcome = outcome.and(Err(e));
            }
            o.into_list()
        }
        None => Vec::new(),
    };
    let mut write_errors = Vec::new();
    let path = opts.out_dir.join(TIMING_CSV);
    if let Some(Err(e)) = writer.map(TraceWriter::finish) {
        write_errors.push(format!("{}: {e}", path.display()));
    }
    let dir = session.dir();
    let (status, error) = session::status(&outcome, false, &opts.interrupt);
    let closed = session.close(ps, Default::default());
    let (ticks, kept_rows, rows_error) = rows.finish();
    write_errors.extend(rows_error);
    let mut events = super::run_events(s, &store, ticks);
    closed.write_files(dir, &mut events, &mut write_errors);
    write_errors.extend(record_error);
    let recording = finish_recording(recorder, &store, ticks, &events, &mut write_errors);
    let mut timing = stats.report(s.run.dt_s);
    timing.cpus = placement;
    timing.placement = placed_as;
    Ok(FreeReport {
        status,
        error,
        steps_completed: ticks,
        wall_time_s: last_ns.saturating_sub(start_ns) as f64 * 1e-9,
        timing,
        rows: kept_rows,
        recording,
        write_errors,
        closed,
        observers,
    })
}

/// The recording's last ticks and events (`None` when the run was not recorded or its
/// recording failed, the failure in `write_errors`).
fn finish_recording(
    recorder: Option<FreeRecorder>,
    store: &Store,
    ticks: u64,
    events: &tiltsim_formats::events::EventLog,
    write_errors: &mut Vec<String>,
) -> Option<FreeRecording> {
    recorder?
        .finish(store, ticks, events)
        .map_err(|e| write_errors.push(e.to_string()))
        .ok()
}

/// The CPU of each participant in a free run, when the run was given a pair of CPUs of its own
/// (`cosim::ipc::placement`, the same registry as lock-step runs, whose claim the run holds
/// until it ends): the controller keeps the participants' CPU to itself, as a controller
/// computer of its own, and the plant and the actuator (a few µs each per millisecond, woken
/// by their timers) move to the orchestrator's, so the controller's compute, however long,
/// never delays the vehicle or its drive, nor the hub's relays it (in lock-step all three
/// share one CPU, since only one computes at a time). Empty when the run is not pinned: asked
/// not to be, or the CPUs are claimed by other runs or kept busy by other work, and then the
/// kernel balances the processes.
fn place(s: &Scenario, ps: &Participants) -> BTreeMap<String, usize> {
    // A pair only: under `free-cpu-each` the participants keep the three CPUs the run claimed
    // for them when they started, spread by the kernel, none pinned to one.
    let Some(p) = ps
        .placement
        .as_ref()
        .filter(|p| p.reason == cosim::ipc::placement::Reason::FreePair)
    else {
        return BTreeMap::new();
    };
    let (Some(first), Some(&last)) = (p.orchestrator_cpu, p.participant_cpus.first()) else {
        return BTreeMap::new();
    };
    let pids = ps.pids();
    let mut placed = BTreeMap::new();
    for (r, cpu) in [
        (Role::Plant, first),
        (Role::Actuator, first),
        (Role::Controller, last),
    ] {
        // A participant on another host has no process here to place.
        if s.network.is_remote(r) {
            continue;
        }
        if cosim::ipc::set_cpus_of(pids[r], &[cpu]) {
            placed.insert(r.name().to_string(), cpu);
        }
    }
    placed
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
    /// `run.mcap` (`--record`), written as the ticks complete.
    recorder: Option<FreeRecorder>,
    /// Why the recording stopped, when a write failed (the run goes on without it).
    record_error: Option<String>,
    /// Steps recorded per role.
    done: RoleMap<u64>,
    totals: RoleMap<u64>,
    ticks: RoleMap<u64>,
    last_heard: RoleMap<u64>,
    start_ns: u64,
    dt_ns: u64,
    /// The caller's observers, told each row as it is written.
    observers: Option<ReplayObservers>,
}

/// An output as it came in, by role. Kept by value (the plant's, 400 bytes, is the largest):
/// boxing it would allocate for every sample of the free loop.
#[derive(Clone, Copy)]
#[allow(clippy::large_enum_variant)]
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
    fn new(
        s: &'a Scenario,
        opts: &'a RunOptions,
        out: &Outputs,
        ps: Participants,
    ) -> Result<Self, FreeError> {
        let steps = s.steps();
        let period = s.controller_period_ticks();
        let dt_ns = (s.run.dt_s * 1e9).round() as u64;
        let rows = RowStream::create(opts, out).map_err(FreeError::Run)?;
        let recorder = if out.record {
            let path = opts.out_dir.join("run.mcap");
            Some(FreeRecorder::create(&path, s).map_err(|e| FreeError::io(&path, e))?)
        } else {
            None
        };
        let start_ns = now_ns();
        Ok(Hub {
            s,
            opts,
            ps,
            store: Store::new(period, s.run.dt_s, &s.links, s.run.seed),
            rows,
            writer: None,
            relays: RoleMap::default(),
            deliveries: Deliveries::new(),
            faults: FaultSchedule::new(&s.faults, s.run.dt_s),
            stats: Stats::new(dt_ns, period),
            recorder,
            record_error: None,
            done: RoleMap::default(),
            totals: RoleMap::new([steps, steps, steps.div_ceil(period)]),
            ticks: RoleMap::new([1, 1, period]),
            last_heard: RoleMap::new([start_ns; 3]),
            start_ns,
            dt_ns,
            observers: None,
        })
    }

    /// Takes the outputs at t₀, starts every participant free at the start instant and
    /// relays until every step of the run is in (or the run is interrupted).
    fn run(&mut self) -> Result<(), String> {
        init_all(&mut self.ps, &mut self.store).map_err(|e| e.to_string())?;
        self.rows
            .start(&self.store)
            .map_err(|e| format!("cannot write timeseries.csv: {e}"))?;
        if let Some(o) = &mut self.observers {
            o.start(&self.store)
                .map_err(|e| format!("an observer: {e}"))?;
        }
        self.start_ns = now_ns() + START_MARGIN.as_nanos() as u64;
        self.last_heard = RoleMap::new([self.start_ns; 3]);
        if let Some(r) = &mut self.recorder {
            r.start(&self.store, self.start_ns)
                .map_err(|e| format!("cannot write run.mcap: {e}"))?;
        }
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
                self.record();
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
        if let Some(r) = &mut self.recorder {
            r.push(t, &self.store);
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
                let told = self.rows.written();
                self.rows
                    .advance(&self.store, self.totals[Role::Plant])
                    .map_err(|e| format!("cannot write timeseries.csv: {e}"))?;
                if let Some(obs) = &mut self.observers {
                    for k in told..self.rows.written() {
                        obs.tick(&self.store, k)
                            .map_err(|e| format!("an observer at tick {k}: {e}"))?;
                    }
                }
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

    /// Records the ticks that are complete; a write that fails ends the recording (the run
    /// goes on, the failure among its write errors).
    fn record(&mut self) {
        let Some(r) = &mut self.recorder else {
            return;
        };
        if let Err(e) = r.advance(&self.store, self.rows.written()) {
            self.record_error = Some(e.to_string());
            self.recorder = None;
        }
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
    /// still on its way is newer than the newest delivered; the ticks not recorded yet name
    /// what their steps read.
    fn forget(&mut self) {
        let mut floor = self.rows.floor();
        if let Some(r) = &self.recorder {
            r.floor(&mut floor);
        }
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
    let remote = ps.remote();
    for f in faults.due_at(k) {
        let role = f.participant;
        match f.action {
            FaultAction::Kill if remote[role] => match role {
                // A participant on another host is told to kill itself.
                Role::Plant => ps.plant.inject(ProcessFault::Kill),
                Role::Actuator => ps.actuator.inject(ProcessFault::Kill),
                Role::Controller => ps.controller.inject(ProcessFault::Kill),
            },
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
