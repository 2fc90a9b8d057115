//! The free-running mode and its exact lock-step replay (docs/architecture.md, "Execution
//! modes"). Nothing here asserts a wall-clock time or an age distribution: a free run on a
//! loaded machine is late, not failed. What is asserted holds whatever the load: the replay
//! gives the free run's bytes, causality in the trace (an input is read only after it was
//! published), and a study busy wait that lies between a controller's read and its publish.

mod links;
mod recording;
mod replayed;
mod trace;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use tiltsim_suite::{leftovers, prefix, run, scenario, summary, temp_dir, Hogs, Tiltsim};
use trace::{check_trace, read_trace};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// A free run of pi-drive over IPC for `duration` s with `extra` arguments; must complete.
fn free_run(name: &str, duration: &str, extra: &[&str]) -> (PathBuf, String) {
    let out = temp_dir(name).join("free");
    let pre = prefix(name);
    Tiltsim::run("pi-drive.toml")
        .free_run()
        .duration(duration)
        .out(&out)
        .ipc_prefix(&pre)
        .quiet()
        .args(extra)
        .success();
    assert!(
        leftovers(&pre).is_empty(),
        "{name}: shared-memory files left"
    );
    (out, pre)
}

fn replay(dir: &Path, out: &Path, extra: &[&str]) -> (i32, String) {
    let mut args = vec!["replay-timing", s(dir), "--out", s(out), "-q"];
    args.extend_from_slice(extra);
    let (code, _, err) = run(&args);
    (code, err)
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn a_free_run_is_replayed_byte_for_byte_in_process_and_over_ipc_and_with_another_system() {
    let (dir, _) = free_run("freerun-replay", "2", &[]);
    let trace = read_trace(&dir);
    check_trace(&trace, 2000, 1);
    let sm = summary(&dir);
    assert_eq!(sm["status"], "completed");
    assert_eq!(sm["steps_completed"], 2000);
    assert!(sm["free_run"]["not_real_time"].is_boolean());
    assert_eq!(
        sm["flags"]["not_real_time"]["raised"],
        sm["free_run"]["not_real_time"]
    );
    // perf.json: an age distribution per link over every step of its consumer.
    let perf: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("perf.json")).unwrap()).unwrap();
    for link in ["actuator_command", "bar_angle", "measurement", "bar_twist"] {
        let n: i64 = perf["free_run"]["input_age_ticks"][link]["counts"]
            .as_array()
            .unwrap_or_else(|| panic!("{link} has no age counts"))
            .iter()
            .map(|p| p[1].as_i64().unwrap())
            .sum();
        assert_eq!(n, 2000, "{link}: one age per consumer step");
    }
    let free = bytes(&dir.join("timeseries.csv"));
    // The header, the start time and 2000 steps.
    assert_eq!(free.iter().filter(|&&b| b == b'\n').count(), 2002);

    let root = temp_dir("freerun-replay-out");
    let (code, err) = replay(&dir, &root.join("in-process"), &[]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(bytes(&root.join("in-process/timeseries.csv")), free);
    let (code, err) = replay(&dir, &root.join("ipc"), &["--transport", "ipc"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(bytes(&root.join("ipc/timeseries.csv")), free);
    // The replay keeps the free run's verdict on real time, judged from the same trace.
    let again = summary(&root.join("in-process"));
    let (a, b) = (
        &sm["flags"]["not_real_time"],
        &again["flags"]["not_real_time"],
    );
    assert_eq!(a["raised"], b["raised"], "{a} {b}");
    assert_eq!(a["margin_s"], b["margin_s"]);
    let late = |v: &serde_json::Value| v["plant_max_lateness_s"].as_f64().unwrap();
    assert!((late(a) - late(b)).abs() < 1e-9, "{a} {b}");
    assert_eq!(sm["comfort_valid"], again["comfort_valid"]);

    replayed::a_late_plant_step_makes_the_replay_not_real_time(&dir, &root);
    replayed::an_edited_trace_changes_the_rows_from_its_step(&dir, &root, &free);
    replayed::another_system_is_replayed_under_the_same_timing(&dir, &root);
    replayed::a_foreign_or_gapped_trace_is_refused(&dir, &root);
}

/// The whole car (`vehicle.model = "full"`) runs free: the run completes and reports its
/// running safety (the five quantities, the quasi-static ones over the 1.6 s of steady curve
/// the 7 s reach) and the comfort at three places; its lock-step replay gives the same rows
/// and the same whole-car assessment to the bit, so the free run's assessment is that of its
/// own rows. The accelerations kept for the comfort along the car are not left behind.
#[test]
fn a_free_whole_car_run_reports_its_running_safety_as_its_replay_does() {
    let (dir, _) = free_run("freerun-full", "7", &["--set", "vehicle.model=full"]);
    let sm = summary(&dir);
    assert_eq!(sm["status"], "completed", "{sm}");
    let safety = sm["full_car"]["running_safety"]
        .as_array()
        .unwrap_or_else(|| panic!("no running safety: {sm}"));
    let names: Vec<&str> = safety
        .iter()
        .map(|q| q["quantity"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["(Y/Q)_2m", "(SumY)_2m", "dQ/Q0", "Y_qst", "Q_qst"]);
    // On the curve the rails push the wheelsets inwards: no quantity is zero.
    for q in safety {
        assert!(q["value"].as_f64().unwrap() > 0.0, "{q}");
    }
    assert_eq!(
        sm["full_car"]["comfort_along_car"].as_array().map(Vec::len),
        Some(3)
    );
    assert!(sm["flags"]["running_safety"]["raised"].is_boolean());
    let out = dir.parent().unwrap().join("replayed");
    let (code, err) = replay(&dir, &out, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(bytes(&dir.join("timeseries.csv")) == bytes(&out.join("timeseries.csv")));
    let again = summary(&out);
    assert_eq!(again["full_car"], sm["full_car"]);
    assert_eq!(
        again["flags"]["running_safety"],
        sm["flags"]["running_safety"]
    );
    for d in [&dir, &out] {
        let left: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect();
        assert!(left.is_empty(), "{}: {left:?}", d.display());
    }
}

#[test]
fn an_injected_controller_delay_shows_in_the_input_ages_and_is_replayed() {
    // A 10 ms controller given 4 ms of extra compute per step.
    let (dir, _) = free_run(
        "freerun-delay",
        "2",
        &[
            "--set",
            "controller.period_s=0.01",
            "--set",
            "run.controller_busy_wait_s=0.004",
        ],
    );
    let trace = read_trace(&dir);
    check_trace(&trace, 2000, 10);
    let delay = 4_000_000;
    let read_of: HashMap<i64, u64> = trace
        .iter()
        .filter(|x| x.role == "controller")
        .map(|x| {
            assert!(
                x.publish - x.read >= delay,
                "controller step {} without its delay",
                x.step
            );
            (x.step, x.read)
        })
        .collect();
    // Every command the actuator read is at least the delay older than the controller's read
    // of the measurement it came from (the delay lies between that read and the publish).
    let mut read_commands = 0;
    for x in trace.iter().filter(|x| x.role == "actuator") {
        let q = x.from["controller"];
        if q >= 0 {
            read_commands += 1;
            assert!(x.read - read_of[&q] >= delay, "actuator step {}", x.step);
        }
    }
    assert!(read_commands > 0);
    let out = temp_dir("freerun-delay-out").join("replay");
    let (code, err) = replay(&dir, &out, &[]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        bytes(&out.join("timeseries.csv")),
        bytes(&dir.join("timeseries.csv"))
    );
}

#[test]
fn free_running_is_refused_in_process_and_with_what_it_does_not_apply() {
    let out = temp_dir("freerun-refused");
    let err = Tiltsim::run("pi-drive.toml")
        .free_run()
        .transport_in_process()
        .out(&out)
        .failure(2);
    assert!(
        err.contains("run.execution") && err.contains("ipc"),
        "{err}"
    );
    let degrading = scenario("fault-controller-killed.toml");
    let text = std::fs::read_to_string(&degrading).unwrap();
    assert!(text.contains("on_failure = \"degrade\""));
    let err = Tiltsim::run(&degrading).free_run().out(&out).failure(2);
    assert!(
        err.contains("run.execution") && err.contains("faults.on_failure"),
        "{err}"
    );
    let err = Tiltsim::run("pi-drive.toml")
        .set("run.controller_busy_wait_s", 0.001)
        .out(&out)
        .failure(2);
    assert!(err.contains("run.controller_busy_wait_s"), "{err}");
}

/// The rows of a CSV file with a header, by column name.
fn csv_rows(path: &Path) -> Vec<HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let head: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|x| {
            let x = x.unwrap();
            head.iter()
                .cloned()
                .zip(x.iter().map(String::from))
                .collect()
        })
        .collect()
}
#[test]
fn link_effects_and_a_stall_act_in_a_free_run_and_its_replay_repeats_them() {
    let root = temp_dir("freerun-links");
    let sc = links::with_links_and_a_stall(&root);
    let out = root.join("free");
    let pre = prefix("freerun-links");
    Tiltsim::run(&sc)
        .free_run()
        .duration(2)
        .record()
        .out(&out)
        .ipc_prefix(&pre)
        .quiet()
        .success();
    assert!(leftovers(&pre).is_empty(), "shared-memory files left");
    let trace = read_trace(&out);
    check_trace(&trace, 2000, 1);
    let by: links::ByStep = trace
        .iter()
        .map(|x| ((x.role.clone(), x.step), x))
        .collect();
    links::commands_arrive_the_link_delay_late(&trace, &by);
    let events = csv_rows(&out.join("events.csv"));
    links::lost_samples_are_logged_and_never_read(&trace, &events);
    links::the_noise_reaches_the_controller(&csv_rows(&out.join("timeseries.csv")), &by);
    links::the_stalled_controller_started_late(&trace, &events);
    recording::recording_holds_the_trace(&out, &by);
    links::the_replay_repeats_values_events_and_flags(&out, &root);
}

#[test]
fn a_participant_killed_in_a_free_run_is_named_and_the_rows_before_are_kept() {
    let root = temp_dir("freerun-kill");
    let base = std::fs::read_to_string(scenario("pi-drive.toml")).unwrap();
    let sc = root.join("killed.toml");
    // A `[[faults.schedule]]` entry is an array-of-tables element, which `--set` cannot add.
    std::fs::write(
        &sc,
        format!(
            "{base}\n[[faults.schedule]]\nparticipant = \"actuator\"\naction = \"kill\"\nat_s = 0.5\n"
        ),
    )
    .unwrap();
    let out = root.join("free");
    let pre = prefix("freerun-kill");
    let err = Tiltsim::run(&sc)
        .free_run()
        .duration(2)
        .out(&out)
        .ipc_prefix(&pre)
        .quiet()
        .failure(1);
    assert!(err.contains("actuator"), "{err}");
    assert!(leftovers(&pre).is_empty(), "shared-memory files left");
    let sm = summary(&out);
    assert_eq!(sm["status"], "failed");
    let rows = sm["steps_completed"].as_u64().unwrap();
    // The message names the step the actuator was at: after its last sample, which it
    // published on its own clock before the kill at 0.5 s of a 2 s run (2000 steps).
    let at: u64 = err
        .split("while step ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no step named: {err}"));
    assert!(at > 0 && at <= 2000, "{err}");
    // The world went on until the loss was seen: at least the 500 steps before it (how many
    // after depends on how soon the hub saw the process gone).
    assert!(rows >= 500, "{rows} rows");
    let series = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    // The header, the start time and every step.
    assert_eq!(series.lines().count() as u64, rows + 2);
}

/// pi-drive with `faults` (TOML of `[[faults.schedule]]` tables) appended, written as
/// `dir/name.toml`: `--set` cannot add an element to an array of tables.
fn pi_drive_with(dir: &Path, name: &str, faults: &str) -> PathBuf {
    let base = std::fs::read_to_string(scenario("pi-drive.toml")).unwrap();
    std::fs::create_dir_all(dir).unwrap();
    let file = dir.join(format!("{name}.toml"));
    std::fs::write(&file, format!("{base}\n{faults}")).unwrap();
    file
}

/// Runs `sc` free for `duration` s into `out` (waiting for it however long it takes), checks
/// that it completed with every step in its trace and no shared-memory file left, replays
/// its trace in process and checks that the replay's rows and events are the free run's
/// bytes.
fn completes_and_replays(sc: &Path, out: &Path, duration: &str, pre: &str) {
    Tiltsim::run(sc)
        .free_run()
        .duration(duration)
        .out(out)
        .ipc_prefix(pre)
        .quiet()
        .success();
    assert!(leftovers(pre).is_empty(), "{pre}: shared-memory files left");
    let sm = summary(out);
    assert_eq!(sm["status"], "completed", "{}", sc.display());
    assert_eq!(sm["execution"], "free");
    let steps = (duration.parse::<f64>().unwrap() * 1000.0).round() as i64;
    check_trace(&read_trace(out), steps, 1);
    let again = out.join("replay");
    let (code, err) = replay(out, &again, &[]);
    assert_eq!(code, 0, "{err}");
    for f in ["timeseries.csv", "events.csv"] {
        assert!(
            bytes(&out.join(f)) == bytes(&again.join(f)),
            "{}: the replay's {f} differs from the free run's",
            sc.display()
        );
    }
}

/// A stall is the timing a free run records, however long: the stalled participant catches
/// up in a burst of steps that no buffer of the exchange drops, and the others go on reading
/// the newest input they have. Each participant is stalled once (3, 10 and 30 s, longer
/// than any buffer of the exchange holds at a 1 ms step), the runs side by side.
#[test]
fn long_stalls_of_each_participant_complete_and_replay_byte_for_byte() {
    let root = temp_dir("freerun-stalls");
    let cases = [
        ("plant", "3.0"),
        ("actuator", "10.0"),
        ("controller", "30.0"),
    ];
    std::thread::scope(|scope| {
        for (role, stall) in cases {
            let root = &root;
            scope.spawn(move || {
                let faults = format!(
                    "[[faults.schedule]]\nparticipant = \"{role}\"\naction = \"stall\"\nat_s = 0.5\nstall_s = {stall}\n"
                );
                let sc = pi_drive_with(root, &format!("stall-{role}"), &faults);
                let out = root.join(format!("{role}-free"));
                completes_and_replays(&sc, &out, "2", &prefix(&format!("freerun-stall-{role}")));
                let t = read_trace(&out);
                // The stalled participant's step due when it was stopped started at least the
                // stall late (SIGSTOP for the wall time of the stall).
                let stall_ns = (stall.parse::<f64>().unwrap() * 1e9) as i64;
                let late = t
                    .iter()
                    .filter(|x| x.role == role)
                    .map(|x| x.read as i64 - x.due as i64)
                    .max()
                    .unwrap();
                assert!(
                    late >= stall_ns - 50_000_000,
                    "{role}: largest start lateness {late} ns for a stall of {stall} s"
                );
                if role == "plant" {
                    let sm = summary(&out);
                    assert_eq!(sm["flags"]["not_real_time"]["raised"], true);
                }
            });
        }
    });
}

/// A participant stopped from outside (SIGSTOP, SIGCONT 10 s later) is waited for as a
/// scheduled stall is, and the run completes and replays exactly.
#[test]
fn a_participant_stopped_from_outside_is_waited_for_and_the_run_replays() {
    let root = temp_dir("freerun-sigstop");
    let out = root.join("free");
    let pre = prefix("freerun-sigstop");
    let child = Tiltsim::run("pi-drive.toml")
        .free_run()
        .duration(3)
        .out(&out)
        .ipc_prefix(&pre)
        .quiet()
        .spawn();
    // The plant process, once it exists, and the run under way (its trace growing).
    let plant = tiltsim_suite::wait_for(std::time::Duration::from_secs(600), || {
        tiltsim_suite::children_of(child.id())
            .into_iter()
            .find(|(_, name)| name.contains("plant"))
            .map(|(pid, _)| pid)
    })
    .expect("the plant process never appeared");
    tiltsim_suite::wait_for(std::time::Duration::from_secs(600), || {
        std::fs::metadata(out.join("timing.csv"))
            .ok()
            .filter(|m| m.len() > 0)
    })
    .expect("the trace never appeared");
    // SAFETY: signals to a child process of the run under test.
    unsafe { libc::kill(plant as i32, libc::SIGSTOP) };
    std::thread::sleep(std::time::Duration::from_secs(10));
    unsafe { libc::kill(plant as i32, libc::SIGCONT) };
    let output = child.wait_with_output().unwrap();
    assert!(
        output.status.success(),
        "the run failed: {}: {}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(leftovers(&pre).is_empty(), "shared-memory files left");
    check_trace(&read_trace(&out), 3000, 1);
    let again = out.join("replay");
    let (code, err) = replay(&out, &again, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(bytes(&out.join("timeseries.csv")) == bytes(&again.join("timeseries.csv")));
}

/// Four free runs at once beside two CPU hogs, on a machine of two CPUs: every participant
/// falls behind, catches up in bursts and is starved again; every run completes, its trace
/// whole, and replays byte for byte.
#[test]
fn four_free_runs_beside_two_cpu_hogs_complete_and_replay_byte_for_byte() {
    let root = temp_dir("freerun-load");
    let _hogs = Hogs::start(2);
    std::thread::scope(|scope| {
        for i in 0..4 {
            let root = &root;
            scope.spawn(move || {
                let out = root.join(format!("run-{i}"));
                completes_and_replays(
                    &scenario("pi-drive.toml"),
                    &out,
                    "2",
                    &prefix(&format!("freerun-load-{i}")),
                );
            });
        }
    });
}

/// A free run's trace is refused while the run goes on. An orchestrator killed with SIGKILL
/// in the middle of a free run leaves whole rows and a prefix of its trace; `replay-timing` replays that prefix, says it is partial, and gives
/// the rows the free run had written, byte for byte.
#[test]
fn a_killed_free_run_leaves_a_trace_prefix_that_replays_its_rows() {
    let root = temp_dir("freerun-sigkill");
    let out = root.join("free");
    let pre = prefix("freerun-sigkill");
    let mut child = Tiltsim::run("pi-drive.toml")
        .free_run()
        .duration(10)
        .out(&out)
        .ipc_prefix(&pre)
        .quiet()
        .spawn();
    // Killed once a few thousand rows are on disk (rows are written in batches of 1000).
    tiltsim_suite::wait_for(std::time::Duration::from_secs(600), || {
        std::fs::read_to_string(out.join("timeseries.csv"))
            .ok()
            .filter(|t| t.lines().count() > 3000)
    })
    .expect("the rows never reached 3000");
    // While it runs, its trace is refused and nothing is written into its directory.
    let (code, _, err) = run(&["replay-timing", s(&out), "-q"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("timing.csv") && err.contains("still running"),
        "{err}"
    );
    assert!(!out.join("replay-timing").exists());
    child.kill().unwrap();
    child.wait().unwrap();
    // The participants see their orchestrator gone and end; its files are removed by `clean`.
    let (code, _, err) = run(&["clean"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        leftovers(&pre).is_empty(),
        "shared-memory files left after clean"
    );
    let again = root.join("replay");
    let (code, err) = replay(&out, &again, &[]);
    assert_eq!(code, 0, "{err}");
    let sm = summary(&again);
    assert!(
        sm["trace_partial"].is_string(),
        "the replay of a killed run's trace must say it is partial: {sm}"
    );
    let free = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let replayed = std::fs::read_to_string(again.join("timeseries.csv")).unwrap();
    // Whole lines only in the free run's file; the replay has as many rows as the trace holds
    // plant steps, which may be more or fewer than the rows on disk.
    let mut free: Vec<&str> = free.lines().collect();
    if !std::fs::read_to_string(out.join("timeseries.csv"))
        .unwrap()
        .ends_with('\n')
    {
        // A batch cut short by the kill: its last line is not a row.
        free.pop();
    }
    let replayed: Vec<&str> = replayed.lines().collect();
    let n = free.len().min(replayed.len());
    assert!(n > 1000, "{n} rows in common");
    assert_eq!(
        free[..n],
        replayed[..n],
        "the replay's rows differ from the free run's"
    );
}
