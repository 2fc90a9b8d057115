//! `controller-proc`: the tilt controller.
//!
//! The controller knows the track only through its onboard database (design curvature and
//! cant along the route, [`vehicle_model::Track::design`]) and the vehicle's position, never
//! through the plant's state. Modes (`controller.mode`):
//! * `passive`: zero command (a non-tilting vehicle); the reference is still computed and
//!   recorded.
//! * `pi`: the PI regulator of Table 3 on the roll error θ_v^d − θ_v,meas, with conditional
//!   integration (anti-windup) against the actuator's range `u_max_deg`.
//! * `lqg`: the LQG servo of section 3.2 ([`lqg`]).
//! * `mpc`: MPC with a built-in Kalman filter, section 3.3 ([`mpc`]), optionally with preview.
//!
//! [`linalg`] holds the Riccati solvers and discretisation, [`design`] the linear model.

pub mod design;
pub mod linalg;
pub mod lqg;
pub mod mpc;
pub mod pi_loop;

use cosim::msg::{FromController, ToController};
use cosim::settings::Checker;
use cosim::{Participant, Role};
use serde::{Deserialize, Serialize};
use vehicle_model::{Track, TrackParams, Vehicle, VehicleParams, G};

pub use design::LinearModel;
pub use lqg::{KalmanSettings, Lqg, LqgSettings};
pub use mpc::{InputShape, Mpc, MpcSettings, QpRows};

/// Outcome of a controller update's QP, as carried in `FromController::solver_status`.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverStatus {
    /// No QP in this update (not an MPC).
    NoQp = 0,
    /// Solved (or almost solved) to Clarabel's tolerances.
    Solved = 1,
    /// Not solved; the previous command was held.
    Failed = 2,
}

impl SolverStatus {
    /// Decodes the value carried in a sample (anything unknown counts as a failure).
    pub fn from_raw(v: u32) -> Self {
        match v {
            0 => SolverStatus::NoQp,
            1 => SolverStatus::Solved,
            _ => SolverStatus::Failed,
        }
    }
}

/// Controller mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// δ_a,cmd = 0.
    #[default]
    Passive,
    /// PI regulator (section 3.1, Table 3).
    Pi,
    /// LQG servo (section 3.2).
    Lqg,
    /// MPC with Kalman filter (section 3.3).
    Mpc,
}

/// Controller settings (scenario section `[controller]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerSettings {
    /// Mode.
    pub mode: Mode,
    /// Reduction ρ of the non-tilting lateral acceleration (eq 18); 0.30 in the paper.
    pub rho: f64,
    /// How the tilt command inverts eq 13: `small-angle` (eq 18 as printed, the default) or
    /// `exact` (docs/model.md D9).
    pub tilt_inverse: TiltInverse,
    /// Controller period (s); a multiple of the base tick.
    pub period_s: f64,
    /// Bar command limit |δ_a,cmd| (deg): the actuator's range (section 3.3: ±3.5°).
    pub u_max_deg: f64,
    /// PI gains (Table 3).
    pub pi: PiGains,
    /// LQI weights (section 3.2).
    pub lqg: LqgSettings,
    /// MPC settings (section 3.3).
    pub mpc: MpcSettings,
    /// Kalman filter design values (LQG and MPC).
    pub kalman: KalmanSettings,
}

/// How the tilt command θ_v^d is obtained from the desired acceleration ÿ^d = (1 − ρ)·ÿ_passive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum TiltInverse {
    /// Eq 18: eq 13 linearised (cos φ ≈ 1, sin φ ≈ φ), θ_v^d = v²κ/g − ÿ^d/g − θ_o. Leaves
    /// 68.9 % of the passive acceleration on the paper's curve at ρ = 0.30, not 70 %.
    #[default]
    SmallAngle,
    /// Eq 13 solved exactly for φ = θ_o + θ_v: v²κ cos φ − g sin φ = ÿ^d.
    Exact,
}

/// PI gains of Table 3: δ_a,cmd = K_p·e + K_i·∫e dt, e = θ_v^d − θ_v (rad → rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PiGains {
    /// Proportional gain K_p (rad/rad).
    pub kp: f64,
    /// Integral gain K_i (1/s).
    pub ki: f64,
}

impl Default for PiGains {
    fn default() -> Self {
        PiGains {
            kp: 38.24,
            ki: 27.36,
        }
    }
}

