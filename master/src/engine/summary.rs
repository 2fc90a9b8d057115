//! The schema of `summary.json`: what a run reports about itself. The engine fills the run's
//! own part (participants, steps, timing, latency, pacing, solver); the caller's analysis step
//! fills `results`, `comfort` and `flags` from the recorded series (`tiltsim_report::analysis`).

use cosim::endpoint::ExitReport;
use cosim::endpoint::{CueCounts, LostSamples};
use cosim::stats::Percentiles;
use cosim::wait::WaitStrategy;
use cosim::Role;
use serde::Serialize;
use tiltsim_scenario::scenario::{Master, Transport};

use super::Status;

/// `summary.json` → `network`: the run's participants on other hosts.
#[derive(Debug, Clone, Serialize)]
pub struct NetworkReport {
    /// Where the orchestrator listened.
    pub listen: String,
    /// The run's key, in every key expression of the run.
    pub run_key: String,
    /// The participants that joined, in role order.
    pub joined: Vec<tiltsim_net::Joined>,
    /// The participants refused at joining, in arrival order.
    pub refused: Vec<tiltsim_net::Refusal>,
    /// Others that tried to reach the run and were refused, in order: connections without
    /// credentials or with wrong ones, sessions with another role's credentials, second
    /// sessions of a role (docs/network.md, "Who can touch a run").
    pub attempts: Vec<tiltsim_net::Attempt>,
}

impl NetworkReport {
    /// The report of a run's network hub.
    pub fn of(hub: &tiltsim_net::NetHub) -> Self {
        NetworkReport {
            listen: hub.settings().listen.to_string(),
            run_key: hub.run_key().to_string(),
            joined: hub.joined(),
            refused: hub.refusals(),
            attempts: hub.attempts(),
        }
    }
}

impl NetworkReport {
    /// Logs the attempts in `events`, each at the step the run was at when it was seen.
    pub fn log_attempts(&self, events: &mut tiltsim_formats::events::EventLog) {
        for a in &self.attempts {
            let from = if a.from.is_empty() {
                String::new()
            } else {
                format!(" from {}", a.from)
            };
            events.insert(
                a.step,
                "network",
                tiltsim_formats::events::EventKind::NetworkRefused,
                f64::NAN,
                format!("{}{from}: {}", a.kind.words(), a.detail),
            );
        }
    }
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
    /// Replies that came after `run.deadline_ms` from a participant that was running (starved
    /// of CPU by other load, not hung) and were waited for.
    pub starved_waits: u64,
    /// Requests re-sent and repeats discarded: what lost samples cost.
    pub lost_samples: LostSamples,
    /// How it handed its CPU over, when it was cued (`run.hand_over = "cue"`).
    #[serde(skip_serializing_if = "CueCounts::is_zero")]
    pub cue: CueCounts,
}

/// Timing of the run.
#[derive(Debug, Clone, Serialize, Default)]
pub struct Timing {
    /// Per-tick coordination overhead (µs): tick wall time minus the participants' compute
    /// time on the critical path (the sum for Gauss-Seidel, the largest for Jacobi). Median.
    #[serde(rename = "overhead_p50_us")]
    pub p50: f64,
    /// 99th percentile of the overhead (µs).
    #[serde(rename = "overhead_p99_us")]
    pub p99: f64,
    /// Largest overhead (µs).
    #[serde(rename = "overhead_max_us")]
    pub max: f64,
    /// Mean overhead (µs).
    #[serde(rename = "overhead_mean_us")]
    pub mean: f64,
    /// Whole tick wall time (µs).
    pub tick_us: Percentiles,
    /// Orchestrator CPU time, user + system (s), and the participants' (s), when measurable.
    pub cpu_s: CpuTime,
    /// The CPU plan chosen from the participants' measured compute (Jacobi over IPC).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu_plan: Option<super::cpu_plan::CpuPlanReport>,
    /// Where the run's processes ran among the other runs and work on the machine, why, and
    /// how they waited (IPC only; `cosim::ipc::placement`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placement: Option<cosim::ipc::placement::Placement>,
    /// How the participants pinned together on one CPU handed it over while they waited
    /// (`cue` or `yield`, `run.hand_over`; IPC lock-step waiting adaptively only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hand_over: Option<tiltsim_scenario::scenario::HandOver>,
    /// How long the loop waited for a CPU and the load average (when the kernel reports
    /// them): whether other work on the machine slowed the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub machine: Option<super::machine::MachineLoad>,
}

/// CPU time spent.
#[derive(Debug, Clone, Serialize, Default)]
pub struct CpuTime {
    /// The orchestrator process (s).
    pub orchestrator: f64,
    /// All participant processes together (s); 0 in-process.
    pub participants: f64,
}

