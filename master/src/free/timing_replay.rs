//! The exact lock-step replay of a free run's timing (`tiltsim replay-timing`).
//!
//! The master algorithm is the trace itself: the consumer steps are taken in the order of
//! their read instants, and each is given, as a lock-step request, the input composed
//! ([`super::compose`]) from the very producer outputs the trace says it read. A step read
//! only outputs published before its read instant, so every output it names has been
//! computed by then; the participants are deterministic functions of their request
//! sequences, so every output, and every row, is the free run's bit for bit.

use std::ops::ControlFlow;
use std::path::Path;

use cosim::msg::{Kind, Message};
use cosim::{Endpoint, LinkError, Role};
use tiltsim_scenario::scenario::Scenario;

use super::compose::Store;
use super::observed::ReplayObservers;
use super::trace::{self, col, StepTrace, TraceError};
use super::{init_all, FreeError, RowStream};
use crate::engine::launch::Participants;
use crate::engine::observe::Observer;
use crate::engine::outputs::Outputs;
use crate::engine::session::{self, Session};
use crate::engine::RunOptions;

/// What a replay did.
pub struct Replayed {
    /// Rows written to `timeseries.csv` after the one at the start time.
    pub steps_completed: u64,
    /// Consumer steps replayed.
    pub exchanges: u64,
    /// What a partial trace lacks (`None`: the whole run was replayed).
    pub partial: Option<String>,
    /// The rows, when kept in memory (`Outputs::rows_in_memory`).
    pub rows: Option<Vec<tiltsim_formats::table::Row>>,
    /// How the replay ended: an interrupt, a completion, or a failure (`error`).
    pub status: crate::engine::Status,
    /// Why the replay stopped before the end of the trace (a participant failed, a file
    /// could not be written, an interrupt).
    pub error: Option<String>,
    /// The free run's real-time verdict, as its trace file tells it (`None` for a trace made
    /// by a program, whose instants are not a run's): a replay of a run that did not keep
    /// real time is no more valid than the run.
    pub not_real_time: Option<tiltsim_assessment::validity::NotRealTime>,
    /// The caller's observers, told every tick and closed, for their part of the summary
    /// ([`super::summary_of_replay`]).
    pub observers: Vec<Box<dyn Observer>>,
    /// What the session left: exits, process ids, prefix, logs.
    pub(crate) closed: crate::engine::session::Closed,
}

impl std::fmt::Debug for Replayed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Replayed")
            .field("steps_completed", &self.steps_completed)
            .field("exchanges", &self.exchanges)
            .field("partial", &self.partial)
            .field("error", &self.error)
            .field("observers", &self.observers.len())
            .finish_non_exhaustive()
    }
}

/// Steps replayed between two clean-ups of the store.
const FORGET_EVERY: u64 = 1024;

/// One lock-step exchange of step `step`.
fn ask<I: Message, O: Message>(
    ep: &mut Box<dyn Endpoint<I, O>>,
    mut req: I,
    step: u64,
) -> Result<O, LinkError> {
    let h = req.header_mut();
    h.step = step;
    h.kind = Kind::Step as u32;
    ep.send(&req)?;
    ep.receive(step, Kind::Step)
}

