//! The tables of a run and of a sweep as a notebook user reads them, checked with the readers
//! such a user has (pandas, and FMPy's CSV reader): time first and exact, a row at the start
//! time, a unit for every column in `columns.csv`, no column named like a pandas attribute,
//! a tidy `series.csv`, and a compare's tidy `table.csv` with a float `value`.

use tiltsim_suite::{fmi_tool, mc_args, root, run_strings, scenario, temp_dir, Tiltsim};

#[test]
fn pandas_and_fmpy_read_the_tables_with_units_exact_times_and_no_reserved_names() {
    let dir = temp_dir("tables");
    let lqg = scenario("paper-lqg.toml");
    let lqg = lqg.to_str().unwrap();
    let out = dir.join("run");
    Tiltsim::run(lqg)
        .duration(0.5)
        .transport_in_process()
        .out(&out)
        .quiet()
        .success();
    let sweep = dir.join("sweep");
    let (code, _, err) = run_strings(&mc_args(lqg, &sweep, "2", None));
    assert_eq!(code, 0, "{err}");

    let cmp = dir.join("compare");
    let passive = scenario("paper-passive.toml");
    let (code, _, err) = run_strings(&[
        "compare".into(),
        passive.display().to_string(),
        lqg.into(),
        "--transport".into(),
        "in-process".into(),
        "--out".into(),
        cmp.display().to_string(),
    ]);
    assert_eq!(code, 0, "{err}");

    let check = root().join("tests/outside/pandas/pandas_check.py");
    let (code, printed, err) = fmi_tool(
        "python",
        &[
            check.to_str().unwrap(),
            out.to_str().unwrap(),
            sweep.to_str().unwrap(),
            cmp.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 0, "pandas_check.py: {err}");
    let r: serde_json::Value =
        serde_json::from_str(&printed).unwrap_or_else(|e| panic!("{e}: {printed}"));
    // Against pandas' own list of DataFrame attributes (`flags`, `index`, `values`, ...).
    assert_eq!(r["clashes"], serde_json::json!([]), "{r}");
    assert_eq!(r["missing_units"], serde_json::json!([]), "{r}");
    assert_eq!(r["first_column"], serde_json::json!(["time", "step"]));
    // The start time has a row, and 9 ms reads as 0.009, not 9 × 0.001.
    assert_eq!(r["time0"], 0.0);
    assert_eq!(r["time_at_9ms"], "0.009");
    assert_eq!(r["time_unit"], "s");
    assert_eq!(r["lat_acc_unit"], "m/s2");
    assert_eq!(r["p_ct_unit"], "%");
    // Tidy series: one line per sample and time, every 10 ms from the start time over the
    // whole 16.8 s track.
    assert_eq!(
        r["series_columns"],
        serde_json::json!(["sample_id", "time", "lat_acc"])
    );
    assert_eq!(
        r["series_times"],
        serde_json::json!(["0.0", "0.01", "0.02", "0.03"])
    );
    assert_eq!(r["series_points"], 1681);
    // FMPy's reader (which its plot_result needs) takes timeseries.csv: 0.5 s at 1 ms and
    // the start time.
    assert_eq!(r["fmpy_rows"], 501);
    assert_eq!(r["fmpy_time0"], 0.0);
    // A compare's table is tidy: `value` a number on every line, read as a float by pandas
    // and polars with their defaults; every column and metric described in columns.csv.
    assert_eq!(r["compare_not_numbers"], serde_json::json!([]), "{r}");
    for c in ["value", "paper", "difference"] {
        assert_eq!(r["compare_pandas_types"][c], "float64", "{c}: {r}");
    }
    assert_eq!(r["compare_polars_value"], "Float64", "{r}");
    assert_eq!(r["compare_undescribed"], serde_json::json!([]), "{r}");
    assert!(r["compare_rows"].as_u64().unwrap() > 50, "{r}");
}
