//! The track: deterministic curve geometry plus the seeded irregularity: the paper's random
//! cant on knots, or lateral alignment and cross-level drawn from the ERRI B176 spectra
//! ([`crate::spectrum`]).
//!
//! Curvature κ = 1/R and cant θ_o follow the transition's shape r(u) (`TransitionShape`). On
//! the clothoid (the paper's, section 2.3) they ramp linearly, so the cant rate θ̇_o jumps at
//! the four corners of the ramps and θ̈_o is a Dirac impulse there. [`Track::corners`] lists
//! those jumps so the plant can apply them exactly as velocity jumps (model-notes 6); between
//! corners the deterministic θ̈_o is zero. The smoothed shapes (cosine, Bloss) have r' = 0 at
//! both ends: no corners, and a deterministic θ̈_o = θ_o·r''/L_t² that the plant integrates.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::params::{IrregularityModel, TrackParams, TransitionShape};

/// Track values at one position.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackPoint {
    /// Design curvature 1/R (1/m), without irregularity.
    pub curvature: f64,
    /// Design cant (rad), without irregularity.
    pub cant_design: f64,
    /// Total cant θ_o including irregularity (rad).
    pub cant: f64,
    /// dθ_o/ds including irregularity (rad/m); design part is the ramp slope.
    pub dcant_ds: f64,
    /// Smooth part of d²θ_o/ds² (irregularity only; the ramp corners are impulses) (rad/m²).
    pub d2cant_ds2: f64,
    /// Lateral alignment irregularity y_o (m), the track's lateral input of eq 11.
    pub y_o: f64,
    /// dy_o/ds (rad, i.e. m/m).
    pub dy_o_ds: f64,
}

/// A corner of a linear ramp: the cant slope changes by `dslope` (rad/m) at `s` (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    /// Position (m).
    pub s: f64,
    /// Change of dθ_o/ds across the corner (rad/m).
    pub dslope: f64,
}

/// The track of a run.
#[derive(Debug, Clone)]
pub struct Track {
    p: TrackParams,
    s1: f64,
    s2: f64,
    s3: f64,
    s4: f64,
    kappa: f64,
    cant: f64,
    shape: TransitionShape,
    corners: Vec<Corner>,
    knots: Vec<f64>,
    /// Spectrum model: alignment y_o (m) and cross-level angle (rad).
    alignment: Option<crate::spectrum::Profile>,
    cross_level: Option<crate::spectrum::Profile>,
}

/// Quintic blend S(u) = 10u³ − 15u⁴ + 6u⁵ and its first two derivatives: S(0)=0, S(1)=1,
/// S' and S'' vanish at both ends, and S stays in [0, 1].
fn quintic(u: f64) -> (f64, f64, f64) {
    let u2 = u * u;
    let u3 = u2 * u;
    (
        u3 * (10.0 - 15.0 * u + 6.0 * u2),
        30.0 * u2 * (1.0 - 2.0 * u + u2),
        60.0 * u * (1.0 - 3.0 * u + 2.0 * u2),
    )
}

