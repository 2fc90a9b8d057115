//! LQG servo (section 3.2): LQI state feedback on the augmented state `z = [x; x_I]`
//! (eqs 19-26) and a Kalman filter (eqs 27-29), both from continuous Riccati equations solved
//! by [`crate::linalg::care`], run at the controller's period.
//!
//! Readings (docs/model.md D10-D11):
//! * the LQI Riccati equation uses the input column only, `B_I = [Φ; 0]` (model-notes);
//! * eqs 28-29 use Ψ where Φ is printed: `ΠP + PΠᵀ + ΓW_nΓᵀ − PΨᵀV_n⁻¹ΨP = 0`,
//!   `K_est = PΨᵀV_n⁻¹`;
//! * W_n's six entries weight ω = [1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o] in that order;
//! * discretisation at period T: plant model by zero-order hold, the filter's correction by
//!   `T·K_est` (exact to first order in T·‖K_est Ψ‖; T = 1 ms here and the test checks the
//!   discrete loop's spectral radius), the integrator by forward Euler, `x_I += T (r − ξ)`.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::design::{DiscreteModel, LinearModel};
use crate::linalg::{care, care_residual, DesignError};
use tiltsim_protocol::settings::Checker;

/// LQI weights (scenario `[controller.lqg]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LqgSettings {
    /// Diagonal of Q_w over z = [y_v, θ_v, y_b, θ_b, ẏ_v, θ̇_v, ẏ_b, θ̇_b, θ_r, x_I] (eq 24).
    pub q_diag: Vec<f64>,
    /// R_w (eq 24).
    pub r_w: f64,
    /// Limit the command to the actuator's range `controller.u_max_deg`, with conditional
    /// integration (default); `false` is the paper's LQI, which has no saturation (D14).
    pub limit_command: bool,
}

impl Default for LqgSettings {
    fn default() -> Self {
        let mut q = vec![0.1; 10];
        q[1] = 1000.0;
        q[9] = 1000.0;
        LqgSettings {
            q_diag: q,
            r_w: 1.0,
            limit_command: true,
        }
    }
}

/// Kalman filter design values (scenario `[controller.kalman]`), shared by LQG and MPC.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct KalmanSettings {
    /// Diagonal of W_n (eq 17), intensities of ω = [1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o].
    pub w_n: Vec<f64>,
    /// V_n (eq 16), the measurement noise design value (rad²·s for the continuous filter,
    /// rad² per sample for the MPC's discrete one).
    pub v_n: f64,
    /// MPC only: variance per sample of the integrated output disturbance (rad²).
    pub disturbance_var: f64,
    /// Feed the known track input (curvature and cant from the onboard database) into the
    /// estimator's model. Off in the paper's design; on for the preview variant.
    pub track_input: bool,
}

impl Default for KalmanSettings {
    fn default() -> Self {
        KalmanSettings {
            w_n: vec![2.1e-7, 2.23e-3, 5.4e-4, 0.0, 0.0, 0.0],
            v_n: 0.10,
            disturbance_var: 0.05,
            track_input: false,
        }
    }
}

impl LqgSettings {
    /// Checks every field.
    pub fn validate(&self, c: &mut Checker) {
        c.require(
            self.q_diag.len() == 10,
            "lqg.q_diag",
            format!("{} entries", self.q_diag.len()),
            "exactly 10 entries (9 states and the integrator)",
        );
        for (i, q) in self.q_diag.iter().enumerate() {
            c.range(&format!("lqg.q_diag[{i}]"), *q, 0.0, 1e9, "");
        }
        // The integrator x_I is a pole at the origin that no other state sees: without a
        // weight of its own (Q not detectable through it) the Riccati equation of eq 24 has
        // no stabilising solution.
        if let Some(q) = self.q_diag.get(9) {
            c.require(
                *q > 0.0,
                "lqg.q_diag[9]",
                *q,
                "a weight > 0 on the integrator x_I (10th entry): without it the LQI design of eq 24 has no stabilising solution",
            );
        }
        c.positive("lqg.r_w", self.r_w, 1e9, "");
    }
}

impl KalmanSettings {
    /// Checks every field.
    pub fn validate(&self, c: &mut Checker) {
        c.require(
            self.w_n.len() == 6,
            "kalman.w_n",
            format!("{} entries", self.w_n.len()),
            "exactly 6 entries (1/R, θ_o, θ̇_o, θ̈_o, y_o, ẏ_o)",
        );
        for (i, w) in self.w_n.iter().enumerate() {
            c.range(&format!("kalman.w_n[{i}]"), *w, 0.0, 1e6, "");
        }
        c.positive("kalman.v_n", self.v_n, 1e6, "rad²");
        c.range(
            "kalman.disturbance_var",
            self.disturbance_var,
            0.0,
            1e3,
            "rad²",
        );
    }
}

