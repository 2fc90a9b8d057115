//! `tiltsim bench SCENARIO --network`: the cost of a participant on another host, against the
//! wire's own floor measured on the same path.
//!
//! Floors, each 256-byte round trips between this process (listening, as a run's
//! orchestrator) and an echo process (connected, as a participant), started through
//! `--remote-via` when given: a bare TCP socket (TCP_NODELAY, the wire's floor), then Zenoh
//! with a run's settings (QUIC, mutual TLS 1.3, access control, the low-latency transport) and,
//! to show what each costs, the same with Zenoh's queued transport and Zenoh over plain TCP with
//! each transport. The runs: the scenario in one
//! process, and again with the plant (one exchange every tick) served from a `tiltsim
//! participant plant --connect` process over a run's link, both masters, `--repeat`
//! alternating rounds. The overhead per tick is the difference of the median walls over the
//! ticks, set beside the raw TCP round trip and the Zenoh floor.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use cosim::stats::Percentiles;
use cosim::Role;
use tiltsim_master::engine::{self, RunOptions, Status};
use tiltsim_net::pingpong::Floor;
use tiltsim_net::session::Tuning;
use tiltsim_protocol::address::{Address, ADDRESS_FORM};
use tiltsim_scenario::scenario::{Master, Scenario, Transport};

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
    /// Echo over a bare TCP socket instead of Zenoh.
    #[arg(long)]
    raw_tcp: bool,
    /// Zenoh over plain TCP (no credentials) instead of a run's QUIC link.
    #[arg(long)]
    plain: bool,
    /// Zenoh's low-latency transport.
    #[arg(long)]
    lowlatency: bool,
}

fn address(text: &str, flag: &str) -> Result<Address, CliError> {
    Address::parse(text).map_err(|why| {
        CliError::Invalid(format!(
            "command line: {flag} {text}: {why}; expected {ADDRESS_FORM}"
        ))
    })
}

/// Runs the echo side.
pub fn echo(a: NetEchoArgs) -> CliResult {
    let at = address(&a.connect, "--connect")?;
    let fail = |e: tiltsim_net::NetError| CliError::Failed(format!("bench-net-echo: {e}"));
    if a.raw_tcp {
        return tiltsim_net::pingpong::raw_tcp_echo(&at, Duration::from_secs(30)).map_err(fail);
    }
    let secret = if a.plain {
        None
    } else {
        Some(std::env::var(tiltsim_net::serve::SECRET_VAR).map_err(|_| {
            CliError::Invalid(format!(
                "bench-net-echo: {} is not set",
                tiltsim_net::serve::SECRET_VAR
            ))
        })?)
    };
    let floor = Floor {
        address: at,
        secret,
        tuning: Tuning {
            lowlatency: a.lowlatency,
            ..Tuning::default()
        },
    };
    tiltsim_net::pingpong::echo(&floor, &a.run, Duration::from_secs(30)).map_err(fail)
}

fn failed(e: impl std::fmt::Display) -> CliError {
    CliError::Failed(format!("bench --network: {e}"))
}

/// Ctrl-C (or SIGTERM, SIGHUP) while measuring `what`: exit 130, nothing written.
fn interrupted(what: &str) -> CliError {
    CliError::Interrupted(format!(
        "bench --network: interrupted while measuring {what}; nothing written"
    ))
}

/// A floor's failure, or its stop at Ctrl-C (whatever the measurement saw then: the echo,
/// started through a `--remote-via` command, may have been ended by the same signal).
fn floor_error<'a>(
    what: &'a str,
    stop: &'a AtomicBool,
) -> impl FnOnce(tiltsim_net::NetError) -> CliError + 'a {
    move |e| {
        if stop.load(Ordering::Relaxed) || matches!(e, tiltsim_net::NetError::Stopped) {
            interrupted(what)
        } else {
            failed(e)
        }
    }
}

/// How long an echo that was measured is given to end on its own (it ends at the bench's
/// one-byte goodbye, or when its connection closes).
const ECHO_END: Duration = Duration::from_secs(5);

