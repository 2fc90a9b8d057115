//! Where the participants' standard error goes: a file per participant, never a pipe, so a
//! participant that writes a lot never waits for a reader (and is never judged stalled for it),
//! and the orchestrator's own standard error is not shared with it.

use std::fs::File;
use std::io::{Read as _, Seek as _, SeekFrom};
use std::path::{Path, PathBuf};

use crate::participant::Role;

/// The directory of a hub's participant logs.
#[derive(Debug)]
pub(super) enum LogDir {
    /// The run's own directory (`IpcHub::logs_into`): what is written there stays for the
    /// run's owner to sort out (remove the empty ones, report the others).
    Run(PathBuf),
    /// A directory of this hub under the system's temporary directory, for callers without
    /// an output directory: removed with everything in it when the hub is dropped.
    Scratch(PathBuf),
}

impl LogDir {
    /// The scratch directory of the hub of the run with `prefix`.
    pub(super) fn scratch(prefix: &str) -> Self {
        LogDir::Scratch(std::env::temp_dir().join(format!("tiltsim-logs-{prefix}")))
    }

    /// The directory.
    pub(super) fn path(&self) -> &Path {
        match self {
            LogDir::Run(p) | LogDir::Scratch(p) => p,
        }
    }

    /// Creates (or empties) the log of `role` and opens it for the participant's standard
    /// error; an error names the file.
    pub(super) fn open(&self, role: Role) -> std::io::Result<(PathBuf, File)> {
        let path = log_file(self.path(), role);
        let named =
            |e: std::io::Error| std::io::Error::new(e.kind(), format!("{}: {e}", path.display()));
        std::fs::create_dir_all(self.path()).map_err(named)?;
        let file = File::create(&path).map_err(named)?;
        Ok((path, file))
    }
}

impl Drop for LogDir {
    fn drop(&mut self) {
        if let LogDir::Scratch(dir) = self {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// The log of `role` in `dir`: `dir/ROLE.log`.
pub(super) fn log_file(dir: &Path, role: Role) -> PathBuf {
    dir.join(format!("{}.log", role.name()))
}

/// The last non-blank line of the file at `path` (read from its last 4 KiB, cut to 300
/// characters), if it has one.
pub(super) fn last_line(path: &Path) -> Option<String> {
    const TAIL: u64 = 4096;
    const WIDTH: usize = 300;
    let mut f = File::open(path).ok()?;
    let len = f.metadata().ok()?.len();
    f.seek(SeekFrom::Start(len.saturating_sub(TAIL))).ok()?;
    let mut bytes = Vec::new();
    f.read_to_end(&mut bytes).ok()?;
    let text = String::from_utf8_lossy(&bytes);
    let line = text.lines().rev().map(str::trim).find(|l| !l.is_empty())?;
    Some(line.chars().take(WIDTH).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scratch_directory_goes_with_its_logs_and_the_last_line_is_found() {
        let logs = LogDir::scratch(&format!("logs-test-{}", std::process::id()));
        let dir = logs.path().to_path_buf();
        let (path, _) = logs.open(Role::Plant).unwrap();
        assert_eq!(path, dir.join("plant.log"));
        assert_eq!(last_line(&path), None);
        let long = "x".repeat(10_000);
        std::fs::write(&path, format!("{long}\nthe reason\n\n  \n")).unwrap();
        assert_eq!(last_line(&path).as_deref(), Some("the reason"));
        drop(logs);
        assert!(!dir.exists());
    }
}
