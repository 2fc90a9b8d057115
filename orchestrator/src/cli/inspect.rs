//! `tiltsim inspect FILE.fmu`: what an FMU declares (version, interfaces, steps, variables
//! with causality, type, unit and description), read from its modelDescription.xml only.

use std::path::PathBuf;

use super::error::{CliError, CliResult};
use tiltsim_fmi::description::{ModelDescription, VarDesc};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct InspectArgs {
    /// The FMU (FMI 2.0 or 3.0).
    fmu: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

fn var_json(v: &VarDesc) -> serde_json::Value {
    serde_json::json!({
        "name": v.name,
        "value_reference": v.vr,
        "causality": v.causality,
        "type": v.type_name,
        "unit": v.unit,
        "description": v.description,
    })
}

fn as_json(d: &ModelDescription) -> serde_json::Value {
    serde_json::json!({
        "fmi_version": d.version.to_string(),
        "model_name": d.model_name,
        "instantiation_token": d.token,
        "co_simulation": d.cs_identifier,
        "model_exchange": d.has_model_exchange,
        "variable_step": d.variable_step,
        "fixed_internal_step_s": d.fixed_step,
        "default_step_s": d.default_step,
        "variables": d.vars.iter().map(var_json).collect::<Vec<_>>(),
    })
}

/// Seconds, or "not declared".
fn secs(v: Option<f64>) -> String {
    v.map_or_else(|| "not declared".to_string(), |s| format!("{s} s"))
}

fn print_table(a: &InspectArgs, d: &ModelDescription) {
    println!("{}: {} `{}`", a.fmu.display(), d.version, d.model_name);
    println!(
        "  co-simulation: {}; model exchange: {}",
        d.cs_identifier
            .as_deref()
            .map_or_else(|| "no".to_string(), |id| format!("yes (`{id}`)")),
        if d.has_model_exchange { "yes" } else { "no" }
    );
    println!(
        "  steps: variable communication step {}; fixed internal step {}; default experiment step {}",
        if d.variable_step { "yes" } else { "no" },
        secs(d.fixed_step),
        secs(d.default_step)
    );
    let mut vars: Vec<&VarDesc> = d.vars.iter().collect();
    // Inputs, outputs and parameters first: what a user connects and sets.
    let rank = |c: &str| match c {
        "input" => 0,
        "output" => 1,
        "parameter" | "structuralParameter" => 2,
        "calculatedParameter" => 3,
        "independent" => 4,
        _ => 5,
    };
    vars.sort_by_key(|v| (rank(&v.causality), v.vr));
    let w = vars.iter().map(|v| v.name.len()).max().unwrap_or(4).max(4);
    println!(
        "  {:<w$}  {:>6}  {:<19}  {:<8}  {:<8}  description",
        "name", "vr", "causality", "type", "unit"
    );
    for v in vars {
        println!(
            "  {:<w$}  {:>6}  {:<19}  {:<8}  {:<8}  {}",
            v.name,
            v.vr,
            v.causality,
            v.type_name,
            v.unit.as_deref().unwrap_or("-"),
            v.description.as_deref().unwrap_or("")
        );
    }
}

/// Runs the command.
pub fn exec(a: InspectArgs) -> CliResult {
    let d = tiltsim_fmi::archive::read_description(&a.fmu)
        .map_err(|e| CliError::Invalid(format!("{}: {e}", a.fmu.display())))?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&as_json(&d)).unwrap_or_default()
        );
    } else {
        print_table(&a, &d);
    }
    Ok(())
}
