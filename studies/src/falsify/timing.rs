//! Timing traces: a link's shape in a scenario (who sends, who reads, how often), the trace
//! (`timing.csv`) the lock-step replay reads for given reads of each consumer step, and the
//! check of any trace against bounds (what a trace shows of each link's timing).
//!
//! A consumer step reads the newest sample delivered at or before its tick (the output at t₀
//! before any). A delay is counted from the tick the sample's value holds from in lock-step;
//! it is negative when the consumer lags its producer (a free run's starved participant reads,
//! at its step k, a producer step of a later tick). A made trace places every step at its
//! tick's instant (the controller before the actuator, the actuator before the plant, as in
//! the lock-step coupling) unless it waits for a sample of a producer it lags; its reads are
//! causal when the delays add up to 0 or more around each loop of links
//! ([`super::bounds::LOOPS`]), as the search's are.

use cosim::Role;
use tiltsim_master::free::trace::{col, inputs_of, StepTrace, Trace, TraceHead};
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::Scenario;

use super::bounds::TickBound;

/// Where a link's samples come from and go to in one scenario.
#[derive(Debug, Clone, Copy)]
pub struct LinkShape {
    /// The link.
    pub id: LinkId,
    /// Who sends.
    pub producer: Role,
    /// Who reads.
    pub consumer: Role,
    /// Ticks between two samples sent.
    pub spacing: u64,
    /// Ticks between two consumer steps.
    pub consumer_period: u64,
    /// Samples sent over the run.
    pub samples: u64,
    /// Ticks of the run.
    pub steps: u64,
}

impl LinkShape {
    /// Link `id` in scenario `s`.
    pub fn of(id: LinkId, s: &Scenario) -> LinkShape {
        let period = s.controller_period_ticks();
        let steps = s.steps();
        let ticks = |r: Role| if r == Role::Controller { period } else { 1 };
        let (producer, consumer) = match id {
            LinkId::ActuatorCommand => (Role::Controller, Role::Actuator),
            LinkId::BarAngle => (Role::Actuator, Role::Plant),
            LinkId::Measurement => (Role::Plant, Role::Controller),
            LinkId::BarTwist => (Role::Plant, Role::Actuator),
        };
        LinkShape {
            id,
            producer,
            consumer,
            spacing: ticks(producer),
            consumer_period: ticks(consumer),
            samples: steps.div_ceil(ticks(producer)),
            steps,
        }
    }

    /// The tick sample `i` holds from in lock-step (a plant output of step q at q + 1).
    pub fn valid_from(&self, i: u64) -> i64 {
        let q = (i * self.spacing) as i64;
        if self.producer == Role::Plant {
            q + 1
        } else {
            q
        }
    }

    /// The producer step of sample `i`.
    pub fn step_of(&self, i: u64) -> i64 {
        (i * self.spacing) as i64
    }
}

/// Instants of a made trace, within a tick of `dt_ns`: the controller reads first, then the
/// actuator, then the plant, as the lock-step coupling orders them.
fn offset(role: Role, dt_ns: u64) -> u64 {
    match role {
        Role::Controller => dt_ns / 8,
        Role::Actuator => 3 * dt_ns / 8,
        Role::Plant => 5 * dt_ns / 8,
    }
}

/// The steps of a made trace as they are placed: per role (by [`col`]) the steps placed so
/// far, each known by its publish instant.
struct Placer<'a> {
    reads: &'a [Vec<i64>; 4],
    period: u64,
    dt_ns: u64,
    /// Steps per role, by [`col`].
    count: [u64; 3],
    /// Publish instants of the steps placed, per role by [`col`].
    published: [Vec<u64>; 3],
}

