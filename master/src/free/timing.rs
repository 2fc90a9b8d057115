//! The wall-clock timing of a free run: the statistics the hub gathers as the steps come in
//! and the report they end in, with what else a free run reports beyond its files.

use std::collections::BTreeMap;

use cosim::Role;
use tiltsim_scenario::roles::RoleMap;

use super::trace::{age, col, inputs_of, StepTrace};
use crate::engine::summary::{AgeDistribution, FreeTiming, RoleFreeTiming, NOT_REAL_TIME_TICKS};
use crate::engine::Status;

/// Per-role timing statistics of a free run (wall clock), in constant memory.
#[derive(Default)]
struct RoleTiming {
    lateness_us: cosim::stats::Timings,
    late_start: u64,
    late_finish: u64,
}

/// What a free run reports beyond its files.
pub struct FreeReport {
    /// How the run ended.
    pub status: Status,
    /// Why it failed or stopped, naming the participant.
    pub error: Option<String>,
    /// Rows in `timeseries.csv` after the one at the start time.
    pub steps_completed: u64,
    /// Wall time from the start instant to the end of the relays (s).
    pub wall_time_s: f64,
    /// The timing the run had.
    pub timing: FreeTiming,
    /// The rows, when kept in memory (`Outputs::rows_in_memory`).
    pub rows: Option<Vec<tiltsim_formats::table::Row>>,
    /// `run.mcap` (`--record`), to be closed with the summary.
    pub recording: Option<super::recording::FreeRecording>,
    /// Files that could not be written (each named), besides the run's own outcome.
    pub write_errors: Vec<String>,
    /// What the session left: exits, process ids, prefix, leftover files, logs, network.
    pub(crate) closed: crate::engine::session::Closed,
    /// The caller's observers, closed, for their part of the summary.
    pub observers: Vec<Box<dyn crate::engine::observe::Observer>>,
}

/// The link a consumer reads from a producer, by its `[links]` name.
fn link_name(consumer: Role, producer: Role) -> &'static str {
    match (consumer, producer) {
        (Role::Actuator, Role::Controller) => "actuator_command",
        (Role::Plant, _) => "bar_angle",
        (Role::Controller, _) => "measurement",
        _ => "bar_twist",
    }
}

/// The timing statistics a free run gathers as its steps come in.
#[derive(Default)]
pub(super) struct Stats {
    roles: RoleMap<RoleTiming>,
    ages: BTreeMap<&'static str, BTreeMap<i64, u64>>,
    dt_ns: u64,
    period: u64,
}

impl Stats {
    /// No step yet, at base tick `dt_ns` and a controller period of `period` ticks.
    pub(super) fn new(dt_ns: u64, period: u64) -> Self {
        Stats {
            dt_ns,
            period,
            ..Stats::default()
        }
    }

    pub(super) fn note(&mut self, t: &StepTrace) {
        let ticks = if t.role == Role::Controller {
            self.period
        } else {
            1
        };
        let rt = &mut self.roles[t.role];
        rt.lateness_us
            .record(t.read_ns.saturating_sub(t.due_ns) as f64 * 1e-3);
        rt.late_start += u64::from(t.late_start(ticks * self.dt_ns));
        rt.late_finish += u64::from(t.late_finish(ticks * self.dt_ns));
        for &p in inputs_of(t.role) {
            if let Some(f) = t.from[col(p)] {
                *self
                    .ages
                    .entry(link_name(t.role, p))
                    .or_default()
                    .entry(age(p, t.step, f))
                    .or_default() += 1;
            }
        }
    }

    pub(super) fn report(&self, dt_s: f64) -> FreeTiming {
        let participants: BTreeMap<String, RoleFreeTiming> = Role::ALL
            .iter()
            .map(|&r| {
                let t = &self.roles[r];
                let p = t.lateness_us.percentiles();
                (
                    r.name().to_string(),
                    RoleFreeTiming {
                        steps: t.lateness_us.len() as u64,
                        start_lateness_us: p,
                        late_starts: t.late_start,
                        late_finishes: t.late_finish,
                    },
                )
            })
            .collect();
        let plant_max_s = self.roles[Role::Plant].lateness_us.percentiles().max * 1e-6;
        let margin_s = NOT_REAL_TIME_TICKS as f64 * dt_s;
        FreeTiming {
            not_real_time: plant_max_s > margin_s,
            not_real_time_margin_s: margin_s,
            plant_max_lateness_s: plant_max_s,
            participants,
            input_age_ticks: self
                .ages
                .iter()
                .map(|(l, h)| (l.to_string(), AgeDistribution::of(h)))
                .collect(),
            cpus: BTreeMap::new(),
            placement: None,
        }
    }
}
