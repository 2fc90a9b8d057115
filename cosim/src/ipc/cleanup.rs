//! The run's files in shared memory and in iceoryx2's directories: listed and removed by the
//! run's unique prefix, never another run's.

use std::path::{Path, PathBuf};

use super::config;

/// The directories a run's files can be in: `/dev/shm` (top level only) and iceoryx2's root
/// directory (with its service and node directories, searched a few levels deep).
fn roots(prefix: &str) -> Vec<(PathBuf, u32)> {
    let mut dirs = vec![(PathBuf::from("/dev/shm"), 0)];
    if let Ok(cfg) = config(prefix) {
        dirs.push((PathBuf::from(cfg.global.root_path().to_string()), 4));
    }
    dirs
}

/// Every entry under `dir` (down to `depth` more levels) whose name starts with `prefix`.
fn walk(dir: &Path, prefix: &str, depth: u32, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        if e.file_name().to_string_lossy().starts_with(prefix) {
            out.push(path);
        } else if depth > 0 && path.is_dir() && !path.is_symlink() {
            walk(&path, prefix, depth - 1, out);
        }
    }
}

/// Lists the files a run's prefix still has on disk (for tests and leak reports).
pub fn leftover_files(prefix: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for (dir, depth) in roots(prefix) {
        walk(&dir, prefix, depth, &mut out);
    }
    out
}

/// Removes every file this run's prefix left in the iceoryx2 directories and in `/dev/shm`.
/// Returns how many were removed. Called last, after every node is gone.
pub fn remove_run_files(prefix: &str) -> usize {
    leftover_files(prefix)
        .iter()
        .filter(|p| {
            if p.is_dir() {
                std::fs::remove_dir_all(p).is_ok()
            } else {
                std::fs::remove_file(p).is_ok()
            }
        })
        .count()
}

/// The owner's pid of a default run prefix `tiltsim_<pid>_<nonce>_<n>_` at the start of `name`
/// (files of test prefixes and of other programs are not recognised).
fn owner(name: &str) -> Option<i32> {
    let rest = name.strip_prefix("tiltsim_")?;
    let (digits, _) = rest.split_once('_')?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// Whether process `pid` exists (signal 0 probes without sending).
fn alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 only checks that the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

/// Removes the files of every run whose owner, the orchestrator whose pid its prefix
/// carries, no longer exists (killed before it could clean up); never a live run's. Returns
/// the prefixes cleaned.
pub fn remove_dead_runs() -> Vec<String> {
    let mut found = Vec::new();
    for (dir, depth) in roots("tiltsim_") {
        walk_names(&dir, depth, &mut found);
    }
    let mut dead: Vec<String> = found
        .iter()
        .filter_map(|n| owner(n).map(|pid| (pid, n)))
        .filter(|(pid, _)| *pid > 0 && !alive(*pid))
        .map(|(pid, _)| format!("tiltsim_{pid}_"))
        .collect();
    dead.sort();
    dead.dedup();
    for p in &dead {
        remove_run_files(p);
    }
    dead
}

/// The names of every entry under `dir`, down to `depth` more levels.
fn walk_names(dir: &Path, depth: u32, out: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        out.push(e.file_name().to_string_lossy().into_owned());
        if depth > 0 && path.is_dir() && !path.is_symlink() {
            walk_names(&path, depth - 1, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_default_prefixes_name_an_owner() {
        assert_eq!(owner("tiltsim_1234_0abc_0_plant.req"), Some(1234));
        assert_eq!(owner("tiltsim_test_faults_99_x"), None);
        assert_eq!(owner("other_1234_"), None);
        assert!(alive(std::process::id() as i32));
    }
}
