//! The free-running execution mode and its exact lock-step replay (docs/architecture.md,
//! "Execution modes").
//!
//! * [`run`]: every participant process steps on its own wall-clock timer from one common
//!   start instant and reads, at each step, the newest input that has arrived; the
//!   orchestrator is the hub that composes each consumer's input from the newest producer
//!   outputs, relays it without waiting, and records the timing trace (`timing.csv`).
//! * `relay`: the hub's relays to each consumer and the samples on their way over the
//!   links.
//! * [`timing`]: the wall-clock statistics a free run gathers and the report it ends in.
//! * [`timing_replay`]: a lock-step run, in-process or over IPC, that feeds each consumer step
//!   exactly the producer outputs the trace says it read, in the order of the read instants.
//! * [`compose`]: the inputs and the rows of `timeseries.csv`, shared by both, so that the
//!   replay's rows are the free run's byte for byte.
//! * [`trace`]: `timing.csv`, written and read back with its checks.

pub mod compose;
mod feed;
mod observed;
pub mod recording;
mod relay;
pub mod run;
pub mod timing;
pub mod timing_replay;
pub mod trace;

use std::path::Path;

use cosim::msg::{FromActuator, FromController, FromPlant, Header, Kind};
use cosim::msg::{ToActuator, ToController, ToPlant};
use cosim::LinkError;
use tiltsim_formats::table::{Recorder, Row};
use tiltsim_scenario::scenario::Scenario;

use crate::engine::instruments::{RowRecorder, RowSink};
use crate::engine::launch::Participants;
use crate::engine::session;
use crate::engine::{RunError, RunMode, Summary};

pub use run::{run, FreeReport};
pub use timing_replay::{replay_timing, Replayed};
pub use trace::TraceError;

/// Why a free run or a replay could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum FreeError {
    /// The participants could not be started, or a file not written.
    #[error(transparent)]
    Run(RunError),
    /// The timing trace does not belong to the scenario.
    #[error(transparent)]
    Trace(#[from] TraceError),
}

