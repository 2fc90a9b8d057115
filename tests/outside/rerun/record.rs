//! A run exported for Rerun (`scripts/to-rerun.py`, Rerun's SDK) and read back by Rerun's own
//! `rerun` command: every signal a Scalars series on simulated time, with the CSV's values.

use tiltsim_suite::{csv_table, fmi_tool, root, temp_dir, Tiltsim};

/// An ISO 8601 duration as Rerun prints one (`PT0.004S`, `PT1M2.5S`, zero as `P0D`) in whole
/// nanoseconds, read digit by digit: no float rounds it.
fn duration_ns(d: &str) -> u64 {
    if d == "P0D" {
        return 0;
    }
    let t = d.strip_prefix("PT").unwrap_or_else(|| panic!("{d}"));
    let (mut ns, mut rest) = (0u64, t);
    for (unit, scale) in [('H', 3_600_000_000_000u64), ('M', 60_000_000_000)] {
        if let Some((n, r)) = rest.split_once(unit) {
            ns += n.parse::<u64>().unwrap() * scale;
            rest = r;
        }
    }
    if let Some(s) = rest.strip_suffix('S') {
        let (whole, frac) = s.split_once('.').unwrap_or((s, ""));
        assert!(frac.len() <= 9, "{d}: finer than a nanosecond");
        let frac: u64 = format!("{frac:0<9}").parse().unwrap();
        ns += whole.parse::<u64>().unwrap() * 1_000_000_000 + frac;
    }
    ns
}

/// The rows of one entity's chunk in `rerun rrd print -vvv`: (time in ns, value).
fn rerun_rows(printed: &str, entity: &str) -> Vec<(u64, f64)> {
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
        let value = cells[2]
            .split(['[', ']'])
            .nth(1)
            .unwrap_or_else(|| panic!("{line}"));
        rows.push((duration_ns(cells[1]), value.parse().unwrap()));
    }
    rows
}

#[test]
fn a_run_exported_for_rerun_holds_every_signal_as_scalars_on_simulated_time() {
    let dir = temp_dir("rerun").join("run");
    // 2 s: float seconds times 1e9, truncated, put 29 of these 2001 times 1 ns early.
    Tiltsim::run("paper-lqg.toml")
        .duration(2)
        .transport_in_process()
        .out(&dir)
        .quiet()
        .success();
    let script = root().join("scripts/to-rerun.py");
    let (code, out, err) = fmi_tool("python", &[script.to_str().unwrap(), dir.to_str().unwrap()]);
    assert_eq!(code, 0, "to-rerun.py: {err}");
    // The start time and 2000 ticks.
    assert!(out.contains("2001 rows"), "{out}");
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
        assert!(line.contains("with 2001 rows"), "{line}");
    }
    // The values Rerun decodes are the CSV's, each at sim_time = step·dt exactly, in whole
    // nanoseconds (1 ms ticks).
    let (code, printed, err) = fmi_tool("rerun", &["rrd", "print", "-vvv", rrd]);
    assert_eq!(code, 0, "{err}");
    let step = table[0].iter().position(|c| c == "step").unwrap();
    let a = table[0].iter().position(|c| c == "lat_acc").unwrap();
    for entity in [
        "/plant/lat_acc",
        "/actuator/delta_a",
        "/links/rx_measurement",
    ] {
        let rows = rerun_rows(&printed, entity);
        assert_eq!(rows.len(), 2001, "{entity}");
        let off: Vec<(u64, u64)> = table[1..]
            .iter()
            .zip(&rows)
            .map(|(r, (ns, _))| (r[step].parse::<u64>().unwrap() * 1_000_000, *ns))
            .filter(|(want, got)| want != got)
            .collect();
        assert!(
            off.is_empty(),
            "{entity}: sim_time not step·dt: {:?}",
            &off[..off.len().min(5)]
        );
    }
    for (r, (_, value)) in table[1..]
        .iter()
        .zip(&rerun_rows(&printed, "/plant/lat_acc"))
    {
        assert_eq!(*value, r[a].parse::<f64>().unwrap());
    }
}
