//! `--record` of a free run: `run.mcap` written as the run goes, with the lock-step
//! recording's channels (`/<role>/in`, `/<role>/out`, `/links/<name>`, `/events`, `/summary`,
//! `/perf`) and the timing trace as `/timing/<role>`.
//!
//! Steps and log times as in lock-step: what a step at tick k read, the controller's answer,
//! the links and the outputs are step k + 1 at t_(k+1), the row of `timeseries.csv` that holds
//! them; a step's timing is step k at t_k, the row of `timing.csv`; the
//! publish times are the wall clock of the trace (CLOCK_MONOTONIC ns: the read instant for an
//! input, the publish instant for an output and for a step's timing). The links' `sent` is
//! the producer's output as published and `received` what the link delivered, for the sample
//! each consumer step read.
//!
//! Tick k is written once its row is in `timeseries.csv` and every participant's step at k is
//! in: nothing a later step does changes what tick k recorded, and the links' events of tick
//! k are known (a sample's events are logged at the tick it is sent, when it is passed). The
//! recorder keeps only the steps not written yet and tells the store which outputs they
//! still name ([`FreeRecorder::floor`]), so a recorded run holds what an unrecorded one does.

use std::path::{Path, PathBuf};

use cosim::Role;
use tiltsim_formats::events::EventLog;
use tiltsim_scenario::links::LinkId;

use super::compose::{Store, Window};
use super::feed::EventFeed;
use super::trace::{age, col, inputs_of, StepTrace};
use crate::engine::mcap::{
    actuator_out, controller_out, inbox, link_channel, plant_out, timing_channel, EventMessage,
    McapRecorder,
};
use tiltsim_scenario::scenario::Scenario;

/// A free run's recording, complete but for the summary, which the caller closes it with.
pub struct FreeRecording {
    rec: McapRecorder,
    end: u64,
}

impl FreeRecording {
    /// Writes the summary's repeatable part `det` and its wall-clock part `perf` and closes
    /// the file; returns its path.
    pub fn finish(
        self,
        det: &serde_json::Value,
        perf: &serde_json::Value,
    ) -> std::io::Result<PathBuf> {
        self.rec.close(det, perf, self.end)
    }
}

/// `run.mcap` of a free run, written tick by tick as the run goes.
pub struct FreeRecorder {
    rec: McapRecorder,
    path: PathBuf,
    /// The steps taken and not written yet, per role by its step index ([`Store::index`]).
    steps: [Window<StepTrace>; 3],
    /// The next tick to write.
    next: u64,
    period: u64,
    /// The start instant (CLOCK_MONOTONIC ns) the trace's times count from.
    start_ns: u64,
    /// The run's events, tick by tick.
    events: EventFeed,
}

impl FreeRecorder {
    /// Creates `path` for a free run of `s`.
    pub fn create(path: &Path, s: &Scenario) -> std::io::Result<Self> {
        Ok(FreeRecorder {
            rec: McapRecorder::create_free(path, s.run.dt_s)?,
            path: path.to_path_buf(),
            steps: Default::default(),
            next: 0,
            period: s.controller_period_ticks(),
            start_ns: 0,
            events: EventFeed::new(s),
        })
    }

    /// The file written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Steps held in memory (for tests that memory stays bounded).
    pub fn held(&self) -> usize {
        self.steps.iter().map(Window::held).sum()
    }

    /// Writes the outputs at t₀ (in `store`); the trace's times count from `start_ns`.
    pub fn start(&mut self, store: &Store, start_ns: u64) -> std::io::Result<()> {
        self.start_ns = start_ns;
        match (store.plant(-1), store.actuator(-1)) {
            (Some(p), Some(a)) => self.rec.at_start(p, a),
            _ => Ok(()),
        }
    }

    /// Keeps a step taken, until its tick is written.
    pub fn push(&mut self, t: StepTrace, store: &Store) {
        self.steps[col(t.role)].set(store.index(t.role, t.step), t);
    }

    /// Writes every tick whose row is among the first `rows` of `timeseries.csv` and whose
    /// participants' steps are all in.
    pub fn advance(&mut self, store: &Store, rows: u64) -> std::io::Result<()> {
        while self.next < rows && self.complete(self.next) {
            self.queue_events_through(store, self.next);
            self.write_tick(store, self.next)?;
        }
        Ok(())
    }