impl Track {
    /// Builds the track; the irregularity knots are drawn from `seed`.
    pub fn new(p: &TrackParams, seed: u64) -> Self {
        let s1 = p.straight_before_m;
        let s2 = s1 + p.transition_m;
        let s3 = s2 + p.curve_m;
        let s4 = s3 + p.transition_m;
        let irr = &p.irregularity;
        let amp = match irr.model {
            IrregularityModel::Knots => irr.amplitude_deg.to_radians(),
            IrregularityModel::Spectrum => 0.0,
        };
        // Knots cover the track plus margin; a dedicated stream keeps them independent of the
        // sensor noise drawn from the same seed.
        let n = (p.length() / p.irregularity.knot_spacing_m).ceil() as usize + 3;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(1);
        let knots = if amp > 0.0 {
            (0..n)
                .map(|i| {
                    if i == 0 {
                        0.0
                    } else {
                        rng.random_range(-amp..=amp)
                    }
                })
                .collect()
        } else {
            Vec::new()
        };
        let (mut alignment, mut cross_level) = (None, None);
        if let (IrregularityModel::Spectrum, Some(level)) = (irr.model, irr.level) {
            use crate::spectrum::{alignment_psd, cross_level_psd, Profile};
            let (lo, hi) = irr.band_m();
            // Streams 3 and 4 of the seed: independent of the knots and the sensor noise.
            let draw = |stream: u64, psd: fn(crate::spectrum::Level, f64) -> f64| {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                rng.set_stream(stream);
                Profile::generate(|w| psd(level, w), p.length(), lo, hi, &mut rng)
            };
            if irr.alignment.unwrap_or(true) {
                alignment = Some(draw(3, alignment_psd));
            }
            if irr.cross_level.unwrap_or(true) {
                cross_level = Some(draw(4, cross_level_psd));
            }
        }
        let cant = p.cant_deg.to_radians();
        let shape = p.transition_shape;
        let corners = if shape == TransitionShape::Clothoid {
            let k = cant / p.transition_m;
            vec![
                Corner { s: s1, dslope: k },
                Corner { s: s2, dslope: -k },
                Corner { s: s3, dslope: -k },
                Corner { s: s4, dslope: k },
            ]
        } else {
            Vec::new()
        };
        Track {
            p: p.clone(),
            s1,
            s2,
            s3,
            s4,
            kappa: 1.0 / p.radius_m,
            cant,
            shape,
            corners,
            knots,
            alignment,
            cross_level,
        }
    }

    /// Settings it was built from.
    pub fn params(&self) -> &TrackParams {
        &self.p
    }

    /// Design ramp r(s) in [0, 1] and its slope dr/ds.
    fn ramp(&self, s: f64) -> (f64, f64) {
        let (r, dr, _) = self.ramp2(s);
        (r, dr)
    }

    /// Design ramp r(s), dr/ds and d²r/ds² (the last 0 on the clothoid, whose corners are
    /// impulses).
    fn ramp2(&self, s: f64) -> (f64, f64, f64) {
        let lt = self.p.transition_m;
        if s <= self.s1 || s >= self.s4 {
            (0.0, 0.0, 0.0)
        } else if s < self.s2 {
            if self.shape == TransitionShape::Clothoid {
                return ((s - self.s1) / lt, 1.0 / lt, 0.0);
            }
            let (r, d, dd) = self.shape.ramp((s - self.s1) / lt);
            (r, d / lt, dd / (lt * lt))
        } else if s <= self.s3 {
            (1.0, 0.0, 0.0)
        } else {
            if self.shape == TransitionShape::Clothoid {
                return ((self.s4 - s) / lt, -1.0 / lt, 0.0);
            }
            let (r, d, dd) = self.shape.ramp((self.s4 - s) / lt);
            (r, -d / lt, dd / (lt * lt))
        }
    }

    /// Irregularity and its first two derivatives with respect to s.
    fn irregularity(&self, s: f64) -> (f64, f64, f64) {
        if let Some(c) = &self.cross_level {
            return c.at(s);
        }
        if self.knots.is_empty() || s <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let h = self.p.irregularity.knot_spacing_m;
        let x = s / h;
        let i = (x.floor() as usize).min(self.knots.len() - 2);
        let u = (x - i as f64).clamp(0.0, 1.0);
        let (a, b) = (self.knots[i], self.knots[i + 1]);
        let (sv, ds, d2s) = quintic(u);
        (a + (b - a) * sv, (b - a) * ds / h, (b - a) * d2s / (h * h))
    }

    /// Design-only values (the onboard track database of the controller sees these).
    pub fn design(&self, s: f64) -> (f64, f64) {
        let (r, _) = self.ramp(s);
        (self.kappa * r, self.cant * r)
    }

