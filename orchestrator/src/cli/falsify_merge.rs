//! `tiltsim falsify-merge SHARD_DIR... --out DIR`: join the shards of a search.

use std::path::PathBuf;

use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct FalsifyMergeArgs {
    /// Shard output directories (`tiltsim falsify --shard I/N`), every shard once.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// No table on standard output.
    #[arg(short, long)]
    quiet: bool,
}

/// Runs the command.
pub fn exec(a: FalsifyMergeArgs) -> CliResult {
    let invalid = |m: String| CliError::Invalid(m);
    super::common::check_shards_to_merge(&a.shards, &a.out)?;
    // Checked whole before the output directory is touched.
    let shards =
        tiltsim_studies::falsify::shards::read_all(&a.shards).map_err(super::falsify::invalid)?;
    let _lock =
        tiltsim_rundir::outdir::claim(&a.out, tiltsim_rundir::outdir::Kind::Sweep, "falsify-merge")
            .map_err(|e| invalid(e.to_string()))?;
    let interrupt = tiltsim_rundir::signals::install();
    let (evals, o) = tiltsim_studies::falsify::shards::merge(&a.shards, &a.out, &interrupt)
        .map_err(|e| {
            if interrupt.load(std::sync::atomic::Ordering::Relaxed) {
                CliError::Interrupted(e.to_string())
            } else {
                super::falsify::invalid(e)
            }
        })?;
    if !a.quiet {
        let evals: Vec<_> = evals.into_iter().map(|(_, e)| e).collect();
        let from = &shards[0].info.bounds_from;
        super::falsify::print_report(from, &evals, &o, &a.out, None);
    }
    super::falsify::verdict(&o, &a.out)
}
