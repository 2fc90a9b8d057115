//! What a free run and its replay share, so that they cannot differ: each consumer's input
//! composed from producer outputs as the links carried them, and the rows of
//! `timeseries.csv` defined from the outputs and the inputs each step read (never from when
//! the orchestrator relayed them).
//!
//! Link effects (`[links]`) act on each sample as it travels: every output a producer
//! publishes is passed, in the order of its steps, through the link to each consumer
//! ([`crate::links::Link::pass`]), at the tick its value holds from (a plant output of step q
//! at q + 1, an actuator's or controller's at q), with one set of random draws per sample.
//! The link loses it or delays it by whole ticks of wall time and gives the value it arrives
//! with; which sample a consumer step read is in the trace, and the value it read is the
//! link's for that sample, so the replay, passing the same samples in the same order, feeds
//! the same values. The outputs at t₀ are what every receiver holds from the start.

use cosim::msg::{FromActuator, FromController, FromPlant, Header, Kind};
use cosim::msg::{ToActuator, ToController, ToPlant};
use cosim::Role;
use tiltsim_formats::events::EventLog;
use tiltsim_formats::table::Row;
use tiltsim_scenario::links::{LinkId, Links};

use super::trace::{col, StepTrace};
use crate::links::LinkSet;

/// A sequence indexed from 0 of which only a window is kept: entries are set as they come
/// (any index at or past the window's start) and forgotten from the front once nothing can
/// name them again, so a run of any length holds only what is still in use.
#[derive(Debug, Clone)]
pub struct Window<T> {
    base: usize,
    items: std::collections::VecDeque<Option<T>>,
}

impl<T: Clone> Default for Window<T> {
    fn default() -> Self {
        Window {
            base: 0,
            items: std::collections::VecDeque::new(),
        }
    }
}

impl<T: Clone> Window<T> {
    /// Entry `i`, when set and not forgotten.
    pub fn get(&self, i: usize) -> Option<&T> {
        self.items.get(i.checked_sub(self.base)?)?.as_ref()
    }
    /// Sets entry `i` (ignored when it was already forgotten).
    pub fn set(&mut self, i: usize, v: T) {
        let Some(j) = i.checked_sub(self.base) else {
            return;
        };
        if self.items.len() <= j {
            self.items.resize(j + 1, None);
        }
        self.items[j] = Some(v);
    }
    /// Forgets every entry before `i`.
    pub fn forget_before(&mut self, i: usize) {
        while self.base < i && !self.items.is_empty() {
            self.items.pop_front();
            self.base += 1;
        }
        self.base = self.base.max(i);
    }
    /// Entries held (set or not) in the window.
    pub fn held(&self) -> usize {
        self.items.len()
    }
    /// The entries set, in index order.
    pub fn iter(&self) -> impl Iterator<Item = &T> {
        self.items.iter().flatten()
    }
}

/// The outputs of a run by producer step, what the links made of each, and the producer steps
/// each consumer step read: of each, only what a later step, relay or row can still name
/// ([`Store::forget_before`]).
pub struct Store {
    /// Controller period in ticks.
    pub period: u64,
    /// Outputs at t₀.
    pub init: (FromPlant, FromActuator, FromController),
    /// Plant outputs by step.
    p: Window<FromPlant>,
    /// Actuator outputs by step.
    a: Window<FromActuator>,
    /// Controller outputs by step / period.
    c: Window<FromController>,
    /// What each step read, per role column, by the role's step index.
    read: [Window<[Option<i64>; 3]>; 3],
    /// The links, each passed its producer's samples in step order.
    links: LinkSet,
    /// Per link ([`LinkId`] order), the value each sample arrived with by sample index (0:
    /// the output at t₀, i + 1: the producer's step index i); `None` = lost or not yet sent.
    arrived: [Window<Option<f64>>; 4],
    /// What the links did, per link (merged in tick order by [`Store::events`]).
    events: [EventLog; 4],
    /// Per link, the tick of the last sample it passed.
    passed: [Option<u64>; 4],
    /// The caller's manipulators of a replay, given every sample after the links' effects.
    manipulators: Vec<Box<dyn crate::engine::manipulate::Manipulator>>,
    dt: f64,
}

impl Store {
    /// An empty store for a controller of `period` ticks, a base tick of `dt` s and the links
    /// `links` with their random streams from `seed`.
    pub fn new(period: u64, dt: f64, links: &Links, seed: u64) -> Self {
        Store {
            period,
            init: Default::default(),
            p: Window::default(),
            a: Window::default(),
            c: Window::default(),
            read: Default::default(),
            links: LinkSet::new(links, seed),
            arrived: Default::default(),
            events: std::array::from_fn(|_| EventLog::new(dt)),
            passed: [None; 4],
            manipulators: Vec::new(),
            dt,
        }
    }

