//! `tiltsim validate SCENARIO`: check a scenario file without running it.

use std::path::PathBuf;

use super::common::load;
use super::error::{CliError, CliResult};

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
        "{}: valid ({} s at {} km/h, {} steps of {} ms, controller {}, actuator {})",
        a.scenario.display(),
        s.duration(),
        s.track.speed_kmh,
        s.steps(),
        s.run.dt_s * 1e3,
        s.controller.mode,
        s.actuator.model
    );
    let out = std::path::Path::new("out").join(&s.name);
    let e = tiltsim_rundir::budget::estimate(&s, tiltsim_rundir::budget::Extras::default());
    println!(
        "outputs: about {} ({} rows); default directory {}",
        tiltsim_rundir::budget::human(e.bytes),
        e.rows,
        out.display()
    );
    match tiltsim_rundir::budget::check(&s, &out, tiltsim_rundir::budget::Extras::default()) {
        tiltsim_rundir::budget::Verdict::Fits => Ok(()),
        tiltsim_rundir::budget::Verdict::Warn(m) => {
            eprintln!("warning: {}: {m}", a.scenario.display());
            Ok(())
        }
        tiltsim_rundir::budget::Verdict::Refuse(m) => {
            Err(CliError::Invalid(format!("{}: {m}", a.scenario.display())))
        }
    }
}
