//! One run per output directory, and a directory holds one run.
//!
//! **The lock.** Every command that writes an output directory (`run`, `sweep` and its shards,
//! `sweep-merge`, `compare` and each of its runs) first takes `DIR/.tiltsim.lock`, before it
//! writes anything else there, and holds it until it ends. The file names its holder: pid,
//! the process's start time (`/proc/<pid>/stat`, field 22, clock ticks since boot), the boot
//! id, the host and the command. It is held two ways:
//! * an exclusive `flock(2)` on the open file, which the kernel drops the moment the holder
//!   exits, however it exits (also across hosts on NFSv4, whose server keeps the lock);
//! * its contents, checked with `kill(pid, 0)` and the start time, so a pid reused by another
//!   process after the holder died is not mistaken for it (and so that the lock still excludes
//!   where a file system accepts `flock` without enforcing it).
//!
//! A directory whose lock is held by a live holder is refused ([`OutDirError::InUse`], naming
//! the directory and the holder's pid). A lock left by a holder that died (SIGKILL, a lost
//! node) is taken over. A holder that ends removes its lock, so a later command into the same
//! directory goes ahead and replaces the files: only concurrent use is refused. Where `flock`
//! is not supported and the holder ran on another host, its liveness cannot be checked: the
//! lock is refused with the path to remove by hand.
//!
//! **What a command owns.** Each command removes, at its start, the files of an earlier command
//! of its kind in the directory that it may not write again ([`clear_run`], the sweep's and the
//! compare's own clearing), so that nothing in the directory belongs to another run: a run
//! without `--record` does not leave an earlier `run.mcap` beside its series, an interrupted
//! run no earlier figures. Only the exact names the program writes are removed (listed here,
//! with the temporary files of [`crate::files::write_atomic`]); a directory is removed only
//! when that leaves it empty. A directory that holds the results of another kind of command
//! (a run into a sweep's directory, say) is refused ([`OutDirError::OtherKind`]).

use std::io::{Read as _, Seek as _, Write as _};
use std::os::unix::fs::MetadataExt as _;
use std::os::unix::io::AsRawFd as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use tiltsim_protocol::process::Owner;

/// The lock file's name inside an output directory.
pub const LOCK_FILE: &str = ".tiltsim.lock";

/// Files a run writes at the top of its directory (engine, analysis, `tiltsim run`, a free
/// run's `timing.csv`, `tiltsim export-mcap`, and `scripts/to-rerun.py`'s `run.rrd`).
pub const RUN_FILES: [&str; 10] = [
    "timeseries.csv",
    "columns.csv",
    "summary.json",
    "perf.json",
    "events.csv",
    "scenario.toml",
    "trace.csv",
    "timing.csv",
    "run.mcap",
    "run.rrd",
];
/// Figures of a run in `plots/` (`.svg` and `.png` each): the run's charts and, with
/// `--trace`, the latency histogram.
pub const RUN_PLOTS: [&str; 5] = [
    "lateral_acceleration",
    "body_roll",
    "control",
    "motor",
    "latency_histogram",
];
/// The directory of a run's participant logs: `logs/ROLE.log`, the standard error of each
/// participant process (kept only when it wrote something; `engine::finish_logs`).
pub const RUN_LOGS: &str = "logs";
/// Files of `tiltsim replay` in `replay-ROLE/` of a run's directory (`ROLE` stands for the role).
pub const REPLAY_FILES: [&str; 2] = ["replay.json", "ROLE-out.jsonl"];
/// Files of a sweep (or a shard, or a merged sweep).
pub const SWEEP_FILES: [&str; 7] = [
    "sweep.json",
    "scenario.toml",
    "samples.csv",
    "series.csv",
    "columns.csv",
    "table.md",
    "table.csv",
];
/// Figures of a sweep in `plots/`.
pub const SWEEP_PLOTS: [&str; 3] = ["sweep_lateral_acceleration", "sweep_p_ct", "sweep_comfort"];
/// Files of a compare (its runs are in subdirectories listed in `compare.json`).
pub const COMPARE_FILES: [&str; 4] = ["compare.json", "table.md", "table.csv", "columns.csv"];
/// Figures of a compare in `plots/`.
pub const COMPARE_PLOTS: [&str; 4] = [
    "compare_lateral_acceleration",
    "compare_body_roll",
    "compare_control",
    "trade_off",
];