    /// Forgets what no later step, relay or row can name: plant, actuator and controller
    /// outputs (and what their steps read, and their samples on the links) before steps
    /// `floor` (per producer column, [`col`]; a controller floor is a step, not an index).
    pub fn forget_before(&mut self, floor: [i64; 3]) {
        // Index of step q in its role's windows; the output at t₀ (q < 0) is kept apart.
        let idx =
            |role: Role, q: i64| -> Option<usize> { (q >= 0).then(|| self.index(role, q as u64)) };
        let [fp, fa, fc] = [
            idx(Role::Plant, floor[0]),
            idx(Role::Actuator, floor[1]),
            idx(Role::Controller, floor[2]),
        ];
        let start = |i: Option<usize>| i.unwrap_or(0);
        self.p.forget_before(start(fp));
        self.a.forget_before(start(fa));
        self.c.forget_before(start(fc));
        self.read[0].forget_before(start(fp));
        self.read[1].forget_before(start(fa));
        self.read[2].forget_before(start(fc));
        // Sample index i + 1 is the producer's step index i; 0 is the output at t₀, kept
        // while any floor is at t₀.
        for (l, f) in [
            (LinkId::ActuatorCommand, fc),
            (LinkId::BarAngle, fa),
            (LinkId::Measurement, fp),
            (LinkId::BarTwist, fp),
        ] {
            self.arrived[l as usize].forget_before(f.map_or(0, |i| i + 1));
        }
    }

    /// Entries held in memory (for tests that memory stays bounded).
    pub fn held(&self) -> usize {
        self.p.held()
            + self.a.held()
            + self.c.held()
            + self.read.iter().map(Window::held).sum::<usize>()
            + self.arrived.iter().map(Window::held).sum::<usize>()
    }

    /// Passes sample `index` (i + 1 for the producer's step index i) of link `id`, valid from
    /// tick `k`, with value `v`; returns its delay in ticks, `None` when lost.
    fn pass(&mut self, id: LinkId, index: usize, k: u64, v: f64) -> Option<u64> {
        let i = id as usize;
        self.passed[i] = Some(k);
        let t = cosim::time::tick_time(k, self.dt);
        let log = &mut self.events[i];
        let got = self.links.pass(id, k, t, v, log).map(|(d, value)| {
            let carried = self
                .manipulators
                .iter_mut()
                .fold(value, |v, m| m.carry(id, k, t, v, log));
            (d, carried)
        });
        self.arrived[i].set(index, got.map(|(_, value)| value));
        got.map(|(d, _)| d)
    }

    /// Gives every sample that arrives, after the links' effects, to `manipulators` in turn
    /// ([`crate::engine::manipulate::Manipulator::carry`]; what they log goes with the link's
    /// events).
    pub fn add_manipulators(
        &mut self,
        manipulators: Vec<Box<dyn crate::engine::manipulate::Manipulator>>,
    ) {
        self.manipulators.extend(manipulators);
    }

    /// Keeps the outputs at t₀. They reach every receiver without the links' effects: they are
    /// what each holds from the start (as in lock-step until a first sample arrives). The
    /// caller's manipulators of a replay act on them, as on the lock-step's tick 0, which
    /// carries them.
    pub fn put_init(&mut self, p: FromPlant, a: FromActuator, c: FromController) {
        let values = LinkId::carried(&p, &a, &c);
        for (i, (arrived, v)) in self.arrived.iter_mut().zip(values).enumerate() {
            let id = LinkId::ALL[i];
            let log = &mut self.events[i];
            let v = self
                .manipulators
                .iter_mut()
                .fold(v, |v, m| m.carry(id, 0, 0.0, v, log));
            arrived.set(0, Some(v));
        }
        self.init = (p, a, c);
    }

    /// Keeps the plant's output of step `q` and passes it on; returns the delays of its
    /// samples on the measurement and bar-twist links (`None`: lost).
    pub fn put_plant(&mut self, q: u64, o: FromPlant) -> [Option<u64>; 2] {
        let i = q as usize;
        self.p.set(i, o);
        [
            self.pass(LinkId::Measurement, i + 1, q + 1, o.theta_v_meas),
            self.pass(LinkId::BarTwist, i + 1, q + 1, o.psi),
        ]
    }

    /// Keeps the actuator's output of step `q` and passes it on the bar-angle link.
    pub fn put_actuator(&mut self, q: u64, o: FromActuator) -> Option<u64> {
        let i = q as usize;
        self.a.set(i, o);
        self.pass(LinkId::BarAngle, i + 1, q, o.delta_a)
    }

