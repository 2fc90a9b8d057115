//! The lock-step engine: owns simulated time, steps the participants in the order the master
//! algorithm prescribes, holds outputs between updates, records every tick and measures the
//! coordination overhead.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use actuator_proc::{Actuator, ActuatorInit};
use controller_proc::{Controller, ControllerInit};
use cosim::endpoint::ExitReport;
use cosim::ipc::{IpcHub, IpcSettings, Launch};
use cosim::msg::{
    FromActuator, FromController, FromPlant, Header, ToActuator, ToController, ToPlant,
};
use cosim::stats::{percentiles, Percentiles};
use cosim::{Endpoint, InProcess, Kind, LinkError, Role};
use plant_proc::{Plant, PlantSettings};
use serde::Serialize;

use crate::record::Recorder;
use crate::scenario::{Master, Scenario, Transport};

/// How to run a scenario (command-line choices on top of the file).
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Output directory.
    pub out_dir: PathBuf,
    /// Executable that serves `participant ROLE ...` (normally `tiltsim` itself).
    pub participant_exe: PathBuf,
    /// iceoryx2 prefix; a unique one is made when `None`.
    pub ipc_prefix: Option<String>,
    /// Set by Ctrl-C.
    pub interrupt: Arc<AtomicBool>,
    /// Draw `plots/` after the run.
    pub plots: bool,
}

impl RunOptions {
    /// Options for a run into `out_dir` with participants served by `participant_exe`: a
    /// unique iceoryx2 prefix, plots drawn, no interrupt flag shared.
    pub fn new(out_dir: PathBuf, participant_exe: PathBuf) -> Self {
        RunOptions {
            out_dir,
            participant_exe,
            ipc_prefix: None,
            interrupt: Arc::new(AtomicBool::new(false)),
            plots: true,
        }
    }
}

/// How the run ended.
#[derive(Debug, Clone, Serialize, PartialEq)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Every step done.
    Completed,
    /// A participant failed; the message names it and the step.
    Failed,
    /// Ctrl-C.
    Interrupted,
}

/// One participant in the summary.
#[derive(Debug, Clone, Serialize)]
pub struct ParticipantReport {
    /// Role.
    pub role: Role,
    /// Process name.
    pub process: &'static str,
    /// Process id.
    pub pid: u32,
    /// Period (s).
    pub period_s: f64,
    /// How it ended.
    pub exit: ExitReport,
    /// Wall time spent inside its model's step per call (µs), as it reports.
    pub compute_us: Percentiles,
}

/// Timing of the run.
#[derive(Debug, Clone, Serialize, Default)]
pub struct Timing {
    /// Per-tick coordination overhead (µs): tick wall time minus the participants' compute
    /// time on the critical path (the sum for Gauss-Seidel, the largest for Jacobi).
    pub p50: f64,
    /// 99th percentile of the overhead (µs).
    pub p99: f64,
    /// Largest overhead (µs).
    pub max: f64,
    /// Mean overhead (µs).
    pub mean: f64,
    /// Whole tick wall time (µs).
    pub tick_us: Percentiles,
    /// Orchestrator CPU time, user + system (s), and the participants' (s), when measurable.
    pub cpu_s: CpuTime,
}

/// CPU time spent.
#[derive(Debug, Clone, Serialize, Default)]
pub struct CpuTime {
    /// The orchestrator process (s).
    pub orchestrator: f64,
    /// All participant processes together (s); 0 in-process.
    pub participants: f64,
}

