//! What several commands share: the argument enums, loading a scenario, the Ctrl-C flag and
//! the participants' executable, writing JSON.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use clap::ValueEnum;
use cosim::wait::WaitStrategy;
use serde::Serialize;

use super::error::CliError;
use tiltsim_scenario::scenario::{Master, Scenario, Transport};

/// `--transport`.
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum TransportArg {
    /// Separate processes over iceoryx2.
    Ipc,
    /// Every participant in this process.
    InProcess,
}

impl From<TransportArg> for Transport {
    fn from(t: TransportArg) -> Self {
        match t {
            TransportArg::Ipc => Transport::Ipc,
            TransportArg::InProcess => Transport::InProcess,
        }
    }
}

/// `--master`.
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum MasterArg {
    /// One participant after the other.
    GaussSeidel,
    /// All in parallel from the previous outputs.
    Jacobi,
}

impl From<MasterArg> for Master {
    fn from(m: MasterArg) -> Self {
        match m {
            MasterArg::GaussSeidel => Master::GaussSeidel,
            MasterArg::Jacobi => Master::Jacobi,
        }
    }
}

/// `--wait`.
#[derive(ValueEnum, Clone, Copy, Debug)]
pub enum WaitArg {
    /// Busy-poll.
    Spin,
    /// Spin, yield, nap.
    Adaptive,
    /// Nap between polls.
    Sleep,
    /// Spin, yield for 100 µs, nap (the default with --pace).
    Paced,
}

impl From<WaitArg> for WaitStrategy {
    fn from(w: WaitArg) -> Self {
        match w {
            WaitArg::Spin => WaitStrategy::Spin,
            WaitArg::Adaptive => WaitStrategy::Adaptive,
            WaitArg::Sleep => WaitStrategy::Sleep,
            WaitArg::Paced => WaitStrategy::Paced,
        }
    }
}

/// Loads and validates a scenario file.
pub fn load(path: &Path) -> Result<Scenario, CliError> {
    Scenario::load(path).map_err(|e| CliError::Invalid(e.to_string()))
}

/// The environment variable that names the executable serving participants, where it is not
/// this program's own executable.
pub const PARTICIPANT_EXE_VAR: &str = "TILTSIM_PARTICIPANT_EXE";

/// The interrupt flag (set by SIGINT, SIGTERM or SIGHUP) and the executable that serves
/// participants.
pub fn interrupt_and_exe() -> Result<(Arc<AtomicBool>, PathBuf), CliError> {
    let interrupt = tiltsim_rundir::signals::install();
    // An FMU unpacked in this process (the in-process transport) stops at Ctrl-C too.
    tiltsim_fmi::archive::stop_unpacking_when(interrupt.clone());
    // A program that carries tiltsim as a library (the Python package's `tiltsim` command,
    // an interpreter running a script) names the executable that serves participants.
    if let Some(exe) = std::env::var_os(PARTICIPANT_EXE_VAR) {
        return Ok((interrupt, PathBuf::from(exe)));
    }
    let exe = std::env::current_exe().map_err(|e| {
        CliError::Failed(format!(
            "cannot find the tiltsim executable to start participants: {e}"
        ))
    })?;
    Ok((interrupt, exe))
}

/// Writes `v` as pretty JSON to `path`.
pub fn write_json<T: Serialize>(path: &Path, v: &T) -> Result<(), CliError> {
    let text = serde_json::to_string_pretty(v).unwrap_or_default() + "\n";
    tiltsim_rundir::files::write_atomic(path, text).map_err(|e| CliError::Failed(e.to_string()))
}

/// The shard a `--shard I/N|auto [--shards N]` pair names, if any (sweeps and searches).
pub fn shard_of(
    shard: Option<&str>,
    shards: Option<usize>,
) -> Result<Option<tiltsim_studies::sweep::Shard>, CliError> {
    use tiltsim_studies::sweep::Shard;
    match shard {
        None => None,
        Some("auto") => Some(Shard::auto(shards, |v| std::env::var(v).ok())),
        Some(s) => Some(Shard::parse(s)),
    }
    .transpose()
    .map_err(|e| CliError::Invalid(e.to_string()))
}

/// Refuses to merge shards of which one is still running or one is the output directory.
pub fn check_shards_to_merge(shards: &[PathBuf], out: &Path) -> Result<(), CliError> {
    let out_real = std::fs::canonicalize(out).ok();
    for d in shards {
        // A shard still running has not written its results.
        if let Some(h) = tiltsim_rundir::outdir::live_holder(d) {
            return Err(CliError::Invalid(format!(
                "{}: in use by {h}: a shard still running cannot be merged",
                d.display()
            )));
        }
        if out_real.is_some() && std::fs::canonicalize(d).ok() == out_real {
            return Err(CliError::Invalid(format!(
                "--out {}: is one of the shards merged; give another directory",
                out.display()
            )));
        }
    }
    Ok(())
}
