//! iceoryx2 transport: one request and one reply publish-subscribe service per participant.
//!
//! The orchestrator creates both services of a participant, spawns its process and waits until
//! the participant's subscriber and publisher are connected before it sends the first request
//! (samples sent before a subscriber connects are lost). Each sample carries its step index and
//! is checked on arrival; each wake-up drains every pending sample.
//!
//! Isolation: every run uses its own iceoryx2 file prefix, so parallel runs never meet, and
//! [`IpcHub::cleanup`] removes what the run's dead participants left behind.

//!
//! Files: this one (settings, errors, configuration, services, draining), [`hub`] (the
//! orchestrator's side: the hub and one endpoint per participant), [`serve`] (the
//! participant's side), [`supervise`] (reaping participant processes), [`affinity`] (CPU
//! pinning), [`placement`] (which CPUs a run claims among other runs and work) and
//! [`cleanup`] (the run's shared-memory files).

mod affinity;
mod cleanup;
mod free;
mod hub;
pub mod pattern;
pub mod pingpong;
pub mod placement;
mod serve;
mod supervise;

pub use affinity::{allowed_cpus, pin_to_cpu, set_cpus, set_cpus_of};
pub use cleanup::{
    boot_id, claim_prefix, leftover_files, remove_dead_runs, remove_run_files, start_ticks, Owner,
};
pub use hub::{IpcEndpoint, IpcHub, Launch};
pub use serve::{
    participant_main, participant_main_with, serve, serve_with, ParticipantArgs, ServeError,
    IDLE_LIMIT,
};

use std::time::Duration;

use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

use crate::endpoint::LinkError;
use crate::msg::{Header, Kind, Message};
use crate::participant::Role;
use crate::wait::WaitStrategy;

/// Per-run iceoryx2 settings shared by the orchestrator and its participants.
#[derive(Debug, Clone)]
pub struct IpcSettings {
    /// File prefix unique to the run (iceoryx2 `global.prefix`).
    pub prefix: String,
    /// How waiters spend time between polls.
    pub wait: WaitStrategy,
    /// How long to wait for a reply before checking whether the participant makes progress.
    pub deadline: Duration,
    /// How long to wait for a participant that runs but does not answer.
    pub ceiling: Duration,
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
    /// The model failed a step (an FMU's `doStep` returned an error): the process ends.
    #[error("{0}")]
    Model(String),
    /// The program's interrupt flag was set while participant `role` was starting (it was
    /// stopped, whatever it was doing: unpacking a large FMU, designing a controller).
    #[error("interrupted while participant {role} was starting")]
    Interrupted { role: Role },
    /// The caller's stop flag was set during a measurement (`pingpong::measure`).
    #[error("stopped")]
    Stopped,
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

/// Samples a subscriber holds. The lock-step has one in flight; a free run's participants
/// publish without waiting for the hub, and a participant that catches up after a stall sends
/// a burst: a full reply buffer holds its publisher back ([`Direction::Reply`]) until the hub
/// has drained it, so no reply is ever lost to the buffer's size.
const BUFFER: usize = 1024;

/// Which way a service carries samples, and so what a full subscriber buffer does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Direction {
    /// Orchestrator to participant: the oldest request is overwritten (a free-running
    /// consumer reads only the newest input; the lock-step has one request in flight).
    Request,
    /// Participant to orchestrator: never overwritten; the participant's publisher waits for
    /// room ([`reply_publisher`]), since every reply is a step of the record.
    Reply,
}

fn service<T: Message>(
    node: &Node<ipc::Service>,
    name: &str,
    direction: Direction,
) -> Result<PubSubFactory<ipc::Service, T, ()>, IpcError> {
    let name: ServiceName = name.try_into().map_err(iox("service name"))?;
    node.service_builder(&name)
        .publish_subscribe::<T>()
        .max_publishers(1)
        .max_subscribers(1)
        .history_size(0)
        .subscriber_max_buffer_size(BUFFER)
        .enable_safe_overflow(direction == Direction::Request)
        .open_or_create()
        .map_err(iox("open or create service"))
}

/// Pause of a participant whose reply buffer is full before it tries again.
const BACKPRESSURE_NAP: std::time::Duration = std::time::Duration::from_micros(100);

/// The participant's reply publisher: when the orchestrator's buffer is full it waits, a nap at
/// a time, for the orchestrator to drain it, and gives the sample up only when the
/// orchestrator (process `parent`) has gone. The wait is part of the step's publish instant, so
/// a free run's trace records it as timing like any other.
fn reply_publisher<T: Message>(
    factory: &PubSubFactory<ipc::Service, T, ()>,
    parent: libc::pid_t,
) -> Result<iceoryx2::port::publisher::Publisher<ipc::Service, T, ()>, IpcError> {
    use iceoryx2::port::{BackpressureAction, BackpressureInfo};
    factory
        .publisher_builder()
        .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
        .set_backpressure_handler(move |_: &BackpressureInfo| {
            // SAFETY: getppid has no preconditions.
            if unsafe { libc::getppid() } != parent {
                return BackpressureAction::DiscardDataAndFail;
            }
            std::thread::sleep(BACKPRESSURE_NAP);
            BackpressureAction::Retry
        })
        .create()
        .map_err(iox("create publisher"))
}

fn request_service(role: Role) -> String {
    format!("tiltsim/{}/request", role.name())
}
fn reply_service(role: Role) -> String {
    format!("tiltsim/{}/reply", role.name())
}

/// Sendings of one sample that may reach no subscriber before [`publish`] leaves it to the
/// exchange's repair of lost samples.
const UNDELIVERED_RETRIES: u32 = 3;

