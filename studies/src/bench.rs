//! `tiltsim bench`: the machine's numbers for the co-simulation, measured in one run.
//!
//! 1. The plant's round trip in a run: orchestrator → participant → orchestrator through
//!    shared memory for the plant, whose step takes about 0.1 µs, minus that step (p50, p99).
//! 2. The per-tick coordination overhead (tick wall time minus the participants' compute on
//!    the critical path) of every master algorithm and wait strategy over IPC.
//! 3. The wall time of the same scenario in-process and across processes, and their ratio.
//! 4. iceoryx2's floor for the same tick ([`ExchangeFloors`], measured after each round), set
//!    beside each round's overhead of each master by [`Report::set_exchange_floors`]
//!    (`bench_floor`).
//!
//! Each configuration is a real `engine::run` of the scenario for `duration` simulated
//! seconds; nothing is modelled. Results print as a table and go to JSON.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use cosim::wait::WaitStrategy;
use serde::Serialize;

use tiltsim_master::engine::{self, RunOptions, Status, Summary};

pub use crate::bench_floor::{ExchangeFloors, Round};
use tiltsim_scenario::scenario::{Master, Scenario, Transport};

/// One measured configuration.
#[derive(Debug, Clone, Serialize)]
pub struct Config {
    /// Transport.
    pub transport: &'static str,
    /// Master algorithm.
    pub master: &'static str,
    /// Wait strategy.
    pub wait: &'static str,
    /// Whether the run's processes ran under SCHED_FIFO (`tiltsim run --realtime`).
    pub realtime: bool,
    /// Ticks run.
    pub ticks: u64,
    /// Coordination overhead per tick, p50 (µs).
    pub overhead_p50_us: f64,
    /// Coordination overhead per tick, p99 (µs).
    pub overhead_p99_us: f64,
    /// Plant round trip minus its compute, p50 (µs).
    pub plant_round_trip_p50_us: f64,
    /// Plant round trip, p99 (µs).
    pub plant_round_trip_p99_us: f64,
    /// Wall time of the loop (s).
    pub wall_s: f64,
    /// CPU seconds, orchestrator + participants.
    pub cpu_s: f64,
    /// Where the run's processes ran (IPC only): a pair of CPUs of its own, or left to the
    /// kernel among other work (`cosim::ipc::placement`).
    pub placement: Option<cosim::ipc::placement::Reason>,
    /// iceoryx2's floor for this tick's exchanges (µs): the best set's p50 tick of the same
    /// pattern, placement and wait with nothing of tiltsim's in between ([`ExchangeFloors`]),
    /// over every round. Only for the IPC rows with the adaptive wait that had a pair of CPUs
    /// of their own (the floor's placement) in at least one round, once the floors are
    /// measured.
    pub exchange_floor_us: Option<f64>,
    /// The worst set's p50 of the same floor (µs): the cost of the same exchanges when the
    /// kernel cycles the processes sharing a CPU in the least favourable order.
    pub exchange_floor_worst_us: Option<f64>,
    /// How far tiltsim's coordination is from the transport's floor for the same pattern: the
    /// median over the rounds of each round's overhead over the floor measured right after it
    /// ([`Round::overhead_over_floor`]).
    pub overhead_over_floor: Option<f64>,
    /// Every round of this configuration in run order, the first its own run above (one for
    /// the configurations the wall-time ratios do not compare).
    pub rounds: Vec<Round>,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// Scenario measured.
    pub scenario: String,
    /// Simulated seconds per configuration.
    pub duration_s: f64,
    /// CPUs available.
    pub cpus: usize,
    /// The machine measured on, so figures from different machines can be set side by side.
    pub machine: Machine,
    /// iceoryx2 round-trip floor: the smallest plant round-trip p50 over the IPC
    /// configurations, minus the plant's compute (µs).
    pub ipc_round_trip_floor_us: f64,
    /// Every configuration.
    pub configs: Vec<Config>,
    /// Wall time in-process (s), Gauss-Seidel: the median of its rounds.
    pub wall_in_process_s: f64,
    /// Wall time across processes (s), Gauss-Seidel, adaptive wait: the median of its rounds.
    pub wall_ipc_s: f64,
    /// `wall_ipc_s / wall_in_process_s`; `None` when withheld ([`Report::ratio_withheld`]).
    pub ipc_over_in_process: Option<f64>,
    /// Wall time across processes (s), Jacobi (pipelined, measured CPU plan), adaptive wait:
    /// the median of its rounds.
    pub wall_ipc_jacobi_s: f64,
    /// `wall_ipc_jacobi_s / wall_in_process_s`; `None` when withheld.
    pub jacobi_ipc_over_in_process: Option<f64>,
    /// With `--realtime`: wall time across processes under SCHED_FIFO (s), Gauss-Seidel and
    /// Jacobi, adaptive wait, the medians of their rounds, and each over `wall_in_process_s`
    /// (the in-process run keeps the ordinary policy: what the real-time policy buys an IPC
    /// run, beside the same hogs).
    pub realtime: Option<RealtimeWalls>,
    /// CPU hogs (spinning threads) that ran beside every configuration (`--hogs`); they are
    /// stopped while the floors are measured.
    pub hogs: usize,
    /// Why the wall-time ratios are not drawn: a configuration's rounds spread too widely
    /// (the load the machine ran under is in `load_average`).
    pub ratio_withheld: Option<String>,
    /// The 1-minute load average before the first configuration and after the last.
    pub load_average: LoadSpan,
    /// Each compared configuration's spread over its rounds, (max − min) / median; `None`
    /// with fewer than three rounds.
    pub wall_spread: [Option<f64>; 3],
    /// Every round's wall time of the three configurations the ratios compare.
    pub wall_rounds: WallRounds,
    /// The machine's ping-pong floors, measured after the configurations (`tiltsim bench`).
    pub machine_floors: Option<MachineFloors>,
    /// iceoryx2's floor for the scenario's tick pattern under each master, measured after
    /// each round of the configurations (`tiltsim bench`).
    pub exchange_floors: Option<ExchangeFloors>,
}

