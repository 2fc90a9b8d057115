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
