//! Ride comfort from a run's recorded signals (the rows of Table 4).
//!
//! P_CT (EN 12299, comfort on curve transitions), in percent of passengers:
//! `P_CT = max(A·ÿ_m + B·y⃛_m − C, 0) + D·φ̇_m^E`, ÿ in m/s², y⃛ in m/s³, φ̇ in deg/s, with the
//! constants of `model-notes.md` for standing and seated passengers. Two evaluations:
//! * `whole-run-peaks` (the paper's, the default headline): ÿ_m, y⃛_m and φ̇_m are whole-run peaks
//!   of the signals as simulated; the jerk is the slope of ÿ over `jerk_window_s` (1 s), the
//!   way a quasi-static transition jerk is read off a plot.
//! * `en12299-transition`: per curve transition, on signals low-pass filtered at
//!   `filter_hz` (0.3 Hz, second-order Butterworth); ÿ_m and φ̇_m the largest filtered values
//!   in the transition extended by `margin_s` (1.6 s) each side, y⃛_m the largest change of the
//!   filtered ÿ over `jerk_window_s` divided by it. The worse transition is reported.
//!
//! The carbody roll speed is the absolute one, φ̇ = θ̇_v + θ̇_o (θ_v is relative to the track).

use serde::{Deserialize, Serialize};

use cosim::settings::Checker;

/// Gravity for %g (m/s²).
pub const G: f64 = 9.81;

/// P_CT constants (A, B, C, D, E).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PctConstants {
    /// A (per m/s²).
    pub a: f64,
    /// B (per m/s³).
    pub b: f64,
    /// C.
    pub c: f64,
    /// D.
    pub d: f64,
    /// E.
    pub e: f64,
}

/// Standing passengers (EN 12299, model-notes).
pub const STANDING: PctConstants = PctConstants {
    a: 28.54,
    b: 20.69,
    c: 11.1,
    d: 0.185,
    e: 2.283,
};
/// Seated passengers.
pub const SEATED: PctConstants = PctConstants {
    a: 8.97,
    b: 9.68,
    c: 5.9,
    d: 0.120,
    e: 1.626,
};

/// P_CT (%) from peak lateral acceleration (m/s²), jerk (m/s³) and roll speed (deg/s).
pub fn p_ct(k: &PctConstants, acc: f64, jerk: f64, roll_deg_s: f64) -> f64 {
    (k.a * acc.abs() + k.b * jerk.abs() - k.c).max(0.0) + k.d * roll_deg_s.abs().powf(k.e)
}

/// Comfort settings (scenario `[comfort]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ComfortSettings {
    /// Low-pass cut-off of the per-transition evaluation (Hz).
    pub filter_hz: f64,
    /// Window of the jerk difference quotient (s).
    pub jerk_window_s: f64,
    /// Time added before and after each transition (s).
    pub margin_s: f64,
    /// Secondary lateral bump-stop clearance (m).
    pub bump_stop_m: f64,
    /// The passenger lateral acceleration comfort is computed from: `eq13` (the paper's,
    /// default) or `with-sway` (eq 13 plus the body's sway acceleration). The other form's
    /// P_CT and peak are reported beside it (`comfort.other_form`).
    pub lateral_acceleration: LateralAcceleration,
}

/// Which passenger lateral acceleration comfort uses (`[comfort] lateral_acceleration`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum LateralAcceleration {
    /// Eq 13: ÿ = (v²/R)·cos(θ_o + θ_v) − g·sin(θ_o + θ_v), quasi-static: the body's own
    /// lateral acceleration on its suspension is left out (the paper's, for reproduction).
    #[default]
    Eq13,
    /// Eq 13 plus the body's sway acceleration ÿ_v + h_gv·θ̈_o from eq 9, i.e. the lateral
    /// specific force at the body's centre of gravity, −2(k_sy Δs + c_sy Δ̇s)/m_v − g·θ_v in
    /// the small-angle model: what an accelerometer on the body measures.
    WithSway,
}

impl LateralAcceleration {
    /// Kebab-case name.
    pub fn name(self) -> &'static str {
        match self {
            LateralAcceleration::Eq13 => "eq13",
            LateralAcceleration::WithSway => "with-sway",
        }
    }
    /// The other form.
    pub fn other(self) -> Self {
        match self {
            LateralAcceleration::Eq13 => LateralAcceleration::WithSway,
            LateralAcceleration::WithSway => LateralAcceleration::Eq13,
        }
    }
}

