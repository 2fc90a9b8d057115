//! The recording (`--record`) of a free run checked against its trace.

use std::collections::HashMap;
use std::path::Path;

use super::s;
use super::trace::Step;

/// `--record` of a free run: the lock-step recording's channels and the trace as
/// `/timing/<role>`, one message per step, in log-time order, read by the Python registry's
/// `mcap` reader (as tests/cli/record.rs reads lock-step recordings) and by the Rust one.
pub fn recording_holds_the_trace(dir: &Path, by: &HashMap<(String, i64), &Step>) {
    let file = dir.join("run.mcap");
    let check = tiltsim_suite::root().join("tests/outside/mcap/mcap_check.py");
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
        // The events, the summary and perf.json are typed objects of their own.
        if ["/events", "/summary", "/perf"].contains(&topic.as_str()) {
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
            // What tick k exchanged is step k + 1, the table's row that holds it.
            "/controller/out" => {
                commands.insert(step - 1, v["delta_a_cmd"].as_f64().unwrap());
            }
            "/actuator/in" => {
                inputs.insert(step - 1, v["delta_a_cmd"].as_f64().unwrap());
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
