//! `--record` of a free run: `run.mcap` written after the run from the store and the trace,
//! with the lock-step recording's channels (`/<role>/in`, `/<role>/out`, `/links/<name>`,
//! `/events`, `/summary`, `/perf`) and the timing trace as `/timing/<role>`.
//!
//! Steps and log times as in lock-step: what a step at tick k read, the controller's answer,
//! the links and the outputs are step k + 1 at t_(k+1), the row of `timeseries.csv` that holds
//! them; a step's timing is step k at t_k, the row of `timing.csv`; the
//! publish times are the wall clock of the trace (CLOCK_MONOTONIC ns: the read instant for an
//! input, the publish instant for an output and for a step's timing). The links' `sent` is
//! the producer's output as published and `received` what the link delivered, for the sample
//! each consumer step read.

use std::path::{Path, PathBuf};

use cosim::Role;
use tiltsim_formats::events::EventLog;
use tiltsim_scenario::links::LinkId;

use super::compose::Store;
use super::trace::{age, col, inputs_of, StepTrace};
use crate::engine::mcap::{
    actuator_out, controller_out, inbox, link_channel, plant_out, timing_channel, EventMessage,
    McapRecorder,
};

/// A free run's recording, complete but for the summary, which the caller closes it with.
pub struct FreeRecording {
    rec: McapRecorder,
    end: u64,
}

impl FreeRecording {
    /// Writes the summary's repeatable part `det` and its wall-clock part `perf` and closes
    /// the file; returns its path.
    pub fn finish(
        self,
        det: &serde_json::Value,
        perf: &serde_json::Value,
    ) -> std::io::Result<PathBuf> {
        self.rec.close(det, perf, self.end)
    }
}

/// The steps of each role by its step index ([`Store::index`]).
struct Steps<'a> {
    by_role: [Vec<Option<StepTrace>>; 3],
    store: &'a Store,
}

impl<'a> Steps<'a> {
    fn new(trace: &[StepTrace], store: &'a Store) -> Self {
        let mut by_role: [Vec<Option<StepTrace>>; 3] = Default::default();
        for t in trace {
            let i = store.index(t.role, t.step);
            let v = &mut by_role[col(t.role)];
            if v.len() <= i {
                v.resize(i + 1, None);
            }
        }
        for t in trace {
            if let Some(slot) = by_role[col(t.role)].get_mut(store.index(t.role, t.step)) {
                *slot = Some(*t);
            }
        }
        Steps { by_role, store }
    }

    /// `role`'s step at tick `k`, if it has one there and it was recorded.
    fn at(&self, role: Role, k: u64) -> Option<&StepTrace> {
        if role == Role::Controller && !k.is_multiple_of(self.store.period) {
            return None;
        }
        self.by_role[col(role)]
            .get(self.store.index(role, k))?
            .as_ref()
    }
}

/// The values of a step's `/timing/<role>` message.
fn timing_values(t: &StepTrace, period_ticks: u64, dt_ns: u64) -> Vec<f64> {
    let mut v = vec![f64::NAN; 12];
    for &p in inputs_of(t.role) {
        if let Some(f) = t.from[col(p)] {
            v[col(p)] = f as f64;
            v[3 + col(p)] = age(p, t.step, f) as f64;
        }
    }
    let ticks = if t.role == Role::Controller {
        period_ticks
    } else {
        1
    };
    v[6] = t.due_ns as f64;
    v[7] = t.read_ns as f64;
    v[8] = t.compute_end_ns as f64;
    v[9] = t.publish_ns as f64;
    v[10] = f64::from(u8::from(t.late_start(ticks * dt_ns)));
    v[11] = f64::from(u8::from(t.late_finish(ticks * dt_ns)));
    v
}

