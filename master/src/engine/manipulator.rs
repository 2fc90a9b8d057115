//! Manipulators of the participants: scheduled process faults, and the degraded-mode
//! replacement of a participant that failed. (The manipulator of the values in flight, the
//! link effects, is `crate::links::LinkSet`.)

use std::time::Duration;

use cosim::endpoint::ExitReport;
use cosim::msg::FLAG_CRASH;
use cosim::{Endpoint, InProcess, LinkError, Message, ProcessFault, Role};

use super::launch::{Held, Participants};
use crate::degraded::{FallbackController, NeutralBar};
use crate::events::{EventKind, EventLog};
use crate::faults::{Fallback, FaultAction, Faults, OnFailure, ScheduledFault};
use crate::roles::RoleMap;
use crate::scenario::Scenario;

/// The scenario's scheduled faults, each at its tick.
pub(crate) struct FaultSchedule {
    due: Vec<(u64, ScheduledFault)>,
}

impl FaultSchedule {
    /// Faults of `f` at ticks of `dt` (each before the first tick at or after its time).
    pub fn new(f: &Faults, dt: f64) -> Self {
        FaultSchedule {
            due: f
                .schedule
                .iter()
                .map(|x| (((x.at_s / dt).round().max(0.0)) as u64, x.clone()))
                .collect(),
        }
    }

    /// Applies the faults due at tick `k` to participants not already `lost`: a kill or stall
    /// through the endpoint, a crash as a flag on the next request.
    pub fn apply(
        &self,
        k: u64,
        ps: &mut Participants,
        flags: &mut RoleMap<u32>,
        lost: RoleMap<bool>,
        ev: &mut EventLog,
    ) {
        for (_, f) in self.due.iter().filter(|(at, _)| *at == k) {
            let role = f.participant;
            if lost[role] {
                continue;
            }
            let fault = match f.action {
                FaultAction::Kill => Some(ProcessFault::Kill),
                FaultAction::Stall => Some(ProcessFault::Stall(Duration::from_secs_f64(f.stall_s))),
                FaultAction::Crash => {
                    flags[role] |= FLAG_CRASH;
                    None
                }
            };
            if let Some(fault) = fault {
                match role {
                    Role::Plant => ps.plant.inject(fault),
                    Role::Actuator => ps.actuator.inject(fault),
                    Role::Controller => ps.controller.inject(fault),
                }
            }
            Self::log(k, f, ev);
        }
    }

    /// The event of fault `f` applied at tick `k`.
    fn log(k: u64, f: &ScheduledFault, ev: &mut EventLog) {
        let value = if f.action == FaultAction::Stall {
            f.stall_s
        } else {
            f64::NAN
        };
        ev.push(
            k,
            f.participant.name(),
            EventKind::FaultInjected,
            value,
            f.action.to_string(),
        );
    }

    /// The faults due at tick `k`.
    pub fn due_at(&self, k: u64) -> impl Iterator<Item = &ScheduledFault> {
        self.due
            .iter()
            .filter(move |(at, _)| *at == k)
            .map(|(_, f)| f)
    }

    /// The events [`FaultSchedule::apply`] logs for every fault due at a tick up to `last`,
    /// in tick order, without applying any (a free run's and its replay's `events.csv`).
    pub fn log_until(&self, last: u64, ev: &mut EventLog) {
        let mut due: Vec<&(u64, ScheduledFault)> =
            self.due.iter().filter(|(at, _)| *at <= last).collect();
        due.sort_by_key(|(at, _)| *at);
        for (k, f) in due {
            Self::log(*k, f, ev);
        }
    }
}

/// Replaces a lost actuator or controller by its degraded-mode stand-in (docs/model.md D26).
pub(crate) struct Degrader {
    policy: OnFailure,
    neutral_ramp_s: f64,
    fallback: Fallback,
    dt: f64,
    controller_period: f64,
    lost: RoleMap<Option<ExitReport>>,
    degraded: bool,
}

fn shut<I: Message, O: Message>(mut ep: Box<dyn Endpoint<I, O>>) -> ExitReport {
    ep.shutdown()
}

impl Degrader {
    /// The policy of scenario `s`.
    pub fn new(s: &Scenario) -> Self {
        Degrader {
            policy: s.faults.on_failure,
            neutral_ramp_s: s.faults.neutral_ramp_s,
            fallback: s.faults.controller_fallback,
            dt: s.run.dt_s,
            controller_period: s.controller.period_s,
            lost: RoleMap::default(),
            degraded: false,
        }
    }

    /// Whether a participant was replaced.
    pub fn degraded(&self) -> bool {
        self.degraded
    }

    /// Which roles were replaced.
    pub fn lost_roles(&self) -> RoleMap<bool> {
        RoleMap::new(Role::ALL.map(|r| self.lost[r].is_some()))
    }

    /// The exit reports of the replaced participants.
    pub fn take_lost(&mut self) -> RoleMap<Option<ExitReport>> {
        std::mem::take(&mut self.lost)
    }

    /// Replaces the participant that failed with `e` when the scenario says so (never the
    /// plant, never twice); otherwise returns `e`.
    pub fn replace(
        &mut self,
        ps: &mut Participants,
        held: &Held,
        k: u64,
        e: LinkError,
        ev: &mut EventLog,
    ) -> Result<(), LinkError> {
        let role = e.role();
        if self.policy != OnFailure::Degrade || role == Role::Plant || self.lost[role].is_some() {
            return Err(e);
        }
        let detail = if role == Role::Actuator {
            let bar = NeutralBar::new(held.a.delta_a, self.neutral_ramp_s, self.dt);
            let old = std::mem::replace(&mut ps.actuator, Box::new(InProcess::new(bar)));
            self.lost[role] = Some(shut(old));
            format!("bar ramps to neutral over {} s", self.neutral_ramp_s)
        } else {
            let ramp = match self.fallback {
                Fallback::Neutral => Some(self.neutral_ramp_s),
                Fallback::Hold => None,
            };
            let fb = FallbackController::new(held.c.delta_a_cmd, ramp, self.controller_period);
            let old = std::mem::replace(&mut ps.controller, Box::new(InProcess::new(fb)));
            self.lost[role] = Some(shut(old));
            match ramp {
                Some(r) => format!("bar command ramps to neutral over {r} s"),
                None => "last bar command held".into(),
            }
        };
        ev.push(
            k,
            role.name(),
            EventKind::ParticipantLost,
            f64::NAN,
            e.cause(),
        );
        ev.push(k, role.name(), EventKind::Degraded, f64::NAN, detail);
        tracing::warn!("{e}; continuing degraded");
        self.degraded = true;
        Ok(())
    }
}