/// Result of a run, written as `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// tiltsim version.
    pub tiltsim_version: &'static str,
    /// Scenario name.
    pub scenario: String,
    /// Scenario file.
    pub scenario_file: String,
    /// Seed.
    pub seed: u64,
    /// Transport.
    pub transport: &'static str,
    /// Master algorithm.
    pub master_algorithm: &'static str,
    /// Wait strategy.
    pub wait_strategy: &'static str,
    /// Outcome.
    pub status: Status,
    /// The failure, naming participant and step.
    pub error: Option<String>,
    /// Participants.
    pub participants: Vec<ParticipantReport>,
    /// Base tick (s).
    pub dt_s: f64,
    /// Steps planned.
    pub steps_planned: u64,
    /// Steps completed (= rows in timeseries.csv).
    pub steps_completed: u64,
    /// Simulated time covered (s).
    pub simulated_time_s: f64,
    /// Wall time of the lock-step loop (s).
    pub wall_time_s: f64,
    /// Simulated seconds per wall second.
    pub realtime_factor: f64,
    /// Coordination overhead and CPU use.
    pub timing: Timing,
    /// A quick look at the results.
    pub results: QuickLook,
    /// The MPC's QP solver (absent for controllers without one).
    pub controller_solver: Option<SolverReport>,
    /// Ride comfort (Table 4 rows), from the recorded series.
    pub comfort: crate::comfort::Comfort,
    /// iceoryx2 prefix of the run ("" in-process).
    pub ipc_prefix: String,
    /// Files of the run still present after clean-up (must be empty).
    pub leftover_ipc_files: Vec<String>,
}

/// The controller's QP solves over the run.
#[derive(Debug, Clone, Serialize)]
pub struct SolverReport {
    /// QPs solved or attempted.
    pub solves: u64,
    /// Solves that did not end `Solved`/`AlmostSolved`; the previous command was held.
    pub failures: u64,
    /// Clarabel iterations per solve.
    pub iterations: Percentiles,
}

/// Headline numbers of a run (the full comfort assessment is separate).
#[derive(Debug, Clone, Serialize, Default)]
pub struct QuickLook {
    /// Largest |passenger lateral acceleration| (m/s²).
    pub lat_acc_peak: f64,
    /// Lateral acceleration at the middle of the steady curve (m/s²).
    pub lat_acc_mid_curve: f64,
    /// Body roll θ_v at the middle of the steady curve (rad).
    pub theta_v_mid_curve: f64,
    /// Largest |δ_a| (rad).
    pub delta_a_peak: f64,
}

/// Why a run could not start.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// Output directory or files.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Transport set-up.
    #[error(transparent)]
    Ipc(#[from] cosim::ipc::IpcError),
    /// The controller design failed.
    #[error("controller design: {0}")]
    Design(String),
}

type PlantEp = Box<dyn Endpoint<ToPlant, FromPlant>>;
type ActuatorEp = Box<dyn Endpoint<ToActuator, FromActuator>>;
type ControllerEp = Box<dyn Endpoint<ToController, FromController>>;

/// The three participants' settings as their processes receive them.
pub struct Inits {
    /// Plant.
    pub plant: PlantSettings,
    /// Actuator.
    pub actuator: ActuatorInit,
    /// Controller.
    pub controller: ControllerInit,
}

impl Inits {
    /// Derives every participant's settings from the scenario (one source of truth).
    pub fn from(s: &Scenario) -> Self {
        Inits {
            plant: PlantSettings {
                vehicle: s.vehicle.clone(),
                track: s.track.clone(),
                sensor: s.sensor.clone(),
                dt_s: s.run.dt_s,
                seed: s.run.seed,
            },
            actuator: ActuatorInit {
                actuator: s.actuator.clone(),
                dt_s: s.run.dt_s,
                k_vr: s.vehicle.k_vr,
            },
            controller: ControllerInit {
                controller: s.controller.clone(),
                track: s.track.clone(),
                vehicle: s.controller_vehicle().clone(),
            },
        }
    }
}

/// CPU time of this process, user + system (s).
fn cpu_self() -> f64 {
    // SAFETY: an all-zero rusage is valid; getrusage only writes into it.
    let mut u: libc::rusage = unsafe { core::mem::zeroed() };
    // SAFETY: RUSAGE_SELF with a valid pointer.
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    (u.ru_utime.tv_sec + u.ru_stime.tv_sec) as f64
        + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) as f64 * 1e-6
}

struct Participants {
    plant: PlantEp,
    actuator: ActuatorEp,
    controller: ControllerEp,
    hub: Option<IpcHub>,
}

