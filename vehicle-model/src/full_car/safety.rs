//! Running safety at every wheelset, quasi-static and dynamic, against the limits of
//! EN 14363 (docs/model.md, "The whole car", running safety): derailment quotient Y/Q,
//! track shift force ΣY (Prud'homme), wheel unloading ΔQ/Q_0, quasi-static Y and Q.

use super::inputs::NW;
use super::outputs::WheelForces;

/// Nadal's limit of the derailment quotient (Nadal 1908): (tan β − μ)/(1 + μ tan β) for a
/// flange angle `beta` (rad) and a coefficient of friction `mu` at the flange.
pub fn nadal_limit(beta: f64, mu: f64) -> f64 {
    (beta.tan() - mu) / (1.0 + mu * beta.tan())
}

/// Limits and their settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SafetyLimits {
    /// (Y/Q)_lim (-): EN 14363, 0.8 for curve radii R ≥ 250 m.
    pub y_over_q: f64,
    /// α of the track shift force limit α(10 + P_0/3) kN: 1.0 for passenger vehicles and
    /// locomotives, 0.85 for freight wagons (EN 14363); 1.0 is Prud'homme's own limit.
    pub alpha: f64,
    /// (ΔQ/Q_0)_lim (-): 0.6, EN 14363's limit of wheel unloading on twisted track.
    pub unloading: f64,
    /// (Y_qst)_lim (N): 60 kN, EN 14363's quasi-static lateral wheel force.
    pub y_qst: f64,
    /// (Q_qst)_lim (N): 145 kN, EN 14363's quasi-static vertical wheel force.
    pub q_qst: f64,
    /// Length of the sliding mean of the dynamic Y/Q and ΣY (m): 2 m in EN 14363.
    pub window_m: f64,
}

impl Default for SafetyLimits {
    fn default() -> Self {
        SafetyLimits {
            y_over_q: 0.8,
            alpha: 1.0,
            unloading: 0.6,
            y_qst: 60e3,
            q_qst: 145e3,
            window_m: 2.0,
        }
    }
}

/// One assessed quantity: its worst value, where, and its limit.
#[derive(Debug, Clone, PartialEq)]
pub struct Assessed {
    /// Name, e.g. `(Y/Q)_2m`.
    pub name: &'static str,
    /// Worst value (the quantity's unit: N or -).
    pub value: f64,
    /// Limit (same unit).
    pub limit: f64,
    /// Wheelset (0 leading) where the worst value occurred.
    pub wheelset: usize,
    /// Where the limit comes from.
    pub source: &'static str,
}

impl Assessed {
    /// value / limit: above 1 the limit is exceeded.
    pub fn utilisation(&self) -> f64 {
        self.value / self.limit
    }
}

/// The five assessed quantities from their worst values and wheelsets, in the order
/// `(Y/Q)_2m`, `(SumY)_2m`, `dQ/Q0`, `Y_qst`, `Q_qst`, with static wheel load `q0` (N).
pub fn assessed(lim: &SafetyLimits, q0: f64, worst: [(f64, usize); 5]) -> Vec<Assessed> {
    let p0_kn = 2.0 * q0 / 1000.0;
    let named = [
        (
            "(Y/Q)_2m",
            lim.y_over_q,
            "EN 14363, derailment quotient, R >= 250 m",
        ),
        (
            "(SumY)_2m",
            lim.alpha * (10.0 + p0_kn / 3.0) * 1000.0,
            "Prud'homme 1967 / EN 14363 alpha (10 + P0/3) kN",
        ),
        (
            "dQ/Q0",
            lim.unloading,
            "EN 14363, wheel unloading (twist test limit)",
        ),
        (
            "Y_qst",
            lim.y_qst,
            "EN 14363, quasi-static lateral wheel force",
        ),
        (
            "Q_qst",
            lim.q_qst,
            "EN 14363, quasi-static vertical wheel force",
        ),
    ];
    named
        .iter()
        .zip(worst)
        .map(|(&(name, limit, source), (value, wheelset))| Assessed {
            name,
            value,
            limit,
            wheelset,
            source,
        })
        .collect()
}

/// Worst (largest) of the wheelsets' values and its wheelset, the first on a tie; NaN never
/// wins.
pub fn worst_of(values: impl IntoIterator<Item = f64>) -> (f64, usize) {
    values
        .into_iter()
        .enumerate()
        .map(|(j, x)| (x, j))
        .fold((f64::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a })
}

/// Y/Q of one wheel: infinite when the wheel lifted (Q ≤ 0, beyond the linear model's range).
pub fn quotient(y: f64, q: f64) -> f64 {
    if q > 0.0 {
        y / q
    } else {
        f64::INFINITY
    }
}

/// Collects wheel forces tick by tick and assesses them.
#[derive(Debug, Clone, Default)]
pub struct RunningSafety {
    /// Samples: for each tick, the forces of every wheelset.
    samples: Vec<[WheelForces; NW]>,
}

