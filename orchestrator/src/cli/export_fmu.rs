//! `tiltsim export-fmu ROLE SCENARIO --out FILE.fmu`: a participant as an FMI 3.0
//! co-simulation FMU.

use std::path::PathBuf;

use tiltsim_fmi::layout::Stepping;

use super::error::{CliError, CliResult};

/// `--steps`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum StepsArg {
    /// Any whole multiple of the base tick.
    Tick,
    /// Whole multiples of the participant's own period.
    Period,
}

impl From<StepsArg> for Stepping {
    fn from(s: StepsArg) -> Self {
        match s {
            StepsArg::Tick => Stepping::Tick,
            StepsArg::Period => Stepping::Period,
        }
    }
}

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
    /// Which communication steps the FMU takes: `tick`, any whole multiple of the scenario's
    /// base tick (the participant computes on its own period and holds its outputs between,
    /// so any master stepping every FMU at the base tick reproduces `tiltsim run --master
    /// jacobi`); `period`, whole multiples of the participant's own period only.
    #[arg(long, value_enum, default_value_t = StepsArg::Tick)]
    steps: StepsArg,
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
    let options = tiltsim_master::export_fmu::FmuOptions {
        version,
        stepping: a.steps.into(),
        library: a.library.as_deref(),
    };
    let r = tiltsim_master::export_fmu::export(&s, role, &a.out, &options)
        .map_err(|e| CliError::Invalid(e.to_string()))?;
    println!(
        "wrote {} ({role}, {version} co-simulation, {} s steps or whole multiples, computing every {} s, {} inputs, {} outputs, {} parameters)",
        a.out.display(),
        r.step_s,
        r.period_s,
        r.inputs,
        r.outputs,
        r.parameters
    );
    Ok(())
}
