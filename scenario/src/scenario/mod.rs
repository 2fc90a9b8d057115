//! Scenario files: TOML mapped onto validated settings. Unknown keys are errors; every default
//! is the paper's value and documented on its field.

use std::path::PathBuf;

use actuator_proc::ActuatorSettings;
use controller_proc::ControllerSettings;
use plant_proc::SensorParams;
use serde::{Deserialize, Serialize};
use tiltsim_protocol::settings::FieldError;
use tiltsim_protocol::wait::WaitStrategy;
use tiltsim_protocol::Role;
use vehicle_model::{TrackParams, VehicleParams};

mod load;
pub mod suggest;
mod validate;

pub use load::*;

/// Master algorithm of the lock-step (docs/architecture.md, "Coupling").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Master {
    /// Sequential: controller, then actuator, then plant, each seeing the others' newest
    /// outputs. One tick of delay on the feedback links (plant → controller, plant → actuator),
    /// none on the forward links.
    #[default]
    GaussSeidel,
    /// Parallel: all participants step at once on the previous tick's outputs. One tick of
    /// delay on every link.
    Jacobi,
}

impl Master {
    /// Kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            Master::GaussSeidel => "gauss-seidel",
            Master::Jacobi => "jacobi",
        }
    }
}

/// Transport between the orchestrator and the participants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Transport {
    /// Separate processes, iceoryx2 shared memory.
    #[default]
    Ipc,
    /// Every participant stepped inside the orchestrator's process.
    InProcess,
}

impl Transport {
    /// Kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            Transport::Ipc => "ipc",
            Transport::InProcess => "in-process",
        }
    }
}

/// Run settings (section `[run]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunSettings {
    /// Base tick = plant step = actuator exchange period (s). Default 1 ms.
    pub dt_s: f64,
    /// Simulated duration (s). Default: the track's length at the vehicle's speed.
    pub duration_s: Option<f64>,
    /// Seed of the track irregularity and the sensor noise.
    pub seed: u64,
    /// Master algorithm.
    pub master: Master,
    /// Transport.
    pub transport: Transport,
    /// How waiting processes spend their time between polls.
    pub wait: WaitStrategy,
    /// A participant that does not answer a step within this time, and has made no progress
    /// (stopped, or sleeping without using CPU), is declared stalled (ms).
    pub deadline_ms: u64,
    /// A participant still running but not answering (starved of CPU by other load, or
    /// spinning) is waited for up to this long, then declared stalled (ms).
    pub hang_ceiling_ms: u64,
    /// Time allowed for a participant process to start and connect (ms).
    pub startup_ms: u64,
    /// Pin the orchestrator to one CPU and the participants to another (ipc transport).
    pub pin_cpus: bool,
    /// Under Jacobi over IPC, give the participant measured heaviest a CPU of its own after a
    /// warm-up (`measured`, default) or keep every participant on one CPU (`fixed`).
    pub cpu_plan: CpuPlanMode,
    /// How participants pinned together on one CPU hand it to each other under Gauss-Seidel
    /// over IPC while they wait adaptively: `cue` (default) or `yield`.
    pub hand_over: HandOver,
    /// Lock-step (default) or free running over IPC (docs/architecture.md, "Execution modes").
    pub execution: Execution,
    /// Free running only: a busy wait added to each controller step (s), for studies of a
    /// slow controller. 0 = none.
    pub controller_busy_wait_s: f64,
}

/// How simulated time advances (`run.execution`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Execution {
    /// The orchestrator steps every participant and waits for its reply.
    #[default]
    LockStep,
    /// Every participant process steps on its own wall-clock timer; nobody waits.
    Free,
}

/// How a Jacobi run over IPC places its processes (`run.cpu_plan`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum CpuPlanMode {
    /// From the participants' measured compute (engine/cpu_plan.rs).
    #[default]
    Measured,
    /// The orchestrator on one CPU, every participant on another.
    Fixed,
}

