//! End-view model of the tilting vehicle: paper eqs 9-13 and A.2, written through the
//! suspension deflections as `model-notes.md` prescribes (this removes the printed sign slips
//! of eqs 11-12).
//!
//! State (eq 14): `x = [y_v, θ_v, y_b, θ_b, ẏ_v, θ̇_v, ẏ_b, θ̇_b, θ_r]`, angles relative to the
//! track plane, positive roll leaning into the curve.

use nalgebra::{SMatrix, SVector};

use crate::params::VehicleParams;
use crate::G;

/// Number of states.
pub const NX: usize = 9;
/// State vector.
pub type State = SVector<f64, NX>;

/// Indices into the state vector.
pub mod ix {
    /// Body lateral displacement y_v (m).
    pub const Y_V: usize = 0;
    /// Body roll θ_v (rad).
    pub const TH_V: usize = 1;
    /// Bogie lateral displacement y_b (m).
    pub const Y_B: usize = 2;
    /// Bogie roll θ_b (rad).
    pub const TH_B: usize = 3;
    /// ẏ_v (m/s).
    pub const DY_V: usize = 4;
    /// θ̇_v (rad/s).
    pub const DTH_V: usize = 5;
    /// ẏ_b (m/s).
    pub const DY_B: usize = 6;
    /// θ̇_b (rad/s).
    pub const DTH_B: usize = 7;
    /// Airspring reservoir roll θ_r (rad).
    pub const TH_R: usize = 8;
}

/// Track inputs, the disturbance vector ω of eq 14: `[1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o]`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackInput {
    /// Curvature 1/R (1/m).
    pub curvature: f64,
    /// Cant θ_o (rad).
    pub cant: f64,
    /// Cant rate θ̇_o (rad/s) (enters through the velocity jumps only; kept for Γ).
    pub cant_rate: f64,
    /// Cant acceleration θ̈_o (rad/s²), smooth part.
    pub cant_acc: f64,
    /// Track lateral irregularity y_o (m).
    pub y_o: f64,
    /// Its rate ẏ_o (m/s).
    pub dy_o: f64,
}

/// The vehicle model with its speed.
#[derive(Debug, Clone)]
pub struct Vehicle {
    /// Parameters.
    pub p: VehicleParams,
    /// Forward speed v (m/s).
    pub v: f64,
}

/// Continuous state-space form `ẋ = Π x + Φ u + Γ ω` (eq 14) with `u = δ_a`.
#[derive(Debug, Clone)]
pub struct StateSpace {
    /// State matrix Π (9×9).
    pub a: SMatrix<f64, NX, NX>,
    /// Input matrix Φ (9×1), input δ_a (rad).
    pub b: SMatrix<f64, NX, 1>,
    /// Disturbance matrix Γ (9×6) for ω = [1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o].
    pub g: SMatrix<f64, NX, 6>,
    /// Output matrix Ψ (1×9): the measured body roll θ_v (eq 15).
    pub c: SMatrix<f64, 1, NX>,
}

impl Vehicle {
    /// A vehicle at speed `v` (m/s).
    pub fn new(p: VehicleParams, v: f64) -> Self {
        Vehicle { p, v }
    }

    /// Time derivative of the state, eqs 9-12 and A.2 as in model-notes, with the secondary
    /// lateral bump stops acting beyond their clearance (docs/model.md D49).
    pub fn deriv(&self, x: &State, delta_a: f64, w: &TrackInput) -> State {
        self.deriv_with(x, delta_a, w, true)
    }

