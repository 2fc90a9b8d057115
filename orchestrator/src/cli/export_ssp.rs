//! `tiltsim export-ssp SCENARIO --out DIR`: the scenario's three participants as FMI 2.0 FMUs
//! and an SSP 1.0 system structure connecting them, for other co-simulation masters.

use std::path::PathBuf;

use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ExportSspArgs {
    /// The scenario: its participants become the FMUs, its values their parameters.
    scenario: PathBuf,
    /// The directory to write: DIR/SystemStructure.ssd and DIR/resources/ROLE.fmu (zipped, an
    /// .ssp package).
    #[arg(long)]
    out: PathBuf,
    /// The FMU library to package (default: libtiltsim_fmu.so beside this program, as cargo
    /// builds it; or the TILTSIM_FMU_LIBRARY environment variable).
    #[arg(long)]
    library: Option<PathBuf>,
}

/// Runs the command.
pub fn exec(a: ExportSspArgs) -> CliResult {
    let s = super::common::load(&a.scenario)?;
    let r = tiltsim_master::export_ssp::export_ssp(&s, &a.out, a.library.as_deref())
        .map_err(|e| CliError::Invalid(format!("{}: {e}", a.scenario.display())))?;
    let names: Vec<String> = r
        .fmus
        .iter()
        .map(|p| p.strip_prefix(&a.out).unwrap_or(p).display().to_string())
        .collect();
    println!(
        "wrote {} (SSP 1.0: {}, FMI 2.0; {} connections; every FMU stepped at {} s, stop {} s)",
        r.ssd.display(),
        names.join(", "),
        r.connections,
        r.step_s,
        r.stop_s
    );
    Ok(())
}