/// Writes `path` for the first `rows` ticks of a free run whose outputs are in `store`, whose
/// steps are `trace` and whose start instant is `start_ns`; `events` are the run's events.
pub fn record(
    path: &Path,
    dt_s: f64,
    store: &Store,
    trace: &[StepTrace],
    rows: u64,
    start_ns: u64,
    events: &EventLog,
) -> std::io::Result<FreeRecording> {
    let mut rec = McapRecorder::create_free(path, dt_s)?;
    rec.queue_events(events.events.iter().map(EventMessage::from));
    let dt_ns = rec.dt_ns();
    let period = store.period;
    let steps = Steps::new(trace, store);
    let wall = |ns: u64| start_ns + ns;
    if let (Some(p), Some(a)) = (store.plant(-1), store.actuator(-1)) {
        rec.at_start(p, a)?;
    }
    for k in 0..rows {
        // The step's timing at t_k (the row of `timing.csv`), the events of tick k, then
        // what each consumer stepping at k read, the links' samples it read and the outputs
        // as step k + 1 at t_(k+1): the row of `timeseries.csv` that holds them.
        let log = k * dt_ns;
        for role in Role::ALL {
            if let Some(t) = steps.at(role, k) {
                let v = timing_values(t, period, dt_ns);
                rec.put_values(timing_channel(role), k, log, wall(t.publish_ns), &v)?;
            }
        }
        rec.events_until(k)?;
        let (row, log) = (k + 1, log + dt_ns);
        if let Some(t) = steps.at(Role::Controller, k) {
            let qp = t.from[col(Role::Plant)].unwrap_or(-1);
            if let (Some(i), Some(p)) = (store.controller_input(qp), store.plant(qp)) {
                let c = inbox(Role::Controller);
                let v = [i.t, i.s, i.theta_v_meas];
                rec.put_values(c, row, log, wall(t.read_ns), &v)?;
                if let Some(o) = store.controller(k as i64) {
                    rec.put_values(c + 1, row, log, wall(t.publish_ns), &controller_out(o))?;
                }
                let sent = [p.theta_v_meas, i.theta_v_meas];
                rec.put_values(link_channel(LinkId::Measurement), row, log, log, &sent)?;
            }
        }
        if let Some(t) = steps.at(Role::Actuator, k) {
            let qc = t.from[col(Role::Controller)].unwrap_or(-1);
            let qp = t.from[col(Role::Plant)].unwrap_or(-1);
            if let (Some(i), Some(c), Some(p)) = (
                store.actuator_input(qc, qp),
                store.controller(qc),
                store.plant(qp),
            ) {
                let a = inbox(Role::Actuator);
                rec.put_values(a, row, log, wall(t.read_ns), &[i.delta_a_cmd, i.psi])?;
                let cmd = [c.delta_a_cmd, i.delta_a_cmd];
                rec.put_values(link_channel(LinkId::ActuatorCommand), row, log, log, &cmd)?;
                let twist = [p.psi, i.psi];
                rec.put_values(link_channel(LinkId::BarTwist), row, log, log, &twist)?;
            }
        }
        if let Some(t) = steps.at(Role::Plant, k) {
            let qa = t.from[col(Role::Actuator)].unwrap_or(-1);
            if let (Some(i), Some(a)) = (store.plant_input(qa), store.actuator(qa)) {
                rec.put_values(inbox(Role::Plant), row, log, wall(t.read_ns), &[i.delta_a])?;
                let bar = [a.delta_a, i.delta_a];
                rec.put_values(link_channel(LinkId::BarAngle), row, log, log, &bar)?;
            }
        }
        if let (Some(t), Some(o)) = (steps.at(Role::Actuator, k), store.actuator(k as i64)) {
            let a = inbox(Role::Actuator) + 1;
            rec.put_values(a, row, log, wall(t.publish_ns), &actuator_out(o))?;
        }
        if let (Some(t), Some(o)) = (steps.at(Role::Plant, k), store.plant(k as i64)) {
            let p = inbox(Role::Plant) + 1;
            rec.put_values(p, row, log, wall(t.publish_ns), &plant_out(o))?;
        }
    }
    Ok(FreeRecording {
        rec,
        end: rows * dt_ns,
    })
}
