//! Test-only participant: the real plant, served by the real transport, that misbehaves on
//! purpose at one step. Used by `tests/faults/faults.rs` through `tiltsim run --participant-exe
//! plant=PATH`. `TILTSIM_FAULT=MODE@STEP` (inherited from the test) chooses:
//! `nan` (NaN lateral acceleration in the reply), `version` (wrong protocol version),
//! `size` (wrong sample size), `skip` (reply carries the next step's index), `hang` (never
//! answers again), `panic` (crashes with a panic). `TILTSIM_STDERR_BYTES=N` makes it write
//! N bytes of text to its standard error before it connects, the last line
//! `faulty plant: wrote N bytes`.

use std::io::Write as _;
use std::time::Duration;

use cosim::msg::FromPlant;
use plant_proc::{Plant, PlantSettings};

fn main() {
    if let Some(n) = std::env::var("TILTSIM_STDERR_BYTES")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
    {
        chatter(n);
    }
    let args: Vec<String> = std::env::args().collect();
    // Same command line as `tiltsim participant plant ...`.
    let rest = args.get(3..).unwrap_or_default().to_vec();
    let spec = std::env::var("TILTSIM_FAULT").unwrap_or_default();
    let (mode, at) = spec.split_once('@').unwrap_or(("none", "0"));
    let mode = mode.to_string();
    let at: u64 = at.parse().unwrap_or(0);
    let hook = move |out: &mut FromPlant| {
        if out.header.kind != cosim::Kind::Step as u32 || out.header.step != at {
            return;
        }
        match mode.as_str() {
            "nan" => out.lat_acc = f64::NAN,
            "version" => out.header.version = 99,
            "size" => out.header.size = 8,
            "skip" => out.header.step += 1,
            "hang" => std::thread::sleep(Duration::from_secs(3600)),
            "panic" => panic!("faulty plant: deliberate crash at step {at}"),
            _ => {}
        }
    };
    let r = cosim::ipc::participant_main_with(&rest, |s: PlantSettings| Ok(Plant::new(&s)), hook);
    if let Err(e) = r {
        eprintln!("{e}");
        std::process::exit(1);
    }
}

/// Writes `n` bytes of text to standard error (at least its last line), in one locked stream.
fn chatter(n: usize) {
    let last = format!("faulty plant: wrote {n} bytes\n");
    let line = "faulty plant: a line of chatter on standard error\n";
    let mut err = std::io::stderr().lock();
    let mut left = n.saturating_sub(last.len());
    while left > 0 {
        let part = &line.as_bytes()[line.len() - left.min(line.len())..];
        let _ = err.write_all(part);
        left -= part.len();
    }
    let _ = err.write_all(last.as_bytes());
    let _ = err.flush();
}
