//! The floor every run loop stands on — lock-step ([`super::simulate`]), free running
//! (`free::run`) and the timing replay (`free::replay_timing`): a [`Session`] prepares the
//! output directory, claims the run's shared-memory prefix and guards it, starts the
//! participants, and at the end shuts them down, cleans up what they leave, and writes the
//! files every run has besides its rows (`events.csv`, `columns.csv`). How the run ended is
//! told by [`status`] in the same words for all three, and the sections of `summary.json`
//! they share are filled by [`Closed::fill`].

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use cosim::endpoint::{ExchangeCounts, ExitReport};
use cosim::Role;
use tiltsim_formats::events::EventLog;
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::{Scenario, Transport};

use super::launch::{self, Participants};
use super::summary::{NetworkReport, ParticipantReport, Summary};
use super::{finish_logs, RunError, RunOptions, Status};
use cosim::stats::Percentiles;

/// A run between the start of its participants and their shut-down. Dropped without
/// [`Session::close`] (an error, a panic), it still removes the run's shared-memory files.
pub(crate) struct Session<'a> {
    s: &'a Scenario,
    opts: &'a RunOptions,
    /// Whether the run writes files to `opts.out_dir` (not an in-process replay whose rows
    /// are kept in memory).
    files: bool,
    /// The run's iceoryx2 prefix (empty in one process).
    prefix: String,
    _guard: RunFilesGuard,
    /// This process's CPU set before the run, restored at the end (a run may pin it).
    cpus: Vec<usize>,
    /// This process's CPU time at the start (s).
    cpu0: f64,
}

/// What a closed session leaves for the run's report.
pub(crate) struct Closed {
    /// Each participant's exit.
    pub exits: RoleMap<ExitReport>,
    /// Each participant's process id.
    pub pids: RoleMap<u32>,
    /// Each participant's exchange counts (waits for a starved participant, lost samples).
    pub counts: RoleMap<ExchangeCounts>,
    /// Participants on other hosts: who joined, their clocks.
    pub network: Option<NetworkReport>,
    /// Where the run placed its processes.
    pub placement: Option<cosim::ipc::placement::Placement>,
    /// How the participants pinned together handed their CPU over.
    pub hand_over: Option<tiltsim_scenario::scenario::HandOver>,
    /// Shared-memory files left behind (empty unless something is wrong).
    pub leftover: Vec<String>,
    /// Participant logs that are not empty.
    pub participant_logs: Vec<String>,
    /// The run's iceoryx2 prefix.
    pub prefix: String,
    /// CPU time of this process during the session (s).
    pub cpu_orchestrator_s: f64,
}

impl<'a> Session<'a> {
    /// Prepares `opts.out_dir` (when `files`: participants in other processes log there, so
    /// an IPC run always has it), guards the run's prefix and starts the participants. A
    /// participant that fails to start has been stopped by now, and its log stays (the error
    /// quotes its last line).
    pub(crate) fn start(
        s: &'a Scenario,
        opts: &'a RunOptions,
        files: bool,
    ) -> Result<(Session<'a>, Participants), RunError> {
        let files = files || s.run.transport == Transport::Ipc;
        if files {
            prepare(s, opts)?;
        }
        let prefix = ipc_prefix(s, opts);
        let session = Session {
            s,
            opts,
            files,
            _guard: RunFilesGuard(prefix.clone()),
            prefix,
            // `start` may pin this process to one CPU for the run; the set is restored at the
            // end so a process that runs several scenarios (sweeps, benchmarks) starts each
            // one alike.
            cpus: cosim::ipc::allowed_cpus(),
            cpu0: launch::cpu_self(),
        };
        let ps = launch::start(s, opts, &session.prefix).inspect_err(|_| {
            if s.run.transport == Transport::Ipc {
                finish_logs(&opts.out_dir);
            }
        })?;
        Ok((session, ps))
    }

    /// Stops every participant (those in `lost` were replaced by stand-ins and have ended
    /// already), removes the run's shared-memory files, FMUs unpacked by participants that
    /// were killed and the empty participant logs, and restores this process's CPU set.
    pub(crate) fn close(self, mut ps: Participants, lost: RoleMap<Option<ExitReport>>) -> Closed {
        let pids = ps.pids();
        let counts = ps.counts();
        let placement = ps.placement.take();
        let hand_over = ps.hand_over;
        let exits = ps.shut_down(lost);
        let network = ps.net.as_ref().map(NetworkReport::of);
        if !self.s.participants.is_empty() {
            tiltsim_fmi::archive::remove_dead_unpacked();
        }
        let mut leftover = Vec::new();
        let mut participant_logs = Vec::new();
        if let Some(hub) = ps.hub.take() {
            hub.cleanup_dead();
            drop(ps);
            drop(hub);
            cosim::ipc::remove_run_files(&self.prefix);
            leftover = cosim::ipc::leftover_files(&self.prefix)
                .iter()
                .map(|p| p.display().to_string())
                .collect();
            participant_logs = finish_logs(&self.opts.out_dir);
        }
        if !self.cpus.is_empty() {
            cosim::ipc::set_cpus(&self.cpus);
        }
        Closed {
            exits,
            pids,
            counts,
            network,
            placement,
            hand_over,
            leftover,
            participant_logs,
            cpu_orchestrator_s: launch::cpu_self() - self.cpu0,
            prefix: self.prefix.clone(),
        }
    }

    /// The CPUs this process was allowed before the run.
    pub(crate) fn cpus(&self) -> &[usize] {
        &self.cpus
    }