/// Discrete PI with conditional integration: the integrator holds while the output is saturated
/// and the error would drive it further into saturation.
#[derive(Debug, Clone, Default)]
pub struct Pi {
    /// Gains.
    pub gains: PiGains,
    /// Output limit (rad).
    pub u_max: f64,
    /// Integrator state ∫e dt (rad·s).
    pub integral: f64,
}

impl Pi {
    /// One update with error `e` (rad) over period `dt` (s); returns the saturated command (rad).
    pub fn step(&mut self, e: f64, dt: f64) -> f64 {
        let g = &self.gains;
        let trial = g.kp * e + g.ki * (self.integral + e * dt);
        let saturated = trial.abs() > self.u_max;
        if !saturated || trial.signum() != e.signum() {
            self.integral += e * dt;
        }
        (g.kp * e + g.ki * self.integral).clamp(-self.u_max, self.u_max)
    }
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            mode: Mode::Passive,
            rho: 0.30,
            tilt_inverse: TiltInverse::SmallAngle,
            period_s: 1e-3,
            u_max_deg: 3.5,
            pi: PiGains::default(),
            lqg: LqgSettings::default(),
            mpc: MpcSettings::default(),
            kalman: KalmanSettings::default(),
        }
    }
}

impl ControllerSettings {
    /// Checks every field.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        c.range("rho", self.rho, 0.0, 1.0, "");
        c.positive("period_s", self.period_s, 1.0, "s");
        c.positive("u_max_deg", self.u_max_deg, 20.0, "deg");
        c.range("pi.kp", self.pi.kp, 0.0, 1e4, "rad/rad");
        c.range("pi.ki", self.pi.ki, 0.0, 1e5, "1/s");
        self.lqg.validate(&mut c);
        self.mpc.validate(&mut c);
        self.kalman.validate(&mut c);
        c
    }
}

/// What the controller process receives: its settings plus the onboard track database.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ControllerInit {
    /// Controller settings.
    pub controller: ControllerSettings,
    /// Track database (the design geometry is used, never the irregularity).
    pub track: TrackParams,
    /// The vehicle's design model (the same parameters as the plant: one source of truth).
    pub vehicle: VehicleParams,
    /// How the actuator applies each new command (`actuator.command_shaping`); the MPC's
    /// prediction model assumes the same.
    pub input_shape: InputShape,
}

/// Tilt command of eq 18: θ_v^d = v²/(gR) − ÿ^d/g − θ_o with ÿ^d = (1 − ρ)·ÿ_passive.
///
/// ÿ_passive is the non-tilting vehicle's quasi-static lateral acceleration at this track point:
/// eq 13 evaluated with the passive vehicle's quasi-static roll `theta_v_passive` (it rolls
/// outwards about 1° on the paper's curve). This reading reproduces the paper's own numbers:
/// Table 4's PI peak of 8.49 %g = 0.70 × 1.18 m/s², and δ_a ≈ 2.4° on the steady curve
/// (model-notes). See docs/model.md, D9.
pub fn tilt_reference(v: f64, curvature: f64, cant: f64, theta_v_passive: f64, rho: f64) -> f64 {
    tilt_command(
        TiltInverse::SmallAngle,
        v,
        curvature,
        cant,
        theta_v_passive,
        rho,
    )
}

/// The tilt command for ÿ^d = (1 − ρ)·ÿ_passive by inverse `inverse` of eq 13 (see
/// [`tilt_reference`] for ÿ_passive). `Exact` solves a cos φ − g sin φ = ÿ^d, a = v²κ, as
/// r cos(φ + α) = ÿ^d with r = √(a² + g²), α = atan2(g, a): φ = acos(ÿ^d/r) − α, the root
/// near zero (|ÿ^d| ≤ (1 − ρ) r, so the arc cosine is defined); θ_v^d = φ − θ_o.
pub fn tilt_command(
    inverse: TiltInverse,
    v: f64,
    curvature: f64,
    cant: f64,
    theta_v_passive: f64,
    rho: f64,
) -> f64 {
    let a = cant + theta_v_passive;
    let a_c = v * v * curvature;
    let a_passive = a_c * a.cos() - G * a.sin();
    let a_desired = (1.0 - rho) * a_passive;
    match inverse {
        TiltInverse::SmallAngle => a_c / G - a_desired / G - cant,
        TiltInverse::Exact => {
            let r = a_c.hypot(G);
            (a_desired / r).clamp(-1.0, 1.0).acos() - G.atan2(a_c) - cant
        }
    }
}

