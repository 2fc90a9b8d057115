//! The whole admissible set is searched: histories drawn by a generator written here, apart
//! from the search's code (piecewise delays that rise and fall within the jitter bound on
//! periods of any length, bursts after a fall, losses and stalls as one outage spending the
//! whole budget or as many), are accepted by the trace check, and the projection the search
//! applies to every candidate leaves each of them as it is: the search's whole-run rewrite
//! (`mutation`) draws any of them with a probability above zero, so each is reachable.

use rand::{Rng as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;

use super::bounds::{Bounds, TickBound};
use super::history::{self, Fate, Layout};
use super::tests::shipped;
use super::timing::{self, LinkShape};

/// Marks `len` samples from `start` as `what` where nothing is marked yet; false when any is.
fn place(h: &mut [Fate], start: usize, len: usize, what: Fate) -> bool {
    if start + len > h.len()
        || h[start..start + len]
            .iter()
            .any(|f| *f != Fate::Delivered(0))
    {
        return false;
    }
    // A stall next to another would merge with it: keep a delivered sample between outages.
    let before = start.checked_sub(1).map(|i| h[i]);
    let after = h.get(start + len).copied();
    if [before, after]
        .iter()
        .any(|f| f.is_some_and(|f| f != Fate::Delivered(0)))
    {
        return false;
    }
    h[start..start + len].fill(what);
    true
}

/// The outages of one history: the loss budget as one outage (a third of the time) or as up
/// to five; the freeze budget likewise, each stall a whole number of consumer periods.
fn outages(rng: &mut ChaCha8Rng, l: &LinkShape, b: &TickBound, h: &mut [Fate]) {
    let n = h.len();
    let (s, p) = (l.spacing as i64, l.consumer_period as i64);
    let mut spend = |budget: i64, unit: i64, what: Fate, rng: &mut ChaCha8Rng| {
        if budget < unit {
            return;
        }
        let units = budget / unit;
        let parts: Vec<i64> = if rng.random_range(0..3) == 0 {
            vec![units]
        } else {
            let k = rng.random_range(1..=5i64.min(units));
            let mut left = rng.random_range(k..=units);
            let mut v = Vec::new();
            for j in (1..=k).rev() {
                let take = if j == 1 {
                    left
                } else {
                    rng.random_range(1..=left - (j - 1))
                };
                v.push(take);
                left -= take;
            }
            v
        };
        for units in parts {
            // A stall of `units` consumer periods holds as many samples as fit in them.
            let len = if what == Fate::Frozen {
                (units * unit / s).max(1) as usize
            } else {
                units as usize
            };
            let len = len.min(n);
            for _ in 0..50 {
                if place(h, rng.random_range(0..=n - len), len, what) {
                    break;
                }
            }
        }
    };
    spend(b.losses, 1, Fate::Lost, rng);
    spend(b.freeze, p.max((s + p - 1) / p * p), Fate::Frozen, rng);
}

/// One admissible history of link `l` under `b`: piecewise segments (1 to 400 samples), each
/// heading for a delay drawn from the range in steps drawn within the jitter bound, or a
/// square wave of the whole jitter bound; a fall of more than the sample spacing arrives as a
/// burst (the delay falls by the spacing per sample until it reaches the target).
pub(super) fn generate(rng: &mut ChaCha8Rng, l: &LinkShape, b: &TickBound) -> Vec<Fate> {
    let n = l.samples as usize;
    let mut h = vec![Fate::Delivered(0); n];
    outages(rng, l, b, &mut h);
    let mut prev: Option<(i64, i64)> = None;
    let mut i = 0;
    while i < n {
        let len = rng.random_range(1..=400usize).min(n - i);
        let target = rng.random_range(b.d_min..=b.d_max);
        let square = rng.random_bool(0.3);
        for (j, fate) in h.iter_mut().enumerate().skip(i).take(len) {
            if *fate != Fate::Delivered(0) {
                continue;
            }
            let v = l.valid_from(j as u64);
            let d = match prev {
                None => target,
                Some((pv, pd)) => {
                    let want = if square {
                        if (j - i) % 2 == 0 {
                            pd + b.jitter
                        } else {
                            pd - b.jitter
                        }
                    } else {
                        pd + (target - pd).clamp(-b.jitter, b.jitter) * rng.random_range(0..=1)
                    };
                    // In send order: the delay falls by at most the time since the last one.
                    want.max(pd - (v - pv))
                        .clamp(b.d_min.max(pd - b.jitter), b.d_max.min(pd + b.jitter))
                }
            };
            *fate = Fate::Delivered(d);
            prev = Some((v, d));
        }
        i += len;
    }
    h
}

/// The producer step each consumer step reads, computed here: the newest sample arrived.
fn newest(l: &LinkShape, h: &[Fate]) -> Vec<i64> {
    (0..l.steps.div_ceil(l.consumer_period))
        .map(|j| {
            let k = (j * l.consumer_period) as i64;
            h.iter()
                .enumerate()
                .filter_map(|(i, f)| match f {
                    Fate::Delivered(d) if l.valid_from(i as u64) + d <= k => {
                        Some(l.step_of(i as u64))
                    }
                    _ => None,
                })
                .max()
                .unwrap_or(-1)
        })
        .collect()
}

#[test]
fn every_admissible_history_drawn_apart_is_reachable() {
    let cases = [
        // The wide bounds: one outage may spend a tenth of the samples and 200 ms of stall.
        "[actuator_command]\ndelay_ms = [0, 200]\njitter_ms = 50\nloss_pct = 10\nfreeze_ms = 200\n\
         [measurement]\ndelay_ms = [0, 200]\njitter_ms = 50\nloss_pct = 10\nfreeze_ms = 200\n",
        "[actuator_command]\ndelay_ms = [0, 60]\njitter_ms = 10\nloss_pct = 1\n",
        "[bar_angle]\ndelay_ms = [1, 4]\njitter_ms = 1\nloss_pct = 2\nfreeze_ms = 30\n\
         [bar_twist]\ndelay_ms = [0, 5]\nloss_pct = 1\n",
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for scen in ["paper-lqg.toml", "paper-mpc.toml"] {
        let s = shipped(scen, 2.0);
        for text in cases {
            let ticks = Bounds::parse(text, "t.toml")
                .unwrap()
                .ticks(&s, "t")
                .unwrap();
            let layout = Layout::new(&s, &ticks);
            let (mut falls, mut rises, mut whole_outage) = (0, 0, 0);
            for draw in 0..25 {
                let h: history::History = std::array::from_fn(|i| {
                    let (l, b, _) = &layout.links[i];
                    generate(&mut rng, l, b)
                });
                let reads: [Vec<i64>; 4] =
                    std::array::from_fn(|i| newest(&layout.links[i].0, &h[i]));
                let t = timing::trace(&s, &reads);
                timing::check(&s, &t, &ticks)
                    .unwrap_or_else(|e| panic!("{scen} {text} draw {draw}: the check: {e}"));
                for (i, (l, b, _)) in layout.links.iter().enumerate() {
                    let p = history::project(l, b, &h[i]);
                    assert!(
                        p == h[i],
                        "{scen} {text} draw {draw}: link {}: the projection moved an admissible history",
                        l.id.name()
                    );
                    assert_eq!(history::reads(l, &p), reads[i], "{scen} {}", l.id.name());
                    let d: Vec<i64> = h[i]
                        .iter()
                        .filter_map(|f| match f {
                            Fate::Delivered(d) => Some(*d),
                            _ => None,
                        })
                        .collect();
                    falls += d.windows(2).filter(|w| w[1] < w[0]).count();
                    rises += d.windows(2).filter(|w| w[1] > w[0]).count();
                    let (lost, _) = history::budgets_used(l, &h[i]);
                    let runs = h[i]
                        .windows(2)
                        .filter(|w| w[1] == Fate::Lost && w[0] != Fate::Lost)
                        .count();
                    if b.losses > 1 && lost == b.losses && runs == 1 {
                        whole_outage += 1;
                    }
                }
            }
            // The generator draws what the search used to miss: falls as well as rises, and
            // a whole loss budget spent as one outage.
            assert!(
                falls > 0 && rises > 0,
                "{scen} {text}: {falls} falls, {rises} rises"
            );
            if text.contains("loss_pct = 10") {
                assert!(whole_outage > 0, "{scen}: no whole-budget outage drawn");
            }
        }
    }
}

/// The obvious adversary with an outage at the curve entry spends each link's whole loss and
/// freeze budgets as one outage there, at the largest delay; every adversary is admissible.
#[test]
fn an_adversary_spends_the_whole_budget_as_one_outage() {
    let s = shipped("paper-lqg.toml", 6.0);
    let text = "[actuator_command]\ndelay_ms = [0, 200]\njitter_ms = 50\nloss_pct = 10\nfreeze_ms = 200\n\
                [measurement]\ndelay_ms = [0, 200]\njitter_ms = 50\nloss_pct = 10\nfreeze_ms = 200\n";
    let ticks = Bounds::parse(text, "t.toml")
        .unwrap()
        .ticks(&s, "t")
        .unwrap();
    let layout = Layout::new(&s, &ticks);
    let adv = super::adversaries::adversaries(&s, &layout);
    // Largest delay on all links and on each alone, then per moment all links and each alone.
    let moments = super::adversaries::moments(&s);
    assert_eq!(adv.len(), 3 + 3 * moments.len());
    for a in &adv {
        let h = layout.history(&a.coords);
        layout.admissible(&h).unwrap();
        timing::check(&s, &layout.trace(&s, &h), &ticks).unwrap();
    }
    let t1 = moments[0].1;
    assert!(
        (t1 - 3.0).abs() < 1e-9,
        "the curve entry begins at 3 s: {t1}"
    );
    let h = layout.history(&adv[3].coords);
    for i in [0, 2] {
        let (l, b, _) = &layout.links[i];
        assert_eq!(history::budgets_used(l, &h[i]), (b.losses, b.freeze));
        let first = h[i].iter().position(|f| *f != Fate::Delivered(b.d_max));
        let out = h[i]
            .iter()
            .filter(|f| !matches!(f, Fate::Delivered(_)))
            .count();
        let start = first.unwrap();
        // One outage: its samples all together, from the first sample sent at 3 s.
        assert!(h[i][start..start + out]
            .iter()
            .all(|f| !matches!(f, Fate::Delivered(_))));
        assert_eq!(l.step_of(start as u64), (t1 / s.run.dt_s).round() as i64);
    }
    assert!(adv[0].coords.iter().all(|c| *c == 0.0 || *c == 1.0));
}
