//! What the worst timing owes to each bound, and how much timing the requirements tolerate.
//!
//! * [`sensitivity`]: for each link and each of its bounds (delay range, jitter, loss, freeze),
//!   the worst history found projected onto the bounds without that one (the range collapsed
//!   to its smallest delay, no change of delay, nothing lost, no stall) and evaluated again:
//!   the objective it loses says how much of the worst that bound carries.
//! * [`timing_margin`]: the bounds scaled by k (every delay, the jitter, the loss and freeze
//!   budgets; k = 0 is the lock-step timing, k = 1 the bounds given), a search at each scale,
//!   and bisection between the largest scale not falsified and the smallest falsified. The
//!   result is evidence at both ends: the requirements not falsified within the budget at the
//!   one, and at the other a timing that breaks them (`margin/worst/timing.csv`).

use std::path::Path;

use serde::Serialize;
use tiltsim_scenario::links::LinkId;
use tiltsim_scenario::scenario::Scenario;

use super::bounds::{Bounds, LinkBound};
use super::history::Layout;
use super::search::{evaluate, Exec, Falsified, Spec};
use super::timing::LinkShape;
use super::FalsifyError;

/// The bounds of a link one may take away.
pub const PARAMETERS: [&str; 4] = ["delay_ms", "jitter_ms", "loss_pct", "freeze_ms"];

/// What the worst timing owes to one bound.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Share {
    /// The link.
    pub link: &'static str,
    /// The bound taken away (a field of the bounds file).
    pub parameter: &'static str,
    /// The objective of the worst history without it (NaN: the replay failed).
    pub objective_without: f64,
    /// How much the objective falls without it (the worst's objective minus that).
    pub drop: f64,
}

/// `b` without `parameter` on its link (the lock-step value of that bound); `None` when the
/// bound does not let the link do anything already.
fn without(b: &LinkBound, parameter: &str) -> Option<LinkBound> {
    let mut o = *b;
    match parameter {
        "delay_ms" if b.delay_ms[1] > b.delay_ms[0] => o.delay_ms[1] = b.delay_ms[0],
        "jitter_ms" if b.delay_ms[1] > b.delay_ms[0] && b.jitter_ms != Some(0.0) => {
            o.jitter_ms = Some(0.0)
        }
        "loss_pct" if b.loss_pct > 0.0 => o.loss_pct = 0.0,
        "freeze_ms" if b.freeze_ms > 0.0 => o.freeze_ms = 0.0,
        _ => return None,
    }
    Some(o)
}

/// Each bound's share of the worst timing `f` found within `spec`, largest drop first
/// (evaluated on `jobs` threads; the order does not depend on them). A bound without which
/// the bounds admit no causal timing is left out.
pub fn sensitivity(
    s: &Scenario,
    spec: &Spec,
    f: &Falsified,
    ex: &Exec,
) -> Result<Vec<Share>, FalsifyError> {
    let mut cases = Vec::new();
    for id in LinkId::ALL {
        for p in PARAMETERS {
            if let Some(l) = without(&spec.bounds.links[id as usize], p) {
                let mut b = spec.bounds;
                b.links[id as usize] = l;
                // Without it no timing may be causal (an envelope whose smallest delays are
                // negative, its range collapsed there): nothing to compare with.
                if let Ok(ticks) = b.ticks(s, &spec.bounds_from) {
                    cases.push((id.name(), p, ticks));
                }
            }
        }
    }
    let worst = &f.worst;
    let values = crate::parallel::map(cases.len(), ex.jobs, &ex.interrupt, |i| {
        let ticks = &cases[i].2;
        let layout = Layout::new(s, ticks);
        let h = layout.project(&worst.0);
        let dir = ex.out.join("sensitivity");
        let v = evaluate(s, &layout, ticks, &spec.objective, &h, dir, &ex.interrupt);
        Some(v.objective)
    });
    let mut shares: Vec<Share> = cases
        .iter()
        .zip(values)
        .map(|((link, parameter, _), v)| {
            let without = v.unwrap_or(f64::NAN);
            Share {
                link,
                parameter,
                objective_without: without,
                drop: worst.1.objective - without,
            }
        })
        .collect();
    shares.sort_by(|a, b| b.drop.total_cmp(&a.drop));
    Ok(shares)
}

/// The bounds `b` scaled by `k`, on whole ticks: every delay and the jitter rounded down to
/// a tick, the freeze budget down to whole periods of the reading participant (and to the
/// run), the loss budget to whole samples (by [`Bounds::ticks`]).
pub fn scaled(b: &Bounds, k: f64, s: &Scenario) -> Bounds {
    let dt_ms = s.run.dt_s * 1e3;
    let tick = |ms: f64| (ms / dt_ms + 1e-9).floor() * dt_ms;
    let mut o = *b;
    for id in LinkId::ALL {
        let l = &mut o.links[id as usize];
        let shape = LinkShape::of(id, s);
        let period_ms = shape.consumer_period as f64 * dt_ms;
        let periods = ((k * l.freeze_ms) / period_ms + 1e-9).floor();
        let most = (shape.steps / shape.consumer_period) as f64;
        l.delay_ms = [tick(k * l.delay_ms[0]), tick(k * l.delay_ms[1])];
        l.jitter_ms = l.jitter_ms.map(|j| tick(k * j));
        l.loss_pct = (k * l.loss_pct).min(100.0);
        l.freeze_ms = periods.min(most) * period_ms;
    }
    o
}

