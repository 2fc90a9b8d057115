//! `actuator-proc`: the anti-roll-bar actuator.
//!
//! Models, selected by `actuator.model` in the scenario:
//! * `bldc` (default): the paper's electric actuator ([`bldc`]): BLDC motor, six-step
//!   inverter with hysteresis current control, speed PI (Table 1), position loop, harmonic
//!   gearbox and bar, the motor electrics integrated at `bldc.dt_switched_s` (1 µs) between
//!   the 1 ms exchanges.
//! * `bldc-averaged`: the same drive with the inverter averaged (no switching), stepping at
//!   `bldc.dt_averaged_s` (20 µs), for long studies.
//! * `ideal`: the bar angle follows the command exactly, δ_a = δ_a,cmd (the paper's section
//!   2.3 assumption "assumed to be ideal").

pub mod bldc;

use cosim::msg::{FromActuator, ToActuator};
use cosim::settings::Checker;
use cosim::{Participant, Role};
use serde::{Deserialize, Serialize};

pub use bldc::{Bldc, BldcParams, Electrics};

/// Which actuator model runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ActuatorModel {
    /// Switched BLDC drive (the reference).
    #[default]
    Bldc,
    /// Averaged BLDC drive.
    BldcAveraged,
    /// δ_a = δ_a,cmd.
    Ideal,
}

/// Actuator settings (scenario section `[actuator]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ActuatorSettings {
    /// Model.
    pub model: ActuatorModel,
    /// Motor, drive and bar parameters (`[actuator.bldc]`).
    pub bldc: BldcParams,
}

impl ActuatorSettings {
    /// Checks every field.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        self.bldc.validate(&mut c);
        let b = &self.bldc;
        for (name, dt) in [
            ("bldc.dt_switched_s", b.dt_switched_s),
            ("bldc.dt_averaged_s", b.dt_averaged_s),
        ] {
            let r = b.control_period_s / dt;
            c.require(
                dt <= b.control_period_s && (r - r.round()).abs() < 1e-6,
                name,
                dt,
                &format!(
                    "a step that divides bldc.control_period_s = {} s",
                    b.control_period_s
                ),
            );
        }
        c
    }
}

/// What the actuator process receives: its settings, the exchange period and the bar
/// stiffness of the vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ActuatorInit {
    /// Actuator settings.
    pub actuator: ActuatorSettings,
    /// Exchange period with the plant, the base tick (s).
    pub dt_s: f64,
    /// Anti-roll bar stiffness k_vr (N·m/rad), from the vehicle parameters.
    pub k_vr: f64,
}

/// The actuator participant.
pub struct Actuator {
    settings: ActuatorSettings,
    dt: f64,
    drive: Option<Bldc>,
    last: FromActuator,
}

impl Actuator {
    /// A bar at neutral, motor at rest.
    pub fn new(init: &ActuatorInit) -> Self {
        let a = &init.actuator;
        let drive = match a.model {
            ActuatorModel::Ideal => None,
            ActuatorModel::Bldc => Some(Bldc::new(&a.bldc, Electrics::Switched, init.k_vr)),
            ActuatorModel::BldcAveraged => Some(Bldc::new(&a.bldc, Electrics::Averaged, init.k_vr)),
        };
        Actuator {
            settings: a.clone(),
            dt: init.dt_s,
            drive,
            last: FromActuator::default(),
        }
    }
    /// Settings.
    pub fn settings(&self) -> &ActuatorSettings {
        &self.settings
    }
}

impl Participant for Actuator {
    type Input = ToActuator;
    type Output = FromActuator;
    const ROLE: Role = Role::Actuator;

    fn initial_output(&mut self) -> FromActuator {
        self.last
    }
    fn step(&mut self, input: &ToActuator) -> FromActuator {
        self.last = match &mut self.drive {
            None => FromActuator {
                delta_a: input.delta_a_cmd,
                ..Default::default()
            },
            Some(d) => {
                let t = d.advance(input.delta_a_cmd, input.psi, self.dt);
                FromActuator {
                    header: Default::default(),
                    delta_a: t.delta_a,
                    motor_torque: t.torque,
                    motor_speed: t.speed,
                    motor_current: t.current,
                    dc_power: t.dc_power,
                    limits: t.limits,
                }
            }
        };
        self.last
    }
}

/// Participant process entry: `--params JSON --prefix P --wait W`.
pub fn serve(args: &[String]) -> Result<(), String> {
    cosim::ipc::participant_main(args, |s: ActuatorInit| Ok(Actuator::new(&s)))
}
