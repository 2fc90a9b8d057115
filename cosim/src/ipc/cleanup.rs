//! The run's files in shared memory and in iceoryx2's directories: listed and removed by the
//! run's unique prefix, never another run's.

use std::path::{Path, PathBuf};

use super::config;

pub use tiltsim_protocol::process::{boot_id, start_ticks, Owner};

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

/// Removes every file this run's prefix left in the iceoryx2 directories and in `/dev/shm`,
/// and a node directory (`nodes/<node id>/`) that this leaves empty. Returns how many files
/// were removed. Called last, after every node is gone.
pub fn remove_run_files(prefix: &str) -> usize {
    remove_files_of(prefix, &[])
}

/// [`remove_run_files`], keeping the files of the live runs whose (longer) prefixes begin with
/// `prefix`.
fn remove_files_of(prefix: &str, live: &[&str]) -> usize {
    let mut files = leftover_files(prefix);
    files.retain(|p| {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
        !live
            .iter()
            .any(|l| l.len() > prefix.len() && name.as_deref().is_some_and(|n| n.starts_with(l)))
    });
    let removed = files
        .iter()
        .filter(|p| {
            if p.is_dir() {
                std::fs::remove_dir_all(p).is_ok()
            } else {
                std::fs::remove_file(p).is_ok()
            }
        })
        .count();
    for p in &files {
        if let Some(node_dir) = p.parent() {
            let in_nodes = node_dir
                .parent()
                .and_then(|d| d.file_name())
                .is_some_and(|n| n == "nodes");
            if in_nodes {
                // Fails, and leaves it, if anything of another node is in it.
                let _ = std::fs::remove_dir(node_dir);
            }
        }
    }
    removed
}

/// The end of the name of a run's owner file, `/dev/shm/<prefix>tiltsim-owner`.
const OWNER_FILE: &str = "tiltsim-owner";

/// Records this process as the owner of the files of `prefix` (`/dev/shm/<prefix>tiltsim-owner`:
/// its pid, start time and boot), so that [`remove_dead_runs`] removes them once it is gone,
/// whatever the prefix. The file is written whole (a temporary renamed into place) and goes
/// with the run's other files ([`remove_run_files`]).
pub fn claim_prefix(prefix: &str) -> std::io::Result<()> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static CLAIMS: AtomicU64 = AtomicU64::new(0);
    let o = Owner::me();
    let n = CLAIMS.fetch_add(1, Ordering::Relaxed);
    let tmp = format!("/dev/shm/.tiltsim-owner-{}-{n}", o.pid);
    std::fs::write(&tmp, format!("{} {} {}\n", o.pid, o.start_ticks, o.boot_id))?;
    std::fs::rename(&tmp, format!("/dev/shm/{prefix}{OWNER_FILE}")).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

/// The prefixes of the owner files in `dir`, each with whether its owner is dead; a file that
/// cannot be read or parsed counts as live (never remove what may be in use).
fn owned_prefixes(dir: &Path) -> Vec<(String, bool)> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_str()?.to_string();
            let prefix = name.strip_suffix(OWNER_FILE)?.to_string();
            let dead = std::fs::read_to_string(e.path())
                .ok()
                .and_then(|t| Owner::parse(&t))
                .is_some_and(|o| o.is_dead());
            (!prefix.is_empty()).then_some((prefix, dead))
        })
        .collect()
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
    // A default prefix names its owner's pid; any prefix may have an owner file, which also
    // tells a dead owner whose pid was reused.
    let owned = owned_prefixes(Path::new("/dev/shm"));
    let mut dead: Vec<String> = found
        .iter()
        .filter_map(|n| owner(n).map(|pid| (pid, n)))
        .filter(|(pid, _)| *pid > 0 && !alive(*pid))
        .map(|(pid, _)| format!("tiltsim_{pid}_"))
        .chain(owned.iter().filter(|o| o.1).map(|o| o.0.clone()))
        .collect();
    dead.sort();
    dead.dedup();
    let live: Vec<&str> = owned
        .iter()
        .filter(|o| !o.1)
        .map(|o| o.0.as_str())
        .collect();
    for p in &dead {
        remove_files_of(p, &live);
    }
    if let Ok(cfg) = config("tiltsim_") {
        remove_abandoned_node_dirs(Path::new(&cfg.global.root_path().to_string()));
    }
    dead
}

/// How long a node directory must have been empty before it counts as abandoned. A live node
/// keeps its `node.details` file in it from its first microseconds to its last; only a node
/// whose process was killed between removing its files and its directory leaves it empty.
const ABANDONED_AFTER: std::time::Duration = std::time::Duration::from_secs(5);

