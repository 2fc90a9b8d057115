//! The search's last phase works on histories themselves: a (1 + λ) evolution strategy whose
//! parent is the worst history found so far (by the adversaries, CMA-ES or an earlier
//! generation) and whose children each rewrite a stretch of one link's history, projected back
//! onto the bounds (`history::project`).
//!
//! A child rewrites a random stretch (the whole run one time in eight) of one free link, by
//! one of:
//!
//! * a new fate for each sample: delivered with a delay drawn uniformly from the bounds'
//!   range, lost or stalled (each kind one time in sixteen, where it has a budget);
//! * one delay drawn uniformly from the range for every delivered sample of the stretch;
//! * an outage: the stretch (no longer than the budget) lost or stalled, the link's other
//!   outages of that kind cleared one time in two (the outage moves);
//! * the stretch's outages cleared (delivered at the largest delay).
//!
//! Every admissible history is reachable from any parent in one child: the first rewrite of
//! the whole run draws it with a probability above zero, and its projection is itself.

use rand::{Rng as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;

use super::history::{project, Fate, History, Layout};

/// Draws the children of a parent history.
pub struct Mutator<'a> {
    layout: &'a Layout,
    free: Vec<usize>,
    rng: ChaCha8Rng,
}

impl<'a> Mutator<'a> {
    /// The children over `layout`, their draws from `seed`.
    pub fn new(layout: &'a Layout, seed: u64) -> Mutator<'a> {
        Mutator {
            layout,
            free: layout.free(),
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// A stretch `[start, end)` of a link of `n` samples: the whole run one time in eight,
    /// else a random start and a length log-uniform up to the end.
    fn stretch(&mut self, n: usize) -> (usize, usize) {
        if n == 0 || self.rng.random_range(0..8) == 0 {
            return (0, n);
        }
        let start = self.rng.random_range(0..n);
        let most = (n - start) as f64;
        let len = (most.ln() * self.rng.random::<f64>()).exp().floor() as usize;
        (start, start + len.clamp(1, n - start))
    }

    /// One child of `parent` (projected: admissible).
    pub fn child(&mut self, parent: &History) -> History {
        let mut h = parent.clone();
        if self.free.is_empty() {
            return h;
        }
        let i = self.free[self.rng.random_range(0..self.free.len())];
        let (l, b, _) = &self.layout.links[i];
        let (l, b) = (*l, *b);
        let n = h[i].len();
        let spread = b.d_max > b.d_min;
        let outages = b.losses > 0 || b.freeze > 0;
        let op = match (spread, outages) {
            (true, true) => self.rng.random_range(0..4),
            (true, false) => self.rng.random_range(0..2),
            (false, _) => [0, 2, 3][self.rng.random_range(0..3)],
        };
        let delay = |rng: &mut ChaCha8Rng| rng.random_range(b.d_min..=b.d_max);
        match op {
            0 => {
                let (a, z) = self.stretch(n);
                for f in &mut h[i][a..z] {
                    let r = self.rng.random_range(0..16);
                    *f = if r == 0 && b.losses > 0 {
                        Fate::Lost
                    } else if r == 1 && b.freeze > 0 {
                        Fate::Frozen
                    } else {
                        Fate::Delivered(delay(&mut self.rng))
                    };
                }
            }
            1 => {
                let (a, z) = self.stretch(n);
                let d = delay(&mut self.rng);
                for f in &mut h[i][a..z] {
                    if matches!(f, Fate::Delivered(_)) {
                        *f = Fate::Delivered(d);
                    }
                }
            }
            2 => {
                let kind = if b.freeze == 0 || (b.losses > 0 && self.rng.random_bool(0.5)) {
                    Fate::Lost
                } else {
                    Fate::Frozen
                };
                let most = if kind == Fate::Lost {
                    b.losses
                } else {
                    b.freeze / l.spacing as i64
                };
                let len = self.rng.random_range(1..=most.max(1)) as usize;
                let len = len.min(n);
                if self.rng.random_bool(0.5) {
                    for f in h[i].iter_mut().filter(|f| **f == kind) {
                        *f = Fate::Delivered(b.d_max);
                    }
                }
                let start = self.rng.random_range(0..=n - len);
                h[i][start..start + len].fill(kind);
            }
            _ => {
                let (a, z) = self.stretch(n);
                for f in &mut h[i][a..z] {
                    if !matches!(f, Fate::Delivered(_)) {
                        *f = Fate::Delivered(b.d_max);
                    }
                }
            }
        }
        h[i] = project(&l, &b, &h[i]);
        h
    }
}
