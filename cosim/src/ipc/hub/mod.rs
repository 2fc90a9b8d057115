//! The orchestrator's side of the transport: the run's hub, which starts the participant
//! processes ([`IpcHub`]), and one endpoint per participant ([`IpcEndpoint`], in `endpoint`),
//! whose stall check judges a silent participant (`liveness`). Each participant's standard
//! error goes to a file (`logs`).

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use iceoryx2::prelude::*;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use crate::endpoint::ExchangeCounts;
use crate::msg::Message;
use crate::participant::Role;

use super::supervise::Status;
use super::{
    config, iox, node, quiet_iceoryx_logs, reply_service, request_service, service, Direction,
    DropPlan, IpcError, IpcSettings,
};

mod endpoint;
mod liveness;
mod logs;
#[cfg(test)]
mod tests;

pub use endpoint::IpcEndpoint;
use logs::LogDir;

/// The orchestrator's side of the transport for one run.
pub struct IpcHub {
    settings: IpcSettings,
    cfg: Config,
    node: Node<ipc::Service>,
    interrupt: Option<Arc<AtomicBool>>,
    logs: LogDir,
}

/// How to start a participant's process.
#[derive(Debug, Clone)]
pub struct Launch {
    /// Executable.
    pub program: PathBuf,
    /// Arguments before the transport's own (`--prefix`, `--wait`, `--deadline-ms`).
    pub args: Vec<OsString>,
}

impl IpcHub {
    /// Opens the orchestrator's node.
    pub fn new(settings: IpcSettings) -> Result<Self, IpcError> {
        quiet_iceoryx_logs();
        let cfg = config(&settings.prefix)?;
        // Whatever the prefix, a run whose orchestrator is killed has its files removed by
        // the next run or `tiltsim clean`.
        super::claim_prefix(&settings.prefix)
            .map_err(|e| IpcError::Iceoryx(format!("owner file of {}: {e}", settings.prefix)))?;
        let node = node(&cfg, "orchestrator")?;
        let logs = LogDir::scratch(&settings.prefix);
        Ok(IpcHub {
            settings,
            cfg,
            node,
            interrupt: None,
            logs,
        })
    }

    /// Writes each participant's standard error to `dir/ROLE.log` ([`IpcHub::log_file`]),
    /// created at its start, and leaves the files there for the caller (who removes the empty
    /// ones and reports the others). Without it, a hub writes them to a directory of its own
    /// under the system's temporary directory, removed with them when the hub is dropped: what
    /// a participant wrote is then lost, except the last line of one that ended while starting,
    /// which its error quotes.
    pub fn logs_into(mut self, dir: PathBuf) -> Self {
        self.logs = LogDir::Run(dir);
        self
    }

    /// The standard error of the participant `role` in a log directory `dir`: `dir/ROLE.log`.
    pub fn log_file(dir: &Path, role: Role) -> PathBuf {
        logs::log_file(dir, role)
    }

    /// Makes [`IpcHub::spawn`] stop waiting for a participant to connect, and stop it, once
    /// `flag` is set (the program's interrupt flag: Ctrl-C during a long start-up).
    pub fn interrupted_by(mut self, flag: Arc<AtomicBool>) -> Self {
        self.interrupt = Some(flag);
        self
    }

    /// The run's settings.
    pub fn settings(&self) -> &IpcSettings {
        &self.settings
    }