fn start(s: &Scenario, opts: &RunOptions, prefix: &str) -> Result<Participants, RunError> {
    let inits = Inits::from(s);
    match s.run.transport {
        Transport::InProcess => Ok(Participants {
            plant: Box::new(InProcess::new(Plant::new(&inits.plant))),
            actuator: Box::new(InProcess::new(Actuator::new(&inits.actuator))),
            controller: Box::new(InProcess::new(
                Controller::new(&inits.controller).map_err(RunError::Design)?,
            )),
            hub: None,
        }),
        Transport::Ipc => {
            let plan = if s.run.pin_cpus {
                cosim::ipc::cpu_plan()
            } else {
                None
            };
            let hub = IpcHub::new(IpcSettings {
                prefix: prefix.to_string(),
                wait: s.run.wait,
                deadline: Duration::from_millis(s.run.deadline_ms),
                participant_cpu: plan.map(|p| p.1),
            })?;
            if let Some((own, _)) = plan {
                cosim::ipc::pin_to_cpu(own);
            }
            let startup = Duration::from_millis(s.run.startup_ms);
            let launch = |role: Role, params: String| Launch {
                program: opts.participant_exe.clone(),
                args: vec![
                    "participant".into(),
                    role.name().into(),
                    "--params".into(),
                    params.into(),
                ],
            };
            let plant = hub.spawn::<ToPlant, FromPlant>(
                Role::Plant,
                &launch(Role::Plant, json(&inits.plant)),
                startup,
            )?;
            let actuator = hub.spawn::<ToActuator, FromActuator>(
                Role::Actuator,
                &launch(Role::Actuator, json(&inits.actuator)),
                startup,
            )?;
            let controller = hub.spawn::<ToController, FromController>(
                Role::Controller,
                &launch(Role::Controller, json(&inits.controller)),
                startup,
            )?;
            Ok(Participants {
                plant: Box::new(plant),
                actuator: Box::new(actuator),
                controller: Box::new(controller),
                hub: Some(hub),
            })
        }
    }
}

/// Settings as the JSON a participant process receives. Plain settings structs (no maps with
/// non-string keys) always serialise.
fn json<T: Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

fn hdr(k: u64, kind: Kind) -> Header {
    Header::new(k, kind)
}

/// The held (latest) outputs of every participant.
struct Held {
    p: FromPlant,
    a: FromActuator,
    c: FromController,
}

struct Compute {
    plant: Vec<f64>,
    actuator: Vec<f64>,
    controller: Vec<f64>,
    solver_iterations: Vec<f64>,
    solver_failures: u64,
}

