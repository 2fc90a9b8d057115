//! What a free run and its replay share, so that they cannot differ: each consumer's input
//! composed from producer outputs, and the rows of `timeseries.csv` defined from the outputs
//! and the inputs each step read (never from when the orchestrator relayed them).

use cosim::msg::{FromActuator, FromController, FromPlant, Header, Kind};
use cosim::msg::{ToActuator, ToController, ToPlant};
use cosim::Role;

use super::trace::{col, StepTrace};
use crate::record::Row;

/// The plant's input from the actuator output `a`.
pub fn to_plant(a: &FromActuator) -> ToPlant {
    ToPlant {
        header: Header::new(0, Kind::Step),
        delta_a: a.delta_a,
    }
}

/// The actuator's input from the controller output `c` and the plant output `p`.
pub fn to_actuator(c: &FromController, p: &FromPlant) -> ToActuator {
    ToActuator {
        header: Header::new(0, Kind::Step),
        delta_a_cmd: c.delta_a_cmd,
        psi: p.psi,
    }
}

/// The controller's input from the plant output `p`.
pub fn to_controller(p: &FromPlant) -> ToController {
    ToController {
        header: Header::new(0, Kind::Step),
        t: p.t,
        s: p.s,
        theta_v_meas: p.theta_v_meas,
    }
}

/// Every output of a run by producer step, and the producer steps each consumer step read.
#[derive(Debug, Default)]
pub struct Store {
    /// Controller period in ticks.
    pub period: u64,
    /// Outputs at t₀.
    pub init: (FromPlant, FromActuator, FromController),
    /// Plant outputs by step.
    pub p: Vec<Option<FromPlant>>,
    /// Actuator outputs by step.
    pub a: Vec<Option<FromActuator>>,
    /// Controller outputs by step / period.
    pub c: Vec<Option<FromController>>,
    /// What each step read, per role column, by the role's step index.
    pub read: [Vec<[Option<i64>; 3]>; 3],
}

impl Store {
    /// An empty store for `steps` plant steps and a controller of `period` ticks.
    pub fn new(steps: u64, period: u64) -> Self {
        let n = steps as usize;
        let nc = steps.div_ceil(period) as usize;
        Store {
            period,
            init: Default::default(),
            p: vec![None; n],
            a: vec![None; n],
            c: vec![None; nc],
            read: [vec![[None; 3]; n], vec![[None; 3]; n], vec![[None; 3]; nc]],
        }
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
            self.p.get(q as usize)?.as_ref()
        }
    }
    /// Actuator output of step `q` (−1: at t₀).
    pub fn actuator(&self, q: i64) -> Option<&FromActuator> {
        if q < 0 {
            Some(&self.init.1)
        } else {
            self.a.get(q as usize)?.as_ref()
        }
    }
    /// Controller output of step `q` (−1: at t₀).
    pub fn controller(&self, q: i64) -> Option<&FromController> {
        if q < 0 {
            Some(&self.init.2)
        } else {
            self.c.get((q as u64 / self.period) as usize)?.as_ref()
        }
    }

    /// Records that `t.role`'s step `t.step` read `t.from`.
    pub fn note_read(&mut self, t: &StepTrace) {
        let i = self.index(t.role, t.step);
        if let Some(slot) = self.read[col(t.role)].get_mut(i) {
            *slot = t.from;
        }
    }

    fn read_of(&self, role: Role, q: i64, producer: Role) -> i64 {
        if q < 0 {
            return -1;
        }
        let i = self.index(role, q as u64);
        self.read[col(role)]
            .get(i)
            .and_then(|r| r[col(producer)])
            .unwrap_or(-1)
    }

    /// The input of `role`'s step as the trace says it read it; `None` if an output it names
    /// is not there (yet).
    pub fn input_plant(&self, t: &StepTrace) -> Option<ToPlant> {
        Some(to_plant(self.actuator(t.from[col(Role::Actuator)]?)?))
    }
    /// See [`Store::input_plant`].
    pub fn input_actuator(&self, t: &StepTrace) -> Option<ToActuator> {
        Some(to_actuator(
            self.controller(t.from[col(Role::Controller)]?)?,
            self.plant(t.from[col(Role::Plant)]?)?,
        ))
    }
    /// See [`Store::input_plant`].
    pub fn input_controller(&self, t: &StepTrace) -> Option<ToController> {
        Some(to_controller(self.plant(t.from[col(Role::Plant)]?)?))
    }

    /// Row `k` of `timeseries.csv`: the plant's output of step `k`, the actuator output that
    /// step read, the controller output that actuator step read, and as the `rx_*` columns
    /// what each of those steps received (the measurement as the controller step read it, the
    /// bar twist as the actuator step read it). An output at t₀ read nothing: the outputs at
    /// t₀ stand for what it would have read. `None` if an output is missing.
    pub fn row(&self, k: u64) -> Option<Row> {
        let p = self.p.get(k as usize)?.as_ref()?;
        let qa = self.read_of(Role::Plant, k as i64, Role::Actuator);
        let a = self.actuator(qa)?;
        let qc = self.read_of(Role::Actuator, qa, Role::Controller);
        let qp_a = self.read_of(Role::Actuator, qa, Role::Plant);
        let c = self.controller(qc)?;
        let qp_c = self.read_of(Role::Controller, qc, Role::Plant);
        let rx = [
            c.delta_a_cmd,
            a.delta_a,
            self.plant(qp_c)?.theta_v_meas,
            self.plant(qp_a)?.psi,
        ];
        Some(Row::new(k, p, a, c, &rx))
    }
}
