//! How to run a scenario, how a run ended, and why it could not start.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use cosim::Role;
use serde::Serialize;

/// How to run a scenario (command-line choices on top of the file). What the run writes
/// beside its summary and events is chosen apart from this: observers added to a lock-step
/// [`Run`](super::Run) ([`super::outputs`]), or the [`Outputs`](super::outputs::Outputs) a free
/// run reads.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Output directory.
    pub out_dir: PathBuf,
    /// Executable that serves `participant ROLE ...` (normally `tiltsim` itself).
    pub participant_exe: PathBuf,
    /// Other executables for some roles (test participants that misbehave on purpose).
    pub participant_overrides: Vec<(Role, PathBuf)>,
    /// iceoryx2 prefix; a unique one is made when `None`.
    pub ipc_prefix: Option<String>,
    /// Set by Ctrl-C.
    pub interrupt: Arc<AtomicBool>,
    /// Draw `plots/` after the run (the caller's analysis step reads this).
    pub plots: bool,
    /// Run the lock-step at this many simulated seconds per wall second.
    pub pace: Option<f64>,
    /// Run every process under `SCHED_FIFO` at this priority with memory locked (paced runs).
    pub realtime: Option<i32>,
    /// Measure wall-clock times: each exchange's send and receive stamps and each
    /// participant's compute per call (link latency, compute statistics, `trace.csv`). A
    /// sweep's in-process samples turn it off: they report none of it, and the clock reads
    /// cost about 5 % of a sample. Values never depend on it.
    pub timing: bool,
    /// The secret participants on other hosts prove they hold to join (`[network]`); one is
    /// drawn and printed with the command that joins when `None`.
    pub network_secret: Option<String>,
}

impl RunOptions {
    /// Options for a run into `out_dir` with participants served by `participant_exe`: a
    /// unique iceoryx2 prefix, plots drawn, no interrupt flag shared.
    pub fn new(out_dir: PathBuf, participant_exe: PathBuf) -> Self {
        RunOptions {
            out_dir,
            participant_exe,
            participant_overrides: Vec::new(),
            ipc_prefix: None,
            interrupt: Arc::new(AtomicBool::new(false)),
            plots: true,
            pace: None,
            realtime: None,
            timing: true,
            network_secret: None,
        }
    }
}

/// How the run ended.
#[derive(Debug, Clone, Copy, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Every step done.
    Completed,
    /// A participant failed; the message names it and the step.
    Failed,
    /// Every step done, but a participant was lost and replaced by its degraded mode.
    Degraded,
    /// Ctrl-C.
    Interrupted,
}

/// As `summary.json` spells it: `completed`, `failed`, `degraded`, `interrupted`.
impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Status::Completed => "completed",
            Status::Failed => "failed",
            Status::Degraded => "degraded",
            Status::Interrupted => "interrupted",
        })
    }
}

/// Why a run could not start or its outputs could not be written.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Output directory or files.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// Transport set-up.
    #[error(transparent)]
    Ipc(#[from] cosim::ipc::IpcError),
    /// The network transport (`[network]`): a participant never joined, the address could
    /// not be listened on.
    #[error(transparent)]
    Net(#[from] tiltsim_net::NetError),
    /// The controller design failed.
    #[error("controller design: {0}")]
    Design(String),
    /// The interrupt flag (Ctrl-C, SIGTERM, SIGHUP) was set while a participant was
    /// starting; it was stopped and nothing was recorded.
    #[error("interrupted while participant {role} was starting")]
    Interrupted {
        /// The participant that was starting.
        role: cosim::Role,
    },
    /// The caller's observers cannot run together.
    #[error("observers: {0}")]
    Observer(String),
    /// An FMU participant could not be loaded or initialised.
    #[error("{role}: {message}")]
    Fmu {
        /// The role it was to play.
        role: cosim::Role,
        /// What went wrong.
        message: String,
    },
}

impl RunError {
    /// An I/O error on `path`.
    pub fn io(path: PathBuf) -> impl FnOnce(std::io::Error) -> RunError {
        move |source| RunError::Io { path, source }
    }
}