    /// Whether every participant stepping at tick `k` has taken its step.
    fn complete(&self, k: u64) -> bool {
        Role::ALL.iter().all(|&r| {
            (r == Role::Controller && !k.is_multiple_of(self.period)) || self.at(r, k).is_some()
        })
    }

    /// Lowers `floor` (the oldest step of each producer, by [`col`], the store must keep) to
    /// what the ticks not written yet name: the outputs of their own steps and what those
    /// steps read.
    pub fn floor(&self, floor: &mut [i64; 3]) {
        let own = [
            self.next,
            self.next,
            self.next.div_ceil(self.period) * self.period,
        ];
        for (f, o) in floor.iter_mut().zip(own) {
            *f = (*f).min(o as i64);
        }
        for w in &self.steps {
            for t in w.iter() {
                for (f, q) in floor.iter_mut().zip(t.from) {
                    if let Some(q) = q {
                        *f = (*f).min(q);
                    }
                }
            }
        }
    }

    /// Writes the ticks left of the first `rows` with what they have (a run that ended early
    /// has steps missing), and the events of `events` (the run's `events.csv`) not written
    /// yet; the recording then waits for the summary.
    pub fn finish(
        mut self,
        store: &Store,
        rows: u64,
        events: &EventLog,
    ) -> std::io::Result<FreeRecording> {
        let rest = events.events.get(self.events.given..).unwrap_or(&[]);
        self.rec.queue_events(rest.iter().map(EventMessage::from));
        self.events.given = events.events.len();
        while self.next < rows {
            self.write_tick(store, self.next)?;
        }
        let end = rows * self.rec.dt_ns();
        Ok(FreeRecording { rec: self.rec, end })
    }

    /// `role`'s step at tick `k`, if it has one there and it is kept.
    fn at(&self, role: Role, k: u64) -> Option<&StepTrace> {
        if role == Role::Controller && !k.is_multiple_of(self.period) {
            return None;
        }
        let i = match role {
            Role::Controller => k / self.period,
            _ => k,
        };
        self.steps[col(role)].get(i as usize)
    }

    /// Queues the events of ticks up to `k` not queued yet.
    fn queue_events_through(&mut self, store: &Store, k: u64) {
        let new = self.events.through(store, k);
        self.rec.queue_events(new.iter().map(EventMessage::from));
    }

    /// Writes tick `k` (the events queued for it included) and forgets its steps.
    fn write_tick(&mut self, store: &Store, k: u64) -> std::io::Result<()> {
        // The step's timing at t_k (the row of `timing.csv`), the events of tick k, then
        // what each consumer stepping at k read, the links' samples it read and the outputs
        // as step k + 1 at t_(k+1): the row of `timeseries.csv` that holds them.
        let dt_ns = self.rec.dt_ns();
        let log = k * dt_ns;
        for role in Role::ALL {
            if let Some(t) = self.at(role, k) {
                let v = timing_values(t, self.period, dt_ns);
                let wall = self.start_ns + t.publish_ns;
                self.rec
                    .put_values(timing_channel(role), k, log, wall, &v)?;
            }
        }
        self.rec.events_until(k)?;
        self.write_controller(store, k)?;
        self.write_actuator(store, k)?;
        self.write_plant(store, k)?;
        self.next = k + 1;
        self.steps[0].forget_before(self.next as usize);
        self.steps[1].forget_before(self.next as usize);
        self.steps[2].forget_before(self.next.div_ceil(self.period) as usize);
        Ok(())
    }

    /// What the controller's step at tick `k` read, its answer and the measurement it read.
    fn write_controller(&mut self, store: &Store, k: u64) -> std::io::Result<()> {
        let Some(t) = self.at(Role::Controller, k).copied() else {
            return Ok(());
        };
        let (row, log) = (k + 1, (k + 1) * self.rec.dt_ns());
        let qp = t.from[col(Role::Plant)].unwrap_or(-1);
        let (Some(i), Some(p)) = (store.controller_input(qp), store.plant(qp)) else {
            return Ok(());
        };
        let c = inbox(Role::Controller);
        let wall = |ns: u64| self.start_ns + ns;
        let v = [i.t, i.s, i.theta_v_meas];
        self.rec.put_values(c, row, log, wall(t.read_ns), &v)?;
        if let Some(o) = store.controller(k as i64) {
            let v = controller_out(o);
            self.rec
                .put_values(c + 1, row, log, wall(t.publish_ns), &v)?;
        }
        let sent = [p.theta_v_meas, i.theta_v_meas];
        let m = link_channel(LinkId::Measurement);
        self.rec.put_values(m, row, log, log, &sent)
    }

