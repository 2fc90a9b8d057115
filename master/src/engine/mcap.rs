//! `--record`: the run as an MCAP file (`DIR/run.mcap`) that Foxglove, Rerun or the `mcap`
//! CLI open. Written live by an observer, one JSON message per exchange:
//!
//! * `/<role>/in`, `/<role>/out`: what each participant received (after link effects) and
//!   what it answered, for every step it ran (the controller every `period_s`);
//! * `/links/<name>`: each link's value as sent and as received, every tick;
//! * `/events`: the run's events as `foxglove.Log` messages (time, level, message, name: the
//!   log panels of Foxglove and Lichtblick list them) with the columns of `events.csv` beside
//!   them; `/summary`: the summary's deterministic part (written after the analysis); `/perf`:
//!   its wall-clock part.
//!
//! A message's `step` is the row of `timeseries.csv` that holds its values, and its log time
//! is that row's time, step·dt in ns: everything exchanged in tick k (what each participant
//! received, the controller's answer, the links) and the outputs after it are step k + 1 at
//! t_(k+1), as the table holds them in row k + 1 (`rx_*`, the controller's columns); the plant's
//! and the actuator's outputs at t_0 are step 0. Events are at their tick's time, the summary
//! at the end. docs/studies.md, "Joining a recording and the table", lists the column of every
//! field. Log times never decrease through the file, and the chunks are
//! zstd-compressed. Publish time is the wall clock of the two-clock trace (`CLOCK_MONOTONIC`
//! ns: request sent for `in`, reply received for `out`; the log time on the wall-clock-free
//! channels). Every channel declares a JSON schema whose fields are numbers; a non-finite
//! value is left out of its message. The messages of a run repeat exactly when the run does;
//! only publish times and `/perf` differ.

use std::collections::{BTreeMap, VecDeque};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use cosim::msg::{FromActuator, FromController, FromPlant, ToActuator, ToController, ToPlant};
use cosim::Role;

use tiltsim_formats::events::EventLog;
use tiltsim_scenario::links::LinkId;

/// One channel: its id and its fields (the schema's properties, in message order).
struct Channel {
    id: u16,
    seq: u32,
}

/// Channel names and the fields of their messages (every field a number but `step`).
const CHANNELS: &[(&str, &[&str])] = &[
    ("/plant/in", &["delta_a"]),
    (
        "/plant/out",
        &[
            "time",
            "s",
            "curvature",
            "cant",
            "y_v",
            "theta_v",
            "y_b",
            "theta_b",
            "dy_v",
            "dtheta_v",
            "dy_b",
            "dtheta_b",
            "theta_r",
            "psi",
            "lat_acc",
            "theta_v_meas",
        ],
    ),
    ("/actuator/in", &["delta_a_cmd", "psi"]),
    (
        "/actuator/out",
        &[
            "delta_a",
            "delta_a_ref",
            "motor_torque",
            "motor_speed",
            "motor_current",
            "dc_power",
            "phase_current_peak",
            "v_dc",
            "chopper_power",
            "actuator_limits",
        ],
    ),
    ("/controller/in", &["time", "s", "theta_v_meas"]),
    (
        "/controller/out",
        &["delta_a_cmd", "theta_ref", "theta_v_hat", "solver_status"],
    ),
    ("/links/actuator_command", &["sent", "received"]),
    ("/links/bar_angle", &["sent", "received"]),
    ("/links/measurement", &["sent", "received"]),
    ("/links/bar_twist", &["sent", "received"]),
];

/// Fields of a free run's timing channels, `/timing/plant`, `/timing/actuator` and
/// `/timing/controller`: one message per step, the columns of `timing.csv` (instants in ns
/// since the common start instant; a producer that is not an input of the role is left out).
pub const TIMING_FIELDS: &[&str] = &[
    "from_plant",
    "from_actuator",
    "from_controller",
    "age_plant",
    "age_actuator",
    "age_controller",
    "due_ns",
    "read_ns",
    "compute_end_ns",
    "publish_ns",
    "late_start",
    "late_finish",
];

/// The timing channels, in `Role` order.
const TIMING_CHANNELS: [&str; 3] = ["/timing/plant", "/timing/actuator", "/timing/controller"];

