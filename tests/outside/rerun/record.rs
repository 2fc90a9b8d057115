//! A run exported for Rerun (`scripts/to-rerun.py`, Rerun's SDK) and read back by Rerun's own
//! `rerun` command: every signal a Scalars series on simulated time, with the CSV's values.

use tiltsim_suite::{csv_table, fmi_tool, root, temp_dir, Tiltsim};

/// The rows of one entity's chunk in `rerun rrd print -vvv`: (time in s, value).
fn rerun_rows(printed: &str, entity: &str) -> Vec<(f64, f64)> {
    let mut rows = Vec::new();
    let mut inside = false;
    for line in printed.lines() {
        if line.starts_with("Chunk(") {
            inside = line.contains(&format!(" - {entity} -"));
            continue;
        }
        if !inside || !line.contains("row_") {
            continue;
        }
        // "│ │ row_… ┆ PT0.004S ┆ [7.406447632314828e-11] │ │"
        let cells: Vec<&str> = line.split('┆').map(str::trim).collect();
        // An ISO 8601 duration: `PT0.004S`, and zero as `P0D`.
        let time = match cells[1] {
            "P0D" => "0",
            d => d.trim_start_matches("PT").trim_end_matches('S'),
        };
        let value = cells[2]
            .split(['[', ']'])
            .nth(1)
            .unwrap_or_else(|| panic!("{line}"));
        rows.push((time.parse().unwrap(), value.parse().unwrap()));
    }
    rows
}

#[test]
fn a_run_exported_for_rerun_holds_every_signal_as_scalars_on_simulated_time() {
    let dir = temp_dir("rerun").join("run");
    Tiltsim::run("paper-lqg.toml")
        .duration(0.5)
        .transport_in_process()
        .out(&dir)
        .quiet()
        .success();
    let script = root().join("scripts/to-rerun.py");
    let (code, out, err) = fmi_tool("python", &[script.to_str().unwrap(), dir.to_str().unwrap()]);
    assert_eq!(code, 0, "to-rerun.py: {err}");
    // The start time and 500 ticks.
    assert!(out.contains("501 rows"), "{out}");
    let rrd = dir.join("run.rrd");
    let rrd = rrd.to_str().unwrap();
    // Rerun's own tools: the file loads, and every signal of the CSV is a Scalars series.
    let (code, _, err) = fmi_tool("rerun", &["rrd", "verify", rrd]);
    assert_eq!(code, 0, "rerun rrd verify: {err}");
    let (code, listing, err) = fmi_tool("rerun", &["rrd", "print", rrd]);
    assert_eq!(code, 0, "rerun rrd print: {err}");
    let csv = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
    let table = csv_table(&csv);
    for col in &table[0][2..] {
        let line = listing
            .lines()
            .find(|l| l.ends_with(&format!("/{col} - data columns: [Scalars:scalars]")))
            .unwrap_or_else(|| panic!("{col} is not a Scalars series in Rerun:\n{listing}"));
        assert!(line.contains("with 501 rows"), "{line}");
    }
    // The values Rerun decodes are the CSV's, at the CSV's times.
    let (code, printed, err) = fmi_tool("rerun", &["rrd", "print", "-vvv", rrd]);
    assert_eq!(code, 0, "{err}");
    let rows = rerun_rows(&printed, "/plant/lat_acc");
    assert_eq!(rows.len(), 501);
    let t = table[0].iter().position(|c| c == "time").unwrap();
    let a = table[0].iter().position(|c| c == "lat_acc").unwrap();
    for (r, (time, value)) in table[1..].iter().zip(&rows) {
        // Rerun keeps a duration in whole nanoseconds.
        let ns = |s: f64| (s * 1e9).round() as i64;
        assert_eq!(ns(*time), ns(r[t].parse::<f64>().unwrap()));
        assert_eq!(*value, r[a].parse::<f64>().unwrap());
    }
}
