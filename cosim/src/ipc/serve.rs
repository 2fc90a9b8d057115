//! The participant's side of the transport: serving requests until told to stop.

use std::time::Duration;

use crate::endpoint::LinkError;
use std::sync::atomic::Ordering;

use crate::msg::{exchange_key, now_ns, Header, Kind, Message, FLAG_CRASH, FLAG_FREE_START};
use crate::participant::{Participant, Role, Served};
use crate::wait::{sleep_until_ns, Backoff, Cadence, WaitStrategy};

use super::supervise::{decode_next, Status, StatusWords};
use super::{
    config, iox, node, pin_to_cpu, quiet_iceoryx_logs, reply_publisher, reply_service,
    request_service, service, Direction, DropPlan, IpcError,
};

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
    tamper: impl FnMut(&mut P::Output),
) -> Result<(), IpcError> {
    let drops = DropPlan::from_env(P::ROLE);
    serve_dropping(p, prefix, wait, spin_polls, idle_limit, tamper, drops)
}

/// [`serve_with`] with the samples to drop given (tests of lost samples).
pub(crate) fn serve_dropping<P: Participant>(
    p: P,
    prefix: &str,
    wait: WaitStrategy,
    spin_polls: u32,
    idle_limit: Duration,
    mut tamper: impl FnMut(&mut P::Output),
    drops: DropPlan,
) -> Result<(), IpcError> {
    quiet_iceoryx_logs();
    let role = P::ROLE;
    set_process_name(role.process_name());
    let parent = unsafe { libc::getppid() };
    let cfg = config(prefix)?;
    let node = node(&cfg, role.process_name())?;
    let req = service::<P::Input>(&node, &request_service(role), Direction::Request)?;
    let rep = service::<P::Output>(&node, &reply_service(role), Direction::Reply)?;
    let subscriber = req
        .subscriber_builder()
        .create()
        .map_err(iox("create subscriber"))?;
    let publisher = reply_publisher(&rep, parent)?;

    // Steps must arrive in increasing order after Init; multi-rate participants are asked only
    // on their own ticks, so the next step may be any later one.
    let mut last_step: Option<u64> = None;
    let mut served = Served::new(p);
    let mut cadence = Cadence::default();
    let status = Status::open(prefix, role);
    let words = status.words();
    let mut peers = Peers::new(prefix);
    let mut repeat = Repeat::default();
    let mut empty_polls = 0u64;
    let waiting = Waiting {
        wait,
        spin_polls,
        idle_limit,
        parent,
        role,
    };
    loop {
        let request: P::Input = waiting.next_request(
            &subscriber,
            &cadence,
            words,
            &mut empty_polls,
            last_step,
            &mut peers,
        )?;
        let h = *request.header();
        let key = exchange_key(&h);
        if let Some(k) = key {
            words.taken.store(k + 1, Ordering::Release);
        }
        // Whom to cue once answered: named with this request, read before the orchestrator
        // can name another for the next one.
        let cue_next = words.cue.next.load(Ordering::Acquire);
        // A repeat of the request last answered: its reply again, the model not stepped.
        if let Some(again) = repeat.answer(&h) {
            let undelivered = super::publish(&publisher, again).map_err(IpcError::Iceoryx)?;
            words.undelivered.fetch_add(undelivered, Ordering::Relaxed);
            // Counted once sent: the orchestrator re-sends again only for a repeat that was
            // answered and still did not come.
            words.repeats.fetch_add(1, Ordering::Release);
            continue;
        }
        if matches!(Kind::from_raw(h.kind), Some(Kind::Step)) && h.flags & FLAG_FREE_START != 0 {
            // The start of a free run: from here the participant keeps its own clock.
            return super::free::serve_free(&mut served, &subscriber, &publisher, request, parent);
        }
        if !admit(&h, role, &mut last_step, &mut cadence)? {
            return Ok(());
        }
        if h.flags & FLAG_CRASH != 0 {
            // A scheduled `crash` fault: die as a crashing process does.
            std::process::abort();
        }
        let mut reply = served.answer(&request);
        if let Some(why) = served.model.failure() {
            // The step failed: no reply; the process ends and the orchestrator names it.
            return Err(IpcError::Model(why));
        }
        tamper(&mut reply);
        reply.header_mut().attempt = h.attempt;
        repeat.keep(&h, &reply);
        if !drops.drops(false, reply.header()) {
            let undelivered = super::publish(&publisher, reply).map_err(IpcError::Iceoryx)?;
            if undelivered > 0 {
                words.undelivered.fetch_add(undelivered, Ordering::Relaxed);
            }
        }
        if let Some(k) = key {
            words.answered.store(k + 1, Ordering::Release);
        }
        if matches!(Kind::from_raw(h.kind), Some(Kind::Step)) {
            peers.cue(words, cue_next);
        }
    }
}

