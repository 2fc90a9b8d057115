//! The admissible timing of each link (`--bounds FILE`, or the envelope of recorded free runs'
//! `timing.csv`): what a falsifying search may do to the samples a link carries.
//!
//! A link carries one sample per producer step. The timing of a sample is its delay, in
//! whole ticks, from the tick its value holds from in lock-step to the tick it is delivered,
//! or its loss. A link's bounds:
//!
//! * `delay_ms = [min, max]`: every delivered sample's delay (whole ticks inside the range);
//! * `jitter_ms`: how much two consecutively delivered samples' delays may differ (the
//!   packet delay variation of RFC 3393); absent, only the range bounds it;
//! * `loss_pct`: the share of the link's samples that may be lost;
//! * `freeze_ms`: for how long in all the link may stall (a stalled sender, a link holding
//!   its last value: the consumer holds the last sample delivered, and the samples sent
//!   meanwhile are never delivered). A budget of its own, apart from the loss budget, counted
//!   at the reading participant's period: whole periods of the consumer, each stall rounded up
//!   to them.
//!
//! Samples are delivered in the order they were sent. A link not named keeps its lock-step
//! timing (delay 0, nothing lost).
//!
//! A delay may be negative: a consumer that lags its producer on the wall clock (in a free
//! run each participant keeps its own clock, and a starved one falls behind) reads, at its
//! step k, a sample whose value holds from a later tick. In tick terms that sample is
//! delivered before the tick it holds from, and the lock-step replay reproduces it as it is
//! (the producer's step is taken before the consumer's). What keeps such a timing causal is
//! the loop it is part of: a consumer ahead of its input in ticks is behind on the way back, so
//! around each loop of links, plant → actuator → plant and controller → actuator → plant →
//! controller, the delays add up to 0 or more ([`LOOPS`]). The bounds must admit that (the
//! largest delays around each loop add up to 0 or more); the search makes delays from each
//! link's causal floor ([`search_floors`]), so its candidates are causal whatever each link
//! does, and a recorded run's trace, causal as it happened, is checked against the whole range.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use tiltsim_scenario::links::{LinkId, LINK_NAMES};
use tiltsim_scenario::scenario::Scenario;

use super::FalsifyError;

/// One link's admissible timing, as the bounds file gives it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkBound {
    /// Smallest and largest delay of a delivered sample (ms).
    pub delay_ms: [f64; 2],
    /// Largest difference between the delays of two consecutively delivered samples (ms);
    /// absent: the width of the range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jitter_ms: Option<f64>,
    /// Share of the link's samples that may be lost (%).
    #[serde(default)]
    pub loss_pct: f64,
    /// Total time the link may deliver nothing (ms).
    #[serde(default)]
    pub freeze_ms: f64,
}

impl LinkBound {
    /// The lock-step timing: delay 0, nothing lost.
    pub const LOCK_STEP: LinkBound = LinkBound {
        delay_ms: [0.0, 0.0],
        jitter_ms: Some(0.0),
        loss_pct: 0.0,
        freeze_ms: 0.0,
    };
}

/// The bounds of every link, in [`LinkId`] order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Per link.
    pub links: [LinkBound; 4],
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds {
            links: [LinkBound::LOCK_STEP; 4],
        }
    }
}

/// A link's bounds in whole ticks and samples of one scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TickBound {
    /// Smallest delay (ticks).
    pub d_min: i64,
    /// Largest delay (ticks).
    pub d_max: i64,
    /// Largest change of delay between consecutively delivered samples (ticks).
    pub jitter: i64,
    /// Samples that may be lost (the loss budget).
    pub losses: i64,
    /// Ticks the link may stall in all (the freeze budget): whole periods of the consumer.
    pub freeze: i64,
    /// Samples that may be left undelivered, lost and frozen together (what a trace, which
    /// does not say why a sample was not delivered, is checked against).
    pub drops: i64,
}

impl TickBound {
    /// Whether the search has anything to choose on this link.
    pub fn free(&self) -> bool {
        self.d_max > self.d_min || self.losses > 0 || self.freeze > 0
    }
}

/// The loops of links: a consumer's step waits for its producer's, which waits, through the
/// links of the loop, for an earlier step of the consumer. A timing is causal when the delays
/// of the samples read add up to 0 or more around each (a plant output holds from the tick
/// after its step, the other outputs from their own step: each loop holds one plant output,
/// so a sum of 0 still leaves the consumer's earlier step first).
pub const LOOPS: [&[LinkId]; 2] = [
    &[LinkId::BarAngle, LinkId::BarTwist],
    &[
        LinkId::ActuatorCommand,
        LinkId::BarAngle,
        LinkId::Measurement,
    ],
];