/// What a directory holds: the results of one kind of command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// `tiltsim run` (and each run of a compare).
    Run,
    /// `tiltsim sweep`, a shard of one, or `tiltsim sweep-merge`.
    Sweep,
    /// `tiltsim compare`.
    Compare,
}

impl Kind {
    /// The name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Run => "run",
            Kind::Sweep => "sweep",
            Kind::Compare => "compare",
        }
    }
}

/// Why an output directory cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum OutDirError {
    /// Another live command holds the directory.
    #[error("{}: in use by {holder}; one run per output directory: wait for it to end, or give another --out", dir.display())]
    InUse {
        /// The directory.
        dir: PathBuf,
        /// Who holds it.
        holder: Holder,
    },
    /// The lock names a holder on another host and this file system has no `flock`.
    #[error("{}: locked by {holder}, on a host this machine cannot check; if that run has ended, remove {}", dir.display(), dir.join(LOCK_FILE).display())]
    Unverifiable {
        /// The directory.
        dir: PathBuf,
        /// Who holds it.
        holder: Holder,
    },
    /// The directory holds the results of another kind of command.
    #[error("{}: holds the results of a {} ({marker}), not of a {}: a directory holds one run; give another --out, or remove those files", dir.display(), found.name(), want.name())]
    OtherKind {
        /// The directory.
        dir: PathBuf,
        /// What it holds.
        found: Kind,
        /// The file that says so.
        marker: String,
        /// What the command writes.
        want: Kind,
    },
    /// The directory or its lock could not be created, read or cleared.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> OutDirError + '_ {
    move |source| OutDirError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The holder of a lock, as its file records it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Holder {
    /// Process id.
    pub pid: u32,
    /// Start time of the process, clock ticks after boot (`/proc/<pid>/stat` field 22).
    pub start_ticks: u64,
    /// `/proc/sys/kernel/random/boot_id` of its machine's boot.
    pub boot_id: String,
    /// Host name.
    pub host: String,
    /// The command (`run`, `sweep`, `compare`, `sweep-merge`).
    pub command: String,
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "tiltsim {} (pid {} on {})",
            self.command, self.pid, self.host
        )
    }
}

fn read_trimmed(p: &str) -> String {
    std::fs::read_to_string(p)
        .map(|s| s.trim().to_string())
        .unwrap_or_default()
}

impl Holder {
    /// This process, holding for `command`.
    fn me(command: &str) -> Holder {
        let me = Owner::me();
        Holder {
            pid: me.pid,
            start_ticks: me.start_ticks,
            boot_id: me.boot_id,
            host: read_trimmed("/proc/sys/kernel/hostname"),
            command: command.to_string(),
        }
    }

    /// Whether the holder is still running: `Some(true)` alive, `Some(false)` dead (or its pid
    /// now another process's, [`Owner::is_dead`]), `None` on another host.
    fn alive(&self, here: &Holder) -> Option<bool> {
        if self.host != here.host {
            return None;
        }
        let owner = Owner {
            pid: self.pid,
            start_ticks: self.start_ticks,
            boot_id: self.boot_id.clone(),
        };
        Some(!owner.is_dead())
    }
}

/// The holder of `dir`'s lock if it is a live process (for commands that read a directory
/// another may be writing: `sweep-merge` of a shard that is still running, `replay`).
pub fn live_holder(dir: &Path) -> Option<Holder> {
    let text = std::fs::read_to_string(dir.join(LOCK_FILE)).ok()?;
    let h: Holder = serde_json::from_str(&text).ok()?;
    let here = Holder::me("");
    (h.alive(&here) != Some(false) && h.pid != here.pid).then_some(h)
}

/// A held output directory; released (its lock file removed) when dropped.
#[derive(Debug)]
pub struct Lock {
    dir: PathBuf,
    path: PathBuf,
    file: std::fs::File,
    replaced: usize,
}