/// The wall times (s) of each round of the configurations the ratios compare, in run order.
#[derive(Debug, Clone, Default, Serialize)]
pub struct WallRounds {
    /// In-process, Gauss-Seidel.
    pub in_process_s: Vec<f64>,
    /// IPC, Gauss-Seidel, adaptive wait.
    pub ipc_gauss_seidel_s: Vec<f64>,
    /// IPC, Jacobi, adaptive wait.
    pub ipc_jacobi_s: Vec<f64>,
    /// IPC, Gauss-Seidel, adaptive wait, under SCHED_FIFO (with `--realtime`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub ipc_gauss_seidel_realtime_s: Vec<f64>,
    /// IPC, Jacobi, adaptive wait, under SCHED_FIFO (with `--realtime`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub ipc_jacobi_realtime_s: Vec<f64>,
}

impl WallRounds {
    fn add(&mut self, p: Plan, wall_s: f64) {
        let list = match (p.transport, p.master, p.wait, p.realtime) {
            (Transport::InProcess, _, _, _) => &mut self.in_process_s,
            (Transport::Ipc, Master::GaussSeidel, WaitStrategy::Adaptive, false) => {
                &mut self.ipc_gauss_seidel_s
            }
            (Transport::Ipc, Master::Jacobi, WaitStrategy::Adaptive, false) => {
                &mut self.ipc_jacobi_s
            }
            (Transport::Ipc, Master::GaussSeidel, WaitStrategy::Adaptive, true) => {
                &mut self.ipc_gauss_seidel_realtime_s
            }
            (Transport::Ipc, Master::Jacobi, WaitStrategy::Adaptive, true) => {
                &mut self.ipc_jacobi_realtime_s
            }
            _ => return,
        };
        list.push(wall_s);
    }

