//! The events of a free run or its replay as the run goes, in the order of its `events.csv`
//! ([`super::run_events`]), for the recording and the replay's observers, which take them
//! tick by tick.

use super::compose::Store;
use tiltsim_formats::events::Event;
use tiltsim_scenario::scenario::Scenario;

/// Hands on the events of each tick once, in the order of `events.csv`.
pub(crate) struct EventFeed {
    /// The events that do not come from the links (the links' set-up and every scheduled
    /// fault of the run), in the order of `events.csv`, and how many of them are handed on.
    planned: Vec<Event>,
    planned_given: usize,
    /// Per link, how many of its events are handed on.
    link_given: [usize; 4],
    /// Events handed on in all: the prefix of the run's `events.csv` they are.
    pub given: usize,
}

impl EventFeed {
    pub fn new(s: &Scenario) -> Self {
        EventFeed {
            planned: super::planned_events(s, s.steps()).events,
            planned_given: 0,
            link_given: [0; 4],
            given: 0,
        }
    }

    /// The events of ticks up to `k` not handed on yet, in the order of `events.csv` (a
    /// tick's planned events before the links'). Every link must have logged its events of
    /// those ticks ([`Store::events_complete_through`]).
    pub fn through(&mut self, store: &Store, k: u64) -> Vec<Event> {
        let planned = &self.planned[self.planned_given..];
        let n = planned.iter().take_while(|e| e.step <= k).count();
        let links = store.link_events_through(k, &mut self.link_given);
        let merged = merge_by_tick(planned[..n].to_vec(), links);
        self.planned_given += n;
        self.given += merged.len();
        merged
    }
}

/// Merges two lists of events, each in tick order, into one in tick order: at a tick, the
/// events of `first` before those of `then` (a tick's planned events before the links').
pub(crate) fn merge_by_tick(first: Vec<Event>, then: Vec<Event>) -> Vec<Event> {
    let mut merged = Vec::with_capacity(first.len() + then.len());
    let (mut a, mut b) = (first.into_iter().peekable(), then.into_iter().peekable());
    loop {
        let take_a = match (a.peek(), b.peek()) {
            (Some(x), Some(y)) => x.step <= y.step,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => break,
        };
        merged.extend(if take_a { a.next() } else { b.next() });
    }
    merged
}