/// The LQG design: gains and the Riccati solutions, with their residuals.
#[derive(Debug, Clone)]
pub struct LqgDesign {
    /// K_op = [K_f, −K_I] (1×10), eq 26.
    pub k_op: DMatrix<f64>,
    /// P_k (10×10), eq 25.
    pub p_k: DMatrix<f64>,
    /// Relative residual of eq 25.
    pub residual_k: f64,
    /// K_est (9×1), eq 29.
    pub k_est: DMatrix<f64>,
    /// P_e (9×9), eq 28.
    pub p_e: DMatrix<f64>,
    /// Relative residual of eq 28.
    pub residual_e: f64,
    /// Augmented matrices Π_I (10×10) and [Φ; 0] (10×1), eq 22.
    pub a_i: DMatrix<f64>,
    /// Input column of Φ_I.
    pub b_i: DMatrix<f64>,
}

fn rel(res: &DMatrix<f64>, scale: &DMatrix<f64>) -> f64 {
    res.norm() / scale.norm().max(1e-300)
}

/// Γ W_n Γᵀ (9×9).
pub fn process_noise(m: &LinearModel, w_n: &[f64]) -> DMatrix<f64> {
    let w = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(w_n));
    &m.g * w * m.g.transpose()
}

impl LqgDesign {
    /// Solves eqs 25 and 28.
    pub fn new(m: &LinearModel, s: &LqgSettings, k: &KalmanSettings) -> Result<Self, DesignError> {
        let mut a_i = DMatrix::zeros(10, 10);
        a_i.view_mut((0, 0), (9, 9)).copy_from(&m.a);
        a_i.view_mut((9, 0), (1, 9)).copy_from(&(-&m.c));
        let mut b_i = DMatrix::zeros(10, 1);
        b_i.view_mut((0, 0), (9, 1)).copy_from(&m.b);
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&s.q_diag));
        let r = DMatrix::from_element(1, 1, s.r_w);
        let p_k = care(&a_i, &b_i, &q, &r)?;
        let residual_k = rel(&care_residual(&a_i, &b_i, &q, &r, &p_k), &q);
        let k_op = b_i.transpose() * &p_k / s.r_w;
        // Filter Riccati equation (eq 28) is the dual CARE: A → Πᵀ, B → Ψᵀ.
        let qn = process_noise(m, &k.w_n);
        let vn = DMatrix::from_element(1, 1, k.v_n);
        let at = m.a.transpose();
        let ct = m.c.transpose();
        let p_e = care(&at, &ct, &qn, &vn)?;
        let residual_e = rel(&care_residual(&at, &ct, &qn, &vn, &p_e), &qn);
        let k_est = &p_e * &ct / k.v_n;
        Ok(LqgDesign {
            k_op,
            p_k,
            residual_k,
            k_est,
            p_e,
            residual_e,
            a_i,
            b_i,
        })
    }
}

/// The running LQG servo at period T.
#[derive(Debug, Clone)]
pub struct Lqg {
    /// The design.
    pub design: LqgDesign,
    d: DiscreteModel,
    /// Correction gain T·K_est.
    l: DMatrix<f64>,
    /// A-priori estimate x̂(k|k−1).
    x_hat: DMatrix<f64>,
    /// Integrator x_I = ∫(r − ξ) dt (rad·s).
    x_i: f64,
    track_input: bool,
    /// Command limit |u| (rad); unbounded unless [`Lqg::with_limit`] sets it.
    u_max: f64,
}

/// One controller update's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Update {
    /// Command u = δ_a,cmd (rad).
    pub u: f64,
    /// Filtered estimate θ̂_v(k|k) (rad).
    pub theta_v_hat: f64,
}

impl Lqg {
    /// The servo for model `m` at period `t`.
    pub fn new(
        m: &LinearModel,
        s: &LqgSettings,
        k: &KalmanSettings,
        t: f64,
    ) -> Result<Self, DesignError> {
        let design = LqgDesign::new(m, s, k)?;
        let l = &design.k_est * t;
        Ok(Lqg {
            design,
            d: m.discretise(t),
            l,
            x_hat: DMatrix::zeros(9, 1),
            x_i: 0.0,
            track_input: k.track_input,
            u_max: f64::INFINITY,
        })
    }

    /// The servo with its command limited to ±`u_max` (rad), the actuator's range: the
    /// command is clamped, the integrator holds while the command is clamped and the error
    /// would drive it further out (conditional integration, the anti-windup of the PI), and
    /// the estimator is told the command actually sent.
    pub fn with_limit(mut self, u_max: f64) -> Self {
        self.u_max = u_max;
        self
    }

