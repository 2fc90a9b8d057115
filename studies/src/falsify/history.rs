//! A timing history, what the search works on: per link, what happens to each sample sent
//! (delivered some ticks late, lost, or sent during a stall); its projection onto the bounds;
//! and the few coordinates of the unit cube CMA-ES searches, each mapped to a history.
//!
//! A history of link `l` is admissible under bounds `b` when
//!
//! * every delivered sample's delay is within `[d_min, d_max]` (in a [`Layout`], `d_min` is
//!   the link's causal floor, `bounds::search_floors`: a negative delay only as far as the
//!   other links of its loops make up for it);
//! * two consecutively delivered samples' delays differ by at most the jitter bound (they may
//!   rise and fall, on any period);
//! * samples arrive in the order they were sent (several may arrive at one tick: after a
//!   delay fell, a burst, of which the consumer reads the newest);
//! * at most the loss budget of samples is lost, and the stalls (runs of samples sent during
//!   a stall), each rounded up to whole periods of the consumer, last no longer than the
//!   freeze budget in all: as one outage or many, anywhere in the run.
//!
//! [`project`] maps any history onto the admissible set, and leaves an admissible history as
//! it is: in send order, a lost or stalled sample beyond its budget is delivered instead, and
//! each delivered sample's delay is clamped to what the bounds allow after the previous
//! delivered one (the previous delay satisfies every bound, so there is always one). The
//! search's candidates are projected histories, so each is admissible, and since the
//! projection is the identity on the admissible set, every admissible history is a
//! candidate the search can make (see `mutation`).

use std::ops::Range;

use tiltsim_master::free::trace::Trace;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::Scenario;

use super::bounds::TickBound;
use super::timing::{LinkShape, OutOfBounds};

/// What happens to one sample of a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    /// Delivered this many ticks after the tick its value holds from in lock-step.
    Delivered(i64),
    /// Lost (the loss budget).
    Lost,
    /// Sent during a stall and never delivered (the freeze budget).
    Frozen,
}

/// One link's history: the fate of each sample, in send order.
pub type LinkHistory = Vec<Fate>;

/// The history of every link, in [`LinkId`] order.
pub type History = [LinkHistory; 4];

/// The samples lost, and the ticks stalled (each run of stalled samples rounded up to whole
/// periods of the consumer), of history `h` of link `l`.
pub fn budgets_used(l: &LinkShape, h: &[Fate]) -> (i64, i64) {
    let lost = h.iter().filter(|f| **f == Fate::Lost).count() as i64;
    let mut stalled = 0;
    let mut run = 0i64;
    for f in h.iter().chain(std::iter::once(&Fate::Delivered(0))) {
        if *f == Fate::Frozen {
            run += 1;
        } else if run > 0 {
            stalled += stall_cost(l, run);
            run = 0;
        }
    }
    (lost, stalled)
}

/// Ticks of the freeze budget a stall of `run` samples of link `l` takes: whole periods of
/// the consumer.
fn stall_cost(l: &LinkShape, run: i64) -> i64 {
    let (s, p) = (l.spacing as i64, l.consumer_period as i64);
    (run * s + p - 1) / p * p
}

/// Checks history `h` of link `l` against bounds `b` (see the module's description); the
/// first bound broken is the error.
pub fn admissible(l: &LinkShape, b: &TickBound, h: &[Fate]) -> Result<(), OutOfBounds> {
    let fail = |what: String| OutOfBounds {
        link: l.id.name(),
        what,
    };
    if h.len() != l.samples as usize {
        return Err(fail(format!(
            "{} samples; the run sends {}",
            h.len(),
            l.samples
        )));
    }
    let (lost, stalled) = budgets_used(l, h);
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
    let mut prev: Option<(i64, i64)> = None;
    for (i, f) in h.iter().enumerate() {
        let Fate::Delivered(d) = *f else { continue };
        let v = l.valid_from(i as u64);
        let at = l.step_of(i as u64);
        if d < b.d_min || d > b.d_max {
            return Err(fail(format!(
                "{} step {at} is delivered {d} ticks late; the bounds allow {}..{}",
                l.producer, b.d_min, b.d_max
            )));
        }
        if let Some((pv, pd)) = prev {
            if (d - pd).abs() > b.jitter {
                return Err(fail(format!(
                    "the delay changes by {} ticks at {} step {at}; the jitter bound is {} ticks",
                    (d - pd).abs(),
                    l.producer,
                    b.jitter
                )));
            }
            if v + d < pv + pd {
                return Err(fail(format!(
                    "{} step {at} arrives before the sample sent before it",
                    l.producer
                )));
            }
        }
        prev = Some((v, d));
    }
    Ok(())
}

