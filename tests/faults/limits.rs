//! Command-line values and signals: every numeric option bounded (exit 2 naming it and its
//! range, never a panic), integers exact through `--set`, a signal to the whole process group
//! reported as an interruption, and nothing of a killed run left in shared memory.

use std::os::unix::process::CommandExt as _;
use std::path::Path;
use std::time::Duration;

use tiltsim_suite::{leftovers, prefix, scenario, temp_dir, wait_for, wait_with_limit, Tiltsim};

const BAD: [&str; 7] = [
    "1e-300",
    "1e300",
    "NaN",
    "inf",
    "-1",
    "0",
    "18446744073709551615",
];

#[test]
fn every_numeric_option_refuses_what_it_does_not_allow_naming_itself_and_its_range() {
    let sc = scenario("paper-passive.toml");
    let sc = sc.to_str().unwrap();
    // (command and positionals, option, values it refuses)
    let all = BAD.to_vec();
    let seed = vec![
        "1e-300",
        "1e300",
        "NaN",
        "inf",
        "-1",
        "18446744073709551616",
    ];
    let margin = vec!["1e300", "NaN", "inf", "-1", "18446744073709551615"];
    let spread = vec!["1e300", "NaN", "inf", "-1", "1", "18446744073709551615"];
    let cases: Vec<(Vec<&str>, &str, Vec<&str>)> = vec![
        (vec!["run", sc], "--pace", all.clone()),
        (vec!["run", sc], "--duration", all.clone()),
        (vec!["run", sc], "--deadline-ms", all.clone()),
        (vec!["run", sc], "--seed", seed.clone()),
        (vec!["sweep", sc], "--samples", all.clone()),
        (vec!["sweep", sc, "--samples", "2"], "--spread", spread),
        (vec!["sweep", sc, "--samples", "2"], "--seed", seed),
        (vec!["sweep", sc, "--samples", "2"], "--jobs", all.clone()),
        (vec!["sweep", sc, "--samples", "2"], "--shards", all.clone()),
        (vec!["bench", sc], "--duration", all.clone()),
        (vec!["bench", sc], "--repeat", all.clone()),
        (vec!["bench", sc, "--ping-pong"], "--rounds", all.clone()),
        (vec!["bench", sc, "--fmu"], "--fmu-runs", all.clone()),
        (
            vec!["linearize", sc, "--design-pi"],
            "--phase-margin",
            margin.clone(),
        ),
        (
            vec!["linearize", sc, "--design-pi"],
            "--gain-margin",
            margin,
        ),
        (vec!["linearize", sc, "--design-pi"], "--ti", all.clone()),
        (
            vec!["export-fmu", "plant", sc, "--out", "x.fmu"],
            "--fmi-version",
            all,
        ),
    ];
    for (cmd, option, values) in cases {
        for v in values {
            let mut args = cmd.clone();
            let with = format!("{option}={v}");
            args.push(&with);
            let (code, _, err) = tiltsim_suite::run(&args);
            assert_eq!(code, 2, "{args:?}: {err}");
            assert!(
                err.contains(option) && err.contains("allowed") && !err.contains("panicked"),
                "{args:?}: {err}"
            );
        }
    }
}

/// The first line of `dir/scenario.toml` that sets `key`.
fn setting(dir: &Path, key: &str) -> String {
    std::fs::read_to_string(dir.join("scenario.toml"))
        .unwrap()
        .lines()
        .find(|l| l.starts_with(&format!("{key} =")))
        .unwrap_or_default()
        .to_string()
}

