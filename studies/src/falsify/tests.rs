//! The mapping from points to traces: every point gives a causal trace within its bounds;
//! the lock-step bounds give the lock-step data flow; bad bounds and objectives are refused
//! with the field named.

use rand::{Rng as _, SeedableRng as _};
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::Scenario;

use super::bounds::{Bounds, LinkBound};
use super::history::{self, Fate, Layout};
use super::objective::Objective;
use super::timing;

/// A shipped scenario, cut to `duration_s`.
pub(super) fn shipped(name: &str, duration_s: f64) -> Scenario {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(name);
    Scenario::load(&path)
        .unwrap()
        .with_setting("run.duration_s", &duration_s.to_string())
        .unwrap()
}

fn bounds(text: &str) -> Bounds {
    Bounds::parse(text, "test.toml").unwrap()
}

/// 300 random points and the cube's corners and centre for each of several bounds, on a
/// controller of 1 tick and one of 50 ticks: every trace passes the replay's causality check
/// and the bounds check, whose delays, jitter and drops never exceed the bounds.
#[test]
fn every_candidate_is_causal_and_within_its_bounds() {
    let cases = [
        "[actuator_command]\ndelay_ms = [0, 60]\njitter_ms = 10\nloss_pct = 1\n",
        "[actuator_command]\ndelay_ms = [20, 80]\nfreeze_ms = 200\n[measurement]\ndelay_ms = [0, 15]\njitter_ms = 3\nloss_pct = 5\n",
        "[bar_angle]\ndelay_ms = [0, 5]\n[bar_twist]\ndelay_ms = [1, 4]\njitter_ms = 1\nloss_pct = 2\nfreeze_ms = 30\n",
        // Lagging consumers: negative delays the other links of their loops make up for.
        "[actuator_command]\ndelay_ms = [-3, 5]\njitter_ms = 2\n[bar_angle]\ndelay_ms = [2, 6]\n[bar_twist]\ndelay_ms = [-4, 3]\nloss_pct = 2\n[measurement]\ndelay_ms = [0, 4]\n",
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for scen in ["paper-lqg.toml", "paper-mpc.toml"] {
        let s = shipped(scen, 1.5);
        for text in cases {
            let b = bounds(text);
            let ticks = b.ticks(&s, "test.toml").unwrap();
            let layout = Layout::new(&s, &ticks);
            let mut points: Vec<Vec<f64>> = (0..300)
                .map(|_| (0..layout.dims).map(|_| rng.random::<f64>()).collect())
                .collect();
            points.push(vec![0.0; layout.dims]);
            points.push(vec![1.0; layout.dims]);
            points.push(vec![0.5; layout.dims]);
            for u in points {
                let t = layout.trace(&s, &layout.history(&u));
                let obs = timing::check(&s, &t, &ticks)
                    .unwrap_or_else(|e| panic!("{scen}, {text}: point {u:?}: {e}"));
                // Where the consumer reads every tick the delays are seen exactly.
                for ((o, b), id) in obs.iter().zip(&ticks).zip(LinkId::ALL) {
                    if timing::LinkShape::of(id, &s).consumer_period == 1 {
                        assert!(o.d_min >= b.d_min && o.d_max <= b.d_max, "{o:?} {b:?}");
                        assert!(o.dropped <= b.drops && o.jitter <= b.jitter, "{o:?} {b:?}");
                    }
                }
            }
        }
    }
}

/// A trace whose reads skip back, or are later than the bounds allow, is refused with the link
/// named.
#[test]
fn the_check_refuses_a_trace_out_of_bounds() {
    let s = shipped("paper-lqg.toml", 0.5);
    let wide = bounds("[actuator_command]\ndelay_ms = [0, 60]\n");
    let ticks = wide.ticks(&s, "t").unwrap();
    let layout = Layout::new(&s, &ticks);
    let t = layout.trace(&s, &layout.history(&vec![1.0; layout.dims]));
    // All knots at the top: every command 60 ticks late.
    let narrow = Bounds::default().ticks(&s, "t").unwrap();
    let e = timing::check(&s, &t, &narrow).unwrap_err();
    assert!(
        e.contains("link actuator_command") && e.contains("60"),
        "{e}"
    );
}

/// With the lock-step bounds (no delay, nothing lost), each consumer step reads what the
/// lock-step coupling gives it: the controller's and the actuator's outputs of its own tick
/// (the command held over the controller's period), the plant's of the tick before.
#[test]
fn lock_step_bounds_give_the_lock_step_reads() {
    let s = shipped("paper-mpc.toml", 0.3);
    let p = s.controller_period_ticks() as i64;
    let ticks = Bounds::default().ticks(&s, "t").unwrap();
    let layout = Layout::new(&s, &ticks);
    let t = layout.trace(&s, &layout.history(&[]));
    for st in &t.steps {
        let k = st.step as i64;
        let want = match st.role {
            cosim::Role::Plant => [None, Some(k), None],
            cosim::Role::Actuator => [Some(k - 1), None, Some(k / p * p)],
            cosim::Role::Controller => [Some(k - 1), None, None],
        };
        assert_eq!(st.from, want, "{st:?}");
    }
}

/// Bounds with min > max, a negative jitter, a loss above 100 %, an unknown link or field, or
/// a range holding no whole tick are refused, naming the file and field.
#[test]
fn bad_bounds_name_the_field() {
    let s = shipped("paper-lqg.toml", 0.5);
    for (text, field) in [
        (
            "[actuator_command]\ndelay_ms = [60, 0]\n",
            "[actuator_command] delay_ms",
        ),
        (
            "[measurement]\ndelay_ms = [0, 1]\njitter_ms = -1\n",
            "[measurement] jitter_ms",
        ),
        (
            "[bar_angle]\ndelay_ms = [0, 1]\nloss_pct = 101\n",
            "[bar_angle] loss_pct",
        ),
        (
            "[bar_angle]\ndelay_ms = [0, 1]\nfreeze_ms = -5\n",
            "[bar_angle] freeze_ms",
        ),
        ("[command]\ndelay_ms = [0, 1]\n", "[command]"),
        ("[bar_twist]\ndelay_ms = [0, 1]\nlatency = 3\n", "latency"),
    ] {
        let e = Bounds::parse(text, "b.toml").unwrap_err().to_string();
        assert!(
            e.starts_with("b.toml: ") && e.contains(field),
            "{text}: {e}"
        );
    }
    let e = bounds("[bar_twist]\ndelay_ms = [0.2, 0.8]\n")
        .ticks(&s, "b.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("[bar_twist] delay_ms") && e.contains("no whole tick"),
        "{e}"
    );
}

/// Objectives: aliases resolve to the metric keys (a requirement's margins:
/// `requirement::tests`); an unknown metric or a malformed requirement is refused naming the flag.
#[test]
fn objectives_and_requirements() {
    let o = Objective::maximise("p_ct").unwrap();
    assert_eq!(o.key(), "p_ct_en12299_standing_pct");
    let r = Objective::requirement("tilt_error >= 0.5").unwrap();
    assert_eq!(r.key(), "tilt_error_rms_deg");
    let e = Objective::maximise("comfort").unwrap_err().to_string();
    assert!(
        e.starts_with("--objective: `comfort` is not a metric; allowed: "),
        "{e}"
    );
    let e = Objective::requirement("p_ct = 3").unwrap_err().to_string();
    assert!(
        e.starts_with("--requirement `p_ct = 3`: no comparison"),
        "{e}"
    );
    let e = Objective::requirement("p_ct < x").unwrap_err().to_string();
    assert!(e.contains("not a finite number"), "{e}");
}

/// The envelope of a run whose commands were all 3 to 7 ticks late, with one sample lost,
/// admits that run and no more.
#[test]
fn the_envelope_of_a_trace_admits_it() {
    let s = shipped("paper-lqg.toml", 0.5);
    let b = bounds("[actuator_command]\ndelay_ms = [3, 7]\njitter_ms = 1\nloss_pct = 0.2\n");
    let ticks = b.ticks(&s, "t").unwrap();
    let layout = Layout::new(&s, &ticks);
    let t = layout.trace(&s, &layout.history(&vec![0.7; layout.dims]));
    let seen = timing::observe_all(&s, &t).unwrap();
    let env = Bounds::envelope(&[seen], &s);
    let l = env.links[0];
    assert!(l.delay_ms[0] >= 3.0 && l.delay_ms[1] <= 7.0, "{l:?}");
    let et = env.ticks(&s, "envelope").unwrap();
    timing::check(&s, &t, &et).unwrap();
    assert_eq!(env.links[1], LinkBound::LOCK_STEP);
}

/// A consumer that lags its producer: the actuator reading the plant's bar twist 4 ticks
/// before its value holds, made up for by a bar angle at least 4 ticks late. The search draws
/// it (the causal floors keep the bounds' own smallest delays, whose loop adds up to 0), its
/// made trace reads each lagging step just after the producer step it reads is published, is
/// causal and replays; the envelope of that trace keeps the negative delay and admits it.
#[test]
fn a_lagging_consumer_is_searched_replayed_and_enveloped() {
    use cosim::Role;
    use tiltsim_master::free::trace::col;
    let mut s = shipped("paper-lqg.toml", 0.5);
    super::prepare(&mut s, "paper-lqg.toml").unwrap();
    let b = bounds("[bar_angle]\ndelay_ms = [4, 8]\n[bar_twist]\ndelay_ms = [-4, 2]\n");
    let ticks = b.ticks(&s, "t").unwrap();
    assert_eq!(super::bounds::search_floors(&ticks), [0, 4, 0, -4]);
    let layout = Layout::new(&s, &ticks);
    let h = layout.earliest();
    let t = layout.trace(&s, &h);
    timing::check(&s, &t, &ticks).unwrap();
    let publish = |role: Role, step: i64| {
        let p = t
            .steps
            .iter()
            .find(|x| x.role == role && x.step as i64 == step);
        p.unwrap().publish_ns
    };
    for a in t
        .steps
        .iter()
        .filter(|x| x.role == Role::Actuator && x.step < 400)
    {
        let m = a.step as i64 + 3;
        assert_eq!(a.from[col(Role::Plant)], Some(m), "{a:?}");
        assert!(a.read_ns > publish(Role::Plant, m), "{a:?}");
    }
    let env = Bounds::envelope(&[timing::observe_all(&s, &t).unwrap()], &s);
    // Every bar twist read 4 ticks early; the envelope's largest delay is never below 0.
    assert_eq!(env.links[LinkId::BarTwist as usize].delay_ms, [-4.0, 0.0]);
    timing::check(&s, &t, &env.ticks(&s, "envelope").unwrap()).unwrap();
    let dir = std::env::temp_dir().join(format!("tiltsim-lag-{}", std::process::id()));
    let interrupt = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let o = Objective::maximise("p_ct").unwrap();
    let v = super::search::evaluate(&s, &layout, &ticks, &o, &h, dir.clone(), &interrupt);
    assert!(v.error.is_empty() && v.metric.is_finite(), "{}", v.error);
    assert!(!dir.exists());
}

/// The search's floors: the bounds' smallest delays where each loop's add up to 0 or more,
/// else raised, the most negative first and toward 0 first (an envelope of lagging runs gives
/// the lock-step floor); bounds whose largest delays add up to less than 0 around a loop admit
/// no causal timing and are refused, naming the links.
#[test]
fn causal_floors_and_loops_no_timing_can_close() {
    let s = shipped("paper-lqg.toml", 0.5);
    let floors = |text: &str| super::bounds::search_floors(&bounds(text).ticks(&s, "t").unwrap());
    let lagging = "[actuator_command]\ndelay_ms = [-7, 3]\n[bar_angle]\ndelay_ms = [-2, 9]\n\
                   [measurement]\ndelay_ms = [-1, 2]\n[bar_twist]\ndelay_ms = [-6, 1]\n";
    assert_eq!(floors(lagging), [0, 0, 0, 0]);
    let made_up = "[actuator_command]\ndelay_ms = [-7, 3]\n[bar_angle]\ndelay_ms = [3, 9]\n\
                   [measurement]\ndelay_ms = [-1, 2]\n[bar_twist]\ndelay_ms = [-6, 1]\n";
    assert_eq!(floors(made_up), [-2, 3, -1, -3]);
    let e = bounds("[bar_angle]\ndelay_ms = [-5, -2]\n[bar_twist]\ndelay_ms = [-3, 1]\n")
        .ticks(&s, "b.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("[bar_angle], [bar_twist] delay_ms") && e.contains("around the loop"),
        "{e}"
    );
}

/// Loss and freeze are budgets of their own: over 300 random points and the corners, on a
/// controller of 1 tick and one of 50 ticks, with the command and the measurement searched at
/// once, no link ever loses more samples than its loss budget or stalls longer than its
/// freeze budget (stalls rounded up to the reading participant's period); and the budgets
/// are used, each apart (some points lose samples, some stall).
#[test]
fn a_candidate_never_exceeds_either_budget() {
    let text = "[actuator_command]\ndelay_ms = [0, 60]\njitter_ms = 10\nloss_pct = 10\nfreeze_ms = 120\n[measurement]\ndelay_ms = [0, 20]\nloss_pct = 1\nfreeze_ms = 230\n";
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for scen in ["paper-lqg.toml", "paper-mpc.toml"] {
        let s = shipped(scen, 1.5);
        let ticks = bounds(text).ticks(&s, "t").unwrap();
        let layout = Layout::new(&s, &ticks);
        let mut points: Vec<Vec<f64>> = (0..300)
            .map(|_| (0..layout.dims).map(|_| rng.random::<f64>()).collect())
            .collect();
        points.push(vec![1.0; layout.dims]);
        points.push(vec![0.0; layout.dims]);
        let mut used = [[0i64; 2]; 4];
        for u in &points {
            let h = layout.history(u);
            layout.admissible(&h).unwrap();
            for (i, (l, b, _)) in layout.links.iter().enumerate() {
                let (lost, stalled) = history::budgets_used(l, &h[i]);
                assert!(lost <= b.losses, "{scen} {i}: {lost} > {}", b.losses);
                assert!(stalled <= b.freeze, "{scen} {i}: {stalled} > {}", b.freeze);
                assert_eq!(stalled % l.consumer_period as i64, 0);
                used[i][0] = used[i][0].max(lost);
                used[i][1] = used[i][1].max(stalled);
            }
            timing::check(&s, &layout.trace(&s, &h), &ticks).unwrap();
        }
        let p = s.controller_period_ticks() as i64;
        // The freeze budgets in ticks, at the reader's period: the actuator reads every tick,
        // the controller every p ticks.
        assert_eq!(ticks[0].freeze, 120);
        assert_eq!(ticks[2].freeze, 230 / p * p);
        for (i, link) in [(0, "actuator_command"), (2, "measurement")] {
            assert!(used[i][0] > 0, "{scen} {link}: no point loses a sample");
            assert!(used[i][1] > 0, "{scen} {link}: no point stalls");
        }
    }
}

/// A stall is counted at the reading participant's period: frozen samples of the measurement
/// read by a controller of 50 ticks are charged whole controller periods; a loss of one
/// sample is a loss, not a stall.
#[test]
fn stalls_are_counted_in_whole_periods_of_the_reader() {
    let s = shipped("paper-mpc.toml", 1.0);
    let l = timing::LinkShape::of(LinkId::Measurement, &s);
    assert_eq!(l.consumer_period, 50);
    let mut h = vec![Fate::Delivered(0); l.samples as usize];
    h[10] = Fate::Lost;
    for f in &mut h[100..151] {
        *f = Fate::Frozen;
    }
    // 51 plant samples of 1 tick: two controller periods.
    assert_eq!(history::budgets_used(&l, &h), (1, 100));
    let b = super::bounds::TickBound {
        d_min: 0,
        d_max: 0,
        jitter: 0,
        losses: 1,
        freeze: 50,
        drops: 0,
    };
    let e = history::admissible(&l, &b, &h).unwrap_err().to_string();
    assert!(
        e.contains("measurement") && e.contains("freeze budget allows 50"),
        "{e}"
    );
    let b = super::bounds::TickBound {
        losses: 0,
        freeze: 100,
        ..b
    };
    let e = history::admissible(&l, &b, &h).unwrap_err().to_string();
    assert!(
        e.contains("1 samples lost; the loss budget allows 0"),
        "{e}"
    );
}

/// A freeze budget below zero, or longer than the run, is refused naming the link and field.
#[test]
fn a_freeze_budget_out_of_range_names_the_field() {
    let s = shipped("paper-lqg.toml", 0.5);
    let e = Bounds::parse(
        "[measurement]\ndelay_ms = [0, 1]\nfreeze_ms = -1\n",
        "b.toml",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("b.toml: [measurement] freeze_ms: -1; allowed: >= 0 ms"),
        "{e}"
    );
    let e = bounds("[measurement]\ndelay_ms = [0, 1]\nfreeze_ms = 600\n")
        .ticks(&s, "b.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.toml: [measurement] freeze_ms: 600 ms is longer than the run")
            && e.contains("allowed: 0 to 500 ms"),
        "{e}"
    );
    // The MPC reads its measurement every 50 ms: a 30 ms budget holds no stall of it.
    let mpc = shipped("paper-mpc.toml", 0.5);
    let e = bounds("[measurement]\ndelay_ms = [0, 1]\nfreeze_ms = 30\n")
        .ticks(&mpc, "b.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("b.toml: [measurement] freeze_ms: 30 ms is shorter than one period")
            && e.contains("allowed: 0, or 50 ms and more"),
        "{e}"
    );
    assert!(bounds("[measurement]\ndelay_ms = [0, 1]\nfreeze_ms = 50\n")
        .ticks(&mpc, "b.toml")
        .is_ok());
}