/// The other participants' status words, mapped when first needed, once a step has been
/// answered: the orchestrator creates each one's just before starting it, so the later ones do
/// not exist yet when the first participant starts. One that does not exist then (a
/// participant on another host, or none made) is not looked for again.
struct Peers<'a> {
    prefix: &'a str,
    mapped: [Option<Status>; 3],
    /// Whether each was looked for.
    looked: [bool; 3],
    /// The last cue this participant gave: the peer's index and the cue word written.
    gave: Option<(usize, u64)>,
    /// The step at which this participant last stepped aside.
    steered: u64,
}

impl<'a> Peers<'a> {
    fn new(prefix: &'a str) -> Self {
        Peers {
            prefix,
            mapped: [None, None, None],
            looked: [false; 3],
            gave: None,
            steered: 0,
        }
    }

    /// The status words of the participant of index `i` in [`Role::ALL`], if it has them.
    fn words(&mut self, i: usize) -> Option<&StatusWords> {
        if !std::mem::replace(&mut self.looked[i], true) {
            self.mapped[i] = Status::open_shared(self.prefix, Role::ALL[i]);
        }
        self.mapped[i].as_ref().map(Status::words)
    }

    /// Whether `me`, polling in vain, runs before a participant that is cued and has not yet
    /// taken its request though the orchestrator asks `me` after it: the processes that yield
    /// their CPU cycle in an order that puts `me` in front of it, and every request of the tick
    /// then waits for one more process switch. Not when `me` gave that cue: it has only just
    /// answered and not yet handed the CPU on. True at most once every [`STEER_EVERY`] steps.
    fn ahead_of_cued(&mut self, me: Role, my_step: u64) -> bool {
        if my_step < self.steered + STEER_EVERY {
            return false;
        }
        let gave = self.gave;
        for (i, r) in Role::ALL.iter().enumerate() {
            if *r == me {
                continue;
            }
            let Some(w) = self.words(i) else {
                continue;
            };
            let cue = w.cue.cue.load(Ordering::Acquire);
            if cue == 0 || w.taken.load(Ordering::Acquire) >= 2 * cue || gave == Some((i, cue)) {
                continue;
            }
            if decode_next(w.cue.next.load(Ordering::Acquire)).map(|(r, _)| r) == Some(me) {
                self.steered = my_step;
                return true;
            }
        }
        false
    }

    /// Cues the participant the orchestrator named as asked next in the `next` word it wrote
    /// into this one's `words` with the request just answered, if any
    /// (`supervise::CueWords`).
    #[inline]
    fn cue(&mut self, words: &StatusWords, next: u64) {
        let Some((role, step)) = decode_next(next) else {
            return;
        };
        let Some(i) = Role::ALL.iter().position(|&r| r == role) else {
            return;
        };
        if let Some(w) = self.words(i) {
            w.cue.cue.store(step + 1, Ordering::Release);
            words.cue.given.fetch_add(1, Ordering::Relaxed);
            self.gave = Some((i, step + 1));
        }
    }
}

