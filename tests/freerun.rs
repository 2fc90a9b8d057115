//! The free-running mode and its exact lock-step replay (docs/architecture.md, "Execution
//! modes"). Nothing here asserts a wall-clock time or an age distribution: a free run on a
//! loaded machine is late, not failed. What is asserted holds whatever the load: the replay
//! gives the free run's bytes, causality in the trace (an input is read only after it was
//! published), and a study busy wait that lies between a controller's read and its publish.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use tiltsim_suite::{leftovers, prefix, run, scenario, summary, temp_dir};

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
    assert!(sm["not_real_time"].is_boolean());
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
    assert!(free["comfort"]["p_ct"]["standing_pct"].as_f64().unwrap() > 0.0);
    assert_eq!(free["flags"], again["flags"]);
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
        "/plant/out",
        "/actuator/in",
    ] {
        assert_eq!(r["counts"][topic], 2000, "{topic}");
    }
    for (topic, fields) in r["schemas"].as_object().unwrap() {
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