/// How the timing margin is searched.
#[derive(Debug, Clone, Copy)]
pub struct MarginPlan {
    /// The largest scale tried.
    pub max_scale: f64,
    /// Bisection steps between the scales that hold and break.
    pub steps: usize,
}

/// One scale tried.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Step {
    /// The scale of the bounds.
    pub scale: f64,
    /// Whether the search at that scale broke the requirements.
    pub violated: bool,
    /// Their margin at the worst timing found there.
    pub margin: f64,
    /// The metric there.
    pub worst_metric: f64,
}

/// The timing margin, in `result.json` → `timing_margin`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TimingMargin {
    /// The largest scale at which the search did not break the requirements (`null`: even
    /// the lock-step timing breaks them).
    pub holds_up_to_scale: Option<f64>,
    /// The smallest scale at which it did (`null`: none up to the largest tried).
    pub broken_at_scale: Option<f64>,
    /// The timing that breaks them there (`margin/worst/timing.csv`), when one does.
    pub counterexample: Option<String>,
    /// Every scale tried, in the order tried.
    pub steps: Vec<Step>,
}

/// The timing margin of `spec`'s requirements, starting from the search at scale 1 already
/// made (`at_one`); the searches of the other scales go to `ex.out/margin/<scale>`, the
/// counterexample of the smallest broken scale to `ex.out/margin/worst`.
pub fn timing_margin(
    s: &Scenario,
    spec: &Spec,
    at_one: &Falsified,
    ex: &Exec,
    plan: MarginPlan,
) -> Result<TimingMargin, FalsifyError> {
    let dir = ex.out.join("margin");
    let search = |k: f64| -> Result<Falsified, FalsifyError> {
        let mut sk = spec.clone();
        sk.bounds = scaled(&spec.bounds, k, s);
        sk.bounds_from = format!("{} scaled by {k}", spec.bounds_from);
        let sub = Exec {
            out: dir.join(format!("{k}")),
            jobs: ex.jobs,
            exe: ex.exe.clone(),
            interrupt: ex.interrupt.clone(),
            done: None,
        };
        super::run(s, &sk, &sub)
    };
    let step = |k: f64, f: &Falsified| Step {
        scale: k,
        violated: f.worst.1.violated,
        margin: f.worst.1.margin,
        worst_metric: f.worst.1.metric,
    };
    let mut steps = vec![step(1.0, at_one)];
    // (scale, search) of the largest held and the smallest broken.
    let mut held: Option<f64> = None;
    let mut broken: Option<(f64, Falsified)> = None;
    if at_one.worst.1.violated {
        broken = Some((1.0, at_one.clone()));
        let f = search(0.0)?;
        steps.push(step(0.0, &f));
        if f.worst.1.violated {
            broken = Some((0.0, f));
        } else {
            held = Some(0.0);
        }
    } else {
        held = Some(1.0);
        let mut k = 1.0;
        while k < plan.max_scale {
            k = (2.0 * k).min(plan.max_scale);
            let f = search(k)?;
            steps.push(step(k, &f));
            if f.worst.1.violated {
                broken = Some((k, f));
                break;
            }
            held = Some(k);
        }
    }
    for _ in 0..plan.steps {
        let (Some(lo), Some((hi, _))) = (held, broken.as_ref()) else {
            break;
        };
        let mid = 0.5 * (lo + *hi);
        let f = search(mid)?;
        steps.push(step(mid, &f));
        if f.worst.1.violated {
            broken = Some((mid, f));
        } else {
            held = Some(mid);
        }
    }
    let counterexample = match &broken {
        Some((k, f)) => {
            let mut sk = spec.clone();
            sk.bounds = scaled(&spec.bounds, *k, s);
            super::outputs::write_worst(s, &sk, f, &dir, &ex.interrupt)?;
            write_bounds(&dir, &sk.bounds)?;
            Some("margin/worst/timing.csv".to_string())
        }
        None => None,
    };
    Ok(TimingMargin {
        holds_up_to_scale: held,
        broken_at_scale: broken.map(|(k, _)| k),
        counterexample,
        steps,
    })
}

fn write_bounds(dir: &Path, b: &Bounds) -> Result<(), FalsifyError> {
    let path = dir.join("worst").join("bounds.toml");
    std::fs::write(&path, b.to_toml())
        .map_err(|e| FalsifyError::Files(format!("{}: {e}", path.display())))
}
