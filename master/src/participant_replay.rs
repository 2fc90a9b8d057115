//! `tiltsim replay RUN_DIR --participant ROLE`: one participant run alone against exactly the
//! inputs it received in a recorded run (`run.mcap` of `tiltsim run --record`: after link
//! effects, faults and bad data), its outputs compared with the recorded ones message by
//! message. With the recorded scenario a deterministic participant reproduces every output
//! byte for byte; with a changed setting the report says where the outputs first differ and
//! by how much. This is also the project's determinism check (`tests/cli/record.rs`).
//!
//! Replay stops where the recording says the participant was lost (a scheduled fault or a
//! failure): after that its stand-in answered, not the model.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cosim::msg::{Header, Kind, Message, FLAG_HOLD_BAD_INPUT, FLAG_REJECTED};
use cosim::{Endpoint, InProcess, Role};
use serde::Serialize;
use tiltsim_scenario::faults::OnBadData;
use tiltsim_scenario::scenario::Scenario;

use crate::engine::mcap as rec;
use crate::engine::Inits;

/// Why a replay could not run.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The recording is missing or unreadable.
    #[error("{path}: {what}")]
    Recording {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        what: String,
    },
    /// The participant could not be built from the scenario.
    #[error("{0}")]
    Model(String),
    /// An output could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}

/// The first output that differs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Difference {
    /// Tick.
    pub step: u64,
    /// Field.
    pub field: String,
    /// As recorded.
    pub recorded: Option<f64>,
    /// As replayed.
    pub replayed: Option<f64>,
}

/// What a replay found (`replay.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The participant replayed.
    pub participant: Role,
    /// Steps replayed.
    pub steps: u64,
    /// Step at which the recording says the participant was lost (replay stopped there).
    pub lost_at_step: Option<u64>,
    /// Whether every replayed output equals the recorded one byte for byte.
    pub identical: bool,
    /// Outputs that differ.
    pub differing_steps: u64,
    /// The first difference.
    pub first_difference: Option<Difference>,
    /// Largest absolute difference per field (fields that never differ are absent).
    pub max_abs_difference: BTreeMap<String, f64>,
}

/// One recorded message: its step and its values in the channel's field order.
type Recorded = (u64, Vec<f64>, String);

/// The messages of `topic` in `run.mcap`, in order.
fn channel(bytes: &[u8], topic: &str, path: &Path) -> Result<Vec<Recorded>, ReplayError> {
    let bad = |what: String| ReplayError::Recording {
        path: path.to_path_buf(),
        what,
    };
    let fields = rec::fields(topic);
    let mut out = Vec::new();
    for m in mcap::MessageStream::new(bytes).map_err(|e| bad(e.to_string()))? {
        let m = m.map_err(|e| bad(e.to_string()))?;
        if m.channel.topic != topic {
            continue;
        }
        let text = String::from_utf8_lossy(&m.data).into_owned();
        let v: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| bad(format!("{topic}: {e}")))?;
        let step = v["step"]
            .as_u64()
            .ok_or_else(|| bad(format!("{topic}: a message without `step`")))?;
        let values = fields
            .iter()
            .map(|f| v[*f].as_f64().unwrap_or(f64::NAN))
            .collect();
        out.push((step, values, text));
    }
    Ok(out)
}

/// The first step at which the recording's events say `role` was lost.
fn lost_at(bytes: &[u8], role: Role, path: &Path) -> Result<Option<u64>, ReplayError> {
    let bad = |what: String| ReplayError::Recording {
        path: path.to_path_buf(),
        what,
    };
    for m in mcap::MessageStream::new(bytes).map_err(|e| bad(e.to_string()))? {
        let m = m.map_err(|e| bad(e.to_string()))?;
        if m.channel.topic != "/events" {
            continue;
        }
        let v: serde_json::Value =
            serde_json::from_slice(&m.data).map_err(|e| bad(format!("/events: {e}")))?;
        let lost = matches!(
            v["kind"].as_str(),
            Some("fault-injected" | "participant-lost" | "run-failed")
        );
        if lost && v["source"] == role.name() {
            return Ok(v["step"].as_u64());
        }
    }
    Ok(None)
}

