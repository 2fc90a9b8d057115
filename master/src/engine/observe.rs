//! The open seam of the lock-step engine: an [`Observer`] a caller writes and adds to a
//! [`Run`](super::Run), told about the run as it goes without being able to change it.
//!
//! Lifecycle, in this order and each on the thread that runs the lock-step:
//! 1. [`Observer::start`] once, with the outputs at t₀ (row 0 of `timeseries.csv`), before the
//!    first tick;
//! 2. [`Observer::tick`] after every tick's exchanges, in tick order, with the outputs at the
//!    end of the tick (row k + 1) and what each link carried;
//! 3. [`Observer::close`] once after the last tick (or the failure or interrupt that ended the
//!    loop), before the participants are stopped: an observer that writes a file completes it
//!    here;
//! 4. [`Observer::finish`] once, also when the run failed or was interrupted (the summary says
//!    which), with the engine's summary; what it returns is its part of `summary.json`, under
//!    `observers.<name>`.
//!
//! An error from `start`, `tick` or `close` stops the run as a failed write does: the run ends
//! with what was recorded so far and its summary names the error. Observers run after the
//! engine's own measurements (tick timing, compute, latency, pacing, the drive's protection
//! events), in the order they were added; a tick's wall time does not include them.
//!
//! The engine writes no series of its own: the rows (`timeseries.csv` or in memory), the
//! trace, the MCAP recording and the progress are observers too ([`super::outputs`]), added
//! by the caller in the order it wants them told.

use cosim::msg::{FromActuator, FromController, FromPlant, Header, ToController};
use cosim::Role;
use tiltsim_formats::events::Event;

use super::Summary;

/// One request to a participant and its reply, stamped on the monotonic clock
/// ([`cosim::msg::now_ns`], ns; all zero when the run measures no wall-clock times).
#[derive(Debug, Clone, Copy)]
pub struct Exchange {
    /// The tick it belongs to (the initialisation's exchanges count as tick 0's).
    pub step: u64,
    /// The participant asked.
    pub role: Role,
    /// The orchestrator sent the request.
    pub sent_ns: u64,
    /// The reply's header (the participant's receive and send times, its compute time).
    pub reply: Header,
    /// The orchestrator had the reply.
    pub received_ns: u64,
}

/// What each of the four links carried in one tick, by link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkValues {
    /// Controller → actuator: the bar angle command δ_a,cmd (rad).
    pub actuator_command: f64,
    /// Actuator → plant: the achieved bar angle δ_a (rad).
    pub bar_angle: f64,
    /// Plant → controller: the measured body roll θ_v (rad).
    pub measurement: f64,
    /// Plant → actuator: the body-to-bogie roll ψ the bar sees (rad).
    pub bar_twist: f64,
}

impl LinkValues {
    /// In the engine's `LinkId` order.
    pub(crate) fn ordered(&self) -> [f64; 4] {
        use tiltsim_scenario::links::LinkId;
        let mut v = [0.0; 4];
        v[LinkId::ActuatorCommand as usize] = self.actuator_command;
        v[LinkId::BarAngle as usize] = self.bar_angle;
        v[LinkId::Measurement as usize] = self.measurement;
        v[LinkId::BarTwist as usize] = self.bar_twist;
        v
    }

    /// From the engine's `LinkId`-ordered array.
    pub(crate) fn from_ordered(v: &[f64; 4]) -> Self {
        use tiltsim_scenario::links::LinkId;
        LinkValues {
            actuator_command: v[LinkId::ActuatorCommand as usize],
            bar_angle: v[LinkId::BarAngle as usize],
            measurement: v[LinkId::Measurement as usize],
            bar_twist: v[LinkId::BarTwist as usize],
        }
    }
}

/// The start of a run, as [`Observer::start`] sees it.
#[derive(Debug)]
pub struct Start<'a> {
    /// The scenario's name.
    pub scenario: &'a str,
    /// Base tick (s).
    pub dt_s: f64,
    /// Ticks planned.
    pub steps: u64,
    /// The plant's outputs at t₀.
    pub plant: &'a FromPlant,
    /// The actuator's outputs at t₀.
    pub actuator: &'a FromActuator,
    /// The controller's outputs at t₀.
    pub controller: &'a FromController,
}

