//! What the machine did to a run: how long the lock-step's thread waited for a CPU while it
//! ran (the kernel's run-queue wait, `/proc/thread-self/schedstat`) and the load average, so
//! that a run slowed by other work says so instead of leaving the user to guess.

use serde::Serialize;

/// The machine's load over one run's loop.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct MachineLoad {
    /// Time the loop's thread was runnable but waited for a CPU (s).
    pub waited_for_cpu_s: f64,
    /// That wait as a share of the loop's wall time.
    pub waited_share: f64,
    /// The 1-minute load average when the loop ended (runnable and waiting tasks).
    pub load_average_1m: f64,
    /// The CPUs this process may run on.
    pub cpus: usize,
    /// Whether the machine slowed the run: the thread waited for a CPU more than
    /// [`SLOWED_SHARE`] of the time. (The load average alone is not the test: it trails the
    /// last minute, so a run just after a busy spell would be blamed for it.)
    pub slowed: bool,
}

/// The share of the wall time spent waiting for a CPU above which a run counts as slowed. Over
/// IPC the loop's thread yields its CPU while the participants compute, and the time after a
/// yield counts as run-queue wait: a quiet paper-passive run on two CPUs shows about half its
/// wall time (48 % measured), an in-process one under 1 %. Three quarters means other work
/// held the CPUs for most of the run (the same run beside two CPU hogs: 94 %).
pub const SLOWED_SHARE: f64 = 0.75;

/// The run-queue wait of the calling thread so far (ns), when the kernel reports it.
pub fn runqueue_wait_ns() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    text.split_whitespace().nth(1)?.parse().ok()
}

/// The 1-minute load average, when the kernel reports it.
pub fn load_average() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

impl MachineLoad {
    /// The load of a loop that ran `wall_s` and whose thread waited `waited_ns` for a CPU,
    /// with `load` the load average at its end on `cpus` CPUs.
    pub fn of(waited_ns: u64, wall_s: f64, load: f64, cpus: usize) -> Self {
        let waited_for_cpu_s = waited_ns as f64 * 1e-9;
        let waited_share = if wall_s > 0.0 {
            waited_for_cpu_s / wall_s
        } else {
            0.0
        };
        MachineLoad {
            waited_for_cpu_s,
            waited_share,
            load_average_1m: load,
            cpus,
            slowed: waited_share > SLOWED_SHARE,
        }
    }

    /// What a user should know about an IPC run the machine slowed, or `None`.
    pub fn note(&self) -> Option<String> {
        self.slowed.then(|| {
            format!(
                "the machine was busy: this run waited {:.2} s ({:.0} % of its wall time) for a \
                 CPU, load average {:.1} on {} CPUs; `--transport in-process` gives the same \
                 bytes without processes to schedule",
                self.waited_for_cpu_s,
                self.waited_share * 100.0,
                self.load_average_1m,
                self.cpus
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_that_waited_or_ran_on_a_loaded_machine_is_slowed_and_names_the_faster_way() {
        let quiet = MachineLoad::of(2_000_000, 1.0, 0.5, 2);
        assert!(!quiet.slowed);
        assert_eq!(quiet.note(), None);
        // A quiet IPC run's yields show as about half its wall time: not slowed.
        assert!(!MachineLoad::of(480_000_000, 1.0, 1.0, 2).slowed);
        let waited = MachineLoad::of(900_000_000, 1.0, 1.0, 2);
        assert!(waited.slowed);
        assert!((waited.waited_share - 0.9).abs() < 1e-12);
        let note = waited.note().unwrap();
        assert!(note.contains("0.90 s (90 %"), "{note}");
        assert!(note.contains("--transport in-process"), "{note}");
        // A load average left over from the minute before, and no wait: not slowed.
        assert!(!MachineLoad::of(1_000_000, 1.0, 4.2, 2).slowed);
    }

    #[test]
    fn the_kernel_reports_this_threads_wait_and_the_load() {
        // Linux has both files; a kernel without schedstats would give None (not a number).
        assert!(runqueue_wait_ns().is_some());
        assert!(load_average().is_some_and(|l| l >= 0.0));
    }
}