/// How participants that share a CPU hand it over (`run.hand_over`; docs/performance.md,
/// "The exchange against iceoryx2's floor").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum HandOver {
    /// Each that has answered cues the one asked after it, which polls without yielding
    /// until its request comes; one found in front of the cued one steps out of the CPU's
    /// queue for a moment, so that the kernel cycles them in the order they are asked.
    #[default]
    Cue,
    /// Each polls and yields the CPU while it waits.
    Yield,
}

impl Default for RunSettings {
    fn default() -> Self {
        RunSettings {
            dt_s: 1e-3,
            duration_s: None,
            seed: 1,
            master: Master::GaussSeidel,
            transport: Transport::Ipc,
            wait: WaitStrategy::Adaptive,
            deadline_ms: 500,
            hang_ceiling_ms: 60_000,
            startup_ms: 5000,
            pin_cpus: true,
            cpu_plan: CpuPlanMode::Measured,
            hand_over: HandOver::Cue,
            execution: Execution::LockStep,
            controller_busy_wait_s: 0.0,
        }
    }
}

/// A whole scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Short name (defaults to the file stem).
    pub name: String,
    /// What the scenario is for.
    pub description: String,
    /// Run settings.
    pub run: RunSettings,
    /// Vehicle parameters.
    pub vehicle: VehicleParams,
    /// Track and speed.
    pub track: TrackParams,
    /// Body roll sensor.
    pub sensor: SensorParams,
    /// Actuator.
    pub actuator: ActuatorSettings,
    /// Controller.
    pub controller: ControllerSettings,
    /// Comfort evaluation.
    pub comfort: tiltsim_assessment::comfort::ComfortSettings,
    /// Link effects between the processes (`[links.<name>]`).
    pub links: crate::links::Links,
    /// Process faults and what follows failures and bad data (`[faults]`).
    pub faults: crate::faults::Faults,
    /// The vehicle the controller was designed for, when it differs from the true `[vehicle]`
    /// the plant simulates (robustness studies: `tiltsim sweep` sets it to the nominal
    /// vehicle). Absent: the controller knows the vehicle exactly.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub design_vehicle: Option<VehicleParams>,
    /// Participants replaced by FMUs (`[participants.<role>]`); absent: the native ones.
    #[serde(skip_serializing_if = "FmuParticipants::is_empty")]
    pub participants: FmuParticipants,
    /// Participants on other hosts (`[network]`); absent: every participant on this host.
    #[serde(skip_serializing_if = "crate::network::Network::is_local")]
    pub network: crate::network::Network,
}

/// `[participants]`: an FMU for any role in place of tiltsim's own participant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct FmuParticipants {
    /// The plant.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plant: Option<tiltsim_fmi::FmuSettings>,
    /// The actuator.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actuator: Option<tiltsim_fmi::FmuSettings>,
    /// The controller.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub controller: Option<tiltsim_fmi::FmuSettings>,
}

impl FmuParticipants {
    /// No FMU anywhere.
    pub fn is_empty(&self) -> bool {
        self.plant.is_none() && self.actuator.is_none() && self.controller.is_none()
    }
    /// The FMU settings of `role`, if an FMU plays it.
    pub fn get(&self, role: Role) -> Option<&tiltsim_fmi::FmuSettings> {
        match role {
            Role::Plant => self.plant.as_ref(),
            Role::Actuator => self.actuator.as_ref(),
            Role::Controller => self.controller.as_ref(),
        }
    }
    fn each_mut(&mut self) -> impl Iterator<Item = &mut tiltsim_fmi::FmuSettings> {
        [&mut self.plant, &mut self.actuator, &mut self.controller]
            .into_iter()
            .flatten()
    }
}

