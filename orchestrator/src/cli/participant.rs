//! `tiltsim participant ROLE ...` and `tiltsim fmu-participant ROLE ...` (hidden): how the
//! orchestrator starts its participant processes from this same executable, native or FMU.

use super::error::{CliError, CliResult};
use tiltsim_fmi::{ActuatorIo, ControllerIo, FmuInit, FmuParticipant, PlantIo};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ParticipantArgs {
    /// plant, actuator or controller.
    role: String,
    /// `--params JSON --prefix P [--wait W] [--cpu N]`, passed to the participant; or, on
    /// another host, `--connect ENDPOINT [--run KEY] [--secret-file PATH]
    /// [--join-timeout-s S] [--lease-ms MS]` (the secret from TILTSIM_SECRET otherwise).
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

/// Runs the command: over iceoryx2 as the orchestrator starts it, or, with `--connect`, as a
/// participant on another host that joins a run over the network.
pub fn exec(a: ParticipantArgs) -> CliResult {
    if tiltsim_net::serve::JoinArgs::wanted(&a.rest) {
        return exec_remote(&a);
    }
    match role_of(&a)? {
        cosim::Role::Plant => plant_proc::serve(&a.rest),
        cosim::Role::Actuator => actuator_proc::serve(&a.rest),
        cosim::Role::Controller => controller_proc::serve(&a.rest),
    }
    .map_err(|e| CliError::Participant(e.to_string()))
}

/// Joins a run on another host (`--connect ENDPOINT`) and serves the native model of the
/// role with the settings the run sends.
fn exec_remote(a: &ParticipantArgs) -> CliResult {
    use tiltsim_net::serve::participant_main;
    let role = role_of(a)?;
    match role {
        cosim::Role::Plant => participant_main(role, &a.rest, |s: plant_proc::PlantSettings| {
            Ok(plant_proc::Plant::new(&s))
        }),
        cosim::Role::Actuator => {
            participant_main(role, &a.rest, |s: actuator_proc::ActuatorInit| {
                Ok(actuator_proc::Actuator::new(&s))
            })
        }
        cosim::Role::Controller => {
            participant_main(role, &a.rest, |s: controller_proc::ControllerInit| {
                controller_proc::Controller::new(&s)
            })
        }
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
