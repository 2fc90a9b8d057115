//! Link effects at run time: what the transport between two processes does to the samples it
//! carries, applied to the values in flight. The settings (section `[links.<name>]`) are
//! [`tiltsim_scenario::links`].
//!
//! Every sample between participants passes through the orchestrator (a star), so the
//! effects are applied there, on the value in flight, and the models never know. Links are
//! evaluated every base tick, in simulated time, with their own seeded random stream, so a
//! scenario and seed give the same rows and the same `events.csv` on both transports.
//!
//! Order of effects on a link at tick k: the sender's value v_k is dropped (probability or
//! window) or queued with delay d_k = `delay_ticks` + jitter; the receiver holds the newest
//! (by send tick) value that has arrived, i.e. the value sent at j = max{j : j + d_j ≤ k};
//! then a freeze window holds what was delivered when it began; then bias and Gaussian noise
//! are added; then a NaN or a fixed (out-of-range) value overrides it inside its window.

use std::collections::VecDeque;

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Exp, Normal};

use tiltsim_scenario::links::{Jitter, LinkEffects, LinkId, Links, LINK_NAMES};

use tiltsim_formats::events::{EventKind, EventLog};

/// The state of one link over a run.
pub struct Link {
    name: &'static str,
    fx: LinkEffects,
    rng: rand_chacha::ChaCha8Rng,
    /// (arrival tick, send tick, value).
    queue: VecDeque<(u64, u64, f64)>,
    delivered: Option<(u64, f64)>,
    frozen: Option<f64>,
    first: Option<f64>,
    in_window: [bool; 4],
}

impl Link {
    /// Link `index` of [`LINK_NAMES`] with its effects and a stream of the run's seed.
    pub fn new(index: usize, fx: &LinkEffects, seed: u64) -> Self {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(1000 + index as u64);
        Link {
            name: LINK_NAMES[index],
            fx: fx.clone(),
            rng,
            queue: VecDeque::new(),
            delivered: None,
            frozen: None,
            first: None,
            in_window: [false; 4],
        }
    }

    fn window_edge(&mut self, i: usize, now: bool, k: u64, what: EventKind, ev: &mut EventLog) {
        if now != self.in_window[i] {
            self.in_window[i] = now;
            ev.push(
                k,
                self.name,
                what,
                f64::NAN,
                if now { "begins" } else { "ends" },
            );
        }
    }

    /// This tick's random draws: the drop variate, the jitter (ticks) and the noise. They
    /// happen every tick whatever the windows say, so a window does not shift the random
    /// stream of what follows it.
    fn draws(&mut self, fx: &LinkEffects) -> (f64, u64, f64) {
        let u_drop: f64 = self.rng.random();
        let extra = match fx.jitter {
            Jitter::None => 0,
            Jitter::Uniform => self.rng.random_range(0..=fx.jitter_ticks.floor() as u64),
            Jitter::Exponential => Exp::new(1.0 / fx.jitter_ticks)
                .map(|d| d.sample(&mut self.rng).floor() as u64)
                .unwrap_or(0),
            Jitter::HalfNormal => Normal::new(0.0, fx.jitter_ticks)
                .map(|d| d.sample(&mut self.rng).abs().round() as u64)
                .unwrap_or(0),
        };
        let noise = if fx.noise_std > 0.0 {
            Normal::new(0.0, fx.noise_std)
                .map(|d| d.sample(&mut self.rng))
                .unwrap_or(0.0)
        } else {
            0.0
        };
        (u_drop, extra, noise)
    }

    /// What the receiver holds at tick `k`: the newest sample (by send tick) among those that
    /// have arrived; until the first arrives, the sender's first value `v`.
    fn deliver(&mut self, k: u64, v: f64) -> f64 {
        let mut newest = self.delivered;
        self.queue.retain(|&(arrive, sent, val)| {
            if arrive <= k {
                if newest.is_none_or(|(s, _)| sent > s) {
                    newest = Some((sent, val));
                }
                false
            } else {
                true
            }
        });
        self.delivered = newest;
        let first = *self.first.get_or_insert(v);
        self.delivered.map_or(first, |(_, val)| val)
    }