/// Steps every tick; returns the error that stopped it, if any.
fn lockstep(
    s: &Scenario,
    ps: &mut Participants,
    rec: &mut Recorder,
    interrupt: &AtomicBool,
    overhead: &mut Vec<f64>,
    ticks: &mut Vec<f64>,
    compute: &mut Compute,
) -> Result<(), LinkError> {
    // Initial outputs at t_0.
    let init = (|| -> Result<Held, LinkError> {
        ps.plant.send(&ToPlant {
            header: hdr(0, Kind::Init),
            ..Default::default()
        })?;
        ps.actuator.send(&ToActuator {
            header: hdr(0, Kind::Init),
            ..Default::default()
        })?;
        ps.controller.send(&ToController {
            header: hdr(0, Kind::Init),
            ..Default::default()
        })?;
        Ok(Held {
            p: ps.plant.receive(0, Kind::Init)?,
            a: ps.actuator.receive(0, Kind::Init)?,
            c: ps.controller.receive(0, Kind::Init)?,
        })
    })();
    let mut h = init?;
    let n = s.steps();
    let c_period = s.controller_period_ticks();
    for k in 0..n {
        if interrupt.load(Ordering::Relaxed) {
            return Ok(());
        }
        let started = Instant::now();
        let c_due = k % c_period == 0;
        let step = hdr(k, Kind::Step);
        let to_c = |p: &FromPlant| ToController {
            header: step,
            t: p.t,
            s: p.s,
            theta_v_meas: p.theta_v_meas,
        };
        let res = (|| -> Result<f64, LinkError> {
            let (cp, ca, mut cc);
            cc = 0u64;
            match s.run.master {
                Master::GaussSeidel => {
                    if c_due {
                        ps.controller.send(&to_c(&h.p))?;
                        h.c = ps.controller.receive(k, Kind::Step)?;
                        cc = h.c.header.compute_ns;
                    }
                    ps.actuator.send(&ToActuator {
                        header: step,
                        delta_a_cmd: h.c.delta_a_cmd,
                        psi: h.p.psi,
                    })?;
                    h.a = ps.actuator.receive(k, Kind::Step)?;
                    ca = h.a.header.compute_ns;
                    ps.plant.send(&ToPlant {
                        header: step,
                        delta_a: h.a.delta_a,
                    })?;
                    h.p = ps.plant.receive(k, Kind::Step)?;
                    cp = h.p.header.compute_ns;
                    Ok(((cp + ca + cc) as f64 * 1e-3, cp, ca, cc))
                }
                Master::Jacobi => {
                    if c_due {
                        ps.controller.send(&to_c(&h.p))?;
                    }
                    ps.actuator.send(&ToActuator {
                        header: step,
                        delta_a_cmd: h.c.delta_a_cmd,
                        psi: h.p.psi,
                    })?;
                    ps.plant.send(&ToPlant {
                        header: step,
                        delta_a: h.a.delta_a,
                    })?;
                    if c_due {
                        h.c = ps.controller.receive(k, Kind::Step)?;
                        cc = h.c.header.compute_ns;
                    }
                    h.a = ps.actuator.receive(k, Kind::Step)?;
                    h.p = ps.plant.receive(k, Kind::Step)?;
                    ca = h.a.header.compute_ns;
                    cp = h.p.header.compute_ns;
                    Ok((cp.max(ca).max(cc) as f64 * 1e-3, cp, ca, cc))
                }
            }
            .map(|(crit, cp, ca, cc)| {
                compute.plant.push(cp as f64 * 1e-3);
                compute.actuator.push(ca as f64 * 1e-3);
                if c_due {
                    compute.controller.push(cc as f64 * 1e-3);
                    match h.c.solver_status {
                        0 => {}
                        1 => compute.solver_iterations.push(h.c.solver_iterations as f64),
                        _ => {
                            compute.solver_iterations.push(h.c.solver_iterations as f64);
                            compute.solver_failures += 1;
                        }
                    }
                }
                crit
            })
        })();
        let crit_us = res?;
        let tick_us = started.elapsed().as_secs_f64() * 1e6;
        ticks.push(tick_us);
        overhead.push((tick_us - crit_us).max(0.0));
        rec.row(k, &h.p, &h.a, &h.c)
            .map_err(|e| LinkError::Transport {
                role: Role::Plant,
                what: format!("cannot record: {e}"),
            })?;
    }
    Ok(())
}

