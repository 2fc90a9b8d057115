//! Launch and shut-down of the participants: their settings derived from the scenario, the
//! endpoints over either transport, and what each exit left behind.

use std::path::Path;
use std::time::Duration;

use actuator_proc::{Actuator, ActuatorInit};
use controller_proc::{Controller, ControllerInit};
use cosim::endpoint::{ExchangeCounts, ExitReport};
use cosim::ipc::placement::{self, Claim, Placement};
use cosim::ipc::{IpcError, IpcHub, IpcSettings, Launch};
use cosim::msg::{FromActuator, FromController, FromPlant, ToActuator, ToController, ToPlant};
use cosim::wait::WaitStrategy;
use cosim::{Endpoint, InProcess, Participant, Role};
use plant_proc::{Plant, PlantSettings};
use serde::Serialize;
use tiltsim_fmi::{ActuatorIo, ControllerIo, PlantIo};
use tiltsim_net::{NetHub, NetSettings};
use tiltsim_scenario::roles::RoleMap;
use tiltsim_scenario::scenario::{Execution, HandOver, Master, Scenario, Transport};

use super::{RunError, RunOptions};

/// The held (latest) outputs of every participant.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Held {
    /// Plant.
    pub p: FromPlant,
    /// Actuator.
    pub a: FromActuator,
    /// Controller.
    pub c: FromController,
}

/// The plant's endpoint.
pub(crate) type PlantEp = Box<dyn Endpoint<ToPlant, FromPlant>>;
/// The actuator's endpoint.
pub(crate) type ActuatorEp = Box<dyn Endpoint<ToActuator, FromActuator>>;
/// The controller's endpoint.
pub(crate) type ControllerEp = Box<dyn Endpoint<ToController, FromController>>;

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

/// The running participants, one typed endpoint each, and the iceoryx2 hub of an IPC run.
pub(crate) struct Participants {
    /// Plant.
    pub plant: PlantEp,
    /// Actuator.
    pub actuator: ActuatorEp,
    /// Controller.
    pub controller: ControllerEp,
    /// The transport's hub (IPC only).
    pub hub: Option<IpcHub>,
    /// The network's hub, when some participants are on other hosts (`[network]`).
    pub net: Option<NetHub>,
    /// Which participants run on the orchestrator's CPU (set by the CPU plan).
    shares_cpu: RoleMap<bool>,
    /// Which participants share one CPU of their own, yield it while they wait, and are asked
    /// one after the other: each cues the one asked after it (`cosim::ipc::supervise::CueWords`).
    cued: RoleMap<bool>,
    /// How the participants pinned together hand their CPU over while they wait, if they are.
    pub hand_over: Option<HandOver>,
    /// Where the processes run and how they wait (IPC only), for `timing.placement`.
    pub placement: Option<Placement>,
    /// The run's claim on its CPUs, released when the participants are dropped.
    _claim: Claim,
}

impl Participants {
    /// Process ids (this process's for in-process participants).
    pub fn pids(&self) -> RoleMap<u32> {
        RoleMap::new([self.plant.pid(), self.actuator.pid(), self.controller.pid()])
    }

    /// Which participants are on other hosts.
    pub fn remote(&self) -> RoleMap<bool> {
        RoleMap::new(Role::ALL.map(|r| self.net.as_ref().is_some_and(|n| n.is_remote(r))))
    }

    /// Records which participants now run on the orchestrator's CPU: the orchestrator yields
    /// at once while it waits for them.
    pub fn set_shares_cpu(&mut self, shared: RoleMap<bool>) {
        self.plant.set_shares_cpu(shared[Role::Plant]);
        self.actuator.set_shares_cpu(shared[Role::Actuator]);
        self.controller.set_shares_cpu(shared[Role::Controller]);
        for r in Role::ALL {
            self.cued[r] &= !shared[r];
        }
        self.shares_cpu = shared;
    }

    /// Which participants cue each other.
    pub fn cued(&self) -> &RoleMap<bool> {
        &self.cued
    }

