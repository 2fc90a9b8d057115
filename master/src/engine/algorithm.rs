//! Master algorithms: in which order one tick's requests go out and its replies come back
//! (docs/architecture.md, "Coupling").
//!
//! * [`GaussSeidel`]: controller (when due), actuator, plant in turn, each with the newest
//!   output of the one before. No delay on the forward links.
//! * [`Jacobi`]: every request from the previous tick's outputs first, then every reply. One
//!   tick on every link; the participants compute in parallel. Its replies are taken in the
//!   order controller, plant, actuator, so that the next tick can begin before the actuator's
//!   is in: the actuator's next request then waits in its queue ([`Algorithm::finish_early`]).

use cosim::msg::{Header, ToActuator, ToController, ToPlant};
use cosim::{Kind, LinkError, Role};
use tiltsim_formats::events::EventLog;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::Master;

use super::team::{actuator, controller, plant, Team};

/// What a tick's exchanges leave besides the held outputs.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TickIo {
    /// What each receiver got, in [`LinkId`] order.
    pub rx: [f64; 4],
    /// What each sender sent, in [`LinkId`] order.
    pub tx: [f64; 4],
    /// The controller's request (sent when it was due).
    pub to_controller: ToController,
}

/// A tick whose first requests are out: started by [`Algorithm::start`], completed by
/// [`Algorithm::finish`]. The pipelined loop starts tick `k + 1` before it records tick `k`.
pub(crate) enum Pending {
    /// Gauss-Seidel: the first request of the chain (controller when due, else actuator).
    GaussSeidel(GsStarted),
    /// Jacobi: every request.
    Jacobi(Posted),
}

