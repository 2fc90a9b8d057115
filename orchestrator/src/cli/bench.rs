//! `tiltsim bench`: measure this machine's coordination overhead and transport floor.

use std::path::PathBuf;

use cosim::ipc::pingpong::Waiting;

use super::bounds::{self, End};
use super::common::{load, write_json};
use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Scenario to run in every configuration.
    #[arg(default_value = "scenarios/paper-passive.toml")]
    scenario: PathBuf,
    /// Simulated seconds per configuration.
    #[arg(long, default_value_t = 2.0,
          value_parser = bounds::real((0.01, End::Closed), (600.0, End::Closed), " s"))]
    pub(super) duration: f64,
    /// Rounds of the three runs the wall-time ratios compare (in-process, IPC Gauss-Seidel, IPC
    /// Jacobi), run one after the other; the ratios are those of the median walls.
    #[arg(long, default_value_t = 3, value_parser = bounds::int(1..=100usize, ""))]
    pub(super) repeat: usize,
    /// JSON report.
    #[arg(long, default_value = "out/bench.json")]
    pub(super) out: PathBuf,
    /// Measure only the transport's floor as iceoryx2's own benchmark does: two processes on
    /// their own CPUs, busy-waiting, one-way latency for 64 B to 4 KB.
    #[arg(long)]
    ping_pong: bool,
    /// With --ping-pong: both processes on one CPU, yielding it while they wait. The one-way
    /// latency is then the cost of handing the CPU from one process to the other.
    #[arg(long, requires = "ping_pong")]
    same_cpu: bool,
    /// Round trips per size with --ping-pong.
    #[arg(long, default_value_t = 100_000, value_parser = bounds::int(100..=10_000_000usize, ""))]
    pub(super) rounds: usize,
    /// Measure each participant as its exported FMU (FMI 3.0, its own process) against the
    /// native participant: wall time per tick, medians of --fmu-runs alternating runs.
    #[arg(long)]
    fmu: bool,
    /// Measure a participant on another host: the network's round-trip floor, then the
    /// scenario with its plant served over the network against in one process, both masters
    /// (docs/network.md).
    #[arg(long, conflicts_with_all = ["ping_pong", "fmu"])]
    pub(super) network: bool,
    /// With --network: where the bench listens, HOST:PORT (each measurement on the next
    /// port up).
    #[arg(long, default_value = "127.0.0.1:17447", requires = "network")]
    pub(super) listen: String,
    /// With --network: start the echo and the remote participant through this command, e.g.
    /// "ip netns exec hostb" or "ssh hostb" (split at spaces; the tiltsim executable must be at
    /// the same path there), so that they run on another host or namespace.
    #[arg(long, value_name = "COMMAND", requires = "network")]
    pub(super) remote_via: Option<String>,
    /// Start this many IPC runs of the scenario at once, for each count given (for example
    /// 1,2,4,16): wall time per run and in total, the placements the runs chose and the load
    /// (docs/performance.md, "Many runs on one machine").
    #[arg(long, value_delimiter = ',', num_args = 1..,
          value_parser = bounds::int(1..=256usize, ""),
          conflicts_with_all = ["ping_pong", "fmu", "network"])]
    concurrent: Vec<usize>,
    /// CPU hogs (spinning threads) beside the runs: one count for the configurations (the
    /// floors are measured after the hogs stop), or with --concurrent each count given.
    #[arg(long, value_delimiter = ',', num_args = 1.., default_value = "0",
          value_parser = bounds::int(0..=64usize, ""),
          conflicts_with_all = ["ping_pong", "fmu", "network"])]
    hogs: Vec<usize>,
    /// Also measure the IPC runs under SCHED_FIFO (`tiltsim run --realtime`) beside the
    /// others (with --concurrent: the runs under it, to compare with rows without it).
    #[arg(long, conflicts_with_all = ["ping_pong", "fmu", "network"])]
    realtime: bool,
    /// Runs of each with --fmu.
    #[arg(long, default_value_t = 5, value_parser = bounds::int(1..=100usize, ""))]
    fmu_runs: usize,
}

/// `tiltsim bench-echo` (hidden): the echo side of `bench --ping-pong`.
#[derive(clap::Args, Debug)]
pub struct EchoArgs {
    /// The run's iceoryx2 prefix.
    #[arg(long)]
    prefix: String,
    /// CPU to pin to.
    #[arg(long, value_parser = bounds::int(0..=4095usize, ""))]
    cpu: Option<usize>,
    /// Yield between polls instead of spinning (`bench --ping-pong --same-cpu`).
    #[arg(long = "yield")]
    yielding: bool,
    /// Answer as participant INDEX of the exchange floor's pattern instead.
    #[arg(long, value_parser = bounds::int(0..=15usize, ""))]
    pattern: Option<usize>,
}

