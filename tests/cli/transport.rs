//! The lock-step runtime, written once and run over both transports: byte-identical output
//! across transports, master algorithms' documented coupling, multi-rate holds.

use std::path::PathBuf;

use tiltsim_suite::{leftovers, prefix, scenario, summary, temp_dir, Series, Tiltsim};

/// Runs `scenario` over IPC with `extra` arguments and one environment variable set.
fn run_with_env(name: &str, scen: &str, extra: &[&str], env: (&str, &str)) -> PathBuf {
    let dir = temp_dir(name);
    let pfx = prefix(name);
    Tiltsim::run(scenario(scen))
        .out(&dir)
        .transport("ipc")
        .ipc_prefix(&pfx)
        .env(env.0, env.1)
        .quiet()
        .args(extra)
        .success();
    assert!(leftovers(&pfx).is_empty(), "shared-memory files left");
    dir
}

/// A one-second Jacobi run of `scen` over IPC that got a pair of CPUs to place its
/// participants on ([`on_a_pair_with`]).
fn on_a_pair(name: &str, scen: &str) -> PathBuf {
    on_a_pair_with(name, scen, &["--master", "jacobi", "--duration", "1"])
}

/// A run of `scen` over IPC with `extra` arguments that got a pair of CPUs to place its
/// participants on. While other runs of this suite claim the machine's CPUs a run takes none
/// (`contended`) and the kernel balances it, with no plan; other load does not decide (every
/// unclaimed CPU is taken for idle). The run is repeated until it gets a pair: the other runs
/// end.
fn on_a_pair_with(name: &str, scen: &str, extra: &[&str]) -> PathBuf {
    let mut dir = PathBuf::new();
    for attempt in 0..=100 {
        dir = run_with_env(name, scen, extra, (cosim::ipc::placement::ASSUME_IDLE, "1"));
        let sm = summary(&dir);
        if sm["timing"]["placement"]["reason"] == "free-pair" || attempt == 100 {
            break;
        }
        assert!(
            sm["timing"]["cpu_plan"].is_null(),
            "no plan without a pair: {sm}"
        );
        std::thread::sleep(std::time::Duration::from_millis(500));
    }
    dir
}

/// Runs `scenario` with `transport` and `master`, returns the output directory.
fn run_with(name: &str, scen: &str, transport: &str, master: &str, extra: &[&str]) -> PathBuf {
    let dir = temp_dir(name);
    let pfx = prefix(name);
    let sc = if std::path::Path::new(scen).is_absolute() {
        PathBuf::from(scen)
    } else {
        scenario(scen)
    };
    Tiltsim::run(sc)
        .out(&dir)
        .transport(transport)
        .master(master)
        .ipc_prefix(&pfx)
        .quiet()
        .args(extra)
        .success();
    assert!(
        leftovers(&pfx).is_empty(),
        "shared-memory files left: {:?}",
        leftovers(&pfx)
    );
    dir
}

fn bytes(dir: &std::path::Path) -> Vec<u8> {
    std::fs::read(dir.join("timeseries.csv")).expect("timeseries.csv")
}

#[test]
fn both_transports_give_byte_identical_timeseries_for_each_master() {
    for master in ["gauss-seidel", "jacobi"] {
        let a = run_with(
            &format!("ipc-{master}"),
            "irregular-track.toml",
            "ipc",
            master,
            &[],
        );
        let b = run_with(
            &format!("inproc-{master}"),
            "irregular-track.toml",
            "in-process",
            master,
            &[],
        );
        assert!(
            bytes(&a) == bytes(&b),
            "{master}: ipc and in-process differ"
        );
        let s = summary(&a);
        assert_eq!(s["transport"], "ipc");
        assert_eq!(s["master_algorithm"], master);
        assert_eq!(s["status"], "completed");
        // three separate participant processes, none of them the orchestrator
        let pids: Vec<u64> = s["participants"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["pid"].as_u64().unwrap())
            .collect();
        assert_eq!(pids.len(), 3);
        assert!(pids[0] != pids[1] && pids[1] != pids[2] && pids[0] != pids[2]);
        for k in ["overhead_p50_us", "overhead_p99_us", "overhead_max_us"] {
            assert!(s["timing"][k].as_f64().unwrap() >= 0.0);
        }
    }
}