impl Default for ComfortSettings {
    fn default() -> Self {
        ComfortSettings {
            filter_hz: 0.3,
            jerk_window_s: 1.0,
            margin_s: 1.6,
            bump_stop_m: 0.060,
            lateral_acceleration: LateralAcceleration::Eq13,
        }
    }
}

impl ComfortSettings {
    /// Checks every field.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        c.positive("filter_hz", self.filter_hz, 50.0, "Hz");
        c.positive("jerk_window_s", self.jerk_window_s, 10.0, "s");
        c.range("margin_s", self.margin_s, 0.0, 30.0, "s");
        c.positive("bump_stop_m", self.bump_stop_m, 1.0, "m");
        c
    }
}

/// The signals the assessment needs, one value per recorded row.
#[derive(Debug, Clone, Default)]
pub struct Signals {
    /// Time (s), uniform step.
    pub t: Vec<f64>,
    /// Passenger lateral acceleration ÿ (m/s²).
    pub lat_acc: Vec<f64>,
    /// Its reference (1 − ρ)·ÿ_passive, eq 13 at θ_v^d (m/s²).
    pub lat_acc_ref: Vec<f64>,
    /// Absolute carbody roll speed φ̇ = θ̇_v + θ̇_o (rad/s).
    pub roll_speed: Vec<f64>,
    /// Its reference d/dt(θ_o + θ_v^d) (rad/s).
    pub roll_speed_ref: Vec<f64>,
    /// Secondary lateral deflection Δs (m).
    pub deflection: Vec<f64>,
    /// Curve transitions as (start, end) times (s).
    pub transitions: Vec<(f64, f64)>,
}

/// P_CT for both passenger postures.
#[derive(Debug, Clone, Copy, Serialize, Default, PartialEq)]
pub struct Pct {
    /// Standing (% of passengers).
    pub standing: f64,
    /// Seated (% of passengers).
    pub seated: f64,
    /// ÿ_m used (m/s²).
    pub lat_acc_m_s2: f64,
    /// y⃛_m used (m/s³).
    pub jerk_m_s3: f64,
    /// φ̇_m used (deg/s).
    pub roll_speed_deg_s: f64,
}

impl Pct {
    fn from_peaks(acc: f64, jerk: f64, roll_deg_s: f64) -> Self {
        Pct {
            standing: p_ct(&STANDING, acc, jerk, roll_deg_s),
            seated: p_ct(&SEATED, acc, jerk, roll_deg_s),
            lat_acc_m_s2: acc,
            jerk_m_s3: jerk,
            roll_speed_deg_s: roll_deg_s,
        }
    }
}

/// The comfort section of `summary.json`.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct Comfort {
    /// How P_CT (the headline) was evaluated.
    pub method: &'static str,
    /// RMS of ÿ − ÿ_ref over the run (%g).
    pub lat_acc_rms_dev_pct_g: f64,
    /// Largest |ÿ| (%g).
    pub lat_acc_peak_pct_g: f64,
    /// RMS of φ̇ − φ̇_ref (rad/s).
    pub roll_speed_rms_dev_rad_s: f64,
    /// Largest |φ̇| (rad/s).
    pub roll_speed_peak_rad_s: f64,
    /// Largest jerk over the jerk window (%g/s).
    pub jerk_peak_pct_g_s: f64,
    /// P_CT from whole-run peaks, as the paper evaluates it (the headline).
    pub p_ct: Pct,
    /// P_CT, per-transition EN 12299 evaluation on filtered signals (the worse transition).
    pub p_ct_en12299: Pct,
    /// Largest |secondary lateral deflection| (mm).
    pub deflection_peak_mm: f64,
    /// Its share of the bump-stop clearance (%).
    pub deflection_of_bump_stop_pct: f64,
    /// The passenger lateral acceleration every number above uses (`eq13`, the paper's, or
    /// `with-sway`).
    pub lateral_acceleration: &'static str,
    /// The same run's peak and whole-run-peak P_CT with the other form of the passenger
    /// lateral acceleration.
    pub other_form: OtherForm,
    /// Straight-track ride (EN 12299 mean comfort, lateral part; roll measures).
    pub ride: Ride,
}