/// Runs a validated scenario. Always writes what it has to `out_dir`; the returned summary
/// says whether the run completed.
pub fn run(s: &Scenario, scenario_file: &str, opts: &RunOptions) -> Result<Summary, RunError> {
    let io = |path: PathBuf| move |source| RunError::Io { path, source };
    std::fs::create_dir_all(&opts.out_dir).map_err(io(opts.out_dir.clone()))?;
    let csv = opts.out_dir.join("timeseries.csv");
    let mut rec = Recorder::create(&csv).map_err(io(csv.clone()))?;
    let resolved = opts.out_dir.join("scenario.toml");
    std::fs::write(&resolved, toml::to_string(s).unwrap_or_default()).map_err(io(resolved))?;

    let prefix = match s.run.transport {
        Transport::Ipc => opts
            .ipc_prefix
            .clone()
            .unwrap_or_else(cosim::ipc::unique_prefix),
        Transport::InProcess => String::new(),
    };
    let cpu0 = cpu_self();
    let cpus_before_run = cosim::ipc::allowed_cpus();
    let mut ps = match start(s, opts, &prefix) {
        Ok(ps) => ps,
        Err(e) => {
            if !prefix.is_empty() {
                cosim::ipc::remove_run_files(&prefix);
            }
            return Err(e);
        }
    };
    let pids = [ps.plant.pid(), ps.actuator.pid(), ps.controller.pid()];
    // `start` may have pinned this process to one CPU for the run; undo it afterwards so a
    // process that runs several scenarios (sweeps, benchmarks) starts each one alike.
    let cpus_before = cpus_before_run;
    let loop_started = Instant::now();
    let mut overhead = Vec::with_capacity(s.steps() as usize);
    let mut ticks = Vec::with_capacity(s.steps() as usize);
    let mut compute = Compute {
        plant: Vec::new(),
        actuator: Vec::new(),
        controller: Vec::new(),
        solver_iterations: Vec::new(),
        solver_failures: 0,
    };
    let outcome = lockstep(
        s,
        &mut ps,
        &mut rec,
        &opts.interrupt,
        &mut overhead,
        &mut ticks,
        &mut compute,
    );
    let wall = loop_started.elapsed().as_secs_f64();
    let _ = rec.flush();

    let (status, error) = match &outcome {
        Ok(_) if opts.interrupt.load(Ordering::Relaxed) => (
            Status::Interrupted,
            Some("interrupted by Ctrl-C".to_string()),
        ),
        Ok(_) => (Status::Completed, None),
        Err(e) => (Status::Failed, Some(e.to_string())),
    };
    // Stop every participant (a dead or hung one is killed and reaped), then clean up.
    let exits = [
        ps.plant.shutdown(),
        ps.actuator.shutdown(),
        ps.controller.shutdown(),
    ];
    let mut leftover = Vec::new();
    if let Some(hub) = ps.hub.take() {
        hub.cleanup_dead();
        drop(ps);
        drop(hub);
        cosim::ipc::remove_run_files(&prefix);
        leftover = cosim::ipc::leftover_files(&prefix)
            .iter()
            .map(|p| p.display().to_string())
            .collect();
    }

    if !cpus_before.is_empty() {
        cosim::ipc::set_cpus(&cpus_before);
    }
    let steps_completed = rec.rows();
    let mut ov = overhead;
    let o = percentiles(&mut ov);
    let periods = [s.run.dt_s, s.run.dt_s, s.controller.period_s];
    let solver = (!compute.solver_iterations.is_empty()).then(|| SolverReport {
        solves: compute.solver_iterations.len() as u64,
        failures: compute.solver_failures,
        iterations: percentiles(&mut compute.solver_iterations),
    });
    let mut comp = [compute.plant, compute.actuator, compute.controller];
    let participants = Role::ALL
        .iter()
        .enumerate()
        .map(|(i, role)| ParticipantReport {
            role: *role,
            process: role.process_name(),
            pid: pids[i],
            period_s: periods[i],
            exit: exits[i].clone(),
            compute_us: percentiles(&mut comp[i]),
        })
        .collect::<Vec<_>>();
    let cpu_participants = exits.iter().filter_map(|e| e.cpu_s).fold(0.0, |a, b| a + b);
    let results = quick_look(s, &csv);
    let comfort = comfort_of(s, &csv);
    if !opts.plots {
    } else if let Err(e) = write_plots(s, &opts.out_dir) {
        tracing::warn!("plots not written: {e}");
    }
    Ok(Summary {
        tiltsim_version: env!("CARGO_PKG_VERSION"),
        scenario: s.name.clone(),
        scenario_file: scenario_file.to_string(),
        seed: s.run.seed,
        transport: s.run.transport.name(),
        master_algorithm: s.run.master.name(),
        wait_strategy: s.run.wait.name(),
        status,
        error,
        participants,
        dt_s: s.run.dt_s,
        steps_planned: s.steps(),
        steps_completed,
        simulated_time_s: steps_completed as f64 * s.run.dt_s,
        wall_time_s: wall,
        realtime_factor: if wall > 0.0 {
            steps_completed as f64 * s.run.dt_s / wall
        } else {
            0.0
        },
        timing: Timing {
            p50: o.p50,
            p99: o.p99,
            max: o.max,
            mean: o.mean,
            tick_us: percentiles(&mut ticks),
            cpu_s: CpuTime {
                orchestrator: cpu_self() - cpu0,
                participants: cpu_participants,
            },
        },
        results,
        controller_solver: solver,
        comfort,
        ipc_prefix: prefix,
        leftover_ipc_files: leftover,
    })
}

