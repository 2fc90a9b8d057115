//! Correctness under load (issue 13): eight IPC runs at once on a two-CPU machine, default
//! settings, all complete, byte-identical to a run alone. A participant that is starved of
//! CPU but running is waited for; only a stopped or idle one is declared stalled.

use std::time::Duration;

use tiltsim_suite::{leftovers, prefix, scenario, spawn, temp_dir, wait_with_limit};

#[test]
fn eight_concurrent_ipc_runs_all_complete_identically() {
    let sc = scenario("paper-lqg.toml");
    let solo = temp_dir("load-solo").join("out");
    let (code, _, err) = tiltsim_suite::run(&[
        "run",
        sc.to_str().unwrap(),
        "--out",
        solo.to_str().unwrap(),
        "--transport",
        "in-process",
        "--duration",
        "2",
        "-q",
    ]);
    assert_eq!(code, 0, "{err}");
    let want = std::fs::read(solo.join("timeseries.csv")).unwrap();
    let runs: Vec<_> = (0..8)
        .map(|i| {
            let name = format!("load-{i}");
            let out = temp_dir(&name).join("out");
            let pfx = prefix(&name);
            let child = spawn(&[
                "run",
                sc.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--transport",
                "ipc",
                "--ipc-prefix",
                &pfx,
                "--duration",
                "2",
                "-q",
            ]);
            (child, out, pfx)
        })
        .collect();
    for (child, out, pfx) in runs {
        let (code, _, err) = wait_with_limit(child, Duration::from_secs(300));
        assert_eq!(code, 0, "{}: {err}", out.display());
        assert_eq!(std::fs::read(out.join("timeseries.csv")).unwrap(), want);
        assert!(leftovers(&pfx).is_empty());
        // The waits for starved participants are counted, per participant.
        let s = tiltsim_suite::summary(&out);
        for p in s["participants"].as_array().unwrap() {
            assert!(p["starved_waits"].is_u64(), "{p}");
        }
    }
}