/// The admissible history nearest `raw` in send order (see the module's description): `raw`
/// itself when it is admissible. Samples past the end of `raw` are delivered as early as
/// allowed.
pub fn project(l: &LinkShape, b: &TickBound, raw: &[Fate]) -> LinkHistory {
    let n = l.samples as usize;
    let mut out = Vec::with_capacity(n);
    let (mut lost, mut stalled) = (0i64, 0i64);
    // The current stall: its samples and the ticks of the budget it takes so far.
    let (mut run, mut run_cost) = (0i64, 0i64);
    // (valid_from, delay) of the last delivered sample.
    let mut prev: Option<(i64, i64)> = None;
    for i in 0..n {
        let held = prev.map_or(b.d_min, |p| p.1);
        let mut f = raw.get(i).copied().unwrap_or(Fate::Delivered(b.d_min));
        if f == Fate::Lost {
            if lost < b.losses {
                lost += 1;
            } else {
                f = Fate::Delivered(held);
            }
        }
        if f == Fate::Frozen {
            let cost = stall_cost(l, run + 1);
            if stalled - run_cost + cost <= b.freeze {
                stalled += cost - run_cost;
                (run, run_cost) = (run + 1, cost);
            } else {
                f = Fate::Delivered(held);
            }
        }
        if f != Fate::Frozen {
            (run, run_cost) = (0, 0);
        }
        if let Fate::Delivered(d) = f {
            let v = l.valid_from(i as u64);
            let (lo, hi) = match prev {
                None => (b.d_min, b.d_max),
                Some((pv, pd)) => (
                    b.d_min.max(pd - b.jitter).max(pd - (v - pv)),
                    b.d_max.min(pd + b.jitter),
                ),
            };
            let d = d.clamp(lo, hi);
            prev = Some((v, d));
            f = Fate::Delivered(d);
        }
        out.push(f);
    }
    out
}

/// Per consumer step of link `l`, the producer step read (−1: the output at t₀) when its
/// samples go as history `h` says: the newest sample delivered at or before the step.
pub fn reads(l: &LinkShape, h: &[Fate]) -> Vec<i64> {
    let arrivals: Vec<(i64, i64)> = h
        .iter()
        .enumerate()
        .filter_map(|(i, f)| match f {
            Fate::Delivered(d) => Some((l.valid_from(i as u64) + d, l.step_of(i as u64))),
            _ => None,
        })
        .collect();
    let mut out = Vec::with_capacity(l.steps.div_ceil(l.consumer_period) as usize);
    let mut next = 0;
    let mut held = -1i64;
    let mut k = 0u64;
    while k < l.steps {
        while next < arrivals.len() && arrivals[next].0 <= k as i64 {
            held = held.max(arrivals[next].1);
            next += 1;
        }
        out.push(held);
        k += l.consumer_period;
    }
    out
}

/// Knots of a link's base delay.
pub const KNOTS: usize = 6;
/// Outages of each kind (lost samples, stalls) per link.
pub const WINDOWS: usize = 2;
/// Longest half-period of the jitter square wave (samples).
pub const JITTER_HALF_PERIOD_MAX: f64 = 50.0;

/// The coordinates of the unit cube a link with bounds `b` takes: [`KNOTS`] knots of a
/// piecewise-linear base delay over the run (when the delay may vary), a jitter amplitude and
/// half-period of a square wave added to it (when the jitter bound is above 0), and per
/// outage of each kind with a budget, its start and its share of the budget.
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

