//! Wait strategies for a port that has no sample yet.
//!
//! Lock-step exchanges are short (microseconds), but four processes share two cores, so a
//! waiter must neither sleep through a sample nor starve the process it waits for.
//! [`WaitStrategy::Adaptive`] (the default) spins briefly, then yields the core on every poll,
//! then sleeps in short naps once a wait has lasted long (a controller idling between its
//! 50 ms updates). Every poll drains the port, so no wake-up can be lost: the worst case of a
//! late sample is one nap. Measured costs are in docs/performance.md.

use std::time::{Duration, Instant};

/// How a waiter spends the time between polls.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum WaitStrategy {
    /// Busy-poll with a CPU spin hint: lowest latency, burns a core per waiter.
    Spin,
    /// Spin ~`SPIN_POLLS`, then `sched_yield` between polls, then nap after `YIELD_FOR`.
    #[default]
    Adaptive,
    /// Sleep `NAP` between polls: cheapest in CPU, slowest.
    Sleep,
    /// For runs paced to the wall clock (`--pace`): spin ~`SPIN_POLLS`, then nap `NAP` between
    /// polls, never yield. The wait between ticks (most of the period) sleeps instead of
    /// keeping a core busy, and under load a sleeper is woken ahead of the processes that
    /// keep the CPU busy, where a yielder would wait behind them for a time slice.
    Paced,
}

impl WaitStrategy {
    /// Parses the kebab-case name.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "spin" => Some(Self::Spin),
            "adaptive" => Some(Self::Adaptive),
            "sleep" => Some(Self::Sleep),
            "paced" => Some(Self::Paced),
            _ => None,
        }
    }
    /// The kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Spin => "spin",
            Self::Adaptive => "adaptive",
            Self::Sleep => "sleep",
            Self::Paced => "paced",
        }
    }
}

/// The strategy a run's waiters use when `processes` share `cpus` CPUs of their own (0: none
/// of their own, the CPUs being wanted by other runs or other work as well).
/// * `spin` keeps spinning only with a CPU for every process; otherwise a spinner holds the
///   CPU the process it waits for needs until the scheduler's time slice ends (measured: 735
///   of 2000 ticks in 203 s with more spinners than CPUs), and it waits as `adaptive` does;
/// * `adaptive` on CPUs of its own spins briefly, then yields among its own processes; on
///   CPUs wanted by others a yield puts it behind every runnable task of theirs, so it naps
///   (`paced`: a sleeper is woken ahead of the processes that keep a CPU busy);
/// * `sleep` and `paced` never spin long: unchanged.
pub fn fallback(asked: WaitStrategy, processes: usize, cpus: usize) -> WaitStrategy {
    match asked {
        WaitStrategy::Spin if processes <= cpus => WaitStrategy::Spin,
        WaitStrategy::Spin | WaitStrategy::Adaptive if cpus == 0 => WaitStrategy::Paced,
        WaitStrategy::Spin => WaitStrategy::Adaptive,
        other => other,
    }
}

/// Polls spent spinning before yielding (adaptive).
pub const SPIN_POLLS: u32 = 200;
/// How long an adaptive waiter yields before it starts to nap.
pub const YIELD_FOR: Duration = Duration::from_millis(2);
/// Length of one nap.
pub const NAP: Duration = Duration::from_micros(50);

/// Asks the kernel to wake this thread's sleeps within 1 µs of their end instead of the
/// default 50 µs slack: a paced run's naps and its pacing sleep then end on time.
pub fn tight_timer_slack() {
    // SAFETY: prctl with PR_SET_TIMERSLACK takes a plain integer and affects this thread only.
    unsafe {
        libc::prctl(libc::PR_SET_TIMERSLACK, 1000 as libc::c_ulong, 0, 0, 0);
    }
}

/// State of one wait.
pub struct Backoff {
    strategy: WaitStrategy,
    polls: u32,
    spin_polls: u32,
    started: Instant,
}

impl Backoff {
    /// Starts a wait.
    pub fn new(strategy: WaitStrategy) -> Self {
        Self::with_spin(strategy, SPIN_POLLS)
    }
    /// Starts a wait that spins `spin_polls` polls before yielding (adaptive). Waiters that
    /// share a CPU with the process they wait for use 0: spinning would only delay it.
    pub fn with_spin(strategy: WaitStrategy, spin_polls: u32) -> Self {
        Backoff {
            strategy,
            polls: 0,
            spin_polls,
            started: Instant::now(),
        }
    }
    /// Time since the wait started.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }
    /// Number of polls so far.
    pub fn polls(&self) -> u32 {
        self.polls
    }
    /// Pauses between two polls.
    pub fn pause(&mut self) {
        self.polls = self.polls.saturating_add(1);
        match self.strategy {
            WaitStrategy::Spin => core::hint::spin_loop(),
            WaitStrategy::Sleep => std::thread::sleep(NAP),
            // Never yields: under load, a yielding process waits behind every other runnable
            // one for a whole time slice, while a sleeper is woken ahead of them.
            WaitStrategy::Paced => {
                if self.polls < self.spin_polls {
                    core::hint::spin_loop();
                } else {
                    std::thread::sleep(NAP);
                }
            }
            WaitStrategy::Adaptive => {
                if self.polls < self.spin_polls {
                    core::hint::spin_loop();
                } else if self.started.elapsed() < YIELD_FOR {
                    std::thread::yield_now();
                } else {
                    std::thread::sleep(NAP);
                }
            }
        }
    }
}

