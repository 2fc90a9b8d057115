//! Participants on other hosts over Zenoh, each test on two hosts of its own: network
//! namespaces joined by a veth link (`support::hosts`, root and iproute2 needed; without them
//! the test fails saying what to install). The orchestrator runs on host `a`, the remote
//! participants on host `b`, started as a user starts them: `tiltsim participant ROLE
//! --connect ADDRESS` with the run's secret in `TILTSIM_SECRET`.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::Child;
use std::time::Duration;

use tiltsim_suite::hosts::{Host, Pair};
use tiltsim_suite::{
    csv_table, leftovers, run, summary, temp_dir, wait_for, wait_with_limit, Tiltsim,
};

const SECRET: &str = "7f3a9c1e5b2d4f60";
const PORT: u16 = 7447;
/// Long enough for any run here to end on a loaded machine; a run past it is a hang.
const LIMIT: Duration = Duration::from_secs(600);

/// `tiltsim run` of `scenario` on host `a` with `roles` on other hosts, the run's secret in
/// the environment.
fn orchestrator(pair: &Pair, scenario: &str, roles: &[&str], out: &Path) -> Tiltsim {
    let mut t = Tiltsim::run(scenario)
        .transport_ipc()
        .out(out)
        .arg("--listen")
        .arg(pair.a.endpoint(PORT))
        .env("TILTSIM_SECRET", SECRET)
        .on(&pair.a);
    for r in roles {
        t = t.arg("--remote").arg(r);
    }
    t
}

/// `tiltsim participant ROLE --connect` on `host`, joining the run on `to` with `secret`.
fn participant(host: &Host, to: &Host, role: &str, secret: &str) -> Tiltsim {
    Tiltsim::command(["participant", role, "--connect"])
        .arg(to.endpoint(PORT))
        .env("TILTSIM_SECRET", secret)
        .on(host)
}

fn finish(child: Child, what: &str) -> (i32, String) {
    let (code, _, err) = wait_with_limit(child, LIMIT);
    eprintln!("{what}: exit {code}\n{err}");
    (code, err)
}

