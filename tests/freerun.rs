//! The free-running mode and its exact lock-step replay (docs/architecture.md, "Execution
//! modes"). Nothing here asserts a wall-clock time or an age distribution: a free run on a
//! loaded machine is late, not failed. What is asserted holds whatever the load: the replay
//! gives the free run's bytes, causality in the trace (an input is read only after it was
//! published), and a study busy wait that lies between a controller's read and its publish.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use tiltsim_suite::{leftovers, prefix, run, scenario, summary, temp_dir, Hogs};

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// One line of `timing.csv`.
#[derive(Debug, Clone)]
struct Step {
    role: String,
    step: i64,
    /// Producer step read, by producer name.
    from: HashMap<String, i64>,
    due: u64,
    read: u64,
    compute_end: u64,
    publish: u64,
}

fn read_trace(dir: &Path) -> Vec<Step> {
    let text = std::fs::read_to_string(dir.join("timing.csv")).expect("timing.csv");
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("# tiltsim timing trace:"));
    let cols: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let at = |n: &str| c[cols.iter().position(|x| *x == n).unwrap()];
            let mut from = HashMap::new();
            for p in ["plant", "actuator", "controller"] {
                let v = at(&format!("from_{p}"));
                if !v.is_empty() {
                    from.insert(p.to_string(), v.parse().unwrap());
                }
            }
            Step {
                role: at("role").to_string(),
                step: at("step").parse().unwrap(),
                from,
                due: at("due_ns").parse().unwrap(),
                read: at("read_ns").parse().unwrap(),
                compute_end: at("compute_end_ns").parse().unwrap(),
                publish: at("publish_ns").parse().unwrap(),
            }
        })
        .collect()
}