fn same_file(file: &std::fs::File, path: &Path) -> bool {
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

/// `flock(LOCK_EX | LOCK_NB)`: `Ok(true)` taken, `Ok(false)` held by another, `Err` when the
/// file system has no such locks.
fn flock(file: &std::fs::File) -> Result<bool, std::io::Error> {
    // SAFETY: flock on a file descriptor this process owns.
    let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if r == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
        Ok(false)
    } else {
        Err(e)
    }
}

fn read_holder(file: &mut std::fs::File) -> Option<Holder> {
    let mut text = String::new();
    file.rewind().ok()?;
    file.read_to_string(&mut text).ok()?;
    serde_json::from_str(&text).ok()
}

/// `dir` held under another's flock, naming its holder (it may still be writing its name).
fn in_use(dir: &Path, file: &mut std::fs::File) -> OutDirError {
    let mut holder = None;
    for _ in 0..50 {
        holder = read_holder(file);
        if holder.is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    OutDirError::InUse {
        dir: dir.to_path_buf(),
        holder: holder.unwrap_or(Holder {
            pid: 0,
            start_ticks: 0,
            boot_id: String::new(),
            host: "an unknown host".into(),
            command: "(starting)".into(),
        }),
    }
}

/// Whether `me` may take over the lock of `dir` from the holder its file names, `old`: not
/// from another live process, nor from one on another host unless `flocked` (the file
/// system's locks then decide).
fn take_over(dir: &Path, old: Holder, me: &Holder, flocked: bool) -> Result<(), OutDirError> {
    match old.alive(me) {
        Some(true) if old.pid != me.pid || old.start_ticks != me.start_ticks => {
            Err(OutDirError::InUse {
                dir: dir.to_path_buf(),
                holder: old,
            })
        }
        None if !flocked => Err(OutDirError::Unverifiable {
            dir: dir.to_path_buf(),
            holder: old,
        }),
        _ => {
            tracing::info!(
                "{}: taking over the lock of {old}, which is no longer running",
                dir.display()
            );
            Ok(())
        }
    }
}

impl Lock {
    /// Takes `dir` (created if missing) for `command`, before anything is written in it.
    pub fn acquire(dir: &Path, command: &str) -> Result<Lock, OutDirError> {
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        let path = dir.join(LOCK_FILE);
        let me = Holder::me(command);
        // A holder that ends removes the file while holding its flock: one opened before that
        // is then no longer the lock, and is opened again.
        for _ in 0..16 {
            let mut file = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io(&path))?;
            let flocked = match flock(&file) {
                Ok(true) => true,
                Ok(false) => return Err(in_use(dir, &mut file)),
                Err(e) => {
                    tracing::debug!(
                        "{}: no flock ({e}); the lock's contents decide",
                        path.display()
                    );
                    false
                }
            };
            if !same_file(&file, &path) {
                continue;
            }
            if let Some(old) = read_holder(&mut file) {
                take_over(dir, old, &me, flocked)?;
            }
            let text = serde_json::to_string(&me).unwrap_or_default() + "\n";
            (|| {
                file.set_len(0)?;
                file.rewind()?;
                file.write_all(text.as_bytes())?;
                file.sync_data()
            })()
            .map_err(io(&path))?;
            return Ok(Lock {
                dir: dir.to_path_buf(),
                path,
                file,
                replaced: 0,
            });
        }
        Err(OutDirError::Io {
            path,
            source: std::io::Error::other("the lock file kept changing; is another run starting?"),
        })
    }

    /// The held directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// How many files of an earlier run [`claim_run`] removed from the directory: a run
    /// that replaces another's results says so.
    pub fn replaced(&self) -> usize {
        self.replaced
    }
}