fn sliding_mean_max(x: &[f64], n: usize) -> f64 {
    let n = n.clamp(1, x.len().max(1));
    let mut sum: f64 = x[..n].iter().sum();
    let mut best = sum / n as f64;
    for k in n..x.len() {
        sum += x[k] - x[k - n];
        best = best.max(sum / n as f64);
    }
    best
}

/// The median (50 % value) of `x`: the middle value, or the mean of the two middle ones.
pub fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n % 2 == 1 {
        x[n / 2]
    } else {
        0.5 * (x[n / 2 - 1] + x[n / 2])
    }
}

impl RunningSafety {
    /// Empty.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds one tick's forces.
    pub fn push(&mut self, f: [WheelForces; NW]) {
        self.samples.push(f);
    }
    /// Number of ticks collected.
    pub fn len(&self) -> usize {
        self.samples.len()
    }
    /// Whether nothing was collected.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// Worst over wheelsets of `f` applied to each wheelset's series.
    fn worst(&self, f: impl Fn(&[WheelForces]) -> f64) -> (f64, usize) {
        worst_of((0..NW).map(|j| {
            let s: Vec<WheelForces> = self.samples.iter().map(|t| t[j]).collect();
            f(&s)
        }))
    }

    /// Assesses what was collected at speed `v` (m/s) and tick `dt` (s), static wheel load
    /// `q0` (N). Dynamic Y/Q and ΣY are the largest 2 m sliding means (EN 14363's (·)_2m);
    /// quasi-static values are medians over the record (its 50 % value), so the caller
    /// passes the section it means (a steady curve). A wheel whose load reaches zero has an
    /// infinite Y/Q (and ΔQ/Q0 ≥ 1): the linear model has left its range there. None when
    /// nothing was collected.
    pub fn assess(&self, lim: &SafetyLimits, v: f64, dt: f64, q0: f64) -> Option<Vec<Assessed>> {
        if self.samples.is_empty() {
            return None;
        }
        let n = window_samples(lim, v, dt);
        let yq = |s: &[WheelForces], plus: bool| -> Vec<f64> {
            s.iter()
                .map(|f| {
                    let (y, q) = if plus {
                        (f.y_climb_plus(), f.q_plus)
                    } else {
                        (f.y_climb_minus(), f.q_minus)
                    };
                    quotient(y, q)
                })
                .collect()
        };
        let (y_q, j_yq) = self
            .worst(|s| sliding_mean_max(&yq(s, true), n).max(sliding_mean_max(&yq(s, false), n)));
        let (sy, j_sy) = self.worst(|s| {
            let a: Vec<f64> = s.iter().map(|f| f.sum_y.abs()).collect();
            sliding_mean_max(&a, n)
        });
        let (dq, j_dq) = self.worst(|s| {
            s.iter()
                .map(|f| (q0 - f.q_plus.min(f.q_minus)) / q0)
                .fold(f64::NEG_INFINITY, f64::max)
        });
        let (yqst, j_yqst) = self.worst(|s| {
            median(
                s.iter()
                    .map(|f| f.y_plus.abs().max(f.y_minus.abs()))
                    .collect(),
            )
        });
        let (qqst, j_qqst) =
            self.worst(|s| median(s.iter().map(|f| f.q_plus.max(f.q_minus)).collect()));
        Some(assessed(
            lim,
            q0,
            [
                (y_q, j_yq),
                (sy, j_sy),
                (dq, j_dq),
                (yqst, j_yqst),
                (qqst, j_qqst),
            ],
        ))
    }

    /// The quantity closest to (or furthest beyond) its limit.
    pub fn binding(assessed: &[Assessed]) -> Option<&Assessed> {
        assessed
            .iter()
            .max_by(|a, b| a.utilisation().total_cmp(&b.utilisation()))
    }
}

/// Samples in EN 14363's 2 m sliding window at speed `v` (m/s) and tick `dt` (s): the window
/// length over the distance run per tick, rounded (a window is at least one sample, and at
/// most the record).
pub fn window_samples(lim: &SafetyLimits, v: f64, dt: f64) -> usize {
    (lim.window_m / (v * dt)).round() as usize
}

/// The largest mean of `n` consecutive values of a series handed over one by one, with the
/// window's values in a ring of `n` (the same sums, in the same order, as the whole-record
/// computation, so the same bits). A record shorter than the window gives its mean.
#[derive(Debug, Clone)]
pub struct SlidingMeanMax {
    n: usize,
    ring: Vec<f64>,
    head: usize,
    sum: f64,
    best: f64,
}