/// When a participant's next request is due at the earliest, from the spacing of its requests
/// (the orchestrator's send stamps, one monotonic clock for all processes). A participant asked only
/// every few ticks (the MPC every 50) would otherwise yield on every poll between its requests,
/// and every one of those yields costs the processes that share its CPU a switch to it and
/// back (measured on paper-mpc: the idle controller ran between every two orchestrator turns on
/// their CPU, about 4 µs a tick). With requests at least [`Cadence::LONG`] apart it sleeps
/// through the first [`Cadence::SHARE`] of the shortest gap seen since `Init`, in one sleep,
/// then polls as before. The shortest, not the last: a gap stretched by a stall (a sleeping
/// participant holds up the whole lock-step) must not lengthen the next sleep, or sleeps and
/// stalls would feed each other. A request that comes earlier than that waits at most until
/// the sleep ends. Only wall-clock placement changes, never a value.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cadence {
    last_sent_ns: Option<u64>,
    shortest_ns: Option<u64>,
}

impl Cadence {
    /// Requests closer than this (ns) are answered from a yield loop: a participant stepped
    /// every tick never sleeps.
    pub const LONG: u64 = 100_000;
    /// The share of the expected gap slept through.
    pub const SHARE: f64 = 0.75;
    /// The longest single sleep (ns), so that a participant whose orchestrator has gone still
    /// notices it.
    pub const MAX_SLEEP: u64 = 100_000_000;

    /// Notes a step request sent at `sent_ns`.
    pub fn observe(&mut self, sent_ns: u64) {
        if let Some(last) = self.last_sent_ns {
            let gap = sent_ns.saturating_sub(last);
            self.shortest_ns = Some(self.shortest_ns.map_or(gap, |s| s.min(gap)));
        }
        self.last_sent_ns = Some(sent_ns);
    }

    /// Forgets the spacing (after an `Init`, whose timing says nothing about the steps').
    pub fn reset(&mut self) {
        *self = Cadence::default();
    }

    /// Until when (monotonic ns) the participant may sleep before polling, if its requests
    /// are far apart.
    pub fn sleep_until(&self) -> Option<u64> {
        let last = self.last_sent_ns?;
        let gap = self.shortest_ns?;
        (gap >= Self::LONG).then(|| {
            let share = (gap as f64 * Self::SHARE) as u64;
            last + share.min(Self::MAX_SLEEP)
        })
    }
}

/// Sleeps until monotonic time `until_ns` (no-op if it has passed).
pub fn sleep_until_ns(until_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (until_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (until_ns % 1_000_000_000) as libc::c_long,
    };
    // SAFETY: an absolute sleep on CLOCK_MONOTONIC reading a valid timespec; an interrupted
    // sleep just ends early, and the caller polls again.
    unsafe {
        libc::clock_nanosleep(
            libc::CLOCK_MONOTONIC,
            libc::TIMER_ABSTIME,
            &ts,
            core::ptr::null_mut(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spin_falls_back_when_processes_outnumber_cpus() {
        use WaitStrategy::*;
        // A CPU for each of four processes: spins.
        assert_eq!(fallback(Spin, 4, 4), Spin);
        assert_eq!(fallback(Spin, 4, 16), Spin);
        // Four processes on two CPUs of their own: adaptive.
        assert_eq!(fallback(Spin, 4, 2), Adaptive);
        assert_eq!(fallback(Adaptive, 4, 2), Adaptive);
        // On CPUs other runs or other work want as well: naps, never spins or yields.
        assert_eq!(fallback(Spin, 4, 0), Paced);
        assert_eq!(fallback(Adaptive, 4, 0), Paced);
        // The strategies that do not spin stay.
        for w in [Sleep, Paced] {
            for cpus in [0, 1, 2, 4] {
                assert_eq!(fallback(w, 4, cpus), w);
            }
        }
    }

    #[test]
    fn a_participant_sleeps_through_three_quarters_of_its_shortest_long_gap_only() {
        let mut c = Cadence::default();
        assert_eq!(c.sleep_until(), None, "nothing known yet");
        c.observe(1_000_000);
        assert_eq!(c.sleep_until(), None, "one request gives no spacing");
        // Every 50 ticks (500 µs apart): sleeps until 375 µs after the last request.
        c.observe(1_500_000);
        assert_eq!(c.sleep_until(), Some(1_500_000 + 375_000));
        // A gap stretched by a stall (100 ms) does not lengthen the sleep.
        c.observe(101_500_000);
        assert_eq!(c.sleep_until(), Some(101_500_000 + 375_000));
        // Requests every tick (10 µs apart) once: never sleeps again.
        c.observe(101_510_000);
        assert_eq!(c.sleep_until(), None);
        c.observe(102_010_000);
        assert_eq!(c.sleep_until(), None);
        // After Init the spacing is learnt again; minutes apart are slept 100 ms at a time.
        c.reset();
        assert_eq!(c.sleep_until(), None);
        c.observe(0);
        c.observe(600_000_000_000);
        assert_eq!(c.sleep_until(), Some(600_000_000_000 + Cadence::MAX_SLEEP));
    }
}