/// Why a scenario was rejected. Displayed messages name the file.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        file: PathBuf,
        source: std::io::Error,
    },
    /// Larger than any scenario ([`MAX_SCENARIO_BYTES`]): not read further.
    #[error("{file}: larger than {} MiB, the most a scenario file may hold (is it a scenario?)", MAX_SCENARIO_BYTES >> 20)]
    TooLarge { file: PathBuf },
    /// Syntax, wrong type or unknown key (toml's message names the key and line).
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    /// Values out of range.
    #[error("{file}: invalid settings:\n{}", errors.iter().map(|e| format!("  {e}")).collect::<Vec<_>>().join("\n"))]
    Invalid {
        file: PathBuf,
        errors: Vec<FieldError>,
    },
}

impl Scenario {
    /// The communication period of `role` (s).
    pub fn period_of(&self, role: Role) -> f64 {
        match role {
            Role::Plant | Role::Actuator => self.run.dt_s,
            Role::Controller => self.controller.period_s,
        }
    }

    /// What the process of an FMU playing `role` receives, if one does.
    pub fn fmu_init(&self, role: Role) -> Option<tiltsim_fmi::FmuInit> {
        self.participants
            .get(role)
            .map(|settings| tiltsim_fmi::FmuInit {
                role,
                settings: settings.clone(),
                period_s: self.period_of(role),
                dt_s: self.run.dt_s,
            })
    }

    /// The vehicle the controller's design and reference use.
    pub fn controller_vehicle(&self) -> &VehicleParams {
        self.design_vehicle.as_ref().unwrap_or(&self.vehicle)
    }

    /// What the controller process receives: its settings, the track database, its design
    /// vehicle and the command shape the actuator applies (the MPC predicts with it).
    pub fn controller_init(&self) -> controller_proc::ControllerInit {
        controller_proc::ControllerInit {
            controller: self.controller.clone(),
            track: self.track.clone(),
            vehicle: self.controller_vehicle().clone(),
            input_shape: match self.actuator.command_shaping {
                actuator_proc::CommandShaping::Hold => controller_proc::InputShape::Hold,
                actuator_proc::CommandShaping::Ramp => controller_proc::InputShape::Ramp,
            },
            seed: self.run.seed,
        }
    }

    /// Simulated duration (s).
    pub fn duration(&self) -> f64 {
        self.run
            .duration_s
            .unwrap_or_else(|| self.track.length() / self.track.speed())
    }

    /// Number of base ticks.
    pub fn steps(&self) -> u64 {
        (self.duration() / self.run.dt_s).round() as u64
    }

    /// Controller period in ticks.
    pub fn controller_period_ticks(&self) -> u64 {
        (self.controller.period_s / self.run.dt_s).round().max(1.0) as u64
    }

    /// The scenario with the setting at dotted `key` (`vehicle.m_v`, `run.seed`,
    /// `controller.mode`) set to the value written `text` (`tiltsim run --set KEY=VALUE`). A
    /// key that holds a whole number takes whole numbers only, parsed as integers, so every
    /// `u64` (a seed of 2^63 or more included) arrives exactly; a decimal key takes a decimal
    /// number; a word or choice takes the word (checked against the choices as the file's
    /// would be); a switch takes true or false; a list or table is written as in a scenario
    /// file. Not re-validated: the caller validates once after all settings. Errors name the
    /// key and what it takes.
    pub fn with_setting(&self, key: &str, text: &str) -> Result<Scenario, String> {
        if key == "name" {
            return Err(
                "key `name` names the scenario and its output directory; it is not a setting (write it in the file, or choose the directory with --out)"
                    .to_string(),
            );
        }
        // JSON numbers hold u64, i64 and f64 exactly, unlike a TOML value (i64 or f64).
        let mut doc = serde_json::to_value(self).map_err(|e| e.to_string())?;
        let (table, last) = setting_slot(&mut doc, key)?;
        let value = setting_value(key, text.trim(), table.get(last))?;
        table.insert(last.to_string(), value);
        let mut s = serde_path_to_error::deserialize::<_, Scenario>(doc).map_err(|e| {
            let inner = e.inner().to_string();
            format!(
                "key `{key}`: {} (at `{}`){}; keys are the scenario's settings as dotted paths, e.g. `vehicle.m_v`, `controller.rho`",
                inner.trim_end(),
                e.path(),
                load::did_you_mean(&inner, "; ")
            )
        })?;
        s.name.clone_from(&self.name);
        Ok(s)
    }