impl SlidingMeanMax {
    /// A window of `n` samples (at least one).
    pub fn new(n: usize) -> Self {
        SlidingMeanMax {
            n: n.max(1),
            ring: Vec::new(),
            head: 0,
            // The empty sum (the identity `Iterator::sum` starts from).
            sum: std::iter::empty::<f64>().sum(),
            best: f64::NEG_INFINITY,
        }
    }
    /// Adds the next value.
    pub fn push(&mut self, x: f64) {
        if self.ring.len() < self.n {
            self.sum += x;
            self.ring.push(x);
            if self.ring.len() == self.n {
                self.best = self.sum / self.n as f64;
            }
        } else {
            let old = std::mem::replace(&mut self.ring[self.head], x);
            self.head = (self.head + 1) % self.n;
            self.sum += x - old;
            self.best = self.best.max(self.sum / self.n as f64);
        }
    }
    /// The largest window mean so far (the mean of all when fewer than `n`); None before
    /// the first value.
    pub fn max(&self) -> Option<f64> {
        match self.ring.len() {
            0 => None,
            k if k < self.n => Some(self.sum / k as f64),
            _ => Some(self.best),
        }
    }
    /// Values held: at most `n`.
    pub fn held(&self) -> usize {
        self.ring.len()
    }
}

/// The dynamic quantities ((Y/Q)_2m, (ΣY)_2m, ΔQ/Q_0) of a record handed over tick by tick:
/// the sliding windows in rings of [`window_samples`], the unloading a running maximum. What
/// it holds does not grow with the record.
#[derive(Debug, Clone)]
pub struct DynamicStream {
    /// Y/Q of the +y and the −y wheel of each wheelset.
    y_q: [[SlidingMeanMax; 2]; NW],
    /// |ΣY| of each wheelset.
    sum_y: [SlidingMeanMax; NW],
    /// Largest ΔQ/Q_0 of each wheelset.
    unloading: [f64; NW],
    q0: f64,
}

impl DynamicStream {
    /// Windows of `n` samples, static wheel load `q0` (N).
    pub fn new(n: usize, q0: f64) -> Self {
        DynamicStream {
            y_q: std::array::from_fn(|_| std::array::from_fn(|_| SlidingMeanMax::new(n))),
            sum_y: std::array::from_fn(|_| SlidingMeanMax::new(n)),
            unloading: [f64::NEG_INFINITY; NW],
            q0,
        }
    }
    /// Adds one tick's forces.
    pub fn push(&mut self, f: &[WheelForces; NW]) {
        for (j, f) in f.iter().enumerate() {
            self.y_q[j][0].push(quotient(f.y_climb_plus(), f.q_plus));
            self.y_q[j][1].push(quotient(f.y_climb_minus(), f.q_minus));
            self.sum_y[j].push(f.sum_y.abs());
            let dq = (self.q0 - f.q_plus.min(f.q_minus)) / self.q0;
            self.unloading[j] = self.unloading[j].max(dq);
        }
    }
    /// Worst (value, wheelset) of (Y/Q)_2m, (ΣY)_2m and ΔQ/Q_0; None before the first tick.
    pub fn finish(&self) -> Option<[(f64, usize); 3]> {
        let mut y_q = [0.0; NW];
        let mut sum_y = [0.0; NW];
        for j in 0..NW {
            y_q[j] = self.y_q[j][0].max()?.max(self.y_q[j][1].max()?);
            sum_y[j] = self.sum_y[j].max()?;
        }
        Some([worst_of(y_q), worst_of(sum_y), worst_of(self.unloading)])
    }
    /// Values held in the windows.
    pub fn held(&self) -> usize {
        self.y_q
            .iter()
            .flatten()
            .chain(&self.sum_y)
            .map(SlidingMeanMax::held)
            .sum()
    }
}

/// The quasi-static quantities (Y_qst, Q_qst: medians) of the ticks handed over: exact
/// medians, so the values are kept, two per wheelset and tick; the caller hands over only
/// the section assessed (the steady curve), which bounds what is held by that section's
/// length, not the record's (docs/model.md, "The whole car in a run").
#[derive(Debug, Clone, Default)]
pub struct QuasiStaticStream {
    y: [Vec<f64>; NW],
    q: [Vec<f64>; NW],
}

impl QuasiStaticStream {
    /// Empty.
    pub fn new() -> Self {
        Self::default()
    }
    /// Adds one tick's forces.
    pub fn push(&mut self, f: &[WheelForces; NW]) {
        for (j, f) in f.iter().enumerate() {
            self.y[j].push(f.y_plus.abs().max(f.y_minus.abs()));
            self.q[j].push(f.q_plus.max(f.q_minus));
        }
    }
    /// Worst (value, wheelset) of Y_qst and Q_qst; None when nothing was handed over.
    pub fn finish(&self) -> Option<[(f64, usize); 2]> {
        if self.y[0].is_empty() {
            return None;
        }
        Some([
            worst_of(self.y.iter().map(|y| median(y.clone()))),
            worst_of(self.q.iter().map(|q| median(q.clone()))),
        ])
    }
    /// Values held.
    pub fn held(&self) -> usize {
        self.y.iter().chain(&self.q).map(Vec::len).sum()
    }
}