    /// What the effects do to the value `v` sent at tick `k` (time `t`): this tick's random
    /// draws, the window edges logged, whether the sample is lost (and the delay it travels
    /// with when it is not), and the value as the receiver will see it once delivered.
    fn effects(&mut self, k: u64, t: f64, v: f64, ev: &mut EventLog) -> Effects {
        let fx = self.fx.clone();
        let in_drop_window = fx.drop_window.is_some_and(|w| w.contains(t));
        let freeze = fx.freeze_window.is_some_and(|w| w.contains(t));
        let nan = fx.nan_window.is_some_and(|w| w.contains(t));
        let over = fx
            .value_window
            .filter(|o| t >= o.start_s && t < o.end_s)
            .map(|o| o.value);
        let (u_drop, extra, noise) = self.draws(&fx);
        let dropped = in_drop_window || u_drop < fx.drop_probability;
        let name = self.name;
        self.window_edge(0, in_drop_window, k, EventKind::DropWindow, ev);
        self.window_edge(1, freeze, k, EventKind::FreezeWindow, ev);
        self.window_edge(2, nan, k, EventKind::NanWindow, ev);
        self.window_edge(3, over.is_some(), k, EventKind::ValueWindow, ev);
        let delay = if dropped {
            if !in_drop_window {
                ev.push(k, name, EventKind::Drop, v, "sample lost");
            }
            None
        } else {
            let d = fx.delay_ticks + extra;
            if extra > 0 {
                ev.push(
                    k,
                    name,
                    EventKind::Jitter,
                    d as f64,
                    format!("delay {d} ticks"),
                );
            }
            Some(d)
        };
        Effects {
            delay,
            freeze,
            offset: fx.bias + noise,
            over: if nan { Some(f64::NAN) } else { over },
        }
    }

    /// Carries value `v` sent at tick `k` (simulated time `t`); returns what the receiver
    /// gets, and logs what the link did.
    pub fn carry(&mut self, k: u64, t: f64, v: f64, ev: &mut EventLog) -> f64 {
        if self.fx.is_identity() {
            return v;
        }
        let e = self.effects(k, t, v, ev);
        if let Some(d) = e.delay {
            self.queue.push_back((k + d, k, v));
        }
        let mut out = self.deliver(k, v);
        if e.freeze {
            out = *self.frozen.get_or_insert(out);
        } else {
            self.frozen = None;
        }
        e.over.unwrap_or(out + e.offset)
    }

    /// One sample of a free run, sent at tick `k` (time `t`) with value `v`, as it travels:
    /// `None` when it is lost (dropped, or sent inside a freeze window, so the receiver keeps
    /// the value it holds), else its delay in ticks and the value it arrives with. The same
    /// random draws as [`Link::carry`] per sample, so a free run and its replay, which pass
    /// every sample of a link in the order it was sent, agree on every one.
    pub fn pass(&mut self, k: u64, t: f64, v: f64, ev: &mut EventLog) -> Option<(u64, f64)> {
        if self.fx.is_identity() {
            return Some((0, v));
        }
        let e = self.effects(k, t, v, ev);
        let d = e.delay.filter(|_| !e.freeze)?;
        Some((d, e.over.unwrap_or(v + e.offset)))
    }
}

/// What a link's effects do to one sample (see [`Link::effects`]).
struct Effects {
    /// Lost (`None`) or delayed by this many ticks.
    delay: Option<u64>,
    /// Sent inside a freeze window.
    freeze: bool,
    /// Bias and this sample's noise.
    offset: f64,
    /// A value that replaces the sample (NaN inside a NaN window).
    over: Option<f64>,
}

/// The four links of a run: the manipulator of the values in flight.
pub struct LinkSet {
    /// In [`LinkId`] order.
    links: Vec<Link>,
    /// Whether any link does something (a run without effects skips the bookkeeping).
    pub active: bool,
}