    /// What the actuator's step at tick `k` read and the command and bar twist it read.
    fn write_actuator(&mut self, store: &Store, k: u64) -> std::io::Result<()> {
        let Some(t) = self.at(Role::Actuator, k).copied() else {
            return Ok(());
        };
        let (row, log) = (k + 1, (k + 1) * self.rec.dt_ns());
        let qc = t.from[col(Role::Controller)].unwrap_or(-1);
        let qp = t.from[col(Role::Plant)].unwrap_or(-1);
        let (Some(i), Some(c), Some(p)) = (
            store.actuator_input(qc, qp),
            store.controller(qc),
            store.plant(qp),
        ) else {
            return Ok(());
        };
        let a = inbox(Role::Actuator);
        let read = self.start_ns + t.read_ns;
        self.rec
            .put_values(a, row, log, read, &[i.delta_a_cmd, i.psi])?;
        let cmd = [c.delta_a_cmd, i.delta_a_cmd];
        let l = link_channel(LinkId::ActuatorCommand);
        self.rec.put_values(l, row, log, log, &cmd)?;
        let twist = [p.psi, i.psi];
        let l = link_channel(LinkId::BarTwist);
        self.rec.put_values(l, row, log, log, &twist)
    }

    /// What the plant's step at tick `k` read and the bar angle it read, then the actuator's
    /// and the plant's outputs of tick `k`.
    fn write_plant(&mut self, store: &Store, k: u64) -> std::io::Result<()> {
        let (row, log) = (k + 1, (k + 1) * self.rec.dt_ns());
        let plant = self.at(Role::Plant, k).copied();
        if let Some(t) = plant {
            let qa = t.from[col(Role::Actuator)].unwrap_or(-1);
            if let (Some(i), Some(a)) = (store.plant_input(qa), store.actuator(qa)) {
                let read = self.start_ns + t.read_ns;
                self.rec
                    .put_values(inbox(Role::Plant), row, log, read, &[i.delta_a])?;
                let bar = [a.delta_a, i.delta_a];
                let l = link_channel(LinkId::BarAngle);
                self.rec.put_values(l, row, log, log, &bar)?;
            }
        }
        let actuator = self.at(Role::Actuator, k).copied();
        if let (Some(t), Some(o)) = (actuator, store.actuator(k as i64)) {
            let a = inbox(Role::Actuator) + 1;
            let wall = self.start_ns + t.publish_ns;
            self.rec.put_values(a, row, log, wall, &actuator_out(o))?;
        }
        if let (Some(t), Some(o)) = (plant, store.plant(k as i64)) {
            let p = inbox(Role::Plant) + 1;
            let wall = self.start_ns + t.publish_ns;
            self.rec.put_values(p, row, log, wall, &plant_out(o))?;
        }
        Ok(())
    }
}

