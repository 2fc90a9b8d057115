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
        assert_eq!(r["schema_names"]["/summary"], "tiltsim.Summary", "{name}");
        assert_eq!(r["schema_names"]["/perf"], "tiltsim.Perf", "{name}");
        assert_eq!(
            r["schemas"]["/summary"]["wall_clock_fields"], "array",
            "{name}"
        );
        for field in ["timestamp", "level", "message", "name"] {
            assert!(
                r["schemas"]["/events"][field].is_string(),
                "{name}: /events.{field}"
            );
        }
        for (topic, fields) in r["schemas"].as_object().unwrap() {
            // The events, the summary and perf.json are typed objects of their own.
            if ["/events", "/summary", "/perf"].contains(&topic.as_str()) {
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

/// What `mcap_join.py` finds joining every channel of `mcap` with `dir`'s `timeseries.csv` on
/// `step` under `master`.
fn joined(mcap: &Path, dir: &Path, master: &str) -> serde_json::Value {
    let check = root().join("tests/outside/mcap/mcap_join.py");
    let table = dir.join("timeseries.csv");
    let args = [check.to_str().unwrap(), mcap.to_str().unwrap()];
    let (code, out, err) = fmi_tool(
        "python",
        &[args[0], args[1], table.to_str().unwrap(), master],
    );
    assert_eq!(code, 0, "mcap_join.py: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"))
}

#[test]
fn every_channel_joins_the_table_on_step_value_for_value() {
    // Every link changes what it carries (a delay, jitter, noise, a bias), so a channel one
    // row off the table's `rx_*` columns differs; the controller steps every 5 ticks.
    for master in ["gauss-seidel", "jacobi"] {
        let dir = temp_dir(&format!("record-join-{master}")).join("run");
        Tiltsim::run("latency-command-jitter.toml")
            .out(&dir)
            .transport_in_process()
            .master(master)
            .duration(3)
            .set("controller.period_s", 0.005)
            .set("links.measurement.noise_std", 0.001)
            .set("links.bar_twist.bias", 0.0005)
            .set("links.bar_angle.delay_ticks", 2)
            .record()
            .quiet()
            .success();
        let live = dir.join("live.mcap");
        std::fs::rename(dir.join("run.mcap"), &live).unwrap();
        let (code, _, err) = run(&["export-mcap", dir.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        for file in [live, dir.join("run.mcap")] {
            let r = joined(&file, &dir, master);
            let name = format!("{master} {}", file.display());
            let channels = [
                "/plant/in",
                "/plant/out",
                "/actuator/in",
                "/actuator/out",
                "/controller/in",
                "/controller/out",
                "/links/actuator_command",
                "/links/bar_angle",
                "/links/measurement",
                "/links/bar_twist",
                "/events",
                "/summary",
                "/perf",
            ];
            let topics: Vec<&String> = r.as_object().unwrap().keys().collect();
            assert_eq!(topics.len(), channels.len(), "{name}: {topics:?}");
            for topic in channels {
                let c = &r[topic];
                assert!(c["messages"].as_u64().unwrap() > 0, "{name}: {topic}");
                if !["/summary", "/perf"].contains(&topic) {
                    assert!(c["values"].as_u64().unwrap() > 0, "{name}: {topic}");
                }
                assert_eq!(c["differ"], 0, "{name}: {topic}: {}", c["mismatches"]);
            }
            // 3 s of 1 ms ticks, the outputs at t = 0 besides; a controller step every 5.
            assert_eq!(r["/plant/out"]["messages"], 3001, "{name}");
            assert_eq!(r["/plant/in"]["messages"], 3000, "{name}");
            assert_eq!(r["/controller/out"]["messages"], 600, "{name}");
        }
    }
}
