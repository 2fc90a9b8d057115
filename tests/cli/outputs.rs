//! Outputs as users read them: one run per output directory and a directory holds one run
//! (docs/outputs.md, "Output directories"); the figures (`outputs/figures.rs`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use tiltsim_suite::{run, scenario, spawn, temp_dir, wait_for, wait_with_limit, Tiltsim};

/// The figures: titles, units, markup, captions, notes, steps and markers.
mod figures;

const LOCK: &str = ".tiltsim.lock";

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The pid the lock of `dir` names, once it exists.
fn lock_pid(dir: &Path) -> Option<u32> {
    let text = std::fs::read_to_string(dir.join(LOCK)).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    v["pid"].as_u64().map(|p| p as u32)
}

/// Starts a run that lasts until it is interrupted: paced at one simulated second per wall
/// second over a long track, in-process. Returns once it holds `out`.
fn long_run(out: &Path) -> std::process::Child {
    let child = Tiltsim::run("paper-passive.toml")
        .transport_in_process()
        .pace(1)
        .duration(3000)
        .out(out)
        .quiet()
        .spawn();
    let held = wait_for(Duration::from_secs(120), || {
        (lock_pid(out) == Some(child.id())).then_some(())
    });
    assert!(held.is_some(), "the run did not take {}", out.display());
    child
}

fn interrupt(child: std::process::Child) -> (i32, String, String) {
    // SAFETY: signalling a child this test started.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    wait_with_limit(child, Duration::from_secs(120))
}

fn quick_run(sc: &str, out: &Path, extra: &[&str]) -> (i32, String, String) {
    Tiltsim::run(sc)
        .transport_in_process()
        .duration(2)
        .out(out)
        .quiet()
        .args(extra)
        .result()
}

