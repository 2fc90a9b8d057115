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
        "{}: valid ({} s at {} km/h, {} steps of {} ms, controller {:?}, actuator {:?})",
        a.scenario.display(),
        s.duration(),
        s.track.speed_kmh,
        s.steps(),
        s.run.dt_s * 1e3,
        s.controller.mode,
        s.actuator.model
    );
    let out = std::path::Path::new("out").join(&s.name);
    let e = crate::budget::estimate(&s, crate::budget::Extras::default());
    println!(
        "outputs: about {} ({} rows); default directory {}",
        crate::budget::human(e.bytes),
        e.rows,
        out.display()
    );
    match crate::budget::check(&s, &out, crate::budget::Extras::default()) {
        crate::budget::Verdict::Fits => Ok(()),
        crate::budget::Verdict::Warn(m) => {
            eprintln!("warning: {}: {m}", a.scenario.display());
            Ok(())
        }
        crate::budget::Verdict::Refuse(m) => {
            Err(CliError::Invalid(format!("{}: {m}", a.scenario.display())))
        }
    }
}