/// How long a participant found in front of the one cued steps out of the queue of its CPU.
/// Yielding keeps it in place (the kernel cycles the processes that yield one CPU in a fixed
/// order); a sleep takes it out, and it comes back at the end, behind the one cued. On this
/// kind of machine the sleep lasts 60-130 µs, once.
const STEP_ASIDE: Duration = Duration::from_micros(20);

/// Steps between two times a participant steps aside: the cycle, once set right, stays so
/// until a nap draws it again; a participant cued in vain (its predecessor replaced by a
/// stand-in) costs the others one sleep in this many steps.
const STEER_EVERY: u64 = 256;

/// Polls a cued participant makes without yielding before it waits as usual: its request
/// comes after the orchestrator has relayed its predecessor's reply, a microsecond or two, and
/// these polls last some tens of microseconds.
const CUED_POLLS: u32 = 1000;

/// How a participant waits for its next request: polling with `wait`'s backoff, asleep
/// through the quiet part of the cadence (adaptive), and giving up when no request came for
/// `idle_limit` and its parent, the orchestrator, is gone.
struct Waiting {
    wait: WaitStrategy,
    spin_polls: u32,
    idle_limit: Duration,
    parent: libc::pid_t,
    /// The participant that waits.
    role: Role,
}

impl Waiting {
    /// The next request from `subscriber`; each empty poll counted in `empty_polls` and
    /// published in the status `words`.
    #[inline]
    fn next_request<I: Message>(
        &self,
        subscriber: &iceoryx2::port::subscriber::Subscriber<iceoryx2::prelude::ipc::Service, I, ()>,
        cadence: &Cadence,
        words: &StatusWords,
        empty_polls: &mut u64,
        last_step: Option<u64>,
        peers: &mut Peers,
    ) -> Result<I, IpcError> {
        let mut backoff = Backoff::with_spin(self.wait, self.spin_polls);
        // Cued for a step after the last one taken: that request comes next.
        let after = last_step.map_or(0, |l| l + 1);
        let mut cued_polls = 0u32;
        let mut sleep = if self.wait == WaitStrategy::Adaptive {
            cadence.sleep_until()
        } else {
            None
        };
        loop {
            let sample = subscriber.receive().map_err(iox("receive"))?;
            if let Some(s) = sample {
                return Ok(*s);
            }
            // Plain stores of a counter only this process writes: no cost worth naming.
            *empty_polls += 1;
            words.empty_polls.store(*empty_polls, Ordering::Release);
            if cued_polls < CUED_POLLS && words.cue.cue.load(Ordering::Acquire) > after {
                if cued_polls == 0 {
                    words.cue.cued_waits.fetch_add(1, Ordering::Relaxed);
                }
                cued_polls += 1;
                std::hint::spin_loop();
                continue;
            }
            if peers.ahead_of_cued(self.role, last_step.unwrap_or(0)) {
                // Out of the queue for a moment: back in it, behind the one cued.
                words.cue.steps_aside.fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(STEP_ASIDE);
                continue;
            }
            if let Some(until) = sleep.take() {
                sleep_until_ns(until);
                continue;
            }
            // SAFETY: getppid has no preconditions.
            if backoff.elapsed() > self.idle_limit && unsafe { libc::getppid() } != self.parent {
                return Err(IpcError::Iceoryx(format!(
                    "{}: orchestrator is gone",
                    self.role
                )));
            }
            backoff.pause();
        }
    }
}

/// Whether the request of header `h` is to be served: `Ok(false)` for `Stop`. An `Init`
/// starts the sequence again; a `Step` must come after the last one (multi-rate participants
/// are asked only on their own ticks, so any later step); any other kind is malformed.
#[inline]
fn admit(
    h: &Header,
    role: Role,
    last_step: &mut Option<u64>,
    cadence: &mut Cadence,
) -> Result<bool, IpcError> {
    match Kind::from_raw(h.kind) {
        Some(Kind::Stop) => Ok(false),
        Some(Kind::Init) => {
            *last_step = None;
            cadence.reset();
            Ok(true)
        }
        Some(Kind::Step) => {
            cadence.observe(h.sent_ns);
            if let Some(last) = last_step.filter(|&l| h.step <= l) {
                return Err(LinkError::OutOfOrder {
                    role,
                    expected: last + 1,
                    got: h.step,
                }
                .into());
            }
            *last_step = Some(h.step);
            Ok(true)
        }
        None => Err(LinkError::Malformed {
            role,
            step: h.step,
            what: format!("kind {}", h.kind),
        }
        .into()),
    }
}

