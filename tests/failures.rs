//! A participant that dies or stalls, and Ctrl-C: detected, named, the run ends cleanly with
//! its rows on disk and no shared-memory files left.

use std::time::Duration;

use tiltsim_suite::{
    children_of, leftovers, prefix, scenario, spawn, summary, temp_dir, wait_for, wait_with_limit,
    Series,
};

/// Starts a long IPC run, waits until `victim` runs and rows are being written; returns the
/// child, its participants and the output directory.
fn start_long_run(
    name: &str,
    extra: &[&str],
) -> (
    std::process::Child,
    Vec<(u32, String)>,
    std::path::PathBuf,
    String,
) {
    let pfx = prefix(name);
    let mut args = vec!["--ipc-prefix", &pfx];
    args.extend(extra);
    let (child, kids, dir) = start_long_ipc_run(name, &args);
    (child, kids, dir, pfx)
}

/// Starts a long IPC run with `extra` arguments and waits until its three participants run and
/// rows are being written; returns the child, its participants and the output directory.
fn start_long_ipc_run(
    name: &str,
    extra: &[&str],
) -> (std::process::Child, Vec<(u32, String)>, std::path::PathBuf) {
    let dir = temp_dir(name);
    let sc = scenario("paper-passive.toml");
    let mut args = vec![
        "run",
        sc.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
        "--transport",
        "ipc",
        "--duration",
        "3600",
        "-q",
    ];
    args.extend(extra);
    let mut child = spawn(&args);
    let pid = child.id();
    // Bounds against a test that never gets going, not verdicts on speed: on a machine busy
    // with other work the start and the first megabyte of rows take minutes.
    let kids = wait_for(Duration::from_secs(600), || {
        let k = children_of(pid);
        (k.len() == 3).then_some(k)
    });
    let csv = dir.join("timeseries.csv");
    let rows = wait_for(Duration::from_secs(600), || {
        (std::fs::metadata(&csv).ok()?.len() > 1_000_000).then_some(())
    });
    match (kids, rows) {
        (Some(kids), Some(())) => (child, kids, dir),
        (kids, _) => {
            // Never leave an hour-long run behind a failed test.
            let _ = child.kill();
            let _ = child.wait();
            panic!("{name}: participants {kids:?}; rows not recorded within 600 s");
        }
    }
}

fn pid_of(kids: &[(u32, String)], comm: &str) -> u32 {
    kids.iter()
        .find(|(_, c)| c == comm)
        .unwrap_or_else(|| panic!("no {comm} in {kids:?}"))
        .0
}

fn assert_clean_end(dir: &std::path::Path, pfx: &str, kids: &[(u32, String)], status: &str) -> u64 {
    let s = summary(dir);
    assert_eq!(s["status"], status);
    let rows = s["steps_completed"].as_u64().unwrap();
    // The victim was stopped only after more than 1 MB (well over 1000 rows of ~500 bytes) was
    // on disk; all of it must still be there.
    assert!(rows >= 1000, "rows recorded so far must be kept ({rows})");
    // every row that the summary counts is on disk, complete
    let series = Series::read(&dir.join("timeseries.csv"));
    assert_eq!(series.rows.len() as u64, rows);
    assert!(
        leftovers(pfx).is_empty(),
        "shared-memory files left: {:?}",
        leftovers(pfx)
    );
    for (pid, comm) in kids {
        assert!(
            !std::path::Path::new(&format!("/proc/{pid}")).exists(),
            "{comm} ({pid}) still exists"
        );
    }
    rows
}

#[test]
fn a_killed_participant_is_detected_named_and_the_run_ends_cleanly() {
    let (child, kids, dir, pfx) = start_long_run("killed", &[]);
    let victim = pid_of(&kids, "actuator-proc");
    unsafe { libc::kill(victim as i32, libc::SIGKILL) };
    let (code, _, err) = wait_with_limit(child, Duration::from_secs(10));
    assert_eq!(code, 1, "stderr: {err}");
    assert!(
        err.contains("participant actuator")
            && err.contains(&victim.to_string())
            && err.contains("step"),
        "{err}"
    );
    assert!(err.contains("signal 9"), "{err}");
    assert_clean_end(&dir, &pfx, &kids, "failed");
}

