//! The orchestrator of a free run: the hub that relays the newest outputs without waiting,
//! and records every step's timing.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::Ordering;
use std::time::Duration;

use cosim::endpoint::check_reply;
use cosim::msg::{now_ns, FromActuator, FromController, FromPlant, Header, Kind, Message};
use cosim::msg::{ToActuator, ToController, ToPlant, FLAG_FREE_START};
use cosim::{Endpoint, LinkError, ProcessFault, Role};

use super::compose::Store;
use super::trace::{age, col, inputs_of, StepTrace, TraceHead, TraceWriter, TIMING_CSV};
use super::{init_all, write_rows, FilesGuard, FreeError};
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
        // The starting request (relay 0) carries the period in ticks in its step instead.
        if req.header().flags & FLAG_FREE_START == 0 {
            req.header_mut().step = self.next;
        }
        self.sent.push_back((self.next, from));
        self.next += 1;
        ep.send(&req)
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

/// Per-role timing statistics of a free run (wall clock).
#[derive(Default)]
struct RoleTiming {
    lateness_ns: Vec<u64>,
    late_start: u64,
    late_finish: u64,
}

/// What a free run reports beyond its files.
#[derive(serde::Serialize)]
pub struct FreeReport {
    /// How the run ended.
    pub status: Status,
    /// Why it failed or stopped, naming the participant.
    pub error: Option<String>,
    /// Rows in `timeseries.csv`.
    pub steps_completed: u64,
    /// Wall time from the start instant to the last step recorded (s).
    pub wall_time_s: f64,
    /// A plant step started more than [`NOT_REAL_TIME_TICKS`] ticks after it was due.
    pub not_real_time: bool,
    /// That margin (s).
    pub not_real_time_margin_s: f64,
    /// The plant's largest start lateness (s).
    pub plant_max_lateness_s: f64,
    /// Per participant: start lateness percentiles (µs), late starts, late finishes.
    pub participants: BTreeMap<String, serde_json::Value>,
    /// Per link: the distribution of input ages (ticks) over the consumer's steps.
    pub input_age_ticks: BTreeMap<String, serde_json::Value>,
    /// Exit of each participant process.
    pub exits: BTreeMap<String, String>,
    /// The run's iceoryx2 prefix.
    pub ipc_prefix: String,
    /// Shared-memory files left behind (empty unless something is wrong).
    pub leftover_ipc_files: Vec<String>,
    /// The CPU each participant was pinned to (empty when not pinned).
    pub cpus: BTreeMap<String, usize>,
    /// `run.mcap` (`--record`), to be closed with the summary.
    #[serde(skip)]
    pub recording: Option<super::record::FreeRecording>,
}

/// Nanoseconds as microseconds with one decimal.
fn us(ns: u64) -> f64 {
    (ns / 100) as f64 / 10.0
}

