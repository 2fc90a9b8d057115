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
use cosim::msg::{now_ns, Message, FLAG_CRASH, FLAG_HELD, FLAG_HOLD_BAD_INPUT};
use cosim::msg::{
    FromActuator, FromController, FromPlant, Header, ToActuator, ToController, ToPlant,
};
use cosim::stats::{percentiles, Percentiles};
use cosim::{Endpoint, InProcess, Kind, LinkError, ProcessFault, Role};
use plant_proc::{Plant, PlantSettings};
use serde::Serialize;

use crate::degraded::{FallbackController, NeutralBar};
use crate::links::{
    Event, Fallback, FaultAction, LinkSet, OnBadData, OnFailure, ScheduledFault, EVENTS_HEADER,
};
use crate::record::Recorder;
use crate::scenario::{Master, Scenario, Transport};

/// How to run a scenario (command-line choices on top of the file).
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Output directory.
    pub out_dir: PathBuf,
    /// Executable that serves `participant ROLE ...` (normally `tiltsim` itself).
    pub participant_exe: PathBuf,
    /// Other executables for some roles (test participants that misbehave on purpose).
    pub participant_overrides: Vec<(Role, PathBuf)>,
    /// iceoryx2 prefix; a unique one is made when `None`.
    pub ipc_prefix: Option<String>,
    /// Set by Ctrl-C.
    pub interrupt: Arc<AtomicBool>,
    /// Draw `plots/` after the run.
    pub plots: bool,
    /// Write `trace.csv` (every exchange's timestamps) and the latency histogram.
    pub trace: bool,
    /// Run the lock-step at this many simulated seconds per wall second.
    pub pace: Option<f64>,
}

impl RunOptions {
    /// Options for a run into `out_dir` with participants served by `participant_exe`: a
    /// unique iceoryx2 prefix, plots drawn, no interrupt flag shared.
    pub fn new(out_dir: PathBuf, participant_exe: PathBuf) -> Self {
        RunOptions {
            out_dir,
            participant_exe,
            participant_overrides: Vec::new(),
            ipc_prefix: None,
            interrupt: Arc::new(AtomicBool::new(false)),
            plots: true,
            trace: false,
            pace: None,
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
    /// Every step done, but a participant was lost and replaced by its degraded mode.
    Degraded,
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
    /// Wall-clock latency of each participant's exchanges (request, reply, round trip; µs).
    pub link_latency: Vec<LinkLatency>,
    /// Real-time pacing (`--pace`), every tick counted.
    pub pacing: Option<PacingReport>,
    /// The MPC's QP solver (absent for controllers without one).
    pub controller_solver: Option<SolverReport>,
    /// Ride comfort (Table 4 rows), from the recorded series.
    pub comfort: crate::comfort::Comfort,
    /// Whether the numbers are valid: oscillation, bump stop, drive limits, chopper, P_CT range.
    pub flags: crate::validity::Flags,
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
                command_period_s: s.controller.period_s,
            },
            controller: s.controller_init(),
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
        Transport::InProcess => {
            let d = Duration::from_millis(s.run.deadline_ms);
            Ok(Participants {
                plant: Box::new(InProcess::new(Plant::new(&inits.plant)).with_deadline(d)),
                actuator: Box::new(InProcess::new(Actuator::new(&inits.actuator)).with_deadline(d)),
                controller: Box::new(
                    InProcess::new(Controller::new(&inits.controller).map_err(RunError::Design)?)
                        .with_deadline(d),
                ),
                hub: None,
            })
        }
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
                program: opts
                    .participant_overrides
                    .iter()
                    .find(|(r, _)| *r == role)
                    .map_or_else(|| opts.participant_exe.clone(), |(_, p)| p.clone()),
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

/// Wall-clock timing of the exchanges with one participant (µs).
#[derive(Default)]
struct LinkClock {
    /// Orchestrator sent the request → participant took it.
    request: Vec<f64>,
    /// Participant sent the reply → orchestrator had it.
    reply: Vec<f64>,
    /// Whole exchange as the orchestrator saw it.
    round_trip: Vec<f64>,
}

/// One exchange of the trace (`trace.csv`); times in ns from the start of the loop.
struct TraceRow {
    step: u64,
    role: Role,
    sent: u64,
    received: u64,
    started: u64,
    finished: u64,
    reply_sent: u64,
    reply_received: u64,
}

/// Everything the lock-step loop keeps besides the participants.
struct Loop<'a> {
    s: &'a Scenario,
    links: LinkSet,
    events: Vec<Event>,
    compute: Compute,
    clocks: [LinkClock; 3],
    trace: Option<Vec<TraceRow>>,
    origin_ns: u64,
    /// Flags for the next request of each role (crash faults, bad-data policy).
    flags: [u32; 3],
    /// Exit reports of participants replaced by degraded-mode stand-ins.
    lost: [Option<ExitReport>; 3],
    degraded: bool,
    overhead: Vec<f64>,
    ticks: Vec<f64>,
    pacing: Option<Pacing>,
    /// The actuator's limit bits of the previous tick (protection events on rising edges).
    drive_bits: u32,
}

fn idx(r: Role) -> usize {
    match r {
        Role::Plant => 0,
        Role::Actuator => 1,
        Role::Controller => 2,
    }
}

impl Loop<'_> {
    /// Logs the drive's protections as they begin: an over-current or over-voltage trip and
    /// the braking chopper switching on (value: the phase-current peak, A, or link voltage, V).
    fn drive_events(&mut self, k: u64, a: &FromActuator) {
        use actuator_proc::bldc::limit;
        let rising = a.limits & !self.drive_bits;
        self.drive_bits = a.limits;
        for (bit, name, value, detail) in [
            (
                limit::OVERCURRENT_TRIP,
                "overcurrent-trip",
                a.phase_current_peak,
                "a phase current passed the current limit plus half the band; gates blocked",
            ),
            (
                limit::OVERVOLTAGE,
                "overvoltage-trip",
                a.v_dc,
                "the DC link passed its over-voltage trip level; gates blocked",
            ),
            (
                limit::CHOPPER,
                "chopper-on",
                a.v_dc,
                "the DC link reached the chopper threshold; braking energy dumped",
            ),
        ] {
            if rising & bit != 0 {
                self.event(k, "actuator", name, value, detail.into());
            }
        }
    }