/// The participant's memory of the request it last answered, to answer a repeat of it (the
/// orchestrator re-sends a request whose reply it has not seen) with the same reply, without
/// stepping the model again.
#[derive(Debug, Default)]
pub(crate) struct Repeat<O: Message> {
    last: Option<(u64, O)>,
}

impl<O: Message> Repeat<O> {
    /// Keeps `reply`, the answer to request `h`.
    pub(crate) fn keep(&mut self, h: &Header, reply: &O) {
        self.last = exchange_key(h).map(|k| (k, *reply));
    }

    /// The reply to send again if `h` repeats the request last answered: the same values,
    /// carrying the repeat's attempt, stamped anew. `None` for anything else (a new request,
    /// or a first sending that repeats a step, which stays a protocol error).
    pub(crate) fn answer(&self, h: &Header) -> Option<O> {
        let (k, reply) = self.last?;
        if h.attempt == 0 || exchange_key(h) != Some(k) {
            return None;
        }
        let mut again = reply;
        again.header_mut().attempt = h.attempt;
        let sent = if again.header().sent_ns == 0 {
            0
        } else {
            now_ns()
        };
        again.stamp_at(sent);
        Some(again)
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
    /// Run under `SCHED_FIFO` at this priority with memory locked (`--realtime`).
    pub realtime: Option<i32>,
}

impl ParticipantArgs {
    /// Parses the arguments after the program name (and after a `participant ROLE` prefix).
    pub fn parse(args: &[String]) -> Result<Self, String> {
        let mut params = None;
        let mut prefix = None;
        let mut wait = WaitStrategy::default();
        let mut cpu = None;
        let mut realtime = None;
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
                        .ok_or_else(|| format!("--wait {w}: allowed spin, adaptive, sleep, paced"))?;
                }
                "--realtime" => {
                    let p = value("--realtime")?;
                    realtime = Some(
                        p.parse()
                            .ok()
                            .filter(|p| (1..=99).contains(p))
                            .ok_or_else(|| format!("--realtime {p}: expected a priority 1-99"))?,
                    );
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
                        "unknown argument `{other}`; expected --params, --prefix, --wait, --cpu, --realtime"
                    ))
                }
            }
        }
        Ok(ParticipantArgs {
            params: params.ok_or("missing --params JSON")?,
            prefix: prefix.ok_or("missing --prefix NAME")?,
            wait,
            cpu,
            realtime,
        })
    }
}

/// Why a participant process could not serve.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// Its command line.
    #[error("{process}: {what}")]
    Arguments {
        /// The participant's process name.
        process: &'static str,
        /// What is wrong and what is allowed.
        what: String,
    },
    /// Its `--params` JSON does not describe its settings.
    #[error("{process}: bad --params: {what}")]
    Params {
        /// The participant's process name.
        process: &'static str,
        /// The JSON error.
        what: String,
    },
    /// Its model could not be built from the settings (a design failed).
    #[error("{process}: {what}")]
    Model {
        /// The participant's process name.
        process: &'static str,
        /// Why.
        what: String,
    },
    /// The transport failed or the orchestrator went away.
    #[error("{process}: {source}")]
    Link {
        /// The participant's process name.
        process: &'static str,
        /// The failure.
        source: IpcError,
    },
}

/// Idle time after which a participant checks that its orchestrator still exists.
pub const IDLE_LIMIT: Duration = Duration::from_secs(2);

