//! A participant that dies or stalls, and Ctrl-C: detected, named, the run ends cleanly with
//! its rows on disk and no shared-memory files left. A participant that writes a lot to its
//! standard error is not held up by it.

use std::time::Duration;

use tiltsim_suite::{
    children_of, leftovers, prefix, scenario, summary, temp_dir, wait_for, wait_with_limit, Series,
    Tiltsim,
};

/// Starts a long IPC run, waits until `victim` runs and rows are being written; returns the
/// child, its participants and the output directory.
fn start_long_run(
    name: &str,
    more: impl FnOnce(Tiltsim) -> Tiltsim,
) -> (
    std::process::Child,
    Vec<(u32, String)>,
    std::path::PathBuf,
    String,
) {
    let pfx = prefix(name);
    let (child, kids, dir) = start_long_ipc_run(name, |cmd| more(cmd.ipc_prefix(&pfx)));
    (child, kids, dir, pfx)
}

/// Starts a long IPC run, its command completed by `more`, and waits until its three
/// participants run and rows are being written; returns the child, its participants and the
/// output directory.
fn start_long_ipc_run(
    name: &str,
    more: impl FnOnce(Tiltsim) -> Tiltsim,
) -> (std::process::Child, Vec<(u32, String)>, std::path::PathBuf) {
    let dir = temp_dir(name);
    let cmd = Tiltsim::run("paper-passive.toml")
        .out(&dir)
        .transport_ipc()
        .duration(3600)
        .quiet();
    let mut child = more(cmd).spawn();
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
    // every tick that the summary counts is on disk, complete, after the row at the start
    let series = Series::read(&dir.join("timeseries.csv"));
    assert_eq!(series.rows.len() as u64, rows + 1);
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

/// How long a run that has seen its failure may take to end, its analysis and figures
/// included: long enough for a machine loaded by other work, so that only a hang exceeds it.
const ENDS_WITHIN: Duration = Duration::from_secs(300);

#[test]
fn a_killed_participant_is_detected_named_and_the_run_ends_cleanly() {
    let (child, kids, dir, pfx) = start_long_run("killed", |c| c);
    let victim = pid_of(&kids, "actuator-proc");
    unsafe { libc::kill(victim as i32, libc::SIGKILL) };
    let (code, _, err) = wait_with_limit(child, ENDS_WITHIN);
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
fn an_actuator_killed_with_its_next_request_queued_is_replaced_and_the_run_goes_on() {
    // Under Jacobi over IPC the actuator's next request waits in its queue while it computes
    // the current one; killed from outside, it dies with both. The stand-in answers both and
    // the run goes on, degraded, until Ctrl-C.
    let (child, kids, dir, pfx) = start_long_run("killed-ahead", |c| {
        c.master("jacobi").set("faults.on_failure", "degrade")
    });
    let victim = pid_of(&kids, "actuator-proc");
    let csv = dir.join("timeseries.csv");
    let size = || std::fs::metadata(&csv).map_or(0, |m| m.len());
    let at_kill = size();
    unsafe { libc::kill(victim as i32, libc::SIGKILL) };
    // Rows go on after the loss; a run that failed on it has ended.
    let mut child = child;
    let went_on = wait_for(Duration::from_secs(600), || {
        if matches!(child.try_wait(), Ok(Some(_))) {
            return Some(false);
        }
        (size() > at_kill + 1_000_000).then_some(true)
    });
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let (code, _, err) = wait_with_limit(child, ENDS_WITHIN);
    assert_eq!(went_on, Some(true), "no rows after the loss; stderr: {err}");
    assert_eq!(code, 130, "stderr: {err}");
    let events = dir.join("events.csv");
    let rows = assert_clean_end(&dir, &pfx, &kids, "interrupted");
    let s = summary(&dir);
    assert!(
        s["participants"][1]["exit"]["status"]
            .as_str()
            .unwrap()
            .contains("signal 9"),
        "{s}"
    );
    // The stand-in's rows follow the loss: the tick it was lost at is recorded, and more.
    let e = std::fs::read_to_string(&events).unwrap();
    let at: u64 = e
        .lines()
        .find(|l| l.contains("actuator,participant-lost"))
        .and_then(|l| l.split(',').nth(1)?.parse().ok())
        .unwrap_or_else(|| panic!("{e}"));
    assert!(rows > at, "rows {rows}, lost at tick {at}");
    assert!(e.contains("actuator,degraded,,bar ramps to neutral"), "{e}");
}

#[test]
fn a_stalled_participant_is_declared_at_its_deadline() {
    let (child, kids, dir, pfx) = start_long_run("stalled", |c| c.deadline_ms(200));
    let victim = pid_of(&kids, "plant-proc");
    unsafe { libc::kill(victim as i32, libc::SIGSTOP) };
    let (code, _, err) = wait_with_limit(child, ENDS_WITHIN);
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
    let (child, kids, dir, pfx) = start_long_run("interrupt", |c| c);
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let (code, _, err) = wait_with_limit(child, ENDS_WITHIN);
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
    let (child, kids, dir, pfx) = start_long_run("sigterm", |c| c);
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let (code, _, err) = wait_with_limit(child, ENDS_WITHIN);
    assert_eq!(code, 130, "stderr: {err}");
    assert_clean_end(&dir, &pfx, &kids, "interrupted");
    assert_eq!(summary(&dir)["error"], "interrupted by SIGTERM");
    // Log lines reach a pipe without colour codes.
    assert!(!err.contains('\u{1b}'), "{err}");
}

#[test]
fn a_killed_orchestrator_leaves_a_readable_series_and_its_files_are_removed_by_the_next_run() {
    // The run's default prefix carries its owner's pid.
    let (child, kids, dir) = start_long_ipc_run("orchestrator-killed", |c| c);
    let pid = child.id();
    let pfx = format!("tiltsim_{pid}_");
    let csv = dir.join("timeseries.csv");
    let sc = scenario("paper-passive.toml");
    unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    let (code, _, _) = wait_with_limit(child, ENDS_WITHIN);
    assert_ne!(code, 0);
    // Its participants follow it (parent-death signal).
    for (p, comm) in &kids {
        let gone = wait_for(ENDS_WITHIN, || {
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
    assert_eq!(t[0][..2], ["time", "step"]);
    assert!(t.len() > 1000);
    assert!(t[1..t.len() - 1].iter().all(|r| r.len() == width));
    let (code, _, err) = tiltsim_suite::run(&["plot", dir.to_str().unwrap()]);
    assert_eq!(code, 0, "the killed run's series reads back: {err}");
    // The next IPC run removes the dead run's files, and only those.
    let other = temp_dir("after-kill");
    let live = prefix("after-kill");
    Tiltsim::run(&sc)
        .out(&other)
        .transport_ipc()
        .ipc_prefix(&live)
        .duration(0.2)
        .quiet()
        .success();
    assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
    assert!(leftovers(&live).is_empty());
    // `tiltsim clean` finds nothing left.
    let (code, out, _) = tiltsim_suite::run(&["clean"]);
    assert_eq!(code, 0);
    assert!(!out.contains(&pfx), "{out}");
}

#[test]
fn a_run_killed_whole_under_a_prefix_of_its_own_is_removed_by_tiltsim_clean() {
    // A prefix that names no pid: only the run's owner file tells that its owner is gone.
    let (child, kids, _dir, pfx) = start_long_run("killed-whole", |c| c);
    let mut all: Vec<u32> = kids.iter().map(|k| k.0).collect();
    all.push(child.id());
    for p in &all {
        unsafe { libc::kill(*p as i32, libc::SIGKILL) };
    }
    let (code, _, _) = wait_with_limit(child, Duration::from_secs(120));
    assert_ne!(code, 0);
    for (p, comm) in &kids {
        let gone = wait_for(Duration::from_secs(120), || {
            (!std::path::Path::new(&format!("/proc/{p}")).exists()).then_some(())
        });
        assert!(gone.is_some(), "{comm} ({p}) still runs");
    }
    // No one cleaned up; `tiltsim clean` (or another test's IPC run starting meanwhile)
    // removes every file of the prefix.
    let (code, out, err) = tiltsim_suite::run(&["clean"]);
    assert_eq!(code, 0, "{out}{err}");
    assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
}

#[test]
fn a_participant_that_writes_a_lot_is_not_held_up_and_its_output_is_kept_in_its_log() {
    let dir = temp_dir("chatter");
    let pfx = prefix("chatter");
    let sc = scenario("paper-passive.toml");
    let exe = env!("CARGO_BIN_EXE_faulty-plant");
    let bytes = 1 << 20;
    let go = |chatter: Option<usize>| {
        let mut cmd = Tiltsim::run(&sc)
            .out(&dir)
            .transport_ipc()
            .ipc_prefix(&pfx)
            .duration(0.2)
            .participant_exe("plant", exe)
            .quiet();
        if let Some(n) = chatter {
            cmd = cmd.env("TILTSIM_STDERR_BYTES", n.to_string());
        }
        // The orchestrator's standard error is a pipe read only after it ends: a participant
        // writing there would fill it (64 KiB) and wait forever.
        let child = cmd.spawn();
        let (code, _, err) = wait_with_limit(child, Duration::from_secs(600));
        assert_eq!(code, 0, "{err}");
        assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
        summary(&dir)
    };
    let s = go(Some(bytes));
    assert_eq!(s["status"], "completed");
    assert_eq!(s["participant_logs"], serde_json::json!(["logs/plant.log"]));
    let log = std::fs::read_to_string(dir.join("logs/plant.log")).unwrap();
    assert_eq!(log.len(), bytes);
    assert!(log.ends_with(&format!("faulty plant: wrote {bytes} bytes\n")));
    // The others wrote nothing: their empty logs are gone.
    assert!(!dir.join("logs/actuator.log").exists());
    assert!(!dir.join("logs/controller.log").exists());
    // A quiet run into the same directory leaves no logs, and none of the earlier run's.
    let s = go(None);
    assert_eq!(s["status"], "completed");
    assert!(s.get("participant_logs").is_none(), "{s}");
    assert!(!dir.join("logs").exists());
}

/// `paper-passive` with its plant played by an exported FMU that carries `bytes` of zeros as
/// a resource (deflated, so the archive stays small while its unpacking writes them all).
fn scenario_with_a_large_fmu(dir: &std::path::Path, bytes: u64) -> std::path::PathBuf {
    use std::io::Write;
    let sc = scenario("paper-passive.toml");
    let fmu = dir.join("plant.fmu");
    let (code, _, err) = tiltsim_suite::run(&[
        "export-fmu",
        "plant",
        sc.to_str().unwrap(),
        "--out",
        fmu.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&fmu)
        .unwrap();
    let mut z = zip::ZipWriter::new_append(file).unwrap();
    let o = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .compression_level(Some(1))
        .large_file(true);
    z.start_file("resources/zeros.bin", o).unwrap();
    let chunk = vec![0u8; 1 << 24];
    for _ in 0..bytes / chunk.len() as u64 {
        z.write_all(&chunk).unwrap();
    }
    z.finish().unwrap();
    let text =
        std::fs::read_to_string(&sc).unwrap() + "\n[participants.plant]\nfmu = \"plant.fmu\"\n";
    let path = dir.join("large-fmu.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The directories FMUs are being unpacked into by `pids`.
fn unpacking_by(pids: &[u32]) -> Vec<std::path::PathBuf> {
    std::fs::read_dir(std::env::temp_dir())
        .unwrap()
        .flatten()
        .filter(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.strip_prefix("tiltsim-fmu-")
                .and_then(|r| r.split('-').next()?.parse::<u32>().ok())
                .is_some_and(|p| pids.contains(&p))
        })
        .map(|e| e.path())
        .collect()
}

#[test]
fn ctrl_c_while_an_fmu_unpacks_stops_it_and_leaves_nothing_unpacked() {
    let dir = temp_dir("unpack-interrupt");
    // 4 GiB to write: seconds even on a fast disk, so the unpacking is under way when the
    // signal comes (the test waits for it to start, however slow the machine).
    let sc = scenario_with_a_large_fmu(&dir, 4 << 30);
    for transport in ["in-process", "ipc"] {
        let out = dir.join(transport);
        let child = Tiltsim::run(&sc)
            .transport(transport)
            .out(&out)
            .duration(1)
            .spawn();
        let pid = child.id();
        // In process the orchestrator unpacks; over IPC the plant's process does.
        let started = wait_for(Duration::from_secs(600), || {
            let mut pids: Vec<u32> = children_of(pid).iter().map(|k| k.0).collect();
            pids.push(pid);
            let dirs = unpacking_by(&pids);
            (!dirs.is_empty()).then_some((pids, dirs))
        });
        let Some((pids, dirs)) = started else {
            let _ = wait_with_limit(child, Duration::from_secs(1));
            panic!("{transport}: the FMU's unpacking never started");
        };
        unsafe { libc::kill(pid as i32, libc::SIGINT) };
        let (code, _, err) = wait_with_limit(child, Duration::from_secs(300));
        assert_eq!(code, 130, "{transport}: {err}");
        assert!(
            err.contains("interrupted by Ctrl-C (SIGINT) while participant plant was starting"),
            "{transport}: {err}"
        );
        assert!(
            dirs.iter().all(|d| !d.exists()),
            "{transport}: {dirs:?} left"
        );
        assert!(unpacking_by(&pids).is_empty(), "{transport}");
    }
}