    /// Lets the participants among `pending` that share the orchestrator's CPU answer first
    /// (their replies are waited for, not taken), while the others compute on theirs.
    pub fn await_colocated(&mut self, pending: RoleMap<bool>) {
        for r in Role::ALL {
            if pending[r] && self.shares_cpu[r] {
                match r {
                    Role::Plant => self.plant.await_pending(),
                    Role::Actuator => self.actuator.await_pending(),
                    Role::Controller => self.controller.await_pending(),
                }
            }
        }
    }

    /// Starved waits, re-sent requests and discarded repeats, per role.
    pub fn counts(&self) -> RoleMap<ExchangeCounts> {
        RoleMap::new([
            self.plant.counts(),
            self.actuator.counts(),
            self.controller.counts(),
        ])
    }

    /// Stops every participant still in place (a dead or hung one is killed and reaped);
    /// `lost` holds the exit reports of those already replaced by degraded-mode stand-ins.
    pub fn shut_down(&mut self, lost: RoleMap<Option<ExitReport>>) -> RoleMap<ExitReport> {
        let [p, a, c] = lost.into_array();
        RoleMap::new([
            p.unwrap_or_else(|| self.plant.shutdown()),
            a.unwrap_or_else(|| self.actuator.shutdown()),
            c.unwrap_or_else(|| self.controller.shutdown()),
        ])
    }
}

/// CPU time of this process, user + system (s).
pub(crate) fn cpu_self() -> f64 {
    // SAFETY: an all-zero rusage is valid; getrusage only writes into it.
    let mut u: libc::rusage = unsafe { core::mem::zeroed() };
    // SAFETY: RUSAGE_SELF with a valid pointer.
    unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    (u.ru_utime.tv_sec + u.ru_stime.tv_sec) as f64
        + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) as f64 * 1e-6
}

/// Starts the participants of `s` on its transport: in this process, or as processes of
/// `opts.participant_exe` connected over iceoryx2 with `prefix`.
pub(crate) fn start(
    s: &Scenario,
    opts: &RunOptions,
    prefix: &str,
) -> Result<Participants, RunError> {
    let inits = Inits::from(s);
    warn_missing_fmu_outputs(s);
    let mut net = open_network(s, opts, &inits)?;
    let mut ps = match s.run.transport {
        Transport::InProcess => start_in_process(s, opts, &inits, &mut net),
        Transport::Ipc => start_processes(s, opts, prefix, &inits, &mut net),
    }?;
    ps.net = net;
    Ok(ps)
}

/// The network's hub of a run with participants on other hosts (`[network]`): listening on
/// `network.listen`, with the run's secret (the caller's, or one drawn now and printed in the
/// command that joins).
fn open_network(
    s: &Scenario,
    opts: &RunOptions,
    inits: &Inits,
) -> Result<Option<NetHub>, RunError> {
    if s.network.is_local() {
        return Ok(None);
    }
    let (secret, drawn) = match &opts.network_secret {
        Some(secret) => (secret.clone(), false),
        None => (
            tiltsim_net::new_secret().map_err(RunError::io("/dev/urandom".into()))?,
            true,
        ),
    };
    let remote = s
        .network
        .remote
        .iter()
        .map(|&r| {
            let params = match r {
                Role::Plant => json(&inits.plant),
                Role::Actuator => json(&inits.actuator),
                Role::Controller => json(&inits.controller),
            };
            (r, params)
        })
        .collect();
    let listen = tiltsim_protocol::address::Address::parse(&s.network.listen).map_err(|why| {
        tiltsim_net::NetError::Participant(format!("network.listen {}: {why}", s.network.listen))
    })?;
    let hub = NetHub::open(
        NetSettings {
            listen,
            secret: secret.clone(),
            deadline: Duration::from_millis(s.run.deadline_ms),
            join_timeout: Duration::from_secs_f64(s.network.join_timeout_s),
            lease: Duration::from_millis(s.network.lease_ms),
        },
        remote,
    )?;
    for &r in &s.network.remote {
        let credentials = if drawn {
            format!("{}={secret} ", tiltsim_net::serve::SECRET_VAR)
        } else {
            String::new()
        };
        // Shown at the default verbosity: the run waits for the user here.
        tracing::warn!(
            "waiting for the {r} to join at {}: on its host run `{credentials}{}`{}",
            s.network.listen,
            hub.join_command(r),
            if drawn {
                ""
            } else {
                " with the run's secret in TILTSIM_SECRET or --secret-file"
            }
        );
    }
    Ok(Some(hub))
}

