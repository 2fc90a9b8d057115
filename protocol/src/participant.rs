//! The participant abstraction: a model with an explicit step and no IPC inside.

use std::time::Instant;

use crate::msg::{clock_ns, Header, Kind, Message, FLAG_HELD, FLAG_HOLD_BAD_INPUT, FLAG_REJECTED};

/// The three participant roles of a tiltsim run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Role {
    /// Vehicle body and bogie dynamics plus the track (`plant-proc`).
    Plant,
    /// Anti-roll-bar actuator (`actuator-proc`).
    Actuator,
    /// Tilt controller (`controller-proc`).
    Controller,
}

impl Role {
    /// All roles.
    pub const ALL: [Role; 3] = [Role::Plant, Role::Actuator, Role::Controller];

    /// Short name, as used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Role::Plant => "plant",
            Role::Actuator => "actuator",
            Role::Controller => "controller",
        }
    }

    /// Name of the participant's operating-system process.
    pub fn process_name(self) -> &'static str {
        match self {
            Role::Plant => "plant-proc",
            Role::Actuator => "actuator-proc",
            Role::Controller => "controller-proc",
        }
    }

    /// Parses a short name.
    pub fn parse(s: &str) -> Option<Role> {
        Role::ALL
            .into_iter()
            .find(|r| r.name() == s || r.process_name() == s)
    }
}

impl core::fmt::Display for Role {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// A co-simulation participant: a plain model struct wrapped with its sample types.
///
/// The step index and period are decided by the orchestrator; the participant computes what
/// it is asked and never reads a clock to decide anything.
pub trait Participant: Send + 'static {
    /// Sample the participant receives.
    type Input: Message;
    /// Sample the participant returns.
    type Output: Message;
    /// Its role.
    const ROLE: Role;

    /// Outputs at `t_0`, before any step.
    fn initial_output(&mut self) -> Self::Output;

    /// Advances from `t_k` to `t_{k+1}` (`k` = `input.header.step`) with `input` held over the
    /// interval, and returns the outputs at `t_{k+1}`.
    fn step(&mut self, input: &Self::Input) -> Self::Output;

    /// Why the last step failed, if it did (an FMU whose `doStep` returned an error). The
    /// transport then ends the participant as if its process had exited: no reply is sent.
    /// Native models never fail a step.
    fn failure(&mut self) -> Option<String> {
        None
    }
}

/// A model as a transport serves it: checks every request where it arrives and answers it.
/// Shared by both transports so they cannot differ in what they compute.
pub struct Served<P: Participant> {
    /// The model.
    pub model: P,
    last_good: Option<P::Input>,
    /// Whether replies carry wall-clock times (receive, compute, send).
    timed: bool,
}

impl<P: Participant> Served<P> {
    /// Wraps a model; its replies are timed.
    pub fn new(model: P) -> Self {
        Served {
            model,
            last_good: None,
            timed: true,
        }
    }

    /// Whether replies carry wall-clock times. Untimed, their `recv_ns`, `compute_ns` and
    /// `sent_ns` are 0 and no clock is read: for runs that report no timing (a sweep's
    /// samples), where the clock reads cost about 5 % of the run. Values do not depend on it.
    pub fn set_timed(&mut self, timed: bool) {
        self.timed = timed;
    }

    /// The monotonic clock (ns) when timed, else 0 ([`clock_ns`]).
    pub fn clock(&self) -> u64 {
        clock_ns(self.timed)
    }

    /// Answers one step of a free run, on any transport: `input` (the newest request that
    /// arrived, or the one read last) as step `step`, whose reply carries the relay number
    /// `relay` of that input, its compute time measured from the read to now including a
    /// study's busy wait of `busy_ns` (the CPU is kept busy, as a slow step's), and is
    /// stamped for sending. The caller checks [`Participant::failure`] before publishing.
    pub fn answer_free(
        &mut self,
        input: &P::Input,
        step: u64,
        relay: u64,
        busy_ns: u64,
    ) -> P::Output {
        let mut req = *input;
        {
            let rh = req.header_mut();
            rh.step = step;
            rh.kind = Kind::Step as u32;
            rh.flags = 0;
            rh.field = 0;
            rh.clock = Default::default();
        }
        let mut reply = self.answer(&req);
        let rh = reply.header_mut();
        if busy_ns > 0 {
            while crate::msg::now_ns() < rh.recv_ns + busy_ns {
                std::hint::spin_loop();
            }
        }
        rh.relay = relay;
        rh.compute_ns = crate::msg::now_ns().saturating_sub(rh.recv_ns);
        reply.stamp();
        reply
    }

    /// Answers one request: checks it, runs the model and stamps the reply's header.
    ///
    /// A request with a NaN or infinite value is bad data caught where it arrives: the model
    /// is not stepped with it. With [`FLAG_HOLD_BAD_INPUT`] the last good request's values
    /// are used instead (the reply says so with [`FLAG_HELD`]); otherwise the reply is
    /// [`FLAG_REJECTED`]. Either way `Header::field` names the field.
    pub fn answer(&mut self, req: &P::Input) -> P::Output {
        let h = *req.header();
        let recv_ns = self.clock();
        let mut flags = 0;
        let mut field = 0;
        let mut input = *req;
        if let Some(i) = req.first_non_finite() {
            field = i as u32 + 1;
            match self.last_good {
                Some(good) if h.flags & FLAG_HOLD_BAD_INPUT != 0 => {
                    input = good;
                    *input.header_mut() = h;
                    flags = FLAG_HELD;
                }
                _ => flags = FLAG_REJECTED,
            }
        } else if h.kind == Kind::Step as u32 {
            self.last_good = Some(*req);
        }
        let started = self.timed.then(Instant::now);
        let mut out = match Kind::from_raw(h.kind) {
            _ if flags == FLAG_REJECTED => P::Output::default(),
            Some(Kind::Init) => self.model.initial_output(),
            Some(Kind::Step) => self.model.step(&input),
            // Stop and unknown kinds carry no data; the caller decides what to do with them.
            _ => P::Output::default(),
        };
        let compute_ns = started.map_or(0, |t| {
            u64::try_from(t.elapsed().as_nanos()).unwrap_or(u64::MAX)
        });
        *out.header_mut() = Header {
            step: h.step,
            kind: h.kind,
            flags,
            field,
            recv_ns,
            compute_ns,
            ..Default::default()
        };
        out.stamp_at(self.clock());
        out
    }
}
