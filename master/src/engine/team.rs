//! The participants handle the master algorithms work through: one request and its reply at a
//! time, with the manipulators on the way (link effects on the values, scheduled faults and
//! the bad-data flag on the requests, degraded replacement on a failure) and a record of every
//! exchange for the observers.

use cosim::endpoint::ExitReport;
use cosim::msg::{clock_ns, FromActuator, FromController, FromPlant, Header, Message};
use cosim::msg::{ToActuator, ToController, ToPlant, FLAG_HELD, FLAG_HOLD_BAD_INPUT};
use cosim::{Endpoint, Kind, LinkError, Role};
use tiltsim_formats::events::{EventKind, EventLog};
use tiltsim_scenario::faults::OnBadData;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::Scenario;

use super::launch::{Held, Participants};
use super::manipulate::{Control, Manipulator};
use super::manipulator::{Degrader, FaultSchedule};
pub(crate) use super::observe::Exchange;
use crate::links::LinkSet;

/// Picks one participant's endpoint out of the set.
pub(crate) type Pick<I, O> = fn(&mut Participants) -> &mut Box<dyn Endpoint<I, O>>;

/// The plant's endpoint.
pub(crate) fn plant(ps: &mut Participants) -> &mut Box<dyn Endpoint<ToPlant, FromPlant>> {
    &mut ps.plant
}
/// The actuator's endpoint.
pub(crate) fn actuator(ps: &mut Participants) -> &mut Box<dyn Endpoint<ToActuator, FromActuator>> {
    &mut ps.actuator
}
/// The controller's endpoint.
pub(crate) fn controller(
    ps: &mut Participants,
) -> &mut Box<dyn Endpoint<ToController, FromController>> {
    &mut ps.controller
}

/// The participant asked after `role`'s step request for tick `k` among those `cued`, and for
/// which step, if another: a Gauss-Seidel tick asks the controller (when due, every
/// `controller_period` ticks), the actuator and the plant in that order, and the plant's
/// successor is the first asked in the next tick.
pub(crate) fn asked_after(
    role: Role,
    k: u64,
    controller_period: u64,
    cued: impl Fn(Role) -> bool,
) -> Option<(Role, u64)> {
    const ORDER: [Role; 3] = [Role::Controller, Role::Actuator, Role::Plant];
    let mut i = ORDER.iter().position(|&r| r == role)?;
    let mut tick = k;
    for _ in 1..ORDER.len() {
        i += 1;
        if i == ORDER.len() {
            i = 0;
            tick += 1;
        }
        let r = ORDER[i];
        if (r != Role::Controller || tick.is_multiple_of(controller_period)) && cued(r) {
            return Some((r, tick));
        }
    }
    None
}

/// The participants with everything that acts on the way to and from them.
pub(crate) struct Team<'a> {
    s: &'a Scenario,
    /// The participants.
    pub ps: Participants,
    /// Their latest outputs.
    pub held: Held,
    /// The scenario's manipulators, then the caller's.
    manipulators: Vec<Box<dyn Manipulator>>,
    /// The participants replaced by stand-ins, with their exit reports.
    lost: RoleMap<Option<ExitReport>>,
    /// Request flags for the next request of each role (crash faults).
    flags: RoleMap<u32>,
    /// What happened, in simulated time.
    pub events: EventLog,
    /// This tick's exchanges (the loop hands them to the observers and clears them).
    pub exchanges: Vec<Exchange>,
    /// Whether exchanges are stamped with the wall clock (`RunOptions::timing`).
    pub timed: bool,
}

impl<'a> Team<'a> {
    /// The team of scenario `s` around running participants `ps`, with the scenario's
    /// manipulators (link effects, scheduled faults, degraded stand-ins) and then `extra`.
    pub fn new(s: &'a Scenario, ps: Participants, extra: Vec<Box<dyn Manipulator>>) -> Self {
        let mut events = EventLog::new(s.run.dt_s);
        LinkSet::describe(&s.links, &mut events);
        let mut manipulators: Vec<Box<dyn Manipulator>> = vec![
            Box::new(LinkSet::new(&s.links, s.run.seed)),
            Box::new(FaultSchedule::new(&s.faults, s.run.dt_s)),
            Box::new(Degrader::new(s)),
        ];
        manipulators.extend(extra);
        Team {
            s,
            ps,
            held: Held::default(),
            manipulators,
            lost: RoleMap::default(),
            flags: RoleMap::default(),
            events,
            exchanges: Vec::new(),
            timed: true,
        }
    }