/// Replays the trace at `trace_path` with scenario `s` (its own or another system's) on
/// `s.run.transport`; writes `timeseries.csv`, `events.csv` and `scenario.toml` to
/// `opts.out_dir`. The trace is read twice, a step at a time, and never held whole: once to
/// check it (and judge the free run's real time), then to replay it, so an hour's trace
/// takes the memory a second's does.
pub fn replay_timing(
    s: &Scenario,
    trace_path: &Path,
    opts: &RunOptions,
    out: &Outputs,
    attached: Attached,
) -> Result<Replayed, FreeError> {
    let (steps, period, dt_s) = (s.steps(), s.controller_period_ticks(), s.run.dt_s);
    let mut stats = super::timing::Stats::new((dt_s * 1e9).round() as u64, period);
    let mut order = ReadOrder::new(steps, period);
    let mut causal = Causal::new(trace_path, period);
    let mut bad = None;
    let partial = trace::each_step_until(trace_path, dt_s, steps, period, |t| {
        stats.note(t);
        order.push(*t);
        while let Some(x) = order.pop(false) {
            if let Err(e) = causal.check(&x) {
                bad = Some(e);
                return ControlFlow::Break(());
            }
        }
        ControlFlow::Continue(())
    })?;
    if let Some(e) = bad {
        return Err(e.into());
    }
    while let Some(x) = order.pop(true) {
        causal.check(&x)?;
    }
    let verdict = real_time_verdict(stats, dt_s);
    let mut r = run_replay(s, opts, out, partial, attached, |rep| {
        let mut order = ReadOrder::new(steps, period);
        let mut failed = None;
        trace::each_step_until(trace_path, dt_s, steps, period, |t| {
            order.push(*t);
            while let Some(x) = order.pop(false) {
                if let Err(e) = rep.take(&x) {
                    failed = Some(e);
                    return ControlFlow::Break(());
                }
                if rep.interrupted() {
                    return ControlFlow::Break(());
                }
            }
            ControlFlow::Continue(())
        })
        .map_err(|e| e.to_string())?;
        if let Some(e) = failed {
            return Err(e);
        }
        while let Some(x) = order.pop(true) {
            if rep.interrupted() {
                break;
            }
            rep.take(&x)?;
        }
        Ok(())
    })?;
    r.not_real_time = Some(verdict);
    Ok(r)
}

/// What the caller adds to a replay, as to a lock-step [`crate::engine::Run`]: observers told
/// every tick ([`super::observed`]) and manipulators given every sample a link delivers, after
/// the scenario's link effects and in the order added (their `carry`; a replay repeats the
/// trace's steps, so it injects no fault and replaces no participant: `tick_commencing` and
/// `participant_failed` are not called).
#[derive(Default)]
pub struct Attached {
    pub observers: Vec<Box<dyn Observer>>,
    pub manipulators: Vec<Box<dyn crate::engine::manipulate::Manipulator>>,
}

/// The free run's verdict on real time, judged from its trace by the free run's own
/// statistics ([`super::timing::Stats`]), which have seen every step.
fn real_time_verdict(
    stats: super::timing::Stats,
    dt_s: f64,
) -> tiltsim_assessment::validity::NotRealTime {
    let f = stats.report(dt_s);
    tiltsim_assessment::validity::NotRealTime {
        raised: f.not_real_time,
        plant_max_lateness_s: f.plant_max_lateness_s,
        margin_s: f.not_real_time_margin_s,
    }
}

/// [`replay_timing`] of a trace already in memory (`trace_path` names it in errors): a
/// trace made by a program (`tiltsim falsify`) is replayed without a file written and read
/// back. Its steps must be the scenario's, as [`trace::read`] checks them. In process and with
/// the rows kept in memory (`Outputs::rows_in_memory`) it writes nothing at all: no directory, no
/// `scenario.toml`, `events.csv` or `columns.csv` (a search's evaluations, whose cost is the
/// run's own).
pub fn replay_trace(
    s: &Scenario,
    trace: trace::Trace,
    trace_path: &Path,
    opts: &RunOptions,
    out: &Outputs,
    attached: Attached,
) -> Result<Replayed, FreeError> {
    let period = s.controller_period_ticks();
    let mut order = trace.steps;
    // A made trace is in read order already: sorted only when it is not.
    if !order.is_sorted_by_key(|t| (t.read_ns, col(t.role))) {
        order.sort_by_key(|t| (t.read_ns, col(t.role)));
    }
    check_causal(trace_path, &order, period)?;
    run_replay(s, opts, out, trace.partial, attached, |rep| {
        for t in &order {
            if rep.interrupted() {
                break;
            }
            rep.take(t)?;
        }
        Ok(())
    })
}

