//! Lock-step coordination benchmark: per-tick overhead and CPU cost of each transport, master
//! algorithm and wait strategy on the paper's passive scenario (16 800 ticks, three
//! participants). Run with `cargo bench -p orchestrator --bench lockstep`; writes a table to
//! stdout. Numbers are measured, never asserted.

use std::path::PathBuf;

use cosim::wait::WaitStrategy;
use tiltsim_master::engine::{run, RunOptions};
use tiltsim_scenario::scenario::{Master, Scenario, Transport};

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf();
    let file = root.join("scenarios/paper-passive.toml");
    let base = Scenario::load(&file).expect("scenario");
    let out = std::env::temp_dir().join(format!("tiltsim-bench-{}", std::process::id()));
    println!("| transport | master | wait | tick p50 (us) | overhead p50 (us) | p99 (us) | max (us) | wall (s) | CPU orch (s) | CPU participants (s) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut cases = vec![(
        Transport::InProcess,
        Master::GaussSeidel,
        WaitStrategy::Adaptive,
    )];
    for master in [Master::GaussSeidel, Master::Jacobi] {
        for wait in [WaitStrategy::Adaptive, WaitStrategy::Sleep] {
            cases.push((Transport::Ipc, master, wait));
        }
    }
    for (transport, master, wait) in cases {
        let mut s = base.clone();
        s.run.transport = transport;
        s.run.master = master;
        s.run.wait = wait;
        let opts = RunOptions::new(out.clone(), PathBuf::from(env!("CARGO_BIN_EXE_tiltsim")));
        let r = run(&s, &file.display().to_string(), &opts).expect("run");
        println!(
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.1} | {:.3} | {:.2} | {:.2} |",
            r.transport.name(),
            r.master_algorithm.name(),
            r.wait_strategy.name(),
            r.timing.tick_us.p50,
            r.timing.p50,
            r.timing.p99,
            r.timing.max,
            r.wall_time_s,
            r.timing.cpu_s.orchestrator,
            r.timing.cpu_s.participants
        );
    }
    let _ = std::fs::remove_dir_all(out);
}
