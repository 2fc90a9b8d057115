//! `tiltsim replay RUN_DIR --participant ROLE`: one participant run alone against exactly the
//! inputs it received in a recorded run (`run.mcap` of `tiltsim run --record`: after link
//! effects, faults and bad data), its outputs compared with the recorded ones message by
//! message. With the recorded scenario a deterministic participant reproduces every output
//! byte for byte; with a changed setting the report says where the outputs first differ and
//! by how much. This is also the project's determinism check (`tests/record.rs`).
//!
//! Replay stops where the recording says the participant was lost (a scheduled fault or a
//! failure): after that its stand-in answered, not the model.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use cosim::msg::{Header, Kind, Message, FLAG_HOLD_BAD_INPUT};
use cosim::participant::{Participant, Served};
use cosim::Role;
use serde::Serialize;

use crate::engine::mcap as rec;
use crate::engine::Inits;
use crate::faults::OnBadData;
use crate::scenario::Scenario;

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
pub fn replay(run_dir: &Path, role: Role, s: &Scenario, out: &Path) -> Result<Report, ReplayError> {
    let path = run_dir.join("run.mcap");
    let bytes = std::fs::read(&path).map_err(|e| ReplayError::Recording {
        path: path.clone(),
        what: format!("{e} (record a run with `tiltsim run SCENARIO --record`)"),
    })?;
    let inbox = channel(&bytes, &format!("/{}/in", role.name()), &path)?;
    let outbox = channel(&bytes, &format!("/{}/out", role.name()), &path)?;
    let lost = lost_at(&bytes, role, &path)?;
    let hold = s.faults.on_bad_data == OnBadData::Hold;
    let inits = Inits::from(s);
    let topic = format!("/{}/out", role.name());
    let fields = rec::fields(&topic);
    let replayed = match role {
        Role::Plant => run_model(
            plant_proc::Plant::new(&inits.plant),
            &inbox,
            lost,
            hold,
            rec::plant_in,
            rec::plant_out,
            fields,
        ),
        Role::Actuator => run_model(
            actuator_proc::Actuator::new(&inits.actuator),
            &inbox,
            lost,
            hold,
            rec::actuator_in,
            rec::actuator_out,
            fields,
        ),
        Role::Controller => run_model(
            controller_proc::Controller::new(&inits.controller).map_err(ReplayError::Model)?,
            &inbox,
            lost,
            hold,
            rec::controller_in,
            rec::controller_out,
            fields,
        ),
    };
    std::fs::create_dir_all(out).map_err(|source| ReplayError::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let lines: String = replayed.iter().map(|(_, _, t)| format!("{t}\n")).collect();
    let file = out.join(format!("{}-out.jsonl", role.name()));
    crate::files::write_atomic(&file, lines)
        .map_err(|source| ReplayError::Io { path: file, source })?;
    let report = compare(role, &replayed, &outbox, lost, fields);
    let file = out.join("replay.json");
    crate::files::write_atomic(
        &file,
        serde_json::to_string_pretty(&report).unwrap_or_default() + "\n",
    )
    .map_err(|source| ReplayError::Io { path: file, source })?;
    Ok(report)
}

/// Steps `model` through the recorded inputs, as its transport would serve them.
fn run_model<P: Participant>(
    model: P,
    inbox: &[Recorded],
    lost: Option<u64>,
    hold: bool,
    input: fn(&[f64]) -> P::Input,
    output: fn(&P::Output) -> Vec<f64>,
    fields: &[&str],
) -> Vec<Recorded> {
    let mut served = Served::new(model);
    let mut init = P::Input::default();
    *init.header_mut() = Header::new(0, Kind::Init);
    served.answer(&init);
    inbox
        .iter()
        .take_while(|(k, _, _)| lost.is_none_or(|l| *k < l))
        .map(|(k, v, _)| {
            let mut req = input(v);
            let mut h = Header::new(*k, Kind::Step);
            if hold {
                h.flags |= FLAG_HOLD_BAD_INPUT;
            }
            *req.header_mut() = h;
            let values = output(&served.answer(&req));
            let text = rec::message(*k, fields, &values);
            (*k, values, text)
        })
        .collect()
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
        steps: replayed.len() as u64,
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