/// Comfort with the passenger lateral acceleration not chosen in `[comfort]`.
#[derive(Debug, Clone, Copy, Serialize, Default, PartialEq)]
pub struct OtherForm {
    /// Its name (`with-sway` or `eq13`).
    pub lateral_acceleration: &'static str,
    /// Largest |ÿ| (%g).
    pub lat_acc_peak_pct_g: f64,
    /// P_CT from whole-run peaks.
    pub p_ct: Pct,
}

/// One comfort metric of Table 4: its short name (CSV column), its label (with unit) and where
/// it is in a [`Comfort`]. [`METRICS`] drives `compare`, the sweeps and their plots.
#[derive(Debug, Clone, Copy)]
pub struct Metric {
    /// Short name, as a CSV column.
    pub key: &'static str,
    /// Label with unit, as a table row.
    pub label: &'static str,
    /// The value in a run's comfort.
    pub get: fn(&Comfort) -> f64,
    /// Whether it is a P_CT (%), whose formula is meaningful only up to 100 %.
    pub is_p_ct: bool,
}

/// Every metric, in the paper's Table 4 order and then ours.
pub const METRICS: [Metric; 15] = [
    Metric {
        key: "lat_acc_rms_dev_pct_g",
        label: "Lateral acceleration RMS deviation (%g)",
        get: |c| c.lat_acc_rms_dev_pct_g,
        is_p_ct: false,
    },
    Metric {
        key: "lat_acc_peak_pct_g",
        label: "Lateral acceleration peak (%g)",
        get: |c| c.lat_acc_peak_pct_g,
        is_p_ct: false,
    },
    Metric {
        key: "roll_speed_rms_dev_rad_s",
        label: "Roll speed RMS deviation (rad/s)",
        get: |c| c.roll_speed_rms_dev_rad_s,
        is_p_ct: false,
    },
    Metric {
        key: "roll_speed_peak_rad_s",
        label: "Roll speed peak (rad/s)",
        get: |c| c.roll_speed_peak_rad_s,
        is_p_ct: false,
    },
    Metric {
        key: "jerk_peak_pct_g_s",
        label: "Peak jerk level (%g/s)",
        get: |c| c.jerk_peak_pct_g_s,
        is_p_ct: false,
    },
    Metric {
        key: "p_ct_standing",
        label: "P_CT standing, whole-run peaks as the paper (%)",
        get: |c| c.p_ct.standing,
        is_p_ct: true,
    },
    Metric {
        key: "p_ct_seated",
        label: "P_CT seated, whole-run peaks as the paper (%)",
        get: |c| c.p_ct.seated,
        is_p_ct: true,
    },
    Metric {
        key: "p_ct_en12299_standing",
        label: "P_CT standing, EN 12299 per transition (%)",
        get: |c| c.p_ct_en12299.standing,
        is_p_ct: true,
    },
    Metric {
        key: "p_ct_en12299_seated",
        label: "P_CT seated, EN 12299 per transition (%)",
        get: |c| c.p_ct_en12299.seated,
        is_p_ct: true,
    },
    Metric {
        key: "deflection_peak_mm",
        label: "Secondary lateral deflection peak (mm, bump stop 60)",
        get: |c| c.deflection_peak_mm,
        is_p_ct: false,
    },
    Metric {
        key: "p_ct_other_form_standing",
        label: "P_CT standing, whole-run peaks, other ÿ form (%)",
        get: |c| c.other_form.p_ct.standing,
        is_p_ct: true,
    },
    Metric {
        key: "n_mv_lateral",
        label: "EN 12299 N_MV, lateral part 6·a_YP95^Wd",
        get: |c| c.ride.n_mv_lateral,
        is_p_ct: false,
    },
    Metric {
        key: "a_y_rms_wd_m_s2",
        label: "Wd-weighted carbody lateral acceleration RMS (m/s²)",
        get: |c| c.ride.a_y_rms_wd_m_s2,
        is_p_ct: false,
    },
    Metric {
        key: "tilt_error_rms_deg",
        label: "Tilt error θ_v − θ_v^d RMS (deg)",
        get: |c| c.ride.tilt_error_rms_deg,
        is_p_ct: false,
    },
    Metric {
        key: "roll_acc_rms_rad_s2",
        label: "Carbody roll acceleration RMS (rad/s²)",
        get: |c| c.ride.roll_acc_rms_rad_s2,
        is_p_ct: false,
    },
];