#[test]
fn a_remote_controller_and_actuator_give_the_bytes_of_one_process() {
    let pair = Pair::new("lockstep");
    let dir = temp_dir("net-lockstep");
    let (local, remote) = (dir.join("in-process"), dir.join("remote"));
    // A link effect acts on the values in flight as on one host.
    let delayed = ("links.measurement.delay_ticks", 3);
    Tiltsim::run("paper-mpc.toml")
        .transport_in_process()
        .duration(1.5)
        .set(delayed.0, delayed.1)
        .out(&local)
        .quiet()
        .success();
    let run = orchestrator(
        &pair,
        "paper-mpc.toml",
        &["controller", "actuator"],
        &remote,
    )
    .duration(1.5)
    .set(delayed.0, delayed.1)
    .deadline_ms(20_000)
    .quiet()
    .spawn();
    let parts: Vec<Child> = ["controller", "actuator"]
        .iter()
        .map(|r| participant(&pair.b, &pair.a, r, SECRET).spawn())
        .collect();
    let (code, err) = finish(run, "orchestrator");
    assert_eq!(code, 0, "{err}");
    for (p, r) in parts.into_iter().zip(["controller", "actuator"]) {
        let (code, err) = finish(p, r);
        assert_eq!(code, 0, "the {r} ends cleanly when the run stops it: {err}");
    }
    for f in ["timeseries.csv", "events.csv"] {
        let (a, b) = (
            std::fs::read(local.join(f)).unwrap(),
            std::fs::read(remote.join(f)).unwrap(),
        );
        assert!(
            a == b,
            "{f}: a run with participants on another host differs from in-process"
        );
    }
    let sm = summary(&remote);
    let joined = sm["network"]["joined"].as_array().unwrap();
    let roles: Vec<&str> = joined.iter().map(|j| j["role"].as_str().unwrap()).collect();
    assert_eq!(roles, ["actuator", "controller"]);
    for j in joined {
        // Both hosts read one kernel's monotonic clock, so the true offset is 0, and the
        // orchestrator's reading lies inside the participant's round trip: the measured offset
        // is within half the round trip of 0, exactly.
        let (offset, rtt) = (
            j["clock_offset_ns"].as_i64().unwrap(),
            j["clock_rtt_ns"].as_u64().unwrap(),
        );
        assert!(
            rtt > 0 && offset.unsigned_abs() <= rtt / 2 + 1,
            "offset {offset} ns, rtt {rtt} ns"
        );
    }
    assert_eq!(sm["network"]["refused"].as_array().unwrap().len(), 0);
    let exits: Vec<&str> = sm["participants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["exit"]["status"].as_str().unwrap())
        .collect();
    assert!(
        exits[1].starts_with("stopped on host") && exits[2].starts_with("stopped on host"),
        "{exits:?}"
    );
}

#[test]
fn wrong_credentials_and_a_second_participant_for_a_role_are_refused_by_name() {
    use std::sync::atomic::Ordering;
    let pair = Pair::new("creds");
    let dir = temp_dir("net-creds");
    let mut run = orchestrator(&pair, "paper-lqg.toml", &["controller"], &dir)
        .duration(10)
        .deadline_ms(20_000)
        .progress_machine()
        .spawn();
    let step = watch_steps(&mut run);
    let (code, err) = finish(
        participant(&pair.b, &pair.a, "controller", "not-the-secret")
            .args(["--join-timeout-s", "3"])
            .spawn(),
        "wrong secret",
    );
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("the run's secret does not match"),
        "a participant with another secret is told why: {err}"
    );
    let right = participant(&pair.b, &pair.a, "controller", SECRET).spawn();
    // Steps go on once the controller has joined; a second one is then refused, naming the
    // first.
    assert!(
        wait_for(LIMIT, || (step.load(Ordering::Acquire) >= 1).then_some(())).is_some(),
        "the run never started"
    );
    let (code, _, second) = participant(&pair.b, &pair.a, "controller", SECRET)
        .args(["--join-timeout-s", "30"])
        .result();
    assert_eq!(code, 1, "{second}");
    assert!(
        second.contains("refused by the run: controller has already joined (from host"),
        "{second}"
    );
    let (code, _, err) = wait_with_limit(run, LIMIT);
    assert_eq!(
        code, 0,
        "the run goes on with the participant that belongs: {err}"
    );
    assert_eq!(finish(right, "controller").0, 0);
    let sm = summary(&dir);
    let refused = sm["network"]["refused"].as_array().unwrap().clone();
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(refused[0]["reason"]
        .as_str()
        .unwrap()
        .contains("already joined"));
    // The wrong secret never got a TLS session: the run names the attempt.
    let kinds = attempt_kinds(&sm);
    assert!(
        kinds.contains(&"wrong_credentials".to_string()),
        "{kinds:?}"
    );
    assert!(kinds.contains(&"second_session".to_string()), "{kinds:?}");
}

/// The kinds of `summary.json` → `network.attempts`.
fn attempt_kinds(sm: &serde_json::Value) -> Vec<String> {
    sm["network"]["attempts"]
        .as_array()
        .unwrap_or_else(|| panic!("no network.attempts in {sm}"))
        .iter()
        .map(|a| a["kind"].as_str().unwrap().to_string())
        .collect()
}

/// `rogue-peer` (tests/bin) on `host` attacking the run `key` on `to` as `mode`, until its
/// standard input closes.
fn rogue(host: &Host, to: &Host, key: &str, mode: &str) -> Child {
    std::process::Command::new(tiltsim_suite::hosts::ip())
        .args(["netns", "exec", host.netns()])
        .arg(env!("CARGO_BIN_EXE_rogue-peer"))
        .args(["--connect", &to.endpoint(PORT), "--run", key, "--as", mode])
        .args(["--secret", SECRET])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("rogue-peer")
}

