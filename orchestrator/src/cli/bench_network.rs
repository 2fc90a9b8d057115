//! `tiltsim bench SCENARIO --network`: the cost of a participant on another host, against the
//! network's own floor measured the same way.
//!
//! The floor: 256-byte round trips between this process (listening, as a run's orchestrator)
//! and an echo process (connected, as a participant), over the same Zenoh settings and
//! channels as a run's exchanges. The runs: the scenario in one process, and again with the
//! plant (one exchange every tick) served from a `tiltsim participant plant --connect` process
//! over the same kind of link, both masters, `--repeat` alternating rounds. The overhead per
//! tick is the difference of the median walls over the ticks; it is set beside the floor's
//! median round trip.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use cosim::Role;
use tiltsim_master::engine::{self, RunOptions, Status};
use tiltsim_master::scenario::{Master, Scenario, Transport};

use super::bench::BenchArgs;
use super::common::write_json;
use super::error::{CliError, CliResult};

/// `tiltsim bench-net-echo` (hidden): the echo side of `bench --network`.
#[derive(clap::Args, Debug)]
pub struct NetEchoArgs {
    /// Where the bench listens.
    #[arg(long)]
    connect: String,
    /// The bench's key.
    #[arg(long)]
    run: String,
}

/// Runs the echo side.
pub fn echo(a: NetEchoArgs) -> CliResult {
    tiltsim_net::pingpong::echo(&a.connect, &a.run, Duration::from_secs(30))
        .map_err(|e| CliError::Failed(format!("bench-net-echo: {e}")))
}

fn failed(e: impl std::fmt::Display) -> CliError {
    CliError::Failed(format!("bench --network: {e}"))
}

/// Endpoint `listen` with its port moved up by `n` (each run listens on a port of its own).
fn port_plus(listen: &str, n: u16) -> Result<String, CliError> {
    let (host, port) = listen
        .rsplit_once(':')
        .and_then(|(h, p)| p.parse::<u16>().ok().map(|p| (h, p)))
        .filter(|(h, _)| h.starts_with("tcp/"))
        .ok_or_else(|| {
            CliError::Invalid(format!(
                "command line: --listen {listen}: expected tcp/ADDRESS:PORT"
            ))
        })?;
    let p = port.checked_add(n).ok_or_else(|| {
        CliError::Invalid(format!("command line: --listen {listen}: port too high"))
    })?;
    Ok(format!("{host}:{p}"))
}

fn spawn(exe: &Path, args: &[&str], secret: Option<&str>) -> Result<Child, CliError> {
    let mut c = Command::new(exe);
    c.args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    if let Some(s) = secret {
        c.env(tiltsim_net::serve::SECRET_VAR, s);
    }
    c.spawn()
        .map_err(|e| failed(format!("cannot start {}: {e}", exe.display())))
}

