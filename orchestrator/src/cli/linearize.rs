//! `tiltsim linearize SCENARIO`: the design model and the controller's gains as JSON; for a PI
//! its loop margins, and with `--design-pi` a PI designed for this drive.

use std::path::PathBuf;

use super::bounds::{self, End};
use super::common::load;
use super::error::{CliError, CliResult};
use crate::linearize::PiTargets;

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct LinearizeArgs {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// Write the JSON here instead of standard output.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also design a PI for this scenario's vehicle and actuator: the largest K_p with
    /// integral time --ti whose margins reach --phase-margin and --gain-margin.
    #[arg(long)]
    design_pi: bool,
    /// Phase-margin target of --design-pi (deg).
    #[arg(long, default_value_t = 60.0,
          value_parser = bounds::real((0.0, End::Closed), (89.0, End::Closed), " deg"))]
    phase_margin: f64,
    /// Gain-margin target of --design-pi (dB).
    #[arg(long, default_value_t = 6.0,
          value_parser = bounds::real((0.0, End::Closed), (40.0, End::Closed), " dB"))]
    gain_margin: f64,
    /// Integral time K_p/K_i of --design-pi (s).
    #[arg(long, default_value_t = 0.25,
          value_parser = bounds::real((1e-3, End::Closed), (100.0, End::Closed), " s"))]
    ti: f64,
}

/// Runs the command.
pub fn exec(a: LinearizeArgs) -> CliResult {
    let design = a.design_pi.then_some(PiTargets {
        phase_margin_deg: a.phase_margin,
        gain_margin_db: a.gain_margin,
        ti_s: a.ti,
    });
    for (flag, v, lo, hi) in [
        ("--phase-margin", a.phase_margin, 0.0, 89.0),
        ("--gain-margin", a.gain_margin, 0.0, 40.0),
        ("--ti", a.ti, 1e-3, 100.0),
    ] {
        if design.is_some() && !(lo..=hi).contains(&v) {
            return Err(CliError::Invalid(format!(
                "{flag} = {v}: allowed {lo} to {hi}"
            )));
        }
    }
    let s = load(&a.scenario)?;
    let report = crate::linearize::report(&s, design).map_err(|e| {
        CliError::Invalid(format!("{}: controller design: {e}", a.scenario.display()))
    })?;
    let text = serde_json::to_string_pretty(&report).unwrap_or_default() + "\n";
    match a.out {
        Some(p) => {
            crate::files::write_atomic(&p, text).map_err(|e| CliError::Failed(e.to_string()))
        }
        None => {
            print!("{text}");
            Ok(())
        }
    }
}