    /// The scenario.
    pub fn scenario(&self) -> &'a Scenario {
        self.s
    }

    /// Whether a participant was lost and replaced.
    pub fn degraded(&self) -> bool {
        Role::ALL.iter().any(|r| self.lost[*r].is_some())
    }

    /// The participants, for their shut-down.
    pub fn into_participants(self) -> Participants {
        self.ps
    }

    /// Exit reports of participants replaced by their stand-ins.
    pub fn take_lost(&mut self) -> RoleMap<Option<ExitReport>> {
        std::mem::take(&mut self.lost)
    }

    /// What the manipulators may act on.
    fn control(&mut self) -> (Control<'_>, &mut Vec<Box<dyn Manipulator>>) {
        let ctl = Control {
            ps: &mut self.ps,
            held: &self.held,
            flags: &mut self.flags,
            lost: &mut self.lost,
            events: &mut self.events,
        };
        (ctl, &mut self.manipulators)
    }

    /// Whether every manipulator lets tick `k` begin before the last reply of `k − 1` is taken
    /// ([`Manipulator::lets_tick_start_early`]).
    pub fn may_start_early(&self, k: u64) -> bool {
        self.manipulators.iter().all(|m| m.lets_tick_start_early(k))
    }

    /// Whether participant `r` was replaced by its stand-in.
    pub fn replaced(&self, r: Role) -> bool {
        self.lost[r].is_some()
    }

    /// Tells the manipulators that tick `k` begins (the scheduled faults act here).
    pub fn inject_faults(&mut self, k: u64) {
        let (mut ctl, ms) = self.control();
        for m in ms.iter_mut() {
            m.tick_commencing(k, &mut ctl);
        }
    }

    /// Carries value `v` sent at tick `k` over `link`, through every manipulator in order.
    pub fn carry(&mut self, link: LinkId, k: u64, v: f64) -> f64 {
        let t = cosim::time::tick_time(k, self.s.run.dt_s);
        self.manipulators
            .iter_mut()
            .fold(v, |v, m| m.carry(link, k, t, v, &mut self.events))
    }

    /// The initial outputs at t₀ of every participant.
    pub fn initialise(&mut self) -> Result<(), LinkError> {
        let h = |k| Header::new(k, Kind::Init);
        self.held.p = self.exchange(
            plant,
            ToPlant {
                header: h(0),
                ..Default::default()
            },
            Kind::Init,
        )?;
        self.held.a = self.exchange(
            actuator,
            ToActuator {
                header: h(0),
                ..Default::default()
            },
            Kind::Init,
        )?;
        self.held.c = self.exchange(
            controller,
            ToController {
                header: h(0),
                ..Default::default()
            },
            Kind::Init,
        )?;
        Ok(())
    }

    /// Sends a request with this tick's flags; returns the send time.
    fn post<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        mut req: I,
    ) -> Result<u64, LinkError> {
        let role = pick(&mut self.ps).role();
        self.flag(role, &mut req);
        let h = *req.header();
        if self.ps.cued()[role] && Kind::from_raw(h.kind) == Some(Kind::Step) {
            let cued = |r: Role| self.ps.cued()[r] && self.lost[r].is_none();
            let next = asked_after(role, h.step, self.s.controller_period_ticks(), cued);
            pick(&mut self.ps).set_cue_next(next);
        }
        let t0 = clock_ns(self.timed);
        pick(&mut self.ps).send(&req)?;
        Ok(t0)
    }

    /// Sets on `role`'s request the flags due to it: those of this tick's faults (taken), and
    /// the bad-data policy's.
    fn flag<I: Message>(&mut self, role: Role, req: &mut I) {
        req.header_mut().flags |= std::mem::take(&mut self.flags[role]);
        if self.s.faults.on_bad_data == OnBadData::Hold {
            req.header_mut().flags |= FLAG_HOLD_BAD_INPUT;
        }
    }

    /// Receives the reply to a request sent at `t0`; logs held bad data and the exchange.
    fn collect<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        k: u64,
        kind: Kind,
        t0: u64,
    ) -> Result<O, LinkError> {
        let ep = pick(&mut self.ps);
        let role = ep.role();
        let reply = ep.receive(k, kind)?;
        let t3 = clock_ns(self.timed);
        let h = *reply.header();
        if h.flags & FLAG_HELD != 0 {
            self.events.push(
                k,
                role.name(),
                EventKind::BadInputHeld,
                f64::NAN,
                format!(
                    "non-finite `{}` in {}; last good input used",
                    cosim::endpoint::field_name::<I>(h.field),
                    I::NAME
                ),
            );
        }
        self.exchanges.push(Exchange {
            step: k,
            role,
            sent_ns: t0,
            reply: h,
            received_ns: t3,
        });
        Ok(reply)
    }

    /// One request and its reply.
    fn exchange<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        req: I,
        kind: Kind,
    ) -> Result<O, LinkError> {
        let k = req.header().step;
        let t0 = self.post(pick, req)?;
        self.collect(pick, k, kind, t0)
    }

    /// Asks the manipulators, in order, to replace the participant that failed with `e` by
    /// a stand-in; returns `e` (as the last one handed it on) when none does.
    fn recover(&mut self, k: u64, e: LinkError) -> Result<(), LinkError> {
        let (mut ctl, ms) = self.control();
        let mut e = e;
        for m in ms.iter_mut() {
            match m.participant_failed(k, e, &mut ctl) {
                Ok(()) => return Ok(()),
                Err(next) => e = next,
            }
        }
        Err(e)
    }

    /// One step exchange; on failure the degraded-mode stand-in (if the scenario has one)
    /// answers the same request.
    pub fn ask<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        req: I,
    ) -> Result<O, LinkError> {
        let k = req.header().step;
        match self.exchange(pick, req, Kind::Step) {
            Ok(r) => Ok(r),
            Err(e) => {
                self.recover(k, e)?;
                self.exchange(pick, req, Kind::Step)
            }
        }
    }

    /// Sends a step request without waiting; `None` if the participant failed and was
    /// replaced (its stand-in is asked in [`Team::answer`]).
    pub fn post_step<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        req: I,
    ) -> Result<Option<u64>, LinkError> {
        let k = req.header().step;
        match self.post(pick, req) {
            Ok(t0) => Ok(Some(t0)),
            Err(e) => {
                self.recover(k, e)?;
                Ok(None)
            }
        }
    }

    /// Sends a step request to a participant whose previous request is still being answered,
    /// where its transport queues it behind that one (`Endpoint::send_ahead`); returns the send
    /// time, or `None` when it was not sent (send it with [`Team::post_step`] once the previous
    /// reply is in). Not one that a fault flags: a crash is asked of the request in turn.
    pub fn post_ahead<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        mut req: I,
    ) -> Option<u64> {
        let role = pick(&mut self.ps).role();
        if self.flags[role] != 0 {
            return None;
        }
        self.flag(role, &mut req);
        let t0 = clock_ns(self.timed);
        // A request that could not be sent ahead is sent the usual way, which reports (and
        // recovers from) a failure.
        matches!(pick(&mut self.ps).send_ahead(&req), Ok(true)).then_some(t0)
    }

    /// The reply to a request posted with [`Team::post_step`].
    pub fn answer<I: Message, O: Message>(
        &mut self,
        pick: Pick<I, O>,
        req: I,
        posted: Option<u64>,
    ) -> Result<O, LinkError> {
        let k = req.header().step;
        let got = match posted {
            Some(t0) => self.collect(pick, k, Kind::Step, t0),
            None => self.exchange(pick, req, Kind::Step),
        };
        match got {
            Ok(r) => Ok(r),
            Err(e) => {
                self.recover(k, e)?;
                self.exchange(pick, req, Kind::Step)
            }
        }
    }

    /// Logs that the run stopped on `e` at tick `k`.
    pub fn log_failure(&mut self, k: u64, e: &LinkError) {
        self.events.push(
            k,
            e.role().name(),
            EventKind::RunFailed,
            f64::NAN,
            e.cause(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::asked_after;
    use cosim::Role::{Actuator, Controller, Plant};

    #[test]
    fn the_one_asked_next_follows_the_gauss_seidel_order_across_ticks() {
        let all = |_| true;
        // The MPC every 50 ticks: due at 100, not at 101.
        assert_eq!(asked_after(Controller, 100, 50, all), Some((Actuator, 100)));
        assert_eq!(asked_after(Actuator, 100, 50, all), Some((Plant, 100)));
        assert_eq!(asked_after(Plant, 100, 50, all), Some((Actuator, 101)));
        assert_eq!(asked_after(Plant, 149, 50, all), Some((Controller, 150)));
        // A controller asked every tick.
        assert_eq!(asked_after(Plant, 7, 1, all), Some((Controller, 8)));
    }

    #[test]
    fn a_participant_not_cued_is_passed_over_and_nobody_named_when_none_is_left() {
        let no_plant = |r| r != Plant;
        assert_eq!(asked_after(Actuator, 3, 1, no_plant), Some((Controller, 4)));
        // Itself next (the controller not due): nobody else to cue.
        assert_eq!(asked_after(Actuator, 3, 50, no_plant), None);
        let only_actuator = |r| r == Actuator;
        assert_eq!(asked_after(Actuator, 3, 1, only_actuator), None);
    }
}
