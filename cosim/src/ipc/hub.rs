//! The orchestrator's side of the transport: the run's hub and one endpoint per participant.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::endpoint::{check_reply, Endpoint, ExchangeCounts, ExitReport, LinkError, ProcessFault};
use crate::msg::{exchange_key, Header, Kind, Message};
use crate::participant::Role;
use crate::wait::{Backoff, WaitStrategy};

use super::supervise::{proc_state, try_reap, Status};
use super::{
    config, iox, node, quiet_iceoryx_logs, reply_service, request_service, service, DropPlan,
    IpcError, IpcSettings, Resent,
};

/// The orchestrator's side of the transport for one run.
pub struct IpcHub {
    settings: IpcSettings,
    cfg: Config,
    node: Node<ipc::Service>,
    interrupt: Option<Arc<AtomicBool>>,
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
        Ok(IpcHub {
            settings,
            cfg,
            node,
            interrupt: None,
        })
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

        let status = Status::create(&self.settings.prefix, role)
            .map_err(|e| IpcError::Iceoryx(format!("status of {role}: {e}")))?;
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
            counts: ExchangeCounts::default(),
            status,
            last_request: None,
            resent: None,
            drops: DropPlan::from_env(role),
        };
        if !ep.await_connection(startup, self.interrupt.as_deref())? {
            // Dropping the endpoint stops the process.
            return Err(IpcError::Interrupted { role });
        }
        Ok(ep)
    }

    /// An endpoint for a participant served in this process (tests of the exchange itself).
    #[cfg(test)]
    fn attach<I: Message, O: Message>(&self, role: Role) -> Result<IpcEndpoint<I, O>, IpcError> {
        let req = service::<I>(&self.node, &request_service(role))?;
        let rep = service::<O>(&self.node, &reply_service(role))?;
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
    /// Starved waits, re-sent requests, discarded repeats.
    counts: ExchangeCounts,
    /// What the participant reports of its side.
    status: Status,
    /// The request last sent (re-sent with the next attempt when its exchange goes silent).
    last_request: Option<I>,
    /// The request last re-sent: answers to its repeats are expected.
    resent: Option<Resent>,
    /// Samples dropped on purpose (tests only).
    drops: DropPlan,
}

/// Silence after which a pending exchange is looked into (the participant's status read) and
/// a request or reply found lost is re-sent. Ten times the 99th percentile of a round trip
/// measured on a quiet machine (under 50 µs, `tiltsim bench`), so the normal path never reaches it;
/// short enough that a loss costs well under a millisecond or two. Looking costs three loads
/// from shared memory, and a re-send happens only when the status shows a loss, so a long
/// wait (a starved participant) costs nothing either.
pub const RESEND_AFTER: Duration = Duration::from_micros(500);

/// Interval between two looks at a participant that has not answered by its deadline.
const LOOK_EVERY: Duration = Duration::from_millis(100);

/// One look at a participant process: for the next look to compare with.
#[derive(Debug, Clone, Copy)]
struct Look {
    cpu_ns: u64,
    empty_polls: u64,
}

/// What the looks at a participant past its deadline remember: the previous look and the
/// first (for the ceiling), and how many looks in a row found it idle.
#[derive(Debug, Default)]
struct Looks {
    previous: Option<Look>,
    first: Option<Look>,
    idle: u32,
}

/// How many ceilings of wall time a running participant is waited for at most, whatever CPU
/// time it got: the bound on one that never gets going (in an uninterruptible wait for ever).
const WALL_CEILINGS: u32 = 10;

/// Whether a participant judged running has gone past the ceiling: it used more CPU time than
/// the ceiling since the first look (it computes for ever), or [`WALL_CEILINGS`] ceilings of
/// wall time have passed. CPU time, not wall time, is what the ceiling counts: a participant
/// starved by other load gets little of it, so load alone never makes it fail.
fn past_ceiling(
    ceiling: Duration,
    elapsed: Duration,
    first: Option<Look>,
    now: Option<Look>,
) -> bool {
    let cpu_ns = match (first, now) {
        (Some(f), Some(n)) => n.cpu_ns.saturating_sub(f.cpu_ns),
        _ => 0,
    };
    Duration::from_nanos(cpu_ns) > ceiling || elapsed > ceiling * WALL_CEILINGS
}

/// Whether a participant that has not answered by the deadline is hung or only slow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Liveness {
    /// Stopped, or sleeping without using CPU: it will not answer.
    Hung,
    /// Runnable or using CPU: starved by other load (or busy); wait on.
    Running,
    /// Polls but has not taken the pending request: it is re-sent, and a second such look
    /// declares the participant hung.
    Idle,
}