/// Starts the participants, lets `drive` hand the replay its steps in read order, stops the
/// participants and finishes the files (none when in process with the rows kept in memory).
fn run_replay(
    s: &Scenario,
    opts: &RunOptions,
    out: &Outputs,
    partial: Option<String>,
    attached: Attached,
    drive: impl FnOnce(&mut Replayer<'_>) -> Result<(), String>,
) -> Result<Replayed, FreeError> {
    let Attached {
        observers,
        manipulators,
    } = attached;
    crate::engine::observe::distinct_names(&observers).map_err(FreeError::Run)?;
    let (session, mut ps) = Session::start(s, opts, !out.rows_in_memory).map_err(FreeError::Run)?;
    let mut rows = RowStream::create(opts, out).map_err(FreeError::Run)?;
    let mut store = Store::new(
        s.controller_period_ticks(),
        s.run.dt_s,
        &s.links,
        s.run.seed,
    );
    store.add_manipulators(manipulators);
    let mut rep = Replayer {
        steps: s.steps(),
        interrupt: &opts.interrupt,
        ps: &mut ps,
        store: &mut store,
        rows: &mut rows,
        last: [[-1; 3]; 3],
        taken: 0,
        observers: (!observers.is_empty()).then(|| ReplayObservers::new(s, observers)),
    };
    let mut outcome = rep.start().and_then(|()| drive(&mut rep));
    let exchanges = rep.taken;
    let observers = match rep.observers.take() {
        Some(mut o) => {
            let closed = o.close();
            if let Some(e) = closed.into_iter().next() {
                outcome = outcome.and(Err(e));
            }
            o.into_list()
        }
        None => Vec::new(),
    };
    let dir = session.dir();
    let (mut status, mut error) = session::status(&outcome, false, &opts.interrupt);
    let closed = session.close(ps, Default::default());
    let (ticks, kept, row_error) = rows.finish();
    let mut write_errors = Vec::new();
    let mut events = super::run_events(s, &store, ticks);
    closed.write_files(dir, &mut events, &mut write_errors);
    let row_error = row_error.map(|e| match dir {
        Some(_) => format!("cannot write timeseries.csv: {e}"),
        None => format!("cannot keep the rows: {e}"),
    });
    let write_error = write_errors.first().map(|e| format!("cannot write {e}"));
    if let (None, Some(e)) = (&error, row_error.or(write_error)) {
        status = crate::engine::Status::Failed;
        error = Some(e);
    }
    Ok(Replayed {
        steps_completed: ticks,
        exchanges,
        partial,
        rows: kept,
        status,
        error,
        not_real_time: None,
        observers,
        closed,
    })
}

/// The steps of a trace in the order the replay takes them (by read instant, then role
/// column), from each role's steps in step order as a trace file holds them: a step is handed
/// on once every role that has steps to come has one waiting, so only the steps read ahead
/// of the slowest role are held (a stalled participant's, for the length of its stall).
struct ReadOrder {
    waiting: [std::collections::VecDeque<StepTrace>; 3],
    /// Per role, by [`col`], its steps not pushed yet.
    left: [u64; 3],
}

impl ReadOrder {
    fn new(steps: u64, period: u64) -> Self {
        ReadOrder {
            waiting: Default::default(),
            left: [steps, steps, steps.div_ceil(period)],
        }
    }

    fn push(&mut self, t: StepTrace) {
        let c = col(t.role);
        self.left[c] = self.left[c].saturating_sub(1);
        self.waiting[c].push_back(t);
    }

    /// The next step in read order, when it is known: once every role with steps to come
    /// has one waiting, or (`ended`) no step will come.
    fn pop(&mut self, ended: bool) -> Option<StepTrace> {
        if !ended && (0..3).any(|c| self.waiting[c].is_empty() && self.left[c] > 0) {
            return None;
        }
        let c = (0..3)
            .filter(|&c| !self.waiting[c].is_empty())
            .min_by_key(|&c| (self.waiting[c][0].read_ns, c))?;
        self.waiting[c].pop_front()
    }
}

/// Checks, step by step in read order, that every input a step names was produced by a step
/// read earlier: a role's steps are taken in step order, so the steps of each producer done
/// so far are its first ones.
struct Causal<'a> {
    path: &'a Path,
    period: u64,
    /// Per role, by [`col`], the steps taken so far.
    done: [u64; 3],
}

