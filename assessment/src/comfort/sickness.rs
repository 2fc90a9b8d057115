//! Motion sickness along a ride: ISO 2631-1's motion sickness dose value (MSDV) through its
//! Wf weighting, and the low-frequency lateral and roll doses of the tilting-train studies.
//!
//! * `MSDV_z = (∫ a_wf,z(t)² dt)^½` (m/s^1.5), a_wf,z the vertical acceleration through Wf
//!   (ISO 2631-1:1997, 9.2.2 and Annex D); ISO 2631-1 Annex D puts the share of unadapted adults
//!   who may vomit at `MSI = K_m·MSDV_z`, K_m = 1/3 for a mixed population.
//! * `MSDV_y`: the same dose of the carbody lateral acceleration through Wf, and `MSDV_φ̈`: of
//!   the carbody roll acceleration through Wf (rad/s^1.5). Förstberg, Andersson & Ledin (1998),
//!   "Influence of different conditions for tilt compensation on symptoms of motion sickness in
//!   tilting trains", Brain Research Bulletin 47(5) 525-535, computed such doses on SJ X2000
//!   rides: the symptoms correlated poorly with the lateral (and vertical) doses and well with
//!   the roll-acceleration dose (r² = 0.43), and 55 % instead of 70 % compensation cut the
//!   symptoms by 25-40 %.
//!
//! A dose over a trip of T seconds is given for the trip and per hour, `MSDV·(3600/T)^½`: the
//! dose an hour of the same motion gives (doses of parts add in their squares).

use serde::Serialize;

use super::ride::{Weighting, WeightingFilter, SQRT_HALF};
use super::sample::Sample;

/// Wf, ISO 2631-1's weighting for motion sickness (vertical acceleration, 0.1-0.5 Hz):
/// f1 = 0.08 Hz, f2 = 0.63 Hz, no f3, f4 = 0.25 Hz (Q4 = 0.86), f5 = 0.0625 Hz (Q5 = 0.80),
/// f6 = 0.1 Hz (Q6 = 0.80), Q1 = Q2 = 1/√2 (ISO 2631-1:1997, Table A.1 of Annex A).
pub const WF: Weighting = Weighting {
    name: "Wf",
    f1: 0.08,
    q1: SQRT_HALF,
    f2: 0.63,
    q2: SQRT_HALF,
    f3: f64::INFINITY,
    f4: 0.25,
    q4: 0.86,
    f5: 0.0625,
    q5: 0.80,
    f6: 0.1,
    q6: 0.80,
    k: 1.0,
};

/// ISO 2631-1 Annex D's K_m for a mixed population of unadapted adults.
pub const K_M: f64 = 1.0 / 3.0;

/// A signal's Wf dose, one sample at a time from rest: `∫ a_wf² dt`.
#[derive(Debug, Clone)]
pub struct DoseMeter {
    dt: f64,
    filter: WeightingFilter,
    sum: f64,
}

impl DoseMeter {
    /// A meter at step `dt` (s).
    pub fn new(dt: f64) -> Self {
        DoseMeter {
            dt,
            filter: WeightingFilter::new(&WF, dt),
            sum: 0.0,
        }
    }
    /// Takes the next sample.
    pub fn push(&mut self, x: f64) {
        let w = self.filter.step(x);
        self.sum += w * w * self.dt;
    }
    /// `∫ a_wf² dt` so far.
    pub fn integral(&self) -> f64 {
        self.sum
    }
    /// The dose value `(∫ a_wf² dt)^½`.
    pub fn msdv(&self) -> f64 {
        self.sum.sqrt()
    }
}

/// The motion-sickness doses of a ride, or of a trip made of rides ([`Sickness::combine`]).
#[derive(Debug, Clone, Copy, Serialize, Default, PartialEq)]
pub struct Sickness {
    /// Time the doses are over (s).
    pub duration_s: f64,
    /// `∫ a_wf,z² dt` (m²/s³), `∫ a_wf,y² dt` (m²/s³) and `∫ φ̈_wf² dt` (rad²/s³): what adds.
    #[serde(skip)]
    pub integrals: [f64; 3],
    /// ISO 2631-1 MSDV_z of the vertical acceleration over the trip (m/s^1.5).
    pub msdv_z: f64,
    /// MSDV_z per hour of the same motion (m/s^1.5).
    pub msdv_z_per_hour: f64,
    /// ISO 2631-1 Annex D's motion sickness incidence K_m·MSDV_z over the trip (%).
    pub msi_z_pct: f64,
    /// Wf dose of the carbody lateral acceleration over the trip (m/s^1.5).
    pub msdv_y: f64,
    /// Per hour (m/s^1.5).
    pub msdv_y_per_hour: f64,
    /// Wf dose of the carbody roll acceleration over the trip (rad/s^1.5).
    pub msdv_roll: f64,
    /// Per hour (rad/s^1.5).
    pub msdv_roll_per_hour: f64,
}

impl Sickness {
    /// The doses of `integrals` over `duration_s`.
    pub fn from_integrals(duration_s: f64, integrals: [f64; 3]) -> Self {
        let hour = if duration_s > 0.0 {
            (3600.0 / duration_s).sqrt()
        } else {
            0.0
        };
        let [z, y, r] = integrals.map(f64::sqrt);
        Sickness {
            duration_s,
            integrals,
            msdv_z: z,
            msdv_z_per_hour: z * hour,
            msi_z_pct: 100.0 * K_M * z,
            msdv_y: y,
            msdv_y_per_hour: y * hour,
            msdv_roll: r,
            msdv_roll_per_hour: r * hour,
        }
    }