/// One finished tick, as [`Observer::tick`] sees it.
#[derive(Debug)]
pub struct Tick<'a> {
    /// Tick index k: the tick from t_k to t_(k+1).
    pub k: u64,
    /// t_(k+1) (s), the time the outputs below hold at (the `time` of row k + 1).
    pub time: f64,
    /// The plant's outputs at t_(k+1).
    pub plant: &'a FromPlant,
    /// The actuator's outputs at t_(k+1).
    pub actuator: &'a FromActuator,
    /// The controller's latest outputs (its answer of this tick when it was stepped).
    pub controller: &'a FromController,
    /// Whether the controller was stepped this tick (every `controller.period_s`).
    pub controller_stepped: bool,
    /// The controller's request, when it was stepped.
    pub to_controller: Option<&'a ToController>,
    /// What each link's sender sent this tick.
    pub sent: LinkValues,
    /// What each link's receiver got this tick (after the link's effects: delay, loss,
    /// noise, bias, faults).
    pub received: LinkValues,
    /// This tick's requests and replies, in the order they were made (tick 0's begin with
    /// the initialisation's).
    pub exchanges: &'a [Exchange],
    /// Every event of the run so far (`events.csv`), in the log's order: the link effects
    /// described at the start, faults, losses, the drive's protections up to this tick.
    pub events: &'a [Event],
}

/// Something that watches a run without changing it (see the module's lifecycle).
pub trait Observer: Send {
    /// Its name: the key of its part of `summary.json` (`observers.<name>`). Names of one
    /// run's observers must differ.
    fn name(&self) -> &str;

    /// Before the first tick, with the outputs at t₀.
    fn start(&mut self, _start: &Start<'_>) -> std::io::Result<()> {
        Ok(())
    }