impl<'a> Causal<'a> {
    fn new(path: &'a Path, period: u64) -> Self {
        Causal {
            path,
            period,
            done: [0; 3],
        }
    }

    fn index(&self, role: Role, step: u64) -> u64 {
        if role == Role::Controller {
            step / self.period
        } else {
            step
        }
    }

    fn check(&mut self, t: &StepTrace) -> Result<(), TraceError> {
        for &p in trace::inputs_of(t.role) {
            let Some(q) = t.from[col(p)].filter(|&q| q >= 0) else {
                continue;
            };
            if self.index(p, q as u64) >= self.done[col(p)] {
                return Err(TraceError {
                    file: self.path.display().to_string(),
                    field: format!("{} step {}: from_{}", t.role, t.step, p.name()),
                    what: format!("{p} step {q} is read before it was computed"),
                });
            }
        }
        let i = self.index(t.role, t.step) + 1;
        let d = &mut self.done[col(t.role)];
        *d = (*d).max(i);
        Ok(())
    }
}

/// A replay under way: the participants, the store and the rows, and what each consumer
/// read last, which bounds what its later steps can name (a consumer never reads an older
/// sample after a newer one, which reading the trace checks).
struct Replayer<'a> {
    steps: u64,
    interrupt: &'a std::sync::atomic::AtomicBool,
    ps: &'a mut Participants,
    store: &'a mut Store,
    rows: &'a mut RowStream,
    /// Per consumer, by [`col`], the producer steps its last step read (−1: none yet).
    last: [[i64; 3]; 3],
    /// Steps replayed.
    taken: u64,
    /// The caller's observers, told each row as it is composed.
    observers: Option<ReplayObservers>,
}

impl Replayer<'_> {
    /// The outputs at t₀ and the row at the start time.
    fn start(&mut self) -> Result<(), String> {
        init_all(self.ps, self.store).map_err(|e| e.to_string())?;
        self.rows.start(self.store).map_err(write_rows)?;
        match &mut self.observers {
            Some(o) => o.start(self.store).map_err(|e| format!("an observer: {e}")),
            None => Ok(()),
        }
    }

    fn interrupted(&self) -> bool {
        self.interrupt.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Replays step `t`, then now and then lets the store forget what no later step or row
    /// can name.
    fn take(&mut self, t: &StepTrace) -> Result<(), String> {
        let told = self.rows.written();
        replay_step(t, self.ps, self.store, self.rows, self.steps)?;
        if let Some(o) = &mut self.observers {
            for k in told..self.rows.written() {
                o.tick(self.store, k)
                    .map_err(|e| format!("an observer at tick {k}: {e}"))?;
            }
        }
        for (l, f) in self.last[col(t.role)].iter_mut().zip(t.from) {
            if let Some(q) = f {
                *l = q;
            }
        }
        self.taken += 1;
        if self.taken.is_multiple_of(FORGET_EVERY) {
            let mut floor = self.rows.floor();
            for r in Role::ALL {
                for &p in trace::inputs_of(r) {
                    floor[col(p)] = floor[col(p)].min(self.last[col(r)][col(p)]);
                }
            }
            self.store.forget_before(floor);
        }
        Ok(())
    }
}

/// The error of a write to `timeseries.csv` that failed.
fn write_rows(e: std::io::Error) -> String {
    format!("cannot write timeseries.csv: {e}")
}

