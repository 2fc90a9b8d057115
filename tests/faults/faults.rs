//! Link effects, process faults, bad data, tracing and pacing.

use std::path::{Path, PathBuf};
use tiltsim_suite::{leftovers, prefix, scenario, summary, temp_dir, Series, Tiltsim};

/// `paper-lqg` with the TOML `extra` appended, written as `NAME.toml`, for what `--set`
/// cannot add: a `[[faults.schedule]]` entry (an array-of-tables element) or a window (a
/// table whose two fields must arrive together, and each `--set` is applied alone).
fn lqg_with(name: &str, extra: &str) -> PathBuf {
    let text = std::fs::read_to_string(scenario("paper-lqg.toml")).unwrap();
    let p = temp_dir(&format!("{name}-scenario")).join(format!("{name}.toml"));
    std::fs::write(&p, format!("{text}\n{extra}\n")).unwrap();
    p
}

/// `tiltsim run SC` with the ideal actuator: the controller, links and faults are what
/// matter here.
fn ideal(sc: &Path) -> Tiltsim {
    Tiltsim::run(sc).set("actuator.model", "ideal")
}

/// Runs `cmd` over `transport` into `dir` with a fixed prefix, quiet; returns (code, stderr).
fn go(cmd: Tiltsim, dir: &Path, transport: &str, pfx: &str) -> (i32, String) {
    let (code, _, err) = cmd
        .out(dir)
        .transport(transport)
        .ipc_prefix(pfx)
        .quiet()
        .result();
    assert!(
        leftovers(pfx).is_empty(),
        "shared-memory files left: {:?}",
        leftovers(pfx)
    );
    (code, err)
}

fn bytes(p: PathBuf) -> Vec<u8> {
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn link_effects_change_the_recorded_signals_exactly_as_declared_on_both_transports() {
    let sc = lqg_with(
        "links",
        "[links.bar_angle]\nfreeze_window = { start_s = 4.0, end_s = 4.5 }\n",
    );
    let cmd = ideal(&sc)
        .set("links.actuator_command.delay_ticks", 20)
        .set("links.measurement.bias", 0.002)
        .duration(6);
    let dir = temp_dir("links");
    let pfx = prefix("links");
    let ipc = dir.join("ipc");
    let (code, err) = go(cmd.clone(), &ipc, "ipc", &pfx);
    assert_eq!(code, 0, "{err}");
    let local = dir.join("in-process");
    let (code, err) = go(cmd, &local, "in-process", &pfx);
    assert_eq!(code, 0, "{err}");
    for f in ["timeseries.csv", "events.csv"] {
        assert!(
            bytes(ipc.join(f)) == bytes(local.join(f)),
            "{f} differs between transports"
        );
    }
    let s = Series::read(&ipc.join("timeseries.csv"));
    let (cmd, rx_cmd) = (s.col("delta_a_cmd"), s.col("rx_actuator_command"));
    // A delay of 20 ticks shifts the command series by 20 rows; before the first sample
    // arrives, the actuator holds the first command (sent in tick 0, row 1). Row 0, at the
    // start time, holds what the controller holds.
    assert_eq!(rx_cmd[0], cmd[0]);
    for n in 1..cmd.len() {
        let want = if n > 20 { cmd[n - 20] } else { cmd[1] };
        assert_eq!(rx_cmd[n], want, "row {n}");
    }
    assert!(
        cmd.iter().any(|c| c.abs() > 0.01),
        "the controller commands something"
    );
    // The bias is added to every measurement the controller receives. In tick k the
    // controller gets the plant's output at t_k, recorded in row k; tick k ends at row k + 1.
    let (meas, rx_meas) = (s.col("theta_v_meas"), s.col("rx_measurement"));
    for k in 1..meas.len() {
        assert_eq!(rx_meas[k], meas[k - 1] + 0.002, "row {k}");
    }
    // Frozen bar angle: the plant sees δ_a of tick 4000 (row 4001) in the ticks of
    // [4.0, 4.5) s (rows 4001 to 4500), then live again.
    let (da, rx_da) = (s.col("delta_a"), s.col("rx_bar_angle"));
    for k in 3990..4600 {
        let want = if (4001..4501).contains(&k) {
            da[4001]
        } else {
            da[k]
        };
        assert_eq!(rx_da[k], want, "row {k}");
    }
    assert_ne!(
        da[4500], da[4001],
        "the bar moved while its reading was frozen"
    );
    let events = std::fs::read_to_string(ipc.join("events.csv")).unwrap();
    assert!(events.starts_with("time,step,source,event,value,detail\n"));
    assert!(
        events.contains("0.0,0,actuator_command,delay,20.0,"),
        "{events}"
    );
    assert!(
        events.contains("4.0,4000,bar_angle,freeze-window,,begins"),
        "{events}"
    );
    assert!(
        events.contains("4.5,4500,bar_angle,freeze-window,,ends"),
        "{events}"
    );
}

#[test]
fn a_nan_on_a_link_is_caught_by_its_receiver_and_ends_or_degrades_the_run() {
    let sc = lqg_with(
        "nan",
        "[links.measurement]\nnan_window = { start_s = 5.0, end_s = 5.1 }\n",
    );
    let window = ideal(&sc).duration(6);
    let dir = temp_dir("nan-link");
    let pfx = prefix("nanlink");
    let (code, err) = go(window.clone(), &dir.join("abort"), "ipc", &pfx);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("participant controller rejected step 5000: non-finite value in field `theta_v_meas` of to_controller"),
        "{err}"
    );
    let s = Series::read(&dir.join("abort/timeseries.csv"));
    assert_eq!(
        s.rows.len(),
        5001,
        "the start and every tick before the bad sample kept"
    );

    let (code, err) = go(
        window.set("faults.on_bad_data", "hold"),
        &dir.join("hold"),
        "in-process",
        &pfx,
    );
    assert_eq!(code, 0, "{err}");
    let events = std::fs::read_to_string(dir.join("hold/events.csv")).unwrap();
    let held: Vec<&str> = events
        .lines()
        .filter(|l| l.contains("bad-input-held"))
        .collect();
    assert_eq!(
        held.len(),
        100,
        "one per 1 ms controller step in the 0.1 s window"
    );
    assert!(held[0].starts_with("5.0,5000,controller,bad-input-held,,non-finite `theta_v_meas`"));
    let s = Series::read(&dir.join("hold/timeseries.csv"));
    assert!(s.col("rx_measurement")[5050].is_nan());
    assert!(s.col("delta_a_cmd").iter().all(|v| v.is_finite()));
}