/// One run's wall time (s): in one process, or with the plant on the network at `listen`.
fn wall(s: &Scenario, exe: &Path, dir: &Path, listen: Option<&str>) -> Result<f64, CliError> {
    let mut s = s.clone();
    let mut opts = RunOptions::new(dir.to_path_buf(), exe.to_path_buf());
    opts.plots = false;
    let mut child = None;
    if let Some(listen) = listen {
        let secret = tiltsim_net::new_secret().map_err(failed)?;
        s.network.remote = vec![Role::Plant];
        s.network.listen = listen.to_string();
        s.network.join_timeout_s = 30.0;
        opts.network_secret = Some(secret.clone());
        child = Some(spawn(
            exe,
            &[
                "participant",
                "plant",
                "--connect",
                listen,
                "--join-timeout-s",
                "30",
            ],
            Some(&secret),
        )?);
    }
    let sum = engine::run(&s, &s.name, &opts);
    if let Some(mut c) = child {
        // The participant ends when the run stops it; one that did not join is ended here.
        let _ = c.kill();
        let _ = c.wait();
    }
    let _ = std::fs::remove_dir_all(dir);
    let sum = sum.map_err(failed)?;
    if sum.status != Status::Completed {
        return Err(failed(sum.error.unwrap_or_else(|| "run failed".into())));
    }
    Ok(sum.wall_time_s)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the network case.
pub fn network(a: &BenchArgs, base: &Scenario, exe: &Path, listen: &str) -> CliResult {
    let rounds = a.rounds.min(20_000);
    eprintln!("  measuring the network's floor ({rounds} round trips) ...");
    let key = tiltsim_net::new_secret().map_err(failed)?;
    let floor_at = port_plus(listen, 0)?;
    let mut echo = spawn(
        exe,
        &["bench-net-echo", "--connect", &floor_at, "--run", &key],
        None,
    )?;
    let rtts = tiltsim_net::pingpong::measure(&floor_at, &key, rounds, Duration::from_secs(30));
    let _ = echo.wait();
    let mut rtts: Vec<f64> = rtts
        .map_err(failed)?
        .into_iter()
        .map(|n| n as f64)
        .collect();
    let floor = cosim::stats::percentiles(&mut rtts);
    let mut s = base.clone();
    s.run.duration_s = Some(a.duration);
    s.run.transport = Transport::InProcess;
    let ticks = s.steps() as f64;
    let scratch = tiltsim_studies::bench::scratch_dir(&a.out).join("network");
    let mut rows = Vec::new();
    let mut port = 1u16;
    for master in [Master::GaussSeidel, Master::Jacobi] {
        s.run.master = master;
        let (mut local, mut remote) = (Vec::new(), Vec::new());
        for _ in 0..a.repeat {
            eprintln!(
                "  measuring {} in one process and with a remote plant ...",
                master.name()
            );
            local.push(wall(&s, exe, &scratch, None)?);
            let at = port_plus(listen, port)?;
            port += 1;
            remote.push(wall(&s, exe, &scratch, Some(&at))?);
        }
        let (l, r) = (median(local.clone()), median(remote.clone()));
        let per_tick_us = (r - l).max(0.0) / ticks * 1e6;
        rows.push(serde_json::json!({
            "master": master.name(),
            "in_process_wall_s": local,
            "remote_plant_wall_s": remote,
            "overhead_per_tick_us": per_tick_us,
            "overhead_over_floor": per_tick_us / (floor.p50 * 1e-3),
        }));
    }
    let machine = tiltsim_studies::bench::Machine::this();
    println!(
        "network floor ({listen}, Zenoh over TCP, {} B, {rounds} round trips): round trip p50 {:.1} µs, p99 {:.1} µs\n",
        tiltsim_net::pingpong::BYTES,
        floor.p50 * 1e-3,
        floor.p99 * 1e-3
    );
    println!(
        "{}, {:.1} s, {} ticks, plant on the network, the others in one process (medians of {} rounds)\n",
        s.name, a.duration, ticks, a.repeat
    );
    println!("| master | in-process wall (s) | remote plant wall (s) | overhead per tick (µs) | over the floor's round trip |");
    println!("|---|---|---|---|---|");
    for r in &rows {
        println!(
            "| {} | {:.3} | {:.3} | {:.1} | {:.2} |",
            r["master"].as_str().unwrap_or("?"),
            median(serde_json::from_value(r["in_process_wall_s"].clone()).unwrap_or_default()),
            median(serde_json::from_value(r["remote_plant_wall_s"].clone()).unwrap_or_default()),
            r["overhead_per_tick_us"].as_f64().unwrap_or(0.0),
            r["overhead_over_floor"].as_f64().unwrap_or(0.0)
        );
    }
    if let Some(dir) = a.out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    write_json(
        &a.out,
        &serde_json::json!({
            "network": {
                "listen": listen,
                "floor_round_trip_ns": floor,
                "payload_bytes": tiltsim_net::pingpong::BYTES,
                "rounds": rounds,
                "scenario": s.name,
                "duration_s": a.duration,
                "runs": rows,
            },
            "machine": machine,
        }),
    )?;
    println!("wrote {}", a.out.display());
    Ok(())
}
