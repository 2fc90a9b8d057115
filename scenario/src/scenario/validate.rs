//! Every rule of a scenario, with the field's dotted path: the name, the timeline, each
//! section's ranges, the FMUs against their descriptions.

use tiltsim_protocol::settings::{Checker, FieldError};
use tiltsim_protocol::Role;

use super::*;

impl Scenario {
    /// The name becomes the default output directory `out/<name>`: one path component, no
    /// way out of `out/` (`--out` is the only way to choose where results go).
    pub(super) fn validate_name(&self) -> Checker {
        let mut c = Checker::new("");
        let n = &self.name;
        let ok = n.chars().count() <= 100
            && n != "."
            && n != ".."
            && !n.contains(['/', '\\', '\0'])
            && !n.chars().any(char::is_control);
        let shown: String = n.chars().take(100).collect();
        c.require(
            ok,
            "name",
            format!("{shown:?}"),
            "at most 100 characters, not `.` or `..`, without `/`, `\\` or control characters",
        );
        c
    }

    /// What can never take effect: a run shorter than one step, faults scheduled after the
    /// end of the run, a stall length on a fault that is not a stall, two faults of the same
    /// participant at the same tick. Each error names a field the file holds: a run without
    /// `run.duration_s` lasts the track's length at its speed, and a track too short for one
    /// step is named as the track; a duration from fields that are out of range themselves
    /// is not checked again (their own errors say what to change).
    pub(super) fn validate_timeline(&self) -> Checker {
        let mut c = Checker::new("");
        let (dt, end) = (self.run.dt_s, self.duration());
        // Shown to the microsecond, as a person would write it.
        let shown = (end * 1e6).round() / 1e6;
        let dt_ok = dt.is_finite() && dt > 0.0;
        let end_ok = match self.run.duration_s {
            Some(d) => d.is_finite() && d > 0.0,
            None => self.track.validate("track").errors.is_empty(),
        };
        if dt_ok && end_ok {
            let one_step = self.steps() >= 1;
            match self.run.duration_s {
                Some(d) => c.require(
                    one_step,
                    "run.duration_s",
                    d,
                    &format!("at least one step of run.dt_s = {dt} s"),
                ),
                None => c.require(
                    one_step,
                    "track",
                    format!(
                        "{} m at {} km/h, {shown} s",
                        self.track.length(),
                        self.track.speed_kmh
                    ),
                    &format!(
                        "a track that lasts at least one step of run.dt_s = {dt} s (its length \
                         is straight_before_m + 2 transition_m + curve_m + straight_after_m), \
                         or a run.duration_s"
                    ),
                ),
            }
        }
        let end_of_run = match self.run.duration_s {
            Some(_) => format!("run.duration_s = {end} s"),
            None => format!("{shown} s (the track's length at its speed)"),
        };
        let mut seen = Vec::new();
        for (i, f) in self.faults.schedule.iter().enumerate() {
            let field = format!("faults.schedule[{i}]");
            c.require(
                !end_ok || f.at_s < end,
                &format!("{field}.at_s"),
                f.at_s,
                &format!("a time before the end of the run, {end_of_run}"),
            );
            c.require(
                f.action == crate::faults::FaultAction::Stall || f.stall_s == 0.0,
                &format!("{field}.stall_s"),
                f.stall_s,
                "only with action = \"stall\"",
            );
            let tick = (f.at_s / dt).round() as i64;
            c.require(
                !seen.contains(&(f.participant, tick)),
                &format!("{field}.at_s"),
                f.at_s,
                "a tick with no other fault of the same participant",
            );
            seen.push((f.participant, tick));
        }
        c
    }

