//! The CPU plan of a Jacobi run over IPC, chosen from the participants' measured compute.
//!
//! An IPC run pinned to a pair of CPUs starts with the orchestrator on one and the participants
//! together on the other (`cosim::ipc::placement`). Under Jacobi the participants compute at
//! the same time, so a heavy one (the event-driven actuator: ~6 µs per tick against ~0.15 µs
//! for the plant) is delayed by the others on its CPU. After a warm-up the planner measures
//! each participant's compute per tick and the orchestrator's own work; when one participant
//! takes at least half of the compute and at least as long as the orchestrator's work, it
//! keeps the last CPU to itself and the others move to the orchestrator's CPU. There the
//! orchestrator lets them answer first ([`Participants::await_colocated`], yielding at once)
//! and then waits for the heavy one, so its recording, the light steps and the heavy step run
//! at the same time. Which participant is heavy is measured, never assumed. Only placement and
//! waiting change: no value computed depends on them, and replies are taken in the same order.

use serde::Serialize;

use cosim::ipc::placement::Placement;
use cosim::Role;
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::{CpuPlanMode, Master, Scenario, Transport};

use super::launch::Participants;

/// What the planner decided, for `summary.json` → `timing.cpu_plan`.
#[derive(Debug, Clone, Serialize)]
pub struct CpuPlanReport {
    /// Ticks measured before deciding.
    pub warmup_ticks: u64,
    /// Compute per tick of each participant over the warm-up (µs), by role: the median compute
    /// of its steps times its steps per tick (a preempted step does not make it heavy).
    pub compute_per_tick_us: std::collections::BTreeMap<&'static str, f64>,
    /// The orchestrator's own work per tick over the warm-up (µs, median): its observers and
    /// the CSV row, which a heavy participant's compute must at least cover.
    pub orchestrator_us: f64,
    /// The participant given a CPU of its own, if one was heavy enough.
    pub own_cpu: Option<&'static str>,
    /// Its CPU.
    pub heavy_cpu: Option<usize>,
    /// The CPU the orchestrator shares with the other participants.
    pub shared_cpu: Option<usize>,
    /// Whether the kernel accepted every placement.
    pub applied: bool,
}

/// Measures, then places (once).
pub(crate) struct CpuPlanner {
    warmup: u64,
    ticks: u64,
    /// Compute of each step of each participant (ns).
    calls: RoleMap<Vec<u64>>,
    /// The orchestrator's own work of each tick (ns): its observers, the CSV row.
    own: Vec<u64>,
    cpus: (usize, usize),
    report: Option<CpuPlanReport>,
}

/// A participant whose compute is at least this share of the total gets a CPU of its own, if
/// it also computes at least as long per tick as the orchestrator's own work (the observers
/// and the CSV row, measured in the same warm-up). The lighter participants then run on the
/// orchestrator's CPU, each step costing it two process switches; that pays only when the
/// heavy one's compute hides the orchestrator's work. A run of light participants
/// (paper-passive: 0.14 µs per tick against 1.3-2 µs of its own) keeps the starting placement.
const HEAVY_SHARE: f64 = 0.5;

impl CpuPlanner {
    /// A planner for `s`, if it runs Jacobi over IPC pinned to a pair of CPUs (`placement`:
    /// the orchestrator's and the participants'). Gauss-Seidel keeps the
    /// starting placement: its participants answer one after the other, so the plan would
    /// only move the light ones' process switches onto the orchestrator's CPU (measured: no
    /// faster, docs/architecture.md).
    pub fn new(s: &Scenario, placement: Option<&Placement>) -> Option<Self> {
        if s.run.transport != Transport::Ipc
            || s.run.master != Master::Jacobi
            || !s.run.pin_cpus
            || s.run.cpu_plan != CpuPlanMode::Measured
            // A participant on another host has no CPU here to place.
            || !s.network.is_local()
        {
            return None;
        }
        let cpus = match placement.map(|p| (p.orchestrator_cpu, p.shared_participant_cpu())) {
            Some((Some(a), Some(b))) => (a, b),
            _ => return None,
        };
        // Long enough to see the controller's updates several times.
        let warmup = (4 * s.controller_period_ticks()).max(200);
        (warmup < s.steps()).then(|| CpuPlanner {
            warmup,
            ticks: 0,
            calls: RoleMap::default(),
            own: Vec::new(),
            cpus,
            report: None,
        })
    }

    /// Adds a tick's compute (ns per role) and the orchestrator's own work in it (ns); at the
    /// end of the warm-up places the participants `ps`.
    pub fn observe(&mut self, compute: &RoleMap<u64>, own_ns: u64, ps: &mut Participants) {
        if self.report.is_some() {
            return;
        }
        self.own.push(own_ns);
        for (r, &v) in compute.iter() {
            // Zero: not stepped this tick (the controller between its updates).
            if v > 0 {
                self.calls[r].push(v);
            }
        }
        self.ticks += 1;
        if self.ticks < self.warmup {
            return;
        }
        let ticks = self.ticks as f64;
        // Medians, so that a preempted step or a page fault does not decide.
        let median_us = |v: &mut Vec<u64>| {
            v.sort_unstable();
            v.get(v.len() / 2).map_or(0.0, |&m| m as f64 * 1e-3)
        };
        let mut per_tick = RoleMap::<f64>::default();
        for r in Role::ALL {
            let n = self.calls[r].len() as f64;
            per_tick[r] = median_us(&mut self.calls[r]) * n / ticks;
        }
        let own_us = median_us(&mut self.own);
        let total: f64 = per_tick.iter().map(|(_, &v)| v).sum();
        let heavy = Role::ALL
            .into_iter()
            .max_by(|a, b| per_tick[*a].total_cmp(&per_tick[*b]))
            .filter(|&r| per_tick[r] >= own_us && per_tick[r] >= HEAVY_SHARE * total);
        let (shared, own) = self.cpus;
        let mut applied = true;
        if let Some(h) = heavy {
            let pids = ps.pids();
            for r in Role::ALL {
                let cpu = if r == h { own } else { shared };
                applied &= cosim::ipc::set_cpus_of(pids[r], &[cpu]);
            }
            if applied {
                ps.set_shares_cpu(RoleMap::new(Role::ALL.map(|r| r != h)));
            }
        }
        self.report = Some(CpuPlanReport {
            warmup_ticks: self.ticks,
            compute_per_tick_us: per_tick.iter().map(|(r, &v)| (r.name(), v)).collect(),
            orchestrator_us: own_us,
            own_cpu: heavy.map(Role::name),
            heavy_cpu: heavy.map(|_| own),
            shared_cpu: heavy.map(|_| shared),
            applied: heavy.is_some() && applied,
        });
    }

    /// The decision, once made.
    pub fn report(&self) -> Option<CpuPlanReport> {
        self.report.clone()
    }
}