/// Gauss-Seidel over IPC with its participants pinned together on one CPU, cued (the
/// default) or yielding: the bytes of one process either way, and `summary.json` says which
/// hand-over ran. Cued, each participant cues the one asked after it once per step it
/// answers: the actuator the plant every tick, the plant the next tick's first every tick,
/// the controller the actuator at each of its updates.
#[test]
fn gauss_seidel_participants_cued_or_yielding_give_the_bytes_of_one_process() {
    let one = run_with(
        "gs-one-process",
        "irregular-track.toml",
        "in-process",
        "gauss-seidel",
        &["--duration", "1"],
    );
    for how in ["cue", "yield"] {
        let set = format!("run.hand_over={how}");
        let dir = on_a_pair_with(
            &format!("gs-{how}"),
            "irregular-track.toml",
            &["--master", "gauss-seidel", "--duration", "1", "--set", &set],
        );
        let sm = summary(&dir);
        let timing = &sm["timing"];
        assert_eq!(timing["placement"]["reason"], "free-pair", "{timing}");
        assert_eq!(timing["hand_over"], how, "{timing}");
        assert!(
            bytes(&dir) == bytes(&one),
            "{how}: ipc and in-process differ"
        );
        let ticks = sm["steps_completed"].as_u64().unwrap();
        let dt = sm["dt_s"].as_f64().unwrap();
        for p in sm["participants"].as_array().unwrap() {
            let cue = &p["cue"];
            if how == "yield" {
                assert!(cue.is_null(), "{p}");
                continue;
            }
            let every = (p["period_s"].as_f64().unwrap() / dt).round() as u64;
            assert_eq!(cue["given"].as_u64(), Some(ticks.div_ceil(every)), "{p}");
        }
    }
    // In one process nobody hands a CPU over.
    assert!(summary(&one)["timing"]["hand_over"].is_null());
}

#[test]
fn two_runs_with_the_same_seed_are_byte_identical_and_another_seed_differs() {
    let a = run_with(
        "seed-a",
        "irregular-track.toml",
        "ipc",
        "gauss-seidel",
        &["--seed", "5"],
    );
    let b = run_with(
        "seed-b",
        "irregular-track.toml",
        "ipc",
        "gauss-seidel",
        &["--seed", "5"],
    );
    let c = run_with(
        "seed-c",
        "irregular-track.toml",
        "in-process",
        "gauss-seidel",
        &["--seed", "6"],
    );
    assert!(bytes(&a) == bytes(&b));
    assert!(bytes(&a) != bytes(&c));
}

#[test]
fn timeseries_has_one_row_per_plant_step_with_the_documented_columns() {
    let d = run_with(
        "columns",
        "paper-passive.toml",
        "in-process",
        "gauss-seidel",
        &[],
    );
    let s = Series::read(&d.join("timeseries.csv"));
    for c in [
        "time",
        "curvature",
        "cant",
        "theta_v",
        "theta_b",
        "y_v",
        "y_b",
        "theta_ref",
        "delta_a_cmd",
        "delta_a",
        "lat_acc",
    ] {
        assert!(s.header.iter().any(|h| h == c), "missing column {c}");
    }
    // 16.8 s at 1 ms: the start time and one row per tick, row k the state at k ms, each
    // time the double nearest to its decimal value (as FMI masters and pandas compare them).
    assert_eq!(s.header[..2], ["time", "step"]);
    assert_eq!(s.rows.len(), 16_801);
    let t = s.col("time");
    for (k, &tk) in t.iter().enumerate() {
        let want: f64 = format!("{}.{:03}", k / 1000, k % 1000).parse().unwrap();
        assert_eq!(tk.to_bits(), want.to_bits(), "row {k}");
    }
    // passive: no command. The eq 18 reference at mid-curve, by hand: the passive vehicle feels
    // 1.164 m/s², so θ_v^d = v²/(gR) − 0.7·1.164/g − θ_o = 0.2064 − 0.0831 − 0.1047 rad ≈ 1.06°.
    assert!(s.col("delta_a_cmd").iter().all(|&v| v == 0.0));
    let r = s.col("theta_ref")[9000];
    assert!(
        (r.to_degrees() - 1.06).abs() < 0.02,
        "theta_ref mid-curve {} deg",
        r.to_degrees()
    );
}

#[test]
fn a_slow_controller_is_held_between_its_updates() {
    // A 50 ms controller period: its outputs change only on multiples of 50 ticks (zero-order
    // hold), on both transports.
    for transport in ["in-process", "ipc"] {
        let d = temp_dir(&format!("multirate-{transport}"));
        let sc = d.join("slow.toml");
        std::fs::write(
            &sc,
            "[controller]\nperiod_s = 0.05\n[run]\nduration_s = 2.0\n",
        )
        .unwrap();
        let pfx = prefix(&format!("mr{transport}"));
        Tiltsim::run(&sc)
            .out(&d)
            .transport(transport)
            .ipc_prefix(&pfx)
            .quiet()
            .duration(8)
            .success();
        let s = Series::read(&d.join("timeseries.csv"));
        let r = s.col("theta_ref");
        let steps = s.col("step");
        let mut changes = 0;
        for i in 1..r.len() {
            if r[i] != r[i - 1] {
                changes += 1;
                // Row `step` ends tick `step` − 1: a controller update at tick 50j shows
                // at step 50j + 1.
                assert_eq!(
                    (steps[i] as u64 - 1) % 50,
                    0,
                    "reference changed at step {}",
                    steps[i]
                );
            }
        }
        assert!(
            changes > 10,
            "the reference must move along the transition ({changes} changes)"
        );
        assert!(leftovers(&pfx).is_empty());
    }
}

