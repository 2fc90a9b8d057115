//! Timing histories that are causal and within their bounds by construction: a point of the
//! unit cube is mapped to each link's sample delays and losses, then to the trace
//! (`timing.csv`) the lock-step replay reads; and the check of any trace against bounds.
//!
//! Per free link (one whose bounds leave a choice), the point holds:
//!
//! * [`KNOTS`] knots of a piecewise-linear base delay over the run, each scaled into
//!   `[d_min, d_max]`;
//! * a jitter amplitude (a share of the jitter bound) and a half-period (1 to
//!   [`JITTER_HALF_PERIOD_MAX`] samples) of a square wave added to the base;
//! * [`WINDOWS`] windows of lost samples, each a position and a share of the link's loss
//!   budget (when it has one);
//! * [`WINDOWS`] stalls, each a position and a share of the link's freeze budget (when it has
//!   one), a stall's samples never delivered, its length whole periods of the consumer.
//!
//! A sample in a stall and a loss window is frozen, not lost: the samples lost never exceed
//! the loss budget, and the stalls, each rounded up to whole consumer periods, never exceed
//! the freeze budget ([`check_budgets`]).
//!
//! Each sample's delay is then projected, in send order, onto what the bounds allow given the
//! previous delivered sample: within `[d_min, d_max]`, within the jitter bound of the
//! previous delay, and late enough that it arrives after the previous one (delivery in send
//! order). The projection always has a solution (the previous delay satisfies every bound),
//! so every point gives an admissible timing. A consumer step reads the newest sample
//! delivered at or before its tick (the output at t₀ before any), which is never a step not
//! yet computed: a sample is delivered no earlier than the tick its value holds from in
//! lock-step, and within a tick the controller steps before the actuator, the actuator before
//! the plant, as in the lock-step coupling.

use cosim::Role;
use tiltsim_master::free::trace::{col, StepTrace, Trace, TraceHead};
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::Scenario;

use super::bounds::TickBound;

/// Knots of a link's base delay.
pub const KNOTS: usize = 6;
/// Windows of undelivered samples per link.
pub const WINDOWS: usize = 2;
/// Longest half-period of the jitter square wave (samples).
pub const JITTER_HALF_PERIOD_MAX: f64 = 50.0;

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

/// The coordinates of the unit cube a link with bounds `b` takes.
pub fn dims(b: &TickBound) -> usize {
    let mut n = 0;
    if b.d_max > b.d_min {
        n += KNOTS;
        if b.jitter > 0 {
            n += 2;
        }
    }
    if b.losses > 0 {
        n += 2 * WINDOWS;
    }
    if b.freeze > 0 {
        n += 2 * WINDOWS;
    }
    n
}

/// A link's timing: per sample, its delay in ticks, or `None` when not delivered.
pub type Schedule = Vec<Option<i64>>;

/// Why a sample is not delivered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Undelivered {
    /// It is delivered.
    No,
    /// Lost (the loss budget).
    Lost,
    /// Sent during a stall (the freeze budget).
    Frozen,
}

/// Which samples of link `l` with bounds `b` are lost and which frozen, from the coordinates
/// of its windows (`u`: the loss windows' then the stalls', each a position and a share).
pub fn undelivered(
    l: &LinkShape,
    b: &TickBound,
    u: &mut impl Iterator<Item = f64>,
) -> Vec<Undelivered> {
    let n = l.samples as usize;
    let mut out = vec![Undelivered::No; n];
    let mut mark = |len: usize, pos: f64, what: Undelivered| {
        let len = len.min(n);
        let start = (pos * (n - len) as f64).floor() as usize;
        for d in &mut out[start..start + len] {
            *d = what;
        }
    };
    if b.losses > 0 {
        for _ in 0..WINDOWS {
            let (pos, share) = (u.next().unwrap_or(0.0), u.next().unwrap_or(0.0));
            let len = (share * b.losses as f64 / WINDOWS as f64).floor() as usize;
            mark(len, pos, Undelivered::Lost);
        }
    }
    if b.freeze > 0 {
        let p = l.consumer_period as f64;
        for _ in 0..WINDOWS {
            let (pos, share) = (u.next().unwrap_or(0.0), u.next().unwrap_or(0.0));
            // Whole consumer periods, and as many samples as fit in them.
            let periods = (share * (b.freeze as f64 / p) / WINDOWS as f64).floor();
            let len = (periods * p / l.spacing as f64).floor() as usize;
            mark(len, pos, Undelivered::Frozen);
        }
    }
    out
}