    /// Creates the participant's services, starts its process and waits until it is connected.
    pub fn spawn<I: Message, O: Message>(
        &self,
        role: Role,
        launch: &Launch,
        startup: Duration,
    ) -> Result<IpcEndpoint<I, O>, IpcError> {
        let req = service::<I>(&self.node, &request_service(role), Direction::Request)?;
        let rep = service::<O>(&self.node, &reply_service(role), Direction::Reply)?;
        let publisher = req
            .publisher_builder()
            .create()
            .map_err(iox("create publisher"))?;
        let subscriber = rep
            .subscriber_builder()
            .create()
            .map_err(iox("create subscriber"))?;

        let status = Status::create(&self.settings.prefix, role)
            .map_err(|e| IpcError::Iceoryx(format!("status of {role}: {e}")))?;
        let spawn_error = |source| IpcError::Spawn {
            role,
            program: launch.program.display().to_string(),
            source,
        };
        // A file, never a pipe: a participant never waits for a reader of its output.
        let (log, stderr) = self.logs.open(role).map_err(spawn_error)?;
        let mut cmd = Command::new(&launch.program);
        cmd.args(&launch.args)
            .arg("--prefix")
            .arg(&self.settings.prefix)
            .arg("--wait")
            .arg(self.settings.wait.name());
        if let Some(cpu) = self.settings.participant_cpu {
            cmd.arg("--cpu").arg(cpu.to_string());
        }
        cmd.stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::from(stderr));
        {
            use std::os::unix::process::CommandExt;
            // Own process group: a terminal Ctrl-C reaches the orchestrator only, which then
            // stops the participants in order.
            cmd.process_group(0);
            // SAFETY: prctl is async-signal-safe; it only asks the kernel to kill this child
            // when the orchestrator dies, so no participant outlives its run.
            unsafe {
                cmd.pre_exec(|| {
                    libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                    Ok(())
                });
            }
        }
        let child = cmd.spawn().map_err(spawn_error)?;
        let mut ep = IpcEndpoint {
            role,
            pid: child.id(),
            child: Some(child),
            exit: None,
            publisher,
            subscriber,
            req,
            rep,
            wait: self.settings.wait,
            spin_polls: crate::wait::SPIN_POLLS,
            deadline: self.settings.deadline,
            ceiling: self.settings.ceiling,
            counts: ExchangeCounts::default(),
            status,
            last_request: None,
            resent: None,
            drops: DropPlan::from_env(role),
            log: Some(log),
            free_pending: 0,
            ahead: None,
            early: None,
        };
        let connected = ep.await_connection(startup, self.interrupt.as_deref())?;
        if !connected {
            // Dropping the endpoint stops the process.
            return Err(IpcError::Interrupted { role });
        }
        Ok(ep)
    }

    /// An endpoint for a participant served in this process (tests of the exchange itself).
    #[cfg(test)]
    fn attach<I: Message, O: Message>(&self, role: Role) -> Result<IpcEndpoint<I, O>, IpcError> {
        let req = service::<I>(&self.node, &request_service(role), Direction::Request)?;
        let rep = service::<O>(&self.node, &reply_service(role), Direction::Reply)?;
        Ok(IpcEndpoint {
            role,
            pid: std::process::id(),
            child: None,
            exit: None,
            publisher: req
                .publisher_builder()
                .create()
                .map_err(iox("create publisher"))?,
            subscriber: rep
                .subscriber_builder()
                .create()
                .map_err(iox("create subscriber"))?,
            req,
            rep,
            wait: self.settings.wait,
            spin_polls: crate::wait::SPIN_POLLS,
            deadline: self.settings.deadline,
            ceiling: self.settings.ceiling,
            counts: ExchangeCounts::default(),
            status: Status::create(&self.settings.prefix, role)
                .map_err(|e| IpcError::Iceoryx(format!("status: {e}")))?,
            last_request: None,
            resent: None,
            drops: DropPlan::default(),
            log: None,
            free_pending: 0,
            ahead: None,
            early: None,
        })
    }

    /// Removes the resources of this run's participants that died without cleaning up.
    pub fn cleanup_dead(&self) -> u64 {
        self.node.try_cleanup_dead_nodes().cleanups
    }

    /// Names of nodes of this run that are dead (for reports).
    pub fn dead_nodes(&self) -> Vec<String> {
        let mut out = Vec::new();
        let _ = Node::<ipc::Service>::list(&self.cfg, |state| {
            if let NodeState::Dead(view) = state {
                use iceoryx2::node::NodeView;
                let name = view
                    .details()
                    .as_ref()
                    .map(|d| d.name().to_string())
                    .unwrap_or_else(|| "?".into());
                out.push(name);
            }
            CallbackProgression::Continue
        });
        out
    }
}
