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
    let out_real = std::fs::canonicalize(&a.out).ok();
    for d in &a.shards {
        // A shard still running has not written its results.
        if let Some(h) = crate::outdir::live_holder(d) {
            return Err(invalid(format!(
                "{}: in use by {h}: a shard still running cannot be merged",
                d.display()
            )));
        }
        if out_real.is_some() && std::fs::canonicalize(d).ok() == out_real {
            return Err(invalid(format!(
                "--out {}: is one of the shards merged; give another directory",
                a.out.display()
            )));
        }
    }
    let (base, plan, build, rows) =
        crate::sweep::merge(&a.shards).map_err(|e| invalid(e.to_string()))?;
    // Checked whole before the output directory is touched.
    let _lock = crate::outdir::claim(&a.out, crate::outdir::Kind::Sweep, "sweep-merge")
        .map_err(|e| invalid(e.to_string()))?;
    crate::sweep::clear_for_merge(&a.out).map_err(|e| invalid(e.to_string()))?;
    crate::sweep::write_outputs(&a.out, &base, &plan, None, &rows, false, &build)
        .map_err(|e| CliError::Failed(format!("{}: {e}", a.out.display())))?;
    println!(
        "merged {} samples from {} shards into {}",
        rows.len(),
        a.shards.len(),
        a.out.display()
    );
    Ok(())
}
