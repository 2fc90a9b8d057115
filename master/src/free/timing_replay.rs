//! The exact lock-step replay of a free run's timing (`tiltsim replay-timing`).
//!
//! The master algorithm is the trace itself: the consumer steps are taken in the order of
//! their read instants, and each is given, as a lock-step request, the input composed
//! ([`super::compose`]) from the very producer outputs the trace says it read. A step read
//! only outputs published before its read instant, so every output it names has been
//! computed by then; the participants are deterministic functions of their request
//! sequences, so every output, and every row, is the free run's bit for bit.

use std::path::Path;

use cosim::msg::{Kind, Message};
use cosim::{Endpoint, LinkError, Role};
use tiltsim_scenario::scenario::{Scenario, Transport};

use super::compose::Store;
use super::trace::{self, col, StepTrace, TraceError};
use super::{init_all, FilesGuard, FreeError, RowStream};
use crate::engine::launch::{self, Participants};
use crate::engine::outputs::Outputs;
use crate::engine::RunOptions;

/// What a replay did.
#[derive(Debug, Clone)]
pub struct Replayed {
    /// Rows written to `timeseries.csv` after the one at the start time.
    pub steps_completed: u64,
    /// Consumer steps replayed.
    pub exchanges: u64,
    /// What a partial trace lacks (`None`: the whole run was replayed).
    pub partial: Option<String>,
    /// The rows, when kept in memory (`Outputs::rows_in_memory`).
    pub rows: Option<Vec<tiltsim_formats::table::Row>>,
    /// Each participant's exit.
    pub exits: tiltsim_scenario::roles::RoleMap<cosim::endpoint::ExitReport>,
    /// Each participant's process id.
    pub pids: tiltsim_scenario::roles::RoleMap<u32>,
    /// Why the replay stopped before the end of the trace (a participant failed).
    pub error: Option<String>,
    /// The run's iceoryx2 prefix (empty in one process).
    pub ipc_prefix: String,
    /// Participant logs that are not empty (`logs/<role>.log`).
    pub participant_logs: Vec<String>,
    /// The free run's real-time verdict, as its trace file tells it (`None` for a trace made
    /// by a program, whose instants are not a run's): a replay of a run that did not keep
    /// real time is no more valid than the run.
    pub not_real_time: Option<tiltsim_assessment::validity::NotRealTime>,
}

/// Per step of `order`, the oldest producer steps (by [`col`]) named by it or any later step.
fn floors(order: &[StepTrace]) -> Vec<[i64; 3]> {
    let mut out = vec![[i64::MAX; 3]; order.len() + 1];
    for (i, t) in order.iter().enumerate().rev() {
        let mut f = out[i + 1];
        for (p, q) in t.from.iter().enumerate() {
            if let Some(q) = q {
                f[p] = f[p].min(*q);
            }
        }
        out[i] = f;
    }
    out
}

/// Steps replayed between two clean-ups of the store.
const FORGET_EVERY: usize = 1024;

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
/// `opts.out_dir`.
pub fn replay_timing(
    s: &Scenario,
    trace_path: &Path,
    opts: &RunOptions,
    out: &Outputs,
) -> Result<Replayed, FreeError> {
    let period = s.controller_period_ticks();
    let trace = trace::read(trace_path, s.run.dt_s, s.steps(), period)?;
    let verdict = real_time_verdict(&trace.steps, s.run.dt_s, period);
    let mut r = replay_trace(s, trace, trace_path, opts, out)?;
    r.not_real_time = Some(verdict);
    Ok(r)
}

/// The free run's verdict on real time, judged from its trace by the free run's own
/// statistics ([`super::timing::Stats`]).
fn real_time_verdict(
    steps: &[StepTrace],
    dt_s: f64,
    period: u64,
) -> tiltsim_assessment::validity::NotRealTime {
    let mut stats = super::timing::Stats::new((dt_s * 1e9).round() as u64, period);
    steps.iter().for_each(|t| stats.note(t));
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
) -> Result<Replayed, FreeError> {
    let period = s.controller_period_ticks();
    let mut order = trace.steps;
    // A made trace is in read order already: sorted only when it is not.
    if !order.is_sorted_by_key(|t| (t.read_ns, col(t.role))) {
        order.sort_by_key(|t| (t.read_ns, col(t.role)));
    }
    check_causal(trace_path, &order, period)?;
    let dir = &opts.out_dir;
    // Participants in other processes log to the directory: it is made for them.
    let files = !(out.rows_in_memory && s.run.transport == Transport::InProcess);
    if files {
        crate::engine::prepare(s, opts).map_err(FreeError::Run)?;
    }
    let prefix = crate::engine::ipc_prefix(s, opts);
    let guard = FilesGuard(prefix.clone());
    let cpus = cosim::ipc::allowed_cpus();
    let mut rows = RowStream::create(opts, out).map_err(FreeError::Run)?;
    let mut ps = launch::start(s, opts, &prefix).map_err(FreeError::Run)?;
    let mut store = Store::new(period, s.run.dt_s, &s.links, s.run.seed);
    let outcome = replay_steps(s, opts, &order, &mut ps, &mut store, &mut rows);
    let pids = ps.pids();
    let exits = super::shut_down(ps, &prefix, &cpus);
    drop(guard);
    let participant_logs = if s.run.transport == Transport::Ipc {
        crate::engine::finish_logs(dir)
    } else {
        Vec::new()
    };
    let dir = files.then_some(dir.as_path());
    let (ticks, kept, error) = finish_files(s, dir, &store, rows, outcome.err());
    Ok(Replayed {
        steps_completed: ticks,
        exchanges: order.len() as u64,
        partial: trace.partial,
        rows: kept,
        exits,
        pids,
        error,
        ipc_prefix: prefix,
        participant_logs,
        not_real_time: None,
    })
}