impl FreeError {
    fn io(path: &Path, source: std::io::Error) -> FreeError {
        FreeError::Run(RunError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// The `Init` exchange of every participant, lock-step: the outputs at t₀ into `store`.
pub(crate) fn init_all(ps: &mut Participants, store: &mut compose::Store) -> Result<(), LinkError> {
    let h = Header::new(0, Kind::Init);
    ps.plant.send(&ToPlant {
        header: h,
        ..Default::default()
    })?;
    let p: FromPlant = ps.plant.receive(0, Kind::Init)?;
    ps.actuator.send(&ToActuator {
        header: h,
        ..Default::default()
    })?;
    let a: FromActuator = ps.actuator.receive(0, Kind::Init)?;
    ps.controller.send(&ToController {
        header: h,
        ..Default::default()
    })?;
    let c: FromController = ps.controller.receive(0, Kind::Init)?;
    store.put_init(p, a, c);
    Ok(())
}

/// `events.csv` of a free run or its replay with `rows` plant steps: the scheduled faults
/// that happened and what the links did, in tick order (a tick's faults first, as they happen
/// before its exchanges).
pub(crate) fn run_events(
    s: &Scenario,
    store: &compose::Store,
    rows: u64,
) -> tiltsim_formats::events::EventLog {
    let mut ev = planned_events(s, rows);
    let planned = std::mem::take(&mut ev.events);
    ev.events = feed::merge_by_tick(planned, store.events().events);
    ev
}

/// The events of a run of `s` that do not come from the links' samples: the links' set-up and
/// the faults scheduled up to tick `last`, in tick order.
pub(crate) fn planned_events(s: &Scenario, last: u64) -> tiltsim_formats::events::EventLog {
    let mut ev = tiltsim_formats::events::EventLog::new(s.run.dt_s);
    crate::links::LinkSet::describe(&s.links, &mut ev);
    crate::engine::manipulator::FaultSchedule::new(&s.faults, s.run.dt_s).log_until(last, &mut ev);
    ev
}

/// The rows of a free run or its replay, written as they complete: the row at the start time,
/// then each tick's row as soon as the plant's step of that tick is in (everything a row names
/// was sent before the plant read it), to `timeseries.csv` or kept in memory
/// (`Outputs::rows_in_memory`).
pub(crate) struct RowStream {
    rec: RowRecorder,
    /// The next tick to write.
    next: u64,
    /// The oldest producer steps (by [`trace::col`]) the last row written names.
    reads: [i64; 3],
}

impl RowStream {
    /// Creates `timeseries.csv` (header first), or the rows' place in memory.
    pub(crate) fn create(
        opts: &crate::engine::RunOptions,
        out: &crate::engine::outputs::Outputs,
    ) -> Result<Self, RunError> {
        let sink = if out.rows_in_memory {
            RowSink::Kept(Vec::new())
        } else {
            let csv = opts.out_dir.join("timeseries.csv");
            RowSink::File(Box::new(Recorder::create(&csv).map_err(RunError::io(csv))?))
        };
        Ok(RowStream {
            rec: RowRecorder::new(sink),
            next: 0,
            reads: [-1; 3],
        })
    }

    /// Writes the row at the start time.
    pub(crate) fn start(&mut self, store: &compose::Store) -> std::io::Result<()> {
        self.rec.put(store.row_at_start())
    }

    /// Writes every row that can be composed now, in tick order, up to tick `steps`.
    pub(crate) fn advance(&mut self, store: &compose::Store, steps: u64) -> std::io::Result<()> {
        while self.next < steps {
            let Some((row, reads)) = store.row_and_reads(self.next) else {
                break;
            };
            self.rec.put(row)?;
            self.reads = reads;
            self.next += 1;
        }
        Ok(())
    }

    /// The ticks whose rows are written (or kept).
    pub(crate) fn written(&self) -> u64 {
        self.next
    }

    /// The oldest producer steps a later row can name.
    pub(crate) fn floor(&self) -> [i64; 3] {
        let [p, a, c] = self.reads;
        [p.min(self.next as i64), a, c]
    }

    /// Writes what is buffered; returns the ticks whose rows are complete, the rows when kept
    /// in memory, and the error of a write that failed.
    pub(crate) fn finish(mut self) -> (u64, Option<Vec<Row>>, Option<String>) {
        let err = self.rec.finish().err().map(|e| e.to_string());
        (self.rec.ticks(), self.rec.take_kept(), err)
    }
}

/// The summary of free run `r` of `s` (not yet analysed); its observers give their parts.
pub fn summary_of_run(s: &Scenario, scenario_file: &str, r: &mut FreeReport) -> Summary {
    let mut sm = Summary::blank(s, scenario_file, RunMode::Free);
    sm.status = r.status;
    sm.error = r.error.clone();
    session::fail_on_write_error(&mut sm, &r.write_errors);
    r.closed.fill(s, &mut sm, None);
    sm.set_progress(r.steps_completed, r.wall_time_s);
    sm.free_run = Some(r.timing.clone());
    sm.timing_trace = Some(trace::TIMING_CSV.to_string());
    for mut o in r.observers.drain(..) {
        if let Some(part) = o.finish(&sm) {
            sm.observers.insert(o.name().to_string(), part);
        }
    }
    sm
}

/// The summary of replay `r` of the trace at `trace_path` with `s` (not yet analysed); its
/// observers give their parts.
pub fn summary_of_replay(
    s: &Scenario,
    scenario_file: &str,
    trace_path: &Path,
    r: &mut Replayed,
) -> Summary {
    let mut sm = Summary::blank(s, scenario_file, RunMode::ReplayTiming);
    sm.status = r.status;
    sm.error = r.error.clone();
    r.closed.fill(s, &mut sm, None);
    sm.set_progress(r.steps_completed, 0.0);
    sm.timing_trace = Some(trace_path.display().to_string());
    sm.trace_partial = r.partial.clone();
    sm.replayed_exchanges = Some(r.exchanges);
    sm.flags.not_real_time = r.not_real_time.clone();
    for mut o in r.observers.drain(..) {
        if let Some(part) = o.finish(&sm) {
            sm.observers.insert(o.name().to_string(), part);
        }
    }
    sm
}

#[cfg(test)]
mod tests {
    use super::trace::StepTrace;
    use super::*;
    use cosim::Role;

    fn step(role: Role, step: u64, from: [Option<i64>; 3]) -> StepTrace {
        StepTrace {
            role,
            step,
            from,
            due_ns: 0,
            read_ns: 0,
            compute_end_ns: 0,
            publish_ns: 0,
        }
    }

    /// Writes a trace of `ticks` of the lock-step data flow (of a run of `steps` ticks, a
    /// controller every `period`), with the plant's steps `swap`ped at ticks 5 and 6.
    fn trace_file(name: &str, steps: u64, ticks: u64, swap: bool) -> std::path::PathBuf {
        let (period, dt_s) = (10, 1e-3);
        let dir = std::env::temp_dir().join(format!("tiltsim-trace-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        let head = trace::TraceHead {
            dt_s,
            steps,
            controller_period_ticks: period,
            start_ns: 0,
        };
        let mut w = trace::TraceWriter::create(&path, &head).unwrap();
        let plant = |k: u64| step(Role::Plant, k, [None, Some(k as i64 - 1), None]);
        for k in 0..ticks {
            if k.is_multiple_of(period) {
                w.push(&step(Role::Controller, k, [Some(k as i64 - 1), None, None]))
                    .unwrap();
            }
            let held = (k / period * period) as i64;
            w.push(&step(
                Role::Actuator,
                k,
                [Some(k as i64 - 1), None, Some(held)],
            ))
            .unwrap();
            let k = match (swap, k) {
                (true, 5) => 6,
                (true, 6) => 5,
                _ => k,
            };
            w.push(&plant(k)).unwrap();
        }
        w.finish().unwrap();
        path
    }

    /// Reading a trace one step at a time gives the steps and the verdict of reading it whole,
    /// and refuses a role's steps out of the order the writer keeps.
    #[test]
    fn a_trace_read_step_by_step_is_the_trace_read_whole() {
        for (name, ticks) in [("whole.csv", 100), ("partial.csv", 55)] {
            let path = trace_file(name, 100, ticks, false);
            let whole = trace::read(&path, 1e-3, 100, 10).unwrap();
            let mut seen = Vec::new();
            let partial = trace::each_step(&path, 1e-3, 100, 10, |t| seen.push(*t)).unwrap();
            assert_eq!(seen, whole.steps);
            assert_eq!(partial, whole.partial);
            assert_eq!(partial.is_some(), ticks < 100);
        }
        let path = trace_file("swapped.csv", 100, 100, true);
        assert!(trace::read(&path, 1e-3, 100, 10).is_ok());
        let e = trace::each_step(&path, 1e-3, 100, 10, |_| {}).unwrap_err();
        assert!(e.to_string().contains("plant step 6"), "{e}");
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }

    /// What a free run holds in memory does not grow with its length: over 200 000 ticks
    /// (200 s at 1 ms) of the lock-step data flow, every row written, the store holds a few
    /// entries of each kind once it forgets what no later step or row can name.
    #[test]
    fn the_store_holds_a_bounded_window_whatever_the_run_length() {
        let period = 10;
        let steps = 200_000u64;
        let mut store = compose::Store::new(period, 1e-3, &Default::default(), 1);
        store.put_init(Default::default(), Default::default(), Default::default());
        let mut rows = RowStream {
            rec: RowRecorder::new(RowSink::Kept(Vec::new())),
            next: 0,
            reads: [-1; 3],
        };
        rows.start(&store).unwrap();
        let mut largest = 0;
        let mut qc = -1i64;
        for k in 0..steps {
            let qp = k as i64 - 1;
            if k % period == 0 {
                store.note_read(&step(Role::Controller, k, [Some(qp), None, None]));
                store.put_controller(k, Default::default());
                qc = k as i64;
            }
            store.note_read(&step(Role::Actuator, k, [Some(qp), None, Some(qc)]));
            store.put_actuator(k, Default::default());
            store.note_read(&step(Role::Plant, k, [None, Some(k as i64), None]));
            store.put_plant(k, Default::default());
            rows.advance(&store, steps).unwrap();
            assert_eq!(rows.next, k + 1, "row {k} could not be composed");
            // What later steps will name: this tick's outputs and the controller's last.
            let mut floor = rows.floor();
            floor[0] = floor[0].min(k as i64);
            floor[2] = floor[2].min(qc);
            store.forget_before(floor);
            largest = largest.max(store.held());
        }
        let (ticks, kept, err) = rows.finish();
        assert_eq!((ticks, err), (steps, None));
        assert_eq!(kept.map(|r| r.len() as u64), Some(steps + 1));
        // Per window, the entries since the oldest step still named: at most a controller
        // period of plant and actuator steps.
        assert!(largest <= 12 * period as usize, "{largest} entries held");
    }
}
