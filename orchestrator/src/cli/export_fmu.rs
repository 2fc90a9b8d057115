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
    /// FMI version: 3 (FMI 3.0) or 2 (FMI 2.0, for importers that do not read 3.0).
    #[arg(long, default_value_t = 3, value_parser = super::bounds::int(2..=3u8, ""))]
    fmi_version: u8,
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
    let version = match a.fmi_version {
        2 => tiltsim_fmi::description::FmiVersion::V2,
        3 => tiltsim_fmi::description::FmiVersion::V3,
        v => {
            return Err(CliError::Invalid(format!(
                "command line: --fmi-version {v}: allowed 2 or 3"
            )))
        }
    };
    let s = super::common::load(&a.scenario)?;
    let r = crate::export_fmu::export(&s, role, version, &a.out, a.library.as_deref())
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    println!(
        "wrote {} ({role}, {version} co-simulation, step {} s, {} inputs, {} outputs, {} parameters)",
        a.out.display(),
        r.step_s,
        r.inputs,
        r.outputs,
        r.parameters
    );
    Ok(())
}
