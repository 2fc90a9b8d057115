//! The CPU plan of a Jacobi run over IPC, chosen from the participants' measured compute.
//!
//! Every IPC run starts with the orchestrator on the first allowed CPU and the participants
//! together on the last (`cosim::ipc::cpu_plan`). Under Jacobi the participants compute at
//! the same time, so a heavy one (the actuator's 1 µs electrics: ~30 µs per tick against
//! ~0.2 µs for the plant) is delayed by the others on its CPU. After a warm-up the planner
//! measures each participant's compute per tick; when one takes at least half of the total and
//! at least 10 µs per tick it keeps the last CPU to itself and the others move to the
//! orchestrator's CPU, where they run while the orchestrator waits for the heavy one. Which participant is heavy is measured,
//! never assumed. Only placement changes: no value computed depends on it.

use serde::Serialize;

use cosim::Role;

use crate::roles::RoleMap;
use crate::scenario::{CpuPlanMode, Master, Scenario, Transport};

/// What the planner decided, for `summary.json` → `timing.cpu_plan`.
#[derive(Debug, Clone, Serialize)]
pub struct CpuPlanReport {
    /// Ticks measured before deciding.
    pub warmup_ticks: u64,
    /// Compute per tick of each participant over the warm-up (µs), by role: the median compute
    /// of its steps times its steps per tick (a preempted step does not make it heavy).
    pub compute_per_tick_us: std::collections::BTreeMap<&'static str, f64>,
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
    cpus: (usize, usize),
    report: Option<CpuPlanReport>,
}

/// A participant whose compute is at least this share of the total gets a CPU of its own...
const HEAVY_SHARE: f64 = 0.5;
/// ...if it computes at least this long per tick (µs): several iceoryx2 round trips, so that
/// the others' waits on the orchestrator's CPU cost less than the parallel compute saves. A
/// run of light participants (paper-passive: 0.2 µs per tick) keeps the starting placement.
const HEAVY_MIN_US: f64 = 10.0;

impl CpuPlanner {
    /// A planner for `s`, if it runs Jacobi over IPC with CPU pinning on two or more of
    /// `cpus` (the CPUs allowed before the run pinned anything).
    pub fn new(s: &Scenario, cpus: &[usize]) -> Option<Self> {
        if s.run.transport != Transport::Ipc
            || s.run.master != Master::Jacobi
            || !s.run.pin_cpus
            || s.run.cpu_plan != CpuPlanMode::Measured
        {
            return None;
        }
        let cpus = match (cpus.first(), cpus.last()) {
            (Some(&a), Some(&b)) if a != b => (a, b),
            _ => return None,
        };
        // Long enough to see the controller's updates several times.
        let warmup = (4 * s.controller_period_ticks()).max(200);
        (warmup < s.steps()).then(|| CpuPlanner {
            warmup,
            ticks: 0,
            calls: RoleMap::default(),
            cpus,
            report: None,
        })
    }

    /// Adds tick's compute (ns per role); at the end of the warm-up places the processes
    /// `pids`.
    pub fn observe(&mut self, compute: &RoleMap<u64>, pids: &RoleMap<u32>) {
        if self.report.is_some() {
            return;
        }
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
        for r in Role::ALL {
            self.calls[r].sort_unstable();
        }
        let ticks = self.ticks as f64;
        let per_tick = |r: Role| {
            let c = &self.calls[r];
            c.get(c.len() / 2)
                .map_or(0.0, |&m| m as f64 * 1e-3 * c.len() as f64 / ticks)
        };
        let total: f64 = Role::ALL.iter().map(|&r| per_tick(r)).sum();
        let heavy = Role::ALL
            .into_iter()
            .max_by(|a, b| per_tick(*a).total_cmp(&per_tick(*b)))
            .filter(|&r| per_tick(r) >= HEAVY_MIN_US && per_tick(r) >= HEAVY_SHARE * total);
        let (shared, own) = self.cpus;
        let mut applied = true;
        if let Some(h) = heavy {
            for r in Role::ALL {
                let cpu = if r == h { own } else { shared };
                applied &= cosim::ipc::set_cpus_of(pids[r], &[cpu]);
            }
        }
        self.report = Some(CpuPlanReport {
            warmup_ticks: self.ticks,
            compute_per_tick_us: Role::ALL.iter().map(|&r| (r.name(), per_tick(r))).collect(),
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