    fn event(&mut self, k: u64, source: &str, event: &'static str, value: f64, detail: String) {
        self.events.push(Event {
            step: k,
            t: k as f64 * self.s.run.dt_s,
            source: source.to_string(),
            event,
            value,
            detail,
        });
    }

    /// Sends one request with this tick's flags; returns the send time.
    fn post<I: Message, O: Message>(
        &mut self,
        ep: &mut Box<dyn Endpoint<I, O>>,
        mut req: I,
    ) -> Result<u64, LinkError> {
        let role = ep.role();
        req.header_mut().flags |= std::mem::take(&mut self.flags[idx(role)]);
        if self.s.faults.on_bad_data == OnBadData::Hold {
            req.header_mut().flags |= FLAG_HOLD_BAD_INPUT;
        }
        let t0 = now_ns();
        ep.send(&req)?;
        Ok(t0)
    }

    /// Receives the reply to a request sent at `t0`, logs held bad data, records timing.
    fn collect<I: Message, O: Message>(
        &mut self,
        ep: &mut Box<dyn Endpoint<I, O>>,
        k: u64,
        kind: Kind,
        t0: u64,
    ) -> Result<O, LinkError> {
        let role = ep.role();
        let reply = ep.receive(k, kind)?;
        let t3 = now_ns();
        let h = *reply.header();
        if h.flags & FLAG_HELD != 0 {
            self.event(
                k,
                role.name(),
                "bad-input-held",
                f64::NAN,
                format!(
                    "non-finite `{}` in {}; last good input used",
                    cosim::endpoint::field_name::<I>(h.field),
                    I::NAME
                ),
            );
        }
        let us = |a: u64, b: u64| b.saturating_sub(a) as f64 * 1e-3;
        let c = &mut self.clocks[idx(role)];
        c.request.push(us(t0, h.recv_ns));
        c.reply.push(us(h.sent_ns, t3));
        c.round_trip.push(us(t0, t3));
        if let Some(tr) = &mut self.trace {
            let rel = |t: u64| t.saturating_sub(self.origin_ns);
            tr.push(TraceRow {
                step: k,
                role,
                sent: rel(t0),
                received: rel(h.recv_ns),
                started: rel(h.recv_ns),
                finished: rel(h.recv_ns + h.compute_ns),
                reply_sent: rel(h.sent_ns),
                reply_received: rel(t3),
            });
        }
        Ok(reply)
    }

