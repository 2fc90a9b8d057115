//! Wait strategies for a port that has no sample yet.
//!
//! Lock-step exchanges are short (microseconds), but four processes share two cores, so a
//! waiter must neither sleep through a sample nor starve the process it waits for.
//! [`WaitStrategy::Adaptive`] (the default) spins briefly, then yields the core on every poll,
//! then sleeps in short naps once a wait has lasted long (a controller idling between its
//! 50 ms updates). Every poll drains the port, so no wake-up can be lost: the worst case of a
//! late sample is one nap. Measured costs are in the README.

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
