//! Equations of motion of the whole car, written through the deflection of every suspension
//! element as the half vehicle's are (docs/model.md, "The whole car").
//!
//! Coordinates are relative to the design track at each body's own position: lateral y
//! (towards +y, the inside of a positive curve), yaw ψ relative to the local track tangent,
//! roll φ relative to the local track plane (positive leaning towards +y). A child body at
//! distance d ahead of its parent sees the track offset by e = d²(2κ_p + κ_c)/6 from the
//! parent's tangent and turned by d(κ_p + κ_c)/2 (both exact for κ linear between the two).

use super::contact::Creep;
use super::inputs::{CarInputs, WheelsetInput, NW};
use super::params::FullCarParams;
use crate::G;

/// Degrees of freedom: body (y, ψ, φ), two bogies (y, ψ, φ), four wheelsets (y, ψ).
pub const NQ: usize = 3 + 2 * 3 + NW * 2;
/// States: positions, velocities and each bogie's airspring reservoir roll θ_r.
pub const NX: usize = 2 * NQ + 2;

/// Indices into the state vector (velocities at `+ NQ`).
pub mod ix {
    use super::NQ;
    /// Body lateral y_c (m).
    pub const Y_C: usize = 0;
    /// Body yaw ψ_c (rad).
    pub const PSI_C: usize = 1;
    /// Body roll φ_c (rad).
    pub const PHI_C: usize = 2;
    /// Bogie `i` lateral y_b (m).
    pub const fn y_b(i: usize) -> usize {
        3 + 3 * i
    }
    /// Bogie `i` yaw ψ_b (rad).
    pub const fn psi_b(i: usize) -> usize {
        4 + 3 * i
    }
    /// Bogie `i` roll φ_b (rad).
    pub const fn phi_b(i: usize) -> usize {
        5 + 3 * i
    }
    /// Wheelset `j` lateral y_w (m).
    pub const fn y_w(j: usize) -> usize {
        9 + 2 * j
    }
    /// Wheelset `j` yaw ψ_w (rad).
    pub const fn psi_w(j: usize) -> usize {
        10 + 2 * j
    }
    /// The rate of coordinate `k`.
    pub const fn rate(k: usize) -> usize {
        NQ + k
    }
    /// Bogie `i`'s airspring reservoir roll θ_r (rad), relative to that bogie's track plane.
    pub const fn th_r(i: usize) -> usize {
        2 * NQ + i
    }
}

/// The track under the bogies (mean of their wheelsets) and under the body (mean of the bogies).
pub fn body_tracks(w: &CarInputs) -> ([WheelsetInput; 2], WheelsetInput) {
    let tb = [
        WheelsetInput::mean(&w[0], &w[1]),
        WheelsetInput::mean(&w[2], &w[3]),
    ];
    (tb, WheelsetInput::mean(&tb[0], &tb[1]))
}

/// Forces of one bogie's secondary suspension (docs/model.md, "The whole car").
#[derive(Debug, Clone, Copy)]
pub struct Secondary {
    /// Lateral force of both sides on the bogie (on the body: the opposite) (N).
    pub lateral: f64,
    /// Roll moment of bar, airsprings and roll damper on the bogie (N·m).
    pub roll: f64,
    /// Yaw moment of the longitudinal springs and yaw dampers on the bogie (N·m).
    pub yaw: f64,
    /// Moment of the body's weight share about its c.o.g., offset from the bogie (N·m).
    pub weight: f64,
    /// Reservoir roll rate θ̇_r (rad/s).
    pub dth_r: f64,
}

/// Forces of one wheelset's primary suspension and contact.
#[derive(Debug, Clone, Copy)]
pub struct Primary {
    /// Lateral force of both axleboxes on the wheelset (on the bogie: the opposite) (N).
    pub lateral: f64,
    /// Yaw moment of the longitudinal springs on the bogie (on the wheelset: opposite) (N·m).
    pub yaw: f64,
    /// Roll moment of the vertical springs on the wheelset (on the bogie: opposite) (N·m).
    pub roll: f64,
    /// Lateral force of the rails on the wheelset: creep and gravitational stiffness (N).
    pub rail_lateral: f64,
    /// Yaw moment of the longitudinal creep forces on the wheelset (N·m).
    pub creep_yaw: f64,
}