    /// [`Vehicle::deriv`] with (`stops`) or without the bump stops: without, the model is
    /// the paper's, linear in x, u and ω.
    fn deriv_with(&self, x: &State, delta_a: f64, w: &TrackInput, stops: bool) -> State {
        let p = &self.p;
        let (y_v, th_v, y_b, th_b) = (x[0], x[1], x[2], x[3]);
        let (dy_v, dth_v, dy_b, dth_b) = (x[4], x[5], x[6], x[7]);
        let th_r = x[8];
        let v2k = self.v * self.v * w.curvature;

        // Secondary lateral deflection Δs, primary lateral deflection Δp, body-to-bogie roll ψ.
        let ds = y_v - p.h1 * th_v - y_b - p.h2 * th_b;
        let dds = dy_v - p.h1 * dth_v - dy_b - p.h2 * dth_b;
        let dp = y_b - p.h3 * th_b - w.y_o;
        let ddp = dy_b - p.h3 * dth_b - w.dy_o;
        let psi = th_v - th_b;
        let dpsi = dth_v - dth_b;

        // One side's secondary lateral spring-damper, and its bump stop past the clearance.
        let stop = if stops { p.bump_stop_force(ds) } else { 0.0 };
        let f_s = p.k_sy * ds + p.c_sy * dds + stop;
        let f_p = p.k_py * dp + p.c_py * ddp; // one primary lateral spring-damper
        let m_bar = p.k_vr * (psi - delta_a); // anti-roll bar moment on the body (active, eq 10)
        let m_air = 2.0 * p.d1 * p.d1 * (p.k_az * psi + p.k_sz * (th_v - th_r)); // airsprings, A.1

        // eq 9
        let ddy_v = (-2.0 * f_s) / p.m_v - v2k + G * w.cant - p.h_gv * w.cant_acc;
        // eq 10
        let ddth_v = (2.0 * p.h1 * f_s + p.m_v * G * (y_v - y_b) - m_bar - m_air - p.c_vr * dpsi)
            / p.i_vr
            - w.cant_acc;
        // eq 11
        let ddy_b = (2.0 * f_s - 2.0 * f_p) / p.m_b - v2k + G * w.cant - p.h_gb * w.cant_acc;
        // eq 12
        let ddth_b = (2.0 * p.h2 * f_s + 2.0 * p.h3 * f_p + m_bar + m_air
            - 2.0 * p.d2 * p.d2 * (p.k_pz * th_b + p.c_pz * dth_b)
            + p.c_vr * dpsi)
            / p.i_br
            - w.cant_acc;
        // A.2: c_rz (θ̇_r − θ̇_b) = k_sz (θ_v − θ_r) − k_rz (θ_r − θ_b)
        let dth_r = dth_b + (p.k_sz * (th_v - th_r) - p.k_rz * (th_r - th_b)) / p.c_rz;

        State::from_column_slice(&[
            dy_v, dth_v, dy_b, dth_b, ddy_v, ddth_v, ddy_b, ddth_b, dth_r,
        ])
    }

    /// Passenger lateral acceleration, eq 13 with θ_o + θ_v (model-notes 4) (m/s²).
    pub fn lateral_acceleration(&self, theta_v: f64, curvature: f64, cant: f64) -> f64 {
        let a = cant + theta_v;
        self.v * self.v * curvature * a.cos() - G * a.sin()
    }

    /// Velocity jump caused by a jump `d_rate` (rad/s) of the cant rate θ̇_o: the integral of
    /// the Dirac θ̈_o terms of eqs 9-12 across the corner.
    pub fn cant_rate_jump(&self, d_rate: f64) -> State {
        let mut j = State::zeros();
        j[ix::DY_V] = -self.p.h_gv * d_rate;
        j[ix::DTH_V] = -d_rate;
        j[ix::DY_B] = -self.p.h_gb * d_rate;
        j[ix::DTH_B] = -d_rate;
        j
    }

    /// The state-space matrices of eq 14, built from [`Vehicle::deriv`] itself without the
    /// bump stops (the model inside the clearance is linear in x, u and ω, so unit-vector
    /// evaluations give the exact matrices): one source of truth for simulation and
    /// controller design.
    pub fn state_space(&self) -> StateSpace {
        let zero = TrackInput::default();
        let deriv = |x: &State, u: f64, w: &TrackInput| self.deriv_with(x, u, w, false);
        let f0 = deriv(&State::zeros(), 0.0, &zero);
        let mut a = SMatrix::<f64, NX, NX>::zeros();
        for j in 0..NX {
            let mut e = State::zeros();
            e[j] = 1.0;
            a.set_column(j, &(deriv(&e, 0.0, &zero) - f0));
        }
        let b = deriv(&State::zeros(), 1.0, &zero) - f0;
        let mut g = SMatrix::<f64, NX, 6>::zeros();
        for j in 0..6 {
            let mut w = TrackInput::default();
            match j {
                0 => w.curvature = 1.0,
                1 => w.cant = 1.0,
                2 => w.cant_rate = 1.0,
                3 => w.cant_acc = 1.0,
                4 => w.y_o = 1.0,
                _ => w.dy_o = 1.0,
            }
            g.set_column(j, &(deriv(&State::zeros(), 0.0, &w) - f0));
        }
        let mut c = SMatrix::<f64, 1, NX>::zeros();
        c[ix::TH_V] = 1.0;
        StateSpace { a, b, g, c }
    }
}
