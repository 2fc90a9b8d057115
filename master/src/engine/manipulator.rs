//! The scenario's own manipulators (`super::manipulate`): the link effects on the values in
//! flight (`crate::links::LinkSet`), the scheduled process faults, and the degraded-mode
//! replacement of a participant that failed.

use std::time::Duration;

use cosim::msg::FLAG_CRASH;
use cosim::{LinkError, ProcessFault, Role};
use tiltsim_formats::events::{EventKind, EventLog};
use tiltsim_scenario::faults::{Fallback, FaultAction, Faults, OnFailure, ScheduledFault};
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::Scenario;

use super::manipulate::{Control, Manipulator};
use crate::degraded::{FallbackController, NeutralBar};
use crate::links::LinkSet;

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

/// The scheduled faults, each applied before its tick to a participant not already replaced:
/// a kill or stall through the endpoint, a crash as a flag on the next request.
impl Manipulator for FaultSchedule {
    fn name(&self) -> &str {
        "faults"
    }
    fn lets_tick_start_early(&self, k: u64) -> bool {
        !self.due.iter().any(|(at, _)| *at == k)
    }
    fn tick_commencing(&mut self, k: u64, ctl: &mut Control<'_>) {
        for (_, f) in self.due.iter().filter(|(at, _)| *at == k) {
            let role = f.participant;
            if ctl.replaced(role) {
                continue;
            }
            match f.action {
                FaultAction::Kill => ctl.inject(role, ProcessFault::Kill),
                FaultAction::Stall => ctl.inject(
                    role,
                    ProcessFault::Stall(Duration::from_secs_f64(f.stall_s)),
                ),
                FaultAction::Crash => ctl.flag_next_request(role, FLAG_CRASH),
            }
            Self::log(k, f, ctl.events);
        }
    }
}

/// The link effects of the scenario (`crate::links`) on the values in flight.
impl Manipulator for LinkSet {
    fn name(&self) -> &str {
        "links"
    }
    /// Each link draws from a random stream of its own, in the order of its own values.
    fn lets_tick_start_early(&self, _k: u64) -> bool {
        true
    }
    fn carry(&mut self, link: LinkId, k: u64, t: f64, v: f64, events: &mut EventLog) -> f64 {
        LinkSet::carry(self, link, k, t, v, events)
    }
}

/// Replaces a lost actuator or controller by its degraded-mode stand-in (docs/model.md D26).
pub(crate) struct Degrader {
    policy: OnFailure,
    neutral_ramp_s: f64,
    fallback: Fallback,
    dt: f64,
    controller_period: f64,
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
        }
    }
}

impl Manipulator for Degrader {
    fn name(&self) -> &str {
        "degraded"
    }

    /// Nothing at a tick's start; a stand-in is built from the outputs held at the failure,
    /// which the tick begun early does not change.
    fn lets_tick_start_early(&self, _k: u64) -> bool {
        true
    }

    /// Replaces the participant that failed with `e` when the scenario says so (never the
    /// plant, never twice); otherwise hands `e` on.
    fn participant_failed(
        &mut self,
        k: u64,
        e: LinkError,
        ctl: &mut Control<'_>,
    ) -> Result<(), LinkError> {
        let role = e.role();
        if self.policy != OnFailure::Degrade || role == Role::Plant || ctl.replaced(role) {
            return Err(e);
        }
        let (_, a, c) = ctl.latest();
        let detail = if role == Role::Actuator {
            let bar = NeutralBar::new(a.delta_a, self.neutral_ramp_s, self.dt);
            ctl.replace_actuator(bar);
            format!("bar ramps to neutral over {} s", self.neutral_ramp_s)
        } else {
            let ramp = match self.fallback {
                Fallback::Neutral => Some(self.neutral_ramp_s),
                Fallback::Hold => None,
            };
            let fb = FallbackController::new(c.delta_a_cmd, ramp, self.controller_period);
            ctl.replace_controller(fb);
            match ramp {
                Some(r) => format!("bar command ramps to neutral over {r} s"),
                None => "last bar command held".into(),
            }
        };
        ctl.events.push(
            k,
            role.name(),
            EventKind::ParticipantLost,
            f64::NAN,
            e.cause(),
        );
        ctl.events
            .push(k, role.name(), EventKind::Degraded, f64::NAN, detail);
        tracing::warn!("{e}; continuing degraded");
        Ok(())
    }
}
