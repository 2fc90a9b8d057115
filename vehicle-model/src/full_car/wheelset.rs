//! One wheelset held by a lateral spring k_y and a yaw spring k_ψ to a frame that follows the
//! track: the classical single-wheelset model (Wickens, *Fundamentals of Rail Vehicle
//! Dynamics*, 2003, ch. 2-3), with the creep forces of the full car ([`creep_forces`]).
//! k_y = k_ψ = 0 is the free wheelset.
//!
//! State [y, ψ, ẏ, ψ̇]; input [κ, θ_o, y_o].

use nalgebra::{DMatrix, SMatrix};

use super::dynamics::creep_forces;
use super::{FullCar, FullCarParams};
use crate::G;

/// A wheelset of the car on springs to a frame following the track.
#[derive(Debug, Clone)]
pub struct WheelsetModel {
    /// The car whose wheelset, contact and creep coefficients are used.
    pub car: FullCar,
    /// Lateral stiffness to the frame k_y (N/m).
    pub k_y: f64,
    /// Yaw stiffness to the frame k_ψ (N·m/rad).
    pub k_psi: f64,
}

impl WheelsetModel {
    /// A wheelset of the car `p` on springs `k_y`, `k_psi`.
    pub fn new(p: FullCarParams, k_y: f64, k_psi: f64) -> Self {
        WheelsetModel {
            car: FullCar::new(p),
            k_y,
            k_psi,
        }
    }

    /// Time derivative at speed `v` for state `x` and input `u` = [κ, θ_o, y_o].
    pub fn deriv(&self, v: f64, x: &[f64; 4], u: &[f64; 3]) -> [f64; 4] {
        let p = &self.car.p;
        let [y, psi, dy, dpsi] = *x;
        let [kappa, cant, y_o] = *u;
        let (fy, mz) = creep_forces(p, &self.car.creep, v, [y - y_o, psi, dy, dpsi], kappa);
        [
            dy,
            dpsi,
            (fy - self.k_y * y) / p.m_w - v * v * kappa + G * cant,
            (mz - self.k_psi * psi) / p.i_wz,
        ]
    }

    /// (A, B) at speed `v`, by unit vectors through [`WheelsetModel::deriv`].
    pub fn state_space(&self, v: f64) -> (SMatrix<f64, 4, 4>, SMatrix<f64, 4, 3>) {
        let mut a = SMatrix::<f64, 4, 4>::zeros();
        let mut b = SMatrix::<f64, 4, 3>::zeros();
        for k in 0..4 {
            let mut x = [0.0; 4];
            x[k] = 1.0;
            let f = self.deriv(v, &x, &[0.0; 3]);
            for r in 0..4 {
                a[(r, k)] = f[r];
            }
        }
        for k in 0..3 {
            let mut u = [0.0; 3];
            u[k] = 1.0;
            let f = self.deriv(v, &[0.0; 4], &u);
            for r in 0..4 {
                b[(r, k)] = f[r];
            }
        }
        (a, b)
    }

    /// Largest real part of A's eigenvalues at `v` (1/s).
    pub fn max_real_part(&self, v: f64) -> f64 {
        let (a, _) = self.state_space(v);
        super::max_real_part(&DMatrix::from_column_slice(4, 4, a.as_slice()))
    }

    /// Critical speed by bisection in [lo, hi] to `tol` (m/s).
    pub fn critical_speed(&self, lo: f64, hi: f64, tol: f64) -> Option<f64> {
        super::bisect_stability(|v| self.max_real_part(v), lo, hi, tol)
    }
}
