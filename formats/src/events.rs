//! `events.csv`: what happened during a run, in simulated time only (so it repeats byte for
//! byte). [`EventKind`] is the vocabulary; the file is written with the `csv` crate.

use std::path::Path;

use serde::{Deserialize, Serialize};

/// Every kind of event `events.csv` can hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EventKind {
    /// A link's fixed delay (at t = 0; value: ticks).
    Delay,
    /// A link's jitter is on (at t = 0; value: scale in ticks).
    JitterOn,
    /// A link's random loss is on (at t = 0; value: probability).
    DropOn,
    /// A link's bias (at t = 0; value: offset).
    Bias,
    /// A link's noise (at t = 0; value: standard deviation).
    Noise,
    /// A sample was lost (value: the sample).
    Drop,
    /// A sample was delayed by jitter (value: total delay in ticks).
    Jitter,
    /// A drop window begins or ends.
    DropWindow,
    /// A freeze window begins or ends.
    FreezeWindow,
    /// A NaN window begins or ends.
    NanWindow,
    /// A value-override window begins or ends.
    ValueWindow,
    /// A scheduled process fault was applied (value: stall seconds).
    FaultInjected,
    /// A participant failed and was replaced.
    ParticipantLost,
    /// The run continues in degraded mode.
    Degraded,
    /// A non-finite input was replaced by the last good one.
    BadInputHeld,
    /// The run stopped on an error.
    RunFailed,
    /// The drive's over-current protection blocked its gates (value: phase current, A).
    OvercurrentTrip,
    /// The drive's over-voltage protection blocked its gates (value: link voltage, V).
    OvervoltageTrip,
    /// The braking chopper switched on (value: link voltage, V).
    ChopperOn,
    /// A caller's manipulator acted (`engine::manipulate`; detail: in its own words).
    Manipulated,
    /// Someone on the network tried to reach the run without the right to and was refused
    /// (at the step the run was at when it was seen; detail: who and why).
    NetworkRefused,
}

/// One line of `events.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    /// Simulated time (s), when tick `step` starts.
    pub time: f64,
    /// Tick.
    pub step: u64,
    /// Link or participant.
    pub source: String,
    /// What happened.
    pub kind: EventKind,
    /// A number that goes with it (delay in ticks, value, ...), or NaN (written empty).
    pub value: f64,
    /// Words.
    pub detail: String,
}

/// `events.csv` columns.
pub const EVENT_COLUMNS: [&str; 6] = ["time", "step", "source", "event", "value", "detail"];

/// The events of a run, in the order they happened.
#[derive(Debug, Clone, Default)]
pub struct EventLog {
    dt: f64,
    /// The events.
    pub events: Vec<Event>,
}

impl EventLog {
    /// An empty log for a run with base tick `dt` (s).
    pub fn new(dt: f64) -> Self {
        EventLog {
            dt,
            events: Vec::new(),
        }
    }

    /// An empty log with the same base tick, for events kept aside and appended later.
    pub fn aside(&self) -> Self {
        EventLog::new(self.dt)
    }

    /// Appends the events of `other` (kept aside with [`EventLog::aside`]), in their order.
    pub fn append(&mut self, other: EventLog) {
        self.events.extend(other.events);
    }

    /// Logs an event at tick `k`.
    pub fn push(
        &mut self,
        k: u64,
        source: &str,
        kind: EventKind,
        value: f64,
        detail: impl Into<String>,
    ) {
        self.events.push(Event {
            step: k,
            time: tiltsim_protocol::time::tick_time(k, self.dt),
            source: source.to_string(),
            kind,
            value,
            detail: detail.into(),
        });
    }

    /// Logs an event at tick `k` after every event logged so far at or before `k` (for events
    /// seen outside the loop and logged when it ends).
    pub fn insert(
        &mut self,
        k: u64,
        source: &str,
        kind: EventKind,
        value: f64,
        detail: impl Into<String>,
    ) {
        let at = self.events.partition_point(|e| e.step <= k);
        self.push(k, source, kind, value, detail);
        let e = self.events.pop().expect("just pushed");
        self.events.insert(at, e);
    }

    /// Writes `events.csv`, whole or not at all.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let mut w = csv::Writer::from_writer(Vec::new());
        w.write_record(EVENT_COLUMNS)
            .map_err(std::io::Error::other)?;
        for e in &self.events {
            let value = if e.value.is_nan() {
                String::new()
            } else {
                crate::float_text::fmt_f64(e.value)
            };
            let kind = serde_json::to_value(e.kind)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default();
            w.write_record([
                crate::float_text::fmt_f64(e.time),
                e.step.to_string(),
                e.source.clone(),
                kind,
                value,
                e.detail.clone(),
            ])
            .map_err(std::io::Error::other)?;
        }
        let bytes = w
            .into_inner()
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        tiltsim_rundir::files::write_atomic(path, bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_are_written_with_their_kind_names_and_text_is_quoted_not_mangled() {
        let dir = std::env::temp_dir().join(format!("tiltsim-events-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut log = EventLog::new(1e-3);
        log.push(
            3,
            "actuator_command",
            EventKind::JitterOn,
            2.0,
            "uniform, 2 ticks",
        );
        log.push(5, "controller", EventKind::RunFailed, f64::NAN, "no reply");
        let p = dir.join("events.csv");
        log.write(&p).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(
            text,
            "time,step,source,event,value,detail\n\
             0.003,3,actuator_command,jitter-on,2.0,\"uniform, 2 ticks\"\n\
             0.005,5,controller,run-failed,,no reply\n"
        );
        let mut rd = csv::Reader::from_path(&p).unwrap();
        let first = rd.records().next().unwrap().unwrap();
        assert_eq!(&first[5], "uniform, 2 ticks");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