/// The passive vehicle's quasi-static body roll per unit curvature and per unit cant, from the
/// design model: x_ss = −Π⁻¹ Γ ω (eq 14 at rest).
pub fn passive_roll_gains(vehicle: &VehicleParams, v: f64) -> (f64, f64) {
    let ss = Vehicle::new(vehicle.clone(), v).state_space();
    let Some(inv) = ss.a.try_inverse() else {
        return (0.0, 0.0);
    };
    let x_k = -(inv * ss.g.column(0));
    let x_c = -(inv * ss.g.column(1));
    (
        x_k[vehicle_model::vehicle::ix::TH_V],
        x_c[vehicle_model::vehicle::ix::TH_V],
    )
}

/// The control law in use.
enum Law {
    Passive,
    Pi(Pi),
    Lqg(Box<Lqg>),
    Mpc(Box<Mpc>),
}

/// The controller participant.
pub struct Controller {
    s: ControllerSettings,
    track: Track,
    v: f64,
    law: Law,
    /// Passive quasi-static roll per unit curvature (rad·m) and per unit cant (rad/rad).
    roll_gains: (f64, f64),
}

impl Controller {
    /// Builds the controller, its design and its track database. Fails if a Riccati equation
    /// or the QP set-up has no solution for these settings.
    pub fn new(init: &ControllerInit) -> Result<Self, String> {
        let mut db = init.track.clone();
        db.irregularity.amplitude_deg = 0.0;
        let c = &init.controller;
        let v = db.speed();
        let model = || LinearModel::new(&init.vehicle, v);
        let law = match c.mode {
            Mode::Passive => Law::Passive,
            Mode::Pi => Law::Pi(Pi {
                gains: c.pi.clone(),
                u_max: c.u_max_deg.to_radians(),
                integral: 0.0,
            }),
            Mode::Lqg => Law::Lqg(Box::new(
                Lqg::new(&model(), &c.lqg, &c.kalman, c.period_s)
                    .map_err(|e| format!("LQG design: {e}"))?,
            )),
            Mode::Mpc => Law::Mpc(Box::new(
                Mpc::new(
                    &model(),
                    &c.mpc,
                    &c.kalman,
                    c.period_s,
                    c.u_max_deg,
                    init.input_shape,
                )
                .map_err(|e| format!("MPC design: {e}"))?,
            )),
        };
        let roll_gains = passive_roll_gains(&init.vehicle, v);
        Ok(Controller {
            s: c.clone(),
            track: Track::new(&db, 0),
            v,
            law,
            roll_gains,
        })
    }

    /// Eq 18 at track position `s` (m).
    pub fn reference_at(&self, s: f64) -> f64 {
        let (curvature, cant) = self.track.design(s);
        let theta_passive = self.roll_gains.0 * curvature + self.roll_gains.1 * cant;
        tilt_command(
            self.s.tilt_inverse,
            self.v,
            curvature,
            cant,
            theta_passive,
            self.s.rho,
        )
    }

    /// The track input ω = [1/R, θ_o, θ̇_o, 0, 0, 0] from the database at `s` (θ̈_o is
    /// impulsive at the ramp corners and zero elsewhere; lateral irregularity is unknown).
    pub fn track_input_at(&self, s: f64) -> [f64; 6] {
        let (k, c) = self.track.design(s);
        let h = 0.01;
        let rate = self.v * (self.track.design(s + h).1 - self.track.design(s - h).1) / (2.0 * h);
        [k, c, rate, 0.0, 0.0, 0.0]
    }

    fn compute(&mut self, input: &ToController) -> FromController {
        let theta_ref = self.reference_at(input.s);
        let mut out = FromController {
            theta_ref,
            theta_v_hat: input.theta_v_meas,
            ..Default::default()
        };
        let w = self.track_input_at(input.s);
        match &mut self.law {
            Law::Passive => {}
            Law::Pi(pi) => {
                out.delta_a_cmd = pi.step(theta_ref - input.theta_v_meas, self.s.period_s);
            }
            Law::Lqg(lqg) => {
                let u = lqg.step(input.theta_v_meas, theta_ref, &w);
                out.delta_a_cmd = u.u;
                out.theta_v_hat = u.theta_v_hat;
            }
            Law::Mpc(_) => {
                let (r, w) = self.horizon(input.s, theta_ref);
                let Law::Mpc(mpc) = &mut self.law else {
                    unreachable!()
                };
                let u = mpc.step(&mpc::MpcInput {
                    xi: input.theta_v_meas,
                    r: &r,
                    w: &w,
                });
                out.delta_a_cmd = u.u;
                out.theta_v_hat = u.theta_v_hat;
                out.solver_iterations = u.iterations;
                out.solver_status = if u.solved {
                    SolverStatus::Solved
                } else {
                    SolverStatus::Failed
                } as u32;
            }
        }
        out
    }