/// Removes the empty node directories (`<root>/nodes/<node id>/`) unchanged for
/// [`ABANDONED_AFTER`]: what remains of a participant whose files were removed (by itself or
/// by [`remove_dead_runs`]) but not its directory. A directory with anything in it is never
/// touched (`remove_dir` refuses it too). Returns how many were removed.
fn remove_abandoned_node_dirs(root: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(root.join("nodes")) else {
        return 0;
    };
    let mut removed = 0;
    for e in entries.flatten() {
        let path = e.path();
        let numeric = e
            .file_name()
            .to_str()
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
        let Ok(meta) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        let old = meta
            .modified()
            .ok()
            .and_then(|m| m.elapsed().ok())
            .is_some_and(|age| age >= ABANDONED_AFTER);
        let empty = std::fs::read_dir(&path).is_ok_and(|mut d| d.next().is_none());
        if numeric && meta.is_dir() && old && empty && std::fs::remove_dir(&path).is_ok() {
            removed += 1;
        }
    }
    removed
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
    fn an_empty_node_directory_is_removed_once_abandoned_and_a_full_or_new_one_never() {
        let root = std::env::temp_dir().join(format!("tiltsim-nodes-{}", std::process::id()));
        let nodes = root.join("nodes");
        let (empty_old, full_old, empty_new, named) = (
            nodes.join("111"),
            nodes.join("222"),
            nodes.join("333"),
            nodes.join("not-a-node"),
        );
        for d in [&empty_old, &full_old, &empty_new, &named] {
            std::fs::create_dir_all(d).unwrap();
        }
        std::fs::write(full_old.join("x_node.details"), b"").unwrap();
        let long_ago = std::time::SystemTime::now() - 2 * ABANDONED_AFTER;
        for d in [&empty_old, &full_old, &named] {
            std::fs::File::open(d)
                .unwrap()
                .set_modified(long_ago)
                .unwrap();
        }
        assert_eq!(remove_abandoned_node_dirs(&root), 1);
        assert!(!empty_old.exists());
        assert!(full_old.exists() && empty_new.exists() && named.exists());
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_dead_owner_of_any_prefix_has_its_files_removed_and_a_live_longer_prefix_kept() {
        let pfx = format!("custom_{}_cleanup_", std::process::id());
        let shm = |name: &str| PathBuf::from(format!("/dev/shm/{pfx}{name}"));
        // The live run: this process owns `<pfx>live_`.
        claim_prefix(&format!("{pfx}live_")).unwrap();
        std::fs::write(shm("live_data"), b"x").unwrap();
        // The dead one: this pid, but a start time no process of this pid has.
        let me = Owner::me();
        let ghost = format!("{} {} {}\n", me.pid, me.start_ticks + 1, me.boot_id);
        std::fs::write(shm(OWNER_FILE), ghost).unwrap();
        std::fs::write(shm("data"), b"x").unwrap();
        let dead = remove_dead_runs();
        assert!(dead.contains(&pfx), "{dead:?}");
        assert!(!shm("data").exists() && !shm(OWNER_FILE).exists());
        assert!(shm("live_data").exists() && shm(&format!("live_{OWNER_FILE}")).exists());
        // The live run's own clean-up takes its owner file with its other files.
        assert_eq!(remove_run_files(&format!("{pfx}live_")), 2);
        assert!(leftover_files(&pfx).is_empty());
    }

    #[test]
    fn the_start_time_of_this_process_is_read_from_proc() {
        let t = start_ticks(std::process::id()).unwrap();
        assert!(t > 0);
        // A child started after this process started later (or in the same tick).
        let mut child = std::process::Command::new("sleep")
            .arg("5")
            .spawn()
            .unwrap();
        let c = start_ticks(child.id()).unwrap();
        let _ = child.kill();
        let _ = child.wait();
        assert!(c >= t, "{c} < {t}");
    }
    #[test]
    fn an_owner_file_names_one_process_of_one_boot() {
        let me = Owner::me();
        let text = format!("{} {} {}\n", me.pid, me.start_ticks, me.boot_id);
        assert_eq!(Owner::parse(&text), Some(me.clone()));
        assert!(!me.is_dead());
        assert!(Owner {
            start_ticks: me.start_ticks + 1,
            ..me.clone()
        }
        .is_dead());
        assert!(Owner {
            boot_id: "another-boot".into(),
            ..me.clone()
        }
        .is_dead());
        assert_eq!(Owner::parse("12 34"), None);
        assert_eq!(Owner::parse("12 34 b extra"), None);
    }

    #[test]
    fn only_default_prefixes_name_an_owner() {
        assert_eq!(owner("tiltsim_1234_0abc_0_plant.req"), Some(1234));
        assert_eq!(owner("tiltsim_test_faults_99_x"), None);
        assert_eq!(owner("other_1234_"), None);
        assert!(alive(std::process::id() as i32));
    }
}
