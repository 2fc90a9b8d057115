//! Master algorithms: in which order one tick's requests go out and its replies come back
//! (docs/architecture.md, "Coupling").
//!
//! * [`GaussSeidel`]: controller (when due), actuator, plant in turn, each with the newest
//!   output of the one before. No delay on the forward links.
//! * [`Jacobi`]: every request from the previous tick's outputs first, then every reply. One
//!   tick on every link; the participants compute in parallel.

use cosim::msg::{Header, ToActuator, ToController, ToPlant};
use cosim::{Kind, LinkError};

use super::team::{actuator, controller, plant, Team};
use crate::links::LinkId;
use crate::scenario::Master;

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

/// A master algorithm.
pub(crate) trait Algorithm {
    /// Steps every participant due at tick `k` through `team`.
    fn tick(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<TickIo, LinkError>;

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

impl Algorithm for GaussSeidel {
    fn tick(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<TickIo, LinkError> {
        let mut io = TickIo::default();
        let step = Header::new(k, Kind::Step);
        let to_c = plant_outputs(team, k, &mut io);
        io.to_controller = to_c;
        if controller_due {
            team.held.c = team.ask(controller, to_c)?;
        }
        io.tx[LinkId::ActuatorCommand as usize] = team.held.c.delta_a_cmd;
        let cmd = team.carry(LinkId::ActuatorCommand, k, team.held.c.delta_a_cmd);
        io.rx[LinkId::ActuatorCommand as usize] = cmd;
        let to_a = ToActuator {
            header: step,
            delta_a_cmd: cmd,
            psi: io.rx[LinkId::BarTwist as usize],
        };
        team.held.a = team.ask(actuator, to_a)?;
        io.tx[LinkId::BarAngle as usize] = team.held.a.delta_a;
        let bar = team.carry(LinkId::BarAngle, k, team.held.a.delta_a);
        io.rx[LinkId::BarAngle as usize] = bar;
        team.held.p = team.ask(
            plant,
            ToPlant {
                header: step,
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

impl Jacobi {
    /// Sends tick `k`'s requests, built from the outputs held after tick `k − 1`.
    pub(crate) fn post(team: &mut Team, k: u64, controller_due: bool) -> Result<Posted, LinkError> {
        let mut io = TickIo::default();
        let step = Header::new(k, Kind::Step);
        let to_c = plant_outputs(team, k, &mut io);
        io.to_controller = to_c;
        io.tx[LinkId::ActuatorCommand as usize] = team.held.c.delta_a_cmd;
        io.tx[LinkId::BarAngle as usize] = team.held.a.delta_a;
        let cmd = team.carry(LinkId::ActuatorCommand, k, team.held.c.delta_a_cmd);
        let bar = team.carry(LinkId::BarAngle, k, team.held.a.delta_a);
        io.rx[LinkId::ActuatorCommand as usize] = cmd;
        io.rx[LinkId::BarAngle as usize] = bar;
        let to_a = ToActuator {
            header: step,
            delta_a_cmd: cmd,
            psi: io.rx[LinkId::BarTwist as usize],
        };
        let to_p = ToPlant {
            header: step,
            delta_a: bar,
        };
        let tc = if controller_due {
            team.post_step(controller, to_c)?
        } else {
            None
        };
        let ta = team.post_step(actuator, to_a)?;
        let tp = team.post_step(plant, to_p)?;
        Ok(Posted {
            k,
            due: controller_due,
            io,
            to_a,
            to_p,
            tc,
            ta,
            tp,
        })
    }

    /// Collects the replies to `p`'s requests into the held outputs.
    pub(crate) fn collect(team: &mut Team, p: Posted) -> Result<TickIo, LinkError> {
        debug_assert_eq!(p.to_p.header.step, p.k);
        if p.due {
            team.held.c = team.answer(controller, p.io.to_controller, p.tc)?;
        }
        team.held.a = team.answer(actuator, p.to_a, p.ta)?;
        team.held.p = team.answer(plant, p.to_p, p.tp)?;
        Ok(p.io)
    }
}

impl Algorithm for Jacobi {
    fn tick(&self, team: &mut Team, k: u64, controller_due: bool) -> Result<TickIo, LinkError> {
        let p = Jacobi::post(team, k, controller_due)?;
        Jacobi::collect(team, p)
    }

    fn critical_path(&self, c: [u64; 3]) -> u64 {
        c.into_iter().max().unwrap_or(0)
    }
}
