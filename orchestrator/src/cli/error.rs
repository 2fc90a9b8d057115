//! The command line's one error type and its exit codes.

/// Exit code: the run failed.
pub const EXIT_FAILED: i32 = 1;
/// Exit code: invalid input.
pub const EXIT_INVALID: i32 = 2;
/// Exit code: a requirement was falsified (`tiltsim falsify --requirement`: a timing that
/// breaks it was found).
pub const EXIT_FALSIFIED: i32 = 3;
/// Exit code: interrupted.
pub const EXIT_INTERRUPTED: i32 = 130;

/// Why a command did not succeed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Invalid input: the message names the file, the field and what is allowed.
    #[error("error: {0}")]
    Invalid(String),
    /// The work failed (a participant died, stalled or sent bad data; an output could not be
    /// written).
    #[error("error: {0}")]
    Failed(String),
    /// A participant process ended with an error of its own (printed as it said it).
    #[error("{0}")]
    Participant(String),
    /// Ctrl-C; the message says what was kept.
    #[error("{0}")]
    Interrupted(String),
    /// A requirement falsified: the search completed and found a timing that breaks it (the
    /// message names the counterexample).
    #[error("{0}")]
    Falsified(String),
}

impl CliError {
    /// The process exit code (docs/outputs.md, "Exit codes").
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::Invalid(_) => EXIT_INVALID,
            CliError::Failed(_) | CliError::Participant(_) => EXIT_FAILED,
            CliError::Interrupted(_) => EXIT_INTERRUPTED,
            CliError::Falsified(_) => EXIT_FALSIFIED,
        }
    }
}

/// What a command returns.
pub type CliResult = Result<(), CliError>;

impl CliError {
    /// A run that could not start or end: an interrupt during the start-up exits as an
    /// interrupt (130), naming the signal; anything else is a failure with `context` first.
    /// The error of a job that could not be carried out, with its exit code.
    pub fn of_job(e: tiltsim_runner::pipeline::JobError) -> CliError {
        use tiltsim_runner::pipeline::JobError;
        match e {
            JobError::Invalid(m) => CliError::Invalid(m),
            JobError::Trace(t) => CliError::Invalid(t.to_string()),
            JobError::Run(r) => CliError::of_run(r, ""),
            JobError::Failed(m) => CliError::Failed(m),
        }
    }

    /// The error of a run that could not start, with `context` before its message.
    pub fn of_run(e: tiltsim_master::engine::RunError, context: &str) -> CliError {
        match e {
            tiltsim_master::engine::RunError::Interrupted { role } => {
                CliError::Interrupted(format!(
                    "interrupted by {} while participant {role} was starting: nothing recorded",
                    tiltsim_rundir::signals::describe()
                ))
            }
            e => CliError::Failed(format!("{context}{e}")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_error_has_its_documented_exit_code() {
        assert_eq!(CliError::Invalid("x".into()).exit_code(), 2);
        assert_eq!(CliError::Failed("x".into()).exit_code(), 1);
        assert_eq!(CliError::Participant("x".into()).exit_code(), 1);
        assert_eq!(CliError::Interrupted("x".into()).exit_code(), 130);
        assert_eq!(
            CliError::Invalid("f.toml: run.dt_s".into()).to_string(),
            "error: f.toml: run.dt_s"
        );
    }
}