fn files_under(dir: &Path) -> Vec<String> {
    fn walk(base: &Path, d: &Path, out: &mut Vec<String>) {
        for e in std::fs::read_dir(d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(base, &p, out);
            } else {
                out.push(p.strip_prefix(base).unwrap().display().to_string());
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

#[test]
fn a_second_run_into_a_directory_in_use_is_refused_naming_it_and_the_pid() {
    let dir = temp_dir("outputs-busy");
    let d = dir.join("D");
    // An earlier, finished run with its figures.
    let passive = scenario("paper-passive.toml");
    let (code, _, err) = quick_run(s(&passive), &d, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(d.join("plots/lateral_acceleration.svg").exists());
    assert!(!d.join(LOCK).exists(), "a finished run leaves no lock");

    let first = long_run(&d);
    let pid = first.id();
    // A run of another scenario into the same directory: refused, nothing of it written.
    let (code, _, err) = quick_run(s(&scenario("paper-mpc.toml")), &d, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(s(&d)) && err.contains(&format!("pid {pid}")),
        "{err}"
    );
    // A sweep and a compare are refused the same way.
    let (code, _, err) = run(&[
        "sweep",
        s(&passive),
        "--grid",
        "vehicle.m_v=16000,22000",
        "--out",
        s(&d),
        "-q",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&format!("pid {pid}")), "{err}");
    let (code, _, err) = run(&[
        "compare",
        s(&passive),
        "--transport",
        "in-process",
        "--out",
        s(&d),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&format!("pid {pid}")), "{err}");
    // The running one writes its scenario.toml after it takes the directory (soon, or late
    // on a loaded machine); the refused ones wrote nothing.
    let text = wait_for(Duration::from_secs(120), || {
        std::fs::read_to_string(d.join("scenario.toml")).ok()
    })
    .expect("the running run's scenario.toml");
    assert!(text.contains("name = \"paper-passive\""), "{text}");

    // Interrupted: its own files, not the earlier run's figures (it draws none).
    let (code, _, err) = interrupt(first);
    assert_eq!(code, 130, "{err}");
    assert!(!d.join("plots/lateral_acceleration.svg").exists());
    assert!(!d.join("plots").exists());
    assert!(!d.join(LOCK).exists());
    // Sequential use is allowed: the next run replaces the files.
    let (code, _, err) = quick_run(s(&scenario("paper-lqg.toml")), &d, &[]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(d.join("scenario.toml")).unwrap();
    assert!(text.contains("name = \"paper-lqg\""));
}

#[test]
fn two_shards_given_one_directory_the_second_is_refused() {
    let dir = temp_dir("outputs-shards");
    let d = dir.join("D");
    let sc = scenario("paper-passive.toml");
    let args = |shard: &str| {
        vec![
            "sweep".to_string(),
            s(&sc).to_string(),
            "--samples".into(),
            "400".into(),
            "--jobs".into(),
            "1".into(),
            "--shard".into(),
            shard.into(),
            "--out".into(),
            s(&d).to_string(),
            "-q".into(),
        ]
    };
    let a0 = args("0/2");
    let first = spawn(&a0.iter().map(String::as_str).collect::<Vec<_>>());
    let held = wait_for(Duration::from_secs(120), || {
        (lock_pid(&d) == Some(first.id())).then_some(())
    });
    assert!(held.is_some());
    let a1 = args("1/2");
    let (code, _, err) = run(&a1.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(s(&d)) && err.contains(&format!("pid {}", first.id())),
        "{err}"
    );
    let (code, _, err) = interrupt(first);
    assert_eq!(code, 130, "{err}");
    // Afterwards, the other shard is still refused: the directory is shard 0/2's.
    let (code, _, err) = run(&a1.iter().map(String::as_str).collect::<Vec<_>>());
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("holds shard 0/2") && err.contains("--shard 0/2"),
        "{err}"
    );
}

/// Process start time in clock ticks after boot, `/proc/<pid>/stat` field 22.
fn start_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    let rest = &stat[stat.rfind(')').unwrap() + 1..];
    rest.split_whitespace().nth(19).unwrap().parse().unwrap()
}

fn lock_text(pid: u32, start: u64) -> String {
    let read = |p: &str| std::fs::read_to_string(p).unwrap().trim().to_string();
    serde_json::json!({
        "pid": pid,
        "start_ticks": start,
        "boot_id": read("/proc/sys/kernel/random/boot_id"),
        "host": read("/proc/sys/kernel/hostname"),
        "command": "run",
    })
    .to_string()
}

#[test]
fn a_lock_left_by_a_dead_run_is_taken_over() {
    let dir = temp_dir("outputs-dead");
    let sc = scenario("paper-passive.toml");
    // A run killed outright leaves its lock; the next run takes it over.
    let d = dir.join("killed");
    let child = long_run(&d);
    let pid = child.id();
    let mut child = child;
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(lock_pid(&d), Some(pid), "the killed run's lock stays");
    let (code, _, err) = quick_run(s(&sc), &d, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(!d.join(LOCK).exists());

    // A lock naming a live process whose start time is not the recorded one: the pid was
    // reused after the holder died; taken over.
    let mut sleeper = std::process::Command::new("sleep")
        .arg("60")
        .spawn()
        .unwrap();
    let live = sleeper.id();
    let d = dir.join("reused");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join(LOCK), lock_text(live, start_ticks(live) + 1)).unwrap();
    let (code, _, err) = quick_run(s(&sc), &d, &[]);
    assert_eq!(code, 0, "{err}");
    // The same process with its own start time is a live holder (whatever flock says): refused.
    let d = dir.join("live");
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join(LOCK), lock_text(live, start_ticks(live))).unwrap();
    let (code, _, err) = quick_run(s(&sc), &d, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(&format!("pid {live}")), "{err}");
    let _ = sleeper.kill();
    let _ = sleeper.wait();
    // Once it has exited, its lock is taken over.
    let (code, _, err) = quick_run(s(&sc), &d, &[]);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn a_run_that_replaces_an_earlier_one_says_so_and_names_what_ran() {
    let dir = temp_dir("outputs-replaced");
    let d = dir.join("D");
    let sc = scenario("paper-pi.toml");
    let loud = |extra: &[&str]| {
        Tiltsim::run(&sc)
            .transport_in_process()
            .duration(0.5)
            .out(&d)
            .args(extra)
            .result()
    };
    let (code, out, err) = loud(&[]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.starts_with("paper-pi (PI, switched BLDC drive): completed, 500 steps"),
        "{out}"
    );
    assert!(
        !out.contains("replaced the earlier run"),
        "a first run replaced nothing: {out}"
    );
    // The same default directory with another controller: the first line says which, and
    // a line says the earlier run's files are gone.
    let (code, out, err) = loud(&[
        "--set",
        "controller.mode=lqg",
        "--set",
        "actuator.model=ideal",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.starts_with("paper-pi (LQG servo, ideal bar): completed,"),
        "{out}"
    );
    assert!(
        out.lines()
            .any(|l| l == format!("  replaced the earlier run in {}", d.display())),
        "{out}"
    );
    // Quiet: not a word.
    let (code, out, err) = loud(&["-q"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!((out.as_str(), err.as_str()), ("", ""));
}

#[test]
fn an_earlier_runs_recording_trace_and_replays_are_not_left_beside_a_new_run() {
    let dir = temp_dir("outputs-stale");
    let d = dir.join("D");
    let lqg = scenario("paper-lqg.toml");
    let (code, _, err) = quick_run(s(&lqg), &d, &["--record", "--trace"]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = run(&["replay", s(&d), "--participant", "controller"]);
    assert_eq!(code, 0, "{err}");
    // The user's own files in the directory.
    std::fs::write(d.join("notes.txt"), "mine").unwrap();
    std::fs::write(d.join("plots/mine.svg"), "<svg/>").unwrap();
    let all = files_under(&d);
    for f in [
        "run.mcap",
        "trace.csv",
        "plots/latency_histogram.png",
        "replay-controller/replay.json",
    ] {
        assert!(all.iter().any(|x| x == f), "{f} not in {all:?}");
    }
    // The program's list of what a run writes covers every file this one made (with
    // --record, --trace and a replay): clearing it leaves only the user's.
    let copy = dir.join("copy");
    std::fs::create_dir_all(copy.join("plots")).unwrap();
    std::fs::create_dir_all(copy.join("replay-controller")).unwrap();
    for f in &all {
        std::fs::copy(d.join(f), copy.join(f)).unwrap();
    }
    tiltsim_rundir::outdir::clear_run(&copy).unwrap();
    assert_eq!(files_under(&copy), ["notes.txt", "plots/mine.svg"]);

    // Another scenario without --record or --trace: nothing of the first run is left, so
    // replay cannot compare the new scenario with the old recording.
    let (code, _, err) = quick_run(s(&scenario("paper-pi.toml")), &d, &[]);
    assert_eq!(code, 0, "{err}");
    let now = files_under(&d);
    for f in [
        "run.mcap",
        "trace.csv",
        "plots/latency_histogram.svg",
        "replay-controller/replay.json",
    ] {
        assert!(!now.iter().any(|x| x == f), "{f} left: {now:?}");
    }
    assert!(now.iter().any(|x| x == "notes.txt") && now.iter().any(|x| x == "plots/mine.svg"));
    let (code, _, err) = run(&["replay", s(&d), "--participant", "controller"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("run.mcap"), "{err}");
}

/// `compare` takes scenario files, not `--set`: a copy of paper-passive with its name and
/// speed changed.
fn scenario_named(dir: &Path, file: &str, name: &str, speed: f64) -> PathBuf {
    let text = std::fs::read_to_string(scenario("paper-passive.toml"))
        .unwrap()
        .replace("name = \"paper-passive\"", &format!("name = \"{name}\""))
        .replace("speed_kmh = 162.0", &format!("speed_kmh = {speed:?}"));
    let p = dir.join(file);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn a_compare_gives_same_named_scenarios_distinct_directories_and_columns() {
    let dir = temp_dir("outputs-compare");
    let a = scenario_named(&dir, "a/x.toml", "x", 150.0);
    let b = scenario_named(&dir, "b/x.toml", "x", 170.0);
    let c = dir.join("C");
    let (code, _, err) = run(&[
        "compare",
        s(&a),
        s(&b),
        "--transport",
        "in-process",
        "--out",
        s(&c),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("x-2"), "{err}");
    let speed = |sub: &str| {
        let t = std::fs::read_to_string(c.join(sub).join("scenario.toml")).unwrap();
        let v: toml::Value = toml::from_str(&t).unwrap();
        v["track"]["speed_kmh"].as_float().unwrap()
    };
    assert_eq!((speed("x"), speed("x-2")), (150.0, 170.0));
    // Two columns, two labels: the table's header names both runs.
    let md = std::fs::read_to_string(c.join("table.md")).unwrap();
    assert!(md.contains("[x]") && md.contains("[x-2]"), "{md}");
    // A later compare of one scenario: the earlier compare's other run does not stay.
    let (code, _, err) = run(&[
        "compare",
        s(&a),
        "--transport",
        "in-process",
        "--out",
        s(&c),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(c.join("x/summary.json").exists());
    assert!(!c.join("x-2").exists());
    // A run into a compare's directory is refused: a directory holds one run.
    let (code, _, err) = quick_run(s(&a), &c, &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("compare"), "{err}");
}

/// An example's executable: examples are built beside the test binaries
/// (target/<profile>/examples).
fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe()
        .unwrap()
        .parent()
        .and_then(Path::parent)
        .unwrap()
        .join("examples")
        .join(name);
    assert!(exe.exists(), "{} not built", exe.display());
    exe
}

/// The observer of `examples/peak_observer.rs`, written outside the crates as a user writes
/// one: what it reports in its part of the summary is what the run's own table holds (the
/// largest |lat_acc| of every row, at that row's time, one tick per row after the first).
#[test]
fn an_observer_written_outside_the_crates_sees_every_row_of_the_table() {
    let exe = example("peak_observer");
    let out = temp_dir("peak-observer").join("run");
    let p = std::process::Command::new(&exe)
        .args([s(&scenario("paper-passive.toml")), s(&out)])
        .output()
        .unwrap();
    assert!(p.status.success(), "{}", String::from_utf8_lossy(&p.stderr));
    let part: serde_json::Value = serde_json::from_slice(&p.stdout).unwrap();
    let table = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let rows = tiltsim_suite::csv_table(&table);
    let col = |name: &str| rows[0].iter().position(|c| c == name).unwrap();
    let (lat, time) = (col("lat_acc"), col("time"));
    let peak = rows[1..]
        .iter()
        .max_by(|a, b| {
            let v = |r: &Vec<String>| r[lat].parse::<f64>().unwrap().abs();
            v(a).total_cmp(&v(b))
        })
        .unwrap();
    assert_eq!(
        part["peak_lat_acc_m_s2"].as_f64().unwrap(),
        peak[lat].parse::<f64>().unwrap().abs()
    );
    assert_eq!(
        part["at_s"].as_f64().unwrap(),
        peak[time].parse::<f64>().unwrap()
    );
    assert_eq!(part["ticks"].as_u64().unwrap() as usize, rows.len() - 2);
    assert_eq!(part["status"], "completed");
}

/// The manipulator of `examples/quantised_sensor.rs`, written outside the crates: every
/// measurement the controller got is a whole multiple of the resolution, within half of it
/// of what the plant sent the tick before (row k's θ_v measured reaches the controller in
/// tick k, row k + 1's `rx_measurement`), every tick's sample passed through it, and what it
/// logged is in `events.csv`.
#[test]
fn a_manipulator_written_outside_the_crates_acts_on_every_sample_of_its_link() {
    let exe = example("quantised_sensor");
    let out = temp_dir("quantised-sensor").join("run");
    let q = 0.001;
    let p = std::process::Command::new(&exe)
        .args([s(&scenario("paper-lqg.toml")), s(&out), "0.001"])
        .output()
        .unwrap();
    assert!(p.status.success(), "{}", String::from_utf8_lossy(&p.stderr));
    let said: serde_json::Value = serde_json::from_slice(&p.stdout).unwrap();
    let table = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let rows = tiltsim_suite::csv_table(&table);
    let col = |name: &str| rows[0].iter().position(|c| c == name).unwrap();
    let (rx, sent) = (col("rx_measurement"), col("theta_v_meas"));
    let v = |r: &Vec<String>, c: usize| r[c].parse::<f64>().unwrap();
    let ticks = rows.len() - 2;
    assert_eq!(said["quantised"].as_u64().unwrap() as usize, ticks);
    assert_eq!(said["status"], "completed");
    let mut levels = std::collections::BTreeSet::new();
    for k in 1..=ticks {
        let got = v(&rows[k + 1], rx);
        let n = (got / q).round();
        assert_eq!((n * q).to_bits(), got.to_bits(), "row {}: {got}", k + 1);
        assert!(
            (got - v(&rows[k], sent)).abs() <= q / 2.0 + 1e-15,
            "row {}",
            k + 1
        );
        levels.insert(n as i64);
    }
    // The body rolls through many levels on the curve (up to about 5° = 87 mrad).
    assert!(levels.len() > 20, "{} levels", levels.len());
    let events = std::fs::read_to_string(out.join("events.csv")).unwrap();
    assert!(
        events.contains("0.0,0,measurement,manipulated,0.001,measurement quantised to 0.001 rad"),
        "{events}"
    );
}