/// The run's key, from the join command a run prints while it waits (the rest of its
/// standard error is read on a thread, so that the run never blocks on a full pipe).
fn run_key(run: &mut Child) -> String {
    let mut lines = BufReader::new(run.stderr.take().expect("stderr piped")).lines();
    let key = loop {
        let line = lines
            .next()
            .and_then(Result::ok)
            .expect("the run ended before printing its join command");
        if let Some(k) = line.split("--run ").nth(1) {
            break k
                .split(|c: char| !c.is_ascii_hexdigit())
                .next()
                .unwrap()
                .to_string();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    key
}

#[test]
fn peers_without_the_runs_credentials_read_nothing_and_change_nothing() {
    let pair = Pair::new("rogue");
    let dir = temp_dir("net-rogue");
    let (local, remote) = (dir.join("in-process"), dir.join("remote"));
    Tiltsim::run("paper-lqg.toml")
        .transport_in_process()
        .duration(3)
        .out(&local)
        .quiet()
        .success();
    let mut run = orchestrator(&pair, "paper-lqg.toml", &["controller"], &remote)
        .duration(3)
        .deadline_ms(60_000)
        .spawn();
    let key = run_key(&mut run);
    assert_eq!(key.len(), 32, "{key}");
    // Zenoh over plain TCP with no credentials (nothing of the run listens on TCP: the kernel
    // refuses it), another secret's credentials, and valid certificates of two roles this run
    // has on no other host; each reads everything it may, stops reading, floods forged
    // samples on every role's keys and answers the run's queries itself, from before the
    // participant joins until the run has ended.
    let modes = ["plain", "wrong", "actuator", "plant"];
    let mut rogues: Vec<Child> = modes
        .iter()
        .map(|m| rogue(&pair.b, &pair.a, &key, m))
        .collect();
    std::thread::sleep(Duration::from_secs(2));
    let part = participant(&pair.b, &pair.a, "controller", SECRET).spawn();
    let (code, _, _) = wait_with_limit(run, LIMIT);
    let (pcode, perr) = finish(part, "controller");
    for r in &mut rogues {
        drop(r.stdin.take());
    }
    let reports: Vec<serde_json::Value> = rogues
        .into_iter()
        .map(|r| {
            let (_, out, err) = wait_with_limit(r, LIMIT);
            serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}\n{err}"))
        })
        .collect();
    assert_eq!(code, 0, "the run completes whatever the others do");
    assert_eq!(pcode, 0, "{perr}");
    for r in &reports {
        assert_eq!(r["samples_received"], 0, "{r}");
        assert_eq!(r["query_answers"], 0, "{r}");
        assert!(r["puts_sent"].as_u64().unwrap() > 0, "it did try: {r}");
    }
    assert!(
        std::fs::read(local.join("timeseries.csv")).unwrap()
            == std::fs::read(remote.join("timeseries.csv")).unwrap(),
        "forged samples change nothing: the rows are those of one process"
    );
    let sm = summary(&remote);
    let kinds = attempt_kinds(&sm);
    for want in ["wrong_credentials", "other_role"] {
        assert!(
            kinds.iter().any(|k| k == want),
            "{want} not named: {kinds:?}"
        );
    }
    let names: Vec<&str> = sm["network"]["attempts"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|a| a["common_name"].as_str())
        .collect();
    // Named by their certificates: `ROLE.<the run's authority>`.
    for role in ["actuator", "plant"] {
        assert!(
            names.iter().any(|n| n.starts_with(&format!("{role}."))),
            "{names:?}"
        );
    }
    let events = std::fs::read_to_string(remote.join("events.csv")).unwrap();
    assert!(
        events
            .lines()
            .filter(|l| l.contains("network-refused"))
            .count()
            >= 4,
        "{events}"
    );
}

#[test]
fn a_participant_that_never_comes_ends_the_run_naming_it() {
    let pair = Pair::new("absent");
    let dir = temp_dir("net-absent");
    let (code, _, err) = orchestrator(&pair, "paper-lqg.toml", &["actuator"], &dir)
        .set("network.join_timeout_s", 1)
        .result();
    assert_ne!(code, 0, "{err}");
    assert!(
        err.contains(&format!(
            "participant actuator never joined the run at {}",
            pair.a.endpoint(PORT)
        )),
        "{err}"
    );
    assert!(leftovers("tiltsim_")
        .iter()
        .all(|p| !p.to_string_lossy().contains("absent")));
}

/// The run's `--progress machine` lines, read on a thread: the step of the newest.
fn watch_steps(run: &mut Child) -> std::sync::Arc<std::sync::atomic::AtomicU64> {
    use std::sync::atomic::{AtomicU64, Ordering};
    let step = std::sync::Arc::new(AtomicU64::new(0));
    let seen = step.clone();
    let err = run.stderr.take().expect("stderr piped");
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            if let Some(k) = line
                .split("\"step\":")
                .nth(1)
                .and_then(|r| r.split(',').next())
                .and_then(|k| k.parse().ok())
            {
                seen.store(k, Ordering::Release);
            }
        }
    });
    step
}