/// The fields of channel `topic`.
pub fn fields(topic: &str) -> &'static [&'static str] {
    if TIMING_CHANNELS.contains(&topic) {
        return TIMING_FIELDS;
    }
    CHANNELS
        .iter()
        .find(|(t, _)| *t == topic)
        .map_or(&[], |(_, f)| f)
}

/// The values of a plant's output, in the order of `/plant/out`.
pub fn plant_out(p: &FromPlant) -> Vec<f64> {
    let mut v = vec![p.t, p.s, p.curvature, p.cant];
    v.extend_from_slice(&p.x);
    v.extend_from_slice(&[p.psi, p.lat_acc, p.theta_v_meas]);
    v
}

/// The values of an actuator's output, in the order of `/actuator/out`.
pub fn actuator_out(a: &FromActuator) -> Vec<f64> {
    vec![
        a.delta_a,
        a.delta_a_ref,
        a.motor_torque,
        a.motor_speed,
        a.motor_current,
        a.dc_power,
        a.phase_current_peak,
        a.v_dc,
        a.chopper_power,
        f64::from(a.limits),
    ]
}

/// The values of a controller's output, in the order of `/controller/out`.
pub fn controller_out(c: &FromController) -> Vec<f64> {
    vec![
        c.delta_a_cmd,
        c.theta_ref,
        c.theta_v_hat,
        f64::from(c.solver_status),
    ]
}

/// A plant's request from the values of `/plant/in`.
pub fn plant_in(v: &[f64]) -> ToPlant {
    ToPlant {
        delta_a: v[0],
        ..Default::default()
    }
}

/// An actuator's request from the values of `/actuator/in`.
pub fn actuator_in(v: &[f64]) -> ToActuator {
    ToActuator {
        delta_a_cmd: v[0],
        psi: v[1],
        ..Default::default()
    }
}

/// A controller's request from the values of `/controller/in`.
pub fn controller_in(v: &[f64]) -> ToController {
    ToController {
        t: v[0],
        s: v[1],
        theta_v_meas: v[2],
        ..Default::default()
    }
}

