//! What the machine did to a run: how long the lock-step's thread and the participants waited
//! for a CPU while it ran (the kernel's run-queue wait, `/proc/<pid>/task/<tid>/schedstat`),
//! how much of the run's CPUs other work took (`/proc/stat` against the run's own processes'
//! CPU time, `/proc/<pid>/stat`) and the load average, so that a run slowed by other work says
//! so, and what would help, instead of leaving the user to guess.

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
    /// Time the participant processes on this host were runnable but waited for a CPU,
    /// summed over them (s); `None` in one process or where the kernel does not say.
    pub participants_waited_for_cpu_s: Option<f64>,
    /// CPU time other work took on the CPUs this process may run on during the loop (the
    /// CPUs' busy time, a hypervisor's steal included, less the run's own processes'), as a
    /// share of those CPUs' time; `None` where the kernel does not say, or for a loop shorter
    /// than [`MIN_SPAN_S`] of the CPUs' time.
    pub others_cpu_share: Option<f64>,
    /// Whether the machine slowed the run: other work took more than [`OTHERS_SHARE`] of
    /// the run's CPUs, or the loop's thread waited for a CPU more than [`SLOWED_SHARE`] of the
    /// time. (The load average alone is not the test: it trails the last minute, so a run just
    /// after a busy spell would be blamed for it.)
    pub slowed: bool,
    /// Whether the run's processes ran under `SCHED_FIFO` (`--realtime`).
    pub realtime: bool,
}

/// The share of the wall time spent waiting for a CPU above which a run counts as slowed. Over
/// IPC the loop's thread yields its CPU while the participants compute, and the time after a
/// yield counts as run-queue wait: a quiet paper-passive run on two CPUs shows about half its
/// wall time (48 % measured), an in-process one under 1 %. Three quarters means other work
/// held the CPUs for most of the run (the same run beside two CPU hogs: 94 %).
pub const SLOWED_SHARE: f64 = 0.75;

/// The share of the run's CPUs taken by other work above which a run counts as slowed. A
/// quiet machine's own work (daemons, the kernel's threads) takes a few per cent; another
/// process that keeps one CPU of two busy takes a quarter to a half, since the kernel shares
/// each CPU between the runnable tasks on it and the run's waiting processes yield theirs.
pub const OTHERS_SHARE: f64 = 0.2;

/// The shortest loop, in CPU-seconds of the run's CPUs, over which other work's share is
/// measured: the kernel counts CPU time in clock ticks (10 ms at the usual 100 Hz), so a share
/// over one CPU-second is good to a few per cent.
pub const MIN_SPAN_S: f64 = 1.0;

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

/// What the kernel says of the machine at one instant, for the difference over a loop.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    /// The loop's thread's run-queue wait so far (ns).
    own_wait_ns: Option<u64>,
    /// The participant processes' run-queue waits so far, summed over their threads (ns).
    participants_wait_ns: Option<u64>,
    /// Busy clock ticks of the CPUs this process may run on.
    cpus_busy_ticks: Option<u64>,
    /// CPU clock ticks of this process and the participants.
    run_ticks: Option<u64>,
}

impl Snapshot {
    /// The machine now, as seen by a run whose participants are the processes `pids` (this
    /// process's own pid among them in one process, or a remote participant's 0: skipped) on
    /// CPUs `cpus`.
    pub fn take(pids: &[u32], cpus: &[usize]) -> Self {
        let me = std::process::id();
        let others: Vec<u32> = pids
            .iter()
            .copied()
            .filter(|&p| p != 0 && p != me)
            .collect();
        let waits: Option<Vec<u64>> = others.iter().map(|&p| process_wait_ns(p)).collect();
        let mut run = others.clone();
        run.push(me);
        Snapshot {
            own_wait_ns: runqueue_wait_ns(),
            participants_wait_ns: waits.filter(|w| !w.is_empty()).map(|w| w.iter().sum()),
            cpus_busy_ticks: cpus_busy_ticks(cpus),
            run_ticks: run_ticks(&run),
        }
    }
}

/// The CPU time of processes `pids` so far, summed (clock ticks).
fn run_ticks(pids: &[u32]) -> Option<u64> {
    pids.iter().map(|&p| process_ticks(p)).sum()
}

/// The run-queue wait of process `pid` so far, summed over its threads (ns).
fn process_wait_ns(pid: u32) -> Option<u64> {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).ok()?;
    let mut sum = 0;
    for t in tasks.flatten() {
        let text = std::fs::read_to_string(t.path().join("schedstat")).ok()?;
        sum += text.split_whitespace().nth(1)?.parse::<u64>().ok()?;
    }
    Some(sum)
}