/// The samples lost, and the ticks stalled (each run of frozen samples rounded up to whole
/// periods of the consumer), of `marks`.
pub fn budgets_used(l: &LinkShape, marks: &[Undelivered]) -> (i64, i64) {
    let lost = marks.iter().filter(|m| **m == Undelivered::Lost).count() as i64;
    let (s, p) = (l.spacing as i64, l.consumer_period as i64);
    let mut stalled = 0;
    let mut run = 0i64;
    for m in marks.iter().chain(std::iter::once(&Undelivered::No)) {
        if *m == Undelivered::Frozen {
            run += 1;
        } else if run > 0 {
            stalled += (run * s + p - 1) / p * p;
            run = 0;
        }
    }
    (lost, stalled)
}

/// Checks the samples lost against the loss budget and the stalls against the freeze budget,
/// each on its own.
pub fn check_budgets(
    l: &LinkShape,
    b: &TickBound,
    marks: &[Undelivered],
) -> Result<(), OutOfBounds> {
    let (lost, stalled) = budgets_used(l, marks);
    let fail = |what: String| OutOfBounds {
        link: l.id.name(),
        what,
    };
    if lost > b.losses {
        return Err(fail(format!(
            "{lost} samples lost; the loss budget allows {}",
            b.losses
        )));
    }
    if stalled > b.freeze {
        return Err(fail(format!(
            "stalled {stalled} ticks (in whole periods of {} of {} ticks); the freeze budget allows {}",
            l.consumer, l.consumer_period, b.freeze
        )));
    }
    Ok(())
}

/// The schedule of a link of shape `l` with bounds `b` from its coordinates `u` (each in
/// `[0, 1]`, [`dims`] of them).
pub fn schedule(l: &LinkShape, b: &TickBound, u: &[f64]) -> Schedule {
    let n = l.samples as usize;
    let mut u = u.iter().map(|x| x.clamp(0.0, 1.0));
    let mut knots = [0.0; KNOTS];
    let (mut amp, mut half) = (0.0, 1usize);
    if b.d_max > b.d_min {
        for k in &mut knots {
            *k = u.next().unwrap_or(0.0);
        }
        if b.jitter > 0 {
            amp = u.next().unwrap_or(0.0);
            half = 1 + (u.next().unwrap_or(0.0) * (JITTER_HALF_PERIOD_MAX - 1.0)).round() as usize;
        }
    }
    let dropped = undelivered(l, b, &mut u);
    let width = (b.d_max - b.d_min) as f64;
    let mut prev: Option<(i64, i64)> = None; // (valid_from, delay) of the last delivered
    let mut out = Vec::with_capacity(n);
    for (i, drop) in dropped.iter().enumerate() {
        if *drop != Undelivered::No {
            out.push(None);
            continue;
        }
        let x = if n > 1 {
            i as f64 / (n - 1) as f64 * (KNOTS - 1) as f64
        } else {
            0.0
        };
        let j = (x.floor() as usize).min(KNOTS - 2);
        let base = knots[j] + (knots[j + 1] - knots[j]) * (x - j as f64);
        let sign = if (i / half) % 2 == 0 { 0.5 } else { -0.5 };
        let raw = b.d_min as f64 + width * base + sign * amp * b.jitter as f64;
        let v = l.valid_from(i as u64);
        let (lo, hi) = match prev {
            None => (b.d_min, b.d_max),
            Some((pv, pd)) => (
                b.d_min.max(pd - b.jitter).max(pd - (v - pv) + 1),
                b.d_max.min(pd + b.jitter),
            ),
        };
        let d = (raw.round() as i64).clamp(lo, hi);
        prev = Some((v, d));
        out.push(Some(d));
    }
    out
}