    /// Every compared configuration's name and rounds.
    fn named(&self) -> [(&'static str, &Vec<f64>); 5] {
        [
            ("in-process", &self.in_process_s),
            ("IPC gauss-seidel", &self.ipc_gauss_seidel_s),
            ("IPC jacobi", &self.ipc_jacobi_s),
            (
                "IPC gauss-seidel realtime",
                &self.ipc_gauss_seidel_realtime_s,
            ),
            ("IPC jacobi realtime", &self.ipc_jacobi_realtime_s),
        ]
    }
}

/// The IPC runs under SCHED_FIFO against the same run in one process under the ordinary
/// policy, beside the same hogs (`tiltsim bench --realtime`).
#[derive(Debug, Clone, Serialize)]
pub struct RealtimeWalls {
    /// Gauss-Seidel, adaptive wait: the median of its rounds (s).
    pub wall_ipc_s: f64,
    /// `wall_ipc_s / wall_in_process_s`; `None` when withheld.
    pub ipc_over_in_process: Option<f64>,
    /// Jacobi, adaptive wait: the median of its rounds (s).
    pub wall_ipc_jacobi_s: f64,
    /// `wall_ipc_jacobi_s / wall_in_process_s`; `None` when withheld.
    pub jacobi_ipc_over_in_process: Option<f64>,
}

/// One configuration to measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Plan {
    pub transport: Transport,
    pub master: Master,
    pub wait: WaitStrategy,
    /// Under SCHED_FIFO (IPC only).
    pub realtime: bool,
}

impl Plan {
    fn new(transport: Transport, master: Master, wait: WaitStrategy, realtime: bool) -> Plan {
        Plan {
            transport,
            master,
            wait,
            realtime,
        }
    }

    fn name(&self) -> String {
        format!(
            "{} {} {}{}",
            self.transport.name(),
            self.master.name(),
            self.wait.name(),
            if self.realtime { " realtime" } else { "" }
        )
    }
}

/// The 1-minute load average around a measurement (`None` where Linux does not report it).
#[derive(Debug, Clone, Serialize)]
pub struct LoadSpan {
    /// Before the first run.
    pub before: Option<f64>,
    /// After the last.
    pub after: Option<f64>,
}

/// The spread of the rounds above which a ratio of medians is not drawn: rounds that span
/// more than half their median leave the median itself uncertain by about a quarter, more
/// than the difference between the configurations a ratio is read for.
pub const MAX_SPREAD: f64 = 0.5;

/// (max − min) / median of `v`, `None` with fewer than three values.
fn spread(v: &[f64]) -> Option<f64> {
    if v.len() < 3 {
        return None;
    }
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
            (l.min(*x), h.max(*x))
        });
    let m = median(v);
    (m > 0.0).then(|| (hi - lo) / m)
}

/// Why ratios of these rounds mean nothing, if so. The load average is printed beside them
/// but not used here: it trails the last minute, so a quiet measurement just after a busy
/// spell would be refused for it.
fn withheld(walls: &WallRounds) -> Option<String> {
    walls.named().into_iter().find_map(|(name, v)| {
        spread(v).filter(|s| *s > MAX_SPREAD).map(|s| {
            format!(
                "the {name} rounds spread over {:.0} % of their median (more than {:.0} %)",
                s * 100.0,
                MAX_SPREAD * 100.0
            )
        })
    })
}

/// The median of `v` (the lower of the middle two), NaN when empty.
pub(crate) fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v.get((v.len().max(1) - 1) / 2).copied().unwrap_or(f64::NAN)
}

/// The machine's iceoryx2 floors beside a scenario's figures (`tiltsim bench --ping-pong`).
#[derive(Debug, Clone, Serialize)]
pub struct MachineFloors {
    /// Payload measured (bytes).
    pub payload_bytes: usize,
    /// One-way p50 between two processes busy-waiting on their own CPUs (µs).
    pub one_way_cross_cpu_us: f64,
    /// One-way p50 between two processes on one CPU, yielding it while they wait (µs): the
    /// cost of handing a CPU from one process to another, which every tick pays where more
    /// processes than CPUs take part.
    pub one_way_same_cpu_us: f64,
}

/// Why a configuration could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The run could not start.
    #[error("{config}: {source}")]
    Start {
        /// Transport, master and wait.
        config: String,
        /// Why.
        source: tiltsim_master::engine::RunError,
    },
    /// Ctrl-C (SIGINT, SIGTERM or SIGHUP) came while measuring.
    #[error("interrupted while measuring {config}; nothing written")]
    Interrupted {
        /// Transport, master and wait.
        config: String,
    },
    /// The run did not complete.
    #[error("{config}: {why}")]
    Run {
        /// Transport, master and wait.
        config: String,
        /// The run's error.
        why: String,
    },
}