/// Replays `role` of the recorded run in `run_dir` with scenario `s`; writes
/// `out/<role>-out.jsonl` (the replayed outputs, one message per line, as recorded) and
/// `out/replay.json`.
pub fn replay(
    run_dir: &Path,
    role: Role,
    s: &Scenario,
    at: &Where,
    out: &Path,
) -> Result<Report, ReplayError> {
    let path = run_dir.join("run.mcap");
    let bytes = std::fs::read(&path).map_err(|e| ReplayError::Recording {
        path: path.clone(),
        what: format!("{e} (record a run with `tiltsim run SCENARIO --record`)"),
    })?;
    let inbox = channel(&bytes, &format!("/{}/in", role.name()), &path)?;
    let outbox = channel(&bytes, &format!("/{}/out", role.name()), &path)?;
    let lost = lost_at(&bytes, role, &path)?;
    let topic = format!("/{}/out", role.name());
    let fields = rec::fields(&topic);
    let replayed = run_role(role, s, at, &inbox, lost)?;
    std::fs::create_dir_all(out).map_err(|source| ReplayError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let lines: String = replayed.iter().map(|(_, _, t)| format!("{t}\n")).collect();
    let file = out.join(format!("{}-out.jsonl", role.name()));
    tiltsim_rundir::files::write_atomic(&file, lines)
        .map_err(|source| ReplayError::Io { path: file, source })?;
    let report = compare(role, &replayed, &outbox, lost, fields);
    let file = out.join("replay.json");
    tiltsim_rundir::files::write_atomic(
        &file,
        serde_json::to_string_pretty(&report).unwrap_or_default() + "\n",
    )
    .map_err(|source| ReplayError::Io { path: file, source })?;
    Ok(report)
}

/// How the recording numbers a participant's outputs: by the row of `timeseries.csv` at the
/// time they hold at.
#[derive(Clone, Copy)]
struct Outbox {
    /// The outputs at t_0 are recorded as step 0 (the plant and the actuator; the
    /// controller's are not recorded).
    records_start: bool,
    fields: &'static [&'static str],
}

/// Drives one participant through the recorded inputs over `ep` (its Init exchange first, as
/// the engine does); stops where the recording says it was lost, or where it rejected an
/// input (the recorded run ended there too).
fn drive<I: Message, O: Message>(
    ep: &mut dyn Endpoint<I, O>,
    inbox: &[Recorded],
    lost: Option<u64>,
    hold: bool,
    input: fn(&[f64]) -> I,
    output: fn(&O) -> Vec<f64>,
    outbox: Outbox,
) -> Result<Vec<Recorded>, ReplayError> {
    let link = |e: cosim::LinkError| ReplayError::Model(format!("replayed participant: {e}"));
    let fields = outbox.fields;
    let mut init = I::default();
    *init.header_mut() = Header::new(0, Kind::Init);
    ep.send(&init).map_err(link)?;
    let first = ep.receive(0, Kind::Init).map_err(link)?;
    let mut out = Vec::new();
    if outbox.records_start {
        let values = output(&first);
        let text = rec::message(0, fields, &values);
        out.push((0, values, text));
    }
    // A message of tick k is step k + 1, the row of `timeseries.csv` that holds it.
    for (row, v, _) in inbox
        .iter()
        .take_while(|(row, _, _)| lost.is_none_or(|l| *row <= l))
    {
        let k = row.saturating_sub(1);
        let mut req = input(v);
        let mut h = Header::new(k, Kind::Step);
        if hold {
            h.flags |= FLAG_HOLD_BAD_INPUT;
        }
        *req.header_mut() = h;
        ep.send(&req).map_err(link)?;
        let reply = ep.receive(k, Kind::Step).map_err(link)?;
        if reply.header().flags & FLAG_REJECTED != 0 {
            break;
        }
        let values = output(&reply);
        let text = rec::message(*row, fields, &values);
        out.push((*row, values, text));
    }
    Ok(out)
}

