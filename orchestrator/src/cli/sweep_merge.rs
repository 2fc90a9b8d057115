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
    let (base, plan, rows) =
        crate::sweep::merge(&a.shards).map_err(|e| CliError::Invalid(e.to_string()))?;
    crate::sweep::write_outputs(&a.out, &base, &plan, None, &rows, false)
        .map_err(|e| CliError::Failed(format!("{}: {e}", a.out.display())))?;
    println!(
        "merged {} samples from {} shards into {}",
        rows.len(),
        a.shards.len(),
        a.out.display()
    );
    Ok(())
}
