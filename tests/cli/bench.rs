//! `tiltsim bench`: every configuration measured, one JSON report.

use std::process::Child;

use tiltsim_suite::{run, scenario, spawn, temp_dir, wait_for, wait_with_limit};

/// The bench report `r`'s walls are the medians of their rounds (the first the
/// configuration's own run), its ratio the two walls it names, its plant round trip the best
/// over the IPC configurations.
fn walls_are_medians_and_floors_the_best_round_trip(
    r: &serde_json::Value,
    configs: &[serde_json::Value],
) {
    // Three rounds (the default) of the runs the ratios compare; each wall is the median of
    // its rounds, the first round being the configuration's own run in the table.
    let rounds = &r["wall_rounds"];
    for (list, wall, cfg) in [
        ("in_process_s", "wall_in_process_s", 0),
        ("ipc_gauss_seidel_s", "wall_ipc_s", 1),
        ("ipc_jacobi_s", "wall_ipc_jacobi_s", 4),
    ] {
        let mut v: Vec<f64> = rounds[list]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(v.len(), 3, "{rounds}");
        assert_eq!(v[0], configs[cfg]["wall_s"].as_f64().unwrap(), "{rounds}");
        v.sort_by(f64::total_cmp);
        assert_eq!(r[wall].as_f64().unwrap(), v[1], "{list}: {rounds}");
    }
    // The ratio is the two wall times it names, unless the rounds' spread or the machine's
    // load made it meaningless, and then the report says which and draws none; the load it ran
    // under is there either way. The floor is the best IPC round trip.
    let ratio = r["wall_ipc_s"].as_f64().unwrap() / r["wall_in_process_s"].as_f64().unwrap();
    assert!(r["load_average"]["after"].as_f64().is_some(), "{r}");
    match r["ratio_withheld"].as_str() {
        None => {
            assert!((r["ipc_over_in_process"].as_f64().unwrap() - ratio).abs() < 1e-9 * ratio);
        }
        Some(why) => {
            assert!(why.contains("spread over"), "{why}");
            assert!(r["ipc_over_in_process"].is_null(), "{r}");
            assert!(r["jacobi_ipc_over_in_process"].is_null(), "{r}");
        }
    }
    // The plant's round trip is the best over the IPC configurations.
    let floor = configs
        .iter()
        .filter(|c| c["transport"] == "ipc")
        .map(|c| c["plant_round_trip_p50_us"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert_eq!(r["ipc_round_trip_floor_us"].as_f64().unwrap(), floor);
}

/// iceoryx2's floor for the scenario's ticks: the passive controller is stepped every tick, so
/// an echo for each of three participants asked every tick, in several sets of fresh processes
/// of the ticks named after each of the three rounds. Each round of an adaptive IPC row that
/// had a pair of CPUs of its own is set beside its master's best set of that round, and the
/// row's ratio is the median of its rounds'; the others (in-process, spin, sleep, a run left
/// to the kernel among other work) are not.
fn exchange_floors_follow_the_pattern_and_set_the_ratios(
    r: &serde_json::Value,
    configs: &[serde_json::Value],
) {
    let f = &r["exchange_floors"];
    assert_eq!(f["every"], serde_json::json!([1, 1, 1]), "{f}");
    let ticks = f["ticks"].as_u64().unwrap();
    let per_round = f["sets_per_round"].as_u64().unwrap() as usize;
    assert!(per_round >= 2, "{f}");
    // Each pattern's sets, round after round; the floor of a round is its best set's p50.
    let sets = |key: &str| -> Vec<f64> {
        let sets = f[key].as_array().unwrap();
        assert_eq!(sets.len(), 3 * per_round, "{f}");
        sets.iter()
            .map(|p| {
                assert_eq!(p["n"].as_u64().unwrap(), ticks, "{f}");
                let (p50, p99) = (p["p50"].as_f64().unwrap(), p["p99"].as_f64().unwrap());
                assert!(p50.is_finite() && p50 > 0.0 && p99 >= p50, "{f}");
                p50
            })
            .collect()
    };
    let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let worst = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let (in_turn, at_once) = (sets("in_turn_sets_us"), sets("all_at_once_sets_us"));
    for c in configs {
        let rounds = c["rounds"].as_array().unwrap();
        // The runs the ratios compare ran three rounds, the others one; the first round is the
        // row's own run.
        let compared = c["wait"] == "adaptive" || c["transport"] == "in-process";
        assert_eq!(rounds.len(), if compared { 3 } else { 1 }, "{c}");
        assert_eq!(rounds[0]["overhead_p50_us"], c["overhead_p50_us"], "{c}");
        let paired = rounds.iter().any(|x| x["placement"] == "free-pair");
        if !(c["transport"] == "ipc" && c["wait"] == "adaptive" && paired) {
            assert!(c["exchange_floor_us"].is_null(), "{c}");
            assert!(c["exchange_floor_worst_us"].is_null(), "{c}");
            assert!(c["overhead_over_floor"].is_null(), "{c}");
            assert!(
                rounds.iter().all(|x| x["overhead_over_floor"].is_null()),
                "{c}"
            );
            continue;
        }
        let pattern = if c["master"] == "jacobi" {
            &at_once
        } else {
            &in_turn
        };
        assert_eq!(
            c["exchange_floor_us"].as_f64().unwrap(),
            best(pattern),
            "{c}"
        );
        assert_eq!(
            c["exchange_floor_worst_us"].as_f64().unwrap(),
            worst(pattern),
            "{c}"
        );
        let mut ratios = Vec::new();
        for (i, x) in rounds.iter().enumerate() {
            if x["placement"] != "free-pair" {
                assert!(x["overhead_over_floor"].is_null(), "{c}");
                continue;
            }
            let floor = best(&pattern[i * per_round..(i + 1) * per_round]);
            let want = x["overhead_p50_us"].as_f64().unwrap() / floor;
            let got = x["overhead_over_floor"].as_f64().unwrap();
            assert!((got - want).abs() <= 1e-9 * want, "round {i}: {c}");
            ratios.push(want);
        }
        // The lower of the middle two, as every median of the bench.
        ratios.sort_by(f64::total_cmp);
        let median = ratios[(ratios.len() - 1) / 2];
        let ratio = c["overhead_over_floor"].as_f64().unwrap();
        assert!((ratio - median).abs() <= 1e-9 * median, "{c}");
    }
}

#[test]
fn bench_measures_every_master_and_wait_strategy_and_both_transports() {
    let dir = temp_dir("bench");
    let out = dir.join("bench.json");
    let (code, stdout, err) = run(&[
        "bench",
        scenario("paper-passive.toml").to_str().unwrap(),
        "--duration",
        "0.2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("iceoryx2 floor per tick"), "{stdout}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    // The machine, as Linux reports it: at least the CPUs this process may use, the kernel
    // release, and the table says so.
    let m = &r["machine"];
    assert!(
        m["logical_cpus"].as_u64().unwrap() as usize
            >= std::thread::available_parallelism().unwrap().get()
    );
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap();
    assert_eq!(m["kernel"], kernel.trim());
    assert!(
        stdout.contains(&format!("Linux {}", kernel.trim())),
        "{stdout}"
    );
    let configs = r["configs"].as_array().unwrap();
    // In-process, then IPC × {gauss-seidel, jacobi} × {adaptive, spin, sleep}.
    assert_eq!(configs.len(), 7);
    let mut seen = std::collections::BTreeSet::new();
    for c in configs {
        seen.insert(format!("{} {} {}", c["transport"], c["master"], c["wait"]));
        let ticks = c["ticks"].as_u64().unwrap();
        let want = if c["wait"] == "spin" { 100 } else { 200 };
        assert_eq!(ticks, want, "{c}");
    }
    assert_eq!(seen.len(), 7);
    walls_are_medians_and_floors_the_best_round_trip(&r, configs);
    assert!(!dir.join("bench.runs").exists(), "scratch runs removed");
    // The machine's own floors beside them, for a sample of tiltsim's size.
    let f = &r["machine_floors"];
    assert_eq!(f["payload_bytes"], 256, "{f}");
    for k in ["one_way_cross_cpu_us", "one_way_same_cpu_us"] {
        let v = f[k].as_f64().unwrap();
        assert!(v.is_finite() && v > 0.0, "{f}");
    }
    assert!(stdout.contains("machine floors"), "{stdout}");
    exchange_floors_follow_the_pattern_and_set_the_ratios(&r, configs);
    // Each row set beside a floor lists its rounds under the table.
    for c in configs
        .iter()
        .filter(|c| !c["overhead_over_floor"].is_null())
    {
        let line = format!(
            "overhead over the floor measured right after it, ipc {}, each round: ",
            c["master"].as_str().unwrap()
        );
        assert!(stdout.contains(&line), "{line}: {stdout}");
    }
    // Each round's floor right after that round's runs; the configurations the ratios do not
    // compare after the first round's floor, before the second round.
    let at = |what: &str| {
        err.find(&format!("measuring {what} ..."))
            .unwrap_or_else(|| panic!("{what}: {err}"))
    };
    let floor = |n: usize| {
        at(&format!(
            "iceoryx2's floor for the scenario's ticks, round {n}"
        ))
    };
    assert!(at("ipc jacobi adaptive") < floor(1), "{err}");
    assert!(floor(1) < at("ipc gauss-seidel spin"), "{err}");
    assert!(
        at("ipc jacobi sleep") < at("in-process gauss-seidel adaptive, round 2"),
        "{err}"
    );
    assert!(at("ipc jacobi adaptive, round 2") < floor(2), "{err}");
    assert!(
        floor(2) < at("in-process gauss-seidel adaptive, round 3"),
        "{err}"
    );
    assert!(at("ipc jacobi adaptive, round 3") < floor(3), "{err}");
}

#[test]
fn ping_pong_measures_the_one_way_latency_of_every_payload_size() {
    // On their own CPUs (iceoryx2's benchmark) and on one CPU (the cost of handing it over).
    for same_cpu in [false, true] {
        let dir = tiltsim_suite::temp_dir(&format!("pingpong-{same_cpu}"));
        let out = dir.join("pp.json");
        let mut args = vec![
            "bench",
            "--ping-pong",
            "--rounds",
            "2000",
            "--out",
            out.to_str().unwrap(),
        ];
        if same_cpu {
            args.push("--same-cpu");
        }
        let (code, stdout, err) = tiltsim_suite::run(&args);
        assert_eq!(code, 0, "{err}");
        assert!(
            stdout.contains("machine:") && stdout.contains("| 4096 |"),
            "{stdout}"
        );
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        assert_eq!(r["same_cpu"], same_cpu);
        let sizes: Vec<u64> = r["ping_pong"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["payload_bytes"].as_u64().unwrap())
            .collect();
        assert_eq!(sizes, [64, 256, 1024, 4096]);
        for s in r["ping_pong"].as_array().unwrap() {
            let p = &s["one_way_ns"];
            // Every round trip after the warm-up tenth is counted.
            assert_eq!(p["n"], 2000, "{s}");
            let (p50, p99, max) = (
                p["p50"].as_f64().unwrap(),
                p["p99"].as_f64().unwrap(),
                p["max"].as_f64().unwrap(),
            );
            assert!(0.0 < p50 && p50 <= p99 && p99 <= max, "{s}");
        }
    }
}

#[test]
fn concurrent_runs_are_measured_per_count_and_hog_and_all_complete() {
    let dir = temp_dir("bench-concurrent");
    let out = dir.join("concurrent.json");
    let (code, stdout, err) = run(&[
        "bench",
        scenario("paper-passive.toml").to_str().unwrap(),
        "--concurrent",
        "1,2",
        "--hogs",
        "0,1",
        "--duration",
        "0.05",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("| runs | hogs |"), "{stdout}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let rows = r["concurrent"].as_array().unwrap();
    // Every count of runs beside every count of hogs, hogs outermost.
    let shape: Vec<(u64, u64)> = rows
        .iter()
        .map(|x| (x["runs"].as_u64().unwrap(), x["hogs"].as_u64().unwrap()))
        .collect();
    assert_eq!(shape, [(1, 0), (2, 0), (1, 1), (2, 1)]);
    for x in rows {
        let n = x["runs"].as_u64().unwrap() as usize;
        // Every run completes (a slow machine makes them slow, not wrong), and each chose a
        // placement its summary names.
        assert_eq!(x["completed"].as_u64().unwrap() as usize, n, "{x}");
        let placed: u64 = x["placements"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_u64().unwrap())
            .sum();
        assert_eq!(placed as usize, n, "{x}");
        assert!(!x["placements"]
            .as_object()
            .unwrap()
            .contains_key("no summary"));
        // A run's lock-step loop lies inside its process's life, and every process inside the
        // row's total.
        let walls = x["wall_s"].as_array().unwrap();
        let loops = x["loop_s"].as_array().unwrap();
        assert_eq!((walls.len(), loops.len()), (n, n), "{x}");
        let total = x["total_s"].as_f64().unwrap();
        for (w, l) in walls.iter().zip(loops) {
            let (w, l) = (w.as_f64().unwrap(), l.as_f64().unwrap());
            assert!(l > 0.0 && l <= w && w <= total, "{x}");
        }
    }
    // Each row's loops are set beside the same run in one process beside the same hogs.
    for x in rows {
        assert_eq!(x["realtime"], false);
        let alone = x["in_process_loop_s"].as_f64().unwrap();
        let median = x["loop_median_s"].as_f64().unwrap();
        let ratio = x["loop_over_in_process"].as_f64().unwrap();
        assert!(alone > 0.0 && (ratio - median / alone).abs() < 1e-12, "{x}");
    }
    assert!(stdout.contains("loop over in process"), "{stdout}");
    // The runs' directories were scratch.
    assert!(!dir.join("concurrent.runs").exists());
    // Under SCHED_FIFO where the system grants it: each run says so; where it refuses, no
    // run completes.
    let (code, _, err) = run(&[
        "bench",
        scenario("paper-passive.toml").to_str().unwrap(),
        "--concurrent",
        "1",
        "--hogs",
        "1",
        "--realtime",
        "--duration",
        "0.05",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let x = &r["concurrent"][0];
    assert_eq!(x["realtime"], true, "{x}");
    if x["completed"] == 1 {
        assert!(x["loop_over_in_process"].as_f64().unwrap() > 0.0, "{x}");
    }
}

#[test]
fn an_interrupted_concurrent_bench_reports_the_rows_it_measured_and_starts_no_other() {
    let dir = temp_dir("bench-concurrent-interrupted");
    let out = dir.join("c.json");
    let sc = scenario("paper-mpc.toml");
    // Two rows of one long run each; Ctrl-C to the bench alone while the first row runs.
    let child = spawn(&[
        "bench",
        sc.to_str().unwrap(),
        "--concurrent",
        "1,1",
        "--duration",
        "300",
        "--out",
        out.to_str().unwrap(),
    ]);
    let first = dir.join("c.runs").join("runs-1-hogs-0").join("r0");
    let started = wait_for(std::time::Duration::from_secs(120), || {
        first.exists().then_some(())
    });
    assert!(started.is_some(), "the first row did not start");
    // SAFETY: signalling a child this test started.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let (code, _, err) = wait_with_limit(child, std::time::Duration::from_secs(600));
    assert_eq!(code, 130, "{err}");
    assert!(err.contains("1 of 2 rows measured"), "{err}");
    // The run of the first row got no signal and completed; the second row never started.
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(r["interrupted"], true);
    let rows = r["concurrent"].as_array().unwrap();
    assert_eq!(rows.len(), 1, "{r}");
    assert_eq!(rows[0]["completed"], 1, "{r}");
    assert!(!dir.join("c.runs").exists(), "scratch runs removed");
}

#[test]
fn bench_sets_the_real_time_ipc_runs_beside_hogs_against_one_process() {
    let sc = scenario("paper-passive.toml");
    // Several counts of hogs mean several tables: only --concurrent has them.
    let (code, _, err) = run(&["bench", sc.to_str().unwrap(), "--hogs", "1,2"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--hogs 1,2") && err.contains("--concurrent"),
        "{err}"
    );
    let dir = temp_dir("bench-realtime");
    let out = dir.join("bench.json");
    // Without the right to SCHED_FIFO (CAP_SYS_NICE dropped from the bounding set, so even
    // root lacks it): refused by name before any run, not after the runs that need no right.
    let refused = std::process::Command::new("setpriv")
        .args(["--bounding-set", "-sys_nice"])
        .arg(tiltsim_suite::tiltsim())
        .args(["bench", sc.to_str().unwrap(), "--realtime", "--out"])
        .arg(&out)
        .output()
        .expect("setpriv (util-linux) runs the bench without CAP_SYS_NICE");
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--realtime") && err.contains("SCHED_FIFO"),
        "{err}"
    );
    assert!(!err.contains("measuring") && !out.exists(), "{err}");
    let (code, stdout, err) = run(&[
        "bench",
        sc.to_str().unwrap(),
        "--duration",
        "0.2",
        "--repeat",
        "1",
        "--realtime",
        "--hogs",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    if code != 0 {
        // Refused by the system (no SCHED_FIFO, or a kernel without real-time throttling):
        // said so by name, before anything ran.
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains("--realtime")
                && (err.contains("SCHED_FIFO") || err.contains("sched_rt_runtime_us")),
            "{err}"
        );
        assert!(!out.exists());
        return;
    }
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(r["hogs"], 1);
    assert!(stdout.contains("beside 1 CPU hog(s)"), "{stdout}");
    let configs = r["configs"].as_array().unwrap();
    // The seven ordinary rows, then the adaptive IPC runs of both masters under SCHED_FIFO.
    assert_eq!(configs.len(), 9);
    assert!(configs[..7].iter().all(|c| c["realtime"] == false));
    for (c, master) in configs[7..].iter().zip(["gauss-seidel", "jacobi"]) {
        assert_eq!(c["realtime"], true, "{c}");
        assert_eq!(c["transport"], "ipc", "{c}");
        assert_eq!(c["master"], master, "{c}");
        assert_eq!(c["wait"], "adaptive", "{c}");
        assert_eq!(c["ticks"], 200, "{c}");
        // Where it ran is reported beside its figures.
        assert!(c["placement"].is_string(), "{c}");
    }
    // One round each: the walls are the rows' own, and each ratio is IPC over in-process.
    let rt = &r["realtime"];
    let in_process = r["wall_in_process_s"].as_f64().unwrap();
    assert_eq!(in_process, configs[0]["wall_s"].as_f64().unwrap());
    for (c, wall, ratio) in [
        (&configs[7], "wall_ipc_s", "ipc_over_in_process"),
        (
            &configs[8],
            "wall_ipc_jacobi_s",
            "jacobi_ipc_over_in_process",
        ),
    ] {
        let w = rt[wall].as_f64().unwrap();
        assert_eq!(w, c["wall_s"].as_f64().unwrap(), "{rt}");
        let q = rt[ratio].as_f64().unwrap();
        assert!((q - w / in_process).abs() <= 1e-12 * q, "{rt}");
    }
    assert!(stdout.contains("under SCHED_FIFO (--realtime)"), "{stdout}");
    assert_eq!(
        r["wall_rounds"]["ipc_jacobi_realtime_s"]
            .as_array()
            .unwrap()
            .len(),
        1
    );
}

/// `tiltsim bench` of paper-passive for `duration` simulated seconds into a fresh directory
/// named after `name`: the directory, the report it would write, the running bench.
fn start_bench(name: &str, duration: &str) -> (std::path::PathBuf, std::path::PathBuf, Child) {
    let dir = temp_dir(name);
    let out = dir.join("b.json");
    let sc = scenario("paper-passive.toml");
    let child = spawn(&[
        "bench",
        sc.to_str().unwrap(),
        "--duration",
        duration,
        "--out",
        out.to_str().unwrap(),
    ]);
    (dir, out, child)
}

/// Ctrl-C to the bench `child`: it exits 130 saying it was "interrupted while measuring
/// `what`", the processes `helpers` it started are gone, and so are its shared-memory files
/// (their prefix starts with its pid). Its stderr.
fn interrupt(child: Child, what: &str, helpers: &[u32]) -> String {
    let pid = child.id();
    // SAFETY: signalling a child this test started.
    unsafe { libc::kill(pid as i32, libc::SIGINT) };
    let (code, _, err) = wait_with_limit(child, std::time::Duration::from_secs(600));
    assert_eq!(code, 130, "{err}");
    assert!(
        err.contains(&format!("interrupted while measuring {what}")),
        "{err}"
    );
    for h in helpers {
        assert!(
            !std::path::Path::new(&format!("/proc/{h}")).exists(),
            "the process {h} is left"
        );
    }
    let left = tiltsim_suite::leftovers(&format!("tiltsim_{pid}_"));
    assert!(left.is_empty(), "{left:?}");
    err
}

#[test]
fn an_interrupted_bench_ends_its_run_and_writes_nothing() {
    let (dir, out, child) = start_bench("bench-interrupted", "300");
    // The second configuration (IPC, Gauss-Seidel) under way: Ctrl-C.
    let second = dir.join("b.runs").join("config-1");
    let started = wait_for(std::time::Duration::from_secs(300), || {
        second.exists().then_some(())
    });
    assert!(started.is_some(), "the second configuration did not start");
    let err = interrupt(child, "ipc gauss-seidel adaptive", &[]);
    // The run ended as interrupted (not the 300 s it was asked for) and no other started.
    assert!(!err.contains("measuring ipc gauss-seidel spin"), "{err}");
    assert!(!out.exists() && !dir.join("b.runs").exists());
}

/// Ctrl-C while iceoryx2's floor is measured between the bench's rounds, with the floor's
/// three echoes stopped (SIGSTOP) so that the floor cannot end on its own: the bench ends at
/// once, naming the floor, ends the echoes, and writes nothing.
#[test]
fn an_interrupted_exchange_floor_ends_its_echoes_and_writes_nothing() {
    let (dir, out, child) = start_bench("exchange-floor-interrupted", "5");
    let pid = child.id();
    // The floor's echoes are the bench's only children named as the bench (the runs'
    // participants have their own names; the ping-pong floor, at the end, has one echo).
    let echoes = wait_for(std::time::Duration::from_secs(300), || {
        let v: Vec<u32> = tiltsim_suite::children_of(pid)
            .into_iter()
            .filter(|(_, comm)| comm == "tiltsim")
            .map(|(p, _)| p)
            .collect();
        (v.len() == 3).then_some(v)
    });
    let Some(echoes) = echoes else {
        let (_, _, err) = wait_with_limit(child, std::time::Duration::from_secs(600));
        panic!("no exchange floor started: {err}");
    };
    for e in &echoes {
        // SAFETY: signalling a grandchild this test's child started.
        unsafe { libc::kill(*e as i32, libc::SIGSTOP) };
    }
    interrupt(child, "iceoryx2's floor", &echoes);
    assert!(!out.exists() && !dir.join("b.runs").exists());
}

#[test]
fn an_interrupted_ping_pong_ends_its_echo_and_writes_nothing() {
    let dir = temp_dir("ping-pong-interrupted");
    let out = dir.join("p.json");
    // Ten million round trips of each size: far longer than the test waits.
    let child = spawn(&[
        "bench",
        "--ping-pong",
        "--rounds",
        "10000000",
        "--out",
        out.to_str().unwrap(),
    ]);
    let pid = child.id();
    let echo = wait_for(std::time::Duration::from_secs(300), || {
        tiltsim_suite::children_of(pid).into_iter().next()
    });
    let Some((echo, _)) = echo else {
        let (_, _, err) = wait_with_limit(child, std::time::Duration::from_secs(600));
        panic!("no echo process started: {err}");
    };
    interrupt(child, "the ping-pong floor", &[echo]);
    assert!(!out.exists());
}

/// `tiltsim bench --network` interrupted while it waits for an echo that never connects (a
/// `--remote-via` command that sleeps instead of starting it): first the raw TCP floor's
/// echo, then, with the raw TCP echo let through, the first Zenoh floor's. Each time the bench
/// ends the echo's process, exits 130 naming what it was measuring, and writes nothing.
#[test]
fn an_interrupted_network_bench_ends_its_echo_and_writes_nothing() {
    use std::os::unix::fs::PermissionsExt;
    let dir = temp_dir("network-interrupted");
    let cases = [
        ("never", "exec sleep 600", 23_611, "the raw TCP floor"),
        (
            "raw-only",
            "case \"$*\" in *--raw-tcp*) exec \"$@\";; esac\nexec sleep 600",
            23_621,
            "a Zenoh floor",
        ),
    ];
    for (name, body, port, what) in cases {
        let via = dir.join(name);
        std::fs::write(&via, format!("#!/bin/sh\n{body}\n")).unwrap();
        std::fs::set_permissions(&via, std::fs::Permissions::from_mode(0o755)).unwrap();
        let out = dir.join(format!("{name}.json"));
        let listen = format!("127.0.0.1:{port}");
        let child = spawn(&[
            "bench",
            "--network",
            "--listen",
            &listen,
            "--remote-via",
            via.to_str().unwrap(),
            "--rounds",
            "200",
            "--out",
            out.to_str().unwrap(),
        ]);
        let pid = child.id();
        let sleeper = wait_for(std::time::Duration::from_secs(300), || {
            tiltsim_suite::children_of(pid)
                .into_iter()
                .find(|(_, comm)| comm == "sleep")
        });
        let Some((sleeper, _)) = sleeper else {
            let (_, _, err) = wait_with_limit(child, std::time::Duration::from_secs(600));
            panic!("{name}: the echo's command never started: {err}");
        };
        // SAFETY: signalling a child this test started.
        unsafe { libc::kill(pid as i32, libc::SIGINT) };
        let (code, _, err) = wait_with_limit(child, std::time::Duration::from_secs(600));
        assert_eq!(code, 130, "{name}: {err}");
        assert!(
            err.contains(&format!(
                "interrupted while measuring {what}; nothing written"
            )),
            "{name}: {err}"
        );
        assert!(
            !std::path::Path::new(&format!("/proc/{sleeper}")).exists(),
            "{name}: the echo's process {sleeper} is left"
        );
        assert!(!out.exists(), "{name}");
    }
}