/// Publishes `v` zero-copy: the sample is written into memory loaned from the shared segment
/// (`loan_uninit`, `write_payload`) and sent from there; the subscriber reads it in place.
///
/// iceoryx2's `send` skips, without an error, a subscriber whose connection the publisher
/// does not hold (not yet set up, or being set up again) and reports it only through the
/// number of recipients it returns. Every service here has exactly one subscriber, so 0
/// recipients is a sample lost at the source: the publisher's connections are brought up to
/// date and the sample sent again, up to [`UNDELIVERED_RETRIES`] times. Returns how many
/// sendings reached nobody (0 on the normal path; the caller counts them). A sample that
/// still reached nobody (a subscriber that has gone, as at shut-down) is left to the
/// exchange's repair of lost samples.
fn publish<T: Message>(
    p: &iceoryx2::port::publisher::Publisher<ipc::Service, T, ()>,
    v: T,
) -> Result<u64, String> {
    let mut undelivered = 0;
    loop {
        let sample = p.loan_uninit().map_err(|e| format!("loan: {e:?}"))?;
        let recipients = sample
            .write_payload(v)
            .send()
            .map_err(|e| format!("send: {e:?}"))?;
        if recipients > 0 || undelivered >= u64::from(UNDELIVERED_RETRIES) {
            return Ok(undelivered);
        }
        undelivered += 1;
        use iceoryx2::port::update_connections::UpdateConnections;
        p.update_connections()
            .map_err(|e| format!("update connections: {e:?}"))?;
    }
}

/// Samples to drop on purpose, for tests of lost samples: `TILTSIM_DROP_SAMPLES` holds
/// `ROLE:request:STEP` or `ROLE:reply:STEP` items, comma-separated. The first sending of
/// that step's request (by the orchestrator) or reply (by the participant) is not published,
/// as if the transport had lost it; a repeat goes through. Unset in every ordinary run.
#[derive(Debug, Clone, Default)]
pub(crate) struct DropPlan {
    steps: Vec<(Role, bool, u64)>,
}

impl DropPlan {
    /// Whether it drops nothing.
    pub(crate) fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// The variable's name.
    pub(crate) const VAR: &'static str = "TILTSIM_DROP_SAMPLES";

    /// The plan of `role` from the environment (empty when unset or unreadable).
    pub(crate) fn from_env(role: Role) -> Self {
        let Some(v) = std::env::var_os(Self::VAR) else {
            return DropPlan::default();
        };
        let steps = v
            .to_string_lossy()
            .split(',')
            .filter_map(|item| {
                let mut it = item.trim().splitn(3, ':');
                let r = Role::parse(it.next()?)?;
                let request = match it.next()? {
                    "request" => true,
                    "reply" => false,
                    _ => return None,
                };
                let step = it.next()?.parse().ok()?;
                (r == role).then_some((r, request, step))
            })
            .collect();
        DropPlan { steps }
    }

    /// A plan of `(role, request, step)` items.
    #[cfg(test)]
    pub(crate) fn new(steps: Vec<(Role, bool, u64)>) -> Self {
        DropPlan { steps }
    }

    /// Whether the first sending of a step request (`request`) or reply for `h` is dropped.
    pub(crate) fn drops(&self, request: bool, h: &Header) -> bool {
        !self.steps.is_empty()
            && h.attempt == 0
            && h.kind == Kind::Step as u32
            && self
                .steps
                .iter()
                .any(|&(_, q, s)| q == request && s == h.step)
    }
}

/// The request last re-sent to a participant: the answers to its repeats that still come are
/// expected and discarded.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Resent {
    /// [`crate::msg::exchange_key`] of the request.
    pub key: u64,
    /// Its highest attempt sent.
    pub attempts: u32,
}

impl Resent {
    /// Whether reply header `h` answers a repeat of the request re-sent.
    fn answers_repeat(&self, h: &Header) -> bool {
        h.attempt >= 1
            && h.attempt <= self.attempts
            && crate::msg::exchange_key(h) == Some(self.key)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_answers_to_repeats_of_the_request_re_sent_are_expected() {
        let r = Resent {
            key: crate::msg::exchange_key(&Header::new(7, Kind::Step)).unwrap(),
            attempts: 2,
        };
        let h = |step, kind, attempt| Header {
            attempt,
            ..Header::new(step, kind)
        };
        assert!(r.answers_repeat(&h(7, Kind::Step, 1)));
        assert!(r.answers_repeat(&h(7, Kind::Step, 2)));
        // The original answer, an attempt never sent, another step or kind: not repeats.
        assert!(!r.answers_repeat(&h(7, Kind::Step, 0)));
        assert!(!r.answers_repeat(&h(7, Kind::Step, 3)));
        assert!(!r.answers_repeat(&h(6, Kind::Step, 1)));
        assert!(!r.answers_repeat(&h(7, Kind::Init, 1)));
    }

    #[test]
    fn a_drop_plan_drops_first_sendings_of_its_own_steps_only() {
        let plan = DropPlan::new(vec![(Role::Plant, true, 5), (Role::Plant, false, 9)]);
        let h = |step, attempt| Header {
            attempt,
            ..Header::new(step, Kind::Step)
        };
        assert!(plan.drops(true, &h(5, 0)));
        assert!(!plan.drops(true, &h(5, 1)), "a repeat goes through");
        assert!(!plan.drops(false, &h(5, 0)));
        assert!(plan.drops(false, &h(9, 0)));
        assert!(!plan.drops(true, &Header::new(5, Kind::Init)));
        assert!(!DropPlan::default().drops(true, &h(5, 0)));
    }
}