    /// Every rule, with the field's dotted path.
    pub fn validate(&self) -> Vec<FieldError> {
        let mut c = Checker::new("run");
        let r = &self.run;
        c.range("dt_s", r.dt_s, 1e-5, 0.01, "s");
        if let Some(d) = r.duration_s {
            c.positive("duration_s", d, 3600.0, "s");
        }
        c.require(
            (1..=60_000).contains(&r.deadline_ms),
            "deadline_ms",
            r.deadline_ms,
            "an integer in [1, 60000] ms",
        );
        c.require(
            r.hang_ceiling_ms >= r.deadline_ms && r.hang_ceiling_ms <= 3_600_000,
            "hang_ceiling_ms",
            r.hang_ceiling_ms,
            &format!(
                "an integer in [run.deadline_ms = {}, 3600000] ms",
                r.deadline_ms
            ),
        );
        c.require(
            (100..=120_000).contains(&r.startup_ms),
            "startup_ms",
            r.startup_ms,
            "an integer in [100, 120000] ms",
        );
        self.validate_execution(&mut c);
        let mut all = c;
        all.merge(self.validate_name());
        all.merge(self.validate_timeline());
        all.merge(self.vehicle.validate("vehicle"));
        all.merge(self.track.validate("track"));
        all.merge(self.sensor.validate("sensor"));
        all.merge(self.actuator.validate("actuator"));
        all.merge(self.controller.validate("controller"));
        all.merge(self.comfort.validate("comfort"));
        all.merge(self.links.validate("links"));
        all.merge(self.faults.validate("faults"));
        all.merge(self.network.validate("network"));
        let mut c = Checker::new("network");
        for &r in &self.network.remote {
            c.require(
                self.participants.get(r).is_none(),
                "remote",
                r,
                "roles played by tiltsim's own models: an FMU ([participants.<role>]) runs on the orchestrator's host",
            );
        }
        all.merge(c);
        if let Some(v) = &self.design_vehicle {
            all.merge(v.validate("design_vehicle"));
        }
        all.merge(self.validate_vehicle_model());
        all.errors.extend(self.validate_fmus());
        let mut c = Checker::new("controller");
        let ratio = self.controller.period_s / r.dt_s;
        c.require(
            (ratio - ratio.round()).abs() < 1e-9 && ratio.round() >= 1.0,
            "period_s",
            self.controller.period_s,
            &format!("a whole multiple of run.dt_s = {} s", r.dt_s),
        );
        all.merge(c);
        if all.errors.is_empty() {
            // The LQG and MPC designs solve Riccati equations and set up the QP: a setting
            // for which they have no solution is a scenario error, reported before any start.
            let init = self.controller_init();
            if let Err(e) = controller_proc::Controller::new(&init) {
                // The design's own settings are what to change: the LQG's and MPC's weights
                // and Kalman values, the PI's gains.
                let mut c = Checker::new("controller");
                let section = match self.controller.mode {
                    controller_proc::Mode::Lqg => "lqg, controller.kalman",
                    controller_proc::Mode::Mpc => "mpc, controller.kalman",
                    _ => "mode",
                };
                c.require(
                    false,
                    section,
                    format!("{}: design failed: {e}", self.controller.mode.label()),
                    "settings for which the controller design exists",
                );
                all.merge(c);
            }
        }
        all.errors
    }

    /// The rules of `run.execution` and `run.controller_busy_wait_s`.
    fn validate_execution(&self, c: &mut Checker) {
        let r = &self.run;
        c.range(
            "controller_busy_wait_s",
            r.controller_busy_wait_s,
            0.0,
            1.0,
            "s",
        );
        if r.execution == Execution::LockStep {
            c.require(
                r.controller_busy_wait_s == 0.0,
                "controller_busy_wait_s",
                r.controller_busy_wait_s,
                "0 unless run.execution = \"free\" (a lock-step run's values do not depend on compute time)",
            );
            return;
        }
        c.require(
            r.transport == Transport::Ipc,
            "execution",
            "\"free\"",
            "\"free\" only with run.transport = \"ipc\": in one process the participants have no clocks of their own",
        );
        c.require(
            self.faults.on_failure == crate::faults::OnFailure::Abort,
            "execution",
            "\"free\"",
            "\"lock-step\" when faults.on_failure = \"degrade\" (a free run ends, naming the participant, when one fails; stand-ins replace participants in lock-step only)",
        );
    }

    /// The rules of `vehicle.model`: the whole car is stepped by tiltsim's own plant (an FMU
    /// plant is the user's own model, with no wheelsets to assess); the controller is designed
    /// on the half vehicle.
    fn validate_vehicle_model(&self) -> Checker {
        let mut c = Checker::new("vehicle");
        if self.vehicle.model == vehicle_model::VehicleModel::Full {
            c.require(
                self.participants.get(Role::Plant).is_none(),
                "model",
                "\"full\"",
                "\"half\" when the plant is an FMU ([participants.plant]): an FMU plant is your own model, which has no wheelsets for the whole car's running safety; remove [participants.plant] to run the whole car on tiltsim's own plant",
            );
        }
        if let Some(v) = &self.design_vehicle {
            let mut d = Checker::new("design_vehicle");
            d.require(
                v.model.is_half(),
                "model",
                format!("\"{}\"", v.model.name()),
                "\"half\": the controllers are designed on the half vehicle (vehicle.model chooses what the plant steps)",
            );
            c.merge(d);
        }
        c
    }

    /// Every FMU checked against its description: the file, the library for this platform,
    /// the mapping's names, causalities and types, the parameters and the step size.
    pub(super) fn validate_fmus(&self) -> Vec<FieldError> {
        let mut errors = Vec::new();
        for role in Role::ALL {
            let Some(init) = self.fmu_init(role) else {
                continue;
            };
            if let Err(e) = tiltsim_fmi::import::check(&init) {
                errors.push(FieldError {
                    field: format!("participants.{role}.{}", e.field),
                    value: e.value,
                    allowed: e.allowed,
                });
            }
        }
        errors
    }
}