impl Drop for Lock {
    fn drop(&mut self) {
        // Removed while the flock is still held (the file closes after this), and only if it
        // is still ours.
        if same_file(&self.file, &self.path) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Whether `file` is one of `names` or a temporary file of one ([`crate::files::write_atomic`]:
/// `.NAME.PID.tmp`).
fn is_named(file: &str, names: &[String]) -> bool {
    if names.iter().any(|n| n == file) {
        return true;
    }
    file.strip_prefix('.')
        .and_then(|f| f.strip_suffix(".tmp"))
        .and_then(|f| f.rsplit_once('.'))
        .is_some_and(|(name, pid)| {
            !pid.is_empty()
                && pid.bytes().all(|b| b.is_ascii_digit())
                && names.iter().any(|n| n == name)
        })
}

/// Removes from `dir` the files named `names` (and their temporary files); returns how many.
fn remove_named(dir: &Path, names: &[String]) -> Result<usize, OutDirError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(io(dir)(e)),
    };
    let mut n = 0;
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let is_file = e.file_type().map(|t| t.is_file()).unwrap_or(false);
        if is_file && is_named(&name, names) {
            let p = e.path();
            std::fs::remove_file(&p).map_err(io(&p))?;
            n += 1;
        }
    }
    Ok(n)
}

/// Removes `dir` if it is empty (a directory the program made and emptied).
pub fn remove_if_empty(dir: &Path) {
    let _ = std::fs::remove_dir(dir);
}

fn figures(stems: &[&str]) -> Vec<String> {
    stems
        .iter()
        .flat_map(|s| [format!("{s}.svg"), format!("{s}.png")])
        .collect()
}