/// The history of link `l` with bounds `b` at coordinates `a` (each in `[0, 1]`, [`dims`] of
/// them), before projection. Each outage may take its kind's whole budget (the projection
/// takes them in send order until the budget is spent): one outage or several, anywhere.
pub fn raw_history(l: &LinkShape, b: &TickBound, a: &[f64]) -> LinkHistory {
    let n = l.samples as usize;
    let mut u = a.iter().map(|x| x.clamp(0.0, 1.0));
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
    let width = (b.d_max - b.d_min) as f64;
    let mut out: LinkHistory = (0..n)
        .map(|i| {
            let x = if n > 1 {
                i as f64 / (n - 1) as f64 * (KNOTS - 1) as f64
            } else {
                0.0
            };
            let j = (x.floor() as usize).min(KNOTS - 2);
            let base = knots[j] + (knots[j + 1] - knots[j]) * (x - j as f64);
            let sign = if (i / half) % 2 == 0 { 0.5 } else { -0.5 };
            let raw = b.d_min as f64 + width * base + sign * amp * b.jitter as f64;
            Fate::Delivered(raw.round() as i64)
        })
        .collect();
    let mut mark = |len: usize, pos: f64, what: Fate| {
        let len = len.min(n);
        let start = ((pos * (n - len) as f64).floor() as usize).min(n - len);
        for f in &mut out[start..start + len] {
            *f = what;
        }
    };
    if b.losses > 0 {
        for _ in 0..WINDOWS {
            let (pos, share) = (u.next().unwrap_or(0.0), u.next().unwrap_or(0.0));
            mark((share * b.losses as f64).round() as usize, pos, Fate::Lost);
        }
    }
    if b.freeze > 0 {
        let p = l.consumer_period as f64;
        for _ in 0..WINDOWS {
            let (pos, share) = (u.next().unwrap_or(0.0), u.next().unwrap_or(0.0));
            // Whole consumer periods, and as many samples as fit in them.
            let periods = (share * (b.freeze as f64 / p)).round();
            mark(
                (periods * p / l.spacing as f64).floor() as usize,
                pos,
                Fate::Frozen,
            );
        }
    }
    out
}

/// The layout of a point over the links: each link's shape, bounds and coordinates.
#[derive(Debug, Clone)]
pub struct Layout {
    /// Per link, in [`LinkId`] order: shape, bounds, and the range of its coordinates.
    pub links: Vec<(LinkShape, TickBound, Range<usize>)>,
    /// Coordinates in all.
    pub dims: usize,
}

impl Layout {
    /// The layout of scenario `s` with bounds `b`: each link's delays from its causal floor
    /// ([`super::bounds::search_floors`]; the bounds' smallest delay unless a loop of links
    /// would let a negative one make a step wait for itself), so every history is causal.
    pub fn new(s: &Scenario, b: &[TickBound; 4]) -> Layout {
        let floors = super::bounds::search_floors(b);
        let mut links = Vec::new();
        let mut at = 0;
        for id in LinkId::ALL {
            let mut tb = b[id as usize];
            tb.d_min = floors[id as usize].min(tb.d_max);
            tb.jitter = tb.jitter.min(tb.d_max - tb.d_min);
            let n = dims(&tb);
            links.push((LinkShape::of(id, s), tb, at..at + n));
            at += n;
        }
        Layout { links, dims: at }
    }

    /// The links the bounds leave a choice on.
    pub fn free(&self) -> Vec<usize> {
        (0..4).filter(|i| self.links[*i].1.free()).collect()
    }

    /// The (projected) history at coordinates `a` (each in `[0, 1]`).
    pub fn history(&self, a: &[f64]) -> History {
        std::array::from_fn(|i| {
            let (l, b, r) = &self.links[i];
            project(l, b, &raw_history(l, b, &a[r.clone()]))
        })
    }

    /// Each link's history projected onto its bounds.
    pub fn project(&self, raw: &History) -> History {
        std::array::from_fn(|i| {
            let (l, b, _) = &self.links[i];
            project(l, b, &raw[i])
        })
    }

    /// Checks every link's history against its bounds.
    pub fn admissible(&self, h: &History) -> Result<(), OutOfBounds> {
        for ((l, b, _), lh) in self.links.iter().zip(h) {
            admissible(l, b, lh)?;
        }
        Ok(())
    }

    /// The trace of history `h` of scenario `s`.
    pub fn trace(&self, s: &Scenario, h: &History) -> Trace {
        let reads: [Vec<i64>; 4] = std::array::from_fn(|i| reads(&self.links[i].0, &h[i]));
        super::timing::trace(s, &reads)
    }

    /// The history of every link delivering every sample as early as its bounds allow.
    pub fn earliest(&self) -> History {
        self.history(&vec![0.0; self.dims])
    }
}