    /// Everything at position `s`.
    pub fn at(&self, s: f64) -> TrackPoint {
        let (r, dr, ddr) = self.ramp2(s);
        let (e, de, d2e) = self.irregularity(s);
        let (y_o, dy_o_ds, _) = self.alignment.as_ref().map_or((0.0, 0.0, 0.0), |a| a.at(s));
        TrackPoint {
            curvature: self.kappa * r,
            cant_design: self.cant * r,
            cant: self.cant * r + e,
            dcant_ds: self.cant * dr + de,
            // The clothoid's r'' is zero between its corners: left out, so its values are
            // those of the straight ramp exactly.
            d2cant_ds2: if self.shape == TransitionShape::Clothoid {
                d2e
            } else {
                self.cant * ddr + d2e
            },
            y_o,
            dy_o_ds,
        }
    }

    /// The cant rate θ̇_o (rad/s) at time `t` of a vehicle running at `v` (m/s) from s = 0,
    /// with the ramp corners on the plant's side of the jump: a corner reached at or before
    /// `t` (s_c/v ≤ t) has been passed, because the plant applies its velocity jump in the
    /// step that ends at it (`plant-proc`'s `advance`), so the θ̇_v recorded at `t` is already
    /// the one after the jump. θ̇_v + this value is then the body's absolute roll rate,
    /// continuous across every corner. Between corners it equals `v·at(v·t).dcant_ds`.
    pub fn cant_rate_at_time(&self, t: f64, v: f64) -> f64 {
        if self.shape != TransitionShape::Clothoid {
            // No corners: the rate is continuous.
            return v * self.at(v * t).dcant_ds;
        }
        let slope: f64 = self
            .corners()
            .iter()
            .filter(|c| c.s / v <= t)
            .map(|c| c.dslope)
            .sum();
        let (_, de, _) = self.irregularity(v * t);
        v * (slope + de)
    }

    /// The ramp corners with their slope jumps: the four of a clothoid's ramps, none on a
    /// smoothed transition.
    pub fn corners(&self) -> &[Corner] {
        &self.corners
    }