/// The index in [`METRICS`] of `key` (a compile-time name of this module's table).
pub fn metric(key: &str) -> usize {
    METRICS
        .iter()
        .position(|m| m.key == key)
        .unwrap_or(usize::MAX)
}

/// A run's values in [`METRICS`] order.
pub fn values(c: &Comfort) -> [f64; 15] {
    METRICS.map(|m| (m.get)(c))
}

/// Largest |x[i+k] − x[i]| over a stream of values, k = round(w/dt): the slope of `x` over the
/// window `w`, as [`slope_peak`] computes it on a slice, with a ring of the last k values.
struct SlopePeak {
    k: usize,
    ring: std::collections::VecDeque<f64>,
    best: f64,
}

impl SlopePeak {
    fn new(dt: f64, w: f64) -> Self {
        let k = ((w / dt).round() as usize).max(1);
        SlopePeak {
            k,
            ring: std::collections::VecDeque::with_capacity(k + 1),
            best: 0.0,
        }
    }
    fn push(&mut self, x: f64) {
        if self.ring.len() == self.k {
            if let Some(old) = self.ring.pop_front() {
                self.best = self.best.max((x - old).abs());
            }
        }
        self.ring.push_back(x);
    }
    /// The slope (per second) at step `dt`.
    fn value(&self, dt: f64) -> f64 {
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

/// Second-order Butterworth low-pass (bilinear transform), one sample at a time, from rest at
/// the first sample's value.
#[derive(Debug, Clone)]
pub struct LowPass {
    b: [f64; 3],
    a: [f64; 2],
    /// x[k−1], x[k−2], y[k−1], y[k−2]; `None` before the first sample.
    state: Option<[f64; 4]>,
}

impl LowPass {
    /// A filter with cut-off `fc` (Hz) at step `dt` (s).
    pub fn new(dt: f64, fc: f64) -> Self {
        let k = (std::f64::consts::PI * fc * dt).tan();
        let q = std::f64::consts::SQRT_2;
        let norm = 1.0 / (1.0 + q * k + k * k);
        let b0 = k * k * norm;
        LowPass {
            b: [b0, 2.0 * b0, b0],
            a: [2.0 * (k * k - 1.0) * norm, (1.0 - q * k + k * k) * norm],
            state: None,
        }
    }

    /// Filters the next sample.
    pub fn step(&mut self, x0: f64) -> f64 {
        let [x1, x2, y1, y2] = self.state.unwrap_or([x0; 4]);
        let y0 = self.b[0] * x0 + self.b[1] * x1 + self.b[2] * x2 - self.a[0] * y1 - self.a[1] * y2;
        self.state = Some([x0, x1, y0, y1]);
        y0
    }
}

/// [`LowPass`] over a whole series.
pub fn low_pass(x: &[f64], dt: f64, fc: f64) -> Vec<f64> {
    let mut f = LowPass::new(dt, fc);
    x.iter().map(|v| f.step(*v)).collect()
}

/// The comfort signals at one instant (the fields of [`Signals`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Sample {
    /// Time (s).
    pub t: f64,
    /// ÿ (m/s²).
    pub lat_acc: f64,
    /// ÿ reference (m/s²).
    pub lat_acc_ref: f64,
    /// φ̇ (rad/s).
    pub roll_speed: f64,
    /// φ̇ reference (rad/s).
    pub roll_speed_ref: f64,
    /// Δs (m).
    pub deflection: f64,
    /// The other form of the passenger lateral acceleration (m/s²); see
    /// [`LateralAcceleration`].
    pub lat_acc_other: f64,
    /// Tilt error θ_v − θ_v^d (rad).
    pub tilt_error: f64,
}

/// One curve transition's EN 12299 evaluation as the samples pass: the filtered peaks inside
/// the transition extended by the margin.
struct TransitionWindow {
    from: f64,
    to: f64,
    seen: bool,
    acc: f64,
    roll: f64,
    jerk: SlopePeak,
}

/// The comfort assessment of a run, one sample at a time in constant memory: what [`assess`]
/// computes on whole series, for runs of any length read straight from `timeseries.csv`.
pub struct Assessor {
    c: ComfortSettings,
    dt: f64,
    n: usize,
    acc_peak: f64,
    roll_peak: f64,
    defl_peak: f64,
    jerk: SlopePeak,
    acc_dev: (f64, usize),
    roll_dev: (f64, usize),
    fa: LowPass,
    fr: LowPass,
    windows: Vec<TransitionWindow>,
    other_peak: f64,
    other_jerk: SlopePeak,
    ride: RideAssessor,
}

impl Assessor {
    /// An assessment at step `dt` (s) with the curve `transitions` as (start, end) times.
    pub fn new(dt: f64, transitions: &[(f64, f64)], c: &ComfortSettings) -> Self {
        Assessor {
            c: c.clone(),
            dt,
            n: 0,
            acc_peak: 0.0,
            roll_peak: 0.0,
            defl_peak: 0.0,
            jerk: SlopePeak::new(dt, c.jerk_window_s),
            acc_dev: (0.0, 0),
            roll_dev: (0.0, 0),
            fa: LowPass::new(dt, c.filter_hz),
            fr: LowPass::new(dt, c.filter_hz),
            windows: transitions
                .iter()
                .map(|&(t0, t1)| TransitionWindow {
                    from: t0 - c.margin_s,
                    to: t1 + c.margin_s,
                    seen: false,
                    acc: 0.0,
                    roll: 0.0,
                    jerk: SlopePeak::new(dt, c.jerk_window_s),
                })
                .collect(),
            other_peak: 0.0,
            other_jerk: SlopePeak::new(dt, c.jerk_window_s),
            ride: RideAssessor::new(dt),
        }
    }

