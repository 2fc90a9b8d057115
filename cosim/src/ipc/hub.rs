//! The orchestrator's side of the transport: the run's hub and one endpoint per participant.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use crate::endpoint::{check_reply, Endpoint, ExitReport, LinkError, ProcessFault};
use crate::msg::{Header, Kind, Message};
use crate::participant::Role;
use crate::wait::{Backoff, WaitStrategy};

use super::supervise::try_reap;
use super::{
    config, drain, iox, node, quiet_iceoryx_logs, reply_service, request_service, service,
    IpcError, IpcSettings,
};

/// The orchestrator's side of the transport for one run.
pub struct IpcHub {
    settings: IpcSettings,
    cfg: Config,
    node: Node<ipc::Service>,
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
        let node = node(&cfg, "orchestrator")?;
        Ok(IpcHub {
            settings,
            cfg,
            node,
        })
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
        let req = service::<I>(&self.node, &request_service(role))?;
        let rep = service::<O>(&self.node, &reply_service(role))?;
        let publisher = req
            .publisher_builder()
            .create()
            .map_err(iox("create publisher"))?;
        let subscriber = rep
            .subscriber_builder()
            .create()
            .map_err(iox("create subscriber"))?;

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
            .stderr(Stdio::inherit());
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
        let child = cmd.spawn().map_err(|source| IpcError::Spawn {
            role,
            program: launch.program.display().to_string(),
            source,
        })?;
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
            starved_waits: 0,
        };
        ep.await_connection(startup)?;
        Ok(ep)
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

/// The orchestrator's handle on a participant process.
pub struct IpcEndpoint<I: Message, O: Message> {
    role: Role,
    pid: u32,
    child: Option<Child>,
    exit: Option<ExitReport>,
    publisher: Publisher<ipc::Service, I, ()>,
    subscriber: Subscriber<ipc::Service, O, ()>,
    req: PubSubFactory<ipc::Service, I, ()>,
    rep: PubSubFactory<ipc::Service, O, ()>,
    wait: WaitStrategy,
    /// Polls spent spinning before yielding: 0 when the participant shares this CPU.
    spin_polls: u32,
    deadline: Duration,
    ceiling: Duration,
    /// Times a reply was late but the participant was running (starved, not hung).
    starved_waits: u64,
}

/// Whether a participant that has not answered by the deadline is hung or only slow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Liveness {
    /// Stopped, or sleeping without using CPU: it will not answer.
    Hung,
    /// Runnable or using CPU: starved by other load (or busy); wait on.
    Running,
}

/// State and CPU ticks (user + system) of process `pid`, from `/proc/<pid>/stat`.
fn proc_stat(pid: u32) -> Option<(char, u64)> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name, which is in parentheses and may hold spaces.
    let rest = s.get(s.rfind(')')? + 2..)?;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let state = f.first()?.chars().next()?;
    let cpu = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    Some((state, cpu))
}

/// The verdict on `pid` given the CPU ticks seen at the previous check (`None` at the first).
fn liveness(pid: u32, previous_cpu: Option<u64>) -> (Liveness, Option<u64>) {
    match proc_stat(pid) {
        None => (Liveness::Hung, None),
        Some(('T' | 't', cpu)) => (Liveness::Hung, Some(cpu)),
        Some(('R', cpu)) => (Liveness::Running, Some(cpu)),
        Some((_, cpu)) => match previous_cpu {
            Some(prev) if cpu > prev => (Liveness::Running, Some(cpu)),
            // First look: a short second look decides.
            None => (Liveness::Running, Some(cpu)),
            Some(_) => (Liveness::Hung, Some(cpu)),
        },
    }
}

impl<I: Message, O: Message> IpcEndpoint<I, O> {
    fn exited(&mut self) -> Option<String> {
        if let Some(r) = &self.exit {
            return Some(r.status.clone());
        }
        self.child.as_ref()?;
        let report = try_reap(self.pid, false)?;
        self.child = None;
        let status = report.status.clone();
        self.exit = Some(report);
        Some(status)
    }

