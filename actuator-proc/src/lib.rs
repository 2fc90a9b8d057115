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
//!
//! Modules: [`bldc`] (the drive), [`dc_link`] (rectifier, DC-link capacitor and braking
//! chopper), [`shaping`] (command shaping between slow controller updates).

pub mod bldc;
pub mod dc_link;
pub mod shaping;

use serde::{Deserialize, Serialize};
use tiltsim_protocol::msg::{FromActuator, ToActuator};
use tiltsim_protocol::settings::Checker;
use tiltsim_protocol::{Participant, Role};

pub use bldc::{Bldc, BldcParams, Electrics, EventStats, SwitchedIntegration};
pub use dc_link::{DcLink, DcLinkParams};
pub use shaping::{CommandShaping, Shaper};

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

impl ActuatorModel {
    /// The model as a scenario file spells it (`actuator.model = "bldc"`).
    pub fn name(self) -> &'static str {
        match self {
            ActuatorModel::Bldc => "bldc",
            ActuatorModel::BldcAveraged => "bldc-averaged",
            ActuatorModel::Ideal => "ideal",
        }
    }

    /// What the actuator is, in words: "switched BLDC drive", "ideal bar".
    pub fn label(self) -> &'static str {
        match self {
            ActuatorModel::Bldc => "switched BLDC drive",
            ActuatorModel::BldcAveraged => "averaged BLDC drive",
            ActuatorModel::Ideal => "ideal bar",
        }
    }
}

/// The scenario file's spelling.
impl std::fmt::Display for ActuatorModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Actuator settings (scenario section `[actuator]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ActuatorSettings {
    /// Model.
    pub model: ActuatorModel,
    /// Motor, drive and bar parameters (`[actuator.bldc]`).
    pub bldc: BldcParams,
    /// Rectifier, capacitor and braking chopper (`[actuator.dc_link]`).
    pub dc_link: DcLinkParams,
    /// How a new set-point is applied between controller updates (`hold` or `ramp`).
    pub command_shaping: CommandShaping,
}

impl ActuatorSettings {
    /// Checks every field.
    pub fn validate(&self, prefix: &str) -> Checker {
        let mut c = Checker::new(prefix);
        self.bldc.validate(&mut c);
        self.dc_link.validate(&mut c, self.bldc.v_dc);
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
    /// Period at which the controller sends new set-points (s), for `command_shaping`.
    pub command_period_s: f64,
}

/// The actuator participant.
pub struct Actuator {
    settings: ActuatorSettings,
    dt: f64,
    drive: Option<Bldc>,
    /// The ideal bar's set-point shaping (the drive shapes its own at its electrical step).
    shaper: Shaper,
    last: FromActuator,
}

impl Actuator {
    /// A bar at neutral, motor at rest.
    pub fn new(init: &ActuatorInit) -> Self {
        let a = &init.actuator;
        let drive = match a.model {
            ActuatorModel::Ideal => None::<Electrics>,
            ActuatorModel::Bldc => Some(Electrics::Switched),
            ActuatorModel::BldcAveraged => Some(Electrics::Averaged),
        }
        .map(|kind| {
            Bldc::new(&a.bldc, &a.dc_link, kind, init.k_vr)
                .with_shaping(a.command_shaping, init.command_period_s)
        });
        // At rest: no current, no torque, the DC link at its supply voltage.
        let last = FromActuator {
            v_dc: drive.as_ref().map_or(0.0, Bldc::v_dc),
            ..Default::default()
        };
        Actuator {
            settings: a.clone(),
            dt: init.dt_s,
            drive,
            shaper: Shaper::new(a.command_shaping, init.command_period_s, init.dt_s),
            last,
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
            None => {
                self.shaper.receive(input.delta_a_cmd);
                self.shaper.advance(1);
                let d = self.shaper.value_after(0);
                FromActuator {
                    delta_a: d,
                    delta_a_ref: d,
                    ..Default::default()
                }
            }
            Some(d) => {
                let t = d.advance(input.delta_a_cmd, input.psi, self.dt);
                FromActuator {
                    header: Default::default(),
                    delta_a: t.delta_a,
                    delta_a_ref: t.delta_a_ref,
                    motor_torque: t.torque,
                    motor_speed: t.speed,
                    motor_current: t.current,
                    dc_power: t.dc_power,
                    phase_current_peak: t.phase_current_peak,
                    v_dc: t.v_dc,
                    chopper_power: t.chopper_power,
                    limits: t.limits,
                }
            }
        };
        self.last
    }
}

/// Participant process entry: `--params JSON --prefix P --wait W`.
#[cfg(feature = "process")]
pub fn serve(args: &[String]) -> Result<(), cosim::ipc::ServeError> {
    cosim::ipc::participant_main(args, |s: ActuatorInit| Ok(Actuator::new(&s)))
}