    /// Takes the next sample.
    pub fn push(&mut self, x: &Sample) {
        self.n += 1;
        self.acc_peak = self.acc_peak.max(x.lat_acc.abs());
        self.roll_peak = self.roll_peak.max(x.roll_speed.abs());
        self.defl_peak = self.defl_peak.max(x.deflection.abs());
        self.jerk.push(x.lat_acc);
        let d = x.lat_acc - x.lat_acc_ref;
        self.acc_dev.0 += d * d;
        self.acc_dev.1 += 1;
        let d = x.roll_speed - x.roll_speed_ref;
        self.roll_dev.0 += d * d;
        self.roll_dev.1 += 1;
        self.other_peak = self.other_peak.max(x.lat_acc_other.abs());
        self.other_jerk.push(x.lat_acc_other);
        // The ride takes the carbody's lateral acceleration as an accelerometer measures it.
        let carbody = match self.c.lateral_acceleration {
            LateralAcceleration::WithSway => x.lat_acc,
            LateralAcceleration::Eq13 => x.lat_acc_other,
        };
        self.ride.push(x, carbody);
        let fa = self.fa.step(x.lat_acc);
        let fr = self.fr.step(x.roll_speed);
        for w in &mut self.windows {
            if x.t >= w.from && x.t <= w.to {
                w.seen = true;
                w.acc = w.acc.max(fa.abs());
                w.roll = w.roll.max(fr.abs());
                w.jerk.push(fa);
            }
        }
    }