/// Times (s) at which the vehicle enters the first transition, the steady curve, the second
/// transition and the final straight.
fn section_times(tp: &plant_proc::TrackParams) -> [f64; 4] {
    let v = tp.speed();
    let t1 = tp.straight_before_m / v;
    let t2 = t1 + tp.transition_m / v;
    let t3 = t2 + tp.curve_m / v;
    [t1, t2, t3, t3 + tp.transition_m / v]
}

/// Reads the recorded series back into the signals the comfort assessment needs.
pub fn signals_from_csv(s: &Scenario, csv: &std::path::Path) -> crate::comfort::Signals {
    use crate::comfort::Signals;
    let Ok(text) = std::fs::read_to_string(csv) else {
        return Signals::default();
    };
    let cols = crate::record::COLUMNS;
    let col = |name: &str| cols.iter().position(|c| *c == name).unwrap_or(0);
    let idx = [
        "t",
        "lat_acc",
        "theta_ref",
        "curvature",
        "cant",
        "dtheta_v",
        "y_v",
        "theta_v",
        "y_b",
        "theta_b",
    ]
    .map(col);
    let mut rows: Vec<[f64; 10]> = Vec::new();
    for line in text.lines().skip(1) {
        let f: Vec<f64> = line
            .split(',')
            .map(|x| x.parse().unwrap_or(f64::NAN))
            .collect();
        if f.len() < cols.len() {
            continue;
        }
        rows.push(idx.map(|i| f[i]));
    }
    let veh = plant_proc::Vehicle::new(s.vehicle.clone(), s.track.speed());
    let n = rows.len();
    let dt = s.run.dt_s;
    let deriv = |k: usize, f: &dyn Fn(&[f64; 10]) -> f64| {
        if n < 2 {
            return 0.0;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (f(&rows[b]) - f(&rows[a])) / ((b - a) as f64 * dt)
    };
    let (h1, h2) = (s.vehicle.h1, s.vehicle.h2);
    let [t1, t2, t3, t4] = section_times(&s.track);
    Signals {
        t: rows.iter().map(|r| r[0]).collect(),
        lat_acc: rows.iter().map(|r| r[1]).collect(),
        lat_acc_ref: rows
            .iter()
            .map(|r| veh.lateral_acceleration(r[2], r[3], r[4]))
            .collect(),
        roll_speed: (0..n).map(|k| rows[k][5] + deriv(k, &|r| r[4])).collect(),
        roll_speed_ref: (0..n).map(|k| deriv(k, &|r| r[4] + r[2])).collect(),
        deflection: rows
            .iter()
            .map(|r| r[6] - h1 * r[7] - r[8] - h2 * r[9])
            .collect(),
        transitions: vec![(t1, t2), (t3, t4)],
    }
}

/// Reads `dir/timeseries.csv` back as numeric rows (complete rows only).
pub fn read_rows(dir: &std::path::Path) -> std::io::Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(dir.join("timeseries.csv"))?;
    let n = crate::record::COLUMNS.len();
    Ok(text
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .filter(|r: &Vec<f64>| r.len() >= n)
        .collect())
}

pub(crate) fn bands(s: &Scenario) -> Vec<(f64, f64, bool)> {
    let [t1, t2, t3, t4] = section_times(&s.track);
    vec![(t1, t2, false), (t2, t3, true), (t3, t4, false)]
}

/// Writes `dir/plots/*.svg` and `*.png` from `dir/timeseries.csv`.
pub fn write_plots(s: &Scenario, dir: &std::path::Path) -> std::io::Result<Vec<PathBuf>> {
    let rows = read_rows(dir)?;
    crate::plot::write_run_plots(
        dir,
        crate::record::COLUMNS,
        &rows,
        &bands(s),
        s.controller.u_max_deg,
    )
}