/// Runs the echo side.
pub fn echo(a: EchoArgs) -> CliResult {
    if let Some(c) = a.cpu {
        cosim::ipc::pin_to_cpu(c);
    }
    if let Some(index) = a.pattern {
        cosim::wait::tight_timer_slack();
        return cosim::ipc::pattern::echo(&a.prefix, index)
            .map_err(|e| CliError::Failed(format!("bench-echo: {e}")));
    }
    let w = if a.yielding {
        Waiting::Yield
    } else {
        Waiting::Spin
    };
    cosim::ipc::pingpong::echo(&a.prefix, w)
        .map_err(|e| CliError::Failed(format!("bench-echo: {e}")))
}

/// One-way latencies (ns) per size of `rounds` ping-pong round trips: the echo process on the
/// last CPU and this one on the first, busy-waiting; with `same_cpu` both on the first,
/// yielding.
fn ping_pong_latencies(
    exe: &std::path::Path,
    rounds: usize,
    same_cpu: bool,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Vec<Vec<f64>>, CliError> {
    let cpus = cosim::ipc::allowed_cpus();
    let prefix = cosim::ipc::unique_prefix();
    let mut cmd = std::process::Command::new(exe);
    cmd.args(["bench-echo", "--prefix", &prefix]);
    let w = if same_cpu {
        cmd.arg("--yield");
        Waiting::Yield
    } else {
        Waiting::Spin
    };
    if let (Some(first), Some(last)) = (cpus.first(), cpus.last()) {
        let echo_cpu = if same_cpu { first } else { last };
        if first != last || same_cpu {
            cmd.args(["--cpu", &echo_cpu.to_string()]);
            cosim::ipc::pin_to_cpu(*first);
        }
    }
    let mut child = cmd
        .spawn()
        .map_err(|e| CliError::Failed(format!("bench: cannot start the echo process: {e}")))?;
    let result = cosim::ipc::pingpong::measure(&prefix, rounds, w, stop);
    if result.is_err() {
        let _ = child.kill();
    }
    let _ = child.wait();
    cosim::ipc::set_cpus(&cpus);
    cosim::ipc::remove_run_files(&prefix);
    result.map_err(|e| match e {
        cosim::ipc::IpcError::Stopped => CliError::Interrupted(
            "bench: interrupted while measuring the ping-pong floor; nothing written".into(),
        ),
        e => CliError::Failed(format!("bench: {e}")),
    })
}

/// The wall time (ns) of each of `ticks` ticks of iceoryx2 exchanges alone in `order`, one echo
/// process per entry of `every` (asked every that many ticks), placed as an adaptive IPC run
/// with a pair of CPUs places its processes: this one on the first allowed CPU, the echoes
/// together on the second, the pair an unclaimed machine gives the first run
/// (`cosim::ipc::pattern`, `cosim::ipc::placement`).
/// Ctrl-C (`stop`) ends it with its echoes at once.
pub(super) fn exchange_floor(
    exe: &std::path::Path,
    every: &[u64],
    order: cosim::ipc::pattern::Order,
    ticks: usize,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Vec<f64>, CliError> {
    let cpus = cosim::ipc::allowed_cpus();
    let prefix = cosim::ipc::unique_prefix();
    let pinned = match cpus.as_slice() {
        [first, second, ..] => Some((*first, *second)),
        _ => None,
    };
    let mut children = Vec::new();
    let mut spawned = Ok(());
    for i in 0..every.len() {
        let mut cmd = std::process::Command::new(exe);
        cmd.args([
            "bench-echo",
            "--prefix",
            &prefix,
            "--pattern",
            &i.to_string(),
        ]);
        if let Some((_, theirs)) = pinned {
            cmd.args(["--cpu", &theirs.to_string()]);
        }
        match cmd.spawn() {
            Ok(c) => children.push(c),
            Err(e) => {
                spawned = Err(CliError::Failed(format!(
                    "bench: cannot start an echo process: {e}"
                )));
                break;
            }
        }
    }
    let result = spawned.and_then(|()| {
        if let Some((own, _)) = pinned {
            cosim::ipc::pin_to_cpu(own);
        }
        // A stop counts as an interruption whatever iceoryx2 saw at that moment (a service
        // being opened reports the signal as its own error).
        cosim::ipc::pattern::measure(&prefix, every, order, ticks, stop).map_err(|e| {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                CliError::Interrupted(
                    "bench: interrupted while measuring iceoryx2's floor; nothing written".into(),
                )
            } else {
                CliError::Failed(format!("bench: {e}"))
            }
        })
    });
    // An echo that answered the end leaves at once; one that did not is killed after a while
    // (it would otherwise wait for this process to go), at once if the measurement failed.
    let started = std::time::Instant::now();
    let grace = if result.is_ok() {
        ECHO_EXIT
    } else {
        std::time::Duration::ZERO
    };
    for mut c in children {
        loop {
            match c.try_wait() {
                Ok(None) if started.elapsed() < grace => {
                    std::thread::sleep(std::time::Duration::from_millis(5));
                }
                Ok(None) => {
                    let _ = c.kill();
                    let _ = c.wait();
                    break;
                }
                _ => break,
            }
        }
    }
    cosim::ipc::set_cpus(&cpus);
    cosim::ipc::remove_run_files(&prefix);
    result
}

/// How long the echo processes of the exchange floor have to leave after the measurement.
const ECHO_EXIT: std::time::Duration = std::time::Duration::from_secs(5);

/// `--ping-pong`: the echo process on the last CPU, this one on the first (`--same-cpu`: both
/// on the first).
fn ping_pong(a: &BenchArgs, exe: &std::path::Path) -> CliResult {
    if !(100..=10_000_000).contains(&a.rounds) {
        return Err(CliError::Invalid(format!(
            "command line: --rounds {}: allowed 100 to 10000000",
            a.rounds
        )));
    }
    // Ctrl-C ends the measurement, the echo process and its files.
    let stop = tiltsim_rundir::signals::install();
    let lat = ping_pong_latencies(exe, a.rounds, a.same_cpu, &stop)?;
    let machine = tiltsim_studies::bench::Machine::this();
    let placement = if a.same_cpu {
        "both processes on one CPU, yielding it while they wait"
    } else {
        "two processes on their own CPUs, busy-waiting"
    };
    println!(
        "iceoryx2 ping-pong, {placement}, {} round trips per size\nmachine: {}, {} logical CPUs, Linux {}\n\n| payload (B) | one-way p50 (ns) | p99 (ns) | max (ns) |\n|---|---|---|---|",
        a.rounds, machine.cpu_model, machine.logical_cpus, machine.kernel
    );
    let mut sizes = Vec::new();
    for (bytes, mut v) in cosim::ipc::pingpong::SIZES.into_iter().zip(lat) {
        let p = cosim::stats::percentiles(&mut v);
        println!("| {bytes} | {:.0} | {:.0} | {:.0} |", p.p50, p.p99, p.max);
        sizes.push(serde_json::json!({
            "payload_bytes": bytes,
            "one_way_ns": p,
        }));
    }
    if let Some(dir) = a.out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    write_json(
        &a.out,
        &serde_json::json!({
            "ping_pong": sizes,
            "rounds": a.rounds,
            "same_cpu": a.same_cpu,
            "machine": machine,
        }),
    )?;
    println!("wrote {}", a.out.display());
    Ok(())
}

/// The machine's floors beside a scenario's figures: one-way p50 of a sample the size of
/// tiltsim's (256 B), 20 000 round trips each, across CPUs busy-waiting and on one CPU yielding.
fn machine_floors(
    exe: &std::path::Path,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<tiltsim_studies::bench::MachineFloors, CliError> {
    const ROUNDS: usize = 20_000;
    let size = cosim::ipc::pingpong::SIZES
        .iter()
        .position(|&b| b == 256)
        .expect("256 B is a ping-pong size");
    let p50_us = |same_cpu| -> Result<f64, CliError> {
        let mut v = ping_pong_latencies(exe, ROUNDS, same_cpu, stop)?.swap_remove(size);
        Ok(cosim::stats::percentiles(&mut v).p50 * 1e-3)
    };
    Ok(tiltsim_studies::bench::MachineFloors {
        payload_bytes: 256,
        one_way_cross_cpu_us: p50_us(false)?,
        one_way_same_cpu_us: p50_us(true)?,
    })
}

/// iceoryx2's floor for `s`'s ticks under both masters: the plant and the actuator asked every
/// tick, the controller every period; [`EXCHANGE_SETS`] sets of fresh processes of
/// [`EXCHANGE_TICKS`] ticks each per master, alternating. Fresh processes because the order
/// in which the kernel cycles processes that yield one CPU is set when they start and holds
/// for their life, and a tick's cost depends on it (docs/performance.md, "The exchange
/// against iceoryx2's floor").
fn exchange_floors(
    exe: &std::path::Path,
    s: &tiltsim_scenario::scenario::Scenario,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<tiltsim_studies::bench::ExchangeFloors, CliError> {
    use cosim::ipc::pattern::Order;
    let every = vec![1, 1, s.controller_period_ticks()];
    let mut sets = [Vec::new(), Vec::new()];
    for _ in 0..EXCHANGE_SETS {
        for (i, order) in [Order::InTurn, Order::AllAtOnce].into_iter().enumerate() {
            let mut v: Vec<f64> = exchange_floor(exe, &every, order, EXCHANGE_TICKS, stop)?
                .into_iter()
                .map(|ns| ns * 1e-3)
                .collect();
            sets[i].push(cosim::stats::percentiles(&mut v));
        }
    }
    let [in_turn_sets_us, all_at_once_sets_us] = sets;
    Ok(tiltsim_studies::bench::ExchangeFloors {
        in_turn_sets_us,
        all_at_once_sets_us,
        every,
        ticks: EXCHANGE_TICKS,
        sets_per_round: EXCHANGE_SETS,
    })
}

/// Sets of processes per master for the exchange floor, after each round.
const EXCHANGE_SETS: usize = 4;

/// Ticks of each set.
const EXCHANGE_TICKS: usize = 5_000;

/// The exchange floor after a round of the bench's runs, with its hogs stopped meanwhile
/// (`hogs` restarted after): the floor is iceoryx2's with nothing else on the machine.
fn round_floor(
    exe: &std::path::Path,
    s: &tiltsim_scenario::scenario::Scenario,
    hogs: &mut Option<super::bench_concurrent::Hogs>,
    count: usize,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<tiltsim_studies::bench::ExchangeFloors, tiltsim_studies::bench::BenchError> {
    use tiltsim_studies::bench::BenchError;
    let config = "iceoryx2's floor for the scenario's ticks".to_string();
    let interrupted = || BenchError::Interrupted {
        config: config.clone(),
    };
    let failed = |e: CliError| match e {
        CliError::Interrupted(_) => interrupted(),
        CliError::Failed(why) | CliError::Invalid(why) | CliError::Participant(why) => {
            BenchError::Run {
                config: config.clone(),
                why: why.trim_start_matches("bench: ").to_string(),
            }
        }
        e => BenchError::Run {
            config: config.clone(),
            why: e.to_string(),
        },
    };
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        return Err(interrupted());
    }
    *hogs = None;
    let floors = exchange_floors(exe, s, stop).map_err(failed)?;
    // Ctrl-C while the last set's echoes were leaving: the floor is what it interrupted.
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        return Err(interrupted());
    }
    *hogs = Some(super::bench_concurrent::Hogs::start(count).map_err(failed)?);
    Ok(floors)
}

/// A bench's failure: exit 130 for Ctrl-C, 1 otherwise.
fn bench_error(e: tiltsim_studies::bench::BenchError) -> CliError {
    match e {
        tiltsim_studies::bench::BenchError::Interrupted { .. } => {
            CliError::Interrupted(format!("bench: {e}"))
        }
        e => CliError::Failed(format!("bench: {e}")),
    }
}

/// The one count of hogs the configurations run beside (several only with --concurrent).
fn single_hog_count(hogs: &[usize]) -> Result<usize, CliError> {
    match hogs {
        [] => Ok(0),
        [n] => Ok(*n),
        _ => Err(CliError::Invalid(format!(
            "command line: --hogs {}: one count without --concurrent",
            hogs.iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(",")
        ))),
    }
}

/// Unpaced real-time runs poll for as long as they last: only the kernel's real-time
/// throttling keeps a share of each CPU for everything else (as `tiltsim run --realtime`).
fn check_realtime(a: &BenchArgs) -> Result<(), CliError> {
    if !a.realtime {
        return Ok(());
    }
    let refused = |e: String| CliError::Invalid(format!("command line: --realtime: {e}"));
    cosim::realtime::throttled().map_err(refused)?;
    // Asked now, so that a refusal comes before the runs without it, not after them.
    cosim::realtime::enter(cosim::realtime::PRIORITY).map_err(refused)?;
    cosim::realtime::leave();
    cosim::realtime::unlock_memory();
    Ok(())
}

/// Runs the command.
pub fn exec(a: BenchArgs) -> CliResult {
    let exe = std::env::current_exe().map_err(|_| {
        CliError::Failed("cannot find the tiltsim executable to start participants".into())
    })?;
    if a.ping_pong {
        return ping_pong(&a, &exe);
    }
    let s = load(&a.scenario)?;
    let d = a.duration;
    if !(d.is_finite() && d > 0.0 && d <= 600.0) {
        return Err(CliError::Invalid(format!(
            "command line: --duration {d}: allowed (0, 600] s"
        )));
    }
    if a.network {
        return super::bench_network::network(&a, &s, &exe, &a.listen);
    }
    check_realtime(&a)?;
    if !a.concurrent.is_empty() {
        let how = super::bench_concurrent::Runs {
            exe: &exe,
            scenario: &a.scenario,
            duration: d,
            realtime: a.realtime,
        };
        return super::bench_concurrent::concurrent(how, &s.name, &a.concurrent, &a.hogs, &a.out);
    }
    let scratch = tiltsim_studies::bench::scratch_dir(&a.out);
    if a.fmu {
        if !(1..=100).contains(&a.fmu_runs) {
            return Err(CliError::Invalid(format!(
                "command line: --fmu-runs {}: allowed 1 to 100",
                a.fmu_runs
            )));
        }
        let interrupt = tiltsim_rundir::signals::install();
        let rows = tiltsim_studies::bench_fmu::fmu(
            &s,
            d,
            a.fmu_runs,
            &exe,
            &scratch,
            &interrupt,
            |name| eprintln!("  measuring {name} ..."),
        );
        let _ = std::fs::remove_dir_all(&scratch);
        let rows = rows.map_err(bench_error)?;
        println!(
            "{}",
            tiltsim_studies::bench_fmu::fmu_table(&s.name, s.run.transport.name(), &rows)
        );
        if let Some(dir) = a.out.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        let machine = tiltsim_studies::bench::Machine::this();
        write_json(
            &a.out,
            &serde_json::json!({ "fmu": rows, "scenario": s.name, "duration_s": d, "machine": machine }),
        )?;
        println!("wrote {}", a.out.display());
        return Ok(());
    }
    main_table(&a, &s, &exe, &scratch)
}

/// The main table: every configuration of `s`, the rounds the ratios compare each followed by
/// iceoryx2's floor for the scenario's ticks, then the machine's floors.
fn main_table(
    a: &BenchArgs,
    s: &tiltsim_scenario::scenario::Scenario,
    exe: &std::path::Path,
    scratch: &std::path::Path,
) -> CliResult {
    let d = a.duration;
    if !(1..=100).contains(&a.repeat) {
        return Err(CliError::Invalid(format!(
            "command line: --repeat {}: allowed 1 to 100",
            a.repeat
        )));
    }
    // Ctrl-C ends the run under way (as interrupted) and starts no other.
    let setup = tiltsim_studies::bench::Setup {
        rounds: a.repeat,
        realtime: a.realtime,
        hogs: single_hog_count(&a.hogs)?,
        interrupt: tiltsim_rundir::signals::install(),
    };
    let mut hogs = Some(super::bench_concurrent::Hogs::start(setup.hogs)?);
    let floors = |round: usize| {
        eprintln!(
            "  measuring iceoryx2's floor for the scenario's ticks, round {} ...",
            round + 1
        );
        round_floor(exe, s, &mut hogs, setup.hogs, &setup.interrupt)
    };
    let report = tiltsim_studies::bench::run(s, d, &setup, exe, scratch, floors, |name| {
        eprintln!("  measuring {name} ...");
    });
    drop(hogs);
    let _ = std::fs::remove_dir_all(scratch);
    let mut report = report.map_err(bench_error)?;
    // The floors' processes end on their own within seconds; Ctrl-C is looked at between them.
    let stop_if_interrupted = |what: &str| {
        if setup.interrupt.load(std::sync::atomic::Ordering::Relaxed) {
            return Err(CliError::Interrupted(format!(
                "bench: interrupted {what}; nothing written"
            )));
        }
        Ok(())
    };
    stop_if_interrupted("before the floors")?;
    eprintln!("  measuring the machine's ping-pong floors ...");
    report.machine_floors = Some(machine_floors(exe, &setup.interrupt)?);
    stop_if_interrupted("while measuring the ping-pong floors")?;
    println!("{}", tiltsim_studies::bench_table::table(&report));
    if let Some(dir) = a.out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    write_json(&a.out, &report)?;
    println!("wrote {}", a.out.display());
    Ok(())
}