/// One step of the trace: the participant is given the input composed from the producer
/// outputs `t` names, and its output goes to the store (with the rows it completes, up to
/// tick `steps`).
fn replay_step(
    t: &StepTrace,
    ps: &mut Participants,
    store: &mut Store,
    rows: &mut RowStream,
    steps: u64,
) -> Result<(), String> {
    store.note_read(t);
    // The inputs exist: `check_causal` has seen each produced before it is read.
    let missing = || LinkError::Malformed {
        role: t.role,
        step: t.step,
        what: "an input the trace names was not computed".into(),
    };
    let step = |e: LinkError| e.to_string();
    match t.role {
        Role::Plant => {
            let req = store.input_plant(t).ok_or_else(missing).map_err(step)?;
            let o = ask(&mut ps.plant, req, t.step).map_err(step)?;
            store.put_plant(t.step, o);
            rows.advance(store, steps).map_err(write_rows)?;
        }
        Role::Actuator => {
            let req = store.input_actuator(t).ok_or_else(missing).map_err(step)?;
            let o = ask(&mut ps.actuator, req, t.step).map_err(step)?;
            store.put_actuator(t.step, o);
        }
        Role::Controller => {
            let req = store
                .input_controller(t)
                .ok_or_else(missing)
                .map_err(step)?;
            let o = ask(&mut ps.controller, req, t.step).map_err(step)?;
            store.put_controller(t.step, o);
        }
    }
    Ok(())
}

/// Every input a step names was produced by a step read earlier (a trace edited by hand, or
/// of another run, may say otherwise); `order` is the trace's steps sorted by read instant
/// (and role column at equal instants), as the replay takes them.
pub fn check_causal(path: &Path, order: &[StepTrace], period: u64) -> Result<(), TraceError> {
    let mut causal = Causal::new(path, period);
    order.iter().try_for_each(|t| causal.check(t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(role: Role, step: u64, read_ns: u64) -> StepTrace {
        StepTrace {
            role,
            step,
            from: [None; 3],
            due_ns: 0,
            read_ns,
            compute_end_ns: read_ns,
            publish_ns: read_ns,
        }
    }

    /// Steps handed on one at a time, each role's in step order but the roles interleaved as
    /// a trace file holds them (a role's steps written up to `lag` steps after the others'),
    /// come out in the order of sorting the whole trace by read instant and role, holding
    /// no more than the lag.
    #[test]
    fn steps_in_file_order_come_out_in_read_order_holding_only_the_lag() {
        let (steps, period, lag) = (5_000u64, 10u64, 40usize);
        let mut file = Vec::new();
        let mut late = std::collections::VecDeque::new();
        let mut actuator = 0;
        for k in 0..steps {
            // Reads 0-300 µs into the tick, the same instants now and then (ties by role).
            let at = |r: u64| k * 1_000_000 + (k * 7919 + r * 104_729) % 3 * 100_000;
            file.push(step(Role::Plant, k, at(0)));
            if k.is_multiple_of(period) {
                late.push_back(step(Role::Controller, k, at(2)));
            }
            // The actuator's lines come `lag` steps late in bursts, the controller's later.
            if k % 25 == 0 || k == steps - 1 {
                for j in actuator..=k {
                    file.push(step(Role::Actuator, j, j * 1_000_000 + 50_000));
                }
                actuator = k + 1;
            }
            if late.len() > lag / 10 || k == steps - 1 {
                file.extend(late.drain(..));
            }
        }
        let mut want = file.clone();
        want.sort_by_key(|t| (t.read_ns, col(t.role)));
        let mut order = ReadOrder::new(steps, period);
        let (mut got, mut held) = (Vec::new(), 0);
        for t in &file {
            order.push(*t);
            held = held.max(order.waiting.iter().map(|w| w.len()).sum::<usize>());
            while let Some(x) = order.pop(false) {
                got.push(x);
            }
        }
        while let Some(x) = order.pop(true) {
            got.push(x);
        }
        assert_eq!(got.len(), want.len());
        let first = got.iter().zip(&want).position(|(a, b)| a != b);
        assert_eq!(first, None, "first step out of read order");
        assert!(held <= 3 * lag, "{held} steps held");
    }
}