    /// One update with measurement ξ, reference r and the track input ω at this sample.
    pub fn step(&mut self, xi: f64, r: f64, w: &[f64; 6]) -> Update {
        let innovation = xi - (&self.d.c * &self.x_hat)[(0, 0)];
        let x_f = &self.x_hat + &self.l * innovation;
        let k = &self.design.k_op;
        let kf = k.view((0, 0), (1, 9));
        // u = −K_op z = −K_f x̂ + K_I x_I (eq 19 with K_op = [K_f, −K_I]).
        let free = -(kf * &x_f)[(0, 0)] - k[(0, 9)] * self.x_i;
        let u = free.clamp(-self.u_max, self.u_max);
        // A step of x_I moves u by −k_I·T·(r − ξ): held while clamped if it would push further.
        let push = -k[(0, 9)] * (r - xi);
        if u == free || push.signum() != free.signum() {
            self.x_i += self.d.t * (r - xi);
        }
        let mut next = &self.d.a * &x_f + &self.d.b * u;
        if self.track_input {
            next += &self.d.g * DMatrix::from_column_slice(6, 1, w);
        }
        self.x_hat = next;
        Update {
            u,
            theta_v_hat: x_f[(1, 0)],
        }
    }

    /// The discrete closed loop of plant, filter and integrator (19 states: x, x̂(k|k−1),
    /// x_I), for stability analysis.
    pub fn closed_loop(&self) -> DMatrix<f64> {
        let (a, b, c, t) = (&self.d.a, &self.d.b, &self.d.c, self.d.t);
        let k = &self.design.k_op;
        let kf = k.view((0, 0), (1, 9)).into_owned();
        let ki = k[(0, 9)];
        let id = DMatrix::<f64>::identity(9, 9);
        // x_f = (I − L C) x̂ + L C x;  u = −K_f x_f − k_I x_I
        let lc = &self.l * c;
        let u_x = -(&kf * &lc); // coefficient of x in u
        let u_xh = -(&kf * (&id - &lc)); // of x̂
        let mut m = DMatrix::zeros(19, 19);
        m.view_mut((0, 0), (9, 9)).copy_from(&(a + b * &u_x));
        m.view_mut((0, 9), (9, 9)).copy_from(&(b * &u_xh));
        m.view_mut((0, 18), (9, 1)).copy_from(&(b * -ki));
        m.view_mut((9, 0), (9, 9)).copy_from(&(a * &lc + b * &u_x));
        m.view_mut((9, 9), (9, 9))
            .copy_from(&(a * (&id - &lc) + b * &u_xh));
        m.view_mut((9, 18), (9, 1)).copy_from(&(b * -ki));
        m.view_mut((18, 0), (1, 9)).copy_from(&(-c * t));
        m[(18, 18)] = 1.0;
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vehicle_model::{TrackParams, VehicleParams};

    /// The servo in closed loop with its own discretised vehicle for `n` steps of 1 ms at
    /// reference `r`; returns the commands sent.
    fn drive(lqg: &mut Lqg, x: &mut DMatrix<f64>, r: f64, n: usize) -> Vec<f64> {
        let d = lqg.d.clone();
        (0..n)
            .map(|_| {
                let xi = (&d.c * &*x)[(0, 0)];
                let u = lqg.step(xi, r, &[0.0; 6]).u;
                *x = &d.a * &*x + &d.b * u;
                u
            })
            .collect()
    }

    #[test]
    fn a_limited_servo_holds_its_integrator_and_leaves_the_limit_at_once() {
        let m = LinearModel::new(&VehicleParams::default(), TrackParams::default().speed());
        let new = || {
            Lqg::new(
                &m,
                &LqgSettings::default(),
                &KalmanSettings::default(),
                1e-3,
            )
        };
        let u_max = 3.5f64.to_radians();
        let mut limited = new().unwrap().with_limit(u_max);
        let mut free = new().unwrap();
        let (mut xl, mut xf) = (DMatrix::zeros(9, 1), DMatrix::zeros(9, 1));
        // A body roll of 10° asks far more than ±3.5° of bar can give.
        let r = 10f64.to_radians();
        let mut ul = drive(&mut limited, &mut xl, r, 1000);
        let wound = limited.x_i;
        ul.extend(drive(&mut limited, &mut xl, r, 2000));
        let uf = drive(&mut free, &mut xf, r, 3000);
        assert!(ul.iter().all(|u| u.abs() <= u_max), "never past the limit");
        assert!(
            uf.iter().any(|u| u.abs() > 2.0 * u_max),
            "the demand is beyond the limit"
        );
        let at_limit = ul.iter().filter(|u| u.abs() == u_max).count();
        assert!(at_limit > 2500, "{at_limit} of 3000 steps at the limit");
        // Conditional integration: clamped all along the last 2 s with an error it cannot
        // remove, the integrator has not moved (unheld, it would have grown by 2 s times the
        // error of several degrees: more than 0.1 rad·s).
        assert!(ul[1000..].iter().all(|u| u.abs() == u_max));
        assert_eq!(
            limited.x_i, wound,
            "x_I moved while the command was clamped"
        );
        // Back to level: the command leaves the limit as soon as the body's state feedback
        // turns (0.34 s); with the integrator left to wind over those 2 s it stays there for
        // more than the whole second that follows.
        let back = drive(&mut limited, &mut xl, 0.0, 1000);
        let held = back.iter().take_while(|u| u.abs() == u_max).count();
        assert!(
            held < 500,
            "held at the limit for {held} ms after the reference fell"
        );
    }
}
