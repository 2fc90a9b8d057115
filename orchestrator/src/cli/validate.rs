//! `tiltsim validate SCENARIO`: check a scenario file without running it.

use std::path::PathBuf;

use super::common::load;
use super::error::CliResult;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ValidateArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
}

/// Runs the command.
pub fn exec(a: ValidateArgs) -> CliResult {
    let s = load(&a.scenario)?;
    println!(
        "{}: valid ({} s at {} km/h, {} steps of {} ms, controller {:?}, actuator {:?})",
        a.scenario.display(),
        s.duration(),
        s.track.speed_kmh,
        s.steps(),
        s.run.dt_s * 1e3,
        s.controller.mode,
        s.actuator.model
    );
    Ok(())
}