    /// One request and its reply.
    fn exchange<I: Message, O: Message>(
        &mut self,
        ep: &mut Box<dyn Endpoint<I, O>>,
        req: I,
        kind: Kind,
    ) -> Result<O, LinkError> {
        let k = req.header().step;
        let t0 = self.post(ep, req)?;
        self.collect(ep, k, kind, t0)
    }

    /// Replaces a failed participant by its degraded-mode stand-in when the scenario says
    /// so; otherwise returns the error.
    fn degrade(
        &mut self,
        ps: &mut Participants,
        h: &Held,
        k: u64,
        e: LinkError,
    ) -> Result<(), LinkError> {
        let role = e.role();
        if self.s.faults.on_failure != OnFailure::Degrade
            || role == Role::Plant
            || self.lost[idx(role)].is_some()
        {
            return Err(e);
        }
        let f = &self.s.faults;
        let detail = match role {
            Role::Actuator => {
                let old = std::mem::replace(
                    &mut ps.actuator,
                    Box::new(InProcess::new(NeutralBar::new(
                        h.a.delta_a,
                        f.neutral_ramp_s,
                        self.s.run.dt_s,
                    ))),
                );
                self.lost[1] = Some(shutdown_box(old));
                format!("bar ramps to neutral over {} s", f.neutral_ramp_s)
            }
            _ => {
                let ramp = match f.controller_fallback {
                    Fallback::Neutral => Some(f.neutral_ramp_s),
                    Fallback::Hold => None,
                };
                let old = std::mem::replace(
                    &mut ps.controller,
                    Box::new(InProcess::new(FallbackController::new(
                        h.c.delta_a_cmd,
                        ramp,
                        self.s.controller.period_s,
                    ))),
                );
                self.lost[2] = Some(shutdown_box(old));
                match ramp {
                    Some(r) => format!("bar command ramps to neutral over {r} s"),
                    None => "last bar command held".into(),
                }
            }
        };
        self.event(
            k,
            role.name(),
            "participant-lost",
            f64::NAN,
            e.cause().into(),
        );
        self.event(k, role.name(), "degraded", f64::NAN, detail);
        tracing::warn!("{e}; continuing degraded");
        self.degraded = true;
        Ok(())
    }

    /// Applies the faults scheduled for tick `k`.
    fn inject(&mut self, ps: &mut Participants, k: u64) {
        let dt = self.s.run.dt_s;
        let due: Vec<ScheduledFault> = self
            .s
            .faults
            .schedule
            .iter()
            .filter(|f| ((f.at_s / dt).round().max(0.0) as u64) == k)
            .cloned()
            .collect();
        for f in due {
            let Some(role) = Role::parse(&f.participant) else {
                continue;
            };
            if self.lost[idx(role)].is_some() {
                continue;
            }
            let fault = match f.action {
                FaultAction::Kill => Some(ProcessFault::Kill),
                FaultAction::Stall => Some(ProcessFault::Stall(Duration::from_secs_f64(f.stall_s))),
                FaultAction::Crash => {
                    self.flags[idx(role)] |= FLAG_CRASH;
                    None
                }
            };
            if let Some(fault) = fault {
                match role {
                    Role::Plant => ps.plant.inject(fault),
                    Role::Actuator => ps.actuator.inject(fault),
                    Role::Controller => ps.controller.inject(fault),
                }
            }
            let value = if f.action == FaultAction::Stall {
                f.stall_s
            } else {
                f64::NAN
            };
            self.event(
                k,
                role.name(),
                "fault-injected",
                value,
                format!("{:?}", f.action).to_lowercase(),
            );
        }
    }
}

fn shutdown_box<I: Message, O: Message>(mut ep: Box<dyn Endpoint<I, O>>) -> ExitReport {
    ep.shutdown()
}

/// Real-time pacing of the loop (`--pace`).
struct Pacing {
    factor: f64,
    overruns: u64,
    late_us: Vec<f64>,
}

/// What `--pace` achieved, every tick counted.
#[derive(Debug, Clone, Serialize)]
pub struct PacingReport {
    /// Requested simulated seconds per wall second.
    pub factor: f64,
    /// Ticks that finished after their wall-clock deadline.
    pub overruns: u64,
    /// Ticks paced.
    pub ticks: u64,
    /// How late the late ticks were (µs).
    pub lateness_us: Percentiles,
    /// Simulated time over wall time of the whole loop.
    pub achieved_realtime_factor: f64,
}