/// One run of `s` in `dir`, its files removed after; `realtime`: this thread and the
/// participants under SCHED_FIFO for the run (as `tiltsim run --realtime`), ordinary after.
pub(crate) fn measure(
    s: &Scenario,
    exe: &Path,
    dir: &Path,
    config: &str,
    realtime: bool,
    interrupt: &Arc<AtomicBool>,
) -> Result<Summary, BenchError> {
    let interrupted = || BenchError::Interrupted {
        config: config.to_string(),
    };
    if interrupt.load(Ordering::Relaxed) {
        return Err(interrupted());
    }
    let mut opts = RunOptions::new(dir.to_path_buf(), exe.to_path_buf());
    opts.plots = false;
    opts.interrupt = interrupt.clone();
    if realtime {
        cosim::realtime::enter(cosim::realtime::PRIORITY).map_err(|why| BenchError::Run {
            config: config.to_string(),
            why,
        })?;
        opts.realtime = Some(cosim::realtime::PRIORITY);
    }
    let sum = engine::run(s, &s.name, &opts);
    if realtime {
        cosim::realtime::leave();
        cosim::realtime::unlock_memory();
    }
    let _ = std::fs::remove_dir_all(dir);
    // Interrupted while starting or running: either way the bench ends here.
    if interrupt.load(Ordering::Relaxed) {
        return Err(interrupted());
    }
    let sum = sum.map_err(|source| BenchError::Start {
        config: config.to_string(),
        source,
    })?;
    if sum.status != Status::Completed {
        return Err(BenchError::Run {
            config: config.to_string(),
            why: sum.error.unwrap_or_else(|| "run failed".into()),
        });
    }
    Ok(sum)
}

/// What `tiltsim bench` measures besides the scenario and its duration.
#[derive(Debug, Clone)]
pub struct Setup {
    /// Rounds of the configurations the wall-time ratios compare.
    pub rounds: usize,
    /// Also the IPC runs under SCHED_FIFO (`--realtime`).
    pub realtime: bool,
    /// CPU hogs the caller runs beside every configuration (`--hogs`), for the report.
    pub hogs: usize,
    /// Set by Ctrl-C: the run under way ends, and no other starts.
    pub interrupt: Arc<AtomicBool>,
}

/// Runs `rounds` rounds of the configurations that the wall-time ratios compare (in-process,
/// IPC Gauss-Seidel and IPC Jacobi with the adaptive wait, and with `realtime` the two IPC ones
/// under SCHED_FIFO), one after the other, so that a shared machine's drift falls on all
/// alike; the ratios are those of the median walls. After each round `floors` measures
/// iceoryx2's floor for the scenario's ticks (given the round's index), so that each round's
/// overhead is set beside a floor taken in the same state of the machine. The other
/// configurations run once, after the first round's floor. `progress` is told each run's name.
pub fn run(
    base: &Scenario,
    duration: f64,
    setup: &Setup,
    exe: &Path,
    scratch: &Path,
    floors: impl FnMut(usize) -> Result<ExchangeFloors, BenchError>,
    progress: impl FnMut(&str),
) -> Result<Report, BenchError> {
    let load_before = tiltsim_master::engine::machine::load_average();
    let m = measure_rounds(base, duration, setup, exe, scratch, floors, progress)?;
    Ok(report(base, duration, setup, m, load_before))
}

/// What the rounds measured: every configuration's row (the compared ones with all their
/// rounds), the compared runs' walls, and the floors measured after each round.
struct Measured {
    configs: Vec<Config>,
    walls: WallRounds,
    floors: Option<ExchangeFloors>,
}

