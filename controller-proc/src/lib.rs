//! `controller-proc`: the tilt controller.
//!
//! The controller knows the track only through its onboard database (design curvature and
//! cant along the route, [`plant_proc::Track::design`]) and the vehicle's position, never
//! through the plant's state. Modes (`controller.mode`):
//! * `passive`: zero command (a non-tilting vehicle); the reference is still computed and
//!   recorded.
//! * `pi`: the PI regulator of Table 3 on the roll error θ_v^d − θ_v,meas, with conditional
//!   integration (anti-windup) against the actuator's range `u_max_deg`.

use cosim::msg::{FromController, ToController};
use cosim::settings::Checker;
use cosim::{Participant, Role};
use plant_proc::{Track, TrackParams, Vehicle, VehicleParams, G};
use serde::{Deserialize, Serialize};

/// Controller mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// δ_a,cmd = 0.
    #[default]
    Passive,
    /// PI regulator (section 3.1, Table 3).
    Pi,
}

/// Controller settings (scenario section `[controller]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerSettings {
    /// Mode.
    pub mode: Mode,
    /// Reduction ρ of the non-tilting lateral acceleration (eq 18); 0.30 in the paper.
    pub rho: f64,
    /// Controller period (s); a multiple of the base tick.
    pub period_s: f64,
    /// Bar command limit |δ_a,cmd| (deg): the actuator's range (section 3.3: ±3.5°).
    pub u_max_deg: f64,
    /// PI gains (Table 3).
    pub pi: PiGains,
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
            period_s: 1e-3,
            u_max_deg: 3.5,
            pi: PiGains::default(),
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
}

/// Tilt command of eq 18: θ_v^d = v²/(gR) − ÿ^d/g − θ_o with ÿ^d = (1 − ρ)·ÿ_passive.
///
/// ÿ_passive is the non-tilting vehicle's quasi-static lateral acceleration at this track point:
/// eq 13 evaluated with the passive vehicle's quasi-static roll `theta_v_passive` (it rolls
/// outwards about 1° on the paper's curve). This reading reproduces the paper's own numbers:
/// Table 4's PI peak of 8.49 %g = 0.70 × 1.18 m/s², and δ_a ≈ 2.4° on the steady curve
/// (model-notes). See docs/model.md, D9.
pub fn tilt_reference(v: f64, curvature: f64, cant: f64, theta_v_passive: f64, rho: f64) -> f64 {
    let a = cant + theta_v_passive;
    let a_passive = v * v * curvature * a.cos() - G * a.sin();
    let a_desired = (1.0 - rho) * a_passive;
    v * v * curvature / G - a_desired / G - cant
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
        x_k[plant_proc::vehicle::ix::TH_V],
        x_c[plant_proc::vehicle::ix::TH_V],
    )
}

/// The controller participant.
pub struct Controller {
    s: ControllerSettings,
    track: Track,
    v: f64,
    pi: Pi,
    /// Passive quasi-static roll per unit curvature (rad·m) and per unit cant (rad/rad).
    roll_gains: (f64, f64),
}

impl Controller {
    /// Builds the controller and its track database.
    pub fn new(init: &ControllerInit) -> Self {
        let mut db = init.track.clone();
        db.irregularity.amplitude_deg = 0.0;
        let c = &init.controller;
        let pi = Pi {
            gains: c.pi.clone(),
            u_max: c.u_max_deg.to_radians(),
            integral: 0.0,
        };
        let roll_gains = passive_roll_gains(&init.vehicle, db.speed());
        Controller {
            s: c.clone(),
            track: Track::new(&db, 0),
            v: db.speed(),
            pi,
            roll_gains,
        }
    }

    fn compute(&mut self, input: &ToController) -> FromController {
        let (curvature, cant) = self.track.design(input.s);
        let theta_passive = self.roll_gains.0 * curvature + self.roll_gains.1 * cant;
        let theta_ref = tilt_reference(self.v, curvature, cant, theta_passive, self.s.rho);
        let delta_a_cmd = match self.s.mode {
            Mode::Passive => 0.0,
            Mode::Pi => self
                .pi
                .step(theta_ref - input.theta_v_meas, self.s.period_s),
        };
        FromController {
            header: Default::default(),
            delta_a_cmd,
            theta_ref,
            theta_v_hat: input.theta_v_meas,
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
pub fn serve(args: &[String]) -> Result<(), String> {
    cosim::ipc::participant_main(args, |s: ControllerInit| Ok(Controller::new(&s)))
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
        assert!(
            (th_p.to_degrees() + 1.01).abs() < 0.02,
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
        assert_eq!(tilt_reference(v, 0.0, 0.0, 0.0, 0.3), 0.0);
    }
}