#[test]
fn a_cut_link_is_detected_and_named_and_degraded_mode_takes_over() {
    use std::sync::atomic::Ordering;
    let pair = Pair::new("cut");
    let dir = temp_dir("net-cut");
    let mut run = orchestrator(&pair, "paper-lqg.toml", &["controller"], &dir)
        .deadline_ms(2000)
        .set("faults.on_failure", "degrade")
        .progress_machine()
        .spawn();
    let step = watch_steps(&mut run);
    let part = participant(&pair.b, &pair.a, "controller", SECRET).spawn();
    assert!(
        wait_for(LIMIT, || (step.load(Ordering::Acquire) >= 1000)
            .then_some(()))
        .is_some(),
        "the run never reached step 1000"
    );
    pair.b.set_link(false);
    let (code, _, _) = wait_with_limit(run, LIMIT);
    let (pcode, perr) = finish(part, "controller");
    pair.b.set_link(true);
    assert_eq!(code, 0, "degraded mode completes the run");
    let sm = summary(&dir);
    assert_eq!(sm["status"], "degraded");
    let events = std::fs::read_to_string(dir.join("events.csv")).unwrap();
    let lost = events
        .lines()
        .find(|l| l.contains("controller") && (l.contains("stalled") || l.contains("exited")))
        .unwrap_or_else(|| panic!("no lost controller in events.csv:\n{events}"));
    let at: u64 = lost.split(',').nth(1).unwrap().parse().unwrap_or(0);
    assert!(at >= 1000, "named at the step it was lost: {lost}");
    let error = sm["participants"][2]["exit"]["status"].to_string();
    assert!(!error.is_empty());
    assert_ne!(pcode, 0, "the cut-off participant ends on its own: {perr}");
    assert!(perr.contains("orchestrator left"), "{perr}");
}

#[test]
fn a_partition_shorter_than_the_deadline_heals_without_a_trace_in_the_results() {
    use std::sync::atomic::Ordering;
    let pair = Pair::new("heal");
    let dir = temp_dir("net-heal");
    let local = dir.join("in-process");
    Tiltsim::run("paper-lqg.toml")
        .transport_in_process()
        .duration(3)
        .out(&local)
        .quiet()
        .success();
    let remote = dir.join("remote");
    let mut run = orchestrator(
        &pair,
        "paper-lqg.toml",
        &["controller", "actuator"],
        &remote,
    )
    .duration(3)
    .deadline_ms(30_000)
    .set("network.lease_ms", 20_000)
    .progress_machine()
    .spawn();
    let step = watch_steps(&mut run);
    let parts: Vec<Child> = ["controller", "actuator"]
        .iter()
        .map(|r| {
            participant(&pair.b, &pair.a, r, SECRET)
                .arg("--lease-ms")
                .arg("20000")
                .spawn()
        })
        .collect();
    assert!(wait_for(LIMIT, || (step.load(Ordering::Acquire) >= 500)
        .then_some(()))
    .is_some());
    pair.b.set_link(false);
    std::thread::sleep(Duration::from_millis(500));
    pair.b.set_link(true);
    let (code, _, err) = wait_with_limit(run, LIMIT);
    assert_eq!(code, 0, "{err}");
    for p in parts {
        assert_eq!(finish(p, "participant").0, 0);
    }
    assert!(
        std::fs::read(local.join("timeseries.csv")).unwrap()
            == std::fs::read(remote.join("timeseries.csv")).unwrap(),
        "a healed partition only delays samples; the values are those of one process"
    );
}

