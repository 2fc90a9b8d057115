//! Correctness under load: sixteen IPC runs at once on a two-CPU machine while two CPU hogs
//! run, default settings: all complete, byte-identical to a run alone. A participant that is
//! starved of CPU but running is waited for, at start-up as at every later exchange; only a
//! stopped, gone or idle one is declared stalled. A test of correctness, not of time: nothing
//! here reads a clock.

use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::Duration;

use tiltsim_suite::{leftovers, prefix, scenario, temp_dir, wait_with_limit, Hogs, Tiltsim};

/// The timeseries of scenario `sc` run alone in this process under `master`, in `name`'s
/// directory.
fn run_alone(sc: &Path, name: &str, master: &str) -> Vec<u8> {
    let out = temp_dir(name).join("out");
    Tiltsim::run(sc)
        .out(&out)
        .transport_in_process()
        .master(master)
        .duration(2)
        .quiet()
        .success();
    std::fs::read(out.join("timeseries.csv")).unwrap()
}

/// Starts run `i` of scenario `sc` over IPC (Gauss-Seidel for even `i`, Jacobi for odd) with
/// a prefix of its own: the child, its output directory, its prefix and its master.
fn start_ipc_run(sc: &Path, i: usize) -> (Child, PathBuf, String, &'static str) {
    let name = format!("load-{i}");
    let out = temp_dir(&name).join("out");
    let pfx = prefix(&name);
    let master = if i.is_multiple_of(2) {
        "gauss-seidel"
    } else {
        "jacobi"
    };
    let child = Tiltsim::run(sc)
        .out(&out)
        .transport_ipc()
        .master(master)
        .ipc_prefix(&pfx)
        .duration(2)
        .quiet()
        .spawn();
    (child, out, pfx, master)
}

#[test]
fn sixteen_concurrent_ipc_runs_under_two_cpu_hogs_all_complete_identically() {
    let sc = scenario("paper-lqg.toml");
    let want = run_alone(&sc, "load-solo", "gauss-seidel");
    let hogs = Hogs::start(2);
    let runs: Vec<_> = (0..16).map(|i| start_ipc_run(&sc, i)).collect();
    // Jacobi's series differs from Gauss-Seidel's (one tick on every link): its own reference.
    let want_jacobi = run_alone(&sc, "load-solo-jacobi", "jacobi");
    let mut outcomes = Vec::new();
    for (child, out, pfx, master) in runs {
        // A bound only against a hung test, far beyond any load: never a verdict on speed.
        let (code, _, err) = wait_with_limit(child, Duration::from_secs(1200));
        outcomes.push((code, err, out, pfx, master));
    }
    drop(hogs);
    for (code, err, out, pfx, master) in outcomes {
        assert_eq!(code, 0, "{}: {err}", out.display());
        let reference = if master == "jacobi" {
            &want_jacobi
        } else {
            &want
        };
        assert!(
            std::fs::read(out.join("timeseries.csv")).unwrap() == *reference,
            "{}: {master} differs from the run alone",
            out.display()
        );
        assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
        // The waits for starved participants and the repair of lost samples are counted,
        // per participant.
        let s = tiltsim_suite::summary(&out);
        for p in s["participants"].as_array().unwrap() {
            assert!(p["starved_waits"].is_u64(), "{p}");
            assert!(p["lost_samples"]["resends"].is_u64(), "{p}");
        }
    }
}

/// An IPC run beside two CPU hogs is told the machine slowed it: other work's share of its
/// CPUs is measured (the hogs alone keep both CPUs busy, whatever else runs), `slowed` is
/// true, and the warning names `--realtime` and one process as what helps. Unpaced
/// `--realtime`, where the system grants it, is reported as such (and the warning then does
/// not suggest it); where it refuses, the refusal names the policy. Nothing reads a clock.
#[test]
fn an_ipc_run_beside_cpu_hogs_is_told_it_was_slowed_and_what_helps() {
    let sc = scenario("paper-passive.toml");
    let hogs = Hogs::start(2);
    let dir = temp_dir("slowed").join("out");
    let pfx = prefix("slowed");
    let run = Tiltsim::run(&sc)
        .out(&dir)
        .transport_ipc()
        .ipc_prefix(&pfx)
        .duration(2);
    let (code, _, err) = wait_with_limit(run.spawn(), Duration::from_secs(1200));
    assert_eq!(code, 0, "{err}");
    let m = &tiltsim_suite::summary(&dir)["timing"]["machine"];
    assert_eq!(m["slowed"], true, "{m}");
    assert!(m["others_cpu_share"].as_f64().unwrap() > 0.2, "{m}");
    assert!(m["participants_waited_for_cpu_s"].as_f64().is_some(), "{m}");
    assert_eq!(m["realtime"], false);
    assert!(err.contains("`--realtime`"), "{err}");
    assert!(err.contains("--transport in-process"), "{err}");
    let dir = temp_dir("slowed-rt").join("out");
    let pfx = prefix("slowed-rt");
    let (code, _, err) = wait_with_limit(
        Tiltsim::run(&sc)
            .out(&dir)
            .transport_ipc()
            .ipc_prefix(&pfx)
            .duration(2)
            .realtime()
            .spawn(),
        Duration::from_secs(1200),
    );
    drop(hogs);
    if code == 0 {
        let m = &tiltsim_suite::summary(&dir)["timing"]["machine"];
        assert_eq!(m["realtime"], true, "{m}");
        assert!(!err.contains("`--realtime`"), "{err}");
    } else {
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains("SCHED_FIFO") || err.contains("mlockall") || err.contains("throttle"),
            "{err}"
        );
    }
    assert!(leftovers(&pfx).is_empty(), "{:?}", leftovers(&pfx));
}
