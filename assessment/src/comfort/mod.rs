//! Ride comfort from a run's recorded signals (the rows of Table 4).
//!
//! P_CT (EN 12299, comfort on curve transitions), in percent of passengers:
//! `P_CT = max(A·ÿ_m + B·y⃛_m − C, 0) + D·φ̇_m^E`, ÿ in m/s², y⃛ in m/s³, φ̇ in deg/s, with the
//! constants of `model-notes.md` for standing and seated passengers. Two evaluations:
//! * `en12299-transition` (the standard's, the headline): per curve transition, on signals
//!   low-pass filtered at `filter_hz` (0.3 Hz, second-order Butterworth); ÿ_m and φ̇_m the
//!   largest filtered values in the transition extended by `margin_s` (1.6 s) each side, y⃛_m
//!   the largest change of the filtered ÿ over `jerk_window_s` (1 s) divided by it. The worse
//!   transition is reported.
//! * `whole-run-peaks` (the paper's, to reproduce its Table 4): ÿ_m, y⃛_m and φ̇_m are
//!   whole-run peaks of the signals as simulated; the jerk is the slope of ÿ over
//!   `jerk_window_s`, the way a quasi-static transition jerk is read off a plot.
//!
//! The two can rank controllers differently: the paper's form sees the unfiltered roll-speed
//! peaks at the ramp corners, which the standard's 0.3 Hz filter removes.
//!
//! The carbody roll speed is the absolute one, φ̇ = θ̇_v + θ̇_o (θ_v is relative to the track).
//!
//! Parts: `sample` (the signals at one instant), `assessor` (P_CT and the peaks, one sample at
//! a time), `ride` (the ride indices beside P_CT), `sickness` (the motion-sickness doses), `position` (the signals where a passenger
//! sits), `filters` (the low-pass and slope filters they share); this file holds the settings,
//! the results and [`assess`] on whole signals.

use serde::{Deserialize, Serialize};

use tiltsim_protocol::settings::Checker;

mod assessor;
mod filters;
mod position;
mod ride;
mod sample;
mod sickness;

pub use assessor::*;
pub use filters::*;
pub use position::*;
pub use ride::*;
pub use sample::Sample;
pub use sickness::*;

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
    /// The passenger lateral acceleration comfort is computed from: `eq13` (the paper's,
    /// default) or `with-sway` (eq 13 plus the body's sway acceleration). The other form's
    /// P_CT and peak are reported beside it (`comfort.other_form`).
    pub lateral_acceleration: LateralAcceleration,
    /// Where passengers are: the comfort at each of these points of the body is reported
    /// beside the centre of gravity's (`comfort.positions`).
    pub positions: Vec<Position>,
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
            lateral_acceleration: LateralAcceleration::Eq13,
            positions: Position::defaults(),
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
        Position::validate_all(&self.positions, &mut c);
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
    #[serde(rename = "standing_pct")]
    pub standing: f64,
    /// Seated (% of passengers).
    #[serde(rename = "seated_pct")]
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
    /// How the headline P_CT (`p_ct_en12299`) was evaluated: `en12299-transition`.
    pub method: &'static str,
    /// P_CT, the standard's evaluation: per transition on 0.3 Hz filtered signals, the worse
    /// transition (the headline).
    pub p_ct_en12299: Pct,
    /// P_CT from whole-run peaks of the unfiltered signals, as the paper evaluates it (the
    /// reproduction of its Table 4).
    pub p_ct_paper: Pct,
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
    /// The comfort where passengers are (`[comfort] positions`).
    pub positions: Vec<PositionComfort>,
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
    /// Unit symbol in ASCII (`%g`: percent of g; `1`: a pure number), as `columns.csv`
    /// gives it.
    pub unit: &'static str,
    /// The value in a run's comfort.
    pub get: fn(&Comfort) -> f64,
    /// Whether it is a P_CT (%), whose formula is meaningful only up to 100 %.
    pub is_p_ct: bool,
}

