//! The caller's observers of a timing replay or a free run ([`crate::engine::observe`]): a
//! replay is a deterministic lock-step run, so it tells observers what the lock-step does,
//! from the rows it composes; a free run tells them the same from the rows it writes.
//!
//! Tick k is told once row k + 1 of `timeseries.csv` is: its plant, actuator and controller
//! outputs are the row's (the plant's output of the tick, the actuator output that step read,
//! the controller output that actuator step read), `received` is what each link delivered to
//! those steps (the row's `rx_*`) and `sent` what its producer published for that sample. The
//! controller counts as stepped in the tick its output first appears in a row, with the
//! request that step read. Events are told as soon as every link has logged those of their
//! tick (a producer that ran ahead of its consumer logs its samples' events before the tick
//! they arrive in is told). A replay asks its participants in the order of the trace's read
//! instants, not tick by tick: `exchanges` is empty.

use super::compose::Store;
use super::feed::EventFeed;
use crate::engine::observe::{LinkValues, Observer, Start, Tick};
use tiltsim_formats::events::Event;
use tiltsim_scenario::scenario::Scenario;

/// The observers of one replay and what they are told beside the rows.
pub(crate) struct ReplayObservers {
    list: Vec<Box<dyn Observer>>,
    feed: EventFeed,
    /// Every event told so far.
    told: Vec<Event>,
    scenario: String,
    steps: u64,
    dt: f64,
    /// The controller step of the last row told.
    last_qc: i64,
}

impl ReplayObservers {
    pub fn new(s: &Scenario, list: Vec<Box<dyn Observer>>) -> Self {
        ReplayObservers {
            list,
            feed: EventFeed::new(s),
            told: Vec::new(),
            scenario: s.name.clone(),
            steps: s.steps(),
            dt: s.run.dt_s,
            last_qc: -1,
        }
    }

    /// Tells each observer the outputs at t₀.
    pub fn start(&mut self, store: &Store) -> std::io::Result<()> {
        let (p, a, c) = &store.init;
        let start = Start {
            scenario: &self.scenario,
            dt_s: self.dt,
            steps: self.steps,
            plant: p,
            actuator: a,
            controller: c,
        };
        self.list.iter_mut().try_for_each(|o| o.start(&start))
    }

    /// Tells each observer tick `k`, whose row is composed from `store`.
    pub fn tick(&mut self, store: &Store, k: u64) -> std::io::Result<()> {
        let Some(r) = store.row_parts(k) else {
            return Ok(());
        };
        let stepped = r.qc >= 0 && r.qc != self.last_qc;
        self.last_qc = r.qc;
        let request = store.controller_input(r.qp_c).filter(|_| stepped);
        let sent_by = |q: i64| store.plant(q).copied().unwrap_or_default();
        let sent = LinkValues {
            actuator_command: r.controller.delta_a_cmd,
            bar_angle: r.actuator.delta_a,
            measurement: sent_by(r.qp_c).theta_v_meas,
            bar_twist: sent_by(r.qp_a).psi,
        };
        if let Some(done) = store.events_complete_through() {
            let new = self.feed.through(store, done.min(k));
            self.told.extend(new);
        }
        let tick = Tick {
            k,
            time: cosim::time::tick_time(k + 1, self.dt),
            plant: r.plant,
            actuator: r.actuator,
            controller: r.controller,
            controller_stepped: stepped,
            to_controller: request.as_ref(),
            sent,
            received: LinkValues::from_ordered(&r.rx),
            exchanges: &[],
            events: &self.told,
        };
        self.list.iter_mut().try_for_each(|o| o.tick(&tick))
    }

    /// Closes every observer; each error, in their order.
    pub fn close(&mut self) -> Vec<String> {
        self.list
            .iter_mut()
            .filter_map(|o| {
                o.close()
                    .err()
                    .map(|e| format!("observer {}: {e}", o.name()))
            })
            .collect()
    }

    /// The observers, for their part of the summary.
    pub fn into_list(self) -> Vec<Box<dyn Observer>> {
        self.list
    }
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use cosim::Role;

    use super::*;
    use crate::engine::{Run, RunOptions, Status, Summary};
    use crate::free::trace::{StepTrace, Trace, TraceHead};
    use tiltsim_scenario::scenario::{Master, Transport};