/// The verdict on a participant that has not answered by its deadline, from its process state,
/// its CPU time and its status, compared with the previous look (`None` at the first).
///
/// * Gone, or stopped (`T`): hung.
/// * Runnable (`R`) or in an uninterruptible wait (`D`): running, starved by other load.
/// * Took the request and computes: running while its CPU time grows, else hung (asleep with
///   the request in hand).
/// * Has not taken the request: hung if it keeps polling without taking it over two looks
///   (the request is re-sent at each), or if it neither polls nor uses CPU; else running.
fn judge(
    pid: u32,
    computing: bool,
    empty_polls: u64,
    previous: Option<Look>,
    idle_looks: &mut u32,
) -> (Liveness, Option<Look>) {
    let Some((state, cpu_ns)) = proc_state(pid) else {
        return (Liveness::Hung, None);
    };
    let look = Look {
        cpu_ns,
        empty_polls,
    };
    let verdict = match (state, previous) {
        ('T' | 't', _) => Liveness::Hung,
        ('R' | 'D', _) => Liveness::Running,
        // First look: a short second look decides.
        (_, None) => Liveness::Running,
        (_, Some(p)) if computing => {
            if cpu_ns > p.cpu_ns {
                Liveness::Running
            } else {
                Liveness::Hung
            }
        }
        (_, Some(p)) if empty_polls > p.empty_polls => {
            *idle_looks += 1;
            if *idle_looks >= 2 {
                Liveness::Hung
            } else {
                Liveness::Idle
            }
        }
        (_, Some(p)) if cpu_ns > p.cpu_ns => Liveness::Running,
        (_, Some(_)) => Liveness::Hung,
    };
    if verdict != Liveness::Idle {
        *idle_looks = 0;
    }
    (verdict, Some(look))
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

    /// Waits until the participant's ports are connected. The liveness rule of every exchange
    /// applies from `startup` on: a participant that is runnable or uses CPU (starting under
    /// load) is waited for, counted, up to the ceiling; a stopped, gone or idle one fails.
    /// Returns `false`, not connected, once `interrupt` is set.
    fn await_connection(
        &mut self,
        startup: Duration,
        interrupt: Option<&AtomicBool>,
    ) -> Result<bool, LinkError> {
        let started = Instant::now();
        let mut look_at = startup;
        let mut previous = None;
        let mut first = None;
        let mut idle_looks = 0;
        loop {
            let subs = self.req.dynamic_config().number_of_subscribers();
            let pubs = self.rep.dynamic_config().number_of_publishers();
            if subs >= 1 && pubs >= 1 {
                return Ok(true);
            }
            if interrupt.is_some_and(|f| f.load(Ordering::Relaxed)) {
                return Ok(false);
            }
            if let Some(status) = self.exited() {
                return Err(LinkError::Exited {
                    role: self.role,
                    pid: self.pid,
                    step: 0,
                    status,
                });
            }
            let elapsed = started.elapsed();
            if elapsed > look_at {
                // Not connected yet: never "computing", never polling.
                let (verdict, look) = judge(self.pid, false, 0, previous, &mut idle_looks);
                previous = look;
                first = first.or(look);
                let limit = match verdict {
                    Liveness::Hung | Liveness::Idle => Some(startup),
                    Liveness::Running if past_ceiling(self.ceiling, elapsed, first, look) => {
                        Some(self.ceiling)
                    }
                    Liveness::Running => None,
                };
                if let Some(limit) = limit {
                    return Err(LinkError::Timeout {
                        role: self.role,
                        pid: self.pid,
                        step: 0,
                        deadline_ms: limit.as_millis() as u64,
                    });
                }
                self.counts.starved_waits += 1;
                look_at = elapsed + LOOK_EVERY;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    /// Takes every reply waiting and keeps in `found` the one sample for `step`; any other
    /// sample is an error. The answer to a repeated request ([`Resent`]) that comes besides
    /// the one taken is discarded and counted; any other extra, stale or early sample stays an
    /// error.
    fn drain(&mut self, step: u64, kind: Kind, found: &mut Option<O>) -> Result<(), LinkError> {
        let role = self.role;
        loop {
            let sample = self
                .subscriber
                .receive()
                .map_err(|e| LinkError::Transport {
                    role,
                    what: format!("receive: {e:?}"),
                })?;
            let Some(sample) = sample else { return Ok(()) };
            let value: O = *sample;
            drop(sample);
            let h = value.header();
            if self.resent.is_some_and(|r| r.answers_repeat(h)) {
                // The answer to a repeat is taken only as the first answer to the pending
                // request (the original request or reply was lost); any other is an expected
                // extra.
                let pending = Header::new(step, kind);
                let first_for_pending = found.is_none()
                    && crate::msg::exchange_key(h) == crate::msg::exchange_key(&pending);
                if !first_for_pending {
                    self.counts.lost_samples.repeats_discarded += 1;
                    continue;
                }
            }
            let got = h.step;
            if got < step {
                return Err(LinkError::Stale {
                    role,
                    expected: step,
                    got,
                });
            }
            if got > step {
                return Err(LinkError::OutOfOrder {
                    role,
                    expected: step,
                    got,
                });
            }
            if found.is_some() {
                return Err(LinkError::Duplicate { role, step });
            }
            *found = Some(value);
        }
    }

    /// A look at a participant whose reply is past the deadline: a reply that came since the
    /// last drain is taken (`Ok(true)`); else a hung participant, or one past the ceiling, is
    /// an error, one that polls without taking the request gets it once more, and a running
    /// one (starved by other load, or computing) is waited for, the wait counted.
    fn look_at_deadline(
        &mut self,
        key: u64,
        step: u64,
        kind: Kind,
        elapsed: Duration,
        looks: &mut Looks,
        found: &mut Option<O>,
    ) -> Result<bool, LinkError> {
        self.drain(step, kind, found)?;
        if found.is_some() {
            return Ok(true);
        }
        let w = self.status.words();
        let computing = w.taken.load(Ordering::Acquire) == key + 1
            && w.answered.load(Ordering::Acquire) != key + 1;
        let polls = w.empty_polls.load(Ordering::Acquire);
        let (verdict, look) = judge(self.pid, computing, polls, looks.previous, &mut looks.idle);
        looks.previous = look;
        looks.first = looks.first.or(look);
        let limit = match verdict {
            Liveness::Hung => Some(self.deadline),
            _ if past_ceiling(self.ceiling, elapsed, looks.first, look) => Some(self.ceiling),
            Liveness::Idle => {
                // Polling, yet the request is not taken: send it once more.
                self.resend(key)?;
                None
            }
            Liveness::Running => None,
        };
        if let Some(limit) = limit {
            return Err(LinkError::Timeout {
                role: self.role,
                pid: self.pid,
                step,
                deadline_ms: limit.as_millis() as u64,
            });
        }
        self.counts.starved_waits += 1;
        Ok(false)
    }

    /// Looks into an exchange that has been silent for a while: the participant's status says
    /// whether it published the reply (then, if the reply is not here, the reply was lost) or
    /// keeps polling without having taken the request (the request was lost); either way the
    /// request is re-sent and the loss counted. Returns whether a reply came meanwhile.
    fn look_into_silence(
        &mut self,
        key: u64,
        step: u64,
        kind: Kind,
        silence: &mut Silence,
        found: &mut Option<O>,
    ) -> Result<bool, LinkError> {
        let w = self.status.words();
        let answered = w.answered.load(Ordering::Acquire);
        let taken = w.taken.load(Ordering::Acquire);
        let polls = w.empty_polls.load(Ordering::Acquire);
        let repeats = w.repeats.load(Ordering::Acquire);
        if answered == key + 1 {
            // Published before the load above, so a drain now finds it unless it was lost.
            self.drain(step, kind, found)?;
            if found.is_some() {
                return Ok(true);
            }
            if silence.repeats.is_some_and(|r| repeats <= r) {
                // The repeat sent last is not answered yet.
                return Ok(false);
            }
            self.counts.lost_samples.lost_replies += 1;
            silence.repeats = Some(repeats);
            self.resend(key)?;
        } else if taken != key + 1 {
            match silence.polls {
                Some(p) if polls >= p + 2 => {
                    // Two polls since the last look, none found the request.
                    self.counts.lost_samples.lost_requests += 1;
                    silence.polls = None;
                    self.resend(key)?;
                }
                Some(_) => {}
                None => silence.polls = Some(polls),
            }
        }
        Ok(false)
    }

    /// Sends the pending request again with the next attempt; the participant answers it from
    /// its last reply if it had answered it already.
    fn resend(&mut self, key: u64) -> Result<(), LinkError> {
        let Some(mut req) = self.last_request else {
            return Ok(());
        };
        let h = req.header_mut();
        h.attempt = h.attempt.saturating_add(1);
        self.resent = Some(Resent {
            key,
            attempts: h.attempt,
        });
        self.last_request = Some(req);
        self.counts.lost_samples.resends += 1;
        req.stamp();
        let undelivered =
            super::publish(&self.publisher, req).map_err(|what| LinkError::Transport {
                role: self.role,
                what,
            })?;
        self.counts.lost_samples.undelivered_requests += undelivered;
        Ok(())
    }
}

/// What [`IpcEndpoint::receive`] keeps between two looks into a silent exchange.
#[derive(Debug, Default)]
struct Silence {
    /// The participant's empty polls at the previous look (a request not taken is lost once
    /// it has polled twice more since).
    polls: Option<u64>,
    /// Repeats the participant had answered when a lost reply's request was last re-sent
    /// (re-sent again only once it has answered that one too).
    repeats: Option<u64>,
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
        req.header_mut().attempt = 0;
        self.last_request = Some(req);
        req.stamp();
        if self.drops.drops(true, req.header()) {
            return Ok(());
        }
        let undelivered =
            super::publish(&self.publisher, req).map_err(|what| LinkError::Transport {
                role: self.role,
                what,
            })?;
        self.counts.lost_samples.undelivered_requests += undelivered;
        Ok(())
    }
    fn receive(&mut self, step: u64, kind: Kind) -> Result<O, LinkError> {
        let mut backoff = Backoff::with_spin(self.wait, self.spin_polls);
        let mut found = None;
        let key = exchange_key(&Header::new(step, kind)).unwrap_or(0);
        let mut check_at = RESEND_AFTER;
        let mut silence = Silence::default();
        let mut look_at = self.deadline;
        let mut looks = Looks::default();
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
            self.drain(step, kind, &mut found)?;
            if let Some(reply) = found {
                check_reply::<I, O>(self.role, &reply, step, kind)?;
                return Ok(reply);
            }
            // A dead process is noticed within ~1k polls. After a short silence the status
            // tells whether the request or its reply was lost (then it is re-sent). At the
            // deadline a stopped, idle or sleeping process is declared stalled; one that runs
            // (starved by other load, or computing) is waited for, looked at again every
            // 100 ms, until it has used the ceiling in CPU time (`past_ceiling`).
            let elapsed = backoff.elapsed();
            if backoff.polls() % 1024 == 1023 || elapsed > check_at {
                if let Some(status) = self.exited() {
                    return Err(LinkError::Exited {
                        role: self.role,
                        pid: self.pid,
                        step,
                        status,
                    });
                }
                if elapsed > check_at {
                    check_at = elapsed + RESEND_AFTER;
                    if self.look_into_silence(key, step, kind, &mut silence, &mut found)? {
                        continue;
                    }
                }
                if elapsed > look_at {
                    if self.look_at_deadline(key, step, kind, elapsed, &mut looks, &mut found)? {
                        continue;
                    }
                    look_at = elapsed + LOOK_EVERY;
                }
            }
            backoff.pause();
        }
    }
    fn take_arrived(&mut self, out: &mut Vec<O>) -> Result<(), LinkError> {
        let before = out.len();
        super::free::take_arrived(self.role, &self.subscriber, out)?;
        if out.len() == before {
            if let Some(status) = self.exited() {
                return Err(LinkError::Exited {
                    role: self.role,
                    pid: self.pid,
                    step: 0,
                    status,
                });
            }
        }
        Ok(())
    }
    fn counts(&self) -> ExchangeCounts {
        let mut c = self.counts;
        c.lost_samples.repeats_answered = self.status.words().repeats.load(Ordering::Relaxed);
        c.lost_samples.undelivered_replies =
            self.status.words().undelivered.load(Ordering::Relaxed);
        c
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
        // Ask politely (again every 50 ms, should a Stop be lost), then insist: a stopped or
        // hung participant is killed.
        let stop = |attempt: u32| {
            let mut m = I::default();
            *m.header_mut() = Header::new(u64::MAX, Kind::Stop);
            m.header_mut().attempt = attempt;
            m
        };
        let _ = super::publish(&self.publisher, stop(0));
        let started = Instant::now();
        let mut report = None;
        let mut attempt = 0;
        while report.is_none() && started.elapsed() < Duration::from_millis(500) {
            report = try_reap(self.pid, false);
            if report.is_none() {
                std::thread::sleep(Duration::from_millis(1));
                let due = started.elapsed().as_millis() as u32 / 50;
                if due > attempt {
                    attempt = due;
                    let _ = super::publish(&self.publisher, stop(attempt));
                }
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

#[cfg(test)]
mod tests {
    use std::sync::atomic::AtomicU64;
    use std::sync::Arc;

    use super::*;
    use crate::msg::{FromController, ToController};
    use crate::participant::Participant;

    /// Doubles the measurement and counts its steps.
    struct Doubler(Arc<AtomicU64>);
    impl Participant for Doubler {
        type Input = ToController;
        type Output = FromController;
        const ROLE: Role = Role::Controller;
        fn initial_output(&mut self) -> FromController {
            FromController::default()
        }
        fn step(&mut self, i: &ToController) -> FromController {
            self.0.fetch_add(1, Ordering::Relaxed);
            FromController {
                theta_v_hat: 2.0 * i.theta_v_meas,
                ..Default::default()
            }
        }
    }

    #[test]
    fn the_ceiling_counts_cpu_time_so_a_starved_participant_is_waited_for() {
        let c = Duration::from_secs(60);
        let look = |cpu_s: f64| {
            Some(Look {
                cpu_ns: (cpu_s * 1e9) as u64,
                empty_polls: 0,
            })
        };
        // Starved: five minutes of wall time, one second of CPU.
        assert!(!past_ceiling(
            c,
            Duration::from_secs(300),
            look(2.0),
            look(3.0)
        ));
        // Computing for ever: more CPU than the ceiling since the first look.
        assert!(past_ceiling(
            c,
            Duration::from_secs(70),
            look(2.0),
            look(62.5)
        ));
        assert!(!past_ceiling(
            c,
            Duration::from_secs(70),
            look(2.0),
            look(61.5)
        ));
        // Never getting going: ten ceilings of wall time, whatever the CPU.
        assert!(past_ceiling(
            c,
            Duration::from_secs(601),
            look(2.0),
            look(2.0)
        ));
        assert!(!past_ceiling(c, Duration::from_secs(599), None, None));
    }

    #[test]
    fn a_lost_request_and_a_lost_reply_are_resent_and_the_model_steps_once_each() {
        let prefix = super::super::unique_prefix();
        let hub = IpcHub::new(IpcSettings {
            prefix: prefix.clone(),
            wait: WaitStrategy::Adaptive,
            deadline: Duration::from_millis(500),
            ceiling: Duration::from_secs(600),
            participant_cpu: None,
        })
        .unwrap();
        let mut ep = hub
            .attach::<ToController, FromController>(Role::Controller)
            .unwrap();
        // The orchestrator loses its first sending of step 3's request, the participant its
        // first sending of step 5's reply.
        ep.drops = DropPlan::new(vec![(Role::Controller, true, 3)]);
        let steps = Arc::new(AtomicU64::new(0));
        let (model, pfx) = (Doubler(steps.clone()), prefix.clone());
        let served = std::thread::spawn(move || {
            super::super::serve::serve_dropping(
                model,
                &pfx,
                WaitStrategy::Adaptive,
                crate::wait::SPIN_POLLS,
                super::super::IDLE_LIMIT,
                |_| {},
                DropPlan::new(vec![(Role::Controller, false, 5)]),
            )
        });
        assert!(ep.await_connection(Duration::from_secs(600), None).unwrap());
        for k in 0..8u64 {
            let req = ToController {
                header: Header::new(k, Kind::Step),
                theta_v_meas: k as f64,
                ..Default::default()
            };
            ep.send(&req).unwrap();
            let reply = ep.receive(k, Kind::Step).unwrap();
            assert_eq!(reply.theta_v_hat, 2.0 * k as f64, "step {k}");
        }
        // Every step computed once: the repeat of step 5 was answered from the last reply.
        assert_eq!(steps.load(Ordering::Relaxed), 8);
        let c = ep.counts().lost_samples;
        assert_eq!((c.lost_requests, c.lost_replies), (1, 1), "{c:?}");
        // One re-send per loss; more only if a slow answer met a look under heavy load.
        assert!(c.resends >= 2 && c.repeats_answered >= 1, "{c:?}");
        let _ = super::super::publish(
            &ep.publisher,
            ToController {
                header: Header::new(u64::MAX, Kind::Stop),
                ..Default::default()
            },
        );
        served.join().unwrap().unwrap();
        drop(ep);
        drop(hub);
        super::super::remove_run_files(&prefix);
        assert!(super::super::leftover_files(&prefix).is_empty());
    }
}