/// Entry point of a participant process: parses the arguments, builds the model from its JSON
/// settings with `make`, and serves until stopped.
pub fn participant_main<S, P>(
    args: &[String],
    make: impl FnOnce(S) -> Result<P, String>,
) -> Result<(), ServeError>
where
    S: serde::de::DeserializeOwned,
    P: Participant,
{
    participant_main_with(args, make, |_| {})
}

/// A panic in a participant prints one line naming the process, where and why, and no
/// backtrace (set `TILTSIM_BACKTRACE=1` to have one): the orchestrator's own message, naming
/// the participant and the step, follows and ends the run.
fn quiet_panics(process: &'static str) {
    if std::env::var_os("TILTSIM_BACKTRACE").is_some_and(|v| v == "1") {
        return;
    }
    std::panic::set_hook(Box::new(move |info| {
        let why = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".into());
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        eprintln!("{process}: panicked{at}: {why}");
    }));
}

/// [`participant_main`] with a reply hook (see [`serve_with`]); for test participants.
pub fn participant_main_with<S, P>(
    args: &[String],
    make: impl FnOnce(S) -> Result<P, String>,
    tamper: impl FnMut(&mut P::Output),
) -> Result<(), ServeError>
where
    S: serde::de::DeserializeOwned,
    P: Participant,
{
    let process = P::ROLE.process_name();
    quiet_panics(process);
    let a = ParticipantArgs::parse(args).map_err(|what| ServeError::Arguments { process, what })?;
    let settings: S = serde_json::from_str(&a.params).map_err(|e| ServeError::Params {
        process,
        what: e.to_string(),
    })?;
    let model = make(settings).map_err(|what| ServeError::Model { process, what })?;
    if matches!(a.wait, WaitStrategy::Paced | WaitStrategy::Adaptive) {
        // Naps and the sleep through a long gap between requests end on time.
        crate::wait::tight_timer_slack();
    }
    if let Some(priority) = a.realtime {
        crate::realtime::enter(priority).map_err(|what| ServeError::Arguments { process, what })?;
    }
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
        .map_err(|source| ServeError::Link { process, source })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::FromController;

    fn header(step: u64, kind: Kind, attempt: u32) -> Header {
        Header {
            attempt,
            ..Header::new(step, kind)
        }
    }

    /// The status words of `roles` under a prefix of their own (removed on drop).
    fn statuses(roles: &[Role]) -> (String, Vec<Status>) {
        let prefix = crate::ipc::unique_prefix();
        let made = roles
            .iter()
            .map(|&r| Status::create(&prefix, r).unwrap())
            .collect();
        (prefix, made)
    }

    #[test]
    fn the_one_named_next_is_cued_for_its_step_and_nobody_when_none_is_named() {
        let (prefix, made) = statuses(&[Role::Actuator, Role::Plant]);
        let (actuator, plant) = (made[0].words(), made[1].words());
        let mut peers = Peers::new(&prefix);
        let next = super::super::supervise::encode_next(Some((Role::Plant, 41)));
        peers.cue(actuator, next);
        assert_eq!(plant.cue.cue.load(Ordering::Acquire), 42);
        assert_eq!(actuator.cue.given.load(Ordering::Acquire), 1);
        plant.cue.cue.store(0, Ordering::Release);
        peers.cue(actuator, 0);
        assert_eq!(plant.cue.cue.load(Ordering::Acquire), 0);
        assert_eq!(actuator.cue.given.load(Ordering::Acquire), 1);
    }

    #[test]
    fn a_participant_in_front_of_the_one_cued_steps_aside_once_in_a_while() {
        let (prefix, made) = statuses(&[Role::Actuator, Role::Plant, Role::Controller]);
        let actuator = made[0].words();
        let mut peers = Peers::new(&prefix);
        // The actuator is cued for step 500 and asks the plant after it; it has taken 499.
        actuator.cue.cue.store(501, Ordering::Release);
        actuator.taken.store(2 * 499 + 2, Ordering::Release);
        let next = |r| super::super::supervise::encode_next(Some((r, 500)));
        actuator
            .cue
            .next
            .store(next(Role::Plant), Ordering::Release);
        // Not the one asked after it: stays.
        assert!(!peers.ahead_of_cued(Role::Controller, 499));
        // The plant runs in front of it: steps aside, then not again within STEER_EVERY steps.
        assert!(peers.ahead_of_cued(Role::Plant, 499));
        assert!(!peers.ahead_of_cued(Role::Plant, 499 + STEER_EVERY - 1));
        // Once the actuator has taken its request, nobody is in front of it.
        actuator.taken.store(2 * 500 + 2, Ordering::Release);
        assert!(!peers.ahead_of_cued(Role::Plant, 499 + STEER_EVERY));
        actuator.taken.store(2 * 499 + 2, Ordering::Release);
        assert!(peers.ahead_of_cued(Role::Plant, 499 + STEER_EVERY));
        // Named nobody: nobody steps aside.
        actuator.cue.next.store(0, Ordering::Release);
        assert!(!peers.ahead_of_cued(Role::Plant, 10 * STEER_EVERY));
    }

    #[test]
    fn a_participant_that_has_just_cued_the_next_does_not_step_aside_for_it() {
        // Two left (the actuator replaced): the plant and the controller ask each other next.
        let (prefix, made) = statuses(&[Role::Plant, Role::Controller]);
        let (plant, controller) = (made[0].words(), made[1].words());
        let encode = super::super::supervise::encode_next;
        controller
            .cue
            .next
            .store(encode(Some((Role::Plant, 700))), Ordering::Release);
        controller.taken.store(2 * 698 + 2, Ordering::Release);
        // The plant answers step 699 and cues the controller for 700, then polls in vain
        // before it has yielded: not in front of the one it cued.
        let mut peers = Peers::new(&prefix);
        peers.cue(plant, encode(Some((Role::Controller, 700))));
        assert!(!peers.ahead_of_cued(Role::Plant, 699));
        // The same cue given by another: the plant is in front of the controller.
        let mut other = Peers::new(&prefix);
        assert!(other.ahead_of_cued(Role::Plant, 699));
    }

    #[test]
    fn the_next_word_names_a_role_and_its_step() {
        use super::super::supervise::{decode_next, encode_next};
        for r in Role::ALL {
            for step in [0, 1, 49, (1 << 56) - 1] {
                assert_eq!(decode_next(encode_next(Some((r, step)))), Some((r, step)));
            }
        }
        assert_eq!(encode_next(None), 0);
        assert_eq!(decode_next(0), None);
        // A step past the word's 56 bits names nobody rather than a wrong step.
        assert_eq!(encode_next(Some((Role::Plant, 1 << 56))), 0);
    }

    #[test]
    fn a_repeated_request_is_answered_with_the_last_reply_and_anything_else_is_not() {
        let mut r = Repeat::<FromController>::default();
        assert!(
            r.answer(&header(7, Kind::Step, 1)).is_none(),
            "nothing answered yet"
        );
        let reply = FromController {
            header: header(7, Kind::Step, 0),
            delta_a_cmd: 0.125,
            theta_ref: -0.5,
            ..Default::default()
        };
        r.keep(&header(7, Kind::Step, 0), &reply);
        let again = r
            .answer(&header(7, Kind::Step, 2))
            .expect("a repeat of step 7");
        assert_eq!((again.delta_a_cmd, again.theta_ref), (0.125, -0.5));
        assert_eq!((again.header.step, again.header.attempt), (7, 2));
        assert_eq!(
            again.header.size as usize,
            core::mem::size_of::<FromController>()
        );
        // A first sending of the same step again is a protocol error for the caller, not a
        // repeat; another step, or the Init of the same index, is a new request.
        assert!(r.answer(&header(7, Kind::Step, 0)).is_none());
        assert!(r.answer(&header(8, Kind::Step, 1)).is_none());
        assert!(r.answer(&header(7, Kind::Init, 1)).is_none());
        assert!(r.answer(&header(u64::MAX, Kind::Stop, 1)).is_none());
    }
}