    /// What an observer saw of one tick, bit for bit.
    type Seen = (u64, u64, u64, u64, u64, bool, u64, Option<u64>, u64);

    /// Notes every tick it is told.
    struct Watch {
        name: &'static str,
        seen: Arc<Mutex<Vec<Seen>>>,
        started: bool,
    }

    impl Observer for Watch {
        fn name(&self) -> &str {
            self.name
        }
        fn start(&mut self, s: &Start<'_>) -> std::io::Result<()> {
            self.started = s.plant.t == 0.0;
            Ok(())
        }
        fn tick(&mut self, t: &Tick<'_>) -> std::io::Result<()> {
            self.seen.lock().unwrap().push((
                t.k,
                t.time.to_bits(),
                t.plant.x[1].to_bits(),
                t.actuator.delta_a.to_bits(),
                t.controller.delta_a_cmd.to_bits(),
                t.controller_stepped,
                t.received.measurement.to_bits(),
                t.to_controller.map(|r| r.theta_v_meas.to_bits()),
                t.sent.bar_twist.to_bits(),
            ));
            Ok(())
        }
        fn finish(&mut self, s: &Summary) -> Option<serde_json::Value> {
            let n = self.seen.lock().unwrap().len();
            Some(
                serde_json::json!({ "started": self.started, "ticks": n, "of": s.steps_completed }),
            )
        }
    }

    /// Rounds the measurement to `q` rad on its way, as a coarse sensor would.
    struct Quantise {
        q: f64,
    }

    impl crate::engine::manipulate::Manipulator for Quantise {
        fn name(&self) -> &str {
            "quantise"
        }
        fn carry(
            &mut self,
            link: tiltsim_scenario::links::LinkId,
            _k: u64,
            _t: f64,
            v: f64,
            _events: &mut tiltsim_formats::events::EventLog,
        ) -> f64 {
            if link == tiltsim_scenario::links::LinkId::Measurement {
                (v / self.q).round() * self.q
            } else {
                v
            }
        }
    }