    /// Section name at `s`, for plots and reports.
    pub fn section(&self, s: f64) -> &'static str {
        if s < self.s1 {
            "straight"
        } else if s < self.s2 {
            "transition-in"
        } else if s <= self.s3 {
            "curve"
        } else if s < self.s4 {
            "transition-out"
        } else {
            "straight"
        }
    }

    /// Section boundaries s1..s4 (m).
    pub fn boundaries(&self) -> [f64; 4] {
        [self.s1, self.s2, self.s3, self.s4]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramps_and_corners_match_the_geometry() {
        let p = TrackParams::default();
        let t = Track::new(&p, 1);
        let mid = t.at(135.0 + 54.0);
        assert!((mid.cant - 3f64.to_radians()).abs() < 1e-12);
        assert!((mid.curvature - 0.5e-3).abs() < 1e-15);
        assert!((t.at(135.0 + 108.0 + 100.0).cant - 6f64.to_radians()).abs() < 1e-12);
        assert_eq!(t.at(10.0).cant, 0.0);
        let total: f64 = t.corners().iter().map(|c| c.dslope).sum();
        assert!(total.abs() < 1e-15, "slope jumps cancel over the curve");
    }

    #[test]
    fn irregularity_is_bounded_smooth_and_seeded() {
        let mut p = TrackParams::default();
        p.irregularity.amplitude_deg = 0.6;
        let a = Track::new(&p, 7);
        let b = Track::new(&p, 7);
        let c = Track::new(&p, 8);
        let amp = 0.6f64.to_radians();
        let mut differs = false;
        let mut prev = a.at(0.0);
        for i in 1..60_000 {
            let s = i as f64 * 0.01;
            let pa = a.at(s);
            let e = pa.cant - pa.cant_design;
            assert!(e.abs() <= amp + 1e-15);
            assert_eq!(pa, b.at(s));
            differs |= c.at(s) != pa;
            // the cant is continuous at 1 cm resolution (no steps)
            assert!((pa.cant - prev.cant).abs() < 1e-3, "jump at s = {s}");
            prev = pa;
        }
        assert!(differs, "a different seed gives a different track");
    }

    #[test]
    fn cant_rate_at_time_takes_the_slope_after_a_corner_reached() {
        let mut p = TrackParams::default();
        p.irregularity.amplitude_deg = 0.6;
        let t = Track::new(&p, 3);
        let v = p.speed();
        let ramp = v * p.cant_deg.to_radians() / p.transition_m;
        // Between corners: v·dθ_o/ds of the track point.
        for s in [50.0, 200.0, 400.0, 560.0, 700.0] {
            let r = t.cant_rate_at_time(s / v, v);
            assert!((r - v * t.at(s).dcant_ds).abs() < 1e-12, "s = {s}");
        }
        // At each corner's instant the slope after it (the plant has applied the jump), and
        // the one before it a hair earlier.
        let flat = Track::new(&TrackParams::default(), 3);
        for (c, after) in flat.corners().iter().zip([ramp, 0.0, -ramp, 0.0]) {
            let tc = c.s / v;
            assert!((flat.cant_rate_at_time(tc, v) - after).abs() < 1e-15);
            let before = after - v * c.dslope;
            assert!((flat.cant_rate_at_time(tc - 1e-9, v) - before).abs() < 1e-15);
        }
    }

    #[test]
    fn smoothed_transitions_have_consistent_derivatives_and_no_corners() {
        for shape in [TransitionShape::Cosine, TransitionShape::Bloss] {
            let p = TrackParams {
                transition_shape: shape,
                ..TrackParams::default()
            };
            let t = Track::new(&p, 1);
            assert!(t.corners().is_empty());
            let [s1, s2, s3, s4] = t.boundaries();
            let theta = p.cant_deg.to_radians();
            // Half way along each transition the shape is at half its rise (both shapes are
            // point-symmetric about u = 1/2).
            for s in [(s1 + s2) / 2.0, (s3 + s4) / 2.0] {
                assert!(
                    (t.at(s).cant - theta / 2.0).abs() < 1e-12,
                    "{shape:?} at {s}"
                );
            }
            // The slope vanishes at the ends and peaks in the middle at peak_slope() times the
            // clothoid's θ/L_t (closed forms: π/2 for the cosine, 3/2 for Bloss).
            for s in [s1 + 1e-9, s2 - 1e-9, s3 + 1e-9, s4 - 1e-9] {
                assert!(t.at(s).dcant_ds.abs() < 1e-9, "{shape:?}: slope at an end");
            }
            let peak = t.at((s1 + s2) / 2.0).dcant_ds;
            let want = shape.peak_slope() * theta / p.transition_m;
            assert!(
                (peak - want).abs() < 1e-12 * want,
                "{shape:?}: {peak} vs {want}"
            );
            // Derivatives match central differences of the value and of the slope (h = 1 mm:
            // truncation h²/6 times the next derivative, below 1e-12 here).
            let h = 1e-3;
            for k in 1..40 {
                let s = s1 + (s4 - s1) * k as f64 / 40.0;
                let (a, b, c) = (t.at(s - h), t.at(s), t.at(s + h));
                let d1 = (c.cant - a.cant) / (2.0 * h);
                let d2 = (c.dcant_ds - a.dcant_ds) / (2.0 * h);
                assert!((d1 - b.dcant_ds).abs() < 1e-9, "{shape:?} slope at {s}");
                assert!(
                    (d2 - b.d2cant_ds2).abs() < 1e-9,
                    "{shape:?} cant curvature at {s}"
                );
                assert!((b.curvature * p.radius_m - b.cant / theta).abs() < 1e-12);
                let rate = t.cant_rate_at_time(s / p.speed(), p.speed());
                assert!((rate - p.speed() * b.dcant_ds).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn quintic_derivatives_match_finite_differences() {
        for &u in &[0.1, 0.37, 0.5, 0.81] {
            let h = 1e-6;
            let (_, d, dd) = quintic(u);
            let fd = (quintic(u + h).0 - quintic(u - h).0) / (2.0 * h);
            let fdd = (quintic(u + h).1 - quintic(u - h).1) / (2.0 * h);
            assert!((d - fd).abs() < 1e-6 && (dd - fdd).abs() < 1e-5);
        }
    }
}