fn names(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// Removes the figures `stems` from `dir/plots` (and `plots/` itself when that empties it).
pub fn clear_plots(dir: &Path, stems: &[&str]) -> Result<usize, OutDirError> {
    let plots = dir.join("plots");
    let n = remove_named(&plots, &figures(stems))?;
    remove_if_empty(&plots);
    Ok(n)
}

/// Removes every file a run writes from `dir` (its series, summaries, events, scenario,
/// trace, recording, figures, participant logs and the replays of its recording): called by a
/// run before it writes, so that what it does not write again (`run.mcap` without `--record`,
/// figures of an interrupted run, the log of a participant quiet this time, ...) is not left
/// from an earlier one. Returns how many files went.
pub fn clear_run(dir: &Path) -> Result<usize, OutDirError> {
    let mut n = remove_named(dir, &names(&RUN_FILES))?;
    n += clear_plots(dir, &RUN_PLOTS)?;
    let logs = dir.join(RUN_LOGS);
    let files: Vec<String> = tiltsim_protocol::Role::ALL
        .iter()
        .map(|r| format!("{}.log", r.name()))
        .collect();
    n += remove_named(&logs, &files)?;
    remove_if_empty(&logs);
    for role in tiltsim_protocol::Role::ALL {
        let sub = dir.join(format!("replay-{}", role.name()));
        let files: Vec<String> = REPLAY_FILES
            .iter()
            .map(|f| f.replace("ROLE", role.name()))
            .collect();
        n += remove_named(&sub, &files)?;
        remove_if_empty(&sub);
    }
    Ok(n)
}

/// Removes a sweep's result files and figures from `dir` (not `done/` and `runs/`, which the
/// sweep's resumption handles); returns how many went.
pub fn clear_sweep_results(dir: &Path) -> Result<usize, OutDirError> {
    Ok(remove_named(dir, &names(&SWEEP_FILES))? + clear_plots(dir, &SWEEP_PLOTS)?)
}

/// Removes a compare's own files and figures from `dir` (its runs' subdirectories are cleared
/// as runs by the compare).
pub fn clear_compare_results(dir: &Path) -> Result<usize, OutDirError> {
    Ok(remove_named(dir, &names(&COMPARE_FILES))? + clear_plots(dir, &COMPARE_PLOTS)?)
}

fn exists(dir: &Path, name: &str) -> bool {
    std::fs::symlink_metadata(dir.join(name)).is_ok()
}

/// What `dir` holds, by the first file found that only one kind of command writes.
pub fn holds(dir: &Path) -> Option<(Kind, String)> {
    for f in ["sweep.json", "samples.csv", "series.csv", "done"] {
        if exists(dir, f) {
            return Some((Kind::Sweep, f.to_string()));
        }
    }
    for f in ["compare.json", "table.md", "table.csv"] {
        if exists(dir, f) {
            return Some((Kind::Compare, f.to_string()));
        }
    }
    for f in figures(&COMPARE_PLOTS) {
        if exists(&dir.join("plots"), &f) {
            return Some((Kind::Compare, format!("plots/{f}")));
        }
    }
    for f in RUN_FILES.iter().filter(|f| **f != "scenario.toml") {
        if exists(dir, f) {
            return Some((Kind::Run, f.to_string()));
        }
    }
    None
}

/// Takes `dir` for a command that writes results of `kind`: the lock, then a refusal if the
/// directory holds another kind's results.
pub fn claim(dir: &Path, kind: Kind, command: &str) -> Result<Lock, OutDirError> {
    let lock = Lock::acquire(dir, command)?;
    if let Some((found, marker)) = holds(dir) {
        if found != kind {
            return Err(OutDirError::OtherKind {
                dir: dir.to_path_buf(),
                found,
                marker,
                want: kind,
            });
        }
    }
    Ok(lock)
}

/// Takes `dir` for a run and removes the files of an earlier run there ([`Lock::replaced`]
/// counts them).
pub fn claim_run(dir: &Path, command: &str) -> Result<Lock, OutDirError> {
    let mut lock = claim(dir, Kind::Run, command)?;
    let n = clear_run(dir)?;
    if n > 0 {
        tracing::info!("{}: {n} files of an earlier run removed", dir.display());
    }
    lock.replaced = n;
    Ok(lock)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("tiltsim-outdir-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn only_the_named_files_and_their_temporaries_are_matched() {
        let n = names(&["summary.json"]);
        assert!(is_named("summary.json", &n));
        assert!(is_named(".summary.json.1234.tmp", &n));
        assert!(!is_named(".summary.json.tmp", &n));
        assert!(!is_named(".summary.json.12a.tmp", &n));
        assert!(!is_named("summary.json.bak", &n));
        assert!(!is_named("my-summary.json", &n));
    }

    #[test]
    fn a_held_directory_is_refused_and_released_on_drop() {
        let d = temp("held");
        let a = Lock::acquire(&d, "run").unwrap();
        // A second open file description of the same process is refused by flock.
        let e = Lock::acquire(&d, "run").unwrap_err();
        assert!(matches!(e, OutDirError::InUse { .. }), "{e}");
        assert!(
            e.to_string()
                .contains(&format!("pid {}", std::process::id())),
            "{e}"
        );
        drop(a);
        assert!(!d.join(LOCK_FILE).exists());
        let b = Lock::acquire(&d, "run").unwrap();
        drop(b);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn clearing_a_run_removes_its_files_and_leaves_the_users() {
        let d = temp("clear");
        std::fs::create_dir_all(d.join("plots")).unwrap();
        std::fs::create_dir_all(d.join("replay-plant")).unwrap();
        std::fs::create_dir_all(d.join("logs")).unwrap();
        for f in [
            "run.mcap",
            "trace.csv",
            "timing.csv",
            ".summary.json.77.tmp",
            "notes.txt",
            "plots/body_roll.png",
            "plots/mine.svg",
            "replay-plant/replay.json",
            "replay-plant/plant-out.jsonl",
            "logs/plant.log",
            "logs/controller.log",
        ] {
            std::fs::write(d.join(f), "x").unwrap();
        }
        assert_eq!(clear_run(&d).unwrap(), 9);
        // Claimed again, the directory holds no earlier run; with a run's file, it does.
        assert_eq!(claim_run(&d, "run").unwrap().replaced(), 0);
        std::fs::write(d.join("summary.json"), "{}").unwrap();
        assert_eq!(claim_run(&d, "run").unwrap().replaced(), 1);
        assert!(d.join("notes.txt").exists() && d.join("plots/mine.svg").exists());
        assert!(!d.join("run.mcap").exists() && !d.join("replay-plant").exists());
        assert!(!d.join("timing.csv").exists());
        assert!(!d.join("logs").exists());
        let _ = std::fs::remove_dir_all(&d);
    }
}