/// A master algorithm.
pub(crate) trait Algorithm {
    /// Sends tick `k`'s first requests: what depends only on the outputs held after `k − 1`.
    fn start(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<Pending, LinkError>;

    /// Completes a started tick: its replies and any requests that depend on them.
    fn finish(&self, team: &mut Team, p: Pending) -> Result<TickIo, LinkError>;

    /// [`Algorithm::finish`], beginning tick `next` before the last reply is taken where the
    /// algorithm can (Jacobi: the requests that do not depend on the actuator's reply); the
    /// begun tick is then started with [`Algorithm::resume`], its faults already injected.
    fn finish_early(
        &self,
        team: &mut Team,
        p: Pending,
        _next: Option<Next<'_>>,
    ) -> Result<(TickIo, Option<Begun>), LinkError> {
        Ok((self.finish(team, p)?, None))
    }

    /// Starts a tick begun by [`Algorithm::finish_early`].
    fn resume(&self, _team: &mut Team, _b: Begun) -> Result<Pending, LinkError> {
        unreachable!("only an algorithm that begins ticks early resumes them")
    }

    /// Steps every participant due at tick `k` through `team`.
    fn tick(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<TickIo, LinkError> {
        let p = self.start(team, k, controller_due)?;
        self.finish(team, p)
    }

    /// The participants' compute time on the tick's critical path (ns): the sum when they run
    /// one after the other, the largest when they run in parallel.
    fn critical_path(&self, compute_ns: [u64; 3]) -> u64;
}

/// The algorithm of `m`.
pub(crate) fn of(m: Master) -> &'static dyn Algorithm {
    match m {
        Master::GaussSeidel => &GaussSeidel,
        Master::Jacobi => &Jacobi,
    }
}

/// The measurement and the bar twist carried to their receivers, and the controller's request.
fn plant_outputs(team: &mut Team, k: u64, io: &mut TickIo) -> ToController {
    let p = team.held.p;
    let meas = team.carry(LinkId::Measurement, k, p.theta_v_meas);
    io.tx[LinkId::Measurement as usize] = p.theta_v_meas;
    io.tx[LinkId::BarTwist as usize] = p.psi;
    io.rx[LinkId::Measurement as usize] = meas;
    io.rx[LinkId::BarTwist as usize] = team.carry(LinkId::BarTwist, k, p.psi);
    ToController {
        header: Header::new(k, Kind::Step),
        t: p.t,
        s: p.s,
        theta_v_meas: meas,
    }
}

/// Gauss-Seidel: one participant after the other.
pub(crate) struct GaussSeidel;

/// A Gauss-Seidel tick with the first request of its chain out.
pub(crate) struct GsStarted {
    due: bool,
    io: TickIo,
    /// The controller's request, posted when due.
    tc: Option<u64>,
    /// The actuator's request, posted when the controller was not due.
    to_a: ToActuator,
    ta: Option<u64>,
}

/// The actuator's request of tick `k` from the controller's held command.
fn actuator_request(team: &mut Team, k: u64, io: &mut TickIo) -> ToActuator {
    io.tx[LinkId::ActuatorCommand as usize] = team.held.c.delta_a_cmd;
    let cmd = team.carry(LinkId::ActuatorCommand, k, team.held.c.delta_a_cmd);
    io.rx[LinkId::ActuatorCommand as usize] = cmd;
    ToActuator {
        header: Header::new(k, Kind::Step),
        delta_a_cmd: cmd,
        psi: io.rx[LinkId::BarTwist as usize],
    }
}

impl Algorithm for GaussSeidel {
    fn start(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<Pending, LinkError> {
        let mut io = TickIo::default();
        let to_c = plant_outputs(team, k, &mut io);
        io.to_controller = to_c;
        let mut st = GsStarted {
            due: controller_due,
            io,
            tc: None,
            to_a: ToActuator::default(),
            ta: None,
        };
        if controller_due {
            st.tc = team.post_step(controller, to_c)?;
        } else {
            st.to_a = actuator_request(team, k, &mut st.io);
            st.ta = team.post_step(actuator, st.to_a)?;
        }
        Ok(Pending::GaussSeidel(st))
    }

    fn finish(&self, team: &mut Team, p: Pending) -> Result<TickIo, LinkError> {
        let Pending::GaussSeidel(mut st) = p else {
            unreachable!("a Gauss-Seidel tick is finished by Gauss-Seidel");
        };
        let k = st.io.to_controller.header.step;
        if st.due {
            team.held.c = team.answer(controller, st.io.to_controller, st.tc)?;
            let to_a = actuator_request(team, k, &mut st.io);
            team.held.a = team.ask(actuator, to_a)?;
        } else {
            team.held.a = team.answer(actuator, st.to_a, st.ta)?;
        }
        let mut io = st.io;
        io.tx[LinkId::BarAngle as usize] = team.held.a.delta_a;
        let bar = team.carry(LinkId::BarAngle, k, team.held.a.delta_a);
        io.rx[LinkId::BarAngle as usize] = bar;
        team.held.p = team.ask(
            plant,
            ToPlant {
                header: Header::new(k, Kind::Step),
                delta_a: bar,
            },
        )?;
        Ok(io)
    }

    fn critical_path(&self, c: [u64; 3]) -> u64 {
        c.iter().sum()
    }
}

/// Jacobi: all requests, then all replies.
pub(crate) struct Jacobi;

/// A Jacobi tick whose requests are out and whose replies are still to come.
pub(crate) struct Posted {
    k: u64,
    due: bool,
    io: TickIo,
    to_a: ToActuator,
    to_p: ToPlant,
    tc: Option<u64>,
    ta: Option<u64>,
    tp: Option<u64>,
}

/// The first half of a Jacobi tick: what depends only on the controller's and the plant's
/// outputs of the tick before (the link carries in their usual order up to the actuator's
/// command, the controller's request sent, the actuator's sent ahead when its transport can).
pub(crate) struct Begun {
    k: u64,
    due: bool,
    io: TickIo,
    to_a: ToActuator,
    tc: Option<u64>,
    /// When the actuator's request went ahead (`None`: still to send).
    ta_ahead: Option<u64>,
    /// Whether the actuator had been replaced when its request went ahead.
    a_replaced: bool,
}

impl Jacobi {
    /// Sends tick `k`'s requests, built from the outputs held after tick `k − 1`.
    pub(crate) fn post(team: &mut Team, k: u64, controller_due: bool) -> Result<Posted, LinkError> {
        let b = Jacobi::begin(team, k, controller_due, false)?;
        Jacobi::complete(team, b)
    }

    /// The first half of tick `k` ([`Begun`]); the actuator's request is sent ahead when
    /// `ahead` and its transport queues it behind the one it is computing.
    fn begin(team: &mut Team, k: u64, due: bool, ahead: bool) -> Result<Begun, LinkError> {
        let mut io = TickIo::default();
        let step = Header::new(k, Kind::Step);
        let to_c = plant_outputs(team, k, &mut io);
        io.to_controller = to_c;
        io.tx[LinkId::ActuatorCommand as usize] = team.held.c.delta_a_cmd;
        let cmd = team.carry(LinkId::ActuatorCommand, k, team.held.c.delta_a_cmd);
        io.rx[LinkId::ActuatorCommand as usize] = cmd;
        let to_a = ToActuator {
            header: step,
            delta_a_cmd: cmd,
            psi: io.rx[LinkId::BarTwist as usize],
        };
        let tc = if due {
            team.post_step(controller, to_c)?
        } else {
            None
        };
        let ta_ahead = if ahead {
            team.post_ahead(actuator, to_a)
        } else {
            None
        };
        Ok(Begun {
            k,
            due,
            io,
            to_a,
            tc,
            ta_ahead,
            a_replaced: team.replaced(Role::Actuator),
        })
    }

