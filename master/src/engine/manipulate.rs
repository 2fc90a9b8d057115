//! The other open seam of the lock-step engine: a [`Manipulator`] acts on the run, on the
//! participants and on the values in flight between them. A run holds an ordered list: the
//! scenario's own first (the link effects `links`, the scheduled process faults `faults`, the
//! degraded-mode stand-ins `degraded`), then the caller's, added to a [`Run`](super::Run) with
//! `add_manipulator`.
//!
//! Lifecycle, each on the thread that runs the lock-step:
//! 1. [`Manipulator::tick_commencing`] before each tick's first request, in list order: may
//!    inject a process fault or flag a participant's next request ([`Control`]);
//! 2. [`Manipulator::carry`] for every value sent over a link, in list order, each given what
//!    the one before made of it: returns what the receiver gets;
//! 3. [`Manipulator::participant_failed`] when a participant's exchange failed, in list order
//!    until one replaces it with a stand-in; when none does, the run fails on the error.
//!
//! A manipulator logs what it does to `events.csv` through the event log it is handed. The
//! run stays deterministic as long as the manipulator is: same scenario and seed, same bytes.

use cosim::endpoint::ExitReport;
use cosim::msg::{FromActuator, FromController, FromPlant, ToActuator, ToController};
use cosim::{Endpoint, InProcess, LinkError, Participant, ProcessFault, Role};
use tiltsim_formats::events::EventLog;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::roles::RoleMap;

use super::launch::{Held, Participants};

/// Something that acts on a run (see the module's lifecycle). Every method has a default that
/// does nothing, so a manipulator implements only what it acts on.
pub trait Manipulator: Send {
    /// Its name, for messages.
    fn name(&self) -> &str;

    /// Before tick `k`'s first request.
    fn tick_commencing(&mut self, _k: u64, _ctl: &mut Control<'_>) {}

    /// Value `v` sent at tick `k` (time `t`, s) over `link`: what the receiver gets.
    fn carry(&mut self, _link: LinkId, _k: u64, _t: f64, v: f64, _events: &mut EventLog) -> f64 {
        v
    }

    /// Whether tick `k` may begin before tick `k − 1`'s last reply is taken: `tick_commencing(k)`
    /// does nothing, and `carry` of tick `k`'s values does not depend on that reply or on a
    /// failure it may bring. The engine then overlaps the two ticks (under Jacobi over IPC, the
    /// actuator's next request waits in its queue while it computes); the values are the same
    /// either way. Default `false`: the engine takes every reply of `k − 1` first.
    fn lets_tick_start_early(&self, _k: u64) -> bool {
        false
    }

    /// Participant `e.role()` failed at tick `k`: replace it through `ctl` and return `Ok`, or
    /// hand the error on.
    fn participant_failed(
        &mut self,
        _k: u64,
        e: LinkError,
        _ctl: &mut Control<'_>,
    ) -> Result<(), LinkError> {
        Err(e)
    }
}

/// What a manipulator may act on at a tick's start or on a failure: the participants, their
/// next requests' flags, the event log.
pub struct Control<'a> {
    pub(crate) ps: &'a mut Participants,
    pub(crate) held: &'a Held,
    pub(crate) flags: &'a mut RoleMap<u32>,
    pub(crate) lost: &'a mut RoleMap<Option<ExitReport>>,
    /// The run's event log (`events.csv`).
    pub events: &'a mut EventLog,
}

impl Control<'_> {
    /// Stops participant `role`'s process (`Kill`) or stops it for a while (`Stall`); a
    /// participant in this process, or one already replaced, is not affected.
    pub fn inject(&mut self, role: Role, fault: ProcessFault) {
        match role {
            Role::Plant => self.ps.plant.inject(fault),
            Role::Actuator => self.ps.actuator.inject(fault),
            Role::Controller => self.ps.controller.inject(fault),
        }
    }

    /// Sets `flags` (`cosim::msg::FLAG_*`) on participant `role`'s next request.
    pub fn flag_next_request(&mut self, role: Role, flags: u32) {
        self.flags[role] |= flags;
    }

    /// Whether participant `role` was replaced by a stand-in.
    pub fn replaced(&self, role: Role) -> bool {
        self.lost[role].is_some()
    }

    /// The latest outputs of the plant, actuator and controller.
    pub fn latest(&self) -> (&FromPlant, &FromActuator, &FromController) {
        (&self.held.p, &self.held.a, &self.held.c)
    }

    /// Replaces the actuator with `stand_in` (run in this process), shutting the one it
    /// replaces down; the run is reported degraded.
    pub fn replace_actuator<P>(&mut self, stand_in: P)
    where
        P: Participant<Input = ToActuator, Output = FromActuator> + 'static,
    {
        let old = std::mem::replace(&mut self.ps.actuator, Box::new(InProcess::new(stand_in)));
        self.lost[Role::Actuator] = Some(shut(old));
    }

    /// Replaces the controller with `stand_in` (run in this process), shutting the one it
    /// replaces down; the run is reported degraded.
    pub fn replace_controller<P>(&mut self, stand_in: P)
    where
        P: Participant<Input = ToController, Output = FromController> + 'static,
    {
        let old = std::mem::replace(&mut self.ps.controller, Box::new(InProcess::new(stand_in)));
        self.lost[Role::Controller] = Some(shut(old));
    }
}

