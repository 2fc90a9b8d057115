//! The relaying of a free run: what was relayed to each consumer, and the samples on their
//! way over the links until the hub delivers them.

use std::collections::VecDeque;

use cosim::msg::Message;
use cosim::{Endpoint, LinkError, Role};
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::roles::RoleMap;

use super::compose::Store;
use crate::engine::launch::Participants;

/// Relays one consumer's inputs and remembers which producer steps each carried.
#[derive(Default)]
pub(super) struct Relay {
    next: u64,
    sent: VecDeque<(u64, [Option<i64>; 3])>,
}

impl Relay {
    pub(super) fn send<I: Message, O: Message>(
        &mut self,
        ep: &mut Box<dyn Endpoint<I, O>>,
        mut req: I,
        from: [Option<i64>; 3],
    ) -> Result<(), LinkError> {
        req.header_mut().relay = self.next;
        self.sent.push_back((self.next, from));
        self.next += 1;
        ep.send(&req)
    }

    /// The producer steps of the oldest relay the consumer may still read.
    pub(super) fn oldest(&self) -> Option<[Option<i64>; 3]> {
        self.sent.front().map(|(_, f)| *f)
    }

    /// The producer steps of relay `n`; older relays are forgotten (a consumer reads newer
    /// relays only).
    pub(super) fn take(&mut self, n: u64) -> Option<[Option<i64>; 3]> {
        while self.sent.front().is_some_and(|(m, _)| *m < n) {
            self.sent.pop_front();
        }
        self.sent.front().filter(|(m, _)| *m == n).map(|(_, f)| *f)
    }
}

/// A sample on its way over a link, delivered to its consumer at `due_ns`.
#[derive(Clone, Copy)]
struct InFlight {
    due_ns: u64,
    link: LinkId,
    step: i64,
}

/// What the hub has delivered over the links and what is still on its way.
pub(super) struct Deliveries {
    /// Per link ([`LinkId`] order), the newest producer step delivered (−1: the output at t₀).
    pub(super) newest: [i64; 4],
    in_flight: Vec<InFlight>,
    /// Flags for the next request of each role (a scheduled crash).
    pub(super) flags: RoleMap<u32>,
    /// Which consumers have published a step (and so read their starting request).
    started: RoleMap<bool>,
    /// Consumers with a newer input held back until they have started.
    held: RoleMap<bool>,
}

impl Deliveries {
    /// Nothing delivered yet beyond the outputs at t₀, nothing on its way.
    pub(super) fn new() -> Self {
        Deliveries {
            newest: [-1; 4],
            in_flight: Vec::new(),
            flags: RoleMap::default(),
            started: RoleMap::default(),
            held: RoleMap::default(),
        }
    }

    /// Sends a sample of producer step `step` over `link` with the delay the link gave it
    /// (`None`: lost): relayed at once, or later by [`Deliveries::release`].
    #[allow(clippy::too_many_arguments)]
    pub(super) fn send(
        &mut self,
        link: LinkId,
        step: i64,
        delay: Option<u64>,
        now: u64,
        dt_ns: u64,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        match delay {
            None => Ok(()),
            Some(0) => self.deliver(link, step, ps, store, relays),
            Some(d) => {
                self.in_flight.push(InFlight {
                    due_ns: now + d * dt_ns,
                    link,
                    step,
                });
                Ok(())
            }
        }
    }

    /// Delivers every sample whose delay has passed, in the order they became due.
    pub(super) fn release(
        &mut self,
        now: u64,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        if self.in_flight.iter().all(|f| f.due_ns > now) {
            return Ok(());
        }
        let mut due: Vec<InFlight> = Vec::new();
        self.in_flight.retain(|f| {
            if f.due_ns <= now {
                due.push(*f);
                false
            } else {
                true
            }
        });
        due.sort_by_key(|f| (f.due_ns, f.link as usize, f.step));
        for f in due {
            self.deliver(f.link, f.step, ps, store, relays)?;
        }
        Ok(())
    }

    /// The consumer of `link` holds the newest sample (by producer step) that has arrived: a
    /// newer one is relayed with the other input of that consumer as it stands.
    fn deliver(
        &mut self,
        link: LinkId,
        step: i64,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        if step <= self.newest[link as usize] {
            return Ok(());
        }
        self.newest[link as usize] = step;
        let consumer = match link {
            LinkId::Measurement => Role::Controller,
            LinkId::BarAngle => Role::Plant,
            LinkId::ActuatorCommand | LinkId::BarTwist => Role::Actuator,
        };
        if self.started[consumer] {
            self.relay(consumer, ps, store, relays)
        } else {
            // Not yet started: a relay now could overwrite its starting request, unread (a
            // participant stopped before its first step). It gets the newest at its first output.
            self.held[consumer] = true;
            Ok(())
        }
    }

    /// `role` has published its first step, so it has read its starting request: the input
    /// held back since then is relayed.
    pub(super) fn started(
        &mut self,
        role: Role,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        self.started[role] = true;
        if std::mem::take(&mut self.held[role]) {
            self.relay(role, ps, store, relays)?;
        }
        Ok(())
    }

    /// Relays to `consumer` its input composed from the newest samples delivered to it.
    fn relay(
        &mut self,
        consumer: Role,
        ps: &mut Participants,
        store: &Store,
        relays: &mut RoleMap<Relay>,
    ) -> Result<(), String> {
        let n = self.newest;
        let lost = || format!("{consumer}: a delivered sample is not in the store");
        let link_err = |e: LinkError| e.to_string();
        let flags = std::mem::take(&mut self.flags[consumer]);
        match consumer {
            Role::Controller => {
                let q = n[LinkId::Measurement as usize];
                let mut req = store.controller_input(q).ok_or_else(lost)?;
                req.header.flags |= flags;
                relays[consumer]
                    .send(&mut ps.controller, req, [Some(q), None, None])
                    .map_err(link_err)
            }
            Role::Plant => {
                let q = n[LinkId::BarAngle as usize];
                let mut req = store.plant_input(q).ok_or_else(lost)?;
                req.header.flags |= flags;
                relays[consumer]
                    .send(&mut ps.plant, req, [None, Some(q), None])
                    .map_err(link_err)
            }
            Role::Actuator => {
                let (qc, qp) = (
                    n[LinkId::ActuatorCommand as usize],
                    n[LinkId::BarTwist as usize],
                );
                let mut req = store.actuator_input(qc, qp).ok_or_else(lost)?;
                req.header.flags |= flags;
                relays[consumer]
                    .send(&mut ps.actuator, req, [Some(qp), None, Some(qc)])
                    .map_err(link_err)
            }
        }
    }
}
