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