/// Per consumer step of link `l`, the producer step read (−1: the output at t₀) when the
/// samples are delivered as `sched` says.
pub fn reads(l: &LinkShape, sched: &Schedule) -> Vec<i64> {
    let arrivals: Vec<(i64, u64)> = sched
        .iter()
        .enumerate()
        .filter_map(|(i, d)| d.map(|d| (l.valid_from(i as u64) + d, i as u64)))
        .collect();
    let mut out = Vec::with_capacity(l.steps.div_ceil(l.consumer_period) as usize);
    let mut next = 0;
    let mut held = -1i64;
    let mut k = 0u64;
    while k < l.steps {
        while next < arrivals.len() && arrivals[next].0 <= k as i64 {
            held = l.step_of(arrivals[next].1);
            next += 1;
        }
        out.push(held);
        k += l.consumer_period;
    }
    out
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

/// The trace of scenario `s` in which consumer steps read as `reads` says (per link, in
/// [`LinkId`] order, one entry per consumer step); its steps in read order.
pub fn trace(s: &Scenario, reads: &[Vec<i64>; 4]) -> Trace {
    let steps = s.steps();
    let period = s.controller_period_ticks();
    let dt_ns = (s.run.dt_s * 1e9).round() as u64;
    let mut out = Vec::with_capacity(2 * steps as usize + steps.div_ceil(period) as usize);
    let at = |l: LinkId, k: u64, p: u64| reads[l as usize][(k / p) as usize];
    for k in 0..steps {
        let mut push = |role: Role, from: [Option<i64>; 3]| {
            let due = k * dt_ns;
            let read = due + offset(role, dt_ns);
            out.push(StepTrace {
                role,
                step: k,
                from,
                due_ns: due,
                read_ns: read,
                compute_end_ns: read + dt_ns / 16,
                publish_ns: read + dt_ns / 16,
            });
        };
        if k % period == 0 {
            let mut f = [None; 3];
            f[col(Role::Plant)] = Some(at(LinkId::Measurement, k, period));
            push(Role::Controller, f);
        }
        let mut f = [None; 3];
        f[col(Role::Controller)] = Some(at(LinkId::ActuatorCommand, k, 1));
        f[col(Role::Plant)] = Some(at(LinkId::BarTwist, k, 1));
        push(Role::Actuator, f);
        let mut f = [None; 3];
        f[col(Role::Actuator)] = Some(at(LinkId::BarAngle, k, 1));
        push(Role::Plant, f);
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

/// The layout of a point over the links: each link's shape, bounds and coordinates.
#[derive(Debug, Clone)]
pub struct Layout {
    /// Per link, in [`LinkId`] order: shape, bounds, and the range of its coordinates.
    pub links: Vec<(LinkShape, TickBound, std::ops::Range<usize>)>,
    /// Coordinates in all.
    pub dims: usize,
}

impl Layout {
    /// The layout of scenario `s` with bounds `b`.
    pub fn new(s: &Scenario, b: &[TickBound; 4]) -> Layout {
        let mut links = Vec::new();
        let mut at = 0;
        for id in LinkId::ALL {
            let tb = b[id as usize];
            let n = dims(&tb);
            links.push((LinkShape::of(id, s), tb, at..at + n));
            at += n;
        }
        Layout { links, dims: at }
    }

    /// Checks each link's samples lost and stalls of point `u` against its loss and freeze
    /// budgets, each on its own.
    pub fn check_budgets(&self, u: &[f64]) -> Result<(), OutOfBounds> {
        for (l, b, r) in &self.links {
            let delays = dims(&TickBound {
                losses: 0,
                freeze: 0,
                ..*b
            });
            let mut it = u[r.start + delays..r.end].iter().map(|x| x.clamp(0.0, 1.0));
            check_budgets(l, b, &undelivered(l, b, &mut it))?;
        }
        Ok(())
    }

    /// The trace of point `u` (coordinates in `[0, 1]`).
    pub fn trace(&self, s: &Scenario, u: &[f64]) -> Trace {
        let reads: [Vec<i64>; 4] = std::array::from_fn(|i| {
            let (l, b, r) = &self.links[i];
            reads(l, &schedule(l, b, &u[r.clone()]))
        });
        trace(s, &reads)
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
        // Delivered after the consumer's previous step, at or before this one.
        let hi = k - l.valid_from(i);
        let lo = (hi - (p - 1)).max(0);
        if hi < 0 {
            return Err(fail(format!(
                "{} step {k} reads {} step {} before its value holds",
                l.consumer,
                l.producer,
                l.step_of(i)
            )));
        }
        obs.d_min = obs.d_min.min(lo);
        obs.d_max = obs.d_max.max(hi);
        if let Some(b) = b {
            if hi < b.d_min || lo > b.d_max {
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
            // A consumer that reads every p > 1 ticks may miss samples delivered between its
            // steps: each of those changed the delay by at most the bound.
            let between = if p > 1 { (i - pi).max(1) as i64 } else { 1 };
            let change = (((hi - ph).abs() - (p - 1)).max(0) + between - 1) / between;
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