    /// The doses of a trip made of `parts` one after the other (integrals and times add).
    pub fn combine<'a>(parts: impl IntoIterator<Item = &'a Sickness>) -> Self {
        let (mut t, mut i) = (0.0, [0.0; 3]);
        for p in parts {
            t += p.duration_s;
            for (a, b) in i.iter_mut().zip(p.integrals) {
                *a += b;
            }
        }
        Sickness::from_integrals(t, i)
    }
}

/// The doses of a ride where a passenger sits, one [`Sample`] (at that point) per step.
#[derive(Debug, Clone)]
pub struct SicknessAssessor {
    dt: f64,
    n: usize,
    z: DoseMeter,
    y: DoseMeter,
    roll: DoseMeter,
    last_roll: Option<f64>,
}

impl SicknessAssessor {
    /// An assessor at step `dt` (s).
    pub fn new(dt: f64) -> Self {
        SicknessAssessor {
            dt,
            n: 0,
            z: DoseMeter::new(dt),
            y: DoseMeter::new(dt),
            roll: DoseMeter::new(dt),
            last_roll: None,
        }
    }
    /// Takes the next sample: its vertical and lateral accelerations and, by the backward
    /// difference of its roll speed, the roll acceleration.
    pub fn push(&mut self, x: &Sample) {
        self.n += 1;
        self.z.push(x.vertical);
        self.y.push(x.lat_acc);
        let acc = self.last_roll.map_or(0.0, |p| (x.roll_speed - p) / self.dt);
        self.last_roll = Some(x.roll_speed);
        self.roll.push(acc);
    }
    /// The doses so far.
    pub fn finish(&self) -> Sickness {
        Sickness::from_integrals(
            self.n as f64 * self.dt,
            [self.z.integral(), self.y.integral(), self.roll.integral()],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ISO 2631-1:1997 Table 3's Wf weighting factors (×1000) at the one-third-octave band
    /// nominal frequencies 0.02-4 Hz, with the size of a unit in the last printed digit.
    const TABLE: [(f64, f64, f64); 24] = [
        (0.02, 24.2, 0.1),
        (0.025, 37.7, 0.1),
        (0.0315, 59.7, 0.1),
        (0.04, 97.1, 0.1),
        (0.05, 157.0, 1.0),
        (0.063, 267.0, 1.0),
        (0.08, 461.0, 1.0),
        (0.1, 695.0, 1.0),
        (0.125, 895.0, 1.0),
        (0.16, 1006.0, 1.0),
        (0.2, 992.0, 1.0),
        (0.25, 854.0, 1.0),
        (0.315, 619.0, 1.0),
        (0.4, 384.0, 1.0),
        (0.5, 224.0, 1.0),
        (0.63, 116.0, 1.0),
        (0.8, 53.0, 0.1),
        (1.0, 23.5, 0.1),
        (1.25, 9.98, 0.01),
        (1.6, 3.77, 0.01),
        (2.0, 1.55, 0.01),
        (2.5, 0.64, 0.01),
        (3.15, 0.25, 0.01),
        (4.0, 0.097, 0.001),
    ];

    #[test]
    fn wf_matches_the_published_table() {
        // The table prints its factors rounded: within half a unit of the last digit.
        for (f, want, unit) in TABLE {
            let got = 1000.0 * WF.gain(f);
            assert!(
                (got - want).abs() <= 0.5 * unit + 1e-9,
                "Wf at {f} Hz: {got:.4} against {want} (x1000)"
            );
        }
    }

    #[test]
    fn dose_of_a_sinusoid_is_its_closed_form() {
        // a = A sin(2πft) for T seconds through Wf: MSDV = A·|Wf(f)|·(T/2)^½ once the filter's
        // start has died away. The transient (about 3 periods of the 0.08 Hz band limit,
        // decaying e-fold in 1/(ζω) ≈ 2.8 s) and the bilinear map at 1 ms (relative gain
        // error below 1e-6 at 0.2 Hz) leave under 1 % over 600 s.
        let dt = 1e-3;
        for f in [0.1, 0.16, 0.25, 0.5] {
            let (a, t_end) = (1.3, 600.0);
            let mut m = DoseMeter::new(dt);
            let n = (t_end / dt) as usize;
            for k in 0..n {
                m.push(a * (std::f64::consts::TAU * f * k as f64 * dt).sin());
            }
            let want = a * WF.gain(f) * (t_end / 2.0).sqrt();
            let rel = (m.msdv() - want).abs() / want;
            assert!(
                rel < 0.01,
                "{f} Hz: {} against {want} ({rel:.2e})",
                m.msdv()
            );
        }
    }

    #[test]
    fn doses_add_in_their_squares_and_scale_to_an_hour() {
        let a = Sickness::from_integrals(600.0, [0.5, 2.0, 1e-4]);
        let b = Sickness::from_integrals(1200.0, [1.0, 1.0, 2e-4]);
        let c = Sickness::combine([&a, &b]);
        assert_eq!(c.duration_s, 1800.0);
        assert!((c.msdv_z - 1.5f64.sqrt()).abs() < 1e-15);
        // Per hour: the trip's dose times (3600/1800)^½.
        assert!((c.msdv_z_per_hour - 3.0f64.sqrt()).abs() < 1e-15);
        assert!((c.msi_z_pct - 100.0 / 3.0 * 1.5f64.sqrt()).abs() < 1e-12);
    }
}