/// Lateral force of the rails on a wheelset (N) and yaw moment of its longitudinal creep
/// forces (N·m): Kalker's linear creep on both wheels without spin, lateral creepage ẏ/V − ψ,
/// longitudinal creepage ∓(l0 (ψ̇/V + κ) + λ y/r0) on the ±y wheel, plus the gravitational
/// stiffness. `q` = [y − y_o, ψ, ẏ, ψ̇] of the wheelset, `kappa` the curvature under it.
pub fn creep_forces(
    p: &FullCarParams,
    creep: &Creep,
    v: f64,
    q: [f64; 4],
    kappa: f64,
) -> (f64, f64) {
    let [y_rel, psi, dy, dpsi] = q;
    let lateral = dy / v - psi;
    let longitudinal = p.l0 * (dpsi / v + kappa) + p.conicity * y_rel / p.r0;
    (
        -2.0 * creep.f22 * lateral - p.k_gy * y_rel,
        -2.0 * p.l0 * creep.f11 * longitudinal,
    )
}

/// The car's equations with its creep coefficients.
#[derive(Debug, Clone)]
pub struct Equations<'a> {
    /// Parameters.
    pub p: &'a FullCarParams,
    /// Creep coefficients of one wheel.
    pub creep: Creep,
    /// Speed V (m/s).
    pub v: f64,
}

impl Equations<'_> {
    /// Secondary suspension of bogie `i` with drive angle `delta` (rad).
    pub fn secondary(
        &self,
        x: &[f64],
        i: usize,
        delta: f64,
        tb: &WheelsetInput,
        tc: &WheelsetInput,
    ) -> Secondary {
        let p = self.p;
        let d = p.bogie_x(i);
        let r = ix::rate;
        let (psib, phib) = (ix::psi_b(i), ix::phi_b(i));
        let twist = tc.cant - tb.cant;
        let dtwist = tc.cant_rate - tb.cant_rate;
        let (ds, dds, y_c) = self.secondary_deflection(x, i, tb, tc);
        let yb = ix::y_b(i);
        // Body roll relative to the bogie's track plane, and to the bogie.
        let phi_c = x[ix::PHI_C] + twist;
        let dphi_c = x[r(ix::PHI_C)] + dtwist;
        let psi = phi_c - x[phib];
        let dpsi = dphi_c - x[r(phib)];
        let th_r = x[ix::th_r(i)];
        let m_air = 2.0 * p.d1 * p.d1 * (p.k_az * psi + p.k_sz * (phi_c - th_r));
        let kap = 0.5 * (tc.curvature + tb.curvature);
        let dkap = 0.5 * (tc.curvature_rate + tb.curvature_rate);
        let yaw = x[ix::PSI_C] - x[psib] - d * kap;
        let dyaw = x[r(ix::PSI_C)] - x[r(psib)] - d * dkap;
        Secondary {
            lateral: 2.0 * (p.k_sy * ds + p.c_sy * dds),
            roll: p.k_vr * (psi - delta) + m_air + p.c_vr * dpsi,
            yaw: p.secondary_yaw_stiffness() * yaw + p.secondary_yaw_damping() * dyaw,
            weight: 0.5 * p.m_c * G * (y_c + p.h_gv * twist - x[yb]),
            dth_r: x[r(phib)] + (p.k_sz * (phi_c - th_r) - p.k_rz * (th_r - x[phib])) / p.c_rz,
        }
    }

    /// The secondary lateral deflection of bogie `i` Δs (m), its rate (m/s), and the body's
    /// lateral at the bogie in the bogie's track frame (m, at the body c.o.g. height: the
    /// chord's versine taken off).
    pub fn secondary_deflection(
        &self,
        x: &[f64],
        i: usize,
        tb: &WheelsetInput,
        tc: &WheelsetInput,
    ) -> (f64, f64, f64) {
        let p = self.p;
        let d = p.bogie_x(i);
        let r = ix::rate;
        let (yb, phib) = (ix::y_b(i), ix::phi_b(i));
        let e = d * d * (2.0 * tc.curvature + tb.curvature) / 6.0;
        let de = d * d * (2.0 * tc.curvature_rate + tb.curvature_rate) / 6.0;
        let twist = tc.cant - tb.cant;
        let dtwist = tc.cant_rate - tb.cant_rate;
        let y_c = x[ix::Y_C] + d * x[ix::PSI_C] - e;
        let dy_c = x[r(ix::Y_C)] + d * x[r(ix::PSI_C)] - de;
        let z_s = p.h_gv - p.h1;
        let ds = y_c - p.h1 * x[ix::PHI_C] - x[yb] - p.h2 * x[phib] + z_s * twist;
        let dds = dy_c - p.h1 * x[r(ix::PHI_C)] - x[r(yb)] - p.h2 * x[r(phib)] + z_s * dtwist;
        (ds, dds, y_c)
    }

    /// Primary suspension and contact of wheelset `j` under bogie `j / 2`.
    pub fn primary(&self, x: &[f64], j: usize, tw: &WheelsetInput, tb: &WheelsetInput) -> Primary {
        let p = self.p;
        let i = j / 2;
        let d = p.wheelset_dx(j);
        let r = ix::rate;
        let (yb, psib, phib) = (ix::y_b(i), ix::psi_b(i), ix::phi_b(i));
        let (yw, psiw) = (ix::y_w(j), ix::psi_w(j));
        let e = d * d * (2.0 * tb.curvature + tw.curvature) / 6.0;
        let de = d * d * (2.0 * tb.curvature_rate + tw.curvature_rate) / 6.0;
        let z_p = p.h_gb - p.h3;
        let dp = x[yb] + d * x[psib] - e - p.h3 * x[phib] - x[yw] + z_p * (tb.cant - tw.cant);
        let ddp = x[r(yb)] + d * x[r(psib)] - de - p.h3 * x[r(phib)] - x[r(yw)]
            + z_p * (tb.cant_rate - tw.cant_rate);
        let yaw = x[psiw] - x[psib] + d * 0.5 * (tb.curvature + tw.curvature);
        let roll = x[phib] + tb.cant - tw.cant;
        let droll = x[r(phib)] + tb.cant_rate - tw.cant_rate;
        let (rail_lateral, creep_yaw) = creep_forces(
            p,
            &self.creep,
            self.v,
            [x[yw] - tw.y_o, x[psiw], x[r(yw)], x[r(psiw)]],
            tw.curvature,
        );
        Primary {
            lateral: 2.0 * (p.k_py * dp + p.c_py * ddp),
            yaw: p.primary_yaw_stiffness() * yaw,
            roll: 2.0 * p.d2 * p.d2 * (p.k_pz * roll + p.c_pz * droll),
            rail_lateral,
            creep_yaw,
        }
    }
}

