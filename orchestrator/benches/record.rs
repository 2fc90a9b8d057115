//! Recording benchmark: the cost of one `timeseries.csv` row, the orchestrator's largest share
//! of a tick after the participants' compute. Rows come from a real in-process paper-mpc run
//! (20 000 of them); each round writes them all to a fresh file through
//! [`Recorder`](tiltsim_formats::table::Recorder) and reads them back with
//! [`each_row`](tiltsim_formats::table::each_row). Run with
//! `cargo bench -p orchestrator --bench record`; prints ns per row, median and best of the
//! rounds. Numbers are measured, never asserted.

use std::path::PathBuf;
use std::time::Instant;

use tiltsim_formats::table::{each_row, read_rows, Recorder};
use tiltsim_master::engine::{run, RunOptions};
use tiltsim_scenario::scenario::{Scenario, Transport};

const ROUNDS: usize = 15;

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf();
    let file = root.join("scenarios/paper-mpc.toml");
    let mut s = Scenario::load(&file).expect("scenario");
    s.run.transport = Transport::InProcess;
    let out = std::env::temp_dir().join(format!("tiltsim-bench-record-{}", std::process::id()));
    let mut opts = RunOptions::new(
        out.join("run"),
        PathBuf::from(env!("CARGO_BIN_EXE_tiltsim")),
    );
    opts.plots = false;
    run(&s, &file.display().to_string(), &opts).expect("run");
    let rows = read_rows(&out.join("run")).expect("rows");
    let n = rows.len() as f64;
    let dir = out.join("copy");
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let (mut write_ns, mut read_ns) = (Vec::new(), Vec::new());
    for _ in 0..ROUNDS {
        let t = Instant::now();
        let mut r = Recorder::create(&dir.join("timeseries.csv")).expect("create");
        for row in &rows {
            r.write(row).expect("write");
        }
        r.finish().expect("finish");
        write_ns.push(t.elapsed().as_nanos() as f64 / n);
        let t = Instant::now();
        let back = each_row(&dir, |_| true).expect("read");
        read_ns.push(t.elapsed().as_nanos() as f64 / n);
        assert_eq!(back as usize, rows.len());
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[0])
    };
    let (w, wb) = median(&mut write_ns);
    let (rd, rb) = median(&mut read_ns);
    println!("| rows | write ns/row p50 | best | read ns/row p50 | best |");
    println!("|---|---|---|---|---|");
    println!("| {} | {w:.0} | {wb:.0} | {rd:.0} | {rb:.0} |", rows.len());
    let _ = std::fs::remove_dir_all(out);
}
