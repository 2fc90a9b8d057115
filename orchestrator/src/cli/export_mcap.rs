//! `tiltsim export-mcap RUN_DIR`: a finished run's files as `RUN_DIR/run.mcap`.

use std::path::PathBuf;

use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ExportMcapArgs {
    /// Directory of a finished run (timeseries.csv, events.csv, summary.json, scenario.toml).
    run_dir: PathBuf,
}

/// Runs the command.
pub fn exec(a: ExportMcapArgs) -> CliResult {
    let p = tiltsim_master::export_mcap::export(&a.run_dir)
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    println!("wrote {}", p.display());
    Ok(())
}