/// The smallest delay the search makes on each link, in [`LinkId`] order: the bounds' own,
/// raised where a loop's smallest delays add up to less than 0 ([`LOOPS`]) until they add up
/// to 0, the most negative first and toward 0 before beyond it. Every timing whose delays are
/// at or above these floors is causal: each link may still lag (a negative floor) as far as
/// the other links of its loops make up for it. Within `[d_min, d_max]` when the largest
/// delays around each loop add up to 0 or more, as [`Bounds::ticks`] checks.
pub fn search_floors(b: &[TickBound; 4]) -> [i64; 4] {
    let mut f: [i64; 4] = std::array::from_fn(|i| b[i].d_min);
    for ring in LOOPS {
        let mut short = -ring.iter().map(|id| f[*id as usize]).sum::<i64>();
        for toward_zero in [true, false] {
            let mut order: Vec<usize> = ring.iter().map(|id| *id as usize).collect();
            order.sort_by_key(|&i| f[i]);
            for i in order {
                let cap = if toward_zero {
                    b[i].d_max.min(0)
                } else {
                    b[i].d_max
                };
                let up = short.min(cap - f[i]).max(0);
                f[i] += up;
                short -= up;
            }
        }
    }
    f
}

fn err(file: &str, field: String, what: String) -> FalsifyError {
    FalsifyError::Invalid(format!("{file}: {field}: {what}"))
}