/// The CPU time of process `pid` so far, user and system (clock ticks).
fn process_ticks(pid: u32) -> Option<u64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name, in parentheses, may hold spaces: fields count from after it.
    let rest = &text[text.rfind(')')? + 1..];
    let mut f = rest.split_whitespace().skip(11);
    let user: u64 = f.next()?.parse().ok()?;
    let system: u64 = f.next()?.parse().ok()?;
    Some(user + system)
}

/// The busy time of CPUs `cpus` so far (clock ticks): user, nice, system, interrupts and the
/// time a hypervisor gave to other machines (steal); not idle or waiting for I/O.
fn cpus_busy_ticks(cpus: &[usize]) -> Option<u64> {
    let text = std::fs::read_to_string("/proc/stat").ok()?;
    let mut sum = 0;
    let mut seen = 0;
    for line in text.lines() {
        let mut f = line.split_whitespace();
        let Some(n) = f.next().and_then(|n| n.strip_prefix("cpu")) else {
            continue;
        };
        let Ok(n) = n.parse::<usize>() else {
            continue;
        };
        if !cpus.contains(&n) {
            continue;
        }
        let v: Vec<u64> = f.filter_map(|x| x.parse().ok()).collect();
        // user nice system idle iowait irq softirq steal (guest time is within user).
        let busy = [0, 1, 2, 5, 6, 7]
            .iter()
            .filter_map(|&i| v.get(i))
            .sum::<u64>();
        sum += busy;
        seen += 1;
    }
    (seen == cpus.len() && seen > 0).then_some(sum)
}

/// The kernel's clock ticks per second (`USER_HZ`).
fn ticks_per_s() -> f64 {
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    if hz > 0 {
        hz as f64
    } else {
        100.0
    }
}

impl MachineLoad {
    /// The load over a loop of `wall_s` on `cpus` CPUs, from the snapshots at its start and
    /// end, with `load` the load average at its end; `realtime` when its processes ran under
    /// `SCHED_FIFO`. `None` where the kernel does not report the loop's thread's wait.
    pub fn between(
        a: &Snapshot,
        b: &Snapshot,
        wall_s: f64,
        load: f64,
        cpus: usize,
        realtime: bool,
    ) -> Option<Self> {
        let waited = b.own_wait_ns?.saturating_sub(a.own_wait_ns?);
        let mut m = Self::of(waited, wall_s, load, cpus);
        m.participants_waited_for_cpu_s = a
            .participants_wait_ns
            .zip(b.participants_wait_ns)
            .map(|(a, b)| b.saturating_sub(a) as f64 * 1e-9);
        let hz = ticks_per_s();
        let busy = a.cpus_busy_ticks.zip(b.cpus_busy_ticks);
        let run = a.run_ticks.zip(b.run_ticks);
        m.others_cpu_share = busy.zip(run).and_then(|((b0, b1), (r0, r1))| {
            let span = wall_s * cpus.max(1) as f64;
            // Busy ticks of the run's processes may fall on CPUs outside the set only when
            // something moved them; the difference is never negative.
            let others = b1.saturating_sub(b0) as f64 - r1.saturating_sub(r0) as f64;
            // The kernel counts in clock ticks (10 ms): over less than a second of the CPUs'
            // time a few ticks either way would be most of the share.
            (span >= MIN_SPAN_S).then(|| (others.max(0.0) / hz / span).min(1.0))
        });
        m.realtime = realtime;
        m.slowed = m.waited_share > SLOWED_SHARE || m.others_cpu_share > Some(OTHERS_SHARE);
        Some(m)
    }