#[test]
fn jacobi_over_ipc_gives_the_measured_heaviest_participant_a_cpu_of_its_own() {
    // paper-mpc: the event-driven electrics (~5-7 µs per tick) against the plant (~0.15 µs),
    // the MPC (~35 µs every 50 ticks, under 1 µs per tick) and the orchestrator's own work
    // per tick (~2-4 µs: the observers and the CSV row).
    let heavy = "paper-mpc.toml";
    let measured = on_a_pair("cpu-plan-measured", heavy);
    let plan = &summary(&measured)["timing"]["cpu_plan"];
    let cpus = cosim::ipc::allowed_cpus();
    if cpus.len() >= 2 {
        let c = &plan["compute_per_tick_us"];
        let (a, p, k) = (
            c["actuator"].as_f64().unwrap(),
            c["plant"].as_f64().unwrap(),
            c["controller"].as_f64().unwrap(),
        );
        // The electrics are most of the compute on any machine.
        assert!(a > 0.5 * (a + p + k), "{plan}");
        // Whether they also cover the orchestrator's own work (about 1.5 µs against 5.5 µs
        // on a quiet machine) is measured: on a machine loaded far past its CPUs the
        // orchestrator's work, timed on the wall, can take longer, and then nobody moves.
        if a >= plan["orchestrator_us"].as_f64().unwrap() {
            assert_eq!(plan["own_cpu"], "actuator", "{plan}");
            assert_eq!(plan["applied"], true, "{plan}");
            assert_eq!(plan["heavy_cpu"], *cpus.last().unwrap(), "{plan}");
            assert_eq!(plan["shared_cpu"], cpus[0], "{plan}");
        } else {
            assert!(plan["own_cpu"].is_null(), "{plan}");
            assert_eq!(plan["applied"], false, "{plan}");
        }
        // The passive vehicle's participants (~0.15 µs per tick at most) cannot hide the
        // orchestrator's work: nobody is moved.
        let light = on_a_pair("cpu-plan-light", "paper-passive.toml");
        let plan = &summary(&light)["timing"]["cpu_plan"];
        assert!(plan["own_cpu"].is_null(), "{plan}");
        assert_eq!(plan["applied"], false, "{plan}");
    } else {
        // One CPU: nothing to place.
        assert!(plan.is_null(), "{plan}");
    }
    // Placement never changes a value: the fixed plan, the measured one and Gauss-Seidel's
    // in-process twin of Jacobi give the same rows.
    let out = run_with(
        "cpu-plan-fixed-run",
        "paper-mpc.toml",
        "ipc",
        "jacobi",
        &["--duration", "1", "--set", "run.cpu_plan=fixed"],
    );
    assert!(summary(&out)["timing"]["cpu_plan"].is_null());
    let in_process = run_with(
        "cpu-plan-inproc",
        heavy,
        "in-process",
        "jacobi",
        &["--duration", "1"],
    );
    assert!(
        bytes(&measured) == bytes(&out),
        "measured and fixed plans differ"
    );
    assert!(
        bytes(&measured) == bytes(&in_process),
        "IPC and in-process Jacobi differ"
    );
}

