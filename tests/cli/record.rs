//! MCAP recordings and replay of one participant: a recorded fault run replays
//! byte for byte for every participant, a changed setting is found where it first acts, and
//! the recording's messages repeat across transports.

use std::collections::BTreeMap;
use std::path::Path;

use tiltsim_suite::{csv_table, prefix, run, temp_dir, Tiltsim};

/// A recording's messages: topic → (sequence, log time, data).
type Messages = BTreeMap<String, Vec<(u32, u64, String)>>;

/// Every message of a recording, publish time left out.
fn messages(path: &Path) -> Messages {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out: BTreeMap<String, Vec<(u32, u64, String)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        out.entry(m.channel.topic.clone()).or_default().push((
            m.sequence,
            m.log_time,
            String::from_utf8(m.data.to_vec()).unwrap(),
        ));
    }
    out
}

fn record(file: &str, dir: &Path, transport: &str) {
    record_with(file, dir, transport, &[]);
}

fn record_with(file: &str, dir: &Path, transport: &str, extra: &[&str]) {
    let pfx = prefix(&format!(
        "rec-{transport}-{}",
        file.trim_end_matches(".toml")
    ));
    Tiltsim::run(file)
        .out(dir)
        .transport(transport)
        .ipc_prefix(&pfx)
        .record()
        .quiet()
        .args(extra)
        .success();
    if let Some(i) = extra.iter().position(|a| *a == "--master") {
        assert_eq!(
            tiltsim_suite::summary(dir)["master_algorithm"],
            extra[i + 1]
        );
    }
}

/// The link channel of recording `m` of run `dir` says what was sent and what arrived: inside
/// the window the NaN that arrived is left out of the message (JSON has no NaN), and the
/// received values are the timeseries' rx column.
fn links_are_the_timeseries(m: &Messages, dir: &Path) {
    let csv = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
    let rows = csv_table(&csv);
    let col = rows[0].iter().position(|c| c == "rx_measurement").unwrap();
    for (k, (_, log, data)) in m["/links/measurement"].iter().enumerate() {
        // Tick k's exchange is row k + 1 of the table, at its time.
        assert_eq!(*log, (k as u64 + 1) * 1_000_000);
        let v: serde_json::Value = serde_json::from_str(data).unwrap();
        assert_eq!(v["step"].as_u64(), Some(k as u64 + 1), "{data}");
        // Line 0 is the header, line 1 the start time: row k + 1 is line k + 2.
        let rx = &rows[k + 2][col];
        if rx == "NaN" {
            assert!(
                v.get("received").is_none() && v["sent"].is_number(),
                "{data}"
            );
        } else {
            assert_eq!(v["received"].as_f64().unwrap(), rx.parse::<f64>().unwrap());
        }
    }
    assert!(
        m["/links/measurement"]
            .iter()
            .filter(|x| !x.2.contains("\"received\":"))
            .count()
            == 200
    );
}

/// The plant's and the actuator's outputs in the recording are the rows of `timeseries.csv`:
/// message `step` k holds the values of row k (line k + 1), at log time t_k, beginning with
/// the outputs at t = 0.
fn outputs_are_the_timeseries_rows(m: &Messages, dir: &Path) {
    let csv = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
    let rows = csv_table(&csv);
    for (topic, field) in [("/plant/out", "theta_v"), ("/actuator/out", "delta_a")] {
        let col = rows[0].iter().position(|c| c == field).unwrap();
        assert_eq!(
            m[topic].len(),
            rows.len() - 1,
            "{topic}: one message per row"
        );
        for (k, (_, log, data)) in m[topic].iter().enumerate() {
            let v: serde_json::Value = serde_json::from_str(data).unwrap();
            assert_eq!(v["step"].as_u64(), Some(k as u64), "{topic}: {data}");
            assert_eq!(*log, k as u64 * 1_000_000, "{topic}: {data}");
            let want: f64 = rows[k + 1][col].parse().unwrap();
            assert_eq!(v[field].as_f64(), Some(want), "{topic} step {k}");
        }
    }
}

/// The events are `foxglove.Log` messages at their ticks, with the columns of `events.csv`.
fn events_are_log_messages(m: &Messages, dir: &Path) {
    let csv = std::fs::read_to_string(dir.join("events.csv")).unwrap();
    let rows = csv_table(&csv);
    assert_eq!(m["/events"].len(), rows.len() - 1);
    for ((_, log, data), row) in m["/events"].iter().zip(&rows[1..]) {
        let v: serde_json::Value = serde_json::from_str(data).unwrap();
        let step: u64 = row[1].parse().unwrap();
        assert_eq!(v["step"].as_u64(), Some(step), "{data}");
        let ns = v["timestamp"]["sec"].as_u64().unwrap() * 1_000_000_000
            + v["timestamp"]["nsec"].as_u64().unwrap();
        assert_eq!((ns, *log), (step * 1_000_000, step * 1_000_000), "{data}");
        assert_eq!(v["name"], row[2].as_str(), "{data}");
        assert_eq!(v["kind"], row[3].as_str(), "{data}");
        assert!(
            v["message"].as_str().unwrap().starts_with(&row[3]),
            "{data}"
        );
        assert!((1..=5).contains(&v["level"].as_u64().unwrap()), "{data}");
    }
}