#[test]
fn a_killed_actuator_in_degraded_mode_returns_the_bar_to_neutral_in_the_declared_time() {
    let sc = lqg_with(
        "kill-actuator",
        "[faults]\non_failure = \"degrade\"\nneutral_ramp_s = 1.5\n\
         [[faults.schedule]]\nparticipant = \"actuator\"\naction = \"kill\"\nat_s = 8.0\n",
    );
    let dir = temp_dir("kill-actuator");
    let pfx = prefix("killact");
    let (code, err) = go(ideal(&sc).duration(11), &dir.join("ipc"), "ipc", &pfx);
    assert_eq!(code, 0, "{err}");
    // -q: nothing but errors, and a degraded run is not one.
    assert_eq!(err, "", "a quiet run printed");
    let sum = summary(&dir.join("ipc"));
    assert_eq!(sum["status"], "degraded");
    let actuator = &sum["participants"][1]["exit"]["status"];
    assert!(
        actuator.as_str().unwrap().contains("signal 9"),
        "{actuator}"
    );
    let s = Series::read(&dir.join("ipc/timeseries.csv"));
    assert_eq!(s.rows.len(), 11_001, "the run went on to the end");
    let da = s.col("delta_a");
    // Row k + 1 holds tick k: row 8000 is the last tick before the kill at 8 s.
    assert!(
        da[8000].abs() > 0.03,
        "tilted mid-curve before the kill: {}",
        da[8000]
    );
    // Linear ramp from δ_a(8000) to zero, reached 1.5 s (1500 ticks) after the loss.
    for k in 8001..11_001 {
        let n = (k - 8000) as f64;
        let want = da[8000] * (1.0 - n / 1500.0).max(0.0);
        assert!((da[k] - want).abs() < 1e-12, "row {k}: {} vs {want}", da[k]);
    }
    assert_eq!(da[9500], 0.0);
    let events = std::fs::read_to_string(dir.join("ipc/events.csv")).unwrap();
    assert!(
        events.contains("8.0,8000,actuator,fault-injected,,kill"),
        "{events}"
    );
    assert!(
        events.contains("8.0,8000,actuator,participant-lost,,exited"),
        "{events}"
    );
    assert!(events.contains("8.0,8000,actuator,degraded,,bar ramps to neutral over 1.5 s"));
    // The same fault in-process gives the same rows and events, byte for byte.
    let (code, err) = go(
        ideal(&sc).duration(11),
        &dir.join("local"),
        "in-process",
        &pfx,
    );
    assert_eq!(code, 0, "{err}");
    for f in ["timeseries.csv", "events.csv"] {
        assert!(
            bytes(dir.join("ipc").join(f)) == bytes(dir.join("local").join(f)),
            "{f}"
        );
    }
}