/// A JSON schema for a message of `step` and `fields`: every field a number, none required (a
/// non-finite value is left out of its message, since JSON has no NaN).
fn schema(title: &str, fields: &[&str]) -> String {
    let mut props = vec![r#""step":{"type":"integer","description":"tick"}"#.to_string()];
    props.extend(
        fields
            .iter()
            .map(|f| format!(r#""{f}":{{"type":"number"}}"#)),
    );
    format!(
        r#"{{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"{title}","type":"object","properties":{{{}}}}}"#,
        props.join(",")
    )
}

/// A JSON message: `step` and the values (shortest round trip). A NaN or an infinity is left
/// out, as the schema allows: readers see a gap, as they would in a plot of the CSV.
pub fn message(step: u64, fields: &[&str], values: &[f64]) -> String {
    let mut s = format!("{{\"step\":{step}");
    for (f, v) in fields.iter().zip(values) {
        if !v.is_finite() {
            continue;
        }
        s.push_str(",\"");
        s.push_str(f);
        s.push_str("\":");
        tiltsim_formats::table::put_f64(*v, &mut s);
    }
    s.push('}');
    s
}

/// Writes `run.mcap` as the run goes, in log-time order: a tick's inputs, links and controller
/// messages at t_k, then the events of tick k, then the plant's and the actuator's outputs at
/// t_(k+1), the time their values hold at.
pub struct McapRecorder {
    out: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    dt_ns: u64,
    channels: Vec<Channel>,
    events: u16,
    summary: u16,
    perf: u16,
    /// Events not yet written, in the order of the run's event log.
    queued: VecDeque<EventMessage>,
    /// Events taken from the run's event log so far.
    taken: usize,
    /// Events written so far (their sequence numbers).
    written: u32,
    /// The largest log time written so far: no message goes below it.
    last_log: u64,
}

fn named(path: &Path, e: impl std::fmt::Display) -> std::io::Error {
    std::io::Error::other(format!("{}: {e}", path.display()))
}

impl McapRecorder {
    /// Creates `path` with every channel and schema; ticks are `dt` s apart.
    pub fn create(path: &Path, dt: f64) -> std::io::Result<Self> {
        Self::create_with(path, dt, false)
    }

    /// [`McapRecorder::create`] for a free run: with the timing channels too.
    pub fn create_free(path: &Path, dt: f64) -> std::io::Result<Self> {
        Self::create_with(path, dt, true)
    }

    fn create_with(path: &Path, dt: f64, timing: bool) -> std::io::Result<Self> {
        let file = BufWriter::new(File::create(path).map_err(|e| named(path, e))?);
        let opts = mcap::WriteOptions::new()
            .library(concat!("tiltsim ", env!("CARGO_PKG_VERSION")))
            .profile("")
            .compression(Some(mcap::Compression::Zstd))
            // zstd's fastest level: half the CPU of its default (3) on a paper-mpc recording
            // (0.07 against 0.15 s for 26 MB of JSON) at a like size.
            .compression_level(1);
        let mut out = opts.create(file).map_err(|e| named(path, e))?;
        let mut add = |schema_name: &str, topic: &str, text: &str| {
            let sid = out
                .add_schema(schema_name, "jsonschema", text.as_bytes())
                .map_err(|e| named(path, e))?;
            out.add_channel(sid, topic, "json", &BTreeMap::new())
                .map_err(|e| named(path, e))
        };
        let mut channels = Vec::new();
        for (topic, fields) in CHANNELS {
            channels.push(Channel {
                id: add(topic, topic, &schema(topic, fields))?,
                seq: 0,
            });
        }
        if timing {
            for topic in TIMING_CHANNELS {
                channels.push(Channel {
                    id: add(topic, topic, &schema(topic, TIMING_FIELDS))?,
                    seq: 0,
                });
            }
        }
        let events = add("foxglove.Log", "/events", EVENT_SCHEMA)?;
        let summary = add("tiltsim.Summary", "/summary", SUMMARY_SCHEMA)?;
        let perf = add("tiltsim.Perf", "/perf", PERF_SCHEMA)?;
        Ok(McapRecorder {
            out,
            path: path.to_path_buf(),
            dt_ns: (dt * 1e9).round() as u64,
            channels,
            events,
            summary,
            perf,
            queued: VecDeque::new(),
            taken: 0,
            written: 0,
            last_log: 0,
        })
    }

    /// Queues `events` (in the run's order) to be written at their ticks.
    pub(crate) fn queue_events(&mut self, events: impl IntoIterator<Item = EventMessage>) {
        self.queued.extend(events);
    }

    /// Queues the events of `log` not taken yet.
    pub(crate) fn take_events(&mut self, log: &[tiltsim_formats::events::Event]) {
        let new = log.get(self.taken..).unwrap_or(&[]);
        self.taken += new.len();
        self.queued.extend(new.iter().map(EventMessage::from));
    }

    /// Writes the queued events of ticks up to `k` (all of them for `None`), in the log's
    /// order, each at its own time or, for one logged after later messages, at the latest
    /// log time written.
    fn write_events(&mut self, k: Option<u64>) -> std::io::Result<()> {
        while let Some(e) = self.queued.front() {
            if k.is_some_and(|k| e.step > k) {
                break;
            }
            let e = self.queued.pop_front().unwrap_or_else(|| unreachable!());
            let log = ((e.t * 1e9).round().max(0.0) as u64).max(self.last_log);
            self.written += 1;
            self.put_on(self.events, self.written, log, &e.json(self.dt_ns))?;
        }
        Ok(())
    }

    fn put(&mut self, channel: usize, log: u64, publish: u64, data: &str) -> std::io::Result<()> {
        self.last_log = self.last_log.max(log);
        let c = &mut self.channels[channel];
        c.seq += 1;
        let header = mcap::records::MessageHeader {
            channel_id: c.id,
            sequence: c.seq,
            log_time: log,
            publish_time: publish,
        };
        self.out
            .write_to_known_channel(&header, data.as_bytes())
            .map_err(|e| named(&self.path, e))
    }

    fn put_on(&mut self, id: u16, seq: u32, log: u64, data: &str) -> std::io::Result<()> {
        self.last_log = self.last_log.max(log);
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence: seq,
            log_time: log,
            publish_time: log,
        };
        self.out
            .write_to_known_channel(&header, data.as_bytes())
            .map_err(|e| named(&self.path, e))
    }

    /// Writes the events not written yet, the summary's deterministic part and its wall-clock
    /// part, and closes the file.
    pub fn finish(
        mut self,
        events: &EventLog,
        summary: &super::Summary,
    ) -> std::io::Result<PathBuf> {
        self.take_events(&events.events);
        let det = super::summary::deterministic(serde_json::to_value(summary).unwrap_or_default());
        let end = summary.steps_completed * self.dt_ns;
        self.close(&det, &summary.perf(), end)
    }

    /// Writes the queued events, the summary's deterministic part `det` and its wall-clock
    /// part `perf` (at log time `end`, or the latest written if later), and closes the file.
    pub(crate) fn close(
        mut self,
        det: &serde_json::Value,
        perf: &serde_json::Value,
        end: u64,
    ) -> std::io::Result<PathBuf> {
        self.write_events(None)?;
        let end = end.max(self.last_log);
        self.put_on(self.summary, 1, end, &det.to_string())?;
        self.put_on(self.perf, 1, end, &perf.to_string())?;
        self.out.finish().map_err(|e| named(&self.path, e))?;
        Ok(self.path)
    }
}

/// The schema of `/events`: Foxglove's `foxglove.Log` (timestamp, level, message, name, file,
/// line) and the columns of `events.csv` (step, time, source, kind, value, detail).
const EVENT_SCHEMA: &str = concat!(
    r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"foxglove.Log","#,
    r#""description":"A run event as a log message, with the columns of events.csv","#,
    r#""type":"object","properties":{"#,
    r#""timestamp":{"type":"object","title":"time","description":"Simulated time of the event","#,
    r#""properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"#,
    r#""level":{"type":"integer","title":"foxglove.LogLevel","description":"1 debug, 2 info, 3 warning, 4 error, 5 fatal","#,
    r#""oneOf":[{"title":"UNKNOWN","const":0},{"title":"DEBUG","const":1},{"title":"INFO","const":2},"#,
    r#"{"title":"WARNING","const":3},{"title":"ERROR","const":4},{"title":"FATAL","const":5}]},"#,
    r#""message":{"type":"string","description":"What happened, in words"},"#,
    r#""name":{"type":"string","description":"The link or participant it happened to"},"#,
    r#""file":{"type":"string","description":"Empty: events come from the run, not from a source line"},"#,
    r#""line":{"type":"integer","minimum":0,"description":"0"},"#,
    r#""step":{"type":"integer","minimum":0,"description":"Tick (the row of timeseries.csv)"},"#,
    r#""time":{"type":"number","description":"Simulated time (s)"},"#,
    r#""source":{"type":"string"},"kind":{"type":"string","description":"The event column of events.csv"},"#,
    r#""value":{"type":"number","description":"The number that goes with it, if any"},"#,
    r#""detail":{"type":"string"}},"#,
    r#""required":["timestamp","level","message","name","file","line","step","time","source","kind","detail"]}"#
);

/// The schema of `/summary`: one message at the end, `summary.json` without the fields its
/// `wall_clock_fields` lists (docs/outputs.md describes every key).
const SUMMARY_SCHEMA: &str = concat!(
    r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"tiltsim.Summary","#,
    r#""description":"The run's summary.json without the fields named in its wall_clock_fields, which /perf holds: "#,
    r#"what repeats exactly when the run does (docs/outputs.md lists every key and its unit)","#,
    r#""type":"object","properties":{"#,
    r#""scenario":{"type":"string"},"seed":{"type":"integer","minimum":0},"#,
    r#""status":{"type":"string","enum":["completed","degraded","failed","interrupted"]},"#,
    r#""steps_completed":{"type":"integer","minimum":0},"#,
    r#""wall_clock_fields":{"type":"array","items":{"type":"string"},"description":"The summary.json fields left out here"},"#,
    r#""comfort":{"type":"object"},"flags":{"type":"object"},"results":{"type":"object"},"#,
    r#""participants":{"type":"array","items":{"type":"object"}}},"#,
    r#""required":["scenario","status","steps_completed","wall_clock_fields"]}"#
);

/// The schema of `/perf`: one message at the end, the run's `perf.json`.
const PERF_SCHEMA: &str = concat!(
    r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"tiltsim.Perf","#,
    r#""description":"The run's perf.json: the wall-clock fields of summary.json (wall time, real-time factor, "#,
    r#"per-tick timing, link latency, pacing, each participant's pid, CPU and compute time); differs from run to run","#,
    r#""type":"object"}"#
);

/// One event as recorded.
pub(crate) struct EventMessage {
    pub step: u64,
    pub t: f64,
    pub source: String,
    pub kind: String,
    pub value: f64,
    pub detail: String,
    /// Its `foxglove.LogLevel`.
    pub level: u8,
}

/// The `foxglove.LogLevel` of an event kind: the per-sample link effects are debug detail,
/// the set-up and the windows information, faults and what the run did about them warnings,
/// a participant lost or a drive's protection tripping an error, a run that stopped fatal.
pub(crate) fn level(kind: tiltsim_formats::events::EventKind) -> u8 {
    use tiltsim_formats::events::EventKind as K;
    match kind {
        K::Drop | K::Jitter => 1,
        K::Delay | K::JitterOn | K::DropOn | K::Bias | K::Noise | K::ChopperOn => 2,
        K::DropWindow | K::FreezeWindow | K::NanWindow | K::ValueWindow => 2,
        K::FaultInjected | K::Degraded | K::BadInputHeld | K::Manipulated => 3,
        K::NetworkRefused => 3,
        K::ParticipantLost | K::OvercurrentTrip | K::OvervoltageTrip => 4,
        K::RunFailed => 5,
    }
}

impl From<&tiltsim_formats::events::Event> for EventMessage {
    fn from(e: &tiltsim_formats::events::Event) -> Self {
        EventMessage {
            step: e.step,
            t: e.time,
            source: e.source.clone(),
            kind: serde_json::to_value(e.kind)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default(),
            value: e.value,
            detail: e.detail.clone(),
            level: level(e.kind),
        }
    }
}

impl EventMessage {
    /// The event as a `foxglove.Log` message with the columns of `events.csv`; an event
    /// without a value (NaN) has no `value` field.
    fn json(&self, dt_ns: u64) -> String {
        let (value, words) = if self.value.is_finite() {
            let v = tiltsim_formats::table::fmt_f64(self.value);
            (format!(",\"value\":{v}"), format!(" ({v})"))
        } else {
            (String::new(), String::new())
        };
        let detail = if self.detail.is_empty() {
            String::new()
        } else {
            format!(": {}", self.detail)
        };
        let ns = self.step * dt_ns;
        let message = format!("{}{words}{detail}", self.kind);
        format!(
            "{{\"timestamp\":{{\"sec\":{},\"nsec\":{}}},\"level\":{},\"message\":{},\"name\":{},\"file\":\"\",\"line\":0,\
             \"step\":{},\"time\":{},\"source\":{},\"kind\":{}{value},\"detail\":{}}}",
            ns / 1_000_000_000,
            ns % 1_000_000_000,
            self.level,
            serde_json::Value::from(message),
            serde_json::Value::from(self.source.as_str()),
            self.step,
            tiltsim_formats::table::fmt_f64(self.t),
            serde_json::Value::from(self.source.as_str()),
            serde_json::Value::from(self.kind.as_str()),
            serde_json::Value::from(self.detail.as_str()),
        )
    }
}

/// Channel index of a role's `in` (the `out` is the next one).
pub(crate) fn inbox(role: Role) -> usize {
    2 * role as usize
}

/// Channel index of a link's `/links/<name>`.
pub(crate) fn link_channel(link: LinkId) -> usize {
    6 + link as usize
}

/// Channel index of a role's `/timing/<role>` (recorders made by
/// [`McapRecorder::create_free`]).
pub(crate) fn timing_channel(role: Role) -> usize {
    CHANNELS.len() + role as usize
}

impl McapRecorder {
    /// Writes one message on channel index `channel` (see [`inbox`], [`link_channel`],
    /// [`timing_channel`]) with the fields of its topic.
    pub(crate) fn put_values(
        &mut self,
        channel: usize,
        step: u64,
        log: u64,
        publish: u64,
        values: &[f64],
    ) -> std::io::Result<()> {
        let fields = if channel >= CHANNELS.len() {
            TIMING_FIELDS
        } else {
            CHANNELS[channel].1
        };
        let m = message(step, fields, values);
        self.put(channel, log, publish, &m)
    }

    /// Writes the queued events of ticks up to `k`.
    pub(crate) fn events_until(&mut self, k: u64) -> std::io::Result<()> {
        self.write_events(Some(k))
    }

    /// The base tick in ns.
    pub(crate) fn dt_ns(&self) -> u64 {
        self.dt_ns
    }
}

/// One tick as the recording holds it.
pub(crate) struct TickData<'a> {
    /// Tick.
    pub k: u64,
    /// Whether the controller was stepped.
    pub due: bool,
    /// The controller's request.
    pub to_controller: &'a ToController,
    /// Outputs after the tick.
    pub p: &'a FromPlant,
    /// Outputs after the tick.
    pub a: &'a FromActuator,
    /// Outputs after the tick.
    pub c: &'a FromController,
    /// What each receiver got, in `LinkId` order.
    pub rx: &'a [f64; 4],
    /// What each sender sent, in `LinkId` order.
    pub tx: &'a [f64; 4],
    /// Wall clock (ns) of each role's request sent and reply received, in `Role` order;
    /// `None` where not measured (then the log time is used).
    pub wall: [Option<(u64, u64)>; 3],
}

impl McapRecorder {
    /// Writes the plant's and the actuator's outputs at t_0 (step 0, log time 0), before any
    /// tick: the values of the table's first row.
    pub(crate) fn at_start(&mut self, p: &FromPlant, a: &FromActuator) -> std::io::Result<()> {
        let (i, j) = (inbox(Role::Actuator) + 1, inbox(Role::Plant) + 1);
        let m = message(0, CHANNELS[i].1, &actuator_out(a));
        self.put(i, 0, 0, &m)?;
        let m = message(0, CHANNELS[j].1, &plant_out(p));
        self.put(j, 0, 0, &m)
    }

    /// Writes one tick's messages: the queued events of tick k (at t_k), then what the
    /// participants received, the controller's answer, the links and the actuator's and the
    /// plant's outputs, each as step k + 1 at t_(k+1): the row of `timeseries.csv` that holds
    /// tick k's exchanges (`rx_*`) and outputs.
    pub(crate) fn write_tick(&mut self, d: &TickData) -> std::io::Result<()> {
        self.write_events(Some(d.k))?;
        let row = d.k + 1;
        let log = row * self.dt_ns;
        let when = |role: Role| d.wall[role as usize].unwrap_or((log, log));
        let rx = d.rx;
        let ch = |i: usize| CHANNELS[i].1;
        if d.due {
            let (sent, got) = when(Role::Controller);
            let c = d.to_controller;
            let i = inbox(Role::Controller);
            let m = message(row, ch(i), &[c.t, c.s, c.theta_v_meas]);
            self.put(i, log, sent, &m)?;
            let m = message(row, ch(i + 1), &controller_out(d.c));
            self.put(i + 1, log, got, &m)?;
        }
        let (a_sent, a_got) = when(Role::Actuator);
        let i = inbox(Role::Actuator);
        let command = [
            rx[LinkId::ActuatorCommand as usize],
            rx[LinkId::BarTwist as usize],
        ];
        self.put(i, log, a_sent, &message(row, ch(i), &command))?;
        let (p_sent, p_got) = when(Role::Plant);
        let j = inbox(Role::Plant);
        let bar = [rx[LinkId::BarAngle as usize]];
        self.put(j, log, p_sent, &message(row, ch(j), &bar))?;
        for link in LinkId::ALL {
            let l = link_channel(link);
            let m = message(row, ch(l), &[d.tx[link as usize], rx[link as usize]]);
            self.put(l, log, log, &m)?;
        }
        let m = message(row, ch(i + 1), &actuator_out(d.a));
        self.put(i + 1, log, a_got, &m)?;
        let m = message(row, ch(j + 1), &plant_out(d.p));
        self.put(j + 1, log, p_got, &m)
    }
}
