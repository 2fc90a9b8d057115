//! The linear design model (paper eqs 14-15, 30-31), derived from the plant's own equations
//! ([`vehicle_model::Vehicle::state_space`]) so that plant and controllers share one source of truth.

use nalgebra::DMatrix;
use serde::Serialize;
use vehicle_model::{Vehicle, VehicleParams};

use crate::linalg::c2d;

/// Continuous model `ẋ = Π x + Φ u + Γ ω`, `ξ = Ψ x` (eqs 14-15).
#[derive(Debug, Clone)]
pub struct LinearModel {
    /// Π (9×9).
    pub a: DMatrix<f64>,
    /// Φ (9×1), input δ_a (rad).
    pub b: DMatrix<f64>,
    /// Γ (9×6), ω = [1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o].
    pub g: DMatrix<f64>,
    /// Ψ (1×9), output θ_v (rad).
    pub c: DMatrix<f64>,
}

/// Discrete model at period `t` (eqs 30-31), zero-order hold on u and ω.
#[derive(Debug, Clone)]
pub struct DiscreteModel {
    /// Period (s).
    pub t: f64,
    /// Π_d.
    pub a: DMatrix<f64>,
    /// Φ_d.
    pub b: DMatrix<f64>,
    /// Γ_d.
    pub g: DMatrix<f64>,
    /// Ψ_d = Ψ.
    pub c: DMatrix<f64>,
}

/// One eigenvalue with its modal quantities.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Mode {
    /// Real part (1/s).
    pub re: f64,
    /// Imaginary part (rad/s).
    pub im: f64,
    /// Natural frequency |λ| (rad/s).
    pub omega_n_rad_s: f64,
    /// Natural frequency (Hz).
    pub f_n_hz: f64,
    /// Damping ratio −Re λ / |λ|.
    pub zeta: f64,
}

impl LinearModel {
    /// The vehicle's linear model at speed `v` (m/s).
    pub fn new(p: &VehicleParams, v: f64) -> Self {
        let ss = Vehicle::new(p.clone(), v).state_space();
        LinearModel {
            a: DMatrix::from_column_slice(9, 9, ss.a.as_slice()),
            b: DMatrix::from_column_slice(9, 1, ss.b.as_slice()),
            g: DMatrix::from_column_slice(9, 6, ss.g.as_slice()),
            c: DMatrix::from_column_slice(1, 9, ss.c.as_slice()),
        }
    }

    /// ZOH discretisation at period `t` (s).
    pub fn discretise(&self, t: f64) -> DiscreteModel {
        let mut bg = DMatrix::zeros(9, 7);
        bg.view_mut((0, 0), (9, 1)).copy_from(&self.b);
        bg.view_mut((0, 1), (9, 6)).copy_from(&self.g);
        let (a, bgd) = c2d(&self.a, &bg, t);
        DiscreteModel {
            t,
            a,
            b: bgd.view((0, 0), (9, 1)).into_owned(),
            g: bgd.view((0, 1), (9, 6)).into_owned(),
            c: self.c.clone(),
        }
    }
}

/// Eigenvalues of a continuous-time state matrix as [`Mode`]s, sorted by frequency.
pub fn modes_of(a: &DMatrix<f64>) -> Vec<Mode> {
    let mut m: Vec<Mode> = a
        .complex_eigenvalues()
        .iter()
        .map(|z| {
            let w = z.norm();
            Mode {
                re: z.re,
                im: z.im,
                omega_n_rad_s: w,
                f_n_hz: w / std::f64::consts::TAU,
                zeta: if w > 0.0 { -z.re / w } else { 1.0 },
            }
        })
        .collect();
    m.sort_by(|a, b| {
        a.omega_n_rad_s
            .total_cmp(&b.omega_n_rad_s)
            .then(a.im.total_cmp(&b.im))
    });
    m
}

/// Row-major nested vectors for JSON.
pub fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect())
        .collect()
}
