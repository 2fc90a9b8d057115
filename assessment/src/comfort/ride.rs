//! The straight-track ride: the EN 12299 frequency weightings (Wd, Wb, Wc) and the ride
//! figures over 5 s windows.

use serde::Serialize;

use super::filters::Biquad;
use super::sample::Sample;

/// A frequency weighting of ISO 2631-1 as ISO 8041 (Table 3.1 of its parameters) and EN 12299
/// use it: band-limiting high-pass (f1, Q1) and low-pass (f2, Q2), acceleration-velocity
/// transition (f3, f4, Q4), upward step (f5, Q5, f6, Q6), gain K. An absent stage has its
/// frequencies infinite.
/// `H(s) = K · s²/(s² + ω1 s/Q1 + ω1²) · ω2²/(s² + ω2 s/Q2 + ω2²)
///        · (1 + s/ω3)/(1 + s/(Q4 ω4) + s²/ω4²)
///        · (ω5/ω6)²·(1 + s/(Q5 ω5) + s²/ω5²)/(1 + s/(Q6 ω6) + s²/ω6²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weighting {
    /// Name (Wd, Wb, Wc).
    pub name: &'static str,
    /// f1, Q1, f2, Q2, f3, f4, Q4, f5, Q5, f6, Q6 (Hz and 1), K.
    pub f1: f64,
    #[allow(missing_docs)]
    pub q1: f64,
    #[allow(missing_docs)]
    pub f2: f64,
    #[allow(missing_docs)]
    pub q2: f64,
    #[allow(missing_docs)]
    pub f3: f64,
    #[allow(missing_docs)]
    pub f4: f64,
    #[allow(missing_docs)]
    pub q4: f64,
    #[allow(missing_docs)]
    pub f5: f64,
    #[allow(missing_docs)]
    pub q5: f64,
    #[allow(missing_docs)]
    pub f6: f64,
    #[allow(missing_docs)]
    pub q6: f64,
    #[allow(missing_docs)]
    pub k: f64,
}

pub(super) const SQRT_HALF: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Wd, horizontal (x and y) acceleration, EN 12299's weighting for lateral ride comfort.
pub const WD: Weighting = Weighting {
    name: "Wd",
    f1: 0.4,
    q1: SQRT_HALF,
    f2: 100.0,
    q2: SQRT_HALF,
    f3: 2.0,
    f4: 2.0,
    q4: 0.63,
    f5: f64::INFINITY,
    q5: 1.0,
    f6: f64::INFINITY,
    q6: 1.0,
    k: 1.0,
};
/// Wb, vertical acceleration (ISO 2631-4, EN 12299's vertical weighting).
pub const WB: Weighting = Weighting {
    name: "Wb",
    f1: 0.4,
    q1: SQRT_HALF,
    f2: 100.0,
    q2: SQRT_HALF,
    f3: 16.0,
    f4: 16.0,
    q4: 0.55,
    f5: 2.5,
    q5: 0.9,
    f6: 4.0,
    q6: 0.95,
    k: 1.024,
};
/// Wc, longitudinal acceleration at the seat back (EN 12299's complete method).
pub const WC: Weighting = Weighting {
    name: "Wc",
    f1: 0.4,
    q1: SQRT_HALF,
    f2: 100.0,
    q2: SQRT_HALF,
    f3: 8.0,
    f4: 8.0,
    q4: 0.63,
    f5: f64::INFINITY,
    q5: 1.0,
    f6: f64::INFINITY,
    q6: 1.0,
    k: 1.0,
};

/// One analog section (b2 s² + b1 s + b0)/(a2 s² + a1 s + a0) and the angular frequency its
/// bilinear transform is prewarped at.
pub(super) type Analog = ([f64; 3], [f64; 3], f64);