    /// The assessment of every sample taken.
    pub fn finish(&self) -> Comfort {
        if self.n < 3 {
            return Comfort {
                method: "whole-run-peaks",
                lateral_acceleration: self.c.lateral_acceleration.name(),
                ..Default::default()
            };
        }
        let dt = self.dt;
        let p_ct = Pct::from_peaks(
            self.acc_peak,
            self.jerk.value(dt),
            self.roll_peak.to_degrees(),
        );
        let mut worst = Pct::default();
        for w in self.windows.iter().filter(|w| w.seen) {
            let p = Pct::from_peaks(w.acc, w.jerk.value(dt), w.roll.to_degrees());
            if p.standing >= worst.standing {
                worst = p;
            }
        }
        let rms = |(s, n): (f64, usize)| if n == 0 { 0.0 } else { (s / n as f64).sqrt() };
        let defl = self.defl_peak;
        Comfort {
            method: "whole-run-peaks",
            lat_acc_rms_dev_pct_g: 100.0 / G * rms(self.acc_dev),
            lat_acc_peak_pct_g: 100.0 * self.acc_peak / G,
            roll_speed_rms_dev_rad_s: rms(self.roll_dev),
            roll_speed_peak_rad_s: self.roll_peak,
            jerk_peak_pct_g_s: 100.0 * self.jerk.value(dt) / G,
            p_ct,
            p_ct_en12299: worst,
            deflection_peak_mm: defl * 1e3,
            deflection_of_bump_stop_pct: 100.0 * defl / self.c.bump_stop_m,
            lateral_acceleration: self.c.lateral_acceleration.name(),
            other_form: OtherForm {
                lateral_acceleration: self.c.lateral_acceleration.other().name(),
                lat_acc_peak_pct_g: 100.0 * self.other_peak / G,
                p_ct: Pct::from_peaks(
                    self.other_peak,
                    self.other_jerk.value(dt),
                    self.roll_peak.to_degrees(),
                ),
            },
            ride: self.ride.finish(),
        }
    }
}

impl Sample {
    /// The same instant under the ideal tilt: the body follows the tilt command of eq 18
    /// exactly (θ_v = θ_v^d), so the passenger feels ÿ_ref and rolls at φ̇_ref. The deflection
    /// is not simulated (0).
    pub fn ideal(&self) -> Sample {
        Sample {
            t: self.t,
            lat_acc: self.lat_acc_ref,
            lat_acc_ref: self.lat_acc_ref,
            roll_speed: self.roll_speed_ref,
            roll_speed_ref: self.roll_speed_ref,
            deflection: 0.0,
            lat_acc_other: self.lat_acc_ref,
            tilt_error: 0.0,
        }
    }
}

impl Signals {
    /// Sample `k`.
    pub fn sample(&self, k: usize) -> Sample {
        Sample {
            t: self.t[k],
            lat_acc: self.lat_acc[k],
            lat_acc_ref: self.lat_acc_ref[k],
            roll_speed: self.roll_speed[k],
            roll_speed_ref: self.roll_speed_ref[k],
            deflection: self.deflection[k],
            lat_acc_other: self.lat_acc[k],
            tilt_error: 0.0,
        }
    }
}

/// Assesses a run held in memory (step from its time axis).
pub fn assess(s: &Signals, c: &ComfortSettings) -> Comfort {
    let n = s.t.len();
    let dt = if n >= 2 {
        (s.t[n - 1] - s.t[0]) / (n - 1) as f64
    } else {
        1.0
    };
    let mut a = Assessor::new(dt, &s.transitions, c);
    (0..n).for_each(|k| a.push(&s.sample(k)));
    a.finish()
}

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

const SQRT_HALF: f64 = std::f64::consts::FRAC_1_SQRT_2;

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
type Analog = ([f64; 3], [f64; 3], f64);

impl Weighting {
    /// The analog sections (numerator and denominator coefficients [s⁰, s¹, s²]).
    fn sections(&self) -> Vec<Analog> {
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
    /// (b0, b1, b2, a1, a2) and the state (x1, x2, y1, y2) of each section.
    biquads: Vec<([f64; 5], [f64; 4])>,
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
                (
                    [
                        nb[0] / na[0],
                        nb[1] / na[0],
                        nb[2] / na[0],
                        na[1] / na[0],
                        na[2] / na[0],
                    ],
                    [0.0; 4],
                )
            })
            .collect();
        WeightingFilter { k: w.k, biquads }
    }

    /// Filters the next sample.
    pub fn step(&mut self, x: f64) -> f64 {
        let mut v = x;
        for (c, st) in &mut self.biquads {
            let y = c[0] * v + c[1] * st[0] + c[2] * st[1] - c[3] * st[2] - c[4] * st[3];
            *st = [v, st[0], y, st[2]];
            v = y;
        }
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
}