/// A request and a reply lost at the transport (the orchestrator's first sending of a
/// request, a participant's first sending of a reply, dropped on purpose through
/// `TILTSIM_DROP_SAMPLES`): the run completes, every value the same as in-process (a repeated
/// request is answered from the last reply, the model is not stepped twice, which would shift
/// every later row), and each loss is found and counted in perf.json for its participant.
#[test]
fn a_lost_request_or_reply_is_resent_counted_and_changes_no_value() {
    for master in ["gauss-seidel", "jacobi"] {
        let name = format!("lost-samples-{master}");
        let dir = temp_dir(&name);
        let pfx = prefix(&name);
        let sc = scenario("paper-lqg.toml");
        // The controller is stepped every tick here, as the plant and the actuator.
        Tiltsim::run(&sc)
            .out(&dir)
            .transport_ipc()
            .master(master)
            .duration(1)
            .ipc_prefix(&pfx)
            .quiet()
            .env(
                "TILTSIM_DROP_SAMPLES",
                "plant:request:100,plant:reply:200,actuator:reply:300,controller:request:400,controller:reply:401",
            )
            .success();
        assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
        let reference = run_with(
            &format!("lost-samples-ref-{master}"),
            "paper-lqg.toml",
            "in-process",
            master,
            &["--duration", "1"],
        );
        assert!(
            bytes(&dir) == bytes(&reference),
            "{master}: a repaired loss changed the series"
        );
        assert_eq!(summary(&dir)["steps_completed"], 1000);
        let perf: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("perf.json")).unwrap()).unwrap();
        let lost = |role: &str| perf["participants"][role]["lost_samples"].clone();
        // What was dropped, per participant: (lost requests, lost replies).
        for (role, requests, replies) in [("plant", 1, 1), ("actuator", 0, 1), ("controller", 1, 1)]
        {
            let l = lost(role);
            assert_eq!(l["lost_requests"], requests, "{master} {role}: {l}");
            assert_eq!(l["lost_replies"], replies, "{master} {role}: {l}");
            // Each loss is repaired by a re-send; a lost reply is answered again from the last
            // reply (a repeat), a lost request is simply taken the second time. (Under heavy
            // load a re-send can also go to a participant that is only slow: never fewer.)
            let at_least = |k: &str, n: u64| {
                assert!(l[k].as_u64().unwrap() >= n, "{master} {role}: {k} in {l}");
            };
            at_least("resends", requests + replies);
            at_least("repeats_answered", replies);
        }
    }
}

/// The whole car (`vehicle.model = "full"`) over both transports: the same bytes; a series
/// other than the half vehicle's; the summary's running safety (five quantities, each with its
/// wheelset and limit) and comfort at three places, with the flag beside the other flags.
/// The centre's P_CT from the whole car's own body acceleration (its equations of motion)
/// agrees with the `with-sway` form, which the assessment builds from the secondary
/// suspension's forces on the car-centre states of the same run, within 3 %: two derivations
/// of the body's acceleration, one from the whole car's equations of motion, one from the
/// secondary suspension's deflection the plant reports at the centre.
#[test]
fn the_whole_car_gives_byte_identical_timeseries_over_both_transports() {
    let full = ["--set", "vehicle.model=full"];
    let a = run_with(
        "full-ipc",
        "irregular-track.toml",
        "ipc",
        "gauss-seidel",
        &full,
    );
    let b = run_with(
        "full-inproc",
        "irregular-track.toml",
        "in-process",
        "gauss-seidel",
        &[
            "--set",
            "vehicle.model=full",
            "--set",
            "comfort.lateral_acceleration=with-sway",
        ],
    );
    assert!(bytes(&a) == bytes(&b), "ipc and in-process differ");
    let half = run_with(
        "half-inproc",
        "irregular-track.toml",
        "in-process",
        "gauss-seidel",
        &[],
    );
    assert!(
        bytes(&a) != bytes(&half),
        "the whole car ran as the half vehicle"
    );
    let s = summary(&a);
    let safety = s["full_car"]["running_safety"].as_array().unwrap();
    let names: Vec<&str> = safety
        .iter()
        .map(|q| q["quantity"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["(Y/Q)_2m", "(SumY)_2m", "dQ/Q0", "Y_qst", "Q_qst"]);
    for q in safety {
        let w = q["wheelset"].as_u64().unwrap();
        assert!((1..=4).contains(&w), "{q}");
        let (v, l) = (q["value"].as_f64().unwrap(), q["limit"].as_f64().unwrap());
        assert_eq!(q["exceeded"].as_bool().unwrap(), v > l, "{q}");
    }
    let flag = &s["flags"]["running_safety"];
    assert_eq!(
        flag["raised"].as_bool().unwrap(),
        safety.iter().any(|q| q["exceeded"].as_bool().unwrap())
    );
    let places = s["full_car"]["comfort_along_car"].as_array().unwrap();
    assert_eq!(places.len(), 3);
    assert!(summary(&half).get("full_car").is_none());
    // Same run, in process, with the other form as the headline.
    let sway = summary(&b)["comfort"]["p_ct_en12299"]["standing_pct"]
        .as_f64()
        .unwrap();
    let centre = places[1]["p_ct_standing"].as_f64().unwrap();
    assert_eq!(places[1]["place"], "centre");
    assert!(
        (centre - sway).abs() < 0.03 * centre,
        "centre {centre} %, with-sway {sway} %"
    );
    // The straight-track ride likewise: N_MV's lateral part at the centre from the body's own
    // acceleration against the summary's, from the secondary forces (measured 1.7 % apart).
    let n_centre = places[1]["n_mv_lateral"].as_f64().unwrap();
    let n_sway = s["comfort"]["ride"]["n_mv_lateral"].as_f64().unwrap();
    assert!(
        (n_centre - n_sway).abs() < 0.03 * n_centre,
        "centre {n_centre}, with-sway {n_sway}"
    );
}
