//! `tiltsim plot DIR`: redraw a finished run's figures.

use std::path::PathBuf;

use super::common::load;
use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct PlotArgs {
    /// A run's output directory.
    dir: PathBuf,
}

/// Runs the command.
pub fn exec(a: PlotArgs) -> CliResult {
    let s = load(&a.dir.join("scenario.toml"))?;
    // Every error names its file: timeseries.csv and its line, or the figure not written.
    let files =
        crate::analysis::write_plots(&s, &a.dir).map_err(|e| CliError::Invalid(e.to_string()))?;
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
