//! Where a run's processes go on a machine that other runs and other work share.
//!
//! Each IPC run that pins its processes claims the CPUs it pins them to in a registry kept
//! beside its other files: `/dev/shm/<prefix>tiltsim-cpus` lists the CPUs and is held under an
//! exclusive `flock` by the orchestrator for as long as the run lasts. Another run starting
//! reads every such file whose lock is held (a file whose lock it can take belongs to a run
//! that is gone: the kernel released the lock with the process, so a killed run's claim
//! vanishes with it, and its file goes with the dead run's other files). Claims are made one at
//! a time, under a lock on the registry's directory, so two runs starting together never pick
//! the same CPUs. A run pins only to CPUs that no live run claims and that other work left
//! idle over a short look at `/proc/stat`; when fewer than two such CPUs are left (more runs
//! than CPU pairs, or a build beside it) it pins nothing and lets the kernel balance its
//! processes, and its waiters stop spinning ([`crate::wait::fallback`]). Only wall-clock
//! placement changes, never a value.

use std::fs::File;
use std::io::Write;
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::wait::{self, WaitStrategy};

/// The end of the name of a run's CPU claim, `/dev/shm/<prefix>tiltsim-cpus`.
pub const CLAIM_FILE: &str = "tiltsim-cpus";
/// The registry's directory.
const REGISTRY: &str = "/dev/shm";
/// How long the CPUs' idle time is sampled before choosing.
const LOOK: Duration = Duration::from_millis(50);
/// A CPU counts as idle when it was idle at least this share of the look.
const IDLE_SHARE: f64 = 0.5;
/// The longest wait for another run's claim to be written before this run gives up pinning.
const REGISTRY_WAIT: Duration = Duration::from_millis(500);
/// The environment variable that makes a run take every unclaimed CPU for idle (tests).
pub const ASSUME_IDLE: &str = "TILTSIM_ASSUME_IDLE_CPUS";
/// The processes of a run: the orchestrator and three participants.
pub const PROCESSES: usize = 4;

/// Why a run's processes are placed as they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reason {
    /// Two CPUs that no other run claims and other work left idle: the orchestrator on one,
    /// the participants on the other.
    FreePair,
    /// `--wait spin` with a CPU for each process: the orchestrator on one, the participants
    /// spread by the kernel over three others.
    FreeCpuEach,
    /// `run.pin_cpus = false`.
    NotAsked,
    /// Fewer than two CPUs allowed.
    TooFewCpus,
    /// Other runs claim, or other work keeps busy, all but fewer than two CPUs: the kernel
    /// balances the processes.
    Contended,
    /// The registry could not be read or written in time: nothing pinned.
    RegistryUnavailable,
}

impl Reason {
    /// Its name, as in `summary.json`.
    pub fn name(self) -> &'static str {
        match self {
            Reason::FreePair => "free-pair",
            Reason::FreeCpuEach => "free-cpu-each",
            Reason::NotAsked => "not-asked",
            Reason::TooFewCpus => "too-few-cpus",
            Reason::Contended => "contended",
            Reason::RegistryUnavailable => "registry-unavailable",
        }
    }
}

/// Where a run's processes run and how they wait, for `summary.json` → `timing.placement`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Placement {
    /// Why.
    pub reason: Reason,
    /// The orchestrator's CPU, when pinned.
    pub orchestrator_cpu: Option<usize>,
    /// The participants' CPUs, when pinned (one, or three under `--wait spin`).
    pub participant_cpus: Vec<usize>,
    /// The CPUs this process may use.
    pub allowed: Vec<usize>,
    /// The CPUs other live runs claimed when this one chose.
    pub claimed_by_other_runs: Vec<usize>,
    /// The unclaimed CPUs that other work kept busy during the look.
    pub busy: Vec<usize>,
    /// The wait strategy asked for.
    pub wait_asked: WaitStrategy,
    /// The wait strategy used ([`crate::wait::fallback`]).
    pub wait: WaitStrategy,
}

impl Placement {
    /// Whether the run pins its processes.
    pub fn pinned(&self) -> bool {
        self.orchestrator_cpu.is_some()
    }

    /// The CPU the participants are pinned to when they share one (`--cpu`).
    pub fn shared_participant_cpu(&self) -> Option<usize> {
        match self.participant_cpus[..] {
            [c] => Some(c),
            _ => None,
        }
    }
}

