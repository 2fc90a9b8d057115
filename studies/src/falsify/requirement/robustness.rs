//! A formula's truth and robustness at every row of a run: Donzé and Maler's space
//! robustness ("Robust satisfaction of temporal logic over real-valued signals", FORMATS
//! 2010), on the run's finite, sampled trace. `x < c` has robustness c − x (`>`: x − c);
//! `not` negates it; `and`/`or` take the least/greatest; `always[a,b]` the least over the rows
//! from a to b seconds later and `eventually[a,b]` the greatest, the window cut at the run's
//! end (an empty window: `always` holds with +∞, `eventually` fails with −∞). An event has
//! robustness +∞ where it holds and −∞ where it does not, so `event -> f` is f's robustness
//! at the event's rows and +∞ elsewhere. The robustness is positive where the formula holds
//! and negative where it fails; the truth is computed beside it, so a bound met exactly by a
//! `<=` holds and by a `<` does not.
//!
//! The windows are sliding extremes kept in a monotone queue (each row enters and leaves once),
//! so a formula costs O(rows) per operator whatever its windows.

use std::collections::VecDeque;

use super::signals::Trace;
use super::stl::{Expr, Formula, Window};
use crate::falsify::objective::Cmp;

/// A formula's robustness and truth at each row.
pub struct Satisfaction {
    /// Robustness (positive: holds with that margin).
    pub margin: Vec<f64>,
    /// Truth.
    pub holds: Vec<bool>,
}

fn expr_values(e: &Expr, t: &Trace) -> Vec<f64> {
    match e {
        Expr::Signal(s) => t.values(*s),
        Expr::Abs(a) => expr_values(a, t).into_iter().map(f64::abs).collect(),
        Expr::Sum(terms) => {
            let mut out = vec![0.0; t.len()];
            for (sign, term) in terms {
                for (o, v) in out.iter_mut().zip(expr_values(term, t)) {
                    *o += sign * v;
                }
            }
            out
        }
    }
}

/// The rows of a window: from `k + lo` to `k + hi` (`hi` `None`: to the end).
fn steps(w: &Window, dt: f64) -> (usize, Option<usize>) {
    // A time within a millionth of a step of a row counts as that row.
    let lo = (w.from_s / dt - 1e-6).ceil().max(0.0) as usize;
    let hi = w.to_s.map(|t| (t / dt + 1e-6).floor().max(0.0) as usize);
    (lo, hi)
}

/// The least (`least`) or greatest of `v` over each row's window; `empty` where the window
/// holds no row.
fn sliding(v: &[f64], lo: usize, hi: Option<usize>, least: bool, empty: f64) -> Vec<f64> {
    let n = v.len();
    let better = |a: f64, b: f64| if least { a <= b } else { a >= b };
    let mut out = vec![empty; n];
    let Some(hi) = hi else {
        // To the end: the extreme of each suffix.
        let mut suffix = vec![empty; n + 1];
        for i in (0..n).rev() {
            suffix[i] = if better(v[i], suffix[i + 1]) {
                v[i]
            } else {
                suffix[i + 1]
            };
        }
        for (k, o) in out.iter_mut().enumerate() {
            if k + lo < n {
                *o = suffix[k + lo];
            }
        }
        return out;
    };
    let mut queue: VecDeque<usize> = VecDeque::new();
    let mut next = 0;
    for (k, o) in out.iter_mut().enumerate() {
        let (a, b) = (k + lo, (k + hi).min(n.saturating_sub(1)));
        if a >= n {
            break;
        }
        while next <= b {
            while queue.back().is_some_and(|&j| better(v[next], v[j])) {
                queue.pop_back();
            }
            queue.push_back(next);
            next += 1;
        }
        while queue.front().is_some_and(|&j| j < a) {
            queue.pop_front();
        }
        if let Some(&j) = queue.front() {
            *o = v[j];
        }
    }
    out
}

/// Whether every (`all`) or some row of each row's window holds (an empty window: `all`).
fn sliding_truth(h: &[bool], lo: usize, hi: Option<usize>, all: bool) -> Vec<bool> {
    let n = h.len();
    // count[i]: rows before i whose truth is the one that decides (false for all, true for any).
    let mut count = vec![0usize; n + 1];
    for i in 0..n {
        count[i + 1] = count[i] + usize::from(h[i] != all);
    }
    (0..n)
        .map(|k| {
            let a = k + lo;
            if a >= n {
                return all;
            }
            let b = hi.map_or(n - 1, |hi| (k + hi).min(n - 1));
            let deciding = count[b + 1] - count[a];
            if all {
                deciding == 0
            } else {
                deciding > 0
            }
        })
        .collect()
}

/// The formula's robustness and truth at every row of `t`.
pub fn satisfaction(f: &Formula, t: &Trace) -> Satisfaction {
    match f {
        Formula::Pred { expr, cmp, bound } => {
            let v = expr_values(expr, t);
            let margin = v
                .iter()
                .map(|x| match cmp {
                    Cmp::Less | Cmp::LessEq => bound - x,
                    Cmp::Greater | Cmp::GreaterEq => x - bound,
                })
                .collect();
            let holds = v
                .iter()
                .map(|x| match cmp {
                    Cmp::Less => x < bound,
                    Cmp::LessEq => x <= bound,
                    Cmp::Greater => x > bound,
                    Cmp::GreaterEq => x >= bound,
                })
                .collect();
            Satisfaction { margin, holds }
        }
        Formula::Event(e) => {
            let holds = t.truth(*e);
            let margin = holds
                .iter()
                .map(|h| if *h { f64::INFINITY } else { f64::NEG_INFINITY })
                .collect();
            Satisfaction { margin, holds }
        }
        Formula::Not(a) => {
            let s = satisfaction(a, t);
            Satisfaction {
                margin: s.margin.into_iter().map(|m| -m).collect(),
                holds: s.holds.into_iter().map(|h| !h).collect(),
            }
        }
        Formula::And(a, b) | Formula::Or(a, b) => {
            let and = matches!(f, Formula::And(..));
            let (x, y) = (satisfaction(a, t), satisfaction(b, t));
            let pick = |p: f64, q: f64| if and { p.min(q) } else { p.max(q) };
            Satisfaction {
                margin: x
                    .margin
                    .iter()
                    .zip(&y.margin)
                    .map(|(p, q)| pick(*p, *q))
                    .collect(),
                holds: x
                    .holds
                    .iter()
                    .zip(&y.holds)
                    .map(|(p, q)| if and { *p && *q } else { *p || *q })
                    .collect(),
            }
        }
        Formula::Always(w, a) | Formula::Eventually(w, a) => {
            let always = matches!(f, Formula::Always(..));
            let s = satisfaction(a, t);
            let (lo, hi) = steps(w, t.dt);
            let empty = if always {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            };
            Satisfaction {
                margin: sliding(&s.margin, lo, hi, always, empty),
                holds: sliding_truth(&s.holds, lo, hi, always),
            }
        }
    }
}

/// The formula's robustness and truth over the run (at its first row); `None` for a run
/// without rows.
pub fn at_start(f: &Formula, t: &Trace) -> Option<(f64, bool)> {
    let s = satisfaction(f, t);
    Some((*s.margin.first()?, *s.holds.first()?))
}