fn percentile(sorted: &[u64], q: f64) -> u64 {
    if sorted.is_empty() {
        return 0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
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

/// Runs `s` free over IPC: writes `timing.csv`, `timeseries.csv`, `events.csv` and
/// `scenario.toml` to `opts.out_dir`.
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
    let mut ps = launch::start(s, opts, &prefix).map_err(FreeError::Run)?;
    let placement = place(s, &ps, &cpus);
    let steps = s.steps();
    let period = s.controller_period_ticks();
    let mut store = Store::new(steps, period, s.run.dt_s, &s.links, s.run.seed);
    let outcome = init_all(&mut ps, &mut store).map_err(|e| e.to_string());
    let dt_ns = (s.run.dt_s * 1e9).round() as u64;
    let start_ns = now_ns() + START_MARGIN.as_nanos() as u64;
    let head = TraceHead {
        dt_s: s.run.dt_s,
        steps,
        controller_period_ticks: period,
        start_ns,
    };
    let path = dir.join(TIMING_CSV);
    let mut writer = TraceWriter::create(&path, &head).map_err(|e| FreeError::io(&path, e))?;
    let mut timing: RoleMap<RoleTiming> = RoleMap::default();
    let mut ages: BTreeMap<&'static str, BTreeMap<i64, u64>> = BTreeMap::new();
    // Every step's trace, kept for the recording (`--record`).
    let mut kept: Vec<StepTrace> = Vec::new();
    let mut outcome = outcome.and_then(|()| {
        hub(
            s,
            opts,
            &mut ps,
            &mut store,
            &mut writer,
            start_ns,
            dt_ns,
            &mut |t: &StepTrace| {
                if opts.record {
                    kept.push(*t);
                }
                let ticks = if t.role == Role::Controller {
                    period
                } else {
                    1
                };
                let rt = &mut timing[t.role];
                rt.lateness_ns.push(t.read_ns.saturating_sub(t.due_ns));
                rt.late_start += u64::from(t.late_start(ticks * dt_ns));
                rt.late_finish += u64::from(t.late_finish(ticks * dt_ns));
                for &p in inputs_of(t.role) {
                    if let Some(f) = t.from[col(p)] {
                        *ages
                            .entry(link_name(t.role, p))
                            .or_default()
                            .entry(age(p, t.step, f))
                            .or_default() += 1;
                    }
                }
            },
        )
    });
    let last_ns = now_ns();
    if let Err(e) = writer.finish() {
        outcome = outcome.and(Err(format!("cannot write {}: {e}", path.display())));
    }
    let exits = shut_down(ps, &prefix, &cpus);
    drop(guard);
    let leftover: Vec<String> = cosim::ipc::leftover_files(&prefix)
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let rows =
        write_rows(dir, &store, steps).map_err(|e| FreeError::io(&dir.join("timeseries.csv"), e));
    let events = super::run_events(s, &store, rows.as_ref().copied().unwrap_or(0));
    let events_csv = dir.join("events.csv");
    events
        .write(&events_csv)
        .map_err(|e| FreeError::io(&events_csv, e))?;
    crate::columns::write_run(dir).map_err(|e| FreeError::io(&dir.join("columns.csv"), e))?;
    let rows = rows?;
    let recording = if opts.record {
        let path = dir.join("run.mcap");
        let r = super::record::record(&path, s.run.dt_s, &store, &kept, rows, start_ns, &events)
            .map_err(|e| FreeError::io(&path, e))?;
        Some(r)
    } else {
        None
    };
    let interrupted = opts.interrupt.load(Ordering::Relaxed);
    let (status, error) = match outcome {
        Ok(()) if interrupted => (
            Status::Interrupted,
            Some(format!("interrupted by {}", crate::signals::describe())),
        ),
        Ok(()) => (Status::Completed, None),
        Err(e) => (Status::Failed, Some(e)),
    };
    let mut participants = BTreeMap::new();
    let mut plant_max = 0;
    for r in Role::ALL {
        let t = &mut timing[r];
        t.lateness_ns.sort_unstable();
        let max = t.lateness_ns.last().copied().unwrap_or(0);
        if r == Role::Plant {
            plant_max = max;
        }
        participants.insert(
            r.name().to_string(),
            serde_json::json!({
                "steps": t.lateness_ns.len(),
                "start_lateness_us": {
                    "p50": us(percentile(&t.lateness_ns, 0.5)),
                    "p99": us(percentile(&t.lateness_ns, 0.99)),
                    "max": us(max),
                },
                "late_starts": t.late_start,
                "late_finishes": t.late_finish,
            }),
        );
    }
    let input_age_ticks = ages
        .into_iter()
        .map(|(link, h)| {
            let n: u64 = h.values().sum();
            let at = |q: f64| {
                let want = ((n.saturating_sub(1)) as f64 * q).round() as u64;
                let mut seen = 0;
                for (a, c) in &h {
                    seen += c;
                    if seen > want {
                        return *a;
                    }
                }
                0
            };
            (
                link.to_string(),
                serde_json::json!({
                    "min": h.keys().next().copied().unwrap_or(0),
                    "p50": at(0.5),
                    "p99": at(0.99),
                    "max": h.keys().next_back().copied().unwrap_or(0),
                    // [age, steps] pairs in increasing age.
                    "counts": h.iter().map(|(a, c)| [*a, *c as i64]).collect::<Vec<_>>(),
                }),
            )
        })
        .collect();
    let margin_ns = NOT_REAL_TIME_TICKS * dt_ns;
    Ok(FreeReport {
        status,
        error,
        steps_completed: rows,
        wall_time_s: last_ns.saturating_sub(start_ns) as f64 * 1e-9,
        not_real_time: plant_max > margin_ns,
        not_real_time_margin_s: margin_ns as f64 * 1e-9,
        plant_max_lateness_s: plant_max as f64 * 1e-9,
        participants,
        input_age_ticks,
        exits: exits
            .iter()
            .map(|(r, x)| (r.name().to_string(), x.status.clone()))
            .collect(),
        ipc_prefix: prefix,
        leftover_ipc_files: leftover,
        cpus: placement,
        recording,
    })
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
        let n = self.newest;
        let lost = || format!("{link:?}: a delivered sample of step {step} is not in the store");
        let link_err = |e: LinkError| e.to_string();
        match link {
            LinkId::Measurement => {
                let mut req = store.controller_input(step).ok_or_else(lost)?;
                req.header.flags |= std::mem::take(&mut self.flags[Role::Controller]);
                relays[Role::Controller]
                    .send(&mut ps.controller, req, [Some(step), None, None])
                    .map_err(link_err)
            }
            LinkId::BarAngle => {
                let mut req = store.plant_input(step).ok_or_else(lost)?;
                req.header.flags |= std::mem::take(&mut self.flags[Role::Plant]);
                relays[Role::Plant]
                    .send(&mut ps.plant, req, [None, Some(step), None])
                    .map_err(link_err)
            }
            LinkId::ActuatorCommand | LinkId::BarTwist => {
                let (qc, qp) = (
                    n[LinkId::ActuatorCommand as usize],
                    n[LinkId::BarTwist as usize],
                );
                let mut req = store.actuator_input(qc, qp).ok_or_else(lost)?;
                req.header.flags |= std::mem::take(&mut self.flags[Role::Actuator]);
                relays[Role::Actuator]
                    .send(&mut ps.actuator, req, [Some(qp), None, Some(qc)])
                    .map_err(link_err)
            }
        }
    }
}

