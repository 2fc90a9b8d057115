//! The obvious adversaries, evaluated before the search and seeding it: every link at its
//! largest delay, and (with several links free) each link alone at its largest delay, the
//! others as early as their bounds allow (a late measurement can soften what a late command
//! does: on the paper's MPC, all links late hurt less than the command alone); and, at each
//! curve transition's start and end and at each scheduled fault, the largest delay with the
//! whole loss and freeze budgets spent as one outage beginning there, on all links at once
//! and on each link alone (the others early). Each is a point of the coordinates CMA-ES
//! searches (`history::dims`), so the best of them is where CMA-ES starts.

use tiltsim_scenario::scenario::Scenario;

use super::history::{Layout, KNOTS, WINDOWS};

/// One obvious adversary.
#[derive(Debug, Clone, PartialEq)]
pub struct Adversary {
    /// What it is, for the progress table.
    pub name: String,
    /// Its coordinates (each in `[0, 1]`).
    pub coords: Vec<f64>,
}

/// The moments of scenario `s` an outage is placed at (s), named: the start and end of each
/// curve transition, and each scheduled fault within the run.
pub fn moments(s: &Scenario) -> Vec<(String, f64)> {
    let tp = &s.track;
    let v = tp.speed();
    let t1 = tp.straight_before_m / v;
    let t2 = t1 + tp.transition_m / v;
    let t3 = t2 + tp.curve_m / v;
    let t4 = t3 + tp.transition_m / v;
    let mut out = vec![
        ("curve entry transition begins".to_string(), t1),
        ("curve entry transition ends".to_string(), t2),
        ("curve exit transition begins".to_string(), t3),
        ("curve exit transition ends".to_string(), t4),
    ];
    for f in &s.faults.schedule {
        out.push((
            format!("scheduled fault ({} {})", f.participant, f.action),
            f.at_s,
        ));
    }
    out.retain(|(_, t)| *t >= 0.0 && *t < s.duration());
    out
}

/// The coordinates of link `i` at its largest delay, its outages (if `at` is given) one run of
/// each kind, the stall then the losses, beginning at `at` seconds.
fn link_coords(s: &Scenario, layout: &Layout, i: usize, at: Option<f64>, a: &mut [f64]) {
    let (l, b, r) = &layout.links[i];
    let c = &mut a[r.clone()];
    let mut k = 0;
    if b.d_max > b.d_min {
        c[..KNOTS].fill(1.0);
        k = KNOTS;
        if b.jitter > 0 {
            c[k] = 0.0;
            c[k + 1] = 0.0;
            k += 2;
        }
    }
    let n = l.samples as i64;
    let stalled = if b.freeze > 0 {
        b.freeze / l.spacing as i64
    } else {
        0
    };
    let spacing = l.spacing as i64;
    let first = at.map(|t| ((t / s.run.dt_s).round() as i64 + spacing - 1) / spacing);
    let pos = |start: i64, len: i64| {
        if n > len {
            ((start as f64 + 0.5) / (n - len) as f64).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    for (budget, len, offset) in [(b.losses, b.losses, stalled), (b.freeze, stalled, 0)] {
        if budget == 0 {
            continue;
        }
        if let Some(first) = first {
            c[k] = pos(first + offset, len);
            c[k + 1] = 1.0;
        }
        k += 2 * WINDOWS;
    }
}

/// The obvious adversaries of scenario `s` searched with `layout` (none when no link is
/// free).
pub fn adversaries(s: &Scenario, layout: &Layout) -> Vec<Adversary> {
    let free = layout.free();
    if free.is_empty() {
        return Vec::new();
    }
    // `late`: the links at their largest delay (the others at coordinates 0, as early as
    // their bounds allow); `on`: those of them with an outage from `at`.
    let point = |late: &[usize], on: &[usize], at: Option<f64>| {
        let mut a = vec![0.0; layout.dims];
        for &i in late {
            link_coords(s, layout, i, at.filter(|_| on.contains(&i)), &mut a);
        }
        a
    };
    let mut out = vec![Adversary {
        name: "largest delay".into(),
        coords: point(&free, &[], None),
    }];
    if free.len() > 1 {
        for &i in &free {
            out.push(Adversary {
                name: format!("largest delay on {} alone", layout.links[i].0.id.name()),
                coords: point(&[i], &[], None),
            });
        }
    }
    let outages: Vec<usize> = free
        .iter()
        .copied()
        .filter(|&i| layout.links[i].1.losses > 0 || layout.links[i].1.freeze > 0)
        .collect();
    if outages.is_empty() {
        return out;
    }
    let mut groups = vec![outages.clone()];
    if outages.len() > 1 {
        groups.extend(outages.iter().map(|&i| vec![i]));
    }
    for (what, t) in moments(s) {
        for g in &groups {
            let on: Vec<&str> = g.iter().map(|&i| layout.links[i].0.id.name()).collect();
            out.push(Adversary {
                name: format!(
                    "largest delay, outage on {} from {t:.2} s ({what})",
                    on.join(" and ")
                ),
                coords: if g.len() > 1 {
                    point(&free, g, Some(t))
                } else {
                    point(g, g, Some(t))
                },
            });
        }
    }
    out
}