/// The endpoint of `role` when it joins from another host, once it has joined.
fn remote<I: cosim::msg::Message, O: cosim::msg::Message>(
    net: &mut Option<NetHub>,
    role: Role,
    opts: &RunOptions,
) -> Result<Option<tiltsim_net::NetEndpoint<I, O>>, RunError> {
    match net {
        Some(hub) if hub.is_remote(role) => Ok(Some(
            hub.await_join(role, Some(&opts.interrupt))
                .map_err(|e| match e {
                    tiltsim_net::NetError::Interrupted { role } => RunError::Interrupted { role },
                    e => RunError::Net(e),
                })?,
        )),
        _ => Ok(None),
    }
}

/// Reply fields an FMU does not provide are recorded as 0, and what its description lacks of
/// what tiltsim relies on: says so once, before the run, naming the FMU.
fn warn_missing_fmu_outputs(s: &Scenario) {
    for role in Role::ALL {
        let Some(init) = s.fmu_init(role) else {
            continue;
        };
        if let Ok((_, plan)) = tiltsim_fmi::import::check(&init) {
            if !plan.missing_outputs.is_empty() {
                tracing::warn!(
                    "the {role}'s FMU provides no {}: recorded as 0",
                    plan.missing_outputs.join(", ")
                );
            }
            for w in &plan.warnings {
                tracing::warn!(
                    "participants.{role}.fmu {}: {w}",
                    init.settings.fmu.display()
                );
            }
        }
    }
}

/// The participants as models (or FMUs) in this process.
fn start_in_process(
    s: &Scenario,
    opts: &RunOptions,
    inits: &Inits,
    net: &mut Option<NetHub>,
) -> Result<Participants, RunError> {
    // A model in this process, with the run's stall deadline and timing.
    fn local<P: Participant>(model: P, s: &Scenario, opts: &RunOptions) -> InProcess<P> {
        InProcess::new(model)
            .with_deadline(Duration::from_millis(s.run.deadline_ms))
            .timed(opts.timing)
    }
    let plant: PlantEp = match (remote(net, Role::Plant, opts)?, s.fmu_init(Role::Plant)) {
        (Some(ep), _) => Box::new(ep),
        (None, Some(init)) => Box::new(local(fmu_model::<PlantIo>(init)?, s, opts)),
        (None, None) => Box::new(local(Plant::new(&inits.plant), s, opts)),
    };
    let actuator: ActuatorEp = match (
        remote(net, Role::Actuator, opts)?,
        s.fmu_init(Role::Actuator),
    ) {
        (Some(ep), _) => Box::new(ep),
        (None, Some(init)) => Box::new(local(fmu_model::<ActuatorIo>(init)?, s, opts)),
        (None, None) => Box::new(local(Actuator::new(&inits.actuator), s, opts)),
    };
    let controller: ControllerEp = match (
        remote(net, Role::Controller, opts)?,
        s.fmu_init(Role::Controller),
    ) {
        (Some(ep), _) => Box::new(ep),
        (None, Some(init)) => Box::new(local(fmu_model::<ControllerIo>(init)?, s, opts)),
        (None, None) => Box::new(local(
            Controller::new(&inits.controller).map_err(RunError::Design)?,
            s,
            opts,
        )),
    };
    Ok(Participants {
        plant,
        actuator,
        controller,
        hub: None,
        net: None,
        shares_cpu: RoleMap::default(),
        cued: RoleMap::default(),
        hand_over: None,
        placement: None,
        _claim: Claim::none(),
    })
}