    /// After tick `tick.k`'s exchanges.
    fn tick(&mut self, tick: &Tick<'_>) -> std::io::Result<()>;

    /// After the last tick, before the participants are stopped: completes what it writes.
    fn close(&mut self) -> std::io::Result<()> {
        Ok(())
    }

    /// The ticks whose records it holds whole, when that can be fewer than the ticks it was
    /// told about (a file whose last writes failed); the summary's `steps_completed` is the
    /// least of these and the ticks the engine finished.
    fn ticks_kept(&self) -> Option<u64> {
        None
    }

    /// After the last tick (or the failure or interrupt that ended the run early): its part
    /// of `summary.json`, or `None` for none.
    fn finish(&mut self, _summary: &Summary) -> Option<serde_json::Value> {
        None
    }
}

/// Refuses observers of which two share a name (their key in `summary.json`).
pub(crate) fn distinct_names(list: &[Box<dyn Observer>]) -> Result<(), super::RunError> {
    let names: Vec<&str> = list.iter().map(|o| o.name()).collect();
    match names
        .iter()
        .enumerate()
        .find_map(|(i, n)| names[..i].contains(n).then_some(*n))
    {
        Some(dup) => Err(super::RunError::Observer(format!(
            "two observers are named `{dup}`; each needs its own name (its key in summary.json)"
        ))),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::outputs::Rows;
    use crate::engine::{Run, RunError, RunOptions, Status};
    use tiltsim_scenario::scenario::{Scenario, Transport};

    /// Counts what it is told; fails at tick `fail_at` if set.
    struct Counter {
        name: &'static str,
        started: bool,
        ticks: Vec<u64>,
        fail_at: Option<u64>,
        log: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
    }

    impl Observer for Counter {
        fn name(&self) -> &str {
            self.name
        }
        fn start(&mut self, s: &Start<'_>) -> std::io::Result<()> {
            self.started = s.plant.t == 0.0;
            Ok(())
        }
        fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
            if Some(t.k) == self.fail_at {
                return Err(std::io::Error::other("observer gave up"));
            }
            // The plant's own time equals the tick's end time, bit for bit.
            assert_eq!(t.plant.t.to_bits(), t.time.to_bits());
            self.ticks.push(t.k);
            self.log
                .lock()
                .unwrap()
                .push(format!("{}:{}", self.name, t.k));
            Ok(())
        }
        fn finish(&mut self, summary: &crate::engine::Summary) -> Option<serde_json::Value> {
            Some(serde_json::json!({
                "started": self.started,
                "ticks": self.ticks.len(),
                "in_order": self.ticks.windows(2).all(|w| w[1] == w[0] + 1),
                "steps_completed": summary.steps_completed,
            }))
        }
    }

    fn counter(
        name: &'static str,
        fail_at: Option<u64>,
        log: &std::sync::Arc<std::sync::Mutex<Vec<String>>>,
    ) -> Box<Counter> {
        Box::new(Counter {
            name,
            started: false,
            ticks: Vec::new(),
            fail_at,
            log: log.clone(),
        })
    }

    fn short_run(name: &str) -> (Scenario, RunOptions) {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut s = Scenario::load(&root.join("scenarios/paper-passive.toml")).unwrap();
        s.run.transport = Transport::InProcess;
        s.run.duration_s = Some(0.5);
        let dir =
            std::env::temp_dir().join(format!("tiltsim-observe-{name}-{}", std::process::id()));
        let opts = RunOptions::new(dir, "tiltsim".into());
        (s, opts)
    }

    #[test]
    fn observers_see_start_every_tick_in_order_and_report_in_the_summary() {
        let (s, opts) = short_run("order");
        let log = Default::default();
        let (rows, kept) = Rows::in_memory(s.run.dt_s, 0);
        let ran = Run::new(&s, "paper-passive.toml", &opts)
            .add_observer(counter("a", None, &log))
            .add_observer(counter("b", None, &log))
            .add_observer(Box::new(rows))
            .simulate()
            .unwrap();
        assert_eq!(ran.summary.status, Status::Completed);
        let steps = ran.summary.steps_completed;
        assert_eq!(steps, 500);
        for name in ["a", "b"] {
            let part = &ran.summary.observers[name];
            assert_eq!(part["started"], true);
            assert_eq!(part["ticks"], steps);
            assert_eq!(part["in_order"], true);
        }
        // In the order added, tick by tick.
        let log = log.lock().unwrap();
        assert_eq!(&log[..4], ["a:0", "b:0", "a:1", "b:1"]);
        let rows = kept.take().unwrap();
        assert_eq!(rows.len() as u64, steps + 1);
        let _ = std::fs::remove_dir_all(&opts.out_dir);
    }

    #[test]
    fn an_observer_that_fails_ends_the_run_with_what_was_recorded_and_names_are_unique() {
        let (s, opts) = short_run("fail");
        let log = Default::default();
        let (rows, kept) = Rows::in_memory(s.run.dt_s, 0);
        let ran = Run::new(&s, "paper-passive.toml", &opts)
            .add_observer(counter("a", Some(100), &log))
            .add_observer(Box::new(rows))
            .simulate()
            .unwrap();
        assert_eq!(ran.summary.status, Status::Failed);
        assert!(ran
            .summary
            .error
            .as_deref()
            .unwrap_or("")
            .contains("observer gave up"));
        assert_eq!(ran.summary.observers["a"]["ticks"], 100);
        // The rows observer, after the one that failed, was told about ticks 0 to 99.
        assert_eq!(kept.take().unwrap().len(), 101);
        assert_eq!(ran.summary.steps_completed, 100);
        let same = Run::new(&s, "paper-passive.toml", &opts)
            .add_observer(counter("a", None, &log))
            .add_observer(counter("a", None, &log))
            .simulate();
        assert!(matches!(same, Err(RunError::Observer(m)) if m.contains("`a`")));
        let _ = std::fs::remove_dir_all(&opts.out_dir);
    }
}