impl Placer<'_> {
    fn ticks(&self, role: Role) -> u64 {
        if role == Role::Controller {
            self.period
        } else {
            1
        }
    }

    /// The producer steps consumer step `k` of `role` reads.
    fn from(&self, role: Role, k: u64) -> [Option<i64>; 3] {
        let at = |l: LinkId, p: u64| Some(self.reads[l as usize][(k / p) as usize]);
        let mut f = [None; 3];
        match role {
            Role::Controller => f[col(Role::Plant)] = at(LinkId::Measurement, self.period),
            Role::Actuator => {
                f[col(Role::Controller)] = at(LinkId::ActuatorCommand, 1);
                f[col(Role::Plant)] = at(LinkId::BarTwist, 1);
            }
            Role::Plant => f[col(Role::Actuator)] = at(LinkId::BarAngle, 1),
        }
        f
    }

    /// Step `k` of `role` read at its tick's instant for the role.
    fn at_tick(&self, role: Role, k: u64) -> StepTrace {
        let due = k * self.dt_ns;
        let read = due + offset(role, self.dt_ns);
        StepTrace {
            role,
            step: k,
            from: self.from(role, k),
            due_ns: due,
            read_ns: read,
            compute_end_ns: read + self.dt_ns / 16,
            publish_ns: read + self.dt_ns / 16,
        }
    }

    /// The next step of `role` (`None`: every step is placed) and whether every input it
    /// reads is placed; read at its tick's instant or, when an input it reads or its own
    /// previous step is published later, just after.
    fn next(&self, role: Role) -> Option<(StepTrace, bool)> {
        let c = col(role);
        let n = self.published[c].len() as u64;
        if n >= self.count[c] {
            return None;
        }
        let mut t = self.at_tick(role, n * self.ticks(role));
        let mut ready = true;
        for &p in inputs_of(role) {
            let Some(q) = t.from[col(p)].filter(|&q| q >= 0) else {
                continue;
            };
            match self.published[col(p)].get((q as u64 / self.ticks(p)) as usize) {
                Some(&at) => t.read_ns = t.read_ns.max(at + 1),
                None => ready = false,
            }
        }
        if let Some(&at) = self.published[c].last() {
            t.read_ns = t.read_ns.max(at + 1);
        }
        t.compute_end_ns = t.read_ns + self.dt_ns / 16;
        t.publish_ns = t.compute_end_ns;
        Some((t, ready))
    }
}