/// The ride assessment, one sample at a time.
struct RideAssessor {
    dt: f64,
    wd: WeightingFilter,
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
    fn new(dt: f64) -> Self {
        RideAssessor {
            dt,
            wd: WeightingFilter::new(&WD, dt),
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

    fn push(&mut self, x: &Sample, carbody_lat_acc: f64) {
        let a = self.wd.step(carbody_lat_acc);
        self.window_sum += a * a;
        self.total.0 += a * a;
        self.total.1 += 1;
        self.in_window += 1;
        if self.in_window == self.per_window {
            self.window_rms
                .push((self.window_sum / self.per_window as f64).sqrt());
            self.in_window = 0;
            self.window_sum = 0.0;
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

    fn finish(&self) -> Ride {
        let rms = |(s, n): (f64, usize)| if n == 0 { 0.0 } else { (s / n as f64).sqrt() };
        let p95 = percentile(&self.window_rms, 0.95);
        Ride {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_metric_key_is_distinct_and_found() {
        for (i, m) in METRICS.iter().enumerate() {
            assert_eq!(metric(m.key), i);
        }
        assert_eq!(METRICS.iter().filter(|m| m.is_p_ct).count(), 5);
    }

    #[test]
    fn p_ct_reproduces_the_papers_pi_and_lqg_columns_from_their_peaks() {
        // Table 4: peaks in %g, %g/s and rad/s; P_CT printed alongside.
        let from_table = |acc_pct: f64, jerk_pct: f64, roll: f64| {
            Pct::from_peaks(acc_pct * G / 100.0, jerk_pct * G / 100.0, roll.to_degrees())
        };
        let pi = from_table(8.491, 4.373, 0.118);
        assert!(
            (pi.standing - 35.975).abs() < 0.3,
            "PI standing {}",
            pi.standing
        );
        assert!((pi.seated - 8.397).abs() < 0.3, "PI seated {}", pi.seated);
        let lqg = from_table(9.796, 4.893, 0.100);
        assert!(
            (lqg.standing - 36.412).abs() < 0.3,
            "LQG standing {}",
            lqg.standing
        );
        assert!(
            (lqg.seated - 9.448).abs() < 0.3,
            "LQG seated {}",
            lqg.seated
        );
        // Below the threshold only the roll term remains: D·φ̇^E.
        assert_eq!(p_ct(&STANDING, 0.1, 0.1, 0.0), 0.0);
        assert!((p_ct(&SEATED, 0.0, 0.0, 2.0) - 0.120 * 2f64.powf(1.626)).abs() < 1e-12);
    }

    fn uniform(n: usize, dt: f64, f: impl Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let x = t.iter().map(|&t| f(t)).collect();
        (t, x)
    }

    #[test]
    fn metrics_of_a_constant_a_ramp_and_a_sinusoid() {
        let dt = 1e-3;
        let c = ComfortSettings::default();
        // Constant: RMS deviation = the offset, peak = the value, no jerk.
        let (t, x) = uniform(5000, dt, |_| 0.5);
        let s = Signals {
            lat_acc_ref: vec![0.4; t.len()],
            roll_speed: vec![0.0; t.len()],
            roll_speed_ref: vec![0.0; t.len()],
            deflection: vec![-0.03; t.len()],
            t,
            lat_acc: x,
            transitions: vec![],
        };
        let m = assess(&s, &c);
        assert!((m.lat_acc_rms_dev_pct_g - 100.0 * 0.1 / G).abs() < 1e-12);
        assert!((m.lat_acc_peak_pct_g - 100.0 * 0.5 / G).abs() < 1e-12);
        assert_eq!(m.jerk_peak_pct_g_s, 0.0);
        assert!((m.deflection_peak_mm - 30.0).abs() < 1e-9);
        assert!((m.deflection_of_bump_stop_pct - 50.0).abs() < 1e-9);
        // Ramp of 0.4 m/s³: the jerk is the slope; the filtered signal of a ramp lags but
        // keeps the slope, so the per-transition jerk is the same once the filter settles.
        let (t, x) = uniform(20_000, dt, |t| 0.4 * t);
        assert!((slope_peak(&x, dt, 1.0) - 0.4).abs() < 1e-9);
        let f = low_pass(&x, dt, 0.3);
        let late = slope_peak(&f[10_000..], dt, 1.0);
        assert!((late - 0.4).abs() < 1e-4, "{late}");
        // Sinusoid of amplitude a: RMS a/√2 about a zero reference, peak a; the 1 s slope of
        // sin(ωt) peaks at 2 sin(ω/2)·a / 1 s; a 0.3 Hz filter passes 0.05 Hz nearly whole.
        let (a, w) = (0.2, std::f64::consts::TAU * 0.05);
        let (_, x) = uniform(t.len(), dt, |t| a * (w * t).sin());
        let s = Signals {
            lat_acc_ref: vec![0.0; t.len()],
            roll_speed: x.clone(),
            roll_speed_ref: vec![0.0; t.len()],
            deflection: vec![0.0; t.len()],
            lat_acc: x.clone(),
            t: t.clone(),
            transitions: vec![(5.0, 15.0)],
        };
        let m = assess(&s, &c);
        assert!((m.lat_acc_rms_dev_pct_g - 100.0 * a / 2f64.sqrt() / G).abs() < 1e-4);
        assert!((m.roll_speed_rms_dev_rad_s - a / 2f64.sqrt()).abs() < 1e-5);
        assert!((m.roll_speed_peak_rad_s - a).abs() < 1e-6);
        let j = 2.0 * (w / 2.0).sin() * a;
        assert!(
            (m.jerk_peak_pct_g_s - 100.0 * j / G).abs() < 1e-3,
            "{}",
            m.jerk_peak_pct_g_s
        );
        let gain = 1.0 / (1.0 + (0.05f64 / 0.3).powi(4)).sqrt();
        assert!((m.p_ct_en12299.lat_acc_m_s2 - a * gain).abs() < 0.005 * a);
    }

    #[test]
    fn weightings_match_their_published_values() {
        // ISO 8041's reference values |W| at its reference frequency 100 rad/s (15.915 Hz),
        // as an instrument maker tabulates them (Zetlab, "frequency weighting functions"):
        // 4 significant digits, so a tolerance of half the last digit plus 1e-4.
        let f_ref = 100.0 / std::f64::consts::TAU;
        for (w, v) in [(WD, 0.1261), (WB, 0.8126), (WC, 0.5145)] {
            let g = w.gain(f_ref);
            assert!(
                (g - v).abs() < 1.5e-4,
                "{} at 15.915 Hz: {g}, published {v}",
                w.name
            );
        }
    }

    #[test]
    fn weighting_filters_at_one_millisecond_follow_their_transfer_functions() {
        // Steady-state amplitude of a sinusoid through the discrete cascade against |H(j2πf)|
        // of the continuous weighting: the bilinear transform warps frequencies by
        // tan(πfT)/(πfT) − 1 < 0.2 % up to 20 Hz at T = 1 ms, and the amplitude read over
        // whole periods after 40 s of settling (the 0.4 Hz high-pass decays in about 1 s)
        // is exact to 1e-4; tolerance 0.5 %.
        let dt = 1e-3;
        for w in [WD, WB, WC] {
            for f in [0.5, 1.0, 2.0, 4.0, 8.0, 16.0] {
                let mut flt = WeightingFilter::new(&w, dt);
                let n = (60.0 / dt) as usize;
                let mut peak: f64 = 0.0;
                for i in 0..n {
                    let t = i as f64 * dt;
                    let y = flt.step((std::f64::consts::TAU * f * t).sin());
                    if t > 40.0 {
                        peak = peak.max(y.abs());
                    }
                }
                let g = w.gain(f);
                assert!(
                    (peak / g - 1.0).abs() < 5e-3,
                    "{} at {f} Hz: filter {peak}, transfer function {g}",
                    w.name
                );
            }
        }
    }

    #[test]
    fn ride_index_of_a_sinusoid_is_six_times_its_weighted_rms() {
        // A 1 Hz carbody lateral acceleration of amplitude 0.1 m/s² for 5 minutes: every 5 s
        // window has the RMS 0.1·|Wd(1 Hz)|/√2 (after the filter settles in the first), so
        // the 95th percentile is that value and N_MV's lateral part is 6 times it.
        let dt = 1e-3;
        let mut r = RideAssessor::new(dt);
        let n = (300.0 / dt) as usize;
        for i in 0..n {
            let t = i as f64 * dt;
            let a = 0.1 * (std::f64::consts::TAU * t).sin();
            r.push(&Sample::default(), a);
        }
        let ride = r.finish();
        let expect = 0.1 * WD.gain(1.0) / 2f64.sqrt();
        assert_eq!(ride.windows, 60);
        assert!(
            (ride.a_y_p95_wd_m_s2 - expect).abs() < 1e-3 * expect,
            "{ride:?}"
        );
        assert!((ride.n_mv_lateral - 6.0 * expect).abs() < 6e-3 * expect);
        assert_eq!(percentile(&[3.0, 1.0, 2.0], 0.5), 2.0);
        assert!((percentile(&[0.0, 1.0], 0.95) - 0.95).abs() < 1e-15);
    }
}
