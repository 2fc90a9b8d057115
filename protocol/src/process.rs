//! A process of one boot, told apart from a later process with its pid: the owner of a run's
//! shared-memory files (the transport's owner file) and the holder of an output directory's
//! lock (the run directory). Plain `/proc` reads, no transport.

/// Start time of process `pid` in clock ticks after boot (`/proc/<pid>/stat` field 22), if it
/// exists: with the pid, it names one process over the machine's uptime.
pub fn start_ticks(pid: u32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // "pid (comm) state ppid ...": comm may hold spaces and parentheses; fields after the last
    // ')' are numbered from 3 (state), so field 22 is the 20th of them.
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(19)?.parse().ok()
}

/// This boot's `/proc/sys/kernel/random/boot_id` (empty if it cannot be read).
pub fn boot_id() -> String {
    std::fs::read_to_string("/proc/sys/kernel/random/boot_id")
        .map(|s| s.trim().to_string())
        .unwrap_or_default()
}

/// One process of one boot, told apart from a later process with its pid: the owner of a
/// run's files (its owner file) or of an output directory's lock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Owner {
    /// Process id.
    pub pid: u32,
    /// Start time of the process, clock ticks after boot (`/proc/<pid>/stat` field 22).
    pub start_ticks: u64,
    /// `/proc/sys/kernel/random/boot_id` of its machine's boot.
    pub boot_id: String,
}

impl Owner {
    /// This process.
    pub fn me() -> Owner {
        let pid = std::process::id();
        Owner {
            pid,
            start_ticks: start_ticks(pid).unwrap_or(0),
            boot_id: boot_id(),
        }
    }

    /// An owner from its text form, `<pid> <start ticks> <boot id>` (an owner file's content).
    pub fn parse(text: &str) -> Option<Owner> {
        let mut w = text.split_whitespace();
        let owner = Owner {
            pid: w.next()?.parse().ok()?,
            start_ticks: w.next()?.parse().ok()?,
            boot_id: w.next()?.to_string(),
        };
        w.next().is_none().then_some(owner)
    }

    /// Whether the process is gone: another boot, or its pid free or now another process's
    /// (a process of that pid that started at another time).
    pub fn is_dead(&self) -> bool {
        self.boot_id != boot_id() || start_ticks(self.pid) != Some(self.start_ticks)
    }
}