/// Chooses where a run goes from what is known of the machine (pure, for tests): `allowed`
/// CPUs, those `claimed` by other live runs and those `busy` with other work.
pub fn choose(
    asked: WaitStrategy,
    pin: bool,
    allowed: &[usize],
    claimed: &[usize],
    busy: &[usize],
) -> Placement {
    let free: Vec<usize> = allowed
        .iter()
        .copied()
        .filter(|c| !claimed.contains(c) && !busy.contains(c))
        .collect();
    let (reason, cpus): (Reason, &[usize]) = if !pin {
        (Reason::NotAsked, &[])
    } else if allowed.len() < 2 {
        (Reason::TooFewCpus, &[])
    } else if asked == WaitStrategy::Spin && free.len() >= PROCESSES {
        (Reason::FreeCpuEach, &free[..PROCESSES])
    } else if free.len() >= 2 {
        (Reason::FreePair, &free[..2])
    } else {
        (Reason::Contended, &[])
    };
    // The CPUs the processes may use: their own when pinned, else all of the allowed ones,
    // which other runs and other work also want when contended.
    let usable = match reason {
        Reason::FreePair | Reason::FreeCpuEach => cpus.len(),
        Reason::Contended => 0,
        _ => allowed.len(),
    };
    Placement {
        reason,
        orchestrator_cpu: cpus.first().copied(),
        participant_cpus: cpus.iter().skip(1).copied().collect(),
        allowed: allowed.to_vec(),
        claimed_by_other_runs: claimed.to_vec(),
        busy: busy.to_vec(),
        wait_asked: asked,
        wait: wait::fallback(asked, PROCESSES, usable),
    }
}

/// A run's claim on its CPUs: the registry file, locked until dropped. Dropping it (or the
/// process dying) releases the claim; the file itself goes with the run's files.
#[derive(Debug)]
pub struct Claim {
    file: Option<(File, PathBuf)>,
}

impl Claim {
    /// A claim of nothing (an unpinned run).
    pub fn none() -> Self {
        Claim { file: None }
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        if let Some((file, path)) = self.file.take() {
            // Removed while still locked, so no other run reads a released claim as live.
            let _ = std::fs::remove_file(&path);
            drop(file);
        }
    }
}

/// Places the run with `prefix`: looks at which CPUs are idle, then, under the registry's lock,
/// reads the other runs' claims, chooses ([`choose`]) and writes this run's claim. `allowed`
/// are the CPUs this thread may use; `realtime`: the run's processes run under SCHED_FIFO.
pub fn place(
    prefix: &str,
    asked: WaitStrategy,
    pin: bool,
    allowed: &[usize],
    realtime: bool,
) -> (Placement, Claim) {
    if !pin || allowed.len() < 2 {
        return (choose(asked, pin, allowed, &[], &[]), Claim::none());
    }
    // The look costs its length; on a machine where nothing else runs it is skipped. Tests
    // of the registry set `TILTSIM_ASSUME_IDLE_CPUS=1`, so that other load cannot decide. A
    // run under SCHED_FIFO (`realtime`) does not look: ordinary work on a CPU gives way to
    // it, so a CPU busy with such work is as good as an idle one (other runs' claims still
    // count).
    let assume_idle = realtime || std::env::var_os(ASSUME_IDLE).is_some_and(|v| v == "1");
    let busy = if !assume_idle && others_runnable() > 0 {
        busy_cpus(allowed, LOOK)
    } else {
        Vec::new()
    };
    let Some(dir) = RegistryLock::take(REGISTRY_WAIT) else {
        let mut p = choose(asked, pin, allowed, &[], &busy);
        p.reason = Reason::RegistryUnavailable;
        p.orchestrator_cpu = None;
        p.participant_cpus.clear();
        p.wait = wait::fallback(asked, PROCESSES, 0);
        return (p, Claim::none());
    };
    let claimed = live_claims(Path::new(REGISTRY));
    let p = choose(asked, pin, allowed, &claimed, &busy);
    let claim = if p.pinned() {
        let cpus: Vec<usize> = p
            .orchestrator_cpu
            .into_iter()
            .chain(p.participant_cpus.iter().copied())
            .collect();
        match write_claim(Path::new(REGISTRY), prefix, &cpus) {
            Ok(c) => c,
            Err(e) => {
                tracing::warn!("cannot claim CPUs {cpus:?}: {e}; not pinning");
                drop(dir);
                let mut p = choose(asked, pin, allowed, &claimed, &busy);
                p.reason = Reason::RegistryUnavailable;
                p.orchestrator_cpu = None;
                p.participant_cpus.clear();
                p.wait = wait::fallback(asked, PROCESSES, 0);
                return (p, Claim::none());
            }
        }
    } else {
        Claim::none()
    };
    drop(dir);
    (p, claim)
}

/// The registry's lock: an exclusive `flock` on its directory, released when dropped or when
/// the process dies.
struct RegistryLock {
    _dir: File,
}