impl Weighting {
    /// The analog sections (numerator and denominator coefficients [s⁰, s¹, s²]).
    pub(super) fn sections(&self) -> Vec<Analog> {
        let w = |f: f64| std::f64::consts::TAU * f;
        let mut v = Vec::new();
        let (w1, w2) = (w(self.f1), w(self.f2));
        v.push(([0.0, 0.0, 1.0], [w1 * w1, w1 / self.q1, 1.0], w1));
        v.push(([w2 * w2, 0.0, 0.0], [w2 * w2, w2 / self.q2, 1.0], w2));
        if self.f4.is_finite() {
            let (w3, w4) = (w(self.f3), w(self.f4));
            let n1 = if self.f3.is_finite() { 1.0 / w3 } else { 0.0 };
            v.push((
                [1.0, n1, 0.0],
                [1.0, 1.0 / (self.q4 * w4), 1.0 / (w4 * w4)],
                w4,
            ));
        }
        if self.f6.is_finite() {
            // Unity at high frequency, (f5/f6)² at low (the Larson Davis HVM200 manual's
            // rendering of ISO 8041 Table 3.1 writes it the same way).
            let (w5, w6) = (w(self.f5), w(self.f6));
            let r = (w5 / w6).powi(2);
            v.push((
                [r, r / (self.q5 * w5), r / (w5 * w5)],
                [1.0, 1.0 / (self.q6 * w6), 1.0 / (w6 * w6)],
                w6,
            ));
        }
        v
    }

    /// |H(j2πf)| of the continuous weighting.
    pub fn gain(&self, f_hz: f64) -> f64 {
        let om = std::f64::consts::TAU * f_hz;
        let eval = |c: &[f64; 3]| {
            let (re, im) = (c[0] - c[2] * om * om, c[1] * om);
            (re * re + im * im).sqrt()
        };
        self.k
            * self
                .sections()
                .iter()
                .map(|(b, a, _)| eval(b) / eval(a))
                .product::<f64>()
    }
}

/// A [`Weighting`] as a cascade of biquads at step `dt`, each the bilinear transform of its
/// analog section prewarped at the section's own corner frequency (so the 100 Hz band limit is
/// placed exactly at a 1 ms step), one sample at a time from rest.
#[derive(Debug, Clone)]
pub struct WeightingFilter {
    k: f64,
    /// The sections, in order.
    biquads: Vec<Biquad>,
}

impl WeightingFilter {
    /// The filter of `w` at step `dt` (s).
    pub fn new(w: &Weighting, dt: f64) -> Self {
        let biquads = w
            .sections()
            .iter()
            .map(|(b, a, wp)| {
                // s = c (1 − z⁻¹)/(1 + z⁻¹), c = ω_p / tan(ω_p T/2); ω_p clamped below Nyquist.
                let wp = wp.min(0.9 * std::f64::consts::PI / dt);
                let c = wp / (wp * dt / 2.0).tan();
                let c2 = c * c;
                let z = |p: &[f64; 3]| {
                    [
                        p[2] * c2 + p[1] * c + p[0],
                        2.0 * (p[0] - p[2] * c2),
                        p[2] * c2 - p[1] * c + p[0],
                    ]
                };
                let (nb, na) = (z(b), z(a));
                Biquad::new(
                    [nb[0] / na[0], nb[1] / na[0], nb[2] / na[0]],
                    [na[1] / na[0], na[2] / na[0]],
                )
            })
            .collect();
        WeightingFilter { k: w.k, biquads }
    }

    /// Filters the next sample.
    pub fn step(&mut self, x: f64) -> f64 {
        let v = self.biquads.iter_mut().fold(x, |v, f| f.step(v));
        self.k * v
    }
}

/// Ride settings are those of EN 12299's mean comfort, standard method: 5 s windows, the
/// 95th percentile of their RMS values.
pub const RIDE_WINDOW_S: f64 = 5.0;

/// Straight-track ride of a run (`summary.json` → `comfort.ride`).
#[derive(Debug, Clone, Copy, Serialize, Default, PartialEq)]
pub struct Ride {
    /// The lateral part of EN 12299's mean comfort N_MV: 6·a_YP95^Wd (the model has no
    /// vertical or longitudinal carbody signal, so this is not N_MV itself).
    pub n_mv_lateral: f64,
    /// a_YP95^Wd: 95th percentile of the 5 s RMS values of the Wd-weighted carbody lateral
    /// acceleration (m/s²).
    pub a_y_p95_wd_m_s2: f64,
    /// RMS of the Wd-weighted carbody lateral acceleration over the whole run (m/s²).
    pub a_y_rms_wd_m_s2: f64,
    /// Number of whole 5 s windows evaluated (EN 12299 takes 60: five minutes).
    pub windows: usize,
    /// RMS of the tilt error θ_v − θ_v^d (deg).
    pub tilt_error_rms_deg: f64,
    /// RMS of the absolute carbody roll acceleration φ̈ (rad/s²).
    pub roll_acc_rms_rad_s2: f64,
    /// RMS of the absolute carbody roll speed φ̇ (rad/s).
    pub roll_speed_rms_rad_s: f64,
    /// a_ZP95^Wb of the vertical acceleration the body's roll gives at the point (m/s²):
    /// 0 on the centre line (the model has no vertical suspension motion).
    pub a_z_p95_wb_m_s2: f64,
    /// 6·√(a_YP95^Wd² + a_ZP95^Wb²): EN 12299's mean comfort N_MV with its vertical part from
    /// roll alone and no longitudinal part, named for what it holds.
    pub n_mv_roll: f64,
}