/// The measurements of [`run`], in its order.
fn measure_rounds(
    base: &Scenario,
    duration: f64,
    setup: &Setup,
    exe: &Path,
    scratch: &Path,
    mut floors: impl FnMut(usize) -> Result<ExchangeFloors, BenchError>,
    mut progress: impl FnMut(&str),
) -> Result<Measured, BenchError> {
    let plans = configurations(setup.realtime);
    let mut rows: Vec<Option<Config>> = vec![None; plans.len()];
    let mut walls = WallRounds::default();
    let mut measured: Option<ExchangeFloors> = None;
    for round in 0..setup.rounds.max(1) {
        for p in compared(setup.realtime) {
            let s = configured(base, duration, p);
            let name = if round == 0 {
                p.name()
            } else {
                format!("{}, round {}", p.name(), round + 1)
            };
            progress(&name);
            let i = plans
                .iter()
                .position(|q| *q == p)
                .expect("compared is measured");
            let dir = if round == 0 {
                scratch.join(format!("config-{i}"))
            } else {
                scratch.join(format!("round-{round}-{}", p.name().replace(' ', "-")))
            };
            let sum = measure(&s, exe, &dir, &name, p.realtime, &setup.interrupt)?;
            walls.add(p, sum.wall_time_s);
            match &mut rows[i] {
                Some(row) => row.rounds.push(Round::of(&sum)),
                row => *row = Some(Config::of(p, &sum)),
            }
        }
        let f = floors(round)?;
        match &mut measured {
            Some(all) => all.append(f),
            all => *all = Some(f),
        }
        if round > 0 {
            continue;
        }
        for (i, p) in plans.iter().enumerate() {
            if rows[i].is_some() {
                continue;
            }
            // Spinning waiters on a 2-CPU machine starve each other (a tick costs whole
            // scheduler slices), so spin gets a tenth of the ticks; the table shows how many.
            let d = if p.wait == WaitStrategy::Spin && p.transport == Transport::Ipc {
                (duration / 10.0).max(base.run.dt_s * 100.0)
            } else {
                duration
            };
            let s = configured(base, d, *p);
            let name = p.name();
            progress(&name);
            let dir = scratch.join(format!("config-{i}"));
            let sum = measure(&s, exe, &dir, &name, p.realtime, &setup.interrupt)?;
            rows[i] = Some(Config::of(*p, &sum));
        }
    }
    Ok(Measured {
        configs: rows.into_iter().flatten().collect(),
        walls,
        floors: measured,
    })
}

/// The report of what [`measure_rounds`] measured: the walls' medians and ratios, the rows
/// set beside their floors.
fn report(
    base: &Scenario,
    duration: f64,
    setup: &Setup,
    m: Measured,
    load_before: Option<f64>,
) -> Report {
    let Measured {
        configs,
        walls,
        floors,
    } = m;
    let floor = configs
        .iter()
        .filter(|c| c.transport == Transport::Ipc.name())
        .map(|c| c.plant_round_trip_p50_us)
        .fold(f64::INFINITY, f64::min);
    let (wall_local, wall_ipc, wall_jacobi) = (
        median(&walls.in_process_s),
        median(&walls.ipc_gauss_seidel_s),
        median(&walls.ipc_jacobi_s),
    );
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let load_average = LoadSpan {
        before: load_before,
        after: tiltsim_master::engine::machine::load_average(),
    };
    let ratio_withheld = withheld(&walls);
    let ratio = |w: f64| (wall_local > 0.0 && ratio_withheld.is_none()).then(|| w / wall_local);
    let realtime = setup.realtime.then(|| {
        let (gs, jacobi) = (
            median(&walls.ipc_gauss_seidel_realtime_s),
            median(&walls.ipc_jacobi_realtime_s),
        );
        RealtimeWalls {
            wall_ipc_s: gs,
            ipc_over_in_process: ratio(gs),
            wall_ipc_jacobi_s: jacobi,
            jacobi_ipc_over_in_process: ratio(jacobi),
        }
    });
    let mut report = Report {
        scenario: base.name.clone(),
        duration_s: duration,
        cpus,
        machine: Machine::this(),
        ipc_round_trip_floor_us: floor,
        configs,
        wall_in_process_s: wall_local,
        wall_ipc_s: wall_ipc,
        ipc_over_in_process: ratio(wall_ipc),
        wall_ipc_jacobi_s: wall_jacobi,
        jacobi_ipc_over_in_process: ratio(wall_jacobi),
        realtime,
        hogs: setup.hogs,
        wall_spread: [
            spread(&walls.in_process_s),
            spread(&walls.ipc_gauss_seidel_s),
            spread(&walls.ipc_jacobi_s),
        ],
        ratio_withheld,
        load_average,
        wall_rounds: walls,
        machine_floors: None,
        exchange_floors: None,
    };
    if let Some(f) = floors {
        report.set_exchange_floors(f);
    }
    report
}

