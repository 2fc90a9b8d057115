//! The participant abstraction: a model with an explicit step and no IPC inside.

use std::time::Instant;

use crate::msg::{Header, Kind, Message, PROTOCOL_VERSION};

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
}

/// Answers one request: runs the model and stamps the reply's header. Shared by both
/// transports so they cannot differ in what they compute.
pub fn answer<P: Participant>(p: &mut P, req: &P::Input) -> P::Output {
    let h = *req.header();
    let started = Instant::now();
    let mut out = match Kind::from_raw(h.kind) {
        Some(Kind::Init) => p.initial_output(),
        Some(Kind::Step) => p.step(req),
        // Stop and unknown kinds carry no data; the caller decides what to do with them.
        _ => P::Output::default(),
    };
    let compute_ns = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
    *out.header_mut() = Header {
        step: h.step,
        kind: h.kind,
        version: PROTOCOL_VERSION,
        compute_ns,
    };
    out
}