/// The ride assessment, one sample at a time.
pub(super) struct RideAssessor {
    dt: f64,
    wd: WeightingFilter,
    wb: WeightingFilter,
    z_window_sum: f64,
    z_window_rms: Vec<f64>,
    per_window: usize,
    in_window: usize,
    window_sum: f64,
    window_rms: Vec<f64>,
    total: (f64, usize),
    tilt: (f64, usize),
    roll_acc: (f64, usize),
    roll: (f64, usize),
    last_roll: Option<f64>,
}

impl RideAssessor {
    pub(super) fn new(dt: f64) -> Self {
        RideAssessor {
            dt,
            wd: WeightingFilter::new(&WD, dt),
            wb: WeightingFilter::new(&WB, dt),
            z_window_sum: 0.0,
            z_window_rms: Vec::new(),
            per_window: ((RIDE_WINDOW_S / dt).round() as usize).max(1),
            in_window: 0,
            window_sum: 0.0,
            window_rms: Vec::new(),
            total: (0.0, 0),
            tilt: (0.0, 0),
            roll_acc: (0.0, 0),
            roll: (0.0, 0),
            last_roll: None,
        }
    }

    pub(super) fn push(&mut self, x: &Sample, carbody_lat_acc: f64) {
        let a = self.wd.step(carbody_lat_acc);
        let z = self.wb.step(x.vertical);
        self.z_window_sum += z * z;
        self.window_sum += a * a;
        self.total.0 += a * a;
        self.total.1 += 1;
        self.in_window += 1;
        if self.in_window == self.per_window {
            self.window_rms
                .push((self.window_sum / self.per_window as f64).sqrt());
            self.z_window_rms
                .push((self.z_window_sum / self.per_window as f64).sqrt());
            self.in_window = 0;
            self.window_sum = 0.0;
            self.z_window_sum = 0.0;
        }
        self.tilt.0 += x.tilt_error * x.tilt_error;
        self.tilt.1 += 1;
        self.roll.0 += x.roll_speed * x.roll_speed;
        self.roll.1 += 1;
        if let Some(p) = self.last_roll {
            let acc = (x.roll_speed - p) / self.dt;
            self.roll_acc.0 += acc * acc;
            self.roll_acc.1 += 1;
        }
        self.last_roll = Some(x.roll_speed);
    }

    pub(super) fn finish(&self) -> Ride {
        let rms = |(s, n): (f64, usize)| if n == 0 { 0.0 } else { (s / n as f64).sqrt() };
        let p95 = percentile(&self.window_rms, 0.95);
        let z95 = percentile(&self.z_window_rms, 0.95);
        Ride {
            a_z_p95_wb_m_s2: z95,
            n_mv_roll: 6.0 * (p95 * p95 + z95 * z95).sqrt(),
            n_mv_lateral: 6.0 * p95,
            a_y_p95_wd_m_s2: p95,
            a_y_rms_wd_m_s2: rms(self.total),
            windows: self.window_rms.len(),
            tilt_error_rms_deg: rms(self.tilt).to_degrees(),
            roll_acc_rms_rad_s2: rms(self.roll_acc),
            roll_speed_rms_rad_s: rms(self.roll),
        }
    }
}

/// The `q` quantile of `v` (linear between order statistics, as EN 12299's 95th percentile of
/// 60 values is usually read); 0 for no values.
pub fn percentile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let x = q * (s.len() - 1) as f64;
    let i = x.floor() as usize;
    let j = (i + 1).min(s.len() - 1);
    s[i] + (s[j] - s[i]) * (x - i as f64)
}