/// Participant `role` replayed alone on `transport` against what it received in run `dir`
/// (recording `m`): every output identical, the replayed outputs the recorded messages byte
/// for byte.
fn replays_identically(m: &Messages, dir: &Path, role: &str, transport: &str) {
    let out = dir.join(format!("replay-{role}-{transport}"));
    let (code, stdout, err) = run(&[
        "replay",
        dir.to_str().unwrap(),
        "--participant",
        role,
        "--transport",
        transport,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        stdout.contains("every output identical"),
        "{role}: {stdout}"
    );
    // The replayed outputs are the recorded messages, byte for byte.
    let replayed = std::fs::read_to_string(out.join(format!("{role}-out.jsonl"))).unwrap();
    let recorded: String = m[&format!("/{role}/out")]
        .iter()
        .map(|x| format!("{}\n", x.2))
        .collect();
    assert!(replayed == recorded, "{role}");
}

#[test]
fn a_recorded_fault_run_replays_byte_for_byte_and_a_changed_gain_is_found() {
    let dir = temp_dir("record-nan").join("run");
    record("fault-measurement-nan.toml", &dir, "ipc");
    let m = messages(&dir.join("run.mcap"));
    // Every tick of every participant (the PI runs every tick), every link, the summary.
    for topic in ["/plant/in", "/actuator/in", "/controller/out"] {
        assert_eq!(m[topic].len(), 16_800, "{topic}");
    }
    assert_eq!(m["/summary"].len(), 1);
    links_are_the_timeseries(&m, &dir);
    outputs_are_the_timeseries_rows(&m, &dir);
    events_are_log_messages(&m, &dir);
    // Each participant alone, against what it received: identical outputs, in this process
    // and as its own process over iceoryx2.
    for (role, transport) in [
        ("plant", "in-process"),
        ("actuator", "ipc"),
        ("controller", "in-process"),
        ("controller", "ipc"),
    ] {
        replays_identically(&m, &dir, role, transport);
    }
    // A changed PI gain: the controller's first command already differs. At tick 0 (row 1 of
    // the table, the recording's step 1) the command is (K_p + K_i·dt)·e (the integral has taken its first step), so the ratio of
    // the two commands is (0.6 + 2.2831e-3) / (0.5708 + 2.2831e-3).
    let text = std::fs::read_to_string(dir.join("scenario.toml")).unwrap();
    assert!(text.contains("kp = 0.5708"));
    let changed = dir.join("changed.toml");
    // `replay` builds the participant from a scenario file; it takes no `--set`.
    std::fs::write(&changed, text.replace("kp = 0.5708", "kp = 0.6")).unwrap();
    let out = dir.join("replay-changed");
    let (code, stdout, err) = run(&[
        "replay",
        dir.to_str().unwrap(),
        "--participant",
        "controller",
        "--scenario",
        changed.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("replay.json")).unwrap()).unwrap();
    assert_eq!(r["identical"], false, "{stdout}");
    let d = &r["first_difference"];
    assert_eq!(d["step"], 1);
    assert_eq!(d["field"], "delta_a_cmd");
    let ratio = d["replayed"].as_f64().unwrap() / d["recorded"].as_f64().unwrap();
    let expected = (0.6 + 2.2831e-3) / (0.5708 + 2.2831e-3);
    assert!((ratio - expected).abs() < 1e-12, "{ratio} vs {expected}");
}

#[test]
fn a_killed_controller_replays_up_to_its_loss_and_recordings_repeat_across_transports() {
    let base = temp_dir("record-kill");
    let (ipc, inproc) = (base.join("ipc"), base.join("in-process"));
    record("fault-controller-killed.toml", &ipc, "ipc");
    record("fault-controller-killed.toml", &inproc, "in-process");
    let (a, b) = (
        messages(&ipc.join("run.mcap")),
        messages(&inproc.join("run.mcap")),
    );
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for topic in a.keys() {
        // `/perf` is the wall clock; `/summary` names the transport.
        if topic == "/perf" || topic == "/summary" {
            continue;
        }
        assert!(a[topic] == b[topic], "{topic} differs between transports");
    }
    assert!(a["/events"]
        .iter()
        .any(|e| e.2.contains("\"kind\":\"fault-injected\"")));
    let (code, stdout, err) = run(&[
        "replay",
        ipc.to_str().unwrap(),
        "--participant",
        "controller",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        stdout.contains("8000 steps replayed, every output identical")
            && stdout.contains("lost at step 8000"),
        "{stdout}"
    );
    // A run without a recording: a clear error.
    let (code, _, err) = run(&["replay", base.to_str().unwrap(), "--participant", "plant"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("run.mcap") || err.contains("scenario.toml"),
        "{err}"
    );
}

#[test]
fn a_finished_run_exported_holds_the_messages_recorded_live_under_both_masters() {
    for (master, file) in [
        ("gauss-seidel", "fault-controller-killed.toml"),
        ("jacobi", "latency-command-jitter.toml"),
    ] {
        let dir = temp_dir(&format!("export-{master}")).join("run");
        record_with(file, &dir, "in-process", &["--master", master]);
        let live = dir.join("live.mcap");
        std::fs::rename(dir.join("run.mcap"), &live).unwrap();
        let (code, _, err) = run(&["export-mcap", dir.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        let (a, b) = (messages(&live), messages(&dir.join("run.mcap")));
        assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
        for topic in a.keys() {
            assert!(a[topic] == b[topic], "{master}: {topic} differs");
        }
    }
}
