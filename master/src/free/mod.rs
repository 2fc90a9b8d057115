//! The free-running execution mode and its exact lock-step replay (docs/architecture.md,
//! "Execution modes").
//!
//! * [`run`]: every participant process steps on its own wall-clock timer from one common
//!   start instant and reads, at each step, the newest input that has arrived; the
//!   orchestrator is the hub that composes each consumer's input from the newest producer
//!   outputs, relays it without waiting, and records the timing trace (`timing.csv`).
//! * [`replay`]: a lock-step run, in-process or over IPC, that feeds each consumer step
//!   exactly the producer outputs the trace says it read, in the order of the read instants.
//! * [`compose`]: the inputs and the rows of `timeseries.csv`, shared by both, so that the
//!   replay's rows are the free run's byte for byte.
//! * [`trace`]: `timing.csv`, written and read back with its checks.

pub mod compose;
pub mod record;
pub mod replay;
pub mod run;
pub mod trace;

use std::path::Path;

use cosim::msg::{FromActuator, FromController, FromPlant, Header, Kind};
use cosim::msg::{ToActuator, ToController, ToPlant};
use cosim::settings::Checker;
use cosim::LinkError;

use crate::engine::launch::Participants;
use crate::engine::RunError;
use crate::record::Recorder;
use crate::scenario::{Execution, Scenario, Transport};

pub use replay::replay;
pub use run::{run, FreeReport};
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
    /// A participant failed during a replay.
    #[error(transparent)]
    Link(#[from] LinkError),
}

impl FreeError {
    fn io(path: &Path, source: std::io::Error) -> FreeError {
        FreeError::Run(RunError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

impl Scenario {
    /// The rules of `run.execution` and `run.controller_busy_wait_s`.
    pub(crate) fn validate_execution(&self, c: &mut Checker) {
        let r = &self.run;
        c.range(
            "controller_busy_wait_s",
            r.controller_busy_wait_s,
            0.0,
            1.0,
            "s",
        );
        if r.execution == Execution::LockStep {
            c.require(
                r.controller_busy_wait_s == 0.0,
                "controller_busy_wait_s",
                r.controller_busy_wait_s,
                "0 unless run.execution = \"free\" (a lock-step run's values do not depend on compute time)",
            );
            return;
        }
        c.require(
            r.transport == Transport::Ipc,
            "execution",
            "\"free\"",
            "\"free\" only with run.transport = \"ipc\": in one process the participants have no clocks of their own",
        );
        c.require(
            self.faults.on_failure == crate::faults::OnFailure::Abort,
            "execution",
            "\"free\"",
            "\"lock-step\" when faults.on_failure = \"degrade\" (a free run ends, naming the participant, when one fails; stand-ins replace participants in lock-step only)",
        );
    }
}

/// Removes a run's shared-memory files when dropped (on every way out).
pub(crate) struct FilesGuard(pub String);

impl Drop for FilesGuard {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            cosim::ipc::remove_run_files(&self.0);
        }
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
) -> crate::events::EventLog {
    let mut ev = crate::events::EventLog::new(s.run.dt_s);
    crate::links::LinkSet::describe(&s.links, &mut ev);
    crate::engine::manipulator::FaultSchedule::new(&s.faults, s.run.dt_s).log_until(rows, &mut ev);
    let links = store.events();
    let mut merged = Vec::with_capacity(ev.events.len() + links.events.len());
    let mut a = ev.events.into_iter().peekable();
    let mut b = links.events.into_iter().peekable();
    loop {
        let take_a = match (a.peek(), b.peek()) {
            (Some(x), Some(y)) => x.step <= y.step,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => break,
        };
        merged.extend(if take_a { a.next() } else { b.next() });
    }
    ev.events = merged;
    ev
}

/// Writes `dir/timeseries.csv` from the store: the row at the start time, then the row after
/// each tick up to the first that cannot be composed (a run that ended early). Returns the
/// number of ticks written.
pub(crate) fn write_rows(dir: &Path, store: &compose::Store, steps: u64) -> std::io::Result<u64> {
    let mut rec = Recorder::create(&dir.join("timeseries.csv"))?;
    rec.write(&store.row_at_start())?;
    let mut n = 0;
    for k in 0..steps {
        let Some(row) = store.row(k) else { break };
        rec.write(&row)?;
        n += 1;
    }
    rec.finish()?;
    Ok(n)
}