/// Takes the outputs at t₀, then each step of `order` in turn, writing the rows as they
/// complete; stops early, without an error, when the run is interrupted.
fn replay_steps(
    s: &Scenario,
    opts: &RunOptions,
    order: &[StepTrace],
    ps: &mut Participants,
    store: &mut Store,
    rows: &mut RowStream,
) -> Result<(), String> {
    let steps = s.steps();
    let floors = floors(order);
    init_all(ps, store).map_err(|e| e.to_string())?;
    rows.start(store).map_err(write_rows)?;
    for (i, t) in order.iter().enumerate() {
        if opts.interrupt.load(std::sync::atomic::Ordering::Relaxed) {
            return Ok(());
        }
        replay_step(t, ps, store, rows, steps)?;
        if i % FORGET_EVERY == FORGET_EVERY - 1 {
            let mut floor = rows.floor();
            for p in 0..3 {
                floor[p] = floor[p].min(floors[i + 1][p]);
            }
            store.forget_before(floor);
        }
    }
    Ok(())
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

/// Finishes `timeseries.csv` and writes `events.csv` and `columns.csv` to `dir` (none: the
/// rows are kept in memory and no file is written); returns the ticks whose rows are
/// complete, the rows when kept in memory, and the replay's error (`error`, or else the first
/// file that could not be written).
fn finish_files(
    s: &Scenario,
    dir: Option<&Path>,
    store: &Store,
    rows: RowStream,
    mut error: Option<String>,
) -> (
    u64,
    Option<Vec<tiltsim_formats::table::Row>>,
    Option<String>,
) {
    let (ticks, kept, row_error) = rows.finish();
    let Some(dir) = dir else {
        if let Some(e) = row_error {
            error.get_or_insert(format!("cannot keep the rows: {e}"));
        }
        return (ticks, kept, error);
    };
    let events_csv = dir.join("events.csv");
    if let Err(e) = super::run_events(s, store, ticks).write(&events_csv) {
        error.get_or_insert(format!("cannot write {}: {e}", events_csv.display()));
    }
    if let Err(e) = tiltsim_formats::columns::write_run(dir) {
        error.get_or_insert(format!("cannot write columns.csv: {e}"));
    }
    if let Some(e) = row_error {
        error.get_or_insert(format!("cannot write timeseries.csv: {e}"));
    }
    (ticks, kept, error)
}

/// Every input a step names was produced by a step read earlier (a trace edited by hand, or
/// of another run, may say otherwise); `order` is the trace's steps sorted by read instant
/// (and role column at equal instants), as the replay takes them.
pub fn check_causal(path: &Path, order: &[StepTrace], period: u64) -> Result<(), TraceError> {
    let n = order.len();
    let mut done = [vec![false; n], vec![false; n], vec![false; n]];
    for t in order {
        for &p in trace::inputs_of(t.role) {
            let Some(q) = t.from[col(p)].filter(|&q| q >= 0) else {
                continue;
            };
            let i = if p == Role::Controller {
                q as u64 / period
            } else {
                q as u64
            } as usize;
            if !done[col(p)].get(i).copied().unwrap_or(false) {
                return Err(TraceError {
                    file: path.display().to_string(),
                    field: format!("{} step {}: from_{}", t.role, t.step, p.name()),
                    what: format!("{p} step {q} is read before it was computed"),
                });
            }
        }
        let i = if t.role == Role::Controller {
            t.step / period
        } else {
            t.step
        } as usize;
        if let Some(d) = done[col(t.role)].get_mut(i) {
            *d = true;
        }
    }
    Ok(())
}