    /// References r(k+1..k+p) and track inputs ω(k..k+p−1) over the MPC horizon: held at
    /// their current values, or read ahead from the database with preview.
    fn horizon(&self, s: f64, theta_ref: f64) -> (Vec<f64>, Vec<[f64; 6]>) {
        let Law::Mpc(mpc) = &self.law else {
            return (Vec::new(), Vec::new());
        };
        let p = mpc.horizon();
        let ds = self.v * self.s.period_s;
        if mpc.preview() {
            let r = (1..=p)
                .map(|i| self.reference_at(s + ds * i as f64))
                .collect();
            let w = (0..p)
                .map(|j| self.track_input_at(s + ds * j as f64))
                .collect();
            (r, w)
        } else {
            (vec![theta_ref; p], vec![self.track_input_at(s); p])
        }
    }
}

impl Participant for Controller {
    type Input = ToController;
    type Output = FromController;
    const ROLE: Role = Role::Controller;

    fn initial_output(&mut self) -> FromController {
        FromController::default()
    }
    fn step(&mut self, input: &ToController) -> FromController {
        self.compute(input)
    }
}

/// Participant process entry: `--params JSON --prefix P --wait W`.
pub fn serve(args: &[String]) -> Result<(), cosim::ipc::ServeError> {
    cosim::ipc::participant_main(args, |s: ControllerInit| Controller::new(&s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pi_matches_its_closed_form_and_does_not_wind_up() {
        // Constant error e inside the limits: u_n = Kp·e + Ki·n·dt·e.
        let mut pi = Pi {
            gains: PiGains::default(),
            u_max: 1.0,
            integral: 0.0,
        };
        let (e, dt) = (1e-3, 1e-3);
        let mut u = 0.0;
        for _ in 0..100 {
            u = pi.step(e, dt);
        }
        assert!((u - (38.24 * e + 27.36 * 0.1 * e)).abs() < 1e-12);
        // A large error saturates; the integrator stops growing, so the output leaves the
        // limit as soon as the error reverses.
        for _ in 0..10_000 {
            assert_eq!(pi.step(0.5, dt), 1.0);
        }
        let frozen = pi.integral;
        assert!(frozen < 0.1, "integrator wound up to {frozen}");
        assert!(pi.step(-0.01, dt) < 1.0);
    }

    #[test]
    fn reference_reduces_the_passive_lateral_acceleration_by_rho() {
        // Tilting the body by θ_v^d leaves ÿ = v²κ cos(θo+θv) − g sin(θo+θv) ≈ (1−ρ)·ÿ_passive,
        // where ÿ_passive includes the passive vehicle's quasi-static roll.
        let (v, k, c) = (45.0, 1e-3, 6f64.to_radians());
        let (gk, gc) = passive_roll_gains(&VehicleParams::default(), v);
        let th_p = gk * k + gc * c;
        // The static force and moment solve of tests/vehicle_physics.rs gives −1.0239°.
        assert!(
            (th_p.to_degrees() + 1.0239).abs() < 5e-4,
            "passive roll {} deg",
            th_p.to_degrees()
        );
        let a = |th: f64| v * v * k * (c + th).cos() - G * (c + th).sin();
        assert!(
            (a(th_p) - 1.164).abs() < 0.01,
            "passive lateral acceleration {}",
            a(th_p)
        );
        let r = tilt_reference(v, k, c, th_p, 0.3);
        // Eq 18 linearises sin/cos at about 6-7°: the achieved ratio is 0.689, within 0.015
        // of 1 − ρ.
        assert!((a(r) / a(th_p) - 0.7).abs() < 0.015, "{}", a(r) / a(th_p));
        assert!((a(r) / a(th_p) - 0.689).abs() < 5e-4, "{}", a(r) / a(th_p));
        assert_eq!(tilt_reference(v, 0.0, 0.0, 0.0, 0.3), 0.0);
    }

    #[test]
    fn the_exact_inverse_leaves_exactly_one_minus_rho_of_the_passive_acceleration() {
        // Eq 13 at the exact command must give (1 − ρ)·ÿ_passive to rounding (1e-12 m/s²),
        // on the paper's steady curve, on a left-hand curve, without cant, and for ρ from 0 to 1;
        // on the straight the command is zero; and it differs from eq 18 by the small-angle
        // error: θ^d_exact − θ^d_eq18 ≈ −(ÿ_eq18 − ÿ^d)/(dÿ/dφ), φ ≈ 7°, a few hundredths of a
        // degree (closed form below, to 2 %).
        let v = 45.0;
        let (gk, gc) = passive_roll_gains(&VehicleParams::default(), v);
        for (k, c) in [
            (1e-3, 6f64.to_radians()),
            (-1e-3, -6f64.to_radians()),
            (1e-3, 0.0),
            (5e-4, 3f64.to_radians()),
        ] {
            let th_p = gk * k + gc * c;
            let a = |th: f64| v * v * k * (c + th).cos() - G * (c + th).sin();
            for rho in [0.0, 0.3, 0.5, 1.0] {
                let r = tilt_command(TiltInverse::Exact, v, k, c, th_p, rho);
                let want = (1.0 - rho) * a(th_p);
                assert!(
                    (a(r) - want).abs() < 1e-12,
                    "κ {k}, cant {c}, ρ {rho}: ÿ {} vs {want}",
                    a(r)
                );
                let small = tilt_command(TiltInverse::SmallAngle, v, k, c, th_p, rho);
                let slope = -v * v * k * (c + small).sin() - G * (c + small).cos();
                let predicted = small - (a(small) - want) / slope;
                assert!(
                    (r - predicted).abs() < 0.02 * (r - small).abs().max(1e-9),
                    "one Newton step from eq 18 predicts {predicted}, exact {r}"
                );
            }
        }
        assert_eq!(tilt_command(TiltInverse::Exact, v, 0.0, 0.0, 0.0, 0.3), 0.0);
    }
}

#[cfg(test)]
mod design_tests {
    use super::*;
    use crate::linalg::{spectral_abscissa, spectral_radius};

    fn model() -> LinearModel {
        LinearModel::new(&VehicleParams::default(), TrackParams::default().speed())
    }

    /// One update of the MPC's closed loop along the paper's drive, before the MPC steps.
    struct DriveUpdate<'a> {
        step: usize,
        /// The previous command u(k−1) (rad).
        u_prev: f64,
        /// The free response of the update (from the filtered measurement).
        f: Vec<f64>,
        /// The references over the horizon.
        r: &'a [f64],
    }

    /// Runs `mpc` (horizon 5, period `period`) in closed loop with the discretised vehicle
    /// along the paper's track at ρ = 0.50, the reference held over the horizon and a small
    /// deterministic measurement noise; `each` sees every update before the MPC steps, and
    /// gets the command it applied. Returns the number of updates.
    fn paper_drive(
        mpc: &mut Mpc,
        period: f64,
        mut each: impl FnMut(&mut Mpc, &DriveUpdate),
        mut applied: impl FnMut(&mpc::MpcUpdate),
    ) -> usize {
        let m = model();
        let track = TrackParams::default();
        let ctrl = Controller::new(&ControllerInit {
            controller: ControllerSettings {
                mode: Mode::Passive,
                rho: 0.5,
                ..Default::default()
            },
            track: track.clone(),
            vehicle: VehicleParams::default(),
            input_shape: InputShape::Hold,
        })
        .unwrap();
        let d = m.discretise(period);
        let v = track.speed();
        let mut x = nalgebra::DMatrix::zeros(9, 1);
        let mut u_prev = 0.0;
        let n = (track.length() / v / period) as usize;
        for step in 0..n {
            let pos = v * period * step as f64;
            let r = vec![ctrl.reference_at(pos); 5];
            let w = vec![ctrl.track_input_at(pos); 5];
            let xi = x[(1, 0)] + 1e-3 * ((step * 7) as f64).sin();
            let f = mpc.free_response(&mpc.filter(xi), &w);
            each(
                mpc,
                &DriveUpdate {
                    step,
                    u_prev,
                    f,
                    r: &r,
                },
            );
            let u = mpc.step(&mpc::MpcInput { xi, r: &r, w: &w });
            applied(&u);
            u_prev = u.u;
            let wk = nalgebra::DMatrix::from_column_slice(6, 1, &w[0]);
            x = &d.a * &x + &d.b * u.u + &d.g * wk;
        }
        n
    }

    #[test]
    fn lqg_riccati_residuals_vanish_and_its_loops_are_stable() {
        let m = model();
        let lqg = Lqg::new(
            &m,
            &LqgSettings::default(),
            &KalmanSettings::default(),
            1e-3,
        )
        .unwrap();
        let d = &lqg.design;
        // Residuals relative to ‖Q‖: double precision with condition numbers of ~1e6 leaves
        // about 1e-10.
        assert!(d.residual_k < 1e-9, "eq 25 residual {}", d.residual_k);
        assert!(d.residual_e < 1e-9, "eq 28 residual {}", d.residual_e);
        // P_k, P_e symmetric positive definite / semi-definite.
        assert!(d.p_k.symmetric_eigenvalues().min() > 0.0);
        assert!(d.p_e.symmetric_eigenvalues().min() > -1e-12 * d.p_e.norm());
        // Continuous LQI loop Π_I − B_I K_op and the filter Π − K_est Ψ: Re λ < 0.
        let a_cl = &d.a_i - &d.b_i * &d.k_op;
        assert!(spectral_abscissa(&a_cl) < 0.0);
        assert!(spectral_abscissa(&(&m.a - &d.k_est * &m.c)) < 0.0);
        // The discrete loop actually run (plant, filter at T = 1 ms, forward-Euler integrator).
        let rho = spectral_radius(&lqg.closed_loop());
        assert!(rho < 1.0, "discrete LQG loop spectral radius {rho}");
        // Integral gain: for a scalar integrator weight q_I and R_w = 1 the LQI integral gain
        // tends to √q_I when the plant is fast compared with the integrator; here within 10 %.
        let ki = -d.k_op[(0, 9)];
        assert!((ki / 1000f64.sqrt() - 1.0).abs() < 0.1, "K_I = {ki}");
        eprintln!("K_op = {}", d.k_op);
        eprintln!("K_est = {}", d.k_est.transpose());
    }

    #[test]
    fn mpc_meets_its_closed_form_in_closed_loop() {
        // The MPC in closed loop with the discretised vehicle along the paper's track at
        // ρ = 0.50 (the benchmark's drive, one pass). Wherever the unconstrained optimum
        // Δu* = −H⁻¹g keeps every constraint with room to spare it is the QP's optimum, and the
        // first move Clarabel returns must match it. Measured with the fitted settings: p50
        // 3.5e-9 rad, max 4.8e-6 rad; with Clarabel's equilibration and its 1e-8 tolerances the
        // same loop gives 2.8e-8 and 3.3e-5 (module notes of `mpc`).
        let period = 0.05;
        let mut mpc = Mpc::new(
            &model(),
            &MpcSettings::default(),
            &KalmanSettings::default(),
            period,
            3.5,
            InputShape::Hold,
        )
        .unwrap();
        let mut errors = Vec::new();
        let n = paper_drive(
            &mut mpc,
            period,
            |mpc, at| {
                let star = mpc.unconstrained(&at.f, at.r);
                let more: Vec<f64> = star.iter().map(|d| d * (1.0 + 1e-3)).collect();
                if mpc.keeps_constraints(at.u_prev, &at.f, &star)
                    && mpc.keeps_constraints(at.u_prev, &at.f, &more)
                {
                    let (du, _, ok) = mpc.solve(&at.f, at.r);
                    assert!(ok, "step {}: an unconstrained QP must solve", at.step);
                    errors.push((du[0] - star[0]).abs());
                }
            },
            |_| {},
        );
        // Both kinds of update occur: the limits bind in the curve transitions.
        assert!(
            errors.len() > 50 && errors.len() < n,
            "{} of {n}",
            errors.len()
        );
        errors.sort_by(f64::total_cmp);
        let (p50, max) = (errors[errors.len() / 2], errors[errors.len() - 1]);
        assert!(p50 < 1e-8, "p50 {p50:e} rad");
        assert!(max < 1e-5, "max {max:e} rad");
    }

    #[test]
    fn mpc_leaves_out_only_rows_that_cannot_bind() {
        // The paper's drive at ρ = 0.50 in closed loop, twice: with the paper's soft output
        // limit (6°), where the input limit binds in the curves, and with it lowered to 1.5°,
        // where the output limit binds (at 2.5° it never does). Where `rows_needed`
        // lets an update leave rows out, the full QP must give the same moves (both are
        // Clarabel's optimum of one problem to its 1e-10 gap: at most 1e-5 rad, the bound of
        // `mpc_meets_its_closed_form_in_closed_loop`). Where it keeps the output rows, the
        // update's prediction must keep the limit up to the slack its weight allows: a slack ε
        // costs λ_ε ε² against the tracking cost, here ε ≲ 1e-5 rad; 1e-4 rad is the bound.
        let period = 0.05;
        let (mut gaps, mut counts, mut binding) = (Vec::new(), [0; 3], [0; 3]);
        for theta_v_max_deg in [6.0, 1.5] {
            let s = MpcSettings {
                theta_v_max_deg,
                ..Default::default()
            };
            let (y_max, u_max) = (s.theta_v_max_deg.to_radians(), 3.5f64.to_radians());
            let k = KalmanSettings::default();
            let mut mpc = Mpc::new(&model(), &s, &k, period, 3.5, InputShape::Hold).unwrap();
            let last = std::cell::Cell::new(QpRows::Full);
            let inputs_binding = std::cell::Cell::new(0);
            paper_drive(
                &mut mpc,
                period,
                |mpc, at| {
                    let (f, r, step) = (&at.f, at.r, at.step);
                    let rows = mpc.rows_needed(f);
                    counts[rows as usize] += 1;
                    last.set(rows);
                    let (du, _, ok) = mpc.solve(f, r);
                    assert!(ok, "step {step}");
                    let (du_full, _, ok) = mpc.solve_with(f, r, QpRows::Full);
                    assert!(ok, "step {step}");
                    if rows == QpRows::Full {
                        assert_eq!(du, du_full, "step {step}: the full QP, solved twice");
                        let worst = (0..5)
                            .map(|i| {
                                (f[i] + mpc.theta[(i, 0)] * du[0] + mpc.theta[(i, 1)] * du[1]).abs()
                            })
                            .fold(0.0, f64::max);
                        assert!(worst <= y_max + 1e-4, "step {step}: |ξ| {worst} > {y_max}");
                        // Whether the limit binds, so that leaving its rows out would have
                        // mattered.
                        if worst > y_max - 1e-6 {
                            binding[0] += 1;
                        }
                    } else {
                        gaps.push((du[0] - du_full[0]).abs().max((du[1] - du_full[1]).abs()));
                    }
                },
                // Whether an input-level limit binds where those rows are kept.
                |u| {
                    if last.get() == QpRows::Inputs && u.u.abs() > u_max - 1e-9 {
                        inputs_binding.set(inputs_binding.get() + 1);
                    }
                },
            );
            binding[1] += inputs_binding.get();
        }
        eprintln!("updates per form (full, inputs, moves) {counts:?}, binding {binding:?}");
        // Every form occurs, and the limits they keep bind in some of their updates.
        assert!(counts.iter().all(|&c| c > 20), "{counts:?}");
        assert!(binding[0] > 5 && binding[1] > 5, "{binding:?}");
        gaps.sort_by(f64::total_cmp);
        let (p50, max) = (gaps[gaps.len() / 2], gaps[gaps.len() - 1]);
        eprintln!("|Δu − Δu_full| p50 {p50:e}, max {max:e} rad");
        assert!(p50 < 1e-8 && max < 1e-5, "p50 {p50:e}, max {max:e} rad");
    }

    #[test]
    fn one_move_mpc_meets_its_clamped_closed_form() {
        // With p = M = 1 the QP is one-dimensional, and where the soft output row cannot bind
        // its optimum is the unconstrained one, Δu* = −θ λ_ξ (f − r) / (θ² λ_ξ + λ_Δu),
        // clamped to the moves the hard limits allow: |Δu| ≤ Δu_max, |u(k−1) + Δu| ≤ u_max.
        // That holds with every constraint active or not, so it checks the constrained optima
        // exactly. Along the paper's drive at ρ = 0.50, both the reduced QP an update solves
        // and the full QP must meet it; measured p50 2.3e-10 and 3.9e-10, max 1.1e-6 and
        // 2.6e-6 rad (an interior point near an active bound); bounds as in
        // `mpc_meets_its_closed_form_in_closed_loop`.
        let period = 0.05;
        let s = MpcSettings {
            horizon_p: 1,
            horizon_m: 1,
            ..Default::default()
        };
        let (lam, lam_du) = (s.output_weight, s.rate_weight);
        let (du_max, u_max) = (s.du_max_deg.to_radians(), 3.5f64.to_radians());
        let k = KalmanSettings::default();
        let mut mpc = Mpc::new(&model(), &s, &k, period, 3.5, InputShape::Hold).unwrap();
        let (mut reduced, mut full, mut clamped) = (Vec::new(), Vec::new(), 0);
        paper_drive(
            &mut mpc,
            period,
            |mpc, at| {
                assert_ne!(mpc.rows_needed(&at.f), QpRows::Full, "step {}", at.step);
                let th = mpc.theta[(0, 0)];
                let star = -th * lam * (at.f[0] - at.r[0]) / (th * th * lam + lam_du);
                let lo = (-du_max).max(-u_max - at.u_prev);
                let hi = du_max.min(u_max - at.u_prev);
                let exact = star.clamp(lo, hi);
                if exact != star {
                    clamped += 1;
                }
                let (du, _, ok) = mpc.solve(&at.f, at.r);
                assert!(ok, "step {}", at.step);
                reduced.push((du[0] - exact).abs());
                let (du, _, ok) = mpc.solve_with(&at.f, at.r, QpRows::Full);
                assert!(ok, "step {}", at.step);
                full.push((du[0] - exact).abs());
            },
            |_| {},
        );
        // The limits bind in some updates and not in others.
        assert!(clamped > 20 && clamped < reduced.len() - 20, "{clamped}");
        for (what, e) in [("reduced", &mut reduced), ("full", &mut full)] {
            e.sort_by(f64::total_cmp);
            let (p50, max) = (e[e.len() / 2], e[e.len() - 1]);
            assert!(
                p50 < 1e-8 && max < 1e-5,
                "{what}: p50 {p50:e}, max {max:e} rad"
            );
        }
    }

    #[test]
    fn unconstrained_mpc_equals_its_closed_form() {
        let m = model();
        let s = MpcSettings::default();
        let mut mpc = Mpc::new(
            &m,
            &s,
            &KalmanSettings::default(),
            0.05,
            3.5,
            InputShape::Hold,
        )
        .unwrap();
        eprintln!("L_est = {}", mpc.l_est.transpose());
        // A state and reference where no constraint binds: the QP optimum must equal
        // Δu* = −(ΘᵀΛΘ + Λ_Δu)⁻¹ ΘᵀΛ (f − r).
        let mut x = nalgebra::DMatrix::zeros(10, 1);
        x[(1, 0)] = 0.002;
        let w = vec![[0.0; 6]; 5];
        let f = mpc.free_response(&x, &w);
        let r = vec![0.0025; 5];
        let exact = mpc.unconstrained(&f, &r);
        assert!(exact.iter().all(|v| v.abs() < 0.5f64.to_radians()));
        let (du, iters, ok) = mpc.solve(&f, &r);
        assert!(ok && iters > 0);
        // Clarabel stops at a duality gap of ~1e-8: the inactive constraints still pull the
        // interior-point iterate by about gap/slack, 1e-5 relative here. 1e-3 relative
        // (5e-6 rad, 3e-4°) is far below anything the bar can resolve.
        for (a, b) in du.iter().zip(&exact) {
            assert!((a - b).abs() < 1e-3 * b.abs() + 1e-9, "{a} vs {b}");
        }
        // A large step: the move is capped at Δu_max exactly.
        let r = vec![0.05; 5];
        let (du, _, ok) = mpc.solve(&f, &r);
        assert!(ok);
        assert!(
            (du[0] - 0.5f64.to_radians()).abs() < 1e-7,
            "{}",
            du[0].to_degrees()
        );
        mpc.set_previous(3.4f64.to_radians());
        let (du, _, _) = mpc.solve(&f, &r);
        assert!(
            du[0] <= 0.1f64.to_radians() + 1e-7,
            "u limit: {}",
            du[0].to_degrees()
        );
        // 0.75° below the limit: the first move is free, the second may take only the rest,
        // so the rows of u(k+1) must be kept although those of u(k) cannot bind.
        mpc.set_previous(2.75f64.to_radians());
        assert_eq!(mpc.rows_needed(&f), QpRows::Inputs);
        let (du, _, ok) = mpc.solve(&f, &r);
        assert!(ok);
        let (first, both) = (du[0].to_degrees(), (du[0] + du[1]).to_degrees());
        assert!((first - 0.5).abs() < 1e-5, "first move {first}°");
        assert!(
            (both - 0.75).abs() < 1e-5,
            "u(k+1) − u(k−1) = {both}°, not 0.75°"
        );
        // Far from every limit only the move rows are left.
        mpc.set_previous(0.0);
        assert_eq!(mpc.rows_needed(&f), QpRows::Moves);
    }
}