/// Where the replayed participant runs.
#[derive(Debug, Clone)]
pub enum Where {
    /// In this process.
    InProcess,
    /// As its own process over iceoryx2, served by this executable.
    Process(PathBuf),
}

/// The participant of `role` for scenario `s`, on `at`, driven through the recorded inputs.
fn run_role(
    role: Role,
    s: &Scenario,
    at: &Where,
    inbox: &[Recorded],
    lost: Option<u64>,
) -> Result<Vec<Recorded>, ReplayError> {
    let inits = Inits::from(s);
    let prefix = cosim::ipc::unique_prefix();
    // The files of the replay's own iceoryx2 run go on every way out.
    let _files = RunFiles(&prefix, matches!(at, Where::Process(_)));
    let hub = hub(s, at, &prefix)?;
    let stage = Stage {
        role,
        at,
        hub: hub.as_ref(),
        // An FMU that played the role in the recorded run plays it again.
        fmu: s.fmu_init(role),
        startup: std::time::Duration::from_millis(s.run.startup_ms),
        inbox,
        lost,
        hold: s.faults.on_bad_data == OnBadData::Hold,
        fields: rec::fields(&format!("/{}/out", role.name())),
    };
    let result = match role {
        Role::Plant => stage.replay::<tiltsim_fmi::PlantIo, _>(
            || Ok(plant_proc::Plant::new(&inits.plant)),
            &inits.plant,
            rec::plant_in,
            rec::plant_out,
        ),
        Role::Actuator => stage.replay::<tiltsim_fmi::ActuatorIo, _>(
            || Ok(actuator_proc::Actuator::new(&inits.actuator)),
            &inits.actuator,
            rec::actuator_in,
            rec::actuator_out,
        ),
        Role::Controller => stage.replay::<tiltsim_fmi::ControllerIo, _>(
            || controller_proc::Controller::new(&inits.controller).map_err(ReplayError::Model),
            &inits.controller,
            rec::controller_in,
            rec::controller_out,
        ),
    };
    drop(hub);
    result
}

/// Removes the files of the replay's own iceoryx2 run (`.0`) when dropped, if it made any
/// (`.1`).
struct RunFiles<'a>(&'a str, bool);

impl Drop for RunFiles<'_> {
    fn drop(&mut self) {
        if self.1 {
            cosim::ipc::remove_run_files(self.0);
        }
    }
}

/// The replay's own iceoryx2 hub when the participant runs as a process.
fn hub(s: &Scenario, at: &Where, prefix: &str) -> Result<Option<cosim::ipc::IpcHub>, ReplayError> {
    match at {
        Where::InProcess => Ok(None),
        Where::Process(_) => cosim::ipc::IpcHub::new(cosim::ipc::IpcSettings {
            prefix: prefix.to_string(),
            wait: s.run.wait,
            deadline: std::time::Duration::from_millis(s.run.deadline_ms),
            ceiling: std::time::Duration::from_millis(s.run.hang_ceiling_ms),
            participant_cpu: None,
        })
        .map(Some)
        .map_err(|e| ReplayError::Model(e.to_string())),
    }
}

/// Where and how the replayed participant runs, and what it is driven through.
struct Stage<'a> {
    role: Role,
    at: &'a Where,
    hub: Option<&'a cosim::ipc::IpcHub>,
    fmu: Option<tiltsim_fmi::FmuInit>,
    startup: std::time::Duration,
    inbox: &'a [Recorded],
    lost: Option<u64>,
    hold: bool,
    fields: &'static [&'static str],
}

