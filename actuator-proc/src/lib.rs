//! `actuator-proc`: the anti-roll-bar actuator.
//!
//! Models, selected by `actuator.model` in the scenario:
//! * `ideal`: the bar angle follows the command exactly, δ_a = δ_a,cmd (the paper's section
//!   2.3 assumption "assumed to be ideal").

use cosim::msg::{FromActuator, ToActuator};
use cosim::settings::Checker;
use cosim::{Participant, Role};
use serde::{Deserialize, Serialize};

/// Which actuator model runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum ActuatorModel {
    /// δ_a = δ_a,cmd.
    #[default]
    Ideal,
}

/// Actuator settings (scenario section `[actuator]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ActuatorSettings {
    /// Model.
    pub model: ActuatorModel,
}

impl Default for ActuatorSettings {
    fn default() -> Self {
        ActuatorSettings {
            model: ActuatorModel::Ideal,
        }
    }
}

impl ActuatorSettings {
    /// Checks every field.
    pub fn validate(&self, prefix: &str) -> Checker {
        Checker::new(prefix)
    }
}

/// What the actuator process receives: its settings and the exchange period.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ActuatorInit {
    /// Actuator settings.
    pub actuator: ActuatorSettings,
    /// Exchange period with the plant, the base tick (s).
    pub dt_s: f64,
}

/// The actuator participant.
pub struct Actuator {
    settings: ActuatorSettings,
    delta_a: f64,
}

impl Actuator {
    /// A bar at neutral.
    pub fn new(init: &ActuatorInit) -> Self {
        Actuator {
            settings: init.actuator.clone(),
            delta_a: 0.0,
        }
    }
    /// Settings.
    pub fn settings(&self) -> &ActuatorSettings {
        &self.settings
    }
    fn output(&self) -> FromActuator {
        FromActuator {
            delta_a: self.delta_a,
            ..Default::default()
        }
    }
}

impl Participant for Actuator {
    type Input = ToActuator;
    type Output = FromActuator;
    const ROLE: Role = Role::Actuator;

    fn initial_output(&mut self) -> FromActuator {
        self.output()
    }
    fn step(&mut self, input: &ToActuator) -> FromActuator {
        match self.settings.model {
            ActuatorModel::Ideal => self.delta_a = input.delta_a_cmd,
        }
        self.output()
    }
}

/// Participant process entry: `--params JSON --prefix P --wait W`.
pub fn serve(args: &[String]) -> Result<(), String> {
    cosim::ipc::participant_main(args, |s: ActuatorInit| Ok(Actuator::new(&s)))
}