/// Shards share the budget whole, shard 0's seed is the search's and the others differ.
#[test]
fn shards_share_the_budget_with_seeds_of_their_own() {
    use super::shards::{shard_seed, share};
    use crate::sweep::Shard;
    for (budget, count) in [(500, 4), (7, 3), (5, 5), (100, 1)] {
        let shares: Vec<usize> = (0..count)
            .map(|index| share(budget, Shard { index, count }))
            .collect();
        assert_eq!(shares.iter().sum::<usize>(), budget, "{shares:?}");
        assert!(shares.iter().max().unwrap() - shares.iter().min().unwrap() <= 1);
    }
    assert_eq!(shard_seed(7, 0), 7);
    let seeds: std::collections::BTreeSet<u64> = (0..64).map(|i| shard_seed(7, i)).collect();
    assert_eq!(seeds.len(), 64);
}

/// An evaluation writes nothing: its run directory is never made, and the metric of the
/// lock-step point (every delay the smallest, nothing lost) is the plain run's.
#[test]
fn an_evaluation_writes_nothing() {
    let mut s = shipped("paper-lqg.toml", 0.5);
    super::prepare(&mut s, "paper-lqg.toml").unwrap();
    let b = bounds("[actuator_command]\ndelay_ms = [0, 60]\nloss_pct = 1\nfreeze_ms = 20\n");
    let ticks = b.ticks(&s, "t").unwrap();
    let layout = Layout::new(&s, &ticks);
    let dir = std::env::temp_dir().join(format!("tiltsim-eval-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let o = Objective::maximise("p_ct").unwrap();
    let interrupt = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let v = super::search::evaluate(
        &s,
        &layout,
        &ticks,
        &o,
        &layout.earliest(),
        dir.clone(),
        &interrupt,
    );
    let m = v.metric;
    assert!(v.error.is_empty() && m.is_finite(), "{}", v.error);
    assert!(!dir.exists(), "{} was made", dir.display());
    let spec = super::Spec {
        bounds: b,
        bounds_from: "t".into(),
        objective: o,
        budget: 1,
        seed: 1,
        margin: None,
    };
    let (nominal, _) = super::outputs::nominal(&s, &spec, &dir, &interrupt);
    assert_eq!(m, nominal);
    let _ = std::fs::remove_dir_all(&dir);
}