/// Ends an echo: one measured is given [`ECHO_END`] to end on its own; it is killed then, at
/// once when the measurement failed or was stopped (it would otherwise wait for pings until its
/// idle limit).
fn end_echo(mut echo: Child, measured: bool) {
    if measured {
        let started = std::time::Instant::now();
        while started.elapsed() < ECHO_END {
            if !matches!(echo.try_wait(), Ok(None)) {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    let _ = echo.kill();
    let _ = echo.wait();
}

/// `listen` with its port moved up by `n` (each measurement listens on a port of its own).
fn port_plus(listen: &Address, n: u16) -> Result<Address, CliError> {
    let port = listen.port.checked_add(n).ok_or_else(|| {
        CliError::Invalid(format!(
            "command line: --listen {listen}: port too high for the bench's {n} ports above it"
        ))
    })?;
    Ok(Address {
        port,
        ..listen.clone()
    })
}

/// Starts `exe args` here, or through the `--remote-via` command.
struct Spawner<'a> {
    exe: &'a Path,
    via: Vec<String>,
    /// Set by Ctrl-C: every measurement ends at it.
    stop: Arc<AtomicBool>,
}

impl Spawner<'_> {
    fn spawn(&self, args: &[&str], secret: Option<&str>) -> Result<Child, CliError> {
        let mut c = match self.via.split_first() {
            Some((first, rest)) => {
                let mut c = Command::new(first);
                c.args(rest).arg(self.exe);
                c
            }
            None => Command::new(self.exe),
        };
        // A process group of its own: a terminal's Ctrl-C reaches the bench, which ends it.
        std::os::unix::process::CommandExt::process_group(&mut c, 0);
        c.args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        if let Some(s) = secret {
            c.env(tiltsim_net::serve::SECRET_VAR, s);
        }
        c.spawn()
            .map_err(|e| failed(format!("cannot start {}: {e}", self.exe.display())))
    }
}

/// One run's wall time (s): in one process, or with the plant on the network at `listen`.
fn wall(
    s: &Scenario,
    sp: &Spawner<'_>,
    dir: &Path,
    listen: Option<&Address>,
) -> Result<f64, CliError> {
    let mut s = s.clone();
    let mut opts = RunOptions::new(dir.to_path_buf(), sp.exe.to_path_buf());
    opts.plots = false;
    opts.interrupt = sp.stop.clone();
    let mut child = None;
    if let Some(listen) = listen {
        let secret = tiltsim_net::new_secret().map_err(failed)?;
        s.network.remote = vec![Role::Plant];
        s.network.listen = listen.to_string();
        s.network.join_timeout_s = 30.0;
        opts.network_secret = Some(secret.clone());
        let at = listen.to_string();
        child = Some(sp.spawn(
            &[
                "participant",
                "plant",
                "--connect",
                &at,
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
    let what = if listen.is_some() {
        "a run with a remote plant"
    } else {
        "a run in one process"
    };
    if sp.stop.load(Ordering::Relaxed) {
        return Err(interrupted(what));
    }
    let sum = sum.map_err(failed)?;
    if sum.status != Status::Completed {
        return Err(failed(sum.error.unwrap_or_else(|| "run failed".into())));
    }
    Ok(sum.wall_time_s)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// One floor: how it was measured and its round trips.
struct FloorRow {
    name: &'static str,
    words: &'static str,
    rtt: Percentiles,
}

fn percentiles(v: Vec<u64>) -> Percentiles {
    let mut v: Vec<f64> = v.into_iter().map(|n| n as f64).collect();
    cosim::stats::percentiles(&mut v)
}

/// The raw TCP floor at `at`.
fn raw_floor(sp: &Spawner<'_>, at: &Address, rounds: usize) -> Result<Percentiles, CliError> {
    let target = at.to_string();
    let mut echo = None;
    let startup = Duration::from_secs(30);
    let rtts = tiltsim_net::pingpong::raw_tcp_measure(at, rounds, startup, &sp.stop, || {
        echo = Some(
            sp.spawn(
                &[
                    "bench-net-echo",
                    "--connect",
                    &target,
                    "--run",
                    "raw",
                    "--raw-tcp",
                ],
                None,
            )
            .map_err(|e| tiltsim_net::NetError::Participant(e.to_string()))?,
        );
        Ok(())
    });
    if let Some(e) = echo {
        end_echo(e, rtts.is_ok());
    }
    let rtts = rtts.map_err(floor_error("the raw TCP floor", &sp.stop))?;
    Ok(percentiles(rtts))
}

/// A Zenoh floor at `at`: QUIC with a run's credentials unless `plain`.
fn zenoh_floor(
    sp: &Spawner<'_>,
    at: &Address,
    rounds: usize,
    plain: bool,
    lowlatency: bool,
) -> Result<Percentiles, CliError> {
    let key = tiltsim_net::new_secret().map_err(failed)?;
    let secret = (!plain)
        .then(tiltsim_net::new_secret)
        .transpose()
        .map_err(failed)?;
    let target = at.to_string();
    let mut args = vec!["bench-net-echo", "--connect", &target, "--run", &key];
    if plain {
        args.push("--plain");
    }
    if lowlatency {
        args.push("--lowlatency");
    }
    let echo = sp.spawn(&args, secret.as_deref())?;
    let floor = Floor {
        address: at.clone(),
        secret,
        tuning: Tuning {
            lowlatency,
            ..Tuning::default()
        },
    };
    let rtts =
        tiltsim_net::pingpong::measure(&floor, &key, rounds, Duration::from_secs(30), &sp.stop);
    end_echo(echo, rtts.is_ok());
    let rtts = rtts.map_err(floor_error("a Zenoh floor", &sp.stop))?;
    Ok(percentiles(rtts))
}

/// The floors, in the order they are printed: the wire's, then Zenoh's variants.
fn floors(sp: &Spawner<'_>, listen: &Address, rounds: usize) -> Result<Vec<FloorRow>, CliError> {
    let mut rows = vec![FloorRow {
        name: "raw-tcp",
        words: "bare TCP socket, TCP_NODELAY",
        rtt: raw_floor(sp, &port_plus(listen, 0)?, rounds)?,
    }];
    // A run's link first: its floor is the one the per-tick overhead is set beside.
    let variants: [(&str, &str, bool, bool); 4] = [
        (
            "zenoh-quic-lowlatency",
            "Zenoh over QUIC, mutual TLS 1.3 and access control, low-latency transport (a run's link)",
            false,
            true,
        ),
        (
            "zenoh-quic",
            "the same, Zenoh's queued transport",
            false,
            false,
        ),
        (
            "zenoh-tcp-lowlatency",
            "Zenoh over plain TCP, no credentials, low-latency transport",
            true,
            true,
        ),
        (
            "zenoh-tcp",
            "Zenoh over plain TCP, queued transport",
            true,
            false,
        ),
    ];
    debug_assert_eq!(variants[0].3, Tuning::default().lowlatency);
    for (i, (name, words, plain, lowlatency)) in variants.into_iter().enumerate() {
        eprintln!("  measuring the floor: {words} ...");
        let at = port_plus(listen, 1 + i as u16)?;
        rows.push(FloorRow {
            name,
            words,
            rtt: zenoh_floor(sp, &at, rounds, plain, lowlatency)?,
        });
    }
    Ok(rows)
}

/// Runs the network case.
pub fn network(a: &BenchArgs, base: &Scenario, exe: &Path, listen: &str) -> CliResult {
    let listen = address(listen, "--listen")?;
    let sp = Spawner {
        exe,
        via: a
            .remote_via
            .as_deref()
            .map(|v| v.split_whitespace().map(String::from).collect())
            .unwrap_or_default(),
        // Ctrl-C ends the measurement under way and its echo or participant; nothing is
        // written.
        stop: tiltsim_rundir::signals::install(),
    };
    let rounds = a.rounds.min(20_000);
    eprintln!("  measuring the raw TCP floor ({rounds} round trips) ...");
    let floors = floors(&sp, &listen, rounds)?;
    let raw = floors[0].rtt;
    let run_floor = floors[1].rtt;
    let mut s = base.clone();
    s.run.duration_s = Some(a.duration);
    s.run.transport = Transport::InProcess;
    let ticks = s.steps() as f64;
    let scratch = tiltsim_studies::bench::scratch_dir(&a.out).join("network");
    let mut rows = Vec::new();
    let mut port = 8u16;
    for master in [Master::GaussSeidel, Master::Jacobi] {
        s.run.master = master;
        let (mut local, mut remote) = (Vec::new(), Vec::new());
        for _ in 0..a.repeat {
            eprintln!(
                "  measuring {} in one process and with a remote plant ...",
                master.name()
            );
            local.push(wall(&s, &sp, &scratch, None)?);
            let at = port_plus(&listen, port)?;
            port += 1;
            remote.push(wall(&s, &sp, &scratch, Some(&at))?);
        }
        let (l, r) = (median(local.clone()), median(remote.clone()));
        let per_tick_us = (r - l).max(0.0) / ticks * 1e6;
        rows.push(serde_json::json!({
            "master": master.name(),
            "in_process_wall_s": local,
            "remote_plant_wall_s": remote,
            "overhead_per_tick_us": per_tick_us,
            "overhead_over_raw_tcp": per_tick_us / (raw.p50 * 1e-3),
            "overhead_over_floor": per_tick_us / (run_floor.p50 * 1e-3),
        }));
    }
    print_report(&listen, &floors, &s, a, ticks, &rows);
    if let Some(dir) = a.out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    let floor_json: Vec<serde_json::Value> = floors
        .iter()
        .map(|f| {
            serde_json::json!({
                "name": f.name,
                "what": f.words,
                "round_trip_ns": f.rtt,
                "p50_over_raw_tcp": f.rtt.p50 / raw.p50,
                "p99_over_raw_tcp": f.rtt.p99 / raw.p99,
            })
        })
        .collect();
    write_json(
        &a.out,
        &serde_json::json!({
            "network": {
                "listen": listen.to_string(),
                "remote_via": a.remote_via,
                "floors": floor_json,
                "raw_tcp_round_trip_ns": raw,
                "floor_round_trip_ns": run_floor,
                "payload_bytes": tiltsim_net::pingpong::BYTES,
                "rounds": rounds,
                "scenario": s.name,
                "duration_s": a.duration,
                "runs": rows,
            },
            "machine": tiltsim_studies::bench::Machine::this(),
        }),
    )?;
    println!("wrote {}", a.out.display());
    Ok(())
}

fn print_report(
    listen: &Address,
    floors: &[FloorRow],
    s: &Scenario,
    a: &BenchArgs,
    ticks: f64,
    rows: &[serde_json::Value],
) {
    let raw = &floors[0].rtt;
    println!(
        "round trips of {} B at {listen} ({} each):\n",
        tiltsim_net::pingpong::BYTES,
        a.rounds.min(20_000)
    );
    println!("| floor | p50 (µs) | p99 (µs) | p50 over raw TCP | p99 over raw TCP |");
    println!("|---|---|---|---|---|");
    for f in floors {
        println!(
            "| {} ({}) | {:.1} | {:.1} | {:.2} | {:.2} |",
            f.name,
            f.words,
            f.rtt.p50 * 1e-3,
            f.rtt.p99 * 1e-3,
            f.rtt.p50 / raw.p50,
            f.rtt.p99 / raw.p99
        );
    }
    println!(
        "\n{}, {:.1} s, {} ticks, plant on the network (a run's QUIC link), the others in one process (medians of {} rounds)\n",
        s.name, a.duration, ticks, a.repeat
    );
    println!("| master | in-process wall (s) | remote plant wall (s) | overhead per tick (µs) | over raw TCP | over the Zenoh floor |");
    println!("|---|---|---|---|---|---|");
    for r in rows {
        let walls = |k: &str| median(serde_json::from_value(r[k].clone()).unwrap_or_default());
        println!(
            "| {} | {:.3} | {:.3} | {:.1} | {:.2} | {:.2} |",
            r["master"].as_str().unwrap_or("?"),
            walls("in_process_wall_s"),
            walls("remote_plant_wall_s"),
            r["overhead_per_tick_us"].as_f64().unwrap_or(0.0),
            r["overhead_over_raw_tcp"].as_f64().unwrap_or(0.0),
            r["overhead_over_floor"].as_f64().unwrap_or(0.0)
        );
    }
}