/// Writes the figures that put several runs side by side (`out/plots/compare_*`): lateral
/// acceleration, body roll and bar angle of every run on one time axis. `runs` are (label,
/// scenario, run directory); the shaded sections are the first run's.
pub fn write_compare_plots(
    runs: &[(String, Scenario, PathBuf)],
    out: &std::path::Path,
) -> std::io::Result<Vec<PathBuf>> {
    use crate::plot::{Chart, Line, PALETTE};
    let cols = crate::record::COLUMNS;
    let col = |name: &str| cols.iter().position(|c| *c == name).unwrap_or(0);
    let mut data = Vec::new();
    for (label, _, dir) in runs {
        data.push((label.as_str(), read_rows(dir)?));
    }
    let n = data.iter().map(|(_, r)| r.len()).min().unwrap_or(0);
    let t: Vec<f64> = data
        .first()
        .map(|(_, r)| r[..n].iter().map(|x| x[col("t")]).collect())
        .unwrap_or_default();
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots)?;
    let bands = runs.first().map(|r| bands(&r.1)).unwrap_or_default();
    let mut files = Vec::new();
    for (name, title, y_label, column, scale) in [
        (
            "compare_lateral_acceleration",
            "Passenger lateral acceleration of each run (Figs 14-15)",
            "lateral acceleration (m/s²)",
            "lat_acc",
            1.0,
        ),
        (
            "compare_body_roll",
            "Carbody roll of each run (Fig. 16)",
            "roll θ_v (deg)",
            "theta_v",
            1f64.to_degrees(),
        ),
        (
            "compare_control",
            "Achieved anti-roll-bar angle of each run (Fig. 17)",
            "bar angle δ_a (deg)",
            "delta_a",
            1f64.to_degrees(),
        ),
    ] {
        let i = col(column);
        let chart = Chart {
            title,
            x_label: "time (s)",
            y_label,
            lines: data
                .iter()
                .enumerate()
                .map(|(k, (label, rows))| Line {
                    label,
                    y: rows[..n].iter().map(|r| r[i] * scale).collect(),
                    colour: PALETTE[k % PALETTE.len()],
                    dashed: false,
                })
                .collect(),
            bands: bands.clone(),
            note: crate::plot::SECTION_NOTE,
        };
        files.extend(crate::plot::write_chart(&plots, name, &chart, &t)?);
    }
    Ok(files)
}

fn comfort_of(s: &Scenario, csv: &std::path::Path) -> crate::comfort::Comfort {
    crate::comfort::assess(&signals_from_csv(s, csv), &s.comfort)
}

/// Reads back the recorded series for the headline numbers (works on partial runs too).
fn quick_look(s: &Scenario, csv: &std::path::Path) -> QuickLook {
    let Ok(text) = std::fs::read_to_string(csv) else {
        return QuickLook::default();
    };
    let col = |name: &str| {
        crate::record::COLUMNS
            .iter()
            .position(|c| *c == name)
            .unwrap_or(0)
    };
    let (it, ilat, ith, ida) = (col("t"), col("lat_acc"), col("theta_v"), col("delta_a"));
    let tp = &s.track;
    let t_mid = (tp.straight_before_m + tp.transition_m + tp.curve_m / 2.0) / tp.speed();
    let mut q = QuickLook::default();
    let mut best = f64::INFINITY;
    for line in text.lines().skip(1) {
        let f: Vec<f64> = line
            .split(',')
            .map(|x| x.parse().unwrap_or(f64::NAN))
            .collect();
        if f.len() < crate::record::COLUMNS.len() {
            continue;
        }
        q.lat_acc_peak = q.lat_acc_peak.max(f[ilat].abs());
        q.delta_a_peak = q.delta_a_peak.max(f[ida].abs());
        if (f[it] - t_mid).abs() < best {
            best = (f[it] - t_mid).abs();
            q.lat_acc_mid_curve = f[ilat];
            q.theta_v_mid_curve = f[ith];
        }
    }
    q
}