/// A free run of pi-drive over IPC for `duration` s with `extra` arguments; must complete.
fn free_run(name: &str, duration: &str, extra: &[&str]) -> (PathBuf, String) {
    let out = temp_dir(name).join("free");
    let pre = prefix(name);
    let sc = scenario("pi-drive.toml");
    let mut args = vec![
        "run",
        s(&sc),
        "--free-run",
        "--duration",
        duration,
        "--out",
        s(&out),
        "--ipc-prefix",
        &pre,
        "-q",
    ];
    args.extend_from_slice(extra);
    let (code, _, err) = run(&args);
    assert_eq!(code, 0, "{name}: {err}");
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

/// Every step of every consumer is in the trace once, started no earlier than it was due, and
/// read only outputs that had been published before its read instant (causality of the relay:
/// a producer's output reaches the hub, then the consumer, after it was published).
fn check_trace(t: &[Step], steps: i64, controller_ticks: i64) {
    let mut by: HashMap<(String, i64), &Step> = HashMap::new();
    for x in t {
        assert!(
            by.insert((x.role.clone(), x.step), x).is_none(),
            "{} step {} twice",
            x.role,
            x.step
        );
        assert!(
            x.read >= x.due,
            "{} step {} read before it was due",
            x.role,
            x.step
        );
        assert!(x.read <= x.compute_end && x.compute_end <= x.publish);
    }
    for k in 0..steps {
        assert!(by.contains_key(&("plant".into(), k)));
        assert!(by.contains_key(&("actuator".into(), k)));
        if k % controller_ticks == 0 {
            assert!(by.contains_key(&("controller".into(), k)));
        }
    }
    for x in t {
        for (p, &q) in &x.from {
            if q >= 0 {
                let src = by[&(p.clone(), q)];
                assert!(
                    src.publish <= x.read,
                    "{} step {} read {p} step {q} before it was published",
                    x.role,
                    x.step
                );
            }
        }
    }
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

    // The replay follows the trace: plant step 1000 told it read the bar angle at t₀ instead
    // gives other rows from there on, and the same rows before.
    let edited = root.join("edited");
    std::fs::create_dir_all(&edited).unwrap();
    std::fs::copy(dir.join("scenario.toml"), edited.join("scenario.toml")).unwrap();
    let text = std::fs::read_to_string(dir.join("timing.csv")).unwrap();
    let changed: Vec<String> = text
        .lines()
        .map(|l| {
            if l.starts_with("plant,1000,") {
                let mut c: Vec<&str> = l.split(',').collect();
                c[3] = "-1";
                c.join(",")
            } else {
                l.to_string()
            }
        })
        .collect();
    std::fs::write(edited.join("timing.csv"), changed.join("\n") + "\n").unwrap();
    let (code, err) = replay(&edited, &root.join("edited-out"), &[]);
    assert_eq!(code, 0, "{err}");
    let other = bytes(&root.join("edited-out/timeseries.csv"));
    let lines = |b: &[u8]| {
        String::from_utf8_lossy(b)
            .lines()
            .map(String::from)
            .collect::<Vec<_>>()
    };
    let (a, b) = (lines(&free), lines(&other));
    assert_eq!(a[..1001], b[..1001], "rows before step 1000 are unchanged");
    assert_ne!(a[1001..], b[1001..], "the edited step changes what follows");

    // Another system under the same timing: twice the PI gain. Same time base, other commands.
    let resolved = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
    assert!(resolved.contains("\nkp = 0.5708\n"));
    let stiffer = root.join("stiffer.toml");
    std::fs::write(
        &stiffer,
        resolved.replace("\nkp = 0.5708\n", "\nkp = 1.1416\n"),
    )
    .unwrap();
    let (code, err) = replay(&dir, &root.join("kp"), &["--scenario", s(&stiffer)]);
    assert_eq!(code, 0, "{err}");
    let kp = tiltsim_suite::Series::read(&root.join("kp/timeseries.csv"));
    let base = tiltsim_suite::Series::read(&dir.join("timeseries.csv"));
    assert_eq!(kp.col("time"), base.col("time"));
    assert_ne!(kp.col("delta_a_cmd"), base.col("delta_a_cmd"));

    // A trace that does not belong to the scenario is refused naming the file and the field.
    let trace_file = dir.join("timing.csv");
    let name = trace_file.display().to_string();
    for (set, field) in [("run.dt_s=0.0005", "dt_s"), ("run.duration_s=1", "steps")] {
        let other = root.join(format!("foreign-{field}"));
        std::fs::create_dir_all(&other).unwrap();
        let (k, v) = set.split_once('=').unwrap();
        let text = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
        let mut doc: toml::Table = toml::from_str(&text).unwrap();
        let (sec, key) = k.split_once('.').unwrap();
        doc.get_mut(sec)
            .and_then(|t| t.as_table_mut())
            .unwrap()
            .insert(key.into(), toml::Value::Float(v.parse().unwrap()));
        let file = other.join("scenario.toml");
        std::fs::write(&file, toml::to_string(&doc).unwrap()).unwrap();
        let (code, err) = replay(&dir, &other.join("out"), &["--scenario", s(&file)]);
        assert_eq!(code, 2, "{field}: {err}");
        assert!(err.contains(&name) && err.contains(field), "{field}: {err}");
    }
    let gap = root.join("gap");
    std::fs::create_dir_all(&gap).unwrap();
    std::fs::copy(dir.join("scenario.toml"), gap.join("scenario.toml")).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with("actuator,500,"))
        .collect();
    std::fs::write(gap.join("timing.csv"), kept.join("\n") + "\n").unwrap();
    let (code, err) = replay(&gap, &root.join("gap-out"), &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("timing.csv") && err.contains("step") && err.contains("actuator step 500"),
        "{err}"
    );
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
    let sc = scenario("pi-drive.toml");
    let out = temp_dir("freerun-refused");
    let (code, _, err) = run(&[
        "run",
        s(&sc),
        "--free-run",
        "--transport",
        "in-process",
        "--out",
        s(&out),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("run.execution") && err.contains("ipc"),
        "{err}"
    );
    let degrading = scenario("fault-controller-killed.toml");
    let text = std::fs::read_to_string(&degrading).unwrap();
    assert!(text.contains("on_failure = \"degrade\""));
    let (code, _, err) = run(&["run", s(&degrading), "--free-run", "--out", s(&out)]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("run.execution") && err.contains("faults.on_failure"),
        "{err}"
    );
    let (code, _, err) = run(&[
        "run",
        s(&sc),
        "--set",
        "run.controller_busy_wait_s=0.001",
        "--out",
        s(&out),
    ]);
    assert_eq!(code, 2, "{err}");
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

/// pi-drive with effects on three links and a stalled controller, written beside `dir`.
fn with_links_and_a_stall(dir: &Path) -> PathBuf {
    let base = std::fs::read_to_string(scenario("pi-drive.toml")).unwrap();
    let file = dir.join("links-and-stall.toml");
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(
        &file,
        format!(
            "{base}
[links.actuator_command]
delay_ticks = 20

[links.bar_angle]
drop_probability = 0.1

[links.measurement]
noise_std = 1e-4

[[faults.schedule]]
participant = \"controller\"
action = \"stall\"
at_s = 1.0
stall_s = 0.2
"
        ),
    )
    .unwrap();
    file
}

#[test]
fn link_effects_and_a_stall_act_in_a_free_run_and_its_replay_repeats_them() {
    let root = temp_dir("freerun-links");
    let sc = with_links_and_a_stall(&root);
    let out = root.join("free");
    let pre = prefix("freerun-links");
    let (code, _, err) = run(&[
        "run",
        s(&sc),
        "--free-run",
        "--duration",
        "2",
        "--record",
        "--out",
        s(&out),
        "--ipc-prefix",
        &pre,
        "-q",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(leftovers(&pre).is_empty(), "shared-memory files left");
    let trace = read_trace(&out);
    check_trace(&trace, 2000, 1);
    let by: HashMap<(String, i64), &Step> = trace
        .iter()
        .map(|x| ((x.role.clone(), x.step), x))
        .collect();

    // The command link's 20 ticks are wall time added to the real delivery: no actuator step
    // read a command sooner than 20 ms after the controller published it. A lower bound on
    // instants the trace recorded, which load can only raise (no duration of the test).
    let mut commands = 0;
    for x in trace.iter().filter(|x| x.role == "actuator") {
        let q = x.from["controller"];
        if q >= 0 {
            commands += 1;
            let published = by[&("controller".to_string(), q)].publish;
            assert!(
                x.read >= published + 20_000_000,
                "actuator step {} read controller step {q} {} ns after its publish",
                x.step,
                x.read - published
            );
        }
    }
    assert!(commands > 1000, "{commands} actuator steps read a command");

    // Lost bar-angle samples: each drawn from the seed per sample (so their number does not
    // depend on the timing), logged, and never read by the plant.
    let events = csv_rows(&out.join("events.csv"));
    let dropped: Vec<i64> = events
        .iter()
        .filter(|e| e["source"] == "bar_angle" && e["event"] == "drop")
        .map(|e| e["step"].parse().unwrap())
        .collect();
    // p = 0.1 over the 2000 samples of the run: 200 ± 6σ (σ = 13.4).
    assert!(
        (120..=280).contains(&dropped.len()),
        "{} drops",
        dropped.len()
    );
    for q in &dropped {
        for x in trace.iter().filter(|x| x.role == "plant") {
            assert_ne!(
                x.from["actuator"], *q,
                "plant step {} read a lost sample",
                x.step
            );
        }
    }

    // The noise reaches the controller: for row k, follow the trace from plant step k to the
    // actuator step it read, the controller step that one read and the plant step that one
    // read; what the controller received less what that plant step measured is the noise,
    // Gaussian with the declared deviation: 1e-4 within 6σ of a deviation estimated from the
    // n distinct samples read (σ/σ ≈ 1/√(2(n−1))), mean within 6σ/√n. How many distinct
    // samples the rows reach depends on the timing (a late or stalled step reads one for
    // several rows); without the noise every difference would be 0.
    let rows = csv_rows(&out.join("timeseries.csv"));
    let num = |r: &HashMap<String, String>, c: &str| r[c].parse::<f64>().unwrap();
    // Each plant sample's noise once (a stalled controller reads one sample for many rows).
    let mut noise_of: HashMap<i64, f64> = HashMap::new();
    // Row k + 1 holds plant step k (row 0 the outputs at the start time).
    for (k, r) in rows.iter().enumerate().skip(1).map(|(i, r)| (i - 1, r)) {
        let qa = by[&("plant".to_string(), k as i64)].from["actuator"];
        if qa < 0 {
            continue;
        }
        let qc = by[&("actuator".to_string(), qa)].from["controller"];
        if qc < 0 {
            continue;
        }
        let qp = by[&("controller".to_string(), qc)].from["plant"];
        if qp < 0 {
            continue;
        }
        noise_of.insert(
            qp,
            num(r, "rx_measurement") - num(&rows[qp as usize + 1], "theta_v_meas"),
        );
    }
    let noise: Vec<f64> = noise_of.into_values().collect();
    let n = noise.len() as f64;
    assert!(n >= 200.0, "{n} measurements traced back from the rows");
    let mean = noise.iter().sum::<f64>() / n;
    let sd = (noise.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let tolerance = 6.0 / (2.0 * (n - 1.0)).sqrt();
    assert!(
        (sd / 1e-4 - 1.0).abs() < tolerance,
        "noise deviation {sd} over {n} samples"
    );
    assert!(mean.abs() < 6.0 * 1e-4 / n.sqrt(), "noise mean {mean}");

    // The stall: SIGSTOP for 0.2 s of wall time when the plant reached 1.0 s. The controller
    // step due next started at least the rest of the stall late (a 1 ms period: > 0.15 s).
    assert!(events.iter().any(|e| e["source"] == "controller"
        && e["event"] == "fault-injected"
        && e["step"] == "1000"));
    let late = trace
        .iter()
        .filter(|x| x.role == "controller")
        .map(|x| x.read - x.due)
        .max()
        .unwrap();
    assert!(
        late >= 150_000_000,
        "the controller was at most {late} ns late"
    );

    recording_holds_the_trace(&out, &by);

    // The replay repeats the values and the events, byte for byte.
    let (code, err) = replay(&out, &root.join("replay"), &[]);
    assert_eq!(code, 0, "{err}");
    for f in ["timeseries.csv", "events.csv"] {
        assert_eq!(
            bytes(&root.join("replay").join(f)),
            bytes(&out.join(f)),
            "{f}"
        );
    }
    // And gives the comfort of what was replayed, as the free run's summary does.
    let free = summary(&out);
    let again = summary(&root.join("replay"));
    assert_eq!(free["comfort"], again["comfort"]);
    assert!(
        free["comfort"]["p_ct_en12299"]["standing_pct"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    // Every flag of the series is the replay's; the real-time judgement is the free run's
    // own (a replay is a lock-step run, which has none).
    let mut free_flags = free["flags"].clone();
    assert!(free_flags
        .as_object_mut()
        .unwrap()
        .remove("not_real_time")
        .is_some());
    assert_eq!(free_flags, again["flags"]);
    assert!(again["flags"].get("not_real_time").is_none());
}

/// `--record` of a free run: the lock-step recording's channels and the trace as
/// `/timing/<role>`, one message per step, in log-time order, read by the Python registry's
/// `mcap` reader (as tests/record.rs reads lock-step recordings) and by the Rust one.
fn recording_holds_the_trace(dir: &Path, by: &HashMap<(String, i64), &Step>) {
    let file = dir.join("run.mcap");
    let check = tiltsim_suite::root().join("tests/record/mcap_check.py");
    let (code, out, err) = tiltsim_suite::fmi_tool("python", &[s(&check), s(&file)]);
    assert_eq!(code, 0, "mcap_check.py: {err}");
    let r: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(r["order"], 0, "messages out of log-time order");
    assert_eq!(r["compression"], serde_json::json!(["zstd"]));
    assert_eq!(r["plant_time"], 0, "/plant/out log time is not its t");
    for topic in [
        "/timing/plant",
        "/timing/actuator",
        "/timing/controller",
        "/actuator/in",
    ] {
        assert_eq!(r["counts"][topic], 2000, "{topic}");
    }
    // Every step's output and the outputs at t = 0.
    assert_eq!(r["counts"]["/plant/out"], 2001);
    assert_eq!(r["schema_names"]["/events"], "foxglove.Log");
    for (topic, fields) in r["schemas"].as_object().unwrap() {
        if topic == "/events" {
            continue;
        }
        for (field, ty) in fields.as_object().unwrap() {
            let want = if field == "step" { "integer" } else { "number" };
            assert_eq!(ty, want, "{topic}.{field}");
        }
    }
    // Each timing message is its step's line of timing.csv; each actuator input's command is
    // the output of the controller step the trace says it read.
    let bytes = std::fs::read(&file).unwrap();
    let mut checked = 0;
    let mut commands: HashMap<u64, f64> = HashMap::new();
    let mut inputs: HashMap<u64, f64> = HashMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        // `/summary` and `/perf` have no step.
        let step = v["step"].as_u64().unwrap_or(u64::MAX);
        match m.channel.topic.as_str() {
            "/timing/plant" | "/timing/actuator" | "/timing/controller" => {
                let role = m.channel.topic.trim_start_matches("/timing/");
                let x = by[&(role.to_string(), step as i64)];
                assert_eq!(
                    v["read_ns"].as_f64().unwrap() as u64,
                    x.read,
                    "{role} {step}"
                );
                assert_eq!(v["publish_ns"].as_f64().unwrap() as u64, x.publish);
                for (p, q) in &x.from {
                    assert_eq!(v[format!("from_{p}")].as_f64().unwrap() as i64, *q);
                }
                assert_eq!(m.log_time, step * 1_000_000);
                checked += 1;
            }
            "/controller/out" => {
                commands.insert(step, v["delta_a_cmd"].as_f64().unwrap());
            }
            "/actuator/in" => {
                inputs.insert(step, v["delta_a_cmd"].as_f64().unwrap());
            }
            _ => {}
        }
    }
    assert_eq!(checked, 6000);
    assert_eq!((commands.len(), inputs.len()), (2000, 2000));
    let mut traced = 0;
    for (k, cmd) in &inputs {
        let q = by[&("actuator".to_string(), *k as i64)].from["controller"];
        if q >= 0 {
            traced += 1;
            assert_eq!(
                *cmd,
                commands[&(q as u64)],
                "actuator step {k} read controller step {q}"
            );
        }
    }
    assert!(
        traced > 1000,
        "{traced} actuator steps read a controller output"
    );
}

#[test]
fn a_participant_killed_in_a_free_run_is_named_and_the_rows_before_are_kept() {
    let root = temp_dir("freerun-kill");
    let base = std::fs::read_to_string(scenario("pi-drive.toml")).unwrap();
    let sc = root.join("killed.toml");
    std::fs::write(
        &sc,
        format!(
            "{base}\n[[faults.schedule]]\nparticipant = \"actuator\"\naction = \"kill\"\nat_s = 0.5\n"
        ),
    )
    .unwrap();
    let out = root.join("free");
    let pre = prefix("freerun-kill");
    let (code, _, err) = run(&[
        "run",
        s(&sc),
        "--free-run",
        "--duration",
        "2",
        "--out",
        s(&out),
        "--ipc-prefix",
        &pre,
        "-q",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("actuator"), "{err}");
    assert!(leftovers(&pre).is_empty(), "shared-memory files left");
    let sm = summary(&out);
    assert_eq!(sm["status"], "failed");
    let rows = sm["steps_completed"].as_u64().unwrap();
    // The world went on until the loss was seen: at least the 500 steps before it (how many
    // after depends on how soon the hub saw the process gone).
    assert!(rows >= 500, "{rows} rows");
    let series = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    // The header, the start time and every step.
    assert_eq!(series.lines().count() as u64, rows + 2);
}

/// pi-drive with `faults` (TOML of `[[faults.schedule]]` tables) appended, written as
/// `dir/name.toml`.
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
    let (code, _, err) = run(&[
        "run",
        s(sc),
        "--free-run",
        "--duration",
        duration,
        "--out",
        s(out),
        "--ipc-prefix",
        pre,
        "-q",
    ]);
    assert_eq!(code, 0, "{}: {err}", sc.display());
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
    let sc = scenario("pi-drive.toml");
    let child = tiltsim_suite::spawn(&[
        "run",
        s(&sc),
        "--free-run",
        "--duration",
        "3",
        "--out",
        s(&out),
        "--ipc-prefix",
        &pre,
        "-q",
    ]);
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

/// An orchestrator killed with SIGKILL in the middle of a free run leaves whole rows and a
/// prefix of its trace; `replay-timing` replays that prefix, says it is partial, and gives
/// the rows the free run had written, byte for byte.
#[test]
fn a_killed_free_run_leaves_a_trace_prefix_that_replays_its_rows() {
    let root = temp_dir("freerun-sigkill");
    let out = root.join("free");
    let pre = prefix("freerun-sigkill");
    let sc = scenario("pi-drive.toml");
    let mut child = tiltsim_suite::spawn(&[
        "run",
        s(&sc),
        "--free-run",
        "--duration",
        "10",
        "--out",
        s(&out),
        "--ipc-prefix",
        &pre,
        "-q",
    ]);
    // Killed once a few thousand rows are on disk (rows are written in batches of 1000).
    tiltsim_suite::wait_for(std::time::Duration::from_secs(600), || {
        std::fs::read_to_string(out.join("timeseries.csv"))
            .ok()
            .filter(|t| t.lines().count() > 3000)
    })
    .expect("the rows never reached 3000");
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
