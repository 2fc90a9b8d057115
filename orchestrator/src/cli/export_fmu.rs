//! `tiltsim export-fmu ROLE SCENARIO --out FILE.fmu`: a participant as an FMI 3.0
//! co-simulation FMU.

use std::path::PathBuf;

use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct ExportFmuArgs {
    /// plant, actuator or controller.
    role: String,
    /// The scenario whose settings become the FMU's parameters (start values).
    scenario: PathBuf,
    /// The FMU file to write.
    #[arg(long)]
    out: PathBuf,
    /// The FMU library to package (default: libtiltsim_fmu.so beside this program, as cargo
    /// builds it; or the TILTSIM_FMU_LIBRARY environment variable).
    #[arg(long)]
    library: Option<PathBuf>,
}

/// Runs the command.
pub fn exec(a: ExportFmuArgs) -> CliResult {
    let role = cosim::Role::parse(&a.role).ok_or_else(|| {
        CliError::Invalid(format!(
            "role `{}`: allowed plant, actuator, controller",
            a.role
        ))
    })?;
    let s = super::common::load(&a.scenario)?;
    let r = crate::export_fmu::export(&s, role, &a.out, a.library.as_deref())
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    println!(
        "wrote {} ({role}, FMI 3.0 co-simulation, step {} s, {} inputs, {} outputs, {} parameters)",
        a.out.display(),
        r.step_s,
        r.inputs,
        r.outputs,
        r.parameters
    );
    Ok(())
}