impl Equations<'_> {
    /// Time derivative of the state `x` with drive angles `delta` (rad, one per bogie) and the
    /// track under each wheelset `w`. Linear in all three.
    pub fn deriv(&self, x: &[f64], delta: [f64; 2], w: &CarInputs) -> [f64; NX] {
        let p = self.p;
        let v2 = self.v * self.v;
        let (tb, tc) = body_tracks(w);
        let mut dx = [0.0; NX];
        dx[..NQ].copy_from_slice(&x[NQ..2 * NQ]);
        let mut acc = [0.0; NQ];
        // Body: inertial terms of the moving track frame (centripetal, cant, its rotation).
        acc[ix::Y_C] = -v2 * tc.curvature + G * tc.cant - p.h_gv * tc.cant_acc;
        acc[ix::PSI_C] = -self.v * tc.curvature_rate;
        acc[ix::PHI_C] = -tc.cant_acc;
        let (mut fy_c, mut mz_c, mut mx_c) = (0.0, 0.0, 0.0);
        for i in 0..2 {
            let s = self.secondary(x, i, delta[i], &tb[i], &tc);
            let d = p.bogie_x(i);
            fy_c -= s.lateral;
            mz_c -= d * s.lateral + s.yaw;
            mx_c += p.h1 * s.lateral + s.weight - s.roll;
            let (mut fy, mut mz, mut mx) = (s.lateral, s.yaw, p.h2 * s.lateral + s.roll);
            for j in [2 * i, 2 * i + 1] {
                let f = self.primary(x, j, &w[j], &tb[i]);
                let dj = p.wheelset_dx(j);
                fy -= f.lateral;
                mz += -dj * f.lateral + f.yaw;
                mx += p.h3 * f.lateral - f.roll;
                let (yw, psiw) = (ix::y_w(j), ix::psi_w(j));
                acc[yw] = (f.lateral + f.rail_lateral) / p.m_w - v2 * w[j].curvature
                    + G * w[j].cant
                    - p.r0 * w[j].cant_acc;
                acc[psiw] = (f.creep_yaw - f.yaw) / p.i_wz - self.v * w[j].curvature_rate;
            }
            acc[ix::y_b(i)] =
                fy / p.m_b - v2 * tb[i].curvature + G * tb[i].cant - p.h_gb * tb[i].cant_acc;
            acc[ix::psi_b(i)] = mz / p.i_bz - self.v * tb[i].curvature_rate;
            acc[ix::phi_b(i)] = mx / p.i_bx - tb[i].cant_acc;
            dx[ix::th_r(i)] = s.dth_r;
        }
        acc[ix::Y_C] += fy_c / p.m_c;
        acc[ix::PSI_C] += mz_c / p.i_cz;
        acc[ix::PHI_C] += mx_c / p.i_cx;
        dx[NQ..2 * NQ].copy_from_slice(&acc);
        dx
    }
}