impl CpuTime {
    /// The CPU time of the orchestrator and of the participants `each` (s, `None` where not
    /// measured: in-process). A sum of nothing is `0.0`, never the `-0.0` that `f64`'s `Sum`
    /// starts from, and nothing below zero is reported, so no reader sees `-0.00 s`.
    pub fn new(orchestrator: f64, each: impl IntoIterator<Item = Option<f64>>) -> CpuTime {
        let participants = each.into_iter().flatten().fold(0.0, |a, b| a + b);
        CpuTime {
            orchestrator: non_negative(orchestrator),
            participants: non_negative(participants),
        }
    }
}

/// `x` if above zero, else `0.0` (a negative zero or a clock's rounding below zero included).
pub fn non_negative(x: f64) -> f64 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
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
    pub transport: Transport,
    /// Master algorithm.
    pub master_algorithm: Master,
    /// Wait strategy.
    pub wait_strategy: WaitStrategy,
    /// How the run was carried out.
    pub execution: RunMode,
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
    pub comfort: tiltsim_assessment::comfort::Comfort,
    /// The validity checks: oscillation, bump stop, drive limits, chopper, thermal, P_CT range
    /// and, for a free run, real time.
    pub flags: tiltsim_assessment::validity::Flags,
    /// Whether `comfort` describes a working tilt system answering the run's question: no
    /// oscillation, P_CT within the formula's range, kept real time, analysis done. The other
    /// flags (bump stop, drive, chopper, thermal) are physics of a valid run, said apart.
    pub comfort_valid: bool,
    /// Why `results`, `comfort` and `flags` were not computed (an interrupted run ends at once;
    /// `tiltsim plot DIR` draws its figures later). Absent when they were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub analysis_skipped: Option<String>,
    /// iceoryx2 prefix of the run ("" in-process).
    pub ipc_prefix: String,
    /// Files of the run still present after clean-up (must be empty).
    pub leftover_ipc_files: Vec<String>,
    /// Participant logs that are not empty, relative to the run's directory
    /// (`logs/plant.log`): what a participant process wrote to its standard error. Absent
    /// when none wrote anything.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub participant_logs: Vec<String>,
    /// Participants on other hosts: the run's address and key, who joined (host, pid, the
    /// offset of its clock and how well it is known) and who was refused. Absent when every
    /// participant ran on this host.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub network: Option<NetworkReport>,
    /// What the caller's observers ([`super::observe::Observer`]) reported when the run
    /// finished, by observer name. Absent when there were none.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub observers: std::collections::BTreeMap<String, serde_json::Value>,
    /// The whole car's running safety and comfort along the car (`vehicle.model = "full"`;
    /// absent for the half vehicle).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub full_car: Option<tiltsim_assessment::running_safety::FullCarReport>,
    /// A free run's wall-clock timing: real time kept or not, lateness, input ages (absent
    /// for lock-step runs and replays).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub free_run: Option<FreeTiming>,
    /// The timing trace a free run wrote (`timing.csv`) or a replay replayed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timing_trace: Option<String>,
    /// A replay of a partial trace (a free run that ended early or was killed): what the
    /// trace lacked. Only the steps it holds were replayed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace_partial: Option<String>,
    /// Consumer steps a replay fed from the trace.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub replayed_exchanges: Option<u64>,
    /// The fields above measured on the wall clock, which differ between repeats of the same
    /// run; everything else repeats exactly. The same values are in `perf.json`.
    pub wall_clock_fields: &'static [&'static str],
}

/// How a run was carried out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RunMode {
    /// The orchestrator steps every participant (`run.execution = "lock-step"`).
    LockStep,
    /// Every participant on its own clock (`run.execution = "free"`).
    Free,
    /// A lock-step replay of a free run's timing trace (`tiltsim replay-timing`).
    ReplayTiming,
}

impl Summary {
    /// The part of a summary every run has, for a run of `s` in `mode` that ended with
    /// `status`: participants, timing and results left empty for the caller to fill.
    pub fn blank(
        s: &tiltsim_scenario::scenario::Scenario,
        scenario_file: &str,
        mode: RunMode,
    ) -> Summary {
        Summary {
            tiltsim_version: env!("CARGO_PKG_VERSION"),
            scenario: s.name.clone(),
            scenario_file: scenario_file.to_string(),
            seed: s.run.seed,
            transport: s.run.transport,
            master_algorithm: s.run.master,
            wait_strategy: s.run.wait,
            execution: mode,
            status: Status::Completed,
            error: None,
            participants: Vec::new(),
            dt_s: s.run.dt_s,
            steps_planned: s.steps(),
            steps_completed: 0,
            simulated_time_s: 0.0,
            wall_time_s: 0.0,
            realtime_factor: 0.0,
            timing: Timing::default(),
            results: QuickLook::default(),
            link_latency: Vec::new(),
            pacing: None,
            controller_solver: None,
            comfort: Default::default(),
            flags: Default::default(),
            comfort_valid: false,
            analysis_skipped: None,
            ipc_prefix: String::new(),
            leftover_ipc_files: Vec::new(),
            participant_logs: Vec::new(),
            network: None,
            observers: std::collections::BTreeMap::new(),
            full_car: None,
            free_run: None,
            timing_trace: None,
            trace_partial: None,
            replayed_exchanges: None,
            wall_clock_fields: WALL_CLOCK_FIELDS,
        }
    }

