//! iceoryx2 transport: one request and one reply publish-subscribe service per participant.
//!
//! The orchestrator creates both services of a participant, spawns its process and waits until
//! the participant's subscriber and publisher are connected before it sends the first request
//! (samples sent before a subscriber connects are lost). Each sample carries its step index and
//! is checked on arrival; each wake-up drains every pending sample.
//!
//! Isolation: every run uses its own iceoryx2 file prefix, so parallel runs never meet, and
//! [`IpcHub::cleanup`] removes what the run's dead participants left behind.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use crate::endpoint::{check_reply, Endpoint, ExitReport, LinkError, ProcessFault};
use crate::msg::{Header, Kind, Message, FLAG_CRASH};
use crate::participant::{Participant, Role, Served};
use crate::wait::{Backoff, WaitStrategy};

/// Per-run iceoryx2 settings shared by the orchestrator and its participants.
#[derive(Debug, Clone)]
pub struct IpcSettings {
    /// File prefix unique to the run (iceoryx2 `global.prefix`).
    pub prefix: String,
    /// How waiters spend time between polls.
    pub wait: WaitStrategy,
    /// How long to wait for a reply before declaring the participant stalled.
    pub deadline: Duration,
    /// CPU the participants are pinned to, if any.
    pub participant_cpu: Option<usize>,
}

/// Errors setting up the transport.
#[derive(Debug, thiserror::Error)]
pub enum IpcError {
    /// iceoryx2 refused something.
    #[error("iceoryx2: {0}")]
    Iceoryx(String),
    /// A participant process could not be started.
    #[error("cannot start participant {role} ({program}): {source}")]
    Spawn {
        role: Role,
        program: String,
        source: std::io::Error,
    },
    /// A participant did not connect in time.
    #[error(transparent)]
    Link(#[from] LinkError),
}

fn iox<E: core::fmt::Debug>(what: &str) -> impl FnOnce(E) -> IpcError + '_ {
    move |e| IpcError::Iceoryx(format!("{what}: {e:?}"))
}

/// iceoryx2 configuration for a run: explicit (no config file is searched), with the run's prefix.
pub fn config(prefix: &str) -> Result<Config, IpcError> {
    let mut cfg = Config::default();
    cfg.global.prefix = FileName::new(prefix.as_bytes()).map_err(iox("invalid prefix"))?;
    Ok(cfg)
}

