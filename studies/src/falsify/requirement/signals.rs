//! The signals a temporal requirement speaks of: every column of `timeseries.csv` by its
//! name and unit, the tilt error the comfort assessment uses, and the track's transitions as
//! truth values.

use tiltsim_formats::table::{Row, COLUMNS, GETTERS, UNITS};
use tiltsim_scenario::scenario::Scenario;

/// The tilt error θ_v − θ_v^d, the reference of eq 18 at the vehicle's position, as the
/// comfort assessment takes it (`tilt_error_rms_deg`).
pub const TILT_ERROR: &str = "tilt_error";

/// A number-valued signal: a column of the table, or the tilt error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signal {
    /// Column `i` of [`COLUMNS`].
    Column(usize),
    /// θ_v − θ_v^d (rad).
    TiltError,
}

impl Signal {
    /// The signal called `name`, if there is one.
    pub fn named(name: &str) -> Option<Signal> {
        if name == TILT_ERROR {
            return Some(Signal::TiltError);
        }
        COLUMNS.iter().position(|c| *c == name).map(Signal::Column)
    }

    /// Its unit (UCUM, as `columns.csv` gives it).
    pub fn unit(self) -> &'static str {
        match self {
            Signal::Column(i) => UNITS[i],
            Signal::TiltError => "rad",
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Signal::Column(i) => COLUMNS[i],
            Signal::TiltError => TILT_ERROR,
        }
    }
}

/// A truth-valued signal of the track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Event {
    /// On a transition curve: the curvature differs from the step before's (from the next
    /// step's at step 0). A transition's curvature changes with position at every step.
    Transition,
    /// The first step on each transition curve.
    TransitionStart,
    /// The first step after each transition curve.
    TransitionEnd,
}

/// The truth-valued signals' names.
pub const EVENTS: [(&str, Event); 3] = [
    ("transition", Event::Transition),
    ("transition_start", Event::TransitionStart),
    ("transition_end", Event::TransitionEnd),
];

impl Event {
    /// The event called `name`, if there is one.
    pub fn named(name: &str) -> Option<Event> {
        EVENTS.iter().find(|(n, _)| *n == name).map(|(_, e)| *e)
    }
}

/// The signals of one run: its rows and what the derived signals need of its scenario.
pub struct Trace<'a> {
    rows: &'a [Row],
    reference: Option<controller_proc::Controller>,
    /// The plant's step (s).
    pub dt: f64,
}

impl<'a> Trace<'a> {
    /// The signals of the rows of a run of `s`.
    pub fn new(s: &Scenario, rows: &'a [Row]) -> Trace<'a> {
        Trace {
            rows,
            reference: controller_proc::Controller::new(&s.controller_init()).ok(),
            dt: s.run.dt_s,
        }
    }

    /// Rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The signal's value at every row.
    pub fn values(&self, signal: Signal) -> Vec<f64> {
        match signal {
            Signal::Column(i) => self.rows.iter().map(GETTERS[i]).collect(),
            Signal::TiltError => self
                .rows
                .iter()
                .map(|r| {
                    let reference = self
                        .reference
                        .as_ref()
                        .map_or(r.theta_ref, |c| c.reference_at(r.s));
                    r.theta_v - reference
                })
                .collect(),
        }
    }

    /// The event's truth at every row.
    pub fn truth(&self, event: Event) -> Vec<bool> {
        let n = self.rows.len();
        let on: Vec<bool> = (0..n)
            .map(|k| {
                let other = if k == 0 { 1 } else { k - 1 };
                other < n && self.rows[k].curvature != self.rows[other].curvature
            })
            .collect();
        match event {
            Event::Transition => on,
            Event::TransitionStart => (0..n).map(|k| on[k] && (k == 0 || !on[k - 1])).collect(),
            Event::TransitionEnd => (0..n).map(|k| !on[k] && k > 0 && on[k - 1]).collect(),
        }
    }
}
