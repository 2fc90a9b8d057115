//! The track as each wheelset sees it, and what the bogies and the body see from it.
//!
//! Each wheelset j at x_j from the body centre (leading first) meets the track at
//! s_j = s + x_j when the body centre is at s: the trailing wheelsets see what the leading one
//! saw (x_0 − x_j)/V earlier. A bogie's track values are the mean of its two wheelsets', the
//! body's the mean of the two bogies': exact midpoint values where curvature and cant are
//! linear in distance between the points (clothoid transitions, steady curves).

use crate::track::Track;

use super::params::FullCarParams;

/// Number of wheelsets.
pub const NW: usize = 4;
/// Track inputs per wheelset, in this order in the input vector.
pub const NWI: usize = 7;

/// Track seen by one wheelset. Positive curvature turns towards +y; positive cant leans the
/// track plane towards +y (the inside of a positive curve).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WheelsetInput {
    /// Curvature κ = 1/R (1/m).
    pub curvature: f64,
    /// Its rate dκ/dt = V dκ/ds (1/(m·s)).
    pub curvature_rate: f64,
    /// Cant, with the cross-level irregularity, θ_o (rad).
    pub cant: f64,
    /// θ̇_o (rad/s).
    pub cant_rate: f64,
    /// θ̈_o, smooth part (rad/s²); ramp corners are velocity jumps ([`super::FullCarSim::cant_rate_jump`]).
    pub cant_acc: f64,
    /// Lateral alignment of the rails y_o (m).
    pub y_o: f64,
    /// ẏ_o (m/s).
    pub dy_o: f64,
}

impl WheelsetInput {
    /// As the input vector's entries [κ, κ̇, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o].
    pub fn to_array(&self) -> [f64; NWI] {
        [
            self.curvature,
            self.curvature_rate,
            self.cant,
            self.cant_rate,
            self.cant_acc,
            self.y_o,
            self.dy_o,
        ]
    }
    /// From the input vector's entries.
    pub fn from_array(a: &[f64]) -> Self {
        WheelsetInput {
            curvature: a[0],
            curvature_rate: a[1],
            cant: a[2],
            cant_rate: a[3],
            cant_acc: a[4],
            y_o: a[5],
            dy_o: a[6],
        }
    }
    /// Mean of two.
    pub fn mean(p: &Self, q: &Self) -> Self {
        let (a, b) = (p.to_array(), q.to_array());
        let mut m = [0.0; NWI];
        for k in 0..NWI {
            m[k] = 0.5 * (a[k] + b[k]);
        }
        WheelsetInput::from_array(&m)
    }
}

/// Track inputs of the whole car: one per wheelset, leading first.
pub type CarInputs = [WheelsetInput; NW];

/// One geometric sample of the track at a distance: what a track description gives.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackSample {
    /// κ (1/m).
    pub curvature: f64,
    /// dκ/ds (1/m²).
    pub dcurvature_ds: f64,
    /// θ_o (rad).
    pub cant: f64,
    /// dθ_o/ds (rad/m).
    pub dcant_ds: f64,
    /// d²θ_o/ds², smooth part (rad/m²).
    pub d2cant_ds2: f64,
    /// y_o (m).
    pub y_o: f64,
    /// dy_o/ds (-).
    pub dy_o_ds: f64,
}

/// The inputs of every wheelset with the body centre at `s` (m) and speed `v` (m/s), from a
/// track described as a function of distance.
pub fn inputs_from_fn(
    p: &FullCarParams,
    s: f64,
    v: f64,
    track: impl Fn(f64) -> TrackSample,
) -> CarInputs {
    std::array::from_fn(|j| {
        let t = track(s + p.wheelset_x(j));
        WheelsetInput {
            curvature: t.curvature,
            curvature_rate: v * t.dcurvature_ds,
            cant: t.cant,
            cant_rate: v * t.dcant_ds,
            cant_acc: v * v * t.d2cant_ds2,
            y_o: t.y_o,
            dy_o: v * t.dy_o_ds,
        }
    })
}

/// The inputs of every wheelset from a [`Track`] (design geometry and irregularity), the body
/// centre at `s`. dκ/ds is the central difference over ±5 mm (the track gives κ only; its
/// clothoid κ is piecewise linear, so this is exact away from the four ramp ends).
pub fn inputs_from_track(p: &FullCarParams, track: &Track, s: f64, v: f64) -> CarInputs {
    inputs_from_fn(p, s, v, |sj| {
        let t = track.at(sj);
        let h = 0.005;
        TrackSample {
            curvature: t.curvature,
            dcurvature_ds: (track.at(sj + h).curvature - track.at(sj - h).curvature) / (2.0 * h),
            cant: t.cant,
            dcant_ds: t.dcant_ds,
            d2cant_ds2: t.d2cant_ds2,
            y_o: t.y_o,
            dy_o_ds: t.dy_o_ds,
        }
    })
}

/// The same values at every wheelset (a steady curve, or a step felt by the whole car at once).
pub fn uniform(w: WheelsetInput) -> CarInputs {
    [w; NW]
}