    fn await_connection(&mut self, startup: Duration) -> Result<(), LinkError> {
        let started = Instant::now();
        loop {
            let subs = self.req.dynamic_config().number_of_subscribers();
            let pubs = self.rep.dynamic_config().number_of_publishers();
            if subs >= 1 && pubs >= 1 {
                return Ok(());
            }
            if let Some(status) = self.exited() {
                return Err(LinkError::Exited {
                    role: self.role,
                    pid: self.pid,
                    step: 0,
                    status,
                });
            }
            if started.elapsed() > startup {
                return Err(LinkError::Timeout {
                    role: self.role,
                    pid: self.pid,
                    step: 0,
                    deadline_ms: startup.as_millis() as u64,
                });
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}

impl<I: Message, O: Message> Endpoint<I, O> for IpcEndpoint<I, O> {
    fn role(&self) -> Role {
        self.role
    }
    fn pid(&self) -> u32 {
        self.pid
    }
    fn send(&mut self, req: &I) -> Result<(), LinkError> {
        let mut req = *req;
        req.stamp();
        super::publish(&self.publisher, req).map_err(|what| LinkError::Transport {
            role: self.role,
            what,
        })
    }
    fn receive(&mut self, step: u64, kind: Kind) -> Result<O, LinkError> {
        let mut backoff = Backoff::with_spin(self.wait, self.spin_polls);
        let mut found = None;
        let mut look_at = self.deadline;
        let mut last_cpu: Option<u64> = None;
        if let Some(r) = &self.exit {
            // Already known to be gone (a kill fault reaps at once).
            return Err(LinkError::Exited {
                role: self.role,
                pid: self.pid,
                step,
                status: r.status.clone(),
            });
        }
        loop {
            drain(self.role, &self.subscriber, step, &mut found)?;
            if let Some(reply) = found {
                check_reply::<I, O>(self.role, &reply, step, kind)?;
                return Ok(reply);
            }
            // A dead process is noticed within ~1k polls. At the deadline a stopped or idle
            // process is declared stalled; one that runs (starved by other load) is waited
            // for, looking again every 100 ms, up to the ceiling.
            if backoff.polls() % 1024 == 1023 || backoff.elapsed() > look_at {
                if let Some(status) = self.exited() {
                    return Err(LinkError::Exited {
                        role: self.role,
                        pid: self.pid,
                        step,
                        status,
                    });
                }
                let elapsed = backoff.elapsed();
                if elapsed > look_at {
                    let (verdict, cpu) = liveness(self.pid, last_cpu);
                    last_cpu = cpu;
                    let limit = if verdict == Liveness::Hung {
                        Some(self.deadline)
                    } else if elapsed > self.ceiling {
                        Some(self.ceiling)
                    } else {
                        None
                    };
                    if let Some(limit) = limit {
                        return Err(LinkError::Timeout {
                            role: self.role,
                            pid: self.pid,
                            step,
                            deadline_ms: limit.as_millis() as u64,
                        });
                    }
                    self.starved_waits += 1;
                    look_at = elapsed + Duration::from_millis(100);
                }
            }
            backoff.pause();
        }
    }
    fn starved_waits(&self) -> u64 {
        self.starved_waits
    }
    fn set_shares_cpu(&mut self, shared: bool) {
        self.spin_polls = if shared { 0 } else { crate::wait::SPIN_POLLS };
    }
    fn await_pending(&mut self) {
        // Bounded well below the deadline: a participant that does not answer soon is left
        // to `receive`, which tells a dead, stalled or starved one apart.
        let started = Instant::now();
        let limit = self.deadline.min(crate::wait::YIELD_FOR);
        while self.exit.is_none()
            && !self.subscriber.has_samples().unwrap_or(true)
            && started.elapsed() < limit
        {
            std::thread::yield_now();
        }
    }
    fn inject(&mut self, fault: ProcessFault) {
        let pid = self.pid as libc::pid_t;
        match fault {
            ProcessFault::Kill => {
                // SAFETY: a signal to our own child, which we have not reaped yet.
                unsafe { libc::kill(pid, libc::SIGKILL) };
                // Reap it now, so that the next exchange finds it gone, deterministically.
                let until = Instant::now() + Duration::from_secs(2);
                while self.exited().is_none() && Instant::now() < until {
                    std::thread::sleep(Duration::from_micros(200));
                }
            }
            ProcessFault::Stall(d) => {
                // SAFETY: as above; the thread resumes it after `d` (a no-op if it died).
                unsafe { libc::kill(pid, libc::SIGSTOP) };
                std::thread::spawn(move || {
                    std::thread::sleep(d);
                    unsafe { libc::kill(pid, libc::SIGCONT) };
                });
            }
        }
    }
    fn shutdown(&mut self) -> ExitReport {
        if let Some(report) = &self.exit {
            return report.clone();
        }
        let Some(mut child) = self.child.take() else {
            return ExitReport {
                status: "unknown".into(),
                cpu_s: None,
            };
        };
        // Ask politely, then insist: a stopped or hung participant is killed.
        let _ = super::publish(&self.publisher, {
            let mut m = I::default();
            *m.header_mut() = Header::new(u64::MAX, Kind::Stop);
            m
        });
        let started = Instant::now();
        let mut report = None;
        while report.is_none() && started.elapsed() < Duration::from_millis(500) {
            report = try_reap(self.pid, false);
            if report.is_none() {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        let report = report.unwrap_or_else(|| {
            // SIGKILL also ends a stopped (SIGSTOP) or hung process.
            let _ = child.kill();
            try_reap(self.pid, true).unwrap_or(ExitReport {
                status: "unknown".into(),
                cpu_s: None,
            })
        });
        self.exit = Some(report.clone());
        report
    }
}

impl<I: Message, O: Message> Drop for IpcEndpoint<I, O> {
    fn drop(&mut self) {
        if self.child.is_some() {
            self.shutdown();
        }
    }
}