/// The participants as processes of `opts.participant_exe` (or its override for a role)
/// connected over iceoryx2 with `prefix`, after the files of dead runs are removed and the run
/// is placed among the other runs and work on the machine (`cosim::ipc::placement`).
fn start_processes(
    s: &Scenario,
    opts: &RunOptions,
    prefix: &str,
    inits: &Inits,
    net: &mut Option<NetHub>,
) -> Result<Participants, RunError> {
    // Files of runs whose orchestrator was killed before it could clean up.
    for p in cosim::ipc::remove_dead_runs() {
        tracing::info!("removed the files of dead run {p}");
    }
    // The owner file first: a claim left by a killed run is then removed with its files.
    cosim::ipc::claim_prefix(prefix)
        .map_err(|e| IpcError::Iceoryx(format!("owner file of {prefix}: {e}")))?;
    let (placement, claim) = placement::place(
        prefix,
        s.run.wait,
        s.run.pin_cpus,
        &cosim::ipc::allowed_cpus(),
        opts.realtime.is_some(),
    );
    tracing::info!("placement: {placement:?}");
    let hub = IpcHub::new(IpcSettings {
        prefix: prefix.to_string(),
        wait: placement.wait,
        deadline: Duration::from_millis(s.run.deadline_ms),
        ceiling: Duration::from_millis(s.run.hang_ceiling_ms),
        participant_cpu: placement.shared_participant_cpu(),
    })?
    .interrupted_by(opts.interrupt.clone())
    .logs_into(opts.out_dir.join(tiltsim_rundir::outdir::RUN_LOGS));
    if let Some(own) = placement.orchestrator_cpu {
        cosim::ipc::pin_to_cpu(own);
    }
    let startup = Duration::from_millis(s.run.startup_ms);
    let start = |role, init| Spawn {
        hub: &hub,
        s,
        opts,
        startup,
        role,
        init,
    };
    let plant: PlantEp = start(Role::Plant, json(&inits.plant)).or_join(net)?;
    let actuator: ActuatorEp = start(Role::Actuator, json(&inits.actuator)).or_join(net)?;
    let controller: ControllerEp = start(Role::Controller, json(&inits.controller)).or_join(net)?;
    if placement.reason == placement::Reason::FreeCpuEach {
        // Spinning, each alone on one of three CPUs; the kernel spreads them. A participant on
        // another host has no process here.
        for (role, pid) in [
            (Role::Plant, plant.pid()),
            (Role::Actuator, actuator.pid()),
            (Role::Controller, controller.pid()),
        ] {
            if !s.network.is_remote(role) {
                cosim::ipc::set_cpus_of(pid, &placement.participant_cpus);
            }
        }
    }
    if placement.wait == WaitStrategy::Paced {
        // Its naps end on time (the participants do the same).
        cosim::wait::tight_timer_slack();
    }
    // Under Gauss-Seidel each request waits for the previous answer, so the participant
    // asked next is known when one answers; under Jacobi the requests are out together.
    let together = placement.shared_participant_cpu().is_some()
        && placement.wait == WaitStrategy::Adaptive
        && s.run.execution == Execution::LockStep;
    let cue = together && s.run.master == Master::GaussSeidel && s.run.hand_over == HandOver::Cue;
    let hand_over = together.then_some(if cue { HandOver::Cue } else { HandOver::Yield });
    Ok(Participants {
        plant,
        actuator,
        controller,
        hub: Some(hub),
        net: None,
        shares_cpu: RoleMap::default(),
        // A participant on another host has no status words here to be cued in.
        cued: RoleMap::new(Role::ALL.map(|r| cue && !s.network.is_remote(r))),
        hand_over,
        placement: Some(placement),
        _claim: claim,
    })
}

/// A participant's process to start on a run's hub, unless it joins from another host.
struct Spawn<'a> {
    hub: &'a IpcHub,
    s: &'a Scenario,
    opts: &'a RunOptions,
    startup: Duration,
    role: Role,
    /// Its settings, as JSON.
    init: String,
}

