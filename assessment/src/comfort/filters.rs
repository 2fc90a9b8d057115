//! The signal filters of the comfort figures: the peak slope over a window (the jerk) and
//! the second-order Butterworth low pass.

/// Largest |x[i+k] − x[i]| over a stream of values, k = round(w/dt): the slope of `x` over the
/// window `w`, as [`slope_peak`] computes it on a slice, with a ring of the last k values.
pub(super) struct SlopePeak {
    k: usize,
    ring: std::collections::VecDeque<f64>,
    best: f64,
}

impl SlopePeak {
    pub(super) fn new(dt: f64, w: f64) -> Self {
        let k = ((w / dt).round() as usize).max(1);
        SlopePeak {
            k,
            ring: std::collections::VecDeque::with_capacity(k + 1),
            best: 0.0,
        }
    }
    pub(super) fn push(&mut self, x: f64) {
        if self.ring.len() == self.k {
            if let Some(old) = self.ring.pop_front() {
                self.best = self.best.max((x - old).abs());
            }
        }
        self.ring.push_back(x);
    }
    /// The slope (per second) at step `dt`.
    pub(super) fn value(&self, dt: f64) -> f64 {
        self.best / (self.k as f64 * dt)
    }
}

/// Largest slope of `x` over a window `w` (step `dt`): max |x[i+k] − x[i]| / (k·dt),
/// k = round(w/dt); 0 when the series is not longer than the window.
pub fn slope_peak(x: &[f64], dt: f64, w: f64) -> f64 {
    let mut sp = SlopePeak::new(dt, w);
    x.iter().for_each(|v| sp.push(*v));
    sp.value(dt)
}

/// One second-order section, y = b0 x + b1 x[k−1] + b2 x[k−2] − a1 y[k−1] − a2 y[k−2], one
/// sample at a time: the low-pass of the comfort filters and each section of a ride
/// weighting ([`super::WeightingFilter`]).
#[derive(Debug, Clone)]
pub(super) struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
    /// x[k−1], x[k−2], y[k−1], y[k−2].
    state: [f64; 4],
}

impl Biquad {
    /// The section with numerator `b` (b0, b1, b2) and denominator `a` (a1, a2; a0 = 1), at
    /// rest at zero.
    pub(super) fn new(b: [f64; 3], a: [f64; 2]) -> Self {
        Biquad {
            b,
            a,
            state: [0.0; 4],
        }
    }

    /// Puts the section at rest at `x` (input and output, as for a unit DC gain).
    pub(super) fn rest_at(&mut self, x: f64) {
        self.state = [x; 4];
    }

    /// Filters the next sample.
    #[inline]
    pub(super) fn step(&mut self, x0: f64) -> f64 {
        let [x1, x2, y1, y2] = self.state;
        let y0 = self.b[0] * x0 + self.b[1] * x1 + self.b[2] * x2 - self.a[0] * y1 - self.a[1] * y2;
        self.state = [x0, x1, y0, y1];
        y0
    }
}

/// Second-order Butterworth low-pass (bilinear transform), one sample at a time, from rest at
/// the first sample's value.
#[derive(Debug, Clone)]
pub struct LowPass {
    f: Biquad,
    /// Whether a sample has come (the filter starts at rest at the first one).
    started: bool,
}

impl LowPass {
    /// A filter with cut-off `fc` (Hz) at step `dt` (s).
    pub fn new(dt: f64, fc: f64) -> Self {
        let k = (std::f64::consts::PI * fc * dt).tan();
        let q = std::f64::consts::SQRT_2;
        let norm = 1.0 / (1.0 + q * k + k * k);
        let b0 = k * k * norm;
        LowPass {
            f: Biquad::new(
                [b0, 2.0 * b0, b0],
                [2.0 * (k * k - 1.0) * norm, (1.0 - q * k + k * k) * norm],
            ),
            started: false,
        }
    }

    /// Filters the next sample.
    pub fn step(&mut self, x0: f64) -> f64 {
        if !self.started {
            self.f.rest_at(x0);
            self.started = true;
        }
        self.f.step(x0)
    }
}

/// [`LowPass`] over a whole series.
pub fn low_pass(x: &[f64], dt: f64, fc: f64) -> Vec<f64> {
    let mut f = LowPass::new(dt, fc);
    x.iter().map(|v| f.step(*v)).collect()
}