/// The configurations measured: in-process, then IPC under each master and wait strategy,
/// then with `realtime` the adaptive IPC runs of each master under SCHED_FIFO.
fn configurations(realtime: bool) -> Vec<Plan> {
    let mut plan = vec![Plan::new(
        Transport::InProcess,
        Master::GaussSeidel,
        WaitStrategy::Adaptive,
        false,
    )];
    for m in [Master::GaussSeidel, Master::Jacobi] {
        for w in [
            WaitStrategy::Adaptive,
            WaitStrategy::Spin,
            WaitStrategy::Sleep,
        ] {
            plan.push(Plan::new(Transport::Ipc, m, w, false));
        }
    }
    plan.extend(compared(realtime).into_iter().filter(|p| p.realtime));
    plan
}

/// The configurations the wall-time ratios compare, in the order each round runs them.
fn compared(realtime: bool) -> Vec<Plan> {
    let mut plan = vec![Plan::new(
        Transport::InProcess,
        Master::GaussSeidel,
        WaitStrategy::Adaptive,
        false,
    )];
    let policies: &[bool] = if realtime { &[false, true] } else { &[false] };
    for &rt in policies {
        for m in [Master::GaussSeidel, Master::Jacobi] {
            plan.push(Plan::new(Transport::Ipc, m, WaitStrategy::Adaptive, rt));
        }
    }
    plan
}

/// `base` run for `duration` (s) as configuration `p`.
fn configured(base: &Scenario, duration: f64, p: Plan) -> Scenario {
    let mut s = base.clone();
    s.run.duration_s = Some(duration);
    s.run.transport = p.transport;
    s.run.master = p.master;
    s.run.wait = p.wait;
    s
}

impl Config {
    /// The row of configuration `(t, m, w)` from the summary of its first run (floors not yet
    /// set, [`Report::set_exchange_floors`]).
    fn of(p: Plan, sum: &Summary) -> Config {
        let (t, m, w) = (p.transport, p.master, p.wait);
        let plant = &sum.link_latency[0];
        let compute = sum.participants[0].compute_us.p50;
        Config {
            transport: t.name(),
            master: m.name(),
            wait: if t == Transport::InProcess {
                "-"
            } else {
                w.name()
            },
            realtime: p.realtime,
            ticks: sum.steps_completed,
            overhead_p50_us: sum.timing.p50,
            overhead_p99_us: sum.timing.p99,
            plant_round_trip_p50_us: (plant.round_trip_us.p50 - compute).max(0.0),
            plant_round_trip_p99_us: plant.round_trip_us.p99,
            wall_s: sum.wall_time_s,
            cpu_s: sum.timing.cpu_s.orchestrator + sum.timing.cpu_s.participants,
            placement: sum.timing.placement.as_ref().map(|p| p.reason),
            exchange_floor_us: None,
            exchange_floor_worst_us: None,
            overhead_over_floor: None,
            rounds: vec![Round::of(sum)],
        }
    }
}

impl Round {
    /// The round measured by the run whose summary is `sum` (not yet set beside a floor).
    fn of(sum: &Summary) -> Round {
        Round {
            overhead_p50_us: sum.timing.p50,
            placement: sum.timing.placement.as_ref().map(|p| p.reason),
            overhead_over_floor: None,
        }
    }
}

/// CPU model, logical CPUs and kernel, as Linux reports them.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// `model name` of `/proc/cpuinfo`.
    pub cpu_model: String,
    /// Logical CPUs online (`/proc/cpuinfo` processors).
    pub logical_cpus: usize,
    /// `/proc/sys/kernel/osrelease`.
    pub kernel: String,
}

impl Machine {
    /// This machine ("unknown" where Linux's files are not readable).
    pub fn this() -> Machine {
        let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let model = info
            .lines()
            .find_map(|l| {
                l.strip_prefix("model name")?
                    .split_once(':')
                    .map(|x| x.1.trim())
            })
            .unwrap_or("unknown");
        Machine {
            cpu_model: model.to_string(),
            logical_cpus: info.lines().filter(|l| l.starts_with("processor")).count(),
            kernel: std::fs::read_to_string("/proc/sys/kernel/osrelease")
                .map_or_else(|_| "unknown".into(), |k| k.trim().to_string()),
        }
    }
}

/// Where the scratch runs go.
pub fn scratch_dir(out: &Path) -> PathBuf {
    out.with_extension("runs")
}

#[cfg(test)]
#[path = "bench_tests.rs"]
mod tests;
