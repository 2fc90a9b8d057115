//! Many runs on one machine: each IPC run claims the CPUs it pins to, a run starting beside it
//! chooses around that claim, a killed run's claim goes with it, `--wait spin` falls back when
//! its processes outnumber its CPUs, and the values never depend on the placement. The runs
//! here take every unclaimed CPU for idle (`TILTSIM_ASSUME_IDLE_CPUS=1`), so other work on the
//! machine cannot change what they choose. Nothing here reads a clock.

use std::os::fd::AsRawFd;
use std::path::Path;
use std::time::Duration;

use cosim::ipc::placement::{ASSUME_IDLE, CLAIM_FILE};
use tiltsim_suite::{leftovers, prefix, scenario, summary, temp_dir, wait_for, Tiltsim};

/// The CPUs a run's summary says it pinned to (orchestrator first).
fn pinned_cpus(s: &serde_json::Value) -> Vec<u64> {
    let p = &s["timing"]["placement"];
    p["orchestrator_cpu"]
        .as_u64()
        .into_iter()
        .chain(
            p["participant_cpus"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|c| c.as_u64()),
        )
        .collect()
}

/// The CPUs in a claim file, if it is there.
fn claim_of(pfx: &str) -> Option<Vec<u64>> {
    let text = std::fs::read_to_string(format!("/dev/shm/{pfx}{CLAIM_FILE}")).ok()?;
    let cpus: Vec<u64> = text.lines().filter_map(|l| l.parse().ok()).collect();
    (!cpus.is_empty()).then_some(cpus)
}

/// Whether a live process holds the lock of the claim file of `pfx`.
fn claim_held(pfx: &str) -> bool {
    let Ok(f) = std::fs::File::open(format!("/dev/shm/{pfx}{CLAIM_FILE}")) else {
        return false;
    };
    // SAFETY: flock on a valid descriptor; a shared lock granted means no exclusive holder.
    unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_SH | libc::LOCK_NB) != 0 }
}

/// The timeseries of paper-passive in one process, 0.5 s.
fn in_process(name: &str) -> Vec<u8> {
    let out = temp_dir(name).join("out");
    Tiltsim::run(scenario("paper-passive.toml"))
        .out(&out)
        .transport_in_process()
        .duration(0.5)
        .quiet()
        .success();
    std::fs::read(out.join("timeseries.csv")).unwrap()
}

#[test]
fn a_second_run_chooses_around_the_first_ones_claim_and_a_killed_runs_claim_goes() {
    let allowed = cosim::ipc::allowed_cpus();
    if allowed.len() < 2 {
        eprintln!("one CPU: nothing is pinned, nothing to claim");
        return;
    }
    let sc = scenario("paper-passive.toml");
    // A long run that holds its claim while the second one starts.
    let first = prefix("placement-first");
    let mut a = Tiltsim::run(&sc)
        .out(temp_dir("placement-first").join("out"))
        .transport_ipc()
        .ipc_prefix(&first)
        .duration(600)
        .env(ASSUME_IDLE, "1")
        .quiet()
        .spawn();
    let claimed = wait_for(Duration::from_secs(120), || claim_of(&first));
    let Some(claimed) = claimed else {
        let _ = a.kill();
        let _ = a.wait();
        // Other runs of this machine held every pair: nothing claimed, nothing to check.
        eprintln!("the first run claimed no CPUs (other runs hold them)");
        return;
    };
    assert!(claim_held(&first), "a live run holds its claim");

    let out = temp_dir("placement-second").join("out");
    let second = prefix("placement-second");
    Tiltsim::run(&sc)
        .out(&out)
        .transport_ipc()
        .ipc_prefix(&second)
        .duration(0.5)
        .env(ASSUME_IDLE, "1")
        .quiet()
        .success();
    let s = summary(&out);
    let p = &s["timing"]["placement"];
    let seen: Vec<u64> = p["claimed_by_other_runs"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|c| c.as_u64())
        .collect();
    for c in &claimed {
        assert!(seen.contains(c), "the second run saw CPU {c} claimed: {p}");
    }
    let mine = pinned_cpus(&s);
    assert!(
        mine.iter().all(|c| !claimed.contains(c)),
        "disjoint CPUs: {mine:?} against {claimed:?}"
    );
    if mine.is_empty() {
        assert_eq!(p["reason"], "contended", "{p}");
        assert_eq!(p["wait"], "paced", "a contended run naps: {p}");
    }
    // Where it ran changes no value.
    assert!(
        std::fs::read(out.join("timeseries.csv")).unwrap() == in_process("placement-reference"),
        "the placed run differs from the run in one process"
    );
    assert!(leftovers(&second).is_empty(), "{:?}", leftovers(&second));

    // Killed: the kernel releases its lock at once; the next run removes its files.
    a.kill().unwrap();
    a.wait().unwrap();
    assert!(!claim_held(&first), "a killed run's claim is released");
    let third = temp_dir("placement-third").join("out");
    Tiltsim::run(&sc)
        .out(&third)
        .transport_ipc()
        .ipc_prefix(&prefix("placement-third"))
        .duration(0.1)
        .env(ASSUME_IDLE, "1")
        .quiet()
        .success();
    assert!(
        !Path::new(&format!("/dev/shm/{first}{CLAIM_FILE}")).exists(),
        "the killed run's claim file was removed with its other files"
    );
}

