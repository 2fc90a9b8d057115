//! `tiltsim bench`: measure this machine's coordination overhead and transport floor.

use std::path::PathBuf;

use super::common::{load, write_json};
use super::error::{CliError, CliResult};

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Scenario to run in every configuration.
    #[arg(default_value = "scenarios/paper-passive.toml")]
    scenario: PathBuf,
    /// Simulated seconds per configuration.
    #[arg(long, default_value_t = 2.0)]
    duration: f64,
    /// JSON report.
    #[arg(long, default_value = "out/bench.json")]
    out: PathBuf,
}

/// Runs the command.
pub fn exec(a: BenchArgs) -> CliResult {
    let s = load(&a.scenario)?;
    let d = a.duration;
    if !(d.is_finite() && d > 0.0 && d <= 600.0) {
        return Err(CliError::Invalid(format!(
            "command line: --duration {d}: allowed (0, 600] s"
        )));
    }
    let exe = std::env::current_exe().map_err(|_| {
        CliError::Failed("cannot find the tiltsim executable to start participants".into())
    })?;
    let scratch = crate::bench::scratch_dir(&a.out);
    let report = crate::bench::run(&s, d, &exe, &scratch, |name| {
        eprintln!("  measuring {name} ...");
    });
    let _ = std::fs::remove_dir_all(&scratch);
    let report = report.map_err(|e| CliError::Failed(format!("bench: {e}")))?;
    println!("{}", crate::bench::table(&report));
    if let Some(dir) = a.out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    write_json(&a.out, &report)?;
    println!("wrote {}", a.out.display());
    Ok(())
}
