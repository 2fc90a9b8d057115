//! [`Assessor`]: P_CT and the peaks of a run, one sample per plant step, both evaluations at
//! once; [`assess`] on whole signals.

use super::filters::{LowPass, SlopePeak};
use super::ride::RideAssessor;
use super::sample::Sample;
use super::{
    Comfort, ComfortSettings, LateralAcceleration, OtherForm, Pct, Position, PositionComfort,
    Signals, G,
};

/// The body the signals are of: what the assessment needs beyond its settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    /// Secondary lateral bump-stop clearance (m).
    pub bump_stop_m: f64,
    /// Height of the carbody's centre of gravity above the rail, h_gv (m): where the signals
    /// are taken.
    pub cog_height_m: f64,
}

/// One curve transition's EN 12299 evaluation as the samples pass: the filtered peaks inside
/// the transition extended by the margin.
pub(super) struct TransitionWindow {
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
    clearance: f64,
    cog_height: f64,
    last_roll: Option<f64>,
    positions: Vec<(Position, Assessor)>,
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
    /// An assessment at step `dt` (s) with the curve `transitions` as (start, end) times, of
    /// `body`: at its centre of gravity and at each of `c.positions`.
    pub fn new(dt: f64, transitions: &[(f64, f64)], c: &ComfortSettings, body: Body) -> Self {
        let at_point = ComfortSettings {
            positions: Vec::new(),
            ..c.clone()
        };
        Assessor {
            positions: c
                .positions
                .iter()
                .map(|p| (p.clone(), Assessor::new(dt, transitions, &at_point, body)))
                .collect(),
            c: at_point.clone(),
            clearance: body.bump_stop_m,
            cog_height: body.cog_height_m,
            last_roll: None,
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
        if !self.positions.is_empty() {
            // φ̈ by the backward difference of φ̇ (continuous across the ramp corners).
            let roll_acc = self.last_roll.map_or(0.0, |p| (x.roll_speed - p) / self.dt);
            self.last_roll = Some(x.roll_speed);
            for (p, a) in &mut self.positions {
                a.push(&p.moved(x, roll_acc, self.cog_height));
            }
        }
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
                method: "en12299-transition",
                lateral_acceleration: self.c.lateral_acceleration.name(),
                positions: self.position_comfort(),
                ..Default::default()
            };
        }
        let dt = self.dt;
        let p_ct_paper = Pct::from_peaks(
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
            method: "en12299-transition",
            lat_acc_rms_dev_pct_g: 100.0 / G * rms(self.acc_dev),
            lat_acc_peak_pct_g: 100.0 * self.acc_peak / G,
            roll_speed_rms_dev_rad_s: rms(self.roll_dev),
            roll_speed_peak_rad_s: self.roll_peak,
            jerk_peak_pct_g_s: 100.0 * self.jerk.value(dt) / G,
            p_ct_en12299: worst,
            p_ct_paper,
            deflection_peak_mm: defl * 1e3,
            deflection_of_bump_stop_pct: 100.0 * defl / self.clearance,
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
            positions: self.position_comfort(),
        }
    }

    fn position_comfort(&self) -> Vec<PositionComfort> {
        self.positions
            .iter()
            .map(|(p, a)| {
                let c = a.finish();
                PositionComfort {
                    name: p.name.clone(),
                    height_m: p.height_m,
                    offset_m: p.offset_m,
                    p_ct_en12299: c.p_ct_en12299,
                    p_ct_paper: c.p_ct_paper,
                    lat_acc_peak_pct_g: c.lat_acc_peak_pct_g,
                    ride: c.ride,
                }
            })
            .collect()
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
            vertical: 0.0,
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
            vertical: 0.0,
        }
    }
}

/// Assesses a run of `body` held in memory (step from its time axis).
pub fn assess(s: &Signals, c: &ComfortSettings, body: Body) -> Comfort {
    let n = s.t.len();
    let dt = if n >= 2 {
        (s.t[n - 1] - s.t[0]) / (n - 1) as f64
    } else {
        1.0
    };
    let mut a = Assessor::new(dt, &s.transitions, c, body);
    (0..n).for_each(|k| a.push(&s.sample(k)));
    a.finish()
}