    /// Whether the setting at dotted `key` holds a whole number (a count, a seed).
    pub fn holds_integer(&self, key: &str) -> bool {
        let Ok(doc) = serde_json::to_value(self) else {
            return false;
        };
        key.split('.')
            .try_fold(&doc, |node, p| node.get(p))
            .is_some_and(|v| v.is_u64() || v.is_i64())
    }
}

/// The table of `doc` that holds the last part of dotted `key`, with that part; tables on the
/// way that are missing or unset (an option) are made.
fn setting_slot<'d, 'k>(
    doc: &'d mut serde_json::Value,
    key: &'k str,
) -> Result<(&'d mut serde_json::Map<String, serde_json::Value>, &'k str), String> {
    use serde_json::Value;
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(format!(
            "key `{key}`: expected a dotted path such as `vehicle.m_v`"
        ));
    }
    let mut node = doc;
    for p in &parts[..parts.len() - 1] {
        let table = node
            .as_object_mut()
            .ok_or_else(|| format!("key `{key}`: `{p}` is not inside a table"))?;
        let child = table
            .entry(p.to_string())
            .or_insert_with(|| Value::Object(Default::default()));
        if child.is_null() {
            *child = Value::Object(Default::default());
        }
        node = child;
    }
    let last = parts[parts.len() - 1];
    let table = node
        .as_object_mut()
        .ok_or_else(|| format!("key `{key}`: not inside a table"))?;
    Ok((table, last))
}

/// The value written `text` for `key`, whose value now is `current`: a whole number where it
/// holds one (every `u64` and `i64` exactly), a decimal number where it holds one, the word
/// for a word or a choice, true or false for a switch, a list or table written as in a
/// scenario file, and for a key with no value yet whatever `text` reads as. Errors name the
/// key and what it takes.
fn setting_value(
    key: &str,
    text: &str,
    current: Option<&serde_json::Value>,
) -> Result<serde_json::Value, String> {
    use serde_json::Value;
    let whole = |t: &str| -> Option<Value> {
        t.parse::<u64>()
            .map(Value::from)
            .or_else(|_| t.parse::<i64>().map(Value::from))
            .ok()
    };
    match current {
        Some(Value::Number(n)) if n.is_u64() || n.is_i64() => whole(text).ok_or_else(|| {
            let digits = text.strip_prefix(['-', '+']).unwrap_or(text);
            if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
                format!(
                    "key `{key}` = {text}: allowed a whole number from {} to {}",
                    i64::MIN,
                    u64::MAX
                )
            } else {
                format!("key `{key}` takes a whole number written in digits, not `{text}`")
            }
        }),
        Some(Value::Number(_)) => {
            let v: f64 = text
                .parse()
                .map_err(|_| format!("key `{key}`: `{text}` is not a number"))?;
            serde_json::Number::from_f64(v)
                .map(Value::Number)
                .ok_or_else(|| format!("key `{key}` = {text}: allowed a finite number"))
        }
        // A key with no value yet (an option, `design_vehicle.*`, a key of a table the file
        // does not have, such as `network.remote`): a list or table as in a scenario file, an
        // integer as written (which a decimal setting takes as well), a number, true or
        // false, or else a word; the scenario's own types then judge it.
        Some(Value::Null) | None if text.starts_with('[') || text.starts_with('{') => {
            let doc: toml::Table = toml::from_str(&format!("v = {text}")).map_err(|_| {
                format!(
                    "key `{key}`: `{text}` is not a list or table written as in a scenario file (for example `[\"controller\"]`)"
                )
            })?;
            serde_json::to_value(&doc["v"]).map_err(|e| format!("key `{key}`: {e}"))
        }
        Some(Value::Null) | None => Ok(whole(text)
            .or_else(|| {
                text.parse::<f64>()
                    .ok()
                    .and_then(serde_json::Number::from_f64)
                    .map(Value::Number)
            })
            .or_else(|| text.parse::<bool>().ok().map(Value::Bool))
            .unwrap_or_else(|| Value::String(unquoted(text).to_string()))),
        // A word or a choice (`controller.mode=mpc`, `actuator.model=ideal`): the scenario's
        // own type says which are allowed when it is read.
        Some(Value::String(_)) => Ok(Value::String(unquoted(text).to_string())),
        Some(Value::Bool(_)) => text
            .parse::<bool>()
            .map(Value::Bool)
            .map_err(|_| format!("key `{key}` takes true or false, not `{text}`")),
        // A list or a table, written as in a scenario file (`[0.1, 1000, 0.1]`).
        Some(Value::Array(_) | Value::Object(_)) => {
            let doc: toml::Table = toml::from_str(&format!("v = {text}")).map_err(|_| {
                format!(
                    "key `{key}` takes a list or table written as in a scenario file (for example `[0.1, 1000]`), not `{text}`"
                )
            })?;
            serde_json::to_value(&doc["v"]).map_err(|e| format!("key `{key}`: {e}"))
        }
    }
}