/// The values of a step's `/timing/<role>` message.
fn timing_values(t: &StepTrace, period_ticks: u64, dt_ns: u64) -> Vec<f64> {
    let mut v = vec![f64::NAN; 12];
    for &p in inputs_of(t.role) {
        if let Some(f) = t.from[col(p)] {
            v[col(p)] = f as f64;
            v[3 + col(p)] = age(p, t.step, f) as f64;
        }
    }
    let ticks = if t.role == Role::Controller {
        period_ticks
    } else {
        1
    };
    v[6] = t.due_ns as f64;
    v[7] = t.read_ns as f64;
    v[8] = t.compute_end_ns as f64;
    v[9] = t.publish_ns as f64;
    v[10] = f64::from(u8::from(t.late_start(ticks * dt_ns)));
    v[11] = f64::from(u8::from(t.late_finish(ticks * dt_ns)));
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::free::RowStream;

    fn step(role: Role, step: u64, from: [Option<i64>; 3]) -> StepTrace {
        StepTrace {
            role,
            step,
            from,
            due_ns: step * 1_000_000,
            read_ns: step * 1_000_000 + 10_000,
            compute_end_ns: step * 1_000_000 + 20_000,
            publish_ns: step * 1_000_000 + 30_000,
        }
    }

    /// Records `ticks` of paper-mpc's data flow with the controller's steps coming in three
    /// ticks late, as the hub would; the largest number of entries held (store and recorder)
    /// and the messages per topic in the file.
    fn record_flow(ticks: u64, dir: &Path) -> (usize, std::collections::BTreeMap<String, u64>) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut s = Scenario::load(&root.join("scenarios/paper-mpc.toml")).unwrap();
        s.run.duration_s = Some(ticks as f64 * s.run.dt_s);
        let period = s.controller_period_ticks();
        let path = dir.join(format!("run-{ticks}.mcap"));
        let mut rec = FreeRecorder::create(&path, &s).unwrap();
        let mut store = Store::new(period, s.run.dt_s, &s.links, 1);
        store.put_init(Default::default(), Default::default(), Default::default());
        let opts = crate::engine::RunOptions::new(dir.join(format!("rows-{ticks}")), "".into());
        std::fs::create_dir_all(&opts.out_dir).unwrap();
        let out = crate::engine::outputs::Outputs::default();
        let mut rows = RowStream::create(&opts, &out).unwrap();
        rows.start(&store).unwrap();
        rec.start(&store, 0).unwrap();
        let (mut qc, mut largest) = (-1i64, 0);
        let lag = 3;
        for k in 0..ticks + lag {
            // The controller's step of tick k − lag, reading the plant's step before it.
            if k >= lag && (k - lag).is_multiple_of(period) {
                let q = k - lag;
                let t = step(Role::Controller, q, [Some(q as i64 - 1), None, None]);
                store.note_read(&t);
                rec.push(t, &store);
                store.put_controller(q, Default::default());
                qc = q as i64;
            }
            if k < ticks {
                let t = step(Role::Actuator, k, [Some(k as i64 - 1), None, Some(qc)]);
                store.note_read(&t);
                rec.push(t, &store);
                store.put_actuator(k, Default::default());
                let t = step(Role::Plant, k, [None, Some(k as i64), None]);
                store.note_read(&t);
                rec.push(t, &store);
                store.put_plant(k, Default::default());
                rows.advance(&store, ticks).unwrap();
            }
            rec.advance(&store, rows.written()).unwrap();
            // What later steps name: this tick's outputs, the controller's last and the
            // ticks not recorded yet.
            let mut floor = rows.floor();
            floor[0] = floor[0].min(k.min(ticks - 1) as i64);
            floor[2] = floor[2].min(qc);
            rec.floor(&mut floor);
            store.forget_before(floor);
            largest = largest.max(store.held() + rec.held());
        }
        let (written, _, err) = rows.finish();
        assert_eq!((written, err), (ticks, None));
        let events = crate::free::run_events(&s, &store, ticks);
        let recording = rec.finish(&store, ticks, &events).unwrap();
        let det = serde_json::json!({});
        let path = recording.finish(&det, &det).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut counts = std::collections::BTreeMap::new();
        let mut last_log = 0;
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            assert!(
                m.log_time >= last_log,
                "{} out of log-time order",
                m.channel.topic
            );
            last_log = m.log_time;
            *counts.entry(m.channel.topic.clone()).or_insert(0) += 1;
        }
        (largest, counts)
    }

    /// A recorded free run holds what an unrecorded one does: a bounded window of steps and
    /// outputs whatever its length (the entries held over 100 000 ticks are those held over
    /// 10 000), and the file has every tick's messages: one per tick per participant input,
    /// output and link, one per controller period on the controller's channels.
    #[test]
    fn a_recorded_free_run_holds_a_bounded_window_and_records_every_tick() {
        let dir = std::env::temp_dir().join(format!("tiltsim-free-rec-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (short, _) = record_flow(10_000, &dir);
        let (long, counts) = record_flow(100_000, &dir);
        assert_eq!(short, long, "entries held grow with the run's length");
        assert!(long <= 400, "{long} entries held");
        for topic in [
            "/plant/in",
            "/actuator/in",
            "/actuator/out",
            "/timing/plant",
        ] {
            assert_eq!(
                counts[topic],
                100_000 + u64::from(topic.ends_with("/out")),
                "{topic}"
            );
        }
        assert_eq!(counts["/plant/out"], 100_001);
        for topic in ["/controller/in", "/controller/out", "/timing/controller"] {
            assert_eq!(counts[topic], 2_000, "{topic}");
        }
        for topic in [
            "/links/bar_angle",
            "/links/bar_twist",
            "/links/actuator_command",
        ] {
            assert_eq!(counts[topic], 100_000, "{topic}");
        }
        assert_eq!(counts["/summary"], 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