#[test]
fn a_large_seed_arrives_exactly_through_set_and_one_beyond_u64_is_refused() {
    let sc = scenario("irregular-track.toml");
    let root = temp_dir("exact-seed");
    let run = |extra: &[&str], out: &str| {
        let out = root.join(out);
        let (code, _, err) = Tiltsim::run(&sc)
            .transport_in_process()
            .duration(0.5)
            .quiet()
            .out(&out)
            .args(extra)
            .result();
        (code, err, out)
    };
    // 2^53 + 1 is the first integer f64 cannot hold; 2^64 - 1 the largest u64.
    for seed in ["9007199254740993", "18446744073709551615"] {
        let set = format!("run.seed={seed}");
        let (code, err, by_set) = run(&["--set", &set], &format!("set-{seed}"));
        assert_eq!(code, 0, "{err}");
        assert_eq!(setting(&by_set, "seed"), format!("seed = {seed}"));
        // The same series as the exact --seed gives.
        let (code, err, by_flag) = run(&["--seed", seed], &format!("flag-{seed}"));
        assert_eq!(code, 0, "{err}");
        let ts = |d: &Path| std::fs::read(d.join("timeseries.csv")).unwrap();
        assert_eq!(ts(&by_set), ts(&by_flag), "{seed}");
    }
    for bad in ["18446744073709551616", "1e3", "1.5"] {
        let set = format!("run.seed={bad}");
        let (code, err, _) = run(&["--set", &set], "bad");
        assert_eq!(code, 2, "{err}");
        assert!(err.contains("run.seed") && err.contains(bad), "{err}");
    }
    // A grid value is an f64: a whole number beyond 2^53 is refused, not rounded.
    let (code, _, err) = tiltsim_suite::run(&[
        "sweep",
        sc.to_str().unwrap(),
        "--grid",
        "run.seed=9007199254740993",
        "--plan-only",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("9007199254740993") && err.contains("2^53"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(root);
}

/// Starts `cmd` as the leader of its own process group (the participants join it).
fn spawn_group(cmd: &Tiltsim) -> std::process::Child {
    cmd.to_command()
        .process_group(0)
        .spawn()
        .unwrap_or_else(|e| panic!("{}: {e}", cmd.line()))
}

/// Waits until `file` holds more than `bytes` (the run is under way).
fn until_written(file: &Path, bytes: u64) {
    wait_for(Duration::from_secs(60), || {
        (std::fs::metadata(file).ok()?.len() > bytes).then_some(())
    })
    .expect("the run did not start writing");
}

#[test]
fn sigterm_to_the_process_group_is_an_interruption_in_a_run_and_in_a_paced_wait() {
    let root = temp_dir("group-sigterm");
    for (name, pace) in [("lockstep", None), ("paced", Some("1e-6"))] {
        let pfx = prefix(&format!("group_{name}"));
        let out = root.join(name);
        let mut cmd = Tiltsim::run("paper-lqg.toml")
            .transport_ipc()
            .ipc_prefix(&pfx)
            .quiet()
            .out(&out);
        if let Some(factor) = pace {
            cmd = cmd.pace(factor);
        }
        let child = spawn_group(&cmd);
        // The header is on disk at once; a paced run at 1e-6 then waits 1000 s per tick.
        until_written(&out.join("timeseries.csv"), 100);
        if name == "lockstep" {
            until_written(&out.join("timeseries.csv"), 100_000);
        } else {
            // Every participant process is up before the first wait: its three children are
            // there, then their start and the Init exchange (no file shows the paced wait; a
            // signal while a participant starts is a different outcome, tested elsewhere).
            let children = format!("/proc/{0}/task/{0}/children", child.id());
            wait_for(Duration::from_secs(60), || {
                let list = std::fs::read_to_string(&children).ok()?;
                (list.split_whitespace().count() >= 3).then_some(())
            })
            .expect("the participants did not start");
            std::thread::sleep(Duration::from_secs(3));
        }
        // As systemd, Slurm's scancel or a container runtime send it: to every process.
        // SAFETY: kill(2) with a negative pid signals the group the child leads.
        assert_eq!(
            unsafe { libc::kill(-(child.id() as i32), libc::SIGTERM) },
            0
        );
        // A hang guard only: the paced wait would otherwise last 1000 s per tick.
        let (code, _, err) = wait_with_limit(child, Duration::from_secs(120));
        assert_eq!(code, 130, "{name}: {err}");
        assert!(err.contains("interrupted"), "{name}: {err}");
        let s = tiltsim_suite::summary(&out);
        assert_eq!(s["status"], "interrupted", "{name}: {s}");
        assert!(
            s["error"].as_str().unwrap().contains("SIGTERM"),
            "{name}: {s}"
        );
        assert!(leftovers(&pfx).is_empty(), "{name}: {:?}", leftovers(&pfx));
    }
    let _ = std::fs::remove_dir_all(root);
}

/// Every entry under `dir` whose name starts with `prefix`, and the node directories
/// (`nodes/<id>/`) that hold one.
fn entries_of(dir: &Path, prefix: &str, out: &mut Vec<std::path::PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let p = e.path();
        if e.file_name().to_string_lossy().starts_with(prefix) {
            out.push(p.clone());
        }
        if p.is_dir() && !p.is_symlink() {
            entries_of(&p, prefix, out);
        }
    }
}

#[test]
fn a_sigkilled_orchestrator_leaves_no_file_and_no_directory_after_the_next_run_and_clean() {
    let root = temp_dir("sigkill-clean");
    let sc = scenario("paper-lqg.toml");
    for after in ["next run", "clean"] {
        // A directory of its own each time: a series left by the killed run before must not
        // be taken for this run's progress.
        let out = root.join(format!("killed-{}", after.replace(' ', "-")));
        // The default prefix, tiltsim_<pid>_..., by which a dead owner is recognised.
        let child = spawn_group(&Tiltsim::run(&sc).transport_ipc().quiet().out(&out));
        let pid = child.id();
        until_written(&out.join("timeseries.csv"), 100_000);
        let own = format!("tiltsim_{pid}_");
        let mut during = Vec::new();
        for d in ["/dev/shm", "/tmp/iceoryx2"] {
            entries_of(Path::new(d), &own, &mut during);
        }
        let node_dirs: Vec<_> = during
            .iter()
            .filter_map(|p| p.parent())
            .filter(|d| {
                d.parent()
                    .and_then(|n| n.file_name())
                    .is_some_and(|n| n == "nodes")
            })
            .map(Path::to_path_buf)
            .collect();
        assert!(!during.is_empty(), "the run has no files under its prefix");
        let participants = tiltsim_suite::children_of(pid);
        // SAFETY: SIGKILL to the orchestrator alone; its participants notice and end.
        assert_eq!(unsafe { libc::kill(pid as i32, libc::SIGKILL) }, 0);
        let _ = wait_with_limit(child, Duration::from_secs(30));
        wait_for(Duration::from_secs(60), || {
            participants
                .iter()
                .all(|(p, _)| !Path::new(&format!("/proc/{p}")).exists())
                .then_some(())
        })
        .expect("the participants of a killed orchestrator did not end");
        // An emptied node directory counts as abandoned once unchanged for 5 s.
        std::thread::sleep(Duration::from_secs(6));
        if after == "next run" {
            let next = root.join("next");
            Tiltsim::run("paper-passive.toml")
                .transport_ipc()
                .duration(0.05)
                // Start-up under the load of a whole test suite.
                .set("run.startup_ms", 60000)
                .quiet()
                .out(&next)
                .success();
        } else {
            let (code, _, err) = tiltsim_suite::run(&["clean"]);
            assert_eq!(code, 0, "{err}");
        }
        let mut left = Vec::new();
        for d in ["/dev/shm", "/tmp/iceoryx2"] {
            entries_of(Path::new(d), &own, &mut left);
        }
        left.extend(node_dirs.into_iter().filter(|d| d.exists()));
        assert!(left.is_empty(), "after the {after}: {left:?}");
    }
    let _ = std::fs::remove_dir_all(root);
}