#[test]
fn a_lost_participant_is_reported_as_a_warning_in_words_and_the_report_names_what_ran() {
    let sc = lqg_with(
        "kill-controller-loud",
        "[faults]\non_failure = \"degrade\"\n\
         [[faults.schedule]]\nparticipant = \"controller\"\naction = \"kill\"\nat_s = 0.5\n",
    );
    let dir = temp_dir("kill-controller-loud");
    let pfx = prefix("killloud");
    let out = ideal(&sc).out(&dir).ipc_prefix(&pfx).duration(1).success();
    let (out, err) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(leftovers(&pfx).is_empty());
    // The engine's log reads as the command's own warning: no level column, no module path.
    assert!(
        err.lines()
            .any(|l| l.starts_with("warning: participant controller")
                && l.ends_with("continuing degraded")),
        "{err}"
    );
    assert!(
        !err.contains("WARN") && !err.contains("tiltsim_master"),
        "{err}"
    );
    assert!(
        err.contains("warning: a participant was lost and the run continued in degraded mode"),
        "{err}"
    );
    assert!(
        out.starts_with("paper-lqg (LQG servo, ideal bar): degraded, 1000 steps"),
        "{out}"
    );
}

#[test]
fn a_killed_controller_with_the_abort_policy_ends_the_run_naming_it_and_repeats_exactly() {
    let sc = lqg_with(
        "kill-controller",
        "[[faults.schedule]]\nparticipant = \"controller\"\naction = \"kill\"\nat_s = 3.0\n",
    );
    let dir = temp_dir("kill-controller");
    let pfx = prefix("killctl");
    for name in ["a", "b"] {
        let (code, err) = go(ideal(&sc), &dir.join(name), "ipc", &pfx);
        assert_eq!(code, 1, "{err}");
        assert!(err.contains("participant controller (pid"), "{err}");
        assert!(
            err.contains("exited (killed by signal 9) while step 3000 was pending"),
            "{err}"
        );
        assert!(err.contains("3000 of 16800 steps recorded"), "{err}");
    }
    for f in ["timeseries.csv", "events.csv"] {
        assert!(
            bytes(dir.join("a").join(f)) == bytes(dir.join("b").join(f)),
            "{f}"
        );
    }
    assert_eq!(Series::read(&dir.join("a/timeseries.csv")).rows.len(), 3001);
    assert_eq!(summary(&dir.join("a"))["status"], "failed");
}

#[test]
fn bad_samples_from_a_process_are_caught_where_they_arrive_and_named() {
    let exe = env!("CARGO_BIN_EXE_faulty-plant");
    let dir = temp_dir("faulty");
    let pfx = prefix("faulty");
    let sc = scenario("paper-passive.toml");
    for (mode, expect) in [
        (
            "nan",
            "participant plant: non-finite value in field `lat_acc` of from_plant at step 1500",
        ),
        (
            "version",
            "participant plant: malformed sample for step 1500: protocol version 99",
        ),
        (
            "size",
            "participant plant: malformed sample for step 1500: from_plant of 8 bytes",
        ),
        (
            "skip",
            "participant plant: sample for step 1501 arrived out of order, expected step 1500",
        ),
        ("panic", "while step 1500 was pending"),
        ("hang", "did not answer step 1500 within 300 ms"),
    ] {
        let out_dir = dir.join(mode);
        let err = Tiltsim::run(&sc)
            .out(&out_dir)
            .transport_ipc()
            .ipc_prefix(&pfx)
            .duration(3)
            .deadline_ms(300)
            .participant_exe("plant", exe)
            .quiet()
            .env("TILTSIM_FAULT", format!("{mode}@1500"))
            .env("RUST_BACKTRACE", "1")
            .failure(1);
        assert!(err.contains(expect), "{mode}: {err}");
        if mode == "panic" {
            // The participant's one line goes to its log, not to tiltsim's standard error;
            // no backtrace anywhere.
            assert!(!err.contains("stack backtrace"), "{err}");
            let log =
                std::fs::read_to_string(out_dir.join("logs").join("plant.log")).unwrap_or_default();
            assert!(
                log.contains("plant-proc: panicked at"),
                "logs/plant.log: {log}"
            );
            assert!(!log.contains("stack backtrace"), "logs/plant.log: {log}");
        }
        let rows = Series::read(&out_dir.join("timeseries.csv")).rows.len();
        assert_eq!(
            rows, 1501,
            "{mode}: the start and the ticks before the bad sample kept"
        );
        assert!(leftovers(&pfx).is_empty(), "{mode}: {:?}", leftovers(&pfx));
    }
}

