//! `tiltsim participant ROLE ...` (hidden): how the orchestrator starts its participant
//! processes from this same executable.

use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ParticipantArgs {
    /// plant, actuator or controller.
    role: String,
    /// `--params JSON --prefix P [--wait W] [--cpu N]`, passed to the participant.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    rest: Vec<String>,
}

/// Runs the command.
pub fn exec(a: ParticipantArgs) -> CliResult {
    let role = cosim::Role::parse(&a.role).ok_or_else(|| {
        CliError::Invalid(format!(
            "participant `{}`: allowed plant, actuator, controller",
            a.role
        ))
    })?;
    match role {
        cosim::Role::Plant => plant_proc::serve(&a.rest),
        cosim::Role::Actuator => actuator_proc::serve(&a.rest),
        cosim::Role::Controller => controller_proc::serve(&a.rest),
    }
    .map_err(|e| CliError::Participant(e.to_string()))
}
