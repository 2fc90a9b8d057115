//! `tiltsim plot DIR`: redraw the figures of a finished run, compare or sweep.

use std::path::{Path, PathBuf};

use super::common::load;
use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct PlotArgs {
    /// The output directory of a run (its timeseries.csv; with a free run's timing.csv, the
    /// timing figures too), of a compare (its compare.json: every run's figures and the
    /// side-by-side ones) or of a sweep or shard (its sweep.json).
    dir: PathBuf,
}

/// A run's figures, and its timing figures when it ran free.
fn run_figures(dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let s = load(&dir.join("scenario.toml"))?;
    // Every error names its file: timeseries.csv and its line, or the figure not written.
    let invalid = |e: std::io::Error| CliError::Invalid(e.to_string());
    let mut files = tiltsim_report::analysis::write_plots(&s, dir).map_err(invalid)?;
    // A free run that ended early keeps an incomplete trace: its run figures are drawn, its
    // timing figures are not (they would show a part as the whole).
    match tiltsim_report::analysis::write_timing_plots(&s, dir) {
        Ok(f) => files.extend(f),
        Err(e) => eprintln!("warning: timing figures not drawn: {e}"),
    }
    Ok(files)
}

/// A compare's figures: each run's, then the runs side by side.
fn compare_figures(dir: &Path) -> Result<Vec<PathBuf>, CliError> {
    let manifest = tiltsim_report::table4::Manifest::read(dir).ok_or_else(|| {
        CliError::Invalid(format!(
            "{}: not the compare.json of a compare of this version of tiltsim",
            dir.join("compare.json").display()
        ))
    })?;
    let mut files = Vec::new();
    let mut runs = Vec::new();
    for r in &manifest.runs {
        let run = dir.join(&r.dir);
        if r.dir.contains(['/', '\\']) || r.dir.starts_with('.') || !run.is_dir() {
            return Err(CliError::Invalid(format!(
                "{}: run `{}` is not a directory of the compare",
                dir.join("compare.json").display(),
                r.dir
            )));
        }
        files.extend(run_figures(&run)?);
        runs.push((r.dir.clone(), load(&run.join("scenario.toml"))?, run));
    }
    let drawn = tiltsim_report::analysis::write_compare_plots(&runs, dir).and_then(|mut f| {
        f.extend(tiltsim_report::table4::write_trade_off_plot(
            &manifest.trade_off,
            dir,
        )?);
        Ok(f)
    });
    files.extend(
        drawn.map_err(|e| CliError::Invalid(format!("{}: {e}", dir.join("plots").display())))?,
    );
    Ok(files)
}

/// Runs the command.
pub fn exec(a: PlotArgs) -> CliResult {
    let files = if a.dir.join("sweep.json").is_file() {
        tiltsim_studies::sweep::redraw(&a.dir).map_err(|e| CliError::Invalid(e.to_string()))?
    } else if a.dir.join("compare.json").is_file() {
        compare_figures(&a.dir)?
    } else {
        run_figures(&a.dir)?
    };
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
