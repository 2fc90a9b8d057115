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

fn median(mut x: Vec<f64>) -> f64 {
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
        (0..NW)
            .map(|j| {
                let s: Vec<WheelForces> = self.samples.iter().map(|t| t[j]).collect();
                (f(&s), j)
            })
            .fold((f64::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a })
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
        let n = (lim.window_m / (v * dt)).round() as usize;
        let yq = |s: &[WheelForces], plus: bool| -> Vec<f64> {
            s.iter()
                .map(|f| {
                    let (y, q) = if plus {
                        (f.y_climb_plus(), f.q_plus)
                    } else {
                        (f.y_climb_minus(), f.q_minus)
                    };
                    // A lifted wheel (Q ≤ 0, beyond the linear model's range) has no quotient.
                    if q > 0.0 {
                        y / q
                    } else {
                        f64::INFINITY
                    }
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
        let p0_kn = 2.0 * q0 / 1000.0;
        Some(vec![
            Assessed {
                name: "(Y/Q)_2m",
                value: y_q,
                limit: lim.y_over_q,
                wheelset: j_yq,
                source: "EN 14363, derailment quotient, R >= 250 m",
            },
            Assessed {
                name: "(SumY)_2m",
                value: sy,
                limit: lim.alpha * (10.0 + p0_kn / 3.0) * 1000.0,
                wheelset: j_sy,
                source: "Prud'homme 1967 / EN 14363 alpha (10 + P0/3) kN",
            },
            Assessed {
                name: "dQ/Q0",
                value: dq,
                limit: lim.unloading,
                wheelset: j_dq,
                source: "EN 14363, wheel unloading (twist test limit)",
            },
            Assessed {
                name: "Y_qst",
                value: yqst,
                limit: lim.y_qst,
                wheelset: j_yqst,
                source: "EN 14363, quasi-static lateral wheel force",
            },
            Assessed {
                name: "Q_qst",
                value: qqst,
                limit: lim.q_qst,
                wheelset: j_qqst,
                source: "EN 14363, quasi-static vertical wheel force",
            },
        ])
    }

    /// The quantity closest to (or furthest beyond) its limit.
    pub fn binding(assessed: &[Assessed]) -> Option<&Assessed> {
        assessed
            .iter()
            .max_by(|a, b| a.utilisation().total_cmp(&b.utilisation()))
    }
}