/// The trace of scenario `s` in which consumer steps read as `reads` says (per link, in
/// [`LinkId`] order, one entry per consumer step); its steps in read order. Of the steps
/// whose inputs are published, the one due first is placed next; a step is read at its
/// tick's instant (controller, actuator, plant within a tick, as the lock-step coupling
/// orders them) unless it waits for an input published later, the sample of a producer it
/// lags (a negative delay). Delays of 0 or more never wait: every step is at its tick's
/// instant. Reads that no order can serve (a loop of steps waiting for each other, see
/// [`super::bounds::LOOPS`]) leave the steps left at their ticks' instants, a trace the
/// causality check refuses.
pub fn trace(s: &Scenario, reads: &[Vec<i64>; 4]) -> Trace {
    let steps = s.steps();
    let period = s.controller_period_ticks();
    let mut p = Placer {
        reads,
        period,
        dt_ns: (s.run.dt_s * 1e9).round() as u64,
        count: [steps, steps, steps.div_ceil(period)],
        published: Default::default(),
    };
    let mut out = Vec::with_capacity(p.count.iter().sum::<u64>() as usize);
    loop {
        let next = [Role::Controller, Role::Actuator, Role::Plant].map(|r| p.next(r));
        if next.iter().all(Option::is_none) {
            break;
        }
        let due_first = |t: &StepTrace| t.due_ns + offset(t.role, p.dt_ns);
        let ready = next.iter().flatten().filter(|n| n.1);
        let Some((t, _)) = ready.min_by_key(|n| due_first(&n.0)) else {
            // Stuck: the steps left at their ticks' instants.
            for r in Role::ALL {
                let c = col(r);
                for n in p.published[c].len() as u64..p.count[c] {
                    out.push(p.at_tick(r, n * p.ticks(r)));
                }
            }
            break;
        };
        p.published[col(t.role)].push(t.publish_ns);
        out.push(*t);
    }
    let key = |x: &StepTrace| (x.read_ns, col(x.role));
    if !out.is_sorted_by_key(key) {
        out.sort_by_key(key);
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

/// What a trace shows of one link's timing, in ticks and samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkObs {
    /// Smallest delay a delivered sample can have had.
    pub d_min: i64,
    /// Largest delay a delivered sample can have had.
    pub d_max: i64,
    /// Largest change of delay between consecutively delivered samples (less the consumer's
    /// period, which hides when within it a sample arrived, and spread over the samples a
    /// consumer of period > 1 tick may not have read in between).
    pub jitter: i64,
    /// Samples not read that no later sample read at the same consumer step can explain.
    pub dropped: i64,
}

/// Why a trace is not within its bounds: the link, where, and which bound.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("link {link}: {what}")]
pub struct OutOfBounds {
    /// The link's name.
    pub link: &'static str,
    /// The bound broken and where.
    pub what: String,
}

/// Per consumer step of link `l`, the producer step it read, from a trace's steps.
pub fn reads_of(l: &LinkShape, steps: &[StepTrace]) -> Vec<i64> {
    let n = l.steps.div_ceil(l.consumer_period) as usize;
    let mut out = vec![-1; n];
    for t in steps.iter().filter(|t| t.role == l.consumer) {
        if let Some(q) = t.from[col(l.producer)] {
            if let Some(o) = out.get_mut((t.step / l.consumer_period) as usize) {
                *o = q;
            }
        }
    }
    out
}

/// What the consumer steps' reads `r` of link `l` show of its timing, checked against `b`
/// when given (the first bound broken is the error). The reads must never go back to an
/// older sample (delivery in send order).
pub fn observe(l: &LinkShape, r: &[i64], b: Option<&TickBound>) -> Result<LinkObs, OutOfBounds> {
    let fail = |what: String| OutOfBounds {
        link: l.id.name(),
        what,
    };
    let p = l.consumer_period as i64;
    // The delivered samples: (sample index, consumer step it was first read at).
    let mut first: Vec<(u64, i64)> = Vec::new();
    let mut last = -1i64;
    for (j, &q) in r.iter().enumerate() {
        let k = j as i64 * p;
        if q < last {
            return Err(fail(format!(
                "{} step {k} reads {} step {q} after step {last}: samples are delivered in the order they were sent",
                l.consumer, l.producer
            )));
        }
        if q > last {
            first.push(((q as u64) / l.spacing, k));
            last = q;
        }
    }
    let mut obs = LinkObs {
        d_min: i64::MAX,
        ..Default::default()
    };
    let mut prev: Option<(u64, i64)> = None;
    for &(i, k) in &first {
        // Delivered after the consumer's previous step, at or before this one: a delay in
        // `hi - (p - 1)..=hi`, of 0 or more unless the read itself shows the consumer lagging
        // its producer (`hi < 0`: the sample read before the tick its value holds from, the
        // read's own delay).
        // Checked against bounds, any delay of that range the bounds admit explains it.
        let hi = k - l.valid_from(i);
        let lo = (hi - (p - 1)).max(hi.min(0));
        obs.d_min = obs.d_min.min(lo);
        obs.d_max = obs.d_max.max(hi);
        if let Some(b) = b {
            if hi < b.d_min || hi - (p - 1) > b.d_max {
                return Err(fail(format!(
                    "{} step {} is delivered {}..{} ticks late; the bounds allow {}..{}",
                    l.producer,
                    l.step_of(i),
                    lo,
                    hi,
                    b.d_min,
                    b.d_max
                )));
            }
        }
        if let Some((pi, ph)) = prev {
            let change = if p > 1 {
                // A consumer that reads every p > 1 ticks may miss samples delivered between
                // its steps: each of those changed the delay by at most the bound.
                let between = (i - pi).max(1) as i64;
                (((hi - ph).abs() - (p - 1)).max(0) + between - 1) / between
            } else if hi < ph {
                fall_change(ph - hi, (i - pi - 1) as i64, l.spacing as i64)
            } else {
                hi - ph
            };
            obs.jitter = obs.jitter.max(change);
            if let Some(b) = b {
                if change > b.jitter {
                    return Err(fail(format!(
                        "the delay changes by {change} ticks at {} step {}; the jitter bound is {} ticks",
                        l.producer,
                        l.step_of(i),
                        b.jitter
                    )));
                }
            }
        }
        prev = Some((i, hi));
    }
    if obs.d_min == i64::MAX {
        obs.d_min = 0;
    }
    let (d_min, d_max) = b.map_or((obs.d_min, obs.d_max), |b| (b.d_min, b.d_max));
    let dropped = dropped(l, &first, d_min, d_max);
    obs.dropped = dropped;
    if let Some(b) = b {
        if dropped > b.drops {
            return Err(fail(format!(
                "{dropped} samples are not delivered; the loss and freeze budgets together allow {}",
                b.drops
            )));
        }
    }
    Ok(obs)
}

/// The smallest change of delay between consecutively delivered samples that explains a
/// fall of `fall` ticks between two samples read by a consumer of every tick, `room` samples
/// apart less one: the samples between were lost, or the last `m` of them were delivered
/// unread at the tick the later one arrived (in send order, a burst: their delays fall by
/// the sample spacing `s` one to the next, and the first of them changed the delay by
/// `fall − m·s`).
fn fall_change(fall: i64, room: i64, s: i64) -> i64 {
    let m = if s > 0 { (fall / s).min(room) } else { 0 };
    let with = |m: i64| {
        if m == 0 {
            fall
        } else {
            (fall - m * s).abs().max(s)
        }
    };
    [0, m, (m + 1).min(room)]
        .into_iter()
        .map(with)
        .min()
        .unwrap_or(fall)
}

/// Of link `l`'s samples before the last one read (`first`: each delivered sample and the
/// consumer step that first read it), those not read that no delay in `[d_min, d_max]` can
/// explain: a sample is explained when it could have arrived with the next sample read, in
/// the same consumer period; dropped otherwise.
fn dropped(l: &LinkShape, first: &[(u64, i64)], d_min: i64, d_max: i64) -> i64 {
    let p = l.consumer_period as i64;
    let mut it = first.iter().peekable();
    let mut dropped = 0;
    let last_read = first.last().map_or(0, |f| f.0 + 1);
    for i in 0..last_read {
        while it.peek().is_some_and(|f| f.0 < i) {
            it.next();
        }
        let Some(&&(next, k)) = it.peek() else { break };
        if next == i {
            continue;
        }
        let v = l.valid_from(i);
        if !(v + d_min <= k && v + d_max > k - p) {
            dropped += 1;
        }
    }
    dropped
}

/// Checks trace `t` of scenario `s` against bounds `b`: every link's reads in send order,
/// delays, jitter and drops within bounds; and causal (each input computed before it is
/// read, in the order the replay takes the steps).
pub fn check(s: &Scenario, t: &Trace, b: &[TickBound; 4]) -> Result<[LinkObs; 4], String> {
    let key = |x: &StepTrace| (x.read_ns, col(x.role));
    // A made trace is in read order already: copied and sorted only when it is not.
    let order = if t.steps.is_sorted_by_key(key) {
        std::borrow::Cow::Borrowed(&t.steps)
    } else {
        let mut o = t.steps.clone();
        o.sort_by_key(key);
        std::borrow::Cow::Owned(o)
    };
    tiltsim_master::free::timing_replay::check_causal(
        std::path::Path::new("(candidate)"),
        &order,
        s.controller_period_ticks(),
    )
    .map_err(|e| e.to_string())?;
    let mut out = [LinkObs::default(); 4];
    for id in LinkId::ALL {
        let l = LinkShape::of(id, s);
        out[id as usize] = observe(&l, &reads_of(&l, &t.steps), Some(&b[id as usize]))
            .map_err(|e| e.to_string())?;
    }
    Ok(out)
}

/// What trace `t` of scenario `s` shows of each link's timing (for the envelope of recorded
/// runs).
pub fn observe_all(s: &Scenario, t: &Trace) -> Result<[LinkObs; 4], OutOfBounds> {
    let mut out = [LinkObs::default(); 4];
    for id in LinkId::ALL {
        let l = LinkShape::of(id, s);
        out[id as usize] = observe(&l, &reads_of(&l, &t.steps), None)?;
    }
    Ok(out)
}