    /// Sets the steps completed, the simulated time and the wall time of the run.
    pub fn set_progress(&mut self, steps: u64, wall_s: f64) {
        self.steps_completed = steps;
        self.simulated_time_s = steps as f64 * self.dt_s;
        self.wall_time_s = wall_s;
        self.realtime_factor = if wall_s > 0.0 {
            self.simulated_time_s / wall_s
        } else {
            0.0
        };
    }
}

/// The fields of `summary.json` that are measured on the wall clock (or name a process or a
/// run's files), as dotted paths; `participants.*` applies to every participant.
pub const WALL_CLOCK_FIELDS: &[&str] = &[
    "participants.pid",
    "participants.exit.cpu_s",
    "participants.compute_us",
    "participants.starved_waits",
    "participants.lost_samples",
    "participants.cue",
    "wall_time_s",
    "realtime_factor",
    "timing",
    "link_latency",
    "pacing",
    "ipc_prefix",
    "free_run",
];

/// A summary's JSON without its wall-clock fields
/// ([`WALL_CLOCK_FIELDS`]).
pub fn deterministic(mut det: serde_json::Value) -> serde_json::Value {
    for f in WALL_CLOCK_FIELDS {
        match f.split_once('.') {
            Some(("participants", rest)) => {
                if let Some(ps) = det["participants"].as_array_mut() {
                    for p in ps {
                        let (parents, last) = rest.rsplit_once('.').unwrap_or(("", rest));
                        let mut node = &mut *p;
                        for k in parents.split('.').filter(|k| !k.is_empty()) {
                            node = &mut node[k];
                        }
                        if let Some(o) = node.as_object_mut() {
                            o.remove(last);
                        }
                    }
                }
            }
            _ => {
                if let Some(o) = det.as_object_mut() {
                    o.remove(*f);
                }
            }
        }
    }
    det
}

impl Summary {
    /// The wall-clock part of the summary, for `perf.json`: the fields of
    /// [`WALL_CLOCK_FIELDS`], participants by role.
    pub fn perf(&self) -> serde_json::Value {
        let participants: serde_json::Map<String, serde_json::Value> = self
            .participants
            .iter()
            .map(|p| {
                (
                    p.role.name().to_string(),
                    serde_json::json!({
                        "process": p.process,
                        "pid": p.pid,
                        "cpu_s": p.exit.cpu_s,
                        "compute_us": p.compute_us,
                        "starved_waits": p.starved_waits,
                        "lost_samples": p.lost_samples,
                        "cue": p.cue,
                    }),
                )
            })
            .collect();
        serde_json::json!({
            "scenario": self.scenario,
            "execution": self.execution,
            "transport": self.transport,
            "master_algorithm": self.master_algorithm,
            "wait_strategy": self.wait_strategy,
            "steps_completed": self.steps_completed,
            "wall_time_s": self.wall_time_s,
            "realtime_factor": self.realtime_factor,
            "timing": self.timing,
            "link_latency": self.link_latency,
            "pacing": self.pacing,
            "free_run": self.free_run,
            "participants": participants,
            "ipc_prefix": self.ipc_prefix,
        })
    }
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
    #[serde(rename = "lat_acc_peak_m_s2")]
    pub lat_acc_peak: f64,
    /// Lateral acceleration at the middle of the steady curve (m/s²).
    #[serde(rename = "lat_acc_mid_curve_m_s2")]
    pub lat_acc_mid_curve: f64,
    /// Body roll θ_v at the middle of the steady curve (rad).
    #[serde(rename = "theta_v_mid_curve_rad")]
    pub theta_v_mid_curve: f64,
    /// Largest |δ_a| (rad).
    #[serde(rename = "delta_a_peak_rad")]
    pub delta_a_peak: f64,
    /// Time the controller's command sat at its limit ±`controller.u_max_deg` (s): where
    /// the tilt asked for more than the actuator's range (anti-windup holding the integrator).
    pub command_at_limit_s: f64,
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
    /// Why the late ticks were late.
    pub causes: OverrunCauses,
    /// Whether the processes ran under SCHED_FIFO with memory locked (`--realtime`).
    pub realtime: bool,
}

