//! `tiltsim participant ROLE ...` and `tiltsim fmu-participant ROLE ...` (hidden): how the
//! orchestrator starts its participant processes from this same executable, native or FMU.

use super::error::{CliError, CliResult};
use tiltsim_fmi::{ActuatorIo, ControllerIo, FmuInit, FmuParticipant, PlantIo};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ParticipantArgs {
    /// plant, actuator or controller.
    role: String,
    /// `--params JSON --prefix P [--wait W] [--cpu N]`, passed to the participant.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    rest: Vec<String>,
}

fn role_of(a: &ParticipantArgs) -> Result<cosim::Role, CliError> {
    cosim::Role::parse(&a.role).ok_or_else(|| {
        CliError::Invalid(format!(
            "participant `{}`: allowed plant, actuator, controller",
            a.role
        ))
    })
}

/// Runs the command.
pub fn exec(a: ParticipantArgs) -> CliResult {
    match role_of(&a)? {
        cosim::Role::Plant => plant_proc::serve(&a.rest),
        cosim::Role::Actuator => actuator_proc::serve(&a.rest),
        cosim::Role::Controller => controller_proc::serve(&a.rest),
    }
    .map_err(|e| CliError::Participant(e.to_string()))
}

/// Runs an FMU as the participant (`--params` holds its [`FmuInit`]).
pub fn exec_fmu(a: ParticipantArgs) -> CliResult {
    use cosim::ipc::participant_main;
    match role_of(&a)? {
        cosim::Role::Plant => participant_main(&a.rest, FmuParticipant::<PlantIo>::new),
        cosim::Role::Actuator => participant_main(&a.rest, FmuParticipant::<ActuatorIo>::new),
        cosim::Role::Controller => {
            participant_main(&a.rest, |i: FmuInit| FmuParticipant::<ControllerIo>::new(i))
        }
    }
    .map_err(|e| CliError::Participant(e.to_string()))
}