/// Starts every participant free at `start_ns` and relays until every step of the run is in.
#[allow(clippy::too_many_arguments)]
fn hub(
    s: &Scenario,
    opts: &RunOptions,
    ps: &mut Participants,
    store: &mut Store,
    writer: &mut TraceWriter,
    start_ns: u64,
    dt_ns: u64,
    observe: &mut dyn FnMut(&StepTrace),
) -> Result<(), String> {
    let steps = s.steps();
    let period = s.controller_period_ticks();
    let totals = RoleMap::new([steps, steps, steps.div_ceil(period)]);
    let ticks = RoleMap::new([1, 1, period]);
    let busy_us = (s.run.controller_busy_wait_s * 1e6).round() as u32;
    let mut relays: RoleMap<Relay> = RoleMap::default();
    let faults = FaultSchedule::new(&s.faults, s.run.dt_s);
    let mut deliveries = Deliveries {
        newest: [-1; 4],
        in_flight: Vec::new(),
        flags: RoleMap::default(),
    };
    // The fault events are written from the schedule (`run_events`), as the replay does.
    inject(&faults, 0, ps, &mut deliveries.flags);
    let start = |mut h: Header, role: Role| {
        h.flags = FLAG_FREE_START;
        h.step = ticks[role];
        h.recv_ns = start_ns;
        h.compute_ns = ticks[role] * dt_ns;
        h.field = if role == Role::Controller { busy_us } else { 0 };
        h
    };
    let link = |e: LinkError| e.to_string();
    let missing = || "the outputs at t₀ are not in the store".to_string();
    // Relay 0 of each consumer: its input from the outputs at t₀, carrying the start.
    let mut tp = store.plant_input(-1).ok_or_else(missing)?;
    tp.header = start(tp.header, Role::Plant);
    relays[Role::Plant]
        .send(&mut ps.plant, tp, [None, Some(-1), None])
        .map_err(link)?;
    let mut ta = store.actuator_input(-1, -1).ok_or_else(missing)?;
    ta.header = start(ta.header, Role::Actuator);
    relays[Role::Actuator]
        .send(&mut ps.actuator, ta, [Some(-1), None, Some(-1)])
        .map_err(link)?;
    let mut tc = store.controller_input(-1).ok_or_else(missing)?;
    tc.header = start(tc.header, Role::Controller);
    relays[Role::Controller]
        .send(&mut ps.controller, tc, [Some(-1), None, None])
        .map_err(link)?;

    let mut done: RoleMap<u64> = RoleMap::default();
    let mut last_heard = RoleMap::new([start_ns; 3]);
    let ceiling_ns = s.run.hang_ceiling_ms * 1_000_000;
    let mut bp: Vec<FromPlant> = Vec::new();
    let mut ba: Vec<FromActuator> = Vec::new();
    let mut bc: Vec<FromController> = Vec::new();
    let complete = |d: &RoleMap<u64>| Role::ALL.iter().all(|&r| d[r] >= totals[r]);
    while !complete(&done) {
        if opts.interrupt.load(Ordering::Relaxed) {
            return Ok(());
        }
        let mut any = false;
        bp.clear();
        ps.plant.take_arrived(&mut bp).map_err(link)?;
        for o in bp.iter() {
            any = true;
            let Some(t) = accept::<ToPlant, FromPlant>(
                Role::Plant,
                o,
                &mut done,
                &totals,
                &ticks,
                &mut relays,
                start_ns,
                dt_ns,
            )?
            else {
                continue;
            };
            let [meas, twist] = store.put_plant(t.step, *o);
            record(store, writer, &t, observe)?;
            let now = now_ns();
            let q = t.step as i64;
            for (l, d) in [(LinkId::Measurement, meas), (LinkId::BarTwist, twist)] {
                deliveries.send(l, q, d, now, dt_ns, ps, store, &mut relays)?;
            }
            // The world's clock has reached tick q + 1: the faults scheduled for it happen.
            inject(&faults, t.step + 1, ps, &mut deliveries.flags);
        }
        bc.clear();
        ps.controller.take_arrived(&mut bc).map_err(link)?;
        for o in bc.iter() {
            any = true;
            let Some(t) = accept::<ToController, FromController>(
                Role::Controller,
                o,
                &mut done,
                &totals,
                &ticks,
                &mut relays,
                start_ns,
                dt_ns,
            )?
            else {
                continue;
            };
            let d = store.put_controller(t.step, *o);
            record(store, writer, &t, observe)?;
            let now = now_ns();
            deliveries.send(
                LinkId::ActuatorCommand,
                t.step as i64,
                d,
                now,
                dt_ns,
                ps,
                store,
                &mut relays,
            )?;
        }
        ba.clear();
        ps.actuator.take_arrived(&mut ba).map_err(link)?;
        for o in ba.iter() {
            any = true;
            let Some(t) = accept::<ToActuator, FromActuator>(
                Role::Actuator,
                o,
                &mut done,
                &totals,
                &ticks,
                &mut relays,
                start_ns,
                dt_ns,
            )?
            else {
                continue;
            };
            let d = store.put_actuator(t.step, *o);
            record(store, writer, &t, observe)?;
            let now = now_ns();
            deliveries.send(
                LinkId::BarAngle,
                t.step as i64,
                d,
                now,
                dt_ns,
                ps,
                store,
                &mut relays,
            )?;
        }
        let now = now_ns();
        deliveries.release(now, ps, store, &mut relays)?;
        for (r, got) in [
            (Role::Plant, !bp.is_empty()),
            (Role::Actuator, !ba.is_empty()),
            (Role::Controller, !bc.is_empty()),
        ] {
            if got {
                last_heard[r] = now;
            } else if done[r] < totals[r]
                && now.saturating_sub(last_heard[r].max(start_ns)) > ceiling_ns
            {
                return Err(format!(
                    "participant {r} published nothing for {} ms (run.hang_ceiling_ms) at step {}",
                    s.run.hang_ceiling_ms,
                    done[r] * ticks[r]
                ));
            }
        }
        if !any {
            std::thread::sleep(HUB_NAP);
        }
    }
    Ok(())
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

/// Checks an output against the step expected next from its role; returns its trace, or
/// `None` for an output past the run's end.
#[allow(clippy::too_many_arguments)]
fn accept<I: Message, O: Message>(
    role: Role,
    o: &O,
    done: &mut RoleMap<u64>,
    totals: &RoleMap<u64>,
    ticks: &RoleMap<u64>,
    relays: &mut RoleMap<Relay>,
    start_ns: u64,
    dt_ns: u64,
) -> Result<Option<StepTrace>, String> {
    if done[role] >= totals[role] {
        return Ok(None);
    }
    let step = done[role] * ticks[role];
    check_reply::<I, O>(role, o, step, Kind::Step).map_err(|e| e.to_string())?;
    let h = o.header();
    let from = relays[role].take(u64::from(h.attempt)).ok_or_else(|| {
        format!(
            "participant {role}: step {step} read relay {} that was never sent",
            h.attempt
        )
    })?;
    done[role] += 1;
    let rel = |t: u64| t.saturating_sub(start_ns);
    Ok(Some(StepTrace {
        role,
        step,
        from,
        due_ns: step * dt_ns,
        read_ns: rel(h.recv_ns),
        compute_end_ns: rel(h.recv_ns + h.compute_ns),
        publish_ns: rel(h.sent_ns),
    }))
}

fn record(
    store: &mut Store,
    writer: &mut TraceWriter,
    t: &StepTrace,
    observe: &mut dyn FnMut(&StepTrace),
) -> Result<(), String> {
    store.note_read(t);
    observe(t);
    writer
        .push(t)
        .map_err(|e| format!("cannot write {TIMING_CSV}: {e}"))
}