impl Bounds {
    /// Reads a bounds file: one table per link, named as in `[links.<name>]`.
    pub fn read(path: &Path) -> Result<Bounds, FalsifyError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| FalsifyError::Invalid(format!("{file}: {e}")))?;
        Bounds::parse(&text, &file)
    }

    /// Parses the text of a bounds file (`file` names it in errors); checks every field.
    pub fn parse(text: &str, file: &str) -> Result<Bounds, FalsifyError> {
        let de = toml::Deserializer::parse(text)
            .map_err(|e| FalsifyError::Invalid(format!("{file}: {e}")))?;
        let map: BTreeMap<String, LinkBound> = serde_path_to_error::deserialize(de)
            .map_err(|e| err(file, e.path().to_string(), e.inner().message().to_string()))?;
        let mut b = Bounds::default();
        for (name, lb) in map {
            let i = LINK_NAMES.iter().position(|n| *n == name).ok_or_else(|| {
                err(
                    file,
                    format!("[{name}]"),
                    format!("not a link; allowed: {}", LINK_NAMES.join(", ")),
                )
            })?;
            b.links[i] = lb;
        }
        b.validate(file)?;
        Ok(b)
    }

    /// Checks every link's fields: finite, `-10000 <= min <= max <= 10000` ms (a negative
    /// delay: the consumer lags its producer), jitter and freeze `>= 0` ms, loss in `[0, 100]` %.
    pub fn validate(&self, file: &str) -> Result<(), FalsifyError> {
        for (name, l) in LINK_NAMES.iter().zip(&self.links) {
            let [lo, hi] = l.delay_ms;
            let f = |field: &str| format!("[{name}] {field}");
            if !(lo.is_finite() && hi.is_finite() && lo >= -10_000.0 && hi <= 10_000.0) {
                return Err(err(
                    file,
                    f("delay_ms"),
                    format!(
                        "[{lo}, {hi}]; allowed: [min, max] with -10000 <= min <= max <= 10000 ms"
                    ),
                ));
            }
            if lo > hi {
                return Err(err(
                    file,
                    f("delay_ms"),
                    format!("[{lo}, {hi}]: min > max; allowed: [min, max] with -10000 <= min <= max <= 10000 ms"),
                ));
            }
            if let Some(j) = l.jitter_ms {
                if !(j.is_finite() && j >= 0.0) {
                    return Err(err(file, f("jitter_ms"), format!("{j}; allowed: >= 0 ms")));
                }
            }
            if !(l.loss_pct.is_finite() && (0.0..=100.0).contains(&l.loss_pct)) {
                return Err(err(
                    file,
                    f("loss_pct"),
                    format!("{}; allowed: 0 to 100 %", l.loss_pct),
                ));
            }
            if !(l.freeze_ms.is_finite() && l.freeze_ms >= 0.0) {
                return Err(err(
                    file,
                    f("freeze_ms"),
                    format!("{}; allowed: >= 0 ms", l.freeze_ms),
                ));
            }
        }
        Ok(())
    }

    /// The bounds in ticks and samples for scenario `s` (`file` names them in errors): a
    /// delay range must hold a whole tick.
    pub fn ticks(&self, s: &Scenario, file: &str) -> Result<[TickBound; 4], FalsifyError> {
        let dt_ms = s.run.dt_s * 1e3;
        let mut out = [TickBound {
            d_min: 0,
            d_max: 0,
            jitter: 0,
            losses: 0,
            freeze: 0,
            drops: 0,
        }; 4];
        for id in LinkId::ALL {
            let l = &self.links[id as usize];
            let d_min = (l.delay_ms[0] / dt_ms - 1e-9).ceil() as i64;
            let d_max = (l.delay_ms[1] / dt_ms + 1e-9).floor() as i64;
            if d_min > d_max {
                return Err(err(
                    file,
                    format!("[{}] delay_ms", id.name()),
                    format!(
                        "[{}, {}] holds no whole tick of run.dt_s = {} s",
                        l.delay_ms[0], l.delay_ms[1], s.run.dt_s
                    ),
                ));
            }
            let jitter = l
                .jitter_ms
                .map_or(d_max - d_min, |j| (j / dt_ms + 1e-9).floor() as i64);
            let link = super::timing::LinkShape::of(id, s);
            let n = link.samples as f64;
            let lost = (l.loss_pct / 100.0 * n + 1e-9).floor() as i64;
            let stall = (l.freeze_ms / dt_ms + 1e-9).floor() as i64;
            if stall > link.steps as i64 {
                return Err(err(
                    file,
                    format!("[{}] freeze_ms", id.name()),
                    format!(
                        "{} ms is longer than the run ({} s); allowed: 0 to {} ms",
                        l.freeze_ms,
                        s.duration(),
                        link.steps as f64 * dt_ms
                    ),
                ));
            }
            // Checked at the reading participant's period: whole periods of the consumer.
            let p = link.consumer_period as i64;
            if stall > 0 && stall < p {
                return Err(err(
                    file,
                    format!("[{}] freeze_ms", id.name()),
                    format!(
                        "{} ms is shorter than one period of the participant that reads the \
                         link ({} ms), so no stall would fit; allowed: 0, or {} ms and more",
                        l.freeze_ms,
                        p as f64 * dt_ms,
                        p as f64 * dt_ms
                    ),
                ));
            }
            let freeze = stall / p * p;
            let frozen = freeze / link.spacing as i64;
            out[id as usize] = TickBound {
                d_min,
                d_max,
                jitter: jitter.min(d_max - d_min),
                losses: lost.min(link.samples as i64),
                freeze,
                drops: (lost + frozen).min(link.samples as i64),
            };
        }
        for ring in LOOPS {
            let most: i64 = ring.iter().map(|id| out[*id as usize].d_max).sum();
            if most < 0 {
                let names: Vec<&str> = ring.iter().map(|id| id.name()).collect();
                return Err(err(
                    file,
                    format!("[{}] delay_ms", names.join("], [")),
                    format!(
                        "the largest delays add up to {most} ticks around the loop, so no \
                         timing they admit is causal; allowed: largest delays that add up to 0 \
                         or more"
                    ),
                ));
            }
        }
        Ok(out)
    }

    /// The envelope of recorded runs: per link, the smallest and largest delay, the largest
    /// delay change and the largest share of samples lost any of `observed` shows. The
    /// smallest delay is negative where a consumer lagged its producer; the largest is never
    /// below 0, so the envelope always admits causal timings (the lock-step one among them).
    pub fn envelope(observed: &[[super::timing::LinkObs; 4]], s: &Scenario) -> Bounds {
        let dt_ms = s.run.dt_s * 1e3;
        let mut b = Bounds::default();
        for id in LinkId::ALL {
            let i = id as usize;
            let n = super::timing::LinkShape::of(id, s).samples.max(1) as f64;
            let mut lo = i64::MAX;
            let mut hi = 0i64;
            let mut jit = 0i64;
            let mut lost = 0i64;
            for o in observed {
                let o = &o[i];
                lo = lo.min(o.d_min);
                hi = hi.max(o.d_max);
                jit = jit.max(o.jitter);
                lost = lost.max(o.dropped);
            }
            let lo = if lo == i64::MAX { 0 } else { lo.min(hi) };
            b.links[i] = LinkBound {
                delay_ms: [lo as f64 * dt_ms, hi as f64 * dt_ms],
                jitter_ms: Some(jit as f64 * dt_ms),
                // Rounded up to a whole sample: the share admits every loss seen.
                loss_pct: ((lost as f64 / n * 100.0) * 1e6).ceil() / 1e6,
                freeze_ms: 0.0,
            };
        }
        b
    }

    /// The bounds file's text (the envelope of recorded runs is written as one).
    pub fn to_toml(&self) -> String {
        let map: BTreeMap<&str, LinkBound> = LINK_NAMES
            .iter()
            .zip(self.links)
            .filter(|(_, l)| *l != LinkBound::LOCK_STEP)
            .map(|(n, l)| (*n, l))
            .collect();
        toml::to_string(&map).unwrap_or_default()
    }
}