/// The late ticks of a paced run by cause. A tick's wall time from its scheduled start is its
/// start delay (the orchestrator woke late, or the previous tick ran over) plus the
/// participants' compute on the critical path plus the coordination (the exchanges'
/// latency); each late tick is counted under the largest of them.
#[derive(Debug, Clone, Default, Serialize)]
pub struct OverrunCauses {
    /// Late because the previous tick ended late.
    pub carried_over: u64,
    /// Late because the orchestrator started the tick late (woke late from its pacing sleep,
    /// or spent long between ticks).
    pub orchestrator: u64,
    /// Late because the participants computed long.
    pub compute: u64,
    /// Late because the exchanges took long (a participant woke late, or was not scheduled).
    pub coordination: u64,
    /// Of the late ticks: start delay (µs).
    pub start_delay_us: Percentiles,
    /// Of the late ticks: critical-path compute (µs).
    pub compute_us: Percentiles,
    /// Of the late ticks: coordination (µs).
    pub coordination_us: Percentiles,
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

#[cfg(test)]
mod tests {
    use super::CpuTime;

    #[test]
    fn cpu_time_is_never_negative_zero() {
        // In-process: no participant process, so nothing measured; `Sum` would give -0.0.
        let c = CpuTime::new(-0.0, [None, None, None]);
        assert_eq!(c.participants.to_bits(), 0.0f64.to_bits());
        assert_eq!(c.orchestrator.to_bits(), 0.0f64.to_bits());
        assert_eq!(format!("{:.2}", c.participants), "0.00");
        assert_eq!(
            serde_json::to_string(&c).unwrap(),
            r#"{"orchestrator":0.0,"participants":0.0}"#
        );
        let c = CpuTime::new(0.5, [Some(0.25), None, Some(0.125)]);
        assert_eq!((c.orchestrator, c.participants), (0.5, 0.375));
    }
}

/// A free run is judged not real-time when one of its plant steps started later than this
/// many base ticks after it was due.
pub const NOT_REAL_TIME_TICKS: u64 = 10;

/// One role's wall-clock timing in a free run.
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct RoleFreeTiming {
    /// Steps recorded.
    pub steps: u64,
    /// How long after it was due each step read its input (µs).
    pub start_lateness_us: cosim::stats::Percentiles,
    /// Steps that started after the next one was due.
    pub late_starts: u64,
    /// Steps published after the next one was due.
    pub late_finishes: u64,
}

/// The distribution of one link's input ages over its consumer's steps (ticks; see
/// `free::trace::age`).
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct AgeDistribution {
    /// Youngest.
    pub min: i64,
    /// Median.
    pub p50: i64,
    /// 99th percentile.
    pub p99: i64,
    /// Oldest.
    pub max: i64,
    /// `[age, steps]` pairs in increasing age.
    pub counts: Vec<[i64; 2]>,
}

impl AgeDistribution {
    pub(crate) fn of(h: &std::collections::BTreeMap<i64, u64>) -> Self {
        let n: u64 = h.values().sum();
        let at = |q: f64| {
            let want = ((n.saturating_sub(1)) as f64 * q).round() as u64;
            let mut seen = 0;
            for (a, c) in h {
                seen += c;
                if seen > want {
                    return *a;
                }
            }
            0
        };
        AgeDistribution {
            min: h.keys().next().copied().unwrap_or(0),
            p50: at(0.5),
            p99: at(0.99),
            max: h.keys().next_back().copied().unwrap_or(0),
            counts: h.iter().map(|(a, c)| [*a, *c as i64]).collect(),
        }
    }
}

/// The wall-clock side of a free run: whether it kept real time, each role's lateness and each
/// link's input ages (all of it differs from one free run to the next; the replay of the trace
/// is what repeats).
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct FreeTiming {
    /// A plant step started more than [`NOT_REAL_TIME_TICKS`] ticks after it was due: the run
    /// did not keep real time, and its ride is not the answer to a real-time question.
    pub not_real_time: bool,
    /// That margin (s).
    pub not_real_time_margin_s: f64,
    /// The plant's largest start lateness (s).
    pub plant_max_lateness_s: f64,
    /// Per participant.
    pub participants: std::collections::BTreeMap<String, RoleFreeTiming>,
    /// Per link, by its `[links]` name.
    pub input_age_ticks: std::collections::BTreeMap<String, AgeDistribution>,
    /// The CPU each participant was pinned to (empty when not pinned).
    pub cpus: std::collections::BTreeMap<String, usize>,
    /// Where the run's processes ran among the other runs and work on the machine, and why
    /// (`cosim::ipc::placement`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub placement: Option<cosim::ipc::placement::Placement>,
}