    /// The second half of a begun tick, once the actuator's reply of the tick before is in:
    /// the bar angle carried, the actuator's request sent (again, to its stand-in, if it was
    /// replaced since it went ahead), the plant's.
    fn complete(team: &mut Team, b: Begun) -> Result<Posted, LinkError> {
        let Begun {
            k,
            due,
            mut io,
            to_a,
            tc,
            ta_ahead,
            a_replaced,
        } = b;
        io.tx[LinkId::BarAngle as usize] = team.held.a.delta_a;
        let bar = team.carry(LinkId::BarAngle, k, team.held.a.delta_a);
        io.rx[LinkId::BarAngle as usize] = bar;
        let to_p = ToPlant {
            header: Header::new(k, Kind::Step),
            delta_a: bar,
        };
        let ta = match ta_ahead {
            Some(t0) if team.replaced(Role::Actuator) == a_replaced => Some(t0),
            _ => team.post_step(actuator, to_a)?,
        };
        let tp = team.post_step(plant, to_p)?;
        Ok(Posted {
            k,
            due,
            io,
            to_a,
            to_p,
            tc,
            ta,
            tp,
        })
    }

    /// Collects the replies to `p`'s requests into the held outputs: the controller's and the
    /// plant's, then (when `next` is given and nothing acts at its start) the first half of
    /// the next tick with its events kept aside in `next`, then the actuator's.
    pub(crate) fn collect(
        team: &mut Team,
        p: Posted,
        next: Option<Next<'_>>,
    ) -> Result<(TickIo, Option<Begun>), LinkError> {
        debug_assert_eq!(p.to_p.header.step, p.k);
        // Participants on the orchestrator's CPU answer while a heavy one computes on its own;
        // the replies are then taken in this fixed order, whatever the placement.
        team.ps.await_colocated(RoleMap::new([
            p.tp.is_some(),
            p.ta.is_some(),
            p.tc.is_some(),
        ]));
        if p.due {
            team.held.c = team.answer(controller, p.io.to_controller, p.tc)?;
        }
        team.held.p = team.answer(plant, p.to_p, p.tp)?;
        let begun = match next {
            Some(n) if team.may_start_early(n.k) => {
                std::mem::swap(&mut team.events, n.events);
                team.inject_faults(n.k);
                let b = Jacobi::begin(team, n.k, n.due, true);
                std::mem::swap(&mut team.events, n.events);
                Some(b?)
            }
            _ => None,
        };
        team.held.a = team.answer(actuator, p.to_a, p.ta)?;
        Ok((p.io, begun))
    }
}

/// The tick after the one being finished, for an algorithm that may begin it early: its index,
/// whether the controller is due, and the event log its events are kept in until the tick
/// being finished is recorded.
pub(crate) struct Next<'e> {
    pub k: u64,
    pub due: bool,
    pub events: &'e mut EventLog,
}

impl Algorithm for Jacobi {
    fn start(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<Pending, LinkError> {
        Jacobi::post(team, k, controller_due).map(Pending::Jacobi)
    }

    fn finish(&self, team: &mut Team, p: Pending) -> Result<TickIo, LinkError> {
        self.finish_early(team, p, None).map(|(io, _)| io)
    }

    fn finish_early(
        &self,
        team: &mut Team,
        p: Pending,
        next: Option<Next<'_>>,
    ) -> Result<(TickIo, Option<Begun>), LinkError> {
        let Pending::Jacobi(p) = p else {
            unreachable!("a Jacobi tick is finished by Jacobi");
        };
        Jacobi::collect(team, p, next)
    }

    fn resume(&self, team: &mut Team, b: Begun) -> Result<Pending, LinkError> {
        Jacobi::complete(team, b).map(Pending::Jacobi)
    }

    fn critical_path(&self, c: [u64; 3]) -> u64 {
        c.into_iter().max().unwrap_or(0)
    }
}