#[test]
fn a_remote_participant_killed_mid_run_is_named_at_once() {
    use std::sync::atomic::Ordering;
    let pair = Pair::new("kill");
    let dir = temp_dir("net-kill");
    let mut run = orchestrator(&pair, "paper-lqg.toml", &["controller"], &dir)
        .deadline_ms(60_000)
        .progress_machine()
        .spawn();
    let step = watch_steps(&mut run);
    let mut part = participant(&pair.b, &pair.a, "controller", SECRET).spawn();
    assert!(wait_for(LIMIT, || (step.load(Ordering::Acquire) >= 500)
        .then_some(()))
    .is_some());
    part.kill().unwrap();
    let _ = part.wait();
    let (code, _, _) = wait_with_limit(run, LIMIT);
    assert_eq!(code, 1, "the run fails as [faults] on_failure = abort says");
    let sm = summary(&dir);
    assert_eq!(sm["status"], "failed");
    let error = sm["error"].as_str().unwrap();
    // Named by the closed connection, long before the 60 s deadline could.
    assert!(
        error.contains("participant controller on host") && error.contains("left the run"),
        "{error}"
    );
    let rows = std::fs::read_to_string(dir.join("timeseries.csv")).unwrap();
    assert!(
        rows.lines().count() > 500,
        "the rows recorded so far are kept"
    );
}