    /// Keeps the controller's output of step `q` and passes it on the command link.
    pub fn put_controller(&mut self, q: u64, o: FromController) -> Option<u64> {
        let i = (q / self.period) as usize;
        self.c.set(i, o);
        self.pass(LinkId::ActuatorCommand, i + 1, q, o.delta_a_cmd)
    }

    /// The value producer step `q` (−1: at t₀) arrived with over link `id`; `None` when it
    /// was lost or has not been sent.
    fn arrived(&self, id: LinkId, q: i64) -> Option<f64> {
        let index = if q < 0 {
            0
        } else if id == LinkId::ActuatorCommand {
            (q as u64 / self.period) as usize + 1
        } else {
            q as usize + 1
        };
        *self.arrived[id as usize].get(index)?
    }

    /// What the links did, in tick order (each link's events in its own order; a tick's
    /// events in link order), so a free run and its replay write the same `events.csv`.
    pub fn events(&self) -> EventLog {
        let mut all = EventLog::new(self.dt);
        let mut tagged: Vec<(u64, usize, usize)> = Vec::new();
        for (l, log) in self.events.iter().enumerate() {
            tagged.extend(log.events.iter().enumerate().map(|(i, e)| (e.step, l, i)));
        }
        tagged.sort_unstable();
        all.events = tagged
            .into_iter()
            .map(|(_, l, i)| self.events[l].events[i].clone())
            .collect();
        all
    }

    /// The links' events of ticks up to `k` that `taken` (per link, how many of its events
    /// were taken before) leaves out, in the order of [`Store::events`]; advances `taken`.
    /// Each link logs its events at the tick its sample is sent, and passes its samples in
    /// the order they were sent, so a link's events are in tick order and those of ticks up
    /// to `k` come first.
    pub fn link_events_through(
        &self,
        k: u64,
        taken: &mut [usize; 4],
    ) -> Vec<tiltsim_formats::events::Event> {
        let mut tagged: Vec<(u64, usize, usize)> = Vec::new();
        for (l, log) in self.events.iter().enumerate() {
            let new = log.events.get(taken[l]..).unwrap_or(&[]);
            let n = new.iter().take_while(|e| e.step <= k).count();
            tagged.extend(
                new[..n]
                    .iter()
                    .enumerate()
                    .map(|(i, e)| (e.step, l, taken[l] + i)),
            );
            taken[l] += n;
        }
        tagged.sort_unstable();
        tagged
            .into_iter()
            .map(|(_, l, i)| self.events[l].events[i].clone())
            .collect()
    }

    /// Index of `role`'s step `step` in its vectors.
    pub fn index(&self, role: Role, step: u64) -> usize {
        match role {
            Role::Controller => (step / self.period) as usize,
            _ => step as usize,
        }
    }

    /// Plant output of step `q` (−1: at t₀).
    pub fn plant(&self, q: i64) -> Option<&FromPlant> {
        if q < 0 {
            Some(&self.init.0)
        } else {
            self.p.get(q as usize)
        }
    }
    /// Actuator output of step `q` (−1: at t₀).
    pub fn actuator(&self, q: i64) -> Option<&FromActuator> {
        if q < 0 {
            Some(&self.init.1)
        } else {
            self.a.get(q as usize)
        }
    }
    /// Controller output of step `q` (−1: at t₀).
    pub fn controller(&self, q: i64) -> Option<&FromController> {
        if q < 0 {
            Some(&self.init.2)
        } else {
            self.c.get((q as u64 / self.period) as usize)
        }
    }

    /// Records that `t.role`'s step `t.step` read `t.from`.
    pub fn note_read(&mut self, t: &StepTrace) {
        let i = self.index(t.role, t.step);
        self.read[col(t.role)].set(i, t.from);
    }

    /// The step of `producer` that `role`'s step `q` read (−1 for an output at t₀, which read
    /// nothing); `None` when that step's reading is not known (not yet, or forgotten).
    fn read_of(&self, role: Role, q: i64, producer: Role) -> Option<i64> {
        if q < 0 {
            return Some(-1);
        }
        let i = self.index(role, q as u64);
        self.read[col(role)].get(i)?[col(producer)]
    }