    /// The output directory, when the run writes files.
    pub(crate) fn dir(&self) -> Option<&'a Path> {
        self.files.then_some(self.opts.out_dir.as_path())
    }
}

/// Creates the output directory and writes `scenario.toml` (the scenario as run): every
/// mode's first step.
pub(crate) fn prepare(s: &Scenario, opts: &RunOptions) -> Result<(), RunError> {
    let dir = &opts.out_dir;
    std::fs::create_dir_all(dir).map_err(RunError::io(dir.clone()))?;
    let resolved = dir.join("scenario.toml");
    tiltsim_rundir::files::write_atomic(&resolved, toml::to_string(s).unwrap_or_default())
        .map_err(RunError::io(resolved))
}

/// Removes a run's shared-memory files when dropped: on every way out of a run (lock-step,
/// free or a timing replay), a failed start, an error, a panic, as well as the normal end
/// (where the shut-down has already removed them and reported any it could not).
struct RunFilesGuard(String);

/// The run's iceoryx2 prefix: the caller's, or a unique one; none in process.
fn ipc_prefix(s: &Scenario, opts: &RunOptions) -> String {
    match s.run.transport {
        Transport::Ipc => opts
            .ipc_prefix
            .clone()
            .unwrap_or_else(cosim::ipc::unique_prefix),
        Transport::InProcess => String::new(),
    }
}

impl Drop for RunFilesGuard {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            cosim::ipc::remove_run_files(&self.0);
        }
    }
}

impl Closed {
    /// Writes `events.csv` (`events`, with the network's connection attempts added) and
    /// `columns.csv` to `dir` (none: a run whose rows are kept in memory writes no file),
    /// keeping each failure, named, in `write_errors`; none skips the other.
    pub(crate) fn write_files(
        &self,
        dir: Option<&Path>,
        events: &mut EventLog,
        write_errors: &mut Vec<String>,
    ) {
        if let Some(n) = &self.network {
            n.log_attempts(events);
        }
        let Some(dir) = dir else {
            return;
        };
        let events_csv = dir.join("events.csv");
        if let Err(e) = events.write(&events_csv) {
            write_errors.push(format!("{}: {e}", events_csv.display()));
        }
        if let Err(e) = tiltsim_formats::columns::write_run(dir) {
            write_errors.push(format!("{}: {e}", dir.join("columns.csv").display()));
        }
    }

    /// Each participant's part of the summary: process, period and exit, with what the
    /// lock-step measured of it (`compute`: its step's compute time; its waits and lost
    /// samples). A free run and a replay measure neither, and report zeros.
    pub(crate) fn participants(
        &self,
        s: &Scenario,
        compute: Option<RoleMap<Percentiles>>,
    ) -> Vec<ParticipantReport> {
        let periods = RoleMap::new([s.run.dt_s, s.run.dt_s, s.controller.period_s]);
        Role::ALL
            .into_iter()
            .map(|role| ParticipantReport {
                role,
                process: role.process_name(),
                pid: self.pids[role],
                period_s: periods[role],
                exit: self.exits[role].clone(),
                compute_us: compute.as_ref().map(|c| c[role]).unwrap_or_default(),
                starved_waits: compute
                    .as_ref()
                    .map_or(0, |_| self.counts[role].starved_waits),
                lost_samples: compute
                    .as_ref()
                    .map(|_| self.counts[role].lost_samples)
                    .unwrap_or_default(),
                cue: compute
                    .as_ref()
                    .map(|_| self.counts[role].cue)
                    .unwrap_or_default(),
            })
            .collect()
    }

    /// Fills the sections of `sm` every run has from its session: the participants (with
    /// the lock-step's `compute`), the prefix, leftover files, logs and the network.
    pub(crate) fn fill(
        &self,
        s: &Scenario,
        sm: &mut Summary,
        compute: Option<RoleMap<Percentiles>>,
    ) {
        sm.participants = self.participants(s, compute);
        sm.ipc_prefix = self.prefix.clone();
        sm.leftover_ipc_files = self.leftover.clone();
        sm.participant_logs = self.participant_logs.clone();
        sm.network = self.network.clone();
    }
}

/// How a run ended, in the summary's words, for every loop alike: an interrupt (even one
/// that ended a participant first: a signal to the whole process group — systemd, Slurm's
/// scancel, a container runtime — reaches the participants too, and they end first, so the
/// run was interrupted, not failed by them), a degraded run, a completion or a failure.
pub(crate) fn status<E: std::fmt::Display>(
    outcome: &Result<(), E>,
    degraded: bool,
    interrupt: &AtomicBool,
) -> (Status, Option<String>) {
    let interrupted = interrupt.load(Ordering::Relaxed);
    match outcome {
        Ok(()) if interrupted => (
            Status::Interrupted,
            Some(format!(
                "interrupted by {}",
                tiltsim_rundir::signals::describe()
            )),
        ),
        Ok(()) if degraded => (
            Status::Degraded,
            Some("a participant was lost; the run continued degraded (events.csv)".into()),
        ),
        Ok(()) => (Status::Completed, None),
        Err(err) if interrupted => (
            Status::Interrupted,
            Some(format!(
                "interrupted by {} ({err})",
                tiltsim_rundir::signals::describe()
            )),
        ),
        Err(err) => (Status::Failed, Some(err.to_string())),
    }
}

/// The first file that could not be written fails a run that has no other error.
pub(crate) fn fail_on_write_error(sm: &mut Summary, write_errors: &[String]) {
    if let Some(e) = write_errors.first() {
        if sm.error.is_none() {
            sm.status = Status::Failed;
            sm.error = Some(format!("cannot write {e}"));
        }
    }
}