    fn watch(name: &'static str) -> (Box<Watch>, Arc<Mutex<Vec<Seen>>>) {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let w = Watch {
            name,
            seen: seen.clone(),
            started: false,
        };
        (Box::new(w), seen)
    }

    /// The timing of Gauss-Seidel's data flow as a trace: in each tick the controller (when
    /// due) reads the plant's previous step, the actuator reads that command and the plant's
    /// previous step, then the plant reads the actuator's step of the tick.
    fn gauss_seidel_trace(s: &Scenario) -> Trace {
        let (steps, period) = (s.steps(), s.controller_period_ticks());
        let mut out = Vec::new();
        let at = |k: u64, role: Role, from: [Option<i64>; 3], offset: u64| StepTrace {
            role,
            step: k,
            from,
            due_ns: k * 1_000_000,
            read_ns: k * 1_000_000 + offset,
            compute_end_ns: k * 1_000_000 + offset + 10,
            publish_ns: k * 1_000_000 + offset + 20,
        };
        for k in 0..steps {
            let prev = k as i64 - 1;
            let qc = (k / period * period) as i64;
            if k.is_multiple_of(period) {
                out.push(at(k, Role::Controller, [Some(prev), None, None], 0));
            }
            out.push(at(k, Role::Actuator, [Some(prev), None, Some(qc)], 100));
            out.push(at(k, Role::Plant, [None, Some(k as i64), None], 200));
        }
        Trace {
            head: TraceHead {
                dt_s: s.run.dt_s,
                steps,
                controller_period_ticks: period,
                start_ns: 0,
            },
            steps: out,
            partial: None,
        }
    }

    /// paper-pi in process under Gauss-Seidel for `duration_s`.
    fn paper_pi_gauss_seidel(duration_s: f64) -> Scenario {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut s = Scenario::load(&root.join("scenarios/paper-pi.toml")).unwrap();
        s.run.transport = Transport::InProcess;
        s.run.master = Master::GaussSeidel;
        s.run.duration_s = Some(duration_s);
        s
    }

    /// A timing replay tells its observers what the lock-step tells them: replaying the
    /// timing of Gauss-Seidel's data flow, an observer sees every tick's outputs, the value
    /// each link delivered, the controller's steps and requests as the Gauss-Seidel lock-step
    /// shows them to it, bit for bit, with a manipulator that quantises the measurement acting
    /// on both (every measurement the controller got is a whole number of quanta); its part of
    /// the summary is there; two observers of one name are refused.
    #[test]
    fn a_timing_replay_tells_observers_what_the_lock_step_does() {
        let s = paper_pi_gauss_seidel(0.6);
        let dir = std::env::temp_dir().join(format!("tiltsim-replay-obs-{}", std::process::id()));
        let opts = RunOptions::new(dir.clone(), "tiltsim".into());
        let out = crate::engine::outputs::Outputs {
            rows_in_memory: true,
            ..Default::default()
        };
        let q = 1e-4;
        let (lock, by_lock) = watch("w");
        Run::new(&s, "paper-pi.toml", &opts)
            .add_observer(lock)
            .add_manipulator(Box::new(Quantise { q }))
            .simulate()
            .unwrap();
        let (replayed, by_replay) = watch("w");
        let path = std::path::Path::new("(gauss-seidel)");
        let trace = gauss_seidel_trace(&s);
        let attached = crate::free::timing_replay::Attached {
            observers: vec![replayed],
            manipulators: vec![Box::new(Quantise { q })],
        };
        let mut r =
            crate::free::timing_replay::replay_trace(&s, trace, path, &opts, &out, attached)
                .unwrap();
        assert_eq!((r.status, r.error.as_deref()), (Status::Completed, None));
        {
            let (lock, replay) = (by_lock.lock().unwrap(), by_replay.lock().unwrap());
            assert_eq!(replay.len() as u64, s.steps());
            assert_eq!(replay.len(), lock.len());
            let first = lock.iter().zip(replay.iter()).position(|(a, b)| a != b);
            assert_eq!(first, None, "first tick told otherwise");
            for t in replay.iter().filter(|t| t.0 > 0) {
                let v = f64::from_bits(t.6);
                assert_eq!(v, (v / q).round() * q, "tick {}: {v} not quantised", t.0);
            }
            let stepped = replay.iter().filter(|t| t.5).count() as u64;
            assert_eq!(stepped, s.steps().div_ceil(s.controller_period_ticks()));
        }
        let sm = crate::free::summary_of_replay(&s, "paper-pi.toml", path, &mut r);
        let part = &sm.observers["w"];
        assert_eq!(part["started"], true);
        assert_eq!(part["ticks"], s.steps());
        let twice = crate::free::timing_replay::Attached {
            observers: vec![watch("w").0 as Box<dyn Observer>, watch("w").0],
            manipulators: Vec::new(),
        };
        let trace = gauss_seidel_trace(&s);
        let e = crate::free::timing_replay::replay_trace(&s, trace, path, &opts, &out, twice)
            .unwrap_err();
        assert!(e.to_string().contains("two observers are named `w`"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A replay interrupted by a signal ends `interrupted` with the steps it had replayed, as
    /// a lock-step or free run does, and its summary says so; it does not claim to have
    /// completed.
    #[test]
    fn an_interrupted_timing_replay_says_it_was_interrupted() {
        let s = paper_pi_gauss_seidel(0.2);
        let dir = std::env::temp_dir().join(format!("tiltsim-replay-int-{}", std::process::id()));
        let opts = RunOptions::new(dir.clone(), "tiltsim".into());
        opts.interrupt
            .store(true, std::sync::atomic::Ordering::Relaxed);
        let out = crate::engine::outputs::Outputs {
            rows_in_memory: true,
            ..Default::default()
        };
        let path = std::path::Path::new("(gauss-seidel)");
        let trace = gauss_seidel_trace(&s);
        let mut r = crate::free::timing_replay::replay_trace(
            &s,
            trace,
            path,
            &opts,
            &out,
            Default::default(),
        )
        .unwrap();
        assert_eq!(r.status, Status::Interrupted);
        assert!(r.steps_completed < s.steps(), "{} rows", r.steps_completed);
        let sm = crate::free::summary_of_replay(&s, "paper-pi.toml", path, &mut r);
        assert_eq!(sm.status, Status::Interrupted);
        let e = sm.error.unwrap_or_default();
        assert!(e.starts_with("interrupted by"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
