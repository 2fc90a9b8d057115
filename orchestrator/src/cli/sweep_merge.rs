//! `tiltsim sweep-merge SHARD_DIR... --out DIR`: join the shards of a sweep.

use std::path::PathBuf;

use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct SweepMergeArgs {
    /// Shard output directories.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
}

/// Runs the command.
pub fn exec(a: SweepMergeArgs) -> CliResult {
    let invalid = |m: String| CliError::Invalid(m);
    super::common::check_shards_to_merge(&a.shards, &a.out)?;
    let (base, plan, build, rows) =
        tiltsim_studies::sweep::merge(&a.shards).map_err(|e| invalid(e.to_string()))?;
    // Checked whole before the output directory is touched.
    let _lock =
        tiltsim_rundir::outdir::claim(&a.out, tiltsim_rundir::outdir::Kind::Sweep, "sweep-merge")
            .map_err(|e| invalid(e.to_string()))?;
    tiltsim_studies::sweep::clear_for_merge(&a.out).map_err(|e| invalid(e.to_string()))?;
    tiltsim_studies::sweep::write_outputs(&a.out, &base, &plan, None, &rows, false, &build)
        .map_err(|e| CliError::Failed(format!("{}: {e}", a.out.display())))?;
    println!(
        "merged {} samples from {} shards into {}",
        rows.len(),
        a.shards.len(),
        a.out.display()
    );
    Ok(())
}