    /// The input of a plant step that read actuator step `qa`, as the bar-angle link
    /// delivered it; `None` if that output is not there (yet) or was lost.
    pub fn plant_input(&self, qa: i64) -> Option<ToPlant> {
        self.actuator(qa)?;
        Some(ToPlant {
            header: Header::new(0, Kind::Step),
            delta_a: self.arrived(LinkId::BarAngle, qa)?,
        })
    }
    /// The input of an actuator step that read controller step `qc` and plant step `qp`.
    pub fn actuator_input(&self, qc: i64, qp: i64) -> Option<ToActuator> {
        self.controller(qc)?;
        self.plant(qp)?;
        Some(ToActuator {
            header: Header::new(0, Kind::Step),
            delta_a_cmd: self.arrived(LinkId::ActuatorCommand, qc)?,
            psi: self.arrived(LinkId::BarTwist, qp)?,
        })
    }
    /// The input of a controller step that read plant step `qp`.
    pub fn controller_input(&self, qp: i64) -> Option<ToController> {
        let p = self.plant(qp)?;
        Some(ToController {
            header: Header::new(0, Kind::Step),
            t: p.t,
            s: p.s,
            theta_v_meas: self.arrived(LinkId::Measurement, qp)?,
        })
    }

    /// The input of `role`'s step as the trace says it read it; `None` if an output it names
    /// is not there (yet).
    pub fn input_plant(&self, t: &StepTrace) -> Option<ToPlant> {
        self.plant_input(t.from[col(Role::Actuator)]?)
    }
    /// See [`Store::input_plant`].
    pub fn input_actuator(&self, t: &StepTrace) -> Option<ToActuator> {
        self.actuator_input(t.from[col(Role::Controller)]?, t.from[col(Role::Plant)]?)
    }
    /// See [`Store::input_plant`].
    pub fn input_controller(&self, t: &StepTrace) -> Option<ToController> {
        self.controller_input(t.from[col(Role::Plant)]?)
    }

    /// Row 0 of `timeseries.csv`: the outputs at t₀.
    pub fn row_at_start(&self) -> Row {
        let (p, a, c) = &self.init;
        Row::at_start(self.dt, p, a, c)
    }

    /// Row `k + 1` of `timeseries.csv`: the plant's output of step `k`, the actuator output that
    /// step read, the controller output that actuator step read, and as the `rx_*` columns
    /// what each of those steps received over its link (the measurement as the controller
    /// step read it, the bar twist as the actuator step read it). An output at t₀ read nothing: the outputs at
    /// t₀ stand for what it would have read. `None` if an output is missing.
    pub fn row(&self, k: u64) -> Option<Row> {
        self.row_and_reads(k).map(|(row, _)| row)
    }

    /// [`Store::row`] and the oldest step of each producer (by [`col`]) the row names: every
    /// later row names only these steps or later ones (each consumer reads its inputs in the
    /// order they were sent, and they were sent in step order).
    pub fn row_and_reads(&self, k: u64) -> Option<(Row, [i64; 3])> {
        let r = self.row_parts(k)?;
        let row = Row::after_tick(k, self.dt, r.plant, r.actuator, r.controller, &r.rx);
        Some((row, [r.qp_c.min(r.qp_a), r.qa, r.qc]))
    }

    /// What row `k + 1` is made of ([`Store::row`]); `None` if an output is missing.
    pub fn row_parts(&self, k: u64) -> Option<RowParts<'_>> {
        let plant = self.p.get(k as usize)?;
        let qa = self.read_of(Role::Plant, k as i64, Role::Actuator)?;
        let actuator = self.actuator(qa)?;
        let qc = self.read_of(Role::Actuator, qa, Role::Controller)?;
        let qp_a = self.read_of(Role::Actuator, qa, Role::Plant)?;
        let controller = self.controller(qc)?;
        let qp_c = self.read_of(Role::Controller, qc, Role::Plant)?;
        self.plant(qp_c)?;
        self.plant(qp_a)?;
        let rx = [
            self.arrived(LinkId::ActuatorCommand, qc)?,
            self.arrived(LinkId::BarAngle, qa)?,
            self.arrived(LinkId::Measurement, qp_c)?,
            self.arrived(LinkId::BarTwist, qp_a)?,
        ];
        Some(RowParts {
            plant,
            actuator,
            controller,
            qa,
            qc,
            qp_c,
            qp_a,
            rx,
        })
    }

    /// The newest tick up to which every link's events are logged: each link has passed a
    /// sample of that tick or a later one (`None` while one has passed none).
    pub fn events_complete_through(&self) -> Option<u64> {
        self.passed.iter().copied().min().flatten()
    }
}

/// What a row of `timeseries.csv` after a tick is made of: the plant's output of the tick,
/// the actuator output that step read (step `qa`), the controller output that actuator step
/// read (step `qc`), the plant steps the controller and the actuator steps read (`qp_c`,
/// `qp_a`; −1 for the outputs at t₀) and what each link delivered to them ([`LinkId`] order).
pub struct RowParts<'a> {
    pub plant: &'a FromPlant,
    pub actuator: &'a FromActuator,
    pub controller: &'a FromController,
    pub qa: i64,
    pub qc: i64,
    pub qp_c: i64,
    pub qp_a: i64,
    pub rx: [f64; 4],
}
