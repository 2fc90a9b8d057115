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

use super::compose::Store;
use super::trace::{self, col, StepTrace, TraceError};
use super::{init_all, write_rows, FilesGuard, FreeError};
use crate::engine::launch;
use crate::engine::RunOptions;
use crate::scenario::{Scenario, Transport};

/// What a replay did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Replayed {
    /// Rows written to `timeseries.csv`.
    pub steps_completed: u64,
    /// Consumer steps replayed.
    pub exchanges: u64,
}

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
pub fn replay(s: &Scenario, trace_path: &Path, opts: &RunOptions) -> Result<Replayed, FreeError> {
    let period = s.controller_period_ticks();
    let steps = s.steps();
    let (_, mut order) = trace::read(trace_path, s.run.dt_s, steps, period)?;
    order.sort_by_key(|t| (t.read_ns, col(t.role)));
    check_causal(trace_path, &order, period)?;
    let dir = &opts.out_dir;
    std::fs::create_dir_all(dir).map_err(|e| FreeError::io(dir, e))?;
    let resolved = dir.join("scenario.toml");
    crate::files::write_atomic(&resolved, toml::to_string(s).unwrap_or_default())
        .map_err(|e| FreeError::io(&resolved, e))?;
    let prefix = match s.run.transport {
        Transport::Ipc => opts
            .ipc_prefix
            .clone()
            .unwrap_or_else(cosim::ipc::unique_prefix),
        Transport::InProcess => String::new(),
    };
    let guard = FilesGuard(prefix.clone());
    let cpus = cosim::ipc::allowed_cpus();
    let mut ps = launch::start(s, opts, &prefix).map_err(FreeError::Run)?;
    let mut store = Store::new(steps, period, s.run.dt_s, &s.links, s.run.seed);
    let outcome = (|| -> Result<(), LinkError> {
        init_all(&mut ps, &mut store)?;
        for t in &order {
            store.note_read(t);
            // The inputs exist: `check_causal` has seen each produced before it is read.
            let missing = || LinkError::Malformed {
                role: t.role,
                step: t.step,
                what: "an input the trace names was not computed".into(),
            };
            match t.role {
                Role::Plant => {
                    let req = store.input_plant(t).ok_or_else(missing)?;
                    let o = ask(&mut ps.plant, req, t.step)?;
                    store.put_plant(t.step, o);
                }
                Role::Actuator => {
                    let req = store.input_actuator(t).ok_or_else(missing)?;
                    let o = ask(&mut ps.actuator, req, t.step)?;
                    store.put_actuator(t.step, o);
                }
                Role::Controller => {
                    let req = store.input_controller(t).ok_or_else(missing)?;
                    let o = ask(&mut ps.controller, req, t.step)?;
                    store.put_controller(t.step, o);
                }
            }
        }
        Ok(())
    })();
    ps.shut_down(crate::roles::RoleMap::default());
    if let Some(hub) = ps.hub.take() {
        hub.cleanup_dead();
        drop(ps);
        drop(hub);
        cosim::ipc::remove_run_files(&prefix);
    }
    drop(guard);
    if !cpus.is_empty() {
        cosim::ipc::set_cpus(&cpus);
    }
    let rows = write_rows(dir, &store, steps)
        .map_err(|e| FreeError::io(&dir.join("timeseries.csv"), e))?;
    let events_csv = dir.join("events.csv");
    super::run_events(s, &store, rows)
        .write(&events_csv)
        .map_err(|e| FreeError::io(&events_csv, e))?;
    crate::columns::write_run(dir).map_err(|e| FreeError::io(&dir.join("columns.csv"), e))?;
    outcome?;
    Ok(Replayed {
        steps_completed: rows,
        exchanges: order.len() as u64,
    })
}

/// Every input a step names was produced by a step read earlier (a trace edited by hand, or
/// of another run, may say otherwise).
fn check_causal(path: &Path, order: &[StepTrace], period: u64) -> Result<(), TraceError> {
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