#[test]
fn a_free_run_across_hosts_is_recorded_and_replayed_byte_for_byte() {
    let pair = Pair::new("free");
    let dir = temp_dir("net-free");
    let free = dir.join("free");
    let orch = orchestrator(&pair, "pi-drive.toml", &["controller"], &free)
        .free_run()
        .duration(2)
        .quiet()
        .spawn();
    let part = participant(&pair.b, &pair.a, "controller", SECRET).spawn();
    let (code, err) = finish(orch, "orchestrator");
    assert_eq!(code, 0, "{err}");
    assert_eq!(finish(part, "controller").0, 0);
    let sm = summary(&free);
    assert_eq!(sm["status"], "completed");
    assert_eq!(sm["network"]["joined"][0]["role"], "controller");
    // The controller's steps in the trace: read and published on the orchestrator's clock, in
    // order, each published after it read.
    let trace = std::fs::read_to_string(free.join("timing.csv")).unwrap();
    let rows = csv_table(
        &trace
            .lines()
            .filter(|l| !l.starts_with('#'))
            .collect::<Vec<_>>()
            .join("\n"),
    );
    let col = |name: &str| rows[0].iter().position(|c| c == name).unwrap();
    let (role, read, publish) = (col("role"), col("read_ns"), col("publish_ns"));
    let ctrl: Vec<&Vec<String>> = rows[1..]
        .iter()
        .filter(|r| r[role] == "controller")
        .collect();
    assert!(!ctrl.is_empty());
    for r in &ctrl {
        let (a, b): (u64, u64) = (r[read].parse().unwrap(), r[publish].parse().unwrap());
        assert!(a <= b, "published before it read: {r:?}");
    }
    let out = dir.join("replay");
    let (code, _, err) = run(&[
        "replay-timing",
        free.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        std::fs::read(free.join("timeseries.csv")).unwrap()
            == std::fs::read(out.join("timeseries.csv")).unwrap(),
        "the replay on one machine gives the free run's rows"
    );
}

#[test]
fn a_scheduled_kill_of_a_remote_participant_degrades_the_run_as_in_one_process() {
    let pair = Pair::new("sched");
    let dir = temp_dir("net-sched");
    // A `[[faults.schedule]]` entry is an array-of-tables element, which `--set` cannot add.
    let base = std::fs::read_to_string(tiltsim_suite::scenario("paper-lqg.toml")).unwrap();
    let sc = dir.join("killed.toml");
    std::fs::write(
        &sc,
        format!("{base}\n[[faults.schedule]]\nparticipant = \"controller\"\naction = \"kill\"\nat_s = 0.5\n"),
    )
    .unwrap();
    let local = dir.join("in-process");
    Tiltsim::run(&sc)
        .transport_in_process()
        .duration(1.5)
        .set("faults.on_failure", "degrade")
        .out(&local)
        .quiet()
        .success();
    let remote = dir.join("remote");
    let run = orchestrator(&pair, sc.to_str().unwrap(), &["controller"], &remote)
        .duration(1.5)
        .set("faults.on_failure", "degrade")
        .deadline_ms(20_000)
        .quiet()
        .spawn();
    let part = participant(&pair.b, &pair.a, "controller", SECRET).spawn();
    let (code, err) = finish(run, "orchestrator");
    assert_eq!(code, 0, "{err}");
    let (pcode, _) = finish(part, "controller");
    assert_ne!(
        pcode, 0,
        "the participant killed itself as the schedule said"
    );
    assert_eq!(summary(&remote)["status"], "degraded");
    assert!(
        std::fs::read(local.join("timeseries.csv")).unwrap()
            == std::fs::read(remote.join("timeseries.csv")).unwrap(),
        "the kill reaches the remote participant at the tick it reaches one in process"
    );
}

/// `tiltsim bench --network` across two hosts: the wire's floor and every Zenoh floor measured
/// on the same path, the run's link first, and the per-tick overhead of a remote plant set
/// beside them. The ratios in `bench.json` are recomputed here from the figures beside them.
#[test]
fn bench_network_measures_the_wire_and_each_zenoh_floor_across_two_hosts() {
    let pair = Pair::new("bench");
    let dir = temp_dir("net-bench");
    let json = dir.join("bench.json");
    let via = format!(
        "{} netns exec {}",
        tiltsim_suite::hosts::ip().display(),
        pair.b.netns()
    );
    let out = Tiltsim::command(["bench"])
        .arg(tiltsim_suite::scenario("paper-passive.toml"))
        .args(["--network", "--listen"])
        .arg(pair.a.endpoint(PORT))
        .args([
            "--remote-via",
            &via,
            "--rounds",
            "300",
            "--duration",
            "0.2",
            "--repeat",
            "1",
        ])
        .arg("--out")
        .arg(&json)
        .on(&pair.a)
        .success();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("(a run's link)"), "{stdout}");
    let b: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let n = &b["network"];
    let floors = n["floors"].as_array().unwrap();
    let names: Vec<&str> = floors.iter().map(|f| f["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "raw-tcp",
            "zenoh-quic-lowlatency",
            "zenoh-quic",
            "zenoh-tcp-lowlatency",
            "zenoh-tcp"
        ]
    );
    let p = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
    let raw = &floors[0]["round_trip_ns"];
    for f in floors {
        let rtt = &f["round_trip_ns"];
        assert_eq!(rtt["n"], 300, "{f}");
        assert!(p(rtt, "p50") > 0.0 && p(rtt, "p99") >= p(rtt, "p50"), "{f}");
        let ratio = p(rtt, "p50") / p(raw, "p50");
        assert!(
            (p(f, "p50_over_raw_tcp") - ratio).abs() <= 1e-9 * ratio,
            "{f}"
        );
    }
    assert_eq!(n["floor_round_trip_ns"], floors[1]["round_trip_ns"]);
    let runs = n["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for r in runs {
        // Every tick of the remote run waits for a round trip the in-process one does not.
        let per_tick = p(r, "overhead_per_tick_us");
        assert!(per_tick > 0.0, "{r}");
        let over_floor = per_tick / (p(&n["floor_round_trip_ns"], "p50") * 1e-3);
        assert!((p(r, "overhead_over_floor") - over_floor).abs() <= 1e-9 * over_floor);
    }
}