impl RegistryLock {
    fn take(within: Duration) -> Option<Self> {
        let dir = File::open(REGISTRY).ok()?;
        let started = Instant::now();
        loop {
            if try_lock(&dir) {
                return Some(RegistryLock { _dir: dir });
            }
            if started.elapsed() >= within {
                return None;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// Takes an exclusive `flock` on `f` without waiting.
fn try_lock(f: &File) -> bool {
    // SAFETY: flock on a valid descriptor; the lock goes with the open file description.
    unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) == 0 }
}

/// Writes this run's claim (`dir/<prefix>tiltsim-cpus`, the CPUs one a line) and keeps it
/// locked. The lock is taken before the CPUs are written; readers hold the registry's lock,
/// so none reads it half written.
fn write_claim(dir: &Path, prefix: &str, cpus: &[usize]) -> std::io::Result<Claim> {
    let path = dir.join(format!("{prefix}{CLAIM_FILE}"));
    let mut f = File::create(&path)?;
    if !try_lock(&f) {
        let _ = std::fs::remove_file(&path);
        return Err(std::io::Error::other(
            "claim file locked by another process",
        ));
    }
    let text: String = cpus.iter().map(|c| format!("{c}\n")).collect();
    f.write_all(text.as_bytes())?;
    Ok(Claim {
        file: Some((f, path)),
    })
}

/// The CPUs claimed by live runs in `dir`: the claim files whose lock another process holds.
/// A file whose lock can be taken belongs to a run that is gone; it is skipped (and left for
/// that run's clean-up).
pub fn live_claims(dir: &Path) -> Vec<usize> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut cpus = Vec::new();
    for e in entries.flatten() {
        if !e.file_name().to_string_lossy().ends_with(CLAIM_FILE) {
            continue;
        }
        let Ok(f) = File::open(e.path()) else {
            continue;
        };
        // SAFETY: flock on a valid descriptor; a shared lock that is granted means no live
        // run holds the exclusive one. Closing the file releases it.
        let free = unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_SH | libc::LOCK_NB) == 0 };
        if free {
            continue;
        }
        let text = std::fs::read_to_string(e.path()).unwrap_or_default();
        cpus.extend(text.lines().filter_map(|l| l.trim().parse::<usize>().ok()));
    }
    cpus.sort_unstable();
    cpus.dedup();
    cpus
}

/// Idle and total time of each CPU (`/proc/stat`, clock ticks), by CPU number.
fn cpu_times() -> Vec<(usize, u64, u64)> {
    let Ok(text) = std::fs::read_to_string("/proc/stat") else {
        return Vec::new();
    };
    text.lines()
        .filter_map(|l| {
            let rest = l.strip_prefix("cpu")?;
            let mut w = rest.split_whitespace();
            let cpu: usize = w.next()?.parse().ok()?;
            let v: Vec<u64> = w.filter_map(|x| x.parse().ok()).collect();
            // user nice system idle iowait irq softirq steal ...
            let idle = v.get(3)? + v.get(4).copied().unwrap_or(0);
            let total = v.iter().take(8).sum();
            Some((cpu, idle, total))
        })
        .collect()
}

/// The most runnable tasks besides this one seen in three looks at `/proc/stat`
/// (`procs_running`) a millisecond apart: whether other work may keep CPUs busy.
fn others_runnable() -> usize {
    (0..3)
        .map(|i| {
            if i > 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
            std::fs::read_to_string("/proc/stat")
                .ok()
                .and_then(|t| {
                    t.lines()
                        .find_map(|l| l.strip_prefix("procs_running "))
                        .and_then(|v| v.trim().parse::<usize>().ok())
                })
                // Unknown: look.
                .unwrap_or(2)
                .saturating_sub(1)
        })
        .max()
        .unwrap_or(0)
}

/// The CPUs of `allowed` that were idle less than [`IDLE_SHARE`] of a look of `look`.
pub fn busy_cpus(allowed: &[usize], look: Duration) -> Vec<usize> {
    let before = cpu_times();
    std::thread::sleep(look);
    let after = cpu_times();
    busy_between(allowed, &before, &after)
}

fn busy_between(
    allowed: &[usize],
    before: &[(usize, u64, u64)],
    after: &[(usize, u64, u64)],
) -> Vec<usize> {
    allowed
        .iter()
        .copied()
        .filter(|c| {
            let a = before.iter().find(|t| t.0 == *c);
            let b = after.iter().find(|t| t.0 == *c);
            match (a, b) {
                (Some(a), Some(b)) if b.2 > a.2 => {
                    let idle = b.1.saturating_sub(a.1) as f64 / (b.2 - a.2) as f64;
                    idle < IDLE_SHARE
                }
                // No tick counted on it in the look: nothing known, so not busy.
                _ => false,
            }
        })
        .collect()
}

#[cfg(test)]
#[path = "placement_tests.rs"]
mod tests;