    /// The load of a loop that ran `wall_s` and whose thread waited `waited_ns` for a CPU,
    /// with `load` the load average at its end on `cpus` CPUs (no other measurement).
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
            participants_waited_for_cpu_s: None,
            others_cpu_share: None,
            slowed: waited_share > SLOWED_SHARE,
            realtime: false,
        }
    }

    /// What a user should know about an IPC run the machine slowed, or `None`: how much it
    /// waited, what other work took, and the remedies (`--realtime` where it was not used,
    /// one process).
    pub fn note(&self) -> Option<String> {
        self.slowed.then(|| {
            let others = self.others_cpu_share.map_or(String::new(), |s| {
                format!(", other work took {:.0} % of its CPUs", s * 100.0)
            });
            let parts = self
                .participants_waited_for_cpu_s
                .map_or(String::new(), |w| {
                    format!(" (the participants together {w:.2} s)")
                });
            let realtime = if self.realtime {
                ""
            } else {
                "`--realtime` (SCHED_FIFO for the run's processes, as root or with \
                 CAP_SYS_NICE; the kernel's real-time throttling still leaves other work 5 %) \
                 keeps other work off the run's CPUs; "
            };
            format!(
                "the machine was busy: this run waited {:.2} s ({:.0} % of its wall time) for a \
                 CPU{parts}{others}, load average {:.1} on {} CPUs; {realtime}`--transport \
                 in-process` gives the same bytes without processes to schedule",
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

    /// Other work's share of the run's CPUs is their busy time less the run's own processes'
    /// CPU time, over the loop's wall time on those CPUs; more than a fifth slows the run
    /// even when the loop's thread waited little.
    #[test]
    fn other_work_on_the_runs_cpus_slows_it() {
        let hz = ticks_per_s();
        let at = |wait_s: f64, busy_s: f64, run_s: f64| Snapshot {
            own_wait_ns: Some((wait_s * 1e9) as u64),
            participants_wait_ns: Some((wait_s * 2e9) as u64),
            cpus_busy_ticks: Some((busy_s * hz) as u64),
            run_ticks: Some((run_s * hz) as u64),
        };
        // 2 s on 2 CPUs: the CPUs were busy 3.6 s, the run's processes 2.0 s of it.
        let m = MachineLoad::between(&at(0.0, 0.0, 0.0), &at(0.4, 3.6, 2.0), 2.0, 1.0, 2, false)
            .unwrap();
        assert!((m.others_cpu_share.unwrap() - 0.4).abs() < 1e-9);
        assert!((m.waited_share - 0.2).abs() < 1e-9);
        assert_eq!(m.participants_waited_for_cpu_s, Some(0.8));
        assert!(m.slowed);
        let note = m.note().unwrap();
        assert!(note.contains("other work took 40 %"), "{note}");
        assert!(note.contains("`--realtime`"), "{note}");
        // The same run with its CPUs to itself is not slowed; under SCHED_FIFO a slowed run
        // is not told to use it.
        let quiet = MachineLoad::between(&at(0.0, 0.0, 0.0), &at(0.4, 2.1, 2.0), 2.0, 1.0, 2, true)
            .unwrap();
        assert!(!quiet.slowed, "{quiet:?}");
        let rt = MachineLoad::between(&at(0.0, 0.0, 0.0), &at(1.8, 2.0, 2.0), 2.0, 1.0, 2, true)
            .unwrap();
        assert!(rt.slowed && !rt.note().unwrap().contains("`--realtime`"));
    }

    /// A process spinning on a CPU that is not one of the run's is other work there: pinned
    /// to one CPU for 1.2 s (more than the shortest span measured), it keeps that CPU busy
    /// whatever else the machine runs, so other work's share of it is at least a half (about
    /// one, on a quiet machine or a busy one), and the kernel counts its CPU time.
    #[test]
    fn a_cpu_kept_busy_by_a_process_outside_the_run_is_other_work() {
        let cpus = cosim::ipc::allowed_cpus();
        let cpu = *cpus.last().unwrap();
        let mut hog = std::process::Command::new("sh")
            .args(["-c", "while :; do :; done"])
            .spawn()
            .unwrap();
        assert!(cosim::ipc::set_cpus_of(hog.id(), &[cpu]));
        // The test process's other threads (other tests) run on any CPU: only the hog is
        // looked at, against that CPU's busy time.
        let look = || Snapshot {
            run_ticks: run_ticks(&[]),
            ..Snapshot::take(&[], &[cpu])
        };
        let a = look();
        let t0 = std::time::Instant::now();
        std::thread::sleep(std::time::Duration::from_millis(1200));
        let b = look();
        let wall = t0.elapsed().as_secs_f64();
        let hog_ticks = process_ticks(hog.id());
        let _ = hog.kill();
        let _ = hog.wait();
        assert!(hog_ticks.is_some_and(|t| t > 0), "{hog_ticks:?}");
        let m = MachineLoad::between(&a, &b, wall, 1.0, 1, false).unwrap();
        // Busy with the hog or with whatever else runs there: the CPU hardly idles.
        let share = m.others_cpu_share.unwrap();
        assert!(share > 0.5, "{m:?}");
    }
}