#[test]
fn trace_and_pace_report_every_exchange_and_every_tick() {
    let dir = temp_dir("trace");
    let pfx = prefix("trace");
    let sc = scenario("paper-passive.toml");
    let (code, err) = go(
        Tiltsim::run(&sc).duration(1).trace().pace(4),
        &dir,
        "ipc",
        &pfx,
    );
    assert_eq!(code, 0, "{err}");
    let trace = std::fs::read_to_string(dir.join("trace.csv")).unwrap();
    let rows: Vec<Vec<u64>> = tiltsim_suite::csv_table(&trace)[1..]
        .iter()
        .map(|f| f[3..].iter().map(|x| x.parse().unwrap()).collect())
        .collect();
    // Init plus 1000 steps, three participants each (the passive controller runs every tick).
    assert_eq!(rows.len(), 3 * 1001);
    for r in &rows {
        // sent ≤ received ≤ started ≤ finished ≤ reply sent ≤ reply received (one clock).
        assert!(r.windows(2).all(|w| w[0] <= w[1]), "{r:?}");
    }
    let sum = summary(&dir);
    let p = &sum["pacing"];
    assert_eq!(p["ticks"], 1000);
    // Paced at 4x, the loop cannot take less than 999 ticks × 0.25 ms.
    let achieved = p["achieved_realtime_factor"].as_f64().unwrap();
    assert!(achieved <= 4.0 * 1000.0 / 999.0 + 1e-9, "{achieved}");
    let overruns = p["overruns"].as_u64().unwrap();
    assert!(overruns <= 1000);
    // Every late tick has exactly one cause.
    let c = &p["causes"];
    let by_cause: u64 = ["carried_over", "orchestrator", "compute", "coordination"]
        .iter()
        .map(|k| c[k].as_u64().unwrap())
        .sum();
    assert_eq!(by_cause, overruns, "{c}");
    assert_eq!(c["start_delay_us"]["n"].as_u64().unwrap(), overruns);
    // Paced runs nap between ticks instead of polling.
    assert_eq!(sum["wait_strategy"], "paced");
    assert_eq!(p["realtime"], false);
    let lat = &sum["link_latency"][0];
    assert_eq!(lat["participant"], "plant");
    assert_eq!(lat["request_us"]["n"], 1001);
    assert!(dir.join("plots/latency_histogram.png").exists());
}

#[test]
fn realtime_is_either_granted_or_refused_by_name() {
    let sc = scenario("paper-passive.toml");
    let dir = temp_dir("realtime");
    let pfx = prefix("realtime");
    let (code, err) = go(
        Tiltsim::run(&sc).duration(0.5).pace(2).realtime(),
        &dir,
        "ipc",
        &pfx,
    );
    if code == 0 {
        // Granted (root, CAP_SYS_NICE or rtprio limits): reported in the summary.
        assert_eq!(summary(&dir)["pacing"]["realtime"], true);
    } else {
        // Refused by the system: said so, naming the policy and what would allow it.
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains("SCHED_FIFO") || err.contains("mlockall"),
            "{err}"
        );
    }
    assert!(leftovers(&pfx).is_empty());
}

/// `summary.json` without the fields it declares as measured on the wall clock.
fn deterministic_part(dir: &Path) -> serde_json::Value {
    let s = summary(dir);
    // The fields the file itself lists are the ones stripped.
    assert_eq!(
        s["wall_clock_fields"],
        serde_json::json!(tiltsim_master::engine::summary::WALL_CLOCK_FIELDS)
    );
    tiltsim_master::engine::summary::deterministic(s)
}

#[test]
fn the_summary_repeats_but_for_its_declared_wall_clock_fields_which_perf_json_holds() {
    let sc = scenario("paper-lqg.toml");
    let dirs = [temp_dir("perf-a"), temp_dir("perf-b")];
    for (i, d) in dirs.iter().enumerate() {
        let pfx = prefix(&format!("perf-{i}"));
        let (code, err) = go(
            Tiltsim::run(&sc).duration(1).progress_machine(),
            d,
            "ipc",
            &pfx,
        );
        assert_eq!(code, 0, "{err}");
        // One JSON line per percent, in order, the last at the last step.
        let lines: Vec<serde_json::Value> = err
            .lines()
            .filter(|l| l.starts_with("{\"progress\""))
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        let percents: Vec<u64> = lines
            .iter()
            .map(|l| l["progress"].as_u64().unwrap())
            .collect();
        assert_eq!(percents, (1..=100).collect::<Vec<_>>());
        assert_eq!(lines[99]["step"], 1000);
        assert_eq!(lines[99]["t_s"], 1.0);
        let perf: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("perf.json")).unwrap()).unwrap();
        assert_eq!(perf["wall_time_s"], summary(d)["wall_time_s"]);
        assert_eq!(perf["participants"]["actuator"]["compute_us"]["n"], 1000);
    }
    assert_eq!(deterministic_part(&dirs[0]), deterministic_part(&dirs[1]));
}