fn shut<I: cosim::Message, O: cosim::Message>(mut ep: Box<dyn Endpoint<I, O>>) -> ExitReport {
    ep.shutdown()
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use super::*;
    use crate::engine::outputs::Rows;
    use crate::engine::{Run, RunOptions, Status};
    use tiltsim_formats::events::EventKind;
    use tiltsim_scenario::scenario::{Scenario, Transport};

    /// Adds `offset` to every value on the bar-twist link and notes what it was handed.
    struct Offset {
        offset: f64,
        seen: Arc<Mutex<Vec<(u64, f64)>>>,
    }

    impl Manipulator for Offset {
        fn name(&self) -> &str {
            "offset"
        }
        fn tick_commencing(&mut self, k: u64, ctl: &mut Control<'_>) {
            if k == 0 {
                let detail = format!("bar twist offset by {}", self.offset);
                ctl.events
                    .push(0, "bar_twist", EventKind::Manipulated, self.offset, detail);
            }
        }
        fn carry(&mut self, link: LinkId, k: u64, _t: f64, v: f64, _ev: &mut EventLog) -> f64 {
            if link != LinkId::BarTwist {
                return v;
            }
            self.seen.lock().unwrap().push((k, v));
            v + self.offset
        }
    }

    fn run_with(
        bias: f64,
        offsets: &[f64],
    ) -> (Vec<tiltsim_formats::table::Row>, Vec<Vec<(u64, f64)>>) {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut s = Scenario::load(&root.join("scenarios/paper-passive.toml")).unwrap();
        s.run.transport = Transport::InProcess;
        s.run.duration_s = Some(0.3);
        s.links.bar_twist.bias = bias;
        let dir = std::env::temp_dir().join(format!(
            "tiltsim-manipulate-{}-{}",
            offsets.len(),
            std::process::id()
        ));
        let opts = RunOptions::new(dir.clone(), "tiltsim".into());
        let (rows, kept) = Rows::in_memory(s.run.dt_s, 0);
        let mut run = Run::new(&s, "paper-passive.toml", &opts).add_observer(Box::new(rows));
        let mut seen = Vec::new();
        for &offset in offsets {
            let log = Arc::new(Mutex::new(Vec::new()));
            seen.push(log.clone());
            run = run.add_manipulator(Box::new(Offset { offset, seen: log }));
        }
        let ran = run.simulate().unwrap();
        assert_eq!(ran.summary.status, Status::Completed);
        let manipulated = ran
            .events
            .events
            .iter()
            .filter(|e| e.kind == EventKind::Manipulated)
            .count();
        assert_eq!(manipulated, offsets.len());
        let _ = std::fs::remove_dir_all(&dir);
        let seen = seen.iter().map(|l| l.lock().unwrap().clone()).collect();
        (kept.take().unwrap(), seen)
    }

    /// The caller's manipulators act after the scenario's link effects and after each other,
    /// in the order added: what the actuator got at tick k is ψ sent at tick k (row k's ψ)
    /// plus the scenario's bias, then each offset in turn, computed here the same way.
    #[test]
    fn manipulators_act_in_order_after_the_scenarios_own_link_effects() {
        let (bias, a, b) = (0.25, 1.0, -0.125);
        let (rows, seen) = run_with(bias, &[a, b]);
        assert_eq!(rows.len(), 301);
        for k in 0..300 {
            let sent = rows[k].psi;
            let expected = ((sent + bias) + a) + b;
            assert_eq!(
                rows[k + 1].rx_bar_twist.to_bits(),
                expected.to_bits(),
                "tick {k}"
            );
            assert_eq!(seen[0][k], (k as u64, sent + bias));
            assert_eq!(seen[1][k], (k as u64, sent + bias + a));
        }
        // Without them, the same run's actuator gets ψ with the bias only.
        let (plain, _) = run_with(bias, &[]);
        assert_eq!(
            plain[7].rx_bar_twist.to_bits(),
            (plain[6].psi + bias).to_bits()
        );
    }
}