#[test]
fn a_stalled_participant_is_declared_at_its_deadline() {
    let (child, kids, dir, pfx) = start_long_run("stalled", &["--deadline-ms", "200"]);
    let victim = pid_of(&kids, "plant-proc");
    unsafe { libc::kill(victim as i32, libc::SIGSTOP) };
    let (code, _, err) = wait_with_limit(child, Duration::from_secs(10));
    assert_eq!(code, 1, "stderr: {err}");
    assert!(
        err.contains("participant plant")
            && err.contains("did not answer step")
            && err.contains("200 ms"),
        "{err}"
    );
    assert_clean_end(&dir, &pfx, &kids, "failed");
}

#[test]
fn ctrl_c_ends_the_run_cleanly() {
    let (child, kids, dir, pfx) = start_long_run("interrupt", &[]);
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let (code, _, err) = wait_with_limit(child, Duration::from_secs(10));
    assert_eq!(code, 130, "stderr: {err}");
    let rows = assert_clean_end(&dir, &pfx, &kids, "interrupted");
    // participants were stopped politely, not killed
    let s = summary(&dir);
    for p in s["participants"].as_array().unwrap() {
        assert_eq!(p["exit"]["status"], "exit code 0", "{p}");
    }
    assert!(rows < 3_600_000);
    assert_eq!(s["error"], "interrupted by Ctrl-C (SIGINT)");
}

#[test]
fn sigterm_ends_the_run_cleanly_and_is_named() {
    let (child, kids, dir, pfx) = start_long_run("sigterm", &[]);
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let (code, _, err) = wait_with_limit(child, Duration::from_secs(10));
    assert_eq!(code, 130, "stderr: {err}");
    assert_clean_end(&dir, &pfx, &kids, "interrupted");
    assert_eq!(summary(&dir)["error"], "interrupted by SIGTERM");
    // Log lines reach a pipe without colour codes.
    assert!(!err.contains('\u{1b}'), "{err}");
}

#[test]
fn a_killed_orchestrator_leaves_a_readable_series_and_its_files_are_removed_by_the_next_run() {
    // The run's default prefix carries its owner's pid.
    let (child, kids, dir) = start_long_ipc_run("orchestrator-killed", &[]);
    let pid = child.id();
    let pfx = format!("tiltsim_{pid}_");
    let csv = dir.join("timeseries.csv");
    let sc = scenario("paper-passive.toml");
    unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    let (code, _, _) = wait_with_limit(child, Duration::from_secs(10));
    assert_ne!(code, 0);
    // Its participants follow it (parent-death signal).
    for (p, comm) in &kids {
        let gone = wait_for(Duration::from_secs(5), || {
            (!std::path::Path::new(&format!("/proc/{p}")).exists()).then_some(())
        });
        assert!(gone.is_some(), "{comm} ({p}) outlived its orchestrator");
    }
    // Its files are left behind (no one cleaned up); the next IPC run to start on this machine
    // (possibly another test's) removes them.
    // The series on disk: the header, then complete rows; only the very last line may be cut
    // (the kernel stops a write at a page boundary when the writer is killed), and tiltsim's
    // readers drop it.
    let text = std::fs::read_to_string(&csv).unwrap();
    let t = tiltsim_suite::csv_table(&text);
    let width = t[0].len();
    assert_eq!(t[0][0], "step");
    assert!(t.len() > 1000);
    assert!(t[1..t.len() - 1].iter().all(|r| r.len() == width));
    let (code, _, err) = tiltsim_suite::run(&["plot", dir.to_str().unwrap()]);
    assert_eq!(code, 0, "the killed run's series reads back: {err}");
    // The next IPC run removes the dead run's files, and only those.
    let other = temp_dir("after-kill");
    let live = prefix("after-kill");
    let (code, _, err) = tiltsim_suite::run(&[
        "run",
        sc.to_str().unwrap(),
        "--out",
        other.to_str().unwrap(),
        "--transport",
        "ipc",
        "--ipc-prefix",
        &live,
        "--duration",
        "0.2",
        "-q",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
    assert!(leftovers(&live).is_empty());
    // `tiltsim clean` finds nothing left.
    let (code, out, _) = tiltsim_suite::run(&["clean"]);
    assert_eq!(code, 0);
    assert!(!out.contains(&pfx), "{out}");
}