/// Per-link wall-clock latency (µs) of one participant's exchanges.
#[derive(Debug, Clone, Serialize)]
pub struct LinkLatency {
    /// Participant.
    pub participant: Role,
    /// Request: orchestrator sent → participant received.
    pub request_us: Percentiles,
    /// Reply: participant sent → orchestrator received.
    pub reply_us: Percentiles,
    /// Whole exchange seen by the orchestrator.
    pub round_trip_us: Percentiles,
}

/// Sleeps until the monotonic instant `target`, spinning the last 100 µs.
fn wait_until(target: Instant) {
    loop {
        let now = Instant::now();
        if now >= target {
            return;
        }
        let left = target - now;
        if left > Duration::from_micros(200) {
            std::thread::sleep(left - Duration::from_micros(100));
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Steps every tick; returns the error that stopped it, if any.
fn lockstep(
    lp: &mut Loop,
    ps: &mut Participants,
    rec: &mut Recorder,
    interrupt: &AtomicBool,
) -> Result<(), LinkError> {
    let s = lp.s;
    // Initial outputs at t_0.
    let init = (|| -> Result<Held, LinkError> {
        let p = lp.exchange(
            &mut ps.plant,
            ToPlant {
                header: hdr(0, Kind::Init),
                ..Default::default()
            },
            Kind::Init,
        )?;
        let a = lp.exchange(
            &mut ps.actuator,
            ToActuator {
                header: hdr(0, Kind::Init),
                ..Default::default()
            },
            Kind::Init,
        )?;
        let c = lp.exchange(
            &mut ps.controller,
            ToController {
                header: hdr(0, Kind::Init),
                ..Default::default()
            },
            Kind::Init,
        )?;
        Ok(Held { p, a, c })
    })();
    let mut h = init?;
    let n = s.steps();
    let c_period = s.controller_period_ticks();
    let dt = s.run.dt_s;
    let loop_start = Instant::now();
    for k in 0..n {
        if interrupt.load(Ordering::Relaxed) {
            return Ok(());
        }
        if let Some(p) = &lp.pacing {
            wait_until(loop_start + Duration::from_secs_f64(k as f64 * dt / p.factor));
        }
        let started = Instant::now();
        lp.inject(ps, k);
        let c_due = k % c_period == 0;
        let step = hdr(k, Kind::Step);
        let t = k as f64 * dt;
        // The links carry this tick's values: what each sender last produced.
        let meas = lp.links.links[2].carry(k, t, h.p.theta_v_meas, &mut lp.events);
        let twist = lp.links.links[3].carry(k, t, h.p.psi, &mut lp.events);
        let to_c = ToController {
            header: step,
            t: h.p.t,
            s: h.p.s,
            theta_v_meas: meas,
        };
        let mut cc = 0u64;
        let mut rx = [0.0; 4];
        rx[2] = meas;
        rx[3] = twist;
        // Each exchange: on failure, the degraded-mode stand-in takes over and the same
        // request is answered by it (or the error ends the run).
        macro_rules! ask {
            ($ep:ident, $req:expr) => {{
                let req = $req;
                match lp.exchange(&mut ps.$ep, req, Kind::Step) {
                    Ok(r) => r,
                    Err(e) => {
                        lp.degrade(ps, &h, k, e)?;
                        lp.exchange(&mut ps.$ep, req, Kind::Step)?
                    }
                }
            }};
        }
        macro_rules! post {
            ($ep:ident, $req:expr) => {{
                match lp.post(&mut ps.$ep, $req) {
                    Ok(t0) => Some(t0),
                    Err(e) => {
                        lp.degrade(ps, &h, k, e)?;
                        None
                    }
                }
            }};
        }
        macro_rules! collect {
            ($ep:ident, $req:expr, $t0:expr) => {{
                let req = $req;
                let got = match $t0 {
                    Some(t0) => lp.collect(&mut ps.$ep, k, Kind::Step, t0),
                    None => lp.exchange(&mut ps.$ep, req, Kind::Step),
                };
                match got {
                    Ok(r) => r,
                    Err(e) => {
                        lp.degrade(ps, &h, k, e)?;
                        lp.exchange(&mut ps.$ep, req, Kind::Step)?
                    }
                }
            }};
        }
        match s.run.master {
            // Gauss-Seidel: controller, actuator, plant in turn, each with the newest output.
            Master::GaussSeidel => {
                if c_due {
                    h.c = ask!(controller, to_c);
                    cc = h.c.header.compute_ns;
                }
                rx[0] = lp.links.links[0].carry(k, t, h.c.delta_a_cmd, &mut lp.events);
                h.a = ask!(
                    actuator,
                    ToActuator {
                        header: step,
                        delta_a_cmd: rx[0],
                        psi: twist,
                    }
                );
                rx[1] = lp.links.links[1].carry(k, t, h.a.delta_a, &mut lp.events);
                h.p = ask!(
                    plant,
                    ToPlant {
                        header: step,
                        delta_a: rx[1],
                    }
                );
            }
            // Jacobi: every request from the previous outputs first, then every reply.
            Master::Jacobi => {
                rx[0] = lp.links.links[0].carry(k, t, h.c.delta_a_cmd, &mut lp.events);
                rx[1] = lp.links.links[1].carry(k, t, h.a.delta_a, &mut lp.events);
                let to_a = ToActuator {
                    header: step,
                    delta_a_cmd: rx[0],
                    psi: twist,
                };
                let to_p = ToPlant {
                    header: step,
                    delta_a: rx[1],
                };
                let tc = if c_due { post!(controller, to_c) } else { None };
                let ta = post!(actuator, to_a);
                let tp = post!(plant, to_p);
                if c_due {
                    h.c = collect!(controller, to_c, tc);
                    cc = h.c.header.compute_ns;
                }
                h.a = collect!(actuator, to_a, ta);
                h.p = collect!(plant, to_p, tp);
            }
        }
        let (cp, ca) = (h.p.header.compute_ns, h.a.header.compute_ns);
        let crit = match s.run.master {
            Master::GaussSeidel => (cp + ca + cc) as f64 * 1e-3,
            Master::Jacobi => cp.max(ca).max(cc) as f64 * 1e-3,
        };
        let comp = &mut lp.compute;
        comp.plant.push(cp as f64 * 1e-3);
        comp.actuator.push(ca as f64 * 1e-3);
        lp.drive_events(k, &h.a);
        let comp = &mut lp.compute;
        if c_due {
            comp.controller.push(cc as f64 * 1e-3);
            match h.c.solver_status {
                0 => {}
                1 => comp.solver_iterations.push(h.c.solver_iterations as f64),
                _ => {
                    comp.solver_iterations.push(h.c.solver_iterations as f64);
                    comp.solver_failures += 1;
                }
            }
        }
        let tick_us = started.elapsed().as_secs_f64() * 1e6;
        lp.ticks.push(tick_us);
        lp.overhead.push((tick_us - crit).max(0.0));
        if let Some(p) = &mut lp.pacing {
            let deadline = loop_start + Duration::from_secs_f64((k + 1) as f64 * dt / p.factor);
            let now = Instant::now();
            if now > deadline {
                p.overruns += 1;
                p.late_us.push((now - deadline).as_secs_f64() * 1e6);
            }
        }
        rec.write(&crate::record::Row::new(k, &h.p, &h.a, &h.c, &rx))
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
    let mut lp = Loop {
        s,
        links: LinkSet::new(&s.links, s.run.seed),
        events: LinkSet::describe(&s.links),
        compute: Compute {
            plant: Vec::new(),
            actuator: Vec::new(),
            controller: Vec::new(),
            solver_iterations: Vec::new(),
            solver_failures: 0,
        },
        clocks: Default::default(),
        trace: opts.trace.then(Vec::new),
        origin_ns: now_ns(),
        flags: [0; 3],
        lost: [None, None, None],
        degraded: false,
        overhead: Vec::with_capacity(s.steps() as usize),
        ticks: Vec::with_capacity(s.steps() as usize),
        drive_bits: 0,
        pacing: opts.pace.map(|factor| Pacing {
            factor,
            overruns: 0,
            late_us: Vec::new(),
        }),
    };
    let outcome = lockstep(&mut lp, &mut ps, &mut rec, &opts.interrupt);
    let wall = loop_started.elapsed().as_secs_f64();
    let _ = rec.flush();
    if let Err(e) = &outcome {
        let k = rec.rows();
        lp.event(k, e.role().name(), "run-failed", f64::NAN, e.cause().into());
    }
    let events_path = opts.out_dir.join("events.csv");
    let mut text = String::from(EVENTS_HEADER);
    text.push('\n');
    for e in &lp.events {
        text.push_str(&e.line());
        text.push('\n');
    }
    std::fs::write(&events_path, text).map_err(io(events_path))?;
    if let Some(tr) = &lp.trace {
        write_trace(&opts.out_dir, tr, s.run.dt_s, &lp.clocks)
            .map_err(io(opts.out_dir.join("trace.csv")))?;
    }
    let Loop {
        mut compute,
        clocks,
        lost,
        degraded,
        overhead,
        mut ticks,
        pacing,
        ..
    } = lp;

    let (status, error) = match &outcome {
        Ok(_) if opts.interrupt.load(Ordering::Relaxed) => (
            Status::Interrupted,
            Some("interrupted by Ctrl-C".to_string()),
        ),
        Ok(_) if degraded => (
            Status::Degraded,
            Some("a participant was lost; the run continued degraded (events.csv)".into()),
        ),
        Ok(_) => (Status::Completed, None),
        Err(e) => (Status::Failed, Some(e.to_string())),
    };
    // Stop every participant (a dead or hung one is killed and reaped), then clean up.
    let [l0, l1, l2] = lost;
    let exits = [
        l0.unwrap_or_else(|| ps.plant.shutdown()),
        l1.unwrap_or_else(|| ps.actuator.shutdown()),
        l2.unwrap_or_else(|| ps.controller.shutdown()),
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
    let steps_done = rec.rows();
    let pacing = pacing.map(|mut p| PacingReport {
        factor: p.factor,
        overruns: p.overruns,
        ticks: steps_done,
        lateness_us: percentiles(&mut p.late_us),
        achieved_realtime_factor: if wall > 0.0 {
            steps_done as f64 * s.run.dt_s / wall
        } else {
            0.0
        },
    });
    let link_latency = Role::ALL
        .iter()
        .zip(clocks)
        .map(|(r, mut c)| LinkLatency {
            participant: *r,
            request_us: percentiles(&mut c.request),
            reply_us: percentiles(&mut c.reply),
            round_trip_us: percentiles(&mut c.round_trip),
        })
        .collect();
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
    let results = quick_look(s, &opts.out_dir);
    let comfort = comfort_of(s, &opts.out_dir);
    let flags = flags_of(s, &opts.out_dir, &comfort);
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
        link_latency,
        pacing,
        controller_solver: solver,
        comfort,
        flags,
        ipc_prefix: prefix,
        leftover_ipc_files: leftover,
    })
}

/// Writes `trace.csv` and the latency histogram `plots/latency_histogram.{svg,png}`.
fn write_trace(
    dir: &std::path::Path,
    rows: &[TraceRow],
    dt: f64,
    clocks: &[LinkClock; 3],
) -> std::io::Result<()> {
    use std::fmt::Write as _;
    let mut t = String::from(
        "step,t,participant,request_sent_ns,request_received_ns,step_started_ns,step_finished_ns,reply_sent_ns,reply_received_ns\n",
    );
    for r in rows {
        let _ = writeln!(
            t,
            "{},{},{},{},{},{},{},{},{}",
            r.step,
            r.step as f64 * dt,
            r.role,
            r.sent,
            r.received,
            r.started,
            r.finished,
            r.reply_sent,
            r.reply_received
        );
    }
    std::fs::write(dir.join("trace.csv"), t)?;
    // Histogram of the request latency per participant, 0.5 µs bins up to the 99.9th
    // percentile of all of them.
    let mut all: Vec<f64> = clocks
        .iter()
        .flat_map(|c| c.request.iter().copied())
        .collect();
    all.sort_by(|a, b| a.total_cmp(b));
    let top = all
        .get(((all.len() as f64) * 0.999) as usize)
        .copied()
        .unwrap_or(1.0)
        .max(1.0);
    let bin = (top / 80.0).max(0.05);
    let nb = (top / bin).ceil() as usize + 1;
    let x: Vec<f64> = (0..nb).map(|i| (i as f64 + 0.5) * bin).collect();
    let lines = Role::ALL
        .iter()
        .zip(clocks)
        .enumerate()
        .map(|(k, (role, c))| {
            let mut h = vec![0.0; nb];
            for v in &c.request {
                let i = ((v / bin) as usize).min(nb - 1);
                h[i] += 1.0;
            }
            crate::plot::Line {
                label: role.name(),
                y: h,
                colour: crate::plot::PALETTE[k],
                dashed: false,
            }
        })
        .collect();
    let chart = crate::plot::Chart {
        title: "Request latency: orchestrator sent → participant received",
        x_label: "latency (µs)",
        y_label: "exchanges per bin",
        lines,
        bands: Vec::new(),
        note: "",
    };
    let plots = dir.join("plots");
    std::fs::create_dir_all(&plots)?;
    crate::plot::write_chart(&plots, "latency_histogram", &chart, &x)?;
    Ok(())
}

/// Times (s) at which the vehicle enters the first transition, the steady curve, the second
/// transition and the final straight.
fn section_times(tp: &vehicle_model::TrackParams) -> [f64; 4] {
    let v = tp.speed();
    let t1 = tp.straight_before_m / v;
    let t2 = t1 + tp.transition_m / v;
    let t3 = t2 + tp.curve_m / v;
    [t1, t2, t3, t3 + tp.transition_m / v]
}

/// Reads a run's recorded series (`dir/timeseries.csv`) back into the signals the comfort
/// assessment needs.
pub fn signals_from_run(s: &Scenario, dir: &std::path::Path) -> crate::comfort::Signals {
    use crate::comfort::Signals;
    let Ok(rows) = read_rows(dir) else {
        return Signals::default();
    };
    // The reference of eq 18 at each row's own position, continuous: the recorded θ_ref is
    // the controller's, held over its period (50 ms for the MPC), whose steps would read as
    // roll-speed spikes of the reference.
    let reference: Vec<f64> = match controller_proc::Controller::new(&s.controller_init()) {
        Ok(c) => rows.iter().map(|r| c.reference_at(r.s)).collect(),
        Err(_) => rows.iter().map(|r| r.theta_ref).collect(),
    };
    let veh = vehicle_model::Vehicle::new(s.vehicle.clone(), s.track.speed());
    let n = rows.len();
    let dt = s.run.dt_s;
    // Central difference of a per-row quantity (one-sided at the ends).
    let deriv = |k: usize, f: &dyn Fn(usize) -> f64| {
        if n < 2 {
            return 0.0;
        }
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        (f(b) - f(a)) / ((b - a) as f64 * dt)
    };
    let (h1, h2) = (s.vehicle.h1, s.vehicle.h2);
    let [t1, t2, t3, t4] = section_times(&s.track);
    Signals {
        t: rows.iter().map(|r| r.t).collect(),
        lat_acc: rows.iter().map(|r| r.lat_acc).collect(),
        lat_acc_ref: rows
            .iter()
            .zip(&reference)
            .map(|(r, th)| veh.lateral_acceleration(*th, r.curvature, r.cant))
            .collect(),
        roll_speed: (0..n)
            .map(|k| rows[k].dtheta_v + deriv(k, &|i| rows[i].cant))
            .collect(),
        roll_speed_ref: (0..n)
            .map(|k| deriv(k, &|i| rows[i].cant + reference[i]))
            .collect(),
        deflection: rows
            .iter()
            .map(|r| r.y_v - h1 * r.theta_v - r.y_b - h2 * r.theta_b)
            .collect(),
        transitions: vec![(t1, t2), (t3, t4)],
    }
}

pub use crate::record::read_rows;

pub(crate) fn bands(s: &Scenario) -> Vec<(f64, f64, bool)> {
    let [t1, t2, t3, t4] = section_times(&s.track);
    vec![(t1, t2, false), (t2, t3, true), (t3, t4, false)]
}

/// Writes `dir/plots/*.svg` and `*.png` from `dir/timeseries.csv`.
pub fn write_plots(s: &Scenario, dir: &std::path::Path) -> std::io::Result<Vec<PathBuf>> {
    let rows = read_rows(dir)?;
    crate::plot::write_run_plots(dir, &rows, &bands(s), s.controller.u_max_deg)
}

/// Writes the figures that put several runs side by side (`out/plots/compare_*`): lateral
/// acceleration, body roll and bar angle of every run on one time axis. `runs` are (label,
/// scenario, run directory); the shaded sections are the first run's.
pub fn write_compare_plots(
    runs: &[(String, Scenario, PathBuf)],
    out: &std::path::Path,
) -> std::io::Result<Vec<PathBuf>> {
    use crate::plot::{Chart, Line, PALETTE};
    use crate::record::Row;
    let mut data = Vec::new();
    for (label, _, dir) in runs {
        data.push((label.as_str(), read_rows(dir)?));
    }
    let n = data.iter().map(|(_, r)| r.len()).min().unwrap_or(0);
    let t: Vec<f64> = data
        .first()
        .map(|(_, r)| r[..n].iter().map(|x| x.t).collect())
        .unwrap_or_default();
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots)?;
    let bands = runs.first().map(|r| bands(&r.1)).unwrap_or_default();
    let mut files = Vec::new();
    /// (file name, title, y label, column, scale).
    type Figure = (
        &'static str,
        &'static str,
        &'static str,
        fn(&Row) -> f64,
        f64,
    );
    let figures: [Figure; 3] = [
        (
            "compare_lateral_acceleration",
            "Passenger lateral acceleration of each run (Figs 14-15)",
            "lateral acceleration (m/s²)",
            |r| r.lat_acc,
            1.0,
        ),
        (
            "compare_body_roll",
            "Carbody roll of each run (Fig. 16)",
            "roll θ_v (deg)",
            |r| r.theta_v,
            1f64.to_degrees(),
        ),
        (
            "compare_control",
            "Achieved anti-roll-bar angle of each run (Fig. 17)",
            "bar angle δ_a (deg)",
            |r| r.delta_a,
            1f64.to_degrees(),
        ),
    ];
    for (name, title, y_label, column, scale) in figures {
        let chart = Chart {
            title,
            x_label: "time (s)",
            y_label,
            lines: data
                .iter()
                .enumerate()
                .map(|(k, (label, rows))| Line {
                    label,
                    y: rows[..n].iter().map(|r| column(r) * scale).collect(),
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

/// The validity flags of a finished run, from its recorded series.
pub fn flags_of(
    s: &Scenario,
    dir: &std::path::Path,
    comfort: &crate::comfort::Comfort,
) -> crate::validity::Flags {
    let Ok(rows) = read_rows(dir) else {
        return crate::validity::Flags::default();
    };
    let get = |f: fn(&crate::record::Row) -> f64| -> Vec<f64> { rows.iter().map(f).collect() };
    let inputs = crate::validity::FlagInputs {
        dt: s.run.dt_s,
        roll_error: get(|r| r.theta_v - r.theta_ref),
        reference: get(|r| r.theta_ref),
        deflection: signals_from_run(s, dir).deflection,
        clearance: s.comfort.bump_stop_m,
        limits: rows.iter().map(|r| r.actuator_limits).collect(),
        phase_current_peak: get(|r| r.phase_current_peak),
        torque: get(|r| r.motor_torque),
        dc_power: get(|r| r.dc_power),
        chopper_power: get(|r| r.chopper_power),
        v_dc: get(|r| r.v_dc),
    };
    crate::validity::assess(&inputs, comfort)
}

fn comfort_of(s: &Scenario, dir: &std::path::Path) -> crate::comfort::Comfort {
    crate::comfort::assess(&signals_from_run(s, dir), &s.comfort)
}

/// Reads back the recorded series for the headline numbers (works on partial runs too).
fn quick_look(s: &Scenario, dir: &std::path::Path) -> QuickLook {
    let Ok(rows) = read_rows(dir) else {
        return QuickLook::default();
    };
    let tp = &s.track;
    let t_mid = (tp.straight_before_m + tp.transition_m + tp.curve_m / 2.0) / tp.speed();
    let mut q = QuickLook::default();
    let mut best = f64::INFINITY;
    for r in &rows {
        q.lat_acc_peak = q.lat_acc_peak.max(r.lat_acc.abs());
        q.delta_a_peak = q.delta_a_peak.max(r.delta_a.abs());
        if (r.t - t_mid).abs() < best {
            best = (r.t - t_mid).abs();
            q.lat_acc_mid_curve = r.lat_acc;
            q.theta_v_mid_curve = r.theta_v;
        }
    }
    q
}
