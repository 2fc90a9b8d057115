//! What the car gives out: wheel-rail forces at every wheelset and what passengers feel
//! along the body.

use super::dynamics::{body_tracks, ix, Equations, NQ};
use super::inputs::{CarInputs, NW};
use super::NY;
use crate::G;

/// Forces between one wheelset and the rails (N). "+y wheel" is the wheel on the +y side
/// (the inner wheel of a curve of positive curvature), "−y wheel" the other.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WheelForces {
    /// ΣY: lateral force of the rails on the wheelset, towards +y (N); the track shift force
    /// is its magnitude.
    pub sum_y: f64,
    /// Lateral force of the rail on the +y wheel, towards +y (N): half the creep force (one
    /// creep coefficient for both wheels, linearised at Q_0), and the flange force when the
    /// wheelset runs against the +y rail.
    pub y_plus: f64,
    /// Lateral force of the rail on the −y wheel, towards +y (N): the other half, and the
    /// flange force when the wheelset runs against the −y rail.
    pub y_minus: f64,
    /// Vertical load on the +y wheel Q_+ (N).
    pub q_plus: f64,
    /// Vertical load on the −y wheel Q_− (N).
    pub q_minus: f64,
}

impl WheelForces {
    /// The flange-climbing lateral force on the +y wheel: the rail pushing it towards −y,
    /// towards the track centre (N).
    pub fn y_climb_plus(&self) -> f64 {
        -self.y_plus
    }
    /// The flange-climbing lateral force on the −y wheel: the rail pushing it towards +y (N).
    pub fn y_climb_minus(&self) -> f64 {
        self.y_minus
    }
}

/// The linear force outputs [ΣY_j, (Q_+ − Q_−)_j / 2] for every wheelset.
///
/// Q from the wheelset's roll balance about its axle (the wheelset rolls with the track):
/// the primary vertical springs' moment M_p, the primary lateral force at its height above
/// the axle, the rails' ΣY at r_0 below it, and the axle load P_0 carried at contact points
/// shifted by the wheelset's displacement on the rails y − y_o, so
/// Q_+ − Q_− = (M_p + (z_p − r_0) F_p − r_0 ΣY + P_0 (y − y_o)) / l_0.
pub fn force_vector(eq: &Equations, x: &[f64], w: &CarInputs) -> [f64; NY] {
    let p = eq.p;
    let (tb, _) = body_tracks(w);
    let z_p = p.h_gb - p.h3;
    let p0 = p.static_axle_load();
    let mut out = [0.0; NY];
    for j in 0..NW {
        let f = eq.primary(x, j, &w[j], &tb[j / 2]);
        out[2 * j] = f.rail_lateral;
        let shift = x[ix::y_w(j)] - w[j].y_o;
        out[2 * j + 1] =
            0.5 * (f.roll + (z_p - p.r0) * f.lateral - p.r0 * f.rail_lateral + p0 * shift) / p.l0;
    }
    out
}

/// Wheel forces of every wheelset, static loads included, with the flange force where a
/// wheelset is beyond its clearance (on the flanging wheel, at rail level in the roll balance).
pub fn wheel_forces(eq: &Equations, x: &[f64], w: &CarInputs) -> [WheelForces; NW] {
    let p = eq.p;
    let q0 = p.static_wheel_load();
    let v = force_vector(eq, x, w);
    std::array::from_fn(|j| {
        let flange = p.flange_force(x[ix::y_w(j)] - w[j].y_o);
        let dq = v[2 * j + 1] - 0.5 * p.r0 * flange / p.l0;
        let creep = 0.5 * v[2 * j];
        let (fp, fm) = if flange < 0.0 {
            (flange, 0.0)
        } else {
            (0.0, flange)
        };
        WheelForces {
            sum_y: v[2 * j] + flange,
            y_plus: creep + fp,
            y_minus: creep + fm,
            q_plus: q0 + dq,
            q_minus: q0 - dq,
        }
    })
}

/// What a passenger at one place in the body feels.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Passenger {
    /// Position along the body from its centre, positive forward (m).
    pub x: f64,
    /// Height above the body's c.o.g. (m).
    pub z: f64,
    /// Lateral acceleration in the body's floor plane, towards +y (m/s²): the suspension's
    /// forces on the body per unit mass at that point, less g times the body's roll relative
    /// to the track plane (the cant's gravity and the curve's centripetal part cancel against
    /// the track frame's own motion).
    pub lateral_acc: f64,
    /// Roll of the body relative to the horizontal, θ_o + φ_c (rad); one value along a rigid body.
    pub roll: f64,
    /// Its rate (rad/s).
    pub roll_rate: f64,
}

/// Passengers at `places` (x along the body, z above its c.o.g.), from the state, the drives
/// and the track under each wheelset.
pub fn passengers(
    eq: &Equations,
    x: &[f64],
    delta: [f64; 2],
    w: &CarInputs,
    places: &[(f64, f64)],
) -> Vec<Passenger> {
    let dx = eq.deriv(x, delta, w);
    let (_, tc) = body_tracks(w);
    let v = eq.v;
    let p = eq.p;
    // Accelerations with the track frame's own terms taken back out: the suspension's part.
    let a_y = dx[NQ + ix::Y_C] + v * v * tc.curvature - G * tc.cant + p.h_gv * tc.cant_acc;
    let a_psi = dx[NQ + ix::PSI_C] + v * tc.curvature_rate;
    let a_phi = dx[NQ + ix::PHI_C] + tc.cant_acc;
    places
        .iter()
        .map(|&(px, pz)| Passenger {
            x: px,
            z: pz,
            lateral_acc: a_y + px * a_psi + pz * a_phi - G * x[ix::PHI_C],
            roll: tc.cant + x[ix::PHI_C],
            roll_rate: tc.cant_rate + x[NQ + ix::PHI_C],
        })
        .collect()
}