/// The CPUs this process may run on (from `sched_getaffinity`).
pub fn allowed_cpus() -> Vec<usize> {
    // SAFETY: cpu_set_t is plain data; sched_getaffinity writes into it.
    unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        if libc::sched_getaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

/// Pins the calling process to `cpu`. Returns false if the kernel refused.
pub fn pin_to_cpu(cpu: usize) -> bool {
    set_cpus(&[cpu])
}

/// Restricts the calling process to `cpus` (used to undo [`pin_to_cpu`]).
pub fn set_cpus(cpus: &[usize]) -> bool {
    // SAFETY: as above; sched_setaffinity reads the set.
    unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        for &c in cpus {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    }
}

/// CPU placement of a run: the orchestrator on one CPU, every participant on another, so the
/// participants' waits round-robin on one run queue while the orchestrator polls undisturbed.
/// `None` when fewer than two CPUs are allowed.
pub fn cpu_plan() -> Option<(usize, usize)> {
    let cpus = allowed_cpus();
    (cpus.len() >= 2).then(|| (cpus[0], cpus[cpus.len() - 1]))
}

/// Silences iceoryx2's own logger except for errors (overridable with `IOX2_LOG_LEVEL`).
pub fn quiet_iceoryx_logs() {
    set_log_level_from_env_or(LogLevel::Error);
}

/// A run prefix unique on this machine: pid, a nonce from the wall clock (used only for
/// uniqueness) and a per-process counter.
pub fn unique_prefix() -> String {
    use std::sync::atomic::{AtomicU32, Ordering};
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let nonce = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!(
        "tiltsim_{}_{:08x}_{}_",
        std::process::id(),
        nonce,
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

fn node(cfg: &Config, name: &str) -> Result<Node<ipc::Service>, IpcError> {
    NodeBuilder::new()
        .config(cfg)
        .name(&NodeName::new(name).map_err(iox("node name"))?)
        // Signals are the orchestrator's business (Ctrl-C ends a run cleanly through it).
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(iox("create node"))
}

fn service<T: Message>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<PubSubFactory<ipc::Service, T, ()>, IpcError> {
    let name: ServiceName = name.try_into().map_err(iox("service name"))?;
    node.service_builder(&name)
        .publish_subscribe::<T>()
        .max_publishers(1)
        .max_subscribers(1)
        .history_size(0)
        .subscriber_max_buffer_size(4)
        .open_or_create()
        .map_err(iox("open or create service"))
}

fn request_service(role: Role) -> String {
    format!("tiltsim/{}/request", role.name())
}
fn reply_service(role: Role) -> String {
    format!("tiltsim/{}/reply", role.name())
}

/// Drains `sub` and returns the one sample for `step`, or an error for any other sample.
fn drain<T: Message>(
    role: Role,
    sub: &Subscriber<ipc::Service, T, ()>,
    step: u64,
    found: &mut Option<T>,
) -> Result<(), LinkError> {
    loop {
        let sample = sub.receive().map_err(|e| LinkError::Transport {
            role,
            what: format!("receive: {e:?}"),
        })?;
        let Some(sample) = sample else { return Ok(()) };
        let value: T = *sample;
        let got = value.header().step;
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
            deadline: self.settings.deadline,
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
    deadline: Duration,
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

/// Reaps child `pid` if it has ended (or waits for it when `block`), reporting its status and
/// the CPU time it used (from `wait4`'s resource usage).
fn try_reap(pid: u32, block: bool) -> Option<ExitReport> {
    let mut status: libc::c_int = 0;
    // SAFETY: an all-zero rusage is a valid value for the kernel to overwrite.
    let mut usage: libc::rusage = unsafe { core::mem::zeroed() };
    let flags = if block { 0 } else { libc::WNOHANG };
    // SAFETY: `pid` is our own child; wait4 writes into the two locals only.
    let r = unsafe { libc::wait4(pid as libc::pid_t, &mut status, flags, &mut usage) };
    if r != pid as libc::pid_t {
        return None;
    }
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let status = if libc::WIFEXITED(status) {
        format!("exit code {}", libc::WEXITSTATUS(status))
    } else if libc::WIFSIGNALED(status) {
        format!("killed by signal {}", libc::WTERMSIG(status))
    } else {
        format!("wait status {status}")
    };
    Some(ExitReport {
        status,
        cpu_s: Some(tv(usage.ru_utime) + tv(usage.ru_stime)),
    })
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
        self.publisher
            .send_copy(req)
            .map(|_| ())
            .map_err(|e| LinkError::Transport {
                role: self.role,
                what: format!("send: {e:?}"),
            })
    }
    fn receive(&mut self, step: u64, kind: Kind) -> Result<O, LinkError> {
        let mut backoff = Backoff::new(self.wait);
        let mut found = None;
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
            // A dead process is noticed within ~1k polls; a stalled one at the deadline.
            if backoff.polls() % 1024 == 1023 || backoff.elapsed() > self.deadline {
                if let Some(status) = self.exited() {
                    return Err(LinkError::Exited {
                        role: self.role,
                        pid: self.pid,
                        step,
                        status,
                    });
                }
                if backoff.elapsed() > self.deadline {
                    return Err(LinkError::Timeout {
                        role: self.role,
                        pid: self.pid,
                        step,
                        deadline_ms: self.deadline.as_millis() as u64,
                    });
                }
            }
            backoff.pause();
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
        let _ = self.publisher.send_copy({
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

/// Removes every file this run's prefix left in the iceoryx2 directories and in `/dev/shm`.
/// Returns how many were removed. Called last, after every node is gone.
pub fn remove_run_files(prefix: &str) -> usize {
    let mut removed = 0;
    let mut dirs = vec![PathBuf::from("/dev/shm")];
    if let Ok(cfg) = config(prefix) {
        let root = PathBuf::from(cfg.global.root_path().to_string());
        dirs.push(root.clone());
        dirs.push(PathBuf::from(cfg.global.service_dir().to_string()));
        dirs.push(PathBuf::from(cfg.global.node_dir().to_string()));
    }
    for dir in dirs {
        removed += remove_prefixed(&dir, prefix);
    }
    removed
}

fn remove_prefixed(dir: &std::path::Path, prefix: &str) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut n = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        let path = e.path();
        if name.starts_with(prefix) {
            let ok = if path.is_dir() {
                std::fs::remove_dir_all(&path).is_ok()
            } else {
                std::fs::remove_file(&path).is_ok()
            };
            n += usize::from(ok);
        } else if path.is_dir() && !path.is_symlink() && dir != std::path::Path::new("/dev/shm") {
            n += remove_prefixed(&path, prefix);
        }
    }
    n
}

/// Lists the files a run's prefix still has on disk (for tests and leak reports).
pub fn leftover_files(prefix: &str) -> Vec<PathBuf> {
    fn walk(dir: &std::path::Path, prefix: &str, out: &mut Vec<PathBuf>, depth: u32) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let path = e.path();
            if e.file_name().to_string_lossy().starts_with(prefix) {
                out.push(path);
            } else if depth < 4 && path.is_dir() && !path.is_symlink() {
                walk(&path, prefix, out, depth + 1);
            }
        }
    }
    let mut out = Vec::new();
    walk(std::path::Path::new("/dev/shm"), prefix, &mut out, 3);
    if let Ok(cfg) = config(prefix) {
        walk(
            std::path::Path::new(&cfg.global.root_path().to_string()),
            prefix,
            &mut out,
            0,
        );
    }
    out
}

/// Participant side: serves requests for model `p` until asked to stop.
///
/// Returns an error if the orchestrator disappears (its requests stop for `idle_limit` and it
/// is no longer our parent) or the transport fails.
pub fn serve<P: Participant>(
    p: P,
    prefix: &str,
    wait: WaitStrategy,
    spin_polls: u32,
    idle_limit: Duration,
) -> Result<(), IpcError> {
    serve_with(p, prefix, wait, spin_polls, idle_limit, |_| {})
}

/// [`serve`] with a hook that may alter each reply before it is sent: the test participants
/// under `tests/` use it to send bad data on purpose. Production participants use `serve`.
pub fn serve_with<P: Participant>(
    p: P,
    prefix: &str,
    wait: WaitStrategy,
    spin_polls: u32,
    idle_limit: Duration,
    mut tamper: impl FnMut(&mut P::Output),
) -> Result<(), IpcError> {
    quiet_iceoryx_logs();
    let role = P::ROLE;
    set_process_name(role.process_name());
    let parent = unsafe { libc::getppid() };
    let cfg = config(prefix)?;
    let node = node(&cfg, role.process_name())?;
    let req = service::<P::Input>(&node, &request_service(role))?;
    let rep = service::<P::Output>(&node, &reply_service(role))?;
    let subscriber = req
        .subscriber_builder()
        .create()
        .map_err(iox("create subscriber"))?;
    let publisher = rep
        .publisher_builder()
        .create()
        .map_err(iox("create publisher"))?;

    // Steps must arrive in increasing order after Init; multi-rate participants are asked only
    // on their own ticks, so the next step may be any later one.
    let mut last_step: Option<u64> = None;
    let mut served = Served::new(p);
    loop {
        let mut backoff = Backoff::with_spin(wait, spin_polls);
        let request = loop {
            let sample = subscriber.receive().map_err(iox("receive"))?;
            if let Some(s) = sample {
                break *s;
            }
            if backoff.elapsed() > idle_limit && unsafe { libc::getppid() } != parent {
                return Err(IpcError::Iceoryx(format!("{role}: orchestrator is gone")));
            }
            backoff.pause();
        };
        let h = *request.header();
        match Kind::from_raw(h.kind) {
            Some(Kind::Stop) => return Ok(()),
            Some(Kind::Init) => last_step = None,
            Some(Kind::Step) => {
                if let Some(last) = last_step.filter(|&l| h.step <= l) {
                    return Err(LinkError::OutOfOrder {
                        role,
                        expected: last + 1,
                        got: h.step,
                    }
                    .into());
                }
                last_step = Some(h.step);
            }
            None => {
                return Err(LinkError::Malformed {
                    role,
                    step: h.step,
                    what: format!("kind {}", h.kind),
                }
                .into());
            }
        }
        if h.flags & FLAG_CRASH != 0 {
            // A scheduled `crash` fault: die as a crashing process does.
            std::process::abort();
        }
        let mut reply = served.answer(&request);
        tamper(&mut reply);
        publisher.send_copy(reply).map_err(iox("send"))?;
    }
}

fn set_process_name(name: &str) {
    let mut buf = [0u8; 16];
    let n = name.len().min(15);
    buf[..n].copy_from_slice(&name.as_bytes()[..n]);
    // SAFETY: PR_SET_NAME reads a NUL-terminated string of at most 16 bytes from `buf`.
    unsafe {
        libc::prctl(libc::PR_SET_NAME, buf.as_ptr() as libc::c_ulong, 0, 0, 0);
    }
}

/// Arguments every participant process takes: `--params JSON --prefix P --wait W`.
#[derive(Debug, Clone)]
pub struct ParticipantArgs {
    /// The model's settings as JSON.
    pub params: String,
    /// The run's iceoryx2 prefix.
    pub prefix: String,
    /// Wait strategy.
    pub wait: WaitStrategy,
    /// CPU to pin to.
    pub cpu: Option<usize>,
}

impl ParticipantArgs {
    /// Parses the arguments after the program name (and after a `participant ROLE` prefix).
    pub fn parse(args: &[String]) -> Result<Self, String> {
        let mut params = None;
        let mut prefix = None;
        let mut wait = WaitStrategy::default();
        let mut cpu = None;
        let mut it = args.iter();
        while let Some(a) = it.next() {
            let mut value = |name: &str| {
                it.next()
                    .cloned()
                    .ok_or_else(|| format!("{name} needs a value"))
            };
            match a.as_str() {
                "--params" => params = Some(value("--params")?),
                "--prefix" => prefix = Some(value("--prefix")?),
                "--wait" => {
                    let w = value("--wait")?;
                    wait = WaitStrategy::parse(&w)
                        .ok_or_else(|| format!("--wait {w}: allowed spin, adaptive, sleep"))?;
                }
                "--cpu" => {
                    let c = value("--cpu")?;
                    cpu = Some(
                        c.parse()
                            .map_err(|_| format!("--cpu {c}: expected a CPU number"))?,
                    );
                }
                other => {
                    return Err(format!(
                        "unknown argument `{other}`; expected --params, --prefix, --wait, --cpu"
                    ))
                }
            }
        }
        Ok(ParticipantArgs {
            params: params.ok_or("missing --params JSON")?,
            prefix: prefix.ok_or("missing --prefix NAME")?,
            wait,
            cpu,
        })
    }
}

/// Idle time after which a participant checks that its orchestrator still exists.
pub const IDLE_LIMIT: Duration = Duration::from_secs(2);

/// Entry point of a participant process: parses the arguments, builds the model from its JSON
/// settings with `make`, and serves until stopped.
pub fn participant_main<S, P>(
    args: &[String],
    make: impl FnOnce(S) -> Result<P, String>,
) -> Result<(), String>
where
    S: serde::de::DeserializeOwned,
    P: Participant,
{
    participant_main_with(args, make, |_| {})
}

/// [`participant_main`] with a reply hook (see [`serve_with`]); for test participants.
pub fn participant_main_with<S, P>(
    args: &[String],
    make: impl FnOnce(S) -> Result<P, String>,
    tamper: impl FnMut(&mut P::Output),
) -> Result<(), String>
where
    S: serde::de::DeserializeOwned,
    P: Participant,
{
    let a = ParticipantArgs::parse(args)?;
    let settings: S = serde_json::from_str(&a.params)
        .map_err(|e| format!("{}: bad --params: {e}", P::ROLE.process_name()))?;
    let model = make(settings)?;
    if let Some(cpu) = a.cpu {
        pin_to_cpu(cpu);
    }
    // Participants pinned together share a CPU: they yield at once instead of spinning.
    let spin = if a.cpu.is_some() {
        0
    } else {
        crate::wait::SPIN_POLLS
    };
    serve_with(model, &a.prefix, a.wait, spin, IDLE_LIMIT, tamper)
        .map_err(|e| format!("{}: {e}", P::ROLE.process_name()))
}
