//! iceoryx2's floor for a scenario's ticks, and the bench's rows set beside it round by round.

use cosim::ipc::placement::Reason;
use cosim::wait::WaitStrategy;
use serde::Serialize;

use tiltsim_scenario::scenario::{Master, Transport};

use crate::bench::{median, Report};

/// One round of a configuration.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    /// Coordination overhead per tick, p50 (µs).
    pub overhead_p50_us: f64,
    /// Where the round's processes ran (IPC only).
    pub placement: Option<cosim::ipc::placement::Reason>,
    /// `overhead_p50_us` over the best set of iceoryx2's floor measured right after this
    /// round's runs: the two taken in the same state of the machine, whose latency between
    /// CPUs changes over minutes (docs/performance.md). Only where the row is set beside a
    /// floor and this round had a pair of CPUs of its own.
    pub overhead_over_floor: Option<f64>,
}

/// The wall time of a tick's exchanges with iceoryx2 alone (`cosim::ipc::pattern`): one
/// process in the orchestrator's place and an echo for each participant, placed and waiting
/// as an adaptive IPC run, each echo asked as often as its participant, 256-byte samples.
/// Measured in several sets of fresh processes: processes that yield one CPU are cycled in
/// an order fixed when they start, and a tick costs a hand-over more for each request that
/// finds another process at the front of that cycle. `tiltsim bench` measures
/// `sets_per_round` sets of each pattern right after each round of the runs it compares.
#[derive(Debug, Clone, Serialize)]
pub struct ExchangeFloors {
    /// Every how many ticks each echo is asked (plant, actuator, controller).
    pub every: Vec<u64>,
    /// Ticks measured per set.
    pub ticks: usize,
    /// Sets of each pattern measured after each round, in round order below.
    pub sets_per_round: usize,
    /// Per tick, one exchange after the other (Gauss-Seidel), µs, each set.
    pub in_turn_sets_us: Vec<cosim::stats::Percentiles>,
    /// Per tick, every request and then every answer (Jacobi), µs, each set.
    pub all_at_once_sets_us: Vec<cosim::stats::Percentiles>,
}

/// The least and the greatest p50 of `sets`.
fn p50_range(sets: &[cosim::stats::Percentiles]) -> (f64, f64) {
    sets.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), p| {
        (lo.min(p.p50), hi.max(p.p50))
    })
}

impl ExchangeFloors {
    /// The floor under Gauss-Seidel, µs: the best set's p50, and the worst's.
    pub fn in_turn_us(&self) -> (f64, f64) {
        p50_range(&self.in_turn_sets_us)
    }
    /// The floor under Jacobi, µs: the best set's p50, and the worst's.
    pub fn all_at_once_us(&self) -> (f64, f64) {
        p50_range(&self.all_at_once_sets_us)
    }
    /// Rounds measured.
    pub fn rounds(&self) -> usize {
        self.in_turn_sets_us
            .len()
            .checked_div(self.sets_per_round)
            .unwrap_or(0)
    }
    /// The sets of `master`'s pattern.
    fn sets(&self, master: &str) -> &[cosim::stats::Percentiles] {
        if master == Master::Jacobi.name() {
            &self.all_at_once_sets_us
        } else {
            &self.in_turn_sets_us
        }
    }
    /// The best p50 of `master`'s pattern among the sets measured after round `r` (µs).
    pub fn round_best_us(&self, master: &str, r: usize) -> Option<f64> {
        let k = self.sets_per_round;
        let sets = self.sets(master).get(r * k..(r + 1) * k)?;
        let (best, _) = p50_range(sets);
        (best.is_finite() && best > 0.0).then_some(best)
    }
    /// Appends the sets of one more round, measured as these.
    pub(crate) fn append(&mut self, next: ExchangeFloors) {
        self.in_turn_sets_us.extend(next.in_turn_sets_us);
        self.all_at_once_sets_us.extend(next.all_at_once_sets_us);
    }
}

impl Report {
    /// Sets the exchange floors and each adaptive IPC row beside its master's floor, round by
    /// round: each round's overhead over the best set measured right after that round.
    pub fn set_exchange_floors(&mut self, f: ExchangeFloors) {
        for c in self.configs.iter_mut() {
            let comparable =
                c.transport == Transport::Ipc.name() && c.wait == WaitStrategy::Adaptive.name();
            if !comparable {
                continue;
            }
            let mut ratios = Vec::new();
            for (i, round) in c.rounds.iter_mut().enumerate() {
                round.overhead_over_floor = f
                    .round_best_us(c.master, i)
                    .filter(|_| round.placement == Some(Reason::FreePair))
                    .map(|best| round.overhead_p50_us / best);
                ratios.extend(round.overhead_over_floor);
            }
            if ratios.is_empty() {
                continue;
            }
            let (floor, worst) = p50_range(f.sets(c.master));
            c.exchange_floor_us = Some(floor);
            c.exchange_floor_worst_us = Some(worst);
            c.overhead_over_floor = Some(median(&ratios));
        }
        self.exchange_floors = Some(f);
    }
}
