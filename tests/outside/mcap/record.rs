//! MCAP recordings as an outside reader sees them: the Python registry's `mcap` reader finds
//! the messages in log-time order, compressed, typed for plotting, and the shipped layout's
//! paths in them.

use std::path::Path;

use tiltsim_suite::{fmi_tool, root, run, temp_dir, Tiltsim};

/// What a reader from the Python registry (`mcap` 1.6.0, tests/outside/mcap/mcap_check.py) finds in
/// a recording of `dir`.
fn registry_check(mcap: &Path) -> serde_json::Value {
    let check = root().join("tests/outside/mcap/mcap_check.py");
    let (code, out, err) = fmi_tool("python", &[check.to_str().unwrap(), mcap.to_str().unwrap()]);
    assert_eq!(code, 0, "mcap_check.py: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"))
}

#[test]
fn recordings_read_by_an_outside_reader_are_in_order_compressed_and_typed_for_plotting() {
    // A run with events during the run (the NaN window opens and closes) and a fault, live
    // and exported from its files.
    let dir = temp_dir("record-order").join("run");
    Tiltsim::run("fault-measurement-nan.toml")
        .out(&dir)
        .transport_in_process()
        .record()
        .quiet()
        .success();
    let live = dir.join("live.mcap");
    std::fs::rename(dir.join("run.mcap"), &live).unwrap();
    let (code, _, err) = run(&["export-mcap", dir.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    for file in [live, dir.join("run.mcap")] {
        let r = registry_check(&file);
        let name = file.display();
        // `mcap doctor --strict-message-order` fails a file whose log times go back.
        assert_eq!(r["order"], 0, "{name}: messages out of log-time order");
        assert_eq!(r["compression"], serde_json::json!(["zstd"]), "{name}");
        // The plant's output of tick k holds at t = (k+1)·dt: its log time.
        assert_eq!(
            r["plant_time"], 0,
            "{name}: /plant/out log time is not its t"
        );
        // Every tick's output and the outputs at t = 0.
        assert_eq!(r["counts"]["/plant/out"], 16_801, "{name}");
        assert!(r["counts"]["/events"].as_u64().unwrap() >= 2, "{name}");
        // Lichtblick reads a field typed "number" as a float and plots it; it refuses a
        // union such as ["number","null"]. Every field but the tick is a number.
        // The events are Foxglove log messages, which its log panel lists.
        assert_eq!(r["schema_names"]["/events"], "foxglove.Log", "{name}");
        for field in ["timestamp", "level", "message", "name"] {
            assert!(
                r["schemas"]["/events"][field].is_string(),
                "{name}: /events.{field}"
            );
        }
        for (topic, fields) in r["schemas"].as_object().unwrap() {
            if topic == "/events" {
                continue;
            }
            for (field, ty) in fields.as_object().unwrap() {
                let want = if field == "step" { "integer" } else { "number" };
                assert_eq!(ty, want, "{name}: {topic}.{field}");
            }
        }
        assert!(
            r["schemas"]["/actuator/out"]
                .as_object()
                .unwrap()
                .contains_key("actuator_limits"),
            "{name}: the CSV's name for the drive's limits"
        );
        // The shipped Foxglove/Lichtblick layout plots only what a recording holds.
        let layout = root().join("docs/layouts/tiltsim-plots.json");
        let layout: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&layout).unwrap()).unwrap();
        for panel in layout["configById"].as_object().unwrap().values() {
            for path in panel["paths"].as_array().unwrap() {
                let path = path["value"].as_str().unwrap();
                let (topic, field) = path.split_once('.').unwrap();
                assert_eq!(
                    r["schemas"][topic][field], "number",
                    "{name}: layout path {path}"
                );
            }
        }
    }
}