impl Stage<'_> {
    /// Drives the participant through the recorded inputs ([`drive`]) and shuts it down: the
    /// model `model()` (with `params` as its process's settings), or the role's FMU as
    /// samples `S`.
    fn replay<S, M>(
        &self,
        model: impl FnOnce() -> Result<M, ReplayError>,
        params: &impl Serialize,
        input: fn(&[f64]) -> S::In,
        output: fn(&S::Out) -> Vec<f64>,
    ) -> Result<Vec<Recorded>, ReplayError>
    where
        S: tiltsim_fmi::Samples,
        M: cosim::Participant<Input = S::In, Output = S::Out>,
    {
        let mut ep = self.endpoint::<S, M>(model, params)?;
        let r = drive(
            ep.as_mut(),
            self.inbox,
            self.lost,
            self.hold,
            input,
            output,
            Outbox {
                records_start: self.role != Role::Controller,
                fields: self.fields,
            },
        );
        ep.shutdown();
        r
    }

    /// The endpoint of the replayed participant: its process (`participant` or
    /// `fmu-participant`) over the hub, or it in this process.
    fn endpoint<S, M>(
        &self,
        model: impl FnOnce() -> Result<M, ReplayError>,
        params: &impl Serialize,
    ) -> Result<Box<dyn Endpoint<S::In, S::Out>>, ReplayError>
    where
        S: tiltsim_fmi::Samples,
        M: cosim::Participant<Input = S::In, Output = S::Out>,
    {
        Ok(match (self.at, self.hub, &self.fmu) {
            (Where::Process(exe), Some(hub), _) => {
                let (command, params) = match &self.fmu {
                    Some(init) => ("fmu-participant", serde_json::to_string(init)),
                    None => ("participant", serde_json::to_string(params)),
                };
                let launch = cosim::ipc::Launch {
                    program: exe.clone(),
                    args: vec![
                        command.into(),
                        self.role.name().into(),
                        "--params".into(),
                        params.unwrap_or_default().into(),
                    ],
                };
                Box::new(
                    hub.spawn::<S::In, S::Out>(self.role, &launch, self.startup)
                        .map_err(|e| ReplayError::Model(e.to_string()))?,
                )
            }
            (_, _, Some(init)) => Box::new(InProcess::new(
                tiltsim_fmi::FmuParticipant::<S>::new(init.clone()).map_err(ReplayError::Model)?,
            )),
            _ => Box::new(InProcess::new(model()?)),
        })
    }
}

/// Compares replayed with recorded outputs, message by message.
fn compare(
    role: Role,
    replayed: &[Recorded],
    recorded: &[Recorded],
    lost: Option<u64>,
    fields: &[&str],
) -> Report {
    let by_step: BTreeMap<u64, &Recorded> = recorded.iter().map(|r| (r.0, r)).collect();
    let mut report = Report {
        participant: role,
        // The outputs at t_0 of a plant or an actuator are not a step.
        steps: (replayed.len() - usize::from(role != Role::Controller && !replayed.is_empty()))
            as u64,
        lost_at_step: lost,
        identical: true,
        differing_steps: 0,
        first_difference: None,
        max_abs_difference: BTreeMap::new(),
    };
    let opt = |v: f64| v.is_finite().then_some(v);
    for (k, values, text) in replayed {
        let Some((_, want, want_text)) = by_step.get(k) else {
            report.identical = false;
            report.differing_steps += 1;
            continue;
        };
        if text == want_text {
            continue;
        }
        report.identical = false;
        report.differing_steps += 1;
        for (i, f) in fields.iter().enumerate() {
            let (a, b) = (want[i], values[i]);
            if a.to_bits() == b.to_bits() {
                continue;
            }
            if report.first_difference.is_none() {
                report.first_difference = Some(Difference {
                    step: *k,
                    field: f.to_string(),
                    recorded: opt(a),
                    replayed: opt(b),
                });
            }
            let d = (a - b).abs();
            let e = report
                .max_abs_difference
                .entry(f.to_string())
                .or_insert(0.0);
            if d.is_nan() || d > *e {
                *e = if d.is_nan() { f64::INFINITY } else { d };
            }
        }
    }
    report
}