impl LinkSet {
    /// Builds the links of a scenario.
    pub fn new(l: &Links, seed: u64) -> Self {
        LinkSet {
            links: l
                .all()
                .iter()
                .enumerate()
                .map(|(i, fx)| Link::new(i, fx, seed))
                .collect(),
            active: l.all().iter().any(|fx| !fx.is_identity()),
        }
    }
    /// Carries `v`, sent at tick `k` (time `t`), over link `id`; returns what the receiver
    /// gets.
    pub fn carry(&mut self, id: LinkId, k: u64, t: f64, v: f64, ev: &mut EventLog) -> f64 {
        self.links[id as usize].carry(k, t, v, ev)
    }

    /// Passes one sample of a free run over link `id` (see [`Link::pass`]).
    pub fn pass(
        &mut self,
        id: LinkId,
        k: u64,
        t: f64,
        v: f64,
        ev: &mut EventLog,
    ) -> Option<(u64, f64)> {
        self.links[id as usize].pass(k, t, v, ev)
    }

    /// Start-of-run events describing the static effects.
    pub fn describe(l: &Links, ev: &mut EventLog) {
        for (name, fx) in LINK_NAMES.iter().zip(l.all()) {
            let mut add = |kind, value, detail: String| ev.push(0, name, kind, value, detail);
            if fx.delay_ticks > 0 {
                add(
                    EventKind::Delay,
                    fx.delay_ticks as f64,
                    format!("fixed delay {} ticks", fx.delay_ticks),
                );
            }
            if fx.jitter != Jitter::None {
                add(
                    EventKind::JitterOn,
                    fx.jitter_ticks,
                    format!("{:?} jitter, scale {} ticks", fx.jitter, fx.jitter_ticks),
                );
            }
            if fx.drop_probability > 0.0 {
                add(
                    EventKind::DropOn,
                    fx.drop_probability,
                    "random sample loss".into(),
                );
            }
            if fx.bias != 0.0 {
                add(EventKind::Bias, fx.bias, "offset added".into());
            }
            if fx.noise_std > 0.0 {
                add(
                    EventKind::Noise,
                    fx.noise_std,
                    "Gaussian noise added (std)".into(),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tiltsim_scenario::links::{Override, Window};

    fn run(fx: LinkEffects, n: u64) -> (Vec<f64>, Vec<tiltsim_formats::events::Event>) {
        let mut l = Link::new(0, &fx, 1);
        let mut ev = EventLog::new(1e-3);
        let out = (0..n)
            .map(|k| l.carry(k, k as f64 * 1e-3, k as f64, &mut ev))
            .collect();
        (out, ev.events)
    }

    #[test]
    fn a_fixed_delay_shifts_by_whole_ticks_and_holds_the_first_value_before() {
        let (out, _) = run(
            LinkEffects {
                delay_ticks: 3,
                ..Default::default()
            },
            10,
        );
        assert_eq!(out, [0., 0., 0., 0., 1., 2., 3., 4., 5., 6.]);
    }

    #[test]
    fn jitter_never_delivers_older_data_and_stays_within_its_bound() {
        let (out, ev) = run(
            LinkEffects {
                delay_ticks: 2,
                jitter: Jitter::Uniform,
                jitter_ticks: 4.0,
                ..Default::default()
            },
            2000,
        );
        for (k, w) in out.windows(2).enumerate() {
            assert!(w[1] >= w[0], "monotone at {k}");
        }
        for (k, v) in out.iter().enumerate().skip(10) {
            let age = k as f64 - v;
            assert!((2.0..=6.0).contains(&age), "age {age} at {k}");
        }
        assert!(ev.iter().any(|e| e.kind == EventKind::Jitter));
    }

    #[test]
    fn drops_freeze_bias_nan_and_override_act_as_declared() {
        let (out, ev) = run(
            LinkEffects {
                drop_window: Some(Window {
                    start_s: 0.005,
                    end_s: 0.008,
                }),
                bias: 0.5,
                ..Default::default()
            },
            10,
        );
        assert_eq!(out, [0.5, 1.5, 2.5, 3.5, 4.5, 4.5, 4.5, 4.5, 8.5, 9.5]);
        assert_eq!(
            ev.iter()
                .filter(|e| e.kind == EventKind::DropWindow)
                .count(),
            2
        );
        let (out, _) = run(
            LinkEffects {
                freeze_window: Some(Window {
                    start_s: 0.002,
                    end_s: 0.004,
                }),
                nan_window: Some(Window {
                    start_s: 0.006,
                    end_s: 0.007,
                }),
                value_window: Some(Override {
                    start_s: 0.008,
                    end_s: 0.009,
                    value: 99.0,
                }),
                ..Default::default()
            },
            10,
        );
        assert_eq!(&out[..6], &[0., 1., 2., 2., 4., 5.]);
        assert!(out[6].is_nan());
        assert_eq!(&out[7..], &[7., 99., 9.]);
        // Random loss at p = 0.3 over 20 000 samples: 0.3 ± 4.5σ (σ = 0.0032).
        let (_, ev) = run(
            LinkEffects {
                drop_probability: 0.3,
                ..Default::default()
            },
            20_000,
        );
        let p = ev.iter().filter(|e| e.kind == EventKind::Drop).count() as f64 / 20_000.0;
        assert!((p - 0.3).abs() < 0.015, "{p}");
    }

    #[test]
    fn a_free_runs_sample_gets_the_values_and_draws_of_the_lock_step_link() {
        // Without delay the two agree sample for sample: the same draws per tick.
        let fx = LinkEffects {
            bias: 0.25,
            noise_std: 0.1,
            jitter: Jitter::Uniform,
            jitter_ticks: 3.0,
            ..Default::default()
        };
        let (carried, _) = run(
            LinkEffects {
                jitter: Jitter::None,
                ..fx.clone()
            },
            50,
        );
        let mut l = Link::new(
            0,
            &LinkEffects {
                jitter: Jitter::None,
                ..fx.clone()
            },
            1,
        );
        let mut ev = EventLog::new(1e-3);
        for (k, c) in carried.iter().enumerate() {
            let (d, v) = l
                .pass(k as u64, k as f64 * 1e-3, k as f64, &mut ev)
                .unwrap();
            assert_eq!((d, v), (0, *c));
        }
        // A delay is the fixed part plus the jitter drawn for the sample, within its bound.
        let mut l = Link::new(
            0,
            &LinkEffects {
                delay_ticks: 5,
                ..fx
            },
            1,
        );
        let delays: Vec<u64> = (0..500)
            .map(|k| l.pass(k, k as f64 * 1e-3, 0.0, &mut ev).unwrap().0)
            .collect();
        assert!(delays.iter().all(|d| (5..=8).contains(d)));
        assert!(
            (5..=8).all(|d| delays.contains(&d)),
            "every delay in the range drawn"
        );
        // Samples sent inside a drop or a freeze window are lost; a NaN window gives NaN.
        let mut l = Link::new(
            0,
            &LinkEffects {
                drop_window: Some(Window {
                    start_s: 0.002,
                    end_s: 0.004,
                }),
                freeze_window: Some(Window {
                    start_s: 0.005,
                    end_s: 0.006,
                }),
                nan_window: Some(Window {
                    start_s: 0.007,
                    end_s: 0.008,
                }),
                ..Default::default()
            },
            1,
        );
        let got: Vec<Option<(u64, f64)>> = (0..9)
            .map(|k| l.pass(k, k as f64 * 1e-3, k as f64, &mut ev))
            .collect();
        assert_eq!(
            &got[..5],
            &[Some((0, 0.)), Some((0, 1.)), None, None, Some((0, 4.))]
        );
        assert_eq!(got[5], None);
        assert_eq!(got[6], Some((0, 6.)));
        assert!(got[7].is_some_and(|(_, v)| v.is_nan()));
        assert_eq!(got[8], Some((0, 8.)));
    }
}