#[test]
fn spin_falls_back_when_its_processes_outnumber_its_cpus() {
    let out = temp_dir("placement-spin").join("out");
    Tiltsim::run(scenario("paper-passive.toml"))
        .out(&out)
        .transport_ipc()
        .ipc_prefix(&prefix("placement-spin"))
        .wait("spin")
        // Unpinned, so that it claims nothing the other test here would have to go around.
        .set("run.pin_cpus", "false")
        .duration(0.5)
        .env(ASSUME_IDLE, "1")
        .quiet()
        .success();
    let s = summary(&out);
    let p = &s["timing"]["placement"];
    assert_eq!(p["wait_asked"], "spin");
    assert_eq!(p["reason"], "not-asked");
    if cosim::ipc::allowed_cpus().len() < 4 {
        assert_ne!(p["wait"], "spin", "four spinners on fewer CPUs: {p}");
    } else {
        assert_eq!(p["wait"], "spin", "a CPU for each process: {p}");
    }
    assert!(
        std::fs::read(out.join("timeseries.csv")).unwrap() == in_process("placement-spin-ref"),
        "the run differs from the run in one process"
    );
}

#[test]
fn a_free_run_pins_only_where_the_registry_placed_it() {
    // Pinned only when the run got a pair of CPUs of its own, and then the controller alone on
    // the participants' CPU and the plant and the actuator beside the orchestrator; left to the
    // kernel when other runs of this machine hold the pairs, and when asked not to pin.
    for pin in [true, false] {
        let name = format!("placement-free-{pin}");
        let out = temp_dir(&name).join("out");
        let pfx = prefix(&name);
        Tiltsim::run(scenario("pi-drive.toml"))
            .free_run()
            .out(&out)
            .ipc_prefix(&pfx)
            .set("run.pin_cpus", pin)
            .duration(0.3)
            .env(ASSUME_IDLE, "1")
            .quiet()
            .success();
        assert!(leftovers(&pfx).is_empty(), "{name}: files left");
        let s = summary(&out);
        let f = &s["free_run"];
        let p = &f["placement"];
        let cpus = f["cpus"].as_object().unwrap();
        if !pin {
            assert_eq!(p["reason"], "not-asked", "{p}");
        }
        if p["reason"] == "free-pair" {
            let own = p["orchestrator_cpu"].as_u64().unwrap();
            let theirs = p["participant_cpus"][0].as_u64().unwrap();
            assert_ne!(own, theirs, "{p}");
            assert_eq!(cpus["plant"], own, "{f}");
            assert_eq!(cpus["actuator"], own, "{f}");
            assert_eq!(cpus["controller"], theirs, "{f}");
        } else {
            assert!(cpus.is_empty(), "pinned though placed as {p}: {f}");
        }
    }
}
