//! `controller-proc`: the tilt controller.
//!
//! The controller knows the track only through its onboard database (design curvature and
//! cant along the route, [`vehicle_model::Track::design`]) and the vehicle's position, never
//! through the plant's state. Modes (`controller.mode`):
//! * `passive`: zero command (a non-tilting vehicle); the reference is still computed and
//!   recorded.
//! * `pi`: the PI regulator of Table 3 on the roll error θ_v^d − θ_v,meas, with conditional
//!   integration (anti-windup) against the actuator's range `u_max_deg`.
//! * `lqg`: the LQG servo of section 3.2 ([`lqg`]), its command limited to `u_max_deg` with
//!   the same conditional integration.
//! * `mpc`: MPC with a built-in Kalman filter, section 3.3 ([`mpc`]), optionally with preview.
//!
//! [`linalg`] holds the Riccati solvers and discretisation, [`design`] the linear model,
//! [`pi_loop`] the PI loop's margins and its design for a phase margin, [`localisation`] the
//! position the controller reads its track database at (with a localisation's error).

pub mod design;
pub mod linalg;
pub mod localisation;
pub mod lqg;
pub mod mpc;
pub mod pi_loop;

use serde::{Deserialize, Serialize};
use tiltsim_protocol::msg::{FromController, ToController};
use tiltsim_protocol::settings::Checker;
use tiltsim_protocol::{Participant, Role};
use vehicle_model::{Track, TrackParams, Vehicle, VehicleParams, G};

pub use design::LinearModel;
pub use localisation::{LocalisationSettings, Localiser};
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

impl Mode {
    /// The mode as a scenario file spells it (`controller.mode = "lqg"`).
    pub fn name(self) -> &'static str {
        match self {
            Mode::Passive => "passive",
            Mode::Pi => "pi",
            Mode::Lqg => "lqg",
            Mode::Mpc => "mpc",
        }
    }

    /// What the controller is, in words: "LQG servo", "MPC with Kalman filter".
    pub fn label(self) -> &'static str {
        match self {
            Mode::Passive => "no tilt control",
            Mode::Pi => "PI",
            Mode::Lqg => "LQG servo",
            Mode::Mpc => "MPC with Kalman filter",
        }
    }
}

/// The scenario file's spelling.
impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
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
    /// The error of the position the track database is read at (none by default).
    pub localisation: LocalisationSettings,
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
            localisation: LocalisationSettings::default(),
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
        self.localisation.validate(&mut c);
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
    /// The run's seed (`run.seed`): the localisation noise is drawn from it.
    #[serde(default)]
    pub seed: u64,
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
    localiser: Localiser,
    /// The MPC's references and track inputs over its horizon, filled in place each update.
    horizon_r: Vec<f64>,
    horizon_w: Vec<[f64; 6]>,
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
                    .map_err(|e| format!("LQG design: {e}"))?
                    .with_limit(if c.lqg.limit_command {
                        c.u_max_deg.to_radians()
                    } else {
                        f64::INFINITY
                    }),
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
            localiser: Localiser::new(&c.localisation, init.seed),
            horizon_r: Vec::with_capacity(c.mpc.horizon_p),
            horizon_w: Vec::with_capacity(c.mpc.horizon_p),
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
        // The database is read where the controller believes the vehicle is.
        let s = self.localiser.position(input.t, input.s);
        let theta_ref = self.reference_at(s);
        let mut out = FromController {
            theta_ref,
            theta_v_hat: input.theta_v_meas,
            ..Default::default()
        };
        let w = self.track_input_at(s);
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
                let (mut r, mut w) = (
                    std::mem::take(&mut self.horizon_r),
                    std::mem::take(&mut self.horizon_w),
                );
                self.horizon(s, theta_ref, &mut r, &mut w);
                let Law::Mpc(mpc) = &mut self.law else {
                    unreachable!()
                };
                let u = mpc.step(&mpc::MpcInput {
                    xi: input.theta_v_meas,
                    r: &r,
                    w: &w,
                });
                (self.horizon_r, self.horizon_w) = (r, w);
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

    /// References r(k+1..k+p) and track inputs ω(k..k+p−1) over the MPC horizon, into `r` and
    /// `w`: held at their current values, or read ahead from the database with preview.
    fn horizon(&self, s: f64, theta_ref: f64, r: &mut Vec<f64>, w: &mut Vec<[f64; 6]>) {
        r.clear();
        w.clear();
        let Law::Mpc(mpc) = &self.law else {
            return;
        };
        let p = mpc.horizon();
        let ds = self.v * self.s.period_s;
        if mpc.preview() {
            r.extend((1..=p).map(|i| self.reference_at(s + ds * i as f64)));
            w.extend((0..p).map(|j| self.track_input_at(s + ds * j as f64)));
        } else {
            r.resize(p, theta_ref);
            w.resize(p, self.track_input_at(s));
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
#[cfg(feature = "process")]
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
        // The static force and moment solve of tests/models/vehicle_physics.rs gives −1.0239°.
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
mod design_tests;