/// `text` without the quotes around it, if it has them (`"mpc"` or `'mpc'` as `mpc`).
fn unquoted(text: &str) -> &str {
    ['"', '\'']
        .iter()
        .find_map(|q| text.strip_prefix(*q).and_then(|t| t.strip_suffix(*q)))
        .unwrap_or(text)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn parse(t: &str) -> Result<Scenario, ScenarioError> {
        Scenario::parse(t, Path::new("x.toml"))
    }

    #[test]
    fn a_setting_takes_words_choices_switches_and_lists_and_names_what_is_allowed() {
        let s = parse("").unwrap();
        let lqg = s.with_setting("controller.mode", "lqg").unwrap();
        assert_eq!(lqg.controller.mode, controller_proc::Mode::Lqg);
        let quoted = s.with_setting("controller.mode", "\"mpc\"").unwrap();
        assert_eq!(quoted.controller.mode, controller_proc::Mode::Mpc);
        let e = s.with_setting("controller.mode", "fuzzy").unwrap_err();
        assert!(
            e.contains("controller.mode") && e.contains("lqg") && e.contains("mpc"),
            "{e}"
        );
        let e = s.with_setting("name", "other-name").unwrap_err();
        assert!(e.contains("name") && e.contains("--out"), "{e}");
        let described = s.with_setting("description", "a word").unwrap();
        assert_eq!(described.description, "a word");
        let off = s.with_setting("run.pin_cpus", "false").unwrap();
        assert!(!off.run.pin_cpus);
        let e = s.with_setting("run.pin_cpus", "maybe").unwrap_err();
        assert!(e.contains("true or false"), "{e}");
        let q = "[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0]";
        let listed = s.with_setting("controller.lqg.q_diag", q).unwrap();
        assert_eq!(listed.controller.lqg.q_diag[9], 10.0);
        let e = s
            .with_setting("controller.lqg.q_diag", "[1, 2")
            .unwrap_err();
        assert!(
            e.contains("controller.lqg.q_diag") && e.contains("list"),
            "{e}"
        );
        let e = s.with_setting("controller.nonsense", "1").unwrap_err();
        assert!(e.contains("nonsense"), "{e}");
        // A table the file does not have takes its keys too.
        let remote = s
            .with_setting("network.remote", "[\"controller\"]")
            .unwrap();
        assert_eq!(remote.network.remote, [tiltsim_protocol::Role::Controller]);
    }

    #[test]
    fn defaults_are_valid_and_last_the_track() {
        let s = parse("").unwrap();
        assert!((s.duration() - 16.8).abs() < 1e-9);
        assert_eq!(s.steps(), 16_800);
    }

    #[test]
    fn a_name_that_would_leave_the_output_directory_is_rejected() {
        for bad in ["../../x", "/tmp/x", "a/b", "..", "a\\b", "tab\there"] {
            let text = format!("name = {bad:?}\n");
            let e = parse(&text).unwrap_err().to_string();
            assert!(
                e.contains("field `name`") && e.contains("without `/`"),
                "{bad}: {e}"
            );
        }
        let long = format!("name = \"{}\"\n", "x".repeat(101));
        assert!(parse(&long)
            .unwrap_err()
            .to_string()
            .contains("at most 100"));
        assert!(parse("name = \"paper-lqg rho 0.3\"\n").is_ok());
        // A hostile file's text is not echoed whole.
        let deep = format!("[vehicle]\nm_v = {}\n", "[".repeat(20_000));
        let e = parse(&deep).unwrap_err().to_string();
        assert!(e.len() < 1_000 && e.contains("x.toml"), "{} bytes", e.len());
    }

    #[test]
    fn inputs_that_can_never_take_effect_are_rejected_with_their_field() {
        let e = parse("[run]\nduration_s = 0.0004\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("run.duration_s") && e.contains("at least one step"),
            "{e}"
        );
        let fault = |body: &str| format!("[run]\nduration_s = 2.0\n{body}");
        let e = parse(&fault(
            "[[faults.schedule]]\nparticipant = \"controller\"\naction = \"kill\"\nat_s = 5.0\n",
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("faults.schedule[0].at_s") && e.contains("before the end"),
            "{e}"
        );
        let e = parse(&fault(
            "[[faults.schedule]]\nparticipant = \"actuator\"\naction = \"kill\"\nat_s = 1.0\nstall_s = 0.5\n",
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("faults.schedule[0].stall_s"), "{e}");
        let two = "[[faults.schedule]]\nparticipant = \"plant\"\naction = \"kill\"\nat_s = 1.0\n\
                   [[faults.schedule]]\nparticipant = \"plant\"\naction = \"kill\"\nat_s = 1.0\n";
        let e = parse(&fault(two)).unwrap_err().to_string();
        assert!(
            e.contains("faults.schedule[1].at_s") && e.contains("no other fault"),
            "{e}"
        );
    }

    #[test]
    fn choices_print_as_a_scenario_file_spells_them() {
        use actuator_proc::{ActuatorModel, CommandShaping};
        use controller_proc::Mode;
        fn same<T: Serialize + std::fmt::Display>(all: &[T]) {
            for v in all {
                assert_eq!(serde_json::to_string(v).unwrap(), format!("\"{v}\""));
            }
        }
        same(&[Mode::Passive, Mode::Pi, Mode::Lqg, Mode::Mpc]);
        same(&[
            ActuatorModel::Bldc,
            ActuatorModel::BldcAveraged,
            ActuatorModel::Ideal,
        ]);
        same(&[CommandShaping::Hold, CommandShaping::Ramp]);
        use crate::faults::FaultAction;
        same(&[FaultAction::Kill, FaultAction::Stall, FaultAction::Crash]);
    }

    #[test]
    fn a_duration_the_file_does_not_hold_is_never_named() {
        // Out-of-range track fields are named alone, not the duration they would give.
        let e = parse("[track]\nstraight_before_m = -9000.0\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("track.straight_before_m"), "{e}");
        assert!(!e.contains("duration_s"), "{e}");
        // A fault against such a track is not measured against a negative end.
        let e = parse("[track]\nspeed_kmh = -162.0\n[[faults.schedule]]\nparticipant = \"plant\"\naction = \"kill\"\nat_s = 1.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("track.speed_kmh") && !e.contains("faults"),
            "{e}"
        );
        // A valid track too short for one step is named as the track, with what to change.
        let e = parse("[run]\ndt_s = 0.01\n[track]\nstraight_before_m = 0.0\ntransition_m = 0.1\ncurve_m = 0.0\nstraight_after_m = 0.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `track` = 0.2 m at 162 km/h")
                && e.contains("run.duration_s")
                && !e.contains("field `run.duration_s`"),
            "{e}"
        );
        // A fault after the end of a run that lasts the track says where the end comes from.
        let e =
            parse("[[faults.schedule]]\nparticipant = \"plant\"\naction = \"kill\"\nat_s = 20.0\n")
                .unwrap_err()
                .to_string();
        assert!(
            e.contains("16.8 s (the track's length at its speed)"),
            "{e}"
        );
        // An explicit duration keeps its own message, once.
        let e = parse("[run]\nduration_s = -5.0\n").unwrap_err().to_string();
        assert_eq!(e.matches("run.duration_s").count(), 1, "{e}");
    }

    #[test]
    fn misleading_type_errors_name_the_field_and_what_to_write() {
        // A link written as an array of tables.
        let e = parse("[[links.measurement]]\ndelay_ticks = 3\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `links.measurement[0]`") && e.contains("write `[links.measurement]`"),
            "{e}"
        );
        // A choice given as a number: the allowed names, as the parser knows them.
        let e = parse("[controller]\nmode = 3\n").unwrap_err().to_string();
        assert!(
            e.contains("field `controller.mode`")
                && e.contains("allowed: one of `passive`, `pi`, `lqg`, `mpc`"),
            "{e}"
        );
        let e = parse("[run]\nmaster = 1.5\n").unwrap_err().to_string();
        assert!(
            e.contains("field `run.master`") && e.contains("`gauss-seidel`"),
            "{e}"
        );
        // LQI weights without the integrator's: the weight is named, not the mode.
        let e = parse("[controller]\nmode = \"lqg\"\n[controller.lqg]\nq_diag = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("controller.lqg.q_diag[9]") && !e.contains("controller.mode"),
            "{e}"
        );
    }

    #[test]
    fn unknown_key_wrong_type_and_range_are_named() {
        let e = parse("[vehicle]\nm_vv = 3.0\n").unwrap_err().to_string();
        assert!(e.starts_with("x.toml:") && e.contains("m_vv"), "{e}");
        let e = parse("[vehicle]\nm_v = \"heavy\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("m_v") && e.contains("invalid type"), "{e}");
        let e = parse("[vehicle]\nm_v = -5.0\n[run]\ndt_s = 1.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `vehicle.m_v` = -5") && e.contains("field `run.dt_s` = 1"),
            "{e}"
        );
        let e = parse("[controller]\nperiod_s = 0.0015\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("controller.period_s") && e.contains("whole multiple"),
            "{e}"
        );
    }

    #[test]
    fn the_vehicle_model_is_half_or_full_and_an_fmu_plant_refuses_the_whole_car() {
        let s = parse("").unwrap();
        assert_eq!(s.vehicle.model, vehicle_model::VehicleModel::Half);
        let s = parse("[vehicle]\nmodel = \"full\"\n").unwrap();
        assert_eq!(s.vehicle.model, vehicle_model::VehicleModel::Full);
        // The half vehicle's settings serialise as before: no `model` key.
        let half = serde_json::to_string(&parse("").unwrap().vehicle).unwrap();
        assert!(!half.contains("model"), "{half}");
        let e = parse("[vehicle]\nmodel = \"whole\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("x.toml:")
                && e.contains("field `vehicle.model`")
                && e.contains("`half`")
                && e.contains("`full`"),
            "{e}"
        );
        // The whole car runs free too.
        let free = parse(
            "[vehicle]\nmodel = \"full\"\n[run]\nexecution = \"free\"\ntransport = \"ipc\"\n",
        )
        .unwrap();
        assert_eq!(free.vehicle.model, vehicle_model::VehicleModel::Full);
        // An FMU plant is the user's own model: no wheelsets, so no whole car.
        let e = parse("[vehicle]\nmodel = \"full\"\n[participants.plant]\nfmu = \"plant.fmu\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("field `vehicle.model`")
                && e.contains("FMU plant is your own model")
                && e.contains("no wheelsets")
                && e.contains("[participants.plant]"),
            "{e}"
        );
        let e = parse("[design_vehicle]\nmodel = \"full\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("field `design_vehicle.model`"), "{e}");
    }
}