impl Spawn<'_> {
    /// The participant's endpoint: its connection from another host through `net`, or its
    /// process started here.
    fn or_join<I: cosim::msg::Message + 'static, O: cosim::msg::Message + 'static>(
        self,
        net: &mut Option<NetHub>,
    ) -> Result<Box<dyn Endpoint<I, O>>, RunError> {
        if let Some(ep) = remote::<I, O>(net, self.role, self.opts)? {
            return Ok(Box::new(ep));
        }
        let launch = launch(self.s, self.opts, self.role, self.init);
        let ep = self
            .hub
            .spawn::<I, O>(self.role, &launch, self.startup)
            .map_err(started)?;
        Ok(Box::new(ep))
    }
}

/// Ends the participant logs of the run in `out_dir` (`logs/ROLE.log`, each participant
/// process's standard error), once its participants have stopped: removes the empty ones, and
/// `logs/` when that empties it, and returns the others as paths relative to `out_dir`
/// (`logs/plant.log`), in role order, for the run's outcome to name. A run whose directory is
/// removed afterwards (a sweep's sample, a run from Python without a directory) loses its logs
/// with it.
pub fn finish_logs(out_dir: &Path) -> Vec<String> {
    let logs = out_dir.join(tiltsim_rundir::outdir::RUN_LOGS);
    let mut kept = Vec::new();
    for role in Role::ALL {
        let path = IpcHub::log_file(&logs, role);
        match std::fs::metadata(&path) {
            Ok(m) if m.len() == 0 => {
                let _ = std::fs::remove_file(&path);
            }
            Ok(_) => {
                if let Ok(rel) = path.strip_prefix(out_dir) {
                    kept.push(rel.display().to_string());
                }
            }
            Err(_) => {}
        }
    }
    tiltsim_rundir::outdir::remove_if_empty(&logs);
    kept
}

/// How the process of `role` is started: `participant ROLE --params PARAMS`, or, for an FMU,
/// this executable's `fmu-participant` given the FMU's settings; `--realtime` when paced.
fn launch(s: &Scenario, opts: &RunOptions, role: Role, params: String) -> Launch {
    let (command, params) = match s.fmu_init(role) {
        Some(init) => ("fmu-participant", json(&init)),
        None => ("participant", params),
    };
    Launch {
        program: opts
            .participant_overrides
            .iter()
            .find(|(r, _)| *r == role)
            .map_or_else(|| opts.participant_exe.clone(), |(_, p)| p.clone()),
        args: [
            command.into(),
            role.name().into(),
            "--params".into(),
            params.into(),
        ]
        .into_iter()
        .chain(
            opts.realtime
                .into_iter()
                .flat_map(|p| ["--realtime".into(), p.to_string().into()]),
        )
        .collect(),
    }
}

/// A participant process that could not be started, or was stopped by an interrupt. An FMU
/// it was unpacking when it was stopped is removed.
fn started(e: cosim::ipc::IpcError) -> RunError {
    tiltsim_fmi::archive::remove_dead_unpacked();
    match e {
        cosim::ipc::IpcError::Interrupted { role } => RunError::Interrupted { role },
        e => RunError::Ipc(e),
    }
}

/// An FMU participant loaded in this process; its unpacking stops at an interrupt.
fn fmu_model<S: tiltsim_fmi::Samples>(
    init: tiltsim_fmi::FmuInit,
) -> Result<tiltsim_fmi::FmuParticipant<S>, RunError> {
    let role = init.role;
    tiltsim_fmi::FmuParticipant::<S>::new(init).map_err(|message| {
        if message.ends_with(tiltsim_fmi::archive::UNPACKING_STOPPED) {
            RunError::Interrupted { role }
        } else {
            RunError::Fmu { role, message }
        }
    })
}

/// Settings as the JSON a participant process receives. Plain settings structs (no maps with
/// non-string keys) always serialise.
fn json<T: Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}
