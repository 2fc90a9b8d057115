//! `tiltsim clean`: remove the shared-memory files of runs whose orchestrator is dead, and the
//! FMUs unpacked by participant processes that are dead.

use super::error::CliResult;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct CleanArgs {}

/// Runs the command.
pub fn exec(_: CleanArgs) -> CliResult {
    let dead = cosim::ipc::remove_dead_runs();
    if dead.is_empty() {
        println!("no files of dead runs");
    }
    for p in dead {
        println!("removed the files of dead run {p}*");
    }
    for d in tiltsim_fmi::archive::remove_dead_unpacked() {
        println!("removed the unpacked FMU {}", d.display());
    }
    Ok(())
}