/// Every metric: the standard's P_CT first, then the paper's Table 4 rows in its order (its
/// P_CT as the paper evaluates it), then ours.
pub const METRICS: [Metric; 15] = [
    Metric {
        key: "p_ct_en12299_standing_pct",
        label: "P_CT standing, EN 12299 (per transition, 0.3 Hz filtered) (%)",
        unit: "%",
        get: |c| c.p_ct_en12299.standing,
        is_p_ct: true,
    },
    Metric {
        key: "p_ct_en12299_seated_pct",
        label: "P_CT seated, EN 12299 (per transition, 0.3 Hz filtered) (%)",
        unit: "%",
        get: |c| c.p_ct_en12299.seated,
        is_p_ct: true,
    },
    Metric {
        key: "lat_acc_rms_dev_pct_g",
        label: "Lateral acceleration RMS deviation (%g)",
        unit: "%g",
        get: |c| c.lat_acc_rms_dev_pct_g,
        is_p_ct: false,
    },
    Metric {
        key: "lat_acc_peak_pct_g",
        label: "Lateral acceleration peak (%g)",
        unit: "%g",
        get: |c| c.lat_acc_peak_pct_g,
        is_p_ct: false,
    },
    Metric {
        key: "roll_speed_rms_dev_rad_s",
        label: "Roll speed RMS deviation (rad/s)",
        unit: "rad/s",
        get: |c| c.roll_speed_rms_dev_rad_s,
        is_p_ct: false,
    },
    Metric {
        key: "roll_speed_peak_rad_s",
        label: "Roll speed peak (rad/s)",
        unit: "rad/s",
        get: |c| c.roll_speed_peak_rad_s,
        is_p_ct: false,
    },
    Metric {
        key: "jerk_peak_pct_g_s",
        label: "Peak jerk level (%g/s)",
        unit: "%g/s",
        get: |c| c.jerk_peak_pct_g_s,
        is_p_ct: false,
    },
    Metric {
        key: "p_ct_paper_standing_pct",
        label: "P_CT standing, the paper's Table 4 form: whole-run peaks (%)",
        unit: "%",
        get: |c| c.p_ct_paper.standing,
        is_p_ct: true,
    },
    Metric {
        key: "p_ct_paper_seated_pct",
        label: "P_CT seated, the paper's Table 4 form: whole-run peaks (%)",
        unit: "%",
        get: |c| c.p_ct_paper.seated,
        is_p_ct: true,
    },
    Metric {
        key: "deflection_peak_mm",
        label: "Secondary lateral deflection peak (mm, bump stop 60)",
        unit: "mm",
        get: |c| c.deflection_peak_mm,
        is_p_ct: false,
    },
    Metric {
        key: "p_ct_other_form_standing_pct",
        label: "P_CT standing, whole-run peaks, other ÿ form (%)",
        unit: "%",
        get: |c| c.other_form.p_ct.standing,
        is_p_ct: true,
    },
    Metric {
        key: "n_mv_lateral",
        label: "EN 12299 N_MV, lateral part 6·a_YP95^Wd",
        unit: "1",
        get: |c| c.ride.n_mv_lateral,
        is_p_ct: false,
    },
    Metric {
        key: "a_y_rms_wd_m_s2",
        label: "Wd-weighted carbody lateral acceleration RMS (m/s²)",
        unit: "m/s2",
        get: |c| c.ride.a_y_rms_wd_m_s2,
        is_p_ct: false,
    },
    Metric {
        key: "tilt_error_rms_deg",
        label: "Tilt error θ_v − θ_v^d RMS (deg)",
        unit: "deg",
        get: |c| c.ride.tilt_error_rms_deg,
        is_p_ct: false,
    },
    Metric {
        key: "roll_acc_rms_rad_s2",
        label: "Carbody roll acceleration RMS (rad/s²)",
        unit: "rad/s2",
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

#[cfg(test)]
mod tests {
    use super::*;

    const TEST_BODY: Body = Body {
        bump_stop_m: 0.060,
        cog_height_m: 1.52,
    };

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
        let m = assess(&s, &c, TEST_BODY);
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
        let m = assess(&s, &c, TEST_BODY);
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
